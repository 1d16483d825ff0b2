//! ROS 2 transform decoding against bytes written by a third-party writer:
//! `tests/fixtures/ros2_tf/tf.mcap` was written by PyPI `mcap-ros2-support` from the upstream
//! `.msg` definitions (`scripts/make_ros2_tf_fixture.py`), and `expected.json` holds the values
//! it wrote. The frame names have odd lengths, so the `float64` fields after them are decoded
//! right only if CDR alignment is counted from the end of the encapsulation header and the
//! strings' NUL terminators are handled. Both decoders are checked: probmot's bounds-checked
//! one and the `cdr` crate's.

use std::path::PathBuf;

use nalgebra::{Isometry3, Point3};
use probmot::msgs::ros2_tf::{decode_cdr, Odometry, TfMessage};
use probmot::transforms::buffer::rigid;
use probmot::transforms::TransformCollector;
use serde_json::Value;

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/ros2_tf")
        .join(name)
}

fn expected() -> Vec<Value> {
    serde_json::from_slice(&std::fs::read(fixture("expected.json")).unwrap()).unwrap()
}

fn f(v: &Value) -> f64 {
    v.as_f64().unwrap()
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 4.0 * f64::EPSILON * a.abs().max(1.0)
}

fn arr(v: &Value) -> Vec<f64> {
    v.as_array().unwrap().iter().map(f).collect()
}

#[test]
fn tf_and_odometry_decode_to_the_values_written() {
    let bytes = std::fs::read(fixture("tf.mcap")).unwrap();
    let want = expected();
    let mut got = Vec::new();
    let mut saw_nul_terminated = false;
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        let topic = m.channel.topic.as_str();
        assert_eq!(m.channel.message_encoding, "cdr");
        // The writer counts the NUL terminator in a string's length: "base_link" is 10 bytes.
        let needle = [&10u32.to_le_bytes()[..], b"base_link\0"].concat();
        saw_nul_terminated |= m.data.windows(needle.len()).any(|w| w == needle);
        match topic {
            "/tf" | "/tf_static" => {
                let tf = TfMessage::decode(&m.data).unwrap();
                // The `cdr` crate reads the same values.
                assert_eq!(decode_cdr::<TfMessage>(&m.data).unwrap(), tf);
                for t in tf.transforms {
                    let tr = t.transform.translation;
                    let q = t.transform.rotation;
                    got.push((
                        topic.to_string(),
                        t.header.frame_id,
                        t.child_frame_id,
                        t.header.stamp.to_nanos().unwrap(),
                        vec![tr.x, tr.y, tr.z],
                        vec![q.x, q.y, q.z, q.w],
                    ));
                }
            }
            "/odom" => {
                let o = Odometry::decode(&m.data).unwrap();
                assert_eq!(decode_cdr::<Odometry>(&m.data).unwrap(), o);
                let e = want
                    .iter()
                    .find(|e| {
                        e["topic"] == "/odom" && e["stamp_ns"] == o.header.stamp.to_nanos().unwrap()
                    })
                    .expect("expected odometry");
                let l = o.twist.twist.linear;
                let a = o.twist.twist.angular;
                let got_rest = [
                    o.pose.covariance.0.to_vec(),
                    o.twist.covariance.0.to_vec(),
                    vec![l.x, l.y, l.z],
                    vec![a.x, a.y, a.z],
                ]
                .concat();
                let want_rest = [
                    arr(&e["covariance"]),
                    arr(&e["covariance"]),
                    arr(&e["twist_linear"]),
                    arr(&e["twist_angular"]),
                ]
                .concat();
                assert_eq!(got_rest.len(), want_rest.len());
                for (x, y) in got_rest.iter().zip(&want_rest) {
                    assert!(close(*x, *y), "odometry: {x} vs {y}");
                }
                let p = o.pose.pose.position;
                let q = o.pose.pose.orientation;
                got.push((
                    topic.to_string(),
                    o.header.frame_id,
                    o.child_frame_id,
                    o.header.stamp.to_nanos().unwrap(),
                    vec![p.x, p.y, p.z],
                    vec![q.x, q.y, q.z, q.w],
                ));
            }
            other => panic!("unexpected topic {other}"),
        }
    }
    assert!(
        saw_nul_terminated,
        "the fixture's strings carry their NUL terminator"
    );
    let want: Vec<_> = want
        .iter()
        .map(|e| {
            (
                e["topic"].as_str().unwrap().to_string(),
                e["parent"].as_str().unwrap().to_string(),
                e["child"].as_str().unwrap().to_string(),
                e["stamp_ns"].as_u64().unwrap(),
                arr(&e["translation"]),
                arr(&e["rotation"]),
            )
        })
        .collect();
    // Names and stamps exactly; numbers to an ulp or two (serde_json's default float parser is
    // not always correctly rounded). A misaligned read would give unrelated numbers.
    assert_eq!(got.len(), want.len());
    for (g, w) in got.iter().zip(&want) {
        assert_eq!((&g.0, &g.1, &g.2, g.3), (&w.0, &w.1, &w.2, w.3));
        for (a, b) in g.4.iter().chain(&g.5).zip(w.4.iter().chain(&w.5)) {
            assert!(close(*a, *b), "{g:?} vs {w:?}");
        }
    }
}

