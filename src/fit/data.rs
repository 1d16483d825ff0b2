//! The plain data the fit works on: per log, the frames (distinct ground-truth stamps) with their
//! truth boxes and the detections of the same stamp.

use crate::mcapio::LabelledBox;
use crate::msgs::detection_frame::SkipReason;
use std::collections::BTreeMap;

/// One frame: a distinct stamp of the ground-truth channel.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FitFrame {
    /// Stamp, nanoseconds.
    pub stamp: u64,
    /// Ground-truth boxes of this stamp.
    pub truth: Vec<LabelledBox>,
    /// Detections with the same stamp.
    pub detections: Vec<LabelledBox>,
}

/// One log (one scene): frames in stamp order. Instance ids are only compared within a log.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FitLog {
    /// Name for messages (the file path).
    pub name: String,
    /// Frames in increasing stamp order.
    pub frames: Vec<FitFrame>,
    /// Detection messages whose stamp is not a ground-truth stamp (not used).
    pub unmatched_detection_messages: u64,
    /// Detection boxes left out when read, by reason, as `probmot track` skips them.
    pub skipped_detections: BTreeMap<SkipReason, u64>,
    /// Ground-truth boxes left out when read: a non-finite centre, size or yaw.
    pub skipped_truth: u64,
}

/// Builds the frames of a log. Every distinct truth stamp is a frame (messages sharing a stamp
/// are merged); detection messages are attached to the frame of the same stamp, and those
/// whose stamp is no truth stamp are only counted.
pub fn assemble_frames(
    name: &str,
    truth: Vec<(u64, Vec<LabelledBox>)>,
    detections: Vec<(u64, Vec<LabelledBox>)>,
) -> FitLog {
    let mut frames: BTreeMap<u64, FitFrame> = BTreeMap::new();
    for (stamp, boxes) in truth {
        frames
            .entry(stamp)
            .or_insert_with(|| FitFrame {
                stamp,
                ..Default::default()
            })
            .truth
            .extend(boxes);
    }
    let mut unmatched = 0;
    for (stamp, boxes) in detections {
        match frames.get_mut(&stamp) {
            Some(f) => f.detections.extend(boxes),
            None => unmatched += 1,
        }
    }
    FitLog {
        name: name.to_string(),
        frames: frames.into_values().collect(),
        unmatched_detection_messages: unmatched,
        skipped_detections: BTreeMap::new(),
        skipped_truth: 0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn b(id: u64) -> LabelledBox {
        LabelledBox {
            id,
            label: "car".into(),
            center: [0.0; 3],
            size: [1.0; 3],
            ..Default::default()
        }
    }

    #[test]
    fn frames_are_truth_stamps_in_order() {
        let log = assemble_frames(
            "x",
            vec![(20, vec![b(1)]), (10, vec![b(1)]), (20, vec![b(2)])],
            vec![(10, vec![b(0)]), (15, vec![b(0)]), (20, vec![b(0), b(0)])],
        );
        let stamps: Vec<u64> = log.frames.iter().map(|f| f.stamp).collect();
        assert_eq!(stamps, vec![10, 20]);
        assert_eq!(log.frames[1].truth.len(), 2);
        assert_eq!(log.frames[0].detections.len(), 1);
        assert_eq!(log.frames[1].detections.len(), 2);
        assert_eq!(log.unmatched_detection_messages, 1);
    }
}
