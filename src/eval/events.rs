//! `eval --events`: the evaluation's own decisions, frame by frame, so that a metric can be traced
//! to the moments that made it. The protocols record what their pass at the best-MOTA threshold
//! decided into a [`Collector`] (matches, misses, false positives; KITTI also the identity
//! switches and fragmentations it counts along each trajectory); [`resolve`] turns that record
//! into located [`Event`]s with the boxes' geometry, and counts them.
//!
//! The counts are those of the metrics: the nuScenes identity switches are the accumulator's
//! switch events and its fragmentations are where an object, tracked before and again later,
//! is first missed (the devkit's rule, applied to the recorded sequence of each object); KITTI's
//! are marked where the evaluation counts them.

use std::collections::HashMap;

use serde::Serialize;

use super::mot_accumulator::EventKind;
use crate::msgs::eval_event::Kind;
use crate::msgs::{size3, v3, EvalEvent};

/// What the evaluation decided about one box.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    /// Ground truth and track paired.
    Match,
    /// Paired with another track than before (nuScenes: counted instead of a match).
    Switch,
    /// Ground truth without track.
    Miss,
    /// Track without ground truth.
    FalsePositive,
    /// Ground truth the protocol ignores (KITTI: truncated, occluded, neighbouring class).
    Ignored,
}

/// A trajectory error counted along a ground-truth trajectory (KITTI).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MarkKind {
    /// Identity switch.
    Switch,
    /// Fragmentation.
    Fragmentation,
}

/// One recorded decision: scene (log) and frame indexes, ids, and the position the protocol used.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Decision {
    /// Index of the scene (log).
    pub scene: usize,
    /// Index of the frame in the scene.
    pub frame: usize,
    /// The decision.
    pub outcome: Outcome,
    /// Ground-truth id as the protocol knows it (KITTI: the label file's track id).
    pub truth: Option<u64>,
    /// Track id.
    pub track: Option<u64>,
    /// Bird's-eye position of the ground truth (else the track), for boxes the scene lacks
    /// (nuScenes' interpolated boxes).
    pub xy: [f64; 2],
}

/// A KITTI trajectory error at the `position`-th frame in which its ground truth appears.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mark {
    /// Index of the scene.
    pub scene: usize,
    /// KITTI ground-truth id.
    pub truth: u64,
    /// Position along the trajectory.
    pub position: usize,
    /// Switch or fragmentation.
    pub kind: MarkKind,
    /// Track paired at that position.
    pub track: u64,
    /// The track paired before.
    pub previous: u64,
}

/// What one evaluation pass decided, in the order it decided it.
#[derive(Debug, Clone, Default)]
pub struct Collector {
    /// Per-box decisions, in frame order.
    pub decisions: Vec<Decision>,
    /// KITTI trajectory errors.
    pub marks: Vec<Mark>,
}

impl Collector {
    /// Records one event of the nuScenes accumulator: truth `(id, x, y)`, track `(id, (x, y, score))`.
    pub(crate) fn record_association(
        &mut self,
        scene: usize,
        frame: usize,
        kind: EventKind,
        truth: Option<(u64, f64, f64)>,
        track: Option<(u64, (f64, f64, f64))>,
    ) {
        let outcome = match kind {
            EventKind::Match => Outcome::Match,
            EventKind::Switch => Outcome::Switch,
            EventKind::Miss => Outcome::Miss,
            EventKind::FalsePositive => Outcome::FalsePositive,
        };
        let xy = match (truth, track) {
            (Some((_, x, y)), _) | (None, Some((_, (x, y, _)))) => [x, y],
            (None, None) => [f64::NAN; 2],
        };
        self.decisions.push(Decision {
            scene,
            frame,
            outcome,
            truth: truth.map(|t| t.0),
            track: track.map(|t| t.0),
            xy,
        });
    }

