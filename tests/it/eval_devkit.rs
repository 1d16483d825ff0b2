//! `probmot eval --json` against the official nuScenes devkit's numbers on the committed
//! fixtures (`tests/fixtures/eval/`; `scripts/devkit_crosscheck.py` made the `.devkit.json` files
//! with nuscenes-devkit 1.2.0 and motmetrics 1.4.0; see the README there).

use crate::common::*;
use serde_json::Value;

const FIXTURES: [&str; 5] = [
    "perfect",
    "idswitch_frag",
    "false_positives",
    "gaps_multiclass",
    "ties",
];
const COUNTS: [&str; 7] = ["mt", "ml", "tp", "fp", "fn", "ids", "frag"];
const RATIOS: [&str; 9] = [
    "amota", "amotp", "recall", "motar", "mota", "motp", "faf", "tid", "lgd",
];

fn compare(name: &str, scope: &str, ours: &Value, devkit: &Value, failures: &mut Vec<String>) {
    for k in COUNTS.iter().chain(&RATIOS) {
        let (o, d) = (&ours[k], &devkit[k]);
        let ok = match (o.as_f64(), d.as_f64()) {
            (None, None) => o.is_null() && d.is_null(),
            (Some(a), Some(b)) if COUNTS.contains(k) => a == b,
            // MOTP-derived values differ from the devkit in the last bits only (distance
            // computation order); everything else is exact to well under 1e-9.
            (Some(a), Some(b)) => (a - b).abs() <= 1e-9 * b.abs().max(1.0),
            _ => false,
        };
        if !ok {
            failures.push(format!("{name} / {scope} / {k}: probmot {o}, devkit {d}"));
        }
    }
}

