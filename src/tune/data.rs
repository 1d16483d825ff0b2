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
    /// file. Autoware classes that are none of probmot's are skipped as `track` skips them with
    /// a config without entries of their names (every preset); [`TuneLog::load_for`] takes the
    /// config's entries.
    pub fn load(path: &Path, truth_topic: &str, detections_topic: &str) -> Result<TuneLog> {
        Self::load_for(path, (truth_topic, detections_topic), &|_| false)
    }

    /// [`TuneLog::load`], reading an Autoware class that is none of probmot's only when
    /// `has_entry` (the config has an entry of its name), as `track` tracks it only then.
    pub fn load_for(
        path: &Path,
        (truth_topic, detections_topic): (&str, &str),
        has_entry: &dyn Fn(&str) -> bool,
    ) -> Result<TuneLog> {
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
            let mut m = match event {
                FrameEvent::Channel(_) => {
                    found = true;
                    return Ok(());
                }
                FrameEvent::Frame(_, m) => m,
            };
            m.skip_classes_without_entry(has_entry);
            count_skips(&mut skipped, &m.skipped);
            let (stamp, detections) = match m.boxes {
                Boxes::Detections(d) => (m.stamp, d),
                Boxes::Tracks(_) => unreachable!("a detections request gives detections"),
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
    use std::collections::BTreeSet;

    use super::*;
    use crate::fit::data::assemble_frames;
    use crate::fit::{fit, fit_gathered, FitOptions, YawMode};
    use crate::msgs::detection_frame::describe_skips;

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

    /// A log of Autoware `DetectedObjects` (4 frames of a car, an UNKNOWN object and an ANIMAL
    /// of length 0) with probmot ground truth for the car and the UNKNOWN object.
    fn write_autoware_log(path: &Path) {
        use crate::mcapio::writer::{AtomicOutput, OutputOptions};
        use crate::msgs::autoware::tests::{car, detected_objects, MSG_TEXT};
        use crate::msgs::autoware::{DETECTED_SCHEMA_NAMES, DETECTION_TOPIC};
        use crate::msgs::{size3, v3, Track3D, Tracks3D, DESCRIPTOR_SET, TRACKS_SCHEMA};
        let mut out = AtomicOutput::create(path, &OutputOptions::default()).unwrap();
        let w = &mut out.writer;
        let aw = (w.add_schema(DETECTED_SCHEMA_NAMES[0], "ros2msg", MSG_TEXT.as_bytes())).unwrap();
        let tr = w
            .add_schema(TRACKS_SCHEMA, "protobuf", DESCRIPTOR_SET)
            .unwrap();
        let none = &BTreeMap::new();
        let dets = w.add_channel(aw, DETECTION_TOPIC, "cdr", none).unwrap();
        let truth = w
            .add_channel(tr, "/ground_truth", "protobuf", none)
            .unwrap();
        for i in 0..4u64 {
            let stamp = 1_000_000_000 + 100_000_000 * i;
            let x = i as f64;
            let mut unknown = car(20.0 + x, 5.0, 0.0);
            unknown.classes = vec![(0, 1.0)];
            let mut animal = car(30.0, -5.0, 0.0);
            animal.classes = vec![(8, 1.0)];
            animal.dimensions[0] = 0.0;
            let objects = [car(10.0 + x, 0.0, 0.0), unknown, animal];
            let header = |channel_id| mcap::records::MessageHeader {
                channel_id,
                sequence: 0,
                log_time: stamp,
                publish_time: stamp,
            };
            let data = detected_objects(stamp, "base_link", &objects);
            w.write_to_known_channel(&header(dets), &data).unwrap();
            let track = |id, label: &str, x: f64| Track3D {
                id,
                label: label.into(),
                center: Some(v3([x, 0.0, 0.8])),
                size: Some(size3([4.5, 1.9, 1.6])),
                ..Default::default()
            };
            let m = Tracks3D {
                stamp,
                tracks: vec![track(1, "car", 10.0 + x), track(2, "unknown", 20.0 + x)],
                ..Default::default()
            };
            let mut data = Vec::new();
            crate::msgs::encode_into(&m, &mut data);
            w.write_to_known_channel(&header(truth), &data).unwrap();
        }
        out.commit().unwrap();
    }

    /// The skip counts of the Autoware log without and with a config entry `unknown`.
    fn autoware_skips() -> [BTreeMap<SkipReason, u64>; 2] {
        let (size, class) = (SkipReason::NonPositiveSize, SkipReason::ClassWithoutEntry);
        [
            BTreeMap::from([(size, 4), (class, 4)]),
            BTreeMap::from([(size, 4)]),
        ]
    }

    /// Autoware classes that are none of probmot's are read by fit (whole or streamed) and
    /// tune as `track` reads them: without a config entry of their name, left out and counted
    /// (`class_without_entry`); with one, kept. A box the check refuses is counted for that,
    /// whatever its class.
    #[test]
    fn autoware_classes_without_entry_are_skipped_as_track_skips_them() {
        use crate::fit::load::{load_log, load_log_progress, stream_log};
        use crate::msgs::autoware::DETECTION_TOPIC;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("autoware.mcap");
        write_autoware_log(&path);
        let topics = ("/ground_truth", DETECTION_TOPIC);
        let [without, with] = autoware_skips();
        let unknown: &dyn Fn(&str) -> bool = &|label| label == "unknown";
        let no_entry: &dyn Fn(&str) -> bool = &|_| false;
        let fit_labels = |log: &crate::fit::data::FitLog| {
            let boxes = log.frames.iter().flat_map(|f| &f.detections);
            boxes.map(|b| b.label.clone()).collect::<BTreeSet<_>>()
        };
        let tune_labels = |log: &TuneLog| {
            let boxes = log.frames.iter().flat_map(|f| &f.detections);
            boxes.map(|d| d.label.to_string()).collect::<BTreeSet<_>>()
        };
        let car = BTreeSet::from(["car".to_string()]);
        let both = BTreeSet::from(["car".to_string(), "unknown".to_string()]);

        let log = load_log(&path, topics.0, topics.1).unwrap();
        let read = (&log.skipped_detections, fit_labels(&log));
        assert_eq!(read, (&without, car.clone()));
        let log = load_log_progress(&path, topics, unknown, &|_| {}).unwrap();
        let read = (&log.skipped_detections, fit_labels(&log));
        assert_eq!(read, (&with, both.clone()));
        let options = FitOptions {
            dt_nominal: 0.1,
            yaw: YawMode::Wrapped,
            min_samples: 1,
        };
        for (has_entry, skipped, detections) in [(no_entry, &without, 4), (unknown, &with, 8)] {
            let mut acc = FitAccumulator::new();
            stream_log(&mut acc, &path, topics, has_entry, &|_| {}).unwrap();
            let report = fit_gathered(acc, &options);
            assert_eq!(report.detections, detections);
            let warning = describe_skips(skipped);
            let warned = report.warnings.iter().any(|w| w.contains(&warning));
            assert!(warned, "{report:?}");
        }

        let log = TuneLog::load(&path, topics.0, topics.1).unwrap();
        let read = (&log.skipped_detections, tune_labels(&log));
        assert_eq!(read, (&without, car));
        let log = TuneLog::load_for(&path, topics, unknown).unwrap();
        let read = (&log.skipped_detections, tune_labels(&log));
        assert_eq!(read, (&with, both));
    }

    /// `probmot fit` and `probmot tune` read the Autoware classes with the base config's
    /// entries.
    #[test]
    fn fit_and_tune_files_take_the_base_configs_entries() {
        use crate::fit::files::{fit_files, FitFilesOptions};
        use crate::msgs::autoware::DETECTION_TOPIC;
        use crate::tune::files::{tune_files, BaseChoice, TuneFilesOptions};
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("autoware.mcap");
        write_autoware_log(&path);
        let inputs = [path.clone()];
        for (unknown_entry, skipped) in [false, true].into_iter().zip(autoware_skips()) {
            let mut base = crate::tracker::Preset::NuscenesChiu2019.config().unwrap();
            if unknown_entry {
                let entry = base.classes["car"].clone();
                base.classes.insert("unknown".into(), entry);
            }
            let base_path = dir.path().join("base.json");
            std::fs::write(&base_path, base.to_json()).unwrap();
            let warning = describe_skips(&skipped);

            let o = FitFilesOptions {
                base_config: Some(base_path.clone()),
                detections_topic: DETECTION_TOPIC.into(),
                ..Default::default()
            };
            let fit = fit_files(&inputs, &dir.path().join("fit.json"), &o, &|_| {});
            let warnings = fit.unwrap().report.warnings;
            assert!(
                warnings.iter().any(|w| w.contains(&warning)),
                "{warnings:?}"
            );

            let mut o = TuneFilesOptions {
                base: BaseChoice {
                    file: Some(base_path),
                    ..Default::default()
                },
                protocol: Some(crate::tune::Protocol::Nuscenes),
                folds: 1,
                detections_topic: DETECTION_TOPIC.into(),
                ..Default::default()
            };
            (o.limits.budget, o.limits.rounds) = (1, 1);
            let out = dir.path().join("tune.json");
            let tune = tune_files(&inputs, &out, &o, &|_| {}, &|_| {});
            let warnings = tune.unwrap().warnings;
            assert!(
                warnings.iter().any(|w| w.contains(&warning)),
                "{warnings:?}"
            );
        }
    }
}
