//! In-process scoring: track the in-memory logs with a config, as `probmot track` would, and
//! evaluate the tracks with the library's protocol implementation (no temporary files).

use std::collections::{BTreeMap, HashSet};

use anyhow::{anyhow, Result};

use super::data::TuneLog;
use crate::eval::columns::{ColumnScene, Side};
use crate::eval::kitti::{self, KittiParams, MeanScores, RowKind, TrackRow};
use crate::eval::kitti_box::{KittiBox, KittiBoxes};
use crate::eval::nuscenes::{self, NuscenesParams};
use crate::eval::scene::Scene;
use crate::mcapio::LabelledBox;
use crate::tracker::{ClassConfig, Detection, Lookback, TrackReport, Tracker, TrackerConfig};

/// The benchmark protocol whose headline metric a tune maximises.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Protocol {
    /// KITTI 3D MOT (AB3DMOT's evaluation): sAMOTA.
    Kitti,
    /// nuScenes tracking: AMOTA.
    Nuscenes,
}

impl crate::tracker::choice::Choice for Protocol {
    const VALUES: &'static [Self] = &[Protocol::Kitti, Protocol::Nuscenes];

    fn name(self) -> &'static str {
        match self {
            Protocol::Kitti => "kitti",
            Protocol::Nuscenes => "nuscenes",
        }
    }

    /// None: the option's own help names both.
    fn description(self) -> &'static str {
        ""
    }
}

