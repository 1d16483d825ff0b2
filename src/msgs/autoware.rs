//! Autoware's detected objects (`autoware_perception_msgs/msg/DetectedObjects`, and the older
//! `autoware_auto_perception_msgs/msg/DetectedObjects` of the same structure; message encoding
//! `cdr`) as probmot detections, and the object fields they share with Autoware's tracked
//! objects ([`super::autoware_tracks`]).
//!
//! The field layout is checked against the channel's schema record (`ros2msg` or `ros2idl`,
//! [`super::ros2_schema`]) before any message is read. The layout (autoware_msgs 1.x,
//! github.com/autowarefoundation/autoware_msgs `autoware_perception_msgs/msg/*.msg`, unchanged
//! since May 2024; tier4/autoware_auto_msgs `autoware_auto_perception_msgs/msg/*.idl`):
//!
//! ```text
//! DetectedObjects          std_msgs/Header header, DetectedObject[] objects
//! DetectedObject           float32 existence_probability, ObjectClassification[] classification,
//!                          DetectedObjectKinematics kinematics, Shape shape
//! ObjectClassification     uint8 label, float32 probability
//! DetectedObjectKinematics geometry_msgs/PoseWithCovariance pose_with_covariance,
//!                          bool has_position_covariance, uint8 orientation_availability,
//!                          geometry_msgs/TwistWithCovariance twist_with_covariance,
//!                          bool has_twist, bool has_twist_covariance
//! Shape                    uint8 type, geometry_msgs/Polygon footprint,
//!                          geometry_msgs/Vector3 dimensions
//! ```
//!
//! Conversion of one object:
//!
//! - **label**: the classification with the highest probability (the first on a tie; UNKNOWN
//!   without any). CAR, TRUCK, BUS, TRAILER, MOTORCYCLE, BICYCLE and PEDESTRIAN are probmot's
//!   classes `car`, `truck`, `bus`, `trailer`, `motorcycle`, `bicycle`, `pedestrian`. UNKNOWN,
//!   ANIMAL, HAZARD, OVER_DRIVABLE and UNDER_DRIVABLE keep their names in lower case
//!   (`unknown`, `animal`, ...; a code beyond them is `label_N`); such a box is tracked only
//!   when the config has an entry of that very name, never with the config's `default` entry
//!   (which holds another class's statistics), and is otherwise skipped and counted
//!   ([`is_class_without_probmot_class`]).
//! - **score**: `existence_probability`. Autoware's learned detectors (CenterPoint, TransFusion,
//!   PointPainting) write their detection confidence there and set the classification
//!   probability to 1, so the classification probability would make every box certain; it only
//!   chooses the label.
//! - **centre and yaw**: `kinematics.pose_with_covariance.pose` (yaw = rotation about z).
//!   `orientation_availability` other than AVAILABLE is kept as the attribute
//!   `orientation_availability` (`sign_unknown`, `unavailable`), which the track of the box
//!   carries into its Autoware output.
//! - **size**: BOUNDING_BOX: `dimensions` x, y, z = length, width, height. CYLINDER: the
//!   diameter `dimensions.x` as length and width, height `dimensions.z`. POLYGON: the footprint
//!   points are in the object's frame (relative to the pose, as Autoware's tracker reads them),
//!   and the box is their axis-aligned bounding box in that frame (so it keeps the pose's yaw):
//!   length and width its extents along x and y, the centre moved to its middle, height
//!   `dimensions.z`. Another shape type gives no size (the box is skipped, counted as a missing
//!   field).
//! - **velocity**: with `has_twist`, `twist.linear` is in the object's frame (x forward, as
//!   Autoware's trackers read it); it is rotated by the yaw into the message frame.

pub use super::autoware_object::{class_code, class_name, shape_type, CLASS_NAMES};
use super::autoware_object::{
    read_classification, read_header, read_pose, read_shape, read_twist, RawObject,
};
use super::cdr_cursor::CdrCursor;
use super::detection_frame::DetectionFrame;
use super::ros2_schema::{self, fields, Expected, Sections};
use super::{v3, DecodeError, Detection3D, Detections3D, Size3};

/// Schema names of the detected objects probmot reads (the current package first).
pub const DETECTED_SCHEMA_NAMES: [&str; 2] = [
    "autoware_perception_msgs/msg/DetectedObjects",
    "autoware_auto_perception_msgs/msg/DetectedObjects",
];

/// Autoware's topic of the detections its tracker reads.
pub const DETECTION_TOPIC: &str = "/perception/object_recognition/detection/objects";

