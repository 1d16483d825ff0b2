//! The tracks as Autoware's `autoware_perception_msgs/msg/TrackedObjects` (message encoding
//! `cdr`, schema encoding `ros2msg`), the message Autoware's own tracker publishes on
//! [`TRACKING_TOPIC`], so that a tracked Autoware bag feeds Autoware's prediction and tools.
//! Also the reader of such tracks (either package) for `plot`, `viz`, `eval` and `info`.
//!
//! One message per frame; per reported track one `TrackedObject`:
//!
//! - `object_id`: a UUID made from the track id alone, so the same track gets the same UUID on
//!   every run ([`track_uuid`]): an RFC 9562 version-8 (custom) UUID whose first six bytes spell
//!   `probmo` and whose other bits hold the 64-bit track id (track 7 is
//!   `70726f62-6d6f-8000-8000-000000000007`);
//! - `existence_probability`: the track's score (the score of its last matched detection),
//!   clamped to [0, 1];
//! - `classification`: one entry, the track's class with probability 1 (the tracker keeps one
//!   class per track; its confidence is the existence probability, as Autoware's detectors
//!   write them). probmot's classes map to CAR ... PEDESTRIAN, the names of Autoware's other
//!   classes (`unknown`, `animal`, ...) back to their codes, any other label to UNKNOWN;
//! - `kinematics.pose_with_covariance`: the box centre and yaw; the 6 x 6 row-major covariance
//!   over x, y, z, rotation about x, y, z holds the filter's x, y, z variances and its yaw
//!   variance on the diagonal, 0 elsewhere;
//! - `kinematics.twist_with_covariance`: the filter's velocity rotated into the object's frame
//!   (x forward, as Autoware writes it) and its yaw rate as `angular.z`; the covariance holds
//!   the velocity variances rotated the same way (x-y block) and the z and yaw-rate variances;
//! - `kinematics.acceleration_with_covariance`: zero (the filter has no acceleration);
//! - `kinematics.orientation_availability`: that of the track's last matched Autoware
//!   detection (carried as its attribute), AVAILABLE otherwise;
//! - `kinematics.is_stationary`: horizontal speed below [`STATIONARY_SPEED`];
//! - `shape`: BOUNDING_BOX with `dimensions` = length, width, height, no footprint.

use super::autoware::{self, class_code, class_name, orientation, Package};
use super::autoware_object::{
    read_classification, read_header, read_pose, read_shape, read_twist, RawObject,
};
use super::cdr_cursor::CdrCursor;
use super::cdr_writer::CdrWriter;
use super::ros2_schema::{self, fields, Expected};
use super::track_encode::RateVariances;
use super::{v3, DecodeError, Track3D, Tracks3D};

/// Schema name of the tracks channel, as rosbag2 names the type.
pub const SCHEMA_NAME: &str = "autoware_perception_msgs/msg/TrackedObjects";

/// Schema names of the tracked objects probmot reads (the current package first).
pub const SCHEMA_NAMES: [&str; 2] = [
    SCHEMA_NAME,
    "autoware_auto_perception_msgs/msg/TrackedObjects",
];

/// Autoware's topic of tracked objects: the default tracks topic of an Autoware input.
pub const TRACKING_TOPIC: &str = "/perception/object_recognition/tracking/objects";

/// Horizontal speed (m/s) below which a track is written as `is_stationary` (well below walking
/// speed, above the speed noise of a filter on a parked car).
pub const STATIONARY_SPEED: f64 = 0.5;

/// The `ros2msg` schema text of `autoware_perception_msgs/msg/TrackedObjects` with every
/// dependency, in the layout rosbag2 writes (the top-level definition, then per dependency a
/// line of 80 `=`, `MSG: package/Type` and its definition). Field and constant lines of
/// autoware_perception_msgs 1.x (github.com/autowarefoundation/autoware_msgs,
/// `autoware_perception_msgs/msg/*.msg`), geometry_msgs and std_msgs
/// (github.com/ros2/common_interfaces), builtin_interfaces (github.com/ros2/rcl_interfaces) and
/// unique_identifier_msgs (github.com/ros2/unique_identifier_msgs); comments left out.
pub const SCHEMA_TEXT: &str = "\
std_msgs/Header header
TrackedObject[] objects

================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id

================================================================================
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec

================================================================================
MSG: autoware_perception_msgs/TrackedObject
unique_identifier_msgs/UUID object_id
float32 existence_probability
ObjectClassification[] classification
TrackedObjectKinematics kinematics
Shape shape

