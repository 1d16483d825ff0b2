//! `probmot import nuscenes` / `probmot export nuscenes` on the hand-written tables in
//! `tests/fixtures/nuscenes/` (three scenes of 5, 3 and 2 samples; instances: a barrier (outside
//! the tracking classes), two cars and a pedestrian; detection results for the first two scenes).
//! When the nuScenes devkit is installed, exports are also checked with its own loader through
//! `scripts/check_nuscenes_export.py`.

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

#[test]
fn import_writes_one_file_per_scene_with_frames_boxes_and_metadata() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("imported");
    import(&out);
    let mut files: Vec<String> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    files.sort();
    // scene-0003 has no sample in the results: not written.
    assert_eq!(files, ["scene-0001.mcap", "scene-0002.mcap"]);

    let results = load("results.json");
    for scene in ["scene-0001", "scene-0002"] {
        let path = out.join(format!("{scene}.mcap"));
        let chain = scene_chain(scene);
        let stamps: Vec<u64> = chain.iter().map(|(_, t)| t * 1000).collect();

        // Metadata records.
        let md = metadata(&path);
        assert_eq!(md[NUSCENES_METADATA]["scene_name"], scene);
        let samples: Vec<(u64, String)> = md[SAMPLES_METADATA]
            .iter()
            .map(|(k, v)| (k.parse().unwrap(), v.clone()))
            .collect();
        let expect: Vec<(u64, String)> =
            chain.iter().map(|(t, us)| (us * 1000, t.clone())).collect();
        assert_eq!(samples, expect);

        // Detections: one message per sample, in time order, with the sample's stamp.
        let all = messages(&path);
        let det_msgs: Vec<_> = all.iter().filter(|m| m.topic == "/detections").collect();
        assert_eq!(
            det_msgs.iter().map(|m| m.log_time).collect::<Vec<_>>(),
            stamps
        );
        let dets = detections(&path, "/detections");
        for (d, (tok, t_us)) in dets.iter().zip(&chain) {
            assert_eq!(d.stamp, Some(t_us * 1000));
            assert_eq!(d.frame_id, "nuscenes_global");
            let want = results["results"][tok].as_array().unwrap();
            assert_eq!(d.detections.len(), want.len(), "{tok}");
            for (got, w) in d.detections.iter().zip(want) {
                let c = got.center.unwrap();
                let sz = got.size.unwrap();
                let v = got.velocity.unwrap();
                let f = |v: &Value, i: usize| v.as_array().unwrap()[i].as_f64().unwrap();
                assert_eq!(
                    [c.x, c.y, c.z],
                    [
                        f(&w["translation"], 0),
                        f(&w["translation"], 1),
                        f(&w["translation"], 2)
                    ]
                );
                // size [w, l, h] -> length l, width w, height h
                assert_eq!(sz.width, f(&w["size"], 0));
                assert_eq!(sz.length, f(&w["size"], 1));
                assert_eq!(sz.height, f(&w["size"], 2));
                let q = [0, 1, 2, 3].map(|i| f(&w["rotation"], i));
                // Fixture quaternions are pure yaw: yaw = 2 atan2(z, w).
                assert!((got.yaw - 2.0 * q[3].atan2(q[0])).abs() < 1e-12);
                assert_eq!(got.label, w["detection_name"].as_str().unwrap());
                assert_eq!(got.score, w["detection_score"].as_f64().unwrap());
                assert_eq!(
                    [v.x, v.y, v.z],
                    [f(&w["velocity"], 0), f(&w["velocity"], 1), 0.0]
                );
                assert_eq!(got.attributes["nuscenes_sample_token"], *tok);
                assert_eq!(
                    got.attributes["nuscenes_attribute_name"],
                    w["attribute_name"].as_str().unwrap()
                );
            }
        }

        // Ego poses: the LIDAR_TOP key frame's pose (not the camera's, not a sweep's).
        let ego: Vec<_> = all.iter().filter(|m| m.topic == "/ego_pose").collect();
        assert_eq!(ego.len(), chain.len());
        let poses: HashMap<String, Value> = load("ego_pose.json")
            .as_array()
            .unwrap()
            .iter()
            .map(|p| (p["token"].as_str().unwrap().to_string(), p.clone()))
            .collect();
        for (m, (tok, t_us)) in ego.iter().zip(&chain) {
            assert_eq!(m.schema, EGO_POSE_SCHEMA);
            assert_eq!(m.message_encoding, "json");
            assert_eq!(m.log_time, t_us * 1000);
            let v: Value = serde_json::from_slice(&m.data).unwrap();
            assert_eq!(v["stamp"].as_u64(), Some(t_us * 1000));
            let lidar = &poses[&format!("ep-lidar-{}", &tok["sample-".len()..])];
            assert_eq!(v["translation"], lidar["translation"]);
            assert_eq!(v["rotation"], lidar["rotation"]);
        }
    }

    // The last sample of scene-0002 has an empty result list: an empty message.
    let d2 = detections(&out.join("scene-0002.mcap"), "/detections");
    assert_eq!(d2.len(), 3);
    assert!(d2[2].detections.is_empty());

    // Ground truth: ids from the instance table's order, tracking classes only.
    let gt = tracks(&out.join("scene-0001.mcap"), "/ground_truth");
    assert_eq!(gt.len(), 5);
    let ids: Vec<Vec<(u64, String)>> = gt
        .iter()
        .map(|t| t.tracks.iter().map(|x| (x.id, x.label.clone())).collect())
        .collect();
    assert_eq!(
        ids[0],
        [(2, "car".to_string()), (3, "pedestrian".to_string())]
    );
    assert_eq!(ids[4], [(2, "car".to_string())]);
    let car = &gt[0].tracks[0];
    assert_eq!(car.attributes["nuscenes_instance_token"], "inst-car-1");
    assert_eq!(car.attributes["nuscenes_category"], "vehicle.car");
    assert_eq!(car.attributes["nuscenes_num_lidar_pts"], "40");
    assert!((car.yaw - 0.1).abs() < 1e-12);
    // Velocity from the neighbouring annotations, like the devkit: 2.5 m over 0.49987 s.
    let v = car.velocity.unwrap();
    assert!((v.x - 2.5 / 0.499870).abs() < 1e-9, "{v:?}");
    let gt2 = tracks(&out.join("scene-0002.mcap"), "/ground_truth");
    // The annotation at b2 stores the negated quaternion: same yaw.
    for t in &gt2 {
        assert_eq!(t.tracks.len(), 1);
        assert_eq!(t.tracks[0].id, 4);
        assert!(
            (t.tracks[0].yaw - -2.8).abs() < 1e-12,
            "{}",
            t.tracks[0].yaw
        );
    }
}

