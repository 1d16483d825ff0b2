//! The KITTI 3D multi-object tracking metrics as the AB3DMOT evaluation (Weng et al. 2020,
//! `scripts/KITTI/evaluate.py`, 3D mode) computes them: sAMOTA, AMOTA and AMOTP over 40 recall
//! points, and the CLEAR MOT metrics (MOTA, MOTP, IDS, FRAG, ...) at the threshold with the
//! highest MOTA. The rules are summarised in `../shared/reference/evaluation-protocols.md`
//! (beside the repository); this is our own implementation of them, checked against numbers of
//! the reference evaluation in `tests/kitti_eval.rs` (see `tests/fixtures/kitti/README.md`).
//!
//! In short, per class and over all scenes:
//! - Rows (ground truth and tracks alike) are kept when a class string is a substring of the
//!   lower-cased KITTI type (the `kitti_type` attribute, else the label): Car evaluation keeps
//!   `car`, `van`, `dontcare`; Pedestrian keeps `pedestrian`, `person_sitting`, `dontcare`;
//!   any other class keeps itself and `dontcare`. Ground-truth DontCare rows become 2D
//!   don't-care regions; other ground-truth rows with KITTI id -1 are dropped.
//! - Per frame, ground truth and tracks are matched by the Munkres algorithm on `1 - IoU3D`,
//!   pairs with `1 - IoU3D > 1 - min_overlap` being forbidden.
//! - Ground truth with truncation > 0, occlusion > 2 or of the neighbouring class (Van for Car,
//!   Person_sitting for Pedestrian) is ignored: neither FN nor, when matched, counted against
//!   the track. Unmatched track boxes of the neighbouring class, with a 2D box at most 25 px high,
//!   or with more than half of their 2D box inside a DontCare region are ignored (not FP).
//! - A track's boxes all get the mean score of the track; at a threshold, tracks with a lower
//!   mean are dropped whole. The thresholds come from the (mean) scores of the matched boxes at
//!   40 recall points; sMOTA, MOTA and MOTP are averaged over them (missing points count 0).
//! - IDS, FRAG and MT/PT/ML are counted along each ground-truth trajectory (its frames in
//!   order, ignored frames interrupting it).
//!
//! Quirks of the reference evaluation that change numbers, and that we therefore keep:
//! - `TP` includes the matches of ignored ground truth (reported separately as `ITP`), and so do
//!   `MOTP` (mean IoU over `TP`), `recall` and `precision`; `MOTA` divides by the non-ignored
//!   ground truth only.
//! - A track box once matched (at any earlier threshold of the same class) can no longer be
//!   ignored by the neighbouring-class, height or DontCare rules.
//! - The mean track score is recomputed at every threshold from the previous means, which can
//!   move it by an ulp (and drop a track whose mean equals the threshold).
//! - FAR and MODP divide by the devkit's frame count, which is one more than the number of
//!   frames (the KITTI seqmap's last column holds the frame count, read as the last index).
//! - `overall` is not printed by the reference script; AB3DMOT's published tables give, for
//!   the three classes, the mean of the ratios and the sum of the counts, which is what we
//!   report, over the classes with ground truth that counts (a class evaluated only because
//!   tracks claim it has MOTA -inf and is left out, as the nuScenes protocol leaves out classes
//!   without ground truth).

use std::cmp::Ordering;
use std::collections::{BTreeMap, HashMap, HashSet};

use serde::Serialize;

use super::events::{Collector, MarkKind};
use super::nan_as_null;
use super::scene::{EvalBox, Scene};
use crate::tracker::geometry::iou3d;
use crate::tracker::Box3;

/// The classes evaluated by default.
pub const KITTI_CLASSES: [&str; 3] = ["car", "pedestrian", "cyclist"];

/// Attribute holding the original KITTI type (written by `probmot import kitti`).
const ATTR_TYPE: &str = "kitti_type";
/// Attribute holding the KITTI truncation.
const ATTR_TRUNCATED: &str = "kitti_truncated";
/// Attribute holding the KITTI occlusion level.
const ATTR_OCCLUDED: &str = "kitti_occluded";
/// Attribute holding the original KITTI track id of ground truth.
const ATTR_TRACK_ID: &str = "kitti_track_id";

/// The cost the reference gives forbidden pairs.
const MAX_COST: f64 = 1e9;
/// Extra frames per scene in the devkit's frame count (see the module documentation).
const DEVKIT_EXTRA_FRAMES: usize = 1;

/// Parameters of the protocol.
#[derive(Debug, Clone)]
pub struct KittiParams {
    /// Classes to evaluate (lower case; `car`, `pedestrian`, `cyclist` in the benchmark).
    pub classes: Vec<String>,
    /// Minimum 3D IoU of a match (0.25 by default; 0.5 and 0.7 are also used).
    pub min_overlap: f64,
    /// Ground truth truncated more than this is ignored.
    pub max_truncation: i64,
    /// Ground truth occluded more than this is ignored.
    pub max_occlusion: i64,
    /// Unmatched track boxes whose 2D box is at most this high (pixels) are ignored.
    pub min_height: f64,
    /// Number of recall points (40).
    pub recall_points: usize,
}

impl Default for KittiParams {
    fn default() -> Self {
        KittiParams {
            classes: KITTI_CLASSES.iter().map(|s| s.to_string()).collect(),
            min_overlap: 0.25,
            max_truncation: 0,
            max_occlusion: 2,
            min_height: 25.0,
            recall_points: 40,
        }
    }
}

/// The metrics at one score threshold (one recall point), as the reference prints them per
/// threshold.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct CurvePoint {
    /// Score threshold (tracks with a lower mean score are dropped).
    pub threshold: f64,
    /// The recall point this threshold stands for.
    pub recall_point: f64,
    /// Scaled MOTA at this recall point.
    #[serde(rename = "sMOTA", serialize_with = "nan_as_null")]
    pub smota: f64,
    /// MOTA.
    #[serde(rename = "MOTA", serialize_with = "nan_as_null")]
    pub mota: f64,
    /// MOTP (mean IoU3D of the matches).
    #[serde(rename = "MOTP", serialize_with = "nan_as_null")]
    pub motp: f64,
    /// Fraction of mostly tracked trajectories.
    #[serde(rename = "MT", serialize_with = "nan_as_null")]
    pub mt: f64,
    /// Fraction of mostly lost trajectories.
    #[serde(rename = "ML", serialize_with = "nan_as_null")]
    pub ml: f64,
    /// Identity switches.
    #[serde(rename = "IDS")]
    pub ids: u64,
    /// Fragmentations.
    #[serde(rename = "FRAG")]
    pub frag: u64,
    /// F1 score.
    #[serde(rename = "F1", serialize_with = "nan_as_null")]
    pub f1: f64,
    /// Precision.
    #[serde(serialize_with = "nan_as_null")]
    pub precision: f64,
    /// Recall achieved.
    #[serde(serialize_with = "nan_as_null")]
    pub recall: f64,
    /// False alarms per frame.
    #[serde(rename = "FAR", serialize_with = "nan_as_null")]
    pub far: f64,
    /// True positives (ignored ones included).
    #[serde(rename = "TP")]
    pub tp: u64,
    /// False positives.
    #[serde(rename = "FP")]
    pub fp: u64,
    /// False negatives.
    #[serde(rename = "FN")]
    pub fn_: u64,
}

