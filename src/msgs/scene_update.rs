//! The `--scene-topic` output of `probmot track`: one `foxglove.SceneUpdate` per frame, so the
//! tracked log opens in the Foxglove 3D panel as it is.
//!
//! One entity per reported track, with the entity id `track/<id>`: a cube (the box, coloured by
//! the track id's stable colour, [`super::colors::id_color`]), a text at its centre (`<id>
//! <label>`), and an arrow from the centre along the velocity (length = 1 s of travel) when
//! the track moves faster than [`MIN_ARROW_SPEED`]. Entities have no lifetime (they stay until
//! replaced or deleted); the update of a frame deletes the entities of the tracks that are no
//! longer reported (a track that died, or one not reported in this frame), so the scene shows
//! exactly the tracks of the tracks channel.
//!
//! The values only the drawing has (the quaternions, the arrow's lengths, the colours) are
//! rounded to a 12-bit mantissa ([`super::short_precision`]: under 0.02° for a heading, 2.5 mm
//! on a 10 m arrow): full-precision digits there cost bytes in every frame and show nothing. The
//! centres and sizes are the tracks' values as they are, and the text sits at the box's centre
//! (billboarded, so it faces the viewer; seen from above, it is where a label above the box
//! would be): zstd codes all of them as repeats of the tracks message written just before, where
//! a label height of its own was a new value in every frame (1.3 % of the default output,
//! docs/scaling.md).
//!
//! Each entity also carries the metadata `label`, `score` (three decimals: the 17 digits of a
//! double there cost 3 % of the default output) and `track_id`: the convention probmot reads
//! `foxglove.SceneUpdate` detections with, so the boxes stay self-describing. The channel
//! has the metadata `probmot.output = tracks`, which keeps `track` from reading it as detections
//! by default when the tracked log is tracked again.

use foxglove::schemas::{
    scene_entity_deletion, ArrowPrimitive, Color, CubePrimitive, KeyValuePair, Pose, Quaternion,
    SceneEntity, SceneEntityDeletion, SceneUpdate, TextPrimitive, Timestamp, Vector3,
};

use super::colors::id_color;
pub use super::detection_source::OUTPUT_METADATA_KEY;
use super::proto_writer::{decimal, three_decimals, ProtoWriter};
use super::{short_precision, Track3D, Tracks3D};

/// Schema name of the output channel.
pub const SCENE_UPDATE_SCHEMA: &str = "foxglove.SceneUpdate";

/// Slowest speed (m/s) drawn as a velocity arrow.
pub const MIN_ARROW_SPEED: f64 = 0.2;

/// Alpha of the cubes (the box stays see-through).
const CUBE_ALPHA: f64 = 0.45;

const TEXT_FONT_SIZE: f64 = 14.0;
const ARROW_SHAFT_DIAMETER: f64 = 0.15;
const ARROW_HEAD_DIAMETER: f64 = 0.4;

/// Head length of the velocity arrow of a track moving at `speed`.
fn arrow_head(speed: f64) -> f64 {
    short_precision((0.3 * speed).clamp(0.3, 1.5))
}

/// Shaft length of that arrow: shaft + head = 1 s of travel.
fn arrow_shaft(speed: f64, head: f64) -> f64 {
    short_precision((speed - head).max(0.1))
}

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

/// The rotation by `yaw` about +z (components rounded to `f32`).
fn yaw_quaternion(yaw: f64) -> Quaternion {
    Quaternion {
        x: 0.0,
        y: 0.0,
        z: short_precision((yaw / 2.0).sin()),
        w: short_precision((yaw / 2.0).cos()),
    }
}

