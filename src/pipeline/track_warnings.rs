//! Warnings of a `track` run about its configuration against the log: entries no label
//! reaches, and a frame rate far from the config's.

use super::detections::InputCounters;
use crate::tracker::TrackerConfig;

/// A warning when the frames come at another rate than the config's `dt_nominal` (by more than
/// a factor of two): its noise was set for that period (the presets for nuScenes' 2 Hz or
/// KITTI's 10 Hz), and a 10 Hz log tracked with the 2 Hz preset gets far more false tracks.
pub(super) fn period_mismatch(
    file: &str,
    dt_nominal: f64,
    span: Option<(u64, u64)>,
    frames: usize,
) -> Option<String> {
    let (first, last) = span?;
    let gaps = frames.checked_sub(1).filter(|&n| n > 0)?;
    let period = (last.saturating_sub(first)) as f64 * 1e-9 / gaps as f64;
    if period <= 0.0 || (0.5..=2.0).contains(&(period / dt_nominal)) {
        return None;
    }
    Some(format!(
        "{file}: frames are {period:.3} s apart on average, the config's dt_nominal is \
         {dt_nominal} s: its noise was set for frames that far apart: fit the noise on labelled \
         logs of this rate (`probmot fit` or `probmot tune`), or at least try --dt-nominal \
         {period:.2}"
    ))
}

/// A warning when a config entry saw no detection while a label close to its name (`car` for
/// an entry `cars`: the same but for case or an edit or two) fell to the default entry: the
/// entry's settings would otherwise go unused without a word. Entries for classes a log simply
/// lacks, beside other labels (a nuScenes scene without buses), are not named.
pub(super) fn unused_entries(
    file: &str,
    config: &TrackerConfig,
    counters: &InputCounters,
) -> Option<String> {
    let near = |entry: &str, label: &str| {
        let (e, l) = (entry.to_lowercase(), label.to_lowercase());
        let allowed = (e.chars().count().min(l.chars().count()) / 4).max(1);
        e == l || strsim::levenshtein(&e, &l) <= allowed
    };
    let pairs: Vec<String> = (config.classes.keys())
        .filter(|c| !counters.per_label.contains_key(*c))
        .flat_map(|entry| {
            (counters.per_label.keys())
                .filter(|l| !config.classes.contains_key(*l) && near(entry, l))
                .map(move |l| format!("entry {entry:?}, label {l:?}"))
        })
        .collect();
    if pairs.is_empty() {
        return None;
    }
    Some(format!(
        "{file}: config entries that no detection's label matches, beside a near label that \
         went to the default entry ({}): labels are compared exactly",
        pairs.join("; ")
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 10 Hz log under a 2 Hz config is named; a rate within a factor of two, or a single
    /// frame, is not.
    #[test]
    fn a_frame_rate_far_from_dt_nominal_is_named() {
        let ns = 1_000_000_000u64;
        let w = period_mismatch("a.mcap", 0.5, Some((0, 30 * ns / 10)), 31).unwrap();
        assert!(
            w.contains("0.100 s apart") && w.contains("--dt-nominal 0.10"),
            "{w}"
        );
        assert!(period_mismatch("a.mcap", 0.5, Some((0, 30 * ns / 2)), 31).is_none());
        assert!(period_mismatch("a.mcap", 0.5, Some((0, 30 * ns / 3)), 31).is_none());
        assert!(period_mismatch("a.mcap", 0.1, Some((0, 30 * ns / 2)), 31).is_some());
        assert!(period_mismatch("a.mcap", 0.5, Some((5, 5)), 1).is_none());
        assert!(period_mismatch("a.mcap", 0.5, None, 0).is_none());
    }
}
