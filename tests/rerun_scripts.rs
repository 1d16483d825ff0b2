//! `scripts/to_rerun.py` and `scripts/compare_runs.py` write .rrd files that the pinned Rerun SDK
//! (rerun-sdk 0.36.3, scripts/requirements.txt) accepts and reads back as logged: `rerun rrd
//! verify` passes, and `scripts/inspect_rrd.py` (built on `rerun.experimental.RrdReader`) finds
//! the entity paths, one row per frame on both timelines, every box, and the top-down views.
//!
//! Needs `python3 -m pip install -r scripts/requirements.txt`; without rerun-sdk (or the MCAP
//! readers) the tests say so on stderr and pass.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use common::{detections, probmot_ok, repo, tracks};
use serde_json::Value;

fn python_has(modules: &str) -> bool {
    Command::new("python3")
        .args(["-c", &format!("import {modules}")])
        .output()
        .is_ok_and(|o| o.status.success())
}

/// Whether the tests can run; prints why not.
fn available(test: &str) -> bool {
    if python_has("rerun, mcap, mcap_protobuf") {
        return true;
    }
    eprintln!(
        "SKIPPED {test}: `python3 -c \"import rerun, mcap, mcap_protobuf\"` failed; install with \
         `python3 -m pip install -r scripts/requirements.txt` (rerun-sdk==0.36.3)"
    );
    false
}

fn python(args: &[&str]) -> Output {
    Command::new("python3")
        .args(args)
        .output()
        .expect("run python3")
}

fn script(name: &str) -> String {
    repo(&format!("scripts/{name}")).display().to_string()
}

fn ok(out: Output, what: &str) -> Output {
    assert!(
        out.status.success(),
        "{what} failed ({}):\n{}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stderr),
        String::from_utf8_lossy(&out.stdout)
    );
    out
}

fn track(input: &Path, out: &Path, extra: &[&str]) {
    let mut args = vec![
        "track",
        input.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--quiet",
    ];
    args.extend(extra);
    probmot_ok(&args);
}

/// `rerun rrd verify` of the pinned SDK (the `rerun` module runs its bundled CLI).
fn verify(rrd: &Path) {
    let out = ok(
        python(&["-m", "rerun", "rrd", "verify", rrd.to_str().unwrap()]),
        "rerun rrd verify",
    );
    let said =
        String::from_utf8_lossy(&out.stderr).to_string() + &String::from_utf8_lossy(&out.stdout);
    assert!(said.contains("verified without error"), "{said}");
}

/// The read-back summary of `scripts/inspect_rrd.py`.
fn inspect(rrd: &Path) -> Value {
    let out = ok(
        python(&[&script("inspect_rrd.py"), rrd.to_str().unwrap()]),
        "inspect_rrd.py",
    );
    serde_json::from_slice(&out.stdout).expect("inspect_rrd.py prints JSON")
}

/// What the MCAP file holds, to compare with the recording.
struct Expected {
    frames: u64,
    first_ns: u64,
    last_ns: u64,
    detections: u64,
    tracks: u64,
    truth: u64,
}

fn expected(mcap: &Path) -> Expected {
    let tr = tracks(mcap, "/tracks");
    let gt = tracks(mcap, "/ground_truth");
    let det = detections(mcap, "/detections");
    let stamps: Vec<u64> = tr.iter().map(|t| t.stamp).collect();
    Expected {
        frames: tr.len() as u64,
        first_ns: *stamps.iter().min().unwrap(),
        last_ns: *stamps.iter().max().unwrap(),
        detections: det.iter().map(|d| d.detections.len() as u64).sum(),
        tracks: tr.iter().map(|t| t.tracks.len() as u64).sum(),
        truth: gt.iter().map(|t| t.tracks.len() as u64).sum(),
    }
}

fn u(v: &Value, what: &str) -> u64 {
    v.as_u64()
        .unwrap_or_else(|| panic!("{what}: expected an unsigned integer, got {v}"))
}

/// Checks the entities of one run under `prefix` (`/world`, `/a/world`, ...).
fn check_run(summary: &Value, prefix: &str, e: &Expected) {
    let entities = &summary["entities"];
    let world = &entities[prefix];
    assert_eq!(
        u(&world["static_rows"], "static"),
        1,
        "{prefix}: view coordinates"
    );
    assert_eq!(world["components"][0], "ViewCoordinates:xyz");
    for (name, instances) in [
        ("detections", e.detections),
        ("tracks", e.tracks),
        ("ground_truth", e.truth),
        ("trails", e.tracks),
        ("velocity", e.tracks),
    ] {
        let path = format!("{prefix}/{name}");
        let ent = &entities[&path];
        assert!(ent.is_object(), "entity {path} missing: {summary:#}");
        assert_eq!(
            u(&ent["rows"], &path),
            e.frames,
            "{path}: one row per frame"
        );
        assert_eq!(u(&ent["static_rows"], &path), 0, "{path}");
        assert_eq!(u(&ent["instances"], &path), instances, "{path}: every box");
        let frame = &ent["timelines"]["frame"];
        assert_eq!(u(&frame["rows"], "frame rows"), e.frames, "{path}");
        assert_eq!(u(&frame["distinct"], "frames"), e.frames, "{path}");
        assert_eq!(u(&frame["min"], "min frame"), 0, "{path}");
        assert_eq!(u(&frame["max"], "max frame"), e.frames - 1, "{path}");
        let lt = &ent["timelines"]["log_time"];
        assert_eq!(u(&lt["rows"], "log_time rows"), e.frames, "{path}");
        assert_eq!(u(&lt["distinct"], "log times"), e.frames, "{path}");
        assert_eq!(u(&lt["min"], "first log time"), e.first_ns, "{path}");
        assert_eq!(u(&lt["max"], "last log time"), e.last_ns, "{path}");
        let timelines: Vec<&String> = ent["timelines"].as_object().unwrap().keys().collect();
        assert_eq!(
            timelines,
            ["frame", "log_time"],
            "{path}: only our timelines"
        );
    }
    let tracks = &entities[format!("{prefix}/tracks")]["components"];
    for c in [
        "Boxes3D:centers",
        "Boxes3D:half_sizes",
        "Boxes3D:rotation_axis_angles",
        "Boxes3D:colors",
        "Boxes3D:labels",
    ] {
        assert!(
            tracks.as_array().unwrap().iter().any(|v| v == c),
            "{prefix}/tracks lacks {c}: {tracks}"
        );
    }
}

/// A 3D view of `origin` whose eye looks straight down with +y up.
fn check_top_down_view(view: &Value, origin: &str) {
    assert_eq!(view["class"], "3D", "{view}");
    assert_eq!(view["origin"], origin, "{view}");
    let eye = view["eye_position"].as_array().expect("eye position set");
    let target = view["look_target"].as_array().expect("look target set");
    let f = |v: &Value| v.as_f64().unwrap();
    assert!(
        f(&eye[2]) > f(&target[2]) + 10.0,
        "eye above the ground: {view}"
    );
    let horizontal = (f(&eye[0]) - f(&target[0])).hypot(f(&eye[1]) - f(&target[1]));
    assert!(
        horizontal < 0.01 * f(&eye[2]),
        "looking straight down: {view}"
    );
    assert_eq!(view["eye_up"], serde_json::json!([0.0, 1.0, 0.0]), "{view}");
}

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
        .filter(|n| n.to_string_lossy().starts_with(".probmot-"))
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
