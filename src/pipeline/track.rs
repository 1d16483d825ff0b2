//! `probmot track`: read an MCAP recording, replay its detections in stamp order through the
//! tracker, and write every input record plus a tracks channel to a new MCAP file.
//!
//! One or two streaming passes over the input (see [`track_file`] and
//! [`super::frame_schedule`]). With two, the first decodes only the detection messages to learn
//! the frame stamps (16 bytes kept per detection message). The tracking pass copies every record
//! to the output in file order and runs the tracker as soon as the next frame (in stamp order)
//! is complete; messages that arrive early wait in a small reorder buffer. Memory is bounded by
//! the live tracks, one chunk of the input and output, and the out-of-orderness of the file,
//! not by its length.
//!
//! The output is written through [`BackgroundOutput`]: with [`TrackOptions::background_writer`]
//! its chunks are compressed on other threads while this one reads and tracks.

use std::collections::{BTreeMap, HashMap, HashSet};
use std::path::Path;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use mcap::records::{MessageHeader, Record};

use super::detections::{convert, reject, InputCounters, Origin};
use super::ego::{EgoMotion, EgoOptions, EgoSummary};
use super::frame_schedule::{NeedsTwoPasses, Schedule, Streaming};
use super::progress::Progress;
use super::track_outputs::{ExtraOutputs, ExtraRequest};
use super::tracks_format::TracksFormat;
use crate::mcapio::background::BackgroundOutput;
use crate::mcapio::reader::{read_records, read_summary_records};
use crate::mcapio::writer::{check_output_path, OutputCompression, OutputOptions};
use crate::msgs::detection_frame::{stamp_or_log_time, DetectionFrame};
use crate::msgs::detection_source::{self, DetectionSource};
pub use crate::msgs::track_encode::{fill_track3d, to_track3d};
use crate::msgs::{self, ImageBox, Track3D, Tracks3D};
use crate::tracker::{Detection, Tracker, TrackerConfig};
use crate::transforms::TransformCollector;

/// Settings of one `track` run.
#[derive(Debug, Clone)]
pub struct TrackOptions {
    /// Detection topics; empty: every channel of a supported detection schema
    /// ([`detection_source::is_detection_schema`]).
    pub detection_topics: Vec<String>,
    /// Topic of the tracks channel written.
    pub tracks_topic: String,
    /// Message type of the tracks channel; `None`: by input ([`TracksFormat::resolve`]).
    pub tracks_format: Option<TracksFormat>,
    /// Tracker configuration.
    pub config: TrackerConfig,
    /// Copy only, no tracking (for measuring the cost of I/O).
    pub no_track: bool,
    /// Turn every skipped box into an error.
    pub strict: bool,
    /// Largest number of boxes accepted in one detection message; more is an error (a frame
    /// that large is a corrupted or misrouted message, and would stall the tracker).
    pub max_detections_per_message: usize,
    /// Ego motion: the fixed frame and the `--tracks-frame ego` output (see [`super::ego`]).
    pub ego: EgoOptions,
    /// Topic of the `foxglove.SceneUpdate` output channel, if any.
    pub scene_topic: Option<String>,
    /// Chunk compression of the output.
    pub compression: OutputCompression,
    /// Write and compress the output on a thread of its own ([`BackgroundOutput`]), so that it
    /// overlaps with reading and tracking: faster for one file when a core is spare; when files
    /// already run in parallel on every core, writing on the file's own thread costs less.
    pub background_writer: bool,
}

/// Default of [`TrackOptions::max_detections_per_message`].
pub const DEFAULT_MAX_DETECTIONS: usize = 100_000;

