//! Which channels probmot reads detections from, and how: the input kind is chosen from the
//! channel's schema name, schema encoding and message encoding, with no flag, and every kind
//! decodes to probmot's own [`Detections3D`] (stamp, frame_id, boxes) and from there to a
//! checked [`DetectionFrame`].
//!
//! | schema name | schema encoding | message encoding |
//! |---|---|---|
//! | `probmot.Detections3D` | any (`protobuf` as probmot writes it) | `protobuf` or `json` |
//! | `vision_msgs/msg/Detection3DArray` | `ros2msg` | `cdr` |
//! | `foxglove.SceneUpdate` | `protobuf` | `protobuf` |
//! | `autoware_perception_msgs/msg/DetectedObjects` (or `autoware_auto_perception_msgs`) | `ros2msg` or `ros2idl` | `cdr` |
//!
//! A ROS 2 channel whose schema record has no text (a bag that stores no message definitions:
//! rosbag2's sqlite3 storage before ROS 2 Iron, or a type rosbag2 could not find) is read with
//! the layout of ROS 2 Humble: vision_msgs 4.x, or Autoware's one `DetectedObjects` layout.
//! A message of another layout then fails to decode, naming the message.

use super::detection_frame::{DetectionFrame, SkipReason};
use super::{
    autoware, decode as decode_probmot, foxglove_scene, lenient_label, ros2_vision, DecodeError,
    Detections3D, DetectionsEnvelope, Encoding, DETECTIONS_SCHEMA,
};

/// The supported detection inputs, for error messages and help texts.
pub const SUPPORTED: &str = "probmot.Detections3D (message encoding protobuf or json), \
     vision_msgs/msg/Detection3DArray (schema encoding ros2msg, message encoding cdr, \
     vision_msgs 4.x or 2.x layout), foxglove.SceneUpdate (schema and message encoding protobuf; one box per \
     cube), autoware_perception_msgs/msg/DetectedObjects or autoware_auto_perception_msgs/msg/DetectedObjects \
     (schema encoding ros2msg or ros2idl, message encoding cdr)";

/// How the messages of one detection channel are decoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DetectionSource {
    /// `probmot.Detections3D` in protobuf or JSON.
    Probmot(Encoding),
    /// ROS 2 `vision_msgs/msg/Detection3DArray` in CDR, with the layout its schema text gives.
    Ros2Vision(ros2_vision::VisionLayout),
    /// `foxglove.SceneUpdate` in protobuf; one box per cube.
    FoxgloveScene,
    /// Autoware's `DetectedObjects` in CDR ([`autoware`]), of either package.
    Autoware(autoware::Package),
}

/// True for the schema names of the supported detection inputs (whatever their encodings):
/// the channels `track` reads by default.
pub fn is_detection_schema(schema_name: &str) -> bool {
    schema_name == DETECTIONS_SCHEMA
        || ros2_vision::SCHEMA_NAMES.contains(&schema_name)
        || schema_name == foxglove_scene::SCHEMA_NAME
        || autoware::DETECTED_SCHEMA_NAMES.contains(&schema_name)
}

/// Channel metadata key marking a channel as one of probmot's own outputs (value: what it
/// holds, e.g. `tracks` on the `--scene-topic` SceneUpdate).
pub const OUTPUT_METADATA_KEY: &str = "probmot.output";

/// Whether `track` considers a channel for its default selection (no `--detections-topic`): a
/// detection schema, and not one of probmot's own outputs.
pub fn is_default_candidate(
    schema_name: &str,
    metadata: &std::collections::BTreeMap<String, String>,
) -> bool {
    is_detection_schema(schema_name) && !metadata.contains_key(OUTPUT_METADATA_KEY)
}

/// Of the readable channels of the default selection, the SceneUpdates to leave out: a
/// SceneUpdate is often a drawing of the same boxes, so it is read by default only when no
/// other kind of detection channel is there.
pub fn scenes_left_out<'a>(
    selected: impl IntoIterator<Item = (u16, &'a DetectionSource)> + Clone,
) -> Vec<u16> {
    let is_scene = |s: &DetectionSource| matches!(s, DetectionSource::FoxgloveScene);
    if selected.clone().into_iter().all(|(_, s)| is_scene(s)) {
        return Vec::new();
    }
    selected
        .into_iter()
        .filter(|(_, s)| is_scene(s))
        .map(|(id, _)| id)
        .collect()
}

