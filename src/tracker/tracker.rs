//! The tracker state machine: feed it one frame at a time, get the reported tracks back.

use std::collections::HashMap;

use super::boxes::{Box3, ClassId, Detection};
use super::confidence::Confidence;
use super::config::{ClassConfig, ConfigError, DistanceKind, MatcherKind, TrackerConfig};
use super::geometry::{giou3d, iou3d};
use super::kalman::{mahalanobis_sq, mahalanobis_sq_xy, Innovation, KalmanState, Noise};
use super::levers::{Coast, Levers};
use super::matching::{greedy, hungarian, Pair, NOT_A_CANDIDATE};
use super::nms::{suppress, NmsScratch};
use super::track::{ReportStatus, Track, TrackReport};
use super::two_point;
use super::two_stage::split;

/// Why a frame was refused. The tracker state is unchanged when an error is returned.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum StepError {
    /// Frames must come with strictly increasing stamps.
    #[error("frame stamp {stamp} ns is not after the previous frame's stamp {previous} ns")]
    NonIncreasingStamp {
        /// The refused stamp.
        stamp: u64,
        /// The last accepted stamp.
        previous: u64,
    },
    /// A detection refers to a class id the tracker never handed out.
    #[error("detection {index} has unknown class id {class}")]
    UnknownClass {
        /// Index of the detection in the frame.
        index: usize,
        /// The class id.
        class: ClassId,
    },
    /// A detection with a non-finite field or a non-positive size.
    #[error("detection {index} has a non-finite value or a non-positive size: {bbox:?}")]
    InvalidDetection {
        /// Index of the detection in the frame.
        index: usize,
        /// The box.
        bbox: Box3,
    },
}

/// Counters over a run.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct TrackerStats {
    /// Frames processed.
    pub frames: u64,
    /// Detections given to the tracker (after the score floor).
    pub detections: u64,
    /// Detections dropped by a class's score floor.
    pub below_score_floor: u64,
    /// Tracks started (one per unmatched detection).
    pub born: u64,
    /// Tracks that reached `min_hits`.
    pub confirmed: u64,
    /// Sum of reported frames over confirmed tracks that have died.
    pub confirmed_reported_frames_of_dead: u64,
    /// Confirmed tracks that have died.
    pub confirmed_dead: u64,
    /// Tracks ended because their state or a variance left [`super::bounds`] (a long coast,
    /// a huge gap between frames).
    pub beyond_bounds: u64,
}

struct ClassState {
    label: String,
    cfg: ClassConfig,
    noise: Noise,
    tracks: Vec<Track>,
    dets: Vec<u32>,
}

#[derive(Default)]
struct Scratch {
    pairs: Vec<Pair>,
    cost: Vec<f64>,
    det_taken: Vec<bool>,
    trk_taken: Vec<bool>,
    matches: Vec<(u32, u32)>,
    matched_det: Vec<bool>,
    track_match: Vec<Option<u32>>,
    pred: Vec<Box3>,
    /// The innovation of each track of the class being associated (Mahalanobis distance).
    innovations: Vec<Innovation>,
    /// Tracks matched by the first round of a two-stage association.
    trk_matched: Vec<bool>,
    /// One round's optimal assignment, before its detection indices are offset.
    round: Vec<(u32, u32)>,
    nms: NmsScratch,
}

/// Up to this many classes, [`Tracker::class_id`] scans the labels instead of hashing.
const LINEAR_LABEL_LOOKUP: usize = 16;

/// The probabilistic 3D multi-object tracker of Chiu et al. (2019), as a sans-I/O state machine.
///
/// ```
/// use probmot::tracker::{Box3, Detection, Tracker, TrackerConfig};
///
/// let mut tracker = Tracker::new(TrackerConfig::preset("nuscenes-chiu2019").unwrap()).unwrap();
/// let car = tracker.class_id("car").unwrap();
/// let mut reported = 0;
/// for frame in 0..5u64 {
///     let det = Detection {
///         bbox: Box3 { center: [frame as f64, 0.0, 0.0], yaw: 0.0, size: [4.0, 2.0, 1.5] },
///         class: car,
///         score: 0.9,
///     };
///     // nuScenes keyframes: 0.5 s apart.
///     let tracks = tracker.step(frame * 500_000_000, &[det]).unwrap();
///     reported = tracks.len();
///     assert!(tracks.iter().all(|t| t.id == 1));
/// }
/// assert_eq!(reported, 1);
/// ```
pub struct Tracker {
    config: TrackerConfig,
    classes: Vec<ClassState>,
    by_label: HashMap<String, ClassId>,
    frame_count: u64,
    last_stamp: Option<u64>,
    next_id: u64,
    reports: Vec<TrackReport>,
    deleted: Vec<u64>,
    stats: TrackerStats,
    scratch: Scratch,
}