/// What a run did; printed as the summary line or as JSON.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct TrackSummary {
    /// Input path.
    pub input: String,
    /// Output path.
    pub output: String,
    /// Detection topics used.
    pub detection_topics: Vec<String>,
    /// Frames (distinct detection stamps) tracked.
    pub frames: u64,
    /// Detection messages read.
    pub detection_messages: u64,
    /// Detections given to the tracker, per label, and the skipped ones by reason.
    pub detections: InputCounters,
    /// Tracks started.
    pub tracks_born: u64,
    /// Tracks that reached `min_hits`.
    pub tracks_confirmed: u64,
    /// Mean number of reported frames per confirmed track.
    pub mean_track_length: Option<f64>,
    /// Input messages copied.
    pub messages_copied: u64,
    /// Attachments copied.
    pub attachments: u64,
    /// Metadata records copied.
    pub metadata: u64,
    /// Tracks messages written.
    pub tracks_messages: u64,
    /// Per detection topic, messages whose stamp is earlier than the previous message's.
    pub stamps_backwards: BTreeMap<String, u64>,
    /// Detection messages that sharing a stamp with a message of another topic were merged.
    pub merged_messages: u64,
    /// Ego-motion compensation: fixed frame, transforms, messages moved or skipped.
    pub ego: EgoSummary,
    /// Warnings for the user.
    pub warnings: Vec<String>,
    /// Passes over the input: 1 (the summary section sufficed, or `--no-track`) or 2 (a first
    /// pass learned the frames); see [`track_file`].
    pub passes: u8,
    /// Wall time in seconds.
    pub wall_time_s: f64,
}

/// Result of the first pass.
#[derive(Default)]
struct Scan {
    profile: String,
    schema_ids: HashSet<u16>,
    /// `(name, encoding, data)` of every schema.
    schemas: HashMap<u16, (String, String, Vec<u8>)>,
    channel_ids: HashSet<u16>,
    det_channels: HashMap<u16, (DetectionSource, String)>,
    /// `(stamp, ordinal)` of every detection message.
    entries: Vec<(u64, u64)>,
    stamps_backwards: BTreeMap<String, u64>,
    topics: HashSet<String>,
    /// Channels of a detection schema left out of the default selection, with the reason.
    unreadable: BTreeMap<u16, String>,
    /// Readable detection channels left out of the default selection (SceneUpdates beside other
    /// detection channels), as warnings.
    left_out: Vec<String>,
    /// Channel of each entry of `entries`.
    entry_channels: Vec<u16>,
    transforms: TransformCollector,
}

/// The error of a detection message that does not decode.
fn undecodable(file: &str, topic: &str, h: &MessageHeader, source: &DetectionSource) -> String {
    format!(
        "{}: cannot decode {}",
        describe_message(file, topic, h),
        source.describe()
    )
}

