//! Measurement noise `R` and the initial velocity uncertainty: residuals `detection - truth` of
//! the pairs matched in each frame, and the frame-to-frame change of that residual for the same
//! true instance (the paper's statistics).
//!
//! Matching, per frame and label: optimal assignment (scipy's algorithm, as the reference used
//! the Hungarian method) on the bird's-eye-view centre distance; pairs at or over
//! [`MATCH_RADIUS_M`] may not be matched.

use std::collections::{BTreeMap, HashMap};

use serde::Serialize;

use super::data::{FitFrame, FitLog};
use super::stats::Moments;
use crate::eval::mot_accumulator::assign_with_missing_edges;
use crate::mcapio::LabelledBox;
use crate::tracker::angle::{fold_half_turn, wrap};

/// Pairs whose BEV centre distance is at least this many metres are never matched.
pub const MATCH_RADIUS_M: f64 = 2.0;

/// How a heading residual is reduced.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum YawMode {
    /// Wrapped to `[-pi, pi)`: a detection facing backwards counts as a residual near `pi`
    /// (what the reference statistics did).
    Wrapped,
    /// Folded to `[-pi/2, pi/2]`: a 180-degree flip counts as aligned, as the tracker's
    /// distance and orientation correction treat it.
    Folded,
}

impl YawMode {
    /// Reduces an angle difference.
    pub fn reduce(self, a: f64) -> f64 {
        match self {
            YawMode::Wrapped => wrap(a),
            YawMode::Folded => fold_half_turn(a),
        }
    }
}

/// Accumulated residual statistics of one label.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MeasurementStats {
    /// Residual `detection - truth` of `x y z yaw l w h`; yaw wrapped.
    pub residual: [Moments; 7],
    /// The yaw residual folded.
    pub yaw_folded: Moments,
    /// Change of the residual of `x y z yaw` between consecutive frames of one instance;
    /// yaw wrapped.
    pub change: [Moments; 4],
    /// The change of the folded yaw residual, folded.
    pub change_yaw_folded: Moments,
}

impl MeasurementStats {
    /// Number of matched pairs.
    pub fn pairs(&self) -> u64 {
        self.residual[0].n
    }

    /// Variance of the residual of field `i` (`x y z yaw l w h`), yaw in the given mode.
    pub fn residual_variance(&self, i: usize, mode: YawMode) -> Option<f64> {
        match (i, mode) {
            (3, YawMode::Folded) => self.yaw_folded.variance(),
            _ => self.residual[i].variance(),
        }
    }

    /// Variance of the frame-to-frame change of the residual of `x y z yaw` (index `i`).
    pub fn change_variance(&self, i: usize, mode: YawMode) -> Option<f64> {
        match (i, mode) {
            (3, YawMode::Folded) => self.change_yaw_folded.variance(),
            _ => self.change[i].variance(),
        }
    }
}

/// Per label statistics.
pub type MeasurementStatsByLabel = BTreeMap<String, MeasurementStats>;

/// Bird's-eye-view distance between two box centres.
pub fn bev_distance(a: &LabelledBox, b: &LabelledBox) -> f64 {
    (a.center[0] - b.center[0]).hypot(a.center[1] - b.center[1])
}

/// Matches truth boxes with detections (all of one label): minimum total BEV centre distance
/// with pairs at or over [`MATCH_RADIUS_M`] invalid. Returns `(truth index, detection index)`.
pub fn match_frame(truth: &[&LabelledBox], detections: &[&LabelledBox]) -> Vec<(usize, usize)> {
    let (n, m) = (truth.len(), detections.len());
    let dist: Vec<f64> = truth
        .iter()
        .flat_map(|t| {
            detections.iter().map(move |d| {
                let v = bev_distance(t, d);
                if v < MATCH_RADIUS_M {
                    v
                } else {
                    f64::NAN
                }
            })
        })
        .collect();
    let mut cost = dist.clone();
    assign_with_missing_edges(&mut cost, n, m)
        .into_iter()
        .filter(|&(i, j)| dist[i * m + j].is_finite())
        .collect()
}

