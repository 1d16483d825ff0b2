//! Reading only a time window of a long log: with the summary's chunk indexes, the chunks whose
//! log times overlap the window (padded by [`SLACK_NS`]) are read and only the channels asked
//! for are decoded, so memory and time follow the window, not the log. The first and last frame
//! (for "seconds after the first frame") come from the first and last message of each layer's
//! topic, one chunk each. A file without chunk indexes is read linearly ([`super::read_layers`]).

use std::collections::{BTreeMap, BTreeSet};
use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::path::Path;

use anyhow::{bail, Context, Result};
use mcap::records::MessageHeader;
use mcap::sans_io::indexed_reader::ReadOrder;
use mcap::sans_io::indexed_reader::{IndexedReadEvent, IndexedReader, IndexedReaderOptions};
use mcap::sans_io::summary_reader::{SummaryReadEvent, SummaryReader};
use mcap::{Channel, Summary};

use super::{drawn_detection, drawn_track, read_layers, FileLayers, Frame, Layer, LayerFrames};
use crate::mcapio::reader::read_records;
use crate::mcapio::recording::tracks_stamp;
use crate::mcapio::LabelledBox;
use crate::msgs::autoware_tracks::{self, KinematicsOrder};
use crate::msgs::detection_frame::stamp_or_log_time;
use crate::msgs::detection_source::DetectionSource;
use crate::msgs::eval_events::EVAL_EVENTS_SCHEMA;
use crate::msgs::{self, ros2_tracks, ros2_vision, Encoding, EvalEvents, Tracks3D, TRACKS_SCHEMA};
use mcap::records::Record;
use prost::Message as _;

/// Log times read beyond each end of the window: a message's stamp (what the window is in) may
/// differ from its log time by up to this much (probmot writes them equal).
pub const SLACK_NS: u64 = 1_000_000_000;

/// The summary section, if the file has one with chunk indexes.
fn summary(file: &mut File) -> Option<Summary> {
    let mut reader = SummaryReader::new();
    while let Some(event) = reader.next_event() {
        match event.ok()? {
            SummaryReadEvent::ReadRequest(need) => {
                let n = file.read(reader.insert(need)).ok()?;
                reader.notify_read(n);
            }
            SummaryReadEvent::SeekRequest(to) => reader.notify_seeked(file.seek(to).ok()?),
        }
    }
    reader
        .finish()
        .filter(|s| !s.chunk_indexes.is_empty() && !s.channels.is_empty())
}

/// Decodes the messages of one channel into boxes, with the message's stamp and frame id.
enum Decoder {
    Detections(DetectionSource),
    Tracks(Encoding),
    Ros2Tracks(ros2_vision::VisionLayout),
    AutowareTracks(KinematicsOrder),
}

impl Decoder {
    fn for_channel(file: &str, layer: Layer, c: &Channel<'_>) -> Result<Decoder> {
        let (name, enc, data) = c
            .schema
            .as_ref()
            .map(|s| (s.name.as_str(), s.encoding.as_str(), &s.data[..]))
            .unwrap_or_default();
        let me = c.message_encoding.as_str();
        let source = || DetectionSource::for_channel(name, enc, data, me);
        let what = || format!("{file}: topic {} ({layer} layer)", c.topic);
        if layer == Layer::Detections {
            return source()
                .map(Decoder::Detections)
                .map_err(|why| anyhow::anyhow!("{}: {why}", what()));
        }
        if let Some(order) = autoware_tracks::layout_for_channel(name, enc, data, me) {
            return order
                .map(Decoder::AutowareTracks)
                .map_err(|why| anyhow::anyhow!("{}: {why}", what()));
        }
        if ros2_vision::SCHEMA_NAMES.contains(&name) {
            return match source() {
                Ok(DetectionSource::Ros2Vision(l)) => Ok(Decoder::Ros2Tracks(l)),
                Ok(_) => unreachable!("a ROS 2 schema name gives a ROS 2 source"),
                Err(why) => bail!("{}: {why}", what()),
            };
        }
        match (name == TRACKS_SCHEMA, Encoding::from_message_encoding(me)) {
            (true, Some(e)) => Ok(Decoder::Tracks(e)),
            _ => bail!(
                "{}: schema '{name}' / encoding '{me}', expected {TRACKS_SCHEMA} (protobuf or \
                 json), ROS 2 vision_msgs/msg/Detection3DArray or Autoware TrackedObjects tracks",
                what()
            ),
        }
    }

