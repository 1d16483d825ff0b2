//! Offline reporting: frames whose reports later frames decide.
//!
//! With [`super::levers::Levers::backfill`] a track's frames before it reaches `min_hits` are
//! shown once it does; with [`super::levers::Coast::Gaps`] a coasted frame is shown once the
//! track is matched again. The tracker marks such reports [`ReportStatus::Tentative`] or
//! [`ReportStatus::Coasting`]; a [`Lookback`] holds the frames they are in until every report is
//! decided, then hands the frames out in order with the shown reports only. Without those
//! options every report is [`ReportStatus::Final`] and a frame is ready as soon as it is pushed,
//! so the lookback adds no delay.
//!
//! An undecided report is shown when its track's next [`ReportStatus::Final`] report comes
//! (a match of a confirmed track), and dropped when a frame passes without a report of its
//! track (the track was deleted, or is past `max_age`) or at [`Lookback::finish`]. A
//! [`ReportStatus::Hidden`] report is never shown but keeps its track's held reports waiting. The delay is
//! bounded: a track is reported only within `max_age` frames of a match, and a tentative track
//! is confirmed after at most `min_hits - 1` more matches.
//!
//! Sans-I/O like the tracker: reports in, frames out. Each held report carries a value `T`
//! (what the caller writes for it), filled in place: held frames and their values are reused,
//! so nothing is allocated per report in steady state.
//!
//! ```
//! use probmot::tracker::{Box3, Detection, Lookback, Tracker, TrackerConfig};
//!
//! let mut cfg = TrackerConfig::preset("ab3dmot-kitti").unwrap();
//! for c in cfg.classes.values_mut() {
//!     c.levers.backfill = true;
//! }
//! let mut tracker = Tracker::new(cfg).unwrap();
//! let car = tracker.class_id("car").unwrap();
//! let mut lookback: Lookback<u64> = Lookback::default();
//! let (mut shown, mut ids) = (Vec::new(), Vec::new());
//! for frame in 0..8u64 {
//!     // One car, seen from frame 4 on (after the first min_hits frames).
//!     let mut dets = Vec::new();
//!     if frame >= 4 {
//!         let bbox = Box3 { center: [0.5 * frame as f64, 5.0, 0.0], yaw: 0.0, size: [4.0, 1.8, 1.5] };
//!         dets.push(Detection { bbox, class: car, score: 0.9 });
//!     }
//!     tracker.step(frame * 100_000_000 + 1, &dets).unwrap();
//!     lookback.push(frame, tracker.reports(), |id, r| *id = r.id);
//!     while let Some(stamp) = lookback.pop_into(&mut ids) {
//!         shown.push((stamp, ids.len()));
//!     }
//! }
//! lookback.finish();
//! // The car is shown from its first detection (frame 4), not from its third (frame 6).
//! assert_eq!(shown[4..], [(4, 1), (5, 1), (6, 1), (7, 1)]);
//! ```

use std::collections::{HashMap, VecDeque};

use super::track::{ReportStatus, TrackReport};

/// What is known of one held report.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
enum Decision {
    Shown,
    Undecided,
    #[default]
    Dropped,
}

/// One held report: its track, its decision and the caller's value.
#[derive(Debug, Default)]
struct Item<T> {
    id: u64,
    decision: Decision,
    value: T,
}

/// One held frame. `items[..used]` are this frame's; the rest are kept for reuse.
#[derive(Debug, Default)]
struct Held<T> {
    stamp: u64,
    items: Vec<Item<T>>,
    used: usize,
    undecided: usize,
}

/// A track with undecided reports: the index of the first frame holding one, and of the last
/// frame that reported the track.
#[derive(Debug, Clone, Copy)]
struct Open {
    first: u64,
    seen: u64,
}

/// Holds frames until their reports are decided; see the module docs.
#[derive(Debug)]
pub struct Lookback<T> {
    frames: VecDeque<Held<T>>,
    /// Index (counted over every pushed frame) of `frames[0]`.
    front: u64,
    open: HashMap<u64, Open>,
    /// Frames handed out, kept for reuse.
    spare: Vec<Held<T>>,
    closing: Vec<u64>,
}

impl<T> Default for Lookback<T> {
    fn default() -> Self {
        Lookback {
            frames: VecDeque::new(),
            front: 0,
            open: HashMap::new(),
            spare: Vec::new(),
            closing: Vec::new(),
        }
    }
}

