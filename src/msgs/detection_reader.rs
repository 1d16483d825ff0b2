//! Reads probmot's own `probmot.Detections3D` protobuf messages straight into checked
//! [`DetectionFrame`]s, reusing the frames and boxes of earlier messages (their label, frame id
//! and attribute strings are overwritten in place): no heap allocation per detection in steady
//! state, where decoding with prost allocates a label, a map and its strings for every box.
//!
//! The reader is as strict as prost or stricter: any message it does not take (malformed bytes,
//! a string that is not UTF-8, a group field) is handed to the prost path
//! ([`DetectionSource::decode_frame`]), which gives the error, or the lenient reading of a label
//! that is not UTF-8, exactly as before. Fields are read as prost reads them: unknown fields
//! skipped, the last of a repeated scalar or string kept, a repeated sub-message merged into the
//! one before it, the last of a repeated map key kept.

use std::collections::BTreeMap;
use std::ops::Range;

use prost::encoding::WireType;

use super::detection_frame::Rejected;
use super::detection_frame::{check_parts, stamp_or_log_time, DetectionBox, DetectionFrame};
use super::detection_source::DetectionSource;
use super::{DecodeError, Encoding, ImageBox};

/// Spare boxes and frames kept at most (a burst of large messages is not held forever).
const MAX_SPARE_BOXES: usize = 1 << 14;
const MAX_SPARE_FRAMES: usize = 64;

/// Attribute maps of up to this many entries are updated in place when the keys are the same.
const MAX_IN_PLACE_ENTRIES: usize = 8;

/// The message is left to prost (malformed, or a form this reader does not take).
#[derive(Debug)]
pub(crate) struct Declined;

type Step<T> = Result<T, Declined>;

/// Decodes detection messages into frames, with the spare frames and boxes of the frames given
/// back by [`FrameReader::recycle`].
#[derive(Default)]
pub struct FrameReader {
    spare_frames: Vec<DetectionFrame>,
    spare_boxes: Vec<DetectionBox>,
    /// Attribute entries of the box being read: byte ranges of key and value in the message.
    entries: Vec<(Range<usize>, Range<usize>)>,
}

impl FrameReader {
    /// Decodes one message of `source` (logged at `log_time`): the same frame, or the same
    /// error, as [`DetectionSource::decode_frame`].
    pub fn read(
        &mut self,
        source: &DetectionSource,
        bytes: &[u8],
        log_time: u64,
    ) -> Result<DetectionFrame, DecodeError> {
        if *source != DetectionSource::Probmot(Encoding::Protobuf) {
            return source.decode_frame(bytes, log_time);
        }
        match self.read_probmot(bytes, log_time) {
            Ok(frame) => Ok(frame),
            Err(Declined) => source.decode_frame(bytes, log_time),
        }
    }

    /// Gives a frame back once its boxes are used: its strings and maps serve later messages.
    pub fn recycle(&mut self, mut frame: DetectionFrame) {
        let room = MAX_SPARE_BOXES.saturating_sub(self.spare_boxes.len());
        self.spare_boxes.extend(frame.boxes.drain(..).take(room));
        frame.rejected.clear();
        if self.spare_frames.len() < MAX_SPARE_FRAMES {
            self.spare_frames.push(frame);
        }
    }

    /// The fast path alone: a `probmot.Detections3D` protobuf message, or [`Declined`].
    pub(crate) fn read_probmot(&mut self, bytes: &[u8], log_time: u64) -> Step<DetectionFrame> {
        let mut frame = self.spare_frames.pop().unwrap_or_default();
        frame.clear();
        frame.frame_id.clear();
        let mut c = Cursor::new(bytes);
        let mut stamp = None;
        let mut index = 0u32;
        let result = (|| {
            while c.more() {
                let (tag, wire) = c.key()?;
                match tag {
                    1 => stamp = Some(c.varint_field(wire)?),
                    2 => {
                        let s = c.string(wire)?;
                        frame.frame_id.clear();
                        frame.frame_id.push_str(s);
                    }
                    3 => {
                        let r = c.delimited(wire)?;
                        self.read_box(c.sub(r), index, &mut frame)?;
                        index = index.wrapping_add(1);
                    }
                    _ => c.skip(wire)?,
                }
            }
            Ok(())
        })();
        if let Err(e) = result {
            self.recycle(frame);
            return Err(e);
        }
        frame.stamp = stamp_or_log_time(stamp, log_time);
        Ok(frame)
    }

