//! HOTA on KITTI tracking data as TrackEval's `Kitti2DBox` dataset prepares it
//! (`trackeval/datasets/kitti_2d_box.py`, 1.3.0):
//! - classes `car` and `pedestrian` only; `van` and `person_sitting` ground truth are
//!   distractors of them, and so is ground truth with occlusion > 2 or truncation > 0;
//! - per frame, tracks of the class are matched to truth of the class or its distractors by an
//!   optimal assignment on the 2D IoU (pairs under 0.5 do not match); tracks matched to a
//!   distractor are removed, and so are unmatched tracks at most 25 px high or more than 50 %
//!   inside a DontCare region; then the distractors leave the truth;
//! - 2D IoU with TrackEval's conventions: continuous pixel coordinates (no +1), a box with area
//!   <= eps overlaps nothing.
//!
//! The 3D variant keeps exactly that selection of boxes (it is made on the image boxes) and
//! scores the remaining pairs by their 3D IoU instead of the 2D IoU.

use std::collections::BTreeMap;

use super::{eval_scenes_by, Evaluation, Hota, RawFrame, Whole, EPS};
use crate::eval::kitti_box::KittiFields;
use crate::eval::scene::Scene;
use crate::tracker::geometry::iou3d;

/// Similarity of the HOTA matching.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum KittiSimilarity {
    /// 2D IoU of the image boxes (the KITTI benchmark's HOTA).
    Image,
    /// 3D IoU of the boxes.
    Box3d,
}

/// Classes `Kitti2DBox` can evaluate.
pub const KITTI_HOTA_CLASSES: [&str; 2] = ["car", "pedestrian"];

const MAX_OCCLUSION: i64 = 2;
const MAX_TRUNCATION: i64 = 0;
const MIN_HEIGHT: f64 = 25.0;

/// TrackEval's class ids (`class_name_to_class_id`; `person` is the sitting person).
fn class_id(kind: &str) -> Option<u8> {
    Some(match kind {
        "car" | "car_2" => 1,
        "van" => 2,
        "truck" => 3,
        "pedestrian" => 4,
        "person" | "person_sitting" => 5,
        "cyclist" => 6,
        "tram" => 7,
        "misc" => 8,
        _ => return None,
    })
}

/// 2D IoU of `x1 y1 x2 y2` boxes as TrackEval's `_calculate_box_ious`.
pub fn iou2d(a: &[f64; 4], b: &[f64; 4]) -> f64 {
    let inter =
        (a[2].min(b[2]) - a[0].max(b[0])).max(0.0) * (a[3].min(b[3]) - a[1].max(b[1])).max(0.0);
    let area1 = (a[2] - a[0]) * (a[3] - a[1]);
    let area2 = (b[2] - b[0]) * (b[3] - b[1]);
    let union = area1 + area2 - inter;
    if area1 <= EPS || area2 <= EPS || union <= EPS {
        return 0.0;
    }
    inter / union
}

/// Share of `a`'s area inside `b` (TrackEval's `do_ioa`); 0 for a box with area <= eps.
fn ioa(a: &[f64; 4], b: &[f64; 4]) -> f64 {
    let inter =
        (a[2].min(b[2]) - a[0].max(b[0])).max(0.0) * (a[3].min(b[3]) - a[1].max(b[1])).max(0.0);
    let area1 = (a[2] - a[0]) * (a[3] - a[1]);
    if area1 > EPS {
        inter / area1
    } else {
        0.0
    }
}

/// A truth box of the class or a distractor.
struct Gt<'a, B> {
    id: i64,
    class: u8,
    occlusion: i64,
    truncation: i64,
    b: &'a B,
}

