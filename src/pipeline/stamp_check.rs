//! Detection stamps that cannot be right: a stamp far outside the log's time range (u64::MAX
//! among 2026 stamps would put every track light-hours away) is skipped with a warning naming
//! the message (an error with `--strict`), and messages of one channel sharing a stamp (merged
//! into one frame) are named in a warning.
//!
//! The range: the median detection stamp, widened by the span of the detection messages'
//! log_times and by [`SLACK_NS`] either side. The single pass cannot know the median, so it
//! goes on only while every stamp lies within [`NEAR_LOG_TIME_NS`] of its message's log_time
//! (which keeps it inside that range); a stamp further off makes the file take two passes.

use std::collections::HashMap;
use std::ops::ControlFlow;

use anyhow::{bail, Result};

use super::frame_schedule::Replan;

/// How far a stamp may be from its message's log_time for the single pass to go on: 24 h.
pub const NEAR_LOG_TIME_NS: u64 = 24 * 3600 * 1_000_000_000;

/// How far beyond the log's range a stamp may lie: 48 h (twice [`NEAR_LOG_TIME_NS`], so that
/// every stamp the single pass accepts is inside).
pub const SLACK_NS: u64 = 2 * NEAR_LOG_TIME_NS;

/// The smallest and largest log_time of the detection messages.
#[derive(Debug, Clone, Copy, Default)]
pub struct LogSpan(Option<(u64, u64)>);

impl LogSpan {
    /// Notes one message's log_time.
    pub fn note(&mut self, log_time: u64) {
        let (lo, hi) = self.0.unwrap_or((log_time, log_time));
        self.0 = Some((lo.min(log_time), hi.max(log_time)));
    }
}

/// The stamps a detection message may carry, `[lo, hi]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StampWindow {
    lo: u64,
    hi: u64,
}

impl StampWindow {
    /// The window of a log whose detection messages have `stamps` and `span` (`None` without
    /// any message).
    pub fn of(stamps: impl Iterator<Item = u64>, span: LogSpan) -> Option<StampWindow> {
        let mut v: Vec<u64> = stamps.collect();
        let (lo, hi) = span.0?;
        let mid = (v.len().checked_sub(1)?) / 2;
        let median = *v.select_nth_unstable(mid).1;
        let wide = (hi - lo).saturating_add(SLACK_NS);
        Some(StampWindow {
            lo: median.saturating_sub(wide),
            hi: median.saturating_add(wide),
        })
    }

    /// Whether `stamp` lies inside.
    pub fn contains(&self, stamp: u64) -> bool {
        (self.lo..=self.hi).contains(&stamp)
    }
}

/// The checks of the tracking pass, and what they found.
#[derive(Debug, Default)]
pub struct StampCheck {
    /// Two passes: the window from the first; the single pass: `None`.
    window: Option<StampWindow>,
    /// Per detection channel, the stamp and log_time of its last message.
    last: HashMap<u16, (u64, u64)>,
    far: u64,
    first_far: Option<String>,
    shared: u64,
    first_shared: Option<String>,
}

impl StampCheck {
    /// The checks of a pass: with `window` from a first pass, else of the single pass.
    pub fn new(window: Option<StampWindow>) -> StampCheck {
        StampCheck {
            window,
            ..Default::default()
        }
    }

    /// Whether the message (`describe` names it) with `stamp` is tracked: `false` skips a
    /// stamp outside the window; `Err`: the same with `strict`; [`Replan::StampFarFromLogTime`]:
    /// the single pass meeting a stamp far from its log_time.
    pub fn keep(
        &mut self,
        channel: u16,
        stamp: u64,
        log_time: u64,
        strict: bool,
        describe: impl Fn() -> String,
    ) -> Result<ControlFlow<Replan, bool>> {
        let Some(w) = self.window else {
            if stamp.abs_diff(log_time) > NEAR_LOG_TIME_NS {
                return Ok(ControlFlow::Break(Replan::StampFarFromLogTime));
            }
            self.note_shared(channel, stamp, log_time, &describe);
            return Ok(ControlFlow::Continue(true));
        };
        if !w.contains(stamp) {
            if strict {
                bail!(
                    "{}: stamp {stamp} lies far outside the log's time range (stamps \
                     {}..{} ns) (--strict)",
                    describe(),
                    w.lo,
                    w.hi
                );
            }
            self.far += 1;
            self.first_far
                .get_or_insert_with(|| format!("{} (stamp {stamp})", describe()));
            return Ok(ControlFlow::Continue(false));
        }
        self.note_shared(channel, stamp, log_time, &describe);
        Ok(ControlFlow::Continue(true))
    }

