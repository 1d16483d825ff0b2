//! Which ground truth each track box stands for, so that `plot` can give a track the colour of
//! the object it follows: from the evaluation's own decisions (`eval --events`) when given, else
//! a per-frame nearest-centre pairing of boxes of the same class (closest pairs first, within
//! a distance; the nuScenes protocol's 2 m rule). Also the event marks of a window.

use std::collections::HashMap;

use super::plot_types::EventMark;
use super::Frame;
use crate::msgs::eval_event::Kind;
use crate::msgs::eval_events::event_text;
use crate::msgs::EvalEvents;

/// `(stamp, track id) -> ground-truth id` by nearest centres, per frame stamp present in both.
pub fn match_by_distance(
    tracks: &[Frame],
    truth: &[Frame],
    max_dist: f64,
) -> HashMap<(u64, u64), u64> {
    let truth_at: HashMap<u64, &Frame> = truth.iter().map(|f| (f.0, f)).collect();
    let mut out = HashMap::new();
    let mut pairs: Vec<(f64, usize, usize)> = Vec::new();
    for (stamp, trk) in tracks {
        let Some((_, gt)) = truth_at.get(stamp) else {
            continue;
        };
        pairs.clear();
        for (i, t) in trk.iter().enumerate() {
            for (j, g) in gt.iter().enumerate() {
                let d = (t.center[0] - g.center[0]).hypot(t.center[1] - g.center[1]);
                if t.label == g.label && d < max_dist {
                    pairs.push((d, i, j));
                }
            }
        }
        pairs.sort_by(|a, b| a.0.total_cmp(&b.0).then((a.1, a.2).cmp(&(b.1, b.2))));
        let (mut ti, mut gi) = (vec![false; trk.len()], vec![false; gt.len()]);
        for &(_, i, j) in &pairs {
            if !ti[i] && !gi[j] {
                ti[i] = true;
                gi[j] = true;
                out.insert((*stamp, trk[i].id), gt[j].id);
            }
        }
    }
    out
}

/// `(stamp, track id) -> ground-truth id` from the evaluation's matches and switches.
pub fn match_from_events(events: &[EvalEvents]) -> HashMap<(u64, u64), u64> {
    let mut out = HashMap::new();
    for ev in events {
        for e in &ev.events {
            if matches!(e.kind(), Kind::Match | Kind::Switch) {
                out.insert((ev.stamp, e.track_id), e.truth_id);
            }
        }
    }
    out
}

/// The errors among `events` (every kind but matches) of the kept classes, as marks.
pub fn marks(events: &[EvalEvents], keep_class: impl Fn(&str) -> bool) -> Vec<EventMark> {
    let mut out = Vec::new();
    for ev in events {
        for e in ev.events.iter().filter(|e| keep_class(&e.label)) {
            if e.kind() == Kind::Match {
                continue;
            }
            let c = e.center.unwrap_or_default();
            out.push(EventMark {
                kind: e.kind(),
                x: c.x,
                y: c.y,
                text: event_text(e),
                truth_id: e.truth_id,
                track_id: e.track_id,
                previous_track_id: e.previous_track_id,
            });
        }
    }
    // Switches and fragmentations last, so they are drawn over the rest.
    out.sort_by_key(|m| matches!(m.kind, Kind::Switch | Kind::Fragmentation));
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mcapio::LabelledBox;

    fn b(id: u64, x: f64) -> LabelledBox {
        LabelledBox {
            id,
            label: "pedestrian".into(),
            center: [x, 0.0, 0.0],
            size: [0.7, 0.7, 1.8],
            score: 1.0,
            ..Default::default()
        }
    }

    #[test]
    fn nearest_pairs_first_within_the_distance() {
        let truth = vec![(1, vec![b(1, 0.0), b(2, 1.0)]), (2, vec![b(1, 0.0)])];
        // Track 7 is closest to truth 2, track 8 to truth 1; track 9 is too far from anything.
        let tracks = vec![
            (1, vec![b(7, 1.1), b(8, 0.2), b(9, 9.0)]),
            (2, vec![b(7, 0.1)]),
        ];
        let m = match_by_distance(&tracks, &truth, 2.0);
        assert_eq!(m.get(&(1, 7)), Some(&2));
        assert_eq!(m.get(&(1, 8)), Some(&1));
        assert_eq!(m.get(&(1, 9)), None);
        // Frame 2: track 7 now follows truth 1 (the colour changes: a switch shows).
        assert_eq!(m.get(&(2, 7)), Some(&1));
    }
}
