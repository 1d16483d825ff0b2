//! Reading a [`FitLog`] from an MCAP file: a ground-truth channel (`probmot.Tracks3D` with the
//! true instance ids) and a detections channel (`probmot.Detections3D`).

use std::collections::{BTreeMap, HashSet};
use std::path::Path;

use anyhow::{bail, Context, Result};
use mcap::records::Record;

use super::data::{assemble_frames, FitBox, FitLog};
use crate::eval::scene::read_tracks_topic;
use crate::mcapio::reader::read_records;
use crate::msgs::{self, Detection3D, Detections3D, Encoding};

/// Reads the `Detections3D` messages of one topic: `(stamp, boxes)` per message, the stamp
/// being the message's `stamp` or else its MCAP `log_time` (as `probmot track` does). Boxes
/// without a centre or size are left out. Errors name the file and topic.
pub fn read_detections_topic(path: &Path, topic: &str) -> Result<Vec<(u64, Vec<FitBox>)>> {
    let file = path.display().to_string();
    let mut schemas: BTreeMap<u16, String> = BTreeMap::new();
    let mut channels: BTreeMap<u16, Encoding> = BTreeMap::new();
    let mut found = false;
    let mut out = Vec::new();
    read_records(path, |rec, _| {
        match rec {
            Record::Schema { header, .. } => {
                schemas.insert(header.id, header.name);
            }
            Record::Channel(c) if c.topic == topic => {
                found = true;
                let schema = schemas.get(&c.schema_id).cloned().unwrap_or_default();
                if schema != msgs::DETECTIONS_SCHEMA {
                    bail!(
                        "{file}: topic {topic} has schema '{schema}', expected {}",
                        msgs::DETECTIONS_SCHEMA
                    );
                }
                let Some(enc) = Encoding::from_message_encoding(&c.message_encoding) else {
                    bail!(
                        "{file}: topic {topic} has message encoding '{}'; expected protobuf or json",
                        c.message_encoding
                    );
                };
                channels.insert(c.id, enc);
            }
            Record::Message { header, data } => {
                if let Some(enc) = channels.get(&header.channel_id) {
                    let m: Detections3D = msgs::decode(&data, *enc).with_context(|| {
                        format!(
                            "{file}: topic {topic}, message at log_time {} (sequence {}): cannot \
                             decode {}",
                            header.log_time,
                            header.sequence,
                            msgs::DETECTIONS_SCHEMA
                        )
                    })?;
                    let stamp = m.stamp.unwrap_or(header.log_time);
                    out.push((
                        stamp,
                        m.detections.iter().filter_map(detection_box).collect(),
                    ));
                }
            }
            _ => {}
        }
        Ok(())
    })?;
    if !found {
        bail!("{file}: no channel with topic {topic} (detections)");
    }
    Ok(out)
}

fn detection_box(d: &Detection3D) -> Option<FitBox> {
    let (c, s) = (d.center?, d.size?);
    Some(FitBox {
        id: 0,
        label: d.label.clone(),
        center: [c.x, c.y, c.z],
        size: [s.length, s.width, s.height],
        yaw: d.yaw,
    })
}

/// Reads one log: truth from `truth_topic`, detections from `detections_topic`. The truth must
/// carry instance ids: a box with id 0 (except `dontcare` regions, which are skipped), or two boxes with the same label and id at one stamp,
/// is an error.
pub fn load_log(path: &Path, truth_topic: &str, detections_topic: &str) -> Result<FitLog> {
    let file = path.display().to_string();
    let truth = read_tracks_topic(path, truth_topic)?;
    if truth.is_empty() {
        bail!("{file}: topic {truth_topic} (ground truth) has no messages");
    }
    let detections = read_detections_topic(path, detections_topic)?;
    let mut by_stamp: BTreeMap<u64, HashSet<(String, u64)>> = BTreeMap::new();
    let mut truth_boxes = Vec::with_capacity(truth.len());
    for (stamp, boxes) in truth {
        let seen = by_stamp.entry(stamp).or_default();
        let mut fb = Vec::with_capacity(boxes.len());
        for b in boxes {
            // Regions without an object (KITTI's DontCare, imported with id 0) hold no box.
            if b.id == 0 && b.label == "dontcare" {
                continue;
            }
            if b.id == 0 {
                bail!(
                    "{file}: topic {truth_topic}, stamp {stamp}: ground-truth box ({}) has no id \
                     (id 0); the fit needs the true instance ids",
                    b.label
                );
            }
            if !seen.insert((b.label.clone(), b.id)) {
                bail!(
                    "{file}: topic {truth_topic}, stamp {stamp}: two ground-truth boxes with label \
                     {} and id {}",
                    b.label,
                    b.id
                );
            }
            fb.push(FitBox {
                id: b.id,
                label: b.label,
                center: b.center,
                size: b.size,
                yaw: b.yaw,
            });
        }
        truth_boxes.push((stamp, fb));
    }
    Ok(assemble_frames(&file, truth_boxes, detections))
}
