//! Image metrics: how far a rendered image is from a reference, the numbers behind the paper's
//! Fig. 5 / Fig. 6 comparisons and `pixelflow-sim compare`.
//!
//! This is the last stage of an experiment: it sees only two [`LinearImage`]s (linear RGB, as
//! written to EXR by `base::image::write` or read by `base::image::read`), never the scene. Every
//! number is computed on the luminance `Y = 0.2126 R + 0.7152 G + 0.0722 B` (Rec. 709 weights), in
//! `f64`, in a fixed loop order, so the same two images give the same bytes on every run and for
//! any thread count (nothing here is parallel).
//!
//! - [`perceptual`]: the project's perceptual distance (`docs/metrics.md`, after Rushmeier et al.
//!   1995, model 1, with the Mannos–Sakrison contrast sensitivity function). Its module doc quotes
//!   the definition and says where each step is in the code.
//! - [`mach`]: the Mach-band measure, the energy of the second differences of the
//!   mean-normalised luminance difference. Derivative discontinuities at element and texel
//!   boundaries (what C0 reconstructions leave and the paper's C1 bicubic ones remove) show up as
//!   spikes of the second difference, which this sums.
//! - [`edges`]: the share of the error within 2 px of the reference's sharp edges (where the
//!   light jumps), and the RMSE on each side.
//! - [`regions`]: the error split by where it lies: the emitters, a band around them, near
//!   sharp edges, the interior.
//! - [`pixels`]: the pixel-by-pixel check against a golden image (which pixels moved, a
//!   difference image), for regression tests.
//! - Here: the plain error measures and [`compare`], which computes all of them, with the
//!   perceptual distance also per pixel (divided by `sqrt(W H)`), for thresholds that must hold
//!   at any image size.
//!
//! In [`compare`]`(a, b, ppd)` the second image `b` is the **reference**: the peak of the PSNR and
//! the denominator of the relative luminance error are taken from it. The perceptual distance and
//! the Mach-band measure are symmetric and invariant to scaling either image by a positive
//! constant (each image is normalised by its own mean luminance); RMSE, PSNR, maximum absolute
//! error and relative luminance error are in the images' own units and are not. `docs/metrics.md`
//! gives every formula.
//!
//! Inputs are validated, not repaired: a NaN or infinite pixel, images of different sizes, an empty
//! image and an image whose mean luminance is not positive (all black: the normalisation would
//! divide by 0) are errors. No output is NaN or infinite; the one number that would be infinite,
//! the PSNR of identical images, is `None` (JSON `null`).

#![forbid(unsafe_code)]

pub mod edges;
pub mod mach;
pub mod perceptual;
pub mod pixels;
pub mod regions;

use std::fmt::Write as _;

use serde::Serialize;

use base::error::{Error, Result};
use base::image::mean;
pub use base::image::{luminance, LinearImage, LUMINANCE_WEIGHTS};

pub use perceptual::{csf, perceptual_distance, DEFAULT_PPD};

/// Every measure of one image against a reference, as printed by `pixelflow-sim compare`.
///
/// All measures are on luminance `Y`. `a` is the image under test, `b` the reference.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Comparison {
    /// Width of both images in pixels.
    pub width: u32,
    /// Height of both images in pixels.
    pub height: u32,
    /// Pixels per degree of visual angle used by the perceptual distance.
    pub ppd: f64,
    /// The perceptual distance of `docs/metrics.md` (dimensionless; 0 for equal images): an L2
    /// norm over the pixels, which grows like `sqrt(width * height)` for the same per-pixel
    /// difference.
    pub perceptual_distance: f64,
    /// `perceptual_distance / sqrt(width * height)`: the root-mean-square per pixel of the
    /// CSF-filtered lightness difference. The same picture at another resolution, seen over the
    /// same visual angle (`ppd` proportional to the width), gives the same value: the measure for
    /// thresholds that must not depend on the image size.
    pub perceptual_distance_per_pixel: f64,
    /// Root-mean-square luminance difference, `sqrt(mean((Y_a - Y_b)^2))`, in the images' units.
    pub rmse: f64,
    /// Peak signal-to-noise ratio in dB, `20 log10(psnr_peak / rmse)`; `None` (JSON `null`) when
    /// the images are equal (`rmse == 0`), where it would be infinite.
    pub psnr_db: Option<f64>,
    /// The peak of the PSNR: the reference's (`b`'s) maximum luminance.
    pub psnr_peak: f64,
    /// Largest absolute luminance difference of one pixel, `max |Y_a - Y_b|`.
    pub max_abs_error: f64,
    /// Relative luminance error, `mean |Y_a - Y_b| / mean Y_b` (dimensionless).
    pub relative_luminance_error: f64,
    /// The Mach-band measure (see [`mach`]): mean squared second difference of the
    /// mean-normalised luminance difference (dimensionless; 0 for equal images).
    pub mach_band: f64,
    /// The error split at the reference's sharp edges ([`edges`]).
    pub edges: edges::EdgeSplit,
    /// Mean luminance of `a`.
    pub mean_luminance_a: f64,
    /// Mean luminance of `b`.
    pub mean_luminance_b: f64,
}

