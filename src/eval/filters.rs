//! The devkit's other two filters of `filter_eval_boxes` (nuscenes-devkit 1.2.0,
//! `nuscenes/eval/common/loaders.py`), applied after the range filter ([`super::range`]) in the
//! devkit's order, before the mean track score and the interpolation:
//!
//! - points: boxes whose lidar + radar point count (`num_pts`) is 0 are removed. Only ground truth
//!   has counts (`load_gt` sums `num_lidar_pts` and `num_radar_pts`; predictions carry -1), so only
//!   ground truth is filtered. `--min-points N` keeps boxes with at least N points; N = 1 is the
//!   devkit's rule.
//! - bicycle racks: bicycle and motorcycle boxes (ground truth and tracks) whose centre lies inside
//!   a `static_object.bicycle_rack` annotation of the same sample are removed. The test is the
//!   devkit's `points_in_box`: the centre projected on the three edges of the rack's oriented 3D
//!   box (full rotation), bounds included.

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::{bail, Context, Result};
use serde::Serialize;

use super::range::RangeRemoved;
use super::scene::{read_tracks_topic, Scene};
use crate::formats::nuscenes::attr;
use crate::mcapio::LabelledBox;

/// Boxes each filter removed, in the devkit's order; `None` for a filter that was off.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct FilterCounts {
    /// Range filter.
    pub range: Option<RangeRemoved>,
    /// Points filter (ground truth only).
    pub points: Option<RangeRemoved>,
    /// Bicycle-rack filter.
    pub bike_racks: Option<RangeRemoved>,
}

impl FilterCounts {
    /// Adds another log's counts.
    pub fn add(&mut self, o: &FilterCounts) {
        let sum = |a: &mut Option<RangeRemoved>, b: &Option<RangeRemoved>| {
            if let Some(b) = b {
                let a = a.get_or_insert_with(RangeRemoved::default);
                a.truth += b.truth;
                a.tracks += b.tracks;
            }
        };
        sum(&mut self.range, &o.range);
        sum(&mut self.points, &o.points);
        sum(&mut self.bike_racks, &o.bike_racks);
    }
}

fn count(b: &LabelledBox, key: &str) -> Option<i64> {
    b.attributes.get(key)?.trim().parse().ok()
}

/// Removes the ground-truth boxes of `scene` with fewer than `min` lidar + radar points. A
/// ground-truth box without both counts is an error (the devkit cannot evaluate it either).
pub fn apply_min_points(scene: &mut Scene, min: u64) -> Result<RangeRemoved> {
    let mut removed = RangeRemoved::default();
    for (stamp, truth, _) in &mut scene.frames {
        if let Some(b) = truth.iter().find(|b| {
            count(b, attr::NUM_LIDAR_PTS).is_none() || count(b, attr::NUM_RADAR_PTS).is_none()
        }) {
            bail!(
                "stamp {stamp}: ground-truth box {} ({}) has no {} / {} attribute; the points \
                 filter needs the counts `probmot import nuscenes` keeps from \
                 sample_annotation.json",
                b.id,
                b.label,
                attr::NUM_LIDAR_PTS,
                attr::NUM_RADAR_PTS
            );
        }
        let n = truth.len();
        truth.retain(|b| {
            let pts = count(b, attr::NUM_LIDAR_PTS).unwrap_or(0)
                + count(b, attr::NUM_RADAR_PTS).unwrap_or(0);
            pts >= min as i64
        });
        removed.truth += (n - truth.len()) as u64;
    }
    Ok(removed)
}

/// A bicycle rack as the devkit's `Box` holds it: centre, `[w, l, h]` and rotation matrix.
#[derive(Debug, Clone, PartialEq)]
pub struct Rack {
    /// Centre.
    pub center: [f64; 3],
    /// Width, length, height.
    pub wlh: [f64; 3],
    /// Rotation of the box frame (rows), from the normalised quaternion.
    pub rot: [[f64; 3]; 3],
}