/// Refuses a detection message with more boxes than `--max-detections`.
fn check_count(
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
fn note_stamp(
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

fn describe_message(file: &str, topic: &str, h: &MessageHeader) -> String {
    format!(
        "{file}: topic {topic}, message at log_time {} (sequence {})",
        h.log_time, h.sequence
    )
}

impl Scan {
    /// A schema record.
    fn on_schema(&mut self, header: mcap::records::SchemaHeader, data: &[u8]) {
        self.schema_ids.insert(header.id);
        let schema = (header.name, header.encoding, data.to_vec());
        self.schemas.insert(header.id, schema);
    }

    /// A channel record: chooses it as detections (by topic, or by schema by default) and
    /// registers it with the transform sources. Returns whether it is a transform source.
    fn on_channel(
        &mut self,
        c: &mcap::records::Channel,
        opts: &TrackOptions,
        file: &str,
    ) -> Result<bool> {
        self.channel_ids.insert(c.id);
        self.topics.insert(c.topic.clone());
        let (schema_name, schema_enc, schema_data) =
            self.schemas.get(&c.schema_id).cloned().unwrap_or_default();
        let transform = self.transforms.on_channel(c, &schema_name).is_some();
        let wanted = if opts.detection_topics.is_empty() {
            // probmot's own outputs (e.g. a --scene-topic SceneUpdate) are not input.
            detection_source::is_default_candidate(&schema_name, &c.metadata)
        } else {
            opts.detection_topics.contains(&c.topic)
        };
        if wanted {
            // A schemaless channel given by topic is read as probmot.Detections3D.
            let name = if schema_name.is_empty() {
                msgs::DETECTIONS_SCHEMA
            } else {
                &schema_name
            };
            match DetectionSource::for_channel(name, &schema_enc, &schema_data, &c.message_encoding)
            {
                Ok(source) => {
                    self.det_channels.insert(c.id, (source, c.topic.clone()));
                }
                // Chosen by topic: the user asked for it, so it is an error.
                Err(why) if !opts.detection_topics.is_empty() => {
                    bail!("{file}: channel {} (topic {}): {why}", c.id, c.topic)
                }
                // Chosen by default: left out, and reported below.
                Err(why) => {
                    let why = format!("channel {} (topic {}): {why}", c.id, c.topic);
                    self.unreadable.insert(c.id, why);
                }
            }
        }
        Ok(transform)
    }

    /// After every channel is known: leaves out SceneUpdates beside other detection channels
    /// (by default), and checks that there is something readable and every named topic exists.
    fn finish(&mut self, opts: &TrackOptions, file: &str) -> Result<()> {
        if opts.detection_topics.is_empty() {
            let left_out = detection_source::scenes_left_out(
                self.det_channels.iter().map(|(id, (src, _))| (*id, src)),
            );
            if !left_out.is_empty() {
                let mut k = self.entry_channels.iter();
                self.entries
                    .retain(|_| !left_out.contains(k.next().expect("one channel per entry")));
                for id in left_out {
                    let (_, topic) = self.det_channels.remove(&id).expect("selected channel");
                    self.stamps_backwards.remove(&topic);
                    self.left_out.push(format!(
                        "channel {id} (topic {topic}, foxglove.SceneUpdate) is left out because \
                         the log has other detection channels; name it with --detections-topic \
                         to track it"
                    ));
                }
            }
        }
        if self.det_channels.is_empty() && !self.unreadable.is_empty() {
            bail!(
                "{file}: no readable detection channel: {}",
                self.unreadable
                    .values()
                    .cloned()
                    .collect::<Vec<_>>()
                    .join("; ")
            );
        }
        for t in &opts.detection_topics {
            if !self.topics.contains(t) {
                bail!("{file}: no channel with topic {t} (given with --detections-topic)");
            }
        }
        Ok(())
    }
}

fn scan(input: &Path, opts: &TrackOptions, progress: &dyn Fn(Progress<'_>)) -> Result<Scan> {
    let file = input.display().to_string();
    let mut s = Scan::default();
    let mut last_stamp: HashMap<u16, u64> = HashMap::new();
    read_records(input, |rec, stats| {
        match rec {
            Record::Header(h) => s.profile = h.profile,
            Record::Schema { header, data } => s.on_schema(header, &data),
            Record::Channel(c) => {
                s.on_channel(&c, opts, &file)?;
            }
            Record::Message { header, data } => {
                s.transforms.on_message(&file, &header, &data);
                if let Some((source, topic)) = s.det_channels.get(&header.channel_id) {
                    let (msg_stamp, count) = source
                        .stamp_and_count(&data)
                        .with_context(|| undecodable(&file, topic, &header, source))?;
                    check_count(count, opts, &file, topic, &header)?;
                    let stamp = stamp_or_log_time(msg_stamp, header.log_time);
                    note_stamp(
                        &mut last_stamp,
                        &header,
                        stamp,
                        topic,
                        &mut s.stamps_backwards,
                    );
                    s.entries.push((stamp, s.entries.len() as u64));
                    s.entry_channels.push(header.channel_id);
                }
                if s.entries.len().is_multiple_of(256) {
                    progress(Progress::Position(stats.bytes_read));
                }
            }
            _ => {}
        }
        Ok(())
    })?;
    s.finish(opts, &file)?;
    Ok(s)
}

/// One decoded detection message waiting for its frame.
struct Pending {
    ordinal: u64,
    log_time: u64,
    topic_idx: usize,
    msg: DetectionFrame,
}

/// Runs `track` on one file. The output appears only when everything succeeded.
///
/// A file is read once when its summary section lists its schemas and channels (and, with
/// several detection channels, their message counts), it has no transform channels, and its
/// detection stamps never go back to a frame already tracked: a frame is then complete once
/// every detection channel has moved past its stamp. Otherwise, or as soon as such a stamp
/// turns up, the file is read twice (the first pass learns every frame's stamp and message
/// count). Both give the same tracks.
pub fn track_file(
    input: &Path,
    output: &Path,
    opts: &TrackOptions,
    progress: &dyn Fn(Progress<'_>),
) -> Result<TrackSummary> {
    let started = Instant::now();
    check_output_path(Some(input), output)?;
    let file = input.display().to_string();
    let size = std::fs::metadata(input)
        .with_context(|| format!("cannot read {}", input.display()))?
        .len();
    if opts.no_track {
        progress(Progress::Length(size));
        return run_pass(
            input,
            output,
            opts,
            progress,
            None,
            Schedule::Known(Vec::new()),
            0,
        )
        .map(|s| finish_summary(s, 1, started));
    }
    if let Some((plan, streaming)) = one_pass_plan(input, opts, &file) {
        progress(Progress::Length(size));
        progress(Progress::Message("tracking"));
        let r = run_pass(input, output, opts, progress, Some(plan), streaming, 0);
        match r {
            Err(e) if e.downcast_ref::<NeedsTwoPasses>().is_some() => {}
            r => return r.map(|s| finish_summary(s, 1, started)),
        }
    }
    progress(Progress::Length(2 * size));
    progress(Progress::Position(0));
    progress(Progress::Message("scanning"));
    let mut s = scan(input, opts, progress)?;
    s.entries.sort_unstable();
    // Frames in stamp order: (stamp, number of messages).
    let mut frames: Vec<(u64, u32)> = Vec::new();
    for &(stamp, _) in &s.entries {
        match frames.last_mut() {
            Some((st, n)) if *st == stamp => *n += 1,
            _ => frames.push((stamp, 1)),
        }
    }
    progress(Progress::Message("tracking"));
    run_pass(
        input,
        output,
        opts,
        progress,
        Some(s),
        Schedule::Known(frames),
        size,
    )
    .map(|s| finish_summary(s, 2, started))
}

fn finish_summary(mut s: TrackSummary, passes: u8, started: Instant) -> TrackSummary {
    s.passes = passes;
    s.wall_time_s = started.elapsed().as_secs_f64();
    s
}

/// The plan of a one-pass run from the file's summary section, or `None` if the file needs
/// two passes: no readable summary (or one without channels), a transform channel (ego motion
/// looks ahead in time), several detection channels without message counts, or a channel
/// choice that fails (the first pass then reports it from the data section).
fn one_pass_plan(input: &Path, opts: &TrackOptions, file: &str) -> Option<(Scan, Schedule)> {
    let Some((Record::Header(header), records)) = read_summary_records(input) else {
        return None;
    };
    let mut plan = Scan {
        profile: header.profile,
        ..Default::default()
    };
    let mut summary_channels = HashMap::new();
    let mut counts = None;
    for rec in records {
        match rec {
            Record::Schema { header, data } if header.id != 0 => plan.on_schema(header, &data),
            Record::Channel(c) => {
                // A transform channel (ego motion looks ahead in time), or an error that the
                // first pass will report with the data section's records.
                if plan.on_channel(&c, opts, file).unwrap_or(true) {
                    return None;
                }
                summary_channels.insert(c.id, (c.topic, c.schema_id));
            }
            Record::Statistics(st) => counts = Some(st.channel_message_counts),
            _ => {}
        }
    }
    if summary_channels.is_empty() || plan.finish(opts, file).is_err() {
        return None;
    }
    if plan.det_channels.len() > 1 && counts.is_none() {
        return None;
    }
    let channels: Vec<(u16, Option<u64>)> = plan
        .det_channels
        .keys()
        .map(|id| {
            (
                *id,
                counts.as_ref().map(|c| c.get(id).copied().unwrap_or(0)),
            )
        })
        .collect();
    let schedule = Schedule::Streaming(Streaming::new(
        channels,
        summary_channels,
        plan.schema_ids.clone(),
    ));
    Some((plan, schedule))
}

/// Warnings about the detection channels chosen (none, unreadable, left out, mixed kinds).
fn selection_warnings(s: &Scan, opts: &TrackOptions, file: &str, warnings: &mut Vec<String>) {
    if s.det_channels.is_empty() {
        warnings.push(format!(
            "{file}: no detection channel (supported: {}); the log is copied unchanged \
             without a tracks channel",
            detection_source::SUPPORTED
        ));
    }
    for why in s.unreadable.values() {
        warnings.push(format!("{file}: {why}; this channel is not tracked"));
    }
    for why in &s.left_out {
        warnings.push(format!("{file}: {why}"));
    }
    let mut kinds: Vec<(&str, &str)> = s
        .det_channels
        .values()
        .map(|(src, topic)| (src.schema_name(), topic.as_str()))
        .collect();
    kinds.sort();
    if opts.detection_topics.is_empty() && kinds.first().map(|k| &k.0) != kinds.last().map(|k| &k.0)
    {
        let list: Vec<String> = kinds.iter().map(|(k, t)| format!("{t} ({k})")).collect();
        warnings.push(format!(
            "{file}: detection channels of different kinds are merged into one frame \
             sequence: {}; if some carry the same boxes (e.g. a visualization), choose with \
             --detections-topic",
            list.join(", ")
        ));
    }
}

/// The pass that copies every record and tracks: `plan` is the detection-channel choice (from
/// the first pass or the summary; `None` with `--no-track`), `base` the progress already made.
fn run_pass(
    input: &Path,
    output: &Path,
    opts: &TrackOptions,
    progress: &dyn Fn(Progress<'_>),
    plan: Option<Scan>,
    mut schedule: Schedule,
    base: u64,
) -> Result<TrackSummary> {
    let file = input.display().to_string();
    let mut summary = TrackSummary {
        input: file.clone(),
        output: output.display().to_string(),
        ..Default::default()
    };
    let mut profile = String::new();
    let mut topics: Vec<String> = Vec::new();
    let mut det_channels: HashMap<u16, (DetectionSource, usize)> = HashMap::new();
    let mut ids = None;
    let mut scan_ids = None;
    let mut transforms = TransformCollector::new();
    if let Some(mut s) = plan {
        if s.topics.contains(&opts.tracks_topic) {
            bail!(
                "{file}: already has a channel on {}; choose another topic with --tracks-topic",
                opts.tracks_topic
            );
        }
        selection_warnings(&s, opts, &file, &mut summary.warnings);
        transforms = std::mem::take(&mut s.transforms);
        summary.stamps_backwards = std::mem::take(&mut s.stamps_backwards);
        profile = std::mem::take(&mut s.profile);
        let mut det: Vec<(u16, (DetectionSource, String))> = s.det_channels.into_iter().collect();
        det.sort_by_key(|(id, _)| *id);
        for (id, (enc, topic)) in det {
            if !topics.contains(&topic) {
                topics.push(topic.clone());
            }
            let idx = topics.iter().position(|t| *t == topic).unwrap();
            det_channels.insert(id, (enc, idx));
        }
        if !det_channels.is_empty() {
            let schema_id = (1..=u16::MAX)
                .find(|i| !s.schema_ids.contains(i))
                .context("no free schema id in the output")?;
            let channel_id = (1..=u16::MAX)
                .find(|i| !s.channel_ids.contains(i))
                .context("no free channel id in the output")?;
            ids = Some((schema_id, channel_id));
        }
        scan_ids = Some((s.schema_ids, s.channel_ids, s.topics));
    }
    summary.detection_topics = topics.clone();
    let format = TracksFormat::resolve(
        opts.tracks_format,
        &profile,
        det_channels.values().map(|d| &d.0),
    );
    if ids.is_some() {
        format.check_extras(
            &file,
            opts.ego.tracks_in_ego_frame,
            opts.scene_topic.is_some(),
        )?;
    }
    let ego = EgoMotion::new(transforms, &opts.ego, opts.strict)?;
    let request = ExtraRequest {
        tracks_topic: &opts.tracks_topic,
        tracks_in_ego_frame: opts.ego.tracks_in_ego_frame,
        scene_topic: opts.scene_topic.as_deref(),
    };
    let extra = ExtraOutputs::new(&request, &file, scan_ids.as_ref(), ids)?;

    let out_opts = OutputOptions {
        profile,
        compression: opts.compression,
        ..Default::default()
    };
    let mut out = if opts.background_writer {
        BackgroundOutput::create(output, &out_opts)?
    } else {
        BackgroundOutput::create_inline(output, &out_opts)?
    };
    if let Some((schema_id, channel_id)) = ids {
        let (name, schema_encoding, data, message_encoding) = format.schema();
        out.add_schema_with_id(schema_id, name, schema_encoding, data)?;
        out.add_channel_with_id(
            channel_id,
            schema_id,
            &opts.tracks_topic,
            message_encoding,
            &format.channel_metadata(),
        )?;
        extra.add_channels(&mut out, schema_id)?;
    }

    let mut pass = Pass {
        opts,
        file: &file,
        topics,
        ids,
        format,
        out,
        extra,
        ego,
        tracker: Tracker::new(opts.config.clone())?,
        counters: InputCounters::default(),
        pending: BTreeMap::new(),
        next_frame: 0,
        frame_state: FrameState::default(),
        summary,
        progress,
    };
    let mut last_stamp: HashMap<u16, u64> = HashMap::new();
    read_records(input, |rec, stats| {
        match rec {
            Record::Header(_) | Record::Footer(_) | Record::DataEnd(_) => {}
            Record::Schema { header, data } if header.id != 0 => {
                schedule.on_schema(header.id)?;
                pass.out
                    .add_schema_with_id(header.id, &header.name, &header.encoding, &data)
                    .with_context(|| format!("{file}: copying schema {}", header.id))?;
            }
            Record::Channel(c) => {
                schedule.on_channel(c.id, &c.topic, c.schema_id)?;
                pass.out
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
                pass.out
                    .write_to_known_channel(&header, &data)
                    .with_context(|| {
                        format!(
                            "{file}: copying message at log_time {} on channel {}",
                            header.log_time, header.channel_id
                        )
                    })?;
                pass.summary.messages_copied += 1;
                if let Some(&(source, topic_idx)) = det_channels.get(&header.channel_id) {
                    let topic = &pass.topics[topic_idx];
                    let mut msg = source
                        .decode_frame(&data, header.log_time)
                        .with_context(|| undecodable(&file, topic, &header, &source))?;
                    check_count(msg.len(), opts, &file, topic, &header)?;
                    let stamp = msg.stamp;
                    schedule.on_message(header.channel_id, stamp)?;
                    // (With two passes, the first has counted them.)
                    if schedule.is_streaming() {
                        let backwards = &mut pass.summary.stamps_backwards;
                        note_stamp(&mut last_stamp, &header, stamp, topic, backwards);
                    }
                    pass.ego
                        .to_fixed(&mut msg, || describe_message(&file, topic, &header))?;
                    pass.pending.entry(stamp).or_default().push(Pending {
                        ordinal: pass.summary.detection_messages,
                        log_time: header.log_time,
                        topic_idx,
                        msg,
                    });
                    pass.summary.detection_messages += 1;
                    while let Some(stamp) = schedule.ready(&pass.pending, pass.next_frame) {
                        pass.track_frame(stamp, schedule.frames())?;
                        schedule.tracked(stamp);
                    }
                }
                if pass.summary.messages_copied.is_multiple_of(256) {
                    progress(Progress::Position(base + stats.bytes_read));
                }
            }
            Record::Attachment { header, data, .. } => {
                pass.out
                    .attach(&mcap::Attachment {
                        log_time: header.log_time,
                        create_time: header.create_time,
                        name: header.name,
                        media_type: header.media_type,
                        data,
                    })
                    .with_context(|| format!("{file}: copying an attachment"))?;
                pass.summary.attachments += 1;
            }
            Record::Metadata(m) => {
                pass.out
                    .write_metadata(&m)
                    .with_context(|| format!("{file}: copying metadata {}", m.name))?;
                pass.summary.metadata += 1;
            }
            _ => {}
        }
        Ok(())
    })?;
    match &schedule {
        Schedule::Known(frames) if pass.next_frame != frames.len() => bail!(
            "{file}: the file changed while it was read ({} of {} frames seen)",
            pass.next_frame,
            frames.len()
        ),
        Schedule::Known(_) => {}
        // Every channel has delivered all it has: the frames left are complete.
        Schedule::Streaming(_) => {
            while let Some((&stamp, _)) = pass.pending.first_key_value() {
                pass.track_frame(stamp, None)?;
            }
        }
    }
    pass.finish()
}

/// The state of the tracking pass.
struct Pass<'a> {
    opts: &'a TrackOptions,
    file: &'a str,
    /// Detection topics, indexed by [`Pending::topic_idx`].
    topics: Vec<String>,
    /// `(schema id, channel id)` of the tracks channel.
    ids: Option<(u16, u16)>,
    /// Message type of the tracks channel.
    format: TracksFormat,
    out: BackgroundOutput,
    extra: ExtraOutputs,
    ego: EgoMotion,
    tracker: Tracker,
    counters: InputCounters,
    /// Decoded detection messages by stamp, waiting for their frame to be complete.
    pending: BTreeMap<u64, Vec<Pending>>,
    next_frame: usize,
    frame_state: FrameState,
    summary: TrackSummary,
    progress: &'a dyn Fn(Progress<'_>),
}

impl Pass<'_> {
    /// Tracks the complete frame at `stamp` and writes its outputs.
    fn track_frame(&mut self, stamp: u64, frames: Option<usize>) -> Result<()> {
        let mut msgs_of_frame = self.pending.remove(&stamp).expect("a pending frame");
        msgs_of_frame.sort_by_key(|p| p.ordinal);
        let (_, channel_id) = self.ids.expect("ids exist with detections");
        self.frame_state.run(
            stamp,
            &mut msgs_of_frame,
            &mut self.tracker,
            &mut self.counters,
            self.opts.strict,
            self.file,
            &self.topics,
        )?;
        self.format
            .encode_into(&self.frame_state.out, &mut self.frame_state.buf);
        let sequence = self.next_frame as u32;
        self.out.write_to_known_channel(
            &MessageHeader {
                channel_id,
                sequence,
                log_time: stamp,
                publish_time: stamp,
            },
            &self.frame_state.buf,
        )?;
        self.extra.write_frame(
            &mut self.out,
            &self.frame_state.out,
            self.ego.take_ego(stamp),
            sequence,
        )?;
        self.frame_state.finish(self.tracker.deleted());
        self.summary.tracks_messages += 1;
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

    /// Commits the output and fills in the summary.
    fn finish(self) -> Result<TrackSummary> {
        let Pass {
            file,
            out,
            ego,
            tracker,
            counters,
            mut summary,
            progress,
            ..
        } = self;
        out.commit()?;
        progress(Progress::Done);
        let st = tracker.stats();
        summary.frames = st.frames;
        summary.tracks_born = st.born;
        summary.tracks_confirmed = st.confirmed;
        summary.mean_track_length = tracker.mean_confirmed_track_length();
        summary.merged_messages = summary.detection_messages - summary.tracks_messages;
        if counters.total_skipped() > 0 {
            let parts: Vec<String> = counters
                .skipped
                .iter()
                .map(|(r, n)| format!("{n} ({})", r.describe()))
                .collect();
            summary.warnings.push(format!(
                "{file}: skipped {} detection boxes: {}",
                counters.total_skipped(),
                parts.join(", ")
            ));
        }
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
        Ok(summary)
    }
}

/// Image box and attributes of a track's last matched detection.
#[derive(Default)]
struct Extra {
    image_box: Option<ImageBox>,
    attributes: BTreeMap<String, String>,
}

/// Per-frame buffers reused across frames, and the attributes of each track's last matched
/// detection. Nothing is allocated per detection in steady state: the output message's tracks
/// are overwritten in place, and a track's attributes are moved (not copied) from its detection
/// into the side table and swapped into the message only while it is encoded.
#[derive(Default)]
struct FrameState {
    dets: Vec<Detection>,
    /// `(message index within the frame, detection index within the message)` per detection.
    src: Vec<(u32, u32)>,
    last_extra: HashMap<u64, Extra>,
    out: Tracks3D,
    buf: Vec<u8>,
}

impl FrameState {
    /// Tracks one frame and fills `self.out`. Call [`FrameState::finish`] after encoding it.
    #[allow(clippy::too_many_arguments)]
    fn run(
        &mut self,
        stamp: u64,
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
        self.out.tracks.resize_with(reports.len(), Track3D::default);
        for (t, r) in self.out.tracks.iter_mut().zip(reports) {
            if let Some(i) = r.detection {
                let (mi, di) = self.src[i as usize];
                let d = &mut frame[mi as usize].msg.boxes[di as usize];
                if d.image_box.is_some() || !d.attributes.is_empty() {
                    let e = self.last_extra.entry(r.id).or_default();
                    e.image_box = d.image_box;
                    std::mem::swap(&mut e.attributes, &mut d.attributes);
                } else {
                    self.last_extra.remove(&r.id);
                }
            }
            fill_track3d(t, r, tracker.label(r.class));
            match self.last_extra.get_mut(&r.id) {
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

    /// Gives the attributes lent to the encoded message back to the side table and forgets the
    /// tracks deleted in this frame.
    fn finish(&mut self, deleted: &[u64]) {
        for t in &mut self.out.tracks {
            if let Some(e) = self.last_extra.get_mut(&t.id) {
                std::mem::swap(&mut t.attributes, &mut e.attributes);
            }
        }
        for id in deleted {
            self.last_extra.remove(id);
        }
    }
}
