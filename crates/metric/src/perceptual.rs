//! The perceptual distance: the project's definition (`docs/metrics.md`), after Rushmeier et al.
//! 1995, model 1, with the Mannos–Sakrison contrast sensitivity function (CSF). The paper
//! (Bastos et al., sec. 3.1) uses this model for Fig. 5 and Fig. 6; its viewing geometry and
//! scaling are unknown, so only ratios of our numbers compare with the paper's.
//!
//! The definition (as in `docs/metrics.md`), with where each step is:
//!
//! > 1. Both images linear RGB, same size W x H. Luminance Y = 0.2126 R + 0.7152 G + 0.0722 B.
//!
//! [`super::luminance`] (called by [`perceptual_distance`]; sizes are checked by
//! `super::validate`).
//!
//! > 2. Normalize each image by its own mean luminance: Y' = Y / mean(Y). (Mean 0: the metric is
//! > undefined; say so.)
//!
//! `normalised_cube_root`, first loop. A mean that is not positive is an error (`super::validate`
//! rejects it before this module runs).
//!
//! > 3. Cube root: L = cbrt(Y').
//!
//! `normalised_cube_root`, same loop. `f64::cbrt` is the real (odd) cube root, so the slightly
//! negative luminances a ringing bicubic reconstruction can write to EXR stay defined and keep
//! their sign.
//!
//! > 4. Unnormalized forward 2-D DFT of each: F1, F2 (size W x H, no padding, no window).
//!
//! `dft2`: rustfft forward transforms (which are unnormalised) of every row, then of every column,
//! for any W and H (rustfft handles non-powers of two exactly, not by padding). Each image is
//! transformed on its own, as the definition says, and the difference is taken per bin.
//!
//! > 5. Frequency of bin (kx, ky): fx = kx / W for kx < W/2, (kx - W)/W otherwise (likewise fy);
//! > f = sqrt(fx^2 + fy^2) * ppd cycles per degree, ppd = 32 pixels per degree unless given.
//!
//! `bin_frequency` (cycles per pixel) and `axis_frequencies` (times ppd); `f` itself is formed
//! in the last loop of `distance_of_luminances`. For even W the bin W/2 gets
//! fx = -1/2; its |fx| is the same as +1/2, so the choice does not matter.
//!
//! > 6. CSF A(f) = 2.6 (0.0192 + 0.114 f) exp(-(0.114 f)^1.1) (peak about 0.98 at f about 7.9
//! > cpd; A(0) = 0.0499).
//!
//! [`csf`]. A(0) is not 0: the mean of L (which differs between images after the cube root) is
//! weighted by 0.0499.
//!
//! > 7. Distance D = sqrt( (1/(W H)) * sum over bins of A(f)^2 |F1 - F2|^2 ). (By Parseval this is
//! > the L2 norm of the difference of the two CSF-filtered images.) D = 0 for equal images.
//!
//! `distance_of_luminances`, last loop: a sequential `f64` sum over the bins in a fixed order.
//! Note what the normalisation does: the DFT's factor W H cancels against 1/(W H), so D is an L2
//! norm over pixels (a sum, not a mean): the same per-pixel difference gives a D that grows like
//! sqrt(W H). Distances compare only between images of one size at one ppd.
//!
//! Everything is `f64` and single-threaded, with a fixed summation order, so the result is the
//! same bytes on every run on a machine. (rustfft picks SSE/AVX kernels by CPU feature at run
//! time, which may change the last bits between different CPUs, never between runs.) Cost: two
//! 2-D FFTs, O(W H log(W H)); a 513 x 513 pair takes about 60 ms including reading the files.

use rustfft::num_complex::Complex;
use rustfft::FftPlanner;

use super::{luminance, validate, LinearImage};
use base::error::Result;

/// The default viewing geometry: 32 pixels per degree of visual angle (`docs/metrics.md`, step 5).
pub const DEFAULT_PPD: f64 = 32.0;

/// The Mannos–Sakrison contrast sensitivity at `f` cycles per degree (`docs/metrics.md`, step 6):
/// `A(f) = 2.6 (0.0192 + 0.114 f) exp(-(0.114 f)^1.1)`.
pub fn csf(f: f64) -> f64 {
    if !f.is_finite() {
        // The limit: the exponential wins (an infinite f would give inf * 0 = NaN).
        return 0.0;
    }
    2.6 * (0.0192 + 0.114 * f) * (-(0.114 * f).powf(1.1)).exp()
}

/// The signed frequency of DFT bin `k` of `n`, in cycles per pixel (`docs/metrics.md`, step 5):
/// `k / n` for `k < n / 2`, `(k - n) / n` otherwise.
pub(crate) fn bin_frequency(k: usize, n: usize) -> f64 {
    // `2 k < n` is `k < n / 2` without rounding n / 2 (for odd n, n / 2 is not an integer).
    if 2 * k < n {
        k as f64 / n as f64
    } else {
        (k as f64 - n as f64) / n as f64
    }
}

