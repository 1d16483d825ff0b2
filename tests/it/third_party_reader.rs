//! A third-party reader agrees with ours: `scripts/check_tracks.py` (PyPI `mcap` +
//! `mcap-protobuf-support`, decoding with the schemas embedded in the file) must print exactly
//! the tracks that prost decodes, and `pymcap-cli doctor` must pass on every file the binary
//! writes, with the messages in log-time order.
//!
//! Needs `python3 -m pip install -r scripts/requirements.txt`; without those packages the test
//! prints SKIPPED on stderr and passes (fails under CI=true).

use crate::common::{python_has, skip};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use probmot::msgs::Tracks3D;
use prost::Message as _;
use serde_json::Value;

const TOLERANCE: f64 = 1e-12;
const PYMCAP_CLI_MODULE: &str =
    "import sys; from pymcap_cli.cli import main; sys.argv[0] = 'pymcap-cli'; sys.exit(main())";

fn probmot(args: &[&str]) {
    let out = Command::new(env!("CARGO_BIN_EXE_probmot"))
        .args(args)
        .output()
        .expect("run probmot");
    assert!(
        out.status.success(),
        "probmot {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn check_tracks(file: &Path, extra: &[&str]) -> Output {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/check_tracks.py");
    Command::new("python3")
        .arg(script)
        .arg(file)
        .args(extra)
        .output()
        .expect("run python3 scripts/check_tracks.py")
}

/// Every message on `topic`, in file order, decoded by prost.
fn rust_frames(file: &Path, topic: &str) -> Vec<Tracks3D> {
    let bytes = std::fs::read(file).expect("read mcap");
    let mut frames = vec![];
    for msg in mcap::MessageStream::new(&bytes).expect("open mcap") {
        let msg = msg.expect("read message");
        if msg.channel.topic == topic {
            let schema = msg.channel.schema.as_ref().expect("channel has a schema");
            assert_eq!(schema.name, "probmot.Tracks3D", "schema of {topic}");
            frames.push(Tracks3D::decode(&msg.data[..]).expect("decode Tracks3D"));
        }
    }
    frames
}

fn num(v: &Value, what: &str) -> f64 {
    v.as_f64()
        .unwrap_or_else(|| panic!("{what}: not a number: {v}"))
}

fn vec3(v: &Value, what: &str) -> [f64; 3] {
    let a = v
        .as_array()
        .unwrap_or_else(|| panic!("{what}: not an array: {v}"));
    assert_eq!(a.len(), 3, "{what}: {v}");
    [num(&a[0], what), num(&a[1], what), num(&a[2], what)]
}

/// Distance in units in the last place (sign-aware; 0 for equal values).
fn ulps(x: f64, y: f64) -> u64 {
    let key = |v: f64| {
        let b = v.to_bits() as i64;
        if b < 0 {
            i64::MIN - b
        } else {
            b
        }
    };
    key(x).abs_diff(key(y))
}

/// Running totals of the float comparison.
#[derive(Default)]
struct Stats {
    compared: usize,
    identical: usize,
    max_ulps: u64,
}

/// Compares one frame: stamp, ids, labels and frames_since_update exactly, floats to
/// [`TOLERANCE`].
fn compare(ours: &Tracks3D, theirs: &Value, ctx: &str, stats: &mut Stats) {
    assert_eq!(theirs["stamp"].as_u64(), Some(ours.stamp), "{ctx}: stamp");
    let tracks = theirs["tracks"]
        .as_array()
        .unwrap_or_else(|| panic!("{ctx}: no tracks array"));
    assert_eq!(tracks.len(), ours.tracks.len(), "{ctx}: number of tracks");
    for (o, t) in ours.tracks.iter().zip(tracks) {
        let ctx = format!("{ctx}, track {}", o.id);
        assert_eq!(t["id"].as_u64(), Some(o.id), "{ctx}: id");
        assert_eq!(t["label"].as_str(), Some(o.label.as_str()), "{ctx}: label");
        assert_eq!(
            t["frames_since_update"].as_u64(),
            Some(u64::from(o.frames_since_update)),
            "{ctx}: frames_since_update"
        );
        let (c, s, v) = (
            o.center.unwrap_or_default(),
            o.size.unwrap_or_default(),
            o.velocity.unwrap_or_default(),
        );
        let pairs = [
            (
                "center",
                [c.x, c.y, c.z].to_vec(),
                vec3(&t["center"], "center").to_vec(),
            ),
            (
                "size",
                [s.length, s.width, s.height].to_vec(),
                vec3(&t["size"], "size").to_vec(),
            ),
            ("yaw", vec![o.yaw], vec![num(&t["yaw"], "yaw")]),
            (
                "velocity",
                [v.x, v.y, v.z].to_vec(),
                vec3(&t["velocity"], "velocity").to_vec(),
            ),
            ("score", vec![o.score], vec![num(&t["score"], "score")]),
        ];
        for (name, a, b) in pairs {
            for (x, y) in a.iter().zip(&b) {
                assert!(
                    (x - y).abs() <= TOLERANCE,
                    "{ctx}: {name}: ours {a:?}, theirs {b:?}"
                );
                stats.compared += 1;
                stats.identical += usize::from(x.to_bits() == y.to_bits());
                stats.max_ulps = stats.max_ulps.max(ulps(*x, *y));
            }
        }
    }
}

