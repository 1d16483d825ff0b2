//! The decoded detection input: one [`DetectionFrame`] per detection message, whatever its
//! source (probmot protobuf/JSON, ROS 2 `vision_msgs`, Foxglove `SceneUpdate`), with the boxes
//! checked once here. Boxes that fail the check are kept as [`Rejected`] entries (index, label,
//! reason), so that the caller counts or refuses them in message order with the label lookup.

use std::collections::BTreeMap;

use super::{Detection3D, Detections3D, ImageBox};
use crate::tracker::{bounds, Box3};

/// Why a detection box was skipped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SkipReason {
    /// A centre, size, yaw or score field is NaN or infinite.
    NonFinite,
    /// A size is zero or negative.
    NonPositiveSize,
    /// The label is not in the config and the config has no default entry.
    UnknownLabel,
    /// An Autoware class that is none of probmot's (UNKNOWN, ANIMAL, ...) and has no config
    /// entry of its own name (the `default` entry does not apply to it).
    ClassWithoutEntry,
    /// The centre or size field is missing.
    MissingField,
    /// A centre coordinate lies beyond [`bounds::MAX_COORDINATE`].
    CentreBeyondBound,
    /// A size exceeds [`bounds::MAX_SIZE`].
    SizeBeyondBound,
    /// A velocity component is NaN or infinite.
    NonFiniteVelocity,
    /// A velocity component exceeds [`bounds::MAX_SPEED`].
    VelocityBeyondBound,
    /// The label is not valid UTF-8 (ROS 2 `vision_msgs`: the class id of any hypothesis).
    LabelNotUtf8,
    /// The per-object id (ROS 2 `vision_msgs` `id` or `tracking_id`) is not valid UTF-8.
    IdNotUtf8,
}

impl SkipReason {
    /// Short description.
    pub fn describe(self) -> &'static str {
        match self {
            SkipReason::NonFinite => "non-finite field",
            SkipReason::NonPositiveSize => "non-positive size",
            SkipReason::UnknownLabel => "label not in the config (no default entry)",
            SkipReason::ClassWithoutEntry => {
                "Autoware class that is none of probmot's (unknown, animal, ...), without a \
                 config entry of its name"
            }
            SkipReason::MissingField => "missing centre or size",
            SkipReason::CentreBeyondBound => "centre coordinate beyond 1e7 m",
            SkipReason::SizeBeyondBound => "size beyond 1e4 m",
            SkipReason::NonFiniteVelocity => "non-finite velocity",
            SkipReason::VelocityBeyondBound => "velocity beyond 1e5 m/s",
            SkipReason::LabelNotUtf8 => "label not valid UTF-8",
            SkipReason::IdNotUtf8 => "id not valid UTF-8",
        }
    }
}

/// One valid detection box: finite geometry with positive sizes and a finite score.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct DetectionBox {
    /// Position of the box in its message (for error messages).
    pub index: u32,
    /// Centre, yaw and size, in the frame's `frame_id`.
    pub bbox: Box3,
    /// Class label as given (looked up in the tracker config later).
    pub label: String,
    /// Detector score (may lie outside `[0, 1]`).
    pub score: f64,
    /// Velocity over ground, if the source gives one.
    pub velocity: Option<[f64; 3]>,
    /// Image box, if any.
    pub image_box: Option<ImageBox>,
    /// Free-form attributes, copied to the track the box updates.
    pub attributes: BTreeMap<String, String>,
    /// Tracked only under a config entry of its own label, never with the config's `default`
    /// entry: an Autoware class that is none of probmot's (UNKNOWN, ANIMAL, ...; see
    /// [`super::autoware`]), whose boxes another class's statistics would not fit.
    pub needs_own_entry: bool,
}

/// A box that failed the check: where it was, its label and why.
#[derive(Debug, Clone, PartialEq)]
pub struct Rejected {
    /// Position of the box in its message.
    pub index: u32,
    /// Its label as given.
    pub label: String,
    /// Why it was rejected.
    pub reason: SkipReason,
}

/// The boxes of one detection message.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct DetectionFrame {
    /// The message's stamp, else the MCAP log_time (see [`stamp_or_log_time`]).
    pub stamp: u64,
    /// Frame of the boxes.
    pub frame_id: String,
    /// Valid boxes, in message order.
    pub boxes: Vec<DetectionBox>,
    /// Invalid boxes, in message order.
    pub rejected: Vec<Rejected>,
}

/// Adds one box per reason to `skipped` (the boxes a reader left out, counted by reason).
pub fn count_skips(skipped: &mut BTreeMap<SkipReason, u64>, reasons: &[SkipReason]) {
    for &reason in reasons {
        *skipped.entry(reason).or_default() += 1;
    }
}

