//! Moving boxes between frames with a rigid transform.
//!
//! The centre goes through the full 3D transform. The heading is the direction of the box's
//! x axis projected on the ground: its yaw after the transform is the direction of the rotated
//! heading vector, which is `yaw + rotation's yaw` when the rotation is about z. That is the
//! assumption for boxes (the ego frame's z axis stays vertical, as for a car on level ground);
//! under roll or pitch the box is still upright in the target frame, not tilted.
//! Velocities are rotated (not translated), so they keep meaning "over ground, in these axes".

use nalgebra::{Isometry3, Point3, UnitQuaternion, Vector3};

use crate::msgs::detection_frame::DetectionFrame;
use crate::msgs::{self, Track3D, Tracks3D};
use crate::tracker::angle::wrap;

/// Yaw after rotating a heading of `yaw` by `iso`.
pub fn transform_yaw(iso: &Isometry3<f64>, yaw: f64) -> f64 {
    if iso.rotation == UnitQuaternion::identity() {
        // Exactly the input (atan2 of sin and cos can differ in the last bit).
        return yaw;
    }
    let h = iso.rotation * Vector3::new(yaw.cos(), yaw.sin(), 0.0);
    if h.x == 0.0 && h.y == 0.0 {
        // The heading became vertical (a 90-degree pitch): keep the input.
        return yaw;
    }
    wrap(h.y.atan2(h.x))
}

fn point(iso: &Isometry3<f64>, v: &msgs::Vector3) -> msgs::Vector3 {
    let p = iso * Point3::new(v.x, v.y, v.z);
    msgs::v3([p.x, p.y, p.z])
}

fn rotate(iso: &Isometry3<f64>, v: &msgs::Vector3) -> msgs::Vector3 {
    let r = iso.rotation * Vector3::new(v.x, v.y, v.z);
    msgs::v3([r.x, r.y, r.z])
}

/// Moves every valid box of a detection frame by `iso` (source to target frame) and sets its
/// `frame_id` to `target`.
pub fn transform_detections(frame: &mut DetectionFrame, iso: &Isometry3<f64>, target: &str) {
    for d in &mut frame.boxes {
        let c = d.bbox.center;
        let p = iso * Point3::new(c[0], c[1], c[2]);
        d.bbox.center = [p.x, p.y, p.z];
        d.bbox.yaw = transform_yaw(iso, d.bbox.yaw);
        if let Some(v) = &mut d.velocity {
            let r = iso.rotation * Vector3::new(v[0], v[1], v[2]);
            *v = [r.x, r.y, r.z];
        }
    }
    frame.frame_id.clear();
    frame.frame_id.push_str(target);
}

/// Moves one track by `iso`: centre, yaw and velocity (the variances, yaw rate and size are
/// kept as they are).
pub fn transform_track(t: &mut Track3D, iso: &Isometry3<f64>) {
    if let Some(c) = &mut t.center {
        *c = point(iso, c);
    }
    t.yaw = transform_yaw(iso, t.yaw);
    if let Some(v) = &mut t.velocity {
        *v = rotate(iso, v);
    }
}

/// Writes into `out` the tracks of `src` moved by `iso`, in frame `frame_id` (reusing `out`'s
/// allocations).
pub fn transform_tracks_into(
    src: &Tracks3D,
    iso: &Isometry3<f64>,
    frame_id: &str,
    out: &mut Tracks3D,
) {
    out.stamp = src.stamp;
    out.frame_id.clear();
    out.frame_id.push_str(frame_id);
    out.tracks.clone_from(&src.tracks);
    for t in &mut out.tracks {
        transform_track(t, iso);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msgs::{Detection3D, Detections3D};

    #[test]
    fn boxes_move_with_the_full_rotation_and_yaw_adds_the_rotation_yaw() {
        let iso = Isometry3::new(
            Vector3::new(10.0, 5.0, 1.0),
            Vector3::new(0.0, 0.0, std::f64::consts::FRAC_PI_2),
        );
        let m = Detections3D {
            stamp: Some(1),
            frame_id: "base_link".into(),
            detections: vec![Detection3D {
                center: Some(msgs::v3([2.0, 0.0, 0.5])),
                size: Some(msgs::Size3 {
                    length: 4.0,
                    width: 2.0,
                    height: 1.5,
                }),
                yaw: 3.0,
                velocity: Some(msgs::v3([1.0, 0.0, 0.0])),
                ..Default::default()
            }],
        };
        let mut m = DetectionFrame::from_message(m, 0);
        transform_detections(&mut m, &iso, "map");
        let d = &m.boxes[0];
        let c = d.bbox.center;
        assert!(
            (c[0] - 10.0).abs() < 1e-12 && (c[1] - 7.0).abs() < 1e-12 && (c[2] - 1.5).abs() < 1e-12
        );
        assert!((d.bbox.yaw - wrap(3.0 + std::f64::consts::FRAC_PI_2)).abs() < 1e-12);
        let v = d.velocity.unwrap();
        assert!(v[0].abs() < 1e-12 && (v[1] - 1.0).abs() < 1e-12);
        assert_eq!(m.frame_id, "map");
        // And back.
        let mut t = Track3D {
            center: Some(msgs::v3(c)),
            yaw: d.bbox.yaw,
            ..Default::default()
        };
        transform_track(&mut t, &iso.inverse());
        let b = t.center.unwrap();
        assert!((b.x - 2.0).abs() < 1e-12 && b.y.abs() < 1e-12);
        assert!((t.yaw - 3.0).abs() < 1e-12);
    }
}
