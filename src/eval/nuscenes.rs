//! The nuScenes tracking metrics (nuscenes-devkit 1.2.0, `tracking_nips_2019`) re-implemented:
//! per-track mean scores, linear interpolation of gaps, 2 m centre-distance matching with
//! motmetrics semantics, 40 recall thresholds, AMOTA / AMOTP and the CLEAR MOT metrics at the
//! best-MOTA threshold. The rules are written out in `../shared/reference/evaluation-protocols.md`
//! (beside the repository) and checked against the devkit's own numbers in `tests/`.

use std::collections::{BTreeMap, HashMap, HashSet};

use rayon::prelude::*;
use serde::Serialize;

use super::columns::{ColumnScene, Side};
use super::events::Collector;
use super::mot_accumulator::{EventKind, MotAccumulator};
use super::nan_as_null;
use super::numpy_compat::{linspace_round12, np_interp, np_mean, np_sum};
use super::scene::Scene;
use crate::tracker::config::NUSCENES_CLASSES;

/// Parameters of the protocol.
#[derive(Debug, Clone)]
pub struct NuscenesParams {
    /// Classes to evaluate.
    pub classes: Vec<String>,
    /// Matching distance in metres (a pair matches when closer than this).
    pub dist_th: f64,
    /// Lowest recall level.
    pub min_recall: f64,
    /// Number of recall levels.
    pub num_thresholds: usize,
    /// Seconds per frame used by TID and LGD (the devkit uses 0.5 whatever the data).
    pub sample_period: f64,
}

impl Default for NuscenesParams {
    fn default() -> Self {
        NuscenesParams {
            classes: NUSCENES_CLASSES.iter().map(|s| s.to_string()).collect(),
            dist_th: 2.0,
            min_recall: 0.1,
            num_thresholds: 40,
            sample_period: 0.5,
        }
    }
}

/// Every metric of one class (or the overall aggregate). NaN where undefined (JSON `null`).
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct Metrics {
    #[serde(serialize_with = "nan_as_null")]
    pub amota: f64,
    #[serde(serialize_with = "nan_as_null")]
    pub amotp: f64,
    #[serde(serialize_with = "nan_as_null")]
    pub recall: f64,
    #[serde(serialize_with = "nan_as_null")]
    pub motar: f64,
    #[serde(serialize_with = "nan_as_null")]
    pub mota: f64,
    #[serde(serialize_with = "nan_as_null")]
    pub motp: f64,
    #[serde(serialize_with = "nan_as_null")]
    pub mt: f64,
    #[serde(serialize_with = "nan_as_null")]
    pub ml: f64,
    #[serde(serialize_with = "nan_as_null")]
    pub faf: f64,
    #[serde(serialize_with = "nan_as_null")]
    pub tp: f64,
    #[serde(serialize_with = "nan_as_null")]
    pub fp: f64,
    #[serde(rename = "fn", serialize_with = "nan_as_null")]
    pub fn_: f64,
    #[serde(serialize_with = "nan_as_null")]
    pub ids: f64,
    #[serde(serialize_with = "nan_as_null")]
    pub frag: f64,
    #[serde(serialize_with = "nan_as_null")]
    pub tid: f64,
    #[serde(serialize_with = "nan_as_null")]
    pub lgd: f64,
    #[serde(serialize_with = "nan_as_null")]
    pub gt: f64,
}

/// Names of the metrics, in report order (the main one first).
pub const METRIC_NAMES: [&str; 17] = [
    "amota", "amotp", "recall", "motar", "mota", "motp", "mt", "ml", "faf", "tp", "fp", "fn",
    "ids", "frag", "tid", "lgd", "gt",
];

impl Metrics {
    fn all(v: f64) -> Metrics {
        Metrics {
            amota: v,
            amotp: v,
            recall: v,
            motar: v,
            mota: v,
            motp: v,
            mt: v,
            ml: v,
            faf: v,
            tp: v,
            fp: v,
            fn_: v,
            ids: v,
            frag: v,
            tid: v,
            lgd: v,
            gt: v,
        }
    }

