//! Property tests: the Kalman covariance stays positive definite, the greedy matcher is
//! Algorithm 1 of the paper, the Hungarian matcher is optimal then gated, and tracker runs are
//! sane, deterministic and gated.

use super::*;

fn assert_spd(p: &StateCov, what: &str) -> Result<(), TestCaseError> {
    prop_assert!(p.iter().all(|v| v.is_finite()), "{what}: non-finite P");
    prop_assert_eq!(*p, p.transpose(), "{}: P not symmetric", what);
    prop_assert!(p.cholesky().is_some(), "{what}: Cholesky failed: {p}");
    let min_eig = p.symmetric_eigen().eigenvalues.min();
    prop_assert!(min_eig > 0.0, "{what}: min eigenvalue {min_eig}");
    Ok(())
}

#[derive(Debug, Clone)]
enum KfOp {
    Predict(f64),
    Update([f64; 7]),
}

fn kf_op() -> impl Strategy<Value = KfOp> {
    prop_oneof![
        (0.1f64..6.0).prop_map(KfOp::Predict),
        (
            -30.0f64..30.0,
            -30.0f64..30.0,
            -2.0f64..2.0,
            -7.0f64..7.0,
            0.3f64..8.0,
            0.3f64..3.0,
            0.3f64..3.0
        )
            .prop_map(|(x, y, z, yaw, l, w, h)| KfOp::Update([x, y, z, yaw, l, w, h])),
    ]
}

/// Noise of a preset class, or random diagonals (zero process noise on the size, as the presets).
fn noise_strategy() -> impl Strategy<Value = Noise> {
    let preset = (0usize..8).prop_map(|i| {
        let c = if i == 7 {
            TrackerConfig::preset("ab3dmot-2019")
                .unwrap()
                .default
                .unwrap()
        } else {
            let cfg = TrackerConfig::preset("nuscenes-chiu2019").unwrap();
            cfg.classes.values().nth(i).unwrap().clone()
        };
        Noise::from_diagonals(&c.q, &c.r, &c.p0, c.angular_velocity)
    });
    let random = (
        prop::array::uniform4(1e-4f64..2.0),
        prop::array::uniform7(1e-3f64..3.0),
        prop::array::uniform11(1e-3f64..1e4),
        any::<bool>(),
    )
        .prop_map(|(q4, r, p0, ang)| {
            let q = [
                q4[0], q4[1], q4[2], q4[3], 0.0, 0.0, 0.0, q4[0], q4[1], q4[2], q4[3],
            ];
            Noise::from_diagonals(&q, &r, &p0, ang)
        });
    prop_oneof![preset, random]
}

#[derive(Debug, Clone)]
struct ObjSpec {
    class: usize,
    pos: [f64; 2],
    vel: [f64; 2],
    yaw: f64,
    size: [f64; 3],
}

#[derive(Debug, Clone)]
struct FrameSpec {
    gap_ms: u64,
    present: u8,
    flipped: u8,
    noise: Vec<[f64; 3]>,
    clutter: Vec<(usize, Box3, f64)>,
}

const LABELS: [&str; 3] = ["car", "pedestrian", "bicycle"];

fn box_strategy() -> impl Strategy<Value = Box3> {
    (
        -20.0f64..20.0,
        -20.0f64..20.0,
        -0.5f64..1.5,
        -4.0f64..4.0,
        0.3f64..6.0,
        0.3f64..3.0,
        0.3f64..3.0,
    )
        .prop_map(|(x, y, z, yaw, l, w, h)| Box3 {
            center: [x, y, z],
            yaw,
            size: [l, w, h],
        })
}

fn obj_strategy() -> impl Strategy<Value = ObjSpec> {
    (
        0usize..3,
        prop::array::uniform2(-15.0f64..15.0),
        prop::array::uniform2(-8.0f64..8.0),
        -3.2f64..3.2,
        (0.5f64..6.0, 0.4f64..2.5, 0.8f64..3.0),
    )
        .prop_map(|(class, pos, vel, yaw, (l, w, h))| ObjSpec {
            class,
            pos,
            vel,
            yaw,
            size: [l, w, h],
        })
}

fn frame_strategy() -> impl Strategy<Value = FrameSpec> {
    (
        // Gaps of 0.05-3 s, mostly short so that objects stay matchable.
        prop_oneof![3 => 50u64..700, 1 => 50u64..=3000],
        any::<u8>(),
        any::<u8>(),
        any::<u8>(),
        prop::collection::vec(
            (-0.6f64..0.6, -0.6f64..0.6, -0.3f64..0.3).prop_map(|(a, b, c)| [a, b, c]),
            5,
        ),
        prop::collection::vec((0usize..3, box_strategy(), 0.0f64..1.0), 0..3),
    )
        .prop_map(|(gap_ms, p1, p2, flipped, noise, clutter)| FrameSpec {
            gap_ms,
            // Each object is present with probability 3/4.
            present: p1 | p2,
            flipped,
            noise,
            clutter,
        })
}

