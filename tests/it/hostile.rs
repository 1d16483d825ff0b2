//! Hostile values (issue #36): absurd numbers in a config or in one detection message of a
//! sample log, stamps far outside the log, shared stamps, a label that is not UTF-8, a read-only
//! output, a FIFO input, a file-size limit. Every input is made by the test from
//! `sample_logs/city.mcap`; no command may write a NaN, an infinite or an absurd value.

use std::path::Path;
use std::process::Output;

use crate::common::*;
use probmot::msgs::{v3, Detection3D, Detections3D, Size3};
use prost::Message as _;

/// `probmot track IN -o OUT --json EXTRA...`.
fn track(input: &Path, out: &Path, extra: &[&str]) -> Output {
    let args = [
        "track",
        input.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ];
    probmot(&[&args[..], &["--json"], extra].concat())
}

fn summary(out: &Output) -> serde_json::Value {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// A copy of city.mcap whose `/detections` message `k` is edited by `f`.
fn city_with(path: &Path, k: usize, f: impl Fn(&mut Detections3D)) {
    city_with_messages(path, "/detections", |i, data| {
        let mut m = Detections3D::decode(data).unwrap();
        if i == k {
            f(&mut m);
        }
        m.encode_to_vec()
    });
}

fn car(x: f64, size: f64, velocity: Option<[f64; 3]>) -> Detection3D {
    Detection3D {
        center: Some(v3([x, 0.0, 0.8])),
        size: Some(Size3 {
            length: size,
            width: 1.9,
            height: 1.6,
        }),
        label: "car".into(),
        score: 0.9,
        velocity: velocity.map(v3),
        ..Default::default()
    }
}

/// Every track of `out` is finite, within 30 m of the area of city.mcap's detections, and its
/// variances at most 1e12: the corrupted message moved nothing.
fn assert_tracks_where_the_objects_are(out: &Path) {
    let dets = detections(&repo("sample_logs/city.mcap"), "/detections");
    let (mut lo, mut hi) = ([f64::MAX; 2], [f64::MIN; 2]);
    for d in dets.iter().flat_map(|m| &m.detections) {
        let c = d.center.unwrap();
        for (i, v) in [c.x, c.y].into_iter().enumerate() {
            (lo[i], hi[i]) = (lo[i].min(v), hi[i].max(v));
        }
    }
    let frames = tracks(out, "/tracks");
    assert!(!frames.is_empty());
    for f in &frames {
        assert_finite(f);
        for t in &f.tracks {
            let c = t.center.unwrap();
            for (i, v) in [c.x, c.y].into_iter().enumerate() {
                assert!(v > lo[i] - 30.0 && v < hi[i] + 30.0, "track {t:?} far away");
            }
            let pv = t.position_variance.unwrap();
            assert!([pv.x, pv.y, pv.z, t.yaw_variance]
                .iter()
                .all(|v| *v <= 1e12));
        }
    }
}

/// Variances of 1e308 or 1e200 (which used to give NaN tracks and exit 0) are refused before
/// any work, naming the class and the field; nothing is written.
#[test]
fn a_config_beyond_the_variance_ceiling_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let city = repo("sample_logs/city.mcap");
    let out = dir.path().join("out.mcap");
    type Edit = fn(&mut probmot::tracker::ClassConfig);
    let cases: [(&str, Edit); 4] = [
        ("q[0] (x)", |c| c.q[0] = 1e308),
        ("q[7] (dx)", |c| c.q[7] = 1e200),
        ("r[1] (y)", |c| c.r[1] = 1e308),
        ("p0[0] (x)", |c| c.p0[0] = 1e308),
    ];
    for (field, edit) in cases {
        let mut cfg = probmot::tracker::TrackerConfig::preset("nuscenes-chiu2019").unwrap();
        edit(cfg.classes.get_mut("car").unwrap());
        // Written by hand: the library would refuse to build it.
        let path = dir.path().join("cfg.json");
        std::fs::write(&path, serde_json::to_string(&cfg).unwrap()).unwrap();
        let r = track(&city, &out, &["--config", path.to_str().unwrap()]);
        assert_eq!(r.status.code(), Some(2), "{field}");
        let err = stderr(&r);
        assert!(err.contains("class 'car'") && err.contains(field), "{err}");
        assert!(!out.exists());
    }
}