    /// Records one KITTI frame: each ground truth (matched track column or none, ignored or
    /// not), then the kept tracks that are false positives (unmatched and not ignored).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn record_kitti_frame(
        &mut self,
        scene: usize,
        frame: usize,
        gt_ids: impl Iterator<Item = i64>,
        matched: &[Option<usize>],
        ignored: impl Fn(usize) -> bool,
        tr_ignored: &[bool],
        tr_id: impl Fn(usize) -> i64,
    ) {
        let mut push = |outcome, truth: Option<i64>, track: Option<i64>| {
            self.decisions.push(Decision {
                scene,
                frame,
                outcome,
                truth: truth.map(|t| t as u64),
                track: track.map(|t| t as u64),
                xy: [f64::NAN; 2],
            })
        };
        for (gi, id) in gt_ids.enumerate() {
            let track = matched[gi].map(&tr_id);
            let outcome = match (ignored(gi), track) {
                (true, _) => Outcome::Ignored,
                (false, Some(_)) => Outcome::Match,
                (false, None) => Outcome::Miss,
            };
            push(outcome, Some(id), track);
        }
        for (col, &ign) in tr_ignored.iter().enumerate() {
            if !ign && !matched.contains(&Some(col)) {
                push(Outcome::FalsePositive, None, Some(tr_id(col)));
            }
        }
    }

    /// Records a KITTI trajectory error.
    pub(crate) fn record_mark(
        &mut self,
        scene: usize,
        truth: i64,
        position: usize,
        kind: MarkKind,
        track: i64,
        previous: i64,
    ) {
        self.marks.push(Mark {
            scene,
            truth: truth as u64,
            position,
            kind,
            track: track as u64,
            previous: previous.max(0) as u64,
        });
    }
}

/// Which protocol recorded a [`Collector`] (ids and rules differ).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Protocol {
    /// nuScenes: ids are the boxes' ids; fragmentations are derived here.
    Nuscenes,
    /// KITTI: truth ids are the label files' track ids; errors come as [`Mark`]s.
    Kitti,
}

/// How many events of each kind (the metrics' counts at the best-MOTA threshold).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct Counts {
    /// Matches (true positives).
    pub tp: u64,
    /// Identity switches.
    pub ids: u64,
    /// Fragmentations.
    pub frag: u64,
    /// False positives.
    pub fp: u64,
    /// Misses (false negatives).
    #[serde(rename = "fn")]
    pub fn_: u64,
}

/// One event as the evaluation keeps it until it is written: the fields of an [`EvalEvent`]
/// but its class, which the events of a class share (a long log has millions of events, and a
/// label string on each was a fifth of their memory).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Event {
    /// Match, miss, false positive, identity switch or fragmentation.
    pub kind: Kind,
    /// Ground-truth id (0: none).
    pub truth_id: u64,
    /// Track id (0: none).
    pub track_id: u64,
    /// The track paired before a switch or a fragmentation (0: none).
    pub previous_track_id: u64,
    /// Centre of the box the event is drawn as, metres.
    pub center: [f64; 3],
    /// Length, width, height, metres.
    pub size: [f64; 3],
    /// Heading, radians.
    pub yaw: f64,
}

impl Event {
    /// The message of this event of class `label`.
    pub fn message(&self, label: &str) -> EvalEvent {
        EvalEvent {
            kind: self.kind as i32,
            label: label.to_string(),
            truth_id: self.truth_id,
            track_id: self.track_id,
            previous_track_id: self.previous_track_id,
            center: Some(v3(self.center)),
            size: Some(size3(self.size)),
            yaw: self.yaw,
        }
    }
}

/// An event with the scene and frame it belongs to.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Located {
    /// Index of the scene (log).
    pub scene: usize,
    /// Index of the frame in the scene.
    pub frame: usize,
    /// The event (ids are the boxes' ids as the logs carry them).
    pub event: Event,
}

/// One class's events, in scene and frame order, and their counts.
#[derive(Debug, Clone, Default)]
pub struct ClassEvents {
    /// Class.
    pub class: String,
    /// Counts by kind.
    pub counts: Counts,
    /// Events.
    pub events: Vec<Located>,
}

/// The geometry and id of one box.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoxAt {
    /// The box's id as its message has it.
    pub id: u64,
    /// Centre, metres.
    pub center: [f64; 3],
    /// Length, width, height, metres.
    pub size: [f64; 3],
    /// Heading, radians.
    pub yaw: f64,
}

/// The evaluated logs as the events read them: names, frame stamps and box lookups
/// (implemented for whole scenes and for columns in [`super::event_boxes`]).
pub trait EventBoxes {
    /// Name of log `scene` (for the report).
    fn name(&self, scene: usize) -> &str;
    /// Stamp of frame `frame` of log `scene`, ns.
    fn stamp(&self, scene: usize, frame: usize) -> u64;
    /// Number of logs.
    fn logs(&self) -> usize;
    /// The truth box the protocol knows as `id` of `class` at `(scene, frame)` (KITTI: its
    /// KITTI track id, any class but DontCare).
    fn truth(&self, at: (usize, usize), id: u64, class: &str, p: Protocol) -> Option<BoxAt>;
    /// The track `id` at `(scene, frame)` (nuScenes: of `class`).
    fn track(&self, at: (usize, usize), id: u64, class: &str, p: Protocol) -> Option<BoxAt>;
}

