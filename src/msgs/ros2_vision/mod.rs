//! ROS 2 `vision_msgs/msg/Detection3DArray` (message encoding `cdr`, schema encoding `ros2msg`)
//! as probmot detections.
//!
//! CDR carries no field names, so the bytes can only be read with the right field layout. The
//! layout is checked against the channel's schema text (the `.msg` definitions that rosbag2 and
//! `mcap-ros2-support` store in the schema record) before any message is read: probmot reads the
//! layout of vision_msgs 4.x (ROS 2 Humble and later):
//!
//! ```text
//! Detection3DArray         std_msgs/Header header, Detection3D[] detections
//! Detection3D              std_msgs/Header header, ObjectHypothesisWithPose[] results,
//!                          BoundingBox3D bbox, string id
//! ObjectHypothesisWithPose ObjectHypothesis hypothesis, geometry_msgs/PoseWithCovariance pose
//! ObjectHypothesis         string class_id, float64 score
//! BoundingBox3D            geometry_msgs/Pose center, geometry_msgs/Vector3 size
//! ```
//!
//! and the layout of vision_msgs 2.x (ROS 2 Foxy):
//!
//! ```text
//! Detection3D              std_msgs/Header header, ObjectHypothesisWithPose[] results,
//!                          BoundingBox3D bbox, sensor_msgs/PointCloud2 source_cloud,
//!                          bool is_tracking, string tracking_id
//! ObjectHypothesisWithPose string id, float64 score, geometry_msgs/PoseWithCovariance pose
//! ```
//!
//! (the class is the hypothesis `id`, the per-object id `tracking_id`; the point cloud is read
//! and dropped). Any other layout is refused with the differing fields named.
//!
//! Conversion: stamp = the array's `header.stamp` (a zero stamp counts as unset, so the MCAP
//! log_time is used), frame_id = the array's `header.frame_id`; per detection the box centre is
//! `bbox.center.position`, yaw the rotation about z of `bbox.center.orientation`, size
//! `bbox.size` (x along the heading = length, y = width, z = height); label and score come from
//! the hypothesis with the highest score (the first one on a tie; empty label and score 0 when
//! there is none); a non-empty `id` (2.x: `tracking_id`) is kept as the attribute `id`. The
//! per-detection headers are not used.
//!
//! A class id or per-object id that is not UTF-8 costs its box, not the message
//! ([`decode_lenient`]); any other string that is not UTF-8 fails the message.

use serde::de::{self, Deserializer, SeqAccess, Visitor};
use serde::Deserialize;

use super::detection_frame::SkipReason;
use super::ros2_common::{cdr_string, Header, LossyString, Pose, Vector3};
use super::ros2_schema::{self, fields, Expected, Fields, Sections};
use super::{v3, DecodeError, Detection3D, Detections3D, Size3};

/// Schema names accepted for `vision_msgs/msg/Detection3DArray` (rosbag2 writes the first).
pub const SCHEMA_NAMES: [&str; 2] = [
    "vision_msgs/msg/Detection3DArray",
    "vision_msgs/Detection3DArray",
];

/// The field layouts of `vision_msgs/msg/Detection3DArray` probmot can read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum VisionLayout {
    /// vision_msgs 4.x (ROS 2 Humble, Jazzy, Kilted, Rolling).
    V4,
    /// vision_msgs 2.x (ROS 2 Foxy).
    V2,
}

impl VisionLayout {
    /// Short description for messages and `probmot info`.
    pub fn describe(self) -> &'static str {
        match self {
            VisionLayout::V4 => "vision_msgs 4.x layout",
            VisionLayout::V2 => "vision_msgs 2.x layout",
        }
    }
}

/// `(type name, required, fields)` of the message types of one layout. The vision_msgs types
/// must be defined in the schema text; the geometry and std types are checked when present.
fn expected_sections(layout: VisionLayout) -> Vec<(&'static str, bool, Fields)> {
    // Detection3D first: the most telling difference between layouts.
    let mut all = match layout {
        VisionLayout::V4 => v4_sections(),
        VisionLayout::V2 => v2_sections(),
    };
    all.append(&mut common_sections());
    all
}