/// A centre at 1e308 m, a 20 km box, NaN and 1e6 m/s velocities in one message: each box is
/// skipped and counted, the warning names the first of each kind (topic, message, box), the
/// tracks stay where the objects are; with --strict the first is an error naming it.
#[test]
fn absurd_boxes_are_skipped_and_named() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("in.mcap");
    city_with(&input, 5, |m| {
        m.detections.push(car(1e308, 4.5, None));
        m.detections.push(car(10.0, 2e4, None));
        m.detections
            .push(car(10.0, 4.5, Some([f64::NAN, 0.0, 0.0])));
        m.detections.push(car(10.0, 4.5, Some([0.0, 1e6, 0.0])));
    });
    let out = dir.path().join("out.mcap");
    let s = summary(&track(&input, &out, &[]));
    let skipped = &s["detections"]["skipped"];
    for reason in [
        "centre_beyond_bound",
        "size_beyond_bound",
        "non_finite_velocity",
        "velocity_beyond_bound",
    ] {
        assert_eq!(skipped[reason], 1, "{reason}: {skipped}");
    }
    let w = s["warnings"].to_string();
    assert!(
        w.contains(
            "first: centre coordinate beyond 1e7 m at topic /detections, message at log_time"
        ) && w.contains("non-finite velocity at")
            && w.contains("detection "),
        "{w}"
    );
    assert_tracks_where_the_objects_are(&out);

    std::fs::remove_file(&out).unwrap();
    let r = track(&input, &out, &["--strict"]);
    assert_eq!(r.status.code(), Some(2));
    assert!(
        stderr(&r).contains("centre coordinate beyond 1e7 m (--strict)"),
        "{}",
        stderr(&r)
    );
    assert!(!out.exists());
}

/// A NaN velocity alone (issue #36 item 7): a warning, and an error with --strict.
#[test]
fn a_nan_velocity_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("in.mcap");
    city_with(&input, 3, |m| {
        m.detections[0].velocity = Some(v3([0.0, f64::NAN, 0.0]))
    });
    let out = dir.path().join("out.mcap");
    let s = summary(&track(&input, &out, &[]));
    assert!(
        s["warnings"].to_string().contains("non-finite velocity"),
        "{s}"
    );
    let r = track(&input, &out, &["--strict"]);
    let err = stderr(&r);
    assert_eq!(r.status.code(), Some(2), "{err}");
    assert!(
        err.contains("non-finite velocity") && err.contains("log_time"),
        "{err}"
    );
}

/// A message stamped u64::MAX among 2026 stamps is skipped with a warning naming it (the
/// single pass gives way to two), and refused with --strict; the tracks stay in place.
#[test]
fn a_stamp_far_outside_the_log_is_skipped_and_named() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("in.mcap");
    city_with(&input, 7, |m| m.stamp = Some(u64::MAX));
    let out = dir.path().join("out.mcap");
    let s = summary(&track(&input, &out, &[]));
    let w = s["warnings"].to_string();
    assert!(
        w.contains("skipped 1 detection messages whose stamp lies far (over 48 h) outside")
            && w.contains("(stamp 18446744073709551615)"),
        "{w}"
    );
    assert_eq!(s["passes"], 2);
    assert_tracks_where_the_objects_are(&out);
    let city = detections(&repo("sample_logs/city.mcap"), "/detections").len();
    assert_eq!(tracks(&out, "/tracks").len(), city - 1, "one frame fewer");

    let r = track(&input, &out, &["--strict"]);
    let err = stderr(&r);
    assert_eq!(r.status.code(), Some(2), "{err}");
    assert!(err.contains("lies far outside the log's time range") && err.contains("log_time"));
}

/// Two messages of one channel with the same stamp are tracked as one frame, and named.
#[test]
fn messages_sharing_a_stamp_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("in.mcap");
    let city = detections(&repo("sample_logs/city.mcap"), "/detections");
    let stamp = city[4].stamp;
    city_with(&input, 5, |m| m.stamp = stamp);
    let out = dir.path().join("out.mcap");
    let s = summary(&track(&input, &out, &[]));
    let w = s["warnings"].to_string();
    assert!(
        w.contains("1 detection messages have the same stamp as the message before them")
            && w.contains(&format!("share stamp {}", stamp.unwrap())),
        "{w}"
    );
    assert_eq!(tracks(&out, "/tracks").len(), city.len() - 1);
}

/// A copy of city.mcap in which the label of box 1 of `/detections` message 4 is not UTF-8.
fn city_with_bad_label(path: &Path) {
    city_with_messages(path, "/detections", |i, data| {
        let mut m = Detections3D::decode(data).unwrap();
        if i != 4 {
            return m.encode_to_vec();
        }
        m.detections[1].label = "QQQQ".into();
        let mut bytes = m.encode_to_vec();
        let at = bytes.windows(4).position(|w| w == b"QQQQ").unwrap();
        bytes[at..at + 4].copy_from_slice(&[0xc3, 0x28, 0xff, b'r']);
        bytes
    });
}

