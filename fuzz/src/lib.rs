//! Shared harness code of the fuzz targets (see `fuzz/README.md`).

pub mod db3_rows;
pub mod frame_reader;
pub mod read_path;

use std::collections::BTreeMap;

use mcap::records::{Channel, MessageHeader};
use probmot::msgs::detection_frame::{stamp_or_log_time, DetectionFrame};
use probmot::msgs::detection_reader::FrameReader;
use probmot::msgs::detection_source::DetectionSource;
use probmot::msgs::ros2_tf::{ODOMETRY_SCHEMA, TF_MESSAGE_SCHEMA};
use probmot::msgs::ros2_vision::VisionLayout;
use probmot::msgs::{
    self, autoware, Detection3D, Detections3D, DetectionsEnvelope, Encoding, Vector3,
};
use probmot::pipeline::detections::{convert, reject, InputCounters, Origin};
use probmot::pipeline::ego::{EgoMotion, EgoOptions};
use probmot::tracker::{Tracker, TrackerConfig};
use probmot::transforms::sources::{FOXGLOVE_FRAME_TRANSFORM, FOXGLOVE_FRAME_TRANSFORMS};
use probmot::transforms::TransformCollector;

/// Preset used when `probmot track` is given no `--preset`/`--config`.
pub const DEFAULT_PRESET: &str = "nuscenes-chiu2019";

/// Frames the decoded message is replayed for (so that the second and third frames exercise
/// prediction, association and update of the tracks born in the first).
const FRAMES: u64 = 3;

/// Decodes `data` as `Detections3D` and as `DetectionsEnvelope` (the two decodes `track` does
/// of every detection message, in its two passes), and runs the boxes of a decoded message
/// through `convert` and `Tracker::step`. Errors are fine; panics and these invariants are not:
///
/// * a message that decodes fully also decodes as an envelope, with the same stamp and box count
///   (otherwise `track`'s two passes would disagree about the frames);
/// * `convert` with `strict` refuses exactly the boxes it skips without;
/// * `Tracker::step` accepts every box `convert` let through, at increasing stamps.
pub fn decode_and_track(data: &[u8], encoding: Encoding) {
    let envelope = msgs::decode::<DetectionsEnvelope>(data, encoding);
    let Ok(msg) = msgs::decode::<Detections3D>(data, encoding) else {
        return;
    };
    let envelope = envelope.expect("a message that decodes fully decodes as an envelope");
    assert_eq!(envelope.stamp, msg.stamp, "envelope stamp");
    assert_eq!(
        envelope.detections.len(),
        msg.detections.len(),
        "envelope count"
    );
    // What `track`'s second pass makes of a message that decodes fully.
    track_decoded(DetectionFrame::from_message(msg, 0));
}

/// The first byte of `data` picks a detection input other than probmot's own (0: ROS 2
/// `vision_msgs` 4.x layout, 1: its 2.x layout, 2: `foxglove.SceneUpdate`, 3: Autoware
/// `autoware_perception_msgs/msg/DetectedObjects`, 4: the same of `autoware_auto_perception_msgs`,
/// modulo 5); the rest is one message of it. Reads it as `track`'s first pass does
/// (`stamp_and_count`) and as its second pass does (`FrameReader::read`, which leaves these
/// inputs to `DetectionSource::decode_frame`: the lenient decode that rejects a box whose label
/// or id is not UTF-8, and for Autoware marks the classes that are none of probmot's), and
/// tracks a decoded frame as [`decode_and_track`] does. Invariant besides no panic: the first
/// pass's stamp and count (kept and rejected boxes) agree with the frame, and both passes fail
/// or succeed together.
pub fn decode_source_and_track(data: &[u8]) {
    let Some((&selector, bytes)) = data.split_first() else {
        return;
    };
    let source = match selector % 5 {
        0 => DetectionSource::Ros2Vision(VisionLayout::V4),
        1 => DetectionSource::Ros2Vision(VisionLayout::V2),
        2 => DetectionSource::FoxgloveScene,
        3 => DetectionSource::Autoware(autoware::Package::Perception),
        _ => DetectionSource::Autoware(autoware::Package::AutoPerception),
    };
    const LOG_TIME: u64 = 77;
    let counted = source.stamp_and_count(bytes);
    let frame = match FrameReader::default().read(&source, bytes, LOG_TIME) {
        Ok(f) => f,
        Err(_) => {
            assert!(
                counted.is_err(),
                "the first pass read a message the second pass refused"
            );
            return;
        }
    };
    let (stamp, count) = counted.expect("a message the second pass reads is counted by the first");
    assert_eq!(
        (stamp_or_log_time(stamp, LOG_TIME), count),
        (frame.stamp, frame.boxes.len() + frame.rejected.len()),
        "stamp and count"
    );
    track_decoded(frame);
}

