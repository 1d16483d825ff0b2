//! The MCAP adapter of a [`TrackSession`], what `probmot track` runs: the caller reads the
//! input and feeds its records in file order; the adapter copies them to a [`RecordSink`],
//! decodes the detection messages into [`DetectionFrame`](crate::msgs::detection_frame::DetectionFrame)s,
//! moves them into the fixed frame, has the session track each frame as soon as the
//! [`Schedule`] says it is complete, and writes the tracks (and the extra channels of
//! [`ExtraOutputs`]). [`super::track::track_input`] is the reading around it.

use std::collections::{BTreeMap, HashMap};
use std::ops::ControlFlow;

use anyhow::{bail, Context, Result};
use mcap::records::{MessageHeader, Record};

use super::ego::EgoMotion;
use super::frame_schedule::{Replan, Schedule};
use super::progress::Progress;
use super::stamp_check::StampCheck;
use super::track_frames::Pending;
use super::track_options::{TrackOptions, TrackSummary};
use super::track_order::LogTimeOrder;
use super::track_outputs::ExtraOutputs;
use super::track_session::TrackSession;
use super::tracks_format::TracksFormat;
use crate::mcapio::sink::RecordSink;
use crate::msgs::detection_reader::FrameReader;
use crate::msgs::detection_source::DetectionSource;

/// The error of a detection message that does not decode.
pub(super) fn undecodable(
    file: &str,
    topic: &str,
    h: &MessageHeader,
    source: &DetectionSource,
) -> String {
    format!(
        "{}: cannot decode {}",
        describe_message(file, topic, h),
        source.describe()
    )
}

/// Refuses a detection message with more boxes than `--max-detections`.
pub(super) fn check_count(
    count: usize,
    opts: &TrackOptions,
    file: &str,
    topic: &str,
    h: &MessageHeader,
) -> Result<()> {
    if count > opts.max_detections_per_message {
        bail!(
            "{}: {count} detections in one message, more than the limit of {} (--max-detections)",
            describe_message(file, topic, h),
            opts.max_detections_per_message
        );
    }
    Ok(())
}

/// Counts, per topic, a stamp earlier than the previous one on the same channel.
pub(super) fn note_stamp(
    last: &mut HashMap<u16, u64>,
    h: &MessageHeader,
    stamp: u64,
    topic: &str,
    backwards: &mut BTreeMap<String, u64>,
) {
    if last
        .insert(h.channel_id, stamp)
        .is_some_and(|prev| stamp < prev)
    {
        *backwards.entry(topic.to_string()).or_default() += 1;
    }
}

/// `FILE: topic T, message at log_time L (sequence S)`, for errors.
pub(super) fn describe_message(file: &str, topic: &str, h: &MessageHeader) -> String {
    format!(
        "{file}: topic {topic}, message at log_time {} (sequence {})",
        h.log_time, h.sequence
    )
}

/// The tracking pass without I/O: records of the input go in ([`RecordSession::on_record`]),
/// the records of the output go to the sink `S` (every input record copied, plus the tracks and
/// the extra channels, each frame as soon as it is complete), the summary comes out of
/// [`RecordSession::finish`], and progress goes to a callback.
pub(super) struct RecordSession<'a, S: RecordSink> {
    pub(super) opts: &'a TrackOptions,
    pub(super) file: &'a str,
    /// Detection channels: how to decode them and the index of their topic.
    pub(super) det_channels: HashMap<u16, (DetectionSource, usize)>,
    /// `(schema id, channel id)` of the tracks channel.
    pub(super) ids: Option<(u16, u16)>,
    /// Message type of the tracks channel.
    pub(super) format: TracksFormat,
    pub(super) out: S,
    pub(super) extra: ExtraOutputs,
    pub(super) ego: EgoMotion,
    /// The tracking of complete frames.
    pub(super) session: TrackSession,
    /// When each frame is complete.
    pub(super) schedule: Schedule,
    /// Per detection channel, the stamp of its last message.
    pub(super) last_stamp: HashMap<u16, u64>,
    /// Stamps far outside the log's range, and stamps shared on a channel.
    pub(super) stamps: StampCheck,
    /// Decoded detection messages by stamp, waiting for their frame to be complete.
    pub(super) pending: BTreeMap<u64, Vec<Pending>>,
    pub(super) next_frame: usize,
    /// Holds input messages until the tracks before them (in log time) are written.
    pub(super) order: LogTimeOrder,
    pub(super) summary: TrackSummary,
    pub(super) progress: &'a dyn Fn(Progress<'_>),
    /// Progress already made before this pass (bytes).
    pub(super) base: u64,
    /// Header records met: each after the first starts the next file of a split bag.
    pub(super) headers: u32,
    /// Decodes the detection messages, reusing the frames already tracked.
    pub(super) reader: FrameReader,
}