    /// A metric by name (see [`METRIC_NAMES`]).
    pub fn get(&self, name: &str) -> f64 {
        match name {
            "amota" => self.amota,
            "amotp" => self.amotp,
            "recall" => self.recall,
            "motar" => self.motar,
            "mota" => self.mota,
            "motp" => self.motp,
            "mt" => self.mt,
            "ml" => self.ml,
            "faf" => self.faf,
            "tp" => self.tp,
            "fp" => self.fp,
            "fn" => self.fn_,
            "ids" => self.ids,
            "frag" => self.frag,
            "tid" => self.tid,
            "lgd" => self.lgd,
            "gt" => self.gt,
            _ => f64::NAN,
        }
    }

    fn set(&mut self, name: &str, v: f64) {
        let slot = match name {
            "amota" => &mut self.amota,
            "amotp" => &mut self.amotp,
            "recall" => &mut self.recall,
            "motar" => &mut self.motar,
            "mota" => &mut self.mota,
            "motp" => &mut self.motp,
            "mt" => &mut self.mt,
            "ml" => &mut self.ml,
            "faf" => &mut self.faf,
            "tp" => &mut self.tp,
            "fp" => &mut self.fp,
            "fn" => &mut self.fn_,
            "ids" => &mut self.ids,
            "frag" => &mut self.frag,
            "tid" => &mut self.tid,
            "lgd" => &mut self.lgd,
            "gt" => &mut self.gt,
            _ => return,
        };
        *slot = v;
    }
}

/// Result of an evaluation.
#[derive(Debug, Clone, Serialize)]
pub struct NuscenesResult {
    /// Protocol name.
    pub protocol: &'static str,
    /// Per class.
    pub classes: BTreeMap<String, Metrics>,
    /// Aggregate over classes (sums for counts, NaN-means otherwise).
    pub overall: Metrics,
    /// Things the user should know (e.g. many identical scores).
    pub notes: Vec<String>,
}

/// A box after preprocessing; `label` indexes the evaluated classes ([`NO_CLASS`]: another).
#[derive(Debug, Clone, Copy)]
struct PBox {
    id: u64,
    label: u16,
    x: f64,
    y: f64,
    score: f64,
}

/// The label id of a box of no evaluated class.
const NO_CLASS: u16 = u16::MAX;

/// One scene after score averaging and interpolation: its columns (read through
/// `class_of`, the evaluated class of each label, and `means`, each track's mean score) and,
/// per frame, the interpolated boxes that follow the frame's own.
struct Prepared<'a> {
    scene: &'a ColumnScene,
    class_of: Vec<u16>,
    means: HashMap<u64, f64>,
    gt_extra: Vec<Vec<PBox>>,
    pred_extra: Vec<Vec<PBox>>,
}

/// The box at row `i` of `side` as the passes see it (`score`: the one it carries).
fn pbox(side: &Side, class_of: &[u16], i: usize, score: f64) -> PBox {
    PBox {
        id: side.id[i],
        label: class_of[side.label[i] as usize],
        x: side.xy[i][0],
        y: side.xy[i][1],
        score,
    }
}

