//! Errors against physics: the path tracer's image ([`truth`]) as the reference of a sweep's
//! error budget. Every other error the sweep reports compares the solver with itself (the same
//! solution evaluated exactly, or a finer run of the same solver); this one does not.
//!
//! The truth image is traced as two independent halves (seeds 1 and 2, half the samples each,
//! at the frame's own sample positions) and averaged. The halves give the truth's own noise: for
//! an L2 measure `E`, `E(a, b)^2` has expectation twice the noise power of one half, so the
//! averaged image carries `N^2 = E(a, b)^2 / 4`. Because the noise is independent of any image
//! measured against it, `E(x, truth)^2 = E(x, physics)^2 + N^2` up to a zero-mean cross term, and
//! [`PhysicsErrors`] reports both the measured distance and the distance with the noise taken
//! out, `sqrt(max(E^2 - N^2, 0))`. This holds exactly for RMSE; for the perceptual distance (an
//! L2 norm of CSF-filtered lightness) it holds to first order in the noise, the cube root adding
//! a bias of about `-sigma^2 / 9` of the relative per-pixel noise `sigma` (6e-5 at 2 %).
//!
//! Invariants: the same scene, size, sample positions and samples give the same bits (the
//! tracer's seeds are fixed); the corrected distances are finite and never negative.

use serde::Serialize;

use app::context::Context;
use base::error::Result;
use engine::frame::FrameOptions;
use imageio::LinearImage;
use metric::compare;
use scene::Scene;
use truth::{PixelFilter, TruthOptions};

/// The seeds of the two halves.
pub const SEEDS: [u64; 2] = [1, 2];

/// One image measured against the truth.
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct PhysicsErrors {
    /// Perceptual distance with the truth's noise taken out.
    pub perceptual: f64,
    /// RMSE of luminance with the truth's noise taken out.
    pub rmse: f64,
    /// Perceptual distance as measured (truth noise included).
    pub perceptual_measured: f64,
    /// RMSE as measured (truth noise included).
    pub rmse_measured: f64,
    /// Whether the truth resolves the perceptual distance: its noise below the distance it
    /// corrects. Where it is not, the noise estimate's own error (about 3 % at the study's
    /// sizes) and the bias of skewed path-traced noise can move the corrected value anywhere
    /// from 0 to the measured one: the pages then give only the measured distance, as an upper
    /// bound ([`PhysicsErrors::perceptual_text`]), and call no difference on it.
    pub resolved: bool,
}

impl PhysicsErrors {
    /// The perceptual distance as the pages show it with `digits` decimals: the corrected value
    /// where the truth resolves it, else `<= measured` (the noise-free distance is no larger).
    pub fn perceptual_text(&self, digits: usize) -> String {
        if self.resolved {
            format!("{:.digits$}", self.perceptual)
        } else {
            format!("≤{:.digits$}", self.perceptual_measured)
        }
    }
}

/// The truth's own noise, in the measures [`PhysicsErrors`] corrects.
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct TruthNoise {
    /// Camera samples per pixel of the averaged image (both halves).
    pub samples_per_pixel: u32,
    /// Perceptual distance of the averaged image's noise (`E(a, b) / 2`).
    pub perceptual: f64,
    /// RMSE of the averaged image's noise.
    pub rmse: f64,
    /// The tracer's own per-pixel estimate: root-mean-square relative standard error of
    /// luminance of the averaged image.
    pub relative_error: f64,
    /// Seconds the two halves took.
    pub seconds: f64,
}

/// The averaged truth image and its noise.
#[derive(Debug, Clone)]
pub struct TruthReference {
    /// The mean of the two halves.
    pub image: LinearImage,
    /// Its noise.
    pub noise: TruthNoise,
}

/// `sqrt(max(measured^2 - noise^2, 0))`: a distance with independent noise taken out.
pub fn without_noise(measured: f64, noise: f64) -> f64 {
    (measured * measured - noise * noise).max(0.0).sqrt()
}