impl<S: RecordSink> RecordSession<'_, S> {
    /// Takes the next record of the input (in file order); `bytes_read` is how far the reader
    /// is, for the progress callback. A [`Replan`] says the single pass cannot go on: the
    /// caller restarts the output and tracks in two passes.
    pub fn on_record(&mut self, rec: Record<'_>, bytes_read: u64) -> Result<ControlFlow<Replan>> {
        let file = self.file;
        match rec {
            Record::Header(_) => {
                self.headers += 1;
                if self.headers > 1 {
                    self.next_part()?;
                }
            }
            Record::Footer(_) | Record::DataEnd(_) => {}
            Record::Schema { header, data } if header.id != 0 => {
                if let replan @ ControlFlow::Break(_) = self.schedule.on_schema(header.id) {
                    return Ok(replan);
                }
                self.out
                    .add_schema_with_id(header.id, &header.name, &header.encoding, &data)
                    .with_context(|| format!("{file}: copying schema {}", header.id))?;
            }
            Record::Channel(c) => {
                if let replan @ ControlFlow::Break(_) =
                    self.schedule.on_channel(c.id, &c.topic, c.schema_id)
                {
                    return Ok(replan);
                }
                self.out
                    .add_channel_with_id(
                        c.id,
                        c.schema_id,
                        &c.topic,
                        &c.message_encoding,
                        &c.metadata,
                    )
                    .with_context(|| format!("{file}: copying channel {} ({})", c.id, c.topic))?;
            }
            Record::Message { header, data } => {
                self.order
                    .copy(&mut self.out, &header, &data)
                    .with_context(|| {
                        format!(
                            "{file}: copying message at log_time {} on channel {}",
                            header.log_time, header.channel_id
                        )
                    })?;
                self.summary.messages_copied += 1;
                if let Some(&(source, topic_idx)) = self.det_channels.get(&header.channel_id) {
                    let step = self.on_detection(&header, &data, source, topic_idx)?;
                    if let replan @ ControlFlow::Break(_) = step {
                        return Ok(replan);
                    }
                }
                if self.summary.messages_copied.is_multiple_of(256) {
                    (self.progress)(Progress::Position(self.base + bytes_read));
                }
            }
            Record::Attachment { header, data, .. } => {
                self.out
                    .attach(&mcap::Attachment {
                        log_time: header.log_time,
                        create_time: header.create_time,
                        name: header.name,
                        media_type: header.media_type,
                        data,
                    })
                    .with_context(|| format!("{file}: copying an attachment"))?;
                self.summary.attachments += 1;
            }
            Record::Metadata(m) => {
                self.out
                    .write_metadata(&m)
                    .with_context(|| format!("{file}: copying metadata {}", m.name))?;
                self.summary.metadata += 1;
            }
            _ => {}
        }
        Ok(ControlFlow::Continue(()))
    }

    /// Adds the tracks channel and the extra channels when there are detections.
    pub(super) fn add_tracks_channels(&mut self) -> Result<()> {
        let Some((schema_id, channel_id)) = self.ids else {
            return Ok(());
        };
        let (name, schema_encoding, data, message_encoding) = self.format.schema();
        let topic = self.opts.tracks_topic_for(self.format);
        let out = &mut self.out;
        out.add_schema_with_id(schema_id, name, schema_encoding, data)?;
        let metadata = self.format.channel_metadata();
        out.add_channel_with_id(channel_id, schema_id, topic, message_encoding, &metadata)?;
        self.extra.add_channels(out, schema_id)
    }

    /// The next file of a split bag starts: every held input message goes to the file it came
    /// from (before tracks still to come, which go to the next file), and the next output file
    /// gets the tracks channels.
    fn next_part(&mut self) -> Result<()> {
        self.order.flush_all(&mut self.out)?;
        self.out
            .next_part()
            .with_context(|| format!("{}: starting output file {}", self.file, self.headers))?;
        self.add_tracks_channels()
    }

    /// A detection message of `source` on the topic `topic_idx`: decoded, checked, moved into
    /// the fixed frame and held until its frame is complete; the frames it completes are tracked.
    fn on_detection(
        &mut self,
        header: &MessageHeader,
        data: &[u8],
        source: DetectionSource,
        topic_idx: usize,
    ) -> Result<ControlFlow<Replan>> {
        let file = self.file;
        let topic = &self.session.topics[topic_idx];
        let mut msg = (self.reader)
            .read(&source, data, header.log_time)
            .with_context(|| undecodable(file, topic, header, &source))?;
        check_count(msg.len(), self.opts, file, topic, header)?;
        let name = || describe_message(file, topic, header);
        let (id, strict) = (header.channel_id, self.opts.strict);
        match (self.stamps).keep(id, msg.stamp, header.log_time, strict, name)? {
            ControlFlow::Continue(true) => {}
            ControlFlow::Continue(false) => return Ok(ControlFlow::Continue(())),
            ControlFlow::Break(replan) => return Ok(ControlFlow::Break(replan)),
        }
        let stamp = msg.stamp;
        if let replan @ ControlFlow::Break(_) = self.schedule.on_message(header.channel_id, stamp) {
            return Ok(replan);
        }
        // (With two passes, the first has counted them.)
        if self.schedule.is_streaming() {
            let backwards = &mut self.summary.stamps_backwards;
            note_stamp(&mut self.last_stamp, header, stamp, topic, backwards);
        }
        self.ego
            .to_fixed(&mut msg, || describe_message(file, topic, header))?;
        let frame = self.pending.entry(stamp).or_default();
        let old = frame.iter().map(|p| p.log_time).max();
        let new = old.map_or(header.log_time, |t| t.max(header.log_time));
        frame.push(Pending {
            ordinal: self.summary.detection_messages,
            log_time: header.log_time,
            topic_idx,
            msg,
        });
        self.order.frame_time(old, new);
        self.summary.detection_messages += 1;
        while let Some(stamp) = self.schedule.ready(&self.pending, self.next_frame) {
            self.track_frame(stamp, self.schedule.frames())?;
            self.schedule.tracked(stamp);
        }
        self.order.release(&mut self.out)?;
        Ok(ControlFlow::Continue(()))
    }

    /// Called after the last record: tracks the frames still pending (streaming), or checks
    /// that every planned frame was seen.
    pub fn end_of_input(&mut self) -> Result<()> {
        let file = self.file;
        match &self.schedule {
            Schedule::Known(frames) if self.next_frame != frames.len() => bail!(
                "{file}: the file changed while it was read ({} of {} frames seen)",
                self.next_frame,
                frames.len()
            ),
            Schedule::Known(_) => {}
            // Every channel has delivered all it has: the frames left are complete.
            Schedule::Streaming(_) => {
                while let Some((&stamp, _)) = self.pending.first_key_value() {
                    self.track_frame(stamp, None)?;
                }
            }
        }
        // The offline options' undecided reports are not shown: every held frame is written.
        self.session.end();
        self.write_ready()?;
        self.order.release(&mut self.out)?;
        debug_assert!(self.order.is_empty(), "every held message is written");
        Ok(())
    }

    /// Tracks the complete frame at `stamp` and writes its outputs (with the offline options,
    /// those of the earlier frames that are now decided).
    fn track_frame(&mut self, stamp: u64, frames: Option<usize>) -> Result<()> {
        let mut msgs_of_frame = self.pending.remove(&stamp).expect("a pending frame");
        msgs_of_frame.sort_by_key(|p| p.ordinal);
        self.session.track_messages(&mut msgs_of_frame)?;
        for p in msgs_of_frame {
            self.reader.recycle(p.msg);
        }
        self.write_ready()?;
        self.next_frame += 1;
        if self.next_frame.is_multiple_of(64) {
            let text = match frames {
                Some(n) => format!("tracking: frame {}/{n}", self.next_frame),
                None => format!("tracking: frame {}", self.next_frame),
            };
            (self.progress)(Progress::Message(&text));
        }
        Ok(())
    }

    /// Writes the frames the session has ready.
    fn write_ready(&mut self) -> Result<()> {
        while let Some(latest) = self.session.next_ready() {
            self.write_tracks(latest)?;
        }
        Ok(())
    }

    /// Writes the tracks in `frame_state.out` (the oldest frame not yet written) and the extra
    /// channels, at the log time of that frame (`latest`: of its last detection message).
    fn write_tracks(&mut self, latest: u64) -> Result<()> {
        let (_, channel_id) = self.ids.expect("ids exist with detections");
        let log_time = self.order.tracks_time(&mut self.out, latest)?;
        let state = &mut self.session.frame_state;
        let sequence = self.summary.tracks_messages as u32;
        let header = MessageHeader {
            channel_id,
            sequence,
            log_time,
            publish_time: log_time,
        };
        (self.format).write(
            &mut self.out,
            &header,
            &state.out,
            &state.rates,
            &mut state.buf,
        )?;
        let ego = self.ego.take_ego(state.out.stamp);
        self.extra
            .write_frame(&mut self.out, &state.out, ego, sequence, log_time)?;
        self.summary.tracks_messages += 1;
        Ok(())
    }

    /// Fills in the summary and gives back the sink (to commit).
    pub fn finish(self) -> (S, TrackSummary) {
        let RecordSession {
            file,
            out,
            ego,
            session,
            mut summary,
            stamps,
            ..
        } = self;
        let s = session.finish();
        summary.frames = s.frames;
        summary.tracks_born = s.tracks_born;
        summary.tracks_confirmed = s.tracks_confirmed;
        summary.mean_track_length = s.mean_track_length;
        summary.merged_messages = summary.detection_messages - summary.tracks_messages;
        summary.warnings.extend(s.warnings);
        for (topic, n) in &summary.stamps_backwards {
            summary.warnings.push(format!(
                "{file}: topic {topic}: {n} messages have a stamp earlier than the message \
                 before them; frames were replayed in stamp order"
            ));
        }
        stamps.warnings(file, &mut summary.warnings);
        summary.detections = s.detections;
        summary.ego = ego.finish(file, &mut summary.warnings);
        (out, summary)
    }
}

