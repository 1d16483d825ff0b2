//! Per-class scores of the class configs a tune has evaluated, so that a candidate seen before
//! (in an earlier round, in the shared stage, or one that tracks the same as another: see
//! [`super::space::key`]) is not tracked and scored again. Classes are tracked independently, so
//! a class's score depends only on its own settings.

use std::collections::HashMap;
use std::sync::Mutex;

use anyhow::Result;

use super::data::TuneLog;
use super::score::{class_truth, score_class_with, single_class, ClassTruth, Scoring};
use super::space::key;
use crate::tracker::{ClassConfig, TrackerConfig};

/// One class's truth, prepared for its evaluation once per tune.
type SharedTruth = std::sync::Arc<ClassTruth>;

/// Scores of one tune's logs, by class and config key.
pub struct ScoreCache<'a> {
    logs: &'a [&'a TuneLog],
    cfg: &'a TrackerConfig,
    scoring: Scoring,
    /// Per class: the truth as its evaluation reads it.
    truth: Mutex<HashMap<String, SharedTruth>>,
    map: Mutex<HashMap<(String, String), f64>>,
}

/// NaN (a class the protocol could not evaluate) ranks below every score.
fn finite_or_min(v: f64) -> f64 {
    if v.is_nan() {
        f64::NEG_INFINITY
    } else {
        v
    }
}

impl<'a> ScoreCache<'a> {
    /// An empty cache for `logs`; `cfg` gives the period the class configs are tracked with.
    pub fn new(logs: &'a [&'a TuneLog], cfg: &'a TrackerConfig, scoring: Scoring) -> Self {
        ScoreCache {
            logs,
            cfg,
            scoring,
            truth: Mutex::new(HashMap::new()),
            map: Mutex::new(HashMap::new()),
        }
    }

    /// The score of `label` tracked with `cc` on the logs (`-inf` when not evaluable).
    pub fn score(&self, label: &str, cc: &ClassConfig) -> Result<f64> {
        let k = (label.to_string(), key(cc));
        if let Some(v) = self.map.lock().expect("cache lock").get(&k) {
            return Ok(*v);
        }
        let truth = self.truth_of(label);
        let cfg = single_class(self.cfg, label, cc.clone());
        let v = finite_or_min(score_class_with(self.logs, &truth, &cfg, label)?);
        self.map.lock().expect("cache lock").insert(k, v);
        Ok(v)
    }

    /// The truth the evaluation of `label` reads, prepared once.
    fn truth_of(&self, label: &str) -> SharedTruth {
        let mut m = self.truth.lock().expect("cache lock");
        m.entry(label.to_string())
            .or_insert_with(|| std::sync::Arc::new(class_truth(self.logs, label, &self.scoring)))
            .clone()
    }

    /// Number of distinct configs scored so far (tracked and evaluated once each).
    pub fn len(&self) -> usize {
        self.map.lock().expect("cache lock").len()
    }

    /// Whether nothing was scored yet.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}
