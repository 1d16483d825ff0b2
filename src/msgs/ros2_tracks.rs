//! The tracks as ROS 2 `vision_msgs/msg/Detection3DArray` messages (message encoding `cdr`,
//! schema encoding `ros2msg`), so that a tracked ROS 2 bag stays readable by ROS tooling
//! (`ros2 bag play`, rosbags, RViz).
//!
//! One message per frame, in the vision_msgs 4.x layout (ROS 2 Humble and later; the layout
//! [`super::ros2_vision`] reads):
//!
//! - `header.stamp` = the frame's stamp, `header.frame_id` = the tracks' frame; every
//!   `Detection3D.header` repeats it;
//! - per track one `Detection3D`: `id` = the track id (decimal), one hypothesis with
//!   `class_id` = label and `score` = the track score, `bbox.center` = centre and the rotation by
//!   the yaw about +z, `bbox.size` = (length, width, height);
//! - the hypothesis `pose` is the box centre pose with a covariance (6 x 6, row-major over x, y,
//!   z, rotation about x, y, z) holding the position variances on the first three diagonal
//!   entries and the yaw variance on the last; the other entries are 0.
//!
//! Velocities and track ages have no field in this message; `--tracks-format probmot` writes
//! them (`probmot.Tracks3D`).

use super::cdr_writer::CdrWriter;
use super::ros2_vision::{self, VisionLayout};
use super::{DecodeError, Track3D, Tracks3D};

/// Schema name of the tracks channel, as rosbag2 names the type.
pub const SCHEMA_NAME: &str = "vision_msgs/msg/Detection3DArray";

/// Schema encoding of the tracks channel.
pub const SCHEMA_ENCODING: &str = "ros2msg";

/// Message encoding of the tracks channel.
pub const MESSAGE_ENCODING: &str = "cdr";

/// The `ros2msg` schema text of `vision_msgs/msg/Detection3DArray` with every dependency, in
/// the layout rosbag2 writes (the top-level definition, then per dependency a line of 80 `=`,
/// `MSG: package/Type` and its definition). Field lines of vision_msgs 4.x (ROS 2 Humble:
/// github.com/ros-perception/vision_msgs, branch ros2, msg/*.msg), geometry_msgs and std_msgs
/// (github.com/ros2/common_interfaces) and builtin_interfaces (github.com/ros2/rcl_interfaces);
/// comments left out.
pub const SCHEMA_TEXT: &str = "\
std_msgs/Header header
Detection3D[] detections

================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id

================================================================================
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec

================================================================================
MSG: vision_msgs/Detection3D
std_msgs/Header header
ObjectHypothesisWithPose[] results
BoundingBox3D bbox
string id

================================================================================
MSG: vision_msgs/ObjectHypothesisWithPose
ObjectHypothesis hypothesis
geometry_msgs/PoseWithCovariance pose

================================================================================
MSG: vision_msgs/ObjectHypothesis
string class_id
float64 score

================================================================================
MSG: geometry_msgs/PoseWithCovariance
Pose pose
float64[36] covariance

================================================================================
MSG: geometry_msgs/Pose
Point position
Quaternion orientation

================================================================================
MSG: geometry_msgs/Point
float64 x
float64 y
float64 z

================================================================================
MSG: geometry_msgs/Quaternion
float64 x 0
float64 y 0
float64 z 0
float64 w 1

================================================================================
MSG: vision_msgs/BoundingBox3D
geometry_msgs/Pose center
geometry_msgs/Vector3 size

================================================================================
MSG: geometry_msgs/Vector3
float64 x
float64 y
float64 z
";

