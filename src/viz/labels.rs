//! Placing the labels of a plot panel so that they do not cover each other: each label tries
//! positions around what it names (above, below, right, left, then higher and higher above) and
//! takes the first one inside the panel that overlaps no label placed before it.

use plotters::style::RGBColor;

use crate::mcapio::LabelledBox;

/// Advance of one character of the embedded font (Hack is monospaced), in em.
const ADVANCE_EM: f64 = 0.6;

/// A label to place: its text, colour and the region (metres) it names.
#[derive(Debug, Clone)]
pub struct Label {
    /// Text.
    pub text: String,
    /// Colour.
    pub color: RGBColor,
    /// `(x0, x1, y0, y1)` of what it names (a box's outline, or a point).
    pub target: (f64, f64, f64, f64),
}

impl Label {
    /// A label for a box (its bird's-eye outline).
    pub fn beside(text: String, b: &LabelledBox, color: RGBColor) -> Label {
        let c = b.bev_corners();
        let xs = c.iter().map(|p| p.0);
        let ys = c.iter().map(|p| p.1);
        Label {
            text,
            color,
            target: (
                xs.clone().fold(f64::MAX, f64::min),
                xs.fold(f64::MIN, f64::max),
                ys.clone().fold(f64::MAX, f64::min),
                ys.fold(f64::MIN, f64::max),
            ),
        }
    }

    /// A label for a point.
    pub fn at(text: String, p: (f64, f64), color: RGBColor) -> Label {
        Label {
            text,
            color,
            target: (p.0, p.0, p.1, p.1),
        }
    }
}

type Rect = (f64, f64, f64, f64);

fn overlaps(a: Rect, b: Rect) -> bool {
    a.0 < b.1 && b.0 < a.1 && a.2 < b.3 && b.2 < a.3
}

fn inside(r: Rect, bounds: Rect) -> bool {
    r.0 >= bounds.0 && r.1 <= bounds.1 && r.2 >= bounds.2 && r.3 <= bounds.3
}

/// Candidate bottom-left corners for a `w` x `h` text beside `t`, best first.
fn candidates(t: Rect, w: f64, h: f64) -> Vec<(f64, f64)> {
    let g = 0.3 * h;
    let mid = (t.2 + t.3) / 2.0 - h / 2.0;
    let mut c = vec![
        (t.0, t.3 + g),
        (t.0, t.2 - g - h),
        (t.1 - w, t.3 + g),
        (t.1 + g, mid),
        (t.0 - g - w, mid),
        (t.1 - w, t.2 - g - h),
    ];
    for n in 1..=8 {
        let up = f64::from(n) * 1.15 * h;
        for x in [t.0, t.1 - w] {
            c.push((x, t.3 + g + up));
            c.push((x, t.2 - g - h - up));
        }
    }
    c
}

/// Places `labels` in order inside `bounds` (metres), text `h` metres high; returns each label
/// with the bottom-left corner of its text. A label with no free position takes its first
/// position inside the panel (moved inside when none is).
pub fn place_labels(labels: &[Label], bounds: Rect, h: f64) -> Vec<(&Label, (f64, f64))> {
    let mut placed: Vec<Rect> = Vec::new();
    let mut out = Vec::new();
    for l in labels {
        let w = l.text.chars().count() as f64 * ADVANCE_EM * h;
        // Padded: glyphs reach a little beyond the em box.
        let rect = |(x, y): (f64, f64)| (x - 0.1 * h, x + w + 0.2 * h, y - 0.15 * h, y + 1.2 * h);
        let cands = candidates(l.target, w, h);
        let free = cands
            .iter()
            .copied()
            .find(|&p| inside(rect(p), bounds) && placed.iter().all(|r| !overlaps(*r, rect(p))));
        let at = free
            .or_else(|| cands.iter().copied().find(|&p| inside(rect(p), bounds)))
            .unwrap_or_else(|| {
                let (x, y) = cands[0];
                (
                    x.clamp(bounds.0, (bounds.1 - w).max(bounds.0)),
                    y.clamp(bounds.2, (bounds.3 - h).max(bounds.2)),
                )
            });
        placed.push(rect(at));
        out.push((l, at));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn labels_of_neighbouring_boxes_do_not_overlap() {
        // Five points 0.5 m apart, text 1 m high: the natural spots all collide.
        let labels: Vec<Label> = (0..5)
            .map(|i| {
                Label::at(
                    format!("pedestrian {i}"),
                    (f64::from(i) * 0.5, 0.0),
                    RGBColor(0, 0, 0),
                )
            })
            .collect();
        let bounds = (-50.0, 50.0, -50.0, 50.0);
        let placed = place_labels(&labels, bounds, 1.0);
        let rects: Vec<Rect> = placed
            .iter()
            .map(|(l, (x, y))| (*x, x + l.text.len() as f64 * 0.6, *y, y + 1.05))
            .collect();
        for i in 0..rects.len() {
            assert!(inside(rects[i], bounds));
            for j in 0..i {
                assert!(!overlaps(rects[i], rects[j]), "{i} and {j}: {rects:?}");
            }
        }
        // The first one takes the best spot: just above its target.
        assert_eq!(placed[0].1, (0.0, 0.3));
    }
}
