//! The one box type of everything that reads boxes back out of a recording (eval, fit, plot,
//! viz, tune): a 3D box with its label, id, score and what the metrics and pictures need, built
//! from a decoded track or detection. The tracker has its own typed state; this is the plain
//! record the readers hand on.

use std::collections::BTreeMap;

use crate::msgs::{Detection3D, Track3D};

/// One labelled 3D box: a track, a ground-truth instance or a detection.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LabelledBox {
    /// Track or instance id; 0 for detections, which have none (and for KITTI's DontCare
    /// regions).
    pub id: u64,
    /// Class label.
    pub label: String,
    /// Centre, metres.
    pub center: [f64; 3],
    /// Length (along the heading), width, height, metres.
    pub size: [f64; 3],
    /// Heading about +z, radians; 0 points along +x.
    pub yaw: f64,
    /// Track or detection score (ground truth: what its message says, usually 1).
    pub score: f64,
    /// Velocity, m/s (zero when the message has none).
    pub velocity: [f64; 3],
    /// Attributes the message carries (KITTI and nuScenes fields), as far as the reader kept
    /// them ([`LabelledBox::keep_attributes`]).
    pub attributes: BTreeMap<String, String>,
    /// 2D box in the image `[x1, y1, x2, y2]`, if known.
    pub image_box: Option<[f64; 4]>,
}

impl LabelledBox {
    /// A track (or ground-truth instance) as a box; a missing centre, size or velocity reads
    /// as zeros.
    pub fn from_track(t: Track3D) -> LabelledBox {
        let c = t.center.unwrap_or_default();
        let s = t.size.unwrap_or_default();
        let v = t.velocity.unwrap_or_default();
        LabelledBox {
            id: t.id,
            label: t.label,
            center: [c.x, c.y, c.z],
            size: [s.length, s.width, s.height],
            yaw: t.yaw,
            score: t.score,
            velocity: [v.x, v.y, v.z],
            attributes: t.attributes,
            image_box: t.image_box.map(|b| [b.x1, b.y1, b.x2, b.y2]),
        }
    }

    /// A detection as a box with id 0; a missing centre, size or velocity reads as zeros
    /// ([`LabelledBox::has_geometry`] tells whether they were there).
    pub fn from_detection(d: Detection3D) -> LabelledBox {
        let c = d.center.unwrap_or_default();
        let s = d.size.unwrap_or_default();
        let v = d.velocity.unwrap_or_default();
        LabelledBox {
            id: 0,
            label: d.label,
            center: [c.x, c.y, c.z],
            size: [s.length, s.width, s.height],
            yaw: d.yaw,
            score: d.score,
            velocity: [v.x, v.y, v.z],
            attributes: d.attributes,
            image_box: d.image_box.map(|b| [b.x1, b.y1, b.x2, b.y2]),
        }
    }

    /// Whether a detection carries both a centre and a size (a box without them is no
    /// measurement).
    pub fn has_geometry(d: &Detection3D) -> bool {
        d.center.is_some() && d.size.is_some()
    }

    /// Keeps only the attributes whose key `keep` accepts: a map per box is most of a long
    /// log's memory when nothing reads it.
    pub fn keep_attributes(mut self, keep: impl Fn(&str) -> bool) -> LabelledBox {
        if self.attributes.keys().any(|k| !keep(k)) {
            self.attributes = std::mem::take(&mut self.attributes)
                .into_iter()
                .filter(|(k, _)| keep(k))
                .collect();
        }
        self
    }

    /// The seven measured values `x y z yaw l w h`, in the tracker's measurement order.
    pub fn measurement(&self) -> [f64; 7] {
        let (c, s) = (self.center, self.size);
        [c[0], c[1], c[2], self.yaw, s[0], s[1], s[2]]
    }

    /// Whether every measured value is finite.
    pub fn is_finite(&self) -> bool {
        self.measurement().iter().all(|v| v.is_finite())
    }

    /// The four corners of the box seen from above, counter-clockwise: front-left, rear-left,
    /// rear-right, front-right.
    pub fn bev_corners(&self) -> [(f64, f64); 4] {
        let (s, c) = self.yaw.sin_cos();
        let (hl, hw) = (self.size[0] / 2.0, self.size[1] / 2.0);
        let at = |l: f64, w: f64| {
            (
                self.center[0] + l * c - w * s,
                self.center[1] + l * s + w * c,
            )
        };
        [at(hl, hw), at(-hl, hw), at(-hl, -hw), at(hl, -hw)]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msgs::{Size3, Vector3};

    #[test]
    fn a_track_keeps_every_field_and_missing_geometry_reads_as_zero() {
        let t = Track3D {
            id: 7,
            label: "car".into(),
            center: Some(Vector3 {
                x: 1.0,
                y: 2.0,
                z: 3.0,
            }),
            velocity: Some(Vector3 {
                x: 4.0,
                y: 0.0,
                z: 0.0,
            }),
            yaw: 0.5,
            score: 0.9,
            attributes: [("kitti_occluded".to_string(), "1".to_string())].into(),
            ..Default::default()
        };
        let b = LabelledBox::from_track(t);
        assert_eq!((b.id, b.label.as_str()), (7, "car"));
        assert_eq!(b.measurement(), [1.0, 2.0, 3.0, 0.5, 0.0, 0.0, 0.0]);
        assert_eq!((b.score, b.velocity), (0.9, [4.0, 0.0, 0.0]));
        assert_eq!(b.attributes["kitti_occluded"], "1");
        assert!(b.image_box.is_none());
    }

    #[test]
    fn a_detection_has_id_zero_and_geometry_is_checked_before() {
        let d = Detection3D {
            label: "pedestrian".into(),
            center: Some(Vector3 {
                x: 1.0,
                y: 0.0,
                z: 0.0,
            }),
            ..Default::default()
        };
        assert!(!LabelledBox::has_geometry(&d));
        let d = Detection3D {
            size: Some(Size3 {
                length: 2.0,
                width: 1.0,
                height: 1.5,
            }),
            ..d
        };
        assert!(LabelledBox::has_geometry(&d));
        let b = LabelledBox::from_detection(d);
        assert_eq!((b.id, b.size), (0, [2.0, 1.0, 1.5]));
    }

    #[test]
    fn keep_attributes_drops_what_is_not_asked_for() {
        let b = LabelledBox {
            attributes: [("kitti_a", "1"), ("sim_truth_id", "3")]
                .map(|(k, v)| (k.to_string(), v.to_string()))
                .into(),
            ..Default::default()
        };
        let b = b.keep_attributes(|k| k.starts_with("kitti_"));
        assert_eq!(b.attributes.keys().collect::<Vec<_>>(), ["kitti_a"]);
    }

    #[test]
    fn bev_corners_turn_with_the_heading() {
        let b = LabelledBox {
            size: [4.0, 2.0, 1.5],
            yaw: std::f64::consts::FRAC_PI_2,
            ..Default::default()
        };
        let [fl, ..] = b.bev_corners();
        assert!((fl.0 + 1.0).abs() < 1e-12 && (fl.1 - 2.0).abs() < 1e-12);
    }
}