#[test]
fn scene_selection_and_stdout_summary() {
    let dir = tempfile::tempdir().unwrap();
    let f = fixtures();
    let out = probmot_ok(&[
        "import",
        "nuscenes",
        "--detections",
        s(&f.join("results.json")),
        "--meta",
        s(&f),
        "-o",
        s(dir.path()),
        "--scene",
        "scene-0002",
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains(
            "1 scenes, 3 frames, 4 detections, 0 track boxes, 0 bicycle racks, 3 ground-truth boxes"
        ),
        "{stdout}"
    );
    assert!(dir.path().join("scene-0002.mcap").is_file());
    assert!(!dir.path().join("scene-0001.mcap").exists());

    let bad = probmot(&[
        "import",
        "nuscenes",
        "--detections",
        s(&f.join("results.json")),
        "--meta",
        s(&f),
        "-o",
        s(dir.path()),
        "--scene",
        "scene-9999",
    ]);
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("no scene named scene-9999"));
}

#[test]
fn track_then_export_is_a_valid_submission() {
    let dir = tempfile::tempdir().unwrap();
    let imported = dir.path().join("imported");
    let tracked = dir.path().join("tracked");
    std::fs::create_dir(&tracked).unwrap();
    import(&imported);
    let inputs = [
        imported.join("scene-0001.mcap"),
        imported.join("scene-0002.mcap"),
    ];
    let mut args = vec!["track", "-q", "--out-dir", s(&tracked)];
    args.extend(inputs.iter().map(|p| s(p)));
    probmot_ok(&args);
    let out_json = dir.path().join("tracking_results.json");
    let t1 = tracked.join("scene-0001.mcap");
    let t2 = tracked.join("scene-0002.mcap");
    let out = probmot_ok(&[
        "export",
        "nuscenes",
        s(&t1),
        s(&t2),
        "-o",
        s(&out_json),
        "--meta",
        s(&fixtures()),
    ]);
    // The traffic cones are tracked but are not a tracking class.
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("traffic_cone"), "{stderr}");

    let (raw, sub) = read_submission(&out_json);
    assert_eq!(
        raw["meta"],
        json!({"use_camera": false, "use_lidar": true, "use_radar": false, "use_map": false,
               "use_external": false})
    );
    // Every sample token of both scenes, nothing else.
    let mut want: Vec<String> = scene_chain("scene-0001")
        .into_iter()
        .chain(scene_chain("scene-0002"))
        .map(|(t, _)| t)
        .collect();
    want.sort();
    assert_eq!(sub.results.keys().cloned().collect::<Vec<_>>(), want);
    let mut n = 0;
    for (tok, boxes) in &raw["results"].as_object().unwrap().clone() {
        assert!(boxes.as_array().unwrap().len() <= 500);
        for b in boxes.as_array().unwrap() {
            n += 1;
            assert_eq!(b["sample_token"], *tok);
            assert!(b["tracking_id"].is_string(), "{b}");
            assert!(
                CLASSES.contains(&b["tracking_name"].as_str().unwrap()),
                "{b}"
            );
            assert!(b["tracking_score"].as_f64().unwrap().is_finite());
            assert_eq!(b["size"].as_array().unwrap().len(), 3);
            assert_eq!(b["rotation"].as_array().unwrap().len(), 4);
            assert_eq!(b["velocity"].as_array().unwrap().len(), 2);
        }
    }
    assert!(n > 0);

    // Each exported box is a track of the tracked file: size [w, l, h], yaw, velocity, id.
    for path in [&t1, &t2] {
        let chain: BTreeMap<u64, String> = metadata(path)[SAMPLES_METADATA]
            .iter()
            .map(|(k, v)| (k.parse().unwrap(), v.clone()))
            .collect();
        for frame in tracks(path, "/tracks") {
            let tok = &chain[&frame.stamp];
            let exported = &sub.results[tok];
            let kept: Vec<&Track3D> = frame
                .tracks
                .iter()
                .filter(|t| CLASSES.contains(&t.label.as_str()))
                .collect();
            assert_eq!(exported.len(), kept.len(), "{tok}");
            for t in kept {
                let b = exported
                    .iter()
                    .find(|b| b.tracking_id == t.id.to_string())
                    .unwrap();
                let c = t.center.unwrap();
                let sz = t.size.unwrap();
                let v = t.velocity.unwrap();
                // serde_json's parser (without `float_roundtrip`) may be 1 ulp off when this
                // test reads the file back, so compare closely rather than exactly.
                close(&b.translation, &[c.x, c.y, c.z]);
                close(&b.size, &[sz.width, sz.length, sz.height]);
                close(&[quaternion_yaw(b.rotation)], &[t.yaw]);
                close(&b.velocity, &[v.x, v.y]);
                assert_eq!(b.tracking_name, t.label);
                close(&[b.tracking_score], &[t.score]);
            }
        }
    }
    assert_devkit_accepts(&out_json);
}

