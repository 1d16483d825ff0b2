//! `eval --bootstrap`'s cost: 1,000 paired resamples (two runs over the same truth), the
//! per-unit curves of the protocol and of HOTA included (KITTI: both HOTA similarities). KITTI: the ten KITTI train sequences of
//! `../shared/data/kitti-tracking-train` tracked with the `kitti-pointrcnn` and `ab3dmot-kitti`
//! presets (10-s blocks; skipped with a message when the data is absent). nuScenes: one log of
//! 20,000 ground-truth boxes (250 frames x 80 objects of the seven classes) and two noisy runs.

use std::path::{Path, PathBuf};
use std::process::Command;

use criterion::{criterion_group, criterion_main, Criterion};
use probmot::eval::bootstrap::curve::{kitti_metrics, nuscenes_metrics};
use probmot::eval::bootstrap::curve::{KITTI_METRICS, NUSCENES_METRICS};
use probmot::eval::bootstrap::paired::{self, aligned, HotaGroup, Protocol, HOTA_METRICS};
use probmot::eval::bootstrap::{Options, Units};
use probmot::eval::columns::ColumnScene;
use probmot::eval::hota::centre::centre_hota_by;
use probmot::eval::hota::kitti2d::{kitti_hota_by, KittiSimilarity};
use probmot::eval::hota::units::ByUnit;
use probmot::eval::kitti::{self, KittiBox, KittiParams};
use probmot::eval::nuscenes::{self, NuscenesParams};
use probmot::eval::scene::{load_kitti_scene, Scene};
use probmot::mcapio::LabelledBox;
use probmot::tracker::config::NUSCENES_CLASSES;

const SEQS: [&str; 10] = [
    "0000", "0002", "0003", "0004", "0005", "0007", "0009", "0011", "0017", "0020",
];
const OPTIONS: Options = Options {
    resamples: 1000,
    seed: 0,
};

