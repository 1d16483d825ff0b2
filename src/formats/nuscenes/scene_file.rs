//! Writing one imported scene's MCAP file (all channels and metadata records).

use std::collections::{BTreeMap, HashMap};

use anyhow::Result;
use mcap::records::{MessageHeader, Metadata};
use mcap::Writer;
use serde::Serialize;

use crate::mcapio::writer::{AtomicOutput, OutputOptions, OutputSink};
use crate::msgs::track_encode::encode_tracks_into;
use crate::msgs::{self, v3, Detection3D, Detections3D, Track3D, Tracks3D};

use super::plan::ScenePlan;
use super::results::DetectionResults;
use super::tables::EgoPoseRow;
use super::tracks::{rack_track, track_of, TrackIds, TrackingResults};
use super::truth::{GroundTruth, TruthBox};
use super::{
    attr, attrs, nusc_size, quaternion_yaw, BIKE_RACKS_TOPIC, EGO_POSE_JSON_SCHEMA,
    EGO_POSE_SCHEMA, FRAME_ID, NUSCENES_METADATA, SAMPLES_METADATA,
};

/// Counts of one written scene.
#[derive(Debug, Clone, Default, Serialize)]
pub struct SceneSummary {
    /// Scene name.
    pub name: String,
    /// Output file.
    pub output: String,
    /// Frames (samples).
    pub frames: u64,
    /// Detections written.
    pub detections: u64,
    /// Ground-truth boxes written.
    pub truth_boxes: u64,
    /// Ego poses written.
    pub ego_poses: u64,
    /// Track boxes written.
    pub tracks: u64,
    /// Bicycle-rack boxes written.
    pub bike_racks: u64,
}

/// An `/ego_pose` message (JSON, schema [`EGO_POSE_JSON_SCHEMA`]).
#[derive(Serialize)]
struct EgoPoseMsg {
    stamp: u64,
    translation: [f64; 3],
    rotation: [f64; 4],
}

/// What the scenes of an import are written from; each `None` leaves its channel out.
pub(crate) struct SceneInputs<'a> {
    /// Detection results (`/detections`).
    pub(crate) results: Option<&'a DetectionResults>,
    /// Tracking submission (`/tracks`).
    pub(crate) tracking: Option<&'a TrackingResults>,
    /// Ground truth (`/ground_truth` and the bicycle racks).
    pub(crate) truth: Option<&'a GroundTruth>,
    /// Ego pose by sample token (`/ego_pose`).
    pub(crate) ego: Option<&'a HashMap<String, EgoPoseRow>>,
    /// The detections and tracks files as named in the metadata (empty when not given).
    pub(crate) files: (&'a str, &'a str),
    /// The detection results' `meta` block as JSON text (empty when absent).
    pub(crate) results_meta: &'a str,
}

/// The channel ids of a scene file, `None` for a channel left out.
struct Channels {
    det: Option<u16>,
    tracks: Option<u16>,
    racks: Option<u16>,
    gt: Option<u16>,
    ego: Option<u16>,
}

type McapWriter = Writer<OutputSink>;

/// Writes one scene's file atomically (channels, metadata, then a message per sample and
/// channel) and returns its counts.
pub(crate) fn write_scene(plan: &ScenePlan, inputs: &SceneInputs) -> Result<SceneSummary> {
    let mut s = SceneSummary {
        name: plan.scene.name.clone(),
        output: plan.output.display().to_string(),
        frames: plan.samples.len() as u64,
        ..Default::default()
    };
    let mut out = AtomicOutput::create(&plan.output, &OutputOptions::default())?;
    let w = &mut out.writer;
    let ch = add_channels(w, inputs)?;
    write_metadata(w, plan, inputs)?;
    let mut buf = Vec::new();
    let mut track_ids = TrackIds::default();
    for (frame, (tok, t_us)) in plan.samples.iter().enumerate() {
        let stamp = t_us * 1000;
        let header = |ch| MessageHeader {
            channel_id: ch,
            sequence: frame as u32,
            log_time: stamp,
            publish_time: stamp,
        };
        if let (Some(c), Some(results)) = (ch.det, inputs.results) {
            let msg = detections_msg(results, tok, stamp);
            s.detections += msg.detections.len() as u64;
            msgs::encode_into(&msg, &mut buf);
            w.write_to_known_channel(&header(c), &buf)?;
        }
        if let (Some(c), Some(tracking)) = (ch.tracks, inputs.tracking) {
            let boxes = tracking.results.get(tok).map(Vec::as_slice).unwrap_or(&[]);
            let tracks = boxes.iter().map(|b| track_of(b, &mut track_ids)).collect();
            s.tracks += boxes.len() as u64;
            encode_tracks_into(&tracks_msg(stamp, tracks), &mut buf);
            w.write_to_known_channel(&header(c), &buf)?;
        }
        if let (Some(c), Some(truth)) = (ch.racks, inputs.truth) {
            let boxes = truth.racks.get(tok).map(Vec::as_slice).unwrap_or(&[]);
            let tracks = boxes.iter().map(|r| rack_track(r, tok)).collect();
            s.bike_racks += boxes.len() as u64;
            encode_tracks_into(&tracks_msg(stamp, tracks), &mut buf);
            w.write_to_known_channel(&header(c), &buf)?;
        }
        if let (Some(c), Some(truth)) = (ch.gt, inputs.truth) {
            let boxes = truth.boxes.get(tok).map(Vec::as_slice).unwrap_or(&[]);
            let tracks = boxes.iter().map(|b| truth_track(b, tok)).collect();
            s.truth_boxes += boxes.len() as u64;
            encode_tracks_into(&tracks_msg(stamp, tracks), &mut buf);
            w.write_to_known_channel(&header(c), &buf)?;
        }
        if let (Some(c), Some(ego)) = (ch.ego, inputs.ego) {
            let pose = &ego[tok];
            let json = serde_json::to_vec(&EgoPoseMsg {
                stamp,
                translation: pose.translation,
                rotation: pose.rotation,
            })?;
            w.write_to_known_channel(&header(c), &json)?;
            s.ego_poses += 1;
        }
    }
    out.commit()?;
    Ok(s)
}