/// A box whose label is not UTF-8 is skipped and counted; the rest of its message is tracked.
#[test]
fn a_label_that_is_not_utf8_skips_only_its_box() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("in.mcap");
    city_with_bad_label(&input);
    let out = dir.path().join("out.mcap");
    let s = summary(&track(&input, &out, &[]));
    assert_eq!(s["detections"]["skipped"]["label_not_utf8"], 1, "{s}");
    let city = detections(&repo("sample_logs/city.mcap"), "/detections");
    let boxes: usize = city.iter().map(|m| m.detections.len()).sum();
    let kept: u64 = (s["detections"]["per_label"].as_object().unwrap().values())
        .map(|v| v.as_u64().unwrap())
        .sum();
    assert_eq!(kept as usize, boxes - 1);
    assert!(s["warnings"]
        .to_string()
        .contains("label not valid UTF-8 at topic /detections"));
}

/// The other commands that read detections take such a message as `track` does: `info`
/// counts the box apart, `fit` skips it with the same reason, `plot` draws the rest.
#[test]
fn every_command_reads_a_message_with_a_label_that_is_not_utf8() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("in.mcap");
    city_with_bad_label(&input);
    let city = detections(&repo("sample_logs/city.mcap"), "/detections");
    let boxes: u64 = city.iter().map(|m| m.detections.len() as u64).sum();

    let info = summary(&probmot(&["info", input.to_str().unwrap(), "--json"]));
    let ch = &info["channels"][0];
    assert_eq!(ch["topic"], "/detections");
    assert_eq!(
        (&ch["undecodable"], &ch["boxes_not_utf8"]),
        (&0.into(), &1.into()),
        "{ch}"
    );
    let per_label: u64 = (ch["per_label"].as_object().unwrap().values())
        .map(|v| v.as_u64().unwrap())
        .sum();
    assert_eq!(per_label, boxes - 1);
    let text = probmot(&["info", input.to_str().unwrap()]);
    assert!(String::from_utf8_lossy(&text.stdout)
        .contains("1 boxes have a label or id that is not UTF-8 (track skips them)"));

    let noise = dir.path().join("noise.json");
    let fit = summary(&probmot(&[
        "fit",
        input.to_str().unwrap(),
        "-o",
        noise.to_str().unwrap(),
        "--json",
    ]));
    assert_eq!(fit["detections"], boxes - 1, "{fit}");
    assert!(fit["warnings"]
        .to_string()
        .contains("skipped 1 detection boxes (label not valid UTF-8)"));

    let png = dir.path().join("city.png");
    let plot = ["plot", input.to_str().unwrap(), "-o", png.to_str().unwrap()];
    let r = probmot(&[&plot[..], &["--layers", "detections"]].concat());
    assert!(r.status.success() && png.exists(), "{}", stderr(&r));
}

/// A read-only output is not replaced: an error names it, and it keeps its bytes and mode.
#[cfg(unix)]
#[test]
fn a_read_only_output_is_refused() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.mcap");
    std::fs::write(&out, b"keep me").unwrap();
    std::fs::set_permissions(&out, std::fs::Permissions::from_mode(0o444)).unwrap();
    let r = track(&repo("sample_logs/city.mcap"), &out, &[]);
    let err = stderr(&r);
    assert_eq!(r.status.code(), Some(2), "{err}");
    assert!(err.contains("out.mcap exists and is read-only"), "{err}");
    assert_eq!(std::fs::read(&out).unwrap(), b"keep me");
    let mode = std::fs::metadata(&out).unwrap().permissions().mode();
    assert_eq!(mode & 0o777, 0o444);
    assert_eq!(entries(dir.path()), ["out.mcap"], "no partial file");
}

/// A FIFO, or a pipe given as /dev/stdin, is refused by name (track reads its input twice).
#[cfg(unix)]
#[test]
fn a_fifo_input_is_not_seekable() {
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("in.mcap");
    mkfifo(&fifo);
    let out = dir.path().join("out.mcap");
    let r = track(&fifo, &out, &[]);
    assert_eq!(r.status.code(), Some(2));
    assert!(
        stderr(&r).contains("in.mcap: not seekable"),
        "{}",
        stderr(&r)
    );
    let r = bin()
        .args(["track", "/dev/stdin", "-o", out.to_str().unwrap()])
        .stdin(std::process::Stdio::piped())
        .output()
        .unwrap();
    let err = stderr(&r);
    assert_eq!(r.status.code(), Some(2), "{err}");
    assert!(err.contains("/dev/stdin: not seekable") && err.contains("give a regular file"));
    assert!(!out.exists());
}

