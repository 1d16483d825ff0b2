//! `probmot track`: read an MCAP recording, replay its detections in stamp order through the
//! tracker, and write every input record plus a tracks channel to a new MCAP file.
//!
//! Two streaming passes over the input. The first decodes only the detection messages to learn
//! the frame stamps (16 bytes kept per detection message). The second copies every record to the
//! output in file order and runs the tracker as soon as all messages of the next frame (in stamp
//! order) have been seen; messages that arrive early wait in a small reorder buffer. Memory is
//! bounded by the live tracks, one chunk of the input and output, and the out-of-orderness of
//! the file, not by its length.
//!
//! The output is written through [`BackgroundOutput`]: with [`TrackOptions::background_writer`]
//! its chunks are compressed on other threads while this one reads and tracks.

use std::collections::{BTreeMap, HashMap, HashSet};
use std::path::Path;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use indicatif::ProgressBar;
use mcap::records::{MessageHeader, Record};

use super::detections::{convert, InputCounters, Origin};
use super::ego::{EgoMotion, EgoOptions, EgoSummary};
use super::track_outputs::ExtraOutputs;
use crate::mcapio::background::BackgroundOutput;
use crate::mcapio::reader::read_records;
use crate::mcapio::writer::{check_output_path, OutputCompression, OutputOptions};
use crate::msgs::detection_source::{self, DetectionSource};
use crate::msgs::{self, v3, Detections3D, ImageBox, Track3D, Tracks3D};
use crate::sim::write::size3;
use crate::tracker::{Detection, TrackReport, Tracker, TrackerConfig};
use crate::transforms::TransformCollector;

/// Settings of one `track` run.
#[derive(Debug, Clone)]
pub struct TrackOptions {
    /// Detection topics; empty: every channel of a supported detection schema
    /// ([`detection_source::is_detection_schema`]).
    pub detection_topics: Vec<String>,
    /// Topic of the tracks channel written.
    pub tracks_topic: String,
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
    /// Wall time in seconds.
    pub wall_time_s: f64,
}

