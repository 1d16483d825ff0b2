//! Writing fitted statistics into a tracker configuration.
//!
//! Each class with at least `min_samples` matched pairs replaces `q`, `r` and `p0` of its entry
//! (an entry is created from the base `default` entry for a new label) and records the number of
//! pairs in `samples`; other classes keep the base values. Within a fitted class, `Q` needs
//! `min_samples` second differences (else the base entry's `Q` is kept) and the velocity entries
//! of `P0` need `min_samples` error changes (else they take `Q`'s values). Variances below
//! [`VARIANCE_FLOOR`] are raised to it so the config validates (a zero variance, e.g. `Q` of `z`
//! for objects on flat ground, would make the filter unable to follow any change).

use super::{FitOptions, FitReport};
use crate::tracker::config::{q_from_xyz_yaw, ConfigError};
use crate::tracker::{ClassConfig, TrackerConfig};

/// Smallest variance written to a config (m², rad²).
pub const VARIANCE_FLOOR: f64 = 1e-6;

const STATE: [&str; 11] = [
    "x", "y", "z", "yaw", "l", "w", "h", "dx", "dy", "dz", "dyaw",
];

/// Raises entries below the floor; names the raised ones as `matrix[entry]` (`offset` = state
/// index of `v[0]`).
fn floor<const N: usize>(
    v: [f64; N],
    matrix: &str,
    offset: usize,
    raised: &mut Vec<String>,
) -> [f64; N] {
    let mut out = v;
    for (i, x) in out.iter_mut().enumerate() {
        if *x < VARIANCE_FLOOR {
            *x = VARIANCE_FLOOR;
            raised.push(format!("{matrix}[{}]", STATE[offset + i]));
        }
    }
    out
}

/// The base config with the fitted classes of `report` applied (see the module doc). Sets
/// `dt_nominal` to the fit's, marks applied classes in `report` and appends warnings to it.
pub fn fitted_config(
    base: &TrackerConfig,
    report: &mut FitReport,
    options: &FitOptions,
) -> Result<TrackerConfig, ConfigError> {
    let mut cfg = base.clone();
    cfg.dt_nominal = options.dt_nominal;
    let min = options.min_samples;
    let mut warnings = Vec::new();
    let mut floored: Vec<String> = Vec::new();
    for c in &mut report.classes {
        let label = &c.label;
        let Some(r) = c.r.filter(|_| c.n_pairs >= min) else {
            warnings.push(format!(
                "class '{label}': only {} matched pairs (< --min-samples {min}); keeping the \
                 base config's values",
                c.n_pairs
            ));
            continue;
        };
        let template: ClassConfig = match cfg.classes.get(label).or(base.default.as_ref()) {
            Some(t) => t.clone(),
            None => {
                warnings.push(format!(
                    "class '{label}': the base config has no entry for it and no default entry; \
                     its non-noise settings are those of the nuscenes-chiu2019 default"
                ));
                TrackerConfig::preset("nuscenes-chiu2019")?
                    .default
                    .expect("preset has a default")
            }
        };
        let mut raised = Vec::new();
        let r = floor(r, "R", 0, &mut raised);
        let q = match c.q.filter(|_| c.n_q_samples >= min) {
            Some(q4) => q_from_xyz_yaw(floor(q4, "Q", 0, &mut raised)),
            None => {
                warnings.push(format!(
                    "class '{label}': only {} truth second differences (< {min}); keeping the \
                     base Q",
                    c.n_q_samples
                ));
                template.q
            }
        };
        let mut p0 = [0.0; 11];
        p0[..7].copy_from_slice(&r);
        match c.p0_velocity.filter(|_| c.n_p0_velocity_samples >= min) {
            Some(v) => p0[7..].copy_from_slice(&floor(v, "P0", 7, &mut raised)),
            None => {
                warnings.push(format!(
                    "class '{label}': only {} detection-error changes (< {min}); the velocity \
                     entries of P0 take Q's values",
                    c.n_p0_velocity_samples
                ));
                p0[7..].copy_from_slice(&floor([q[7], q[8], q[9], q[10]], "P0", 7, &mut raised));
            }
        }
        floored.extend(raised.into_iter().map(|e| format!("{label} {e}")));
        cfg.classes.insert(
            label.clone(),
            ClassConfig {
                q,
                r,
                p0,
                samples: Some(c.n_pairs),
                ..template
            },
        );
        c.applied = true;
    }
    if !floored.is_empty() {
        warnings.push(format!(
            "variances below {VARIANCE_FLOOR:e} raised to it (no variation in the data): {}",
            floored.join(", ")
        ));
    }
    report.warnings.extend(warnings);
    cfg.validate()?;
    Ok(cfg)
}

