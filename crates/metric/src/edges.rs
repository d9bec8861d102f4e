//! Error near sharp edges: how much of an image's error lies within a few pixels of the places
//! where the reference's light jumps (a spot's cone rim, a hard shadow, a silhouette).
//!
//! A pixel pair is an **edge** when two 4-neighbours' reference luminances differ by more than
//! [`EDGE_JUMP`] of the larger, and the larger is at least [`EDGE_FLOOR`] of the reference's
//! peak (so noise in the dark does not count). Pixels within [`EDGE_RADIUS`] (Chebyshev
//! distance) of an edge pixel are **near** an edge. The split then says which share of the
//! squared luminance error is near edges, and the RMSE on each side. Images rendered by the same
//! rasterizer share their silhouettes pixel for pixel, so between two of them the near-edge
//! error is that of the light's edges. Only the reference `b` decides the mask, so two images
//! measured against one reference are measured on the same pixels.

use serde::Serialize;

/// Relative luminance jump between 4-neighbours that makes an edge.
pub const EDGE_JUMP: f64 = 0.25;
/// Smallest luminance, relative to the reference's peak, at which a jump counts.
pub const EDGE_FLOOR: f64 = 1e-3;
/// Pixels within this Chebyshev distance of an edge pixel are near it.
pub const EDGE_RADIUS: usize = 2;

/// The error of `a` against `b` split at the reference's sharp edges.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct EdgeSplit {
    /// Pixels near an edge.
    pub near_pixels: usize,
    /// Share of the summed squared luminance error on those pixels, in [0, 1] (0 for equal
    /// images).
    pub near_share: f64,
    /// RMSE over the pixels near an edge (0 if there are none).
    pub rmse_near: f64,
    /// RMSE over the other pixels (0 if there are none).
    pub rmse_far: f64,
}

/// Whether neighbours of luminances `p` and `q` make an edge, given the absolute `floor`.
fn is_edge(p: f64, q: f64, floor: f64) -> bool {
    let m = p.max(q);
    m >= floor && m > 0.0 && (p - q).abs() > EDGE_JUMP * m
}

/// Which pixels (row-major, `w` x `h`) are near a sharp edge of the luminances `yb`.
pub fn near_edges(yb: &[f64], w: usize, h: usize) -> Vec<bool> {
    let peak = yb.iter().copied().fold(0.0f64, f64::max);
    let floor = EDGE_FLOOR * peak;
    let edge = mark_pairs(w, h, |i, j| is_edge(yb[i], yb[j], floor));
    dilate(&edge, w, h, EDGE_RADIUS)
}

/// The pixels (row-major, `w` x `h`) of every pair of 4-neighbours (indices `i < j`) that
/// `pair` accepts.
pub fn mark_pairs(w: usize, h: usize, pair: impl Fn(usize, usize) -> bool) -> Vec<bool> {
    let mut marked = vec![false; w * h];
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            for j in [(x + 1 < w).then_some(i + 1), (y + 1 < h).then_some(i + w)]
                .into_iter()
                .flatten()
            {
                if pair(i, j) {
                    marked[i] = true;
                    marked[j] = true;
                }
            }
        }
    }
    marked
}

/// The pixels within Chebyshev distance `radius` of a marked pixel of `marked` (row-major,
/// `w` x `h`).
pub fn dilate(marked: &[bool], w: usize, h: usize, radius: usize) -> Vec<bool> {
    let mut near = vec![false; marked.len()];
    for y in 0..h {
        for x in 0..w {
            if !marked[y * w + x] {
                continue;
            }
            for yy in y.saturating_sub(radius)..(y + radius + 1).min(h) {
                for xx in x.saturating_sub(radius)..(x + radius + 1).min(w) {
                    near[yy * w + xx] = true;
                }
            }
        }
    }
    near
}

/// The error of luminances `ya` against the reference's `yb` split at `yb`'s sharp edges.
pub fn edge_split(ya: &[f64], yb: &[f64], w: usize, h: usize) -> EdgeSplit {
    split_at(ya, yb, &near_edges(yb, w, h))
}

/// The error of luminances `ya` against `yb` split at the pixels `near` marks (any mask of the
/// same length: near sharp edges, near shadow boundaries).
pub fn split_at(ya: &[f64], yb: &[f64], near: &[bool]) -> EdgeSplit {
    let (mut sq_near, mut sq_far, mut n_near) = (0.0f64, 0.0f64, 0usize);
    for ((p, q), &m) in ya.iter().zip(yb).zip(near) {
        let d = (p - q) * (p - q);
        if m {
            sq_near += d;
            n_near += 1;
        } else {
            sq_far += d;
        }
    }
    let n_far = ya.len() - n_near;
    let total = sq_near + sq_far;
    EdgeSplit {
        near_pixels: n_near,
        near_share: if total > 0.0 { sq_near / total } else { 0.0 },
        rmse_near: if n_near > 0 {
            (sq_near / n_near as f64).sqrt()
        } else {
            0.0
        },
        rmse_far: if n_far > 0 {
            (sq_far / n_far as f64).sqrt()
        } else {
            0.0
        },
    }
}

/// The error of luminances `ya` against a reference known only through two independent noisy
/// estimates `yb1` and `yb2` (two path-traced images at different seeds), split at `near`.
///
/// The mean of `(Y_a - Y_b1) (Y_a - Y_b2)` over a set of pixels is an unbiased estimate of the
/// mean squared error against the noise-free reference: the two noises are independent with
/// mean zero, so their product and their cross terms with the error vanish in expectation,
/// where `(Y_a - Y_b1)^2` would add the reference's variance. Its standard error comes from the
/// products' spread. The RMSEs are the square roots of the estimates, clamped at 0 (noise can
/// make an estimate of a small error negative).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CrossSplit {
    /// Pixels in the set.
    pub near_pixels: usize,
    /// RMSE estimate in the set.
    pub rmse_near: f64,
    /// RMSE estimate outside the set.
    pub rmse_far: f64,
    /// Standard error of the mean squared error whose root `rmse_near` is.
    pub squared_se_near: f64,
    /// Standard error of the mean squared error whose root `rmse_far` is.
    pub squared_se_far: f64,
}

