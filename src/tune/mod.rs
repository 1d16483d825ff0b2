//! `probmot tune`: per-class settings chosen by search on logs with ground truth, with an
//! honest K-fold cross-validation (noise fitted and settings tuned on the training folds only,
//! scores measured on the held-out fold). Everything runs in memory: the logs are read once,
//! tracked and evaluated with the library.

pub mod cache;
pub mod data;
pub mod files;
pub mod gains;
pub mod score;
pub mod search;
pub mod shared;
pub mod space;
pub mod text;

use std::collections::BTreeMap;

use crate::pipeline::progress::ProgressFn;
use anyhow::{anyhow, Result};

pub use data::TuneLog;
pub use score::{Protocol, Scoring};
pub use search::{ClassTune, SearchLimits, Step};

use crate::eval::kitti_box::KittiBox;
use crate::eval::scene::Scene;
use crate::fit::{fit_gathered, fitted_config, FitAccumulator, FitOptions, YawMode};
use crate::tracker::{ClassConfig, TrackerConfig};
use cache::ScoreCache;
use space::{at, dims, restrict, ScoreStats};

/// Settings of a tune.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct TuneOptions {
    /// Protocol whose headline metric is maximised.
    pub scoring: Scoring,
    /// Search bounds per class.
    pub limits: SearchLimits,
    /// Period of the config's velocities; `None`: the data's median frame period.
    pub dt_nominal: Option<f64>,
    /// Minimum matched pairs for fitted noise (as `probmot fit --min-samples`).
    pub min_samples: u64,
    /// Classes to tune and score; empty: every class of the protocol.
    pub classes: Vec<String>,
    /// Search dimensions to search ([`space::DIM_NAMES`]); empty: all but `two_point_speed`,
    /// which is searched only when named. One option at a time gives the ablation of that
    /// option.
    pub search: Vec<String>,
    /// Classes kept at the base config's own settings whatever their trajectories (as under
    /// `min_tracks`), e.g. those whose tuning lost held-out in a cross-validation.
    pub keep_base: Vec<String>,
}

/// The shared stage of a tune (see [`shared`]).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct SharedTune {
    /// Classes whose mean training score the stage maximised (enough ground truth).
    pub classes: Vec<String>,
    /// Mean training score of those classes with the base settings.
    pub base_score: f64,
    /// The same with the shared settings.
    pub score: f64,
    /// Configurations tried.
    pub evaluations: usize,
    /// Accepted moves in order.
    pub steps: Vec<Step>,
}

/// A config fitted and tuned on some logs, with the search outcomes.
#[derive(Debug, Clone)]
pub struct Tuned {
    /// The base config with noise fitted on the logs (the starting point).
    pub fitted: TrackerConfig,
    /// The fitted config with the tuned settings of every tuned class.
    pub tuned: TrackerConfig,
    /// The shared stage.
    pub shared: SharedTune,
    /// Per class.
    pub classes: Vec<ClassTune>,
    /// Distinct class configs tracked and scored.
    pub scored: usize,
}

/// The base config with the noise fitted on `logs` (yaw residuals folded, as
/// `probmot fit --fold-yaw`).
pub fn fit_noise(
    base: &TrackerConfig,
    logs: &[&TuneLog],
    o: &TuneOptions,
) -> Result<TrackerConfig> {
    let mut acc = FitAccumulator::new();
    for l in logs {
        l.feed_fit(&mut acc);
    }
    let dt_nominal = match o.dt_nominal {
        Some(d) => d,
        None => (acc.frame_period())
            .map(|p| p.median_s)
            .filter(|p| *p > 0.0)
            .unwrap_or(base.dt_nominal),
    };
    let options = FitOptions {
        dt_nominal,
        yaw: YawMode::Folded,
        min_samples: o.min_samples,
    };
    let mut report = fit_gathered(acc, &options);
    Ok(fitted_config(base, &mut report, &options)?)
}

/// The classes a tune works on: the chosen classes (default: the protocol's) that have
/// detections in `logs`.
pub fn classes(logs: &[&TuneLog], o: &TuneOptions) -> Vec<String> {
    let wanted = if o.classes.is_empty() {
        o.scoring.classes()
    } else {
        o.classes.clone()
    };
    wanted
        .into_iter()
        .filter(|c| logs.iter().any(|l| l.scores(c).next().is_some()))
        .collect()
}

/// Ground-truth trajectories (distinct ids per log) labelled `label` in `logs`.
pub fn trajectories(logs: &[&TuneLog], label: &str) -> usize {
    logs.iter()
        .map(|l| {
            let ids: std::collections::BTreeSet<u64> = l
                .frames
                .iter()
                .flat_map(|f| f.truth.iter())
                .filter(|b| b.label() == label && b.id != 0)
                .map(|b| b.id)
                .collect();
            ids.len()
        })
        .sum()
}

