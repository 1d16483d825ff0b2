//! The Kalman filter of one track: constant linear and angular velocity model, `H = [I7 0]`.

use nalgebra::{Cholesky, SMatrix, SVector};

use super::angle::{correct_orientation, fold_half_turn, wrap};
use super::boxes::Box3;

/// 11-d state `x y z yaw l w h dx dy dz dyaw` (velocities per nominal frame).
pub type State = SVector<f64, 11>;
/// 11x11 state covariance.
pub type StateCov = SMatrix<f64, 11, 11>;
/// 7-d measurement `x y z yaw l w h`.
pub type Meas = SVector<f64, 7>;
/// 7x7 measurement-space covariance.
pub type MeasCov = SMatrix<f64, 7, 7>;

/// Mean and covariance of one object.
#[derive(Debug, Clone)]
pub struct KalmanState {
    /// State mean.
    pub x: State,
    /// State covariance (kept symmetric positive definite).
    pub p: StateCov,
}

/// Noise of one class as full diagonal matrices.
#[derive(Debug, Clone)]
pub struct Noise {
    /// Process noise per nominal frame.
    pub q: StateCov,
    /// Measurement noise.
    pub r: MeasCov,
    /// Initial covariance.
    pub p0: StateCov,
    /// Whether yaw follows `dyaw`.
    pub angular_velocity: bool,
}

impl Noise {
    /// Builds the matrices from diagonals.
    pub fn from_diagonals(q: &[f64; 11], r: &[f64; 7], p0: &[f64; 11], angular: bool) -> Self {
        Noise {
            q: StateCov::from_diagonal(&State::from_row_slice(q)),
            r: MeasCov::from_diagonal(&Meas::from_row_slice(r)),
            p0: StateCov::from_diagonal(&State::from_row_slice(p0)),
            angular_velocity: angular,
        }
    }
}

/// The transition matrix over `k` nominal frames.
pub fn transition(k: f64, angular_velocity: bool) -> StateCov {
    let mut a = StateCov::identity();
    a[(0, 7)] = k;
    a[(1, 8)] = k;
    a[(2, 9)] = k;
    if angular_velocity {
        a[(3, 10)] = k;
    }
    a
}

/// Per-frame association cache: the predicted measurement and the Cholesky factor of `S`.
#[derive(Debug, Clone)]
pub struct Innovation {
    /// Predicted measurement `H x`.
    pub z_pred: Meas,
    /// Lower-triangular Cholesky factor `L` of `S = H P H^T + R`.
    pub l: MeasCov,
    /// `S[0,0] + S[1,1]`: a bound used by the pre-gate (`|y_xy|^2 <= g^2 * trace` is necessary).
    pub trace_xy: f64,
}

impl KalmanState {
    /// A new state at a measured box: zero velocity, covariance `P0`.
    pub fn new(b: &Box3, noise: &Noise) -> Self {
        let z = b.to_measurement();
        let mut x = State::zeros();
        x.fixed_rows_mut::<7>(0).copy_from(&z);
        x[3] = wrap(x[3]);
        KalmanState { x, p: noise.p0 }
    }

    /// Prediction over `k` nominal frames: `x = A x`, `P = A P A^T + k Q`.
    ///
    /// `A` is the identity plus `k` on the (position, velocity) couplings, so `A P A^T` is
    /// computed as row and column additions (about 90 multiply-adds instead of two dense
    /// 11x11 products).
    pub fn predict(&mut self, k: f64, noise: &Noise) {
        let m = if noise.angular_velocity { 4 } else { 3 };
        for i in 0..m {
            self.x[i] += k * self.x[i + 7];
        }
        self.x[3] = wrap(self.x[3]);
        let p = &mut self.p;
        for i in 0..m {
            for j in 0..11 {
                p[(i, j)] += k * p[(i + 7, j)];
            }
        }
        for i in 0..m {
            for r in 0..11 {
                p[(r, i)] += k * p[(r, i + 7)];
            }
        }
        for i in 0..11 {
            p[(i, i)] += k * noise.q[(i, i)];
        }
    }

