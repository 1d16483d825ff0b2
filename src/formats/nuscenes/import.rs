//! `probmot import nuscenes`: tables and results checked and planned into one MCAP per scene.

use std::collections::{BTreeMap, HashMap, HashSet};
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use serde::Serialize;

use crate::mcapio::writer::check_output_path;
use crate::msgs;
use crate::msgs::size3;

use super::results::{read_results, DetectionResults};
use super::scene_file::write_scene;
use super::tables::{
    read_all, read_table, AnnotationRow, CalibratedSensorRow, CategoryRow, EgoPoseRow, InstanceRow,
    SampleDataRow, SampleRow, SceneRow, SensorRow,
};
use super::tracks::{read_tracking_results, RackAnn};
use super::{tracking_name, BIKE_RACK_CATEGORY};

// ---------------------------------------------------------------------------------------------
// Import

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

/// Counts of one written scene.
#[derive(Debug, Clone, Default, Serialize)]
pub struct SceneSummary {
    /// Scene name.
    pub name: String,
    /// Output file.
    pub output: String,
    /// Frames (samples).
    pub frames: u64,
    /// Detections written.
    pub detections: u64,
    /// Ground-truth boxes written.
    pub truth_boxes: u64,
    /// Ego poses written.
    pub ego_poses: u64,
    /// Track boxes written.
    pub tracks: u64,
    /// Bicycle-rack boxes written.
    pub bike_racks: u64,
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

/// One scene to write.
pub(crate) struct ScenePlan {
    pub(crate) scene: SceneRow,
    /// `(sample token, timestamp µs)` in time order.
    pub(crate) samples: Vec<(String, u64)>,
    pub(crate) output: PathBuf,
}

/// Ground-truth box of one sample.
pub(crate) struct TruthBox {
    pub(crate) id: u64,
    pub(crate) label: &'static str,
    pub(crate) ann: AnnotationRow,
    pub(crate) category: String,
    pub(crate) velocity: [f64; 3],
}

pub(crate) fn file_name_of(scene: &str) -> String {
    let s: String = scene
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.') {
                c
            } else {
                '_'
            }
        })
        .collect();
    format!("{s}.mcap")
}

pub(crate) fn table(dir: &Path, name: &str) -> PathBuf {
    dir.join(name)
}

/// Walks a scene's sample chain, checking it against the tables.
pub(crate) fn scene_samples(
    meta: &Path,
    scene: &SceneRow,
    samples: &HashMap<String, SampleRow>,
) -> Result<Vec<(String, u64)>> {
    let sample_json = table(meta, "sample.json");
    let mut out: Vec<(String, u64)> = Vec::new();
    let mut token = scene.first_sample_token.clone();
    let mut prev_token = String::new();
    while !token.is_empty() {
        let s = samples.get(&token).with_context(|| {
            if prev_token.is_empty() {
                format!(
                    "{}: no sample {token} (first_sample_token of scene {} {})",
                    sample_json.display(),
                    scene.name,
                    scene.token
                )
            } else {
                format!(
                    "{}: no sample {token} (next of sample {prev_token} in scene {})",
                    sample_json.display(),
                    scene.name
                )
            }
        })?;
        if s.scene_token != scene.token {
            bail!(
                "{}: sample {token} is in the chain of scene {} ({}) but has scene_token {}",
                sample_json.display(),
                scene.name,
                scene.token,
                s.scene_token
            );
        }
        if let Some(&(_, t_prev)) = out.last() {
            if s.timestamp <= t_prev {
                bail!(
                    "{}: sample {token} (timestamp {}) does not come after sample {prev_token} \
                     (timestamp {t_prev}) in scene {}",
                    sample_json.display(),
                    s.timestamp,
                    scene.name
                );
            }
        }
        if out.len() > samples.len() {
            bail!(
                "{}: the sample chain of scene {} loops",
                sample_json.display(),
                scene.name
            );
        }
        out.push((token.clone(), s.timestamp));
        prev_token = std::mem::replace(&mut token, s.next.clone());
    }
    if let Some(last) = &scene.last_sample_token {
        if *last != prev_token {
            bail!(
                "{}: scene {} ({}) has last_sample_token {last}, but its sample chain ends at {}",
                table(meta, "scene.json").display(),
                scene.name,
                scene.token,
                prev_token
            );
        }
    }
    if let Some(n) = scene.nbr_samples {
        if n != out.len() as u64 {
            bail!(
                "{}: scene {} ({}) has nbr_samples {n}, but its sample chain holds {} samples",
                table(meta, "scene.json").display(),
                scene.name,
                scene.token,
                out.len()
            );
        }
    }
    Ok(out)
}

