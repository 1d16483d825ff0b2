//! Ego motion: a simulated drive whose detections are given in the frame of a turning ego
//! vehicle (`probmot simulate --ego-frame`) tracks exactly like the same drive given in the
//! fixed frame, when the transforms are used; without them it tracks much worse.

use std::path::{Path, PathBuf};

use crate::common::*;
use probmot::msgs::Tracks3D;
use probmot::sim::ego::ego_pose;
use probmot::sim::write::START_NS;
use serde_json::Value;

const SIM: [&str; 8] = [
    "--scenario",
    "city",
    "--seed",
    "1",
    "--frames",
    "40",
    "--objects",
    "40",
];

fn simulate(dir: &Path, name: &str, extra: &[&str]) -> PathBuf {
    let out = dir.join(name);
    let mut args = vec!["simulate"];
    args.extend(SIM);
    args.extend(extra);
    args.extend(["-o", out.to_str().unwrap()]);
    probmot_ok(&args);
    out
}

fn overall(truth: &Path, truth_topic: &str, tracks_topic: &str) -> Value {
    let out = probmot_ok(&[
        "eval",
        "--truth",
        truth.to_str().unwrap(),
        "--truth-topic",
        truth_topic,
        "--tracks-topic",
        tracks_topic,
        "--json",
    ]);
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    v["result"]["overall"].clone()
}

fn angle_diff(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(std::f64::consts::TAU);
    d.min(std::f64::consts::TAU - d)
}

fn stamp_secs(stamp: u64) -> f64 {
    (stamp - START_NS) as f64 * 1e-9
}

#[test]
fn ego_frame_detections_are_the_fixed_frame_detections_moved() {
    let dir = tempfile::tempdir().unwrap();
    let map = simulate(dir.path(), "map.mcap", &[]);
    let ego = simulate(dir.path(), "ego.mcap", &["--ego-frame"]);
    let a = detections(&map, "/detections");
    let b = detections(&ego, "/detections");
    assert_eq!(a.len(), b.len());
    let mut turned = false;
    for (fa, fb) in a.iter().zip(&b) {
        assert_eq!(
            (fa.frame_id.as_str(), fb.frame_id.as_str()),
            ("map", "base_link")
        );
        let pose = ego_pose(stamp_secs(fa.stamp.unwrap()));
        turned |= pose.yaw.abs() > 1.0;
        assert_eq!(fa.detections.len(), fb.detections.len());
        for (da, db) in fa.detections.iter().zip(&fb.detections) {
            let c = da.center.unwrap();
            let e = pose.to_ego([c.x, c.y, c.z]);
            let g = db.center.unwrap();
            assert!((e[0] - g.x).abs() < 1e-9 && (e[1] - g.y).abs() < 1e-9);
            assert!(angle_diff(da.yaw - pose.yaw, db.yaw) < 1e-9);
            assert_eq!((&da.label, &da.attributes), (&db.label, &db.attributes));
        }
    }
    assert!(turned, "the ego vehicle turns during the drive");
    // The ground truth stays in the fixed frame.
    let ta = tracks(&map, "/ground_truth");
    let tb = tracks(&ego, "/ground_truth");
    assert_eq!(ta, tb);
}

#[test]
fn with_transforms_the_tracks_match_the_fixed_frame_run() {
    let dir = tempfile::tempdir().unwrap();
    let map = simulate(dir.path(), "map.mcap", &[]);
    let ego = simulate(dir.path(), "ego.mcap", &["--ego-frame"]);
    let map_out = dir.path().join("map.tracked.mcap");
    let ego_out = dir.path().join("ego.tracked.mcap");
    track_json(&map, &map_out, &[]);
    let s = track_json(&ego, &ego_out, &["--tracks-frame", "ego"]);
    assert_eq!(s["ego"]["fixed_frame"], "map");
    assert_eq!(s["ego"]["messages_transformed"], 40);
    assert_eq!(s["ego"]["messages_without_transform"], 0);

    let a = tracks(&map_out, "/tracks");
    let b = tracks(&ego_out, "/tracks");
    assert_eq!(a.len(), b.len());
    let mut n = 0;
    for (fa, fb) in a.iter().zip(&b) {
        assert_eq!(fb.frame_id, "map");
        let ids_a: Vec<u64> = fa.tracks.iter().map(|t| t.id).collect();
        let ids_b: Vec<u64> = fb.tracks.iter().map(|t| t.id).collect();
        assert_eq!(ids_a, ids_b, "track ids at stamp {}", fa.stamp);
        for (ta, tb) in fa.tracks.iter().zip(&fb.tracks) {
            let (ca, cb) = (ta.center.unwrap(), tb.center.unwrap());
            let (va, vb) = (ta.velocity.unwrap(), tb.velocity.unwrap());
            for (x, y) in [
                (ca.x, cb.x),
                (ca.y, cb.y),
                (ca.z, cb.z),
                (va.x, vb.x),
                (va.y, vb.y),
            ] {
                assert!((x - y).abs() < 1e-6, "track {}: {x} vs {y}", ta.id);
            }
            assert!(angle_diff(ta.yaw, tb.yaw) < 1e-6);
            assert_eq!(ta.label, tb.label);
            n += 1;
        }
    }
    assert!(n > 500, "{n} track reports compared");

    // The ego-frame channel holds the same tracks moved into base_link at each stamp.
    let e = tracks(&ego_out, "/tracks/ego");
    assert_eq!(e.len(), b.len());
    for (fe, fb) in e.iter().zip(&b) {
        assert_eq!((fe.stamp, fe.frame_id.as_str()), (fb.stamp, "base_link"));
        let pose = ego_pose(stamp_secs(fb.stamp));
        for (te, tb) in fe.tracks.iter().zip(&fb.tracks) {
            assert_eq!(te.id, tb.id);
            let c = tb.center.unwrap();
            let want = pose.to_ego([c.x, c.y, c.z]);
            let got = te.center.unwrap();
            assert!((want[0] - got.x).abs() < 1e-9 && (want[1] - got.y).abs() < 1e-9);
            assert!(angle_diff(pose.yaw_to_ego(tb.yaw), te.yaw) < 1e-9);
        }
    }
}