/// One frame of a scene: the stamp in ns and the detections as `(label index, box, score)`.
type SceneFrame = (u64, Vec<(usize, Box3, f64)>);

/// The detections of every frame, with the stamps in ns, for a scenario. Class indices refer to
/// [`LABELS`] and are mapped to tracker class ids by [`run_tracker`].
fn scenario(objs: &[ObjSpec], frames: &[FrameSpec]) -> Vec<SceneFrame> {
    let mut out = vec![];
    let mut stamp_ns = 1_000_000_000u64;
    for (f, fr) in frames.iter().enumerate() {
        if f > 0 {
            stamp_ns += fr.gap_ms * 1_000_000;
        }
        let t = (stamp_ns - 1_000_000_000) as f64 * 1e-9;
        let mut dets = vec![];
        for (i, o) in objs.iter().enumerate() {
            if fr.present & (1 << i) == 0 {
                continue;
            }
            let n = fr.noise[i];
            let flip = if fr.flipped & (1 << i) != 0 { PI } else { 0.0 };
            let b = Box3 {
                center: [
                    o.pos[0] + o.vel[0] * t + n[0],
                    o.pos[1] + o.vel[1] * t + n[1],
                    0.5,
                ],
                yaw: o.yaw + n[2] + flip,
                size: o.size,
            };
            dets.push((o.class, b, 0.5 + 0.1 * i as f64));
        }
        dets.extend(fr.clutter.iter().copied());
        out.push((stamp_ns, dets));
    }
    out
}

type Run = Vec<(Vec<Detection>, Vec<TrackReport>, Vec<u64>)>;

fn run_tracker(cfg: &TrackerConfig, scen: &[SceneFrame]) -> Run {
    let mut t = Tracker::new(cfg.clone()).unwrap();
    let ids: Vec<u32> = LABELS.iter().map(|l| t.class_id(l).unwrap()).collect();
    let mut out = vec![];
    for (stamp, dets) in scen {
        let dets: Vec<Detection> = dets
            .iter()
            .map(|&(c, bbox, score)| Detection {
                bbox,
                class: ids[c],
                score,
            })
            .collect();
        let reports = t.step(*stamp, &dets).unwrap().to_vec();
        out.push((dets, reports, t.deleted().to_vec()));
    }
    out
}

/// The configurations the tracker property tests run: two presets and a few variations of
/// distance, matcher, filtered box origin and gating.
fn config_variant(i: usize) -> TrackerConfig {
    match i {
        0 => TrackerConfig::preset("nuscenes-chiu2019").unwrap(),
        1 => TrackerConfig::preset("ab3dmot-2019").unwrap(),
        2 => {
            let mut c = TrackerConfig::preset("nuscenes-chiu2019").unwrap();
            c.for_each_class(|k| k.matcher = MatcherKind::Hungarian);
            c
        }
        3 => {
            let mut c = TrackerConfig::preset("nuscenes-chiu2019").unwrap();
            c.for_each_class(|k| {
                k.distance = DistanceKind::Center;
                k.threshold = 2.0;
            });
            c
        }
        4 => {
            let mut c = TrackerConfig::preset("ab3dmot-2019").unwrap();
            c.for_each_class(|k| {
                k.distance = DistanceKind::Giou3d;
                k.threshold = -0.5;
                k.matcher = MatcherKind::Greedy;
            });
            c
        }
        _ => {
            // ab3dmot-kitti's cyclist setting for every class.
            let mut c = TrackerConfig::preset("ab3dmot-2019").unwrap();
            c.for_each_class(|k| {
                k.distance = DistanceKind::Dist3d;
                k.threshold = 2.0;
                k.origin = BoxOrigin::Bottom;
                k.gate_after_assignment = true;
            });
            c
        }
    }
}

fn report_is_finite(r: &TrackReport) -> bool {
    let b = &r.bbox;
    b.center
        .iter()
        .chain(&b.size)
        .chain(&r.velocity)
        .chain(&r.position_variance)
        .chain([&b.yaw, &r.yaw_rate, &r.score, &r.yaw_variance])
        .all(|v| v.is_finite())
}