/// The sections both layouts share: the array, the box and the geometry and std types.
fn common_sections() -> Vec<(&'static str, bool, Fields)> {
    let float3 = [("float64", "x"), ("float64", "y"), ("float64", "z")];
    vec![
        (
            "Detection3DArray",
            true,
            fields(&[("Header", "header"), ("Detection3D[]", "detections")]),
        ),
        (
            "BoundingBox3D",
            true,
            fields(&[("Pose", "center"), ("Vector3", "size")]),
        ),
        (
            "PoseWithCovariance",
            false,
            fields(&[("Pose", "pose"), ("float64[36]", "covariance")]),
        ),
        (
            "Pose",
            false,
            fields(&[("Point", "position"), ("Quaternion", "orientation")]),
        ),
        ("Point", false, fields(&float3)),
        ("Vector3", false, fields(&float3)),
        (
            "Quaternion",
            false,
            fields(&[
                ("float64", "x"),
                ("float64", "y"),
                ("float64", "z"),
                ("float64", "w"),
            ]),
        ),
        (
            "Header",
            false,
            fields(&[("Time", "stamp"), ("string", "frame_id")]),
        ),
        (
            "Time",
            false,
            fields(&[("int32", "sec"), ("uint32", "nanosec")]),
        ),
    ]
}

/// The sections of the vision_msgs 4.x layout ([`VisionLayout::V4`]).
fn v4_sections() -> Vec<(&'static str, bool, Fields)> {
    vec![
        (
            "Detection3D",
            true,
            fields(&[
                ("Header", "header"),
                ("ObjectHypothesisWithPose[]", "results"),
                ("BoundingBox3D", "bbox"),
                ("string", "id"),
            ]),
        ),
        (
            "ObjectHypothesisWithPose",
            true,
            fields(&[
                ("ObjectHypothesis", "hypothesis"),
                ("PoseWithCovariance", "pose"),
            ]),
        ),
        (
            "ObjectHypothesis",
            true,
            fields(&[("string", "class_id"), ("float64", "score")]),
        ),
    ]
}

/// The sections of the vision_msgs 2.x layout ([`VisionLayout::V2`]).
fn v2_sections() -> Vec<(&'static str, bool, Fields)> {
    vec![
        (
            "Detection3D",
            true,
            fields(&[
                ("Header", "header"),
                ("ObjectHypothesisWithPose[]", "results"),
                ("BoundingBox3D", "bbox"),
                ("PointCloud2", "source_cloud"),
                ("bool", "is_tracking"),
                ("string", "tracking_id"),
            ]),
        ),
        (
            "ObjectHypothesisWithPose",
            true,
            fields(&[
                ("string", "id"),
                ("float64", "score"),
                ("PoseWithCovariance", "pose"),
            ]),
        ),
        (
            "PointCloud2",
            false,
            fields(&[
                ("Header", "header"),
                ("uint32", "height"),
                ("uint32", "width"),
                ("PointField[]", "fields"),
                ("bool", "is_bigendian"),
                ("uint32", "point_step"),
                ("uint32", "row_step"),
                ("uint8[]", "data"),
                ("bool", "is_dense"),
            ]),
        ),
        (
            "PointField",
            false,
            fields(&[
                ("string", "name"),
                ("uint32", "offset"),
                ("uint8", "datatype"),
                ("uint32", "count"),
            ]),
        ),
    ]
}

/// Why the schema text does not have `layout`, or `Ok`.
fn check_layout(sections: &Sections, layout: VisionLayout) -> Result<(), String> {
    let expected: Vec<Expected> = expected_sections(layout)
        .into_iter()
        .map(|(name, required, fields)| Expected {
            name,
            required,
            fields,
        })
        .collect();
    ros2_schema::check(sections, &expected, layout.describe())
}

/// Finds the layout of a channel from its schema record (`ros2msg` text).
pub fn detect_layout(schema_data: &[u8]) -> Result<VisionLayout, String> {
    let text =
        std::str::from_utf8(schema_data).map_err(|_| "the schema text is not UTF-8".to_string())?;
    let sections = ros2_schema::parse_msg(text, "Detection3DArray");
    let v4 = match check_layout(&sections, VisionLayout::V4) {
        Ok(()) => return Ok(VisionLayout::V4),
        Err(why) => why,
    };
    match check_layout(&sections, VisionLayout::V2) {
        Ok(()) => Ok(VisionLayout::V2),
        Err(v2) if v2 == v4 => Err(v4),
        Err(v2) => Err(format!("{v4}; and {v2}")),
    }
}

/// `vision_msgs/msg/Detection3DArray` (4.x).
#[derive(Deserialize)]
struct Detection3DArray {
    header: Header,
    detections: Vec<RosDetection3D>,
}