/// The devkit's `interpolate_tracks` on one side: the boxes that fill the gaps of every track
/// (by id, across classes) at the scene's timestamps, per frame: weight `r = (t_right - t) /
/// (t_right - t_left)` on the *right* box, class and id of the right box, in the order the
/// tracks first appear (they follow the frame's own boxes). Each track visits only the frames
/// of its own time span. `boxed(i)` is the box at row `i`.
fn interpolate(ts: &[i64], side: &Side, boxed: impl Fn(usize) -> PBox) -> Vec<Vec<PBox>> {
    // Per track in order of first appearance: its (frame, row) positions in frame order.
    let mut index: HashMap<u64, usize> = HashMap::new();
    let mut tracks: Vec<Vec<(u32, u32)>> = Vec::new();
    for fi in 0..ts.len() {
        for row in side.frame(fi) {
            let slot = *index.entry(side.id[row]).or_insert_with(|| {
                tracks.push(Vec::new());
                tracks.len() - 1
            });
            tracks[slot].push((fi as u32, row as u32));
        }
    }
    drop(index);
    let sorted = ts.windows(2).all(|w| w[0] <= w[1]);
    let mut extra: Vec<Vec<PBox>> = vec![Vec::new(); ts.len()];
    for track in &tracks {
        let time = |i: usize| ts[track[i].0 as usize];
        let (first, last) = (time(0), time(track.len() - 1));
        let span = if sorted {
            ts.partition_point(|v| *v < first)..ts.partition_point(|v| *v <= last)
        } else {
            0..ts.len()
        };
        for fi in span {
            let t = ts[fi];
            let right = track.partition_point(|p| ts[p.0 as usize] <= t);
            let present = if sorted {
                right > 0 && time(right - 1) == t
            } else {
                track.iter().any(|p| ts[p.0 as usize] == t)
            };
            if t < first || t > last || present {
                continue;
            }
            let left = right - 1;
            let r = (time(right) - t) as f64 / (time(right) - time(left)) as f64;
            let (lb, rb) = (
                boxed(track[left].1 as usize),
                boxed(track[right].1 as usize),
            );
            extra[fi].push(PBox {
                id: rb.id,
                label: rb.label,
                x: (1.0 - r) * lb.x + r * rb.x,
                y: (1.0 - r) * lb.y + r * rb.y,
                score: (1.0 - r) * lb.score + r * rb.score,
            });
        }
    }
    extra
}

fn prepare<'a>(scene: &'a ColumnScene, classes: &[String]) -> Prepared<'a> {
    // The devkit's timestamps are microseconds.
    let ts: Vec<i64> = scene.stamps.iter().map(|s| (s / 1000) as i64).collect();
    let class_of: Vec<u16> = scene
        .labels
        .iter()
        .map(|l| {
            classes
                .iter()
                .position(|c| c == l)
                .map_or(NO_CLASS, |i| i as u16)
        })
        .collect();
    // Each track's boxes get the track's mean score (np.mean, before interpolation).
    let tr = &scene.tracks;
    let mut scores: HashMap<u64, Vec<f64>> = HashMap::new();
    for (id, score) in tr.id.iter().zip(&tr.score) {
        scores.entry(*id).or_default().push(*score);
    }
    let means: HashMap<u64, f64> = scores.iter().map(|(k, v)| (*k, np_mean(v))).collect();
    drop(scores);
    let gt = &scene.truth;
    let gt_extra = interpolate(&ts, gt, |i| pbox(gt, &class_of, i, gt.score[i]));
    let pred_extra = interpolate(&ts, tr, |i| pbox(tr, &class_of, i, means[&tr.id[i]]));
    Prepared {
        scene,
        class_of,
        means,
        gt_extra,
        pred_extra,
    }
}

/// One scene restricted to one class: per frame, `(id, x, y)` of the truth and
/// `(id, x, y, score)` of the tracks, in the devkit's box order.
struct ClassScene {
    gt: Vec<Vec<(u64, f64, f64)>>,
    pred: Vec<Vec<(u64, f64, f64, f64)>>,
}

fn class_view(p: &Prepared, class: u16) -> ClassScene {
    let s = p.scene;
    let (gt, tr) = (&s.truth, &s.tracks);
    let of_class = |side: &Side, i: usize| p.class_of[side.label[i] as usize] == class;
    let frames = 0..s.stamps.len();
    ClassScene {
        gt: frames
            .clone()
            .map(|f| {
                gt.frame(f)
                    .filter(|&i| of_class(gt, i))
                    .map(|i| (gt.id[i], gt.xy[i][0], gt.xy[i][1]))
                    .chain(
                        p.gt_extra[f]
                            .iter()
                            .filter(|b| b.label == class)
                            .map(|b| (b.id, b.x, b.y)),
                    )
                    .collect()
            })
            .collect(),
        pred: frames
            .map(|f| {
                tr.frame(f)
                    .filter(|&i| of_class(tr, i))
                    .map(|i| (tr.id[i], tr.xy[i][0], tr.xy[i][1], p.means[&tr.id[i]]))
                    .chain(
                        p.pred_extra[f]
                            .iter()
                            .filter(|b| b.label == class)
                            .map(|b| (b.id, b.x, b.y, b.score)),
                    )
                    .collect()
            })
            .collect(),
    }
}

