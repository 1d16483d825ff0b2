//! Static bird's-eye-view pictures: one panel per layer side by side, every box of the chosen
//! frames drawn in place as an oriented rectangle with a heading tick, a colour per id (grey for
//! detections), each id's centre path, and the id's label beside its last box. Axes are in metres
//! with the same metres per pixel on x and y, and every panel shows the same region.
//!
//! Pure drawing: frames in, PNG bytes out. Text is drawn with a TTF embedded in the binary (Hack,
//! from the `epaint_default_fonts` crate), so no system font is needed.

use std::collections::BTreeMap;
use std::sync::OnceLock;

use anyhow::{anyhow, bail, Context, Result};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use plotters::style::{register_font, FontStyle};

use super::{BevBox, Frame, Layer};

/// One panel: a titled BEV view of one layer's frames.
#[derive(Debug, Clone)]
pub struct Panel {
    /// Title drawn above the panel.
    pub title: String,
    /// The layer, which decides the colouring (grey detections, a colour per id otherwise).
    pub layer: Layer,
    /// The frames to draw, all in place.
    pub frames: Vec<Frame>,
}

/// Size and title of the picture.
#[derive(Debug, Clone)]
pub struct PlotOptions {
    /// Width of the whole picture, pixels.
    pub width: u32,
    /// Height of the whole picture, pixels.
    pub height: u32,
    /// Title above all panels, if any.
    pub title: Option<String>,
}

impl Default for PlotOptions {
    fn default() -> Self {
        PlotOptions {
            width: 1800,
            height: 700,
            title: None,
        }
    }
}

pub use crate::msgs::colors::{id_color, mix64, PALETTE};

/// Colour of detections, which have no id.
pub const DETECTION_GREY: (u8, u8, u8) = (0x8c, 0x8c, 0x8c);

/// Picture background.
pub const BACKGROUND: (u8, u8, u8) = (0xff, 0xff, 0xff);

fn rgb(c: (u8, u8, u8)) -> RGBColor {
    RGBColor(c.0, c.1, c.2)
}

/// Font family name under which the embedded font is registered (also as `sans-serif`, the
/// family plotters uses for its default text).
const FONT: &str = "sans-serif";

/// Registers the embedded font with plotters, once per process.
pub fn register_fonts() -> Result<()> {
    static OK: OnceLock<bool> = OnceLock::new();
    let ok = *OK.get_or_init(|| {
        let font: &'static [u8] = epaint_default_fonts::HACK_REGULAR;
        ["sans-serif", "serif", "monospace"]
            .iter()
            .all(|name| register_font(name, FontStyle::Normal, font).is_ok())
    });
    if ok {
        Ok(())
    } else {
        bail!("the embedded font could not be loaded")
    }
}

/// World region `[x0, x1] x [y0, y1]` covering every box corner of every panel, with a margin;
/// `None` when there is no box.
pub fn world_extent(panels: &[Panel]) -> Option<(f64, f64, f64, f64)> {
    let mut ext: Option<(f64, f64, f64, f64)> = None;
    for b in panels
        .iter()
        .flat_map(|p| p.frames.iter().flat_map(|f| f.1.iter()))
    {
        for (x, y) in b.corners() {
            if !(x.is_finite() && y.is_finite()) {
                continue;
            }
            ext = Some(match ext {
                None => (x, x, y, y),
                Some((a, b, c, d)) => (a.min(x), b.max(x), c.min(y), d.max(y)),
            });
        }
    }
    let (x0, x1, y0, y1) = ext?;
    // At least 10 m across, and 5 % (at least 2 m) of margin on every side.
    let (cx, cy) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0);
    let (hx, hy) = (((x1 - x0) / 2.0).max(5.0), ((y1 - y0) / 2.0).max(5.0));
    let m = (0.05 * hx.max(hy)).max(2.0);
    Some((cx - hx - m, cx + hx + m, cy - hy - m, cy + hy + m))
}

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

fn draw_err<E: std::fmt::Display>(e: E) -> anyhow::Error {
    anyhow!("drawing failed: {e}")
}

