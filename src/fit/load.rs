//! Reading a [`FitLog`] from an MCAP file: a ground-truth channel (`probmot.Tracks3D` with the
//! true instance ids) and a detections channel (`probmot.Detections3D`).

use std::collections::{BTreeMap, HashSet};
use std::path::Path;

use anyhow::{bail, Context, Result};

use super::data::{assemble_frames, FitBox, FitLog};
use crate::eval::scene::read_tracks_topic;
use crate::mcapio::topic::for_each_message;
use crate::msgs::{self, Detection3D, Detections3D};

/// Reads the `Detections3D` messages of one topic: `(stamp, boxes)` per message, the stamp
/// being the message's `stamp` or else its MCAP `log_time` (as `probmot track` does). Boxes
/// without a centre or size are left out. Errors name the file and topic.
pub fn read_detections_topic(path: &Path, topic: &str) -> Result<Vec<(u64, Vec<FitBox>)>> {
    let mut out = Vec::new();
    for_each_message(
        path,
        topic,
        msgs::DETECTIONS_SCHEMA,
        |header, m: Detections3D| {
            let stamp = m.stamp.unwrap_or(header.log_time);
            out.push((
                stamp,
                m.detections.iter().filter_map(detection_box).collect(),
            ));
            Ok(())
        },
        |_| Ok(()),
    )
    .with_context(|| format!("reading detections from {}", path.display()))?;
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
