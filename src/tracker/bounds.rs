//! The physical bounds every value in and out of probmot keeps to: detections beyond them are
//! skipped, configs beyond them refused, and tracks whose state leaves them are ended. Large
//! enough for Earth-centred and UTM frames (coordinates up to 1e7 m); see docs/inputs.md
//! "Bounds on values".

use super::track::TrackReport;

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

/// Whether every number of a track report is finite and within the bounds: centre, size,
/// velocity, and every variance at most [`MAX_VARIANCE`].
pub fn report_ok(r: &TrackReport) -> bool {
    let b = &r.bbox;
    let variances = (r.position_variance.iter())
        .chain(&r.velocity_variance)
        .chain([&r.yaw_variance, &r.yaw_rate_variance]);
    b.center.iter().all(|v| v.abs() <= MAX_COORDINATE)
        && b.size.iter().all(|v| v.abs() <= MAX_SIZE)
        && r.velocity.iter().all(|v| v.abs() <= MAX_SPEED)
        && b.yaw.is_finite()
        && r.yaw_rate.is_finite()
        && variances
            .into_iter()
            .all(|v| (0.0..=MAX_VARIANCE).contains(v))
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

    /// A track whose variance grows past the ceiling over a long gap between frames is ended
    /// (neither reported nor kept), and counted; a gap that keeps it within is not.
    #[test]
    fn a_track_beyond_the_bounds_is_ended() {
        use crate::tracker::{Box3, Detection, Tracker, TrackerConfig};
        let mut cfg = TrackerConfig::preset("ab3dmot-2019").unwrap();
        let class = cfg.default.as_mut().unwrap();
        class.p0[7..].copy_from_slice(&[1e8; 4]);
        (class.min_hits, class.max_age) = (1, 5);
        let mut t = Tracker::new(cfg).unwrap();
        let car = t.class_id("car").unwrap();
        let det = Detection {
            bbox: Box3 {
                center: [0.0, 0.0, 0.0],
                yaw: 0.0,
                size: [4.0, 2.0, 1.5],
            },
            class: car,
            score: 0.9,
        };
        assert_eq!(t.step(0, &[det]).unwrap().len(), 1);
        let second = 1_000_000_000;
        assert_eq!(
            t.step(second, &[]).unwrap().len(),
            1,
            "a coast of 10 frames"
        );
        assert_eq!(t.stats().beyond_bounds, 0);
        let hour = 3600 * second;
        assert!(
            t.step(hour, &[]).unwrap().is_empty(),
            "variance 1e8 * 36000^2"
        );
        assert_eq!((t.stats().beyond_bounds, t.live_tracks()), (1, 0));
        assert_eq!(t.deleted().len(), 1);
    }
}
