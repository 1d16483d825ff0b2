//! Bird's-eye-view polygon geometry for oriented boxes: intersection, convex hull, IoU and GIoU.
//!
//! All polygons are small and convex (at most 8 vertices), kept in fixed-size arrays so that no
//! heap allocation happens per pair.

use super::boxes::Box3;

/// A convex polygon of at most 16 vertices, counter-clockwise.
#[derive(Debug, Clone, Copy)]
pub struct Polygon {
    pts: [[f64; 2]; 16],
    len: usize,
}

impl Polygon {
    /// An empty polygon.
    pub fn empty() -> Self {
        Polygon {
            pts: [[0.0; 2]; 16],
            len: 0,
        }
    }

    /// A polygon from counter-clockwise vertices (at most 16).
    pub fn from_points(points: &[[f64; 2]]) -> Self {
        let mut p = Polygon::empty();
        for q in points {
            p.push(*q);
        }
        p
    }

    fn push(&mut self, q: [f64; 2]) {
        if self.len < self.pts.len() {
            self.pts[self.len] = q;
            self.len += 1;
        }
    }

    /// The vertices.
    pub fn points(&self) -> &[[f64; 2]] {
        &self.pts[..self.len]
    }

    /// Area by the shoelace formula (absolute value).
    pub fn area(&self) -> f64 {
        let p = self.points();
        if p.len() < 3 {
            return 0.0;
        }
        let mut s = 0.0;
        for i in 0..p.len() {
            let a = p[i];
            let b = p[(i + 1) % p.len()];
            s += a[0] * b[1] - a[1] * b[0];
        }
        0.5 * s.abs()
    }
}

#[inline]
fn cross(o: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
}

/// Intersection of two convex counter-clockwise polygons (Sutherland-Hodgman clipping).
pub fn convex_intersection(subject: &Polygon, clip: &Polygon) -> Polygon {
    let mut out = *subject;
    let c = clip.points();
    for i in 0..c.len() {
        let a = c[i];
        let b = c[(i + 1) % c.len()];
        let input = out;
        out = Polygon::empty();
        let pts = input.points();
        if pts.is_empty() {
            break;
        }
        for j in 0..pts.len() {
            let p = pts[j];
            let q = pts[(j + 1) % pts.len()];
            let cp = cross(a, b, p);
            let cq = cross(a, b, q);
            let p_in = cp >= 0.0;
            let q_in = cq >= 0.0;
            if p_in {
                out.push(p);
            }
            if p_in != q_in {
                let t = cp / (cp - cq);
                out.push([p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])]);
            }
        }
    }
    out
}

/// Convex hull (counter-clockwise) of up to 16 points, Andrew's monotone chain.
pub fn convex_hull(points: &[[f64; 2]]) -> Polygon {
    let mut pts = [[0.0; 2]; 16];
    let n = points.len().min(16);
    pts[..n].copy_from_slice(&points[..n]);
    let pts = &mut pts[..n];
    pts.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    if n < 3 {
        return Polygon::from_points(pts);
    }
    let mut hull = [[0.0; 2]; 32];
    let mut k = 0usize;
    for &p in pts.iter() {
        while k >= 2 && cross(hull[k - 2], hull[k - 1], p) <= 0.0 {
            k -= 1;
        }
        hull[k] = p;
        k += 1;
    }
    let lower = k + 1;
    for &p in pts.iter().rev().skip(1) {
        while k >= lower && cross(hull[k - 2], hull[k - 1], p) <= 0.0 {
            k -= 1;
        }
        hull[k] = p;
        k += 1;
    }
    Polygon::from_points(&hull[..k - 1])
}

/// BEV footprint of a box as a polygon.
pub fn footprint(b: &Box3) -> Polygon {
    Polygon::from_points(&b.bev_corners())
}

/// Overlap of two boxes along z.
fn height_overlap(a: &Box3, b: &Box3) -> f64 {
    let (a0, a1) = a.z_range();
    let (b0, b1) = b.z_range();
    (a1.min(b1) - a0.max(b0)).max(0.0)
}

/// Intersection volume and union volume of two oriented boxes.
fn intersection_union(a: &Box3, b: &Box3) -> (f64, f64) {
    let dh = height_overlap(a, b);
    let inter = if dh > 0.0 {
        convex_intersection(&footprint(a), &footprint(b)).area() * dh
    } else {
        0.0
    };
    (inter, a.volume() + b.volume() - inter)
}

