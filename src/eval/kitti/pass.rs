//! One pass over a class's data at one score threshold: per-frame matching, then the counts
//! along every ground-truth trajectory. Buffers live in [`ClassEval`] and are reused.
//!
//! The matching of a frame is the reference's Munkres on `1 - IoU3D` over the kept tracks,
//! forbidden pairs costing `MAX_COST`. When no kept ground truth or track has more than one
//! feasible pair, every feasible pair is matched without running it: any assignment leaving
//! such a pair out costs at least `MAX_COST - 1` more than one taking it (swap the forbidden
//! pairs it uses for the feasible one and one other), far beyond rounding, so the Munkres takes
//! them all, and the rest of its assignment is forbidden pairs, which count nothing but misses.
//! Other frames (rare: 42 in 100 000 on KITTI) run the Munkres on the same matrix as before.
//!
//! A frame whose kept tracks are those of the previous pass gives the previous pass's counts
//! (the matching depends only on the kept set, and the rows' `valid` flags changed only by that
//! same matching), so they are replayed from [`FrameMemo`], the cost sums in the same order.

use std::cmp::Ordering;

use super::munkres::Munkres;
use super::prepare::{ClassTruth, GtObj, TruthSeq};
use super::tracks::{Edge, SeqTracks, TrObj};
use super::{MeanScores, MAX_COST};
use crate::eval::bootstrap::curve::UnitCounts;
use crate::eval::bootstrap::Units;
use crate::eval::events::{Collector, MarkKind};

/// Counts and derived metrics of one pass over the data at one threshold.
#[derive(Debug, Clone, Default)]
pub(super) struct Pass {
    pub tp: u64,
    pub itp: u64,
    pub fp: u64,
    pub fn_: u64,
    pub ifn: u64,
    pub ids: u64,
    pub frag: u64,
    /// Ground truth minus ignored.
    pub n_gt: u64,
    pub n_igt: u64,
    pub n_tr: u64,
    pub n_itr: u64,
    pub mt: f64,
    pub pt: f64,
    pub ml: f64,
    pub mota: f64,
    pub moda: f64,
    pub motal: f64,
    pub smota: f64,
    pub motp: f64,
    pub modp: f64,
    pub recall: f64,
    pub precision: f64,
    pub f1: f64,
    pub far: f64,
    /// Mean scores of the matched boxes, in matching order.
    pub scores: Vec<f64>,
    /// Whether a track was kept or dropped otherwise than its first mean score says (the
    /// re-averaging drift of [`MeanScores::EveryPass`]).
    pub drifted: bool,
}

/// Sums a pass carries besides [`Pass`]'s counts.
#[derive(Debug, Default)]
struct Tally {
    total_cost: f64,
    modp_sum: f64,
    n_frames: usize,
    pub mt: u64,
    pub pt: u64,
    pub ml: u64,
    n_ignored_traj: u64,
}

/// What one frame added to a pass, kept to be replayed while its kept tracks do not change.
#[derive(Debug, Default)]
struct FrameMemo {
    /// Whether the fields below are those of the frame's kept tracks of the last pass.
    fresh: bool,
    /// Added to `n_gt, n_igt, n_tr, n_itr, tp, itp, fp, fn_, ifn`.
    counts: [u64; 9],
    /// `1 - cost` of each match, in matching order (added to the total cost).
    ious: Vec<f64>,
    /// Added to the MODP sum.
    modp: f64,
    /// The matched track id (or -1) of each ground truth.
    assigned: Vec<i64>,
}

impl FrameMemo {
    /// Adds the frame's counts and sums to the pass.
    fn apply(&self, r: &mut Pass, t: &mut Tally) {
        let c = &self.counts;
        r.n_gt += c[0];
        r.n_igt += c[1];
        r.n_tr += c[2];
        r.n_itr += c[3];
        r.tp += c[4];
        r.itp += c[5];
        r.fp += c[6];
        r.fn_ += c[7];
        r.ifn += c[8];
        for &v in &self.ious {
            t.total_cost += v;
        }
        t.modp_sum += self.modp;
    }

    /// Adds the frame's counts to its resampling unit's.
    fn apply_unit(&self, u: &mut UnitCounts) {
        let c = &self.counts;
        u.gt += c[0] as f64;
        u.tp += c[4] as f64;
        u.fp += c[6] as f64;
        u.fn_ += c[7] as f64;
        u.sim += self.ious.iter().sum::<f64>();
    }
}

/// "Not kept" in [`Scratch::col_of`].
const NONE: u32 = u32::MAX;

