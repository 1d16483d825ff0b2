//! Outputs whose destination is not a regular file (`/dev/null`, a FIFO, `/dev/stdout`) are
//! written in place, and a symbolic link is written through: the atomic rename of a finished
//! file would replace the device node or the link, which as root turns `/dev/null` or
//! `/dev/stdout` into an ordinary file for every process on the machine. A FIFO and links in a
//! temporary directory stand for those here (no privileges needed, and a regression cannot
//! touch the machine's `/dev`).
#![cfg(unix)]

use std::ffi::CString;
use std::os::unix::ffi::OsStrExt;
use std::os::unix::fs::{symlink, FileTypeExt};
use std::path::Path;
use std::process::Stdio;
use std::thread::JoinHandle;

use crate::common::{bin, entries, probmot_ok, repo};

/// Makes a FIFO at `path` and starts a thread reading it to the end.
fn fifo_reader(path: &Path) -> JoinHandle<Vec<u8>> {
    let c = CString::new(path.as_os_str().as_bytes()).unwrap();
    // SAFETY: mkfifo(3) with a NUL-terminated path; the result is checked.
    let rc = unsafe { libc::mkfifo(c.as_ptr(), 0o644) };
    assert_eq!(rc, 0, "mkfifo {}", path.display());
    let path = path.to_path_buf();
    std::thread::spawn(move || std::fs::read(path).unwrap())
}

/// `args` with `-o DEST` written once into a FIFO and once into a file: the same bytes, the
/// FIFO still a FIFO, nothing else left in its directory.
fn fifo_gets_the_file_bytes(args: &[&str], name: &str) {
    let fifo_dir = tempfile::tempdir().unwrap();
    let file_dir = tempfile::tempdir().unwrap();
    let fifo = fifo_dir.path().join(name);
    let file = file_dir.path().join(name);
    let reader = fifo_reader(&fifo);
    probmot_ok(&[args, &["-o", fifo.to_str().unwrap()]].concat());
    // Checked before joining the reader: a FIFO replaced by a file is never opened for writing.
    assert!(
        std::fs::metadata(&fifo).unwrap().file_type().is_fifo(),
        "{} is no longer a FIFO",
        fifo.display()
    );
    assert_eq!(entries(fifo_dir.path()), vec![name.to_string()]);
    let through_fifo = reader.join().unwrap();
    probmot_ok(&[args, &["-o", file.to_str().unwrap()]].concat());
    let in_file = std::fs::read(&file).unwrap();
    assert!(!in_file.is_empty());
    assert!(
        through_fifo == in_file,
        "{name}: {} bytes through the FIFO, {} in the file",
        through_fifo.len(),
        in_file.len()
    );
}

#[test]
fn track_writes_its_mcap_into_a_fifo_in_place() {
    let city = repo("sample_logs/city.mcap");
    fifo_gets_the_file_bytes(&["track", city.to_str().unwrap()], "city.tracked.mcap");
}

#[test]
fn plot_writes_its_png_into_a_fifo_in_place() {
    let city = repo("sample_logs/city.mcap");
    fifo_gets_the_file_bytes(&["plot", city.to_str().unwrap()], "city.png");
}

/// `track -o LINK`: the tracked bytes end up where the link points, the link stays a link.
fn track_through_link(link_target: &Path, dir: &Path) -> Vec<u8> {
    let city = repo("sample_logs/city.mcap");
    let link = dir.join("out.mcap");
    symlink(link_target, &link).unwrap();
    probmot_ok(&[
        "track",
        city.to_str().unwrap(),
        "-o",
        link.to_str().unwrap(),
        "-q",
    ]);
    assert!(std::fs::symlink_metadata(&link)
        .unwrap()
        .file_type()
        .is_symlink());
    let plain = dir.join("plain.mcap");
    probmot_ok(&[
        "track",
        city.to_str().unwrap(),
        "-o",
        plain.to_str().unwrap(),
        "-q",
    ]);
    std::fs::read(plain).unwrap()
}