    /// `(stamp, frame_id, boxes)` of one message.
    fn decode(&self, h: &MessageHeader, data: &[u8]) -> Result<(u64, String, Vec<LabelledBox>)> {
        Ok(match self {
            Decoder::Detections(s) => {
                let m = s.decode(data)?;
                let stamp = stamp_or_log_time(m.stamp, h.log_time);
                let boxes = m.detections.into_iter().map(drawn_detection).collect();
                (stamp, m.frame_id, boxes)
            }
            Decoder::Tracks(e) => tracks(msgs::decode::<Tracks3D>(data, *e)?, h),
            Decoder::Ros2Tracks(l) => tracks(ros2_tracks::decode_tracks(data, *l)?, h),
            Decoder::AutowareTracks(o) => tracks(autoware_tracks::decode_tracks(data, *o)?, h),
        })
    }
}

fn tracks(m: Tracks3D, h: &MessageHeader) -> (u64, String, Vec<LabelledBox>) {
    let boxes = m.tracks.into_iter().map(drawn_track).collect();
    (tracks_stamp(m.stamp, h.log_time), m.frame_id, boxes)
}

/// Runs an indexed read of `channels` (log-time `order`, optional inclusive bounds), calling `f`
/// per message until it returns `false`.
fn indexed(
    file: &mut File,
    summary: &Summary,
    opts: IndexedReaderOptions,
    mut f: impl FnMut(&MessageHeader, &[u8]) -> Result<bool>,
) -> Result<()> {
    // Chunks are decompressed whole here: the size limit of every read (`--max-chunk-mib`)
    // bounds them, against corrupted indexes and files that expand to gigabytes.
    let limit = usize::try_from(crate::mcapio::chunk_stream::size_limit()).unwrap_or(usize::MAX);
    let mut reader =
        IndexedReader::new_with_options(summary, opts.with_record_length_limit(limit))?;
    let mut buf = Vec::new();
    while let Some(event) = reader.next_event() {
        match event? {
            IndexedReadEvent::ReadChunkRequest { offset, length } => {
                file.seek(SeekFrom::Start(offset))?;
                buf.resize(length, 0);
                file.read_exact(&mut buf)?;
                reader.insert_chunk_record_data(offset, &buf)?;
            }
            IndexedReadEvent::Message { header, data } => {
                if !f(&header, data)? {
                    break;
                }
            }
        }
    }
    Ok(())
}

/// First and last frame stamp over `topics` (the first message of each topic in log-time order,
/// and the last), and the stamp minus the log time of the first frame.
fn span(
    file: &mut File,
    summary: &Summary,
    topics: &[&String],
    decoders: &BTreeMap<u16, (usize, Decoder)>,
    ctx: &dyn Fn(&MessageHeader) -> String,
) -> Result<(Option<(u64, u64)>, i128)> {
    let mut span: Option<(u64, u64)> = None;
    let mut offset: i128 = 0;
    for order in [ReadOrder::LogTime, ReadOrder::ReverseLogTime] {
        for topic in topics {
            let opts = IndexedReaderOptions::new()
                .with_order(order)
                .include_topics([topic.as_str()]);
            indexed(file, summary, opts, |h, data| {
                let (stamp, _, _) = decoders[&h.channel_id]
                    .1
                    .decode(h, data)
                    .with_context(|| ctx(h))?;
                let (a, b) = span.unwrap_or((stamp, stamp));
                if span.is_none() || stamp < a {
                    offset = stamp as i128 - h.log_time as i128;
                }
                span = Some((a.min(stamp), b.max(stamp)));
                Ok(false)
            })?;
        }
    }
    Ok((span, offset))
}

