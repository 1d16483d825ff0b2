//! The `--scene-topic` output: one `foxglove.SceneUpdate` per frame mirroring the tracks
//! channel. Checked with our prost types and with the official Foxglove Python schemas
//! (`scripts/check_scene_update.py`, PyPI `foxglove-schemas-protobuf`); without those Python
//! packages the second part says so on stderr and is skipped.

use std::collections::BTreeSet;
use std::path::Path;
use std::process::Command;

use crate::common::*;
use foxglove::schemas::SceneUpdate;
use probmot::msgs::Tracks3D;
use prost::Message as _;
use serde_json::Value;

fn tracked_with_scene(dir: &Path) -> std::path::PathBuf {
    let out = dir.join("city.tracked.mcap");
    probmot_ok(&[
        "track",
        repo("sample_logs/city.mcap").to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--scene-topic",
        "/tracks/scene",
        "--quiet",
    ]);
    out
}

/// Ids shown before and not now.
fn expected_deletions(prev: &BTreeSet<u64>, now: &Tracks3D) -> BTreeSet<String> {
    let ids: BTreeSet<u64> = now.tracks.iter().map(|t| t.id).collect();
    prev.difference(&ids)
        .map(|id| format!("track/{id}"))
        .collect()
}

#[test]
fn scene_updates_mirror_the_tracks_channel() {
    let dir = tempfile::tempdir().unwrap();
    let out = tracked_with_scene(dir.path());
    let frames = tracks(&out, "/tracks");
    let all = messages(&out);
    let scene: Vec<&Msg> = all.iter().filter(|m| m.topic == "/tracks/scene").collect();
    assert_eq!(scene.len(), frames.len());
    let mut prev = BTreeSet::new();
    let mut deleted = 0;
    for (m, f) in scene.iter().zip(&frames) {
        assert_eq!(m.schema, "foxglove.SceneUpdate");
        assert_eq!(m.log_time, f.stamp);
        let u = SceneUpdate::decode(m.data.as_slice()).unwrap();
        assert_eq!(u.entities.len(), f.tracks.len());
        for (e, t) in u.entities.iter().zip(&f.tracks) {
            assert_eq!(e.id, format!("track/{}", t.id));
            assert_eq!(e.frame_id, f.frame_id);
            let c = e.cubes[0].pose.unwrap().position.unwrap();
            let tc = t.center.unwrap();
            assert_eq!((c.x, c.y, c.z), (tc.x, tc.y, tc.z));
            assert_eq!(e.texts[0].text, format!("{} {}", t.id, t.label));
            // The metadata convention probmot reads SceneUpdate detections with.
            let meta: Vec<(&str, &str)> = e
                .metadata
                .iter()
                .map(|kv| (kv.key.as_str(), kv.value.as_str()))
                .collect();
            // The score with three decimals, within half a thousandth of the track's.
            let id = t.id.to_string();
            let score = meta[2].1;
            assert_eq!(score.len() - score.find('.').unwrap(), 4, "{score}");
            let back: f64 = score.parse().unwrap();
            assert!((back - t.score).abs() <= 5e-4, "{score} vs {}", t.score);
            assert_eq!(
                meta,
                [
                    ("label", t.label.as_str()),
                    ("track_id", &id),
                    ("score", score)
                ]
            );
        }
        let dels: BTreeSet<String> = u.deletions.iter().map(|d| d.id.clone()).collect();
        assert_eq!(dels, expected_deletions(&prev, f));
        deleted += dels.len();
        prev = f.tracks.iter().map(|t| t.id).collect();
    }
    assert!(deleted > 0, "some tracks die in the city log");
}

#[test]
fn tracking_a_tracked_log_again_does_not_read_its_scene_output() {
    // The scene channel is marked as probmot's output: by default the second run reads only
    // /detections and gives the same tracks; named with --detections-topic it is read, and its
    // boxes (the tracks) carry the labels and scores of the metadata.
    let dir = tempfile::tempdir().unwrap();
    let first = tracked_with_scene(dir.path());
    let again = dir.path().join("again.mcap");
    let out = probmot_ok(&[
        "track",
        first.to_str().unwrap(),
        "-o",
        again.to_str().unwrap(),
        "--tracks-topic",
        "/tracks2",
        "--json",
    ]);
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["detection_topics"], serde_json::json!(["/detections"]));
    assert_eq!(tracks(&again, "/tracks2"), tracks(&first, "/tracks"));
    let info = probmot_ok(&["info", first.to_str().unwrap(), "--json"]);
    let info: Value = serde_json::from_slice(&info.stdout).unwrap();
    let scene = info["channels"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["topic"] == "/tracks/scene")
        .unwrap();
    assert_eq!(scene["role"], "detections");
    assert_eq!(scene["default_detections"], false);
    let from_scene = dir.path().join("scene.mcap");
    probmot_ok(&[
        "track",
        first.to_str().unwrap(),
        "-o",
        from_scene.to_str().unwrap(),
        "--tracks-topic",
        "/tracks3",
        "--detections-topic",
        "/tracks/scene",
        "--quiet",
    ]);
    let labels: BTreeSet<String> = tracks(&from_scene, "/tracks3")
        .iter()
        .flat_map(|f| f.tracks.iter().map(|t| t.label.clone()))
        .collect();
    let want: BTreeSet<String> = tracks(&first, "/tracks")
        .iter()
        .flat_map(|f| f.tracks.iter().map(|t| t.label.clone()))
        .collect();
    assert_eq!(labels, want);
}

