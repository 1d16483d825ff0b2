//! Atomic output: written to a partial file beside the destination (`.NAME.probmot-partial`),
//! renamed over the destination only when complete. An error removes the partial file, an
//! interrupt too ([`abandon_partials`], called by the binary's signal handler); one left by a
//! hard kill (SIGKILL, power loss) is named so that a user can tell what it is, and the next run
//! writing the same output removes it. A destination that is not a regular file (`/dev/null`,
//! a FIFO, standard output) is written in place and a symbolic link is followed
//! ([`super::destination`]): renaming over them would replace the device node or the link.

use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard};

use anyhow::{bail, Context, Result};
use mcap::write::NoSeek;
use mcap::{WriteOptions, Writer};

use super::destination::{absolute, destination, parent_dir, take_stdout, Destination};

/// zstd level of the output's chunks. Measured in `track` (docs/scaling.md, issue #39): level 2
/// writes 4-5 % fewer bytes than level 1 and, with fewer bytes to code, takes fewer instructions;
/// level 3 writes 3 % fewer again for 25 % more compression work.
pub const ZSTD_LEVEL: u32 = 2;

/// Compression of the output's chunks.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum OutputCompression {
    /// zstd level [`ZSTD_LEVEL`] (the default: small files, fast enough).
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

    /// The level given to the compressor: zstd [`ZSTD_LEVEL`], lz4 1.
    fn level(self) -> u32 {
        match self {
            OutputCompression::Zstd => ZSTD_LEVEL,
            OutputCompression::Lz4 | OutputCompression::None => 1,
        }
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
    /// Sync the file to the disk before it is renamed into place. The files of a partial
    /// directory (a split bag's) are synced by its owner before the directory is renamed:
    /// syncing each as it ends would stall the writing at every file.
    pub sync: bool,
}