/// The layers of `path` for a window of `[from_s, to_s]` seconds after the first frame: every
/// asked-for topic's presence and the first and last frame stamps over them
/// ([`FileLayers::span`]), and the frames of the `drawn` layers in the window (a little more:
/// the caller selects by stamp). Falls back to reading the whole file when it has no chunk
/// indexes.
pub fn read_window(
    path: &Path,
    wanted: &[(Layer, String)],
    drawn: &[Layer],
    from_s: Option<f64>,
    to_s: Option<f64>,
) -> Result<FileLayers> {
    let name = path.display().to_string();
    let mut file = File::open(path).with_context(|| format!("cannot open {name}"))?;
    let Some(summary) = summary(&mut file) else {
        return read_layers(path, wanted);
    };
    let topics: BTreeSet<String> = summary.channels.values().map(|c| c.topic.clone()).collect();
    // Channels of each asked-for layer, with their decoders.
    let mut decoders: BTreeMap<u16, (usize, Decoder)> = BTreeMap::new();
    for (i, (layer, topic)) in wanted.iter().enumerate() {
        for c in summary.channels.values().filter(|c| &c.topic == topic) {
            decoders.insert(c.id, (i, Decoder::for_channel(&name, *layer, c)?));
        }
    }
    let present: Vec<&String> = wanted
        .iter()
        .map(|w| &w.1)
        .filter(|t| topics.contains(*t))
        .collect();
    let ctx = |h: &MessageHeader| {
        let topic = summary
            .channels
            .get(&h.channel_id)
            .map(|c| c.topic.as_str())
            .unwrap_or("?");
        format!(
            "{name}: topic {topic}, message at log_time {}: cannot decode",
            h.log_time
        )
    };
    let (span, offset) = span(&mut file, &summary, &present, &decoders, &ctx)?;
    let mut layers: Vec<LayerFrames> = wanted
        .iter()
        .filter(|(_, t)| topics.contains(t))
        .map(|(l, t)| LayerFrames {
            layer: *l,
            topic: t.clone(),
            frames: Vec::new(),
            log_times: Vec::new(),
            frame_ids: BTreeSet::new(),
        })
        .collect();
    if let Some((t0, _)) = span {
        let at =
            |s: f64| (t0 as i128 + (s * 1e9) as i128 - offset).clamp(0, u64::MAX as i128) as u64;
        let mut opts = IndexedReaderOptions::new()
            .with_order(ReadOrder::File)
            .include_topics(
                wanted
                    .iter()
                    .filter(|(l, _)| drawn.contains(l))
                    .map(|(_, t)| t.as_str()),
            );
        if let Some(f) = from_s {
            opts = opts.starting_at(at(f).saturating_sub(SLACK_NS));
        }
        if let Some(t) = to_s {
            opts = opts.ending_at(at(t).saturating_add(SLACK_NS));
        }
        indexed(&mut file, &summary, opts, |h, data| {
            let (i, decoder) = &decoders[&h.channel_id];
            let (stamp, frame_id, boxes) = decoder.decode(h, data).with_context(|| ctx(h))?;
            let lf = layers
                .iter_mut()
                .find(|l| l.topic == wanted[*i].1)
                .expect("present");
            let frame: Frame = (stamp, boxes);
            lf.frames.push(frame);
            lf.log_times.push(h.log_time);
            lf.frame_ids.insert(frame_id);
            Ok(true)
        })?;
    }
    Ok(FileLayers {
        layers,
        topics,
        span,
    })
}

/// The `probmot.EvalEvents` messages of `topic` in `path` (written by `eval --events`) whose log
/// time lies in `[from_ns, to_ns]`, read through the chunk indexes when the file has them.
pub fn read_events(path: &Path, topic: &str, from_ns: u64, to_ns: u64) -> Result<Vec<EvalEvents>> {
    let timed = read_timed_events(path, topic, from_ns, to_ns)?;
    Ok(timed.into_iter().map(|(_, m)| m).collect())
}

/// [`read_events`] with the log time of each message (to place it on a recording's timelines).
pub fn read_timed_events(
    path: &Path,
    topic: &str,
    from_ns: u64,
    to_ns: u64,
) -> Result<Vec<(u64, EvalEvents)>> {
    let name = path.display().to_string();
    let mut file = File::open(path).with_context(|| format!("cannot open {name}"))?;
    let mut out = Vec::new();
    let mut decode = |h: &MessageHeader, data: &[u8]| -> Result<()> {
        if (from_ns..=to_ns).contains(&h.log_time) {
            let m = EvalEvents::decode(data).with_context(|| {
                format!(
                    "{name}: topic {topic}, message at log_time {}: not probmot.EvalEvents",
                    h.log_time
                )
            })?;
            out.push((h.log_time, m));
        }
        Ok(())
    };
    if let Some(summary) = summary(&mut file) {
        let Some(c) = summary.channels.values().find(|c| c.topic == topic) else {
            bail!("{name} has no topic {topic} (write it with `probmot eval --events {name}`)");
        };
        check_events_schema(&name, c)?;
        let opts = IndexedReaderOptions::new()
            .with_order(ReadOrder::File)
            .include_topics([topic])
            .starting_at(from_ns)
            .ending_at(to_ns);
        indexed(&mut file, &summary, opts, |h, data| {
            decode(h, data).map(|_| true)
        })?;
        return Ok(out);
    }
    let mut channel = None;
    read_records(path, |rec, _| {
        match rec {
            Record::Channel(c) if c.topic == topic => channel = Some(c.id),
            Record::Message { header, data } if Some(header.channel_id) == channel => {
                decode(&header, &data)?
            }
            _ => {}
        }
        Ok(())
    })?;
    if channel.is_none() {
        bail!("{name} has no topic {topic} (write it with `probmot eval --events {name}`)");
    }
    Ok(out)
}

fn check_events_schema(name: &str, c: &Channel<'_>) -> Result<()> {
    let schema = c.schema.as_ref().map(|s| s.name.as_str()).unwrap_or("");
    if schema != EVAL_EVENTS_SCHEMA || c.message_encoding != "protobuf" {
        bail!(
            "{name}: topic {} has schema '{schema}' ({}), expected {EVAL_EVENTS_SCHEMA} (protobuf)",
            c.topic,
            c.message_encoding
        );
    }
    Ok(())
}
