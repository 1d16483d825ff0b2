//! `scripts/ray_track.py` on a local Ray instance (two CPUs, loopback, no dashboard): every
//! output is byte-identical to `probmot track X -o Y` with the same options, a corrupt input is
//! reported as failed without stopping the others, the aggregated metrics equal `probmot eval`
//! over the same files, a task whose probmot is killed is retried once, and a binary shipped in
//! the runtime_env working_dir is the one that runs. While it runs every server of the instance
//! listens on loopback only; after each run no process of the Ray
//! instance is left (any that is, is killed by the guard, and the test fails).
//!
//! Needs `python3 -m pip install -r scripts/requirements.txt` (ray, pyarrow); without them the
//! tests say so on stderr and pass.

use crate::common;

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::Mutex;
use std::time::{Duration, Instant};

use crate::common::{probmot_ok, repo};
use serde_json::Value;

/// One Ray instance at a time: the machine has two cores.
static RAY: Mutex<()> = Mutex::new(());

/// Options passed through to `probmot track` (not the defaults, so that dropping them shows).
const TRACK_ARGS: [&str; 2] = ["--preset", "ab3dmot-2019"];

fn available(test: &str) -> bool {
    let ok = common::python_has("ray, pyarrow.fs");
    if !ok {
        common::skip(
            test,
            "`python3 -c \"import ray, pyarrow.fs\"` failed; install with \
             `python3 -m pip install -r scripts/requirements.txt` (ray==2.60.0)",
        );
    }
    ok
}

/// A short temporary directory under /tmp: Ray's unix socket paths inside it must stay short.
fn short_tempdir() -> tempfile::TempDir {
    tempfile::Builder::new()
        .prefix("rt")
        .tempdir_in("/tmp")
        .unwrap()
}

/// Processes (other than this one) with an open file or an argument under `dir`: the Ray
/// instance whose temporary directory `dir` is (its workers rename themselves, but their
/// stdout and stderr are log files in the session directory).
fn processes_using(dir: &Path) -> Vec<(u32, String)> {
    let me = std::process::id();
    let needle = dir.to_string_lossy().into_owned();
    let mut found = Vec::new();
    let Ok(entries) = std::fs::read_dir("/proc") else {
        return found;
    };
    for e in entries.flatten() {
        let Ok(pid) = e.file_name().to_string_lossy().parse::<u32>() else {
            continue;
        };
        if pid == me {
            continue;
        }
        let cmdline = std::fs::read(e.path().join("cmdline"))
            .map(|b| String::from_utf8_lossy(&b).replace('\0', " "))
            .unwrap_or_default();
        let mut uses = cmdline.contains(&needle);
        if !uses {
            if let Ok(fds) = std::fs::read_dir(e.path().join("fd")) {
                uses = fds.flatten().any(|fd| {
                    std::fs::read_link(fd.path())
                        .is_ok_and(|t| t.to_string_lossy().starts_with(&needle))
                });
            }
        }
        if uses {
            found.push((pid, cmdline));
        }
    }
    found
}

/// Kills whatever is left of the Ray instance under `dir` when dropped (also on a failed test).
struct RayGuard {
    dir: PathBuf,
}

impl Drop for RayGuard {
    fn drop(&mut self) {
        for (pid, _) in processes_using(&self.dir) {
            let _ = Command::new("kill").args(["-9", &pid.to_string()]).status();
        }
    }
}

/// Waits up to 20 s for the Ray instance under `dir` to be gone; returns what is left.
fn wait_for_shutdown(dir: &Path) -> Vec<(u32, String)> {
    let start = Instant::now();
    loop {
        let left = processes_using(dir);
        if left.is_empty() || start.elapsed() > Duration::from_secs(20) {
            return left;
        }
        std::thread::sleep(Duration::from_millis(200));
    }
}

/// Listening TCP sockets on this machine: inode -> (local address in /proc/net hex, IPv6).
fn listening_sockets() -> HashMap<u64, (String, bool)> {
    let mut out = HashMap::new();
    for (table, v6) in [("/proc/net/tcp", false), ("/proc/net/tcp6", true)] {
        let Ok(text) = std::fs::read_to_string(table) else {
            continue;
        };
        for line in text.lines().skip(1) {
            let f: Vec<&str> = line.split_whitespace().collect();
            // sl local_address rem_address st tx:rx tr:when retrnsmt uid timeout inode
            if f.len() > 9 && f[3] == "0A" {
                let addr = f[1].split(':').next().unwrap_or_default().to_string();
                if let Ok(inode) = f[9].parse() {
                    out.insert(inode, (addr, v6));
                }
            }
        }
    }
    out
}

