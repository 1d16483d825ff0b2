//! The transform buffer: the frame tree of a recording with its static and time-stamped
//! transforms, and lookups between any two connected frames at a stamp.
//!
//! Each frame has at most one parent (as in ROS tf2). A dynamic edge keeps its samples sorted
//! by stamp; a lookup between two samples interpolates the translation linearly and the
//! rotation by slerp. Outside an edge's time range the nearest sample is held if the stamp is
//! within the tolerance of it, and the lookup fails otherwise (no extrapolation).

use std::collections::HashMap;

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

/// Default of [`TransformBuffer::tolerance_ns`]: 0.1 s.
pub const DEFAULT_TOLERANCE_NS: u64 = 100_000_000;

/// One edge of the tree: the transforms of a child frame into its parent frame.
#[derive(Debug, Clone)]
pub struct Edge {
    /// Parent frame index.
    pub parent: usize,
    /// Static (`/tf_static`): one transform valid at every stamp.
    pub is_static: bool,
    /// `(stamp, child-to-parent transform)`, sorted by stamp after [`TransformBuffer::finish`].
    /// A static edge has one sample (its stamp is ignored).
    pub samples: Vec<(u64, Isometry3<f64>)>,
}

/// Why a lookup failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LookupError {
    /// A frame is not in the tree.
    #[error("frame '{0}' is not in the transform tree")]
    UnknownFrame(String),
    /// The two frames are in different trees.
    #[error("frames '{0}' and '{1}' are not connected in the transform tree")]
    NotConnected(String, String),
    /// The stamp lies outside the time range of an edge (beyond the tolerance).
    #[error(
        "no transform {child} -> {parent} at stamp {stamp}: its transforms span {first} .. {last}"
    )]
    OutOfRange {
        /// Child frame of the edge.
        child: String,
        /// Parent frame of the edge.
        parent: String,
        /// Stamp asked for.
        stamp: u64,
        /// First sample's stamp.
        first: u64,
        /// Last sample's stamp.
        last: u64,
    },
}

/// A summary of one edge, for `probmot info`.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct EdgeSummary {
    /// Parent frame.
    pub parent: String,
    /// Child frame.
    pub child: String,
    /// Static edge.
    pub is_static: bool,
    /// Number of transforms.
    pub transforms: u64,
    /// First and last stamp (dynamic edges).
    pub stamp_range: Option<(u64, u64)>,
}

/// Frame tree with static and dynamic transforms.
#[derive(Debug, Clone)]
pub struct TransformBuffer {
    names: Vec<String>,
    index: HashMap<String, usize>,
    /// Edge to the parent, per frame index.
    edges: Vec<Option<Edge>>,
    /// Transforms dropped because their child already had another parent.
    pub conflicting_parent: u64,
    /// Lookups hold the nearest sample up to this far outside an edge's time range, ns.
    pub tolerance_ns: u64,
}

impl Default for TransformBuffer {
    fn default() -> Self {
        TransformBuffer {
            names: Vec::new(),
            index: HashMap::new(),
            edges: Vec::new(),
            conflicting_parent: 0,
            tolerance_ns: DEFAULT_TOLERANCE_NS,
        }
    }
}

impl TransformBuffer {
    /// An empty buffer.
    pub fn new() -> Self {
        Self::default()
    }

    /// True when no transform was added.
    pub fn is_empty(&self) -> bool {
        self.edges.iter().all(Option::is_none)
    }

    fn frame(&mut self, name: &str) -> usize {
        if let Some(&i) = self.index.get(name) {
            return i;
        }
        self.names.push(name.to_string());
        self.edges.push(None);
        self.index.insert(name.to_string(), self.names.len() - 1);
        self.names.len() - 1
    }

    /// Index of a frame, if it is in the tree.
    pub fn frame_index(&self, name: &str) -> Option<usize> {
        self.index.get(name).copied()
    }

