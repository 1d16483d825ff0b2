//! A `foxglove.SceneUpdate` in which some strings are not UTF-8, read as far as the boxes
//! allow: the strings are replaced lossily ([`utf8_repair`]), then each one's place decides.
//!
//! - An entity's label (the metadata value read as its label) or its `id`: that entity's
//!   cubes are rejected (`label_not_utf8`, `id_not_utf8`), the rest of the update is read.
//! - A deletion, a text or a model, a label key the label is not read from, or anything in an
//!   entity without cubes: not read as detections, so it costs nothing.
//! - An entity's `frame_id`, a metadata key, any other metadata value (an attribute or the
//!   score): the update fails with prost's error, as a probmot message with such a string.

use foxglove::schemas::{SceneEntity, SceneUpdate};
use prost::Message as _;

use super::{detections, LABEL_KEYS};
use crate::msgs::detection_frame::SkipReason;
use crate::msgs::utf8_repair::{self, Field, Schema, Step};
use crate::msgs::{DecodeError, Detections3D};

static KEY_VALUE: Schema = Schema(&[(1, Field::Str), (2, Field::Str)]);
static TEXT: Schema = Schema(&[(6, Field::Str)]);
static MODEL: Schema = Schema(&[(5, Field::Str), (6, Field::Str)]);
static DELETION: Schema = Schema(&[(3, Field::Str)]);
static ENTITY: Schema = Schema(&[
    (FRAME_ID, Field::Str),
    (ID, Field::Str),
    (METADATA, Field::Msg(&KEY_VALUE)),
    (13, Field::Msg(&TEXT)),
    (14, Field::Msg(&MODEL)),
]);
static UPDATE: Schema = Schema(&[(1, Field::Msg(&DELETION)), (ENTITIES, Field::Msg(&ENTITY))]);

/// Tags of `SceneUpdate.entities`, `SceneEntity.frame_id`, `.id`, `.metadata`, `.cubes`, and
/// of `KeyValuePair.value`.
const ENTITIES: u32 = 2;
const FRAME_ID: u32 = 2;
const ID: u32 = 3;
const METADATA: u32 = 6;
const VALUE: u32 = 2;

/// Decodes one protobuf `foxglove.SceneUpdate` into detections, with the boxes to reject
/// because their entity's label or id is not UTF-8, as `(index, reason)`, ascending.
pub fn decode_lenient(bytes: &[u8]) -> Result<(Detections3D, Vec<(u32, SkipReason)>), DecodeError> {
    let error = match SceneUpdate::decode(bytes) {
        Ok(update) => return Ok((detections(&update)?, Vec::new())),
        Err(e) => e,
    };
    let Some((repaired, places)) = utf8_repair::repair(bytes, &UPDATE) else {
        return Err(error.into());
    };
    let Ok(update) = SceneUpdate::decode(repaired.as_slice()) else {
        return Err(error.into());
    };
    let mut reasons: Vec<Option<SkipReason>> = vec![None; update.entities.len()];
    for place in &places {
        let [(ENTITIES, e), ref inside @ ..] = place[..] else {
            continue; // a deletion
        };
        match reason(&update.entities[e], inside) {
            Verdict::Reject(r) => reasons[e] = Some(reasons[e].map_or(r, |old| old.min(r))),
            Verdict::Unread => {}
            Verdict::Fail => return Err(error.into()),
        }
    }
    let msg = detections(&update)?;
    let mut rejected = Vec::new();
    let mut first = 0u32;
    for (entity, reason) in update.entities.iter().zip(reasons) {
        let cubes = entity.cubes.len() as u32;
        if let Some(r) = reason {
            rejected.extend((first..first + cubes).map(|i| (i, r)));
        }
        first += cubes;
    }
    Ok((msg, rejected))
}

/// What a string that is not UTF-8 at this place of an entity means for its boxes.
enum Verdict {
    Reject(SkipReason),
    Unread,
    Fail,
}

fn reason(entity: &SceneEntity, place: &[Step]) -> Verdict {
    match place {
        [(FRAME_ID, _)] => Verdict::Fail,
        _ if entity.cubes.is_empty() => Verdict::Unread,
        [(ID, _)] => Verdict::Reject(SkipReason::IdNotUtf8),
        [(METADATA, k), (VALUE, _)] if Some(*k) == label_pair(entity) => {
            Verdict::Reject(SkipReason::LabelNotUtf8)
        }
        [(METADATA, k), (VALUE, _)] if LABEL_KEYS.contains(&entity.metadata[*k].key.as_str()) => {
            Verdict::Unread
        }
        [(METADATA, _), ..] => Verdict::Fail,
        _ => Verdict::Unread, // a text or a model
    }
}

/// The index of the metadata pair the entity's label is read from, as
/// [`detections`](super::detections) chooses it.
fn label_pair(entity: &SceneEntity) -> Option<usize> {
    LABEL_KEYS
        .iter()
        .find_map(|k| entity.metadata.iter().position(|kv| kv.key == *k))
}

#[cfg(test)]
mod tests {
    use super::*;
    use foxglove::schemas::{CubePrimitive, KeyValuePair, Pose, TextPrimitive, Vector3};

