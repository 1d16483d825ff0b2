//! `probmot eval`.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{bail, Context, Result};
use clap::{Args, ValueEnum};
use indicatif::{ProgressBar, ProgressStyle};
use std::collections::BTreeMap;

use probmot::eval::columns::{load_columns, ColumnScene};
use probmot::eval::filters::{apply_bike_racks, apply_min_points, read_racks, FilterCounts, Rack};
use probmot::eval::hota::centre::{centre_hota, ZERO_DISTANCE};
use probmot::eval::hota::kitti2d::{kitti_hota, KittiSimilarity};
use probmot::eval::hota::{hota_rows, HOTA_COLUMNS};
use probmot::eval::kitti::{self, KittiBox, KittiMetrics, KittiParams, KittiResult, MeanScores};

use super::means_arg::MeansArg;
use probmot::eval::nuscenes::{
    evaluate_columns, evaluate_columns_recording, NuscenesParams, NuscenesResult,
};
use probmot::eval::range::{
    apply_range_filter, read_ego_positions, EgoPositions, RangeFilter, RangeRemoved,
};
use probmot::eval::report::{fmt_value, table};
use probmot::eval::scene::{load_kitti_scene, Scene};
use probmot::formats::nuscenes::BIKE_RACKS_TOPIC;
use probmot::mcapio::LabelledBox;
use probmot::pipeline::log_pairs::log_pairs;
use rayon::prelude::*;