/// Per-frame working buffers.
#[derive(Debug, Default)]
struct Scratch {
    munkres: Munkres,
    pairs: Vec<(usize, usize)>,
    /// Kept track rows (indices in the frame), in order: column `c` is row `kept[c]`.
    kept: Vec<u32>,
    /// Per track row of the frame, its column among the kept ones, or [`NONE`].
    col_of: Vec<u32>,
    /// The feasible pairs among the kept tracks: `(ground truth, column, cost)`.
    feasible: Vec<(u32, u32, f64)>,
    row_deg: Vec<u8>,
    col_deg: Vec<u8>,
    cost: Vec<f64>,
    /// Per ground truth, its matched column and the pair's cost.
    matched: Vec<Option<usize>>,
    matched_cost: Vec<f64>,
    tmpcs: Vec<f64>,
    tr_ignored: Vec<bool>,
    sums: Vec<ScoreSum>,
    /// Along one trajectory: matched track ids and ignore flags.
    traj_ids: Vec<i64>,
    traj_ignored: Vec<bool>,
    /// The frames of a scene's identity switches, in counting order.
    switch_frames: Vec<u32>,
}

/// One class's tracks against its truth, and the state the reference carries from one
/// threshold to the next.
pub(super) struct ClassEval<'a> {
    pub truth: &'a ClassTruth,
    pub seqs: Vec<SeqTracks>,
    /// Where the decisions of a pass are recorded (`eval --events`), when set.
    pub log: Option<Collector>,
    /// With resampling units (`eval --bootstrap`): each unit's counts of the last pass.
    pub units: Option<(&'a Units, Vec<UnitCounts>)>,
    /// Per scene, per frame: its share of the last pass.
    memos: Vec<Vec<FrameMemo>>,
    scratch: Scratch,
    /// When the tracks' mean scores are computed.
    means: MeanScores,
    /// Whether the first pass has averaged the scores.
    averaged: bool,
    /// [`MeanScores::EveryPass`]: per scene, per track slot, its mean score after the first
    /// pass (to see the drift).
    first_means: Vec<Vec<f64>>,
}

impl<'a> ClassEval<'a> {
    /// The evaluation of prepared tracks against `truth`.
    pub(super) fn new(truth: &'a ClassTruth, seqs: Vec<SeqTracks>, means: MeanScores) -> Self {
        let memos = truth.seqs.iter().map(|t| {
            let frames = t.frames.iter();
            frames.map(|_| FrameMemo::default()).collect()
        });
        ClassEval {
            truth,
            seqs,
            log: None,
            units: None,
            memos: memos.collect(),
            scratch: Scratch::default(),
            means,
            averaged: false,
            first_means: Vec::new(),
        }
    }

    /// The tracks, as the passes left them.
    pub(super) fn into_seqs(self) -> Vec<SeqTracks> {
        self.seqs
    }

    /// One pass at `threshold` (tracks whose mean score is below it are dropped), with sMOTA at
    /// `recall_point`; with `scores`, [`Pass::scores`] is filled.
    pub(super) fn pass(&mut self, threshold: f64, recall_point: f64, scores: bool) -> Pass {
        let mut r = Pass::default();
        let mut t = Tally::default();
        if let Some((_, tally)) = self.units.as_mut() {
            tally.iter_mut().for_each(|u| *u = UnitCounts::default());
        }
        let s = &mut self.scratch;
        let first_pass = !self.averaged;
        self.averaged = true;
        let every_pass = self.means.every_pass();
        let compensated = self.means.compensated();
        let seqs = self.seqs.iter_mut().zip(&self.truth.seqs);
        for (si, ((seq, truth), memos)) in seqs.zip(&mut self.memos).enumerate() {
            t.n_frames += truth.frames.len();
            if first_pass || every_pass {
                average_scores(seq, &mut s.sums, compensated);
            }
            if first_pass && every_pass {
                let mut means = vec![f64::NAN; seq.n_tracks];
                for row in &seq.rows {
                    means[row.slot as usize] = row.score;
                }
                self.first_means.push(means);
            }
            // Averaged once, the scores are the first means: nothing can drift.
            let first_means = self.first_means.get(si).map(Vec::as_slice);
            for (fi, (f, memo)) in truth.frames.iter().zip(memos.iter_mut()).enumerate() {
                let (rows, edges) = seq.frame(fi);
                let (changed, drifted) = update_kept(rows, threshold, first_means);
                r.drifted |= drifted;
                if changed || !memo.fresh || scores || self.log.is_some() {
                    let scores = scores.then_some(&mut r.scores);
                    match_frame((&f.gt, &mut *rows, edges), s, memo, scores);
                }
                memo.apply(&mut r, &mut t);
                if let Some((units, tally)) = self.units.as_mut() {
                    memo.apply_unit(&mut tally[units.unit(si, fi)]);
                }
                if let Some(log) = self.log.as_mut() {
                    record_frame(log, (si, fi), &f.gt, rows, s);
                }
            }
            let log = self.log.as_mut().map(|l| (l, si));
            s.switch_frames.clear();
            count_trajectories(truth, memos, s, (&mut r, &mut t), log);
            if let Some((units, tally)) = self.units.as_mut() {
                for &fi in &s.switch_frames {
                    tally[units.unit(si, fi as usize)].ids += 1.0;
                }
            }
        }
        finish(r, &t, self.truth.n_gt_trajectories, recall_point)
    }
}

