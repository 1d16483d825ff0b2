//! `eval --events`: on real KITTI sequences tracked with the default configuration, the events
//! written are the decisions behind the numbers: per class, as many identity switches,
//! fragmentations, false positives and misses as `eval` reports, in both protocols; the events
//! channel decodes with the Python `mcap` reader; the copy keeps every message of the truth log.

use crate::common;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use crate::common::{probmot_ok, skip};
use serde_json::Value;

/// Short sequences with cars, pedestrians and cyclists (about 830 frames in all).
const SEQUENCES: [&str; 4] = ["0000", "0003", "0017", "0004"];

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Imports and tracks the sequences; `None` (after a skip) without the data.
fn tracked_logs(dir: &Path) -> Option<Vec<PathBuf>> {
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/kitti-tracking-train");
    if !data.join("label_02").is_dir() {
        skip(
            "eval_events",
            &format!("no KITTI tracking data at {}", data.display()),
        );
        return None;
    }
    let mut out = Vec::new();
    for seq in SEQUENCES {
        let input = dir.join(format!("{seq}.mcap"));
        common::import_kitti_sequence(&data, seq, &input);
        let tracked = dir.join(format!("tracked/{seq}.mcap"));
        std::fs::create_dir_all(tracked.parent().unwrap()).unwrap();
        probmot_ok(&["track", s(&input), "-o", s(&tracked), "--quiet"]);
        out.push(tracked);
    }
    Some(out)
}

/// `eval --json --events DIR` on the logs; returns the JSON.
fn eval_with_events(logs: &[PathBuf], extra: &[&str], events: &Path) -> Value {
    let mut args = vec!["eval", "--json", "--events", s(events), "--truth"];
    args.extend(logs.iter().map(|p| s(p)));
    args.extend(extra);
    let out = probmot_ok(&args);
    serde_json::from_slice(&out.stdout).unwrap()
}

/// The events' counts of each class equal the metrics' (`names`: JSON names of IDS, FRAG, FP,
/// FN, TP in the protocol's result).
fn assert_counts_agree(v: &Value, names: [&str; 5]) -> BTreeMap<String, [u64; 5]> {
    let classes = v["result"]["classes"].as_object().unwrap();
    let counts = v["events"]["counts"].as_object().unwrap();
    let mut out = BTreeMap::new();
    assert!(!counts.is_empty());
    for (class, c) in counts {
        let m = &classes[class];
        let ours: [u64; 5] =
            ["ids", "frag", "fp", "fn", "tp"].map(|k| c[k].as_u64().unwrap_or(u64::MAX));
        let metric: [u64; 5] = names.map(|k| m[k].as_f64().unwrap() as u64);
        assert_eq!(
            ours, metric,
            "{class}: events [ids, frag, fp, fn, tp] vs eval"
        );
        out.insert(class.clone(), ours);
    }
    out
}

/// Sums the Python reader's counts over the event files of `dir`.
fn python_counts(dir: &Path) -> BTreeMap<String, [u64; 5]> {
    let mut sum: BTreeMap<String, [u64; 5]> = BTreeMap::new();
    for seq in SEQUENCES {
        let f = dir.join(format!("{seq}.mcap"));
        let out = std::process::Command::new("python3")
            .arg(common::repo("scripts/read_eval_events.py"))
            .arg(&f)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let v: Value = serde_json::from_slice(&out.stdout).unwrap();
        for (class, c) in v["counts"].as_object().unwrap() {
            let e = sum.entry(class.clone()).or_default();
            for (i, k) in ["ids", "frag", "fp", "fn", "tp"].iter().enumerate() {
                e[i] += c[k].as_u64().unwrap();
            }
        }
    }
    sum
}

#[test]
fn events_count_what_the_metrics_count_in_both_protocols() {
    let tmp = tempfile::tempdir().unwrap();
    let Some(logs) = tracked_logs(tmp.path()) else {
        return;
    };
    let classes = ["--classes", "car,pedestrian,cyclist"];
    let nu_dir = tmp.path().join("nu");
    let nu = eval_with_events(&logs, &classes, &nu_dir);
    let nu_counts = assert_counts_agree(&nu, ["ids", "frag", "fp", "fn", "tp"]);
    let kitti_dir = tmp.path().join("kitti");
    let kitti = eval_with_events(&logs, &["--protocol", "kitti"], &kitti_dir);
    let kitti_counts = assert_counts_agree(&kitti, ["IDS", "FRAG", "FP", "FN", "TP"]);
    // Real errors happen on these sequences, so the comparison is not between zeros.
    assert!(nu_counts.values().map(|c| c[0]).sum::<u64>() > 0);
    assert!(kitti_counts.values().map(|c| c[1]).sum::<u64>() > 0);

    // Every identity switch is listed among the worst moments first, with a plot window.
    let worst = nu["events"]["worst_moments"].as_array().unwrap();
    let switches: u64 = nu_counts.values().map(|c| c[0]).sum();
    assert!(worst.len() as u64 >= switches.min(10));
    for w in worst.iter().take(switches.min(10) as usize) {
        assert!(w["event"].as_str().unwrap().starts_with("id switch"), "{w}");
        assert!(w["from_s"].as_f64().unwrap() <= w["time_s"].as_f64().unwrap());
    }

    // The copy keeps every message of the truth log, and adds the two event channels.
    let original = common::messages(&logs[0]);
    let copy = common::messages(&nu_dir.join("0000.mcap"));
    let kept: Vec<_> = copy
        .iter()
        .filter(|m| !m.topic.starts_with("/eval/"))
        .cloned()
        .collect();
    assert_eq!(kept, original);
    let topics: std::collections::BTreeSet<&str> = copy.iter().map(|m| m.topic.as_str()).collect();
    assert!(topics.contains("/eval/events") && topics.contains("/eval/events_scene"));

    if !common::python_has("mcap, mcap_protobuf") {
        skip(
            "eval_events (Python reader)",
            "python3 lacks mcap / mcap-protobuf-support (pip install -r scripts/requirements.txt)",
        );
        return;
    }
    assert_eq!(python_counts(&nu_dir), nu_counts);
    assert_eq!(python_counts(&kitti_dir), kitti_counts);
}

