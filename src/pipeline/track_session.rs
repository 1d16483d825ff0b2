//! The tracking pass of `probmot track` as a session without I/O: the caller reads the input
//! and feeds its records in file order, the session copies them to a [`RecordSink`], decodes the
//! detection messages into [`DetectionFrame`]s, moves them into the fixed frame, tracks each
//! frame as soon as the [`Schedule`] says it is complete, and writes the tracks (and the extra
//! channels of [`ExtraOutputs`]). [`super::track::track_file`] is the file adapter around it.

use std::collections::{BTreeMap, HashMap, HashSet, VecDeque};
use std::ops::ControlFlow;

use anyhow::{bail, Context, Result};
use mcap::records::{MessageHeader, Record};

use super::detections::{convert, describe_unknown_labels, reject, InputCounters, Origin};
use super::ego::EgoMotion;
use super::frame_schedule::{Replan, Schedule};
use super::progress::Progress;
use super::track_options::{TrackOptions, TrackSummary};
use super::track_order::LogTimeOrder;
use super::track_outputs::ExtraOutputs;
use super::track_warnings::{period_mismatch, unused_entries, FrameIntervals};
use super::tracks_format::TracksFormat;
use crate::mcapio::sink::RecordSink;
use crate::msgs::detection_frame::{describe_skips, DetectionFrame};
use crate::msgs::detection_source::DetectionSource;
use crate::msgs::track_encode::{fill_track3d, rate_variances, RateVariances};
use crate::msgs::{ImageBox, Track3D, Tracks3D};
use crate::tracker::{Detection, Lookback, TrackReport, Tracker};

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

/// One decoded detection message waiting for its frame.
pub(super) struct Pending {
    pub(super) ordinal: u64,
    pub(super) log_time: u64,
    pub(super) topic_idx: usize,
    pub(super) msg: DetectionFrame,
}

/// The tracking pass without I/O: records of the input go in ([`TrackSession::on_record`]), the
/// records of the output go to the sink `S` (every input record copied, plus the tracks and the
/// extra channels, each frame as soon as it is complete), the summary comes out of
/// [`TrackSession::finish`], and progress goes to a callback.
pub struct TrackSession<'a, S: RecordSink> {
    pub(super) opts: &'a TrackOptions,
    pub(super) file: &'a str,
    /// Detection topics, indexed by [`Pending::topic_idx`].
    pub(super) topics: Vec<String>,
    /// Detection channels: how to decode them and the index of their topic.
    pub(super) det_channels: HashMap<u16, (DetectionSource, usize)>,
    /// `(schema id, channel id)` of the tracks channel.
    pub(super) ids: Option<(u16, u16)>,
    /// Message type of the tracks channel.
    pub(super) format: TracksFormat,
    pub(super) out: S,
    pub(super) extra: ExtraOutputs,
    pub(super) ego: EgoMotion,
    pub(super) tracker: Tracker,
    pub(super) counters: InputCounters,
    /// When each frame is complete.
    pub(super) schedule: Schedule,
    /// Per detection channel, the stamp of its last message.
    pub(super) last_stamp: HashMap<u16, u64>,
    /// Decoded detection messages by stamp, waiting for their frame to be complete.
    pub(super) pending: BTreeMap<u64, Vec<Pending>>,
    pub(super) next_frame: usize,
    /// Intervals between the tracked frames (for the frame-rate warning).
    pub(super) intervals: FrameIntervals,
    pub(super) frame_state: FrameState,
    /// Holds input messages until the tracks before them (in log time) are written.
    pub(super) order: LogTimeOrder,
    pub(super) summary: TrackSummary,
    pub(super) progress: &'a dyn Fn(Progress<'_>),
    /// Progress already made before this pass (bytes).
    pub(super) base: u64,
}

