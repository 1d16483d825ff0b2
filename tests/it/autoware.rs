//! Autoware in and out (issue #35): a bag of `autoware_perception_msgs/msg/DetectedObjects`
//! tracks into `autoware_perception_msgs/msg/TrackedObjects` on Autoware's tracking topic.
//!
//! The bags come from an independent writer, PyPI `rosbags` (scripts/make_autoware_bag.py: the
//! upstream field lists registered as types, its own CDR serializer and rosbag2 writer): two cars,
//! a pedestrian, a truck given as a footprint polygon, a parked car and an UNKNOWN object over 60
//! frames. The tracked bag is read back by rosbags (scripts/check_autoware_bag.py), which decodes
//! the TrackedObjects from the definitions in the bag's own schema record.

use std::path::Path;
use std::process::Command;

use crate::common::autoware_bag::{have_rosbags, make_autoware_bag as make_bag};
use crate::common::*;
use probmot::msgs::autoware_tracks::{self, KinematicsOrder, TRACKING_TOPIC};
use probmot::msgs::Tracks3D;

const DETECTION_TOPIC: &str = "/perception/object_recognition/detection/objects";

/// Runs scripts/check_autoware_bag.py on `path` (`ids` UUIDs expected, the truth of bag
/// `name`); returns (success, stdout + stderr).
fn check(path: &Path, dir: &Path, name: &str, ids: usize, extra: &[&str]) -> (bool, String) {
    let out = Command::new("python3")
        .arg(repo("scripts/check_autoware_bag.py"))
        .arg(path)
        .args(["--messages", "60", "--ids", &ids.to_string(), "--truth"])
        .arg(dir.join(format!("{name}.jsonl")))
        .args(extra)
        .output()
        .unwrap();
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    (out.status.success(), text)
}

/// The TrackedObjects of a tracked file, decoded by probmot's reader.
fn autoware_tracks(path: &Path) -> Vec<Tracks3D> {
    messages(path)
        .into_iter()
        .filter(|m| m.topic == TRACKING_TOPIC)
        .map(|m| {
            assert_eq!(
                (m.schema.as_str(), m.message_encoding.as_str()),
                (autoware_tracks::SCHEMA_NAME, "cdr")
            );
            autoware_tracks::decode_tracks(&m.data, KinematicsOrder::Perception).unwrap()
        })
        .collect()
}

#[test]
fn rosbags_autoware_bag_tracks_into_tracked_objects() {
    if !have_rosbags("rosbags_autoware_bag_tracks_into_tracked_objects") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let bag = make_bag(d, "drive", &[]);
    let out = d.join("tracked");
    let s = track_json(&bag, &out, &[]);
    assert_eq!(s["detection_topics"][0], DETECTION_TOPIC);
    assert_eq!(s["tracks_messages"], 60);
    // The UNKNOWN object is skipped and counted: the default preset has no `unknown` entry
    // (its `default` entry, car statistics, does not take Autoware's other classes).
    assert_eq!(s["detections"]["skipped"]["class_without_entry"], 60, "{s}");
    let per_label = &s["detections"]["per_label"];
    assert_eq!(
        (
            &per_label["car"],
            &per_label["pedestrian"],
            &per_label["truck"]
        ),
        (&180.into(), &60.into(), &60.into())
    );
    assert!(per_label.get("unknown").is_none());
    let (ok, text) = check(&out, d, "drive", 5, &[]);
    assert!(ok, "rosbags on the tracked bag: {text}");
    assert!(
        text.contains("5 UUIDs, classes car, pedestrian, truck"),
        "{text}"
    );
    if python_has("mcap_ros2") {
        assert!(
            text.contains("mcap-ros2-support: 60 messages, 5 ids"),
            "{text}"
        );
    }
    let yaml = std::fs::read_to_string(out.join("metadata.yaml")).unwrap();
    assert!(
        yaml.contains("autoware_perception_msgs/msg/TrackedObjects"),
        "{yaml}"
    );

    // The same check fails on the ROS 2 tracks of the same bag: it is not vacuous.
    let ros = d.join("tracked-ros2");
    track_json(&bag, &ros, &["--tracks-format", "ros2"]);
    let (ok, text) = check(&ros, d, "drive", 5, &["--tracks-topic", "/tracks"]);
    assert!(!ok, "the check passed on vision_msgs tracks: {text}");
}