/// Renders the panels side by side into an RGB buffer of `width * height * 3` bytes.
pub fn render_rgb(panels: &[Panel], opts: &PlotOptions) -> Result<Vec<u8>> {
    if panels.is_empty() {
        bail!("nothing to plot: no panel");
    }
    if opts.width < 100 * panels.len() as u32 || opts.height < 100 {
        bail!(
            "picture of {}x{} px is too small for {} panel(s); give at least {} x 100 px",
            opts.width,
            opts.height,
            panels.len(),
            100 * panels.len()
        );
    }
    let Some(ext) = world_extent(panels) else {
        bail!("nothing to plot: no box in any panel");
    };
    register_fonts()?;
    let (w, h) = (opts.width, opts.height);
    let mut buf = vec![0u8; w as usize * h as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&rgb(BACKGROUND)).map_err(draw_err)?;
        // Text sizes follow the picture's height (700 px: 1x).
        let k = (f64::from(h) / 700.0).clamp(0.7, 2.5);
        let px = |s: f64| (s * k).round();
        let root = match &opts.title {
            Some(t) => root
                .titled(t, (FONT, px(20.0)).into_font().color(&BLACK))
                .map_err(draw_err)?,
            None => root,
        };
        let areas = root.split_evenly((1, panels.len()));
        for (area, panel) in areas.iter().zip(panels) {
            draw_panel(area, panel, ext, k)?;
        }
        root.present().map_err(draw_err)?;
    }
    Ok(buf)
}

/// Renders the panels side by side and encodes them as a PNG.
pub fn render_png(panels: &[Panel], opts: &PlotOptions) -> Result<Vec<u8>> {
    let rgb = render_rgb(panels, opts)?;
    encode_png(&rgb, opts.width, opts.height)
}

/// Encodes an RGB buffer as PNG bytes.
pub fn encode_png(rgb: &[u8], width: u32, height: u32) -> Result<Vec<u8>> {
    let mut out = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut out, width, height);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        enc.set_compression(png::Compression::Best);
        let mut wr = enc.write_header().context("encoding PNG")?;
        wr.write_image_data(rgb).context("encoding PNG")?;
        wr.finish().context("encoding PNG")?;
    }
    Ok(out)
}

/// Per id, in time order: its boxes (id 0 — detections — is one group).
fn by_id(frames: &[Frame]) -> BTreeMap<u64, Vec<&BevBox>> {
    let mut m: BTreeMap<u64, Vec<&BevBox>> = BTreeMap::new();
    let mut order: Vec<&Frame> = frames.iter().collect();
    order.sort_by_key(|f| f.0);
    for (_, boxes) in order {
        for b in boxes {
            m.entry(b.id).or_default().push(b);
        }
    }
    m
}

fn outline(b: &BevBox) -> Vec<(f64, f64)> {
    let c = b.corners();
    vec![c[0], c[1], c[2], c[3], c[0]]
}

/// Heading tick: from the middle of the front edge, outward by a third of the length (at most
/// 1.5 m, at least 0.5 m).
fn heading_tick(b: &BevBox) -> Vec<(f64, f64)> {
    let (s, c) = b.yaw.sin_cos();
    let hl = b.size[0] / 2.0;
    let len = (b.size[0] / 3.0).clamp(0.5, 1.5);
    let (x, y) = (b.center[0], b.center[1]);
    vec![
        (x + hl * c, y + hl * s),
        (x + (hl + len) * c, y + (hl + len) * s),
    ]
}

fn finite(b: &BevBox) -> bool {
    b.center[0].is_finite()
        && b.center[1].is_finite()
        && b.size[0].is_finite()
        && b.size[1].is_finite()
        && b.yaw.is_finite()
}