/// Looks up the boxes of events in their logs.
struct Boxes<'a, B: EventBoxes + ?Sized> {
    logs: &'a B,
    class: &'a str,
    protocol: Protocol,
}

impl<B: EventBoxes + ?Sized> Boxes<'_, B> {
    /// The event of kind `kind` at `(scene, frame)`, its geometry from the truth box (else the
    /// track box, else the recorded position).
    fn event(&self, d: &Decision, kind: Kind, previous: u64) -> Located {
        let (at, class, p) = ((d.scene, d.frame), self.class, self.protocol);
        let truth = d.truth.and_then(|id| self.logs.truth(at, id, class, p));
        let track = d.track.and_then(|id| self.logs.track(at, id, class, p));
        let (center, size, yaw) = match truth.or(track) {
            Some(b) => (b.center, b.size, b.yaw),
            None => ([d.xy[0], d.xy[1], 0.0], [1.0; 3], 0.0),
        };
        let truth_id = match (self.protocol, truth, d.truth) {
            (Protocol::Kitti, Some(b), _) => b.id,
            (Protocol::Kitti, None, Some(t)) => t + 1,
            (_, _, t) => t.unwrap_or(0),
        };
        Located {
            scene: d.scene,
            frame: d.frame,
            event: Event {
                kind,
                truth_id,
                track_id: d.track.unwrap_or(0),
                previous_track_id: previous,
                center,
                size,
                yaw,
            },
        }
    }
}

/// Turns one class's record into located events (sorted by scene and frame) and counts them.
pub fn resolve<B: EventBoxes + ?Sized>(
    logs: &B,
    class: &str,
    log: &Collector,
    protocol: Protocol,
) -> ClassEvents {
    let boxes = Boxes {
        logs,
        class,
        protocol,
    };
    let mut out = ClassEvents {
        class: class.to_string(),
        ..Default::default()
    };
    // Per (scene, truth id), in the order recorded: (decision index, tracked).
    let mut order: Vec<(usize, u64)> = Vec::new();
    let mut seqs: HashMap<(usize, u64), Vec<(usize, bool)>> = HashMap::new();
    let mut last_track: HashMap<(usize, u64), u64> = HashMap::new();
    for (i, d) in log.decisions.iter().enumerate() {
        if let Some(t) = d.truth {
            let key = (d.scene, t);
            let seq = seqs.entry(key).or_insert_with(|| {
                order.push(key);
                Vec::new()
            });
            seq.push((i, matches!(d.outcome, Outcome::Match | Outcome::Switch)));
        }
        let (kind, previous) = match d.outcome {
            // An ignored object paired with a track is a true positive of KITTI's count.
            Outcome::Ignored if d.track.is_none() => continue,
            Outcome::Ignored => {
                out.counts.tp += 1;
                (Kind::Match, 0)
            }
            Outcome::Match => {
                out.counts.tp += 1;
                (Kind::Match, 0)
            }
            Outcome::Switch => {
                out.counts.ids += 1;
                let key = (d.scene, d.truth.unwrap_or(0));
                (Kind::Switch, last_track.get(&key).copied().unwrap_or(0))
            }
            Outcome::Miss => {
                out.counts.fn_ += 1;
                (Kind::Miss, 0)
            }
            Outcome::FalsePositive => {
                out.counts.fp += 1;
                (Kind::FalsePositive, 0)
            }
        };
        if let (Some(t), Some(h)) = (d.truth, d.track) {
            last_track.insert((d.scene, t), h);
        }
        out.events.push(boxes.event(d, kind, previous));
    }
    match protocol {
        Protocol::Nuscenes => nuscenes_fragmentations(&boxes, log, &order, &seqs, &mut out),
        Protocol::Kitti => kitti_marks(&boxes, log, &seqs, &mut out),
    }
    out.events.sort_by_key(|e| (e.scene, e.frame));
    out
}

/// The devkit's fragmentations: along each object's sequence, between its first and last tracked
/// frame, every frame where it is missed right after being tracked; the event names the track
/// it was paired with just before.
fn nuscenes_fragmentations<B: EventBoxes + ?Sized>(
    boxes: &Boxes<'_, B>,
    log: &Collector,
    order: &[(usize, u64)],
    seqs: &HashMap<(usize, u64), Vec<(usize, bool)>>,
    out: &mut ClassEvents,
) {
    for key in order {
        let seq = &seqs[key];
        let (Some(first), Some(last)) =
            (seq.iter().position(|s| s.1), seq.iter().rposition(|s| s.1))
        else {
            continue;
        };
        for k in first + 1..=last {
            if !seq[k].1 && seq[k - 1].1 {
                out.counts.frag += 1;
                let lost = log.decisions[seq[k - 1].0].track.unwrap_or(0);
                let d = log.decisions[seq[k].0];
                out.events.push(boxes.event(&d, Kind::Fragmentation, lost));
            }
        }
    }
}