#[test]
fn export_caps_each_sample_at_500_boxes_keeping_the_highest_scores() {
    let dir = tempfile::tempdir().unwrap();
    // The fixture results plus 600 well-separated cars in the first sample of scene-0001.
    let mut results = load("results.json");
    let a1 = results["results"]["sample-a1"].as_array_mut().unwrap();
    for i in 0..600 {
        let yaw: f64 = 0.01 * i as f64;
        a1.push(json!({
            "sample_token": "sample-a1",
            "translation": [1000.0 + 12.0 * (i % 25) as f64, 2000.0 + 12.0 * (i / 25) as f64, 1.0],
            "size": [1.9, 4.5, 1.6],
            "rotation": [(yaw / 2.0).cos(), 0.0, 0.0, (yaw / 2.0).sin()],
            "velocity": [0.0, 0.0],
            "detection_name": "car",
            "detection_score": 0.0005 * (i + 1) as f64,
            "attribute_name": "vehicle.parked",
        }));
    }
    let res_path = dir.path().join("results600.json");
    std::fs::write(&res_path, serde_json::to_vec(&results).unwrap()).unwrap();
    let imported = dir.path().join("imported");
    let f = fixtures();
    probmot_ok(&[
        "import",
        "nuscenes",
        "--detections",
        s(&res_path),
        "--meta",
        s(&f),
        "-o",
        s(&imported),
        "--scene",
        "scene-0001",
    ]);
    let tracked = dir.path().join("scene-0001.tracked.mcap");
    probmot_ok(&[
        "track",
        "-q",
        s(&imported.join("scene-0001.mcap")),
        "-o",
        s(&tracked),
    ]);
    let out_json = dir.path().join("capped.json");
    let out = probmot_ok(&["export", "nuscenes", s(&tracked), "-o", s(&out_json)]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("more than 500 boxes"), "{stderr}");
    let (_, sub) = read_submission(&out_json);
    let chain: BTreeMap<u64, String> = metadata(&tracked)[SAMPLES_METADATA]
        .iter()
        .map(|(k, v)| (k.parse().unwrap(), v.clone()))
        .collect();
    let mut capped = 0;
    let mut dropped = 0;
    for frame in tracks(&tracked, "/tracks") {
        let tok = &chain[&frame.stamp];
        let exported = &sub.results[tok];
        assert!(exported.len() <= 500);
        let mut all: Vec<f64> = frame
            .tracks
            .iter()
            .filter(|t| CLASSES.contains(&t.label.as_str()))
            .map(|t| t.score)
            .collect();
        if all.len() > 500 {
            capped += 1;
            dropped += all.len() - 500;
            all.sort_by(|a, b| b.total_cmp(a));
            let mut got: Vec<f64> = exported.iter().map(|b| b.tracking_score).collect();
            got.sort_by(|a, b| b.total_cmp(a));
            close(&got, &all[..500]);
        } else {
            assert_eq!(exported.len(), all.len());
        }
    }
    assert!(capped >= 1, "no sample reached the cap");
    assert!(
        stdout.contains(&format!("{dropped} dropped over the 500-per-sample cap")),
        "{stdout}"
    );
    assert_devkit_accepts(&out_json);

    // The check has teeth: 501 boxes in one sample are refused by the devkit's loader.
    let mut raw: Value = serde_json::from_slice(&std::fs::read(&out_json).unwrap()).unwrap();
    let list = raw["results"]["sample-a1"].as_array_mut().unwrap();
    let extra = list[0].clone();
    list.push(extra);
    let bad = dir.path().join("bad.json");
    std::fs::write(&bad, serde_json::to_vec(&raw).unwrap()).unwrap();
    if let Some(o) = devkit_check(&bad, &[]) {
        assert!(!o.status.success());
        assert!(String::from_utf8_lossy(&o.stdout).contains("500"));
    }
}

