//! Pixel-by-pixel comparison against a golden image: which pixels differ by more than a
//! tolerance, by how much, and a difference image to look at. This is the regression check of
//! the project's golden-image tests and of `pixelflow-sim compare --tolerance`, which a user's CI
//! can run on its own scenes.
//!
//! Unlike the perceptual distance (a single number that forgives a change too small to see), it
//! is meant to break on **one** changed pixel: a pixel differs when any channel moves by more
//! than `tolerance * max(|reference|, floor)`. The floor keeps black pixels from demanding an
//! exact zero; the default tolerance is a few `f32` rounding steps, so a rebuild with the same
//! compiler on the same CPU kind passes and any change of the algorithm fails. The share of
//! differing pixels is reported as a percentage too, so a caller can tolerate a fraction of the
//! image that does not depend on its size.
//!
//! Invariants: the two images have the same size (else an error); NaN in either image is a
//! difference (never equal); the difference image is finite.

use glam::Vec3;
use serde::Serialize;

use base::error::{Error, Result};
use base::image::LinearImage;

/// Default relative tolerance per channel: 16 `f32` rounding steps (2^-19, about 1.9e-6).
pub const DEFAULT_TOLERANCE: f32 = 1.0 / (1 << 19) as f32;

/// Default floor, in the images' units, under which the tolerance is absolute:
/// `tolerance * floor` is the smallest difference that counts.
pub const DEFAULT_FLOOR: f32 = 1e-3;

/// One pixel that differs.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct DifferentPixel {
    /// Column.
    pub x: u32,
    /// Row (0 on top).
    pub y: u32,
    /// The image under test.
    pub got: [f32; 3],
    /// The reference.
    pub want: [f32; 3],
}

/// The result of [`diff`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PixelDiff {
    /// Pixels compared.
    pub pixels: u64,
    /// Pixels that differ by more than the tolerance.
    pub differing: u64,
    /// `differing` as a percentage of `pixels` (0 to 100): comparable between image sizes.
    pub differing_percent: f64,
    /// The first differing pixels in row order (at most `PixelDiff::LISTED`).
    pub first: Vec<DifferentPixel>,
    /// Largest absolute channel difference over all pixels.
    pub max_abs: f32,
    /// Largest channel difference relative to `max(|reference|, floor)`.
    pub max_rel: f32,
    /// Per pixel `|got - want|` (a NaN or infinite difference shown as `f32::MAX`: never
    /// non-finite), for a difference image.
    #[serde(skip)]
    pub image: LinearImage,
}

impl PixelDiff {
    /// How many differing pixels [`PixelDiff::first`] lists.
    pub(crate) const LISTED: usize = 10;

    /// `3 of 4096 pixels (0.0732 %) differ (largest absolute difference ..., relative ...)`
    /// and the listed pixels, or `all 4096 pixels within the tolerance (...)`.
    pub fn summary(&self) -> String {
        if self.differing == 0 {
            return format!(
                "all {} pixels within the tolerance (largest relative difference {:.3e})",
                self.pixels, self.max_rel
            );
        }
        let mut s = format!(
            "{} of {} pixels ({:.4} %) differ (largest absolute difference {:.4e}, relative {:.4e})",
            self.differing, self.pixels, self.differing_percent, self.max_abs, self.max_rel
        );
        for p in &self.first {
            s += &format!(
                "\n  ({}, {}): got [{:.6e}, {:.6e}, {:.6e}], want [{:.6e}, {:.6e}, {:.6e}]",
                p.x, p.y, p.got[0], p.got[1], p.got[2], p.want[0], p.want[1], p.want[2]
            );
        }
        if self.differing as usize > self.first.len() {
            s += &format!(
                "\n  ... and {} more",
                self.differing as usize - self.first.len()
            );
        }
        s
    }

    /// The difference image scaled so its largest channel is 1 (all black when identical),
    /// for writing as a PNG.
    pub fn normalized_image(&self) -> LinearImage {
        let m = self
            .image
            .pixels
            .iter()
            .map(|p| p.max_element())
            .fold(0.0f32, f32::max);
        let k = if m > 0.0 { 1.0 / m } else { 0.0 };
        LinearImage {
            width: self.image.width,
            height: self.image.height,
            pixels: self.image.pixels.iter().map(|p| *p * k).collect(),
        }
    }
}