    /// Adds the transform of `child` into `parent` at `stamp` (static: valid at every stamp;
    /// a later static transform of the same edge replaces the earlier one). A transform whose
    /// child already has another parent is dropped and counted in
    /// [`TransformBuffer::conflicting_parent`]; one that would close a cycle likewise.
    pub fn add(
        &mut self,
        parent: &str,
        child: &str,
        stamp: u64,
        transform: Isometry3<f64>,
        is_static: bool,
    ) {
        let p = self.frame(parent);
        let c = self.frame(child);
        match &mut self.edges[c] {
            Some(e) => {
                if e.parent != p {
                    self.conflicting_parent += 1;
                } else if e.is_static {
                    e.samples[0] = (0, transform);
                } else {
                    e.samples.push((stamp, transform));
                }
            }
            None => {
                if p == c {
                    self.conflicting_parent += 1;
                    return;
                }
                // Refuse an edge that would make the child its own ancestor.
                let mut a = p;
                let mut steps = 0;
                while let Some(e) = &self.edges[a] {
                    if e.parent == c || steps > self.names.len() {
                        self.conflicting_parent += 1;
                        return;
                    }
                    a = e.parent;
                    steps += 1;
                }
                self.edges[c] = Some(Edge {
                    parent: p,
                    is_static,
                    samples: vec![(if is_static { 0 } else { stamp }, transform)],
                });
            }
        }
    }

    /// Sorts every dynamic edge by stamp (stable: of equal stamps the last added wins).
    pub fn finish(&mut self) {
        for e in self.edges.iter_mut().flatten() {
            e.samples.sort_by_key(|(t, _)| *t);
            // Keep the last of each run of equal stamps.
            let mut out: Vec<(u64, Isometry3<f64>)> = Vec::with_capacity(e.samples.len());
            for s in e.samples.drain(..) {
                match out.last_mut() {
                    Some(last) if last.0 == s.0 => *last = s,
                    _ => out.push(s),
                }
            }
            e.samples = out;
        }
    }

    /// The names of the frames in the tree, in the order they were first seen.
    pub fn frame_names(&self) -> &[String] {
        &self.names
    }

    /// The root of the tree holding `frame` (the frame itself if it has no parent).
    pub fn root_of(&self, frame: &str) -> Option<&str> {
        let mut i = self.frame_index(frame)?;
        while let Some(e) = &self.edges[i] {
            i = e.parent;
        }
        Some(&self.names[i])
    }

    /// Every edge, sorted by parent then child name.
    pub fn summary(&self) -> Vec<EdgeSummary> {
        let mut v: Vec<EdgeSummary> = self
            .edges
            .iter()
            .enumerate()
            .filter_map(|(c, e)| {
                let e = e.as_ref()?;
                Some(EdgeSummary {
                    parent: self.names[e.parent].clone(),
                    child: self.names[c].clone(),
                    is_static: e.is_static,
                    transforms: e.samples.len() as u64,
                    stamp_range: if e.is_static {
                        None
                    } else {
                        let a = e.samples.iter().map(|s| s.0).min()?;
                        let b = e.samples.iter().map(|s| s.0).max()?;
                        Some((a, b))
                    },
                })
            })
            .collect();
        v.sort_by(|a, b| (&a.parent, &a.child).cmp(&(&b.parent, &b.child)));
        v
    }

    /// The transform of one edge (child index `c`) at `stamp`.
    fn edge_at(&self, c: usize, stamp: u64) -> Result<Isometry3<f64>, LookupError> {
        let e = self.edges[c].as_ref().expect("caller checked the edge");
        if e.is_static {
            return Ok(e.samples[0].1);
        }
        let s = &e.samples;
        let (first, last) = (s[0].0, s[s.len() - 1].0);
        let out_of_range = || LookupError::OutOfRange {
            child: self.names[c].clone(),
            parent: self.names[e.parent].clone(),
            stamp,
            first,
            last,
        };
        if stamp <= first {
            return if first - stamp <= self.tolerance_ns {
                Ok(s[0].1)
            } else {
                Err(out_of_range())
            };
        }
        if stamp >= last {
            return if stamp - last <= self.tolerance_ns {
                Ok(s[s.len() - 1].1)
            } else {
                Err(out_of_range())
            };
        }
        // first < stamp < last: s[k-1].0 <= stamp < s[k].0.
        let k = s.partition_point(|(t, _)| *t <= stamp);
        let (t0, a) = s[k - 1];
        if t0 == stamp {
            return Ok(a);
        }
        let (t1, b) = s[k];
        let f = (stamp - t0) as f64 / (t1 - t0) as f64;
        Ok(interpolate(&a, &b, f))
    }

