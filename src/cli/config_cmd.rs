//! `probmot config`: print a preset or check a config file; the tracker-setting flags shared by
//! the commands that run the tracker.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use clap::{Args, ValueEnum};
use probmot::pipeline::overrides::{base_config, Overrides};
use probmot::pipeline::per_class::PerClass;
use probmot::tracker::ctrv::Motion;
use probmot::tracker::levers::Coast;
use probmot::tracker::{DistanceKind, MatcherKind, Preset, TrackerConfig};

use super::choice::choice;

/// Print a built-in preset as JSON, or load, validate and print a config file.
///
/// Examples:
///   probmot config --preset nuscenes-chiu2019 > my.json   # a preset to edit
///   probmot config --config my.json                      # validate the edited file, print it
///   probmot config --preset ab3dmot-kitti                # AB3DMOT's own KITTI settings
///   probmot config --preset ab3dmot-kitti --motion ctrv --nms-iou 0.1   # with two levers on
///   probmot config --preset ab3dmot-kitti --coast gaps --backfill        # offline reporting
///   probmot config --list
#[derive(Debug, Args)]
#[command(verbatim_doc_comment)]
pub struct ConfigArgs {
    #[command(flatten)]
    tracker: TrackerArgs,
    /// List the built-in presets with a line on each.
    #[arg(long)]
    list: bool,
}

/// Covariance choices on the command line.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum CovarianceArg {
    /// The covariances of the config or preset.
    Config,
    /// AB3DMOT's hand-set defaults (the paper's "default covariance" ablation).
    Default,
}

/// Tracker settings: a config file or preset, and the ablation switches that override it
/// (the rows of the paper's Table 1).
#[derive(Debug, Clone, Args)]
pub struct TrackerArgs {
    /// Tracker config file (JSON, as printed by `probmot config`).
    #[arg(
        long,
        value_name = "FILE",
        conflicts_with = "preset",
        help_heading = "Tracker"
    )]
    pub config: Option<PathBuf>,
    /// Built-in preset (default nuscenes-chiu2019). Example: --preset ab3dmot-kitti
    #[arg(long, value_parser = choice::<Preset>(), value_name = "NAME", help_heading = "Tracker")]
    pub preset: Option<Preset>,
    /// Override the distance of every class.
    #[arg(long, value_parser = choice::<DistanceKind>(), help_heading = "Ablations")]
    pub distance: Option<DistanceKind>,
    /// Override the gate of every class (max distance, or min IoU for IoU kinds).
    #[arg(long, help_heading = "Ablations")]
    pub threshold: Option<f64>,
    /// Override the matcher of every class.
    #[arg(long, value_parser = choice::<MatcherKind>(), help_heading = "Ablations")]
    pub matcher: Option<MatcherKind>,
    /// Turn off the angular velocity in the motion model.
    #[arg(long, help_heading = "Ablations")]
    pub no_angular_velocity: bool,
    /// Use the covariances of the config, or AB3DMOT's defaults.
    #[arg(long, value_enum, help_heading = "Ablations")]
    pub covariance: Option<CovarianceArg>,
    /// Override the nominal frame period, seconds (nuScenes 0.5, KITTI 0.1).
    #[arg(long, value_name = "S", help_heading = "Tracker")]
    pub dt_nominal: Option<f64>,
    /// Override min_hits of every class.
    #[arg(long, help_heading = "Tracker")]
    pub min_hits: Option<u32>,
    /// Override max_age of every class.
    #[arg(long, help_heading = "Tracker")]
    pub max_age: Option<u32>,
    /// Ignore detections scoring below this.
    #[arg(long, help_heading = "Tracker")]
    pub score_floor: Option<f64>,
    /// Motion model of every class: cv (constant velocity, the paper) or ctrv (coordinated
    /// turn; turns the yaw rate on). See docs/tune.md. Example: --motion ctrv
    #[arg(long, value_parser = choice::<Motion>(), help_heading = "Levers",
          conflicts_with = "no_angular_velocity")]
    pub motion: Option<Motion>,
    /// Drop a detection whose 3D IoU with a higher-scoring detection of its class exceeds this,
    /// before association (every class). Example: --nms-iou 0.1
    #[arg(long, value_name = "IOU", help_heading = "Levers")]
    pub nms_iou: Option<f64>,
    /// Two-stage association for every class: detections scoring below this cannot start a
    /// track but may continue one the first round left unmatched (detector's score scale).
    /// Example: --birth-score 0.5
    #[arg(long, value_name = "SCORE", help_heading = "Levers")]
    pub birth_score: Option<f64>,
    /// Which coasted frames (predictions without a detection) every class reports: all (the
    /// paper, up to max_age), gaps (only those a later match bridges) or none. Offline: the
    /// output waits a few frames to know. Example: --coast gaps
    #[arg(long, value_parser = choice::<Coast>(), help_heading = "Levers")]
    pub coast: Option<Coast>,
    /// Offline: once a track reaches min_hits, also report its earlier frames (every class),
    /// so tracks start at their first detection; `--backfill false` turns it off (e.g. in the
    /// kitti-pointrcnn preset). Example: --backfill
    #[arg(long, help_heading = "Levers", value_name = "BOOL", num_args = 0..=1,
          default_missing_value = "true")]
    pub backfill: Option<bool>,
    /// Two-point initialization: a detection left unmatched (one that could start a track)
    /// may continue a track born in the previous frame within this speed (m/s), which then
    /// takes the velocity of the two detections; for objects that move further per frame than
    /// the gate allows (fast cars at nuScenes' 2 Hz). One speed for every class, or per class
    /// (`*=`: the others), since a pedestrian's is far lower than a car's.
    /// Example: --two-point-speed car=40,motorcycle=40,bus=30,truck=30
    #[arg(long, value_name = "M/S|CLASS=M/S,...", help_heading = "Levers",
          value_parser = |s: &str| PerClass::parse(s, "m/s"))]
    pub two_point_speed: Option<PerClass>,
}

impl TrackerArgs {
    /// The configuration these flags describe, validated ([`Overrides`] holds the rules).
    pub fn resolve(&self) -> Result<TrackerConfig> {
        let mut cfg = base_config(self.config.as_deref(), self.preset)?;
        self.overrides().apply(&mut cfg)?;
        Ok(cfg)
    }

    /// The override flags as the library's [`Overrides`].
    fn overrides(&self) -> Overrides {
        Overrides {
            distance: self.distance,
            threshold: self.threshold,
            matcher: self.matcher,
            no_angular_velocity: self.no_angular_velocity,
            default_covariance: matches!(self.covariance, Some(CovarianceArg::Default)),
            dt_nominal: self.dt_nominal,
            min_hits: self.min_hits,
            max_age: self.max_age,
            score_floor: self.score_floor,
            motion: self.motion,
            nms_iou: self.nms_iou,
            birth_score: self.birth_score,
            coast: self.coast,
            backfill: self.backfill,
            two_point_speed: self.two_point_speed.clone(),
        }
    }
}

pub fn run(a: ConfigArgs) -> Result<ExitCode> {
    if a.list {
        for p in Preset::ALL {
            println!("{:<18} {}", p.name(), p.description());
        }
        return Ok(ExitCode::SUCCESS);
    }
    let cfg = a.tracker.resolve()?;
    println!("{}", cfg.to_json());
    Ok(ExitCode::SUCCESS)
}
