//! `probmot tune`.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use clap::Args;
use probmot::eval::kitti::MeanScores;
use probmot::tracker::levers::Coast;
use probmot::tune::files::{tune_files, BaseChoice, TuneFilesOptions};
use probmot::tune::text::loss_warning;
use probmot::tune::{Protocol, SearchLimits};

use super::choice::choice;

/// Tune per-class tracker settings on logs with ground truth and detections, cross-validated.
///
/// For logs as `probmot import kitti|nuscenes` writes them. With --folds K (default 2) the logs
/// are split into K contiguous folds in the order given; for each fold the noise is fitted (as
/// `probmot fit --fold-yaw`) and the settings tuned on the other folds only, and the held-out
/// fold is scored. A table shows, per fold and per class, the held-out score of the base config
/// (with the noise fitted on the training folds) next to the tuned one, and the score over all
/// held-out logs together. Then the noise is fitted and the settings tuned on all logs, and that
/// config is written to -o.
///
/// Search: coordinate descent (classes are tracked and scored independently). Each round tries
/// every candidate value of one option at a time and keeps the best when it raises the training
/// score (sAMOTA for kitti, AMOTA for nuscenes; for kitti with each track's mean score computed
/// once, see --search-means) by more than --margin. Options: fitted or the base config's own
/// noise, gate and distance, matcher, min_hits, max_age, which frames are reported (coast,
/// backfill), yaw rate, Q and R factors, NMS, reported score and its refinement, score floor,
/// two-stage birth score, life cycle by confidence (and two-point initialization when
/// --search names it). Only classes with at least --min-tracks ground-truth trajectories in the
/// training logs are searched (from the base with fitted noise); the others keep the base
/// config's own settings and noise, as a handful of trajectories supports no data-driven
/// choice. With --shared, a first stage chooses the class-agnostic options jointly for every
/// class (on the mean score of the searched classes), and the other classes keep those instead.
/// Bound the work with --budget (configurations per search; about 80 make one round) and
/// --rounds; the total is at most (folds + 1) x (classes + 1) x budget configurations, and a
/// configuration seen before is not scored again. Deterministic for the same inputs and
/// options, whatever --jobs.
///
/// Examples:
///   probmot tune sample_logs/*.mcap -o tuned.json
///   probmot tune logs/*.mcap -o tuned.json --folds 2 --budget 100 --jobs 2 --json
///   probmot tune logs/*.mcap -o tuned.json --min-tracks 20 --margin 0.01
///   probmot tune logs/*.mcap -o nms.json --search nms_iou     # what NMS alone gives
///   probmot tune logs/*.mcap -o tuned.json --preset ab3dmot-kitti --coast gaps   # offline base
///   probmot track drive.mcap -o out.mcap --config tuned.json
#[derive(Debug, Args)]
#[command(verbatim_doc_comment)]
pub struct TuneArgs {
    /// Input MCAP files with ground truth and detections.
    #[arg(required = true, value_name = "LOG.mcap")]
    inputs: Vec<PathBuf>,
    /// Output config (JSON), fitted and tuned on all inputs; written atomically.
    #[arg(short, long, value_name = "tuned.json")]
    output: PathBuf,
    /// Protocol whose headline metric is maximised: kitti (sAMOTA) or nuscenes (AMOTA).
    /// Default: kitti when every log was written by `probmot import kitti`, nuscenes when none
    /// was (logs of both kinds need it given).
    #[arg(long, value_parser = choice::<Protocol>())]
    protocol: Option<Protocol>,
    /// KITTI: minimum 3D IoU of a match (as `probmot eval --iou`).
    #[arg(long, default_value_t = 0.25, value_name = "IOU")]
    iou: f64,
    /// KITTI: how the search's objective computes each track's mean score. once (default):
    /// from the track's own scores. every-pass: as the reference evaluation does on Python 3.11
    /// or older, re-averaged at every threshold, whose ulp of drift drops tracks at thresholds
    /// equal to their own means (see `probmot eval --means`), noise a search would chase.
    /// every-pass-py312: as the reference does on Python 3.12+. The held-out table is always
    /// scored as the reference does on Python 3.11. Example: --search-means every-pass
    #[arg(long, value_parser = choice::<MeanScores>(), value_name = "WHEN")]
    search_means: Option<MeanScores>,
    /// Number of cross-validation folds; 0 or 1: no cross-validation, only the final tune.
    #[arg(long, default_value_t = 2, value_name = "K")]
    folds: usize,
    /// Base config file (JSON); its settings are the search's starting point. `--base-config`
    /// as in `fit`.
    #[arg(
        long,
        visible_alias = "base-config",
        value_name = "CONFIG",
        conflicts_with = "preset"
    )]
    base: Option<PathBuf>,
    /// Base preset (default nuscenes-chiu2019); `--base-preset` as in `fit`.
    #[arg(long, visible_alias = "base-preset", value_name = "NAME")]
    preset: Option<String>,
    /// Set the base's coasted-frame reporting for every class, as `track --coast` (all, gaps,
    /// none); classes that are not searched keep it. Example: --coast gaps
    #[arg(long, value_parser = choice::<Coast>())]
    coast: Option<Coast>,
    /// Set backfill on (or with `false` off) for every class of the base, as
    /// `track --backfill`.
    #[arg(long, value_name = "BOOL", num_args = 0..=1, default_missing_value = "true")]
    backfill: Option<bool>,
    /// Classes to tune and score, comma-separated (default: the protocol's classes).
    #[arg(
        long,
        value_delimiter = ',',
        value_name = "LIST",
        visible_alias = "class"
    )]
    classes: Vec<String>,
    /// Search only these options, comma-separated (default: all but two_point_speed): noise,
    /// gate, matcher, min_hits, max_age, coast, backfill, angular_velocity, motion, q_factor,
    /// r_factor, nms_iou, score, blend, score_floor, birth_score, boost, decay, keep_score, and
    /// two_point_speed (two-point initialization, for fast objects at low frame rates; searched
    /// only when named). One option gives its ablation (scripts/kitti_levers.sh).
    /// Example: --search nms_iou
    #[arg(long, value_delimiter = ',', value_name = "LIST")]
    search: Vec<String>,
    /// Largest number of configurations evaluated per class in one search.
    #[arg(long, default_value_t = 100, value_name = "N")]
    budget: usize,
    /// Largest number of coordinate-descent rounds per search.
    #[arg(long, default_value_t = 3, value_name = "N")]
    rounds: usize,
    /// A move must raise the training score by more than this (fraction, 0.005 = half a point).
    #[arg(long, default_value_t = 0.005, value_name = "M")]
    margin: f64,
    /// Ground-truth trajectories a class needs in the training logs to be tuned on its own;
    /// classes with fewer keep the shared settings.
    #[arg(long, default_value_t = 10, value_name = "N")]
    min_tracks: usize,
    /// Run the shared stage first (class-agnostic options chosen jointly for every class on the
    /// mean score of the classes with enough trajectories; classes with too few keep them).
    #[arg(long)]
    shared: bool,
    /// First choose which frames every class reports (coast, backfill) once, on the mean
    /// training score of the searched classes; classes with too few trajectories get that
    /// choice too (with the base's other settings). These options follow how the ground truth
    /// is labelled more than the class. Example: probmot tune logs/*.mcap -o t.json
    /// --pool-reporting
    #[arg(long)]
    pool_reporting: bool,
    /// After the cross-validation, keep the base config's own settings in the written config
    /// for every class whose tuned settings scored below the base on a held-out fold (the
    /// classes the warning names). The cross-validation's scores are of the search without
    /// this rule. Example: probmot tune logs/*.mcap -o tuned.json --keep-base-on-loss
    #[arg(long)]
    keep_base_on_loss: bool,
    /// Worker threads, 1 to 1024 (default: all cores).
    #[arg(long, value_name = "N", value_parser = super::count::count_in(1, super::count::MAX_JOBS))]
    jobs: Option<u64>,
    /// Period in seconds of the config's velocities (default: the data's frame period).
    #[arg(long, value_name = "S")]
    dt_nominal: Option<f64>,
    /// Classes with fewer matched pairs keep the base noise (as `probmot fit --min-samples`).
    #[arg(long, default_value_t = 50, value_name = "N")]
    min_samples: u64,
    /// Also write the config tuned for each fold to DIR/fold_<i>.json (to re-score the held-out
    /// logs with `probmot track` and `probmot eval`).
    #[arg(long, value_name = "DIR")]
    fold_configs: Option<PathBuf>,
    /// Ground-truth topic.
    #[arg(long, default_value = "/ground_truth", value_name = "TOPIC")]
    truth_topic: String,
    /// Detections topic.
    #[arg(long, default_value = "/detections", value_name = "TOPIC")]
    detections_topic: String,
    /// Print the report as JSON instead of the table.
    #[arg(long)]
    json: bool,
    /// No progress bar.
    #[arg(short, long)]
    quiet: bool,
}

