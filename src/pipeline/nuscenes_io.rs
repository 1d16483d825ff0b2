//! `probmot import nuscenes` and `probmot export nuscenes`.
//!
//! Import turns a detection submission (`results.json`, the nuScenes detection result format)
//! and the dataset's metadata tables (`sample.json`, `scene.json`, ...) into one MCAP file per
//! scene. Export writes `Tracks3D` channels of such files as a tracking submission.
//!
//! Conventions (nuScenes -> probmot):
//! - boxes stay in the global frame (`frame_id` [`FRAME_ID`]), centre = `translation`;
//! - `size` `[w, l, h]` -> `Size3 { length: l, width: w, height: h }`;
//! - `rotation` quaternion `[w, x, y, z]` -> yaw about +z, the heading of the box's x axis
//!   projected on the ground plane (the devkit's `quaternion_yaw`); export writes the pure-yaw
//!   quaternion `[cos(yaw/2), 0, 0, sin(yaw/2)]`;
//! - a frame per sample, stamp = sample `timestamp` (µs) × 1000 ns.

use std::collections::{BTreeMap, HashMap, HashSet};
use std::fmt;
use std::fs::File;
use std::io::BufReader;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use mcap::records::{MessageHeader, Metadata, Record};
use serde::de::{DeserializeOwned, DeserializeSeed, IgnoredAny, MapAccess, SeqAccess, Visitor};
use serde::{Deserialize, Deserializer, Serialize};

use crate::mcapio::topic::for_each_message;
use crate::mcapio::writer::{check_output_path, write_file_atomic, AtomicOutput, OutputOptions};
use crate::msgs::{self, v3, Detection3D, Detections3D, Track3D, Tracks3D};
use crate::sim::write::size3;
use crate::tracker::config::NUSCENES_CLASSES;

use super::nuscenes_tracks::{
    rack_track, read_tracking_results, track_of, RackAnn, TrackIds, TrackingResults,
};

/// Metadata record with the scene: `scene_token`, `scene_name`, `scene_description`,
/// `nbr_samples`, `detections_file`, `ground_truth` (`true`/`false`), `ego_pose` (`true`/`false`).
pub const NUSCENES_METADATA: &str = "probmot.nuscenes";
/// Metadata record mapping each frame stamp (ns, decimal) to its sample token.
pub const SAMPLES_METADATA: &str = "probmot.nuscenes.samples";
pub use crate::msgs::EGO_POSE_SCHEMA;
/// JSON schema of an `/ego_pose` message.
pub const EGO_POSE_JSON_SCHEMA: &str = r#"{"$schema":"https://json-schema.org/draft/2020-12/schema","title":"probmot.EgoPose","description":"Ego vehicle pose of a nuScenes sample, from the ego_pose record of the sample's LIDAR_TOP key frame (global frame).","type":"object","properties":{"stamp":{"type":"integer","description":"Frame stamp, ns (sample timestamp * 1000)"},"translation":{"type":"array","items":{"type":"number"},"minItems":3,"maxItems":3,"description":"x, y, z, metres"},"rotation":{"type":"array","items":{"type":"number"},"minItems":4,"maxItems":4,"description":"quaternion w, x, y, z"}},"required":["stamp","translation","rotation"]}"#;
/// Coordinate frame of every box written by the import.
pub const FRAME_ID: &str = "nuscenes_global";
/// The devkit's limit of boxes per sample.
pub const MAX_BOXES_PER_SAMPLE: usize = 500;

/// Attributes that carry nuScenes fields the box does not hold.
pub mod attr {
    /// Sample token of the frame (detections and ground truth).
    pub const SAMPLE_TOKEN: &str = "nuscenes_sample_token";
    /// `attribute_name` of a detection.
    pub const ATTRIBUTE_NAME: &str = "nuscenes_attribute_name";
    /// Instance token of a ground-truth box.
    pub const INSTANCE_TOKEN: &str = "nuscenes_instance_token";
    /// Annotation token of a ground-truth box.
    pub const ANNOTATION_TOKEN: &str = "nuscenes_annotation_token";
    /// Full category name of a ground-truth box, e.g. `human.pedestrian.adult`.
    pub const CATEGORY: &str = "nuscenes_category";
    /// Lidar points in a ground-truth box.
    pub const NUM_LIDAR_PTS: &str = "nuscenes_num_lidar_pts";
    /// Radar points in a ground-truth box.
    pub const NUM_RADAR_PTS: &str = "nuscenes_num_radar_pts";
    /// The annotation's full rotation quaternion `[w, x, y, z]` as a JSON array (bicycle racks:
    /// the devkit's in-rack test uses the whole rotation, not only the yaw).
    pub const ROTATION: &str = "nuscenes_rotation";
    /// Original `tracking_id` of a box of an imported tracking submission.
    pub const TRACKING_ID: &str = "nuscenes_tracking_id";
}

