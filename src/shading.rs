//! Shading: the deferred pass, the last stage before the image is written. It reads only a
//! composited region G-buffer ([`RegionGBuffer`]: per sample a polygon id, (u, v) and a slot into
//! the region-local patch table) and evaluates the bicubic radiosity reconstruction patch (RRP) of
//! each sample, then resolves the samples of each pixel with a box filter. It never sees the scene,
//! as PixelFlow's shader boards never saw it: everything a sample needs was written into the region
//! by the rasterizer, so shading cost depends on pixels, not on scene complexity.
//!
//! Invariants: a patch is a power-basis bicubic over local (s, t) in [0, 1]^2; a sample with
//! [`NO_POLYGON`] takes the background colour; the result is a finite linear RGB value per pixel.
//!
//! Why it is built this way: neighbouring samples nearly always share one patch, so each run of 8
//! samples with the same slot is evaluated with the patch's 48 coefficients broadcast over 8 lanes
//! (Horner in s for each of the 4 rows, then Horner in t: 15 multiply-adds per channel per lane,
//! in fixed-width `[f32; 8]` loops the compiler vectorizes); blocks that mix patches or contain
//! empty samples fall back to the same arithmetic one lane at a time. Both paths perform the same
//! IEEE operations in the same order (Rust never contracts `a * b + c` into an FMA), so which path a
//! sample takes never changes its bits.
//!
//! Antialiasing filter: every pixel's N samples (see [`crate::raster::sample_offsets`]) are
//! averaged with equal weights, a box filter over the pixel's own square; samples that see nothing
//! contribute the background colour.

// Lane loops index several fixed-width arrays with one lane index on purpose: that is the form
// the compiler vectorizes and the reader checks lane by lane.
#![allow(clippy::needless_range_loop)]

use glam::Vec3;
use rayon::prelude::*;

use crate::raster::gbuffer::{RegionGBuffer, NO_POLYGON};

/// One bicubic patch in power basis over local (s, t) in [0,1]^2, s = (u - u0) * inv_w,
/// t = (v - v0) * inv_w: f_ch(s,t) = sum_{i,j<4} c[ch][4*j + i] * s^i * t^j.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(16))]
pub struct PatchCoeffs {
    /// Coefficients per channel (R, G, B), index `4 * j + i` multiplies s^i t^j.
    pub c: [[f32; 16]; 3],
    /// Parameter u of the patch's corner (s = 0).
    pub u0: f32,
    /// Parameter v of the patch's corner (t = 0).
    pub v0: f32,
    /// Reciprocal of the patch's side in (u, v).
    pub inv_w: f32,
    /// Padding to a multiple of 16 bytes.
    pub _pad: f32,
}

impl PatchCoeffs {
    /// A patch over the whole polygon domain (u0 = v0 = 0, side 1) with the given coefficients.
    pub fn whole(c: [[f32; 16]; 3]) -> PatchCoeffs {
        PatchCoeffs {
            c,
            u0: 0.0,
            v0: 0.0,
            inv_w: 1.0,
            _pad: 0.0,
        }
    }

    /// The local coordinates (s, t) of (u, v).
    #[inline(always)]
    pub fn local(&self, u: f32, v: f32) -> (f32, f32) {
        ((u - self.u0) * self.inv_w, (v - self.v0) * self.inv_w)
    }

    /// Whether (u, v) lies strictly inside the patch's square, farther than `margin` (in local
    /// units) from its sides.
    #[inline]
    pub fn contains_strictly(&self, u: f32, v: f32, margin: f32) -> bool {
        let (s, t) = self.local(u, v);
        s > margin && s < 1.0 - margin && t > margin && t < 1.0 - margin
    }

    /// Evaluates the patch at (u, v), the arithmetic of the vectorized path on one lane.
    #[inline(always)]
    pub fn eval(&self, u: f32, v: f32) -> Vec3 {
        let (s, t) = self.local(u, v);
        Vec3::new(
            eval_channel(&self.c[0], s, t),
            eval_channel(&self.c[1], s, t),
            eval_channel(&self.c[2], s, t),
        )
    }
}

