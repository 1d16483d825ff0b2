//! Reading transforms from a recording's channels into a [`TransformBuffer`]: ROS 2
//! `tf2_msgs/msg/TFMessage` (`/tf`, and `/tf_static` as static), `nav_msgs/msg/Odometry`
//! (the pose of `child_frame_id` in `header.frame_id`), and `foxglove.FrameTransform` /
//! `foxglove.FrameTransforms` (protobuf).

use std::collections::{BTreeMap, HashMap};

use mcap::records::{Channel, MessageHeader};
use prost::Message as _;

use super::buffer::{rigid, TransformBuffer};
use crate::msgs::ros2_tf::{Odometry, TfMessage, ODOMETRY_SCHEMA, TF_MESSAGE_SCHEMA};

/// Schema name of a Foxglove single-transform channel.
pub const FOXGLOVE_FRAME_TRANSFORM: &str = "foxglove.FrameTransform";
/// Schema name of a Foxglove transform-array channel.
pub const FOXGLOVE_FRAME_TRANSFORMS: &str = "foxglove.FrameTransforms";

/// The kind of a transform channel.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SourceKind {
    /// `tf2_msgs/msg/TFMessage` in CDR.
    Ros2Tf,
    /// `nav_msgs/msg/Odometry` in CDR.
    Ros2Odometry,
    /// `foxglove.FrameTransform` in protobuf.
    FoxgloveFrameTransform,
    /// `foxglove.FrameTransforms` in protobuf.
    FoxgloveFrameTransforms,
}

impl SourceKind {
    /// The kind of a channel from its schema name and message encoding, if it carries
    /// transforms probmot reads.
    pub fn of(schema: &str, message_encoding: &str) -> Option<SourceKind> {
        match (schema, message_encoding) {
            (TF_MESSAGE_SCHEMA, "cdr") => Some(SourceKind::Ros2Tf),
            (ODOMETRY_SCHEMA, "cdr") => Some(SourceKind::Ros2Odometry),
            (FOXGLOVE_FRAME_TRANSFORM, "protobuf") => Some(SourceKind::FoxgloveFrameTransform),
            (FOXGLOVE_FRAME_TRANSFORMS, "protobuf") => Some(SourceKind::FoxgloveFrameTransforms),
            _ => None,
        }
    }
}

/// Counts of one transform topic.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct SourceCounters {
    /// Messages read.
    pub messages: u64,
    /// Transforms added to the buffer.
    pub transforms: u64,
    /// Messages that failed to decode.
    pub undecodable: u64,
    /// Transforms dropped: empty frame name, negative stamp, non-finite number or zero
    /// quaternion.
    pub invalid: u64,
}

struct SourceChannel {
    kind: SourceKind,
    topic: String,
    is_static: bool,
}

/// Collects the transforms of every transform channel of a file while it is streamed.
#[derive(Default)]
pub struct TransformCollector {
    channels: HashMap<u16, SourceChannel>,
    /// The transforms read so far.
    pub buffer: TransformBuffer,
    /// Per topic counts.
    pub per_topic: BTreeMap<String, SourceCounters>,
    /// First decode error, for `--strict` and the warning text.
    pub first_error: Option<String>,
}

impl TransformCollector {
    /// An empty collector.
    pub fn new() -> Self {
        Self::default()
    }

    /// Registers a channel if it carries transforms; returns its kind. A `tf2_msgs` channel
    /// whose topic ends in `tf_static` holds static transforms.
    pub fn on_channel(&mut self, c: &Channel, schema: &str) -> Option<SourceKind> {
        let kind = SourceKind::of(schema, &c.message_encoding)?;
        let is_static = c.topic.ends_with("tf_static");
        self.channels.insert(
            c.id,
            SourceChannel {
                kind,
                topic: c.topic.clone(),
                is_static,
            },
        );
        self.per_topic.entry(c.topic.clone()).or_default();
        Some(kind)
    }

    /// True when the channel carries transforms.
    pub fn is_transform_channel(&self, channel_id: u16) -> bool {
        self.channels.contains_key(&channel_id)
    }