impl<S: RecordSink> TrackSession<'_, S> {
    /// Takes the next record of the input (in file order); `bytes_read` is how far the reader
    /// is, for the progress callback. A [`Replan`] says the single pass cannot go on: the
    /// caller restarts the output and tracks in two passes.
    pub fn on_record(&mut self, rec: Record<'_>, bytes_read: u64) -> Result<ControlFlow<Replan>> {
        let file = self.file;
        match rec {
            Record::Header(_) | Record::Footer(_) | Record::DataEnd(_) => {}
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
                    let topic = &self.topics[topic_idx];
                    let mut msg = source
                        .decode_frame(&data, header.log_time)
                        .with_context(|| undecodable(file, topic, &header, &source))?;
                    check_count(msg.len(), self.opts, file, topic, &header)?;
                    let stamp = msg.stamp;
                    if let replan @ ControlFlow::Break(_) =
                        self.schedule.on_message(header.channel_id, stamp)
                    {
                        return Ok(replan);
                    }
                    // (With two passes, the first has counted them.)
                    if self.schedule.is_streaming() {
                        let backwards = &mut self.summary.stamps_backwards;
                        note_stamp(&mut self.last_stamp, &header, stamp, topic, backwards);
                    }
                    self.ego
                        .to_fixed(&mut msg, || describe_message(file, topic, &header))?;
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
        if let Some(held) = &mut self.frame_state.held {
            held.lookback.finish();
            self.write_held()?;
        }
        self.order.release(&mut self.out)?;
        debug_assert!(self.order.is_empty(), "every held message is written");
        Ok(())
    }

    /// Tracks the complete frame at `stamp` and writes its outputs (with the offline options,
    /// those of the earlier frames that are now decided).
    fn track_frame(&mut self, stamp: u64, frames: Option<usize>) -> Result<()> {
        let mut msgs_of_frame = self.pending.remove(&stamp).expect("a pending frame");
        msgs_of_frame.sort_by_key(|p| p.ordinal);
        let latest = msgs_of_frame.iter().map(|p| p.log_time).max();
        let latest = latest.expect("a frame has a message");
        self.frame_state.run(
            stamp,
            latest,
            &mut msgs_of_frame,
            &mut self.tracker,
            &mut self.counters,
            self.opts.strict,
            self.file,
            &self.topics,
        )?;
        if self.frame_state.held.is_none() {
            self.write_tracks(latest)?;
        } else {
            self.write_held()?;
        }
        self.frame_state.finish(self.tracker.deleted());
        self.next_frame += 1;
        self.intervals.push(stamp);
        if self.next_frame.is_multiple_of(64) {
            let text = match frames {
                Some(n) => format!("tracking: frame {}/{n}", self.next_frame),
                None => format!("tracking: frame {}", self.next_frame),
            };
            (self.progress)(Progress::Message(&text));
        }
        Ok(())
    }

    /// Writes the frames the offline options have decided.
    fn write_held(&mut self) -> Result<()> {
        while let Some(latest) = self.frame_state.next_held(&self.tracker) {
            self.write_tracks(latest)?;
        }
        Ok(())
    }

    /// Writes the tracks in `frame_state.out` (the oldest frame not yet written) and the extra
    /// channels, at the log time of that frame (`latest`: of its last detection message).
    fn write_tracks(&mut self, latest: u64) -> Result<()> {
        let (_, channel_id) = self.ids.expect("ids exist with detections");
        let log_time = self.order.tracks_time(&mut self.out, latest)?;
        let state = &mut self.frame_state;
        self.format
            .encode_into(&state.out, &state.rates, &mut state.buf);
        let sequence = self.summary.tracks_messages as u32;
        self.out.write_to_known_channel(
            &MessageHeader {
                channel_id,
                sequence,
                log_time,
                publish_time: log_time,
            },
            &state.buf,
        )?;
        let ego = self.ego.take_ego(state.out.stamp);
        self.extra
            .write_frame(&mut self.out, &state.out, ego, sequence, log_time)?;
        self.summary.tracks_messages += 1;
        Ok(())
    }

    /// Fills in the summary and gives back the sink (to commit).
    pub fn finish(self) -> (S, TrackSummary) {
        let TrackSession {
            file,
            out,
            ego,
            tracker,
            counters,
            mut summary,
            frame_state,
            mut intervals,
            ..
        } = self;
        let st = tracker.stats();
        summary.frames = st.frames;
        summary.tracks_born = st.born;
        summary.tracks_confirmed = st.confirmed;
        summary.mean_track_length = match &frame_state.held {
            // Offline reporting: what was written (every shown track is confirmed).
            Some(h) => {
                (h.shown_boxes > 0).then(|| h.shown_boxes as f64 / h.shown_tracks.len() as f64)
            }
            None => tracker.mean_confirmed_track_length(),
        };
        summary.merged_messages = summary.detection_messages - summary.tracks_messages;
        if counters.total_skipped() > 0 {
            let mut warning = format!("{file}: skipped {}", describe_skips(&counters.skipped));
            if !counters.unknown_labels.is_empty() {
                let known: Vec<&str> = tracker
                    .config()
                    .classes
                    .keys()
                    .map(|k| k.as_str())
                    .collect();
                warning.push_str(&format!(
                    "; labels not in the config: {}; the config has entries for {} (add an \
                     entry for a label, or a \"default\" one, to track it: `probmot config`)",
                    describe_unknown_labels(&counters.unknown_labels),
                    known.join(", ")
                ));
            }
            summary.warnings.push(warning);
        }
        if let Some(w) = unused_entries(file, tracker.config(), &counters) {
            summary.warnings.push(w);
        }
        let mismatch = period_mismatch(file, tracker.config(), &mut intervals);
        summary.warnings.extend(mismatch);
        if counters.score_outside_unit > 0 {
            summary.warnings.push(format!(
                "{file}: {} detections have a score outside [0, 1]; they are tracked as given",
                counters.score_outside_unit
            ));
        }
        for (topic, n) in &summary.stamps_backwards {
            summary.warnings.push(format!(
                "{file}: topic {topic}: {n} messages have a stamp earlier than the message \
                 before them; frames were replayed in stamp order"
            ));
        }
        summary.detections = counters;
        summary.ego = ego.finish(file, &mut summary.warnings);
        (out, summary)
    }
}

