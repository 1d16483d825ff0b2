//! One reader of the box channels of a recording, for every consumer that reads frames (eval,
//! fit, plot, viz, tune, export): each channel is resolved once into a [`Decoder`] (also what
//! viz's windowed read uses), and each message becomes a [`Frame`] `{stamp, log_time, boxes}`
//! with the stamp rule applied here.
//!
//! The stamp rule: a message's own stamp, else its MCAP `log_time`. A detection message's
//! stamp is optional ([`crate::msgs::detection_frame::stamp_or_log_time`]); a
//! `probmot.Tracks3D` stamp of 0 counts as absent ([`tracks_stamp`]).

use std::collections::{BTreeMap, BTreeSet};
use std::fmt;
use std::path::Path;

use anyhow::{bail, Context, Result};
use mcap::records::Record;

use super::reader::{read_records, read_summary_records, ReadStats};
use crate::msgs::autoware;
use crate::msgs::autoware_tracks::{self, KinematicsOrder};
use crate::msgs::detection_frame::{check_box, stamp_or_log_time, SkipReason};
use crate::msgs::detection_source::DetectionSource;
use crate::msgs::ros2_tracks;
use crate::msgs::ros2_vision::{self, VisionLayout};
use crate::msgs::{self, Detection3D, Encoding, Track3D, Tracks3D, TRACKS_SCHEMA};

/// What a requested topic holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TopicKind {
    /// Detections of any supported input schema ([`DetectionSource`]).
    Detections,
    /// `probmot.Tracks3D` (tracks or ground truth) in protobuf or JSON, ROS 2
    /// `vision_msgs/msg/Detection3DArray` tracks (track id in `Detection3D.id`, as `track
    /// --tracks-format ros2` writes them), or Autoware `TrackedObjects` (track id from the
    /// UUID, [`autoware_tracks::uuid_track_id`]).
    Tracks,
}

/// One requested topic: its name, its kind, and how errors call it (e.g. `tracks layer`).
#[derive(Debug, Clone)]
pub struct TopicRequest {
    /// Topic name.
    pub topic: String,
    /// What it holds.
    pub kind: TopicKind,
    /// Its role, for error messages (`topic /tracks (tracks layer): ...`).
    pub role: String,
}

/// The boxes of one message, as decoded (each consumer keeps what it needs).
#[derive(Debug, Clone, PartialEq)]
pub enum Boxes {
    /// The boxes of a detection message.
    Detections(Vec<Detection3D>),
    /// The tracks of a `probmot.Tracks3D` message.
    Tracks(Vec<Track3D>),
}

/// One message of a box channel.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    /// The message's stamp, else its log_time.
    pub stamp: u64,
    /// The MCAP log_time of the message.
    pub log_time: u64,
    /// Its boxes.
    pub boxes: Boxes,
    /// Detection boxes left out of `boxes`, one reason per box: a string of theirs is not
    /// UTF-8 ([`DetectionSource::decode_kept`]), or [`Frame::skip_classes_without_entry`].
    pub skipped: Vec<SkipReason>,
    /// The boxes are Autoware `DetectedObjects`, whose classes that are none of probmot's
    /// (UNKNOWN, ANIMAL, ...) are tracked only under a config entry of their own name.
    pub autoware_classes: bool,
}

impl Frame {
    /// The rule of `probmot track` for Autoware classes that are none of probmot's
    /// ([`autoware::is_class_without_probmot_class`]): a box of such a class whose label has no
    /// config entry (`has_entry`) is left out and counted in `skipped` as
    /// [`SkipReason::ClassWithoutEntry`]. As in `track`, a box the box check refuses
    /// ([`check_box`]) stays, to be counted for that. Other frames are unchanged.
    pub fn skip_classes_without_entry(&mut self, has_entry: &dyn Fn(&str) -> bool) {
        let Boxes::Detections(d) = &mut self.boxes else {
            return;
        };
        if !self.autoware_classes {
            return;
        }
        let before = d.len();
        d.retain(|b| {
            check_box(b).is_err()
                || !autoware::is_class_without_probmot_class(&b.label)
                || has_entry(&b.label)
        });
        let n = before - d.len();
        (self.skipped).extend(std::iter::repeat_n(SkipReason::ClassWithoutEntry, n));
    }
}

