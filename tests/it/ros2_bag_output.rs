//! ROS 2 bags out (issue #20): a ROS 2 input gets its tracks as
//! `vision_msgs/msg/Detection3DArray` (CDR, ros2msg schema), readable by ROS 2 tooling.
//!
//! The round trip uses an independent ROS 2 implementation, PyPI `rosbags`: it writes the bag
//! (scripts/make_rosbag_fixture.py: three objects over 60 frames) and reads the whole tracked
//! output back (scripts/check_ros2_bag.py: every message of every topic, the tracks decoded with
//! their ids and compared with the generator's true positions). The other tests need no Python.

use crate::common;

use std::path::Path;
use std::process::Command;

use crate::common::*;
use probmot::msgs::ros2_vision::{self, VisionLayout};

const ROS2_FIXTURE: &str = "tests/fixtures/ros2/city.mcap";

/// Writes the rosbags bag directory into `dir/bag` and its truth into `dir/truth.jsonl`.
fn make_bag(dir: &Path) -> std::path::PathBuf {
    let bag = dir.join("bag");
    let out = Command::new("python3")
        .arg(repo("scripts/make_rosbag_fixture.py"))
        .arg(&bag)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "make_rosbag_fixture.py: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    std::fs::write(dir.join("truth.jsonl"), &out.stdout).unwrap();
    bag
}

/// Runs scripts/check_ros2_bag.py on `path`; returns (success, stdout + stderr).
fn check_with_rosbags(path: &Path, truth: &Path) -> (bool, String) {
    let out = Command::new("python3")
        .arg(repo("scripts/check_ros2_bag.py"))
        .arg(path)
        .args([
            "--tracks-topic",
            "/tracks",
            "--messages",
            "60",
            "--ids",
            "3",
        ])
        .arg("--truth")
        .arg(truth)
        .output()
        .unwrap();
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    (out.status.success(), text)
}

