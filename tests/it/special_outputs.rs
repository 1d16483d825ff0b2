//! Outputs whose destination is not a regular file (`/dev/null`, a FIFO) are written in place:
//! the atomic rename of a finished file would replace the device node, which as root turns
//! `/dev/null` into an ordinary file for every process on the machine. A FIFO stands for every
//! such destination here (it needs no privileges, unlike a device node).
#![cfg(unix)]

use std::ffi::CString;
use std::os::unix::ffi::OsStrExt;
use std::os::unix::fs::FileTypeExt;
use std::path::Path;
use std::thread::JoinHandle;

use crate::common::{probmot_ok, repo};

/// Makes a FIFO at `path` and starts a thread reading it to the end.
fn fifo_reader(path: &Path) -> JoinHandle<Vec<u8>> {
    let c = CString::new(path.as_os_str().as_bytes()).unwrap();
    // SAFETY: mkfifo(3) with a NUL-terminated path; the result is checked.
    let rc = unsafe { libc::mkfifo(c.as_ptr(), 0o644) };
    assert_eq!(rc, 0, "mkfifo {}", path.display());
    let path = path.to_path_buf();
    std::thread::spawn(move || std::fs::read(path).unwrap())
}

/// The entries of `dir` (hidden ones too: a partial file would be one).
fn entries(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
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