/// The checks shared by every frame of every run: no NaN, positive variances, one report per id,
/// one report per detection, matched detections of the report's own class.
fn check_frame(f: usize, dets: &[Detection], reports: &[TrackReport]) -> Result<(), TestCaseError> {
    let mut ids = HashSet::new();
    let mut used = HashSet::new();
    for r in reports {
        prop_assert!(report_is_finite(r), "frame {f}: non-finite report {r:?}");
        prop_assert!(r.position_variance.iter().all(|v| *v > 0.0), "{r:?}");
        prop_assert!(r.yaw_variance > 0.0, "{r:?}");
        prop_assert!(r.bbox.size.iter().all(|v| *v > 0.0), "{r:?}");
        prop_assert!((-PI..PI).contains(&r.bbox.yaw), "{r:?}");
        prop_assert!(ids.insert(r.id), "frame {f}: id {} reported twice", r.id);
        match r.detection {
            Some(d) => {
                prop_assert!(used.insert(d), "frame {f}: detection {d} matched twice");
                prop_assert!((d as usize) < dets.len());
                prop_assert_eq!(dets[d as usize].class, r.class);
                prop_assert_eq!(r.frames_since_update, 0);
            }
            None => prop_assert!(r.frames_since_update > 0),
        }
    }
    Ok(())
}

