//! A Rerun recording (.rrd) of a file, as `probmot viz` writes it: the options checked, then
//! the recording written by `viz::rrd` (cargo feature `rerun`; without it, an error saying
//! how to get it).

use std::path::Path;

use anyhow::{bail, Result};

pub use super::rrd_options::{RrdSummary, VizOptions};
use crate::mcapio::destination::{destination, Destination};
use crate::mcapio::writer::check_output_path;
use crate::pipeline::progress::{Progress, ProgressFn};
use crate::pipeline::rosbag_dir::resolve_input;

/// The error without the `rerun` feature: how to enable it, or the script to use instead.
pub const NEEDS_FEATURE: &str = "this probmot was built without the `rerun` cargo feature; \
     rebuild with `cargo build --release --features rerun` (or `cargo install --path . \
     --features rerun`), or convert a tracked file with `python3 scripts/to_rerun.py \
     TRACKED.mcap -o OUT.rrd` (needs `python3 -m pip install -r scripts/requirements-view.txt`, \
     the viewer only, about 770 MB)";

/// Checks the output path of a recording before any work.
pub fn check_rrd_output(input: Option<&Path>, out: &Path) -> Result<()> {
    let is_rrd = (out.extension()).is_some_and(|e| e.eq_ignore_ascii_case("rrd"));
    if !is_rrd {
        bail!(
            "output {} must end in .rrd (a Rerun recording)",
            out.display()
        );
    }
    check_output_path(input, out)
}

/// Checks `track --rerun RRD` before any work: a `.rrd` path that is not the input, and not the
/// `-o` output, which must be a regular file since the recording reads it back.
pub fn check_track_rerun(input: Option<&Path>, output: Option<&Path>, rrd: &Path) -> Result<()> {
    check_rrd_output(input, rrd)?;
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

#[cfg(feature = "rerun")]
fn write(file: &Path, output: &Path, o: &VizOptions) -> Result<RrdSummary> {
    super::rrd::mcap_to_rrd(file, output, o)
}

#[cfg(not(feature = "rerun"))]
fn write(_: &Path, _: &Path, _: &VizOptions) -> Result<RrdSummary> {
    bail!("probmot viz: {NEEDS_FEATURE}")
}
