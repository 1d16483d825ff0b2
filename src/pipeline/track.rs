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
use mcap::records::Record;

use super::detections::InputCounters;
use super::ego::EgoMotion;
use super::frame_schedule::{NeedsTwoPasses, Schedule, Streaming};
use super::progress::Progress;
use super::stamp_check::{LogSpan, StampCheck, StampWindow};
use super::track_outputs::{ExtraOutputs, ExtraRequest};
use super::track_session::{check_count, note_stamp, undecodable, FrameState, TrackSession};
use super::tracks_format::TracksFormat;
use crate::mcapio::background::BackgroundOutput;
use crate::mcapio::reader::{read_records, read_summary_records};
use crate::mcapio::writer::{check_output_path, OutputOptions};
use crate::msgs;
use crate::msgs::detection_frame::stamp_or_log_time;
use crate::msgs::detection_source::{self, DetectionSource};
pub use crate::msgs::track_encode::{fill_track3d, to_track3d};
use crate::tracker::Tracker;
use crate::transforms::TransformCollector;

pub use super::track_options::{
    SceneOutput, TrackOptions, TrackSummary, DEFAULT_MAX_DETECTIONS, SCENE_TOPIC_SUFFIX,
};

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
    /// log_times of the detection messages, and the stamps they may carry (two passes).
    log_span: LogSpan,
    stamp_window: Option<StampWindow>,
    transforms: TransformCollector,
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
                    s.log_span.note(header.log_time);
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
    let size = super::track_input::regular_input(input)?;
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
    s.stamp_window = StampWindow::of(s.entries.iter().map(|e| e.0), s.log_span);
    s.entries
        .retain(|e| s.stamp_window.is_none_or(|w| w.contains(e.0)));
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

/// Creates the output (written on a thread of its own with [`TrackOptions::background_writer`])
/// and adds the tracks channel and the extra channels when there are detections (`ids`).
fn create_output(
    output: &Path,
    opts: &TrackOptions,
    profile: String,
    ids: Option<(u16, u16)>,
    format: TracksFormat,
    extra: &ExtraOutputs,
) -> Result<BackgroundOutput> {
    let tracks_topic = opts.tracks_topic_for(format);
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
            tracks_topic,
            message_encoding,
            &format.channel_metadata(),
        )?;
        extra.add_channels(&mut out, schema_id)?;
    }

    Ok(out)
}

/// What the output's channels come from: the detection channels chosen in the scan, the ids free
/// for the tracks' schema and channel, and what the scan collected on the way.
#[derive(Default)]
struct PlannedChannels {
    /// The input's ROS 2 / probmot profile.
    profile: String,
    /// The detection topics, in channel-id order.
    topics: Vec<String>,
    /// Per detection channel: its decoder and the index of its topic.
    det_channels: HashMap<u16, (DetectionSource, usize)>,
    /// Schema and channel ids of the tracks (`None`: no detection channel).
    ids: Option<(u16, u16)>,
    /// The input's schema ids, channel ids and topics.
    scan_ids: Option<(HashSet<u16>, HashSet<u16>, HashSet<String>)>,
    /// The transforms met in the scan.
    transforms: TransformCollector,
}

/// The channels of the output from the scan `s`; adds the selection warnings to `summary`.
fn planned_channels(
    mut s: Scan,
    opts: &TrackOptions,
    file: &str,
    summary: &mut TrackSummary,
) -> Result<PlannedChannels> {
    let mut p = PlannedChannels::default();
    selection_warnings(&s, opts, file, &mut summary.warnings);
    p.transforms = std::mem::take(&mut s.transforms);
    summary.stamps_backwards = std::mem::take(&mut s.stamps_backwards);
    p.profile = std::mem::take(&mut s.profile);
    let mut det: Vec<(u16, (DetectionSource, String))> = s.det_channels.into_iter().collect();
    det.sort_by_key(|(id, _)| *id);
    for (id, (enc, topic)) in det {
        if !p.topics.contains(&topic) {
            p.topics.push(topic.clone());
        }
        let idx = p.topics.iter().position(|t| *t == topic).unwrap();
        p.det_channels.insert(id, (enc, idx));
    }
    if !p.det_channels.is_empty() {
        let schema_id = (1..=u16::MAX)
            .find(|i| !s.schema_ids.contains(i))
            .context("no free schema id in the output")?;
        let channel_id = (1..=u16::MAX)
            .find(|i| !s.channel_ids.contains(i))
            .context("no free channel id in the output")?;
        p.ids = Some((schema_id, channel_id));
    }
    p.scan_ids = Some((s.schema_ids, s.channel_ids, s.topics));
    Ok(p)
}

