//! Class ids and per-object ids that are not UTF-8, in messages of both layouts written with
//! [`CdrWriter`] (strings as raw bytes).

use super::*;
use crate::msgs::cdr_writer::CdrWriter;

/// One box: its hypotheses `(class id, score)` and its per-object id, as bytes.
struct TestBox {
    hypotheses: Vec<(&'static [u8], f64)>,
    id: &'static [u8],
}

/// A box of one hypothesis of score 0.9.
fn one(class: &'static [u8], id: &'static [u8]) -> TestBox {
    TestBox {
        hypotheses: vec![(class, 0.9)],
        id,
    }
}

/// A CDR `string` of any bytes: length counting the NUL, the bytes, the NUL.
fn raw_string(w: &mut CdrWriter, s: &[u8]) {
    w.u32(s.len() as u32 + 1);
    w.bytes(s);
    w.u8(0);
}

/// `std_msgs/Header` at 5 s with the given frame id.
fn header(w: &mut CdrWriter, frame_id: &[u8]) {
    w.i32(5);
    w.u32(0);
    raw_string(w, frame_id);
}

/// `geometry_msgs/PoseWithCovariance` (identity pose, zero covariance).
fn pose_with_covariance(w: &mut CdrWriter) {
    w.pose([0.0; 3], 0.0);
    for _ in 0..36 {
        w.f64(0.0);
    }
}

/// `vision_msgs/BoundingBox3D` at x = `x`.
fn bbox(w: &mut CdrWriter, x: f64) {
    w.pose([x, 2.0, 0.5], 0.3);
    for v in [4.5, 1.9, 1.6] {
        w.f64(v);
    }
}

/// A `Detection3DArray` of `layout` in frame `frame_id`; the box `i` lies at x = `i`. In the
/// 2.x layout each source cloud has one point field named `field`.
fn message(layout: VisionLayout, frame_id: &[u8], field: &[u8], boxes: &[TestBox]) -> Vec<u8> {
    let mut buf = Vec::new();
    let mut w = CdrWriter::new(&mut buf);
    header(&mut w, frame_id);
    w.u32(boxes.len() as u32);
    for (i, b) in boxes.iter().enumerate() {
        header(&mut w, b"map");
        w.u32(b.hypotheses.len() as u32);
        // Both layouts write a hypothesis as class id, score, pose.
        for &(class, score) in &b.hypotheses {
            raw_string(&mut w, class);
            w.f64(score);
            pose_with_covariance(&mut w);
        }
        bbox(&mut w, i as f64);
        if layout == VisionLayout::V2 {
            source_cloud(&mut w, field);
            w.bool(true);
        }
        raw_string(&mut w, b.id);
    }
    buf
}

/// `sensor_msgs/PointCloud2` without points, with one point field named `field`.
fn source_cloud(w: &mut CdrWriter, field: &[u8]) {
    header(w, b"lidar");
    w.u32(1); // height
    w.u32(0); // width
    w.u32(1);
    raw_string(w, field);
    w.u32(0); // offset
    w.u8(7); // datatype FLOAT32
    w.u32(1); // count
    w.bool(false);
    w.u32(16); // point_step
    w.u32(0); // row_step
    w.u32(0); // no data
    w.bool(true);
}

const LAYOUTS: [VisionLayout; 2] = [VisionLayout::V4, VisionLayout::V2];

/// The middle one of three boxes has a class id that is not UTF-8: the other two are read
/// exactly, the middle one is named for rejection, and the strict decode refuses the message.
#[test]
fn a_class_id_that_is_not_utf8_names_only_its_box() {
    for layout in LAYOUTS {
        let boxes = [one(b"car", b"a"), one(b"\xffcar", b"b"), one(b"bus", b"c")];
        let bytes = message(layout, b"map", b"x", &boxes);
        let (msg, rejected) = decode_lenient(&bytes, layout).unwrap();
        assert_eq!(rejected, [(1, SkipReason::LabelNotUtf8)], "{layout:?}");
        assert_eq!(
            (msg.stamp, msg.frame_id.as_str()),
            (Some(5_000_000_000), "map")
        );
        let d = &msg.detections;
        assert_eq!(d.len(), 3);
        assert_eq!((d[0].label.as_str(), d[0].score), ("car", 0.9));
        assert_eq!((d[2].label.as_str(), d[2].score), ("bus", 0.9));
        assert_eq!(d[2].center.unwrap().x, 2.0);
        assert_eq!(d[2].attributes.get("id").map(String::as_str), Some("c"));
        assert_eq!(d[1].label, "\u{fffd}car", "read lossily, for the warning");
        let err = decode(&bytes, layout).unwrap_err().to_string();
        assert!(
            err.contains("detection 1") && err.contains("UTF-8"),
            "{err}"
        );
        // The same message with valid class ids names no box.
        let fine = [one(b"car", b"a"), one(b"bus", b"b")];
        let bytes = message(layout, b"map", b"x", &fine);
        assert_eq!(decode_lenient(&bytes, layout).unwrap().1, []);
        assert_eq!(decode(&bytes, layout).unwrap().detections.len(), 2);
    }
}

/// A box whose best hypothesis is valid but another one is not is rejected as well; a bad
/// per-object id rejects its box with its own reason.
#[test]
fn any_bad_hypothesis_or_id_rejects_the_box() {
    for layout in LAYOUTS {
        let boxes = [
            TestBox {
                hypotheses: vec![(b"car", 0.9), (b"tr\xc3\x28ck", 0.2)],
                id: b"a",
            },
            one(b"bus", b"\xfe7"),
            one(b"car", b""),
        ];
        let bytes = message(layout, b"map", b"x", &boxes);
        let (msg, rejected) = decode_lenient(&bytes, layout).unwrap();
        let want = [(0, SkipReason::LabelNotUtf8), (1, SkipReason::IdNotUtf8)];
        assert_eq!(rejected, want, "{layout:?}");
        assert_eq!(
            msg.detections[0].label, "car",
            "the best hypothesis is valid"
        );
        assert_eq!(msg.detections[2].label, "car");
    }
}

/// A frame id (or a point field name) that is not UTF-8 still fails the whole message.
#[test]
fn other_strings_that_are_not_utf8_fail_the_message() {
    for layout in LAYOUTS {
        let boxes = [one(b"car", b"a")];
        let bytes = message(layout, b"m\xffp", b"x", &boxes);
        let err = decode_lenient(&bytes, layout).unwrap_err().to_string();
        assert!(err.contains("string") && err.contains("utf-8"), "{err}");
    }
    let bytes = message(VisionLayout::V2, b"map", b"\xff", &[one(b"car", b"a")]);
    assert!(decode_lenient(&bytes, VisionLayout::V2).is_err());
    let bytes = message(VisionLayout::V2, b"map", b"x", &[one(b"car", b"a")]);
    assert!(decode_lenient(&bytes, VisionLayout::V2).is_ok());
}