================================================================================
MSG: unique_identifier_msgs/UUID
uint8[16] uuid

================================================================================
MSG: autoware_perception_msgs/ObjectClassification
uint8 UNKNOWN = 0
uint8 CAR = 1
uint8 TRUCK = 2
uint8 BUS = 3
uint8 TRAILER = 4
uint8 MOTORCYCLE = 5
uint8 BICYCLE = 6
uint8 PEDESTRIAN = 7
uint8 ANIMAL = 8
uint8 HAZARD = 9
uint8 OVER_DRIVABLE = 10
uint8 UNDER_DRIVABLE = 11
uint8 label
float32 probability

================================================================================
MSG: autoware_perception_msgs/TrackedObjectKinematics
uint8 UNAVAILABLE=0
uint8 SIGN_UNKNOWN=1
uint8 AVAILABLE=2
geometry_msgs/PoseWithCovariance pose_with_covariance
geometry_msgs/TwistWithCovariance twist_with_covariance
geometry_msgs/AccelWithCovariance acceleration_with_covariance
uint8 orientation_availability
bool is_stationary

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
MSG: geometry_msgs/TwistWithCovariance
Twist twist
float64[36] covariance

================================================================================
MSG: geometry_msgs/Twist
Vector3 linear
Vector3 angular

================================================================================
MSG: geometry_msgs/Vector3
float64 x
float64 y
float64 z

================================================================================
MSG: geometry_msgs/AccelWithCovariance
Accel accel
float64[36] covariance

================================================================================
MSG: geometry_msgs/Accel
Vector3 linear
Vector3 angular

================================================================================
MSG: autoware_perception_msgs/Shape
uint8 BOUNDING_BOX=0
uint8 CYLINDER=1
uint8 POLYGON=2
uint8 type
geometry_msgs/Polygon footprint
geometry_msgs/Vector3 dimensions

================================================================================
MSG: geometry_msgs/Polygon
Point32[] points

================================================================================
MSG: geometry_msgs/Point32
float32 x
float32 y
float32 z
";

/// The first six bytes of probmot's track UUIDs: `probmo` in ASCII.
const UUID_TAG: [u8; 6] = *b"probmo";

/// The low 62 bits.
const LOW_62: u64 = (1 << 62) - 1;

/// The UUID of a track: the same for the same id on every run, different for different ids.
///
/// An RFC 9562 version-8 UUID: bytes 0-5 `probmo`, byte 6 the version (0x80), byte 7 the top
/// two bits of the id, bytes 8-15 the variant bits `10` and the low 62 bits of the id.
pub fn track_uuid(id: u64) -> [u8; 16] {
    let mut u = [0u8; 16];
    u[..6].copy_from_slice(&UUID_TAG);
    u[6] = 0x80;
    u[7] = (id >> 62) as u8;
    u[8..].copy_from_slice(&((id & LOW_62) | (1 << 63)).to_be_bytes());
    u
}

/// The track id of a UUID: the id of [`track_uuid`]'s UUIDs; for another UUID (Autoware's own
/// tracker writes random ones) the XOR of its two 64-bit halves, the same for the same UUID.
pub fn uuid_track_id(u: &[u8; 16]) -> u64 {
    let low = u64::from_be_bytes(u[8..].try_into().expect("8 bytes"));
    let ours = u[..6] == UUID_TAG && u[6] == 0x80 && u[7] < 4 && low >> 62 == 0b10;
    if ours {
        return (u64::from(u[7]) << 62) | (low & LOW_62);
    }
    u64::from_be_bytes(u[..8].try_into().expect("8 bytes")) ^ low
}

/// The 6 x 6 covariances of one track's pose and twist (row-major; module docs).
fn covariances(t: &Track3D, rates: RateVariances) -> ([f64; 36], [f64; 36]) {
    let p = t.position_variance.unwrap_or_default();
    let mut pose = [0.0; 36];
    pose[0] = p.x;
    pose[7] = p.y;
    pose[14] = p.z;
    pose[35] = t.yaw_variance;
    // Velocity variances (diagonal in the message frame) rotated into the object's frame.
    let (s, c) = t.yaw.sin_cos();
    let (vx, vy) = (rates[0], rates[1]);
    let mut twist = [0.0; 36];
    twist[0] = c * c * vx + s * s * vy;
    twist[7] = s * s * vx + c * c * vy;
    twist[1] = c * s * (vy - vx);
    twist[6] = twist[1];
    twist[14] = rates[2];
    twist[35] = rates[3];
    (pose, twist)
}