/// Category of the bicycle racks whose bicycles and motorcycles the devkit leaves out.
pub const BIKE_RACK_CATEGORY: &str = "static_object.bicycle_rack";
/// Channel of the bicycle-rack boxes (`probmot.Tracks3D`, label [`BIKE_RACK_LABEL`]).
pub const BIKE_RACKS_TOPIC: &str = "/bicycle_racks";
/// Label of a bicycle-rack box.
pub const BIKE_RACK_LABEL: &str = "bicycle_rack";

/// The tracking class of a nuScenes category, as the devkit maps it
/// (`category_to_tracking_name`); `None` for categories outside the seven classes.
pub fn tracking_name(category: &str) -> Option<&'static str> {
    Some(match category {
        "vehicle.bicycle" => "bicycle",
        "vehicle.bus.bendy" | "vehicle.bus.rigid" => "bus",
        "vehicle.car" => "car",
        "vehicle.motorcycle" => "motorcycle",
        "human.pedestrian.adult"
        | "human.pedestrian.child"
        | "human.pedestrian.construction_worker"
        | "human.pedestrian.police_officer" => "pedestrian",
        "vehicle.trailer" => "trailer",
        "vehicle.truck" => "truck",
        _ => return None,
    })
}

/// Yaw about +z of a quaternion `[w, x, y, z]`: the direction of the rotated x axis projected on
/// the ground plane. The quaternion need not be normalised.
pub fn quaternion_yaw(q: [f64; 4]) -> f64 {
    let [w, x, y, z] = q;
    (2.0 * (w * z + x * y)).atan2(w * w + x * x - y * y - z * z)
}

/// The rotation about +z by `yaw` as a quaternion `[w, x, y, z]`.
pub fn yaw_quaternion(yaw: f64) -> [f64; 4] {
    let (s, c) = (yaw / 2.0).sin_cos();
    [c, 0.0, 0.0, s]
}

// ---------------------------------------------------------------------------------------------
// Tables

#[derive(Debug, Clone, Deserialize)]
struct SampleRow {
    token: String,
    timestamp: u64,
    scene_token: String,
    #[serde(default)]
    next: String,
}

#[derive(Debug, Clone, Deserialize)]
struct SceneRow {
    token: String,
    name: String,
    #[serde(default)]
    description: String,
    nbr_samples: Option<u64>,
    first_sample_token: String,
    last_sample_token: Option<String>,
}

#[derive(Debug, Clone, Deserialize)]
struct AnnotationRow {
    token: String,
    sample_token: String,
    instance_token: String,
    translation: [f64; 3],
    size: [f64; 3],
    rotation: [f64; 4],
    #[serde(default)]
    prev: String,
    #[serde(default)]
    next: String,
    num_lidar_pts: Option<i64>,
    num_radar_pts: Option<i64>,
}

#[derive(Debug, Clone, Deserialize)]
struct InstanceRow {
    token: String,
    category_token: String,
}

#[derive(Debug, Clone, Deserialize)]
struct CategoryRow {
    token: String,
    name: String,
}

#[derive(Debug, Clone, Deserialize)]
struct SampleDataRow {
    token: String,
    sample_token: String,
    ego_pose_token: String,
    #[serde(default)]
    calibrated_sensor_token: String,
    #[serde(default)]
    filename: String,
    #[serde(default)]
    is_key_frame: bool,
}

#[derive(Debug, Clone, Deserialize)]
struct EgoPoseRow {
    token: String,
    translation: [f64; 3],
    rotation: [f64; 4],
}