/// Image box and attributes of a track's last matched detection.
#[derive(Default)]
struct Extra {
    image_box: Option<ImageBox>,
    attributes: BTreeMap<String, String>,
}

/// The side-table entry of report `r`'s track after this frame: a match moves its detection's
/// image box and attributes in (or clears the entry when the detection has none).
fn take_extra<'a>(
    last_extra: &'a mut HashMap<u64, Extra>,
    src: &[(u32, u32)],
    frame: &mut [Pending],
    r: &TrackReport,
) -> Option<&'a mut Extra> {
    if let Some(i) = r.detection {
        let (mi, di) = src[i as usize];
        let d = &mut frame[mi as usize].msg.boxes[di as usize];
        if d.image_box.is_some() || !d.attributes.is_empty() {
            let e = last_extra.entry(r.id).or_default();
            e.image_box = d.image_box;
            std::mem::swap(&mut e.attributes, &mut d.attributes);
        } else {
            last_extra.remove(&r.id);
        }
    }
    last_extra.get_mut(&r.id)
}

/// A report held by the offline options, with the extras its track had in its frame.
#[derive(Default)]
struct HeldTrack {
    report: TrackReport,
    image_box: Option<ImageBox>,
    attributes: BTreeMap<String, String>,
}

/// The frames held while the offline options (`backfill`, `coast: gaps`) decide their reports,
/// with each frame's latest detection log time and frame id. The attributes of a held report
/// are a copy (the only allocation per report, and only for detections that carry attributes).
#[derive(Default)]
pub(super) struct HeldFrames {
    lookback: Lookback<HeldTrack>,
    /// Per held frame, in order: latest detection log time and frame id.
    frames: VecDeque<(u64, String)>,
    /// Frame id strings of written frames, reused.
    spare_ids: Vec<String>,
    shown: Vec<HeldTrack>,
    /// Track boxes written, and the tracks they belong to (for the mean track length: the
    /// tracker counts frames the lookback may leave out).
    shown_boxes: u64,
    shown_tracks: HashSet<u64>,
}

/// Per-frame buffers reused across frames, and the attributes of each track's last matched
/// detection. Nothing is allocated per detection in steady state: the output message's tracks
/// are overwritten in place, and a track's attributes are moved (not copied) from its detection
/// into the side table and swapped into the message only while it is encoded.
#[derive(Default)]
pub(super) struct FrameState {
    dets: Vec<Detection>,
    /// `(message index within the frame, detection index within the message)` per detection.
    src: Vec<(u32, u32)>,
    last_extra: HashMap<u64, Extra>,
    out: Tracks3D,
    /// Velocity and yaw-rate variances of `out.tracks`, in the same order (written by the
    /// Autoware tracks format; `Track3D` has no field for them).
    rates: Vec<RateVariances>,
    buf: Vec<u8>,
    /// Present when a class reports offline (see [`crate::tracker::lookback`]).
    held: Option<HeldFrames>,
}

