//! Frame-by-frame association with the semantics of py-motmetrics 1.4.0's `MOTAccumulator`:
//! keep last frame's pairing while it is still valid, then a minimum-cost assignment of the rest
//! (scipy's algorithm, invalid pairs replaced by a large constant as motmetrics does); a match
//! whose object was last paired with another hypothesis is an identity switch.

use std::collections::HashMap;

/// Kind of a (non-raw) event.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EventKind {
    /// Object and hypothesis paired, same pairing as before (or first pairing).
    Match,
    /// Object paired with a different hypothesis than last time.
    Switch,
    /// Object without hypothesis.
    Miss,
    /// Hypothesis without object.
    FalsePositive,
}

/// One event. `object` / `hypothesis` index into the frame's input slices.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Event {
    /// Kind.
    pub kind: EventKind,
    /// Object index in the frame (None for false positives).
    pub object: Option<usize>,
    /// Hypothesis index in the frame (None for misses).
    pub hypothesis: Option<usize>,
    /// Distance for matches and switches, NaN otherwise.
    pub distance: f64,
}

/// The accumulator of one scene.
#[derive(Debug, Default)]
pub struct MotAccumulator {
    /// Last hypothesis paired with each object.
    last_pair: HashMap<u64, u64>,
    cost: Vec<f64>,
}

impl MotAccumulator {
    /// A fresh accumulator.
    pub fn new() -> Self {
        Self::default()
    }

    /// Associates one frame. `dist` is row-major `objects x hypotheses`, NaN for pairs that may
    /// not be matched. Events are appended to `out` in motmetrics' order: re-established
    /// matches, assigned pairs (by object index), misses, false positives.
    pub fn update(&mut self, oids: &[u64], hids: &[u64], dist: &[f64], out: &mut Vec<Event>) {
        let no = oids.len();
        let nh = hids.len();
        let mut omask = vec![false; no];
        let mut hmask = vec![false; nh];
        if no > 0 && nh > 0 {
            // 1. Re-establish last frame's pairings that are still valid.
            for i in 0..no {
                let Some(&hprev) = self.last_pair.get(&oids[i]) else {
                    continue;
                };
                let Some(j) = (0..nh).find(|&j| !hmask[j] && hids[j] == hprev) else {
                    continue;
                };
                let d = dist[i * nh + j];
                if d.is_finite() {
                    omask[i] = true;
                    hmask[j] = true;
                    out.push(Event {
                        kind: EventKind::Match,
                        object: Some(i),
                        hypothesis: Some(j),
                        distance: d,
                    });
                }
            }
            // 2. Minimum-cost assignment of the rest (nothing to do when no valid pair is left:
            // every pair the solver could return would be dropped).
            let any_left = (0..no)
                .any(|i| !omask[i] && (0..nh).any(|j| !hmask[j] && dist[i * nh + j].is_finite()));
            if !any_left {
                self.push_unmatched(&omask, &hmask, out);
                return;
            }
            self.cost.clear();
            self.cost.extend_from_slice(dist);
            for (i, om) in omask.iter().enumerate() {
                for (j, hm) in hmask.iter().enumerate() {
                    if *om || *hm {
                        self.cost[i * nh + j] = f64::NAN;
                    }
                }
            }
            for (i, j) in assign_with_missing_edges(&mut self.cost, no, nh) {
                let d = dist[i * nh + j];
                if omask[i] || hmask[j] || !d.is_finite() {
                    continue;
                }
                let (o, h) = (oids[i], hids[j]);
                let switch = self.last_pair.get(&o).is_some_and(|&p| p != h);
                out.push(Event {
                    kind: if switch {
                        EventKind::Switch
                    } else {
                        EventKind::Match
                    },
                    object: Some(i),
                    hypothesis: Some(j),
                    distance: d,
                });
                omask[i] = true;
                hmask[j] = true;
                self.last_pair.insert(o, h);
            }
        }
        self.push_unmatched(&omask, &hmask, out);
    }