/// `vision_msgs/msg/Detection3D` (4.x).
#[derive(Deserialize)]
struct RosDetection3D {
    #[allow(dead_code)]
    header: Header,
    results: Vec<ObjectHypothesisWithPose>,
    bbox: BoundingBox3D,
    id: LossyString,
}

/// `vision_msgs/msg/ObjectHypothesisWithPose` (4.x).
#[derive(Deserialize)]
struct ObjectHypothesisWithPose {
    hypothesis: ObjectHypothesis,
    #[allow(dead_code)]
    pose: PoseWithCovariance,
}

/// `vision_msgs/msg/ObjectHypothesis` (4.x).
#[derive(Deserialize)]
struct ObjectHypothesis {
    class_id: LossyString,
    score: f64,
}

/// `geometry_msgs/msg/PoseWithCovariance` (the covariance is read and dropped).
#[derive(Deserialize)]
struct PoseWithCovariance {
    #[allow(dead_code)]
    pose: Pose,
    #[allow(dead_code)]
    covariance: Covariance,
}

/// `vision_msgs/msg/BoundingBox3D`.
#[derive(Deserialize)]
struct BoundingBox3D {
    center: Pose,
    size: Vector3,
}

/// `vision_msgs/msg/Detection3DArray` (2.x).
#[derive(Deserialize)]
struct Detection3DArrayV2 {
    header: Header,
    detections: Vec<RosDetection3DV2>,
}

/// `vision_msgs/msg/Detection3D` (2.x).
#[derive(Deserialize)]
struct RosDetection3DV2 {
    #[allow(dead_code)]
    header: Header,
    results: Vec<ObjectHypothesisWithPoseV2>,
    bbox: BoundingBox3D,
    #[allow(dead_code)]
    source_cloud: PointCloud2,
    #[allow(dead_code)]
    is_tracking: bool,
    tracking_id: LossyString,
}

/// `vision_msgs/msg/ObjectHypothesisWithPose` (2.x).
#[derive(Deserialize)]
struct ObjectHypothesisWithPoseV2 {
    id: LossyString,
    score: f64,
    #[allow(dead_code)]
    pose: PoseWithCovariance,
}

/// `sensor_msgs/msg/PointCloud2` (read to get past it; the points are not used).
#[allow(dead_code)]
#[derive(Deserialize)]
struct PointCloud2 {
    header: Header,
    height: u32,
    width: u32,
    fields: Vec<PointField>,
    is_bigendian: bool,
    point_step: u32,
    row_step: u32,
    data: Vec<u8>,
    is_dense: bool,
}

/// `sensor_msgs/msg/PointField`.
#[allow(dead_code)]
#[derive(Deserialize)]
struct PointField {
    #[serde(deserialize_with = "cdr_string")]
    name: String,
    offset: u32,
    datatype: u8,
    count: u32,
}

/// One detection of either layout: hypotheses `(class, score)`, box, per-object id, and why
/// the box is rejected, if it is.
struct RosBox {
    hypotheses: Vec<(String, f64)>,
    bbox: BoundingBox3D,
    id: String,
    fault: Option<SkipReason>,
}

impl RosBox {
    /// A box from its hypotheses, bounding box and per-object id, read lossily; its fault as
    /// [`decode_lenient`] gives it (any hypothesis' class id first, then the id).
    fn new(
        hypotheses: impl Iterator<Item = (LossyString, f64)>,
        bbox: BoundingBox3D,
        id: LossyString,
    ) -> RosBox {
        let mut labels_utf8 = true;
        let hypotheses = hypotheses
            .map(|(class, score)| {
                labels_utf8 &= class.utf8;
                (class.text, score)
            })
            .collect();
        let fault = match (labels_utf8, id.utf8) {
            (false, _) => Some(SkipReason::LabelNotUtf8),
            (true, false) => Some(SkipReason::IdNotUtf8),
            (true, true) => None,
        };
        RosBox {
            hypotheses,
            bbox,
            id: id.text,
            fault,
        }
    }
}

/// `float64[36]`: a fixed-size array, no length on the wire (serde's arrays stop at 32).
struct Covariance;

impl<'de> Deserialize<'de> for Covariance {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = Covariance;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("36 float64")
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Covariance, A::Error> {
                for i in 0..36 {
                    seq.next_element::<f64>()?
                        .ok_or_else(|| de::Error::invalid_length(i, &self))?;
                }
                Ok(Covariance)
            }
        }
        d.deserialize_tuple(36, V)
    }
}

