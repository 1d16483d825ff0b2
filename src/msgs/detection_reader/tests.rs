//! The fast reader against prost: generated messages (field by field and whole prost
//! encodings), damaged bytes, and the limits where prost refuses a message.

use super::*;
use crate::msgs::{test_box, v3, Detection3D, Detections3D, Size3};
use proptest::prelude::*;
use prost::encoding::{encode_key, encode_varint};
use prost::Message;

const PROBMOT: DetectionSource = DetectionSource::Probmot(Encoding::Protobuf);

/// An unknown field: its tag above the message's own, wire type and value.
#[derive(Debug, Clone)]
enum Unknown {
    Varint(u32, u64),
    Fixed64(u32, u64),
    Fixed32(u32, u32),
    Bytes(u32, Vec<u8>),
}

/// One field of a `Detection3D` (sub-messages as their own fields, possibly partial).
#[derive(Debug, Clone)]
enum BoxField {
    Center(Vec<(u32, f64)>),
    Size(Vec<(u32, f64)>),
    Yaw(f64),
    Label(String),
    Score(f64),
    Velocity(Vec<(u32, f64)>),
    ImageBox(Vec<(u32, f64)>),
    /// A map entry: key, value (absent ones default) and unknown fields, in this order.
    Attribute(Option<String>, Option<String>, Vec<Unknown>),
    Unknown(Unknown),
}

/// One field of a `Detections3D`.
#[derive(Debug, Clone)]
enum Field {
    Stamp(u64),
    FrameId(String),
    Detection(Vec<BoxField>),
    Unknown(Unknown),
}

fn delimited(buf: &mut Vec<u8>, tag: u32, payload: &[u8]) {
    encode_key(tag, WireType::LengthDelimited, buf);
    encode_varint(payload.len() as u64, buf);
    buf.extend_from_slice(payload);
}

fn double(buf: &mut Vec<u8>, tag: u32, v: f64) {
    encode_key(tag, WireType::SixtyFourBit, buf);
    buf.extend_from_slice(&v.to_le_bytes());
}

/// Encodes an unknown field, its tag `base + t`.
fn unknown(buf: &mut Vec<u8>, base: u32, u: &Unknown) {
    match u {
        Unknown::Varint(t, v) => {
            encode_key(base + t, WireType::Varint, buf);
            encode_varint(*v, buf);
        }
        Unknown::Fixed64(t, v) => {
            encode_key(base + t, WireType::SixtyFourBit, buf);
            buf.extend_from_slice(&v.to_le_bytes());
        }
        Unknown::Fixed32(t, v) => {
            encode_key(base + t, WireType::ThirtyTwoBit, buf);
            buf.extend_from_slice(&v.to_le_bytes());
        }
        Unknown::Bytes(t, v) => delimited(buf, base + t, v),
    }
}

/// A message of doubles: tags 1..=n are its fields, higher tags unknown ones.
fn doubles(buf: &mut Vec<u8>, tag: u32, fields: &[(u32, f64)]) {
    let mut inner = Vec::new();
    for &(t, v) in fields {
        double(&mut inner, t, v);
    }
    delimited(buf, tag, &inner);
}

fn encode_box(fields: &[BoxField]) -> Vec<u8> {
    let mut buf = Vec::new();
    for f in fields {
        match f {
            BoxField::Center(v) => doubles(&mut buf, 1, v),
            BoxField::Size(v) => doubles(&mut buf, 2, v),
            BoxField::Yaw(v) => double(&mut buf, 3, *v),
            BoxField::Label(s) => delimited(&mut buf, 4, s.as_bytes()),
            BoxField::Score(v) => double(&mut buf, 5, *v),
            BoxField::Velocity(v) => doubles(&mut buf, 6, v),
            BoxField::ImageBox(v) => doubles(&mut buf, 7, v),
            BoxField::Attribute(k, v, unknowns) => {
                let mut entry = Vec::new();
                if let Some(k) = k {
                    delimited(&mut entry, 1, k.as_bytes());
                }
                if let Some(v) = v {
                    delimited(&mut entry, 2, v.as_bytes());
                }
                for u in unknowns {
                    unknown(&mut entry, 3, u);
                }
                delimited(&mut buf, 8, &entry);
            }
            BoxField::Unknown(u) => unknown(&mut buf, 9, u),
        }
    }
    buf
}