/// Which of the two packages a channel's messages come from (same layout, other names).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Package {
    /// `autoware_perception_msgs` (Autoware since 2024).
    Perception,
    /// `autoware_auto_perception_msgs` (Autoware.Auto, Autoware until 2024).
    AutoPerception,
}

impl Package {
    /// The ROS package name.
    pub fn name(self) -> &'static str {
        match self {
            Package::Perception => "autoware_perception_msgs",
            Package::AutoPerception => "autoware_auto_perception_msgs",
        }
    }

    /// The package of a schema name `package/msg/Type`, if it is one of Autoware's.
    pub fn of_schema(schema_name: &str) -> Option<Package> {
        match schema_name.split('/').next() {
            Some("autoware_perception_msgs") => Some(Package::Perception),
            Some("autoware_auto_perception_msgs") => Some(Package::AutoPerception),
            _ => None,
        }
    }
}

/// Whether a label read from an Autoware message is not one of probmot's classes (UNKNOWN,
/// ANIMAL, HAZARD, ...): tracked only under a config entry of its own name.
pub fn is_class_without_probmot_class(label: &str) -> bool {
    !CLASS_NAMES[1..=7].contains(&label)
}

/// `orientation_availability` constants and their attribute values.
pub mod orientation {
    /// The orientation is unknown.
    pub const UNAVAILABLE: u8 = 0;
    /// The orientation is known up to a sign flip.
    pub const SIGN_UNKNOWN: u8 = 1;
    /// The full orientation is known.
    pub const AVAILABLE: u8 = 2;
    /// The attribute a detection carries when its orientation is not AVAILABLE.
    pub const ATTRIBUTE: &str = "orientation_availability";

    /// The attribute value of a code (`None` for AVAILABLE and unknown codes).
    pub fn attribute_value(code: u8) -> Option<&'static str> {
        match code {
            UNAVAILABLE => Some("unavailable"),
            SIGN_UNKNOWN => Some("sign_unknown"),
            _ => None,
        }
    }

    /// The code of an attribute value (AVAILABLE without one).
    pub fn code(value: Option<&str>) -> u8 {
        match value {
            Some("unavailable") => UNAVAILABLE,
            Some("sign_unknown") => SIGN_UNKNOWN,
            _ => AVAILABLE,
        }
    }
}

/// The fields of the geometry and std types both Autoware layouts use (checked when the schema
/// text defines them).
pub(crate) fn common_sections() -> Vec<Expected> {
    let f3 = [("float64", "x"), ("float64", "y"), ("float64", "z")];
    let cov = |pose: &'static str, name: &'static str| {
        fields(&[(pose, name), ("float64[36]", "covariance")])
    };
    let opt = |name, fields| Expected {
        name,
        required: false,
        fields,
    };
    vec![
        opt(
            "ObjectClassification",
            fields(&[("uint8", "label"), ("float32", "probability")]),
        ),
        opt(
            "Shape",
            fields(&[
                ("uint8", "type"),
                ("Polygon", "footprint"),
                ("Vector3", "dimensions"),
            ]),
        ),
        opt("PoseWithCovariance", cov("Pose", "pose")),
        opt("TwistWithCovariance", cov("Twist", "twist")),
        opt("AccelWithCovariance", cov("Accel", "accel")),
        opt(
            "Pose",
            fields(&[("Point", "position"), ("Quaternion", "orientation")]),
        ),
        opt(
            "Twist",
            fields(&[("Vector3", "linear"), ("Vector3", "angular")]),
        ),
        opt(
            "Accel",
            fields(&[("Vector3", "linear"), ("Vector3", "angular")]),
        ),
        opt("Point", fields(&f3)),
        opt("Vector3", fields(&f3)),
        opt("Polygon", fields(&[("Point32[]", "points")])),
        opt(
            "Point32",
            fields(&[("float32", "x"), ("float32", "y"), ("float32", "z")]),
        ),
        opt(
            "Quaternion",
            fields(&[
                ("float64", "x"),
                ("float64", "y"),
                ("float64", "z"),
                ("float64", "w"),
            ]),
        ),
        opt(
            "Header",
            fields(&[("Time", "stamp"), ("string", "frame_id")]),
        ),
        opt("Time", fields(&[("int32", "sec"), ("uint32", "nanosec")])),
        opt("UUID", fields(&[("uint8[16]", "uuid")])),
    ]
}

