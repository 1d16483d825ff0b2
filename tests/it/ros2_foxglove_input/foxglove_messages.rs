//! Foxglove: hand-made SceneUpdates (prost types of the `foxglove` crate).

use super::*;

use foxglove::schemas::{
    CubePrimitive, KeyValuePair, Pose as FgPose, Quaternion as FgQuat, SceneEntity, SceneUpdate,
    Timestamp, Vector3 as FgVec,
};

fn kv(k: &str, v: &str) -> KeyValuePair {
    KeyValuePair {
        key: k.into(),
        value: v.into(),
    }
}

fn cube(x: f64, yaw: Option<f64>) -> CubePrimitive {
    CubePrimitive {
        pose: Some(FgPose {
            position: Some(FgVec { x, y: 2.0, z: 0.8 }),
            orientation: yaw.map(|a| FgQuat {
                x: 0.0,
                y: 0.0,
                z: (a / 2.0).sin(),
                w: (a / 2.0).cos(),
            }),
        }),
        size: Some(FgVec {
            x: 4.0,
            y: 2.0,
            z: 1.5,
        }),
        color: None,
    }
}

fn entity(
    id: &str,
    frame: &str,
    meta: Vec<KeyValuePair>,
    cubes: Vec<CubePrimitive>,
) -> SceneEntity {
    SceneEntity {
        timestamp: Some(Timestamp::new(12, 500)),
        frame_id: frame.into(),
        id: id.into(),
        metadata: meta,
        cubes,
        ..Default::default()
    }
}

#[test]
fn foxglove_metadata_convention() {
    let update = SceneUpdate {
        deletions: vec![],
        entities: vec![
            entity(
                "a",
                "map",
                vec![kv("label", "truck"), kv("score", "0.25"), kv("lane", "3")],
                vec![cube(1.0, Some(0.7)), cube(2.0, None)],
            ),
            entity(
                "b",
                "map",
                vec![kv("class", "pedestrian")],
                vec![cube(3.0, Some(-2.0))],
            ),
            entity(
                "c",
                "map",
                vec![kv("class_id", "bus"), kv("class", "car")],
                vec![cube(4.0, None)],
            ),
            entity("d", "map", vec![], vec![cube(5.0, None)]),
            // An entity without cubes gives no detection.
            entity("e", "map", vec![kv("label", "car")], vec![]),
        ],
    };
    let out = foxglove_scene::decode(&update.encode_to_vec()).unwrap();
    assert_eq!(out.stamp, Some(12_000_000_500));
    assert_eq!(out.frame_id, "map");
    let d = &out.detections;
    assert_eq!(d.len(), 5);
    let summary: Vec<(&str, f64)> = d.iter().map(|x| (x.label.as_str(), x.score)).collect();
    assert_eq!(
        summary,
        [
            ("truck", 0.25),
            ("truck", 0.25),
            ("pedestrian", 1.0),
            ("car", 1.0), // `class` is preferred over `class_id`
            ("", 1.0),
        ]
    );
    assert!((d[0].yaw - 0.7).abs() < 1e-12);
    assert_eq!(d[1].yaw, 0.0, "no orientation = identity");
    assert!((d[2].yaw + 2.0).abs() < 1e-12);
    assert_eq!(d[0].center.unwrap().x, 1.0);
    let s = d[0].size.unwrap();
    assert_eq!((s.length, s.width, s.height), (4.0, 2.0, 1.5));
    assert_eq!(d[0].attributes.get("lane").map(String::as_str), Some("3"));
    assert_eq!(
        d[0].attributes.get("entity_id").map(String::as_str),
        Some("a")
    );
    assert!(!d[0].attributes.contains_key("label") && !d[0].attributes.contains_key("score"));
    assert_eq!(d[3].attributes.get("class_id").map(String::as_str), None);

    // A score that is not a number, and cubes in two frames, are errors naming the entity.
    let bad = SceneUpdate {
        deletions: vec![],
        entities: vec![entity(
            "q",
            "map",
            vec![kv("score", "high")],
            vec![cube(1.0, None)],
        )],
    };
    let err = foxglove_scene::decode(&bad.encode_to_vec()).unwrap_err();
    assert!(
        err.to_string().contains("'q'") && err.to_string().contains("high"),
        "{err}"
    );
    let mixed = SceneUpdate {
        deletions: vec![],
        entities: vec![
            entity("m", "map", vec![], vec![cube(1.0, None)]),
            entity("n", "lidar", vec![], vec![cube(1.0, None)]),
        ],
    };
    let err = foxglove_scene::decode(&mixed.encode_to_vec()).unwrap_err();
    assert!(err.to_string().contains("lidar"), "{err}");
    // An empty update has no stamp (track uses the log_time) and no boxes.
    let empty = foxglove_scene::decode(&[]).unwrap();
    assert_eq!((empty.stamp, empty.detections.len()), (None, 0));
    // Bad protobuf bytes.
    assert!(foxglove_scene::decode(&[0x12, 0x40, 0x01]).is_err());
}

/// An entity label that is not UTF-8 costs that entity's cubes, not the run: `track` tracks
/// the rest of the update and counts the boxes as it does for the other inputs.
#[test]
fn a_label_that_is_not_utf8_skips_only_its_entity() {
    let dir = tempfile::tempdir().unwrap();
    let bytes = std::fs::read(repo(FOXGLOVE_FIXTURE)).unwrap();
    let mut messages = Vec::new();
    let mut schema = None;
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        schema.get_or_insert(m.channel.schema.clone().unwrap());
        messages.push(m.data.to_vec());
    }
    let all: usize = (messages.iter())
        .map(|m| foxglove_scene::decode(m).unwrap().detections.len())
        .sum();
    // The first label value of message 4: a KeyValuePair `label` = its bytes.
    let at = (messages[4].windows(8))
        .position(|w| w == b"\x0a\x05label\x12")
        .expect("a label pair");
    messages[4][at + 9] = 0xff;
    assert!(SceneUpdate::decode(messages[4].as_slice()).is_err());
    let schema = schema.unwrap();
    let path = dir.path().join("in.mcap");
    let (name, enc) = (schema.name.as_str(), schema.encoding.as_str());
    let s = (name, enc, &schema.data[..]);
    super::ros2_messages::write_mcap(&path, s, "/detections", "protobuf", &messages);
    let out = dir.path().join("out.mcap");
    let s = track_json(&path, &out, &[]);
    assert_eq!(s["detections"]["skipped"]["label_not_utf8"], 1, "{s}");
    let boxes: u64 = (s["detections"]["per_label"].as_object().unwrap().values())
        .map(|v| v.as_u64().unwrap())
        .sum();
    assert_eq!(boxes as usize, all - 1, "{s}");
}