/// `pymcap-cli doctor` on each file, all at once; asserts success, no error and no warning.
/// With `--strict-message-order` a message whose log time is earlier than the one before it is
/// an error: `track` writes each frame's tracks before any later message.
fn doctor(files: &[PathBuf]) {
    let cli_on_path = Command::new("pymcap-cli")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    let children: Vec<_> = files
        .iter()
        .map(|f| {
            let mut cmd = if cli_on_path {
                Command::new("pymcap-cli")
            } else {
                let mut c = Command::new("python3");
                c.args(["-c", PYMCAP_CLI_MODULE]);
                c
            };
            cmd.args(["doctor", "--strict-message-order", "--format", "jsonl"])
                .arg(f)
                .stdout(std::process::Stdio::piped())
                .stderr(std::process::Stdio::piped())
                .spawn()
                .expect("run pymcap-cli doctor")
        })
        .collect();
    for (f, child) in files.iter().zip(children) {
        let out = child
            .wait_with_output()
            .expect("wait for pymcap-cli doctor");
        let stdout = String::from_utf8_lossy(&out.stdout);
        let name = f.file_name().unwrap().to_string_lossy();
        assert!(
            out.status.success(),
            "pymcap-cli doctor {name} failed ({}):\n{stdout}{}",
            out.status,
            String::from_utf8_lossy(&out.stderr)
        );
        let summary: Value = stdout
            .lines()
            .filter_map(|l| serde_json::from_str::<Value>(l).ok())
            .find(|v| v["type"] == "summary")
            .unwrap_or_else(|| panic!("pymcap-cli doctor {name}: no summary line in\n{stdout}"));
        assert_eq!(summary["errors"], 0, "pymcap-cli doctor {name}:\n{stdout}");
        assert_eq!(
            summary["warnings"], 0,
            "pymcap-cli doctor {name}:\n{stdout}"
        );
        assert_eq!(
            summary["complete"], true,
            "pymcap-cli doctor {name}:\n{stdout}"
        );
        eprintln!(
            "pymcap-cli doctor {name}: ok ({} messages, {} info)",
            summary["messages"], summary["info"]
        );
    }
}

#[test]
fn python_mcap_reader_agrees_and_doctor_passes() {
    if !python_has("mcap, mcap_protobuf") {
        skip(
            "python_mcap_reader_agrees_and_doctor_passes",
            "`python3 -c \"import mcap, mcap_protobuf\"` failed; \
             install with `python3 -m pip install -r scripts/requirements.txt`",
        );
        return;
    }
    let dir = tempfile::tempdir().expect("temp dir");
    let mut written = vec![];
    let mut stats = Stats::default();
    let mut tracks_seen = 0;
    for scenario in ["turning-car", "pedestrians"] {
        let sim = dir.path().join(format!("{scenario}.mcap"));
        let out = dir.path().join(format!("{scenario}.tracked.mcap"));
        probmot(&[
            "simulate",
            "--scenario",
            scenario,
            "-o",
            sim.to_str().unwrap(),
        ]);
        probmot(&[
            "track",
            "-q",
            sim.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ]);
        written.extend([sim, out.clone()]);

        let frames = rust_frames(&out, "/tracks");
        let n = frames.len();
        assert!(n > 2, "{scenario}: only {n} frames");
        // First, middle and last frames, and the first one with a coasting track.
        let mut picks = vec![0, n / 2, n - 1];
        if let Some(k) = frames
            .iter()
            .position(|f| f.tracks.iter().any(|t| t.frames_since_update > 0))
        {
            picks.push(k);
        }
        picks.sort_unstable();
        picks.dedup();
        for &k in &picks {
            let res = check_tracks(&out, &["--json", "--frame", &k.to_string()]);
            assert!(
                res.status.success(),
                "check_tracks.py {scenario} frame {k} failed: {}",
                String::from_utf8_lossy(&res.stderr)
            );
            let theirs: Value =
                serde_json::from_slice(&res.stdout).expect("JSON from check_tracks.py");
            compare(
                &frames[k],
                &theirs,
                &format!("{scenario} /tracks frame {k}"),
                &mut stats,
            );
            tracks_seen += frames[k].tracks.len();
        }

        // --topic: ground truth uses the same schema.
        let gt = rust_frames(&out, "/ground_truth");
        let k = gt.len() / 2;
        let res = check_tracks(
            &out,
            &[
                "--json",
                "--topic",
                "/ground_truth",
                "--frame",
                &k.to_string(),
            ],
        );
        assert!(
            res.status.success(),
            "{}",
            String::from_utf8_lossy(&res.stderr)
        );
        let theirs: Value = serde_json::from_slice(&res.stdout).expect("JSON from check_tracks.py");
        compare(
            &gt[k],
            &theirs,
            &format!("{scenario} /ground_truth frame {k}"),
            &mut stats,
        );

        // Both readers see the same number of frames: one past the last is out of range.
        let res = check_tracks(&out, &["--frame", &n.to_string()]);
        assert_eq!(
            res.status.code(),
            Some(2),
            "{scenario}: frame {n} should be out of range"
        );
        eprintln!("{scenario}: frames {picks:?} of {n} agree");
    }
    let res = check_tracks(&written[1], &["--topic", "/no_such_topic"]);
    assert_eq!(res.status.code(), Some(2), "absent topic should exit 2");
    assert!(String::from_utf8_lossy(&res.stderr).contains("/no_such_topic"));
    assert!(tracks_seen > 0, "no tracks compared");
    // Python prints repr() (exact); serde_json's default float parser may round the last bit.
    eprintln!(
        "{} floats agree to {TOLERANCE:e}: {} bit-identical, the others within {} ulp",
        stats.compared, stats.identical, stats.max_ulps
    );

    if python_has("pymcap_cli") {
        doctor(&written);
    } else {
        skip(
            "python_mcap_reader_agrees_and_doctor_passes (pymcap-cli doctor)",
            "python module pymcap_cli not found; \
             install with `python3 -m pip install -r scripts/requirements.txt`",
        );
    }
}
