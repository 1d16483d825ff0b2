//! Split and file-compressed rosbag2 bags (issue #35): a bag of several files is one drive.
//!
//! The bags are written by an independent writer, PyPI `rosbags`: scripts/make_autoware_bag.py
//! writes a drive, scripts/split_bag.py rewrites it split into files (each written by rosbags'
//! Writer, the later ones declaring their topics in another order, so with other ids), or
//! compressed whole with zstd. The tracked bags are read back whole by rosbags' AnyReader
//! (scripts/check_autoware_bag.py, which also compares metadata.yaml's counts with what it
//! reads). The property test splits one-file bags at arbitrary messages in Rust
//! (tests/it/common/split.rs), so that it can try many splits quickly.

use std::path::{Path, PathBuf};
use std::process::Command;

use probmot::pipeline::bag_track::track_path;
use probmot::pipeline::progress::no_progress;
use probmot::pipeline::track_options::{TrackOptions, TrackSummary};
use probmot::tracker::TrackerConfig;
use proptest::prelude::*;
use proptest::test_runner::{Config, TestRunner};

use crate::common::autoware_bag::{have_rosbags, make_autoware_bag};
use crate::common::split::split_mcap;
use crate::common::*;

const TRACKING_TOPIC: &str = "/perception/object_recognition/tracking/objects";

/// Runs a Python script of scripts/ with `args`; panics with its stderr when it fails.
fn python(script: &str, args: &[&Path], flags: &[&str]) -> Vec<u8> {
    let out = Command::new("python3")
        .arg(repo(script))
        .args(args)
        .args(flags)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{script}: {err}");
    out.stdout
}

/// The drive of scripts/make_autoware_bag.py (`flags`) in `d/drive`, its truth in
/// `d/drive.jsonl`.
fn drive(d: &Path, flags: &[&str]) -> PathBuf {
    make_autoware_bag(d, "drive", flags)
}

/// The MCAP files of a bag directory, in name order (the order of a split).
fn files(bag: &Path) -> Vec<PathBuf> {
    let mut f: Vec<PathBuf> = std::fs::read_dir(bag)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "mcap"))
        .collect();
    f.sort();
    f
}

/// `(log_time, bytes)` of every tracks message of the bag, file after file.
fn tracks_of(bag: &Path) -> Vec<(u64, Vec<u8>)> {
    (files(bag).iter())
        .flat_map(|f| messages(f))
        .filter(|m| m.topic == TRACKING_TOPIC)
        .map(|m| (m.log_time, m.data))
        .collect()
}

/// Per file: the `(topic, log_time)` of its messages other than the tracks, sorted.
fn input_messages(bag: &Path) -> Vec<Vec<(String, u64)>> {
    (files(bag).iter())
        .map(|f| {
            let mut m: Vec<(String, u64)> = (messages(f).into_iter())
                .filter(|m| m.topic != TRACKING_TOPIC)
                .map(|m| (m.topic, m.log_time))
                .collect();
            m.sort();
            m
        })
        .collect()
}

fn track(input: &Path, out: &Path) -> serde_json::Value {
    let (i, o) = (input.to_str().unwrap(), out.to_str().unwrap());
    let run = probmot_ok(&["track", i, "-o", o, "--json"]);
    serde_json::from_slice(&run.stdout).unwrap()
}

/// rosbags reads the tracked bag whole: 60 tracks messages, one UUID per object.
fn check_with_rosbags(out: &Path, d: &Path) {
    let truth = d.join("drive.jsonl");
    let text = python(
        "scripts/check_autoware_bag.py",
        &[out],
        &[
            "--messages",
            "60",
            "--ids",
            "5",
            "--truth",
            truth.to_str().unwrap(),
        ],
    );
    let text = String::from_utf8_lossy(&text);
    assert!(text.contains("5 UUIDs"), "{text}");
}

