//! Turning checked detection frames into tracker input: label lookup and the counted (or, with
//! `--strict`, refused) skips. The geometry checks are done once, when a message is decoded
//! ([`crate::msgs::detection_frame`]).

use std::collections::BTreeMap;

use anyhow::{bail, Result};

use crate::msgs::detection_frame::{DetectionBox, Rejected};
use crate::tracker::{Detection, Tracker};

pub use crate::msgs::detection_frame::SkipReason;

/// Warnings that do not skip a box.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct InputCounters {
    /// Skipped boxes by reason.
    pub skipped: BTreeMap<SkipReason, u64>,
    /// Boxes kept whose score lies outside `[0, 1]` (e.g. raw detector logits).
    pub score_outside_unit: u64,
    /// Detections given to the tracker, per label.
    pub per_label: BTreeMap<String, u64>,
    /// Boxes skipped because the config has no entry for their label, per label: what the
    /// warning names, so that a preset for other classes does not drop them unsaid.
    pub unknown_labels: BTreeMap<String, u64>,
    /// Where the first box skipped for each bad value was (topic, message, box), for the
    /// warning; labels the config lacks are named by [`describe_unknown_labels`] instead.
    #[serde(skip)]
    pub first_skipped: BTreeMap<SkipReason, String>,
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

/// Counts a skipped box, or with `strict` refuses it with an error naming it.
fn skip(
    index: u32,
    label: &str,
    reason: SkipReason,
    counters: &mut InputCounters,
    strict: bool,
    origin: &Origin<'_>,
) -> Result<()> {
    if strict {
        bail!(
            "{}: topic {} message at log_time {}: detection {index} ({}): {} (--strict)",
            origin.file,
            origin.topic,
            origin.log_time,
            if label.is_empty() { "no label" } else { label },
            reason.describe()
        );
    }
    *counters.skipped.entry(reason).or_default() += 1;
    if !matches!(
        reason,
        SkipReason::UnknownLabel | SkipReason::ClassWithoutEntry
    ) {
        (counters.first_skipped.entry(reason)).or_insert_with(|| {
            format!(
                "topic {}, message at log_time {}, detection {index}",
                origin.topic, origin.log_time
            )
        });
    }
    Ok(())
}

/// `; first: <reason> at <where>, ...`: where the first box of each bad value was, or nothing.
pub fn describe_first_skips(counters: &InputCounters) -> String {
    let parts: Vec<String> = (counters.first_skipped.iter())
        .map(|(r, at)| format!("{} at {at}", r.describe()))
        .collect();
    match parts.is_empty() {
        true => String::new(),
        false => format!("; first: {}", parts.join(", ")),
    }
}

/// Counts (or with `strict` refuses) a box that failed the decode-time check.
pub fn reject(
    r: &Rejected,
    counters: &mut InputCounters,
    strict: bool,
    origin: &Origin<'_>,
) -> Result<()> {
    skip(r.index, &r.label, r.reason, counters, strict, origin)
}

/// Looks up the class of a checked box and converts it. `Ok(None)`: its label is unknown, or it
/// is an Autoware class without a config entry of its name (counted); `Err`: refused with
/// `--strict`.
pub fn convert(
    d: &DetectionBox,
    tracker: &mut Tracker,
    counters: &mut InputCounters,
    strict: bool,
    origin: &Origin<'_>,
) -> Result<Option<Detection>> {
    if d.needs_own_entry && !tracker.config().classes.contains_key(&d.label) {
        let reason = SkipReason::ClassWithoutEntry;
        skip(d.index, &d.label, reason, counters, strict, origin)?;
        return Ok(None);
    }
    let Some(class) = tracker.class_id(&d.label) else {
        count_label(&mut counters.unknown_labels, &d.label);
        skip(
            d.index,
            &d.label,
            SkipReason::UnknownLabel,
            counters,
            strict,
            origin,
        )?;
        return Ok(None);
    };
    if !(0.0..=1.0).contains(&d.score) {
        counters.score_outside_unit += 1;
    }
    count_label(&mut counters.per_label, &d.label);
    Ok(Some(Detection {
        bbox: d.bbox,
        class,
        score: d.score,
    }))
}

/// Adds one to `label`'s count; the label is copied only the first time it is seen.
fn count_label(counts: &mut BTreeMap<String, u64>, label: &str) {
    match counts.get_mut(label) {
        Some(n) => *n += 1,
        None => {
            counts.insert(label.to_string(), 1);
        }
    }
}

/// The labels the config has no entry for, with their counts (`bicycle 131, bus 81`), most
/// frequent first: the words of the skip warning.
pub fn describe_unknown_labels(counts: &BTreeMap<String, u64>) -> String {
    let mut v: Vec<(&String, &u64)> = counts.iter().collect();
    v.sort_by(|a, b| b.1.cmp(a.1).then(a.0.cmp(b.0)));
    let named: Vec<String> = v.iter().map(|(l, n)| format!("{l:?} {n}")).collect();
    named.join(", ")
}
