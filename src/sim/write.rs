//! Writes a simulated drive as MCAP: `/detections` (`probmot.Detections3D`) and
//! `/ground_truth` (`probmot.Tracks3D` with the true ids).

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::Result;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use super::scenario::{objects, SimOptions};
use super::sensor::detect;
use crate::mcapio::writer::{AtomicOutput, OutputOptions};
use crate::msgs::{self, v3, Detection3D, Detections3D, Size3, Track3D, Tracks3D};

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
    let objs = objects(opts);
    // The detector's random stream is separate from the scenario's.
    let mut rng = ChaCha8Rng::seed_from_u64(opts.seed ^ 0x5eed_0fde_7ec7);
    let mut output = AtomicOutput::create(out, &OutputOptions::default())?;
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
        let msg = Detections3D {
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
                    attributes: BTreeMap::from([(
                        "sim_truth_id".to_string(),
                        d.truth_id.to_string(),
                    )]),
                    ..Default::default()
                })
                .collect(),
        };
        summary.detections += dets.len() as u64;
        msgs::encode_into(&msg, &mut buf);
        w.write_to_known_channel(&header(ch_det, f, stamp), &buf)?;

        let gt = Tracks3D {
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
        };
        summary.truth_boxes += gt.tracks.len() as u64;
        msgs::encode_into(&gt, &mut buf);
        w.write_to_known_channel(&header(ch_gt, f, stamp), &buf)?;
    }
    output.commit()?;
    Ok(summary)
}

fn header(channel_id: u16, frame: usize, stamp: u64) -> mcap::records::MessageHeader {
    mcap::records::MessageHeader {
        channel_id,
        sequence: frame as u32,
        log_time: stamp,
        publish_time: stamp,
    }
}

/// A [`Size3`] from `[l, w, h]`.
pub fn size3(s: [f64; 3]) -> Size3 {
    Size3 {
        length: s[0],
        width: s[1],
        height: s[2],
    }
}