impl Tracker {
    /// A tracker for a validated configuration.
    pub fn new(config: TrackerConfig) -> Result<Self, ConfigError> {
        config.validate()?;
        let mut t = Tracker {
            config,
            classes: Vec::new(),
            by_label: HashMap::new(),
            frame_count: 0,
            last_stamp: None,
            next_id: 1,
            reports: Vec::new(),
            deleted: Vec::new(),
            stats: TrackerStats::default(),
            scratch: Scratch::default(),
        };
        // Listed classes get ids in config order so that output order is stable.
        let labels: Vec<String> = t.config.classes.keys().cloned().collect();
        for l in labels {
            t.class_id(&l);
        }
        Ok(t)
    }

    /// The configuration in use.
    pub fn config(&self) -> &TrackerConfig {
        &self.config
    }

    /// The class id of a label, registering it on first use. `None` when the label is not in the
    /// config and the config has no `default` entry.
    pub fn class_id(&mut self, label: &str) -> Option<ClassId> {
        // With a handful of classes, comparing the labels is cheaper than hashing one (the hash
        // showed in profiles of `track`); the map serves logs with many labels.
        let known = if self.classes.len() <= LINEAR_LABEL_LOOKUP {
            self.classes
                .iter()
                .position(|c| c.label == label)
                .map(|i| i as ClassId)
        } else {
            self.by_label.get(label).copied()
        };
        if known.is_some() {
            return known;
        }
        let cfg = self.config.class(label)?.clone();
        let id = self.classes.len() as ClassId;
        self.classes.push(ClassState {
            label: label.to_string(),
            noise: Noise::from_diagonals(&cfg.q, &cfg.r, &cfg.p0, cfg.angular_velocity)
                .with_motion(cfg.levers.motion),
            cfg,
            tracks: Vec::new(),
            dets: Vec::new(),
        });
        self.by_label.insert(label.to_string(), id);
        Some(id)
    }

    /// The label of a class id.
    pub fn label(&self, class: ClassId) -> &str {
        &self.classes[class as usize].label
    }

    /// The tracks reported by the last [`Tracker::step`].
    pub fn reports(&self) -> &[TrackReport] {
        &self.reports
    }

    /// Ids of the tracks deleted during the last [`Tracker::step`].
    pub fn deleted(&self) -> &[u64] {
        &self.deleted
    }

    /// Run counters.
    pub fn stats(&self) -> TrackerStats {
        self.stats
    }

    /// Mean number of reported frames per confirmed track, counting live tracks too.
    pub fn mean_confirmed_track_length(&self) -> Option<f64> {
        let (mut n, mut sum) = (
            self.stats.confirmed_dead,
            self.stats.confirmed_reported_frames_of_dead,
        );
        for c in &self.classes {
            for t in c.tracks.iter().filter(|t| t.confirmed) {
                n += 1;
                sum += t.reported_frames as u64;
            }
        }
        (n > 0).then(|| sum as f64 / n as f64)
    }

    /// Number of live tracks (tentative, confirmed and coasting).
    pub fn live_tracks(&self) -> usize {
        self.classes.iter().map(|c| c.tracks.len()).sum()
    }

    /// Processes one frame: predicts every class to `stamp_ns`, associates each class's
    /// detections with its tracks, updates, starts and deletes tracks, and returns the reported
    /// tracks in a stable order (class id, then track age). `detections[i].class` must come from
    /// [`Tracker::class_id`].
    pub fn step(
        &mut self,
        stamp_ns: u64,
        detections: &[Detection],
    ) -> Result<&[TrackReport], StepError> {
        let k = match self.last_stamp {
            Some(prev) if stamp_ns <= prev => {
                return Err(StepError::NonIncreasingStamp {
                    stamp: stamp_ns,
                    previous: prev,
                })
            }
            Some(prev) => Some((stamp_ns - prev) as f64 * 1e-9 / self.config.dt_nominal),
            None => None,
        };
        for (index, d) in detections.iter().enumerate() {
            if d.class as usize >= self.classes.len() {
                return Err(StepError::UnknownClass {
                    index,
                    class: d.class,
                });
            }
            if !d.bbox.is_valid() || !d.score.is_finite() {
                return Err(StepError::InvalidDetection {
                    index,
                    bbox: d.bbox,
                });
            }
        }
        self.last_stamp = Some(stamp_ns);
        self.frame_count += 1;
        self.stats.frames += 1;
        self.reports.clear();
        self.deleted.clear();

        for c in &mut self.classes {
            c.dets.clear();
        }
        for (i, d) in detections.iter().enumerate() {
            let c = &mut self.classes[d.class as usize];
            if c.cfg.score_floor.is_some_and(|f| d.score < f) {
                self.stats.below_score_floor += 1;
                continue;
            }
            c.dets.push(i as u32);
            self.stats.detections += 1;
        }

        for c in &mut self.classes {
            step_class(
                c,
                k,
                detections,
                self.frame_count,
                self.config.dt_nominal,
                &mut self.next_id,
                &mut self.scratch,
                &mut self.reports,
                &mut self.deleted,
                &mut self.stats,
            );
        }
        Ok(&self.reports)
    }
}