/// Runs the boxes of a checked message through `reject` (refused ones) and `convert` (with and
/// without `--strict`, as `track` does) and a tracker of the default preset for [`FRAMES`]
/// frames.
fn track_decoded(frame: DetectionFrame) {
    let config = TrackerConfig::preset(DEFAULT_PRESET).expect("default preset");
    let mut tracker = Tracker::new(config.clone()).expect("default preset validates");
    let mut strict_tracker = Tracker::new(config).expect("default preset validates");
    let mut counters = InputCounters::default();
    let mut strict_counters = InputCounters::default();
    let origin = Origin {
        file: "fuzz",
        topic: "/detections",
        log_time: 0,
    };
    for r in &frame.rejected {
        reject(r, &mut counters, false, &origin).expect("reject without --strict never fails");
        assert!(
            reject(r, &mut strict_counters, true, &origin).is_err(),
            "--strict refuses rejected box {}",
            r.index
        );
    }
    let mut dets = Vec::with_capacity(frame.boxes.len());
    for d in &frame.boxes {
        let lenient = convert(d, &mut tracker, &mut counters, false, &origin)
            .expect("convert without --strict never fails");
        let strict = convert(d, &mut strict_tracker, &mut strict_counters, true, &origin);
        match (&lenient, &strict) {
            (Some(a), Ok(Some(b))) => assert_eq!((a.bbox, a.score), (b.bbox, b.score)),
            (None, Err(_)) => {}
            _ => panic!(
                "strict and lenient convert disagree on detection {}: {d:?}",
                d.index
            ),
        }
        dets.extend(lenient);
    }
    assert_eq!(
        counters.total_skipped() as usize + dets.len(),
        frame.boxes.len() + frame.rejected.len(),
        "every box is either converted or counted as skipped"
    );

    // Step spacing from the message's own stamp: 1 ns .. ~10 s.
    let dt = frame.stamp % 10_000_000_000 + 1;
    for k in 0..FRAMES {
        let stamp = 1 + k * dt;
        if let Err(e) = tracker.step(stamp, &dets) {
            panic!("step refused converted detections at stamp {stamp}: {e}");
        }
        // Touch every report (formats and reads all fields).
        for r in tracker.reports() {
            std::hint::black_box(format!("{r:?} {}", tracker.label(r.class)));
        }
    }
    std::hint::black_box(tracker.mean_confirmed_track_length());
}

/// The transform channels [`read_transforms`] registers: `(topic, schema, message encoding)`.
const TRANSFORM_CHANNELS: [(&str, &str, &str); 5] = [
    ("/tf", TF_MESSAGE_SCHEMA, "cdr"),
    ("/tf_static", TF_MESSAGE_SCHEMA, "cdr"),
    ("/odom", ODOMETRY_SCHEMA, "cdr"),
    ("/frame", FOXGLOVE_FRAME_TRANSFORM, "protobuf"),
    ("/frames", FOXGLOVE_FRAME_TRANSFORMS, "protobuf"),
];

/// Most frames whose pairs are looked up (bounds the time of one input).
const MAX_LOOKUP_FRAMES: usize = 12;

