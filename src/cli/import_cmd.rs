//! `probmot import` and `probmot export`.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use clap::{Args, Subcommand};
use probmot::formats::nuscenes::{
    export_nuscenes, import_nuscenes, ExportOptions, ImportOptions, SubmissionMeta,
};
use probmot::pipeline::kitti_files::{
    export_kitti_file, import_kitti_sequence, KittiImportOptions,
};
use probmot::pipeline::kitti_io::TracksInput;

/// Convert a dataset's files to an MCAP recording.
///
/// Examples:
///   probmot import kitti --labels label_02/0000.txt --detections pointrcnn/ -o 0000.mcap
///   probmot import nuscenes --detections results.json --meta v1.0-trainval/ -o scenes/
#[derive(Debug, Args)]
#[command(verbatim_doc_comment)]
pub struct ImportArgs {
    #[command(subcommand)]
    format: ImportFormat,
    /// No summary line (warnings still go to stderr), e.g. in a loop over sequences.
    #[arg(short, long, global = true)]
    quiet: bool,
}

#[derive(Debug, Subcommand)]
enum ImportFormat {
    Kitti(ImportKitti),
    Nuscenes(ImportNuscenes),
}

/// One KITTI tracking sequence -> MCAP with /detections and /ground_truth at 10 Hz.
///
/// Each channel is written when its input is given: --detections for /detections, --labels
/// for /ground_truth, --tracks for a tracks channel; at least one of them is needed.
///
/// Boxes are converted from KITTI camera coordinates (bottom-centre location, y down,
/// rotation_y) to probmot's right-handed z-up frame with box centres
/// (x = z_cam, y = -x_cam, z = -(y_cam - h/2), yaw = -rotation_y - pi/2). Type, 2D box, alpha,
/// truncation, occlusion and the original track id are kept as attributes, so export loses
/// nothing.
///
/// With --tracks, another tracker's KITTI tracking result file (e.g. AB3DMOT's) becomes a
/// probmot.Tracks3D channel (--tracks-topic, default /tracks) of the same log, so that
/// `probmot eval` scores it on the same truth, or compares it with probmot's tracks
/// (--baseline). Its ids are kept (export kitti writes them back unchanged).
///
/// Examples:
///   probmot import kitti --labels label_02/0000.txt --detections pointrcnn/ -o 0000.mcap
///   probmot import kitti --labels label_02/0000.txt --tracks ab3dmot/0000.txt -o ab_0000.mcap
///   probmot eval --protocol kitti --truth ab_0000.mcap
///   probmot eval --protocol kitti --truth 0000.tracked.mcap --baseline ab_0000.mcap
#[derive(Debug, Args)]
#[command(verbatim_doc_comment)]
#[command(group(
    clap::ArgGroup::new("inputs")
        .args(["labels", "detections", "tracks"])
        .required(true)
        .multiple(true)
))]
struct ImportKitti {
    /// Ground-truth label file `label_02/SSSS.txt`; its name is the sequence's.
    #[arg(long, value_name = "FILE")]
    labels: Option<PathBuf>,
    /// Detection files (`frame, type, x1, y1, x2, y2, score, h, w, l, x, y, z, rotation_y,
    /// alpha`), or directories holding `SSSS.txt` directly or one level down (e.g. pointrcnn/).
    /// Without them (--labels or --tracks only) the log has no /detections channel.
    #[arg(long, num_args = 1.., value_name = "DIR_OR_FILE")]
    detections: Vec<PathBuf>,
    /// Another tracker's result file for this sequence (`frame id type 0 0 alpha x1 y1 x2 y2 h w
    /// l x y z rotation_y score`), written as a tracks channel.
    #[arg(long, value_name = "RESULTS.txt")]
    tracks: Option<PathBuf>,
    /// Topic of the tracks channel written from --tracks.
    #[arg(
        long,
        default_value = "/tracks",
        value_name = "TOPIC",
        requires = "tracks"
    )]
    tracks_topic: String,
    /// Sequence name (default: the label file's name, e.g. 0000).
    #[arg(long)]
    sequence: Option<String>,
    /// Output MCAP file.
    #[arg(short, long)]
    output: PathBuf,
}

/// Write a tracks (or ground-truth) channel in a dataset's result format.
///
/// Examples:
///   probmot export kitti 0000.tracked.mcap -o 0000.txt
///   probmot export nuscenes scenes_tracked/*.mcap -o tracking_results.json
#[derive(Debug, Args)]
#[command(verbatim_doc_comment)]
pub struct ExportArgs {
    #[command(subcommand)]
    format: ExportFormat,
    /// No summary line (warnings still go to stderr).
    #[arg(short, long, global = true)]
    quiet: bool,
}