/// The sections of the `DetectedObjects` layout.
fn detected_sections() -> Vec<Expected> {
    let req = |name, fields| Expected {
        name,
        required: true,
        fields,
    };
    let mut all = vec![
        req(
            "DetectedObjects",
            fields(&[("Header", "header"), ("DetectedObject[]", "objects")]),
        ),
        req(
            "DetectedObject",
            fields(&[
                ("float32", "existence_probability"),
                ("ObjectClassification[]", "classification"),
                ("DetectedObjectKinematics", "kinematics"),
                ("Shape", "shape"),
            ]),
        ),
        req(
            "DetectedObjectKinematics",
            fields(&[
                ("PoseWithCovariance", "pose_with_covariance"),
                ("bool", "has_position_covariance"),
                ("uint8", "orientation_availability"),
                ("TwistWithCovariance", "twist_with_covariance"),
                ("bool", "has_twist"),
                ("bool", "has_twist_covariance"),
            ]),
        ),
    ];
    // The object's own types must be there too (made required here).
    for mut e in common_sections() {
        e.required = matches!(e.name, "ObjectClassification" | "Shape");
        all.push(e);
    }
    all
}

/// The sections of a channel's schema record, or why they cannot be read.
pub(crate) fn schema_sections(
    schema_name: &str,
    schema_encoding: &str,
    schema_data: &[u8],
) -> Result<Sections, String> {
    let top = ros2_schema::base_name(schema_name);
    ros2_schema::parse(schema_encoding, schema_data, top)
}

/// Checks a detected-objects channel: its package from the schema name, its layout from the
/// schema record (`ros2msg` or `ros2idl`).
pub fn detect_package(
    schema_name: &str,
    schema_encoding: &str,
    schema_data: &[u8],
) -> Result<Package, String> {
    let package = Package::of_schema(schema_name)
        .ok_or_else(|| format!("'{schema_name}' is not an Autoware detected-objects schema"))?;
    let sections = schema_sections(schema_name, schema_encoding, schema_data)?;
    ros2_schema::check(&sections, &detected_sections(), "DetectedObjects layout")?;
    Ok(package)
}

/// Smallest wire size of one `DetectedObject` (for the sequence length check).
const MIN_DETECTED_OBJECT: usize = 4 + 4 + (7 + 36 + 6 + 36) * 8 + 4 + 4 + 3 * 8;

/// Decodes one CDR `DetectedObjects` message (with its encapsulation header).
pub fn decode(bytes: &[u8]) -> Result<Detections3D, DecodeError> {
    let mut c = CdrCursor::new(bytes)?;
    let (stamp, frame_id) = read_header(&mut c)?;
    let n = c.sequence_len(MIN_DETECTED_OBJECT)?;
    let mut detections = Vec::with_capacity(n);
    for _ in 0..n {
        let mut o = RawObject {
            existence: c.f32()?,
            class: read_classification(&mut c)?,
            ..Default::default()
        };
        read_pose(&mut c, &mut o)?;
        let _has_position_covariance = c.bool()?;
        o.orientation_availability = c.u8()?;
        let twist = read_twist(&mut c)?;
        let has_twist = c.bool()?;
        let _has_twist_covariance = c.bool()?;
        o.twist = has_twist.then_some(twist);
        o.shape = read_shape(&mut c)?;
        detections.push(to_detection(&o));
    }
    Ok(Detections3D {
        stamp,
        frame_id,
        detections,
    })
}

/// The probmot detection of an object (module docs).
fn to_detection(o: &RawObject) -> Detection3D {
    let mut det = Detection3D {
        yaw: o.yaw(),
        label: o.label(),
        score: o.existence as f64,
        velocity: o.velocity().map(v3),
        ..Default::default()
    };
    if let Some((center, size)) = o.center_and_size() {
        det.center = Some(v3(center));
        det.size = Some(Size3 {
            length: size[0],
            width: size[1],
            height: size[2],
        });
    }
    if let Some(v) = orientation::attribute_value(o.orientation_availability) {
        det.attributes
            .insert(orientation::ATTRIBUTE.to_string(), v.to_string());
    }
    det
}