#[test]
fn rosbags_bag_round_trips_through_track() {
    if !python_has("rosbags, numpy") {
        skip(
            "rosbags_bag_round_trips_through_track",
            "python3 cannot import rosbags (pip install -r scripts/requirements.txt)",
        );
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let bag = make_bag(dir.path());
    let mcap = bag.join("bag.mcap");
    let out = dir.path().join("tracked.mcap");
    probmot_ok(&[
        "track",
        mcap.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    let (ok, text) = check_with_rosbags(&out, &dir.path().join("truth.jsonl"));
    assert!(ok, "rosbags on the tracked file: {text}");
    assert!(
        text.contains("/perception/detections 60, /tracks 60"),
        "{text}"
    );
    if python_has("mcap_ros2") {
        // The second independent decoder (mcap-ros2-support) agrees.
        assert!(
            text.contains("mcap-ros2-support: 60 messages, 3 ids"),
            "{text}"
        );
    }

    // The same check fails on probmot's own tracks (the report): it is not vacuous.
    let pb = dir.path().join("tracked-probmot.mcap");
    probmot_ok(&[
        "track",
        mcap.to_str().unwrap(),
        "-o",
        pb.to_str().unwrap(),
        "--quiet",
        "--tracks-format",
        "probmot",
    ]);
    let (ok, text) = check_with_rosbags(&pb, &dir.path().join("truth.jsonl"));
    assert!(!ok, "rosbags should not decode probmot.Tracks3D: {text}");
}

#[test]
fn rosbags_bag_directory_in_bag_directory_out() {
    if !python_has("rosbags, numpy") {
        skip(
            "rosbags_bag_directory_in_bag_directory_out",
            "python3 cannot import rosbags (pip install -r scripts/requirements.txt)",
        );
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let bag = make_bag(dir.path());
    let out = dir.path().join("tracked_bag");
    probmot_ok(&[
        "track",
        bag.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(out.join("metadata.yaml").is_file());
    // rosbags opens the directory through its metadata.yaml; the checker also compares the
    // topics and counts listed there with the messages read.
    let (ok, text) = check_with_rosbags(&out, &dir.path().join("truth.jsonl"));
    assert!(ok, "rosbags on the tracked bag directory: {text}");
    let yaml = std::fs::read_to_string(out.join("metadata.yaml")).unwrap();
    assert!(yaml.contains("name: \"/tracks\""), "{yaml}");
    // An existing, non-empty output directory is refused.
    let again = probmot(&["track", bag.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    assert!(!again.status.success());
    assert!(String::from_utf8_lossy(&again.stderr).contains("exists"));
}

/// The tracks channel of `path`: (schema name, message encoding, message bytes).
fn tracks_channel(path: &Path) -> Vec<(String, String, Vec<u8>)> {
    messages(path)
        .into_iter()
        .filter(|m| m.topic == "/tracks")
        .map(|m| (m.schema, m.message_encoding, m.data))
        .collect()
}

#[test]
fn ros2_tracks_carry_the_same_tracks_as_probmot_tracks() {
    let dir = tempfile::tempdir().unwrap();
    let (ros, pb) = common::track_ros2_fixture_both_ways(dir.path());
    let ros_msgs = tracks_channel(&ros);
    let pb_msgs = tracks(&pb, "/tracks");
    assert_eq!(ros_msgs.len(), pb_msgs.len());
    assert!(!pb_msgs.is_empty());
    let mut n = 0;
    for ((schema, encoding, data), want) in ros_msgs.iter().zip(&pb_msgs) {
        assert_eq!(
            (schema.as_str(), encoding.as_str()),
            ("vision_msgs/msg/Detection3DArray", "cdr")
        );
        let got = ros2_vision::decode(data, VisionLayout::V4).unwrap();
        assert_eq!(got.stamp, Some(want.stamp));
        assert_eq!(got.frame_id, want.frame_id);
        assert_eq!(got.detections.len(), want.tracks.len());
        for (d, t) in got.detections.iter().zip(&want.tracks) {
            assert_eq!(d.attributes.get("id"), Some(&t.id.to_string()));
            assert_eq!((&d.label, d.score), (&t.label, t.score));
            assert_eq!((d.center, d.size), (t.center, t.size));
            let dyaw = (d.yaw - t.yaw).sin().abs();
            assert!(dyaw < 1e-9, "yaw {} vs {}", d.yaw, t.yaw);
            n += 1;
        }
    }
    assert!(n > 100, "only {n} tracks compared");
}

#[test]
fn probmot_outputs_refused_in_ros2_tracks_with_a_clear_message() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o.mcap");
    let input = repo(ROS2_FIXTURE);
    let args = [
        "track",
        input.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--quiet",
        "--scene-topic",
        "/scene",
    ];
    let r = probmot(&args);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(!r.status.success());
    assert!(
        err.contains("--scene-topic") && err.contains("--tracks-format probmot"),
        "{err}"
    );
    assert!(!out.exists(), "no output after the error");
    // With probmot's tracks the scene channel is written as before.
    let mut with_probmot = args.to_vec();
    with_probmot.extend(["--tracks-format", "probmot"]);
    probmot_ok(&with_probmot);
    assert!(messages(&out).iter().any(|m| m.topic == "/scene"));
}

#[test]
fn probmot_input_keeps_probmot_tracks_unless_asked() {
    let dir = tempfile::tempdir().unwrap();
    let input = repo("sample_logs/turning-car.mcap");
    let input = input.to_str().unwrap();
    let a = dir.path().join("a.mcap");
    probmot_ok(&["track", input, "-o", a.to_str().unwrap(), "--quiet"]);
    let a_msgs = tracks_channel(&a);
    assert!(!a_msgs.is_empty());
    assert!(a_msgs
        .iter()
        .all(|(s, e, _)| s == "probmot.Tracks3D" && e == "protobuf"));
    let b = dir.path().join("b.mcap");
    let b_path = b.to_str().unwrap();
    probmot_ok(&[
        "track",
        input,
        "-o",
        b_path,
        "--quiet",
        "--tracks-format",
        "ros2",
    ]);
    let b_msgs = tracks_channel(&b);
    assert_eq!(a_msgs.len(), b_msgs.len());
    assert!(b_msgs
        .iter()
        .all(|(s, e, _)| s == "vision_msgs/msg/Detection3DArray" && e == "cdr"));
}
