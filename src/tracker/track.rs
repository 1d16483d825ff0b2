//! One track: its filter, its life-cycle counters and what the tracker reports of it.

use super::bounds::{MAX_COORDINATE, MAX_SIZE, MAX_SPEED, MAX_VARIANCE};
use super::boxes::{Box3, ClassId};
use super::confidence::Confidence;
use super::config::BoxOrigin;
use super::kalman::KalmanState;

/// A live track inside the tracker.
#[derive(Debug, Clone)]
pub struct Track {
    /// Unique id within a run (one counter over all classes, starting at 1).
    pub id: u64,
    /// Class index.
    pub class: ClassId,
    /// Filter state.
    pub kf: KalmanState,
    /// Total number of matched detections, the birth included.
    pub hits: u32,
    /// Frames since birth.
    pub age: u32,
    /// Frames since the last matched detection (0 when matched this frame).
    pub time_since_update: u32,
    /// Score of the last matched detection.
    pub score: f64,
    /// Number of frames in which this track was reported (with the offline options: reported
    /// for the lookback to decide, so it also counts frames the lookback drops).
    pub reported_frames: u32,
    /// Whether `hits` ever reached `min_hits`.
    pub confirmed: bool,
    /// Refined and mean score (see [`super::levers`]).
    pub conf: Confidence,
    /// Whether its state or a variance has left [`super::bounds`]: it is then ended.
    pub beyond_bounds: bool,
}

/// Whether a report is shown now or waits for later frames to decide (the offline options
/// [`super::levers::Levers::backfill`] and [`super::levers::Coast::Gaps`]; without them every
/// report is `Final`). [`super::lookback::Lookback`] makes the decisions.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ReportStatus {
    /// Shown.
    #[default]
    Final,
    /// A track that has not reached `min_hits`: shown if it reaches it later (backfill).
    Tentative,
    /// A coasted frame: shown if the track is matched again before it stops being reported.
    Coasting,
    /// Never shown (a coasted frame under `coast: none`), but the track lives on: a tentative
    /// track's held frames still wait for its confirmation.
    Hidden,
}

/// What the tracker reports for one track in one frame.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TrackReport {
    /// Track id.
    pub id: u64,
    /// Class index.
    pub class: ClassId,
    /// Posterior box, or the prediction when the track was not matched this frame.
    pub bbox: Box3,
    /// Velocity in m/s.
    pub velocity: [f64; 3],
    /// Yaw rate in rad/s (0 without angular velocity).
    pub yaw_rate: f64,
    /// Score of the last matched detection.
    pub score: f64,
    /// Variances of x, y, z (m^2).
    pub position_variance: [f64; 3],
    /// Variance of yaw (rad^2).
    pub yaw_variance: f64,
    /// Variances of the velocity in x, y, z (m^2/s^2).
    pub velocity_variance: [f64; 3],
    /// Variance of the yaw rate (rad^2/s^2; without angular velocity the yaw-rate state stays 0
    /// and this is its prior variance).
    pub yaw_rate_variance: f64,
    /// Frames since birth.
    pub age: u32,
    /// Total hits.
    pub hits: u32,
    /// Frames since the last matched detection.
    pub frames_since_update: u32,
    /// Index (into the detections passed to this step) of the detection matched this frame.
    pub detection: Option<u32>,
    /// Shown now, or to be decided by later frames.
    pub status: ReportStatus,
}

impl TrackReport {
    /// Whether every number is finite and within [`super::bounds`]: centre, size, velocity,
    /// and every variance at most [`MAX_VARIANCE`].
    pub fn within_bounds(&self) -> bool {
        let b = &self.bbox;
        let variances = (self.position_variance.iter())
            .chain(&self.velocity_variance)
            .chain([&self.yaw_variance, &self.yaw_rate_variance]);
        b.center.iter().all(|v| v.abs() <= MAX_COORDINATE)
            && b.size.iter().all(|v| v.abs() <= MAX_SIZE)
            && self.velocity.iter().all(|v| v.abs() <= MAX_SPEED)
            && b.yaw.is_finite()
            && self.yaw_rate.is_finite()
            && variances
                .into_iter()
                .all(|v| (0.0..=MAX_VARIANCE).contains(v))
    }
}

impl Track {
    /// The report of this track, with velocities converted from per-nominal-frame to per-second.
    /// `origin` is the point of the box the filter's position follows.
    pub fn report(
        &self,
        dt_nominal: f64,
        origin: BoxOrigin,
        detection: Option<u32>,
    ) -> TrackReport {
        let x = &self.kf.x;
        let p = &self.kf.p;
        // Per nominal frame squared to per second squared.
        let per_s2 = 1.0 / (dt_nominal * dt_nominal);
        TrackReport {
            id: self.id,
            class: self.class,
            bbox: Box3::from_slice(x.as_slice()).from_origin(origin),
            velocity: [x[7] / dt_nominal, x[8] / dt_nominal, x[9] / dt_nominal],
            yaw_rate: x[10] / dt_nominal,
            score: self.score,
            position_variance: [p[(0, 0)], p[(1, 1)], p[(2, 2)]],
            yaw_variance: p[(3, 3)],
            velocity_variance: [p[(7, 7)] * per_s2, p[(8, 8)] * per_s2, p[(9, 9)] * per_s2],
            yaw_rate_variance: p[(10, 10)] * per_s2,
            age: self.age,
            hits: self.hits,
            frames_since_update: self.time_since_update,
            detection,
            status: ReportStatus::Final,
        }
    }
}
