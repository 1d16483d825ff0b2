//! A whole tune over MCAP logs, as `probmot tune` runs it: the options checked, the logs read
//! and checked, the cross-validation, the tune on every log, the config named and written.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use anyhow::{bail, ensure, Context, Result};
use rayon::prelude::*;

use super::{cross_validate, CvReport, HeldOutLoss, Protocol, Scoring, SearchLimits, TuneLog};
use super::{TuneOptions, Tuned};
use crate::eval::kitti::MeanScores;
use crate::fit::timing::mixed_periods;
use crate::mcapio::writer::{check_output_path, write_file_atomic};
use crate::msgs::detection_frame::describe_skips;
use crate::pipeline::kitti_io::is_kitti_import;
use crate::pipeline::log_pairs::refuse_repeats;
use crate::pipeline::overrides::Overrides;
use crate::pipeline::progress::{Progress, ProgressFn};
use crate::pipeline::rosbag_dir::resolve_input;
use crate::tracker::levers::Coast;
use crate::tracker::TrackerConfig;

/// Where a tune's base config comes from, and the reporting set on every class of it.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct BaseChoice {
    /// A config file (JSON); wins over `preset`.
    pub file: Option<PathBuf>,
    /// A preset name; `None`: nuscenes-chiu2019.
    pub preset: Option<String>,
    /// Coasted-frame reporting set on every class (as `track --coast`).
    pub coast: Option<Coast>,
    /// Backfill set on or off for every class (as `track --backfill`).
    pub backfill: Option<bool>,
}

/// Settings of a tune over files ([`tune_files`]); the defaults are `probmot tune`'s.
#[derive(Debug, Clone, PartialEq)]
pub struct TuneFilesOptions {
    /// The base config, the search's starting point.
    pub base: BaseChoice,
    /// Protocol; `None`: KITTI when every log was written by `probmot import kitti`, nuScenes
    /// when none was.
    pub protocol: Option<Protocol>,
    /// KITTI: minimum 3D IoU of a match.
    pub iou: f64,
    /// KITTI: how the search's objective computes each track's mean score (`None`: once).
    pub search_means: Option<MeanScores>,
    /// Cross-validation folds; 0 or 1: no cross-validation, only the final tune.
    pub folds: usize,
    /// Search bounds per class.
    pub limits: SearchLimits,
    /// Period of the config's velocities; `None`: the data's frame period.
    pub dt_nominal: Option<f64>,
    /// Minimum matched pairs for fitted noise.
    pub min_samples: u64,
    /// Classes to tune and score (lower case); empty: the protocol's.
    pub classes: Vec<String>,
    /// Search dimensions ([`super::space::DIM_NAMES`]); empty: the default set.
    pub search: Vec<String>,
    /// Keep the base's own settings in the final config for every class that lost held-out.
    pub keep_base_on_loss: bool,
    /// Also write each fold's config to `DIR/fold_<i>.json`.
    pub fold_configs: Option<PathBuf>,
    /// Worker threads; `None`: all cores.
    pub jobs: Option<usize>,
    /// Ground-truth topic.
    pub truth_topic: String,
    /// Detections topic.
    pub detections_topic: String,
}

impl Default for TuneFilesOptions {
    fn default() -> Self {
        TuneFilesOptions {
            base: BaseChoice::default(),
            protocol: None,
            iou: 0.25,
            search_means: None,
            folds: 2,
            limits: SearchLimits::default(),
            dt_nominal: None,
            min_samples: 50,
            classes: Vec::new(),
            search: Vec::new(),
            keep_base_on_loss: false,
            fold_configs: None,
            jobs: None,
            truth_topic: "/ground_truth".into(),
            detections_topic: "/detections".into(),
        }
    }
}

/// What a tune over files found and wrote.
#[derive(Debug, Clone)]
pub struct TuneFilesReport {
    /// The options of the final tune (the protocol resolved, `keep_base` set).
    pub options: TuneOptions,
    /// Warnings about the logs, also given to the `warn` callback as they were found.
    pub warnings: Vec<String>,
    /// The cross-validation (with at least 2 folds).
    pub cv: Option<CvReport>,
    /// Classes whose tuned settings lost held-out (with a cross-validation).
    pub losses: Option<Vec<HeldOutLoss>>,
    /// The final tune on every log.
    pub tuned: Tuned,
    /// The config written: the final tune's, named after the run.
    pub config: TrackerConfig,
}