fn encode(fields: &[Field]) -> Vec<u8> {
    let mut buf = Vec::new();
    for f in fields {
        match f {
            Field::Stamp(v) => {
                encode_key(1, WireType::Varint, &mut buf);
                encode_varint(*v, &mut buf);
            }
            Field::FrameId(s) => delimited(&mut buf, 2, s.as_bytes()),
            Field::Detection(d) => delimited(&mut buf, 3, &encode_box(d)),
            Field::Unknown(u) => unknown(&mut buf, 4, u),
        }
    }
    buf
}

fn value() -> impl Strategy<Value = f64> {
    prop_oneof![
        Just(0.0),
        Just(-0.0),
        Just(f64::NAN),
        Just(f64::INFINITY),
        Just(2e7),
        -50.0..50.0,
        0.1..10.0,
        any::<f64>(),
    ]
}

fn unknown_field() -> impl Strategy<Value = Unknown> {
    prop_oneof![
        (0..5u32, any::<u64>()).prop_map(|(t, v)| Unknown::Varint(t, v)),
        (0..5u32, any::<u64>()).prop_map(|(t, v)| Unknown::Fixed64(t, v)),
        (0..5u32, any::<u32>()).prop_map(|(t, v)| Unknown::Fixed32(t, v)),
        (0..5u32, proptest::collection::vec(any::<u8>(), 0..6))
            .prop_map(|(t, v)| Unknown::Bytes(t, v)),
    ]
}

/// Fields of a sub-message of `n` doubles, with unknown tags after them.
fn partial(n: u32) -> impl Strategy<Value = Vec<(u32, f64)>> {
    proptest::collection::vec((1..n + 3, value()), 0..6)
}

fn text() -> impl Strategy<Value = String> {
    prop_oneof![
        Just(String::new()),
        Just("car".to_string()),
        Just("sim_truth_id".to_string()),
        "[a-c]{1,2}",
        "\\PC{0,12}",
    ]
}

fn box_field() -> impl Strategy<Value = BoxField> {
    let entry = (
        proptest::option::of(text()),
        proptest::option::of(text()),
        proptest::collection::vec(unknown_field(), 0..2),
    );
    prop_oneof![
        3 => partial(3).prop_map(BoxField::Center),
        3 => partial(3).prop_map(BoxField::Size),
        1 => value().prop_map(BoxField::Yaw),
        2 => text().prop_map(BoxField::Label),
        1 => value().prop_map(BoxField::Score),
        1 => partial(3).prop_map(BoxField::Velocity),
        1 => partial(4).prop_map(BoxField::ImageBox),
        2 => entry.prop_map(|(k, v, u)| BoxField::Attribute(k, v, u)),
        1 => unknown_field().prop_map(BoxField::Unknown),
    ]
}

fn field() -> impl Strategy<Value = Field> {
    prop_oneof![
        1 => any::<u64>().prop_map(Field::Stamp),
        1 => text().prop_map(Field::FrameId),
        6 => proptest::collection::vec(box_field(), 0..12).prop_map(Field::Detection),
        1 => unknown_field().prop_map(Field::Unknown),
    ]
}

/// A whole valid box, as prost encodes a `Detection3D` (most boxes of a real log).
fn prost_box() -> impl Strategy<Value = Detection3D> {
    let xyz = || (value(), value(), value());
    let attrs = proptest::collection::btree_map(text(), text(), 0..3);
    let image = proptest::option::of((value(), value(), value(), value()));
    let velocity = proptest::option::of(xyz());
    let geometry = (xyz(), (0.5..5.0, 0.5..5.0, 0.5..5.0), value());
    ((geometry, text(), value()), velocity, image, attrs).prop_map(
        |(((c, s, yaw), label, score), velocity, image, attributes)| Detection3D {
            center: Some(v3([c.0, c.1, c.2])),
            size: Some(Size3 {
                length: s.0,
                width: s.1,
                height: s.2,
            }),
            yaw,
            label,
            score,
            velocity: velocity.map(|v| v3([v.0, v.1, v.2])),
            image_box: image.map(|i| ImageBox {
                x1: i.0,
                y1: i.1,
                x2: i.2,
                y2: i.3,
            }),
            attributes,
        },
    )
}

/// Messages of either kind: field by field, or a prost `Detections3D` with unknown fields.
fn message() -> impl Strategy<Value = Vec<u8>> {
    let by_field = proptest::collection::vec(field(), 0..8).prop_map(|f| encode(&f));
    let whole = (
        proptest::option::of(any::<u64>()),
        text(),
        proptest::collection::vec(prost_box(), 0..6),
        proptest::collection::vec(field(), 0..3),
    )
        .prop_map(|(stamp, frame_id, detections, extra)| {
            let msg = Detections3D {
                stamp,
                frame_id,
                detections,
            };
            let mut bytes = msg.encode_to_vec();
            bytes.extend(encode(&extra));
            bytes
        });
    prop_oneof![by_field, whole]
}

