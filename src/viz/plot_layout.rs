//! Where everything of a `probmot plot` picture went, in picture pixels (x right, y down): each
//! panel's plotting area and the ground region it shows, the labels with their leader lines,
//! the event marks, and the legend. The picture is drawn from this model, so checks on it
//! (labels apart, events in view) are checks on the picture; `plot --layout` writes it as JSON.

use serde::Serialize;

use super::plot_types::Extent;

/// A rectangle in picture pixels, `x0 <= x1`, `y0 <= y1`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PxRect {
    /// Left edge.
    pub x0: f64,
    /// Right edge.
    pub x1: f64,
    /// Top edge.
    pub y0: f64,
    /// Bottom edge.
    pub y1: f64,
}

impl PxRect {
    /// The rectangle spanning two corners.
    pub fn spanning(a: (f64, f64), b: (f64, f64)) -> PxRect {
        PxRect {
            x0: a.0.min(b.0),
            x1: a.0.max(b.0),
            y0: a.1.min(b.1),
            y1: a.1.max(b.1),
        }
    }

    /// The smallest rectangle holding every point (`None` for none).
    pub fn around(points: impl IntoIterator<Item = (f64, f64)>) -> Option<PxRect> {
        let mut it = points.into_iter();
        let first = it.next()?;
        Some(it.fold(PxRect::spanning(first, first), |r, p| PxRect {
            x0: r.x0.min(p.0),
            x1: r.x1.max(p.0),
            y0: r.y0.min(p.1),
            y1: r.y1.max(p.1),
        }))
    }

    /// Width.
    pub fn width(&self) -> f64 {
        self.x1 - self.x0
    }

    /// Height.
    pub fn height(&self) -> f64 {
        self.y1 - self.y0
    }

    /// Centre.
    pub fn center(&self) -> (f64, f64) {
        ((self.x0 + self.x1) / 2.0, (self.y0 + self.y1) / 2.0)
    }

    /// Grown by `d` on every side.
    pub fn grown(&self, d: f64) -> PxRect {
        PxRect {
            x0: self.x0 - d,
            x1: self.x1 + d,
            y0: self.y0 - d,
            y1: self.y1 + d,
        }
    }

    /// Whether the interiors meet (touching edges do not).
    pub fn overlaps(&self, o: &PxRect) -> bool {
        self.x0 < o.x1 && o.x0 < self.x1 && self.y0 < o.y1 && o.y0 < self.y1
    }

    /// Whether `o` lies wholly inside.
    pub fn contains_rect(&self, o: &PxRect) -> bool {
        o.x0 >= self.x0 && o.x1 <= self.x1 && o.y0 >= self.y0 && o.y1 <= self.y1
    }

    /// Whether the point lies inside (edges included).
    pub fn contains(&self, p: (f64, f64)) -> bool {
        p.0 >= self.x0 && p.0 <= self.x1 && p.1 >= self.y0 && p.1 <= self.y1
    }

    /// The point of the rectangle nearest to `p`.
    pub fn nearest(&self, p: (f64, f64)) -> (f64, f64) {
        (p.0.clamp(self.x0, self.x1), p.1.clamp(self.y0, self.y1))
    }

    /// The part of segment `a`-`b` inside the rectangle (Liang-Barsky), if any.
    pub fn clip(&self, a: (f64, f64), b: (f64, f64)) -> Option<[(f64, f64); 2]> {
        let (dx, dy) = (b.0 - a.0, b.1 - a.1);
        let (mut t0, mut t1) = (0f64, 1f64);
        for (p, q) in [
            (-dx, a.0 - self.x0),
            (dx, self.x1 - a.0),
            (-dy, a.1 - self.y0),
            (dy, self.y1 - a.1),
        ] {
            if p == 0.0 {
                if q < 0.0 {
                    return None;
                }
                continue;
            }
            let t = q / p;
            if p < 0.0 {
                t0 = t0.max(t);
            } else {
                t1 = t1.min(t);
            }
            if t0 > t1 {
                return None;
            }
        }
        let at = |t: f64| (a.0 + t * dx, a.1 + t * dy);
        Some([at(t0), at(t1)])
    }

    /// Whether segment `a`-`b` passes through the interior (not only along an edge).
    pub fn crossed_by(&self, a: (f64, f64), b: (f64, f64)) -> bool {
        let inner = self.grown(-1e-6);
        inner.width() > 0.0 && inner.height() > 0.0 && inner.clip(a, b).is_some()
    }
}

/// The ground region a panel shows and where: metres to picture pixels.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct View {
    /// The plotting area, pixels.
    pub area: PxRect,
    /// The region shown, metres `(x0, x1, y0, y1)`: as asked, widened to equal metres per pixel
    /// on both axes.
    pub extent: Extent,
}

impl View {
    /// Pixel position of the ground point `(x, y)` (metres), y up on the ground, down on screen.
    pub fn to_px(&self, (x, y): (f64, f64)) -> (f64, f64) {
        let (x0, x1, y0, y1) = self.extent;
        let a = &self.area;
        (
            a.x0 + (x - x0) / (x1 - x0) * a.width(),
            a.y1 - (y - y0) / (y1 - y0) * a.height(),
        )
    }