    /// Counts a message whose stamp equals the previous one of its channel.
    fn note_shared(
        &mut self,
        channel: u16,
        stamp: u64,
        log_time: u64,
        describe: &dyn Fn() -> String,
    ) {
        if let Some((prev, prev_log)) = self.last.insert(channel, (stamp, log_time)) {
            if prev == stamp {
                self.shared += 1;
                self.first_shared.get_or_insert_with(|| {
                    format!(
                        "{} and the one before it (log_time {prev_log}) share stamp {stamp}",
                        describe()
                    )
                });
            }
        }
    }

    /// The warnings of what was found, naming the first message of each kind.
    pub fn warnings(&self, file: &str, out: &mut Vec<String>) {
        // The messages are described with their file, which the warning names first.
        let prefix = format!("{file}: ");
        let short = |m: &String| m.strip_prefix(&prefix).unwrap_or(m).to_string();
        if let Some(first) = self.first_far.as_ref().map(short) {
            out.push(format!(
                "{file}: skipped {} detection messages whose stamp lies far (over 48 h) outside \
                 the log's time range; first: {first}",
                self.far
            ));
        }
        if let Some(first) = self.first_shared.as_ref().map(short) {
            out.push(format!(
                "{file}: {} detection messages have the same stamp as the message before them \
                 on their topic; their boxes were tracked as one frame; first: {first}",
                self.shared
            ));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const HOUR: u64 = 3600 * 1_000_000_000;

    fn span(lo: u64, hi: u64) -> LogSpan {
        let mut s = LogSpan::default();
        s.note(hi);
        s.note(lo);
        s
    }

    #[test]
    fn the_window_is_the_median_widened_by_the_span_and_the_slack() {
        let t0 = 1_780_000_000 * 1_000_000_000u64;
        let stamps = [t0, t0 + HOUR, u64::MAX, t0 + 2 * HOUR, 0];
        let w = StampWindow::of(stamps.into_iter(), span(t0, t0 + 2 * HOUR)).unwrap();
        assert!(w.contains(t0) && w.contains(t0 + 2 * HOUR));
        assert!(w.contains(t0 + HOUR + 50 * HOUR) && !w.contains(t0 + HOUR + 51 * HOUR));
        assert!(!w.contains(u64::MAX) && !w.contains(0));
        assert!(StampWindow::of([].into_iter(), LogSpan::default()).is_none());
    }

    #[test]
    fn far_stamps_are_skipped_or_refused_and_shared_stamps_named() {
        let t0 = 1_780_000_000 * 1_000_000_000u64;
        let w = StampWindow::of([t0].into_iter(), span(t0, t0));
        let mut c = StampCheck::new(w);
        let name = || "a.mcap: topic /d, message at log_time 5".to_string();
        let first = "first: topic /d, message at log_time 5";
        let (kept, skipped) = (ControlFlow::Continue(true), ControlFlow::Continue(false));
        assert_eq!(c.keep(1, t0, t0, false, name).unwrap(), kept);
        assert_eq!(c.keep(1, u64::MAX, t0, false, name).unwrap(), skipped);
        assert_eq!(c.keep(1, t0, t0, false, name).unwrap(), kept);
        assert_eq!(
            c.keep(2, t0, t0, false, name).unwrap(),
            kept,
            "another channel"
        );
        let err = c.keep(1, u64::MAX, t0, true, name).unwrap_err().to_string();
        assert!(
            err.contains("log_time 5") && err.contains("--strict"),
            "{err}"
        );
        let mut w = Vec::new();
        c.warnings("a.mcap", &mut w);
        assert_eq!(w.len(), 2, "{w:?}");
        assert!(
            w[0].contains("skipped 1 detection messages")
                && w[0].contains("stamp 18446744073709551615")
        );
        assert!(
            w[1].contains("1 detection messages have the same stamp"),
            "{w:?}"
        );
        assert!(
            w.iter()
                .all(|w| w.starts_with("a.mcap: ") && w.contains(first)),
            "{w:?}"
        );
        // The single pass: a stamp a day off its log_time needs two passes.
        let mut single = StampCheck::new(None);
        assert_eq!(single.keep(1, t0, t0 + HOUR, false, name).unwrap(), kept);
        let far = single.keep(1, t0 + 30 * HOUR, t0, false, name).unwrap();
        assert_eq!(far, ControlFlow::Break(Replan::StampFarFromLogTime));
    }
}
