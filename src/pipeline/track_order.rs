//! Keeps `track`'s output in log-time order. A frame is known to be complete only when a later
//! detection message arrives (or the input ends), so its tracks are ready after input messages
//! that come later in time. Those messages are held here, in file order, until the tracks of
//! every frame that could come before them are written: each frame's tracks then precede every
//! input message with a later log time, and a time-ordered input gives a time-ordered output
//! (streaming readers such as `McapStreamReader` see the tracks in time).
//!
//! The log time of a frame's tracks is the latest log time of its detection messages (when the
//! tracker could first have produced them), and never earlier than the previous frame's, so the
//! tracks channel is itself in order. What is held is at most the input between a frame's last
//! detection message and the message that completes it (the frame in flight), in one reused
//! byte buffer: no allocation per message in steady state.

use std::collections::{BTreeMap, VecDeque};

use anyhow::Result;
use mcap::records::MessageHeader;

use crate::mcapio::sink::RecordSink;

/// Input messages held back until the tracks before them are written, and the log times the
/// pending frames' tracks will have at least.
#[derive(Default)]
pub(super) struct LogTimeOrder {
    /// Held messages in file order: header and `[start, end)` in `bytes`.
    held: VecDeque<(MessageHeader, usize, usize)>,
    bytes: Vec<u8>,
    /// Per pending frame, the latest log time of its detection messages so far (a multiset:
    /// log time → number of frames).
    pending: BTreeMap<u64, u32>,
    /// Log time of the last tracks written.
    last_tracks: u64,
}

impl LogTimeOrder {
    /// Earliest log time any pending frame's tracks can have; `u64::MAX` with none pending.
    fn bound(&self) -> u64 {
        self.pending
            .first_key_value()
            .map_or(u64::MAX, |(&t, _)| t.max(self.last_tracks))
    }

    /// Copies an input message to `out`, or holds it while tracks that must precede it are
    /// still to come (and while earlier messages are held, to keep the file order).
    pub(super) fn copy(
        &mut self,
        out: &mut impl RecordSink,
        header: &MessageHeader,
        data: &[u8],
    ) -> Result<()> {
        if self.held.is_empty() && header.log_time <= self.bound() {
            return out.write_to_known_channel(header, data);
        }
        let start = self.bytes.len();
        self.bytes.extend_from_slice(data);
        self.held.push_back((*header, start, self.bytes.len()));
        Ok(())
    }

    /// A pending frame's latest detection log time went from `old` (`None`: a new frame) to
    /// `new`.
    pub(super) fn frame_time(&mut self, old: Option<u64>, new: u64) {
        if let Some(old) = old {
            self.forget(old);
        }
        *self.pending.entry(new).or_default() += 1;
    }

    fn forget(&mut self, t: u64) {
        if let Some(n) = self.pending.get_mut(&t) {
            *n -= 1;
            if *n == 0 {
                self.pending.remove(&t);
            }
        }
    }

    /// A pending frame with latest detection log time `t` is being tracked: writes the held
    /// messages up to its tracks' log time and returns that log time (write the tracks next).
    pub(super) fn tracks_time(&mut self, out: &mut impl RecordSink, t: u64) -> Result<u64> {
        self.forget(t);
        let t = t.max(self.last_tracks);
        self.last_tracks = t;
        self.flush(out, t)?;
        Ok(t)
    }

    /// Writes the held messages that no pending frame's tracks must precede (all of them when
    /// nothing is pending).
    pub(super) fn release(&mut self, out: &mut impl RecordSink) -> Result<()> {
        self.flush(out, self.bound())
    }

    /// Writes every held message, whatever tracks are still to come (the end of one file of a
    /// split bag: its messages stay in its output file).
    pub(super) fn flush_all(&mut self, out: &mut impl RecordSink) -> Result<()> {
        self.flush(out, u64::MAX)
    }