/// The frames of the requested topics of one recording.
#[derive(Debug, Clone, Default)]
pub struct RecordingFrames {
    /// Per request (same order): its frames in file order, `None` when the file has no channel
    /// of that topic.
    pub frames: Vec<Option<Vec<Frame>>>,
    /// Every topic of the file.
    pub topics: BTreeSet<String>,
}

/// The stamp of a `probmot.Tracks3D` message: its `stamp`, or the log_time when that is 0.
pub fn tracks_stamp(stamp: u64, log_time: u64) -> u64 {
    if stamp != 0 {
        stamp
    } else {
        log_time
    }
}

/// How the messages of one box channel are decoded: chosen once per channel from its schema and
/// encodings for a request ([`Decoder::for_channel`]), then applied to each message with the
/// stamp rule ([`Decoder::decode`]). Every reader of box channels (eval, fit, plot, viz, tune,
/// export) decodes through it.
#[derive(Debug, Clone, Copy)]
pub enum Decoder {
    /// Detections of any supported input schema.
    Detections(DetectionSource),
    /// `probmot.Tracks3D` in protobuf or JSON.
    Tracks(Encoding),
    /// ROS 2 `vision_msgs/msg/Detection3DArray` tracks.
    Ros2Tracks(VisionLayout),
    /// Autoware `TrackedObjects`.
    AutowareTracks(KinematicsOrder),
}

/// A schema record: name, encoding, data.
#[derive(Default, Clone)]
struct SchemaInfo {
    name: String,
    encoding: String,
    data: Vec<u8>,
}

impl fmt::Display for TopicRequest {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "topic {} ({})", self.topic, self.role)
    }
}

impl Decoder {
    /// The decoder of a channel (its schema's name, encoding and data, and its message
    /// encoding; a channel without a schema gives empty ones) for a request, or an error naming
    /// the file, topic and role.
    pub fn for_channel(
        file: &str,
        req: &TopicRequest,
        schema: (&str, &str, &[u8]),
        message_encoding: &str,
    ) -> Result<Decoder> {
        let (name, encoding, data) = schema;
        match req.kind {
            TopicKind::Detections => {
                DetectionSource::for_channel(name, encoding, data, message_encoding)
                    .map(Decoder::Detections)
                    .map_err(|why| anyhow::anyhow!("{file}: {req}: {why}"))
            }
            TopicKind::Tracks => {
                if let Some(layout) =
                    autoware_tracks::layout_for_channel(name, encoding, data, message_encoding)
                {
                    return layout
                        .map(Decoder::AutowareTracks)
                        .map_err(|why| anyhow::anyhow!("{file}: {req}: {why}"));
                }
                if ros2_vision::SCHEMA_NAMES.contains(&name) {
                    return match DetectionSource::for_channel(
                        name,
                        encoding,
                        data,
                        message_encoding,
                    ) {
                        Ok(DetectionSource::Ros2Vision(layout)) => Ok(Decoder::Ros2Tracks(layout)),
                        Ok(_) => unreachable!("a ROS 2 schema name gives a ROS 2 source"),
                        Err(why) => bail!("{file}: {req}: {why}"),
                    };
                }
                if name != TRACKS_SCHEMA {
                    bail!(
                        "{file}: topic {} has schema '{}', expected {TRACKS_SCHEMA} (or ROS 2 \
                     vision_msgs/msg/Detection3DArray tracks, or Autoware TrackedObjects) for \
                     the {}",
                        req.topic,
                        name,
                        req.role
                    );
                }
                let Some(enc) = Encoding::from_message_encoding(message_encoding) else {
                    bail!(
                        "{file}: topic {} has message encoding '{message_encoding}'; expected \
                     protobuf or json",
                        req.topic
                    );
                };
                Ok(Decoder::Tracks(enc))
            }
        }
    }

    /// Decodes one message of the channel (logged at `log_time`), with the stamp rule applied.
    pub fn decode(&self, data: &[u8], log_time: u64) -> Result<Frame> {
        // The frame id is dropped here, as soon as decoded, not with the frame.
        self.decode_with_frame_id(data, log_time).map(|(f, _)| f)
    }

