//! HOTA (Higher Order Tracking Accuracy; Luiten et al., IJCV 2020) with its sub-metrics DetA,
//! AssA, LocA, DetRe, DetPr, AssRe and AssPr, computed as the TrackEval package (1.3.0,
//! `trackeval/metrics/hota.py`) computes them, so that the numbers are comparable with the KITTI
//! leaderboard and with papers that report TrackEval's output.
//!
//! Per sequence: a first pass accumulates, for every (truth id, track id) pair, the sum over frames
//! of `sim / (row sum + column sum - sim)` of the frame's similarity matrix; its ratio to the
//! ids' detection counts is the pair's global alignment score. A second pass matches each frame
//! by an optimal assignment maximising `alignment score x similarity`; for every alpha in
//! 0.05, 0.10, ..., 0.95 the matched pairs with similarity >= alpha are true positives. Sequences
//! are combined by summing the counts and weighting AssA/AssRe/AssPr/LocA by the true positives.
//! The reported scalars are the means over the 19 alphas.
//!
//! The similarity itself comes from the dataset: [`kitti2d`] (KITTI 2D boxes as TrackEval's
//! `Kitti2DBox` prepares them, and a 3D-IoU variant) and [`centre`] (BEV centre distance).

pub mod centre;
pub mod kitti2d;
pub mod units;

use std::collections::HashMap;

use serde::Serialize;

/// Number of localisation thresholds alpha.
pub const N_ALPHA: usize = 19;

/// `numpy.finfo(float).eps`, the tolerance TrackEval adds to its comparisons.
pub(crate) const EPS: f64 = f64::EPSILON;

/// The thresholds alpha = 0.05 + i * 0.05 (as `numpy.arange(0.05, 0.99, 0.05)` computes them).
pub fn alphas() -> [f64; N_ALPHA] {
    std::array::from_fn(|i| 0.05 + i as f64 * 0.05)
}

/// One frame of one class after the dataset's preprocessing: truth and track ids (contiguous,
/// `0..n` per sequence) and the row-major `truth x tracks` similarity matrix in `[0, 1]`.
#[derive(Debug, Clone, Default)]
pub struct HotaFrame {
    /// Truth ids, one per truth box.
    pub gt: Vec<u32>,
    /// Track ids, one per track box.
    pub tr: Vec<u32>,
    /// Similarity, `gt.len() x tr.len()`, row-major, its nonzero entries only ([`sparse`]).
    pub sim: SparseSim,
}

/// The nonzero entries of a row-major similarity matrix as `(index, value)`, in index order:
/// most pairs of a frame are far apart (similarity 0), and a long log cannot keep them all.
pub type SparseSim = Vec<(u32, f64)>;

/// The nonzero entries of a dense row-major similarity matrix.
pub fn sparse(dense: &[f64]) -> SparseSim {
    dense
        .iter()
        .enumerate()
        .filter(|(_, v)| **v != 0.0)
        .map(|(k, v)| (k as u32, *v))
        .collect()
}

impl HotaFrame {
    /// Writes the dense `gt x tr` similarity matrix into `buf` (zeros where nothing is stored:
    /// adding them changes no sum, so the metrics are those of the dense matrix).
    fn dense_into(&self, buf: &mut Vec<f64>) {
        buf.clear();
        buf.resize(self.gt.len() * self.tr.len(), 0.0);
        for &(k, v) in &self.sim {
            buf[k as usize] = v;
        }
    }
}

/// Per-alpha counts and association scores of one sequence (or of several combined).
#[derive(Debug, Clone, Default)]
pub struct HotaCounts {
    /// True positives per alpha.
    pub tp: [f64; N_ALPHA],
    /// False negatives per alpha.
    pub fn_: [f64; N_ALPHA],
    /// False positives per alpha.
    pub fp: [f64; N_ALPHA],
    /// Association accuracy per alpha.
    pub ass_a: [f64; N_ALPHA],
    /// Association recall per alpha.
    pub ass_re: [f64; N_ALPHA],
    /// Association precision per alpha.
    pub ass_pr: [f64; N_ALPHA],
    /// Localisation accuracy per alpha (mean similarity of the true positives).
    pub loc_a: [f64; N_ALPHA],
}

