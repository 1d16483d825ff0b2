//! The Rust Rerun writer (cargo feature `rerun`): `probmot viz` and `probmot track --rerun` write
//! .rrd files that the pinned Rerun SDK (rerun-sdk 0.36.3, scripts/requirements.txt) verifies and
//! reads back with the same entities, row counts per timeline and top-down view as
//! `scripts/to_rerun.py` (checked with the helpers of tests/it/rerun_scripts.rs).
//!
//! The read-back needs `python3 -m pip install -r scripts/requirements.txt`; without rerun-sdk the
//! tests check what they can without it, say so on stderr and pass. Without the feature, the
//! tests check that `viz` and `track --rerun` fail with a message saying how to get a recording.

#[path = "it/common/mod.rs"]
mod common;
#[path = "it/common/rrd.rs"]
mod rrd;

use common::{probmot, repo};

/// `viz` is listed in `probmot --help` with or without the feature.
#[test]
fn viz_is_listed_in_help() {
    let out = probmot(&["--help"]);
    assert!(out.status.success());
    let help = String::from_utf8_lossy(&out.stdout);
    assert!(
        help.lines().any(|l| l.trim_start().starts_with("viz ")),
        "{help}"
    );
    let out = probmot(&["viz", "--help"]);
    assert!(out.status.success());
    let help = String::from_utf8_lossy(&out.stdout);
    assert!(
        help.contains("--features rerun") && help.contains("to_rerun.py"),
        "{help}"
    );
}

/// A non-.rrd output is refused before anything else (feature or not).
#[test]
fn viz_wants_an_rrd_output() {
    let dir = tempfile::tempdir().unwrap();
    let out_path = dir.path().join("out.png");
    let input = repo("sample_logs/turning-car.mcap");
    let out = probmot(&[
        "viz",
        input.to_str().unwrap(),
        "-o",
        out_path.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2), "{out:?}");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("must end in .rrd"), "{err}");
    assert!(!out_path.exists());
}

#[cfg(not(feature = "rerun"))]
mod without_feature {
    use super::common::{probmot, repo};

    fn assert_explains(err: &str) {
        assert!(
            err.contains("without the `rerun` cargo feature")
                && err.contains("--features rerun")
                && err.contains("scripts/to_rerun.py"),
            "{err}"
        );
    }

    #[test]
    fn viz_says_how_to_get_a_recording() {
        let dir = tempfile::tempdir().unwrap();
        let rrd = dir.path().join("out.rrd");
        let input = repo("sample_logs/turning-car.mcap");
        let out = probmot(&["viz", input.to_str().unwrap(), "-o", rrd.to_str().unwrap()]);
        assert_eq!(out.status.code(), Some(2));
        assert_explains(&String::from_utf8_lossy(&out.stderr));
        assert!(!rrd.exists());
    }

    #[test]
    fn track_rerun_says_how_to_get_a_recording_before_tracking() {
        let dir = tempfile::tempdir().unwrap();
        let rrd = dir.path().join("out.rrd");
        let tracked = dir.path().join("out.mcap");
        let input = repo("sample_logs/turning-car.mcap");
        let out = probmot(&[
            "track",
            input.to_str().unwrap(),
            "-o",
            tracked.to_str().unwrap(),
            "--rerun",
            rrd.to_str().unwrap(),
        ]);
        assert_eq!(out.status.code(), Some(2));
        assert_explains(&String::from_utf8_lossy(&out.stderr));
        assert!(!rrd.exists());
        assert!(!tracked.exists(), "fails before tracking");
    }
}

#[cfg(feature = "rerun")]
mod with_feature {
    use std::path::Path;

    use serde_json::Value;

    use super::common::{probmot, probmot_ok, repo};
    use super::rrd::{
        available, check_run, check_top_down_view, expected, inspect, ok, python, script, track,
        verify,
    };

    /// What can be checked without the SDK: a non-empty file starting with the RRD magic bytes.
    fn check_file(rrd: &Path) {
        let bytes = std::fs::read(rrd).expect("the .rrd was written");
        assert!(bytes.len() > 1000, "{} bytes", bytes.len());
        assert_eq!(&bytes[..4], b"RRF2", "RRD stream header");
    }

    fn no_leftovers(dir: &Path) {
        let leftovers: Vec<_> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .filter(|n| n.to_string_lossy().contains(".probmot-"))
            .collect();
        assert!(leftovers.is_empty(), "{leftovers:?}");
    }

    /// Entities with their row and instance counts and timelines, without the recording id.
    fn entities(summary: &Value) -> Value {
        summary["entities"].clone()
    }

