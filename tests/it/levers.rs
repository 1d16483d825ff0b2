//! The per-class options beyond the paper, each shown to change what it should (and nothing when
//! off), through the public tracker API.

use probmot::tracker::levers::{Coast, Levers, Motion, ScoreMode};
use probmot::tracker::{Box3, Detection, Lookback, Tracker, TrackerConfig};
use proptest::prelude::*;

const DT: u64 = 100_000_000;

fn config(levers: Levers) -> TrackerConfig {
    let mut cfg = TrackerConfig::preset("nuscenes-chiu2019").unwrap();
    cfg.dt_nominal = 0.1;
    cfg.for_each_class(|c| {
        c.min_hits = 1;
        c.max_age = 2;
        c.levers = levers.clone();
    });
    cfg
}

fn car(x: f64, score: f64) -> Detection {
    Detection {
        bbox: Box3 {
            center: [x, 0.0, 0.0],
            yaw: 0.0,
            size: [4.0, 2.0, 1.5],
        },
        class: 0,
        score,
    }
}

/// Runs frames of detections; per frame the `(id, score)` of every reported track.
fn run(cfg: TrackerConfig, frames: &[Vec<Detection>]) -> (Vec<Vec<(u64, f64)>>, Tracker) {
    let mut t = Tracker::new(cfg).unwrap();
    let c = t.class_id("car").unwrap();
    let mut out = vec![];
    for (i, f) in frames.iter().enumerate() {
        let dets: Vec<Detection> = f.iter().map(|d| Detection { class: c, ..*d }).collect();
        let r = t.step(i as u64 * DT, &dets).unwrap();
        out.push(r.iter().map(|r| (r.id, r.score)).collect());
    }
    (out, t)
}

#[test]
fn old_configs_load_and_presets_keep_their_json() {
    let cfg = TrackerConfig::preset("nuscenes-chiu2019").unwrap();
    assert!(cfg.classes.values().all(|c| c.levers.is_off()));
    // Off levers are not written, so configs written before the levers existed read back equal.
    assert!(!cfg.to_json().contains("levers"));
    let mut on = cfg.clone();
    on.for_each_class(|c| c.levers.score = ScoreMode::Mean);
    let back = TrackerConfig::from_json(&on.to_json()).unwrap();
    assert_eq!(back, on);
}

#[test]
fn invalid_levers_are_refused() {
    let mut cfg = config(Levers {
        keep_score: Some(0.5),
        ..Levers::default()
    });
    assert!(cfg.validate().unwrap_err().0.contains("decay"));
    cfg.for_each_class(|c| c.levers.decay = 0.1);
    cfg.validate().unwrap();
    cfg.for_each_class(|c| c.levers.nms_iou = Some(1.5));
    assert!(cfg.validate().is_err());
}

#[test]
fn reported_score_modes() {
    let frames = vec![
        vec![car(0.0, 0.2)],
        vec![car(0.0, 0.6)],
        vec![car(0.0, 0.4)],
    ];
    let last = run(config(Levers::default()), &frames).0;
    assert_eq!(last[2], vec![(1, 0.4)]);
    let mean = run(
        config(Levers {
            score: ScoreMode::Mean,
            ..Levers::default()
        }),
        &frames,
    )
    .0;
    assert!((mean[2][0].1 - 0.4).abs() < 1e-12 && (mean[1][0].1 - 0.4).abs() < 1e-12);
    // Refined with blend 0.5 and boost 0.1: 0.2 -> 0.2+0.2+0.1 = 0.5 -> 0.5-0.05+0.1 = 0.55.
    let refined = run(
        config(Levers {
            score: ScoreMode::Refined,
            blend: 0.5,
            boost: 0.1,
            ..Levers::default()
        }),
        &frames,
    )
    .0;
    assert!((refined[1][0].1 - 0.5).abs() < 1e-12);
    assert!((refined[2][0].1 - 0.55).abs() < 1e-12);
}

#[test]
fn refined_score_decays_while_coasting() {
    let frames = vec![vec![car(0.0, 0.8)], vec![]];
    let l = Levers {
        score: ScoreMode::Refined,
        decay: 0.3,
        ..Levers::default()
    };
    let r = run(config(l), &frames).0;
    assert_eq!(r[0], vec![(1, 0.8)]);
    assert!((r[1][0].1 - 0.5).abs() < 1e-12);
}