/// Tunes on the MCAP logs `inputs` (rosbag directories resolved), cross-validated with
/// `o.folds` folds, and writes the config tuned on all of them to `output` atomically (and each
/// fold's with `o.fold_configs`). Warnings about the logs go to `warn` before the search;
/// progress counts configurations scored.
pub fn tune_files(
    inputs: &[PathBuf],
    output: &Path,
    o: &TuneFilesOptions,
    warn: &(dyn Fn(&str) + Sync),
    progress: ProgressFn<'_>,
) -> Result<TuneFilesReport> {
    let inputs: Vec<PathBuf> = (inputs.iter())
        .map(|p| resolve_input(p))
        .collect::<Result<_>>()?;
    refuse_repeats(&inputs)?;
    check(&inputs, output, o)?;
    let inferred = o.protocol.is_none();
    let protocol = protocol_of(&inputs, o.protocol)?;
    check_search_means(o, protocol, inferred)?;
    let base = base_config(&o.base)?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(o.jobs.unwrap_or(0))
        .build()?;
    pool.install(|| {
        let run = Run {
            inputs: &inputs,
            output,
            o,
            protocol,
        };
        run.tune(&base, warn, progress)
    })
}

/// Checks the options and the inputs before any log is read (a long log takes a while).
fn check(inputs: &[PathBuf], output: &Path, o: &TuneFilesOptions) -> Result<()> {
    ensure!(o.limits.budget >= 1, "--budget must be at least 1");
    let margin = o.limits.margin;
    ensure!(
        margin.is_finite() && margin >= 0.0,
        "--margin must be a finite number >= 0, got {margin}"
    );
    ensure!(
        o.iou > 0.0 && o.iou <= 1.0,
        "--iou must lie in (0, 1], got {}",
        o.iou
    );
    if let Some(p) = o.protocol {
        check_search_means(o, p, false)?;
    }
    super::space::check_names(&o.search).map_err(anyhow::Error::msg)?;
    // A misspelt log is named as such, before the fold count that it would otherwise fail.
    for p in inputs {
        std::fs::File::open(p).with_context(|| format!("cannot open {}", p.display()))?;
    }
    ensure!(
        o.folds < 2 || inputs.len() >= o.folds,
        "--folds {} needs one log per fold ({} log(s) given); --folds 1 tunes on all the logs \
         without cross-validation",
        o.folds,
        inputs.len()
    );
    for input in inputs {
        check_output_path(Some(input), output)?;
    }
    Ok(())
}

/// The search-means option only with the KITTI protocol (given, or found from the logs:
/// `inferred`).
fn check_search_means(o: &TuneFilesOptions, protocol: Protocol, inferred: bool) -> Result<()> {
    ensure!(
        o.search_means.is_none() || protocol == Protocol::Kitti,
        "--search-means is a KITTI option (the nuScenes devkit averages each track's score \
         once){}",
        match inferred {
            true =>
                "; these logs were not written by `probmot import kitti`, so they are \
                     scored with the nuScenes protocol (--protocol kitti chooses KITTI's)",
            false => "",
        }
    );
    Ok(())
}

/// The protocol: `given`, else KITTI when every input is a KITTI import and nuScenes when none
/// is.
fn protocol_of(inputs: &[PathBuf], given: Option<Protocol>) -> Result<Protocol> {
    if let Some(p) = given {
        return Ok(p);
    }
    let mut kitti = Vec::new();
    for p in inputs {
        kitti.push(is_kitti_import(p)?);
    }
    match (kitti.iter().all(|k| *k), kitti.iter().any(|k| *k)) {
        (true, _) => Ok(Protocol::Kitti),
        (false, false) => Ok(Protocol::Nuscenes),
        (false, true) => bail!(
            "some logs were written by `probmot import kitti` and some not: give --protocol \
             kitti or nuscenes"
        ),
    }
}