/// Fits the noise on `logs`, then tunes on them: optionally first the shared settings of every
/// class (`limits.shared`, on the classes with at least `min_tracks` ground-truth trajectories),
/// then each of those classes on its own from there. Classes with fewer trajectories keep the
/// base config's own settings (noise not fitted), or the shared ones with `limits.shared`: too
/// few trajectories support no data-driven choice.
pub fn tune(
    base: &TrackerConfig,
    logs: &[&TuneLog],
    o: &TuneOptions,
    progress: ProgressFn<'_>,
) -> Result<Tuned> {
    let fitted = fit_noise(base, logs, o)?;
    let starts: BTreeMap<String, ClassConfig> = classes(logs, o)
        .into_iter()
        .filter_map(|l| fitted.class(&l).cloned().map(|c| (l, c)))
        .collect();
    let traj: BTreeMap<&str, usize> = starts
        .keys()
        .map(|l| (l.as_str(), trajectories(logs, l)))
        .collect();
    let signal: Vec<String> = starts
        .keys()
        .filter(|l| traj[l.as_str()] >= o.limits.min_tracks && !o.keep_base.contains(l))
        .cloned()
        .collect();
    let cache = ScoreCache::new(logs, &fitted, o.scoring);
    let two_point = space::searches_two_point(&o.search);
    // The reporting options pooled over the searched classes (none chosen: every point keeps).
    let (reporting, point) = pooled_reporting(&cache, &starts, &signal, o, progress)?;
    let keep = |label: &str| {
        let own = base.class(label).unwrap_or(&starts[label]);
        at(own, &reporting, &point)
    };
    let pooled: BTreeMap<String, ClassConfig> = starts
        .iter()
        .map(|(l, c)| (l.clone(), at(c, &reporting, &point)))
        .collect();
    let (sd, shared) =
        shared::tune_shared(&cache, &pooled, &signal, o.limits, &o.search, progress)?;
    let mut tuned = fitted.clone();
    // Classes the tune does not score, and the default entry, get the pooled reporting too.
    tuned.for_each_class(|c| *c = at(c, &reporting, &point));
    let mut out = Vec::new();
    for (label, start) in &starts {
        let refined = signal.contains(label);
        let (d, config) = if refined {
            let stats = ScoreStats::of(logs.iter().flat_map(|l| l.scores(label)).collect());
            let own = base.class(label);
            let space = restrict(dims(stats, &shared[label], own, two_point), &o.search);
            let (d, cc) =
                search::tune_class(&cache, label, &shared[label], &space, o.limits, progress)?;
            (Some(d), cc)
        } else if o.limits.shared {
            (None, shared[label].clone())
        } else {
            (None, keep(label))
        };
        let shared_score = cache.score(label, &shared[label])?;
        tuned.classes.insert(label.clone(), config.clone());
        out.push(ClassTune {
            label: label.clone(),
            trajectories: traj[label.as_str()],
            base_score: cache.score(label, start)?,
            shared_score,
            refined,
            score: match &d {
                Some(d) => d.score,
                None => cache.score(label, &config)?,
            },
            evaluations: d.as_ref().map_or(0, |d| d.evaluations),
            steps: d.map(|d| d.steps).unwrap_or_default(),
            config,
        });
    }
    let scored = cache.len();
    drop(cache);
    Ok(Tuned {
        fitted,
        tuned,
        shared: SharedTune {
            classes: signal,
            base_score: sd.start,
            score: sd.score,
            evaluations: sd.evaluations,
            steps: sd.steps,
        },
        classes: out,
        scored,
    })
}

/// With `limits.pool_reporting`: the reporting dimensions and the point of them chosen on the
/// mean training score of the `signal` classes (within `o.search` when it is given). Without:
/// no dimension.
fn pooled_reporting(
    cache: &ScoreCache,
    starts: &BTreeMap<String, ClassConfig>,
    signal: &[String],
    o: &TuneOptions,
    progress: ProgressFn<'_>,
) -> Result<(Vec<space::Dim>, Vec<usize>)> {
    let mut names: Vec<String> = space::REPORTING_NAMES.map(String::from).to_vec();
    names.retain(|n| o.search.is_empty() || o.search.contains(n));
    if !o.limits.pool_reporting || names.is_empty() {
        return Ok((Vec::new(), Vec::new()));
    }
    let limits = SearchLimits {
        shared: true,
        ..o.limits
    };
    let (d, _) = shared::tune_shared(cache, starts, signal, limits, &names, progress)?;
    Ok((restrict(space::shared_dims(), &names), d.point))
}