    /// Predicted measurement and the Cholesky factor of the innovation covariance.
    pub fn innovation(&self, noise: &Noise) -> Innovation {
        let s = self.p.fixed_view::<7, 7>(0, 0).into_owned() + noise.r;
        let l = match Cholesky::new(s) {
            Some(c) => c.l(),
            // S = HPH^T + R with R positive definite cannot fail unless P lost definiteness;
            // fall back to the diagonal so that the tracker never produces NaN.
            None => MeasCov::from_diagonal(&s.diagonal().map(|v| v.max(1e-12).sqrt())),
        };
        Innovation {
            z_pred: self.x.fixed_rows::<7>(0).into_owned(),
            l,
            trace_xy: s[(0, 0)] + s[(1, 1)],
        }
    }

    /// Kalman update with a measured box, after the orientation correction.
    pub fn update(&mut self, b: &Box3, noise: &Noise) {
        let inn = self.innovation(noise);
        self.update_with(b, noise, &inn);
    }

    /// Kalman update reusing this frame's innovation (the Cholesky factor `L` of `S`, computed
    /// once per track per frame for the distance). Flipping the track's yaw by `pi` (the
    /// orientation correction) leaves `P`, hence `S`, unchanged.
    ///
    /// With `C = H P` and `V = L^-1 C`: the gain is `K = C^T S^-1 = (L^-T V)^T` and the
    /// covariance becomes `P - K C = P - V^T V`, a symmetric downdate by construction. Should
    /// rounding ever leave a non-positive variance, the Joseph form
    /// `(I - KH) P (I - KH)^T + K R K^T` is used instead.
    pub fn update_with(&mut self, b: &Box3, noise: &Noise, inn: &Innovation) {
        let (track_yaw, yaw_residual) = correct_orientation(self.x[3], b.yaw);
        self.x[3] = track_yaw;
        let mut y = b.to_measurement() - self.x.fixed_rows::<7>(0);
        y[3] = yaw_residual;
        let c: SMatrix<f64, 7, 11> = self.p.fixed_view::<7, 11>(0, 0).into_owned();
        let Some(v) = inn.l.solve_lower_triangular(&c) else {
            return;
        };
        let Some(w) = inn.l.tr_solve_lower_triangular(&v) else {
            return;
        };
        // K = W^T (11x7).
        self.x += w.tr_mul(&y);
        self.x[3] = wrap(self.x[3]);
        let before = self.p;
        self.p -= v.tr_mul(&v);
        symmetrize(&mut self.p);
        if (0..11).any(|i| self.p[(i, i)].is_nan() || self.p[(i, i)] <= 0.0) {
            let k = w.transpose();
            let mut i_kh = StateCov::identity();
            {
                let mut block = i_kh.fixed_view_mut::<11, 7>(0, 0);
                block -= k;
            }
            self.p = i_kh * before * i_kh.transpose() + k * noise.r * k.transpose();
            symmetrize(&mut self.p);
        }
    }
}

/// Mahalanobis distance `sqrt(y^T S^-1 y)` of a measured box from a predicted one, with the
/// yaw residual folded into `[-pi/2, pi/2]`. Uses the Cholesky factor: `|L^-1 y|`.
#[inline]
pub fn mahalanobis(inn: &Innovation, b: &Box3) -> f64 {
    let mut y = b.to_measurement() - inn.z_pred;
    y[3] = fold_half_turn(y[3]);
    // Forward substitution with the lower-triangular factor.
    let l = &inn.l;
    let mut v = [0.0f64; 7];
    let mut sum = 0.0;
    for i in 0..7 {
        let mut acc = y[i];
        for j in 0..i {
            acc -= l[(i, j)] * v[j];
        }
        v[i] = acc / l[(i, i)];
        sum += v[i] * v[i];
    }
    sum.sqrt()
}

