//! Checking Rerun recordings with the pinned Rerun SDK (rerun-sdk 0.36.3 from
//! scripts/requirements.txt): `rerun rrd verify` and `scripts/inspect_rrd.py`, which reads the
//! .rrd back with `rerun.experimental.RrdReader`. Shared by tests/it/rerun_scripts.rs (the Python
//! converters) and tests/rerun_feature.rs (the Rust `rerun` feature), so both are held to the
//! same entities, row counts and top-down view. Included with `#[path]` next to `mod common;`.
#![allow(dead_code)]

use std::path::Path;
use std::process::{Command, Output};

use serde_json::Value;

use crate::common::{detections, probmot_ok, repo, tracks};

/// Whether the tests can run; prints why not.
pub fn available(test: &str) -> bool {
    if crate::common::python_has("rerun, mcap, mcap_protobuf, mcap_ros2") {
        return true;
    }
    crate::common::skip(
        test,
        "`python3 -c \"import rerun, mcap, mcap_protobuf, mcap_ros2\"` failed; install with \
         `python3 -m pip install -r scripts/requirements.txt` (rerun-sdk==0.36.3)",
    );
    false
}

/// Runs `python3` with `args`.
pub fn python(args: &[&str]) -> Output {
    Command::new("python3")
        .args(args)
        .output()
        .expect("run python3")
}

/// Path of a script in `scripts/`.
pub fn script(name: &str) -> String {
    repo(&format!("scripts/{name}")).display().to_string()
}

/// Asserts that a command succeeded; returns its output.
pub fn ok(out: Output, what: &str) -> Output {
    assert!(
        out.status.success(),
        "{what} failed ({}):\n{}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stderr),
        String::from_utf8_lossy(&out.stdout)
    );
    out
}

/// `probmot track INPUT -o OUT --quiet EXTRA...`.
pub fn track(input: &Path, out: &Path, extra: &[&str]) {
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
pub fn verify(rrd: &Path) {
    let out = ok(
        python(&["-m", "rerun", "rrd", "verify", rrd.to_str().unwrap()]),
        "rerun rrd verify",
    );
    let said =
        String::from_utf8_lossy(&out.stderr).to_string() + &String::from_utf8_lossy(&out.stdout);
    assert!(said.contains("verified without error"), "{said}");
}

/// The read-back summary of `scripts/inspect_rrd.py`.
pub fn inspect(rrd: &Path) -> Value {
    let out = ok(
        python(&[&script("inspect_rrd.py"), rrd.to_str().unwrap()]),
        "inspect_rrd.py",
    );
    serde_json::from_slice(&out.stdout).expect("inspect_rrd.py prints JSON")
}

/// What the MCAP file holds, to compare with the recording.
pub struct Expected {
    pub frames: u64,
    pub first_ns: u64,
    pub last_ns: u64,
    pub detections: u64,
    pub tracks: u64,
    pub truth: u64,
}

/// The frames and box counts of a tracked MCAP file.
pub fn expected(mcap: &Path) -> Expected {
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

/// A JSON value as u64.
pub fn u(v: &Value, what: &str) -> u64 {
    v.as_u64()
        .unwrap_or_else(|| panic!("{what}: expected an unsigned integer, got {v}"))
}

/// Checks the entities of one run under `prefix` (`/world`, `/a/world`, ...).
pub fn check_run(summary: &Value, prefix: &str, e: &Expected) {
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
pub fn check_top_down_view(view: &Value, origin: &str) {
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