#[derive(Debug, Subcommand)]
enum ExportFormat {
    Kitti(ExportKitti),
    Nuscenes(ExportNuscenes),
}

/// A Tracks3D channel -> KITTI tracking result file
/// (`frame id type truncated occluded alpha x1 y1 x2 y2 h w l x y z rotation_y score`).
///
/// Type, 2D box and alpha come from each track's last matched detection (as imported);
/// truncation and occlusion are written as 0. Exporting /ground_truth writes the label format
/// (original ids, truncation and occlusion, no score).
///
/// Example:
///   probmot export kitti 0000.tracked.mcap -o 0000.txt
#[derive(Debug, Args)]
#[command(verbatim_doc_comment)]
struct ExportKitti {
    /// Tracked MCAP file (imported with `probmot import kitti`).
    input: PathBuf,
    /// Topic to export (a tracks or ground-truth channel), e.g. /ground_truth.
    #[arg(
        long,
        default_value = "/tracks",
        value_name = "TOPIC",
        visible_alias = "tracks-topic"
    )]
    topic: String,
    /// Output text file.
    #[arg(short, long)]
    output: PathBuf,
}

/// A nuScenes detection results file and/or tracking submission -> one MCAP per scene, with
/// /detections and/or /tracks, /ground_truth, /bicycle_racks and
/// /ego_pose at the dataset's samples (about 2 Hz).
///
/// Scenes written: those with at least one sample token in the results (or the --scene names),
/// as OUT_DIR/<scene name>.mcap. Frames are the scene's samples in time order (from
/// scene.first_sample_token along sample.next); stamp = sample timestamp (us) * 1000 ns; every
/// sample gets a message on each channel, empty where nothing was seen.
///
/// Boxes stay in the global frame (frame_id nuscenes_global), centre = translation; size [w, l, h]
/// becomes length l, width w, height h; the quaternion becomes the yaw of the box's x axis about
/// +z. Detections keep their label (detection_name), score, velocity and the attributes
/// nuscenes_sample_token and nuscenes_attribute_name.
///
/// Tables read from --meta DIR: sample.json and scene.json (required);
/// sample_annotation.json + instance.json + category.json for /ground_truth (probmot.Tracks3D;
/// id = position of the instance in instance.json + 1, label = the devkit's tracking class of
/// the category; categories outside the seven classes are skipped and counted; velocity from
/// the neighbouring annotations like the devkit); sample_data.json + ego_pose.json (with
/// calibrated_sensor.json + sensor.json, else the file names) for /ego_pose: JSON messages
/// (schema probmot.EgoPose) {"stamp": ns, "translation": [x, y, z], "rotation": [w, x, y, z]}
/// holding the ego pose of each sample's LIDAR_TOP key frame, which the devkit's range filter
/// uses. Metadata records: probmot.nuscenes (scene token and name) and
/// probmot.nuscenes.samples (frame stamp in ns -> sample token), which `export nuscenes` reads.
///
/// With --tracks, a tracking submission (the format `probmot export nuscenes` writes) becomes
/// the /tracks channel of each scene (probmot.Tracks3D; label = tracking_name, score =
/// tracking_score, id = 1, 2, ... per scene in order of appearance, the original tracking_id
/// kept as the attribute nuscenes_tracking_id), ready for `probmot eval`. With ground truth, the
/// scene's bicycle racks (category static_object.bicycle_rack) go to /bicycle_racks
/// (probmot.Tracks3D, label bicycle_rack, the full quaternion as the attribute
/// nuscenes_rotation) for `probmot eval --bike-racks` / `--devkit`.
///
/// Examples:
///   probmot import nuscenes --detections results_val.json --meta v1.0-trainval/ -o val/
///   probmot import nuscenes --tracks tracking_val.json --meta v1.0-trainval/ -o val/
///   probmot eval --devkit --truth val/
#[derive(Debug, Args)]
#[command(verbatim_doc_comment)]
struct ImportNuscenes {
    /// Detection results JSON (nuScenes detection submission format), written to /detections.
    #[arg(long, value_name = "FILE", required_unless_present = "tracks")]
    detections: Option<PathBuf>,
    /// Tracking submission JSON (nuScenes tracking result format), written to /tracks.
    #[arg(long, value_name = "FILE")]
    tracks: Option<PathBuf>,
    /// Directory holding the dataset's tables (sample.json, scene.json, ...).
    #[arg(long, value_name = "DIR")]
    meta: PathBuf,
    /// Output directory (created if missing).
    #[arg(short, long, value_name = "OUT_DIR")]
    output: PathBuf,
    /// Import only these scenes (by name, e.g. scene-0103; repeatable).
    #[arg(long, value_name = "NAME")]
    scene: Vec<String>,
}

