//! `scripts/to_rerun.py` and `scripts/compare_runs.py` write .rrd files that the pinned Rerun SDK
//! (rerun-sdk 0.36.3, scripts/requirements.txt) accepts and reads back as logged: `rerun rrd
//! verify` passes, and `scripts/inspect_rrd.py` (built on `rerun.experimental.RrdReader`) finds
//! the entity paths, one row per frame on both timelines, every box, and the top-down views.
//!
//! Needs `python3 -m pip install -r scripts/requirements.txt`; without rerun-sdk (or the MCAP
//! readers) the tests say so on stderr and pass.

#[path = "common/rrd.rs"]
pub(crate) mod rrd;

use std::path::{Path, PathBuf};

use crate::common::{detections, messages, repo, tracks};
use rrd::{
    available, check_run, check_top_down_view, expected, inspect, ok, python, script, track, verify,
};
use serde_json::Value;

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

/// The boxes `to_rerun.read_run` decodes from each file (one Python run), per role:
/// `log_time -> [[id, label, score, cx, cy, cz, l, w, h, yaw, velocity or null]]` (JSON; roles
/// without a topic are null).
fn read_run_boxes(files: &[PathBuf]) -> Vec<Value> {
    let code = "import json, sys; sys.path.insert(0, sys.argv[1]); import to_rerun\n\
        def enc(frames):\n\
        \x20   if frames is None: return None\n\
        \x20   return {str(t): [[b.id, b.label, b.score, *b.center, *b.size, b.yaw, b.velocity]\n\
        \x20                    for b in bs] for t, bs in frames.items()}\n\
        for f in sys.argv[2:]:\n\
        \x20   run = to_rerun.read_run(f, require_tracks=False)\n\
        \x20   print(json.dumps({r: enc(getattr(run, r)) for r in ('detections', 'tracks')}))";
    let scripts = repo("scripts");
    let mut args = vec!["-c", code, scripts.to_str().unwrap()];
    args.extend(files.iter().map(|f| f.to_str().unwrap()));
    let out = ok(python(&args), "to_rerun.read_run");
    let text = String::from_utf8(out.stdout).unwrap();
    text.lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

/// One expected box: id, label, score, centre and size, yaw, velocity (None: not in the
/// message).
type WantBox = (u64, String, f64, [f64; 6], f64, Option<[f64; 3]>);

fn det_boxes(file: &Path) -> Vec<(u64, Vec<WantBox>)> {
    let times = messages(file)
        .into_iter()
        .filter(|m| m.topic == "/detections");
    let times: Vec<u64> = times.map(|m| m.log_time).collect();
    let frames = detections(file, "/detections").into_iter().map(|f| {
        f.detections
            .iter()
            .map(|d| {
                let (c, s) = (d.center.unwrap(), d.size.unwrap());
                let geo = [c.x, c.y, c.z, s.length, s.width, s.height];
                (0, d.label.clone(), d.score, geo, d.yaw, None)
            })
            .collect()
    });
    times.into_iter().zip(frames).collect()
}

fn track_boxes(file: &Path, with_velocity: bool) -> Vec<(u64, Vec<WantBox>)> {
    let times = messages(file).into_iter().filter(|m| m.topic == "/tracks");
    let times: Vec<u64> = times.map(|m| m.log_time).collect();
    let frames = tracks(file, "/tracks").into_iter().map(|f| {
        f.tracks
            .iter()
            .map(|t| {
                let (c, s, v) = (t.center.unwrap(), t.size.unwrap(), t.velocity.unwrap());
                let geo = [c.x, c.y, c.z, s.length, s.width, s.height];
                let vel = with_velocity.then_some([v.x, v.y, v.z]);
                (t.id, t.label.clone(), t.score, geo, t.yaw, vel)
            })
            .collect()
    });
    times.into_iter().zip(frames).collect()
}

/// The script's boxes of one role equal `want` (to 1e-9; yaw modulo a turn).
fn assert_boxes(got: &Value, want: &[(u64, Vec<WantBox>)], what: &str) {
    let got = got
        .as_object()
        .unwrap_or_else(|| panic!("{what}: no frames"));
    assert_eq!(got.len(), want.len(), "{what}: frames");
    let f = |v: &Value| v.as_f64().unwrap();
    for (t, boxes) in want {
        let g = got[&t.to_string()].as_array().unwrap();
        assert_eq!(g.len(), boxes.len(), "{what} at {t}: boxes");
        for (b, w) in g.iter().zip(boxes) {
            let b = b.as_array().unwrap();
            let at = format!("{what} at {t}: {b:?} vs {w:?}");
            // Detections have no track id (a ROS 2 fixture's Detection3D.id is the truth id).
            if !what.ends_with("detections") {
                assert_eq!(b[0].as_u64(), Some(w.0), "{at}: id");
            }
            assert_eq!(b[1], w.1.as_str(), "{at}: label");
            assert!((f(&b[2]) - w.2).abs() <= 1e-9, "{at}: score");
            for k in 0..6 {
                assert!((f(&b[3 + k]) - w.3[k]).abs() <= 1e-9, "{at}: geometry {k}");
            }
            let dyaw = (f(&b[9]) - w.4).rem_euclid(std::f64::consts::TAU);
            assert!(dyaw.min(std::f64::consts::TAU - dyaw) <= 1e-9, "{at}: yaw");
            // Detections: no velocity drawn (probmot's may carry one, the others none).
            match w.5 {
                _ if what.ends_with("detections") => {}
                Some(v) => {
                    let gv: Vec<f64> = b[10].as_array().unwrap().iter().map(f).collect();
                    assert_eq!(gv, v, "{at}: velocity");
                }
                None => assert!(b[10].is_null(), "{at}: no velocity"),
            }
        }
    }
}

/// A copy of `input` with its probmot.Detections3D messages as JSON (message encoding `json`).
pub(crate) fn json_copy(input: &Path, out: &Path) {
    let file = std::fs::File::create(out).unwrap();
    let mut w = mcap::Writer::new(std::io::BufWriter::new(file)).unwrap();
    let s = w
        .add_schema(probmot::msgs::DETECTIONS_SCHEMA, "jsonschema", b"{}")
        .unwrap();
    let ch = w
        .add_channel(s, "/detections", "json", &Default::default())
        .unwrap();
    let frames = detections(input, "/detections");
    let times = messages(input)
        .into_iter()
        .filter(|m| m.topic == "/detections");
    for (i, (f, m)) in frames.iter().zip(times).enumerate() {
        let header = mcap::records::MessageHeader {
            channel_id: ch,
            sequence: i as u32,
            log_time: m.log_time,
            publish_time: m.log_time,
        };
        let data = serde_json::to_vec(f).unwrap();
        w.write_to_known_channel(&header, &data).unwrap();
    }
    w.finish().unwrap();
}

/// `to_rerun.py` reads what `track` reads: the detections of the ROS 2 (CDR, vision_msgs 4.x and
/// 2.x) and Foxglove (SceneUpdate) fixtures and of a JSON log decode to the boxes of the probmot
/// log they were made from, the ROS 2 tracks `track` writes for a ROS 2 input to the tracks of
/// that log, and each converts to a recording the SDK verifies.
#[test]
fn to_rerun_reads_ros2_foxglove_and_json_inputs() {
    if !available("to_rerun_reads_ros2_foxglove_and_json_inputs") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let city = repo("sample_logs/city.mcap");
    let json_log = dir.path().join("city.json.mcap");
    json_copy(&city, &json_log);
    let cases = [
        (
            "ros2",
            repo("tests/fixtures/ros2/city.mcap"),
            city.clone(),
            true,
        ),
        (
            "foxglove",
            repo("tests/fixtures/foxglove/city.mcap"),
            city.clone(),
            false,
        ),
        ("json", json_log.clone(), city.clone(), false),
        (
            "ros2 vision_msgs 2.x",
            repo("tests/fixtures/ros2/turning-car-vision_msgs2.mcap"),
            repo("sample_logs/turning-car.mcap"),
            true,
        ),
    ];
    let tracked: Vec<PathBuf> = cases
        .iter()
        .map(|(name, input, _, _)| {
            let out = dir
                .path()
                .join(format!("{}.tracked.mcap", name.replace(' ', "_")));
            track(input, &out, &[]);
            out
        })
        .collect();
    let read = read_run_boxes(&tracked);
    for ((name, _, source, ros2_tracks), (tracked, got)) in
        cases.iter().zip(tracked.iter().zip(&read))
    {
        let (name, ros2_tracks) = (*name, *ros2_tracks);
        assert_boxes(
            &got["detections"],
            &det_boxes(source),
            &format!("{name} detections"),
        );
        // ROS 2 tracks carry no velocity; their boxes are those of the probmot log's tracks
        // (tests/it/ros2_foxglove_input/fixtures.rs: the same tracks to 1e-9).
        let want = if ros2_tracks {
            let reference = dir.path().join("reference.tracked.mcap");
            track(source, &reference, &[]);
            track_boxes(&reference, false)
        } else {
            track_boxes(tracked, true)
        };
        assert_boxes(&got["tracks"], &want, &format!("{name} tracks"));

        // A recording (the slow part) of one CDR and one SceneUpdate input.
        if !matches!(name, "ros2" | "foxglove") {
            continue;
        }
        let rrd = dir.path().join("out.rrd");
        let out = ok(
            python(&[
                &script("to_rerun.py"),
                tracked.to_str().unwrap(),
                "-o",
                rrd.to_str().unwrap(),
            ]),
            "to_rerun.py",
        );
        let said = String::from_utf8_lossy(&out.stdout);
        assert!(said.contains("40 frames"), "{name}: {said}");
        verify(&rrd);
        let summary = inspect(&rrd);
        let boxes: u64 = want.iter().map(|(_, b)| b.len() as u64).sum();
        let tracks_entity = &summary["entities"]["/world/tracks"];
        assert_eq!(tracks_entity["instances"], boxes, "{name}: every track box");
    }
}