/// A drive split in two files (ego motion on /tf, so two passes) and in three (no /tf: one
/// pass over the files' summaries) tracks exactly as unsplit: the same tracks messages, byte
/// for byte; each output file holds the messages of its input file; rosbags reads the output
/// bag whole.
#[test]
fn a_split_bag_tracks_exactly_as_the_unsplit_bag() {
    if !have_rosbags("a_split_bag_tracks_exactly_as_the_unsplit_bag") {
        return;
    }
    for (flags, parts, passes) in [(&["--ego"][..], "2", 2), (&[][..], "3", 1)] {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let whole = drive(d, flags);
        let split = d.join("split");
        python(
            "scripts/split_bag.py",
            &[&whole, &split],
            &["--parts", parts],
        );
        let (out_whole, out_split) = (d.join("tracked_whole"), d.join("tracked_split"));
        track(&whole, &out_whole);
        let s = track(&split, &out_split);
        assert_eq!(s["passes"], passes, "{s}");
        assert_eq!(s["tracks_born"], 5, "{s}");
        let expected = tracks_of(&out_whole);
        assert_eq!(expected.len(), 60);
        assert!(
            tracks_of(&out_split) == expected,
            "tracks differ once split"
        );
        let n: usize = parts.parse().unwrap();
        assert_eq!(files(&out_split).len(), n);
        assert_eq!(input_messages(&out_split), input_messages(&split));
        check_with_rosbags(&out_split, d);
        let yaml = std::fs::read_to_string(out_split.join("metadata.yaml")).unwrap();
        assert!(yaml.contains("split_1.mcap") && yaml.contains(TRACKING_TOPIC));
    }
}

/// A bag compressed file by file (`.mcap.zstd`) tracks as the plain bag; the output is plain
/// MCAP files that rosbags reads, and the input is left as it was.
#[test]
fn a_file_compressed_bag_tracks_and_its_output_opens_in_rosbags() {
    if !have_rosbags("a_file_compressed_bag_tracks_and_its_output_opens_in_rosbags") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let whole = drive(d, &["--ego"]);
    let zbag = d.join("zbag");
    let flags = ["--parts", "2", "--compress"];
    python("scripts/split_bag.py", &[&whole, &zbag], &flags);
    let before: Vec<Vec<u8>> = (std::fs::read_dir(&zbag).unwrap())
        .map(|e| std::fs::read(e.unwrap().path()).unwrap())
        .collect();
    let (out_whole, out_z) = (d.join("tracked_whole"), d.join("tracked_z"));
    track(&whole, &out_whole);
    track(&zbag, &out_z);
    assert!(tracks_of(&out_z) == tracks_of(&out_whole));
    assert_eq!(
        entries(&out_z),
        ["metadata.yaml", "zbag_0.mcap", "zbag_1.mcap"]
    );
    let yaml = std::fs::read_to_string(out_z.join("metadata.yaml")).unwrap();
    assert!(yaml.contains("compression_mode: \"\""), "{yaml}");
    check_with_rosbags(&out_z, d);
    let after: Vec<Vec<u8>> = (std::fs::read_dir(&zbag).unwrap())
        .map(|e| std::fs::read(e.unwrap().path()).unwrap())
        .collect();
    assert!(before == after, "the input bag changed");
}