/// What one pass over all scenes at one score threshold gives.
#[derive(Default)]
struct Pass {
    frames: u64,
    matches: u64,
    switches: u64,
    misses: u64,
    fps: u64,
    dist_sum_terms: Vec<f64>,
    /// Per ground-truth object: `(global frame index, tracked)` in frame order.
    objects: Vec<Vec<(u64, bool)>>,
    /// Scores of matched predictions (only collected without threshold).
    match_scores: Vec<f64>,
}

/// `sklearn.metrics.pairwise.euclidean_distances` for 2-d points (dot-product expansion).
fn euclidean(ax: f64, ay: f64, bx: f64, by: f64) -> f64 {
    let dot = ax * bx + ay * by;
    let aa = ax * ax + ay * ay;
    let bb = bx * bx + by * by;
    let d2 = (-2.0 * dot + aa + bb).max(0.0);
    d2.sqrt()
}

fn run_pass(scenes: &[ClassScene], threshold: Option<f64>, p: &NuscenesParams) -> Pass {
    run_pass_with(scenes, threshold, p, None)
}

/// [`run_pass`], recording every association decision into `log` when given (`eval --events`).
fn run_pass_with(
    scenes: &[ClassScene],
    threshold: Option<f64>,
    p: &NuscenesParams,
    mut log: Option<&mut Collector>,
) -> Pass {
    let mut pass = Pass::default();
    let mut events = Vec::new();
    let mut dist = Vec::new();
    let mut oids: Vec<u64> = Vec::new();
    let mut hids: Vec<u64> = Vec::new();
    let mut hpos: Vec<(f64, f64, f64)> = Vec::new();
    let mut matched_hids: Vec<u64> = Vec::new();
    for (si, scene) in scenes.iter().enumerate() {
        let mut acc = MotAccumulator::new();
        let mut object_index: HashMap<u64, usize> = HashMap::new();
        for (fi, (g, h)) in scene.gt.iter().zip(&scene.pred).enumerate() {
            hids.clear();
            hpos.clear();
            for &(id, x, y, score) in h {
                if threshold.is_none_or(|t| score >= t) {
                    hids.push(id);
                    hpos.push((x, y, score));
                }
            }
            if g.is_empty() && hids.is_empty() {
                continue;
            }
            oids.clear();
            oids.extend(g.iter().map(|b| b.0));
            dist.clear();
            for &(_, gx, gy) in g {
                for &(hx, hy, _) in &hpos {
                    let d = euclidean(gx, gy, hx, hy);
                    dist.push(if d >= p.dist_th { f64::NAN } else { d });
                }
            }
            events.clear();
            acc.update(&oids, &hids, &dist, &mut events);
            let frame = pass.frames;
            pass.frames += 1;
            matched_hids.clear();
            for e in &events {
                if let Some(log) = log.as_deref_mut() {
                    let truth = e.object.map(|i| g[i]);
                    let track = e.hypothesis.map(|j| (hids[j], hpos[j]));
                    log.record_association(si, fi, e.kind, truth, track);
                }
                match e.kind {
                    EventKind::Match => {
                        pass.matches += 1;
                        pass.dist_sum_terms.push(e.distance);
                        matched_hids.push(hids[e.hypothesis.unwrap()]);
                    }
                    EventKind::Switch => {
                        pass.switches += 1;
                        pass.dist_sum_terms.push(e.distance);
                    }
                    EventKind::Miss => {
                        pass.misses += 1;
                        pass.dist_sum_terms.push(0.0);
                    }
                    EventKind::FalsePositive => {
                        pass.fps += 1;
                        pass.dist_sum_terms.push(0.0);
                    }
                }
                if let Some(oi) = e.object {
                    let next = pass.objects.len();
                    let idx = *object_index.entry(oids[oi]).or_insert(next);
                    if idx == pass.objects.len() {
                        pass.objects.push(Vec::new());
                    }
                    pass.objects[idx].push((frame, e.kind != EventKind::Miss));
                }
            }
            if threshold.is_none() {
                // The devkit collects the score of every kept box whose id was matched.
                pass.match_scores.extend(
                    hids.iter()
                        .zip(&hpos)
                        .filter(|(id, _)| matched_hids.contains(id))
                        .map(|(_, pos)| pos.2),
                );
            }
        }
    }
    pass
}

