//! `probmot tune`.

use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write as _;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{bail, ensure, Context, Result};
use clap::{Args, ValueEnum};
use indicatif::{ProgressBar, ProgressStyle};
use probmot::eval::kitti::MeanScores;
use probmot::fit::timing::mixed_periods;
use probmot::mcapio::writer::{check_output_path, write_file_atomic};
use probmot::msgs::detection_frame::describe_skips;
use probmot::pipeline::kitti_io::is_kitti_import;
use probmot::pipeline::overrides::Overrides;
use probmot::pipeline::rosbag_dir::resolve_input;
use probmot::tracker::TrackerConfig;

use super::config_cmd::CoastArg;
use super::means_arg::MeansArg;
use probmot::tune::{
    self, cross_validate, overall, CvReport, HeldOutLoss, Protocol, Scoring, SearchLimits, TuneLog,
    TuneOptions,
};
use rayon::prelude::*;

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
///   probmot tune logs/*.mcap -o tuned.json
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
    #[arg(long, value_enum)]
    protocol: Option<ProtocolArg>,
    /// KITTI: minimum 3D IoU of a match (as `probmot eval --iou`).
    #[arg(long, default_value_t = 0.25, value_name = "IOU")]
    iou: f64,
    /// KITTI: how the search's objective computes each track's mean score. once (default):
    /// from the track's own scores. every-pass: as the reference evaluation does on Python 3.11
    /// or older, re-averaged at every threshold, whose ulp of drift drops tracks at thresholds
    /// equal to their own means (see `probmot eval --means`), noise a search would chase.
    /// every-pass-py312: as the reference does on Python 3.12+. The held-out table is always
    /// scored as the reference does on Python 3.11. Example: --search-means every-pass
    #[arg(long, value_enum, value_name = "WHEN")]
    search_means: Option<MeansArg>,
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
    #[arg(long, value_enum)]
    coast: Option<CoastArg>,
    /// Set backfill on (or with `false` off) for every class of the base, as
    /// `track --backfill`.
    #[arg(long, value_name = "BOOL", num_args = 0..=1, default_missing_value = "true")]
    backfill: Option<bool>,
    /// Classes to tune and score, comma-separated (default: the protocol's classes).
    #[arg(long, value_delimiter = ',', value_name = "LIST")]
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
    /// Worker threads (default: all cores).
    #[arg(long, value_name = "N")]
    jobs: Option<usize>,
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

#[derive(Debug, Clone, Copy, ValueEnum)]
enum ProtocolArg {
    Kitti,
    Nuscenes,
}

/// The base config: the file or preset, with `--coast` and `--backfill` applied.
fn base_config(a: &TuneArgs) -> Result<TrackerConfig> {
    let mut cfg = match &a.base {
        Some(p) => {
            let text = std::fs::read_to_string(p)
                .with_context(|| format!("cannot read base config {}", p.display()))?;
            TrackerConfig::from_json(&text).with_context(|| format!("{}", p.display()))?
        }
        None => TrackerConfig::preset(a.preset.as_deref().unwrap_or("nuscenes-chiu2019"))?,
    };
    let reporting = Overrides {
        coast: a.coast.map(CoastArg::mode),
        backfill: a.backfill,
        ..Overrides::default()
    };
    reporting.apply(&mut cfg)?;
    let mut set = Vec::new();
    if let Some(c) = a.coast {
        set.push(format!(
            "coast {}",
            c.to_possible_value().expect("a value").get_name()
        ));
    }
    match a.backfill {
        Some(true) => set.push("backfill".to_string()),
        Some(false) => set.push("no backfill".to_string()),
        None => {}
    }
    if !set.is_empty() {
        cfg.name = format!("{} with {}", cfg.name, set.join(", "));
    }
    Ok(cfg)
}

fn pct(v: f64) -> String {
    if v.is_finite() {
        format!("{:.2}", 100.0 * v)
    } else {
        "-".into()
    }
}

