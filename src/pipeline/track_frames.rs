//! The per-frame work of a track session: the detections of a complete frame into the tracker,
//! its reports into a reused [`Tracks3D`] with each track's image box and attributes, and, with
//! the offline reporting options, the frames held until their reports are decided.

use std::collections::{BTreeMap, HashMap, HashSet, VecDeque};

use anyhow::{Context, Result};

use super::detections::{convert, reject, InputCounters, Origin};
use crate::msgs::detection_frame::DetectionFrame;
use crate::msgs::track_encode::{fill_track3d, rate_variances, RateVariances};
use crate::msgs::{ImageBox, Track3D, Tracks3D};
use crate::tracker::{Detection, Lookback, TrackReport, Tracker};

/// One decoded detection message waiting for its frame.
pub(super) struct Pending {
    pub(super) ordinal: u64,
    pub(super) log_time: u64,
    pub(super) topic_idx: usize,
    pub(super) msg: DetectionFrame,
}

/// Image box and attributes of a track's last matched detection.
#[derive(Default)]
struct Extra {
    image_box: Option<ImageBox>,
    attributes: BTreeMap<String, String>,
}

/// The side-table entry of report `r`'s track after this frame: a match moves its detection's
/// image box and attributes in (or clears the entry when the detection has none).
fn take_extra<'a>(
    last_extra: &'a mut HashMap<u64, Extra>,
    src: &[(u32, u32)],
    frame: &mut [Pending],
    r: &TrackReport,
) -> Option<&'a mut Extra> {
    if let Some(i) = r.detection {
        let (mi, di) = src[i as usize];
        let d = &mut frame[mi as usize].msg.boxes[di as usize];
        if d.image_box.is_some() || !d.attributes.is_empty() {
            let e = last_extra.entry(r.id).or_default();
            e.image_box = d.image_box;
            std::mem::swap(&mut e.attributes, &mut d.attributes);
        } else {
            last_extra.remove(&r.id);
        }
    }
    last_extra.get_mut(&r.id)
}

/// A report held by the offline options, with the extras its track had in its frame.
#[derive(Default)]
struct HeldTrack {
    report: TrackReport,
    image_box: Option<ImageBox>,
    attributes: BTreeMap<String, String>,
}

/// The frames held while the offline options (`backfill`, `coast: gaps`) decide their reports,
/// with each frame's latest detection log time and frame id. The attributes of a held report
/// are a copy (the only allocation per report, and only for detections that carry attributes).
#[derive(Default)]
pub(super) struct HeldFrames {
    lookback: Lookback<HeldTrack>,
    /// Per held frame, in order: latest detection log time and frame id.
    frames: VecDeque<(u64, String)>,
    /// Frame id strings of written frames, reused.
    spare_ids: Vec<String>,
    shown: Vec<HeldTrack>,
    /// Track boxes written, and the tracks they belong to (for the mean track length: the
    /// tracker counts frames the lookback may leave out).
    pub(super) shown_boxes: u64,
    pub(super) shown_tracks: HashSet<u64>,
}

/// Per-frame buffers reused across frames, and the attributes of each track's last matched
/// detection. Nothing is allocated per detection in steady state: the output message's tracks
/// are overwritten in place, and a track's attributes are moved (not copied) from its detection
/// into the side table and swapped into the message only while it is encoded.
#[derive(Default)]
pub(super) struct FrameState {
    dets: Vec<Detection>,
    /// `(message index within the frame, detection index within the message)` per detection.
    src: Vec<(u32, u32)>,
    last_extra: HashMap<u64, Extra>,
    pub(super) out: Tracks3D,
    /// Velocity and yaw-rate variances of `out.tracks`, in the same order (written by the
    /// Autoware tracks format; `Track3D` has no field for them).
    pub(super) rates: Vec<RateVariances>,
    pub(super) buf: Vec<u8>,
    /// Present when a class reports offline (see [`crate::tracker::lookback`]).
    pub(super) held: Option<HeldFrames>,
}

impl FrameState {
    /// The buffers for a run with `config`: frames are held when a class reports offline.
    pub(super) fn new(config: &crate::tracker::TrackerConfig) -> FrameState {
        FrameState {
            held: config.holds_frames().then(HeldFrames::default),
            ..FrameState::default()
        }
    }

