//! Warnings of a `track` run about its configuration against the log: entries no label
//! reaches, and a frame rate far from the config's.

use super::detections::InputCounters;
use crate::tracker::{Preset, TrackerConfig};

/// The intervals between consecutive tracked frames, seconds (8 bytes a frame), for the
/// frame-rate warning.
#[derive(Debug, Default)]
pub(super) struct FrameIntervals {
    last: Option<u64>,
    gaps: Vec<f64>,
}

impl FrameIntervals {
    /// Notes the stamp of the next tracked frame.
    pub(super) fn push(&mut self, stamp: u64) {
        if let Some(last) = self.last {
            self.gaps.push(stamp.saturating_sub(last) as f64 * 1e-9);
        }
        self.last = Some(stamp);
    }

    /// The median interval (robust to a pause or a dropped frame); `None` under two intervals.
    fn median(&self) -> Option<f64> {
        if self.gaps.len() < 2 {
            return None;
        }
        let mut g = self.gaps.clone();
        g.sort_by(f64::total_cmp);
        Some(g[g.len() / 2])
    }
}

/// A warning when a preset's `dt_nominal` is more than twice or less than half the log's frame
/// period: its noise was set for its dataset's rate (nuScenes' 2 Hz for the default), and a
/// 10 Hz log tracked with the 2 Hz preset gets far more false tracks. A config file (e.g.
/// fitted by `probmot fit`, which converts the noise to its `dt_nominal`) is taken as meant.
pub(super) fn period_mismatch(
    file: &str,
    config: &TrackerConfig,
    intervals: &FrameIntervals,
) -> Option<String> {
    let preset = Preset::from_name(&config.name)?;
    let (period, dt) = (intervals.median()?, config.dt_nominal);
    if period <= 0.0 || (0.5..=2.0).contains(&(period / dt)) {
        return None;
    }
    Some(format!(
        "{file}: frames are {period:.3} s apart (median), and the preset {}'s noise is set for \
         frames {dt} s apart (its dt_nominal): fit the noise on labelled logs of this rate \
         (`probmot fit` or `probmot tune`), or at least try --dt-nominal {period:.2}",
        preset.name()
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

    /// A 10 Hz log under the 2 Hz preset is named, even with a pause; a rate within a factor
    /// of two, a config file (fitted), or a single interval is not.
    #[test]
    fn a_frame_rate_far_from_a_presets_is_named() {
        let preset = TrackerConfig::preset("nuscenes-chiu2019").unwrap();
        let at = |period_ns: u64, n: u64, pause_ns: u64| {
            let mut f = FrameIntervals::default();
            for i in 0..n {
                f.push(i * period_ns + if i > n / 2 { pause_ns } else { 0 });
            }
            f
        };
        let ns = 1_000_000_000;
        let w = period_mismatch("a.mcap", &preset, &at(ns / 10, 31, 30 * ns)).unwrap();
        assert!(
            w.contains("0.100 s apart") && w.contains("--dt-nominal 0.10"),
            "{w}"
        );
        assert!(w.contains("nuscenes-chiu2019"), "{w}");
        assert!(period_mismatch("a.mcap", &preset, &at(ns / 2, 31, 0)).is_none());
        assert!(period_mismatch("a.mcap", &preset, &at(ns / 3, 31, 0)).is_none());
        assert!(period_mismatch("a.mcap", &preset, &at(ns / 10, 2, 0)).is_none());
        let mut fitted = preset.clone();
        fitted.name = "fit of 1 log(s) on nuscenes-chiu2019".into();
        assert!(period_mismatch("a.mcap", &fitted, &at(ns / 10, 31, 0)).is_none());
    }
}
