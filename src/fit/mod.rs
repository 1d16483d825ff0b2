//! `probmot fit`: per-class noise statistics (`Q`, `R`, `P0`) from logs with ground truth and
//! detections, the way the paper's reference implementation made its nuScenes statistics (see
//! `/work/shared/reference/chiu2019-constants.md`, "How the statistics were made").
//!
//! * `Q` ([`process`]): variance of the truth's second differences of `x y z yaw` over each
//!   instance's consecutive frames, reused on the velocity entries, 0 on `l w h`.
//! * `R` ([`measurement`]): variance of `detection - truth` per field over pairs matched in each
//!   frame by optimal assignment on BEV centre distance (< 2 m), same label only.
//! * `P0`: `R` on the measured entries; on the velocity entries the variance of the
//!   frame-to-frame change of the detection error of one instance (falling back to `Q`).
//!
//! Every variance is a population variance (`ddof = 0`, numpy's `np.var` default, as the
//! reference used). Statistics are per data frame and converted to the config's `dt_nominal`
//! ([`timing`]). [`apply`] writes them into a [`TrackerConfig`](crate::tracker::TrackerConfig).
//!
//! The statistics are pure functions of [`FitLog`]s; [`load`] reads those from MCAP files.

pub mod accumulate;
pub mod apply;
pub mod data;
pub mod files;
pub mod load;
pub mod measurement;
pub mod process;
pub mod stats;
pub mod timing;

use std::collections::BTreeSet;

use serde::Serialize;

pub use apply::fitted_config;
pub use data::{FitFrame, FitLog};
pub use measurement::YawMode;
pub use timing::FramePeriod;

use crate::msgs::detection_frame::describe_skips;
pub use accumulate::FitAccumulator;
use timing::{mixed_periods, q_scale, velocity_variance_scale};

/// Settings of a fit.
#[derive(Debug, Clone, PartialEq)]
pub struct FitOptions {
    /// Period (seconds) the config's velocities and `Q` are expressed in.
    pub dt_nominal: f64,
    /// Yaw residual used for `R` and `P0` in the config (both are reported).
    pub yaw: YawMode,
    /// Classes with fewer matched pairs keep the base config's values; `Q` and the velocity
    /// entries of `P0` need as many samples of their own.
    pub min_samples: u64,
}

/// How the variances are computed (reported for the record).
pub const VARIANCE_KIND: &str = "population (ddof=0)";

/// The fitted statistics of one class. Variances are `None` without samples.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ClassFit {
    /// Class label.
    pub label: String,
    /// Matched detection/truth pairs (samples of `R`).
    pub n_pairs: u64,
    /// Truth second differences (samples of `Q`).
    pub n_q_samples: u64,
    /// Frame-to-frame changes of the detection error (samples of the velocity entries of `P0`).
    pub n_p0_velocity_samples: u64,
    /// `R` diagonal `x y z yaw l w h`, yaw in the selected mode.
    pub r: Option<[f64; 7]>,
    /// Mean residual `detection - truth` of `x y z yaw l w h` (yaw wrapped): detector bias, which
    /// the tracker assumes to be zero.
    pub residual_mean: Option<[f64; 7]>,
    /// Variance of the yaw residual wrapped to `[-pi, pi)` (180-degree flips count as errors
    /// near `pi`).
    pub r_yaw_wrapped: Option<f64>,
    /// Variance of the yaw residual folded to `[-pi/2, pi/2]` (flips count as aligned).
    pub r_yaw_folded: Option<f64>,
    /// `Q` of `x y z yaw` per nominal frame (the per-data-frame variance times the `q_scale`).
    pub q: Option<[f64; 4]>,
    /// Velocity entries of `P0` (`dx dy dz dyaw`) per nominal frame, yaw in the selected mode.
    pub p0_velocity: Option<[f64; 4]>,
    /// The `dyaw` entry of `P0` with the wrapped yaw.
    pub p0_dyaw_wrapped: Option<f64>,
    /// The `dyaw` entry of `P0` with the folded yaw.
    pub p0_dyaw_folded: Option<f64>,
    /// Whether the config got this class's fitted values (set by [`fitted_config`]).
    pub applied: bool,
}

