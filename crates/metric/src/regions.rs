//! Where an image's error lies: every pixel in one of three regions, and the squared luminance
//! error split by them, so that a study can say which part of the picture a method's error (or
//! the solution's) comes from rather than one number for the whole image.
//!
//! - [`Region::Emitters`]: the pixels that show an emitter, the brightest of the image (kept
//!   apart so that their luminance does not hide the error around them in a relative figure).
//! - [`Region::EmitterBand`]: within [`BAND_RADIUS`] pixels (Chebyshev distance) of an
//!   emitter's pixels, not showing one: where a texture or a mesh can carry an emitter's light
//!   into its neighbours.
//! - [`Region::Edges`]: outside the band, near the reference's sharp edges
//!   ([`crate::edges::near_edges`]: light and shadow edges, silhouettes), where the light jumps
//!   and a smooth reconstruction cannot follow.
//! - [`Region::Interior`]: the rest, smooth light, where a method's own interpolation error and
//!   the solution's sampling error lie.
//!
//! The regions come from the reference alone (its luminances and which of its pixels show an
//! emitter), so every image measured against one reference is split on the same pixels. The
//! squared errors of the regions add up to the whole image's, so the shares sum to 1 and
//! `rmse^2` of the image is the pixel-weighted mean of the regions' `rmse^2`. A noisy reference
//! (a path tracer's) is handled by [`split_without_noise`]: each region's mean squared error
//! less the mean noise variance of its pixels, which is unbiased for noise independent of the
//! measured image (as [`crate::edges`] does with two estimates).

use serde::Serialize;

use crate::edges::{dilate, near_edges};

/// Pixels within this Chebyshev distance of an emitter's pixel are in its band.
pub const BAND_RADIUS: usize = 3;

/// Regions, the length of every per-region array.
pub const REGIONS: usize = 4;

/// The region of a pixel (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum Region {
    /// Showing an emitter.
    Emitters,
    /// Near an emitter's pixels, not showing one.
    EmitterBand,
    /// Near a sharp edge of the reference, outside the band.
    Edges,
    /// Everything else.
    Interior,
}

impl Region {
    /// The regions in the order of every per-region array.
    pub const ALL: [Region; REGIONS] = [
        Region::Emitters,
        Region::EmitterBand,
        Region::Edges,
        Region::Interior,
    ];

    /// A short name for tables.
    pub fn name(self) -> &'static str {
        match self {
            Region::Emitters => "emitters",
            Region::EmitterBand => "emitter band",
            Region::Edges => "edges",
            Region::Interior => "interior",
        }
    }

    /// Its index in [`Region::ALL`].
    fn index(self) -> usize {
        self as usize
    }
}

/// The region of every pixel of one reference (row-major).
#[derive(Debug, Clone, PartialEq)]
pub struct Regions {
    of: Vec<Region>,
}

impl Regions {
    /// The regions of a `w` x `h` reference with luminances `yb` whose pixels `emitter` show an
    /// emitter. Panics if the lengths are not `w h`.
    pub fn classify(emitter: &[bool], yb: &[f64], w: usize, h: usize) -> Regions {
        assert!(
            emitter.len() == w * h && yb.len() == w * h,
            "{w} x {h} pixels"
        );
        let band = dilate(emitter, w, h, BAND_RADIUS);
        let edges = near_edges(yb, w, h);
        let of = (0..w * h)
            .map(|i| match (emitter[i], band[i], edges[i]) {
                (true, _, _) => Region::Emitters,
                (false, true, _) => Region::EmitterBand,
                (false, false, true) => Region::Edges,
                (false, false, false) => Region::Interior,
            })
            .collect();
        Regions { of }
    }

    /// The region of pixel `i`.
    pub fn at(&self, i: usize) -> Region {
        self.of[i]
    }

    /// Pixels per region, in the order of [`Region::ALL`].
    pub fn pixels(&self) -> [usize; REGIONS] {
        let mut n = [0; REGIONS];
        for r in &self.of {
            n[r.index()] += 1;
        }
        n
    }

    /// The sum of `value(i)` over each region's pixels, in pixel order (deterministic).
    fn sums(&self, value: impl Fn(usize) -> f64) -> [f64; REGIONS] {
        let mut s = [0.0; REGIONS];
        for (i, r) in self.of.iter().enumerate() {
            s[r.index()] += value(i);
        }
        s
    }
}

