//! In-process scoring: track the in-memory logs with a config, as `probmot track` would, and
//! evaluate the tracks with the library's protocol implementation (no temporary files).

use std::collections::BTreeMap;

use anyhow::{anyhow, Result};

use super::data::TuneLog;
use crate::eval::kitti::{self, KittiParams};
use crate::eval::nuscenes::{self, NuscenesParams};
use crate::eval::scene::Scene;
use crate::mcapio::LabelledBox;
use crate::tracker::{ClassConfig, Detection, Tracker, TrackerConfig};

/// The benchmark protocol whose headline metric a tune maximises.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Protocol {
    /// KITTI 3D MOT (AB3DMOT's evaluation): sAMOTA.
    Kitti,
    /// nuScenes tracking: AMOTA.
    Nuscenes,
}

/// Protocol and its parameters.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Scoring {
    /// Protocol.
    pub protocol: Protocol,
    /// KITTI: minimum 3D IoU of a match. nuScenes: unused (2 m centre distance).
    pub iou: f64,
}

impl Scoring {
    /// The classes the protocol evaluates.
    pub fn classes(&self) -> Vec<String> {
        match self.protocol {
            Protocol::Kitti => KittiParams::default().classes,
            Protocol::Nuscenes => NuscenesParams::default().classes,
        }
    }

    /// Name of the headline metric.
    pub fn metric(&self) -> &'static str {
        match self.protocol {
            Protocol::Kitti => "sAMOTA",
            Protocol::Nuscenes => "AMOTA",
        }
    }

    /// The headline metric per class over `scenes` (NaN for a class that is not evaluated, e.g.
    /// without ground truth or without tracks).
    pub fn evaluate(&self, scenes: &[Scene], classes: &[String]) -> BTreeMap<String, f64> {
        match self.protocol {
            Protocol::Kitti => {
                let p = KittiParams {
                    classes: classes.to_vec(),
                    min_overlap: self.iou,
                    ..KittiParams::default()
                };
                let r = kitti::evaluate(scenes, &p);
                classes
                    .iter()
                    .map(|c| {
                        let v = r.classes.get(c).map_or(f64::NAN, |m| m.samota);
                        (c.clone(), v)
                    })
                    .collect()
            }
            Protocol::Nuscenes => {
                let p = NuscenesParams {
                    classes: classes.to_vec(),
                    ..NuscenesParams::default()
                };
                let r = nuscenes::evaluate(scenes, &p);
                classes
                    .iter()
                    .map(|c| {
                        let v = r.classes.get(c).map_or(f64::NAN, |m| m.amota);
                        (c.clone(), v)
                    })
                    .collect()
            }
        }
    }
}

/// A config with only the entry of `label` (so that only that class is tracked).
pub fn single_class(cfg: &TrackerConfig, label: &str, cc: ClassConfig) -> TrackerConfig {
    TrackerConfig {
        name: cfg.name.clone(),
        dt_nominal: cfg.dt_nominal,
        classes: [(label.to_string(), cc)].into_iter().collect(),
        default: None,
    }
}

/// Tracks one log with `cfg`, as `probmot track` does for a log without ego motion: one tracker
/// step per detection message stamp, detections of labels the config does not know skipped,
/// each track carrying the 2D box of its last matched detection. Returns the scene (truth and
/// tracks) for the evaluation.
pub fn track_log(log: &TuneLog, cfg: &TrackerConfig) -> Result<Scene> {
    track_frames(log, cfg, |i| log.frames[i].truth.clone())
}

/// The KITTI attribute holding a truth box's type (as `probmot import kitti` writes it).
const KITTI_TYPE: &str = "kitti_type";

/// Whether the KITTI evaluation of class `label` reads truth box `b`: its type (the `kitti_type`
/// attribute, else the label, lower-cased) contains the class, its neighbouring class (`van` for
/// `car`, `person_sitting` for `pedestrian`) or `dontcare` (the rule of `eval::kitti`, repeated
/// here so that each candidate only copies the truth its class needs).
fn kitti_reads(label: &str, b: &LabelledBox) -> bool {
    let kind = b
        .attributes
        .get(KITTI_TYPE)
        .unwrap_or(&b.label)
        .to_lowercase();
    let neighbour = if label.contains("car") {
        "van"
    } else if label.contains("pedestrian") {
        "person_sitting"
    } else {
        label
    };
    kind.contains(label) || kind.contains(neighbour) || kind.contains("dontcare")
}