/// Residual `detection - truth` of `x y z yaw l w h`, the yaw wrapped to `[-pi, pi)`.
pub fn residual(detection: &LabelledBox, truth: &LabelledBox) -> [f64; 7] {
    let d = detection.measurement();
    let t = truth.measurement();
    let mut r: [f64; 7] = std::array::from_fn(|i| d[i] - t[i]);
    r[3] = wrap(r[3]);
    r
}

/// Residual of the previous frame of one instance: frame index, `x y z` and wrapped yaw, and
/// folded yaw.
type LastResidual = (usize, [f64; 4], f64);

/// Adds the matched pairs of one log to `stats`. Only boxes of the same label are matched;
/// boxes with non-finite fields are ignored. The change of the residual is taken between
/// adjacent frames of the log where the same true instance is matched in both.
pub fn accumulate_measurement_noise(log: &FitLog, stats: &mut MeasurementStatsByLabel) {
    let mut state = MeasurementState::default();
    for frame in &log.frames {
        state.push(frame, stats);
    }
}

/// [`accumulate_measurement_noise`] frame by frame: what it keeps between frames is the last
/// residual of each matched instance.
#[derive(Default)]
pub struct MeasurementState {
    last: HashMap<(String, u64), LastResidual>,
    k: usize,
}

impl MeasurementState {
    /// Adds the matched pairs of the log's next frame.
    pub fn push(&mut self, frame: &FitFrame, stats: &mut MeasurementStatsByLabel) {
        let k = self.k;
        self.k += 1;
        let mut by_label: BTreeMap<&str, (Vec<&LabelledBox>, Vec<&LabelledBox>)> = BTreeMap::new();
        for t in frame.truth.iter().filter(|b| b.is_finite()) {
            by_label.entry(&t.label).or_default().0.push(t);
        }
        for d in frame.detections.iter().filter(|b| b.is_finite()) {
            if let Some(e) = by_label.get_mut(d.label.as_str()) {
                e.1.push(d);
            }
        }
        for (label, (truth, dets)) in by_label {
            let s = stats.entry(label.to_string()).or_default();
            for (i, j) in match_frame(&truth, &dets) {
                let r = residual(dets[j], truth[i]);
                for (m, v) in s.residual.iter_mut().zip(r) {
                    m.push(v);
                }
                let folded = fold_half_turn(r[3]);
                s.yaw_folded.push(folded);
                let now = [r[0], r[1], r[2], r[3]];
                let key = (label.to_string(), truth[i].id);
                if let Some((kp, prev, prev_folded)) = self.last.get(&key) {
                    if *kp + 1 == k {
                        for c in 0..3 {
                            s.change[c].push(now[c] - prev[c]);
                        }
                        s.change[3].push(wrap(now[3] - prev[3]));
                        s.change_yaw_folded
                            .push(fold_half_turn(folded - prev_folded));
                    }
                }
                self.last.insert(key, (k, now, folded));
            }
        }
        // A residual older than this frame can never pair again.
        self.last.retain(|_, v| v.0 == k);
    }
}

#[cfg(test)]
mod tests {
    use super::super::data::FitFrame;
    use super::*;
    use std::f64::consts::PI;

    fn b(id: u64, label: &str, x: f64, y: f64, yaw: f64) -> LabelledBox {
        LabelledBox {
            id,
            label: label.into(),
            center: [x, y, 1.0],
            size: [4.0, 2.0, 1.5],
            yaw,
            ..Default::default()
        }
    }