/// One region's share of an image's error.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RegionError {
    /// Pixels in the region.
    pub pixels: usize,
    /// The region's share of the image's squared luminance error, in [0, 1] (0 where the image
    /// has none).
    pub share: f64,
    /// RMSE of luminance over the region's pixels (0 for an empty region).
    pub rmse: f64,
    /// The reference's mean luminance over the region's pixels (0 for an empty region): `rmse`
    /// over it is the region's relative RMSE.
    pub reference_mean: f64,
    /// The RMSE as measured, the reference's noise included (equal to `rmse` without noise).
    pub measured_rmse: f64,
    /// The reference's noise over the region: the root of its pixels' mean noise variance (0
    /// without noise). Where it is not below `rmse`, the correction does not resolve the
    /// region's error: only `measured_rmse` bounds it.
    pub noise_rmse: f64,
}

impl RegionError {
    /// `rmse` over the reference's mean luminance in the region (0 where that mean is 0).
    pub fn relative_rmse(&self) -> f64 {
        self.relative(self.rmse)
    }

    /// `measured_rmse` over the reference's mean luminance in the region.
    pub fn relative_measured_rmse(&self) -> f64 {
        self.relative(self.measured_rmse)
    }

    /// Whether the noise-free error is resolved: the reference's noise below it (always
    /// without noise).
    pub fn resolved(&self) -> bool {
        self.noise_rmse == 0.0 || self.noise_rmse < self.rmse
    }

    fn relative(&self, x: f64) -> f64 {
        if self.reference_mean > 0.0 {
            x / self.reference_mean
        } else {
            0.0
        }
    }
}

/// The error of luminances `ya` against the reference's `yb`, split by `regions` (in the order
/// of [`Region::ALL`]).
pub fn split(ya: &[f64], yb: &[f64], regions: &Regions) -> [RegionError; REGIONS] {
    split_without_noise(ya, yb, None, regions)
}

