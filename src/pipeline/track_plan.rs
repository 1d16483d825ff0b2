//! Whether `track` reads its input once or twice, decided before reading ([`PassPlan`]): once
//! when the summary section lists every schema and channel (and, with several detection
//! channels, their message counts) and there is no transform channel; else twice, a first pass
//! ([`scan`]) learning every frame's stamp and message count. What the plan cannot know (a stamp
//! going back to a frame already tracked, or over a day from its log_time) is a
//! [`super::frame_schedule::Replan`] of the single pass, not an error.

use std::collections::{BTreeMap, HashMap, HashSet};
use std::ops::ControlFlow;

use anyhow::{bail, Context, Result};
use mcap::records::Record;

use super::frame_schedule::{Schedule, Streaming};
use super::progress::Progress;
use super::stamp_check::{LogSpan, StampWindow};
use super::track_options::TrackOptions;
use super::track_records::{check_count, note_stamp, undecodable};
use crate::mcapio::reader::CutShort;
use crate::mcapio::recording::topic_list;
use crate::mcapio::source::RecordSource;
use crate::msgs;
use crate::msgs::detection_frame::stamp_or_log_time;
use crate::msgs::detection_source::{self, DetectionSource};
use crate::transforms::TransformCollector;

/// How `track` reads its input, decided before reading.
pub(super) enum PassPlan {
    /// `--no-track`: one pass that copies every record.
    CopyOnly,
    /// One pass, frames complete by the watermark over the detection channels: the detection
    /// channels chosen from the summary section, and the schedule.
    OnePass(Box<Scan>, Schedule),
    /// A first pass learns every frame ([`scan`]), the second tracks.
    TwoPasses,
}

impl PassPlan {
    /// The plan for `input` from its summary section alone (reads its start and its end).
    pub(super) fn decide<I: RecordSource>(input: &mut I, opts: &TrackOptions) -> PassPlan {
        if opts.no_track {
            return PassPlan::CopyOnly;
        }
        match one_pass_plan(input, opts) {
            Some((plan, schedule)) => PassPlan::OnePass(Box::new(plan), schedule),
            None => PassPlan::TwoPasses,
        }
    }
}

/// Result of the first pass.
#[derive(Default)]
pub(super) struct Scan {
    /// The files the first pass found cut short: what the run warns of (a later read stops
    /// where this one did, and may not meet the damage, or not all of a grown file).
    pub(super) cuts: Vec<CutShort>,
    pub(super) profile: String,
    pub(super) schema_ids: HashSet<u16>,
    /// `(name, encoding, data)` of every schema.
    pub(super) schemas: HashMap<u16, (String, String, Vec<u8>)>,
    pub(super) channel_ids: HashSet<u16>,
    pub(super) det_channels: HashMap<u16, (DetectionSource, String)>,
    /// `(stamp, ordinal)` of every detection message.
    pub(super) entries: Vec<(u64, u64)>,
    pub(super) stamps_backwards: BTreeMap<String, u64>,
    pub(super) topics: HashSet<String>,
    /// Channels of a detection schema left out of the default selection, with the reason.
    pub(super) unreadable: BTreeMap<u16, String>,
    /// Readable detection channels left out of the default selection (SceneUpdates beside other
    /// detection channels), as warnings.
    pub(super) left_out: Vec<String>,
    /// Channel of each entry of `entries`.
    pub(super) entry_channels: Vec<u16>,
    /// log_times of the detection messages, and the stamps they may carry (two passes).
    pub(super) log_span: LogSpan,
    pub(super) stamp_window: Option<StampWindow>,
    pub(super) transforms: TransformCollector,
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
                let has = topic_list(&self.topics);
                bail!("{file}: no channel with topic {t} (given with --detections-topic; {has})");
            }
        }
        Ok(())
    }
}

/// The first pass of two: the detection channels and every detection message's stamp (and
/// the transforms), from the start of `input`.
pub(super) fn scan<I: RecordSource>(
    input: &mut I,
    opts: &TrackOptions,
    progress: &dyn Fn(Progress<'_>),
) -> Result<Scan> {
    let file = input.name().to_string();
    let mut s = Scan::default();
    let mut last_stamp: HashMap<u16, u64> = HashMap::new();
    s.cuts = input.read_while(&mut |rec, stats| {
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
        Ok(ControlFlow::Continue(()))
    })?;
    s.finish(opts, &file)?;
    Ok(s)
}

/// The plan of a one-pass run from the file's summary section, or `None` if the file needs
/// two passes: no readable summary (or one without channels), a transform channel (ego motion
/// looks ahead in time), several detection channels without message counts, or a channel
/// choice that fails (the first pass then reports it from the data section).
fn one_pass_plan<I: RecordSource>(input: &mut I, opts: &TrackOptions) -> Option<(Scan, Schedule)> {
    let file = &input.name().to_string();
    let Some((Record::Header(header), records)) = input.summary() else {
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
