//! `probmot tune` from the command line: the config it writes, its help, the protocol it picks,
//! ROS 2 input, and the 2-fold cross-validation on the shared KITTI data with a reduced budget
//! (skipped without the data). The search itself on synthetic logs is in `tune.rs`.

use crate::common;

use std::path::Path;

use probmot::eval::kitti::{KittiParams, MeanScores};
use probmot::pipeline::progress::no_progress;
use probmot::tracker::TrackerConfig;
use probmot::tune::score::{score_class, single_class, track_log};
use probmot::tune::{cross_validate, Protocol, Scoring, SearchLimits, TuneLog, TuneOptions};

#[test]
fn cli_tune_writes_a_config_that_track_accepts() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("tuned.json");
    let logs = [
        common::repo("sample_logs/pedestrians.mcap"),
        common::repo("sample_logs/turning-car.mcap"),
    ];
    let (l0, l1) = (logs[0].to_str().unwrap(), logs[1].to_str().unwrap());
    let o = out.to_str().unwrap();
    let args = [
        "tune",
        l0,
        l1,
        "-o",
        o,
        "--protocol",
        "nuscenes",
        "--folds",
        "2",
        "--budget",
        "6",
        "--quiet",
        "--json",
    ];
    let r = common::probmot_ok(&args);
    let v: serde_json::Value = serde_json::from_slice(&r.stdout).unwrap();
    assert_eq!(v["cross_validation"]["folds"].as_array().unwrap().len(), 2);
    // The once-averaged KITTI numbers do not apply to nuScenes.
    assert!(
        v["cross_validation"].get("tuned_means_once").is_none(),
        "{v}"
    );
    // The table says, per fold and class, how many trajectories trained it and whether it was
    // searched.
    let text = common::probmot_ok(&args[..args.len() - 1]);
    let text = String::from_utf8_lossy(&text.stdout);
    assert!(text.contains("training trajectories"), "{text}");
    assert!(text.contains("paired 95 % bootstrap interval"), "{text}");
    let overall_gain =
        (text.lines()).find(|l| l.trim_start().starts_with("overall") && l.contains('['));
    let verdicts = ["beyond the noise", "within the noise"];
    assert!(
        overall_gain.is_some_and(|l| verdicts.iter().any(|v| l.contains(v))),
        "{text}"
    );
    let fold_rows = text
        .lines()
        .filter(|l| l.starts_with("fold ") && !l.contains("overall"));
    assert!(
        fold_rows.clone().count() > 0
            && fold_rows.clone().all(|l| l.ends_with("(searched)")
                || l.ends_with(
                    "(no detections in the training folds: folds are the logs in the order given)"
                )
                || l.ends_with("(too few trajectories: the base's own settings and noise)")),
        "{text}"
    );
    // It says which classes the protocol scored, and what the others get.
    assert!(
        text.contains("scored with the nuScenes protocol: ")
            && text.contains("other classes keep the base's settings with the fitted noise"),
        "{text}"
    );
    let cfg = TrackerConfig::from_json(&std::fs::read_to_string(&out).unwrap()).unwrap();
    assert!(cfg.name.starts_with("tune of 2 log(s)"));
    let tracked = dir.path().join("t.mcap");
    common::probmot_ok(&[
        "track",
        l0,
        "-o",
        tracked.to_str().unwrap(),
        "--config",
        o,
        "--quiet",
    ]);
    assert!(!common::tracks(&tracked, "/tracks").is_empty());
    // Bad input: a log without ground truth is refused with its name.
    let r = common::probmot(&[
        "tune",
        tracked.to_str().unwrap(),
        "-o",
        o,
        "--truth-topic",
        "/nope",
        "--folds",
        "1",
        "--quiet",
    ]);
    assert!(!r.status.success());
    assert!(String::from_utf8_lossy(&r.stderr).contains("t.mcap"));
    // An unknown search option is refused with the list of options.
    let r = common::probmot(&["tune", l0, "-o", o, "--search", "nsm", "--quiet"]);
    assert_eq!(r.status.code(), Some(2));
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(err.contains("'nsm'") && err.contains("nms_iou"), "{err}");
    // A class of --classes without detections (a typo) is named, with the labels there are.
    let r = common::probmot(&["tune", l0, l1, "-o", o, "--classes", "cars", "--quiet"]);
    assert_eq!(r.status.code(), Some(2));
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        err.contains(
            "--classes: no detection of cars in the inputs (their labels: car, pedestrian)"
        ),
        "{err}"
    );
    // --search-means belongs to the KITTI protocol.
    let r = common::probmot(&[
        "tune",
        l0,
        "-o",
        o,
        "--protocol",
        "nuscenes",
        "--search-means",
        "once",
        "--quiet",
    ]);
    assert_eq!(r.status.code(), Some(2));
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(err.contains("--search-means is a KITTI option"), "{err}");
    // Too few logs for the folds: refused before any log is read (a log that does not exist
    // is named first: tests/it/error_hints.rs).
    let r = common::probmot(&["tune", l0, "-o", o, "--quiet"]);
    assert_eq!(r.status.code(), Some(2));
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        err.contains("--folds 2 needs one log per fold (1 log(s) given)")
            && err.contains("--folds 1"),
        "{err}"
    );
}

