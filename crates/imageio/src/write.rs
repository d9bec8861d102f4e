//! Image output: a frame's linear radiosity into files, always written
//! atomically through [`base::output::Outputs::write_atomic`].
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

use crate::ImageView;
use base::error::{Error, Result};
use base::output::Outputs;

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
    level(x)
}

/// The 8-bit level of a value already clamped to [0, 1]: the definition [`to_srgb8`] applies.
fn level(x: f32) -> u8 {
    (srgb_encode(x) * 255.0).round() as u8
}

/// `T[k - 1]`, k = 1..=255: the smallest `f32` in [0, 1] whose [`level`] is at least k, found by
/// bisection over the bit patterns (non-negative floats order like their bits). [`level`] is
/// monotone on [0, 1], so the level of `x` is the number of thresholds `<= x`: a binary search of
/// 255 floats instead of a `powf` per channel, with the same result bit for bit (tested at and
/// around every threshold).
fn srgb8_thresholds() -> &'static [f32; 255] {
    static T: std::sync::OnceLock<[f32; 255]> = std::sync::OnceLock::new();
    T.get_or_init(|| {
        let mut t = [0.0f32; 255];
        for (i, slot) in t.iter_mut().enumerate() {
            let k = (i + 1) as u8;
            let (mut lo, mut hi) = (0u32, 1.0f32.to_bits());
            while lo < hi {
                let mid = lo + (hi - lo) / 2;
                if level(f32::from_bits(mid)) >= k {
                    hi = mid;
                } else {
                    lo = mid + 1;
                }
            }
            *slot = f32::from_bits(lo);
        }
        t
    })
}

/// [`level`] by the threshold table, for `x` in [0, 1].
#[inline]
fn level_by_table(t: &[f32; 255], x: f32) -> u8 {
    t.partition_point(|&v| v <= x) as u8
}

/// Bits of an `f32` below a bucket of [`Buckets`]: a bucket is 2^16 consecutive floats.
const BUCKET_SHIFT: u32 = 16;

/// [`level`] in one lookup and one comparison: the floats of [0, 1] in buckets of 2^16
/// consecutive bit patterns, each with the level of its first float and the one threshold of
/// [`srgb8_thresholds`] inside it (+inf when none; NaN when more than one, where the binary
/// search decides). The thresholds are at least 3e-4 apart and a bucket spans at most 0.004 of
/// [0, 1] (below 1.0; less near 0), so every bucket holds at most one; the tests check the
/// result against [`level`] around every threshold.
struct Buckets {
    level: Vec<u8>,
    threshold: Vec<f32>,
}

fn buckets() -> &'static Buckets {
    static B: std::sync::OnceLock<Buckets> = std::sync::OnceLock::new();
    B.get_or_init(|| {
        let t = srgb8_thresholds();
        let n = (1.0f32.to_bits() >> BUCKET_SHIFT) as usize + 1;
        let mut b = Buckets {
            level: Vec::with_capacity(n),
            threshold: Vec::with_capacity(n),
        };
        for i in 0..n as u32 {
            let lo = f32::from_bits(i << BUCKET_SHIFT);
            let hi = f32::from_bits(((i + 1) << BUCKET_SHIFT) - 1);
            let first = level_by_table(t, lo);
            let inside = t.iter().filter(|&&v| v > lo && v <= hi).count();
            b.level.push(first);
            b.threshold.push(match inside {
                0 => f32::INFINITY,
                1 => t[first as usize],
                _ => f32::NAN,
            });
        }
        b
    })
}

/// [`level`] by [`Buckets`], for `x` in [0, 1] (not NaN).
#[inline(always)]
fn level_by_bucket(b: &Buckets, t: &[f32; 255], x: f32) -> u8 {
    let i = (x.to_bits() >> BUCKET_SHIFT) as usize;
    let th = b.threshold[i];
    if th.is_nan() {
        return level_by_table(t, x);
    }
    b.level[i] + (x >= th) as u8
}