/// [`CrossSplit`] of `ya` against the reference estimates `yb1` and `yb2`, split at `near`.
pub fn cross_split_at(ya: &[f64], yb1: &[f64], yb2: &[f64], near: &[bool]) -> CrossSplit {
    // Per side: count, sum and sum of squares of the products.
    let mut acc = [(0usize, 0.0f64, 0.0f64); 2];
    for (((a, b1), b2), &m) in ya.iter().zip(yb1).zip(yb2).zip(near) {
        let q = (a - b1) * (a - b2);
        let side = &mut acc[usize::from(!m)];
        side.0 += 1;
        side.1 += q;
        side.2 += q * q;
    }
    let stats = |(n, sum, sq): (usize, f64, f64)| {
        if n == 0 {
            return (0.0, 0.0);
        }
        let nf = n as f64;
        let mean = sum / nf;
        let var = if n > 1 {
            ((sq - sum * mean) / (nf - 1.0)).max(0.0)
        } else {
            0.0
        };
        (mean.max(0.0).sqrt(), (var / nf).sqrt())
    };
    let (near_rmse, near_se) = stats(acc[0]);
    let (far_rmse, far_se) = stats(acc[1]);
    CrossSplit {
        near_pixels: acc[0].0,
        rmse_near: near_rmse,
        rmse_far: far_rmse,
        squared_se_near: near_se,
        squared_se_far: far_se,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A vertical step at x = 5 in a 12 x 3 reference: columns 4 and 5 are the edge, 2..=7
    /// near it (radius 2); an error of 1 on column 3 and of 2 on column 10 splits 1 : 4 per
    /// row.
    #[test]
    fn a_step_and_its_band() {
        let (w, h) = (12, 3);
        let yb: Vec<f64> = (0..w * h)
            .map(|i| if i % w < 5 { 1.0 } else { 2.0 })
            .collect();
        let near = near_edges(&yb, w, h);
        for (i, &n) in near.iter().enumerate() {
            assert_eq!(n, (2..=7).contains(&(i % w)), "pixel {i}");
        }
        let mut ya = yb.clone();
        for y in 0..h {
            ya[y * w + 3] += 1.0;
            ya[y * w + 10] += 2.0;
        }
        let s = edge_split(&ya, &yb, w, h);
        assert_eq!(s.near_pixels, 18);
        assert!((s.near_share - 0.2).abs() < 1e-15);
        assert!((s.rmse_near - (3.0f64 / 18.0).sqrt()).abs() < 1e-15);
        assert!((s.rmse_far - (12.0f64 / 18.0).sqrt()).abs() < 1e-15);
    }

    /// A jump below the floor or below the relative threshold is no edge; equal images share 0.
    #[test]
    fn small_jumps_are_not_edges() {
        assert!(is_edge(0.1, 0.2, 0.15));
        assert!(!is_edge(0.1, 0.2, 0.25), "below the floor");
        assert!(!is_edge(1.0, 1.2, 0.0), "a 17 % step");
        assert!(!is_edge(0.0, 0.0, 0.0));
        let yb = vec![1.0, 1.2, 1.44, 1.2, 1.0];
        assert!(near_edges(&yb, 5, 1).iter().all(|&n| !n));
        let s = edge_split(&yb, &yb, 5, 1);
        assert_eq!((s.near_share, s.rmse_near, s.rmse_far), (0.0, 0.0, 0.0));
    }

    /// Two noisy references of a known image: the cross estimate recovers an error the noise
    /// hides. The reference is 1 everywhere, the image 1.01 inside the mask (an error of 0.01)
    /// and exact outside; the references carry independent noise of +-0.05 (five times the
    /// error). Squared against one reference, the noise swamps the error; the cross estimate
    /// gives 0.01 inside and 0 outside, to its own standard errors.
    #[test]
    fn two_references_take_their_noise_out() {
        let n = 80_000;
        let mut rng = base::rng::Rng::new(7);
        let mut noise = || 0.05 * (2.0 * rng.next_f64() - 1.0) * 3f64.sqrt();
        let near: Vec<bool> = (0..n).map(|i| i % 4 == 0).collect();
        let ya: Vec<f64> = near.iter().map(|&m| if m { 1.01 } else { 1.0 }).collect();
        let yb1: Vec<f64> = (0..n).map(|_| 1.0 + noise()).collect();
        let yb2: Vec<f64> = (0..n).map(|_| 1.0 + noise()).collect();
        let single = split_at(&ya, &yb1, &near);
        assert!(single.rmse_near > 0.04, "{single:?}");
        let c = cross_split_at(&ya, &yb1, &yb2, &near);
        assert_eq!(c.near_pixels, n / 4);
        // 0.01^2 = 1e-4 inside, 0 outside, each within 4 standard errors.
        let sq_near = c.rmse_near * c.rmse_near;
        assert!((sq_near - 1e-4).abs() <= 4.0 * c.squared_se_near, "{c:?}");
        assert!(c.rmse_far * c.rmse_far <= 4.0 * c.squared_se_far, "{c:?}");
        assert!(
            c.squared_se_near < 3e-5,
            "the estimate resolves the error: {c:?}"
        );
    }
}