/// What a class that was not searched got: the same words in the table and the summary.
/// `kept_on_loss`: the final tune kept it for its held-out loss (the folds never do).
fn not_searched(o: &TuneOptions, kept_on_loss: bool) -> &'static str {
    if kept_on_loss {
        "lost held-out (--keep-base-on-loss): the base's own settings and noise"
    } else if o.limits.shared {
        "too few trajectories: shared settings"
    } else {
        "too few trajectories: the base's own settings and noise"
    }
}

fn table(cv: &CvReport, o: &TuneOptions) -> String {
    let metric = o.scoring.metric();
    let mut s = String::new();
    let _ = writeln!(s, "held-out {metric} (x100): base (fitted noise) vs tuned");
    let _ = writeln!(
        s,
        "{:<28} {:<12} {:>8} {:>8}  training trajectories",
        "held-out logs", "class", "base", "tuned"
    );
    let mut rows = |name: &str,
                    base: &BTreeMap<String, f64>,
                    tuned: &BTreeMap<String, f64>,
                    search: &[tune::ClassTune]| {
        for (c, b) in base {
            let t = tuned.get(c).copied().unwrap_or(f64::NAN);
            let note = match search.iter().find(|x| &x.label == c) {
                Some(x) if x.refined => format!("{} (searched)", x.trajectories),
                Some(x) => format!("{} ({})", x.trajectories, not_searched(o, false)),
                None if search.is_empty() => String::new(),
                None => "none (no detections in the training folds: folds are the logs in the order given)".into(),
            };
            let line = format!("{name:<28} {c:<12} {:>8} {:>8}  {note}", pct(*b), pct(t));
            let _ = writeln!(s, "{}", line.trim_end());
        }
        let _ = writeln!(
            s,
            "{name:<28} {:<12} {:>8} {:>8}",
            "overall",
            pct(overall(base)),
            pct(overall(tuned))
        );
    };
    for (i, f) in cv.folds.iter().enumerate() {
        let n = f.held_out.len();
        let name = format!("fold {} ({n} log{})", i + 1, if n == 1 { "" } else { "s" });
        rows(&name, &f.base, &f.tuned, &f.search);
    }
    rows("all held-out together", &cv.base, &cv.tuned, &[]);
    let once = !cv.tuned_means_once.is_empty();
    if once {
        rows(
            "all, means once *",
            &cv.base_means_once,
            &cv.tuned_means_once,
            &[],
        );
        let _ = writeln!(
            s,
            "* each track's mean score computed once, not re-averaged at every threshold as the\n  \
             reference does: not the official number (see `probmot eval --means`)"
        );
    }
    s.push_str(&gains_table(cv, metric));
    s
}

/// The held-out gains with their paired intervals; a gain whose interval holds 0 is within the
/// noise, and said so.
fn gains_table(cv: &CvReport, metric: &str) -> String {
    let mut s = format!(
        "held-out gain of {metric} (tuned - base, x100), all held-out logs together, with its \
         paired 95 % bootstrap interval ({} resamples):\n",
        tune::gains::RESAMPLES
    );
    for (c, g) in &cv.gains {
        let (lo, hi) = (g.ci95[0] * 100.0, g.ci95[1] * 100.0);
        let verdict = if g.ci95[0] > 0.0 {
            "a gain beyond the noise"
        } else if g.ci95[1] < 0.0 {
            "a loss beyond the noise"
        } else {
            "within the noise"
        };
        let d = g.delta * 100.0;
        let _ = writeln!(s, "  {c:<12} {d:>+7.2} [{lo:+.2}, {hi:+.2}]  {verdict}");
    }
    s
}