/// `N detection boxes (reason)`, or `N detection boxes: a (reason), b (reason)` for several
/// reasons: the boxes a reader of detections skipped, as `track`, `fit` and `tune` report them.
pub fn describe_skips(skipped: &BTreeMap<SkipReason, u64>) -> String {
    let total: u64 = skipped.values().sum();
    if let [(r, _)] = skipped.iter().collect::<Vec<_>>()[..] {
        return format!("{total} detection boxes ({})", r.describe());
    }
    let parts: Vec<String> = (skipped.iter())
        .map(|(r, n)| format!("{n} ({})", r.describe()))
        .collect();
    format!("{total} detection boxes: {}", parts.join(", "))
}

/// The stamp rule of every reader: a message's own stamp, else the MCAP record's log_time.
pub fn stamp_or_log_time(stamp: Option<u64>, log_time: u64) -> u64 {
    stamp.unwrap_or(log_time)
}

/// Checks one decoded box: `Err` names the first failed check (missing field, non-finite,
/// non-positive size, centre and size beyond their bounds, velocity, in that order).
pub fn check_box(d: &Detection3D) -> Result<Box3, SkipReason> {
    let xyz = |v: &super::Vector3| [v.x, v.y, v.z];
    let size = d.size.as_ref().map(|s| [s.length, s.width, s.height]);
    let velocity = d.velocity.as_ref().map(xyz);
    check_parts(d.center.as_ref().map(xyz), size, d.yaw, d.score, velocity)
}

/// [`check_box`] on the fields of a box: centre, size `[l, w, h]`, yaw, score and velocity.
pub fn check_parts(
    center: Option<[f64; 3]>,
    size: Option<[f64; 3]>,
    yaw: f64,
    score: f64,
    velocity: Option<[f64; 3]>,
) -> Result<Box3, SkipReason> {
    let (Some(center), Some(size)) = (center, size) else {
        return Err(SkipReason::MissingField);
    };
    let bbox = Box3 { center, yaw, size };
    let finite = bbox.center.iter().chain(&bbox.size).all(|v| v.is_finite())
        && bbox.yaw.is_finite()
        && score.is_finite();
    if !finite {
        return Err(SkipReason::NonFinite);
    }
    if bbox.size.iter().any(|v| *v <= 0.0) {
        return Err(SkipReason::NonPositiveSize);
    }
    if bbox.center.iter().any(|v| v.abs() > bounds::MAX_COORDINATE) {
        return Err(SkipReason::CentreBeyondBound);
    }
    if bbox.size.iter().any(|v| *v > bounds::MAX_SIZE) {
        return Err(SkipReason::SizeBeyondBound);
    }
    if let Some(v) = velocity {
        if !v.iter().all(|c| c.is_finite()) {
            return Err(SkipReason::NonFiniteVelocity);
        }
        if v.iter().any(|c| c.abs() > bounds::MAX_SPEED) {
            return Err(SkipReason::VelocityBeyondBound);
        }
    }
    Ok(bbox)
}

impl DetectionFrame {
    /// Checks and converts a decoded message (moving its strings and attributes).
    pub fn from_message(msg: Detections3D, log_time: u64) -> DetectionFrame {
        let mut frame = DetectionFrame {
            stamp: stamp_or_log_time(msg.stamp, log_time),
            frame_id: msg.frame_id,
            boxes: Vec::with_capacity(msg.detections.len()),
            rejected: Vec::new(),
        };
        for (i, d) in msg.detections.into_iter().enumerate() {
            let index = i as u32;
            match check_box(&d) {
                Ok(bbox) => frame.boxes.push(DetectionBox {
                    index,
                    bbox,
                    label: d.label,
                    score: d.score,
                    velocity: d.velocity.map(|v| [v.x, v.y, v.z]),
                    image_box: d.image_box,
                    attributes: d.attributes,
                    needs_own_entry: false,
                }),
                Err(reason) => frame.rejected.push(Rejected {
                    index,
                    label: d.label,
                    reason,
                }),
            }
        }
        frame
    }

    /// Moves the boxes at the indices of `rejects` (`(index, reason)`, ascending message order)
    /// to the rejected ones, each for its reason: one pass with a binary search, so a message
    /// of many such boxes costs no more than a sort.
    pub fn reject(&mut self, rejects: &[(u32, SkipReason)]) {
        if rejects.is_empty() {
            return;
        }
        let reason_of = |index: u32| {
            rejects
                .binary_search_by_key(&index, |r| r.0)
                .ok()
                .map(|k| rejects[k].1)
        };
        let mut kept = Vec::with_capacity(self.boxes.len());
        for b in std::mem::take(&mut self.boxes) {
            match reason_of(b.index) {
                Some(reason) => self.rejected.push(Rejected {
                    index: b.index,
                    label: b.label,
                    reason,
                }),
                None => kept.push(b),
            }
        }
        self.boxes = kept;
        self.rejected.sort_by_key(|r| r.index);
    }

    /// Number of boxes in the message, valid or not.
    pub fn len(&self) -> usize {
        self.boxes.len() + self.rejected.len()
    }

