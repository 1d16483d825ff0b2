//! The logs a tune works on, read once into memory: per frame the ground truth (as the
//! evaluation sees it) and the detections (as the tracker sees them, with the 2D box the KITTI
//! protocol needs).

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

use anyhow::{bail, Context, Result};

use crate::eval::kitti_box::{KittiBox, KittiBoxes};
use crate::eval::scene::read_kitti_topic;
use crate::fit::stats::median;
use crate::fit::timing::interval_s;
use crate::fit::{FitAccumulator, FitFrame};
use crate::mcapio::recording::{
    for_each_frame, no_channel, Boxes, FrameEvent, TopicKind, TopicRequest,
};
use crate::mcapio::LabelledBox;
use crate::msgs::detection_frame::{check_box, count_skips, SkipReason};
use crate::tracker::Box3;

/// One detection, reduced to what tracking and scoring need.
#[derive(Debug, Clone, PartialEq)]
pub struct TuneDet {
    /// Class label (shared by the log's detections and truth with that label).
    pub label: Arc<str>,
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
    /// Ground-truth boxes of this stamp, as the evaluations read them (KITTI's fields with the
    /// id, label, box and score: what both protocols and the fit read), a few times smaller
    /// than whole boxes with their attribute maps.
    pub truth: Vec<KittiBox>,
}

/// One log in memory.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TuneLog {
    /// File name (scene name in reports).
    pub name: String,
    /// Frames in stamp order.
    pub frames: Vec<TuneFrame>,
    /// Detections left out when read, by reason, as `probmot track` skips them (no centre or
    /// size, a non-finite field or score, a non-positive size).
    pub skipped_detections: BTreeMap<SkipReason, u64>,
}