/// Tracks3D channels -> one nuScenes tracking submission JSON.
///
/// Give one tracked MCAP per scene, as written by `probmot import nuscenes` (and
/// `probmot track`). The submission holds every sample token of the input scenes only (empty
/// lists where no box); scenes of the split without an input file are not added, so give every
/// scene of the split. At most 500 boxes per sample (the highest tracking scores are kept; drops
/// are counted). Box: translation = centre, size [w, l, h], rotation = quaternion of the yaw,
/// velocity [vx, vy], tracking_id = the track id as a string, tracking_name = the label (boxes
/// whose label is not one of bicycle, bus, car, motorcycle, pedestrian, trailer, truck are
/// skipped and counted), tracking_score = the score (NaN or infinite values are refused).
///
/// Example:
///   probmot export nuscenes tracked/*.mcap -o tracking_results.json
#[derive(Debug, Args)]
#[command(verbatim_doc_comment)]
struct ExportNuscenes {
    /// Tracked MCAP files, one per scene.
    #[arg(required = true)]
    inputs: Vec<PathBuf>,
    /// Topic to export (probmot.Tracks3D), e.g. /ground_truth.
    #[arg(
        long,
        default_value = "/tracks",
        value_name = "TOPIC",
        visible_alias = "tracks-topic"
    )]
    topic: String,
    /// Output JSON file.
    #[arg(short, long)]
    output: PathBuf,
    /// Table directory (sample.json, scene.json): check each input's samples against its scene.
    #[arg(long, value_name = "DIR")]
    meta: Option<PathBuf>,
    /// meta.use_camera = true.
    #[arg(long)]
    use_camera: bool,
    /// meta.use_radar = true.
    #[arg(long)]
    use_radar: bool,
    /// meta.use_map = true.
    #[arg(long)]
    use_map: bool,
    /// meta.use_external = true.
    #[arg(long)]
    use_external: bool,
    /// meta.use_lidar = false (default true).
    #[arg(long)]
    no_lidar: bool,
}

/// Prints the summary lines unless `quiet`; warnings always, on stderr.
fn report(quiet: bool, warnings: &[String], lines: &[String]) {
    for w in warnings {
        eprintln!("warning: {w}");
    }
    if !quiet {
        for l in lines {
            println!("{l}");
        }
    }
}

pub fn run_import(a: ImportArgs) -> Result<ExitCode> {
    match a.format {
        ImportFormat::Kitti(k) => {
            let tracks = k.tracks.clone().map(|file| TracksInput {
                file,
                topic: k.tracks_topic.clone(),
            });
            let o = KittiImportOptions {
                labels: k.labels.clone(),
                detections: k.detections.clone(),
                tracks: tracks.clone(),
                sequence: k.sequence.clone(),
            };
            let (sequence, s) = import_kitti_sequence(&o, &k.output)?;
            let topic = tracks.as_ref().map(|t| t.topic.as_str());
            report(a.quiet, &[], &[s.line(&k.output, &sequence, topic)]);
        }
        ImportFormat::Nuscenes(n) => {
            let s = import_nuscenes(&ImportOptions {
                detections: n.detections.clone(),
                tracks: n.tracks.clone(),
                meta: n.meta.clone(),
                out_dir: n.output.clone(),
                scenes: n.scene.clone(),
            })?;
            report(a.quiet, &s.warnings, &s.lines(&n.output));
        }
    }
    Ok(ExitCode::SUCCESS)
}

pub fn run_export(a: ExportArgs) -> Result<ExitCode> {
    match a.format {
        ExportFormat::Kitti(k) => {
            let bar = super::bar(super::show_progress(a.quiet), super::style(super::READING));
            let s = export_kitti_file(&k.input, &k.topic, &k.output, &|e| {
                super::show_on_bar(&bar, e)
            });
            bar.finish_and_clear();
            let s = s?;
            report(a.quiet, &s.warnings, &[s.line(&k.output)]);
        }
        ExportFormat::Nuscenes(n) => {
            let opts = ExportOptions {
                topic: n.topic.clone(),
                meta_dir: n.meta.clone(),
                meta: SubmissionMeta {
                    use_camera: n.use_camera,
                    use_lidar: !n.no_lidar,
                    use_radar: n.use_radar,
                    use_map: n.use_map,
                    use_external: n.use_external,
                },
            };
            let s = export_nuscenes(&n.inputs, &n.output, &opts)?;
            report(a.quiet, &s.warnings, &[s.line(&n.output)]);
        }
    }
    Ok(ExitCode::SUCCESS)
}