/// The colour of a track id, opaque or with `alpha` (components rounded to `f32`).
pub fn track_color(id: u64, alpha: f64) -> Color {
    let (r, g, b) = id_color(id);
    Color {
        r: short_precision(r as f64 / 255.0),
        g: short_precision(g as f64 / 255.0),
        b: short_precision(b as f64 / 255.0),
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
                    position: Some(center),
                    orientation: Some(yaw_quaternion(0.0)),
                }),
                billboard: true,
                font_size: TEXT_FONT_SIZE,
                scale_invariant: true,
                color: Some(track_color(t.id, 1.0)),
                text: format!("{} {}", t.id, t.label),
            };
            let v = t.velocity.unwrap_or_default();
            let speed = v.x.hypot(v.y);
            let arrows = if speed > MIN_ARROW_SPEED {
                let head = arrow_head(speed);
                vec![ArrowPrimitive {
                    pose: Some(Pose {
                        position: Some(center),
                        orientation: Some(yaw_quaternion(v.y.atan2(v.x))),
                    }),
                    shaft_length: arrow_shaft(speed, head),
                    shaft_diameter: ARROW_SHAFT_DIAMETER,
                    head_length: head,
                    head_diameter: ARROW_HEAD_DIAMETER,
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
                        key: "track_id".into(),
                        value: t.id.to_string(),
                    },
                    KeyValuePair {
                        key: "score".into(),
                        value: score_text(t.score),
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
    /// Encodes the update of the next frame of tracks into `buf` (protobuf), cleared first.
    pub fn encode_frame(&mut self, tracks: &Tracks3D, buf: &mut Vec<u8>) {
        buf.clear();
        self.append_frame(tracks, buf);
    }

    /// Appends the update of the next frame of tracks to `buf`, leaving what it holds (for a
    /// sink that has it written straight into its batch, `RecordSink::write_encoded`).
    pub fn append_frame(&mut self, tracks: &Tracks3D, buf: &mut Vec<u8>) {
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
        write_update(&mut ProtoWriter::new(buf), tracks, &self.gone);
    }
}

// Field numbers of the foxglove schemas written below.
const UPDATE_DELETIONS: u32 = 1;
const UPDATE_ENTITIES: u32 = 2;
const ENTITY_TIMESTAMP: u32 = 1;
const ENTITY_FRAME_ID: u32 = 2;
const ENTITY_ID: u32 = 3;
const ENTITY_METADATA: u32 = 6;
const ENTITY_ARROWS: u32 = 7;
const ENTITY_CUBES: u32 = 8;
const ENTITY_TEXTS: u32 = 13;
const DELETION_TIMESTAMP: u32 = 1;
const DELETION_ID: u32 = 3;

/// Writes [`scene_update`]`(tracks, deleted)` without building it: the bytes of one frame are
/// written straight into the reused buffer (prost reads them back as that message; the fields
/// of an entity are in the order [`write_primitives`] says).
fn write_update(w: &mut ProtoWriter<'_>, tracks: &Tracks3D, deleted: &[u64]) {
    let ts = timestamp(tracks.stamp);
    let mut digits = [0; 20];
    for &id in deleted {
        w.message(UPDATE_DELETIONS, |w| {
            w.message(DELETION_TIMESTAMP, |w| write_timestamp(w, ts));
            // type MATCHING_ID is 0, the default: not written.
            w.string_parts(DELETION_ID, &[b"track/", decimal(id, &mut digits)]);
        });
    }
    for t in &tracks.tracks {
        let id = decimal(t.id, &mut digits);
        w.message(UPDATE_ENTITIES, |w| {
            w.message(ENTITY_TIMESTAMP, |w| write_timestamp(w, ts));
            w.string(ENTITY_FRAME_ID, &tracks.frame_id);
            w.string_parts(ENTITY_ID, &[b"track/", id]);
            write_metadata(w, b"label", |w| w.string(2, &t.label));
            write_metadata(w, b"track_id", |w| w.string_parts(2, &[id]));
            write_primitives(w, t, id);
            write_metadata(w, b"score", |w| write_score(w, t.score));
        });
    }
}

/// The `score` metadata of a track: three decimals (`0.870`), or as `{}` writes it when it has
/// none (not finite, or too large).
fn score_text(score: f64) -> String {
    let mut buf = [0; 24];
    match three_decimals(score, &mut buf) {
        Some(t) => String::from_utf8_lossy(t).into_owned(),
        None => format!("{score}"),
    }
}

/// [`score_text`] as field 2 of a `KeyValuePair`.
fn write_score(w: &mut ProtoWriter<'_>, score: f64) {
    let mut buf = [0; 24];
    match three_decimals(score, &mut buf) {
        Some(t) => w.string_parts(2, &[t]),
        None => w.string_fmt(2, format_args!("{score}")),
    }
}

fn write_timestamp(w: &mut ProtoWriter<'_>, ts: Timestamp) {
    w.uint(1, ts.sec().into());
    w.uint(2, ts.nsec().into());
}

/// A `KeyValuePair` of the entity's metadata; `value` writes field 2.
fn write_metadata(w: &mut ProtoWriter<'_>, key: &[u8], value: impl FnOnce(&mut ProtoWriter<'_>)) {
    w.message(ENTITY_METADATA, |w| {
        w.string_parts(1, &[key]);
        value(w);
    });
}

/// A `Pose` at `p`, rotated by `yaw` about +z (the orientation first: see [`write_primitives`]).
fn write_pose(w: &mut ProtoWriter<'_>, field: u32, p: [f64; 3], yaw: f64) {
    let q = yaw_quaternion(yaw);
    w.message(field, |w| {
        w.doubles(2, &[q.x, q.y, q.z, q.w]);
        w.doubles(1, &p);
    });
}

/// The track's colour `c` with `alpha`.
fn write_color(w: &mut ProtoWriter<'_>, field: u32, c: &Color, alpha: f64) {
    w.doubles(field, &[c.r, c.g, c.b, alpha]);
}

/// The text, cube and arrow of a track's entity, as [`scene_update`] makes them.
///
/// Fields are written in the order that suits zstd, not in field-number order (protobuf readers
/// take fields in any order; the decoded message is the same): in each primitive what stays the
/// same from frame to frame (colour, sizes of the text and the arrow, the text) comes first, so
/// that it and the entity's id and metadata before it are one match with the same track's
/// entity one frame earlier; then the pose, orientation first, so that the position is followed
/// by the box's size as in the tracks message just before (one match again); the values only
/// this frame has (the quaternions, the arrow's length) sit between those matches. The `score` metadata, new in every frame, closes the entity.
fn write_primitives(w: &mut ProtoWriter<'_>, t: &Track3D, id: &[u8]) {
    let c = t.center.unwrap_or_default();
    let s = t.size.unwrap_or_default();
    let center = [c.x, c.y, c.z];
    let v = t.velocity.unwrap_or_default();
    let speed = v.x.hypot(v.y);
    // The id's colour once for the three primitives.
    let color = track_color(t.id, 1.0);
    w.message(ENTITY_TEXTS, |w| {
        w.bool(2, true);
        w.bool(4, true);
        w.double(3, TEXT_FONT_SIZE);
        write_color(w, 5, &color, 1.0);
        w.string_parts(6, &[id, b" ", t.label.as_bytes()]);
        write_pose(w, 1, center, 0.0);
    });
    w.message(ENTITY_CUBES, |w| {
        write_color(w, 3, &color, CUBE_ALPHA);
        write_pose(w, 1, center, t.yaw);
        w.doubles(2, &[s.length, s.width, s.height]);
    });
    if speed > MIN_ARROW_SPEED {
        let head = arrow_head(speed);
        w.message(ENTITY_ARROWS, |w| {
            write_color(w, 6, &color, 1.0);
            w.double(3, ARROW_SHAFT_DIAMETER);
            w.double(5, ARROW_HEAD_DIAMETER);
            w.double(4, head);
            write_pose(w, 1, center, v.y.atan2(v.x));
            w.double(2, arrow_shaft(speed, head));
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msgs::{v3, Size3, Track3D};
    use proptest::prelude::any;

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
        // (5 = 3.5 + 1.5, both exact with a 12-bit mantissa.)
        assert!((a.shaft_length + a.head_length - 5.0).abs() < 1e-6);
        let q = a.pose.unwrap().orientation.unwrap();
        // (a 12-bit mantissa: the angle is within 1/2048 rad.)
        assert!((2.0 * q.z.atan2(q.w) - 4f64.atan2(3.0)).abs() < 5e-4);
        // The drawing's own values have a 12-bit mantissa, the centre is the track's, the
        // text is at the centre.
        for x in [q.z, q.w, a.shaft_length, a.head_length] {
            assert_eq!(x, short_precision(x));
        }
        assert_ne!(q.z, (4f64.atan2(3.0) / 2.0).sin());
        assert_eq!(a.pose.unwrap().position.unwrap().x, 1.0);
        assert_eq!(
            e.texts[0].pose.unwrap().position,
            e.cubes[0].pose.unwrap().position
        );
        assert!(u.entities[1].arrows.is_empty());
        // Stable colours: the same id gets the same colour, always.
        assert_eq!(e.cubes[0].color, Some(track_color(7, CUBE_ALPHA)));
    }

    fn track() -> impl proptest::strategy::Strategy<Value = Track3D> {
        use proptest::prelude::*;
        let x = || {
            prop_oneof![
                Just(0.0),
                Just(-0.0),
                Just(f64::NAN),
                -1e4..1e4f64,
                any::<f64>()
            ]
        };
        let v = move || proptest::option::of([x(), x(), x()].prop_map(v3));
        let size = proptest::option::of([x(), x(), x()]).prop_map(|s| {
            s.map(|[length, width, height]| Size3 {
                length,
                width,
                height,
            })
        });
        let id = prop_oneof![0u64..300, any::<u64>()];
        let label = prop_oneof![Just(String::new()), "[a-z_]{1,12}", ".{100,140}"];
        (id, label, v(), size, x(), v(), x()).prop_map(
            |(id, label, center, size, yaw, velocity, score)| Track3D {
                id,
                label,
                center,
                size,
                yaw,
                velocity,
                score,
                ..Default::default()
            },
        )
    }

    proptest::proptest! {
        /// The encoder writes [`scene_update`]: prost decodes its bytes to that message (compared
        /// through prost's own encoding of both, which is canonical and keeps NaNs comparable).
        #[test]
        fn encoded_frames_decode_to_scene_update(
            frames in proptest::collection::vec(
                (any::<u64>(), "[a-z_/]{0,8}", proptest::collection::vec(track(), 0..6)), 1..4)
        ) {
            let mut enc = SceneEncoder::default();
            let mut shown: Vec<u64> = Vec::new();
            let mut buf = vec![1, 2, 3];
            for (stamp, frame_id, tracks) in frames {
                let tracks = Tracks3D { stamp, frame_id, tracks };
                let mut now: Vec<u64> = tracks.tracks.iter().map(|t| t.id).collect();
                now.sort_unstable();
                let gone: Vec<u64> = shown.iter().copied().filter(|id| !now.contains(id)).collect();
                enc.encode_frame(&tracks, &mut buf);
                let decoded = <SceneUpdate as prost::Message>::decode(buf.as_slice()).unwrap();
                let mut got = Vec::new();
                crate::msgs::encode_into(&decoded, &mut got);
                let mut want = Vec::new();
                crate::msgs::encode_into(&scene_update(&tracks, &gone), &mut want);
                proptest::prop_assert_eq!(&got, &want);
                shown = now;
            }
        }

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
