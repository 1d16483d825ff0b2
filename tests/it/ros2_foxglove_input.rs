//! Detections from recordings written by other tools: ROS 2 `vision_msgs/msg/Detection3DArray`
//! (CDR) and Foxglove `foxglove.SceneUpdate` (protobuf cubes).
//!
//! The fixtures in `tests/fixtures/ros2/` and `tests/fixtures/foxglove/` were written by PyPI
//! `mcap-ros2-support` and `mcap-protobuf-support` + `foxglove-schemas-protobuf` from
//! `sample_logs/city.mcap` (see their README), so tracking them must give exactly the tracks of
//! the probmot log. The decoders are also tested on hand-made messages (layouts, yaw, best
//! hypothesis, metadata convention, malformed bytes). The one test that regenerates the fixtures
//! needs those Python packages and skips with a message without them.

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

#[test]
fn ros2_and_foxglove_fixtures_track_exactly_like_the_probmot_log() {
    let dir = tempfile::tempdir().unwrap();
    for (name, fixture, log, min_reports) in [
        ("ros2", ROS2_FIXTURE, PROBMOT_LOG, 500),
        ("foxglove", FOXGLOVE_FIXTURE, PROBMOT_LOG, 500),
        ("ros2 vision_msgs 2.x", ROS2_V2_FIXTURE, PROBMOT_V2_LOG, 150),
    ] {
        let reference = dir.path().join("probmot.mcap");
        track(&repo(log), &reference);
        let want = tracks(&reference, "/tracks");
        let out = dir.path().join("other.mcap");
        track(&repo(fixture), &out);
        let got = tracks(&out, "/tracks");
        assert_same_tracks(&got, &want, name, min_reports);
        // The input messages are kept byte for byte (beside the tracks and their SceneUpdate).
        let before = messages(&repo(fixture));
        let after: Vec<Msg> = messages(&out)
            .into_iter()
            .filter(|m| m.topic != "/tracks" && m.topic != "/tracks/scene")
            .collect();
        assert_eq!(before, after, "{name}: input messages changed");
    }
}

#[test]
fn fixtures_decode_to_the_boxes_of_the_probmot_log() {
    for (name, fixture, log) in [
        ("ros2", ROS2_FIXTURE, PROBMOT_LOG),
        ("foxglove", FOXGLOVE_FIXTURE, PROBMOT_LOG),
        ("ros2 vision_msgs 2.x", ROS2_V2_FIXTURE, PROBMOT_V2_LOG),
    ] {
        let want = detections(&repo(log), "/detections");
        let bytes = std::fs::read(repo(fixture)).unwrap();
        let mut frames = vec![];
        for m in mcap::MessageStream::new(&bytes).unwrap() {
            let m = m.unwrap();
            let schema = m.channel.schema.as_ref().unwrap();
            let source = DetectionSource::for_channel(
                &schema.name,
                &schema.encoding,
                &schema.data,
                &m.channel.message_encoding,
            )
            .unwrap();
            frames.push(source.decode(&m.data).unwrap());
        }
        assert_eq!(frames.len(), want.len(), "{name}");
        for (g, w) in frames.iter().zip(&want) {
            assert_eq!(g.stamp, w.stamp, "{name}");
            assert_eq!(g.frame_id, w.frame_id, "{name}");
            assert_eq!(g.detections.len(), w.detections.len(), "{name}");
            for (a, b) in g.detections.iter().zip(&w.detections) {
                assert_eq!(a.label, b.label, "{name}");
                assert_eq!(a.score, b.score, "{name}: scores are copied exactly");
                assert_eq!(a.center, b.center, "{name}: centres are copied exactly");
                assert_eq!(a.size, b.size, "{name}: sizes are copied exactly");
                if name.starts_with("ros2") {
                    assert_eq!(a.attributes.get("id"), b.attributes.get("sim_truth_id"));
                }
                close(a.yaw, b.yaw, name);
            }
        }
    }
}

#[test]
fn info_names_the_detection_channels() {
    for (fixture, how, cars) in [
        (ROS2_FIXTURE, "vision_msgs 4.x layout", 475),
        (FOXGLOVE_FIXTURE, "one box per cube", 475),
        (ROS2_V2_FIXTURE, "vision_msgs 2.x layout", 202),
    ] {
        let out = probmot_ok(&["info", repo(fixture).to_str().unwrap(), "--json"]);
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        let ch = &v["channels"][0];
        assert_eq!(ch["role"], "detections", "{fixture}");
        assert!(
            ch["detections_note"].as_str().unwrap().contains(how),
            "{ch}"
        );
        assert_eq!(ch["per_label"]["car"], cars, "{fixture}");
        assert_eq!(ch["undecodable"], 0, "{fixture}");
        let text = probmot_ok(&["info", repo(fixture).to_str().unwrap()]);
        let text = String::from_utf8(text.stdout).unwrap();
        assert!(
            text.contains("detection channels (read by `track` by default): /detections"),
            "{text}"
        );
    }
}

