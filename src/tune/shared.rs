//! The shared stage of a tune: the class-agnostic settings (gate, matcher, counts, noise
//! factors, modes; [`super::space::shared_dims`]) chosen jointly for every class, maximising the
//! mean training score of the classes with enough ground truth. Classes with too little ground
//! truth to be tuned on their own keep these settings (shrinkage toward the shared choice).

use std::collections::BTreeMap;

use crate::pipeline::progress::ProgressFn;
use anyhow::Result;

use super::cache::ScoreCache;
use super::search::{descend, Descent, SearchLimits};
use super::space::{at, restrict, shared_dims};
use crate::tracker::ClassConfig;

/// The shared settings applied to every class of `starts`, chosen on the mean score of the
/// `signal` classes, over the dimensions named in `only` (empty: all). Without a signal class,
/// or with `limits.shared` off, nothing moves.
pub fn tune_shared(
    cache: &ScoreCache,
    starts: &BTreeMap<String, ClassConfig>,
    signal: &[String],
    limits: SearchLimits,
    only: &[String],
    progress: ProgressFn<'_>,
) -> Result<(Descent, BTreeMap<String, ClassConfig>)> {
    let dims = restrict(shared_dims(), only);
    let limits = if signal.is_empty() || !limits.shared {
        SearchLimits {
            rounds: 0,
            ..limits
        }
    } else {
        limits
    };
    let mean = |p: &[usize]| -> Result<f64> {
        let mut sum = 0.0;
        for l in signal {
            sum += cache.score(l, &at(&starts[l], &dims, p))?;
        }
        Ok(if signal.is_empty() {
            0.0
        } else {
            sum / signal.len() as f64
        })
    };
    let valid = |p: &[usize]| starts.values().all(|c| at(c, &dims, p).validate().is_ok());
    let d = descend(&dims, limits, valid, mean, progress)?;
    let configs = starts
        .iter()
        .map(|(l, c)| (l.clone(), at(c, &dims, &d.point)))
        .collect();
    Ok((d, configs))
}
