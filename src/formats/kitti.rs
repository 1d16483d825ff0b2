//! KITTI tracking text formats and the camera-to-probmot coordinate conversion.
//!
//! KITTI boxes are in rectified camera coordinates (x right, y down, z forward) with the
//! location at the centre of the box's *bottom face* and `rotation_y` about the camera's y axis
//! (0 = facing +x). probmot uses a right-handed z-up frame with box centres:
//! `x = z_cam`, `y = -x_cam`, `z = -(y_cam - h/2)`, `yaw = -rotation_y - pi/2`.

use std::f64::consts::FRAC_PI_2;

use anyhow::{bail, Context, Result};

use crate::tracker::angle::wrap;
use crate::tracker::Box3;

/// One row of a KITTI tracking label or result file.
#[derive(Debug, Clone, PartialEq)]
pub struct KittiRow {
    /// Frame number.
    pub frame: u32,
    /// Track id (-1 for DontCare).
    pub track_id: i64,
    /// Object type as written (e.g. `Car`, `DontCare`).
    pub kind: String,
    /// Truncation (0..1; labels only).
    pub truncated: f64,
    /// Occlusion level 0..3 (labels only).
    pub occluded: i64,
    /// Observation angle.
    pub alpha: f64,
    /// 2D box `x1 y1 x2 y2`, pixels.
    pub bbox: [f64; 4],
    /// Height, width, length (metres).
    pub hwl: [f64; 3],
    /// Bottom-centre location in camera coordinates.
    pub xyz: [f64; 3],
    /// Rotation about the camera's y axis.
    pub rotation_y: f64,
    /// Score (results and detections).
    pub score: Option<f64>,
}

impl KittiRow {
    /// Whether every number of the row is finite (a result file cannot hold NaN or infinity:
    /// the evaluators would read them as garbage).
    pub fn is_finite(&self) -> bool {
        let fixed = [self.truncated, self.alpha, self.rotation_y];
        (fixed
            .iter()
            .chain(&self.bbox)
            .chain(&self.hwl)
            .chain(&self.xyz))
        .chain(self.score.as_ref())
        .all(|v| v.is_finite())
    }
}

fn num(field: &str, name: &str) -> Result<f64> {
    let v: f64 = field
        .trim()
        .parse()
        .with_context(|| format!("field {name}: '{field}' is not a number"))?;
    Ok(v)
}

/// Parses a label/result line: `frame id type truncated occluded alpha x1 y1 x2 y2 h w l x y z
/// rotation_y [score]` (space separated).
pub fn parse_label_line(line: &str) -> Result<KittiRow> {
    let f: Vec<&str> = line.split_whitespace().collect();
    if f.len() != 17 && f.len() != 18 {
        bail!(
            "expected 17 or 18 space-separated fields, found {}",
            f.len()
        );
    }
    let n = |i: usize, name: &str| num(f[i], name);
    Ok(KittiRow {
        frame: f[0].parse().with_context(|| format!("frame '{}'", f[0]))?,
        track_id: f[1]
            .parse()
            .with_context(|| format!("track id '{}'", f[1]))?,
        kind: f[2].to_string(),
        truncated: n(3, "truncated")?,
        occluded: n(4, "occluded")? as i64,
        alpha: n(5, "alpha")?,
        bbox: [n(6, "x1")?, n(7, "y1")?, n(8, "x2")?, n(9, "y2")?],
        hwl: [n(10, "h")?, n(11, "w")?, n(12, "l")?],
        xyz: [n(13, "x")?, n(14, "y")?, n(15, "z")?],
        rotation_y: n(16, "rotation_y")?,
        score: if f.len() == 18 {
            Some(n(17, "score")?)
        } else {
            None
        },
    })
}

/// Names of the PointRCNN detection type codes distributed with AB3DMOT.
pub fn pointrcnn_type(code: &str) -> Result<&'static str> {
    Ok(match code.trim() {
        "1" => "Pedestrian",
        "2" => "Car",
        "3" => "Cyclist",
        other => bail!("unknown PointRCNN type code '{other}' (1 Pedestrian, 2 Car, 3 Cyclist)"),
    })
}

