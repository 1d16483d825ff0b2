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
//!
//! Embedding the tracking in a program of your own (a ROS node, a test harness), with no MCAP
//! file: a [`pipeline::track_session::TrackSession`] takes frames of detections made in code and
//! hands out each frame's tracks (`cargo run --example track_in_code` is a longer example):
//!
//! ```
//! use probmot::msgs::detection_frame::{DetectionBox, DetectionFrame};
//! use probmot::pipeline::track_session::{SessionOptions, TrackSession};
//! use probmot::tracker::{Box3, TrackerConfig};
//!
//! let config = TrackerConfig::preset("nuscenes-chiu2019")?;
//! let mut session = TrackSession::new(config, SessionOptions::default())?;
//! let mut ids = std::collections::BTreeSet::new();
//! for i in 0..10u32 {
//!     // One car driving along x at 4 m/s, seen every 0.5 s (the preset's frame rate).
//!     let car = DetectionBox {
//!         index: 0,
//!         bbox: Box3 { center: [2.0 * f64::from(i), 0.0, 0.0], yaw: 0.0, size: [4.0, 2.0, 1.5] },
//!         label: "car".into(),
//!         score: 0.9,
//!         velocity: None,
//!         image_box: None,
//!         attributes: Default::default(),
//!         needs_own_entry: false,
//!     };
//!     let stamp = 1_000_000_000 + u64::from(i) * 500_000_000;
//!     let frame = DetectionFrame { stamp, frame_id: "map".into(), boxes: vec![car], rejected: vec![] };
//!     session.track(frame)?;
//!     while let Some(tracks) = session.next_frame() {
//!         ids.extend(tracks.tracks.iter().map(|t| t.id));
//!     }
//! }
//! let summary = session.finish();
//! assert_eq!((summary.frames, summary.tracks_confirmed), (10, 1));
//! assert_eq!(ids.len(), 1, "one car, one track: {ids:?}");
//! assert!(summary.warnings.is_empty(), "{:?}", summary.warnings);
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