#[cfg(test)]
mod tests {
    use std::borrow::Cow;

    use mcap::records::{Channel, SchemaHeader};
    use prost::Message as _;

    use super::*;

    use crate::mcapio::sink::{MemorySink, SinkRecord};
    use crate::msgs::Tracks3D;
    use crate::msgs::{self, test_box, v3, Detection3D, Detections3D, Encoding};
    use crate::pipeline::ego::EgoOptions;
    use crate::pipeline::progress::no_progress;
    use crate::pipeline::track_options::SceneOutput;
    use crate::pipeline::track_outputs::ExtraRequest;
    use crate::pipeline::track_session::SessionOptions;
    use crate::tracker::TrackerConfig;
    use crate::transforms::TransformCollector;

    /// A detection message: a car at `x` (when given, with the attribute `frame` = `frame`) and
    /// a box without a size.
    fn detections(stamp: u64, car: Option<(f64, usize)>) -> Vec<u8> {
        let mut detections = Vec::new();
        if let Some((x, frame)) = car {
            detections.push(Detection3D {
                attributes: [("frame".to_string(), frame.to_string())].into(),
                ..test_box("car", x)
            });
        }
        // No size: rejected when decoded, counted when its frame is tracked.
        detections.push(Detection3D {
            center: Some(v3([50.0, 0.0, 0.0])),
            label: "car".into(),
            ..Default::default()
        });
        let m = Detections3D {
            stamp: Some(stamp),
            frame_id: "map".into(),
            detections,
        };
        m.encode_to_vec()
    }

