//! What one panel of `probmot plot` draws, in picture pixels: every box outline, heading tick
//! and path step clipped to the plotting area, the bold last box of each id, the event marks,
//! and the labels to place (events first, then the ids the events involve, then the other ids,
//! longest-lived first). The thin lines, several for every box, are handed to the caller in
//! batches as they are made (and drawn at once), so a panel of millions of boxes does not hold
//! them; the rest waits for the labels to be placed.

use std::collections::{BTreeMap, BTreeSet};

use super::labels::LabelRequest;
use super::plot_layout::{LabelKind, MarkLayout, PxRect, View};
use super::plot_types::{EventMark, Panel, DETECTION_GREY, UNMATCHED};
use super::text::text_size;
use super::{Frame, Layer};
use crate::mcapio::LabelledBox;
use crate::msgs::colors::id_color;
use crate::msgs::eval_event::Kind;
use crate::msgs::eval_events::kind_rgb;

/// A line segment to draw (already clipped to the plotting area).
#[derive(Debug, Clone, Copy)]
pub(super) struct Stroke {
    /// From, pixels.
    pub a: (f64, f64),
    /// To, pixels.
    pub b: (f64, f64),
    /// Colour.
    pub color: (u8, u8, u8),
    /// Opacity, 0 to 1.
    pub alpha: f64,
    /// Width, pixels.
    pub width: f64,
}

/// A label waiting for a place.
#[derive(Debug, Clone)]
pub(super) struct Pending {
    pub kind: LabelKind,
    pub text: String,
    pub color: (u8, u8, u8),
    pub request: LabelRequest,
}

/// Thin lines handed over at a time.
const THIN_BATCH: usize = 4096;

/// The panel's geometry.
#[derive(Debug, Default)]
pub(super) struct Scene {
    /// Thin lines not yet handed over: boxes, ticks, paths.
    strokes: Vec<Stroke>,
    /// Bold lines: the last box of each id.
    pub bold: Vec<Stroke>,
    /// Bounding boxes of the bold last boxes in view.
    pub last_boxes: Vec<PxRect>,
    /// Event marks with their kinds (all of them; those out of view are not drawn).
    pub marks: Vec<(Kind, MarkLayout)>,
    /// Labels to place, most important first.
    pub labels: Vec<Pending>,
}

/// Sizes at the picture's text scale.
#[derive(Debug, Clone, Copy)]
pub(super) struct Sizes {
    /// Text scale (1 at 700 px high).
    pub k: f64,
    /// Label text height, pixels.
    pub label_px: f64,
}

impl Sizes {
    /// Sizes for text scale `k`.
    pub fn new(k: f64) -> Sizes {
        Sizes {
            k,
            label_px: (13.0 * k).round(),
        }
    }

    /// Box of a label's text with its backing.
    pub fn label_box(&self, text: &str) -> (f64, f64) {
        let (w, h) = text_size(text, self.label_px);
        (w.ceil() + 4.0, h + 2.0)
    }
}

/// Per id, in time order: its boxes with their stamps (id 0, detections, is one group).
fn by_id(frames: &[Frame]) -> BTreeMap<u64, Vec<(u64, &LabelledBox)>> {
    let mut m: BTreeMap<u64, Vec<(u64, &LabelledBox)>> = BTreeMap::new();
    let mut order: Vec<&Frame> = frames.iter().collect();
    order.sort_by_key(|f| f.0);
    for (stamp, boxes) in order {
        for b in boxes.iter().filter(|b| bev_drawable(b)) {
            m.entry(b.id).or_default().push((*stamp, b));
        }
    }
    m
}

/// Whether a box can be drawn from above: finite ground-plane centre, length, width and yaw.
pub fn bev_drawable(b: &LabelledBox) -> bool {
    b.center[0].is_finite()
        && b.center[1].is_finite()
        && b.size[0].is_finite()
        && b.size[1].is_finite()
        && b.yaw.is_finite()
}

/// Heading tick: from the middle of the front edge, outward by a third of the length (at most
/// 1.5 m, at least 0.5 m).
fn heading_tick(b: &LabelledBox) -> [(f64, f64); 2] {
    let (s, c) = b.yaw.sin_cos();
    let hl = b.size[0] / 2.0;
    let len = (b.size[0] / 3.0).clamp(0.5, 1.5);
    let (x, y) = (b.center[0], b.center[1]);
    [
        (x + hl * c, y + hl * s),
        (x + (hl + len) * c, y + (hl + len) * s),
    ]
}

/// The colour of a box of `panel` with id `id` at `stamp`.
fn box_color(panel: &Panel, id: u64, stamp: u64) -> (u8, u8, u8) {
    if !panel.layer.has_ids() {
        return DETECTION_GREY;
    }
    match &panel.truth_of {
        Some(m) => m.get(&(stamp, id)).map_or(UNMATCHED, |gt| id_color(*gt)),
        None => id_color(id),
    }
}