    /// Checks one recording of the tracked turning-car log, written by the Rust feature.
    fn check_recording(rrd: &Path, tracked: &Path, recording_id: Option<&str>) -> Value {
        verify(rrd);
        let summary = inspect(rrd);
        assert_eq!(summary["sdk_version"], "0.36.3", "the pinned SDK");
        assert_eq!(summary["recordings"].as_array().unwrap().len(), 1);
        assert_eq!(summary["recordings"][0]["application_id"], "probmot");
        if let Some(id) = recording_id {
            assert_eq!(summary["recordings"][0]["recording_id"], id);
        }
        assert_eq!(summary["blueprints"].as_array().unwrap().len(), 1);
        let e = expected(tracked);
        assert_eq!(e.frames, 40);
        check_run(&summary, "/world", &e);
        let views = summary["views"].as_array().unwrap();
        assert_eq!(views.len(), 1, "{views:?}");
        check_top_down_view(&views[0], "world");
        summary
    }

    /// A box that cannot be drawn (a NaN centre) is left out of the recording and named in a
    /// warning, not dropped unsaid.
    #[test]
    fn viz_names_undrawable_boxes() {
        let dir = tempfile::tempdir().unwrap();
        let nan = dir.path().join("nan.mcap");
        super::common::city_with_nan_truth(&nan);
        let rrd = dir.path().join("nan.rrd");
        let out = probmot_ok(&["viz", nan.to_str().unwrap(), "-o", rrd.to_str().unwrap()]);
        let err = String::from_utf8_lossy(&out.stderr);
        let want = format!(
            "warning: {}: topic /ground_truth: 1 box(es) with a non-finite centre",
            nan.display()
        );
        assert!(err.contains(&want), "{err}");
        check_file(&rrd);
    }

    #[test]
    fn viz_writes_what_to_rerun_py_writes() {
        let dir = tempfile::tempdir().unwrap();
        let tracked = dir.path().join("turning-car.tracked.mcap");
        track(&repo("sample_logs/turning-car.mcap"), &tracked, &[]);
        let rrd = dir.path().join("rust.rrd");
        let out = probmot_ok(&[
            "viz",
            tracked.to_str().unwrap(),
            "-o",
            rrd.to_str().unwrap(),
            "--recording-id",
            "probmot-test",
        ]);
        let said = String::from_utf8_lossy(&out.stdout);
        assert!(said.contains("40 frames"), "{said}");
        check_file(&rrd);
        no_leftovers(dir.path());
        if !available("viz_writes_what_to_rerun_py_writes (SDK read-back)") {
            return;
        }
        let rust = check_recording(&rrd, &tracked, Some("probmot-test"));

        // The script's recording of the same file: the same entities, components, rows,
        // instances and times.
        let py_rrd = dir.path().join("python.rrd");
        ok(
            python(&[
                &script("to_rerun.py"),
                tracked.to_str().unwrap(),
                "-o",
                py_rrd.to_str().unwrap(),
            ]),
            "to_rerun.py",
        );
        let py = inspect(&py_rrd);
        let (mut re, mut pe) = (entities(&rust), entities(&py));
        // Recording properties (name, start time) are SDK bookkeeping, not our entities.
        for e in [&mut re, &mut pe] {
            e.as_object_mut()
                .unwrap()
                .retain(|k, _| k.starts_with("/world"));
        }
        assert_eq!(re, pe, "Rust and Python recordings hold the same entities");
        let (rv, pv) = (&rust["views"][0], &py["views"][0]);
        for key in ["eye_position", "look_target", "eye_up"] {
            let (a, b) = (rv[key].as_array().unwrap(), pv[key].as_array().unwrap());
            for (x, y) in a.iter().zip(b) {
                let (x, y) = (x.as_f64().unwrap(), y.as_f64().unwrap());
                assert!(
                    (x - y).abs() < 1e-3 * (1.0 + y.abs()),
                    "{key}: {rv} vs {pv}"
                );
            }
        }
    }