/// Per (truth id, track id) pair that is ever similar: the summed normalised similarity.
#[derive(Clone, Default)]
struct Pair {
    gt: u32,
    tr: u32,
    potential: f64,
}

/// The first pass over a sequence: detection counts per id and, per pair of ids that is ever
/// similar, the summed normalised similarity.
struct Alignment {
    gt_count: Vec<f64>,
    tr_count: Vec<f64>,
    pairs: Vec<Pair>,
    index: HashMap<(u32, u32), usize>,
    /// Global alignment score per pair.
    score: Vec<f64>,
}

impl Alignment {
    fn new(frames: &[HotaFrame], n_gt: usize, n_tr: usize) -> Alignment {
        let mut a = Alignment {
            gt_count: vec![0.0; n_gt],
            tr_count: vec![0.0; n_tr],
            pairs: Vec::new(),
            index: HashMap::new(),
            score: Vec::new(),
        };
        let (mut row_sum, mut col_sum, mut sim) = (Vec::new(), Vec::new(), Vec::new());
        for f in frames {
            let nt = f.tr.len();
            f.dense_into(&mut sim);
            row_sum.clear();
            row_sum.extend(sim.chunks_exact(nt.max(1)).map(|r| r.iter().sum::<f64>()));
            col_sum.clear();
            col_sum.extend((0..nt).map(|j| sim.iter().skip(j).step_by(nt).sum::<f64>()));
            for (i, (&g, rs)) in f.gt.iter().zip(&row_sum).enumerate() {
                for (j, (&t, cs)) in f.tr.iter().zip(&col_sum).enumerate() {
                    let s = sim[i * nt + j];
                    let denom = cs + rs - s;
                    if s != 0.0 && denom > EPS {
                        let k = a.pair(g, t);
                        a.pairs[k].potential += s / denom;
                    }
                }
            }
            for &g in &f.gt {
                a.gt_count[g as usize] += 1.0;
            }
            for &t in &f.tr {
                a.tr_count[t as usize] += 1.0;
            }
        }
        a.score = a
            .pairs
            .iter()
            .map(|p| {
                p.potential / (a.gt_count[p.gt as usize] + a.tr_count[p.tr as usize] - p.potential)
            })
            .collect();
        a
    }

    /// Index of the pair `(g, t)`, added if new.
    fn pair(&mut self, g: u32, t: u32) -> usize {
        let pairs = &mut self.pairs;
        *self.index.entry((g, t)).or_insert_with(|| {
            pairs.push(Pair {
                gt: g,
                tr: t,
                ..Pair::default()
            });
            pairs.len() - 1
        })
    }
}

/// Evaluates one sequence; `n_gt`/`n_tr` bound the ids of the frames.
pub fn eval_sequence(frames: &[HotaFrame], n_gt: usize, n_tr: usize) -> HotaCounts {
    let mut res = HotaCounts::default();
    let num_gt: usize = frames.iter().map(|f| f.gt.len()).sum();
    let num_tr: usize = frames.iter().map(|f| f.tr.len()).sum();
    if num_tr == 0 || num_gt == 0 {
        res.fn_ = [if num_tr == 0 { num_gt as f64 } else { 0.0 }; N_ALPHA];
        res.fp = [if num_tr == 0 { 0.0 } else { num_tr as f64 }; N_ALPHA];
        res.loc_a = [1.0; N_ALPHA];
        return res;
    }
    let al = Alignment::new(frames, n_gt, n_tr);
    let (loc_sum, matches) = match_frames(frames, &al, &mut res);
    for (a, loc) in loc_sum.iter().enumerate() {
        let (mut ass_a, mut ass_re, mut ass_pr) = (0.0, 0.0, 0.0);
        for (p, m) in al.pairs.iter().zip(&matches) {
            let m = m[a];
            if m == 0.0 {
                continue;
            }
            let (gc, tc) = (al.gt_count[p.gt as usize], al.tr_count[p.tr as usize]);
            ass_a += m * (m / (gc + tc - m).max(1.0));
            ass_re += m * (m / gc.max(1.0));
            ass_pr += m * (m / tc.max(1.0));
        }
        let tp = res.tp[a].max(1.0);
        res.ass_a[a] = ass_a / tp;
        res.ass_re[a] = ass_re / tp;
        res.ass_pr[a] = ass_pr / tp;
        res.loc_a[a] = loc.max(1e-10) / res.tp[a].max(1e-10);
    }
    res
}