impl Scene {
    /// Adds the segments of a ground polyline, clipped to the view.
    fn line(&mut self, view: &View, pts: &[(f64, f64)], color: (u8, u8, u8), alpha: f64, w: f64) {
        for p in pts.windows(2) {
            if let Some([a, b]) = view.area.clip(view.to_px(p[0]), view.to_px(p[1])) {
                let s = Stroke {
                    a,
                    b,
                    color,
                    alpha,
                    width: w,
                };
                if w > 1.5 {
                    self.bold.push(s);
                } else {
                    self.strokes.push(s);
                }
            }
        }
    }

    /// Hands the thin lines to `thin` once there are [`THIN_BATCH`] of them.
    fn hand_over_full_batch<E>(
        &mut self,
        thin: &mut dyn FnMut(&mut Vec<Stroke>) -> Result<(), E>,
    ) -> Result<(), E> {
        if self.strokes.len() >= THIN_BATCH {
            thin(&mut self.strokes)?;
            self.strokes.clear();
        }
        Ok(())
    }

    /// Builds the panel's geometry in `view`; `marks` are drawn on panels with ids. The thin
    /// lines go to `thin` in order, in batches (it may empty the vector it gets).
    pub fn build<E>(
        panel: &Panel,
        view: &View,
        marks: &[EventMark],
        sz: Sizes,
        thin: &mut dyn FnMut(&mut Vec<Stroke>) -> Result<(), E>,
    ) -> Result<Scene, E> {
        let mut scene = Scene::default();
        let involved = scene.add_marks(panel, view, marks, sz);
        let mut ids: Vec<(bool, usize, u64, Pending)> = Vec::new();
        for (id, boxes) in by_id(&panel.frames) {
            for &(stamp, b) in &boxes {
                let c = b.bev_corners();
                let color = box_color(panel, id, stamp);
                scene.line(view, &[c[0], c[1], c[2], c[3], c[0]], color, 1.0, 1.0);
                scene.line(view, &heading_tick(b), color, 1.0, 1.0);
                scene.hand_over_full_batch(thin)?;
            }
            if !panel.layer.has_ids() {
                continue;
            }
            // The path through the centres, each step in the colour of the box it leads to.
            for w in boxes.windows(2) {
                let (a, b) = (w[0].1.center, w[1].1.center);
                let color = box_color(panel, id, w[1].0);
                scene.line(view, &[(a[0], a[1]), (b[0], b[1])], color, 0.6, 1.0);
                scene.hand_over_full_batch(thin)?;
            }
            let Some(&(stamp, last)) = boxes.last() else {
                continue;
            };
            if let Some(p) = scene.last_box(panel, view, id, (stamp, last), sz) {
                ids.push((!involved.contains(&id), usize::MAX - boxes.len(), id, p));
            }
        }
        ids.sort_by_key(|(not_involved, rank, id, _)| (*not_involved, *rank, *id));
        scene.labels.extend(ids.into_iter().map(|t| t.3));
        thin(&mut scene.strokes)?;
        scene.strokes = Vec::new();
        Ok(scene)
    }

    /// Draws the bold last box of an id when its centre is in view, and returns its label.
    fn last_box(
        &mut self,
        panel: &Panel,
        view: &View,
        id: u64,
        (stamp, b): (u64, &LabelledBox),
        sz: Sizes,
    ) -> Option<Pending> {
        if !view.shows((b.center[0], b.center[1])) {
            return None;
        }
        let c = b.bev_corners();
        let color = box_color(panel, id, stamp);
        self.line(
            view,
            &[c[0], c[1], c[2], c[3], c[0]],
            color,
            1.0,
            2.5 * sz.k,
        );
        let px = c.iter().map(|p| view.to_px(*p));
        let target = PxRect::around(px)?;
        let target = clip_rect(&target, &view.area);
        self.last_boxes.push(target);
        let text = match b.label.is_empty() {
            true => format!("{id}"),
            false => format!("{} {id}", b.label),
        };
        Some(Pending {
            kind: LabelKind::Id,
            request: LabelRequest {
                size: sz.label_box(&text),
                target,
                steps: 8,
                strict: true,
            },
            text,
            color,
        })
    }

