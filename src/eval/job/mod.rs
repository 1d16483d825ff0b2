//! One evaluation job (`probmot eval`) as a library call: [`evaluate`] loads the logs (and the
//! baseline's), runs the chosen protocol's metrics and HOTA, the bootstrap and the regression
//! gate, writes the events when asked, and assembles the report.

pub mod common;
pub mod events;
pub mod kitti;
pub mod logs;
pub mod nuscenes;
pub mod options;

use anyhow::{bail, Result};

pub use options::{EvalOptions, EvalReport, Gate, Protocol};

use crate::eval::range::RangeFilter;
use crate::pipeline::progress::ProgressFn;

/// Runs the evaluation `o` describes; `progress` hears of the bytes read and of the scoring.
/// `Err`: options that contradict each other (the message names the options as `probmot eval`
/// spells them), unreadable logs, nothing to evaluate.
pub fn evaluate(o: &EvalOptions, progress: ProgressFn) -> Result<EvalReport> {
    let mut o = o.clone();
    let nuscenes_filters = o.max_range.is_some() || o.min_points.is_some() || o.bike_racks;
    if o.devkit {
        o.max_range.get_or_insert_with(RangeFilter::nuscenes);
        o.min_points.get_or_insert(1);
        o.bike_racks = true;
    }
    if o.max_drop.is_some() && o.baseline.is_empty() {
        bail!("--max-drop needs --baseline");
    }
    if let Some(b) = o.block.filter(|b| !(*b > 0.0 && b.is_finite())) {
        bail!("--block must be a positive number of seconds, got {b}");
    }
    if let Some(d) = o.max_drop.filter(|d| !(*d >= 0.0 && d.is_finite())) {
        bail!("--max-drop must be a number of points >= 0, got {d}");
    }
    match o.protocol {
        Protocol::Nuscenes => {
            if o.iou.is_some() {
                bail!("--iou is a KITTI option (the nuScenes protocol matches by 2 m centre distance)");
            }
            if o.means.is_some() {
                bail!("--means is a KITTI option (the nuScenes devkit averages each track's score once)");
            }
            nuscenes::run(&o, progress)
        }
        Protocol::Kitti => {
            if o.devkit || nuscenes_filters {
                bail!(
                    "--devkit, --max-range, --min-points and --bike-racks are nuScenes options \
                     (the KITTI protocol has no range, points or bicycle-rack filter)"
                );
            }
            kitti::run(&o, progress)
        }
    }
}