impl DetectionSource {
    /// The decoder for a channel, or why its messages cannot be read as detections (the reason
    /// names the channel's schema and encodings and lists the supported ones).
    pub fn for_channel(
        schema_name: &str,
        schema_encoding: &str,
        schema_data: &[u8],
        message_encoding: &str,
    ) -> Result<DetectionSource, String> {
        let unsupported = |why: &str| {
            Err(format!(
                "{why}; supported detection inputs: {SUPPORTED}",
                why = if why.is_empty() {
                    format!(
                        "schema '{schema_name}' (schema encoding '{schema_encoding}', message \
                         encoding '{message_encoding}') is not a detection schema probmot reads"
                    )
                } else {
                    why.to_string()
                }
            ))
        };
        if schema_name == DETECTIONS_SCHEMA {
            return match Encoding::from_message_encoding(message_encoding) {
                Some(enc) => Ok(DetectionSource::Probmot(enc)),
                None => unsupported(&format!(
                    "schema '{schema_name}' with message encoding '{message_encoding}' (probmot \
                     reads protobuf or json)"
                )),
            };
        }
        if ros2_vision::SCHEMA_NAMES.contains(&schema_name) {
            if schema_encoding != "ros2msg" || message_encoding != "cdr" {
                return unsupported(&format!(
                    "schema '{schema_name}' with schema encoding '{schema_encoding}' and message \
                     encoding '{message_encoding}' (probmot reads ros2msg + cdr)"
                ));
            }
            if schema_data.is_empty() {
                return Ok(DetectionSource::Ros2Vision(ros2_vision::VisionLayout::V4));
            }
            return match ros2_vision::detect_layout(schema_data) {
                Ok(layout) => Ok(DetectionSource::Ros2Vision(layout)),
                Err(why) => Err(format!(
                    "schema '{schema_name}': unsupported field layout: {why}"
                )),
            };
        }
        if schema_name == foxglove_scene::SCHEMA_NAME {
            if schema_encoding != "protobuf" || message_encoding != "protobuf" {
                return unsupported(&format!(
                    "schema '{schema_name}' with schema encoding '{schema_encoding}' and message \
                     encoding '{message_encoding}' (probmot reads protobuf)"
                ));
            }
            return Ok(DetectionSource::FoxgloveScene);
        }
        if autoware::DETECTED_SCHEMA_NAMES.contains(&schema_name) {
            if message_encoding != "cdr" {
                return unsupported(&format!(
                    "schema '{schema_name}' with message encoding '{message_encoding}' (probmot \
                     reads cdr)"
                ));
            }
            if let (true, Some(package)) = (
                schema_data.is_empty(),
                autoware::Package::of_schema(schema_name),
            ) {
                return Ok(DetectionSource::Autoware(package));
            }
            return match autoware::detect_package(schema_name, schema_encoding, schema_data) {
                Ok(package) => Ok(DetectionSource::Autoware(package)),
                Err(why) => Err(format!(
                    "schema '{schema_name}': unsupported field layout: {why}"
                )),
            };
        }
        unsupported("")
    }

