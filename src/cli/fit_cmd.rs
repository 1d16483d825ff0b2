//! `probmot fit`.

use std::fmt::Write as _;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{ensure, Context, Result};
use clap::Args;
use probmot::fit::load::stream_log;
use probmot::fit::{
    fit_gathered, fitted_config, ClassFit, FitAccumulator, FitOptions, FitReport, YawMode,
};
use probmot::mcapio::writer::{check_output_path, write_file_atomic};
use probmot::pipeline::rosbag_dir::resolve_input;
use probmot::tracker::{Preset, TrackerConfig};

use super::config_cmd::PresetArg;
use super::eval_args::bytes_bar;
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
///   probmot fit train/*.mcap -o noise.json
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
        value_enum,
        value_name = "NAME",
        conflicts_with = "base_config"
    )]
    base_preset: Option<PresetArg>,
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

fn base_config(a: &FitArgs) -> Result<TrackerConfig> {
    Ok(match &a.base_config {
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("cannot read base config {}", path.display()))?;
            TrackerConfig::from_json(&text)
                .with_context(|| format!("base config {}", path.display()))?
        }
        None => a
            .base_preset
            .map_or(Preset::NuscenesChiu2019, |p| p.0)
            .config()?,
    })
}

/// A variance for the table: 4 decimals from 0.01 up, scientific notation below, "-" when
/// unknown.
fn num(v: Option<f64>) -> String {
    match v {
        None => "-".into(),
        Some(0.0) => "0".into(),
        Some(v) if v.abs() >= 0.01 => format!("{v:.4}"),
        Some(v) => format!("{v:.3e}"),
    }
}

const COLUMNS: [&str; 16] = [
    "class", "pairs", "q_n", "R_x", "R_y", "R_z", "R_yaw", "R_l", "R_w", "R_h", "yaw_wrap",
    "yaw_fold", "Q_x", "Q_y", "Q_z", "Q_yaw",
];

fn row(c: &ClassFit) -> Vec<String> {
    let r = |i: usize| num(c.r.map(|r| r[i]));
    let q = |i: usize| num(c.q.map(|q| q[i]));
    let mut label = c.label.clone();
    if !c.applied {
        label.push('*');
    }
    vec![
        label,
        c.n_pairs.to_string(),
        c.n_q_samples.to_string(),
        r(0),
        r(1),
        r(2),
        r(3),
        r(4),
        r(5),
        r(6),
        num(c.r_yaw_wrapped),
        num(c.r_yaw_folded),
        q(0),
        q(1),
        q(2),
        q(3),
    ]
}

fn table(rep: &FitReport) -> String {
    let rows: Vec<Vec<String>> = rep.classes.iter().map(row).collect();
    let widths: Vec<usize> = (0..COLUMNS.len())
        .map(|i| {
            rows.iter()
                .map(|r| r[i].len())
                .chain([COLUMNS[i].len()])
                .max()
                .unwrap_or(0)
        })
        .collect();
    let line = |cells: &mut dyn Iterator<Item = &str>| {
        let mut s = String::new();
        for (i, (c, w)) in cells.zip(&widths).enumerate() {
            let _ = if i == 0 {
                write!(s, "{c:<w$}")
            } else {
                write!(s, "  {c:>w$}")
            };
        }
        s.push('\n');
        s
    };
    let mut s = line(&mut COLUMNS.iter().copied());
    for r in &rows {
        s.push_str(&line(&mut r.iter().map(String::as_str)));
    }
    s
}

/// The inputs for an error: the file, or how many.
fn describe_inputs(inputs: &[PathBuf]) -> String {
    match inputs {
        [one] => one.display().to_string(),
        many => format!("the {} logs", many.len()),
    }
}

/// Runs `probmot fit`.
pub fn run(mut a: FitArgs) -> Result<ExitCode> {
    a.inputs = (a.inputs.iter())
        .map(|p| resolve_input(p))
        .collect::<Result<_>>()?;
    ensure!(a.min_samples >= 1, "--min-samples must be at least 1");
    for input in &a.inputs {
        check_output_path(Some(input), &a.output)?;
    }
    let base = base_config(&a)?;
    let dt_nominal = a.dt_nominal.unwrap_or(base.dt_nominal);
    ensure!(
        dt_nominal.is_finite() && dt_nominal > 0.0,
        "--dt-nominal must be a positive number of seconds, got {dt_nominal}"
    );
    let files: Vec<&std::path::Path> = a.inputs.iter().map(PathBuf::as_path).collect();
    let bar = bytes_bar(&files, show_progress(a.quiet || a.json));
    // Log after log, frame by frame: memory bounded by a few frames, not by the logs.
    let mut acc = FitAccumulator::new();
    for p in &a.inputs {
        let topics = (a.truth_topic.as_str(), a.detections_topic.as_str());
        stream_log(&mut acc, p, topics, &|n| bar.inc(n))?;
    }
    bar.finish_and_clear();
    let options = FitOptions {
        dt_nominal,
        yaw: if a.fold_yaw {
            YawMode::Folded
        } else {
            YawMode::Wrapped
        },
        min_samples: a.min_samples,
    };
    let mut report = fit_gathered(acc, &options);
    ensure!(
        report.detections > 0,
        "no detection box on topic {} in {}: the fit needs detections beside the ground truth \
         (as `probmot import kitti|nuscenes` and `probmot simulate` write them)",
        a.detections_topic,
        describe_inputs(&a.inputs)
    );
    let mut cfg = fitted_config(&base, &mut report, &options)?;
    let fitted = report.classes.iter().filter(|c| c.applied).count();
    cfg.name = format!(
        "fit of {} log(s) on {}{}",
        a.inputs.len(),
        base.name,
        if a.fold_yaw { " (yaw folded)" } else { "" }
    );
    write_file_atomic(&a.output, format!("{}\n", cfg.to_json()).as_bytes())?;
    for w in &report.warnings {
        eprintln!("warning: {w}");
    }
    if a.json {
        let mut v = serde_json::to_value(&report)?;
        v["output"] = a.output.display().to_string().into();
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        print!("{}", table(&report));
        let period = report
            .period
            .map(|p| format!("{:.4} s", p.median_s))
            .unwrap_or_else(|| "unknown".into());
        println!(
            "{} log(s), {} frames, frame period {period}, dt_nominal {} s (Q x {}); variances: {}; \
             config yaw: {}",
            report.logs.len(),
            report.frames,
            dt_nominal,
            num(Some(report.q_scale)),
            report.variance,
            if a.fold_yaw { "folded" } else { "wrapped" },
        );
        if fitted < report.classes.len() {
            println!(
                "* kept the base values (fewer than {} pairs)",
                a.min_samples
            );
        }
        println!("wrote {} ({fitted} class(es) fitted)", a.output.display());
    }
    Ok(ExitCode::SUCCESS)
}
