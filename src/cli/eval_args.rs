//! The arguments of `probmot eval`, as the library's [`EvalOptions`].

use std::path::PathBuf;

use clap::Args;

use super::choice::choice;
use probmot::eval::job::{EvalOptions, Gate, Protocol};
use probmot::eval::kitti::MeanScores;
use probmot::eval::legend::SECTIONS;
use probmot::eval::range::RangeFilter;
use probmot::formats::nuscenes::BIKE_RACKS_TOPIC;

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
///   probmot eval --truth city.tracked.mcap                   # from the first `track` example
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
    #[arg(long, default_value = "/ground_truth", value_name = "TOPIC")]
    pub(super) truth_topic: String,
    /// Tracks topic.
    #[arg(long, default_value = "/tracks", value_name = "TOPIC")]
    pub(super) tracks_topic: String,
    /// Protocol.
    #[arg(long, value_parser = choice::<Protocol>(), default_value = "nuscenes")]
    pub(super) protocol: Protocol,
    /// Classes to evaluate, comma separated (default: the seven nuScenes classes; for kitti:
    /// car, pedestrian, cyclist).
    #[arg(long, value_delimiter = ',', visible_alias = "class")]
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
    #[arg(long, value_parser = choice::<MeanScores>(), value_name = "WHEN")]
    pub(super) means: Option<MeanScores>,
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
    #[arg(long, value_parser = choice::<Gate>(), default_value = "interval", requires = "max_drop")]
    pub(super) gate: Gate,
    /// Bootstrap with N resamples: each compared metric (nuscenes AMOTA, AMOTP, MOTA, IDS; kitti
    /// sAMOTA, AMOTA, MOTA; and HOTA, DetA, AssA: kitti's of both similarities) per class and
    /// overall with its 95 % interval; with --baseline the change this - baseline with a paired
    /// interval (both runs resampled alike). Resampled are whole logs when there are 20 or more,
    /// else time blocks within them (--block).
    /// Example: --bootstrap 1000
    #[arg(long, value_name = "N", value_parser = super::count::count_in(1, u64::MAX))]
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
        value_parser = super::count::count_in(1, u64::MAX)
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

impl EvalArgs {
    /// The library's options.
    pub(super) fn options(&self) -> EvalOptions {
        EvalOptions {
            truth: self.truth.clone(),
            tracks: self.tracks.clone(),
            truth_topic: self.truth_topic.clone(),
            tracks_topic: self.tracks_topic.clone(),
            protocol: self.protocol,
            classes: self.classes.clone(),
            iou: self.iou,
            means: self.means,
            baseline: self.baseline.clone(),
            max_drop: self.max_drop,
            per_class: self.per_class,
            gate: self.gate,
            bootstrap: self.bootstrap.map(|n| n as usize),
            seed: self.seed,
            block: self.block,
            max_range: self.max_range.clone(),
            ego_topic: self.ego_topic.clone(),
            min_points: self.min_points,
            bike_racks: self.bike_racks,
            racks_topic: self.racks_topic.clone(),
            devkit: self.devkit,
            json: self.json,
            events: self.events.clone(),
            explain: self.explain,
        }
    }
}
