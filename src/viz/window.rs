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

use super::{drawn_boxes, read_layers, FileLayers, Frame, Layer, LayerFrames};
use crate::mcapio::reader::read_records;
use crate::mcapio::recording::Decoder;
use crate::msgs::eval_events::EVAL_EVENTS_SCHEMA;
use crate::msgs::EvalEvents;
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

/// The decoder of a layer's channel (the one decoder of box channels, [`Decoder`]).
fn decoder(file: &str, layer: Layer, c: &Channel<'_>) -> Result<Decoder> {
    let schema = c.schema.as_ref().map_or(("", "", &[][..]), |s| {
        (s.name.as_str(), s.encoding.as_str(), &s.data[..])
    });
    Decoder::for_channel(file, &layer.request(&c.topic), schema, &c.message_encoding)
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
                let Some((_, decoder)) = decoders.get(&h.channel_id) else {
                    return Ok(true);
                };
                let stamp = decoder
                    .decode(data, h.log_time)
                    .with_context(|| ctx(h))?
                    .stamp;
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
/// the caller selects by stamp; none when no layer is drawn or the file has none of the drawn
/// ones). Falls back to reading the whole file when it has no chunk indexes.
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
            decoders.insert(c.id, (i, decoder(&name, *layer, c)?));
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
    // The drawn layers the file has: an empty list would read every channel.
    let drawn_topics: Vec<&str> = (wanted.iter())
        .filter(|(l, t)| drawn.contains(l) && topics.contains(t))
        .map(|(_, t)| t.as_str())
        .collect();
    if let (Some((t0, _)), false) = (span, drawn_topics.is_empty()) {
        let at =
            |s: f64| (t0 as i128 + (s * 1e9) as i128 - offset).clamp(0, u64::MAX as i128) as u64;
        let mut opts = IndexedReaderOptions::new()
            .with_order(ReadOrder::File)
            .include_topics(drawn_topics);
        if let Some(f) = from_s {
            opts = opts.starting_at(at(f).saturating_sub(SLACK_NS));
        }
        if let Some(t) = to_s {
            opts = opts.ending_at(at(t).saturating_add(SLACK_NS));
        }
        indexed(&mut file, &summary, opts, |h, data| {
            let Some((i, decoder)) = decoders.get(&h.channel_id) else {
                return Ok(true);
            };
            let Some(lf) = layers.iter_mut().find(|l| l.topic == wanted[*i].1) else {
                return Ok(true);
            };
            let (f, frame_id) =
                (decoder.decode_with_frame_id(data, h.log_time)).with_context(|| ctx(h))?;
            let frame: Frame = (f.stamp, drawn_boxes(f.boxes));
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mcapio::writer::{AtomicOutput, OutputOptions};
    use crate::msgs::{
        encode_into, Detection3D, Detections3D, Track3D, Tracks3D, DESCRIPTOR_SET,
        DETECTIONS_SCHEMA, TRACKS_SCHEMA,
    };

    /// A chunked log with detections, tracks and a tracks topic nobody asks for (`/other`),
    /// one message each at log times 1, 2 and 3 s.
    fn write_log(path: &Path) {
        let mut out = AtomicOutput::create(path, &OutputOptions::default()).unwrap();
        let w = &mut out.writer;
        let none = BTreeMap::new();
        let det = w
            .add_schema(DETECTIONS_SCHEMA, "protobuf", DESCRIPTOR_SET)
            .unwrap();
        let tr = w
            .add_schema(TRACKS_SCHEMA, "protobuf", DESCRIPTOR_SET)
            .unwrap();
        let channels = [
            w.add_channel(det, "/detections", "protobuf", &none)
                .unwrap(),
            w.add_channel(tr, "/tracks", "protobuf", &none).unwrap(),
            w.add_channel(tr, "/other", "protobuf", &none).unwrap(),
        ];
        for (k, channel_id) in channels.into_iter().enumerate() {
            let log_time = (k as u64 + 1) * 1_000_000_000;
            let mut buf = Vec::new();
            if k == 0 {
                let detections = vec![Detection3D::default()];
                encode_into(
                    &Detections3D {
                        detections,
                        ..Default::default()
                    },
                    &mut buf,
                );
            } else {
                let tracks = vec![Track3D {
                    id: 7,
                    ..Default::default()
                }];
                let frame_id = "map".to_string();
                encode_into(
                    &Tracks3D {
                        tracks,
                        frame_id,
                        ..Default::default()
                    },
                    &mut buf,
                );
            }
            let header = MessageHeader {
                channel_id,
                sequence: 0,
                log_time,
                publish_time: log_time,
            };
            w.write_to_known_channel(&header, &buf).unwrap();
        }
        out.commit().unwrap();
    }

    fn wanted(layers: &[Layer]) -> Vec<(Layer, String)> {
        (layers.iter())
            .map(|l| (*l, l.default_topic().to_string()))
            .collect()
    }

    #[test]
    fn a_window_reads_only_the_drawn_layers_the_file_has() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("log.mcap");
        write_log(&path);
        let all = wanted(&Layer::ALL);
        let read = read_window(&path, &all, &[Layer::Tracks], None, None).unwrap();
        assert_eq!(
            read.span,
            Some((1_000_000_000, 2_000_000_000)),
            "indexed read"
        );
        let tracks = read.get(Layer::Tracks).unwrap();
        assert_eq!(tracks.frames.len(), 1);
        assert_eq!(tracks.frames[0].1[0].id, 7);
        assert_eq!(tracks.frame_ids, BTreeSet::from(["map".to_string()]));
        assert!(read.get(Layer::Detections).unwrap().frames.is_empty());
        assert!(
            read.get(Layer::GroundTruth).is_none(),
            "the file has no truth"
        );
        assert!(read.topics.contains("/other"));
    }

    #[test]
    fn a_window_of_no_layers_is_empty_not_a_panic() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("log.mcap");
        write_log(&path);
        let all = wanted(&Layer::ALL);
        // Nothing drawn, a drawn layer the file lacks, nothing asked for.
        for (wanted, drawn) in [
            (all.clone(), vec![]),
            (all.clone(), vec![Layer::GroundTruth]),
            (vec![], Layer::ALL.to_vec()),
        ] {
            let read = read_window(&path, &wanted, &drawn, Some(0.0), None).unwrap();
            assert!(read.layers.iter().all(|l| l.frames.is_empty()), "{drawn:?}");
            assert_eq!(read.layers.len(), wanted.len().min(2), "{drawn:?}");
            assert_eq!(read.topics.len(), 3);
        }
    }
}
