//! First-use errors that pointed the wrong way: `tune` on a misspelt log, `eval` with its file
//! as a positional argument, `info`'s count of boxes without a class, a misspelt topic (`track`
//! named no alternative, `plot` and `viz` dropped the layer), a file that is not MCAP at all,
//! and the options spelt differently from one command to the next (`export --topic`, `plot
//! --class` beside `eval --classes`), a count of 0 refused with the largest u64 in the message
//! or (`--jobs 0`) run on all cores unsaid, and `plot -o /dev/null` refused for its name; and
//! the exit statuses only the README gave.

use crate::common::{probmot, probmot_ok, repo};

fn s(p: &std::path::Path) -> &str {
    p.to_str().unwrap()
}

fn stderr_of_failure(args: &[&str]) -> String {
    let run = probmot(args);
    let stderr = String::from_utf8_lossy(&run.stderr).to_string();
    assert_eq!(run.status.code(), Some(2), "{args:?}: {stderr}");
    stderr
}

#[test]
fn tune_names_a_log_it_cannot_open() {
    let dir = tempfile::tempdir().unwrap();
    let missing = repo("sample_logs/cty.mcap");
    let out = dir.path().join("t.json");
    let err = stderr_of_failure(&["tune", s(&missing), "-o", s(&out)]);
    assert!(
        err.contains(&format!("cannot open {}", missing.display())),
        "{err}"
    );
    assert!(!err.contains("--folds"), "{err}");
    assert!(!out.exists());
}

#[test]
fn eval_with_a_positional_file_hints_truth() {
    let city = repo("sample_logs/city.mcap");
    let err = stderr_of_failure(&["eval", s(&city)]);
    assert!(
        err.contains(&format!("--truth {}", city.display())),
        "{err}"
    );
    assert!(err.contains("--tracks"), "{err}");
    // A second file after --truth is still one of its values, not a stray argument.
    let err = stderr_of_failure(&["eval", "--truth", s(&city), s(&city)]);
    assert!(!err.contains("unexpected argument"), "{err}");
}

#[test]
fn info_names_boxes_without_a_class() {
    let dir = tempfile::tempdir().unwrap();
    let tracked = dir.path().join("turning-car.tracked.mcap");
    let log = repo("sample_logs/turning-car.mcap");
    probmot_ok(&["track", s(&log), "-o", s(&tracked), "--quiet"]);
    let events = dir.path().join("events.mcap");
    probmot_ok(&["eval", "--truth", s(&tracked), "--events", s(&events), "-q"]);
    let out = String::from_utf8(probmot_ok(&["info", s(&events)]).stdout).unwrap();
    let counts: Vec<&str> = out
        .lines()
        .filter(|l| l.contains("boxes per class:"))
        .collect();
    assert!(counts.iter().any(|l| l.contains("(no class) ")), "{out}");
    // Every count has a name before it.
    for l in counts {
        let list = l.split("boxes per class:").nth(1).unwrap();
        for part in list.split(", ") {
            assert!(!part.starts_with("  ") && part.trim().contains(' '), "{l}");
        }
    }
}

#[test]
fn track_names_the_topics_beside_a_misspelt_detections_topic() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("t.mcap");
    let city = repo("sample_logs/city.mcap");
    let err = stderr_of_failure(&[
        "track",
        s(&city),
        "-o",
        s(&out),
        "--detections-topic",
        "/dets",
    ]);
    assert!(err.contains("no channel with topic /dets"), "{err}");
    assert!(err.contains("topics: /detections, /ground_truth"), "{err}");
    assert!(!out.exists());
}

#[test]
fn plot_refuses_a_named_topic_the_file_lacks() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("p.png");
    let city = repo("sample_logs/city.mcap");
    let err = stderr_of_failure(&["plot", s(&city), "-o", s(&png), "--truth-topic", "/gt"]);
    assert!(
        err.contains("no topic /gt for the ground_truth layer"),
        "{err}"
    );
    assert!(err.contains("--truth-topic"), "{err}");
    assert!(!png.exists());
    // The default topics stay optional: the untracked log has no /tracks and plots.
    probmot_ok(&["plot", s(&city), "-o", s(&png), "-q"]);
}