/// Writes one `TrackedObject`.
fn write_track(w: &mut CdrWriter<'_>, t: &Track3D, rates: RateVariances) {
    w.bytes(&track_uuid(t.id));
    w.f32(t.score.clamp(0.0, 1.0) as f32);
    w.u32(1);
    w.u8(class_code(&t.label));
    w.f32(1.0);
    let c = t.center.unwrap_or_default();
    let (pose_cov, twist_cov) = covariances(t, rates);
    w.pose([c.x, c.y, c.z], t.yaw);
    pose_cov.iter().for_each(|v| w.f64(*v));
    let v = t.velocity.unwrap_or_default();
    let (s, co) = t.yaw.sin_cos();
    for x in [
        co * v.x + s * v.y,
        -s * v.x + co * v.y,
        v.z,
        0.0,
        0.0,
        t.yaw_rate,
    ] {
        w.f64(x);
    }
    twist_cov.iter().for_each(|v| w.f64(*v));
    // Acceleration and its covariance: not estimated.
    (0..42).for_each(|_| w.f64(0.0));
    let availability = t.attributes.get(orientation::ATTRIBUTE).map(String::as_str);
    w.u8(orientation::code(availability));
    w.bool(v.x.hypot(v.y) < STATIONARY_SPEED);
    w.u8(autoware::shape_type::BOUNDING_BOX);
    w.u32(0);
    let s = t.size.unwrap_or_default();
    for x in [s.length, s.width, s.height] {
        w.f64(x);
    }
}

/// Encodes one frame's tracks as a CDR `TrackedObjects` into `buf` (cleared first), with the
/// little-endian encapsulation header. `rates[i]` are the velocity and yaw-rate variances of
/// `tracks.tracks[i]` (0 when missing).
pub fn encode_tracks_into(tracks: &Tracks3D, rates: &[RateVariances], buf: &mut Vec<u8>) {
    let mut w = CdrWriter::new(buf);
    w.header(tracks.stamp, &tracks.frame_id);
    w.u32(tracks.tracks.len() as u32);
    for (i, t) in tracks.tracks.iter().enumerate() {
        write_track(&mut w, t, rates.get(i).copied().unwrap_or_default());
    }
}

/// The field order of `TrackedObjectKinematics`, which differs between the packages.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum KinematicsOrder {
    /// `autoware_perception_msgs`: pose, twist, acceleration, orientation_availability,
    /// is_stationary.
    Perception,
    /// `autoware_auto_perception_msgs`: pose, orientation_availability, twist, acceleration,
    /// is_stationary.
    AutoPerception,
}

/// The expected sections of a `TrackedObjects` schema of `package`.
fn tracked_sections(package: Package) -> Vec<Expected> {
    let pose = ("PoseWithCovariance", "pose_with_covariance");
    let twist = ("TwistWithCovariance", "twist_with_covariance");
    let accel = ("AccelWithCovariance", "acceleration_with_covariance");
    let orient = ("uint8", "orientation_availability");
    let still = ("bool", "is_stationary");
    let kinematics = match package {
        Package::Perception => fields(&[pose, twist, accel, orient, still]),
        Package::AutoPerception => fields(&[pose, orient, twist, accel, still]),
    };
    let req = |name, fields| Expected {
        name,
        required: true,
        fields,
    };
    let mut all = vec![
        req(
            "TrackedObjects",
            fields(&[("Header", "header"), ("TrackedObject[]", "objects")]),
        ),
        req(
            "TrackedObject",
            fields(&[
                ("UUID", "object_id"),
                ("float32", "existence_probability"),
                ("ObjectClassification[]", "classification"),
                ("TrackedObjectKinematics", "kinematics"),
                ("Shape", "shape"),
            ]),
        ),
        req("TrackedObjectKinematics", kinematics),
    ];
    for mut e in autoware::common_sections() {
        e.required = matches!(e.name, "ObjectClassification" | "Shape");
        all.push(e);
    }
    all
}

