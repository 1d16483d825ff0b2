//! What `track` can read: a regular file. It seeks (to the summary section, and back to the
//! start for a second pass), so a FIFO or a pipe on `/dev/stdin` would otherwise fail with a
//! puzzling "Bad magic number" once its first bytes were consumed.

use std::path::Path;

use anyhow::{bail, Context, Result};

/// The size of `track`'s input, or an error naming it when it is not a regular file.
pub fn regular_input(input: &Path) -> Result<u64> {
    let m = std::fs::metadata(input).with_context(|| format!("cannot open {}", input.display()))?;
    if !m.is_file() {
        let what = match () {
            _ if m.is_dir() => "a directory",
            _ => "not seekable (a pipe, FIFO or device)",
        };
        bail!(
            "{}: {what}: track reads its input more than once; give a regular file (e.g. save \
             the stream to a file first)",
            input.display()
        );
    }
    Ok(m.len())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// (A FIFO and a pipe on /dev/stdin: `tests/it/hostile.rs`.)
    #[test]
    fn a_directory_is_refused_by_name_and_a_file_gives_its_size() {
        let dir = tempfile::tempdir().unwrap();
        let err = regular_input(dir.path()).unwrap_err().to_string();
        assert!(
            err.contains("a directory") && err.contains("give a regular file"),
            "{err}"
        );
        let file = dir.path().join("f.mcap");
        std::fs::write(&file, b"12345").unwrap();
        assert_eq!(regular_input(&file).unwrap(), 5);
    }
}
