//! Atomic output: written to a partial file beside the destination (`.NAME.probmot-partial`),
//! renamed over the destination only when complete. An error removes the partial file, an
//! interrupt too ([`abandon_partials`], called by the binary's signal handler); one left by a
//! hard kill (SIGKILL, power loss) is named so that a user can tell what it is, and the next run
//! writing the same output removes it. A destination that exists and is not a regular file
//! (`/dev/null`, a FIFO) is written in place: renaming over it would replace the device node.

use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard};

use anyhow::{bail, Context, Result};
use mcap::write::NoSeek;
use mcap::{WriteOptions, Writer};

/// Compression of the output's chunks.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum OutputCompression {
    /// zstd level 1 (the default: small files, fast enough).
    #[default]
    Zstd,
    /// lz4: faster to write and read, larger files.
    Lz4,
    /// Uncompressed chunks.
    None,
}

impl OutputCompression {
    /// Every variant with its name, for parsing and help texts.
    pub const NAMES: [(&'static str, OutputCompression); 3] = [
        ("zstd", OutputCompression::Zstd),
        ("lz4", OutputCompression::Lz4),
        ("none", OutputCompression::None),
    ];

    /// Parses `zstd`, `lz4` or `none`.
    pub fn parse(s: &str) -> Result<OutputCompression, String> {
        Self::NAMES
            .iter()
            .find(|(n, _)| *n == s)
            .map(|(_, c)| *c)
            .ok_or_else(|| format!("'{s}': expected zstd, lz4 or none"))
    }

    fn mcap(self) -> Option<mcap::Compression> {
        match self {
            OutputCompression::Zstd => Some(mcap::Compression::Zstd),
            OutputCompression::Lz4 => Some(mcap::Compression::Lz4),
            OutputCompression::None => None,
        }
    }
}

/// Options of the output file.
#[derive(Debug, Clone)]
pub struct OutputOptions {
    /// Profile of the header record (kept from the input).
    pub profile: String,
    /// Chunk size in bytes before compression.
    pub chunk_size: u64,
    /// Chunk compression.
    pub compression: OutputCompression,
}

impl Default for OutputOptions {
    fn default() -> Self {
        OutputOptions {
            profile: String::new(),
            chunk_size: 1 << 20,
            compression: OutputCompression::Zstd,
        }
    }
}

/// What the MCAP writer of an output writes into: the file, buffered, counting its position
/// instead of seeking, so that a device or a FIFO written in place works like a file (the
/// writer buffers each chunk, at most the chunk size, rather than going back to fill in its
/// length; the bytes are the same).
pub type OutputSink = NoSeek<BufWriter<File>>;

/// An MCAP writer on a partial file that becomes `dest` on [`AtomicOutput::commit`].
pub struct AtomicOutput {
    /// The MCAP writer.
    pub writer: Writer<OutputSink>,
    partial: Partial,
}

/// Suffix of partial output files.
pub const PARTIAL_SUFFIX: &str = ".probmot-partial";

/// Partial files being written now, with their destinations: what an interrupt removes.
static PARTIALS: Mutex<Vec<(PathBuf, PathBuf)>> = Mutex::new(Vec::new());

fn partials() -> MutexGuard<'static, Vec<(PathBuf, PathBuf)>> {
    PARTIALS.lock().unwrap_or_else(|e| e.into_inner())
}

/// The partial file of output `dest`: `.NAME.probmot-partial` in the same directory (the same
/// file system, so the final rename is atomic).
pub fn partial_path(dest: &Path) -> PathBuf {
    let name = dest
        .file_name()
        .unwrap_or(dest.as_os_str())
        .to_string_lossy();
    parent_dir(dest).join(format!(".{name}{PARTIAL_SUFFIX}"))
}

/// Removes the partial file of every output being written and returns their destinations. The
/// registry stays locked, so that no output starts or is committed afterwards: call it only on the
/// way out of the process (the signal handler).
pub fn abandon_partials() -> Vec<PathBuf> {
    let guard = partials();
    let dests = guard
        .iter()
        .map(|(partial, dest)| {
            let _ = std::fs::remove_file(partial);
            dest.clone()
        })
        .collect();
    std::mem::forget(guard);
    dests
}

/// A partial output file, removed on drop unless [`Partial::persist`]ed.
struct Partial {
    /// The partial file; `None` when the destination is written in place
    /// ([`Destination::InPlace`]): renaming a file over a device node, a FIFO or a link to one
    /// would replace it with an ordinary file.
    path: Option<PathBuf>,
    dest: PathBuf,
    done: bool,
}

