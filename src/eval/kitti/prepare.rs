//! One class's rows of every scene, with the pair costs and the ignore flags of the truth,
//! as the passes read them: ids are small per-scene slots, so a pass needs no map.

use std::collections::{HashMap, HashSet};

use super::DEVKIT_EXTRA_FRAMES;
use super::{KittiParams, ATTR_OCCLUDED, ATTR_TRACK_ID, ATTR_TRUNCATED, ATTR_TYPE};
use crate::eval::scene::Scene;
use crate::mcapio::LabelledBox;
use crate::tracker::geometry::iou3d;
use crate::tracker::Box3;

/// A ground-truth box of the evaluated class (or its neighbour).
#[derive(Debug, Clone)]
pub(super) struct GtObj {
    /// KITTI track id of the object (for `eval --events`).
    pub id: i64,
    /// Truncated, occluded or of the neighbouring class: never counted.
    pub ignored: bool,
}

/// A track box; `score` and `valid` persist across thresholds, as in the reference.
#[derive(Debug, Clone)]
pub(super) struct TrObj {
    /// Track id.
    pub id: i64,
    /// Index of the track among the scene's tracks (for its mean score).
    pub slot: u32,
    /// Of the neighbouring class (ignored when unmatched).
    pub neighbour: bool,
    /// 2D box `x1 y1 x2 y2`.
    pub bbox: [f64; 4],
    /// Score: the track's mean after the first pass.
    pub score: f64,
    /// Matched at some threshold already (then never ignored).
    pub valid: bool,
}

/// One frame of one class: ground truth, DontCare regions, track boxes and the cost
/// `1 - IoU3D` of every (ground truth, track) pair, row-major.
#[derive(Debug, Clone, Default)]
pub(super) struct Frame {
    pub gt: Vec<GtObj>,
    pub dc: Vec<[f64; 4]>,
    pub tr: Vec<TrObj>,
    pub cost: Vec<f64>,
}

/// One scene of one class.
#[derive(Debug, Clone, Default)]
pub(super) struct Seq {
    pub frames: Vec<Frame>,
    /// Number of distinct track ids (slots of [`TrObj::slot`]).
    pub n_tracks: usize,
    /// Per ground-truth trajectory, its rows in frame order as `(frame, index in frame.gt)`.
    pub trajectories: Vec<Vec<(u32, u32)>>,
}

/// The lower-cased KITTI type of a box: the `kitti_type` attribute, else the label.
fn kitti_type(b: &LabelledBox) -> String {
    b.attributes
        .get(ATTR_TYPE)
        .unwrap_or(&b.label)
        .to_lowercase()
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

/// A numeric attribute truncated to an integer like Python's `int(float(s))`.
fn int_attr(b: &LabelledBox, key: &str, default: i64) -> i64 {
    b.attributes
        .get(key)
        .and_then(|v| v.trim().parse::<f64>().ok())
        .map(|v| v.trunc() as i64)
        .unwrap_or(default)
}

fn box3(b: &LabelledBox) -> Box3 {
    Box3 {
        center: b.center,
        yaw: b.yaw,
        size: b.size,
    }
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

/// Why a class cannot be evaluated.
pub(super) enum Skip {
    NoTracks,
    DuplicateId {
        scene: String,
        frame: usize,
        id: i64,
    },
}

/// Selects one class's rows of every scene and computes the pair costs: the sequences and the
/// numbers of ground-truth and track trajectories.
pub(super) fn prepare(
    scenes: &[Scene],
    cls: &str,
    p: &KittiParams,
) -> Result<(Vec<Seq>, u64, u64), Skip> {
    let types = loaded_types(cls);
    let mut seqs = Vec::with_capacity(scenes.len());
    let (mut n_gt_traj, mut n_tr_traj) = (0u64, 0u64);
    for scene in scenes {
        let mut seq = Seq::default();
        let mut gt_slots: HashMap<i64, u32> = HashMap::new();
        let mut tr_slots: HashMap<i64, u32> = HashMap::new();
        let mut tr_ids = HashSet::new();
        let (mut gt_boxes, mut tr_boxes) = (Vec::new(), Vec::new());
        for (fi, (_, truth, tracks)) in scene.frames.iter().enumerate() {
            let mut frame = Frame::default();
            gt_boxes.clear();
            tr_boxes.clear();
            for b in truth {
                let Some((id, g)) = truth_row(b, cls, &types, p, &mut frame.dc) else {
                    continue;
                };
                let next = gt_slots.len() as u32;
                let slot = *gt_slots.entry(id).or_insert(next);
                if slot == next {
                    seq.trajectories.push(Vec::new());
                }
                seq.trajectories[slot as usize].push((fi as u32, frame.gt.len() as u32));
                frame.gt.push(g);
                gt_boxes.push(box3(b));
            }
            let mut seen = HashSet::new();
            for b in tracks {
                let kind = kitti_type(b);
                if !types.iter().any(|t| kind.contains(t.as_str())) {
                    continue;
                }
                let id = b.id as i64;
                if id == -1 && kind != "dontcare" {
                    continue;
                }
                if !seen.insert(id) {
                    let scene = scene.name.clone();
                    return Err(Skip::DuplicateId {
                        scene,
                        frame: fi,
                        id,
                    });
                }
                if kind != "dontcare" && tr_ids.insert(id) {
                    n_tr_traj += 1;
                }
                let next = tr_slots.len() as u32;
                frame.tr.push(TrObj {
                    id,
                    slot: *tr_slots.entry(id).or_insert(next),
                    neighbour: is_neighbour(cls, &kind),
                    bbox: b.image_box.unwrap_or([0.0; 4]),
                    score: b.score,
                    valid: false,
                });
                tr_boxes.push(box3(b));
            }
            frame.cost = Vec::with_capacity(gt_boxes.len() * tr_boxes.len());
            for g in &gt_boxes {
                for t in &tr_boxes {
                    frame.cost.push(1.0 - iou3d(g, t));
                }
            }
            seq.frames.push(frame);
        }
        for _ in 0..DEVKIT_EXTRA_FRAMES {
            seq.frames.push(Frame::default());
        }
        n_gt_traj += gt_slots.len() as u64;
        seq.n_tracks = tr_slots.len();
        seqs.push(seq);
    }
    if n_tr_traj == 0 {
        return Err(Skip::NoTracks);
    }
    Ok((seqs, n_gt_traj, n_tr_traj))
}

/// A truth box of the class (or its neighbour): its KITTI id and row; DontCare
/// boxes go to `dc`; `None` for rows the class does not load and ids of -1.
fn truth_row(
    b: &LabelledBox,
    cls: &str,
    types: &[String],
    p: &KittiParams,
    dc: &mut Vec<[f64; 4]>,
) -> Option<(i64, GtObj)> {
    let kind = kitti_type(b);
    if !types.iter().any(|t| kind.contains(t.as_str())) {
        return None;
    }
    if kind == "dontcare" {
        dc.push(b.image_box.unwrap_or([0.0; 4]));
        return None;
    }
    let id = match b
        .attributes
        .get(ATTR_TRACK_ID)
        .map(|v| v.trim().parse::<f64>())
    {
        Some(Ok(v)) => v.trunc() as i64,
        _ => b.id as i64 - 1,
    };
    if id == -1 {
        return None;
    }
    let ignored = int_attr(b, ATTR_OCCLUDED, 0) > p.max_occlusion
        || int_attr(b, ATTR_TRUNCATED, 0) > p.max_truncation
        || is_neighbour(cls, &kind);
    Some((id, GtObj { id, ignored }))
}
