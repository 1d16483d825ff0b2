//! `probmot track`.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{bail, Result};
use clap::Args;
use probmot::mcapio::writer::OutputCompression;
use probmot::pipeline::bag_track::track_path;
use probmot::pipeline::ego::EgoOptions;
use probmot::pipeline::many::{check_track_outputs, track_many, ManyReport};
use probmot::pipeline::track::{SceneOutput, TrackOptions, DEFAULT_MAX_DETECTIONS};
use probmot::pipeline::tracks_format::TracksFormat;
use probmot::viz::rrd_file::check_track_rerun;

use super::choice::choice;
use super::config_cmd::TrackerArgs;
use super::show_progress;
use super::viz_cmd::NEEDS_FEATURE;

/// Track the detections of MCAP recordings and write each back with a tracks channel added.
///
/// Every input record (schemas, channels, messages with their times and sequence numbers,
/// attachments, metadata) is copied unchanged; the tracks are written one message per frame,
/// as `probmot.Tracks3D` (and as foxglove.SceneUpdate on /tracks/scene, see --scene-topic) or,
/// for ROS 2 inputs, `vision_msgs/msg/Detection3DArray`, for Autoware inputs
/// `autoware_perception_msgs/msg/TrackedObjects` (see --tracks-format). A tracks message
/// has the frame's stamp in the message and, as log_time, the latest log_time of the frame's
/// detection messages; it is written before any later input message, so the output is in
/// log-time order when the input is. Frames are the distinct detection stamps, replayed in
/// stamp order. The output is written to a partial file beside it (.NAME.probmot-partial) and
/// renamed at the end; the input is never modified. --out-dir is created when missing. Ctrl-C,
/// SIGTERM or SIGHUP remove the partial files (exit 130/143/129).
///
/// Detection inputs, chosen by each channel's schema and encodings (no flag needed):
///   probmot.Detections3D               protobuf or json
///   vision_msgs/msg/Detection3DArray   ROS 2: ros2msg schema + cdr, vision_msgs 4.x or 2.x
///                                      layout (read from the schema text); label and score
///                                      of the best-scoring hypothesis, yaw from the bbox
///                                      orientation, stamp from header.stamp
///   foxglove.SceneUpdate               protobuf; one box per cube; label from the entity
///                                      metadata key `label` (else `class`, else `class_id`,
///                                      else empty: the config's default entry), score from
///                                      `score` (else 1); other metadata become attributes
///   autoware_perception_msgs/msg/DetectedObjects (also autoware_auto_perception_msgs)
///                                      Autoware: ros2msg or ros2idl schema + cdr; label of
///                                      the most probable class (CAR..PEDESTRIAN = car..
///                                      pedestrian; UNKNOWN, ANIMAL, ... only with a config
///                                      entry of that name), score = existence_probability,
///                                      box from pose and shape, velocity from the twist
///
/// Examples:
///   probmot track sample_logs/city.mcap -o city.tracked.mcap
///   probmot track ros2_bag.mcap -o tracked.mcap   (ROS 2 tracks: see --tracks-format)
///   probmot track my_bag/ -o my_bag_tracked/     (rosbag2 directory in and out; a split
///                                                 bag is one drive; .mcap or .db3 files)
///   probmot track autoware_bag/ -o tracked_bag/  (Autoware: TrackedObjects on
///                                                 /perception/object_recognition/tracking/objects)
///   probmot track drive.mcap -o out.mcap --preset ab3dmot-kitti
///   probmot track drive.mcap -o out.mcap --distance iou3d --matcher hungarian
///   probmot track logs/*.mcap --out-dir tracked/ --jobs 2
///   probmot track drive.mcap -o out.mcap --fixed-frame map --tracks-frame ego
#[derive(Debug, Args)]
#[command(verbatim_doc_comment)]
pub struct TrackArgs {
    /// Input MCAP file(s), or one rosbag2 bag directory (metadata.yaml + its .mcap or sqlite3
    /// .db3 files, split or compressed: tracked as one drive; the output -o is then a new MCAP
    /// bag directory split the same way, with its own metadata.yaml). A lone .db3 file is read
    /// too (its output is MCAP).
    #[arg(required = true)]
    inputs: Vec<PathBuf>,
    /// Output file (one input); a new bag directory when the input is a bag directory.
    #[arg(short, long, conflicts_with = "out_dir")]
    output: Option<PathBuf>,
    /// Output directory, created when missing (any number of inputs; each output keeps its
    /// input's file name).
    #[arg(long, value_name = "DIR")]
    out_dir: Option<PathBuf>,
    /// Threads to use, 1 to 1024 (default: all cores). With --out-dir, files run in parallel
    /// on N threads; a file whose share is two or more threads (one file on a multi-core
    /// machine) writes and compresses its output on a second thread, overlapping with tracking.
    #[arg(long, value_name = "N", value_parser = super::count::count_in(1, super::count::MAX_JOBS))]
    jobs: Option<u64>,
    /// Detection topic(s); default: every channel of a supported detection schema
    /// (probmot.Detections3D, vision_msgs/msg/Detection3DArray, foxglove.SceneUpdate,
    /// autoware_perception_msgs/msg/DetectedObjects).
    #[arg(long = "detections-topic", value_name = "TOPIC")]
    detections_topics: Vec<String>,
    /// Topic of the tracks channel to write [default: /tracks; Autoware tracks:
    /// /perception/object_recognition/tracking/objects].
    #[arg(long, value_name = "TOPIC")]
    tracks_topic: Option<String>,
    /// Message type of the tracks channel: `probmot` (probmot.Tracks3D, protobuf: velocities,
    /// variances, ages), `ros2` (vision_msgs/msg/Detection3DArray, CDR: track id in
    /// Detection3D.id, label and score in the hypothesis, box in bbox; readable by ROS 2 tools)
    /// or `autoware` (autoware_perception_msgs/msg/TrackedObjects, CDR: a UUID per track,
    /// class, pose and twist with covariances, shape). Default: autoware when the detections
    /// are Autoware's DetectedObjects, ros2 when the input is a ROS 2 bag (MCAP profile `ros2`)
    /// or its detections are ROS 2 messages, else probmot. With ros2 or autoware, --scene-topic
    /// and --tracks-frame ego are refused. See docs/ros2.md.
    /// Example: probmot track bag.mcap -o out.mcap --tracks-format probmot
    #[arg(long, value_parser = choice::<TracksFormat>(), value_name = "FORMAT")]
    tracks_format: Option<TracksFormat>,
    #[command(flatten)]
    tracker: TrackerArgs,
    /// Copy the log without tracking (measures the cost of plain I/O).
    #[arg(long)]
    no_track: bool,
    /// Fail on any detection box that would otherwise be skipped with a warning, and on a file
    /// cut short (whose unfinished last chunk would be left out with a warning).
    #[arg(long)]
    strict: bool,
    /// Largest number of boxes accepted in one detection message (more is an error).
    #[arg(
        long,
        value_name = "N",
        default_value_t = DEFAULT_MAX_DETECTIONS
    )]
    max_detections: usize,
    /// Chunk compression of the output: zstd (level 2, the smallest files), lz4 (faster to
    /// write and to read, larger files) or none.
    #[arg(long, value_name = "ALGO", default_value = "zstd", value_parser = OutputCompression::parse)]
    compression: OutputCompression,
    /// Frame to track in when detections are in a moving frame (e.g. base_link); default: the
    /// root of the transform tree read from /tf, /tf_static (tf2_msgs/msg/TFMessage),
    /// nav_msgs/msg/Odometry or foxglove.FrameTransform(s) channels.
    #[arg(long, value_name = "FRAME")]
    fixed_frame: Option<String>,
    /// Frame(s) of the written tracks: `fixed` (the tracks channel only), or `ego` to also
    /// write them in each frame's detection frame on <tracks-topic>/ego.
    #[arg(long, value_enum, default_value_t = TracksFrame::Fixed)]
    tracks_frame: TracksFrame,
    /// Largest gap, in seconds, between a detection stamp and the nearest transform outside
    /// the transforms' time range (that transform is held; further is a missing transform).
    #[arg(long, value_name = "SECONDS", default_value_t = 0.1)]
    tf_tolerance: f64,
    /// Topic of the foxglove.SceneUpdate channel written beside the tracks (boxes, ids,
    /// velocity arrows for the Foxglove 3D panel). Default: <tracks-topic>/scene (/tracks/scene)
    /// when the tracks are probmot.Tracks3D; none with ROS 2 tracks (a ROS 2 bag keeps CDR
    /// channels only), where giving it is refused. See docs/viewing.md.
    /// Example: probmot track drive.mcap -o out.mcap --scene-topic /viz/tracks
    #[arg(long, value_name = "TOPIC", conflicts_with = "no_scene")]
    scene_topic: Option<String>,
    /// Write no foxglove.SceneUpdate channel (only the tracks channel).
    /// Example: probmot track drive.mcap -o out.mcap --no-scene
    #[arg(long)]
    no_scene: bool,
    /// Also write a Rerun recording of the output (as `probmot viz OUTPUT -o OUT.rrd`; one input
    /// with -o only; needs the `rerun` cargo feature).
    #[arg(long, value_name = "OUT.rrd", conflicts_with = "out_dir")]
    rerun: Option<PathBuf>,
    /// No progress bar and no summary line (errors and warnings still go to stderr).
    #[arg(short, long)]
    quiet: bool,
    /// Print the summary as JSON on stdout.
    #[arg(long)]
    json: bool,
}