#[test]
fn without_transforms_tracking_is_visibly_worse() {
    let dir = tempfile::tempdir().unwrap();
    let ego = simulate(dir.path(), "ego.mcap", &["--ego-frame"]);
    let with = dir.path().join("with.mcap");
    let without = dir.path().join("without.mcap");
    track_json(&ego, &with, &[]);
    // Tracking in the moving frame itself: no transform is used.
    let s = track_json(&ego, &without, &["--fixed-frame", "base_link"]);
    assert_eq!(s["ego"]["messages_transformed"], 0);
    let good = overall(&with, "/ground_truth", "/tracks");
    // Scored in base_link against the truth moved into base_link (distances are the same in
    // any frame, so the two scores are comparable).
    let bad = overall(&without, "/ground_truth/ego", "/tracks");
    let (ga, ba) = (
        good["amota"].as_f64().unwrap(),
        bad["amota"].as_f64().unwrap(),
    );
    let (gi, bi) = (good["ids"].as_f64().unwrap(), bad["ids"].as_f64().unwrap());
    eprintln!("AMOTA with transforms {ga:.3}, without {ba:.3}; IDS {gi} vs {bi}");
    assert!(ga > ba + 0.3, "AMOTA {ga} vs {ba}");
    assert!(bi > gi, "IDS {gi} vs {bi}");
}

/// Copies an MCAP, dropping the messages of `topic` with log_time after `after`.
fn drop_messages(input: &Path, output: &Path, topic: &str, after: u64) {
    rewrite(input, output, |m| {
        !(m.channel.topic == topic && m.log_time > after)
    });
}

/// Copies an MCAP through `keep`, which may change a message or drop it (false).
fn rewrite(input: &Path, output: &Path, mut keep: impl FnMut(&mut mcap::Message) -> bool) {
    let bytes = std::fs::read(input).unwrap();
    let mut w = mcap::Writer::new(std::io::BufWriter::new(
        std::fs::File::create(output).unwrap(),
    ))
    .unwrap();
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let mut m = m.unwrap();
        if keep(&mut m) {
            w.write(&m).unwrap();
        }
    }
    w.finish().unwrap();
}

#[test]
fn a_missing_transform_skips_the_frame_with_a_warning_or_fails_with_strict() {
    let dir = tempfile::tempdir().unwrap();
    let ego = simulate(dir.path(), "ego.mcap", &["--ego-frame"]);
    let cut = dir.path().join("cut.mcap");
    // Transforms for the first 10 s only; frames are 0.5 s apart.
    drop_messages(&ego, &cut, "/tf", START_NS + 10_000_000_000);
    let out = dir.path().join("out.mcap");
    let s = track_json(&cut, &out, &["--tf-tolerance", "0.2"]);
    // Frames at 0.0 .. 19.5 s: 10.0 is the last with a transform, and 10.5 is beyond the
    // 0.2 s tolerance, so 19 frames have none.
    assert_eq!(s["ego"]["messages_without_transform"], 19);
    assert!(s["ego"]["boxes_without_transform"].as_u64().unwrap() > 0);
    let w = s["warnings"].to_string();
    assert!(
        w.contains("missing transform") && w.contains("/detections"),
        "{w}"
    );
    // Every frame still gets a tracks message, in the fixed frame.
    let t: Vec<Tracks3D> = tracks(&out, "/tracks");
    assert_eq!(t.len(), 40);
    assert!(t.iter().all(|f| f.frame_id == "map"));

    let strict = probmot(&[
        "track",
        cut.to_str().unwrap(),
        "-o",
        dir.path().join("strict.mcap").to_str().unwrap(),
        "--strict",
    ]);
    assert!(!strict.status.success());
    let err = String::from_utf8_lossy(&strict.stderr);
    assert!(
        err.contains("no transform from 'base_link' to the fixed frame 'map'")
            && err.contains("/detections"),
        "{err}"
    );
    assert!(!dir.path().join("strict.mcap").exists());

    // The one-line summary counts the boxes skipped for a missing transform.
    let plain = probmot_ok(&[
        "track",
        cut.to_str().unwrap(),
        "-o",
        dir.path().join("plain.mcap").to_str().unwrap(),
        "--tf-tolerance",
        "0.2",
    ]);
    let skipped = s["ego"]["boxes_without_transform"].as_u64().unwrap();
    let line = String::from_utf8_lossy(&plain.stdout);
    assert!(
        line.contains(&format!(", {skipped} boxes skipped,")),
        "{line}"
    );
}