/// The kinematics order of a tracked-objects channel, or why it cannot be read: `None` when the
/// schema is not Autoware's `TrackedObjects`.
pub fn layout_for_channel(
    schema_name: &str,
    schema_encoding: &str,
    schema_data: &[u8],
    message_encoding: &str,
) -> Option<Result<KinematicsOrder, String>> {
    if !SCHEMA_NAMES.contains(&schema_name) {
        return None;
    }
    let package = Package::of_schema(schema_name)?;
    if message_encoding != "cdr" {
        return Some(Err(format!(
            "schema '{schema_name}' with message encoding '{message_encoding}' (probmot reads \
             cdr)"
        )));
    }
    let checked = autoware::schema_sections(schema_name, schema_encoding, schema_data)
        .and_then(|s| ros2_schema::check(&s, &tracked_sections(package), "TrackedObjects layout"));
    Some(match checked {
        Ok(()) if package == Package::Perception => Ok(KinematicsOrder::Perception),
        Ok(()) => Ok(KinematicsOrder::AutoPerception),
        Err(why) => Err(format!(
            "schema '{schema_name}': unsupported field layout: {why}"
        )),
    })
}

/// Smallest wire size of one `TrackedObject` (for the sequence length check).
const MIN_TRACKED_OBJECT: usize = 16 + 4 + 4 + (7 + 36 + 2 * (6 + 36)) * 8 + 2 + 4 + 4 + 3 * 8;

/// Reads one CDR `TrackedObjects` message as tracks (the inverse of [`encode_tracks_into`]): id
/// from the UUID ([`uuid_track_id`]), label and size as [`autoware`] reads detections, score =
/// existence probability, velocity from the twist rotated into the message frame, yaw rate =
/// `angular.z`, position and yaw variances from the pose covariance's diagonal. A zero
/// `header.stamp` gives stamp 0 (the caller uses the log_time).
pub fn decode_tracks(bytes: &[u8], order: KinematicsOrder) -> Result<Tracks3D, DecodeError> {
    let mut c = CdrCursor::new(bytes)?;
    let (stamp, frame_id) = read_header(&mut c)?;
    let n = c.sequence_len(MIN_TRACKED_OBJECT)?;
    let mut tracks = Vec::with_capacity(n);
    for _ in 0..n {
        let id = uuid_track_id(&c.u8_array::<16>()?);
        let mut o = RawObject {
            existence: c.f32()?,
            class: read_classification(&mut c)?,
            ..Default::default()
        };
        read_pose(&mut c, &mut o)?;
        if order == KinematicsOrder::AutoPerception {
            o.orientation_availability = c.u8()?;
        }
        o.twist = Some(read_twist(&mut c)?);
        let _acceleration = read_twist(&mut c)?;
        if order == KinematicsOrder::Perception {
            o.orientation_availability = c.u8()?;
        }
        let _is_stationary = c.bool()?;
        o.shape = read_shape(&mut c)?;
        tracks.push(to_track(id, &o));
    }
    Ok(Tracks3D {
        stamp: stamp.unwrap_or(0),
        frame_id,
        tracks,
    })
}