/// Traces `scene` at the frame's size and sample positions with `samples_per_pixel` samples
/// (split over the two halves, at least one each).
pub fn trace(
    job: &Context<'_>,
    scene: &Scene,
    opts: &FrameOptions,
    samples_per_pixel: u32,
    ppd: f64,
) -> Result<TruthReference> {
    let start = std::time::Instant::now();
    let half = samples_per_pixel.div_ceil(2).max(1);
    let mut halves = Vec::new();
    for seed in SEEDS {
        let o = TruthOptions {
            seed,
            width: opts.width,
            height: opts.height,
            samples_per_pixel: half,
            filter: PixelFilter::from_aa(Some(opts.aa)),
            ..TruthOptions::new(scene)
        };
        halves.push(truth::render(scene, &o, job.observer)?);
    }
    let (a, b) = (&halves[0], &halves[1]);
    let mut t = TruthReference::from_halves(&a.mean, &b.mean, ppd)?;
    t.noise.samples_per_pixel = 2 * half;
    // Two independent halves: the mean's relative error is the halves' over sqrt(2).
    t.noise.relative_error = 0.5 * (a.relative_error.powi(2) + b.relative_error.powi(2)).sqrt();
    t.noise.seconds = start.elapsed().as_secs_f64();
    Ok(t)
}

impl TruthReference {
    /// The mean of two independent estimates `a` and `b` of one image, with its noise from their
    /// difference (samples, relative error and seconds left 0 for the caller).
    pub fn from_halves(a: &LinearImage, b: &LinearImage, ppd: f64) -> Result<TruthReference> {
        let between = compare(a, b, ppd)?;
        let pixels = a
            .pixels
            .iter()
            .zip(&b.pixels)
            .map(|(p, q)| (*p + *q) * 0.5)
            .collect();
        Ok(TruthReference {
            image: LinearImage::new(a.width, a.height, pixels)?,
            noise: TruthNoise {
                samples_per_pixel: 0,
                perceptual: between.perceptual_distance / 2.0,
                rmse: between.rmse / 2.0,
                relative_error: 0.0,
                seconds: 0.0,
            },
        })
    }