fn metrics_of(pass: &Pass, p: &NuscenesParams) -> Metrics {
    let tp = pass.matches as f64;
    let ids = pass.switches as f64;
    let fp = pass.fps as f64;
    let fn_ = pass.misses as f64;
    let objects = tp + ids + fn_;
    let detections = tp + ids;
    let recall_m = tp / objects;
    let nominator = (fn_ + ids + fp) - (1.0 - recall_m) * objects;
    let denominator = recall_m * objects;
    let motar = if denominator == 0.0 {
        f64::NAN
    } else {
        (1.0 - nominator / denominator).max(0.0)
    };
    let mota = (1.0 - (fn_ + ids + fp) / objects).max(0.0);
    let motp = if detections == 0.0 {
        f64::NAN
    } else {
        np_sum(&pass.dist_sum_terms) / detections
    };
    let (mut mt, mut ml, mut frag) = (0.0, 0.0, 0.0);
    let (mut tid, mut lgd) = (0.0, 0.0);
    let mut missed = 0usize;
    for seq in &pass.objects {
        let tracked = seq.iter().filter(|s| s.1).count() as f64;
        let ratio = tracked / seq.len() as f64;
        if ratio >= 0.8 {
            mt += 1.0;
        }
        if ratio < 0.2 {
            ml += 1.0;
        }
        let Some(first) = seq.iter().position(|s| s.1) else {
            missed += 1;
            continue;
        };
        let last = seq.iter().rposition(|s| s.1).unwrap();
        for k in first + 1..=last {
            if !seq[k].1 && seq[k - 1].1 {
                frag += 1.0;
            }
        }
        tid += (seq[first].0 - seq[0].0) as f64 * p.sample_period;
        let matched: HashSet<u64> = seq.iter().filter(|s| s.1).map(|s| s.0).collect();
        let (mut gap, mut cur) = (0u64, 0u64);
        for i in seq[0].0..=seq.last().unwrap().0 {
            if matched.contains(&i) {
                gap = gap.max(cur);
                cur = 0;
            } else {
                cur += 1;
            }
        }
        gap = gap.max(cur);
        lgd += gap as f64 * p.sample_period;
    }
    let matched_tracks = pass.objects.len() - missed;
    let (tid, lgd) = if matched_tracks == 0 {
        (f64::NAN, f64::NAN)
    } else {
        (tid / matched_tracks as f64, lgd / matched_tracks as f64)
    };
    Metrics {
        amota: f64::NAN,
        amotp: f64::NAN,
        recall: detections / objects,
        motar,
        mota,
        motp,
        mt,
        ml,
        faf: fp / pass.frames as f64 * 100.0,
        tp,
        fp,
        fn_,
        ids,
        frag,
        tid,
        lgd,
        gt: objects,
    }
}

/// The score thresholds of the `p.num_thresholds` recall levels from the scores of the matched
/// predictions (NaN for a level the tracks never reach), in the devkit's order.
fn recall_thresholds(mut scores: Vec<f64>, gt_boxes: u64, p: &NuscenesParams) -> Vec<f64> {
    let n = p.num_thresholds;
    let mut thresholds = vec![f64::NAN; n];
    if !scores.is_empty() {
        scores.sort_by(|a, b| b.total_cmp(a));
        let rec: Vec<f64> = (1..=scores.len())
            .map(|k| k as f64 / gt_boxes as f64)
            .collect();
        let max_rec = *rec.last().unwrap();
        let levels = linspace_round12(p.min_recall, 1.0, n);
        for (i, r) in levels.iter().enumerate() {
            thresholds[i] = if *r > max_rec {
                f64::NAN
            } else {
                np_interp(*r, &rec, &scores, 0.0)
            };
        }
        thresholds.reverse();
    }
    thresholds
}