impl Rack {
    /// A rack from its centre, `[w, l, h]` and quaternion `[w, x, y, z]`.
    pub fn new(center: [f64; 3], wlh: [f64; 3], q: [f64; 4]) -> Rack {
        let n = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
        let [w, x, y, z] = q.map(|v| v / n);
        let rot = [
            [
                1.0 - 2.0 * (y * y + z * z),
                2.0 * (x * y - w * z),
                2.0 * (x * z + w * y),
            ],
            [
                2.0 * (x * y + w * z),
                1.0 - 2.0 * (x * x + z * z),
                2.0 * (y * z - w * x),
            ],
            [
                2.0 * (x * z - w * y),
                2.0 * (y * z + w * x),
                1.0 - 2.0 * (x * x + y * y),
            ],
        ];
        Rack { center, wlh, rot }
    }

    /// The corner at `(sx l/2, sy w/2, sz h/2)` in the world frame.
    fn corner(&self, s: [f64; 3]) -> [f64; 3] {
        let [w, l, h] = self.wlh;
        let local = [s[0] * l / 2.0, s[1] * w / 2.0, s[2] * h / 2.0];
        let r = &self.rot;
        [0, 1, 2]
            .map(|k| r[k][0] * local[0] + r[k][1] * local[1] + r[k][2] * local[2] + self.center[k])
    }

    /// The devkit's `points_in_box` for one point: from corner 0 along the box's three edges.
    pub fn contains(&self, p: [f64; 3]) -> bool {
        let p1 = self.corner([1.0, 1.0, 1.0]);
        let edges = [
            self.corner([-1.0, 1.0, 1.0]),
            self.corner([1.0, -1.0, 1.0]),
            self.corner([1.0, 1.0, -1.0]),
        ];
        let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
        let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        let v = sub(p, p1);
        edges.iter().all(|&e| {
            let i = sub(e, p1);
            let iv = dot(i, v);
            (0.0..=dot(i, i)).contains(&iv)
        })
    }
}

/// Reads the bicycle racks of `topic` (`probmot.Tracks3D`, as `probmot import nuscenes` writes
/// them) by frame stamp. The rotation is the `nuscenes_rotation` attribute when present, else the
/// box's yaw.
pub fn read_racks(path: &Path, topic: &str) -> Result<BTreeMap<u64, Vec<Rack>>> {
    let mut out: BTreeMap<u64, Vec<Rack>> = BTreeMap::new();
    for (stamp, boxes) in read_tracks_topic(path, topic)? {
        let racks = out.entry(stamp).or_default();
        for b in boxes {
            let q = match b.attributes.get(attr::ROTATION) {
                Some(text) => serde_json::from_str::<[f64; 4]>(text).with_context(|| {
                    format!(
                        "{}: topic {topic}, stamp {stamp}: rack {}: {} '{text}' is not a \
                         quaternion [w, x, y, z]",
                        path.display(),
                        b.id,
                        attr::ROTATION
                    )
                })?,
                None => [(b.yaw / 2.0).cos(), 0.0, 0.0, (b.yaw / 2.0).sin()],
            };
            racks.push(Rack::new(b.center, [b.size[1], b.size[0], b.size[2]], q));
        }
    }
    Ok(out)
}

/// Removes the bicycle and motorcycle boxes (truth and tracks) whose centre lies in a rack of
/// their frame.
pub fn apply_bike_racks(scene: &mut Scene, racks: &BTreeMap<u64, Vec<Rack>>) -> RangeRemoved {
    let mut removed = RangeRemoved::default();
    for (stamp, truth, tracks) in &mut scene.frames {
        let Some(racks) = racks.get(stamp).filter(|r| !r.is_empty()) else {
            continue;
        };
        let keep = |b: &LabelledBox| {
            !matches!(b.label.as_str(), "bicycle" | "motorcycle")
                || !racks.iter().any(|r| r.contains(b.center))
        };
        let (nt, nr) = (truth.len(), tracks.len());
        truth.retain(keep);
        tracks.retain(keep);
        removed.truth += (nt - truth.len()) as u64;
        removed.tracks += (nr - tracks.len()) as u64;
    }
    removed
}

#[cfg(test)]
mod tests {
    use super::*;