/// The second pass: counts TP/FN/FP and each pair's matches per alpha (in the order of
/// `al.pairs`); returns the summed similarity of the TPs per alpha, and the matches.
fn match_frames(
    frames: &[HotaFrame],
    al: &Alignment,
    res: &mut HotaCounts,
) -> ([f64; N_ALPHA], Vec<[f64; N_ALPHA]>) {
    let alpha = alphas();
    let mut loc_sum = [0.0f64; N_ALPHA];
    let mut matches = vec![[0.0f64; N_ALPHA]; al.pairs.len()];
    for_each_match(frames, al, |_, (ng, nt), matched| {
        for (a, &alpha) in alpha.iter().enumerate() {
            let mut n = 0usize;
            let mut s_sum = 0.0f64;
            for &(k, s) in matched {
                if s >= alpha - EPS {
                    n += 1;
                    s_sum += s;
                    matches[k][a] += 1.0;
                }
            }
            res.tp[a] += n as f64;
            res.fn_[a] += (ng - n) as f64;
            res.fp[a] += (nt - n) as f64;
            if n > 0 {
                loc_sum[a] += s_sum;
            }
        }
    });
    (loc_sum, matches)
}

/// Matches every frame by the optimal assignment maximising `alignment score x similarity`:
/// `visit(frame index, (truth count, track count), matched)` gets the matched pairs as
/// `(index into al.pairs, similarity)`, in row order (none when a side is empty).
fn for_each_match(
    frames: &[HotaFrame],
    al: &Alignment,
    mut visit: impl FnMut(usize, (usize, usize), &[(usize, f64)]),
) {
    let mut assigned = Vec::new();
    let mut matched = Vec::new();
    let mut sim = Vec::new();
    for (fi, f) in frames.iter().enumerate() {
        let (ng, nt) = (f.gt.len(), f.tr.len());
        matched.clear();
        if ng > 0 && nt > 0 {
            f.dense_into(&mut sim);
            let sim = &sim;
            let score = |i: usize, j: usize| {
                let s = sim[i * nt + j];
                if s == 0.0 {
                    return 0.0;
                }
                al.index
                    .get(&(f.gt[i], f.tr[j]))
                    .map_or(0.0, |&k| al.score[k] * s)
            };
            best_assignment(ng, nt, score, &mut assigned);
            matched.extend(
                (assigned.iter()).map(|&(i, j)| (al.index[&(f.gt[i], f.tr[j])], sim[i * nt + j])),
            );
        }
        visit(fi, (ng, nt), &matched);
    }
}

