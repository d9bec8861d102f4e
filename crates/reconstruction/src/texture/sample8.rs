//! Texture filtering 8 samples at a time: the lane form of [`Sampler::sample`] that the deferred
//! pass uses for radiosity textures (RAT), so that the texture method runs the same kind of inner
//! loop as the direct method's broadcast patch evaluation: fixed-width [`F32x8`] lanes, compiled
//! for the instruction set of the kernel they are inlined into, with the texel gather the one
//! operation taken from the token ([`Simd::gather_rgb8`]).
//!
//! Per block of 8 samples of one texture: the level of detail, the level choice, the texel
//! coordinates, the fractions and the filter weights are computed lane-wise; the texels are
//! gathered with scalar loads (row base + clamped column, one `Vec3` per texel and lane) into
//! per-channel lane arrays and blended lane-wise. Lanes are grouped by mip level; under
//! magnification (the usual case) all lanes share level 0 and one filter pass serves the block,
//! without the trilinear second level.
//!
//! Invariant: every lane performs the same IEEE operations in the same order as the scalar
//! [`Sampler::sample`] (clamp of (u, v), `x = u n - 0.5` or `x = u (n - 1)` by the texture's
//! [`Placement`], `floor`, the cubic weights by Horner,
//! the row-then-column sums starting from 0, the level blend `a + (b - a) f`), so a lane's result
//! has the same bits as the scalar call: the lane path is an implementation detail, not a new
//! filter. Texel indices are clamped to the stored level, gutters included (clamp-to-edge
//! addressing past the gutter), so every load is in bounds and every result finite.

// Lane loops index several fixed-width arrays with one lane index on purpose: that is the form
// the compiler vectorizes and the reader checks lane by lane.
#![allow(clippy::needless_range_loop)]

use glam::Vec3;

use super::MipLevel;
use super::{lod_from_squares, Cubic, Filter, Placement, RadiosityTexture, Sampler};
use lanes::{F32x8, Simd, LANES};

/// Three channels of 8 lanes (r, g, b).
pub type Rgb8 = [F32x8; 3];

/// Loads texel `idx[l]` of `texels` into lane l of each channel, by the token's gather.
///
/// Safety: every `idx[l]` must be a valid index of `texels` (the callers build the indices from
/// clamped rows and columns of a level whose `texels.len() == width * height`, see
/// [`check_level`]).
#[inline(always)]
unsafe fn gather<S: Simd>(s: S, texels: &[Vec3], idx: &[i32; LANES]) -> Rgb8 {
    // SAFETY: the caller guarantees 0 <= idx[l] < texels.len().
    unsafe { s.gather_rgb8(texels, idx) }
}

/// The level invariant the unchecked gathers rely on: `texels.len() == stride * rows`
/// ([`MipLevel::stride`], [`MipLevel::rows`]), both sides at least 1, and every stored index
/// within i32. Holds for every level [`RadiosityTexture`] builds (sides are powers of two up to
/// [`super::MAX_TEXTURE_SIZE`] = 2^12 plus at most [`super::MAX_GUTTER`] texels each way);
/// checked once per level and block.
#[inline(always)]
fn check_level(lv: &MipLevel) {
    let n = lv.stride() as usize * lv.rows() as usize;
    assert!(
        lv.width >= 1 && lv.height >= 1 && n <= i32::MAX as usize && lv.texels.len() == n,
        "mip level of {} x {} (gutter {}) with {} texels",
        lv.width,
        lv.height,
        lv.gutter,
        lv.texels.len()
    );
}

/// Lane-wise `floor` (a loop, not a closure: closures do not inherit the caller's target
/// features, and a non-inlined `floor` would be a library call per lane).
#[inline(always)]
fn floor8(x: F32x8) -> F32x8 {
    let mut r = [0.0f32; LANES];
    for l in 0..LANES {
        r[l] = x.0[l].floor();
    }
    F32x8(r)
}

/// Lane form of `split` in the float domain: x = u scale - offset ([`Placement::texel_map`]:
/// u n - 0.5 for centres, u (n - 1) for corners), returns (floor(x), x - floor(x)). With u in
/// [0, 1], floor(x) is an integer in [-1, n - 1], exact in f32.
#[inline(always)]
fn split8(u: F32x8, n: u32, p: Placement) -> (F32x8, F32x8) {
    let (scale, offset) = p.texel_map(n);
    let x = u * F32x8::splat(scale) - F32x8::splat(offset);
    let f = floor8(x);
    (f, x - f)
}

