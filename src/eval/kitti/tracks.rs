//! The tracks' side of one class's evaluation: the track rows of each scene with their mean-score
//! slots, the rules that can ignore them (fixed per row), and the feasible (ground truth, track)
//! pairs of each frame with their cost `1 - IoU3D`, computed once per set of tracks and read by
//! every threshold pass.

use std::collections::HashMap;

use rayon::prelude::*;

use super::prepare::{is_neighbour, loaded_types, overlap_share, TruthSeq};
use super::KittiParams;
use crate::eval::kitti_box::KittiFields;
use crate::eval::scene::Scene;
use crate::tracker::geometry::iou3d;
use crate::tracker::Box3;

/// What a track row is to the evaluated class.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RowKind {
    /// Of the class itself.
    Class,
    /// Of the neighbouring class (Van for Car, Person_sitting for Pedestrian): ignored when
    /// unmatched.
    Neighbour,
    /// A DontCare track row (kept, as the reference does, but not a trajectory).
    DontCare,
}

/// One track box as the KITTI evaluation of a class reads it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackRow {
    /// Index of the frame in its scene (the frames given to [`super::ClassTruth::new`]).
    pub frame: u32,
    /// Track id (-1 only for DontCare rows).
    pub id: i64,
    /// What the row is to the class.
    pub kind: RowKind,
    /// 3D box.
    pub bbox: Box3,
    /// Score (the evaluation averages it over the track).
    pub score: f64,
    /// 2D box `x1 y1 x2 y2` (of the track's last matched detection), for the ignore rules.
    pub image_box: Option<[f64; 4]>,
}

/// The rows of class `cls` in the tracks of `scene`, in frame and file order (the rows the
/// reference loads: the class, its neighbour and DontCare; ids of -1 only for DontCare).
pub fn scene_rows<B: KittiFields>(scene: &Scene<B>, cls: &str) -> Vec<TrackRow> {
    let types = loaded_types(cls);
    let mut rows = Vec::new();
    for (fi, (_, _, tracks)) in scene.frames.iter().enumerate() {
        rows.extend(
            tracks
                .iter()
                .filter_map(|b| track_row(b, cls, &types, fi as u32)),
        );
    }
    rows
}

/// What a track box of KITTI type `kind` (lower case: the `kitti_type` attribute, else the
/// label) is to the evaluation of class `cls`; `None` when the class does not load it.
pub fn row_kind(cls: &str, kind: &str) -> Option<RowKind> {
    let types = loaded_types(cls);
    types
        .iter()
        .any(|t| kind.contains(t.as_str()))
        .then(|| classify(cls, kind))
}

/// [`row_kind`] of a type the class loads.
fn classify(cls: &str, kind: &str) -> RowKind {
    if kind == "dontcare" {
        RowKind::DontCare
    } else if is_neighbour(cls, kind) {
        RowKind::Neighbour
    } else {
        RowKind::Class
    }
}

/// One evaluation box as a row of class `cls` (`types`: [`loaded_types`]).
fn track_row(b: &impl KittiFields, cls: &str, types: &[String], frame: u32) -> Option<TrackRow> {
    let kind = b.kitti_type();
    if !types.iter().any(|t| kind.contains(t.as_str())) {
        return None;
    }
    let id = b.id() as i64;
    if id == -1 && kind != "dontcare" {
        return None;
    }
    let kind = classify(cls, &kind);
    Some(TrackRow {
        frame,
        id,
        kind,
        bbox: b.box3(),
        score: b.score(),
        image_box: b.image_box(),
    })
}

/// A track row in a pass; `score` and `valid` persist across thresholds, as in the reference.
#[derive(Debug, Clone)]
pub(super) struct TrObj {
    /// Track id.
    pub id: i64,
    /// Index of the track among the scene's tracks (for its mean score).
    pub slot: u32,
    /// Ignored when unmatched and not matched before: of the neighbouring class, a 2D box at
    /// most `min_height` high, or more than half inside a DontCare region (rows without a 2D
    /// box: only the first rule).
    pub ignorable: bool,
    /// Score: the track's mean after the first pass.
    pub score: f64,
    /// Matched at some threshold already (then never ignored).
    pub valid: bool,
    /// Kept (score at least the threshold) in the last pass.
    pub kept: bool,
}

/// A (ground truth, track) pair of a frame that may match: `1 - IoU3D <= 1 - min_overlap`.
/// Every other pair costs the reference's `MAX_COST`.
#[derive(Debug, Clone, Copy)]
pub(super) struct Edge {
    /// Index in the frame's ground truth.
    pub gt: u32,
    /// Index in the frame's track rows.
    pub tr: u32,
    /// `1 - IoU3D`.
    pub cost: f64,
}

/// One scene's tracks of one class: rows and feasible pairs, both grouped by frame.
#[derive(Debug, Clone, Default)]
pub(super) struct SeqTracks {
    pub rows: Vec<TrObj>,
    /// Rows of frame `f`: `rows[row_start[f]..row_start[f + 1]]`.
    pub row_start: Vec<u32>,
    /// Feasible pairs in (ground truth, track) order.
    pub edges: Vec<Edge>,
    /// Edges of frame `f`: `edges[edge_start[f]..edge_start[f + 1]]`.
    pub edge_start: Vec<u32>,
    /// Number of distinct track ids (slots of [`TrObj::slot`]).
    pub n_tracks: usize,
}

impl SeqTracks {
    /// The rows' scores as [`prepare_tracks`] gave them (the passes replace them by means).
    pub fn scores(&self) -> Vec<f64> {
        self.rows.iter().map(|r| r.score).collect()
    }