#[test]
fn eval_equals_the_nuscenes_devkit_on_every_fixture() {
    let mut failures = Vec::new();
    for name in FIXTURES {
        let fixture = repo(&format!("tests/fixtures/eval/{name}.mcap"));
        let devkit: Value = serde_json::from_slice(
            &std::fs::read(repo(&format!("tests/fixtures/eval/{name}.devkit.json"))).unwrap(),
        )
        .unwrap();
        let out = probmot_ok(&["eval", "--truth", fixture.to_str().unwrap(), "--json"]);
        let ours: Value = serde_json::from_slice(&out.stdout).unwrap();
        let ours = &ours["result"];
        for (class, d) in devkit["classes"].as_object().unwrap() {
            compare(name, class, &ours["classes"][class], d, &mut failures);
        }
        compare(
            name,
            "overall",
            &ours["overall"],
            &devkit["overall"],
            &mut failures,
        );
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn gate_fails_a_worse_configuration() {
    let dir = tempfile::tempdir().unwrap();
    let input = repo("sample_logs/city.mcap");
    let good = dir.path().join("good.mcap");
    let worse = dir.path().join("worse.mcap");
    let i = input.to_str().unwrap();
    probmot_ok(&["track", i, "-o", good.to_str().unwrap(), "--quiet"]);
    // The AB3DMOT baseline on 2 Hz data: IoU cannot follow moving objects.
    probmot_ok(&[
        "track",
        i,
        "-o",
        worse.to_str().unwrap(),
        "--quiet",
        "--preset",
        "ab3dmot-2019",
    ]);
    let truth = good.to_str().unwrap();
    let r = probmot(&[
        "eval",
        "--truth",
        truth,
        "--tracks",
        worse.to_str().unwrap(),
        "--baseline",
        truth,
        "--max-drop",
        "1",
        "--gate",
        "point",
    ]);
    assert_eq!(
        r.status.code(),
        Some(3),
        "{}",
        String::from_utf8_lossy(&r.stderr)
    );
    assert!(String::from_utf8_lossy(&r.stderr).contains("AMOTA fell by"));
    // The same configuration against itself passes.
    let r = probmot(&[
        "eval",
        "--truth",
        truth,
        "--baseline",
        truth,
        "--max-drop",
        "1",
    ]);
    assert_eq!(r.status.code(), Some(0));
}

#[test]
fn bad_eval_input_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let sample = repo("sample_logs/city.mcap");
    // A log without tracks: missing channel.
    let r = probmot(&["eval", "--truth", sample.to_str().unwrap()]);
    assert_eq!(r.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&r.stderr).contains("no channel with topic /tracks"));
    // Tracks of another log (no common time): a tracks channel 1000 s after the truth.
    let other = dir.path().join("other.mcap");
    probmot_ok(&[
        "simulate",
        "--scenario",
        "city",
        "--frames",
        "10",
        "-o",
        other.to_str().unwrap(),
    ]);
    let far = dir.path().join("far.mcap");
    {
        let mut w = mcap::Writer::new(std::fs::File::create(&far).unwrap()).unwrap();
        let s = w
            .add_schema(
                "probmot.Tracks3D",
                "protobuf",
                probmot::msgs::DESCRIPTOR_SET,
            )
            .unwrap();
        let ch = w
            .add_channel(s, "/tracks", "protobuf", &Default::default())
            .unwrap();
        let stamp = probmot::sim::write::START_NS + 1_000_000_000_000;
        let msg = probmot::msgs::Tracks3D {
            stamp,
            ..Default::default()
        };
        let header = mcap::records::MessageHeader {
            channel_id: ch,
            sequence: 0,
            log_time: stamp,
            publish_time: stamp,
        };
        w.write_to_known_channel(&header, &prost::Message::encode_to_vec(&msg))
            .unwrap();
        w.finish().unwrap();
    }
    let r = probmot(&[
        "eval",
        "--truth",
        other.to_str().unwrap(),
        "--tracks",
        far.to_str().unwrap(),
    ]);
    assert_eq!(r.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&r.stderr).contains("another log"));
    // Ground truth without ids: a tracks channel used as truth whose ids are 0.
    let tracked = dir.path().join("t.mcap");
    probmot_ok(&[
        "track",
        other.to_str().unwrap(),
        "-o",
        tracked.to_str().unwrap(),
        "--quiet",
    ]);
    let r = probmot(&[
        "eval",
        "--truth",
        tracked.to_str().unwrap(),
        "--truth-topic",
        "/detections",
    ]);
    assert_eq!(r.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&r.stderr).contains("expected probmot.Tracks3D"));
    // Ground truth without instance ids (id 0).
    let no_ids = dir.path().join("no_ids.mcap");
    {
        let mut w = mcap::Writer::new(std::fs::File::create(&no_ids).unwrap()).unwrap();
        let s = w
            .add_schema(
                "probmot.Tracks3D",
                "protobuf",
                probmot::msgs::DESCRIPTOR_SET,
            )
            .unwrap();
        let ch = w
            .add_channel(s, "/ground_truth", "protobuf", &Default::default())
            .unwrap();
        let msg = probmot::msgs::Tracks3D {
            stamp: 5,
            tracks: vec![probmot::msgs::Track3D {
                label: "car".into(),
                ..Default::default()
            }],
            ..Default::default()
        };
        let header = mcap::records::MessageHeader {
            channel_id: ch,
            sequence: 0,
            log_time: 5,
            publish_time: 5,
        };
        w.write_to_known_channel(&header, &prost::Message::encode_to_vec(&msg))
            .unwrap();
        w.finish().unwrap();
    }
    let r = probmot(&[
        "eval",
        "--truth",
        no_ids.to_str().unwrap(),
        "--tracks",
        tracked.to_str().unwrap(),
    ]);
    assert_eq!(r.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&r.stderr).contains("no id"));
}