    /// Feeds one detection message per frame (stamps 100, 200, ...; `cars[i]`: the car's x in
    /// frame i, if seen) as records to a session with `config`, with no file anywhere. Returns
    /// the sink, the tracks messages with their log times, and the summary.
    fn run_session(
        config: TrackerConfig,
        cars: &[Option<f64>],
    ) -> (MemorySink, Vec<(u64, Tracks3D)>, TrackSummary) {
        let opts = TrackOptions {
            detection_topics: vec![],
            tracks_topic: None,
            tracks_format: None,
            config,
            no_track: false,
            strict: false,
            max_detections_per_message: 10,
            ego: EgoOptions::default(),
            scene: SceneOutput::Off,
            compression: Default::default(),
            background_writer: false,
        };
        let request = ExtraRequest {
            tracks_topic: "/tracks",
            tracks_in_ego_frame: false,
            scene_topic: None,
        };
        let stamps: Vec<u64> = (1..=cars.len() as u64).map(|i| 100 * i).collect();
        let options = SessionOptions {
            name: "memory".into(),
            strict: false,
        };
        let mut tracking = TrackSession::new(opts.config.clone(), options).unwrap();
        tracking.topics = vec!["/detections".into()];
        let mut session = RecordSession {
            opts: &opts,
            file: "memory",
            det_channels: HashMap::from([(1, (DetectionSource::Probmot(Encoding::Protobuf), 0))]),
            ids: Some((9, 9)),
            format: TracksFormat::Probmot,
            out: MemorySink::default(),
            extra: ExtraOutputs::new(&request, "memory", None, None).unwrap(),
            ego: EgoMotion::new(TransformCollector::new(), &opts.ego, false).unwrap(),
            session: tracking,
            schedule: Schedule::Known(stamps.iter().map(|&s| (s, 1)).collect()),
            last_stamp: HashMap::new(),
            stamps: Default::default(),
            pending: BTreeMap::new(),
            next_frame: 0,
            order: LogTimeOrder::default(),
            summary: TrackSummary::default(),
            progress: &no_progress,
            base: 0,
            headers: 0,
            reader: FrameReader::default(),
        };
        let schema = Record::Schema {
            header: SchemaHeader {
                id: 1,
                name: msgs::DETECTIONS_SCHEMA.into(),
                encoding: "protobuf".into(),
            },
            data: Cow::Borrowed(msgs::DESCRIPTOR_SET),
        };
        assert!(session.on_record(schema, 0).unwrap().is_continue());
        let channel = Channel {
            id: 1,
            schema_id: 1,
            topic: "/detections".into(),
            message_encoding: "protobuf".into(),
            metadata: BTreeMap::new(),
        };
        assert!(session
            .on_record(Record::Channel(channel), 0)
            .unwrap()
            .is_continue());
        for (i, (&stamp, car)) in stamps.iter().zip(cars).enumerate() {
            let header = MessageHeader {
                channel_id: 1,
                sequence: i as u32,
                log_time: stamp + 1,
                publish_time: stamp + 1,
            };
            let data = detections(stamp, car.map(|x| (x, i)));
            let rec = Record::Message {
                header,
                data: Cow::Owned(data),
            };
            assert!(session.on_record(rec, 0).unwrap().is_continue());
        }
        session.end_of_input().unwrap();
        let (sink, summary) = session.finish();
        let tracks: Vec<(u64, Tracks3D)> = sink
            .records
            .iter()
            .filter_map(|r| match r {
                SinkRecord::Message(h, d) if h.channel_id == 9 => {
                    Some((h.log_time, Tracks3D::decode(d.as_slice()).unwrap()))
                }
                _ => None,
            })
            .collect();
        (sink, tracks, summary)
    }

