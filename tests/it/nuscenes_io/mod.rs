//! `probmot import nuscenes` / `probmot export nuscenes` on the hand-written tables in
//! `tests/fixtures/nuscenes/` (three scenes of 5, 3 and 2 samples; instances: a barrier (outside
//! the tracking classes), two cars and a pedestrian; detection results for the first two scenes).
//! When the nuScenes devkit is installed, exports are also checked with its own loader through
//! `scripts/check_nuscenes_export.py`.
//!
//! One file per area: import, export, and the errors of both; shared helpers here.

mod errors;
mod export;
mod import;
use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use std::process::Command;

use crate::common::{
    detections, devkit_has, devkit_python, messages, probmot, probmot_ok, repo, skip, tracks,
};
use probmot::formats::nuscenes::{
    quaternion_yaw, Submission, EGO_POSE_SCHEMA, NUSCENES_METADATA, SAMPLES_METADATA,
};
use probmot::mcapio::reader::read_records;
use probmot::msgs::{self, Track3D, Tracks3D};
use serde_json::{json, Value};

const CLASSES: [&str; 7] = [
    "bicycle",
    "bus",
    "car",
    "motorcycle",
    "pedestrian",
    "trailer",
    "truck",
];

/// Equal to 1e-12 relative.
fn close(a: &[f64], b: &[f64]) {
    assert_eq!(a.len(), b.len());
    for (x, y) in a.iter().zip(b) {
        assert!((x - y).abs() <= 1e-12 * y.abs().max(1.0), "{a:?} vs {b:?}");
    }
}

fn fixtures() -> PathBuf {
    repo("tests/fixtures/nuscenes")
}

fn load(name: &str) -> Value {
    serde_json::from_str(&std::fs::read_to_string(fixtures().join(name)).unwrap()).unwrap()
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Sample tokens and timestamps (µs) of a scene, in chain order.
fn scene_chain(scene_name: &str) -> Vec<(String, u64)> {
    let samples: HashMap<String, Value> = load("sample.json")
        .as_array()
        .unwrap()
        .iter()
        .map(|s| (s["token"].as_str().unwrap().to_string(), s.clone()))
        .collect();
    let scene = load("scene.json")
        .as_array()
        .unwrap()
        .iter()
        .find(|s| s["name"] == scene_name)
        .unwrap()
        .clone();
    let mut out = Vec::new();
    let mut tok = scene["first_sample_token"].as_str().unwrap().to_string();
    while !tok.is_empty() {
        let s = &samples[&tok];
        out.push((tok.clone(), s["timestamp"].as_u64().unwrap()));
        tok = s["next"].as_str().unwrap().to_string();
    }
    out
}

fn import(out_dir: &Path) {
    let f = fixtures();
    probmot_ok(&[
        "import",
        "nuscenes",
        "--detections",
        s(&f.join("results.json")),
        "--meta",
        s(&f),
        "-o",
        s(out_dir),
    ]);
}

fn metadata(path: &Path) -> BTreeMap<String, BTreeMap<String, String>> {
    let mut out = BTreeMap::new();
    read_records(path, |rec, _| {
        if let mcap::records::Record::Metadata(m) = rec {
            out.insert(m.name, m.metadata);
        }
        Ok(())
    })
    .unwrap();
    out
}

fn read_submission(path: &Path) -> (Value, Submission) {
    let text = std::fs::read_to_string(path).unwrap();
    (
        serde_json::from_str(&text).unwrap(),
        serde_json::from_str(&text).unwrap(),
    )
}

/// Runs `scripts/check_nuscenes_export.py` when the devkit is importable; `None` (with a message)
/// when it is not.
fn devkit_check(results: &Path, extra: &[&str]) -> Option<std::process::Output> {
    static HAVE_DEVKIT: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    let have = *HAVE_DEVKIT.get_or_init(|| devkit_has("nuscenes"));
    if !have {
        skip(
            &format!("the devkit check of {}", results.display()),
            "`$PROBMOT_DEVKIT_PYTHON -c \"import nuscenes\"` failed (default python3; \
             pip install -r scripts/requirements-devkit.txt in a venv to run it)",
        );
        return None;
    }
    let out = Command::new(devkit_python())
        .arg(repo("scripts/check_nuscenes_export.py"))
        .arg(results)
        .arg("--meta")
        .arg(fixtures())
        .args(extra)
        .output()
        .expect("run python3");
    Some(out)
}

fn assert_devkit_accepts(results: &Path) {
    if let Some(out) = devkit_check(results, &[]) {
        assert!(
            out.status.success(),
            "the devkit check refused {}:\n{}\n{}",
            results.display(),
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
    }
}
