//! `probmot export nuscenes`: `Tracks3D` channels as a tracking submission.

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use mcap::records::Record;
use serde::{Deserialize, Serialize};

use crate::mcapio::reader::has_metadata;
use crate::mcapio::recording::for_each_tracks_frame_with;
use crate::mcapio::writer::{check_output_path, write_file_atomic};
use crate::msgs::Track3D;
use crate::tracker::config::NUSCENES_CLASSES;

use super::plan::{scene_samples, table};
use super::tables::{read_all, SampleRow, SceneRow};
use super::{yaw_quaternion, MAX_BOXES_PER_SAMPLE, NUSCENES_METADATA, SAMPLES_METADATA};

// ---------------------------------------------------------------------------------------------
// Export

/// The `meta` block of a submission.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq, Eq)]
pub struct SubmissionMeta {
    /// Camera data used.
    pub use_camera: bool,
    /// Lidar data used.
    pub use_lidar: bool,
    /// Radar data used.
    pub use_radar: bool,
    /// Map data used.
    pub use_map: bool,
    /// External data used.
    pub use_external: bool,
}

impl Default for SubmissionMeta {
    fn default() -> Self {
        SubmissionMeta {
            use_camera: false,
            use_lidar: true,
            use_radar: false,
            use_map: false,
            use_external: false,
        }
    }
}

/// One box of a tracking submission.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct TrackingBox {
    /// Sample token.
    pub sample_token: String,
    /// Box centre, global frame.
    pub translation: [f64; 3],
    /// `[w, l, h]`.
    pub size: [f64; 3],
    /// Quaternion `[w, x, y, z]`.
    pub rotation: [f64; 4],
    /// `[vx, vy]`, m/s.
    pub velocity: [f64; 2],
    /// Track id.
    pub tracking_id: String,
    /// One of the seven tracking classes.
    pub tracking_name: String,
    /// Score.
    pub tracking_score: f64,
}

/// A tracking submission file.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Submission {
    /// Sensors and data used.
    pub meta: SubmissionMeta,
    /// Boxes per sample token.
    pub results: BTreeMap<String, Vec<TrackingBox>>,
}

/// Settings of an export.
#[derive(Debug, Clone)]
pub struct ExportOptions {
    /// Tracks3D topic to export.
    pub topic: String,
    /// Optional table directory: each input's samples are checked against its scene.
    pub meta_dir: Option<PathBuf>,
    /// The submission's `meta`.
    pub meta: SubmissionMeta,
}

/// Counts of an export.
#[derive(Debug, Clone, Default, Serialize)]
pub struct ExportSummary {
    /// Input files (= scenes).
    pub scenes: u64,
    /// Sample tokens written.
    pub samples: u64,
    /// Boxes written.
    pub boxes: u64,
    /// Boxes dropped because their sample had more than 500 (the lowest scores go).
    pub dropped_over_cap: u64,
    /// Samples that had more than 500 boxes.
    pub samples_over_cap: u64,
    /// Boxes skipped because the label is not a tracking class, per label.
    pub skipped_labels: BTreeMap<String, u64>,
    /// Warnings for the user.
    pub warnings: Vec<String>,
}

/// What export reads from one file.
pub(crate) struct ExportInput {
    pub(crate) scene: BTreeMap<String, String>,
    pub(crate) samples: BTreeMap<u64, String>,
    pub(crate) frames: Vec<(u64, Vec<Track3D>)>,
}

pub(crate) fn read_export_input(path: &Path, topic: &str) -> Result<ExportInput> {
    let file = path.display().to_string();
    let not_imported = || {
        anyhow::anyhow!(
            "{file}: no metadata record {SAMPLES_METADATA} (the sample token of each frame); \
             export nuscenes needs a file written by `probmot import nuscenes` (or `probmot \
             track` of one)"
        )
    };
    // Said before the messages are read, when the summary can tell.
    if has_metadata(path, SAMPLES_METADATA) == Some(false) {
        return Err(not_imported());
    }
    let mut scene = None;
    let mut samples = None;
    let mut frames = Vec::new();
    for_each_tracks_frame_with(
        path,
        topic,
        |stamp, tracks, _| {
            frames.push((stamp, tracks));
            Ok(())
        },
        |rec| {
            match rec {
                Record::Metadata(m) if m.name == NUSCENES_METADATA => scene = Some(m.metadata),
                Record::Metadata(m) if m.name == SAMPLES_METADATA => {
                    let mut map = BTreeMap::new();
                    for (k, v) in m.metadata {
                        let stamp: u64 = k.parse().with_context(|| {
                            format!("{file}: metadata {SAMPLES_METADATA}: key '{k}' is not a stamp")
                        })?;
                        map.insert(stamp, v);
                    }
                    samples = Some(map);
                }
                _ => {}
            }
            Ok(())
        },
    )?;
    let Some(samples) = samples else {
        return Err(not_imported());
    };
    Ok(ExportInput {
        scene: scene.unwrap_or_default(),
        samples,
        frames,
    })
}