/// Marks the boxes of a decoded frame whose class is not one of probmot's
/// ([`is_class_without_probmot_class`]): they are tracked only under a config entry of their
/// own name.
pub fn mark_classes_without_probmot_class(frame: &mut DetectionFrame) {
    for b in &mut frame.boxes {
        b.needs_own_entry = is_class_without_probmot_class(&b.label);
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::msgs::cdr_writer::CdrWriter;

    /// One object to write: classes, existence, position, yaw, shape type, footprint points,
    /// dimensions, twist (object frame), orientation availability.
    pub(crate) struct Obj {
        pub classes: Vec<(u8, f32)>,
        pub existence: f32,
        pub position: [f64; 3],
        pub yaw: f64,
        pub shape: u8,
        pub footprint: Vec<[f32; 2]>,
        pub dimensions: [f64; 3],
        pub twist: Option<[f64; 2]>,
        pub orientation: u8,
    }

    pub(crate) fn car(x: f64, y: f64, yaw: f64) -> Obj {
        Obj {
            classes: vec![(1, 1.0)],
            existence: 0.875,
            position: [x, y, 0.8],
            yaw,
            shape: shape_type::BOUNDING_BOX,
            footprint: vec![],
            dimensions: [4.5, 1.9, 1.6],
            twist: None,
            orientation: orientation::AVAILABLE,
        }
    }

    /// Writes a `Shape`.
    pub(crate) fn write_shape(w: &mut CdrWriter<'_>, o: &Obj) {
        w.u8(o.shape);
        w.u32(o.footprint.len() as u32);
        for p in &o.footprint {
            w.f32(p[0]);
            w.f32(p[1]);
            w.f32(0.0);
        }
        o.dimensions.iter().for_each(|v| w.f64(*v));
    }

    /// Writes `existence_probability` and the classification.
    pub(crate) fn write_classes(w: &mut CdrWriter<'_>, o: &Obj) {
        w.f32(o.existence);
        w.u32(o.classes.len() as u32);
        for (l, p) in &o.classes {
            w.u8(*l);
            w.f32(*p);
        }
    }

    /// Writes a `PoseWithCovariance` (variances 0.01, 0.02, ... on the diagonal).
    pub(crate) fn write_pose_and_cov(w: &mut CdrWriter<'_>, o: &Obj) {
        w.pose(o.position, o.yaw);
        for i in 0..36 {
            w.f64(if i % 7 == 0 {
                0.01 * (i / 7 + 1) as f64
            } else {
                0.0
            });
        }
    }

    /// Writes a `TwistWithCovariance` (yaw rate 0.25, covariance 0).
    pub(crate) fn write_twist(w: &mut CdrWriter<'_>, o: &Obj) {
        let t = o.twist.unwrap_or_default();
        for v in [t[0], t[1], 0.0, 0.0, 0.0, 0.25] {
            w.f64(v);
        }
        (0..36).for_each(|_| w.f64(0.0));
    }

    /// A CDR `DetectedObjects` of `objects`.
    pub(crate) fn detected_objects(stamp: u64, frame: &str, objects: &[Obj]) -> Vec<u8> {
        let mut buf = Vec::new();
        let mut w = CdrWriter::new(&mut buf);
        w.header(stamp, frame);
        w.u32(objects.len() as u32);
        for o in objects {
            write_classes(&mut w, o);
            write_pose_and_cov(&mut w, o);
            w.bool(false);
            w.u8(o.orientation);
            write_twist(&mut w, o);
            w.bool(o.twist.is_some());
            w.bool(false);
            write_shape(&mut w, o);
        }
        buf
    }

    fn close(a: [f64; 3], b: [f64; 3]) -> bool {
        a.iter().zip(&b).all(|(x, y)| (x - y).abs() < 1e-9)
    }

    fn xyz(v: &Option<crate::msgs::Vector3>) -> [f64; 3] {
        let v = v.unwrap();
        [v.x, v.y, v.z]
    }

    #[test]
    fn objects_become_boxes_by_shape() {
        let mut pedestrian = car(5.0, 20.0, -1.0);
        pedestrian.classes = vec![(7, 0.9)];
        pedestrian.shape = shape_type::CYLINDER;
        pedestrian.dimensions = [0.7, 0.0, 1.8];
        // A footprint 8 x 2.5 m whose middle is 0.5 m ahead of the pose, at yaw 0.3.
        let mut truck = car(-20.0, 30.0, 0.3);
        truck.classes = vec![(2, 1.0)];
        truck.shape = shape_type::POLYGON;
        truck.footprint = vec![[-3.5, -1.25], [4.5, -1.25], [4.5, 1.25], [-3.5, 1.25]];
        truck.dimensions = [0.0, 0.0, 3.2];
        let bytes = detected_objects(
            1_700_000_000_500_000_000,
            "base_link",
            &[car(1.0, 2.0, 0.5), pedestrian, truck],
        );
        let m = decode(&bytes).unwrap();
        assert_eq!(m.stamp, Some(1_700_000_000_500_000_000));
        assert_eq!(m.frame_id, "base_link");
        let [c, p, t] = &m.detections[..] else {
            panic!("{m:?}")
        };
        assert_eq!((c.label.as_str(), c.score), ("car", 0.875));
        assert!(close(xyz(&c.center), [1.0, 2.0, 0.8]));
        assert_eq!(c.size, Some(crate::msgs::size3([4.5, 1.9, 1.6])));
        assert!((c.yaw - 0.5).abs() < 1e-12 && c.velocity.is_none());
        assert!(c.attributes.is_empty());
        assert_eq!(p.label, "pedestrian");
        assert_eq!(p.size, Some(crate::msgs::size3([0.7, 0.7, 1.8])));
        assert_eq!(t.label, "truck");
        let (s, co) = 0.3f64.sin_cos();
        assert!(close(
            xyz(&t.center),
            [-20.0 + 0.5 * co, 30.0 + 0.5 * s, 0.8]
        ));
        assert!(close(
            [
                t.size.unwrap().length,
                t.size.unwrap().width,
                t.size.unwrap().height
            ],
            [8.0, 2.5, 3.2]
        ));
        assert!((t.yaw - 0.3).abs() < 1e-12);
    }

    #[test]
    fn label_score_twist_and_orientation() {
        // TRUCK 0.3 then CAR 0.7: the most probable is the label; the twist (object frame) is
        // rotated by the yaw; a sign-unknown orientation becomes an attribute.
        let mut o = car(0.0, 0.0, std::f64::consts::FRAC_PI_2);
        o.classes = vec![(2, 0.3), (1, 0.7)];
        o.twist = Some([6.0, 0.5]);
        o.orientation = orientation::SIGN_UNKNOWN;
        let mut animal = car(9.0, 9.0, 0.0);
        animal.classes = vec![(8, 0.6)];
        let mut none = car(3.0, 3.0, 0.0);
        none.classes = vec![];
        none.shape = 7;
        let m = decode(&detected_objects(0, "map", &[o, animal, none])).unwrap();
        assert_eq!(m.stamp, None, "a zero stamp is unset");
        let d = &m.detections[0];
        assert_eq!(d.label, "car");
        assert!(
            close(xyz(&d.velocity), [-0.5, 6.0, 0.0]),
            "{:?}",
            d.velocity
        );
        assert_eq!(
            d.attributes.get(orientation::ATTRIBUTE).map(String::as_str),
            Some("sign_unknown")
        );
        assert_eq!(m.detections[1].label, "animal");
        assert!(is_class_without_probmot_class("animal"));
        assert!(!is_class_without_probmot_class("car"));
        // No classification: UNKNOWN; an unknown shape type: no size (skipped later).
        assert_eq!(m.detections[2].label, "unknown");
        assert!(m.detections[2].size.is_none());
        // Marked for the label lookup.
        let mut frame = DetectionFrame::from_message(m, 5);
        mark_classes_without_probmot_class(&mut frame);
        let marks: Vec<bool> = frame.boxes.iter().map(|b| b.needs_own_entry).collect();
        assert_eq!(marks, [false, true]);
    }

    #[test]
    fn class_names_and_codes() {
        for code in 0..=11u8 {
            assert_eq!(class_code(&class_name(code)), code);
        }
        assert_eq!(class_name(40), "label_40");
        assert_eq!(class_code("label_40"), 40);
        assert_eq!(class_code("cyclist"), 0);
        assert!(is_class_without_probmot_class("label_40"));
    }

    #[test]
    fn truncated_and_corrupt_messages_are_errors() {
        let bytes = detected_objects(5, "map", &[car(1.0, 2.0, 0.0)]);
        for cut in [3, 10, 40, bytes.len() - 1] {
            assert!(decode(&bytes[..cut]).is_err(), "cut at {cut}");
        }
        // An object count far beyond the message.
        let mut b = detected_objects(5, "map", &[]);
        let n = b.len();
        b[n - 4..].copy_from_slice(&0x4000_0000u32.to_le_bytes());
        let e = decode(&b).unwrap_err().to_string();
        assert!(e.contains("longer than the message"), "{e}");
    }

    /// The field lines of the `.msg` files (as rosbags writes the schema record).
    pub(crate) const MSG_TEXT: &str = "\
std_msgs/Header header
autoware_perception_msgs/DetectedObject[] objects
================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id
================================================================================
MSG: autoware_perception_msgs/DetectedObject
float32 existence_probability
autoware_perception_msgs/ObjectClassification[] classification
autoware_perception_msgs/DetectedObjectKinematics kinematics
autoware_perception_msgs/Shape shape
================================================================================
MSG: autoware_perception_msgs/ObjectClassification
uint8 UNKNOWN=0
uint8 label
float32 probability
================================================================================
MSG: autoware_perception_msgs/DetectedObjectKinematics
uint8 AVAILABLE=2
geometry_msgs/PoseWithCovariance pose_with_covariance
bool has_position_covariance
uint8 orientation_availability
geometry_msgs/TwistWithCovariance twist_with_covariance
bool has_twist
bool has_twist_covariance
================================================================================
MSG: autoware_perception_msgs/Shape
uint8 type
geometry_msgs/Polygon footprint
geometry_msgs/Vector3 dimensions
";

    /// The IDL form of the older package (as rosbag2 stores an IDL-defined type): the field
    /// lists of tier4/autoware_auto_msgs, written here without its comments.
    const IDL_TEXT: &str = r#"
module autoware_auto_perception_msgs { module msg {
  struct DetectedObjects { std_msgs::msg::Header header;
    sequence<autoware_auto_perception_msgs::msg::DetectedObject> objects; };
}; };
================================================================================
IDL: autoware_auto_perception_msgs/msg/DetectedObject
module autoware_auto_perception_msgs { module msg {
  struct DetectedObject {
    @range (min=0.0, max=1.0)
    float existence_probability;
    sequence<autoware_auto_perception_msgs::msg::ObjectClassification> classification;
    autoware_auto_perception_msgs::msg::DetectedObjectKinematics kinematics;
    autoware_auto_perception_msgs::msg::Shape shape;
  };
}; };
================================================================================
IDL: autoware_auto_perception_msgs/msg/ObjectClassification
module autoware_auto_perception_msgs { module msg {
  module ObjectClassification_Constants { const uint8 CAR = 1; };
  struct ObjectClassification { uint8 label; @range (min=0.0, max=1.0) float probability; };
}; };
================================================================================
IDL: autoware_auto_perception_msgs/msg/DetectedObjectKinematics
module autoware_auto_perception_msgs { module msg {
  struct DetectedObjectKinematics {
    geometry_msgs::msg::PoseWithCovariance pose_with_covariance;
    boolean has_position_covariance;
    uint8 orientation_availability;
    geometry_msgs::msg::TwistWithCovariance twist_with_covariance;
    boolean has_twist;
    boolean has_twist_covariance;
  };
}; };
================================================================================
IDL: autoware_auto_perception_msgs/msg/Shape
module autoware_auto_perception_msgs { module msg {
  struct Shape {
    @verbatim (language="comment", text=" x: the length (BOUNDING_BOX) or diameter (CYLINDER)")
    uint8 type;
    geometry_msgs::msg::Polygon footprint;
    geometry_msgs::msg::Vector3 dimensions;
  };
}; };
"#;

    #[test]
    fn layouts_from_msg_and_idl_schema_texts() {
        let name = DETECTED_SCHEMA_NAMES[0];
        assert_eq!(
            detect_package(name, "ros2msg", MSG_TEXT.as_bytes()),
            Ok(Package::Perception)
        );
        let auto = DETECTED_SCHEMA_NAMES[1];
        assert_eq!(
            detect_package(auto, "ros2idl", IDL_TEXT.as_bytes()),
            Ok(Package::AutoPerception)
        );
        // A field of another type is refused, naming it.
        let bad = MSG_TEXT.replace(
            "float32 existence_probability",
            "float64 existence_probability",
        );
        let e = detect_package(name, "ros2msg", bad.as_bytes()).unwrap_err();
        assert!(
            e.contains("DetectedObject has fields [float64 existence_probability"),
            "{e}"
        );
        // No definition at all: the layout cannot be checked.
        let e = detect_package(name, "ros2msg", b"").unwrap_err();
        assert!(e.contains("no definition text"), "{e}");
        let e = detect_package(
            name,
            "ros2msg",
            b"std_msgs/Header header\nDetectedObject[] objects\n",
        )
        .unwrap_err();
        assert!(e.contains("does not define DetectedObject"), "{e}");
        let e = detect_package(name, "jsonschema", b"{}").unwrap_err();
        assert!(e.contains("ros2msg or ros2idl"), "{e}");
    }
}