    /// Pixels per metre.
    pub fn px_per_m(&self) -> f64 {
        self.area.width() / (self.extent.1 - self.extent.0)
    }

    /// Whether the ground point is in the region shown.
    pub fn shows(&self, (x, y): (f64, f64)) -> bool {
        let (x0, x1, y0, y1) = self.extent;
        x >= x0 && x <= x1 && y >= y0 && y <= y1
    }
}

/// What a label names.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum LabelKind {
    /// An id (track or ground-truth object), at its last box.
    Id,
    /// An identity switch or fragmentation, at its ring.
    Event,
}

/// A placed label.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LabelLayout {
    /// What it names.
    pub kind: LabelKind,
    /// Its text.
    pub text: String,
    /// Its colour.
    pub color: (u8, u8, u8),
    /// The box of its text with the light backing drawn behind it.
    pub rect: PxRect,
    /// What it names: the bounding box of the last box, or of the event's ring.
    pub target: PxRect,
    /// The line from the label to what it names, `[at the label, at the target]`; `None` when
    /// the label touches it.
    pub leader: Option<[(f64, f64); 2]>,
}

/// An event mark.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MarkLayout {
    /// `switch`, `fragmentation`, `false_positive` or `miss`.
    pub kind: String,
    /// The event's text.
    pub text: String,
    /// Where it happened, metres.
    pub world: (f64, f64),
    /// Where that is in the picture.
    pub px: (f64, f64),
    /// Radius of its ring (half side of its cross), pixels.
    pub radius_px: f64,
    /// Whether it is in the region shown (marks outside are not drawn).
    pub in_view: bool,
}

/// One panel.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PanelLayout {
    /// Its title as drawn.
    pub title: String,
    /// The region it shows.
    pub view: View,
    /// The bold last box of each id in view (bounding boxes, pixels): the labels keep off them.
    pub last_boxes: Vec<PxRect>,
    /// The labels placed.
    pub labels: Vec<LabelLayout>,
    /// Labels that found no free place and were left out.
    pub labels_left_out: usize,
    /// The event marks (panels with ids).
    pub marks: Vec<MarkLayout>,
}

/// What a legend entry's sample shows.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Swatch {
    /// Boxes in these colours.
    Boxes(Vec<(u8, u8, u8)>),
    /// A bold box with its path and heading tick.
    LastBox,
    /// A ring (an event mark).
    Ring((u8, u8, u8)),
    /// A small ring.
    SmallRing((u8, u8, u8)),
    /// A cross.
    Cross((u8, u8, u8)),
}

/// One entry of the legend.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LegendEntry {
    /// Its sample.
    pub swatch: Swatch,
    /// What it means.
    pub text: String,
    /// Where the entry (sample and text) is drawn.
    pub rect: PxRect,
}

/// The legend: a strip under the panels.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LegendLayout {
    /// The strip.
    pub rect: PxRect,
    /// Its entries, in rows.
    pub entries: Vec<LegendEntry>,
}

/// How the region shown was chosen.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ViewRule {
    /// `--extent`.
    Extent,
    /// The identity switches and fragmentations of the window (`--events` with a window).
    Events,
    /// The boxes of the tracks and ground truth (detections without them).
    Boxes,
}

/// The whole picture.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PictureLayout {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// How the region was chosen.
    pub view_rule: ViewRule,
    /// The panels, left to right.
    pub panels: Vec<PanelLayout>,
    /// The legend.
    pub legend: LegendLayout,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clipping_keeps_the_inside_part() {
        let r = PxRect {
            x0: 0.0,
            x1: 10.0,
            y0: 0.0,
            y1: 10.0,
        };
        assert_eq!(
            r.clip((-5.0, 5.0), (5.0, 5.0)),
            Some([(0.0, 5.0), (5.0, 5.0)])
        );
        assert_eq!(r.clip((-5.0, -1.0), (20.0, -1.0)), None);
        assert_eq!(
            r.clip((2.0, 2.0), (3.0, 3.0)),
            Some([(2.0, 2.0), (3.0, 3.0)])
        );
        assert!(r.crossed_by((-1.0, 5.0), (11.0, 5.0)));
        assert!(!r.crossed_by((-1.0, 0.0), (11.0, 0.0)), "along an edge");
        assert!(!r.crossed_by((-1.0, -1.0), (-1.0, 11.0)));
    }

    #[test]
    fn the_view_maps_metres_to_pixels_y_up() {
        let v = View {
            area: PxRect {
                x0: 100.0,
                x1: 300.0,
                y0: 50.0,
                y1: 150.0,
            },
            extent: (-10.0, 10.0, 0.0, 10.0),
        };
        assert_eq!(v.to_px((-10.0, 0.0)), (100.0, 150.0));
        assert_eq!(v.to_px((10.0, 10.0)), (300.0, 50.0));
        assert_eq!(v.px_per_m(), 10.0);
        assert!(v.shows((0.0, 5.0)) && !v.shows((0.0, 11.0)));
    }
}
