//! `scripts/to_rerun.py` and `scripts/compare_runs.py` write .rrd files that the pinned Rerun SDK
//! (rerun-sdk 0.36.3, scripts/requirements.txt) accepts and reads back as logged: `rerun rrd
//! verify` passes, and `scripts/inspect_rrd.py` (built on `rerun.experimental.RrdReader`) finds
//! the entity paths, one row per frame on both timelines, every box, and the top-down views.
//!
//! Needs `python3 -m pip install -r scripts/requirements.txt`; without rerun-sdk (or the MCAP
//! readers) the tests say so on stderr and pass.

mod common;
#[path = "common/rrd.rs"]
mod rrd;

use std::path::PathBuf;

use common::repo;
use rrd::{
    available, check_run, check_top_down_view, expected, inspect, ok, python, script, track, verify,
};

#[test]
fn to_rerun_writes_a_recording_the_sdk_reads_back() {
    if !available("to_rerun_writes_a_recording_the_sdk_reads_back") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let tracked: PathBuf = dir.path().join("turning-car.tracked.mcap");
    track(&repo("sample_logs/turning-car.mcap"), &tracked, &[]);
    let rrd = dir.path().join("turning-car.rrd");
    let out = ok(
        python(&[
            &script("to_rerun.py"),
            tracked.to_str().unwrap(),
            "-o",
            rrd.to_str().unwrap(),
            "--recording-id",
            "probmot-test",
        ]),
        "to_rerun.py",
    );
    let said = String::from_utf8_lossy(&out.stdout);
    assert!(said.contains("40 frames"), "{said}");

    verify(&rrd);
    let summary = inspect(&rrd);
    assert_eq!(summary["sdk_version"], "0.36.3", "the pinned SDK");
    assert_eq!(summary["recordings"][0]["application_id"], "probmot");
    assert_eq!(summary["recordings"][0]["recording_id"], "probmot-test");
    assert_eq!(summary["blueprints"].as_array().unwrap().len(), 1);
    let e = expected(&tracked);
    assert_eq!(e.frames, 40);
    check_run(&summary, "/world", &e);
    let views = summary["views"].as_array().unwrap();
    assert_eq!(views.len(), 1, "{views:?}");
    check_top_down_view(&views[0], "world");

    // Untracked input: a clear error, no output.
    let bad = dir.path().join("bad.rrd");
    let out = python(&[
        &script("to_rerun.py"),
        repo("sample_logs/turning-car.mcap").to_str().unwrap(),
        "-o",
        bad.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("no messages on topic '/tracks'"), "{err}");
    assert!(!bad.exists());
    let leftovers: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .filter(|n| n.to_string_lossy().contains(".probmot-"))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}

#[test]
fn compare_runs_puts_two_runs_side_by_side() {
    if !available("compare_runs_puts_two_runs_side_by_side") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let input = repo("sample_logs/turning-car.mcap");
    let a = dir.path().join("a.mcap");
    let b = dir.path().join("b.mcap");
    track(&input, &a, &[]);
    // A run that drops tracks sooner and confirms them later: other ids and box counts.
    track(&input, &b, &["--max-age", "1", "--min-hits", "3"]);
    let (ea, eb) = (expected(&a), expected(&b));
    assert_ne!(ea.tracks, eb.tracks, "the two runs differ");

    let rrd = dir.path().join("compare.rrd");
    ok(
        python(&[
            &script("compare_runs.py"),
            a.to_str().unwrap(),
            b.to_str().unwrap(),
            "-o",
            rrd.to_str().unwrap(),
        ]),
        "compare_runs.py",
    );
    verify(&rrd);
    let summary = inspect(&rrd);
    assert_eq!(
        summary["recordings"].as_array().unwrap().len(),
        1,
        "one recording"
    );
    check_run(&summary, "/a/world", &ea);
    check_run(&summary, "/b/world", &eb);
    assert!(
        summary["entities"]["/world/tracks"].is_null(),
        "runs live under a/ and b/ only"
    );
    let views = summary["views"].as_array().unwrap();
    assert_eq!(views.len(), 2, "{views:?}");
    let mut origins: Vec<&str> = views
        .iter()
        .map(|v| v["origin"].as_str().unwrap())
        .collect();
    origins.sort();
    assert_eq!(origins, ["a/world", "b/world"]);
    for v in views {
        check_top_down_view(v, v["origin"].as_str().unwrap());
    }
}
