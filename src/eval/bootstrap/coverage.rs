//! The coverage of the paired 95 % interval on simulated drives drawn from one scenario: two
//! "trackers" (the simulated detections with their true identities, and the same with one
//! detection in six dropped more) scored with the nuScenes protocol over 20 drives at a time.
//! The true change is the mean of the point changes over all pairs (the Monte Carlo value of
//! what each pair estimates); the interval should hold it in about 95 % of the pairs.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use super::curve::{nuscenes_metrics, NuscenesCurve, NUSCENES_METRICS};
use super::{changes, Options, Units};
use crate::eval::columns::ColumnScene;
use crate::eval::nuscenes::curve::unit_curves;
use crate::eval::nuscenes::NuscenesParams;
use crate::eval::scene::Scene;
use crate::mcapio::LabelledBox;
use crate::sim::scenario::objects;
use crate::sim::sensor::detect;
use crate::sim::{Scenario, SimOptions};

const PAIRS: usize = 200;
const DRIVES: usize = 20;
const FRAMES: u32 = 12;

/// One simulated drive as two runs over the same truth: the detections (true ids) and the
/// same with one in six more missed.
fn drive(seed: u64) -> (ColumnScene, ColumnScene) {
    let opts = SimOptions {
        scenario: Scenario::City,
        seed,
        frames: FRAMES,
        objects: Some(12),
        rate_hz: 2.0,
        ego_frame: false,
    };
    let objs = objects(&opts);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut drop = ChaCha8Rng::seed_from_u64(!seed);
    let (mut a, mut b) = (Scene::default(), Scene::default());
    for f in 0..FRAMES as usize {
        let stamp = f as u64 * 500_000_000;
        let truth: Vec<LabelledBox> = (objs.iter())
            .filter_map(|o| o.states[f].map(|s| (o, s)))
            .map(|(o, s)| LabelledBox {
                id: o.id,
                label: o.label.into(),
                center: s.center,
                size: o.size,
                score: 1.0,
                ..Default::default()
            })
            .collect();
        let (mut ta, mut tb) = (Vec::new(), Vec::new());
        for (k, d) in detect(Scenario::City, &objs, f, &mut rng)
            .into_iter()
            .enumerate()
        {
            let id = if d.truth_id == 0 {
                1_000_000 + (f * 1000 + k) as u64
            } else {
                d.truth_id
            };
            let t = LabelledBox {
                id,
                label: d.label.into(),
                center: d.center,
                size: d.size,
                score: d.score,
                ..Default::default()
            };
            if drop.random::<f64>() >= 1.0 / 6.0 {
                tb.push(t.clone());
            }
            ta.push(t);
        }
        a.frames.push((stamp, truth.clone(), ta));
        b.frames.push((stamp, truth, tb));
    }
    (ColumnScene::from_scene(&a), ColumnScene::from_scene(&b))
}

/// The overall AMOTA change of one pair of runs over `DRIVES` drives and its interval.
fn pair(i: usize, p: &NuscenesParams) -> (f64, [f64; 2]) {
    let (a, b): (Vec<ColumnScene>, Vec<ColumnScene>) =
        (0..DRIVES).map(|d| drive((i * DRIVES + d) as u64)).unzip();
    let stamps: Vec<&[u64]> = a.iter().map(|s| s.stamps.as_slice()).collect();
    let units = Units::logs(&stamps);
    let curves = |s: &[ColumnScene]| -> Vec<NuscenesCurve> {
        unit_curves(s, p, &units).into_iter().map(|c| c.1).collect()
    };
    let (ca, cb) = (curves(&a), curves(&b));
    let o = Options {
        resamples: 250,
        seed: i as u64,
    };
    let c = changes(
        units.count,
        o,
        |w| nuscenes_metrics(&ca, w),
        |w| nuscenes_metrics(&cb, w),
    );
    let overall_amota = &c[p.classes.len() * NUSCENES_METRICS.len()];
    (overall_amota.delta, overall_amota.ci95)
}

#[test]
fn the_paired_interval_covers_the_true_change_about_95_percent_of_the_time() {
    let p = NuscenesParams {
        classes: vec!["car".into(), "pedestrian".into()],
        ..Default::default()
    };
    let runs: Vec<(f64, [f64; 2])> = (0..PAIRS).into_par_iter().map(|i| pair(i, &p)).collect();
    let truth = runs.iter().map(|r| r.0).sum::<f64>() / PAIRS as f64;
    assert!(
        truth > 0.01,
        "the detections alone should beat the thinned ones: {truth}"
    );
    let covered = (runs.iter())
        .filter(|(_, ci)| ci[0] <= truth && truth <= ci[1])
        .count();
    let rate = covered as f64 / PAIRS as f64;
    eprintln!("coverage {rate} over {PAIRS} pairs (true change {truth})");
    assert!(
        (0.90..=0.99).contains(&rate),
        "coverage {rate} (true change {truth})"
    );
}
