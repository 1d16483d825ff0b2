//! One-to-one assignment of detections to tracks: the paper's greedy algorithm and the optimal
//! (Hungarian-style) assignment.

/// A candidate pair: cost (lower is better), detection index, track index.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pair {
    /// Cost of the pair; for similarities this is the negated similarity.
    pub cost: f64,
    /// Index of the detection within the class.
    pub det: u32,
    /// Index of the track within the class.
    pub trk: u32,
}

/// Greedy matching (Algorithm 1 of Chiu et al. 2019): sort all pairs by cost, accept a pair when
/// both its detection and its track are still free, and stop at the first pair whose cost exceeds
/// `max_cost`. Ties are broken by detection index, then track index, so the result is
/// deterministic. `det_taken` / `trk_taken` are scratch flags (resized here); accepted pairs are
/// appended to `out`.
pub fn greedy(
    pairs: &mut [Pair],
    max_cost: f64,
    det_taken: &mut Vec<bool>,
    trk_taken: &mut Vec<bool>,
    n_det: usize,
    n_trk: usize,
    out: &mut Vec<(u32, u32)>,
) {
    pairs.sort_unstable_by(|a, b| {
        a.cost
            .total_cmp(&b.cost)
            .then(a.det.cmp(&b.det))
            .then(a.trk.cmp(&b.trk))
    });
    det_taken.clear();
    det_taken.resize(n_det, false);
    trk_taken.clear();
    trk_taken.resize(n_trk, false);
    for p in pairs.iter() {
        if p.cost > max_cost {
            break;
        }
        if !det_taken[p.det as usize] && !trk_taken[p.trk as usize] {
            det_taken[p.det as usize] = true;
            trk_taken[p.trk as usize] = true;
            out.push((p.det, p.trk));
        }
    }
}

/// Cost given to pairs that are not candidates (cut by the pre-gate) in the optimal assignment.
/// Large enough never to be preferred over any pair under the gate, small enough to keep the
/// solver's arithmetic exact.
pub const NOT_A_CANDIDATE: f64 = 1e9;

/// Optimal assignment minimising the total cost over an `n_det x n_trk` matrix (row-major,
/// detections as rows; non-candidates hold [`NOT_A_CANDIDATE`]). Pairs with cost over `max_cost`
/// are dropped afterwards. Uses the `lsap` crate (the shortest augmenting path algorithm of
/// scipy's `linear_sum_assignment`).
pub fn hungarian(
    cost: &Vec<f64>,
    n_det: usize,
    n_trk: usize,
    max_cost: f64,
    out: &mut Vec<(u32, u32)>,
) {
    if n_det == 0 || n_trk == 0 {
        return;
    }
    let (rows, cols) = lsap::solve(n_det, n_trk, cost, false)
        .expect("finite cost matrix always has an assignment");
    for (r, c) in rows.into_iter().zip(cols) {
        if cost[r * n_trk + c] <= max_cost {
            out.push((r as u32, c as u32));
        }
    }
    out.sort_unstable();
}

#[cfg(test)]
mod tests {
    use super::*;

    fn matrix_pairs(m: &[&[f64]]) -> Vec<Pair> {
        let mut v = vec![];
        for (d, row) in m.iter().enumerate() {
            for (t, c) in row.iter().enumerate() {
                v.push(Pair {
                    cost: *c,
                    det: d as u32,
                    trk: t as u32,
                });
            }
        }
        v
    }

    fn run_greedy(m: &[&[f64]], max: f64) -> Vec<(u32, u32)> {
        let mut pairs = matrix_pairs(m);
        let mut out = vec![];
        greedy(
            &mut pairs,
            max,
            &mut vec![],
            &mut vec![],
            m.len(),
            m[0].len(),
            &mut out,
        );
        out.sort();
        out
    }

    /// Algorithm 1 worked by hand. Sorted pairs: (d0,t0)=1, (d1,t0)=2, (d1,t1)=3, (d2,t2)=12,
    /// (d2,t1)=13, ... With gate 11: take (d0,t0); skip (d1,t0) (t0 taken); take (d1,t1);
    /// (d2,t2)=12 is over the gate: stop. d2 stays unmatched even though nothing else wants t2.
    #[test]
    fn greedy_algorithm_1_with_early_stop() {
        let m: &[&[f64]] = &[&[1.0, 5.0, 20.0], &[2.0, 3.0, 30.0], &[40.0, 13.0, 12.0]];
        assert_eq!(run_greedy(m, 11.0), vec![(0, 0), (1, 1)]);
        assert_eq!(run_greedy(m, 12.0), vec![(0, 0), (1, 1), (2, 2)]);
    }

    #[test]
    fn greedy_ties_are_deterministic() {
        let m: &[&[f64]] = &[&[1.0, 1.0], &[1.0, 1.0]];
        assert_eq!(run_greedy(m, 5.0), vec![(0, 0), (1, 1)]);
    }

    /// Greedy takes the cheapest pair (d0,t0)=1 and is left with (d1,t1)=10: total 11.
    /// The optimal assignment is (d0,t1)+(d1,t0) = 2 + 2 = 4.
    #[test]
    fn hungarian_and_greedy_differ() {
        let m: &[&[f64]] = &[&[1.0, 2.0], &[2.0, 10.0]];
        assert_eq!(run_greedy(m, 11.0), vec![(0, 0), (1, 1)]);
        let flat: Vec<f64> = m.iter().flat_map(|r| r.iter().copied()).collect();
        let mut out = vec![];
        hungarian(&flat, 2, 2, 11.0, &mut out);
        assert_eq!(out, vec![(0, 1), (1, 0)]);
        // The gate is applied after the assignment.
        let mut out = vec![];
        hungarian(&flat, 2, 2, 1.5, &mut out);
        assert_eq!(out, vec![]);
    }

    #[test]
    fn hungarian_rectangular() {
        let flat = vec![5.0, 1.0, NOT_A_CANDIDATE, 2.0, 3.0, 4.0];
        let mut out = vec![];
        hungarian(&flat, 2, 3, 10.0, &mut out);
        assert_eq!(out, vec![(0, 1), (1, 0)]);
    }
}