/// `i + off` clamped per lane into [0, max] (clamp-to-edge addressing), computed on the exact
/// small integers that f32 holds, so it equals the scalar code's integer clamp. Written as
/// compares and selects (one `vmaxps` and one `vminps` each) rather than `f32::max` / `min`,
/// whose NaN rule the compiler spells out in extra compares and blends: the values here are
/// finite integers, where both forms agree.
#[inline(always)]
fn clamp_index(i: F32x8, off: f32, max: f32) -> F32x8 {
    let mut r = [0.0f32; LANES];
    for l in 0..LANES {
        let a = i.0[l] + off;
        let a = if a > 0.0 { a } else { 0.0 };
        r[l] = if a < max { a } else { max };
    }
    F32x8(r)
}

/// Lane form of `clamp01`: NaN to 0, else clamped into [0, 1], as compares and selects (the
/// same values, -0.0 kept as `clamp` keeps it).
#[inline(always)]
fn clamp01_8(x: F32x8) -> F32x8 {
    let mut r = [0.0f32; LANES];
    for l in 0..LANES {
        let v = x.0[l];
        let hi = if v <= 1.0 { v } else { 1.0 };
        r[l] = if v >= 0.0 { hi } else { 0.0 };
    }
    F32x8(r)
}

/// `row * stride + col` per lane as an integer texel index, from a clamped stored row and
/// column (exact small integers in f32, converted first and combined in i32: a level with
/// gutters can hold more than 2^24 texels, past f32's exact integers).
#[inline(always)]
fn index(row: F32x8, stride: i32, col: F32x8) -> [i32; LANES] {
    let mut r = [0i32; LANES];
    for l in 0..LANES {
        // SAFETY: row and column are integers in [0, 2^13), representable in i32.
        let (y, x) = unsafe {
            (
                row.0[l].to_int_unchecked::<i32>(),
                col.0[l].to_int_unchecked::<i32>(),
            )
        };
        r[l] = y * stride + x;
    }
    r
}

/// Lane form of `nearest_index`: floor(u scale + (0.5 - offset)) (floor(u n) for centres),
/// as a stored index (shifted by the gutter `g`) clamped to the square's n texels: the nearest
/// texel of a clamped coordinate is never a gutter texel.
#[inline(always)]
fn nearest_index8(u: F32x8, n: u32, p: Placement, g: f32) -> F32x8 {
    let (scale, offset) = p.texel_map(n);
    let x = u * F32x8::splat(scale) + F32x8::splat(0.5 - offset);
    clamp_index(floor8(x), g, g + n as f32 - 1.0)
}

/// Lane form of `nearest`.
#[inline(always)]
fn nearest8<S: Simd>(simd: S, lv: &MipLevel, p: Placement, u: F32x8, v: F32x8) -> Rgb8 {
    check_level(lv);
    let g = lv.gutter as f32;
    let i = nearest_index8(u, lv.width, p, g);
    let j = nearest_index8(v, lv.height, p, g);
    // SAFETY: clamped row and column of a level checked by check_level.
    unsafe { gather(simd, &lv.texels, &index(j, lv.stride() as i32, i)) }
}

/// Lane form of `bilinear`.
#[inline(always)]
fn bilinear8<S: Simd>(simd: S, lv: &MipLevel, p: Placement, u: F32x8, v: F32x8) -> Rgb8 {
    check_level(lv);
    let g = lv.gutter as f32;
    let (w, h, stride) = (lv.stride() as f32, lv.rows() as f32, lv.stride() as i32);
    let (i, s) = split8(u, lv.width, p);
    let (j, t) = split8(v, lv.height, p);
    let (c0, c1) = (clamp_index(i, g, w - 1.0), clamp_index(i, g + 1.0, w - 1.0));
    let (r0, r1) = (clamp_index(j, g, h - 1.0), clamp_index(j, g + 1.0, h - 1.0));
    // SAFETY: clamped rows and columns of a level checked by check_level.
    let (t00, t10, t01, t11) = unsafe {
        (
            gather(simd, &lv.texels, &index(r0, stride, c0)),
            gather(simd, &lv.texels, &index(r0, stride, c1)),
            gather(simd, &lv.texels, &index(r1, stride, c0)),
            gather(simd, &lv.texels, &index(r1, stride, c1)),
        )
    };
    let one = F32x8::splat(1.0);
    let (s1, t1) = (one - s, one - t);
    let mut r = [F32x8::splat(0.0); 3];
    for ch in 0..3 {
        let a = t00[ch] * s1 + t10[ch] * s;
        let b = t01[ch] * s1 + t11[ch] * s;
        r[ch] = a * t1 + b * t;
    }
    r
}

/// Lane form of [`Cubic::weights`]: k(1 + t), k(t), k(1 - t), k(2 - t).
#[inline(always)]
fn weights8(k: &Cubic, t: F32x8) -> [F32x8; 4] {
    let one = F32x8::splat(1.0);
    [
        cubic8(&k.far, one + t),
        cubic8(&k.near, t),
        cubic8(&k.near, one - t),
        cubic8(&k.far, F32x8::splat(2.0) - t),
    ]
}