    /// Misses for the objects and false positives for the hypotheses left unpaired.
    fn push_unmatched(&self, omask: &[bool], hmask: &[bool], out: &mut Vec<Event>) {
        for (i, m) in omask.iter().enumerate() {
            if !m {
                out.push(Event {
                    kind: EventKind::Miss,
                    object: Some(i),
                    hypothesis: None,
                    distance: f64::NAN,
                });
            }
        }
        for (j, m) in hmask.iter().enumerate() {
            if !m {
                out.push(Event {
                    kind: EventKind::FalsePositive,
                    object: None,
                    hypothesis: Some(j),
                    distance: f64::NAN,
                });
            }
        }
    }
}

/// motmetrics' `lsa_solve_scipy`: non-finite entries become `2 r c + 1` with
/// `c = max |finite| + 1` and `r = min(rows, cols)`, scipy's algorithm solves, and pairs on
/// non-finite entries are dropped by the caller. `cost` is overwritten.
pub fn assign_with_missing_edges(
    cost: &mut Vec<f64>,
    rows: usize,
    cols: usize,
) -> Vec<(usize, usize)> {
    if rows == 0 || cols == 0 {
        return Vec::new();
    }
    let mut any_valid = false;
    let mut all_valid = true;
    let mut max_abs = 0.0f64;
    for v in cost.iter() {
        if v.is_finite() {
            any_valid = true;
            max_abs = max_abs.max(v.abs());
        } else {
            all_valid = false;
        }
    }
    if !any_valid {
        return Vec::new();
    }
    if !all_valid {
        let c = max_abs + 1.0;
        let large = 2.0 * rows.min(cols) as f64 * c + 1.0;
        for v in cost.iter_mut() {
            if !v.is_finite() {
                *v = large;
            }
        }
    }
    match lsap::solve(rows, cols, cost, false) {
        Ok((r, c)) => r.into_iter().zip(c).collect(),
        Err(_) => Vec::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    const NAN: f64 = f64::NAN;

    #[test]
    fn keeps_previous_pairing_then_switches() {
        let mut acc = MotAccumulator::new();
        let mut ev = vec![];
        // Frame 1: object 1 pairs with hypothesis 10.
        acc.update(&[1], &[10, 11], &[0.5, 0.2], &mut ev);
        assert_eq!(ev[0].kind, EventKind::Match);
        assert_eq!(ev[0].hypothesis, Some(1)); // the closer one, 11
                                               // Frame 2: 11 is still valid though 10 is closer: the pairing is kept.
        ev.clear();
        acc.update(&[1], &[10, 11], &[0.1, 1.5], &mut ev);
        assert_eq!(ev[0].kind, EventKind::Match);
        assert_eq!(ev[0].hypothesis, Some(1));
        assert_eq!(ev[1].kind, EventKind::FalsePositive);
        // Frame 3: 11 out of range: switch to 10.
        ev.clear();
        acc.update(&[1], &[10, 11], &[0.1, NAN], &mut ev);
        assert_eq!(ev[0].kind, EventKind::Switch);
        // Frame 4: missed, then frame 5 back on 10: no switch (pairing survives misses).
        ev.clear();
        acc.update(&[1], &[], &[], &mut ev);
        assert_eq!(ev[0].kind, EventKind::Miss);
        ev.clear();
        acc.update(&[1], &[10], &[0.3], &mut ev);
        assert_eq!(ev[0].kind, EventKind::Match);
    }

    #[test]
    fn expensive_edges_maximise_matches_first() {
        // Object 0 can match hypothesis 0 or 1; object 1 only hypothesis 0. Pure min cost on
        // valid entries would pair 0-0; with the expensive edges, both objects are matched.
        let mut cost = vec![0.1, 1.0, 1.5, NAN];
        let pairs = assign_with_missing_edges(&mut cost, 2, 2);
        assert_eq!(pairs, vec![(0, 1), (1, 0)]);
    }
}
