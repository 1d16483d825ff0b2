//! Tracker configuration: per-class noise, association and life-cycle settings, and the
//! built-in presets.

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

use super::bounds::{magnitude_ok, variance_ok, MAX_MAGNITUDE, MAX_VARIANCE, MIN_VARIANCE};
pub use super::error::ConfigError;
pub use super::levers::{Levers, ScoreMode};

/// How a detection is compared with a track's predicted box.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum DistanceKind {
    /// `sqrt(y^T S^-1 y)` with `S = H P H^T + R` (the paper). A cost: pairs at or under the
    /// threshold are matchable.
    Mahalanobis,
    /// Oriented 3D IoU (AB3DMOT). A similarity: pairs at or over the threshold are matchable.
    Iou3d,
    /// Generalized 3D IoU. A similarity, in `(-1, 1]`.
    Giou3d,
    /// Bird's-eye-view centre distance in metres. A cost.
    Center,
    /// 3D distance between the box centres in metres (AB3DMOT's `dist_3d`). A cost.
    Dist3d,
}

impl DistanceKind {
    /// True for similarities (larger is better), false for costs.
    pub fn is_similarity(self) -> bool {
        matches!(self, DistanceKind::Iou3d | DistanceKind::Giou3d)
    }

    /// The name used in configs and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            DistanceKind::Mahalanobis => "mahalanobis",
            DistanceKind::Iou3d => "iou3d",
            DistanceKind::Giou3d => "giou3d",
            DistanceKind::Center => "center",
            DistanceKind::Dist3d => "dist3d",
        }
    }
}

/// How matchable pairs are turned into a one-to-one assignment.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum MatcherKind {
    /// The paper's Algorithm 1: pairs sorted by cost, take a pair when both sides are free, stop
    /// at the first pair over the threshold.
    Greedy,
    /// Optimal assignment (minimum total cost), then pairs over the threshold are dropped.
    Hungarian,
}

impl super::choice::Choice for DistanceKind {
    const VALUES: &'static [Self] = &[
        DistanceKind::Mahalanobis,
        DistanceKind::Iou3d,
        DistanceKind::Giou3d,
        DistanceKind::Center,
        DistanceKind::Dist3d,
    ];

    fn name(self) -> &'static str {
        DistanceKind::name(self)
    }

    fn description(self) -> &'static str {
        match self {
            DistanceKind::Mahalanobis => {
                "Mahalanobis distance with the innovation covariance (the paper)"
            }
            DistanceKind::Iou3d => "Oriented 3D IoU (AB3DMOT)",
            DistanceKind::Giou3d => "Generalized 3D IoU",
            DistanceKind::Center => "BEV centre distance, metres",
            DistanceKind::Dist3d => "3D centre distance, metres (AB3DMOT's dist_3d)",
        }
    }
}

impl super::choice::Choice for MatcherKind {
    const VALUES: &'static [Self] = &[MatcherKind::Greedy, MatcherKind::Hungarian];

    fn name(self) -> &'static str {
        match self {
            MatcherKind::Greedy => "greedy",
            MatcherKind::Hungarian => "hungarian",
        }
    }

    fn description(self) -> &'static str {
        match self {
            MatcherKind::Greedy => "Greedy, Algorithm 1 of the paper",
            MatcherKind::Hungarian => "Optimal assignment",
        }
    }
}

/// The point of a box whose position the filter follows.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum BoxOrigin {
    /// The box centre.
    #[default]
    Center,
    /// The centre of the bottom face, as KITTI labels and AB3DMOT do. With a size that changes
    /// this filters a different quantity than the centre: AB3DMOT's boxes need it to be exact.
    Bottom,
}

