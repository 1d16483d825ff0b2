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
    /// A message has been read by this reader's own path, which takes the spares.
    reads_probmot: bool,
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
    /// Until a message is read by this reader's own path (`probmot.Detections3D` protobuf), no
    /// message will take them, so the frame is dropped: the spares of a ROS 2, Foxglove or
    /// Autoware input would be megabytes held for nothing.
    pub fn recycle(&mut self, mut frame: DetectionFrame) {
        if !self.reads_probmot {
            return;
        }
        let room = MAX_SPARE_BOXES.saturating_sub(self.spare_boxes.len());
        self.spare_boxes.extend(frame.boxes.drain(..).take(room));
        frame.rejected.clear();
        if self.spare_frames.len() < MAX_SPARE_FRAMES {
            self.spare_frames.push(frame);
        }
    }

    /// The fast path alone: a `probmot.Detections3D` protobuf message, or [`Declined`].
    pub(crate) fn read_probmot(&mut self, bytes: &[u8], log_time: u64) -> Step<DetectionFrame> {
        self.reads_probmot = true;
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
mod tests;
