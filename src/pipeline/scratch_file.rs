//! Scratch files: the decompressed copy of a file that cannot be read as a stream (a sqlite3
//! bag's `NAME.db3.zstd`: SQLite needs random access), or the copy of a sqlite3 file with its
//! write-ahead log (which SQLite reads only by writing beside it). Written in the temporary directory
//! (`TMPDIR`, else `/tmp`), removed when dropped, and on an interrupt by
//! [`remove_scratch_files`] (called by the binary's signal handler), so an interrupted run
//! leaves none behind. At most two exist per bag being read, both of the file being read (a
//! decompressed or logged copy, and the copy of that whose header's page count is set right).

use std::fs::File;
use std::io::BufReader;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, MutexGuard};

use anyhow::{Context, Result};

/// The scratch files that exist now: what an interrupt removes.
static SCRATCH: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn registry() -> MutexGuard<'static, Vec<PathBuf>> {
    SCRATCH.lock().unwrap_or_else(|e| e.into_inner())
}

/// Removes every scratch file. The registry stays locked, so that no scratch file is made
/// afterwards: call it only on the way out of the process (the signal handler).
pub fn remove_scratch_files() {
    let guard = registry();
    for p in guard.iter() {
        remove_with_logs(p);
    }
    std::mem::forget(guard);
}

/// Removes the file `path` and the files SQLite keeps beside a database it reads in WAL mode.
fn remove_with_logs(path: &Path) {
    let _ = std::fs::remove_file(path);
    for suffix in ["-wal", "-shm"] {
        let mut log = path.as_os_str().to_owned();
        log.push(suffix);
        let _ = std::fs::remove_file(log);
    }
}

/// A file in the temporary directory, removed on drop.
pub struct ScratchFile {
    path: PathBuf,
}

impl ScratchFile {
    /// A new empty scratch file for a copy of `source`, named after it (`stem`), open for
    /// writing.
    fn create(source: &Path, stem: &str) -> Result<(ScratchFile, File)> {
        static NEXT: AtomicU64 = AtomicU64::new(0);
        let n = NEXT.fetch_add(1, Ordering::Relaxed);
        let path =
            (std::env::temp_dir()).join(format!(".probmot-{}-{n}-{stem}", std::process::id()));
        let mut registry = registry();
        let out = (std::fs::OpenOptions::new().write(true).create_new(true))
            .open(&path)
            .with_context(|| {
                format!(
                    "{}: cannot make its scratch file {} (TMPDIR chooses where)",
                    source.display(),
                    path.display()
                )
            })?;
        registry.push(path.clone());
        Ok((ScratchFile { path }, out))
    }

    /// The zstd file `compressed` decompressed into a new scratch file (named after it).
    pub fn unzstd(compressed: &Path) -> Result<ScratchFile> {
        let name = compressed.display();
        let input = File::open(compressed).with_context(|| format!("cannot open {name}"))?;
        let stem = (compressed.file_name().map(|n| n.to_string_lossy()))
            .map(|n| n.trim_end_matches(".zstd").to_string())
            .unwrap_or_default();
        let (scratch, mut out) = Self::create(compressed, &stem)?;
        let mut decoder = zstd::stream::read::Decoder::with_buffer(BufReader::new(input))
            .with_context(|| format!("{name}: cannot start zstd"))?;
        std::io::copy(&mut decoder, &mut out).with_context(|| {
            format!(
                "{name}: decompressing it into {} (a scratch copy SQLite can read; TMPDIR \
                 chooses where)",
                scratch.path.display()
            )
        })?;
        Ok(scratch)
    }

    /// A copy of the SQLite file `db` with its write-ahead log `wal` (when there is one) beside it (as `PATH-wal`),
    /// so that SQLite reads the log's transactions from the copy: reading them in place would
    /// write an index (`-shm`) beside the input, and fail in a directory it cannot write.
    pub fn sqlite_with_wal(db: &Path, wal: &Path) -> Result<ScratchFile> {
        let stem = (db.file_name().map(|n| n.to_string_lossy().into_owned())).unwrap_or_default();
        let (scratch, mut out) = Self::create(db, &stem)?;
        let copy = |from: &Path, to: &mut File| {
            let mut input =
                File::open(from).with_context(|| format!("cannot open {}", from.display()))?;
            std::io::copy(&mut input, to).with_context(|| {
                format!(
                    "{}: copying it into the scratch file {} (a copy SQLite can read with its \
                     write-ahead log; TMPDIR chooses where)",
                    from.display(),
                    scratch.path.display()
                )
            })
        };
        copy(db, &mut out)?;
        if !wal.exists() {
            return Ok(scratch);
        }
        let mut log = scratch.path.as_os_str().to_owned();
        log.push("-wal");
        let mut log = (std::fs::OpenOptions::new().write(true).create_new(true))
            .open(PathBuf::from(log))
            .with_context(|| format!("{}: cannot make its scratch copy", wal.display()))?;
        copy(wal, &mut log)?;
        Ok(scratch)
    }

    /// A copy of the SQLite file `db` whose header counts `pages` pages (the pages the file
    /// holds, where a writer killed while committing left a header counting more, which SQLite
    /// refuses at once).
    pub fn sqlite_with_page_count(db: &Path, pages: u64) -> Result<ScratchFile> {
        use std::io::{Seek, SeekFrom, Write};
        let stem = (db.file_name().map(|n| n.to_string_lossy().into_owned())).unwrap_or_default();
        let (scratch, mut out) = Self::create(db, &stem)?;
        let mut input = File::open(db).with_context(|| format!("cannot open {}", db.display()))?;
        let count = u32::try_from(pages).unwrap_or(u32::MAX).to_be_bytes();
        (std::io::copy(&mut input, &mut out))
            .and_then(|_| out.seek(SeekFrom::Start(28)))
            .and_then(|_| out.write_all(&count))
            .with_context(|| {
                format!(
                    "{}: copying it into the scratch file {} (a copy whose header SQLite reads; \
                     TMPDIR chooses where)",
                    db.display(),
                    scratch.path.display()
                )
            })?;
        Ok(scratch)
    }

    /// Where the scratch file is.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

impl Drop for ScratchFile {
    fn drop(&mut self) {
        let mut registry = registry();
        remove_with_logs(&self.path);
        registry.retain(|p| p != &self.path);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The scratch file holds the decompressed bytes while it lives, and is gone after.
    #[test]
    fn a_scratch_file_is_the_decompressed_file_and_goes_on_drop() {
        let d = tempfile::tempdir().unwrap();
        let z = d.path().join("b_0.db3.zstd");
        std::fs::write(&z, zstd::encode_all(&b"some bytes"[..], 3).unwrap()).unwrap();
        let s = ScratchFile::unzstd(&z).unwrap();
        assert_eq!(std::fs::read(s.path()).unwrap(), b"some bytes");
        assert!(s.path().to_string_lossy().ends_with("-b_0.db3"));
        assert!(registry().contains(&s.path().to_path_buf()));
        let path = s.path().to_path_buf();
        drop(s);
        assert!(!path.exists() && !registry().contains(&path));
        std::fs::write(&z, b"not zstd").unwrap();
        let e = format!("{:#}", ScratchFile::unzstd(&z).err().unwrap());
        assert!(e.contains("b_0.db3.zstd"), "{e}");
    }
}