/// Settings of one class.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClassConfig {
    /// Process noise diagonal per nominal frame: `x y z yaw l w h dx dy dz dyaw`.
    pub q: [f64; 11],
    /// Measurement noise diagonal: `x y z yaw l w h`.
    pub r: [f64; 7],
    /// Initial state covariance diagonal.
    pub p0: [f64; 11],
    /// Distance used for association.
    pub distance: DistanceKind,
    /// Gate: maximum cost, or minimum similarity for IoU kinds.
    pub threshold: f64,
    /// Assignment method.
    pub matcher: MatcherKind,
    /// Hits before a track is reported (total, not consecutive).
    pub min_hits: u32,
    /// A track is deleted when its frames since the last update reach this.
    pub max_age: u32,
    /// Whether the heading follows a constant angular velocity.
    pub angular_velocity: bool,
    /// Detections scoring below this are ignored. `None`: keep all.
    #[serde(default)]
    pub score_floor: Option<f64>,
    // AB3DMOT's KITTI configuration (issue #17); each defaults to the earlier behaviour.
    /// Point of the box the filter's position follows.
    #[serde(default)]
    pub origin: BoxOrigin,
    /// With the Hungarian matcher: solve the assignment over every pair and drop pairs over the
    /// gate afterwards (AB3DMOT). `false`: pairs over the gate are never candidates, so the
    /// solver maximises the number of gated pairs first.
    #[serde(default)]
    pub gate_after_assignment: bool,
    /// Number of samples the noise was fitted from, when fitted (informational).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub samples: Option<u64>,
    /// Options beyond the paper (all off by default; see [`Levers`]).
    #[serde(default, skip_serializing_if = "Levers::is_off")]
    pub levers: Levers,
}

/// The full tracker configuration.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrackerConfig {
    /// Preset or config name (informational).
    pub name: String,
    /// Nominal frame period in seconds; velocities in the state are per this period.
    pub dt_nominal: f64,
    /// Per-label settings.
    pub classes: BTreeMap<String, ClassConfig>,
    /// Settings for labels not listed in `classes`. `None`: detections with other labels are
    /// skipped (and counted by the caller).
    pub default: Option<ClassConfig>,
}

/// The seven nuScenes tracking classes, in the order of the benchmark.
pub const NUSCENES_CLASSES: [&str; 7] = [
    "bicycle",
    "bus",
    "car",
    "motorcycle",
    "pedestrian",
    "trailer",
    "truck",
];

/// AB3DMOT's default covariances: `(P0, Q, R)` diagonals.
pub fn ab3dmot_covariances() -> ([f64; 11], [f64; 11], [f64; 7]) {
    let mut p0 = [10.0; 11];
    let mut q = [1.0; 11];
    for i in 7..11 {
        p0[i] = 10000.0;
        q[i] = 0.01;
    }
    (p0, q, [1.0; 7])
}