/// `tune --coast gaps --backfill` sets the base's reporting for every class, and a class the
/// search does not move keeps it in the written config.
#[test]
fn cli_tune_base_reporting_flags_reach_the_written_config() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("tuned.json");
    let log = common::repo("sample_logs/pedestrians.mcap");
    let args = [
        "tune",
        log.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--protocol",
        "nuscenes",
        "--folds",
        "0",
        "--search",
        "min_hits",
        "--budget",
        "3",
        "--coast",
        "gaps",
        "--backfill",
        "--quiet",
    ];
    common::probmot_ok(&args);
    let cfg = TrackerConfig::from_json(&std::fs::read_to_string(&out).unwrap()).unwrap();
    assert!(!cfg.classes.is_empty());
    assert!(
        cfg.name.contains("with coast gaps, backfill"),
        "{}",
        cfg.name
    );
    for (label, c) in &cfg.classes {
        assert_eq!(
            c.levers.coast,
            probmot::tracker::levers::Coast::Gaps,
            "{label}"
        );
        assert!(c.levers.backfill, "{label}");
    }
}

/// `tune --help` lists every search option `--search` accepts (the help text is written by
/// hand, the names are the search space's).
#[test]
fn tune_help_lists_every_search_option() {
    let out = common::probmot_ok(&["tune", "--help"]);
    let help = String::from_utf8_lossy(&out.stdout);
    let search = help
        .split_once("--search <LIST>")
        .map(|(_, rest)| rest.split("\n      --").next().unwrap_or_default())
        .expect("a --search option");
    let words: Vec<&str> = search
        .split(|c: char| !(c.is_alphanumeric() || c == '_'))
        .collect();
    for name in probmot::tune::space::DIM_NAMES {
        assert!(
            words.contains(&name),
            "--search help lacks {name}:\n{search}"
        );
    }
}

