//! The Mach-band measure: how much more (or less) curvature one image has than another,
//! concentrated where reconstructions have derivative discontinuities.
//!
//! A reconstruction that is only C0 (bilinear texture filtering, Gouraud shading, piecewise-linear
//! interpolation of radiosity samples) has kinks along element and texel boundaries. The eye
//! enhances them into Mach bands; the paper's C1 bicubic reconstruction removes them. A kink is a
//! spike of the second derivative, so this measure sums the squared second differences of the
//! luminance difference between the two images.
//!
//! Definition. With `Y_a`, `Y_b` the luminances and `mu_a`, `mu_b` their means, let
//! `E(x, y) = Y_a(x, y) / mu_a - Y_b(x, y) / mu_b` (the same mean normalisation as the perceptual
//! distance, so the measure is dimensionless, symmetric and unchanged by scaling either image).
//! The second differences along rows and columns are
//! `Dxx(x, y) = E(x-1, y) - 2 E(x, y) + E(x+1, y)` for `1 <= x <= W-2`, and
//! `Dyy(x, y) = E(x, y-1) - 2 E(x, y) + E(x, y+1)` for `1 <= y <= H-2`. The measure is their mean
//! square:
//!
//! `M = (sum Dxx^2 + sum Dyy^2) / (H (W - 2) + W (H - 2))`,
//!
//! each sum over the interior positions where the difference exists (0 when neither exists, for
//! images narrower and lower than 3 pixels). Units: (relative luminance per pixel^2)^2.
//!
//! Why the difference of the two images and not the test image alone: a smooth reference has
//! curvature of its own (the spot lights' falloff); subtracting it leaves what the reconstruction
//! added. A piecewise-linear reconstruction with knots every `s` pixels of a function with second
//! derivative `g''` (per pixel^2) has `Dxx = -g''` between knots and a spike of about `g'' s` at
//! each knot, so `M` grows like `g''^2 s`; a C1 cubic reconstruction's second derivative is
//! continuous up to an error `O(g''' s)`, so its `M` is smaller by a factor of order
//! `(g'' / (g''' s))^2 / s`, which is large for a smooth function and moderate knot spacing.
//! The measure does count every curvature difference, not only spikes: noise raises it too (a
//! second difference amplifies the highest frequencies by up to 16 in energy).

/// The Mach-band measure of two row-major `w x h` luminance arrays (see the module doc). The
/// caller has checked the sizes and that both means are positive.
pub(crate) fn mach_band_of_luminances(ya: &[f64], yb: &[f64], w: usize, h: usize) -> f64 {
    let ma = super::mean(ya);
    let mb = super::mean(yb);
    let e: Vec<f64> = ya.iter().zip(yb).map(|(a, b)| a / ma - b / mb).collect();
    let mut sum = 0.0;
    let mut count = 0usize;
    for y in 0..h {
        let row = &e[y * w..(y + 1) * w];
        for x in 1..w.saturating_sub(1) {
            let d = row[x - 1] - 2.0 * row[x] + row[x + 1];
            sum += d * d;
            count += 1;
        }
    }
    for y in 1..h.saturating_sub(1) {
        for x in 0..w {
            let d = e[(y - 1) * w + x] - 2.0 * e[y * w + x] + e[(y + 1) * w + x];
            sum += d * d;
            count += 1;
        }
    }
    if count == 0 {
        0.0
    } else {
        sum / count as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_kink_gives_the_hand_computed_energy() {
        // 5 x 1 rows: a = [1, 2, 3, 2, 1] (a kink at x = 2), b = constant 1.8 (mean 1.8, like a).
        // E = a / 1.8 - 1 = [-0.8, 0.2, 1.2, 0.2, -0.8] / 1.8; Dxx at x = 1, 2, 3 is
        // (0, -2, 0) / 1.8; no vertical differences (H = 1). M = (4 / 3.24) / 3.
        let a = [1.0, 2.0, 3.0, 2.0, 1.0];
        let b = [1.8; 5];
        let m = mach_band_of_luminances(&a, &b, 5, 1);
        assert!((m - 4.0 / 3.24 / 3.0).abs() < 1e-14, "{m}");
        // Symmetric, and 0 against itself.
        assert_eq!(mach_band_of_luminances(&b, &a, 5, 1), m);
        assert_eq!(mach_band_of_luminances(&a, &a, 5, 1), 0.0);
        // The same rows as a column (1 x 5): the same energy, from the vertical differences.
        assert!((mach_band_of_luminances(&a, &b, 1, 5) - m).abs() < 1e-14);
    }

    #[test]
    fn a_linear_ramp_difference_has_no_energy() {
        // E linear in x and y: every second difference is 0 (up to rounding).
        let (w, h) = (6, 5);
        let a: Vec<f64> = (0..w * h)
            .map(|i| 1.0 + 0.1 * (i % w) as f64 + 0.05 * (i / w) as f64)
            .collect();
        let b = vec![1.0; w * h];
        assert!(mach_band_of_luminances(&a, &b, w, h) < 1e-28);
    }
}