/// Writes one `Detection3D` of a track.
fn write_track(w: &mut CdrWriter<'_>, t: &Track3D, stamp: u64, frame_id: &str) {
    let c = t.center.unwrap_or_default();
    let center = [c.x, c.y, c.z];
    w.header(stamp, frame_id);
    // results: one ObjectHypothesisWithPose.
    w.u32(1);
    w.string(&t.label);
    w.f64(t.score);
    w.pose(center, t.yaw);
    let var = t.position_variance.unwrap_or_default();
    let mut cov = [0.0; 36];
    cov[0] = var.x;
    cov[7] = var.y;
    cov[14] = var.z;
    cov[35] = t.yaw_variance;
    for v in cov {
        w.f64(v);
    }
    // bbox.
    w.pose(center, t.yaw);
    let s = t.size.unwrap_or_default();
    for v in [s.length, s.width, s.height] {
        w.f64(v);
    }
    // id: the decimal track id (no allocation: itoa into a stack buffer).
    let mut digits = [0u8; 20];
    w.string(decimal(t.id, &mut digits));
}

/// The decimal text of `v`, written into `buf`.
fn decimal(mut v: u64, buf: &mut [u8; 20]) -> &str {
    let mut i = buf.len();
    loop {
        i -= 1;
        buf[i] = b'0' + (v % 10) as u8;
        v /= 10;
        if v == 0 {
            break;
        }
    }
    std::str::from_utf8(&buf[i..]).expect("ASCII digits")
}

/// Encodes one frame's tracks as a CDR `vision_msgs/msg/Detection3DArray` into `buf` (cleared
/// first), with the little-endian encapsulation header `00 01 00 00`.
pub fn encode_tracks_into(tracks: &Tracks3D, buf: &mut Vec<u8>) {
    let mut w = CdrWriter::new(buf);
    w.header(tracks.stamp, &tracks.frame_id);
    w.u32(tracks.tracks.len() as u32);
    for t in &tracks.tracks {
        write_track(&mut w, t, tracks.stamp, &tracks.frame_id);
    }
}

