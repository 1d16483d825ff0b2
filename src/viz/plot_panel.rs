//! One panel of `probmot plot`: axes and grid for the region shown, then what the panel holds
//! ([`super::plot_scene`]) drawn in picture pixels, the labels placed apart
//! ([`super::labels`]) with leader lines to what they name, and the title, which says how many
//! labels found no room.

use anyhow::Result;
use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::labels::{place_labels, Obstacles, OccupancyGrid};
use super::plot_layout::{LabelLayout, PanelLayout, PxRect, View};
use super::plot_scene::{Scene, Sizes, Stroke};
use super::plot_types::{draw_err, equal_aspect, rgb, EventMark, Extent, Panel, FONT};
use super::text::text_size;
use crate::msgs::eval_event::Kind;
use crate::msgs::eval_events::kind_rgb;

type Chart<'a, DB> = ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// Draws the axes and grid in `area`; returns the chart on a region of `ext` with equal metres
/// per pixel on both axes, and the view it gives.
fn chart_for<'a, DB: DrawingBackend + 'a>(
    area: &'a DrawingArea<DB, Shift>,
    ext: Extent,
    sz: Sizes,
) -> Result<(Chart<'a, DB>, View)>
where
    DB::ErrorType: 'static,
{
    let px = |s: f64| (s * sz.k).round().max(1.0) as u32;
    let builder = |area| {
        let mut b = ChartBuilder::on(area);
        b.margin(px(8.0))
            .margin_right(px(14.0))
            .x_label_area_size(px(42.0))
            .y_label_area_size(px(52.0));
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
    let text = |s: f64| (FONT, (s * sz.k).round()).into_font().color(&BLACK);
    chart
        .configure_mesh()
        .x_desc("x (m)")
        .y_desc("y (m)")
        .x_labels(8)
        .y_labels(8)
        .x_label_formatter(&fmt)
        .y_label_formatter(&fmt)
        .label_style(text(12.0))
        .axis_desc_style(text(13.0))
        .bold_line_style(RGBColor(0xdd, 0xdd, 0xdd))
        .light_line_style(RGBColor(0xf2, 0xf2, 0xf2))
        .draw()
        .map_err(draw_err)?;
    let (xr, yr) = chart.plotting_area().get_pixel_range();
    let area = PxRect {
        x0: f64::from(xr.start),
        x1: f64::from(xr.end),
        y0: f64::from(yr.start),
        y1: f64::from(yr.end),
    };
    let view = View {
        area,
        extent: (x0, x1, y0, y1),
    };
    Ok((chart, view))
}

fn px(p: (f64, f64)) -> (i32, i32) {
    (p.0.round() as i32, p.1.round() as i32)
}

/// Draws line segments on the picture.
fn draw_strokes<DB: DrawingBackend>(
    canvas: &DrawingArea<DB, Shift>,
    strokes: &[Stroke],
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    for s in strokes {
        let style = rgb(s.color)
            .mix(s.alpha)
            .stroke_width(s.width.round().max(1.0) as u32);
        canvas
            .draw(&PathElement::new(vec![px(s.a), px(s.b)], style))
            .map_err(draw_err)?;
    }
    Ok(())
}

/// Draws the event marks in view: rings for switches, fragmentations and misses, crosses for
/// false positives.
fn draw_marks<DB: DrawingBackend>(
    canvas: &DrawingArea<DB, Shift>,
    scene: &Scene,
    sz: Sizes,
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    for (kind, m) in scene.marks.iter().filter(|m| m.1.in_view) {
        let kind = *kind;
        let bold = matches!(kind, Kind::Switch | Kind::Fragmentation);
        let width = ((if bold { 2.0 } else { 1.0 }) * sz.k).round().max(1.0) as u32;
        let style = rgb(kind_rgb(kind)).stroke_width(width);
        let (x, y, r) = (m.px.0, m.px.1, m.radius_px);
        if kind == Kind::FalsePositive {
            for (a, b) in [
                ((x - r, y - r), (x + r, y + r)),
                ((x - r, y + r), (x + r, y - r)),
            ] {
                canvas
                    .draw(&PathElement::new(vec![px(a), px(b)], style))
                    .map_err(draw_err)?;
            }
        } else {
            canvas
                .draw(&Circle::new(px(m.px), r.round() as i32, style))
                .map_err(draw_err)?;
        }
    }
    Ok(())
}

/// Draws the placed labels: leader lines (with a dot where they meet what they name), then
/// each text on a light backing.
fn draw_labels<DB: DrawingBackend>(
    canvas: &DrawingArea<DB, Shift>,
    labels: &[LabelLayout],
    sz: Sizes,
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    for l in labels {
        if let Some([a, b]) = l.leader {
            let c = rgb(l.color);
            canvas
                .draw(&PathElement::new(vec![px(a), px(b)], c.stroke_width(1)))
                .map_err(draw_err)?;
            let dot = (1.5 * sz.k).round().max(1.0) as i32;
            canvas
                .draw(&Circle::new(px(b), dot, c.filled()))
                .map_err(draw_err)?;
        }
    }
    for l in labels {
        let r = &l.rect;
        canvas
            .draw(&Rectangle::new(
                [px((r.x0, r.y0)), px((r.x1, r.y1))],
                WHITE.mix(0.8).filled(),
            ))
            .map_err(draw_err)?;
        let style = (FONT, sz.label_px)
            .into_font()
            .color(&rgb(l.color))
            .pos(Pos::new(HPos::Left, VPos::Top));
        canvas
            .draw(&Text::new(
                l.text.clone(),
                px((r.x0 + 2.0, r.y0 + 1.0)),
                style,
            ))
            .map_err(draw_err)?;
    }
    Ok(())
}

/// Draws one panel in `area` (`canvas` is the whole picture, in whose pixels the layout is):
/// every box in place, per id its path and its last box bold and labelled, the event marks
/// (on panels with ids), and its title.
pub(super) fn draw_panel<DB: DrawingBackend>(
    canvas: &DrawingArea<DB, Shift>,
    area: &DrawingArea<DB, Shift>,
    panel: &Panel,
    ext: Extent,
    sz: Sizes,
    marks: &[EventMark],
) -> Result<PanelLayout>
where
    DB::ErrorType: 'static,
{
    let title_px = (16.0 * sz.k).round();
    let (title_area, body) = area.split_vertically((title_px * 1.8).round() as u32);
    let (_chart, view) = chart_for(&body, ext, sz)?;
    // The thin lines are drawn as they come (nothing else is drawn before the bold ones), and
    // only their cells are kept, for the labels.
    let mut grid = OccupancyGrid::new(view.area, 2.0);
    let scene = Scene::build(panel, &view, marks, sz, &mut |strokes: &mut Vec<Stroke>| {
        for s in strokes.iter() {
            grid.mark(s.a, s.b);
        }
        draw_strokes(canvas, strokes)
    })?;
    for s in &scene.bold {
        grid.mark(s.a, s.b);
    }
    let lines = grid.finish();
    let mut obstacles = Obstacles {
        marks: Vec::new(),
        boxes: scene.last_boxes.iter().map(|r| r.grown(1.0)).collect(),
    };
    for (kind, m) in scene.marks.iter().filter(|m| m.1.in_view) {
        let r = PxRect::spanning(m.px, m.px).grown(m.radius_px + 1.0);
        match kind {
            Kind::Switch | Kind::Fragmentation => obstacles.marks.push(r),
            _ => obstacles.boxes.push(r),
        }
    }
    let requests: Vec<_> = scene.labels.iter().map(|l| l.request.clone()).collect();
    let placed = place_labels(&requests, view.area, &obstacles, &lines);
    let labels: Vec<LabelLayout> = (scene.labels.iter().zip(&placed))
        .filter_map(|(l, p)| {
            p.map(|p| LabelLayout {
                kind: l.kind,
                text: l.text.clone(),
                color: l.color,
                rect: p.rect,
                target: l.request.target,
                leader: p.leader,
            })
        })
        .collect();
    let labels_left_out = placed.iter().filter(|p| p.is_none()).count();
    draw_strokes(canvas, &scene.bold)?;
    draw_marks(canvas, &scene, sz)?;
    draw_labels(canvas, &labels, sz)?;
    if panel.frames.iter().all(|f| f.1.is_empty()) {
        let style = (FONT, (14.0 * sz.k).round())
            .into_font()
            .color(&RGBColor(0x80, 0x80, 0x80))
            .pos(Pos::new(HPos::Center, VPos::Center));
        canvas
            .draw(&Text::new(
                "no boxes in this window",
                px(view.area.center()),
                style,
            ))
            .map_err(draw_err)?;
    }
    let title = match labels_left_out {
        0 => panel.title.clone(),
        1 => format!("{}; 1 label left out", panel.title),
        n => format!("{}; {n} labels left out", panel.title),
    };
    let (tw, th) = title_area.dim_in_pixel();
    // Smaller type for a title wider than the panel (down to 10 px at 700 px high).
    let fit = f64::from(tw) * 0.98 / text_size(&title, title_px).0.max(1.0);
    let title_px = (title_px * fit.min(1.0)).max((10.0 * sz.k).round()).floor();
    let style = (FONT, title_px)
        .into_font()
        .color(&BLACK)
        .pos(Pos::new(HPos::Center, VPos::Center));
    title_area
        .draw(&Text::new(
            title.clone(),
            (tw as i32 / 2, th as i32 / 2),
            style,
        ))
        .map_err(draw_err)?;
    Ok(PanelLayout {
        title,
        view,
        last_boxes: scene.last_boxes,
        labels,
        labels_left_out,
        marks: scene.marks.into_iter().map(|m| m.1).collect(),
    })
}