#[test]
fn ground_truth_round_trips_through_import_and_export() {
    let dir = tempfile::tempdir().unwrap();
    let imported = dir.path().join("imported");
    import(&imported);
    let out_json = dir.path().join("gt.json");
    probmot_ok(&[
        "export",
        "nuscenes",
        s(&imported.join("scene-0001.mcap")),
        s(&imported.join("scene-0002.mcap")),
        "--topic",
        "/ground_truth",
        "-o",
        s(&out_json),
    ]);
    let (_, sub) = read_submission(&out_json);
    let instances: Vec<Value> = load("instance.json").as_array().unwrap().clone();
    let categories: HashMap<String, String> = load("category.json")
        .as_array()
        .unwrap()
        .iter()
        .map(|c| {
            (
                c["token"].as_str().unwrap().to_string(),
                c["name"].as_str().unwrap().to_string(),
            )
        })
        .collect();
    let mut checked = 0;
    for ann in load("sample_annotation.json").as_array().unwrap() {
        let (idx, inst) = instances
            .iter()
            .enumerate()
            .find(|(_, i)| i["token"] == ann["instance_token"])
            .unwrap();
        let cat = &categories[inst["category_token"].as_str().unwrap()];
        let boxes = &sub.results[ann["sample_token"].as_str().unwrap()];
        let found = boxes
            .iter()
            .find(|b| b.tracking_id == (idx + 1).to_string());
        if cat == "movable_object.barrier" {
            assert!(found.is_none());
            continue;
        }
        let b = found.unwrap_or_else(|| panic!("annotation {} not exported", ann["token"]));
        let arr = |k: &str| -> Vec<f64> {
            ann[k]
                .as_array()
                .unwrap()
                .iter()
                .map(|x| x.as_f64().unwrap())
                .collect()
        };
        for (a, e) in b.translation.iter().zip(arr("translation")) {
            assert!((a - e).abs() < 1e-9);
        }
        for (a, e) in b.size.iter().zip(arr("size")) {
            assert!((a - e).abs() < 1e-9);
        }
        // q and -q are the same rotation.
        let q = arr("rotation");
        let sign = if q[0] * b.rotation[0] + q[3] * b.rotation[3] < 0.0 {
            -1.0
        } else {
            1.0
        };
        for (a, e) in b.rotation.iter().zip(&q) {
            assert!((a - sign * e).abs() < 1e-9, "{:?} vs {q:?}", b.rotation);
        }
        assert_eq!(
            b.tracking_name,
            if cat == "vehicle.car" {
                "car"
            } else {
                "pedestrian"
            }
        );
        assert_eq!(b.tracking_score, 1.0);
        checked += 1;
    }
    assert_eq!(checked, 12);
    assert_devkit_accepts(&out_json);
}

