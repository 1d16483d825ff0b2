//! Loading the logs of an evaluation, in parallel: for the nuScenes protocol streamed into
//! columns through the devkit's filters ([`LogFilters`]), for KITTI each box as its evaluation
//! reads it.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use rayon::prelude::*;

use super::common::{reading, LogPairs};
use super::options::EvalOptions;
use crate::eval::columns::{load_columns, ColumnScene};
use crate::eval::filters::{apply_bike_racks, apply_min_points, read_racks, FilterCounts, Rack};
use crate::eval::kitti::KittiBox;
use crate::eval::range::RangeFilter;
use crate::eval::range::{apply_range_filter, read_ego_positions, EgoPositions, RangeRemoved};
use crate::eval::scene::{load_kitti_scene, Scene};
use crate::mcapio::LabelledBox;
use crate::pipeline::log_pairs::log_pairs;
use crate::pipeline::progress::{Progress, ProgressFn};

/// The filters that are on for one log, with the ego poses and racks of its truth file.
pub struct LogFilters<'a> {
    options: &'a EvalOptions,
    truth: &'a Path,
    ego: Option<(&'a RangeFilter, EgoPositions)>,
    racks: Option<BTreeMap<u64, Vec<Rack>>>,
}

impl<'a> LogFilters<'a> {
    /// The filters `o` turns on, for the log whose truth file is `truth` (its ego poses and
    /// racks read when needed).
    pub fn new(o: &'a EvalOptions, truth: &'a Path) -> Result<LogFilters<'a>> {
        let ego = match &o.max_range {
            Some(filter) => Some((filter, read_ego_positions(truth, &o.ego_topic)?)),
            None => None,
        };
        let racks = if o.bike_racks {
            Some(read_racks(truth, &o.racks_topic).with_context(|| {
                format!(
                    "--bike-racks needs the bicycle racks of each scene on {} (`probmot import \
                     nuscenes` writes them from sample_annotation.json)",
                    o.racks_topic
                )
            })?)
        } else {
            None
        };
        Ok(LogFilters {
            options: o,
            truth,
            ego,
            racks,
        })
    }

    /// Applies the filters to `scene`, in the devkit's order (range, points, racks).
    pub fn apply(&self, scene: &mut Scene) -> Result<FilterCounts> {
        let mut counts = FilterCounts::default();
        if let Some((filter, ego)) = &self.ego {
            counts.range = Some(apply_range_filter(scene, filter, ego).with_context(|| {
                format!("--max-range with the ego poses of {}", self.truth.display())
            })?);
        }
        if let Some(min) = self.options.min_points {
            counts.points = Some(apply_min_points(scene, min).with_context(|| {
                format!(
                    "--min-points: {} (topic {})",
                    self.truth.display(),
                    self.options.truth_topic
                )
            })?);
        }
        if let Some(racks) = &self.racks {
            counts.bike_racks = Some(apply_bike_racks(scene, racks));
        }
        Ok(counts)
    }

    /// [`LogFilters::apply`] to the boxes of one message (truth or tracks) of `scene_name` at
    /// `stamp`: every filter is a rule per frame, so filtering message by message while the log
    /// streams removes the same boxes.
    pub fn apply_message(
        &self,
        scene_name: &str,
        (stamp, boxes, truth): (u64, &mut Vec<LabelledBox>, bool),
        counts: &mut FilterCounts,
    ) -> Result<()> {
        let o = self.options;
        if self.ego.is_none() && o.min_points.is_none() && self.racks.is_none() {
            return Ok(());
        }
        let mut one = Scene {
            name: scene_name.to_string(),
            frames: vec![(stamp, Vec::new(), Vec::new())],
        };
        let (_, f, t) = &mut one.frames[0];
        std::mem::swap(boxes, if truth { f } else { t });
        let c = self.apply(&mut one);
        let (_, f, t) = &mut one.frames[0];
        std::mem::swap(boxes, if truth { f } else { t });
        counts.add(&c?);
        Ok(())
    }
}