/// Results compared by their debug text (NaN equals NaN, -0.0 differs from 0.0).
fn text_of<T: std::fmt::Debug, E: std::fmt::Debug>(r: &Result<T, E>) -> String {
    format!("{r:?}")
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    /// A run of well-formed messages read by one reader (each frame given back before the
    /// next message, as `track` does) gives prost's frames, on the fast path every time.
    #[test]
    fn reads_what_prost_reads(msgs in proptest::collection::vec(message(), 1..5)) {
        let mut reader = FrameReader::default();
        for (i, bytes) in msgs.iter().enumerate() {
            let want = PROBMOT.decode_frame(bytes, i as u64);
            prop_assert!(want.is_ok(), "generated messages are valid: {want:?}");
            let got = reader.read_probmot(bytes, i as u64);
            prop_assert!(got.is_ok(), "the fast path reads every valid message");
            prop_assert_eq!(text_of(&got), text_of(&want));
            reader.recycle(got.unwrap());
        }
    }

    /// Damaged messages (truncated, a byte changed, bytes inserted) and random bytes: no
    /// panic, and whatever the fast path accepts prost accepts the same way.
    #[test]
    fn damaged_bytes_give_prost_result(
        bytes in message(),
        cut in any::<prop::sample::Index>(),
        at in any::<prop::sample::Index>(),
        junk in proptest::collection::vec(any::<u8>(), 0..4),
        how in 0..4u8,
    ) {
        let mut bytes = bytes;
        match how {
            0 => bytes.truncate(cut.index(bytes.len() + 1)),
            1 if !bytes.is_empty() => {
                let i = at.index(bytes.len());
                bytes[i] ^= junk.first().copied().unwrap_or(0x80) | 1;
            }
            2 => {
                let i = at.index(bytes.len() + 1);
                bytes.splice(i..i, junk);
            }
            _ => bytes = junk,
        }
        let want = PROBMOT.decode_frame(&bytes, 3);
        let mut reader = FrameReader::default();
        if let Ok(got) = reader.read_probmot(&bytes, 3) {
            prop_assert_eq!(text_of(&Ok::<_, ()>(got)), text_of(&want.as_ref().map_err(|_| ())));
        }
        prop_assert_eq!(text_of(&reader.read(&PROBMOT, &bytes, 3)), text_of(&want));
    }
}

fn car(x: f64) -> Detection3D {
    Detection3D {
        attributes: [("sim_truth_id".to_string(), format!("{x}"))].into(),
        ..test_box("car", x)
    }
}

/// Every truncation of a message that prost refuses is refused by the fast path too, and
/// the reader gives prost's error.
#[test]
fn truncated_messages_are_errors() {
    let msg = Detections3D {
        stamp: Some(9),
        frame_id: "map".into(),
        detections: vec![car(1.0), car(2.0)],
    };
    let bytes = msg.encode_to_vec();
    let mut reader = FrameReader::default();
    let mut refused = 0;
    for n in 0..bytes.len() {
        let want = PROBMOT.decode_frame(&bytes[..n], 0);
        if want.is_err() {
            refused += 1;
            assert!(reader.read_probmot(&bytes[..n], 0).is_err(), "cut at {n}");
        }
        let got = reader.read(&PROBMOT, &bytes[..n], 0);
        assert_eq!(text_of(&got), text_of(&want), "cut at {n}");
    }
    assert!(refused > bytes.len() / 2, "most cuts fall inside a field");
}

/// A label that is not UTF-8 and a group field are left to prost: the box with the bad
/// label is rejected as before, and the group is skipped as prost skips it.
#[test]
fn declined_messages_are_read_as_before() {
    let msg = Detections3D {
        stamp: None,
        frame_id: "map".into(),
        detections: vec![
            car(1.0),
            Detection3D {
                label: "XXXX".into(),
                ..car(2.0)
            },
        ],
    };
    let mut bad = msg.encode_to_vec();
    let at = bad.windows(4).position(|w| w == b"XXXX").unwrap();
    bad[at..at + 4].copy_from_slice(&[0xff, 0xfe, b'c', 0x80]);
    let mut grouped = msg.encode_to_vec();
    grouped.extend([0x2b, 0x08, 0x01, 0x2c]); // group 5 { varint 1 = 1 }
    let mut reader = FrameReader::default();
    for bytes in [&bad, &grouped] {
        assert!(reader.read_probmot(bytes, 4).is_err());
        let got = reader.read(&PROBMOT, bytes, 4).unwrap();
        assert_eq!(got, PROBMOT.decode_frame(bytes, 4).unwrap());
    }
    let got = reader.read(&PROBMOT, &bad, 4).unwrap();
    assert_eq!(got.boxes.len(), 1);
    assert_eq!(
        got.rejected[0].reason,
        super::super::detection_frame::SkipReason::LabelNotUtf8
    );
}