/// Refuses a tracks topic the input already has (`topics`: the input's topics, when scanned).
fn check_tracks_topic(
    opts: &TrackOptions,
    format: TracksFormat,
    topics: Option<&HashSet<String>>,
    file: &str,
) -> Result<()> {
    let topic = opts.tracks_topic_for(format);
    if !topics.is_some_and(|t| t.contains(topic)) {
        return Ok(());
    }
    let hint = if opts.tracks_topic.is_none() && format == TracksFormat::Autoware {
        " (the default for Autoware tracks; the bag holds Autoware's own tracks there), e.g. \
         --tracks-topic /probmot/tracking/objects"
    } else {
        ""
    };
    bail!(
        "{file}: already has a channel on {topic}; choose another topic with --tracks-topic{hint}"
    )
}

/// The pass that copies every record and tracks: `plan` is the detection-channel choice (from
/// the first pass or the summary; `None` with `--no-track`), `base` the progress already made.
fn run_pass(
    input: &Path,
    output: &Path,
    opts: &TrackOptions,
    progress: &dyn Fn(Progress<'_>),
    plan: Option<Scan>,
    schedule: Schedule,
    base: u64,
) -> Result<TrackSummary> {
    let file = input.display().to_string();
    let mut summary = TrackSummary {
        input: file.clone(),
        output: output.display().to_string(),
        ..Default::default()
    };
    let stamps = StampCheck::new(plan.as_ref().and_then(|s| s.stamp_window));
    let PlannedChannels {
        profile,
        topics,
        det_channels,
        ids,
        scan_ids,
        transforms,
    } = match plan {
        Some(s) => planned_channels(s, opts, &file, &mut summary)?,
        None => PlannedChannels::default(),
    };
    summary.detection_topics = topics.clone();
    let format = TracksFormat::resolve(
        opts.tracks_format,
        &profile,
        det_channels.values().map(|d| &d.0),
    );
    check_tracks_topic(opts, format, scan_ids.as_ref().map(|s| &s.2), &file)?;
    let tracks_topic = opts.tracks_topic_for(format);
    summary.tracks_topic = tracks_topic.to_string();
    if ids.is_some() {
        format.check_extras(
            &file,
            opts.ego.tracks_in_ego_frame,
            matches!(opts.scene, SceneOutput::Topic(_)),
        )?;
    }
    let ego = EgoMotion::new(transforms, &opts.ego, opts.strict)?;
    let scene_topic = opts.scene.topic(tracks_topic, format);
    let request = ExtraRequest {
        tracks_topic,
        tracks_in_ego_frame: opts.ego.tracks_in_ego_frame,
        scene_topic: scene_topic.as_deref(),
    };
    let extra = ExtraOutputs::new(&request, &file, scan_ids.as_ref(), ids)?;

    let out = create_output(output, opts, profile, ids, format, &extra)?;

    let mut session = TrackSession {
        opts,
        file: &file,
        topics,
        det_channels,
        ids,
        format,
        out,
        extra,
        ego,
        tracker: Tracker::new(opts.config.clone())?,
        counters: InputCounters::default(),
        schedule,
        last_stamp: HashMap::new(),
        stamps,
        pending: BTreeMap::new(),
        next_frame: 0,
        intervals: super::track_warnings::FrameIntervals::default(),
        frame_state: FrameState::new(&opts.config),
        order: Default::default(),
        summary,
        progress,
        base,
    };
    read_records(input, |rec, stats| session.on_record(rec, stats.bytes_read))?;
    session.end_of_input()?;
    let (out, summary) = session.finish();
    out.commit()?;
    progress(Progress::Done);
    Ok(summary)
}
