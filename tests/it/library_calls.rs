//! The library calls behind the commands (docs/library.md, "One call per command"), made from
//! a program of one's own with default options: what they return is what they wrote, and their
//! progress and warnings reach the callbacks.

use std::sync::Mutex;

use probmot::fit::files::{fit_files, FitFilesOptions};
use probmot::pipeline::info::recording_info;
use probmot::pipeline::progress::{no_progress, Progress};
use probmot::sim::{simulate_file, SimOptions};
use probmot::tracker::TrackerConfig;
use probmot::tune::files::{tune_files, TuneFilesOptions};
use probmot::tune::SearchLimits;
use probmot::viz::plot_file::{plot_file, PlotFileOptions};
use probmot::viz::Layer;

/// A simulated drive with the default options, in `dir`.
fn drive(dir: &std::path::Path, seed: u64) -> std::path::PathBuf {
    let path = dir.join(format!("drive{seed}.mcap"));
    let o = SimOptions {
        seed,
        ..SimOptions::default()
    };
    let frames = Mutex::new(0u64);
    let s = simulate_file(&o, &path, &|e| {
        if let Progress::Advance(n) = e {
            *frames.lock().unwrap() += n;
        }
    })
    .unwrap();
    assert_eq!(s.frames, 40);
    assert_eq!(*frames.lock().unwrap(), 40, "a progress step per frame");
    path
}

#[test]
fn fit_files_writes_the_config_it_returns_and_counts_the_bytes_read() {
    let dir = tempfile::tempdir().unwrap();
    let log = drive(dir.path(), 1);
    let out = dir.path().join("noise.json");
    let events = Mutex::new((0u64, 0u64));
    let o = FitFilesOptions {
        min_samples: 5,
        ..FitFilesOptions::default()
    };
    let fit = fit_files(std::slice::from_ref(&log), &out, &o, &|e| {
        let mut ev = events.lock().unwrap();
        match e {
            Progress::Length(n) => ev.0 = n,
            Progress::Advance(n) => ev.1 += n,
            _ => {}
        }
    })
    .unwrap();
    let written = TrackerConfig::from_json(&std::fs::read_to_string(&out).unwrap()).unwrap();
    assert_eq!(written.to_json(), fit.config.to_json());
    assert_eq!(fit.config.name, "fit of 1 log(s) on nuscenes-chiu2019");
    // Out of the file's size, the bytes up to the summary section (which the fit skips).
    let size = std::fs::metadata(&log).unwrap().len();
    let (length, advanced) = *events.lock().unwrap();
    assert_eq!(length, size);
    assert!(
        advanced > size * 9 / 10 && advanced <= size,
        "{advanced} of {size}"
    );
    assert!(fit.report.table().starts_with("class"));
}

#[test]
fn tune_files_with_defaults_writes_its_config_and_reports_it() {
    let dir = tempfile::tempdir().unwrap();
    let logs = vec![drive(dir.path(), 1), drive(dir.path(), 2)];
    let out = dir.path().join("tuned.json");
    let o = TuneFilesOptions {
        limits: SearchLimits {
            budget: 3,
            rounds: 1,
            ..SearchLimits::default()
        },
        jobs: Some(1),
        ..TuneFilesOptions::default()
    };
    let warnings = Mutex::new(Vec::new());
    let warn = |w: &str| warnings.lock().unwrap().push(w.to_string());
    let r = tune_files(&logs, &out, &o, &warn, &no_progress).unwrap();
    let written = std::fs::read_to_string(&out).unwrap();
    assert_eq!(written, format!("{}\n", r.config.to_json()));
    // Two folds by default: a cross-validation, and the protocol found from the logs.
    assert_eq!(r.cv.as_ref().map(|cv| cv.folds.len()), Some(2));
    assert!(r
        .config
        .name
        .starts_with("tune of 2 log(s) on nuscenes-chiu2019 (nuscenes,"));
    let text = r.text(&out);
    assert!(
        text.starts_with("scored with the nuScenes protocol: "),
        "{text}"
    );
    assert!(
        text.ends_with(&format!("wrote {}\n", out.display())),
        "{text}"
    );
    assert_eq!(r.warnings, *warnings.lock().unwrap());
}

#[test]
fn plot_file_draws_the_layers_the_file_has_and_warns_of_absent_classes() {
    let dir = tempfile::tempdir().unwrap();
    let log = drive(dir.path(), 1);
    let png = dir.path().join("drive.png");
    let o = PlotFileOptions {
        classes: vec!["car".into(), "unicorn".into()],
        ..PlotFileOptions::default()
    };
    let warnings = Mutex::new(Vec::new());
    let warn = |w: &str| warnings.lock().unwrap().push(w.to_string());
    let s = plot_file(&log, &png, &o, &warn, &no_progress).unwrap();
    // A simulated drive has detections and ground truth, no tracks.
    assert_eq!(s.layers, vec![Layer::Detections, Layer::GroundTruth]);
    assert_eq!(s.frames, 40);
    assert!(s.boxes > 0);
    assert!(std::fs::read(&png).unwrap().starts_with(b"\x89PNG"));
    let w = warnings.lock().unwrap();
    assert_eq!(w.len(), 1, "{w:?}");
    assert!(w[0].contains("no box of class unicorn"), "{w:?}");
}

#[test]
fn recording_info_reads_the_file_and_prints_it() {
    let dir = tempfile::tempdir().unwrap();
    let log = drive(dir.path(), 1);
    let info = recording_info(&log, &no_progress).unwrap();
    assert_eq!(info.path, log.display().to_string());
    let text = info.text();
    assert!(text.starts_with(&format!("file:        {}\n", log.display())));
    assert!(text.contains("/detections"), "{text}");
}