/// The probmot track of one read object.
fn to_track(id: u64, o: &RawObject) -> Track3D {
    let var = o.pose_variances;
    let (center, size) = match o.center_and_size() {
        Some((c, s)) => (Some(v3(c)), Some(super::size3(s))),
        None => (None, None),
    };
    Track3D {
        id,
        label: class_name(o.class.map_or(0, |(l, _)| l)),
        center,
        size,
        yaw: o.yaw(),
        velocity: o.velocity().map(v3),
        yaw_rate: o.twist.map_or(0.0, |t| t[5]),
        score: o.existence as f64,
        position_variance: Some(v3([var[0], var[1], var[2]])),
        yaw_variance: var[3],
        ..Default::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msgs::autoware::tests::{
        car, write_classes, write_pose_and_cov, write_shape, write_twist,
    };
    use crate::msgs::{size3, v3};
    use std::collections::BTreeMap;

    fn track(id: u64, label: &str, c: [f64; 3], yaw: f64, v: [f64; 3]) -> Track3D {
        Track3D {
            id,
            label: label.into(),
            center: Some(v3(c)),
            size: Some(size3([4.5, 1.9, 1.6])),
            yaw,
            velocity: Some(v3(v)),
            yaw_rate: 0.125,
            score: 0.8125,
            position_variance: Some(v3([0.1, 0.2, 0.3])),
            yaw_variance: 0.05,
            ..Default::default()
        }
    }

    fn frame() -> Tracks3D {
        let mut ped = track(
            12345678901,
            "pedestrian",
            [-1.0, 3.0, 0.9],
            -2.0,
            [0.1, 0.2, 0.0],
        );
        ped.attributes = BTreeMap::from([(
            orientation::ATTRIBUTE.to_string(),
            "sign_unknown".to_string(),
        )]);
        Tracks3D {
            stamp: 1_700_000_000_250_000_000,
            frame_id: "map".into(),
            tracks: vec![
                track(7, "car", [10.0, -2.5, 0.8], 0.3, [8.0, 2.0, 0.0]),
                ped,
                track(u64::MAX, "cyclist", [0.0, 0.0, 0.0], 0.0, [0.0; 3]),
            ],
        }
    }

    #[test]
    fn schema_text_passes_the_readers_layout_check() {
        let r = layout_for_channel(SCHEMA_NAME, "ros2msg", SCHEMA_TEXT.as_bytes(), "cdr");
        assert_eq!(r, Some(Ok(KinematicsOrder::Perception)));
        assert_eq!(
            layout_for_channel("probmot.Tracks3D", "", b"", "protobuf"),
            None
        );
        let r = layout_for_channel(SCHEMA_NAME, "ros2msg", SCHEMA_TEXT.as_bytes(), "json");
        assert!(r.unwrap().unwrap_err().contains("cdr"));
        // The older package's field order is refused under the current name.
        let swapped = SCHEMA_TEXT.replace(
            "geometry_msgs/AccelWithCovariance acceleration_with_covariance\nuint8 orientation_availability",
            "uint8 orientation_availability\ngeometry_msgs/AccelWithCovariance acceleration_with_covariance",
        );
        let r = layout_for_channel(SCHEMA_NAME, "ros2msg", swapped.as_bytes(), "cdr");
        assert!(r
            .unwrap()
            .unwrap_err()
            .contains("TrackedObjectKinematics has fields"));
    }

    #[test]
    fn uuids_are_stable_distinct_and_give_back_the_id() {
        for id in [0, 1, 7, 1 << 40, (1 << 62) - 1, 1 << 62, u64::MAX] {
            let u = track_uuid(id);
            assert_eq!(u, track_uuid(id));
            assert_eq!(uuid_track_id(&u), id, "{id}");
            assert_eq!(u[6] >> 4, 8, "version 8");
            assert_eq!(u[8] >> 6, 0b10, "RFC 9562 variant");
        }
        assert_ne!(track_uuid(1), track_uuid(2));
        let hex: String = track_uuid(7).iter().map(|b| format!("{b:02x}")).collect();
        assert_eq!(hex, "70726f626d6f80008000000000000007");
        // Another tracker's UUID: the same number every time.
        let foreign = [0x12u8; 16];
        assert_eq!(uuid_track_id(&foreign), 0);
        let mut other = foreign;
        other[15] = 0x13;
        assert_eq!(uuid_track_id(&other), 1);
    }

    #[test]
    fn tracks_round_trip() {
        let msg = frame();
        let rates = [[0.5, 0.25, 0.125, 0.0625], [0.4, 0.4, 0.1, 0.2]];
        let mut buf = Vec::new();
        encode_tracks_into(&msg, &rates, &mut buf);
        let back = decode_tracks(&buf, KinematicsOrder::Perception).unwrap();
        assert_eq!((back.stamp, back.frame_id.as_str()), (msg.stamp, "map"));
        let ids: Vec<u64> = back.tracks.iter().map(|t| t.id).collect();
        assert_eq!(ids, [7, 12345678901, u64::MAX]);
        let labels: Vec<&str> = back.tracks.iter().map(|t| t.label.as_str()).collect();
        assert_eq!(
            labels,
            ["car", "pedestrian", "unknown"],
            "cyclist has no Autoware class"
        );
        for (t, b) in msg.tracks.iter().zip(&back.tracks) {
            assert_eq!(b.score, t.score, "exact in float32");
            assert_eq!((b.center, b.size), (t.center, t.size));
            assert!((b.yaw - t.yaw).abs() < 1e-12);
            let (v, w) = (t.velocity.unwrap(), b.velocity.unwrap());
            assert!(
                (v.x - w.x).abs() < 1e-12 && (v.y - w.y).abs() < 1e-12,
                "{v:?} {w:?}"
            );
            assert_eq!(b.yaw_rate, t.yaw_rate);
            assert_eq!(b.position_variance, t.position_variance);
            assert_eq!(b.yaw_variance, t.yaw_variance);
        }
        // Re-encoding into the same buffer gives the same bytes.
        let first = buf.clone();
        encode_tracks_into(&msg, &rates, &mut buf);
        assert_eq!(buf, first);
    }

    #[test]
    fn twist_covariance_turns_into_the_objects_frame() {
        let t = track(1, "car", [0.0; 3], std::f64::consts::FRAC_PI_2, [0.0; 3]);
        let (pose, twist) = covariances(&t, [0.5, 0.25, 0.125, 0.0625]);
        assert_eq!(
            [pose[0], pose[7], pose[14], pose[35]],
            [0.1, 0.2, 0.3, 0.05]
        );
        // At yaw 90 degrees the object's x is the message's y.
        assert!((twist[0] - 0.25).abs() < 1e-12 && (twist[7] - 0.5).abs() < 1e-12);
        assert!(twist[1].abs() < 1e-12 && twist[1] == twist[6]);
        assert_eq!([twist[14], twist[35]], [0.125, 0.0625]);
        let t = track(1, "car", [0.0; 3], std::f64::consts::FRAC_PI_4, [0.0; 3]);
        let (_, twist) = covariances(&t, [0.5, 0.25, 0.0, 0.0]);
        assert!((twist[1] - 0.5 * (0.25 - 0.5)).abs() < 1e-12);
    }

    #[test]
    fn kinematics_flags_of_the_written_tracks() {
        let mut msg = frame();
        msg.tracks[0].velocity = Some(v3([0.3, 0.3, 0.0]));
        let mut buf = Vec::new();
        encode_tracks_into(&msg, &[], &mut buf);
        // Read the flags back: orientation_availability and is_stationary follow the
        // acceleration covariance (the last float64 before them).
        let flags = |buf: &[u8], i: usize| {
            let mut c = CdrCursor::new(buf).unwrap();
            read_header(&mut c).unwrap();
            c.sequence_len(1).unwrap();
            for k in 0..=i {
                c.u8_array::<16>().unwrap();
                c.f32().unwrap();
                read_classification(&mut c).unwrap();
                let mut o = RawObject::default();
                read_pose(&mut c, &mut o).unwrap();
                read_twist(&mut c).unwrap();
                read_twist(&mut c).unwrap();
                let f = (c.u8().unwrap(), c.bool().unwrap());
                read_shape(&mut c).unwrap();
                if k == i {
                    return f;
                }
            }
            unreachable!()
        };
        let still = (orientation::AVAILABLE, true);
        assert_eq!(flags(&buf, 0), still, "0.42 m/s is stationary");
        assert_eq!(flags(&buf, 1), (orientation::SIGN_UNKNOWN, true));
        msg.tracks[0].velocity = Some(v3([8.0, 0.0, 0.0]));
        encode_tracks_into(&msg, &[], &mut buf);
        assert_eq!(flags(&buf, 0), (orientation::AVAILABLE, false));
    }

    #[test]
    fn auto_package_order_decodes() {
        // autoware_auto_perception_msgs: orientation_availability right after the pose.
        let mut o = car(3.0, 4.0, 0.0);
        o.twist = Some([2.0, 0.0]);
        let mut buf = Vec::new();
        let mut w = CdrWriter::new(&mut buf);
        w.header(9, "map");
        w.u32(1);
        w.bytes(&track_uuid(42));
        write_classes(&mut w, &o);
        write_pose_and_cov(&mut w, &o);
        w.u8(orientation::UNAVAILABLE);
        write_twist(&mut w, &o);
        write_twist(&mut w, &o);
        w.bool(false);
        write_shape(&mut w, &o);
        let back = decode_tracks(&buf, KinematicsOrder::AutoPerception).unwrap();
        let t = &back.tracks[0];
        assert_eq!((t.id, t.label.as_str(), back.stamp), (42, "car", 9));
        assert_eq!(t.center, Some(v3([3.0, 4.0, 0.8])));
        assert_eq!(t.velocity, Some(v3([2.0, 0.0, 0.0])));
        assert_eq!(t.yaw_rate, 0.25);
        assert_eq!(t.position_variance, Some(v3([0.01, 0.02, 0.03])));
        // The same bytes in the other order do not decode to the same track.
        let other = decode_tracks(&buf, KinematicsOrder::Perception);
        assert!(other.map_or(true, |m| m.tracks[0].velocity != t.velocity));
    }
}
