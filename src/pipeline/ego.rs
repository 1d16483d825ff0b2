//! Ego motion in `probmot track`: detections given in a moving frame (e.g. `base_link`) are
//! moved into the fixed frame with the transforms of the log, at each detection stamp, before
//! they reach the tracker; the tracker's state and the tracks channel are in the fixed frame.
//!
//! The fixed frame is `--fixed-frame`, else the root of the transform tree holding the first
//! detection frame (e.g. `map` for `map -> odom -> base_link`). Without any transform channel
//! and without `--fixed-frame`, detections are tracked in the frame they are given in, as
//! before. A detection message with an empty `frame_id` is taken to be in the fixed frame.
//!
//! A message whose transform is missing at its stamp (frame not in the tree, not connected to
//! the fixed frame, or the stamp outside the transforms' time range beyond the tolerance) has
//! its boxes skipped and is counted; with `--strict` it is an error. A `--fixed-frame` that no
//! transform of the log names is always an error (a typo would otherwise skip every message):
//! the tree is complete before tracking starts, so no later message could be moved into it.

use std::collections::BTreeMap;

use anyhow::{bail, Result};
use nalgebra::Isometry3;

use crate::msgs::detection_frame::DetectionFrame;
use crate::transforms::boxes::transform_detections;
use crate::transforms::buffer::DEFAULT_TOLERANCE_NS;
use crate::transforms::TransformCollector;

/// Settings of ego-motion compensation.
#[derive(Debug, Clone)]
pub struct EgoOptions {
    /// Frame to track in; `None`: the root of the transform tree.
    pub fixed_frame: Option<String>,
    /// Lookups hold the nearest transform up to this far outside the transforms' time range.
    pub tolerance_ns: u64,
    /// Also write the tracks in the detection (ego) frame, on `<tracks-topic>/ego`.
    pub tracks_in_ego_frame: bool,
}

impl Default for EgoOptions {
    fn default() -> Self {
        EgoOptions {
            fixed_frame: None,
            tolerance_ns: DEFAULT_TOLERANCE_NS,
            tracks_in_ego_frame: false,
        }
    }
}

/// What ego-motion compensation did, for the run summary.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct EgoSummary {
    /// The frame tracks are in (`None`: detections were tracked as given).
    pub fixed_frame: Option<String>,
    /// Transforms read from the log.
    pub transforms: u64,
    /// Detection messages moved into the fixed frame.
    pub messages_transformed: u64,
    /// Detection messages skipped for a missing transform.
    pub messages_without_transform: u64,
    /// Boxes in those messages.
    pub boxes_without_transform: u64,
    /// Transform messages that failed to decode.
    pub undecodable_transform_messages: u64,
    /// Transforms dropped (invalid numbers or frame names, or a second parent of a frame).
    pub invalid_transforms: u64,
}

/// Moves detection messages into the fixed frame; remembers, per pending stamp, the detection
/// frame and its transform for the `--tracks-frame ego` output.
pub struct EgoMotion {
    collector: TransformCollector,
    fixed: Option<String>,
    strict: bool,
    /// Per stamp not yet tracked: the first message's frame and its frame-to-fixed transform.
    ego_of_stamp: BTreeMap<u64, (String, Isometry3<f64>)>,
    first_failure: Option<String>,
    /// Whether the fixed frame is `--fixed-frame`'s (not the tree's root).
    fixed_given: bool,
    summary: EgoSummary,
}

impl EgoMotion {
    /// Starts from the transforms collected in the first pass. Undecodable transform messages
    /// are an error with `strict`.
    pub fn new(mut collector: TransformCollector, opts: &EgoOptions, strict: bool) -> Result<Self> {
        collector.finish();
        collector.buffer.tolerance_ns = opts.tolerance_ns;
        if strict {
            if let Some(e) = &collector.first_error {
                bail!("{e} (--strict)");
            }
        }
        let summary = EgoSummary {
            fixed_frame: opts.fixed_frame.clone(),
            transforms: collector.per_topic.values().map(|c| c.transforms).sum(),
            undecodable_transform_messages: collector.undecodable(),
            invalid_transforms: collector.invalid() + collector.buffer.conflicting_parent,
            ..Default::default()
        };
        Ok(EgoMotion {
            fixed: opts.fixed_frame.clone(),
            collector,
            strict,
            ego_of_stamp: BTreeMap::new(),
            first_failure: None,
            fixed_given: opts.fixed_frame.is_some(),
            summary,
        })
    }

