//! HOTA with a BEV centre-distance similarity, for nuScenes-style scoring: the similarity of a
//! truth box and a track box of the same class is `max(0, 1 - d / 2 m)`, `d` the distance of
//! their centres in the ground (x, y) plane (TrackEval's `_calculate_euclidean_similarity` with
//! its default zero distance of 2, which also makes alpha = 0 correspond to the devkit's 2 m
//! matching distance). Every box of the class counts (after `--max-range`, if given); each log is
//! one sequence.

use std::collections::BTreeMap;

use super::{eval_scenes, Hota};
use crate::eval::scene::Scene;

/// Distance (m) at which the similarity reaches 0.
pub const ZERO_DISTANCE: f64 = 2.0;

/// Similarity of two BEV centres, as TrackEval computes it (`sqrt(dx^2 + dy^2)`, then
/// `max(0, 1 - d / 2)`).
pub fn centre_similarity(gt: &[f64; 3], tr: &[f64; 3]) -> f64 {
    let (dx, dy) = (gt[0] - tr[0], gt[1] - tr[1]);
    let d = (dx * dx + dy * dy).sqrt();
    (1.0 - d / ZERO_DISTANCE).max(0.0)
}

/// HOTA per class of `classes` (classes without any box on either side are left out).
pub fn centre_hota(scenes: &[Scene], classes: &[String]) -> (BTreeMap<String, Hota>, Vec<String>) {
    let mut out = BTreeMap::new();
    let mut notes = Vec::new();
    for c in classes {
        let prepared = eval_scenes(scenes, |scene| {
            scene
                .frames
                .iter()
                .map(|(_, g, t)| {
                    let g: Vec<_> = g.iter().filter(|b| b.label == *c).collect();
                    let t: Vec<_> = t.iter().filter(|b| b.label == *c).collect();
                    let sim = g
                        .iter()
                        .flat_map(|a| t.iter().map(|b| centre_similarity(&a.center, &b.center)))
                        .enumerate()
                        .filter(|(_, v)| *v != 0.0)
                        .map(|(k, v)| (k as u32, v))
                        .collect();
                    (
                        g.iter().map(|b| b.id as i64).collect(),
                        t.iter().map(|b| b.id as i64).collect(),
                        sim,
                    )
                })
                .collect()
        });
        match prepared {
            Ok((counts, true)) => {
                out.insert(c.clone(), Hota::from_counts(&counts));
            }
            Ok((_, false)) => {}
            Err(e) => notes.push(format!("HOTA: class {c} is not evaluated: {e}")),
        }
    }
    (out, notes)
}
