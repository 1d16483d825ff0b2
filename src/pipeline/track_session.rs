//! Tracking without I/O, for programs that embed probmot: a [`TrackSession`] is made from a
//! tracker configuration and [`SessionOptions`], takes complete frames of decoded detections
//! ([`DetectionFrame`]s, made in code or decoded from any source) and hands out each frame's
//! tracks as a [`Tracks3D`]; [`TrackSession::finish`] sums up the run. `probmot track` drives
//! the same session from the records of an MCAP file (its adapter adds the reading, the
//! reordering of messages by stamp, ego motion and the output channels).
//!
//! The crate documentation ([`crate`]) and `examples/track_in_code.rs` show it in use.

use anyhow::Result;

use super::detections::{describe_first_skips, describe_unknown_labels, InputCounters};
use super::track_frames::{FrameState, Pending};
use super::track_warnings::{beyond_bounds, period_mismatch, unused_entries, FrameIntervals};
use crate::msgs::detection_frame::{describe_skips, DetectionFrame};
use crate::msgs::Tracks3D;
use crate::tracker::{Tracker, TrackerConfig};

/// Options of a [`TrackSession`].
#[derive(Debug, Clone)]
pub struct SessionOptions {
    /// Named in errors and warnings (e.g. the input file).
    pub name: String,
    /// Turn every skipped box (invalid, or of a label the configuration does not track) into
    /// an error.
    pub strict: bool,
}

impl Default for SessionOptions {
    fn default() -> Self {
        SessionOptions {
            name: "session".into(),
            strict: false,
        }
    }
}

/// What a session did, with the warnings for its user.
#[derive(Debug, Clone, Default)]
pub struct SessionSummary {
    /// Frames tracked.
    pub frames: u64,
    /// Tracks started.
    pub tracks_born: u64,
    /// Tracks that reached `min_hits`.
    pub tracks_confirmed: u64,
    /// Mean number of reported frames per confirmed track (with the offline reporting options:
    /// shown boxes per shown track).
    pub mean_track_length: Option<f64>,
    /// Detections given to the tracker, per label, and the skipped ones by reason.
    pub detections: InputCounters,
    /// Warnings (skipped boxes, unused config entries, a frame rate unlike the config's, ...).
    pub warnings: Vec<String>,
}

/// A tracker fed complete frames of decoded detections, handing out each frame's tracks. Frames
/// go in stamp order, one [`TrackSession::track`] per frame; after each, take the frames it
/// made ready with [`TrackSession::next_frame`] (one, or with the offline reporting options
/// `backfill`/`coast: gaps`, the earlier frames now decided). After the last frame,
/// [`TrackSession::end`] makes the held frames ready. Nothing is allocated per detection in
/// steady state.
pub struct TrackSession {
    pub(super) tracker: Tracker,
    pub(super) counters: InputCounters,
    pub(super) frame_state: FrameState,
    intervals: FrameIntervals,
    options: SessionOptions,
    /// Topics of the messages of a frame (for errors); one, `frames`, for frames given by
    /// [`TrackSession::track`].
    pub(super) topics: Vec<String>,
    /// The frame given to [`TrackSession::track`], reused.
    one: Vec<Pending>,
    /// The latest log time of the frame tracked and not yet handed out (without the offline
    /// options).
    fresh: Option<u64>,
    /// The frame's attributes are still lent to the tracks handed out: give them back before
    /// the next frame.
    unsettled: bool,
}

impl TrackSession {
    /// A session tracking with `config`.
    pub fn new(config: TrackerConfig, options: SessionOptions) -> Result<Self> {
        Ok(TrackSession {
            frame_state: FrameState::new(&config),
            tracker: Tracker::new(config)?,
            counters: InputCounters::default(),
            intervals: FrameIntervals::default(),
            options,
            topics: vec!["frames".into()],
            one: Vec::with_capacity(1),
            fresh: None,
            unsettled: false,
        })
    }

    /// Tracks one complete frame: every detection at `frame.stamp`, later than the frame
    /// before. Invalid boxes and labels the configuration does not track are counted (errors
    /// with [`SessionOptions::strict`]).
    pub fn track(&mut self, frame: DetectionFrame) -> Result<()> {
        let mut one = std::mem::take(&mut self.one);
        one.push(Pending {
            ordinal: 0,
            log_time: frame.stamp,
            topic_idx: 0,
            msg: frame,
        });
        let r = self.track_messages(&mut one);
        one.clear();
        self.one = one;
        r
    }

    /// Tracks the frame made of the detection messages `msgs` (in arrival order, one stamp).
    pub(super) fn track_messages(&mut self, msgs: &mut [Pending]) -> Result<()> {
        self.settle();
        let stamp = msgs.first().expect("a frame has a message").msg.stamp;
        let latest = msgs.iter().map(|p| p.log_time).max().unwrap_or(stamp);
        self.frame_state.run(
            stamp,
            latest,
            msgs,
            &mut self.tracker,
            &mut self.counters,
            self.options.strict,
            &self.options.name,
            &self.topics,
        )?;
        if self.frame_state.held.is_none() {
            self.fresh = Some(latest);
            self.unsettled = true;
        } else {
            // Held frames copied their attributes: nothing is lent.
            self.frame_state.finish(self.tracker.deleted());
        }
        self.intervals.push(stamp);
        Ok(())
    }

    /// The tracks of the next frame ready, oldest first; `None` when every ready frame has been
    /// handed out.
    pub fn next_frame(&mut self) -> Option<&Tracks3D> {
        self.next_ready()?;
        Some(&self.frame_state.out)
    }

