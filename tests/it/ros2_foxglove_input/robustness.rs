//! Robustness and channel selection.

use super::*;

/// The (decoder, message bytes) of every message of a fixture.
fn fixture_messages(fixture: &str) -> Vec<(DetectionSource, Vec<u8>)> {
    let bytes = std::fs::read(repo(fixture)).unwrap();
    mcap::MessageStream::new(&bytes)
        .unwrap()
        .map(|m| {
            let m = m.unwrap();
            let s = m.channel.schema.as_ref().unwrap();
            let source = DetectionSource::for_channel(
                &s.name,
                &s.encoding,
                &s.data,
                &m.channel.message_encoding,
            )
            .unwrap();
            (source, m.data.to_vec())
        })
        .collect()
}

#[test]
fn corrupted_messages_never_panic() {
    // A fixed linear congruential sequence: the same corruptions on every run.
    let mut state: u64 = 0x9E37_79B9_7F4A_7C15;
    let mut next = move || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        state >> 33
    };
    let mut errors = 0;
    let mut runs = 0;
    for fixture in [ROS2_FIXTURE, FOXGLOVE_FIXTURE, ROS2_V2_FIXTURE] {
        for (source, data) in fixture_messages(fixture).into_iter().take(4) {
            for _ in 0..300 {
                let mut d = data.clone();
                match next() % 3 {
                    0 => d.truncate(next() as usize % d.len()),
                    1 => {
                        for _ in 0..1 + next() % 4 {
                            let i = next() as usize % d.len();
                            d[i] = next() as u8;
                        }
                    }
                    _ => {
                        // A length-like field set to a large value.
                        let i = (next() as usize % (d.len() - 4)) & !3;
                        d[i..i + 4].copy_from_slice(&(next() as u32 | 0x8000_0000).to_le_bytes());
                    }
                }
                runs += 1;
                if source.decode(&d).is_err() {
                    errors += 1;
                }
            }
        }
    }
    assert!(
        errors > runs / 4,
        "{errors} of {runs} corrupted messages were refused"
    );
}

#[test]
fn default_selection_leaves_a_sceneupdate_beside_other_detections_out_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("both.mcap");
    {
        let mut w = mcap::Writer::new(std::io::BufWriter::new(
            std::fs::File::create(&path).unwrap(),
        ))
        .unwrap();
        for (fixture, topic) in [(PROBMOT_LOG, "/detections"), (FOXGLOVE_FIXTURE, "/scene")] {
            let bytes = std::fs::read(repo(fixture)).unwrap();
            let mut ch = None;
            for m in mcap::MessageStream::new(&bytes).unwrap() {
                let m = m.unwrap();
                if m.channel.topic != "/detections" {
                    continue;
                }
                let id = *ch.get_or_insert_with(|| {
                    let s = m.channel.schema.as_ref().unwrap();
                    let sid = w.add_schema(&s.name, &s.encoding, &s.data).unwrap();
                    w.add_channel(sid, topic, &m.channel.message_encoding, &BTreeMap::new())
                        .unwrap()
                });
                w.write_to_known_channel(
                    &mcap::records::MessageHeader {
                        channel_id: id,
                        sequence: m.sequence,
                        log_time: m.log_time,
                        publish_time: m.publish_time,
                    },
                    &m.data,
                )
                .unwrap();
            }
        }
        w.finish().unwrap();
    }
    let out = dir.path().join("out.mcap");
    let run = |extra: &[&str]| -> serde_json::Value {
        let _ = std::fs::remove_file(&out);
        track_json(&path, &out, extra)
    };
    // A SceneUpdate is often a drawing of the same boxes: by default it is read only when the
    // log has no other detection channel.
    let v = run(&[]);
    assert_eq!(v["detection_topics"], serde_json::json!(["/detections"]));
    assert_eq!(v["merged_messages"], 0);
    assert_eq!(v["detection_messages"], 40);
    let warned = v["warnings"].as_array().unwrap().iter().any(|w| {
        let w = w.as_str().unwrap();
        w.contains("topic /scene, foxglove.SceneUpdate) is left out")
            && w.contains("--detections-topic")
    });
    assert!(warned, "{v}");
    // Both named: merged, with the warning about different kinds.
    let v = run(&[
        "--detections-topic",
        "/detections",
        "--detections-topic",
        "/scene",
    ]);
    assert_eq!(
        v["detection_topics"],
        serde_json::json!(["/detections", "/scene"])
    );
    assert_eq!(v["merged_messages"], 40, "the two topics share every stamp");
    let v = run(&["--detections-topic", "/scene"]);
    assert_eq!(v["detection_topics"], serde_json::json!(["/scene"]));
    assert_eq!(v["warnings"], serde_json::json!([]));
}

#[test]
fn unreadable_channels_are_left_out_of_the_default_selection_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("mixed.mcap");
    {
        let mut w = mcap::Writer::new(std::io::BufWriter::new(
            std::fs::File::create(&path).unwrap(),
        ))
        .unwrap();
        let bytes = std::fs::read(repo(ROS2_FIXTURE)).unwrap();
        let mut ch = None;
        for m in mcap::MessageStream::new(&bytes).unwrap() {
            let m = m.unwrap();
            let id = *ch.get_or_insert_with(|| {
                let s = m.channel.schema.as_ref().unwrap();
                let sid = w.add_schema(&s.name, &s.encoding, &s.data).unwrap();
                w.add_channel(sid, "/objects", "cdr", &BTreeMap::new())
                    .unwrap()
            });
            let h = mcap::records::MessageHeader {
                channel_id: id,
                sequence: m.sequence,
                log_time: m.log_time,
                publish_time: m.publish_time,
            };
            w.write_to_known_channel(&h, &m.data).unwrap();
        }
        // A SceneUpdate in JSON: a detection schema in an encoding probmot does not read.
        let sid = w
            .add_schema("foxglove.SceneUpdate", "jsonschema", b"{}")
            .unwrap();
        let cid = w
            .add_channel(sid, "/scene_json", "json", &BTreeMap::new())
            .unwrap();
        let h = mcap::records::MessageHeader {
            channel_id: cid,
            sequence: 0,
            log_time: 1,
            publish_time: 1,
        };
        w.write_to_known_channel(&h, b"{}").unwrap();
        w.finish().unwrap();
    }
    let out = dir.path().join("out.mcap");
    let v = track_json(&path, &out, &[]);
    assert_eq!(v["detection_topics"], serde_json::json!(["/objects"]));
    assert_eq!(v["frames"], 40);
    let warnings: Vec<&str> = v["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w.as_str().unwrap())
        .collect();
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(
        warnings[0].contains("/scene_json")
            && warnings[0].contains("jsonschema")
            && warnings[0].contains("not tracked"),
        "{warnings:?}"
    );
    // Asked for by topic, the same channel is an error.
    let err = track_err(&path, &["--detections-topic", "/scene_json"]);
    assert!(
        err.contains("/scene_json") && err.contains(SUPPORTED),
        "{err}"
    );
}
