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

    // `-o newdir/`: a path written as a directory, which does not exist, fails at once (it
    // used to fail only when the finished output was renamed into place).
    let newdir = format!("{}/newdir/", dir.path().display());
    let city = repo("sample_logs/city.mcap");
    let runs: [&[&str]; 3] = [
        &["track", s(&missing), "-o", &newdir],
        &["fit", s(&city), "-o", &newdir],
        &["simulate", "--scenario", "city", "-o", &newdir],
    ];
    for args in runs {
        let run = probmot(args);
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains("ends with a slash"), "{args:?}: {stderr}");
    }
    assert!(!dir.path().join("newdir").exists());
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

/// The first example of each `--help` that works on the shipped samples runs as printed, from a
/// folder laid out like the repository's root (`sample_logs/`), in the order a reader meets them
/// (`probmot --help` first writes the city.tracked.mcap the later ones read). `import` and
/// `export` stay out: their examples need the user's dataset files.
#[test]
fn first_help_examples_run_from_the_repo_root() {
    let dir = tempfile::tempdir().unwrap();
    std::os::unix::fs::symlink(repo("sample_logs"), dir.path().join("sample_logs")).unwrap();
    let bin_dir = std::path::Path::new(env!("CARGO_BIN_EXE_probmot"))
        .parent()
        .unwrap();
    let path = format!("{}:{}", bin_dir.display(), std::env::var("PATH").unwrap());
    let mut commands = vec![
        "", "track", "info", "simulate", "config", "eval", "fit", "plot", "tune",
    ];
    if cfg!(feature = "rerun") {
        commands.push("viz");
    }
    for c in commands {
        let args: Vec<&str> = [c, "--help"]
            .into_iter()
            .filter(|a| !a.is_empty())
            .collect();
        let help = String::from_utf8(probmot_ok(&args).stdout).unwrap();
        let line = help
            .split_once("Example")
            .and_then(|(_, rest)| rest.lines().nth(1))
            .unwrap_or_default();
        // The command without its comment (`# ...`, `(...)`) and what follows `&&` (a viewer).
        let cmd = line.split("  #").next().unwrap();
        let cmd = cmd.split("  (").next().unwrap();
        let cmd = cmd.split(" && ").next().unwrap().trim();
        assert!(cmd.starts_with("probmot "), "probmot {c} --help: {line}");
        let run = std::process::Command::new("sh")
            .args(["-c", cmd])
            .current_dir(dir.path())
            .env("PATH", &path)
            .output()
            .unwrap();
        assert!(
            run.status.success(),
            "probmot {c} --help: `{cmd}` failed: {}",
            String::from_utf8_lossy(&run.stderr)
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
    // Two-point initialization for every class; a speed that is not positive is refused.
    let two_point = [
        "config",
        "--preset",
        "nuscenes-chiu2019",
        "--two-point-speed",
        "40",
    ];
    let classes = config_classes(&two_point);
    assert_eq!(classes.len(), 7);
    for (label, c) in &classes {
        assert_eq!(c["levers"]["two_point_speed"], 40.0, "{label}");
    }
    let bad = probmot(&["config", "--two-point-speed", "-5"]);
    assert_eq!(bad.status.code(), Some(2));
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(
        err.contains("'-5' is not a positive number of m/s"),
        "{err}"
    );
    // The help's example: cars, motorcycles, buses and trucks only.
    let per_class = [
        "config",
        "--preset",
        "nuscenes-chiu2019",
        "--two-point-speed",
        "car=40,motorcycle=40,bus=30,truck=30",
    ];
    for (label, c) in &config_classes(&per_class) {
        let want = match label.as_str() {
            "car" | "motorcycle" => serde_json::json!(40.0),
            "bus" | "truck" => serde_json::json!(30.0),
            _ => serde_json::Value::Null,
        };
        assert_eq!(
            c["levers"]
                .get("two_point_speed")
                .cloned()
                .unwrap_or_default(),
            want,
            "{label}"
        );
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

/// The first `eval` a new user runs is often on the untracked log: the error names the topics
/// the file has and says that `probmot track` writes the tracks. `--classes` naming no class of
/// the ground truth lists the classes it has (both protocols).
#[test]
fn eval_errors_say_what_the_file_has() {
    let city = repo("sample_logs/city.mcap");
    let run = probmot(&["eval", "--truth", s(&city)]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("no channel with topic /tracks (topics: /detections, /ground_truth); `probmot track` writes /tracks"),
        "{stderr}"
    );
    let gt = ["--tracks-topic", "/ground_truth"];
    let classes = ["--classes", "Car,unicorn"];
    let run = probmot(&[&["eval", "--truth", s(&city)][..], &gt, &classes].concat());
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("its classes: bicycle, bus, car, motorcycle, pedestrian, trailer, truck"),
        "{stderr}"
    );
    let kitti = ["--protocol", "kitti", "--classes", "unicorn"];
    let run = probmot(&[&["eval", "--truth", s(&city)][..], &gt, &kitti].concat());
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("its classes: bicycle, bus, car"),
        "{stderr}"
    );
}

/// A negative number is a value, not a flag: `--score-floor -2` (PointRCNN's scores are logits)
/// is accepted, and `--min-hits -1` gets a range error instead of clap's "use '-- -1'" tip.
#[test]
fn negative_numbers_are_values() {
    let dir = tempfile::tempdir().unwrap();
    let city = repo("sample_logs/city.mcap");
    let out = dir.path().join("out.mcap");
    let args = ["track", s(&city), "-o", s(&out), "--quiet"];
    probmot_ok(&[&args[..], &["--score-floor", "-2"]].concat());
    let run = probmot(&[&args[..], &["--min-hits", "-1"]].concat());
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("invalid value '-1' for '--min-hits") && !stderr.contains("'-- -1'"),
        "{stderr}"
    );
    // A negative gate would fail an unchanged result: refused.
    let eval = ["eval", "--truth", s(&out), "--baseline", s(&out)];
    let run = probmot(&[&eval[..], &["--max-drop", "-1"]].concat());
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("--max-drop must be a number of points >= 0"),
        "{stderr}"
    );
}