/// Per-class statistics published with the paper's reference implementation (covariance set 2,
/// nuScenes training split): `(label, P0 diagonal, Q for x y z yaw)`. R is the first seven
/// entries of P0. Source: eddyhkchiu/mahalanobis_3d_multi_object_tracking, `covariance.py`.
const CHIU2019: [(&str, [f64; 11], [f64; 4]); 7] = [
    (
        "bicycle",
        [
            0.05390982, 0.05039431, 0.01863044, 1.29464435, 0.02713823, 0.01169572, 0.01295084,
            0.04560422, 0.04097244, 0.01725477, 1.21635902,
        ],
        [
            1.98881347e-02,
            1.36552276e-02,
            5.10175742e-03,
            1.33430252e-01,
        ],
    ),
    (
        "bus",
        [
            0.17546469, 0.13818929, 0.05947248, 0.1979503, 0.78867322, 0.05507407, 0.06684149,
            0.13263319, 0.11508148, 0.05033665, 0.22529652,
        ],
        [
            1.17729925e-01,
            8.84659079e-02,
            1.17616440e-02,
            2.09050032e-01,
        ],
    ),
    (
        "car",
        [
            0.08900372, 0.09412005, 0.03265469, 1.00535696, 0.10912802, 0.02359175, 0.02455134,
            0.08120681, 0.08224643, 0.02266425, 0.99492726,
        ],
        [
            1.58918523e-01,
            1.24935318e-01,
            5.35573165e-03,
            9.22800791e-02,
        ],
    ),
    (
        "motorcycle",
        [
            0.04052819, 0.0398904, 0.01511711, 1.06442726, 0.03291016, 0.00957574, 0.0111605,
            0.0437039, 0.04327734, 0.01465631, 1.30414345,
        ],
        [
            3.23647590e-02,
            3.86650974e-02,
            5.47421635e-03,
            2.34967407e-01,
        ],
    ),
    (
        "pedestrian",
        [
            0.03855275, 0.0377111, 0.02482115, 2.0751833, 0.02286483, 0.0136347, 0.0203149,
            0.04237008, 0.04092393, 0.01482923, 2.0059979,
        ],
        [
            3.34814566e-02,
            2.47354921e-02,
            5.94592529e-03,
            4.24962535e-01,
        ],
    ),
    (
        "trailer",
        [
            0.23228021, 0.22229261, 0.07006275, 1.05163481, 1.37451601, 0.06354783, 0.10500918,
            0.2138643, 0.19625241, 0.05231335, 0.97082174,
        ],
        [
            4.19985099e-02,
            3.68661552e-02,
            1.19415050e-02,
            5.63166240e-02,
        ],
    ),
    (
        "truck",
        [
            0.14862173, 0.1444596, 0.05417157, 0.73122169, 0.69387238, 0.05484365, 0.07748085,
            0.10683797, 0.10248689, 0.0378078, 0.76188901,
        ],
        [
            9.45275998e-02,
            9.45620374e-02,
            8.38061721e-03,
            1.41680460e-01,
        ],
    ),
];

/// Expands the four fitted process-noise values `x y z yaw` to the 11-d diagonal: 0 on `l w h`,
/// and the same values again on the velocity entries (as the paper's code does).
pub fn q_from_xyz_yaw(q4: [f64; 4]) -> [f64; 11] {
    [
        q4[0], q4[1], q4[2], q4[3], 0.0, 0.0, 0.0, q4[0], q4[1], q4[2], q4[3],
    ]
}

fn chiu_class(p0: [f64; 11], q4: [f64; 4]) -> ClassConfig {
    let mut r = [0.0; 7];
    r.copy_from_slice(&p0[..7]);
    ClassConfig {
        q: q_from_xyz_yaw(q4),
        r,
        p0,
        distance: DistanceKind::Mahalanobis,
        threshold: 11.0,
        matcher: MatcherKind::Greedy,
        min_hits: 3,
        max_age: 2,
        angular_velocity: true,
        score_floor: None,
        origin: BoxOrigin::Center,
        gate_after_assignment: false,
        samples: None,
        levers: Levers::default(),
    }
}

/// The settings of one class of AB3DMOT's 2019 default (3D IoU 0.1, Hungarian, its default
/// covariances, no angular velocity): the `ab3dmot-2019` preset.
pub fn ab3dmot_class() -> ClassConfig {
    let (p0, q, r) = ab3dmot_covariances();
    ClassConfig {
        q,
        r,
        p0,
        distance: DistanceKind::Iou3d,
        threshold: 0.1,
        matcher: MatcherKind::Hungarian,
        min_hits: 3,
        max_age: 2,
        angular_velocity: false,
        score_floor: None,
        origin: BoxOrigin::Center,
        gate_after_assignment: false,
        samples: None,
        levers: Levers::default(),
    }
}

/// The per-class settings of the `nuscenes-chiu2019` preset (the paper's covariance set 2).
pub(crate) fn chiu2019_classes() -> BTreeMap<String, ClassConfig> {
    CHIU2019
        .iter()
        .map(|(label, p0, q4)| (label.to_string(), chiu_class(*p0, *q4)))
        .collect()
}

