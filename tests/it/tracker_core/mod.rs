//! Integration tests of the tracker core, one file per area: life cycle, ids and classes, the
//! 180-degree flip, property tests of the Kalman filter, the matchers and the tracker, the
//! sharp-turn case of Figure 2 of Chiu et al. (2019), and the config options. Shared helpers
//! are here.

mod config_options;
mod flip;
mod hot_loop;
mod ids_classes;
mod life_cycle;
mod properties;
mod sharp_turn;

use std::collections::{HashMap, HashSet};
use std::f64::consts::{FRAC_PI_2, PI};

use probmot::tracker::angle::wrap;
use probmot::tracker::geometry::{giou3d, iou3d};
use probmot::tracker::kalman::{mahalanobis, KalmanState, Noise, StateCov};
use probmot::tracker::matching::{greedy, hungarian, Pair, NOT_A_CANDIDATE};
use probmot::tracker::{
    Box3, BoxOrigin, ClassConfig, Detection, DistanceKind, MatcherKind, TrackReport, Tracker,
    TrackerConfig,
};
use proptest::prelude::*;

/// nuScenes keyframes are 0.5 s apart.
const HALF_SECOND_NS: u64 = 500_000_000;

fn tracker(preset: &str) -> Tracker {
    Tracker::new(TrackerConfig::preset(preset).unwrap()).unwrap()
}

fn car_box(x: f64, y: f64, yaw: f64) -> Box3 {
    Box3 {
        center: [x, y, 0.8],
        yaw,
        size: [4.5, 1.9, 1.6],
    }
}

fn det(class: u32, bbox: Box3) -> Detection {
    Detection {
        bbox,
        class,
        score: 0.9,
    }
}

fn step(t: &mut Tracker, frame: u64, dets: &[Detection]) -> Vec<TrackReport> {
    t.step(frame * HALF_SECOND_NS, dets).unwrap().to_vec()
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol
}

/// A tiny deterministic pseudo-random sequence (64-bit LCG, Knuth's constants).
struct Lcg(u64);

impl Lcg {
    fn next_f64(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
    /// Uniform in `[-a, a)`.
    fn sym(&mut self, a: f64) -> f64 {
        (2.0 * self.next_f64() - 1.0) * a
    }
}
