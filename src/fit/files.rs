//! A fit over MCAP logs, as `probmot fit` runs it: the base config, the logs streamed one after
//! the other, the noise fitted, the config named and written; and its report as a table.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{ensure, Context, Result};

use super::load::stream_log;
use super::{
    fit_gathered, fitted_config, ClassFit, FitAccumulator, FitOptions, FitReport, YawMode,
};
use crate::mcapio::writer::{check_output_path, write_file_atomic};
use crate::pipeline::log_pairs::refuse_repeats;
use crate::pipeline::progress::{Progress, ProgressFn};
use crate::pipeline::rosbag_dir::resolve_input;
use crate::tracker::{Preset, TrackerConfig};

/// Settings of a fit over files ([`fit_files`]); the defaults are `probmot fit`'s.
#[derive(Debug, Clone, PartialEq)]
pub struct FitFilesOptions {
    /// Base config file (JSON); wins over `base_preset`.
    pub base_config: Option<PathBuf>,
    /// Base preset (default nuscenes-chiu2019).
    pub base_preset: Preset,
    /// Period the config's velocities and Q are expressed in; `None`: the base config's.
    pub dt_nominal: Option<f64>,
    /// Fold yaw residuals to [-pi/2, pi/2] in R and P0.
    pub fold_yaw: bool,
    /// Classes with fewer matched pairs keep the base values.
    pub min_samples: u64,
    /// Ground-truth topic.
    pub truth_topic: String,
    /// Detections topic.
    pub detections_topic: String,
}

impl Default for FitFilesOptions {
    fn default() -> Self {
        FitFilesOptions {
            base_config: None,
            base_preset: Preset::NuscenesChiu2019,
            dt_nominal: None,
            fold_yaw: false,
            min_samples: 50,
            truth_topic: "/ground_truth".into(),
            detections_topic: "/detections".into(),
        }
    }
}

/// What a fit over files found and wrote.
#[derive(Debug, Clone)]
pub struct FitFiles {
    /// The statistics, per class.
    pub report: FitReport,
    /// The config written: the base with the fitted noise, named after the run.
    pub config: TrackerConfig,
}

/// Fits the noise on the logs `inputs` (rosbag directories resolved), read one after the
/// other (memory bounded by a few frames), and writes the fitted config to `output`
/// atomically. Progress: bytes read of all the inputs.
pub fn fit_files(
    inputs: &[PathBuf],
    output: &Path,
    o: &FitFilesOptions,
    progress: ProgressFn<'_>,
) -> Result<FitFiles> {
    let inputs: Vec<PathBuf> = (inputs.iter())
        .map(|p| resolve_input(p))
        .collect::<Result<_>>()?;
    refuse_repeats(&inputs)?;
    ensure!(o.min_samples >= 1, "--min-samples must be at least 1");
    for input in &inputs {
        check_output_path(Some(input), output)?;
    }
    let base = base_config(o)?;
    let dt_nominal = o.dt_nominal.unwrap_or(base.dt_nominal);
    ensure!(
        dt_nominal.is_finite() && dt_nominal > 0.0,
        "--dt-nominal must be a positive number of seconds, got {dt_nominal}"
    );
    let total = (inputs.iter())
        .map(|p| std::fs::metadata(p).map_or(0, |m| m.len()))
        .sum();
    progress(Progress::Length(total));
    let mut acc = FitAccumulator::new();
    for p in &inputs {
        let topics = (o.truth_topic.as_str(), o.detections_topic.as_str());
        let has_entry = |label: &str| base.classes.contains_key(label);
        stream_log(&mut acc, p, topics, &has_entry, &|n| {
            progress(Progress::Advance(n))
        })?;
    }
    progress(Progress::Done);
    let options = FitOptions {
        dt_nominal,
        yaw: match o.fold_yaw {
            true => YawMode::Folded,
            false => YawMode::Wrapped,
        },
        min_samples: o.min_samples,
    };
    let mut report = fit_gathered(acc, &options);
    ensure!(
        report.detections > 0,
        "no detection box on topic {} in {}: the fit needs detections beside the ground truth \
         (as `probmot import kitti|nuscenes` and `probmot simulate` write them)",
        o.detections_topic,
        describe_inputs(&inputs)
    );
    let mut config = fitted_config(&base, &mut report, &options)?;
    config.name = format!(
        "fit of {} log(s) on {}{}",
        inputs.len(),
        base.name,
        if o.fold_yaw { " (yaw folded)" } else { "" }
    );
    write_file_atomic(output, format!("{}\n", config.to_json()).as_bytes())?;
    Ok(FitFiles { report, config })
}

fn base_config(o: &FitFilesOptions) -> Result<TrackerConfig> {
    Ok(match &o.base_config {
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("cannot read base config {}", path.display()))?;
            TrackerConfig::from_json(&text)
                .with_context(|| format!("base config {}", path.display()))?
        }
        None => o.base_preset.config()?,
    })
}

/// The inputs for an error: the file, or how many.
fn describe_inputs(inputs: &[PathBuf]) -> String {
    match inputs {
        [one] => one.display().to_string(),
        many => format!("the {} logs", many.len()),
    }
}

/// A variance for the table: 4 decimals from 0.01 up, scientific notation below, "-" when
/// unknown.
pub fn num(v: Option<f64>) -> String {
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
    let mut cells = vec![label, c.n_pairs.to_string(), c.n_q_samples.to_string()];
    cells.extend((0..7).map(r));
    cells.extend([num(c.r_yaw_wrapped), num(c.r_yaw_folded)]);
    cells.extend((0..4).map(q));
    cells
}

impl FitReport {
    /// The per-class statistics as a table with aligned columns (a `*` after a class that kept
    /// the base values).
    pub fn table(&self) -> String {
        let rows: Vec<Vec<String>> = self.classes.iter().map(row).collect();
        let widths: Vec<usize> = (0..COLUMNS.len())
            .map(|i| {
                (rows.iter().map(|r| r[i].len()))
                    .chain([COLUMNS[i].len()])
                    .max()
                    .unwrap_or(0)
            })
            .collect();
        let line = |cells: &mut dyn Iterator<Item = &str>| {
            let mut s = String::new();
            for (i, (c, w)) in cells.zip(&widths).enumerate() {
                let _ = match i {
                    0 => write!(s, "{c:<w$}"),
                    _ => write!(s, "  {c:>w$}"),
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

    /// What `probmot fit` prints: the table, a summary line, and the config written to `output`.
    pub fn text(&self, output: &Path) -> String {
        let mut s = self.table();
        let period = (self.period)
            .map(|p| format!("{:.4} s", p.median_s))
            .unwrap_or_else(|| "unknown".into());
        let yaw = match self.yaw_mode {
            YawMode::Folded => "folded",
            YawMode::Wrapped => "wrapped",
        };
        let _ = writeln!(
            s,
            "{} log(s), {} frames, frame period {period}, dt_nominal {} s (Q x {}); variances: \
             {}; config yaw: {yaw}",
            self.logs.len(),
            self.frames,
            self.dt_nominal,
            num(Some(self.q_scale)),
            self.variance,
        );
        let fitted = self.classes.iter().filter(|c| c.applied).count();
        if fitted < self.classes.len() {
            let _ = writeln!(
                s,
                "* kept the base values (fewer than {} pairs)",
                self.min_samples
            );
        }
        let _ = writeln!(s, "wrote {} ({fitted} class(es) fitted)", output.display());
        s
    }
}
