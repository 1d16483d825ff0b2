//! `import kitti` and `export kitti` over the command's inputs: the sequence named, the
//! detection files found, the progress of the two passes of an export.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};

use super::kitti_io::{
    export_kitti, import_kitti, resolve_detection_files, ExportSummary, ImportSummary, TracksInput,
};
use super::progress::{Progress, ProgressFn};
use super::rosbag_dir::resolve_input;

/// The inputs of one KITTI sequence's import ([`import_kitti_sequence`]); at least one of
/// `labels`, `detections` and `tracks`.
#[derive(Debug, Clone, Default)]
pub struct KittiImportOptions {
    /// Ground-truth label file `label_02/SSSS.txt`; its name is the sequence's.
    pub labels: Option<PathBuf>,
    /// Detection files, or directories holding `SSSS.txt` directly or one level down (see
    /// [`resolve_detection_files`]).
    pub detections: Vec<PathBuf>,
    /// Another tracker's result file for this sequence, written as a tracks channel.
    pub tracks: Option<TracksInput>,
    /// Sequence name; `None`: the label file's name.
    pub sequence: Option<String>,
}

/// Writes one KITTI sequence as MCAP to `output` (see [`import_kitti`]); the sequence's name and
/// the counts.
pub fn import_kitti_sequence(
    o: &KittiImportOptions,
    output: &Path,
) -> Result<(String, ImportSummary)> {
    let (sequence, files) = kitti_inputs(o)?;
    let s = import_kitti(
        o.labels.as_deref(),
        &files,
        o.tracks.as_ref(),
        &sequence,
        output,
    )?;
    Ok((sequence, s))
}

/// The sequence name (given, else the label file's name) and the detection files.
fn kitti_inputs(o: &KittiImportOptions) -> Result<(String, Vec<PathBuf>)> {
    let sequence = match (&o.sequence, &o.labels) {
        (Some(s), _) => s.clone(),
        (None, Some(l)) => l
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .context("cannot tell the sequence from the label file name; give --sequence")?,
        (None, None) => anyhow::bail!("give --sequence when no --labels file is given"),
    };
    if o.detections.is_empty() {
        return Ok((sequence, Vec::new()));
    }
    let files = resolve_detection_files(&o.detections, &sequence, o.labels.as_deref());
    let files = match (&o.sequence, &o.labels) {
        (None, Some(l)) => files.with_context(|| {
            format!(
                "sequence {sequence}, named after the label file {} (--sequence sets it)",
                l.display()
            )
        })?,
        _ => files?,
    };
    Ok((sequence, files))
}

/// Writes the `topic` of the tracked file `input` (a rosbag directory resolved) as a KITTI
/// tracking result file, or as a label file for `/ground_truth` (no scores). Progress: bytes
/// read over both passes, out of twice the file's size.
pub fn export_kitti_file(
    input: &Path,
    topic: &str,
    output: &Path,
    progress: ProgressFn<'_>,
) -> Result<ExportSummary> {
    let input = resolve_input(input)?;
    let size = std::fs::metadata(&input).map_or(0, |m| m.len());
    progress(Progress::Length(2 * size));
    let scores = topic != "/ground_truth";
    export_kitti(&input, topic, output, scores, &|bytes| {
        progress(Progress::Position(bytes))
    })
}

impl ImportSummary {
    /// The line `probmot import kitti` prints: the output, the sequence and the counts (the
    /// tracks' with their topic, when another tracker's results were imported).
    pub fn line(&self, output: &Path, sequence: &str, tracks_topic: Option<&str>) -> String {
        format!(
            "{}: sequence {sequence}, {} frames, {} detections from {} files, {} ground-truth \
             rows{}",
            output.display(),
            self.frames,
            self.detections,
            self.detection_files.len(),
            self.truth_rows,
            match tracks_topic {
                Some(t) => format!(", {} track rows on {t}", self.track_rows),
                None => String::new(),
            }
        )
    }
}

impl ExportSummary {
    /// The line `probmot export kitti` prints.
    pub fn line(&self, output: &Path) -> String {
        format!(
            "{}: {} rows in {} frames",
            output.display(),
            self.rows,
            self.frames
        )
    }
}
