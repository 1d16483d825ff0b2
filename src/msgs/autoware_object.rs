//! One Autoware object as read from CDR: the fields `DetectedObject`
//! ([`super::autoware`]) and `TrackedObject` ([`super::autoware_tracks`]) share, the box they
//! describe (the conversion rules are in [`super::autoware`]'s module docs), and the class and
//! shape codes of `ObjectClassification` and `Shape`.

use super::cdr_cursor::{CdrCursor, CdrError};
use super::ros2_common::{Quaternion, Time};
use super::DecodeError;

/// `ObjectClassification` labels by code: probmot's class names for the road users, the
/// lower-case constant names for the rest.
pub const CLASS_NAMES: [&str; 12] = [
    "unknown",
    "car",
    "truck",
    "bus",
    "trailer",
    "motorcycle",
    "bicycle",
    "pedestrian",
    "animal",
    "hazard",
    "over_drivable",
    "under_drivable",
];

/// The label of an `ObjectClassification` code.
pub fn class_name(code: u8) -> String {
    match CLASS_NAMES.get(code as usize) {
        Some(name) => name.to_string(),
        None => format!("label_{code}"),
    }
}

/// The `ObjectClassification` code of a label (UNKNOWN for a label Autoware has no code for).
pub fn class_code(label: &str) -> u8 {
    if let Some(i) = CLASS_NAMES.iter().position(|n| *n == label) {
        return i as u8;
    }
    label
        .strip_prefix("label_")
        .and_then(|n| n.parse().ok())
        .unwrap_or(0)
}

/// `Shape.type` constants.
pub mod shape_type {
    /// `dimensions` = length, width, height.
    pub const BOUNDING_BOX: u8 = 0;
    /// `dimensions.x` = diameter, `dimensions.z` = height.
    pub const CYLINDER: u8 = 1;
    /// `footprint` in the object's frame, `dimensions.z` = height.
    pub const POLYGON: u8 = 2;
}

/// One object as read from the wire: the fields `DetectedObject` and `TrackedObject` share.
#[derive(Debug, Clone, Default)]
pub(crate) struct RawObject {
    /// `existence_probability`.
    pub existence: f32,
    /// `(label, probability)` of the most probable classification (the first on a tie).
    pub class: Option<(u8, f32)>,
    /// Pose position.
    pub position: [f64; 3],
    /// Pose orientation.
    pub orientation: Quaternion,
    /// The pose covariance's variances of x, y, z and of the rotation about z.
    pub pose_variances: [f64; 4],
    /// Twist (linear, angular) in the object's frame, when given.
    pub twist: Option<[f64; 6]>,
    /// `orientation_availability`.
    pub orientation_availability: u8,
    /// The shape.
    pub shape: RawShape,
}

/// `Shape`, with the footprint reduced to its extents in the object's frame.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct RawShape {
    /// `type`.
    pub kind: u8,
    /// `[min x, min y, max x, max y]` of the footprint points, `None` without points.
    pub footprint: Option<[f64; 4]>,
    /// `dimensions`.
    pub dimensions: [f64; 3],
}

/// `std_msgs/Header`: stamp (None when zero) and frame id.
pub(crate) fn read_header(c: &mut CdrCursor) -> Result<(Option<u64>, String), DecodeError> {
    let t = Time {
        sec: c.i32()?,
        nanosec: c.u32()?,
    };
    let frame_id = c.string()?;
    if t.sec == 0 && t.nanosec == 0 {
        return Ok((None, frame_id));
    }
    let stamp = t.to_nanos().ok_or_else(|| {
        DecodeError::Content(format!(
            "header.stamp out of range (sec {}, nanosec {})",
            t.sec, t.nanosec
        ))
    })?;
    Ok((Some(stamp), frame_id))
}

/// `float64` values into `out`.
pub(crate) fn read_f64s(c: &mut CdrCursor, out: &mut [f64]) -> Result<(), CdrError> {
    for v in out {
        *v = c.f64()?;
    }
    Ok(())
}