#[derive(Debug, Clone, Deserialize)]
struct CalibratedSensorRow {
    token: String,
    sensor_token: String,
}

#[derive(Debug, Clone, Deserialize)]
struct SensorRow {
    token: String,
    channel: String,
}

/// Visits a JSON array, keeping the records `keep` accepts (big tables are never held whole).
struct FilterSeq<'a, T, F> {
    keep: &'a mut F,
    out: &'a mut Vec<T>,
}

impl<'de, T, F> Visitor<'de> for FilterSeq<'_, T, F>
where
    T: Deserialize<'de>,
    F: FnMut(&T) -> bool,
{
    type Value = ();

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("a JSON array of records")
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<(), A::Error> {
        while let Some(row) = seq.next_element::<T>()? {
            if (self.keep)(&row) {
                self.out.push(row);
            }
        }
        Ok(())
    }
}

/// Reads a nuScenes table (a JSON array of records), keeping the records `keep` accepts.
fn read_table<T, F>(path: &Path, mut keep: F) -> Result<Vec<T>>
where
    T: DeserializeOwned,
    F: FnMut(&T) -> bool,
{
    let file = File::open(path).with_context(|| format!("cannot read {}", path.display()))?;
    let mut de = serde_json::Deserializer::from_reader(BufReader::with_capacity(1 << 20, file));
    let mut out = Vec::new();
    de.deserialize_seq(FilterSeq {
        keep: &mut keep,
        out: &mut out,
    })
    .and_then(|()| de.end())
    .with_context(|| format!("{}: not a readable nuScenes table", path.display()))?;
    Ok(out)
}

fn read_all<T: DeserializeOwned>(path: &Path) -> Result<Vec<T>> {
    read_table(path, |_: &T| true)
}

// ---------------------------------------------------------------------------------------------
// Detection results

/// One detection box of the results file, compact (tokens and names interned).
#[derive(Debug, Clone)]
struct DetBox {
    translation: [f64; 3],
    size: [f64; 3],
    rotation: [f64; 4],
    velocity: [f64; 2],
    score: f64,
    name: u32,
    attribute: u32,
}

#[derive(Debug, Deserialize)]
struct RawDetBox {
    sample_token: String,
    translation: [f64; 3],
    size: [f64; 3],
    rotation: [f64; 4],
    velocity: Option<[f64; 2]>,
    detection_name: String,
    detection_score: f64,
    #[serde(default)]
    attribute_name: String,
}

#[derive(Debug, Default)]
struct Interner {
    names: Vec<String>,
    index: HashMap<String, u32>,
}

impl Interner {
    fn get(&mut self, s: String) -> u32 {
        if let Some(&i) = self.index.get(&s) {
            return i;
        }
        let i = self.names.len() as u32;
        self.names.push(s.clone());
        self.index.insert(s, i);
        i
    }
}

/// The results file: boxes per sample token (a key with an empty list is kept).
#[derive(Debug, Default)]
struct DetectionResults {
    meta: Option<serde_json::Value>,
    boxes: HashMap<String, Vec<DetBox>>,
    strings: Interner,
    /// A box whose `sample_token` differs from its key: `(key, box token)`.
    mismatch: Option<(String, String)>,
}

struct ResultsVisitor<'a>(&'a mut DetectionResults);

impl<'de> Visitor<'de> for ResultsVisitor<'_> {
    type Value = ();
    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str(r#"an object {"meta": {...}, "results": {sample_token: [box, ...]}}"#)
    }
    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<(), A::Error> {
        let mut seen_results = false;
        while let Some(key) = map.next_key::<String>()? {
            match key.as_str() {
                "meta" => self.0.meta = Some(map.next_value()?),
                "results" => {
                    map.next_value_seed(SamplesSeed(&mut *self.0))?;
                    seen_results = true;
                }
                _ => {
                    map.next_value::<IgnoredAny>()?;
                }
            }
        }
        if !seen_results {
            return Err(serde::de::Error::missing_field("results"));
        }
        Ok(())
    }
}

struct SamplesSeed<'a>(&'a mut DetectionResults);

impl<'de> DeserializeSeed<'de> for SamplesSeed<'_> {
    type Value = ();
    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        d.deserialize_map(self)
    }
}