    /// Reads one `Detection3D` into a spare box, checks it and adds it to `frame`.
    fn read_box(&mut self, mut c: Cursor<'_>, index: u32, frame: &mut DetectionFrame) -> Step<()> {
        let mut b = self.spare_boxes.pop().unwrap_or_default();
        let mut p = Parts::default();
        b.label.clear();
        self.entries.clear();
        while c.more() {
            let (tag, wire) = c.key()?;
            match tag {
                1 => c.doubles(wire, p.center.get_or_insert([0.0; 3]))?,
                2 => c.doubles(wire, p.size.get_or_insert([0.0; 3]))?,
                3 => p.yaw = c.double(wire)?,
                4 => {
                    let s = c.string(wire)?;
                    b.label.clear();
                    b.label.push_str(s);
                }
                5 => p.score = c.double(wire)?,
                6 => c.doubles(wire, p.velocity.get_or_insert([0.0; 3]))?,
                7 => {
                    let ib = p.image_box.get_or_insert_with(ImageBox::default);
                    let mut v = [ib.x1, ib.y1, ib.x2, ib.y2];
                    c.doubles(wire, &mut v)?;
                    [ib.x1, ib.y1, ib.x2, ib.y2] = v;
                }
                8 => {
                    let r = c.delimited(wire)?;
                    self.entries.push(c.sub(r).map_entry()?);
                }
                _ => c.skip(wire)?,
            }
        }
        set_attributes(&mut b.attributes, c.buf, &self.entries)?;
        match check_parts(p.center, p.size, p.yaw, p.score, p.velocity) {
            Ok(bbox) => {
                b.index = index;
                b.bbox = bbox;
                b.score = p.score;
                b.velocity = p.velocity;
                b.image_box = p.image_box;
                b.needs_own_entry = false;
                frame.boxes.push(b);
            }
            Err(reason) => {
                let label = std::mem::take(&mut b.label);
                frame.rejected.push(Rejected {
                    index,
                    label,
                    reason,
                });
                self.spare_boxes.push(b);
            }
        }
        Ok(())
    }
}

/// The fields of a box that are checked before it is kept.
#[derive(Default)]
struct Parts {
    center: Option<[f64; 3]>,
    size: Option<[f64; 3]>,
    yaw: f64,
    score: f64,
    velocity: Option<[f64; 3]>,
    image_box: Option<ImageBox>,
}

/// Makes `map` hold the entries (key and value ranges of `buf`, the last of a repeated key
/// winning), as prost's map decoding would; [`Declined`] when a key or value is not UTF-8. A
/// map with the same keys is updated in place (its strings keep their memory).
fn set_attributes(
    map: &mut BTreeMap<String, String>,
    buf: &[u8],
    entries: &[(Range<usize>, Range<usize>)],
) -> Step<()> {
    let text = |r: &Range<usize>| std::str::from_utf8(&buf[r.clone()]).map_err(|_| Declined);
    // As many entries as keys, each key among them: the entries' keys are the map's, once each.
    if entries.len() == map.len() && entries.len() <= MAX_IN_PLACE_ENTRIES {
        let mut same_keys = true;
        for (key, slot) in map.iter_mut() {
            let Some((_, v)) = entries
                .iter()
                .find(|(k, _)| &buf[k.clone()] == key.as_bytes())
            else {
                same_keys = false;
                break;
            };
            slot.clear();
            slot.push_str(text(v)?);
        }
        if same_keys {
            return Ok(());
        }
    }
    map.clear();
    for (k, v) in entries {
        map.insert(text(k)?.to_owned(), text(v)?.to_owned());
    }
    Ok(())
}

/// A position in a message, read up to `end` (the end of the message or sub-message).
struct Cursor<'a> {
    buf: &'a [u8],
    pos: usize,
    end: usize,
}

impl<'a> Cursor<'a> {
    fn new(buf: &'a [u8]) -> Cursor<'a> {
        Cursor {
            buf,
            pos: 0,
            end: buf.len(),
        }
    }

    /// A cursor over the sub-message at `r`.
    fn sub(&self, r: Range<usize>) -> Cursor<'a> {
        Cursor {
            buf: self.buf,
            pos: r.start,
            end: r.end,
        }
    }

    #[inline(always)]
    fn more(&self) -> bool {
        self.pos < self.end
    }

    /// A varint, refused where prost refuses it: past the end, longer than ten bytes, or
    /// beyond 64 bits.
    #[inline(always)]
    fn varint(&mut self) -> Step<u64> {
        match self.buf[..self.end].get(self.pos) {
            Some(&b) if b < 0x80 => {
                self.pos += 1;
                Ok(u64::from(b))
            }
            _ => self.long_varint(),
        }
    }

    /// [`Cursor::varint`] of more than one byte.
    #[inline(never)]
    fn long_varint(&mut self) -> Step<u64> {
        let mut v = 0u64;
        for i in 0..10 {
            let b = *self.buf[..self.end].get(self.pos).ok_or(Declined)?;
            self.pos += 1;
            if i == 9 && b >= 0x02 {
                return Err(Declined);
            }
            v |= u64::from(b & 0x7f) << (7 * i);
            if b < 0x80 {
                return Ok(v);
            }
        }
        Err(Declined)
    }

