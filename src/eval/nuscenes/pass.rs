//! One pass of the nuScenes protocol over every scene at a score threshold (motmetrics'
//! accumulator over the centre distance), the CLEAR MOT metrics of a pass and the recall
//! thresholds.

use std::collections::{HashMap, HashSet};

use super::prepare::ClassScene;
use super::{Metrics, NuscenesParams};
use crate::eval::bootstrap::curve::UnitCounts;
use crate::eval::bootstrap::Units;
use crate::eval::events::Collector;
use crate::eval::mot_accumulator::{EventKind, MotAccumulator};
use crate::eval::numpy_compat::{linspace_round12, np_interp, np_sum};

/// What one pass over all scenes at one score threshold gives.
#[derive(Default)]
pub(super) struct Pass {
    frames: u64,
    matches: u64,
    switches: u64,
    misses: u64,
    fps: u64,
    dist_sum_terms: Vec<f64>,
    /// Per ground-truth object: `(global frame index, tracked)` in frame order.
    objects: Vec<Vec<(u64, bool)>>,
    /// Scores of matched predictions (only collected without threshold).
    pub(super) match_scores: Vec<f64>,
    /// Per resampling unit, its counts (with units only).
    pub(super) units: Vec<UnitCounts>,
}

/// `sklearn.metrics.pairwise.euclidean_distances` for 2-d points (dot-product expansion).
pub(super) fn euclidean(ax: f64, ay: f64, bx: f64, by: f64) -> f64 {
    let dot = ax * bx + ay * by;
    let aa = ax * ax + ay * ay;
    let bb = bx * bx + by * by;
    let d2 = (-2.0 * dot + aa + bb).max(0.0);
    d2.sqrt()
}

pub(super) fn run_pass(scenes: &[ClassScene], threshold: Option<f64>, p: &NuscenesParams) -> Pass {
    run_pass_with(scenes, threshold, p, None)
}

/// [`run_pass`], recording every association decision into `log` when given (`eval --events`).
pub(super) fn run_pass_with(
    scenes: &[ClassScene],
    threshold: Option<f64>,
    p: &NuscenesParams,
    log: Option<&mut Collector>,
) -> Pass {
    run_pass_units(scenes, threshold, p, log, None)
}

/// [`run_pass_with`], also counting per resampling unit when `units` are given.
pub(super) fn run_pass_units(
    scenes: &[ClassScene],
    threshold: Option<f64>,
    p: &NuscenesParams,
    mut log: Option<&mut Collector>,
    units: Option<&Units>,
) -> Pass {
    let mut pass = Pass::default();
    if let Some(u) = units {
        pass.units = vec![UnitCounts::default(); u.count];
    }
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
            let unit = units.map(|u| u.unit(si, fi));
            for e in &events {
                if let Some(u) = unit {
                    count_unit(&mut pass.units[u], e.kind, e.distance);
                }
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

/// Adds one event of the accumulator to its unit's counts.
fn count_unit(u: &mut UnitCounts, kind: EventKind, distance: f64) {
    match kind {
        EventKind::Match => (u.tp, u.sim) = (u.tp + 1.0, u.sim + distance),
        EventKind::Switch => (u.ids, u.sim) = (u.ids + 1.0, u.sim + distance),
        EventKind::Miss => u.fn_ += 1.0,
        EventKind::FalsePositive => u.fp += 1.0,
    }
}

pub(super) fn metrics_of(pass: &Pass, p: &NuscenesParams) -> Metrics {
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
pub(super) fn recall_thresholds(
    mut scores: Vec<f64>,
    gt_boxes: u64,
    p: &NuscenesParams,
) -> Vec<f64> {
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
pub(super) fn worst_metrics(gt_objects: usize, gt_boxes: u64) -> Metrics {
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
