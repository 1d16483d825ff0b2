//! ROS 2 transform and odometry messages (`tf2_msgs`, `geometry_msgs`, `nav_msgs`) as serde
//! structs in wire order, for CDR decoding with the `cdr` crate.
//!
//! Field order and types follow the upstream `.msg` files (ROS 2 Humble and later):
//! `geometry_msgs/msg/Transform.msg`, `TransformStamped.msg`, `Twist.msg`,
//! `PoseWithCovariance.msg`, `TwistWithCovariance.msg` (ros2/common_interfaces),
//! `tf2_msgs/msg/TFMessage.msg` (ros2/geometry2) and `nav_msgs/msg/Odometry.msg`
//! (ros2/common_interfaces).
//!
//! Two decoders give the same values: [`decode_cdr`] (the `cdr` crate through serde: it measures
//! alignment from the end of the 4-byte encapsulation header and drops the NUL terminator counted
//! in a string's length, as ROS 2 writes them) and the hand-written, bounds-checked
//! [`TfMessage::decode`] / [`Odometry::decode`] that probmot uses on logs, because the `cdr`
//! crate allocates a corrupt string length before checking it (see [`super::cdr_cursor`]).
//! `tests/it/ros2_tf_fixture.rs` checks both on bytes written by `mcap-ros2-support`.

use serde::de::{Deserializer, Error as _, SeqAccess, Visitor};
use serde::Deserialize;

use super::cdr_cursor::{CdrCursor, CdrError};
use super::ros2_common::{Header, Point, Pose, Quaternion, Time, Vector3};

/// Schema name of a ROS 2 transform channel (`/tf`, `/tf_static`).
pub const TF_MESSAGE_SCHEMA: &str = "tf2_msgs/msg/TFMessage";
/// The `ros2msg` schema text of `tf2_msgs/msg/TFMessage` with every dependency, in the layout
/// rosbag2 writes: the field lines of the upstream `.msg` files named above (ROS 2 Humble),
/// comments left out. Written for a bag that stores no definitions (a Humble sqlite3 bag), so
/// that the output's `/tf` stays readable by tools that decode by the definition.
pub const TF_MESSAGE_TEXT: &str = "\
geometry_msgs/TransformStamped[] transforms

================================================================================
MSG: geometry_msgs/TransformStamped
std_msgs/Header header
string child_frame_id
Transform transform

================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id

================================================================================
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec

================================================================================
MSG: geometry_msgs/Transform
Vector3 translation
Quaternion rotation

================================================================================
MSG: geometry_msgs/Vector3
float64 x
float64 y
float64 z

================================================================================
MSG: geometry_msgs/Quaternion
float64 x 0
float64 y 0
float64 z 0
float64 w 1
";

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

fn header(c: &mut CdrCursor) -> Result<Header, CdrError> {
    Ok(Header {
        stamp: Time {
            sec: c.i32()?,
            nanosec: c.u32()?,
        },
        frame_id: c.string()?,
    })
}

fn vector3(c: &mut CdrCursor) -> Result<Vector3, CdrError> {
    Ok(Vector3 {
        x: c.f64()?,
        y: c.f64()?,
        z: c.f64()?,
    })
}

fn quaternion(c: &mut CdrCursor) -> Result<Quaternion, CdrError> {
    Ok(Quaternion {
        x: c.f64()?,
        y: c.f64()?,
        z: c.f64()?,
        w: c.f64()?,
    })
}

fn covariance(c: &mut CdrCursor) -> Result<Covariance36, CdrError> {
    let mut v = [0.0; 36];
    for x in &mut v {
        *x = c.f64()?;
    }
    Ok(Covariance36(v))
}

impl TfMessage {
    /// Decodes CDR bytes (with the encapsulation header), checking every length.
    pub fn decode(bytes: &[u8]) -> Result<Self, CdrError> {
        let mut c = CdrCursor::new(bytes)?;
        // Smallest element: stamp 8, two empty strings 8, 7 float64 56.
        let n = c.sequence_len(72)?;
        let mut transforms = Vec::with_capacity(n);
        for _ in 0..n {
            transforms.push(TransformStamped {
                header: header(&mut c)?,
                child_frame_id: c.string()?,
                transform: Transform {
                    translation: vector3(&mut c)?,
                    rotation: quaternion(&mut c)?,
                },
            });
        }
        Ok(TfMessage { transforms })
    }
}

impl Odometry {
    /// Decodes CDR bytes (with the encapsulation header), checking every length.
    pub fn decode(bytes: &[u8]) -> Result<Self, CdrError> {
        let mut c = CdrCursor::new(bytes)?;
        let header = header(&mut c)?;
        let child_frame_id = c.string()?;
        let position: Point = vector3(&mut c)?;
        let orientation = quaternion(&mut c)?;
        let pose = PoseWithCovariance {
            pose: Pose {
                position,
                orientation,
            },
            covariance: covariance(&mut c)?,
        };
        let twist = TwistWithCovariance {
            twist: Twist {
                linear: vector3(&mut c)?,
                angular: vector3(&mut c)?,
            },
            covariance: covariance(&mut c)?,
        };
        Ok(Odometry {
            header,
            child_frame_id,
            pose,
            twist,
        })
    }
}

/// Decodes a CDR message (with its 4-byte encapsulation header) with the `cdr` crate. Only for
/// trusted bytes: a corrupt string length makes it allocate up to 4 GiB.
pub fn decode_cdr<'de, T: Deserialize<'de>>(bytes: &[u8]) -> Result<T, cdr::Error> {
    // Bounded by the input length: a corrupt length prefix cannot allocate more than the input.
    cdr::deserialize_from(bytes, cdr::Bounded(bytes.len() as u64))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_corrupt_string_length_is_an_error_not_a_huge_allocation() {
        // Little-endian CDR: one transform whose frame_id claims 4 GiB.
        let mut b = vec![0u8, 1, 0, 0];
        b.extend(1u32.to_le_bytes());
        b.extend(5i32.to_le_bytes());
        b.extend(6u32.to_le_bytes());
        b.extend(0xffff_fff0u32.to_le_bytes());
        b.extend(b"map\0");
        b.extend([0u8; 80]);
        assert!(matches!(TfMessage::decode(&b), Err(CdrError::Truncated(_))));
        // A sequence count beyond the message.
        let mut b = vec![0u8, 1, 0, 0];
        b.extend(0x4000_0000u32.to_le_bytes());
        assert!(matches!(
            TfMessage::decode(&b),
            Err(CdrError::SequenceTooLong(..))
        ));
        assert_eq!(TfMessage::decode(&[0, 9, 0, 0]), Err(CdrError::BadHeader));
    }
}