#[test]
fn the_collector_builds_the_tree_and_looks_up_through_static_and_dynamic_edges() {
    let file = fixture("tf.mcap");
    let bytes = std::fs::read(&file).unwrap();
    let mut c = TransformCollector::new();
    let mut seen = std::collections::HashSet::new();
    // Feed the collector the way `track` does: channel records, then messages.
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        let ch = &m.channel;
        if seen.insert(ch.id) {
            let schema = ch.schema.as_ref().unwrap().name.clone();
            let rec = mcap::records::Channel {
                id: ch.id,
                schema_id: 1,
                topic: ch.topic.clone(),
                message_encoding: ch.message_encoding.clone(),
                metadata: Default::default(),
            };
            assert!(c.on_channel(&rec, &schema).is_some(), "{}", ch.topic);
        }
        let h = mcap::records::MessageHeader {
            channel_id: ch.id,
            sequence: m.sequence,
            log_time: m.log_time,
            publish_time: m.publish_time,
        };
        assert!(c.on_message("tf.mcap", &h, &m.data));
    }
    c.finish();
    assert_eq!(c.undecodable(), 0);
    assert_eq!(c.invalid(), 0);
    let edges: Vec<(String, String, bool)> = c
        .buffer
        .summary()
        .into_iter()
        .map(|e| (e.parent, e.child, e.is_static))
        .collect();
    assert_eq!(
        edges,
        vec![
            ("base_link".into(), "lidar_top".into(), true),
            ("map".into(), "odom".into(), false),
            ("odom".into(), "base_footprint".into(), false),
            ("odom".into(), "base_link".into(), false),
        ]
    );
    assert_eq!(c.buffer.root_of("lidar_top"), Some("map"));

    // map <- lidar_top at the second /tf stamp: the product of the three written transforms.
    let want = expected();
    let iso = |e: &Value| {
        let t = arr(&e["translation"]);
        let q = arr(&e["rotation"]);
        rigid([t[0], t[1], t[2]], [q[0], q[1], q[2], q[3]]).unwrap()
    };
    let stamp = 1_700_000_001_250_000_000u64;
    let pick = |child: &str| -> Isometry3<f64> {
        let e = want
            .iter()
            .find(|e| e["child"] == child && (e["topic"] == "/tf_static" || e["stamp_ns"] == stamp))
            .unwrap();
        iso(e)
    };
    let composed = pick("odom") * pick("base_link") * pick("lidar_top");
    let looked_up = c.buffer.lookup("map", "lidar_top", stamp).unwrap();
    let p = Point3::new(1.0, 2.0, 3.0);
    assert!(((composed * p) - (looked_up * p)).norm() < 1e-12);
    // And the inverse direction.
    let back = c.buffer.lookup("lidar_top", "map", stamp).unwrap();
    assert!(((back * (looked_up * p)) - p).norm() < 1e-12);
    // Between the two odometry samples (0.5 s and 1.5 s past T0) the translation is the
    // midpoint and the yaw the mean (-0.3 and 0.2).
    let mid = c
        .buffer
        .lookup("odom", "base_footprint", 1_700_000_001_000_000_000)
        .unwrap();
    assert!((mid.translation.vector - nalgebra::Vector3::new(2.0, 3.25, 0.0)).norm() < 1e-12);
    assert!((mid.rotation.euler_angles().2 - (-0.05)).abs() < 1e-12);
}
