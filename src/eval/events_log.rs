//! Writes `eval --events` output: a copy of a log (every schema, channel, message, attachment
//! and metadata record) with two more channels, the events as `probmot.EvalEvents` and as a
//! `foxglove.SceneUpdate`, each frame's events placed before the first copied message that is
//! later than the frame, so a time-ordered input stays time-ordered.

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::path::Path;

use anyhow::{bail, Context, Result};
use mcap::records::{MessageHeader, Record};

use super::events::Event;
use crate::mcapio::background::BackgroundOutput;
use crate::mcapio::reader::{read_records, read_summary_records};
use crate::mcapio::writer::OutputOptions;
use crate::msgs::eval_events::{
    scene_update, EVAL_DESCRIPTOR_SET, EVAL_EVENTS_SCHEMA, EVENTS_SCENE_TOPIC, EVENTS_TOPIC,
};
use crate::msgs::scene_update::{scene_update_descriptor, SCENE_UPDATE_SCHEMA};
use crate::msgs::{decode, encode_into, Encoding, EvalEvents, Tracks3D};

/// Schema and channel ids of the two added channels (high, so they do not meet the input's ids;
/// an input that uses them is refused).
const EVENTS_ID: u16 = u16::MAX - 1;
const SCENE_ID: u16 = u16::MAX - 2;

/// The events of one log, by frame stamp (ns), each with the index of its class in
/// [`EventLabels::classes`].
pub type LogEvents = BTreeMap<u64, Vec<(u16, Event)>>;

/// What the written events are labelled with: the protocol's name and the class names that
/// [`LogEvents`] index.
#[derive(Debug, Clone, Copy)]
pub struct EventLabels<'a> {
    /// `nuscenes` or `kitti`.
    pub protocol: &'a str,
    /// Class names.
    pub classes: &'a [String],
}

/// What [`write_events_log`] wrote.
#[derive(Debug, Clone, Copy, Default)]
pub struct Written {
    /// Messages copied from the input.
    pub copied: u64,
    /// Frames of events written (each on both channels).
    pub frames: u64,
}

/// Copies `src` to `dest` (atomically) with the events added. The events take the `frame_id`
/// of the latest message of `truth_topic` at or before their stamp (protobuf or JSON
/// `probmot.Tracks3D`; `map` when none is known). Matches are drawn in the scene only when
/// `scene_matches`.
pub fn write_events_log(
    src: &Path,
    dest: &Path,
    truth_topic: &str,
    (events, labels): (&LogEvents, EventLabels<'_>),
    scene_matches: bool,
) -> Result<Written> {
    let name = src.display().to_string();
    let mut opts = OutputOptions::default();
    if let Some((Record::Header(h), _)) = read_summary_records(src) {
        opts.profile = h.profile;
    }
    let mut out = BackgroundOutput::create_inline(dest, &opts)?;
    out.add_schema_with_id(
        EVENTS_ID,
        EVAL_EVENTS_SCHEMA,
        "protobuf",
        EVAL_DESCRIPTOR_SET,
    )?;
    let scene_descriptor = scene_update_descriptor();
    out.add_schema_with_id(SCENE_ID, SCENE_UPDATE_SCHEMA, "protobuf", &scene_descriptor)?;
    let meta = BTreeMap::new();
    out.add_channel_with_id(EVENTS_ID, EVENTS_ID, EVENTS_TOPIC, "protobuf", &meta)?;
    out.add_channel_with_id(SCENE_ID, SCENE_ID, EVENTS_SCENE_TOPIC, "protobuf", &meta)?;
    let mut w = Writer {
        out,
        pending: events.iter().peekable(),
        labels,
        frame_id: "map".to_string(),
        buf: Vec::new(),
        written: Written::default(),
        scene_matches,
    };
    let mut truth_channels: BTreeMap<u16, Encoding> = BTreeMap::new();
    read_records(src, |rec, _| {
        match rec {
            Record::Schema { header, data } if header.id != 0 => {
                if header.id >= SCENE_ID {
                    bail!("{name}: schema id {} is reserved for the events", header.id);
                }
                w.out
                    .add_schema_with_id(header.id, &header.name, &header.encoding, &data)?;
            }
            Record::Channel(c) => {
                if c.id >= SCENE_ID {
                    bail!("{name}: channel id {} is reserved for the events", c.id);
                }
                if c.topic == truth_topic {
                    if let Some(e) = Encoding::from_message_encoding(&c.message_encoding) {
                        truth_channels.insert(c.id, e);
                    }
                }
                w.out.add_channel_with_id(
                    c.id,
                    c.schema_id,
                    &c.topic,
                    &c.message_encoding,
                    &c.metadata,
                )?;
            }
            Record::Message { header, data } => {
                w.flush_before(header.log_time)?;
                if let Some(&e) = truth_channels.get(&header.channel_id) {
                    if let Ok(t) = decode::<Tracks3D>(&data, e) {
                        if !t.frame_id.is_empty() {
                            w.frame_id = t.frame_id;
                        }
                    }
                }
                w.out.write_to_known_channel(&header, &data)?;
                w.written.copied += 1;
            }
            Record::Attachment { header, data, .. } => w.out.attach(&mcap::Attachment {
                log_time: header.log_time,
                create_time: header.create_time,
                name: header.name,
                media_type: header.media_type,
                data: Cow::Owned(data.into_owned()),
            })?,
            Record::Metadata(m) => w.out.write_metadata(&m)?,
            _ => {}
        }
        Ok(())
    })
    .with_context(|| format!("copying {name} to {}", dest.display()))?;
    w.flush_before(u64::MAX)?;
    let written = w.written;
    w.out.commit()?;
    Ok(written)
}

/// The output and the events not yet written.
struct Writer<'a> {
    out: BackgroundOutput,
    pending: std::iter::Peekable<std::collections::btree_map::Iter<'a, u64, Vec<(u16, Event)>>>,
    labels: EventLabels<'a>,
    frame_id: String,
    buf: Vec<u8>,
    written: Written,
    scene_matches: bool,
}

impl Writer<'_> {
    /// Writes the events of every frame earlier than `log_time` (all with `u64::MAX`).
    fn flush_before(&mut self, log_time: u64) -> Result<()> {
        while let Some((&stamp, ev)) = self.pending.peek() {
            if stamp >= log_time && log_time != u64::MAX {
                break;
            }
            let ev = EvalEvents {
                stamp,
                frame_id: self.frame_id.clone(),
                protocol: self.labels.protocol.to_string(),
                events: (ev.iter())
                    .map(|&(class, e)| e.message(&self.labels.classes[usize::from(class)]))
                    .collect(),
            };
            let seq = self.written.frames as u32;
            let header = |channel_id| MessageHeader {
                channel_id,
                sequence: seq,
                log_time: stamp,
                publish_time: stamp,
            };
            encode_into(&ev, &mut self.buf);
            self.out
                .write_to_known_channel(&header(EVENTS_ID), &self.buf)?;
            encode_into(&scene_update(&ev, self.scene_matches), &mut self.buf);
            self.out
                .write_to_known_channel(&header(SCENE_ID), &self.buf)?;
            self.written.frames += 1;
            self.pending.next();
        }
        Ok(())
    }
}