    /// The transform taking points in `source` frame coordinates to `target` frame coordinates
    /// at `stamp`.
    pub fn lookup(
        &self,
        target: &str,
        source: &str,
        stamp: u64,
    ) -> Result<Isometry3<f64>, LookupError> {
        if target == source {
            return Ok(Isometry3::identity());
        }
        let t = self
            .frame_index(target)
            .ok_or_else(|| LookupError::UnknownFrame(target.to_string()))?;
        let s = self
            .frame_index(source)
            .ok_or_else(|| LookupError::UnknownFrame(source.to_string()))?;
        // Walk both chains only as far as the common ancestor, so that an out-of-range edge
        // above it does not fail the lookup.
        let target_ancestors = self.ancestors(t);
        let mut common = None;
        let mut i = s;
        loop {
            if target_ancestors.contains(&i) {
                common = Some(i);
                break;
            }
            match &self.edges[i] {
                Some(e) => i = e.parent,
                None => break,
            }
        }
        let common = common
            .ok_or_else(|| LookupError::NotConnected(target.to_string(), source.to_string()))?;
        let up_source = self.chain_to(s, common, stamp)?;
        let up_target = self.chain_to(t, common, stamp)?;
        Ok(up_target.inverse() * up_source)
    }

    fn ancestors(&self, start: usize) -> Vec<usize> {
        let mut v = vec![start];
        let mut i = start;
        while let Some(e) = &self.edges[i] {
            i = e.parent;
            v.push(i);
        }
        v
    }

    /// Transform of `start` into its ancestor `end`.
    fn chain_to(
        &self,
        start: usize,
        end: usize,
        stamp: u64,
    ) -> Result<Isometry3<f64>, LookupError> {
        let mut i = start;
        let mut acc = Isometry3::identity();
        while i != end {
            let e = self.edges[i].as_ref().expect("end is an ancestor of start");
            acc = self.edge_at(i, stamp)? * acc;
            i = e.parent;
        }
        Ok(acc)
    }
}

/// Interpolates two rigid transforms: translation linearly, rotation by slerp (the shorter
/// arc), `f` in `[0, 1]`.
pub fn interpolate(a: &Isometry3<f64>, b: &Isometry3<f64>, f: f64) -> Isometry3<f64> {
    let t = a.translation.vector.lerp(&b.translation.vector, f);
    // try_slerp fails only for (nearly) opposite rotations; fall back to the nearer endpoint.
    let r = a
        .rotation
        .try_slerp(&b.rotation, f, 1e-12)
        .unwrap_or(if f < 0.5 { a.rotation } else { b.rotation });
    Isometry3::from_parts(Translation3::from(t), r)
}