/// Splits `data` into messages of the transform channels `track` reads (`/tf`, `/tf_static`,
/// `nav_msgs/msg/Odometry`, `foxglove.FrameTransform(s)`): each message is a channel byte
/// (modulo 5), a log-time byte (tenths of a second) and a little-endian `u16` length, then
/// that many payload bytes (fewer at the end of the input). Feeds them to a
/// `TransformCollector`, then asks the transform buffer for every pair of its frames and moves a
/// one-box detection message from each frame into the fixed frame with `EgoMotion`, at the
/// stamps around every edge's samples. Invariants besides no panic and no hang (a cycle in the
/// frames must not loop): a frame looked up in itself is the identity, a lookup that succeeds
/// in one direction succeeds in the other, and `EgoMotion` without `--strict` never fails and
/// leaves a message either in the fixed frame or without boxes.
pub fn read_transforms(data: &[u8]) {
    let mut collector = TransformCollector::new();
    for (i, (topic, schema, encoding)) in TRANSFORM_CHANNELS.iter().enumerate() {
        let channel = Channel {
            id: i as u16,
            schema_id: 1,
            topic: topic.to_string(),
            message_encoding: encoding.to_string(),
            metadata: BTreeMap::new(),
        };
        assert!(
            collector.on_channel(&channel, schema).is_some(),
            "{schema} is a transform source"
        );
    }
    let mut rest = data;
    let mut sequence = 0;
    while rest.len() >= 4 {
        let channel_id = (rest[0] % TRANSFORM_CHANNELS.len() as u8) as u16;
        let log_time = rest[1] as u64 * 100_000_000;
        let len = (u16::from_le_bytes([rest[2], rest[3]]) as usize).min(rest.len() - 4);
        let payload = &rest[4..4 + len];
        rest = &rest[4 + len..];
        let header = MessageHeader {
            channel_id,
            sequence,
            log_time,
            publish_time: log_time,
        };
        assert!(collector.on_message("fuzz", &header, payload));
        sequence += 1;
    }
    collector.finish();

    let summary = collector.buffer.summary();
    let mut frames: Vec<&str> = Vec::new();
    let mut stamps = vec![0, 1, u64::MAX];
    for e in &summary {
        for f in [e.parent.as_str(), e.child.as_str()] {
            if !frames.contains(&f) && frames.len() < MAX_LOOKUP_FRAMES {
                frames.push(f);
            }
        }
        if let Some((first, last)) = e.stamp_range {
            stamps.extend([first, last, first / 2 + last / 2, last.saturating_add(1)]);
        }
    }
    stamps.sort_unstable();
    stamps.dedup();
    stamps.truncate(16);

    let buffer = &collector.buffer;
    for &a in &frames {
        for &stamp in &stamps {
            let same = buffer.lookup(a, a, stamp).expect("a frame in itself");
            assert_eq!(same, nalgebra::Isometry3::identity(), "{a} in itself");
            for &b in &frames {
                let ab = buffer.lookup(a, b, stamp).is_ok();
                let ba = buffer.lookup(b, a, stamp).is_ok();
                assert_eq!(ab, ba, "lookups {a} <- {b} and {b} <- {a} at {stamp}");
            }
        }
    }

    let frames: Vec<String> = frames.iter().map(|f| f.to_string()).collect();
    let mut ego = EgoMotion::new(collector, &EgoOptions::default(), false)
        .expect("EgoMotion without --strict accepts every collector");
    for frame in &frames {
        for &stamp in &stamps {
            let msg = Detections3D {
                stamp: Some(stamp),
                frame_id: frame.clone(),
                detections: vec![Detection3D {
                    center: Some(Vector3 {
                        x: 1.0,
                        y: 2.0,
                        z: 0.5,
                    }),
                    yaw: 0.3,
                    label: "car".to_string(),
                    score: 0.9,
                    ..Default::default()
                }],
            };
            let mut msg = DetectionFrame::from_message(msg, stamp);
            ego.to_fixed(&mut msg, || format!("{frame} at {stamp}"))
                .expect("to_fixed without --strict never fails");
            // Taken every time, so that the next message at this stamp is remembered afresh.
            let remembered = ego.take_ego(stamp).is_some();
            if !msg.is_empty() && ego.is_active() {
                assert!(remembered, "a transformed message remembers its ego frame");
            }
        }
    }
    let mut warnings = Vec::new();
    std::hint::black_box(ego.finish("fuzz", &mut warnings));
}

/// Parses `data` as the text of a rosbag2 `metadata.yaml` (not UTF-8: refused before parsing,
/// as `read_metadata` does). Errors are fine; a panic or a hang is not.
pub fn parse_bag_metadata(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    std::hint::black_box(probmot::pipeline::bag_metadata::parse_metadata(text).ok());
}