    /// [`Decoder::decode`], with the message's `frame_id` (the coordinate frame of its boxes).
    pub fn decode_with_frame_id(&self, data: &[u8], log_time: u64) -> Result<(Frame, String)> {
        let autoware_classes = matches!(self, Decoder::Detections(DetectionSource::Autoware(_)));
        let frame = |stamp, boxes, frame_id, skipped| {
            let f = Frame {
                stamp,
                log_time,
                boxes,
                skipped,
                autoware_classes,
            };
            (f, frame_id)
        };
        let tracks = |m: Tracks3D| {
            let stamp = tracks_stamp(m.stamp, log_time);
            frame(stamp, Boxes::Tracks(m.tracks), m.frame_id, Vec::new())
        };
        Ok(match self {
            Decoder::Detections(source) => {
                let (m, skipped) = source.decode_kept(data)?;
                let stamp = stamp_or_log_time(m.stamp, log_time);
                frame(stamp, Boxes::Detections(m.detections), m.frame_id, skipped)
            }
            Decoder::Ros2Tracks(layout) => tracks(ros2_tracks::decode_tracks(data, *layout)?),
            Decoder::AutowareTracks(order) => tracks(autoware_tracks::decode_tracks(data, *order)?),
            Decoder::Tracks(enc) => tracks(msgs::decode::<Tracks3D>(data, *enc)?),
        })
    }
}

/// Reads the requested topics of `path` in one pass. A topic the file lacks gives `None`; a
/// channel of the wrong schema or an undecodable message is an error naming the file, topic and
/// log time. Holds every frame in memory: long logs are better read with [`for_each_frame`].
pub fn frames(path: &Path, wanted: &[TopicRequest]) -> Result<RecordingFrames> {
    let mut frames: Vec<Option<Vec<Frame>>> = vec![None; wanted.len()];
    let topics = for_each_frame(path, wanted, |event, _| {
        match event {
            FrameEvent::Channel(i) => {
                frames[i].get_or_insert_with(Vec::new);
            }
            FrameEvent::Frame(i, frame) => frames[i].get_or_insert_with(Vec::new).push(frame),
        }
        Ok(())
    })?;
    Ok(RecordingFrames { frames, topics })
}

/// What [`for_each_frame`] hands its callback, in file order.
#[derive(Debug)]
pub enum FrameEvent {
    /// The file has a channel of request `i` (given before that channel's first frame, and
    /// again for every further channel record, e.g. the summary section's copy).
    Channel(usize),
    /// One decoded message of request `i`.
    Frame(usize, Frame),
}

/// Streams the requested topics of `path` in one pass: each message is decoded and handed to
/// `f` at once (with the bytes read so far, for progress), so memory stays bounded by what the
/// caller keeps. Errors as [`frames`]; an error of `f` ends the read. Returns every topic of
/// the file.
pub fn for_each_frame(
    path: &Path,
    wanted: &[TopicRequest],
    f: impl FnMut(FrameEvent, ReadStats) -> Result<()>,
) -> Result<BTreeSet<String>> {
    for_each_frame_with(path, wanted, f, |_| Ok(()))
}

