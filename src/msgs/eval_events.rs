//! The channels `probmot eval --events` writes: the evaluation's decisions per frame as the
//! compact `probmot.EvalEvents` (for programs) and as a `foxglove.SceneUpdate` (to look at: a
//! box per decision, coloured by kind, with a text naming the ground-truth and track ids).

use foxglove::schemas::{
    CubePrimitive, Pose, Quaternion, SceneEntity, SceneUpdate, TextPrimitive, Timestamp,
};

use super::eval_event::Kind;
use super::{EvalEvent, EvalEvents};

/// Schema name of the events channel.
pub const EVAL_EVENTS_SCHEMA: &str = "probmot.EvalEvents";

/// Default topic of the `probmot.EvalEvents` channel.
pub const EVENTS_TOPIC: &str = "/eval/events";

/// Default topic of the `foxglove.SceneUpdate` channel of the events.
pub const EVENTS_SCENE_TOPIC: &str = "/eval/events_scene";

/// Serialized `FileDescriptorSet` of `probmot.EvalEvents` (with the geometry it imports), the data
/// of the events channel's schema record. Kept apart from [`super::DESCRIPTOR_SET`], so the schema
/// records of tracked logs do not change with the evaluation's messages.
pub const EVAL_DESCRIPTOR_SET: &[u8] =
    include_bytes!(concat!(env!("OUT_DIR"), "/probmot_eval_descriptor.bin"));

/// Short name of a kind, as printed and drawn.
pub fn kind_name(k: Kind) -> &'static str {
    match k {
        Kind::Match => "match",
        Kind::Switch => "id switch",
        Kind::Fragmentation => "fragmentation",
        Kind::FalsePositive => "false positive",
        Kind::Miss => "miss",
    }
}

/// Colour of a kind (RGB, 0-255): matches green, switches magenta, fragmentations orange, false
/// positives red, misses blue.
pub fn kind_rgb(k: Kind) -> (u8, u8, u8) {
    match k {
        Kind::Match => (40, 170, 70),
        Kind::Switch => (220, 0, 220),
        Kind::Fragmentation => (255, 140, 0),
        Kind::FalsePositive => (220, 30, 30),
        Kind::Miss => (30, 90, 230),
    }
}

/// Text of an event: the kind and both ids (`gt 5 / trk 12`; switches `trk 3->12`).
pub fn event_text(e: &EvalEvent) -> String {
    let kind = e.kind();
    let mut s = String::from(kind_name(kind));
    if e.truth_id != 0 {
        s.push_str(&format!(" gt {}", e.truth_id));
    }
    match kind {
        Kind::Switch => s.push_str(&format!(" trk {}->{}", e.previous_track_id, e.track_id)),
        Kind::Fragmentation => s.push_str(&format!(" lost trk {}", e.previous_track_id)),
        _ if e.track_id != 0 => s.push_str(&format!(" trk {}", e.track_id)),
        _ => {}
    }
    s
}

fn timestamp(stamp: u64) -> Timestamp {
    let sec = (stamp / 1_000_000_000).min(u32::MAX as u64) as u32;
    Timestamp::new(sec, (stamp % 1_000_000_000) as u32)
}

fn color(k: Kind, a: f64) -> foxglove::schemas::Color {
    let (r, g, b) = kind_rgb(k);
    foxglove::schemas::Color {
        r: r as f64 / 255.0,
        g: g as f64 / 255.0,
        b: b as f64 / 255.0,
        a,
    }
}

/// The scene update of one frame's events: one entity per event (`event/<i>`, living until the
/// next frame's update replaces the scene), a see-through cube in the kind's colour, slightly
/// larger than the box, and its [`event_text`] above it. Matches are drawn only when `matches`.
pub fn scene_update(ev: &EvalEvents, matches: bool) -> SceneUpdate {
    let ts = timestamp(ev.stamp);
    let entities = ev
        .events
        .iter()
        .filter(|e| matches || e.kind() != Kind::Match)
        .enumerate()
        .map(|(i, e)| {
            let c = e.center.unwrap_or_default();
            let s = e.size.unwrap_or_default();
            let position = foxglove::schemas::Vector3 {
                x: c.x,
                y: c.y,
                z: c.z,
            };
            let orientation = Quaternion {
                x: 0.0,
                y: 0.0,
                z: (e.yaw / 2.0).sin(),
                w: (e.yaw / 2.0).cos(),
            };
            let alpha = if e.kind() == Kind::Match { 0.25 } else { 0.55 };
            SceneEntity {
                timestamp: Some(ts),
                frame_id: ev.frame_id.clone(),
                id: format!("event/{i}"),
                frame_locked: false,
                cubes: vec![CubePrimitive {
                    pose: Some(Pose {
                        position: Some(position),
                        orientation: Some(orientation),
                    }),
                    size: Some(foxglove::schemas::Vector3 {
                        x: s.length + 0.4,
                        y: s.width + 0.4,
                        z: s.height + 0.4,
                    }),
                    color: Some(color(e.kind(), alpha)),
                }],
                texts: vec![TextPrimitive {
                    pose: Some(Pose {
                        position: Some(foxglove::schemas::Vector3 {
                            z: c.z + s.height / 2.0 + 1.2,
                            ..position
                        }),
                        orientation: Some(Quaternion {
                            x: 0.0,
                            y: 0.0,
                            z: 0.0,
                            w: 1.0,
                        }),
                    }),
                    billboard: true,
                    font_size: 14.0,
                    scale_invariant: true,
                    color: Some(color(e.kind(), 1.0)),
                    text: event_text(e),
                }],
                ..Default::default()
            }
        })
        .collect();
    // Replace the previous frame's events entirely.
    let deletions = vec![foxglove::schemas::SceneEntityDeletion {
        timestamp: Some(ts),
        r#type: foxglove::schemas::scene_entity_deletion::Type::All as i32,
        id: String::new(),
    }];
    SceneUpdate {
        deletions,
        entities,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn switch_text_names_both_tracks_and_the_truth() {
        let e = EvalEvent {
            kind: Kind::Switch as i32,
            truth_id: 5,
            track_id: 12,
            previous_track_id: 3,
            ..Default::default()
        };
        assert_eq!(event_text(&e), "id switch gt 5 trk 3->12");
        let u = scene_update(
            &EvalEvents {
                stamp: 1_500_000_000,
                frame_id: "map".into(),
                events: vec![
                    e,
                    EvalEvent {
                        kind: Kind::Match as i32,
                        ..Default::default()
                    },
                ],
                ..Default::default()
            },
            false,
        );
        assert_eq!(u.entities.len(), 1, "matches are left out");
        assert_eq!(u.entities[0].frame_id, "map");
        assert_eq!(
            u.entities[0].timestamp,
            Some(Timestamp::new(1, 500_000_000))
        );
    }
}
