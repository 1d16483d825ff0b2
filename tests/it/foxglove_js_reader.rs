//! A tracked log read by the libraries the Foxglove app uses: `scripts/js/check_tracked.mjs`
//! (`@mcap/core` indexed and stream readers, `@mcap/support` decompressors, `protobufjs` with
//! the descriptors embedded in the file) must decode every `/tracks` Tracks3D and
//! `/tracks/scene` SceneUpdate message into exactly the ids, stamps and box centres that prost
//! decodes, and its stream reader must see the messages in log-time order.
//!
//! Needs Node (20) and `npm ci` in scripts/js (run by `.ci/run`); without them the test prints
//! SKIPPED on stderr and passes (fails under CI=true).

use std::path::Path;
use std::process::Command;

use crate::common::*;
use foxglove::schemas::SceneUpdate;
use prost::Message as _;
use serde_json::Value;

/// Why the script cannot run here, if it cannot.
fn missing_node() -> Option<String> {
    let node = Command::new("node").arg("--version").output();
    if !node.is_ok_and(|o| o.status.success()) {
        return Some("`node --version` failed; install Node.js 20".into());
    }
    let modules = repo("scripts/js/node_modules/@mcap/core");
    if !modules.exists() {
        return Some(format!(
            "{} is missing; run `npm ci` in scripts/js",
            modules.display()
        ));
    }
    None
}

/// The script's JSON for `file`.
fn check_tracked(file: &Path) -> Value {
    let out = Command::new("node")
        .arg(repo("scripts/js/check_tracked.mjs"))
        .arg(file)
        .output()
        .expect("run node scripts/js/check_tracked.mjs");
    assert!(
        out.status.success(),
        "check_tracked.mjs {} failed: {}",
        file.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("JSON from check_tracked.mjs")
}

fn centers(v: &Value) -> Vec<[f64; 3]> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|c| {
            let c = c.as_array().unwrap();
            [0, 1, 2].map(|i| c[i].as_f64().unwrap())
        })
        .collect()
}

fn strings(v: &Value) -> Vec<String> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|s| s.as_str().unwrap().to_string())
        .collect()
}

/// Compares the script's frames of `file` with prost's, message by message, in log-time order
/// (the order of the indexed reader); returns the number of messages compared.
fn assert_same_as_prost(file: &Path, js: &Value) -> usize {
    let mut ours: Vec<Msg> = messages(file)
        .into_iter()
        .filter(|m| m.topic == "/tracks" || m.topic == "/tracks/scene")
        .collect();
    ours.sort_by_key(|m| m.log_time);
    let theirs = js["frames"].as_array().unwrap();
    let theirs: Vec<&Value> = theirs
        .iter()
        .filter(|f| f["topic"] == "/tracks" || f["topic"] == "/tracks/scene")
        .collect();
    assert_eq!(theirs.len(), ours.len(), "{}: messages", file.display());
    for (m, f) in ours.iter().zip(&theirs) {
        let what = format!("{} {} at {}", file.display(), m.topic, m.log_time);
        assert_eq!(f["topic"], m.topic.as_str(), "{what}: order");
        assert_eq!(f["log_time"], m.log_time.to_string(), "{what}");
        let (stamp, frame_id, ids, boxes, deletions): (u64, String, Vec<String>, Vec<[f64; 3]>, _) =
            if m.topic == "/tracks" {
                let t = probmot::msgs::Tracks3D::decode(m.data.as_slice()).unwrap();
                let ids = t.tracks.iter().map(|t| t.id.to_string()).collect();
                let boxes = t.tracks.iter().map(|t| t.center.unwrap());
                let boxes = boxes.map(|c| [c.x, c.y, c.z]).collect();
                (t.stamp, t.frame_id, ids, boxes, vec![])
            } else {
                let u = SceneUpdate::decode(m.data.as_slice()).unwrap();
                let ids: Vec<String> = u.entities.iter().map(|e| e.id.clone()).collect();
                let boxes = u
                    .entities
                    .iter()
                    .map(|e| e.cubes[0].pose.unwrap().position.unwrap());
                let boxes = boxes.map(|c| [c.x, c.y, c.z]).collect();
                let dels = u.deletions.iter().map(|d| d.id.clone()).collect();
                let ts = u.entities.first().map(|e| e.timestamp.unwrap());
                let stamp = ts.map_or(0, |t| t.total_nanos());
                let frame_id = u.entities.first().map(|e| e.frame_id.clone());
                (stamp, frame_id.unwrap_or_default(), ids, boxes, dels)
            };
        if !ids.is_empty() {
            assert_eq!(f["stamp"], stamp.to_string(), "{what}");
            assert_eq!(f["frame_id"], frame_id.as_str(), "{what}");
        }
        assert_eq!(strings(&f["ids"]), ids, "{what}");
        // Bit for bit: JSON numbers of JavaScript doubles read back exactly.
        assert_eq!(centers(&f["centers"]), boxes, "{what}");
        assert_eq!(strings(&f["deletions"]), deletions, "{what}");
    }
    ours.len()
}

#[test]
fn foxglove_libraries_decode_every_tracks_message() {
    if let Some(why) = missing_node() {
        skip("foxglove_libraries_decode_every_tracks_message", &why);
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    // The default output (zstd chunks) and lz4 chunks, as Foxglove decompresses both.
    for (sample, compression) in [("city", "zstd"), ("pedestrians", "lz4")] {
        let out = dir.path().join(format!("{sample}.tracked.mcap"));
        probmot_ok(&[
            "track",
            "-q",
            repo(&format!("sample_logs/{sample}.mcap"))
                .to_str()
                .unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--compression",
            compression,
        ]);
        let js = check_tracked(&out);
        let n = assert_same_as_prost(&out, &js);
        let frames = tracks(&out, "/tracks").len();
        assert!(frames >= 40, "{sample}: {frames} frames");
        assert_eq!(n, 2 * frames, "{sample}: a SceneUpdate per tracks message");
        let total = messages(&out).len() as u64;
        assert_eq!(js["indexed_messages"], total, "{sample}");
        assert_eq!(js["stream_messages"], total, "{sample}");
        assert_eq!(
            js["log_time_backwards"], 0,
            "{sample}: a stream reader sees every message in log-time order"
        );
        let scene = js["channels"]
            .as_array()
            .unwrap()
            .iter()
            .find(|c| c["topic"] == "/tracks/scene")
            .expect("a /tracks/scene channel");
        assert_eq!(scene["schema"], "foxglove.SceneUpdate");
    }
}
