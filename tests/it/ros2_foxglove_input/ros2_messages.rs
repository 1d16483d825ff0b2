//! ROS 2: hand-made messages, serialized by the `cdr` crate (classic CDR, little endian).

use super::*;

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
pub(super) fn write_mcap(
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

/// A class id that is not UTF-8 costs its box, not the run: `track` tracks the other boxes of
/// its message and names the skipped box in the summary and a warning (both layouts). The log
/// times of [`write_mcap`] are far from the stamps, so `track` reads the file in two passes,
/// and both passes take the message.
#[test]
fn a_class_id_that_is_not_utf8_skips_only_its_box() {
    let dir = tempfile::tempdir().unwrap();
    for (fixture, layout) in [
        (ROS2_FIXTURE, VisionLayout::V4),
        (ROS2_V2_FIXTURE, VisionLayout::V2),
    ] {
        let bytes = std::fs::read(repo(fixture)).unwrap();
        let mut messages = Vec::new();
        let mut schema = None;
        for m in mcap::MessageStream::new(&bytes).unwrap() {
            let m = m.unwrap();
            let s = m.channel.schema.clone().unwrap();
            schema.get_or_insert(s);
            messages.push(m.data.to_vec());
        }
        // The first class id "car" of message 4 (a CDR string: length 4, the bytes, NUL).
        let at = (messages[4].windows(8))
            .position(|w| w == b"\x04\0\0\0car\0")
            .unwrap();
        messages[4][at + 4] = 0xff;
        let (_, rejected) = ros2_vision::decode_lenient(&messages[4], layout).unwrap();
        assert_eq!(rejected.len(), 1, "{fixture}: {rejected:?}");
        let schema = schema.unwrap();
        let path = dir.path().join(format!("{layout:?}.mcap"));
        let (name, enc) = (schema.name.as_str(), schema.encoding.as_str());
        write_mcap(
            &path,
            (name, enc, &schema.data),
            "/detections",
            "cdr",
            &messages,
        );
        let out = dir.path().join(format!("{layout:?}-out.mcap"));
        let s = track_json(&path, &out, &["--tracks-format", "probmot"]);
        assert_eq!(s["passes"], 2, "{s}");
        assert_eq!(s["detections"]["skipped"]["label_not_utf8"], 1, "{s}");
        let boxes: usize = (messages.iter())
            .map(|m| {
                ros2_vision::decode_lenient(m, layout)
                    .unwrap()
                    .0
                    .detections
                    .len()
            })
            .sum();
        let kept: u64 = (s["detections"]["per_label"].as_object().unwrap().values())
            .map(|v| v.as_u64().unwrap())
            .sum();
        assert_eq!(kept as usize, boxes - 1, "{s}");
        assert!(
            (s["warnings"].to_string()).contains("label not valid UTF-8 at topic /detections"),
            "{s}"
        );
        let tracks = common::tracks(&out, "/tracks");
        assert_eq!(tracks.len(), messages.len());
        assert!(
            !tracks[4].tracks.is_empty(),
            "{fixture}: tracks at message 4"
        );
    }
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
    let v = track_json(&path, &out, &[]);
    assert!(v["warnings"][0]
        .as_str()
        .unwrap()
        .contains("no detection channel"));
}