/// Copies the fixture tables to a temporary directory, for editing.
fn fixture_copy() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    for e in std::fs::read_dir(fixtures()).unwrap() {
        let e = e.unwrap();
        std::fs::copy(e.path(), dir.path().join(e.file_name())).unwrap();
    }
    dir
}

fn import_err(meta: &Path, results: &Path, out: &Path) -> String {
    let o = probmot(&[
        "import",
        "nuscenes",
        "--detections",
        s(results),
        "--meta",
        s(meta),
        "-o",
        s(out),
    ]);
    assert!(!o.status.success(), "import should have failed");
    let no_files = std::fs::read_dir(out)
        .map(|d| d.count() == 0)
        .unwrap_or(true);
    assert!(no_files, "a failed import left files in {}", out.display());
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn import_errors_name_the_file_and_token() {
    // A results token that is not a sample.
    let t = fixture_copy();
    let mut r = load("results.json");
    r["results"]["sample-zz"] = json!([]);
    let rp = t.path().join("results.json");
    std::fs::write(&rp, serde_json::to_vec(&r).unwrap()).unwrap();
    let e = import_err(t.path(), &rp, &t.path().join("out1"));
    assert!(
        e.contains("sample-zz") && e.contains("results.json") && e.contains("sample.json"),
        "{e}"
    );

    // Missing scene.json.
    let t = fixture_copy();
    std::fs::remove_file(t.path().join("scene.json")).unwrap();
    let e = import_err(
        t.path(),
        &t.path().join("results.json"),
        &t.path().join("o"),
    );
    assert!(e.contains("scene.json"), "{e}");

    // Annotations without the instance table.
    let t = fixture_copy();
    std::fs::remove_file(t.path().join("instance.json")).unwrap();
    let e = import_err(
        t.path(),
        &t.path().join("results.json"),
        &t.path().join("o"),
    );
    assert!(e.contains("instance.json"), "{e}");

    // A broken sample chain.
    let t = fixture_copy();
    let text = std::fs::read_to_string(t.path().join("sample.json")).unwrap();
    let text = text.replace("\"next\": \"sample-a3\"", "\"next\": \"sample-gone\"");
    std::fs::write(t.path().join("sample.json"), text).unwrap();
    let e = import_err(
        t.path(),
        &t.path().join("results.json"),
        &t.path().join("o"),
    );
    assert!(
        e.contains("sample-gone") && e.contains("sample.json") && e.contains("scene-0001"),
        "{e}"
    );

    // An annotation of an unknown instance.
    let t = fixture_copy();
    let text = std::fs::read_to_string(t.path().join("sample_annotation.json")).unwrap();
    let text = text.replacen("\"inst-ped-1\"", "\"inst-nobody\"", 1);
    std::fs::write(t.path().join("sample_annotation.json"), text).unwrap();
    let e = import_err(
        t.path(),
        &t.path().join("results.json"),
        &t.path().join("o"),
    );
    assert!(
        e.contains("inst-nobody") && e.contains("instance.json"),
        "{e}"
    );

    // A sample without a LIDAR_TOP key frame (scene-0003 has no sample_data).
    let t = fixture_copy();
    let o = probmot(&[
        "import",
        "nuscenes",
        "--detections",
        s(&t.path().join("results.json")),
        "--meta",
        s(t.path()),
        "-o",
        s(&t.path().join("o")),
        "--scene",
        "scene-0003",
    ]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        e.contains("sample-c1") && e.contains("sample_data.json"),
        "{e}"
    );
}

/// Writes a minimal MCAP with one Tracks3D message at `stamp` on /tracks and, optionally, the
/// samples metadata record naming `sample-x` at `sample_stamp`.
fn write_tracks_file(path: &Path, stamp: u64, score: f64, sample_stamp: Option<u64>) {
    let mut w = mcap::Writer::new(std::io::BufWriter::new(
        std::fs::File::create(path).unwrap(),
    ))
    .unwrap();
    let sid = w
        .add_schema(msgs::TRACKS_SCHEMA, "protobuf", msgs::DESCRIPTOR_SET)
        .unwrap();
    let cid = w
        .add_channel(sid, "/tracks", "protobuf", &BTreeMap::new())
        .unwrap();
    if let Some(at) = sample_stamp {
        w.write_metadata(&mcap::records::Metadata {
            name: SAMPLES_METADATA.into(),
            metadata: [(at.to_string(), "sample-x".to_string())].into(),
        })
        .unwrap();
    }
    let msg = Tracks3D {
        stamp,
        frame_id: "nuscenes_global".into(),
        tracks: vec![Track3D {
            id: 1,
            label: "car".into(),
            center: Some(msgs::v3([1.0, 2.0, 3.0])),
            size: Some(msgs::Size3 {
                length: 4.0,
                width: 2.0,
                height: 1.5,
            }),
            score,
            ..Default::default()
        }],
    };
    let mut buf = Vec::new();
    msgs::encode_into(&msg, &mut buf);
    w.write_to_known_channel(
        &mcap::records::MessageHeader {
            channel_id: cid,
            sequence: 0,
            log_time: stamp,
            publish_time: stamp,
        },
        &buf,
    )
    .unwrap();
    w.finish().unwrap();
}

#[test]
fn export_refuses_nan_scores_foreign_files_and_repeated_scenes() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.json");

    let nan = dir.path().join("nan.mcap");
    write_tracks_file(&nan, 1_000, f64::NAN, Some(1_000));
    let o = probmot(&["export", "nuscenes", s(&nan), "-o", s(&out)]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        e.contains("NaN") && e.contains("nan.mcap") && e.contains("sample-x"),
        "{e}"
    );
    assert!(!out.exists());

    let foreign = dir.path().join("foreign.mcap");
    write_tracks_file(&foreign, 1_000, 0.5, None);
    let o = probmot(&["export", "nuscenes", s(&foreign), "-o", s(&out)]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        e.contains(SAMPLES_METADATA) && e.contains("foreign.mcap"),
        "{e}"
    );

    let ok = dir.path().join("ok.mcap");
    write_tracks_file(&ok, 1_000, 0.5, Some(1_000));
    let o = probmot(&["export", "nuscenes", s(&ok), s(&ok), "-o", s(&out)]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("sample-x") && e.contains("both"), "{e}");
    probmot_ok(&["export", "nuscenes", s(&ok), "-o", s(&out), "--use-camera"]);
    let (raw, sub) = read_submission(&out);
    assert_eq!(raw["meta"]["use_camera"], true);
    assert_eq!(sub.results["sample-x"][0].size, [2.0, 4.0, 1.5]);

    // A frame whose stamp is not a sample of the scene.
    let off = dir.path().join("off.mcap");
    write_tracks_file(&off, 1_000, 0.5, Some(2_000));
    let o = probmot(&["export", "nuscenes", s(&off), "-o", s(&out)]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("stamp 1000") && e.contains("off.mcap"), "{e}");

    // --meta checks each input's scene against the tables.
    let o = probmot(&[
        "export",
        "nuscenes",
        s(&ok),
        "-o",
        s(&out),
        "--meta",
        s(&fixtures()),
    ]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("scene_token") && e.contains("ok.mcap"), "{e}");
}

