//! Text drawn into sRGB pixels: the viewer's status line, in the shipped DejaVu Sans (so the
//! strip looks the same on every machine and needs no system font). Glyphs are rasterized by
//! `ab_glyph` and blended by their coverage.
//!
//! The font's bytes are public ([`FONT`]) so that the study's plots use the same face.

use ab_glyph::{point, Font, FontRef, PxScale, ScaleFont};
use base::error::{Error, Result};
use std::sync::OnceLock;

/// DejaVu Sans (its licence is beside it in `assets/fonts/`).
pub static FONT: &[u8] = include_bytes!("../assets/fonts/DejaVuSans.ttf");

/// The colour of the strip behind the text.
const STRIP: [u8; 3] = [20, 20, 20];

/// Glyph height in pixels.
const SIZE: f32 = 14.0;

/// The shipped font, parsed once (the viewer draws a status line every frame).
fn font() -> Result<&'static FontRef<'static>> {
    static FONT_REF: OnceLock<Option<FontRef<'static>>> = OnceLock::new();
    FONT_REF
        .get_or_init(|| FontRef::try_from_slice(FONT).ok())
        .as_ref()
        .ok_or_else(|| Error::internal("the shipped font does not load"))
}

/// Writes `text` in white on a dark strip across the top `strip` rows of an sRGB image (`rgb`,
/// 3 bytes per pixel, `w` x `h`). Text past the right edge is cut; rows below the strip are not
/// touched.
pub fn overlay_text(rgb: &mut [u8], w: u32, h: u32, strip: u32, text: &str) -> Result<()> {
    let font = font()?;
    let strip = strip.min(h);
    let (w, strip_rows) = (w as usize, strip as usize);
    if rgb.len() < 3 * w * h as usize {
        return Err(Error::internal(
            "overlay text: the image is smaller than its size",
        ));
    }
    for px in rgb[..3 * w * strip_rows].chunks_exact_mut(3) {
        px.copy_from_slice(&STRIP);
    }
    let scaled = font.as_scaled(PxScale::from(SIZE));
    let baseline = 4.0 + scaled.ascent();
    let mut x = 6.0f32;
    let mut previous = None;
    for c in text.chars() {
        let id = scaled.glyph_id(c);
        if let Some(p) = previous {
            x += scaled.kern(p, id);
        }
        let glyph = id.with_scale_and_position(SIZE, point(x, baseline));
        x += scaled.h_advance(id);
        previous = Some(id);
        let Some(outline) = font.outline_glyph(glyph) else {
            continue;
        };
        let bounds = outline.px_bounds();
        outline.draw(|gx, gy, coverage| {
            let px = bounds.min.x as i64 + gx as i64;
            let py = bounds.min.y as i64 + gy as i64;
            if px < 0 || py < 0 || px as usize >= w || py as usize >= strip_rows {
                return;
            }
            let at = 3 * (py as usize * w + px as usize);
            let a = coverage.clamp(0.0, 1.0);
            for (k, channel) in rgb[at..at + 3].iter_mut().enumerate() {
                let blended = STRIP[k] as f32 * (1.0 - a) + 255.0 * a;
                *channel = (*channel).max(blended.round() as u8);
            }
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The text lands in the strip only: rows below it keep their bytes, and the strip holds
    /// both its own colour and brighter glyph pixels.
    #[test]
    fn text_stays_in_its_strip() {
        let (w, h, strip) = (120u32, 40u32, 22u32);
        let mut rgb = vec![7u8; (3 * w * h) as usize];
        overlay_text(&mut rgb, w, h, strip, "direct 60 fps").unwrap();
        let split = (3 * w * strip) as usize;
        assert!(rgb[split..].iter().all(|&b| b == 7));
        assert!(rgb[..split].chunks_exact(3).any(|p| p == STRIP));
        assert!(rgb[..split].iter().any(|&b| b > 200), "no glyph was drawn");
    }
}