    fn kv(key: &str, value: &str) -> KeyValuePair {
        KeyValuePair {
            key: key.into(),
            value: value.into(),
        }
    }

    fn cube(x: f64) -> CubePrimitive {
        CubePrimitive {
            pose: Some(Pose {
                position: Some(Vector3 { x, y: 0.0, z: 0.0 }),
                orientation: None,
            }),
            size: Some(Vector3 {
                x: 4.0,
                y: 2.0,
                z: 1.5,
            }),
            color: None,
        }
    }

    /// Entities `a` (2 cubes, label `QA`), `b` (1 cube, label `QB`, a text `QT`) and `c` (1
    /// cube, class `car`); each `QQQQ` of the edited strings becomes bytes that are not UTF-8.
    fn update(edit: impl Fn(&mut SceneUpdate)) -> Vec<u8> {
        let entity = |id: &str, label: &str, cubes: Vec<CubePrimitive>| SceneEntity {
            frame_id: "map".into(),
            id: id.into(),
            metadata: vec![kv("label", label), kv("score", "0.5"), kv("lane", "1")],
            cubes,
            ..Default::default()
        };
        let mut u = SceneUpdate {
            deletions: vec![],
            entities: vec![
                entity("a", "car", vec![cube(0.0), cube(5.0)]),
                entity("b", "truck", vec![cube(10.0)]),
                entity("c", "pedestrian", vec![cube(20.0)]),
            ],
        };
        u.entities[1].texts.push(TextPrimitive {
            text: "b truck".into(),
            ..Default::default()
        });
        edit(&mut u);
        let mut bytes = u.encode_to_vec();
        while let Some(at) = bytes.windows(4).position(|w| w == b"QQQQ") {
            bytes[at..at + 4].copy_from_slice(&[0xc3, 0x28, 0xff, b'r']);
        }
        bytes
    }

    fn lenient(edit: impl Fn(&mut SceneUpdate)) -> Result<Vec<(u32, SkipReason)>, String> {
        let bytes = update(edit);
        match decode_lenient(&bytes) {
            Ok((msg, rejected)) => {
                assert_eq!(msg.detections.len(), 4);
                Ok(rejected)
            }
            Err(e) => Err(e.to_string()),
        }
    }

    use SkipReason::{IdNotUtf8, LabelNotUtf8};

    #[test]
    fn a_label_or_an_id_rejects_the_cubes_of_its_entity() {
        assert_eq!(lenient(|_| {}), Ok(vec![]));
        let label = |u: &mut SceneUpdate| u.entities[0].metadata[0].value = "QQQQ".into();
        assert_eq!(
            lenient(label),
            Ok(vec![(0, LabelNotUtf8), (1, LabelNotUtf8)])
        );
        let id = |u: &mut SceneUpdate| u.entities[1].id = "bQQQQ".into();
        assert_eq!(lenient(id), Ok(vec![(2, IdNotUtf8)]));
        let both = |u: &mut SceneUpdate| {
            u.entities[2].id = "QQQQ".into();
            u.entities[2].metadata[0].value = "QQQQ".into();
        };
        assert_eq!(lenient(both), Ok(vec![(3, LabelNotUtf8)]));
    }

    #[test]
    fn strings_no_detection_is_read_from_cost_nothing() {
        let text = |u: &mut SceneUpdate| u.entities[1].texts[0].text = "QQQQ".into();
        assert_eq!(lenient(text), Ok(vec![]));
        let other_key = |u: &mut SceneUpdate| u.entities[0].metadata.push(kv("class", "QQQQ"));
        assert_eq!(lenient(other_key), Ok(vec![]));
        let no_cubes = |u: &mut SceneUpdate| {
            let mut e = u.entities[0].clone();
            (e.id, e.cubes) = ("QQQQ".into(), vec![]);
            e.metadata[2].value = "QQQQ".into();
            u.entities.push(e);
        };
        assert_eq!(lenient(no_cubes), Ok(vec![]));
    }

    #[test]
    fn a_frame_id_an_attribute_or_a_score_fails_the_update() {
        let edits: [fn(&mut SceneUpdate); 4] = [
            |u| u.entities[1].frame_id = "QQQQ".into(),
            |u| u.entities[1].metadata[2].value = "QQQQ".into(),
            |u| u.entities[1].metadata[2].key = "QQQQ".into(),
            |u| u.entities[1].metadata[1].value = "0.QQQQ".into(),
        ];
        for edit in edits {
            let err = lenient(edit).unwrap_err();
            assert!(err.contains("not UTF-8") || err.contains("UTF-8"), "{err}");
        }
    }

    #[test]
    fn other_faults_keep_prosts_error() {
        let mut bytes = update(|u| u.entities[0].metadata[0].value = "QQQQ".into());
        let strict = SceneUpdate::decode(&bytes[..bytes.len() - 3]).unwrap_err();
        let lenient = decode_lenient(&bytes[..bytes.len() - 3]).unwrap_err();
        assert_eq!(lenient.to_string(), DecodeError::from(strict).to_string());
        bytes.push(0x07); // a key with the reserved wire type 7
        assert!(decode_lenient(&bytes).is_err());
    }
}