/// Runs `probmot tune`.
pub fn run(mut a: TuneArgs) -> Result<ExitCode> {
    a.inputs = (a.inputs.iter())
        .map(|p| resolve_input(p))
        .collect::<Result<_>>()?;
    ensure!(a.budget >= 1, "--budget must be at least 1");
    ensure!(
        a.margin.is_finite() && a.margin >= 0.0,
        "--margin must be a finite number >= 0, got {}",
        a.margin
    );
    ensure!(
        a.iou > 0.0 && a.iou <= 1.0,
        "--iou must lie in (0, 1], got {}",
        a.iou
    );
    if a.protocol.is_some() {
        check_search_means(&a, false)?;
    }
    tune::space::check_names(&a.search).map_err(anyhow::Error::msg)?;
    // A misspelt log is named as such, before the fold count that it would otherwise fail.
    for p in &a.inputs {
        std::fs::File::open(p).with_context(|| format!("cannot open {}", p.display()))?;
    }
    // Checked before the logs are read (a long log takes a while).
    ensure!(
        a.folds < 2 || a.inputs.len() >= a.folds,
        "--folds {} needs one log per fold ({} log(s) given); --folds 1 tunes on all the logs \
         without cross-validation",
        a.folds,
        a.inputs.len()
    );
    for input in &a.inputs {
        check_output_path(Some(input), &a.output)?;
    }
    let inferred = a.protocol.is_none();
    a.protocol = Some(protocol_of(&a)?);
    check_search_means(&a, inferred)?;
    let base = base_config(&a)?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(a.jobs.unwrap_or(0))
        .build()?;
    pool.install(|| run_in_pool(&a, &base))
}

/// --search-means only with the KITTI protocol (given, or found from the logs: `inferred`).
fn check_search_means(a: &TuneArgs, inferred: bool) -> Result<()> {
    ensure!(
        a.search_means.is_none() || matches!(a.protocol, Some(ProtocolArg::Kitti)),
        "--search-means is a KITTI option (the nuScenes devkit averages each track's score \
         once){}",
        match inferred {
            true =>
                "; these logs were not written by `probmot import kitti`, so they are \
                     scored with the nuScenes protocol (--protocol kitti chooses KITTI's)",
            false => "",
        }
    );
    Ok(())
}

/// A warning when the KITTI protocol scores logs `probmot import kitti` did not write: their
/// boxes have no 2D image box, so the rules that ignore boxes by it cannot apply.
fn kitti_protocol_warning(a: &TuneArgs) -> Result<Option<String>> {
    if !matches!(a.protocol, Some(ProtocolArg::Kitti)) {
        return Ok(None);
    }
    let mut other = Vec::new();
    for p in &a.inputs {
        if !is_kitti_import(p)? {
            other.push(p.display().to_string());
        }
    }
    Ok((!other.is_empty()).then(|| {
        format!(
            "--protocol kitti on logs `probmot import kitti` did not write ({}): their boxes \
             have no 2D image box, so KITTI's rules that ignore low boxes and boxes in DontCare \
             regions do not apply and every unmatched track box counts as a false positive",
            other.join(", ")
        )
    }))
}

/// The protocol: --protocol, else kitti when every input is a KITTI import and nuscenes when
/// none is.
fn protocol_of(a: &TuneArgs) -> Result<ProtocolArg> {
    if let Some(p) = a.protocol {
        return Ok(p);
    }
    let mut kitti = Vec::new();
    for p in &a.inputs {
        kitti.push(is_kitti_import(p)?);
    }
    match (kitti.iter().all(|k| *k), kitti.iter().any(|k| *k)) {
        (true, _) => Ok(ProtocolArg::Kitti),
        (false, false) => Ok(ProtocolArg::Nuscenes),
        (false, true) => bail!(
            "some logs were written by `probmot import kitti` and some not: give --protocol \
             kitti or nuscenes"
        ),
    }
}

/// The tune's options from the flags (`keep_base` empty: the final tune sets it).
fn options(a: &TuneArgs) -> TuneOptions {
    TuneOptions {
        scoring: Scoring {
            protocol: match a.protocol {
                Some(ProtocolArg::Kitti) => Protocol::Kitti,
                Some(ProtocolArg::Nuscenes) | None => Protocol::Nuscenes,
            },
            iou: a.iou,
            search_means: a.search_means.map_or(MeanScores::Once, MeansArg::means),
        },
        limits: SearchLimits {
            budget: a.budget,
            rounds: a.rounds,
            margin: a.margin,
            min_tracks: a.min_tracks,
            shared: a.shared,
            pool_reporting: a.pool_reporting,
        },
        dt_nominal: a.dt_nominal,
        min_samples: a.min_samples,
        classes: a.classes.iter().map(|c| c.to_lowercase()).collect(),
        search: a.search.clone(),
        keep_base: Vec::new(),
    }
}

