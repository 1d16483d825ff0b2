//! `probmot viz`, and the Rerun recording of `probmot track --rerun`.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use clap::Args;
pub use probmot::viz::rrd_file::NEEDS_FEATURE;
use probmot::viz::rrd_file::{rrd_file, VizOptions};

use super::layer_topics::LayerTopics;

/// Write a Rerun recording (.rrd) of a recording's detections, tracks and ground truth.
///
/// Entities under `world` (z up, metres): detections (grey boxes), tracks (a colour per id,
/// labelled "car 12"), ground_truth (green, when present), trails (each track's last centres)
/// and velocity (arrows); timelines `log_time` (the MCAP log time) and `frame` (frame index).
/// The recording opens in a top-down 3D view. Same content as scripts/to_rerun.py.
///
/// Needs probmot built with the `rerun` cargo feature (cargo build --release --features rerun);
/// without it, use scripts/to_rerun.py.
///
/// Examples:
///   probmot viz city.tracked.mcap -o city.rrd && rerun city.rrd
///   probmot viz drive.tracked.mcap -o cars.rrd --class car --trail 50
///   probmot viz hour.tracked.mcap -o minute.rrd --from 600 --to 660
#[derive(Debug, Args)]
#[command(verbatim_doc_comment)]
pub struct VizArgs {
    /// MCAP file with probmot's channels, e.g. the output of `probmot track`.
    file: PathBuf,
    /// Output .rrd file (written atomically).
    #[arg(short, long, value_name = "OUT.rrd")]
    output: PathBuf,
    /// Centres per track in world/trails.
    #[arg(long, value_name = "N", default_value_t = 20)]
    trail: usize,
    /// Only boxes of these classes (comma-separated or repeated); default: every class.
    #[arg(
        long,
        value_name = "CLASS",
        value_delimiter = ',',
        visible_alias = "classes"
    )]
    class: Vec<String>,
    /// Window start, seconds after the first frame; with --from or --to only the chunks that
    /// overlap the window are read (a minute of an hour-long drive reads a minute).
    #[arg(long, value_name = "SECONDS")]
    from: Option<f64>,
    /// Window end, seconds after the first frame (inclusive).
    #[arg(long, value_name = "SECONDS")]
    to: Option<f64>,
    #[command(flatten)]
    topics: LayerTopics,
    /// Rerun recording id (default: a random one).
    #[arg(long, value_name = "ID")]
    recording_id: Option<String>,
    /// Print nothing on success (and no spinner while it works).
    #[arg(short, long)]
    quiet: bool,
}

pub fn run(a: VizArgs) -> Result<ExitCode> {
    let o = VizOptions {
        detections_topic: a.topics.detections_topic.clone(),
        tracks_topic: a.topics.tracks_topic.clone(),
        truth_topic: a.topics.truth_topic.clone(),
        classes: a.class.clone(),
        trail: a.trail,
        recording_id: a.recording_id.clone(),
        from_s: a.from,
        to_s: a.to,
    };
    let spinner = super::spinner(super::show_progress(a.quiet));
    let warn = |w: &str| eprintln!("warning: {w}");
    let s = rrd_file(&a.file, &a.output, &o, &warn, &|e| {
        super::show_on_spinner(&spinner, e)
    });
    spinner.finish_and_clear();
    let s = s?;
    if !a.quiet {
        println!("{}", s.line(&a.output));
    }
    Ok(ExitCode::SUCCESS)
}

/// The Rerun recording of a finished `probmot track` run: the same as `probmot viz TRACKED -o
/// OUT` with the run's detections and tracks topics.
#[cfg(feature = "rerun")]
pub fn track_recording(
    tracked: &std::path::Path,
    out: &std::path::Path,
    detections_topic: &str,
    tracks_topic: &str,
) -> Result<probmot::viz::rrd::RrdSummary> {
    use probmot::viz::rrd::mcap_to_rrd;
    let o = VizOptions {
        detections_topic: detections_topic.into(),
        tracks_topic: tracks_topic.into(),
        ..VizOptions::default()
    };
    mcap_to_rrd(tracked, out, &o)
}
