//! Helpers shared by the integration tests.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use probmot::msgs::{Detections3D, Tracks3D};
use prost::Message as _;

pub mod alloc;
pub mod autoware_bag;
pub mod split;

/// The probmot binary built for the tests.
pub fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_probmot"))
}

/// Runs probmot with arguments; returns the output (any exit status).
pub fn probmot(args: &[&str]) -> Output {
    bin().args(args).output().expect("run probmot")
}

/// Runs probmot and asserts success.
pub fn probmot_ok(args: &[&str]) -> Output {
    let out = probmot(args);
    assert!(
        out.status.success(),
        "probmot {args:?} failed: {}\n{}",
        String::from_utf8_lossy(&out.stderr),
        String::from_utf8_lossy(&out.stdout)
    );
    out
}

/// Runs `probmot track INPUT -o OUTPUT --json EXTRA...`, asserts success and returns the
/// summary it printed.
pub fn track_json(input: &Path, output: &Path, extra: &[&str]) -> serde_json::Value {
    let mut args = vec![
        "track",
        input.to_str().unwrap(),
        "-o",
        output.to_str().unwrap(),
        "--json",
    ];
    args.extend_from_slice(extra);
    serde_json::from_slice(&probmot_ok(&args).stdout).unwrap()
}

/// Whether `python3` can import `modules` (comma-separated), for checks that need Python tools.
pub fn python_has(modules: &str) -> bool {
    can_import("python3", modules)
}

/// The Python of the nuScenes devkit checks: `$PROBMOT_DEVKIT_PYTHON` when set (the devkit's
/// numpy<2 conflicts with scripts/requirements.txt, so it lives in a virtual environment of its
/// own, which `.ci/run` makes), else `python3`.
pub fn devkit_python() -> String {
    std::env::var("PROBMOT_DEVKIT_PYTHON").unwrap_or_else(|_| "python3".into())
}

/// Whether the devkit's Python ([`devkit_python`]) can import `modules`.
pub fn devkit_has(modules: &str) -> bool {
    can_import(&devkit_python(), modules)
}

fn can_import(python: &str, modules: &str) -> bool {
    Command::new(python)
        .args(["-c", &format!("import {modules}")])
        .output()
        .is_ok_and(|o| o.status.success())
}

/// Reports that the check `test` cannot run here, and why. Under `CI=true` this panics: CI must
/// prove that a fresh machine runs every check, so a check that could not run is a failure there.
/// Elsewhere it prints `SKIPPED test: reason` on stderr and the caller returns.
///
/// The line goes straight to the process's stderr (`write_all` on `std::io::stderr()`), not
/// through `eprintln!`: libtest captures the `eprint!` output of passing tests, which would turn a
/// skipped check into a silent `ok` in the `cargo test` output.
pub fn skip(test: &str, reason: &str) {
    use std::io::Write as _;
    if std::env::var("CI").is_ok_and(|v| v == "true") {
        panic!("{test} could not run under CI=true: {reason}");
    }
    let line = format!("SKIPPED {test}: {reason}\n");
    let _ = std::io::stderr().lock().write_all(line.as_bytes());
}