fn prepare_frame<B: KittiFields>(
    truth: &[B],
    tracks: &[B],
    cls: u8,
    distractor: u8,
    sim: KittiSimilarity,
) -> RawFrame {
    let mut dontcare = Vec::new();
    let mut gt = Vec::new();
    for b in truth {
        let k = b.kitti_type();
        if k == "dontcare" {
            dontcare.push(b.image_box().unwrap_or([0.0; 4]));
            continue;
        }
        let id = b.truth_track_id();
        match class_id(&k) {
            Some(c) if id >= 0 && (c == cls || c == distractor) => gt.push(Gt {
                id,
                class: c,
                occlusion: b.occluded(),
                truncation: b.truncated(),
                b,
            }),
            _ => {}
        }
    }
    let tr: Vec<&B> = tracks
        .iter()
        .filter(|b| class_id(&b.kitti_type()) == Some(cls))
        .collect();
    let img = |b: &B| b.image_box().unwrap_or([0.0; 4]);
    let (ng, nt) = (gt.len(), tr.len());
    let iou: Vec<f64> = gt
        .iter()
        .flat_map(|g| tr.iter().map(|t| iou2d(&img(g.b), &img(t))))
        .collect();

    // Tracks matched (2D IoU >= 0.5) to a distractor leave; so do small or DontCare unmatched ones.
    let mut remove = vec![false; nt];
    let mut matched = vec![false; nt];
    if ng > 0 && nt > 0 {
        let cost: Vec<f64> = iou
            .iter()
            .map(|&s| if s < 0.5 - EPS { -0.0 } else { -s })
            .collect();
        let (rows, cols) = lsap::solve(ng, nt, &cost, false).expect("finite IoU matrix");
        for (i, j) in rows.into_iter().zip(cols) {
            if -cost[i * nt + j] > EPS {
                matched[j] = true;
                let g = &gt[i];
                remove[j] = g.class == distractor
                    || g.occlusion > MAX_OCCLUSION
                    || g.truncation > MAX_TRUNCATION;
            }
        }
    }
    for (j, t) in tr.iter().enumerate() {
        if !matched[j] {
            let b = img(t);
            let small = b[3] - b[1] <= MIN_HEIGHT + EPS;
            remove[j] = small || dontcare.iter().any(|d| ioa(&b, d) > 0.5 + EPS);
        }
    }
    let keep_gt: Vec<usize> = (0..ng)
        .filter(|&i| {
            let g = &gt[i];
            g.occlusion <= MAX_OCCLUSION && g.truncation <= MAX_TRUNCATION && g.class == cls
        })
        .collect();
    let keep_tr: Vec<usize> = (0..nt).filter(|&j| !remove[j]).collect();
    let mut s = Vec::with_capacity(keep_gt.len() * keep_tr.len());
    for &i in &keep_gt {
        for &j in &keep_tr {
            s.push(match sim {
                KittiSimilarity::Image => iou[i * nt + j],
                KittiSimilarity::Box3d => iou3d(&gt[i].b.box3(), &tr[j].box3()),
            });
        }
    }
    (
        keep_gt.iter().map(|&i| gt[i].id).collect(),
        keep_tr.iter().map(|&j| tr[j].id() as i64).collect(),
        super::sparse(&s),
    )
}

/// HOTA per class (of `classes`, those `Kitti2DBox` knows: car, pedestrian), each scene one
/// sequence. Returns the results and notes (classes left out, data TrackEval would refuse).
pub fn kitti_hota<B: KittiFields + Sync>(
    scenes: &[Scene<B>],
    classes: &[String],
    sim: KittiSimilarity,
) -> (BTreeMap<String, Hota>, Vec<String>) {
    kitti_hota_by(scenes, classes, sim, &Whole)
}

