//! Static bird's-eye-view pictures: one panel per layer side by side, every box of the chosen
//! frames drawn in place as an oriented rectangle with a heading tick, a colour per id (grey for
//! detections), each id's centre path, and the id's label beside its last box (labels placed
//! apart, [`super::labels`]), with a legend under the panels (the `legend` module). Track boxes can
//! take the colour of the ground truth they match, so a track that follows one object keeps one
//! colour and an identity switch shows as a colour change; the evaluation's errors can be
//! marked. Axes are in metres with the same metres per pixel on x and y, and every panel shows
//! the same region: the one given, else that of the marked switches and fragmentations (when
//! asked), else that of the tracks and ground truth (detections far away do not zoom the scene
//! out).
//!
//! Pure drawing: frames in, PNG bytes and the layout ([`super::plot_layout`]) out. Text is drawn
//! with a TTF embedded in the binary (Hack, from the `epaint_default_fonts` crate), so no system
//! font is needed ([`super::text`]).

use std::sync::OnceLock;

use anyhow::{bail, Context, Result};
use plotters::prelude::*;
use plotters::style::{register_font, FontStyle};

use super::legend;
use super::plot_layout::{PictureLayout, PxRect, ViewRule};
use super::plot_panel::draw_panel;
pub use super::plot_scene::bev_drawable;
use super::plot_scene::Sizes;
use super::plot_types::{draw_err, rgb, FONT};
pub use super::plot_types::{
    equal_aspect, EventMark, Extent, Panel, BACKGROUND, DETECTION_GREY, UNMATCHED,
};
use super::text::{check_font, GlyphBackend};
use crate::eval::event_view::frame_points;
use crate::msgs::eval_event::Kind;

/// Size and title of the picture.
#[derive(Debug, Clone)]
pub struct PlotOptions {
    /// Width of the whole picture, pixels.
    pub width: u32,
    /// Height of the whole picture, pixels.
    pub height: u32,
    /// Title above all panels, if any.
    pub title: Option<String>,
    /// Region shown; default: see [`frame_events`](Self::frame_events), else [`world_extent`].
    pub extent: Option<Extent>,
    /// Evaluation events to mark.
    pub marks: Vec<EventMark>,
    /// Without `extent`: show the region of the identity switches and fragmentations among
    /// `marks` ([`frame_points`], the region `eval --events` suggests), when there are any.
    /// `plot` sets it for a time window.
    pub frame_events: bool,
}

impl Default for PlotOptions {
    fn default() -> Self {
        PlotOptions {
            width: 1800,
            height: 700,
            title: None,
            extent: None,
            marks: Vec::new(),
            frame_events: false,
        }
    }
}

pub use crate::msgs::colors::{id_color, mix64, PALETTE};

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

