//! `probmot import nuscenes`: tables and results read and checked, the scenes planned, then one
//! MCAP written per scene (`scene_file`). Every table is read and checked before any file is
//! written.

use std::collections::{BTreeMap, HashMap, HashSet};
use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use serde::Serialize;

use super::ego_pose::read_ego_poses;
use super::plan::{choose_scenes, plan_scenes, table, ScenePlan};
use super::results::{read_results, DetectionResults};
use super::scene_file::{write_scene, SceneInputs, SceneSummary};
use super::tables::{read_all, SampleRow, SceneRow};
use super::tracks::{read_tracking_results, TrackingResults};
use super::truth::read_truth;

/// Settings of an import.
#[derive(Debug, Clone)]
pub struct ImportOptions {
    /// Detection results JSON (`/detections`).
    pub detections: Option<PathBuf>,
    /// Tracking submission JSON (`/tracks`).
    pub tracks: Option<PathBuf>,
    /// Directory of the dataset's tables (`v1.0-trainval/` etc.).
    pub meta: PathBuf,
    /// Output directory (created if missing); one `<scene name>.mcap` per scene.
    pub out_dir: PathBuf,
    /// Scene names to import; empty: every scene with a sample in the results.
    pub scenes: Vec<String>,
}

/// Counts of an import.
#[derive(Debug, Clone, Default, Serialize)]
pub struct ImportSummary {
    /// Per scene, in `scene.json` order.
    pub scenes: Vec<SceneSummary>,
    /// Frames written.
    pub frames: u64,
    /// Detections written.
    pub detections: u64,
    /// Ground-truth boxes written.
    pub truth_boxes: u64,
    /// Ground-truth boxes skipped because the category is outside the seven tracking classes,
    /// per category.
    pub truth_skipped: BTreeMap<String, u64>,
    /// Ego poses written.
    pub ego_poses: u64,
    /// Track boxes written.
    pub tracks: u64,
    /// Bicycle-rack boxes written.
    pub bike_racks: u64,
    /// Whether ground truth was written.
    pub ground_truth: bool,
    /// Whether `/ego_pose` was written.
    pub ego_pose: bool,
    /// Warnings for the user.
    pub warnings: Vec<String>,
}

/// The submissions of an import, read and checked, with their file names (empty when not given).
struct Submissions {
    detections: Option<DetectionResults>,
    tracking: Option<TrackingResults>,
    det_file: String,
    trk_file: String,
}

impl Submissions {
    fn read(opts: &ImportOptions) -> Result<Submissions> {
        if opts.detections.is_none() && opts.tracks.is_none() {
            bail!("give --detections, --tracks or both");
        }
        let detections = match &opts.detections {
            Some(p) => Some(read_results(p)?),
            None => None,
        };
        let tracking = match &opts.tracks {
            Some(p) => Some(read_tracking_results(p)?),
            None => None,
        };
        let name = |p: &Option<PathBuf>| p.as_ref().map(|p| p.display().to_string());
        Ok(Submissions {
            detections,
            tracking,
            det_file: name(&opts.detections).unwrap_or_default(),
            trk_file: name(&opts.tracks).unwrap_or_default(),
        })
    }

    /// The file named in an error about the results as a whole.
    fn any_file(&self) -> &str {
        if self.det_file.is_empty() {
            &self.trk_file
        } else {
            &self.det_file
        }
    }

    /// The tokens of every sample of the results, each with its file, sorted.
    fn sample_tokens(&self) -> Vec<(&String, &str)> {
        let det = self.detections.iter().flat_map(|r| r.boxes.keys());
        let trk = self.tracking.iter().flat_map(|t| t.results.keys());
        let mut v: Vec<(&String, &str)> = det
            .map(|k| (k, self.det_file.as_str()))
            .chain(trk.map(|k| (k, self.trk_file.as_str())))
            .collect();
        v.sort();
        v
    }

    /// Warnings for the samples of each planned scene missing from a submission.
    fn missing_warnings(&self, plans: &[ScenePlan], warnings: &mut Vec<String>) {
        for plan in plans {
            let (n, scene) = (plan.samples.len(), &plan.scene.name);
            let missing = |has: &dyn Fn(&String) -> bool| {
                plan.samples.iter().filter(|(t, _)| !has(t)).count()
            };
            if let Some(r) = &self.detections {
                let m = missing(&|t| r.boxes.contains_key(t));
                if m > 0 {
                    warnings.push(format!(
                        "{}: {m} of the {n} samples of scene {scene} are not in the results; \
                         written as frames without detections",
                        self.det_file
                    ));
                }
            }
            if let Some(t) = &self.tracking {
                let m = missing(&|tok| t.results.contains_key(tok));
                if m > 0 {
                    warnings.push(format!(
                        "{}: {m} of the {n} samples of scene {scene} are not in the \
                         submission; written as frames without tracks",
                        self.trk_file
                    ));
                }
            }
        }
    }
}

