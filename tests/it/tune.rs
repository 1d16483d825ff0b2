//! `probmot tune`: the search on tiny synthetic logs in memory (fast). The command line and
//! the cross-validation on the shared KITTI data are in `tune_cli.rs`.

use crate::common;

use probmot::eval::columns::ColumnScene;
use probmot::eval::kitti::MeanScores;
use probmot::eval::kitti_box::{KittiBox, KittiNames};
use probmot::mcapio::LabelledBox;
use probmot::pipeline::progress::no_progress;
use probmot::tracker::{Box3, TrackerConfig};
use probmot::tune::data::{TuneDet, TuneFrame};
use probmot::tune::score::{score_class, single_class, track_log};
use probmot::tune::{
    cross_validate, overall, tune, Protocol, Scoring, SearchLimits, TuneLog, TuneOptions,
};

const PERIOD: u64 = 500_000_000;

fn truth(id: u64, x: f64, y: f64) -> LabelledBox {
    LabelledBox {
        id,
        label: "car".into(),
        center: [x, y, 0.8],
        size: [4.5, 1.9, 1.6],
        score: 1.0,
        ..Default::default()
    }
}

fn det(x: f64, y: f64, score: f64) -> TuneDet {
    TuneDet {
        label: "car".into(),
        bbox: Box3 {
            center: [x, y, 0.8],
            yaw: 0.0,
            size: [4.5, 1.9, 1.6],
        },
        score,
        image_box: None,
    }
}

/// Deterministic pseudo-random numbers in [0, 1).
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Frame `i` of a synthetic log (stamps every [`PERIOD`]), with truth and detections to add.
fn frame(i: u64) -> TuneFrame {
    TuneFrame {
        stamp: (i + 1) * PERIOD,
        has_truth: true,
        has_detections: true,
        ..Default::default()
    }
}

/// A log of `frames` named `name`, nothing skipped.
fn named_log(name: String, frames: Vec<TuneFrame>) -> TuneLog {
    TuneLog {
        name,
        frames,
        skipped_detections: Default::default(),
    }
}

/// Three cars driving along x at 5 m/s, detected every frame (small noise, score ~0.8) and
/// each also detected a second time half a metre off with a low score (a duplicate the base
/// config turns into a false track), plus low-scoring clutter.
fn synthetic_log(seed: u64) -> TuneLog {
    let mut rng = Lcg(seed);
    let frames = (0..30u64)
        .map(|i| {
            let mut f = frame(i);
            for car in 0..3u64 {
                let (x, y) = (2.5 * i as f64 + 10.0 * car as f64, 6.0 * car as f64);
                f.truth.push(KittiBox::from(&truth(car + 1, x, y)));
                let n = |r: &mut Lcg| 0.2 * (r.next() - 0.5);
                f.detections.push(det(
                    x + n(&mut rng),
                    y + n(&mut rng),
                    0.7 + 0.2 * rng.next(),
                ));
                f.detections
                    .push(det(x + 0.5, y + 0.3, 0.2 + 0.1 * rng.next()));
            }
            let (cx, cy) = (100.0 * rng.next() - 50.0, 100.0 * rng.next() - 50.0);
            f.detections.push(det(cx, cy, 0.3 * rng.next()));
            f
        })
        .collect();
    named_log(format!("synthetic_{seed}"), frames)
}

fn options(budget: usize) -> TuneOptions {
    TuneOptions {
        scoring: Scoring {
            protocol: Protocol::Nuscenes,
            iou: 0.25,
            search_means: MeanScores::Once,
        },
        limits: SearchLimits {
            budget,
            rounds: 2,
            margin: 0.0,
            min_tracks: 1,
            ..SearchLimits::default()
        },
        dt_nominal: None,
        min_samples: 10,
        classes: vec![],
        search: vec![],
        keep_base: vec![],
    }
}