/// The folds of `n` logs: `k` contiguous chunks in input order, sizes differing by at most one
/// (the first chunks take the remainder). With ten logs and `k = 2`: the first five and the last
/// five, as in `scripts/kitti_benchmark.sh`.
pub fn folds(n: usize, k: usize) -> Vec<std::ops::Range<usize>> {
    let k = k.clamp(1, n.max(1));
    let (q, r) = (n / k, n % k);
    let mut start = 0;
    (0..k)
        .map(|i| {
            let len = q + usize::from(i < r);
            let range = start..start + len;
            start += len;
            range
        })
        .collect()
}

/// One fold of a cross-validation.
#[derive(Debug, Clone, serde::Serialize)]
pub struct FoldReport {
    /// Held-out logs.
    pub held_out: Vec<String>,
    /// Held-out score per class with the base config (noise fitted on the training folds).
    pub base: BTreeMap<String, f64>,
    /// Held-out score per class with the config tuned on the training folds.
    pub tuned: BTreeMap<String, f64>,
    /// The shared stage on the training folds.
    pub shared: SharedTune,
    /// The per-class search on the training folds.
    pub search: Vec<ClassTune>,
}

/// A cross-validation: per fold, and over all held-out logs together (each tracked with the
/// config of the fold that held it out), which is how `scripts/kitti_benchmark.sh` scores.
#[derive(Debug, Clone, serde::Serialize)]
pub struct CvReport {
    /// Per fold.
    pub folds: Vec<FoldReport>,
    /// All held-out logs together, base config.
    pub base: BTreeMap<String, f64>,
    /// All held-out logs together, tuned configs.
    pub tuned: BTreeMap<String, f64>,
    /// KITTI: `base` with each track's mean score computed once (not official; empty for
    /// nuScenes).
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub base_means_once: BTreeMap<String, f64>,
    /// KITTI: `tuned` with each track's mean score computed once.
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub tuned_means_once: BTreeMap<String, f64>,
    /// All held-out logs together: per class and `overall`, the gain `tuned - base` of the
    /// headline metric with its paired 95 % bootstrap interval ([`gains::gains`]).
    pub gains: BTreeMap<String, crate::eval::bootstrap::Change>,
    /// The configs tuned per fold (for re-scoring with `probmot track` and `probmot eval`).
    #[serde(skip)]
    pub fold_configs: Vec<TrackerConfig>,
}

/// A class searched on a fold's training logs whose tuned settings scored below the base on the
/// held-out fold: the sign that its training logs were too few to tune it (see `--min-tracks`).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct HeldOutLoss {
    /// Fold (1-based, as the table prints it).
    pub fold: usize,
    /// Class label.
    pub label: String,
    /// Its ground-truth trajectories in the fold's training logs.
    pub trajectories: usize,
    /// Held-out score of the base config.
    pub base: f64,
    /// Held-out score of the tuned config.
    pub tuned: f64,
}

impl CvReport {
    /// The (fold, searched class) pairs whose tuned held-out score is below the base's by more
    /// than `margin`, in fold and class order. Classes that kept the base config's own settings
    /// (too few trajectories) are not listed: nothing was tuned on them.
    pub fn losses(&self, margin: f64) -> Vec<HeldOutLoss> {
        let mut out = Vec::new();
        for (i, f) in self.folds.iter().enumerate() {
            for c in f.search.iter().filter(|c| c.refined) {
                let base = f.base.get(&c.label).copied().unwrap_or(f64::NAN);
                let tuned = f.tuned.get(&c.label).copied().unwrap_or(f64::NAN);
                if base.is_finite() && tuned.is_finite() && tuned < base - margin {
                    out.push(HeldOutLoss {
                        fold: i + 1,
                        label: c.label.clone(),
                        trajectories: c.trajectories,
                        base,
                        tuned,
                    });
                }
            }
        }
        out
    }
}

/// Mean over the classes with a value (the protocol's overall figure for sAMOTA and AMOTA).
pub fn overall(scores: &BTreeMap<String, f64>) -> f64 {
    let v: Vec<f64> = scores.values().copied().filter(|v| v.is_finite()).collect();
    if v.is_empty() {
        f64::NAN
    } else {
        v.iter().sum::<f64>() / v.len() as f64
    }
}

fn track_all(logs: &[&TuneLog], cfg: &TrackerConfig) -> Result<Vec<Scene<KittiBox>>> {
    logs.iter().map(|l| score::track_log(l, cfg)).collect()
}