#[test]
fn eval_range_filter_reads_the_imported_ego_poses() {
    // Import, track, and evaluate with --max-range: the filter takes the ego position of each
    // frame from the /ego_pose channel that the import wrote (kept in the tracked file).
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("imported");
    import(&out);
    let input = out.join("scene-0001.mcap");
    let tracked = dir.path().join("scene-0001.tracked.mcap");
    probmot_ok(&["track", s(&input), "-o", s(&tracked), "--quiet"]);
    let ego: HashMap<u64, [f64; 3]> = messages(&tracked)
        .iter()
        .filter(|m| m.topic == "/ego_pose")
        .map(|m| {
            let v: Value = serde_json::from_slice(&m.data).unwrap();
            let t = &v["translation"];
            (
                v["stamp"].as_u64().unwrap(),
                [0, 1, 2].map(|k| t[k].as_f64().unwrap()),
            )
        })
        .collect();
    let truth = tracks(&tracked, "/ground_truth");
    let dists: Vec<f64> = truth
        .iter()
        .flat_map(|f| {
            let p = ego[&f.stamp];
            f.tracks
                .iter()
                .filter(|t| CLASSES.contains(&t.label.as_str()))
                .map(move |t| {
                    let c = t.center.unwrap();
                    (c.x - p[0]).hypot(c.y - p[1])
                })
        })
        .collect();
    assert!(!dists.is_empty());
    let mut sorted = dists.clone();
    sorted.sort_by(f64::total_cmp);
    // Three ranges: beyond every box, through the middle, below every box.
    for range in [
        sorted[sorted.len() - 1] + 1.0,
        sorted[sorted.len() / 2],
        sorted[0] * 0.5,
    ] {
        let want = dists.iter().filter(|d| **d >= range).count() as u64;
        let r = probmot(&[
            "eval",
            "--truth",
            s(&tracked),
            "--json",
            "--max-range",
            &format!("{range}"),
        ]);
        if want == dists.len() as u64 {
            // Nothing left to evaluate: a clear error, not numbers.
            assert_eq!(r.status.code(), Some(2));
            assert!(String::from_utf8_lossy(&r.stderr).contains("no ground-truth box"));
            continue;
        }
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        let v: Value = serde_json::from_slice(&r.stdout).unwrap();
        assert_eq!(
            v["range_filter"]["removed_truth_boxes"],
            json!(want),
            "range {range}"
        );
    }
}

