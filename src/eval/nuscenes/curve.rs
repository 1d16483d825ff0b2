//! The passes of the nuScenes evaluation with each resampling unit's counts kept
//! (`eval --bootstrap`): the recall levels' thresholds as [`super::evaluate_columns`] finds
//! them, each distinct one run once.

use rayon::prelude::*;

use super::pass::{recall_thresholds, run_pass_units};
use super::prepare::{class_view, prepare, ClassScene, Prepared};
use super::NuscenesParams;
use crate::eval::bootstrap::curve::NuscenesCurve;
use crate::eval::bootstrap::Units;
use crate::eval::columns::ColumnScene;

/// Per class of `p.classes` (in order): its recall curve with per-unit counts over `scenes`.
pub fn unit_curves(
    scenes: &[ColumnScene],
    p: &NuscenesParams,
    units: &Units,
) -> Vec<(String, NuscenesCurve)> {
    let prepared: Vec<Prepared> = scenes.par_iter().map(|s| prepare(s, &p.classes)).collect();
    (p.classes.par_iter().enumerate())
        .map(|(i, c)| {
            let scenes: Vec<ClassScene> =
                prepared.iter().map(|s| class_view(s, i as u16)).collect();
            (c.clone(), class_curve(&scenes, p, units))
        })
        .collect()
}

/// One class's curve.
fn class_curve(scenes: &[ClassScene], p: &NuscenesParams, units: &Units) -> NuscenesCurve {
    let mut gt = vec![0.0; units.count];
    for (si, s) in scenes.iter().enumerate() {
        for (fi, f) in s.gt.iter().enumerate() {
            gt[units.unit(si, fi)] += f.len() as f64;
        }
    }
    let gt_boxes: f64 = gt.iter().sum();
    if gt_boxes == 0.0 {
        let matched = gt.clone();
        let min_recall = p.min_recall;
        return NuscenesCurve {
            levels: Vec::new(),
            gt,
            matched,
            min_recall,
        };
    }
    let all = run_pass_units(scenes, None, p, None, Some(units));
    let matched = all.units.iter().map(|u| u.tp + u.ids).collect();
    let scores = all.match_scores;
    let thresholds = recall_thresholds(scores, gt_boxes as u64, p);
    let mut distinct: Vec<f64> = Vec::new();
    for &t in thresholds.iter().filter(|t| !t.is_nan()) {
        if !distinct.contains(&t) {
            distinct.push(t);
        }
    }
    let passes: Vec<_> = (distinct.par_iter())
        .map(|&t| run_pass_units(scenes, Some(t), p, None, Some(units)).units)
        .collect();
    let levels = (thresholds.iter())
        .map(|t| (distinct.iter().position(|d| d == t)).map(|k| passes[k].clone()))
        .collect();
    NuscenesCurve {
        levels,
        gt,
        matched,
        min_recall: p.min_recall,
    }
}
