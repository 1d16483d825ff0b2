//! The whole `track` path (MCAP read, decode, track, encode, write) on a generated dense log,
//! next to a plain copy of the same log (`--no-track`), in one run: the ratio of the two is the
//! cost of tracking over I/O. Both are measured with each output compression (`--compression
//! zstd`, the default, and `lz4`) and, for zstd, also with the output written on the caller's
//! thread (`zstd-inline`, what each file gets when `--jobs` runs files on every core).

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use probmot::mcapio::writer::OutputCompression;
use probmot::pipeline::progress::no_progress;
use probmot::pipeline::track::{track_file, SceneOutput, TrackOptions, DEFAULT_MAX_DETECTIONS};
use probmot::sim::{write_simulation, Scenario, SimOptions};
use probmot::tracker::TrackerConfig;

fn bench(c: &mut Criterion) {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("dense.mcap");
    // 600 frames of a dense city: 200 objects, all seven classes.
    let sim = SimOptions {
        scenario: Scenario::City,
        seed: 3,
        frames: 600,
        objects: Some(200),
        rate_hz: 2.0,
        ego_frame: false,
    };
    let s = write_simulation(&sim, &input).unwrap();
    let bytes = std::fs::metadata(&input).unwrap().len();
    eprintln!(
        "dense log: {} frames, {} detections, {} ground-truth boxes, {:.1} MB",
        s.frames,
        s.detections,
        s.truth_boxes,
        bytes as f64 / 1e6
    );
    let out = dir.path().join("out.mcap");
    let mut opts = TrackOptions {
        detection_topics: vec![],
        tracks_topic: None,
        tracks_format: None,
        config: TrackerConfig::preset("nuscenes-chiu2019").unwrap(),
        no_track: false,
        strict: false,
        max_detections_per_message: DEFAULT_MAX_DETECTIONS,
        ego: Default::default(),
        scene: SceneOutput::Off,
        compression: Default::default(),
        background_writer: true,
    };
    let mut g = c.benchmark_group("track_path");
    g.sample_size(10);
    g.throughput(Throughput::Bytes(bytes));
    for (name, compression, background) in [
        ("zstd", OutputCompression::Zstd, true),
        ("lz4", OutputCompression::Lz4, true),
        // As when files run in parallel on every core: compression on the file's own thread.
        ("zstd-inline", OutputCompression::Zstd, false),
    ] {
        opts.compression = compression;
        opts.background_writer = background;
        g.bench_function(format!("copy_no_track/{name}"), |b| {
            opts.no_track = true;
            b.iter(|| track_file(&input, &out, &opts, &no_progress).unwrap())
        });
        g.bench_function(format!("track/{name}"), |b| {
            opts.no_track = false;
            b.iter(|| track_file(&input, &out, &opts, &no_progress).unwrap())
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
