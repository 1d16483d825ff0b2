//! Interrupting a writing command: on SIGINT, SIGTERM or SIGHUP `probmot track` removes its
//! partial output, says in one line what was left unwritten and exits with 128 + the signal
//! number; the partial file of a hard-killed run (SIGKILL) is named after its output and the
//! next run writing that output removes it.
#![cfg(unix)]

use crate::common;

use std::path::{Path, PathBuf};
use std::process::{Child, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

use crate::common::split::split_mcap;
use crate::common::{bin, entries, probmot_ok, repo};

/// A log long enough that tracking it takes seconds (debug build): 1,500 frames of the city.
fn long_log() -> &'static Path {
    static LOG: OnceLock<(tempfile::TempDir, PathBuf)> = OnceLock::new();
    let (_, path) = LOG.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("long.mcap");
        let p = path.to_str().unwrap();
        probmot_ok(&[
            "simulate",
            "--scenario",
            "city",
            "--frames",
            "1500",
            "--objects",
            "80",
            "-o",
            p,
        ]);
        (dir, path)
    });
    path
}

/// Starts `probmot track ARGS` as from a terminal (SIGINT, SIGTERM and SIGHUP at their default
/// disposition, whatever this test process inherited: a test run started in the background of a
/// script ignores SIGINT) and waits until a partial file shows up in `out_dir`.
fn start_track(args: &[&str], out_dir: &Path) -> Child {
    start_track_with(terminal_bin(), args, out_dir)
}

/// The binary under test with SIGINT, SIGTERM and SIGHUP at their default disposition.
fn terminal_bin() -> std::process::Command {
    use std::os::unix::process::CommandExt;
    let mut cmd = bin();
    // SAFETY: signal(2) is async-signal-safe, the only call made between fork and exec.
    unsafe {
        cmd.pre_exec(|| {
            for sig in [libc::SIGINT, libc::SIGTERM, libc::SIGHUP] {
                libc::signal(sig, libc::SIG_DFL);
            }
            Ok(())
        });
    }
    cmd
}

