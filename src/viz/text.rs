//! Text of the plots, laid out and rasterised here with `ab_glyph` from the embedded font (Hack,
//! from `epaint_default_fonts`), and a drawing backend that draws every text of a picture this
//! way ([`GlyphBackend`], plotters' axes and titles included).
//!
//! Why not plotters' own text: its `ab_glyph` font code (plotters 0.3.7,
//! `style/font/ab_glyph.rs`) draws each glyph's pixels from the pen position without the glyph's
//! left side bearing (the offset of its outline within its advance), so a narrow glyph sits at
//! the left of its cell and leaves a gap after it: "pedes trian", "x ( m)". Here each glyph is
//! placed at its pen position and rasterised at its own pixel bounds, and a text's box is its
//! advance width by the font's ascent-to-descent height, the box [`text_size`] reports and the
//! labels are placed with.

use std::sync::OnceLock;

use ab_glyph::{point, Font, FontRef, PxScale, ScaleFont};
use anyhow::{bail, Result};
use plotters::prelude::DrawingBackend;
use plotters_backend::text_anchor::{HPos, VPos};
use plotters_backend::{
    BackendColor, BackendCoord, BackendStyle, BackendTextStyle, DrawingErrorKind,
};

/// The embedded font, parsed once.
fn font() -> Option<&'static FontRef<'static>> {
    static FONT: OnceLock<Option<FontRef<'static>>> = OnceLock::new();
    FONT.get_or_init(|| FontRef::try_from_slice(epaint_default_fonts::HACK_REGULAR).ok())
        .as_ref()
}

/// Checks that the embedded font loads (so drawing cannot fail on it later).
pub fn check_font() -> Result<()> {
    match font() {
        Some(_) => Ok(()),
        None => bail!("the embedded font could not be loaded"),
    }
}

/// Width and height (pixels) of `text` drawn `size` pixels high (the font's ascent to descent;
/// the size plotters' font descriptions give).
pub fn text_size(text: &str, size: f64) -> (f64, f64) {
    let Some(f) = font() else {
        return (0.0, size);
    };
    let sf = f.as_scaled(PxScale::from(size as f32));
    let mut width = 0f32;
    let mut prev = None;
    for c in text.chars() {
        let id = sf.glyph_id(c);
        if let Some(p) = prev {
            width += sf.kern(p, id);
        }
        width += sf.h_advance(id);
        prev = Some(id);
    }
    (f64::from(width), size)
}

/// Calls `put(x, y, coverage)` for every pixel of `text` drawn `size` pixels high, `(x, y)`
/// from the top-left corner of its box.
pub fn rasterise(text: &str, size: f64, mut put: impl FnMut(i32, i32, f32)) {
    let Some(f) = font() else {
        return;
    };
    let scale = PxScale::from(size as f32);
    let sf = f.as_scaled(scale);
    let ascent = sf.ascent();
    let mut caret = 0f32;
    let mut prev = None;
    for c in text.chars() {
        let id = sf.glyph_id(c);
        if let Some(p) = prev {
            caret += sf.kern(p, id);
        }
        prev = Some(id);
        let glyph = id.with_scale_and_position(scale, point(caret, ascent));
        caret += sf.h_advance(id);
        if let Some(outline) = f.outline_glyph(glyph) {
            let b = outline.px_bounds();
            let (x0, y0) = (b.min.x as i32, b.min.y as i32);
            outline.draw(|x, y, cov| put(x0 + x as i32, y0 + y as i32, cov));
        }
    }
}

/// A drawing backend that draws text with [`rasterise`] and measures it with [`text_size`],
/// passing everything else to the backend it wraps.
pub struct GlyphBackend<B>(pub B);

impl<B: DrawingBackend> DrawingBackend for GlyphBackend<B> {
    type ErrorType = B::ErrorType;

    fn get_size(&self) -> (u32, u32) {
        self.0.get_size()
    }
    fn ensure_prepared(&mut self) -> Result<(), DrawingErrorKind<B::ErrorType>> {
        self.0.ensure_prepared()
    }
    fn present(&mut self) -> Result<(), DrawingErrorKind<B::ErrorType>> {
        self.0.present()
    }
    fn draw_pixel(
        &mut self,
        point: BackendCoord,
        color: BackendColor,
    ) -> Result<(), DrawingErrorKind<B::ErrorType>> {
        self.0.draw_pixel(point, color)
    }
    fn draw_line<S: BackendStyle>(
        &mut self,
        from: BackendCoord,
        to: BackendCoord,
        style: &S,
    ) -> Result<(), DrawingErrorKind<B::ErrorType>> {
        self.0.draw_line(from, to, style)
    }
    fn draw_rect<S: BackendStyle>(
        &mut self,
        upper_left: BackendCoord,
        bottom_right: BackendCoord,
        style: &S,
        fill: bool,
    ) -> Result<(), DrawingErrorKind<B::ErrorType>> {
        self.0.draw_rect(upper_left, bottom_right, style, fill)
    }
    fn draw_path<S: BackendStyle, I: IntoIterator<Item = BackendCoord>>(
        &mut self,
        path: I,
        style: &S,
    ) -> Result<(), DrawingErrorKind<B::ErrorType>> {
        self.0.draw_path(path, style)
    }
    fn draw_circle<S: BackendStyle>(
        &mut self,
        center: BackendCoord,
        radius: u32,
        style: &S,
        fill: bool,
    ) -> Result<(), DrawingErrorKind<B::ErrorType>> {
        self.0.draw_circle(center, radius, style, fill)
    }
    fn fill_polygon<S: BackendStyle, I: IntoIterator<Item = BackendCoord>>(
        &mut self,
        vert: I,
        style: &S,
    ) -> Result<(), DrawingErrorKind<B::ErrorType>> {
        self.0.fill_polygon(vert, style)
    }
    fn blit_bitmap(
        &mut self,
        pos: BackendCoord,
        size: (u32, u32),
        src: &[u8],
    ) -> Result<(), DrawingErrorKind<B::ErrorType>> {
        self.0.blit_bitmap(pos, size, src)
    }