/// [`split`] against a noisy reference whose per-pixel noise variance (of luminance) is
/// `noise_var`: each region's mean squared error less its pixels' mean noise variance, clamped
/// at 0 (a chance low reading), and the shares of those corrected squared errors. With `None`,
/// no correction. Panics if the lengths differ.
pub fn split_without_noise(
    ya: &[f64],
    yb: &[f64],
    noise_var: Option<&[f64]>,
    regions: &Regions,
) -> [RegionError; REGIONS] {
    assert!(ya.len() == regions.of.len() && yb.len() == regions.of.len());
    let sq = regions.sums(|i| (ya[i] - yb[i]) * (ya[i] - yb[i]));
    let noise = match noise_var {
        Some(v) => {
            assert_eq!(v.len(), regions.of.len());
            regions.sums(|i| v[i])
        }
        None => [0.0; REGIONS],
    };
    let n = regions.pixels();
    let lum = regions.sums(|i| yb[i]);
    let corrected: [f64; REGIONS] = std::array::from_fn(|r| (sq[r] - noise[r]).max(0.0));
    let total: f64 = corrected.iter().sum();
    let per_pixel = |x: f64, r: usize| {
        if n[r] > 0 {
            (x / n[r] as f64).sqrt()
        } else {
            0.0
        }
    };
    std::array::from_fn(|r| RegionError {
        measured_rmse: per_pixel(sq[r], r),
        noise_rmse: per_pixel(noise[r], r),
        pixels: n[r],
        share: if total > 0.0 {
            corrected[r] / total
        } else {
            0.0
        },
        rmse: if n[r] > 0 {
            (corrected[r] / n[r] as f64).sqrt()
        } else {
            0.0
        },
        reference_mean: if n[r] > 0 { lum[r] / n[r] as f64 } else { 0.0 },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 20 x 10 reference: 0.5 everywhere, an emitter of 10 at pixels (2..4, 2..4) and a step
    /// to 0.1 from column 14 on (a sharp edge between columns 13 and 14).
    fn reference() -> (Vec<bool>, Vec<f64>, usize, usize) {
        let (w, h) = (20, 10);
        let emitter: Vec<bool> = (0..w * h)
            .map(|i| (2..4).contains(&(i % w)) && (2..4).contains(&(i / w)))
            .collect();
        let yb = (0..w * h)
            .map(|i| match (emitter[i], i % w) {
                (true, _) => 10.0,
                (false, x) if x >= 14 => 0.1,
                _ => 0.5,
            })
            .collect();
        (emitter, yb, w, h)
    }

    #[test]
    fn every_pixel_is_in_the_region_its_distances_give() {
        let (emitter, yb, w, h) = reference();
        let r = Regions::classify(&emitter, &yb, w, h);
        for i in 0..w * h {
            let (x, y) = ((i % w) as i64, (i / w) as i64);
            // Chebyshev distance to the emitter square [2, 3] x [2, 3], and column distance to
            // the step's two sides (columns 13 and 14) within the edge radius of 2.
            let d = |v: i64| (2 - v).max(v - 3).max(0);
            let band = d(x).max(d(y)) <= BAND_RADIUS as i64;
            let edge = (11..=16).contains(&x);
            let want = if d(x).max(d(y)) == 0 {
                Region::Emitters
            } else if band {
                Region::EmitterBand
            } else if edge {
                Region::Edges
            } else {
                Region::Interior
            };
            assert_eq!(r.at(i), want, "pixel ({x}, {y})");
        }
        // The band: the 2 x 2 emitter grown by 3 on every side, cut by the image's top (rows
        // 0..=6, columns 0..=6): 7 x 7 less the emitter's 4; the edge strip: columns 11..=16,
        // 10 rows.
        assert_eq!(r.pixels(), [4, 45, 60, 200 - 49 - 60]);
    }

    #[test]
    fn shares_and_rmse_add_up_to_the_whole_image() {
        let (emitter, yb, w, h) = reference();
        let r = Regions::classify(&emitter, &yb, w, h);
        // Errors of 0.4 on the emitter, 0.3 in the band, 0.2 near the step, 0.1 elsewhere.
        let err = [0.4, 0.3, 0.2, 0.1];
        let ya: Vec<f64> = (0..w * h).map(|i| yb[i] + err[r.at(i).index()]).collect();
        let s = split(&ya, &yb, &r);
        let n = r.pixels();
        let sq: Vec<f64> = (0..REGIONS)
            .map(|k| n[k] as f64 * err[k] * err[k])
            .collect();
        let total: f64 = sq.iter().sum();
        for k in 0..REGIONS {
            assert_eq!(s[k].pixels, n[k]);
            assert!((s[k].rmse - err[k]).abs() < 1e-12, "{k}: {:?}", s[k]);
            assert!(
                (s[k].share - sq[k] / total).abs() < 1e-12,
                "{k}: {:?}",
                s[k]
            );
        }
        // The emitter's pixels are 10 and the band's 0.5; the edge strip has 3 columns of 0.5
        // and 3 of 0.1; the interior 61 pixels of 0.5 (columns 0-6 below the band, columns
        // 7-10) and the 30 of columns 17-19 at 0.1.
        let interior = (61.0 * 0.5 + 30.0 * 0.1) / 91.0;
        let means = [10.0, 0.5, (30.0 * 0.5 + 30.0 * 0.1) / 60.0, interior];
        for k in 0..REGIONS {
            assert!(
                (s[k].reference_mean - means[k]).abs() < 1e-12,
                "{k}: {:?}",
                s[k]
            );
            assert!((s[k].relative_rmse() - err[k] / means[k]).abs() < 1e-12);
        }
        assert!((s.iter().map(|e| e.share).sum::<f64>() - 1.0).abs() < 1e-12);
        // The same image: no error, shares 0, not NaN.
        let z = split(&yb, &yb, &r);
        assert!(z.iter().all(|e| e.share == 0.0 && e.rmse == 0.0));
    }

    #[test]
    fn the_noise_correction_takes_out_a_known_variance() {
        let (emitter, yb, w, h) = reference();
        let r = Regions::classify(&emitter, &yb, w, h);
        // Measured squared error 0.25 per pixel, of which 0.09 is the reference's noise
        // variance: 0.16 is left, rmse 0.4; where the variance exceeds the error, 0.
        let ya: Vec<f64> = yb.iter().map(|y| y + 0.5).collect();
        let var: Vec<f64> = (0..w * h)
            .map(|i| {
                if r.at(i) == Region::Interior {
                    0.09
                } else {
                    0.3
                }
            })
            .collect();
        let s = split_without_noise(&ya, &yb, Some(&var), &r);
        assert!((s[3].rmse - 0.4).abs() < 1e-12, "{:?}", s[3]);
        assert!((s[3].measured_rmse - 0.5).abs() < 1e-12 && (s[3].noise_rmse - 0.3).abs() < 1e-12);
        assert!(
            s[3].resolved() && !s[0].resolved() && !s[2].resolved(),
            "{s:?}"
        );
        assert_eq!((s[0].rmse, s[1].rmse, s[2].rmse), (0.0, 0.0, 0.0));
        assert_eq!(s.map(|e| e.share), [0.0, 0.0, 0.0, 1.0]);
    }
}
