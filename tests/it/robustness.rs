//! Bad input gets a defined answer: skipped boxes are counted (or refused with --strict), bad
//! files fail with status 2 and leave no output, a killed run leaves no output, and no NaN ever
//! reaches a tracks message.

use std::collections::BTreeMap;
use std::path::Path;

use crate::common::*;
use probmot::msgs::{self, v3, Detection3D, Detections3D, Size3};

fn det(label: &str, c: [f64; 3], yaw: f64, score: f64) -> Detection3D {
    Detection3D {
        center: Some(v3(c)),
        size: Some(Size3 {
            length: 4.5,
            width: 1.9,
            height: 1.6,
        }),
        yaw,
        label: label.into(),
        score,
        ..Default::default()
    }
}

/// Writes `/detections` frames as protobuf (or JSON) messages.
fn write_log(path: &Path, frames: &[(u64, Vec<Detection3D>)], json: bool) {
    let mut w = mcap::Writer::new(std::io::BufWriter::new(
        std::fs::File::create(path).unwrap(),
    ))
    .unwrap();
    let (enc, schema_enc, schema_data): (&str, &str, &[u8]) = if json {
        ("json", "jsonschema", b"{}")
    } else {
        ("protobuf", "protobuf", msgs::DESCRIPTOR_SET)
    };
    let s = w
        .add_schema(msgs::DETECTIONS_SCHEMA, schema_enc, schema_data)
        .unwrap();
    let ch = w
        .add_channel(s, "/detections", enc, &BTreeMap::new())
        .unwrap();
    for (i, (stamp, dets)) in frames.iter().enumerate() {
        let m = Detections3D {
            stamp: Some(*stamp),
            frame_id: "map".into(),
            detections: dets.clone(),
        };
        let bytes = if json {
            serde_json::to_vec(&m).unwrap()
        } else {
            prost::Message::encode_to_vec(&m)
        };
        w.write_to_known_channel(
            &mcap::records::MessageHeader {
                channel_id: ch,
                sequence: i as u32,
                log_time: *stamp,
                publish_time: *stamp,
            },
            &bytes,
        )
        .unwrap();
    }
    w.finish().unwrap();
}

const S: u64 = 1_000_000_000;

fn straight_car(n: u64, gap_at: Option<(u64, u64)>) -> Vec<(u64, Vec<Detection3D>)> {
    let mut t = 0;
    (0..n)
        .map(|k| {
            if let Some((at, extra)) = gap_at {
                if k == at {
                    t += extra;
                }
            }
            t += S / 2;
            (t, vec![det("car", [5.0 * k as f64, 0.0, 0.8], 0.0, 0.9)])
        })
        .collect()
}

fn json_summary(out: &std::process::Output) -> serde_json::Value {
    serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
        panic!(
            "no JSON summary ({e}): {}",
            String::from_utf8_lossy(&out.stderr)
        )
    })
}