#[test]
fn two_stage_low_scores_continue_but_never_start_tracks() {
    let l = Levers {
        birth_score: Some(0.5),
        ..Levers::default()
    };
    // A low-scoring detection alone starts nothing.
    let (r, t) = run(
        config(l.clone()),
        &[vec![car(0.0, 0.3)], vec![car(0.0, 0.3)]],
    );
    assert!(r.iter().all(|f| f.is_empty()));
    assert_eq!(t.stats().born, 0);
    // A low-scoring detection continues a track started by a high-scoring one; a second low one
    // elsewhere starts nothing.
    let frames = vec![
        vec![car(0.0, 0.9)],
        vec![car(0.0, 0.3), car(30.0, 0.3)],
        vec![car(0.0, 0.3)],
    ];
    let (r, t) = run(config(l), &frames);
    assert_eq!(r[2], vec![(1, 0.3)]);
    assert_eq!(t.stats().born, 1);
    // Without the option, the far detection starts track 2.
    let (_, t) = run(config(Levers::default()), &frames);
    assert_eq!(t.stats().born, 2);
}

#[test]
fn two_stage_prefers_high_scores_in_the_first_round() {
    // Track at x=0. Frame 2: a low-score box at x=0 and a high-score box at x=0.3. With the
    // two-stage association the high-score box gets the track, the low one is dropped.
    let l = Levers {
        birth_score: Some(0.5),
        ..Levers::default()
    };
    let frames = vec![vec![car(0.0, 0.9)], vec![car(0.0, 0.2), car(0.3, 0.8)]];
    let (r, t) = run(config(l), &frames);
    assert_eq!(r[1], vec![(1, 0.8)]);
    assert_eq!(t.stats().born, 1);
}

#[test]
fn nms_removes_duplicates_before_association() {
    let frames = vec![vec![car(0.0, 0.9), car(0.5, 0.6)]];
    let (r, _) = run(config(Levers::default()), &frames);
    assert_eq!(r[0].len(), 2);
    let l = Levers {
        nms_iou: Some(0.3),
        ..Levers::default()
    };
    let (r, _) = run(config(l), &frames);
    assert_eq!(r[0], vec![(1, 0.9)]);
}

#[test]
fn confident_tracks_outlive_max_age() {
    // Seen twice, then missed for 3 frames (max_age 2), then seen again.
    let frames = vec![
        vec![car(0.0, 0.9)],
        vec![car(0.0, 0.9)],
        vec![],
        vec![],
        vec![],
        vec![car(0.0, 0.9)],
    ];
    let (r, _) = run(config(Levers::default()), &frames);
    assert_eq!(r[5], vec![(2, 0.9)]);
    let l = Levers {
        decay: 0.1,
        keep_score: Some(0.5),
        ..Levers::default()
    };
    let (r, _) = run(config(l.clone()), &frames);
    assert_eq!(r[5], vec![(1, 0.9)]);
    // Not reported while past max_age.
    assert!(r[3].is_empty() && r[4].is_empty());
    // A fast decay ends it as before.
    let (r, _) = run(config(Levers { decay: 0.3, ..l }), &frames);
    assert_eq!(r[5], vec![(2, 0.9)]);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    /// With every lever off, the reported scores are the matched detections' scores (the paper).
    #[test]
    fn off_levers_report_last_detection_score(xs in prop::collection::vec((0.0f64..0.1, 0.0f64..1.0), 1..15)) {
        let frames: Vec<Vec<Detection>> = xs.iter().scan(0.0, |x, (dx, s)| { *x += dx; Some(vec![car(*x, *s)]) }).collect();
        let (r, _) = run(config(Levers::default()), &frames);
        for (f, (_, s)) in r.iter().zip(&xs) {
            prop_assert_eq!(f.len(), 1);
            prop_assert_eq!(f[0].1, *s);
        }
    }

    /// NMS never keeps two boxes overlapping more than its threshold, and never starts more
    /// tracks than there are detections.
    #[test]
    fn nms_bounds_births(xs in prop::collection::vec((0.0f64..6.0, 0.0f64..1.0), 1..8)) {
        let frame: Vec<Detection> = xs.iter().map(|(x, s)| car(*x, *s)).collect();
        let l = Levers { nms_iou: Some(0.1), ..Levers::default() };
        let (_, t) = run(config(l), std::slice::from_ref(&frame));
        let (_, t0) = run(config(Levers::default()), &[frame]);
        prop_assert!(t.stats().born >= 1);
        prop_assert!(t.stats().born <= t0.stats().born);
    }
}