impl TuneArgs {
    /// The library's options from the flags.
    fn options(&self) -> TuneFilesOptions {
        TuneFilesOptions {
            base: BaseChoice {
                file: self.base.clone(),
                preset: self.preset.clone(),
                coast: self.coast,
                backfill: self.backfill,
            },
            protocol: self.protocol,
            iou: self.iou,
            search_means: self.search_means,
            folds: self.folds,
            limits: SearchLimits {
                budget: self.budget,
                rounds: self.rounds,
                margin: self.margin,
                min_tracks: self.min_tracks,
                shared: self.shared,
                pool_reporting: self.pool_reporting,
            },
            dt_nominal: self.dt_nominal,
            min_samples: self.min_samples,
            classes: self.classes.iter().map(|c| c.to_lowercase()).collect(),
            search: self.search.clone(),
            keep_base_on_loss: self.keep_base_on_loss,
            fold_configs: self.fold_configs.clone(),
            jobs: self.jobs.map(super::count::to_usize),
            truth_topic: self.truth_topic.clone(),
            detections_topic: self.detections_topic.clone(),
        }
    }
}

/// Runs `probmot tune`.
pub fn run(a: TuneArgs) -> Result<ExitCode> {
    let template = "{spinner} [{bar:30}] {pos} configs of at most {len}, {elapsed} {msg}";
    let pb = super::bar(super::show_progress(a.quiet), super::style(template));
    let warn = |w: &str| pb.suspend(|| eprintln!("warning: {w}"));
    let r = tune_files(&a.inputs, &a.output, &a.options(), &warn, &|e| {
        super::show_on_bar(&pb, e)
    });
    pb.finish_and_clear();
    let r = r?;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&r.json(&a.output))?);
    } else {
        print!("{}", r.text(&a.output));
    }
    for l in r.losses.iter().flatten() {
        eprintln!("warning: {}", loss_warning(l));
    }
    Ok(ExitCode::SUCCESS)
}
