//! The message type of the tracks channel `track` writes: probmot's own `probmot.Tracks3D`
//! (protobuf), ROS 2 `vision_msgs/msg/Detection3DArray` (CDR) so that a tracked ROS 2 bag
//! stays a bag ROS tooling reads ([`crate::msgs::ros2_tracks`]), or Autoware's
//! `autoware_perception_msgs/msg/TrackedObjects` (CDR) for an Autoware input
//! ([`crate::msgs::autoware_tracks`]).

use std::collections::BTreeMap;

use anyhow::{bail, Result};
use mcap::records::MessageHeader;

use crate::mcapio::sink::RecordSink;

use crate::msgs::detection_source::{DetectionSource, OUTPUT_METADATA_KEY};
use crate::msgs::track_encode::{encode_tracks, RateVariances};
use crate::msgs::{self, autoware_tracks, ros2_tracks, Tracks3D};

/// The tracks topic of the probmot and ROS 2 formats when `--tracks-topic` is not given.
pub const DEFAULT_TRACKS_TOPIC: &str = "/tracks";

/// The message type of the tracks channel (`--tracks-format`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TracksFormat {
    /// `probmot.Tracks3D`, protobuf: every field (velocities, variances, ages, attributes).
    Probmot,
    /// `vision_msgs/msg/Detection3DArray`, CDR with a `ros2msg` schema (ROS 2 Humble layout).
    Ros2,
    /// `autoware_perception_msgs/msg/TrackedObjects`, CDR with a `ros2msg` schema: UUIDs,
    /// classes, pose and twist with covariances.
    Autoware,
}

impl crate::tracker::choice::Choice for TracksFormat {
    const VALUES: &'static [Self] = &[
        TracksFormat::Probmot,
        TracksFormat::Ros2,
        TracksFormat::Autoware,
    ];

    fn name(self) -> &'static str {
        TracksFormat::name(self)
    }

    fn description(self) -> &'static str {
        match self {
            TracksFormat::Probmot => "probmot.Tracks3D (protobuf)",
            TracksFormat::Ros2 => "vision_msgs/msg/Detection3DArray (ROS 2, CDR)",
            TracksFormat::Autoware => "autoware_perception_msgs/msg/TrackedObjects (Autoware, CDR)",
        }
    }
}