/// Compares `got` against the reference `want` pixel by pixel (module docs): a channel differs
/// when `|got - want| > tolerance * max(|want|, floor)` or either is NaN.
pub fn diff(
    got: &LinearImage,
    want: &LinearImage,
    tolerance: f32,
    floor: f32,
) -> Result<PixelDiff> {
    if (got.width, got.height) != (want.width, want.height) {
        return Err(Error::invalid_option(
            "images",
            "",
            format!(
                "sizes differ: {} x {} against the reference's {} x {}",
                got.width, got.height, want.width, want.height
            ),
        ));
    }
    if !(tolerance.is_finite() && tolerance >= 0.0 && floor.is_finite() && floor >= 0.0) {
        return Err(Error::invalid_option(
            "tolerance",
            format!("{tolerance}"),
            "must be a finite number >= 0",
        ));
    }
    let mut out = PixelDiff {
        pixels: got.pixels.len() as u64,
        differing: 0,
        differing_percent: 0.0,
        first: Vec::new(),
        max_abs: 0.0,
        max_rel: 0.0,
        image: LinearImage {
            width: got.width,
            height: got.height,
            pixels: Vec::with_capacity(got.pixels.len()),
        },
    };
    for (i, (g, w)) in got.pixels.iter().zip(&want.pixels).enumerate() {
        let mut differs = false;
        let mut d = [0.0f32; 3];
        for c in 0..3 {
            let (a, b) = (g[c], w[c]);
            let abs = (a - b).abs();
            let abs = if abs.is_finite() { abs } else { f32::MAX };
            let rel = abs / b.abs().max(floor).max(f32::MIN_POSITIVE);
            let rel = if rel.is_finite() { rel } else { f32::MAX };
            differs |= abs > tolerance * b.abs().max(floor) || a.is_nan() || b.is_nan();
            out.max_abs = out.max_abs.max(abs);
            out.max_rel = out.max_rel.max(rel);
            d[c] = abs;
        }
        out.image.pixels.push(Vec3::from(d));
        if differs {
            out.differing += 1;
            if out.first.len() < PixelDiff::LISTED {
                out.first.push(DifferentPixel {
                    x: (i % got.width as usize) as u32,
                    y: (i / got.width as usize) as u32,
                    got: g.to_array(),
                    want: w.to_array(),
                });
            }
        }
    }
    // `pixels` is at least 1 for a valid image; an empty one differs nowhere.
    out.differing_percent = 100.0 * out.differing as f64 / out.pixels.max(1) as f64;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn img(pixels: Vec<Vec3>) -> LinearImage {
        LinearImage::new(2, 2, pixels).unwrap()
    }

    #[test]
    fn one_changed_pixel_is_found_and_listed() {
        let want = img(vec![
            Vec3::splat(0.5),
            Vec3::ZERO,
            Vec3::ONE,
            Vec3::splat(2.0),
        ]);
        let same = diff(&want, &want, DEFAULT_TOLERANCE, DEFAULT_FLOOR).unwrap();
        assert_eq!(same.differing, 0);
        assert_eq!(same.max_abs, 0.0);
        assert!(same.summary().starts_with("all 4 pixels within"));
        // One channel of one pixel moved by 1e-4 of its value: far above 16 f32 steps.
        let mut got = want.clone();
        got.pixels[3].y *= 1.0 + 1e-4;
        let d = diff(&got, &want, DEFAULT_TOLERANCE, DEFAULT_FLOOR).unwrap();
        assert_eq!(d.differing, 1);
        // One of 4 pixels: exactly 25 %.
        assert_eq!(d.differing_percent, 25.0);
        assert!(d.summary().contains("(25.0000 %)"), "{}", d.summary());
        assert_eq!((d.first[0].x, d.first[0].y), (1, 1));
        assert!((d.max_rel - 1e-4).abs() < 1e-6, "{}", d.max_rel);
        assert_eq!(d.normalized_image().pixels[3], Vec3::new(0.0, 1.0, 0.0));
        assert!(d.summary().contains("(1, 1): got"), "{}", d.summary());
        // A change of one f32 step is within the default tolerance.
        let mut got = want.clone();
        got.pixels[0].x = f32::from_bits(got.pixels[0].x.to_bits() + 1);
        assert_eq!(
            diff(&got, &want, DEFAULT_TOLERANCE, DEFAULT_FLOOR)
                .unwrap()
                .differing,
            0
        );
    }

    #[test]
    fn black_pixels_use_the_floor_and_nan_always_differs() {
        let want = img(vec![Vec3::ZERO; 4]);
        let mut got = want.clone();
        got.pixels[0].x = 0.5 * DEFAULT_TOLERANCE * DEFAULT_FLOOR;
        got.pixels[1].z = 2.0 * DEFAULT_TOLERANCE * DEFAULT_FLOOR;
        got.pixels[2].y = f32::NAN;
        let d = diff(&got, &want, DEFAULT_TOLERANCE, DEFAULT_FLOOR).unwrap();
        assert_eq!(d.differing, 2);
        assert_eq!(
            d.first.iter().map(|p| (p.x, p.y)).collect::<Vec<_>>(),
            [(1, 0), (0, 1)]
        );
        assert!(d.image.pixels.iter().all(|p| p.is_finite()));
        let other = LinearImage::new(1, 4, vec![Vec3::ZERO; 4]).unwrap();
        assert!(diff(&other, &want, DEFAULT_TOLERANCE, DEFAULT_FLOOR).is_err());
    }
}
