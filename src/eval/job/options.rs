//! What an evaluation job is asked to do ([`EvalOptions`]) and what it gives ([`EvalReport`]).

use std::path::PathBuf;

use crate::eval::kitti::MeanScores;
use crate::eval::range::RangeFilter;
use crate::formats::nuscenes::BIKE_RACKS_TOPIC;

/// The rule of the regression gate (`max_drop`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Gate {
    /// The fall is larger than `max_drop` and its paired 95 % interval lies below 0.
    #[default]
    Interval,
    /// The fall is larger than `max_drop`.
    Point,
}

/// Evaluation protocols.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Protocol {
    /// The nuScenes tracking benchmark (AMOTA, AMOTP, MOTA, ...; 2 m centre distance).
    #[default]
    Nuscenes,
    /// KITTI 3D MOT as AB3DMOT evaluates it (sAMOTA, AMOTA, MOTA, ...; 3D IoU matching).
    Kitti,
}

impl crate::tracker::choice::Choice for Gate {
    const VALUES: &'static [Self] = &[Gate::Interval, Gate::Point];

    fn name(self) -> &'static str {
        match self {
            Gate::Interval => "interval",
            Gate::Point => "point",
        }
    }

    fn description(self) -> &'static str {
        match self {
            Gate::Interval => {
                "The fall is larger than --max-drop and its paired 95 % interval lies below 0"
            }
            Gate::Point => "The fall is larger than --max-drop",
        }
    }
}

impl crate::tracker::choice::Choice for Protocol {
    const VALUES: &'static [Self] = &[Protocol::Nuscenes, Protocol::Kitti];

    fn name(self) -> &'static str {
        match self {
            Protocol::Nuscenes => "nuscenes",
            Protocol::Kitti => "kitti",
        }
    }

    fn description(self) -> &'static str {
        match self {
            Protocol::Nuscenes => {
                "nuScenes tracking benchmark (AMOTA, AMOTP, MOTA, ...; 2 m centre distance)"
            }
            Protocol::Kitti => {
                "KITTI 3D MOT as evaluated by AB3DMOT (sAMOTA, AMOTA, AMOTP, MOTA, ...; 3D IoU \
                 matching, KITTI's ignore rules for truncated/occluded ground truth, DontCare \
                 regions, small boxes and the neighbouring classes Van and Person_sitting)"
            }
        }
    }
}

/// The options of one evaluation (`probmot eval`): the logs, the protocol and its filters, the
/// baseline and the gate, the bootstrap, what to report.
#[derive(Debug, Clone, PartialEq)]
pub struct EvalOptions {
    /// Files with the ground-truth channel: files, directories (their `*.mcap`) or glob patterns.
    pub truth: Vec<PathBuf>,
    /// Files with the tracks channel (empty: the truth files), paired with the truth by name.
    pub tracks: Vec<PathBuf>,
    /// Ground-truth topic.
    pub truth_topic: String,
    /// Tracks topic.
    pub tracks_topic: String,
    /// The protocol.
    pub protocol: Protocol,
    /// Classes to evaluate (empty: the protocol's).
    pub classes: Vec<String>,
    /// KITTI: the minimum 3D IoU of a match (`None`: the protocol's 0.25).
    pub iou: Option<f64>,
    /// KITTI: when each track's mean score is computed (`None`: the official every pass).
    pub means: Option<MeanScores>,
    /// Another tracked version of the same logs to compare with (empty: none).
    pub baseline: Vec<PathBuf>,
    /// The regression gate: fail when the main metric falls by more than this many points.
    pub max_drop: Option<f64>,
    /// The gate also fails on any single class.
    pub per_class: bool,
    /// The gate's rule.
    pub gate: Gate,
    /// Bootstrap resamples (`None`: no bootstrap, unless the interval gate needs 1000).
    pub bootstrap: Option<usize>,
    /// Seed of the bootstrap's draws.
    pub seed: u64,
    /// Bootstrap block length in seconds (`None`: whole logs with 20 or more, else 10 s).
    pub block: Option<f64>,
    /// nuScenes: the class range filter.
    pub max_range: Option<RangeFilter>,
    /// Ego pose channel of the range filter.
    pub ego_topic: String,
    /// nuScenes: remove ground truth with fewer lidar + radar points.
    pub min_points: Option<u64>,
    /// nuScenes: remove bicycles and motorcycles in bicycle racks.
    pub bike_racks: bool,
    /// Bicycle-rack channel.
    pub racks_topic: String,
    /// nuScenes: every filter of the devkit (range, points, racks) unless given otherwise.
    pub devkit: bool,
    /// The report as JSON (else as text tables).
    pub json: bool,
    /// Write the evaluation's decisions as channels of a copy of the truth log(s) here.
    pub events: Option<PathBuf>,
    /// End the text report with the legend of its tables.
    pub explain: bool,
}

impl Default for EvalOptions {
    fn default() -> EvalOptions {
        EvalOptions {
            truth: Vec::new(),
            tracks: Vec::new(),
            truth_topic: "/ground_truth".into(),
            tracks_topic: "/tracks".into(),
            protocol: Protocol::default(),
            classes: Vec::new(),
            iou: None,
            means: None,
            baseline: Vec::new(),
            max_drop: None,
            per_class: false,
            gate: Gate::default(),
            bootstrap: None,
            seed: 0,
            block: None,
            max_range: None,
            ego_topic: "/ego_pose".into(),
            min_points: None,
            bike_racks: false,
            racks_topic: BIKE_RACKS_TOPIC.into(),
            devkit: false,
            json: false,
            events: None,
            explain: false,
        }
    }
}

/// What an evaluation gives.
#[derive(Debug, Clone)]
pub struct EvalReport {
    /// The JSON document (with [`EvalOptions::json`]).
    pub json: Option<serde_json::Value>,
    /// The text report (without [`EvalOptions::json`]).
    pub text: String,
    /// What failed the regression gate (empty: it passed, or there is none).
    pub gate_failures: Vec<String>,
}
