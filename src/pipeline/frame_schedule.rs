//! When is a frame complete? The tracking pass of `track` runs the tracker on a frame (all
//! detection messages with one stamp) once no more messages of it can arrive. Two ways to know:
//! a first pass that learned every frame's stamp and message count ([`Schedule::Known`]), or,
//! in a single pass, a watermark over the detection channels ([`Schedule::Streaming`]): the
//! earliest pending frame is complete once every channel has moved past its stamp or delivered
//! all its messages. The watermark assumes no stamp goes back to a frame already tracked; one
//! that does stops the single pass with a [`Replan`], and the run goes on in two passes.

use std::collections::{BTreeMap, HashMap, HashSet};
use std::ops::ControlFlow;

/// Why the single pass cannot go on: the file is tracked in two passes instead (the plan made
/// from the summary section was wrong about the file).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Replan {
    /// A detection stamp at or before a frame already tracked.
    StampBeforeTracked,
    /// A schema or channel record the summary did not list (or listed otherwise).
    UnlistedRecord,
    /// A detection stamp over a day from its message's log_time: the far-stamp check needs the
    /// median stamp of the file ([`super::stamp_check`]).
    StampFarFromLogTime,
}

/// How the tracking pass tells that a frame is complete.
pub enum Schedule {
    /// From the first pass: `(stamp, messages)` of every frame, in stamp order.
    Known(Vec<(u64, u32)>),
    /// One pass: a watermark over the detection channels.
    Streaming(Streaming),
}

/// Progress of one detection channel in a single pass.
#[derive(Debug, Clone, Copy)]
struct ChannelProgress {
    /// Messages in the file, from the summary's statistics, if known.
    total: Option<u64>,
    /// Messages seen so far.
    seen: u64,
    /// Stamp of the last one.
    last: Option<u64>,
}

/// State of the single-pass schedule, planned from the file's summary section.
pub struct Streaming {
    channels: HashMap<u16, ChannelProgress>,
    /// `(topic, schema id)` of every channel in the summary, and the schema ids: a record of the
    /// data section that the summary did not announce ends the single pass.
    summary_channels: HashMap<u16, (String, u16)>,
    summary_schemas: HashSet<u16>,
    /// Stamp of the last frame tracked.
    done: Option<u64>,
}

impl Streaming {
    /// A plan over `detection_channels` (`(id, message count if known)`), with the channels
    /// and schema ids the summary lists.
    pub fn new(
        detection_channels: impl IntoIterator<Item = (u16, Option<u64>)>,
        summary_channels: HashMap<u16, (String, u16)>,
        summary_schemas: HashSet<u16>,
    ) -> Self {
        Streaming {
            channels: detection_channels
                .into_iter()
                .map(|(id, total)| {
                    let p = ChannelProgress {
                        total,
                        seen: 0,
                        last: None,
                    };
                    (id, p)
                })
                .collect(),
            summary_channels,
            summary_schemas,
            done: None,
        }
    }
}

impl Schedule {
    /// Whether this is the single pass.
    pub fn is_streaming(&self) -> bool {
        matches!(self, Schedule::Streaming(_))
    }

    /// A schema record of the data section: the single pass stops at one the summary did not
    /// list.
    pub fn on_schema(&self, id: u16) -> ControlFlow<Replan> {
        match self {
            Schedule::Streaming(st) if !st.summary_schemas.contains(&id) => {
                ControlFlow::Break(Replan::UnlistedRecord)
            }
            _ => ControlFlow::Continue(()),
        }
    }

    /// A channel record of the data section: the single pass stops at one that differs from
    /// the summary's.
    pub fn on_channel(&self, id: u16, topic: &str, schema_id: u16) -> ControlFlow<Replan> {
        match self {
            Schedule::Streaming(st)
                if st.summary_channels.get(&id).map(|(t, s)| (t.as_str(), *s))
                    != Some((topic, schema_id)) =>
            {
                ControlFlow::Break(Replan::UnlistedRecord)
            }
            _ => ControlFlow::Continue(()),
        }
    }

    /// A message of detection channel `channel` with `stamp` has arrived; the single pass stops
    /// if the stamp's frame is already tracked.
    pub fn on_message(&mut self, channel: u16, stamp: u64) -> ControlFlow<Replan> {
        if let Schedule::Streaming(st) = self {
            if st.done.is_some_and(|d| stamp <= d) {
                return ControlFlow::Break(Replan::StampBeforeTracked);
            }
            let c = st.channels.get_mut(&channel).expect("a detection channel");
            c.seen += 1;
            c.last = Some(stamp);
        }
        ControlFlow::Continue(())
    }

