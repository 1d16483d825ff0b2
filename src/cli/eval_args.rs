//! The arguments of `probmot eval` and what its two protocol runners ([`super::eval_cmd`] for
//! nuScenes, [`super::eval_kitti`]) share: progress bars, log pairs, the regression gate.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::{Args, ValueEnum};
use indicatif::{ProgressBar, ProgressStyle};

use super::means_arg::MeansArg;
use super::show_progress;
use probmot::eval::legend::{Section, SECTIONS};
use probmot::eval::range::RangeFilter;
use probmot::formats::nuscenes::BIKE_RACKS_TOPIC;

/// The rule of the regression gate (--max-drop).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Gate {
    /// The fall is larger than --max-drop and its paired 95 % interval lies below 0.
    Interval,
    /// The fall is larger than --max-drop.
    Point,
}

/// Evaluation protocols.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Protocol {
    /// nuScenes tracking benchmark (AMOTA, AMOTP, MOTA, ...; 2 m centre distance).
    Nuscenes,
    /// KITTI 3D MOT as evaluated by AB3DMOT (sAMOTA, AMOTA, AMOTP, MOTA, ...; 3D IoU matching,
    /// KITTI's ignore rules for truncated/occluded ground truth, DontCare regions, small boxes
    /// and the neighbouring classes Van and Person_sitting).
    Kitti,
}

