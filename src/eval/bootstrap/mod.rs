//! Paired bootstrap intervals for the tracking metrics: is a change a regression or noise?
//!
//! The data are cut into resampling units: whole logs when there are at least [`MIN_LOGS`] of
//! them, else fixed-length time blocks within the logs (a block bootstrap: errors of a tracker
//! are correlated over a track's life, so single frames would be far too optimistic). A
//! resample draws as many units as there are, with replacement, and gives each unit a weight
//! (how often it was drawn). Two runs over the same truth (`this` and a baseline) are
//! resampled with the same weights — a paired bootstrap — and the 2.5 % and 97.5 % quantiles
//! of the resampled changes form the 95 % interval (the percentile method). Identical runs
//! change by exactly 0 in every resample: the interval is [0, 0].
//!
//! Speed: the matching is done once. Each protocol's passes (one per score threshold of its
//! recall curve) are run once over all the data, and every unit keeps its own counts per pass
//! ([`curve`]); a resample only sums the counts with its weights and recomputes the
//! aggregate metrics. Where the protocol does not allow this exactly, we hold something fixed:
//! the score thresholds of the recall levels are those of the full data (the protocols derive
//! them from the pooled matched scores, which a resample would move slightly), and KITTI's
//! tracks keep the mean scores and the matching of the full data. Identity switches are
//! counted in the unit of the frame they happen in.
//!
//! Determinism: resample `i` draws from its own ChaCha8 stream seeded by `(seed, i)`, so the
//! result is the same for a seed whatever the number of threads.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::Serialize;

#[cfg(test)]
mod coverage;
pub mod curve;
pub mod paired;
pub mod report;

/// Fewer logs than this are resampled by time blocks within them.
pub const MIN_LOGS: usize = 20;
/// The block length (seconds) when the logs are too few and none is given.
pub const DEFAULT_BLOCK_S: f64 = 10.0;

/// How the frames of the logs are cut into resampling units.
#[derive(Debug, Clone, PartialEq)]
pub struct Units {
    /// Per log, per frame: its unit.
    pub of_frame: Vec<Vec<u32>>,
    /// Number of units.
    pub count: usize,
    /// The block length in seconds, or `None` when the units are whole logs.
    pub block_s: Option<f64>,
}

impl Units {
    /// Units for logs with the given frame stamps (ns): a block of `block_s` seconds when
    /// given, else whole logs when there are at least [`MIN_LOGS`], else blocks of
    /// [`DEFAULT_BLOCK_S`].
    pub fn choose(stamps: &[&[u64]], block_s: Option<f64>) -> Units {
        Units::choose_paired(&[stamps.to_vec()], block_s).remove(0)
    }

    /// [`Units::choose`] for several runs over the same logs (their frames may differ where
    /// the tracks have stamps the truth has not): one [`Units`] per run, numbered alike, so a
    /// unit is the same stretch of time in every run.
    pub fn choose_paired(runs: &[Vec<&[u64]>], block_s: Option<f64>) -> Vec<Units> {
        let logs = runs.first().map_or(0, Vec::len);
        match block_s {
            Some(b) => Units::blocks(runs, b),
            None if logs >= MIN_LOGS => runs.iter().map(|r| Units::logs(r)).collect(),
            None => Units::blocks(runs, DEFAULT_BLOCK_S),
        }
    }

    /// One unit per log.
    pub fn logs(stamps: &[&[u64]]) -> Units {
        let of_frame = (stamps.iter().enumerate())
            .map(|(i, s)| vec![i as u32; s.len()])
            .collect();
        Units {
            of_frame,
            count: stamps.len(),
            block_s: None,
        }
    }