    /// Adds the marks (in view and not) and the labels of the switches and fragmentations in
    /// view; returns the ids the events involve (tracks on a tracks panel, else ground truth).
    fn add_marks(
        &mut self,
        panel: &Panel,
        view: &View,
        marks: &[EventMark],
        sz: Sizes,
    ) -> BTreeSet<u64> {
        let mut involved = BTreeSet::new();
        if !panel.layer.has_ids() {
            return involved;
        }
        let mut order: Vec<&EventMark> = marks.iter().collect();
        // Switches, then fragmentations, then the rest: the labels' order.
        order.sort_by_key(|m| match m.kind {
            Kind::Switch => 0,
            Kind::Fragmentation => 1,
            _ => 2,
        });
        for m in order {
            let labelled = matches!(m.kind, Kind::Switch | Kind::Fragmentation);
            let (metres, min_px) = match labelled {
                true => (1.0, 7.0),
                false => (0.5, 4.0),
            };
            let radius_px = (metres * view.px_per_m()).max(min_px * sz.k);
            let px = view.to_px((m.x, m.y));
            let in_view = view.shows((m.x, m.y));
            let mark = MarkLayout {
                kind: kind_key(m.kind).into(),
                text: m.text.clone(),
                world: (m.x, m.y),
                px,
                radius_px,
                in_view,
            };
            self.marks.push((m.kind, mark));
            if !(labelled && in_view) {
                continue;
            }
            involved.extend(match panel.layer {
                Layer::Tracks => [m.track_id, m.previous_track_id],
                _ => [m.truth_id, 0],
            });
            let target = PxRect::spanning(px, px).grown(radius_px);
            self.labels.push(Pending {
                kind: LabelKind::Event,
                text: m.text.clone(),
                color: kind_rgb(m.kind),
                request: LabelRequest {
                    size: sz.label_box(&m.text),
                    target: clip_rect(&target, &view.area),
                    steps: 16,
                    strict: false,
                },
            });
        }
        involved.remove(&0);
        involved
    }
}

/// `r` cut to `bounds` (a degenerate rectangle at the nearest edge when outside).
fn clip_rect(r: &PxRect, bounds: &PxRect) -> PxRect {
    PxRect {
        x0: r.x0.clamp(bounds.x0, bounds.x1),
        x1: r.x1.clamp(bounds.x0, bounds.x1),
        y0: r.y0.clamp(bounds.y0, bounds.y1),
        y1: r.y1.clamp(bounds.y0, bounds.y1),
    }
}

/// The name of an event kind in the layout.
pub(super) fn kind_key(k: Kind) -> &'static str {
    match k {
        Kind::Switch => "switch",
        Kind::Fragmentation => "fragmentation",
        Kind::FalsePositive => "false_positive",
        Kind::Miss => "miss",
        Kind::Match => "match",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A panel of `n` boxes on a line, all in view, in `layer`.
    fn panel(layer: Layer, n: u64) -> Panel {
        let boxes = (0..n)
            .map(|i| LabelledBox {
                id: if layer.has_ids() { 1 + i % 7 } else { 0 },
                label: "car".into(),
                center: [(i % 100) as f64, (i / 100) as f64, 0.8],
                size: [0.5, 0.3, 1.6],
                ..Default::default()
            })
            .collect();
        Panel {
            title: "t".into(),
            layer,
            frames: vec![(0, boxes)],
            truth_of: None,
        }
    }

    fn view() -> View {
        View {
            area: PxRect {
                x0: 0.0,
                x1: 1000.0,
                y0: 0.0,
                y1: 1000.0,
            },
            extent: (-5.0, 105.0, -5.0, 105.0),
        }
    }

    /// The thin lines come in batches of about [`THIN_BATCH`], all of them (four edges and a
    /// heading tick per box in view), and the scene keeps none.
    #[test]
    fn thin_lines_are_handed_over_in_batches() {
        for (layer, n) in [
            (Layer::Detections, 1000),
            (Layer::Detections, 10),
            (Layer::Tracks, 1000),
        ] {
            let mut batches = Vec::new();
            let mut thin = |s: &mut Vec<Stroke>| -> Result<(), ()> {
                batches.push(s.len());
                s.clear();
                Ok(())
            };
            let scene =
                Scene::build(&panel(layer, n), &view(), &[], Sizes::new(1.0), &mut thin).unwrap();
            assert!(scene.strokes.is_empty());
            let total: usize = batches.iter().sum();
            let paths = match layer.has_ids() {
                true => n as usize - 7, // one step between consecutive boxes of each of 7 ids
                false => 0,
            };
            assert_eq!(total, 5 * n as usize + paths, "{layer:?} {n}: {batches:?}");
            assert!(batches.iter().all(|&b| b < THIN_BATCH + 5), "{batches:?}");
            assert_eq!(batches.len(), total / THIN_BATCH + 1, "{batches:?}");
        }
    }

    /// An error of the caller stops the build.
    #[test]
    fn an_error_in_drawing_stops_the_build() {
        let mut fail = |_: &mut Vec<Stroke>| -> Result<(), &str> { Err("disk full") };
        let r = Scene::build(
            &panel(Layer::Detections, 1000),
            &view(),
            &[],
            Sizes::new(1.0),
            &mut fail,
        );
        assert_eq!(r.err(), Some("disk full"));
    }
}
