//! One class's ground truth of every scene, prepared once (rows of the class, ignore flags,
//! DontCare regions, trajectories, boxes), so that many sets of tracks can be scored against it
//! (`probmot tune` scores hundreds). The tracks' side is in `tracks.rs`.

use std::collections::HashMap;

use super::KittiParams;
use super::DEVKIT_EXTRA_FRAMES;
use crate::eval::kitti_box::KittiFields;
use crate::eval::scene::Scene;
use crate::tracker::Box3;

/// A ground-truth box of the evaluated class (or its neighbour).
#[derive(Debug, Clone)]
pub(super) struct GtObj {
    /// KITTI track id of the object (for `eval --events`).
    pub id: i64,
    /// Truncated, occluded or of the neighbouring class: never counted.
    pub ignored: bool,
}

/// One frame of one class's truth: its rows, their boxes (same order) and the DontCare regions.
#[derive(Debug, Clone, Default)]
pub(super) struct TruthFrame {
    pub gt: Vec<GtObj>,
    pub boxes: Vec<Box3>,
    pub dc: Vec<[f64; 4]>,
}

/// One scene of one class's truth.
#[derive(Debug, Clone, Default)]
pub(super) struct TruthSeq {
    /// Scene name (for messages).
    pub name: String,
    /// The scene's frames, then the devkit's extra empty frame(s).
    pub frames: Vec<TruthFrame>,
    /// Per ground-truth trajectory, its rows in frame order as `(frame, index in frame.gt)`.
    pub trajectories: Vec<Vec<(u32, u32)>>,
}

/// One class's ground truth of a list of scenes, prepared once to score many sets of tracks of
/// the same scenes with [`ClassTruth::evaluate`]; `evaluate` (the whole protocol) builds one per
/// class.
#[derive(Debug, Clone)]
pub struct ClassTruth {
    /// The class (lower case).
    pub(super) cls: String,
    pub(super) p: KittiParams,
    pub(super) seqs: Vec<TruthSeq>,
    pub(super) n_gt_trajectories: u64,
}

impl ClassTruth {
    /// The truth of class `cls` in `scenes`: per scene its name and the truth boxes of each
    /// frame, in frame order (boxes carry the KITTI attributes `probmot import kitti` writes).
    /// Only the rows the class reads are kept (the class, its neighbour, DontCare regions).
    pub fn new<'a, S, F, B>(scenes: S, cls: &str, p: &KittiParams) -> ClassTruth
    where
        S: IntoIterator<Item = (&'a str, F)>,
        F: IntoIterator<Item = &'a [B]>,
        B: KittiFields + 'a,
    {
        let cls = cls.to_lowercase();
        let types = loaded_types(&cls);
        let mut seqs = Vec::new();
        let mut n_gt_trajectories = 0u64;
        for (name, frames) in scenes {
            let mut seq = TruthSeq {
                name: name.to_string(),
                ..TruthSeq::default()
            };
            let mut slots: HashMap<i64, u32> = HashMap::new();
            for (fi, truth) in frames.into_iter().enumerate() {
                let mut frame = TruthFrame::default();
                for b in truth {
                    let Some((id, g)) = truth_row(b, &cls, &types, p, &mut frame.dc) else {
                        continue;
                    };
                    let next = slots.len() as u32;
                    let slot = *slots.entry(id).or_insert(next);
                    if slot == next {
                        seq.trajectories.push(Vec::new());
                    }
                    seq.trajectories[slot as usize].push((fi as u32, frame.gt.len() as u32));
                    frame.gt.push(g);
                    frame.boxes.push(b.box3());
                }
                seq.frames.push(frame);
            }
            for _ in 0..DEVKIT_EXTRA_FRAMES {
                seq.frames.push(TruthFrame::default());
            }
            n_gt_trajectories += slots.len() as u64;
            seqs.push(seq);
        }
        ClassTruth {
            cls,
            p: p.clone(),
            seqs,
            n_gt_trajectories,
        }
    }

    /// [`ClassTruth::new`] from the truth of evaluation scenes.
    pub fn of_scenes<B: KittiFields>(
        scenes: &[Scene<B>],
        cls: &str,
        p: &KittiParams,
    ) -> ClassTruth {
        let it = scenes.iter().map(|s| {
            let frames = s.frames.iter().map(|(_, truth, _)| truth.as_slice());
            (s.name.as_str(), frames)
        });
        ClassTruth::new(it, cls, p)
    }

    /// The class (lower case).
    pub fn class(&self) -> &str {
        &self.cls
    }

    /// Number of scenes.
    pub fn scenes(&self) -> usize {
        self.seqs.len()
    }
}

/// The type substrings a class evaluation loads.
pub(super) fn loaded_types(cls: &str) -> Vec<String> {
    let mut v: Vec<String> = if cls.contains("car") {
        vec!["car".into(), "van".into()]
    } else if cls.contains("pedestrian") {
        vec!["pedestrian".into(), "person_sitting".into()]
    } else {
        vec![cls.to_string()]
    };
    v.push("dontcare".into());
    v
}

/// Whether `kind` is the neighbouring class of `cls` (ignored, never counted).
pub(super) fn is_neighbour(cls: &str, kind: &str) -> bool {
    (cls == "car" && kind == "van") || (cls == "pedestrian" && kind == "person_sitting")
}

/// Share of box `a`'s area inside box `b` (2D boxes `x1 y1 x2 y2`); 0 without overlap.
pub(super) fn overlap_share(a: &[f64; 4], b: &[f64; 4]) -> f64 {
    let w = a[2].min(b[2]) - a[0].max(b[0]);
    let h = a[3].min(b[3]) - a[1].max(b[1]);
    if w <= 0.0 || h <= 0.0 {
        return 0.0;
    }
    w * h / ((a[2] - a[0]) * (a[3] - a[1]))
}

/// A truth box of the class (or its neighbour): its KITTI id and row; DontCare
/// boxes go to `dc`; `None` for rows the class does not load and ids of -1.
fn truth_row(
    b: &impl KittiFields,
    cls: &str,
    types: &[String],
    p: &KittiParams,
    dc: &mut Vec<[f64; 4]>,
) -> Option<(i64, GtObj)> {
    let kind = b.kitti_type();
    if !types.iter().any(|t| kind.contains(t.as_str())) {
        return None;
    }
    if kind == "dontcare" {
        dc.push(b.image_box().unwrap_or([0.0; 4]));
        return None;
    }
    let id = b.truth_track_id();
    if id == -1 {
        return None;
    }
    let ignored = b.occluded() > p.max_occlusion
        || b.truncated() > p.max_truncation
        || is_neighbour(cls, &kind);
    Some((id, GtObj { id, ignored }))
}