#[test]
fn ego_motion_from_tf_moves_base_link_detections_into_map() {
    if !have_rosbags("ego_motion_from_tf_moves_base_link_detections_into_map") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // Detections in base_link of an ego driving and turning, its pose on /tf.
    let bag = make_bag(d, "ego", &["--ego"]);
    let out = d.join("tracked");
    let s = track_json(&bag, &out, &[]);
    assert_eq!(s["ego"]["fixed_frame"], "map", "{}", s["ego"]);
    let frames = autoware_tracks(&out.join("ego.mcap"));
    assert_eq!(frames.len(), 60);
    assert!(frames.iter().all(|f| f.frame_id == "map"));
    // rosbags finds every track at its true place in map, which the base_link coordinates are
    // not (the ego is 23.6 m along and 0.59 rad turned by the last frame).
    let (ok, text) = check(&out, d, "ego", 5, &[]);
    assert!(ok, "rosbags on the ego-motion bag: {text}");
}

#[test]
fn autoware_auto_package_tracks_too() {
    if !have_rosbags("autoware_auto_package_tracks_too") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let bag = make_bag(d, "auto", &["--auto"]);
    let info = probmot_ok(&["info", bag.to_str().unwrap()]);
    let info = String::from_utf8_lossy(&info.stdout);
    assert!(
        info.contains("detections: autoware_auto_perception_msgs/msg/DetectedObjects (cdr)"),
        "{info}"
    );
    let out = d.join("tracked");
    track_json(&bag, &out, &[]);
    let (ok, text) = check(&out, d, "auto", 5, &[]);
    assert!(ok, "rosbags on the tracked auto bag: {text}");
}

#[test]
fn autoware_tracks_carry_probmots_tracks_and_read_back_everywhere() {
    if !have_rosbags("autoware_tracks_carry_probmots_tracks_and_read_back_everywhere") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let bag = make_bag(d, "drive", &[]);
    let mcap = bag.join("drive.mcap");
    let aw = d.join("aw.mcap");
    let pb = d.join("pb.mcap");
    track_json(&mcap, &aw, &[]);
    track_json(&mcap, &pb, &["--tracks-format", "probmot", "--no-scene"]);
    let got = autoware_tracks(&aw);
    let want = tracks(&pb, "/tracks");
    assert_eq!(got.len(), want.len());
    let mut n = 0;
    for (g, w) in got.iter().zip(&want) {
        assert_eq!((g.stamp, &g.frame_id), (w.stamp, &w.frame_id));
        assert_eq!(g.tracks.len(), w.tracks.len());
        for (a, b) in g.tracks.iter().zip(&w.tracks) {
            assert_eq!((a.id, &a.label), (b.id, &b.label));
            assert_eq!((a.center, a.size), (b.center, b.size));
            assert!((a.yaw - b.yaw).sin().abs() < 1e-9);
            assert_eq!(a.score, b.score as f32 as f64);
            let (va, vb) = (a.velocity.unwrap(), b.velocity.unwrap());
            assert!((va.x - vb.x).abs() < 1e-9 && (va.y - vb.y).abs() < 1e-9);
            assert_eq!(a.yaw_rate, b.yaw_rate);
            assert_eq!(a.position_variance, b.position_variance);
            assert_eq!(a.yaw_variance, b.yaw_variance);
            n += 1;
        }
    }
    assert_eq!(n, 300);

    // info lists the Autoware tracks channel as tracks, per class.
    let info = probmot_ok(&["info", aw.to_str().unwrap()]);
    let info = String::from_utf8_lossy(&info.stdout);
    let line = info
        .lines()
        .skip_while(|l| !l.contains(TRACKING_TOPIC))
        .take(2)
        .collect::<Vec<_>>()
        .join("\n");
    assert!(line.contains("<- usable as tracks"), "{info}");
    assert!(line.contains("car 180, pedestrian 60, truck 60"), "{info}");

    // eval reads them: scored against the same run's probmot tracks, they are perfect.
    let e = probmot_ok(&[
        "eval",
        "--truth",
        pb.to_str().unwrap(),
        "--truth-topic",
        "/tracks",
        "--tracks",
        aw.to_str().unwrap(),
        "--tracks-topic",
        TRACKING_TOPIC,
        "--classes",
        "car,pedestrian,truck",
        "--json",
    ]);
    let e: serde_json::Value = serde_json::from_slice(&e.stdout).unwrap();
    for class in ["car", "pedestrian", "truck"] {
        let m = &e["result"]["classes"][class];
        assert_eq!(
            (&m["mota"], &m["amota"]),
            (&1.0.into(), &1.0.into()),
            "{class}: {m}"
        );
        assert_eq!(
            (&m["ids"], &m["fp"]),
            (&0.0.into(), &0.0.into()),
            "{class}: {m}"
        );
    }

    // Without --tracks-topic, eval names the topic to give.
    let r = probmot(&[
        "eval",
        "--truth",
        pb.to_str().unwrap(),
        "--truth-topic",
        "/tracks",
        "--tracks",
        aw.to_str().unwrap(),
    ]);
    assert!(!r.status.success());
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        err.contains(&format!("--tracks-topic {TRACKING_TOPIC}")),
        "{err}"
    );

    // plot and export kitti read them with the topic named.
    let png = d.join("aw.png");
    let p = probmot_ok(&[
        "plot",
        aw.to_str().unwrap(),
        "-o",
        png.to_str().unwrap(),
        "--layers",
        "tracks",
        "--tracks-topic",
        TRACKING_TOPIC,
    ]);
    assert!(String::from_utf8_lossy(&p.stdout).contains("300 boxes"));
    // A time window (the indexed reader of viz/window.rs): 11 frames of 5 tracks and 6 boxes.
    let p = probmot_ok(&[
        "plot",
        aw.to_str().unwrap(),
        "-o",
        png.to_str().unwrap(),
        "--layers",
        "tracks,detections",
        "--tracks-topic",
        TRACKING_TOPIC,
        "--detections-topic",
        DETECTION_TOPIC,
        "--from",
        "1",
        "--to",
        "2",
    ]);
    let text = String::from_utf8_lossy(&p.stdout);
    assert!(
        text.contains("11 frames") && text.contains("121 boxes"),
        "{text}"
    );
    let kitti = d.join("kitti.txt");
    probmot_ok(&[
        "export",
        "kitti",
        aw.to_str().unwrap(),
        "-o",
        kitti.to_str().unwrap(),
        "--topic",
        TRACKING_TOPIC,
        "--quiet",
    ]);
    let rows = std::fs::read_to_string(&kitti).unwrap();
    assert!(rows.lines().count() >= 240, "{rows}");
}

