//! Process noise `Q`: the variance of the ground truth's second differences of `x y z yaw` over
//! each instance's consecutive frames (the paper's statistic).
//!
//! For a constant-velocity motion whose velocity takes a random step each frame, the second
//! difference `p[k+1] - 2 p[k] + p[k-1]` is exactly that step times the frame period, so its
//! variance is the per-frame velocity noise in the state's "displacement per frame" units.

use std::collections::{BTreeMap, HashMap, VecDeque};

use super::data::FitLog;
use super::stats::Moments;
use crate::mcapio::LabelledBox;
use crate::tracker::angle::wrap;

/// Per label, the moments of the second differences of `x y z yaw`.
pub type ProcessStats = BTreeMap<String, [Moments; 4]>;

/// Second difference `c - 2 b + a` of `x y z yaw` for three consecutive truth boxes of one
/// instance. Yaw: both first differences are wrapped to `[-pi, pi)` and so is their difference,
/// so that crossing `+-pi` is not a jump of `2 pi`.
pub fn second_difference(a: &LabelledBox, b: &LabelledBox, c: &LabelledBox) -> [f64; 4] {
    let d = |i: usize| c.center[i] - 2.0 * b.center[i] + a.center[i];
    let yaw = wrap(wrap(c.yaw - b.yaw) - wrap(b.yaw - a.yaw));
    [d(0), d(1), d(2), yaw]
}

/// Adds the second differences of one log to `stats`. Frames are consecutive when adjacent in
/// the log's frame list; an instance (same label and id) absent from a frame breaks its
/// sequence, so no difference spans a gap. Boxes with non-finite fields are ignored.
pub fn accumulate_process_noise(log: &FitLog, stats: &mut ProcessStats) {
    let mut window = ProcessWindow::default();
    for f in &log.frames {
        window.push(f.truth.clone(), stats);
    }
}

/// One frame's truth boxes and, per instance `(label, id)`, the position of the box that
/// counts (the last finite one with that key).
type IndexedFrame = (Vec<LabelledBox>, HashMap<(String, u64), usize>);

/// [`accumulate_process_noise`] frame by frame, holding only the last three frames: each frame
/// is the middle of a second difference when its successor arrives.
#[derive(Default)]
pub struct ProcessWindow {
    frames: VecDeque<IndexedFrame>,
}

impl ProcessWindow {
    /// Adds the next frame's truth boxes and the second differences it completes.
    pub fn push(&mut self, truth: Vec<LabelledBox>, stats: &mut ProcessStats) {
        let index = truth
            .iter()
            .enumerate()
            .filter(|(_, b)| b.is_finite())
            .map(|(i, b)| ((b.label.clone(), b.id), i))
            .collect();
        self.frames.push_back((truth, index));
        if self.frames.len() > 3 {
            self.frames.pop_front();
        }
        if self.frames.len() == 3 {
            self.middle(stats);
        }
    }

    /// The second differences centred on the middle frame of three.
    fn middle(&self, stats: &mut ProcessStats) {
        let (prev, (boxes, index), next) = (&self.frames[0].1, &self.frames[1], &self.frames[2]);
        // In the frame's box order (not the map's), so that the sums are deterministic; a key
        // given twice counts once, with the box the map kept.
        for (i, b) in boxes.iter().enumerate().filter(|(_, b)| b.is_finite()) {
            let key = (b.label.clone(), b.id);
            if index[&key] != i {
                continue;
            }
            let (Some(&a), Some(&c)) = (prev.get(&key), next.1.get(&key)) else {
                continue;
            };
            let d = second_difference(&self.frames[0].0[a], b, &next.0[c]);
            let m = stats.entry(key.0).or_default();
            for (mi, v) in m.iter_mut().zip(d) {
                mi.push(v);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::data::FitFrame;
    use super::*;
    use std::f64::consts::PI;

    fn b(id: u64, x: f64, yaw: f64) -> LabelledBox {
        LabelledBox {
            id,
            label: "car".into(),
            center: [x, 2.0 * x, 1.0],
            size: [4.0, 2.0, 1.5],
            yaw,
            ..Default::default()
        }
    }

    fn log(frames: Vec<Vec<LabelledBox>>) -> FitLog {
        FitLog {
            name: "t".into(),
            frames: frames
                .into_iter()
                .enumerate()
                .map(|(i, truth)| FitFrame {
                    stamp: i as u64,
                    truth,
                    detections: vec![],
                })
                .collect(),
            unmatched_detection_messages: 0,
            skipped_detections: Default::default(),
            skipped_truth: 0,
        }
    }

    #[test]
    fn second_difference_of_accelerating_box() {
        let d = second_difference(&b(1, 0.0, 0.1), &b(1, 1.0, 0.2), &b(1, 3.0, 0.4));
        assert_eq!(d[0], 1.0);
        assert_eq!(d[1], 2.0);
        assert_eq!(d[2], 0.0);
        assert!((d[3] - 0.1).abs() < 1e-12);
    }

    #[test]
    fn yaw_second_difference_is_wrapped() {
        // A steady turn of 0.2 rad/frame across +-pi: second difference 0, not 2 pi.
        let y0 = PI - 0.3;
        let d = second_difference(
            &b(1, 0.0, y0),
            &b(1, 0.0, wrap(y0 + 0.2)),
            &b(1, 0.0, wrap(y0 + 0.4)),
        );
        assert!(d[3].abs() < 1e-12, "{}", d[3]);
    }

    #[test]
    fn gaps_break_sequences() {
        // Instance 1: frames 0 1 2 (one triple), missing in 3, frames 4 5 6 (one triple).
        // Instance 2: frames 0 1 3 4: no three consecutive frames.
        let l = log(vec![
            vec![b(1, 0.0, 0.0), b(2, 0.0, 0.0)],
            vec![b(1, 1.0, 0.0), b(2, 5.0, 0.0)],
            vec![b(1, 3.0, 0.0)],
            vec![b(2, 9.0, 0.0)],
            vec![b(1, 100.0, 0.0), b(2, 10.0, 0.0)],
            vec![b(1, 101.0, 0.0)],
            vec![b(1, 104.0, 0.0)],
        ]);
        let mut s = ProcessStats::new();
        accumulate_process_noise(&l, &mut s);
        let car = &s["car"];
        assert_eq!(car[0].n, 2);
        // Second differences 1 and 2: mean 1.5, population variance 0.25.
        assert!((car[0].variance().unwrap() - 0.25).abs() < 1e-12);
    }

    #[test]
    fn labels_are_separate() {
        let mut p = b(1, 0.0, 0.0);
        p.label = "pedestrian".into();
        let l = log(vec![vec![p.clone()], vec![p.clone()], vec![b(1, 0.0, 0.0)]]);
        let mut s = ProcessStats::new();
        accumulate_process_noise(&l, &mut s);
        assert!(s.is_empty());
    }
}