/// Marks the rows kept at `threshold` (score not below it); whether any changed, and whether
/// any is kept otherwise than its track's first mean score (`first_means`, by slot, when
/// given) says.
fn update_kept(rows: &mut [TrObj], threshold: f64, first_means: Option<&[f64]>) -> (bool, bool) {
    let at_least = |score: f64| score.partial_cmp(&threshold) != Some(Ordering::Less);
    let (mut changed, mut drifted) = (false, false);
    for row in rows {
        let kept = at_least(row.score);
        changed |= kept != row.kept;
        if let Some(first) = first_means {
            drifted |= kept != at_least(first[row.slot as usize]);
        }
        row.kept = kept;
    }
    (changed, drifted)
}

/// Every row of a track takes the mean score of the track's rows, summed in file order (with
/// Python 3.12's compensation when `compensated`).
pub(super) fn average_scores(seq: &mut SeqTracks, sums: &mut Vec<ScoreSum>, compensated: bool) {
    sums.clear();
    sums.resize(seq.n_tracks, ScoreSum::default());
    for t in &seq.rows {
        sums[t.slot as usize].add(t.score, compensated);
    }
    for t in &mut seq.rows {
        t.score = sums[t.slot as usize].mean();
    }
}

/// A running sum of a track's scores as Python's `sum` adds floats: left to right up to 3.11,
/// from 3.12 with Neumaier's compensation (the rounding error of each addition is kept apart
/// and added at the end, when it is finite and not zero).
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct ScoreSum {
    total: f64,
    compensation: f64,
    n: usize,
}

impl ScoreSum {
    /// Adds `x` to the sum.
    pub(super) fn add(&mut self, x: f64, compensated: bool) {
        let t = self.total + x;
        if compensated {
            self.compensation += if self.total.abs() >= x.abs() {
                (self.total - t) + x
            } else {
                (x - t) + self.total
            };
        }
        self.total = t;
        self.n += 1;
    }

    /// The mean of the added values.
    pub(super) fn mean(&self) -> f64 {
        let c = self.compensation;
        let sum = if c != 0.0 && c.is_finite() {
            self.total + c
        } else {
            self.total
        };
        sum / self.n as f64
    }
}

/// The pairs the reference's Munkres matches in a frame, into `s.matched` and
/// `s.matched_cost` (see the module documentation for the shortcut).
fn select_pairs(edges: &[Edge], ng: usize, nt: usize, s: &mut Scratch) {
    s.matched.clear();
    s.matched.resize(ng, None);
    s.matched_cost.clear();
    s.matched_cost.resize(ng, 0.0);
    s.feasible.clear();
    s.row_deg.clear();
    s.row_deg.resize(ng, 0);
    s.col_deg.clear();
    s.col_deg.resize(nt, 0);
    let mut conflict = false;
    for e in edges {
        let col = s.col_of[e.tr as usize];
        if col == NONE {
            continue;
        }
        s.feasible.push((e.gt, col, e.cost));
        let (rd, cd) = (&mut s.row_deg[e.gt as usize], &mut s.col_deg[col as usize]);
        *rd = rd.saturating_add(1);
        *cd = cd.saturating_add(1);
        conflict |= *rd > 1 || *cd > 1;
    }
    if !conflict {
        for &(g, col, c) in &s.feasible {
            s.matched[g as usize] = Some(col as usize);
            s.matched_cost[g as usize] = c;
        }
        return;
    }
    s.cost.clear();
    s.cost.resize(ng * nt, MAX_COST);
    for &(g, col, c) in &s.feasible {
        s.cost[g as usize * nt + col as usize] = c;
    }
    s.munkres.solve(&s.cost, ng, nt, &mut s.pairs);
    for &(row, col) in &s.pairs {
        let c = s.cost[row * nt + col];
        if c < MAX_COST {
            s.matched[row] = Some(col);
            s.matched_cost[row] = c;
        }
    }
}