    /// The stamp of the next frame to track if it is complete: `pending` holds the messages
    /// seen and not yet tracked by stamp, `next_frame` counts the frames tracked.
    pub fn ready<T>(&self, pending: &BTreeMap<u64, Vec<T>>, next_frame: usize) -> Option<u64> {
        match self {
            Schedule::Known(frames) => {
                let &(stamp, count) = frames.get(next_frame)?;
                (pending.get(&stamp).map(|v| v.len() as u32) == Some(count)).then_some(stamp)
            }
            Schedule::Streaming(st) => {
                let (&stamp, _) = pending.first_key_value()?;
                st.channels
                    .values()
                    .all(|c| c.total == Some(c.seen) || c.last.is_some_and(|l| l > stamp))
                    .then_some(stamp)
            }
        }
    }

    /// The frame at `stamp` has been tracked.
    pub fn tracked(&mut self, stamp: u64) {
        if let Schedule::Streaming(st) = self {
            st.done = Some(stamp);
        }
    }

    /// Number of frames, when known in advance.
    pub fn frames(&self) -> Option<usize> {
        match self {
            Schedule::Known(f) => Some(f.len()),
            Schedule::Streaming(_) => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Feeds `(channel, stamp)` messages; returns the frames tracked after each, and whether
    /// the single pass gave up.
    fn run(s: &mut Schedule, msgs: &[(u16, u64)]) -> (Vec<Vec<u64>>, bool) {
        let mut pending: BTreeMap<u64, Vec<u16>> = BTreeMap::new();
        let mut tracked = Vec::new();
        let mut n = 0;
        for &(ch, stamp) in msgs {
            if s.on_message(ch, stamp).is_break() {
                return (tracked, true);
            }
            pending.entry(stamp).or_default().push(ch);
            let mut now = Vec::new();
            while let Some(st) = s.ready(&pending, n) {
                pending.remove(&st);
                s.tracked(st);
                now.push(st);
                n += 1;
            }
            tracked.push(now);
        }
        (tracked, false)
    }

    fn streaming(channels: &[(u16, Option<u64>)]) -> Schedule {
        Schedule::Streaming(Streaming::new(
            channels.iter().copied(),
            HashMap::new(),
            HashSet::new(),
        ))
    }

    #[test]
    fn one_channel_tracks_a_frame_when_the_next_stamp_arrives() {
        let mut s = streaming(&[(1, None)]);
        let (t, gave_up) = run(&mut s, &[(1, 10), (1, 10), (1, 20), (1, 30)]);
        assert!(!gave_up);
        assert_eq!(t, vec![vec![], vec![], vec![10], vec![20]]);
    }

    #[test]
    fn two_channels_wait_for_the_slower_one_and_its_message_count() {
        // Channel 2 has 2 messages in the file: after its second it holds nothing back; channel
        // 1's fourth and last message releases the rest.
        let mut s = streaming(&[(1, Some(4)), (2, Some(2))]);
        let (t, gave_up) = run(
            &mut s,
            &[(1, 10), (1, 20), (2, 10), (1, 30), (2, 20), (1, 40)],
        );
        assert!(!gave_up);
        // (2, 10) does not release 10: channel 2 may have another message stamped 10.
        let none = Vec::<u64>::new();
        assert_eq!(
            t,
            vec![
                none.clone(),
                none.clone(),
                none.clone(),
                none,
                vec![10, 20],
                vec![30, 40]
            ]
        );
    }

    #[test]
    fn stamps_going_back_are_fine_until_they_reach_a_tracked_frame() {
        let mut s = streaming(&[(1, None)]);
        // 25 goes back from 30 but no frame after 20 was tracked yet.
        let (t, gave_up) = run(&mut s, &[(1, 10), (1, 20), (1, 30), (1, 25), (1, 40)]);
        assert!(!gave_up);
        assert_eq!(t, vec![vec![], vec![10], vec![20], vec![], vec![25, 30]]);
        // 15 goes back to before 20, which is tracked.
        let mut s = streaming(&[(1, None)]);
        let (_, gave_up) = run(&mut s, &[(1, 10), (1, 20), (1, 30), (1, 15)]);
        assert!(gave_up);
    }

    #[test]
    fn known_frames_are_complete_at_their_message_count() {
        let mut s = Schedule::Known(vec![(10, 2), (20, 1)]);
        let (t, gave_up) = run(&mut s, &[(1, 20), (1, 10), (2, 10)]);
        assert!(!gave_up);
        assert_eq!(t, vec![vec![], vec![], vec![10, 20]]);
    }

    #[test]
    fn records_the_summary_did_not_list_end_the_single_pass() {
        let s = Schedule::Streaming(Streaming::new(
            [(1, None)],
            HashMap::from([(1, ("/detections".to_string(), 3))]),
            HashSet::from([3]),
        ));
        let unlisted = ControlFlow::Break(Replan::UnlistedRecord);
        assert!(s.on_schema(3).is_continue() && s.on_schema(4) == unlisted);
        assert!(s.on_channel(1, "/detections", 3).is_continue());
        assert_eq!(s.on_channel(1, "/other", 3), unlisted);
        assert_eq!(s.on_channel(2, "/detections", 3), unlisted);
        let known = Schedule::Known(vec![]);
        assert!(known.on_schema(4).is_continue() && known.on_channel(2, "/x", 0).is_continue());
    }
}
