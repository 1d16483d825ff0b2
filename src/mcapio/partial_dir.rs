//! Atomic output directories (a split rosbag2 bag): written as `.NAME.probmot-partial` beside
//! the destination and renamed to it only when complete ([`PartialDir`]). An error removes the
//! partial directory, an interrupt too ([`abandon_partial_dirs`], called by the binary's signal
//! handler); one left by a hard kill is removed by the next run writing the same output.

use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard};

use anyhow::{Context, Result};

use super::writer::partial_path;

/// Partial directories being written now, with their destinations: what an interrupt removes.
static PARTIAL_DIRS: Mutex<Vec<(PathBuf, PathBuf)>> = Mutex::new(Vec::new());

fn registry() -> MutexGuard<'static, Vec<(PathBuf, PathBuf)>> {
    PARTIAL_DIRS.lock().unwrap_or_else(|e| e.into_inner())
}

/// Removes every partial directory being written, with all it holds, and returns the pairs
/// `(partial directory, destination)`. The registry stays locked, so that no output directory
/// starts or is renamed afterwards: call it only on the way out of the process (the signal
/// handler), after [`super::writer::abandon_partials`].
pub fn abandon_partial_dirs() -> Vec<(PathBuf, PathBuf)> {
    let guard = registry();
    let dirs = guard.clone();
    for (partial, _) in &dirs {
        let _ = std::fs::remove_dir_all(partial);
    }
    std::mem::forget(guard);
    dirs
}

/// A partial output directory, removed on drop unless [`PartialDir::persist`]ed.
pub struct PartialDir {
    path: PathBuf,
    dest: PathBuf,
    done: bool,
}

impl PartialDir {
    /// Creates the partial directory of the output directory `dest` (`.NAME.probmot-partial`
    /// beside it), replacing one left by a killed run, and registers it for removal on an
    /// interrupt.
    pub fn create(dest: &Path) -> Result<PartialDir> {
        dest.file_name()
            .with_context(|| format!("{}: no directory name", dest.display()))?;
        let path = partial_path(dest);
        let mut registry = registry();
        if path.exists() {
            // Left by an interrupted run: it is ours by its name.
            std::fs::remove_dir_all(&path)
                .with_context(|| format!("cannot remove {}", path.display()))?;
        }
        std::fs::create_dir_all(&path)
            .with_context(|| format!("cannot create {}", path.display()))?;
        registry.push((path.clone(), dest.to_path_buf()));
        Ok(PartialDir {
            path,
            dest: dest.to_path_buf(),
            done: false,
        })
    }

    /// The partial directory, where the output's files are written.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Renames the complete partial directory to the destination.
    pub fn persist(mut self) -> Result<()> {
        // Locked for the rename: an interrupt sees the partial directory or the output.
        let mut registry = registry();
        std::fs::rename(&self.path, &self.dest).with_context(|| {
            format!(
                "cannot rename {} to {}",
                self.path.display(),
                self.dest.display()
            )
        })?;
        registry.retain(|(p, _)| p != &self.path);
        self.done = true;
        Ok(())
    }
}

impl Drop for PartialDir {
    fn drop(&mut self) {
        if !self.done {
            let mut registry = registry();
            let _ = std::fs::remove_dir_all(&self.path);
            registry.retain(|(p, _)| p != &self.path);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The output appears only on persist; dropped, the partial directory goes with its files.
    #[test]
    fn persisted_it_becomes_the_output_dropped_it_goes() {
        let d = tempfile::tempdir().unwrap();
        let out = d.path().join("bag");
        let p = PartialDir::create(&out).unwrap();
        assert_eq!(p.path(), d.path().join(".bag.probmot-partial"));
        std::fs::write(p.path().join("a.mcap"), b"x").unwrap();
        drop(p);
        assert_eq!(std::fs::read_dir(d.path()).unwrap().count(), 0);
        let p = PartialDir::create(&out).unwrap();
        std::fs::write(p.path().join("a.mcap"), b"x").unwrap();
        p.persist().unwrap();
        assert_eq!(std::fs::read(out.join("a.mcap")).unwrap(), b"x");
        assert!(!registry().iter().any(|(_, dest)| dest == &out));
    }
}
