//! Turning decoded detection messages into tracker input: validation, label lookup and the
//! counted skips.

use std::collections::BTreeMap;

use anyhow::{bail, Result};

use crate::msgs::Detection3D;
use crate::tracker::{Box3, Detection, Tracker};

/// Why a detection box was skipped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SkipReason {
    /// A centre, size, yaw or score field is NaN or infinite.
    NonFinite,
    /// A size is zero or negative.
    NonPositiveSize,
    /// The label is not in the config and the config has no default entry.
    UnknownLabel,
    /// The centre or size field is missing.
    MissingField,
}

impl SkipReason {
    /// Short description.
    pub fn describe(self) -> &'static str {
        match self {
            SkipReason::NonFinite => "non-finite field",
            SkipReason::NonPositiveSize => "non-positive size",
            SkipReason::UnknownLabel => "label not in the config (no default entry)",
            SkipReason::MissingField => "missing centre or size",
        }
    }
}

/// Warnings that do not skip a box.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct InputCounters {
    /// Skipped boxes by reason.
    pub skipped: BTreeMap<SkipReason, u64>,
    /// Boxes kept whose score lies outside `[0, 1]` (e.g. raw detector logits).
    pub score_outside_unit: u64,
    /// Detections given to the tracker, per label.
    pub per_label: BTreeMap<String, u64>,
}

impl InputCounters {
    /// Total skipped boxes.
    pub fn total_skipped(&self) -> u64 {
        self.skipped.values().sum()
    }
}

/// Where a detection came from, for error messages.
pub struct Origin<'a> {
    /// Input file.
    pub file: &'a str,
    /// Topic.
    pub topic: &'a str,
    /// MCAP log_time of the message.
    pub log_time: u64,
}

/// Checks one detection and converts it. `Ok(None)`: skipped (counted); `Err`: refused with
/// `--strict`.
pub fn convert(
    d: &Detection3D,
    index: usize,
    tracker: &mut Tracker,
    counters: &mut InputCounters,
    strict: bool,
    origin: &Origin<'_>,
) -> Result<Option<Detection>> {
    let skip = |reason: SkipReason, counters: &mut InputCounters| -> Result<Option<Detection>> {
        if strict {
            bail!(
                "{}: topic {} message at log_time {}: detection {index} ({}): {} (--strict)",
                origin.file,
                origin.topic,
                origin.log_time,
                if d.label.is_empty() {
                    "no label"
                } else {
                    &d.label
                },
                reason.describe()
            );
        }
        *counters.skipped.entry(reason).or_default() += 1;
        Ok(None)
    };
    let (Some(c), Some(s)) = (&d.center, &d.size) else {
        return skip(SkipReason::MissingField, counters);
    };
    let bbox = Box3 {
        center: [c.x, c.y, c.z],
        yaw: d.yaw,
        size: [s.length, s.width, s.height],
    };
    let finite = bbox.center.iter().chain(&bbox.size).all(|v| v.is_finite())
        && bbox.yaw.is_finite()
        && d.score.is_finite();
    if !finite {
        return skip(SkipReason::NonFinite, counters);
    }
    if bbox.size.iter().any(|v| *v <= 0.0) {
        return skip(SkipReason::NonPositiveSize, counters);
    }
    let Some(class) = tracker.class_id(&d.label) else {
        return skip(SkipReason::UnknownLabel, counters);
    };
    if !(0.0..=1.0).contains(&d.score) {
        counters.score_outside_unit += 1;
    }
    match counters.per_label.get_mut(d.label.as_str()) {
        Some(n) => *n += 1,
        None => {
            counters.per_label.insert(d.label.clone(), 1);
        }
    }
    Ok(Some(Detection {
        bbox,
        class,
        score: d.score,
    }))
}