    /// `img` measured against the truth, with and without its noise.
    pub fn errors(&self, img: &LinearImage, ppd: f64) -> Result<PhysicsErrors> {
        let c = compare(img, &self.image, ppd)?;
        let perceptual = without_noise(c.perceptual_distance, self.noise.perceptual);
        Ok(PhysicsErrors {
            perceptual,
            resolved: self.noise.perceptual < perceptual,
            rmse: without_noise(c.rmse, self.noise.rmse),
            perceptual_measured: c.perceptual_distance,
            rmse_measured: c.rmse,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn noise_comes_out_in_quadrature() {
        assert_eq!(without_noise(5.0, 3.0), 4.0);
        assert_eq!(without_noise(3.0, 3.0), 0.0);
        // Less than the noise (a chance low reading): zero, not NaN.
        assert_eq!(without_noise(2.0, 3.0), 0.0);
        assert_eq!(without_noise(0.7, 0.0), 0.7);
    }

    /// A smooth image: a horizontal ramp times a vertical one, luminance 0.2 to 1.
    fn clean(n: u32) -> LinearImage {
        let pixels = (0..n * n)
            .map(|i| {
                let (x, y) = ((i % n) as f32 / n as f32, (i / n) as f32 / n as f32);
                glam::Vec3::splat((0.2 + 0.8 * x) * (0.6 + 0.4 * y))
            })
            .collect();
        LinearImage::new(n, n, pixels).unwrap()
    }

    /// `img` brightened by `1 + gain(t)` at `t`, the column over the width (0 to 1).
    fn brightened(img: &LinearImage, gain: impl Fn(f32) -> f32) -> LinearImage {
        let w = img.width as usize;
        let pixels = img
            .pixels
            .iter()
            .enumerate()
            .map(|(i, p)| *p * (1.0 + gain((i % w) as f32 / w as f32)))
            .collect();
        LinearImage::new(img.width, img.height, pixels).unwrap()
    }

    /// `img` with independent zero-mean noise of relative amplitude `amp` (uniform, so
    /// standard deviation `amp / sqrt(3)`) from `seed`.
    fn noisy(img: &LinearImage, amp: f32, seed: u64) -> LinearImage {
        let mut rng = base::rng::Rng::new(seed);
        let pixels = img
            .pixels
            .iter()
            .map(|p| *p * (1.0 + amp * (2.0 * rng.next_f64() as f32 - 1.0)))
            .collect();
        LinearImage::new(img.width, img.height, pixels).unwrap()
    }

    /// The correction recovers a known distance from noisy halves. With `K` independent noise
    /// components, the noise power estimated from the halves' difference and the noise power in
    /// a measured distance each scatter by `sqrt(2 / K)` of themselves; at 128^2 pixels, even
    /// counting only a tenth of them as independent after the CSF filter (K ~ 1,600), that is
    /// 3.5 %, so with the noise as large as the distance the corrected squared distance is off
    /// by about 5 % (1 sigma) and the distance by 2.5 %: 10 % is four sigma.
    #[test]
    fn the_noise_correction_recovers_a_known_distance() {
        let x = clean(128);
        let ppd = metric::DEFAULT_PPD;
        // A smooth 5 % brightening of the right half: the image under test.
        let y = brightened(&x, |t| 0.05 * t * t);
        let exact = compare(&y, &x, ppd).unwrap().perceptual_distance;
        // Noise per half chosen so the averaged truth's noise is comparable to the distance.
        let t = TruthReference::from_halves(&noisy(&x, 0.01, 1), &noisy(&x, 0.01, 2), ppd).unwrap();
        let ratio = t.noise.perceptual / exact;
        assert!((0.5..4.0).contains(&ratio), "noise / distance {ratio}");
        let e = t.errors(&y, ppd).unwrap();
        assert!(e.perceptual_measured > exact * 1.1, "{e:?} vs {exact}");
        assert!(
            (e.perceptual - exact).abs() <= 0.1 * exact,
            "corrected {} against exact {exact} (measured {})",
            e.perceptual,
            e.perceptual_measured
        );
        assert_eq!(e.resolved, t.noise.perceptual < e.perceptual, "{e:?}");
        // The clean image itself: what is left after the correction is a fraction of the noise,
        // and not resolved: the page shows only the measured bound.
        let own = t.errors(&x, ppd).unwrap();
        assert!(
            own.perceptual <= 0.35 * t.noise.perceptual,
            "{own:?} {:?}",
            t.noise
        );
        assert!(!own.resolved);
        assert_eq!(
            own.perceptual_text(3),
            format!("≤{:.3}", own.perceptual_measured)
        );
    }

    /// `img` as a path tracer with `spp` samples per pixel sees it: each sample finds the light
    /// with probability 1/8 and then carries 8 times the pixel's value, so the estimate's noise
    /// is skewed (most pixels low, a few far too bright), as a path tracer's is at low counts.
    fn traced(img: &LinearImage, spp: u32, seed: u64) -> LinearImage {
        let mut rng = base::rng::Rng::new(seed);
        let pixels = img
            .pixels
            .iter()
            .map(|p| {
                let hits = (0..spp).filter(|_| rng.next_f64() < 0.125).count();
                *p * (8.0 * hits as f32 / spp as f32)
            })
            .collect();
        LinearImage::new(img.width, img.height, pixels).unwrap()
    }

    /// Skewed noise: with few samples the truth's noise exceeds the distance and the correction
    /// is flagged as unresolved (its value then reads anywhere from 0 to the measured one);
    /// with many it resolves the distance and the corrected value is within 10 % of the exact
    /// one, as with symmetric noise.
    #[test]
    fn skewed_noise_is_flagged_where_it_exceeds_the_distance() {
        let x = clean(128);
        let ppd = metric::DEFAULT_PPD;
        let y = brightened(&x, |t| 0.2 * t);
        let exact = compare(&y, &x, ppd).unwrap().perceptual_distance;
        let at = |spp| {
            let t =
                TruthReference::from_halves(&traced(&x, spp, 1), &traced(&x, spp, 2), ppd).unwrap();
            (t.errors(&y, ppd).unwrap(), t.noise.perceptual)
        };
        let (few, noise) = at(4);
        assert!(noise > exact && !few.resolved, "{few:?}, noise {noise}");
        assert!(few.perceptual_text(3).starts_with('≤'));
        let (many, noise) = at(16_384);
        assert!(noise < exact && many.resolved, "{many:?}, noise {noise}");
        assert!(
            (many.perceptual - exact).abs() <= 0.1 * exact,
            "corrected {} against exact {exact}",
            many.perceptual
        );
    }
}
