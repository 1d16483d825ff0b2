//! The logs a tune works on, read once into memory: per frame the ground truth (as the
//! evaluation sees it) and the detections (as the tracker sees them, with the 2D box the KITTI
//! protocol needs).

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::{bail, Context, Result};

use crate::eval::scene::read_tracks_topic;
use crate::fit::{FitAccumulator, FitFrame};
use crate::mcapio::topic::for_each_message;
use crate::mcapio::LabelledBox;
use crate::msgs::{self, Detections3D};
use crate::tracker::Box3;

/// One detection, reduced to what tracking and scoring need.
#[derive(Debug, Clone, PartialEq)]
pub struct TuneDet {
    /// Class label.
    pub label: String,
    /// Box.
    pub bbox: Box3,
    /// Detector score.
    pub score: f64,
    /// 2D box (KITTI), carried to the track it updates.
    pub image_box: Option<[f64; 4]>,
}

/// One frame: a stamp of either channel.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TuneFrame {
    /// Stamp, nanoseconds.
    pub stamp: u64,
    /// Whether a ground-truth message has this stamp (the fit's frames).
    pub has_truth: bool,
    /// Whether a detection message has this stamp (the tracker steps only on those frames).
    pub has_detections: bool,
    /// Detections of this stamp (valid boxes only).
    pub detections: Vec<TuneDet>,
    /// Ground-truth boxes of this stamp.
    pub truth: Vec<LabelledBox>,
}

/// One log in memory.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TuneLog {
    /// File name (scene name in reports).
    pub name: String,
    /// Frames in stamp order.
    pub frames: Vec<TuneFrame>,
}

impl TuneLog {
    /// Reads a log: truth from `truth_topic` (`probmot.Tracks3D` with the true instance ids),
    /// detections from `detections_topic` (`probmot.Detections3D`). Errors name the file.
    pub fn load(path: &Path, truth_topic: &str, detections_topic: &str) -> Result<TuneLog> {
        let file = path.display().to_string();
        let truth = read_tracks_topic(path, truth_topic)?;
        if truth.is_empty() {
            bail!("{file}: topic {truth_topic} (ground truth) has no messages; tune needs logs with ground truth, as `probmot import kitti|nuscenes` writes them");
        }
        let mut frames: BTreeMap<u64, TuneFrame> = BTreeMap::new();
        for (stamp, boxes) in truth {
            let f = frames.entry(stamp).or_default();
            f.stamp = stamp;
            f.has_truth = true;
            f.truth.extend(boxes);
        }
        let mut n_msgs = 0u64;
        for_each_message(
            path,
            detections_topic,
            msgs::DETECTIONS_SCHEMA,
            |header, m: Detections3D| {
                let stamp = m.stamp.unwrap_or(header.log_time);
                let f = frames.entry(stamp).or_default();
                f.stamp = stamp;
                f.has_detections = true;
                n_msgs += 1;
                f.detections
                    .extend(m.detections.iter().filter_map(|d| -> Option<TuneDet> {
                        let (c, s) = (d.center?, d.size?);
                        let bbox = Box3 {
                            center: [c.x, c.y, c.z],
                            yaw: d.yaw,
                            size: [s.length, s.width, s.height],
                        };
                        (bbox.is_valid() && d.score.is_finite()).then(|| TuneDet {
                            label: d.label.clone(),
                            bbox,
                            score: d.score,
                            image_box: d.image_box.map(|b| [b.x1, b.y1, b.x2, b.y2]),
                        })
                    }));
                Ok(())
            },
            |_| Ok(()),
        )
        .with_context(|| format!("reading detections from {file}"))?;
        if n_msgs == 0 {
            bail!("{file}: topic {detections_topic} (detections) has no messages");
        }
        Ok(TuneLog {
            name: path
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or(file),
            frames: frames.into_values().collect(),
        })
    }

    /// Feeds the log to a noise fit as `probmot fit` reads it (truth stamps as frames, boxes
    /// without DontCare regions, a detection stamp without truth only counted), one frame at a
    /// time: the fit never holds a second copy of the log.
    pub fn feed_fit(&self, acc: &mut FitAccumulator) {
        // The fit reads geometry and labels only.
        let fit_box = |id, label: &str, b: Box3| LabelledBox {
            id,
            label: label.to_string(),
            center: b.center,
            size: b.size,
            yaw: b.yaw,
            ..Default::default()
        };
        let mut state = acc.begin_log(&self.name);
        let mut unmatched = 0;
        for f in &self.frames {
            if !f.has_truth {
                unmatched += u64::from(f.has_detections);
                continue;
            }
            let truth = (f.truth.iter().filter(|b| b.id != 0))
                .map(|b| {
                    let (center, size, yaw) = (b.center, b.size, b.yaw);
                    fit_box(b.id, &b.label, Box3 { center, size, yaw })
                })
                .collect();
            let detections = (f.detections.iter())
                .map(|d| fit_box(0, &d.label, d.bbox))
                .collect();
            let frame = FitFrame {
                stamp: f.stamp,
                truth,
                detections,
            };
            acc.push_frame(&mut state, frame);
        }
        acc.add_unmatched(unmatched);
    }

    /// Scores of this log's detections of one class.
    pub fn scores<'a>(&'a self, label: &'a str) -> impl Iterator<Item = f64> + 'a {
        self.frames
            .iter()
            .flat_map(|f| f.detections.iter())
            .filter(move |d| d.label == label)
            .map(|d| d.score)
    }
}