/// Reads one CDR `vision_msgs/msg/Detection3DArray` message as tracks (the inverse of
/// [`encode_tracks_into`], for `plot`, `viz`, `eval` and `fit` of a ROS 2 tracks channel): the
/// track id is `Detection3D.id` (vision_msgs 2.x: `tracking_id`), which must be a decimal
/// integer; label, score, centre, size and yaw as [`ros2_vision`] reads detections. A zero
/// `header.stamp` gives stamp 0 (the caller uses the log_time). Velocities, variances and ages
/// stay unset.
pub fn decode_tracks(bytes: &[u8], layout: VisionLayout) -> Result<Tracks3D, DecodeError> {
    let m = ros2_vision::decode(bytes, layout)?;
    let mut tracks = Vec::with_capacity(m.detections.len());
    for (i, mut d) in m.detections.into_iter().enumerate() {
        let id = match d.attributes.remove("id") {
            Some(text) => text.parse::<u64>().map_err(|_| {
                DecodeError::Content(format!(
                    "detection {i}: id '{text}' is not a track number (probmot reads ROS 2 \
                     tracks whose Detection3D.id is a decimal integer)"
                ))
            })?,
            None => {
                return Err(DecodeError::Content(format!(
                    "detection {i} has an empty id; tracks need Detection3D.id set to the \
                     track id (a decimal integer)"
                )))
            }
        };
        tracks.push(Track3D {
            id,
            label: d.label,
            center: d.center,
            size: d.size,
            yaw: d.yaw,
            score: d.score,
            attributes: d.attributes,
            ..Default::default()
        });
    }
    Ok(Tracks3D {
        stamp: m.stamp.unwrap_or(0),
        frame_id: m.frame_id,
        tracks,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msgs::ros2_vision::{decode, detect_layout, VisionLayout};
    use crate::msgs::{size3, v3};

    fn track(id: u64, label: &str, c: [f64; 3], yaw: f64, score: f64) -> Track3D {
        Track3D {
            id,
            label: label.into(),
            center: Some(v3(c)),
            size: Some(size3([4.5, 1.9, 1.6])),
            yaw,
            score,
            position_variance: Some(v3([0.1, 0.2, 0.3])),
            yaw_variance: 0.05,
            ..Default::default()
        }
    }

    #[test]
    fn schema_text_has_the_humble_layout() {
        assert_eq!(
            detect_layout(SCHEMA_TEXT.as_bytes()),
            Ok(VisionLayout::V4),
            "the reader's layout check must accept the schema we write"
        );
    }

    /// Two tracks in `map`; the pedestrian's label of odd length and negative yaw put padding
    /// before the doubles.
    fn two_tracks() -> Tracks3D {
        Tracks3D {
            stamp: 1_700_000_000_250_000_000,
            frame_id: "map".into(),
            tracks: vec![
                track(7, "car", [10.0, -2.5, 0.8], 0.3, 0.9),
                track(12345678901, "pedestrian", [-1.0, 3.0, 0.9], -2.0, 0.55),
            ],
        }
    }

    #[test]
    fn encoded_tracks_decode_with_the_ros2_reader() {
        let msg = two_tracks();
        let mut buf = Vec::new();
        encode_tracks_into(&msg, &mut buf);
        let back = decode(&buf, VisionLayout::V4).unwrap();
        assert_eq!(back.stamp, Some(msg.stamp));
        assert_eq!(back.frame_id, "map");
        assert_eq!(back.detections.len(), 2);
        for (t, d) in msg.tracks.iter().zip(&back.detections) {
            assert_eq!(d.attributes.get("id"), Some(&t.id.to_string()));
            assert_eq!(d.label, t.label);
            assert_eq!(d.score, t.score);
            assert_eq!(d.center, t.center);
            assert_eq!(d.size, t.size);
            assert!((d.yaw - t.yaw).abs() < 1e-12, "{} vs {}", d.yaw, t.yaw);
        }
        // Re-encoding into the same buffer gives the same bytes (it is cleared first).
        let first = buf.clone();
        encode_tracks_into(&msg, &mut buf);
        assert_eq!(buf, first);
    }

    #[test]
    fn tracks_read_back_with_their_ids() {
        let msg = two_tracks();
        let mut buf = Vec::new();
        encode_tracks_into(&msg, &mut buf);
        let back = decode_tracks(&buf, VisionLayout::V4).unwrap();
        assert_eq!((back.stamp, back.frame_id.as_str()), (msg.stamp, "map"));
        let ids: Vec<u64> = back.tracks.iter().map(|t| t.id).collect();
        assert_eq!(ids, [7, 12345678901]);
        for (t, b) in msg.tracks.iter().zip(&back.tracks) {
            assert_eq!((&b.label, b.score), (&t.label, t.score));
            assert_eq!((b.center, b.size), (t.center, t.size));
            assert!((b.yaw - t.yaw).abs() < 1e-12);
            assert!(b.attributes.is_empty());
        }
    }

    #[test]
    fn tracks_without_a_numeric_id_are_refused() {
        // Detections (no id) written in the same layout: no track id to read.
        let mut buf = Vec::new();
        let mut msg = Tracks3D {
            stamp: 5,
            tracks: vec![track(3, "car", [1.0, 2.0, 0.0], 0.0, 0.5)],
            ..Default::default()
        };
        encode_tracks_into(&msg, &mut buf);
        // Replace the id "3" (length 2 with its NUL, the last string of the message) by "x".
        let n = buf.len();
        assert_eq!(&buf[n - 2..], b"3\0");
        buf[n - 2] = b'x';
        let err = decode_tracks(&buf, VisionLayout::V4)
            .unwrap_err()
            .to_string();
        assert!(err.contains("id 'x' is not a track number"), "{err}");
        msg.tracks.clear();
        encode_tracks_into(&msg, &mut buf);
        assert!(decode_tracks(&buf, VisionLayout::V4)
            .unwrap()
            .tracks
            .is_empty());
    }

    #[test]
    fn empty_frame_and_decimal_ids() {
        let mut buf = Vec::new();
        encode_tracks_into(
            &Tracks3D {
                stamp: 5,
                ..Default::default()
            },
            &mut buf,
        );
        let back = decode(&buf, VisionLayout::V4).unwrap();
        assert_eq!((back.stamp, back.detections.len()), (Some(5), 0));
        let mut d = [0u8; 20];
        assert_eq!(decimal(0, &mut d), "0");
        assert_eq!(decimal(u64::MAX, &mut d), u64::MAX.to_string());
    }
}