#[test]
fn bad_boxes_are_skipped_and_counted_or_refused_with_strict() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("in.mcap");
    let mut frames = straight_car(6, None);
    let mut bad_nan = det("car", [f64::NAN, 0.0, 0.0], 0.0, 0.9);
    bad_nan.yaw = 0.0;
    let mut bad_size = det("car", [50.0, 50.0, 0.0], 0.0, 0.9);
    bad_size.size.as_mut().unwrap().width = 0.0;
    let inf_score = det("car", [70.0, 70.0, 0.0], 0.0, f64::INFINITY);
    let mut no_size = det("car", [90.0, 90.0, 0.0], 0.0, 0.9);
    no_size.size = None;
    let logit = det("pedestrian", [-30.0, 5.0, 0.0], 0.0, 7.5);
    frames[2]
        .1
        .extend([bad_nan, bad_size, inf_score, no_size, logit]);
    frames[3].1.clear(); // an empty array is a frame with no detection
    write_log(&input, &frames, false);
    let out = dir.path().join("out.mcap");
    let run = probmot_ok(&[
        "track",
        input.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--json",
    ]);
    let s = json_summary(&run);
    let skipped = &s["detections"]["skipped"];
    assert_eq!(skipped["non_finite"], 2, "{s}");
    assert_eq!(skipped["non_positive_size"], 1);
    assert_eq!(skipped["missing_field"], 1);
    assert_eq!(s["detections"]["score_outside_unit"], 1);
    assert_eq!(s["frames"], 6);
    assert!(s["warnings"]
        .to_string()
        .contains("skipped 4 detection boxes"));
    for t in tracks(&out, "/tracks") {
        assert_finite(&t);
    }
    // The skipped boxes did not change the tracks: same as a log without them.
    let clean = dir.path().join("clean.mcap");
    let mut frames2 = straight_car(6, None);
    frames2[2]
        .1
        .push(det("pedestrian", [-30.0, 5.0, 0.0], 0.0, 7.5));
    frames2[3].1.clear();
    write_log(&clean, &frames2, false);
    let out2 = dir.path().join("out2.mcap");
    probmot_ok(&[
        "track",
        clean.to_str().unwrap(),
        "-o",
        out2.to_str().unwrap(),
        "--quiet",
    ]);
    assert_eq!(tracks(&out, "/tracks"), tracks(&out2, "/tracks"));

    // --strict: the first bad box is an error naming file, topic, log time and detection.
    let out3 = dir.path().join("strict.mcap");
    let r = probmot(&[
        "track",
        input.to_str().unwrap(),
        "-o",
        out3.to_str().unwrap(),
        "--strict",
    ]);
    assert_eq!(r.status.code(), Some(2));
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        err.contains("in.mcap") && err.contains("/detections") && err.contains("log_time"),
        "{err}"
    );
    assert!(
        err.contains("detection 1") && err.contains("non-finite"),
        "{err}"
    );
    assert!(!out3.exists());
}

/// A box whose label the config has no entry for is skipped and counted, and the warning names
/// the label and the config's classes (a preset for other classes drops nothing unsaid).
#[test]
fn unknown_labels_without_default_entry_are_counted() {
    let dir = tempfile::tempdir().unwrap();
    let cfg_path = dir.path().join("cfg.json");
    let mut cfg = probmot::tracker::TrackerConfig::preset("nuscenes-chiu2019").unwrap();
    cfg.default = None;
    std::fs::write(&cfg_path, cfg.to_json()).unwrap();
    let input = dir.path().join("in.mcap");
    let mut frames = straight_car(4, None);
    frames[1]
        .1
        .push(det("forklift", [20.0, 20.0, 0.0], 0.0, 0.9));
    write_log(&input, &frames, false);
    let out = dir.path().join("out.mcap");
    let run = probmot_ok(&[
        "track",
        input.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--json",
        "--config",
        cfg_path.to_str().unwrap(),
    ]);
    let s = json_summary(&run);
    assert_eq!(s["detections"]["skipped"]["unknown_label"], 1);
    assert_eq!(s["detections"]["unknown_labels"]["forklift"], 1);
    let w = s["warnings"][0].as_str().unwrap();
    assert!(
        w.contains("skipped 1 detection boxes (label not in the config")
            && w.contains("labels not in the config: \"forklift\" 1;")
            && w.contains("entries for bicycle, bus, car, motorcycle, pedestrian, trailer, truck"),
        "{w}"
    );
}

