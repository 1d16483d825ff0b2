//! The zero-allocation reader of probmot's protobuf detections (`FrameReader`) against the
//! prost path it replaced in `track` (`DetectionSource::decode_frame`), over a run of messages
//! read by one reader that recycles every frame, as `track` does.

use probmot::msgs::detection_frame::{DetectionFrame, Rejected, SkipReason};
use probmot::msgs::detection_reader::FrameReader;
use probmot::msgs::detection_source::DetectionSource;
use probmot::msgs::{Encoding, ImageBox};

const PROBMOT: DetectionSource = DetectionSource::Probmot(Encoding::Protobuf);

/// Most messages read from one input.
const MAX_MESSAGES: usize = 8;

/// Splits `data` into messages, each a little-endian `u16` length and then that many bytes
/// (fewer at the end of the input), and reads them in turn with one `FrameReader` (log time:
/// the message's number). Invariant besides no panic: every message gives the same frame (by
/// its debug text, so that NaN equals NaN), or the same error, as `decode_frame` (the prost
/// path). Each frame is then changed as `track` may change it (moved into another frame, boxes
/// marked) and more (strings, attributes and rejected boxes added), and given back with
/// `recycle`, so that anything of an earlier frame leaking into a later one shows.
pub fn read_frames(data: &[u8]) {
    let mut reader = FrameReader::default();
    let mut rest = data;
    let mut n = 0u64;
    while rest.len() >= 2 && (n as usize) < MAX_MESSAGES {
        let len = (u16::from_le_bytes([rest[0], rest[1]]) as usize).min(rest.len() - 2);
        let bytes = &rest[2..2 + len];
        rest = &rest[2 + len..];
        let want = PROBMOT.decode_frame(bytes, n);
        let got = reader.read(&PROBMOT, bytes, n);
        assert_eq!(
            format!("{got:?}"),
            format!("{want:?}"),
            "FrameReader and prost differ on message {n} ({len} bytes)"
        );
        if let Ok(mut frame) = got {
            spoil(&mut frame);
            reader.recycle(frame);
        }
        n += 1;
    }
}

/// Changes every part of a frame that a later frame must not inherit.
fn spoil(frame: &mut DetectionFrame) {
    frame.stamp ^= 0x5a5a;
    frame.frame_id.push_str("/stale");
    for b in &mut frame.boxes {
        b.index = b.index.wrapping_add(1000);
        b.label.push_str("-stale");
        b.score = -7.0;
        b.velocity = Some([9.0; 3]);
        b.image_box = Some(ImageBox {
            x1: 1.0,
            y1: 2.0,
            x2: 3.0,
            y2: 4.0,
        });
        b.needs_own_entry = true;
        for v in b.attributes.values_mut() {
            v.push_str("-stale");
        }
        b.attributes.insert("stale".into(), "yes".into());
    }
    frame.rejected.push(Rejected {
        index: 99,
        label: "stale".into(),
        reason: SkipReason::LabelNotUtf8,
    });
}