/// As [`start_track`], the binary started by `cmd` (e.g. through `nohup`).
fn start_track_with(mut cmd: std::process::Command, args: &[&str], out_dir: &Path) -> Child {
    let mut child = cmd
        .arg("track")
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while !entries(out_dir)
        .iter()
        .any(|n| n.ends_with(".probmot-partial"))
    {
        if let Some(status) = child.try_wait().unwrap() {
            panic!("track ended ({status}) before writing anything to {out_dir:?}");
        }
        assert!(
            start.elapsed() < Duration::from_secs(120),
            "no partial file"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    child
}

fn signal(child: &Child, sig: i32) {
    // SAFETY: kill(2) on the pid of a child we have not yet waited for.
    assert_eq!(unsafe { libc::kill(child.id() as i32, sig) }, 0);
}

/// Interrupts a `track` run with `sig` mid-run: exit status 128 + sig, one line naming the
/// signal and the unwritten outputs, nothing left in `out_dir`.
fn check_interrupt(args: &[&str], out_dir: &Path, sig: i32, name: &str, outputs: &[&str]) {
    let child = start_track(args, out_dir);
    check_interrupted(child, out_dir, sig, name, outputs);
}

/// As [`check_interrupt`], for the `track` run `child`.
fn check_interrupted(child: Child, out_dir: &Path, sig: i32, name: &str, outputs: &[&str]) {
    signal(&child, sig);
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(128 + sig), "{stderr}");
    let lines: Vec<&str> = stderr
        .lines()
        .filter(|l| l.contains("interrupted"))
        .collect();
    assert_eq!(lines.len(), 1, "{stderr}");
    assert!(
        lines[0].contains(&format!("interrupted by {name}")),
        "{stderr}"
    );
    assert!(lines[0].contains("not written"), "{stderr}");
    assert!(
        outputs.iter().any(|o| lines[0].contains(o)),
        "names none of {outputs:?}: {stderr}"
    );
    assert_eq!(
        entries(out_dir),
        Vec::<String>::new(),
        "left in the output folder"
    );
}

#[test]
fn sigint_and_sigterm_with_o_leave_nothing() {
    let log = long_log().to_str().unwrap();
    for (sig, name) in [(libc::SIGINT, "SIGINT"), (libc::SIGTERM, "SIGTERM")] {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("out.mcap");
        let args = [log, "-o", out.to_str().unwrap()];
        check_interrupt(&args, dir.path(), sig, name, &["out.mcap"]);
    }
}

#[test]
fn sigint_sigterm_and_sighup_with_out_dir_leave_nothing() {
    let inputs = tempfile::tempdir().unwrap();
    let a = inputs.path().join("a.mcap");
    let b = inputs.path().join("b.mcap");
    std::fs::copy(long_log(), &a).unwrap();
    std::fs::copy(long_log(), &b).unwrap();
    for (sig, name) in [
        (libc::SIGINT, "SIGINT"),
        (libc::SIGTERM, "SIGTERM"),
        (libc::SIGHUP, "SIGHUP"),
    ] {
        let dir = tempfile::tempdir().unwrap();
        let args = [
            a.to_str().unwrap(),
            b.to_str().unwrap(),
            "--out-dir",
            dir.path().to_str().unwrap(),
            "--jobs",
            "2",
        ];
        check_interrupt(&args, dir.path(), sig, name, &["a.mcap", "b.mcap"]);
    }
}

/// A split bag tracked into a bag directory, interrupted once its first output file is
/// complete: the partial directory goes with every file in it, and the line names the bag.
#[test]
fn sigint_while_tracking_a_split_bag_leaves_nothing() {
    let inputs = tempfile::tempdir().unwrap();
    let bag = inputs.path().join("bag");
    let n = common::messages(long_log()).len();
    split_mcap(long_log(), &bag, &[n / 3, 2 * n / 3]);
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("tracked");
    let args = [bag.to_str().unwrap(), "-o", out.to_str().unwrap()];
    let mut child = start_track(&args, dir.path());
    let first = dir.path().join(".tracked.probmot-partial/bag_0.mcap");
    let start = Instant::now();
    while !first.exists() {
        if let Some(status) = child.try_wait().unwrap() {
            panic!("track ended ({status}) before its first output file");
        }
        assert!(start.elapsed() < Duration::from_secs(120), "no first file");
        std::thread::sleep(Duration::from_millis(20));
    }
    check_interrupted(child, dir.path(), libc::SIGINT, "SIGINT", &["tracked"]);
}

#[test]
fn a_stale_partial_file_of_a_killed_run_is_removed_by_the_next_run() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.mcap");
    let o = out.to_str().unwrap();
    let child = start_track(&[long_log().to_str().unwrap(), "-o", o], dir.path());
    signal(&child, libc::SIGKILL);
    let status = child.wait_with_output().unwrap().status;
    assert_eq!(status.code(), None, "killed by a signal");
    // What a user finds after a hard kill: a hidden file named after the output.
    assert_eq!(entries(dir.path()), [".out.mcap.probmot-partial"]);

    let run = probmot_ok(&[
        "track",
        repo("sample_logs/city.mcap").to_str().unwrap(),
        "-o",
        o,
    ]);
    assert_eq!(entries(dir.path()), ["out.mcap"]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(
        stderr.contains(".out.mcap.probmot-partial") && stderr.contains("interrupted run"),
        "the removal is reported: {stderr}"
    );
    // The output is the complete, normal one.
    assert!(!common::tracks(&out, "/tracks").is_empty());
}

#[test]
fn sighup_stays_ignored_under_nohup() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.mcap");
    let mut nohup = std::process::Command::new("nohup");
    nohup.arg(env!("CARGO_BIN_EXE_probmot"));
    let args = [long_log().to_str().unwrap(), "-o", out.to_str().unwrap()];
    let mut child = start_track_with(nohup, &args, dir.path());
    signal(&child, libc::SIGHUP);
    std::thread::sleep(Duration::from_millis(500));
    match child.try_wait().unwrap() {
        // A fast (release) build may finish within the wait: then it must have finished normally.
        Some(status) => {
            assert_eq!(status.code(), Some(0), "SIGHUP ended a nohup run: {status}");
            assert_eq!(entries(dir.path()), vec!["out.mcap".to_string()]);
            return;
        }
        None => signal(&child, libc::SIGTERM),
    }
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(128 + libc::SIGTERM));
    assert_eq!(entries(dir.path()), Vec::<String>::new());
}

