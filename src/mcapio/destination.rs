//! Where an output's bytes go. probmot writes a file atomically (a partial file renamed over
//! the destination, [`super::writer`]); a rename replaces whatever the path names, so a path
//! that is not a regular file is resolved first. As root, a rename over `/dev/null` or the
//! `/dev/stdout` link would turn them into ordinary files for every process on the machine.

use std::fs::{File, Metadata};
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};

/// Where the bytes of an output go.
#[derive(Debug, PartialEq, Eq)]
pub enum Destination {
    /// A regular file, written atomically: the path given, or the file its symbolic links lead
    /// to, existing or not (the links stay links).
    File(PathBuf),
    /// Written in place at the path given: a device, FIFO or socket (links followed), or a
    /// regular file behind a link that names no path (a deleted file's `/proc/self/fd/N`).
    InPlace,
    /// This process's standard output (`-o /dev/stdout`, or the file stdout is redirected to):
    /// written through a duplicate of it, its offset and append mode kept ([`take_stdout`]).
    Stdout,
}

/// Most links followed before a chain is taken for a loop (as Linux's `MAXSYMLINKS`).
const MAX_LINKS: usize = 40;

/// Resolves the output path `dest` (see [`Destination`]).
pub fn destination(dest: &Path) -> Result<Destination> {
    let link = std::fs::symlink_metadata(dest).is_ok_and(|m| m.file_type().is_symlink());
    match std::fs::metadata(dest) {
        Ok(m) if is_stdout(&m) => Ok(Destination::Stdout),
        Ok(m) if !m.is_file() && !m.is_dir() => Ok(Destination::InPlace),
        Ok(_) if link => Ok(std::fs::canonicalize(dest)
            .map(Destination::File)
            .unwrap_or(Destination::InPlace)),
        Err(e) if link && e.kind() == std::io::ErrorKind::NotFound => {
            missing_target(dest).map(Destination::File)
        }
        Err(e) if link => {
            Err(e).with_context(|| format!("cannot follow the output link {}", dest.display()))
        }
        _ => Ok(Destination::File(dest.to_path_buf())),
    }
}

/// The path a chain of links ending in a missing file leads to: the file to create.
fn missing_target(dest: &Path) -> Result<PathBuf> {
    let mut path = dest.to_path_buf();
    for _ in 0..MAX_LINKS {
        match std::fs::symlink_metadata(&path) {
            Ok(m) if m.file_type().is_symlink() => {
                let next = std::fs::read_link(&path)
                    .with_context(|| format!("cannot read the link {}", path.display()))?;
                path = parent_dir(&path).join(next);
            }
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                if !parent_dir(&path).is_dir() {
                    bail!(
                        "output {} is a symbolic link to {}, whose directory does not exist",
                        dest.display(),
                        path.display()
                    );
                }
                return Ok(path);
            }
            _ => bail!("cannot follow the output link {}", dest.display()),
        }
    }
    bail!(
        "output {} is a loop of symbolic links (more than {MAX_LINKS})",
        dest.display()
    )
}