/// Writes the final config to -o and, with --fold-configs, each fold's config.
fn write_configs(a: &TuneArgs, cfg: &TrackerConfig, cv: Option<&CvReport>) -> Result<()> {
    write_file_atomic(&a.output, format!("{}\n", cfg.to_json()).as_bytes())?;
    if let (Some(dir), Some(cv)) = (&a.fold_configs, cv) {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        for (i, c) in cv.fold_configs.iter().enumerate() {
            let p = dir.join(format!("fold_{}.json", i + 1));
            write_file_atomic(&p, format!("{}\n", c.to_json()).as_bytes())?;
        }
    }
    Ok(())
}

fn run_in_pool(a: &TuneArgs, base: &TrackerConfig) -> Result<ExitCode> {
    let logs = a
        .inputs
        .par_iter()
        .map(|p| TuneLog::load(p, &a.truth_topic, &a.detections_topic))
        .collect::<Result<Vec<_>>>()?;
    let mut warnings = skip_warnings(a, &logs);
    warnings.extend(period_warning(&logs));
    warnings.extend(kitti_protocol_warning(a)?);
    for w in &warnings {
        eprintln!("warning: {w}");
    }
    let o = options(a);
    let scoring = o.scoring;
    let all: Vec<&TuneLog> = logs.iter().collect();
    let n_classes = scored_classes(&all, &o)?;
    let cv_folds = if a.folds >= 2 { a.folds } else { 0 };
    let pb = if super::show_progress(a.quiet) {
        let total = (cv_folds + 1) * (n_classes + 1) * a.budget;
        ProgressBar::new(total as u64).with_style(
            ProgressStyle::with_template(
                "{spinner} [{bar:30}] {pos} configs of at most {len}, {elapsed} {msg}",
            )
            .expect("valid template"),
        )
    } else {
        ProgressBar::hidden()
    };
    let cv = if cv_folds >= 2 {
        pb.set_message("cross-validating");
        Some(cross_validate(base, &logs, cv_folds, &o, &|e| {
            super::show_on_bar(&pb, e)
        })?)
    } else {
        None
    };
    pb.set_message("tuning on all logs");
    let losses = cv.as_ref().map(|cv| cv.losses(o.limits.margin));
    let mut final_options = o.clone();
    if a.keep_base_on_loss {
        final_options.keep_base = losses.iter().flatten().map(|l| l.label.clone()).collect();
    }
    let t = tune::tune(base, &all, &final_options, &|e| super::show_on_bar(&pb, e))?;
    pb.finish_and_clear();
    let mut cfg = t.tuned.clone();
    cfg.name = format!(
        "tune of {} log(s) on {} ({}, {} per class, budget {})",
        logs.len(),
        base.name,
        match scoring.protocol {
            Protocol::Kitti => "kitti",
            Protocol::Nuscenes => "nuscenes",
        },
        scoring.search_metric(),
        a.budget
    );
    if a.pool_reporting {
        cfg.name = cfg
            .name
            .replace(" per class,", " per class, reporting pooled,");
    }
    write_configs(a, &cfg, cv.as_ref())?;
    let found = (cv.as_ref(), losses.as_deref(), &warnings[..]);
    report(a, &final_options, found, &t)?;
    for l in losses.iter().flatten() {
        eprintln!(
            "warning: {} on fold {}: the settings tuned on its {} training trajectories scored {} \
             held-out against the base's {}; too few to tune it? (--min-tracks above {}, or \
             --keep-base-on-loss, keeps the base's settings)",
            l.label,
            l.fold,
            l.trajectories,
            pct(l.tuned),
            pct(l.base),
            l.trajectories
        );
    }
    Ok(ExitCode::SUCCESS)
}

