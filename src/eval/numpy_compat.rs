//! Bit-for-bit re-implementations of the few numpy routines whose rounding shows up in the
//! nuScenes metrics: `np.mean` (pairwise summation), `np.interp`, and `np.linspace(...).round(12)`.

/// numpy's pairwise summation of a contiguous float64 array (`pairwise_sum_DOUBLE`).
fn pairwise_sum(a: &[f64]) -> f64 {
    let n = a.len();
    if n < 8 {
        let mut res = 0.0;
        for v in a {
            res += v;
        }
        res
    } else if n <= 128 {
        let mut r = [0.0f64; 8];
        r.copy_from_slice(&a[..8]);
        let mut i = 8;
        while i < n - (n % 8) {
            for j in 0..8 {
                r[j] += a[i + j];
            }
            i += 8;
        }
        let mut res = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]));
        while i < n {
            res += a[i];
            i += 1;
        }
        res
    } else {
        let mut n2 = n / 2;
        n2 -= n2 % 8;
        pairwise_sum(&a[..n2]) + pairwise_sum(&a[n2..])
    }
}

/// `np.sum` of a contiguous 1-d float64 array: pairwise summation of the whole array (valid for
/// arrays shorter than numpy's 8192-element buffer).
pub fn np_sum(a: &[f64]) -> f64 {
    pairwise_sum(a)
}

/// `np.mean` of a 1-d float64 array.
pub fn np_mean(a: &[f64]) -> f64 {
    np_sum(a) / a.len() as f64
}

/// `np.interp(x, xp, fp, right=right)` for strictly increasing `xp` (left = `fp[0]`).
pub fn np_interp(x: f64, xp: &[f64], fp: &[f64], right: f64) -> f64 {
    let n = xp.len();
    if x.is_nan() {
        return x;
    }
    if x == xp[n - 1] {
        return fp[n - 1];
    }
    if x > xp[n - 1] {
        return right;
    }
    if x < xp[0] {
        return fp[0];
    }
    // Largest j with xp[j] <= x.
    let j = xp.partition_point(|v| *v <= x) - 1;
    if j == n - 1 {
        return fp[j];
    }
    if xp[j] == x {
        return fp[j];
    }
    let slope = (fp[j + 1] - fp[j]) / (xp[j + 1] - xp[j]);
    let mut r = slope * (x - xp[j]) + fp[j];
    if r.is_nan() {
        r = slope * (x - xp[j + 1]) + fp[j + 1];
        if r.is_nan() && fp[j] == fp[j + 1] {
            r = fp[j];
        }
    }
    r
}

/// `np.linspace(start, stop, num).round(12)`.
pub fn linspace_round12(start: f64, stop: f64, num: usize) -> Vec<f64> {
    let div = (num - 1) as f64;
    let step = (stop - start) / div;
    (0..num)
        .map(|i| {
            let v = if i == num - 1 {
                stop
            } else {
                i as f64 * step + start
            };
            (v * 1e12).round_ties_even() / 1e12
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mean_of_three_tenths_is_not_a_tenth() {
        // numpy: np.mean([0.1, 0.1, 0.1]) == 0.10000000000000002
        assert_eq!(np_mean(&[0.1, 0.1, 0.1]), 0.10000000000000002);
        assert_eq!(np_mean(&[0.5, 0.25]), 0.375);
    }

    /// Values printed by numpy 1.26.4 (`np.mean([0.3] * n)`, `np.sum([0.1 * i + 0.37 ...])`).
    #[test]
    fn matches_numpy_rounding() {
        let mean = |n: usize| np_mean(&vec![0.3; n]);
        assert_eq!(mean(9), 0.3);
        assert_eq!(mean(10), 0.29999999999999993);
        assert_eq!(mean(11), 0.29999999999999993);
        assert_eq!(mean(16), 0.3);
        assert_eq!(mean(129), 0.30000000000000004);
        let sum = |n: usize| np_sum(&(0..n).map(|i| 0.1 * i as f64 + 0.37).collect::<Vec<_>>());
        assert_eq!(sum(3), 1.4100000000000001);
        assert_eq!(sum(40), 92.80000000000001);
        assert_eq!(sum(129), 873.3299999999999);
        assert_eq!(sum(300), 4596.0);
    }

    #[test]
    fn pairwise_blocks() {
        let a: Vec<f64> = (0..300).map(|i| 0.1 * i as f64).collect();
        let s = np_sum(&a);
        let exact: f64 = (0..300).map(|i| i as f64).sum::<f64>() * 0.1;
        assert!((s - exact).abs() < 1e-9);
    }

    #[test]
    fn interp_like_numpy() {
        let xp = [0.25, 0.5, 0.75, 1.0];
        let fp = [0.9, 0.8, 0.5, 0.1];
        assert_eq!(np_interp(0.1, &xp, &fp, 0.0), 0.9);
        assert_eq!(np_interp(0.5, &xp, &fp, 0.0), 0.8);
        assert!((np_interp(0.625, &xp, &fp, 0.0) - 0.65).abs() < 1e-15);
        assert_eq!(np_interp(1.0, &xp, &fp, 0.0), 0.1);
        assert_eq!(np_interp(1.5, &xp, &fp, 0.0), 0.0);
    }

    #[test]
    fn recall_levels() {
        let r = linspace_round12(0.1, 1.0, 40);
        assert_eq!(r.len(), 40);
        assert_eq!(r[0], 0.1);
        assert_eq!(r[39], 1.0);
        assert_eq!(r[1], 0.123076923077);
    }
}