/// Score tracks against ground truth with the nuScenes tracking metrics or the KITTI 3D MOT
/// metrics (AB3DMOT's evaluation), optionally against a baseline run, as a regression gate.
///
/// Ground truth is a probmot.Tracks3D channel whose ids are the true instance ids (a simulated
/// log carries it as /ground_truth, so a tracked simulated log holds both channels; so does a
/// KITTI sequence written by `probmot import kitti` with --labels, once tracked).
///
/// Exit status: 0 ok, 2 error, 3 the gate (--max-drop) failed.
///
/// Examples:
///   probmot eval --truth drive.tracked.mcap
///   probmot eval --truth drive.mcap --tracks drive.tracked.mcap --json
///   probmot eval --truth gt.mcap --tracks new.mcap --baseline old.mcap --max-drop 1
///   probmot eval --truth gt/ --tracks new/ --baseline old/ --bootstrap 1000 --max-drop 1
///   probmot eval --protocol kitti --truth 0000.tracked.mcap
///   probmot eval --protocol kitti --iou 0.5 --classes car --truth 0000.tracked.mcap
///   probmot eval --protocol kitti --means once --truth new/ --baseline old/ --max-drop 1
///   probmot eval --truth gt/ --tracks tracked/ --json        # many logs, paired by file name
///   probmot eval --devkit --truth val/                        # the official nuScenes number
///   probmot eval --explain                                    # what each column means
#[derive(Debug, Args)]
#[command(verbatim_doc_comment, after_long_help = probmot::eval::legend::text(&SECTIONS))]
pub struct EvalArgs {
    /// Files with the ground-truth channel: files, directories (their *.mcap) or glob patterns.
    /// Several logs are scored together, each log one scene, as the devkit does across scenes.
    #[arg(long, value_name = "GT", num_args = 1.., required_unless_present_any = ["explain", "stray"])]
    pub(super) truth: Vec<PathBuf>,
    /// Files given without an option: refused with the hint to name them with --truth.
    #[arg(hide = true, value_name = "FILE")]
    pub(super) stray: Vec<PathBuf>,
    /// Files with the tracks channel (default: the truth files), paired with the truth files by
    /// file name (or taken as is when both sides are one file).
    #[arg(long, value_name = "TRACKED", num_args = 1..)]
    pub(super) tracks: Vec<PathBuf>,
    /// Ground-truth topic.
    #[arg(long, default_value = "/ground_truth")]
    pub(super) truth_topic: String,
    /// Tracks topic.
    #[arg(long, default_value = "/tracks")]
    pub(super) tracks_topic: String,
    /// Protocol.
    #[arg(long, value_enum, default_value_t = Protocol::Nuscenes)]
    pub(super) protocol: Protocol,
    /// Classes to evaluate, comma separated (default: the seven nuScenes classes; for kitti:
    /// car, pedestrian, cyclist).
    #[arg(long, value_delimiter = ',')]
    pub(super) classes: Vec<String>,
    /// KITTI only: minimum 3D IoU of a match [default: 0.25; 0.5 and 0.7 are also used].
    #[arg(long, value_name = "IOU")]
    pub(super) iou: Option<f64>,
    /// KITTI only: when each track's mean score is computed. every-pass (official): at every
    /// threshold from the previous means, as the reference does on Python 3.11 or older, whose
    /// ulp of drift can drop a track at a threshold equal to its own mean (the report notes it
    /// and what it cost). every-pass-py312: the same with Python 3.12's compensated sum (the
    /// reference run on a current Python; it barely drifts). once: from the track's own
    /// scores. Example: --means once
    #[arg(long, value_enum, value_name = "WHEN")]
    pub(super) means: Option<MeansArg>,
    /// Another tracked version of the same log(s) to compare with (same truth; paired like
    /// --tracks).
    #[arg(long, value_name = "OTHER", num_args = 1..)]
    pub(super) baseline: Vec<PathBuf>,
    /// With --baseline: the regression gate on the overall main metric (AMOTA for nuscenes,
    /// sAMOTA for kitti). With --gate interval (the default) exit 3 when the metric falls by
    /// more than POINTS percentage points AND the upper end of the paired 95 % bootstrap
    /// interval of its change is below 0 (the fall is not noise); the bootstrap runs with
    /// --bootstrap N resamples, 1000 when not given. With --gate point: exit 3 when it falls by
    /// more than POINTS, whatever the noise.
    #[arg(long, value_name = "POINTS")]
    pub(super) max_drop: Option<f64>,
    /// With --max-drop: also fail when any single class falls (by the same rule).
    #[arg(long, requires = "max_drop")]
    pub(super) per_class: bool,
    /// The rule of --max-drop: `interval` (the fall must also lie outside the noise: the whole
    /// 95 % interval of the change below 0) or `point` (the fall alone). Example: --gate point
    #[arg(long, value_enum, default_value_t = Gate::Interval, requires = "max_drop")]
    pub(super) gate: Gate,
    /// Bootstrap with N resamples: each compared metric (nuscenes AMOTA, AMOTP, MOTA, IDS; kitti
    /// sAMOTA, AMOTA, MOTA; and HOTA, DetA, AssA: kitti's of both similarities) per class and
    /// overall with its 95 % interval; with --baseline the change this - baseline with a paired
    /// interval (both runs resampled alike). Resampled are whole logs when there are 20 or more,
    /// else time blocks within them (--block).
    /// Example: --bootstrap 1000
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..))]
    pub(super) bootstrap: Option<u64>,
    /// Seed of the bootstrap's draws: the same seed gives the same intervals, whatever the
    /// number of threads. Example: --seed 7
    #[arg(long, value_name = "S", default_value_t = 0)]
    pub(super) seed: u64,
    /// Resample time blocks of this many seconds within the logs [default: whole logs with 20
    /// logs or more, else 10-second blocks]. Example: --block 20
    #[arg(long, value_name = "SECONDS")]
    pub(super) block: Option<f64>,
    /// nuScenes only: remove boxes of ground truth and tracks farther from the ego vehicle than
    /// their class's range, before the mean track score and the interpolation, as the devkit does.
    /// SPEC: `nuscenes` (the devkit's table: 40 m bicycle, motorcycle, pedestrian; 50 m bus, car,
    /// trailer, truck; the value when SPEC is left out), one number for every class, or
    /// `car=50,pedestrian=40,*=30` (`*`: classes not named; without it they are not filtered).
    /// Needs the ego pose channel (--ego-topic) in the truth file. Off by default.
    #[arg(long, value_name = "SPEC", num_args = 0..=1, default_missing_value = "nuscenes",
          value_parser = RangeFilter::parse)]
    pub(super) max_range: Option<RangeFilter>,
    /// Ego pose channel for --max-range (schema probmot.EgoPose, JSON, as `probmot import
    /// nuscenes` writes it), read from the truth file.
    #[arg(long, default_value = "/ego_pose", value_name = "TOPIC")]
    pub(super) ego_topic: String,
    /// nuScenes only: remove ground-truth boxes with fewer than N lidar + radar points (the
    /// nuscenes_num_lidar_pts / nuscenes_num_radar_pts attributes `probmot import nuscenes`
    /// keeps); the devkit removes boxes with 0 points, i.e. N = 1. Tracks carry no counts and are
    /// kept, as in the devkit. Example: --min-points 1
    #[arg(
        long,
        value_name = "N",
        value_parser = clap::value_parser!(u64).range(1..)
    )]
    pub(super) min_points: Option<u64>,
    /// nuScenes only: remove bicycle and motorcycle boxes (ground truth and tracks) whose centre
    /// lies inside a bicycle rack of the same frame, as the devkit does. The racks are the
    /// --racks-topic channel of the truth file (`probmot import nuscenes` writes it).
    /// Example: --bike-racks
    #[arg(long)]
    pub(super) bike_racks: bool,
    /// Bicycle-rack channel for --bike-racks (probmot.Tracks3D), read from the truth file.
    #[arg(long, default_value = BIKE_RACKS_TOPIC, value_name = "TOPIC")]
    pub(super) racks_topic: String,
    /// nuScenes only: every filter of the devkit's filter_eval_boxes, in its order: the class
    /// ranges (--max-range nuscenes, unless --max-range is given), ground truth without lidar or
    /// radar points (--min-points 1, unless given) and bicycles/motorcycles in bicycle racks
    /// (--bike-racks). With logs written by `probmot import nuscenes --tracks` this reproduces the
    /// official tracking numbers. Example: probmot eval --devkit --truth val/
    #[arg(long)]
    pub(super) devkit: bool,
    /// Print every number as JSON.
    #[arg(long)]
    pub(super) json: bool,
    /// Also write the evaluation's decisions at each class's best-MOTA threshold (matches,
    /// misses, false positives, identity switches, fragmentations) as channels /eval/events
    /// (probmot.EvalEvents) and /eval/events_scene (foxglove.SceneUpdate) of a copy of the truth
    /// log; with several logs OUT is a directory of copies. The report lists the worst moments,
    /// each with the `probmot plot` window (--from/--to) and region (--extent) that frame it.
    /// Example: probmot eval --truth drive.tracked.mcap --events drive.events.mcap
    #[arg(long, value_name = "OUT.mcap")]
    pub(super) events: Option<PathBuf>,
    /// Explain the tables: each column's meaning, unit and which way is better. Alone it prints
    /// the legend of every table; with --truth the report ends with the legend of its tables.
    /// Example: probmot eval --explain
    #[arg(long)]
    pub(super) explain: bool,
    /// No progress bar (it is shown on a terminal only, on stderr). Example: --quiet
    #[arg(long, short)]
    pub(super) quiet: bool,
}

