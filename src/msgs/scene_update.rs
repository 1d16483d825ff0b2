//! The `--scene-topic` output of `probmot track`: one `foxglove.SceneUpdate` per frame, so the
//! tracked log opens in the Foxglove 3D panel as it is.
//!
//! One entity per reported track, with the entity id `track/<id>`: a cube (the box, coloured by
//! the track id's stable colour, [`super::colors::id_color`]), a text above it (`<id>
//! <label>`), and an arrow from the centre along the velocity (length = 1 s of travel) when
//! the track moves faster than [`MIN_ARROW_SPEED`]. Entities have no lifetime (they stay until
//! replaced or deleted); the update of a frame deletes the entities of the tracks that are no
//! longer reported (a track that died, or one not reported in this frame), so the scene shows
//! exactly the tracks of the tracks channel.
//!
//! Each entity also carries the metadata `label`, `score` and `track_id`: the convention probmot
//! reads `foxglove.SceneUpdate` detections with, so the boxes stay self-describing. The channel
//! has the metadata `probmot.output = tracks`, which keeps `track` from reading it as detections
//! by default when the tracked log is tracked again.

use foxglove::schemas::{
    scene_entity_deletion, ArrowPrimitive, Color, CubePrimitive, KeyValuePair, Pose, Quaternion,
    SceneEntity, SceneEntityDeletion, SceneUpdate, TextPrimitive, Timestamp, Vector3,
};

use super::colors::id_color;
pub use super::detection_source::OUTPUT_METADATA_KEY;
use super::Tracks3D;

/// Schema name of the output channel.
pub const SCENE_UPDATE_SCHEMA: &str = "foxglove.SceneUpdate";

/// Slowest speed (m/s) drawn as a velocity arrow.
pub const MIN_ARROW_SPEED: f64 = 0.2;

/// Alpha of the cubes (the box stays see-through).
const CUBE_ALPHA: f64 = 0.45;

/// The `FileDescriptorSet` of `foxglove.SceneUpdate`, as stored in the output's schema record.
pub fn scene_update_descriptor() -> Vec<u8> {
    use foxglove::Encode as _;
    SceneUpdate::get_schema()
        .expect("foxglove.SceneUpdate has a schema")
        .data
        .into_owned()
}

/// Entity id of a track.
pub fn entity_id(track_id: u64) -> String {
    format!("track/{track_id}")
}

fn timestamp(stamp: u64) -> Timestamp {
    // Seconds past u32::MAX (year 2106) saturate.
    let sec = (stamp / 1_000_000_000).min(u32::MAX as u64) as u32;
    Timestamp::new(sec, (stamp % 1_000_000_000) as u32)
}

fn yaw_quaternion(yaw: f64) -> Quaternion {
    Quaternion {
        x: 0.0,
        y: 0.0,
        z: (yaw / 2.0).sin(),
        w: (yaw / 2.0).cos(),
    }
}

/// The colour of a track id, opaque or with `alpha`.
pub fn track_color(id: u64, alpha: f64) -> Color {
    let (r, g, b) = id_color(id);
    Color {
        r: r as f64 / 255.0,
        g: g as f64 / 255.0,
        b: b as f64 / 255.0,
        a: alpha,
    }
}

/// Builds the scene update of one frame: entities for the tracks of `tracks` (in its
/// `frame_id`) and deletions for the track ids in `deleted`.
pub fn scene_update(tracks: &Tracks3D, deleted: &[u64]) -> SceneUpdate {
    let ts = timestamp(tracks.stamp);
    let deletions = deleted
        .iter()
        .map(|&id| SceneEntityDeletion {
            timestamp: Some(ts),
            r#type: scene_entity_deletion::Type::MatchingId as i32,
            id: entity_id(id),
        })
        .collect();
    let entities = tracks
        .tracks
        .iter()
        .map(|t| {
            let c = t.center.unwrap_or_default();
            let s = t.size.unwrap_or_default();
            let center = Vector3 {
                x: c.x,
                y: c.y,
                z: c.z,
            };
            let cube = CubePrimitive {
                pose: Some(Pose {
                    position: Some(center),
                    orientation: Some(yaw_quaternion(t.yaw)),
                }),
                size: Some(Vector3 {
                    x: s.length,
                    y: s.width,
                    z: s.height,
                }),
                color: Some(track_color(t.id, CUBE_ALPHA)),
            };
            let text = TextPrimitive {
                pose: Some(Pose {
                    position: Some(Vector3 {
                        z: c.z + s.height / 2.0 + 0.5,
                        ..center
                    }),
                    orientation: Some(yaw_quaternion(0.0)),
                }),
                billboard: true,
                font_size: 14.0,
                scale_invariant: true,
                color: Some(track_color(t.id, 1.0)),
                text: format!("{} {}", t.id, t.label),
            };
            let v = t.velocity.unwrap_or_default();
            let speed = v.x.hypot(v.y);
            let arrows = if speed > MIN_ARROW_SPEED {
                let head = (0.3 * speed).clamp(0.3, 1.5);
                vec![ArrowPrimitive {
                    pose: Some(Pose {
                        position: Some(center),
                        orientation: Some(yaw_quaternion(v.y.atan2(v.x))),
                    }),
                    shaft_length: (speed - head).max(0.1),
                    shaft_diameter: 0.15,
                    head_length: head,
                    head_diameter: 0.4,
                    color: Some(track_color(t.id, 1.0)),
                }]
            } else {
                Vec::new()
            };
            SceneEntity {
                timestamp: Some(ts),
                frame_id: tracks.frame_id.clone(),
                id: entity_id(t.id),
                lifetime: None,
                frame_locked: false,
                cubes: vec![cube],
                texts: vec![text],
                arrows,
                metadata: vec![
                    KeyValuePair {
                        key: "label".into(),
                        value: t.label.clone(),
                    },
                    KeyValuePair {
                        key: "score".into(),
                        value: format!("{}", t.score),
                    },
                    KeyValuePair {
                        key: "track_id".into(),
                        value: t.id.to_string(),
                    },
                ],
                ..Default::default()
            }
        })
        .collect();
    SceneUpdate {
        deletions,
        entities,
    }
}

