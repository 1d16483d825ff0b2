//! `probmot import nuscenes` and `probmot export nuscenes`.
//!
//! Import turns a detection submission (`results.json`, the nuScenes detection result format)
//! and/or a tracking submission, and the dataset's metadata tables (`sample.json`, `scene.json`,
//! ...) into one MCAP file per scene. Export writes `Tracks3D` channels of such files as a
//! tracking submission. Files: `tables` (table rows and readers), `results` (detection results),
//! `tracks` (tracking submissions, bicycle racks), `plan` (the scenes and their sample chains), `truth`
//! (ground truth), `ego_pose`, `import` (the import: checks, then one file per scene),
//! `scene_file` (writing one scene), `export`.
//!
//! Conventions (nuScenes -> probmot):
//! - boxes stay in the global frame (`frame_id` [`FRAME_ID`]), centre = `translation`;
//! - `size` `[w, l, h]` -> `Size3 { length: l, width: w, height: h }`;
//! - `rotation` quaternion `[w, x, y, z]` -> yaw about +z, the heading of the box's x axis
//!   projected on the ground plane (the devkit's `quaternion_yaw`); export writes the pure-yaw
//!   quaternion `[cos(yaw/2), 0, 0, sin(yaw/2)]`;
//! - a frame per sample, stamp = sample `timestamp` (µs) × 1000 ns.

mod ego_pose;
mod export;
mod import;
mod plan;
mod results;
mod scene_file;
mod summary_text;
mod tables;
pub mod tracks;
mod truth;

pub use export::*;
pub use import::{import_nuscenes, ImportOptions, ImportSummary};
pub use scene_file::SceneSummary;

use std::collections::BTreeMap;

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

/// `[w, l, h]` -> probmot size.
pub(crate) fn nusc_size(s: [f64; 3]) -> crate::msgs::Size3 {
    crate::msgs::size3([s[1], s[0], s[2]])
}

/// String attributes from `(key, value)` pairs.
pub(crate) fn attrs(pairs: &[(&str, String)]) -> BTreeMap<String, String> {
    pairs
        .iter()
        .map(|(k, v)| (k.to_string(), v.clone()))
        .collect()
}

/// The rotation about +z by `yaw` as a quaternion `[w, x, y, z]`.
pub fn yaw_quaternion(yaw: f64) -> [f64; 4] {
    let (s, c) = (yaw / 2.0).sin_cos();
    [c, 0.0, 0.0, s]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tracker::config::NUSCENES_CLASSES;
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
}