/// ((p0 a + p1) a + p2) a + p3 per lane (a function, not a closure: a closure is compiled without
/// the target features of the kernel it is written in unless it is inlined).
#[inline(always)]
fn cubic8(p: &[f32; 4], a: F32x8) -> F32x8 {
    let c = F32x8::splat;
    ((c(p[0]) * a + c(p[1])) * a + c(p[2])) * a + c(p[3])
}

/// Lane form of `bicubic`: per row j - 1 .. j + 2 the 4 clamped columns are gathered and
/// filtered with the u weights, then accumulated (from 0, as the scalar code) with the v weight.
#[inline(always)]
fn bicubic8<S: Simd>(simd: S, lv: &MipLevel, p: Placement, u: F32x8, v: F32x8, k: &Cubic) -> Rgb8 {
    check_level(lv);
    let g = lv.gutter as f32;
    let (w, h, stride) = (lv.stride() as f32, lv.rows() as f32, lv.stride() as i32);
    let (i, s) = split8(u, lv.width, p);
    let (j, t) = split8(v, lv.height, p);
    let wu = weights8(k, s);
    let wv = weights8(k, t);
    let cols = [
        clamp_index(i, g - 1.0, w - 1.0),
        clamp_index(i, g, w - 1.0),
        clamp_index(i, g + 1.0, w - 1.0),
        clamp_index(i, g + 2.0, w - 1.0),
    ];
    let mut acc = [F32x8::splat(0.0); 3];
    for (b, &wy) in wv.iter().enumerate() {
        let row = clamp_index(j, g + b as f32 - 1.0, h - 1.0);
        // SAFETY: clamped rows and columns of a level checked by check_level.
        let tx = unsafe {
            [
                gather(simd, &lv.texels, &index(row, stride, cols[0])),
                gather(simd, &lv.texels, &index(row, stride, cols[1])),
                gather(simd, &lv.texels, &index(row, stride, cols[2])),
                gather(simd, &lv.texels, &index(row, stride, cols[3])),
            ]
        };
        for ch in 0..3 {
            let h = tx[0][ch] * wu[0] + tx[1][ch] * wu[1] + tx[2][ch] * wu[2] + tx[3][ch] * wu[3];
            acc[ch] = acc[ch] + h * wy;
        }
    }
    acc
}

impl Sampler {
    /// Filters one level for 8 lanes of already clamped coordinates.
    #[inline(always)]
    fn level8<S: Simd>(&self, simd: S, lv: &MipLevel, p: Placement, u: F32x8, v: F32x8) -> Rgb8 {
        // One instance per placement, so that the texel map is a constant in each and the
        // centre instance is the code without placements (a run-time placement in the lane
        // loops made the deferred pass about 1.5x slower).
        match p {
            Placement::Centre => self.level8_at::<S, false>(simd, lv, u, v),
            Placement::Corner => self.level8_at::<S, true>(simd, lv, u, v),
        }
    }

    /// [`Sampler::level8`] for the placement `CORNER` selects.
    #[inline(always)]
    fn level8_at<S: Simd, const CORNER: bool>(
        &self,
        simd: S,
        lv: &MipLevel,
        u: F32x8,
        v: F32x8,
    ) -> Rgb8 {
        let p = if CORNER {
            Placement::Corner
        } else {
            Placement::Centre
        };
        match self.filter {
            Filter::Nearest => nearest8(simd, lv, p, u, v),
            Filter::Bilinear => bilinear8(simd, lv, p, u, v),
            Filter::Bicubic { .. } => bicubic8(simd, lv, p, u, v, &self.cubic),
        }
    }