/// The SceneUpdate encoder of a tracks sequence: remembers the track ids shown, so that each
/// frame's update deletes the entities of the tracks no longer reported (dead, or not reported
/// in this frame) and the scene shows exactly the tracks of the tracks channel.
#[derive(Debug, Default)]
pub struct SceneEncoder {
    /// Track ids with an entity in the scene (sorted).
    shown: Vec<u64>,
    /// Ids to delete this frame (reused buffer).
    gone: Vec<u64>,
    /// Ids of this frame's tracks (sorted; reused buffer).
    now: Vec<u64>,
}

impl SceneEncoder {
    /// Encodes the update of the next frame of tracks into `buf` (protobuf).
    pub fn encode_frame(&mut self, tracks: &Tracks3D, buf: &mut Vec<u8>) {
        self.now.clear();
        self.now.extend(tracks.tracks.iter().map(|t| t.id));
        self.now.sort_unstable();
        // Both lists are sorted: one merge finds the ids shown before and missing now.
        self.gone.clear();
        let mut k = 0;
        for &old in &self.shown {
            while k < self.now.len() && self.now[k] < old {
                k += 1;
            }
            if self.now.get(k) != Some(&old) {
                self.gone.push(old);
            }
        }
        std::mem::swap(&mut self.shown, &mut self.now);
        super::encode_into(&scene_update(tracks, &self.gone), buf);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msgs::{v3, Size3, Track3D};

    #[test]
    fn one_entity_per_track_with_deletions_and_arrows_for_movers() {
        let tracks = Tracks3D {
            stamp: 1_500_000_001,
            frame_id: "map".into(),
            tracks: vec![
                Track3D {
                    id: 7,
                    label: "car".into(),
                    center: Some(v3([1.0, 2.0, 0.5])),
                    size: Some(Size3 {
                        length: 4.0,
                        width: 2.0,
                        height: 1.5,
                    }),
                    yaw: 0.3,
                    velocity: Some(v3([3.0, 4.0, 0.0])),
                    ..Default::default()
                },
                Track3D {
                    id: 9,
                    label: "pedestrian".into(),
                    velocity: Some(v3([0.0, 0.0, 0.0])),
                    ..Default::default()
                },
            ],
        };
        let u = scene_update(&tracks, &[3]);
        assert_eq!(u.entities.len(), 2);
        assert_eq!(u.deletions.len(), 1);
        assert_eq!(u.deletions[0].id, "track/3");
        let e = &u.entities[0];
        assert_eq!((e.id.as_str(), e.frame_id.as_str()), ("track/7", "map"));
        assert_eq!(e.texts[0].text, "7 car");
        assert_eq!(e.cubes[0].size.unwrap().x, 4.0);
        let ts = e.timestamp.unwrap();
        assert_eq!((ts.sec(), ts.nsec()), (1, 500_000_001));
        // 5 m/s: shaft + head = 5 m, pointing along atan2(4, 3).
        let a = &e.arrows[0];
        assert!((a.shaft_length + a.head_length - 5.0).abs() < 1e-12);
        let q = a.pose.unwrap().orientation.unwrap();
        assert!((2.0 * q.z.atan2(q.w) - 4f64.atan2(3.0)).abs() < 1e-12);
        assert!(u.entities[1].arrows.is_empty());
        // Stable colours: the same id gets the same colour, always.
        assert_eq!(e.cubes[0].color, Some(track_color(7, CUBE_ALPHA)));
    }

    proptest::proptest! {
        /// Each frame deletes exactly the ids shown in the previous frame and missing now,
        /// whatever the order of the tracks.
        #[test]
        fn deletions_are_the_ids_shown_before_and_missing_now(
            frames in proptest::collection::vec(proptest::collection::vec(0u64..12, 0..8), 1..10)
        ) {
            let mut enc = SceneEncoder::default();
            let mut before = std::collections::BTreeSet::new();
            for ids in frames {
                let now: std::collections::BTreeSet<u64> = ids.iter().copied().collect();
                let tracks = Tracks3D {
                    tracks: now.iter().rev().map(|&id| Track3D { id, ..Default::default() }).collect(),
                    ..Default::default()
                };
                let mut buf = Vec::new();
                enc.encode_frame(&tracks, &mut buf);
                let u = <SceneUpdate as prost::Message>::decode(buf.as_slice()).unwrap();
                let deleted: Vec<String> = u.deletions.iter().map(|d| d.id.clone()).collect();
                let expected: Vec<String> = before.difference(&now).map(|&id| entity_id(id)).collect();
                proptest::prop_assert_eq!(deleted, expected);
                before = now;
            }
        }
    }
}