/// Whether a /proc/net address (32-bit words in host order, little-endian here) is loopback:
/// 127.x.x.x, ::1 or ::ffff:127.x.x.x.
fn is_loopback(addr: &str, v6: bool) -> bool {
    if !v6 {
        return addr.len() == 8 && addr.ends_with("7F");
    }
    addr == "00000000000000000000000001000000"
        || (addr.len() == 32
            && addr.starts_with("0000000000000000FFFF0000")
            && addr.ends_with("7F"))
}

/// The listening sockets of the processes of the Ray instance under `dir`, as
/// (pid, command line, address in /proc/net hex, loopback?).
fn ray_listeners(dir: &Path) -> Vec<(u32, String, String, bool)> {
    let sockets = listening_sockets();
    let mut out = Vec::new();
    for (pid, cmdline) in processes_using(dir) {
        let Ok(fds) = std::fs::read_dir(format!("/proc/{pid}/fd")) else {
            continue;
        };
        for fd in fds.flatten() {
            let Ok(target) = std::fs::read_link(fd.path()) else {
                continue;
            };
            let target = target.to_string_lossy();
            let Some(inode) = target
                .strip_prefix("socket:[")
                .and_then(|t| t.strip_suffix(']'))
                .and_then(|t| t.parse::<u64>().ok())
            else {
                continue;
            };
            if let Some((addr, v6)) = sockets.get(&inode) {
                out.push((pid, cmdline.clone(), addr.clone(), is_loopback(addr, *v6)));
            }
        }
    }
    out
}

/// Runs `scripts/ray_track.py` with a local instance whose temporary directory is `ray_dir`,
/// checking while it runs that every server of the instance listens on loopback only.
fn ray_track(ray_dir: &Path, args: &[String]) -> Output {
    let _guard = RayGuard {
        dir: ray_dir.to_path_buf(),
    };
    let logs = tempfile::tempdir().unwrap();
    let (stdout, stderr) = (logs.path().join("stdout"), logs.path().join("stderr"));
    let mut child = Command::new("python3")
        .arg(repo("scripts/ray_track.py"))
        .args(["--num-cpus", "2", "--temp-dir"])
        .arg(ray_dir)
        .args(args)
        .stdout(std::fs::File::create(&stdout).unwrap())
        .stderr(std::fs::File::create(&stderr).unwrap())
        .spawn()
        .expect("run python3 scripts/ray_track.py");
    let mut listeners = Vec::new();
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        listeners.extend(ray_listeners(ray_dir));
        std::thread::sleep(Duration::from_millis(250));
    };
    let left = wait_for_shutdown(ray_dir);
    assert!(
        left.is_empty(),
        "Ray processes still running after ray_track.py exited: {left:?}"
    );
    assert!(
        !listeners.is_empty(),
        "saw no listening socket of the Ray instance while it ran"
    );
    let exposed: Vec<_> = listeners.iter().filter(|l| !l.3).collect();
    assert!(
        exposed.is_empty(),
        "Ray listened beyond loopback: {exposed:?}"
    );
    Output {
        status,
        stdout: std::fs::read(&stdout).unwrap(),
        stderr: std::fs::read(&stderr).unwrap(),
    }
}

fn s(p: &Path) -> String {
    p.to_str().unwrap().to_string()
}

fn uri(p: &Path) -> String {
    format!("file://{}", s(p))
}

fn simulate(scenario: &str, seed: u32, out: &Path) {
    probmot_ok(&[
        "simulate",
        "--scenario",
        scenario,
        "--seed",
        &seed.to_string(),
        "--frames",
        "30",
        "-o",
        &s(out),
    ]);
}

/// `probmot track IN -o OUT` with `TRACK_ARGS`: the reference output.
fn track_plain(input: &Path, out: &Path) {
    let mut args = vec![
        "track",
        input.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ];
    args.extend(["--quiet"]);
    args.extend(TRACK_ARGS);
    probmot_ok(&args);
}

/// `probmot eval --json` with the given arguments.
fn eval_plain(args: &[String]) -> Value {
    let mut all = vec!["eval".to_string(), "--json".to_string()];
    all.extend(args.iter().cloned());
    let refs: Vec<&str> = all.iter().map(String::as_str).collect();
    serde_json::from_slice(&probmot_ok(&refs).stdout).expect("eval prints JSON")
}

fn read_report(path: &Path) -> Value {
    serde_json::from_slice(&std::fs::read(path).expect("the report is written"))
        .expect("the report is JSON")
}

fn explain(out: &Output) -> String {
    format!(
        "status {}\nstdout:\n{}\nstderr:\n{}",
        out.status,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    )
}

fn name_of(v: &Value) -> String {
    v.as_str().unwrap().rsplit('/').next().unwrap().to_string()
}