/// Everything a fit found: inputs, timing, per-class statistics and warnings.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FitReport {
    /// Logs used.
    pub logs: Vec<String>,
    /// Frames (distinct truth stamps) over all logs.
    pub frames: u64,
    /// Ground-truth boxes over all frames.
    pub truth_boxes: u64,
    /// Detections in those frames.
    pub detections: u64,
    /// Detection messages whose stamp is no truth stamp (not used).
    pub unmatched_detection_messages: u64,
    /// Frame timing of the data; `None` with fewer than two frames per log.
    pub period: Option<FramePeriod>,
    /// Nominal period of the config, seconds.
    pub dt_nominal: f64,
    /// Factor from per-data-frame to per-nominal-frame `Q` (see [`timing`]).
    pub q_scale: f64,
    /// Factor from per-data-frame to per-nominal-frame `P0` velocity entries.
    pub p0_velocity_scale: f64,
    /// Yaw residual written to the config.
    pub yaw_mode: YawMode,
    /// How variances are computed.
    pub variance: &'static str,
    /// Minimum number of samples for a fitted value.
    pub min_samples: u64,
    /// Per class, by label.
    pub classes: Vec<ClassFit>,
    /// Things the user should know (also printed on stderr by the CLI).
    pub warnings: Vec<String>,
}

fn arr<const N: usize>(f: impl Fn(usize) -> Option<f64>) -> Option<[f64; N]> {
    let v: Vec<f64> = (0..N).map_while(&f).collect();
    v.try_into().ok()
}

/// Computes the per-class statistics of the logs (pooled; instance ids and consecutive frames
/// are only considered within a log).
pub fn fit(logs: &[FitLog], options: &FitOptions) -> FitReport {
    let mut acc = FitAccumulator::new();
    for log in logs {
        acc.add_log(log);
    }
    fit_gathered(acc, options)
}

