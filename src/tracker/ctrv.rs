//! Coordinated-turn motion (`levers.motion = "ctrv"`): an extended Kalman filter predict on the
//! same 11-d state `x y z yaw l w h dx dy dz dyaw` as the constant-velocity model.
//!
//! Over `k` nominal frames with yaw rate `w = dyaw` and turn angle `t = w k`, the horizontal
//! velocity `(dx, dy)` rotates by `t` and the position advances along the arc:
//!
//! ```text
//! x' = x + S dx - C dy          dx' = cos t dx - sin t dy
//! y' = y + C dx + S dy          dy' = sin t dx + cos t dy
//! S = sin(t) / w,  C = (1 - cos t) / w,  yaw' = yaw + t
//! ```
//!
//! This is the coordinated-turn model with Cartesian velocity (Bar-Shalom, Li and Kirubarajan,
//! *Estimation with Applications to Tracking and Navigation*, 2001, sec. 11.7; Li and Jilkov,
//! "Survey of maneuvering target tracking, part I", IEEE TAES 2003). Poly-MOT (Li et al. 2023)
//! uses a turn-rate model for cars and cyclists. With `w = 0` it is the constant-velocity mean.
//! `S`, `C` and their derivatives are evaluated by Taylor series for `|t| < 1e-2`, so there is
//! no division by a near-zero `w`. The covariance follows `P = F P F^T + k Q` with `F` the
//! Jacobian, which makes `P` dense: the update then uses the dense equations
//! ([`super::kalman`]).

use serde::{Deserialize, Serialize};

use nalgebra::{SMatrix, SVector};

/// The 11-d state (as [`super::kalman::State`]).
type State = SVector<f64, 11>;
/// Its 11x11 Jacobian.
type StateCov = SMatrix<f64, 11, 11>;

/// Motion model of one class.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Motion {
    /// Constant velocity (and constant yaw rate with `angular_velocity`): the paper's model.
    #[default]
    Cv,
    /// Coordinated turn: the velocity turns with the yaw rate (needs `angular_velocity`).
    Ctrv,
}

impl Motion {
    /// True for the constant-velocity default (not serialized).
    pub fn is_cv(&self) -> bool {
        *self == Motion::Cv
    }
}

impl super::choice::Choice for Motion {
    const VALUES: &'static [Self] = &[Motion::Cv, Motion::Ctrv];

    fn name(self) -> &'static str {
        match self {
            Motion::Cv => "cv",
            Motion::Ctrv => "ctrv",
        }
    }

    fn description(self) -> &'static str {
        match self {
            Motion::Cv => "Constant velocity (the paper)",
            Motion::Ctrv => {
                "Coordinated turn (an extended Kalman filter; needs the yaw rate, which it turns on)"
            }
        }
    }
}

/// Below this turn angle the series are used instead of the closed forms.
const SMALL_TURN: f64 = 1e-2;

/// `g(t) = sin(t)/t`, `h(t) = (1 - cos t)/t` and their derivatives `g'(t)`, `h'(t)`.
fn turn_terms(t: f64) -> [f64; 4] {
    if t.abs() < SMALL_TURN {
        let t2 = t * t;
        [
            1.0 - t2 / 6.0 + t2 * t2 / 120.0 - t2 * t2 * t2 / 5040.0,
            t * (0.5 - t2 / 24.0 + t2 * t2 / 720.0 - t2 * t2 * t2 / 40320.0),
            t * (-1.0 / 3.0 + t2 / 30.0 - t2 * t2 / 840.0),
            0.5 - t2 / 8.0 + t2 * t2 / 144.0 - t2 * t2 * t2 / 5760.0,
        ]
    } else {
        let (s, c) = t.sin_cos();
        let t2 = t * t;
        [
            s / t,
            (1.0 - c) / t,
            (t * c - s) / t2,
            (t * s - (1.0 - c)) / t2,
        ]
    }
}

/// The coordinated-turn state after `k` nominal frames (yaw not wrapped).
pub fn propagate(x: &State, k: f64) -> State {
    let (vx, vy, w) = (x[7], x[8], x[10]);
    let t = w * k;
    let [g, h, _, _] = turn_terms(t);
    let (s, c) = (k * g, k * h);
    let (sin, cos) = t.sin_cos();
    let mut y = *x;
    y[0] += s * vx - c * vy;
    y[1] += c * vx + s * vy;
    y[2] += k * x[9];
    y[3] += t;
    y[7] = cos * vx - sin * vy;
    y[8] = sin * vx + cos * vy;
    y
}