/// Velocity of an annotation the way the devkit's `box_velocity` computes it (centre difference
/// of the previous and next annotations over their time difference, at most 1.5 s per side);
/// zero where it is undefined.
pub(crate) fn truth_velocity(
    ann: &AnnotationRow,
    anns: &HashMap<String, AnnotationRow>,
    time_us: &HashMap<String, u64>,
) -> [f64; 3] {
    let prev = anns.get(&ann.prev);
    let next = anns.get(&ann.next);
    if prev.is_none() && next.is_none() {
        return [0.0; 3];
    }
    let first = prev.unwrap_or(ann);
    let last = next.unwrap_or(ann);
    let (Some(&t0), Some(&t1)) = (
        time_us.get(&first.sample_token),
        time_us.get(&last.sample_token),
    ) else {
        return [0.0; 3];
    };
    let dt = (t1 as f64 - t0 as f64) * 1e-6;
    let max_dt = if prev.is_some() && next.is_some() {
        3.0
    } else {
        1.5
    };
    if dt <= 0.0 || dt > max_dt {
        return [0.0; 3];
    }
    let d = |i: usize| (last.translation[i] - first.translation[i]) / dt;
    [d(0), d(1), d(2)]
}

pub(crate) fn attrs(pairs: &[(&str, String)]) -> BTreeMap<String, String> {
    pairs
        .iter()
        .map(|(k, v)| (k.to_string(), v.clone()))
        .collect()
}

/// `[w, l, h]` -> probmot size.
pub(crate) fn nusc_size(s: [f64; 3]) -> msgs::Size3 {
    size3([s[1], s[0], s[2]])
}

#[derive(Serialize)]
pub(crate) struct EgoPoseMsg {
    pub(crate) stamp: u64,
    pub(crate) translation: [f64; 3],
    pub(crate) rotation: [f64; 4],
}