/// The truth of each frame of `log` that the evaluation of `label` reads (KITTI: the class, its
/// neighbour and DontCare regions; nuScenes: all of it).
pub fn class_truth(log: &TuneLog, label: &str, scoring: &Scoring) -> Vec<Vec<LabelledBox>> {
    log.frames
        .iter()
        .map(|f| match scoring.protocol {
            Protocol::Kitti => f
                .truth
                .iter()
                .filter(|b| kitti_reads(label, b))
                .cloned()
                .collect(),
            Protocol::Nuscenes => f.truth.clone(),
        })
        .collect()
}

/// [`track_log`] with the truth of frame `i` given by `truth(i)`.
pub fn track_frames(
    log: &TuneLog,
    cfg: &TrackerConfig,
    truth: impl Fn(usize) -> Vec<LabelledBox>,
) -> Result<Scene> {
    let mut tracker = Tracker::new(cfg.clone()).map_err(|e| anyhow!("{e}"))?;
    let mut dets: Vec<Detection> = Vec::new();
    let mut src: Vec<usize> = Vec::new();
    let mut buf = Vec::new();
    // Image box of each track's last matched detection, by track id.
    let mut image: Vec<Option<[f64; 4]>> = Vec::new();
    let mut frames = Vec::with_capacity(log.frames.len());
    for (fi, f) in log.frames.iter().enumerate() {
        let mut tracks = Vec::new();
        if f.has_detections {
            dets.clear();
            src.clear();
            for (i, d) in f.detections.iter().enumerate() {
                if let Some(class) = tracker.class_id(&d.label) {
                    dets.push(Detection {
                        bbox: d.bbox,
                        class,
                        score: d.score,
                    });
                    src.push(i);
                }
            }
            let reports = tracker
                .step(f.stamp, &dets)
                .map_err(|e| anyhow!("{}: stamp {}: {e}", log.name, f.stamp))?;
            buf.clear();
            buf.extend_from_slice(reports);
            for r in &buf {
                let id = r.id as usize;
                if image.len() <= id {
                    image.resize(id + 1, None);
                }
                if let Some(d) = r.detection {
                    image[id] = f.detections[src[d as usize]].image_box;
                }
                tracks.push(LabelledBox {
                    id: r.id,
                    label: tracker.label(r.class).to_string(),
                    center: r.bbox.center,
                    size: r.bbox.size,
                    yaw: r.bbox.yaw,
                    score: r.score,
                    attributes: BTreeMap::new(),
                    image_box: image[id],
                    ..Default::default()
                });
            }
        }
        frames.push((f.stamp, truth(fi), tracks));
    }
    Ok(Scene {
        name: log.name.clone(),
        frames,
    })
}

/// The headline metric of one class when `logs` are tracked with `cfg`.
pub fn score_class(
    logs: &[&TuneLog],
    cfg: &TrackerConfig,
    label: &str,
    scoring: &Scoring,
) -> Result<f64> {
    let truth: Vec<_> = logs
        .iter()
        .map(|l| class_truth(l, label, scoring))
        .collect();
    score_class_with(logs, &truth, cfg, label, scoring)
}

/// [`score_class`] with each log's per-frame truth prepared by [`class_truth`] (once per tune).
pub fn score_class_with(
    logs: &[&TuneLog],
    truth: &[Vec<Vec<LabelledBox>>],
    cfg: &TrackerConfig,
    label: &str,
    scoring: &Scoring,
) -> Result<f64> {
    let scenes = logs
        .iter()
        .zip(truth)
        .map(|(l, t)| track_frames(l, cfg, |i| t[i].clone()))
        .collect::<Result<Vec<_>>>()?;
    let classes = [label.to_string()];
    Ok(scoring.evaluate(&scenes, &classes)[label])
}