/// KITTI's switches and fragmentations, placed at the frame of their trajectory position.
fn kitti_marks<B: EventBoxes + ?Sized>(
    boxes: &Boxes<'_, B>,
    log: &Collector,
    seqs: &HashMap<(usize, u64), Vec<(usize, bool)>>,
    out: &mut ClassEvents,
) {
    for m in &log.marks {
        let Some(&(i, _)) = seqs
            .get(&(m.scene, m.truth))
            .and_then(|s| s.get(m.position))
        else {
            continue;
        };
        let d = Decision {
            track: Some(m.track),
            ..log.decisions[i]
        };
        let kind = match m.kind {
            MarkKind::Switch => {
                out.counts.ids += 1;
                Kind::Switch
            }
            MarkKind::Fragmentation => {
                out.counts.frag += 1;
                Kind::Fragmentation
            }
        };
        out.events.push(boxes.event(&d, kind, m.previous));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eval::scene::Scene;
    use crate::mcapio::LabelledBox;

    fn gt(id: u64, x: f64) -> LabelledBox {
        LabelledBox {
            id,
            label: "car".into(),
            center: [x, 0.0, 0.0],
            size: [4.0, 2.0, 1.5],
            score: 1.0,
            ..Default::default()
        }
    }

    /// A class with ground truth that no track ever matches: the metrics count every box as
    /// missed (the devkit's worst case), and so do the events.
    #[test]
    fn a_class_no_track_matches_has_every_truth_box_missed() {
        use crate::eval::nuscenes::{evaluate_recording, NuscenesParams};
        let scene = Scene {
            name: "s".into(),
            frames: (0..5).map(|i| (i, vec![gt(1, i as f64)], vec![])).collect(),
        };
        let p = NuscenesParams::default();
        let scenes = [scene];
        let (result, logs) = evaluate_recording(&scenes, &p, true);
        let metrics = result.classes["car"];
        assert_eq!(metrics.fn_, 5.0);
        let (_, log) = logs.iter().find(|(c, _)| c == "car").unwrap();
        let c = resolve(&scenes[..], "car", log, Protocol::Nuscenes).counts;
        assert_eq!((c.tp, c.ids, c.frag, c.fp, c.fn_), (0, 0, 0, 0, 5));
    }

    /// docs/eval.md and BENCHMARKS.md quote this size: an event holds no heap memory.
    #[test]
    fn an_event_is_88_bytes() {
        assert_eq!(std::mem::size_of::<Event>(), 88);
    }

    #[test]
    fn nuscenes_switch_names_the_previous_track_and_a_gap_is_a_fragmentation() {
        let scene = Scene {
            name: "s".into(),
            frames: (0..5).map(|i| (i, vec![gt(1, i as f64)], vec![])).collect(),
        };
        let mut log = Collector::default();
        let t = |id| Some((id, (0.0, 0.0, 1.0)));
        let g = Some((1, 0.0, 0.0));
        log.record_association(0, 0, EventKind::Match, g, t(10));
        log.record_association(0, 1, EventKind::Miss, g, None);
        log.record_association(0, 2, EventKind::Switch, g, t(11));
        log.record_association(0, 3, EventKind::Miss, g, None);
        log.record_association(0, 4, EventKind::FalsePositive, None, t(12));
        let r = resolve(&[scene][..], "car", &log, Protocol::Nuscenes);
        let c = r.counts;
        assert_eq!((c.tp, c.ids, c.frag, c.fp, c.fn_), (1, 1, 1, 1, 2));
        let sw = r.events.iter().find(|e| e.event.kind == Kind::Switch);
        let sw = sw.unwrap();
        assert_eq!((sw.frame, sw.event.previous_track_id), (2, 10));
        assert_eq!(sw.event.center[0], 2.0, "geometry of the truth box");
        // The miss after the last tracked frame is not a fragmentation; the one between is.
        let fr: Vec<_> = r
            .events
            .iter()
            .filter(|e| e.event.kind == Kind::Fragmentation)
            .map(|e| (e.frame, e.event.previous_track_id))
            .collect();
        assert_eq!(fr, vec![(1, 10)]);
    }
}