/// Matches one frame (its ground truth, track rows marked by [`update_kept`] and feasible
/// pairs) and writes its share of the pass into `memo`; the matched boxes' scores go to
/// `scores` when given.
fn match_frame(
    (gt, tr, edges): (&[GtObj], &mut [TrObj], &[Edge]),
    s: &mut Scratch,
    memo: &mut FrameMemo,
    mut scores: Option<&mut Vec<f64>>,
) {
    s.kept.clear();
    s.col_of.clear();
    for (k, row) in tr.iter().enumerate() {
        if row.kept {
            s.col_of.push(s.kept.len() as u32);
            s.kept.push(k as u32);
        } else {
            s.col_of.push(NONE);
        }
    }
    let (ng, nt) = (gt.len(), s.kept.len());
    select_pairs(edges, ng, nt, s);
    memo.assigned.clear();
    memo.assigned.resize(ng, -1);
    memo.ious.clear();
    s.tmpcs.clear();
    s.tmpcs.resize(ng, 0.0);
    let (mut tmptp, mut n_matched, mut tmpc) = (0u64, 0i64, 0.0f64);
    for (row, m) in s.matched.iter().enumerate() {
        let Some(col) = *m else { continue };
        let c = s.matched_cost[row];
        let tr = &mut tr[s.kept[col] as usize];
        tr.valid = true;
        memo.ious.push(1.0 - c);
        tmpc += 1.0 - c;
        s.tmpcs[row] = 1.0 - c;
        memo.assigned[row] = tr.id;
        tmptp += 1;
        n_matched += 1;
        if let Some(v) = scores.as_mut() {
            v.push(tr.score);
        }
    }
    let tp = tmptp;
    // Ignored track boxes: neighbouring class, too small, or inside DontCare.
    s.tr_ignored.clear();
    s.tr_ignored.resize(nt, false);
    let mut n_ignored_tr = 0u64;
    for (col, &k) in s.kept.iter().enumerate() {
        let tr = &tr[k as usize];
        if !tr.valid && tr.ignorable {
            n_ignored_tr += 1;
            s.tr_ignored[col] = true;
        }
    }
    // Ignored ground truth: truncated, occluded or of the neighbouring class.
    let (mut ignored_fn, mut ignored_tp, mut ignored_pairs) = (0u64, 0u64, 0u64);
    for (gi, _) in gt.iter().enumerate().filter(|(_, g)| g.ignored) {
        match s.matched[gi] {
            None => ignored_fn += 1,
            Some(col) => {
                ignored_tp += 1;
                if s.tr_ignored[col] {
                    ignored_pairs += 1;
                }
                tmpc -= s.tmpcs[gi];
            }
        }
    }
    tmptp -= ignored_tp;
    // The reference: pairs over the IoU limit, plus ground truth left unassigned, minus the
    // ignored ones among both; its Munkres pairs min(ng, nt) rows, so this is the ground truth
    // without a feasible match minus the ignored ones (never negative).
    let frame_fn = ng as i64 - n_matched - ignored_fn as i64;
    let n_ignored_gt = ignored_fn + ignored_tp;
    memo.counts = [
        ng as u64 - n_ignored_gt,
        n_ignored_gt,
        nt as u64,
        n_ignored_tr,
        tp,
        ignored_tp,
        nt as u64 + ignored_pairs - tmptp - n_ignored_tr - ignored_tp,
        frame_fn.max(0) as u64,
        ignored_fn,
    ];
    memo.modp = if tmptp != 0 { tmpc / tmptp as f64 } else { 1.0 };
    memo.fresh = true;
}

/// Records the decisions `match_frame` took in frame `fi` of scene `si` (`eval --events`).
fn record_frame(
    log: &mut Collector,
    (si, fi): (usize, usize),
    gt: &[GtObj],
    tr: &[TrObj],
    s: &Scratch,
) {
    log.record_kitti_frame(
        si,
        fi,
        gt.iter().map(|g| g.id),
        &s.matched,
        |gi| gt[gi].ignored,
        &s.tr_ignored,
        |col| tr[s.kept[col] as usize].id,
    );
}