/// `export kitti` of a log `import kitti` did not write (a 2 Hz simulated drive) numbers its
/// frames 0, 1, 2, ... by stamp instead of placing them on a 10 Hz grid (it wrote frames 0, 5,
/// 10, ... without a word), and names the types KITTI's labels do not have.
#[test]
fn export_kitti_of_another_log_numbers_frames_in_order() {
    let dir = tempfile::tempdir().unwrap();
    let city = repo("sample_logs/city.mcap");
    let tracked = dir.path().join("city.tracked.mcap");
    probmot_ok(&["track", s(&city), "-o", s(&tracked), "--quiet"]);
    let out = dir.path().join("city.txt");
    let run = probmot_ok(&["export", "kitti", s(&tracked), "-o", s(&out)]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(
        stderr.contains("frames are numbered 0, 1, 2, ... in the order of the 40 stamps"),
        "{stderr}"
    );
    assert!(
        stderr.contains("types KITTI's labels do not have")
            && stderr.contains("Bicycle 118")
            && stderr.contains("rows have no 2D image box"),
        "{stderr}"
    );
    let text = std::fs::read_to_string(&out).unwrap();
    let frames: std::collections::BTreeSet<u32> = text
        .lines()
        .map(|l| l.split(' ').next().unwrap().parse().unwrap())
        .collect();
    assert_eq!(frames, (0..40).collect());
}

/// A folder of logs is not a bag: `track` and `info` on it say to name the files.
#[test]
fn a_folder_of_logs_is_not_a_bag() {
    let dir = tempfile::tempdir().unwrap();
    let (logs, out) = (repo("sample_logs"), dir.path().join("never-written.mcap"));
    for args in [
        vec!["track", s(&logs), "-o", s(&out)],
        vec!["info", s(&logs)],
    ] {
        let run = probmot(&args);
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(2), "{stderr}");
        assert!(
            stderr.contains("3 .mcap files without metadata.yaml")
                && stderr.contains("sample_logs/*.mcap")
                && !stderr.contains("split"),
            "{stderr}"
        );
    }
    assert!(!out.exists());
}

