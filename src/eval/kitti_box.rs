//! The fields of a box that the KITTI evaluation (and TrackEval's KITTI HOTA) reads
//! ([`KittiFields`]), from a whole [`LabelledBox`] or from a [`KittiBox`]: those fields alone,
//! parsed once while a log streams, so that `eval --protocol kitti` holds about 170 bytes per
//! box instead of a box with its label and attribute map (several hundred; a long log has
//! millions).

use std::borrow::Cow;
use std::collections::HashMap;
use std::sync::Arc;

use crate::mcapio::LabelledBox;
use crate::pipeline::kitti_io::attr::{
    OCCLUDED as ATTR_OCCLUDED, TRUNCATED as ATTR_TRUNCATED, TYPE as ATTR_TYPE,
};
use crate::pipeline::kitti_io::{number_attr, truth_track_id};
use crate::tracker::Box3;

/// What the KITTI evaluation reads of a box.
pub trait KittiFields {
    /// Track or instance id of the message (0 when it has none).
    fn id(&self) -> u64;
    /// Class label of the message.
    fn label(&self) -> &str;
    /// The lower-cased KITTI type: the `kitti_type` attribute, else the label.
    fn kitti_type(&self) -> Cow<'_, str>;
    /// The KITTI track id of a ground-truth box: the `kitti_track_id` attribute, else id - 1.
    fn truth_track_id(&self) -> i64;
    /// Truncation level (`kitti_truncated`, as Python's `int(float(s))`; 0 when absent).
    fn truncated(&self) -> i64;
    /// Occlusion level (`kitti_occluded`, likewise).
    fn occluded(&self) -> i64;
    /// The 3D box.
    fn box3(&self) -> Box3;
    /// Score.
    fn score(&self) -> f64;
    /// 2D box `x1 y1 x2 y2` in the image, if known.
    fn image_box(&self) -> Option<[f64; 4]>;
}

/// A numeric attribute truncated to an integer like Python's `int(float(s))`; 0 when absent or
/// not a number.
fn int_attr(b: &LabelledBox, key: &str) -> i64 {
    number_attr(&b.attributes, key).map_or(0, |v| v.trunc() as i64)
}

impl KittiFields for LabelledBox {
    fn id(&self) -> u64 {
        self.id
    }

    fn label(&self) -> &str {
        &self.label
    }

    fn kitti_type(&self) -> Cow<'_, str> {
        Cow::Owned(
            self.attributes
                .get(ATTR_TYPE)
                .unwrap_or(&self.label)
                .to_lowercase(),
        )
    }

    fn truth_track_id(&self) -> i64 {
        truth_track_id(self)
    }

    fn truncated(&self) -> i64 {
        int_attr(self, ATTR_TRUNCATED)
    }

    fn occluded(&self) -> i64 {
        int_attr(self, ATTR_OCCLUDED)
    }

    fn box3(&self) -> Box3 {
        Box3 {
            center: self.center,
            yaw: self.yaw,
            size: self.size,
        }
    }

    fn score(&self) -> f64 {
        self.score
    }

    fn image_box(&self) -> Option<[f64; 4]> {
        self.image_box
    }
}

/// A box's label and lower-cased KITTI type, one copy shared by the boxes of a log that have
/// both (a pointer in each box instead of two strings).
#[derive(Debug, PartialEq, Eq)]
pub struct KittiNames {
    /// Label of the message.
    pub label: Box<str>,
    /// Lower-cased KITTI type: the `kitti_type` attribute, else the label.
    pub kitti_type: Box<str>,
}

impl KittiNames {
    /// Names not shared with any other box (tests, single boxes).
    pub fn new(label: &str, kitti_type: &str) -> Arc<KittiNames> {
        Arc::new(KittiNames {
            label: label.into(),
            kitti_type: kitti_type.into(),
        })
    }
}

/// A box as the KITTI evaluation reads it, its fields parsed once ([`KittiBoxes::read`]): 136
/// bytes, where a whole box with its label and attribute map takes several hundred.
#[derive(Debug, Clone, PartialEq)]
pub struct KittiBox {
    /// Track or instance id of the message.
    pub id: u64,
    /// Label and KITTI type (shared by the boxes of a log with the same two).
    pub names: Arc<KittiNames>,
    /// KITTI track id of a ground-truth box.
    pub truth_track_id: i64,
    /// Truncation level, saturated to `i32` (the evaluation only compares it with 0 to 2).
    pub truncated: i32,
    /// Occlusion level, likewise.
    pub occluded: i32,
    /// The 3D box.
    pub box3: Box3,
    /// Score.
    pub score: f64,
    /// 2D box in the image.
    pub image_box: Option<[f64; 4]>,
}

impl KittiBox {
    /// Label of the message.
    pub fn label(&self) -> &str {
        &self.names.label
    }
}

impl KittiFields for KittiBox {
    fn id(&self) -> u64 {
        self.id
    }

    fn label(&self) -> &str {
        &self.names.label
    }