    fn b(label: &str, c: [f64; 3], pts: Option<(i64, i64)>) -> LabelledBox {
        let mut attributes = BTreeMap::new();
        if let Some((l, r)) = pts {
            attributes.insert(attr::NUM_LIDAR_PTS.to_string(), l.to_string());
            attributes.insert(attr::NUM_RADAR_PTS.to_string(), r.to_string());
        }
        LabelledBox {
            id: 1,
            label: label.into(),
            center: c,
            size: [1.8, 0.6, 1.2],
            score: 0.5,
            attributes,
            ..Default::default()
        }
    }

    #[test]
    fn rack_test_uses_the_oriented_3d_box_bounds_included() {
        // 4 m long (x after a 90 degree yaw: along y), 1 m wide, 2 m high, centre (10, 0, 1).
        let q = [
            (std::f64::consts::FRAC_PI_4).cos(),
            0.0,
            0.0,
            (std::f64::consts::FRAC_PI_4).sin(),
        ];
        let r = Rack::new([10.0, 0.0, 1.0], [1.0, 4.0, 2.0], q);
        assert!(r.contains([10.0, 1.9, 1.0]));
        assert!(!r.contains([10.0, 2.1, 1.0]));
        assert!(r.contains([10.4, 0.0, 0.1]));
        assert!(!r.contains([10.6, 0.0, 1.0]));
        assert!(!r.contains([10.0, 0.0, 2.1])); // above the rack
        let axis = Rack::new([0.0; 3], [2.0, 2.0, 2.0], [1.0, 0.0, 0.0, 0.0]);
        assert!(axis.contains([1.0, 1.0, 1.0])); // a corner: bounds included
    }

    #[test]
    fn points_filter_removes_only_truth_below_the_minimum() {
        let mut scene = Scene {
            name: "s".into(),
            frames: vec![(
                5,
                vec![
                    b("car", [0.0; 3], Some((0, 0))),
                    b("car", [0.0; 3], Some((0, 1))),
                    b("car", [0.0; 3], Some((3, 0))),
                ],
                vec![b("car", [0.0; 3], None)],
            )],
        };
        let mut two = scene.clone();
        assert_eq!(apply_min_points(&mut scene, 1).unwrap().truth, 1);
        assert_eq!((scene.frames[0].1.len(), scene.frames[0].2.len()), (2, 1));
        assert_eq!(apply_min_points(&mut two, 2).unwrap().truth, 2);
        two.frames[0].1.push(b("car", [0.0; 3], None));
        let err = apply_min_points(&mut two, 1).unwrap_err().to_string();
        assert!(
            err.contains("stamp 5") && err.contains(attr::NUM_LIDAR_PTS),
            "{err}"
        );
    }

    #[test]
    fn rack_filter_removes_bicycles_and_motorcycles_of_its_frame_only() {
        let rack = Rack::new([0.0, 0.0, 0.5], [2.0, 6.0, 1.5], [1.0, 0.0, 0.0, 0.0]);
        let racks: BTreeMap<u64, Vec<Rack>> = [(1, vec![rack])].into_iter().collect();
        let frame = |s| {
            (
                s,
                vec![
                    b("bicycle", [1.0, 0.5, 0.6], Some((5, 0))),
                    b("pedestrian", [1.0, 0.5, 0.6], None),
                ],
                vec![
                    b("motorcycle", [2.0, -0.5, 0.4], None),
                    b("bicycle", [4.0, 0.0, 0.6], None),
                ],
            )
        };
        let mut scene = Scene {
            name: "s".into(),
            frames: vec![frame(1), frame(2)],
        };
        let removed = apply_bike_racks(&mut scene, &racks);
        assert_eq!(
            removed,
            RangeRemoved {
                truth: 1,
                tracks: 1
            }
        );
        assert_eq!(scene.frames[0].1[0].label, "pedestrian");
        assert_eq!(scene.frames[0].2[0].center[0], 4.0);
        assert_eq!((scene.frames[1].1.len(), scene.frames[1].2.len()), (2, 2));
    }
}
