//! Errors against physics: the path tracer's image ([`truth`]) as the reference of a sweep's
//! error budget. Every other error the sweep reports compares the solver with itself (the same
//! solution evaluated exactly, or a finer run of the same solver); this one does not.
//!
//! The truth image is traced as [`PARTS`] independent parts (seeds 1 to [`PARTS`], an equal share
//! of the samples each, at the frame's own sample positions) and averaged. The parts give the
//! truth's own noise: for an L2 measure `E`, each part's distance from the mean has expectation
//! `(K - 1) / K` of one part's noise power (`K` parts), so the mean carries
//! `N^2 = sum_k E(part_k, mean)^2 / (K (K - 1))` (with two halves, `E(a, b)^2 / 4`). Because the
//! noise is independent of any image measured against it, `E(x, truth)^2 = E(x, physics)^2 + N^2`
//! up to a zero-mean cross term, and [`PhysicsErrors`] reports both the measured distance and the
//! distance with the noise taken out, `sqrt(max(E^2 - N^2, 0))`. This holds exactly for RMSE;
//! for the perceptual distance (an L2 norm of CSF-filtered lightness) it holds to first order in
//! the noise, the cube root adding a bias of about `-sigma^2 / 9` of the relative per-pixel noise
//! `sigma` (6e-5 at 2 %).
//!
//! How sure a figure is: the same figure is measured again against the mean of every part but
//! one, for each part in turn (the delete-one jackknife, Efron and Tibshirani 1993, ch. 11),
//! each with its own noise taken out. The replicates' spread is the figure's standard error from
//! the truth's noise, and a difference of two figures measured against one truth has paired
//! replicates, so the noise they share cancels in it ([`Interval::difference`]). A difference is
//! called only where its 95 % interval (Student's t with `K - 1` degrees of freedom) excludes 0.
//!
//! Invariants: the same scene, size, sample positions and samples give the same bits (the
//! tracer's seeds are fixed); the corrected distances are finite and never negative.

use serde::Serialize;

use app::context::Context;
use base::error::Error;
use base::error::Result;
use engine::frame::FrameOptions;
use imageio::LinearImage;
use metric::regions::{split_without_noise, RegionError, Regions, REGIONS};
use metric::{compare, perceptual_distance};
use scene::Scene;
use truth::{PixelFilter, TruthOptions};

/// Independent parts the truth is traced in (seeds 1 to `PARTS`): eight give its noise to a
/// few percent and a jackknife interval whose t factor (2.36 for 7 degrees of freedom) is near
/// the normal's 1.96, at the same total samples as two halves.
pub const PARTS: usize = 8;

/// Student's t quantile 0.975 at `PARTS - 1` degrees of freedom: the half width of a 95 %
/// interval in standard errors.
const T_975: f64 = 2.364_624;

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
    /// The corrected perceptual distance against the mean of every part of the truth but one,
    /// for each part in turn (see the module documentation): what [`Interval`]s are built from.
    pub replicates: [f64; PARTS],
    /// The measured perceptual distance against the same truths: what a difference of two
    /// images' squared distances is built from ([`Interval::squares`]).
    pub measured_replicates: [f64; PARTS],
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

/// A 95 % interval of a figure measured against the truth, or of a difference of two, from the
/// jackknife over the truth's parts (see the module documentation).
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct Interval {
    /// The figure (or difference) against the whole truth.
    pub value: f64,
    /// Its 95 % interval.
    pub low: f64,
    /// Its 95 % interval.
    pub high: f64,
}

impl Interval {
    /// The interval of `value` from its jackknife replicates.
    fn of(value: f64, replicates: impl Iterator<Item = f64> + Clone) -> Interval {
        let k = PARTS as f64;
        let mean = replicates.clone().sum::<f64>() / k;
        let var = replicates.map(|r| (r - mean) * (r - mean)).sum::<f64>() * (k - 1.0) / k;
        let half = T_975 * var.sqrt();
        Interval {
            value,
            low: value - half,
            high: value + half,
        }
    }