/// [`for_each_frame`], handing `other` every record that is not a schema, a channel or a
/// message (metadata, attachments, the summary's statistics...) in file order.
pub fn for_each_frame_with(
    path: &Path,
    wanted: &[TopicRequest],
    mut f: impl FnMut(FrameEvent, ReadStats) -> Result<()>,
    mut other: impl FnMut(Record<'_>) -> Result<()>,
) -> Result<BTreeSet<String>> {
    let file = path.display().to_string();
    let mut schemas: BTreeMap<u16, SchemaInfo> = BTreeMap::new();
    // Per channel, the requests it serves (a topic may be requested twice, as two kinds).
    let mut channels: BTreeMap<u16, Vec<(usize, Decoder)>> = BTreeMap::new();
    let mut topics = BTreeSet::new();
    read_records(path, |rec, stats| {
        match rec {
            Record::Schema { header, data } => {
                let info = SchemaInfo {
                    name: header.name,
                    encoding: header.encoding,
                    data: data.into_owned(),
                };
                schemas.insert(header.id, info);
            }
            Record::Channel(c) => {
                topics.insert(c.topic.clone());
                for (i, req) in wanted
                    .iter()
                    .enumerate()
                    .filter(|(_, r)| r.topic == c.topic)
                {
                    let schema = schemas.get(&c.schema_id).map_or(("", "", &[][..]), |s| {
                        (s.name.as_str(), s.encoding.as_str(), &s.data[..])
                    });
                    let decoder = Decoder::for_channel(&file, req, schema, &c.message_encoding)?;
                    channels.entry(c.id).or_default().push((i, decoder));
                    f(FrameEvent::Channel(i), stats)?;
                }
            }
            Record::Message { header, data } => {
                for (i, decoder) in channels.get(&header.channel_id).into_iter().flatten() {
                    let ctx = || {
                        format!(
                            "{file}: topic {}, message at log_time {}: cannot decode",
                            wanted[*i].topic, header.log_time
                        )
                    };
                    let frame = decoder.decode(&data, header.log_time).with_context(ctx)?;
                    f(FrameEvent::Frame(*i, frame), stats)?;
                }
            }
            rec => other(rec)?,
        }
        Ok(())
    })?;
    Ok(topics)
}

/// Every topic of `path`: from its summary section's channel records when it has them (two
/// small reads), else from a pass over the file.
pub fn file_topics(path: &Path) -> Result<BTreeSet<String>> {
    let from_summary = read_summary_records(path).map(|(_, records)| {
        (records.into_iter())
            .filter_map(|r| match r {
                Record::Channel(c) => Some(c.topic),
                _ => None,
            })
            .collect::<BTreeSet<String>>()
    });
    match from_summary {
        Some(topics) if !topics.is_empty() => Ok(topics),
        _ => for_each_frame(path, &[], |_, _| Ok(())),
    }
}

/// `topics: a, b` (sorted), or that the file has none: what an error about a missing topic
/// names beside it.
pub fn topic_list<'a>(topics: impl IntoIterator<Item = &'a String>) -> String {
    let mut names: Vec<&str> = topics.into_iter().map(String::as_str).collect();
    names.sort_unstable();
    match names.is_empty() {
        true => "the file has no channels".to_string(),
        false => format!("topics: {}", names.join(", ")),
    }
}

/// The error for a topic the file has no channel for: it names the topics the file has, and for
/// `/tracks` (the tracks `probmot track` writes) says where they come from, since an untracked
/// log is the usual cause.
pub fn no_channel(
    file: impl fmt::Display,
    topic: &str,
    topics: &BTreeSet<String>,
) -> anyhow::Error {
    let has = topic_list(topics);
    let autoware_hint = format!(
        "; the file has Autoware tracks on {0} (`probmot track` writes them there for an \
         Autoware input): name that topic (--tracks-topic {0})",
        autoware_tracks::TRACKING_TOPIC
    );
    let hint = match topic {
        "/tracks" if topics.contains(autoware_tracks::TRACKING_TOPIC) => &autoware_hint,
        "/tracks" if !topics.contains("/detections") && topics.contains("/ground_truth") => {
            "; the file holds ground truth but no detections to track (`--topic /ground_truth` \
             reads the truth)"
        }
        "/tracks" => "; `probmot track` writes /tracks: track the log first",
        _ => "",
    };
    anyhow::anyhow!("{file}: no channel with topic {topic} ({has}){hint}")
}

/// Streams one tracks topic (`probmot.Tracks3D` or ROS 2 tracks, [`TopicKind::Tracks`]): `f`
/// gets `(stamp, tracks, bytes read so far)` per message in file order, one message at a time;
/// an error when the file has no such channel (after the pass, since a channel record may come
/// late).
pub fn for_each_tracks_frame(
    path: &Path,
    topic: &str,
    f: impl FnMut(u64, Vec<Track3D>, ReadStats) -> Result<()>,
) -> Result<()> {
    for_each_tracks_frame_with(path, topic, f, |_| Ok(()))
}

