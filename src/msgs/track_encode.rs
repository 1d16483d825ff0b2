//! The tracks output: one reported track of the tracker as a `probmot.Tracks3D` entry.

use std::collections::BTreeMap;

use super::proto_writer::ProtoWriter;
use super::{short_precision, size3, v3, ImageBox, Size3, Track3D, Tracks3D, Vector3};
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

/// Appends the protobuf bytes of `tracks` to `buf`, the bytes prost writes for it, field by
/// field: no length computed beforehand, nothing allocated once `buf` has grown.
pub fn encode_tracks(tracks: &Tracks3D, buf: &mut Vec<u8>) {
    let w = &mut ProtoWriter::new(buf);
    w.uint(1, tracks.stamp);
    w.string(2, &tracks.frame_id);
    for t in &tracks.tracks {
        w.message(3, |w| write_track(w, t));
    }
}

/// The protobuf bytes of `tracks` in `buf` (cleared first), as [`super::encode_into`] writes
/// them, without prost.
pub fn encode_tracks_into(tracks: &Tracks3D, buf: &mut Vec<u8>) {
    buf.clear();
    encode_tracks(tracks, buf);
}

fn write_track(w: &mut ProtoWriter<'_>, t: &Track3D) {
    w.uint(1, t.id);
    w.string(2, &t.label);
    write_vector3(w, 3, t.center.as_ref());
    if let Some(Size3 {
        length,
        width,
        height,
    }) = t.size
    {
        w.doubles(4, &[length, width, height]);
    }
    w.double(5, t.yaw);
    write_vector3(w, 6, t.velocity.as_ref());
    w.double(7, t.yaw_rate);
    w.double(8, t.score);
    write_vector3(w, 9, t.position_variance.as_ref());
    w.double(10, t.yaw_variance);
    w.uint(11, t.age.into());
    w.uint(12, t.hits.into());
    w.uint(13, t.frames_since_update.into());
    if let Some(b) = &t.image_box {
        w.doubles(14, &[b.x1, b.y1, b.x2, b.y2]);
    }
    for (k, v) in &t.attributes {
        w.message(15, |w| {
            w.string(1, k);
            w.string(2, v);
        });
    }
}

fn write_vector3(w: &mut ProtoWriter<'_>, field: u32, v: Option<&Vector3>) {
    if let Some(v) = v {
        w.doubles(field, &[v.x, v.y, v.z]);
    }
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

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::collection::{btree_map, vec};
    use proptest::prelude::*;

    /// Doubles with the values proto3 treats apart: zeros (both signs), NaN, negatives,
    /// infinities, anything.
    fn double() -> impl Strategy<Value = f64> {
        prop_oneof![
            Just(0.0),
            Just(-0.0),
            Just(f64::NAN),
            Just(f64::NEG_INFINITY),
            -1e3..1e3f64,
            any::<f64>(),
        ]
    }

    fn vector3() -> impl Strategy<Value = Option<Vector3>> {
        proptest::option::of(
            (double(), double(), double()).prop_map(|(x, y, z)| Vector3 { x, y, z }),
        )
    }

    fn id() -> impl Strategy<Value = u64> {
        prop_oneof![Just(0), Just(u64::MAX), any::<u64>(), 0..300u64]
    }

    fn count() -> impl Strategy<Value = u32> {
        prop_oneof![Just(0), Just(u32::MAX), any::<u32>(), 0..200u32]
    }

    fn track() -> impl Strategy<Value = Track3D> {
        let size =
            proptest::option::of((double(), double(), double()).prop_map(|(l, w, h)| Size3 {
                length: l,
                width: w,
                height: h,
            }));
        let image_box = proptest::option::of(
            (double(), double(), double(), double()).prop_map(|(x1, y1, x2, y2)| ImageBox {
                x1,
                y1,
                x2,
                y2,
            }),
        );
        // Empty keys and values too; long values make an entry's length take two bytes.
        let attributes = btree_map(".{0,4}", ".{0,3}|.{100,200}", 0..4);
        let head = (id(), ".{0,6}", vector3(), size, double(), vector3());
        let tail = (
            double(),
            double(),
            vector3(),
            double(),
            (count(), count(), count()),
        );
        (head, tail, image_box, attributes).prop_map(
            |((id, label, center, size, yaw, velocity), tail, image_box, attributes)| {
                let (yaw_rate, score, position_variance, yaw_variance, (age, hits, since)) = tail;
                Track3D {
                    id,
                    label,
                    center,
                    size,
                    yaw,
                    velocity,
                    yaw_rate,
                    score,
                    position_variance,
                    yaw_variance,
                    age,
                    hits,
                    frames_since_update: since,
                    image_box,
                    attributes,
                }
            },
        )
    }

    proptest::proptest! {
        /// The bytes are prost's, whatever the values (appended after what `buf` held).
        #[test]
        fn encode_tracks_writes_what_prost_writes(
            stamp in id(),
            frame_id in ".{0,8}",
            tracks in vec(track(), 0..5),
        ) {
            let msg = Tracks3D { stamp, frame_id, tracks };
            let mut buf = vec![7];
            encode_tracks(&msg, &mut buf);
            let mut want = vec![7];
            want.extend(prost::Message::encode_to_vec(&msg));
            prop_assert_eq!(buf, want);
        }
    }

    /// A message of many tracks (its tracks' lengths take two bytes) decodes back to itself.
    #[test]
    fn a_large_message_round_trips() {
        let t = |i: u64| Track3D {
            id: i,
            label: "car".into(),
            center: Some(v3([i as f64, -1.5, 0.25])),
            size: Some(size3([4.0, 2.0, 1.5])),
            velocity: Some(v3([1.0, 0.0, -0.0])),
            position_variance: Some(v3([0.1, 0.2, 0.3])),
            score: 0.9,
            hits: 3,
            attributes: [("k".to_string(), "v".repeat(i as usize))].into(),
            ..Default::default()
        };
        let msg = Tracks3D {
            stamp: 1,
            frame_id: "map".into(),
            tracks: (0..300).map(t).collect(),
        };
        let mut buf = Vec::new();
        encode_tracks(&msg, &mut buf);
        assert_eq!(buf, prost::Message::encode_to_vec(&msg));
        let back: Tracks3D = prost::Message::decode(buf.as_slice()).unwrap();
        assert_eq!(back, msg);
    }
}