/// A map entry whose key comes twice, the first not UTF-8: prost refuses the message, and
/// so does the fast path (which checks only the strings it keeps otherwise).
#[test]
fn replaced_attribute_strings_are_checked() {
    for tag in [1u32, 2] {
        let mut entry = Vec::new();
        delimited(&mut entry, tag, &[0xff, b'a']);
        delimited(&mut entry, tag, b"ok");
        let mut det = encode_box(&[BoxField::Label("car".into())]);
        delimited(&mut det, 8, &entry);
        let mut bytes = Vec::new();
        delimited(&mut bytes, 3, &det);
        assert!(PROBMOT.decode_frame(&bytes, 0).is_err());
        assert!(FrameReader::default().read_probmot(&bytes, 0).is_err());
    }
}

/// Varints at prost's limits: ten bytes with the last 1 is `u64::MAX`-sized, with the last
/// 2 (beyond 64 bits) or eleven bytes it is refused; a key beyond 32 bits is refused.
#[test]
fn varints_end_where_prost_ends_them() {
    let stamp = |tail: &[u8]| {
        let mut b = vec![0x08];
        b.extend(std::iter::repeat_n(0xff, 9));
        b.extend_from_slice(tail);
        b
    };
    let key_too_wide = vec![0x80, 0x80, 0x80, 0x80, 0x10, 0x00];
    let cases = [
        (stamp(&[0x01]), true),
        (stamp(&[0x02]), false),
        (stamp(&[0x81, 0x00]), false),
        (key_too_wide, false),
    ];
    for (bytes, ok) in cases {
        let want = PROBMOT.decode_frame(&bytes, 0);
        assert_eq!(want.is_ok(), ok, "{bytes:?}");
        let got = FrameReader::default().read_probmot(&bytes, 0);
        assert_eq!(
            text_of(&got),
            text_of(&want.map_err(|_| Declined)),
            "{bytes:?}"
        );
    }
}

/// A recycled box keeps its strings: a box with the same attribute key and a label that fits
/// is read into them without a new allocation.
#[test]
fn recycled_boxes_reuse_their_strings() {
    let msg = |x| Detections3D {
        stamp: Some(1),
        frame_id: "map".into(),
        detections: vec![car(x)],
    };
    let mut reader = FrameReader::default();
    let first = reader.read(&PROBMOT, &msg(1.0).encode_to_vec(), 0).unwrap();
    let label_at = first.boxes[0].label.as_ptr();
    let value_at = first.boxes[0].attributes["sim_truth_id"].as_ptr();
    reader.recycle(first);
    let second = reader.read(&PROBMOT, &msg(7.0).encode_to_vec(), 0).unwrap();
    assert_eq!(second.boxes[0].attributes["sim_truth_id"], "7");
    assert_eq!(second.boxes[0].label.as_ptr(), label_at);
    assert_eq!(
        second.boxes[0].attributes["sim_truth_id"].as_ptr(),
        value_at
    );
}

/// Frames of other inputs (here ROS 2 vision_msgs, decoded by the prost-free CDR path) are not
/// kept as spares until a probmot message is read, which would take them; then they are.
#[test]
fn frames_are_kept_only_for_the_reader_s_own_path() {
    let mut reader = FrameReader::default();
    let frame = |n: usize| DetectionFrame {
        boxes: vec![DetectionBox::default(); n],
        ..Default::default()
    };
    reader.recycle(frame(50));
    assert_eq!(
        (reader.spare_boxes.len(), reader.spare_frames.len()),
        (0, 0)
    );
    let bytes = Detections3D {
        detections: vec![car(1.0)],
        ..Default::default()
    }
    .encode_to_vec();
    let source = DetectionSource::Probmot(Encoding::Protobuf);
    let read = reader.read(&source, &bytes, 1).unwrap();
    reader.recycle(read);
    reader.recycle(frame(50));
    assert_eq!(reader.spare_frames.len(), 2);
    assert!(reader.spare_boxes.len() >= 50);
}