/// `ObjectClassification[]`: the most probable entry.
pub(crate) fn read_classification(c: &mut CdrCursor) -> Result<Option<(u8, f32)>, CdrError> {
    let n = c.sequence_len(5)?;
    let mut best: Option<(u8, f32)> = None;
    for _ in 0..n {
        let label = c.u8()?;
        let p = c.f32()?;
        if best.is_none_or(|(_, bp)| p > bp) {
            best = Some((label, p));
        }
    }
    Ok(best)
}

/// `geometry_msgs/PoseWithCovariance` into `o`.
pub(crate) fn read_pose(c: &mut CdrCursor, o: &mut RawObject) -> Result<(), CdrError> {
    read_f64s(c, &mut o.position)?;
    let mut q = [0.0; 4];
    read_f64s(c, &mut q)?;
    o.orientation = Quaternion {
        x: q[0],
        y: q[1],
        z: q[2],
        w: q[3],
    };
    let mut cov = [0.0; 36];
    read_f64s(c, &mut cov)?;
    o.pose_variances = [cov[0], cov[7], cov[14], cov[35]];
    Ok(())
}

/// `geometry_msgs/TwistWithCovariance` (or `AccelWithCovariance`): the six values, the
/// covariance skipped.
pub(crate) fn read_twist(c: &mut CdrCursor) -> Result<[f64; 6], CdrError> {
    let mut t = [0.0; 6];
    read_f64s(c, &mut t)?;
    let mut cov = [0.0; 36];
    read_f64s(c, &mut cov)?;
    Ok(t)
}

/// `Shape`.
pub(crate) fn read_shape(c: &mut CdrCursor) -> Result<RawShape, CdrError> {
    let kind = c.u8()?;
    let n = c.sequence_len(12)?;
    let mut footprint: Option<[f64; 4]> = None;
    for _ in 0..n {
        let (x, y, _z) = (c.f32()? as f64, c.f32()? as f64, c.f32()?);
        let e = footprint.get_or_insert([x, y, x, y]);
        *e = [e[0].min(x), e[1].min(y), e[2].max(x), e[3].max(y)];
    }
    let mut dimensions = [0.0; 3];
    read_f64s(c, &mut dimensions)?;
    Ok(RawShape {
        kind,
        footprint,
        dimensions,
    })
}

impl RawObject {
    /// The label of the most probable class (`unknown` without a classification).
    pub fn label(&self) -> String {
        class_name(self.class.map_or(0, |(l, _)| l))
    }

    /// Yaw about z of the pose (NaN for a zero or non-finite quaternion, which the box check
    /// then rejects).
    pub fn yaw(&self) -> f64 {
        self.orientation.yaw().unwrap_or(f64::NAN)
    }

    /// Centre and size of the box the shape describes (module docs), `None` for an unknown
    /// shape type or a polygon without points.
    pub fn center_and_size(&self) -> Option<([f64; 3], [f64; 3])> {
        let d = self.shape.dimensions;
        let p = self.position;
        match self.shape.kind {
            shape_type::BOUNDING_BOX => Some((p, d)),
            shape_type::CYLINDER => Some((p, [d[0], d[0], d[2]])),
            shape_type::POLYGON => {
                let [x0, y0, x1, y1] = self.shape.footprint?;
                let (cx, cy) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0);
                let (s, c) = self.yaw().sin_cos();
                let center = [p[0] + c * cx - s * cy, p[1] + s * cx + c * cy, p[2]];
                Some((center, [x1 - x0, y1 - y0, d[2]]))
            }
            _ => None,
        }
    }

    /// The twist's linear velocity rotated from the object's frame into the message frame.
    pub fn velocity(&self) -> Option<[f64; 3]> {
        let t = self.twist?;
        let (s, c) = self.yaw().sin_cos();
        Some([c * t[0] - s * t[1], s * t[0] + c * t[1], t[2]])
    }
}