#[test]
fn search_beats_the_base_on_synthetic_logs_and_is_deterministic() {
    let logs: Vec<TuneLog> = (1..=2).map(synthetic_log).collect();
    let refs: Vec<&TuneLog> = logs.iter().collect();
    let base = TrackerConfig::preset("nuscenes-chiu2019").unwrap();
    let o = options(40);
    let run = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| tune(&base, &refs, &o, &no_progress).unwrap())
    };
    let a = run(1);
    let b = run(2);
    assert_eq!(
        a.tuned, b.tuned,
        "the result depends on the number of threads"
    );
    assert_eq!(a.classes.len(), 1);
    let car = &a.classes[0];
    assert!(car.evaluations <= 40);
    // The duplicates cost the base config precision; some lever (NMS, birth score, score floor,
    // min_hits) removes them.
    assert!(
        car.score > car.base_score + 0.01,
        "tuned {} vs base {}",
        car.score,
        car.base_score
    );
    assert!(!car.steps.is_empty());
    // The tuned config is valid and differs from the fitted one only in the car entry.
    a.tuned.validate().unwrap();
    assert_ne!(a.tuned.classes["car"], a.fitted.classes["car"]);
    assert_eq!(a.tuned.classes["bus"], a.fitted.classes["bus"]);
}

#[test]
fn classes_with_too_few_trajectories_keep_the_base_settings() {
    let logs: Vec<TuneLog> = (1..=2).map(synthetic_log).collect();
    let refs: Vec<&TuneLog> = logs.iter().collect();
    assert_eq!(probmot::tune::trajectories(&refs, "car"), 6);
    let base = TrackerConfig::preset("nuscenes-chiu2019").unwrap();
    let mut o = options(20);
    // Six car trajectories: under 7 the class is not searched and keeps the base's own
    // settings (noise not fitted).
    o.limits.min_tracks = 7;
    let t = tune(&base, &refs, &o, &no_progress).unwrap();
    let car = &t.classes[0];
    assert!(!car.refined && car.steps.is_empty() && car.evaluations == 0);
    assert_eq!(t.tuned.classes["car"], base.classes["car"]);
    assert_ne!(t.fitted.classes["car"], base.classes["car"]);
    // At 6 it is searched.
    o.limits.min_tracks = 6;
    let t = tune(&base, &refs, &o, &no_progress).unwrap();
    assert!(t.classes[0].refined && !t.classes[0].steps.is_empty());
}

/// Cars (and one truck) that leave the scene mid-log: the tracker keeps coasting past each
/// object's last detection, so the predictions after it are false positives.
fn leaving_log(seed: u64) -> TuneLog {
    let mut rng = Lcg(seed);
    let visible = |k: u64, i: u64| (4 * k..4 * k + 12).contains(&i);
    let frames = (0..30u64)
        .map(|i| {
            let mut f = frame(i);
            for k in 0..5u64 {
                let n = |r: &mut Lcg| 0.4 * (r.next() - 0.5);
                // Jitter in the true path too, so that the fitted process noise can track it.
                let (x, y) = (2.5 * i as f64 + n(&mut rng), 6.0 * k as f64 + n(&mut rng));
                let label = if k == 4 { "truck" } else { "car" };
                if visible(k, i) {
                    let mut t = truth(k + 1, x, y);
                    t.label = label.into();
                    f.truth.push(KittiBox::from(&t));
                    let (dx, dy) = (n(&mut rng), n(&mut rng));
                    let mut d = det(x + dx, y + dy, 0.6 + 0.3 * rng.next());
                    d.label = label.into();
                    f.detections.push(d);
                }
            }
            f
        })
        .collect();
    named_log(format!("leaving_{seed}"), frames)
}

