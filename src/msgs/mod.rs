//! probmot's message schemas (`schemas/probmot/*.proto`): the generated Rust types, the
//! serialized `FileDescriptorSet` for MCAP schema records, and decoding from protobuf or JSON.

#[allow(missing_docs, clippy::all)]
mod generated {
    include!(concat!(env!("OUT_DIR"), "/probmot.rs"));
}

pub use generated::*;

pub mod autoware;
pub mod autoware_object;
pub mod autoware_tracks;
pub mod cdr_cursor;
pub mod cdr_writer;
pub mod colors;
pub mod detection_frame;
pub mod detection_reader;
pub mod detection_source;
pub mod eval_events;
pub mod foxglove_scene;
pub mod lenient_label;
pub mod proto_writer;
pub mod ros2_common;
pub mod ros2_schema;
pub mod ros2_tf;
pub mod ros2_tracks;
pub mod ros2_vision;
pub mod scene_update;
pub mod track_encode;
pub mod utf8_repair;

/// Serialized `google.protobuf.FileDescriptorSet` holding every probmot schema file, as stored in
/// the data of each MCAP schema record (schema encoding `protobuf`).
pub const DESCRIPTOR_SET: &[u8] =
    include_bytes!(concat!(env!("OUT_DIR"), "/probmot_descriptor.bin"));

/// Schema name of a detections channel.
pub const DETECTIONS_SCHEMA: &str = "probmot.Detections3D";
/// Schema name of a tracks (or ground truth) channel.
pub const TRACKS_SCHEMA: &str = "probmot.Tracks3D";

/// Schema name of an ego pose channel (`/ego_pose`, JSON messages `{stamp, translation,
/// rotation}` in the global frame), as `probmot import nuscenes` writes it.
pub const EGO_POSE_SCHEMA: &str = "probmot.EgoPose";

/// A [`Size3`] from `[l, w, h]` (the order of [`crate::tracker::Box3::size`]).
pub fn size3(s: [f64; 3]) -> Size3 {
    Size3 {
        length: s[0],
        width: s[1],
        height: s[2],
    }
}

/// How a message is encoded, from the MCAP channel's `message_encoding`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Encoding {
    /// Protobuf binary.
    Protobuf,
    /// JSON (serde field names = proto field names).
    Json,
}

impl Encoding {
    /// The encoding of a channel, if it is one probmot reads.
    pub fn from_message_encoding(s: &str) -> Option<Encoding> {
        match s {
            "protobuf" => Some(Encoding::Protobuf),
            "json" => Some(Encoding::Json),
            _ => None,
        }
    }
}

