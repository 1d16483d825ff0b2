//! The tracker core: pure, no I/O. Boxes, the Kalman filter, distances, matching, the track life
//! cycle and the configuration with its presets.
//!
//! The entry point is [`Tracker`]: create it from a [`TrackerConfig`], map labels to class ids
//! with [`Tracker::class_id`], and call [`Tracker::step`] once per frame. With the offline
//! options (`backfill`, `coast: gaps`) some reports wait for later frames: pass them through a
//! [`Lookback`].

pub mod angle;
pub mod bounds;
pub mod boxes;
pub mod choice;
pub mod confidence;
pub mod config;
pub mod ctrv;
pub mod error;
pub mod geometry;
pub mod kalman;
pub mod levers;
pub mod lookback;
pub mod matching;
pub mod nms;
pub mod presets;
pub mod track;
#[allow(clippy::module_inception)]
pub mod tracker;
pub mod two_point;
pub mod two_stage;

pub use boxes::{Box3, ClassId, Detection};
pub use choice::Choice;
pub use config::{BoxOrigin, ClassConfig, ConfigError, DistanceKind, MatcherKind, TrackerConfig};
pub use lookback::Lookback;
pub use presets::Preset;
pub use track::{ReportStatus, TrackReport};
pub use tracker::{StepError, Tracker, TrackerStats};