/// Decodes one CDR message (with its 4-byte encapsulation header) of the given layout; a box
/// whose class id or id is not UTF-8 fails the message (as a probmot protobuf label does
/// outside `track`; [`decode_lenient`] keeps the message).
pub fn decode(bytes: &[u8], layout: VisionLayout) -> Result<Detections3D, DecodeError> {
    let (msg, rejected) = decode_lenient(bytes, layout)?;
    match rejected.first() {
        None => Ok(msg),
        Some((i, reason)) => Err(DecodeError::Content(format!(
            "detection {i}: {}",
            reason.describe()
        ))),
    }
}

/// Decodes one CDR message as [`decode`] does, but a box whose class id or per-object id is not
/// UTF-8 is decoded with those strings read lossily and named in the list `(index, reason)` for
/// the caller to reject. The class id of *any* hypothesis of the box counts, not only the best
/// one's ([`SkipReason::LabelNotUtf8`]): a detector that garbles one class id may garble the
/// scores too, so the best valid hypothesis may be the wrong one. Else a per-object id that is
/// not UTF-8 rejects the box ([`SkipReason::IdNotUtf8`]): the id is copied to the track, and a
/// lossy copy is not the id the detector gave. Any other string that is not UTF-8
/// (`header.frame_id`, a point field name) fails the message.
pub fn decode_lenient(
    bytes: &[u8],
    layout: VisionLayout,
) -> Result<(Detections3D, Vec<(u32, SkipReason)>), DecodeError> {
    // XCDR2 encapsulations (ids 6-11) align 8-byte values to 4; the `cdr` crate reads only the
    // classic ids 0-3, which are what ROS 2 (Fast DDS, Cyclone DDS) record.
    match layout {
        VisionLayout::V4 => {
            let msg: Detection3DArray = cdr::deserialize(bytes)?;
            let boxes = msg.detections.into_iter().map(|d| {
                let results = d.results.into_iter();
                let hypotheses = results.map(|r| (r.hypothesis.class_id, r.hypothesis.score));
                RosBox::new(hypotheses, d.bbox, d.id)
            });
            convert(msg.header, boxes)
        }
        VisionLayout::V2 => {
            let msg: Detection3DArrayV2 = cdr::deserialize(bytes)?;
            let boxes = msg.detections.into_iter().map(|d| {
                let hypotheses = d.results.into_iter().map(|r| (r.id, r.score));
                RosBox::new(hypotheses, d.bbox, d.tracking_id)
            });
            convert(msg.header, boxes)
        }
    }
}

/// The message of `header` and `boxes`, and the `(index, reason)` of the rejected boxes.
fn convert(
    header: Header,
    boxes: impl Iterator<Item = RosBox>,
) -> Result<(Detections3D, Vec<(u32, SkipReason)>), DecodeError> {
    let t = header.stamp;
    let stamp = if t.sec == 0 && t.nanosec == 0 {
        None
    } else {
        Some(t.to_nanos().ok_or_else(|| {
            DecodeError::Content(format!(
                "header.stamp out of range (sec {}, nanosec {})",
                t.sec, t.nanosec
            ))
        })?)
    };
    let mut rejected = Vec::new();
    let detections = boxes
        .enumerate()
        .map(|(i, d)| {
            if let Some(reason) = d.fault {
                rejected.push((i as u32, reason));
            }
            let mut best: Option<(String, f64)> = None;
            for h in d.hypotheses {
                if best.as_ref().is_none_or(|b| h.1 > b.1) {
                    best = Some(h);
                }
            }
            let (label, score) = best.unwrap_or_default();
            let p = d.bbox.center.position;
            let s = d.bbox.size;
            let mut det = Detection3D::default();
            if !d.id.is_empty() {
                det.attributes.insert("id".to_string(), d.id);
            }
            Detection3D {
                center: Some(v3([p.x, p.y, p.z])),
                size: Some(Size3 {
                    length: s.x,
                    width: s.y,
                    height: s.z,
                }),
                yaw: d.bbox.center.orientation.yaw().unwrap_or(f64::NAN),
                label,
                score,
                ..det
            }
        })
        .collect();
    let msg = Detections3D {
        stamp,
        frame_id: header.frame_id,
        detections,
    };
    Ok((msg, rejected))
}

#[cfg(test)]
mod tests;