    /// The rows as [`prepare_tracks`] left them, from their `scores` then: nothing kept or
    /// matched yet.
    pub fn restart(&mut self, scores: &[f64]) {
        for (r, &score) in self.rows.iter_mut().zip(scores) {
            (r.score, r.valid, r.kept) = (score, false, false);
        }
    }

    /// The rows and the feasible pairs of frame `f`.
    pub fn frame(&mut self, f: usize) -> (&mut [TrObj], &[Edge]) {
        let r = self.row_start[f] as usize..self.row_start[f + 1] as usize;
        let e = self.edge_start[f] as usize..self.edge_start[f + 1] as usize;
        (&mut self.rows[r], &self.edges[e])
    }
}

/// Why a class cannot be evaluated.
#[derive(Debug, Clone, PartialEq)]
pub enum Skip {
    /// No track row of the class's types.
    NoTracks,
    /// A track id twice in one frame (the reference rejects such results).
    DuplicateId {
        /// Scene name.
        scene: String,
        /// Frame index.
        frame: usize,
        /// Track id.
        id: i64,
    },
    /// Track rows for another number of scenes than the truth has, or a row's frame outside
    /// its scene.
    Mismatch(String),
}

/// The tracks of every scene against the truth's scenes: rows and feasible pairs (scenes in
/// parallel), and the number of track trajectories.
pub(super) fn prepare_tracks(
    truth: &[TruthSeq],
    tracks: &[Vec<TrackRow>],
    p: &KittiParams,
) -> Result<(Vec<SeqTracks>, u64), Skip> {
    if truth.len() != tracks.len() {
        return Err(Skip::Mismatch(format!(
            "{} scene(s) of tracks for {} scene(s) of truth",
            tracks.len(),
            truth.len()
        )));
    }
    // Collected first, so that the error reported is the first scene's whatever the threads.
    let seqs: Vec<Result<(SeqTracks, u64), Skip>> = truth
        .par_iter()
        .zip(tracks)
        .map(|(t, rows)| prepare_seq(t, rows, p))
        .collect();
    let seqs = seqs.into_iter().collect::<Result<Vec<_>, Skip>>()?;
    let n_tr_trajectories: u64 = seqs.iter().map(|(_, n)| n).sum();
    if n_tr_trajectories == 0 {
        return Err(Skip::NoTracks);
    }
    Ok((
        seqs.into_iter().map(|(s, _)| s).collect(),
        n_tr_trajectories,
    ))
}

/// One scene's rows (in frame order; sorted stably when they are not) and feasible pairs.
fn prepare_seq(
    truth: &TruthSeq,
    rows: &[TrackRow],
    p: &KittiParams,
) -> Result<(SeqTracks, u64), Skip> {
    let sorted;
    let rows = if rows.windows(2).all(|w| w[0].frame <= w[1].frame) {
        rows
    } else {
        let mut v = rows.to_vec();
        v.sort_by_key(|r| r.frame);
        sorted = v;
        &sorted
    };
    let n_frames = truth.frames.len();
    if let Some(r) = rows.last().filter(|r| r.frame as usize >= n_frames) {
        return Err(Skip::Mismatch(format!(
            "{}: a track row in frame {} of a scene of {} frames",
            truth.name,
            r.frame,
            n_frames - super::DEVKIT_EXTRA_FRAMES
        )));
    }
    let mut seq = SeqTracks {
        rows: Vec::with_capacity(rows.len()),
        row_start: Vec::with_capacity(n_frames + 1),
        edge_start: Vec::with_capacity(n_frames + 1),
        ..SeqTracks::default()
    };
    // Per track id: its slot, the last frame (+1) it was seen in, and whether it is a trajectory.
    let mut slots: HashMap<i64, (u32, u32, bool)> = HashMap::new();
    let mut n_traj = 0u64;
    let limit = 1.0 - p.min_overlap;
    let mut next = 0usize;
    for (fi, frame) in truth.frames.iter().enumerate() {
        seq.row_start.push(seq.rows.len() as u32);
        seq.edge_start.push(seq.edges.len() as u32);
        let start = next;
        while next < rows.len() && rows[next].frame as usize == fi {
            let r = &rows[next];
            next += 1;
            let n = slots.len() as u32;
            let e = slots.entry(r.id).or_insert((n, 0, false));
            if e.1 == fi as u32 + 1 {
                return Err(Skip::DuplicateId {
                    scene: truth.name.clone(),
                    frame: fi,
                    id: r.id,
                });
            }
            e.1 = fi as u32 + 1;
            if r.kind != RowKind::DontCare && !e.2 {
                e.2 = true;
                n_traj += 1;
            }
            // The 2D rules need the box in the image: a row without one (a log not imported
            // from KITTI) is never too low or inside a DontCare region, so an unmatched one
            // counts as a false positive (evaluate_class notes how many rows had none).
            let in_2d = r.image_box.is_some_and(|bbox| {
                (bbox[1] - bbox[3]).abs() <= p.min_height
                    || frame.dc.iter().any(|d| overlap_share(&bbox, d) > 0.5)
            });
            seq.rows.push(TrObj {
                id: r.id,
                slot: e.0,
                ignorable: r.kind == RowKind::Neighbour || in_2d,
                score: r.score,
                valid: false,
                kept: false,
            });
        }
        for (gi, g) in frame.boxes.iter().enumerate() {
            for (k, r) in rows[start..next].iter().enumerate() {
                let cost = 1.0 - iou3d(g, &r.bbox);
                if cost <= limit {
                    seq.edges.push(Edge {
                        gt: gi as u32,
                        tr: k as u32,
                        cost,
                    });
                }
            }
        }
    }
    seq.row_start.push(seq.rows.len() as u32);
    seq.edge_start.push(seq.edges.len() as u32);
    seq.n_tracks = slots.len();
    Ok((seq, n_traj))
}