/// The reading bar over the bytes of every file (a file holding both channels is read twice);
/// hidden with --quiet, --json or off a terminal.
pub(super) fn reading_bar(a: &EvalArgs, pairs: &[(PathBuf, PathBuf)]) -> ProgressBar {
    let files: Vec<&Path> = pairs
        .iter()
        .flat_map(|(t, r)| [t.as_path(), r.as_path()])
        .collect();
    bytes_bar(&files, show_progress(a.quiet || a.json))
}

/// A bar over the total size of `files` (hidden unless `show`), for commands that read them.
pub(super) fn bytes_bar(files: &[&Path], show: bool) -> ProgressBar {
    if !show {
        return ProgressBar::hidden();
    }
    let total = files
        .iter()
        .map(|p| std::fs::metadata(p).map_or(0, |m| m.len()))
        .sum();
    ProgressBar::new(total).with_style(
        ProgressStyle::with_template(
            "{spinner} reading {wide_bar} {binary_bytes}/{binary_total_bytes} ETA {eta}",
        )
        .expect("valid template"),
    )
}

/// A spinner while the metrics are computed (same visibility as [`reading_bar`]).
pub(super) fn scoring_spinner(a: &EvalArgs, what: &str) -> ProgressBar {
    super::spinner(
        show_progress(a.quiet || a.json),
        &format!("scoring ({what})"),
    )
}