/// A config entry whose class name matches no label (`cars` for `car`) while that label falls to
/// the default entry is named in a warning; a config with entries for classes the log lacks,
/// all its labels known, gives none.
#[test]
fn a_config_entry_that_matches_no_label_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let mut cfg = probmot::tracker::TrackerConfig::preset("nuscenes-chiu2019").unwrap();
    let car = cfg.classes.remove("car").unwrap();
    cfg.classes.insert("cars".into(), car);
    let cfg_path = dir.path().join("cfg.json");
    std::fs::write(&cfg_path, cfg.to_json()).unwrap();
    let city = repo("sample_logs/city.mcap");
    let out = dir.path().join("out.mcap");
    let run = |extra: &[&str]| {
        let args = [
            "track",
            city.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--json",
        ];
        json_summary(&probmot_ok(&[&args[..], extra].concat()))["warnings"].to_string()
    };
    let w = run(&["--config", cfg_path.to_str().unwrap()]);
    assert!(
        w.contains("config entries that no detection's label matches, beside a near label that went to the default entry (entry \\\"cars\\\", label \\\"car\\\")"),
        "{w}"
    );
    let w = run(&[]);
    assert!(!w.contains("no detection's label matches"), "{w}");
}

#[test]
fn absurd_detection_counts_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("in.mcap");
    let many: Vec<Detection3D> = (0..1_000_000)
        .map(|i| det("car", [i as f64, 0.0, 0.0], 0.0, 0.5))
        .collect();
    write_log(&input, &[(S, many)], false);
    let out = dir.path().join("out.mcap");
    let r = probmot(&[
        "track",
        input.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(r.status.code(), Some(2));
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(err.contains("1000000 detections in one message"), "{err}");
    assert!(!out.exists());
}

#[test]
fn json_detections_track_like_protobuf() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("a.mcap"), dir.path().join("b.mcap"));
    write_log(&a, &straight_car(8, None), false);
    write_log(&b, &straight_car(8, None), true);
    let (oa, ob) = (dir.path().join("oa.mcap"), dir.path().join("ob.mcap"));
    probmot_ok(&[
        "track",
        a.to_str().unwrap(),
        "-o",
        oa.to_str().unwrap(),
        "--quiet",
    ]);
    probmot_ok(&[
        "track",
        b.to_str().unwrap(),
        "-o",
        ob.to_str().unwrap(),
        "--quiet",
    ]);
    let ta = tracks(&oa, "/tracks");
    assert_eq!(ta.len(), 8);
    assert_eq!(ta, tracks(&ob, "/tracks"));
}

#[test]
fn extreme_coordinates_and_long_gaps_give_no_nan() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("in.mcap");
    // A 10-second gap in the middle, and a second object 1e6 m away.
    let mut frames = straight_car(12, Some((6, 10 * S)));
    for (_, d) in frames.iter_mut() {
        d.push(det("car", [1e6, -1e6, 1e3], 3.0, 0.8));
    }
    // The car is missed in the frame right after the gap: it coasts through 10.5 s.
    frames[6].1.remove(0);
    write_log(&input, &frames, false);
    let out = dir.path().join("out.mcap");
    probmot_ok(&[
        "track",
        input.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    let t = tracks(&out, "/tracks");
    assert_eq!(t.len(), 12);
    for m in &t {
        assert_finite(m);
    }
    assert!(t[6].tracks.iter().any(|x| x.frames_since_update == 1));
}

#[test]
fn bad_files_fail_with_status_2_and_leave_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let good = std::fs::read(repo("sample_logs/city.mcap")).unwrap();
    let mut cases: Vec<(&str, Vec<u8>)> = vec![
        ("empty", vec![]),
        ("magic", {
            let mut b = good.clone();
            b[1] = b'X';
            b
        }),
        ("short", b"hello".to_vec()),
        // Cut inside the header record: nothing to read. (Cut later, a file is read up to the
        // cut: tests/it/cut_short.rs.)
        ("header", good[..12].to_vec()),
    ];
    // Corrupt a byte inside the first chunk's compressed records: its CRC no longer matches.
    let mut crc = good.clone();
    crc[200] ^= 0x55;
    cases.push(("crc", crc));
    for (name, bytes) in &cases {
        let input = dir.path().join(format!("{name}.mcap"));
        std::fs::write(&input, bytes).unwrap();
        let out = dir.path().join(format!("{name}.out.mcap"));
        let r = probmot(&[
            "track",
            input.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ]);
        assert_eq!(r.status.code(), Some(2), "{name}: {:?}", r);
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(err.contains(&format!("{name}.mcap")), "{name}: {err}");
        assert!(!err.contains("panicked"), "{name}: {err}");
        assert_eq!(
            err.contains("the file is empty"),
            *name == "empty",
            "{name}: {err}"
        );
        let short = err.contains("too short to be an MCAP file");
        assert_eq!(short, *name == "short", "{name}: {err}");
        assert_eq!(
            err.contains("cut short inside its header record"),
            *name == "header",
            "{name}: {err}"
        );
        assert!(!out.exists(), "{name}: output left behind");
        assert_eq!(
            &std::fs::read(&input).unwrap(),
            bytes,
            "{name}: input changed"
        );
    }
    // Nothing else was left in the directory (no temporary files either).
    let left = std::fs::read_dir(dir.path()).unwrap().count();
    assert_eq!(left, cases.len());
    // An unreadable input path.
    let r = probmot(&[
        "track",
        "/nonexistent/in.mcap",
        "-o",
        dir.path().join("x.mcap").to_str().unwrap(),
    ]);
    assert_eq!(r.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&r.stderr).contains("/nonexistent/in.mcap"));
}