impl TrackerConfig {
    /// Parses and validates a JSON config.
    pub fn from_json(text: &str) -> Result<TrackerConfig, ConfigError> {
        let cfg: TrackerConfig =
            serde_json::from_str(text).map_err(|e| ConfigError(format!("{e}")))?;
        cfg.validate()?;
        Ok(cfg)
    }

    /// Pretty JSON of this config.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("config serializes")
    }

    /// The settings for a label: its own entry, else the default entry.
    pub fn class(&self, label: &str) -> Option<&ClassConfig> {
        self.classes.get(label).or(self.default.as_ref())
    }

    /// Applies a change to every class entry, the default included.
    pub fn for_each_class(&mut self, mut f: impl FnMut(&mut ClassConfig)) {
        self.classes.values_mut().for_each(&mut f);
        if let Some(d) = self.default.as_mut() {
            f(d);
        }
    }

    /// True when some class reports offline, so that frames must pass through a
    /// [`super::Lookback`] (without, every report is final when it is made).
    pub fn holds_frames(&self) -> bool {
        let mut classes = self.classes.values().chain(self.default.iter());
        classes.any(|c| c.levers.holds_frames())
    }

    /// Checks every value: variances finite and within [`super::bounds`] (positive where they
    /// must be), every other number finite and bounded, `max_age >= 1`. Errors name the class
    /// and the field.
    pub fn validate(&self) -> Result<(), ConfigError> {
        if !(1e-9..=1e6).contains(&self.dt_nominal) {
            return Err(ConfigError(format!(
                "dt_nominal must be a number of seconds in [1e-9, 1e6], got {}",
                self.dt_nominal
            )));
        }
        let entries = self
            .classes
            .iter()
            .map(|(k, v)| (k.as_str(), v))
            .chain(self.default.iter().map(|d| ("default", d)));
        for (label, c) in entries {
            c.validate()
                .map_err(|e| ConfigError(format!("class '{label}': {}", e.0)))?;
        }
        Ok(())
    }
}

