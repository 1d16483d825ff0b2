//! ROS 2 message types shared by the ROS 2 decoders (`std_msgs`, `builtin_interfaces`,
//! `geometry_msgs`), as serde structs in field order for CDR decoding with the `cdr` crate.
//!
//! Field order and types follow the `.msg` definitions of ROS 2 (Humble and later); CDR has no
//! field names, so the order here is the wire format.

use serde::Deserialize;

/// `builtin_interfaces/msg/Time`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize)]
pub struct Time {
    /// Seconds.
    pub sec: i32,
    /// Nanoseconds within the second.
    pub nanosec: u32,
}

impl Time {
    /// Nanoseconds since the epoch; `None` for a negative or out-of-range time.
    pub fn to_nanos(self) -> Option<u64> {
        if self.sec < 0 || self.nanosec >= 1_000_000_000 {
            return None;
        }
        Some(self.sec as u64 * 1_000_000_000 + self.nanosec as u64)
    }
}

/// `std_msgs/msg/Header`.
#[derive(Debug, Clone, Default, PartialEq, Deserialize)]
pub struct Header {
    /// Acquisition time.
    pub stamp: Time,
    /// Coordinate frame of the data.
    #[serde(deserialize_with = "cdr_string")]
    pub frame_id: String,
}

/// Reads a ROS 2 CDR `string` (a `uint32` length that counts the terminating NUL, the bytes, the
/// NUL) for `#[serde(deserialize_with = "cdr_string")]`.
///
/// The `cdr` crate's own `String` reader allocates and zero-fills the declared length before it
/// checks that the bytes are there, so a corrupted length of 4 GiB costs 4 GiB of memory before
/// the error. Read as a byte sequence instead, serde reserves at most 1 MiB up front and the
/// read fails at the end of the data. A zero length (no NUL, written by some non-ROS writers) is
/// read as the empty string; otherwise the last byte must be NUL and the rest UTF-8.
pub fn cdr_string<'de, D: serde::Deserializer<'de>>(d: D) -> Result<String, D::Error> {
    use serde::de::Error as _;
    String::from_utf8(cdr_string_bytes(d)?).map_err(|e| D::Error::custom(format!("string: {e}")))
}

/// The bytes of a ROS 2 CDR `string` without its terminating NUL (see [`cdr_string`]).
fn cdr_string_bytes<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Vec<u8>, D::Error> {
    use serde::de::Error as _;
    let mut bytes = Vec::<u8>::deserialize(d)?;
    match bytes.pop() {
        None | Some(0) => Ok(bytes),
        Some(_) => Err(D::Error::custom("string without its terminating NUL")),
    }
}

/// A ROS 2 CDR `string` that may not be UTF-8 (read as [`cdr_string`] otherwise), for the
/// strings whose fault costs one box rather than the message: the text with invalid sequences
/// replaced by U+FFFD, and whether the bytes were UTF-8. Valid bytes become the text without a
/// copy; only an invalid string is copied.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LossyString {
    /// The text (lossy when `utf8` is false).
    pub text: String,
    /// Whether the bytes were valid UTF-8.
    pub utf8: bool,
}

impl<'de> Deserialize<'de> for LossyString {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        Ok(match String::from_utf8(cdr_string_bytes(d)?) {
            Ok(text) => LossyString { text, utf8: true },
            Err(e) => LossyString {
                text: String::from_utf8_lossy(e.as_bytes()).into_owned(),
                utf8: false,
            },
        })
    }
}

/// `geometry_msgs/msg/Vector3` (also the layout of `geometry_msgs/msg/Point`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize)]
pub struct Vector3 {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
}

/// `geometry_msgs/msg/Point`.
pub type Point = Vector3;

/// `geometry_msgs/msg/Quaternion`.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
pub struct Quaternion {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
    /// w.
    pub w: f64,
}

impl Default for Quaternion {
    fn default() -> Self {
        Quaternion {
            x: 0.0,
            y: 0.0,
            z: 0.0,
            w: 1.0,
        }
    }
}

impl Quaternion {
    /// Rotation about z (yaw, radians) of this quaternion, ZYX convention; `None` when the
    /// quaternion is zero or not finite.
    pub fn yaw(&self) -> Option<f64> {
        let n2 = self.x * self.x + self.y * self.y + self.z * self.z + self.w * self.w;
        if !(n2.is_finite() && n2 > 0.0) {
            return None;
        }
        // Scale-invariant form: both arguments scale with |q|^2.
        let siny = 2.0 * (self.w * self.z + self.x * self.y);
        let cosy = self.w * self.w + self.x * self.x - self.y * self.y - self.z * self.z;
        Some(siny.atan2(cosy))
    }
}

/// `geometry_msgs/msg/Pose`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize)]
pub struct Pose {
    /// Position.
    pub position: Point,
    /// Orientation.
    pub orientation: Quaternion,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn yaw_of_rotation_about_z_and_of_unnormalised_quaternion() {
        let a: f64 = 0.7;
        let q = Quaternion {
            x: 0.0,
            y: 0.0,
            z: (a / 2.0).sin(),
            w: (a / 2.0).cos(),
        };
        assert!((q.yaw().unwrap() - a).abs() < 1e-12);
        let q2 = Quaternion {
            x: 0.0,
            y: 0.0,
            z: 3.0 * q.z,
            w: 3.0 * q.w,
        };
        assert!((q2.yaw().unwrap() - a).abs() < 1e-12);
        assert!(Quaternion {
            x: 0.0,
            y: 0.0,
            z: 0.0,
            w: 0.0
        }
        .yaw()
        .is_none());
        assert_eq!(Time { sec: 2, nanosec: 5 }.to_nanos(), Some(2_000_000_005));
        assert_eq!(
            Time {
                sec: -1,
                nanosec: 0
            }
            .to_nanos(),
            None
        );
    }
}