/// The optimal assignment maximising `score` over a `rows x cols` frame, as
/// `scipy.optimize.linear_sum_assignment(-score)` (the `lsap` crate is its translation). Rows
/// and columns whose scores are all zero cannot form a match that counts (every threshold is
/// positive) and are left out of the solve, which keeps large, sparse frames fast. `out` gets
/// the pairs with a positive score, in row order.
fn best_assignment(
    rows: usize,
    cols: usize,
    score: impl Fn(usize, usize) -> f64,
    out: &mut Vec<(usize, usize)>,
) {
    out.clear();
    let mut keep_r = Vec::new();
    let mut keep_c = vec![false; cols];
    for i in 0..rows {
        let mut any = false;
        for (j, k) in keep_c.iter_mut().enumerate() {
            if score(i, j) > 0.0 {
                any = true;
                *k = true;
            }
        }
        if any {
            keep_r.push(i);
        }
    }
    let keep_c: Vec<usize> = (0..cols).filter(|&j| keep_c[j]).collect();
    if keep_r.is_empty() {
        return;
    }
    let (nr, nc) = (keep_r.len(), keep_c.len());
    let mut cost = Vec::with_capacity(nr * nc);
    for &i in &keep_r {
        cost.extend(keep_c.iter().map(|&j| -score(i, j)));
    }
    let (r, c) = lsap::solve(nr, nc, &cost, false).expect("finite scores have an assignment");
    out.extend(
        r.into_iter()
            .zip(c)
            .filter(|&(i, j)| cost[i * nc + j] < 0.0)
            .map(|(i, j)| (keep_r[i], keep_c[j])),
    );
    out.sort_unstable();
}

/// Combines sequences as TrackEval's `combine_sequences` does.
pub fn combine(seqs: &[HotaCounts]) -> HotaCounts {
    let mut res = HotaCounts::default();
    let mut loc = [0.0f64; N_ALPHA];
    for s in seqs {
        for (a, loc) in loc.iter_mut().enumerate() {
            res.tp[a] += s.tp[a];
            res.fn_[a] += s.fn_[a];
            res.fp[a] += s.fp[a];
            res.ass_a[a] += s.ass_a[a] * s.tp[a];
            res.ass_re[a] += s.ass_re[a] * s.tp[a];
            res.ass_pr[a] += s.ass_pr[a] * s.tp[a];
            *loc += s.loc_a[a] * s.tp[a];
        }
    }
    for (a, loc) in loc.iter().enumerate() {
        let tp = res.tp[a].max(1.0);
        res.ass_a[a] /= tp;
        res.ass_re[a] /= tp;
        res.ass_pr[a] /= tp;
        res.loc_a[a] = loc.max(1e-10) / res.tp[a].max(1e-10);
    }
    res
}

/// The per-alpha curves of [`Hota`].
#[derive(Debug, Clone, Serialize)]
pub struct HotaCurves {
    /// The thresholds.
    pub alpha: Vec<f64>,
    /// HOTA = sqrt(DetA x AssA).
    pub hota: Vec<f64>,
    /// Detection accuracy TP / (TP + FN + FP).
    pub deta: Vec<f64>,
    /// Association accuracy.
    pub assa: Vec<f64>,
    /// Localisation accuracy.
    pub loca: Vec<f64>,
    /// Detection recall.
    pub detre: Vec<f64>,
    /// Detection precision.
    pub detpr: Vec<f64>,
    /// Association recall.
    pub assre: Vec<f64>,
    /// Association precision.
    pub asspr: Vec<f64>,
    /// True positives.
    pub tp: Vec<f64>,
    /// False negatives.
    #[serde(rename = "fn")]
    pub fn_: Vec<f64>,
    /// False positives.
    pub fp: Vec<f64>,
}

/// HOTA of one class: the means over alpha, and the curves.
#[derive(Debug, Clone, Serialize)]
pub struct Hota {
    /// Mean HOTA over alpha (the leaderboard's HOTA).
    pub hota: f64,
    /// Mean DetA.
    pub deta: f64,
    /// Mean AssA.
    pub assa: f64,
    /// Mean LocA.
    pub loca: f64,
    /// Mean DetRe.
    pub detre: f64,
    /// Mean DetPr.
    pub detpr: f64,
    /// Mean AssRe.
    pub assre: f64,
    /// Mean AssPr.
    pub asspr: f64,
    /// Per alpha.
    pub curves: HotaCurves,
}

