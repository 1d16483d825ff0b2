//! The data's frame period and the conversion of per-frame statistics to the config's nominal
//! period `dt_nominal`.
//!
//! The statistics are taken per data frame of period `T` (the median stamp difference); a config
//! expresses velocities and `Q` per nominal frame of period `D = dt_nominal`.
//!
//! * `Q` is rescaled by `(D / T)^3`. Model: the velocity performs a random walk (white
//!   acceleration), so its change over a period `t` has variance `q_c t`, and the second
//!   difference of positions sampled every `t` (that change times `t`) has variance `q_c t^3`.
//!   The fitted value at `T` is therefore converted to what the same statistic would be on data
//!   recorded at `D`. This is also what the tracker needs: its velocity state is a displacement
//!   per nominal frame (a factor `(D/T)^2` on a variance) and it adds `k Q` over `k = T/D`
//!   nominal frames (a factor `D/T`). The position entries reuse the velocity value (the paper's
//!   rule `Q_x = Q_dx`), so they get the same factor. Yaw is treated like position.
//! * `R` is the noise of one measurement and does not depend on the period: not scaled.
//! * The velocity entries of `P0` (variance of the change of the detection error between
//!   consecutive frames, i.e. of a velocity from two detections in displacement per data frame)
//!   are converted to displacement per nominal frame: a factor `(D / T)^2`.
//!
//! When `T == D` (the usual case, e.g. nuScenes keyframes at 2 Hz and `dt_nominal` 0.5 s) every
//! factor is exactly 1.

use serde::Serialize;

use super::stats::median;

/// An interval is "irregular" when it differs from the median by more than this fraction.
pub const IRREGULAR_FRACTION: f64 = 0.1;

/// Frame timing of the data.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FramePeriod {
    /// Median difference of consecutive frame stamps over all logs, seconds.
    pub median_s: f64,
    /// Number of frame intervals.
    pub intervals: u64,
    /// Intervals differing from the median by more than [`IRREGULAR_FRACTION`]: second
    /// differences across them mix periods (the fit still uses them).
    pub irregular: u64,
}

/// The interval between two consecutive frame stamps (ns), seconds.
pub fn interval_s(a: u64, b: u64) -> f64 {
    (b - a) as f64 * 1e-9
}

/// The frame timing of the frame intervals `dts` (seconds, within each log; see
/// [`super::FitAccumulator::frame_period`]); `None` without any interval.
pub fn period_of_intervals(dts: &[f64]) -> Option<FramePeriod> {
    let m = median(dts)?;
    let irregular = dts
        .iter()
        .filter(|d| (*d - m).abs() > IRREGULAR_FRACTION * m)
        .count() as u64;
    Some(FramePeriod {
        median_s: m,
        intervals: dts.len() as u64,
        irregular,
    })
}

/// A warning when the logs' own frame periods (`(name, median interval)`) differ by more than
/// [`IRREGULAR_FRACTION`]: the fit pools their intervals at one period (`pooled`) that may be
/// none of them (a 2 Hz and a 10 Hz log pool at 0.3 s), and its second differences mix them.
pub fn mixed_periods(periods: &[(&str, f64)], pooled: f64) -> Option<String> {
    let (lo, hi) = periods
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), (_, p)| {
            (lo.min(*p), hi.max(*p))
        });
    if periods.len() < 2 || hi - lo <= IRREGULAR_FRACTION * lo {
        return None;
    }
    let each: Vec<String> = periods
        .iter()
        .map(|(n, p)| format!("{n} {p:.4} s"))
        .collect();
    Some(format!(
        "the logs have different frame periods ({}); the fit pools them at {pooled:.4} s: fit \
         logs of one frame rate together",
        each.join(", ")
    ))
}

/// Factor applied to the fitted `Q` (per data frame of `data_period` seconds) to express it per
/// nominal frame of `dt_nominal` seconds: `(dt_nominal / data_period)^3`.
pub fn q_scale(data_period: f64, dt_nominal: f64) -> f64 {
    (dt_nominal / data_period).powi(3)
}

/// Factor applied to the fitted velocity entries of `P0`: `(dt_nominal / data_period)^2`.
pub fn velocity_variance_scale(data_period: f64, dt_nominal: f64) -> f64 {
    (dt_nominal / data_period).powi(2)
}

#[cfg(test)]
mod tests {
    use super::super::data::{FitFrame, FitLog};
    use super::*;

    fn log(stamps: &[u64]) -> FitLog {
        FitLog {
            name: "t".into(),
            frames: stamps
                .iter()
                .map(|&stamp| FitFrame {
                    stamp,
                    ..Default::default()
                })
                .collect(),
            unmatched_detection_messages: 0,
            skipped_detections: Default::default(),
            skipped_truth: 0,
        }
    }

    /// The frame timing of `logs` fed whole to the fit's accumulator.
    fn frame_period(logs: &[FitLog]) -> Option<FramePeriod> {
        let mut acc = super::super::FitAccumulator::new();
        for l in logs {
            acc.add_log(l);
        }
        acc.frame_period()
    }

    #[test]
    fn median_period_over_logs() {
        let a = log(&[0, 100_000_000, 200_000_000, 400_000_000]);
        let b = log(&[5_000_000_000, 5_100_000_000]);
        let p = frame_period(&[a, b]).unwrap();
        assert!((p.median_s - 0.1).abs() < 1e-12);
        assert_eq!(p.intervals, 4);
        assert_eq!(p.irregular, 1);
        assert_eq!(frame_period(&[log(&[7])]), None);
    }

    #[test]
    fn scaling_of_a_velocity_random_walk() {
        assert_eq!(q_scale(0.5, 0.5), 1.0);
        assert_eq!(velocity_variance_scale(0.5, 0.5), 1.0);
        // Velocity random walk with q_c = 2 (m/s)^2 per second: second differences of positions
        // at T = 0.1 s have variance q_c T^3; at D = 0.5 s, q_c D^3.
        let qc = 2.0;
        let at = |t: f64| qc * t * t * t;
        assert!((at(0.1) * q_scale(0.1, 0.5) - at(0.5)).abs() < 1e-12);
        // A velocity error of e m per 0.1 s frame is 5 e m per 0.5 s frame.
        assert!((velocity_variance_scale(0.1, 0.5) - 25.0).abs() < 1e-12);
    }
}
