//! Arbitrary bytes as an MCAP file, through the whole read path: `read_records`, `track_file`
//! (default options and preset) and `file_info`. Errors are fine; panics are not, and neither is
//! an output file (or a leftover temporary file) after `track_file` failed. When `track_file`
//! succeeds its output must be readable again with `read_records`.
#![no_main]

use std::path::PathBuf;
use std::sync::OnceLock;

use libfuzzer_sys::fuzz_target;
use probmot::mcapio::reader::read_records;
use probmot::pipeline::info::file_info;
use probmot::pipeline::progress::no_progress;
use probmot::pipeline::track::{track_file, TrackOptions, DEFAULT_MAX_DETECTIONS};
use probmot::tracker::TrackerConfig;

struct Paths {
    _dir: tempfile::TempDir,
    input: PathBuf,
    out_dir: PathBuf,
    output: PathBuf,
}

/// One scratch directory per process, on tmpfs when there is one (`track_file` syncs its output).
fn paths() -> &'static Paths {
    static P: OnceLock<Paths> = OnceLock::new();
    P.get_or_init(|| {
        let shm = std::path::Path::new("/dev/shm");
        let dir = if shm.is_dir() {
            tempfile::Builder::new()
                .prefix("probmot-fuzz-")
                .tempdir_in(shm)
        } else {
            tempfile::Builder::new().prefix("probmot-fuzz-").tempdir()
        }
        .expect("scratch directory");
        let out_dir = dir.path().join("out");
        std::fs::create_dir(&out_dir).expect("output directory");
        Paths {
            input: dir.path().join("input.mcap"),
            output: out_dir.join("output.mcap"),
            out_dir,
            _dir: dir,
        }
    })
}

fn options() -> TrackOptions {
    TrackOptions {
        detection_topics: Vec::new(),
        tracks_topic: "/tracks".into(),
        tracks_format: None,
        config: TrackerConfig::preset("nuscenes-chiu2019").expect("default preset"),
        no_track: false,
        strict: false,
        max_detections_per_message: DEFAULT_MAX_DETECTIONS,
        ego: Default::default(),
        scene_topic: None,
        compression: Default::default(),
        background_writer: false,
    }
}

fuzz_target!(|data: &[u8]| {
    let p = paths();
    std::fs::write(&p.input, data).expect("write input");
    let _ = std::fs::remove_file(&p.output);

    let mut records = 0u64;
    let _ = read_records(&p.input, |rec, stats| {
        records += 1;
        std::hint::black_box((&rec, stats.bytes_read));
        Ok(())
    });
    std::hint::black_box(records);

    match track_file(&p.input, &p.output, &options(), &no_progress) {
        Ok(summary) => {
            std::hint::black_box(serde_json::to_string(&summary).expect("summary serializes"));
            assert!(p.output.is_file(), "track_file succeeded without an output");
            if let Err(e) = read_records(&p.output, |_, _| Ok(())) {
                panic!("track_file wrote an output read_records cannot read: {e:#}");
            }
        }
        Err(e) => {
            std::hint::black_box(format!("{e:#}"));
            assert!(
                !p.output.exists(),
                "track_file failed ({e:#}) but left an output file"
            );
        }
    }
    let leftovers: Vec<_> = std::fs::read_dir(&p.out_dir)
        .expect("list output directory")
        .filter_map(|e| e.ok())
        .map(|e| e.file_name())
        .filter(|n| n != "output.mcap")
        .collect();
    assert!(
        leftovers.is_empty(),
        "temporary files left behind: {leftovers:?}"
    );

    if let Ok(info) = file_info(&p.input) {
        std::hint::black_box(serde_json::to_string(&info).expect("info serializes"));
    }
});