/// One frame of one class: predict, associate (NMS and two-stage rounds as configured), update,
/// birth, report, delete.
#[allow(clippy::too_many_arguments)]
fn step_class(
    c: &mut ClassState,
    k: Option<f64>,
    all_dets: &[Detection],
    frame_count: u64,
    dt_nominal: f64,
    next_id: &mut u64,
    s: &mut Scratch,
    reports: &mut Vec<TrackReport>,
    deleted: &mut Vec<u64>,
    stats: &mut TrackerStats,
) {
    // Predict every track of the class, also when the class has no detection this frame.
    if let Some(k) = k {
        for t in &mut c.tracks {
            t.kf.predict(k, &c.noise);
            t.age += 1;
            t.time_since_update += 1;
        }
    }

    if let Some(max_iou) = c.cfg.levers.nms_iou {
        suppress(&mut c.dets, all_dets, max_iou, &mut s.nms);
    }
    // Two-stage association: detections under the birth score come last and only get a 2nd round.
    let n_high = split(&mut c.dets, all_dets, c.cfg.levers.birth_score);
    let n_det = c.dets.len();
    let n_trk = c.tracks.len();
    s.matches.clear();
    s.trk_matched.clear();
    s.trk_matched.resize(n_trk, false);
    if n_det > 0 && n_trk > 0 {
        associate(c, all_dets, s, 0, n_high);
        if n_high < n_det {
            for &(_, t) in &s.matches {
                s.trk_matched[t as usize] = true;
            }
            associate(c, all_dets, s, n_high, n_det);
        }
    }
    update_matched(c, all_dets, s);
    if let (Some(speed), Some(k)) = (c.cfg.levers.two_point_speed, k) {
        two_point_round(c, all_dets, s, n_high, k, speed * k * dt_nominal);
    }
    birth(c, all_dets, s, n_high, next_id, stats);
    report_and_delete(c, frame_count, dt_nominal, s, reports, deleted, stats);
}

/// Kalman update of every matched track with its detection.
fn update_matched(c: &mut ClassState, all_dets: &[Detection], s: &mut Scratch) {
    let (n_det, n_trk) = (c.dets.len(), c.tracks.len());
    s.matched_det.clear();
    s.matched_det.resize(n_det, false);
    s.track_match.clear();
    s.track_match.resize(n_trk, None);
    for &(d, t) in &s.matches {
        let det = &all_dets[c.dets[d as usize] as usize];
        let trk = &mut c.tracks[t as usize];
        trk.kf.update(&det.bbox.to_origin(c.cfg.origin), &c.noise);
        count_match(trk, det.score, &c.cfg.levers);
        s.matched_det[d as usize] = true;
        s.track_match[t as usize] = Some(c.dets[d as usize]);
    }
}

/// The life-cycle side of a match (the filter is updated by the caller): a hit, the score.
fn count_match(trk: &mut Track, score: f64, levers: &Levers) {
    trk.hits += 1;
    trk.time_since_update = 0;
    trk.score = score;
    trk.conf.on_match(score, levers);
}

/// The two-point round ([`super::two_point`]): unmatched detections of the first round continue
/// tracks born in the previous frame within `radius` metres, nearest first; each such track
/// restarts with the velocity of its two detections.
fn two_point_round(
    c: &mut ClassState,
    all_dets: &[Detection],
    s: &mut Scratch,
    n_high: usize,
    k: f64,
    radius: f64,
) {
    two_point::candidates(
        &c.tracks,
        &c.dets,
        all_dets,
        &s.matched_det,
        n_high,
        radius,
        &mut s.pairs,
    );
    if s.pairs.is_empty() {
        return;
    }
    s.round.clear();
    let (n_det, n_trk) = (c.dets.len(), c.tracks.len());
    greedy(
        &mut s.pairs,
        radius,
        &mut s.det_taken,
        &mut s.trk_taken,
        n_det,
        n_trk,
        &mut s.round,
    );
    for &(d, t) in &s.round {
        let det = &all_dets[c.dets[d as usize] as usize];
        let trk = &mut c.tracks[t as usize];
        trk.kf
            .restart_two_point(&det.bbox.to_origin(c.cfg.origin), k, &c.noise);
        count_match(trk, det.score, &c.cfg.levers);
        s.matched_det[d as usize] = true;
        s.track_match[t as usize] = Some(c.dets[d as usize]);
    }
}