/// `--pool-reporting`: the reporting options are chosen once on the searched classes (cars)
/// and reach the class with too few trajectories (the truck), whose other settings stay the
/// base's own, and the classes the logs do not hold.
#[test]
fn pooled_reporting_reaches_the_classes_that_are_not_searched() {
    use probmot::tracker::levers::Coast;
    let logs: Vec<TuneLog> = (1..=2).map(leaving_log).collect();
    let refs: Vec<&TuneLog> = logs.iter().collect();
    let base = TrackerConfig::preset("nuscenes-chiu2019").unwrap();
    let mut o = options(20);
    o.limits.min_tracks = 3;
    o.search = vec!["coast".into(), "backfill".into()];
    let plain = tune(&base, &refs, &o, &no_progress).unwrap();
    assert_eq!(plain.tuned.classes["truck"], base.classes["truck"]);
    o.limits.pool_reporting = true;
    let t = tune(&base, &refs, &o, &no_progress).unwrap();
    let (car, truck) = (&t.tuned.classes["car"], &t.tuned.classes["truck"]);
    assert_ne!(car.levers.coast, Coast::All, "{car:?}");
    assert_eq!(truck.levers.coast, car.levers.coast);
    // A class the logs do not hold gets the choice too.
    assert_eq!(t.tuned.classes["bus"].levers.coast, car.levers.coast);
    let mut own = truck.clone();
    own.levers = base.classes["truck"].levers.clone();
    assert_eq!(own, base.classes["truck"]);
    // The truck's held-out-free check: the pooled choice also scores it better here.
    let score = |cc: &probmot::tracker::ClassConfig| {
        let cfg = single_class(&base, "truck", cc.clone());
        score_class(&refs, &cfg, "truck", &o.scoring).unwrap()
    };
    assert!(score(truck) > score(&base.classes["truck"]));
}

/// `--search noise,nms_iou`: only those options move (the fitted noise of this synthetic log is
/// too tight to track with, so the choice of noise is needed for any gain).
#[test]
fn a_restricted_search_moves_only_the_named_options() {
    let logs: Vec<TuneLog> = (1..=2).map(synthetic_log).collect();
    let refs: Vec<&TuneLog> = logs.iter().collect();
    let base = TrackerConfig::preset("nuscenes-chiu2019").unwrap();
    let mut o = options(40);
    o.search = vec!["noise".into(), "nms_iou".into()];
    let t = tune(&base, &refs, &o, &no_progress).unwrap();
    let car = &t.classes[0];
    let dims: Vec<&str> = car.steps.iter().map(|s| s.dim.as_str()).collect();
    assert!(dims.contains(&"noise"), "{car:?}");
    assert!(
        dims.iter().all(|d| ["noise", "nms_iou"].contains(d)),
        "{dims:?}"
    );
    assert!(car.score > car.base_score + 0.01);
    // Apart from the noise and NMS, the tuned entry is the fitted one.
    let (mut tuned, fitted) = (t.tuned.classes["car"].clone(), &t.fitted.classes["car"]);
    (tuned.q, tuned.r, tuned.p0) = (fitted.q, fitted.r, fitted.p0);
    tuned.levers.nms_iou = None;
    assert_eq!(&tuned, fitted);
}

/// Three cars at 20 m/s, 10 m per frame at 2 Hz: past the gate of a new track, so with the
/// paper's method each detection starts a track of its own.
fn fast_log(seed: u64) -> TuneLog {
    let mut rng = Lcg(seed);
    let frames = (0..20u64)
        .map(|i| {
            let mut f = frame(i);
            for car in 0..3u64 {
                let (x, y) = (10.0 * i as f64 - 30.0 * car as f64, 8.0 * car as f64);
                f.truth.push(KittiBox::from(&truth(car + 1, x, y)));
                let n = |r: &mut Lcg| 0.2 * (r.next() - 0.5);
                f.detections
                    .push(det(x + n(&mut rng), y + n(&mut rng), 0.8));
            }
            f
        })
        .collect();
    named_log(format!("fast_{seed}"), frames)
}

