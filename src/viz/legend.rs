//! The legend of a `probmot plot` picture: a strip under the panels saying what each colour and
//! mark means, for the layers and events the picture holds (grey detections, a colour per id or
//! the colour of the matched ground truth, dark grey for a track matching nothing, bold last
//! box with path and heading tick, the four event marks).

use anyhow::Result;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::plot_layout::{LegendEntry, LegendLayout, PxRect, Swatch};
use super::plot_types::{draw_err, rgb, EventMark, Panel, DETECTION_GREY, FONT, UNMATCHED};
use super::text::text_size;
use super::Layer;
use crate::msgs::colors::id_color;
use crate::msgs::eval_event::Kind;
use crate::msgs::eval_events::kind_rgb;

/// The entries for these panels and marks, in order.
pub(super) fn entries(panels: &[Panel], marks: &[EventMark]) -> Vec<(Swatch, String)> {
    let has = |l: Layer| panels.iter().any(|p| p.layer == l);
    let ids = Swatch::Boxes((1..=3).map(id_color).collect());
    let mut out = Vec::new();
    if has(Layer::Detections) {
        out.push((
            Swatch::Boxes(vec![DETECTION_GREY]),
            "detection (no id)".into(),
        ));
    }
    let by_truth = (panels.iter()).any(|p| p.layer == Layer::Tracks && p.truth_of.is_some());
    if by_truth {
        out.push((
            ids.clone(),
            "track: colour of the ground-truth object it matches".into(),
        ));
        out.push((
            Swatch::Boxes(vec![UNMATCHED]),
            "track matching no ground truth".into(),
        ));
    } else if has(Layer::Tracks) {
        out.push((ids.clone(), "track: a colour per track id".into()));
    }
    if has(Layer::GroundTruth) {
        out.push((ids, "ground truth: a colour per object id".into()));
    }
    if has(Layer::Tracks) || has(Layer::GroundTruth) {
        out.push((
            Swatch::LastBox,
            "bold: last box of an id, line: its path, tick: heading".into(),
        ));
    }
    if !marks.is_empty() {
        let c = kind_rgb;
        out.push((Swatch::Ring(c(Kind::Switch)), "identity switch".into()));
        out.push((Swatch::Ring(c(Kind::Fragmentation)), "fragmentation".into()));
        out.push((
            Swatch::Cross(c(Kind::FalsePositive)),
            "false positive".into(),
        ));
        out.push((Swatch::SmallRing(c(Kind::Miss)), "miss".into()));
    }
    out
}

/// Width of a sample, pixels at text scale `k`.
fn swatch_width(s: &Swatch, k: f64) -> f64 {
    let w = match s {
        Swatch::Boxes(c) => 15.0 * c.len() as f64 - 3.0,
        Swatch::LastBox => 34.0,
        Swatch::Ring(_) => 16.0,
        Swatch::SmallRing(_) | Swatch::Cross(_) => 12.0,
    };
    (w * k).round()
}

/// Legend text height, pixels.
fn text_px(k: f64) -> f64 {
    (12.0 * k).round()
}

/// Places the entries in rows across `width` pixels from `(x0, y0)`; returns each entry's box.
fn flow(entries: &[(Swatch, String)], (x0, y0): (f64, f64), width: f64, k: f64) -> Vec<PxRect> {
    let (pad, gap, row) = ((10.0 * k).round(), (24.0 * k).round(), (20.0 * k).round());
    let mut out = Vec::with_capacity(entries.len());
    let (mut x, mut y) = (x0 + pad, y0 + (5.0 * k).round());
    for (s, text) in entries {
        let w = swatch_width(s, k) + (6.0 * k).round() + text_size(text, text_px(k)).0.ceil();
        if x > x0 + pad && x + w > x0 + width - pad {
            x = x0 + pad;
            y += row;
        }
        out.push(PxRect {
            x0: x,
            x1: x + w,
            y0: y,
            y1: y + row,
        });
        x += w + gap;
    }
    out
}

/// Height of the strip holding `entries` across `width` pixels.
pub(super) fn height(entries: &[(Swatch, String)], width: u32, k: f64) -> u32 {
    let rows = flow(entries, (0.0, 0.0), f64::from(width), k);
    rows.last().map_or(0.0, |r| r.y1 + (5.0 * k).round()).ceil() as u32
}