/// Birth: every unmatched detection of the first round (index under `n_high`) starts a track.
fn birth(
    c: &mut ClassState,
    all_dets: &[Detection],
    s: &mut Scratch,
    n_high: usize,
    next_id: &mut u64,
    stats: &mut TrackerStats,
) {
    for (d, &det_index) in c.dets.iter().enumerate() {
        if s.matched_det[d] || d >= n_high {
            continue;
        }
        let det = &all_dets[det_index as usize];
        c.tracks.push(Track {
            id: *next_id,
            class: det.class,
            kf: KalmanState::new(&det.bbox.to_origin(c.cfg.origin), &c.noise),
            hits: 1,
            age: 0,
            time_since_update: 0,
            score: det.score,
            reported_frames: 0,
            confirmed: false,
            conf: Confidence::born(det.score),
            beyond_bounds: false,
        });
        s.track_match.push(Some(det_index));
        *next_id += 1;
        stats.born += 1;
    }
}

/// Report the tracks the life cycle shows, then delete the ones past `max_age` (unless kept
/// alive by their confidence).
fn report_and_delete(
    c: &mut ClassState,
    frame_count: u64,
    dt_nominal: f64,
    s: &Scratch,
    reports: &mut Vec<TrackReport>,
    deleted: &mut Vec<u64>,
    stats: &mut TrackerStats,
) {
    let min_hits = c.cfg.min_hits;
    let max_age = c.cfg.max_age;
    let levers = &c.cfg.levers;
    for (t, m) in c.tracks.iter_mut().zip(&s.track_match) {
        if m.is_none() {
            t.conf.on_coast(levers);
        }
        if !t.confirmed && t.hits >= min_hits {
            t.confirmed = true;
            stats.confirmed += 1;
        }
        if t.time_since_update >= max_age {
            continue;
        }
        // One report per track and frame: checked against the bounds, then handed out.
        let mut r = t.report(dt_nominal, c.cfg.origin, *m);
        if !r.within_bounds() {
            t.beyond_bounds = true;
            stats.beyond_bounds += 1;
            continue;
        }
        let shown = t.hits >= min_hits || frame_count <= min_hits as u64;
        if let Some(status) = report_status(levers, shown, m.is_none()) {
            t.reported_frames += u32::from(status != ReportStatus::Hidden);
            r.score = t.conf.reported(t.score, levers);
            r.status = status;
            reports.push(r);
        }
    }
    c.tracks.retain(|t| {
        let keep =
            !t.beyond_bounds && (t.time_since_update < max_age || t.conf.keeps_alive(levers));
        if !keep {
            deleted.push(t.id);
            if t.confirmed {
                stats.confirmed_dead += 1;
                stats.confirmed_reported_frames_of_dead += t.reported_frames as u64;
            }
        }
        keep
    });
}

/// How a live track within `max_age` is reported this frame: `shown` is the paper's rule
/// (`min_hits` reached, or one of the first `min_hits` frames), `coasted` a frame without a
/// match. `None`: not reported.
fn report_status(levers: &Levers, shown: bool, coasted: bool) -> Option<ReportStatus> {
    if coasted && levers.coast == Coast::None {
        // A tentative track stays open in the lookback through the frames it is not shown.
        (!shown && levers.backfill).then_some(ReportStatus::Hidden)
    } else if !shown {
        levers.backfill.then_some(ReportStatus::Tentative)
    } else if coasted && levers.coast == Coast::Gaps {
        Some(ReportStatus::Coasting)
    } else {
        Some(ReportStatus::Final)
    }
}