/// Protocol and its parameters.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Scoring {
    /// Protocol.
    pub protocol: Protocol,
    /// KITTI: minimum 3D IoU of a match. nuScenes: unused (2 m centre distance).
    pub iou: f64,
    /// KITTI: how the search's objective computes the tracks' mean scores. The reported
    /// scores ([`Scoring::evaluate`]) are always the reference's.
    pub search_means: MeanScores,
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

    /// Name of the search's objective: the headline metric, and for KITTI how it averages.
    pub fn search_metric(&self) -> &'static str {
        match (self.protocol, self.search_means) {
            (Protocol::Kitti, MeanScores::Once) => "sAMOTA (means once)",
            (Protocol::Kitti, MeanScores::EveryPassCompensated) => "sAMOTA (Python 3.12 sums)",
            _ => self.metric(),
        }
    }

    /// The headline metric per class over `scenes` (NaN for a class that is not evaluated, e.g.
    /// without ground truth or without tracks).
    pub fn evaluate(
        &self,
        scenes: &[Scene<KittiBox>],
        classes: &[String],
    ) -> BTreeMap<String, f64> {
        self.evaluate_with_once(scenes, classes).0
    }

    /// [`Scoring::evaluate`], and for KITTI from the same evaluation sAMOTA per class with each
    /// track's mean score computed once (not the official number; shown beside it, see
    /// `probmot eval --means`). The second map is empty for nuScenes.
    pub fn evaluate_with_once(
        &self,
        scenes: &[Scene<KittiBox>],
        classes: &[String],
    ) -> (BTreeMap<String, f64>, BTreeMap<String, f64>) {
        let per_class = |f: &dyn Fn(&str) -> f64| -> BTreeMap<String, f64> {
            classes.iter().map(|c| (c.clone(), f(c))).collect()
        };
        match self.protocol {
            Protocol::Kitti => {
                // The reference's averaging: reported scores are the official ones.
                let p = KittiParams {
                    classes: classes.to_vec(),
                    min_overlap: self.iou,
                    means: MeanScores::EveryPass,
                    ..KittiParams::default()
                };
                let r = kitti::evaluate(scenes, &p);
                let metric = |f: fn(&kitti::KittiMetrics) -> f64| {
                    per_class(&|c| r.classes.get(c).map_or(f64::NAN, f))
                };
                (metric(|m| m.samota), metric(|m| m.samota_means_once))
            }
            Protocol::Nuscenes => {
                let p = NuscenesParams {
                    classes: classes.to_vec(),
                    ..NuscenesParams::default()
                };
                let columns: Vec<ColumnScene> =
                    scenes.iter().map(ColumnScene::from_scene).collect();
                let r = nuscenes::evaluate_columns(&columns, &p);
                let amota = per_class(&|c| r.classes.get(c).map_or(f64::NAN, |m| m.amota));
                (amota, BTreeMap::new())
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
pub fn track_log(log: &TuneLog, cfg: &TrackerConfig) -> Result<Scene<KittiBox>> {
    let mut tracks: Vec<Vec<KittiBox>> = vec![Vec::new(); log.frames.len()];
    let mut boxes = KittiBoxes::default();
    run_tracker(log, cfg, |fi, r, label, image_box| {
        // What the evaluations read of the box `probmot track` would write.
        let written = LabelledBox {
            id: r.id,
            label: label.to_string(),
            center: r.bbox.center,
            size: r.bbox.size,
            yaw: r.bbox.yaw,
            score: r.score,
            image_box,
            ..Default::default()
        };
        tracks[fi].push(boxes.read(&written))
    })?;
    let frames = (log.frames.iter().zip(tracks))
        .map(|(f, t)| (f.stamp, f.truth.clone(), t))
        .collect();
    Ok(Scene {
        name: log.name.clone(),
        frames,
    })
}

/// One class's truth in a tune's logs, prepared once and read by every candidate.
#[derive(Debug, Clone)]
pub enum ClassTruth {
    /// KITTI: the class's truth as the protocol reads it.
    Kitti(kitti::ClassTruth),
    /// nuScenes: per log, the truth the class's evaluation reads, in columns (no tracks yet).
    Nuscenes(Vec<ColumnScene>),
}

/// The truth of class `label` in `logs` as the protocol's evaluation of that class reads it
/// (KITTI: the class, its neighbour and DontCare regions, with their ignore flags).
pub fn class_truth(logs: &[&TuneLog], label: &str, scoring: &Scoring) -> ClassTruth {
    match scoring.protocol {
        Protocol::Kitti => {
            let scenes = logs.iter().map(|l| {
                let frames = l.frames.iter().map(|f| f.truth.as_slice());
                (l.name.as_str(), frames)
            });
            ClassTruth::Kitti(kitti::ClassTruth::new(
                scenes,
                label,
                &kitti_params(label, scoring),
            ))
        }
        Protocol::Nuscenes => {
            ClassTruth::Nuscenes(logs.iter().map(|l| nuscenes_truth(l, label)).collect())
        }
    }
}

/// The truth of `log` that the nuScenes evaluation of class `label` reads, in columns: the
/// boxes of the class, and those of other classes that share an id with one of them (the
/// evaluation fills gaps by id across classes). Every frame of the log is a frame.
fn nuscenes_truth(log: &TuneLog, label: &str) -> ColumnScene {
    let ids: HashSet<u64> = (log.frames.iter())
        .flat_map(|f| f.truth.iter().filter(|b| b.label() == label).map(|b| b.id))
        .collect();
    let mut scene = ColumnScene {
        name: log.name.clone(),
        labels: vec![label.to_string()],
        stamps: log.frames.iter().map(|f| f.stamp).collect(),
        truth: Side::new(),
        tracks: Side::new(),
    };
    for f in &log.frames {
        for b in f.truth.iter().filter(|b| ids.contains(&b.id)) {
            let l = scene.label_or_add(b.label());
            scene
                .truth
                .push_box(b.id, l, [b.box3.center[0], b.box3.center[1]], b.score);
        }
        scene.truth.end_frame();
    }
    scene
}

/// `log` tracked with `cfg`, in columns beside the class's `truth` (from [`nuscenes_truth`]).
fn track_columns(log: &TuneLog, cfg: &TrackerConfig, truth: &ColumnScene) -> Result<ColumnScene> {
    let mut scene = truth.clone();
    let mut tracks = Side::new();
    let mut frames = 0;
    run_tracker(log, cfg, |fi, r, label, _| {
        debug_assert!(fi >= frames, "frames are emitted in order");
        for _ in frames..fi {
            tracks.end_frame();
        }
        frames = frames.max(fi);
        let l = scene.label_or_add(label);
        let c = r.bbox.center;
        tracks.push_box(r.id, l, [c[0], c[1]], r.score);
    })?;
    for _ in frames..log.frames.len() {
        tracks.end_frame();
    }
    scene.tracks = tracks;
    Ok(scene)
}

/// The KITTI parameters of one class's evaluation.
fn kitti_params(label: &str, scoring: &Scoring) -> KittiParams {
    KittiParams {
        classes: vec![label.to_string()],
        min_overlap: scoring.iou,
        means: scoring.search_means,
        ..KittiParams::default()
    }
}

/// Runs the tracker over `log` as [`track_log`] describes, handing every shown track to `emit`
/// with its frame index, class label and 2D box (frames in order, each once its reports are
/// decided: see [`Lookback`]).
fn run_tracker(
    log: &TuneLog,
    cfg: &TrackerConfig,
    mut emit: impl FnMut(usize, &TrackReport, &str, Option<[f64; 4]>),
) -> Result<()> {
    let mut tracker = Tracker::new(cfg.clone()).map_err(|e| anyhow!("{e}"))?;
    let mut dets: Vec<Detection> = Vec::new();
    let mut src: Vec<usize> = Vec::new();
    // Image box of each track's last matched detection, by track id.
    let mut image: Vec<Option<[f64; 4]>> = Vec::new();
    // Frames wait here while the offline options decide their reports (when a class has them).
    let held = cfg.holds_frames();
    let mut lookback: Lookback<HeldReport> = Lookback::default();
    let mut shown = Vec::new();
    for (fi, f) in log.frames.iter().enumerate() {
        if !f.has_detections {
            continue;
        }
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
        tracker
            .step(f.stamp, &dets)
            .map_err(|e| anyhow!("{}: stamp {}: {e}", log.name, f.stamp))?;
        for r in tracker.reports() {
            let id = r.id as usize;
            if image.len() <= id {
                image.resize(id + 1, None);
            }
            if let Some(d) = r.detection {
                image[id] = f.detections[src[d as usize]].image_box;
            }
        }
        if !held {
            for r in tracker.reports() {
                emit(fi, r, tracker.label(r.class), image[r.id as usize]);
            }
            continue;
        }
        // The frame index stands for the stamp: the reports come out with their frame.
        lookback.push(fi as u64, tracker.reports(), |v, r| {
            *v = (*r, image[r.id as usize])
        });
        drain(&mut lookback, &mut shown, &tracker, &mut emit);
    }
    lookback.finish();
    drain(&mut lookback, &mut shown, &tracker, &mut emit);
    Ok(())
}

/// A report held with the 2D box its track had in its frame.
type HeldReport = (TrackReport, Option<[f64; 4]>);

/// Hands every frame the lookback has decided to `emit`, in order (frame indexes as stamps).
fn drain(
    lookback: &mut Lookback<HeldReport>,
    shown: &mut Vec<HeldReport>,
    tracker: &Tracker,
    emit: &mut impl FnMut(usize, &TrackReport, &str, Option<[f64; 4]>),
) {
    while let Some(fi) = lookback.pop_into(shown) {
        for (r, image_box) in shown.iter() {
            emit(fi as usize, r, tracker.label(r.class), *image_box);
        }
    }
}

/// The rows of class `cls` in the tracks of `log` tracked with `cfg`, as the KITTI evaluation
/// reads them (the tracks' label is their KITTI type).
pub fn track_rows(log: &TuneLog, cfg: &TrackerConfig, cls: &str) -> Result<Vec<TrackRow>> {
    let mut rows = Vec::new();
    // What each tracker class is to `cls`, by class index (looked up once per class).
    let mut kinds: Vec<Option<Option<RowKind>>> = Vec::new();
    run_tracker(log, cfg, |fi, r, label, image_box| {
        let c = r.class as usize;
        if kinds.len() <= c {
            kinds.resize(c + 1, None);
        }
        let kind = *kinds[c].get_or_insert_with(|| kitti::row_kind(cls, &label.to_lowercase()));
        if let Some(kind) = kind {
            rows.push(TrackRow {
                frame: fi as u32,
                id: r.id as i64,
                kind,
                bbox: r.bbox,
                score: r.score,
                image_box,
            });
        }
    })?;
    Ok(rows)
}

/// The headline metric of one class when `logs` are tracked with `cfg`.
pub fn score_class(
    logs: &[&TuneLog],
    cfg: &TrackerConfig,
    label: &str,
    scoring: &Scoring,
) -> Result<f64> {
    score_class_with(logs, &class_truth(logs, label, scoring), cfg, label)
}

/// [`score_class`] with the class's truth prepared by [`class_truth`] (once per tune, with the
/// protocol's settings): the tracks go to the evaluation as rows (KITTI) or columns (nuScenes)
/// beside the prepared truth, without evaluation scenes of whole boxes.
pub fn score_class_with(
    logs: &[&TuneLog],
    truth: &ClassTruth,
    cfg: &TrackerConfig,
    label: &str,
) -> Result<f64> {
    match truth {
        ClassTruth::Kitti(t) => {
            let rows = logs
                .iter()
                .map(|l| track_rows(l, cfg, t.class()))
                .collect::<Result<Vec<_>>>()?;
            Ok(t.evaluate(&rows).map_or(f64::NAN, |m| m.samota))
        }
        ClassTruth::Nuscenes(t) => {
            let scenes = (logs.iter().zip(t))
                .map(|(l, t)| track_columns(l, cfg, t))
                .collect::<Result<Vec<_>>>()?;
            let p = NuscenesParams {
                classes: vec![label.to_string()],
                ..NuscenesParams::default()
            };
            let r = nuscenes::evaluate_columns(&scenes, &p);
            Ok(r.classes.get(label).map_or(f64::NAN, |m| m.amota))
        }
    }
}
