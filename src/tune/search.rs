//! Coordinate descent over one class's search space: starting at the base config, each round
//! tries every candidate of one dimension at a time (in parallel) and moves to the best when it
//! beats the current score; rounds repeat until none improves or the budget is spent.

use anyhow::Result;
use indicatif::ProgressBar;
use rayon::prelude::*;

use super::data::TuneLog;
use super::score::{score_class, single_class, Scoring};
use super::space::{at, describe, Dim};
use crate::tracker::{ClassConfig, TrackerConfig};

/// Bounds of a search.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct SearchLimits {
    /// Largest number of configurations evaluated per class.
    pub budget: usize,
    /// Largest number of coordinate-descent rounds.
    pub rounds: usize,
}

/// One accepted move of the search.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Step {
    /// Dimension.
    pub dim: String,
    /// New value.
    pub value: String,
    /// Training score after the move.
    pub score: f64,
}

/// The outcome of tuning one class.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ClassTune {
    /// Class label.
    pub label: String,
    /// Training score of the base settings.
    pub base_score: f64,
    /// Training score of the tuned settings.
    pub score: f64,
    /// Configurations evaluated.
    pub evaluations: usize,
    /// Accepted moves in order.
    pub steps: Vec<Step>,
    /// Tuned settings.
    #[serde(skip)]
    pub config: ClassConfig,
}

fn finite_or_min(v: f64) -> f64 {
    if v.is_nan() {
        f64::NEG_INFINITY
    } else {
        v
    }
}

/// Tunes the settings of `label` on `logs`. `cfg` holds the starting settings (the fitted
/// noise); `dims` is the class's search space. Deterministic: candidates are evaluated in
/// parallel but compared in a fixed order, and a move needs a strictly better score.
pub fn tune_class(
    logs: &[&TuneLog],
    cfg: &TrackerConfig,
    label: &str,
    dims: &[Dim],
    scoring: &Scoring,
    limits: SearchLimits,
    progress: &ProgressBar,
) -> Result<ClassTune> {
    let base = cfg
        .class(label)
        .cloned()
        .ok_or_else(|| anyhow::anyhow!("the base config has no settings for class '{label}'"))?;
    let eval = |cc: ClassConfig| -> Result<f64> {
        let r = score_class(logs, &single_class(cfg, label, cc), label, scoring);
        progress.inc(1);
        r.map(finite_or_min)
    };
    let mut point = vec![0usize; dims.len()];
    let base_score = eval(base.clone())?;
    let mut best = base_score;
    let mut evaluations = 1;
    let mut steps = Vec::new();
    'rounds: for _ in 0..limits.rounds {
        let mut improved = false;
        for (di, dim) in dims.iter().enumerate() {
            let mut cands: Vec<(usize, ClassConfig)> = (0..dim.values.len())
                .filter(|&j| j != point[di])
                .filter_map(|j| {
                    let mut p = point.clone();
                    p[di] = j;
                    let cc = at(&base, dims, &p);
                    cc.validate().is_ok().then_some((j, cc))
                })
                .collect();
            let left = limits.budget.saturating_sub(evaluations);
            if left == 0 {
                break 'rounds;
            }
            cands.truncate(left);
            evaluations += cands.len();
            let scores = cands
                .par_iter()
                .map(|(_, cc)| eval(cc.clone()))
                .collect::<Result<Vec<f64>>>()?;
            let mut pick: Option<(usize, f64)> = None;
            for (k, s) in scores.iter().enumerate() {
                if pick.is_none_or(|(_, b)| *s > b) {
                    pick = Some((k, *s));
                }
            }
            if let Some((k, s)) = pick.filter(|(_, s)| *s > best + 1e-9) {
                point[di] = cands[k].0;
                best = s;
                improved = true;
                steps.push(Step {
                    dim: dim.name.to_string(),
                    value: describe(dim.values[point[di]]),
                    score: s,
                });
            }
        }
        if !improved {
            break;
        }
    }
    Ok(ClassTune {
        label: label.to_string(),
        base_score,
        score: best,
        evaluations,
        steps,
        config: at(&base, dims, &point),
    })
}
