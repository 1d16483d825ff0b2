//! Plain box and detection types of the tracker core.

use nalgebra::SVector;

use super::config::BoxOrigin;

/// Index of a class (label) inside a [`crate::tracker::Tracker`]; see
/// [`crate::tracker::Tracker::class_id`].
pub type ClassId = u32;

/// An oriented 3D box: centre, heading about +z and size. Units: metres and radians.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Box3 {
    /// Centre `[x, y, z]` of the box.
    pub center: [f64; 3],
    /// Heading about +z, radians; 0 points along +x.
    pub yaw: f64,
    /// Length (along the heading), width and height.
    pub size: [f64; 3],
}

impl Box3 {
    /// The 7-d measurement vector `x y z yaw l w h`.
    pub fn to_measurement(&self) -> SVector<f64, 7> {
        SVector::<f64, 7>::from([
            self.center[0],
            self.center[1],
            self.center[2],
            self.yaw,
            self.size[0],
            self.size[1],
            self.size[2],
        ])
    }

    /// Builds a box from the first seven entries of a state or measurement vector.
    pub fn from_slice(v: &[f64]) -> Self {
        Box3 {
            center: [v[0], v[1], v[2]],
            yaw: v[3],
            size: [v[4], v[5], v[6]],
        }
    }

    /// The box with its `center` moved to the given origin point: the bottom-face centre is
    /// `h / 2` below the centre. Used to filter the position of that point.
    #[inline]
    pub fn to_origin(&self, origin: BoxOrigin) -> Box3 {
        match origin {
            BoxOrigin::Center => *self,
            BoxOrigin::Bottom => {
                let mut b = *self;
                b.center[2] -= 0.5 * self.size[2];
                b
            }
        }
    }

    /// The inverse of [`Box3::to_origin`]: a box whose `center` field holds the origin point,
    /// back to its centre.
    #[inline]
    pub fn from_origin(&self, origin: BoxOrigin) -> Box3 {
        match origin {
            BoxOrigin::Center => *self,
            BoxOrigin::Bottom => {
                let mut b = *self;
                b.center[2] += 0.5 * self.size[2];
                b
            }
        }
    }

    /// The four bird's-eye-view corners, counter-clockwise.
    pub fn bev_corners(&self) -> [[f64; 2]; 4] {
        let (s, c) = self.yaw.sin_cos();
        let hl = 0.5 * self.size[0];
        let hw = 0.5 * self.size[1];
        let local = [[hl, hw], [-hl, hw], [-hl, -hw], [hl, -hw]];
        local.map(|[u, v]| {
            [
                self.center[0] + c * u - s * v,
                self.center[1] + s * u + c * v,
            ]
        })
    }

    /// Lower and upper z of the box.
    pub fn z_range(&self) -> (f64, f64) {
        let hh = 0.5 * self.size[2];
        (self.center[2] - hh, self.center[2] + hh)
    }

    /// Volume `l * w * h`.
    pub fn volume(&self) -> f64 {
        self.size[0] * self.size[1] * self.size[2]
    }

    /// Half the BEV diagonal: no point of the box is farther than this from its centre in BEV.
    pub fn bev_radius(&self) -> f64 {
        0.5 * self.size[0].hypot(self.size[1])
    }

    /// True when every field is finite and every size is positive.
    pub fn is_valid(&self) -> bool {
        self.center.iter().all(|v| v.is_finite())
            && self.yaw.is_finite()
            && self.size.iter().all(|v| v.is_finite() && *v > 0.0)
    }
}

/// One detection handed to the tracker: a box, its class and its confidence.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Detection {
    /// The measured box.
    pub bbox: Box3,
    /// Class index from [`crate::tracker::Tracker::class_id`].
    pub class: ClassId,
    /// Detector confidence. Not required to lie in `[0, 1]`.
    pub score: f64,
}