proptest! {
    // No regression files: an integration test has no lib.rs next to it to put them beside.
    #![proptest_config(ProptestConfig {
        cases: 64,
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    /// (a) The Kalman covariance stays symmetric positive definite over random predict / update
    /// sequences, predictions never shrink the diagonal and updates never grow it.
    #[test]
    fn kalman_covariance_stays_spd(
        noise in noise_strategy(),
        start in box_strategy(),
        ops in prop::collection::vec(kf_op(), 1..40),
    ) {
        let mut s = KalmanState::new(&start, &noise);
        assert_spd(&s.p, "birth")?;
        for (i, op) in ops.iter().enumerate() {
            let before = s.p;
            match op {
                KfOp::Predict(k) => {
                    s.predict(*k, &noise);
                    for j in 0..11 {
                        prop_assert!(s.p[(j, j)] >= before[(j, j)] * (1.0 - 1e-12));
                    }
                }
                KfOp::Update(m) => {
                    let b = Box3::from_slice(m);
                    let inn = s.innovation(&noise);
                    let d = mahalanobis(&inn, &b);
                    prop_assert!(d.is_finite() && d >= 0.0);
                    s.update(&b, &noise);
                    for j in 0..11 {
                        prop_assert!(
                            s.p[(j, j)] <= before[(j, j)] * (1.0 + 1e-9) + 1e-12,
                            "op {i}: P[{j},{j}] grew from {} to {}", before[(j, j)], s.p[(j, j)]
                        );
                    }
                }
            }
            prop_assert!(s.x.iter().all(|v| v.is_finite()));
            prop_assert!((-PI..PI).contains(&s.x[3]));
            assert_spd(&s.p, &format!("after op {i} {op:?}"))?;
        }
    }

    /// (c) Greedy matching is one-to-one, accepts only pairs under the gate, and equals a direct
    /// simulation of Algorithm 1: repeatedly take the cheapest pair whose detection and track are
    /// both free (ties: lower detection, then lower track), until the cheapest is over the gate.
    #[test]
    fn greedy_is_algorithm_1(
        n_det in 0usize..6,
        n_trk in 0usize..6,
        costs in prop::collection::vec((0u8..12, any::<bool>()), 36),
        max_cost in 0.0f64..12.0,
        order in Just((0..36usize).collect::<Vec<_>>()).prop_shuffle(),
    ) {
        // Integer costs make ties common; some pairs are not candidates.
        let mut pairs = vec![];
        for &i in &order {
            let (d, t) = (i / 6, i % 6);
            let (c, candidate) = costs[i];
            if d < n_det && t < n_trk && candidate {
                pairs.push(Pair { cost: c as f64, det: d as u32, trk: t as u32 });
            }
        }
        let mut expected = vec![];
        let (mut det_free, mut trk_free) = (vec![true; n_det], vec![true; n_trk]);
        loop {
            let best = pairs
                .iter()
                .filter(|p| det_free[p.det as usize] && trk_free[p.trk as usize])
                .min_by(|a, b| {
                    a.cost.total_cmp(&b.cost).then(a.det.cmp(&b.det)).then(a.trk.cmp(&b.trk))
                });
            match best {
                Some(p) if p.cost <= max_cost => {
                    det_free[p.det as usize] = false;
                    trk_free[p.trk as usize] = false;
                    expected.push((p.det, p.trk));
                }
                _ => break,
            }
        }
        let cost_of: HashMap<(u32, u32), f64> =
            pairs.iter().map(|p| ((p.det, p.trk), p.cost)).collect();
        let mut out = vec![(99, 99)]; // greedy appends
        greedy(&mut pairs, max_cost, &mut vec![], &mut vec![], n_det, n_trk, &mut out);
        prop_assert_eq!(out.remove(0), (99, 99));
        prop_assert_eq!(&out, &expected);
        let dets: HashSet<u32> = out.iter().map(|m| m.0).collect();
        let trks: HashSet<u32> = out.iter().map(|m| m.1).collect();
        prop_assert_eq!(dets.len(), out.len());
        prop_assert_eq!(trks.len(), out.len());
        for m in &out {
            prop_assert!(cost_of[m] <= max_cost);
        }
    }

    /// (c) The optimal assignment: with no gate it assigns min(n_det, n_trk) pairs one-to-one at
    /// the brute-force minimum total cost; with a gate it returns exactly those pairs under it.
    #[test]
    fn hungarian_is_optimal_then_gated(
        n_det in 1usize..6,
        n_trk in 1usize..6,
        costs in prop::collection::vec((0.0f64..20.0, 0u8..5), 25),
        max_cost in 0.0f64..20.0,
    ) {
        let mut m = vec![0.0; n_det * n_trk];
        for d in 0..n_det {
            for t in 0..n_trk {
                let (c, kind) = costs[d * 5 + t];
                m[d * n_trk + t] = if kind == 0 { NOT_A_CANDIDATE } else { c };
            }
        }
        let mut all = vec![];
        hungarian(&m, n_det, n_trk, f64::INFINITY, &mut all);
        prop_assert_eq!(all.len(), n_det.min(n_trk));
        let dets: HashSet<u32> = all.iter().map(|p| p.0).collect();
        let trks: HashSet<u32> = all.iter().map(|p| p.1).collect();
        prop_assert_eq!(dets.len(), all.len());
        prop_assert_eq!(trks.len(), all.len());
        let total: f64 = all.iter().map(|&(d, t)| m[d as usize * n_trk + t as usize]).sum();
        let best = brute_force_min_assignment(&m, n_det, n_trk);
        prop_assert!((total - best).abs() <= 1e-6 * best.max(1.0), "{total} vs {best}");

        let mut gated = vec![];
        hungarian(&m, n_det, n_trk, max_cost, &mut gated);
        let expected: Vec<(u32, u32)> = all
            .iter()
            .copied()
            .filter(|&(d, t)| m[d as usize * n_trk + t as usize] <= max_cost)
            .collect();
        prop_assert_eq!(gated, expected);
    }

    /// (a)-(d) on the tracker: random scenes of up to five objects of three classes moving at
    /// constant velocity, with position / yaw noise, random 180-degree flips, random misses,
    /// random clutter and random gaps (0.05-3 s), under several distance / matcher settings.
    /// Every report is finite with positive variances, ids and detections appear at most once
    /// per frame, a deleted id never comes back, an id keeps its class, and a second run on the
    /// same input gives identical output.
    #[test]
    fn tracker_runs_are_sane_and_deterministic(
        variant in 0usize..6,
        objs in prop::collection::vec(obj_strategy(), 1..5),
        frames in prop::collection::vec(frame_strategy(), 1..20),
    ) {
        let cfg = config_variant(variant);
        let scen = scenario(&objs, &frames);
        let run = run_tracker(&cfg, &scen);
        let mut dead = HashSet::new();
        let mut class_of = HashMap::new();
        for (f, (dets, reports, deleted)) in run.iter().enumerate() {
            check_frame(f, dets, reports)?;
            for r in reports {
                prop_assert!(!dead.contains(&r.id), "frame {f}: deleted id {} is back", r.id);
                prop_assert_eq!(*class_of.entry(r.id).or_insert(r.class), r.class);
            }
            dead.extend(deleted.iter().copied());
        }
        let again = run_tracker(&cfg, &scen);
        prop_assert!(run == again, "two runs on the same input differ");
    }

    /// (c) with every live track reported (`min_hits = 1`): each detection is used exactly once
    /// (matched or born), a newborn sits exactly on its detection, and every matched pair passes
    /// the gate against the prediction made from the track's previous report
    /// (`centre + velocity * dt`, `yaw + yaw_rate * dt`).
    #[test]
    fn tracker_matches_pass_the_gate(
        variant in prop::sample::select(vec![1usize, 3, 4, 5]),
        objs in prop::collection::vec(obj_strategy(), 1..5),
        frames in prop::collection::vec(frame_strategy(), 2..20),
    ) {
        let mut cfg = config_variant(variant);
        cfg.for_each_class(|k| k.min_hits = 1);
        let scen = scenario(&objs, &frames);
        let run = run_tracker(&cfg, &scen);
        for (f, (dets, reports, _)) in run.iter().enumerate() {
            check_frame(f, dets, reports)?;
            let used: Vec<u32> = {
                let mut u: Vec<u32> = reports.iter().filter_map(|r| r.detection).collect();
                u.sort_unstable();
                u
            };
            prop_assert_eq!(used, (0..dets.len() as u32).collect::<Vec<_>>());
            for r in reports {
                let Some(d) = r.detection else { continue };
                let db = dets[d as usize].bbox;
                if r.age == 0 {
                    prop_assert_eq!(r.hits, 1);
                    // Exact, except for the rounding of a bottom-face origin (z - h/2 + h/2).
                    let ulps = if cfg.class(LABELS[0]).unwrap().origin == BoxOrigin::Center { 0.0 } else { 1e-12 };
                    for i in 0..3 {
                        let tol = ulps * (1.0 + db.center[i].abs() + db.size[2]);
                        prop_assert!(close(r.bbox.center[i], db.center[i], tol));
                    }
                    prop_assert_eq!(r.bbox.size, db.size);
                    prop_assert!(close(r.bbox.yaw, wrap(db.yaw), 1e-12));
                    prop_assert_eq!(r.velocity, [0.0; 3]);
                    continue;
                }
                let prev = run[f - 1].1.iter().find(|p| p.id == r.id);
                prop_assert!(prev.is_some(), "frame {f}: track {} was not reported before", r.id);
                let prev = prev.unwrap();
                let dt = (scen[f].0 - scen[f - 1].0) as f64 * 1e-9;
                let pred = Box3 {
                    center: [
                        prev.bbox.center[0] + prev.velocity[0] * dt,
                        prev.bbox.center[1] + prev.velocity[1] * dt,
                        prev.bbox.center[2] + prev.velocity[2] * dt,
                    ],
                    yaw: wrap(prev.bbox.yaw + prev.yaw_rate * dt),
                    size: prev.bbox.size,
                };
                let k = cfg.class(LABELS[0]).unwrap();
                let thr = k.threshold;
                match k.distance {
                    DistanceKind::Center => {
                        let dist = (db.center[0] - pred.center[0]).hypot(db.center[1] - pred.center[1]);
                        prop_assert!(dist <= thr + 1e-6, "frame {f}: centre distance {dist} > {thr}");
                    }
                    DistanceKind::Dist3d => {
                        let d: f64 = (0..3).map(|i| (db.center[i] - pred.center[i]).powi(2)).sum();
                        let dist = d.sqrt();
                        prop_assert!(dist <= thr + 1e-6, "frame {f}: 3D distance {dist} > {thr}");
                    }
                    DistanceKind::Iou3d => {
                        let s = iou3d(&db, &pred);
                        prop_assert!(s >= thr - 1e-6, "frame {f}: IoU {s} < {thr}");
                    }
                    DistanceKind::Giou3d => {
                        let s = giou3d(&db, &pred);
                        prop_assert!(s >= thr - 1e-6, "frame {f}: GIoU {s} < {thr}");
                    }
                    DistanceKind::Mahalanobis => unreachable!("no Mahalanobis variant here"),
                }
            }
        }
    }
}

/// Minimum total cost over all one-to-one assignments of `min(n_det, n_trk)` pairs.
fn brute_force_min_assignment(m: &[f64], n_det: usize, n_trk: usize) -> f64 {
    fn rec(m: &[f64], n_det: usize, n_trk: usize, row: usize, used: &mut [bool]) -> f64 {
        // Rows are the smaller side.
        let (rows, cols) = if n_det <= n_trk {
            (n_det, n_trk)
        } else {
            (n_trk, n_det)
        };
        if row == rows {
            return 0.0;
        }
        let mut best = f64::INFINITY;
        for c in 0..cols {
            if used[c] {
                continue;
            }
            let cost = if n_det <= n_trk {
                m[row * n_trk + c]
            } else {
                m[c * n_trk + row]
            };
            used[c] = true;
            best = best.min(cost + rec(m, n_det, n_trk, row + 1, used));
            used[c] = false;
        }
        best
    }
    let mut used = vec![false; n_det.max(n_trk)];
    rec(m, n_det, n_trk, 0, &mut used)
}