/// A bag directory (`ros2 bag record`'s folder holding one .mcap) is read by every command, as
/// `track` and `eval` already did: `info`, `plot`, `fit` and `export kitti` open its MCAP file
/// (they failed with "Is a directory").
#[test]
fn every_command_reads_a_bag_directory() {
    let dir = tempfile::tempdir().unwrap();
    let bag = dir.path().join("drive_bag");
    std::fs::create_dir(&bag).unwrap();
    std::fs::copy(repo("sample_logs/city.mcap"), bag.join("city.mcap")).unwrap();
    let tracked = dir.path().join("tracked_bag");
    // Without rosbag2's metadata.yaml, nor its files' names, a folder is not a bag: refused,
    // naming the file, and no output directory appears.
    let run = probmot(&["track", s(&bag), "-o", s(&tracked), "--quiet"]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("no metadata.yaml") && stderr.contains("city.mcap"),
        "{stderr}"
    );
    assert!(!tracked.exists());
    // Named as rosbag2 names it, it is read as a bag that lost its metadata.yaml, with a word.
    std::fs::rename(bag.join("city.mcap"), bag.join("drive_bag_0.mcap")).unwrap();
    let run = probmot_ok(&["track", s(&bag), "-o", s(&tracked), "--quiet"]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(stderr.contains("its file drive_bag_0.mcap"), "{stderr}");
    std::fs::remove_dir_all(&tracked).unwrap();
    std::fs::write(bag.join("metadata.yaml"), "rosbag2_bagfile_information:\n").unwrap();
    probmot_ok(&["track", s(&bag), "-o", s(&tracked), "--quiet"]);
    let (png, noise, txt) = (
        dir.path().join("p.png"),
        dir.path().join("n.json"),
        dir.path().join("t.txt"),
    );
    let runs: [Vec<&str>; 4] = [
        vec!["info", s(&bag)],
        vec!["plot", s(&tracked), "-o", s(&png), "--quiet"],
        vec!["fit", s(&bag), "-o", s(&noise)],
        vec!["export", "kitti", s(&tracked), "-o", s(&txt)],
    ];
    for args in runs {
        probmot_ok(&args);
    }
    for f in [&png, &noise, &txt] {
        assert!(f.is_file(), "{}", f.display());
    }
}

/// `fit` and `tune` take the base under either command's names (`fit --base-preset`, `tune
/// --preset`): each accepts the other's spelling.
#[test]
fn fit_and_tune_take_each_others_base_flags() {
    let dir = tempfile::tempdir().unwrap();
    let log = repo("sample_logs/pedestrians.mcap");
    let out = dir.path().join("out.json");
    let base = ["--quiet", "-o", s(&out)];
    probmot_ok(&[&["fit", s(&log), "--preset", "ab3dmot-kitti"][..], &base].concat());
    let cfg = std::fs::read_to_string(&out).unwrap();
    assert!(cfg.contains("on ab3dmot-kitti"), "{cfg}");
    let tune = [
        "tune",
        s(&log),
        "--base-preset",
        "ab3dmot-kitti",
        "--folds",
        "1",
    ];
    probmot_ok(&[&tune[..], &["--budget", "2"], &base].concat());
    let cfg = std::fs::read_to_string(&out).unwrap();
    assert!(cfg.contains("on ab3dmot-kitti"), "{cfg}");
}

/// `info` on a tracked log marks the `/tracks/scene` SceneUpdate as probmot's own output, not as
/// "usable as detections" beside the real detections.
#[test]
fn info_marks_probmots_own_outputs() {
    let dir = tempfile::tempdir().unwrap();
    let tracked = dir.path().join("t.mcap");
    let city = repo("sample_logs/city.mcap");
    probmot_ok(&["track", s(&city), "-o", s(&tracked), "--quiet"]);
    let text = String::from_utf8(probmot_ok(&["info", s(&tracked)]).stdout).unwrap();
    let line = |topic: &str| {
        let l = text.lines().find(|l| l.contains(&format!(") {topic} ")));
        l.unwrap_or_else(|| panic!("no {topic} line: {text}"))
            .to_string()
    };
    assert!(
        line("/detections").ends_with("<- usable as detections"),
        "{text}"
    );
    let scene = line("/tracks/scene");
    assert!(
        scene.ends_with("<- probmot's own output (read as detections only when named)"),
        "{scene}"
    );
}

/// `import` and `export` take `--quiet` (before or after the format) like the other commands:
/// no summary line, the same files.
#[test]
fn import_and_export_are_quiet_on_request() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::create_dir(d.join("dets")).unwrap();
    let label = |f: u32, z: f64| {
        format!("{f} 1 Car 0 0 -1.5 100 150 200 220 1.5 1.7 4.0 2.0 1.6 {z} -1.57\n")
    };
    std::fs::write(d.join("labels.txt"), label(0, 15.0) + &label(1, 15.5)).unwrap();
    let det =
        |f: u32, z: f64| format!("{f},2,100,150,200,220,0.9,1.5,1.7,4.0,2.0,1.6,{z},-1.57,-1.5\n");
    std::fs::write(d.join("dets/0000.txt"), det(0, 15.0) + &det(1, 15.5)).unwrap();
    let (labels, dets) = (d.join("labels.txt"), d.join("dets"));
    let import = |out: &str, quiet: &[&str], after: &[&str]| {
        let out = d.join(out);
        let args = [
            &["import"][..],
            quiet,
            &["kitti", "--labels", s(&labels), "--sequence", "0000"],
            &["--detections", s(&dets), "-o", s(&out)],
            after,
        ]
        .concat();
        (probmot_ok(&args).stdout, std::fs::read(out).unwrap())
    };
    let (said, loud) = import("loud.mcap", &[], &[]);
    assert!(String::from_utf8_lossy(&said).contains("2 ground-truth rows"));
    for (quiet, after) in [(&["-q"][..], &[][..]), (&[], &["--quiet"])] {
        let (said, bytes) = import("quiet.mcap", quiet, after);
        assert!(said.is_empty(), "{}", String::from_utf8_lossy(&said));
        assert_eq!(bytes, loud);
    }
    let loud_log = d.join("loud.mcap");
    let export = |quiet: &[&str]| {
        let out = d.join("gt.txt");
        let args = [
            &["export", "kitti", s(&loud_log), "--topic", "/ground_truth"][..],
            &["-o", s(&out)],
            quiet,
        ]
        .concat();
        (
            probmot_ok(&args).stdout,
            std::fs::read_to_string(out).unwrap(),
        )
    };
    let (said, rows) = export(&[]);
    assert!(String::from_utf8_lossy(&said).contains("2 rows in 2 frames"));
    assert_eq!(export(&["--quiet"]), (Vec::new(), rows));
}