impl FrameState {
    /// The buffers for a run with `config`: frames are held when a class reports offline.
    pub(super) fn new(config: &crate::tracker::TrackerConfig) -> FrameState {
        FrameState {
            held: config.holds_frames().then(HeldFrames::default),
            ..FrameState::default()
        }
    }

    /// Tracks one frame and fills `self.out`. Call [`FrameState::finish`] after encoding it.
    #[allow(clippy::too_many_arguments)]
    fn run(
        &mut self,
        stamp: u64,
        latest: u64,
        frame: &mut [Pending],
        tracker: &mut Tracker,
        counters: &mut InputCounters,
        strict: bool,
        file: &str,
        topics: &[String],
    ) -> Result<()> {
        self.dets.clear();
        self.src.clear();
        for (mi, p) in frame.iter().enumerate() {
            let origin = Origin {
                file,
                topic: &topics[p.topic_idx],
                log_time: p.log_time,
            };
            // Valid and rejected boxes in message order, as a --strict error names the first.
            let mut rejected = p.msg.rejected.iter().peekable();
            for (di, d) in p.msg.boxes.iter().enumerate() {
                while let Some(r) = rejected.next_if(|r| r.index < d.index) {
                    reject(r, counters, strict, &origin)?;
                }
                if let Some(det) = convert(d, tracker, counters, strict, &origin)? {
                    self.dets.push(det);
                    self.src.push((mi as u32, di as u32));
                }
            }
            for r in rejected {
                reject(r, counters, strict, &origin)?;
            }
        }
        tracker
            .step(stamp, &self.dets)
            .with_context(|| format!("{file}: frame at stamp {stamp}"))?;
        let reports = tracker.reports();
        self.out.stamp = stamp;
        self.out.frame_id.clear();
        if let Some(p) = frame.first() {
            self.out.frame_id.push_str(&p.msg.frame_id);
        }
        if let Some(held) = &mut self.held {
            // Offline options: the reports wait in the lookback with a copy of their extras.
            let mut fill = |v: &mut HeldTrack, r: &TrackReport| {
                v.report = *r;
                match take_extra(&mut self.last_extra, &self.src, frame, r) {
                    Some(e) => {
                        v.image_box = e.image_box;
                        v.attributes.clone_from(&e.attributes);
                    }
                    None => {
                        v.image_box = None;
                        v.attributes.clear();
                    }
                }
            };
            held.lookback.push(stamp, reports, &mut fill);
            let mut frame_id = held.spare_ids.pop().unwrap_or_default();
            frame_id.clone_from(&self.out.frame_id);
            held.frames.push_back((latest, frame_id));
            return Ok(());
        }
        self.out.tracks.resize_with(reports.len(), Track3D::default);
        self.rates.clear();
        self.rates.extend(reports.iter().map(rate_variances));
        for (t, r) in self.out.tracks.iter_mut().zip(reports) {
            let extra = take_extra(&mut self.last_extra, &self.src, frame, r);
            fill_track3d(t, r, tracker.label(r.class));
            match extra {
                Some(e) => {
                    t.image_box = e.image_box;
                    std::mem::swap(&mut t.attributes, &mut e.attributes);
                }
                None => {
                    t.image_box = None;
                    t.attributes.clear();
                }
            }
        }
        Ok(())
    }

