//! The 180-degree flip: a detection with its heading reversed continues the track.

use super::*;

/// A car driving along +x (4 m/s, yaw about 0) is detected once with its heading flipped (yaw
/// about pi). It keeps its id, the reported yaw follows the detection's yaw (mod 2 pi) and the
/// velocity still points along +x. Flipping back works the same way.
#[test]
fn half_turn_flip_keeps_the_track() {
    let mut t = tracker("nuscenes-chiu2019");
    let car = t.class_id("car").unwrap();
    let yaw_noise = [0.02, -0.01, 0.015, -0.02, 0.0, 0.01];
    for (f, &n) in yaw_noise.iter().enumerate() {
        let r = step(
            &mut t,
            f as u64,
            &[det(car, car_box(2.0 * f as f64, 0.0, n))],
        );
        assert_eq!(r.len(), 1);
        assert_eq!(r[0].id, 1);
    }

    let flipped_yaw = PI + 0.03;
    let r = step(&mut t, 6, &[det(car, car_box(12.0, 0.0, flipped_yaw))]);
    assert_eq!(r.len(), 1, "{r:?}");
    let r = r[0];
    assert_eq!(r.id, 1);
    assert_eq!(r.detection, Some(0));
    assert_eq!(r.frames_since_update, 0);
    let off = wrap(r.bbox.yaw - flipped_yaw).abs();
    assert!(
        off < 0.05,
        "reported yaw {} vs detection {flipped_yaw}",
        r.bbox.yaw
    );
    assert!((-PI..PI).contains(&r.bbox.yaw));
    assert!(
        r.velocity[0] > 3.0,
        "velocity must not flip: {:?}",
        r.velocity
    );
    assert!(close(r.bbox.center[0], 12.0, 0.2), "{:?}", r.bbox);

    // The detector stays flipped: still the same track.
    let r = step(&mut t, 7, &[det(car, car_box(14.0, 0.0, -PI + 0.01))]);
    assert_eq!((r.len(), r[0].id, r[0].detection), (1, 1, Some(0)));
    assert!(
        wrap(r[0].bbox.yaw - (-PI + 0.01)).abs() < 0.05,
        "{:?}",
        r[0]
    );

    // And back to the true heading.
    let r = step(&mut t, 8, &[det(car, car_box(16.0, 0.0, 0.01))]);
    assert_eq!((r.len(), r[0].id, r[0].detection), (1, 1, Some(0)));
    assert!(wrap(r[0].bbox.yaw - 0.01).abs() < 0.05, "{:?}", r[0]);
    assert!(r[0].velocity[0] > 3.0, "{:?}", r[0].velocity);
    assert_eq!(t.stats().born, 1);
}

/// The flip costs nothing in the distance: with the car gate tightened from 11 to 1.5, a slowly
/// moving car (0.1 m per frame) still matches a detection flipped by pi (unfolded, the yaw
/// residual of pi alone would add about pi / sqrt(S_yaw) > 2 to the distance), and the outcome
/// equals that of the unflipped detection except for the yaw.
#[test]
fn half_turn_flip_is_free_in_the_distance() {
    let mut cfg = TrackerConfig::preset("nuscenes-chiu2019").unwrap();
    cfg.classes.get_mut("car").unwrap().threshold = 1.5;
    let mut runs = vec![];
    for flip in [0.0, PI] {
        let mut t = Tracker::new(cfg.clone()).unwrap();
        let car = t.class_id("car").unwrap();
        let mut last = vec![];
        for f in 0..8u64 {
            let yaw = if f == 7 { 0.03 + flip } else { 0.0 };
            last = step(&mut t, f, &[det(car, car_box(0.1 * f as f64, 0.0, yaw))]);
            assert_eq!(last.len(), 1, "flip {flip} frame {f}: {last:?}");
            assert_eq!(
                (last[0].id, last[0].detection),
                (1, Some(0)),
                "flip {flip} frame {f}"
            );
        }
        runs.push(last[0]);
    }
    let (a, b) = (runs[0], runs[1]);
    assert!(
        close(wrap(b.bbox.yaw - a.bbox.yaw - PI), 0.0, 1e-9),
        "{a:?} {b:?}"
    );
    for j in 0..3 {
        assert!(close(a.bbox.center[j], b.bbox.center[j], 1e-12));
        assert!(close(a.velocity[j], b.velocity[j], 1e-12));
        assert!(close(a.position_variance[j], b.position_variance[j], 1e-12));
    }
    assert!(close(a.yaw_variance, b.yaw_variance, 1e-12));
    assert!(close(a.yaw_rate, b.yaw_rate, 1e-9));
}
