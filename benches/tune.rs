//! `probmot tune`'s speed: configurations evaluated per second on the ten KITTI tracking train
//! sequences in `../shared/data/kitti-tracking-train` (PointRCNN detections). One configuration
//! of one class = track the class in all ten logs in memory and score it with the KITTI protocol
//! (sAMOTA at IoU 0.25), which is what the search does per candidate. Criterion's throughput line
//! (elem/s) is the configurations per second of one candidate (its tracks' IoUs are computed on
//! all cores, its threshold passes on one); `tune` runs candidates in parallel.
//! Skipped (with a message) when the data is absent.

use std::path::{Path, PathBuf};

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use probmot::eval::kitti::MeanScores;
use probmot::pipeline::kitti_io::{import_kitti, resolve_detection_files};
use probmot::tracker::TrackerConfig;
use probmot::tune::score::{class_truth, score_class_with, single_class};
use probmot::tune::{fit_noise, Protocol, Scoring, SearchLimits, TuneLog, TuneOptions};

const SEQS: [&str; 10] = [
    "0000", "0002", "0003", "0004", "0005", "0007", "0009", "0011", "0017", "0020",
];

fn load(data: &Path, dir: &Path) -> Vec<TuneLog> {
    SEQS.iter()
        .map(|s| {
            let out: PathBuf = dir.join(format!("{s}.mcap"));
            let dets = resolve_detection_files(&[data.join("pointrcnn")], s, None).unwrap();
            let labels = data.join("label_02").join(format!("{s}.txt"));
            import_kitti(Some(&labels), &dets, None, s, &out).unwrap();
            TuneLog::load(&out, "/ground_truth", "/detections").unwrap()
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/kitti-tracking-train");
    if !data.is_dir() {
        eprintln!("SKIPPED tune bench: no KITTI data at {}", data.display());
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let logs = load(&data, dir.path());
    let refs: Vec<&TuneLog> = logs.iter().collect();
    let scoring = Scoring {
        protocol: Protocol::Kitti,
        iou: 0.25,
        search_means: MeanScores::Once,
    };
    let o = TuneOptions {
        scoring,
        limits: SearchLimits {
            budget: 1,
            rounds: 1,
            ..SearchLimits::default()
        },
        dt_nominal: None,
        min_samples: 50,
        classes: vec![],
        search: vec![],
        keep_base: vec![],
    };
    let base = TrackerConfig::preset("nuscenes-chiu2019").unwrap();
    let fitted = fit_noise(&base, &refs, &o).unwrap();
    let mut g = c.benchmark_group("tune");
    g.sample_size(10);
    g.throughput(Throughput::Elements(1));
    for label in ["car", "pedestrian", "cyclist"] {
        let cfg = single_class(&fitted, label, fitted.classes[label].clone());
        // As the tune does: the class's truth is prepared once.
        let truth = class_truth(&refs, label, &scoring);
        g.bench_function(format!("one_config_{label}_10_logs"), |b| {
            b.iter(|| score_class_with(&refs, &truth, &cfg, label).unwrap())
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