/// A `--fixed-frame` that no transform of the log names (a typo, say) would skip every message
/// in another frame: it is an error naming the frames the transforms have, and nothing is
/// written. Detections already in the named frame need no transform.
#[test]
fn a_fixed_frame_outside_the_transform_tree_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let ego = simulate(dir.path(), "ego.mcap", &["--ego-frame"]);
    let city = repo("sample_logs/city.mcap");
    let cases = [
        (&ego, "odom", "its transforms name map, base_link"),
        (&city, "mapp", "the log has no transforms"),
    ];
    for (input, frame, frames) in cases {
        let out = dir.path().join(format!("{frame}.mcap"));
        let args = [
            "track",
            input.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ];
        let r = probmot(&[&args[..], &["--fixed-frame", frame]].concat());
        assert_eq!(r.status.code(), Some(2), "{frame}");
        let err = String::from_utf8_lossy(&r.stderr);
        let want = format!("--fixed-frame '{frame}' is in no transform of the log");
        assert!(err.contains(&want) && err.contains(frames), "{err}");
        assert!(err.contains("topic /detections"), "{err}");
        assert!(!out.exists(), "{frame}");
    }
    let s = track_json(
        &city,
        &dir.path().join("map.mcap"),
        &["--fixed-frame", "map"],
    );
    assert_eq!(s["ego"]["messages_without_transform"], 0);
}

#[test]
fn info_prints_the_transform_tree() {
    let dir = tempfile::tempdir().unwrap();
    let ego = simulate(dir.path(), "ego.mcap", &["--ego-frame"]);
    let out = probmot_ok(&["info", ego.to_str().unwrap()]);
    let text = String::from_utf8_lossy(&out.stdout);
    let tree = text
        .split("transform tree:")
        .nth(1)
        .expect("a tree section");
    let lines: Vec<&str> = tree.lines().filter(|l| !l.trim().is_empty()).collect();
    assert_eq!(lines[0].trim(), "map");
    assert!(
        lines[1].trim().starts_with("base_link  (196 transforms"),
        "{text}"
    );
    assert!(text.contains("/tf") && text.contains("usable as transforms"));
    let json = probmot_ok(&["info", ego.to_str().unwrap(), "--json"]);
    let v: Value = serde_json::from_slice(&json.stdout).unwrap();
    assert_eq!(v["transform_tree"][0]["parent"], "map");
    assert_eq!(v["transform_tree"][0]["child"], "base_link");
}

#[test]
fn an_undecodable_transform_message_is_a_warning_or_a_strict_error() {
    let dir = tempfile::tempdir().unwrap();
    let ego = simulate(dir.path(), "ego.mcap", &["--ego-frame"]);
    let bad = dir.path().join("bad.mcap");
    let mut n = 0;
    rewrite(&ego, &bad, |m| {
        if m.channel.topic == "/tf" && m.sequence == 12 {
            m.data = std::borrow::Cow::Owned(vec![0xff, 0xff, 0xff]);
            n += 1;
        }
        true
    });
    assert_eq!(n, 1);
    let s = track_json(&bad, &dir.path().join("out.mcap"), &[]);
    assert_eq!(s["ego"]["undecodable_transform_messages"], 1);
    // The other transforms still cover every frame.
    assert_eq!(s["ego"]["messages_without_transform"], 0);
    let w = s["warnings"].to_string();
    assert!(
        w.contains("could not be decoded") && w.contains("/tf"),
        "{w}"
    );
    let strict = probmot(&[
        "track",
        bad.to_str().unwrap(),
        "-o",
        dir.path().join("strict.mcap").to_str().unwrap(),
        "--strict",
    ]);
    assert!(!strict.status.success());
    let err = String::from_utf8_lossy(&strict.stderr);
    assert!(
        err.contains("topic /tf") && err.contains("foxglove.FrameTransform"),
        "{err}"
    );
}

#[test]
fn without_transforms_the_ego_channel_equals_the_tracks() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.mcap");
    let s = track_json(
        &repo("sample_logs/turning-car.mcap"),
        &out,
        &["--tracks-frame", "ego"],
    );
    assert!(s["ego"]["fixed_frame"].is_null());
    let a = tracks(&out, "/tracks");
    let b = tracks(&out, "/tracks/ego");
    assert_eq!(a.len(), 40);
    assert!(a == b, "the ego channel differs from the tracks channel");
}