/// [`fit`] of what an accumulator gathered (logs fed whole or frame by frame).
pub fn fit_gathered(acc: FitAccumulator, options: &FitOptions) -> FitReport {
    let mut warnings: Vec<String> = (acc.skipped.iter())
        .map(|(name, counts)| {
            let skipped = describe_skips(counts);
            format!("{name}: skipped {skipped}, as `probmot track` skips them")
        })
        .collect();
    warnings.extend(acc.skipped_truth.iter().map(|(name, n)| {
        format!("{name}: skipped {n} ground-truth boxes with a non-finite centre, size or yaw")
    }));
    let (pstats, mstats) = (&acc.process, &acc.measurement);
    let period = acc.frame_period();
    let data_period = match period {
        Some(p) if p.median_s > 0.0 => p.median_s,
        _ => {
            warnings.push(
                "no two frames in any log: the frame period is unknown; Q is taken as per \
                 nominal frame"
                    .to_string(),
            );
            options.dt_nominal
        }
    };
    if let Some(w) = mixed_periods(&acc.log_periods(), data_period) {
        warnings.push(w);
    }
    if let Some(p) = period {
        if p.irregular > 0 {
            warnings.push(format!(
                "{} of {} frame intervals differ from the median period {:.4} s by more than \
                 {:.0}%; second differences across them mix periods",
                p.irregular,
                p.intervals,
                p.median_s,
                timing::IRREGULAR_FRACTION * 100.0
            ));
        }
    }
    let qs = q_scale(data_period, options.dt_nominal);
    let vs = velocity_variance_scale(data_period, options.dt_nominal);
    let labels: BTreeSet<&String> = pstats.keys().chain(mstats.keys()).collect();
    let classes = labels
        .into_iter()
        .map(|label| {
            let m = mstats.get(label).cloned().unwrap_or_default();
            let p = pstats.get(label).copied().unwrap_or_default();
            let yaw = options.yaw;
            ClassFit {
                label: label.clone(),
                n_pairs: m.pairs(),
                n_q_samples: p[0].n,
                n_p0_velocity_samples: m.change[0].n,
                r: arr(|i| m.residual_variance(i, yaw)),
                residual_mean: (m.pairs() > 0).then(|| std::array::from_fn(|i| m.residual[i].mean)),
                r_yaw_wrapped: m.residual_variance(3, YawMode::Wrapped),
                r_yaw_folded: m.residual_variance(3, YawMode::Folded),
                q: arr(|i| p[i].variance().map(|v| v * qs)),
                p0_velocity: arr(|i| m.change_variance(i, yaw).map(|v| v * vs)),
                p0_dyaw_wrapped: m.change_variance(3, YawMode::Wrapped).map(|v| v * vs),
                p0_dyaw_folded: m.change_variance(3, YawMode::Folded).map(|v| v * vs),
                applied: false,
            }
        })
        .collect();
    FitReport {
        logs: acc.names,
        frames: acc.frames,
        truth_boxes: acc.truth_boxes,
        detections: acc.detections,
        unmatched_detection_messages: acc.unmatched_detection_messages,
        period,
        dt_nominal: options.dt_nominal,
        q_scale: qs,
        p0_velocity_scale: vs,
        yaw_mode: options.yaw,
        variance: VARIANCE_KIND,
        min_samples: options.min_samples,
        classes,
        warnings,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mcapio::LabelledBox;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, Normal};

    /// A synthetic log: `n` cars whose velocity takes a random step of std `q_std` per frame,
    /// detected every frame with noise `r_std` on x (other fields exact).
    fn synthetic(n: u64, frames: usize, dt_s: f64, q_std: f64, r_std: f64) -> FitLog {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let step = Normal::new(0.0, q_std).unwrap();
        let noise = Normal::new(0.0, r_std).unwrap();
        let mut truth = vec![Vec::new(); frames];
        let mut dets = vec![Vec::new(); frames];
        for id in 1..=n {
            let (mut x, mut v) = (id as f64 * 100.0, 1.0);
            for f in 0..frames {
                let b = LabelledBox {
                    id,
                    label: "car".into(),
                    center: [x, 0.0, 1.0],
                    size: [4.0, 2.0, 1.5],
                    ..Default::default()
                };
                let mut d = b.clone();
                d.id = 0;
                d.center[0] += noise.sample(&mut rng);
                truth[f].push(b);
                dets[f].push(d);
                x += v * dt_s;
                v += step.sample(&mut rng);
            }
        }
        let stamp = |f: usize| (f as f64 * dt_s * 1e9).round() as u64;
        data::assemble_frames(
            "synthetic",
            truth
                .into_iter()
                .enumerate()
                .map(|(f, t)| (stamp(f), t))
                .collect(),
            dets.into_iter()
                .enumerate()
                .map(|(f, d)| (stamp(f), d))
                .collect(),
        )
    }

    #[test]
    fn recovers_synthetic_noise_and_rescales_q() {
        let (q_std, r_std) = (0.3, 0.2);
        let opts = FitOptions {
            dt_nominal: 0.1,
            yaw: YawMode::Wrapped,
            min_samples: 50,
        };
        let rep = fit(&[synthetic(20, 200, 0.1, q_std, r_std)], &opts);
        assert_eq!(rep.classes.len(), 1);
        let car = &rep.classes[0];
        assert_eq!(car.n_pairs, 20 * 200);
        assert_eq!(car.n_q_samples, 20 * 198);
        assert_eq!(car.n_p0_velocity_samples, 20 * 199);
        assert_eq!(rep.q_scale, 1.0);
        let r = car.r.unwrap();
        assert!((r[0] / (r_std * r_std) - 1.0).abs() < 0.1, "{r:?}");
        assert!(r[1] == 0.0 && r[3] == 0.0);
        // Second differences: velocity step times dt.
        let q = car.q.unwrap();
        let truth = (q_std * 0.1f64).powi(2);
        assert!((q[0] / truth - 1.0).abs() < 0.1, "{} vs {truth}", q[0]);
        assert_eq!(q[1], 0.0);
        // Change of an independent error: twice its variance.
        let p0v = car.p0_velocity.unwrap();
        assert!(
            (p0v[0] / (2.0 * r_std * r_std) - 1.0).abs() < 0.1,
            "{p0v:?}"
        );

        // The same data with a nominal period of 0.5 s: Q scaled by 5^3, P0 velocity by 5^2.
        let opts5 = FitOptions {
            dt_nominal: 0.5,
            ..opts
        };
        let rep5 = fit(&[synthetic(20, 200, 0.1, q_std, r_std)], &opts5);
        assert!((rep5.q_scale - 125.0).abs() < 1e-9);
        let c5 = &rep5.classes[0];
        assert!((c5.q.unwrap()[0] / q[0] - 125.0).abs() < 1e-6);
        assert!((c5.p0_velocity.unwrap()[0] / p0v[0] - 25.0).abs() < 1e-6);
        assert_eq!(c5.r, car.r);
    }

    #[test]
    fn empty_input_gives_empty_report() {
        let rep = fit(
            &[],
            &FitOptions {
                dt_nominal: 0.5,
                yaw: YawMode::Folded,
                min_samples: 50,
            },
        );
        assert!(rep.classes.is_empty());
        assert_eq!(rep.q_scale, 1.0);
        assert_eq!(rep.warnings.len(), 1);
    }
}
