//! ROS 2 transform and odometry messages (`tf2_msgs`, `geometry_msgs`, `nav_msgs`) as serde
//! structs in wire order, for CDR decoding with the `cdr` crate.
//!
//! Field order and types follow the upstream `.msg` files (ROS 2 Humble and later):
//! `geometry_msgs/msg/Transform.msg`, `TransformStamped.msg`, `Twist.msg`,
//! `PoseWithCovariance.msg`, `TwistWithCovariance.msg` (ros2/common_interfaces),
//! `tf2_msgs/msg/TFMessage.msg` (ros2/geometry2) and `nav_msgs/msg/Odometry.msg`
//! (ros2/common_interfaces). The `cdr` crate measures alignment from the end of the 4-byte
//! encapsulation header and drops the NUL terminator counted in a string's length, as ROS 2
//! writes them; `tests/ros2_tf_fixture.rs` checks both on bytes written by `mcap-ros2-support`.

use serde::de::{Deserializer, Error as _, SeqAccess, Visitor};
use serde::Deserialize;

use super::ros2_common::{Header, Pose, Quaternion, Vector3};

/// Schema name of a ROS 2 transform channel (`/tf`, `/tf_static`).
pub const TF_MESSAGE_SCHEMA: &str = "tf2_msgs/msg/TFMessage";
/// Schema name of a ROS 2 odometry channel.
pub const ODOMETRY_SCHEMA: &str = "nav_msgs/msg/Odometry";

/// `geometry_msgs/msg/Transform`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize)]
pub struct Transform {
    /// Position of the child frame's origin in the parent frame.
    pub translation: Vector3,
    /// Orientation of the child frame in the parent frame.
    pub rotation: Quaternion,
}

/// `geometry_msgs/msg/TransformStamped`.
#[derive(Debug, Clone, Default, PartialEq, Deserialize)]
pub struct TransformStamped {
    /// Stamp and parent frame (`header.frame_id`).
    pub header: Header,
    /// Child frame.
    pub child_frame_id: String,
    /// The transform from the child frame to the parent frame.
    pub transform: Transform,
}

/// `tf2_msgs/msg/TFMessage`.
#[derive(Debug, Clone, Default, PartialEq, Deserialize)]
pub struct TfMessage {
    /// The transforms.
    pub transforms: Vec<TransformStamped>,
}

/// A row-major 6x6 covariance (`float64[36]`: a fixed-size CDR array, no length prefix).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Covariance36(pub [f64; 36]);

impl Default for Covariance36 {
    fn default() -> Self {
        Covariance36([0.0; 36])
    }
}

impl<'de> Deserialize<'de> for Covariance36 {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = Covariance36;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("36 float64 values")
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Self::Value, A::Error> {
                let mut out = [0.0; 36];
                for (i, v) in out.iter_mut().enumerate() {
                    *v = seq
                        .next_element()?
                        .ok_or_else(|| A::Error::invalid_length(i, &self))?;
                }
                Ok(Covariance36(out))
            }
        }
        d.deserialize_tuple(36, V)
    }
}

/// `geometry_msgs/msg/PoseWithCovariance`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize)]
pub struct PoseWithCovariance {
    /// Pose.
    pub pose: Pose,
    /// Covariance of x, y, z, rotation about x, y, z.
    pub covariance: Covariance36,
}

/// `geometry_msgs/msg/Twist`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize)]
pub struct Twist {
    /// Linear velocity.
    pub linear: Vector3,
    /// Angular velocity.
    pub angular: Vector3,
}

/// `geometry_msgs/msg/TwistWithCovariance`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize)]
pub struct TwistWithCovariance {
    /// Twist.
    pub twist: Twist,
    /// Covariance.
    pub covariance: Covariance36,
}

/// `nav_msgs/msg/Odometry`: the pose of `child_frame_id` in `header.frame_id`.
#[derive(Debug, Clone, Default, PartialEq, Deserialize)]
pub struct Odometry {
    /// Stamp and parent frame.
    pub header: Header,
    /// Child (body) frame.
    pub child_frame_id: String,
    /// Pose of the child frame in the parent frame.
    pub pose: PoseWithCovariance,
    /// Velocity in the child frame.
    pub twist: TwistWithCovariance,
}

/// Decodes a CDR message (with its 4-byte encapsulation header).
pub fn decode_cdr<'de, T: Deserialize<'de>>(bytes: &[u8]) -> Result<T, cdr::Error> {
    // Bounded by the input length: a corrupt length prefix cannot allocate more than the input.
    cdr::deserialize_from(bytes, cdr::Bounded(bytes.len() as u64))
}
