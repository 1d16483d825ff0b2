//! `eval` (nuScenes protocol) on a nuScenes-val-sized input: 150 scenes x 40 frames, about 80
//! ground-truth objects per frame over the seven classes, tracks with noise, misses, false
//! positives and identity switches.

use criterion::{criterion_group, criterion_main, Criterion};
use probmot::eval::columns::ColumnScene;
use probmot::eval::hota::centre::centre_hota;
use probmot::eval::nuscenes::{evaluate_columns, NuscenesParams};
use probmot::eval::scene::Scene;
use probmot::mcapio::LabelledBox;
use probmot::tracker::config::NUSCENES_CLASSES;

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

fn eval_box(id: u64, label: &str, x: f64, y: f64, score: f64) -> LabelledBox {
    LabelledBox {
        id,
        label: label.into(),
        center: [x, y, 1.0],
        size: [4.5, 1.9, 1.6],
        score,
        ..Default::default()
    }
}

/// `scenes` scenes of `frames` frames with `objects` ground-truth objects each.
pub fn val_sized(scenes: usize, frames: usize, objects: usize) -> Vec<Scene> {
    let mut rng = Lcg(11);
    (0..scenes)
        .map(|s| {
            let objs: Vec<(f64, f64, f64, f64, &str, f64)> = (0..objects)
                .map(|i| {
                    (
                        rng.next() * 100.0,
                        rng.next() * 100.0,
                        rng.next() * 2.0 - 1.0,
                        rng.next() * 2.0 - 1.0,
                        NUSCENES_CLASSES[i % 7],
                        0.3 + 0.7 * rng.next(),
                    )
                })
                .collect();
            let frames = (0..frames)
                .map(|f| {
                    let t = f as f64 * 0.5;
                    let mut gt = Vec::new();
                    let mut tr = Vec::new();
                    for (i, o) in objs.iter().enumerate() {
                        let (x, y) = (o.0 + o.2 * t, o.1 + o.3 * t);
                        gt.push(eval_box(1 + i as u64, o.4, x, y, 1.0));
                        if rng.next() < 0.9 {
                            // Every 15th object switches id half way.
                            let id = if i % 15 == 0 && f > frames / 2 {
                                10_000 + i
                            } else {
                                1 + i
                            };
                            tr.push(eval_box(
                                id as u64,
                                o.4,
                                x + rng.next() - 0.5,
                                y + rng.next() - 0.5,
                                o.5,
                            ));
                        }
                    }
                    for k in 0..5 {
                        tr.push(eval_box(
                            50_000 + (f * 5 + k) as u64,
                            NUSCENES_CLASSES[k % 7],
                            rng.next() * 100.0,
                            rng.next() * 100.0,
                            0.2 * rng.next(),
                        ));
                    }
                    (1_000_000_000 * (s as u64 * 1000 + f as u64), gt, tr)
                })
                .collect();
            Scene {
                name: format!("scene-{s}"),
                frames,
            }
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    let scenes = val_sized(150, 40, 80);
    let columns: Vec<ColumnScene> = scenes.iter().map(ColumnScene::from_scene).collect();
    let params = NuscenesParams::default();
    let mut g = c.benchmark_group("eval");
    g.sample_size(10);
    g.bench_function("nuscenes_val_sized_150x40x80", |b| {
        b.iter(|| evaluate_columns(&columns, &params))
    });
    // What `probmot eval` adds to that for HOTA (BEV centre distance, all seven classes).
    g.bench_function("hota_centre_val_sized_150x40x80", |b| {
        b.iter(|| centre_hota(&columns, &params.classes))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