/// Path of a file in the repository.
pub fn repo(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

/// One message as stored in a file.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord)]
pub struct Msg {
    pub topic: String,
    pub schema: String,
    pub message_encoding: String,
    pub log_time: u64,
    pub publish_time: u64,
    pub sequence: u32,
    pub data: Vec<u8>,
}

/// Every message of an MCAP file, in file order.
pub fn messages(path: &Path) -> Vec<Msg> {
    let bytes = std::fs::read(path).unwrap();
    mcap::MessageStream::new(&bytes)
        .unwrap()
        .map(|m| {
            let m = m.unwrap();
            Msg {
                topic: m.channel.topic.clone(),
                schema: m
                    .channel
                    .schema
                    .as_ref()
                    .map(|s| s.name.clone())
                    .unwrap_or_default(),
                message_encoding: m.channel.message_encoding.clone(),
                log_time: m.log_time,
                publish_time: m.publish_time,
                sequence: m.sequence,
                data: m.data.into_owned(),
            }
        })
        .collect()
}

/// The decoded messages of a tracks topic, in file order.
pub fn tracks(path: &Path, topic: &str) -> Vec<Tracks3D> {
    messages(path)
        .into_iter()
        .filter(|m| m.topic == topic)
        .map(|m| Tracks3D::decode(m.data.as_slice()).unwrap())
        .collect()
}

/// The decoded messages of a detections topic, in file order.
pub fn detections(path: &Path, topic: &str) -> Vec<Detections3D> {
    messages(path)
        .into_iter()
        .filter(|m| m.topic == topic)
        .map(|m| Detections3D::decode(m.data.as_slice()).unwrap())
        .collect()
}

/// Asserts that no number in a tracks message is NaN or infinite.
pub fn assert_finite(t: &Tracks3D) {
    for tr in &t.tracks {
        let c = tr.center.unwrap();
        let s = tr.size.unwrap();
        let v = tr.velocity.unwrap();
        let pv = tr.position_variance.unwrap();
        for x in [
            c.x,
            c.y,
            c.z,
            s.length,
            s.width,
            s.height,
            tr.yaw,
            v.x,
            v.y,
            v.z,
            tr.yaw_rate,
            tr.score,
            pv.x,
            pv.y,
            pv.z,
            tr.yaw_variance,
        ] {
            assert!(x.is_finite(), "non-finite value in track {}: {tr:?}", tr.id);
        }
    }
}

/// Per truth id, the track id that reported it (matched this frame) in each frame, using the
/// `sim_truth_id` attribute the simulator puts on detections and probmot carries to tracks.
pub fn truth_to_track(frames: &[Tracks3D]) -> std::collections::BTreeMap<u64, Vec<(usize, u64)>> {
    let mut m: std::collections::BTreeMap<u64, Vec<(usize, u64)>> = Default::default();
    for (f, t) in frames.iter().enumerate() {
        for tr in &t.tracks {
            if tr.frames_since_update != 0 {
                continue;
            }
            if let Some(id) = tr.attributes.get("sim_truth_id") {
                let id: u64 = id.parse().unwrap();
                if id != 0 {
                    m.entry(id).or_default().push((f, tr.id));
                }
            }
        }
    }
    m
}

/// Number of id switches: consecutive reports of one truth object by different track ids.
pub fn id_switches(seq: &[(usize, u64)]) -> usize {
    seq.windows(2).filter(|w| w[0].1 != w[1].1).count()
}

/// Tracks the ROS 2 fixture (tests/fixtures/ros2/city.mcap) twice into `dir`: with the default
/// tracks format (ROS 2 messages) and with `--tracks-format probmot`; `(ROS 2, probmot)` outputs.
pub fn track_ros2_fixture_both_ways(dir: &Path) -> (PathBuf, PathBuf) {
    let input = repo("tests/fixtures/ros2/city.mcap");
    let input = input.to_str().unwrap();
    let ros = dir.join("ros.mcap");
    let pb = dir.join("pb.mcap");
    probmot_ok(&["track", input, "-o", ros.to_str().unwrap(), "--quiet"]);
    probmot_ok(&[
        "track",
        input,
        "-o",
        pb.to_str().unwrap(),
        "--quiet",
        "--tracks-format",
        "probmot",
    ]);
    (ros, pb)
}

/// The entries of `dir`, hidden ones included (a partial file would be one), sorted.
pub fn entries(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// `probmot import kitti` of one sequence of a KITTI tracking folder (`label_02/SEQ.txt` and the
/// PointRCNN detections in `pointrcnn/`) into `out`.
pub fn import_kitti_sequence(data: &Path, seq: &str, out: &Path) {
    let label = data.join(format!("label_02/{seq}.txt"));
    let dets = data.join("pointrcnn");
    probmot_ok(&[
        "import",
        "kitti",
        "--labels",
        label.to_str().unwrap(),
        "--detections",
        dets.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
}

/// A copy of `sample_logs/city.mcap` with the first message of `topic` rewritten by `edit`.
pub fn city_with_first_message(out: &Path, topic: &str, edit: impl FnOnce(&[u8]) -> Vec<u8>) {
    let mut edit = Some(edit);
    city_with_messages(out, topic, |i, data| match edit.take_if(|_| i == 0) {
        Some(f) => f(data),
        None => data.to_vec(),
    });
}

/// A copy of `sample_logs/city.mcap` with each message of `topic` rewritten by `edit`, which is
/// given the message's index on that topic.
pub fn city_with_messages(out: &Path, topic: &str, mut edit: impl FnMut(usize, &[u8]) -> Vec<u8>) {
    let bytes = std::fs::read(repo("sample_logs/city.mcap")).unwrap();
    let file = std::fs::File::create(out).unwrap();
    let mut w = mcap::Writer::new(std::io::BufWriter::new(file)).unwrap();
    let mut channels = std::collections::BTreeMap::new();
    let mut index = 0;
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        let id = *channels.entry(m.channel.id).or_insert_with(|| {
            let s = m.channel.schema.as_ref().unwrap();
            let sid = w.add_schema(&s.name, &s.encoding, &s.data).unwrap();
            let (topic, enc) = (&m.channel.topic, &m.channel.message_encoding);
            w.add_channel(sid, topic, enc, &m.channel.metadata).unwrap()
        });
        let data = match m.channel.topic == topic {
            true => {
                index += 1;
                edit(index - 1, &m.data)
            }
            false => m.data.to_vec(),
        };
        let header = mcap::records::MessageHeader {
            channel_id: id,
            sequence: m.sequence,
            log_time: m.log_time,
            publish_time: m.publish_time,
        };
        w.write_to_known_channel(&header, &data).unwrap();
    }
    w.finish().unwrap();
}

/// A copy of `sample_logs/city.mcap` whose first detection message has one box without a size
/// and one of zero length.
pub fn city_with_bad_boxes(out: &Path) {
    city_with_first_message(out, "/detections", |data| {
        let mut d = Detections3D::decode(data).unwrap();
        d.detections[0].size = None;
        d.detections[1].size.as_mut().unwrap().length = 0.0;
        d.encode_to_vec()
    });
}

/// A copy of `sample_logs/city.mcap` whose first ground-truth box has a NaN centre.
pub fn city_with_nan_truth(out: &Path) {
    city_with_first_message(out, "/ground_truth", |data| {
        let mut t = Tracks3D::decode(data).unwrap();
        t.tracks[0].center.as_mut().unwrap().x = f64::NAN;
        t.encode_to_vec()
    });
}

/// Makes a FIFO at `path` (mode 0644).
#[cfg(unix)]
pub fn mkfifo(path: &Path) {
    let c = std::ffi::CString::new(path.to_str().unwrap()).unwrap();
    // SAFETY: mkfifo(3) with a NUL-terminated path; the result is checked.
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o644) }, 0);
}