/// The legend in the strip `rect`.
pub(super) fn layout(entries: &[(Swatch, String)], rect: PxRect, k: f64) -> LegendLayout {
    let boxes = flow(entries, (rect.x0, rect.y0), rect.width(), k);
    LegendLayout {
        rect,
        entries: (entries.iter().zip(boxes))
            .map(|((swatch, text), r)| LegendEntry {
                swatch: swatch.clone(),
                text: text.clone(),
                rect: r,
            })
            .collect(),
    }
}

fn ipx(x: f64, y: f64) -> (i32, i32) {
    (x.round() as i32, y.round() as i32)
}

/// Draws a sample with its left edge at `x`, centred on `cy`.
fn draw_swatch<DB: DrawingBackend>(
    canvas: &DrawingArea<DB, Shift>,
    s: &Swatch,
    (x, cy): (f64, f64),
    k: f64,
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let half = (5.0 * k).round();
    let thin = (k.round() as u32).max(1);
    let result = match s {
        Swatch::Boxes(colours) => {
            for (i, c) in colours.iter().enumerate() {
                let x0 = x + i as f64 * (15.0 * k).round();
                let r = [ipx(x0, cy - half), ipx(x0 + 2.0 * half, cy + half)];
                canvas
                    .draw(&Rectangle::new(r, rgb(*c).stroke_width(thin)))
                    .map_err(draw_err)?;
            }
            Ok(())
        }
        Swatch::LastBox => {
            let c = rgb(id_color(1));
            let bx = [ipx(x + 14.0 * k, cy - half), ipx(x + 28.0 * k, cy + half)];
            canvas.draw(&Rectangle::new(
                bx,
                c.stroke_width((2.5 * k).round() as u32),
            ))?;
            canvas.draw(&PathElement::new(
                vec![ipx(x, cy), ipx(x + 14.0 * k, cy)],
                c.mix(0.6).stroke_width(thin),
            ))?;
            canvas.draw(&PathElement::new(
                vec![ipx(x + 28.0 * k, cy), ipx(x + 34.0 * k, cy)],
                c.stroke_width(thin),
            ))
        }
        Swatch::Ring(c) => canvas.draw(&Circle::new(
            ipx(x + 8.0 * k, cy),
            (7.0 * k).round() as i32,
            rgb(*c).stroke_width((2.0 * k).round().max(1.0) as u32),
        )),
        Swatch::SmallRing(c) => canvas.draw(&Circle::new(
            ipx(x + 6.0 * k, cy),
            (4.0 * k).round() as i32,
            rgb(*c).stroke_width(thin),
        )),
        Swatch::Cross(c) => {
            let r = 4.0 * k;
            let (mx, st) = (x + 6.0 * k, rgb(*c).stroke_width(thin));
            canvas.draw(&PathElement::new(
                vec![ipx(mx - r, cy - r), ipx(mx + r, cy + r)],
                st,
            ))?;
            canvas.draw(&PathElement::new(
                vec![ipx(mx - r, cy + r), ipx(mx + r, cy - r)],
                st,
            ))
        }
    };
    result.map_err(draw_err)
}

/// Draws the legend: a thin rule over the strip, then each entry's sample and text.
pub(super) fn draw<DB: DrawingBackend>(
    canvas: &DrawingArea<DB, Shift>,
    legend: &LegendLayout,
    k: f64,
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let r = &legend.rect;
    canvas
        .draw(&PathElement::new(
            vec![ipx(r.x0 + 10.0 * k, r.y0), ipx(r.x1 - 10.0 * k, r.y0)],
            RGBColor(0xcc, 0xcc, 0xcc).stroke_width(1),
        ))
        .map_err(draw_err)?;
    for e in &legend.entries {
        let cy = (e.rect.y0 + e.rect.y1) / 2.0;
        draw_swatch(canvas, &e.swatch, (e.rect.x0, cy), k)?;
        let x = e.rect.x0 + swatch_width(&e.swatch, k) + (6.0 * k).round();
        let style = (FONT, text_px(k))
            .into_font()
            .color(&BLACK)
            .pos(Pos::new(HPos::Left, VPos::Center));
        canvas
            .draw(&Text::new(e.text.clone(), ipx(x, cy), style))
            .map_err(draw_err)?;
    }
    Ok(())
}