use super::eval_events;
use super::show_progress;
use probmot::eval::events::Protocol as EventsProtocol;

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
///   probmot eval --protocol kitti --truth 0000.tracked.mcap
///   probmot eval --protocol kitti --iou 0.5 --classes car --truth 0000.tracked.mcap
///   probmot eval --protocol kitti --means once --truth new/ --baseline old/ --max-drop 1
///   probmot eval --truth gt/ --tracks tracked/ --json        # many logs, paired by file name
///   probmot eval --devkit --truth val/                        # the official nuScenes number
#[derive(Debug, Args)]
#[command(verbatim_doc_comment)]
pub struct EvalArgs {
    /// Files with the ground-truth channel: files, directories (their *.mcap) or glob patterns.
    /// Several logs are scored together, each log one scene, as the devkit does across scenes.
    #[arg(long, value_name = "GT", num_args = 1.., required = true)]
    truth: Vec<PathBuf>,
    /// Files with the tracks channel (default: the truth files), paired with the truth files by
    /// file name (or taken as is when both sides are one file).
    #[arg(long, value_name = "TRACKED", num_args = 1..)]
    tracks: Vec<PathBuf>,
    /// Ground-truth topic.
    #[arg(long, default_value = "/ground_truth")]
    truth_topic: String,
    /// Tracks topic.
    #[arg(long, default_value = "/tracks")]
    tracks_topic: String,
    /// Protocol.
    #[arg(long, value_enum, default_value_t = Protocol::Nuscenes)]
    protocol: Protocol,
    /// Classes to evaluate, comma separated (default: the seven nuScenes classes; for kitti:
    /// car, pedestrian, cyclist).
    #[arg(long, value_delimiter = ',')]
    classes: Vec<String>,
    /// KITTI only: minimum 3D IoU of a match [default: 0.25; 0.5 and 0.7 are also used].
    #[arg(long, value_name = "IOU")]
    iou: Option<f64>,
    /// KITTI only: when each track's mean score is computed. every-pass (official): at every
    /// threshold from the previous means, as the reference does on Python 3.11 or older, whose
    /// ulp of drift can drop a track at a threshold equal to its own mean (the report notes it
    /// and what it cost). every-pass-py312: the same with Python 3.12's compensated sum (the
    /// reference run on a current Python; it barely drifts). once: from the track's own
    /// scores. Example: --means once
    #[arg(long, value_enum, value_name = "WHEN")]
    means: Option<MeansArg>,
    /// Another tracked version of the same log(s) to compare with (same truth; paired like
    /// --tracks).
    #[arg(long, value_name = "OTHER", num_args = 1..)]
    baseline: Vec<PathBuf>,
    /// With --baseline: exit 3 if the overall main metric (AMOTA for nuscenes, sAMOTA for kitti)
    /// falls by more than this many percentage points.
    #[arg(long, value_name = "POINTS")]
    max_drop: Option<f64>,
    /// With --max-drop: also fail when any single class falls by more than that.
    #[arg(long, requires = "max_drop")]
    per_class: bool,
    /// nuScenes only: remove boxes of ground truth and tracks farther from the ego vehicle than
    /// their class's range, before the mean track score and the interpolation, as the devkit does.
    /// SPEC: `nuscenes` (the devkit's table: 40 m bicycle, motorcycle, pedestrian; 50 m bus, car,
    /// trailer, truck; the value when SPEC is left out), one number for every class, or
    /// `car=50,pedestrian=40,*=30` (`*`: classes not named; without it they are not filtered).
    /// Needs the ego pose channel (--ego-topic) in the truth file. Off by default.
    #[arg(long, value_name = "SPEC", num_args = 0..=1, default_missing_value = "nuscenes",
          value_parser = RangeFilter::parse)]
    max_range: Option<RangeFilter>,
    /// Ego pose channel for --max-range (schema probmot.EgoPose, JSON, as `probmot import
    /// nuscenes` writes it), read from the truth file.
    #[arg(long, default_value = "/ego_pose", value_name = "TOPIC")]
    ego_topic: String,
    /// nuScenes only: remove ground-truth boxes with fewer than N lidar + radar points (the
    /// nuscenes_num_lidar_pts / nuscenes_num_radar_pts attributes `probmot import nuscenes`
    /// keeps); the devkit removes boxes with 0 points, i.e. N = 1. Tracks carry no counts and are
    /// kept, as in the devkit. Example: --min-points 1
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..))]
    min_points: Option<u64>,
    /// nuScenes only: remove bicycle and motorcycle boxes (ground truth and tracks) whose centre
    /// lies inside a bicycle rack of the same frame, as the devkit does. The racks are the
    /// --racks-topic channel of the truth file (`probmot import nuscenes` writes it).
    /// Example: --bike-racks
    #[arg(long)]
    bike_racks: bool,
    /// Bicycle-rack channel for --bike-racks (probmot.Tracks3D), read from the truth file.
    #[arg(long, default_value = BIKE_RACKS_TOPIC, value_name = "TOPIC")]
    racks_topic: String,
    /// nuScenes only: every filter of the devkit's filter_eval_boxes, in its order: the class
    /// ranges (--max-range nuscenes, unless --max-range is given), ground truth without lidar or
    /// radar points (--min-points 1, unless given) and bicycles/motorcycles in bicycle racks
    /// (--bike-racks). With logs written by `probmot import nuscenes --tracks` this reproduces the
    /// official tracking numbers. Example: probmot eval --devkit --truth val/
    #[arg(long)]
    devkit: bool,
    /// Print every number as JSON.
    #[arg(long)]
    json: bool,
    /// Also write the evaluation's decisions at each class's best-MOTA threshold (matches,
    /// misses, false positives, identity switches, fragmentations) as channels /eval/events
    /// (probmot.EvalEvents) and /eval/events_scene (foxglove.SceneUpdate) of a copy of the truth
    /// log; with several logs OUT is a directory of copies. The report lists the worst moments.
    /// Example: probmot eval --truth drive.tracked.mcap --events drive.events.mcap
    #[arg(long, value_name = "OUT.mcap")]
    events: Option<PathBuf>,
    /// No progress bar (it is shown on a terminal only, on stderr). Example: --quiet
    #[arg(long, short)]
    quiet: bool,
}

const COLUMNS: [&str; 14] = [
    "amota", "amotp", "recall", "mota", "motp", "ids", "frag", "fp", "fn", "mt", "ml", "faf",
    "tid", "lgd",
];

fn rows(r: &NuscenesResult) -> Vec<(String, Vec<f64>)> {
    let mut out: Vec<(String, Vec<f64>)> = r
        .classes
        .iter()
        .filter(|(_, m)| !m.gt.is_nan())
        .map(|(c, m)| (c.clone(), COLUMNS.iter().map(|k| m.get(k)).collect()))
        .collect();
    out.push((
        "overall".into(),
        COLUMNS.iter().map(|k| r.overall.get(k)).collect(),
    ));
    out
}

