//! Config options: the `ab3dmot-kitti` preset's settings, the box origin, gating after the
//! assignment and the distance with height.

use super::*;

/// A box of the given centre and height (length 4, width 2, yaw 0).
fn box_at(x: f64, y: f64, z: f64, h: f64) -> Box3 {
    Box3 {
        center: [x, y, z],
        yaw: 0.0,
        size: [4.0, 2.0, h],
    }
}

/// `ab3dmot-kitti` holds AB3DMOT's KITTI + PointRCNN settings as listed in
/// `../shared/data/ab3dmot-kitti-train/README.md` (its `get_param` and filter).
#[test]
fn ab3dmot_kitti_preset_has_ab3dmots_settings() {
    let cfg = TrackerConfig::preset("ab3dmot-kitti").unwrap();
    assert_eq!(cfg.dt_nominal, 0.1);
    assert!(cfg.default.is_none(), "other labels are not tracked");
    let expect = [
        (
            "car",
            MatcherKind::Hungarian,
            DistanceKind::Giou3d,
            -0.2,
            3,
            2,
        ),
        (
            "pedestrian",
            MatcherKind::Greedy,
            DistanceKind::Giou3d,
            -0.4,
            1,
            4,
        ),
        (
            "cyclist",
            MatcherKind::Hungarian,
            DistanceKind::Dist3d,
            2.0,
            3,
            4,
        ),
    ];
    assert_eq!(cfg.classes.len(), expect.len());
    for (label, matcher, distance, threshold, min_hits, max_age) in expect {
        let c = &cfg.classes[label];
        assert_eq!(
            (c.matcher, c.distance, c.threshold, c.min_hits, c.max_age),
            (matcher, distance, threshold, min_hits, max_age),
            "{label}"
        );
        // P0 = diag(10 x7, 10000 x3), Q = diag(1 x7, 0.01 x3), R = I7, no yaw rate.
        assert_eq!(
            &c.p0[..10],
            &[10.0, 10.0, 10.0, 10.0, 10.0, 10.0, 10.0, 1e4, 1e4, 1e4]
        );
        assert_eq!(
            &c.q[..10],
            &[1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 0.01, 0.01, 0.01]
        );
        assert_eq!(c.r, [1.0; 7]);
        assert!(!c.angular_velocity);
        assert_eq!(c.origin, BoxOrigin::Bottom);
        assert!(c.gate_after_assignment);
        assert_eq!(c.score_floor, None);
    }
    // The old name still resolves to the 2019 default.
    assert_eq!(
        TrackerConfig::preset("ab3dmot").unwrap().default,
        TrackerConfig::preset("ab3dmot-2019").unwrap().default
    );
}

/// With `origin = bottom` the filter follows the bottom-face centre: a detection that grows
/// taller on the same ground keeps the filtered bottom on the ground. Worked by hand with AB3DMOT's
/// covariances (P0 = 10, Q = 1 on h and z, 10000 and 0.01 on dz, R = 1), one frame apart:
/// - h: P = 10 + 1 = 11, K = 11/12, h = 1.5 + 11/12 * (2.5 - 1.5) = 2.416667.
/// - bottom: measured 0 as before, so it stays 0 and the centre is h / 2 = 1.208333.
/// - centre origin instead: P_zz = 10 + 10000 + 1 = 10011, K = 10011/10012,
///   z = 0.75 + K * (1.25 - 0.75) = 1.249950.
#[test]
fn bottom_origin_filters_the_bottom_face() {
    let run = |origin| {
        let mut cfg = TrackerConfig::preset("ab3dmot-2019").unwrap();
        cfg.dt_nominal = 0.5;
        cfg.for_each_class(|k| {
            k.origin = origin;
            k.min_hits = 1;
        });
        let mut t = Tracker::new(cfg).unwrap();
        let c = t.class_id("car").unwrap();
        let r0 = step(&mut t, 0, &[det(c, box_at(0.0, 0.0, 0.75, 1.5))]);
        assert_eq!(
            r0[0].bbox.center[2], 0.75,
            "a newborn sits on its detection"
        );
        let r = step(&mut t, 1, &[det(c, box_at(0.0, 0.0, 1.25, 2.5))]);
        assert_eq!(r.len(), 1);
        r[0].bbox
    };
    let h = 1.5 + 11.0 / 12.0;
    let bottom = run(BoxOrigin::Bottom);
    assert!(close(bottom.size[2], h, 1e-12), "{bottom:?}");
    assert!(close(bottom.center[2], h / 2.0, 1e-12), "{bottom:?}");
    let center = run(BoxOrigin::Center);
    assert!(close(center.size[2], h, 1e-12), "{center:?}");
    assert!(
        close(center.center[2], 0.75 + 0.5 * 10011.0 / 10012.0, 1e-12),
        "{center:?}"
    );
}

