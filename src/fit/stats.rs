//! Running mean and variance (population variance, `ddof = 0`, like numpy's `np.var` default
//! that the paper's reference statistics used) and the median.

use serde::Serialize;

/// Mean and population variance of a stream of numbers (Welford's algorithm: one pass, stable).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Moments {
    /// Number of samples.
    pub n: u64,
    /// Mean of the samples.
    pub mean: f64,
    /// Sum of squared deviations from the mean.
    #[serde(skip)]
    m2: f64,
}

impl Moments {
    /// No samples yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds one sample.
    pub fn push(&mut self, x: f64) {
        self.n += 1;
        let d = x - self.mean;
        self.mean += d / self.n as f64;
        self.m2 += d * (x - self.mean);
    }

    /// Population variance `sum (x - mean)^2 / n` (`ddof = 0`); `None` without samples.
    pub fn variance(&self) -> Option<f64> {
        (self.n > 0).then(|| (self.m2 / self.n as f64).max(0.0))
    }
}

/// Median of a list (mean of the two middle values for an even count); `None` when empty.
/// NaNs are not expected (callers pass finite values).
pub fn median(values: &[f64]) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let m = v.len() / 2;
    Some(if v.len() % 2 == 1 {
        v[m]
    } else {
        0.5 * (v[m - 1] + v[m])
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn population_variance_like_numpy() {
        // np.var([1, 2, 3, 4]) == 1.25 (ddof=0).
        let mut m = Moments::new();
        for x in [1.0, 2.0, 3.0, 4.0] {
            m.push(x);
        }
        assert_eq!(m.n, 4);
        assert!((m.mean - 2.5).abs() < 1e-15);
        assert!((m.variance().unwrap() - 1.25).abs() < 1e-15);
        assert_eq!(Moments::new().variance(), None);
        let mut one = Moments::new();
        one.push(7.0);
        assert_eq!(one.variance(), Some(0.0));
    }

    #[test]
    fn variance_is_stable_with_a_large_offset() {
        let mut m = Moments::new();
        for x in [1e9 + 1.0, 1e9 + 2.0, 1e9 + 3.0] {
            m.push(x);
        }
        assert!((m.variance().unwrap() - 2.0 / 3.0).abs() < 1e-6);
    }

    #[test]
    fn median_of_odd_and_even_lists() {
        assert_eq!(median(&[]), None);
        assert_eq!(median(&[3.0, 1.0, 2.0]), Some(2.0));
        assert_eq!(median(&[4.0, 1.0, 3.0, 2.0]), Some(2.5));
    }
}