    #[test]
    fn track_rerun_writes_the_recording_of_its_output() {
        let dir = tempfile::tempdir().unwrap();
        let tracked = dir.path().join("turning-car.tracked.mcap");
        let rrd = dir.path().join("track.rrd");
        let out = probmot_ok(&[
            "track",
            repo("sample_logs/turning-car.mcap").to_str().unwrap(),
            "-o",
            tracked.to_str().unwrap(),
            "--rerun",
            rrd.to_str().unwrap(),
        ]);
        let said = String::from_utf8_lossy(&out.stdout);
        assert!(said.contains("track.rrd: 40 frames"), "{said}");
        check_file(&rrd);
        no_leftovers(dir.path());
        if !available("track_rerun_writes_the_recording_of_its_output (SDK read-back)") {
            return;
        }
        let from_track = check_recording(&rrd, &tracked, None);
        // The same as `probmot viz` on the output.
        let viz = dir.path().join("viz.rrd");
        probmot_ok(&[
            "viz",
            tracked.to_str().unwrap(),
            "-o",
            viz.to_str().unwrap(),
        ]);
        let from_viz = inspect(&viz);
        assert_eq!(entities(&from_track), entities(&from_viz));
        assert_eq!(from_track["views"], from_viz["views"]);
    }

    /// `viz` on the file `eval --events` writes draws the events layer as `to_rerun.py` does:
    /// a row of error boxes per frame and a text entry per identity switch and fragmentation.
    #[test]
    fn viz_draws_the_events_layer_as_to_rerun_py() {
        let dir = tempfile::tempdir().unwrap();
        let tracked = dir.path().join("ped.tracked.mcap");
        let events = dir.path().join("ped.events.mcap");
        track(&repo("sample_logs/pedestrians.mcap"), &tracked, &[]);
        let out = probmot_ok(&[
            "eval",
            "--truth",
            tracked.to_str().unwrap(),
            "--events",
            events.to_str().unwrap(),
            "--json",
        ]);
        let v: Value = serde_json::from_slice(&out.stdout).unwrap();
        let moments: u64 = v["events"]["counts"]
            .as_object()
            .unwrap()
            .values()
            .map(|c| c["ids"].as_u64().unwrap() + c["frag"].as_u64().unwrap())
            .sum();
        assert!(
            moments > 0,
            "the sample has switches or fragmentations: {v}"
        );
        let rrd = dir.path().join("events.rrd");
        probmot_ok(&[
            "viz",
            events.to_str().unwrap(),
            "-o",
            rrd.to_str().unwrap(),
            "--quiet",
        ]);
        check_file(&rrd);
        if !available("viz_draws_the_events_layer_as_to_rerun_py (SDK read-back)") {
            return;
        }
        verify(&rrd);
        let rust = inspect(&rrd);
        let e = &rust["entities"];
        assert_eq!(e["/events"]["rows"].as_u64(), Some(moments), "{e}");
        assert_eq!(e["/world/events"]["rows"].as_u64(), Some(40), "{e}");
        let py_rrd = dir.path().join("python.rrd");
        ok(
            python(&[
                &script("to_rerun.py"),
                events.to_str().unwrap(),
                "-o",
                py_rrd.to_str().unwrap(),
            ]),
            "to_rerun.py",
        );
        let py = inspect(&py_rrd);
        for key in ["/events", "/world/events"] {
            assert_eq!(rust["entities"][key], py["entities"][key], "{key}");
        }
    }

    /// `--from/--to` draws the frames whose stamp lies in the window (counted here from the
    /// tracked file itself), and an empty or reversed window is a clear error.
    #[test]
    fn viz_window_draws_the_frames_of_the_window_only() {
        let dir = tempfile::tempdir().unwrap();
        let tracked = dir.path().join("turning-car.tracked.mcap");
        track(&repo("sample_logs/turning-car.mcap"), &tracked, &[]);
        let stamps: Vec<u64> = probmot::mcapio::recording::tracks_topic(&tracked, "/tracks")
            .unwrap()
            .iter()
            .map(|(s, _)| *s)
            .collect();
        let t0 = *stamps.iter().min().unwrap();
        let in_window = |s: &&u64| (1.0..=2.0 + 1e-6).contains(&((**s - t0) as f64 / 1e9));
        let expected = stamps.iter().filter(in_window).count();
        assert!(
            expected > 0 && expected < stamps.len(),
            "{expected} of {}",
            stamps.len()
        );
        let rrd = dir.path().join("window.rrd");
        let args = [
            "viz",
            tracked.to_str().unwrap(),
            "-o",
            rrd.to_str().unwrap(),
        ];
        let out = probmot_ok(&[&args[..], &["--from", "1", "--to", "2"]].concat());
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(
            stdout.contains(&format!(": {expected} frames,")),
            "{stdout} (expected {expected} frames)"
        );
        check_file(&rrd);
        for (window, says) in [
            (
                ["--from", "100", "--to", "200"],
                "in the window 100 to 200 s",
            ),
            (["--from", "2", "--to", "1"], "--from 2 is after --to 1"),
        ] {
            let bad = dir.path().join("bad.rrd");
            let args = [
                "viz",
                tracked.to_str().unwrap(),
                "-o",
                bad.to_str().unwrap(),
            ];
            let out = probmot(&[&args[..], &window[..]].concat());
            assert_eq!(out.status.code(), Some(2));
            let err = String::from_utf8_lossy(&out.stderr);
            assert!(err.contains(says), "{err}");
            assert!(!bad.exists());
        }
        no_leftovers(dir.path());
    }