// ---- ROS 2: hand-made messages, serialized by the `cdr` crate (classic CDR, little endian) ----

/// The schema text of the fixture (written by mcap-ros2-support's user, scripts/).
fn fixture_schema_text() -> String {
    schema_text_of(ROS2_FIXTURE)
}

fn schema_text_of(fixture: &str) -> String {
    let bytes = std::fs::read(repo(fixture)).unwrap();
    let m = mcap::MessageStream::new(&bytes)
        .unwrap()
        .next()
        .unwrap()
        .unwrap();
    String::from_utf8(m.channel.schema.as_ref().unwrap().data.to_vec()).unwrap()
}

#[derive(Serialize, Clone)]
struct Time {
    sec: i32,
    nanosec: u32,
}
#[derive(Serialize, Clone)]
struct Header {
    stamp: Time,
    frame_id: String,
}
#[derive(Serialize, Clone, Copy)]
struct Xyz {
    x: f64,
    y: f64,
    z: f64,
}
#[derive(Serialize, Clone, Copy)]
struct Quat {
    x: f64,
    y: f64,
    z: f64,
    w: f64,
}
#[derive(Serialize, Clone, Copy)]
struct Pose {
    position: Xyz,
    orientation: Quat,
}
#[derive(Clone)]
struct Cov;
impl Serialize for Cov {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut t = s.serialize_tuple(36)?;
        for i in 0..36 {
            t.serialize_element(&(i as f64))?;
        }
        t.end()
    }
}
#[derive(Serialize, Clone)]
struct PoseCov {
    pose: Pose,
    covariance: Cov,
}
#[derive(Serialize, Clone)]
struct Hyp {
    class_id: String,
    score: f64,
}
#[derive(Serialize, Clone)]
struct HypPose {
    hypothesis: Hyp,
    pose: PoseCov,
}
#[derive(Serialize, Clone)]
struct BBox {
    center: Pose,
    size: Xyz,
}
#[derive(Serialize, Clone)]
struct Det {
    header: Header,
    results: Vec<HypPose>,
    bbox: BBox,
    id: String,
}
#[derive(Serialize, Clone)]
struct DetArray {
    header: Header,
    detections: Vec<Det>,
}

fn header(sec: i32, nanosec: u32) -> Header {
    Header {
        stamp: Time { sec, nanosec },
        frame_id: "base_link".into(),
    }
}

fn pose(q: Quat) -> Pose {
    Pose {
        position: Xyz {
            x: 1.0,
            y: -2.0,
            z: 0.5,
        },
        orientation: q,
    }
}

fn hyp(class_id: &str, score: f64) -> HypPose {
    HypPose {
        hypothesis: Hyp {
            class_id: class_id.into(),
            score,
        },
        pose: PoseCov {
            pose: pose(Quat {
                x: 0.0,
                y: 0.0,
                z: 0.0,
                w: 1.0,
            }),
            covariance: Cov,
        },
    }
}

fn det(q: Quat, results: Vec<HypPose>, id: &str) -> Det {
    Det {
        header: header(5, 6),
        results,
        bbox: BBox {
            center: pose(q),
            size: Xyz {
                x: 4.5,
                y: 1.9,
                z: 1.6,
            },
        },
        id: id.into(),
    }
}

fn cdr_bytes(m: &DetArray) -> Vec<u8> {
    cdr::serialize::<_, _, cdr::CdrLe>(m, cdr::Infinite).unwrap()
}

fn yaw_quat(yaw: f64, scale: f64) -> Quat {
    Quat {
        x: 0.0,
        y: 0.0,
        z: scale * (yaw / 2.0).sin(),
        w: scale * (yaw / 2.0).cos(),
    }
}