/// A rigid transform from a translation and an (unnormalised) quaternion `x y z w`; `None`
/// when a number is not finite or the quaternion is zero.
pub fn rigid(translation: [f64; 3], quaternion: [f64; 4]) -> Option<Isometry3<f64>> {
    let [x, y, z, w] = quaternion;
    if !translation.iter().chain(&quaternion).all(|v| v.is_finite()) {
        return None;
    }
    let q = nalgebra::Quaternion::new(w, x, y, z);
    if q.norm() < 1e-9 {
        return None;
    }
    Some(Isometry3::from_parts(
        Translation3::from(Vector3::from(translation)),
        UnitQuaternion::from_quaternion(q),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Point3;
    use std::f64::consts::FRAC_PI_2;

    fn yaw_iso(x: f64, y: f64, yaw: f64) -> Isometry3<f64> {
        Isometry3::new(Vector3::new(x, y, 0.0), Vector3::new(0.0, 0.0, yaw))
    }

    #[test]
    fn interpolates_translation_linearly_and_rotation_by_slerp() {
        let mut b = TransformBuffer::new();
        b.add("map", "base_link", 1000, yaw_iso(0.0, 0.0, 0.0), false);
        b.add(
            "map",
            "base_link",
            3000,
            yaw_iso(4.0, 2.0, FRAC_PI_2),
            false,
        );
        b.finish();
        let t = b.lookup("map", "base_link", 1500).unwrap();
        assert!((t.translation.vector - Vector3::new(1.0, 0.5, 0.0)).norm() < 1e-12);
        assert!((t.rotation.euler_angles().2 - FRAC_PI_2 / 4.0).abs() < 1e-12);
        // Exact samples are returned as they are.
        assert_eq!(
            b.lookup("map", "base_link", 3000).unwrap(),
            yaw_iso(4.0, 2.0, FRAC_PI_2)
        );
        // The inverse direction maps back.
        let inv = b.lookup("base_link", "map", 1500).unwrap();
        let p = Point3::new(3.0, -1.0, 2.0);
        assert!((inv * (t * p) - p).norm() < 1e-12);
    }

    #[test]
    fn outside_the_time_range_holds_within_the_tolerance_and_refuses_beyond() {
        let mut b = TransformBuffer::new();
        b.tolerance_ns = 100;
        b.add("map", "base_link", 1000, yaw_iso(1.0, 0.0, 0.0), false);
        b.add("map", "base_link", 2000, yaw_iso(2.0, 0.0, 0.0), false);
        b.finish();
        assert_eq!(
            b.lookup("map", "base_link", 2100).unwrap(),
            yaw_iso(2.0, 0.0, 0.0)
        );
        assert_eq!(
            b.lookup("map", "base_link", 900).unwrap(),
            yaw_iso(1.0, 0.0, 0.0)
        );
        let e = b.lookup("map", "base_link", 2101).unwrap_err();
        assert!(
            matches!(
                e,
                LookupError::OutOfRange {
                    first: 1000,
                    last: 2000,
                    ..
                }
            ),
            "{e}"
        );
        assert!(b.lookup("map", "base_link", 899).is_err());
        assert!(matches!(
            b.lookup("map", "lidar", 1500),
            Err(LookupError::UnknownFrame(_))
        ));
    }

    #[test]
    fn chains_static_and_dynamic_edges_and_finds_the_common_ancestor() {
        let mut b = TransformBuffer::new();
        b.add("map", "odom", 0, yaw_iso(10.0, 0.0, 0.0), true);
        b.add("odom", "base_link", 0, yaw_iso(0.0, 0.0, 0.0), false);
        b.add(
            "odom",
            "base_link",
            10,
            yaw_iso(0.0, 10.0, FRAC_PI_2),
            false,
        );
        b.add("base_link", "lidar", 0, yaw_iso(1.0, 0.0, 0.0), true);
        b.add("base_link", "camera", 0, yaw_iso(0.0, 1.0, 0.0), true);
        b.add("world", "other", 0, yaw_iso(0.0, 0.0, 0.0), true);
        b.finish();
        assert_eq!(b.root_of("lidar"), Some("map"));
        // At t=10 base_link is at odom (0, 10) facing +y; the lidar 1 m ahead is at (0, 11).
        let t = b.lookup("map", "lidar", 10).unwrap();
        assert!((t * Point3::origin() - Point3::new(10.0, 11.0, 0.0)).norm() < 1e-12);
        // Sibling frames: lidar -> camera does not depend on the dynamic edge above them.
        let s = b.lookup("camera", "lidar", 1_000_000_000).unwrap();
        assert!((s * Point3::origin() - Point3::new(1.0, -1.0, 0.0)).norm() < 1e-12);
        assert!(matches!(
            b.lookup("map", "other", 0),
            Err(LookupError::NotConnected(..))
        ));
    }

    #[test]
    fn a_second_parent_or_a_cycle_is_dropped_and_counted() {
        let mut b = TransformBuffer::new();
        b.add("map", "odom", 0, Isometry3::identity(), true);
        b.add("world", "odom", 0, Isometry3::identity(), true);
        b.add("odom", "map", 0, Isometry3::identity(), true);
        b.add("a", "a", 0, Isometry3::identity(), true);
        assert_eq!(b.conflicting_parent, 3);
        assert_eq!(b.root_of("odom"), Some("map"));
        // Equal stamps: the last one added wins.
        b.add("odom", "base", 5, yaw_iso(1.0, 0.0, 0.0), false);
        b.add("odom", "base", 5, yaw_iso(2.0, 0.0, 0.0), false);
        b.finish();
        assert_eq!(
            b.summary()
                .iter()
                .find(|e| e.child == "base")
                .unwrap()
                .transforms,
            1
        );
        assert_eq!(b.lookup("odom", "base", 5).unwrap(), yaw_iso(2.0, 0.0, 0.0));
        assert!(rigid([0.0; 3], [0.0; 4]).is_none());
        assert!(rigid([f64::NAN, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]).is_none());
    }
}