#[test]
fn autoware_classes_are_tracked_under_their_own_config_entry() {
    if !have_rosbags("autoware_classes_are_tracked_under_their_own_config_entry") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let bag = make_bag(d, "drive", &[]);
    let mcap = bag.join("drive.mcap");
    // A config with an `unknown` entry (a copy of its car entry) tracks the UNKNOWN object.
    let cfg = probmot_ok(&["config", "--preset", "nuscenes-chiu2019"]);
    let mut cfg: serde_json::Value = serde_json::from_slice(&cfg.stdout).unwrap();
    cfg["classes"]["unknown"] = cfg["classes"]["car"].clone();
    let cfg_path = d.join("unknown.json");
    std::fs::write(&cfg_path, cfg.to_string()).unwrap();
    let out = d.join("out.mcap");
    let s = track_json(&mcap, &out, &["--config", cfg_path.to_str().unwrap()]);
    assert_eq!(s["detections"]["per_label"]["unknown"], 60, "{s}");
    assert!(s["detections"]["skipped"]
        .get("class_without_entry")
        .is_none());
    let last = autoware_tracks(&out).pop().unwrap();
    let labels: Vec<&str> = last.tracks.iter().map(|t| t.label.as_str()).collect();
    assert_eq!(labels.len(), 6);
    assert!(labels.contains(&"unknown"), "{labels:?}");
    // With --strict, an Autoware class without an entry is an error naming it.
    let r = probmot(&[
        "track",
        mcap.to_str().unwrap(),
        "-o",
        d.join("strict.mcap").to_str().unwrap(),
        "--strict",
    ]);
    assert!(!r.status.success());
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        err.contains("(unknown)") && err.contains("--strict"),
        "{err}"
    );
}

#[test]
fn default_tracking_topic_taken_by_autowares_own_tracks_is_refused_with_the_fix() {
    if !have_rosbags("default_tracking_topic_taken_by_autowares_own_tracks_is_refused_with_the_fix")
    {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let bag = make_bag(d, "drive", &[]);
    // A tracked bag holds TrackedObjects on Autoware's topic, as a recorded Autoware drive does.
    let once = d.join("once.mcap");
    track_json(&bag.join("drive.mcap"), &once, &[]);
    let again = d.join("again.mcap");
    let r = probmot(&[
        "track",
        once.to_str().unwrap(),
        "-o",
        again.to_str().unwrap(),
    ]);
    assert!(!r.status.success());
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        err.contains(&format!("already has a channel on {TRACKING_TOPIC}"))
            && err.contains("--tracks-topic /probmot/tracking/objects"),
        "{err}"
    );
    let s = track_json(
        &once,
        &again,
        &["--tracks-topic", "/probmot/tracking/objects"],
    );
    assert_eq!(s["tracks_messages"], 60);
    // Autoware's TrackedObjects are not read as detections.
    assert_eq!(s["detection_topics"], serde_json::json!([DETECTION_TOPIC]));
}