/// `two_point_speed` is searched when `--search` names it, and then keeps fast cars in one
/// track; the default search leaves it off.
#[test]
fn two_point_speed_is_searched_when_named() {
    let logs: Vec<TuneLog> = (1..=2).map(fast_log).collect();
    let refs: Vec<&TuneLog> = logs.iter().collect();
    let base = TrackerConfig::preset("nuscenes-chiu2019").unwrap();
    let mut o = options(40);
    o.search = vec!["two_point_speed".into()];
    let t = tune(&base, &refs, &o, &no_progress).unwrap();
    let car = &t.classes[0];
    let dims: Vec<&str> = car.steps.iter().map(|s| s.dim.as_str()).collect();
    assert_eq!(dims, ["two_point_speed"], "{car:?}");
    let speed = t.tuned.classes["car"].levers.two_point_speed;
    assert!(speed.is_some_and(|v| v >= 20.0), "{speed:?}");
    assert!(car.score > car.base_score + 0.5, "{car:?}");

    o.search.clear();
    let t = tune(&base, &refs, &o, &no_progress).unwrap();
    assert!(t.classes[0]
        .steps
        .iter()
        .all(|s| s.dim != "two_point_speed"));
    assert_eq!(t.tuned.classes["car"].levers.two_point_speed, None);
}

#[test]
fn a_move_needs_more_than_the_margin() {
    let logs: Vec<TuneLog> = (1..=2).map(synthetic_log).collect();
    let refs: Vec<&TuneLog> = logs.iter().collect();
    let base = TrackerConfig::preset("nuscenes-chiu2019").unwrap();
    let mut o = options(40);
    let free = tune(&base, &refs, &o, &no_progress).unwrap();
    assert!(!free.classes[0].steps.is_empty());
    // AMOTA lies in [0, 1]: with a margin of 1 no move can be accepted, and the search stays
    // at the fitted base.
    o.limits.margin = 1.0;
    let t = tune(&base, &refs, &o, &no_progress).unwrap();
    assert!(t.classes[0].steps.is_empty(), "{:?}", t.classes[0].steps);
    assert_eq!(t.tuned.classes["car"], t.fitted.classes["car"]);
}

#[test]
fn shared_stage_moves_every_class_together() {
    let logs: Vec<TuneLog> = (1..=2).map(synthetic_log).collect();
    let refs: Vec<&TuneLog> = logs.iter().collect();
    let base = TrackerConfig::preset("nuscenes-chiu2019").unwrap();
    let mut o = options(30);
    o.limits.shared = true;
    let t = tune(&base, &refs, &o, &no_progress).unwrap();
    assert_eq!(t.shared.classes, vec!["car".to_string()]);
    assert!(
        t.shared.score > t.shared.base_score && !t.shared.steps.is_empty(),
        "{:?}",
        t.shared
    );
    assert!((t.classes[0].shared_score - t.shared.score).abs() < 1e-12);
    assert!(t.classes[0].score >= t.classes[0].shared_score);
}

#[test]
fn cross_validation_scores_held_out_logs() {
    let logs: Vec<TuneLog> = (1..=4).map(synthetic_log).collect();
    let base = TrackerConfig::preset("nuscenes-chiu2019").unwrap();
    let cv = cross_validate(&base, &logs, 2, &options(25), &no_progress).unwrap();
    assert_eq!(cv.folds.len(), 2);
    assert_eq!(cv.folds[0].held_out, vec!["synthetic_1", "synthetic_2"]);
    assert_eq!(cv.folds[1].held_out, vec!["synthetic_3", "synthetic_4"]);
    // The duplicates are systematic, so what is learnt on one fold carries to the other.
    assert!(overall(&cv.tuned) > overall(&cv.base));
    // Each held-out gain carries its paired interval; its values are the table's.
    let g = &cv.gains["overall"];
    assert!(
        (g.delta - (overall(&cv.tuned) - overall(&cv.base))).abs() < 1e-9,
        "{g:?}"
    );
    assert!(g.ci95[0] <= g.ci95[1], "{g:?}");
    for (c, gain) in cv.gains.iter().filter(|(c, _)| *c != "overall") {
        assert!((gain.this - cv.tuned[c]).abs() < 1e-9, "{c}: {gain:?}");
        assert!((gain.baseline - cv.base[c]).abs() < 1e-9, "{c}: {gain:?}");
    }
    assert!(cross_validate(&base, &logs[..1], 2, &options(5), &no_progress).is_err());
}

