//! The simulated ego vehicle of `probmot simulate --ego-frame`: a car driving a slalom of
//! 90-degree turns, whose pose gives the `base_link` frame the detections are written in.
//!
//! The path repeats four segments of [`SEGMENT_S`] seconds at [`SPEED`] m/s: straight, a left
//! turn of 90 degrees, straight, a right turn of 90 degrees. The pose at any time is exact
//! (arcs integrated in closed form), so the transforms written at and between the frame stamps
//! agree with the ones used to move the detections.

use std::f64::consts::FRAC_PI_2;

use crate::tracker::angle::wrap;

/// Name of the ego frame.
pub const EGO_FRAME: &str = "base_link";
/// Name of the fixed frame.
pub const FIXED_FRAME: &str = "map";
/// Ego speed, m/s.
pub const SPEED: f64 = 8.0;
/// Duration of each segment, s.
pub const SEGMENT_S: f64 = 4.0;
/// Transforms written per frame period (one at the frame's stamp, the others between frames).
pub const TRANSFORMS_PER_FRAME: u32 = 5;

/// Pose of the ego vehicle in the fixed frame: `x`, `y`, `yaw` (z = 0, no roll or pitch).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EgoPose {
    /// Position x, m.
    pub x: f64,
    /// Position y, m.
    pub y: f64,
    /// Heading, rad.
    pub yaw: f64,
}

fn segment_rate(k: u64) -> f64 {
    match k % 4 {
        1 => FRAC_PI_2 / SEGMENT_S,
        3 => -FRAC_PI_2 / SEGMENT_S,
        _ => 0.0,
    }
}

fn advance(p: EgoPose, rate: f64, dt: f64) -> EgoPose {
    let dyaw = rate * dt;
    let (x, y) = if rate == 0.0 {
        (
            p.x + SPEED * dt * p.yaw.cos(),
            p.y + SPEED * dt * p.yaw.sin(),
        )
    } else {
        let r = SPEED / rate;
        (
            p.x + r * ((p.yaw + dyaw).sin() - p.yaw.sin()),
            p.y + r * (p.yaw.cos() - (p.yaw + dyaw).cos()),
        )
    };
    EgoPose {
        x,
        y,
        yaw: p.yaw + dyaw,
    }
}

/// The ego pose `t` seconds after the first frame (`t >= 0`).
pub fn ego_pose(t: f64) -> EgoPose {
    let mut p = EgoPose {
        x: 0.0,
        y: 0.0,
        yaw: 0.0,
    };
    let whole = (t / SEGMENT_S).floor().max(0.0) as u64;
    for k in 0..whole {
        p = advance(p, segment_rate(k), SEGMENT_S);
    }
    let p = advance(p, segment_rate(whole), t - whole as f64 * SEGMENT_S);
    EgoPose {
        yaw: wrap(p.yaw),
        ..p
    }
}

impl EgoPose {
    /// A point of the fixed frame in ego coordinates.
    pub fn to_ego(&self, c: [f64; 3]) -> [f64; 3] {
        let (s, co) = self.yaw.sin_cos();
        let dx = c[0] - self.x;
        let dy = c[1] - self.y;
        [co * dx + s * dy, -s * dx + co * dy, c[2]]
    }

    /// A heading of the fixed frame in ego coordinates.
    pub fn yaw_to_ego(&self, yaw: f64) -> f64 {
        wrap(yaw - self.yaw)
    }

    /// A velocity of the fixed frame in ego axes (rotated only).
    pub fn rotate_to_ego(&self, v: [f64; 3]) -> [f64; 3] {
        let (s, co) = self.yaw.sin_cos();
        [co * v[0] + s * v[1], -s * v[0] + co * v[1], v[2]]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slalom_turns_left_then_right_and_is_continuous() {
        let p = ego_pose(2.0 * SEGMENT_S);
        assert!((p.yaw - FRAC_PI_2).abs() < 1e-12);
        // After the first straight (32 m) the left arc of radius 8*4/(pi/2) ends at +r, +r.
        let r = SPEED * SEGMENT_S / FRAC_PI_2;
        assert!((p.x - (SPEED * SEGMENT_S + r)).abs() < 1e-9);
        assert!((p.y - r).abs() < 1e-9);
        assert!(ego_pose(4.0 * SEGMENT_S).yaw.abs() < 1e-12);
        // Continuity across a segment boundary.
        let a = ego_pose(SEGMENT_S - 1e-9);
        let b = ego_pose(SEGMENT_S + 1e-9);
        assert!((a.x - b.x).abs() < 1e-6 && (a.y - b.y).abs() < 1e-6);
        // to_ego inverts the pose.
        let q = ego_pose(5.3);
        let e = q.to_ego([q.x, q.y, 1.0]);
        assert!(e[0].abs() < 1e-12 && e[1].abs() < 1e-12);
    }
}
