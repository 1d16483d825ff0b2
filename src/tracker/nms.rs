//! Non-maximum suppression of duplicate detections of one class before association
//! (SimpleTrack uses 3D IoU 0.1 on nuScenes).

use super::boxes::Detection;
use super::geometry::iou3d;

/// Buffers reused across frames.
#[derive(Debug, Default)]
pub struct NmsScratch {
    order: Vec<u32>,
    keep: Vec<bool>,
}

/// Drops from `dets` (indices into `all`) every detection whose 3D IoU with a kept detection of
/// higher score (ties: lower index) exceeds `max_iou`. The kept indices stay in their order.
pub fn suppress(dets: &mut Vec<u32>, all: &[Detection], max_iou: f64, s: &mut NmsScratch) {
    if dets.len() < 2 {
        return;
    }
    s.order.clear();
    s.order.extend(0..dets.len() as u32);
    s.order.sort_by(|&a, &b| {
        let (da, db) = (
            &all[dets[a as usize] as usize],
            &all[dets[b as usize] as usize],
        );
        db.score.total_cmp(&da.score).then(a.cmp(&b))
    });
    s.keep.clear();
    s.keep.resize(dets.len(), false);
    for i in 0..s.order.len() {
        let cand = &all[dets[s.order[i] as usize] as usize].bbox;
        let dup = s.order[..i].iter().any(|&k| {
            s.keep[k as usize] && iou3d(cand, &all[dets[k as usize] as usize].bbox) > max_iou
        });
        s.keep[s.order[i] as usize] = !dup;
    }
    let mut i = 0;
    dets.retain(|_| {
        i += 1;
        s.keep[i - 1]
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tracker::Box3;

    fn det(x: f64, score: f64) -> Detection {
        Detection {
            bbox: Box3 {
                center: [x, 0.0, 0.0],
                yaw: 0.0,
                size: [4.0, 2.0, 1.5],
            },
            class: 0,
            score,
        }
    }

    #[test]
    fn drops_the_lower_scoring_duplicate_only() {
        // 0 and 1 overlap (IoU 3/5 = 0.6), 2 is far away.
        let all = [det(0.0, 0.5), det(1.0, 0.9), det(20.0, 0.1)];
        let mut s = NmsScratch::default();
        let mut dets = vec![0, 1, 2];
        suppress(&mut dets, &all, 0.5, &mut s);
        assert_eq!(dets, vec![1, 2]);
        let mut dets = vec![0, 1, 2];
        suppress(&mut dets, &all, 0.7, &mut s);
        assert_eq!(dets, vec![0, 1, 2]);
    }

    #[test]
    fn suppressed_boxes_do_not_suppress() {
        // a (best) suppresses b; b would have suppressed c, but c only touches a lightly.
        let all = [det(0.0, 0.9), det(1.5, 0.8), det(3.0, 0.7)];
        let mut dets = vec![0, 1, 2];
        suppress(&mut dets, &all, 0.4, &mut NmsScratch::default());
        assert_eq!(dets, vec![0, 2]);
    }
}