    /// Two frames of one car: every record is copied to the sink, a tracks message follows each
    /// frame, and the summary counts what happened.
    #[test]
    fn a_session_copies_records_and_writes_a_tracks_message_per_frame() {
        let config = TrackerConfig::preset("nuscenes-chiu2019").unwrap();
        let (sink, tracks, summary) = run_session(config, &[Some(0.0), Some(1.0)]);
        let stamps: Vec<u64> = tracks.iter().map(|(t, m)| (*t).min(m.stamp)).collect();
        assert_eq!(
            stamps,
            [100, 200],
            "one tracks message per frame, at its stamp"
        );
        assert!(matches!(sink.records[0], SinkRecord::Schema(1, _, _)));
        assert!(matches!(sink.records[1], SinkRecord::Channel(1, 1, _)));
        assert_eq!(summary.messages_copied, 2);
        assert_eq!(summary.detection_messages, 2);
        assert_eq!(summary.tracks_messages, 2);
        assert_eq!(summary.tracks_born, 1, "the car is one track");
        assert_eq!(summary.detections.per_label["car"], 2);
        assert_eq!(
            summary.detections.total_skipped(),
            2,
            "the boxes without size"
        );
    }

    /// With backfill, the frames written late show the car from its first detection, each with
    /// the attributes of that frame's detection; one tracks message per frame, in order.
    #[test]
    fn held_frames_carry_the_attributes_of_their_own_frame() {
        // Four frames without the car (past the first min_hits frames), then four with it.
        let cars: Vec<Option<f64>> = (0..8).map(|i| (i >= 4).then_some(0.3 * i as f64)).collect();
        let shown = |backfill: bool| {
            let mut config = TrackerConfig::preset("nuscenes-chiu2019").unwrap();
            config.for_each_class(|c| c.levers.backfill = backfill);
            let (_, tracks, summary) = run_session(config, &cars);
            assert_eq!(summary.tracks_messages, 8);
            let stamps: Vec<u64> = tracks.iter().map(|(_, m)| m.stamp).collect();
            assert_eq!(stamps, (1..=8).map(|i| 100 * i).collect::<Vec<u64>>());
            let frames: Vec<Vec<String>> = tracks
                .iter()
                .map(|(_, m)| {
                    m.tracks
                        .iter()
                        .map(|t| t.attributes["frame"].clone())
                        .collect()
                })
                .collect();
            frames
        };
        let none: Vec<String> = vec![];
        let one = |i: usize| vec![i.to_string()];
        assert_eq!(shown(false)[4..], [none.clone(), none, one(6), one(7)]);
        assert_eq!(shown(true)[4..], [one(4), one(5), one(6), one(7)]);
    }
}