/// Imports a detection results file and/or a tracking submission: one MCAP per scene in
/// `opts.out_dir`, with `/detections`, `/tracks`, `/ground_truth` and the bicycle racks (when
/// `sample_annotation.json` is present), `/ego_pose` (when `sample_data.json` and
/// `ego_pose.json` are present) and the metadata records [`NUSCENES_METADATA`] and
/// [`SAMPLES_METADATA`]. Every table is read and checked before any file is written.
///
/// [`NUSCENES_METADATA`]: super::NUSCENES_METADATA
/// [`SAMPLES_METADATA`]: super::SAMPLES_METADATA
pub fn import_nuscenes(opts: &ImportOptions) -> Result<ImportSummary> {
    let meta = &opts.meta;
    if !meta.is_dir() {
        bail!(
            "--meta {}: not a directory (give the directory holding sample.json and scene.json, \
             e.g. v1.0-trainval/)",
            meta.display()
        );
    }
    let mut summary = ImportSummary::default();
    let subs = Submissions::read(opts)?;
    let plans = {
        let samples: HashMap<String, SampleRow> =
            read_all::<SampleRow>(&table(meta, "sample.json"))?
                .into_iter()
                .map(|s| (s.token.clone(), s))
                .collect();
        let scenes: Vec<SceneRow> = read_all(&table(meta, "scene.json"))?;
        let with_results = scenes_with_results(opts, &subs, &samples, &scenes)?;
        let chosen = choose_scenes(meta, &scenes, &opts.scenes, &with_results, subs.any_file())?;
        std::fs::create_dir_all(&opts.out_dir)
            .with_context(|| format!("cannot create {}", opts.out_dir.display()))?;
        plan_scenes(meta, &chosen, &samples, &opts.out_dir)?
    };
    subs.missing_warnings(&plans, &mut summary.warnings);
    let wanted: HashSet<&str> = plans
        .iter()
        .flat_map(|p| p.samples.iter().map(|(t, _)| t.as_str()))
        .collect();
    let time_us: HashMap<String, u64> = plans
        .iter()
        .flat_map(|p| p.samples.iter().cloned())
        .collect();
    let truth = read_truth(meta, &wanted, &time_us)?;
    let ego = read_ego_poses(meta, &wanted, &mut summary.warnings)?;
    summary.ground_truth = truth.is_some();
    summary.ego_pose = ego.is_some();
    let results_meta = subs
        .detections
        .as_ref()
        .and_then(|r| r.meta.as_ref())
        .map(|m| m.to_string())
        .unwrap_or_default();
    let inputs = SceneInputs {
        results: subs.detections.as_ref(),
        tracking: subs.tracking.as_ref(),
        truth: truth.as_ref(),
        ego: ego.as_ref(),
        files: (&subs.det_file, &subs.trk_file),
        results_meta: &results_meta,
    };
    for plan in &plans {
        summary.add(write_scene(plan, &inputs)?);
    }
    if let Some(t) = truth {
        summary.skipped_warning(t.skipped);
    }
    Ok(summary)
}

/// The scenes holding a sample of the results; every results token must be a sample of the
/// tables, in a scene of the tables.
fn scenes_with_results<'a>(
    opts: &ImportOptions,
    subs: &Submissions,
    samples: &'a HashMap<String, SampleRow>,
    scenes: &[SceneRow],
) -> Result<HashSet<&'a str>> {
    let meta = &opts.meta;
    let scene_tokens: HashSet<&str> = scenes.iter().map(|s| s.token.as_str()).collect();
    let mut out: HashSet<&str> = HashSet::new();
    for (tok, file) in subs.sample_tokens() {
        let s = samples.get(tok).with_context(|| {
            format!(
                "{file}: sample token {tok} is not in {}",
                table(meta, "sample.json").display()
            )
        })?;
        if !scene_tokens.contains(s.scene_token.as_str()) {
            bail!(
                "{}: sample {tok} has scene_token {}, which is not in {}",
                table(meta, "sample.json").display(),
                s.scene_token,
                table(meta, "scene.json").display()
            );
        }
        out.insert(s.scene_token.as_str());
    }
    Ok(out)
}

impl ImportSummary {
    /// Adds the counts of one written scene.
    fn add(&mut self, s: SceneSummary) {
        self.tracks += s.tracks;
        self.bike_racks += s.bike_racks;
        self.frames += s.frames;
        self.detections += s.detections;
        self.truth_boxes += s.truth_boxes;
        self.ego_poses += s.ego_poses;
        self.scenes.push(s);
    }

    /// Records the ground-truth boxes skipped (outside the tracking classes), with a warning.
    fn skipped_warning(&mut self, skipped: BTreeMap<String, u64>) {
        self.truth_skipped = skipped;
        if self.truth_skipped.is_empty() {
            return;
        }
        let parts: Vec<String> = self
            .truth_skipped
            .iter()
            .map(|(c, n)| format!("{c} {n}"))
            .collect();
        self.warnings.push(format!(
            "skipped {} ground-truth boxes outside the seven tracking classes: {}",
            self.truth_skipped.values().sum::<u64>(),
            parts.join(", ")
        ));
    }
}
