//! "No per-detection heap allocation in the hot loop": once its buffers have grown to a scene's
//! size, `Tracker::step` makes no allocation with the greedy matcher (the paper's), with or
//! without NMS, two-stage association, the refined score, life cycle by confidence, CTRV,
//! two-point initialization and the offline reporting marks; with the Hungarian matcher (whose
//! solver allocates its working vectors) the same few per frame, however many detections the
//! frame holds. Counted by the test binary's allocator (`common::alloc`) on this thread: the
//! tracker runs on its caller's thread.

use super::*;
use crate::common::alloc::allocations;
use probmot::tracker::levers::{Coast, Motion, ScoreMode};

/// `frames` frames of `n` cars and `n` pedestrians in lanes 12 m apart, every object of a class
/// moving straight at the class's speed (so the scene's density never changes), detected every
/// frame with a small jitter and a score that drops under 0.5 one frame in four (for the second
/// round of two-stage association); each car also has a weaker duplicate 0.2 m off (for NMS);
/// every fifth frame one false positive per class far from the others (a track born and deleted
/// again, in steady state).
fn scene(t: &mut Tracker, n: usize, frames: usize) -> Vec<Vec<Detection>> {
    let (car, ped) = (
        t.class_id("car").unwrap(),
        t.class_id("pedestrian").unwrap(),
    );
    let mut rng = Lcg(7);
    (0..frames)
        .map(|f| {
            let mut dets = Vec::new();
            for i in 0..n {
                let (gx, gy) = ((i % 10) as f64 * 12.0, (i / 10) as f64 * 12.0);
                let mut jitter = || (rng.next_f64() - 0.5) * 0.1;
                let score = if (f + i) % 4 == 0 { 0.3 } else { 0.9 };
                let c = car_box(gx + 0.5 * f as f64 + jitter(), gy + jitter(), 0.0);
                let mut twin = c;
                twin.center[0] += 0.2;
                let p = Box3 {
                    center: [gx + 0.1 * f as f64 + jitter(), gy + 6.0 + jitter(), 0.9],
                    yaw: 0.0,
                    size: [0.7, 0.7, 1.8],
                };
                for (class, bbox, score) in [(car, c, score), (car, twin, 0.2), (ped, p, score)] {
                    dets.push(Detection { bbox, class, score });
                }
            }
            if f % 5 == 0 {
                let far = 500.0 + f as f64 * 40.0;
                dets.push(det(car, car_box(far, -300.0, 0.0)));
                dets.push(det(ped, car_box(-300.0, far, 0.0)));
            }
            dets
        })
        .collect()
}

/// Allocations of the 60 frames after `warm` of a scene of `n` objects per class under
/// `config`.
fn steady_allocations(config: &TrackerConfig, n: usize, warm: usize) -> u64 {
    let mut t = Tracker::new(config.clone()).unwrap();
    let frames = scene(&mut t, n, warm + 60);
    let period = (config.dt_nominal * 1e9) as u64;
    for (f, dets) in frames[..warm].iter().enumerate() {
        t.step(f as u64 * period, dets).unwrap();
    }
    let ((), count) = allocations(|| {
        for (f, dets) in frames.iter().enumerate().skip(warm) {
            let reports = t.step(f as u64 * period, dets).unwrap();
            assert!(!reports.is_empty());
        }
    });
    count
}

#[test]
fn a_steady_frame_allocates_nothing_per_detection() {
    let chiu = TrackerConfig::preset("nuscenes-chiu2019").unwrap();
    let mut levers = chiu.clone();
    levers.for_each_class(|c| {
        let l = &mut c.levers;
        l.nms_iou = Some(0.1);
        l.birth_score = Some(0.5);
        (l.score, l.decay, l.keep_score) = (ScoreMode::Refined, 0.05, Some(0.3));
        (l.coast, l.backfill, l.two_point_speed) = (Coast::Gaps, true, Some(20.0));
        l.motion = Motion::Ctrv;
        c.angular_velocity = true;
    });
    // The paper's method (greedy matching) and the options beyond it: nothing at all.
    for (name, cfg) in [("nuscenes-chiu2019", &chiu), ("with levers", &levers)] {
        for n in [5, 20] {
            let count = steady_allocations(cfg, n, 100);
            assert_eq!(
                count, 0,
                "{name}, {n} objects per class: {count} allocations"
            );
        }
    }
    // AB3DMOT's KITTI settings match cars and cyclists with the Hungarian method, whose solver
    // (the lsap crate) allocates its working vectors on every call: the same count with three
    // times the detections, a fixed few per frame. That count is not 0 also shows that the
    // allocator counts.
    let kitti = TrackerConfig::preset("ab3dmot-kitti").unwrap();
    let (few, many) = (
        steady_allocations(&kitti, 10, 40),
        steady_allocations(&kitti, 30, 40),
    );
    assert_eq!(
        few, many,
        "ab3dmot-kitti: {few} allocations with 10 objects, {many} with 30"
    );
    assert!(
        (60..=12 * 60).contains(&many),
        "ab3dmot-kitti: {many} allocations in 60 frames"
    );
}