#[test]
fn a_scene_topic_that_exists_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let out = probmot(&[
        "track",
        repo("sample_logs/city.mcap").to_str().unwrap(),
        "-o",
        dir.path().join("x.mcap").to_str().unwrap(),
        "--scene-topic",
        "/ground_truth",
    ]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--scene-topic"));
}

#[test]
fn official_foxglove_python_schemas_decode_the_scene_updates() {
    if !python_has("mcap, foxglove_schemas_protobuf") {
        skip(
            "official_foxglove_python_schemas_decode_the_scene_updates",
            "`python3 -c \"import mcap, foxglove_schemas_protobuf\"` failed; install with \
             `python3 -m pip install -r scripts/requirements.txt`",
        );
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let out = tracked_with_scene(dir.path());
    let run = Command::new("python3")
        .arg(repo("scripts/check_scene_update.py"))
        .arg(&out)
        .args(["--topic", "/tracks/scene"])
        .output()
        .expect("run python3 scripts/check_scene_update.py");
    assert!(
        run.status.success(),
        "check_scene_update.py failed: {}",
        String::from_utf8_lossy(&run.stderr)
    );
    let lines: Vec<Value> = String::from_utf8_lossy(&run.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let frames = tracks(&out, "/tracks");
    assert_eq!(lines.len(), frames.len());
    let mut prev = BTreeSet::new();
    let mut arrows = 0;
    for (l, f) in lines.iter().zip(&frames) {
        assert_eq!(l["log_time"].as_u64(), Some(f.stamp));
        let ents = l["entities"].as_array().unwrap();
        assert_eq!(ents.len(), f.tracks.len());
        for (e, t) in ents.iter().zip(&f.tracks) {
            assert_eq!(e["id"], format!("track/{}", t.id));
            assert_eq!(e["frame_id"], f.frame_id.as_str());
            assert_eq!(e["stamp_ns"].as_u64(), Some(f.stamp));
            assert_eq!(e["lifetime_ns"], 0);
            let cube = &e["cubes"][0];
            let (c, s) = (t.center.unwrap(), t.size.unwrap());
            let num = |v: &Value| v.as_f64().unwrap();
            let near = |a: f64, b: f64| (a - b).abs() <= 1e-12 * b.abs().max(1.0);
            for (got, want) in [
                (num(&cube["position"][0]), c.x),
                (num(&cube["position"][1]), c.y),
                (num(&cube["position"][2]), c.z),
                (num(&cube["size"][0]), s.length),
                (num(&cube["size"][1]), s.width),
                (num(&cube["size"][2]), s.height),
            ] {
                assert!(near(got, want), "track {}: {got} vs {want}", t.id);
            }
            // Orientation: a rotation about z by the track's yaw (its components have a 12-bit
            // mantissa: within 1/2048 rad).
            let yaw = 2.0 * num(&cube["orientation"][2]).atan2(num(&cube["orientation"][3]));
            assert!(
                (yaw - t.yaw).abs() < 5e-4,
                "track {}: {yaw} vs {}",
                t.id,
                t.yaw
            );
            assert_eq!(e["texts"][0], format!("{} {}", t.id, t.label));
            let v = t.velocity.unwrap();
            let n_arrows = e["arrows"].as_array().unwrap().len();
            assert_eq!(n_arrows, usize::from(v.x.hypot(v.y) > 0.2));
            arrows += n_arrows;
        }
        let dels: BTreeSet<String> = l["deletions"]
            .as_array()
            .unwrap()
            .iter()
            .map(|d| {
                assert_eq!(d["type"], 0, "MATCHING_ID");
                d["id"].as_str().unwrap().to_string()
            })
            .collect();
        assert_eq!(dels, expected_deletions(&prev, f));
        prev = f.tracks.iter().map(|t| t.id).collect();
    }
    assert!(arrows > 0);
    eprintln!(
        "check_scene_update.py: {} scene updates decoded by foxglove-schemas-protobuf agree",
        lines.len()
    );
}