impl Hota {
    /// The final fields (TrackEval's `_compute_final_fields`) and their means over alpha.
    pub fn from_counts(c: &HotaCounts) -> Hota {
        let per = |f: &dyn Fn(usize) -> f64| (0..N_ALPHA).map(f).collect::<Vec<f64>>();
        let detre = per(&|a| c.tp[a] / (c.tp[a] + c.fn_[a]).max(1.0));
        let detpr = per(&|a| c.tp[a] / (c.tp[a] + c.fp[a]).max(1.0));
        let deta = per(&|a| c.tp[a] / (c.tp[a] + c.fn_[a] + c.fp[a]).max(1.0));
        let hota = per(&|a| (deta[a] * c.ass_a[a]).sqrt());
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        let curves = HotaCurves {
            alpha: alphas().to_vec(),
            assa: c.ass_a.to_vec(),
            assre: c.ass_re.to_vec(),
            asspr: c.ass_pr.to_vec(),
            loca: c.loc_a.to_vec(),
            tp: c.tp.to_vec(),
            fn_: c.fn_.to_vec(),
            fp: c.fp.to_vec(),
            hota,
            deta,
            detre,
            detpr,
        };
        Hota {
            hota: mean(&curves.hota),
            deta: mean(&curves.deta),
            assa: mean(&curves.assa),
            loca: mean(&curves.loca),
            detre: mean(&curves.detre),
            detpr: mean(&curves.detpr),
            assre: mean(&curves.assre),
            asspr: mean(&curves.asspr),
            curves,
        }
    }
}

/// Maps the ids of one sequence's frames (given as raw ids) to `0..n`; returns the frames and the
/// number of distinct truth and track ids.
pub fn relabel(raw: Vec<RawFrame>) -> (Vec<HotaFrame>, usize, usize) {
    let mut gt_ids: HashMap<i64, u32> = HashMap::new();
    let mut tr_ids: HashMap<i64, u32> = HashMap::new();
    let next = |map: &mut HashMap<i64, u32>, id: i64| {
        let n = map.len() as u32;
        *map.entry(id).or_insert(n)
    };
    let frames = raw
        .into_iter()
        .map(|(g, t, sim)| HotaFrame {
            gt: g.into_iter().map(|id| next(&mut gt_ids, id)).collect(),
            tr: t.into_iter().map(|id| next(&mut tr_ids, id)).collect(),
            sim,
        })
        .collect();
    (frames, gt_ids.len(), tr_ids.len())
}

/// One frame of one class before relabelling: `(truth ids, track ids, similarity)` (the
/// similarity's nonzero entries, [`sparse`]).
pub type RawFrame = (Vec<i64>, Vec<i64>, SparseSim);

/// How each sequence of a class is evaluated, and the sequences combined: [`Whole`] (the
/// metrics) or per resampling unit (`units::ByUnit`, for `eval --bootstrap`).
pub trait Evaluation: Sync {
    /// What one sequence gives.
    type Seq: Send;
    /// What a class gives (its sequences combined, in scene order).
    type Class;
    /// Evaluates the frames of scene `scene` (ids relabelled to `0..n_gt` and `0..n_tr`).
    fn sequence(&self, scene: usize, frames: &[HotaFrame], n_gt: usize, n_tr: usize) -> Self::Seq;
    /// Combines a class's sequences.
    fn class(&self, seqs: Vec<Self::Seq>) -> Self::Class;
}

/// The metrics of all the data: [`eval_sequence`], [`combine`] and [`Hota::from_counts`].
#[derive(Debug, Clone, Copy, Default)]
pub struct Whole;

impl Evaluation for Whole {
    type Seq = HotaCounts;
    type Class = Hota;
    fn sequence(&self, _: usize, frames: &[HotaFrame], n_gt: usize, n_tr: usize) -> HotaCounts {
        eval_sequence(frames, n_gt, n_tr)
    }
    fn class(&self, seqs: Vec<HotaCounts>) -> Hota {
        Hota::from_counts(&combine(&seqs))
    }
}

