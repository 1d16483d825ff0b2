//! Detections from recordings written by other tools: ROS 2 `vision_msgs/msg/Detection3DArray`
//! (CDR) and Foxglove `foxglove.SceneUpdate` (protobuf cubes).
//!
//! The fixtures in `tests/fixtures/ros2/` and `tests/fixtures/foxglove/` were written by PyPI
//! `mcap-ros2-support` and `mcap-protobuf-support` + `foxglove-schemas-protobuf` from
//! `sample_logs/city.mcap` (see their README), so tracking them must give exactly the tracks of
//! the probmot log. The decoders are also tested on hand-made messages (layouts, yaw, best
//! hypothesis, metadata convention, malformed bytes). The one test that regenerates the fixtures
//! needs those Python packages and skips with a message without them.
//!
//! One file per area: the fixtures, hand-made ROS 2 messages, hand-made Foxglove
//! SceneUpdates, regenerating the fixtures, robustness and channel selection; shared helpers
//! here.

mod fixtures;
mod foxglove_messages;
mod regenerate;
mod robustness;
mod ros2_messages;

use crate::common;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

use crate::common::*;
use probmot::msgs::detection_source::{DetectionSource, SUPPORTED};
use probmot::msgs::ros2_vision::{self, VisionLayout};
use probmot::msgs::{foxglove_scene, Tracks3D};
use prost::Message as _;
use serde::ser::{SerializeTuple, Serializer};
use serde::Serialize;

const ROS2_FIXTURE: &str = "tests/fixtures/ros2/city.mcap";
const FOXGLOVE_FIXTURE: &str = "tests/fixtures/foxglove/city.mcap";
const PROBMOT_LOG: &str = "sample_logs/city.mcap";
/// vision_msgs 2.x (Foxy) layout, from `sample_logs/turning-car.mcap`.
const ROS2_V2_FIXTURE: &str = "tests/fixtures/ros2/turning-car-vision_msgs2.mcap";
const PROBMOT_V2_LOG: &str = "sample_logs/turning-car.mcap";

/// Tracks into probmot.Tracks3D (every field, to compare in full; a ROS 2 input's default is
/// ROS 2 tracks, compared with these in tests/it/ros2_bag_output.rs).
fn track(input: &Path, output: &Path) {
    probmot_ok(&[
        "track",
        input.to_str().unwrap(),
        "-o",
        output.to_str().unwrap(),
        "--quiet",
        "--tracks-format",
        "probmot",
    ]);
}

fn close(a: f64, b: f64, what: &str) {
    assert!((a - b).abs() <= 1e-9, "{what}: {a} vs {b}");
}

/// Same frames, same track ids and labels, boxes and states to 1e-9.
fn assert_same_tracks(a: &[Tracks3D], b: &[Tracks3D], name: &str, min_reports: usize) {
    assert_eq!(a.len(), b.len(), "{name}: number of frames");
    let mut n = 0;
    for (fa, fb) in a.iter().zip(b) {
        assert_eq!(fa.stamp, fb.stamp, "{name}: frame stamps");
        assert_eq!(fa.frame_id, fb.frame_id, "{name}: frame_id");
        let ids_a: Vec<u64> = fa.tracks.iter().map(|t| t.id).collect();
        let ids_b: Vec<u64> = fb.tracks.iter().map(|t| t.id).collect();
        assert_eq!(ids_a, ids_b, "{name}: track ids at stamp {}", fa.stamp);
        for (ta, tb) in fa.tracks.iter().zip(&fb.tracks) {
            let what = format!("{name}: track {} at stamp {}", ta.id, fa.stamp);
            assert_eq!(ta.label, tb.label, "{what}");
            assert_eq!(
                (ta.age, ta.hits, ta.frames_since_update),
                (tb.age, tb.hits, tb.frames_since_update),
                "{what}"
            );
            let (ca, cb) = (ta.center.unwrap(), tb.center.unwrap());
            let (sa, sb) = (ta.size.unwrap(), tb.size.unwrap());
            let (va, vb) = (ta.velocity.unwrap(), tb.velocity.unwrap());
            for (x, y) in [
                (ca.x, cb.x),
                (ca.y, cb.y),
                (ca.z, cb.z),
                (sa.length, sb.length),
                (sa.width, sb.width),
                (sa.height, sb.height),
                (ta.yaw, tb.yaw),
                (va.x, vb.x),
                (va.y, vb.y),
                (ta.yaw_rate, tb.yaw_rate),
                (ta.score, tb.score),
            ] {
                close(x, y, &what);
            }
            n += 1;
        }
    }
    assert!(n >= min_reports, "{name}: only {n} track reports compared");
}

fn track_err(input: &Path, extra: &[&str]) -> String {
    let out_path = input.with_extension("out.mcap");
    let mut args = vec![
        "track",
        input.to_str().unwrap(),
        "-o",
        out_path.to_str().unwrap(),
        "--quiet",
    ];
    args.extend_from_slice(extra);
    let out = probmot(&args);
    assert_eq!(out.status.code(), Some(2), "{args:?} should fail");
    assert!(!out_path.exists(), "no output after a failure");
    let err = String::from_utf8_lossy(&out.stderr).to_string();
    assert!(!err.contains("panicked"), "{err}");
    err
}