    /// With the offline options: the next frame whose reports are all decided, in
    /// `self.out` (its tracks own their attributes; [`FrameState::finish`] is not needed), and
    /// the latest log time of its detection messages.
    fn next_held(&mut self, tracker: &Tracker) -> Option<u64> {
        let held = self.held.as_mut()?;
        let stamp = held.lookback.pop_into(&mut held.shown)?;
        let (latest, frame_id) = held.frames.pop_front().expect("a held frame's own data");
        self.out.stamp = stamp;
        held.spare_ids
            .push(std::mem::replace(&mut self.out.frame_id, frame_id));
        self.out
            .tracks
            .resize_with(held.shown.len(), Track3D::default);
        held.shown_boxes += held.shown.len() as u64;
        held.shown_tracks
            .extend(held.shown.iter().map(|v| v.report.id));
        self.rates.clear();
        (self.rates).extend(held.shown.iter().map(|v| rate_variances(&v.report)));
        for (t, v) in self.out.tracks.iter_mut().zip(&mut held.shown) {
            fill_track3d(t, &v.report, tracker.label(v.report.class));
            t.image_box = v.image_box;
            std::mem::swap(&mut t.attributes, &mut v.attributes);
        }
        Some(latest)
    }

    /// Gives the attributes lent to the encoded message back to the side table and forgets the
    /// tracks deleted in this frame.
    fn finish(&mut self, deleted: &[u64]) {
        // Held frames copied their attributes: nothing was lent.
        let lent = if self.held.is_none() {
            &mut self.out.tracks[..]
        } else {
            &mut []
        };
        for t in lent {
            if let Some(e) = self.last_extra.get_mut(&t.id) {
                std::mem::swap(&mut t.attributes, &mut e.attributes);
            }
        }
        for id in deleted {
            self.last_extra.remove(id);
        }
    }
}

#[cfg(test)]
mod tests {
    use std::borrow::Cow;

    use mcap::records::{Channel, SchemaHeader};
    use prost::Message as _;

    use super::*;

    use crate::mcapio::sink::{MemorySink, SinkRecord};
    use crate::msgs::{self, v3, Detection3D, Detections3D, Encoding, Size3};
    use crate::pipeline::ego::EgoOptions;
    use crate::pipeline::progress::no_progress;
    use crate::pipeline::track_options::SceneOutput;
    use crate::pipeline::track_outputs::ExtraRequest;
    use crate::tracker::TrackerConfig;
    use crate::transforms::TransformCollector;

    /// A detection message: a car at `x` (when given, with the attribute `frame` = `frame`) and
    /// a box without a size.
    fn detections(stamp: u64, car: Option<(f64, usize)>) -> Vec<u8> {
        let mut detections = Vec::new();
        if let Some((x, frame)) = car {
            detections.push(Detection3D {
                center: Some(v3([x, 0.0, 0.0])),
                size: Some(Size3 {
                    length: 4.0,
                    width: 2.0,
                    height: 1.5,
                }),
                label: "car".into(),
                score: 0.9,
                attributes: [("frame".to_string(), frame.to_string())].into(),
                ..Default::default()
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
        let mut session = TrackSession {
            opts: &opts,
            file: "memory",
            topics: vec!["/detections".into()],
            det_channels: HashMap::from([(1, (DetectionSource::Probmot(Encoding::Protobuf), 0))]),
            ids: Some((9, 9)),
            format: TracksFormat::Probmot,
            out: MemorySink::default(),
            extra: ExtraOutputs::new(&request, "memory", None, None).unwrap(),
            ego: EgoMotion::new(TransformCollector::new(), &opts.ego, false).unwrap(),
            tracker: Tracker::new(opts.config.clone()).unwrap(),
            counters: InputCounters::default(),
            schedule: Schedule::Known(stamps.iter().map(|&s| (s, 1)).collect()),
            last_stamp: HashMap::new(),
            pending: BTreeMap::new(),
            next_frame: 0,
            intervals: FrameIntervals::default(),
            frame_state: FrameState::new(&opts.config),
            order: LogTimeOrder::default(),
            summary: TrackSummary::default(),
            progress: &no_progress,
            base: 0,
        };
        let schema = Record::Schema {
            header: SchemaHeader {
                id: 1,
                name: msgs::DETECTIONS_SCHEMA.into(),
                encoding: "protobuf".into(),
            },
            data: Cow::Borrowed(msgs::DESCRIPTOR_SET),
        };
        session.on_record(schema, 0).unwrap();
        let channel = Channel {
            id: 1,
            schema_id: 1,
            topic: "/detections".into(),
            message_encoding: "protobuf".into(),
            metadata: BTreeMap::new(),
        };
        session.on_record(Record::Channel(channel), 0).unwrap();
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
            session.on_record(rec, 0).unwrap();
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