/// [`kitti_hota`] with each class evaluated by `how`.
pub fn kitti_hota_by<B: KittiFields + Sync, E: Evaluation>(
    scenes: &[Scene<B>],
    classes: &[String],
    sim: KittiSimilarity,
    how: &E,
) -> (BTreeMap<String, E::Class>, Vec<String>) {
    let mut out = BTreeMap::new();
    let mut notes = Vec::new();
    for c in classes {
        let c = c.to_lowercase();
        let (cls, distractor) = match c.as_str() {
            "car" => (1, 2),
            "pedestrian" => (4, 5),
            _ => {
                notes.push(format!(
                    "HOTA: class {c} is not evaluated (TrackEval's Kitti2DBox evaluates car and \
                     pedestrian only)"
                ));
                continue;
            }
        };
        if let Some(missing) = without_image_boxes(scenes, cls) {
            notes.push(format!(
                "HOTA: class {c} is not evaluated: {missing}, which Kitti2DBox matches and \
                 selects by (`probmot import kitti` keeps the label file's; a track carries its \
                 detection's)"
            ));
            continue;
        }
        let frames = |scene: &Scene<B>| {
            (scene.frames.iter())
                .map(|(_, g, t)| prepare_frame(g, t, cls, distractor, sim))
                .collect()
        };
        match eval_scenes_by(scenes, frames, how) {
            Ok((seqs, _)) => {
                out.insert(c, how.class(seqs));
            }
            Err(e) => notes.push(format!(
                "HOTA: class {c} is not evaluated: {e} (TrackEval refuses such data)"
            )),
        }
    }
    (out, notes)
}

