//! ROS 2 `vision_msgs/msg/Detection3DArray` (message encoding `cdr`, schema encoding `ros2msg`)
//! as probmot detections.
//!
//! CDR carries no field names, so the bytes can only be read with the right field layout. The
//! layout is checked against the channel's schema text (the `.msg` definitions that rosbag2 and
//! `mcap-ros2-support` store in the schema record) before any message is read: probmot reads the
//! layout of vision_msgs 4.x (ROS 2 Humble and later; the same message definitions since 3.0):
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
//! Any other layout (for example vision_msgs 2.x with `source_cloud`, `is_tracking` and
//! `tracking_id`) is refused with the differing fields named.
//!
//! Conversion: stamp = the array's `header.stamp` (a zero stamp counts as unset, so the MCAP
//! log_time is used), frame_id = the array's `header.frame_id`; per detection the box centre is
//! `bbox.center.position`, yaw the rotation about z of `bbox.center.orientation`, size
//! `bbox.size` (x along the heading = length, y = width, z = height); label and score come from
//! the hypothesis with the highest score (the first one on a tie; empty label and score 0 when
//! there is none); a non-empty `id` is kept as the attribute `id`. The per-detection headers are
//! not used.

use std::collections::BTreeMap;

use serde::de::{self, Deserializer, SeqAccess, Visitor};
use serde::Deserialize;

use super::ros2_common::{cdr_string, Header, Pose, Vector3};
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
}

impl VisionLayout {
    /// Short description for messages and `probmot info`.
    pub fn describe(self) -> &'static str {
        match self {
            VisionLayout::V4 => "vision_msgs 4.x layout",
        }
    }
}

/// `(type, name)` of each field, as the `.msg` text writes them.
type Fields = Vec<(String, String)>;

/// The fields of each message type a ros2msg schema text defines, by type name without package
/// (`Detection3D`, `Header`, ...). The top-level type is stored under `top`.
fn parse_sections(text: &str, top: &str) -> BTreeMap<String, Fields> {
    let mut out: BTreeMap<String, Fields> = BTreeMap::new();
    let mut current = top.to_string();
    let mut after_separator = false;
    out.entry(current.clone()).or_default();
    for raw in text.lines() {
        let line = raw.split('#').next().unwrap_or("").trim();
        if line.starts_with("===") {
            after_separator = true;
            continue;
        }
        if after_separator {
            if let Some(name) = line.strip_prefix("MSG:") {
                current = base_name(name.trim()).to_string();
                out.entry(current.clone()).or_default();
                after_separator = false;
                continue;
            }
        }
        let tokens: Vec<&str> = line.split_whitespace().collect();
        if tokens.len() < 2 {
            continue;
        }
        // Constants: `TYPE NAME=VALUE` or `TYPE NAME = VALUE`.
        if tokens[1].contains('=') || tokens.get(2) == Some(&"=") {
            continue;
        }
        out.entry(current.clone())
            .or_default()
            .push((base_name(tokens[0]).to_string(), tokens[1].to_string()));
    }
    out
}

/// `pkg/msg/Type` or `pkg/Type` -> `Type` (array suffixes kept).
fn base_name(t: &str) -> &str {
    t.rsplit('/').next().unwrap_or(t)
}

fn fields(spec: &[(&str, &str)]) -> Fields {
    spec.iter()
        .map(|(t, n)| (t.to_string(), n.to_string()))
        .collect()
}

fn show(f: &Fields) -> String {
    if f.is_empty() {
        return "no fields".into();
    }
    f.iter()
        .map(|(t, n)| format!("{t} {n}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Finds the layout of a channel from its schema record (`ros2msg` text). The vision_msgs
/// types must be defined in the text; the geometry and std types are checked when present.
pub fn detect_layout(schema_data: &[u8]) -> Result<VisionLayout, String> {
    let text =
        std::str::from_utf8(schema_data).map_err(|_| "the schema text is not UTF-8".to_string())?;
    let sections = parse_sections(text, "Detection3DArray");
    let float3 = [("float64", "x"), ("float64", "y"), ("float64", "z")];
    let expected: [(&str, bool, Fields); 11] = [
        (
            "Detection3DArray",
            true,
            fields(&[("Header", "header"), ("Detection3D[]", "detections")]),
        ),
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
    ];
    for (name, required, want) in &expected {
        match sections.get(*name) {
            Some(got) if got == want => {}
            Some(got) => {
                return Err(format!(
                    "{name} has fields [{}]; probmot reads the {} [{}]",
                    show(got),
                    VisionLayout::V4.describe(),
                    show(want)
                ))
            }
            None if *required => {
                return Err(format!(
                    "the schema text does not define {name}, so the field layout cannot be checked"
                ))
            }
            None => {}
        }
    }
    if let Some(time) = sections.get("Time") {
        let want = fields(&[("int32", "sec"), ("uint32", "nanosec")]);
        if *time != want {
            return Err(format!(
                "Time has fields [{}]; expected [{}]",
                show(time),
                show(&want)
            ));
        }
    }
    Ok(VisionLayout::V4)
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
    #[serde(deserialize_with = "cdr_string")]
    id: String,
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
    #[serde(deserialize_with = "cdr_string")]
    class_id: String,
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

/// Decodes one CDR message (with its 4-byte encapsulation header) of the given layout.
pub fn decode(bytes: &[u8], layout: VisionLayout) -> Result<Detections3D, DecodeError> {
    match layout {
        VisionLayout::V4 => {
            // XCDR2 encapsulations (ids 6-11) align 8-byte values to 4; the `cdr` crate reads
            // only the classic ids 0-3, which are what ROS 2 (Fast DDS, Cyclone DDS) record.
            let msg: Detection3DArray = cdr::deserialize(bytes)?;
            convert(msg)
        }
    }
}

fn convert(msg: Detection3DArray) -> Result<Detections3D, DecodeError> {
    let t = msg.header.stamp;
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
    let detections = msg
        .detections
        .into_iter()
        .map(|d| {
            let mut best: Option<ObjectHypothesis> = None;
            for r in d.results {
                if best.as_ref().is_none_or(|b| r.hypothesis.score > b.score) {
                    best = Some(r.hypothesis);
                }
            }
            let (label, score) = best.map(|b| (b.class_id, b.score)).unwrap_or_default();
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
    Ok(Detections3D {
        stamp,
        frame_id: msg.header.frame_id,
        detections,
    })
}