/// Where the bytes of an output go.
enum Destination {
    /// Written in place: a device, FIFO or socket (symbolic links followed, so `/dev/stdout`
    /// too), or a link whose regular file has no path to write beside (a deleted file).
    InPlace,
    /// A regular file, written atomically: the path given, or the file its symbolic link points
    /// to, existing or not (the link stays a link).
    File(PathBuf),
}

/// Resolves an output path: a rename over a symbolic link would replace the link itself (as
/// root, `-o /dev/stdout` turned the machine's `/dev/stdout` into an ordinary file).
fn destination(dest: &Path) -> Result<Destination> {
    let link = std::fs::symlink_metadata(dest).is_ok_and(|m| m.file_type().is_symlink());
    match std::fs::metadata(dest) {
        Ok(m) if !m.is_file() && !m.is_dir() => Ok(Destination::InPlace),
        Ok(_) if link => Ok(std::fs::canonicalize(dest)
            .map(Destination::File)
            .unwrap_or(Destination::InPlace)),
        Err(_) if link => {
            // A link to a file not written yet: the file is created where the link points.
            let target = std::fs::read_link(dest)
                .with_context(|| format!("cannot read the link {}", dest.display()))?;
            let target = parent_dir(dest).join(target);
            if !parent_dir(&target).is_dir() {
                bail!(
                    "output {} is a symbolic link to {}, whose directory does not exist",
                    dest.display(),
                    target.display()
                );
            }
            Ok(Destination::File(target))
        }
        _ => Ok(Destination::File(dest.to_path_buf())),
    }
}

/// When `output` is the pipe or socket this process's standard output writes to
/// (`-o /dev/stdout | ...`), everything the command prints to stdout from now on (its summary
/// line) goes to stderr instead, so the reader at the other end gets the output's bytes only.
#[cfg(unix)]
fn leave_stdout_to(output: &File) -> Result<()> {
    use std::io::Write;
    use std::os::fd::AsFd;
    use std::os::unix::fs::{FileTypeExt, MetadataExt};
    let out = output.metadata()?;
    if !(out.file_type().is_fifo() || out.file_type().is_socket()) {
        return Ok(());
    }
    let Ok(stdout) = std::io::stdout().as_fd().try_clone_to_owned() else {
        return Ok(());
    };
    let Ok(ours) = File::from(stdout).metadata() else {
        return Ok(());
    };
    if (ours.dev(), ours.ino()) == (out.dev(), out.ino()) {
        std::io::stdout().flush()?;
        // SAFETY: dup2 on two descriptors this process holds open (1 and 2); afterwards fd 1
        // refers to stderr's file, the output keeps its own descriptor.
        if unsafe { libc::dup2(2, 1) } < 0 {
            return Err(std::io::Error::last_os_error())
                .context("cannot move standard output to stderr");
        }
    }
    Ok(())
}

impl Partial {
    /// Creates the partial file of `dest` (mode 0644, an ordinary file once renamed), replacing a
    /// stale one of a killed run, and registers it for removal on an interrupt.
    fn create(dest: &Path) -> Result<(File, Partial)> {
        let dest = match destination(dest)? {
            Destination::File(path) => path,
            Destination::InPlace => return Partial::in_place(dest),
        };
        let dest = dest.as_path();
        let path = partial_path(dest);
        let mut registry = partials();
        match std::fs::remove_file(&path) {
            Ok(()) => eprintln!(
                "note: removed {}, left by an interrupted run writing {}",
                path.display(),
                dest.display()
            ),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => {
                return Err(e).with_context(|| {
                    format!("cannot remove the stale partial file {}", path.display())
                })
            }
        }
        let mut open = std::fs::OpenOptions::new();
        open.write(true).create_new(true);
        #[cfg(unix)]
        std::os::unix::fs::OpenOptionsExt::mode(&mut open, 0o644);
        let file = open
            .open(&path)
            .with_context(|| format!("cannot create the partial file {}", path.display()))?;
        registry.push((path.clone(), dest.to_path_buf()));
        let partial = Partial {
            path: Some(path),
            dest: dest.to_path_buf(),
            done: false,
        };
        Ok((file, partial))
    }

    /// Opens `dest` to be written in place (see [`Destination::InPlace`]): nothing to rename,
    /// nothing to remove.
    fn in_place(dest: &Path) -> Result<(File, Partial)> {
        // A regular file behind an unresolvable link is rewritten from its start; O_TRUNC on a
        // device or FIFO would do nothing, but stays off there.
        let regular = std::fs::metadata(dest).is_ok_and(|m| m.is_file());
        let file = std::fs::OpenOptions::new()
            .write(true)
            .truncate(regular)
            .open(dest)
            .with_context(|| format!("cannot open {} for writing", dest.display()))?;
        #[cfg(unix)]
        leave_stdout_to(&file)?;
        let partial = Partial {
            path: None,
            dest: dest.to_path_buf(),
            done: false,
        };
        Ok((file, partial))
    }

