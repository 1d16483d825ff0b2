//! Angle helpers: wrapping to `[-pi, pi)` and folding heading residuals.

use std::f64::consts::{FRAC_PI_2, PI, TAU};

/// Wraps an angle (radians) into `[-pi, pi)`.
#[inline]
pub fn wrap(angle: f64) -> f64 {
    if (-PI..PI).contains(&angle) {
        return angle;
    }
    let a = (angle + PI).rem_euclid(TAU) - PI;
    // rem_euclid can return TAU for tiny negative inputs through rounding.
    if a >= PI {
        a - TAU
    } else {
        a
    }
}

/// Folds a heading residual into `[-pi/2, pi/2]`: a box seen front-to-back (180 degrees off)
/// counts as aligned. Used by the distance, as in the paper and AB3DMOT.
#[inline]
pub fn fold_half_turn(residual: f64) -> f64 {
    let mut r = wrap(residual);
    if r > FRAC_PI_2 {
        r -= PI;
    } else if r < -FRAC_PI_2 {
        r += PI;
    }
    r
}

/// Orientation correction applied before a Kalman update: returns the track heading to use so
/// that the detection differs from it by an acute angle. When the wrapped difference lies strictly
/// between 90 and 270 degrees the track heading is flipped by `pi`.
///
/// Returns `(corrected_track_yaw, residual)` with `residual = detection - corrected` in `[-pi/2, pi/2]`.
#[inline]
pub fn correct_orientation(track_yaw: f64, detection_yaw: f64) -> (f64, f64) {
    let t = wrap(track_yaw);
    let d = wrap(detection_yaw);
    let diff = wrap(d - t);
    if diff.abs() > FRAC_PI_2 {
        let flipped = wrap(t + PI);
        (flipped, wrap(d - flipped))
    } else {
        (t, diff)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrap_stays_in_half_open_range() {
        assert_eq!(wrap(PI), -PI);
        assert!((wrap(3.0 * PI / 2.0) - (-PI / 2.0)).abs() < 1e-12);
        assert!((wrap(-3.0 * PI / 2.0) - (PI / 2.0)).abs() < 1e-12);
        assert!((wrap(7.0 * TAU + 0.25) - 0.25).abs() < 1e-9);
        for i in -1000..1000 {
            let a = wrap(i as f64 * 0.0137);
            assert!((-PI..PI).contains(&a), "{a}");
        }
    }

    #[test]
    fn wrap_across_plus_minus_pi() {
        // 179 degrees and -179 degrees are 2 degrees apart, not 358.
        let a = 179f64.to_radians();
        let b = -179f64.to_radians();
        assert!((wrap(b - a) - 2f64.to_radians()).abs() < 1e-12);
        assert!((fold_half_turn(b - a) - 2f64.to_radians()).abs() < 1e-12);
    }

    #[test]
    fn fold_treats_opposite_headings_as_aligned() {
        assert!(fold_half_turn(PI).abs() < 1e-12);
        assert!((fold_half_turn(170f64.to_radians()) - (-10f64).to_radians()).abs() < 1e-12);
        assert!((fold_half_turn(-100f64.to_radians()) - 80f64.to_radians()).abs() < 1e-12);
        assert!((fold_half_turn(30f64.to_radians()) - 30f64.to_radians()).abs() < 1e-12);
    }

    #[test]
    fn orientation_correction_flips_between_90_and_270() {
        // Track at 0, detection at 200 degrees: difference 200 (wrapped -160) -> flip to 180.
        let (t, r) = correct_orientation(0.0, 200f64.to_radians());
        assert!((wrap(t - PI)).abs() < 1e-12);
        assert!((r - 20f64.to_radians()).abs() < 1e-12);
        // 80 degrees apart: no flip.
        let (t, r) = correct_orientation(0.0, 80f64.to_radians());
        assert_eq!(t, 0.0);
        assert!((r - 80f64.to_radians()).abs() < 1e-12);
        // Across the seam: track 170, detection -170 -> 20 apart, no flip.
        let (t, r) = correct_orientation(170f64.to_radians(), -170f64.to_radians());
        assert!((t - 170f64.to_radians()).abs() < 1e-12);
        assert!((r - 20f64.to_radians()).abs() < 1e-12);
    }
}