/// `(truth, tracks)` file pairs, one per log.
pub(super) type LogPairs = Vec<(PathBuf, PathBuf)>;

/// The regression gate: what fell by more than `max_drop` percentage points, as
/// `(baseline, this)` values of the main metric, overall and (with `per_class`) per class. An
/// overall value that has become undefined (no ground truth that counts) also fails.
pub(super) fn gate_failures<'a>(
    metric: &str,
    (old, new): (f64, f64),
    classes: impl Iterator<Item = (&'a str, f64, f64)>,
    max_drop: f64,
    per_class: bool,
) -> Vec<String> {
    let mut failures = Vec::new();
    let d = (old - new) * 100.0;
    if d > max_drop || (d.is_nan() && old.is_finite()) {
        failures.push(format!(
            "overall {metric} fell by {d:.2} points ({old:.4} -> {new:.4}), more than --max-drop {max_drop}"
        ));
    }
    if per_class {
        for (c, old, new) in classes {
            let d = (old - new) * 100.0;
            if d > max_drop {
                failures.push(format!(
                    "{c}: {metric} fell by {d:.2} points ({old:.4} -> {new:.4})"
                ));
            }
        }
    }
    failures
}

/// Refuses files given without an option (`probmot eval drive.tracked.mcap`), with the command
/// that names them.
pub(super) fn refuse_stray(a: &EvalArgs) -> anyhow::Result<()> {
    let Some(first) = a.stray.first() else {
        return Ok(());
    };
    let files: Vec<String> = a.stray.iter().map(|p| p.display().to_string()).collect();
    anyhow::bail!(
        "unexpected argument {}: `probmot eval` takes its files by option: --truth FILE (the \
         ground truth, and the tracks when one file holds both), --tracks FILE (a separate \
         tracked file); e.g. `probmot eval --truth {}`",
        files.join(" "),
        first.display()
    )
}

/// "file" or "N logs" for the report's header.
pub(super) fn describe(pairs: &[(PathBuf, PathBuf)], tracks: bool) -> String {
    match pairs {
        [(t, r)] => if tracks { r } else { t }.display().to_string(),
        _ => format!("{} logs", pairs.len()),
    }
}

/// The report's header: its title, then the tracks and truth files with their topics, one
/// labelled line each.
pub(super) fn header(title: &str, pairs: &[(PathBuf, PathBuf)], a: &EvalArgs) -> String {
    format!(
        "{title}\n  tracks: {} (topic {})\n  truth:  {} (topic {})",
        describe(pairs, true),
        a.tracks_topic,
        describe(pairs, false),
        a.truth_topic
    )
}

/// The end of a text report: with --explain the legend of `tables`, else a line saying where
/// it is.
pub(super) fn footer(a: &EvalArgs, tables: &[Section]) -> String {
    match a.explain {
        true => format!("\n{}", probmot::eval::legend::text(tables)),
        false => "\n`probmot eval --explain` says what each column means, its unit and which way \
                  is better.\n"
            .to_string(),
    }
}

/// The change table (`this - baseline`) with its row `better`: the sign of an improvement per
/// column.
pub(super) fn change_table(
    table: &Section,
    columns: &[&str],
    delta: &[(String, Vec<f64>)],
) -> String {
    let signs = table.signs(columns);
    let t = probmot::eval::report::table_with_row(columns, ("better", &signs), delta);
    format!("\nchange (this - baseline; row `better`: + higher is better, - lower is better):\n{t}")
}

pub(super) fn paths(pairs: &[(PathBuf, PathBuf)]) -> serde_json::Value {
    serde_json::json!(pairs
        .iter()
        .map(|(t, r)| serde_json::json!({"truth": t, "tracks": r}))
        .collect::<Vec<_>>())
}

/// Exit status 3 when the regression gate failed (each failure on stderr), else success.
pub(super) fn gate_exit(failures: &[String]) -> ExitCode {
    for f in failures {
        eprintln!("gate failed: {f}");
    }
    if failures.is_empty() {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(3)
    }
}