/// Frames the tracks are written in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum TracksFrame {
    /// The fixed frame.
    Fixed,
    /// The fixed frame, and the detection (ego) frame on <tracks-topic>/ego.
    Ego,
}

/// The template of the bar of one file.
const FILE_BAR: &str = "{spinner} {msg:<24} [{bar:30}] {binary_bytes}/{binary_total_bytes} {binary_bytes_per_sec} ETA {eta}";

pub fn run(a: TrackArgs) -> Result<ExitCode> {
    let outputs = check_track_outputs(&a.inputs, a.output.as_deref(), a.out_dir.as_deref())?;
    if let Some(rrd) = &a.rerun {
        if !cfg!(feature = "rerun") {
            bail!("--rerun: {NEEDS_FEATURE}");
        }
        check_track_rerun(
            a.inputs.first().map(|p| p.as_path()),
            a.output.as_deref(),
            rrd,
        )?;
    }
    if !(a.tf_tolerance.is_finite() && a.tf_tolerance >= 0.0) {
        bail!("--tf-tolerance must be a number of seconds >= 0");
    }
    let config = a.tracker.resolve()?;
    let jobs = a.jobs.map(super::count::to_usize).unwrap_or_else(|| {
        std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(1)
    });
    let opts = TrackOptions {
        detection_topics: a.detections_topics.clone(),
        tracks_topic: a.tracks_topic.clone(),
        tracks_format: a.tracks_format,
        config,
        no_track: a.no_track,
        strict: a.strict,
        max_detections_per_message: a.max_detections,
        ego: EgoOptions {
            fixed_frame: a.fixed_frame.clone(),
            tolerance_ns: (a.tf_tolerance * 1e9) as u64,
            tracks_in_ego_frame: a.tracks_frame == TracksFrame::Ego,
        },
        scene: match (&a.scene_topic, a.no_scene) {
            (Some(t), _) => SceneOutput::Topic(t.clone()),
            (None, true) => SceneOutput::Off,
            (None, false) => SceneOutput::Default,
        },
        compression: a.compression,
        // A file gets a writer thread of its own when there is a core for it: one file on two
        // or more, not several files that already keep every core busy.
        background_writer: jobs >= 2 * a.inputs.len(),
    };
    let progress = show_progress(a.quiet || a.json);
    match (&a.output, &a.out_dir) {
        (Some(out), None) => {
            let bar = super::bar(progress, super::style(FILE_BAR).progress_chars("=> "));
            // A bag directory in: a bag directory out, with its metadata.yaml.
            let s = track_path(&a.inputs[0], out, &opts, &|e| super::show_on_bar(&bar, e))?;
            bar.finish_and_clear();
            for w in &s.warnings {
                eprintln!("warning: {w}");
            }
            if let Some(rrd) = &a.rerun {
                let tracked = probmot::pipeline::rosbag_dir::resolve_input(out)?;
                write_recording(&a, &tracked, rrd, &s.tracks_topic)?;
            }
            if a.json {
                println!("{}", serde_json::to_string_pretty(&s)?);
            } else if !a.quiet {
                println!("{}", s.line());
            }
            Ok(ExitCode::SUCCESS)
        }
        _ => run_many(&a, &outputs, &opts, jobs, progress),
    }
}