/// What the direct method needs from a reconstruction.
pub trait PatchSource: Sync {
    /// Global id of the patch covering (u, v) of scene polygon `polygon`; (u, v) in [0,1]^2.
    fn locate(&self, polygon: u32, u: f32, v: f32) -> u32;
    /// The coefficients of patch `id`.
    fn patch(&self, id: u32) -> &PatchCoeffs;
}

/// Horner's scheme: rows in s, then the rows in t.
#[inline(always)]
fn eval_channel(k: &[f32; 16], s: f32, t: f32) -> f32 {
    let r = |j: usize| ((k[4 * j + 3] * s + k[4 * j + 2]) * s + k[4 * j + 1]) * s + k[4 * j];
    ((r(3) * t + r(2)) * t + r(1)) * t + r(0)
}

/// Lanes per block of the deferred pass.
pub const LANES: usize = 8;

/// Evaluates one channel for 8 lanes with broadcast coefficients; same operations as
/// [`eval_channel`].
#[inline(always)]
fn eval_channel8(k: &[f32; 16], s: &[f32; LANES], t: &[f32; LANES]) -> [f32; LANES] {
    let mut out = [0.0f32; LANES];
    for l in 0..LANES {
        let (s, t) = (s[l], t[l]);
        let r3 = ((k[15] * s + k[14]) * s + k[13]) * s + k[12];
        let r2 = ((k[11] * s + k[10]) * s + k[9]) * s + k[8];
        let r1 = ((k[7] * s + k[6]) * s + k[5]) * s + k[4];
        let r0 = ((k[3] * s + k[2]) * s + k[1]) * s + k[0];
        out[l] = ((r3 * t + r2) * t + r1) * t + r0;
    }
    out
}

/// Counters of one shading pass.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ShadeCounts {
    /// Samples that saw a polygon and were evaluated.
    pub samples_shaded: u64,
    /// Blocks of 8 evaluated with one broadcast patch.
    pub uniform_blocks: u64,
    /// Blocks evaluated lane by lane.
    pub mixed_blocks: u64,
}

/// Shades one composited region: returns its `width * height` resolved linear pixels (row-major,
/// row 0 at the region's top) and the counters.
pub fn shade_region(gb: &RegionGBuffer, background: Vec3) -> (Vec<Vec3>, ShadeCounts) {
    let (w, h, stride) = (gb.width as usize, gb.height as usize, gb.stride as usize);
    let plane = stride * h;
    let mut acc = vec![[0.0f32; 3]; plane];
    let mut counts = ShadeCounts::default();
    let bg = background.to_array();
    for si in 0..gb.samples as usize {
        for y in 0..h {
            let row = si * plane + y * stride;
            for bx in (0..w).step_by(LANES) {
                let i0 = row + bx;
                let polys: &[u32; LANES] = gb.polygon[i0..i0 + LANES].try_into().unwrap();
                let slots: &[u32; LANES] = gb.slot[i0..i0 + LANES].try_into().unwrap();
                let us: &[f32; LANES] = gb.u[i0..i0 + LANES].try_into().unwrap();
                let vs: &[f32; LANES] = gb.v[i0..i0 + LANES].try_into().unwrap();
                let dst = &mut acc[y * stride + bx..y * stride + bx + LANES];
                let uniform =
                    polys.iter().all(|&p| p != NO_POLYGON) && slots.iter().all(|&s| s == slots[0]);
                if uniform {
                    counts.uniform_blocks += 1;
                    counts.samples_shaded += LANES as u64;
                    let p = &gb.table[slots[0] as usize];
                    let mut s = [0.0f32; LANES];
                    let mut t = [0.0f32; LANES];
                    for l in 0..LANES {
                        s[l] = (us[l] - p.u0) * p.inv_w;
                        t[l] = (vs[l] - p.v0) * p.inv_w;
                    }
                    for ch in 0..3 {
                        let r = eval_channel8(&p.c[ch], &s, &t);
                        for l in 0..LANES {
                            dst[l][ch] += r[l];
                        }
                    }
                } else {
                    counts.mixed_blocks += 1;
                    for l in 0..LANES {
                        let c = if polys[l] == NO_POLYGON {
                            bg
                        } else {
                            counts.samples_shaded += 1;
                            gb.table[slots[l] as usize].eval(us[l], vs[l]).to_array()
                        };
                        for ch in 0..3 {
                            dst[l][ch] += c[ch];
                        }
                    }
                }
            }
        }
    }
    // Box filter: equal weights over the pixel's samples. Padding lanes beyond the region's width
    // hold NO_POLYGON (the rasterizer masks them), so they are never counted, and never read here.
    let inv = 1.0 / gb.samples as f32;
    let mut out = Vec::with_capacity(w * h);
    for y in 0..h {
        for x in 0..w {
            let a = acc[y * stride + x];
            out.push(sanitize(Vec3::new(a[0] * inv, a[1] * inv, a[2] * inv)));
        }
    }
    (out, counts)
}