/// A damaged second file: the error names it, and neither the output bag nor its partial
/// directory is left behind.
#[test]
fn a_damaged_file_of_a_split_bag_is_named_and_leaves_no_output() {
    if !have_rosbags("a_damaged_file_of_a_split_bag_is_named_and_leaves_no_output") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let whole = drive(d, &[]);
    let split = d.join("split");
    python("scripts/split_bag.py", &[&whole, &split], &["--parts", "2"]);
    let second = split.join("split_1.mcap");
    // Its first bytes overwritten (a file cut short is read up to the cut: cut_short.rs).
    let mut bytes = std::fs::read(&second).unwrap();
    bytes[..8].copy_from_slice(b"NOTMCAP!");
    std::fs::write(&second, &bytes).unwrap();
    let out = d.join("tracked");
    let run = probmot(&[
        "track",
        split.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("split_1.mcap"), "{stderr}");
    assert_eq!(entries(d), ["drive", "drive.jsonl", "split"]);
}

/// Per output file: every message's `(topic, log_time, bytes)`.
fn all_messages(bag: &Path) -> Vec<Vec<(String, u64, Vec<u8>)>> {
    (files(bag).iter())
        .map(|f| {
            (messages(f).into_iter())
                .map(|m| (m.topic, m.log_time, m.data))
                .collect()
        })
        .collect()
}

/// The bytes of every file of `dir`, by name.
fn snapshot(dir: &Path) -> Vec<(String, Vec<u8>)> {
    (entries(dir).into_iter())
        .map(|n| (n.clone(), std::fs::read(dir.join(&n)).unwrap()))
        .collect()
}

/// Bags of the other kinds rosbag2 records, each split in two like the MCAP bag: sqlite3
/// storage (`.db3`, ROS 2 Humble's default), plain and compressed file by file (`.db3.zstd`,
/// read from a scratch copy that is gone after); the same without stored message definitions
/// (as Humble writes it) and with each message compressed on its own; and MCAP with compressed
/// messages. Each tracks exactly as the plain MCAP split: every message of every output file,
/// tracks included, the same, byte for byte; the output is a plain MCAP bag rosbags reads
/// whole (when the input stored its message definitions); the input is left as it was.
#[test]
fn sqlite3_and_message_compressed_bags_track_as_the_mcap_bag() {
    if !have_rosbags("sqlite3_and_message_compressed_bags_track_as_the_mcap_bag") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let whole = drive(d, &["--ego"]);
    let split = d.join("split");
    python("scripts/split_bag.py", &[&whole, &split], &["--parts", "2"]);
    let scratch = d.join("tmp");
    std::fs::create_dir(&scratch).unwrap();
    let out_split = d.join("tracked_split");
    track(&split, &out_split);
    let expected = all_messages(&out_split);
    assert_eq!(expected.iter().map(Vec::len).sum::<usize>(), 180);
    let kinds: [(&str, &[&str]); 4] = [
        ("db3", &["--storage", "sqlite3"]),
        ("zdb3", &["--storage", "sqlite3", "--compress"]),
        (
            "humble",
            &[
                "--storage",
                "sqlite3",
                "--no-definitions",
                "--compress-messages",
            ],
        ),
        ("zmsg", &["--compress-messages"]),
    ];
    for (name, flags) in kinds {
        let bag = d.join(name);
        let flags = [&["--parts", "2"][..], flags].concat();
        python("scripts/split_bag.py", &[&whole, &bag], &flags);
        let before = snapshot(&bag);
        let out = d.join(format!("tracked_{name}"));
        let (i, o) = (bag.to_str().unwrap(), out.to_str().unwrap());
        let run = bin()
            .env("TMPDIR", &scratch)
            .args(["track", i, "-o", o, "--json"])
            .output()
            .unwrap();
        assert!(
            run.status.success(),
            "{}",
            String::from_utf8_lossy(&run.stderr)
        );
        let s: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
        assert_eq!(s["tracks_born"], 5, "{name}: {s}");
        assert!(
            entries(&scratch).is_empty(),
            "{name}: a scratch file is left"
        );
        assert!(all_messages(&out) == expected, "{name}: the output differs");
        let mut names = [
            "metadata.yaml".to_string(),
            format!("{name}_0.mcap"),
            format!("{name}_1.mcap"),
        ];
        names.sort();
        assert_eq!(entries(&out), names, "{name}");
        let yaml = std::fs::read_to_string(out.join("metadata.yaml")).unwrap();
        assert!(yaml.contains("compression_mode: \"\""), "{yaml}");
        // The Humble bag stores no definitions, so its output has none for Autoware's
        // DetectedObjects either, and rosbags cannot decode those (docs/ros2.md).
        if name != "humble" {
            check_with_rosbags(&out, d);
        }
        assert!(snapshot(&bag) == before, "{name}: the input bag changed");
    }
    one_db3_file_on_its_own(&d.join("db3/db3_0.db3"), &expected[0], d);
}

/// A `.db3` file named on its own (no bag directory): `info` reads it, `track -o` and
/// `--out-dir` write it as an MCAP file (`NAME.mcap`) holding its messages; `expected` is the
/// tracked bag's first file, whose input messages they are.
fn one_db3_file_on_its_own(file: &Path, expected: &[(String, u64, Vec<u8>)], d: &Path) {
    let f = file.to_str().unwrap();
    let info = probmot_ok(&["info", f, "--json"]);
    let info: serde_json::Value = serde_json::from_slice(&info.stdout).unwrap();
    assert_eq!(info["messages"], 60, "{info}");
    let inputs = |v: Vec<(String, u64, Vec<u8>)>| -> Vec<(String, u64, Vec<u8>)> {
        let topics = ["/tf", "/perception/object_recognition/detection/objects"];
        v.into_iter()
            .filter(|m| topics.contains(&m.0.as_str()))
            .collect()
    };
    let one = d.join("one.mcap");
    let s = track(file, &one);
    assert_eq!(s["frames"], 30, "{s}");
    let got: Vec<_> = (messages(&one).into_iter())
        .map(|m| (m.topic, m.log_time, m.data))
        .collect();
    assert!(
        inputs(got) == inputs(expected.to_vec()),
        "the file's messages"
    );
    let out_dir = d.join("out_dir");
    let o = out_dir.to_str().unwrap();
    probmot_ok(&["track", f, "--out-dir", o, "--quiet"]);
    assert_eq!(entries(&out_dir), ["db3_0.mcap"]);
}

/// `info` on a split bag describes the whole drive; `--out-dir` takes a bag directory as one
/// input (beside a file), its output a bag directory of the same name.
#[test]
fn info_and_out_dir_take_a_split_bag_as_one_drive() {
    if !have_rosbags("info_and_out_dir_take_a_split_bag_as_one_drive") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let whole = drive(d, &["--ego"]);
    let split = d.join("split");
    python("scripts/split_bag.py", &[&whole, &split], &["--parts", "3"]);
    let info = probmot_ok(&["info", split.to_str().unwrap(), "--json"]);
    let info: serde_json::Value = serde_json::from_slice(&info.stdout).unwrap();
    assert_eq!(info["messages"], 120, "{info}");
    assert_eq!(info["channels"].as_array().unwrap().len(), 2, "{info}");
    let out = d.join("out");
    let log = repo("sample_logs/city.mcap");
    let (s, l, o) = (
        split.to_str().unwrap(),
        log.to_str().unwrap(),
        out.to_str().unwrap(),
    );
    probmot_ok(&["track", s, l, "--out-dir", o, "--jobs", "2", "--quiet"]);
    assert_eq!(entries(&out), ["city.mcap", "split"]);
    assert_eq!(files(&out.join("split")).len(), 3);
    let alone = d.join("alone");
    track(&split, &alone);
    assert!(tracks_of(&out.join("split")) == tracks_of(&alone));
}

/// `input` (a file or a bag directory) tracked in this process with `track`'s default options
/// into `out`.
fn track_here(input: &Path, out: &Path) -> TrackSummary {
    let config = TrackerConfig::preset("nuscenes-chiu2019").unwrap();
    track_path(input, out, &TrackOptions::new(config), &no_progress).unwrap()
}

/// The MCAP files of an output: the file itself, or the files of a bag directory.
fn output_files(out: &Path) -> Vec<PathBuf> {
    match out.is_dir() {
        true => files(out),
        false => vec![out.to_path_buf()],
    }
}

/// A message as compared: topic, log_time, publish_time, bytes.
type Stored = (String, u64, u64, Vec<u8>);

/// The messages of `files` on topics that are (or are not, when `inputs` is false) among
/// `topics`, file after file.
fn on_topics(files: &[PathBuf], topics: &[String], inputs: bool) -> Vec<Vec<Stored>> {
    (files.iter())
        .map(|f| {
            (messages(f).into_iter())
                .filter(|m| topics.contains(&m.topic) == inputs)
                .map(|m| (m.topic, m.log_time, m.publish_time, m.data))
                .collect()
        })
        .collect()
}

/// The one-file bag `input` (its one MCAP file `file`) split at `starts` tracks as unsplit:
/// the same summary counts, the same messages written beside the input ones (the tracks: ids
/// and boxes, byte for byte, in the same order), and each output file holds exactly the input
/// messages of its input file.
fn check_split(
    input: &Path,
    file: &Path,
    starts: &[usize],
    whole: &(TrackSummary, Vec<Stored>),
) -> Result<(), TestCaseError> {
    let dir = tempfile::tempdir().unwrap();
    let bag = dir.path().join("part");
    let parts = split_mcap(file, &bag, starts);
    let out = dir.path().join("tracked");
    let s = track_here(&bag, &out);
    let (w, written) = whole;
    prop_assert_eq!(
        (s.frames, s.tracks_born, s.passes, s.messages_copied),
        (w.frames, w.tracks_born, w.passes, w.messages_copied),
        "{} split at {:?}",
        input.display(),
        starts
    );
    let topics: Vec<String> = messages(file).into_iter().map(|m| m.topic).collect();
    let got = on_topics(&output_files(&out), &topics, false).concat();
    prop_assert!(
        &got == written,
        "the tracks differ once split at {starts:?}"
    );
    let (outs, ins) = (output_files(&out), on_topics(&parts, &topics, true));
    prop_assert_eq!(on_topics(&outs, &topics, true), ins, "input messages moved");
    Ok(())
}

/// Splitting a one-file bag at any message (one or two splits, each file declaring the
/// channels it uses in its own numbering) gives the same tracks as the unsplit bag: for the
/// vision_msgs fixture (written by mcap-ros2-support; tracked in one pass over the files'
/// summaries) and, when rosbags is installed, an Autoware drive with ego motion on /tf (two
/// passes).
#[test]
fn splitting_a_bag_at_any_message_gives_the_same_tracks() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut inputs = vec![(repo("tests/fixtures/ros2/city.mcap"), None)];
    if have_rosbags("splitting_a_bag_at_any_message_gives_the_same_tracks") {
        let bag = drive(d, &["--ego"]);
        let file = files(&bag).remove(0);
        inputs.push((bag, Some(file)));
    }
    for (i, (input, file)) in inputs.into_iter().enumerate() {
        let file = file.unwrap_or_else(|| input.clone());
        let ext = if input.is_dir() { "" } else { ".mcap" };
        let out = d.join(format!("whole{i}{ext}"));
        let summary = track_here(&input, &out);
        let topics: Vec<String> = messages(&file).into_iter().map(|m| m.topic).collect();
        let written = on_topics(&output_files(&out), &topics, false).concat();
        assert!(
            summary.tracks_born > 1 && written.len() >= 40,
            "{summary:?}"
        );
        let whole = (summary, written);
        let n = topics.len();
        let starts = proptest::collection::btree_set(1..n, 1..=2)
            .prop_map(|s| s.into_iter().collect::<Vec<usize>>());
        let mut runner = TestRunner::new(Config::with_cases(16));
        let result = runner.run(&starts, |starts| {
            check_split(&input, &file, &starts, &whole)
        });
        if let Err(e) = result {
            panic!("{}: {e}", input.display());
        }
    }
}

