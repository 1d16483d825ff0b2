//! Writes a simulated drive as MCAP: `/detections` (`probmot.Detections3D`) and
//! `/ground_truth` (`probmot.Tracks3D` with the true ids).

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::{Context, Result};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use super::ego::{self, ego_pose, EgoPose};
use super::scenario::{objects, SimOptions};
use super::sensor::{detect, SimDetection};
use super::SimObject;
use crate::mcapio::writer::{AtomicOutput, OutputOptions};
use crate::msgs::track_encode::encode_tracks_into;
use crate::msgs::{self, v3, Detection3D, Detections3D, Track3D, Tracks3D};
use crate::transforms::sources::FOXGLOVE_FRAME_TRANSFORM;

/// First frame's stamp: 2026-01-01T00:00:00Z in nanoseconds.
pub const START_NS: u64 = 1_767_225_600_000_000_000;

/// Counts of a written simulation.
#[derive(Debug, Clone, Copy, Default, serde::Serialize)]
pub struct SimSummary {
    /// Frames written.
    pub frames: u32,
    /// True objects.
    pub objects: usize,
    /// Detections written.
    pub detections: u64,
    /// Ground-truth boxes written.
    pub truth_boxes: u64,
}

/// Simulates and writes `out` atomically. The same options give a byte-identical file.
pub fn write_simulation(opts: &SimOptions, out: &Path) -> Result<SimSummary> {
    write_simulation_progress(opts, out, &|_| {})
}

/// [`write_simulation`], telling `progress` each frame written (long drives take a while).
pub fn write_simulation_progress(
    opts: &SimOptions,
    out: &Path,
    progress: &dyn Fn(u64),
) -> Result<SimSummary> {
    let objs = objects(opts);
    // The detector's random stream is separate from the scenario's.
    let mut rng = ChaCha8Rng::seed_from_u64(opts.seed ^ 0x5eed_0fde_7ec7);
    let mut output = AtomicOutput::create(out, &OutputOptions::default())?;
    // Every write error names the output (a full disk, a file-size limit).
    let summary = (|| -> Result<SimSummary> {
        let w = &mut output.writer;
        let schema_det = w.add_schema(msgs::DETECTIONS_SCHEMA, "protobuf", msgs::DESCRIPTOR_SET)?;
        let schema_trk = w.add_schema(msgs::TRACKS_SCHEMA, "protobuf", msgs::DESCRIPTOR_SET)?;
        let mut meta = BTreeMap::new();
        meta.insert(
            "probmot.simulate.scenario".to_string(),
            opts.scenario.name().to_string(),
        );
        let ch_det = w.add_channel(schema_det, "/detections", "protobuf", &meta)?;
        let ch_gt = w.add_channel(schema_trk, "/ground_truth", "protobuf", &meta)?;
        let ego_channels = if opts.ego_frame {
            let schema_tf = w.add_schema(
                FOXGLOVE_FRAME_TRANSFORM,
                "protobuf",
                &frame_transform_descriptor(),
            )?;
            let ch_tf = w.add_channel(schema_tf, "/tf", "protobuf", &meta)?;
            let ch_gt_ego = w.add_channel(schema_trk, "/ground_truth/ego", "protobuf", &meta)?;
            Some((ch_tf, ch_gt_ego))
        } else {
            None
        };
        let period_ns = (1e9 / opts.rate_hz).round() as u64;
        let mut summary = SimSummary {
            frames: opts.frames,
            objects: objs.len(),
            ..Default::default()
        };
        let mut buf = Vec::new();
        for f in 0..opts.frames as usize {
            let stamp = START_NS + f as u64 * period_ns;
            let dets = detect(opts.scenario, &objs, f, &mut rng);
            let mut msg = detections_msg(&dets, stamp);
            summary.detections += dets.len() as u64;
            let pose = ego_pose(f as f64 * opts.dt());
            if let Some((ch_tf, _)) = ego_channels {
                // The transforms up to and including this frame's stamp, then the detections.
                let per = ego::TRANSFORMS_PER_FRAME as u64;
                let first = if f == 0 { per - 1 } else { 0 };
                for k in first..per {
                    let t_ns = stamp - (per - 1 - k) * period_ns / per;
                    let t = (t_ns - START_NS) as f64 * 1e-9;
                    let p = if k == per - 1 { pose } else { ego_pose(t) };
                    msgs::encode_into(&frame_transform(t_ns, &p), &mut buf);
                    let seq = (f as u64 * per + k) as usize;
                    w.write_to_known_channel(&header(ch_tf, seq, t_ns), &buf)?;
                }
                detections_to_ego(&mut msg, &pose);
            }
            msgs::encode_into(&msg, &mut buf);
            w.write_to_known_channel(&header(ch_det, f, stamp), &buf)?;

            let gt = truth_msg(&objs, f, stamp);
            summary.truth_boxes += gt.tracks.len() as u64;
            encode_tracks_into(&gt, &mut buf);
            w.write_to_known_channel(&header(ch_gt, f, stamp), &buf)?;
            if let Some((_, ch_gt_ego)) = ego_channels {
                encode_tracks_into(&truth_to_ego(gt, &pose), &mut buf);
                w.write_to_known_channel(&header(ch_gt_ego, f, stamp), &buf)?;
            }
            progress(1);
        }
        Ok(summary)
    })()
    .with_context(|| format!("writing {}", out.display()))?;
    output.commit()?;
    Ok(summary)
}