#[test]
fn many_logs_are_scored_together_like_the_devkit_scores_scenes() {
    // The five fixtures as five scenes of one evaluation (the devkit's own run over all five).
    let devkit: Value = serde_json::from_slice(
        &std::fs::read(repo("tests/fixtures/eval/all_fixtures.devkit.json")).unwrap(),
    )
    .unwrap();
    let files: Vec<String> = FIXTURES
        .iter()
        .map(|f| {
            repo(&format!("tests/fixtures/eval/{f}.mcap"))
                .to_string_lossy()
                .into_owned()
        })
        .collect();
    let mut args = vec!["eval", "--json", "--truth"];
    args.extend(files.iter().map(String::as_str));
    let out = probmot_ok(&args);
    let ours: Value = serde_json::from_slice(&out.stdout).unwrap();
    let mut failures = Vec::new();
    for (class, d) in devkit["classes"].as_object().unwrap() {
        compare(
            "all",
            class,
            &ours["result"]["classes"][class],
            d,
            &mut failures,
        );
    }
    compare(
        "all",
        "overall",
        &ours["result"]["overall"],
        &devkit["overall"],
        &mut failures,
    );
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    // The per-log breakdown holds each fixture's own numbers.
    let per_log = ours["per_log"].as_array().unwrap();
    assert_eq!(per_log.len(), 5);
    for (log, name) in per_log.iter().zip(FIXTURES) {
        let single: Value = serde_json::from_slice(
            &std::fs::read(repo(&format!("tests/fixtures/eval/{name}.devkit.json"))).unwrap(),
        )
        .unwrap();
        compare(
            name,
            "overall",
            &log["result"]["overall"],
            &single["overall"],
            &mut failures,
        );
    }
    // A directory gives the same as the list of its files.
    let dir = tempfile::tempdir().unwrap();
    for f in &files {
        let p = std::path::Path::new(f);
        std::fs::copy(p, dir.path().join(p.file_name().unwrap())).unwrap();
    }
    let out = probmot_ok(&["eval", "--json", "--truth", dir.path().to_str().unwrap()]);
    let from_dir: Value = serde_json::from_slice(&out.stdout).unwrap();
    compare(
        "dir",
        "overall",
        &from_dir["result"]["overall"],
        &devkit["overall"],
        &mut failures,
    );
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn range_filter_equals_the_devkits_filter_eval_boxes() {
    // `range_filter.mcap` carries an /ego_pose channel; the ego drives past parked cars and
    // pedestrians, and objects ahead oscillate across the 40/50 m ranges. The devkit JSON with
    // `.range` was made with its own add_center_dist + filter_eval_boxes (class_range).
    let fixture = repo("tests/fixtures/eval/range_filter.mcap");
    let fixture = fixture.to_str().unwrap();
    let mut failures = Vec::new();
    for (json, extra) in [
        ("range_filter.devkit.json", None),
        ("range_filter.range.devkit.json", Some("--max-range")),
    ] {
        let devkit: Value = serde_json::from_slice(
            &std::fs::read(repo(&format!("tests/fixtures/eval/{json}"))).unwrap(),
        )
        .unwrap();
        let mut args = vec!["eval", "--truth", fixture, "--json"];
        args.extend(extra);
        let ours: Value = serde_json::from_slice(&probmot_ok(&args).stdout).unwrap();
        for (class, d) in devkit["classes"].as_object().unwrap() {
            compare(
                json,
                class,
                &ours["result"]["classes"][class],
                d,
                &mut failures,
            );
        }
        compare(
            json,
            "overall",
            &ours["result"]["overall"],
            &devkit["overall"],
            &mut failures,
        );
        if extra.is_some() {
            let d = &devkit["inputs"]["range_filter"];
            let o = &ours["range_filter"];
            assert!(d["removed_truth_boxes"].as_u64().unwrap() > 0);
            assert_eq!(o["removed_truth_boxes"], d["removed_truth_boxes"]);
            assert_eq!(o["removed_track_boxes"], d["removed_track_boxes"]);
        } else {
            assert!(ours["range_filter"].is_null());
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    // The explicit spec of the devkit's table gives the same numbers as the default.
    let table = probmot_ok(&[
        "eval",
        "--truth",
        fixture,
        "--json",
        "--max-range",
        "car=50,bus=50,trailer=50,truck=50,pedestrian=40,bicycle=40,motorcycle=40",
    ]);
    let table: Value = serde_json::from_slice(&table.stdout).unwrap();
    let default: Value = serde_json::from_slice(
        &probmot_ok(&["eval", "--truth", fixture, "--json", "--max-range"]).stdout,
    )
    .unwrap();
    assert_eq!(table["result"], default["result"]);
    // A tighter range removes more and changes the result.
    let tight: Value = serde_json::from_slice(
        &probmot_ok(&["eval", "--truth", fixture, "--json", "--max-range", "30"]).stdout,
    )
    .unwrap();
    assert!(
        tight["range_filter"]["removed_truth_boxes"].as_u64()
            > default["range_filter"]["removed_truth_boxes"].as_u64()
    );
    assert_ne!(tight["result"]["overall"], default["result"]["overall"]);
}

#[test]
fn range_filter_needs_an_ego_pose_and_the_nuscenes_protocol() {
    let no_pose = repo("tests/fixtures/eval/perfect.mcap");
    let r = probmot(&["eval", "--truth", no_pose.to_str().unwrap(), "--max-range"]);
    assert_eq!(r.status.code(), Some(2));
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        err.contains("perfect.mcap: no channel with topic /ego_pose")
            && err.contains("--max-range"),
        "{err}"
    );
    let with_pose = repo("tests/fixtures/eval/range_filter.mcap");
    for (args, want) in [
        (
            vec!["--protocol", "kitti", "--max-range"],
            "--max-range, --min-points and --bike-racks are nuScenes options",
        ),
        (vec!["--max-range", "car=-1"], "not a positive number"),
        (
            vec!["--max-range", "--ego-topic", "/tracks"],
            "the range filter needs probmot.EgoPose",
        ),
    ] {
        let mut a = vec!["eval", "--truth", with_pose.to_str().unwrap()];
        a.extend(args);
        let r = probmot(&a);
        assert_eq!(r.status.code(), Some(2), "{a:?}");
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(err.contains(want), "{a:?}: {err}");
    }
}

#[test]
fn ids_that_restart_in_every_log_are_objects_of_their_own_log() {
    // Three logs whose ids all start at 1 (`make_eval_fixtures.py`, `repeated_ids_*`), scored
    // together by the devkit with scene-unique track ids. The bicycles are never matched (no
    // recall threshold reached): ML counts 2 objects in each of 3 logs, not 2 ids.
    let devkit: Value = serde_json::from_slice(
        &std::fs::read(repo("tests/fixtures/eval/repeated_ids.devkit.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(devkit["classes"]["bicycle"]["ml"], 6.0);
    assert!(devkit["metric_data"]["bicycle"]["confidence"]
        .as_array()
        .unwrap()
        .iter()
        .all(Value::is_null));
    let files: Vec<String> = ["a", "b", "c"]
        .iter()
        .map(|p| {
            repo(&format!("tests/fixtures/eval/repeated_ids_{p}.mcap"))
                .to_string_lossy()
                .into_owned()
        })
        .collect();
    let mut args = vec!["eval", "--json", "--truth"];
    args.extend(files.iter().map(String::as_str));
    let ours: Value = serde_json::from_slice(&probmot_ok(&args).stdout).unwrap();
    let mut failures = Vec::new();
    for (class, d) in devkit["classes"].as_object().unwrap() {
        compare(
            "repeated_ids",
            class,
            &ours["result"]["classes"][class],
            d,
            &mut failures,
        );
    }
    compare(
        "repeated_ids",
        "overall",
        &ours["result"]["overall"],
        &devkit["overall"],
        &mut failures,
    );
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Imports the nuScenes tables fixture (`make_eval_fixtures.py`: two scenes with zero-point
/// ground truth, boxes beyond the class ranges and bicycle racks holding ground truth and
/// predictions) with its tracking submission; returns the output directory.
fn import_filters_fixture(dir: &std::path::Path) -> std::path::PathBuf {
    let f = repo("tests/fixtures/eval/nuscenes_filters");
    let out = dir.join("logs");
    probmot_ok(&[
        "import",
        "nuscenes",
        "--tracks",
        f.join("tracking_results.json").to_str().unwrap(),
        "--meta",
        f.join("v1.0-probmot").to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    out
}

fn eval_json(truth: &std::path::Path, extra: &[&str]) -> Value {
    let mut args = vec!["eval", "--json", "--truth", truth.to_str().unwrap()];
    args.extend(extra);
    serde_json::from_slice(&probmot_ok(&args).stdout).unwrap()
}

#[test]
fn devkit_flag_on_imported_tables_equals_the_devkits_whole_evaluation() {
    // `nuscenes_filters.devkit.json`: the devkit's own TrackingEval (NuScenes tables, custom
    // split, add_center_dist + filter_eval_boxes + create_tracks + evaluate) on the same files.
    let devkit: Value = serde_json::from_slice(
        &std::fs::read(repo("tests/fixtures/eval/nuscenes_filters.devkit.json")).unwrap(),
    )
    .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let logs = import_filters_fixture(dir.path());
    let ours = eval_json(&logs, &["--devkit"]);
    let mut failures = Vec::new();
    for (class, d) in devkit["classes"].as_object().unwrap() {
        compare(
            "nuscenes_filters",
            class,
            &ours["result"]["classes"][class],
            d,
            &mut failures,
        );
    }
    compare(
        "nuscenes_filters",
        "overall",
        &ours["result"]["overall"],
        &devkit["overall"],
        &mut failures,
    );
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    // Boxes removed by each filter, in the devkit's order.
    let removed = &devkit["inputs"]["removed_boxes"];
    let f = &ours["filters"];
    for (ours_key, devkit_key) in [
        ("range", "range"),
        ("min_points", "points"),
        ("bike_racks", "bike_racks"),
    ] {
        let truth = removed["truth"][devkit_key].as_u64().unwrap();
        assert!(truth > 0, "{devkit_key}: the fixture must exercise it");
        assert_eq!(f[ours_key]["removed_truth_boxes"].as_u64(), Some(truth));
        assert_eq!(
            f[ours_key]["removed_track_boxes"],
            removed["tracks"][devkit_key]
        );
    }
    // --devkit is the three filters spelled out, and leaving any one out changes the result.
    let spelled = eval_json(
        &logs,
        &[
            "--max-range",
            "nuscenes",
            "--min-points",
            "1",
            "--bike-racks",
        ],
    );
    assert_eq!(spelled["result"], ours["result"]);
    for partial in [
        vec!["--min-points", "1", "--bike-racks"],
        vec!["--max-range", "--bike-racks"],
        vec!["--max-range", "--min-points", "1"],
    ] {
        let r = eval_json(&logs, &partial);
        assert_ne!(
            r["result"]["overall"], ours["result"]["overall"],
            "{partial:?}"
        );
    }
}

#[test]
fn filters_need_their_inputs() {
    let dir = tempfile::tempdir().unwrap();
    // Simulated-style fixtures carry no point counts and no racks.
    let perfect = repo("tests/fixtures/eval/perfect.mcap");
    for (args, want) in [
        (vec!["--min-points", "1"], "nuscenes_num_lidar_pts"),
        (vec!["--bike-racks"], "no channel with topic /bicycle_racks"),
        (vec!["--min-points", "0"], "0 is too small: give at least 1"),
    ] {
        let mut a = vec!["eval", "--truth", perfect.to_str().unwrap()];
        a.extend(args);
        let r = probmot(&a);
        assert_eq!(r.status.code(), Some(2), "{a:?}");
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(err.contains(want), "{a:?}: {err}");
    }
    // The KITTI protocol has none of these filters.
    let logs = import_filters_fixture(dir.path());
    let r = probmot(&[
        "eval",
        "--protocol",
        "kitti",
        "--devkit",
        "--truth",
        logs.to_str().unwrap(),
    ]);
    assert_eq!(r.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&r.stderr).contains("are nuScenes options"));
}
