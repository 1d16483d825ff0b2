//! Tracker core alone at nuScenes-like density: 7 classes, 20 / 100 / 200 / 500 detections per
//! frame (and as many live tracks), the paper's Mahalanobis + greedy and AB3DMOT's 3D IoU +
//! Hungarian. Throughput is in frames; detections/s = frames/s x detections per frame.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use probmot::tracker::config::NUSCENES_CLASSES;
use probmot::tracker::{Box3, Detection, Tracker, TrackerConfig};
use std::hint::black_box;

const FRAMES: usize = 40;

/// Deterministic noise in [-0.5, 0.5).
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64 / (1u64 << 53) as f64) - 0.5
    }
}

/// `n` objects of the seven classes on a 10 m grid, each moving straight at 1-10 m/s, observed
/// every 0.5 s with 0.2 m / 0.05 rad noise.
fn frames(n: usize, class_ids: &[u32]) -> Vec<Vec<Detection>> {
    let mut rng = Lcg(7);
    let side = (n as f64).sqrt().ceil() as usize;
    let objs: Vec<([f64; 2], [f64; 2], u32)> = (0..n)
        .map(|i| {
            let p = [(i % side) as f64 * 10.0, (i / side) as f64 * 10.0];
            let yaw = rng.next() * 6.0;
            let speed = 1.0 + 9.0 * (rng.next() + 0.5);
            (
                [p[0], p[1]],
                [speed * yaw.cos(), speed * yaw.sin()],
                class_ids[i % 7],
            )
        })
        .collect();
    (0..FRAMES)
        .map(|f| {
            let t = f as f64 * 0.5;
            objs.iter()
                .map(|(p, v, c)| Detection {
                    bbox: Box3 {
                        center: [
                            p[0] + v[0] * t + 0.4 * rng.next(),
                            p[1] + v[1] * t + 0.4 * rng.next(),
                            1.0,
                        ],
                        yaw: v[1].atan2(v[0]) + 0.1 * rng.next(),
                        size: [4.5, 1.9, 1.6],
                    },
                    class: *c,
                    score: 0.5 + rng.next(),
                })
                .collect()
        })
        .collect()
}

fn run(cfg: &TrackerConfig, frames: &[Vec<Detection>]) -> usize {
    let mut t = Tracker::new(cfg.clone()).unwrap();
    for l in NUSCENES_CLASSES {
        t.class_id(l);
    }
    let mut reported = 0;
    for (i, f) in frames.iter().enumerate() {
        reported += t.step(i as u64 * 500_000_000, f).unwrap().len();
    }
    reported
}

fn bench(c: &mut Criterion) {
    let paper = TrackerConfig::preset("nuscenes-chiu2019").unwrap();
    let baseline = TrackerConfig::preset("ab3dmot-2019").unwrap();
    let mut g = c.benchmark_group("tracker_core");
    g.sample_size(20);
    for n in [20usize, 100, 200, 500] {
        for (name, cfg) in [
            ("mahalanobis_greedy", &paper),
            ("iou3d_hungarian", &baseline),
        ] {
            let mut probe = Tracker::new(cfg.clone()).unwrap();
            let ids: Vec<u32> = NUSCENES_CLASSES
                .iter()
                .map(|l| probe.class_id(l).unwrap())
                .collect();
            let data = frames(n, &ids);
            g.throughput(Throughput::Elements(FRAMES as u64));
            g.bench_with_input(BenchmarkId::new(name, n), &data, |b, data| {
                b.iter(|| black_box(run(cfg, data)))
            });
        }
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