/// `gate_after_assignment` solves the assignment over every pair (AB3DMOT) and drops pairs over
/// the gate afterwards. Tracks T0 at (0, 0), T1 at (2, 0); detections D0 at (0.1, 0) and D1 at
/// (0.8, 1.7234), so that the distances are D0-T0 0.1, D0-T1 1.9, D1-T0 1.9, D1-T1 2.1 with gate 2.
/// Over every pair the optimum is D0-T0 + D1-T1 (2.2 < 3.8), and D1-T1 is then dropped: one match
/// and a new track. Gating first leaves D1-T1 out, so the solver pairs D0-T1 and D1-T0.
#[test]
fn gate_after_assignment_solves_over_every_pair() {
    let run = |after: bool| {
        let mut cfg = TrackerConfig::preset("ab3dmot-2019").unwrap();
        cfg.for_each_class(|k| {
            k.distance = DistanceKind::Dist3d;
            k.threshold = 2.0;
            k.min_hits = 1;
            k.gate_after_assignment = after;
        });
        let mut t = Tracker::new(cfg).unwrap();
        let c = t.class_id("car").unwrap();
        step(
            &mut t,
            0,
            &[
                det(c, box_at(0.0, 0.0, 0.0, 1.5)),
                det(c, box_at(2.0, 0.0, 0.0, 1.5)),
            ],
        );
        let r = step(
            &mut t,
            1,
            &[
                det(c, box_at(0.1, 0.0, 0.0, 1.5)),
                det(c, box_at(0.8, 1.7234, 0.0, 1.5)),
            ],
        );
        let mut pairs: Vec<(u64, Option<u32>)> = r.iter().map(|r| (r.id, r.detection)).collect();
        pairs.sort();
        pairs
    };
    // Ids 1 = T0, 2 = T1 (coasting, no detection), 3 = born from D1.
    assert_eq!(run(true), vec![(1, Some(0)), (2, None), (3, Some(1))]);
    assert_eq!(run(false), vec![(1, Some(1)), (2, Some(0))]);
}

/// `dist3d` counts the height difference, `center` does not: 1.5 m apart on the ground and 1.5 m
/// in height is 2.12 m, over a 2 m gate.
#[test]
fn dist3d_counts_the_height_difference() {
    let matched = |distance| {
        let mut cfg = TrackerConfig::preset("ab3dmot-2019").unwrap();
        cfg.for_each_class(|k| {
            k.distance = distance;
            k.threshold = 2.0;
            k.min_hits = 1;
        });
        let mut t = Tracker::new(cfg).unwrap();
        let c = t.class_id("car").unwrap();
        step(&mut t, 0, &[det(c, box_at(0.0, 0.0, 0.0, 1.5))]);
        let r = step(&mut t, 1, &[det(c, box_at(1.5, 0.0, 1.5, 1.5))]);
        r.iter().any(|r| r.id == 1 && r.detection == Some(0))
    };
    assert!(matched(DistanceKind::Center));
    assert!(!matched(DistanceKind::Dist3d));
}