/// viz refuses a named topic the file lacks as plot does, before any recording is made (so
/// also without the `rerun` feature), naming the file's topics as every command does.
#[test]
fn viz_refuses_a_named_topic_the_file_lacks() {
    let dir = tempfile::tempdir().unwrap();
    let rrd = dir.path().join("v.rrd");
    let city = repo("sample_logs/city.mcap");
    let err = stderr_of_failure(&["viz", s(&city), "-o", s(&rrd), "--tracks-topic", "/trk"]);
    let want = format!(
        "{} has no topic /trk for the tracks layer (topics: /detections, /ground_truth); \
         check --tracks-topic",
        city.display()
    );
    assert!(err.contains(&want), "{err}");
    assert!(!err.contains("rerun` cargo feature"), "{err}");
    assert!(!rrd.exists());
    // The default topics stay optional: the untracked log has no /tracks and is recorded
    // (without the feature, only the feature is missing).
    let run = probmot(&["viz", s(&city), "-o", s(&rrd), "-q"]);
    let err = String::from_utf8_lossy(&run.stderr);
    match cfg!(feature = "rerun") {
        true => assert!(run.status.success() && rrd.is_file(), "{err}"),
        false => assert!(err.contains("rerun` cargo feature"), "{err}"),
    }
}

/// Every command that misses a topic names the file's topics the same way
/// (`recording::topic_list`): here a file with no channels, which plot once called `topics:
/// none`.
#[test]
fn every_command_names_a_file_without_channels_alike() {
    let dir = tempfile::tempdir().unwrap();
    let empty = dir.path().join("empty.mcap");
    let file = std::io::BufWriter::new(std::fs::File::create(&empty).unwrap());
    mcap::Writer::new(file).unwrap().finish().unwrap();
    let (e, out) = (s(&empty), dir.path().join("out"));
    let png = s(&out).to_string() + ".png";
    let rrd = s(&out).to_string() + ".rrd";
    let runs: [&[&str]; 7] = [
        &["plot", e, "-o", &png],
        &["plot", e, "-o", &png, "--layers", "tracks"],
        &["viz", e, "-o", &rrd, "--truth-topic", "/gt"],
        &["track", e, "-o", s(&out), "--detections-topic", "/d"],
        &["eval", "--truth", e],
        &["export", "kitti", e, "-o", s(&out)],
        &["fit", e, "-o", s(&out)],
    ];
    for args in runs {
        let err = stderr_of_failure(args);
        assert!(err.contains("the file has no channels)"), "{err}");
        assert!(!err.contains("none)"), "{err}");
    }
}

#[test]
fn a_file_that_is_not_mcap_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let bag = dir.path().join("drive.mcap");
    std::fs::write(&bag, b"#ROSBAG V2.0\nnot an mcap file at all").unwrap();
    let out = dir.path().join("t.mcap");
    for args in [vec!["info", s(&bag)], vec!["track", s(&bag), "-o", s(&out)]] {
        let err = stderr_of_failure(&args);
        assert!(err.contains(&bag.display().to_string()), "{err}");
        assert!(err.contains("not an MCAP file"), "{err}");
        assert!(err.contains("mcap convert"), "{err}");
    }
    assert!(!out.exists());
}

#[test]
fn export_takes_tracks_topic_like_the_other_commands() {
    let dir = tempfile::tempdir().unwrap();
    let city = repo("sample_logs/city.mcap");
    let (a, b) = (dir.path().join("a.txt"), dir.path().join("b.txt"));
    let truth = "/ground_truth";
    probmot_ok(&[
        "export",
        "kitti",
        s(&city),
        "-o",
        s(&a),
        "--topic",
        truth,
        "-q",
    ]);
    probmot_ok(&[
        "export",
        "kitti",
        s(&city),
        "-o",
        s(&b),
        "--tracks-topic",
        truth,
        "-q",
    ]);
    assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
    // Every topic option shows its value as TOPIC.
    for cmd in [&["eval"][..], &["export", "kitti"], &["export", "nuscenes"]] {
        let help = String::from_utf8(probmot_ok(&[cmd, &["--help"]].concat()).stdout).unwrap();
        for l in help.lines().filter(|l| l.contains("-topic <")) {
            assert!(l.contains("-topic <TOPIC>"), "{cmd:?}: {l}");
        }
    }
}

