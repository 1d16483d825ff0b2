//! HOTA per resampling unit, for `eval --bootstrap`: the matching of all the data (its global
//! alignment scores and its optimal assignments) is run once; every unit keeps its counts, and a
//! resample recomputes HOTA, DetA and AssA from the weighted sums of them.
//!
//! Kept per unit: TP, FN and FP per alpha; per truth id and per track id, its detections; per
//! (truth id, track id) pair, its matches per alpha. A resample sums each of these with the
//! units' weights and applies TrackEval's formulas to the sums: AssA per alpha is
//! `sum over pairs of m * m / (gt count + track count - m)` over the TPs, per sequence, then
//! weighted by the TPs over the sequences. A unit drawn twice counts its frames twice for the
//! same ids (its ids seen twice as long there), not as new ids: with whole logs as units this is
//! the same as two copies with distinct ids (every sum of the log doubles, and so do its pairs'
//! terms and its TPs), and with every weight 1 the numbers are exactly those of
//! [`super::eval_scenes`]. Held fixed, as in the protocols' curves: the alignment scores that
//! steer the matching are those of all the data.

use super::{alphas, for_each_match, Alignment, Evaluation, HotaFrame, EPS, N_ALPHA};
use crate::eval::bootstrap::Units;

/// Evaluates each sequence per resampling unit of `units` (its frames' units).
#[derive(Debug, Clone, Copy)]
pub struct ByUnit<'a>(pub &'a Units);

/// Per-alpha values.
type PerAlpha = [f64; N_ALPHA];

/// One sequence's HOTA counts, per resampling unit (only the units it has frames in).
#[derive(Debug, Clone, Default)]
pub struct SeqUnits {
    /// Per unit: `(unit, [TP, FN, FP] per alpha)`.
    det: Vec<(u32, [PerAlpha; 3])>,
    /// Per truth id: `(unit, detections)`.
    gt_count: Vec<Vec<(u32, f64)>>,
    /// Per track id: `(unit, detections)`.
    tr_count: Vec<Vec<(u32, f64)>>,
    /// Per pair matched at some alpha, in the order of the alignment's pairs: its truth id,
    /// track id and `(unit, matches per alpha)`.
    pairs: Vec<(u32, u32, PerUnit)>,
}

/// A pair's matches per alpha, per unit: `(unit, matches)`.
type PerUnit = Vec<(u32, PerAlpha)>;

/// One class's HOTA counts per unit: its sequences in scene order.
pub type HotaCurve = Vec<SeqUnits>;

impl Evaluation for ByUnit<'_> {
    type Seq = SeqUnits;
    type Class = HotaCurve;
    fn sequence(&self, scene: usize, frames: &[HotaFrame], n_gt: usize, n_tr: usize) -> SeqUnits {
        let unit = |fi: usize| self.0.unit(scene, fi) as u32;
        unit_sequence(frames, (n_gt, n_tr), unit)
    }
    fn class(&self, seqs: Vec<SeqUnits>) -> HotaCurve {
        seqs
    }
}

/// The entry of `unit` in `v` (added if new; a sequence's frames mostly run unit by unit).
fn entry<T: Default>(v: &mut Vec<(u32, T)>, unit: u32) -> &mut T {
    let k = match v.iter().rposition(|e| e.0 == unit) {
        Some(k) => k,
        None => {
            v.push((unit, T::default()));
            v.len() - 1
        }
    };
    &mut v[k].1
}

/// One sequence's counts per unit (`unit(frame index)`).
fn unit_sequence(
    frames: &[HotaFrame],
    (n_gt, n_tr): (usize, usize),
    unit: impl Fn(usize) -> u32,
) -> SeqUnits {
    let mut s = SeqUnits {
        gt_count: vec![Vec::new(); n_gt],
        tr_count: vec![Vec::new(); n_tr],
        ..SeqUnits::default()
    };
    for (fi, f) in frames.iter().enumerate() {
        let u = unit(fi);
        for &g in &f.gt {
            *entry(&mut s.gt_count[g as usize], u) += 1.0;
        }
        for &t in &f.tr {
            *entry(&mut s.tr_count[t as usize], u) += 1.0;
        }
    }
    let al = Alignment::new(frames, n_gt, n_tr);
    let mut pairs: Vec<PerUnit> = vec![Vec::new(); al.pairs.len()];
    let alpha = alphas();
    for_each_match(frames, &al, |fi, (ng, nt), matched| {
        let u = unit(fi);
        let det = entry(&mut s.det, u);
        for (a, &alpha) in alpha.iter().enumerate() {
            let mut n = 0usize;
            for &(k, sim) in matched {
                if sim >= alpha - EPS {
                    n += 1;
                    entry(&mut pairs[k], u)[a] += 1.0;
                }
            }
            det[0][a] += n as f64;
            det[1][a] += (ng - n) as f64;
            det[2][a] += (nt - n) as f64;
        }
    });
    s.pairs = (al.pairs.iter().zip(pairs))
        .filter(|(_, units)| !units.is_empty())
        .map(|(p, units)| (p.gt, p.tr, units))
        .collect();
    s
}

/// `sum over entries of weight(unit) x value`.
fn weighted(v: &[(u32, f64)], w: &[u32]) -> f64 {
    v.iter().map(|&(u, x)| f64::from(w[u as usize]) * x).sum()
}

