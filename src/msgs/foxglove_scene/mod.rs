//! Foxglove `foxglove.SceneUpdate` (protobuf) as probmot detections: one detection per cube.
//!
//! A `SceneUpdate` has no label or score fields, so probmot reads them from each entity's
//! `metadata` (`KeyValuePair`s), by this convention:
//!
//! - label: the value of the first of the keys `label`, `class`, `class_id` that is present;
//!   without any of them the label is empty (tracked with the config's `default` entry);
//! - score: the key `score`, a decimal number; without it the score is 1. A value that is not a
//!   number is an error naming the message;
//! - every other metadata pair, and the entity `id` as `entity_id`, become detection attributes
//!   (carried to the matched track).
//!
//! Every cube of an entity is one detection with that entity's label and score: centre =
//! `pose.position`, yaw = the rotation about z of `pose.orientation` (identity when absent),
//! size = `size` (x along the heading = length, y = width, z = height). Other primitives
//! (spheres, lines, text, ...) and `deletions` are ignored. Stamp and frame: those of the first
//! entity (no entities: the MCAP log_time); entities in different frames are an error, since
//! the boxes of one message are tracked in one frame.
//!
//! A string that is not UTF-8 makes prost refuse the whole update; [`decode_lenient`] reads it
//! anyway when that string is an entity's label or id (its cubes are then rejected, as
//! `track` rejects such a box of the other inputs) or lies where no detection is read from.

mod lenient;

pub use lenient::decode_lenient;

use foxglove::schemas::{SceneEntity, SceneUpdate};
use prost::Message as _;

use super::ros2_common::Quaternion;
use super::{v3, DecodeError, Detection3D, Detections3D, Size3};

/// Schema name of a Foxglove scene update channel.
pub const SCHEMA_NAME: &str = "foxglove.SceneUpdate";

/// Metadata keys read as the label, in order of preference.
pub const LABEL_KEYS: [&str; 3] = ["label", "class", "class_id"];
/// Metadata key read as the score.
pub const SCORE_KEY: &str = "score";
/// Score of a cube whose entity has no `score` metadata.
pub const DEFAULT_SCORE: f64 = 1.0;

/// The value of the first metadata pair of `e` with this key.
fn meta<'a>(e: &'a SceneEntity, key: &str) -> Option<&'a str> {
    e.metadata
        .iter()
        .find(|kv| kv.key == key)
        .map(|kv| kv.value.as_str())
}

/// Decodes one protobuf `foxglove.SceneUpdate` into detections.
pub fn decode(bytes: &[u8]) -> Result<Detections3D, DecodeError> {
    detections(&SceneUpdate::decode(bytes)?)
}

/// The detections of a decoded update: one per cube, entity by entity.
fn detections(update: &SceneUpdate) -> Result<Detections3D, DecodeError> {
    let mut out = Detections3D::default();
    if let Some(first) = update.entities.first() {
        out.stamp = first.timestamp.map(|t| t.total_nanos());
        out.frame_id = first.frame_id.clone();
    }
    for e in &update.entities {
        if e.frame_id != out.frame_id && !e.cubes.is_empty() {
            return Err(DecodeError::Content(format!(
                "entity '{}' is in frame '{}' and entity '{}' in frame '{}'; the cubes of one \
                 SceneUpdate must share a frame",
                update.entities[0].id, out.frame_id, e.id, e.frame_id
            )));
        }
        let label = LABEL_KEYS
            .iter()
            .find_map(|k| meta(e, k))
            .unwrap_or("")
            .to_string();
        let score = match meta(e, SCORE_KEY) {
            None => DEFAULT_SCORE,
            Some(v) => v.trim().parse::<f64>().map_err(|_| {
                DecodeError::Content(format!(
                    "entity '{}': metadata score '{v}' is not a number",
                    e.id
                ))
            })?,
        };
        for cube in &e.cubes {
            let mut d = Detection3D {
                label: label.clone(),
                score,
                ..Default::default()
            };
            if let Some(pose) = &cube.pose {
                d.center = pose.position.map(|p| v3([p.x, p.y, p.z]));
                d.yaw = match pose.orientation {
                    None => 0.0,
                    Some(q) => Quaternion {
                        x: q.x,
                        y: q.y,
                        z: q.z,
                        w: q.w,
                    }
                    .yaw()
                    .unwrap_or(f64::NAN),
                };
            }
            d.size = cube.size.map(|s| Size3 {
                length: s.x,
                width: s.y,
                height: s.z,
            });
            for kv in &e.metadata {
                if kv.key != SCORE_KEY && !LABEL_KEYS.contains(&kv.key.as_str()) {
                    d.attributes.insert(kv.key.clone(), kv.value.clone());
                }
            }
            if !e.id.is_empty() {
                d.attributes.insert("entity_id".into(), e.id.clone());
            }
            out.detections.push(d);
        }
    }
    Ok(out)
}