#[test]
fn class_and_classes_are_one_option_everywhere() {
    let dir = tempfile::tempdir().unwrap();
    let tracked = dir.path().join("city.tracked.mcap");
    probmot_ok(&[
        "track",
        s(&repo("sample_logs/city.mcap")),
        "-o",
        s(&tracked),
        "-q",
    ]);
    let stdout = |args: &[&str]| probmot_ok(args).stdout;
    let eval = ["eval", "--truth", s(&tracked), "--json", "-q"];
    assert_eq!(
        stdout(&[&eval[..], &["--classes", "car,bus"]].concat()),
        stdout(&[&eval[..], &["--class", "car,bus"]].concat())
    );
    let (one, two) = (dir.path().join("1.png"), dir.path().join("2.png"));
    probmot_ok(&["plot", s(&tracked), "-o", s(&one), "--class", "car", "-q"]);
    probmot_ok(&["plot", s(&tracked), "-o", s(&two), "--classes", "car", "-q"]);
    assert_eq!(std::fs::read(&one).unwrap(), std::fs::read(&two).unwrap());
}

#[test]
fn counts_out_of_range_are_refused_in_words() {
    let city = repo("sample_logs/city.mcap");
    for (flag, words) in [
        ("--bootstrap", "0 is too small: give at least 1"),
        ("--min-points", "0 is too small: give at least 1"),
        (
            "--max-chunk-mib",
            "0 is out of range: give 1 to 1099511627776",
        ),
    ] {
        let err = stderr_of_failure(&["eval", "--truth", s(&city), flag, "0"]);
        assert!(err.contains(&format!("for '{flag} <")), "{err}");
        assert!(err.contains(words), "{err}");
        assert!(!err.contains("18446744073709551615"), "{err}");
    }
    let err = stderr_of_failure(&["eval", "--truth", s(&city), "--bootstrap", "many"]);
    assert!(err.contains("`many` is not a whole number"), "{err}");
    // In range, the value is taken.
    let err = stderr_of_failure(&["eval", "--truth", s(&city), "--bootstrap", "1"]);
    assert!(err.contains("/tracks"), "{err}");
}

/// `--jobs` follows one rule in `track` and `tune`: at least 1, all cores when left out, both
/// said in the help; `--jobs 0` is refused in words, not run on all cores unsaid.
#[test]
fn jobs_out_of_range_is_refused_alike_and_the_default_is_said() {
    let dir = tempfile::tempdir().unwrap();
    let city = repo("sample_logs/city.mcap");
    let out = dir.path().join("out");
    for cmd in ["track", "tune"] {
        let err = stderr_of_failure(&[cmd, s(&city), "-o", s(&out), "--jobs", "0"]);
        assert!(err.contains("for '--jobs <N>'"), "{cmd}: {err}");
        assert!(
            err.contains("0 is out of range: give 1 to 1024"),
            "{cmd}: {err}"
        );
        let err = stderr_of_failure(&[cmd, s(&city), "-o", s(&out), "--jobs", "100000"]);
        assert!(
            err.contains("100000 is out of range: give 1 to 1024"),
            "{cmd}: {err}"
        );
        assert!(!out.exists(), "{cmd}");
        let help = String::from_utf8(probmot_ok(&[cmd, "--help"]).stdout).unwrap();
        let jobs = help.split("--jobs <N>").nth(1).unwrap();
        let text = jobs.split("\n\n").next().unwrap();
        assert!(
            text.contains("1 to 1024 (default: all cores)"),
            "{cmd}: {text}"
        );
    }
    probmot_ok(&["track", s(&city), "-o", s(&out), "--jobs", "1", "-q"]);
}

#[test]
fn plot_writes_into_a_device_or_fifo_whatever_its_name() {
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("picture");
    crate::common::mkfifo(&fifo);
    let reader = {
        let fifo = fifo.clone();
        std::thread::spawn(move || std::fs::read(fifo).unwrap())
    };
    let city = repo("sample_logs/city.mcap");
    let run = probmot(&["plot", s(&city), "-o", s(&fifo), "-q"]);
    if !run.status.success() {
        // Let the reader's open return, so that the failure below is reported, not a hang.
        drop(std::fs::OpenOptions::new().write(true).open(&fifo));
    }
    let png = reader.join().unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert!(png.starts_with(b"\x89PNG"));
    // A regular file still needs the .png its format takes.
    let err = stderr_of_failure(&["plot", s(&city), "-o", s(&dir.path().join("p.jpg"))]);
    assert!(err.contains("must end in .png"), "{err}");
}

#[test]
fn the_top_help_gives_the_exit_statuses() {
    let help = String::from_utf8(probmot_ok(&["--help"]).stdout).unwrap();
    let status = help.split_once("Exit status:").map(|(_, rest)| rest);
    let status = status.unwrap_or_else(|| panic!("no exit status in:\n{help}"));
    for code in [
        "0 success",
        "2 error",
        "3 the evaluation",
        "130, 143 or 129",
    ] {
        assert!(status.contains(code), "{code}: {help}");
    }
}