/// Imports a detection results file: one MCAP per scene in `opts.out_dir`, with `/detections`,
/// `/ground_truth` (when `sample_annotation.json` is present), `/ego_pose` (when
/// `sample_data.json` and `ego_pose.json` are present) and the metadata records
/// [`NUSCENES_METADATA`] and [`SAMPLES_METADATA`]. Every table is read and checked before any
/// file is written.
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
    if opts.detections.is_none() && opts.tracks.is_none() {
        bail!("give --detections, --tracks or both");
    }
    let results = match &opts.detections {
        Some(p) => read_results(p)?,
        None => DetectionResults::default(),
    };
    let tracking = match &opts.tracks {
        Some(p) => Some(read_tracking_results(p)?),
        None => None,
    };
    let det_file = opts
        .detections
        .as_ref()
        .map(|p| p.display().to_string())
        .unwrap_or_default();
    let trk_file = opts
        .tracks
        .as_ref()
        .map(|p| p.display().to_string())
        .unwrap_or_default();

    let samples: HashMap<String, SampleRow> = read_all::<SampleRow>(&table(meta, "sample.json"))?
        .into_iter()
        .map(|s| (s.token.clone(), s))
        .collect();
    let scenes: Vec<SceneRow> = read_all(&table(meta, "scene.json"))?;
    let scene_by_token: HashMap<&str, &SceneRow> =
        scenes.iter().map(|s| (s.token.as_str(), s)).collect();

    // Every results token must be a sample of the tables.
    let mut result_tokens: Vec<(&String, &str)> = results
        .boxes
        .keys()
        .map(|k| (k, det_file.as_str()))
        .chain(
            tracking
                .iter()
                .flat_map(|t| t.results.keys().map(|k| (k, trk_file.as_str()))),
        )
        .collect();
    result_tokens.sort();
    let mut scenes_with_results: HashSet<&str> = HashSet::new();
    for (tok, file) in &result_tokens {
        let s = samples.get(*tok).with_context(|| {
            format!(
                "{file}: sample token {tok} is not in {}",
                table(meta, "sample.json").display()
            )
        })?;
        if !scene_by_token.contains_key(s.scene_token.as_str()) {
            bail!(
                "{}: sample {tok} has scene_token {}, which is not in {}",
                table(meta, "sample.json").display(),
                s.scene_token,
                table(meta, "scene.json").display()
            );
        }
        scenes_with_results.insert(s.scene_token.as_str());
    }

    // The scenes to write.
    let chosen: Vec<&SceneRow> = if opts.scenes.is_empty() {
        let v: Vec<&SceneRow> = scenes
            .iter()
            .filter(|s| scenes_with_results.contains(s.token.as_str()))
            .collect();
        if v.is_empty() {
            bail!(
                "{}: the results hold no sample",
                if det_file.is_empty() {
                    &trk_file
                } else {
                    &det_file
                }
            );
        }
        v
    } else {
        let mut v = Vec::new();
        for name in &opts.scenes {
            let s = scenes.iter().find(|s| s.name == *name).with_context(|| {
                format!(
                    "no scene named {name} in {}",
                    table(meta, "scene.json").display()
                )
            })?;
            if !v.iter().any(|x: &&SceneRow| x.token == s.token) {
                v.push(s);
            }
        }
        v
    };
    std::fs::create_dir_all(&opts.out_dir)
        .with_context(|| format!("cannot create {}", opts.out_dir.display()))?;
    let mut plans: Vec<ScenePlan> = Vec::new();
    let mut outputs: HashSet<PathBuf> = HashSet::new();
    for scene in chosen {
        let list = scene_samples(meta, scene, &samples)?;
        let output = opts.out_dir.join(file_name_of(&scene.name));
        if !outputs.insert(output.clone()) {
            bail!(
                "two scenes would both be written to {} (scene names must be unique)",
                output.display()
            );
        }
        check_output_path(None, &output)?;
        let missing = list
            .iter()
            .filter(|(t, _)| !results.boxes.contains_key(t))
            .count();
        if missing > 0 && opts.detections.is_some() {
            summary.warnings.push(format!(
                "{det_file}: {missing} of the {} samples of scene {} are not in the results; \
                 written as frames without detections",
                list.len(),
                scene.name
            ));
        }
        if let Some(t) = &tracking {
            let missing = list
                .iter()
                .filter(|(tok, _)| !t.results.contains_key(tok))
                .count();
            if missing > 0 {
                summary.warnings.push(format!(
                    "{trk_file}: {missing} of the {} samples of scene {} are not in the \
                     submission; written as frames without tracks",
                    list.len(),
                    scene.name
                ));
            }
        }
        plans.push(ScenePlan {
            scene: scene.clone(),
            samples: list,
            output,
        });
    }
    let wanted: HashSet<&str> = plans
        .iter()
        .flat_map(|p| p.samples.iter().map(|(t, _)| t.as_str()))
        .collect();
    let time_us: HashMap<String, u64> = plans
        .iter()
        .flat_map(|p| p.samples.iter().cloned())
        .collect();
    drop(samples);

    // Ground truth.
    let ann_path = table(meta, "sample_annotation.json");
    let mut truth: HashMap<String, Vec<TruthBox>> = HashMap::new();
    let mut racks: HashMap<String, Vec<RackAnn>> = HashMap::new();
    if ann_path.is_file() {
        summary.ground_truth = true;
        for need in ["instance.json", "category.json"] {
            if !table(meta, need).is_file() {
                bail!(
                    "{} is present but {} is missing (needed to name the classes of the ground \
                     truth)",
                    ann_path.display(),
                    table(meta, need).display()
                );
            }
        }
        let instances: Vec<InstanceRow> = read_all(&table(meta, "instance.json"))?;
        let categories: HashMap<String, String> =
            read_all::<CategoryRow>(&table(meta, "category.json"))?
                .into_iter()
                .map(|c| (c.token, c.name))
                .collect();
        let instance_index: HashMap<&str, (usize, &str)> = instances
            .iter()
            .enumerate()
            .map(|(i, r)| (r.token.as_str(), (i, r.category_token.as_str())))
            .collect();
        let anns: Vec<AnnotationRow> = read_table(&ann_path, |a: &AnnotationRow| {
            wanted.contains(a.sample_token.as_str())
        })?;
        let by_token: HashMap<String, AnnotationRow> =
            anns.iter().map(|a| (a.token.clone(), a.clone())).collect();
        for a in anns {
            let &(idx, cat_tok) =
                instance_index
                    .get(a.instance_token.as_str())
                    .with_context(|| {
                        format!(
                            "{}: no instance {} (instance_token of sample_annotation {})",
                            table(meta, "instance.json").display(),
                            a.instance_token,
                            a.token
                        )
                    })?;
            let category = categories.get(cat_tok).with_context(|| {
                format!(
                    "{}: no category {cat_tok} (category_token of instance {})",
                    table(meta, "category.json").display(),
                    a.instance_token
                )
            })?;
            if category == BIKE_RACK_CATEGORY {
                racks
                    .entry(a.sample_token.clone())
                    .or_default()
                    .push(RackAnn {
                        id: idx as u64 + 1,
                        token: a.token,
                        translation: a.translation,
                        size: a.size,
                        rotation: a.rotation,
                    });
                continue;
            }
            let Some(label) = tracking_name(category) else {
                *summary.truth_skipped.entry(category.clone()).or_default() += 1;
                continue;
            };
            let velocity = truth_velocity(&a, &by_token, &time_us);
            truth
                .entry(a.sample_token.clone())
                .or_default()
                .push(TruthBox {
                    id: idx as u64 + 1,
                    label,
                    category: category.clone(),
                    velocity,
                    ann: a,
                });
        }
    }

    // Ego poses: the ego_pose of each sample's LIDAR_TOP key frame.
    let sd_path = table(meta, "sample_data.json");
    let ep_path = table(meta, "ego_pose.json");
    let mut ego: HashMap<String, EgoPoseRow> = HashMap::new();
    match (sd_path.is_file(), ep_path.is_file()) {
        (true, true) => {
            summary.ego_pose = true;
            let cs_path = table(meta, "calibrated_sensor.json");
            let sensor_path = table(meta, "sensor.json");
            // The channel of a sample_data record: from calibrated_sensor -> sensor when those
            // tables exist, else from the file name (`samples/LIDAR_TOP/...`).
            let lidar_cs: Option<HashSet<String>> = if cs_path.is_file() && sensor_path.is_file() {
                let lidar: HashSet<String> = read_all::<SensorRow>(&sensor_path)?
                    .into_iter()
                    .filter(|s| s.channel == "LIDAR_TOP")
                    .map(|s| s.token)
                    .collect();
                Some(
                    read_all::<CalibratedSensorRow>(&cs_path)?
                        .into_iter()
                        .filter(|c| lidar.contains(&c.sensor_token))
                        .map(|c| c.token)
                        .collect(),
                )
            } else {
                None
            };
            let sd: Vec<SampleDataRow> = read_table(&sd_path, |r: &SampleDataRow| {
                r.is_key_frame
                    && wanted.contains(r.sample_token.as_str())
                    && match &lidar_cs {
                        Some(set) => set.contains(&r.calibrated_sensor_token),
                        None => r.filename.starts_with("samples/LIDAR_TOP/"),
                    }
            })?;
            let mut lidar_of: HashMap<String, SampleDataRow> = HashMap::new();
            for r in sd {
                if let Some(prev) = lidar_of.get(&r.sample_token) {
                    bail!(
                        "{}: sample {} has two LIDAR_TOP key frames ({} and {})",
                        sd_path.display(),
                        r.sample_token,
                        prev.token,
                        r.token
                    );
                }
                lidar_of.insert(r.sample_token.clone(), r);
            }
            let needed: HashSet<&str> = lidar_of
                .values()
                .map(|r| r.ego_pose_token.as_str())
                .collect();
            let poses: HashMap<String, EgoPoseRow> =
                read_table(&ep_path, |p: &EgoPoseRow| needed.contains(p.token.as_str()))?
                    .into_iter()
                    .map(|p| (p.token.clone(), p))
                    .collect();
            let mut wanted_sorted: Vec<&str> = wanted.iter().copied().collect();
            wanted_sorted.sort();
            for tok in wanted_sorted {
                let sd = lidar_of.get(tok).with_context(|| {
                    format!(
                        "{}: no LIDAR_TOP key frame for sample {tok}",
                        sd_path.display()
                    )
                })?;
                let pose = poses.get(&sd.ego_pose_token).with_context(|| {
                    format!(
                        "{}: no ego pose {} (ego_pose_token of sample_data {})",
                        ep_path.display(),
                        sd.ego_pose_token,
                        sd.token
                    )
                })?;
                ego.insert(tok.to_string(), pose.clone());
            }
        }
        (true, false) | (false, true) => summary.warnings.push(format!(
            "{} needs {}; no /ego_pose channel written",
            if sd_path.is_file() {
                sd_path.display()
            } else {
                ep_path.display()
            },
            if sd_path.is_file() {
                ep_path.display()
            } else {
                sd_path.display()
            }
        )),
        (false, false) => {}
    }

    // Write.
    let results_meta = results
        .meta
        .as_ref()
        .map(|m| m.to_string())
        .unwrap_or_default();
    for plan in &plans {
        let s = write_scene(
            plan,
            opts.detections.is_some().then_some(&results),
            tracking.as_ref(),
            summary.ground_truth.then_some((&truth, &racks)),
            summary.ego_pose.then_some(&ego),
            (&det_file, &trk_file),
            &results_meta,
        )?;
        summary.tracks += s.tracks;
        summary.bike_racks += s.bike_racks;
        summary.frames += s.frames;
        summary.detections += s.detections;
        summary.truth_boxes += s.truth_boxes;
        summary.ego_poses += s.ego_poses;
        summary.scenes.push(s);
    }
    if !summary.truth_skipped.is_empty() {
        let parts: Vec<String> = summary
            .truth_skipped
            .iter()
            .map(|(c, n)| format!("{c} {n}"))
            .collect();
        summary.warnings.push(format!(
            "skipped {} ground-truth boxes outside the seven tracking classes: {}",
            summary.truth_skipped.values().sum::<u64>(),
            parts.join(", ")
        ));
    }
    Ok(summary)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn velocity_like_the_devkit() {
        let row = |tok: &str, s: &str, x: f64, prev: &str, next: &str| AnnotationRow {
            token: tok.into(),
            sample_token: s.into(),
            instance_token: "i".into(),
            translation: [x, 0.0, 0.0],
            size: [1.0; 3],
            rotation: [1.0, 0.0, 0.0, 0.0],
            prev: prev.into(),
            next: next.into(),
            num_lidar_pts: None,
            num_radar_pts: None,
        };
        let anns: HashMap<String, AnnotationRow> = [
            row("a", "s1", 0.0, "", "b"),
            row("b", "s2", 1.0, "a", "c"),
            row("c", "s3", 3.0, "b", ""),
            row("d", "s4", 9.0, "", ""),
        ]
        .into_iter()
        .map(|r| (r.token.clone(), r))
        .collect();
        let t: HashMap<String, u64> = [("s1", 0), ("s2", 500_000), ("s3", 1_000_000)]
            .into_iter()
            .map(|(k, v)| (k.to_string(), v))
            .collect();
        assert_eq!(truth_velocity(&anns["a"], &anns, &t), [2.0, 0.0, 0.0]);
        assert_eq!(truth_velocity(&anns["b"], &anns, &t), [3.0, 0.0, 0.0]);
        assert_eq!(truth_velocity(&anns["c"], &anns, &t), [4.0, 0.0, 0.0]);
        assert_eq!(truth_velocity(&anns["d"], &anns, &t), [0.0; 3]);
    }
}