#[test]
fn vision_layout_is_read_from_the_schema_text() {
    let text = fixture_schema_text();
    assert_eq!(
        ros2_vision::detect_layout(text.as_bytes()),
        Ok(VisionLayout::V4)
    );
    // Comments, blank lines, constants and `pkg/msg/Type` spellings do not matter.
    let decorated = text
        .replace(
            "string class_id",
            "# the class\nstring class_id  # trailing comment\nuint8 SOME_CONSTANT=3",
        )
        .replace(
            "MSG: vision_msgs/Detection3D\n",
            "MSG: vision_msgs/msg/Detection3D\n",
        );
    assert_eq!(
        ros2_vision::detect_layout(decorated.as_bytes()),
        Ok(VisionLayout::V4)
    );
    // vision_msgs 2.x (Foxy): Detection3D with source_cloud / is_tracking / tracking_id.
    let old = text.replace(
        "BoundingBox3D bbox\n\nstring id\n",
        "BoundingBox3D bbox\n\nsensor_msgs/PointCloud2 source_cloud\nbool is_tracking\nstring tracking_id\n",
    );
    let err = ros2_vision::detect_layout(old.as_bytes()).unwrap_err();
    assert!(
        err.contains("Detection3D") && err.contains("source_cloud") && err.contains("string id"),
        "{err}"
    );
    // The 2.x layout as the fixture writer wrote it.
    let v2 = schema_text_of(ROS2_V2_FIXTURE);
    assert_eq!(
        ros2_vision::detect_layout(v2.as_bytes()),
        Ok(VisionLayout::V2)
    );
    // A 2.x Detection3D with a hypothesis of neither layout is refused.
    let bad_v2 = v2.replace("string id\n\nfloat64 score", "int64 id\n\nfloat64 score");
    let err = ros2_vision::detect_layout(bad_v2.as_bytes()).unwrap_err();
    assert!(err.contains("int64 id") && err.contains("2.x"), "{err}");
    // The older hypothesis (`string id`, score) is refused too.
    let old_hyp = text.replace("string class_id", "string id");
    let err = ros2_vision::detect_layout(old_hyp.as_bytes()).unwrap_err();
    assert!(
        err.contains("ObjectHypothesis") && err.contains("class_id"),
        "{err}"
    );
    // Without the dependency sections the layout cannot be checked.
    let top_only = text.split("=====").next().unwrap();
    let err = ros2_vision::detect_layout(top_only.as_bytes()).unwrap_err();
    assert!(err.contains("does not define Detection3D"), "{err}");
}

#[test]
fn ros2_yaw_best_hypothesis_stamp_and_id() {
    let quarter = std::f64::consts::FRAC_PI_4;
    let msg = DetArray {
        header: header(1_700_000_000, 250_000_000),
        detections: vec![
            // Best of three hypotheses, not the first; an unnormalised quaternion.
            det(
                yaw_quat(2.5, 3.0),
                vec![hyp("car", 0.3), hyp("truck", 0.8), hyp("bus", 0.5)],
                "obj-7",
            ),
            // Tie: the first of the best wins; a rotation with roll and pitch too.
            det(
                Quat {
                    // yaw pi/4 after a roll of pi/2: q = q_z(pi/4) * q_x(pi/2).
                    x: (quarter / 2.0).cos() * quarter.sin(),
                    y: (quarter / 2.0).sin() * quarter.sin(),
                    z: (quarter / 2.0).sin() * quarter.cos(),
                    w: (quarter / 2.0).cos() * quarter.cos(),
                },
                vec![hyp("pedestrian", 0.6), hyp("bicycle", 0.6)],
                "",
            ),
            // No hypothesis: empty label, score 0; yaw -3 (beyond -pi/2).
            det(yaw_quat(-3.0, 1.0), vec![], ""),
        ],
    };
    let out = ros2_vision::decode(&cdr_bytes(&msg), VisionLayout::V4).unwrap();
    assert_eq!(out.stamp, Some(1_700_000_000_250_000_000));
    assert_eq!(out.frame_id, "base_link");
    let d = &out.detections;
    assert_eq!(d.len(), 3);
    assert_eq!((d[0].label.as_str(), d[0].score), ("truck", 0.8));
    assert!((d[0].yaw - 2.5).abs() < 1e-12, "{}", d[0].yaw);
    assert_eq!(d[0].attributes.get("id").map(String::as_str), Some("obj-7"));
    let c = d[0].center.unwrap();
    assert_eq!((c.x, c.y, c.z), (1.0, -2.0, 0.5));
    let s = d[0].size.unwrap();
    assert_eq!((s.length, s.width, s.height), (4.5, 1.9, 1.6));
    assert_eq!((d[1].label.as_str(), d[1].score), ("pedestrian", 0.6));
    assert!((d[1].yaw - quarter).abs() < 1e-12, "{}", d[1].yaw);
    assert!(d[1].attributes.is_empty());
    assert_eq!((d[2].label.as_str(), d[2].score), ("", 0.0));
    assert!((d[2].yaw + 3.0).abs() < 1e-12, "{}", d[2].yaw);

    // A zero stamp is "unset" (track uses the log_time); a negative one is refused.
    let mut zero = msg.clone();
    zero.header = header(0, 0);
    let out = ros2_vision::decode(&cdr_bytes(&zero), VisionLayout::V4).unwrap();
    assert_eq!(out.stamp, None);
    let mut negative = msg.clone();
    negative.header = header(-5, 0);
    let err = ros2_vision::decode(&cdr_bytes(&negative), VisionLayout::V4).unwrap_err();
    assert!(err.to_string().contains("header.stamp"), "{err}");
    // Big-endian CDR reads the same.
    let be = cdr::serialize::<_, _, cdr::CdrBe>(&msg, cdr::Infinite).unwrap();
    let out_be = ros2_vision::decode(&be, VisionLayout::V4).unwrap();
    assert_eq!(out_be.detections[0].label, "truck");
    assert_eq!(out_be.detections[0].yaw, d[0].yaw);
}