/// `import kitti --labels` alone writes a log of ground truth only: no `/detections` channel,
/// so `track` warns instead of writing empty tracks, and the export gives the labels back.
/// With no input at all, the error names the three inputs.
#[test]
fn import_kitti_takes_labels_alone() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let label = |f: u32, id: u32, z: f64| {
        let fixed = "Car 0 0 -1.500000 100.000000 150.000000 200.000000 220.000000";
        format!("{f} {id} {fixed} 1.500000 1.700000 4.000000 2.000000 1.600000 {z:.6} -1.570000\n")
    };
    let rows = label(0, 1, 15.0) + &label(1, 1, 15.5) + &label(1, 2, 30.0);
    std::fs::write(d.join("0007.txt"), &rows).unwrap();
    let (labels, log) = (d.join("0007.txt"), d.join("truth.mcap"));
    let said = probmot_ok(&["import", "kitti", "--labels", s(&labels), "-o", s(&log)]);
    let said = String::from_utf8_lossy(&said.stdout);
    assert!(
        said.contains("sequence 0007, 2 frames") && said.contains("3 ground-truth rows"),
        "{said}"
    );
    let topics: std::collections::BTreeSet<String> = crate::common::messages(&log)
        .into_iter()
        .map(|m| m.topic)
        .collect();
    assert_eq!(topics.into_iter().collect::<Vec<_>>(), ["/ground_truth"]);
    // What `tune` and `export nuscenes` ask the summary before reading any message.
    use probmot::mcapio::reader::has_metadata;
    assert_eq!(has_metadata(&log, "probmot.kitti"), Some(true));
    assert_eq!(
        has_metadata(&repo("sample_logs/city.mcap"), "probmot.kitti"),
        Some(false)
    );

    let tracked = d.join("tracked.mcap");
    let run = probmot_ok(&["track", s(&log), "-o", s(&tracked)]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(stderr.contains("no detection channel"), "{stderr}");

    let back = d.join("back.txt");
    let untracked = probmot(&["export", "kitti", s(&log), "-o", s(&back)]);
    let stderr = String::from_utf8_lossy(&untracked.stderr);
    assert!(
        stderr.contains("`--topic /ground_truth` reads the truth"),
        "{stderr}"
    );
    probmot_ok(&[
        "export",
        "kitti",
        s(&log),
        "--topic",
        "/ground_truth",
        "-o",
        s(&back),
    ]);
    let mut want: Vec<&str> = rows.lines().collect();
    let got = std::fs::read_to_string(&back).unwrap();
    let mut got: Vec<&str> = got.lines().collect();
    want.sort();
    got.sort();
    assert_eq!(got, want);

    let none = probmot(&["import", "kitti", "--sequence", "0007", "-o", s(&log)]);
    let stderr = String::from_utf8_lossy(&none.stderr);
    assert_eq!(none.status.code(), Some(2), "{stderr}");
    assert!(
        ["--labels", "--detections", "--tracks"]
            .iter()
            .all(|f| stderr.contains(f)),
        "{stderr}"
    );
}