    #[test]
    fn viz_reads_an_untracked_log_and_refuses_a_foreign_one() {
        let dir = tempfile::tempdir().unwrap();
        // Untracked: detections and ground truth only.
        let rrd = dir.path().join("raw.rrd");
        probmot_ok(&[
            "viz",
            repo("sample_logs/turning-car.mcap").to_str().unwrap(),
            "-o",
            rrd.to_str().unwrap(),
            "--quiet",
        ]);
        check_file(&rrd);
        if available("viz_reads_an_untracked_log_and_refuses_a_foreign_one (SDK read-back)") {
            let s = inspect(&rrd);
            assert!(s["entities"]["/world/tracks"].is_null(), "no tracks");
            assert!(s["entities"]["/world/detections"]["rows"].as_u64().unwrap() > 0);
        }

        // Topics named that the log lacks: refused before any recording, no output and no
        // temporary file left.
        let bad = dir.path().join("bad.rrd");
        let out = probmot(&[
            "viz",
            repo("sample_logs/turning-car.mcap").to_str().unwrap(),
            "-o",
            bad.to_str().unwrap(),
            "--detections-topic",
            "/lidar",
            "--tracks-topic",
            "/nothing",
            "--truth-topic",
            "/none",
        ]);
        assert_eq!(out.status.code(), Some(2));
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains("has no topic /lidar for the detections layer (topics: ")
                && err.contains("check --detections-topic"),
            "{err}"
        );
        assert!(!bad.exists());
        no_leftovers(dir.path());

        // A log without our topics (the default ones): a clear error naming its topics.
        let empty = dir.path().join("empty.mcap");
        let file = std::io::BufWriter::new(std::fs::File::create(&empty).unwrap());
        mcap::Writer::new(file).unwrap().finish().unwrap();
        let out = probmot(&["viz", empty.to_str().unwrap(), "-o", bad.to_str().unwrap()]);
        assert_eq!(out.status.code(), Some(2));
        let err = String::from_utf8_lossy(&out.stderr);
        let want = "has no messages on /detections, /tracks or /ground_truth (the file has no \
                    channels)";
        assert!(err.contains(want), "{err}");
        assert!(!bad.exists());
    }

    /// `--rerun` reads the tracked output back: an output that is a FIFO (or a device, or
    /// standard output) is refused before any work.
    #[cfg(unix)]
    #[test]
    fn track_rerun_needs_a_file_output() {
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("out.mcap");
        let status = std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap();
        assert!(status.success());
        // Drains the FIFO should track open it (a regression), so that the test fails instead
        // of hanging on the open.
        let drain = fifo.clone();
        std::thread::spawn(move || std::fs::read(drain));
        let rrd = dir.path().join("run.rrd");
        let city = repo("sample_logs/city.mcap");
        let out = probmot(&[
            "track",
            city.to_str().unwrap(),
            "-o",
            fifo.to_str().unwrap(),
            "--rerun",
            rrd.to_str().unwrap(),
        ]);
        assert_eq!(out.status.code(), Some(2));
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains("--rerun reads the tracked file back"), "{err}");
        assert!(!rrd.exists());
    }

    /// `track --rerun` on a bag split into several files is refused before any work (its
    /// output would be split too, and a recording reads one file back): no output is left.
    #[test]
    fn track_rerun_refuses_a_split_bag_up_front() {
        let dir = tempfile::tempdir().unwrap();
        let bag = dir.path().join("bag");
        let log = repo("sample_logs/city.mcap");
        super::common::split::split_mcap(&log, &bag, &[20]);
        let (out, rrd) = (dir.path().join("out"), dir.path().join("run.rrd"));
        let run = probmot(&[
            "track",
            bag.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--rerun",
            rrd.to_str().unwrap(),
        ]);
        let err = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(2), "{err}");
        assert!(err.contains("split into 2 files"), "{err}");
        assert_eq!(super::common::entries(dir.path()), ["bag"]);
    }
}