    /// [`TrackSession::next_frame`] for the record adapter: the latest log time of the ready
    /// frame's messages; its tracks are in `frame_state.out` (and their rate variances in
    /// `frame_state.rates`).
    pub(super) fn next_ready(&mut self) -> Option<u64> {
        if let Some(latest) = self.fresh.take() {
            return Some(latest);
        }
        self.settle();
        self.frame_state.next_held(&self.tracker)
    }

    /// No frame follows: with the offline reporting options, the held frames become ready.
    pub fn end(&mut self) {
        self.frame_state.end();
    }

    /// Gives the attributes lent to the frame handed out back, and forgets the deleted tracks.
    fn settle(&mut self) {
        self.fresh = None;
        if std::mem::take(&mut self.unsettled) {
            self.frame_state.finish(self.tracker.deleted());
        }
    }

    /// Frames tracked so far.
    pub fn frames(&self) -> u64 {
        self.tracker.stats().frames
    }

    /// The summary of the run and its warnings.
    pub fn finish(self) -> SessionSummary {
        let TrackSession {
            options,
            tracker,
            counters,
            frame_state,
            mut intervals,
            ..
        } = self;
        let file = &options.name;
        let st = tracker.stats();
        let mut summary = SessionSummary {
            frames: st.frames,
            tracks_born: st.born,
            tracks_confirmed: st.confirmed,
            ..Default::default()
        };
        summary.mean_track_length = match &frame_state.held {
            // Offline reporting: what was shown (every shown track is confirmed).
            Some(h) => {
                (h.shown_boxes > 0).then(|| h.shown_boxes as f64 / h.shown_tracks.len() as f64)
            }
            None => tracker.mean_confirmed_track_length(),
        };
        let warnings = &mut summary.warnings;
        if counters.total_skipped() > 0 {
            let mut warning = format!("{file}: skipped {}", describe_skips(&counters.skipped));
            warning.push_str(&describe_first_skips(&counters));
            if !counters.unknown_labels.is_empty() {
                let known: Vec<&str> = (tracker.config().classes.keys())
                    .map(|k| k.as_str())
                    .collect();
                warning.push_str(&format!(
                    "; labels not in the config: {}; the config has entries for {} (add an \
                     entry for a label, or a \"default\" one, to track it: `probmot config`)",
                    describe_unknown_labels(&counters.unknown_labels),
                    known.join(", ")
                ));
            }
            warnings.push(warning);
        }
        if let Some(w) = unused_entries(file, tracker.config(), &counters) {
            warnings.push(w);
        }
        warnings.extend(period_mismatch(file, tracker.config(), &mut intervals));
        if counters.score_outside_unit > 0 {
            warnings.push(format!(
                "{file}: {} detections have a score outside [0, 1]; they are tracked as given",
                counters.score_outside_unit
            ));
        }
        warnings.extend(beyond_bounds(file, &st));
        summary.detections = counters;
        summary
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msgs::detection_frame::DetectionBox;
    use crate::tracker::Box3;

    /// One frame per call, a car at `x` when given.
    fn frame(i: u64, car: Option<f64>) -> DetectionFrame {
        let boxes = car.map(|x| DetectionBox {
            index: 0,
            bbox: Box3 {
                center: [x, 0.0, 0.0],
                yaw: 0.0,
                size: [4.0, 2.0, 1.5],
            },
            label: "car".into(),
            score: 0.9,
            velocity: None,
            image_box: None,
            attributes: [("frame".to_string(), i.to_string())].into(),
            needs_own_entry: false,
        });
        DetectionFrame {
            stamp: 100_000_000 * (i + 1),
            frame_id: "map".into(),
            boxes: boxes.into_iter().collect(),
            rejected: vec![],
        }
    }

    /// Tracks `cars` (one frame each) and returns, per frame handed out, its stamp and the
    /// `frame` attribute of each track.
    fn handed_out(backfill: bool, cars: &[Option<f64>]) -> Vec<(u64, Vec<String>)> {
        let mut config = TrackerConfig::preset("nuscenes-chiu2019").unwrap();
        config.for_each_class(|c| c.levers.backfill = backfill);
        let mut s = TrackSession::new(config, SessionOptions::default()).unwrap();
        let mut out = Vec::new();
        let mut take = |s: &mut TrackSession| {
            while let Some(t) = s.next_frame() {
                let attrs = t.tracks.iter().map(|t| t.attributes["frame"].clone());
                out.push((t.stamp, attrs.collect()));
            }
        };
        for (i, car) in cars.iter().enumerate() {
            s.track(frame(i as u64, *car)).unwrap();
            take(&mut s);
        }
        s.end();
        take(&mut s);
        assert_eq!(s.finish().frames, cars.len() as u64);
        out
    }

    /// Every frame is handed out once, in order, with the attributes of its own detection;
    /// with backfill the frames wait until decided and show the car from its first frame.
    #[test]
    fn frames_are_handed_out_once_in_order_with_their_own_attributes() {
        let cars: Vec<Option<f64>> = (0..8).map(|i| (i >= 4).then_some(0.3 * i as f64)).collect();
        let stamps: Vec<u64> = (1..=8).map(|i| 100_000_000 * i).collect();
        let shown = handed_out(false, &cars);
        let backfilled = handed_out(true, &cars);
        for run in [&shown, &backfilled] {
            assert_eq!(run.iter().map(|f| f.0).collect::<Vec<_>>(), stamps);
        }
        let none: Vec<String> = vec![];
        let one = |i: usize| vec![i.to_string()];
        let tracks = |run: &[(u64, Vec<String>)]| run[4..].iter().map(|f| f.1.clone()).collect();
        let plain: Vec<Vec<String>> = tracks(&shown);
        assert_eq!(plain, [none.clone(), none, one(6), one(7)]);
        let held: Vec<Vec<String>> = tracks(&backfilled);
        assert_eq!(held, [one(4), one(5), one(6), one(7)]);
    }
}