/// The perceptual distance between two images at `ppd` pixels per degree (`docs/metrics.md`).
/// Symmetric; 0 for equal images; unchanged when either image is multiplied by a positive
/// constant. Errors as [`super::compare`].
pub fn perceptual_distance(a: &LinearImage, b: &LinearImage, ppd: f64) -> Result<f64> {
    validate(a, b, ppd)?;
    let ya: Vec<f64> = a.pixels.iter().map(|p| luminance(*p)).collect();
    let yb: Vec<f64> = b.pixels.iter().map(|p| luminance(*p)).collect();
    Ok(distance_of_luminances(
        &ya,
        &yb,
        a.width as usize,
        a.height as usize,
        ppd,
    ))
}

/// Steps 2 and 3: `L = cbrt(Y / mean(Y))`, as complex numbers ready for the DFT. The caller has
/// checked that the mean is positive.
fn normalised_cube_root(y: &[f64]) -> Vec<Complex<f64>> {
    let m = super::mean(y);
    y.iter()
        .map(|&v| Complex::new((v / m).cbrt(), 0.0))
        .collect()
}

/// Step 4: the unnormalised forward 2-D DFT of a row-major `w x h` array. The result is returned
/// **transposed**: bin (kx, ky) is at `kx * h + ky`.
fn dft2(
    planner: &mut FftPlanner<f64>,
    data: &mut [Complex<f64>],
    w: usize,
    h: usize,
) -> Vec<Complex<f64>> {
    let rows = planner.plan_fft_forward(w);
    let mut scratch = vec![Complex::new(0.0, 0.0); rows.get_inplace_scratch_len()];
    // A buffer of h * w values is processed as h consecutive transforms of length w.
    rows.process_with_scratch(data, &mut scratch);
    let mut t = vec![Complex::new(0.0, 0.0); w * h];
    for y in 0..h {
        for x in 0..w {
            t[x * h + y] = data[y * w + x];
        }
    }
    let cols = planner.plan_fft_forward(h);
    scratch.resize(cols.get_inplace_scratch_len(), Complex::new(0.0, 0.0));
    cols.process_with_scratch(&mut t, &mut scratch);
    t
}

/// Steps 5 and 6 per axis: `A(f)` is not separable, so this returns the per-axis frequencies in
/// cycles per degree, `fx[kx]` and `fy[ky]`.
fn axis_frequencies(n: usize, ppd: f64) -> Vec<f64> {
    (0..n).map(|k| bin_frequency(k, n) * ppd).collect()
}

/// Steps 2-7 on two luminance arrays of `w x h` (row-major), already validated (same size,
/// finite, positive means, ppd > 0).
pub(crate) fn distance_of_luminances(ya: &[f64], yb: &[f64], w: usize, h: usize, ppd: f64) -> f64 {
    let mut planner = FftPlanner::<f64>::new();
    let mut la = normalised_cube_root(ya);
    let mut lb = normalised_cube_root(yb);
    let fa = dft2(&mut planner, &mut la, w, h);
    let fb = dft2(&mut planner, &mut lb, w, h);
    let fx = axis_frequencies(w, ppd);
    let fy = axis_frequencies(h, ppd);
    let mut sum = 0.0;
    for (kx, &fxk) in fx.iter().enumerate() {
        for (ky, &fyk) in fy.iter().enumerate() {
            let i = kx * h + ky;
            let a = csf((fxk * fxk + fyk * fyk).sqrt());
            sum += a * a * (fa[i] - fb[i]).norm_sqr();
        }
    }
    (sum / (w * h) as f64).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csf_matches_the_quoted_values() {
        // Mannos-Sakrison: A(0) = 0.0499 (2.6 * 0.0192 = 0.04992 exactly), peak about 0.98 near 7.9 cpd.
        assert!((csf(0.0) - 0.04992).abs() < 1e-15);
        let (mut best_f, mut best) = (0.0, 0.0);
        for i in 0..=4000 {
            let f = i as f64 * 0.005;
            if csf(f) > best {
                best = csf(f);
                best_f = f;
            }
        }
        assert!((best - 0.98).abs() < 0.005, "peak {best}");
        assert!((best_f - 7.9).abs() < 0.1, "peak at {best_f}");
        // Far above the peak the sensitivity falls off: at 60 cpd it is below 1 %.
        assert!(csf(60.0) < 0.01);
    }

    #[test]
    fn bin_frequencies_wrap_at_half() {
        assert_eq!(bin_frequency(0, 4), 0.0);
        assert_eq!(bin_frequency(1, 4), 0.25);
        assert_eq!(bin_frequency(2, 4), -0.5);
        assert_eq!(bin_frequency(3, 4), -0.25);
        // Odd n: bin 2 of 5 is below n / 2 = 2.5, bin 3 wraps.
        assert_eq!(bin_frequency(2, 5), 0.4);
        assert_eq!(bin_frequency(3, 5), -0.4);
    }
}