/// The 8-bit sRGB bytes of a frame (RGB, row-major) after exposure `exposure` (stops), exactly
/// [`to_srgb8`] per channel, computed by `Buckets` and in parallel over rows (the bytes do not
/// depend on the split).
pub fn srgb8_bytes(frame: ImageView<'_>, exposure: f32) -> Vec<u8> {
    use rayon::prelude::*;
    let t = srgb8_thresholds();
    let b = buckets();
    let k = exposure.exp2();
    let mut raw = vec![0u8; frame.pixels.len() * 3];
    let w = (frame.width as usize).max(1);
    raw.par_chunks_mut(w * 3)
        .zip(frame.pixels.par_chunks(w))
        .for_each(|(out, row)| {
            for (o, p) in out.chunks_exact_mut(3).zip(row) {
                for c in 0..3 {
                    // The same operations as `to_srgb8`: scale, then max/min (NaN to 0).
                    #[allow(clippy::manual_clamp)]
                    let x = (p[c] * k).max(0.0).min(1.0);
                    o[c] = level_by_bucket(b, t, x);
                }
            }
        });
    raw
}

fn check(frame: ImageView<'_>) -> Result<()> {
    if frame.pixels.len() != (frame.width as usize) * (frame.height as usize) || frame.width == 0 {
        return Err(Error::internal(format!(
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
    srgb_png_bytes(frame.width, frame.height, srgb8_bytes(frame, e))
}

/// PNG bytes of sRGB bytes (3 per pixel, `w` x `h`, already encoded): a plot's or a window's
/// pixels, which are drawn in sRGB.
pub fn srgb_png_bytes(w: u32, h: u32, rgb: Vec<u8>) -> Result<Vec<u8>> {
    let img: ImageBuffer<Rgb<u8>, Vec<u8>> = ImageBuffer::from_raw(w, h, rgb)
        .ok_or_else(|| Error::internal("PNG buffer size mismatch"))?;
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
            .ok_or_else(|| Error::internal("EXR buffer size mismatch"))?;
    let mut bytes = Vec::new();
    img.write_to(&mut Cursor::new(&mut bytes), ImageFormat::OpenExr)
        .map_err(|e| Error::Runtime(format!("EXR encoding failed: {e}")))?;
    Ok(bytes)
}

/// Encodes an image as a Radiance HDR (RGBE) file's bytes: linear, 8-bit mantissas with a
/// shared exponent (about 1 % precision).
pub fn encode_hdr(frame: ImageView<'_>) -> Result<Vec<u8>> {
    check(frame)?;
    let pixels: Vec<Rgb<f32>> = frame
        .pixels
        .iter()
        .map(|p| Rgb(Vec3::select(p.is_finite_mask(), p.max(Vec3::ZERO), Vec3::ZERO).to_array()))
        .collect();
    let mut bytes = Vec::new();
    image::codecs::hdr::HdrEncoder::new(&mut bytes)
        .encode(&pixels, frame.width as usize, frame.height as usize)
        .map_err(|e| Error::Runtime(format!("HDR encoding failed: {e}")))?;
    Ok(bytes)
}

/// Encodes an image as a colour PFM file's bytes: `PF`, the size, scale -1 (little-endian), then
/// the rows bottom to top as three `f32` per pixel.
pub fn encode_pfm(frame: ImageView<'_>) -> Result<Vec<u8>> {
    check(frame)?;
    let (w, h) = (frame.width as usize, frame.height as usize);
    let mut bytes = format!("PF\n{w} {h}\n-1.0\n").into_bytes();
    bytes.reserve(w * h * 12);
    for row in (0..h).rev() {
        for p in &frame.pixels[row * w..(row + 1) * w] {
            let p = Vec3::select(p.is_finite_mask(), *p, Vec3::ZERO);
            for c in p.to_array() {
                bytes.extend_from_slice(&c.to_le_bytes());
            }
        }
    }
    Ok(bytes)
}

/// The image formats an image output can be written as, chosen by the file's extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OutputFormat {
    /// `.png`: 8-bit sRGB after the exposure.
    Png,
    /// `.exr`: OpenEXR, linear float.
    Exr,
    /// `.hdr`: Radiance RGBE, linear.
    Hdr,
    /// `.pfm`: portable float map, linear float.
    Pfm,
}

impl OutputFormat {
    /// Every format with its extension.
    pub const ALL: [(OutputFormat, &'static str); 4] = [
        (OutputFormat::Png, "png"),
        (OutputFormat::Exr, "exr"),
        (OutputFormat::Hdr, "hdr"),
        (OutputFormat::Pfm, "pfm"),
    ];

    /// The format of `path` by its extension (any case), if it names one.
    pub fn of(path: &Path) -> Option<OutputFormat> {
        let ext = path.extension()?.to_str()?;
        Self::ALL
            .iter()
            .find(|(_, e)| ext.eq_ignore_ascii_case(e))
            .map(|(f, _)| *f)
    }

    /// The file's bytes: the PNG with `exposure` stops, the others linear.
    pub fn encode(self, frame: ImageView<'_>, exposure: f64) -> Result<Vec<u8>> {
        match self {
            OutputFormat::Png => encode_png(frame, exposure),
            OutputFormat::Exr => encode_exr(frame),
            OutputFormat::Hdr => encode_hdr(frame),
            OutputFormat::Pfm => encode_pfm(frame),
        }
    }
}

/// Writes sRGB bytes (3 per pixel, `w` x `h`, already encoded) as a PNG, atomically through
/// `outputs`.
pub fn write_srgb_png(outputs: &Outputs, path: &Path, w: u32, h: u32, rgb: Vec<u8>) -> Result<()> {
    outputs.write_atomic(path, &srgb_png_bytes(w, h, rgb)?)
}

/// Writes an image as an sRGB PNG (exposure in stops), atomically through `outputs`.
pub fn write_png(
    outputs: &Outputs,
    path: &Path,
    frame: ImageView<'_>,
    exposure: f64,
) -> Result<()> {
    outputs.write_atomic(path, &encode_png(frame, exposure)?)
}

/// Writes an image as a linear float EXR, atomically through `outputs`.
pub fn write_exr(outputs: &Outputs, path: &Path, frame: ImageView<'_>) -> Result<()> {
    outputs.write_atomic(path, &encode_exr(frame)?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::LinearImage;

    /// The table and the buckets give `level` exactly: at and within 4096 ulps around every
    /// threshold (where a difference would show), at 2^20 evenly spaced values of [0, 1], at
    /// the first and last float of every bucket, and for the clamped inputs (negative, NaN,
    /// above 1, infinite) through `srgb8_bytes` against `to_srgb8`. No bucket holds two
    /// thresholds (the binary-search fallback is never needed on [0, 1]).
    #[test]
    fn srgb8_by_table_is_bit_exact() {
        let t = srgb8_thresholds();
        let b = buckets();
        assert!(t.windows(2).all(|w| w[0] < w[1]), "thresholds increase");
        assert!(
            b.threshold.iter().all(|v| !v.is_nan()),
            "a bucket holds two thresholds"
        );
        let check = |x: f32| {
            assert_eq!(level_by_table(t, x), level(x), "x = {x:e}");
            assert_eq!(level_by_bucket(b, t, x), level(x), "bucket, x = {x:e}");
        };
        for &th in t.iter() {
            let bits = th.to_bits();
            for d in 0..=8192u32 {
                check(f32::from_bits(
                    (bits + d).saturating_sub(4096).min(1.0f32.to_bits()),
                ));
            }
        }
        let n = 1u32 << 20;
        for i in 0..=n {
            check(i as f32 / n as f32);
        }
        for i in 0..b.level.len() as u32 {
            check(f32::from_bits(i << BUCKET_SHIFT));
            check(f32::from_bits(((i + 1) << BUCKET_SHIFT) - 1).min(1.0));
        }
        let odd = [
            -1.0,
            -0.0,
            0.0,
            f32::NAN,
            1.5,
            f32::INFINITY,
            f32::NEG_INFINITY,
            1e-40,
        ];
        let pixels: Vec<Vec3> = odd.iter().map(|&x| Vec3::new(x, x * 0.5, 0.7)).collect();
        let frame = ImageView {
            width: 4,
            height: 2,
            pixels: &pixels,
        };
        for e in [0.0f32, 1.5, -3.0] {
            let want: Vec<u8> = pixels
                .iter()
                .flat_map(|p| p.to_array().map(|c| to_srgb8(c, e)))
                .collect();
            assert_eq!(srgb8_bytes(frame, e), want, "exposure {e}");
        }
    }

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