fn draw_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    panel: &Panel,
    ext: (f64, f64, f64, f64),
    k: f64,
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let px = |s: f64| (s * k).round();
    let pxu = |s: f64| (s * k).round().max(1.0) as u32;
    let area = area
        .titled(&panel.title, (FONT, px(16.0)).into_font().color(&BLACK))
        .map_err(draw_err)?;
    let builder = || {
        let mut b = ChartBuilder::on(&area);
        b.margin(pxu(8.0))
            .margin_right(pxu(14.0))
            .x_label_area_size(pxu(42.0))
            .y_label_area_size(pxu(52.0));
        b
    };
    // First build on a dummy range to learn the plotting area's size, then the real one with
    // equal metres per pixel on both axes (building draws nothing).
    let (pw, ph) = builder()
        .build_cartesian_2d(0f64..1f64, 0f64..1f64)
        .map_err(draw_err)?
        .plotting_area()
        .dim_in_pixel();
    let (x0, x1, y0, y1) = equal_aspect(ext, pw, ph);
    let mut chart = builder()
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
        .label_style((FONT, px(12.0)).into_font().color(&BLACK))
        .axis_desc_style((FONT, px(13.0)).into_font().color(&BLACK))
        .bold_line_style(RGBColor(0xdd, 0xdd, 0xdd))
        .light_line_style(RGBColor(0xf2, 0xf2, 0xf2))
        .draw()
        .map_err(draw_err)?;

    let groups = by_id(&panel.frames);
    if groups.values().all(|v| v.is_empty()) {
        let (cx, cy) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0);
        chart
            .draw_series(std::iter::once(Text::new(
                "no boxes in this window".to_string(),
                (cx, cy),
                (FONT, px(14.0))
                    .into_font()
                    .color(&RGBColor(0x80, 0x80, 0x80))
                    .pos(Pos::new(HPos::Center, VPos::Center)),
            )))
            .map_err(draw_err)?;
        return Ok(());
    }

    let thin = pxu(1.0);
    // Labels are drawn after every box, so that no box covers one.
    let mut labels: Vec<(String, (f64, f64), Pos, RGBColor)> = Vec::new();
    let label_px = px(13.0);
    let m_per_px = (x1 - x0) / f64::from(pw.max(1));
    for (&id, boxes) in &groups {
        let boxes: Vec<&BevBox> = boxes.iter().copied().filter(|b| finite(b)).collect();
        if boxes.is_empty() {
            continue;
        }
        let color = if panel.layer.has_ids() {
            rgb(id_color(id))
        } else {
            rgb(DETECTION_GREY)
        };
        let style = color.stroke_width(thin);
        chart
            .draw_series(
                boxes
                    .iter()
                    .flat_map(|b| [outline(b), heading_tick(b)])
                    .map(|pts| PathElement::new(pts, style)),
            )
            .map_err(draw_err)?;
        if !panel.layer.has_ids() {
            continue;
        }
        // The id's path through its box centres, and its last box drawn bold and labelled.
        if boxes.len() > 1 {
            chart
                .draw_series(LineSeries::new(
                    boxes.iter().map(|b| (b.center[0], b.center[1])),
                    color.mix(0.6).stroke_width(thin),
                ))
                .map_err(draw_err)?;
        }
        let last = boxes[boxes.len() - 1];
        chart
            .draw_series(std::iter::once(PathElement::new(
                outline(last),
                color.stroke_width(pxu(2.5)),
            )))
            .map_err(draw_err)?;
        let label = if last.label.is_empty() {
            format!("{id}")
        } else {
            format!("{} {id}", last.label)
        };
        // Above the last box (below it when it heads down, so the label is ahead of it and off
        // its path), starting at its left edge, or ending at its right edge when the text
        // would leave the panel.
        let c = last.corners();
        let fold = |f: fn(&(f64, f64)) -> f64, init: f64, pick: fn(f64, f64) -> f64| {
            c.iter().map(f).fold(init, pick)
        };
        let (xl, xr) = (
            fold(|p| p.0, f64::MAX, f64::min),
            fold(|p| p.0, f64::MIN, f64::max),
        );
        let (yb, yt) = (
            fold(|p| p.1, f64::MAX, f64::min),
            fold(|p| p.1, f64::MIN, f64::max),
        );
        let gap = 3.0 * m_per_px;
        // Hack is monospaced: every advance is 0.6 em.
        let text_w = label.chars().count() as f64 * 0.6 * label_px * m_per_px;
        let (x, h) = if xl + text_w <= x1 {
            (xl, HPos::Left)
        } else {
            (xr, HPos::Right)
        };
        let (y, v) = if last.yaw.sin() < -0.5 {
            (yb - gap, VPos::Top)
        } else {
            (yt + gap, VPos::Bottom)
        };
        labels.push((label, (x, y), Pos::new(h, v), color));
    }
    chart
        .draw_series(labels.into_iter().map(|(text, at, pos, color)| {
            let style = (FONT, label_px).into_font().color(&color).pos(pos);
            Text::new(text, at, style)
        }))
        .map_err(draw_err)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bx(id: u64, x: f64, y: f64, yaw: f64) -> BevBox {
        BevBox {
            id,
            label: "car".into(),
            center: [x, y, 0.8],
            size: [4.5, 1.9, 1.6],
            yaw,
            score: 0.9,
            velocity: [0.0; 3],
        }
    }

    #[test]
    fn id_colours_are_stable_and_spread() {
        assert_eq!(id_color(7), id_color(7));
        // Known values: the same hash is used by scripts/to_rerun.py.
        assert_eq!(mix64(0), 0xe220_a839_7b1d_cdaf);
        assert_eq!(mix64(1), 0x910a_2dec_8902_5cc1);
        let distinct: std::collections::BTreeSet<_> = (1..=20u64).map(id_color).collect();
        assert!(distinct.len() >= 8, "{distinct:?}");
        assert!(!PALETTE.contains(&DETECTION_GREY));
    }

    #[test]
    fn equal_aspect_gives_equal_scale() {
        let (x0, x1, y0, y1) = equal_aspect((0.0, 100.0, 0.0, 10.0), 500, 400);
        assert!(((x1 - x0) / 500.0 - (y1 - y0) / 400.0).abs() < 1e-12);
        assert!((x1 - x0 - 100.0).abs() < 1e-9, "x was the binding axis");
        assert!(((y0 + y1) / 2.0 - 5.0).abs() < 1e-12, "centre kept");
    }

    #[test]
    fn extent_covers_every_corner() {
        let p = Panel {
            title: "t".into(),
            layer: Layer::Tracks,
            frames: vec![(0, vec![bx(1, 0.0, 0.0, 0.0), bx(1, 50.0, 20.0, 1.0)])],
        };
        let (x0, x1, y0, y1) = world_extent(std::slice::from_ref(&p)).unwrap();
        for b in &p.frames[0].1 {
            for (x, y) in b.corners() {
                assert!(x > x0 && x < x1 && y > y0 && y < y1);
            }
        }
        let empty = Panel {
            frames: vec![(0, vec![])],
            ..p
        };
        assert!(world_extent(&[empty]).is_none());
    }

    #[test]
    fn renders_a_png_of_the_requested_size() {
        let frames: Vec<Frame> = (0..10)
            .map(|i| {
                let t = f64::from(i);
                (
                    i as u64,
                    vec![bx(3, 5.0 * t, 0.0, 0.0), bx(9, 0.0, 4.0 * t, 1.57)],
                )
            })
            .collect();
        let panels = vec![
            Panel {
                title: "detections".into(),
                layer: Layer::Detections,
                frames: frames.clone(),
            },
            Panel {
                title: "tracks".into(),
                layer: Layer::Tracks,
                frames,
            },
        ];
        let opts = PlotOptions {
            width: 640,
            height: 300,
            title: Some("test".into()),
        };
        let rgb = render_rgb(&panels, &opts).unwrap();
        assert_eq!(rgb.len(), 640 * 300 * 3);
        let has = |c: (u8, u8, u8)| rgb.chunks(3).any(|p| (p[0], p[1], p[2]) == c);
        assert!(has(id_color(3)) && has(id_color(9)) && has(DETECTION_GREY));
        let png = encode_png(&rgb, 640, 300).unwrap();
        assert_eq!(&png[1..4], b"PNG");
        // Too small, and nothing to draw, are errors.
        assert!(render_rgb(
            &panels,
            &PlotOptions {
                width: 150,
                ..opts.clone()
            }
        )
        .is_err());
        let empty = vec![Panel {
            title: "x".into(),
            layer: Layer::Tracks,
            frames: vec![(0, vec![])],
        }];
        assert!(render_rgb(&empty, &opts).is_err());
    }
}