impl ClassConfig {
    /// Checks one class entry; see [`TrackerConfig::validate`].
    pub fn validate(&self) -> Result<(), ConfigError> {
        const STATE: [&str; 11] = [
            "x", "y", "z", "yaw", "l", "w", "h", "dx", "dy", "dz", "dyaw",
        ];
        let variances = [("r", &self.r[..], false), ("p0", &self.p0[..], false)];
        for (name, values, zero_ok) in variances.into_iter().chain([("q", &self.q[..], true)]) {
            if let Some((i, v)) =
                (values.iter().enumerate()).find(|(_, v)| !variance_ok(**v, zero_ok))
            {
                let range = format!("[{MIN_VARIANCE:e}, {MAX_VARIANCE:e}]");
                let zero = if zero_ok { "0 or " } else { "" };
                return Err(ConfigError(format!(
                    "{name}[{i}] ({}) must be {zero}a variance in {range}, got {v}",
                    STATE[i]
                )));
            }
        }
        if self.q[..4].iter().chain(&self.q[7..]).any(|v| *v == 0.0) {
            return Err(ConfigError(
                "q must be positive on x y z yaw and on the velocity entries (a zero-variance \
                 motion model cannot follow a moving object)"
                    .into(),
            ));
        }
        if !magnitude_ok(self.threshold) {
            return Err(ConfigError(format!(
                "threshold must be finite and within {MAX_MAGNITUDE:e}, got {}",
                self.threshold
            )));
        }
        if self.distance.is_similarity() && !(-1.0..=1.0).contains(&self.threshold) {
            return Err(ConfigError(format!(
                "threshold of {} must lie in [-1, 1], got {}",
                self.distance.name(),
                self.threshold
            )));
        }
        if !self.distance.is_similarity() && self.threshold <= 0.0 {
            return Err(ConfigError(format!(
                "threshold of {} must be positive, got {}",
                self.distance.name(),
                self.threshold
            )));
        }
        if self.max_age == 0 {
            return Err(ConfigError("max_age must be at least 1".into()));
        }
        if let Some(f) = self.score_floor {
            if !magnitude_ok(f) {
                return Err(ConfigError(format!(
                    "score_floor must be finite and within {MAX_MAGNITUDE:e}, got {f}"
                )));
            }
        }
        if self.levers.motion == super::levers::Motion::Ctrv && !self.angular_velocity {
            return Err(ConfigError(
                "levers.motion \"ctrv\" needs angular_velocity: true (the velocity turns with \
                 the yaw rate)"
                    .into(),
            ));
        }
        self.levers.validate()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chiu_preset_has_published_numbers() {
        let cfg = TrackerConfig::preset("nuscenes-chiu2019").unwrap();
        let car = &cfg.classes["car"];
        assert_eq!(car.r[3], 1.00535696);
        assert_eq!(car.p0[10], 0.99492726);
        assert_eq!(car.q[0], 1.58918523e-01);
        assert_eq!(car.q[7], car.q[0]);
        assert_eq!(car.q[4], 0.0);
        assert_eq!(cfg.classes.len(), 7);
        assert_eq!(car.threshold, 11.0);
    }

    #[test]
    fn zero_variance_is_rejected() {
        let mut cfg = TrackerConfig::preset("nuscenes-chiu2019").unwrap();
        cfg.classes.get_mut("bus").unwrap().r[0] = 0.0;
        let err = cfg.validate().unwrap_err();
        assert!(
            err.0.contains("class 'bus'") && err.0.contains("r[0]"),
            "{err}"
        );
        let mut cfg = TrackerConfig::preset("ab3dmot-2019").unwrap();
        cfg.default.as_mut().unwrap().threshold = f64::NAN;
        assert!(cfg.validate().is_err());
    }

    /// Variances beyond the ceiling (issue #36: q = 1e308 made NaN tracks) and absurd other
    /// numbers are refused, naming the class and the field.
    #[test]
    fn absurd_values_are_rejected() {
        let base = TrackerConfig::preset("nuscenes-chiu2019").unwrap();
        let refused = |f: &dyn Fn(&mut ClassConfig), want: &str| {
            let mut cfg = base.clone();
            f(cfg.classes.get_mut("car").unwrap());
            let err = cfg.validate().unwrap_err().0;
            assert!(err.contains("class 'car'") && err.contains(want), "{err}");
        };
        refused(&|c| c.q[0] = 1e308, "q[0] (x)");
        refused(&|c| c.q[7] = 1e200, "q[7] (dx)");
        refused(&|c| c.r[6] = 1e308, "r[6] (h)");
        refused(&|c| c.p0[10] = 1e13, "p0[10] (dyaw)");
        refused(&|c| c.p0[0] = 1e-300, "p0[0] (x)");
        refused(&|c| c.threshold = 1e300, "threshold");
        refused(&|c| c.score_floor = Some(-1e300), "score_floor");
        refused(&|c| c.levers.two_point_speed = Some(1e9), "two_point_speed");
        refused(&|c| c.levers.boost = 1e300, "levers.boost");
        let mut cfg = base.clone();
        cfg.classes.get_mut("car").unwrap().p0[0] = 1e12;
        assert!(cfg.validate().is_ok(), "the ceiling itself is allowed");
        cfg.dt_nominal = 1e300;
        assert!(cfg.validate().unwrap_err().0.contains("dt_nominal"));
    }

    #[test]
    fn unknown_fields_and_kinds_are_errors() {
        let mut v: serde_json::Value =
            serde_json::from_str(&TrackerConfig::preset("ab3dmot-2019").unwrap().to_json())
                .unwrap();
        v["default"]["distance"] = "manhattan".into();
        let e = TrackerConfig::from_json(&v.to_string()).unwrap_err();
        assert!(e.0.contains("manhattan"), "{e}");
    }
}
