//! The viewer-only install: a fresh virtual environment with nothing but
//! `scripts/requirements-view.txt` (`.ci/run` makes it and exports its `python3` as
//! `PROBMOT_VIEW_PYTHON`) runs `scripts/to_rerun.py` on every kind of input the script reads,
//! `scripts/compare_runs.py` and `scripts/read_eval_events.py`, and the recordings pass the
//! pinned SDK's `rerun rrd verify`. Without the variable the test says "skipped" (and fails under
//! CI=true).

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use crate::common::{probmot_ok, repo, skip};
use crate::rerun_scripts::json_copy;
use crate::rerun_scripts::rrd::{ok, script};

/// The viewer environment's python, if `PROBMOT_VIEW_PYTHON` names one.
fn view_python(test: &str) -> Option<String> {
    match std::env::var("PROBMOT_VIEW_PYTHON") {
        Ok(p) if !p.is_empty() => Some(p),
        _ => {
            let why = "PROBMOT_VIEW_PYTHON is not set (.ci/run sets it to the python3 of a venv \
                       made from scripts/requirements-view.txt)";
            skip(test, why);
            None
        }
    }
}

/// Runs the viewer python with `args` and asserts success.
fn run(python: &str, args: &[&str]) -> Output {
    let out = Command::new(python)
        .args(args)
        .output()
        .expect("run the view python");
    ok(out, &format!("{python} {args:?}"))
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// `to_rerun.py INPUT -o OUT.rrd`, then `rerun rrd verify` of the result.
fn convert_and_verify(python: &str, input: &Path, rrd: &Path, what: &str) {
    let out = run(python, &[&script("to_rerun.py"), s(input), "-o", s(rrd)]);
    let said = String::from_utf8_lossy(&out.stdout);
    assert!(said.contains(" frames"), "{what}: {said}");
    let out = run(python, &["-m", "rerun", "rrd", "verify", s(rrd)]);
    let said = String::from_utf8_lossy(&out.stderr) + String::from_utf8_lossy(&out.stdout);
    assert!(said.contains("verified without error"), "{what}: {said}");
}

#[test]
fn the_viewer_environment_runs_the_viewer_scripts_on_every_input() {
    let Some(python) = view_python("the_viewer_environment_runs_the_viewer_scripts_on_every_input")
    else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let json_log = dir.path().join("city.json.mcap");
    json_copy(&repo("sample_logs/city.mcap"), &json_log);
    // Every message kind to_rerun.py reads: probmot protobuf (detections, tracks, ground
    // truth), JSON detections, vision_msgs 4.x and 2.x (detections and ROS 2 tracks) and
    // foxglove.SceneUpdate detections.
    let inputs: [(&str, PathBuf); 5] = [
        ("protobuf", repo("sample_logs/turning-car.mcap")),
        ("json", json_log),
        ("ros2", repo("tests/fixtures/ros2/city.mcap")),
        (
            "ros2_vision_msgs2",
            repo("tests/fixtures/ros2/turning-car-vision_msgs2.mcap"),
        ),
        ("foxglove", repo("tests/fixtures/foxglove/city.mcap")),
    ];
    let mut tracked = Vec::new();
    for (name, input) in &inputs {
        let out = dir.path().join(format!("{name}.tracked.mcap"));
        probmot_ok(&["track", s(input), "-o", s(&out), "--quiet"]);
        convert_and_verify(&python, &out, &dir.path().join(format!("{name}.rrd")), name);
        tracked.push(out);
    }
    // The evaluation's events (/eval/events), and the script that reads them.
    let events = dir.path().join("events.mcap");
    let t = s(&tracked[0]);
    probmot_ok(&["eval", "--truth", t, "--events", s(&events), "--quiet"]);
    convert_and_verify(&python, &events, &dir.path().join("events.rrd"), "events");
    let out = run(&python, &[&script("read_eval_events.py"), s(&events)]);
    let read: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(read["frames"], 40, "{read}");
    // Two runs side by side.
    let both = dir.path().join("both.rrd");
    let out = run(&python, &[&script("compare_runs.py"), t, t, "-o", s(&both)]);
    assert!(String::from_utf8_lossy(&out.stdout).contains("40 frames"));
    let out = run(&python, &["-m", "rerun", "rrd", "verify", s(&both)]);
    let said = String::from_utf8_lossy(&out.stderr) + String::from_utf8_lossy(&out.stdout);
    assert!(said.contains("verified without error"), "{said}");
}

/// Without the packages (`python3 -S`: no site-packages), each viewer script says which file
/// installs them, and how big that install is.
#[test]
fn without_the_packages_the_scripts_point_at_the_viewer_requirements() {
    for name in ["to_rerun.py", "compare_runs.py", "read_eval_events.py"] {
        let out = Command::new("python3")
            .args(["-S", &script(name), "in.mcap", "in.mcap", "-o", "out.rrd"])
            .output()
            .expect("run python3");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{name}: {err}");
        let hint = "pip install -r scripts/requirements-view.txt` (the viewer only, about 770 MB)";
        assert!(err.contains(hint), "{name}: {err}");
    }
}
