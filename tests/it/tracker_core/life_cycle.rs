//! The life cycle of a track: birth, confirmation, coasting, deletion, and the prediction over
//! irregular gaps, checked against a closed-form Kalman filter.

use super::*;

/// Published car statistics of the `nuscenes-chiu2019` preset (see the reference constants).
const CAR_P0_X: f64 = 0.08900372;
const CAR_P0_Y: f64 = 0.09412005;
const CAR_P0_Z: f64 = 0.03265469;
const CAR_P0_YAW: f64 = 1.00535696;
const CAR_P0_DX: f64 = 0.08120681;
const CAR_Q_X: f64 = 1.58918523e-01;

/// One axis of a constant-velocity Kalman filter with diagonal noise, worked in closed form:
/// state `(p, v)` with covariance `[[pp, pv], [pv, vv]]`, velocity per nominal frame. The blocks
/// of the 11-d filter are independent when `P0`, `Q` and `R` are diagonal, so this is the exact
/// x / dx block of the tracker's filter.
#[derive(Debug, Clone, Copy)]
struct Axis {
    p: f64,
    v: f64,
    pp: f64,
    pv: f64,
    vv: f64,
}

impl Axis {
    fn born(z: f64, p0: f64, p0v: f64) -> Self {
        Axis {
            p: z,
            v: 0.0,
            pp: p0,
            pv: 0.0,
            vv: p0v,
        }
    }
    /// Prediction over `k` nominal frames: `P = A P A^T + k Q`.
    fn predict(&mut self, k: f64, q: f64, qv: f64) {
        self.p += k * self.v;
        self.pp = self.pp + 2.0 * k * self.pv + k * k * self.vv + k * q;
        self.pv += k * self.vv;
        self.vv += k * qv;
    }
    fn update(&mut self, z: f64, r: f64) {
        let s = self.pp + r;
        let (kp, kv) = (self.pp / s, self.pv / s);
        let y = z - self.p;
        self.p += kp * y;
        self.v += kv * y;
        let (pp, pv, vv) = (self.pp, self.pv, self.vv);
        self.pp = pp - kp * pp;
        self.pv = pv - kp * pv;
        self.vv = vv - kv * pv;
    }
}

