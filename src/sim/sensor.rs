//! The simulated detector: noisy boxes, misses, false positives and heading flips.

use std::f64::consts::PI;

use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::scenario::{class_profile, Scenario};
use super::{SimObject, TruthState};
use crate::tracker::angle::wrap;

/// Noise and error rates of the simulated detector for one class.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorModel {
    /// Standard deviation of the error of `x y z yaw l w h` (metres, radians).
    pub std: [f64; 7],
    /// Probability that a present object is detected.
    pub p_detect: f64,
    /// Probability that a detection's heading is off by 180 degrees.
    pub p_flip: f64,
}

/// The detector's error model of a class in a scenario. These are the "true" `R` that
/// `probmot fit` should recover: `R = std^2` (yaw without flips).
pub fn sensor_model(scenario: Scenario, label: &str) -> SensorModel {
    let base = match label {
        "pedestrian" => [0.12, 0.12, 0.08, 0.25, 0.06, 0.05, 0.06],
        "bicycle" | "motorcycle" => [0.15, 0.15, 0.08, 0.15, 0.12, 0.06, 0.06],
        "bus" | "trailer" | "truck" => [0.3, 0.3, 0.15, 0.08, 0.5, 0.15, 0.15],
        _ => [0.2, 0.2, 0.1, 0.06, 0.2, 0.08, 0.08],
    };
    match scenario {
        Scenario::TurningCar => SensorModel {
            std: base,
            p_detect: 0.97,
            p_flip: 0.0,
        },
        Scenario::Pedestrians => SensorModel {
            std: base,
            p_detect: 0.95,
            p_flip: 0.0,
        },
        Scenario::City => SensorModel {
            std: base,
            p_detect: 0.9,
            p_flip: 0.03,
        },
    }
}

/// Mean number of false positives per frame.
pub fn false_positive_rate(scenario: Scenario) -> f64 {
    match scenario {
        Scenario::TurningCar => 0.3,
        Scenario::Pedestrians => 0.5,
        Scenario::City => 3.0,
    }
}

/// One simulated detection.
#[derive(Debug, Clone, PartialEq)]
pub struct SimDetection {
    /// Class label.
    pub label: &'static str,
    /// Centre, metres.
    pub center: [f64; 3],
    /// Length, width, height.
    pub size: [f64; 3],
    /// Heading.
    pub yaw: f64,
    /// Confidence.
    pub score: f64,
    /// True instance id (0 for false positives); written as the attribute `sim_truth_id`.
    pub truth_id: u64,
}

/// Detections of one frame.
pub fn detect(
    scenario: Scenario,
    objects: &[SimObject],
    frame: usize,
    rng: &mut ChaCha8Rng,
) -> Vec<SimDetection> {
    let unit = Normal::new(0.0, 1.0).unwrap();
    let mut out = Vec::new();
    for o in objects {
        let Some(TruthState { center, yaw, .. }) = o.states[frame] else {
            continue;
        };
        let m = sensor_model(scenario, o.label);
        // Draw every random number in a fixed order, whatever happens, so that one object's
        // fate does not shift the random stream of the others.
        let detected = rng.random::<f64>() < m.p_detect;
        let flip = rng.random::<f64>() < m.p_flip;
        let e: [f64; 7] = std::array::from_fn(|i| m.std[i] * unit.sample(rng));
        let score = rng.random_range(0.5..1.0);
        if !detected || o.occluded[frame] {
            continue;
        }
        let mut det_yaw = yaw + e[3];
        if flip {
            det_yaw += PI;
        }
        out.push(SimDetection {
            label: o.label,
            center: [center[0] + e[0], center[1] + e[1], center[2] + e[2]],
            size: [
                (o.size[0] + e[4]).max(0.1),
                (o.size[1] + e[5]).max(0.1),
                (o.size[2] + e[6]).max(0.1),
            ],
            yaw: wrap(det_yaw),
            score,
            truth_id: o.id,
        });
    }
    // False positives: a Poisson number of low-score boxes near the scene.
    let lambda = false_positive_rate(scenario);
    let n_fp = poisson(lambda, rng);
    let labels: Vec<&'static str> = {
        let mut l: Vec<&'static str> = objects.iter().map(|o| o.label).collect();
        l.sort_unstable();
        l.dedup();
        l
    };
    for _ in 0..n_fp {
        let label = labels[rng
            .random_range(0..labels.len().max(1))
            .min(labels.len() - 1)];
        let (size, _, _) = class_profile(label);
        out.push(SimDetection {
            label,
            center: [
                rng.random_range(-60.0..60.0),
                rng.random_range(-60.0..60.0),
                size[2] / 2.0,
            ],
            size,
            yaw: rng.random_range(-PI..PI),
            score: rng.random_range(0.05..0.4),
            truth_id: 0,
        });
    }
    out
}

fn poisson(lambda: f64, rng: &mut ChaCha8Rng) -> u32 {
    // Knuth's method; lambda is small.
    let l = (-lambda).exp();
    let mut k = 0;
    let mut p = 1.0;
    loop {
        p *= rng.random::<f64>();
        if p <= l {
            return k;
        }
        k += 1;
    }
}
