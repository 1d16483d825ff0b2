//! Writing one imported scene's MCAP file (all channels and metadata records).

use std::collections::{BTreeMap, HashMap};

use anyhow::Result;
use mcap::records::{MessageHeader, Metadata};

use crate::mcapio::writer::{AtomicOutput, OutputOptions};
use crate::msgs::{self, v3, Detection3D, Detections3D, Track3D, Tracks3D};

use super::import::{attrs, nusc_size, EgoPoseMsg, ScenePlan, SceneSummary, TruthBox};
use super::results::DetectionResults;
use super::tables::EgoPoseRow;
use super::tracks::{rack_track, track_of, RackAnn, TrackIds, TrackingResults};
use super::{
    attr, quaternion_yaw, BIKE_RACKS_TOPIC, EGO_POSE_JSON_SCHEMA, EGO_POSE_SCHEMA, FRAME_ID,
    NUSCENES_METADATA, SAMPLES_METADATA,
};

/// Ground truth and bicycle racks by sample token.
pub(crate) type TruthAndRacks<'a> = (
    &'a HashMap<String, Vec<TruthBox>>,
    &'a HashMap<String, Vec<RackAnn>>,
);

pub(crate) fn write_scene(
    plan: &ScenePlan,
    results: Option<&DetectionResults>,
    tracking: Option<&TrackingResults>,
    truth_racks: Option<TruthAndRacks>,
    ego: Option<&HashMap<String, EgoPoseRow>>,
    (det_file, trk_file): (&str, &str),
    results_meta: &str,
) -> Result<SceneSummary> {
    let truth = truth_racks.map(|t| t.0);
    let mut s = SceneSummary {
        name: plan.scene.name.clone(),
        output: plan.output.display().to_string(),
        frames: plan.samples.len() as u64,
        ..Default::default()
    };
    let mut out = AtomicOutput::create(&plan.output, &OutputOptions::default())?;
    let w = &mut out.writer;
    let none = BTreeMap::new();
    let c_det = match results {
        Some(_) => {
            let s_det = w.add_schema(msgs::DETECTIONS_SCHEMA, "protobuf", msgs::DESCRIPTOR_SET)?;
            Some(w.add_channel(s_det, "/detections", "protobuf", &none)?)
        }
        None => None,
    };
    let s_trk = if truth.is_some() || tracking.is_some() {
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
    let c_gt = tracks_channel("/ground_truth", truth.is_some())?;
    let c_racks = tracks_channel(BIKE_RACKS_TOPIC, truth.is_some())?;
    let c_tracks = tracks_channel("/tracks", tracking.is_some())?;
    let c_ego = match ego {
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
    w.write_metadata(&Metadata {
        name: NUSCENES_METADATA.into(),
        metadata: attrs(&[
            ("scene_token", plan.scene.token.clone()),
            ("scene_name", plan.scene.name.clone()),
            ("scene_description", plan.scene.description.clone()),
            ("nbr_samples", plan.samples.len().to_string()),
            ("detections_file", det_file.to_string()),
            ("tracks_file", trk_file.to_string()),
            ("detections_meta", results_meta.to_string()),
            ("ground_truth", truth.is_some().to_string()),
            ("ego_pose", ego.is_some().to_string()),
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
        if let (Some(c_det), Some(results)) = (c_det, results) {
            let names = &results.strings.names;
            let boxes = results.boxes.get(tok).map(Vec::as_slice).unwrap_or(&[]);
            let msg = Detections3D {
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
                            (attr::SAMPLE_TOKEN, tok.clone()),
                            (attr::ATTRIBUTE_NAME, names[b.attribute as usize].clone()),
                        ]),
                    })
                    .collect(),
            };
            s.detections += boxes.len() as u64;
            msgs::encode_into(&msg, &mut buf);
            w.write_to_known_channel(&header(c_det), &buf)?;
        }
        if let (Some(c_tracks), Some(tracking)) = (c_tracks, tracking) {
            let boxes = tracking.results.get(tok).map(Vec::as_slice).unwrap_or(&[]);
            let msg = Tracks3D {
                stamp,
                frame_id: FRAME_ID.into(),
                tracks: boxes.iter().map(|b| track_of(b, &mut track_ids)).collect(),
            };
            s.tracks += boxes.len() as u64;
            msgs::encode_into(&msg, &mut buf);
            w.write_to_known_channel(&header(c_tracks), &buf)?;
        }
        if let (Some(c_racks), Some((_, racks))) = (c_racks, truth_racks) {
            let boxes = racks.get(tok).map(Vec::as_slice).unwrap_or(&[]);
            let msg = Tracks3D {
                stamp,
                frame_id: FRAME_ID.into(),
                tracks: boxes.iter().map(|r| rack_track(r, tok)).collect(),
            };
            s.bike_racks += boxes.len() as u64;
            msgs::encode_into(&msg, &mut buf);
            w.write_to_known_channel(&header(c_racks), &buf)?;
        }
        if let (Some(c_gt), Some(truth)) = (c_gt, truth) {
            let boxes = truth.get(tok).map(Vec::as_slice).unwrap_or(&[]);
            let gt = Tracks3D {
                stamp,
                frame_id: FRAME_ID.into(),
                tracks: boxes
                    .iter()
                    .map(|b| Track3D {
                        id: b.id,
                        label: b.label.into(),
                        center: Some(v3(b.ann.translation)),
                        size: Some(nusc_size(b.ann.size)),
                        yaw: quaternion_yaw(b.ann.rotation),
                        velocity: Some(v3(b.velocity)),
                        score: 1.0,
                        attributes: attrs(&[
                            (attr::SAMPLE_TOKEN, tok.clone()),
                            (attr::INSTANCE_TOKEN, b.ann.instance_token.clone()),
                            (attr::ANNOTATION_TOKEN, b.ann.token.clone()),
                            (attr::CATEGORY, b.category.clone()),
                            (
                                attr::NUM_LIDAR_PTS,
                                b.ann
                                    .num_lidar_pts
                                    .map(|n| n.to_string())
                                    .unwrap_or_default(),
                            ),
                            (
                                attr::NUM_RADAR_PTS,
                                b.ann
                                    .num_radar_pts
                                    .map(|n| n.to_string())
                                    .unwrap_or_default(),
                            ),
                        ]),
                        ..Default::default()
                    })
                    .collect(),
            };
            s.truth_boxes += boxes.len() as u64;
            msgs::encode_into(&gt, &mut buf);
            w.write_to_known_channel(&header(c_gt), &buf)?;
        }
        if let (Some(c_ego), Some(ego)) = (c_ego, ego) {
            let pose = &ego[tok];
            let json = serde_json::to_vec(&EgoPoseMsg {
                stamp,
                translation: pose.translation,
                rotation: pose.rotation,
            })?;
            w.write_to_known_channel(&header(c_ego), &json)?;
            s.ego_poses += 1;
        }
    }
    out.commit()?;
    Ok(s)
}
