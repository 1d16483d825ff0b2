//! The held-out gain of the tuned configs over the base, per class and overall, with its paired
//! bootstrap interval ([`crate::eval::bootstrap`]): the headline metric of both runs over the
//! same held-out logs, resampled alike.

use std::collections::BTreeMap;

use super::score::{Protocol, Scoring};
use crate::eval::bootstrap::curve::{kitti_metrics, nuscenes_metrics, KittiCurve, NuscenesCurve};
use crate::eval::bootstrap::{changes, Change, Options, Units};
use crate::eval::columns::ColumnScene;
use crate::eval::kitti::{self, KittiParams, MeanScores};
use crate::eval::kitti_box::KittiBox;
use crate::eval::nuscenes::{self, NuscenesParams};
use crate::eval::scene::Scene;

/// Resamples of the held-out gains.
pub const RESAMPLES: usize = 1000;

/// Per class of `classes` with a value, then `overall`: the change `tuned - base` of the
/// headline metric with its 95 % interval (logs resampled when there are 20 or more, else
/// 10-s blocks; seed 0).
pub fn gains(
    scoring: &Scoring,
    (base, tuned): (&[Scene<KittiBox>], &[Scene<KittiBox>]),
    classes: &[String],
) -> BTreeMap<String, Change> {
    let stamps = |s: &[Scene<KittiBox>]| -> Vec<Vec<u64>> {
        (s.iter())
            .map(|s| s.frames.iter().map(|f| f.0).collect())
            .collect()
    };
    let (sb, st) = (stamps(base), stamps(tuned));
    let runs: Vec<Vec<&[u64]>> = [&sb, &st]
        .iter()
        .map(|r| r.iter().map(Vec::as_slice).collect())
        .collect();
    let units = Units::choose_paired(&runs, None);
    let o = Options {
        resamples: RESAMPLES,
        seed: 0,
    };
    let (rows, all) = match scoring.protocol {
        Protocol::Kitti => {
            let p = KittiParams {
                classes: classes.to_vec(),
                min_overlap: scoring.iou,
                means: MeanScores::EveryPass,
                ..KittiParams::default()
            };
            let (cb, ct) = (
                kitti::curve::unit_curves(base, &p, &units[0]),
                kitti::curve::unit_curves(tuned, &p, &units[1]),
            );
            let rows: Vec<String> = (cb.iter().map(|c| c.0.clone()))
                .filter(|c| ct.iter().any(|t| &t.0 == c))
                .collect();
            let pick = |v: &[(String, KittiCurve)]| -> Vec<KittiCurve> {
                (rows.iter())
                    .filter_map(|r| v.iter().find(|x| &x.0 == r).map(|x| x.1.clone()))
                    .collect()
            };
            let (cb, ct) = (pick(&cb), pick(&ct));
            let f = |c: &[KittiCurve], w: &[u32]| -> Vec<f64> {
                // sAMOTA only: every third value.
                kitti_metrics(c, w).into_iter().step_by(3).collect()
            };
            (
                rows,
                changes(units[0].count, o, |w| f(&ct, w), |w| f(&cb, w)),
            )
        }
        Protocol::Nuscenes => {
            let p = NuscenesParams {
                classes: classes.to_vec(),
                ..NuscenesParams::default()
            };
            let col = |s: &[Scene<KittiBox>]| -> Vec<ColumnScene> {
                s.iter().map(ColumnScene::from_scene).collect()
            };
            let curves = |s: &[ColumnScene], u: &Units| -> Vec<NuscenesCurve> {
                (nuscenes::curve::unit_curves(s, &p, u).into_iter())
                    .map(|c| c.1)
                    .collect()
            };
            let (cb, ct) = (
                curves(&col(base), &units[0]),
                curves(&col(tuned), &units[1]),
            );
            let f = |c: &[NuscenesCurve], w: &[u32]| -> Vec<f64> {
                // AMOTA only: every fourth value.
                nuscenes_metrics(c, w).into_iter().step_by(4).collect()
            };
            (
                classes.to_vec(),
                changes(units[0].count, o, |w| f(&ct, w), |w| f(&cb, w)),
            )
        }
    };
    let names = rows.into_iter().chain(["overall".to_string()]);
    (names.zip(all))
        .filter(|(_, c)| !(c.this.is_nan() && c.baseline.is_nan()))
        .collect()
}
