//! A Rerun recording (.rrd) of a file, as `probmot viz` writes it: the options checked, then
//! the recording written by `viz::rrd` (cargo feature `rerun`; without it, an error saying
//! how to get it).

use std::path::Path;

use anyhow::{bail, Result};

pub use super::rrd_options::{RrdSummary, VizOptions};
use super::{check_named_topics, Layer};
use crate::mcapio::destination::{destination, Destination};
use crate::mcapio::recording::file_topics;
use crate::mcapio::writer::{check_output_path, is_device_or_fifo};
use crate::pipeline::progress::{Progress, ProgressFn};
use crate::pipeline::rosbag_dir::{open_bag, resolve_input};

/// The error without the `rerun` feature: how to enable it, or the script to use instead.
pub const NEEDS_FEATURE: &str = "this probmot was built without the `rerun` cargo feature; \
     rebuild with `cargo build --release --features rerun` (or `cargo install --locked --path \
     . --features rerun`), or convert a tracked file with `python3 scripts/to_rerun.py \
     TRACKED.mcap -o OUT.rrd` (needs `python3 -m pip install -r scripts/requirements-view.txt`, \
     the viewer only, about 770 MB)";

/// Checks the output path of a recording before any work.
pub fn check_rrd_output(input: Option<&Path>, out: &Path) -> Result<()> {
    let is_rrd = (out.extension()).is_some_and(|e| e.eq_ignore_ascii_case("rrd"));
    if !is_rrd && !is_device_or_fifo(out) {
        bail!(
            "output {} must end in .rrd (a Rerun recording)",
            out.display()
        );
    }
    check_output_path(input, out)
}

/// Checks `track --rerun RRD` before any work: a `.rrd` path that is not the input, and not the
/// `-o` output, which must be a regular file since the recording reads it back; and an input
/// that is not a bag split into several files (its output is split too, and a recording is
/// made of one file).
pub fn check_track_rerun(input: Option<&Path>, output: Option<&Path>, rrd: &Path) -> Result<()> {
    check_rrd_output(input, rrd)?;
    if let Some(bag) = input.map(open_bag).transpose()?.flatten() {
        if bag.files.len() > 1 {
            bail!(
                "--rerun: {} is a bag split into {} files, and so is its output, while a                  recording reads one file back: track without --rerun, then record one output                  file with `probmot viz OUT_BAG/FILE.mcap -o OUT.rrd`",
                bag.dir.display(),
                bag.files.len()
            );
        }
    }
    if output == Some(rrd) {
        bail!(
            "--rerun {} is also the -o output; give two paths",
            rrd.display()
        );
    }
    if let Some(out) = output {
        if !matches!(destination(out)?, Destination::File(_)) {
            bail!(
                "--rerun reads the tracked file back, and -o {} is not a file (a device, \
                 pipe or standard output); write to a file",
                out.display()
            );
        }
    }
    Ok(())
}

/// Writes the Rerun recording of `file` (a rosbag directory resolved) to `output`, atomically.
/// Boxes that cannot be drawn are counted in a warning per topic to `warn`; progress: a message
/// while it works, then done.
pub fn rrd_file(
    file: &Path,
    output: &Path,
    o: &VizOptions,
    warn: &dyn Fn(&str),
    progress: ProgressFn<'_>,
) -> Result<RrdSummary> {
    let file = resolve_input(file)?;
    check_rrd_output(Some(&file), output)?;
    if o.trail == 0 {
        bail!("--trail must be at least 1");
    }
    for (name, v) in [("--from", o.from_s), ("--to", o.to_s)] {
        if v.is_some_and(|v| !v.is_finite()) {
            bail!("{name} must be a number of seconds");
        }
    }
    if let (Some(f), Some(t)) = (o.from_s, o.to_s) {
        if f > t {
            bail!("--from {f} is after --to {t}; the window is empty");
        }
    }
    check_viz_topics(&file, o)?;
    progress(Progress::Message(&format!("writing {}", output.display())));
    let s = write(&file, output, o);
    progress(Progress::Done);
    let s = s?;
    for (topic, n) in &s.undrawable {
        warn(&format!(
            "{}: topic {topic}: {n} box(es) with a non-finite centre, size or yaw are not drawn",
            file.display()
        ));
    }
    Ok(s)
}

/// Refuses a layer topic named on purpose that the file lacks, before any recording is made
/// ([`check_named_topics`]); the file's topics are read only when one is named.
fn check_viz_topics(file: &Path, o: &VizOptions) -> Result<()> {
    let named = [
        (Layer::Detections, o.detections_topic.as_str()),
        (Layer::Tracks, o.tracks_topic.as_str()),
        (Layer::GroundTruth, o.truth_topic.as_str()),
    ];
    if named.iter().all(|(l, t)| *t == l.default_topic()) {
        return Ok(());
    }
    check_named_topics(file.display(), named, &file_topics(file)?)
}

#[cfg(feature = "rerun")]
fn write(file: &Path, output: &Path, o: &VizOptions) -> Result<RrdSummary> {
    super::rrd::mcap_to_rrd(file, output, o)
}

#[cfg(not(feature = "rerun"))]
fn write(_: &Path, _: &Path, _: &VizOptions) -> Result<RrdSummary> {
    bail!("probmot viz: {NEEDS_FEATURE}")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A split bag is refused before any work, naming the bag and what to do; a bag of one
    /// file is not.
    #[test]
    fn track_rerun_refuses_a_split_bag_up_front() {
        let d = tempfile::tempdir().unwrap();
        let bag = d.path().join("bag");
        std::fs::create_dir(&bag).unwrap();
        for f in ["bag_0.mcap", "bag_1.mcap"] {
            std::fs::write(bag.join(f), b"").unwrap();
        }
        let yaml = |files: &str| {
            format!("rosbag2_bagfile_information:\n  storage_identifier: mcap\n  relative_file_paths: [{files}]\n")
        };
        std::fs::write(bag.join("metadata.yaml"), yaml("bag_0.mcap, bag_1.mcap")).unwrap();
        let (out, rrd) = (d.path().join("out"), d.path().join("run.rrd"));
        let e = check_track_rerun(Some(&bag), Some(&out), &rrd).unwrap_err();
        let e = format!("{e:#}");
        assert!(
            e.contains("split into 2 files") && e.contains("probmot viz"),
            "{e}"
        );
        std::fs::write(bag.join("metadata.yaml"), yaml("bag_0.mcap")).unwrap();
        check_track_rerun(Some(&bag), Some(&out), &rrd).unwrap();
    }
}
