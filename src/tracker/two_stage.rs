//! Two-stage association (SimpleTrack, Poly-MOT, ByteTrack): detections under a class's birth
//! score are held back from the first round; they may only continue tracks the first round left
//! unmatched, and never start a track.

use super::boxes::Detection;

/// Moves the detections scoring at least `birth_score` to the front of `dets` (stable within
/// both parts) and returns how many there are. Without a birth score every detection is in the
/// first round and `dets` is untouched.
pub fn split(dets: &mut [u32], all: &[Detection], birth_score: Option<f64>) -> usize {
    let Some(b) = birth_score else {
        return dets.len();
    };
    let high = |i: &u32| all[*i as usize].score >= b;
    // Stable partition in place without allocation: insertion by rotation (frames hold few
    // detections per class).
    let mut n_high = 0;
    for i in 0..dets.len() {
        if high(&dets[i]) {
            dets[n_high..=i].rotate_right(1);
            n_high += 1;
        }
    }
    n_high
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tracker::Box3;
    use proptest::prelude::*;

    fn det(score: f64) -> Detection {
        Detection {
            bbox: Box3 {
                center: [0.0; 3],
                yaw: 0.0,
                size: [1.0; 3],
            },
            class: 0,
            score,
        }
    }

    #[test]
    fn off_keeps_everything() {
        let all = [det(0.1), det(0.9)];
        let mut d = vec![0, 1];
        assert_eq!(split(&mut d, &all, None), 2);
        assert_eq!(d, vec![0, 1]);
    }

    proptest! {
        #[test]
        fn stable_partition(scores in prop::collection::vec(0.0f64..1.0, 0..30), b in 0.0f64..1.0) {
            let all: Vec<Detection> = scores.iter().map(|s| det(*s)).collect();
            let mut d: Vec<u32> = (0..all.len() as u32).collect();
            let n = split(&mut d, &all, Some(b));
            let want_hi: Vec<u32> = (0..all.len() as u32).filter(|i| scores[*i as usize] >= b).collect();
            let want_lo: Vec<u32> = (0..all.len() as u32).filter(|i| scores[*i as usize] < b).collect();
            prop_assert_eq!(&d[..n], &want_hi[..]);
            prop_assert_eq!(&d[n..], &want_lo[..]);
        }
    }
}