    /// Syncs the complete `file` and renames the partial file over the destination (a
    /// destination written in place is left as it is: a device need not support syncing).
    fn persist(mut self, file: File) -> Result<()> {
        self.done = true;
        let Some(path) = self.path.take() else {
            return Ok(());
        };
        let mut registry = partials();
        let result = file
            .sync_all()
            .with_context(|| format!("syncing {}", self.dest.display()))
            .and_then(|()| {
                drop(file);
                std::fs::rename(&path, &self.dest)
                    .with_context(|| format!("renaming the output to {}", self.dest.display()))
            });
        if result.is_err() {
            let _ = std::fs::remove_file(&path);
        }
        registry.retain(|(p, _)| p != &path);
        result
    }
}

impl Drop for Partial {
    fn drop(&mut self) {
        if let (false, Some(path)) = (self.done, &self.path) {
            let mut registry = partials();
            let _ = std::fs::remove_file(path);
            registry.retain(|(p, _)| p != path);
        }
    }
}

/// Library string written into the header of every file probmot writes.
pub fn library_string() -> String {
    format!("probmot {}", env!("CARGO_PKG_VERSION"))
}

/// Checks an output path before any work: it is not a directory (nor written as one, with a
/// trailing slash), its directory exists and it is not the input.
pub fn check_output_path(input: Option<&Path>, dest: &Path) -> Result<()> {
    let text = dest.as_os_str().to_string_lossy();
    if text.ends_with(std::path::is_separator) {
        bail!(
            "output {} names a directory (it ends with a slash); give the path of a file to \
             write, e.g. {}",
            dest.display(),
            dest.join("out.mcap").display()
        );
    }
    if dest.is_dir() {
        bail!(
            "output {} is a directory; give the path of a file to write",
            dest.display()
        );
    }
    let dir = parent_dir(dest);
    if !dir.is_dir() {
        bail!(
            "output directory {} does not exist (for output {})",
            dir.display(),
            dest.display()
        );
    }
    if let Some(input) = input {
        let same = match (input.canonicalize(), dest.canonicalize()) {
            (Ok(a), Ok(b)) => a == b,
            _ => false,
        };
        if same {
            bail!(
                "output {} is the input file; probmot never modifies its input, choose another path",
                dest.display()
            );
        }
    }
    Ok(())
}

fn parent_dir(p: &Path) -> PathBuf {
    match p.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// Writes `bytes` to `dest` atomically: a partial file in the same directory, synced, then
/// renamed over `dest`. Permissions are those of an ordinary file (0644). A device or FIFO is
/// written in place.
pub fn write_file_atomic(dest: &Path, bytes: &[u8]) -> Result<()> {
    use std::io::Write;
    let (mut file, partial) = Partial::create(dest)?;
    file.write_all(bytes)
        .with_context(|| format!("writing {}", dest.display()))?;
    partial.persist(file)
}

impl AtomicOutput {
    /// Creates the partial file beside `dest` and an MCAP writer on it: compressed chunks (zstd
    /// level 1 by default, on the thread that writes: `BackgroundOutput` gives the output a thread
    /// of its own where it pays), message and chunk indexes, and a summary section,
    /// so viewers can seek.
    pub fn create(dest: &Path, opts: &OutputOptions) -> Result<Self> {
        let (file, partial) = Partial::create(dest)?;
        let writer = WriteOptions::new()
            .profile(opts.profile.clone())
            .library(library_string())
            .compression(opts.compression.mcap())
            .compression_threads(0)
            .compression_level(1)
            .chunk_size(Some(opts.chunk_size))
            .disable_seeking(true)
            .create(NoSeek::new(BufWriter::with_capacity(1 << 16, file)))
            .with_context(|| format!("cannot start MCAP output {}", dest.display()))?;
        Ok(AtomicOutput { writer, partial })
    }

    /// Finishes the MCAP (summary, footer), flushes, syncs and renames over the destination.
    pub fn commit(mut self) -> Result<()> {
        let dest = self.partial.dest.clone();
        self.writer
            .finish()
            .with_context(|| format!("finishing {}", dest.display()))?;
        let file = self
            .writer
            .into_inner()
            .into_inner()
            .into_inner()
            .map_err(|e| e.into_error())
            .with_context(|| format!("flushing {}", dest.display()))?;
        self.partial.persist(file)
    }
}