#[test]
fn motion_option_round_trips_and_is_validated() {
    let cfg = config(Levers {
        motion: Motion::Ctrv,
        ..Levers::default()
    });
    let json = cfg.to_json();
    assert!(json.contains(r#""motion": "ctrv""#), "{json}");
    assert_eq!(TrackerConfig::from_json(&json).unwrap(), cfg);
    // An unknown model name is refused.
    // `cv` is not written: configs with other levers keep their bytes.
    let mean = config(Levers {
        score: ScoreMode::Mean,
        ..Levers::default()
    });
    assert!(!mean.to_json().contains("motion"));
    let bad = json.replace(r#""motion": "ctrv""#, r#""motion": "turn""#);
    assert!(TrackerConfig::from_json(&bad).is_err());
    // The coordinated turn needs the yaw rate in the state.
    let mut no_rate = cfg.clone();
    no_rate.for_each_class(|c| c.angular_velocity = false);
    let err = no_rate.validate().unwrap_err().to_string();
    assert!(err.contains("angular_velocity"), "{err}");
    assert!(Tracker::new(no_rate).is_err());
}

/// A car driving a circle (1 m and 0.05 rad per frame), detected exactly for 60 frames, then
/// missed for one: the coasting prediction of the coordinated-turn model stays on the circle,
/// the constant-velocity one leaves it along the lagging velocity.
#[test]
fn ctrv_coasts_along_a_turn() {
    let (v, w) = (1.0, 0.05);
    let truth = |n: usize| {
        let t = w * n as f64;
        ((v / w) * t.sin(), (v / w) * (1.0 - t.cos()), t)
    };
    let frames: Vec<Vec<Detection>> = (0..=60)
        .map(|n| {
            if n == 60 {
                return vec![];
            }
            let (x, y, yaw) = truth(n);
            let mut d = car(x, 0.9);
            d.bbox.center[1] = y;
            d.bbox.yaw = yaw;
            vec![d]
        })
        .collect();
    let err = |motion| {
        let mut t = Tracker::new(config(Levers {
            motion,
            ..Levers::default()
        }))
        .unwrap();
        let c = t.class_id("car").unwrap();
        let mut last = None;
        for (i, f) in frames.iter().enumerate() {
            let dets: Vec<Detection> = f.iter().map(|d| Detection { class: c, ..*d }).collect();
            let r = t.step(i as u64 * DT, &dets).unwrap();
            assert_eq!(r.len(), 1, "frame {i}: one track");
            last = Some(r[0]);
        }
        let r = last.unwrap();
        assert_eq!(r.frames_since_update, 1);
        let (x, y, _) = truth(60);
        (r.bbox.center[0] - x).hypot(r.bbox.center[1] - y)
    };
    let (cv, ct) = (err(Motion::Cv), err(Motion::Ctrv));
    assert!(cv > 0.02, "cv error {cv} m");
    assert!(ct < 0.5 * cv, "ctrv {ct} m vs cv {cv} m");
}

/// Runs frames through the tracker and a [`Lookback`], as `probmot track` does; per frame the
/// `(id, x)` of every shown track.
fn run_offline(cfg: TrackerConfig, frames: &[Vec<Detection>]) -> Vec<Vec<(u64, f64)>> {
    let mut t = Tracker::new(cfg).unwrap();
    let c = t.class_id("car").unwrap();
    let mut lookback: Lookback<(u64, f64)> = Lookback::default();
    let mut out = vec![];
    let drain = |lookback: &mut Lookback<(u64, f64)>, out: &mut Vec<Vec<(u64, f64)>>| {
        let mut shown = vec![];
        while let Some(frame) = lookback.pop_into(&mut shown) {
            assert_eq!(frame as usize, out.len(), "frames come out in order");
            out.push(shown.clone());
        }
    };
    for (i, f) in frames.iter().enumerate() {
        let dets: Vec<Detection> = f.iter().map(|d| Detection { class: c, ..*d }).collect();
        let r = t.step(i as u64 * DT + 1, &dets).unwrap();
        lookback.push(i as u64, r, |v, r| *v = (r.id, r.bbox.center[0]));
        drain(&mut lookback, &mut out);
    }
    lookback.finish();
    drain(&mut lookback, &mut out);
    out
}

fn offline_config(levers: Levers, min_hits: u32, max_age: u32) -> TrackerConfig {
    let mut cfg = config(levers);
    cfg.for_each_class(|c| {
        c.min_hits = min_hits;
        c.max_age = max_age;
    });
    cfg
}

fn ids(frames: &[Vec<(u64, f64)>]) -> Vec<Vec<u64>> {
    frames
        .iter()
        .map(|f| f.iter().map(|r| r.0).collect())
        .collect()
}

#[test]
fn backfill_shows_a_confirmed_track_from_its_first_detection() {
    // Four empty frames (past the first min_hits frames, which show every track), a car seen
    // in frames 4 to 7, and a second car seen only twice (frames 5 and 6: never confirmed).
    let frames: Vec<Vec<Detection>> = (0..9)
        .map(|i| {
            let mut f = vec![];
            if (4..8).contains(&i) {
                f.push(car(0.5 * i as f64, 0.9));
            }
            if (5..7).contains(&i) {
                f.push(car(40.0, 0.9));
            }
            f
        })
        .collect();
    let paper = run_offline(offline_config(Levers::default(), 3, 1), &frames);
    let back = Levers {
        backfill: true,
        ..Levers::default()
    };
    let backfilled = run_offline(offline_config(back, 3, 1), &frames);
    let empty: Vec<u64> = vec![];
    assert_eq!(
        ids(&paper)[4..8],
        [empty.clone(), empty.clone(), vec![1], vec![1]]
    );
    assert_eq!(ids(&backfilled)[4..8], [vec![1], vec![1], vec![1], vec![1]]);
    // The backfilled frames carry the boxes the track had then.
    assert_eq!(backfilled[4][0].1, 2.0);
}

/// Backfill shows a confirmed track from its first detection also when it missed a frame
/// before it was confirmed, whatever the coast mode (under `none` the missed frame itself is
/// not shown).
#[test]
fn backfill_reaches_back_across_a_miss_before_confirmation() {
    // A car in frames 4 and 5, missed in 6, seen again in 7 to 9.
    let frames: Vec<Vec<Detection>> = (0..10)
        .map(|i| match i {
            4 | 5 | 7..=9 => vec![car(0.4 * i as f64, 0.9)],
            _ => vec![],
        })
        .collect();
    let shown = |coast| {
        let l = Levers {
            coast,
            backfill: true,
            ..Levers::default()
        };
        let f = ids(&run_offline(offline_config(l, 3, 3), &frames));
        (4..10)
            .filter(|&i| !f[i].is_empty())
            .collect::<Vec<usize>>()
    };
    assert_eq!(shown(Coast::All), [4, 5, 6, 7, 8, 9]);
    assert_eq!(shown(Coast::Gaps), [4, 5, 6, 7, 8, 9]);
    assert_eq!(shown(Coast::None), [4, 5, 7, 8, 9]);
}

#[test]
fn coast_modes_report_every_prediction_only_gaps_or_none() {
    // A car in frames 0, 1 and 3 (a one-frame gap), then gone; max_age 3 keeps it coasting
    // through frames 4 and 5.
    let frames: Vec<Vec<Detection>> = (0..7)
        .map(|i| match i {
            0 | 1 | 3 => vec![car(0.3 * i as f64, 0.9)],
            _ => vec![],
        })
        .collect();
    let run_with = |coast| {
        let l = Levers {
            coast,
            ..Levers::default()
        };
        ids(&run_offline(offline_config(l, 1, 3), &frames))
    };
    let one = || vec![1u64];
    let none: Vec<u64> = vec![];
    let all = [one(), one(), one(), one(), one(), one(), none.clone()];
    assert_eq!(run_with(Coast::All), all);
    let gaps = [
        one(),
        one(),
        one(),
        one(),
        none.clone(),
        none.clone(),
        none.clone(),
    ];
    assert_eq!(run_with(Coast::Gaps), gaps);
    let matched = [
        one(),
        one(),
        none.clone(),
        one(),
        none.clone(),
        none.clone(),
        none,
    ];
    assert_eq!(run_with(Coast::None), matched);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    /// The reporting options change which frames are shown, never the tracking: per frame,
    /// coast none ⊆ gaps ⊆ all, the paper ⊆ backfill, and a track shown in two runs has the
    /// same box in both.
    #[test]
    fn reporting_options_only_choose_frames(
        xs in prop::collection::vec((prop::option::of(0.0f64..0.5), 0.0f64..1.0), 1..25),
        min_hits in 1u32..4,
        max_age in 1u32..4,
    ) {
        let frames: Vec<Vec<Detection>> = xs
            .iter()
            .enumerate()
            .map(|(i, (seen, s))| seen.map(|dx| car(0.4 * i as f64 + dx, *s)).into_iter().collect())
            .collect();
        let run_with = |coast, backfill| {
            let l = Levers { coast, backfill, ..Levers::default() };
            run_offline(offline_config(l, min_hits, max_age), &frames)
        };
        let within = |a: &[Vec<(u64, f64)>], b: &[Vec<(u64, f64)>]| {
            a.len() == b.len() && a.iter().zip(b).all(|(fa, fb)| fa.iter().all(|r| fb.contains(r)))
        };
        for backfill in [false, true] {
            let (n, g, a) = (
                run_with(Coast::None, backfill),
                run_with(Coast::Gaps, backfill),
                run_with(Coast::All, backfill),
            );
            prop_assert!(within(&n, &g) && within(&g, &a));
        }
        for coast in [Coast::All, Coast::Gaps, Coast::None] {
            prop_assert!(within(&run_with(coast, false), &run_with(coast, true)));
        }
    }
}

/// Frames of one car at constant `speed` m/s along `heading`, nuScenes keyframes (0.5 s).
fn fast_car_frames(speed: f64, heading: f64, n: usize) -> Vec<Detection> {
    (0..n)
        .map(|f| {
            let s = speed * 0.5 * f as f64;
            Detection {
                bbox: Box3 {
                    center: [s * heading.cos(), 3.0 + s * heading.sin(), 0.0],
                    yaw: heading,
                    size: [4.5, 1.9, 1.6],
                },
                class: 0,
                score: 0.8,
            }
        })
        .collect()
}

/// The paper's preset with `two_point_speed` on every class; per frame the ids and velocities.
fn run_keyframes(two_point_speed: Option<f64>, dets: &[Detection]) -> Vec<Vec<(u64, [f64; 3])>> {
    let mut cfg = TrackerConfig::preset("nuscenes-chiu2019").unwrap();
    cfg.for_each_class(|c| c.levers.two_point_speed = two_point_speed);
    let mut t = Tracker::new(cfg).unwrap();
    let car = t.class_id("car").unwrap();
    dets.iter()
        .enumerate()
        .map(|(f, d)| {
            let d = Detection { class: car, ..*d };
            let r = t.step(f as u64 * 500_000_000 + 1, &[d]).unwrap();
            r.iter().map(|r| (r.id, r.velocity)).collect()
        })
        .collect()
}

#[test]
fn two_point_initialization_keeps_a_fast_car_in_one_track() {
    // 20 m/s is 10 m between keyframes: past the paper's gate for a track without velocity.
    let dets = fast_car_frames(20.0, 0.0, 20);
    let paper = run_keyframes(None, &dets);
    let ids: std::collections::BTreeSet<u64> = paper.iter().flatten().map(|r| r.0).collect();
    assert!(ids.len() > 2, "the paper's method keeps it: {ids:?}");
    assert!(
        paper[10].is_empty(),
        "no confirmed track mid-run: {:?}",
        paper[10]
    );

    let two_point = run_keyframes(Some(40.0), &dets);
    for (f, reports) in two_point.iter().enumerate() {
        assert_eq!(reports.len(), 1, "frame {f}: {reports:?}");
        assert_eq!(reports[0].0, 1, "frame {f}: one id throughout");
    }
    let v = two_point[10][0].1;
    assert!(
        (v[0] - 20.0).abs() < 1e-6 && v[1].abs() < 1e-6,
        "velocity {v:?}"
    );

    // A limit under the car's speed leaves it as the paper does.
    assert_eq!(run_keyframes(Some(15.0), &dets), paper);
    // A car the gate follows anyway is tracked identically with the option.
    let slow = fast_car_frames(4.0, 0.3, 20);
    assert_eq!(run_keyframes(Some(40.0), &slow), run_keyframes(None, &slow));
}

#[test]
fn two_point_speed_is_validated() {
    let mut cfg = config(Levers {
        two_point_speed: Some(-1.0),
        ..Levers::default()
    });
    assert!(cfg.validate().unwrap_err().0.contains("two_point_speed"));
    cfg.for_each_class(|c| c.levers.two_point_speed = Some(30.0));
    cfg.validate().unwrap();
    let back = TrackerConfig::from_json(&cfg.to_json()).unwrap();
    assert_eq!(back, cfg);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    /// Any car up to the two-point speed, in any direction, keeps one id from its first frame.
    #[test]
    fn two_point_tracks_any_heading_and_speed(speed in 0.0f64..35.0, heading in -3.1f64..3.1) {
        let frames = run_keyframes(Some(36.0), &fast_car_frames(speed, heading, 12));
        for reports in &frames {
            prop_assert_eq!(reports.len(), 1);
            prop_assert_eq!(reports[0].0, 1);
        }
    }
}