/// Result of the first pass.
struct Scan {
    profile: String,
    schema_ids: HashSet<u16>,
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

/// Stamp of a detection message: its own `stamp`, else the MCAP `log_time`.
fn stamp_of(msg: &Detections3D, log_time: u64) -> u64 {
    msg.stamp.unwrap_or(log_time)
}

fn describe_message(file: &str, topic: &str, h: &MessageHeader) -> String {
    format!(
        "{file}: topic {topic}, message at log_time {} (sequence {})",
        h.log_time, h.sequence
    )
}

fn scan(input: &Path, opts: &TrackOptions, progress: &ProgressBar) -> Result<Scan> {
    let file = input.display().to_string();
    let mut schemas: HashMap<u16, (String, String, Vec<u8>)> = HashMap::new();
    let mut s = Scan {
        profile: String::new(),
        schema_ids: HashSet::new(),
        channel_ids: HashSet::new(),
        det_channels: HashMap::new(),
        entries: Vec::new(),
        stamps_backwards: BTreeMap::new(),
        topics: HashSet::new(),
        unreadable: BTreeMap::new(),
        left_out: Vec::new(),
        entry_channels: Vec::new(),
        transforms: TransformCollector::new(),
    };
    let mut last_stamp: HashMap<u16, u64> = HashMap::new();
    let mut ordinal = 0u64;
    read_records(input, |rec, stats| {
        match rec {
            Record::Header(h) => s.profile = h.profile,
            Record::Schema { header, data } => {
                s.schema_ids.insert(header.id);
                schemas.insert(header.id, (header.name, header.encoding, data.into_owned()));
            }
            Record::Channel(c) => {
                s.channel_ids.insert(c.id);
                s.topics.insert(c.topic.clone());
                let (schema_name, schema_enc, schema_data) =
                    schemas.get(&c.schema_id).cloned().unwrap_or_default();
                s.transforms.on_channel(&c, &schema_name);
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
                    match DetectionSource::for_channel(
                        name,
                        &schema_enc,
                        &schema_data,
                        &c.message_encoding,
                    ) {
                        Ok(source) => {
                            s.det_channels.insert(c.id, (source, c.topic.clone()));
                        }
                        // Chosen by topic: the user asked for it, so it is an error.
                        Err(why) if !opts.detection_topics.is_empty() => {
                            bail!("{file}: channel {} (topic {}): {why}", c.id, c.topic)
                        }
                        // Chosen by default: left out, and reported below.
                        Err(why) => {
                            let why = format!("channel {} (topic {}): {why}", c.id, c.topic);
                            s.unreadable.insert(c.id, why);
                        }
                    }
                }
            }
            Record::Message { header, data } => {
                s.transforms.on_message(&file, &header, &data);
                if let Some((source, topic)) = s.det_channels.get(&header.channel_id) {
                    let (msg_stamp, count) = source.stamp_and_count(&data).with_context(|| {
                        format!(
                            "{}: cannot decode {}",
                            describe_message(&file, topic, &header),
                            source.describe()
                        )
                    })?;
                    if count > opts.max_detections_per_message {
                        bail!(
                            "{}: {} detections in one message, more than the limit of {} \
                             (--max-detections)",
                            describe_message(&file, topic, &header),
                            count,
                            opts.max_detections_per_message
                        );
                    }
                    let stamp = msg_stamp.unwrap_or(header.log_time);
                    if let Some(prev) = last_stamp.insert(header.channel_id, stamp) {
                        if stamp < prev {
                            *s.stamps_backwards.entry(topic.clone()).or_default() += 1;
                        }
                    }
                    s.entries.push((stamp, ordinal));
                    s.entry_channels.push(header.channel_id);
                    ordinal += 1;
                }
                if ordinal.is_multiple_of(256) {
                    progress.set_position(stats.bytes_read);
                }
            }
            _ => {}
        }
        Ok(())
    })?;
    if opts.detection_topics.is_empty() {
        let left_out = detection_source::scenes_left_out(
            s.det_channels.iter().map(|(id, (src, _))| (*id, src)),
        );
        if !left_out.is_empty() {
            let mut k = s.entry_channels.iter();
            s.entries
                .retain(|_| !left_out.contains(k.next().expect("one channel per entry")));
            for id in left_out {
                let (_, topic) = s.det_channels.remove(&id).expect("selected channel");
                s.stamps_backwards.remove(&topic);
                s.left_out.push(format!(
                    "channel {id} (topic {topic}, foxglove.SceneUpdate) is left out because the \
                     log has other detection channels; name it with --detections-topic to track it"
                ));
            }
        }
    }
    if s.det_channels.is_empty() && !s.unreadable.is_empty() {
        bail!(
            "{file}: no readable detection channel: {}",
            s.unreadable
                .values()
                .cloned()
                .collect::<Vec<_>>()
                .join("; ")
        );
    }
    for t in &opts.detection_topics {
        if !s.topics.contains(t) {
            bail!("{file}: no channel with topic {t} (given with --detections-topic)");
        }
    }
    Ok(s)
}

/// One decoded detection message waiting for its frame.
struct Pending {
    ordinal: u64,
    log_time: u64,
    topic_idx: usize,
    msg: Detections3D,
}