/// World region `[x0, x1] x [y0, y1]` covering every box corner of the panels with ids (tracks,
/// ground truth), or of every panel when those have no box, with a margin; `None` when there is
/// no box.
pub fn world_extent(panels: &[Panel]) -> Option<Extent> {
    let boxes = |ids_only: bool| {
        panels
            .iter()
            .filter(move |p| !ids_only || p.layer.has_ids())
            .flat_map(|p| p.frames.iter().flat_map(|f| f.1.iter()))
    };
    let ids_only = boxes(true).next().is_some();
    let mut ext: Option<Extent> = None;
    for b in boxes(ids_only) {
        for (x, y) in b.bev_corners() {
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

/// The region to show and why: `--extent`, else the events (when asked), else the boxes.
fn choose_view(panels: &[Panel], opts: &PlotOptions) -> Option<(Extent, ViewRule)> {
    if let Some(e) = opts.extent {
        return Some((e, ViewRule::Extent));
    }
    let events = (opts.marks.iter())
        .filter(|m| matches!(m.kind, Kind::Switch | Kind::Fragmentation))
        .map(|m| (m.x, m.y));
    match opts.frame_events.then(|| frame_points(events)).flatten() {
        Some(e) => Some((e, ViewRule::Events)),
        None => world_extent(panels).map(|e| (e, ViewRule::Boxes)),
    }
}

/// Renders the panels side by side into an RGB buffer of `width * height * 3` bytes, with a
/// legend under them; returns the buffer and where everything went.
pub fn render(panels: &[Panel], opts: &PlotOptions) -> Result<(Vec<u8>, PictureLayout)> {
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
    let Some((ext, view_rule)) = choose_view(panels, opts) else {
        bail!("nothing to plot: no box in any panel");
    };
    register_fonts()?;
    check_font()?;
    let (w, h) = (opts.width, opts.height);
    let mut buf = vec![0u8; w as usize * h as usize * 3];
    let layout = {
        let backend = GlyphBackend(BitMapBackend::with_buffer(&mut buf, (w, h)));
        let canvas = backend.into_drawing_area();
        canvas.fill(&rgb(BACKGROUND)).map_err(draw_err)?;
        // Text sizes follow the picture's height (700 px: 1x).
        let k = (f64::from(h) / 700.0).clamp(0.7, 2.5);
        let sz = Sizes::new(k);
        let body = match &opts.title {
            Some(t) => canvas
                .titled(t, (FONT, (20.0 * k).round()).into_font().color(&BLACK))
                .map_err(draw_err)?,
            None => canvas.clone(),
        };
        let entries = legend::entries(panels, &opts.marks);
        let body_h = body.dim_in_pixel().1;
        let strip = legend::height(&entries, w, k).min(body_h / 3);
        let (panels_area, legend_area) = body.split_vertically(body_h - strip);
        let mut layouts = Vec::with_capacity(panels.len());
        for (area, panel) in panels_area
            .split_evenly((1, panels.len()))
            .iter()
            .zip(panels)
        {
            layouts.push(draw_panel(&canvas, area, panel, ext, sz, &opts.marks)?);
        }
        let (xr, yr) = legend_area.get_pixel_range();
        let strip_rect = PxRect {
            x0: f64::from(xr.start),
            x1: f64::from(xr.end),
            y0: f64::from(yr.start),
            y1: f64::from(yr.end),
        };
        let legend = legend::layout(&entries, strip_rect, k);
        legend::draw(&canvas, &legend, k)?;
        canvas.present().map_err(draw_err)?;
        PictureLayout {
            width: w,
            height: h,
            view_rule,
            panels: layouts,
            legend,
        }
    };
    Ok((buf, layout))
}

/// Renders the panels side by side into an RGB buffer of `width * height * 3` bytes.
pub fn render_rgb(panels: &[Panel], opts: &PlotOptions) -> Result<Vec<u8>> {
    render(panels, opts).map(|r| r.0)
}

/// Renders the panels side by side and encodes them as a PNG.
pub fn render_png(panels: &[Panel], opts: &PlotOptions) -> Result<Vec<u8>> {
    render_png_with_layout(panels, opts).map(|r| r.0)
}

/// Renders the panels side by side and encodes them as a PNG; also returns the layout.
pub fn render_png_with_layout(
    panels: &[Panel],
    opts: &PlotOptions,
) -> Result<(Vec<u8>, PictureLayout)> {
    let (rgb, layout) = render(panels, opts)?;
    Ok((encode_png(&rgb, opts.width, opts.height)?, layout))
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mcapio::LabelledBox;
    use crate::viz::{Frame, Layer};

    fn bx(id: u64, x: f64, y: f64, yaw: f64) -> LabelledBox {
        LabelledBox {
            id,
            label: "car".into(),
            center: [x, y, 0.8],
            size: [4.5, 1.9, 1.6],
            yaw,
            score: 0.9,
            ..Default::default()
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
            truth_of: None,
        };
        let (x0, x1, y0, y1) = world_extent(std::slice::from_ref(&p)).unwrap();
        for b in &p.frames[0].1 {
            for (x, y) in b.bev_corners() {
                assert!(x > x0 && x < x1 && y > y0 && y < y1);
            }
        }
        let empty = Panel {
            frames: vec![(0, vec![])],
            ..p.clone()
        };
        assert!(world_extent(&[empty]).is_none());
        // A far detection does not widen the region of the tracks.
        let far = Panel {
            title: "d".into(),
            layer: Layer::Detections,
            frames: vec![(0, vec![bx(0, 900.0, -400.0, 0.0)])],
            truth_of: None,
        };
        let with_far = world_extent(&[far.clone(), p.clone()]).unwrap();
        assert_eq!(with_far, (x0, x1, y0, y1));
        // Detections alone still give a region.
        assert!(world_extent(&[far]).unwrap().1 > 900.0);
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
                truth_of: None,
            },
            Panel {
                title: "tracks".into(),
                layer: Layer::Tracks,
                frames,
                truth_of: None,
            },
        ];
        let opts = PlotOptions {
            width: 640,
            height: 300,
            title: Some("test".into()),
            ..PlotOptions::default()
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
            truth_of: None,
        }];
        assert!(render_rgb(&empty, &opts).is_err());
    }
}