impl<T: Default> Lookback<T> {
    /// Takes one frame's reports (those of [`super::Tracker::reports`], in order) with the
    /// frame's `stamp`; `fill` writes each report's value into a reused slot.
    pub fn push(
        &mut self,
        stamp: u64,
        reports: &[TrackReport],
        mut fill: impl FnMut(&mut T, &TrackReport),
    ) {
        let index = self.front + self.frames.len() as u64;
        let mut held = self.spare.pop().unwrap_or_default();
        held.stamp = stamp;
        held.used = 0;
        held.undecided = 0;
        for r in reports.iter().filter(|r| r.status != ReportStatus::Hidden) {
            if held.used == held.items.len() {
                held.items.push(Item::default());
            }
            let item = &mut held.items[held.used];
            held.used += 1;
            item.id = r.id;
            fill(&mut item.value, r);
            if r.status == ReportStatus::Final {
                item.decision = Decision::Shown;
            } else {
                item.decision = Decision::Undecided;
                held.undecided += 1;
            }
        }
        self.frames.push_back(held);
        for r in reports {
            match (r.status, self.open.get_mut(&r.id)) {
                (ReportStatus::Final, Some(_)) => self.close(r.id, Decision::Shown),
                (ReportStatus::Final | ReportStatus::Hidden, None) => {}
                (_, Some(open)) => open.seen = index,
                (_, None) => {
                    let open = Open {
                        first: index,
                        seen: index,
                    };
                    self.open.insert(r.id, open);
                }
            }
        }
        // A track not reported in this frame has ended (or stopped being reported): its held
        // reports are not shown.
        self.closing.clear();
        let ended = self.open.iter().filter(|(_, o)| o.seen < index);
        self.closing.extend(ended.map(|(&id, _)| id));
        for i in 0..self.closing.len() {
            self.close(self.closing[i], Decision::Dropped);
        }
    }

    /// Decides every undecided report of track `id` and forgets the track.
    fn close(&mut self, id: u64, decision: Decision) {
        let Some(open) = self.open.remove(&id) else {
            return;
        };
        let start = (open.first - self.front) as usize;
        for held in self.frames.range_mut(start..) {
            let used = held.used;
            let item = held.items[..used].iter_mut().find(|i| i.id == id);
            if let Some(item) = item.filter(|i| i.decision == Decision::Undecided) {
                item.decision = decision;
                held.undecided -= 1;
            }
        }
    }

    /// Moves the oldest held frame out once every report in it is decided: returns its stamp
    /// and leaves the values of its shown reports, in report order, in `out` (swapped with
    /// `out`'s own values, which are kept for reuse). `None` while the oldest frame waits.
    pub fn pop_into(&mut self, out: &mut Vec<T>) -> Option<u64> {
        let held = self.frames.front_mut().filter(|h| h.undecided == 0)?;
        let mut n = 0;
        let shown = held.items[..held.used]
            .iter_mut()
            .filter(|i| i.decision == Decision::Shown);
        for item in shown {
            if n == out.len() {
                out.push(T::default());
            }
            std::mem::swap(&mut out[n], &mut item.value);
            n += 1;
        }
        out.truncate(n);
        let stamp = held.stamp;
        let held = self.frames.pop_front().expect("the front frame");
        self.front += 1;
        self.spare.push(held);
        Some(stamp)
    }

    /// The input has ended: every undecided report is dropped, so every held frame is ready.
    pub fn finish(&mut self) {
        self.closing.clear();
        self.closing.extend(self.open.keys().copied());
        for i in 0..self.closing.len() {
            self.close(self.closing[i], Decision::Dropped);
        }
    }

    /// Number of frames held (pushed and not yet moved out).
    pub fn held_frames(&self) -> usize {
        self.frames.len()
    }
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;

    fn report(id: u64, status: ReportStatus) -> TrackReport {
        let bbox = crate::tracker::Box3 {
            center: [0.0; 3],
            yaw: 0.0,
            size: [1.0; 3],
        };
        TrackReport {
            id,
            class: 0,
            bbox,
            velocity: [0.0; 3],
            yaw_rate: 0.0,
            score: 1.0,
            position_variance: [0.0; 3],
            yaw_variance: 0.0,
            velocity_variance: [0.0; 3],
            yaw_rate_variance: 0.0,
            age: 0,
            hits: 1,
            frames_since_update: 0,
            detection: None,
            status,
        }
    }

