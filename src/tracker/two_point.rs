//! Two-point initialization (an option beyond the paper, `levers.two_point_speed`): a track born
//! in the previous frame has no velocity yet (the paper starts it at zero, with the small
//! velocity variance of `P0`), so an object that moved further than the gate allows in one
//! frame, such as a car at 15 m/s between nuScenes keyframes 0.5 s apart, is never matched
//! again and starts a new track every frame. After the association rounds, a detection left
//! unmatched (one that could start a track) may continue such a track when their centres are
//! within `two_point_speed x elapsed time` on the ground plane, nearest pairs first; the track
//! then restarts at the detection with the velocity of the displacement
//! ([`super::kalman::KalmanState::restart_two_point`]). This is the two-point differencing
//! initialization of the tracking literature (Bar-Shalom, Li and Kirubarajan, *Estimation with
//! Applications to Tracking and Navigation*, 2001).

use super::boxes::Detection;
use super::matching::Pair;
use super::track::Track;

/// Fills `out` with the candidate pairs of the two-point round: detections `d < n_high` not yet
/// matched (`matched_det`) against tracks born in the previous frame and not matched in this
/// one, whose ground-plane centre distance is at most `radius` metres; the cost is that
/// distance. Centres are compared as the boxes' centres (the origin convention does not move
/// x and y).
pub fn candidates(
    tracks: &[Track],
    dets: &[u32],
    all: &[Detection],
    matched_det: &[bool],
    n_high: usize,
    radius: f64,
    out: &mut Vec<Pair>,
) {
    out.clear();
    for (ti, t) in tracks.iter().enumerate() {
        if !just_born_and_unmatched(t) {
            continue;
        }
        for (d, &di) in dets.iter().enumerate().take(n_high) {
            if matched_det[d] {
                continue;
            }
            let c = all[di as usize].bbox.center;
            let dist = (c[0] - t.kf.x[0]).hypot(c[1] - t.kf.x[1]);
            if dist <= radius {
                out.push(Pair {
                    cost: dist,
                    det: d as u32,
                    trk: ti as u32,
                });
            }
        }
    }
}

/// Born one frame ago (one hit, one prediction since) and not matched this frame.
fn just_born_and_unmatched(t: &Track) -> bool {
    t.hits == 1 && t.age == 1 && t.time_since_update == 1
}