/// The base config: the file or preset, with the reporting choices applied and named.
pub fn base_config(b: &BaseChoice) -> Result<TrackerConfig> {
    let mut cfg = match &b.file {
        Some(p) => {
            let text = std::fs::read_to_string(p)
                .with_context(|| format!("cannot read base config {}", p.display()))?;
            TrackerConfig::from_json(&text).with_context(|| format!("{}", p.display()))?
        }
        None => TrackerConfig::preset(b.preset.as_deref().unwrap_or("nuscenes-chiu2019"))?,
    };
    let reporting = Overrides {
        coast: b.coast,
        backfill: b.backfill,
        ..Overrides::default()
    };
    reporting.apply(&mut cfg)?;
    let mut set = Vec::new();
    if let Some(c) = b.coast {
        set.push(format!("coast {}", coast_name(c)));
    }
    match b.backfill {
        Some(true) => set.push("backfill".to_string()),
        Some(false) => set.push("no backfill".to_string()),
        None => {}
    }
    if !set.is_empty() {
        cfg.name = format!("{} with {}", cfg.name, set.join(", "));
    }
    Ok(cfg)
}

/// The name of a coast mode, as `--coast` takes it.
fn coast_name(c: Coast) -> &'static str {
    match c {
        Coast::All => "all",
        Coast::Gaps => "gaps",
        Coast::None => "none",
    }
}

/// The protocol's name in messages.
pub fn protocol_name(p: Protocol) -> &'static str {
    match p {
        Protocol::Kitti => "KITTI",
        Protocol::Nuscenes => "nuScenes",
    }
}

/// One tune over checked inputs.
struct Run<'a> {
    inputs: &'a [PathBuf],
    output: &'a Path,
    o: &'a TuneFilesOptions,
    protocol: Protocol,
}

impl Run<'_> {
    fn tune(
        &self,
        base: &TrackerConfig,
        warn: &(dyn Fn(&str) + Sync),
        progress: ProgressFn<'_>,
    ) -> Result<TuneFilesReport> {
        let logs = (self.inputs.par_iter())
            .map(|p| {
                let topics = (
                    self.o.truth_topic.as_str(),
                    self.o.detections_topic.as_str(),
                );
                TuneLog::load_for(p, topics, &|label| base.classes.contains_key(label))
            })
            .collect::<Result<Vec<_>>>()?;
        let mut warnings = self.skip_warnings(&logs);
        warnings.extend(period_warning(&logs));
        warnings.extend(self.kitti_protocol_warning()?);
        for w in &warnings {
            warn(w);
        }
        let o = self.options();
        let all: Vec<&TuneLog> = logs.iter().collect();
        let n_classes = scored_classes(&all, &o)?;
        let cv_folds = if self.o.folds >= 2 { self.o.folds } else { 0 };
        let total = (cv_folds + 1) * (n_classes + 1) * o.limits.budget;
        progress(Progress::Length(total as u64));
        let cv = if cv_folds >= 2 {
            progress(Progress::Message("cross-validating"));
            Some(cross_validate(base, &logs, cv_folds, &o, progress)?)
        } else {
            None
        };
        progress(Progress::Message("tuning on all logs"));
        let losses = cv.as_ref().map(|cv| cv.losses(o.limits.margin));
        let mut options = o;
        if self.o.keep_base_on_loss {
            options.keep_base = losses.iter().flatten().map(|l| l.label.clone()).collect();
        }
        let tuned = super::tune(base, &all, &options, progress)?;
        let config = self.named(&tuned, base, logs.len());
        self.write_configs(&config, cv.as_ref())?;
        Ok(TuneFilesReport {
            options,
            warnings,
            cv,
            losses,
            tuned,
            config,
        })
    }

    /// The final config, named after the run.
    fn named(&self, t: &Tuned, base: &TrackerConfig, logs: usize) -> TrackerConfig {
        let scoring = self.scoring();
        let mut cfg = t.tuned.clone();
        cfg.name = format!(
            "tune of {logs} log(s) on {} ({}, {} per class, budget {})",
            base.name,
            match scoring.protocol {
                Protocol::Kitti => "kitti",
                Protocol::Nuscenes => "nuscenes",
            },
            scoring.search_metric(),
            self.o.limits.budget
        );
        if self.o.limits.pool_reporting {
            cfg.name = cfg
                .name
                .replace(" per class,", " per class, reporting pooled,");
        }
        cfg
    }

    fn scoring(&self) -> Scoring {
        Scoring {
            protocol: self.protocol,
            iou: self.o.iou,
            search_means: self.o.search_means.unwrap_or(MeanScores::Once),
        }
    }

    /// The tune's options (`keep_base` empty: the final tune sets it).
    fn options(&self) -> TuneOptions {
        TuneOptions {
            scoring: self.scoring(),
            limits: self.o.limits,
            dt_nominal: self.o.dt_nominal,
            min_samples: self.o.min_samples,
            classes: self.o.classes.clone(),
            search: self.o.search.clone(),
            keep_base: Vec::new(),
        }
    }

    /// Writes the final config and, with `fold_configs`, each fold's config.
    fn write_configs(&self, cfg: &TrackerConfig, cv: Option<&CvReport>) -> Result<()> {
        write_file_atomic(self.output, format!("{}\n", cfg.to_json()).as_bytes())?;
        if let (Some(dir), Some(cv)) = (&self.o.fold_configs, cv) {
            std::fs::create_dir_all(dir)
                .with_context(|| format!("cannot create {}", dir.display()))?;
            for (i, c) in cv.fold_configs.iter().enumerate() {
                let p = dir.join(format!("fold_{}.json", i + 1));
                write_file_atomic(&p, format!("{}\n", c.to_json()).as_bytes())?;
            }
        }
        Ok(())
    }

    /// One warning per log that had detections left out when read (none is dropped unsaid).
    fn skip_warnings(&self, logs: &[TuneLog]) -> Vec<String> {
        (self.inputs.iter().zip(logs))
            .filter(|(_, l)| !l.skipped_detections.is_empty())
            .map(|(p, l)| {
                format!(
                    "{}: topic {}: skipped {}, as `probmot track` skips them",
                    p.display(),
                    self.o.detections_topic,
                    describe_skips(&l.skipped_detections)
                )
            })
            .collect()
    }

    /// A warning when the KITTI protocol scores logs `probmot import kitti` did not write: their
    /// boxes have no 2D image box, so the rules that ignore boxes by it cannot apply.
    fn kitti_protocol_warning(&self) -> Result<Option<String>> {
        if self.protocol != Protocol::Kitti {
            return Ok(None);
        }
        let mut other = Vec::new();
        for p in self.inputs {
            if !is_kitti_import(p)? {
                other.push(p.display().to_string());
            }
        }
        Ok((!other.is_empty()).then(|| {
            format!(
                "--protocol kitti on logs `probmot import kitti` did not write ({}): their boxes \
                 have no 2D image box, so KITTI's rules that ignore low boxes and boxes in \
                 DontCare regions do not apply and every unmatched track box counts as a false \
                 positive",
                other.join(", ")
            )
        }))
    }
}