/// [`for_each_tracks_frame`], handing `other` the records [`for_each_frame_with`] does (e.g.
/// the metadata an export needs beside the tracks).
pub fn for_each_tracks_frame_with(
    path: &Path,
    topic: &str,
    mut f: impl FnMut(u64, Vec<Track3D>, ReadStats) -> Result<()>,
    other: impl FnMut(Record<'_>) -> Result<()>,
) -> Result<()> {
    let req = TopicRequest {
        topic: topic.to_string(),
        kind: TopicKind::Tracks,
        role: "tracks or ground truth".to_string(),
    };
    let mut found = false;
    let topics = for_each_frame_with(
        path,
        std::slice::from_ref(&req),
        |event, stats| match event {
            FrameEvent::Channel(_) => {
                found = true;
                Ok(())
            }
            FrameEvent::Frame(_, frame) => match frame.boxes {
                Boxes::Tracks(t) => f(frame.stamp, t, stats),
                Boxes::Detections(_) => bail!("{}: topic {topic} gave detections", path.display()),
            },
        },
        other,
    )?;
    match found {
        true => Ok(()),
        false => Err(no_channel(path.display(), topic, &topics)),
    }
}

/// The frames of one tracks topic, as [`for_each_tracks_frame`] gives them, held in memory.
pub fn tracks_topic(path: &Path, topic: &str) -> Result<Vec<(u64, Vec<Track3D>)>> {
    let mut frames = Vec::new();
    for_each_tracks_frame(path, topic, |stamp, tracks, _| {
        frames.push((stamp, tracks));
        Ok(())
    })?;
    Ok(frames)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mcapio::writer::{AtomicOutput, OutputOptions};
    use crate::msgs::{Detections3D, DESCRIPTOR_SET, DETECTIONS_SCHEMA};

    fn write_log(path: &Path) {
        let mut out = AtomicOutput::create(path, &OutputOptions::default()).unwrap();
        let w = &mut out.writer;
        let det_schema = w
            .add_schema(DETECTIONS_SCHEMA, "protobuf", DESCRIPTOR_SET)
            .unwrap();
        let tr_schema = w
            .add_schema(TRACKS_SCHEMA, "protobuf", DESCRIPTOR_SET)
            .unwrap();
        let det = w
            .add_channel(det_schema, "/detections", "protobuf", &BTreeMap::new())
            .unwrap();
        let tr = w
            .add_channel(tr_schema, "/tracks", "protobuf", &BTreeMap::new())
            .unwrap();
        let header = |channel_id, log_time| mcap::records::MessageHeader {
            channel_id,
            sequence: 0,
            log_time,
            publish_time: log_time,
        };
        let d = |stamp| Detections3D {
            stamp,
            detections: vec![Detection3D {
                label: "car".into(),
                ..Default::default()
            }],
            ..Default::default()
        };
        let t = |stamp| Tracks3D {
            stamp,
            tracks: vec![Track3D {
                id: 4,
                ..Default::default()
            }],
            ..Default::default()
        };
        w.write_to_known_channel(&header(det, 10), &enc(&d(Some(5))))
            .unwrap();
        w.write_to_known_channel(&header(det, 20), &enc(&d(None)))
            .unwrap();
        w.write_to_known_channel(&header(tr, 30), &enc(&t(7)))
            .unwrap();
        w.write_to_known_channel(&header(tr, 40), &enc(&t(0)))
            .unwrap();
        out.commit().unwrap();
    }

    fn enc<M: prost::Message>(m: &M) -> Vec<u8> {
        let mut buf = Vec::new();
        msgs::encode_into(m, &mut buf);
        buf
    }

    fn req(topic: &str, kind: TopicKind) -> TopicRequest {
        TopicRequest {
            topic: topic.into(),
            kind,
            role: "test".into(),
        }
    }

    #[test]
    fn tracks_topic_gives_stamped_tracks_or_names_the_missing_topic() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("log.mcap");
        write_log(&path);
        let t = tracks_topic(&path, "/tracks").unwrap();
        // The second message has stamp 0: its log_time (40) stands in.
        let stamps: Vec<u64> = t.iter().map(|f| f.0).collect();
        assert_eq!(stamps, [7, 40]);
        assert!(t.iter().all(|f| f.1.len() == 1 && f.1[0].id == 4));
        let err = tracks_topic(&path, "/gt").unwrap_err().to_string();
        assert!(err.contains("log.mcap: no channel with topic /gt"), "{err}");
        // A detections channel is not a tracks topic.
        let err = format!("{:#}", tracks_topic(&path, "/detections").unwrap_err());
        assert!(err.contains("/detections"), "{err}");
    }

    #[test]
    fn file_topics_reads_the_summary_or_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("log.mcap");
        write_log(&path);
        let want = ["/detections", "/tracks"].map(String::from);
        assert!(read_summary_records(&path).is_some());
        assert_eq!(file_topics(&path).unwrap(), BTreeSet::from(want.clone()));
        // A file whose summary lists no channels is read through.
        let bare = dir.path().join("bare.mcap");
        let opts = mcap::WriteOptions::new().emit_summary_records(false);
        let mut w = opts
            .create(std::io::BufWriter::new(
                std::fs::File::create(&bare).unwrap(),
            ))
            .unwrap();
        let schema = w.add_schema("x", "", &[]).unwrap();
        let ch = w
            .add_channel(schema, "/only", "", &BTreeMap::new())
            .unwrap();
        let header = mcap::records::MessageHeader {
            channel_id: ch,
            sequence: 0,
            log_time: 1,
            publish_time: 1,
        };
        w.write_to_known_channel(&header, b"m").unwrap();
        w.finish().unwrap();
        drop(w);
        let summary = read_summary_records(&bare).map(|s| s.1).unwrap_or_default();
        assert!(!summary.iter().any(|r| matches!(r, Record::Channel(_))));
        let only = BTreeSet::from(["/only".to_string()]);
        assert_eq!(file_topics(&bare).unwrap(), only);
    }

    #[test]
    fn frames_apply_the_stamp_rule_per_kind() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("log.mcap");
        write_log(&path);
        let r = frames(
            &path,
            &[
                req("/tracks", TopicKind::Tracks),
                req("/missing", TopicKind::Tracks),
                req("/detections", TopicKind::Detections),
            ],
        )
        .unwrap();
        assert!(r.frames[1].is_none());
        let tracks = r.frames[0].as_ref().unwrap();
        let st: Vec<(u64, u64)> = tracks.iter().map(|f| (f.stamp, f.log_time)).collect();
        assert_eq!(
            st,
            [(7, 30), (40, 40)],
            "a tracks stamp of 0 is the log_time"
        );
        let dets = r.frames[2].as_ref().unwrap();
        let st: Vec<(u64, u64)> = dets.iter().map(|f| (f.stamp, f.log_time)).collect();
        assert_eq!(st, [(5, 10), (20, 20)], "no detections stamp: the log_time");
        assert!(matches!(&dets[0].boxes, Boxes::Detections(b) if b[0].label == "car"));
        assert_eq!(r.topics.len(), 2);
    }

    #[test]
    fn a_wrong_schema_names_file_topic_and_role() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("log.mcap");
        write_log(&path);
        let e = frames(&path, &[req("/detections", TopicKind::Tracks)]).unwrap_err();
        let text = format!("{e:#}");
        assert!(text.contains("log.mcap: topic /detections has schema 'probmot.Detections3D'"));
        assert!(text.contains("for the test"), "{text}");
    }

    #[test]
    fn for_each_frame_streams_in_file_order_and_stops_on_error() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("log.mcap");
        write_log(&path);
        let wanted = [
            req("/detections", TopicKind::Detections),
            req("/tracks", TopicKind::Tracks),
            req("/tracks", TopicKind::Tracks),
        ];
        let mut seen = Vec::new();
        let mut last_bytes = 0;
        for_each_frame(&path, &wanted, |e, stats| {
            assert!(stats.bytes_read >= last_bytes, "bytes read only grow");
            last_bytes = stats.bytes_read;
            seen.push(match e {
                FrameEvent::Channel(i) => (i, None),
                FrameEvent::Frame(i, f) => (i, Some(f.log_time)),
            });
            Ok(())
        })
        .unwrap();
        let frames: Vec<(usize, Option<u64>)> =
            seen.iter().copied().filter(|e| e.1.is_some()).collect();
        assert_eq!(
            frames,
            [
                (0, Some(10)),
                (0, Some(20)),
                (1, Some(30)),
                (2, Some(30)),
                (1, Some(40)),
                (2, Some(40))
            ],
            "a topic requested twice serves both requests"
        );
        let channels: BTreeSet<usize> =
            seen.iter().filter(|e| e.1.is_none()).map(|e| e.0).collect();
        assert_eq!(channels.into_iter().collect::<Vec<_>>(), [0, 1, 2]);
        let mut n = 0;
        let e = for_each_frame(&path, &wanted, |e, _| {
            if matches!(e, FrameEvent::Frame(..)) {
                n += 1;
                anyhow::bail!("enough");
            }
            Ok(())
        })
        .unwrap_err();
        assert_eq!(n, 1);
        assert!(format!("{e:#}").contains("enough"));
    }
}
