//! Autoware drives written by an independent writer (PyPI `rosbags`, through
//! scripts/make_autoware_bag.py), shared by the Autoware and split-bag tests.

use std::path::{Path, PathBuf};
use std::process::Command;

use super::{python_has, repo, skip};

/// Whether the rosbags tools can run; reports a skip when not.
pub fn have_rosbags(test: &str) -> bool {
    if python_has("rosbags, numpy") {
        return true;
    }
    skip(
        test,
        "python3 cannot import rosbags (pip install -r scripts/requirements.txt)",
    );
    false
}

/// Writes the rosbags bag directory `dir/name` (`flags` to make_autoware_bag.py) and its truth
/// into `dir/name.jsonl`; returns the bag directory.
pub fn make_autoware_bag(dir: &Path, name: &str, flags: &[&str]) -> PathBuf {
    let bag = dir.join(name);
    let out = Command::new("python3")
        .arg(repo("scripts/make_autoware_bag.py"))
        .arg(&bag)
        .args(flags)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "make_autoware_bag.py: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    std::fs::write(dir.join(format!("{name}.jsonl")), &out.stdout).unwrap();
    bag
}