/// Parses a PointRCNN detection line: `frame, type, x1, y1, x2, y2, score, h, w, l, x, y, z,
/// rotation_y, alpha` (comma separated).
pub fn parse_detection_line(line: &str) -> Result<KittiRow> {
    let f: Vec<&str> = line.split(',').collect();
    if f.len() != 15 {
        let words = line.split_whitespace().count();
        let hint = match words {
            17 | 18 => {
                " (a line of the label or tracking result format: --labels or --tracks \
                        take those; --detections takes PointRCNN detection files)"
            }
            _ => "",
        };
        bail!(
            "expected 15 comma-separated fields, found {}{hint}",
            f.len()
        );
    }
    let n = |i: usize, name: &str| num(f[i], name);
    Ok(KittiRow {
        frame: f[0]
            .trim()
            .parse()
            .with_context(|| format!("frame '{}'", f[0]))?,
        track_id: -1,
        kind: pointrcnn_type(f[1])?.to_string(),
        truncated: 0.0,
        occluded: 0,
        alpha: n(14, "alpha")?,
        bbox: [n(2, "x1")?, n(3, "y1")?, n(4, "x2")?, n(5, "y2")?],
        score: Some(n(6, "score")?),
        hwl: [n(7, "h")?, n(8, "w")?, n(9, "l")?],
        xyz: [n(10, "x")?, n(11, "y")?, n(12, "z")?],
        rotation_y: n(13, "rotation_y")?,
    })
}

/// Converts a KITTI camera-frame box to probmot's frame.
pub fn camera_to_box(hwl: [f64; 3], xyz: [f64; 3], rotation_y: f64) -> Box3 {
    let [h, w, l] = hwl;
    Box3 {
        center: [xyz[2], -xyz[0], -(xyz[1] - h / 2.0)],
        yaw: wrap(-rotation_y - FRAC_PI_2),
        size: [l, w, h],
    }
}

/// Converts a probmot box back to KITTI `(hwl, bottom-centre xyz, rotation_y)`.
pub fn box_to_camera(b: &Box3) -> ([f64; 3], [f64; 3], f64) {
    let [l, w, h] = b.size;
    let xyz = [-b.center[1], -b.center[2] + h / 2.0, b.center[0]];
    ([h, w, l], xyz, wrap(-b.yaw - FRAC_PI_2))
}

/// Formats a result row in the 18-field KITTI tracking result format (6 decimals, as the
/// benchmark's files).
pub fn format_row(r: &KittiRow) -> String {
    format!(
        "{} {} {} {} {} {:.6} {:.6} {:.6} {:.6} {:.6} {:.6} {:.6} {:.6} {:.6} {:.6} {:.6} {:.6}{}",
        r.frame,
        r.track_id,
        r.kind,
        fmt_trunc(r.truncated),
        r.occluded,
        r.alpha,
        r.bbox[0],
        r.bbox[1],
        r.bbox[2],
        r.bbox[3],
        r.hwl[0],
        r.hwl[1],
        r.hwl[2],
        r.xyz[0],
        r.xyz[1],
        r.xyz[2],
        r.rotation_y,
        r.score.map(|s| format!(" {s:.6}")).unwrap_or_default()
    )
}

fn fmt_trunc(t: f64) -> String {
    if t.fract() == 0.0 {
        format!("{}", t as i64)
    } else {
        format!("{t}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn camera_round_trip() {
        let hwl = [1.5, 1.6, 3.9];
        let xyz = [-4.55, 1.86, 13.41];
        for ry in [-2.115488, 0.0, 1.2, -1.5, 3.0] {
            let b = camera_to_box(hwl, xyz, ry);
            let (h2, x2, r2) = box_to_camera(&b);
            for i in 0..3 {
                assert!((h2[i] - hwl[i]).abs() < 1e-12);
                assert!((x2[i] - xyz[i]).abs() < 1e-12);
            }
            assert!(wrap(r2 - ry).abs() < 1e-12);
        }
    }

    #[test]
    fn axes() {
        // A car 10 m ahead of the camera, facing forward (rotation_y = -pi/2), bottom at y = 1.7.
        let b = camera_to_box([1.5, 1.6, 4.0], [0.0, 1.7, 10.0], -FRAC_PI_2);
        assert_eq!(b.center[0], 10.0);
        assert_eq!(b.center[1], 0.0);
        assert!((b.center[2] - (-0.95)).abs() < 1e-12); // centre 0.75 above the bottom at -1.7
        assert!(b.yaw.abs() < 1e-12); // facing +x
    }

    #[test]
    fn parses_both_formats() {
        let r = parse_label_line("0 0 Van 0 0 -1.793451 296.744956 161.752147 455.226042 292.372804 2.000000 1.823255 4.433886 -4.552284 1.858523 13.410495 -2.115488").unwrap();
        assert_eq!(r.kind, "Van");
        assert_eq!(r.hwl, [2.0, 1.823255, 4.433886]);
        let d = parse_detection_line(
            "0,2,296.7,161.7,455.2,292.3,12.5,2.0,1.8,4.4,-4.5,1.8,13.4,-2.1,-1.7",
        )
        .unwrap();
        assert_eq!(d.kind, "Car");
        assert_eq!(d.score, Some(12.5));
        assert!(parse_detection_line("0,9,1,2,3,4,5,6,7,8,9,10,11,12,13").is_err());
        assert!(parse_label_line("0 0 Car").is_err());
    }
}
