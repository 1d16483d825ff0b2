//! The nuScenes protocol's preparation of each scene: each track's mean score, the gaps of
//! truth and tracks filled by interpolation, and one class's view of the boxes, as the devkit
//! prepares them.

use std::collections::HashMap;

use crate::eval::columns::{ColumnScene, Side};
use crate::eval::numpy_compat::np_mean;

/// A box after preprocessing; `label` indexes the evaluated classes ([`NO_CLASS`]: another).
#[derive(Debug, Clone, Copy)]
pub(super) struct PBox {
    id: u64,
    label: u16,
    x: f64,
    y: f64,
    score: f64,
}

/// The label id of a box of no evaluated class.
pub(super) const NO_CLASS: u16 = u16::MAX;

/// One scene after score averaging and interpolation: its columns (read through
/// `class_of`, the evaluated class of each label, and `means`, each track's mean score) and,
/// per frame, the interpolated boxes that follow the frame's own.
pub(super) struct Prepared<'a> {
    scene: &'a ColumnScene,
    class_of: Vec<u16>,
    means: HashMap<u64, f64>,
    gt_extra: Vec<Vec<PBox>>,
    pred_extra: Vec<Vec<PBox>>,
}

/// The box at row `i` of `side` as the passes see it (`score`: the one it carries).
pub(super) fn pbox(side: &Side, class_of: &[u16], i: usize, score: f64) -> PBox {
    PBox {
        id: side.id[i],
        label: class_of[side.label[i] as usize],
        x: side.xy[i][0],
        y: side.xy[i][1],
        score,
    }
}

/// The devkit's `interpolate_tracks` on one side: the boxes that fill the gaps of every track
/// (by id, across classes) at the scene's timestamps, per frame: weight `r = (t_right - t) /
/// (t_right - t_left)` on the *right* box, class and id of the right box, in the order the
/// tracks first appear (they follow the frame's own boxes). Each track visits only the frames
/// of its own time span. `boxed(i)` is the box at row `i`.
pub(super) fn interpolate(
    ts: &[i64],
    side: &Side,
    boxed: impl Fn(usize) -> PBox,
) -> Vec<Vec<PBox>> {
    // Per track in order of first appearance: its (frame, row) positions in frame order.
    let mut index: HashMap<u64, usize> = HashMap::new();
    let mut tracks: Vec<Vec<(u32, u32)>> = Vec::new();
    for fi in 0..ts.len() {
        for row in side.frame(fi) {
            let slot = *index.entry(side.id[row]).or_insert_with(|| {
                tracks.push(Vec::new());
                tracks.len() - 1
            });
            tracks[slot].push((fi as u32, row as u32));
        }
    }
    drop(index);
    let sorted = ts.windows(2).all(|w| w[0] <= w[1]);
    let mut extra: Vec<Vec<PBox>> = vec![Vec::new(); ts.len()];
    for track in &tracks {
        let time = |i: usize| ts[track[i].0 as usize];
        let (first, last) = (time(0), time(track.len() - 1));
        let span = if sorted {
            ts.partition_point(|v| *v < first)..ts.partition_point(|v| *v <= last)
        } else {
            0..ts.len()
        };
        for fi in span {
            let t = ts[fi];
            let right = track.partition_point(|p| ts[p.0 as usize] <= t);
            let present = if sorted {
                right > 0 && time(right - 1) == t
            } else {
                track.iter().any(|p| ts[p.0 as usize] == t)
            };
            if t < first || t > last || present {
                continue;
            }
            let left = right - 1;
            let r = (time(right) - t) as f64 / (time(right) - time(left)) as f64;
            let (lb, rb) = (
                boxed(track[left].1 as usize),
                boxed(track[right].1 as usize),
            );
            extra[fi].push(PBox {
                id: rb.id,
                label: rb.label,
                x: (1.0 - r) * lb.x + r * rb.x,
                y: (1.0 - r) * lb.y + r * rb.y,
                score: (1.0 - r) * lb.score + r * rb.score,
            });
        }
    }
    extra
}

pub(super) fn prepare<'a>(scene: &'a ColumnScene, classes: &[String]) -> Prepared<'a> {
    // The devkit's timestamps are microseconds.
    let ts: Vec<i64> = scene.stamps.iter().map(|s| (s / 1000) as i64).collect();
    let class_of: Vec<u16> = scene
        .labels
        .iter()
        .map(|l| {
            classes
                .iter()
                .position(|c| c == l)
                .map_or(NO_CLASS, |i| i as u16)
        })
        .collect();
    // Each track's boxes get the track's mean score (np.mean, before interpolation).
    let tr = &scene.tracks;
    let mut scores: HashMap<u64, Vec<f64>> = HashMap::new();
    for (id, score) in tr.id.iter().zip(&tr.score) {
        scores.entry(*id).or_default().push(*score);
    }
    let means: HashMap<u64, f64> = scores.iter().map(|(k, v)| (*k, np_mean(v))).collect();
    drop(scores);
    let gt = &scene.truth;
    let gt_extra = interpolate(&ts, gt, |i| pbox(gt, &class_of, i, gt.score[i]));
    let pred_extra = interpolate(&ts, tr, |i| pbox(tr, &class_of, i, means[&tr.id[i]]));
    Prepared {
        scene,
        class_of,
        means,
        gt_extra,
        pred_extra,
    }
}

/// One scene restricted to one class: per frame, `(id, x, y)` of the truth and
/// `(id, x, y, score)` of the tracks, in the devkit's box order.
pub(super) struct ClassScene {
    pub(super) gt: Vec<Vec<(u64, f64, f64)>>,
    pub(super) pred: Vec<Vec<(u64, f64, f64, f64)>>,
}

pub(super) fn class_view(p: &Prepared, class: u16) -> ClassScene {
    let s = p.scene;
    let (gt, tr) = (&s.truth, &s.tracks);
    let of_class = |side: &Side, i: usize| p.class_of[side.label[i] as usize] == class;
    let frames = 0..s.stamps.len();
    ClassScene {
        gt: frames
            .clone()
            .map(|f| {
                gt.frame(f)
                    .filter(|&i| of_class(gt, i))
                    .map(|i| (gt.id[i], gt.xy[i][0], gt.xy[i][1]))
                    .chain(
                        p.gt_extra[f]
                            .iter()
                            .filter(|b| b.label == class)
                            .map(|b| (b.id, b.x, b.y)),
                    )
                    .collect()
            })
            .collect(),
        pred: frames
            .map(|f| {
                tr.frame(f)
                    .filter(|&i| of_class(tr, i))
                    .map(|i| (tr.id[i], tr.xy[i][0], tr.xy[i][1], p.means[&tr.id[i]]))
                    .chain(
                        p.pred_extra[f]
                            .iter()
                            .filter(|b| b.label == class)
                            .map(|b| (b.id, b.x, b.y, b.score)),
                    )
                    .collect()
            })
            .collect(),
    }
}