/// Prepares (with `prepare`) and evaluates every scene as one sequence, in parallel, and
/// combines them in scene order. Also says whether any box was there. `Err`: the first scene
/// whose frames hold an id twice, as `"scene, frame F: truth/track id N occurs twice"`.
pub fn eval_scenes<S, F>(scenes: &[S], prepare: F) -> Result<(HotaCounts, bool), String>
where
    S: Named + Sync,
    F: Fn(&S) -> Vec<RawFrame> + Sync,
{
    let (seqs, any) = eval_scenes_by(scenes, prepare, &Whole)?;
    Ok((combine(&seqs), any))
}

/// [`eval_scenes`] with each sequence evaluated by `how`, not combined.
pub fn eval_scenes_by<S, F, E>(
    scenes: &[S],
    prepare: F,
    how: &E,
) -> Result<(Vec<E::Seq>, bool), String>
where
    S: Named + Sync,
    F: Fn(&S) -> Vec<RawFrame> + Sync,
    E: Evaluation,
{
    use rayon::prelude::*;
    let per_scene: Vec<Result<(E::Seq, bool), String>> = (scenes.par_iter().enumerate())
        .map(|(si, scene)| {
            let raw = prepare(scene);
            if let Some((frame, id, what)) = duplicate_id(&raw) {
                return Err(format!(
                    "{}, frame {frame}: {what} id {id} occurs twice",
                    scene.name()
                ));
            }
            let any = raw.iter().any(|(g, t, _)| !g.is_empty() || !t.is_empty());
            let (frames, n_gt, n_tr) = relabel(raw);
            Ok((how.sequence(si, &frames, n_gt, n_tr), any))
        })
        .collect();
    let mut seqs = Vec::with_capacity(per_scene.len());
    let mut any = false;
    for r in per_scene {
        let (c, a) = r?;
        seqs.push(c);
        any |= a;
    }
    Ok((seqs, any))
}

/// A scene with a name for the messages (a [`crate::eval::scene::Scene`] or its columns).
pub trait Named {
    /// The scene's name.
    fn name(&self) -> &str;
}

impl<B> Named for crate::eval::scene::Scene<B> {
    fn name(&self) -> &str {
        &self.name
    }
}

impl Named for crate::eval::columns::ColumnScene {
    fn name(&self) -> &str {
        &self.name
    }
}

/// The first id that occurs twice in one frame, as `(frame index, id, "truth"/"track")`;
/// TrackEval refuses such data.
pub fn duplicate_id(raw: &[RawFrame]) -> Option<(usize, i64, &'static str)> {
    for (fi, (g, t, _)) in raw.iter().enumerate() {
        for (ids, what) in [(g, "truth"), (t, "track")] {
            let mut seen = std::collections::HashSet::new();
            if let Some(&id) = ids.iter().find(|&&id| !seen.insert(id)) {
                return Some((fi, id, what));
            }
        }
    }
    None
}

#[cfg(test)]
mod tests;

/// Columns of the HOTA table in `probmot eval`'s text report.
pub const HOTA_COLUMNS: [&str; 8] = [
    "hota", "deta", "assa", "loca", "detre", "detpr", "assre", "asspr",
];

/// Rows `(class + suffix, values of HOTA_COLUMNS)` for the text report, then (when there is a
/// class) the row `overall + suffix`: the mean of each column over the classes shown
/// (TrackEval's class-averaged combination, `cls_comb_cls_av`).
pub fn hota_rows(
    classes: &std::collections::BTreeMap<String, Hota>,
    suffix: &str,
) -> Vec<(String, Vec<f64>)> {
    let mut rows: Vec<(String, Vec<f64>)> = classes
        .iter()
        .map(|(c, h)| {
            let v = [
                h.hota, h.deta, h.assa, h.loca, h.detre, h.detpr, h.assre, h.asspr,
            ];
            (format!("{c}{suffix}"), v.to_vec())
        })
        .collect();
    if !rows.is_empty() {
        let n = rows.len() as f64;
        let mean = (0..HOTA_COLUMNS.len())
            .map(|k| rows.iter().map(|r| r.1[k]).sum::<f64>() / n)
            .collect();
        rows.push((format!("overall{suffix}"), mean));
    }
    rows
}