    fn kitti_type(&self) -> Cow<'_, str> {
        Cow::Borrowed(&self.names.kitti_type)
    }

    fn truth_track_id(&self) -> i64 {
        self.truth_track_id
    }

    fn truncated(&self) -> i64 {
        self.truncated.into()
    }

    fn occluded(&self) -> i64 {
        self.occluded.into()
    }

    fn box3(&self) -> Box3 {
        self.box3
    }

    fn score(&self) -> f64 {
        self.score
    }

    fn image_box(&self) -> Option<[f64; 4]> {
        self.image_box
    }
}

impl From<&LabelledBox> for KittiBox {
    /// The KITTI fields of one box, its strings not shared (see [`KittiBoxes`] for a log).
    fn from(b: &LabelledBox) -> KittiBox {
        KittiBoxes::default().read(b)
    }
}

/// Makes [`KittiBox`]es of one log, sharing each distinct pair of label and type (and, for
/// other users, each distinct string: [`KittiBoxes::shared`]).
#[derive(Debug, Default)]
pub struct KittiBoxes {
    /// By label, then by KITTI type.
    names: HashMap<String, HashMap<String, Arc<KittiNames>>>,
    strings: HashMap<String, Arc<str>>,
}

/// `v` saturated to `i32`: the same answer to every comparison with a small number.
fn saturate(v: i64) -> i32 {
    v.clamp(i32::MIN.into(), i32::MAX.into()) as i32
}

impl KittiBoxes {
    /// The KITTI fields of `b`.
    pub fn read(&mut self, b: &LabelledBox) -> KittiBox {
        KittiBox {
            id: b.id,
            names: self.names(&b.label, &b.kitti_type()),
            truth_track_id: b.truth_track_id(),
            truncated: saturate(b.truncated()),
            occluded: saturate(b.occluded()),
            box3: b.box3(),
            score: b.score,
            image_box: b.image_box,
        }
    }

    /// The shared names of a label and type.
    fn names(&mut self, label: &str, kitti_type: &str) -> Arc<KittiNames> {
        if let Some(n) = self
            .names
            .get(label)
            .and_then(|by_type| by_type.get(kitti_type))
        {
            return n.clone();
        }
        let n = KittiNames::new(label, kitti_type);
        let by_type = self.names.entry(label.to_string()).or_default();
        by_type.insert(kitti_type.to_string(), n.clone());
        n
    }

    /// The shared copy of `s` (a label, say): one allocation per distinct string of the log.
    pub fn shared(&mut self, s: &str) -> Arc<str> {
        if let Some(a) = self.strings.get(s) {
            return a.clone();
        }
        let a: Arc<str> = Arc::from(s);
        self.strings.insert(s.to_string(), a.clone());
        a
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_kitti_box_reads_as_the_labelled_box_it_was_made_of() {
        let attributes = [
            (ATTR_TYPE, "Person_sitting"),
            (ATTR_TRUNCATED, "1.0"),
            (ATTR_OCCLUDED, " 2 "),
            (crate::pipeline::kitti_io::attr::TRACK_ID, "7"),
        ];
        let with = LabelledBox {
            id: 8,
            label: "pedestrian".into(),
            center: [1.0, 2.0, 3.0],
            size: [0.8, 0.6, 1.2],
            yaw: 0.5,
            score: 0.25,
            attributes: attributes
                .iter()
                .map(|(k, v)| (k.to_string(), v.to_string()))
                .collect(),
            image_box: Some([1.0, 2.0, 30.0, 40.0]),
            ..Default::default()
        };
        let without = LabelledBox {
            id: 3,
            label: "Car".into(),
            ..Default::default()
        };
        let mut boxes = KittiBoxes::default();
        for b in [&with, &without] {
            let k = boxes.read(b);
            assert_eq!(k.id(), b.id());
            assert_eq!(k.label(), b.label());
            assert_eq!(k.kitti_type(), b.kitti_type());
            assert_eq!(k.truth_track_id(), b.truth_track_id());
            assert_eq!((k.truncated(), k.occluded()), (b.truncated(), b.occluded()));
            assert_eq!(k.box3(), b.box3());
            assert_eq!((k.score(), k.image_box()), (b.score(), b.image_box()));
        }
        let k = boxes.read(&with);
        assert_eq!(&*k.names.kitti_type, "person_sitting");
        assert_eq!((k.truncated, k.occluded, k.truth_track_id), (1, 2, 7));
        assert_eq!(
            boxes.read(&without).truth_track_id,
            2,
            "no attribute: id - 1"
        );
        assert_eq!(&*boxes.read(&without).names.kitti_type, "car");
        // One copy per distinct label and type.
        assert!(Arc::ptr_eq(&boxes.read(&with).names, &k.names));
        assert!(!Arc::ptr_eq(&boxes.read(&without).names, &k.names));
        // Levels beyond i32 compare as they did: above the thresholds.
        let huge = LabelledBox {
            attributes: [(ATTR_TRUNCATED.to_string(), "1e12".to_string())].into(),
            ..without.clone()
        };
        assert_eq!(huge.truncated(), 1_000_000_000_000);
        assert_eq!(boxes.read(&huge).truncated, i32::MAX);
        assert_eq!(std::mem::size_of::<KittiBox>(), 136);
    }
}
