//! One panel of `probmot plot`: axes, the boxes of each id with its path, labels placed apart
//! ([`super::labels`]), and the evaluation's events.

use std::collections::BTreeMap;

use anyhow::Result;
use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::labels::{place_labels, Label};
use super::plot_types::{
    draw_err, equal_aspect, rgb, EventMark, Extent, Panel, DETECTION_GREY, FONT, UNMATCHED,
};
use super::Frame;
use crate::mcapio::LabelledBox;
use crate::msgs::colors::id_color;
use crate::msgs::eval_event::Kind;
use crate::msgs::eval_events::kind_rgb;

type Chart<'a, DB> = ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// Per id, in time order: its boxes with their stamps (id 0, detections, is one group).
fn by_id(frames: &[Frame]) -> BTreeMap<u64, Vec<(u64, &LabelledBox)>> {
    let mut m: BTreeMap<u64, Vec<(u64, &LabelledBox)>> = BTreeMap::new();
    let mut order: Vec<&Frame> = frames.iter().collect();
    order.sort_by_key(|f| f.0);
    for (stamp, boxes) in order {
        for b in boxes {
            m.entry(b.id).or_default().push((*stamp, b));
        }
    }
    m
}

fn outline(b: &LabelledBox) -> Vec<(f64, f64)> {
    let c = b.bev_corners();
    vec![c[0], c[1], c[2], c[3], c[0]]
}

/// Heading tick: from the middle of the front edge, outward by a third of the length (at most
/// 1.5 m, at least 0.5 m).
fn heading_tick(b: &LabelledBox) -> Vec<(f64, f64)> {
    let (s, c) = b.yaw.sin_cos();
    let hl = b.size[0] / 2.0;
    let len = (b.size[0] / 3.0).clamp(0.5, 1.5);
    let (x, y) = (b.center[0], b.center[1]);
    vec![
        (x + hl * c, y + hl * s),
        (x + (hl + len) * c, y + (hl + len) * s),
    ]
}

/// Whether a box can be drawn from above: finite ground-plane centre, length, width and yaw.
pub fn bev_drawable(b: &LabelledBox) -> bool {
    b.center[0].is_finite()
        && b.center[1].is_finite()
        && b.size[0].is_finite()
        && b.size[1].is_finite()
        && b.yaw.is_finite()
}

/// Pixel sizes at the picture's text scale `k`.
#[derive(Clone, Copy)]
struct Scale {
    k: f64,
    /// Metres per pixel of the plotting area.
    m_per_px: f64,
}

impl Scale {
    fn px(self, s: f64) -> f64 {
        (s * self.k).round()
    }
    fn pxu(self, s: f64) -> u32 {
        (s * self.k).round().max(1.0) as u32
    }
}

/// The colour of a box of `panel` with id `id` at `stamp`.
fn box_color(panel: &Panel, id: u64, stamp: u64) -> RGBColor {
    if !panel.layer.has_ids() {
        return rgb(DETECTION_GREY);
    }
    match &panel.truth_of {
        Some(m) => m
            .get(&(stamp, id))
            .map_or(rgb(UNMATCHED), |gt| rgb(id_color(*gt))),
        None => rgb(id_color(id)),
    }
}

/// Draws the axes and grid in the (titled) `area`; returns the chart on a region of `ext` with
/// equal metres per pixel on both axes, and the scale.
fn chart_for<'a, DB: DrawingBackend + 'a>(
    area: &'a DrawingArea<DB, Shift>,
    ext: Extent,
    k: f64,
) -> Result<(Chart<'a, DB>, Scale)>
where
    DB::ErrorType: 'static,
{
    let sc = Scale { k, m_per_px: 1.0 };
    let builder = |area| {
        let mut b = ChartBuilder::on(area);
        b.margin(sc.pxu(8.0))
            .margin_right(sc.pxu(14.0))
            .x_label_area_size(sc.pxu(42.0))
            .y_label_area_size(sc.pxu(52.0));
        b
    };
    // First build on a dummy range to learn the plotting area's size (building draws nothing).
    let (pw, ph) = builder(area)
        .build_cartesian_2d(0f64..1f64, 0f64..1f64)
        .map_err(draw_err)?
        .plotting_area()
        .dim_in_pixel();
    let (x0, x1, y0, y1) = equal_aspect(ext, pw, ph);
    let mut chart = builder(area)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(draw_err)?;
    let fmt = |v: &f64| format!("{v:.0}");
    chart
        .configure_mesh()
        .x_desc("x (m)")
        .y_desc("y (m)")
        .x_labels(8)
        .y_labels(8)
        .x_label_formatter(&fmt)
        .y_label_formatter(&fmt)
        .label_style((FONT, sc.px(12.0)).into_font().color(&BLACK))
        .axis_desc_style((FONT, sc.px(13.0)).into_font().color(&BLACK))
        .bold_line_style(RGBColor(0xdd, 0xdd, 0xdd))
        .light_line_style(RGBColor(0xf2, 0xf2, 0xf2))
        .draw()
        .map_err(draw_err)?;
    let m_per_px = (x1 - x0) / f64::from(pw.max(1));
    Ok((chart, Scale { k, m_per_px }))
}

/// Draws one panel in `area`: every box in place, per id its path and its last box bold and
/// labelled, then the event marks (on panels with ids).
pub(super) fn draw_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    panel: &Panel,
    ext: Extent,
    k: f64,
    marks: &[EventMark],
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let title_font = (FONT, (16.0 * k).round()).into_font().color(&BLACK);
    let area = area.titled(&panel.title, title_font).map_err(draw_err)?;
    let (mut chart, sc) = chart_for(&area, ext, k)?;
    let groups = by_id(&panel.frames);
    if groups.values().all(|v| v.is_empty()) {
        let (xr, yr) = (chart.x_range(), chart.y_range());
        let (cx, cy) = ((xr.start + xr.end) / 2.0, (yr.start + yr.end) / 2.0);
        chart
            .draw_series(std::iter::once(Text::new(
                "no boxes in this window".to_string(),
                (cx, cy),
                (FONT, sc.px(14.0))
                    .into_font()
                    .color(&RGBColor(0x80, 0x80, 0x80))
                    .pos(Pos::new(HPos::Center, VPos::Center)),
            )))
            .map_err(draw_err)?;
        return Ok(());
    }
    // Event texts are placed first: they get the best spots.
    let mut labels = Vec::new();
    if panel.layer.has_ids() {
        draw_marks(&mut chart, marks, sc, &mut labels)?;
    }
    for (&id, boxes) in &groups {
        let boxes: Vec<(u64, &LabelledBox)> = boxes
            .iter()
            .copied()
            .filter(|b| bev_drawable(b.1))
            .collect();
        if let Some(label) = draw_id(&mut chart, panel, id, &boxes, sc)? {
            labels.push(label);
        }
    }
    let (x, y) = (chart.x_range(), chart.y_range());
    let bounds = (x.start, x.end, y.start, y.end);
    let label_px = sc.px(13.0);
    let placed = place_labels(&labels, bounds, label_px * sc.m_per_px);
    chart
        .draw_series(placed.into_iter().map(|(l, at)| {
            let style = (FONT, label_px)
                .into_font()
                .color(&l.color)
                .pos(Pos::new(HPos::Left, VPos::Bottom));
            Text::new(l.text.clone(), at, style)
        }))
        .map_err(draw_err)?;
    Ok(())
}