/// HOTA, DetA and AssA (means over alpha) of one class under the units' weights `w`; `None`
/// when the resample holds no box of the class on either side.
pub fn hota_class(c: &[SeqUnits], w: &[u32]) -> Option<[f64; 3]> {
    let (mut tp, mut fn_, mut fp, mut ass) = (
        [0.0; N_ALPHA],
        [0.0; N_ALPHA],
        [0.0; N_ALPHA],
        [0.0; N_ALPHA],
    );
    let mut gc = Vec::new();
    let mut tc = Vec::new();
    for s in c {
        let mut det = [[0.0; N_ALPHA]; 3];
        for (u, d) in &s.det {
            let k = f64::from(w[*u as usize]);
            if k > 0.0 {
                for (sum, v) in det.iter_mut().zip(d) {
                    sum.iter_mut().zip(v).for_each(|(s, v)| *s += k * v);
                }
            }
        }
        gc.clear();
        gc.extend(s.gt_count.iter().map(|v| weighted(v, w)));
        tc.clear();
        tc.extend(s.tr_count.iter().map(|v| weighted(v, w)));
        let mut pair_sum = [0.0; N_ALPHA];
        for (g, t, units) in &s.pairs {
            let (g, t) = (gc[*g as usize], tc[*t as usize]);
            let mut m = [0.0; N_ALPHA];
            for (u, v) in units {
                let k = f64::from(w[*u as usize]);
                if k > 0.0 {
                    m.iter_mut().zip(v).for_each(|(m, v)| *m += k * v);
                }
            }
            for (a, &m) in m.iter().enumerate() {
                if m != 0.0 {
                    pair_sum[a] += m * (m / (g + t - m).max(1.0));
                }
            }
        }
        // As `eval_sequence` then `combine`: AssA per sequence, weighted by its TPs.
        for a in 0..N_ALPHA {
            let seq_ass = pair_sum[a] / det[0][a].max(1.0);
            tp[a] += det[0][a];
            fn_[a] += det[1][a];
            fp[a] += det[2][a];
            ass[a] += seq_ass * det[0][a];
        }
    }
    if tp[0] + fn_[0] + fp[0] == 0.0 {
        return None;
    }
    let ass_a: PerAlpha = std::array::from_fn(|a| ass[a] / tp[a].max(1.0));
    let deta: PerAlpha = std::array::from_fn(|a| tp[a] / (tp[a] + fn_[a] + fp[a]).max(1.0));
    let hota: PerAlpha = std::array::from_fn(|a| (deta[a] * ass_a[a]).sqrt());
    let mean = |v: &PerAlpha| v.iter().sum::<f64>() / v.len() as f64;
    Some([mean(&hota), mean(&deta), mean(&ass_a)])
}

#[cfg(test)]
mod tests {
    use super::super::{combine, eval_sequence, sparse, Hota};
    use super::*;

    /// A few sequences with switches, misses, false positives and partial similarities.
    fn sequences() -> Vec<(Vec<HotaFrame>, usize, usize)> {
        let f = |gt: &[u32], tr: &[u32], sim: &[f64]| HotaFrame {
            gt: gt.to_vec(),
            tr: tr.to_vec(),
            sim: sparse(sim),
        };
        let a = vec![
            f(&[0, 1], &[0, 1], &[0.9, 0.0, 0.1, 0.7]),
            f(&[0, 1], &[0, 2], &[0.8, 0.0, 0.0, 0.6]),
            f(&[0], &[2], &[0.55]),
            f(&[0, 1], &[], &[]),
            f(&[1], &[1, 3], &[0.95, 0.2]),
            f(&[], &[3], &[]),
        ];
        let b = vec![f(&[0], &[0], &[0.33]), f(&[0], &[0], &[1.0])];
        let empty = vec![f(&[0], &[], &[]); 3];
        vec![(a, 2, 4), (b, 1, 1), (empty, 1, 0)]
    }

    fn curve(units_of: &[Vec<u32>]) -> HotaCurve {
        (sequences().iter().zip(units_of))
            .map(|((frames, g, t), u)| unit_sequence(frames, (*g, *t), |fi| u[fi]))
            .collect()
    }

    #[test]
    fn every_weight_one_gives_the_metrics_exactly() {
        let seqs: Vec<_> = (sequences().iter())
            .map(|(f, g, t)| eval_sequence(f, *g, *t))
            .collect();
        let h = Hota::from_counts(&combine(&seqs));
        let units = [vec![0, 0, 1, 1, 2, 2], vec![3, 4], vec![5, 5, 5]];
        let r = hota_class(&curve(&units), &[1; 6]).unwrap();
        assert_eq!(r, [h.hota, h.deta, h.assa]);
    }

    /// Whole sequences as units: drawing one twice gives what two copies of it (with their own
    /// ids) give, and a resample without any box has no value.
    #[test]
    fn a_sequence_drawn_twice_counts_as_two_copies() {
        let units = [vec![0; 6], vec![1; 2], vec![2; 3]];
        let c = curve(&units);
        let s = sequences();
        let seqs: Vec<_> = [&s[0], &s[0], &s[1]]
            .iter()
            .map(|(f, g, t)| eval_sequence(f, *g, *t))
            .collect();
        let h = Hota::from_counts(&combine(&seqs));
        let r = hota_class(&c, &[2, 1, 0]).unwrap();
        for (x, y) in r.iter().zip([h.hota, h.deta, h.assa]) {
            assert!((x - y).abs() < 1e-12, "{r:?} vs {y}");
        }
        assert_eq!(hota_class(&c[1..2], &[0, 0, 3]), None);
    }
}
