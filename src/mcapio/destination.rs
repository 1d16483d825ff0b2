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

/// Whether `m` is the file this process's standard output writes to. Not for a character
/// device: `-o /dev/null` with stdout also on `/dev/null` is not writing to the terminal.
#[cfg(unix)]
fn is_stdout(m: &Metadata) -> bool {
    use std::os::fd::AsFd;
    use std::os::unix::fs::{FileTypeExt, MetadataExt};
    if m.file_type().is_char_device() {
        return false;
    }
    let Ok(fd) = std::io::stdout().as_fd().try_clone_to_owned() else {
        return false;
    };
    File::from(fd)
        .metadata()
        .is_ok_and(|s| (s.dev(), s.ino()) == (m.dev(), m.ino()))
}

#[cfg(not(unix))]
fn is_stdout(_: &Metadata) -> bool {
    false
}

/// Takes standard output for an output's bytes: returns a duplicate of it and points the
/// process's stdout at stderr, so what the command prints afterwards (its summary line) does
/// not land in the output (at `/dev/null` when stderr is closed).
#[cfg(unix)]
pub fn take_stdout() -> Result<File> {
    use std::io::Write;
    use std::os::fd::{AsFd, AsRawFd};
    std::io::stdout().flush()?;
    let out = std::io::stdout()
        .as_fd()
        .try_clone_to_owned()
        .context("cannot duplicate standard output")?;
    // SAFETY: dup2 on descriptors this process holds open; afterwards fd 1 refers to stderr's
    // file (or /dev/null) and the output keeps its own duplicate.
    if unsafe { libc::dup2(2, 1) } < 0 {
        let null = File::options().write(true).open("/dev/null")?;
        // SAFETY: as above, with /dev/null's descriptor.
        if unsafe { libc::dup2(null.as_raw_fd(), 1) } < 0 {
            return Err(std::io::Error::last_os_error())
                .context("cannot move standard output away from the output");
        }
    }
    Ok(File::from(out))
}

#[cfg(not(unix))]
pub fn take_stdout() -> Result<File> {
    bail!("writing an output to standard output needs a Unix system")
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
