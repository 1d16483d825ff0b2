//! HOTA with a BEV centre-distance similarity, for nuScenes-style scoring: the similarity of a
//! truth box and a track box of the same class is `max(0, 1 - d / 2 m)`, `d` the distance of
//! their centres in the ground (x, y) plane (TrackEval's `_calculate_euclidean_similarity` with
//! its default zero distance of 2, which also makes alpha = 0 correspond to the devkit's 2 m
//! matching distance). Every box of the class counts (after `--max-range`, if given); each log is
//! one sequence.

use std::collections::BTreeMap;

use super::{eval_scenes_by, Evaluation, Hota, RawFrame, Whole};
use crate::eval::columns::ColumnScene;

/// Distance (m) at which the similarity reaches 0.
pub const ZERO_DISTANCE: f64 = 2.0;

/// Similarity of two BEV centres, as TrackEval computes it (`sqrt(dx^2 + dy^2)`, then
/// `max(0, 1 - d / 2)`).
pub fn centre_similarity(gt: &[f64; 3], tr: &[f64; 3]) -> f64 {
    xy_similarity(&[gt[0], gt[1]], &[tr[0], tr[1]])
}

/// [`centre_similarity`] of two ground-plane points.
fn xy_similarity(gt: &[f64; 2], tr: &[f64; 2]) -> f64 {
    let (dx, dy) = (gt[0] - tr[0], gt[1] - tr[1]);
    let d = (dx * dx + dy * dy).sqrt();
    (1.0 - d / ZERO_DISTANCE).max(0.0)
}

/// HOTA per class of `classes` (classes without any box on either side are left out).
pub fn centre_hota(
    scenes: &[ColumnScene],
    classes: &[String],
) -> (BTreeMap<String, Hota>, Vec<String>) {
    centre_hota_by(scenes, classes, &Whole)
}

/// [`centre_hota`] with each class evaluated by `how`.
pub fn centre_hota_by<E: Evaluation>(
    scenes: &[ColumnScene],
    classes: &[String],
    how: &E,
) -> (BTreeMap<String, E::Class>, Vec<String>) {
    let mut out = BTreeMap::new();
    let mut notes = Vec::new();
    for c in classes {
        let prepared = eval_scenes_by(scenes, |scene| class_frames(scene, c), how);
        match prepared {
            Ok((seqs, true)) => {
                out.insert(c.clone(), how.class(seqs));
            }
            Ok((_, false)) => {}
            Err(e) => notes.push(format!("HOTA: class {c} is not evaluated: {e}")),
        }
    }
    (out, notes)
}

/// The frames of one class of one scene: truth and track ids and the sparse similarity.
fn class_frames(scene: &ColumnScene, class: &str) -> Vec<RawFrame> {
    let Some(label) = scene.label_index(class) else {
        return vec![Default::default(); scene.stamps.len()];
    };
    let (gt, tr) = (&scene.truth, &scene.tracks);
    let mut g: Vec<usize> = Vec::new();
    let mut t: Vec<usize> = Vec::new();
    (0..scene.stamps.len())
        .map(|f| {
            g.clear();
            g.extend(gt.frame(f).filter(|&i| gt.label[i] == label));
            t.clear();
            t.extend(tr.frame(f).filter(|&i| tr.label[i] == label));
            let sim = g
                .iter()
                .flat_map(|&a| t.iter().map(move |&b| (a, b)))
                .map(|(a, b)| xy_similarity(&gt.xy[a], &tr.xy[b]))
                .enumerate()
                .filter(|(_, v)| *v != 0.0)
                .map(|(k, v)| (k as u32, v))
                .collect();
            (
                g.iter().map(|&i| gt.id[i] as i64).collect(),
                t.iter().map(|&i| tr.id[i] as i64).collect(),
                sim,
            )
        })
        .collect()
}