/// Every metric of one class (or of the overall aggregate). Names follow the reference's
/// output; non-finite values are JSON `null`.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct KittiMetrics {
    /// Scaled AMOTA: mean sMOTA over the recall points.
    #[serde(rename = "sAMOTA", serialize_with = "nan_as_null")]
    pub samota: f64,
    /// Mean MOTA over the recall points.
    #[serde(rename = "AMOTA", serialize_with = "nan_as_null")]
    pub amota: f64,
    /// Mean MOTP over the recall points.
    #[serde(rename = "AMOTP", serialize_with = "nan_as_null")]
    pub amotp: f64,
    /// MOTA at the best threshold.
    #[serde(rename = "MOTA", serialize_with = "nan_as_null")]
    pub mota: f64,
    /// MOTP (mean IoU3D of the true positives) at the best threshold.
    #[serde(rename = "MOTP", serialize_with = "nan_as_null")]
    pub motp: f64,
    /// MOTA with `log10(IDS)` in place of IDS.
    #[serde(rename = "MOTAL", serialize_with = "nan_as_null")]
    pub motal: f64,
    /// MODA (MOTA without IDS).
    #[serde(rename = "MODA", serialize_with = "nan_as_null")]
    pub moda: f64,
    /// MODP (mean over frames of the mean IoU of non-ignored matches; 1 in frames without).
    #[serde(rename = "MODP", serialize_with = "nan_as_null")]
    pub modp: f64,
    /// Recall.
    #[serde(serialize_with = "nan_as_null")]
    pub recall: f64,
    /// Precision.
    #[serde(serialize_with = "nan_as_null")]
    pub precision: f64,
    /// F1 score.
    #[serde(rename = "F1", serialize_with = "nan_as_null")]
    pub f1: f64,
    /// False alarms per frame.
    #[serde(rename = "FAR", serialize_with = "nan_as_null")]
    pub far: f64,
    /// Fraction of mostly tracked trajectories (> 80 % of their frames).
    #[serde(rename = "MT", serialize_with = "nan_as_null")]
    pub mt: f64,
    /// Fraction of partly tracked trajectories.
    #[serde(rename = "PT", serialize_with = "nan_as_null")]
    pub pt: f64,
    /// Fraction of mostly lost trajectories (< 20 %).
    #[serde(rename = "ML", serialize_with = "nan_as_null")]
    pub ml: f64,
    /// True positives, ignored ones included.
    #[serde(rename = "TP")]
    pub tp: u64,
    /// True positives on ignored ground truth.
    #[serde(rename = "ITP")]
    pub itp: u64,
    /// False positives.
    #[serde(rename = "FP")]
    pub fp: u64,
    /// False negatives.
    #[serde(rename = "FN")]
    pub fn_: u64,
    /// Ignored false negatives.
    #[serde(rename = "IFN")]
    pub ifn: u64,
    /// Identity switches.
    #[serde(rename = "IDS")]
    pub ids: u64,
    /// Fragmentations.
    #[serde(rename = "FRAG")]
    pub frag: u64,
    /// Ground-truth boxes (ignored ones included).
    pub gt_objects: u64,
    /// Ignored ground-truth boxes.
    pub ignored_gt: u64,
    /// Ground-truth trajectories.
    pub gt_trajectories: u64,
    /// Track boxes kept at the best threshold.
    pub tracker_objects: u64,
    /// Ignored track boxes.
    pub ignored_tracker: u64,
    /// Track trajectories (all, before thresholding).
    pub tracker_trajectories: u64,
    /// The threshold of the best MOTA (the reference's "best results with single threshold").
    #[serde(serialize_with = "nan_as_null")]
    pub best_threshold: f64,
    /// The metrics at every recall point, in order (empty for `overall`).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub curve: Vec<CurvePoint>,
}

/// Names accepted by [`KittiMetrics::get`], in report order (the main one first).
pub const METRIC_NAMES: [&str; 27] = [
    "sAMOTA",
    "AMOTA",
    "AMOTP",
    "MOTA",
    "MOTP",
    "MOTAL",
    "MODA",
    "MODP",
    "recall",
    "precision",
    "F1",
    "FAR",
    "MT",
    "PT",
    "ML",
    "TP",
    "ITP",
    "FP",
    "FN",
    "IFN",
    "IDS",
    "FRAG",
    "gt_objects",
    "ignored_gt",
    "gt_trajectories",
    "tracker_objects",
    "ignored_tracker",
];

impl KittiMetrics {
    /// A metric by its reference name (see [`METRIC_NAMES`]; also `tracker_trajectories` and
    /// `best_threshold`); NaN for an unknown name.
    pub fn get(&self, name: &str) -> f64 {
        match name {
            "sAMOTA" => self.samota,
            "AMOTA" => self.amota,
            "AMOTP" => self.amotp,
            "MOTA" => self.mota,
            "MOTP" => self.motp,
            "MOTAL" => self.motal,
            "MODA" => self.moda,
            "MODP" => self.modp,
            "recall" => self.recall,
            "precision" => self.precision,
            "F1" => self.f1,
            "FAR" => self.far,
            "MT" => self.mt,
            "PT" => self.pt,
            "ML" => self.ml,
            "TP" => self.tp as f64,
            "ITP" => self.itp as f64,
            "FP" => self.fp as f64,
            "FN" => self.fn_ as f64,
            "IFN" => self.ifn as f64,
            "IDS" => self.ids as f64,
            "FRAG" => self.frag as f64,
            "gt_objects" => self.gt_objects as f64,
            "ignored_gt" => self.ignored_gt as f64,
            "gt_trajectories" => self.gt_trajectories as f64,
            "tracker_objects" => self.tracker_objects as f64,
            "ignored_tracker" => self.ignored_tracker as f64,
            "tracker_trajectories" => self.tracker_trajectories as f64,
            "best_threshold" => self.best_threshold,
            _ => f64::NAN,
        }
    }

    /// The aggregate of several classes: mean of the ratios, sum of the counts.
    fn overall<'a>(classes: impl Iterator<Item = &'a KittiMetrics>) -> KittiMetrics {
        let all: Vec<&KittiMetrics> = classes.collect();
        let mean = |f: fn(&KittiMetrics) -> f64| {
            if all.is_empty() {
                f64::NAN
            } else {
                all.iter().map(|m| f(m)).sum::<f64>() / all.len() as f64
            }
        };
        let sum = |f: fn(&KittiMetrics) -> u64| all.iter().map(|m| f(m)).sum::<u64>();
        KittiMetrics {
            samota: mean(|m| m.samota),
            amota: mean(|m| m.amota),
            amotp: mean(|m| m.amotp),
            mota: mean(|m| m.mota),
            motp: mean(|m| m.motp),
            motal: mean(|m| m.motal),
            moda: mean(|m| m.moda),
            modp: mean(|m| m.modp),
            recall: mean(|m| m.recall),
            precision: mean(|m| m.precision),
            f1: mean(|m| m.f1),
            far: mean(|m| m.far),
            mt: mean(|m| m.mt),
            pt: mean(|m| m.pt),
            ml: mean(|m| m.ml),
            tp: sum(|m| m.tp),
            itp: sum(|m| m.itp),
            fp: sum(|m| m.fp),
            fn_: sum(|m| m.fn_),
            ifn: sum(|m| m.ifn),
            ids: sum(|m| m.ids),
            frag: sum(|m| m.frag),
            gt_objects: sum(|m| m.gt_objects),
            ignored_gt: sum(|m| m.ignored_gt),
            gt_trajectories: sum(|m| m.gt_trajectories),
            tracker_objects: sum(|m| m.tracker_objects),
            ignored_tracker: sum(|m| m.ignored_tracker),
            tracker_trajectories: sum(|m| m.tracker_trajectories),
            best_threshold: f64::NAN,
            curve: Vec::new(),
        }
    }
}

/// Result of an evaluation.
#[derive(Debug, Clone, Serialize)]
pub struct KittiResult {
    /// Protocol name.
    pub protocol: &'static str,
    /// Minimum 3D IoU of a match.
    pub min_overlap: f64,
    /// Per evaluated class. A class without any track box of its types is not evaluated (as in
    /// the reference) and is absent here; see `notes`.
    pub classes: BTreeMap<String, KittiMetrics>,
    /// Aggregate over the evaluated classes with ground truth that counts: mean of the ratios,
    /// sum of the counts (NaN / 0 when there is none).
    pub overall: KittiMetrics,
    /// Things the user should know (skipped classes, classes without ground truth).
    pub notes: Vec<String>,
}

/// A ground-truth box of the evaluated class (or its neighbour).
#[derive(Debug, Clone)]
struct GtObj {
    id: i64,
    kind: String,
    truncation: i64,
    occlusion: i64,
}