impl Default for OutputOptions {
    fn default() -> Self {
        OutputOptions {
            profile: String::new(),
            chunk_size: 1 << 20,
            compression: OutputCompression::Zstd,
            sync: true,
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

/// Outputs being written in place now (no partial file): what an interrupt leaves half written.
static IN_PLACE: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn in_place_outputs() -> MutexGuard<'static, Vec<PathBuf>> {
    IN_PLACE.lock().unwrap_or_else(|e| e.into_inner())
}

/// The outputs being written in place (a device, FIFO or standard output) when the process is
/// interrupted: nothing to remove, but their readers got part of an output. Like
/// [`abandon_partials`], for the way out of the process only (the list stays locked).
pub fn abandon_in_place() -> Vec<PathBuf> {
    let guard = in_place_outputs();
    let dests = guard.clone();
    std::mem::forget(guard);
    dests
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
    /// ([`Destination::InPlace`], [`Destination::Stdout`]): renaming a file over a device node,
    /// a FIFO or a link to one would replace it with an ordinary file.
    path: Option<PathBuf>,
    dest: PathBuf,
    done: bool,
    /// Whether [`Partial::persist`] syncs the file.
    sync: bool,
}

impl Partial {
    /// Creates the partial file of the output `given` (mode 0644, an ordinary file once
    /// renamed) beside the file it resolves to, replacing a stale one of a killed run, and
    /// registers it for removal on an interrupt; or opens a destination written in place.
    fn create(given: &Path) -> Result<(File, Partial)> {
        let dest = match destination(given)? {
            // Absolute, so that two spellings of one file share one partial path (refused).
            Destination::File(path) => absolute(&path)?,
            Destination::InPlace => return Partial::in_place(given),
            Destination::Stdout => return Ok((take_stdout()?, Partial::unnamed(given))),
        };
        let dest = dest.as_path();
        refuse_read_only(given, dest)?;
        let path = partial_path(dest);
        let mut registry = partials();
        if registry.iter().any(|(p, _)| p == &path) {
            bail!(
                "{} is already being written by this run (two outputs lead to the same file)",
                given.display()
            );
        }
        match std::fs::remove_file(&path) {
            Ok(()) => eprintln!(
                "note: removed {}, left by an interrupted run writing {}",
                path.display(),
                given.display()
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
        // Interrupt messages name the output as given.
        registry.push((path.clone(), given.to_path_buf()));
        let partial = Partial {
            path: Some(path),
            dest: dest.to_path_buf(),
            done: false,
            sync: true,
        };
        Ok((file, partial))
    }

    /// Opens `dest` to be written in place (see [`Destination::InPlace`]): nothing to rename,
    /// nothing to remove.
    fn in_place(dest: &Path) -> Result<(File, Partial)> {
        // A regular file behind a link that names no path is rewritten from its start.
        let regular = std::fs::metadata(dest).is_ok_and(|m| m.is_file());
        let file = std::fs::OpenOptions::new()
            .write(true)
            .truncate(regular)
            .open(dest)
            .with_context(|| format!("cannot open {} for writing", dest.display()))?;
        Ok((file, Partial::unnamed(dest)))
    }

    /// The bookkeeping of an output written in place: no partial file, listed for an interrupt.
    fn unnamed(dest: &Path) -> Partial {
        in_place_outputs().push(dest.to_path_buf());
        Partial {
            path: None,
            dest: dest.to_path_buf(),
            done: false,
            sync: true,
        }
    }

    /// Takes an output written in place off the interrupt's list (one entry: the same device
    /// may be written twice at once).
    fn forget_in_place(&self) {
        let mut list = in_place_outputs();
        if let Some(k) = list.iter().position(|d| d == &self.dest) {
            list.remove(k);
        }
    }

    /// Syncs the complete `file` (unless told not to) and renames the partial file over the destination (a
    /// destination written in place is left as it is: a device need not support syncing).
    fn persist(mut self, file: File) -> Result<()> {
        self.done = true;
        let Some(path) = self.path.take() else {
            self.forget_in_place();
            return Ok(());
        };
        let synced = match self.sync {
            true => file.sync_all(),
            false => Ok(()),
        };
        let result = synced
            .with_context(|| format!("syncing {}", self.dest.display()))
            .and_then(|()| {
                drop(file);
                // Locked for the rename only: an interrupt sees the partial file or the output.
                let mut registry = partials();
                let renamed = std::fs::rename(&path, &self.dest)
                    .with_context(|| format!("renaming the output to {}", self.dest.display()));
                if renamed.is_ok() {
                    registry.retain(|(p, _)| p != &path);
                }
                renamed
            });
        if result.is_err() {
            let mut registry = partials();
            let _ = std::fs::remove_file(&path);
            registry.retain(|(p, _)| p != &path);
        }
        result
    }
}

impl Drop for Partial {
    fn drop(&mut self) {
        match (self.done, &self.path) {
            (false, Some(path)) => {
                let mut registry = partials();
                let _ = std::fs::remove_file(path);
                registry.retain(|(p, _)| p != path);
            }
            (false, None) => self.forget_in_place(),
            _ => {}
        }
    }
}

/// Refuses to replace an existing output file that has no write permission (mode 0444): the
/// rename would replace it anyway, and the new file would come back writable.
fn refuse_read_only(given: &Path, dest: &Path) -> Result<()> {
    match std::fs::metadata(dest) {
        Ok(m) if m.is_file() && m.permissions().readonly() => bail!(
            "output {} exists and is read-only: probmot does not replace a read-only file \
             (make it writable, or remove it, first)",
            given.display()
        ),
        _ => Ok(()),
    }
}

/// Library string written into the header of every file probmot writes.
pub fn library_string() -> String {
    format!("probmot {}", env!("CARGO_PKG_VERSION"))
}

/// Whether `dest` exists as something other than a regular file or a directory (a device such
/// as `/dev/null`, a FIFO): written in place, so its name need not give the format.
pub fn is_device_or_fifo(dest: &Path) -> bool {
    std::fs::metadata(dest).is_ok_and(|m| !m.is_file() && !m.is_dir())
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

/// Refuses an output that is (a link to) any of the inputs: writing it would replace that
/// input. One canonical path per file, so a run over many logs stays linear.
pub fn refuse_outputs_onto_inputs(outputs: &[PathBuf], inputs: &[PathBuf]) -> Result<()> {
    let canonical_inputs: std::collections::HashMap<PathBuf, &PathBuf> = inputs
        .iter()
        .filter_map(|i| Some((i.canonicalize().ok()?, i)))
        .collect();
    for o in outputs {
        if let Some(input) = o.canonicalize().ok().and_then(|c| canonical_inputs.get(&c)) {
            bail!(
                "output {} is the input {}; probmot never modifies its inputs, choose another \
                 output path",
                o.display(),
                input.display()
            );
        }
    }
    Ok(())
}

/// Writes `bytes` to `dest` atomically: a partial file in the same directory, synced, then
/// renamed over `dest`. Permissions are those of an ordinary file (0644). A device or FIFO is
/// written in place.
pub fn write_file_atomic(dest: &Path, bytes: &[u8]) -> Result<()> {
    use std::io::Write;
    write_file_atomic_with(dest, |w| {
        w.write_all(bytes)
            .with_context(|| format!("writing {}", dest.display()))
    })
}

/// Writes `dest` atomically as [`write_file_atomic`] does, from `fill`, which streams into a
/// buffered writer: the output is never held in memory whole. After an error of `fill` (or an
/// interrupt) no partial file is left behind and what is still buffered is dropped; a
/// destination written in place (stdout, a pipe, a device) keeps what was flushed before, so
/// callers check their input before they write to one.
pub fn write_file_atomic_with(
    dest: &Path,
    fill: impl FnOnce(&mut BufWriter<File>) -> Result<()>,
) -> Result<()> {
    let (file, partial) = Partial::create(dest)?;
    let mut w = BufWriter::with_capacity(1 << 16, file);
    if let Err(e) = fill(&mut w) {
        // Dropping the writer would flush its buffer into the destination.
        drop(w.into_parts());
        return Err(e);
    }
    let file = (w.into_inner().map_err(|e| e.into_error()))
        .with_context(|| format!("writing {}", dest.display()))?;
    partial.persist(file)
}

impl AtomicOutput {
    /// Creates the partial file beside `dest` and an MCAP writer on it: compressed chunks (zstd
    /// level [`ZSTD_LEVEL`] by default, on the thread that writes: `BackgroundOutput` gives the output a thread
    /// of its own where it pays), message and chunk indexes, and a summary section,
    /// so viewers can seek.
    pub fn create(dest: &Path, opts: &OutputOptions) -> Result<Self> {
        let (file, mut partial) = Partial::create(dest)?;
        partial.sync = opts.sync;
        let writer = WriteOptions::new()
            .profile(opts.profile.clone())
            .library(library_string())
            .compression(opts.compression.mcap())
            .compression_threads(0)
            .compression_level(opts.compression.level())
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