    /// The schema name of this kind of input (one name per kind, whatever the encoding).
    pub fn schema_name(&self) -> &'static str {
        match self {
            DetectionSource::Probmot(_) => DETECTIONS_SCHEMA,
            DetectionSource::Ros2Vision(_) => ros2_vision::SCHEMA_NAMES[0],
            DetectionSource::FoxgloveScene => foxglove_scene::SCHEMA_NAME,
            DetectionSource::Autoware(autoware::Package::Perception) => {
                autoware::DETECTED_SCHEMA_NAMES[0]
            }
            DetectionSource::Autoware(autoware::Package::AutoPerception) => {
                autoware::DETECTED_SCHEMA_NAMES[1]
            }
        }
    }

    /// What the channel holds, e.g. `vision_msgs/msg/Detection3DArray (cdr, vision_msgs 4.x
    /// layout)`.
    pub fn describe(&self) -> String {
        match self {
            DetectionSource::Probmot(Encoding::Protobuf) => {
                format!("{DETECTIONS_SCHEMA} (protobuf)")
            }
            DetectionSource::Probmot(Encoding::Json) => format!("{DETECTIONS_SCHEMA} (json)"),
            DetectionSource::Ros2Vision(l) => {
                format!("{} (cdr, {})", ros2_vision::SCHEMA_NAMES[0], l.describe())
            }
            DetectionSource::FoxgloveScene => {
                format!(
                    "{} (protobuf, one box per cube)",
                    foxglove_scene::SCHEMA_NAME
                )
            }
            DetectionSource::Autoware(_) => format!("{} (cdr)", self.schema_name()),
        }
    }

    /// Decodes one message.
    pub fn decode(&self, bytes: &[u8]) -> Result<Detections3D, DecodeError> {
        match *self {
            DetectionSource::Probmot(enc) => decode_probmot(bytes, enc),
            DetectionSource::Ros2Vision(layout) => ros2_vision::decode(bytes, layout),
            DetectionSource::FoxgloveScene => foxglove_scene::decode(bytes),
            DetectionSource::Autoware(_) => autoware::decode(bytes),
        }
    }

    /// Decodes one message into a checked [`DetectionFrame`]; `log_time` is its stamp when the
    /// message carries none.
    /// A box whose label is not UTF-8 is rejected and the rest of the message kept: a probmot
    /// protobuf label ([`lenient_label`]), a ROS 2 vision_msgs class id of any hypothesis or
    /// per-object id ([`ros2_vision::decode_lenient`]), a Foxglove entity's label or id
    /// ([`foxglove_scene::decode_lenient`]).
    pub fn decode_frame(&self, bytes: &[u8], log_time: u64) -> Result<DetectionFrame, DecodeError> {
        let (msg, rejected) = self.decode_lenient(bytes)?;
        let mut frame = DetectionFrame::from_message(msg, log_time);
        frame.reject(&rejected);
        if let DetectionSource::Autoware(_) = self {
            autoware::mark_classes_without_probmot_class(&mut frame);
        }
        Ok(frame)
    }

    /// Decodes one message without the boxes [`Self::decode_frame`] rejects for a string that
    /// is not UTF-8, and their reasons: the read of the commands that take boxes as decoded
    /// (`fit`, `tune`, `plot`, `viz`, `info`), so they accept the messages `track` accepts.
    pub fn decode_kept(
        &self,
        bytes: &[u8],
    ) -> Result<(Detections3D, Vec<SkipReason>), DecodeError> {
        let (mut msg, rejected) = self.decode_lenient(bytes)?;
        if rejected.is_empty() {
            return Ok((msg, Vec::new()));
        }
        let mut index = 0u32;
        msg.detections.retain(|_| {
            let keep = rejected.binary_search_by_key(&index, |r| r.0).is_err();
            index += 1;
            keep
        });
        Ok((msg, rejected.into_iter().map(|r| r.1).collect()))
    }

    /// Decodes one message, with the boxes to reject for a string that is not UTF-8 (see
    /// [`Self::decode_frame`]) as `(index, reason)`, ascending.
    fn decode_lenient(
        &self,
        bytes: &[u8],
    ) -> Result<(Detections3D, Vec<(u32, SkipReason)>), DecodeError> {
        match *self {
            DetectionSource::Ros2Vision(layout) => ros2_vision::decode_lenient(bytes, layout),
            DetectionSource::FoxgloveScene => foxglove_scene::decode_lenient(bytes),
            DetectionSource::Probmot(Encoding::Protobuf) => match self.decode(bytes) {
                Ok(msg) => Ok((msg, Vec::new())),
                Err(e) => {
                    let (msg, bad) = lenient_label::decode_with_bad_labels(bytes).ok_or(e)?;
                    let reason = SkipReason::LabelNotUtf8;
                    Ok((msg, bad.into_iter().map(|i| (i, reason)).collect()))
                }
            },
            _ => Ok((self.decode(bytes)?, Vec::new())),
        }
    }

    /// The stamp and the number of boxes of one message, for the first pass of `track`:
    /// probmot messages are read without building their boxes, the other kinds fully (counting
    /// the boxes [`Self::decode_frame`] rejects for a string that is not UTF-8).
    pub fn stamp_and_count(&self, bytes: &[u8]) -> Result<(Option<u64>, usize), DecodeError> {
        match *self {
            DetectionSource::Probmot(enc) => {
                let e: DetectionsEnvelope = decode_probmot(bytes, enc)?;
                Ok((e.stamp, e.detections.len()))
            }
            _ => {
                let (m, _) = self.decode_lenient(bytes)?;
                Ok((m.stamp, m.detections.len()))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A ROS 2 detection channel whose schema has no text (a bag that stores no definitions)
    /// is read with the Humble layout; a text that is not a known layout is still refused.
    #[test]
    fn a_schema_without_text_is_read_with_the_humble_layout() {
        let vision = "vision_msgs/msg/Detection3DArray";
        assert_eq!(
            DetectionSource::for_channel(vision, "ros2msg", b"", "cdr"),
            Ok(DetectionSource::Ros2Vision(ros2_vision::VisionLayout::V4))
        );
        assert!(DetectionSource::for_channel(vision, "ros2msg", b"int8 x", "cdr").is_err());
        for name in autoware::DETECTED_SCHEMA_NAMES {
            let package = autoware::Package::of_schema(name).unwrap();
            assert_eq!(
                DetectionSource::for_channel(name, "ros2msg", b"", "cdr"),
                Ok(DetectionSource::Autoware(package))
            );
            assert!(DetectionSource::for_channel(name, "ros2msg", b"int8 x", "cdr").is_err());
        }
    }
}