/// The `/detections` message of one frame, in the map frame.
fn detections_msg(dets: &[SimDetection], stamp: u64) -> Detections3D {
    Detections3D {
        stamp: Some(stamp),
        frame_id: "map".into(),
        detections: dets
            .iter()
            .map(|d| Detection3D {
                center: Some(v3(d.center)),
                size: Some(size3(d.size)),
                yaw: d.yaw,
                label: d.label.into(),
                score: d.score,
                attributes: BTreeMap::from([("sim_truth_id".to_string(), d.truth_id.to_string())]),
                ..Default::default()
            })
            .collect(),
    }
}

/// The detections seen from the ego vehicle at `pose`.
fn detections_to_ego(msg: &mut Detections3D, pose: &EgoPose) {
    msg.frame_id = ego::EGO_FRAME.into();
    for d in &mut msg.detections {
        let c = d.center.expect("set above");
        d.center = Some(v3(pose.to_ego([c.x, c.y, c.z])));
        d.yaw = pose.yaw_to_ego(d.yaw);
    }
}

/// The `/ground_truth` message of frame `f`: every object present, in the map frame.
fn truth_msg(objs: &[SimObject], f: usize, stamp: u64) -> Tracks3D {
    Tracks3D {
        stamp,
        frame_id: "map".into(),
        tracks: objs
            .iter()
            .filter_map(|o| {
                let s = o.states[f]?;
                Some(Track3D {
                    id: o.id,
                    label: o.label.into(),
                    center: Some(v3(s.center)),
                    size: Some(size3(o.size)),
                    yaw: s.yaw,
                    velocity: Some(v3(s.velocity)),
                    yaw_rate: s.yaw_rate,
                    score: 1.0,
                    ..Default::default()
                })
            })
            .collect(),
    }
}

/// The ground truth seen from the ego vehicle at `pose` (`/ground_truth/ego`).
fn truth_to_ego(mut gt: Tracks3D, pose: &EgoPose) -> Tracks3D {
    gt.frame_id = ego::EGO_FRAME.into();
    for t in &mut gt.tracks {
        let c = t.center.expect("set above");
        let v = t.velocity.expect("set above");
        t.center = Some(v3(pose.to_ego([c.x, c.y, c.z])));
        t.velocity = Some(v3(pose.rotate_to_ego([v.x, v.y, v.z])));
        t.yaw = pose.yaw_to_ego(t.yaw);
    }
    gt
}

/// The `FileDescriptorSet` of `foxglove.FrameTransform`.
fn frame_transform_descriptor() -> Vec<u8> {
    use foxglove::Encode as _;
    foxglove::schemas::FrameTransform::get_schema()
        .expect("foxglove.FrameTransform has a schema")
        .data
        .into_owned()
}

/// The ego pose as the transform map -> base_link at `stamp`.
fn frame_transform(stamp: u64, p: &EgoPose) -> foxglove::schemas::FrameTransform {
    foxglove::schemas::FrameTransform {
        timestamp: Some(foxglove::schemas::Timestamp::new(
            (stamp / 1_000_000_000) as u32,
            (stamp % 1_000_000_000) as u32,
        )),
        parent_frame_id: ego::FIXED_FRAME.into(),
        child_frame_id: ego::EGO_FRAME.into(),
        translation: Some(foxglove::schemas::Vector3 {
            x: p.x,
            y: p.y,
            z: 0.0,
        }),
        rotation: Some(foxglove::schemas::Quaternion {
            x: 0.0,
            y: 0.0,
            z: (p.yaw / 2.0).sin(),
            w: (p.yaw / 2.0).cos(),
        }),
    }
}

fn header(channel_id: u16, frame: usize, stamp: u64) -> mcap::records::MessageHeader {
    mcap::records::MessageHeader {
        channel_id,
        sequence: frame as u32,
        log_time: stamp,
        publish_time: stamp,
    }
}

/// Re-exported for the importers that still take it from here (it belongs to the messages).
pub use crate::msgs::size3;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::Scenario;
    use std::cell::Cell;

    #[test]
    fn progress_counts_every_frame_and_changes_nothing_written() {
        let dir = tempfile::tempdir().unwrap();
        let opts = SimOptions {
            scenario: Scenario::City,
            seed: 3,
            frames: 25,
            objects: Some(5),
            rate_hz: 10.0,
            ego_frame: true,
        };
        let (a, b) = (dir.path().join("a.mcap"), dir.path().join("b.mcap"));
        let frames = Cell::new(0);
        let with = write_simulation_progress(&opts, &a, &|n| frames.set(frames.get() + n)).unwrap();
        let without = write_simulation(&opts, &b).unwrap();
        assert_eq!(frames.get(), 25);
        assert_eq!(
            (with.frames, with.detections),
            (without.frames, without.detections)
        );
        assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
    }
}