#[test]
fn one_log_writes_one_file_and_the_report_lists_the_moments() {
    let tmp = tempfile::tempdir().unwrap();
    let log = tmp.path().join("ped.mcap");
    let tracked = tmp.path().join("ped.tracked.mcap");
    let events = tmp.path().join("ped.events.mcap");
    probmot_ok(&["simulate", "--scenario", "pedestrians", "-o", s(&log)]);
    probmot_ok(&["track", s(&log), "-o", s(&tracked), "--quiet"]);
    let out = probmot_ok(&["eval", "--truth", s(&tracked), "--events", s(&events)]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("events ("), "{text}");
    assert!(events.is_file());
    // The output may not be the input.
    let same = common::probmot(&["eval", "--truth", s(&tracked), "--events", s(&tracked)]);
    assert!(!same.status.success());
    assert!(String::from_utf8_lossy(&same.stderr).contains("is the input file"));
}

/// With several logs, an events output that is a link to another log (here the second log's
/// copy, linked to the first log) is refused before anything is written: writing through it
/// would replace that log.
#[cfg(unix)]
#[test]
fn an_events_output_linked_to_another_input_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let mut tracked = Vec::new();
    for name in ["city", "pedestrians"] {
        let t = tmp.path().join(format!("{name}.mcap"));
        let input = common::repo(&format!("sample_logs/{name}.mcap"));
        probmot_ok(&["track", s(&input), "-o", s(&t), "--quiet"]);
        tracked.push(t);
    }
    let events = tmp.path().join("events");
    std::fs::create_dir(&events).unwrap();
    std::os::unix::fs::symlink(&tracked[0], events.join("pedestrians.mcap")).unwrap();
    let before = std::fs::read(&tracked[0]).unwrap();
    let out = common::probmot(&[
        "eval",
        "--events",
        s(&events),
        "--truth",
        s(&tracked[0]),
        s(&tracked[1]),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("is the input") && err.contains("city.mcap"),
        "{err}"
    );
    assert!(
        std::fs::read(&tracked[0]).unwrap() == before,
        "the log is unchanged"
    );
}

#[test]
fn to_rerun_draws_the_events_layer() {
    if !common::python_has("rerun, mcap, mcap_protobuf, pyarrow") {
        skip(
            "to_rerun_draws_the_events_layer",
            "python3 lacks rerun-sdk / mcap (pip install -r scripts/requirements.txt)",
        );
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let tracked = tmp.path().join("ped.tracked.mcap");
    let events = tmp.path().join("ped.events.mcap");
    let rrd = tmp.path().join("ped.rrd");
    let input = common::repo("sample_logs/pedestrians.mcap");
    probmot_ok(&["track", s(&input), "-o", s(&tracked), "--quiet"]);
    let out = probmot_ok(&[
        "eval",
        "--truth",
        s(&tracked),
        "--events",
        s(&events),
        "--json",
    ]);
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    let moments: u64 = v["events"]["counts"]
        .as_object()
        .unwrap()
        .values()
        .map(|c| c["ids"].as_u64().unwrap() + c["frag"].as_u64().unwrap())
        .sum();
    assert!(moments > 0);
    let py = |args: &[&str]| {
        let out = std::process::Command::new("python3")
            .args(args)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        out.stdout
    };
    let script = |n: &str| {
        common::repo(&format!("scripts/{n}"))
            .to_str()
            .unwrap()
            .to_string()
    };
    py(&[&script("to_rerun.py"), s(&events), "-o", s(&rrd)]);
    let summary: Value =
        serde_json::from_slice(&py(&[&script("inspect_rrd.py"), s(&rrd)])).unwrap();
    let e = &summary["entities"];
    // One text entry per switch and fragmentation (the moments to jump to), a row of error boxes
    // per frame.
    assert_eq!(e["/events"]["rows"].as_u64(), Some(moments), "{e}");
    assert_eq!(e["/world/events"]["rows"].as_u64(), Some(40), "{e}");
    // A tracked log without events: no events entities.
    let plain = tmp.path().join("plain.rrd");
    py(&[&script("to_rerun.py"), s(&tracked), "-o", s(&plain)]);
    let summary: Value =
        serde_json::from_slice(&py(&[&script("inspect_rrd.py"), s(&plain)])).unwrap();
    assert!(summary["entities"].get("/events").is_none());
}