impl Comparison {
    /// A small aligned table of the numbers, one per line, for the terminal.
    pub fn table(&self) -> String {
        let mut s = String::new();
        let psnr = match self.psnr_db {
            Some(p) => format!("{p:.4} dB (peak {:.6})", self.psnr_peak),
            None => format!("inf (equal images; peak {:.6})", self.psnr_peak),
        };
        let e = &self.edges;
        let rows: [(&str, String); 10] = [
            ("size", format!("{} x {}", self.width, self.height)),
            (
                "perceptual distance",
                format!("{:.6} (ppd {})", self.perceptual_distance, self.ppd),
            ),
            (
                "  per pixel",
                format!("{:.6e}", self.perceptual_distance_per_pixel),
            ),
            ("rmse", format!("{:.6e}", self.rmse)),
            ("psnr", psnr),
            ("max abs error", format!("{:.6e}", self.max_abs_error)),
            (
                "relative luminance error",
                format!("{:.6e}", self.relative_luminance_error),
            ),
            ("mach-band energy", format!("{:.6e}", self.mach_band)),
            (
                "near sharp edges",
                format!(
                    "{:.1} % of squared error on {} px (rmse {:.6e} near, {:.6e} away)",
                    100.0 * e.near_share,
                    e.near_pixels,
                    e.rmse_near,
                    e.rmse_far
                ),
            ),
            (
                "mean luminance a / b",
                format!(
                    "{:.6} / {:.6}",
                    self.mean_luminance_a, self.mean_luminance_b
                ),
            ),
        ];
        for (k, v) in rows {
            let _ = writeln!(s, "{k:<26}{v}");
        }
        s
    }
}

/// Which of the two images an input problem is in, for messages.
fn which(i: usize) -> &'static str {
    if i == 0 {
        "a"
    } else {
        "b (reference)"
    }
}

/// Largest pixels-per-degree accepted: far beyond any display or eye (about 60 resolves the
/// fovea), and small enough that every frequency of the measure stays a finite number.
pub(crate) const MAX_PPD: f64 = 1e6;

/// Checks what every measure needs: a positive ppd (at most [`MAX_PPD`]), valid shapes, equal sizes, finite pixels and
/// a positive mean luminance in each image. Messages name the image as `a` or `b`.
fn validate(a: &LinearImage, b: &LinearImage, ppd: f64) -> Result<()> {
    if !(ppd.is_finite() && ppd > 0.0 && ppd <= MAX_PPD) {
        return Err(Error::invalid_option(
            "ppd",
            ppd.to_string(),
            format!("pixels per degree must be a number > 0 and at most {MAX_PPD}"),
        ));
    }
    for (i, img) in [a, b].into_iter().enumerate() {
        img.check_shape()
            .map_err(|e| Error::invalid_option(format!("image {}", which(i)), "", e.to_string()))?;
    }
    if (a.width, a.height) != (b.width, b.height) {
        return Err(Error::invalid_option(
            "images",
            "",
            format!(
                "sizes differ: a is {} x {}, b is {} x {}",
                a.width, a.height, b.width, b.height
            ),
        ));
    }
    for (i, img) in [a, b].into_iter().enumerate() {
        if let Some((x, y, p)) = img.first_non_finite() {
            return Err(Error::invalid_option(
                format!("image {}", which(i)),
                "",
                format!("pixel ({x}, {y}) is {p}, not finite"),
            ));
        }
        let m = img.mean_luminance();
        // The pixels are finite (checked), so the mean is finite: `<=` catches every bad case.
        if m <= 0.0 {
            return Err(Error::invalid_option(
                format!("image {}", which(i)),
                "",
                format!("mean luminance is {m} (all black?): the metric normalises by it and is undefined"),
            ));
        }
    }
    Ok(())
}

