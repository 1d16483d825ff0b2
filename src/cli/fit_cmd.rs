//! `probmot fit`.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use clap::Args;
use probmot::fit::files::{fit_files, FitFilesOptions};

use probmot::tracker::Preset;

use super::choice::choice;
use super::show_progress;

/// Fit per-class noise (Q, R, P0) from logs with ground truth and detections, and write a
/// tracker config.
///
/// The statistics are those of the paper's reference implementation: Q = variance of the ground
/// truth's second differences of x y z yaw over each instance's consecutive frames (reused on the
/// velocity entries, 0 on l w h); R = variance of detection - truth per field over pairs
/// matched per frame and label by optimal assignment on BEV centre distance (< 2 m); P0 = R,
/// and on the velocity entries the variance of the frame-to-frame change of the detection
/// error of one instance. Variances are population variances (ddof = 0). Frames are the
/// distinct stamps of the truth channel; Q is converted from the data's frame period to
/// dt_nominal with the factor (dt_nominal / period)^3 (velocity random walk).
///
/// The config is the base config (preset nuscenes-chiu2019 by default) with q, r, p0 and samples
/// of every class with at least --min-samples matched pairs replaced. Both yaw statistics are
/// reported: wrapped to [-pi, pi) (as the reference; 180-degree flips of the detector count as
/// large errors) and folded to [-pi/2, pi/2] (flips count as aligned, as the tracker's distance
/// treats them); the config gets the wrapped one unless --fold-yaw.
///
/// Examples:
///   probmot fit sample_logs/*.mcap -o noise.json
///   probmot fit drive.mcap -o noise.json --fold-yaw --base-preset ab3dmot-2019 --json
///   probmot track drive.mcap -o out.mcap --config noise.json
#[derive(Debug, Args)]
#[command(verbatim_doc_comment)]
pub struct FitArgs {
    /// Input MCAP file(s) with ground truth and detections.
    #[arg(required = true, value_name = "LOG.mcap")]
    inputs: Vec<PathBuf>,
    /// Output config file (JSON), written atomically.
    #[arg(short, long, value_name = "noise.json")]
    output: PathBuf,
    /// Ground-truth topic (probmot.Tracks3D with the true instance ids).
    #[arg(long, default_value = "/ground_truth", value_name = "TOPIC")]
    truth_topic: String,
    /// Detections topic (probmot.Detections3D).
    #[arg(long, default_value = "/detections", value_name = "TOPIC")]
    detections_topic: String,
    /// Period in seconds the config's velocities and Q are expressed in (default: the base
    /// config's).
    #[arg(long, value_name = "S")]
    dt_nominal: Option<f64>,
    /// Base preset (default nuscenes-chiu2019); `--preset` as in `tune`.
    #[arg(
        long,
        visible_alias = "preset",
        value_parser = choice::<Preset>(),
        value_name = "NAME",
        conflicts_with = "base_config"
    )]
    base_preset: Option<Preset>,
    /// Base config file (JSON, as printed by `probmot config`); `--base` as in `tune`.
    #[arg(long, visible_alias = "base", value_name = "FILE")]
    base_config: Option<PathBuf>,
    /// Fold yaw residuals to [-pi/2, pi/2] in R and P0 (180-degree flips count as aligned).
    #[arg(long)]
    fold_yaw: bool,
    /// Classes with fewer matched pairs keep the base values.
    #[arg(long, default_value_t = 50, value_name = "N")]
    min_samples: u64,
    /// Print the report as JSON instead of the table.
    #[arg(long)]
    json: bool,
    /// No progress bar (it is shown on a terminal only, on stderr). Example: --quiet
    #[arg(long, short)]
    quiet: bool,
}

/// Runs `probmot fit`.
pub fn run(a: FitArgs) -> Result<ExitCode> {
    let defaults = FitFilesOptions::default();
    let o = FitFilesOptions {
        base_config: a.base_config.clone(),
        base_preset: a.base_preset.unwrap_or(defaults.base_preset),
        dt_nominal: a.dt_nominal,
        fold_yaw: a.fold_yaw,
        min_samples: a.min_samples,
        truth_topic: a.truth_topic.clone(),
        detections_topic: a.detections_topic.clone(),
    };
    let bar = super::bar(
        show_progress(a.quiet || a.json),
        super::style(super::READING),
    );
    let fit = fit_files(&a.inputs, &a.output, &o, &|e| super::show_on_bar(&bar, e));
    bar.finish_and_clear();
    let report = fit?.report;
    for w in &report.warnings {
        eprintln!("warning: {w}");
    }
    if a.json {
        let mut v = serde_json::to_value(&report)?;
        v["output"] = a.output.display().to_string().into();
        println!("{}", serde_json::to_string_pretty(&v)?);
        return Ok(ExitCode::SUCCESS);
    }
    print!("{}", report.text(&a.output));
    Ok(ExitCode::SUCCESS)
}