/// The filters that are on for one log, with the ego poses and racks of its truth file.
struct LogFilters<'a> {
    args: &'a EvalArgs,
    truth: &'a Path,
    ego: Option<(&'a RangeFilter, EgoPositions)>,
    racks: Option<BTreeMap<u64, Vec<Rack>>>,
}

impl<'a> LogFilters<'a> {
    fn new(a: &'a EvalArgs, truth: &'a Path) -> Result<LogFilters<'a>> {
        let ego = match &a.max_range {
            Some(filter) => Some((filter, read_ego_positions(truth, &a.ego_topic)?)),
            None => None,
        };
        let racks = if a.bike_racks {
            Some(read_racks(truth, &a.racks_topic).with_context(|| {
                format!(
                    "--bike-racks needs the bicycle racks of each scene on {} (`probmot import \
                     nuscenes` writes them from sample_annotation.json)",
                    a.racks_topic
                )
            })?)
        } else {
            None
        };
        Ok(LogFilters {
            args: a,
            truth,
            ego,
            racks,
        })
    }

    /// Applies the filters to `scene`, in the devkit's order (range, points, racks).
    fn apply(&self, scene: &mut Scene) -> Result<FilterCounts> {
        let mut counts = FilterCounts::default();
        if let Some((filter, ego)) = &self.ego {
            counts.range = Some(apply_range_filter(scene, filter, ego).with_context(|| {
                format!("--max-range with the ego poses of {}", self.truth.display())
            })?);
        }
        if let Some(min) = self.args.min_points {
            counts.points = Some(apply_min_points(scene, min).with_context(|| {
                format!(
                    "--min-points: {} (topic {})",
                    self.truth.display(),
                    self.args.truth_topic
                )
            })?);
        }
        if let Some(racks) = &self.racks {
            counts.bike_racks = Some(apply_bike_racks(scene, racks));
        }
        Ok(counts)
    }

    /// [`LogFilters::apply`] to the boxes of one message (truth or tracks) of `scene_name` at
    /// `stamp`: every filter is a rule per frame, so filtering message by message while the log
    /// streams removes the same boxes.
    fn apply_message(
        &self,
        scene_name: &str,
        (stamp, boxes, truth): (u64, &mut Vec<LabelledBox>, bool),
        counts: &mut FilterCounts,
    ) -> Result<()> {
        if self.ego.is_none() && self.args.min_points.is_none() && self.racks.is_none() {
            return Ok(());
        }
        let mut one = Scene {
            name: scene_name.to_string(),
            frames: vec![(stamp, Vec::new(), Vec::new())],
        };
        let (_, f, t) = &mut one.frames[0];
        std::mem::swap(boxes, if truth { f } else { t });
        let c = self.apply(&mut one);
        let (_, f, t) = &mut one.frames[0];
        std::mem::swap(boxes, if truth { f } else { t });
        counts.add(&c?);
        Ok(())
    }
}

/// Loads every log (in parallel) for the KITTI protocol, each box as the KITTI evaluation
/// reads it ([`load_kitti_scene`]): ground-truth boxes without id (DontCare) are allowed. The
/// protocol has no filters.
fn load_logs(a: &EvalArgs, pairs: &[(PathBuf, PathBuf)]) -> Result<Vec<Scene<KittiBox>>> {
    let bar = reading_bar(a, pairs);
    let scenes = pairs
        .par_iter()
        .map(|(truth, tracks)| {
            let (truth, tracks) = ((&**truth, &*a.truth_topic), (&**tracks, &*a.tracks_topic));
            load_kitti_scene(truth, tracks, &|n| bar.inc(n))
        })
        .collect::<Result<_>>()?;
    bar.finish_and_clear();
    Ok(scenes)
}

/// The scenes, and the filters' counts summed over them.
fn sum_counts<S>(loaded: Vec<(S, FilterCounts)>) -> (Vec<S>, FilterCounts) {
    let mut total = FilterCounts::default();
    let scenes = loaded
        .into_iter()
        .map(|(s, c)| {
            total.add(&c);
            s
        })
        .collect();
    (scenes, total)
}

