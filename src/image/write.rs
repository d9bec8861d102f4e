//! Image output: a frame's linear radiosity into files, always written
//! atomically through [`crate::output::write_atomic`].
//!
//! - PNG (8-bit sRGB): each channel is multiplied by 2^exposure (stops), clamped to [0, 1] (the
//!   documented clamp: over-exposed values saturate, negative values from ringing of the bicubic
//!   reconstruction become black, NaN becomes 0), encoded with the sRGB transfer function
//!   (12.92 x below 0.0031308, 1.055 x^(1/2.4) - 0.055 above) and rounded to the nearest of the
//!   256 levels (halves away from zero).
//! - EXR (32-bit float, linear RGB): the radiosity of the visible point itself (W/m^2 per channel,
//!   no division by pi, no exposure), the input of image comparisons.

use std::io::Cursor;
use std::path::Path;

use ::image::{ImageBuffer, ImageFormat, Rgb};
use glam::Vec3;

use crate::error::{Error, Result};
use crate::image::ImageView;
use crate::output::write_atomic;

/// sRGB transfer function of a linear value in [0, 1].
pub fn srgb_encode(x: f32) -> f32 {
    if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

/// The 8-bit sRGB value of a linear channel after exposure `exposure` (stops).
pub fn to_srgb8(linear: f32, exposure: f32) -> u8 {
    let scaled = linear * exposure.exp2();
    // max/min rather than clamp: they map a NaN to 0 instead of propagating it.
    #[allow(clippy::manual_clamp)]
    let x = scaled.max(0.0).min(1.0);
    (srgb_encode(x) * 255.0).round() as u8
}

fn check(frame: ImageView<'_>) -> Result<()> {
    if frame.pixels.len() != (frame.width as usize) * (frame.height as usize) || frame.width == 0 {
        return Err(Error::Runtime(format!(
            "image of {} x {} holds {} pixels",
            frame.width,
            frame.height,
            frame.pixels.len()
        )));
    }
    Ok(())
}

/// Encodes an image as PNG bytes with the given exposure (stops).
pub fn encode_png(frame: ImageView<'_>, exposure: f64) -> Result<Vec<u8>> {
    check(frame)?;
    let e = if exposure.is_finite() {
        exposure as f32
    } else {
        0.0
    };
    let mut raw = Vec::with_capacity(frame.pixels.len() * 3);
    for p in frame.pixels {
        raw.extend(p.to_array().iter().map(|&c| to_srgb8(c, e)));
    }
    let img: ImageBuffer<Rgb<u8>, Vec<u8>> = ImageBuffer::from_raw(frame.width, frame.height, raw)
        .ok_or_else(|| Error::Runtime("PNG buffer size mismatch".into()))?;
    let mut bytes = Vec::new();
    img.write_to(&mut Cursor::new(&mut bytes), ImageFormat::Png)
        .map_err(|e| Error::Runtime(format!("PNG encoding failed: {e}")))?;
    Ok(bytes)
}

/// Encodes an image as a linear float RGB OpenEXR file's bytes. Non-finite values (none are
/// produced by the renderer) would be written as 0.
pub fn encode_exr(frame: ImageView<'_>) -> Result<Vec<u8>> {
    check(frame)?;
    let mut raw = Vec::with_capacity(frame.pixels.len() * 3);
    for p in frame.pixels {
        let p = Vec3::select(p.is_finite_mask(), *p, Vec3::ZERO);
        raw.extend_from_slice(&p.to_array());
    }
    let img: ImageBuffer<Rgb<f32>, Vec<f32>> =
        ImageBuffer::from_raw(frame.width, frame.height, raw)
            .ok_or_else(|| Error::Runtime("EXR buffer size mismatch".into()))?;
    let mut bytes = Vec::new();
    img.write_to(&mut Cursor::new(&mut bytes), ImageFormat::OpenExr)
        .map_err(|e| Error::Runtime(format!("EXR encoding failed: {e}")))?;
    Ok(bytes)
}

/// Writes an image as an sRGB PNG (exposure in stops), atomically.
pub fn write_png(path: &Path, frame: ImageView<'_>, exposure: f64) -> Result<()> {
    write_atomic(path, &encode_png(frame, exposure)?)
}

/// Writes an image as a linear float EXR, atomically.
pub fn write_exr(path: &Path, frame: ImageView<'_>) -> Result<()> {
    write_atomic(path, &encode_exr(frame)?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image::LinearImage;

    fn frame() -> LinearImage {
        LinearImage {
            width: 3,
            height: 2,
            pixels: vec![
                Vec3::new(0.0, 0.5, 1.0),
                Vec3::new(0.25, 2.0, -1.0),
                Vec3::new(0.002, 0.18, 0.9),
                Vec3::splat(0.125),
                Vec3::new(f32::NAN, 0.0, 0.0),
                Vec3::ONE,
            ],
        }
    }

    #[test]
    fn srgb_levels_and_exposure() {
        assert_eq!(to_srgb8(0.0, 0.0), 0);
        assert_eq!(to_srgb8(1.0, 0.0), 255);
        assert_eq!(to_srgb8(5.0, 0.0), 255);
        assert_eq!(to_srgb8(-1.0, 0.0), 0);
        assert_eq!(to_srgb8(f32::NAN, 0.0), 0);
        // 0.5 linear -> 0.7354 sRGB -> 187.5... rounds to 188; one stop up saturates.
        assert_eq!(to_srgb8(0.5, 0.0), 188);
        assert_eq!(to_srgb8(0.5, 1.0), 255);
        assert_eq!(to_srgb8(0.25, 1.0), 188);
        // Linear segment: 0.002 * 12.92 * 255 = 6.59 -> 7.
        assert_eq!(to_srgb8(0.002, 0.0), 7);
    }

    #[test]
    fn png_and_exr_round_trip() {
        let f = frame();
        let png = ::image::load_from_memory(&encode_png(f.view(), 0.0).unwrap())
            .unwrap()
            .to_rgb8();
        assert_eq!(png.dimensions(), (3, 2));
        assert_eq!(png.get_pixel(0, 0).0, [0, 188, 255]);
        assert_eq!(png.get_pixel(1, 1).0, [0, 0, 0]);
        let exr = ::image::load_from_memory(&encode_exr(f.view()).unwrap())
            .unwrap()
            .to_rgb32f();
        assert_eq!(exr.get_pixel(1, 0).0, [0.25, 2.0, -1.0]);
        assert_eq!(exr.get_pixel(2, 0).0, [0.002, 0.18, 0.9]);
        assert_eq!(exr.get_pixel(1, 1).0, [0.0, 0.0, 0.0]);
    }
}