    /// Tracks one frame and fills `self.out`. Call [`FrameState::finish`] after encoding it.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn run(
        &mut self,
        stamp: u64,
        latest: u64,
        frame: &mut [Pending],
        tracker: &mut Tracker,
        counters: &mut InputCounters,
        strict: bool,
        file: &str,
        topics: &[String],
    ) -> Result<()> {
        self.dets.clear();
        self.src.clear();
        for (mi, p) in frame.iter().enumerate() {
            let origin = Origin {
                file,
                topic: &topics[p.topic_idx],
                log_time: p.log_time,
            };
            // Valid and rejected boxes in message order, as a --strict error names the first.
            let mut rejected = p.msg.rejected.iter().peekable();
            for (di, d) in p.msg.boxes.iter().enumerate() {
                while let Some(r) = rejected.next_if(|r| r.index < d.index) {
                    reject(r, counters, strict, &origin)?;
                }
                if let Some(det) = convert(d, tracker, counters, strict, &origin)? {
                    self.dets.push(det);
                    self.src.push((mi as u32, di as u32));
                }
            }
            for r in rejected {
                reject(r, counters, strict, &origin)?;
            }
        }
        tracker
            .step(stamp, &self.dets)
            .with_context(|| format!("{file}: frame at stamp {stamp}"))?;
        let reports = tracker.reports();
        self.out.stamp = stamp;
        self.out.frame_id.clear();
        if let Some(p) = frame.first() {
            self.out.frame_id.push_str(&p.msg.frame_id);
        }
        if let Some(held) = &mut self.held {
            // Offline options: the reports wait in the lookback with a copy of their extras.
            let mut fill = |v: &mut HeldTrack, r: &TrackReport| {
                v.report = *r;
                match take_extra(&mut self.last_extra, &self.src, frame, r) {
                    Some(e) => {
                        v.image_box = e.image_box;
                        v.attributes.clone_from(&e.attributes);
                    }
                    None => {
                        v.image_box = None;
                        v.attributes.clear();
                    }
                }
            };
            held.lookback.push(stamp, reports, &mut fill);
            let mut frame_id = held.spare_ids.pop().unwrap_or_default();
            frame_id.clone_from(&self.out.frame_id);
            held.frames.push_back((latest, frame_id));
            return Ok(());
        }
        self.out.tracks.resize_with(reports.len(), Track3D::default);
        self.rates.clear();
        self.rates.extend(reports.iter().map(rate_variances));
        for (t, r) in self.out.tracks.iter_mut().zip(reports) {
            let extra = take_extra(&mut self.last_extra, &self.src, frame, r);
            fill_track3d(t, r, tracker.label(r.class));
            match extra {
                Some(e) => {
                    t.image_box = e.image_box;
                    std::mem::swap(&mut t.attributes, &mut e.attributes);
                }
                None => {
                    t.image_box = None;
                    t.attributes.clear();
                }
            }
        }
        Ok(())
    }

    /// No frame follows: the held frames' reports are decided as they stand (the offline
    /// options' undecided reports are not shown).
    pub(super) fn end(&mut self) {
        if let Some(held) = &mut self.held {
            held.lookback.finish();
        }
    }

    /// With the offline options: the next frame whose reports are all decided, in
    /// `self.out` (its tracks own their attributes; [`FrameState::finish`] is not needed), and
    /// the latest log time of its detection messages.
    pub(super) fn next_held(&mut self, tracker: &Tracker) -> Option<u64> {
        let held = self.held.as_mut()?;
        let stamp = held.lookback.pop_into(&mut held.shown)?;
        let (latest, frame_id) = held.frames.pop_front().expect("a held frame's own data");
        self.out.stamp = stamp;
        held.spare_ids
            .push(std::mem::replace(&mut self.out.frame_id, frame_id));
        self.out
            .tracks
            .resize_with(held.shown.len(), Track3D::default);
        held.shown_boxes += held.shown.len() as u64;
        held.shown_tracks
            .extend(held.shown.iter().map(|v| v.report.id));
        self.rates.clear();
        (self.rates).extend(held.shown.iter().map(|v| rate_variances(&v.report)));
        for (t, v) in self.out.tracks.iter_mut().zip(&mut held.shown) {
            fill_track3d(t, &v.report, tracker.label(v.report.class));
            t.image_box = v.image_box;
            std::mem::swap(&mut t.attributes, &mut v.attributes);
        }
        Some(latest)
    }

    /// Gives the attributes lent to the encoded message back to the side table and forgets the
    /// tracks deleted in this frame.
    pub(super) fn finish(&mut self, deleted: &[u64]) {
        // Held frames copied their attributes: nothing was lent.
        let lent = if self.held.is_none() {
            &mut self.out.tracks[..]
        } else {
            &mut []
        };
        for t in lent {
            if let Some(e) = self.last_extra.get_mut(&t.id) {
                std::mem::swap(&mut t.attributes, &mut e.attributes);
            }
        }
        for id in deleted {
            self.last_extra.remove(id);
        }
    }
}
