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
use std::ops::ControlFlow;
use std::path::Path;
use std::time::Instant;

use anyhow::{bail, Context, Result};

use super::bag_source::BagSource;
use super::db3_file::is_sqlite_file;
use super::ego::EgoMotion;
use super::frame_schedule::{Replan, Schedule};
use super::progress::Progress;
use super::stamp_check::{StampCheck, StampWindow};
use super::track_outputs::{ExtraOutputs, ExtraRequest};
use super::track_plan::{scan, PassPlan, Scan};
use super::track_records::RecordSession;
use super::track_session::{SessionOptions, TrackSession};
use super::tracks_format::TracksFormat;
use crate::mcapio::background::BackgroundOutput;
use crate::mcapio::reader::{CutShort, McapInput};
use crate::mcapio::sink::RecordSink;
use crate::mcapio::source::RecordSource;
use crate::mcapio::writer::{check_output_path, OutputOptions};
use crate::msgs::detection_source::{self, DetectionSource};
pub use crate::msgs::track_encode::{fill_track3d, to_track3d};
use crate::transforms::TransformCollector;

pub use super::track_options::{
    SceneOutput, TrackOptions, TrackSummary, DEFAULT_MAX_DETECTIONS, SCENE_TOPIC_SUFFIX,
};

/// Runs `track` on one file. The output appears only when everything succeeded.
///
/// A file is read once when its summary section lists its schemas and channels (and, with
/// several detection channels, their message counts), it has no transform channels, and its
/// detection stamps never go back to a frame already tracked (nor lie over a day from their
/// message's log_time): a frame is then complete once every detection channel has moved past
/// its stamp. Otherwise, or as soon as such a stamp turns up, the file is read twice (the first pass learns every frame's stamp and message
/// count). Both give the same tracks.
pub fn track_file(
    input: &Path,
    output: &Path,
    opts: &TrackOptions,
    progress: &dyn Fn(Progress<'_>),
) -> Result<TrackSummary> {
    let started = Instant::now();
    check_output_path(Some(input), output)?;
    let open = |profile| open_output(output, opts, profile);
    let (out, mut summary) = if is_sqlite_file(input) {
        track_input(&mut BagSource::sqlite_file(input), opts, progress, open)?
    } else {
        track_input(&mut McapInput::open_regular(input)?, opts, progress, open)?
    };
    out.commit()?;
    progress(Progress::Done);
    summary.output = output.display().to_string();
    summary.wall_time_s = started.elapsed().as_secs_f64();
    Ok(summary)
}

/// [`track_file`] over any seekable input, into the sink `open` makes from the input's
/// profile (made once; a single pass that turns out to need two restarts it). Returns the sink,
/// for the caller to finish, and the summary (its `output` and `wall_time_s` left to the
/// caller).
pub fn track_input<I: RecordSource, S: RecordSink>(
    input: &mut I,
    opts: &TrackOptions,
    progress: &dyn Fn(Progress<'_>),
    open: impl FnOnce(String) -> Result<S>,
) -> Result<(S, TrackSummary)> {
    let size = input.byte_len();
    let mut out = Output::Unopened(open);
    let single = match PassPlan::decide(input, opts) {
        PassPlan::CopyOnly => Some((None, Schedule::Known(Vec::new()))),
        PassPlan::OnePass(plan, schedule) => Some((Some(*plan), schedule)),
        PassPlan::TwoPasses => None,
    };
    if let Some((plan, schedule)) = single {
        progress(Progress::Length(size));
        if plan.is_some() {
            progress(Progress::Message("tracking"));
        }
        let (sink, end) = run_pass(input, out, opts, progress, plan, schedule, 0)?;
        match end {
            ControlFlow::Continue(summary) => return Ok((sink, with_passes(summary, 1))),
            // The plan from the summary was wrong about the file: two passes after all.
            ControlFlow::Break(_) => out = Output::Open(sink),
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
    let schedule = Schedule::Known(frames);
    let (sink, end) = run_pass(input, out, opts, progress, Some(s), schedule, size)?;
    match end {
        ControlFlow::Continue(summary) => Ok((sink, with_passes(summary, 2))),
        // (Only a file changed between the passes can make the tracking pass replan.)
        ControlFlow::Break(replan) => bail!(
            "{}: the file changed while it was read ({replan:?} in the second pass)",
            input.name()
        ),
    }
}

fn with_passes(mut s: TrackSummary, passes: u8) -> TrackSummary {
    s.passes = passes;
    s
}

/// The output of a run: made by the first pass, restarted by a second.
enum Output<S, F> {
    Unopened(F),
    Open(S),
}

impl<S: RecordSink, F: FnOnce(String) -> Result<S>> Output<S, F> {
    /// The sink, empty, with the input's `profile`.
    fn start(self, profile: String) -> Result<S> {
        match self {
            Output::Unopened(open) => open(profile),
            Output::Open(mut sink) => {
                sink.restart()?;
                Ok(sink)
            }
        }
    }
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

/// Creates the output file (written on a thread of its own with
/// [`TrackOptions::background_writer`]).
fn open_output(output: &Path, opts: &TrackOptions, profile: String) -> Result<BackgroundOutput> {
    let out_opts = OutputOptions {
        profile,
        compression: opts.compression,
        ..Default::default()
    };
    if opts.background_writer {
        BackgroundOutput::create(output, &out_opts)
    } else {
        BackgroundOutput::create_inline(output, &out_opts)
    }
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
/// Returns the output, and the summary or the [`Replan`] that stopped a single pass.
fn run_pass<I: RecordSource, S: RecordSink, F: FnOnce(String) -> Result<S>>(
    input: &mut I,
    out: Output<S, F>,
    opts: &TrackOptions,
    progress: &dyn Fn(Progress<'_>),
    mut plan: Option<Scan>,
    schedule: Schedule,
    base: u64,
) -> Result<(S, ControlFlow<Replan, TrackSummary>)> {
    let file = input.name().to_string();
    // The cuts of a first pass, if this is the second: those are what the run warns of.
    let scanned_cuts = (plan.as_mut()).map_or(Vec::new(), |p| std::mem::take(&mut p.cuts));
    let mut summary = TrackSummary {
        input: file.clone(),
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

    let out = out.start(profile)?;

    let options = SessionOptions {
        name: file.clone(),
        strict: opts.strict,
    };
    let mut tracking = TrackSession::new(opts.config.clone(), options)?;
    tracking.topics = topics;
    let mut session = RecordSession {
        opts,
        file: &file,
        det_channels,
        ids,
        format,
        out,
        extra,
        ego,
        session: tracking,
        schedule,
        last_stamp: HashMap::new(),
        stamps,
        pending: BTreeMap::new(),
        next_frame: 0,
        order: Default::default(),
        summary,
        progress,
        base,
        headers: 0,
        reader: Default::default(),
    };
    session.add_tracks_channels()?;
    let mut replan = None;
    let read_cuts = input.read_while(&mut |rec, stats| {
        let flow = session.on_record(rec, stats.bytes_read)?;
        replan = flow.break_value();
        Ok(flow.map_break(|_| ()))
    })?;
    if let Some(replan) = replan {
        return Ok((session.out, ControlFlow::Break(replan)));
    }
    let cuts = match scanned_cuts.is_empty() {
        true => read_cuts,
        false => scanned_cuts,
    };
    if let (Some(cut), true) = (cuts.first(), opts.strict) {
        bail!("{}; --strict refuses it", cut.warning());
    }
    session.end_of_input()?;
    let (out, mut summary) = session.finish();
    summary.warnings.extend(cuts.iter().map(CutShort::warning));
    Ok((out, ControlFlow::Continue(summary)))
}