/// Replaces a non-finite channel by 0 (documented clamp: a patch source with non-finite
/// coefficients must not put NaN or inf into an image).
#[inline]
fn sanitize(c: Vec3) -> Vec3 {
    Vec3::select(c.is_finite_mask(), c, Vec3::ZERO)
}

/// The deferred pass over many regions in parallel (rayon, one task per region): each region's
/// resolved pixels, in the order of `regions`, and the summed counters.
pub fn shade_regions(regions: &[RegionGBuffer], background: Vec3) -> (Vec<Vec<Vec3>>, ShadeCounts) {
    let results: Vec<(Vec<Vec3>, ShadeCounts)> = regions
        .par_iter()
        .map(|gb| shade_region(gb, background))
        .collect();
    let mut total = ShadeCounts::default();
    let mut out = Vec::with_capacity(results.len());
    for (px, c) in results {
        total.samples_shaded += c.samples_shaded;
        total.uniform_blocks += c.uniform_blocks;
        total.mixed_blocks += c.mixed_blocks;
        out.push(px);
    }
    (out, total)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn poly_patch() -> PatchCoeffs {
        let mut c = [[0.0f32; 16]; 3];
        for (ch, row) in c.iter_mut().enumerate() {
            for (k, x) in row.iter_mut().enumerate() {
                *x = ((k * 7 + ch * 3) % 11) as f32 * 0.125 - 0.5;
            }
        }
        PatchCoeffs {
            c,
            u0: 0.25,
            v0: 0.5,
            inv_w: 4.0,
            _pad: 0.0,
        }
    }

    #[test]
    fn horner_matches_the_power_basis_sum() {
        let p = poly_patch();
        for &(u, v) in &[(0.25, 0.5), (0.3, 0.6), (0.5, 0.75), (0.41, 0.52)] {
            let (s, t) = ((u - 0.25) * 4.0f64, (v - 0.5) * 4.0f64);
            let got = p.eval(u as f32, v as f32);
            for ch in 0..3 {
                let mut want = 0.0f64;
                for j in 0..4 {
                    for i in 0..4 {
                        want += p.c[ch][4 * j + i] as f64 * s.powi(i as i32) * t.powi(j as i32);
                    }
                }
                // |coefficients| <= 0.75, 16 terms, s, t <= 1: f32 rounding stays below 1e-5.
                assert!(
                    (got[ch] as f64 - want).abs() < 1e-5,
                    "{ch}: {} vs {want}",
                    got[ch]
                );
            }
        }
    }

    #[test]
    fn lane_path_and_scalar_path_agree_bit_for_bit() {
        let p = poly_patch();
        let s: [f32; 8] = std::array::from_fn(|l| l as f32 * 0.13);
        let t: [f32; 8] = std::array::from_fn(|l| 1.0 - l as f32 * 0.11);
        let r = eval_channel8(&p.c[1], &s, &t);
        for l in 0..8 {
            assert_eq!(r[l].to_bits(), eval_channel(&p.c[1], s[l], t[l]).to_bits());
        }
    }
}