/// A message that could not be decoded.
#[derive(Debug, thiserror::Error)]
pub enum DecodeError {
    /// Bad protobuf bytes.
    #[error("protobuf: {0}")]
    Protobuf(#[from] prost::DecodeError),
    /// Bad JSON.
    #[error("json: {0}")]
    Json(#[from] serde_json::Error),
    /// Bad CDR (ROS 2) bytes.
    #[error("cdr: {0}")]
    Cdr(#[from] cdr::Error),
    /// Bad CDR bytes, found by the bounds-checked reader ([`cdr_cursor::CdrCursor`]).
    #[error("cdr: {0}")]
    CdrChecked(#[from] cdr_cursor::CdrError),
    /// Well-formed bytes whose content cannot be used (e.g. a timestamp out of range).
    #[error("{0}")]
    Content(String),
}

/// Decodes a message of either encoding.
pub fn decode<M>(bytes: &[u8], encoding: Encoding) -> Result<M, DecodeError>
where
    M: prost::Message + Default + serde::de::DeserializeOwned,
{
    Ok(match encoding {
        Encoding::Protobuf => M::decode(bytes)?,
        Encoding::Json => serde_json::from_slice(bytes)?,
    })
}

/// What the first pass of `track` needs from a detections message: its stamp and the number of
/// boxes, decoded without building the boxes (they are skipped, not allocated).
#[derive(Clone, PartialEq, prost::Message, serde::Deserialize)]
#[serde(from = "EnvelopeJson")]
pub struct DetectionsEnvelope {
    /// `Detections3D.stamp`.
    #[prost(uint64, optional, tag = "1")]
    pub stamp: Option<u64>,
    /// One (empty) entry per box.
    #[prost(message, repeated, tag = "3")]
    pub detections: Vec<Skipped>,
}

/// The JSON form of [`DetectionsEnvelope`]: every field of `Detections3D`, in its order, with
/// `frame_id` skipped. The order matters because serde also reads a struct from a JSON array of
/// its fields by position (`[stamp, frame_id, detections]`), and every message that decodes as
/// `Detections3D` must decode as the envelope too, with the same stamp and count (found by the
/// `decode_json` fuzz target).
#[derive(Default, serde::Deserialize)]
#[serde(default)]
struct EnvelopeJson {
    stamp: Option<u64>,
    #[allow(dead_code)]
    frame_id: serde::de::IgnoredAny,
    detections: Vec<Skipped>,
}

impl From<EnvelopeJson> for DetectionsEnvelope {
    fn from(j: EnvelopeJson) -> Self {
        DetectionsEnvelope {
            stamp: j.stamp,
            detections: j.detections,
        }
    }
}

/// A message whose content is skipped (zero-sized: a `Vec` of these never allocates).
#[derive(Clone, Copy, PartialEq, prost::Message)]
pub struct Skipped {}

impl<'de> serde::Deserialize<'de> for Skipped {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        serde::de::IgnoredAny::deserialize(d)?;
        Ok(Skipped {})
    }
}

/// Encodes a message to protobuf bytes into `buf` (cleared first).
pub fn encode_into<M: prost::Message>(msg: &M, buf: &mut Vec<u8>) {
    buf.clear();
    msg.encode(buf).expect("Vec grows as needed");
}

/// Bits of the mantissa kept in the values probmot writes where more digits cost
/// bytes and carry nothing: what only a drawing has (quaternions, arrow lengths, colours) and the
/// filter variances. 12 bits are 1/4096 relative (three to four significant
/// digits): a heading off by at most 0.02°, an arrow of 10 m off by at most 2.5 mm, far below a
/// pixel of any view; a variance's own uncertainty is far larger. The low bytes of such a
/// `double` are zeros, which zstd codes in almost nothing (see docs/scaling.md, issue #39).
pub const SHORT_BITS: u32 = 12;

/// `x` with its mantissa rounded to [`SHORT_BITS`] bits (to nearest, ties away from zero),
/// kept as an `f64`. Zeros, infinities and NaN stay as they are, and so does a finite value
/// whose rounding would overflow.
pub fn short_precision(x: f64) -> f64 {
    const DROP: u32 = 52 - SHORT_BITS;
    if !x.is_finite() {
        return x;
    }
    // Adding half of the dropped part to the bit pattern rounds the magnitude (the sign bit is
    // not touched); a carry out of the mantissa moves the exponent up, as it should.
    let bits = (x.to_bits() + (1 << (DROP - 1))) & !((1u64 << DROP) - 1);
    let r = f64::from_bits(bits);
    if r.is_finite() {
        r
    } else {
        x
    }
}

/// Builds a [`Vector3`].
pub fn v3(v: [f64; 3]) -> Vector3 {
    Vector3 {
        x: v[0],
        y: v[1],
        z: v[2],
    }
}

/// A 4 x 2 x 1.5 m box at (`x`, 0, 0) with score 0.9: the detection the unit tests of the
/// readers and of the tracking session are made of.
#[cfg(test)]
pub(crate) fn test_box(label: &str, x: f64) -> Detection3D {
    Detection3D {
        center: Some(v3([x, 0.0, 0.0])),
        size: Some(Size3 {
            length: 4.0,
            width: 2.0,
            height: 1.5,
        }),
        label: label.into(),
        score: 0.9,
        ..Default::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use prost::Message;

    #[test]
    fn short_precision_keeps_twelve_bits() {
        assert_eq!(short_precision(0.5), 0.5);
        assert_eq!(short_precision(-3.0), -3.0);
        assert_eq!(short_precision(0.0), 0.0);
        // 1 + 2^-12 is exact at 12 bits; 1 + 2^-13 is a tie, rounded away from zero; below
        // that it rounds down.
        assert_eq!(short_precision(1.0 + 2f64.powi(-12)), 1.0 + 2f64.powi(-12));
        assert_eq!(short_precision(1.0 + 2f64.powi(-13)), 1.0 + 2f64.powi(-12));
        assert_eq!(short_precision(1.0 + 2f64.powi(-14)), 1.0);
        assert_eq!(
            short_precision(-(1.0 + 2f64.powi(-13))),
            -(1.0 + 2f64.powi(-12))
        );
        // A carry out of the mantissa: just below 2 rounds to 2.
        assert_eq!(short_precision(2.0 - 2f64.powi(-20)), 2.0);
        for x in [0.1, -std::f64::consts::FRAC_1_SQRT_2, 1234.5678, 3.0e-9] {
            let r = short_precision(x);
            assert!(((r - x) / x).abs() <= 2f64.powi(-13), "{x} -> {r}");
            assert_eq!(r.to_bits() & ((1 << 40) - 1), 0, "{x} -> {r}");
        }
        for x in [f64::MAX, f64::INFINITY, f64::NEG_INFINITY] {
            assert_eq!(short_precision(x), x);
        }
        assert!(short_precision(f64::NAN).is_nan());
    }

    #[test]
    fn descriptor_set_names_our_messages() {
        let fds = prost_types::FileDescriptorSet::decode(DESCRIPTOR_SET).unwrap();
        let names: Vec<String> = fds
            .file
            .iter()
            .flat_map(|f| {
                let pkg = f.package().to_string();
                f.message_type
                    .iter()
                    .map(move |m| format!("{pkg}.{}", m.name()))
            })
            .collect();
        assert!(names.contains(&DETECTIONS_SCHEMA.to_string()));
        assert!(names.contains(&TRACKS_SCHEMA.to_string()));
    }

    #[test]
    fn envelope_reads_stamp_and_count_only() {
        let msg = Detections3D {
            stamp: Some(7),
            frame_id: "f".into(),
            detections: vec![Detection3D::default(); 3],
        };
        let e: DetectionsEnvelope = decode(&msg.encode_to_vec(), Encoding::Protobuf).unwrap();
        assert_eq!((e.stamp, e.detections.len()), (Some(7), 3));
        let j: DetectionsEnvelope =
            decode(&serde_json::to_vec(&msg).unwrap(), Encoding::Json).unwrap();
        assert_eq!((j.stamp, j.detections.len()), (Some(7), 3));
    }

    #[test]
    fn json_and_protobuf_decode_the_same_message() {
        let msg = Detections3D {
            stamp: Some(42),
            frame_id: "map".into(),
            detections: vec![Detection3D {
                center: Some(v3([1.0, 2.0, 3.0])),
                size: Some(Size3 {
                    length: 4.0,
                    width: 2.0,
                    height: 1.5,
                }),
                yaw: 0.5,
                label: "car".into(),
                score: 0.9,
                attributes: [("k".to_string(), "v".to_string())].into(),
                ..Default::default()
            }],
        };
        let pb = msg.encode_to_vec();
        let js = serde_json::to_vec(&msg).unwrap();
        let a: Detections3D = decode(&pb, Encoding::Protobuf).unwrap();
        let b: Detections3D = decode(&js, Encoding::Json).unwrap();
        assert_eq!(a, msg);
        assert_eq!(b, msg);
        // Missing fields default, as in protobuf.
        let c: Detections3D =
            decode(br#"{"detections":[{"label":"car"}]}"#, Encoding::Json).unwrap();
        assert_eq!(c.stamp, None);
        assert_eq!(c.detections[0].label, "car");
    }
}