/// The Jacobian of [`propagate`] with respect to the state.
pub fn jacobian(x: &State, k: f64) -> StateCov {
    let (vx, vy, w) = (x[7], x[8], x[10]);
    let t = w * k;
    let [g, h, dg, dh] = turn_terms(t);
    let (s, c) = (k * g, k * h);
    // d/dw of S = k g(wk) and C = k h(wk).
    let (ds, dc) = (k * k * dg, k * k * dh);
    let (sin, cos) = t.sin_cos();
    let mut f = StateCov::identity();
    f[(0, 7)] = s;
    f[(0, 8)] = -c;
    f[(0, 10)] = ds * vx - dc * vy;
    f[(1, 7)] = c;
    f[(1, 8)] = s;
    f[(1, 10)] = dc * vx + ds * vy;
    f[(2, 9)] = k;
    f[(3, 10)] = k;
    f[(7, 7)] = cos;
    f[(7, 8)] = -sin;
    f[(7, 10)] = -k * (sin * vx + cos * vy);
    f[(8, 7)] = sin;
    f[(8, 8)] = cos;
    f[(8, 10)] = k * (cos * vx - sin * vy);
    f
}

#[cfg(test)]
mod tests {
    use super::*;

    fn state(vx: f64, vy: f64, w: f64) -> State {
        let mut x = State::zeros();
        x[0] = 3.0;
        x[1] = -1.0;
        x[2] = 0.5;
        x[3] = 0.2;
        x[4] = 4.0;
        x[5] = 2.0;
        x[6] = 1.5;
        x[7] = vx;
        x[8] = vy;
        x[9] = 0.05;
        x[10] = w;
        x
    }

    #[test]
    fn zero_turn_is_constant_velocity() {
        let x = state(1.2, -0.7, 0.0);
        let y = propagate(&x, 2.5);
        let mut cv = x;
        for i in 0..4 {
            cv[i] += 2.5 * x[i + 7];
        }
        assert!((y - cv).amax() < 1e-15, "{y} vs {cv}");
    }

    /// A full turn (`w k = 2 pi`) brings the target back to its start with its velocity; a
    /// quarter turn at speed v moves it by the radius `v / w` along both axes.
    #[test]
    fn turns_follow_the_circle() {
        let w = std::f64::consts::PI / 10.0;
        let x = state(1.0, 0.0, w);
        let y = propagate(&x, 20.0);
        assert!((y[0] - x[0]).abs() < 1e-12 && (y[1] - x[1]).abs() < 1e-12);
        assert!((y[7] - 1.0).abs() < 1e-12 && y[8].abs() < 1e-12);
        let q = propagate(&x, 5.0);
        let r = 1.0 / w;
        assert!((q[0] - x[0] - r).abs() < 1e-12 && (q[1] - x[1] - r).abs() < 1e-12);
        assert!(q[7].abs() < 1e-12 && (q[8] - 1.0).abs() < 1e-12);
    }

    /// The series and the closed forms agree where they meet.
    #[test]
    fn series_meets_closed_form() {
        for t in [SMALL_TURN * 0.999, -SMALL_TURN * 0.999] {
            let a = turn_terms(t);
            let b = turn_terms(t * 1.002);
            for i in 0..4 {
                assert!((a[i] - b[i]).abs() < 1e-4, "term {i}: {} vs {}", a[i], b[i]);
            }
        }
        // The closed forms just above the threshold against the series just below.
        let t = SMALL_TURN;
        let (s, c) = t.sin_cos();
        let exact = [s / t, (1.0 - c) / t];
        let series = turn_terms(t * (1.0 - 1e-12));
        assert!((exact[0] - series[0]).abs() < 1e-13);
        assert!((exact[1] - series[1]).abs() < 1e-13);
    }

    /// The Jacobian equals central finite differences of [`propagate`], at large and small
    /// (series) turn rates and at zero.
    #[test]
    fn jacobian_matches_finite_differences() {
        for (w, k) in [
            (0.3, 1.0),
            (-0.8, 2.5),
            (1e-4, 1.0),
            (0.0, 1.5),
            (3e-3, 3.0),
        ] {
            let x = state(1.4, -0.6, w);
            let f = jacobian(&x, k);
            for j in 0..11 {
                let e = 1e-6;
                let (mut a, mut b) = (x, x);
                a[j] += e;
                b[j] -= e;
                let col = (propagate(&a, k) - propagate(&b, k)) / (2.0 * e);
                for i in 0..11 {
                    assert!(
                        (col[i] - f[(i, j)]).abs() < 1e-6,
                        "w {w} k {k}: dF[{i},{j}] = {} vs {}",
                        f[(i, j)],
                        col[i]
                    );
                }
            }
        }
    }
}
