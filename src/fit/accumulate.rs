//! The fit's running state over logs read frame by frame: the `Q` and `R` moments, the frame
//! intervals and the counts of the report. A log is fed one frame at a time
//! ([`FitAccumulator::push_frame`]) so that a long log never needs to be held whole; feeding
//! whole [`FitLog`]s ([`FitAccumulator::add_log`]) gives the same numbers.

use std::collections::BTreeMap;

use super::data::{FitFrame, FitLog};
use super::measurement::{MeasurementState, MeasurementStatsByLabel};
use super::process::{ProcessStats, ProcessWindow};
use super::stats::median;
use super::timing::{interval_s, period_of_intervals, FramePeriod};
use crate::msgs::detection_frame::SkipReason;

/// What the fit has gathered so far (pooled over the logs, in the order they were fed).
#[derive(Default, Clone)]
pub struct FitAccumulator {
    pub(super) names: Vec<String>,
    pub(super) frames: u64,
    pub(super) truth_boxes: u64,
    pub(super) detections: u64,
    pub(super) unmatched_detection_messages: u64,
    pub(super) intervals: Vec<f64>,
    /// Per log (as `names`), where its intervals start in `intervals`.
    pub(super) log_starts: Vec<usize>,
    /// Per log with skipped detection boxes: its name and the counts by reason.
    pub(super) skipped: Vec<(String, BTreeMap<SkipReason, u64>)>,
    /// Per log with skipped ground-truth boxes: its name and how many.
    pub(super) skipped_truth: Vec<(String, u64)>,
    pub(super) process: ProcessStats,
    pub(super) measurement: MeasurementStatsByLabel,
}

/// The state of the log being fed: instances are only followed within a log.
#[derive(Default)]
pub struct LogState {
    window: ProcessWindow,
    matched: MeasurementState,
    last_stamp: Option<u64>,
}

impl FitAccumulator {
    /// Nothing gathered yet.
    pub fn new() -> FitAccumulator {
        FitAccumulator::default()
    }

    /// Starts the log `name`; its frames go through the returned state.
    pub fn begin_log(&mut self, name: &str) -> LogState {
        self.names.push(name.to_string());
        self.log_starts.push(self.intervals.len());
        LogState::default()
    }

    /// Adds the log's next frame (frames in increasing stamp order).
    pub fn push_frame(&mut self, log: &mut LogState, frame: FitFrame) {
        self.frames += 1;
        self.truth_boxes += frame.truth.len() as u64;
        self.detections += frame.detections.len() as u64;
        if let Some(prev) = log.last_stamp {
            self.intervals.push(interval_s(prev, frame.stamp));
        }
        log.last_stamp = Some(frame.stamp);
        log.matched.push(&frame, &mut self.measurement);
        log.window.push(frame.truth, &mut self.process);
    }

    /// Counts the detection boxes of the current log that were left out when read, by reason.
    pub fn add_skipped(&mut self, counts: &BTreeMap<SkipReason, u64>) {
        if counts.is_empty() {
            return;
        }
        let name = self.names.last().cloned().unwrap_or_default();
        self.skipped.push((name, counts.clone()));
    }

    /// Counts the ground-truth boxes of the current log left out for a non-finite centre, size
    /// or yaw.
    pub fn add_skipped_truth(&mut self, boxes: u64) {
        if boxes > 0 {
            let name = self.names.last().cloned().unwrap_or_default();
            self.skipped_truth.push((name, boxes));
        }
    }

    /// Counts detection messages of the current log whose stamp is no truth stamp.
    pub fn add_unmatched(&mut self, messages: u64) {
        self.unmatched_detection_messages += messages;
    }

    /// The frame timing of the frames fed so far: the intervals between consecutive frames of
    /// each log.
    pub fn frame_period(&self) -> Option<FramePeriod> {
        period_of_intervals(&self.intervals)
    }

    /// Per log with two frames or more: its name and median frame interval, seconds.
    pub fn log_periods(&self) -> Vec<(&str, f64)> {
        let ends = self
            .log_starts
            .iter()
            .skip(1)
            .copied()
            .chain([self.intervals.len()]);
        (self.names.iter().zip(self.log_starts.iter().zip(ends)))
            .filter_map(|(name, (&a, b))| Some((name.as_str(), median(&self.intervals[a..b])?)))
            .collect()
    }

    /// Adds a whole log.
    pub fn add_log(&mut self, log: &FitLog) {
        let mut state = self.begin_log(&log.name);
        for f in &log.frames {
            self.push_frame(&mut state, f.clone());
        }
        self.add_unmatched(log.unmatched_detection_messages);
        self.add_skipped(&log.skipped_detections);
        self.add_skipped_truth(log.skipped_truth);
    }
}