    #[test]
    fn optimal_assignment_with_radius() {
        // Truth 0 is 0.1 m from detection 0 and 1.0 m from detection 1; truth 1 can only take
        // detection 0 (1.5 m). Taking the closest pair first would leave truth 1 unmatched; the
        // optimal assignment (with invalid pairs as expensive edges) matches both.
        let t = [b(1, "car", 0.0, 0.0, 0.0), b(2, "car", 1.6, 0.0, 0.0)];
        let d = [b(0, "car", 0.1, 0.0, 0.0), b(0, "car", -1.0, 0.0, 0.0)];
        let tr: Vec<&LabelledBox> = t.iter().collect();
        let de: Vec<&LabelledBox> = d.iter().collect();
        let mut p = match_frame(&tr, &de);
        p.sort_unstable();
        assert_eq!(p, vec![(0, 1), (1, 0)]);
        // Nothing within 2 m: no pair; exactly 2 m is not a pair either.
        let far = [b(0, "car", 2.0, 0.0, 0.0)];
        let fa: Vec<&LabelledBox> = far.iter().collect();
        assert!(match_frame(&tr[..1], &fa).is_empty());
        assert!(match_frame(&tr, &[]).is_empty());
    }

    #[test]
    fn residual_wraps_and_folds() {
        let r = residual(
            &b(0, "car", 1.0, 2.0, -PI + 0.1),
            &b(1, "car", 0.5, 2.5, PI - 0.1),
        );
        assert_eq!(r[0], 0.5);
        assert_eq!(r[1], -0.5);
        assert!((r[3] - 0.2).abs() < 1e-12);
        // A flipped detection: wrapped near pi, folded near 0.
        let r = residual(
            &b(0, "car", 0.0, 0.0, 0.05 + PI),
            &b(1, "car", 0.0, 0.0, 0.0),
        );
        assert!((r[3].abs() - (PI - 0.05)).abs() < 1e-12);
        assert!((YawMode::Folded.reduce(r[3]) - 0.05).abs() < 1e-12);
    }

    #[test]
    fn labels_pairs_and_changes() {
        let frames = vec![
            // Frame 0: car 1 matched (error 0.1 in x); a pedestrian detection next to the car
            // is of another label and never matched with it.
            FitFrame {
                stamp: 0,
                truth: vec![b(1, "car", 0.0, 0.0, 0.0)],
                detections: vec![
                    b(0, "car", 0.1, 0.0, 0.0),
                    b(0, "pedestrian", 0.0, 0.0, 0.0),
                ],
            },
            // Frame 1: error 0.3.
            FitFrame {
                stamp: 1,
                truth: vec![b(1, "car", 10.0, 0.0, 0.0)],
                detections: vec![b(0, "car", 10.3, 0.0, PI)],
            },
            // Frame 2: missed. Frame 3: error -0.1; no change sample (gap).
            FitFrame {
                stamp: 2,
                truth: vec![b(1, "car", 20.0, 0.0, 0.0)],
                detections: vec![],
            },
            FitFrame {
                stamp: 3,
                truth: vec![b(1, "car", 30.0, 0.0, 0.0)],
                detections: vec![b(0, "car", 29.9, 0.0, 0.0)],
            },
        ];
        let log = FitLog {
            name: "t".into(),
            frames,
            unmatched_detection_messages: 0,
            skipped_detections: Default::default(),
            skipped_truth: 0,
        };
        let mut s = MeasurementStatsByLabel::new();
        accumulate_measurement_noise(&log, &mut s);
        assert!(!s.contains_key("pedestrian"));
        let car = &s["car"];
        assert_eq!(car.pairs(), 3);
        // x residuals 0.1 0.3 -0.1: mean 0.1, population variance 0.08/3.
        let vx = car.residual_variance(0, YawMode::Wrapped).unwrap();
        assert!((vx - 0.08 / 3.0).abs() < 1e-12, "{vx}");
        assert_eq!(car.change[0].n, 1);
        assert!((car.change[0].mean - 0.2).abs() < 1e-12);
        // Yaw residuals 0, -pi (wrapped), 0: folded all 0.
        assert!(car.residual_variance(3, YawMode::Wrapped).unwrap() > 2.0);
        assert!(car.residual_variance(3, YawMode::Folded).unwrap() < 1e-20);
        assert!(car.change_variance(3, YawMode::Folded).unwrap() < 1e-20);
    }
}