impl<'de> Visitor<'de> for SamplesSeed<'_> {
    type Value = ();
    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("an object {sample_token: [box, ...]}")
    }
    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<(), A::Error> {
        while let Some(token) = map.next_key::<String>()? {
            let mut boxes = Vec::new();
            map.next_value_seed(BoxesSeed {
                key: &token,
                res: &mut *self.0,
                out: &mut boxes,
            })?;
            self.0.boxes.entry(token).or_default().extend(boxes);
        }
        Ok(())
    }
}

struct BoxesSeed<'a> {
    key: &'a str,
    res: &'a mut DetectionResults,
    out: &'a mut Vec<DetBox>,
}

impl<'de> DeserializeSeed<'de> for BoxesSeed<'_> {
    type Value = ();
    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        d.deserialize_seq(self)
    }
}

impl<'de> Visitor<'de> for BoxesSeed<'_> {
    type Value = ();
    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("a list of detection boxes")
    }
    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<(), A::Error> {
        while let Some(b) = seq.next_element::<RawDetBox>()? {
            if b.sample_token != self.key && self.res.mismatch.is_none() {
                self.res.mismatch = Some((self.key.to_string(), b.sample_token.clone()));
            }
            let name = self.res.strings.get(b.detection_name);
            let attribute = self.res.strings.get(b.attribute_name);
            self.out.push(DetBox {
                translation: b.translation,
                size: b.size,
                rotation: b.rotation,
                velocity: b.velocity.unwrap_or([0.0, 0.0]),
                score: b.detection_score,
                name,
                attribute,
            });
        }
        Ok(())
    }
}

fn read_results(path: &Path) -> Result<DetectionResults> {
    let file = File::open(path).with_context(|| format!("cannot read {}", path.display()))?;
    let mut de = serde_json::Deserializer::from_reader(BufReader::with_capacity(1 << 20, file));
    let mut res = DetectionResults::default();
    de.deserialize_map(ResultsVisitor(&mut res))
        .and_then(|()| de.end())
        .with_context(|| {
            format!(
                "{}: not a nuScenes detection results file (JSON {{\"meta\": ..., \"results\": \
                 {{sample_token: [box, ...]}}}}; NaN and Infinity are not JSON)",
                path.display()
            )
        })?;
    if let Some((key, tok)) = &res.mismatch {
        bail!(
            "{}: results[{key}] holds a box whose sample_token is {tok}",
            path.display()
        );
    }
    Ok(res)
}

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
struct ScenePlan {
    scene: SceneRow,
    /// `(sample token, timestamp µs)` in time order.
    samples: Vec<(String, u64)>,
    output: PathBuf,
}

/// Ground-truth box of one sample.
struct TruthBox {
    id: u64,
    label: &'static str,
    ann: AnnotationRow,
    category: String,
    velocity: [f64; 3],
}