/// The nuScenes protocol (eval's default) on a KITTI import names the labels it does not
/// evaluate (KITTI's `cyclist` is nuScenes' `bicycle`) instead of leaving them out unsaid.
#[test]
fn eval_names_the_labels_it_does_not_evaluate() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let row = |f: u32, id: u32, kind: &str, z: f64| {
        let fixed = "0 0 -1.500000 100.000000 150.000000 200.000000 220.000000";
        format!("{f} {id} {kind} {fixed} 1.500000 1.700000 4.000000 2.000000 1.600000 {z:.6} -1.570000\n")
    };
    let rows: String = (0..3)
        .flat_map(|f| [row(f, 1, "Car", 15.0), row(f, 2, "Cyclist", 30.0)])
        .collect();
    std::fs::write(d.join("0001.txt"), rows).unwrap();
    let log = d.join("truth.mcap");
    probmot_ok(&[
        "import",
        "kitti",
        "--labels",
        s(&d.join("0001.txt")),
        "-o",
        s(&log),
        "-q",
    ]);
    let args = [
        "eval",
        "--truth",
        s(&log),
        "--tracks",
        s(&log),
        "--tracks-topic",
        "/ground_truth",
    ];
    let out = probmot_ok(&args);
    let all = String::from_utf8_lossy(&out.stdout) + String::from_utf8_lossy(&out.stderr);
    assert!(
        all.contains("labels with ground truth not evaluated (not classes of the nuScenes")
            && all.contains("--protocol kitti evaluates these KITTI logs")
            && all.contains("cyclist (3 truth, 3 track boxes)")
            && !all.contains("car ("),
        "{all}"
    );
    let with = probmot_ok(&[&args[..], &["--classes", "car,cyclist"]].concat());
    let all = String::from_utf8_lossy(&with.stdout) + String::from_utf8_lossy(&with.stderr);
    assert!(!all.contains("not evaluated"), "{all}");
}

/// `import kitti --detections` given the dataset folder (one level too high) does not read the
/// label file as detections, and a label file given as detections is named as one.
#[test]
fn import_kitti_detections_one_folder_too_high() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("kitti");
    std::fs::create_dir_all(root.join("label_02")).unwrap();
    std::fs::create_dir_all(root.join("pointrcnn/Car")).unwrap();
    let labels = root.join("label_02/0000.txt");
    let row = "0 1 Car 0 0 -1.5 100 150 200 220 1.5 1.7 4.0 2.0 1.6 15.0 -1.57\n";
    std::fs::write(&labels, row).unwrap();
    let det = "0,2,100,150,200,220,0.9,1.5,1.7,4.0,2.0,1.6,15.0,-1.57,-1.5\n";
    std::fs::write(root.join("pointrcnn/Car/0000.txt"), det).unwrap();
    std::fs::create_dir_all(root.join("calib")).unwrap();
    let p0 = "P0: 7.2e+02 0.0 6.0e+02 0.0 0.0 7.2e+02 1.7e+02 0.0 0.0 0.0 1.0 0.0\n";
    std::fs::write(root.join("calib/0000.txt"), p0).unwrap();
    std::fs::create_dir_all(root.join("oxts")).unwrap();
    let oxts = format!("49.0 8.4 113.8 0.02{}\n", " 0.1".repeat(26));
    std::fs::write(root.join("oxts/0000.txt"), oxts).unwrap();
    let out = dir.path().join("0000.mcap");
    let import = |dets: &std::path::Path| {
        let args = [
            "import",
            "kitti",
            "--labels",
            s(&labels),
            "--detections",
            s(dets),
        ];
        probmot(&[&args[..], &["-o", s(&out), "-q"]].concat())
    };
    let run = import(&root);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("no detection file 0000.txt")
            && stderr.contains("skipped, not detection files")
            && stderr.contains("calib/0000.txt")
            && stderr.contains("oxts/0000.txt")
            && stderr.contains("label_02/0000.txt")
            && !stderr.contains("comma-separated"),
        "{stderr}"
    );
    let run = import(&labels);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(
        stderr.contains("a line of the label or tracking result format"),
        "{stderr}"
    );
    assert!(!out.exists());
    let run = import(&root.join("pointrcnn"));
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    // A damaged detection file in the folder is an error naming it, not a file left out.
    std::fs::remove_file(&out).unwrap();
    std::fs::create_dir_all(root.join("pointrcnn/Pedestrian")).unwrap();
    let damaged = format!("\u{feff}{det}");
    std::fs::write(root.join("pointrcnn/Pedestrian/0000.txt"), damaged).unwrap();
    let run = import(&root.join("pointrcnn"));
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("Pedestrian/0000.txt"), "{stderr}");
    assert!(!out.exists());
}