/// Identity switches, fragmentations and coverage along each ground-truth trajectory of a
/// scene, from the matched ids of its rows; each switch and fragmentation also goes to `log`
/// (with the scene's index) when given.
fn count_trajectories(
    seq: &TruthSeq,
    memos: &[FrameMemo],
    s: &mut Scratch,
    (r, t): (&mut Pass, &mut Tally),
    mut log: Option<(&mut Collector, usize)>,
) {
    let (g, ign) = (&mut s.traj_ids, &mut s.traj_ignored);
    let switches = &mut s.switch_frames;
    for rows in &seq.trajectories {
        let mut mark = |kind, f: usize, track: i64, previous: i64| {
            if let Some((log, si)) = log.as_mut() {
                let (fi, gi) = rows[f];
                let truth = seq.frames[fi as usize].gt[gi as usize].id;
                log.record_mark(*si, truth, f, kind, track, previous);
            }
        };
        g.clear();
        ign.clear();
        for &(fi, gi) in rows {
            g.push(memos[fi as usize].assigned[gi as usize]);
            ign.push(seq.frames[fi as usize].gt[gi as usize].ignored);
        }
        if ign.iter().all(|&i| i) {
            t.n_ignored_traj += 1;
            continue;
        }
        if g.iter().all(|&id| id == -1) {
            t.ml += 1;
            continue;
        }
        let n = g.len();
        let mut last_id = g[0];
        let mut tracked = u64::from(g[0] >= 0);
        for f in 1..n {
            if ign[f] {
                last_id = -1;
                continue;
            }
            if last_id != g[f] && last_id != -1 && g[f] != -1 && g[f - 1] != -1 {
                r.ids += 1;
                switches.push(rows[f].0);
                mark(MarkKind::Switch, f, g[f], last_id);
            }
            if f < n - 1 && g[f - 1] != g[f] && last_id != -1 && g[f] != -1 && g[f + 1] != -1 {
                r.frag += 1;
                mark(MarkKind::Fragmentation, f, g[f], last_id);
            }
            if g[f] != -1 {
                tracked += 1;
                last_id = g[f];
            }
        }
        if n > 1 {
            let f = n - 1;
            if g[f - 1] != g[f] && last_id != -1 && g[f] != -1 && !ign[f] {
                r.frag += 1;
                mark(MarkKind::Fragmentation, f, g[f], last_id);
            }
        }
        let considered = n - ign.iter().filter(|&&i| i).count();
        let ratio = tracked as f64 / considered as f64;
        if ratio > 0.8 {
            t.mt += 1;
        } else if ratio < 0.2 {
            t.ml += 1;
        } else {
            t.pt += 1;
        }
    }
}

/// The ratios of a pass from its counts.
fn finish(mut r: Pass, t: &Tally, n_gt_trajectories: u64, recall_point: f64) -> Pass {
    let (mt, pt, ml, n_frames) = (t.mt, t.pt, t.ml, t.n_frames);
    let (total_cost, modp_sum) = (t.total_cost, t.modp_sum);
    let n_traj = n_gt_trajectories - t.n_ignored_traj;
    if n_traj == 0 {
        (r.mt, r.pt, r.ml) = (0.0, 0.0, 0.0);
    } else {
        r.mt = mt as f64 / n_traj as f64;
        r.pt = pt as f64 / n_traj as f64;
        r.ml = ml as f64 / n_traj as f64;
    }
    if r.fp + r.tp == 0 || r.tp + r.fn_ == 0 {
        (r.recall, r.precision) = (0.0, 0.0);
    } else {
        r.recall = r.tp as f64 / (r.tp + r.fn_) as f64;
        r.precision = r.tp as f64 / (r.fp + r.tp) as f64;
    }
    r.f1 = if r.recall + r.precision == 0.0 {
        0.0
    } else {
        2.0 * (r.precision * r.recall) / (r.precision + r.recall)
    };
    r.far = r.fp as f64 / n_frames as f64;
    if r.n_gt == 0 {
        (r.mota, r.moda, r.smota, r.motal) = (
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        );
    } else {
        let n_gt = r.n_gt as f64;
        r.mota = 1.0 - (r.fn_ + r.fp + r.ids) as f64 / n_gt;
        r.moda = 1.0 - (r.fn_ + r.fp) as f64 / n_gt;
        let s = 1.0
            - ((r.fn_ + r.fp + r.ids) as f64 - (1.0 - recall_point) * n_gt) / (recall_point * n_gt);
        r.smota = s.clamp(0.0, 1.0);
        r.motal = if r.ids == 0 {
            r.mota
        } else {
            1.0 - ((r.fn_ + r.fp) as f64 + (r.ids as f64).log10()) / n_gt
        };
    }
    r.motp = if r.tp == 0 {
        0.0
    } else {
        total_cost / r.tp as f64
    };
    r.modp = modp_sum / n_frames as f64;
    r
}
