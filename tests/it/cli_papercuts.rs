//! What a new user trips over first: `--out-dir` is created, a bad output path fails before any
//! work, every `--help` has an example, `info` prints readable times and no empty lines.

use crate::common::{probmot, probmot_ok, repo};

fn s(p: &std::path::Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn out_dir_is_created() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("tracked/deeper");
    let city = repo("sample_logs/city.mcap");
    probmot_ok(&["track", s(&city), "--out-dir", s(&out), "--quiet"]);
    assert!(out.join("city.mcap").is_file());
}

#[test]
fn output_paths_are_checked_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    // The input does not exist: an error about the output shows that it was checked first.
    let missing = dir.path().join("no-such-input.mcap");
    let run = probmot(&["track", s(&missing), "-o", s(dir.path())]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("is a directory"), "{stderr}");

    // --out-dir equal to the input's folder would overwrite the input.
    let input = dir.path().join("a.mcap");
    std::fs::copy(repo("sample_logs/city.mcap"), &input).unwrap();
    let run = probmot(&["track", s(&input), "--out-dir", s(dir.path())]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("is the input file"), "{stderr}");

    // --out-dir naming a file.
    let run = probmot(&["track", s(&input), "--out-dir", s(&input)]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("not a directory"), "{stderr}");
}

#[test]
fn every_help_has_an_example() {
    let commands: &[&[&str]] = &[
        &[],
        &["track"],
        &["info"],
        &["simulate"],
        &["config"],
        &["eval"],
        &["fit"],
        &["import"],
        &["import", "kitti"],
        &["import", "nuscenes"],
        &["export"],
        &["export", "kitti"],
        &["export", "nuscenes"],
        &["plot"],
        &["viz"],
        &["tune"],
    ];
    for c in commands {
        let mut args = c.to_vec();
        args.push("--help");
        let out = probmot_ok(&args);
        let help = String::from_utf8_lossy(&out.stdout);
        let example = help
            .split_once("Example")
            .and_then(|(_, rest)| rest.lines().nth(1))
            .unwrap_or_default();
        assert!(
            example.trim_start().starts_with("probmot "),
            "probmot {c:?} --help has no example:\n{help}"
        );
    }
}

/// The class entries of the config `probmot ARGS` prints.
fn config_classes(args: &[&str]) -> serde_json::Map<String, serde_json::Value> {
    let v: serde_json::Value = serde_json::from_slice(&probmot_ok(args).stdout).unwrap();
    v["classes"].as_object().unwrap().clone()
}

#[test]
fn config_help_examples_run() {
    let dir = tempfile::tempdir().unwrap();
    let out = probmot_ok(&["config", "--preset", "nuscenes-chiu2019"]);
    let my = dir.path().join("my.json");
    std::fs::write(&my, &out.stdout).unwrap();
    let back = probmot_ok(&["config", "--config", s(&my)]);
    assert_eq!(
        back.stdout, out.stdout,
        "a preset read back prints unchanged"
    );
    std::fs::write(&my, "{\"classes\": 3}").unwrap();
    assert_eq!(
        probmot(&["config", "--config", s(&my)]).status.code(),
        Some(2)
    );
    // The levers example: every class gets the coordinated turn (with its yaw rate) and NMS.
    let levers = [
        "config",
        "--preset",
        "ab3dmot-kitti",
        "--motion",
        "ctrv",
        "--nms-iou",
        "0.1",
    ];
    let classes = config_classes(&levers);
    assert!(!classes.is_empty());
    for (label, c) in &classes {
        assert_eq!(c["levers"]["motion"], "ctrv", "{label}");
        assert_eq!(c["levers"]["nms_iou"], 0.1, "{label}");
        assert_eq!(c["angular_velocity"], true, "{label}");
    }
    // The offline example: every class reports coasted frames inside gaps only, and backfills.
    let offline = [
        "config",
        "--preset",
        "ab3dmot-kitti",
        "--coast",
        "gaps",
        "--backfill",
    ];
    for (label, c) in &config_classes(&offline) {
        assert_eq!(c["levers"]["coast"], "gaps", "{label}");
        assert_eq!(c["levers"]["backfill"], true, "{label}");
    }
    // `--backfill false` turns it off again (the kitti-pointrcnn preset has it on).
    let off = [
        "config",
        "--preset",
        "kitti-pointrcnn",
        "--backfill",
        "false",
    ];
    for (label, c) in &config_classes(&off) {
        assert!(c["levers"].get("backfill").is_none(), "{label}: {c}");
    }
    let clash = ["config", "--motion", "ctrv", "--no-angular-velocity"];
    assert_eq!(probmot(&clash).status.code(), Some(2));
}

#[test]
fn info_prints_iso_times_and_duration_and_no_empty_profile() {
    // The turning-car sample: 40 frames at 2 Hz (sample_logs/README.md), so 39 periods of 0.5 s.
    let out = probmot_ok(&["info", s(&repo("sample_logs/turning-car.mcap"))]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("\nduration:    19.500s\n"), "{text}");
    let json = probmot_ok(&["info", s(&repo("sample_logs/turning-car.mcap")), "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&json.stdout).unwrap();
    let start = v["log_time_range"][0].as_u64().unwrap();
    let line = text.lines().find(|l| l.starts_with("start:")).unwrap();
    // ISO 8601 UTC with nanoseconds, then the epoch seconds it stands for.
    let iso = line.split_whitespace().nth(1).unwrap();
    assert_eq!(iso.len(), "2026-01-01T00:00:00.000000000Z".len(), "{line}");
    assert!(iso.ends_with('Z') && iso.as_bytes()[10] == b'T', "{line}");
    assert!(
        line.ends_with(&format!(
            "({}.{:09})",
            start / 1_000_000_000,
            start % 1_000_000_000
        )),
        "{line}"
    );
    assert_eq!(v["profile"], "", "the sample has no profile");
    assert!(!text.contains("profile:"), "{text}");
}