/// K-fold cross-validation of [`tune`] against the fitted base config.
pub fn cross_validate(
    base: &TrackerConfig,
    logs: &[TuneLog],
    k: usize,
    o: &TuneOptions,
    progress: ProgressFn<'_>,
) -> Result<CvReport> {
    if k < 2 || logs.len() < k {
        return Err(anyhow!(
            "--folds {k} needs at least 2 folds and one log per fold ({} log(s) given)",
            logs.len()
        ));
    }
    let all: Vec<&TuneLog> = logs.iter().collect();
    let classes = classes(&all, o);
    let (mut base_scenes, mut tuned_scenes) = (Vec::new(), Vec::new());
    let mut reports = Vec::new();
    let mut fold_configs = Vec::new();
    for range in folds(logs.len(), k) {
        let held: Vec<&TuneLog> = all[range.clone()].to_vec();
        let train: Vec<&TuneLog> = all
            .iter()
            .enumerate()
            .filter(|(i, _)| !range.contains(i))
            .map(|(_, l)| *l)
            .collect();
        let t = tune(base, &train, o, progress)?;
        let b = track_all(&held, &t.fitted)?;
        let u = track_all(&held, &t.tuned)?;
        reports.push(FoldReport {
            held_out: held.iter().map(|l| l.name.clone()).collect(),
            base: o.scoring.evaluate(&b, &classes),
            tuned: o.scoring.evaluate(&u, &classes),
            shared: t.shared,
            search: t.classes,
        });
        base_scenes.extend(b);
        tuned_scenes.extend(u);
        fold_configs.push(t.tuned);
    }
    let (base, base_means_once) = o.scoring.evaluate_with_once(&base_scenes, &classes);
    let (tuned, tuned_means_once) = o.scoring.evaluate_with_once(&tuned_scenes, &classes);
    let gains = gains::gains(&o.scoring, (&base_scenes, &tuned_scenes), &classes);
    Ok(CvReport {
        gains,
        folds: reports,
        base,
        tuned,
        base_means_once,
        tuned_means_once,
        fold_configs,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn losses_are_the_searched_classes_tuned_below_the_base_held_out() {
        let scores = |v: &[(&str, f64)]| -> BTreeMap<String, f64> {
            v.iter().map(|(k, x)| (k.to_string(), *x)).collect()
        };
        let searched = |label: &str, refined: bool| ClassTune {
            label: label.into(),
            trajectories: 17,
            base_score: 0.0,
            shared_score: 0.0,
            refined,
            score: 0.0,
            evaluations: 0,
            steps: vec![],
            config: TrackerConfig::preset("ab3dmot-kitti").unwrap().classes["car"].clone(),
        };
        let fold = |base: &[(&str, f64)], tuned: &[(&str, f64)], search| FoldReport {
            held_out: vec![],
            base: scores(base),
            tuned: scores(tuned),
            shared: SharedTune {
                classes: vec![],
                base_score: 0.0,
                score: 0.0,
                evaluations: 0,
                steps: vec![],
            },
            search,
        };
        let cv = CvReport {
            folds: vec![
                fold(
                    &[("car", 0.7), ("pedestrian", 0.58)],
                    &[("car", 0.77), ("pedestrian", 0.06)],
                    vec![searched("car", true), searched("pedestrian", true)],
                ),
                fold(
                    &[("car", 0.9), ("pedestrian", 0.65), ("cyclist", f64::NAN)],
                    &[("car", 0.898), ("pedestrian", 0.62), ("cyclist", 0.0)],
                    vec![
                        searched("car", true),
                        searched("pedestrian", false),
                        searched("cyclist", true),
                    ],
                ),
            ],
            base: BTreeMap::new(),
            tuned: BTreeMap::new(),
            base_means_once: BTreeMap::new(),
            tuned_means_once: BTreeMap::new(),
            gains: BTreeMap::new(),
            fold_configs: vec![],
        };
        let l = cv.losses(0.005);
        assert_eq!(l.len(), 1, "{l:?}");
        assert_eq!(
            (l[0].fold, l[0].label.as_str(), l[0].trajectories),
            (1, "pedestrian", 17)
        );
        // Without a margin the small car loss counts; the unsearched pedestrian never does.
        let l0: Vec<_> = cv
            .losses(0.0)
            .into_iter()
            .map(|l| (l.fold, l.label))
            .collect();
        assert_eq!(l0, [(1, "pedestrian".to_string()), (2, "car".to_string())]);
    }

    #[test]
    fn folds_are_contiguous_and_cover() {
        assert_eq!(folds(10, 2), vec![0..5, 5..10]);
        assert_eq!(folds(7, 3), vec![0..3, 3..5, 5..7]);
        assert_eq!(folds(2, 5), vec![0..1, 1..2]);
    }
}
