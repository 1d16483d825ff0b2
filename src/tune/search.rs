//! Coordinate descent over a search space: starting at candidate 0 of every dimension, each
//! round tries every candidate of one dimension at a time (in parallel) and moves to the best
//! when it beats the current score by more than the margin; rounds repeat until none improves or
//! the budget is spent. [`tune_class`] runs it on one class's settings.

use crate::pipeline::progress::{Progress, ProgressFn};
use anyhow::Result;
use rayon::prelude::*;

use super::cache::ScoreCache;
use super::space::{at, describe, Dim};
use crate::tracker::ClassConfig;

/// Bounds of a search and the rules that keep it from fitting noise.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct SearchLimits {
    /// Largest number of configurations tried per search (the shared stage, then each class).
    pub budget: usize,
    /// Largest number of coordinate-descent rounds.
    pub rounds: usize,
    /// A move must raise the training score by more than this (sAMOTA/AMOTA as a fraction).
    pub margin: f64,
    /// A class is refined on its own only with at least this many ground-truth trajectories in
    /// the training logs; with fewer it keeps the base config's own settings (or the shared
    /// ones with `shared`).
    pub min_tracks: usize,
    /// Run the shared stage (class-agnostic settings chosen jointly) before the per-class search.
    pub shared: bool,
    /// Choose the reporting options (`coast`, `backfill`) once for every class first, on the
    /// mean training score of the searched classes; the other classes get them too.
    pub pool_reporting: bool,
}

impl Default for SearchLimits {
    fn default() -> Self {
        SearchLimits {
            budget: 100,
            rounds: 3,
            margin: 0.005,
            min_tracks: 10,
            shared: false,
            pool_reporting: false,
        }
    }
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

/// The outcome of a coordinate descent.
#[derive(Debug, Clone, PartialEq)]
pub struct Descent {
    /// Candidate index per dimension.
    pub point: Vec<usize>,
    /// Score at the start.
    pub start: f64,
    /// Score at `point`.
    pub score: f64,
    /// Candidates tried (cached ones included).
    pub evaluations: usize,
    /// Accepted moves in order.
    pub steps: Vec<Step>,
}

/// Coordinate descent from the origin of `dims`. `valid` filters candidates, `eval` scores them
/// (called in parallel). Deterministic: candidates are compared in a fixed order and a move needs
/// a score above the current one plus `limits.margin`. A start that cannot be scored (`-inf`)
/// is kept as it is.
pub fn descend<V, E>(
    dims: &[Dim],
    limits: SearchLimits,
    valid: V,
    eval: E,
    progress: ProgressFn<'_>,
) -> Result<Descent>
where
    V: Fn(&[usize]) -> bool,
    E: Fn(&[usize]) -> Result<f64> + Sync,
{
    let mut point = vec![0usize; dims.len()];
    let start = eval(&point)?;
    progress(Progress::Advance(1));
    let (mut best, mut evaluations, mut steps) = (start, 1, Vec::new());
    let rounds = if start.is_finite() { limits.rounds } else { 0 };
    'rounds: for _ in 0..rounds {
        let mut improved = false;
        for (di, dim) in dims.iter().enumerate() {
            let mut cands: Vec<Vec<usize>> = (0..dim.values.len())
                .filter(|&j| j != point[di])
                .map(|j| {
                    let mut p = point.clone();
                    p[di] = j;
                    p
                })
                .filter(|p| valid(p))
                .collect();
            let left = limits.budget.saturating_sub(evaluations);
            if left == 0 {
                break 'rounds;
            }
            cands.truncate(left);
            evaluations += cands.len();
            let scores = cands
                .par_iter()
                .map(|p| {
                    let s = eval(p);
                    progress(Progress::Advance(1));
                    s
                })
                .collect::<Result<Vec<f64>>>()?;
            let mut pick: Option<(usize, f64)> = None;
            for (k, s) in scores.iter().enumerate() {
                if pick.is_none_or(|(_, b)| *s > b) {
                    pick = Some((k, *s));
                }
            }
            if let Some((k, s)) = pick.filter(|(_, s)| *s > best + limits.margin.max(1e-9)) {
                point = cands[k].clone();
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
    Ok(Descent {
        point,
        start,
        score: best,
        evaluations,
        steps,
    })
}

/// The outcome of tuning one class.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ClassTune {
    /// Class label.
    pub label: String,
    /// Ground-truth trajectories of the class in the training logs.
    pub trajectories: usize,
    /// Training score of the base settings (fitted noise).
    pub base_score: f64,
    /// Training score after the shared stage.
    pub shared_score: f64,
    /// Whether the class had enough trajectories to be refined on its own.
    pub refined: bool,
    /// Training score of the tuned settings.
    pub score: f64,
    /// Configurations tried in the class's own search.
    pub evaluations: usize,
    /// Accepted moves of the class's own search, in order.
    pub steps: Vec<Step>,
    /// Tuned settings.
    #[serde(skip)]
    pub config: ClassConfig,
}

/// Refines the settings of `label` from `start` (the shared stage's settings) over `dims`.
pub fn tune_class(
    cache: &ScoreCache,
    label: &str,
    start: &ClassConfig,
    dims: &[Dim],
    limits: SearchLimits,
    progress: ProgressFn<'_>,
) -> Result<(Descent, ClassConfig)> {
    let d = descend(
        dims,
        limits,
        |p| at(start, dims, p).validate().is_ok(),
        |p| cache.score(label, &at(start, dims, p)),
        progress,
    )?;
    let cc = at(start, dims, &d.point);
    Ok((d, cc))
}