#[test]
fn killed_run_leaves_no_output_and_an_intact_input() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("big.mcap");
    probmot_ok(&[
        "simulate",
        "--scenario",
        "city",
        "--frames",
        "2000",
        "--objects",
        "120",
        "-o",
        input.to_str().unwrap(),
    ]);
    let before = std::fs::read(&input).unwrap();
    let out_dir = dir.path().join("out");
    std::fs::create_dir(&out_dir).unwrap();
    let out = out_dir.join("big.tracked.mcap");
    let mut child = bin()
        .args([
            "track",
            input.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--quiet",
        ])
        .spawn()
        .unwrap();
    // Wait until the output is being written (its temporary file exists), then SIGKILL.
    let started = std::time::Instant::now();
    loop {
        let writing = std::fs::read_dir(&out_dir).unwrap().count() > 0;
        if writing || started.elapsed().as_secs() > 60 {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    std::thread::sleep(std::time::Duration::from_millis(200));
    let finished_already = child.try_wait().unwrap().is_some();
    child.kill().unwrap();
    child.wait().unwrap();
    assert!(
        !finished_already,
        "the run finished before it could be killed; use a bigger log"
    );
    assert!(!out.exists(), "a killed run left an output file");
    assert!(
        std::fs::read(&input).unwrap() == before,
        "the input changed"
    );
}

#[test]
fn stamps_going_backwards_are_replayed_in_order_and_counted() {
    let dir = tempfile::tempdir().unwrap();
    let sorted = straight_car(6, None);
    let mut shuffled = sorted.clone();
    shuffled.swap(1, 4); // two stamps out of order on the one topic
    let (a, b) = (dir.path().join("a.mcap"), dir.path().join("b.mcap"));
    write_log(&a, &sorted, false);
    write_log(&b, &shuffled, false);
    let (oa, ob) = (dir.path().join("oa.mcap"), dir.path().join("ob.mcap"));
    probmot_ok(&[
        "track",
        a.to_str().unwrap(),
        "-o",
        oa.to_str().unwrap(),
        "--quiet",
    ]);
    let run = probmot_ok(&[
        "track",
        b.to_str().unwrap(),
        "-o",
        ob.to_str().unwrap(),
        "--json",
    ]);
    let s = json_summary(&run);
    // 1 4 3 2 5 -> the stamp drops after 4 and after 3.
    assert_eq!(s["stamps_backwards"]["/detections"], 2, "{s}");
    let mut ta = tracks(&oa, "/tracks");
    let mut tb = tracks(&ob, "/tracks");
    ta.sort_by_key(|t| t.stamp);
    tb.sort_by_key(|t| t.stamp);
    assert_eq!(ta, tb);
}

#[cfg(unix)]
#[test]
fn a_closed_stdout_pipe_ends_the_process_without_a_panic() {
    // `probmot info --json | head -0`: the reader is gone before probmot writes.
    use std::os::unix::process::ExitStatusExt;
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    let out = bin()
        .args([
            "info",
            repo("sample_logs/city.mcap").to_str().unwrap(),
            "--json",
        ])
        .stdout(writer)
        .stderr(std::process::Stdio::piped())
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert_eq!(
        out.status.signal(),
        Some(13),
        "ended by SIGPIPE: {:?}",
        out.status
    );
}

/// A ground-truth (or track) box with a non-finite number the command reads cannot be scored
/// or exported: `eval` (both protocols, the box in the truth or in the tracks), `tune` and
/// `export kitti` stop with an error naming the file, the topic, the stamp and the box, and
/// write nothing; `fit` leaves the box out and says so.
#[test]
fn non_finite_truth_is_an_error_naming_the_box() {
    let dir = tempfile::tempdir().unwrap();
    let nan = dir.path().join("nan.mcap");
    city_with_nan_truth(&nan);
    let city = repo("sample_logs/city.mcap");
    let (n, c) = (nan.to_str().unwrap(), city.to_str().unwrap());
    let out = dir.path().join("out.json");
    let o = out.to_str().unwrap();
    let gt = ["--tracks-topic", "/ground_truth"];
    let runs: [Vec<&str>; 5] = [
        [&["eval", "--truth", n, "--tracks", c][..], &gt].concat(),
        [
            &["eval", "--protocol", "kitti", "--truth", n, "--tracks", c][..],
            &gt,
        ]
        .concat(),
        [&["eval", "--truth", c, "--tracks", n][..], &gt].concat(),
        vec!["tune", n, "-o", o, "--protocol", "nuscenes", "--folds", "1"],
        vec!["export", "kitti", n, "-o", o, "--topic", "/ground_truth"],
    ];
    for args in runs {
        let r = probmot(&args);
        assert_eq!(r.status.code(), Some(2), "{args:?}");
        let err = String::from_utf8_lossy(&r.stderr);
        let want = format!("{n}: topic /ground_truth, stamp 1767225600000000000: box 0 ");
        assert!(
            err.contains(&want) && err.contains("id 5") && err.contains("non-finite"),
            "{args:?}: {err}"
        );
        assert!(!out.exists(), "{args:?} wrote an output");
    }
    let r = probmot_ok(&["fit", n, "-o", o, "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&r.stdout).unwrap();
    let warned = format!("{n}: skipped 1 ground-truth boxes with a non-finite centre, size or yaw");
    assert!(
        v["warnings"]
            .as_array()
            .unwrap()
            .iter()
            .any(|w| w == &warned),
        "{v}"
    );
}

/// The first box `eval` cannot score stops the reading there, under both protocols: the rest
/// of a long log is not read for an error already known. Every later ground-truth message is
/// garbage the reader could not decode, and the tracks file does not exist; the error is still
/// the first message's box.
#[test]
fn eval_stops_at_the_first_box_it_cannot_score() {
    use probmot::msgs::Tracks3D;
    use prost::Message as _;
    let dir = tempfile::tempdir().unwrap();
    let nan = dir.path().join("nan_then_garbage.mcap");
    city_with_messages(&nan, "/ground_truth", |i, data| match i {
        0 => {
            let mut t = Tracks3D::decode(data).unwrap();
            t.tracks[0].center.as_mut().unwrap().x = f64::NAN;
            t.encode_to_vec()
        }
        _ => vec![0xff; 7],
    });
    let missing = dir.path().join("missing.mcap");
    let (n, m) = (nan.to_str().unwrap(), missing.to_str().unwrap());
    for protocol in ["nuscenes", "kitti"] {
        let r = probmot(&["eval", "--protocol", protocol, "--truth", n, "--tracks", m]);
        assert_eq!(r.status.code(), Some(2), "{protocol}");
        let err = String::from_utf8_lossy(&r.stderr);
        let want = format!("{n}: topic /ground_truth, stamp 1767225600000000000: box 0 ");
        assert!(
            err.contains(&want) && err.contains("non-finite"),
            "{protocol}: {err}"
        );
    }
}

/// The nuScenes protocol reads a box's ground-plane centre and score only: a truth box whose
/// yaw is not a number (a ROS 2 zero quaternion, say) is scored as before, while the KITTI
/// protocol, whose 3D IoU reads the yaw, refuses it.
#[test]
fn the_nuscenes_protocol_checks_only_what_it_reads() {
    use probmot::msgs::Tracks3D;
    use prost::Message as _;
    let dir = tempfile::tempdir().unwrap();
    let nan_yaw = dir.path().join("nan_yaw.mcap");
    city_with_first_message(&nan_yaw, "/ground_truth", |data| {
        let mut t = Tracks3D::decode(data).unwrap();
        t.tracks[0].yaw = f64::NAN;
        t.encode_to_vec()
    });
    let city = repo("sample_logs/city.mcap");
    let (n, c) = (nan_yaw.to_str().unwrap(), city.to_str().unwrap());
    let gt = ["--tracks-topic", "/ground_truth", "--json"];
    let scored = |truth: &str| {
        let r = probmot_ok(&[&["eval", "--truth", truth, "--tracks", c][..], &gt].concat());
        let v: serde_json::Value = serde_json::from_slice(&r.stdout).unwrap();
        v["result"]["overall"]["amota"].as_f64().unwrap()
    };
    assert_eq!(scored(n), scored(c));
    let r = probmot(
        &[
            &["eval", "--protocol", "kitti", "--truth", n, "--tracks", c][..],
            &gt,
        ]
        .concat(),
    );
    assert_eq!(r.status.code(), Some(2));
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        err.contains("non-finite centre, size, yaw or score"),
        "{err}"
    );
}

/// `export kitti` checks every row before it opens the output, then writes them as it reads: a
/// box it cannot write in the last message (after about 130 KB of rows, more than its 64 KB
/// buffer) leaves no output and nothing beside it, and writes nothing to stdout, which has no
/// partial file to remove.
#[test]
fn export_kitti_stopped_late_leaves_nothing() {
    use probmot::msgs::Tracks3D;
    use prost::Message as _;
    let dir = tempfile::tempdir().unwrap();
    let nan = dir.path().join("nan_last.mcap");
    city_with_messages(&nan, "/ground_truth", |i, data| match i {
        39 => {
            let mut t = Tracks3D::decode(data).unwrap();
            t.tracks[0].center.as_mut().unwrap().x = f64::NAN;
            t.encode_to_vec()
        }
        _ => data.to_vec(),
    });
    let out = dir.path().join("gt.txt");
    let (n, o) = (nan.to_str().unwrap(), out.to_str().unwrap());
    let r = probmot(&["export", "kitti", n, "-o", o, "--topic", "/ground_truth"]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(2), "{err}");
    assert!(err.contains("non-finite") && err.contains("box 0"), "{err}");
    let left: Vec<String> = entries(dir.path());
    assert_eq!(left, ["nan_last.mcap"], "{err}");
    // Standard output through a link in the temporary folder (never the machine's /dev, see
    // tests/it/special_outputs.rs), to a pipe.
    let stdout = dir.path().join("stdout");
    std::os::unix::fs::symlink("/proc/self/fd/1", &stdout).unwrap();
    let o = stdout.to_str().unwrap();
    let r = probmot(&["export", "kitti", n, "-o", o, "--topic", "/ground_truth"]);
    assert_eq!(r.status.code(), Some(2));
    assert!(r.stdout.is_empty(), "{} bytes on stdout", r.stdout.len());
}