/// Loads every log for the nuScenes protocol, streamed into columns ([`load_columns`]) and
/// filtered message by message; with `geometry` the columns keep the boxes' geometry too.
/// Returns the scenes and the filters' counts summed over them.
pub fn load_columns_logs(
    o: &EvalOptions,
    pairs: &[(PathBuf, PathBuf)],
    geometry: bool,
    progress: ProgressFn,
) -> Result<(Vec<ColumnScene>, FilterCounts)> {
    reading(progress, pairs);
    let loaded: Vec<(ColumnScene, FilterCounts)> = pairs
        .par_iter()
        .map(|(truth, tracks)| {
            let filters = LogFilters::new(o, truth)?;
            let name = tracks
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default();
            let mut counts = FilterCounts::default();
            let scene = load_columns(
                (truth, &o.truth_topic),
                (tracks, &o.tracks_topic),
                &|n| progress(Progress::Advance(n)),
                &mut |stamp, boxes, is_truth| {
                    filters.apply_message(&name, (stamp, boxes, is_truth), &mut counts)
                },
                geometry,
            )?;
            Ok((scene, counts))
        })
        .collect::<Result<_>>()?;
    let mut total = FilterCounts::default();
    let scenes = (loaded.into_iter())
        .map(|(s, c)| {
            total.add(&c);
            s
        })
        .collect();
    Ok((scenes, total))
}

/// Loads every log for the KITTI protocol, each box as the KITTI evaluation reads it
/// ([`load_kitti_scene`]): ground-truth boxes without id (DontCare) are allowed. The protocol
/// has no filters.
pub fn load_kitti_logs(
    o: &EvalOptions,
    pairs: &[(PathBuf, PathBuf)],
    progress: ProgressFn,
) -> Result<Vec<Scene<KittiBox>>> {
    reading(progress, pairs);
    pairs
        .par_iter()
        .map(|(truth, tracks)| {
            let (truth, tracks) = ((&**truth, &*o.truth_topic), (&**tracks, &*o.tracks_topic));
            load_kitti_scene(truth, tracks, &|n| progress(Progress::Advance(n)))
        })
        .collect()
}

/// The `baseline` logs of the KITTI protocol, paired with the truth like the tracks, loaded as
/// [`load_kitti_logs`] does; no pairs and `None` without a baseline.
pub fn load_kitti_baseline(
    o: &EvalOptions,
    progress: ProgressFn,
) -> Result<(LogPairs, Option<Vec<Scene<KittiBox>>>)> {
    if o.baseline.is_empty() {
        return Ok((Vec::new(), None));
    }
    let pairs = log_pairs(&o.truth, &o.baseline)?;
    let scenes = load_kitti_logs(o, &pairs, progress)?;
    Ok((pairs, Some(scenes)))
}

/// The filters that ran, in the devkit's order, with what each removed (JSON).
pub fn filters_json(o: &EvalOptions, c: &FilterCounts) -> serde_json::Value {
    let counts = |r: &RangeRemoved| serde_json::json!({"removed_truth_boxes": r.truth, "removed_track_boxes": r.tracks});
    serde_json::json!({
        "devkit": o.devkit,
        "range": c.range.as_ref().map(counts),
        "min_points": c.points.as_ref().map(|r| serde_json::json!({
            "min": o.min_points, "removed_truth_boxes": r.truth, "removed_track_boxes": r.tracks})),
        "bike_racks": c.bike_racks.as_ref().map(|r| serde_json::json!({
            "topic": o.racks_topic, "removed_truth_boxes": r.truth,
            "removed_track_boxes": r.tracks})),
    })
}

/// One line per filter that ran, in the devkit's order.
pub fn filter_notes(c: &FilterCounts, min_points: Option<u64>) -> Vec<String> {
    let mut out = Vec::new();
    if let Some(r) = c.range {
        out.push(format!(
            "range filter removed {} ground-truth and {} track boxes",
            r.truth, r.tracks
        ));
    }
    if let (Some(r), Some(n)) = (c.points, min_points) {
        out.push(format!(
            "points filter (fewer than {n} lidar + radar points) removed {} ground-truth boxes",
            r.truth
        ));
    }
    if let Some(r) = c.bike_racks {
        out.push(format!(
            "bicycle-rack filter removed {} ground-truth and {} track boxes",
            r.truth, r.tracks
        ));
    }
    out
}