/// One car, scripted frame by frame (0.5 s apart):
///
/// | frame | detection | expected                                                        |
/// |-------|-----------|-----------------------------------------------------------------|
/// | 0, 1  | none      | nothing                                                         |
/// | 2     | (10, 5)   | id 1 born and reported with 1 hit (frame_count 3 <= min_hits)   |
/// | 3     | none      | id 1 coasts, not reported (1 hit, frame_count 4), still alive   |
/// | 4     | none      | id 1 deleted (2 frames without update = max_age)                |
/// | 5, 6  | x = 0, 2  | id 2 born; not reported at its 1st and 2nd hit                  |
/// | 7     | x = 4     | id 2 reported at its 3rd hit (confirmed)                        |
/// | 8     | none      | id 2 reported once with its prediction, frames_since_update = 1 |
/// | 9     | none      | nothing reported, id 2 in `deleted()`                           |
#[test]
fn life_cycle_of_one_object() {
    let mut t = tracker("nuscenes-chiu2019");
    let car = t.class_id("car").unwrap();

    assert!(step(&mut t, 0, &[]).is_empty());
    assert!(step(&mut t, 1, &[]).is_empty());

    // Frame 2: born and reported with a single hit, because frame_count (3) <= min_hits (3).
    let b = car_box(10.0, 5.0, 0.3);
    let r = step(&mut t, 2, &[det(car, b)]);
    assert_eq!(r.len(), 1, "{r:?}");
    assert_eq!(r[0].id, 1);
    assert_eq!(r[0].hits, 1);
    assert_eq!(r[0].age, 0);
    assert_eq!(r[0].frames_since_update, 0);
    assert_eq!(r[0].detection, Some(0));
    // A new track sits exactly on its detection with zero velocity and covariance P0 (the yaw
    // goes through `wrap`, which may move it by an ulp).
    assert_eq!((r[0].bbox.center, r[0].bbox.size), (b.center, b.size));
    assert!(close(r[0].bbox.yaw, b.yaw, 1e-12));
    assert_eq!(r[0].velocity, [0.0; 3]);
    assert_eq!(r[0].position_variance, [CAR_P0_X, CAR_P0_Y, CAR_P0_Z]);
    assert_eq!(r[0].yaw_variance, CAR_P0_YAW);
    assert_eq!(r[0].score, 0.9);

    // Frame 3: a tentative track (1 hit) after the first three frames is not reported.
    assert!(step(&mut t, 3, &[]).is_empty());
    assert!(t.deleted().is_empty());
    assert_eq!(t.live_tracks(), 1);

    // Frame 4: second frame without an update: deleted.
    assert!(step(&mut t, 4, &[]).is_empty());
    assert_eq!(t.deleted(), &[1]);
    assert_eq!(t.live_tracks(), 0);

    // Frames 5 and 6: a track born after the first three frames is not reported at 1 or 2 hits.
    let (v, yaw) = (2.0, 0.0); // 2 m per frame = 4 m/s along +x
    assert!(step(&mut t, 5, &[det(car, car_box(0.0, 0.0, yaw))]).is_empty());
    assert_eq!(t.live_tracks(), 1);
    assert!(step(&mut t, 6, &[det(car, car_box(v, 0.0, yaw))]).is_empty());
    assert_eq!(
        t.live_tracks(),
        1,
        "the second detection must match, not start a track"
    );

    // Frame 7: third hit, reported.
    let r7 = step(&mut t, 7, &[det(car, car_box(2.0 * v, 0.0, yaw))]);
    assert_eq!(r7.len(), 1, "{r7:?}");
    let r7 = r7[0];
    assert_eq!(r7.id, 2);
    assert_eq!(r7.hits, 3);
    assert_eq!(r7.age, 2);
    assert_eq!(r7.frames_since_update, 0);
    assert_eq!(r7.detection, Some(0));
    // The x / dx block worked in closed form.
    let mut ax = Axis::born(0.0, CAR_P0_X, CAR_P0_DX);
    for z in [v, 2.0 * v] {
        ax.predict(1.0, CAR_Q_X, CAR_Q_X);
        ax.update(z, CAR_P0_X);
    }
    assert!(
        close(r7.bbox.center[0], ax.p, 1e-9),
        "{} {}",
        r7.bbox.center[0],
        ax.p
    );
    assert!(
        close(r7.velocity[0], ax.v / 0.5, 1e-9),
        "{:?} {}",
        r7.velocity,
        ax.v
    );
    assert!(close(r7.position_variance[0], ax.pp, 1e-12));
    assert!(r7.velocity[0] > 2.0, "{:?}", r7.velocity);

    // Frame 8: the detection is missing: reported once, as the prediction.
    let r8 = step(&mut t, 8, &[]);
    assert_eq!(r8.len(), 1, "{r8:?}");
    let r8 = r8[0];
    assert_eq!(r8.id, 2);
    assert_eq!(r8.frames_since_update, 1);
    assert_eq!(r8.hits, 3);
    assert_eq!(r8.age, 3);
    assert_eq!(r8.detection, None);
    assert_eq!(r8.score, r7.score);
    for j in 0..3 {
        let expected = r7.bbox.center[j] + r7.velocity[j] * 0.5;
        assert!(close(r8.bbox.center[j], expected, 1e-9), "axis {j}");
        assert!(close(r8.velocity[j], r7.velocity[j], 1e-12));
    }
    assert!(close(
        r8.bbox.yaw,
        wrap(r7.bbox.yaw + r7.yaw_rate * 0.5),
        1e-9
    ));
    assert_eq!(r8.bbox.size, r7.bbox.size);
    ax.predict(1.0, CAR_Q_X, CAR_Q_X);
    assert!(close(r8.bbox.center[0], ax.p, 1e-9));
    assert!(close(r8.position_variance[0], ax.pp, 1e-12));
    assert!(r8.position_variance[0] > r7.position_variance[0]);
    assert!(t.deleted().is_empty());

    // Frame 9: second miss: not reported, deleted.
    assert!(step(&mut t, 9, &[]).is_empty());
    assert_eq!(t.deleted(), &[2]);
    assert_eq!(t.live_tracks(), 0);
    let stats = t.stats();
    assert_eq!(stats.born, 2);
    assert_eq!(stats.confirmed, 1);
}