fn symmetrize(p: &mut StateCov) {
    for i in 0..11 {
        for j in (i + 1)..11 {
            let m = 0.5 * (p[(i, j)] + p[(j, i)]);
            p[(i, j)] = m;
            p[(j, i)] = m;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn noise() -> Noise {
        // P0 = 2 on measured entries, 10 on velocities; Q = 0.5 on x,y,z,yaw and velocities.
        let mut p0 = [2.0; 11];
        p0[7..].iter_mut().for_each(|v| *v = 10.0);
        let q = [0.5, 0.5, 0.5, 0.5, 0.0, 0.0, 0.0, 0.5, 0.5, 0.5, 0.5];
        Noise::from_diagonals(&q, &[1.0; 7], &p0, true)
    }

    fn bx(x: f64, y: f64, yaw: f64) -> Box3 {
        Box3 {
            center: [x, y, 0.0],
            yaw,
            size: [4.0, 2.0, 1.5],
        }
    }

    /// Hand-worked predict and update on the x / dx block (the blocks are independent):
    /// after predict, P_xx = 2 + 10 + 0.5 = 12.5, P_x,dx = 10, P_dxdx = 10.5.
    /// With a measurement at x = 1: S = 13.5, K = [12.5, 10] / 13.5,
    /// x = 12.5/13.5 = 0.925926, dx = 10/13.5 = 0.740741,
    /// P_xx = 12.5 - 12.5^2/13.5 = 0.925926, P_dxdx = 10.5 - 100/13.5 = 3.092593.
    #[test]
    fn predict_and_update_by_hand() {
        let n = noise();
        let mut s = KalmanState::new(&bx(0.0, 0.0, 0.0), &n);
        s.predict(1.0, &n);
        assert!((s.p[(0, 0)] - 12.5).abs() < 1e-12);
        assert!((s.p[(0, 7)] - 10.0).abs() < 1e-12);
        assert!((s.p[(7, 7)] - 10.5).abs() < 1e-12);
        assert!((s.p[(4, 4)] - 2.0).abs() < 1e-12); // size: no process noise
        s.update(&bx(1.0, 0.0, 0.0), &n);
        assert!((s.x[0] - 12.5 / 13.5).abs() < 1e-12);
        assert!((s.x[7] - 10.0 / 13.5).abs() < 1e-12);
        assert!((s.p[(0, 0)] - (12.5 - 12.5 * 12.5 / 13.5)).abs() < 1e-12);
        assert!((s.p[(7, 7)] - (10.5 - 100.0 / 13.5)).abs() < 1e-12);
        assert!((s.p[(0, 7)] - (10.0 - 12.5 * 10.0 / 13.5)).abs() < 1e-12);
        assert_eq!(s.x[1], 0.0);
    }

    #[test]
    fn predict_scales_with_gap() {
        let n = noise();
        let mut s = KalmanState::new(&bx(0.0, 0.0, 0.0), &n);
        s.x[7] = 2.0; // 2 m per nominal frame
        s.x[10] = 0.1;
        s.predict(2.5, &n);
        assert!((s.x[0] - 5.0).abs() < 1e-12);
        assert!((s.x[3] - 0.25).abs() < 1e-12);
        // P_xx = 2 + 2.5^2 * 10 + 2.5 * 0.5
        assert!((s.p[(0, 0)] - (2.0 + 62.5 + 1.25)).abs() < 1e-12);
    }

    #[test]
    fn mahalanobis_matches_explicit_inverse() {
        let n = noise();
        let mut s = KalmanState::new(&bx(0.0, 0.0, 0.0), &n);
        s.predict(1.0, &n);
        let inn = s.innovation(&n);
        let det = bx(1.0, -2.0, 0.3);
        let d = mahalanobis(&inn, &det);
        let sm = s.p.fixed_view::<7, 7>(0, 0).into_owned() + n.r;
        let mut y = det.to_measurement() - inn.z_pred;
        y[3] = fold_half_turn(y[3]);
        let expected = (y.transpose() * sm.try_inverse().unwrap() * y)[(0, 0)].sqrt();
        assert!((d - expected).abs() < 1e-12);
        // diagonal S here: sqrt(1/13.5 + 4/13.5 + 0.09/13.5)
        assert!((d - (5.09f64 / 13.5).sqrt()).abs() < 1e-12);
    }

    #[test]
    fn flipped_detection_is_close_in_distance_and_update() {
        let n = noise();
        let mut s = KalmanState::new(&bx(0.0, 0.0, 0.1), &n);
        s.predict(1.0, &n);
        let inn = s.innovation(&n);
        let flipped = bx(0.0, 0.0, 0.1 + std::f64::consts::PI);
        assert!(mahalanobis(&inn, &flipped) < 1e-9);
        s.update(&flipped, &n);
        // The track was flipped by pi and then matched the detection exactly.
        assert!((wrap(s.x[3] - flipped.yaw)).abs() < 1e-9, "{}", s.x[3]);
    }
}