/// The acceptance run, reduced to fit CI time: 2-fold cross-validation of the car class on the
/// ten KITTI train sequences with a small budget (`--budget 13 --rounds 1 --margin 0`); the
/// tuned configs must beat the fitted base
/// config on the held-out folds. (Pedestrians and cyclists are left out: with these two folds
/// their tuned settings do not carry to the other fold, see docs/tune.md.)
#[test]
fn kitti_two_fold_cross_validation_beats_the_base() {
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/kitti-tracking-train");
    if !data.is_dir() {
        common::skip(
            "kitti_two_fold_cross_validation_beats_the_base",
            "no ../shared/data/kitti-tracking-train",
        );
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let seqs = [
        "0000", "0002", "0003", "0004", "0005", "0007", "0009", "0011", "0017", "0020",
    ];
    let logs: Vec<TuneLog> = seqs
        .iter()
        .map(|s| {
            let out = dir.path().join(format!("{s}.mcap"));
            let dets = probmot::pipeline::kitti_io::resolve_detection_files(
                &[data.join("pointrcnn")],
                s,
                None,
            )
            .unwrap();
            let labels = data.join("label_02").join(format!("{s}.txt"));
            probmot::pipeline::kitti_io::import_kitti(Some(&labels), &dets, None, s, &out).unwrap();
            TuneLog::load(&out, "/ground_truth", "/detections").unwrap()
        })
        .collect();
    let o = TuneOptions {
        scoring: Scoring {
            protocol: Protocol::Kitti,
            iou: 0.25,
            // The reference's averaging, for which this 13-configuration search was set up
            // (with the default `once` it picks a gate that scores 87.54 held-out against the
            // base's 87.64; docs/tune.md).
            search_means: MeanScores::EveryPass,
        },
        // The start, the base's own noise, then the first eleven gates.
        limits: SearchLimits {
            budget: 13,
            rounds: 1,
            margin: 0.0,
            ..SearchLimits::default()
        },
        dt_nominal: None,
        min_samples: 50,
        classes: vec!["car".into()],
        search: vec![],
        keep_base: vec![],
    };
    let base = TrackerConfig::preset("nuscenes-chiu2019").unwrap();
    // Scoring a class on only the truth its evaluation reads gives the score of the full truth
    // (on three logs, which hold all three classes, vans and DontCare regions, to stay fast).
    let refs: Vec<&TuneLog> = logs[..3].iter().collect();
    // With either averaging of the tracks' mean scores (the search's default is `once`).
    let full: Vec<_> = refs.iter().map(|l| track_log(l, &base).unwrap()).collect();
    for (label, means) in ["car", "pedestrian", "cyclist"]
        .into_iter()
        .flat_map(|l| [(l, MeanScores::EveryPass), (l, MeanScores::Once)])
    {
        let p = KittiParams {
            classes: vec![label.to_string()],
            means,
            ..KittiParams::default()
        };
        let want = probmot::eval::kitti::evaluate(&full, &p).classes[label].samota;
        let scoring = Scoring {
            search_means: means,
            ..o.scoring
        };
        let cfg = single_class(&base, label, base.class(label).unwrap().clone());
        let got = score_class(&refs, &cfg, label, &scoring).unwrap();
        assert_eq!(
            got.to_bits(),
            want.to_bits(),
            "{label} {means:?}: {got} vs {want}"
        );
        assert!(label != "car" || want > 0.5, "car: {want}");
    }
    let cv = cross_validate(&base, &logs, 2, &o, &no_progress).unwrap();
    eprintln!("base {:?}\ntuned {:?}", cv.base, cv.tuned);
    assert_eq!(cv.tuned.len(), 1);
    // Next to the official numbers, the same tracks with each mean computed once.
    assert_eq!(
        cv.tuned_means_once.keys().collect::<Vec<_>>(),
        cv.tuned.keys().collect::<Vec<_>>()
    );
    assert!(cv.tuned_means_once["car"] > 0.5 && cv.base_means_once["car"] > 0.5);
    assert!(
        cv.tuned["car"] > cv.base["car"],
        "held-out sAMOTA: tuned {:?} vs base {:?}",
        cv.tuned,
        cv.base
    );
    // Fold 1's pedestrians, tuned on fold B's 17 trajectories with this small budget (one
    // round of 40), lose to the base held-out: the warning's case. With
    // --keep-base-on-loss the written config keeps AB3DMOT's own pedestrian settings.
    let paths: Vec<String> = seqs
        .iter()
        .map(|s| dir.path().join(format!("{s}.mcap")).display().to_string())
        .collect();
    let out = dir.path().join("tuned.json");
    let mut args: Vec<&str> = vec!["tune"];
    args.extend(paths.iter().map(String::as_str));
    args.extend(["-o", out.to_str().unwrap(), "--preset", "ab3dmot-kitti"]);
    args.extend(["--classes", "pedestrian", "--budget", "40", "--rounds", "1"]);
    args.extend(["--keep-base-on-loss", "--quiet", "--json"]);
    let r = common::probmot_ok(&args);
    assert!(
        String::from_utf8_lossy(&r.stderr).contains("warning: pedestrian on fold 1"),
        "{}",
        String::from_utf8_lossy(&r.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&r.stdout).unwrap();
    assert_eq!(v["held_out_losses"][0]["label"], "pedestrian", "{v}");
    assert_eq!(v["options"]["keep_base"], serde_json::json!(["pedestrian"]));
    let tuned = TrackerConfig::from_json(&std::fs::read_to_string(&out).unwrap()).unwrap();
    let ab3dmot = TrackerConfig::preset("ab3dmot-kitti").unwrap();
    assert_eq!(tuned.classes["pedestrian"], ab3dmot.classes["pedestrian"]);
}

/// Without --protocol, tune scores KITTI imports with the KITTI protocol and other logs with
/// the nuScenes one, and refuses a mix.
#[test]
fn the_protocol_follows_the_logs() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let row = |f: u32, z: f64| {
        let fixed = "Car 0 0 -1.5 100 150 200 220 1.5 1.7 4.0";
        format!("{f} 1 {fixed} 2.0 1.6 {z} -1.57\n")
    };
    let det =
        |f: u32, z: f64| format!("{f},2,100,150,200,220,0.9,1.5,1.7,4.0,2.0,1.6,{z},-1.57,-1.5\n");
    let (labels, dets) = (d.join("0000.txt"), d.join("dets.txt"));
    std::fs::write(
        &labels,
        (0..4).map(|f| row(f, 15.0 + f as f64)).collect::<String>(),
    )
    .unwrap();
    std::fs::write(
        &dets,
        (0..4).map(|f| det(f, 15.0 + f as f64)).collect::<String>(),
    )
    .unwrap();
    let kitti = d.join("k.mcap");
    common::probmot_ok(&[
        "import",
        "kitti",
        "--labels",
        labels.to_str().unwrap(),
        "--detections",
        dets.to_str().unwrap(),
        "-o",
        kitti.to_str().unwrap(),
        "-q",
    ]);
    let city = common::repo("sample_logs/city.mcap");
    let out = d.join("t.json");
    let tune = |logs: &[&Path]| {
        let mut args = vec![
            "tune",
            "--folds",
            "0",
            "--budget",
            "1",
            "-o",
            out.to_str().unwrap(),
        ];
        args.extend(logs.iter().map(|p| p.to_str().unwrap()));
        common::probmot(&args)
    };
    let said = |o: &std::process::Output| {
        String::from_utf8_lossy(&o.stdout).to_string() + &String::from_utf8_lossy(&o.stderr)
    };
    let k = tune(&[&kitti]);
    assert!(
        said(&k).contains("scored with the KITTI protocol"),
        "{}",
        said(&k)
    );
    let n = tune(&[&city]);
    assert!(
        said(&n).contains("scored with the nuScenes protocol"),
        "{}",
        said(&n)
    );
    let warned = common::probmot(&[
        "tune",
        "--folds",
        "0",
        "--budget",
        "1",
        "-o",
        out.to_str().unwrap(),
        city.to_str().unwrap(),
        "--protocol",
        "kitti",
    ]);
    assert!(
        said(&warned).contains("warning: --protocol kitti on logs"),
        "{}",
        said(&warned)
    );
    let means = common::probmot(&[
        "tune",
        "-o",
        out.to_str().unwrap(),
        city.to_str().unwrap(),
        "--folds",
        "0",
        "--search-means",
        "once",
    ]);
    assert_eq!(means.status.code(), Some(2));
    assert!(
        said(&means).contains("so they are scored with the nuScenes protocol"),
        "{}",
        said(&means)
    );
    let mixed = tune(&[&kitti, &city]);
    assert_eq!(mixed.status.code(), Some(2), "{}", said(&mixed));
    assert!(said(&mixed).contains("give --protocol"), "{}", said(&mixed));
}

/// Tune reads detections through the one decoder of box channels: a ROS 2
/// `vision_msgs/msg/Detection3DArray` channel (here the tracks `track --tracks-format ros2`
/// writes) gives, as detections, the boxes it gives as tracks.
#[test]
fn tune_reads_ros2_detections() {
    let dir = tempfile::tempdir().unwrap();
    let input = common::repo("sample_logs/city.mcap");
    let ros = dir.path().join("ros2.mcap");
    let s = |p: &Path| p.to_str().unwrap().to_string();
    common::probmot_ok(&[
        "track",
        &s(&input),
        "-o",
        &s(&ros),
        "--tracks-format",
        "ros2",
        "--quiet",
    ]);
    let log = TuneLog::load(&ros, "/ground_truth", "/tracks").unwrap();
    let tracks = probmot::mcapio::recording::tracks_topic(&ros, "/tracks").unwrap();
    let frames: Vec<_> = log.frames.iter().filter(|f| f.has_detections).collect();
    assert_eq!(frames.len(), tracks.len());
    let boxes: usize = frames.iter().map(|f| f.detections.len()).sum();
    assert!(boxes > 100, "{boxes}");
    for (f, (stamp, t)) in frames.iter().zip(&tracks) {
        assert_eq!(f.stamp, *stamp);
        assert_eq!(f.detections.len(), t.len());
        for (d, t) in f.detections.iter().zip(t) {
            assert_eq!(&*d.label, t.label.as_str());
            let c = t.center.as_ref().unwrap();
            assert!((d.bbox.center[0] - c.x).abs() < 1e-9);
        }
    }
}
