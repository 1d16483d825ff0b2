//! The nuScenes tracking metrics (nuscenes-devkit 1.2.0, `tracking_nips_2019`) re-implemented:
//! per-track mean scores, linear interpolation of gaps, 2 m centre-distance matching with
//! motmetrics semantics, 40 recall thresholds, AMOTA / AMOTP and the CLEAR MOT metrics at the
//! best-MOTA threshold. The rules are written out in `../shared/reference/evaluation-protocols.md`
//! (beside the repository) and checked against the devkit's own numbers in `tests/`.

use std::collections::{BTreeMap, HashSet};

use rayon::prelude::*;
use serde::Serialize;

use super::columns::ColumnScene;
use super::events::Collector;
use super::nan_as_null;
use super::numpy_compat::{np_mean, np_sum};
use super::scene::Scene;
use crate::tracker::config::NUSCENES_CLASSES;
use pass::{metrics_of, recall_thresholds, run_pass, run_pass_with, worst_metrics};
use prepare::{class_view, prepare, ClassScene, Prepared};

pub mod curve;
mod pass;
mod prepare;

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
    /// Average MOTA over recall thresholds (the devkit's headline metric).
    #[serde(serialize_with = "nan_as_null")]
    pub amota: f64,
    /// Average MOTP over recall thresholds, metres (lower is better).
    #[serde(serialize_with = "nan_as_null")]
    pub amotp: f64,
    /// Recall at the threshold of the best MOTA.
    #[serde(serialize_with = "nan_as_null")]
    pub recall: f64,
    /// Recall-normalised MOTA at that threshold.
    #[serde(serialize_with = "nan_as_null")]
    pub motar: f64,
    /// MOTA at that threshold.
    #[serde(serialize_with = "nan_as_null")]
    pub mota: f64,
    /// MOTP (mean centre distance of matches), metres.
    #[serde(serialize_with = "nan_as_null")]
    pub motp: f64,
    /// Mostly tracked trajectories (tracked for at least 80 % of their life).
    #[serde(serialize_with = "nan_as_null")]
    pub mt: f64,
    /// Mostly lost trajectories (tracked for under 20 % of their life).
    #[serde(serialize_with = "nan_as_null")]
    pub ml: f64,
    /// False alarms per frame.
    #[serde(serialize_with = "nan_as_null")]
    pub faf: f64,
    /// True positives.
    #[serde(serialize_with = "nan_as_null")]
    pub tp: f64,
    /// False positives.
    #[serde(serialize_with = "nan_as_null")]
    pub fp: f64,
    /// False negatives (`fn` in JSON).
    #[serde(rename = "fn", serialize_with = "nan_as_null")]
    pub fn_: f64,
    /// Identity switches.
    #[serde(serialize_with = "nan_as_null")]
    pub ids: f64,
    /// Fragmentations.
    #[serde(serialize_with = "nan_as_null")]
    pub frag: f64,
    /// Track initialization duration, seconds.
    #[serde(serialize_with = "nan_as_null")]
    pub tid: f64,
    /// Longest gap duration, seconds.
    #[serde(serialize_with = "nan_as_null")]
    pub lgd: f64,
    /// Ground-truth boxes.
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
