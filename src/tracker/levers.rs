//! Per-class options beyond the paper: track confidence, two-stage association, non-maximum
//! suppression of duplicate detections, a life cycle by confidence, two-point initialization of
//! fast objects, and which frames of a track are reported (offline: from its first detection, coasted frames only inside gaps). All are
//! off by default, so a config without them runs the method of Chiu et al. (2019) exactly.
//!
//! Sources of the ideas (own implementation): CBMOT (Benbarka et al. 2021) for score refinement,
//! SimpleTrack (Pang et al. 2021) and ByteTrack (Zhang et al. 2022) for two-stage association and
//! NMS before association, ImmortalTracker (Wang et al. 2021) and Fast-Poly (Li et al. 2024) for
//! keeping confident tracks alive.

use serde::{Deserialize, Serialize};

use super::bounds::{magnitude_ok, MAX_MAGNITUDE, MAX_SPEED};
pub use super::ctrv::Motion;
use super::error::ConfigError;

/// Which score a track reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ScoreMode {
    /// The score of the last matched detection (the paper).
    #[default]
    Last,
    /// The running mean of the matched detections' scores.
    Mean,
    /// The refined score (see [`Levers::blend`], [`Levers::boost`], [`Levers::decay`]).
    Refined,
}

/// Which coasted frames (predictions without a matched detection) of a shown track are reported.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Coast {
    /// Every coasted frame while the track lives (`max_age`), as the paper does.
    #[default]
    All,
    /// Only the coasted frames of a gap the track bridges, i.e. followed by a match: the
    /// predictions after a track's last match are not reported. Known only later, so the
    /// frames are held (see [`super::lookback`]).
    Gaps,
    /// None: only the frames with a matched detection.
    None,
}

impl Coast {
    /// True for the paper's behaviour (not serialized, so older configs keep their bytes).
    pub fn is_all(&self) -> bool {
        *self == Coast::All
    }
}

impl super::choice::Choice for Coast {
    const VALUES: &'static [Self] = &[Coast::All, Coast::Gaps, Coast::None];

    fn name(self) -> &'static str {
        match self {
            Coast::All => "all",
            Coast::Gaps => "gaps",
            Coast::None => "none",
        }
    }

    fn description(self) -> &'static str {
        match self {
            Coast::All => "Every coasted frame up to max_age (the paper)",
            Coast::Gaps => "Only coasted frames followed by a match of the same track",
            Coast::None => "Only frames with a matched detection",
        }
    }
}

/// The options beyond the paper of one class. Every field's default is "off".
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Levers {
    /// Score reported for the track.
    pub score: ScoreMode,
    /// Refinement on a match: `r <- r + blend * (s - r) + boost`, with `s` the detection score.
    pub blend: f64,
    /// Added to the refined score on every match (rewards long, consistent tracks).
    pub boost: f64,
    /// Subtracted from the refined score in every frame without a match.
    pub decay: f64,
    /// Two-stage association: detections scoring below this cannot start a track; they may
    /// continue a track left unmatched by the first round (`None`: one round, every detection
    /// may start a track).
    pub birth_score: Option<f64>,
    /// Non-maximum suppression before association: a detection whose 3D IoU with a higher
    /// scoring detection of its class exceeds this is dropped (`None`: off).
    pub nms_iou: Option<f64>,
    /// Life cycle by confidence: a track past `max_age` frames without a match is kept (not
    /// reported) while its refined score stays at or above this (`None`: delete by age only).
    /// Needs `decay > 0` so that every track eventually ends.
    pub keep_score: Option<f64>,
    /// Motion model: `cv` (constant velocity, the paper) or `ctrv` (coordinated turn, see
    /// [`super::ctrv`]; needs `angular_velocity`). Not written when `cv`, so configs written
    /// before the option existed keep their bytes.
    #[serde(skip_serializing_if = "Motion::is_cv")]
    pub motion: Motion,
    /// Which coasted frames are reported (offline option; `all` is the paper).
    #[serde(skip_serializing_if = "Coast::is_all")]
    pub coast: Coast,
    /// Offline: once a track reaches `min_hits`, its earlier frames (from its birth) are
    /// reported too, so a track is not missing its first detections. Known only later, so the
    /// frames are held (see [`super::lookback`]).
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub backfill: bool,
    /// Two-point initialization ([`super::two_point`]): a detection left unmatched that could
    /// start a track (at or above `birth_score`) may continue a track born in the previous
    /// frame within this speed, m/s (ground-plane centre distance
    /// over the elapsed time); the track takes the velocity of the displacement. For objects
    /// faster than the gate allows at the frame rate (`None`: off, the paper). Not written when
    /// off, so earlier configs keep their bytes.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub two_point_speed: Option<f64>,
}

impl Default for Levers {
    fn default() -> Self {
        Levers {
            score: ScoreMode::Last,
            blend: 1.0,
            boost: 0.0,
            decay: 0.0,
            birth_score: None,
            nms_iou: None,
            keep_score: None,
            motion: Motion::Cv,
            coast: Coast::All,
            backfill: false,
            two_point_speed: None,
        }
    }
}

impl Levers {
    /// True when every option is off (the paper's method); such levers are not serialized.
    pub fn is_off(&self) -> bool {
        *self == Levers::default()
    }

    /// True when the class's reports may have to wait for later frames (see
    /// [`super::lookback`]).
    pub fn holds_frames(&self) -> bool {
        self.backfill || self.coast == Coast::Gaps
    }

    /// Checks the values; see the field docs.
    pub fn validate(&self) -> Result<(), ConfigError> {
        if !(self.blend.is_finite() && (0.0..=1.0).contains(&self.blend)) {
            return Err(ConfigError(format!(
                "levers.blend must lie in [0, 1], got {}",
                self.blend
            )));
        }
        for (name, v) in [("boost", self.boost), ("decay", self.decay)] {
            if !(magnitude_ok(v) && v >= 0.0) {
                return Err(ConfigError(format!(
                    "levers.{name} must be non-negative, finite and within {MAX_MAGNITUDE:e}, got {v}"
                )));
            }
        }
        for (name, v) in [
            ("birth_score", self.birth_score),
            ("keep_score", self.keep_score),
        ] {
            if let Some(v) = v.filter(|v| !magnitude_ok(*v)) {
                return Err(ConfigError(format!(
                    "levers.{name} must be finite and within {MAX_MAGNITUDE:e}, got {v}"
                )));
            }
        }
        if let Some(v) = self
            .nms_iou
            .filter(|v| !(v.is_finite() && (0.0..=1.0).contains(v)))
        {
            return Err(ConfigError(format!(
                "levers.nms_iou must lie in [0, 1], got {v}"
            )));
        }
        if let Some(v) = self
            .two_point_speed
            .filter(|v| !(v.is_finite() && *v > 0.0 && *v <= MAX_SPEED))
        {
            return Err(ConfigError(format!(
                "levers.two_point_speed must be a positive speed in m/s up to {MAX_SPEED:e}, got {v}"
            )));
        }
        if self.keep_score.is_some() && self.decay <= 0.0 {
            return Err(ConfigError(
                "levers.keep_score needs levers.decay > 0 (otherwise an unmatched track could \
                 live forever)"
                    .into(),
            ));
        }
        Ok(())
    }
}