/// A 10 Hz log under the default preset (set for nuScenes' 2 Hz) gets the frame-rate warning
/// with the `--dt-nominal` to try; the same log with that flag, or with a config fitted on it
/// (other noise than the preset's, converted to the fit's own `dt_nominal`), does not.
#[test]
fn a_log_at_another_rate_than_the_preset_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("c10.mcap");
    let out = dir.path().join("out.mcap");
    let fitted = dir.path().join("fit.json");
    probmot_ok(&[
        "simulate",
        "--scenario",
        "city",
        "--rate",
        "10",
        "--frames",
        "60",
        "-q",
        "-o",
        s(&log),
    ]);
    let warning = |extra: &[&str]| {
        let mut args = vec!["track", s(&log), "-o", s(&out), "--quiet"];
        args.extend_from_slice(extra);
        let run = probmot_ok(&args);
        let stderr = String::from_utf8_lossy(&run.stderr).into_owned();
        stderr
            .lines()
            .find(|l| l.contains("apart"))
            .map(str::to_owned)
    };
    let w = warning(&[]).expect("a warning at 10 Hz under the 2 Hz preset");
    assert!(
        w.contains("0.1 s apart") && w.ends_with("--dt-nominal 0.1"),
        "{w}"
    );
    assert!(w.contains("nuscenes-chiu2019"), "{w}");
    assert_eq!(warning(&["--dt-nominal", "0.1"]), None);
    probmot_ok(&["fit", s(&log), "-o", s(&fitted), "-q"]);
    assert_eq!(warning(&["--config", s(&fitted)]), None);
}

/// A log named twice (here through two paths to one file, or an overlapping pattern) would count
/// twice in `eval`'s metrics and `fit`'s statistics, and could sit in a training and a held-out
/// fold of `tune` at once: each command refuses it, naming both.
#[test]
fn a_log_given_twice_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let city = repo("sample_logs/city.mcap");
    let again = repo("sample_logs/../sample_logs/city.mcap");
    let (city, again) = (s(&city), s(&again));
    let out = dir.path().join("out.json");
    let runs: [Vec<&str>; 4] = [
        vec!["fit", city, again, "-o", s(&out)],
        vec!["tune", city, again, "-o", s(&out), "--budget", "2"],
        vec!["eval", "--truth", city, "--truth", again],
        vec!["eval", "--truth", city, "--tracks", city, "--tracks", again],
    ];
    for args in runs {
        let r = probmot(&args);
        let err = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(2), "{args:?}: {err}");
        let named = format!("{again} is the same file as {city}, given before it");
        assert!(err.contains(&named), "{args:?}: {err}");
        assert!(!out.exists(), "{args:?}");
    }
    let pattern = format!("{}/*.mcap", repo("sample_logs").display());
    let r = probmot(&["eval", "--truth", &pattern, "--truth", city]);
    assert_eq!(r.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&r.stderr).contains("give each log once"));
}