/// The number of classes the tune scores (the chosen classes, default the protocol's, that have
/// detections; as [`tune::classes`]). An error when a class of `--classes` has none (a typo,
/// say), or when none of the protocol's classes has: each names the labels there are.
fn scored_classes(logs: &[&TuneLog], o: &TuneOptions) -> Result<usize> {
    let labels: BTreeSet<&str> = (logs.iter())
        .flat_map(|l| l.frames.iter().flat_map(|f| f.detections.iter()))
        .map(|d| &*d.label)
        .collect();
    let listed = || labels.iter().copied().collect::<Vec<_>>().join(", ");
    let missing: Vec<&str> = (o.classes.iter())
        .map(String::as_str)
        .filter(|c| !labels.contains(c))
        .collect();
    if !missing.is_empty() {
        bail!(
            "--classes: no detection of {} in the inputs (their labels: {})",
            missing.join(", "),
            listed()
        );
    }
    let n = tune::classes(logs, o).len();
    if n == 0 {
        bail!(
            "no detection of the {} protocol's classes ({}) in the inputs (their labels: {}); \
             choose the protocol with --protocol or the classes with --classes",
            protocol_name(o.scoring.protocol),
            o.scoring.classes().join(", "),
            listed()
        );
    }
    Ok(n)
}

/// The protocol's name in messages.
fn protocol_name(p: Protocol) -> &'static str {
    match p {
        Protocol::Kitti => "KITTI",
        Protocol::Nuscenes => "nuScenes",
    }
}

/// A warning when the logs' frame periods differ (the noise fit of each fold pools them at one
/// period), as `probmot fit` gives it.
fn period_warning(logs: &[TuneLog]) -> Option<String> {
    let (periods, pooled) = tune::data::frame_periods(logs);
    mixed_periods(&periods, pooled?)
}

/// One warning per log that had detections left out when read (none is dropped unsaid).
fn skip_warnings(a: &TuneArgs, logs: &[TuneLog]) -> Vec<String> {
    (a.inputs.iter().zip(logs))
        .filter(|(_, l)| !l.skipped_detections.is_empty())
        .map(|(p, l)| {
            format!(
                "{}: topic {}: skipped {}, as `probmot track` skips them",
                p.display(),
                a.detections_topic,
                describe_skips(&l.skipped_detections)
            )
        })
        .collect()
}

/// Prints the cross-validation table and the final tune's per-class summary, or all as JSON
/// (the held-out losses and the reading warnings included).
fn report(
    a: &TuneArgs,
    o: &TuneOptions,
    (cv, losses, warnings): (Option<&CvReport>, Option<&[HeldOutLoss]>, &[String]),
    t: &tune::Tuned,
) -> Result<()> {
    if a.json {
        let v = serde_json::json!({
            "output": a.output.display().to_string(),
            "options": o,
            "warnings": warnings,
            "cross_validation": cv,
            "held_out_losses": losses,
            "final": { "shared": t.shared, "classes": t.classes, "scored": t.scored },
        });
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        let scored: Vec<&str> = t.classes.iter().map(|c| c.label.as_str()).collect();
        println!(
            "scored with the {} protocol: {} (its classes with detections in the logs); other \
             classes keep the base's settings with the fitted noise{}",
            protocol_name(o.scoring.protocol),
            scored.join(", "),
            match a.pool_reporting {
                true => " and the pooled reporting options",
                false => "",
            }
        );
        if let Some(cv) = cv {
            print!("{}", table(cv, o));
        }
        for c in &t.classes {
            println!(
                "{}: {} trajector{}, training {} base {} -> shared {} -> {} ({})",
                c.label,
                c.trajectories,
                if c.trajectories == 1 { "y" } else { "ies" },
                o.scoring.search_metric(),
                pct(c.base_score),
                pct(c.shared_score),
                pct(c.score),
                if c.refined {
                    "searched"
                } else {
                    not_searched(o, o.keep_base.contains(&c.label))
                }
            );
        }
        println!("wrote {}", a.output.display());
    }
    Ok(())
}