/// Scoring one class on the truth prepared for it (in columns: its boxes, and those of other
/// classes that share an id with them) gives the nuScenes score of the whole truth, to the bit.
/// Truth id 3 is a car, then a truck for two frames, then a car again: the evaluation fills
/// gaps by id across classes, so those two frames hold no interpolated car, and the car
/// detections there are false positives.
#[test]
fn nuscenes_class_score_on_the_prepared_truth_equals_the_full_truth() {
    let mut logs: Vec<TuneLog> = (1..=2).map(synthetic_log).collect();
    for f in logs[0].frames.iter_mut() {
        let i = f.stamp / PERIOD - 1;
        let b = f.truth.iter_mut().find(|b| b.id == 3).unwrap();
        if (10..12).contains(&i) {
            b.names = KittiNames::new("truck", "truck");
        }
        // A pedestrian that no car shares an id with.
        f.truth.push(KittiBox::from(&LabelledBox {
            label: "pedestrian".into(),
            ..truth(40, -20.0, 3.0 + 0.1 * i as f64)
        }));
    }
    let refs: Vec<&TuneLog> = logs.iter().collect();
    let base = TrackerConfig::preset("nuscenes-chiu2019").unwrap();
    let scoring = options(1).scoring;
    let cfg = single_class(&base, "car", base.class("car").unwrap().clone());
    let full: Vec<_> = refs.iter().map(|l| track_log(l, &cfg).unwrap()).collect();
    let p = probmot::eval::nuscenes::NuscenesParams {
        classes: vec!["car".into()],
        ..Default::default()
    };
    let full: Vec<ColumnScene> = full.iter().map(ColumnScene::from_scene).collect();
    let want = probmot::eval::nuscenes::evaluate_columns(&full, &p).classes["car"].amota;
    let got = score_class(&refs, &cfg, "car", &scoring).unwrap();
    assert_eq!(got.to_bits(), want.to_bits(), "{got} vs {want}");
    assert!(want > 0.3 && want < 1.0, "{want}");
}

/// Detections `track` would skip are left out of the tune too, counted, and named in a warning.
#[test]
fn skipped_detections_are_counted_and_named() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.mcap");
    common::city_with_bad_boxes(&bad);
    let log = TuneLog::load(&bad, "/ground_truth", "/detections").unwrap();
    let good = TuneLog::load(
        &common::repo("sample_logs/city.mcap"),
        "/ground_truth",
        "/detections",
    );
    let count = |l: &TuneLog| l.frames.iter().map(|f| f.detections.len()).sum::<usize>();
    let total: u64 = log.skipped_detections.values().sum();
    assert_eq!(total, 2);
    assert_eq!(count(&log) + 2, count(&good.unwrap()));
    let out = dir.path().join("t.json");
    let (b, o) = (bad.to_str().unwrap(), out.to_str().unwrap());
    let r = common::probmot_ok(&[
        "tune",
        b,
        "-o",
        o,
        "--protocol",
        "nuscenes",
        "--folds",
        "1",
        "--budget",
        "1",
        "--json",
    ]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        err.contains(
            "bad.mcap: topic /detections: skipped 2 detection boxes: 1 (non-positive size), 1 \
             (missing centre or size), as `probmot track` skips them"
        ),
        "{err}"
    );
    let v: serde_json::Value = serde_json::from_slice(&r.stdout).unwrap();
    assert_eq!(v["warnings"].as_array().unwrap().len(), 1, "{v}");
}
