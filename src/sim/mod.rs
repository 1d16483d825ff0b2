//! Deterministic synthetic drives with ground truth (`probmot simulate`).
//!
//! A scenario scripts the true motion of every object ([`scenario`]); a sensor model turns the
//! truth into noisy detections with misses, false positives and heading flips ([`sensor`]);
//! [`mod@write`] stores both as MCAP channels `/detections` and `/ground_truth`.

pub mod ego;
pub mod scenario;
pub mod sensor;
pub mod write;

use std::path::Path;

use anyhow::Result;

use crate::mcapio::writer::check_output_path;
use crate::pipeline::progress::{Progress, ProgressFn};
pub use scenario::{Scenario, SimOptions};
pub use write::{write_simulation, write_simulation_progress, SimSummary};

/// [`write_simulation`] after checking the options and the output path, as `probmot simulate`
/// runs it. Progress: frames written, out of `opts.frames`.
pub fn simulate_file(
    opts: &SimOptions,
    out: &Path,
    progress: ProgressFn<'_>,
) -> Result<SimSummary> {
    anyhow::ensure!(
        opts.rate_hz.is_finite() && opts.rate_hz > 0.0,
        "--rate must be a positive number of Hz"
    );
    anyhow::ensure!(opts.frames > 0, "--frames must be at least 1");
    check_output_path(None, out)?;
    progress(Progress::Length(u64::from(opts.frames)));
    write_simulation_progress(opts, out, &|n| progress(Progress::Advance(n)))
}

/// The true state of one object in one frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TruthState {
    /// Centre x, y, z in metres (fixed "map" frame).
    pub center: [f64; 3],
    /// Heading, radians.
    pub yaw: f64,
    /// Velocity, m/s.
    pub velocity: [f64; 3],
    /// Yaw rate, rad/s.
    pub yaw_rate: f64,
}

/// One simulated object: identity, class, size and its per-frame state (`None`: not present).
#[derive(Debug, Clone)]
pub struct SimObject {
    /// True instance id.
    pub id: u64,
    /// Class label.
    pub label: &'static str,
    /// Length, width, height.
    pub size: [f64; 3],
    /// State per frame.
    pub states: Vec<Option<TruthState>>,
    /// Frames in which the sensor misses the object on purpose (occlusion scripts).
    pub occluded: Vec<bool>,
}
