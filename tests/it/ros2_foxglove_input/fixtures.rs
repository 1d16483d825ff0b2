//! The ROS 2 and Foxglove fixtures (written by other tools from `sample_logs/city.mcap`) decode
//! to the probmot log's boxes and track exactly like it.

use super::*;

#[test]
fn ros2_and_foxglove_fixtures_track_exactly_like_the_probmot_log() {
    let dir = tempfile::tempdir().unwrap();
    for (name, fixture, log, min_reports) in [
        ("ros2", ROS2_FIXTURE, PROBMOT_LOG, 500),
        ("foxglove", FOXGLOVE_FIXTURE, PROBMOT_LOG, 500),
        ("ros2 vision_msgs 2.x", ROS2_V2_FIXTURE, PROBMOT_V2_LOG, 150),
    ] {
        let reference = dir.path().join("probmot.mcap");
        track(&repo(log), &reference);
        let want = tracks(&reference, "/tracks");
        let out = dir.path().join("other.mcap");
        track(&repo(fixture), &out);
        let got = tracks(&out, "/tracks");
        assert_same_tracks(&got, &want, name, min_reports);
        // The input messages are kept byte for byte (beside the tracks and their SceneUpdate).
        let before = messages(&repo(fixture));
        let after: Vec<Msg> = messages(&out)
            .into_iter()
            .filter(|m| m.topic != "/tracks" && m.topic != "/tracks/scene")
            .collect();
        assert_eq!(before, after, "{name}: input messages changed");
    }
}

#[test]
fn fixtures_decode_to_the_boxes_of_the_probmot_log() {
    for (name, fixture, log) in [
        ("ros2", ROS2_FIXTURE, PROBMOT_LOG),
        ("foxglove", FOXGLOVE_FIXTURE, PROBMOT_LOG),
        ("ros2 vision_msgs 2.x", ROS2_V2_FIXTURE, PROBMOT_V2_LOG),
    ] {
        let want = detections(&repo(log), "/detections");
        let bytes = std::fs::read(repo(fixture)).unwrap();
        let mut frames = vec![];
        for m in mcap::MessageStream::new(&bytes).unwrap() {
            let m = m.unwrap();
            let schema = m.channel.schema.as_ref().unwrap();
            let source = DetectionSource::for_channel(
                &schema.name,
                &schema.encoding,
                &schema.data,
                &m.channel.message_encoding,
            )
            .unwrap();
            frames.push(source.decode(&m.data).unwrap());
        }
        assert_eq!(frames.len(), want.len(), "{name}");
        for (g, w) in frames.iter().zip(&want) {
            assert_eq!(g.stamp, w.stamp, "{name}");
            assert_eq!(g.frame_id, w.frame_id, "{name}");
            assert_eq!(g.detections.len(), w.detections.len(), "{name}");
            for (a, b) in g.detections.iter().zip(&w.detections) {
                assert_eq!(a.label, b.label, "{name}");
                assert_eq!(a.score, b.score, "{name}: scores are copied exactly");
                assert_eq!(a.center, b.center, "{name}: centres are copied exactly");
                assert_eq!(a.size, b.size, "{name}: sizes are copied exactly");
                if name.starts_with("ros2") {
                    assert_eq!(a.attributes.get("id"), b.attributes.get("sim_truth_id"));
                }
                close(a.yaw, b.yaw, name);
            }
        }
    }
}

#[test]
fn info_names_the_detection_channels() {
    for (fixture, how, cars) in [
        (ROS2_FIXTURE, "vision_msgs 4.x layout", 475),
        (FOXGLOVE_FIXTURE, "one box per cube", 475),
        (ROS2_V2_FIXTURE, "vision_msgs 2.x layout", 202),
    ] {
        let out = probmot_ok(&["info", repo(fixture).to_str().unwrap(), "--json"]);
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        let ch = &v["channels"][0];
        assert_eq!(ch["role"], "detections", "{fixture}");
        assert!(
            ch["detections_note"].as_str().unwrap().contains(how),
            "{ch}"
        );
        assert_eq!(ch["per_label"]["car"], cars, "{fixture}");
        assert_eq!(ch["undecodable"], 0, "{fixture}");
        let text = probmot_ok(&["info", repo(fixture).to_str().unwrap()]);
        let text = String::from_utf8(text.stdout).unwrap();
        assert!(
            text.contains("detection channels (read by `track` by default): /detections"),
            "{text}"
        );
    }
}