/// One association round: detections `lo..hi` of the class against the tracks not matched by an
/// earlier round; the matches are appended to `s.matches`.
fn associate(c: &mut ClassState, all_dets: &[Detection], s: &mut Scratch, lo: usize, hi: usize) {
    if lo == hi {
        return;
    }
    let n_det = c.dets.len();
    let n_trk = c.tracks.len();
    candidate_pairs(c, all_dets, s, lo, hi);
    let max_cost = if c.cfg.distance.is_similarity() {
        -c.cfg.threshold
    } else {
        c.cfg.threshold
    };
    match c.cfg.matcher {
        MatcherKind::Greedy => greedy(
            &mut s.pairs,
            max_cost,
            &mut s.det_taken,
            &mut s.trk_taken,
            n_det,
            n_trk,
            &mut s.matches,
        ),
        MatcherKind::Hungarian => {
            let rows = hi - lo;
            s.cost.clear();
            s.cost.resize(rows * n_trk, NOT_A_CANDIDATE);
            for p in &s.pairs {
                s.cost[(p.det as usize - lo) * n_trk + p.trk as usize] = p.cost;
            }
            s.round.clear();
            hungarian(&s.cost, rows, n_trk, max_cost, &mut s.round);
            s.matches
                .extend(s.round.iter().map(|&(d, t)| (d + lo as u32, t)));
        }
    }
}

/// Fills `s.pairs` with the candidate pairs of detections `lo..hi` of a class and the tracks not
/// yet matched: each pair that passes the cheap pre-gate, with its full cost. Pairs cut by the
/// pre-gate could never be matched. With `gate_after_assignment` and the Hungarian matcher every
/// such pair is a candidate: the assignment is solved over all of them and the gate applied
/// afterwards.
fn candidate_pairs(
    c: &mut ClassState,
    all_dets: &[Detection],
    s: &mut Scratch,
    lo: usize,
    hi: usize,
) {
    s.pairs.clear();
    let cfg = &c.cfg;
    let thr = cfg.threshold;
    let origin = cfg.origin;
    let all = cfg.gate_after_assignment && cfg.matcher == MatcherKind::Hungarian;
    let mut push = |cost: f64, d: usize, t: usize| {
        s.pairs.push(Pair {
            cost,
            det: d as u32,
            trk: t as u32,
        })
    };
    match cfg.distance {
        DistanceKind::Mahalanobis => {
            s.innovations.clear();
            s.innovations
                .extend(c.tracks.iter().map(|t| t.kf.innovation(&c.noise)));
            let g2 = thr * thr;
            for (d, &di) in c.dets.iter().enumerate().take(hi).skip(lo) {
                let b = all_dets[di as usize].bbox.to_origin(origin);
                for (ti, inn) in s.innovations.iter().enumerate() {
                    if s.trk_matched[ti] {
                        continue;
                    }
                    // Pre-gate: the x and y terms alone already exceed the gate.
                    if !all && mahalanobis_sq_xy(inn, &b) > g2 {
                        continue;
                    }
                    push(mahalanobis_sq(inn, &b).sqrt(), d, ti);
                }
            }
        }
        DistanceKind::Center | DistanceKind::Dist3d => {
            let in_3d = cfg.distance == DistanceKind::Dist3d;
            s.pred.clear();
            s.pred.extend(
                c.tracks
                    .iter()
                    .map(|t| Box3::from_slice(t.kf.x.as_slice()).from_origin(origin)),
            );
            for (d, &di) in c.dets.iter().enumerate().take(hi).skip(lo) {
                let b = &all_dets[di as usize].bbox;
                for (ti, p) in s.pred.iter().enumerate() {
                    if s.trk_matched[ti] {
                        continue;
                    }
                    let dx = b.center[0] - p.center[0];
                    let dy = b.center[1] - p.center[1];
                    let dz = if in_3d {
                        b.center[2] - p.center[2]
                    } else {
                        0.0
                    };
                    let dist = (dx * dx + dy * dy + dz * dz).sqrt();
                    if all || dist <= thr {
                        push(dist, d, ti);
                    }
                }
            }
        }
        DistanceKind::Iou3d | DistanceKind::Giou3d => {
            s.pred.clear();
            s.pred.extend(
                c.tracks
                    .iter()
                    .map(|t| Box3::from_slice(t.kf.x.as_slice()).from_origin(origin)),
            );
            let giou = cfg.distance == DistanceKind::Giou3d;
            for (d, &di) in c.dets.iter().enumerate().take(hi).skip(lo) {
                let b = &all_dets[di as usize].bbox;
                for (ti, p) in s.pred.iter().enumerate() {
                    if s.trk_matched[ti] {
                        continue;
                    }
                    let sim = if giou {
                        giou3d(b, p)
                    } else {
                        // iou3d itself skips pairs whose footprints cannot touch.
                        iou3d(b, p)
                    };
                    if all || sim >= thr {
                        push(-sim, d, ti);
                    }
                }
            }
        }
    }
}