    /// `a`'s figure less `b`'s, both measured against one truth: paired replicates, so the
    /// noise the two share cancels.
    pub fn difference(a: &PhysicsErrors, b: &PhysicsErrors) -> Interval {
        let reps = a.replicates.iter().zip(&b.replicates).map(|(x, y)| x - y);
        Interval::of(a.perceptual - b.perceptual, reps)
    }

    /// `a`'s squared measured distance less `b`'s, both against one truth: the squared
    /// distances of the images from the light differ by this much in expectation, the truth's
    /// noise power being the same in both. Unlike the difference of two corrected figures it
    /// needs neither figure resolved: in filtered lightness it is `|a|^2 - |b|^2 - 2 <a - b, t>`,
    /// linear in the truth `t`, so its jackknife is the plain standard error over the parts
    /// however large their noise; its sign says which image is nearer the light.
    pub fn squares(a: &PhysicsErrors, b: &PhysicsErrors) -> Interval {
        let reps = a
            .measured_replicates
            .iter()
            .zip(&b.measured_replicates)
            .map(|(x, y)| x * x - y * y);
        let value = a.perceptual_measured.powi(2) - b.perceptual_measured.powi(2);
        Interval::of(value, reps)
    }

    /// `a`'s figure less `c`, a figure that does not depend on the truth (a reconstruction
    /// error, measured against the solution's exact image).
    pub fn above(a: &PhysicsErrors, c: f64) -> Interval {
        Interval::of(a.perceptual - c, a.replicates.iter().map(|x| x - c))
    }

    /// The figure's own interval.
    pub fn own(a: &PhysicsErrors) -> Interval {
        Interval::of(a.perceptual, a.replicates.iter().copied())
    }

    /// The sign of a difference where its interval excludes 0, else a tie.
    pub fn sign(&self) -> Sign {
        if self.low > 0.0 {
            Sign::Positive
        } else if self.high < 0.0 {
            Sign::Negative
        } else {
            Sign::Tie
        }
    }
}

/// What an [`Interval`] of a difference calls.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Sign {
    /// Above 0 beyond doubt.
    Positive,
    /// Below 0 beyond doubt.
    Negative,
    /// Its interval holds 0.
    Tie,
}

/// The truth's own noise, in the measures [`PhysicsErrors`] corrects.
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct TruthNoise {
    /// Camera samples per pixel of the averaged image (every part).
    pub samples_per_pixel: u32,
    /// Independent parts it was traced in ([`PARTS`]).
    pub parts: u32,
    /// Perceptual distance of the averaged image's noise: the larger of its estimates from the
    /// parts' spread and from the two halves' difference.
    pub perceptual: f64,
    /// The halves' estimate over the parts' (at least 1): near 1 where the noise is what the
    /// measure sees linearly; above it where a skewed noise at few samples per part reads low
    /// in the parts (the larger is kept).
    pub skew: f64,
    /// RMSE of the averaged image's noise.
    pub rmse: f64,
    /// The tracer's own per-pixel estimate: root-mean-square relative standard error of
    /// luminance of the averaged image.
    pub relative_error: f64,
    /// Seconds the parts took.
    pub seconds: f64,
}

/// The averaged truth image, its noise, and the truths its jackknife measures against.
#[derive(Debug, Clone)]
pub struct TruthReference {
    /// The mean of the parts.
    pub image: LinearImage,
    /// Its noise.
    pub noise: TruthNoise,
    /// For each part, the mean of every other part and that mean's perceptual noise.
    left_out: Vec<(LinearImage, f64)>,
    /// Per pixel, the noise variance of the mean's luminance: the parts' squared deviations
    /// from it over `K (K - 1)` ([`TruthReference::region_errors`]).
    noise_var: Vec<f64>,
}

/// `sqrt(max(measured^2 - noise^2, 0))`: a distance with independent noise taken out.
pub fn without_noise(measured: f64, noise: f64) -> f64 {
    (measured * measured - noise * noise).max(0.0).sqrt()
}

