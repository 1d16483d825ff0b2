//! `probmot export nuscenes`: a valid submission, the 500-box cap, and ground truth round trips.

use super::*;

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