/// The metrics of a class whose tracks reach no recall level: worst values everywhere; FP, IDS
/// and FRAG cannot be known.
fn worst_metrics(gt_objects: usize, gt_boxes: u64) -> Metrics {
    let mut m = Metrics::all(f64::NAN);
    for (k, v) in [
        ("amota", 0.0),
        ("amotp", 2.0),
        ("recall", 0.0),
        ("motar", 0.0),
        ("mota", 0.0),
        ("motp", 2.0),
        ("mt", 0.0),
        ("ml", gt_objects as f64),
        ("faf", 500.0),
        ("tp", 0.0),
        ("fn", gt_boxes as f64),
        ("tid", 20.0),
        ("lgd", 20.0),
        ("gt", gt_boxes as f64),
    ] {
        m.set(k, v);
    }
    m
}

/// Evaluates one class (all metrics NaN when it has no ground truth), recording the decisions of
/// its best-MOTA threshold into `log` when given.
fn evaluate_class(
    scenes: &[Prepared],
    (class_id, class): (u16, &str),
    p: &NuscenesParams,
    notes: &mut Vec<String>,
    log: Option<&mut Collector>,
) -> Metrics {
    let scenes: Vec<ClassScene> = scenes.iter().map(|s| class_view(s, class_id)).collect();
    // Ids restart in every log (KITTI label files, `simulate`, per-drive counters): a ground-truth
    // object is the pair (log, id). The devkit's instance tokens are unique across scenes.
    let mut gt_boxes = 0u64;
    let mut gt_ids: HashSet<(usize, u64)> = HashSet::new();
    for (si, s) in scenes.iter().enumerate() {
        for f in &s.gt {
            for b in f {
                gt_boxes += 1;
                gt_ids.insert((si, b.0));
            }
        }
    }
    if gt_boxes == 0 {
        return Metrics::all(f64::NAN);
    }
    // Recall thresholds from the scores of matched predictions.
    let thresholds = recall_thresholds(run_pass(&scenes, None, p).match_scores, gt_boxes, p);
    let achieved = thresholds.iter().filter(|t| !t.is_nan()).count();
    if achieved == 0 {
        // No track ever matched: the metrics count every ground-truth box as missed, and so do
        // the events (a pass that keeps no track).
        if let Some(log) = log {
            run_pass_with(&scenes, Some(f64::INFINITY), p, Some(log));
        }
        return worst_metrics(gt_ids.len(), gt_boxes);
    }
    // The distinct reached thresholds, each scored once, in parallel.
    let mut distinct: Vec<f64> = Vec::new();
    for &t in thresholds.iter().filter(|t| !t.is_nan()) {
        if !distinct.contains(&t) {
            distinct.push(t);
        }
    }
    let computed: Vec<(f64, Metrics)> = distinct
        .par_iter()
        .map(|&t| (t, metrics_of(&run_pass(&scenes, Some(t), p), p)))
        .collect();
    let per_threshold: Vec<Metrics> = thresholds
        .iter()
        .map(|&t| match computed.iter().find(|(v, _)| *v == t) {
            Some((_, m)) => *m,
            None => Metrics::all(f64::NAN),
        })
        .collect();
    if computed.len() == 1 && achieved > 1 {
        notes.push(format!(
            "{class}: every matched track has the same score, so all {achieved} reached recall \
             levels share one threshold (evaluated once; the devkit can fail on such input)"
        ));
    }
    // Best MOTA: the first maximum in threshold order (ties go to the highest recall).
    let mut best = None;
    for (i, m) in per_threshold.iter().enumerate() {
        if !m.mota.is_nan() && best.is_none_or(|b: usize| m.mota > per_threshold[b].mota) {
            best = Some(i);
        }
    }
    let best = best.expect("an achieved threshold exists");
    if let Some(log) = log {
        run_pass_with(&scenes, Some(thresholds[best]), p, Some(log));
    }
    let mut out = per_threshold[best];
    let motar: Vec<f64> = per_threshold
        .iter()
        .map(|m| if m.motar.is_nan() { 0.0 } else { m.motar })
        .collect();
    let motp: Vec<f64> = per_threshold
        .iter()
        .map(|m| if m.motp.is_nan() { 2.0 } else { m.motp })
        .collect();
    out.amota = np_mean(&motar);
    out.amotp = np_mean(&motp);
    out
}

/// Evaluates scenes (one log each) with the nuScenes protocol.
pub fn evaluate(scenes: &[Scene], p: &NuscenesParams) -> NuscenesResult {
    evaluate_recording(scenes, p, false).0
}