/// A track box; `score` and `valid` persist across thresholds, as in the reference.
#[derive(Debug, Clone)]
struct TrObj {
    id: i64,
    kind: String,
    bbox: [f64; 4],
    score: f64,
    valid: bool,
}

/// One frame of one class: ground truth, DontCare regions, track boxes and the cost
/// `1 - IoU3D` of every (ground truth, track) pair, row-major.
#[derive(Debug, Clone, Default)]
struct Frame {
    gt: Vec<GtObj>,
    dc: Vec<[f64; 4]>,
    tr: Vec<TrObj>,
    cost: Vec<f64>,
}

/// One scene of one class.
#[derive(Debug, Clone, Default)]
struct Seq {
    frames: Vec<Frame>,
}

/// The lower-cased KITTI type of a box: the `kitti_type` attribute, else the label.
fn kitti_type(b: &EvalBox) -> String {
    b.attributes
        .get(ATTR_TYPE)
        .unwrap_or(&b.label)
        .to_lowercase()
}

/// The type substrings a class evaluation loads.
fn loaded_types(cls: &str) -> Vec<String> {
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
fn is_neighbour(cls: &str, kind: &str) -> bool {
    (cls == "car" && kind == "van") || (cls == "pedestrian" && kind == "person_sitting")
}

/// A numeric attribute truncated to an integer like Python's `int(float(s))`.
fn int_attr(b: &EvalBox, key: &str, default: i64) -> i64 {
    b.attributes
        .get(key)
        .and_then(|v| v.trim().parse::<f64>().ok())
        .map(|v| v.trunc() as i64)
        .unwrap_or(default)
}

fn box3(b: &EvalBox) -> Box3 {
    Box3 {
        center: b.center,
        yaw: b.yaw,
        size: b.size,
    }
}

/// Share of box `a`'s area inside box `b` (2D boxes `x1 y1 x2 y2`); 0 without overlap.
fn overlap_share(a: &[f64; 4], b: &[f64; 4]) -> f64 {
    let w = a[2].min(b[2]) - a[0].max(b[0]);
    let h = a[3].min(b[3]) - a[1].max(b[1]);
    if w <= 0.0 || h <= 0.0 {
        return 0.0;
    }
    w * h / ((a[2] - a[0]) * (a[3] - a[1]))
}

/// Why a class cannot be evaluated.
enum Skip {
    NoTracks,
    DuplicateId {
        scene: String,
        frame: usize,
        id: i64,
    },
}

/// Selects one class's rows of every scene and computes the pair costs.
fn prepare(scenes: &[Scene], cls: &str) -> Result<(Vec<Seq>, u64, u64), Skip> {
    let types = loaded_types(cls);
    let loaded = |kind: &str| types.iter().any(|t| kind.contains(t.as_str()));
    let mut seqs = Vec::with_capacity(scenes.len());
    let (mut n_gt_traj, mut n_tr_traj) = (0u64, 0u64);
    for scene in scenes {
        let mut seq = Seq::default();
        let mut gt_ids = HashSet::new();
        let mut tr_ids = HashSet::new();
        for (fi, (_, truth, tracks)) in scene.frames.iter().enumerate() {
            let mut frame = Frame::default();
            let mut gt_boxes = Vec::new();
            for b in truth {
                let kind = kitti_type(b);
                if !loaded(&kind) {
                    continue;
                }
                if kind == "dontcare" {
                    frame.dc.push(b.image_box.unwrap_or([0.0; 4]));
                    continue;
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
                    continue;
                }
                if gt_ids.insert(id) {
                    n_gt_traj += 1;
                }
                frame.gt.push(GtObj {
                    id,
                    kind,
                    truncation: int_attr(b, ATTR_TRUNCATED, 0),
                    occlusion: int_attr(b, ATTR_OCCLUDED, 0),
                });
                gt_boxes.push(box3(b));
            }
            let mut seen = HashSet::new();
            let mut tr_boxes = Vec::new();
            for b in tracks {
                let kind = kitti_type(b);
                if !loaded(&kind) {
                    continue;
                }
                let id = b.id as i64;
                if id == -1 && kind != "dontcare" {
                    continue;
                }
                if !seen.insert(id) {
                    return Err(Skip::DuplicateId {
                        scene: scene.name.clone(),
                        frame: fi,
                        id,
                    });
                }
                if kind != "dontcare" && tr_ids.insert(id) {
                    n_tr_traj += 1;
                }
                frame.tr.push(TrObj {
                    id,
                    kind,
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
        seqs.push(seq);
    }
    if n_tr_traj == 0 {
        return Err(Skip::NoTracks);
    }
    Ok((seqs, n_gt_traj, n_tr_traj))
}

/// The Munkres (Hungarian) algorithm in the classic six-step formulation, with the same scan
/// orders as the implementation the reference uses, so that ties between equally good
/// assignments are broken the same way. `cost` is `rows x cols`, row-major; the matrix is padded
/// with zeros to a square. Returns the assigned `(row, col)` pairs in row order.
fn munkres(cost: &[f64], rows: usize, cols: usize) -> Vec<(usize, usize)> {
    if rows == 0 || cols == 0 {
        return Vec::new();
    }
    let n = rows.max(cols);
    let mut c = vec![0.0f64; n * n];
    for i in 0..rows {
        c[i * n..i * n + cols].copy_from_slice(&cost[i * cols..(i + 1) * cols]);
    }
    // 1 = starred, 2 = primed.
    let mut marked = vec![0u8; n * n];
    let mut row_cov = vec![false; n];
    let mut col_cov = vec![false; n];
    let mut path: Vec<(usize, usize)> = Vec::with_capacity(2 * n);
    let mut z0 = (0usize, 0usize);

    // Step 1: subtract each row's minimum.
    for i in 0..n {
        let row = &mut c[i * n..(i + 1) * n];
        let mut m = row[0];
        for &v in row.iter().skip(1) {
            if v < m {
                m = v;
            }
        }
        for v in row.iter_mut() {
            *v -= m;
        }
    }
    // Step 2: star zeros with no starred zero in their row or column.
    for i in 0..n {
        for j in 0..n {
            if c[i * n + j] == 0.0 && !col_cov[j] && !row_cov[i] {
                marked[i * n + j] = 1;
                col_cov[j] = true;
                row_cov[i] = true;
            }
        }
    }
    row_cov.iter_mut().for_each(|v| *v = false);
    col_cov.iter_mut().for_each(|v| *v = false);

    let mut step = 3;
    loop {
        match step {
            3 => {
                let mut count = 0;
                for i in 0..n {
                    for j in 0..n {
                        if marked[i * n + j] == 1 {
                            col_cov[j] = true;
                            count += 1;
                        }
                    }
                }
                if count >= n {
                    break;
                }
                step = 4;
            }
            4 => loop {
                // The first row with an uncovered zero, and the last such zero in that row.
                let mut found = None;
                for i in 0..n {
                    for j in 0..n {
                        if c[i * n + j] == 0.0 && !row_cov[i] && !col_cov[j] {
                            found = Some((i, j));
                        }
                    }
                    if found.is_some() {
                        break;
                    }
                }
                let Some((r, col)) = found else {
                    step = 6;
                    break;
                };
                marked[r * n + col] = 2;
                match (0..n).find(|&j| marked[r * n + j] == 1) {
                    Some(sc) => {
                        row_cov[r] = true;
                        col_cov[sc] = false;
                    }
                    None => {
                        z0 = (r, col);
                        step = 5;
                        break;
                    }
                }
            },
            5 => {
                path.clear();
                path.push(z0);
                loop {
                    let col = path[path.len() - 1].1;
                    let Some(r) = (0..n).find(|&i| marked[i * n + col] == 1) else {
                        break;
                    };
                    path.push((r, col));
                    let pc = (0..n).find(|&j| marked[r * n + j] == 2).unwrap_or(0);
                    path.push((r, pc));
                }
                for &(i, j) in &path {
                    let m = &mut marked[i * n + j];
                    *m = if *m == 1 { 0 } else { 1 };
                }
                row_cov.iter_mut().for_each(|v| *v = false);
                col_cov.iter_mut().for_each(|v| *v = false);
                marked.iter_mut().filter(|m| **m == 2).for_each(|m| *m = 0);
                step = 3;
            }
            _ => {
                // Step 6: add the smallest uncovered value to covered rows, subtract it from
                // uncovered columns.
                let mut minval = i64::MAX as f64;
                for i in 0..n {
                    for j in 0..n {
                        if !row_cov[i] && !col_cov[j] && minval > c[i * n + j] {
                            minval = c[i * n + j];
                        }
                    }
                }
                for i in 0..n {
                    for j in 0..n {
                        if row_cov[i] {
                            c[i * n + j] += minval;
                        }
                        if !col_cov[j] {
                            c[i * n + j] -= minval;
                        }
                    }
                }
                step = 4;
            }
        }
    }
    let mut out = Vec::new();
    for i in 0..rows {
        for j in 0..cols {
            if marked[i * n + j] == 1 {
                out.push((i, j));
            }
        }
    }
    out
}

/// Counts and derived metrics of one pass over the data at one threshold.
#[derive(Debug, Clone, Default)]
struct Pass {
    tp: u64,
    itp: u64,
    fp: u64,
    fn_: u64,
    ifn: u64,
    ids: u64,
    frag: u64,
    /// Ground truth minus ignored.
    n_gt: u64,
    n_igt: u64,
    n_tr: u64,
    n_itr: u64,
    mt: f64,
    pt: f64,
    ml: f64,
    mota: f64,
    moda: f64,
    motal: f64,
    smota: f64,
    motp: f64,
    modp: f64,
    recall: f64,
    precision: f64,
    f1: f64,
    far: f64,
    /// Mean scores of the matched boxes, in matching order.
    scores: Vec<f64>,
}

/// One class's data and the state the reference carries from one threshold to the next.
struct ClassEval<'a> {
    cls: String,
    p: &'a KittiParams,
    seqs: Vec<Seq>,
    n_gt_trajectories: u64,
    /// Where the decisions of a pass are recorded (`eval --events`), when set.
    log: Option<Collector>,
}

impl ClassEval<'_> {
    /// One pass at `threshold` (tracks whose mean score is below it are dropped), with sMOTA at
    /// `recall_point`.
    fn pass(&mut self, threshold: f64, recall_point: f64) -> Pass {
        let mut r = Pass::default();
        let mut total_cost = 0.0f64;
        let mut modp_sum = 0.0f64;
        let mut n_frames = 0usize;
        let (mut mt, mut pt, mut ml) = (0u64, 0u64, 0u64);
        let mut n_ignored_traj = 0u64;
        let cls = self.cls.clone();
        let p = self.p;
        for (si, seq) in self.seqs.iter_mut().enumerate() {
            n_frames += seq.frames.len();
            // Mean score per track over its rows, summed in file order; every row takes it.
            let mut sums: HashMap<i64, (f64, usize)> = HashMap::new();
            for f in &seq.frames {
                for t in &f.tr {
                    let e = sums.entry(t.id).or_insert((0.0, 0));
                    e.0 += t.score;
                    e.1 += 1;
                }
            }
            let avg: HashMap<i64, f64> = sums
                .into_iter()
                .map(|(id, (s, n))| (id, s / n as f64))
                .collect();
            for f in &mut seq.frames {
                for t in &mut f.tr {
                    t.score = avg[&t.id];
                }
            }
            // Per ground-truth trajectory: matched track id (or -1) and ignored flag per frame.
            let mut traj_index: HashMap<i64, usize> = HashMap::new();
            let mut trajs: Vec<(Vec<i64>, Vec<bool>)> = Vec::new();
            for (fi, f) in seq.frames.iter_mut().enumerate() {
                let kept: Vec<usize> = (0..f.tr.len())
                    .filter(|&k| f.tr[k].score.partial_cmp(&threshold) != Some(Ordering::Less))
                    .collect();
                let ng = f.gt.len();
                let nt = kept.len();
                r.n_gt += ng as u64;
                r.n_tr += nt as u64;
                let mut cost = Vec::with_capacity(ng * nt);
                let mut slots = Vec::with_capacity(ng);
                for (gi, g) in f.gt.iter().enumerate() {
                    for &k in &kept {
                        let c = f.cost[gi * f.tr.len() + k];
                        cost.push(if c <= 1.0 - p.min_overlap {
                            c
                        } else {
                            MAX_COST
                        });
                    }
                    let slot = *traj_index.entry(g.id).or_insert_with(|| {
                        trajs.push((Vec::new(), Vec::new()));
                        trajs.len() - 1
                    });
                    trajs[slot].0.push(-1);
                    trajs[slot].1.push(false);
                    slots.push(slot);
                }
                let pairs = munkres(&cost, ng, nt);
                // Matched track (index into `kept`) of each ground truth.
                let mut matched: Vec<Option<usize>> = vec![None; ng];
                let mut tmptp = 0u64;
                let mut gated = 0i64;
                let mut tmpc = 0.0f64;
                let mut tmpcs = vec![0.0f64; ng];
                for &(row, col) in &pairs {
                    let c = cost[row * nt + col];
                    if c < MAX_COST {
                        let t = &mut f.tr[kept[col]];
                        matched[row] = Some(col);
                        t.valid = true;
                        total_cost += 1.0 - c;
                        tmpc += 1.0 - c;
                        tmpcs[row] = 1.0 - c;
                        let last = trajs[slots[row]].0.len() - 1;
                        trajs[slots[row]].0[last] = t.id;
                        r.tp += 1;
                        tmptp += 1;
                        r.scores.push(t.score);
                    } else {
                        gated += 1;
                    }
                }
                // Ignored track boxes: neighbouring class, too small, or inside DontCare.
                let mut n_ignored_tr = 0u64;
                let mut tr_ignored = vec![false; nt];
                for (col, &k) in kept.iter().enumerate() {
                    let t = &f.tr[k];
                    if t.valid {
                        continue;
                    }
                    let height = (t.bbox[1] - t.bbox[3]).abs();
                    if is_neighbour(&cls, &t.kind) || height <= p.min_height {
                        n_ignored_tr += 1;
                        tr_ignored[col] = true;
                        continue;
                    }
                    if f.dc.iter().any(|d| overlap_share(&t.bbox, d) > 0.5) {
                        n_ignored_tr += 1;
                        tr_ignored[col] = true;
                    }
                }
                // Ignored ground truth: truncated, occluded or of the neighbouring class.
                let (mut ignored_fn, mut ignored_tp, mut ignored_pairs) = (0u64, 0u64, 0u64);
                for (gi, g) in f.gt.iter().enumerate() {
                    let ignored = g.occlusion > p.max_occlusion
                        || g.truncation > p.max_truncation
                        || is_neighbour(&cls, &g.kind);
                    if !ignored {
                        continue;
                    }
                    let last = trajs[slots[gi]].1.len() - 1;
                    trajs[slots[gi]].1[last] = true;
                    match matched[gi] {
                        None => ignored_fn += 1,
                        Some(col) => {
                            ignored_tp += 1;
                            if tr_ignored[col] {
                                ignored_pairs += 1;
                            }
                            tmpc -= tmpcs[gi];
                        }
                    }
                }
                if let Some(log) = self.log.as_mut() {
                    let ignored = |gi: usize| trajs[slots[gi]].1.last() == Some(&true);
                    let tr_id = |col: usize| f.tr[kept[col]].id;
                    let gt_ids = f.gt.iter().map(|g| g.id);
                    log.record_kitti_frame(si, fi, gt_ids, &matched, ignored, &tr_ignored, tr_id);
                }
                tmptp -= ignored_tp;
                r.itp += ignored_tp;
                r.n_gt -= ignored_fn + ignored_tp;
                r.n_igt += ignored_fn + ignored_tp;
                r.n_itr += n_ignored_tr;
                // Pairs over the IoU limit, plus ground truth left unassigned, minus the ignored
                // ones among both (never negative).
                let frame_fn = gated + ng as i64 - pairs.len() as i64 - ignored_fn as i64;
                r.fn_ += frame_fn.max(0) as u64;
                r.ifn += ignored_fn;
                r.fp += nt as u64 + ignored_pairs - tmptp - n_ignored_tr - ignored_tp;
                modp_sum += if tmptp != 0 { tmpc / tmptp as f64 } else { 1.0 };
            }
            // Identity switches, fragmentations and coverage along each trajectory.
            let mut slot_ids = vec![0i64; trajs.len()];
            for (id, slot) in &traj_index {
                slot_ids[*slot] = *id;
            }
            for (slot, (g, ign)) in trajs.iter().enumerate() {
                let mut mark = |kind, f: usize, previous: i64| {
                    if let Some(log) = self.log.as_mut() {
                        log.record_mark(si, slot_ids[slot], f, kind, g[f], previous);
                    }
                };
                if ign.iter().all(|&i| i) {
                    n_ignored_traj += 1;
                    continue;
                }
                if g.iter().all(|&t| t == -1) {
                    ml += 1;
                    continue;
                }
                let n = g.len();
                let mut last_id = g[0];
                let mut tracked = u64::from(g[0] >= 0);
                for f in 1..n {
                    if ign[f] {
                        last_id = -1;
                        continue;
                    }
                    if last_id != g[f] && last_id != -1 && g[f] != -1 && g[f - 1] != -1 {
                        r.ids += 1;
                        mark(MarkKind::Switch, f, last_id);
                    }
                    if f < n - 1
                        && g[f - 1] != g[f]
                        && last_id != -1
                        && g[f] != -1
                        && g[f + 1] != -1
                    {
                        r.frag += 1;
                        mark(MarkKind::Fragmentation, f, last_id);
                    }
                    if g[f] != -1 {
                        tracked += 1;
                        last_id = g[f];
                    }
                }
                if n > 1 {
                    let f = n - 1;
                    if g[f - 1] != g[f] && last_id != -1 && g[f] != -1 && !ign[f] {
                        r.frag += 1;
                        mark(MarkKind::Fragmentation, f, last_id);
                    }
                }
                let considered = n - ign.iter().filter(|&&i| i).count();
                let ratio = tracked as f64 / considered as f64;
                if ratio > 0.8 {
                    mt += 1;
                } else if ratio < 0.2 {
                    ml += 1;
                } else {
                    pt += 1;
                }
            }
        }
        let n_traj = self.n_gt_trajectories - n_ignored_traj;
        if n_traj == 0 {
            (r.mt, r.pt, r.ml) = (0.0, 0.0, 0.0);
        } else {
            r.mt = mt as f64 / n_traj as f64;
            r.pt = pt as f64 / n_traj as f64;
            r.ml = ml as f64 / n_traj as f64;
        }
        if r.fp + r.tp == 0 || r.tp + r.fn_ == 0 {
            (r.recall, r.precision) = (0.0, 0.0);
        } else {
            r.recall = r.tp as f64 / (r.tp + r.fn_) as f64;
            r.precision = r.tp as f64 / (r.fp + r.tp) as f64;
        }
        r.f1 = if r.recall + r.precision == 0.0 {
            0.0
        } else {
            2.0 * (r.precision * r.recall) / (r.precision + r.recall)
        };
        r.far = r.fp as f64 / n_frames as f64;
        if r.n_gt == 0 {
            (r.mota, r.moda, r.smota, r.motal) = (
                f64::NEG_INFINITY,
                f64::NEG_INFINITY,
                f64::NEG_INFINITY,
                f64::NEG_INFINITY,
            );
        } else {
            let n_gt = r.n_gt as f64;
            r.mota = 1.0 - (r.fn_ + r.fp + r.ids) as f64 / n_gt;
            r.moda = 1.0 - (r.fn_ + r.fp) as f64 / n_gt;
            let s = 1.0
                - ((r.fn_ + r.fp + r.ids) as f64 - (1.0 - recall_point) * n_gt)
                    / (recall_point * n_gt);
            r.smota = s.clamp(0.0, 1.0);
            r.motal = if r.ids == 0 {
                r.mota
            } else {
                1.0 - ((r.fn_ + r.fp) as f64 + (r.ids as f64).log10()) / n_gt
            };
        }
        r.motp = if r.tp == 0 {
            0.0
        } else {
            total_cost / r.tp as f64
        };
        r.modp = modp_sum / n_frames as f64;
        r
    }
}

/// The score thresholds and their recall points: walking the matched boxes' scores from the
/// highest, a threshold is taken whenever the recall reached is the closest to the next of the
/// `recall_points` evenly spaced points (the first, at recall 0, is dropped).
fn thresholds(scores: &[f64], num_gt: u64, recall_points: usize) -> (Vec<f64>, Vec<f64>) {
    let mut s = scores.to_vec();
    s.sort_by(|a, b| b.total_cmp(a));
    let (mut th, mut rec) = (Vec::new(), Vec::new());
    let mut current = 0.0f64;
    let n = s.len();
    for (i, &score) in s.iter().enumerate() {
        let l_recall = (i + 1) as f64 / num_gt as f64;
        let r_recall = if i + 1 < n {
            (i + 2) as f64 / num_gt as f64
        } else {
            l_recall
        };
        if (r_recall - current) < (current - l_recall) && i + 1 < n {
            continue;
        }
        th.push(score);
        rec.push(current);
        current += 1.0 / recall_points as f64;
    }
    if !th.is_empty() {
        th.remove(0);
        rec.remove(0);
    }
    (th, rec)
}

fn evaluate_class(
    scenes: &[Scene],
    cls: &str,
    p: &KittiParams,
    notes: &mut Vec<String>,
    log: Option<&mut Collector>,
) -> Option<KittiMetrics> {
    let (seqs, n_gt_trajectories, n_tr_trajectories) = match prepare(scenes, cls) {
        Ok(v) => v,
        Err(Skip::NoTracks) => {
            notes.push(format!(
                "{cls}: no track box of the types {} evaluated; class not evaluated (as the \
                 reference does)",
                loaded_types(cls)[..loaded_types(cls).len() - 1].join("/")
            ));
            return None;
        }
        Err(Skip::DuplicateId { scene, frame, id }) => {
            notes.push(format!(
                "{cls}: {scene}: track id {id} appears twice in frame {frame}; class not \
                 evaluated (the reference rejects such results)"
            ));
            return None;
        }
    };
    let mut e = ClassEval {
        cls: cls.to_string(),
        p,
        seqs,
        n_gt_trajectories,
        log: None,
    };
    let first = e.pass(-10000.0, 1.0);
    let num_gt = first.tp + first.fn_;
    let (ths, recs) = thresholds(&first.scores, num_gt, p.recall_points);
    let mut curve = Vec::with_capacity(ths.len());
    let (mut sum_smota, mut sum_mota, mut sum_motp) = (0.0f64, 0.0f64, 0.0f64);
    let (mut best_mota, mut best_threshold) = (0.0f64, -10000.0f64);
    for (&th, &rec) in ths.iter().zip(&recs) {
        let r = e.pass(th, rec);
        sum_smota += r.smota;
        sum_mota += r.mota;
        sum_motp += r.motp;
        if r.mota > best_mota {
            best_threshold = th;
            best_mota = r.mota;
        }
        curve.push(CurvePoint {
            threshold: th,
            recall_point: rec,
            smota: r.smota,
            mota: r.mota,
            motp: r.motp,
            mt: r.mt,
            ml: r.ml,
            ids: r.ids,
            frag: r.frag,
            f1: r.f1,
            precision: r.precision,
            recall: r.recall,
            far: r.far,
            tp: r.tp,
            fp: r.fp,
            fn_: r.fn_,
        });
    }
    e.log = log.is_some().then(Collector::default);
    let best = e.pass(best_threshold, 1.0);
    if let (Some(out), Some(recorded)) = (log, e.log.take()) {
        *out = recorded;
    }
    if best.n_gt == 0 {
        notes.push(format!(
            "{cls}: no ground truth that counts (all ignored or none): MOTA is -inf (null), as \
             in the reference; left out of overall"
        ));
    }
    let k = p.recall_points as f64;
    Some(KittiMetrics {
        samota: sum_smota / k,
        amota: sum_mota / k,
        amotp: sum_motp / k,
        mota: best.mota,
        motp: best.motp,
        motal: best.motal,
        moda: best.moda,
        modp: best.modp,
        recall: best.recall,
        precision: best.precision,
        f1: best.f1,
        far: best.far,
        mt: best.mt,
        pt: best.pt,
        ml: best.ml,
        tp: best.tp,
        itp: best.itp,
        fp: best.fp,
        fn_: best.fn_,
        ifn: best.ifn,
        ids: best.ids,
        frag: best.frag,
        gt_objects: best.n_gt + best.n_igt,
        ignored_gt: best.n_igt,
        gt_trajectories: n_gt_trajectories,
        tracker_objects: best.n_tr,
        ignored_tracker: best.n_itr,
        tracker_trajectories: n_tr_trajectories,
        best_threshold,
        curve,
    })
}

/// Per evaluated class, the decisions of the pass at its best-MOTA threshold (the pass the counts
/// of [`evaluate`] come from), for `eval --events`.
pub fn best_threshold_decisions(scenes: &[Scene], p: &KittiParams) -> Vec<(String, Collector)> {
    let mut out = Vec::new();
    for c in &p.classes {
        let c = c.to_lowercase();
        let mut log = Collector::default();
        if evaluate_class(scenes, &c, p, &mut Vec::new(), Some(&mut log)).is_some() {
            out.push((c, log));
        }
    }
    out
}

/// Evaluates scenes (one KITTI sequence each) with the KITTI 3D MOT protocol of AB3DMOT.
///
/// Truth boxes carry the KITTI fields as attributes (`kitti_type`, `kitti_truncated`,
/// `kitti_occluded`, `kitti_track_id`) and DontCare regions as boxes of type DontCare with an
/// `image_box`; track boxes need `image_box` (the 2D box of their last matched detection) for
/// the ignore rules and take their type from `kitti_type` (else the label).
pub fn evaluate(scenes: &[Scene], p: &KittiParams) -> KittiResult {
    let mut notes = Vec::new();
    let mut classes = BTreeMap::new();
    for c in &p.classes {
        let c = c.to_lowercase();
        if let Some(m) = evaluate_class(scenes, &c, p, &mut notes, None) {
            classes.insert(c, m);
        }
    }
    let overall = KittiMetrics::overall(classes.values().filter(|m| m.gt_objects > m.ignored_gt));
    KittiResult {
        protocol: "kitti",
        min_overlap: p.min_overlap,
        classes,
        overall,
        notes,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A normal-sized 2D box (100 px high).
    const IMG: [f64; 4] = [100.0, 100.0, 200.0, 200.0];
    /// IoU of a track on its ground truth (see [`trk`]): overlap 3.5 x 1.75 m of 4 x 2 m boxes.
    const IOU: f64 = 6.125 / 9.875;

    fn attrs(pairs: &[(&str, String)]) -> BTreeMap<String, String> {
        pairs
            .iter()
            .map(|(k, v)| (k.to_string(), v.clone()))
            .collect()
    }

    /// A ground-truth box as `probmot import kitti` writes it: a 4 x 2 x 1.5 m box at `(x, 0)`.
    fn gt(kitti_id: i64, kind: &str, x: f64, truncated: u8, occluded: u8) -> EvalBox {
        EvalBox {
            id: (kitti_id + 1) as u64,
            label: kind.to_lowercase(),
            center: [x, 0.0, 0.0],
            size: [4.0, 2.0, 1.5],
            yaw: 0.0,
            score: 1.0,
            attributes: attrs(&[
                (ATTR_TYPE, kind.to_string()),
                (ATTR_TRUNCATED, truncated.to_string()),
                (ATTR_OCCLUDED, occluded.to_string()),
                (ATTR_TRACK_ID, kitti_id.to_string()),
            ]),
            image_box: Some(IMG),
        }
    }

    fn dontcare(image_box: [f64; 4]) -> EvalBox {
        EvalBox {
            id: 0,
            attributes: attrs(&[(ATTR_TYPE, "DontCare".into()), (ATTR_TRACK_ID, "-1".into())]),
            image_box: Some(image_box),
            ..gt(-1, "DontCare", -100.0, 0, 0)
        }
    }

    /// A track box of `kind` at `(x + 0.5, 0.25)`, the same size as [`gt`]'s: on a ground truth
    /// at `x` its IoU is [`IOU`]. (Not exactly on it: the reference's polygon clipping fails on
    /// collinear edges, and these scenes are also checked against the reference, see
    /// `tests/fixtures/kitti/README.md`.)
    fn trk(id: u64, kind: &str, x: f64, score: f64, image_box: [f64; 4]) -> EvalBox {
        EvalBox {
            id,
            label: kind.to_lowercase(),
            center: [x + 0.5, 0.25, 0.0],
            size: [4.0, 2.0, 1.5],
            yaw: 0.0,
            score,
            attributes: attrs(&[(ATTR_TYPE, kind.to_string())]),
            image_box: Some(image_box),
        }
    }

    fn scene(frames: Vec<(Vec<EvalBox>, Vec<EvalBox>)>) -> Scene {
        Scene {
            name: "test".into(),
            frames: frames
                .into_iter()
                .enumerate()
                .map(|(i, (g, t))| (i as u64 * 100_000_000, g, t))
                .collect(),
        }
    }

    fn params(classes: &[&str]) -> KittiParams {
        KittiParams {
            classes: classes.iter().map(|s| s.to_string()).collect(),
            ..KittiParams::default()
        }
    }

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() < 1e-12
    }

    #[test]
    fn ignore_rules_for_ground_truth_and_tracks() {
        // One frame, Car evaluation.
        let truth = vec![
            gt(0, "Car", 10.0, 0, 0),   // A: matched by 1 -> TP
            gt(1, "Car", 20.0, 1, 0),   // B: truncated, missed -> ignored FN
            gt(2, "Car", 30.0, 0, 3),   // C: occluded, matched by 2 -> ignored TP
            gt(3, "Van", 40.0, 0, 0),   // D: neighbouring class, missed -> ignored FN
            gt(4, "Car", 50.0, 0, 0),   // E: missed -> FN
            gt(5, "Truck", 60.0, 0, 0), // not loaded at all
            dontcare([500.0, 100.0, 700.0, 300.0]),
        ];
        let tracks = vec![
            trk(1, "Car", 10.0, 1.0, IMG),
            trk(2, "Car", 30.0, 1.0, IMG),
            // Van in a Car evaluation, unmatched: ignored.
            trk(3, "Van", 70.0, 1.0, IMG),
            // 2D box exactly 25 px high: ignored.
            trk(4, "Car", 80.0, 1.0, [100.0, 100.0, 200.0, 125.0]),
            // 2D box inside the DontCare region: ignored.
            trk(5, "Car", 90.0, 1.0, [550.0, 150.0, 650.0, 250.0]),
            // Exactly half inside the DontCare region: not ignored -> FP.
            trk(6, "Car", 100.0, 1.0, [600.0, 100.0, 800.0, 300.0]),
            // An ordinary false positive.
            trk(7, "Car", 110.0, 1.0, IMG),
            // A truck track is not loaded in the Car evaluation.
            trk(8, "Truck", 120.0, 1.0, IMG),
        ];
        let r = evaluate(&[scene(vec![(truth, tracks)])], &params(&["car"]));
        let m = &r.classes["car"];
        assert_eq!(m.gt_objects, 5);
        assert_eq!(m.ignored_gt, 3);
        assert_eq!(m.tp, 2, "TP includes the ignored match of C");
        assert_eq!(m.itp, 1);
        assert_eq!(m.fn_, 1);
        assert_eq!(m.ifn, 2);
        assert_eq!(m.fp, 2);
        assert_eq!(m.ignored_tracker, 3);
        assert_eq!(m.tracker_objects, 7);
        assert_eq!(m.tracker_trajectories, 7);
        assert_eq!(
            m.gt_trajectories, 5,
            "the van's trajectory is loaded (and ignored)"
        );
        assert_eq!((m.ids, m.frag), (0, 0));
        // MOTA over the two ground truths that count (A, E): 1 - (FN 1 + FP 2) / 2.
        assert!(close(m.mota, -0.5));
        assert!(close(m.motp, IOU));
        assert!(close(m.recall, 2.0 / 3.0));
        assert!(close(m.precision, 0.5));
        // FP per devkit frame (one frame + the devkit's extra one).
        assert!(close(m.far, 1.0));
        // MT: A; ML: E; B, C, D are wholly ignored.
        assert!(close(m.mt, 0.5) && close(m.ml, 0.5) && close(m.pt, 0.0));
        // One recall point (scores [1, 1], 3 positives): MOTA -0.5 there, sMOTA clipped to 0,
        // and no positive MOTA, so the "best" threshold stays at -10000.
        assert_eq!(m.curve.len(), 1);
        assert!(close(m.curve[0].recall_point, 0.025));
        assert!(close(m.samota, 0.0));
        assert!(close(m.amota, -0.5 / 40.0));
        assert!(close(m.amotp, IOU / 40.0));
        assert_eq!(m.best_threshold, -10000.0);
    }

    #[test]
    fn pedestrian_neighbour_and_cyclist_rows() {
        let truth = vec![
            gt(0, "Pedestrian", 10.0, 0, 0),
            gt(1, "Person_sitting", 20.0, 0, 0),
            gt(2, "Cyclist", 30.0, 0, 0),
        ];
        let tracks = vec![
            trk(1, "Pedestrian", 10.0, 1.0, IMG),
            trk(2, "Person_sitting", 50.0, 1.0, IMG), // ignored in Pedestrian
            trk(3, "Cyclist", 30.0, 1.0, IMG),
            trk(4, "Van", 70.0, 1.0, IMG), // loaded by neither
        ];
        let r = evaluate(
            &[scene(vec![(truth, tracks)])],
            &params(&["pedestrian", "cyclist"]),
        );
        let p = &r.classes["pedestrian"];
        assert_eq!((p.tp, p.fp, p.fn_, p.ifn), (1, 0, 0, 1));
        assert_eq!((p.gt_objects, p.ignored_gt, p.ignored_tracker), (2, 1, 1));
        assert!(close(p.mota, 1.0));
        let c = &r.classes["cyclist"];
        assert_eq!(
            (c.tp, c.fp, c.fn_, c.gt_objects, c.tracker_objects),
            (1, 0, 0, 1, 1)
        );
        // Overall: mean of the ratios, sum of the counts.
        assert_eq!(r.overall.tp, 2);
        assert!(close(r.overall.mota, 1.0));
        assert!(close(r.overall.samota, (p.samota + c.samota) / 2.0));
    }

    #[test]
    fn id_switches_and_fragmentations_along_trajectories() {
        let f = |g: Vec<EvalBox>, t: Vec<EvalBox>| (g, t);
        let frames = vec![
            f(
                vec![
                    gt(0, "Car", 10.0, 0, 0),
                    gt(1, "Car", 20.0, 0, 0),
                    gt(2, "Car", 30.0, 0, 0),
                    gt(3, "Car", 40.0, 0, 0),
                ],
                vec![
                    trk(1, "Car", 10.0, 1.0, IMG),
                    trk(3, "Car", 20.0, 1.0, IMG),
                    trk(4, "Car", 30.0, 1.0, IMG),
                    trk(6, "Car", 40.0, 1.0, IMG),
                ],
            ),
            f(
                vec![
                    gt(0, "Car", 10.0, 0, 0),
                    gt(1, "Car", 20.0, 0, 0),
                    gt(2, "Car", 30.0, 0, 0),
                    gt(3, "Car", 40.0, 0, 3), // occluded: an ignored frame
                ],
                vec![
                    trk(1, "Car", 10.0, 1.0, IMG),
                    trk(3, "Car", 20.0, 1.0, IMG),
                    trk(6, "Car", 40.0, 1.0, IMG),
                ],
            ),
            f(
                vec![
                    gt(0, "Car", 10.0, 0, 0),
                    gt(1, "Car", 20.0, 0, 0),
                    gt(2, "Car", 30.0, 0, 0),
                    gt(3, "Car", 40.0, 0, 0),
                ],
                vec![
                    trk(2, "Car", 10.0, 1.0, IMG),
                    trk(5, "Car", 30.0, 1.0, IMG),
                    trk(7, "Car", 40.0, 1.0, IMG),
                ],
            ),
            f(
                vec![gt(0, "Car", 10.0, 0, 0), gt(1, "Car", 20.0, 0, 0)],
                vec![trk(2, "Car", 10.0, 1.0, IMG), trk(3, "Car", 20.0, 1.0, IMG)],
            ),
        ];
        let r = evaluate(&[scene(frames)], &params(&["car"]));
        let m = &r.classes["car"];
        // GT 0: tracks [1, 1, 2, 2] -> 1 switch, 1 fragmentation.
        // GT 1: [3, 3, -, 3] -> a gap: 1 fragmentation, no switch.
        // GT 2: [4, -, 5] -> a new id after a gap: a fragmentation but no switch.
        // GT 3: [6, 6 (ignored), 7] -> a new id after an ignored frame: a fragmentation only.
        assert_eq!(m.ids, 1);
        assert_eq!(m.frag, 4);
        assert_eq!((m.tp, m.itp, m.fn_, m.fp), (12, 1, 2, 0));
        // 13 ground truths count: MOTA = 1 - (FN 2 + FP 0 + IDS 1) / 13.
        assert!(close(m.mota, 10.0 / 13.0));
        // Coverage: GT 0 4/4 and GT 3 2/2 mostly tracked; GT 1 3/4 and GT 2 2/3 partly.
        assert!(close(m.mt, 0.5) && close(m.pt, 0.5) && close(m.ml, 0.0));
        assert_eq!(m.best_threshold, 1.0);
        // Twelve equal scores over 14 positives: every match is a recall point, the first
        // dropped, so 11 points with sMOTA 1 (MOTA 10/13 is above every point's recall).
        assert_eq!(m.curve.len(), 11);
        assert!(close(m.samota, 11.0 / 40.0));
        assert!(close(m.amota, 11.0 * (10.0 / 13.0) / 40.0));
    }

    #[test]
    fn ids_repeated_in_another_log_are_other_objects() {
        // Two logs whose ids both start at 0: GT 0 and 1 in each, track 1 on GT 0 in the first
        // log (score 0.9) and on GT 1 in the second (score 0.1). Four trajectories, two mostly
        // tracked and two mostly lost; each track's mean score is its own log's.
        let frames = |tracked: i64, score: f64| -> Vec<(Vec<EvalBox>, Vec<EvalBox>)> {
            (0..4)
                .map(|_| {
                    let x = if tracked == 0 { 10.0 } else { 20.0 };
                    (
                        vec![gt(0, "Car", 10.0, 0, 0), gt(1, "Car", 20.0, 0, 0)],
                        vec![trk(1, "Car", x, score, IMG)],
                    )
                })
                .collect()
        };
        let r = evaluate(
            &[scene(frames(0, 0.9)), scene(frames(1, 0.1))],
            &params(&["car"]),
        );
        let m = &r.classes["car"];
        assert_eq!((m.tp, m.fn_, m.ids, m.frag), (8, 8, 0, 0));
        assert!(close(m.mt, 0.5) && close(m.ml, 0.5) && close(m.pt, 0.0));
        assert!(close(m.best_threshold, 0.1), "{}", m.best_threshold);
    }

    #[test]
    fn whole_trajectories_are_filtered_by_their_mean_score() {
        // GT 0 in four frames, matched by track 1 with scores averaging 0.5 (one box below);
        // GT 1 in the first two frames, matched by track 3 (mean 0.125); track 2 is a false
        // positive in every frame (mean 0.25).
        let s1 = [0.75, 0.5, 0.25, 0.5];
        let frames: Vec<_> = (0..4)
            .map(|i| {
                let mut g = vec![gt(0, "Car", 10.0, 0, 0)];
                let mut t = vec![
                    trk(1, "Car", 10.0, s1[i], IMG),
                    trk(2, "Car", 50.0, 0.25, IMG),
                ];
                if i < 2 {
                    g.push(gt(1, "Car", 20.0, 0, 0));
                    t.push(trk(3, "Car", 20.0, 0.125, IMG));
                }
                (g, t)
            })
            .collect();
        let r = evaluate(&[scene(frames)], &params(&["car"]));
        let m = &r.classes["car"];
        // Matched scores: 0.5 x4, 0.125 x2 over 6 positives -> the recall walk takes
        // [0.5, 0.5, 0.5, 0.5, 0.125, 0.125] and drops the first.
        let th: Vec<f64> = m.curve.iter().map(|c| c.threshold).collect();
        assert_eq!(th, vec![0.5, 0.5, 0.5, 0.125, 0.125]);
        let rec: Vec<f64> = m.curve.iter().map(|c| c.recall_point).collect();
        for (a, b) in rec.iter().zip([0.025, 0.05, 0.075, 0.1, 0.125]) {
            assert!(close(*a, b));
        }
        // At 0.5 track 1 is kept whole (4 TP; its 0.25 box too), tracks 2 and 3 dropped.
        let c = &m.curve[0];
        assert_eq!((c.tp, c.fp, c.fn_), (4, 0, 2));
        assert!(close(c.mota, 1.0 - 2.0 / 6.0));
        // At 0.125 everything is kept: 4 false positives.
        let c = &m.curve[3];
        assert_eq!((c.tp, c.fp, c.fn_), (6, 4, 0));
        assert!(close(c.mota, 1.0 - 4.0 / 6.0));
        // Best MOTA at 0.5.
        assert_eq!(m.best_threshold, 0.5);
        assert_eq!((m.tp, m.fp, m.fn_, m.tracker_objects), (4, 0, 2, 4));
        assert!(close(m.mt, 0.5) && close(m.ml, 0.5));
        // sMOTA is 1 at the five low recall points; the 35 points never reached count 0.
        assert!(close(m.samota, 5.0 / 40.0));
        assert!(close(
            m.amota,
            (3.0 * (4.0 / 6.0) + 2.0 * (2.0 / 6.0)) / 40.0
        ));
    }

    #[test]
    fn a_class_without_tracks_is_not_evaluated() {
        let frames = vec![(
            vec![gt(0, "Car", 10.0, 0, 0), gt(1, "Pedestrian", 20.0, 0, 0)],
            vec![trk(1, "Car", 10.0, 1.0, IMG)],
        )];
        let r = evaluate(&[scene(frames)], &KittiParams::default());
        assert_eq!(r.classes.keys().collect::<Vec<_>>(), vec!["car"]);
        assert_eq!(r.notes.len(), 2, "{:?}", r.notes);
        assert_eq!(r.overall.tp, 1);
    }

    #[test]
    fn a_class_without_ground_truth_is_left_out_of_overall() {
        // A cyclist track but no cyclist: the class is evaluated (as the reference does), with
        // MOTA -inf, but the overall numbers are those of Car alone.
        let frames = vec![(
            vec![gt(0, "Car", 10.0, 0, 0)],
            vec![
                trk(1, "Car", 10.0, 1.0, IMG),
                trk(2, "Cyclist", 40.0, 1.0, IMG),
            ],
        )];
        let r = evaluate(&[scene(frames)], &params(&["car", "cyclist"]));
        let c = &r.classes["cyclist"];
        assert_eq!(c.mota, f64::NEG_INFINITY);
        assert_eq!((c.fp, c.samota), (1, 0.0));
        let car_alone = KittiMetrics::overall([&r.classes["car"]].into_iter());
        assert_eq!(
            serde_json::to_value(&r.overall).unwrap(),
            serde_json::to_value(&car_alone).unwrap()
        );
        assert!(r.notes[0].contains("left out of overall"), "{:?}", r.notes);
        let json = serde_json::to_value(&r).unwrap();
        assert!(json["classes"]["cyclist"]["MOTA"].is_null());
    }

    #[test]
    fn duplicate_track_ids_in_a_frame_skip_the_class() {
        let frames = vec![(
            vec![gt(0, "Car", 10.0, 0, 0)],
            vec![trk(1, "Car", 10.0, 1.0, IMG), trk(1, "Car", 30.0, 1.0, IMG)],
        )];
        let r = evaluate(&[scene(frames)], &params(&["car"]));
        assert!(r.classes.is_empty());
        assert!(r.notes[0].contains("twice"), "{:?}", r.notes);
    }

    #[test]
    fn iou_threshold_gates_matches() {
        // Shifted by 2 m along the 4 m length and 0.25 m across: IoU = 3.5 / (16 - 3.5).
        let frames = vec![(
            vec![gt(0, "Car", 10.0, 0, 0)],
            vec![trk(1, "Car", 11.5, 1.0, IMG)],
        )];
        let s = [scene(frames)];
        let m = &evaluate(&s, &params(&["car"])).classes["car"];
        assert_eq!((m.tp, m.fp, m.fn_), (1, 0, 0));
        assert!((m.motp - 0.28).abs() < 1e-12);
        let strict = KittiParams {
            min_overlap: 0.5,
            ..params(&["car"])
        };
        let m = &evaluate(&s, &strict).classes["car"];
        assert_eq!((m.tp, m.fp, m.fn_), (0, 1, 1));
    }

    #[test]
    fn thresholds_walk_the_recall_points() {
        let (th, rec) = thresholds(&[1.0, 1.0], 3, 40);
        assert_eq!(th, vec![1.0]);
        assert_eq!(rec, vec![0.025]);
        // Forty matches of 400 positives: a point (every 10 matches) is taken at the score
        // whose recall is the closest to it, the 10th, 20th, 30th and 40th highest.
        let scores: Vec<f64> = (0..40).map(|i| i as f64).collect();
        let (th, rec) = thresholds(&scores, 400, 40);
        assert_eq!(th, vec![30.0, 20.0, 10.0, 0.0]);
        assert!(close(rec[3], 0.1));
        assert!(thresholds(&[], 0, 40).0.is_empty());
    }

    fn brute_force(cost: &[f64], n: usize) -> f64 {
        fn go(cost: &[f64], n: usize, row: usize, used: &mut Vec<bool>) -> f64 {
            if row == n {
                return 0.0;
            }
            let mut best = f64::INFINITY;
            for j in 0..n {
                if !used[j] {
                    used[j] = true;
                    best = best.min(cost[row * n + j] + go(cost, n, row + 1, used));
                    used[j] = false;
                }
            }
            best
        }
        go(cost, n, 0, &mut vec![false; n])
    }

    #[test]
    fn munkres_finds_minimum_cost_assignments() {
        // Deterministic pseudo-random square matrices with ties and forbidden pairs.
        let mut state = 12345u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 33) as f64 / (1u64 << 31) as f64
        };
        for n in 1..=5 {
            for _ in 0..50 {
                let cost: Vec<f64> = (0..n * n)
                    .map(|_| {
                        let v = next();
                        if v > 0.8 {
                            MAX_COST
                        } else {
                            (v * 8.0).floor() / 8.0
                        }
                    })
                    .collect();
                let pairs = munkres(&cost, n, n);
                assert_eq!(pairs.len(), n);
                let total: f64 = pairs.iter().map(|&(i, j)| cost[i * n + j]).sum();
                assert_eq!(total, brute_force(&cost, n), "{cost:?}");
            }
        }
        // Rectangular: the classic example, padded with zeros.
        let c = [
            400.0, 150.0, 400.0, 1.0, 400.0, 450.0, 600.0, 2.0, 300.0, 225.0, 300.0, 3.0,
        ];
        let pairs = munkres(&c, 3, 4);
        assert_eq!(pairs, vec![(0, 1), (1, 3), (2, 2)]);
        assert!(munkres(&[], 0, 3).is_empty());
    }
}