fn file_name_of(scene: &str) -> String {
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

fn table(dir: &Path, name: &str) -> PathBuf {
    dir.join(name)
}

/// Walks a scene's sample chain, checking it against the tables.
fn scene_samples(
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
fn truth_velocity(
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

fn attrs(pairs: &[(&str, String)]) -> BTreeMap<String, String> {
    pairs
        .iter()
        .map(|(k, v)| (k.to_string(), v.clone()))
        .collect()
}

/// `[w, l, h]` -> probmot size.
fn nusc_size(s: [f64; 3]) -> msgs::Size3 {
    size3([s[1], s[0], s[2]])
}

#[derive(Serialize)]
struct EgoPoseMsg {
    stamp: u64,
    translation: [f64; 3],
    rotation: [f64; 4],
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

/// Ground truth and bicycle racks by sample token.
type TruthAndRacks<'a> = (
    &'a HashMap<String, Vec<TruthBox>>,
    &'a HashMap<String, Vec<RackAnn>>,
);

fn write_scene(
    plan: &ScenePlan,
    results: Option<&DetectionResults>,
    tracking: Option<&TrackingResults>,
    truth_racks: Option<TruthAndRacks>,
    ego: Option<&HashMap<String, EgoPoseRow>>,
    (det_file, trk_file): (&str, &str),
    results_meta: &str,
) -> Result<SceneSummary> {
    let truth = truth_racks.map(|t| t.0);
    let mut s = SceneSummary {
        name: plan.scene.name.clone(),
        output: plan.output.display().to_string(),
        frames: plan.samples.len() as u64,
        ..Default::default()
    };
    let mut out = AtomicOutput::create(&plan.output, &OutputOptions::default())?;
    let w = &mut out.writer;
    let none = BTreeMap::new();
    let c_det = match results {
        Some(_) => {
            let s_det = w.add_schema(msgs::DETECTIONS_SCHEMA, "protobuf", msgs::DESCRIPTOR_SET)?;
            Some(w.add_channel(s_det, "/detections", "protobuf", &none)?)
        }
        None => None,
    };
    let s_trk = if truth.is_some() || tracking.is_some() {
        Some(w.add_schema(msgs::TRACKS_SCHEMA, "protobuf", msgs::DESCRIPTOR_SET)?)
    } else {
        None
    };
    let mut tracks_channel = |topic: &str, on: bool| -> Result<Option<u16>> {
        match (s_trk, on) {
            (Some(schema), true) => Ok(Some(w.add_channel(schema, topic, "protobuf", &none)?)),
            _ => Ok(None),
        }
    };
    let c_gt = tracks_channel("/ground_truth", truth.is_some())?;
    let c_racks = tracks_channel(BIKE_RACKS_TOPIC, truth.is_some())?;
    let c_tracks = tracks_channel("/tracks", tracking.is_some())?;
    let c_ego = match ego {
        Some(_) => {
            let s_ego = w.add_schema(
                EGO_POSE_SCHEMA,
                "jsonschema",
                EGO_POSE_JSON_SCHEMA.as_bytes(),
            )?;
            Some(w.add_channel(s_ego, "/ego_pose", "json", &none)?)
        }
        None => None,
    };
    w.write_metadata(&Metadata {
        name: NUSCENES_METADATA.into(),
        metadata: attrs(&[
            ("scene_token", plan.scene.token.clone()),
            ("scene_name", plan.scene.name.clone()),
            ("scene_description", plan.scene.description.clone()),
            ("nbr_samples", plan.samples.len().to_string()),
            ("detections_file", det_file.to_string()),
            ("tracks_file", trk_file.to_string()),
            ("detections_meta", results_meta.to_string()),
            ("ground_truth", truth.is_some().to_string()),
            ("ego_pose", ego.is_some().to_string()),
        ]),
    })?;
    w.write_metadata(&Metadata {
        name: SAMPLES_METADATA.into(),
        metadata: plan
            .samples
            .iter()
            .map(|(tok, t)| ((t * 1000).to_string(), tok.clone()))
            .collect(),
    })?;
    let mut buf = Vec::new();
    let mut track_ids = TrackIds::default();
    for (frame, (tok, t_us)) in plan.samples.iter().enumerate() {
        let stamp = t_us * 1000;
        let header = |ch| MessageHeader {
            channel_id: ch,
            sequence: frame as u32,
            log_time: stamp,
            publish_time: stamp,
        };
        if let (Some(c_det), Some(results)) = (c_det, results) {
            let names = &results.strings.names;
            let boxes = results.boxes.get(tok).map(Vec::as_slice).unwrap_or(&[]);
            let msg = Detections3D {
                stamp: Some(stamp),
                frame_id: FRAME_ID.into(),
                detections: boxes
                    .iter()
                    .map(|b| Detection3D {
                        center: Some(v3(b.translation)),
                        size: Some(nusc_size(b.size)),
                        yaw: quaternion_yaw(b.rotation),
                        label: names[b.name as usize].clone(),
                        score: b.score,
                        velocity: Some(v3([b.velocity[0], b.velocity[1], 0.0])),
                        image_box: None,
                        attributes: attrs(&[
                            (attr::SAMPLE_TOKEN, tok.clone()),
                            (attr::ATTRIBUTE_NAME, names[b.attribute as usize].clone()),
                        ]),
                    })
                    .collect(),
            };
            s.detections += boxes.len() as u64;
            msgs::encode_into(&msg, &mut buf);
            w.write_to_known_channel(&header(c_det), &buf)?;
        }
        if let (Some(c_tracks), Some(tracking)) = (c_tracks, tracking) {
            let boxes = tracking.results.get(tok).map(Vec::as_slice).unwrap_or(&[]);
            let msg = Tracks3D {
                stamp,
                frame_id: FRAME_ID.into(),
                tracks: boxes.iter().map(|b| track_of(b, &mut track_ids)).collect(),
            };
            s.tracks += boxes.len() as u64;
            msgs::encode_into(&msg, &mut buf);
            w.write_to_known_channel(&header(c_tracks), &buf)?;
        }
        if let (Some(c_racks), Some((_, racks))) = (c_racks, truth_racks) {
            let boxes = racks.get(tok).map(Vec::as_slice).unwrap_or(&[]);
            let msg = Tracks3D {
                stamp,
                frame_id: FRAME_ID.into(),
                tracks: boxes.iter().map(|r| rack_track(r, tok)).collect(),
            };
            s.bike_racks += boxes.len() as u64;
            msgs::encode_into(&msg, &mut buf);
            w.write_to_known_channel(&header(c_racks), &buf)?;
        }
        if let (Some(c_gt), Some(truth)) = (c_gt, truth) {
            let boxes = truth.get(tok).map(Vec::as_slice).unwrap_or(&[]);
            let gt = Tracks3D {
                stamp,
                frame_id: FRAME_ID.into(),
                tracks: boxes
                    .iter()
                    .map(|b| Track3D {
                        id: b.id,
                        label: b.label.into(),
                        center: Some(v3(b.ann.translation)),
                        size: Some(nusc_size(b.ann.size)),
                        yaw: quaternion_yaw(b.ann.rotation),
                        velocity: Some(v3(b.velocity)),
                        score: 1.0,
                        attributes: attrs(&[
                            (attr::SAMPLE_TOKEN, tok.clone()),
                            (attr::INSTANCE_TOKEN, b.ann.instance_token.clone()),
                            (attr::ANNOTATION_TOKEN, b.ann.token.clone()),
                            (attr::CATEGORY, b.category.clone()),
                            (
                                attr::NUM_LIDAR_PTS,
                                b.ann
                                    .num_lidar_pts
                                    .map(|n| n.to_string())
                                    .unwrap_or_default(),
                            ),
                            (
                                attr::NUM_RADAR_PTS,
                                b.ann
                                    .num_radar_pts
                                    .map(|n| n.to_string())
                                    .unwrap_or_default(),
                            ),
                        ]),
                        ..Default::default()
                    })
                    .collect(),
            };
            s.truth_boxes += boxes.len() as u64;
            msgs::encode_into(&gt, &mut buf);
            w.write_to_known_channel(&header(c_gt), &buf)?;
        }
        if let (Some(c_ego), Some(ego)) = (c_ego, ego) {
            let pose = &ego[tok];
            let json = serde_json::to_vec(&EgoPoseMsg {
                stamp,
                translation: pose.translation,
                rotation: pose.rotation,
            })?;
            w.write_to_known_channel(&header(c_ego), &json)?;
            s.ego_poses += 1;
        }
    }
    out.commit()?;
    Ok(s)
}

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
struct ExportInput {
    scene: BTreeMap<String, String>,
    samples: BTreeMap<u64, String>,
    frames: Vec<(u64, Vec<Track3D>)>,
}

fn read_export_input(path: &Path, topic: &str) -> Result<ExportInput> {
    let file = path.display().to_string();
    let mut scene = None;
    let mut samples = None;
    let mut frames = Vec::new();
    for_each_message(
        path,
        topic,
        msgs::TRACKS_SCHEMA,
        |header, m: Tracks3D| {
            let stamp = if m.stamp != 0 {
                m.stamp
            } else {
                header.log_time
            };
            frames.push((stamp, m.tracks));
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
        bail!(
            "{file}: no metadata record {SAMPLES_METADATA} (the sample token of each frame); \
             export nuscenes needs a file written by `probmot import nuscenes` (or `probmot \
             track` of one)"
        );
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
        Some(dir) => {
            let samples: HashMap<String, SampleRow> =
                read_all::<SampleRow>(&table(dir, "sample.json"))?
                    .into_iter()
                    .map(|s| (s.token.clone(), s))
                    .collect();
            let scenes: Vec<SceneRow> = read_all(&table(dir, "scene.json"))?;
            Some((dir, samples, scenes))
        }
        None => None,
    };
    let mut summary = ExportSummary::default();
    let mut results: BTreeMap<String, Vec<TrackingBox>> = BTreeMap::new();
    let mut owner: HashMap<String, String> = HashMap::new();
    let classes: HashSet<&str> = NUSCENES_CLASSES.iter().copied().collect();
    for input in inputs {
        let file = input.display().to_string();
        let inp = read_export_input(input, &opts.topic)?;
        let scene_name = inp.scene.get("scene_name").cloned().unwrap_or_default();
        if let Some((dir, samples, scenes)) = &tables {
            let tok = inp.scene.get("scene_token").with_context(|| {
                format!("{file}: metadata {NUSCENES_METADATA} lacks scene_token")
            })?;
            let scene = scenes.iter().find(|s| s.token == *tok).with_context(|| {
                format!(
                    "{file}: scene {scene_name} ({tok}) is not in {}",
                    table(dir, "scene.json").display()
                )
            })?;
            let chain = scene_samples(dir, scene, samples)?;
            let want: BTreeMap<u64, String> =
                chain.into_iter().map(|(t, us)| (us * 1000, t)).collect();
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
        }
        summary.scenes += 1;
        for tok in inp.samples.values() {
            if let Some(other) = owner.insert(tok.clone(), file.clone()) {
                bail!("sample {tok} is in both {other} and {file}; give each scene once");
            }
            results.entry(tok.clone()).or_default();
        }
        let mut labels_of: HashMap<u64, String> = HashMap::new();
        let mut relabelled = 0u64;
        for (stamp, tracks) in inp.frames {
            let tok = inp.samples.get(&stamp).with_context(|| {
                format!(
                    "{file}: topic {}: a frame at stamp {stamp} ns is not a sample of the scene \
                     (metadata {SAMPLES_METADATA})",
                    opts.topic
                )
            })?;
            let list = results.get_mut(tok).expect("inserted above");
            for t in tracks {
                if !classes.contains(t.label.as_str()) {
                    *summary.skipped_labels.entry(t.label.clone()).or_default() += 1;
                    continue;
                }
                let b = tracking_box(&t, tok).with_context(|| {
                    format!(
                        "{file}: topic {}, stamp {stamp} (sample {tok}), track {}",
                        opts.topic, t.id
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
    }
    for list in results.values_mut() {
        if list.len() > MAX_BOXES_PER_SAMPLE {
            summary.samples_over_cap += 1;
            summary.dropped_over_cap += (list.len() - MAX_BOXES_PER_SAMPLE) as u64;
            list.sort_by(|a, b| b.tracking_score.total_cmp(&a.tracking_score));
            list.truncate(MAX_BOXES_PER_SAMPLE);
        }
        summary.boxes += list.len() as u64;
    }
    summary.samples = results.len() as u64;
    if summary.dropped_over_cap > 0 {
        summary.warnings.push(format!(
            "{} samples had more than {MAX_BOXES_PER_SAMPLE} boxes; dropped their {} \
             lowest-scoring boxes",
            summary.samples_over_cap, summary.dropped_over_cap
        ));
    }
    if !summary.skipped_labels.is_empty() {
        let parts: Vec<String> = summary
            .skipped_labels
            .iter()
            .map(|(l, n)| format!("{} {n}", if l.is_empty() { "(empty)" } else { l }))
            .collect();
        summary.warnings.push(format!(
            "skipped {} boxes whose label is not a tracking class ({}): {}",
            summary.skipped_labels.values().sum::<u64>(),
            NUSCENES_CLASSES.join(", "),
            parts.join(", ")
        ));
    }
    let sub = Submission {
        meta: opts.meta,
        results,
    };
    let bytes = serde_json::to_vec(&sub).context("serializing the submission")?;
    write_file_atomic(output, &bytes)?;
    Ok(summary)
}

fn tracking_box(t: &Track3D, sample_token: &str) -> Result<TrackingBox> {
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
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn yaw_from_quaternion() {
        for yaw in [-3.0, -PI / 2.0, -0.3, 0.0, 0.1, 1.9, 3.1] {
            let q = yaw_quaternion(yaw);
            assert!((quaternion_yaw(q) - yaw).abs() < 1e-12, "{yaw}");
            // -q is the same rotation.
            let n = [-q[0], -q[1], -q[2], -q[3]];
            assert!((quaternion_yaw(n) - yaw).abs() < 1e-12, "{yaw}");
            // Scale does not matter.
            let s = [2.0 * q[0], 0.0, 0.0, 2.0 * q[3]];
            assert!((quaternion_yaw(s) - yaw).abs() < 1e-12, "{yaw}");
        }
        // A small pitch does not change the heading of the x axis: yaw 0.4 then pitch 0.1.
        let (qy, qp) = (
            yaw_quaternion(0.4),
            [(0.05f64).cos(), 0.0, (0.05f64).sin(), 0.0],
        );
        // q = qy * qp (Hamilton product).
        let q = [
            qy[0] * qp[0] - qy[3] * qp[3],
            qy[0] * qp[1] - qy[3] * qp[2],
            qy[0] * qp[2] + qy[3] * qp[1],
            qy[3] * qp[0],
        ];
        assert!((quaternion_yaw(q) - 0.4).abs() < 1e-12);
    }

    #[test]
    fn devkit_class_mapping() {
        assert_eq!(tracking_name("vehicle.car"), Some("car"));
        assert_eq!(tracking_name("human.pedestrian.child"), Some("pedestrian"));
        assert_eq!(tracking_name("vehicle.bus.bendy"), Some("bus"));
        assert_eq!(tracking_name("vehicle.bicycle"), Some("bicycle"));
        assert_eq!(tracking_name("vehicle.motorcycle"), Some("motorcycle"));
        assert_eq!(tracking_name("vehicle.trailer"), Some("trailer"));
        assert_eq!(tracking_name("vehicle.truck"), Some("truck"));
        assert_eq!(tracking_name("vehicle.construction"), None);
        assert_eq!(tracking_name("human.pedestrian.stroller"), None);
        assert_eq!(tracking_name("movable_object.barrier"), None);
        for c in NUSCENES_CLASSES {
            assert!(
                [
                    "vehicle.bicycle",
                    "vehicle.bus.rigid",
                    "vehicle.car",
                    "vehicle.motorcycle",
                    "human.pedestrian.adult",
                    "vehicle.trailer",
                    "vehicle.truck"
                ]
                .iter()
                .any(|k| tracking_name(k) == Some(c)),
                "{c}"
            );
        }
    }

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

    #[test]
    fn reads_results_and_refuses_a_wrong_sample_token() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("r.json");
        std::fs::write(
            &p,
            r#"{"results": {"s1": [{"sample_token": "s1", "translation": [1, 2, 3],
                "size": [1, 2, 3], "rotation": [1, 0, 0, 0], "velocity": [0, 0],
                "detection_name": "car", "detection_score": 0.5, "attribute_name": ""}],
                "s2": []}, "meta": {"use_lidar": true}, "extra": [1]}"#,
        )
        .unwrap();
        let r = read_results(&p).unwrap();
        assert_eq!(r.boxes.len(), 2);
        assert_eq!(r.boxes["s1"].len(), 1);
        assert!(r.boxes["s2"].is_empty());
        assert_eq!(r.strings.names[r.boxes["s1"][0].name as usize], "car");
        std::fs::write(
            &p,
            r#"{"results": {"s1": [{"sample_token": "s9", "translation": [1, 2, 3],
                "size": [1, 2, 3], "rotation": [1, 0, 0, 0], "velocity": [0, 0],
                "detection_name": "car", "detection_score": 0.5}]}}"#,
        )
        .unwrap();
        let e = format!("{:#}", read_results(&p).unwrap_err());
        assert!(e.contains("results[s1]") && e.contains("s9"), "{e}");
        std::fs::write(&p, r#"{"meta": {}}"#).unwrap();
        let e = format!("{:#}", read_results(&p).unwrap_err());
        assert!(e.contains("results"), "{e}");
    }
}