/// Runs `track` on one file. The output appears only when everything succeeded.
pub fn track_file(
    input: &Path,
    output: &Path,
    opts: &TrackOptions,
    progress: &ProgressBar,
) -> Result<TrackSummary> {
    let started = Instant::now();
    check_output_path(Some(input), output)?;
    let file = input.display().to_string();
    let size = std::fs::metadata(input)
        .with_context(|| format!("cannot read {}", input.display()))?
        .len();
    let mut summary = TrackSummary {
        input: file.clone(),
        output: output.display().to_string(),
        ..Default::default()
    };
    progress.set_length(if opts.no_track { size } else { 2 * size });
    progress.set_message("scanning");

    let scan = if opts.no_track {
        None
    } else {
        let s = scan(input, opts, progress)?;
        if s.topics.contains(&opts.tracks_topic) {
            bail!(
                "{file}: already has a channel on {}; choose another topic with --tracks-topic",
                opts.tracks_topic
            );
        }
        if s.det_channels.is_empty() {
            summary.warnings.push(format!(
                "{file}: no detection channel (supported: {}); the log is copied unchanged \
                 without a tracks channel",
                detection_source::SUPPORTED
            ));
        }
        for why in s.unreadable.values() {
            summary
                .warnings
                .push(format!("{file}: {why}; this channel is not tracked"));
        }
        for why in &s.left_out {
            summary.warnings.push(format!("{file}: {why}"));
        }
        let mut kinds: Vec<(&str, &str)> = s
            .det_channels
            .values()
            .map(|(src, topic)| (src.schema_name(), topic.as_str()))
            .collect();
        kinds.sort();
        if opts.detection_topics.is_empty()
            && kinds.first().map(|k| &k.0) != kinds.last().map(|k| &k.0)
        {
            let list: Vec<String> = kinds.iter().map(|(k, t)| format!("{t} ({k})")).collect();
            summary.warnings.push(format!(
                "{file}: detection channels of different kinds are merged into one frame \
                 sequence: {}; if some carry the same boxes (e.g. a visualization), choose with \
                 --detections-topic",
                list.join(", ")
            ));
        }
        Some(s)
    };

    // Frames in stamp order: (stamp, number of messages).
    let mut frames: Vec<(u64, u32)> = Vec::new();
    let mut profile = String::new();
    let mut topics: Vec<String> = Vec::new();
    let mut det_channels: HashMap<u16, (DetectionSource, usize)> = HashMap::new();
    let mut ids = None;
    let mut scan_ids = None;
    let mut transforms = TransformCollector::new();
    if let Some(mut s) = scan {
        transforms = std::mem::take(&mut s.transforms);
        s.entries.sort_unstable();
        for &(stamp, _) in &s.entries {
            match frames.last_mut() {
                Some((st, n)) if *st == stamp => *n += 1,
                _ => frames.push((stamp, 1)),
            }
        }
        summary.merged_messages = s.entries.len() as u64 - frames.len() as u64;
        summary.detection_messages = s.entries.len() as u64;
        summary.stamps_backwards = s.stamps_backwards;
        profile = s.profile;
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
    let mut ego = EgoMotion::new(transforms, &opts.ego, opts.strict)?;
    let mut extra = ExtraOutputs::new(opts, &file, scan_ids.as_ref(), ids)?;

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
        out.add_schema_with_id(
            schema_id,
            msgs::TRACKS_SCHEMA,
            "protobuf",
            msgs::DESCRIPTOR_SET,
        )?;
        out.add_channel_with_id(
            channel_id,
            schema_id,
            &opts.tracks_topic,
            "protobuf",
            &BTreeMap::new(),
        )?;
        extra.add_channels(&mut out, schema_id)?;
    }

    let mut tracker = Tracker::new(opts.config.clone())?;
    let mut counters = InputCounters::default();
    let mut pending: BTreeMap<u64, Vec<Pending>> = BTreeMap::new();
    let mut next_frame = 0usize;
    let mut ordinal = 0u64;
    let mut frame_state = FrameState::default();
    let base = if opts.no_track { 0 } else { size };
    if !opts.no_track {
        progress.set_message("tracking");
    }

    read_records(input, |rec, stats| {
        match rec {
            Record::Header(_) | Record::Footer(_) | Record::DataEnd(_) => {}
            Record::Schema { header, data } if header.id != 0 => {
                out.add_schema_with_id(header.id, &header.name, &header.encoding, &data)
                    .with_context(|| format!("{file}: copying schema {}", header.id))?;
            }
            Record::Channel(c) => {
                out.add_channel_with_id(
                    c.id,
                    c.schema_id,
                    &c.topic,
                    &c.message_encoding,
                    &c.metadata,
                )
                .with_context(|| format!("{file}: copying channel {} ({})", c.id, c.topic))?;
            }
            Record::Message { header, data } => {
                out.write_to_known_channel(&header, &data)
                    .with_context(|| {
                        format!(
                            "{file}: copying message at log_time {} on channel {}",
                            header.log_time, header.channel_id
                        )
                    })?;
                summary.messages_copied += 1;
                if let Some(&(source, topic_idx)) = det_channels.get(&header.channel_id) {
                    let mut msg: Detections3D = source
                        .decode(&data)
                        .with_context(|| describe_message(&file, &topics[topic_idx], &header))?;
                    let stamp = stamp_of(&msg, header.log_time);
                    ego.to_fixed(&mut msg, stamp, || {
                        describe_message(&file, &topics[topic_idx], &header)
                    })?;
                    pending.entry(stamp).or_default().push(Pending {
                        ordinal,
                        log_time: header.log_time,
                        topic_idx,
                        msg,
                    });
                    ordinal += 1;
                    while let Some(&(stamp, count)) = frames.get(next_frame) {
                        if pending.get(&stamp).map(|v| v.len() as u32) != Some(count) {
                            break;
                        }
                        let mut msgs_of_frame = pending.remove(&stamp).unwrap();
                        msgs_of_frame.sort_by_key(|p| p.ordinal);
                        let (_, channel_id) = ids.expect("ids exist with detections");
                        frame_state.run(
                            stamp,
                            &mut msgs_of_frame,
                            &mut tracker,
                            &mut counters,
                            opts.strict,
                            &file,
                            &topics,
                        )?;
                        msgs::encode_into(&frame_state.out, &mut frame_state.buf);
                        out.write_to_known_channel(
                            &MessageHeader {
                                channel_id,
                                sequence: next_frame as u32,
                                log_time: stamp,
                                publish_time: stamp,
                            },
                            &frame_state.buf,
                        )?;
                        extra.write_frame(
                            &mut out,
                            &frame_state.out,
                            ego.take_ego(stamp),
                            next_frame as u32,
                        )?;
                        frame_state.finish(tracker.deleted());
                        summary.tracks_messages += 1;
                        next_frame += 1;
                        if next_frame.is_multiple_of(64) {
                            progress.set_message(format!(
                                "tracking: frame {next_frame}/{}",
                                frames.len()
                            ));
                        }
                    }
                }
                if summary.messages_copied.is_multiple_of(256) {
                    progress.set_position(base + stats.bytes_read);
                }
            }
            Record::Attachment { header, data, .. } => {
                out.attach(&mcap::Attachment {
                    log_time: header.log_time,
                    create_time: header.create_time,
                    name: header.name,
                    media_type: header.media_type,
                    data,
                })
                .with_context(|| format!("{file}: copying an attachment"))?;
                summary.attachments += 1;
            }
            Record::Metadata(m) => {
                out.write_metadata(&m)
                    .with_context(|| format!("{file}: copying metadata {}", m.name))?;
                summary.metadata += 1;
            }
            _ => {}
        }
        Ok(())
    })?;
    if next_frame != frames.len() {
        bail!(
            "{file}: the file changed while it was read ({} of {} frames seen)",
            next_frame,
            frames.len()
        );
    }
    out.commit()?;
    progress.set_position(progress.length().unwrap_or(0));

    let st = tracker.stats();
    summary.frames = st.frames;
    summary.tracks_born = st.born;
    summary.tracks_confirmed = st.confirmed;
    summary.mean_track_length = tracker.mean_confirmed_track_length();
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
            "{file}: topic {topic}: {n} messages have a stamp earlier than the message before \
             them; frames were replayed in stamp order"
        ));
    }
    summary.detections = counters;
    summary.ego = ego.finish(&file, &mut summary.warnings);
    summary.wall_time_s = started.elapsed().as_secs_f64();
    Ok(summary)
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
            for (di, d) in p.msg.detections.iter().enumerate() {
                if let Some(det) = convert(d, di, tracker, counters, strict, &origin)? {
                    self.dets.push(det);
                    self.src.push((mi as u32, di as u32));
                }
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
                let d = &mut frame[mi as usize].msg.detections[di as usize];
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

/// Writes one reported track into an output message, reusing its allocations (the image box and
/// attributes are left to the caller).
pub fn fill_track3d(t: &mut Track3D, r: &TrackReport, label: &str) {
    t.id = r.id;
    t.label.clear();
    t.label.push_str(label);
    t.center = Some(v3(r.bbox.center));
    t.size = Some(size3(r.bbox.size));
    t.yaw = r.bbox.yaw;
    t.velocity = Some(v3(r.velocity));
    t.yaw_rate = r.yaw_rate;
    t.score = r.score;
    t.position_variance = Some(v3(r.position_variance));
    t.yaw_variance = r.yaw_variance;
    t.age = r.age;
    t.hits = r.hits;
    t.frames_since_update = r.frames_since_update;
}

/// The output message of one reported track.
pub fn to_track3d(
    r: &TrackReport,
    label: &str,
    image_box: Option<ImageBox>,
    attributes: BTreeMap<String, String>,
) -> Track3D {
    let mut t = Track3D {
        image_box,
        attributes,
        ..Default::default()
    };
    fill_track3d(&mut t, r, label);
    t
}
