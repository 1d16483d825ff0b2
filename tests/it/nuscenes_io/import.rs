//! `probmot import nuscenes`: one file per scene, scene selection, exact floats, and the ego
//! poses that `eval --max-range` reads.

use super::*;

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
