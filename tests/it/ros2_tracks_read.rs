//! `plot`, `viz` and `eval` read a tracks channel written as ROS 2
//! `vision_msgs/msg/Detection3DArray` (`track --tracks-format ros2`, the default for ROS 2
//! inputs) as they read `probmot.Tracks3D`.
//!
//! The reference is the same input tracked with `--tracks-format probmot`, read by the
//! existing protobuf path: both runs hold the same tracks (tests/it/ros2_bag_output.rs checks that
//! message by message), so every reader must see the same boxes, draw the same pixels and score
//! the same metrics. Velocities have no field in the ROS 2 message and are left out of the
//! comparison.

use crate::common;

use std::path::{Path, PathBuf};

use crate::common::*;
use probmot::viz::{read_layers, Layer};

/// Tracks the ROS 2 fixture twice into `dir`: `(ROS 2 tracks, probmot tracks)`.
fn tracked_both_ways(dir: &Path) -> (PathBuf, PathBuf) {
    let (ros, pb) = common::track_ros2_fixture_both_ways(dir);
    let schemas: Vec<String> = messages(&ros)
        .into_iter()
        .filter(|m| m.topic == "/tracks")
        .map(|m| m.schema)
        .collect();
    assert!(!schemas.is_empty());
    assert!(schemas
        .iter()
        .all(|s| s == "vision_msgs/msg/Detection3DArray"));
    (ros, pb)
}

#[test]
fn viz_layers_of_ros2_tracks_are_the_probmot_tracks() {
    let dir = tempfile::tempdir().unwrap();
    let (ros, pb) = tracked_both_ways(dir.path());
    let wanted = [(Layer::Tracks, "/tracks".to_string())];
    let a = read_layers(&ros, &wanted).unwrap();
    let b = read_layers(&pb, &wanted).unwrap();
    let (a, b) = (a.get(Layer::Tracks).unwrap(), b.get(Layer::Tracks).unwrap());
    assert_eq!(a.log_times, b.log_times);
    assert_eq!(a.frames.len(), b.frames.len());
    let mut n = 0;
    for ((sa, ba), (sb, bb)) in a.frames.iter().zip(&b.frames) {
        assert_eq!(sa, sb);
        assert_eq!(ba.len(), bb.len());
        for (x, y) in ba.iter().zip(bb) {
            assert_eq!((x.id, &x.label, x.score), (y.id, &y.label, y.score));
            assert_eq!((x.center, x.size), (y.center, y.size));
            assert!((x.yaw - y.yaw).sin().abs() < 1e-9, "{} vs {}", x.yaw, y.yaw);
            n += 1;
        }
    }
    assert!(n > 100, "only {n} boxes compared");
}

#[test]
fn plot_of_ros2_tracks_is_the_plot_of_probmot_tracks() {
    let dir = tempfile::tempdir().unwrap();
    let (ros, pb) = tracked_both_ways(dir.path());
    let mut pngs = Vec::new();
    for input in [&ros, &pb] {
        let png = input.with_extension("png");
        probmot_ok(&[
            "plot",
            input.to_str().unwrap(),
            "-o",
            png.to_str().unwrap(),
            "--layers",
            "detections,tracks",
            "--title",
            "city",
        ]);
        pngs.push(std::fs::read(&png).unwrap());
    }
    assert!(pngs[0] == pngs[1], "the two pictures differ");
}

#[test]
fn eval_of_ros2_tracks_scores_as_probmot_tracks() {
    let dir = tempfile::tempdir().unwrap();
    let (ros, pb) = tracked_both_ways(dir.path());
    // The ROS 2 fixture carries the detections of sample_logs/city.mcap, whose /ground_truth
    // is the truth of both runs.
    let truth = repo("sample_logs/city.mcap");
    let metrics = |tracks: &Path| {
        let out = probmot_ok(&[
            "eval",
            "--truth",
            truth.to_str().unwrap(),
            "--tracks",
            tracks.to_str().unwrap(),
            "--json",
        ]);
        let mut v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        strip_names(&mut v);
        v
    };
    let (a, b) = (metrics(&ros), metrics(&pb));
    assert!(a.to_string().contains("amota"), "{a}");
    assert_eq!(a, b);
}

/// Removes the file names (the only intended difference) from an eval report.
fn strip_names(v: &mut serde_json::Value) {
    match v {
        serde_json::Value::Object(m) => {
            m.retain(|_, x| !x.as_str().is_some_and(|s| s.ends_with(".mcap")));
            m.values_mut().for_each(strip_names);
        }
        serde_json::Value::Array(a) => a.iter_mut().for_each(strip_names),
        _ => {}
    }
}