#[test]
fn malformed_cdr_is_an_error_not_a_panic_nor_a_huge_allocation() {
    let msg = DetArray {
        header: header(3, 0),
        detections: vec![det(yaw_quat(0.1, 1.0), vec![hyp("car", 0.9)], "x")],
    };
    let good = cdr_bytes(&msg);
    for cut in [0, 3, 4, 10, good.len() / 2, good.len() - 1] {
        assert!(
            ros2_vision::decode(&good[..cut], VisionLayout::V4).is_err(),
            "truncated at {cut}"
        );
    }
    // A string length of almost 4 GiB (frame_id, right after the stamp): an error at the end of
    // the data, without reserving the declared length first.
    let mut huge = good.clone();
    huge[12..16].copy_from_slice(&0xFFFF_FFF0u32.to_le_bytes());
    let t = std::time::Instant::now();
    assert!(ros2_vision::decode(&huge, VisionLayout::V4).is_err());
    assert!(t.elapsed().as_secs_f64() < 1.0, "took {:?}", t.elapsed());
    // A string whose last byte is not NUL.
    let mut no_nul = good.clone();
    no_nul[16 + 9] = b'!'; // "base_link\0": the NUL is the 10th byte of the frame_id
    let err = ros2_vision::decode(&no_nul, VisionLayout::V4).unwrap_err();
    assert!(err.to_string().contains("NUL"), "{err}");
    // An unknown encapsulation id.
    let mut bad_id = good.clone();
    bad_id[1] = 9;
    assert!(ros2_vision::decode(&bad_id, VisionLayout::V4).is_err());
}