/// Adds the schemas and channels of the inputs given, in a fixed order.
fn add_channels(w: &mut McapWriter, inputs: &SceneInputs) -> Result<Channels> {
    let none = BTreeMap::new();
    let det = match inputs.results {
        Some(_) => {
            let s_det = w.add_schema(msgs::DETECTIONS_SCHEMA, "protobuf", msgs::DESCRIPTOR_SET)?;
            Some(w.add_channel(s_det, "/detections", "protobuf", &none)?)
        }
        None => None,
    };
    let has_truth = inputs.truth.is_some();
    let s_trk = if has_truth || inputs.tracking.is_some() {
        Some(w.add_schema(msgs::TRACKS_SCHEMA, "protobuf", msgs::DESCRIPTOR_SET)?)
    } else {
        None
    };
    let mut tracks_channel = |topic: &str, on: bool| -> Result<Option<u16>> {
        match (s_trk, on) {
            (Some(schema), true) => Ok(Some(w.add_channel(schema, topic, "protobuf", &none)?)),
            _ => Ok(None),
        }
    };
    let gt = tracks_channel("/ground_truth", has_truth)?;
    let racks = tracks_channel(BIKE_RACKS_TOPIC, has_truth)?;
    let tracks = tracks_channel("/tracks", inputs.tracking.is_some())?;
    let ego = match inputs.ego {
        Some(_) => {
            let s_ego = w.add_schema(
                EGO_POSE_SCHEMA,
                "jsonschema",
                EGO_POSE_JSON_SCHEMA.as_bytes(),
            )?;
            Some(w.add_channel(s_ego, "/ego_pose", "json", &none)?)
        }
        None => None,
    };
    Ok(Channels {
        det,
        tracks,
        racks,
        gt,
        ego,
    })
}

/// The metadata records [`NUSCENES_METADATA`] and [`SAMPLES_METADATA`].
fn write_metadata(w: &mut McapWriter, plan: &ScenePlan, inputs: &SceneInputs) -> Result<()> {
    let (det_file, trk_file) = inputs.files;
    w.write_metadata(&Metadata {
        name: NUSCENES_METADATA.into(),
        metadata: attrs(&[
            ("scene_token", plan.scene.token.clone()),
            ("scene_name", plan.scene.name.clone()),
            ("scene_description", plan.scene.description.clone()),
            ("nbr_samples", plan.samples.len().to_string()),
            ("detections_file", det_file.to_string()),
            ("tracks_file", trk_file.to_string()),
            ("detections_meta", inputs.results_meta.to_string()),
            ("ground_truth", inputs.truth.is_some().to_string()),
            ("ego_pose", inputs.ego.is_some().to_string()),
        ]),
    })?;
    w.write_metadata(&Metadata {
        name: SAMPLES_METADATA.into(),
        metadata: plan
            .samples
            .iter()
            .map(|(tok, t)| ((t * 1000).to_string(), tok.clone()))
            .collect(),
    })?;
    Ok(())
}

/// The `/detections` message of sample `tok`.
fn detections_msg(results: &DetectionResults, tok: &str, stamp: u64) -> Detections3D {
    let names = &results.strings.names;
    let boxes = results.boxes.get(tok).map(Vec::as_slice).unwrap_or(&[]);
    Detections3D {
        stamp: Some(stamp),
        frame_id: FRAME_ID.into(),
        detections: boxes
            .iter()
            .map(|b| Detection3D {
                center: Some(v3(b.translation)),
                size: Some(nusc_size(b.size)),
                yaw: quaternion_yaw(b.rotation),
                label: names[b.name as usize].clone(),
                score: b.score,
                velocity: Some(v3([b.velocity[0], b.velocity[1], 0.0])),
                image_box: None,
                attributes: attrs(&[
                    (attr::SAMPLE_TOKEN, tok.to_string()),
                    (attr::ATTRIBUTE_NAME, names[b.attribute as usize].clone()),
                ]),
            })
            .collect(),
    }
}

/// A `Tracks3D` message of the import's frame.
fn tracks_msg(stamp: u64, tracks: Vec<Track3D>) -> Tracks3D {
    Tracks3D {
        stamp,
        frame_id: FRAME_ID.into(),
        tracks,
    }
}

/// A ground-truth box of sample `tok` as a track, its nuScenes fields as attributes.
fn truth_track(b: &TruthBox, tok: &str) -> Track3D {
    let count = |n: Option<i64>| n.map(|n| n.to_string()).unwrap_or_default();
    Track3D {
        id: b.id,
        label: b.label.into(),
        center: Some(v3(b.ann.translation)),
        size: Some(nusc_size(b.ann.size)),
        yaw: quaternion_yaw(b.ann.rotation),
        velocity: Some(v3(b.velocity)),
        score: 1.0,
        attributes: attrs(&[
            (attr::SAMPLE_TOKEN, tok.to_string()),
            (attr::INSTANCE_TOKEN, b.ann.instance_token.clone()),
            (attr::ANNOTATION_TOKEN, b.ann.token.clone()),
            (attr::CATEGORY, b.category.clone()),
            (attr::NUM_LIDAR_PTS, count(b.ann.num_lidar_pts)),
            (attr::NUM_RADAR_PTS, count(b.ann.num_radar_pts)),
        ]),
        ..Default::default()
    }
}
