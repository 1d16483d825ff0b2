//! Settings and summary of a `track` run (shared by the file adapter and the session).

use std::collections::BTreeMap;

use super::detections::InputCounters;
use super::ego::{EgoOptions, EgoSummary};
use crate::mcapio::writer::OutputCompression;
use crate::tracker::TrackerConfig;

/// Settings of one `track` run.
#[derive(Debug, Clone)]
pub struct TrackOptions {
    /// Detection topics; empty: every channel of a supported detection schema
    /// ([`crate::msgs::detection_source::is_detection_schema`]).
    pub detection_topics: Vec<String>,
    /// Topic of the tracks channel written; `None`: the format's default
    /// ([`super::tracks_format::TracksFormat::default_topic`]: `/tracks`, or Autoware's tracking
    /// topic for Autoware tracks).
    pub tracks_topic: Option<String>,
    /// Message type of the tracks channel; `None`: by input
    /// ([`super::tracks_format::TracksFormat::resolve`]).
    pub tracks_format: Option<super::tracks_format::TracksFormat>,
    /// Tracker configuration.
    pub config: TrackerConfig,
    /// Copy only, no tracking (for measuring the cost of I/O).
    pub no_track: bool,
    /// Turn every skipped box into an error, and a file cut short too.
    pub strict: bool,
    /// Largest number of boxes accepted in one detection message; more is an error (a frame
    /// that large is a corrupted or misrouted message, and would stall the tracker).
    pub max_detections_per_message: usize,
    /// Ego motion: the fixed frame and the `--tracks-frame ego` output (see [`super::ego`]).
    pub ego: EgoOptions,
    /// The `foxglove.SceneUpdate` output channel (boxes for the Foxglove 3D panel).
    pub scene: SceneOutput,
    /// Chunk compression of the output.
    pub compression: OutputCompression,
    /// Write and compress the output on a thread of its own ([`crate::mcapio::background::BackgroundOutput`]), so that it
    /// overlaps with reading and tracking: faster for one file when a core is spare; when files
    /// already run in parallel on every core, writing on the file's own thread costs less.
    pub background_writer: bool,
}

impl TrackOptions {
    /// The options of `probmot track` without flags, with the tracker configuration `config`:
    /// every detection channel, the format's tracks topic, the scene channel by default, zstd
    /// output written on the caller's thread.
    pub fn new(config: TrackerConfig) -> TrackOptions {
        TrackOptions {
            detection_topics: Vec::new(),
            tracks_topic: None,
            tracks_format: None,
            config,
            no_track: false,
            strict: false,
            max_detections_per_message: DEFAULT_MAX_DETECTIONS,
            ego: EgoOptions::default(),
            scene: SceneOutput::Default,
            compression: OutputCompression::default(),
            background_writer: false,
        }
    }

    /// The topic of the tracks channel of a run whose tracks are written as `format`.
    pub fn tracks_topic_for(&self, format: super::tracks_format::TracksFormat) -> &str {
        self.tracks_topic
            .as_deref()
            .unwrap_or_else(|| format.default_topic())
    }
}

/// Whether and where `track` writes the tracks as `foxglove.SceneUpdate` beside the tracks
/// channel, so a tracked log shows boxes in Foxglove without extra files.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub enum SceneOutput {
    /// On `<tracks-topic>/scene` ([`SCENE_TOPIC_SUFFIX`]) when the tracks are `probmot.Tracks3D`;
    /// none with ROS 2 tracks, whose bag must stay decodable by ROS 2 tools (CDR only).
    #[default]
    Default,
    /// On this topic (`--scene-topic`); refused with ROS 2 tracks.
    Topic(String),
    /// None (`--no-scene`).
    Off,
}

/// Suffix of the tracks topic for the default scene topic (`/tracks` → `/tracks/scene`).
pub const SCENE_TOPIC_SUFFIX: &str = "/scene";

impl SceneOutput {
    /// The scene topic of a run with tracks on `tracks_topic` written as `format`, or `None`.
    pub fn topic(
        &self,
        tracks_topic: &str,
        format: super::tracks_format::TracksFormat,
    ) -> Option<String> {
        match self {
            SceneOutput::Default if format == super::tracks_format::TracksFormat::Probmot => {
                Some(format!("{tracks_topic}{SCENE_TOPIC_SUFFIX}"))
            }
            SceneOutput::Default | SceneOutput::Off => None,
            SceneOutput::Topic(t) => Some(t.clone()),
        }
    }
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
    /// Mean number of reported frames per confirmed track (with the offline reporting options:
    /// written boxes per written track).
    pub mean_track_length: Option<f64>,
    /// Input messages copied.
    pub messages_copied: u64,
    /// Attachments copied.
    pub attachments: u64,
    /// Metadata records copied.
    pub metadata: u64,
    /// Tracks messages written.
    pub tracks_messages: u64,
    /// Topic of the tracks channel (not in the JSON summary, whose fields stay as they were).
    #[serde(skip)]
    pub tracks_topic: String,
    /// Per detection topic, messages whose stamp is earlier than the previous message's.
    pub stamps_backwards: BTreeMap<String, u64>,
    /// Detection messages that sharing a stamp with a message of another topic were merged.
    pub merged_messages: u64,
    /// Ego-motion compensation: fixed frame, transforms, messages moved or skipped.
    pub ego: EgoSummary,
    /// Warnings for the user.
    pub warnings: Vec<String>,
    /// Passes over the input: 1 (the summary section sufficed, or `--no-track`) or 2 (a first
    /// pass learned the frames); see [`super::track::track_file`].
    pub passes: u8,
    /// Wall time in seconds.
    pub wall_time_s: f64,
}

impl TrackSummary {
    /// The one-line summary `track` prints (no trailing newline).
    pub fn line(&self) -> String {
        let classes: Vec<String> = (self.detections.per_label.iter())
            .map(|(l, n)| format!("{l} {n}"))
            .collect();
        let total: u64 = self.detections.per_label.values().sum();
        format!(
            "{}: {} frames, {} detections ({}), {} tracks born, {} confirmed, mean track length {} frames, {} boxes skipped, {} messages copied, {:.2} s ({} {})",
            self.output,
            self.frames,
            total,
            if classes.is_empty() { "none".to_string() } else { classes.join(", ") },
            self.tracks_born,
            self.tracks_confirmed,
            self.mean_track_length.map(|v| format!("{v:.1}")).unwrap_or_else(|| "-".into()),
            self.detections.total_skipped() + self.ego.boxes_without_transform,
            self.messages_copied,
            self.wall_time_s,
            self.passes,
            if self.passes == 1 { "pass" } else { "passes" }
        )
    }
}