/// Documented departure from the reference code: a class without detections in a frame is still
/// predicted and aged (the reference skips the class entirely). A pedestrian track born in frame
/// 0 coasts in frame 1 while only a car is detected: its age and frames since update grow and its
/// covariance is the one-frame prediction of `P0`; in frame 2 it is deleted.
#[test]
fn class_without_detections_is_still_predicted_and_aged() {
    let mut t = tracker("nuscenes-chiu2019");
    let car = t.class_id("car").unwrap();
    let ped = t.class_id("pedestrian").unwrap();
    let ped_box = Box3 {
        center: [3.0, -2.0, 0.9],
        yaw: 1.0,
        size: [0.7, 0.6, 1.8],
    };
    let r0 = step(
        &mut t,
        0,
        &[det(car, car_box(20.0, 0.0, 0.0)), det(ped, ped_box)],
    );
    assert_eq!(r0.len(), 2);
    let ped_id = r0.iter().find(|r| r.class == ped).unwrap().id;

    let r1 = step(&mut t, 1, &[det(car, car_box(20.5, 0.0, 0.0))]);
    let p = r1
        .iter()
        .find(|r| r.id == ped_id)
        .expect("the pedestrian is reported in frame 2 <= min_hits");
    assert_eq!(p.age, 1);
    assert_eq!(p.frames_since_update, 1);
    assert_eq!(p.detection, None);
    // P_xx = P0_x + P0_dx + Q_x (pedestrian statistics), zero velocity: same centre.
    let expected = 0.03855275 + 0.04237008 + 3.34814566e-02;
    assert!(close(p.position_variance[0], expected, 1e-12), "{p:?}");
    let expected_yaw = 2.0751833 + 2.0059979 + 4.24962535e-01;
    assert!(close(p.yaw_variance, expected_yaw, 1e-12), "{p:?}");
    assert_eq!(p.bbox.center, ped_box.center);

    let r2 = step(&mut t, 2, &[det(car, car_box(21.0, 0.0, 0.0))]);
    assert!(r2.iter().all(|r| r.id != ped_id));
    assert_eq!(t.deleted(), &[ped_id]);
    assert_eq!(t.live_tracks(), 1);
}

/// Stamps that are not 0.5 s apart: the prediction spans `k = gap / 0.5 s` nominal frames, for the
/// mean (`x + k dx`) and the covariance (`A P A^T + k Q`). Frames at 0, 0.5 s (detections at
/// x = 0 and 1), 1.75 s (no detection, k = 2.5) and 1.80 s (detection, k = 0.1).
#[test]
fn irregular_gaps_scale_the_prediction() {
    let mut t = tracker("nuscenes-chiu2019");
    let car = t.class_id("car").unwrap();
    let ms = 1_000_000u64;
    t.step(0, &[det(car, car_box(0.0, 0.0, 0.0))]).unwrap();
    t.step(500 * ms, &[det(car, car_box(1.0, 0.0, 0.0))])
        .unwrap();
    let mut ax = Axis::born(0.0, CAR_P0_X, CAR_P0_DX);
    ax.predict(1.0, CAR_Q_X, CAR_Q_X);
    ax.update(1.0, CAR_P0_X);

    let r = t.step(1750 * ms, &[]).unwrap().to_vec();
    assert_eq!(r.len(), 1, "{r:?}"); // frame 3 <= min_hits
    assert_eq!(r[0].frames_since_update, 1);
    ax.predict(2.5, CAR_Q_X, CAR_Q_X);
    assert!(
        close(r[0].bbox.center[0], ax.p, 1e-9),
        "{} {}",
        r[0].bbox.center[0],
        ax.p
    );
    assert!(close(r[0].position_variance[0], ax.pp, 1e-12), "{r:?}");
    // The yaw / yaw-rate block has the same form (angular velocity on, R_yaw = P0_yaw).
    let (p0_dyaw, q_yaw) = (0.99492726, 9.22800791e-02);
    let mut yaw = Axis::born(0.0, CAR_P0_YAW, p0_dyaw);
    yaw.predict(1.0, q_yaw, q_yaw);
    yaw.update(0.0, CAR_P0_YAW);
    yaw.predict(2.5, q_yaw, q_yaw);
    assert!(
        close(r[0].yaw_variance, yaw.pp, 1e-12),
        "{} {}",
        r[0].yaw_variance,
        yaw.pp
    );

    let r = t
        .step(1800 * ms, &[det(car, car_box(3.6, 0.0, 0.0))])
        .unwrap()
        .to_vec();
    assert_eq!(r.len(), 1, "{r:?}");
    assert_eq!((r[0].hits, r[0].detection), (3, Some(0)));
    ax.predict(0.1, CAR_Q_X, CAR_Q_X);
    ax.update(3.6, CAR_P0_X);
    assert!(
        close(r[0].bbox.center[0], ax.p, 1e-9),
        "{} {}",
        r[0].bbox.center[0],
        ax.p
    );
    assert!(close(r[0].velocity[0], ax.v / 0.5, 1e-9));
    assert!(close(r[0].position_variance[0], ax.pp, 1e-12));
}