/// The Rerun recording of the finished output (`--rerun`).
#[cfg(feature = "rerun")]
fn write_recording(a: &TrackArgs, tracked: &Path, rrd: &Path, tracks_topic: &str) -> Result<()> {
    use anyhow::Context as _;
    // The recording shows one detections topic: the first --detections-topic, else /detections
    // (`probmot viz --detections-topic T` draws another one).
    let detections = a
        .detections_topics
        .first()
        .map(String::as_str)
        .unwrap_or("/detections");
    let r = super::viz_cmd::track_recording(tracked, rrd, detections, tracks_topic)
        .context("--rerun")?;
    if !a.quiet && !a.json {
        println!("{}", r.line(rrd));
    }
    Ok(())
}

#[cfg(not(feature = "rerun"))]
fn write_recording(_: &TrackArgs, _: &Path, _: &Path, _: &str) -> Result<()> {
    bail!("--rerun: {NEEDS_FEATURE}")
}

fn run_many(
    a: &TrackArgs,
    outputs: &[PathBuf],
    opts: &TrackOptions,
    jobs: usize,
    progress: bool,
) -> Result<ExitCode> {
    let files = super::style("{spinner} [{bar:30}] {pos}/{len} files {msg} ETA {eta}");
    let bar = super::bar(progress, files.progress_chars("=> "));
    bar.set_length(a.inputs.len() as u64);
    let on_done = |failed: usize| {
        bar.inc(1);
        bar.set_message(format!("({failed} failed)"));
    };
    let results = track_many(&a.inputs, outputs, opts, jobs, &on_done)?;
    bar.finish_and_clear();
    let report = ManyReport {
        inputs: &a.inputs,
        results: &results,
    };
    for (input, r) in a.inputs.iter().zip(&results) {
        match r {
            Ok(s) => {
                for w in &s.warnings {
                    eprintln!("warning: {w}");
                }
                if !a.quiet && !a.json {
                    println!("{}", s.line());
                }
            }
            Err(e) => eprintln!("error: {}: {e:#}", input.display()),
        }
    }
    if a.json {
        println!("{}", serde_json::to_string_pretty(&report.json())?);
    } else if !a.quiet {
        println!("{}", report.totals_line());
    }
    Ok(if report.failed() > 0 {
        ExitCode::from(2)
    } else {
        ExitCode::SUCCESS
    })
}