    fn estimate_text_size<S: BackendTextStyle>(
        &self,
        text: &str,
        style: &S,
    ) -> Result<(u32, u32), DrawingErrorKind<B::ErrorType>> {
        let (w, h) = text_size(text, style.size());
        Ok((w.ceil() as u32, h.ceil() as u32))
    }

    fn draw_text<S: BackendTextStyle>(
        &mut self,
        text: &str,
        style: &S,
        pos: BackendCoord,
    ) -> Result<(), DrawingErrorKind<B::ErrorType>> {
        let color = style.color();
        if color.alpha == 0.0 {
            return Ok(());
        }
        let (w, h) = text_size(text, style.size());
        let (w, h) = (w.round() as i32, h.round() as i32);
        let anchor = style.anchor();
        let dx = match anchor.h_pos {
            HPos::Left => 0,
            HPos::Center => -w / 2,
            HPos::Right => -w,
        };
        let dy = match anchor.v_pos {
            VPos::Top => 0,
            VPos::Center => -h / 2,
            VPos::Bottom => -h,
        };
        let transform = style.transform();
        let mut result = Ok(());
        rasterise(text, style.size(), |x, y, cov| {
            if result.is_err() || cov <= 0.0 {
                return;
            }
            let (x, y) = transform.transform(x + dx, y + dy);
            let c = BackendColor {
                alpha: color.alpha * f64::from(cov.min(1.0)),
                rgb: color.rgb,
            };
            result = self.0.draw_pixel((pos.0 + x, pos.1 + y), c);
        });
        result
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Columns of the box of `text` that hold ink: as drawn here, or (`bearings` false) as
    /// plotters 0.3.7 drew them, each glyph's ink from its pen position.
    fn inked_columns(text: &str, size: f64, bearings: bool) -> Vec<bool> {
        let (w, _) = text_size(text, size);
        let mut ink = vec![0f32; w.ceil() as usize + 8];
        let last = ink.len() as i32 - 1;
        let mut mark = |x: i32, cov: f32| ink[x.clamp(0, last) as usize] += cov;
        if bearings {
            rasterise(text, size, |x, _, cov| mark(x, cov));
            return ink.iter().map(|c| *c > 0.5).collect();
        }
        let f = font().unwrap();
        let scale = PxScale::from(size as f32);
        let sf = f.as_scaled(scale);
        let mut caret = 0f32;
        for c in text.chars() {
            let id = sf.glyph_id(c);
            if let Some(o) = f.outline_glyph(id.with_scale(scale)) {
                o.draw(|x, _, cov| mark(caret as i32 + x as i32, cov));
            }
            caret += sf.h_advance(id);
        }
        ink.iter().map(|c| *c > 0.5).collect()
    }

    /// Longest run of empty columns between the first and the last inked one.
    fn widest_gap(cols: &[bool]) -> usize {
        let first = cols.iter().position(|c| *c).unwrap();
        let last = cols.iter().rposition(|c| *c).unwrap();
        let mut widest = 0;
        let mut run = 0;
        for c in &cols[first..=last] {
            run = if *c { 0 } else { run + 1 };
            widest = widest.max(run);
        }
        widest
    }

    #[test]
    fn words_have_no_gap_inside() {
        check_font().unwrap();
        // plotters drew "pedestrian" as "pedes trian": a glyph with a wide side bearing
        // ('t', 'i') was drawn at the left of its cell and left a gap after it.
        // plotters drew "pedestrian" as "pedes trian": a glyph with a wide side bearing was
        // drawn at the left of its cell, so 'e', 's' and 't' ran together and a gap followed.
        // Placed with their bearings, the ten glyphs of Hack at 13 px stand apart, one run of
        // inked columns each, and no gap inside the word is wider than 3 px.
        let runs = |cols: &[bool]| cols.windows(2).filter(|w| !w[0] && w[1]).count();
        let old = inked_columns(" pedestrian", 13.0, false);
        let new = inked_columns(" pedestrian", 13.0, true);
        assert_eq!(runs(&new), 10);
        assert!(runs(&old) < 10);
        assert!(widest_gap(&new) <= 3);
        // A narrow glyph is centred in its cell (Hack is monospaced), so punctuation keeps at
        // most half a cell on each side; a space leaves a whole cell.
        for word in ["tracked.mcap", "(m)", "4->7"] {
            let gap = widest_gap(&inked_columns(word, 13.0, true));
            assert!(gap <= 4, "{word}: a gap of {gap} px");
        }
        assert!(widest_gap(&inked_columns("a b", 13.0, true)) >= 5);
        // The box is the sum of the advances.
        let (w1, h) = text_size("x", 13.0);
        let (w10, _) = text_size("pedestrian", 13.0);
        assert!((w10 - 10.0 * w1).abs() < 1e-3 && h == 13.0, "{w1} {w10}");
    }

    #[test]
    fn ink_stays_in_the_box() {
        let (w, h) = text_size("Ág(y)|", 20.0);
        rasterise("Ág(y)|", 20.0, |x, y, cov| {
            if cov > 0.05 {
                assert!(x >= -1 && f64::from(x) <= w + 1.0, "x {x} of {w}");
                assert!(y >= -1 && f64::from(y) <= h + 1.0, "y {y} of {h}");
            }
        });
    }
}
