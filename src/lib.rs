//! probmot: probabilistic 3D multi-object tracking (Chiu et al. 2019) for MCAP recordings.
//!
//! [`tracker`] is the pure tracker core, a sans-I/O state machine: frames of detections in,
//! tracks out, no file or clock of its own, so the command-line tool, the tuner and a user's
//! own program drive the same code. Around it, each depending on the core and never the other
//! way round: [`mcapio`] and [`msgs`] read and write MCAP and decode the detection schemas,
//! [`pipeline`] runs the commands (`track`, `import`, `export`, ...) over files, [`eval`]
//! scores tracks with the nuScenes and KITTI protocols, [`fit`] and [`tune`] choose settings
//! from labelled logs, [`formats`] holds the dataset formats, [`transforms`] the ego motion,
//! [`sim`] the synthetic drives and [`viz`] the pictures and Rerun recordings.
//! `docs/development.md` has the module map and the layering rules.
//!
//! Tracking the detections of a sample log with the library (what `probmot track` does,
//! without writing the output):
//!
//! ```
//! use probmot::mcapio::recording::{frames, Boxes, TopicKind, TopicRequest};
//! use probmot::msgs::detection_frame::check_box;
//! use probmot::tracker::{Detection, Tracker, TrackerConfig};
//!
//! let log = concat!(env!("CARGO_MANIFEST_DIR"), "/sample_logs/turning-car.mcap");
//! let detections = TopicRequest {
//!     topic: "/detections".into(),
//!     kind: TopicKind::Detections,
//!     role: "detections".into(),
//! };
//! let read = frames(log.as_ref(), &[detections])?;
//! let mut tracker = Tracker::new(TrackerConfig::preset("nuscenes-chiu2019")?)?;
//! let mut ids = std::collections::BTreeSet::new();
//! for frame in read.frames[0].as_deref().unwrap_or_default() {
//!     let Boxes::Detections(boxes) = &frame.boxes else { continue };
//!     let dets: Vec<Detection> = (boxes.iter())
//!         .filter_map(|d| {
//!             let class = tracker.class_id(&d.label)?;
//!             Some(Detection { bbox: check_box(d).ok()?, class, score: d.score })
//!         })
//!         .collect();
//!     ids.extend(tracker.step(frame.stamp, &dets)?.iter().map(|t| t.id));
//! }
//! // Five cars are in the log (its ground truth); six ids are reported over the 40 frames,
//! // as in `probmot track`'s output of the same log.
//! assert_eq!(ids.len(), 6, "{ids:?}");
//! # Ok::<(), anyhow::Error>(())
//! ```

#![warn(missing_docs)]

pub mod eval;
pub mod fit;
pub mod formats;
pub mod mcapio;
pub mod msgs;
pub mod pipeline;
pub mod sim;
pub mod tracker;
pub mod transforms;
pub mod tune;
pub mod viz;