    /// Blocks of `block_s` seconds from each log's first frame (over all runs); a log's last
    /// block may be shorter. Blocks without a frame in any run are no units.
    pub fn blocks(runs: &[Vec<&[u64]>], block_s: f64) -> Vec<Units> {
        let len = (block_s * 1e9).max(1.0);
        let logs = runs.first().map_or(0, Vec::len);
        let mut out: Vec<Units> = (runs.iter())
            .map(|_| Units {
                of_frame: Vec::with_capacity(logs),
                count: 0,
                block_s: Some(block_s),
            })
            .collect();
        let mut count = 0u32;
        for li in 0..logs {
            let t0 = (runs.iter().filter_map(|r| r[li].first()))
                .min()
                .copied()
                .unwrap_or(0);
            let block = |t: u64| ((t - t0) as f64 / len) as u64;
            let mut ids: Vec<u64> = (runs.iter())
                .flat_map(|r| r[li].iter().map(|&t| block(t)))
                .collect();
            ids.sort_unstable();
            ids.dedup();
            for (run, units) in runs.iter().zip(&mut out) {
                let of = run[li].iter().map(|&t| {
                    let k = ids.binary_search(&block(t)).expect("every block is listed");
                    count + k as u32
                });
                units.of_frame.push(of.collect());
            }
            count += ids.len() as u32;
        }
        for u in &mut out {
            u.count = count as usize;
        }
        out
    }

    /// The unit of frame `fi` of log `si`; frames past the log's end (the KITTI devkit's extra
    /// empty frame) belong to its last unit.
    pub fn unit(&self, si: usize, fi: usize) -> usize {
        let f = &self.of_frame[si];
        f.get(fi).or(f.last()).map_or(0, |&u| u as usize)
    }
}

/// The options of a bootstrap.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Options {
    /// Number of resamples.
    pub resamples: usize,
    /// Seed of the random draws.
    pub seed: u64,
}

/// The weights of resample `i`: how often each of `n` units was drawn (`n` draws).
pub fn weights(n: usize, seed: u64, i: usize) -> Vec<u32> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(i as u64);
    let mut w = vec![0u32; n];
    for _ in 0..n {
        w[rng.random_range(0..n)] += 1;
    }
    w
}

/// `f` (a vector of metrics) over every resample of `n` units, in resample order, computed in
/// parallel.
pub fn resample<F>(n: usize, o: Options, f: F) -> Vec<Vec<f64>>
where
    F: Fn(&[u32]) -> Vec<f64> + Sync,
{
    (0..o.resamples)
        .into_par_iter()
        .map(|i| f(&weights(n, o.seed, i)))
        .collect()
}

/// The central 95 % of the finite values (linear interpolation between order statistics);
/// NaN when there is none.
pub fn interval95(values: impl Iterator<Item = f64>) -> [f64; 2] {
    let mut v: Vec<f64> = values.filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return [f64::NAN; 2];
    }
    v.sort_by(f64::total_cmp);
    [quantile(&v, 0.025), quantile(&v, 0.975)]
}

/// Quantile `q` of sorted values (the default of R and numpy: linear between order statistics).
fn quantile(sorted: &[f64], q: f64) -> f64 {
    let h = (sorted.len() - 1) as f64 * q;
    let (lo, hi) = (h.floor() as usize, h.ceil() as usize);
    sorted[lo] + (h - lo as f64) * (sorted[hi] - sorted[lo])
}

/// One metric with its 95 % interval.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Estimate {
    /// The value on all the data.
    #[serde(serialize_with = "super::nan_as_null")]
    pub value: f64,
    /// The 95 % bootstrap interval.
    #[serde(serialize_with = "nan_pair")]
    pub ci95: [f64; 2],
}

/// The change of one metric from a baseline, with its paired 95 % interval.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Change {
    /// `this - baseline` on all the data.
    #[serde(serialize_with = "super::nan_as_null")]
    pub delta: f64,
    /// The 95 % paired bootstrap interval of the change.
    #[serde(serialize_with = "nan_pair")]
    pub ci95: [f64; 2],
    /// The value of this run.
    #[serde(serialize_with = "super::nan_as_null")]
    pub this: f64,
    /// The value of the baseline.
    #[serde(serialize_with = "super::nan_as_null")]
    pub baseline: f64,
}

impl Change {
    /// Whether the whole interval lies below zero: a fall that is not noise at 95 %.
    pub fn below_zero(&self) -> bool {
        self.ci95[1] < 0.0
    }
}