/// Under a file-size limit (`ulimit -f`) the write fails instead of SIGXFSZ killing the
/// process: exit 2, an error naming the output, no partial file; `simulate` names its file too.
#[cfg(unix)]
#[test]
fn a_file_size_limit_is_an_error_naming_the_output() {
    use std::os::unix::process::CommandExt;
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.mcap");
    let limited = |args: &[&str]| {
        let mut cmd = bin();
        cmd.args(args);
        // SAFETY: setrlimit only, in the child between fork and exec.
        unsafe {
            cmd.pre_exec(|| {
                let lim = libc::rlimit {
                    rlim_cur: 16 * 1024,
                    rlim_max: 16 * 1024,
                };
                match libc::setrlimit(libc::RLIMIT_FSIZE, &lim) {
                    0 => Ok(()),
                    _ => Err(std::io::Error::last_os_error()),
                }
            });
        }
        cmd.output().unwrap()
    };
    let city = repo("sample_logs/city.mcap");
    let out_s = out.to_str().unwrap();
    for args in [
        vec!["track", city.to_str().unwrap(), "-o", out_s],
        vec!["simulate", "--scenario", "city", "-o", out_s],
    ] {
        let r = limited(&args);
        let err = stderr(&r);
        assert_eq!(r.status.code(), Some(2), "{args:?}: {err}");
        assert!(
            err.contains(out_s) && err.contains("File too large"),
            "{err}"
        );
        assert!(entries(dir.path()).is_empty(), "{:?}", entries(dir.path()));
    }
}

/// A track whose variance grows past the ceiling over a long gap between frames is ended
/// (neither reported nor kept), and counted; a gap that keeps it within is not.
#[test]
fn a_track_beyond_the_bounds_is_ended() {
    use probmot::tracker::{Box3, Detection, Tracker, TrackerConfig};
    let mut cfg = TrackerConfig::preset("ab3dmot-2019").unwrap();
    let class = cfg.default.as_mut().unwrap();
    class.p0[7..].copy_from_slice(&[1e8; 4]);
    (class.min_hits, class.max_age) = (1, 5);
    let mut t = Tracker::new(cfg).unwrap();
    let car = t.class_id("car").unwrap();
    let det = Detection {
        bbox: Box3 {
            center: [0.0, 0.0, 0.0],
            yaw: 0.0,
            size: [4.0, 2.0, 1.5],
        },
        class: car,
        score: 0.9,
    };
    assert_eq!(t.step(0, &[det]).unwrap().len(), 1);
    let second = 1_000_000_000;
    assert_eq!(
        t.step(second, &[]).unwrap().len(),
        1,
        "a coast of 10 frames"
    );
    assert_eq!(t.stats().beyond_bounds, 0);
    let hour = 3600 * second;
    assert!(
        t.step(hour, &[]).unwrap().is_empty(),
        "variance 1e8 * 36000^2"
    );
    assert_eq!((t.stats().beyond_bounds, t.live_tracks()), (1, 0));
    assert_eq!(t.deleted().len(), 1);
}

/// A truth or track box at x = 1e308 (which `track` used to write) is refused by `eval` under
/// both protocols, naming the file, topic, stamp and box, as a non-finite one is.
#[test]
fn eval_refuses_a_box_beyond_the_bounds() {
    let dir = tempfile::tempdir().unwrap();
    let far = dir.path().join("far.mcap");
    city_with_messages(&far, "/ground_truth", |i, data| {
        let mut t = probmot::msgs::Tracks3D::decode(data).unwrap();
        if i == 0 {
            t.tracks[0].center.as_mut().unwrap().x = 1e308;
        }
        t.encode_to_vec()
    });
    let city = repo("sample_logs/city.mcap");
    let (f, c) = (far.to_str().unwrap(), city.to_str().unwrap());
    let gt = ["--tracks-topic", "/ground_truth"];
    for protocol in ["nuscenes", "kitti"] {
        for (truth, tracks) in [(f, c), (c, f)] {
            let args = [
                "eval",
                "--protocol",
                protocol,
                "--truth",
                truth,
                "--tracks",
                tracks,
            ];
            let r = probmot(&[&args[..], &gt].concat());
            let err = stderr(&r);
            assert_eq!(r.status.code(), Some(2), "{args:?}: {err}");
            assert!(
                err.contains(&format!("{f}: topic /ground_truth, stamp "))
                    && err.contains("box 0 (")
                    && err.contains("lies beyond the physical bounds"),
                "{err}"
            );
        }
    }
}