/// Which side of class `cls` has boxes without a 2D image box, and how many of how many (e.g.
/// "tracks: 3 of 120"): with all of them missing its HOTA would be 0 by construction, and with
/// some, those would be matched and selected as empty boxes, not by the tracks' quality.
fn without_image_boxes<B: KittiFields>(scenes: &[Scene<B>], cls: u8) -> Option<String> {
    let of_class = |b: &&B| class_id(&b.kitti_type()) == Some(cls);
    // Boxes of the class on one side (`truth` or the tracks): (without an image box, all).
    let count = |truth: bool| {
        (scenes.iter())
            .flat_map(|s| s.frames.iter())
            .flat_map(|f| if truth { &f.1 } else { &f.2 })
            .filter(of_class)
            .fold((0u64, 0u64), |(n, all), b| {
                (n + u64::from(b.image_box().is_none()), all + 1)
            })
    };
    [(true, "ground-truth boxes"), (false, "tracks")]
        .into_iter()
        .find_map(|(truth, side)| match count(truth) {
            (0, _) => None,
            (n, all) if n == all => Some(format!("its {side} have no 2D image boxes")),
            (n, all) => Some(format!("{n} of its {all} {side} have no 2D image box")),
        })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mcapio::LabelledBox;

    fn b(id: u64, kind: &str, img: [f64; 4], occluded: u8, truncated: u8) -> LabelledBox {
        let attributes = [
            ("kitti_type", kind.to_string()),
            ("kitti_occluded", occluded.to_string()),
            ("kitti_truncated", truncated.to_string()),
        ]
        .into_iter()
        .map(|(k, v)| (k.to_string(), v))
        .collect();
        LabelledBox {
            id,
            label: kind.to_lowercase(),
            center: [10.0 * id as f64, 0.0, 0.0],
            size: [4.0, 2.0, 1.5],
            score: 1.0,
            attributes,
            image_box: Some(img),
            ..Default::default()
        }
    }

    #[test]
    fn iou_without_the_plus_one() {
        assert!(
            (iou2d(&[0.0, 0.0, 10.0, 10.0], &[5.0, 0.0, 15.0, 10.0]) - 1.0 / 3.0).abs() < 1e-15
        );
        assert_eq!(iou2d(&[0.0, 0.0, 0.0, 10.0], &[0.0, 0.0, 0.0, 10.0]), 0.0);
    }

    /// Kitti2DBox's rules, one box each: a track on a van (distractor) leaves, a track on a
    /// heavily occluded car leaves, an unmatched 25 px track leaves, an unmatched track 60 %
    /// inside a DontCare region leaves; a 26 px unmatched track and a track on a visible car
    /// stay. The van and the occluded car leave the truth.
    #[test]
    fn kitti2dbox_removes_what_trackeval_removes() {
        let truth = vec![
            b(1, "Car", [0.0, 0.0, 100.0, 100.0], 0, 0),
            b(2, "Van", [200.0, 0.0, 300.0, 100.0], 0, 0),
            b(3, "Car", [400.0, 0.0, 500.0, 100.0], 3, 0),
            b(0, "DontCare", [600.0, 0.0, 700.0, 100.0], 0, 0),
        ];
        let tracks = vec![
            b(11, "Car", [0.0, 0.0, 100.0, 90.0], 0, 0), // on car 1: stays
            b(12, "Car", [200.0, 0.0, 300.0, 90.0], 0, 0), // on the van: leaves
            b(13, "Car", [400.0, 0.0, 500.0, 90.0], 0, 0), // on occluded car 3: leaves
            b(14, "Car", [800.0, 0.0, 900.0, 25.0], 0, 0), // 25 px: leaves
            b(15, "Car", [800.0, 50.0, 900.0, 76.0], 0, 0), // 26 px: stays
            b(16, "Car", [640.0, 0.0, 740.0, 100.0], 0, 0), // 60 % in DontCare: leaves
            b(17, "Pedestrian", [0.0, 0.0, 100.0, 100.0], 0, 0), // other class
        ];
        let (g, t, s) = prepare_frame(&truth, &tracks, 1, 2, KittiSimilarity::Image);
        assert_eq!(g, vec![0]); // car 1 (KITTI id = id - 1)
        assert_eq!(t, vec![11, 15]);
        // Only the nonzero similarity is kept: (car 1, track 11); track 15 overlaps nothing.
        assert_eq!(s.len(), 1);
        assert!(s[0].0 == 0 && (s[0].1 - 0.9).abs() < 1e-12);
    }

    /// A class whose truth (or tracks) carry no image box at all is left out with a note,
    /// instead of a row of zeros; a class with image boxes on both sides is evaluated.
    #[test]
    fn a_class_without_image_boxes_is_not_evaluated() {
        let no_image = |mut x: LabelledBox| {
            x.image_box = None;
            x
        };
        let car = |id| b(id, "Car", [0.0, 0.0, 100.0, 100.0], 0, 0);
        let ped = |id| b(id, "Pedestrian", [0.0, 0.0, 50.0, 100.0], 0, 0);
        let scene = |truth, tracks| Scene {
            name: "s".into(),
            frames: vec![(0, truth, tracks)],
        };
        let classes = ["car".to_string(), "pedestrian".to_string()];
        let cases = [
            (
                vec![no_image(car(1)), ped(2)],
                vec![car(11), ped(12)],
                "ground-truth boxes",
            ),
            (
                vec![car(1), ped(2)],
                vec![no_image(car(11)), ped(12)],
                "tracks",
            ),
        ];
        for (truth, tracks, side) in cases {
            let (h, notes) = kitti_hota(&[scene(truth, tracks)], &classes, KittiSimilarity::Image);
            assert_eq!(h.keys().collect::<Vec<_>>(), ["pedestrian"], "{side}");
            assert_eq!(notes.len(), 1, "{notes:?}");
            assert!(
                notes[0].starts_with(&format!(
                    "HOTA: class car is not evaluated: its {side} have no"
                )),
                "{notes:?}"
            );
        }
        // Some tracks without an image box: left out too, with how many.
        let tracks = vec![no_image(car(11)), car(13), ped(12)];
        let truth = vec![car(1), car(3), ped(2)];
        let (h, notes) = kitti_hota(&[scene(truth, tracks)], &classes, KittiSimilarity::Image);
        assert_eq!(h.keys().collect::<Vec<_>>(), ["pedestrian"]);
        assert!(
            notes[0].contains("1 of its 2 tracks have no 2D image box"),
            "{notes:?}"
        );
    }
}
