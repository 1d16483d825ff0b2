//! The tracking side of `probmot import nuscenes`: a tracking submission (`--tracks`) as the
//! `/tracks` channel of each scene, and the scene's bicycle racks as a channel of their own, so
//! that `probmot eval --devkit` can apply every filter of the devkit.

use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::BufReader;
use std::path::Path;

use anyhow::{bail, Context, Result};
use serde::Deserialize;

use super::{attr, quaternion_yaw, TrackingBox, BIKE_RACK_LABEL, MAX_BOXES_PER_SAMPLE};
use crate::msgs::{v3, Size3, Track3D};
use crate::tracker::config::NUSCENES_CLASSES;

/// A tracking submission: boxes per sample token.
#[derive(Debug, Default, Deserialize)]
pub struct TrackingResults {
    /// The `meta` block, as given.
    #[serde(default)]
    pub meta: Option<serde_json::Value>,
    /// Boxes per sample token.
    pub results: HashMap<String, Vec<TrackingBox>>,
}

/// Reads and checks a tracking submission: each box's `sample_token` is its key, its class is
/// one of the seven tracking classes, its numbers are finite, and no sample holds more than the
/// devkit's 500 boxes.
pub fn read_tracking_results(path: &Path) -> Result<TrackingResults> {
    let file = File::open(path).with_context(|| format!("cannot read {}", path.display()))?;
    let res: TrackingResults = serde_json::from_reader(BufReader::with_capacity(1 << 20, file))
        .with_context(|| {
            format!(
                "{}: not a nuScenes tracking submission (JSON {{\"meta\": ..., \"results\": \
                 {{sample_token: [{{sample_token, translation, size, rotation, velocity, \
                 tracking_id, tracking_name, tracking_score}}, ...]}}}})",
                path.display()
            )
        })?;
    let mut keys: Vec<&String> = res.results.keys().collect();
    keys.sort();
    for key in keys {
        let boxes = &res.results[key];
        if boxes.len() > MAX_BOXES_PER_SAMPLE {
            bail!(
                "{}: sample {key} holds {} boxes, more than the devkit's {MAX_BOXES_PER_SAMPLE}",
                path.display(),
                boxes.len()
            );
        }
        for (i, b) in boxes.iter().enumerate() {
            let at = format!("{}: results[{key}][{i}]", path.display());
            if b.sample_token != *key {
                bail!("{at}: sample_token is {}", b.sample_token);
            }
            if !NUSCENES_CLASSES.contains(&b.tracking_name.as_str()) {
                bail!(
                    "{at}: tracking_name '{}' is not one of the tracking classes ({})",
                    b.tracking_name,
                    NUSCENES_CLASSES.join(", ")
                );
            }
            let numbers = b.translation.iter().chain(&b.size).chain(&b.rotation);
            if numbers.chain(&b.velocity).any(|v| !v.is_finite()) || !b.tracking_score.is_finite() {
                bail!("{at}: a number is not finite");
            }
        }
    }
    Ok(res)
}

/// `[w, l, h]` -> probmot size.
fn size_of(s: [f64; 3]) -> Size3 {
    Size3 {
        length: s[1],
        width: s[0],
        height: s[2],
    }
}

/// Numeric ids for the string `tracking_id`s of one scene: 1, 2, ... in order of appearance.
#[derive(Debug, Default)]
pub struct TrackIds(HashMap<String, u64>);

impl TrackIds {
    /// The id of `tracking_id`, given on first sight.
    pub fn get(&mut self, tracking_id: &str) -> u64 {
        let next = self.0.len() as u64 + 1;
        *self.0.entry(tracking_id.to_string()).or_insert(next)
    }
}

/// A submission box as a track: class, score, centre, size, yaw (of the quaternion), velocity;
/// the sample token and the original `tracking_id` as attributes.
pub fn track_of(b: &TrackingBox, ids: &mut TrackIds) -> Track3D {
    Track3D {
        id: ids.get(&b.tracking_id),
        label: b.tracking_name.clone(),
        center: Some(v3(b.translation)),
        size: Some(size_of(b.size)),
        yaw: quaternion_yaw(b.rotation),
        velocity: Some(v3([b.velocity[0], b.velocity[1], 0.0])),
        score: b.tracking_score,
        attributes: [
            (attr::SAMPLE_TOKEN, b.sample_token.clone()),
            (attr::TRACKING_ID, b.tracking_id.clone()),
        ]
        .into_iter()
        .map(|(k, v)| (k.to_string(), v))
        .collect(),
        ..Default::default()
    }
}

/// A bicycle-rack annotation of one sample.
#[derive(Debug, Clone)]
pub struct RackAnn {
    /// Id (position of the instance in instance.json + 1).
    pub id: u64,
    /// Annotation token.
    pub token: String,
    /// Centre.
    pub translation: [f64; 3],
    /// `[w, l, h]`.
    pub size: [f64; 3],
    /// Quaternion `[w, x, y, z]`.
    pub rotation: [f64; 4],
}

/// A rack as a `Track3D` (label [`BIKE_RACK_LABEL`]); the full quaternion is kept as the
/// `nuscenes_rotation` attribute (JSON, exact), since the devkit's in-rack test uses it.
pub fn rack_track(r: &RackAnn, sample_token: &str) -> Track3D {
    let rotation = serde_json::to_string(&r.rotation).unwrap_or_default();
    let attributes: BTreeMap<String, String> = [
        (attr::SAMPLE_TOKEN, sample_token.to_string()),
        (attr::ANNOTATION_TOKEN, r.token.clone()),
        (attr::ROTATION, rotation),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v))
    .collect();
    Track3D {
        id: r.id,
        label: BIKE_RACK_LABEL.into(),
        center: Some(v3(r.translation)),
        size: Some(size_of(r.size)),
        yaw: quaternion_yaw(r.rotation),
        score: 1.0,
        attributes,
        ..Default::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_are_numbered_per_scene_in_order_of_appearance() {
        let mut ids = TrackIds::default();
        assert_eq!((ids.get("b7"), ids.get("a1"), ids.get("b7")), (1, 2, 1));
    }

    #[test]
    fn rack_keeps_the_exact_quaternion() {
        let r = RackAnn {
            id: 3,
            token: "t".into(),
            translation: [1.0, 2.0, 0.5],
            size: [2.0, 6.0, 1.0],
            rotation: [0.9238795325112867, 0.01, -0.02, 0.3826834323650898],
        };
        let t = rack_track(&r, "s");
        let q: [f64; 4] = serde_json::from_str(&t.attributes[attr::ROTATION]).unwrap();
        assert_eq!(q, r.rotation);
        assert_eq!(t.size.unwrap().length, 6.0);
    }
}