fn probmot(args: &[&str]) {
    let out = Command::new(env!("CARGO_BIN_EXE_probmot"))
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The ten sequences imported and tracked with `preset`, loaded for the KITTI protocol.
fn kitti_run(data: &Path, dir: &Path, preset: &str) -> Vec<Scene<KittiBox>> {
    SEQS.iter()
        .map(|s| {
            let input: PathBuf = dir.join(format!("{s}.mcap"));
            if !input.exists() {
                let labels = data.join(format!("label_02/{s}.txt"));
                let dets = data.join("pointrcnn");
                let (l, d, i) = (
                    labels.to_str().unwrap(),
                    dets.to_str().unwrap(),
                    input.to_str().unwrap(),
                );
                probmot(&["import", "kitti", "--labels", l, "--detections", d, "-o", i]);
            }
            let out = dir.join(format!("{s}.{preset}.mcap"));
            let (i, o) = (input.to_str().unwrap(), out.to_str().unwrap());
            probmot(&["track", i, "-o", o, "--quiet", "--preset", preset]);
            load_kitti_scene((&out, "/ground_truth"), (&out, "/tracks"), &|_| {}).unwrap()
        })
        .collect()
}

fn stamps<B>(s: &[Scene<B>]) -> Vec<Vec<u64>> {
    s.iter()
        .map(|s| s.frames.iter().map(|f| f.0).collect())
        .collect()
}

fn kitti_bench(c: &mut Criterion) {
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/kitti-tracking-train");
    if !data.is_dir() {
        eprintln!(
            "SKIPPED bootstrap kitti bench: no KITTI data at {}",
            data.display()
        );
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let a = kitti_run(&data, dir.path(), "kitti-pointrcnn");
    let b = kitti_run(&data, dir.path(), "ab3dmot-kitti");
    let p = KittiParams::default();
    let (sa, sb) = (stamps(&a), stamps(&b));
    let runs: Vec<Vec<&[u64]>> = [&sa, &sb]
        .iter()
        .map(|r| r.iter().map(Vec::as_slice).collect())
        .collect();
    let units = Units::choose_paired(&runs, None);
    let mut g = c.benchmark_group("bootstrap");
    g.sample_size(10);
    g.bench_function("kitti_10_train_sequences_1000_resamples", |bench| {
        bench.iter(|| {
            let (ca, cb) = (
                kitti::curve::unit_curves(&a, &p, &units[0]),
                kitti::curve::unit_curves(&b, &p, &units[1]),
            );
            let group = |names, sim| {
                let hota = |s: &[Scene<KittiBox>], u| kitti_hota_by(s, &p.classes, sim, &ByUnit(u));
                let runs = vec![hota(&a, &units[0]).0, hota(&b, &units[1]).0];
                HotaGroup { names, runs }
            };
            let hota = [
                group(&HOTA_METRICS, KittiSimilarity::Image),
                group(&HOTA_METRICS, KittiSimilarity::Box3d),
            ];
            let (rows, ca, cb) = aligned(ca, Some(cb));
            let proto = Protocol {
                names: &KITTI_METRICS,
                metrics: kitti_metrics,
            };
            let runs = (&ca[..], cb.as_deref());
            paired::run((proto, rows), runs, &hota, &units[0], OPTIONS)
        })
    });
    g.finish();
}

struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = (self.0.wrapping_mul(6364136223846793005)).wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// One log of `frames` x `objects` truth boxes; tracks miss one in ten, drift, switch ids now
/// and then and add false positives (`seed` draws them).
fn nuscenes_log(frames: usize, objects: usize, seed: u64) -> ColumnScene {
    let mut truth = Lcg(7);
    let objs: Vec<[f64; 4]> = (0..objects)
        .map(|_| {
            [
                truth.next() * 200.0,
                truth.next() * 200.0,
                truth.next() * 4.0 - 2.0,
                truth.next() * 4.0 - 2.0,
            ]
        })
        .collect();
    let mut rng = Lcg(seed);
    let b = |id: u64, label: &str, x: f64, y: f64, score: f64| LabelledBox {
        id,
        label: label.into(),
        center: [x, y, 1.0],
        size: [4.5, 1.9, 1.6],
        score,
        ..Default::default()
    };
    let mut scene = Scene::default();
    for f in 0..frames {
        let t = f as f64 * 0.5;
        let (mut gt, mut tr) = (Vec::new(), Vec::new());
        for (i, o) in objs.iter().enumerate() {
            let (x, y) = (o[0] + o[2] * t, o[1] + o[3] * t);
            let label = NUSCENES_CLASSES[i % 7];
            gt.push(b(1 + i as u64, label, x, y, 1.0));
            if rng.next() < 0.9 {
                let id = if rng.next() < 0.01 {
                    10_000 + i as u64
                } else {
                    1 + i as u64
                };
                let (dx, dy) = (rng.next() - 0.5, rng.next() - 0.5);
                tr.push(b(id, label, x + dx, y + dy, 0.3 + 0.7 * rng.next()));
            }
        }
        if rng.next() < 0.5 {
            tr.push(b(
                99_999,
                "car",
                rng.next() * 200.0,
                rng.next() * 200.0,
                0.3 * rng.next(),
            ));
        }
        scene.frames.push((f as u64 * 500_000_000, gt, tr));
    }
    ColumnScene::from_scene(&scene)
}

fn nuscenes_bench(c: &mut Criterion) {
    let (a, b) = ([nuscenes_log(250, 80, 1)], [nuscenes_log(250, 80, 2)]);
    assert_eq!(a[0].truth.len(), 20_000);
    let p = NuscenesParams::default();
    let units = Units::choose(&[a[0].stamps.as_slice()], None);
    let mut g = c.benchmark_group("bootstrap");
    g.sample_size(10);
    g.bench_function("nuscenes_20000_box_log_1000_resamples", |bench| {
        bench.iter(|| {
            let curves = |s: &[ColumnScene]| nuscenes::curve::unit_curves(s, &p, &units);
            let hota = |s: &[ColumnScene]| centre_hota_by(s, &p.classes, &ByUnit(&units)).0;
            let group = HotaGroup {
                names: &HOTA_METRICS,
                runs: vec![hota(&a), hota(&b)],
            };
            let (rows, ca, cb) = aligned(curves(&a), Some(curves(&b)));
            let proto = Protocol {
                names: &NUSCENES_METRICS,
                metrics: nuscenes_metrics,
            };
            let runs = (&ca[..], cb.as_deref());
            paired::run((proto, rows), runs, &[group], &units, OPTIONS)
        })
    });
    g.finish();
}

criterion_group!(benches, nuscenes_bench, kitti_bench);
criterion_main!(benches);
