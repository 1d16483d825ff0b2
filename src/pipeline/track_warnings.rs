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

    /// The median interval (robust to a pause or a dropped frame; the lower middle of an even
    /// count); `None` under two intervals.
    fn median(&mut self) -> Option<f64> {
        if self.gaps.len() < 2 {
            return None;
        }
        self.gaps.sort_by(f64::total_cmp);
        Some(self.gaps[(self.gaps.len() - 1) / 2])
    }
}

/// A warning when the log's frame period is more than twice or less than half the config's
/// `dt_nominal` while the config carries a preset's noise (its name and every class's Q, R and
/// P0): that noise was set for its dataset's rate (nuScenes' 2 Hz for the default), and a 10 Hz
/// log tracked with the 2 Hz preset gets far more false tracks. A config with other noise (fitted
/// by `probmot fit` or `tune`, or edited) is taken as meant: fit converts its noise to its own
/// `dt_nominal`, from the period of the logs it was fitted on.
pub(super) fn period_mismatch(
    file: &str,
    config: &TrackerConfig,
    intervals: &mut FrameIntervals,
) -> Option<String> {
    let preset = Preset::from_name(&config.name)?;
    let own = preset.config().ok()?;
    if !same_noise(config, &own) {
        return None;
    }
    let (period, dt) = (intervals.median()?, config.dt_nominal);
    if period <= 0.0 || (0.5..=2.0).contains(&(period / dt)) {
        return None;
    }
    let set_for = if dt == own.dt_nominal {
        format!(
            "the preset {}'s noise is set for frames {dt} s apart",
            preset.name()
        )
    } else {
        format!(
            "the config's dt_nominal is {dt} s (the preset {}'s noise, set for frames {} s apart)",
            preset.name(),
            own.dt_nominal
        )
    };
    Some(format!(
        "{file}: frames are {period} s apart (median), and {set_for}: fit the noise on \
         labelled logs of this rate (`probmot fit` or `probmot tune`), or at least try \
         --dt-nominal {period}",
        period = three_digits(period)
    ))
}

/// A warning when tracks were ended because their state or a variance left the bounds of
/// [`crate::tracker::bounds`] (a long coast, a huge gap between frames).
pub(super) fn beyond_bounds(file: &str, stats: &crate::tracker::TrackerStats) -> Option<String> {
    (stats.beyond_bounds > 0).then(|| {
        format!(
            "{file}: {} tracks were ended because their position, size, velocity or a variance              left the bounds (coordinates 1e7 m, sizes 1e4 m, speeds 1e5 m/s, variances 1e12)",
            stats.beyond_bounds
        )
    })
}

/// Whether every class (and the default entry) of `a` has the noise of `b`'s.
fn same_noise(a: &TrackerConfig, b: &TrackerConfig) -> bool {
    let noise = |c: &crate::tracker::ClassConfig| (c.q, c.r, c.p0);
    let default = (a.default.as_ref().map(noise)) == (b.default.as_ref().map(noise));
    default
        && a.classes.len() == b.classes.len()
        && (a.classes.iter().zip(&b.classes))
            .all(|((ka, ca), (kb, cb))| ka == kb && noise(ca) == noise(cb))
}

/// `v` rounded to three significant digits, printed without trailing zeros (0.1, 0.00417).
fn three_digits(v: f64) -> f64 {
    let scale = 10f64.powi(2 - v.abs().log10().floor() as i32);
    (v * scale).round() / scale
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
    /// of two, a config with other noise (fitted, or edited under the preset's name), or a
    /// single interval is not. A `--dt-nominal` override is named as the config's.
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
        let w = period_mismatch("a.mcap", &preset, &mut at(ns / 10, 31, 30 * ns)).unwrap();
        assert!(
            w.contains("0.1 s apart") && w.ends_with("--dt-nominal 0.1"),
            "{w}"
        );
        assert!(
            w.contains("preset nuscenes-chiu2019's noise is set for frames 0.5 s"),
            "{w}"
        );
        assert!(period_mismatch("a.mcap", &preset, &mut at(ns / 2, 31, 0)).is_none());
        assert!(period_mismatch("a.mcap", &preset, &mut at(ns / 3, 31, 0)).is_none());
        assert!(period_mismatch("a.mcap", &preset, &mut at(ns / 10, 2, 0)).is_none());
        // Two intervals, one of them a pause: the lower one counts.
        assert!(period_mismatch("a.mcap", &preset, &mut at(ns / 2, 3, 5 * ns)).is_none());
        let mut fitted = preset.clone();
        fitted.name = "fit of 1 log(s) on nuscenes-chiu2019".into();
        assert!(period_mismatch("a.mcap", &fitted, &mut at(ns / 10, 31, 0)).is_none());
        let mut edited = preset.clone();
        edited.classes.get_mut("car").unwrap().q[0] *= 5.0;
        assert!(period_mismatch("a.mcap", &edited, &mut at(ns / 10, 31, 0)).is_none());
        let mut overridden = preset.clone();
        overridden.dt_nominal = 0.3;
        let w = period_mismatch("a.mcap", &overridden, &mut at(ns / 10, 31, 0)).unwrap();
        assert!(w.contains("the config's dt_nominal is 0.3 s"), "{w}");
        // Frames a few milliseconds apart get a suggestion that is not rounded to zero.
        let w = period_mismatch("a.mcap", &preset, &mut at(4_170_000, 31, 0)).unwrap();
        assert!(
            w.contains("0.00417 s apart") && w.ends_with("--dt-nominal 0.00417"),
            "{w}"
        );
    }
}