/// Writes the `Tracks3D` topic of each input (one scene each, as imported) as a nuScenes
/// tracking submission: every sample token of the input scenes (empty lists where no box), at
/// most [`MAX_BOXES_PER_SAMPLE`] boxes per sample (the highest scores), labels outside the seven
/// tracking classes skipped. Refuses non-finite numbers (JSON cannot hold them; the devkit
/// refuses a NaN score).
pub fn export_nuscenes(
    inputs: &[PathBuf],
    output: &Path,
    opts: &ExportOptions,
) -> Result<ExportSummary> {
    if inputs.is_empty() {
        bail!("no input file");
    }
    for i in inputs {
        check_output_path(Some(i), output)?;
    }
    let tables = match &opts.meta_dir {
        Some(dir) => Some(ExportTables::read(dir)?),
        None => None,
    };
    let mut summary = ExportSummary::default();
    let mut results: BTreeMap<String, Vec<TrackingBox>> = BTreeMap::new();
    let mut owner: HashMap<String, String> = HashMap::new();
    for input in inputs {
        let file = input.display().to_string();
        let inp = read_export_input(input, &opts.topic)?;
        if let Some(t) = &tables {
            t.check(&file, &inp)?;
        }
        summary.scenes += 1;
        for tok in inp.samples.values() {
            if let Some(other) = owner.insert(tok.clone(), file.clone()) {
                bail!("sample {tok} is in both {other} and {file}; give each scene once");
            }
            results.entry(tok.clone()).or_default();
        }
        add_frames(&file, inp, &opts.topic, &mut results, &mut summary)?;
    }
    summary.cap_samples(&mut results);
    summary.skipped_warning();
    let sub = Submission {
        meta: opts.meta,
        results,
    };
    let bytes = serde_json::to_vec(&sub).context("serializing the submission")?;
    write_file_atomic(output, &bytes)?;
    Ok(summary)
}

/// The dataset tables an export checks each input's samples against (`--meta`).
struct ExportTables<'a> {
    dir: &'a Path,
    samples: HashMap<String, SampleRow>,
    scenes: Vec<SceneRow>,
}

impl<'a> ExportTables<'a> {
    fn read(dir: &'a Path) -> Result<Self> {
        let samples: HashMap<String, SampleRow> =
            read_all::<SampleRow>(&table(dir, "sample.json"))?
                .into_iter()
                .map(|s| (s.token.clone(), s))
                .collect();
        let scenes: Vec<SceneRow> = read_all(&table(dir, "scene.json"))?;
        Ok(ExportTables {
            dir,
            samples,
            scenes,
        })
    }

    /// The samples recorded in input `file` are those of its scene in the tables.
    fn check(&self, file: &str, inp: &ExportInput) -> Result<()> {
        let dir = self.dir;
        let scene_name = inp.scene.get("scene_name").cloned().unwrap_or_default();
        let tok = inp
            .scene
            .get("scene_token")
            .with_context(|| format!("{file}: metadata {NUSCENES_METADATA} lacks scene_token"))?;
        let scene = self
            .scenes
            .iter()
            .find(|s| s.token == *tok)
            .with_context(|| {
                format!(
                    "{file}: scene {scene_name} ({tok}) is not in {}",
                    table(dir, "scene.json").display()
                )
            })?;
        let chain = scene_samples(dir, scene, &self.samples)?;
        let want: BTreeMap<u64, String> = chain.into_iter().map(|(t, us)| (us * 1000, t)).collect();
        if want != inp.samples {
            bail!(
                "{file}: the samples recorded for scene {} ({tok}) differ from those of {} \
                 ({} recorded, {} in the tables)",
                scene.name,
                dir.display(),
                inp.samples.len(),
                want.len()
            );
        }
        Ok(())
    }
}

/// Adds the boxes of one input's frames to `results` (every sample already has its list),
/// skipping labels outside the tracking classes; warns when a track changes label.
fn add_frames(
    file: &str,
    inp: ExportInput,
    topic: &str,
    results: &mut BTreeMap<String, Vec<TrackingBox>>,
    summary: &mut ExportSummary,
) -> Result<()> {
    let mut labels_of: HashMap<u64, String> = HashMap::new();
    let mut relabelled = 0u64;
    for (stamp, tracks) in inp.frames {
        let tok = inp.samples.get(&stamp).with_context(|| {
            format!(
                "{file}: topic {topic}: a frame at stamp {stamp} ns is not a sample of the scene \
                 (metadata {SAMPLES_METADATA})"
            )
        })?;
        let list = results.get_mut(tok).expect("every sample has a list");
        for t in tracks {
            if !NUSCENES_CLASSES.contains(&t.label.as_str()) {
                *summary.skipped_labels.entry(t.label.clone()).or_default() += 1;
                continue;
            }
            let b = tracking_box(&t, tok).with_context(|| {
                format!(
                    "{file}: topic {topic}, stamp {stamp} (sample {tok}), track {}",
                    t.id
                )
            })?;
            if let Some(prev) = labels_of.insert(t.id, t.label.clone()) {
                if prev != t.label {
                    relabelled += 1;
                }
            }
            list.push(b);
        }
    }
    if relabelled > 0 {
        summary.warnings.push(format!(
            "{file}: {relabelled} boxes have a label different from an earlier box of the \
             same track; the devkit expects one tracking_name per track"
        ));
    }
    Ok(())
}