#[test]
fn a_fleet_on_ray_matches_the_cli_and_reports_the_corrupt_log() {
    if !available("a_fleet_on_ray_matches_the_cli_and_reports_the_corrupt_log") {
        return;
    }
    let _one = RAY.lock().unwrap_or_else(|e| e.into_inner());
    let tmp = short_tempdir();
    let (local_in, uri_in, out, reference) = (
        tmp.path().join("in"),
        tmp.path().join("gen"),
        tmp.path().join("out"),
        tmp.path().join("ref"),
    );
    for d in [&local_in, &uri_in, &reference] {
        std::fs::create_dir(d).unwrap();
    }
    // Local inputs: the sample logs and one file that is not MCAP at all.
    let mut expected: Vec<PathBuf> = Vec::new();
    for name in ["city.mcap", "pedestrians.mcap", "turning-car.mcap"] {
        std::fs::copy(repo(&format!("sample_logs/{name}")), local_in.join(name)).unwrap();
    }
    std::fs::write(
        local_in.join("corrupt.mcap"),
        b"this is not an MCAP file, only text\n".repeat(20),
    )
    .unwrap();
    // Generated inputs, given as a file:// URI pattern (copied through pyarrow.fs).
    for (scenario, seed, name) in [
        ("city", 21, "sim-a.mcap"),
        ("pedestrians", 22, "sim-b.mcap"),
        ("turning-car", 23, "sim-c.mcap"),
    ] {
        simulate(scenario, seed, &uri_in.join(name));
    }
    // The order in which the script lists the logs: its arguments in turn, each sorted by name.
    for name in ["city.mcap", "pedestrians.mcap", "turning-car.mcap"] {
        expected.push(local_in.join(name));
    }
    for name in ["sim-a.mcap", "sim-b.mcap", "sim-c.mcap"] {
        expected.push(uri_in.join(name));
    }
    let report_path = tmp.path().join("report.json");
    let mut args = vec![
        format!("{}/*.mcap", s(&local_in)),
        format!("{}/*.mcap", uri(&uri_in)),
        "--out".into(),
        s(&out),
        "--eval".into(),
        "--probmot".into(),
        env!("CARGO_BIN_EXE_probmot").into(),
        "--report".into(),
        s(&report_path),
        "--".into(),
    ];
    args.extend(TRACK_ARGS.iter().map(|a| a.to_string()));
    let run = ray_track(&tmp.path().join("ray"), &args);
    assert_eq!(
        run.status.code(),
        Some(1),
        "a failed log: exit 1\n{}",
        explain(&run)
    );

    let report = read_report(&report_path);
    assert_eq!(report["logs"], 7, "{report:#}");
    assert_eq!(report["tracked"], 6, "{report:#}");
    assert_eq!(report["failed"], 1, "{report:#}");
    let failure = &report["failures"][0];
    assert_eq!(name_of(&failure["input"]), "corrupt.mcap");
    assert_eq!(failure["stage"], "track");
    let error = failure["error"].as_str().unwrap();
    assert!(error.contains("corrupt.mcap"), "{error}");
    assert!(
        !out.join("corrupt.mcap").exists(),
        "no output for a failed log"
    );
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(
        stderr.contains("error:") && stderr.contains("corrupt.mcap"),
        "{stderr}"
    );

    // Every output equals the plain CLI's, and so does every per-log evaluation.
    let per_log = report["per_log"].as_array().unwrap();
    let ok_logs: Vec<&Value> = per_log.iter().filter(|r| r["ok"] == true).collect();
    assert_eq!(ok_logs.len(), 6);
    let mut refs = Vec::new();
    for input in &expected {
        let name = input.file_name().unwrap().to_str().unwrap();
        let reference_out = reference.join(name);
        track_plain(input, &reference_out);
        let got = std::fs::read(out.join(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(
            got == std::fs::read(&reference_out).unwrap(),
            "{name}: the Ray output differs from `probmot track` with the same options"
        );
        let entry = ok_logs
            .iter()
            .find(|r| name_of(&r["input"]) == name)
            .unwrap_or_else(|| panic!("{name} missing from the report"));
        assert!(entry["summary"]["frames"].as_u64().unwrap() > 0);
        let single = eval_plain(&["--truth".into(), s(&reference_out)]);
        assert_eq!(entry["eval"], single["result"], "{name}: per-log metrics");
        refs.push(s(&reference_out));
    }

    // The aggregated metrics equal one `probmot eval` over the same six logs.
    let mut eval_args = vec!["--truth".to_string()];
    eval_args.extend(refs);
    let all = eval_plain(&eval_args);
    assert_eq!(
        report["metrics"]["result"], all["result"],
        "aggregated metrics differ from probmot eval over the same files"
    );
    assert!(report["metrics"]["result"]["overall"]["amota"].is_number());

    // Progress: one line per finished log, then the table and the per-class metrics.
    let stdout = String::from_utf8_lossy(&run.stdout);
    let progress: Vec<&str> = stdout
        .lines()
        .filter(|l| l.starts_with('[') && l.contains("/7] "))
        .collect();
    assert_eq!(progress.len(), 7, "{stdout}");
    for name in [
        "city.mcap",
        "pedestrians.mcap",
        "turning-car.mcap",
        "sim-a.mcap",
        "sim-b.mcap",
        "sim-c.mcap",
        "corrupt.mcap",
    ] {
        assert!(
            progress.iter().any(|l| l.contains(&format!("] {name}: "))),
            "no progress line for {name}:\n{stdout}"
        );
    }
    assert!(stdout.contains("7 logs: 6 tracked, 1 failed"), "{stdout}");
    assert!(
        stdout.contains("nuScenes tracking metrics over 6 logs"),
        "{stdout}"
    );
}

#[test]
fn a_killed_task_is_retried_and_a_shipped_binary_runs() {
    if !available("a_killed_task_is_retried_and_a_shipped_binary_runs") {
        return;
    }
    let _one = RAY.lock().unwrap_or_else(|e| e.into_inner());
    let tmp = short_tempdir();
    let (input, out, reference, wrap) = (
        tmp.path().join("in"),
        tmp.path().join("out"),
        tmp.path().join("ref"),
        tmp.path().join("wrap"),
    );
    for d in [&input, &reference, &wrap] {
        std::fs::create_dir(d).unwrap();
    }
    simulate("city", 31, &input.join("flaky.mcap"));
    std::fs::copy(
        repo("sample_logs/turning-car.mcap"),
        input.join("steady.mcap"),
    )
    .unwrap();
    // The shipped "binary": records where it runs from, kills itself the first time it tracks
    // flaky.mcap (as the kernel's OOM killer would), else runs the real probmot.
    let calls = tmp.path().join("calls");
    let crashed = tmp.path().join("crashed");
    let wrapper = wrap.join("probmot");
    std::fs::write(
        &wrapper,
        format!(
            "#!/bin/sh\necho \"$0 $1 $2\" >> '{calls}'\n\
             if [ \"$1\" = track ] && [ ! -e '{crashed}' ]; then\n\
             case \"$2\" in *flaky.mcap) touch '{crashed}'; kill -9 $$;; esac\nfi\n\
             exec '{real}' \"$@\"\n",
            calls = s(&calls),
            crashed = s(&crashed),
            real = env!("CARGO_BIN_EXE_probmot"),
        ),
    )
    .unwrap();
    Command::new("chmod")
        .args(["+x", &s(&wrapper)])
        .status()
        .unwrap();
    let ray_dir = tmp.path().join("ray");
    let report_path = tmp.path().join("report.json");
    let mut args = vec![
        uri(&input),
        "--out".into(),
        uri(&out),
        "--eval".into(),
        "--truth-prefix".into(),
        s(&input),
        "--ship-probmot".into(),
        "--probmot".into(),
        s(&wrapper),
        "--report".into(),
        s(&report_path),
        "--".into(),
    ];
    args.extend(TRACK_ARGS.iter().map(|a| a.to_string()));
    let run = ray_track(&ray_dir, &args);
    assert!(run.status.success(), "{}", explain(&run));
    let report = read_report(&report_path);
    assert_eq!(report["tracked"], 2, "{report:#}");
    assert!(crashed.exists(), "the wrapper killed itself once");

    let calls = std::fs::read_to_string(&calls).unwrap();
    let flaky_tracks = calls
        .lines()
        .filter(|l| l.contains(" track ") && l.ends_with("flaky.mcap"))
        .count();
    assert_eq!(flaky_tracks, 2, "killed once, retried once:\n{calls}");
    for line in calls.lines() {
        let program = line.split(' ').next().unwrap();
        assert!(
            program.starts_with(&s(&ray_dir)) && program != s(&wrapper),
            "probmot ran from {program}, not from the job's working_dir:\n{calls}"
        );
    }

    let mut truth = vec!["--truth".to_string()];
    let mut tracks = vec!["--tracks".to_string()];
    for name in ["flaky.mcap", "steady.mcap"] {
        let reference_out = reference.join(name);
        track_plain(&input.join(name), &reference_out);
        assert!(
            std::fs::read(out.join(name)).unwrap() == std::fs::read(&reference_out).unwrap(),
            "{name}: output copied back through pyarrow.fs differs from `probmot track`"
        );
        truth.push(s(&input.join(name)));
        tracks.push(s(&reference_out));
    }
    truth.extend(tracks);
    let all = eval_plain(&truth);
    assert_eq!(report["metrics"]["result"], all["result"]);
}