    /// True when the message held no box.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Drops every box, valid or not.
    pub fn clear(&mut self) {
        self.boxes.clear();
        self.rejected.clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msgs::{v3, Size3};

    fn det(center: Option<[f64; 3]>, size: [f64; 3], score: f64) -> Detection3D {
        Detection3D {
            center: center.map(v3),
            size: Some(Size3 {
                length: size[0],
                width: size[1],
                height: size[2],
            }),
            yaw: 0.5,
            label: "car".into(),
            score,
            velocity: Some(v3([1.0, 2.0, 0.0])),
            ..Default::default()
        }
    }

    #[test]
    fn boxes_are_checked_once_in_message_order() {
        let msg = Detections3D {
            stamp: None,
            frame_id: "map".into(),
            detections: vec![
                det(Some([1.0, 2.0, 3.0]), [4.0, 2.0, 1.5], 0.9),
                det(None, [4.0, 2.0, 1.5], 0.9),
                det(Some([f64::NAN, 0.0, 0.0]), [4.0, 2.0, 1.5], 0.9),
                det(Some([0.0, 0.0, 0.0]), [4.0, 0.0, 1.5], 0.9),
                det(Some([0.0, 0.0, 0.0]), [4.0, 2.0, 1.5], f64::INFINITY),
                det(Some([5.0, 6.0, 7.0]), [1.0, 1.0, 1.0], 1.7),
                det(Some([1e308, 0.0, 0.0]), [4.0, 2.0, 1.5], 0.9),
                det(Some([0.0, -2e7, 0.0]), [4.0, 2.0, 1.5], 0.9),
                det(Some([0.0, 0.0, 0.0]), [4.0, 2e4, 1.5], 0.9),
                Detection3D {
                    velocity: Some(v3([f64::NAN, 0.0, 0.0])),
                    ..det(Some([0.0, 0.0, 0.0]), [4.0, 2.0, 1.5], 0.9)
                },
                Detection3D {
                    velocity: Some(v3([0.0, 0.0, -1e6])),
                    ..det(Some([0.0, 0.0, 0.0]), [4.0, 2.0, 1.5], 0.9)
                },
                det(Some([6.3e6, -9e6, 1e3]), [1e4, 1.0, 1.0], 0.5),
            ],
        };
        let f = DetectionFrame::from_message(msg, 42);
        assert_eq!(f.stamp, 42, "no stamp: the log_time");
        assert_eq!(f.len(), 12);
        let valid: Vec<u32> = f.boxes.iter().map(|b| b.index).collect();
        assert_eq!(
            valid,
            [0, 5, 11],
            "Earth-centred coordinates are within the bounds"
        );
        assert_eq!(f.boxes[0].bbox.center, [1.0, 2.0, 3.0]);
        assert_eq!(f.boxes[0].bbox.size, [4.0, 2.0, 1.5]);
        assert_eq!(f.boxes[0].velocity, Some([1.0, 2.0, 0.0]));
        assert_eq!(f.boxes[1].score, 1.7, "scores outside [0, 1] are kept");
        let reasons: Vec<(u32, SkipReason)> =
            f.rejected.iter().map(|r| (r.index, r.reason)).collect();
        assert_eq!(
            reasons,
            [
                (1, SkipReason::MissingField),
                (2, SkipReason::NonFinite),
                (3, SkipReason::NonPositiveSize),
                (4, SkipReason::NonFinite),
                (6, SkipReason::CentreBeyondBound),
                (7, SkipReason::CentreBeyondBound),
                (8, SkipReason::SizeBeyondBound),
                (9, SkipReason::NonFiniteVelocity),
                (10, SkipReason::VelocityBeyondBound),
            ]
        );
    }

    /// Rejected boxes leave the valid ones with their own reasons, merged in message order with
    /// those the checks rejected; indices of boxes already rejected are left alone.
    #[test]
    fn reject_moves_the_given_boxes_with_their_reasons() {
        let ok = || det(Some([1.0, 2.0, 3.0]), [4.0, 2.0, 1.5], 0.9);
        let msg = Detections3D {
            detections: vec![ok(), det(None, [1.0; 3], 0.9), ok(), ok(), ok()],
            ..Default::default()
        };
        let mut f = DetectionFrame::from_message(msg, 42);
        f.reject(&[
            (1, SkipReason::LabelNotUtf8),
            (2, SkipReason::IdNotUtf8),
            (4, SkipReason::LabelNotUtf8),
        ]);
        let valid: Vec<u32> = f.boxes.iter().map(|b| b.index).collect();
        assert_eq!(valid, [0, 3]);
        let reasons: Vec<(u32, SkipReason)> =
            f.rejected.iter().map(|r| (r.index, r.reason)).collect();
        assert_eq!(
            reasons,
            [
                (1, SkipReason::MissingField),
                (2, SkipReason::IdNotUtf8),
                (4, SkipReason::LabelNotUtf8),
            ]
        );
    }

    #[test]
    fn own_stamp_wins_over_log_time() {
        let msg = Detections3D {
            stamp: Some(7),
            ..Default::default()
        };
        assert_eq!(DetectionFrame::from_message(msg, 42).stamp, 7);
        assert_eq!(stamp_or_log_time(Some(0), 42), 0, "a zero stamp is a stamp");
    }
}