/// Oriented 3D IoU: BEV polygon intersection times height overlap, over the union volume.
pub fn iou3d(a: &Box3, b: &Box3) -> f64 {
    let dx = a.center[0] - b.center[0];
    let dy = a.center[1] - b.center[1];
    let r = a.bev_radius() + b.bev_radius();
    if dx * dx + dy * dy > r * r {
        return 0.0;
    }
    let (inter, union) = intersection_union(a, b);
    if union <= 0.0 {
        0.0
    } else {
        inter / union
    }
}

/// Generalized 3D IoU (as in AB3DMOT): IoU minus the share of the enclosing volume not covered by
/// the union. The enclosing volume is the BEV convex hull of both footprints times the combined
/// height span. Lies in `(-1, 1]`.
pub fn giou3d(a: &Box3, b: &Box3) -> f64 {
    let (inter, union) = intersection_union(a, b);
    let ca = a.bev_corners();
    let cb = b.bev_corners();
    let all = [ca[0], ca[1], ca[2], ca[3], cb[0], cb[1], cb[2], cb[3]];
    let hull = convex_hull(&all).area();
    let (a0, a1) = a.z_range();
    let (b0, b1) = b.z_range();
    let enclosing = hull * (a1.max(b1) - a0.min(b0));
    if enclosing <= 0.0 || union <= 0.0 {
        return 0.0;
    }
    inter / union - (enclosing - union) / enclosing
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::FRAC_PI_4;

    fn bx(x: f64, y: f64, yaw: f64, l: f64, w: f64) -> Box3 {
        Box3 {
            center: [x, y, 0.0],
            yaw,
            size: [l, w, 1.0],
        }
    }

    #[test]
    fn identical_boxes_have_iou_one() {
        let a = bx(1.0, 2.0, 0.3, 4.0, 2.0);
        assert!((iou3d(&a, &a) - 1.0).abs() < 1e-12);
        assert!((giou3d(&a, &a) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn axis_aligned_half_overlap() {
        // Two 2x2x1 boxes shifted by 1 m along x: intersection 2, union 6 -> 1/3.
        let a = bx(0.0, 0.0, 0.0, 2.0, 2.0);
        let b = bx(1.0, 0.0, 0.0, 2.0, 2.0);
        assert!((iou3d(&a, &b) - 1.0 / 3.0).abs() < 1e-12);
        // Enclosing box 3x2x1 = 6 equals the union: GIoU = IoU.
        assert!((giou3d(&a, &b) - 1.0 / 3.0).abs() < 1e-12);
    }

    #[test]
    fn square_rotated_45_degrees_inside_square() {
        // Unit-side square A (area 4, side 2) and the same square rotated by 45 degrees:
        // the intersection is a regular octagon of area 8 (sqrt(2) - 1) = 3.3137.
        let a = bx(0.0, 0.0, 0.0, 2.0, 2.0);
        let b = bx(0.0, 0.0, FRAC_PI_4, 2.0, 2.0);
        let inter = 8.0 * (2f64.sqrt() - 1.0);
        let expected = inter / (8.0 - inter);
        assert!(
            (iou3d(&a, &b) - expected).abs() < 1e-12,
            "{}",
            iou3d(&a, &b)
        );
    }

    #[test]
    fn height_overlap_scales_iou() {
        let a = bx(0.0, 0.0, 0.0, 2.0, 2.0);
        let mut b = a;
        b.center[2] = 0.5; // half the height overlaps: inter 2, union 6
        assert!((iou3d(&a, &b) - 1.0 / 3.0).abs() < 1e-12);
    }

    #[test]
    fn disjoint_boxes_giou_is_negative() {
        // 1x1x1 boxes 3 m apart along x: enclosing 4x1x1 = 4, union 2 -> GIoU = -0.5.
        let a = bx(0.0, 0.0, 0.0, 1.0, 1.0);
        let b = bx(3.0, 0.0, 0.0, 1.0, 1.0);
        assert_eq!(iou3d(&a, &b), 0.0);
        assert!((giou3d(&a, &b) + 0.5).abs() < 1e-12);
    }

    #[test]
    fn hull_of_square_points() {
        let pts = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.5, 0.5]];
        let h = convex_hull(&pts);
        assert_eq!(h.points().len(), 4);
        assert!((h.area() - 1.0).abs() < 1e-12);
    }
}