/// The number of classes the tune scores (the chosen classes, default the protocol's, that have
/// detections; as [`super::classes`]). An error when a chosen class has none (a typo, say), or
/// when none of the protocol's classes has: each names the labels there are.
fn scored_classes(logs: &[&TuneLog], o: &TuneOptions) -> Result<usize> {
    let labels: BTreeSet<&str> = (logs.iter())
        .flat_map(|l| l.frames.iter().flat_map(|f| f.detections.iter()))
        .map(|d| &*d.label)
        .collect();
    let listed = || labels.iter().copied().collect::<Vec<_>>().join(", ");
    let missing: Vec<&str> = (o.classes.iter())
        .map(String::as_str)
        .filter(|c| !labels.contains(c))
        .collect();
    if !missing.is_empty() {
        bail!(
            "--classes: no detection of {} in the inputs (their labels: {})",
            missing.join(", "),
            listed()
        );
    }
    let n = super::classes(logs, o).len();
    if n == 0 {
        bail!(
            "no detection of the {} protocol's classes ({}) in the inputs (their labels: {}); \
             choose the protocol with --protocol or the classes with --classes",
            protocol_name(o.scoring.protocol),
            o.scoring.classes().join(", "),
            listed()
        );
    }
    Ok(n)
}

/// A warning when the logs' frame periods differ (the noise fit of each fold pools them at one
/// period), as `probmot fit` gives it.
fn period_warning(logs: &[TuneLog]) -> Option<String> {
    let (periods, pooled) = super::data::frame_periods(logs);
    mixed_periods(&periods, pooled?)
}
