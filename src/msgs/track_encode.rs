//! The tracks output: one reported track of the tracker as a `probmot.Tracks3D` entry.

use std::collections::BTreeMap;

use super::{short_precision, size3, v3, ImageBox, Track3D};
use crate::tracker::TrackReport;

/// Writes one reported track into an output message, reusing its allocations (the image box and
/// attributes are left to the caller).
pub fn fill_track3d(t: &mut Track3D, r: &TrackReport, label: &str) {
    t.id = r.id;
    t.label.clear();
    t.label.push_str(label);
    t.center = Some(v3(r.bbox.center));
    t.size = Some(size3(r.bbox.size));
    t.yaw = r.bbox.yaw;
    t.velocity = Some(v3(r.velocity));
    t.yaw_rate = r.yaw_rate;
    t.score = r.score;
    // A 12-bit mantissa (`short_precision`): a variance's fifth digit means nothing, and full
    // digits cost a tenth of the tracks channel's bytes.
    t.position_variance = Some(v3(r.position_variance.map(short_precision)));
    t.yaw_variance = short_precision(r.yaw_variance);
    t.age = r.age;
    t.hits = r.hits;
    t.frames_since_update = r.frames_since_update;
}

/// The output message of one reported track.
pub fn to_track3d(
    r: &TrackReport,
    label: &str,
    image_box: Option<ImageBox>,
    attributes: BTreeMap<String, String>,
) -> Track3D {
    let mut t = Track3D {
        image_box,
        attributes,
        ..Default::default()
    };
    fill_track3d(&mut t, r, label);
    t
}

/// Filter variances of a track's velocity in x, y, z (m²/s²) and of its yaw rate (rad²/s²),
/// kept beside its [`Track3D`] (which has no field for them) for the outputs that carry them
/// (Autoware's `TrackedObject` twist covariance, [`super::autoware_tracks`]).
pub type RateVariances = [f64; 4];

/// The [`RateVariances`] of one reported track.
pub fn rate_variances(r: &TrackReport) -> RateVariances {
    let v = r.velocity_variance;
    [v[0], v[1], v[2], r.yaw_rate_variance]
}