/// An output written in place (a FIFO here, as `/dev/stdout | reader`) has no partial file to
/// remove: the interrupt line says it was partly written, and nothing else is left beside it.
#[test]
fn sigint_while_writing_into_a_fifo_says_partly_written() {
    use std::io::Read;
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("out.mcap");
    common::mkfifo(&fifo);
    let mut cmd = bin();
    // SAFETY: as in start_track: only signal(2) between fork and exec.
    unsafe {
        use std::os::unix::process::CommandExt;
        cmd.pre_exec(|| {
            libc::signal(libc::SIGINT, libc::SIG_DFL);
            Ok(())
        });
    }
    let log = long_log().to_str().unwrap();
    let child = cmd
        .args(["track", log, "-o", fifo.to_str().unwrap()])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Should track end without opening the FIFO, a watchdog opens it for writing, so that the
    // open below returns and the test fails instead of hanging.
    let unblock = fifo.clone();
    std::thread::spawn(move || {
        use std::os::unix::fs::OpenOptionsExt;
        std::thread::sleep(Duration::from_secs(120));
        let _ = std::fs::OpenOptions::new()
            .write(true)
            .custom_flags(libc::O_NONBLOCK)
            .open(unblock);
    });
    // Blocks until track opens the FIFO; the first bytes show the writing has started.
    let mut reader = std::fs::File::open(&fifo).unwrap();
    let mut first = [0u8; 4096];
    reader.read_exact(&mut first).unwrap();
    signal(&child, libc::SIGINT);
    let mut rest = Vec::new();
    reader.read_to_end(&mut rest).unwrap();
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(128 + libc::SIGINT), "{stderr}");
    assert!(
        stderr.contains("interrupted by SIGINT; partly written (in place): ")
            && stderr.contains("out.mcap"),
        "{stderr}"
    );
    assert_eq!(entries(dir.path()), ["out.mcap"]);
}

/// The long log as a one-file rosbag2 bag with sqlite3 storage compressed whole
/// (`bag/bag_0.db3.zstd`), its rows made here from the log's messages.
fn compressed_sqlite_bag(dir: &Path) -> PathBuf {
    let bag = dir.join("bag");
    std::fs::create_dir(&bag).unwrap();
    let db3 = dir.join("bag_0.db3");
    let conn = rusqlite::Connection::open(&db3).unwrap();
    conn.execute_batch(
        "CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL,
           serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL);
         CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL,
           timestamp INTEGER NOT NULL, data BLOB NOT NULL);
         BEGIN;",
    )
    .unwrap();
    let mut topics: Vec<String> = Vec::new();
    for m in common::messages(long_log()) {
        let id = match topics.iter().position(|t| *t == m.topic) {
            Some(i) => i + 1,
            None => {
                topics.push(m.topic.clone());
                let row = (topics.len(), &m.topic, &m.schema, &m.message_encoding);
                conn.execute("INSERT INTO topics VALUES (?1, ?2, ?3, ?4, '')", row)
                    .unwrap();
                topics.len()
            }
        };
        let row = (id, m.log_time as i64, &m.data);
        conn.execute(
            "INSERT INTO messages (topic_id, timestamp, data) VALUES (?1, ?2, ?3)",
            row,
        )
        .unwrap();
    }
    conn.execute_batch("COMMIT;").unwrap();
    drop(conn);
    let bytes = zstd::encode_all(&std::fs::read(&db3).unwrap()[..], 3).unwrap();
    std::fs::write(bag.join("bag_0.db3.zstd"), bytes).unwrap();
    let yaml = "rosbag2_bagfile_information:\n  storage_identifier: sqlite3\n  \
                relative_file_paths:\n  - bag_0.db3.zstd\n  compression_mode: file\n  \
                compression_format: zstd\n";
    std::fs::write(bag.join("metadata.yaml"), yaml).unwrap();
    bag
}

/// A sqlite3 bag compressed whole is read from a decompressed scratch copy in TMPDIR: an
/// interrupt while it is read removes the scratch copy with the partial output.
#[test]
fn sigint_while_reading_a_compressed_sqlite_bag_leaves_no_scratch_copy() {
    let inputs = tempfile::tempdir().unwrap();
    let bag = compressed_sqlite_bag(inputs.path());
    let scratch = tempfile::tempdir().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("tracked");
    let mut cmd = terminal_bin();
    cmd.env("TMPDIR", scratch.path());
    let args = [bag.to_str().unwrap(), "-o", out.to_str().unwrap()];
    let mut child = start_track_with(cmd, &args, dir.path());
    let start = Instant::now();
    while entries(scratch.path()).is_empty() {
        if let Some(status) = child.try_wait().unwrap() {
            panic!("track ended ({status}) before its scratch copy");
        }
        assert!(
            start.elapsed() < Duration::from_secs(120),
            "no scratch copy"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    check_interrupted(child, dir.path(), libc::SIGINT, "SIGINT", &["tracked"]);
    assert_eq!(
        entries(scratch.path()),
        Vec::<String>::new(),
        "scratch left"
    );
}