#[test]
fn a_link_to_a_file_is_written_through() {
    let dir = tempfile::tempdir().unwrap();
    let target = dir.path().join("target.mcap");
    std::fs::write(&target, b"old").unwrap();
    let plain = track_through_link(&target, dir.path());
    assert!(std::fs::read(&target).unwrap() == plain);
    // A link to a file not written yet: created where the link points.
    let dir = tempfile::tempdir().unwrap();
    let plain = track_through_link(Path::new("new.mcap"), dir.path());
    assert!(std::fs::read(dir.path().join("new.mcap")).unwrap() == plain);
    let mut names = entries(dir.path());
    names.retain(|n| n != "plain.mcap");
    assert_eq!(names, ["new.mcap", "out.mcap"]);
}

#[test]
fn a_link_to_a_fifo_is_written_in_place() {
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("fifo");
    let reader = fifo_reader(&fifo);
    let plain = track_through_link(&fifo, dir.path());
    assert!(std::fs::metadata(&fifo).unwrap().file_type().is_fifo());
    assert!(reader.join().unwrap() == plain);
}

/// `track -o LINK` with LINK -> /proc/self/fd/1 (standing for `/dev/stdout`) in `dir` and the
/// given stdout: the run's output (the summary checked to be on stderr) and the bytes `track`
/// writes to a plain file.
#[cfg(target_os = "linux")]
fn track_to_stdout(dir: &Path, stdout: Stdio) -> (std::process::Output, Vec<u8>) {
    let link = dir.join("stdout");
    symlink("/proc/self/fd/1", &link).unwrap();
    let city = repo("sample_logs/city.mcap");
    let city = city.to_str().unwrap();
    let out = bin()
        .args(["track", city, "-o", link.to_str().unwrap()])
        .stdout(stdout)
        .stderr(Stdio::piped())
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(err.contains("1048 detections"), "{err}");
    assert!(std::fs::symlink_metadata(&link)
        .unwrap()
        .file_type()
        .is_symlink());
    let plain = dir.join("plain.mcap");
    probmot_ok(&["track", city, "-o", plain.to_str().unwrap(), "-q"]);
    (out, std::fs::read(plain).unwrap())
}

/// `-o /dev/stdout | reader`: the reader gets the output's bytes only; the summary line goes to
/// stderr.
#[cfg(target_os = "linux")]
#[test]
fn standard_output_through_a_pipe_gets_the_output_alone() {
    let dir = tempfile::tempdir().unwrap();
    let (out, plain) = track_to_stdout(dir.path(), Stdio::piped());
    assert!(out.stdout == plain, "{} bytes on stdout", out.stdout.len());
}

/// `-o /dev/stdout >> log`: the output is appended where stdout writes (its offset and append
/// mode kept, the file not replaced), the summary goes to stderr.
#[cfg(target_os = "linux")]
#[test]
fn standard_output_redirected_to_a_file_is_appended_to() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("log.bin");
    std::fs::write(&log, b"HEAD").unwrap();
    let appending = std::fs::OpenOptions::new().append(true).open(&log).unwrap();
    let (_, plain) = track_to_stdout(dir.path(), appending.into());
    let expected = [&b"HEAD"[..], &plain].concat();
    assert!(std::fs::read(&log).unwrap() == expected);
    assert_eq!(
        entries(dir.path()),
        ["log.bin", "plain.mcap", "stdout"],
        "nothing else written beside"
    );
}

/// `-o /dev/stdout 2>&1 | reader`: warnings would be mixed into the output, so it is refused
/// with a message (which the reader gets), before any work.
#[cfg(target_os = "linux")]
#[test]
fn standard_output_with_stderr_joined_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("stdout");
    symlink("/proc/self/fd/1", &link).unwrap();
    let got = dir.path().join("got");
    let city = repo("sample_logs/city.mcap");
    let script = r#""$0" track "$1" -o "$2" 2>&1 | cat > "$3"; exit "${PIPESTATUS[0]}""#;
    let status = std::process::Command::new("bash")
        .args(["-c", script, env!("CARGO_BIN_EXE_probmot")])
        .args([city.as_os_str(), link.as_os_str(), got.as_os_str()])
        .status()
        .unwrap();
    assert_eq!(status.code(), Some(2));
    let text = std::fs::read_to_string(&got).unwrap();
    assert!(
        text.contains("standard error goes where the output does"),
        "{text}"
    );
}
