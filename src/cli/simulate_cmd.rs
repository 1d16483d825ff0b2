//! `probmot simulate`.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use clap::Args;
use probmot::sim::{simulate_file, Scenario, SimOptions};

use super::choice::choice;
use super::show_progress;

/// Write a deterministic synthetic drive with `/detections` and `/ground_truth`.
///
/// The same arguments always give a byte-identical file. A progress bar counts the frames on a
/// terminal (--quiet hides it).
///
/// Examples:
///   probmot simulate --scenario turning-car -o turning-car.mcap
///   probmot simulate --scenario city --frames 20000 --objects 200 -o city20k.mcap
#[derive(Debug, Args)]
#[command(verbatim_doc_comment)]
pub struct SimulateArgs {
    /// Which drive.
    #[arg(long, value_parser = choice::<Scenario>())]
    scenario: Scenario,
    /// Random seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Number of frames. Velocities are a random walk (the process noise `fit` recovers), so
    /// over thousands of frames speeds drift from typical ones: long logs are for scale tests.
    #[arg(long, default_value_t = 40)]
    frames: u32,
    /// Objects: total for city (default 40), extra background objects otherwise.
    #[arg(long)]
    objects: Option<u32>,
    /// Frame rate, Hz (2 = nuScenes keyframes).
    #[arg(long, default_value_t = 2.0)]
    rate: f64,
    /// Write the detections in the frame `base_link` of a simulated ego vehicle that drives a
    /// slalom of 90-degree turns, with its pose as foxglove.FrameTransform on /tf (map ->
    /// base_link), and the ground truth also in base_link on /ground_truth/ego. The detections
    /// are those of the same run without this option, moved into base_link.
    #[arg(long)]
    ego_frame: bool,
    /// Output MCAP file.
    #[arg(short, long)]
    output: PathBuf,
    /// Print the summary as JSON.
    #[arg(long)]
    json: bool,
    /// No progress bar and no summary line (--json still prints its summary).
    #[arg(short, long)]
    quiet: bool,
}

pub fn run(a: SimulateArgs) -> Result<ExitCode> {
    let opts = SimOptions {
        scenario: a.scenario,
        seed: a.seed,
        frames: a.frames,
        objects: a.objects,
        rate_hz: a.rate,
        ego_frame: a.ego_frame,
    };
    let template = "{spinner} simulating [{bar:30}] {pos}/{len} frames, {elapsed}";
    let frames = super::style(template).progress_chars("=> ");
    let bar = super::bar(show_progress(a.quiet || a.json), frames);
    let s = simulate_file(&opts, &a.output, &|e| super::show_on_bar(&bar, e));
    bar.finish_and_clear();
    let s = s?;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&s)?);
    } else if !a.quiet {
        println!(
            "{}: {} frames, {} objects, {} detections, {} ground-truth boxes",
            a.output.display(),
            s.frames,
            s.objects,
            s.detections,
            s.truth_boxes
        );
    }
    Ok(ExitCode::SUCCESS)
}