/// [`evaluate`] on scenes already in columns (what `eval` loads).
pub fn evaluate_columns(scenes: &[ColumnScene], p: &NuscenesParams) -> NuscenesResult {
    evaluate_columns_recording(scenes, p, false).0
}

/// [`evaluate`]; with `record`, also the association decisions of each class with ground truth
/// at its best-MOTA threshold (the pass its counts come from), for `eval --events`.
pub fn evaluate_recording(
    scenes: &[Scene],
    p: &NuscenesParams,
    record: bool,
) -> (NuscenesResult, Vec<(String, Collector)>) {
    let scenes: Vec<ColumnScene> = scenes.par_iter().map(ColumnScene::from_scene).collect();
    evaluate_columns_recording(&scenes, p, record)
}

/// [`evaluate_recording`] on scenes already in columns.
pub fn evaluate_columns_recording(
    scenes: &[ColumnScene],
    p: &NuscenesParams,
    record: bool,
) -> (NuscenesResult, Vec<(String, Collector)>) {
    let prepared: Vec<Prepared> = scenes.par_iter().map(|s| prepare(s, &p.classes)).collect();
    // Classes are independent: evaluate them in parallel.
    let per_class: Vec<(Metrics, Vec<String>, Option<Collector>)> = p
        .classes
        .par_iter()
        .enumerate()
        .map(|(i, c)| {
            let mut notes = Vec::new();
            let mut log = record.then(Collector::default);
            let m = evaluate_class(&prepared, (i as u16, c), p, &mut notes, log.as_mut());
            (m, notes, log)
        })
        .collect();
    let mut notes = Vec::new();
    let mut classes = BTreeMap::new();
    let mut decisions = Vec::new();
    for (c, (m, n, log)) in p.classes.iter().zip(per_class) {
        if let Some(log) = log.filter(|_| !m.gt.is_nan()) {
            decisions.push((c.clone(), log));
        }
        classes.insert(c.clone(), m);
        notes.extend(n);
    }
    let mut overall = Metrics::all(f64::NAN);
    for name in METRIC_NAMES {
        let vals: Vec<f64> = classes.values().map(|m| m.get(name)).collect();
        let finite: Vec<f64> = vals.iter().copied().filter(|v| !v.is_nan()).collect();
        let summed = matches!(name, "mt" | "ml" | "tp" | "fp" | "fn" | "ids" | "frag");
        // Counts are only aggregated over classes that have ground truth.
        let with_gt = classes.values().any(|m| !m.gt.is_nan());
        let v = if summed {
            if with_gt {
                np_sum(&finite)
            } else {
                f64::NAN
            }
        } else if finite.is_empty() {
            f64::NAN
        } else {
            np_sum(&finite) / finite.len() as f64
        };
        overall.set(name, v);
    }
    let result = NuscenesResult {
        protocol: "nuscenes",
        classes,
        overall,
        notes,
    };
    (result, decisions)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mcapio::LabelledBox;

    fn gt(id: u64, x: f64) -> LabelledBox {
        LabelledBox {
            id,
            label: "bicycle".into(),
            center: [x, 0.0, 0.0],
            size: [1.7, 0.6, 1.2],
            score: 1.0,
            ..Default::default()
        }
    }

    #[test]
    fn mostly_lost_without_a_reached_threshold_counts_objects_per_log() {
        // Two logs with bicycles 1 and 2 each, never tracked: four objects, not two.
        let log = |name: &str| Scene {
            name: name.into(),
            frames: (0..3)
                .map(|i| (i * 500_000_000, vec![gt(1, 0.0), gt(2, 10.0)], vec![]))
                .collect(),
        };
        let p = NuscenesParams {
            classes: vec!["bicycle".into()],
            ..Default::default()
        };
        let r = evaluate(&[log("a.mcap"), log("b.mcap")], &p);
        let m = &r.classes["bicycle"];
        assert_eq!((m.ml, m.gt, m.fn_, m.amota), (4.0, 12.0, 12.0, 0.0));
        assert_eq!(r.overall.ml, 4.0);
    }
}