/// Draws the boxes of one id (its path and bold last box when the layer has ids); returns the
/// label to place for it.
fn draw_id<DB: DrawingBackend>(
    chart: &mut Chart<'_, DB>,
    panel: &Panel,
    id: u64,
    boxes: &[(u64, &LabelledBox)],
    sc: Scale,
) -> Result<Option<Label>>
where
    DB::ErrorType: 'static,
{
    let Some(&(last_stamp, last)) = boxes.last() else {
        return Ok(None);
    };
    let thin = sc.pxu(1.0);
    chart
        .draw_series(boxes.iter().flat_map(|(stamp, b)| {
            let style = box_color(panel, id, *stamp).stroke_width(thin);
            [outline(b), heading_tick(b)]
                .into_iter()
                .map(move |pts| PathElement::new(pts, style))
        }))
        .map_err(draw_err)?;
    if !panel.layer.has_ids() {
        return Ok(None);
    }
    // The path through the box centres, each step in the colour of the box it leads to.
    chart
        .draw_series(boxes.windows(2).map(|w| {
            let color = box_color(panel, id, w[1].0).mix(0.6).stroke_width(thin);
            let (a, b) = (w[0].1.center, w[1].1.center);
            PathElement::new(vec![(a[0], a[1]), (b[0], b[1])], color)
        }))
        .map_err(draw_err)?;
    let color = box_color(panel, id, last_stamp);
    chart
        .draw_series(std::iter::once(PathElement::new(
            outline(last),
            color.stroke_width(sc.pxu(2.5)),
        )))
        .map_err(draw_err)?;
    let text = if last.label.is_empty() {
        format!("{id}")
    } else {
        format!("{} {id}", last.label)
    };
    Ok(Some(Label::beside(text, last, color)))
}

/// Marks the events: switches and fragmentations as a ring with their text (placed with the
/// labels), false positives as a cross, misses as a small ring.
fn draw_marks<DB: DrawingBackend>(
    chart: &mut Chart<'_, DB>,
    marks: &[EventMark],
    sc: Scale,
    labels: &mut Vec<Label>,
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    for m in marks {
        let color = rgb(kind_rgb(m.kind));
        let r = match m.kind {
            Kind::Switch | Kind::Fragmentation => 1.0,
            _ => 0.5,
        };
        let ring: Vec<(f64, f64)> = (0..=24)
            .map(|i| {
                let a = f64::from(i) / 24.0 * std::f64::consts::TAU;
                (m.x + r * a.cos(), m.y + r * a.sin())
            })
            .collect();
        let style = color.stroke_width(sc.pxu(if r > 1.0 { 2.5 } else { 1.0 }));
        let shapes = if m.kind == Kind::FalsePositive {
            vec![
                vec![(m.x - r, m.y - r), (m.x + r, m.y + r)],
                vec![(m.x - r, m.y + r), (m.x + r, m.y - r)],
            ]
        } else {
            vec![ring]
        };
        chart
            .draw_series(shapes.into_iter().map(|s| PathElement::new(s, style)))
            .map_err(draw_err)?;
        if matches!(m.kind, Kind::Switch | Kind::Fragmentation) {
            labels.push(Label::at(m.text.clone(), (m.x + r, m.y + r), color));
        }
    }
    Ok(())
}