    /// Reads one message if its channel carries transforms; returns whether it did. Decode
    /// errors are counted, not returned (see [`TransformCollector::first_error`]).
    pub fn on_message(&mut self, file: &str, h: &MessageHeader, data: &[u8]) -> bool {
        let Some(ch) = self.channels.get(&h.channel_id) else {
            return false;
        };
        let counters = self.per_topic.entry(ch.topic.clone()).or_default();
        counters.messages += 1;
        let buffer = &mut self.buffer;
        let mut add =
            |parent: &str, child: &str, stamp: Option<u64>, t: [f64; 3], q: [f64; 4]| match (
                stamp,
                rigid(t, q),
            ) {
                (Some(stamp), Some(iso)) if !parent.is_empty() && !child.is_empty() => {
                    buffer.add(parent, child, stamp, iso, ch.is_static);
                    counters.transforms += 1;
                }
                _ => counters.invalid += 1,
            };
        let result: Result<(), String> = match ch.kind {
            SourceKind::Ros2Tf => match TfMessage::decode(data) {
                Ok(m) => {
                    for ts in &m.transforms {
                        let tr = ts.transform.translation;
                        let q = ts.transform.rotation;
                        add(
                            &ts.header.frame_id,
                            &ts.child_frame_id,
                            ts.header.stamp.to_nanos(),
                            [tr.x, tr.y, tr.z],
                            [q.x, q.y, q.z, q.w],
                        );
                    }
                    Ok(())
                }
                Err(e) => Err(format!("{TF_MESSAGE_SCHEMA}: {e}")),
            },
            SourceKind::Ros2Odometry => match Odometry::decode(data) {
                Ok(m) => {
                    let p = m.pose.pose.position;
                    let q = m.pose.pose.orientation;
                    add(
                        &m.header.frame_id,
                        &m.child_frame_id,
                        m.header.stamp.to_nanos(),
                        [p.x, p.y, p.z],
                        [q.x, q.y, q.z, q.w],
                    );
                    Ok(())
                }
                Err(e) => Err(format!("{ODOMETRY_SCHEMA}: {e}")),
            },
            SourceKind::FoxgloveFrameTransform => {
                match foxglove::schemas::FrameTransform::decode(data) {
                    Ok(m) => {
                        add_foxglove(&m, h.log_time, &mut add);
                        Ok(())
                    }
                    Err(e) => Err(format!("{FOXGLOVE_FRAME_TRANSFORM}: {e}")),
                }
            }
            SourceKind::FoxgloveFrameTransforms => {
                match foxglove::schemas::FrameTransforms::decode(data) {
                    Ok(m) => {
                        for t in &m.transforms {
                            add_foxglove(t, h.log_time, &mut add);
                        }
                        Ok(())
                    }
                    Err(e) => Err(format!("{FOXGLOVE_FRAME_TRANSFORMS}: {e}")),
                }
            }
        };
        if let Err(e) = result {
            counters.undecodable += 1;
            if self.first_error.is_none() {
                self.first_error = Some(format!(
                    "{file}: topic {}, message at log_time {} (sequence {}): cannot decode {e}",
                    ch.topic, h.log_time, h.sequence
                ));
            }
        }
        true
    }

    /// Sorts the buffer's samples; call once after the last message.
    pub fn finish(&mut self) {
        self.buffer.finish();
    }

    /// Messages that failed to decode, over all topics.
    pub fn undecodable(&self) -> u64 {
        self.per_topic.values().map(|c| c.undecodable).sum()
    }

    /// Transforms dropped as invalid, over all topics.
    pub fn invalid(&self) -> u64 {
        self.per_topic.values().map(|c| c.invalid).sum()
    }
}

/// A Foxglove transform: a missing rotation is the identity, a missing timestamp is the
/// message's log_time.
fn add_foxglove(
    m: &foxglove::schemas::FrameTransform,
    log_time: u64,
    add: &mut impl FnMut(&str, &str, Option<u64>, [f64; 3], [f64; 4]),
) {
    let t = m.translation.unwrap_or_default();
    let q = m
        .rotation
        .map(|q| [q.x, q.y, q.z, q.w])
        .unwrap_or([0.0, 0.0, 0.0, 1.0]);
    let stamp = m.timestamp.map(|s| s.total_nanos()).unwrap_or(log_time);
    add(
        &m.parent_frame_id,
        &m.child_frame_id,
        Some(stamp),
        [t.x, t.y, t.z],
        q,
    );
}