/// Traces `scene` at the frame's size and sample positions with `samples_per_pixel` samples
/// (split over the [`PARTS`] parts, at least one each).
pub fn trace(
    job: &Context<'_>,
    scene: &Scene,
    opts: &FrameOptions,
    samples_per_pixel: u32,
    ppd: f64,
) -> Result<TruthReference> {
    let start = std::time::Instant::now();
    let share = samples_per_pixel.div_ceil(PARTS as u32).max(1);
    let mut parts = Vec::new();
    let mut error2 = 0.0;
    for seed in 1..=PARTS as u64 {
        let o = TruthOptions {
            seed,
            width: opts.width,
            height: opts.height,
            samples_per_pixel: share,
            filter: PixelFilter::from_aa(Some(opts.aa)),
            ..TruthOptions::new(scene)
        };
        let part = truth::render(scene, &o, job.observer)?;
        error2 += part.relative_error.powi(2);
        parts.push(part.mean);
    }
    let mut t = TruthReference::from_parts(&parts, ppd)?;
    t.noise.samples_per_pixel = PARTS as u32 * share;
    // Independent parts: the mean's relative error is the parts' over sqrt(K).
    t.noise.relative_error = error2.sqrt() / PARTS as f64;
    t.noise.seconds = start.elapsed().as_secs_f64();
    Ok(t)
}

/// The mean of `parts` (images of one size).
fn mean_of<'a>(parts: impl Iterator<Item = &'a LinearImage> + Clone) -> Result<LinearImage> {
    let first = parts.clone().next().expect("at least one part");
    let n = parts.clone().count() as f32;
    let mut pixels = vec![glam::Vec3::ZERO; first.pixels.len()];
    for p in parts {
        for (acc, q) in pixels.iter_mut().zip(&p.pixels) {
            *acc += *q;
        }
    }
    pixels.iter_mut().for_each(|p| *p /= n);
    LinearImage::new(first.width, first.height, pixels)
}

/// The noise power of `mean`, the mean of `parts`, in a measure `e`: the parts' squared
/// distances from it over `K (K - 1)`.
fn noise2(
    parts: &[&LinearImage],
    mean: &LinearImage,
    e: impl Fn(&LinearImage, &LinearImage) -> Result<f64>,
) -> Result<f64> {
    let k = parts.len() as f64;
    let mut sum = 0.0;
    for p in parts {
        sum += e(p, mean)?.powi(2);
    }
    Ok(sum / (k * (k - 1.0)))
}

impl TruthReference {
    /// The mean of [`PARTS`] independent estimates of one image, with its noise from their
    /// spread (samples, relative error and seconds left 0 for the caller) and the truths of its
    /// jackknife.
    pub fn from_parts(parts: &[LinearImage], ppd: f64) -> Result<TruthReference> {
        if parts.len() != PARTS {
            return Err(Error::Runtime(format!(
                "a truth needs {PARTS} independent parts, got {}",
                parts.len()
            )));
        }
        let image = mean_of(parts.iter())?;
        let all: Vec<&LinearImage> = parts.iter().collect();
        let perceptual = |a: &LinearImage, b: &LinearImage| perceptual_distance(a, b, ppd);
        let rmse = |a: &LinearImage, b: &LinearImage| compare(a, b, ppd).map(|c| c.rmse);
        // The noise from the parts' spread, and from the two halves' (each the mean of half
        // the parts): equal for noise the measure sees linearly. A skewed noise (a path
        // tracer's at a few samples per part) is compressed by the cube root of each part more
        // than of the halves, so the parts' figure reads low; the larger is kept, and the
        // jackknife's figures are scaled by the same ratio.
        let by_parts = noise2(&all, &image, perceptual)?.sqrt();
        let halves = [
            mean_of(all[..PARTS / 2].iter().copied())?,
            mean_of(all[PARTS / 2..].iter().copied())?,
        ];
        let by_halves = perceptual(&halves[0], &halves[1])? / 2.0;
        let skew = if by_parts > 0.0 {
            (by_halves / by_parts).max(1.0)
        } else {
            1.0
        };
        let mut left_out = Vec::with_capacity(PARTS);
        for k in 0..PARTS {
            let others: Vec<&LinearImage> =
                (0..PARTS).filter(|&j| j != k).map(|j| all[j]).collect();
            let m = mean_of(others.iter().copied())?;
            let n2 = noise2(&others, &m, perceptual)?;
            left_out.push((m, skew * n2.sqrt()));
        }
        let ym = image.luminance();
        let mut noise_var = vec![0.0f64; ym.len()];
        for part in &all {
            for ((v, y), m) in noise_var.iter_mut().zip(part.luminance()).zip(&ym) {
                *v += (y - m) * (y - m);
            }
        }
        let k = PARTS as f64;
        noise_var.iter_mut().for_each(|v| *v /= k * (k - 1.0));
        Ok(TruthReference {
            noise_var,
            noise: TruthNoise {
                samples_per_pixel: 0,
                parts: PARTS as u32,
                perceptual: by_parts.max(by_halves),
                skew,
                rmse: noise2(&all, &image, rmse)?.sqrt(),
                relative_error: 0.0,
                seconds: 0.0,
            },
            image,
            left_out,
        })
    }