/// Compares `a` (the image under test) with `b` (the reference): every measure of
/// [`Comparison`], the perceptual distance at `ppd` pixels per degree.
///
/// Errors ([`Error::InvalidOption`]): `ppd` not finite and positive, an image with a size of 0 or a pixel
/// count that does not match, different sizes (the message names both), a NaN or infinite pixel,
/// a mean luminance that is not positive.
pub fn compare(a: &LinearImage, b: &LinearImage, ppd: f64) -> Result<Comparison> {
    validate(a, b, ppd)?;
    let (w, h) = (a.width as usize, a.height as usize);
    let ya = a.luminance();
    let yb = b.luminance();
    let n = ya.len() as f64;
    let mut sq = 0.0;
    let mut abs = 0.0;
    let mut max_abs = 0.0f64;
    for (p, q) in ya.iter().zip(&yb) {
        let d = p - q;
        sq += d * d;
        abs += d.abs();
        max_abs = max_abs.max(d.abs());
    }
    let rmse = (sq / n).sqrt();
    let mean_a = mean(&ya);
    let mean_b = mean(&yb);
    let peak = yb.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    // rmse > 0 and peak > 0 (the mean is positive), so the logarithm is finite.
    let psnr_db = (rmse > 0.0).then(|| 20.0 * (peak / rmse).log10());
    let perceptual_distance = perceptual::distance_of_luminances(&ya, &yb, w, h, ppd);
    Ok(Comparison {
        width: a.width,
        height: a.height,
        ppd,
        perceptual_distance,
        perceptual_distance_per_pixel: perceptual_distance / n.sqrt(),
        rmse,
        psnr_db,
        psnr_peak: peak,
        max_abs_error: max_abs,
        relative_luminance_error: abs / n / mean_b,
        mach_band: mach::mach_band_of_luminances(&ya, &yb, w, h),
        edges: edges::edge_split(&ya, &yb, w, h),
        mean_luminance_a: mean_a,
        mean_luminance_b: mean_b,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn img(w: u32, h: u32, f: impl Fn(u32, u32) -> f32) -> LinearImage {
        LinearImage::from_fn(w, h, |x, y| Vec3::splat(f(x, y)))
    }

    #[test]
    fn luminance_weights_sum_to_one() {
        // A grey pixel's luminance is its value: the weights sum to 1 exactly in decimal.
        assert!((luminance(Vec3::splat(0.5)) - 0.5).abs() < 1e-15);
        assert_eq!(luminance(Vec3::new(1.0, 0.0, 0.0)), 0.2126);
        assert_eq!(luminance(Vec3::new(0.0, 0.0, 1.0)), 0.0722);
    }

    #[test]
    fn plain_measures_on_a_two_pixel_case() {
        // b = [1, 3] (reference), a = [2, 3]: differences 1 and 0.
        let a = img(2, 1, |x, _| [2.0, 3.0][x as usize]);
        let b = img(2, 1, |x, _| [1.0, 3.0][x as usize]);
        let c = compare(&a, &b, 32.0).unwrap();
        // rmse = sqrt((1 + 0) / 2); all values are exact in binary up to the sqrt's rounding.
        assert!((c.rmse - 0.5f64.sqrt()).abs() < 1e-15);
        assert_eq!(c.max_abs_error, 1.0);
        assert_eq!(c.psnr_peak, 3.0);
        let psnr = 20.0 * (3.0 / 0.5f64.sqrt()).log10();
        assert!((c.psnr_db.unwrap() - psnr).abs() < 1e-12);
        // mean |d| = 0.5, mean Y_b = 2.
        assert!((c.relative_luminance_error - 0.25).abs() < 1e-15);
        assert_eq!(c.mean_luminance_a, 2.5);
        assert_eq!(c.mean_luminance_b, 2.0);
        // 2 x 1 has no second differences: the Mach-band measure is 0 by definition.
        assert_eq!(c.mach_band, 0.0);
    }

    #[test]
    fn equal_images_give_zeros_and_no_psnr() {
        let a = img(5, 4, |x, y| 0.1 + (x * 7 + y * 3) as f32 * 0.01);
        let c = compare(&a, &a, 32.0).unwrap();
        assert_eq!(c.perceptual_distance, 0.0);
        assert_eq!(c.perceptual_distance_per_pixel, 0.0);
        assert_eq!(c.rmse, 0.0);
        assert_eq!(c.max_abs_error, 0.0);
        assert_eq!(c.relative_luminance_error, 0.0);
        assert_eq!(c.mach_band, 0.0);
        assert_eq!(c.psnr_db, None);
        let json = serde_json::to_value(&c).unwrap();
        assert!(json["psnr_db"].is_null());
        assert!(c.table().contains("inf (equal images"));
    }

    /// The same periodic picture sampled at `side x side` pixel centres: a lit gradient of whole
    /// cycles, and the image under test with a ripple of 3 cycles over it.
    fn picture(side: u32, ripple: f32) -> LinearImage {
        use std::f32::consts::TAU;
        img(side, side, |x, y| {
            let (u, v) = (
                (x as f32 + 0.5) / side as f32,
                (y as f32 + 0.5) / side as f32,
            );
            (1.0 + 0.5 * (TAU * u).cos() * (TAU * v).sin()) * (1.0 + ripple * (3.0 * TAU * u).sin())
        })
    }

    #[test]
    fn the_per_pixel_distance_does_not_depend_on_the_image_size() {
        // Both sizes seen over the same 8 degrees (ppd = side / 8): every harmonic of the
        // picture falls on the same cycles per degree, so by Parseval D^2 / (W H) is the same
        // sum of |Fourier coefficient|^2 A(f)^2 at both sizes, up to the harmonics folded back
        // above the smaller image's Nyquist frequency and f32 rounding of the pixels (relative
        // 1e-7 each): agreement to 1e-5. D itself grows with the side: a ratio of 4.
        let at = |side: u32| {
            compare(&picture(side, 0.02), &picture(side, 0.0), side as f64 / 8.0).unwrap()
        };
        let (small, large) = (at(64), at(256));
        let rel =
            (small.perceptual_distance_per_pixel / large.perceptual_distance_per_pixel - 1.0).abs();
        assert!(rel < 1e-5, "{small:?} {large:?}");
        // The value itself: the ripple moves the lightness cbrt(Y') by about 0.02 / 3 sin(..)
        // (first order), an RMS of 0.02 / (3 sqrt 2), weighted by the CSF at its 3 cycles over
        // 8 degrees; the gradient's modulation changes that by a few percent at most.
        let want = 0.02 / (3.0 * 2f64.sqrt()) * csf(3.0 / 8.0);
        let got = small.perceptual_distance_per_pixel;
        assert!((got / want - 1.0).abs() < 0.05, "{got} against {want}");
        let ratio = large.perceptual_distance / small.perceptual_distance;
        assert!((ratio - 4.0).abs() < 4e-5, "{ratio}");
        assert_eq!(
            small.perceptual_distance_per_pixel,
            small.perceptual_distance / 64.0
        );
    }

    #[test]
    fn bad_inputs_are_usage_errors_naming_the_problem() {
        let a = img(4, 4, |_, _| 1.0);
        let b = img(4, 3, |_, _| 1.0);
        let e = compare(&a, &b, 32.0).unwrap_err().to_string();
        assert!(e.contains("a is 4 x 4") && e.contains("b is 4 x 3"), "{e}");
        let black = img(4, 4, |_, _| 0.0);
        let e = compare(&a, &black, 32.0).unwrap_err().to_string();
        assert!(
            e.contains("image b") && e.contains("mean luminance is 0"),
            "{e}"
        );
        let mut nan = a.clone();
        nan.pixels[6] = Vec3::new(0.0, f32::NAN, 0.0);
        let e = compare(&nan, &a, 32.0).unwrap_err().to_string();
        assert!(e.contains("image a") && e.contains("(2, 1)"), "{e}");
        // Regression: 1e300 used to give a NaN distance and exit 0.
        for ppd in [0.0, -1.0, f64::NAN, f64::INFINITY, 1e300, MAX_PPD * 2.0] {
            assert!(compare(&a, &a, ppd).is_err());
        }
        let short = LinearImage {
            width: 4,
            height: 4,
            pixels: vec![Vec3::ONE; 15],
        };
        assert!(compare(&short, &a, 32.0).is_err());
        assert!(LinearImage::new(0, 4, vec![]).is_err());
        assert!(LinearImage::new(2, 2, vec![Vec3::ONE; 4]).is_ok());
    }

    /// Images smaller than the measures' filters still give finite numbers for every measure
    /// (the serialised comparison holds no NaN or infinity). What broke: 1 x 1, 1 x 64, 64 x 1
    /// and 2 x 2 images gave non-finite measures.
    #[test]
    fn tiny_images_give_finite_measures() {
        for (w, h) in [(1, 1), (1, 64), (64, 1), (2, 2), (3, 1), (1, 3), (3, 3)] {
            let a = img(w, h, |x, y| 0.2 + 0.1 * ((x + 2 * y) % 3) as f32);
            let b = img(w, h, |x, y| 0.25 + 0.05 * ((x * 3 + y) % 2) as f32);
            let c = compare(&a, &b, 32.0).unwrap();
            let json = serde_json::to_string(&c).unwrap();
            assert!(
                !json.contains("null") || c.psnr_db.is_none(),
                "{w}x{h}: {json}"
            );
            let v: serde_json::Value = serde_json::from_str(&json).unwrap();
            fn finite(v: &serde_json::Value) -> bool {
                match v {
                    serde_json::Value::Number(n) => n.as_f64().is_some_and(f64::is_finite),
                    serde_json::Value::Object(m) => m.values().all(finite),
                    serde_json::Value::Array(a) => a.iter().all(finite),
                    _ => true,
                }
            }
            assert!(finite(&v), "{w}x{h}: {json}");
            for x in [
                c.perceptual_distance,
                c.rmse,
                c.mach_band,
                c.edges.near_share,
            ] {
                assert!(x.is_finite(), "{w}x{h}: {c:?}");
            }
            assert!(!c.table().contains("NaN"), "{w}x{h}: {}", c.table());
        }
    }
}