/// Writes an MCAP with one channel and the given messages.
fn write_mcap(
    path: &Path,
    schema: (&str, &str, &[u8]),
    topic: &str,
    message_encoding: &str,
    messages: &[Vec<u8>],
) {
    let mut w = mcap::Writer::new(std::io::BufWriter::new(
        std::fs::File::create(path).unwrap(),
    ))
    .unwrap();
    let s = w.add_schema(schema.0, schema.1, schema.2).unwrap();
    let ch = w
        .add_channel(s, topic, message_encoding, &BTreeMap::new())
        .unwrap();
    for (i, data) in messages.iter().enumerate() {
        let t = (i as u64 + 1) * 500_000_000;
        w.write_to_known_channel(
            &mcap::records::MessageHeader {
                channel_id: ch,
                sequence: i as u32,
                log_time: t,
                publish_time: t,
            },
            data,
        )
        .unwrap();
    }
    w.finish().unwrap();
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

#[test]
fn malformed_ros2_message_names_file_topic_and_message() {
    let dir = tempfile::tempdir().unwrap();
    let text = fixture_schema_text();
    let msg = DetArray {
        header: header(3, 0),
        detections: vec![det(yaw_quat(0.1, 1.0), vec![hyp("car", 0.9)], "x")],
    };
    let good = cdr_bytes(&msg);
    let path = dir.path().join("broken-ros2.mcap");
    write_mcap(
        &path,
        (
            "vision_msgs/msg/Detection3DArray",
            "ros2msg",
            text.as_bytes(),
        ),
        "/perception/objects",
        "cdr",
        &[good.clone(), good[..good.len() - 20].to_vec()],
    );
    let err = track_err(&path, &[]);
    assert!(
        err.contains("broken-ros2.mcap")
            && err.contains("/perception/objects")
            && err.contains("log_time 1000000000")
            && err.contains("vision_msgs/msg/Detection3DArray"),
        "{err}"
    );
    // The old layout is refused before any message is read, naming the differing fields.
    let old = text.replace(
        "BoundingBox3D bbox\n\nstring id\n",
        "BoundingBox3D bbox\n\nsensor_msgs/PointCloud2 source_cloud\nbool is_tracking\nstring tracking_id\n",
    );
    let path = dir.path().join("foxy.mcap");
    write_mcap(
        &path,
        (
            "vision_msgs/msg/Detection3DArray",
            "ros2msg",
            old.as_bytes(),
        ),
        "/objects",
        "cdr",
        &[good],
    );
    let err = track_err(&path, &[]);
    assert!(
        err.contains("foxy.mcap")
            && err.contains("/objects")
            && err.contains("unsupported field layout")
            && err.contains("source_cloud"),
        "{err}"
    );
}

#[test]
fn unsupported_schema_lists_the_supported_ones() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("points.mcap");
    write_mcap(
        &path,
        ("sensor_msgs/msg/PointCloud2", "ros2msg", b"uint32 height\n"),
        "/points",
        "cdr",
        &[vec![0, 1, 0, 0, 0, 0, 0, 0]],
    );
    let err = track_err(&path, &["--detections-topic", "/points"]);
    assert!(
        err.contains("points.mcap") && err.contains("/points"),
        "{err}"
    );
    assert!(err.contains("sensor_msgs/msg/PointCloud2"), "{err}");
    assert!(err.contains(SUPPORTED), "{err}");
    for name in [
        "probmot.Detections3D",
        "vision_msgs/msg/Detection3DArray",
        "foxglove.SceneUpdate",
    ] {
        assert!(SUPPORTED.contains(name));
    }
    // A known schema with the wrong encodings says which encodings are read.
    let why = DetectionSource::for_channel("foxglove.SceneUpdate", "jsonschema", b"{}", "json")
        .unwrap_err();
    assert!(
        why.contains("jsonschema") && why.contains(SUPPORTED),
        "{why}"
    );
    let why =
        DetectionSource::for_channel("vision_msgs/msg/Detection3DArray", "ros2idl", b"", "cdr")
            .unwrap_err();
    assert!(why.contains("ros2idl") && why.contains("ros2msg"), "{why}");
    // Without --detections-topic such a channel is not a detection channel: copied with a warning.
    let out = dir.path().join("copied.mcap");
    let r = probmot_ok(&[
        "track",
        path.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--json",
    ]);
    let v: serde_json::Value = serde_json::from_slice(&r.stdout).unwrap();
    assert!(v["warnings"][0]
        .as_str()
        .unwrap()
        .contains("no detection channel"));
}

// ---- Foxglove: hand-made SceneUpdates (prost types of the `foxglove` crate) ----

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

// ---- Regenerating the fixtures (needs the Python packages of scripts/requirements.txt) ----

#[test]
fn fixtures_regenerate_byte_identical() {
    let needed = "mcap, mcap_protobuf, mcap_ros2, foxglove_schemas_protobuf";
    if !common::python_has(needed) {
        common::skip(
            "fixtures_regenerate_byte_identical",
            &format!(
                "python3 cannot import {needed}; \
                 install with `python3 -m pip install -r scripts/requirements.txt`"
            ),
        );
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    for (script, log, extra, fixture) in [
        (
            "scripts/make_ros2_fixture.py",
            PROBMOT_LOG,
            None,
            ROS2_FIXTURE,
        ),
        (
            "scripts/make_ros2_fixture.py",
            PROBMOT_V2_LOG,
            Some(["--layout", "2"]),
            ROS2_V2_FIXTURE,
        ),
        (
            "scripts/make_foxglove_fixture.py",
            PROBMOT_LOG,
            None,
            FOXGLOVE_FIXTURE,
        ),
    ] {
        let out: PathBuf = dir.path().join("fixture.mcap");
        let r = Command::new("python3")
            .arg(repo(script))
            .arg(repo(log))
            .args(extra.iter().flatten())
            .arg("-o")
            .arg(&out)
            .output()
            .unwrap();
        assert!(
            r.status.success(),
            "{script}: {}",
            String::from_utf8_lossy(&r.stderr)
        );
        assert!(
            std::fs::read(&out).unwrap() == std::fs::read(repo(fixture)).unwrap(),
            "{fixture} differs from a fresh run of {script}"
        );
    }
}

// ---- Robustness and channel selection ----

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
        let mut args = vec![
            "track",
            path.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--json",
        ];
        args.extend_from_slice(extra);
        let _ = std::fs::remove_file(&out);
        serde_json::from_slice(&probmot_ok(&args).stdout).unwrap()
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
    let r = probmot_ok(&[
        "track",
        path.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--json",
    ]);
    let v: serde_json::Value = serde_json::from_slice(&r.stdout).unwrap();
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