/// [`load_logs`] for the nuScenes protocol: each log streamed into columns
/// ([`load_columns`]), filtered message by message.
fn load_columns_logs(
    a: &EvalArgs,
    pairs: &[(PathBuf, PathBuf)],
    geometry: bool,
) -> Result<(Vec<ColumnScene>, FilterCounts)> {
    let bar = reading_bar(a, pairs);
    let loaded: Vec<(ColumnScene, FilterCounts)> = pairs
        .par_iter()
        .map(|(truth, tracks)| {
            let filters = LogFilters::new(a, truth)?;
            let name = tracks
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default();
            let mut counts = FilterCounts::default();
            let scene = load_columns(
                (truth, &a.truth_topic),
                (tracks, &a.tracks_topic),
                &|n| bar.inc(n),
                &mut |stamp, boxes, is_truth| {
                    filters.apply_message(&name, (stamp, boxes, is_truth), &mut counts)
                },
                geometry,
            )?;
            Ok((scene, counts))
        })
        .collect::<Result<_>>()?;
    bar.finish_and_clear();
    Ok(sum_counts(loaded))
}

/// The reading bar over the bytes of every file (a file holding both channels is read twice);
/// hidden with --quiet, --json or off a terminal.
fn reading_bar(a: &EvalArgs, pairs: &[(PathBuf, PathBuf)]) -> ProgressBar {
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
fn scoring_spinner(a: &EvalArgs, what: &str) -> ProgressBar {
    super::spinner(
        show_progress(a.quiet || a.json),
        &format!("scoring ({what})"),
    )
}

/// `(truth, tracks)` file pairs, one per log.
type LogPairs = Vec<(PathBuf, PathBuf)>;

/// The `--baseline` logs of the KITTI protocol, paired with the truth like `--tracks`, loaded as
/// [`load_logs`] does; no pairs and `None` without `--baseline`.
fn load_baseline(a: &EvalArgs) -> Result<(LogPairs, Option<Vec<Scene<KittiBox>>>)> {
    if a.baseline.is_empty() {
        return Ok((Vec::new(), None));
    }
    let pairs = log_pairs(&a.truth, &a.baseline)?;
    let scenes = load_logs(a, &pairs)?;
    Ok((pairs, Some(scenes)))
}

/// The regression gate: what fell by more than `max_drop` percentage points, as
/// `(baseline, this)` values of the main metric, overall and (with `per_class`) per class. An
/// overall value that has become undefined (no ground truth that counts) also fails.
fn gate_failures<'a>(
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

/// "file" or "N logs" for the report's header.
fn describe(pairs: &[(PathBuf, PathBuf)], tracks: bool) -> String {
    match pairs {
        [(t, r)] => if tracks { r } else { t }.display().to_string(),
        _ => format!("{} logs", pairs.len()),
    }
}

fn paths(pairs: &[(PathBuf, PathBuf)]) -> serde_json::Value {
    serde_json::json!(pairs
        .iter()
        .map(|(t, r)| serde_json::json!({"truth": t, "tracks": r}))
        .collect::<Vec<_>>())
}

pub fn run(mut a: EvalArgs) -> Result<ExitCode> {
    let nuscenes_filters = a.max_range.is_some() || a.min_points.is_some() || a.bike_racks;
    if a.devkit {
        a.max_range.get_or_insert_with(RangeFilter::nuscenes);
        a.min_points.get_or_insert(1);
        a.bike_racks = true;
    }
    if a.max_drop.is_some() && a.baseline.is_empty() {
        bail!("--max-drop needs --baseline");
    }
    match a.protocol {
        Protocol::Nuscenes => {
            if a.iou.is_some() {
                bail!("--iou is a KITTI option (the nuScenes protocol matches by 2 m centre distance)");
            }
            if a.means.is_some() {
                bail!("--means is a KITTI option (the nuScenes devkit averages each track's score once)");
            }
            run_nuscenes(a)
        }
        Protocol::Kitti => {
            if a.devkit || nuscenes_filters {
                bail!(
                    "--devkit, --max-range, --min-points and --bike-racks are nuScenes options \
                     (the KITTI protocol has no range, points or bicycle-rack filter)"
                );
            }
            run_kitti(a)
        }
    }
}

/// The per-log breakdown when several logs were scored together (empty for one log).
fn per_log_json(
    scenes: &[ColumnScene],
    pairs: &[(PathBuf, PathBuf)],
    params: &NuscenesParams,
) -> Vec<serde_json::Value> {
    if scenes.len() < 2 {
        return Vec::new();
    }
    scenes
        .par_iter()
        .zip(pairs)
        .map(|(s, (t, r))| {
            serde_json::json!({"truth": t, "tracks": r,
                "result": evaluate_columns(std::slice::from_ref(s), params)})
        })
        .collect()
}

/// The `--baseline` logs scored with the nuScenes protocol (none without `--baseline`).
fn nuscenes_baseline(
    a: &EvalArgs,
    params: &NuscenesParams,
) -> Result<(LogPairs, Option<NuscenesResult>)> {
    if a.baseline.is_empty() {
        return Ok((Vec::new(), None));
    }
    let pairs = log_pairs(&a.truth, &a.baseline)?;
    let (scenes, _) = load_columns_logs(a, &pairs, false)?;
    Ok((pairs, Some(evaluate_columns(&scenes, params))))
}

fn run_nuscenes(a: EvalArgs) -> Result<ExitCode> {
    let mut params = NuscenesParams::default();
    if !a.classes.is_empty() {
        params.classes = a.classes.clone();
    }
    let pairs = log_pairs(&a.truth, &a.tracks)?;
    // With --events the columns keep the boxes' geometry too, to place the events.
    let (scenes, removed) = load_columns_logs(&a, &pairs, a.events.is_some())?;
    let spinner = scoring_spinner(&a, "nuScenes metrics and HOTA");
    let ((result, decisions), (hota, hota_notes)) = rayon::join(
        || evaluate_columns_recording(&scenes, &params, a.events.is_some()),
        || centre_hota(&scenes, &params.classes),
    );
    spinner.finish_and_clear();
    if result.classes.values().all(|m| m.gt.is_nan()) {
        bail!(
            "{}: topic {} has no ground-truth box of the evaluated classes ({})",
            describe(&pairs, false),
            a.truth_topic,
            params.classes.join(", ")
        );
    }
    let events = (a.events.as_deref())
        .map(|out| {
            let logs = (EventsProtocol::Nuscenes, &decisions[..]);
            eval_events::write(out, logs, &pairs, &scenes[..], &a.truth_topic)
        })
        .transpose()?;
    let (base_pairs, baseline) = nuscenes_baseline(&a, &params)?;

    // The gate, on AMOTA.
    let failures = match (&baseline, a.max_drop) {
        (Some(base), Some(max_drop)) => gate_failures(
            "AMOTA",
            (base.overall.amota, result.overall.amota),
            result
                .classes
                .iter()
                .filter_map(|(c, m)| base.classes.get(c).map(|o| (c.as_str(), o.amota, m.amota))),
            max_drop,
            a.per_class,
        ),
        _ => Vec::new(),
    };

    if a.json {
        let per_log = per_log_json(&scenes, &pairs, &params);
        let mut v = serde_json::json!({
            "logs": paths(&pairs), "result": result, "per_log": per_log,
            "baseline": baseline.as_ref().map(|b| serde_json::json!({"logs": paths(&base_pairs), "result": b})),
            "gate_failures": failures,
            "hota": {"similarity": "bev_centre_distance", "zero_distance_m": ZERO_DISTANCE,
                     "classes": hota, "notes": hota_notes},
            "range_filter": a.max_range.as_ref().map(|f| {
                let r = removed.range.unwrap_or_default();
                serde_json::json!({
                "ranges": f.per_class, "other": f.other, "ego_topic": a.ego_topic,
                "removed_truth_boxes": r.truth, "removed_track_boxes": r.tracks})
            }),
            "filters": filters_json(&a, &removed),
        });
        if let Some(e) = &events {
            v["events"] = e.json();
        }
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        println!(
            "nuScenes tracking metrics: {} vs {} ({} / {})",
            describe(&pairs, true),
            describe(&pairs, false),
            a.tracks_topic,
            a.truth_topic
        );
        print!("{}", table(&COLUMNS, &rows(&result)));
        println!(
            "\nHOTA (TrackEval's definition; similarity max(0, 1 - BEV centre distance / 2 m)):"
        );
        print!("{}", table(&HOTA_COLUMNS, &hota_rows(&hota, "")));
        if let Some(base) = &baseline {
            println!("\nbaseline {}:", describe(&base_pairs, true));
            print!("{}", table(&COLUMNS, &rows(base)));
            println!("\nchange (this - baseline):");
            let mut delta = Vec::new();
            for ((name, new), (_, old)) in rows(&result).into_iter().zip(rows(base)) {
                delta.push((name, new.iter().zip(&old).map(|(n, o)| n - o).collect()));
            }
            print!("{}", table(&COLUMNS, &delta));
        }
        for line in filter_notes(&removed, a.min_points) {
            println!("note: {line}");
        }
        for n in result.notes.iter().chain(&hota_notes) {
            println!("note: {n}");
        }
        print!("{}", events.as_ref().map(|e| e.text()).unwrap_or_default());
        let _ = fmt_value;
    }
    Ok(gate_exit(&failures))
}

/// The filters that ran, in the devkit's order, with what each removed (JSON).
fn filters_json(a: &EvalArgs, c: &FilterCounts) -> serde_json::Value {
    let counts = |r: &RangeRemoved| serde_json::json!({"removed_truth_boxes": r.truth, "removed_track_boxes": r.tracks});
    serde_json::json!({
        "devkit": a.devkit,
        "range": c.range.as_ref().map(counts),
        "min_points": c.points.as_ref().map(|r| serde_json::json!({
            "min": a.min_points, "removed_truth_boxes": r.truth, "removed_track_boxes": r.tracks})),
        "bike_racks": c.bike_racks.as_ref().map(|r| serde_json::json!({
            "topic": a.racks_topic, "removed_truth_boxes": r.truth,
            "removed_track_boxes": r.tracks})),
    })
}

/// One line per filter that ran, in the devkit's order.
fn filter_notes(c: &FilterCounts, min_points: Option<u64>) -> Vec<String> {
    let mut out = Vec::new();
    if let Some(r) = c.range {
        out.push(format!(
            "range filter removed {} ground-truth and {} track boxes",
            r.truth, r.tracks
        ));
    }
    if let (Some(r), Some(n)) = (c.points, min_points) {
        out.push(format!(
            "points filter (fewer than {n} lidar + radar points) removed {} ground-truth boxes",
            r.truth
        ));
    }
    if let Some(r) = c.bike_racks {
        out.push(format!(
            "bicycle-rack filter removed {} ground-truth and {} track boxes",
            r.truth, r.tracks
        ));
    }
    out
}

/// Table columns of the KITTI report; lower-case names are counts (printed without decimals).
const KITTI_COLUMNS: [&str; 14] = [
    "sAMOTA",
    "AMOTA",
    "AMOTP",
    "MOTA",
    "MOTP",
    "ids",
    "frag",
    "fp",
    "fn",
    "tp",
    "recall",
    "precision",
    "MT",
    "ML",
];

fn kitti_value(m: &KittiMetrics, column: &str) -> f64 {
    match column {
        "ids" | "frag" | "fp" | "fn" | "tp" => m.get(&column.to_uppercase()),
        _ => m.get(column),
    }
}

fn kitti_rows(r: &KittiResult, classes: &[String]) -> Vec<(String, Vec<f64>)> {
    let row = |m: &KittiMetrics| KITTI_COLUMNS.iter().map(|c| kitti_value(m, c)).collect();
    let mut out: Vec<(String, Vec<f64>)> = classes
        .iter()
        .filter_map(|c| r.classes.get(c).map(|m| (c.clone(), row(m))))
        .collect();
    out.push(("overall".into(), row(&r.overall)));
    out
}

/// Exit status 3 when the regression gate failed (each failure on stderr), else success.
fn gate_exit(failures: &[String]) -> ExitCode {
    for f in failures {
        eprintln!("gate failed: {f}");
    }
    if failures.is_empty() {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(3)
    }
}

/// The KITTI protocol's parameters from --classes and --iou.
fn kitti_params(a: &EvalArgs) -> Result<KittiParams> {
    let mut params = KittiParams::default();
    if !a.classes.is_empty() {
        params.classes = a.classes.iter().map(|c| c.to_lowercase()).collect();
    }
    if let Some(iou) = a.iou {
        if !(iou > 0.0 && iou <= 1.0) {
            bail!("--iou {iou}: the minimum 3D IoU must lie in (0, 1]");
        }
        params.min_overlap = iou;
    }
    params.means = a.means.map_or(MeanScores::EveryPass, MeansArg::means);
    Ok(params)
}

fn run_kitti(a: EvalArgs) -> Result<ExitCode> {
    let params = kitti_params(&a)?;
    let pairs = log_pairs(&a.truth, &a.tracks)?;
    let scenes = load_logs(&a, &pairs)?;
    let spinner = scoring_spinner(&a, "KITTI metrics");
    let (result, decisions) = kitti::evaluate_recording(&scenes, &params, a.events.is_some());
    spinner.finish_and_clear();
    let (hota_2d, mut hota_notes) = kitti_hota(&scenes, &params.classes, KittiSimilarity::Image);
    let (hota_3d, _) = kitti_hota(&scenes, &params.classes, KittiSimilarity::Box3d);
    hota_notes.dedup();
    if result.classes.is_empty() {
        bail!(
            "{}: topic {} has no track box of the evaluated classes ({}); nothing to evaluate",
            describe(&pairs, true),
            a.tracks_topic,
            params.classes.join(", ")
        );
    }
    let events = (a.events.as_deref())
        .map(|out| {
            let logs = (EventsProtocol::Kitti, &decisions[..]);
            eval_events::write(out, logs, &pairs, &scenes[..], &a.truth_topic)
        })
        .transpose()?;
    let (base_pairs, base_scenes) = load_baseline(&a)?;
    let baseline = base_scenes.map(|scenes| kitti::evaluate(&scenes, &params));

    // The gate, on sAMOTA.
    let failures = match (&baseline, a.max_drop) {
        (Some(base), Some(max_drop)) => gate_failures(
            "sAMOTA",
            (base.overall.samota, result.overall.samota),
            result.classes.iter().filter_map(|(c, m)| {
                base.classes
                    .get(c)
                    .map(|o| (c.as_str(), o.samota, m.samota))
            }),
            max_drop,
            a.per_class,
        ),
        _ => Vec::new(),
    };

    if a.json {
        let mut v = serde_json::json!({
            "logs": paths(&pairs), "result": result,
            "baseline": baseline.as_ref().map(|b| serde_json::json!({"logs": paths(&base_pairs), "result": b})),
            "gate_failures": failures,
            "hota": {"image_2d": hota_2d, "iou_3d": hota_3d, "notes": hota_notes},
        });
        if let Some(e) = &events {
            v["events"] = e.json();
        }
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        println!(
            "KITTI 3D MOT metrics (AB3DMOT evaluation{}, 3D IoU >= {}): {} vs {} ({} / {})",
            match params.means {
                MeanScores::EveryPass => "",
                MeanScores::EveryPassCompensated =>
                    " as run on Python 3.12+, not the published numbers",
                MeanScores::Once => " with each track's mean computed once, not official",
            },
            params.min_overlap,
            describe(&pairs, true),
            describe(&pairs, false),
            a.tracks_topic,
            a.truth_topic
        );
        print!(
            "{}",
            table(&KITTI_COLUMNS, &kitti_rows(&result, &params.classes))
        );
        println!(
            "\nHOTA (TrackEval's Kitti2DBox: 2D image-box IoU; 3d: the same boxes by 3D IoU):"
        );
        let mut h = hota_rows(&hota_2d, "");
        h.extend(hota_rows(&hota_3d, " 3d"));
        print!("{}", table(&HOTA_COLUMNS, &h));
        if let Some(base) = &baseline {
            println!("\nbaseline {}:", describe(&base_pairs, true));
            print!(
                "{}",
                table(&KITTI_COLUMNS, &kitti_rows(base, &params.classes))
            );
            println!("\nchange (this - baseline):");
            let mut delta = Vec::new();
            for (name, new) in kitti_rows(&result, &params.classes) {
                if let Some((_, old)) = kitti_rows(base, &params.classes)
                    .into_iter()
                    .find(|(n, _)| *n == name)
                {
                    delta.push((name, new.iter().zip(&old).map(|(n, o)| n - o).collect()));
                }
            }
            print!("{}", table(&KITTI_COLUMNS, &delta));
        }
        for n in result.notes.iter().chain(&hota_notes) {
            println!("note: {n}");
        }
        print!("{}", events.as_ref().map(|e| e.text()).unwrap_or_default());
    }
    Ok(gate_exit(&failures))
}
