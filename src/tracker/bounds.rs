//! The physical bounds every value in and out of probmot keeps to: detections beyond them are
//! skipped, configs beyond them refused, and tracks whose state leaves them are ended. Large
//! enough for Earth-centred and UTM frames (coordinates up to 1e7 m); see docs/inputs.md
//! "Bounds on values".

/// Largest absolute box-centre coordinate, metres (Earth-centred frames reach 6.4e6 m).
pub const MAX_COORDINATE: f64 = 1e7;

/// Largest box size (length, width or height), metres.
pub const MAX_SIZE: f64 = 1e4;

/// Largest absolute velocity component, m/s.
pub const MAX_SPEED: f64 = 1e5;

/// Smallest positive variance a config may give (any unit).
pub const MIN_VARIANCE: f64 = 1e-12;

/// Largest variance a config may give, and the largest a track may reach before it is ended.
pub const MAX_VARIANCE: f64 = 1e12;

/// Largest absolute value of any other number of a config (thresholds, scores, speeds).
pub const MAX_MAGNITUDE: f64 = 1e12;

/// Whether `v` is a variance a config may give: finite and within
/// `[MIN_VARIANCE, MAX_VARIANCE]`, or exactly zero when `zero_ok`.
pub fn variance_ok(v: f64, zero_ok: bool) -> bool {
    (zero_ok && v == 0.0) || (MIN_VARIANCE..=MAX_VARIANCE).contains(&v)
}

/// Whether `v` is a finite number within `MAX_MAGNITUDE` of zero.
pub fn magnitude_ok(v: f64) -> bool {
    v.is_finite() && v.abs() <= MAX_MAGNITUDE
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn variances_are_finite_positive_and_bounded() {
        assert!(variance_ok(1.0, false) && variance_ok(1e12, false));
        assert!(!variance_ok(1e308, false) && !variance_ok(f64::NAN, true));
        assert!(!variance_ok(f64::INFINITY, true) && !variance_ok(1e-13, true));
        assert!(!variance_ok(0.0, false) && variance_ok(0.0, true));
        assert!(!variance_ok(-1.0, true));
        assert!(magnitude_ok(-1e12) && !magnitude_ok(1e13) && !magnitude_ok(f64::NAN));
    }
}