    /// `img`'s error against the truth split by `regions` ([`metric::regions`]), each
    /// region's mean squared luminance error less its pixels' mean noise variance. Errors if
    /// the sizes differ.
    pub fn region_errors(
        &self,
        img: &LinearImage,
        regions: &Regions,
    ) -> Result<[RegionError; REGIONS]> {
        if (img.width, img.height) != (self.image.width, self.image.height) {
            return Err(Error::Runtime(format!(
                "an image of {} x {} against a truth of {} x {}",
                img.width, img.height, self.image.width, self.image.height
            )));
        }
        Ok(split_without_noise(
            &img.luminance(),
            &self.image.luminance(),
            Some(&self.noise_var),
            regions,
        ))
    }

    /// `img` measured against the truth, with and without its noise.
    pub fn errors(&self, img: &LinearImage, ppd: f64) -> Result<PhysicsErrors> {
        let c = compare(img, &self.image, ppd)?;
        let perceptual = without_noise(c.perceptual_distance, self.noise.perceptual);
        let (mut replicates, mut measured_replicates) = ([0.0; PARTS], [0.0; PARTS]);
        for (k, (truth, noise)) in self.left_out.iter().enumerate() {
            measured_replicates[k] = perceptual_distance(img, truth, ppd)?;
            replicates[k] = without_noise(measured_replicates[k], *noise);
        }
        Ok(PhysicsErrors {
            replicates,
            measured_replicates,
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

    /// The truth of [`PARTS`] parts `part(seed)`, seeds 1 to [`PARTS`].
    fn truth_of(part: impl Fn(u64) -> LinearImage, ppd: f64) -> TruthReference {
        let parts: Vec<_> = (1..=PARTS as u64).map(part).collect();
        TruthReference::from_parts(&parts, ppd).unwrap()
    }

    /// The correction recovers a known distance from noisy parts. With `K` independent noise
    /// components, the noise power estimated from the parts' spread and the noise power in
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
        // Noise per part chosen so the averaged truth's noise is comparable to the distance.
        let t = truth_of(|seed| noisy(&x, 0.02, seed), ppd);
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

    /// The per-region correction recovers known region errors from noisy parts. The image
    /// under test is the clean one plus 0.03 in luminance on the left third of the columns and
    /// 0.01 elsewhere, split into regions by column (an "emitter" strip, its band, an edge);
    /// the parts carry uniform relative noise of 0.15 (luminance 0.2-1: a standard deviation
    /// of up to 0.087 per part, a noise variance of the mean of 8 of about 2.5e-4 on average,
    /// more than the smaller squared errors measured, 1e-4). A region's corrected mean squared
    /// error scatters by about sqrt(2 / n) of the noise variance (n >= 288 here: 3e-5), and the
    /// variance estimated from 8 parts by about 3 % over 288 pixels: the RMSE is checked to
    /// 25 % of 0.03 (4.5e-4 in squares, over 10 sigma) and to 0.015 in absolute for 0.01.
    #[test]
    fn region_errors_take_the_truths_noise_out_per_region() {
        use metric::regions::Region;
        let x = clean(96);
        let ppd = metric::DEFAULT_PPD;
        let w = x.width as usize;
        let t = truth_of(|seed| noisy(&x, 0.15, seed), ppd);
        let y = LinearImage::new(
            x.width,
            x.height,
            x.pixels
                .iter()
                .enumerate()
                .map(|(i, p)| *p + glam::Vec3::splat(if i % w < w / 3 { 0.03 } else { 0.01 }))
                .collect(),
        )
        .unwrap();
        // Emitters in columns 0..3 (their band: columns 3..6); the reference's one sharp edge
        // at column 60 (a drop to a tenth).
        let emitter: Vec<bool> = (0..w * w).map(|i| i % w < 3).collect();
        let yb: Vec<f64> = (0..w * w)
            .map(|i| if i % w < 60 { 1.0 } else { 0.1 })
            .collect();
        let regions = Regions::classify(&emitter, &yb, w, w);
        assert!(
            regions.pixels().iter().all(|&n| n >= 280),
            "{:?}",
            regions.pixels()
        );
        let got = t.region_errors(&y, &regions).unwrap();
        let measured = metric::regions::split(&y.luminance(), &t.image.luminance(), &regions);
        let want = |r: Region| match r {
            Region::Emitters | Region::EmitterBand => 0.03,
            Region::Edges => 0.01,
            // Columns 6..32 at 0.03, 32..57 and 63..96 at 0.01 (the band is columns 0..6,
            // the edge's pixels 57..63): a mean square.
            Region::Interior => (26.0 * 0.03f64.powi(2) + 58.0 * 0.01f64.powi(2)) / 84.0,
        };
        for (k, r) in Region::ALL.into_iter().enumerate() {
            let exact = if r == Region::Interior {
                want(r).sqrt()
            } else {
                want(r)
            };
            assert!(
                (got[k].rmse - exact).abs() <= (0.25 * exact).max(0.015),
                "{}: corrected {} against {exact} (measured {})",
                r.name(),
                got[k].rmse,
                measured[k].rmse
            );
            assert!(measured[k].rmse > got[k].rmse, "{}: {got:?}", r.name());
        }
        assert!(t.region_errors(&clean(32), &regions).is_err());
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

    /// A truth of fewer or more parts than [`PARTS`] is refused, not measured with a wrong
    /// noise.
    #[test]
    fn a_truth_of_the_wrong_number_of_parts_is_refused() {
        let x = clean(16);
        let parts = vec![x.clone(), x];
        assert!(TruthReference::from_parts(&parts, metric::DEFAULT_PPD).is_err());
    }

    /// The jackknife's intervals are calibrated. Two images 4 % and 3 % brighter than a clean
    /// one, measured against truths of independent noisy parts (noise as large as their
    /// distances' difference), over 20 independent truths: the difference's 95 % interval
    /// holds the exact difference in at least 16 of 20 (expected 19; 15 or fewer has a chance
    /// of 0.3 %), its mean half width is within 0.6-1.7x of 1.96 times the scatter of the
    /// difference between truths (the interval's own scatter with 7 degrees of freedom is about
    /// 25 %), and the same image against itself is always a tie.
    #[test]
    fn jackknife_intervals_hold_the_exact_difference() {
        let x = clean(96);
        let ppd = metric::DEFAULT_PPD;
        let a = brightened(&x, |t| 0.04 * t);
        let b = brightened(&x, |t| 0.03 * t);
        let exact = compare(&a, &x, ppd).unwrap().perceptual_distance
            - compare(&b, &x, ppd).unwrap().perceptual_distance;
        let (mut held, mut halves, mut values) = (0, Vec::new(), Vec::new());
        for set in 0..20u64 {
            let t = truth_of(|seed| noisy(&x, 0.01, 100 * set + seed), ppd);
            let (ea, eb) = (t.errors(&a, ppd).unwrap(), t.errors(&b, ppd).unwrap());
            assert!(ea.resolved && eb.resolved, "{ea:?} {eb:?}");
            let d = Interval::difference(&ea, &eb);
            held += usize::from(d.low <= exact && exact <= d.high);
            halves.push(0.5 * (d.high - d.low));
            values.push(d.value);
            // The squared distances' difference calls the same sign.
            let sq = Interval::squares(&ea, &eb);
            assert!(sq.value > 0.0, "{sq:?}");
            let own = Interval::difference(&ea, &ea);
            assert_eq!((own.value, own.sign()), (0.0, Sign::Tie));
        }
        let mean = values.iter().sum::<f64>() / 20.0;
        let sd = (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / 19.0).sqrt();
        let half = halves.iter().sum::<f64>() / 20.0;
        assert!(held >= 16, "{held} of 20 intervals hold {exact}");
        let ratio = half / (1.96 * sd);
        assert!(
            (0.6..1.7).contains(&ratio),
            "half width {half}, scatter {sd}: {ratio}"
        );
        // The difference is resolved: its intervals exclude 0 on average.
        assert!(
            mean - half > 0.0,
            "mean {mean}, half width {half}, exact {exact}"
        );
    }

    /// Two images' squared distances from the light are told apart where the truth resolves
    /// neither distance: 8 % and 4 % brighter than a clean image (squared distances differ by
    /// 0.030), against 20 truths whose noise (0.42) is several times both distances. The difference of squares is linear in the truth, so
    /// its interval holds the exact difference in at least 16 of 20 and, on average, excludes
    /// 0.
    #[test]
    fn squared_distances_are_told_apart_through_noise() {
        let x = clean(96);
        let ppd = metric::DEFAULT_PPD;
        let a = brightened(&x, |t| 0.08 * t);
        let b = brightened(&x, |t| 0.04 * t);
        let exact = compare(&a, &x, ppd).unwrap().perceptual_distance.powi(2)
            - compare(&b, &x, ppd).unwrap().perceptual_distance.powi(2);
        let (mut held, mut lows, mut noise) = (0, 0.0, 0.0f64);
        for set in 0..20u64 {
            let t = truth_of(|seed| noisy(&x, 0.08, 100 * set + seed), ppd);
            let (ea, eb) = (t.errors(&a, ppd).unwrap(), t.errors(&b, ppd).unwrap());
            assert!(!ea.resolved && !eb.resolved, "{ea:?} {eb:?}");
            let d = Interval::squares(&ea, &eb);
            held += usize::from(d.low <= exact && exact <= d.high);
            lows += d.low / 20.0;
            noise += t.noise.perceptual / 20.0;
        }
        assert!(held >= 16, "{held} of 20 intervals hold {exact}");
        assert!(lows > 0.0, "mean lower end {lows}, exact {exact}");
        // The noise is several times either distance: neither is resolved.
        assert!(noise > 0.2, "noise {noise}");
    }

    /// Skewed noise: with few samples (16 per pixel, 2 per part) the truth's noise exceeds the
    /// distance and the correction is flagged as unresolved (its value then reads anywhere
    /// from 0 to the measured one); the parts' spread alone would read that noise low enough
    /// to pass the flag (26 against a corrected 27, the exact distance 0.56), which the halves'
    /// estimate catches. With many samples it resolves the distance and the corrected value is
    /// within 10 % of the exact one, as with symmetric noise.
    #[test]
    fn skewed_noise_is_flagged_where_it_exceeds_the_distance() {
        let x = clean(128);
        let ppd = metric::DEFAULT_PPD;
        let y = brightened(&x, |t| 0.2 * t);
        let exact = compare(&y, &x, ppd).unwrap().perceptual_distance;
        let at = |spp| {
            let t = truth_of(|seed| traced(&x, spp / PARTS as u32, seed), ppd);
            (t.errors(&y, ppd).unwrap(), t.noise.perceptual, t.noise.skew)
        };
        // Two samples per part: the parts' spread reads the noise a third low, and the halves'
        // is kept.
        let (few, noise, skew) = at(16);
        assert!(skew > 1.3, "skew {skew}");
        assert!(noise > exact && !few.resolved, "{few:?}, noise {noise}");
        assert!(few.perceptual_text(3).starts_with('≤'));
        let (many, noise, skew) = at(32_768);
        assert!(skew < 1.05, "skew {skew}");
        assert!(noise < exact && many.resolved, "{many:?}, noise {noise}");
        assert!(
            (many.perceptual - exact).abs() <= 0.1 * exact,
            "corrected {} against exact {exact}",
            many.perceptual
        );
    }
}