impl ExportSummary {
    /// Keeps at most [`MAX_BOXES_PER_SAMPLE`] boxes per sample (the highest scores), counting
    /// samples and boxes, with a warning when any were dropped.
    fn cap_samples(&mut self, results: &mut BTreeMap<String, Vec<TrackingBox>>) {
        for list in results.values_mut() {
            if list.len() > MAX_BOXES_PER_SAMPLE {
                self.samples_over_cap += 1;
                self.dropped_over_cap += (list.len() - MAX_BOXES_PER_SAMPLE) as u64;
                list.sort_by(|a, b| b.tracking_score.total_cmp(&a.tracking_score));
                list.truncate(MAX_BOXES_PER_SAMPLE);
            }
            self.boxes += list.len() as u64;
        }
        self.samples = results.len() as u64;
        if self.dropped_over_cap > 0 {
            self.warnings.push(format!(
                "{} samples had more than {MAX_BOXES_PER_SAMPLE} boxes; dropped their {} \
                 lowest-scoring boxes",
                self.samples_over_cap, self.dropped_over_cap
            ));
        }
    }

    /// A warning listing the boxes skipped for their label, if any.
    fn skipped_warning(&mut self) {
        if self.skipped_labels.is_empty() {
            return;
        }
        let parts: Vec<String> = self
            .skipped_labels
            .iter()
            .map(|(l, n)| format!("{} {n}", if l.is_empty() { "(empty)" } else { l }))
            .collect();
        self.warnings.push(format!(
            "skipped {} boxes whose label is not a tracking class ({}): {}",
            self.skipped_labels.values().sum::<u64>(),
            NUSCENES_CLASSES.join(", "),
            parts.join(", ")
        ));
    }
}

pub(crate) fn tracking_box(t: &Track3D, sample_token: &str) -> Result<TrackingBox> {
    let c = t.center.context("the track has no center")?;
    let s = t.size.context("the track has no size")?;
    let v = t.velocity.unwrap_or_default();
    if t.score.is_nan() {
        bail!("tracking_score is NaN (the devkit refuses NaN scores)");
    }
    let b = TrackingBox {
        sample_token: sample_token.to_string(),
        translation: [c.x, c.y, c.z],
        size: [s.width, s.length, s.height],
        rotation: yaw_quaternion(t.yaw),
        velocity: [v.x, v.y],
        tracking_id: t.id.to_string(),
        tracking_name: t.label.clone(),
        tracking_score: t.score,
    };
    let nums = b
        .translation
        .iter()
        .chain(&b.size)
        .chain(&b.rotation)
        .chain(&b.velocity)
        .chain(std::iter::once(&b.tracking_score));
    if nums.clone().any(|x| !x.is_finite()) {
        bail!(
            "non-finite number (translation {:?}, size {:?}, yaw {}, velocity {:?}, score {}); \
             JSON cannot hold it",
            b.translation,
            b.size,
            t.yaw,
            b.velocity,
            b.tracking_score
        );
    }
    Ok(b)
}

#[cfg(test)]
mod tests {
    use super::super::nusc_size;
    use super::super::quaternion_yaw;
    use super::*;
    use crate::msgs::v3;

    #[test]
    fn box_round_trip() {
        let t = Track3D {
            id: 7,
            label: "car".into(),
            center: Some(v3([601.5, 1640.25, 1.0])),
            size: Some(nusc_size([1.9, 4.5, 1.65])),
            yaw: quaternion_yaw([0.9, 0.0, 0.0, -0.435_889_894_354_067_4]),
            velocity: Some(v3([1.0, -2.0, 0.5])),
            score: 0.5,
            ..Default::default()
        };
        let b = tracking_box(&t, "tok").unwrap();
        assert_eq!(b.size, [1.9, 4.5, 1.65]);
        assert_eq!(b.translation, [601.5, 1640.25, 1.0]);
        assert_eq!(b.velocity, [1.0, -2.0]);
        assert_eq!(b.tracking_id, "7");
        for (a, e) in b
            .rotation
            .iter()
            .zip([0.9, 0.0, 0.0, -0.435_889_894_354_067_4])
        {
            assert!((a - e).abs() < 1e-12);
        }
        let nan = Track3D {
            score: f64::NAN,
            ..t.clone()
        };
        assert!(tracking_box(&nan, "tok").is_err());
        let inf = Track3D {
            center: Some(v3([f64::INFINITY, 0.0, 0.0])),
            ..t
        };
        assert!(tracking_box(&inf, "tok").is_err());
    }
}