fn nan_pair<S: serde::Serializer>(v: &[f64; 2], s: S) -> Result<S::Ok, S::Error> {
    use serde::ser::SerializeTuple;
    let mut t = s.serialize_tuple(2)?;
    for x in v {
        t.serialize_element(&x.is_finite().then_some(*x))?;
    }
    t.end()
}

/// Per metric (index into the vectors `f` returns): its value on all the data (all weights 1)
/// and its interval over the resamples.
pub fn estimates<F>(n: usize, o: Options, f: F) -> Vec<Estimate>
where
    F: Fn(&[u32]) -> Vec<f64> + Sync,
{
    let all = f(&vec![1; n]);
    let runs = resample(n, o, &f);
    (all.iter().enumerate())
        .map(|(k, &value)| Estimate {
            value,
            ci95: interval95(runs.iter().map(|r| r[k])),
        })
        .collect()
}

/// Per metric: the change of `this` from `base` (both computed from the same weights, i.e. the
/// same resample of the same units), with its paired interval.
pub fn changes<F, G>(n: usize, o: Options, this: F, base: G) -> Vec<Change>
where
    F: Fn(&[u32]) -> Vec<f64> + Sync,
    G: Fn(&[u32]) -> Vec<f64> + Sync,
{
    let ones = vec![1; n];
    let (a, b) = (this(&ones), base(&ones));
    let deltas = resample(n, o, |w| {
        let (t, o) = (this(w), base(w));
        t.iter().zip(&o).map(|(t, o)| t - o).collect()
    });
    (a.iter().zip(&b).enumerate())
        .map(|(k, (&t, &o))| Change {
            delta: t - o,
            ci95: interval95(deltas.iter().map(|r| r[k])),
            this: t,
            baseline: o,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weights_draw_n_units_and_depend_only_on_seed_and_index() {
        let w = weights(7, 3, 11);
        assert_eq!(w.iter().sum::<u32>(), 7);
        assert_eq!(w, weights(7, 3, 11));
        assert_ne!(weights(50, 3, 11), weights(50, 3, 12));
        assert_ne!(weights(50, 3, 11), weights(50, 4, 11));
    }

    #[test]
    fn blocks_cut_each_log_from_its_first_frame() {
        let a = [0u64, 4_000_000_000, 10_000_000_000, 25_000_000_000];
        let b = [7u64, 8];
        let u = Units::choose(&[&a, &b], Some(10.0));
        assert_eq!(u.of_frame, vec![vec![0, 0, 1, 2], vec![3, 3]]);
        assert_eq!(u.count, 4);
        assert_eq!(u.unit(1, 5), 3);
        assert_eq!(
            Units::choose(&[&a, &b], None).block_s,
            Some(DEFAULT_BLOCK_S)
        );
        // A run with a frame the other lacks: units numbered alike in both.
        let c = [0u64, 15_000_000_000];
        let p = Units::choose_paired(&[vec![&a, &b], vec![&c, &b]], Some(10.0));
        assert_eq!(p[0].of_frame, vec![vec![0, 0, 1, 2], vec![3, 3]]);
        assert_eq!(p[1].of_frame, vec![vec![0, 1], vec![3, 3]]);
        let many: Vec<&[u64]> = vec![&b; MIN_LOGS];
        assert_eq!(Units::choose(&many, None).count, MIN_LOGS);
    }

    #[test]
    fn interval_of_a_known_sample_and_identical_runs() {
        let v = (0..=100).map(f64::from);
        assert_eq!(interval95(v), [2.5, 97.5]);
        let o = Options {
            resamples: 50,
            seed: 1,
        };
        let mean = |w: &[u32]| {
            let s: f64 = w
                .iter()
                .enumerate()
                .map(|(i, &k)| i as f64 * k as f64)
                .sum();
            vec![s / w.len() as f64]
        };
        let c = changes(9, o, mean, mean);
        assert_eq!((c[0].delta, c[0].ci95), (0.0, [0.0, 0.0]));
        let e = estimates(9, o, mean);
        assert_eq!(e[0].value, 4.0);
        assert!(e[0].ci95[0] < 4.0 && e[0].ci95[1] > 4.0, "{:?}", e[0]);
    }
}