#[test]
fn import_reads_every_float_exactly_and_writes_a_tracking_submission_as_tracks() {
    // 17-digit numbers that serde_json's default (fast, inexact) float parser reads one ulp off;
    // Rust's own parser (`str::parse`, correctly rounded) is the reference.
    let xs: [f64; 3] = [
        "93.66745596122337".parse().unwrap(),
        "-1462.8248718212421".parse().unwrap(),
        "1681.5221252502379".parse().unwrap(),
    ];
    let ts: [f64; 3] = [
        "411.05632224727196".parse().unwrap(),
        "93.66745596122337".parse().unwrap(),
        "-1462.8248718212421".parse().unwrap(),
    ];
    let dir = tempfile::tempdir().unwrap();
    let det = dir.path().join("det.json");
    let trk = dir.path().join("trk.json");
    let meta = json!({"use_camera": false, "use_lidar": true, "use_radar": false,
                      "use_map": false, "use_external": false});
    // Written as text so that the digits are exactly the ones above.
    let rot = "[1.0, 0.0, 0.0, 0.0]";
    std::fs::write(
        &det,
        format!(
            r#"{{"meta": {meta}, "results": {{"sample-b1": [{{"sample_token": "sample-b1",
            "translation": [93.66745596122337, -1462.8248718212421, 1681.5221252502379],
            "size": [1.9, 4.5, 1.65], "rotation": {rot}, "velocity": [0.0, 0.0],
            "detection_name": "car", "detection_score": 0.5, "attribute_name": ""}}]}}}}"#
        ),
    )
    .unwrap();
    std::fs::write(
        &trk,
        format!(
            r#"{{"meta": {meta}, "results": {{"sample-b1": [{{"sample_token": "sample-b1",
            "translation": [411.05632224727196, 93.66745596122337, -1462.8248718212421],
            "size": [1.9, 4.5, 1.65], "rotation": {rot}, "velocity": [0.0, 0.0],
            "tracking_id": "abc", "tracking_name": "car", "tracking_score": 0.7}},
            {{"sample_token": "sample-b1", "translation": [1.0, 2.0, 3.0],
            "size": [0.7, 0.7, 1.8], "rotation": {rot}, "velocity": [0.0, 0.0],
            "tracking_id": "xyz", "tracking_name": "pedestrian", "tracking_score": 0.4}}],
            "sample-b3": [{{"sample_token": "sample-b3", "translation": [5.0, 6.0, 1.0],
            "size": [1.9, 4.5, 1.65], "rotation": {rot}, "velocity": [0.0, 0.0],
            "tracking_id": "abc", "tracking_name": "car", "tracking_score": 0.9}}]}}}}"#
        ),
    )
    .unwrap();
    let out = dir.path().join("out");
    probmot_ok(&[
        "import",
        "nuscenes",
        "--detections",
        s(&det),
        "--tracks",
        s(&trk),
        "--meta",
        s(&fixtures()),
        "-o",
        s(&out),
    ]);
    let file = out.join("scene-0002.mcap");
    let d = &detections(&file, "/detections")[0].detections[0];
    let c = d.center.unwrap();
    assert_eq!([c.x, c.y, c.z], xs);
    let t = tracks(&file, "/tracks");
    assert_eq!(t.len(), 3, "one message per sample");
    let c = t[0].tracks[0].center.unwrap();
    assert_eq!([c.x, c.y, c.z], ts);
    // Ids 1, 2, ... per scene in order of appearance; class, score and the original id kept.
    let ids: Vec<Vec<(u64, &str, f64)>> = t
        .iter()
        .map(|m| {
            m.tracks
                .iter()
                .map(|b| (b.id, b.label.as_str(), b.score))
                .collect()
        })
        .collect();
    assert_eq!(
        ids,
        vec![
            vec![(1, "car", 0.7), (2, "pedestrian", 0.4)],
            vec![],
            vec![(1, "car", 0.9)]
        ]
    );
    assert_eq!(t[2].tracks[0].attributes["nuscenes_tracking_id"], "abc");
    // Ground truth is there too, and a (here empty) bicycle-rack channel per sample.
    assert_eq!(tracks(&file, "/bicycle_racks").len(), 3);
    assert!(!tracks(&file, "/ground_truth").is_empty());
    // Only --tracks: no /detections channel.
    let only = dir.path().join("only");
    probmot_ok(&[
        "import",
        "nuscenes",
        "--tracks",
        s(&trk),
        "--meta",
        s(&fixtures()),
        "-o",
        s(&only),
    ]);
    let m = messages(&only.join("scene-0002.mcap"));
    assert!(m.iter().all(|m| m.topic != "/detections"));
    // A submission box of an unknown class is a clear error.
    std::fs::write(
        &trk,
        std::fs::read_to_string(&trk)
            .unwrap()
            .replace("\"pedestrian\"", "\"dog\""),
    )
    .unwrap();
    let r = probmot(&[
        "import",
        "nuscenes",
        "--tracks",
        s(&trk),
        "--meta",
        s(&fixtures()),
        "-o",
        s(&only),
    ]);
    assert!(!r.status.success());
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        err.contains("results[sample-b1][1]") && err.contains("'dog'"),
        "{err}"
    );
}