#[cfg(test)]
mod tests {
    use super::super::{ClassFit, YawMode};
    use super::*;

    fn class(label: &str, n: u64) -> ClassFit {
        ClassFit {
            label: label.into(),
            n_pairs: n,
            n_q_samples: n,
            n_p0_velocity_samples: 10,
            r: Some([0.04, 0.04, 0.01, 0.0036, 0.04, 0.0064, 0.0064]),
            residual_mean: Some([0.0; 7]),
            r_yaw_wrapped: Some(0.3),
            r_yaw_folded: Some(0.0036),
            q: Some([0.0156, 0.0156, 0.0, 0.01]),
            p0_velocity: Some([0.08, 0.08, 0.02, 0.007]),
            p0_dyaw_wrapped: Some(0.6),
            p0_dyaw_folded: Some(0.007),
            applied: false,
        }
    }

    fn report(classes: Vec<ClassFit>) -> FitReport {
        FitReport {
            logs: vec![],
            frames: 0,
            truth_boxes: 0,
            detections: 0,
            unmatched_detection_messages: 0,
            period: None,
            dt_nominal: 0.5,
            q_scale: 1.0,
            p0_velocity_scale: 1.0,
            yaw_mode: YawMode::Folded,
            variance: super::super::VARIANCE_KIND,
            min_samples: 50,
            classes,
            warnings: vec![],
        }
    }

    #[test]
    fn fitted_classes_replace_noise_only() {
        let base = TrackerConfig::preset("nuscenes-chiu2019").unwrap();
        let opts = FitOptions {
            dt_nominal: 0.5,
            yaw: YawMode::Folded,
            min_samples: 50,
        };
        let mut rep = report(vec![
            class("car", 100),
            class("bus", 20),
            class("robot", 60),
        ]);
        let cfg = fitted_config(&base, &mut rep, &opts).unwrap();
        let car = &cfg.classes["car"];
        assert_eq!(car.r[0], 0.04);
        assert_eq!(car.q[0], 0.0156);
        assert_eq!(car.q[7], 0.0156);
        assert_eq!(car.q[4], 0.0);
        // z had no motion: raised to the floor so the config validates.
        assert_eq!(car.q[2], VARIANCE_FLOOR);
        assert_eq!(car.p0[..7], car.r[..]);
        // Too few error changes: P0 velocity = Q velocity.
        assert_eq!(car.p0[7..], car.q[7..]);
        assert_eq!(car.samples, Some(100));
        assert_eq!(car.threshold, base.classes["car"].threshold);
        // Too few pairs: base values kept.
        assert_eq!(cfg.classes["bus"], base.classes["bus"]);
        // New label: created from the default entry.
        let robot = &cfg.classes["robot"];
        assert_eq!(robot.r[0], 0.04);
        assert_eq!(robot.distance, base.default.as_ref().unwrap().distance);
        assert!(rep.classes[0].applied && !rep.classes[1].applied && rep.classes[2].applied);
        assert!(rep.warnings.iter().any(|w| w.contains("'bus'")));
        assert!(rep
            .warnings
            .iter()
            .any(|w| w.contains("raised") && w.contains("car Q[z]")));
        // Round trip through JSON.
        assert_eq!(TrackerConfig::from_json(&cfg.to_json()).unwrap(), cfg);
    }

    #[test]
    fn new_label_without_default_entry() {
        let mut base = TrackerConfig::preset("nuscenes-chiu2019").unwrap();
        base.default = None;
        base.dt_nominal = 0.1;
        let opts = FitOptions {
            dt_nominal: 0.5,
            yaw: YawMode::Wrapped,
            min_samples: 5,
        };
        let mut c = class("robot", 60);
        c.n_p0_velocity_samples = 60;
        let mut rep = report(vec![c]);
        let cfg = fitted_config(&base, &mut rep, &opts).unwrap();
        assert_eq!(cfg.dt_nominal, 0.5);
        assert_eq!(cfg.classes["robot"].p0[7], 0.08);
        assert!(rep.warnings.iter().any(|w| w.contains("no default entry")));
    }
}