    /// Writes the held messages, in file order, while their log time is at most `upto`.
    fn flush(&mut self, out: &mut impl RecordSink, upto: u64) -> Result<()> {
        while let Some(&(header, start, end)) = self.held.front() {
            if header.log_time > upto {
                break;
            }
            out.write_to_known_channel(&header, &self.bytes[start..end])?;
            self.held.pop_front();
        }
        match self.held.front() {
            None => self.bytes.clear(),
            // Held for long (a frame that stays incomplete): drop the written part.
            Some(&(_, start, _)) if start > self.bytes.len() / 2 && start > 1 << 20 => {
                self.bytes.drain(..start);
                for h in &mut self.held {
                    h.1 -= start;
                    h.2 -= start;
                }
            }
            Some(_) => {}
        }
        Ok(())
    }

    /// Whether nothing is held (true after the last frame's tracks).
    pub(super) fn is_empty(&self) -> bool {
        self.held.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mcapio::sink::{MemorySink, SinkRecord};

    fn header(channel_id: u16, log_time: u64) -> MessageHeader {
        MessageHeader {
            channel_id,
            sequence: 0,
            log_time,
            publish_time: log_time,
        }
    }

    fn log_times(sink: &MemorySink) -> Vec<(u16, u64)> {
        sink.records
            .iter()
            .filter_map(|r| match r {
                SinkRecord::Message(h, _) => Some((h.channel_id, h.log_time)),
                _ => None,
            })
            .collect()
    }

    /// A detection at 10 is complete only when the one at 20 arrives: the image at 15 between
    /// them waits, and the tracks (channel 9) come out between the detection at 10 and it.
    #[test]
    fn messages_after_a_pending_frame_wait_for_its_tracks() {
        let mut o = LogTimeOrder::default();
        let mut sink = MemorySink::default();
        o.copy(&mut sink, &header(1, 10), b"det10").unwrap();
        o.frame_time(None, 10);
        o.copy(&mut sink, &header(2, 15), b"image15").unwrap();
        o.copy(&mut sink, &header(2, 10), b"image10").unwrap();
        o.copy(&mut sink, &header(1, 20), b"det20").unwrap();
        o.frame_time(None, 20);
        let t = o.tracks_time(&mut sink, 10).unwrap();
        assert_eq!(t, 10);
        sink.write_to_known_channel(&header(9, t), b"tracks10")
            .unwrap();
        o.release(&mut sink).unwrap();
        // The image at 10 stays behind the one at 15 (file order is kept).
        assert_eq!(
            log_times(&sink),
            [(1, 10), (9, 10), (2, 15), (2, 10), (1, 20)]
        );
        assert!(o.is_empty());
        let t = o.tracks_time(&mut sink, 20).unwrap();
        sink.write_to_known_channel(&header(9, t), b"tracks20")
            .unwrap();
        assert_eq!(log_times(&sink).last(), Some(&(9, 20)));
        // Nothing pending: straight through, bytes intact.
        o.copy(&mut sink, &header(2, 30), b"image30").unwrap();
        assert_eq!(
            sink.records.last(),
            Some(&SinkRecord::Message(header(2, 30), b"image30".to_vec()))
        );
    }

    /// A frame whose detections were logged before the previous frame's tracks gets the
    /// previous tracks' log time, so the tracks channel never goes back in time.
    #[test]
    fn tracks_log_times_never_decrease() {
        let mut o = LogTimeOrder::default();
        let mut sink = MemorySink::default();
        o.frame_time(None, 50);
        o.frame_time(None, 40);
        assert_eq!(o.tracks_time(&mut sink, 50).unwrap(), 50);
        assert_eq!(o.tracks_time(&mut sink, 40).unwrap(), 50);
    }

    /// A frame's log time that grows (a second detection channel logged later) moves the bound.
    #[test]
    fn a_later_message_of_a_frame_moves_its_time() {
        let mut o = LogTimeOrder::default();
        let mut sink = MemorySink::default();
        o.frame_time(None, 10);
        o.copy(&mut sink, &header(2, 12), b"a").unwrap();
        assert!(!o.is_empty());
        o.frame_time(Some(10), 12);
        o.release(&mut sink).unwrap();
        assert!(o.is_empty(), "12 is not after the frame's tracks at 12");
    }
}