    /// The fixed frame for a message in `source`: set, or chosen now from the tree.
    fn fixed_for(&mut self, source: &str) -> Option<String> {
        if self.fixed.is_none() && !self.collector.buffer.is_empty() {
            // The root of the detection frame's tree; a frame outside the tree is its own.
            let root = self.collector.buffer.root_of(source).unwrap_or(source);
            self.fixed = Some(root.to_string());
            self.summary.fixed_frame = self.fixed.clone();
        }
        self.fixed.clone()
    }

    /// Moves `msg` into the fixed frame at its stamp. On a missing transform its boxes (valid
    /// or not) are dropped and counted, or with `strict` an error naming `where_` is returned.
    pub fn to_fixed(
        &mut self,
        msg: &mut DetectionFrame,
        where_: impl Fn() -> String,
    ) -> Result<()> {
        let stamp = msg.stamp;
        if msg.frame_id.is_empty() {
            return Ok(());
        }
        let Some(fixed) = self.fixed_for(&msg.frame_id) else {
            // Tracked in the detections' own frame: the ego frame is the tracking frame.
            self.ego_of_stamp
                .entry(stamp)
                .or_insert_with(|| (msg.frame_id.clone(), Isometry3::identity()));
            return Ok(());
        };
        match self.collector.buffer.lookup(&fixed, &msg.frame_id, stamp) {
            Ok(iso) => {
                self.ego_of_stamp
                    .entry(stamp)
                    .or_insert_with(|| (msg.frame_id.clone(), iso));
                if msg.frame_id != fixed {
                    transform_detections(msg, &iso, &fixed);
                    self.summary.messages_transformed += 1;
                }
                Ok(())
            }
            Err(e) => {
                self.check_fixed_in_tree(&fixed, &msg.frame_id, &where_)?;
                let text = format!(
                    "{}: no transform from '{}' to the fixed frame '{}': {e}",
                    where_(),
                    msg.frame_id,
                    fixed
                );
                if self.strict {
                    bail!("{text} (--strict)");
                }
                if self.first_failure.is_none() {
                    self.first_failure = Some(text);
                }
                self.summary.messages_without_transform += 1;
                self.summary.boxes_without_transform += msg.len() as u64;
                msg.clear();
                msg.frame_id.clear();
                msg.frame_id.push_str(&fixed);
                Ok(())
            }
        }
    }

    /// An error when the fixed frame came from `--fixed-frame` and no transform names it: no
    /// message in another frame (`source`) could ever be moved into it.
    fn check_fixed_in_tree(
        &self,
        fixed: &str,
        source: &str,
        where_: &impl Fn() -> String,
    ) -> Result<()> {
        let buffer = &self.collector.buffer;
        if !self.fixed_given || buffer.frame_index(fixed).is_some() {
            return Ok(());
        }
        let frames = match buffer.frame_names() {
            [] => "the log has no transforms".to_string(),
            names => format!("its transforms name {}", names.join(", ")),
        };
        bail!(
            "{}: --fixed-frame '{fixed}' is in no transform of the log, so detections in \
             '{source}' cannot be moved into it; {frames}",
            where_()
        )
    }

    /// The detection frame of a tracked stamp and the transform from the fixed frame into it
    /// (for `--tracks-frame ego`); forgets the stamp. `None` when the frame's messages had no
    /// transform or no frame id.
    pub fn take_ego(&mut self, stamp: u64) -> Option<(String, Isometry3<f64>)> {
        let (frame, iso) = self.ego_of_stamp.remove(&stamp)?;
        Some((frame, iso.inverse()))
    }

    /// True when tracks are written in a fixed frame chosen from the transforms or the
    /// command line.
    pub fn is_active(&self) -> bool {
        self.fixed.is_some()
    }

    /// The summary, with warnings for `file` appended to `warnings`.
    pub fn finish(self, file: &str, warnings: &mut Vec<String>) -> EgoSummary {
        let s = self.summary;
        if s.messages_without_transform > 0 {
            warnings.push(format!(
                "{file}: {} detection messages ({} boxes) skipped for a missing transform; \
                 the first: {}",
                s.messages_without_transform,
                s.boxes_without_transform,
                self.first_failure.unwrap_or_default()
            ));
        }
        if let Some(e) = &self.collector.first_error {
            warnings.push(format!(
                "{file}: {} transform messages could not be decoded; the first: {e}",
                s.undecodable_transform_messages
            ));
        }
        if s.invalid_transforms > 0 {
            warnings.push(format!(
                "{file}: {} transforms dropped (empty frame name, negative stamp, non-finite \
                 number, zero quaternion, or a frame given a second parent)",
                s.invalid_transforms
            ));
        }
        s
    }
}