/// A Humble recording that lost power: no `metadata.yaml`, and its sqlite3 file's last pages
/// never written though its header counts them (rosbag2's default pragmas; SQLite alone refuses
/// such a file). `track` reads it as far as its pages go, with a warning for each; the tracks
/// are the whole recording's up to there.
#[test]
fn a_humble_recording_that_lost_power_tracks_as_far_as_its_pages_go() {
    if !have_rosbags("a_humble_recording_that_lost_power_tracks_as_far_as_its_pages_go") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let whole = make_autoware_bag(d, "drive", &["--frames", "400"]);
    let bag = d.join("humble");
    let flags = ["--parts", "1", "--storage", "sqlite3", "--no-definitions"];
    python("scripts/split_bag.py", &[&whole, &bag], &flags);
    let all_out = d.join("all");
    track(&bag, &all_out);
    std::fs::remove_file(bag.join("metadata.yaml")).unwrap();
    let file = bag.join("humble_0.db3");
    let bytes = std::fs::read(&file).unwrap();
    let pages = bytes.len() / 4096;
    std::fs::write(&file, &bytes[..(pages - pages / 4) * 4096]).unwrap();
    let out = d.join("out");
    let run = probmot(&["track", s(&bag), "-o", s(&out), "--quiet"]);
    let err = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(0), "{err}");
    assert!(err.contains("humble: no metadata.yaml"), "{err}");
    assert!(
        err.contains("humble_0.db3: the file is cut short")
            && err.contains(&format!("its header counts {pages} pages"))
            && err.contains("the rows after the first unreadable one were not"),
        "{err}"
    );
    // --strict refuses it (its tracking pass, which stops at the first pass's last row, meets
    // no damage: the first pass's finding is what counts).
    let strict = d.join("strict");
    let run = probmot(&["track", s(&bag), "-o", s(&strict), "--strict"]);
    assert_eq!(run.status.code(), Some(2), "{run:?}");
    assert!(!strict.exists());
    let (cut, all) = (tracks_of(&out), tracks_of(&all_out));
    assert!(
        all.len() / 2 < cut.len() && cut.len() < all.len(),
        "{} of {}",
        cut.len(),
        all.len()
    );
    assert!(cut[..] == all[..cut.len()], "the tracks up to the cut");
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}