/// Frame periods of `logs` from their truth stamps, seconds: each log's median interval (logs
/// with two truth frames or more) and the median of every interval of every log (`None` without
/// any interval).
pub fn frame_periods<'a>(
    logs: impl IntoIterator<Item = &'a TuneLog>,
) -> (Vec<(&'a str, f64)>, Option<f64>) {
    let mut all = Vec::new();
    let mut each = Vec::new();
    for l in logs {
        let stamps: Vec<u64> = (l.frames.iter().filter(|f| f.has_truth))
            .map(|f| f.stamp)
            .collect();
        let dts: Vec<f64> = (stamps.windows(2))
            .map(|w| interval_s(w[0], w[1]))
            .collect();
        all.extend(&dts);
        if let Some(m) = median(&dts) {
            each.push((l.name.as_str(), m));
        }
    }
    (each, median(&all))
}

impl TuneLog {
    /// Reads a log: truth from `truth_topic` (`probmot.Tracks3D` with the true instance ids),
    /// detections from `detections_topic` (any detection input `track` reads). Errors name the
    /// file.
    pub fn load(path: &Path, truth_topic: &str, detections_topic: &str) -> Result<TuneLog> {
        let file = path.display().to_string();
        let mut shared = KittiBoxes::default();
        let truth = read_kitti_topic(path, truth_topic, &mut shared)?;
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
        let (mut n_msgs, mut skipped) = (0u64, BTreeMap::new());
        let request = TopicRequest {
            topic: detections_topic.to_string(),
            kind: TopicKind::Detections,
            role: "detections".to_string(),
        };
        let mut found = false;
        let topics = for_each_frame(path, std::slice::from_ref(&request), |event, _| {
            let (stamp, detections) = match event {
                FrameEvent::Channel(_) => {
                    found = true;
                    return Ok(());
                }
                FrameEvent::Frame(_, m) => match m.boxes {
                    Boxes::Detections(d) => {
                        count_skips(&mut skipped, &m.skipped);
                        (m.stamp, d)
                    }
                    Boxes::Tracks(_) => unreachable!("a detections request gives detections"),
                },
            };
            let f = frames.entry(stamp).or_default();
            f.stamp = stamp;
            f.has_detections = true;
            n_msgs += 1;
            // Exactly the message's boxes: grown push by push, a frame's vector would keep
            // up to twice its size for as long as the tune runs.
            f.detections.reserve_exact(detections.len());
            for d in &detections {
                match check_box(d) {
                    Ok(bbox) => f.detections.push(TuneDet {
                        label: shared.shared(&d.label),
                        bbox,
                        score: d.score,
                        image_box: d.image_box.map(|b| [b.x1, b.y1, b.x2, b.y2]),
                    }),
                    Err(reason) => *skipped.entry(reason).or_default() += 1,
                }
            }
            Ok(())
        })
        .with_context(|| format!("reading detections from {file}"))?;
        if !found {
            let e = no_channel(&file, detections_topic, &topics);
            return Err(e.context(format!("reading detections from {file}")));
        }
        if n_msgs == 0 {
            bail!("{file}: topic {detections_topic} (detections) has no messages");
        }
        Ok(TuneLog {
            name: path
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or(file),
            frames: frames.into_values().collect(),
            skipped_detections: skipped,
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
                .map(|b| fit_box(b.id, b.label(), b.box3))
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
            .filter(move |d| &*d.label == label)
            .map(|d| d.score)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::data::assemble_frames;
    use crate::fit::{fit, fit_gathered, FitOptions, YawMode};

    fn truth(id: u64, label: &str, x: f64) -> KittiBox {
        KittiBox::from(&LabelledBox {
            id,
            label: label.into(),
            center: [x, 0.5 * x, 0.8],
            size: [4.5, 1.9, 1.6],
            yaw: 0.01 * x,
            score: 1.0,
            ..Default::default()
        })
    }

    /// A log with a detection stamp without truth, a truth stamp without detections and a
    /// box without id (a DontCare region).
    fn log() -> TuneLog {
        let frames = (0..12u64)
            .map(|i| {
                let x = i as f64;
                let has_truth = i != 3;
                let has_detections = i != 7;
                let mut f = TuneFrame {
                    stamp: 1_000 + 100_000_000 * i,
                    has_truth,
                    has_detections,
                    ..Default::default()
                };
                if has_truth {
                    f.truth = vec![truth(1, "car", x), truth(2, "car", 20.0 - x)];
                    f.truth.push(truth(0, "dontcare", 5.0));
                }
                if has_detections {
                    f.detections = [(x + 0.1, "car"), (20.2 - x, "car"), (9.0, "truck")]
                        .into_iter()
                        .map(|(x, label)| TuneDet {
                            label: label.into(),
                            bbox: Box3 {
                                center: [x, 0.5 * x, 0.7],
                                yaw: 0.01 * x,
                                size: [4.4, 1.9, 1.6],
                            },
                            score: 0.8,
                            image_box: None,
                        })
                        .collect();
                }
                f
            })
            .collect();
        TuneLog {
            name: "log".into(),
            frames,
            skipped_detections: BTreeMap::new(),
        }
    }

    /// Fed frame by frame, the fit gives the report of the whole log assembled as
    /// `probmot fit` reads a file.
    #[test]
    fn feeding_the_fit_equals_the_assembled_log() {
        let log = log();
        let as_fit_box = |id, label: &str, b: Box3| LabelledBox {
            id,
            label: label.into(),
            center: b.center,
            size: b.size,
            yaw: b.yaw,
            ..Default::default()
        };
        let truth = (log.frames.iter().filter(|f| f.has_truth))
            .map(|f| {
                let boxes = (f.truth.iter().filter(|b| b.id != 0))
                    .map(|b| as_fit_box(b.id, b.label(), b.box3));
                (f.stamp, boxes.collect())
            })
            .collect();
        let dets = (log.frames.iter().filter(|f| f.has_detections))
            .map(|f| {
                let boxes = f.detections.iter().map(|d| as_fit_box(0, &d.label, d.bbox));
                (f.stamp, boxes.collect())
            })
            .collect();
        let options = FitOptions {
            dt_nominal: 0.1,
            yaw: YawMode::Folded,
            min_samples: 2,
        };
        let want = fit(&[assemble_frames("log", truth, dets)], &options);
        let mut acc = FitAccumulator::new();
        log.feed_fit(&mut acc);
        assert_eq!(acc.frame_period().unwrap().median_s, 0.1);
        let got = fit_gathered(acc, &options);
        assert_eq!(got, want);
        assert_eq!((got.frames, got.unmatched_detection_messages), (11, 1));
        assert_eq!((got.truth_boxes, got.detections), (22, 30));
    }
}
