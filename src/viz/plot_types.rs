//! The data of a `probmot plot` picture (panels, event marks, region) and the drawing constants
//! shared by the picture ([`super::plot`]) and its panels.

use plotters::style::RGBColor;

use super::{Frame, Layer};
use crate::msgs::eval_event::Kind;
use std::collections::HashMap;

/// One panel: a titled BEV view of one layer's frames.
#[derive(Debug, Clone)]
pub struct Panel {
    /// Title drawn above the panel.
    pub title: String,
    /// The layer, which decides the colouring (grey detections, a colour per id otherwise).
    pub layer: Layer,
    /// The frames to draw, all in place.
    pub frames: Vec<Frame>,
    /// Tracks: the ground-truth id each `(stamp, track id)` box matched; such a box takes that
    /// id's colour, an unmatched one [`UNMATCHED`]. `None`: each track its own colour.
    pub truth_of: Option<HashMap<(u64, u64), u64>>,
}

/// An evaluation event marked on the panels with ids.
#[derive(Debug, Clone, PartialEq)]
pub struct EventMark {
    /// What happened.
    pub kind: Kind,
    /// Where (metres).
    pub x: f64,
    /// Where (metres).
    pub y: f64,
    /// Text drawn beside switches and fragmentations.
    pub text: String,
    /// The ground-truth object (0: none).
    pub truth_id: u64,
    /// The track (0: none).
    pub track_id: u64,
    /// The track before a switch or fragmentation (0: none).
    pub previous_track_id: u64,
}

/// World region `(x0, x1, y0, y1)`, metres.
pub type Extent = (f64, f64, f64, f64);

/// Colour of detections, which have no id.
pub const DETECTION_GREY: (u8, u8, u8) = (0x8c, 0x8c, 0x8c);

/// Picture background.
pub const BACKGROUND: (u8, u8, u8) = (0xff, 0xff, 0xff);

/// Colour of a track box that matches no ground truth (when tracks take the truth's colours).
pub const UNMATCHED: (u8, u8, u8) = (0x3a, 0x3a, 0x3a);

pub(super) fn rgb(c: (u8, u8, u8)) -> RGBColor {
    RGBColor(c.0, c.1, c.2)
}

/// Font family name under which the embedded font is registered (also as `sans-serif`, the
/// family plotters uses for its default text).
pub(super) const FONT: &str = "sans-serif";

/// Widens `ext` along x or y so that a `pw` x `ph` pixel area shows it with equal metres per
/// pixel on both axes, keeping its centre. Returns the new region.
pub fn equal_aspect(ext: (f64, f64, f64, f64), pw: u32, ph: u32) -> (f64, f64, f64, f64) {
    let (x0, x1, y0, y1) = ext;
    let (pw, ph) = (f64::from(pw.max(1)), f64::from(ph.max(1)));
    let scale = ((x1 - x0) / pw).max((y1 - y0) / ph);
    let (cx, cy) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0);
    let (hx, hy) = (scale * pw / 2.0, scale * ph / 2.0);
    (cx - hx, cx + hx, cy - hy, cy + hy)
}

pub(super) fn draw_err<E: std::fmt::Display>(e: E) -> anyhow::Error {
    anyhow::anyhow!("drawing failed: {e}")
}