impl TracksFormat {
    /// The format of a run: the requested one, else Autoware's when any chosen detection channel
    /// carries Autoware's `DetectedObjects`, else ROS 2 when the input is a ROS 2 bag (MCAP
    /// profile `ros2`) or any chosen detection channel carries ROS 2 messages, else probmot's.
    pub fn resolve<'a>(
        requested: Option<TracksFormat>,
        profile: &str,
        sources: impl IntoIterator<Item = &'a DetectionSource>,
    ) -> TracksFormat {
        if let Some(f) = requested {
            return f;
        }
        let sources: Vec<&DetectionSource> = sources.into_iter().collect();
        if sources
            .iter()
            .any(|s| matches!(s, DetectionSource::Autoware(_)))
        {
            return TracksFormat::Autoware;
        }
        let ros2_input = profile == "ros2"
            || sources
                .iter()
                .any(|s| matches!(s, DetectionSource::Ros2Vision(_)));
        if ros2_input {
            TracksFormat::Ros2
        } else {
            TracksFormat::Probmot
        }
    }

    /// Name of the format on the command line.
    pub fn name(self) -> &'static str {
        match self {
            TracksFormat::Probmot => "probmot",
            TracksFormat::Ros2 => "ros2",
            TracksFormat::Autoware => "autoware",
        }
    }

    /// The tracks topic when `--tracks-topic` is not given: Autoware's tracking topic for
    /// Autoware tracks, else [`DEFAULT_TRACKS_TOPIC`].
    pub fn default_topic(self) -> &'static str {
        match self {
            TracksFormat::Autoware => autoware_tracks::TRACKING_TOPIC,
            TracksFormat::Probmot | TracksFormat::Ros2 => DEFAULT_TRACKS_TOPIC,
        }
    }

    /// `(schema name, schema encoding, schema data, message encoding)` of the tracks channel.
    pub fn schema(self) -> (&'static str, &'static str, &'static [u8], &'static str) {
        match self {
            TracksFormat::Probmot => (
                msgs::TRACKS_SCHEMA,
                "protobuf",
                msgs::DESCRIPTOR_SET,
                "protobuf",
            ),
            TracksFormat::Ros2 => (
                ros2_tracks::SCHEMA_NAME,
                ros2_tracks::SCHEMA_ENCODING,
                ros2_tracks::SCHEMA_TEXT.as_bytes(),
                ros2_tracks::MESSAGE_ENCODING,
            ),
            TracksFormat::Autoware => (
                autoware_tracks::SCHEMA_NAME,
                "ros2msg",
                autoware_tracks::SCHEMA_TEXT.as_bytes(),
                "cdr",
            ),
        }
    }

    /// Metadata of the tracks channel. The ROS 2 and Autoware tracks are marked as probmot's
    /// output (a later `track` of the file does not read the ROS 2 ones, which have a detection
    /// schema, as detections); rosbag2's `offered_qos_profiles` key is left out, as for a bag
    /// recorded from a publisher that offered nothing special (readers then use the default
    /// QoS).
    pub fn channel_metadata(self) -> BTreeMap<String, String> {
        match self {
            TracksFormat::Probmot => BTreeMap::new(),
            TracksFormat::Ros2 | TracksFormat::Autoware => {
                BTreeMap::from([(OUTPUT_METADATA_KEY.to_string(), "tracks".to_string())])
            }
        }
    }

    /// Writes one frame's tracks to `out` with `header`; `rates[i]`: the velocity and yaw-rate
    /// variances of `tracks.tracks[i]` (only the Autoware format writes them). probmot's
    /// tracks are encoded straight into the sink's buffer; the CDR formats, whose alignment
    /// counts from the message's first byte, go through `scratch`.
    pub fn write(
        self,
        out: &mut impl RecordSink,
        header: &MessageHeader,
        tracks: &Tracks3D,
        rates: &[RateVariances],
        scratch: &mut Vec<u8>,
    ) -> Result<()> {
        match self {
            TracksFormat::Probmot => {
                return out.write_encoded(header, scratch, |buf| encode_tracks(tracks, buf))
            }
            TracksFormat::Ros2 => ros2_tracks::encode_tracks_into(tracks, scratch),
            TracksFormat::Autoware => autoware_tracks::encode_tracks_into(tracks, rates, scratch),
        }
        out.write_to_known_channel(header, scratch)
    }

    /// Refuses the optional outputs that have no ROS 2 form (`--tracks-frame ego` and
    /// `--scene-topic` write protobuf channels, which ROS 2 bag readers cannot decode).
    pub fn check_extras(self, file: &str, ego_tracks: bool, scene_topic: bool) -> Result<()> {
        let (input, message) = match self {
            TracksFormat::Probmot => return Ok(()),
            TracksFormat::Ros2 => ("ROS 2", "vision_msgs/msg/Detection3DArray"),
            TracksFormat::Autoware => ("Autoware", autoware_tracks::SCHEMA_NAME),
        };
        let what = match (ego_tracks, scene_topic) {
            (false, false) => return Ok(()),
            (true, false) => "--tracks-frame ego",
            (false, true) => "--scene-topic",
            (true, true) => "--tracks-frame ego and --scene-topic",
        };
        bail!(
            "{file}: {what} writes protobuf channels, which ROS 2 bag readers cannot decode; \
             the tracks of this {input} input are written as {message} (--tracks-format {}). \
             Leave out {what}, or add --tracks-format probmot to write probmot.Tracks3D tracks \
             and these channels",
            self.name()
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msgs::ros2_vision::VisionLayout;
    use crate::msgs::Encoding;

    #[test]
    fn ros2_inputs_get_ros2_tracks_unless_asked() {
        let ros = DetectionSource::Ros2Vision(VisionLayout::V4);
        let pb = DetectionSource::Probmot(Encoding::Protobuf);
        let fox = DetectionSource::FoxgloveScene;
        assert_eq!(
            TracksFormat::resolve(None, "", [&pb]),
            TracksFormat::Probmot
        );
        assert_eq!(
            TracksFormat::resolve(None, "", [&fox]),
            TracksFormat::Probmot
        );
        assert_eq!(TracksFormat::resolve(None, "", [&ros]), TracksFormat::Ros2);
        assert_eq!(
            TracksFormat::resolve(None, "ros2", [&pb]),
            TracksFormat::Ros2
        );
        assert_eq!(
            TracksFormat::resolve(Some(TracksFormat::Probmot), "ros2", [&ros]),
            TracksFormat::Probmot
        );
        assert_eq!(
            TracksFormat::resolve(Some(TracksFormat::Ros2), "", [&pb]),
            TracksFormat::Ros2
        );
    }

    #[test]
    fn autoware_inputs_get_autoware_tracks_on_autowares_topic() {
        use crate::msgs::autoware::Package;
        let aw = DetectionSource::Autoware(Package::Perception);
        let ros = DetectionSource::Ros2Vision(VisionLayout::V4);
        let f = TracksFormat::resolve(None, "ros2", [&ros, &aw]);
        assert_eq!(f, TracksFormat::Autoware);
        assert_eq!(
            f.default_topic(),
            "/perception/object_recognition/tracking/objects"
        );
        assert_eq!(TracksFormat::Ros2.default_topic(), "/tracks");
        let asked = TracksFormat::resolve(Some(TracksFormat::Ros2), "ros2", [&aw]);
        assert_eq!(asked, TracksFormat::Ros2);
        let e = TracksFormat::Autoware
            .check_extras("f", true, false)
            .unwrap_err();
        assert!(
            e.to_string()
                .contains("TrackedObjects (--tracks-format autoware)"),
            "{e}"
        );
    }

    #[test]
    fn extras_refused_only_in_ros2() {
        assert!(TracksFormat::Probmot.check_extras("f", true, true).is_ok());
        assert!(TracksFormat::Ros2.check_extras("f", false, false).is_ok());
        let e = TracksFormat::Ros2
            .check_extras("f", false, true)
            .unwrap_err();
        assert!(e.to_string().contains("--scene-topic"), "{e}");
        assert!(e.to_string().contains("--tracks-format probmot"), "{e}");
    }
}
