//! `probmot import` and `probmot export`.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, Result};
use clap::{Args, Subcommand};
use probmot::pipeline::kitti_io::{export_kitti, import_kitti, resolve_detection_files};

/// Convert a dataset's files to an MCAP recording.
#[derive(Debug, Args)]
pub struct ImportArgs {
    #[command(subcommand)]
    format: ImportFormat,
}

#[derive(Debug, Subcommand)]
enum ImportFormat {
    Kitti(ImportKitti),
}

/// One KITTI tracking sequence -> MCAP with /detections and /ground_truth at 10 Hz.
///
/// Boxes are converted from KITTI camera coordinates (bottom-centre location, y down,
/// rotation_y) to probmot's right-handed z-up frame with box centres
/// (x = z_cam, y = -x_cam, z = -(y_cam - h/2), yaw = -rotation_y - pi/2). Type, 2D box, alpha,
/// truncation, occlusion and the original track id are kept as attributes, so export loses
/// nothing.
///
/// Example:
///   probmot import kitti --labels label_02/0000.txt --detections pointrcnn/ -o 0000.mcap
#[derive(Debug, Args)]
#[command(verbatim_doc_comment)]
struct ImportKitti {
    /// Ground-truth label file `label_02/SSSS.txt` (optional).
    #[arg(long, value_name = "FILE")]
    labels: Option<PathBuf>,
    /// Detection files (`frame, type, x1, y1, x2, y2, score, h, w, l, x, y, z, rotation_y,
    /// alpha`), or directories holding `SSSS.txt` directly or one level down (e.g. pointrcnn/).
    #[arg(long, num_args = 1.., required = true, value_name = "DIR_OR_FILE")]
    detections: Vec<PathBuf>,
    /// Sequence name (default: the label file's name, e.g. 0000).
    #[arg(long)]
    sequence: Option<String>,
    /// Output MCAP file.
    #[arg(short, long)]
    output: PathBuf,
}

/// Write a tracks (or ground-truth) channel in a dataset's result format.
#[derive(Debug, Args)]
pub struct ExportArgs {
    #[command(subcommand)]
    format: ExportFormat,
}

#[derive(Debug, Subcommand)]
enum ExportFormat {
    Kitti(ExportKitti),
}

/// A Tracks3D channel -> KITTI tracking result file
/// (`frame id type truncated occluded alpha x1 y1 x2 y2 h w l x y z rotation_y score`).
///
/// Type, 2D box and alpha come from each track's last matched detection (as imported);
/// truncation and occlusion are written as 0. Exporting /ground_truth writes the label format
/// (original ids, truncation and occlusion, no score).
///
/// Example:
///   probmot export kitti 0000.tracked.mcap -o results/0000.txt
#[derive(Debug, Args)]
#[command(verbatim_doc_comment)]
struct ExportKitti {
    /// Tracked MCAP file (imported with `probmot import kitti`).
    input: PathBuf,
    /// Topic to export.
    #[arg(long, default_value = "/tracks")]
    topic: String,
    /// Output text file.
    #[arg(short, long)]
    output: PathBuf,
}

pub fn run_import(a: ImportArgs) -> Result<ExitCode> {
    match a.format {
        ImportFormat::Kitti(k) => {
            let sequence = match (&k.sequence, &k.labels) {
                (Some(s), _) => s.clone(),
                (None, Some(l)) => l
                    .file_stem()
                    .map(|s| s.to_string_lossy().into_owned())
                    .context(
                        "cannot tell the sequence from the label file name; give --sequence",
                    )?,
                (None, None) => {
                    anyhow::bail!("give --sequence when no --labels file is given")
                }
            };
            let files = resolve_detection_files(&k.detections, &sequence)?;
            let s = import_kitti(k.labels.as_deref(), &files, &sequence, &k.output)?;
            println!(
                "{}: sequence {sequence}, {} frames, {} detections from {} files, {} ground-truth rows",
                k.output.display(),
                s.frames,
                s.detections,
                s.detection_files.len(),
                s.truth_rows
            );
        }
    }
    Ok(ExitCode::SUCCESS)
}

pub fn run_export(a: ExportArgs) -> Result<ExitCode> {
    match a.format {
        ExportFormat::Kitti(k) => {
            let s = export_kitti(&k.input, &k.topic, &k.output, k.topic == "/tracks")?;
            println!(
                "{}: {} rows in {} frames",
                k.output.display(),
                s.rows,
                s.frames
            );
        }
    }
    Ok(ExitCode::SUCCESS)
}
