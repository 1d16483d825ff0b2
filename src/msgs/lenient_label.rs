//! A `probmot.Detections3D` protobuf message in which some box's label is not UTF-8: prost
//! refuses the whole message, so it is read again field by field, each such box without its
//! label; the caller skips those boxes (counted like any other bad box) and tracks the rest.

use prost::encoding::{decode_key, decode_varint, skip_field, DecodeContext, WireType};
use prost::Message;

use super::{Detection3D, Detections3D};

/// Tag of `Detections3D.detections` and of `Detection3D.label`.
const DETECTIONS_TAG: u32 = 3;
const LABEL_TAG: u32 = 4;

/// One field of a protobuf message: its tag, its bytes (key included) and, when
/// length-delimited, its payload.
struct Field<'a> {
    tag: u32,
    whole: &'a [u8],
    payload: Option<&'a [u8]>,
}

/// The top-level fields of `buf`, in order; `None` when it is not well-formed protobuf.
fn fields(buf: &[u8]) -> Option<Vec<Field<'_>>> {
    let mut rest = buf;
    let mut out = Vec::new();
    while !rest.is_empty() {
        let start = buf.len() - rest.len();
        let (tag, wire) = decode_key(&mut rest).ok()?;
        let payload = if wire == WireType::LengthDelimited {
            let len = usize::try_from(decode_varint(&mut rest).ok()?).ok()?;
            let p = rest.get(..len)?;
            rest = &rest[len..];
            Some(p)
        } else {
            skip_field(wire, tag, &mut rest, DecodeContext::default()).ok()?;
            None
        };
        let end = buf.len() - rest.len();
        out.push(Field {
            tag,
            whole: &buf[start..end],
            payload,
        });
    }
    Some(out)
}

/// Decodes one box whose label is not UTF-8: the box without its label, and the label read
/// lossily (for the warning). `None` when the box fails for another reason too.
fn without_label(bytes: &[u8]) -> Option<Detection3D> {
    let fields = fields(bytes)?;
    let mut label = None;
    let mut kept = Vec::with_capacity(bytes.len());
    for f in &fields {
        match (f.tag, f.payload) {
            (LABEL_TAG, Some(p)) => label = Some(p),
            _ => kept.extend_from_slice(f.whole),
        }
    }
    let label = label.filter(|l| std::str::from_utf8(l).is_err())?;
    let mut d = Detection3D::decode(kept.as_slice()).ok()?;
    d.label = String::from_utf8_lossy(label).into_owned();
    Some(d)
}

/// Reads a message prost refused: `Some((message, indices))` with the positions of the boxes
/// whose label is not UTF-8 (their labels read lossily), when those labels were the only fault.
pub fn decode_with_bad_labels(bytes: &[u8]) -> Option<(Detections3D, Vec<u32>)> {
    let fields = fields(bytes)?;
    let mut rest = Vec::new();
    let mut detections = Vec::new();
    let mut bad = Vec::new();
    for f in &fields {
        let Some(p) = f.payload.filter(|_| f.tag == DETECTIONS_TAG) else {
            rest.extend_from_slice(f.whole);
            continue;
        };
        match Detection3D::decode(p) {
            Ok(d) => detections.push(d),
            Err(_) => {
                bad.push(detections.len() as u32);
                detections.push(without_label(p)?);
            }
        }
    }
    let mut msg = Detections3D::decode(rest.as_slice()).ok()?;
    msg.detections = detections;
    (!bad.is_empty()).then_some((msg, bad))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msgs::test_box;

    /// The label bytes of the middle box are overwritten with invalid UTF-8: prost refuses the
    /// message, the lenient read keeps the other boxes exactly and names the bad one.
    #[test]
    fn only_the_box_with_the_bad_label_is_lost() {
        let msg = Detections3D {
            stamp: Some(5),
            frame_id: "map".into(),
            detections: vec![
                test_box("car", 1.0),
                test_box("XXXX", 2.0),
                test_box("bus", 3.0),
            ],
        };
        let mut bytes = msg.encode_to_vec();
        let at = bytes.windows(4).position(|w| w == b"XXXX").unwrap();
        bytes[at..at + 4].copy_from_slice(&[0xff, 0xfe, b'c', 0x80]);
        assert!(Detections3D::decode(bytes.as_slice()).is_err());
        let (got, bad) = decode_with_bad_labels(&bytes).unwrap();
        assert_eq!(bad, [1]);
        assert_eq!((got.stamp, got.frame_id.as_str()), (Some(5), "map"));
        assert_eq!(got.detections[0], msg.detections[0]);
        assert_eq!(got.detections[2], msg.detections[2]);
        assert_eq!(got.detections[1].center, msg.detections[1].center);
        assert!(got.detections[1].label.contains('\u{fffd}'));
        // A message that is broken elsewhere stays refused.
        assert!(decode_with_bad_labels(&bytes[..bytes.len() - 3]).is_none());
        assert!(decode_with_bad_labels(&msg.encode_to_vec()).is_none());
    }
}
