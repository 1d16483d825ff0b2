//! The passes of the KITTI evaluation with each resampling unit's counts kept
//! (`eval --bootstrap`): the same passes, in the same order, as [`ClassTruth::evaluate`].

use rayon::prelude::*;

use super::pass::ClassEval;
use super::tracks::{prepare_tracks, scene_rows};
use super::{thresholds, ClassTruth, KittiFields, KittiParams, Scene, Skip, TrackRow};
use crate::eval::bootstrap::curve::{KittiCurve, UnitCounts};
use crate::eval::bootstrap::Units;

impl ClassTruth {
    /// The class's recall curve with per-unit counts for one set of tracks (as
    /// [`ClassTruth::evaluate`] takes them).
    pub fn unit_curve(&self, tracks: &[Vec<TrackRow>], units: &Units) -> Result<KittiCurve, Skip> {
        let (seqs, _) = prepare_tracks(&self.seqs, tracks, &self.p)?;
        let mut e = ClassEval::new(self, seqs, self.p.means);
        e.units = Some((units, vec![UnitCounts::default(); units.count]));
        let first = e.pass(-10000.0, 1.0, true);
        let all_tracks = take(&e);
        let (ths, recs) = thresholds(&first.scores, first.tp + first.fn_, self.p.recall_points);
        let mut passes = Vec::with_capacity(ths.len());
        for (&th, &rec) in ths.iter().zip(&recs) {
            e.pass(th, rec, false);
            passes.push((rec, take(&e)));
        }
        Ok(KittiCurve {
            passes,
            all_tracks,
            recall_points: self.p.recall_points,
        })
    }
}

/// Per evaluated class (in `p.classes` order; a class the evaluation skips is left out): its
/// curve with per-unit counts over `scenes`.
pub fn unit_curves<B: KittiFields + Sync>(
    scenes: &[Scene<B>],
    p: &KittiParams,
    units: &Units,
) -> Vec<(String, KittiCurve)> {
    let per_class: Vec<Option<(String, KittiCurve)>> = (p.classes.par_iter())
        .map(|c| {
            let c = c.to_lowercase();
            let truth = ClassTruth::of_scenes(scenes, &c, p);
            let tracks: Vec<Vec<TrackRow>> = scenes.iter().map(|s| scene_rows(s, &c)).collect();
            truth.unit_curve(&tracks, units).ok().map(|k| (c, k))
        })
        .collect();
    per_class.into_iter().flatten().collect()
}

/// The per-unit counts of the last pass.
fn take(e: &ClassEval) -> Vec<UnitCounts> {
    e.units.as_ref().map(|u| u.1.clone()).unwrap_or_default()
}