    /// A field key: tag and wire type, refused as prost refuses it (a key beyond 32 bits, wire
    /// type 6 or 7, tag 0).
    #[inline(always)]
    fn key(&mut self) -> Step<(u32, WireType)> {
        let key = self.varint()?;
        let key = u32::try_from(key).map_err(|_| Declined)?;
        let wire = match key & 7 {
            0 => WireType::Varint,
            1 => WireType::SixtyFourBit,
            2 => WireType::LengthDelimited,
            3 => WireType::StartGroup,
            4 => WireType::EndGroup,
            5 => WireType::ThirtyTwoBit,
            _ => return Err(Declined),
        };
        match key >> 3 {
            0 => Err(Declined),
            tag => Ok((tag, wire)),
        }
    }

    fn varint_field(&mut self, wire: WireType) -> Step<u64> {
        expect(wire, WireType::Varint)?;
        self.varint()
    }

    /// `n` bytes, advanced past.
    #[inline(always)]
    fn take(&mut self, n: usize) -> Step<Range<usize>> {
        if n > self.end - self.pos {
            return Err(Declined);
        }
        self.pos += n;
        Ok(self.pos - n..self.pos)
    }

    #[inline(always)]
    fn double(&mut self, wire: WireType) -> Step<f64> {
        expect(wire, WireType::SixtyFourBit)?;
        let bytes = self.buf[self.pos..self.end].first_chunk::<8>();
        let v = f64::from_le_bytes(*bytes.ok_or(Declined)?);
        self.pos += 8;
        Ok(v)
    }

    /// The payload of a length-delimited field.
    fn delimited(&mut self, wire: WireType) -> Step<Range<usize>> {
        expect(wire, WireType::LengthDelimited)?;
        let len = self.varint()?;
        self.take(usize::try_from(len).map_err(|_| Declined)?)
    }

    fn string(&mut self, wire: WireType) -> Step<&'a str> {
        let r = self.delimited(wire)?;
        std::str::from_utf8(&self.buf[r]).map_err(|_| Declined)
    }

    /// Reads a message of doubles with tags `1..=N` into `v` (merged: fields absent stay).
    fn doubles<const N: usize>(&mut self, wire: WireType, v: &mut [f64; N]) -> Step<()> {
        let r = self.delimited(wire)?;
        let mut c = self.sub(r);
        while c.more() {
            let (tag, wire) = c.key()?;
            match v.get_mut(tag as usize - 1) {
                Some(slot) => *slot = c.double(wire)?,
                None => c.skip(wire)?,
            }
        }
        Ok(())
    }

    /// Reads a map entry: the ranges of its key and value (empty when absent; checked UTF-8 by
    /// [`set_attributes`]).
    fn map_entry(mut self) -> Step<(Range<usize>, Range<usize>)> {
        let (mut key, mut value) = (0..0, 0..0);
        while self.more() {
            let (tag, wire) = self.key()?;
            match tag {
                // prost checks every occurrence, also the ones a later one replaces.
                1 => key = self.replace_string(key, wire)?,
                2 => value = self.replace_string(value, wire)?,
                _ => self.skip(wire)?,
            }
        }
        Ok((key, value))
    }

    /// The range of the next string field, after checking the one it replaces (if any).
    fn replace_string(&mut self, old: Range<usize>, wire: WireType) -> Step<Range<usize>> {
        if !old.is_empty() {
            std::str::from_utf8(&self.buf[old]).map_err(|_| Declined)?;
        }
        self.delimited(wire)
    }

    /// Skips an unknown field; groups are left to prost (its recursion limit applies to them).
    fn skip(&mut self, wire: WireType) -> Step<()> {
        match wire {
            WireType::Varint => self.varint().map(drop),
            WireType::SixtyFourBit => self.take(8).map(drop),
            WireType::ThirtyTwoBit => self.take(4).map(drop),
            WireType::LengthDelimited => self.delimited(wire).map(drop),
            WireType::StartGroup | WireType::EndGroup => Err(Declined),
        }
    }
}

/// A known field must have its own wire type (prost refuses any other).
fn expect(wire: WireType, want: WireType) -> Step<()> {
    match wire == want {
        true => Ok(()),
        false => Err(Declined),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msgs::{v3, Detection3D, Detections3D, Size3};
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
            center: Some(v3([x, 0.0, 0.0])),
            size: Some(Size3 {
                length: 4.0,
                width: 2.0,
                height: 1.5,
            }),
            label: "car".into(),
            score: 0.9,
            attributes: [("sim_truth_id".to_string(), format!("{x}"))].into(),
            ..Default::default()
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
}