/// The directory of `p` (`.` for a bare name).
pub fn parent_dir(p: &Path) -> PathBuf {
    match p.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// Device and inode of a descriptor's file.
#[cfg(unix)]
fn file_id(fd: std::os::fd::BorrowedFd<'_>) -> Option<(u64, u64)> {
    use std::os::unix::fs::MetadataExt;
    let m = File::from(fd.try_clone_to_owned().ok()?).metadata().ok()?;
    Some((m.dev(), m.ino()))
}

/// The file standard output wrote to when the process first resolved an output (before
/// [`take_stdout`] points fd 1 elsewhere), so a later `-o /dev/stdout` is still recognised.
#[cfg(unix)]
fn original_stdout() -> Option<(u64, u64)> {
    use std::os::fd::AsFd;
    static ORIGINAL: std::sync::OnceLock<Option<(u64, u64)>> = std::sync::OnceLock::new();
    *ORIGINAL.get_or_init(|| file_id(std::io::stdout().as_fd()))
}

/// Whether `m` is the file this process's standard output writes to. Not for a character
/// device: `-o /dev/null` with stdout also on `/dev/null` is not writing to the terminal.
#[cfg(unix)]
fn is_stdout(m: &Metadata) -> bool {
    use std::os::unix::fs::{FileTypeExt, MetadataExt};
    !m.file_type().is_char_device() && original_stdout() == Some((m.dev(), m.ino()))
}

#[cfg(not(unix))]
fn is_stdout(_: &Metadata) -> bool {
    false
}

/// Takes standard output for an output's bytes: returns a duplicate of it and points the
/// process's stdout at stderr, so what the command prints afterwards (its summary line) does
/// not land in the output. Once per process: a second output to stdout is refused, and so is
/// stderr going to the same place (`2>&1`: warnings would be mixed into the output).
#[cfg(unix)]
pub fn take_stdout() -> Result<File> {
    use std::io::Write;
    use std::os::fd::AsFd;
    static TAKEN: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);
    if TAKEN.swap(true, std::sync::atomic::Ordering::SeqCst) {
        bail!("standard output already holds another output of this run; give a file path");
    }
    // Locked throughout, so that no other thread prints into the output meanwhile.
    let mut lock = std::io::stdout().lock();
    lock.flush()?;
    if file_id(std::io::stderr().as_fd()) == file_id(lock.as_fd()) {
        bail!(
            "standard error goes where the output does (2>&1?): its warnings would be mixed \
             into the output; send stderr elsewhere"
        );
    }
    let out = lock
        .as_fd()
        .try_clone_to_owned()
        .context("cannot duplicate standard output")?;
    // SAFETY: dup2 on two descriptors this process holds open (Rust's runtime opens /dev/null
    // on a closed fd 2 at start); afterwards fd 1 refers to stderr's file and the output keeps
    // its own duplicate.
    if unsafe { libc::dup2(2, 1) } < 0 {
        return Err(std::io::Error::last_os_error())
            .context("cannot move standard output away from the output");
    }
    drop(lock);
    Ok(File::from(out))
}

#[cfg(not(unix))]
pub fn take_stdout() -> Result<File> {
    bail!("writing an output to standard output needs a Unix system")
}

/// The absolute path an output's bytes go to when it is a file ([`Destination::File`], its
/// directory canonical), else `None`: the key under which two outputs of one run are the same.
pub fn resolved_file(dest: &Path) -> Result<Option<PathBuf>> {
    match destination(dest)? {
        Destination::File(path) => absolute(&path).map(Some),
        _ => Ok(None),
    }
}

/// `path` with its directory made canonical (the file itself need not exist).
pub fn absolute(path: &Path) -> Result<PathBuf> {
    let dir = parent_dir(path);
    let dir = dir
        .canonicalize()
        .with_context(|| format!("output directory {} does not exist", dir.display()))?;
    Ok(match path.file_name() {
        Some(name) => dir.join(name),
        None => dir,
    })
}

#[cfg(all(test, unix))]
mod tests {
    use super::*;
    use std::os::unix::fs::symlink;

    #[test]
    fn link_chains_lead_to_the_file_to_create_and_loops_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        symlink("a", d.join("out")).unwrap();
        symlink("sub/b", d.join("a")).unwrap();
        std::fs::create_dir(d.join("sub")).unwrap();
        assert_eq!(
            destination(&d.join("out")).unwrap(),
            Destination::File(d.join("sub/b"))
        );
        symlink("loop2", d.join("loop1")).unwrap();
        symlink("loop1", d.join("loop2")).unwrap();
        assert!(destination(&d.join("loop1")).is_err());
        symlink("nowhere/x", d.join("lost")).unwrap();
        let err = destination(&d.join("lost")).unwrap_err().to_string();
        assert!(err.contains("directory does not exist"), "{err}");
        assert_eq!(
            destination(&d.join("plain.mcap")).unwrap(),
            Destination::File(d.join("plain.mcap"))
        );
    }
}