    /// The lane form of [`Sampler::sample`]: lane l of the result has the bits of
    /// `self.sample(tex, lod_from_squares(lx2[l], ly2[l], tex.last_level()), u[l], v[l])` for
    /// every lane with `mask[l]`; lanes without it hold unspecified finite values (their
    /// coordinates are still clamped, so they cost no more than a masked lane would).
    ///
    /// `lx2` and `ly2` are the squared footprint lengths in level-0 texels per pixel (see
    /// [`lod_from_squares`]). Lanes are processed in groups of equal mip level: one filter pass
    /// per distinct level in the block, plus one for the next level when a lane of the group
    /// blends two levels (bilinear and bicubic under minification).
    ///
    /// The texels are gathered with the token `simd`; every other operation is the same for every
    /// token, so the result does not depend on it.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub fn sample8<S: Simd>(
        &self,
        simd: S,
        tex: &RadiosityTexture,
        lx2: F32x8,
        ly2: F32x8,
        u: F32x8,
        v: F32x8,
        mask: &[bool; LANES],
    ) -> Rgb8 {
        let last = tex.last_level();
        let (uc, vc) = (clamp01_8(u), clamp01_8(v));
        // Every lane magnified (the footprint at most one texel, or NaN): level 0 for every
        // lane, as the per-lane loop below finds (`lod_from_squares` returns 0 without a
        // logarithm), decided in lanes and the loop skipped. One call of `level8` serves both
        // (every further call site inlines every filter again per instruction set).
        // `max(lx2, ly2) <= 1 or NaN` (f32::max skips a NaN) is `!(lx2 > 1 or ly2 > 1)`: plain
        // compares, which the compiler keeps in lanes.
        let mut large = [false; LANES];
        for l in 0..LANES {
            large[l] = mask[l] & ((lx2.0[l] > 1.0) | (ly2.0[l] > 1.0));
        }
        let small = !large.iter().fold(false, |a, &b| a | b);
        let nearest = matches!(self.filter, Filter::Nearest);
        let mut level = [0usize; LANES];
        let mut frac = [0.0f32; LANES];
        let mut blend = [false; LANES];
        let mut magnified = true;
        if !small {
            for l in 0..LANES {
                if !mask[l] {
                    continue;
                }
                let lod = lod_from_squares(lx2.0[l], ly2.0[l], last);
                if lod == 0.0 {
                    // d = 0: level 0 for every filter, no blend (the scalar code's f <= 0 exit).
                    continue;
                }
                magnified = false;
                let d = if lod.is_nan() {
                    0.0
                } else {
                    lod.clamp(0.0, last as f32)
                };
                // SAFETY (both conversions): d is in [0, last] (NaN mapped to 0, then clamped)
                // and `last` is below a chain's level count (13 at most: sides up to
                // `MAX_TEXTURE_SIZE`), so its rounding and floor are small integers in i32;
                // `as usize` would add a saturating range check per lane.
                if nearest {
                    level[l] = (unsafe { d.round().to_int_unchecked::<i32>() } as usize).min(last);
                } else {
                    let l0 = (unsafe { d.floor().to_int_unchecked::<i32>() } as usize).min(last);
                    level[l] = l0;
                    frac[l] = d - l0 as f32;
                    blend[l] = !((frac[l] <= 0.0) | (l0 == last));
                }
            }
        }
        if magnified {
            return self.level8(simd, &tex.levels[0], tex.placement, uc, vc);
        }
        // Minified: one call site of the filter for every group of lanes that share a mip level
        // (three filters x two placements inlined once more per instruction set, not twice).
        // The first pass of a group filters its own level, the second (when a lane of the
        // group blends) the next one. Written as one loop with a pass flag: a nested
        // `for pass in 0..2` reads more plainly but costs 4 % more instructions in the texture
        // pass (callgrind, cornell-box at 512^2) and brings the second copy back.
        let mut out = [F32x8::splat(0.0); 3];
        let mut done = [false; LANES];
        for l in 0..LANES {
            done[l] = !mask[l];
        }
        let mut group = next_group(&mut done, &level, &blend);
        let mut a = [F32x8::splat(0.0); 3];
        let mut second = false;
        while let Some((lv, m, any_blend)) = group {
            let filtered = self.level8(
                simd,
                &tex.levels[lv + second as usize],
                tex.placement,
                uc,
                vc,
            );
            if !second {
                a = filtered;
            } else {
                let f = F32x8(frac);
                for ch in 0..3 {
                    a[ch] = F32x8::select(&blend, a[ch] + (filtered[ch] - a[ch]) * f, a[ch]);
                }
            }
            if any_blend && !second {
                second = true;
                continue;
            }
            for ch in 0..3 {
                out[ch] = F32x8::select(&m, a[ch], out[ch]);
            }
            second = false;
            group = next_group(&mut done, &level, &blend);
        }
        out
    }
}

/// The next group of lanes not yet `done` that share the first such lane's mip level: (level,
/// the group's lanes, whether any of them blends with the next level); the group is marked done.
#[inline(always)]
fn next_group(
    done: &mut [bool; LANES],
    level: &[usize; LANES],
    blend: &[bool; LANES],
) -> Option<(usize, [bool; LANES], bool)> {
    let first = done.iter().position(|&d| !d)?;
    let lv = level[first];
    let mut m = [false; LANES];
    let mut any_blend = false;
    for l in 0..LANES {
        m[l] = !done[l] & (level[l] == lv);
        done[l] |= m[l];
        any_blend |= m[l] & blend[l];
    }
    Some((lv, m, any_blend))
}