    /// Pushes every frame, collecting the frames as soon as they are ready, then finishes.
    fn run(frames: &[Vec<(u64, ReportStatus)>]) -> Vec<(u64, Vec<u64>)> {
        let mut lb: Lookback<u64> = Lookback::default();
        let mut out = Vec::new();
        let mut drain = |lb: &mut Lookback<u64>| {
            let mut ids = Vec::new();
            while let Some(stamp) = lb.pop_into(&mut ids) {
                out.push((stamp, ids.clone()));
            }
        };
        for (stamp, f) in frames.iter().enumerate() {
            let reports: Vec<TrackReport> = f.iter().map(|&(id, s)| report(id, s)).collect();
            lb.push(stamp as u64, &reports, |v, r| *v = r.id);
            drain(&mut lb);
        }
        lb.finish();
        drain(&mut lb);
        assert_eq!(lb.held_frames(), 0);
        out
    }

    /// The rule stated plainly over the whole sequence: an undecided report is shown when its
    /// track has a later final report and is reported (hidden or not) in every frame up to it;
    /// a hidden report is never shown.
    fn reference(frames: &[Vec<(u64, ReportStatus)>]) -> Vec<(u64, Vec<u64>)> {
        let status_at = |f: usize, id: u64| frames[f].iter().find(|r| r.0 == id).map(|r| r.1);
        let shown = |f: usize, id: u64| {
            for later in f + 1..frames.len() {
                match status_at(later, id) {
                    None => return false,
                    Some(ReportStatus::Final) => return true,
                    Some(_) => {}
                }
            }
            false
        };
        let frame_ids = |(f, reports): (usize, &Vec<(u64, ReportStatus)>)| {
            let ids = reports
                .iter()
                .filter(|&&(id, s)| match s {
                    Final => true,
                    Hidden => false,
                    Tentative | Coasting => shown(f, id),
                })
                .map(|r| r.0);
            (f as u64, ids.collect())
        };
        frames.iter().enumerate().map(frame_ids).collect()
    }

    use ReportStatus::{Coasting, Final, Hidden, Tentative};

    #[test]
    fn final_reports_pass_without_delay() {
        let mut lb: Lookback<u64> = Lookback::default();
        lb.push(7, &[report(1, Final), report(2, Final)], |v, r| *v = r.id);
        let mut ids = Vec::new();
        assert_eq!(lb.pop_into(&mut ids), Some(7));
        assert_eq!(ids, [1, 2]);
    }

    #[test]
    fn tentative_frames_are_shown_once_the_track_is_confirmed() {
        let frames = vec![
            vec![(1, Tentative), (2, Tentative)],
            vec![(1, Tentative), (2, Tentative)],
            vec![(1, Final)],
            vec![(1, Final)],
        ];
        // Track 2 was never confirmed: its frames are dropped when it stops being reported.
        let want = vec![(0, vec![1]), (1, vec![1]), (2, vec![1]), (3, vec![1])];
        assert_eq!(run(&frames), want);
    }

    #[test]
    fn coasted_frames_are_shown_inside_gaps_only() {
        let frames = vec![
            vec![(1, Final), (2, Final)],
            vec![(1, Coasting), (2, Coasting)],
            vec![(1, Final), (2, Coasting)],
            vec![(1, Coasting)],
        ];
        // Track 1's gap (frame 1) is bridged; its last coasted frame (3) ends the input.
        let want = vec![(0, vec![1, 2]), (1, vec![1]), (2, vec![1]), (3, vec![])];
        assert_eq!(run(&frames), want);
    }

    #[test]
    fn a_frame_waits_for_its_undecided_reports() {
        let mut lb: Lookback<u64> = Lookback::default();
        lb.push(0, &[report(1, Tentative)], |v, r| *v = r.id);
        lb.push(1, &[report(1, Tentative), report(2, Final)], |v, r| {
            *v = r.id
        });
        let mut ids = vec![9, 9, 9];
        assert_eq!(lb.pop_into(&mut ids), None);
        assert_eq!(lb.held_frames(), 2);
        lb.push(2, &[report(1, Final)], |v, r| *v = r.id);
        assert_eq!(lb.pop_into(&mut ids), Some(0));
        assert_eq!(ids, [1]);
    }

    fn frames_strategy() -> impl Strategy<Value = Vec<Vec<(u64, ReportStatus)>>> {
        let status = prop_oneof![Just(Final), Just(Tentative), Just(Coasting), Just(Hidden)];
        let frame = proptest::collection::btree_map(1u64..6, status, 0..5)
            .prop_map(|m| m.into_iter().collect::<Vec<_>>());
        proptest::collection::vec(frame, 0..30)
    }

    proptest! {
        #[test]
        fn frames_come_out_in_order_as_the_rule_says(frames in frames_strategy()) {
            prop_assert_eq!(run(&frames), reference(&frames));
        }
    }
}
