//! Atomic MCAP output: written to a temporary file in the destination directory, renamed over
//! the destination only when complete. A crash or an error leaves no output file behind.

use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use mcap::{WriteOptions, Writer};
use tempfile::NamedTempFile;

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

/// An MCAP writer on a temporary file that becomes `dest` on [`AtomicOutput::commit`].
pub struct AtomicOutput {
    /// The MCAP writer.
    pub writer: Writer<BufWriter<File>>,
    temp_path: tempfile::TempPath,
    dest: PathBuf,
}

/// Library string written into the header of every file probmot writes.
pub fn library_string() -> String {
    format!("probmot {}", env!("CARGO_PKG_VERSION"))
}

/// Checks an output path before any work: its directory exists and it is not the input.
pub fn check_output_path(input: Option<&Path>, dest: &Path) -> Result<()> {
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

/// Writes `bytes` to `dest` atomically: a temporary file in the same directory, synced, then
/// renamed over `dest`. Permissions are those of an ordinary file (0644).
pub fn write_file_atomic(dest: &Path, bytes: &[u8]) -> Result<()> {
    use std::io::Write;
    let dir = parent_dir(dest);
    let mut tmp = NamedTempFile::with_prefix_in(".probmot-", &dir)
        .with_context(|| format!("cannot create a temporary file in {}", dir.display()))?;
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        tmp.as_file()
            .set_permissions(std::fs::Permissions::from_mode(0o644))?;
    }
    tmp.write_all(bytes)
        .and_then(|_| tmp.as_file().sync_all())
        .with_context(|| format!("writing {}", dest.display()))?;
    tmp.persist(dest)
        .with_context(|| format!("renaming the output to {}", dest.display()))?;
    Ok(())
}

impl AtomicOutput {
    /// Creates the temporary file beside `dest` and an MCAP writer on it: compressed chunks (zstd
    /// level 1 by default, on the thread that writes: `BackgroundOutput` gives the output a thread
    /// of its own where it pays), message and chunk indexes, and a summary section,
    /// so viewers can seek.
    pub fn create(dest: &Path, opts: &OutputOptions) -> Result<Self> {
        let dir = parent_dir(dest);
        let tmp = NamedTempFile::with_prefix_in(".probmot-", &dir)
            .with_context(|| format!("cannot create a temporary file in {}", dir.display()))?;
        let (file, temp_path) = tmp.into_parts();
        // Temporary files are created private (0600); the output is an ordinary file.
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            file.set_permissions(std::fs::Permissions::from_mode(0o644))
                .with_context(|| format!("setting permissions of {}", dest.display()))?;
        }
        let writer = WriteOptions::new()
            .profile(opts.profile.clone())
            .library(library_string())
            .compression(opts.compression.mcap())
            .compression_threads(0)
            .compression_level(1)
            .chunk_size(Some(opts.chunk_size))
            .create(BufWriter::with_capacity(1 << 16, file))
            .with_context(|| format!("cannot start MCAP output {}", dest.display()))?;
        Ok(AtomicOutput {
            writer,
            temp_path,
            dest: dest.to_path_buf(),
        })
    }

    /// Finishes the MCAP (summary, footer), flushes, syncs and renames over the destination.
    pub fn commit(mut self) -> Result<()> {
        self.writer
            .finish()
            .with_context(|| format!("finishing {}", self.dest.display()))?;
        let buf = self.writer.into_inner();
        let file = buf
            .into_inner()
            .map_err(|e| e.into_error())
            .with_context(|| format!("flushing {}", self.dest.display()))?;
        file.sync_all()
            .with_context(|| format!("syncing {}", self.dest.display()))?;
        self.temp_path
            .persist(&self.dest)
            .with_context(|| format!("renaming the output to {}", self.dest.display()))?;
        Ok(())
    }
}
