//! Texture filtering 8 samples at a time: the lane form of [`Sampler::sample`] that the deferred
//! pass uses for radiosity textures (RAT), so that the texture method runs the same kind of inner
//! loop as the direct method's broadcast patch evaluation: the filters are written on the
//! registers of the token ([`Simd`]) of the kernel they are inlined into, 8 lanes, with the
//! texel fetch ([`Simd::gather_rgb`]) one of its operations.
//!
//! Per block of 8 samples of one texture: a block whose lanes are all magnified (the usual
//! case in a view close to its surfaces) filters level 0 once, without computing a level of
//! detail; otherwise the levels of detail, the level choice and the blend fractions are
//! computed lane-wise on arrays (a branch-free loop the compiler vectorizes, with the
//! logarithm of [`super::log2_above_one`]), and the lanes are grouped by mip level, one filter
//! pass per group plus one for the next level where a lane blends. In a pass the texel
//! coordinates, the clamped indices, the fractions and the filter weights stay in registers.
//! Keeping them there (rather than in lane arrays the compiler spilled between steps) cut the
//! pass's instructions by a third; its time is mostly the texel fetch.
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

use super::MipLevel;
use super::{lod_from_squares, Cubic, Filter, Placement, RadiosityTexture, Sampler};
use lanes::{F32x8, Simd, LANES};

/// Three channels of 8 lanes (r, g, b), as arrays.
pub type Rgb8 = [F32x8; 3];

/// Three channels in the token's registers.
type Rgb<S> = [<S as Simd>::F; 3];

/// The level invariant the unchecked gathers rely on: `texels.len() == stride * rows`
/// ([`MipLevel::stride`], [`MipLevel::rows`]), both sides at least 1, and every stored index
/// (times 3, the gather's float offset) within i32. Holds for every level
/// [`RadiosityTexture`] builds (sides are powers of two up to [`super::MAX_TEXTURE_SIZE`] =
/// 2^12 plus at most [`super::MAX_GUTTER`] texels each way); checked once per level and block.
#[inline(always)]
fn check_level(lv: &MipLevel) {
    let n = lv.stride() as usize * lv.rows() as usize;
    assert!(
        lv.width >= 1 && lv.height >= 1 && 3 * n <= i32::MAX as usize && lv.texels.len() == n,
        "mip level of {} x {} (gutter {}) with {} texels",
        lv.width,
        lv.height,
        lv.gutter,
        lv.texels.len()
    );
}

/// Loads texel `idx[l]` of the level's texels into lane l of each channel, by the token's
/// gather.
///
/// Safety: every lane of `idx` must be a valid index of `lv.texels`, for a level that passed
/// [`check_level`] (the callers build the indices from clamped rows and columns).
#[inline(always)]
unsafe fn gather<S: Simd>(s: S, lv: &MipLevel, idx: S::U) -> Rgb<S> {
    // SAFETY: the caller guarantees 0 <= idx[l] < texels.len(), and check_level that 3 idx + 2
    // fits in i32.
    unsafe { s.gather_rgb(&lv.texels, idx) }
}

/// Lane form of `split`: x = u scale - offset ([`Placement::texel_map`]: u n - 0.5 for
/// centres, u (n - 1) for corners), returns (floor(x), x - floor(x)). With u in [0, 1],
/// floor(x) is an integer in [-1, n - 1], exact in f32.
#[inline(always)]
fn split<S: Simd>(s: S, u: S::F, n: u32, p: Placement) -> (S::F, S::F) {
    let (scale, offset) = p.texel_map(n);
    let x = s.sub(s.mul(u, s.splat(scale)), s.splat(offset));
    let f = s.floor(x);
    (f, s.sub(x, f))
}

/// `i + off` clamped per lane into [0, max] (clamp-to-edge addressing): `if a > 0 { a } else
/// { 0 }`, then `if a < max { a } else { max }`, on the exact small integers that f32 holds, so
/// it equals the scalar code's integer clamp.
#[inline(always)]
fn clamp_index<S: Simd>(s: S, i: S::F, off: f32, max: f32) -> S::F {
    let a = s.add(i, s.splat(off));
    s.min(s.max(a, s.splat(0.0)), s.splat(max))
}

/// `row * stride + col` per lane as an i32 texel index, from a clamped stored row and column
/// (exact small integers in f32, converted first and combined in i32: a level with gutters can
/// hold more than 2^24 texels, past f32's exact integers).
#[inline(always)]
fn index<S: Simd>(s: S, row: S::F, stride: u32, col: S::F) -> S::U {
    s.add_i(s.mul_i(s.to_i32(row), s.splat_u(stride)), s.to_i32(col))
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

/// Lane form of `nearest_index`: floor(u scale + (0.5 - offset)) (floor(u n) for centres),
/// as a stored index (shifted by the gutter `g`) clamped to the square's n texels: the nearest
/// texel of a clamped coordinate is never a gutter texel.
#[inline(always)]
fn nearest_index<S: Simd>(s: S, u: S::F, n: u32, p: Placement, g: f32) -> S::F {
    let (scale, offset) = p.texel_map(n);
    let x = s.add(s.mul(u, s.splat(scale)), s.splat(0.5 - offset));
    clamp_index(s, s.floor(x), g, g + n as f32 - 1.0)
}

/// Lane form of `nearest`.
#[inline(always)]
fn nearest8<S: Simd>(s: S, lv: &MipLevel, p: Placement, u: S::F, v: S::F) -> Rgb<S> {
    check_level(lv);
    let g = lv.gutter as f32;
    let i = nearest_index(s, u, lv.width, p, g);
    let j = nearest_index(s, v, lv.height, p, g);
    // SAFETY: clamped row and column of a level checked by check_level.
    unsafe { gather(s, lv, index(s, j, lv.stride(), i)) }
}

/// Lane form of `bilinear`.
#[inline(always)]
fn bilinear8<S: Simd>(s: S, lv: &MipLevel, p: Placement, u: S::F, v: S::F) -> Rgb<S> {
    check_level(lv);
    let g = lv.gutter as f32;
    let (w, h, stride) = (lv.stride() as f32, lv.rows() as f32, lv.stride());
    let (i, fs) = split(s, u, lv.width, p);
    let (j, ft) = split(s, v, lv.height, p);
    let (c0, c1) = (
        clamp_index(s, i, g, w - 1.0),
        clamp_index(s, i, g + 1.0, w - 1.0),
    );
    let (r0, r1) = (
        clamp_index(s, j, g, h - 1.0),
        clamp_index(s, j, g + 1.0, h - 1.0),
    );
    // SAFETY: clamped rows and columns of a level checked by check_level.
    let (t00, t10, t01, t11) = unsafe {
        (
            gather(s, lv, index(s, r0, stride, c0)),
            gather(s, lv, index(s, r0, stride, c1)),
            gather(s, lv, index(s, r1, stride, c0)),
            gather(s, lv, index(s, r1, stride, c1)),
        )
    };
    let one = s.splat(1.0);
    let (s1, t1) = (s.sub(one, fs), s.sub(one, ft));
    let mut r = [s.splat(0.0); 3];
    for ch in 0..3 {
        let a = s.add(s.mul(t00[ch], s1), s.mul(t10[ch], fs));
        let b = s.add(s.mul(t01[ch], s1), s.mul(t11[ch], fs));
        r[ch] = s.add(s.mul(a, t1), s.mul(b, ft));
    }
    r
}

/// Lane form of [`Cubic::weights`]: k(1 + t), k(t), k(1 - t), k(2 - t).
#[inline(always)]
fn weights8<S: Simd>(s: S, k: &Cubic, t: S::F) -> [S::F; 4] {
    let one = s.splat(1.0);
    [
        cubic8(s, &k.far, s.add(one, t)),
        cubic8(s, &k.near, t),
        cubic8(s, &k.near, s.sub(one, t)),
        cubic8(s, &k.far, s.sub(s.splat(2.0), t)),
    ]
}

/// ((p0 a + p1) a + p2) a + p3 per lane (a function, not a closure: a closure is compiled without
/// the target features of the kernel it is written in unless it is inlined).
#[inline(always)]
fn cubic8<S: Simd>(s: S, p: &[f32; 4], a: S::F) -> S::F {
    let r = s.add(s.mul(s.splat(p[0]), a), s.splat(p[1]));
    let r = s.add(s.mul(r, a), s.splat(p[2]));
    s.add(s.mul(r, a), s.splat(p[3]))
}

/// Lane form of `bicubic`: per row j - 1 .. j + 2 the 4 clamped columns are gathered and
/// filtered with the u weights, then accumulated (from 0, as the scalar code) with the v weight.
#[inline(always)]
fn bicubic8<S: Simd>(s: S, lv: &MipLevel, p: Placement, u: S::F, v: S::F, k: &Cubic) -> Rgb<S> {
    check_level(lv);
    let g = lv.gutter as f32;
    let (w, h, stride) = (lv.stride() as f32, lv.rows() as f32, lv.stride());
    let (i, fs) = split(s, u, lv.width, p);
    let (j, ft) = split(s, v, lv.height, p);
    let wu = weights8(s, k, fs);
    let wv = weights8(s, k, ft);
    let cols = [
        clamp_index(s, i, g - 1.0, w - 1.0),
        clamp_index(s, i, g, w - 1.0),
        clamp_index(s, i, g + 1.0, w - 1.0),
        clamp_index(s, i, g + 2.0, w - 1.0),
    ];
    let mut acc = [s.splat(0.0); 3];
    for (b, &wy) in wv.iter().enumerate() {
        let row = clamp_index(s, j, g + b as f32 - 1.0, h - 1.0);
        // SAFETY: clamped rows and columns of a level checked by check_level.
        let tx = unsafe {
            [
                gather(s, lv, index(s, row, stride, cols[0])),
                gather(s, lv, index(s, row, stride, cols[1])),
                gather(s, lv, index(s, row, stride, cols[2])),
                gather(s, lv, index(s, row, stride, cols[3])),
            ]
        };
        for ch in 0..3 {
            let h = s.add(s.mul(tx[0][ch], wu[0]), s.mul(tx[1][ch], wu[1]));
            let h = s.add(h, s.mul(tx[2][ch], wu[2]));
            let h = s.add(h, s.mul(tx[3][ch], wu[3]));
            acc[ch] = s.add(acc[ch], s.mul(h, wy));
        }
    }
    acc
}

impl Sampler {
    /// Filters one level for 8 lanes of already clamped coordinates.
    #[inline(always)]
    fn level8<S: Simd>(&self, s: S, lv: &MipLevel, p: Placement, u: S::F, v: S::F) -> Rgb<S> {
        // One instance per placement, so that the texel map is a constant in each and the
        // centre instance is the code without placements (a run-time placement in the lane
        // loops made the deferred pass about 1.5x slower).
        match p {
            Placement::Centre => self.level8_at::<S, false>(s, lv, u, v),
            Placement::Corner => self.level8_at::<S, true>(s, lv, u, v),
        }
    }

    /// [`Sampler::level8`] for the placement `CORNER` selects.
    #[inline(always)]
    fn level8_at<S: Simd, const CORNER: bool>(
        &self,
        s: S,
        lv: &MipLevel,
        u: S::F,
        v: S::F,
    ) -> Rgb<S> {
        let p = if CORNER {
            Placement::Corner
        } else {
            Placement::Centre
        };
        match self.filter {
            Filter::Nearest => nearest8(s, lv, p, u, v),
            Filter::Bilinear => bilinear8(s, lv, p, u, v),
            Filter::Bicubic { .. } => bicubic8(s, lv, p, u, v, &self.cubic),
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
    /// The token `simd` has 8 lanes. Every operation is the lane-wise IEEE operation of the
    /// scalar code, so the result does not depend on the token.
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
        const { assert!(S::LANES == LANES, "the sampler works in blocks of 8") };
        let s = simd;
        let last = tex.last_level();
        let (uc, vc) = (s.load(&clamp01_8(u).0), s.load(&clamp01_8(v).0));
        let one = s.splat_u(1);
        let all = s.bits(s.eq_u(s.load_u(&mask.map(u32::from)), one));
        // Every lane magnified (the footprint at most one texel, or NaN): level 0 for every
        // lane without a blend, as `levels8` would find, decided by two compares and the level
        // computation skipped (most blocks of a view that magnifies its textures; computing it
        // anyway made the gallery's texture pass 1.25x slower).
        let (x2, y2) = (s.load(&lx2.0), s.load(&ly2.0));
        let large = s.or_m(s.lt(s.splat(1.0), x2), s.lt(s.splat(1.0), y2));
        let levels = if s.bits(large) & all == 0 {
            Levels::MAGNIFIED
        } else {
            match self.filter {
                Filter::Nearest => levels8::<true>(lx2, ly2, last),
                _ => levels8::<false>(lx2, ly2, last),
            }
        };
        let Levels { level, frac, blend } = levels;
        let blend_m = s.eq_u(s.load_u(&blend), one);
        let blend_bits = s.bits(blend_m) & all;
        let frac = s.load(&frac);
        let level_u = s.load_u(&level);
        // One call site of the filter for every group of lanes that share a mip level (three
        // filters x two placements inlined once more per instruction set, not twice); a
        // magnified block is one group at level 0 with one pass.
        // The first pass of a group filters its own level, the second (when a lane of the
        // group blends) the next one. Written as one loop with a pass flag: a nested
        // `for pass in 0..2` reads more plainly but costs 4 % more instructions in the texture
        // pass (callgrind, cornell-box at 512^2) and brings the second copy back.
        let mut todo = all;
        let mut out = [s.splat(0.0); 3];
        let mut a = out;
        let mut second = false;
        while todo != 0 {
            // The lanes still to do at the first such lane's level.
            let lv = level[todo.trailing_zeros() as usize];
            let group = s.bits(s.eq_u(level_u, s.splat_u(lv))) & todo;
            let filtered = self.level8(
                s,
                &tex.levels[lv as usize + second as usize],
                tex.placement,
                uc,
                vc,
            );
            if !second {
                a = filtered;
            } else {
                for ch in 0..3 {
                    let blended = s.add(a[ch], s.mul(s.sub(filtered[ch], a[ch]), frac));
                    a[ch] = s.select(blend_m, blended, a[ch]);
                }
            }
            if group & blend_bits != 0 && !second {
                second = true;
                continue;
            }
            second = false;
            todo &= !group;
            if group == all {
                // One level for the whole block (the usual case): nothing to merge.
                out = a;
                break;
            }
            let m = s.mask(group);
            for ch in 0..3 {
                out[ch] = s.select(m, a[ch], out[ch]);
            }
        }
        let mut r = [F32x8::splat(0.0); 3];
        for ch in 0..3 {
            s.store(out[ch], &mut r[ch].0);
        }
        r
    }
}

/// The mip levels of 8 lanes (see [`levels8`]).
struct Levels {
    /// The level each lane filters first.
    level: [u32; LANES],
    /// The fraction of the way to the next level.
    frac: [f32; LANES],
    /// 1 where the lane blends with the next level (a fraction above 0 short of the last
    /// level), else 0.
    blend: [u32; LANES],
}

impl Levels {
    /// Every lane at level 0 without a blend.
    const MAGNIFIED: Levels = Levels {
        level: [0; LANES],
        frac: [0.0; LANES],
        blend: [0; LANES],
    };
}

/// The levels of 8 lanes with squared footprints `lx2`, `ly2` in a chain whose last level is
/// `last`: per lane, d = [`lod_from_squares`] (in [0, last], never NaN, so the scalar
/// [`Sampler::sample`]'s clamp leaves it as it is), then the nearest level for the nearest
/// filter, else floor(d) and the fraction d - floor(d), blending where that is above 0 short
/// of the last level: the scalar code's choices, branch-free, so the loop runs in lanes.
#[inline(always)]
fn levels8<const NEAREST: bool>(lx2: F32x8, ly2: F32x8, last: usize) -> Levels {
    let last_f = last as f32;
    let mut level = [0u32; LANES];
    let mut frac = [0.0f32; LANES];
    let mut blend = [0u32; LANES];
    for l in 0..LANES {
        let d = lod_from_squares(lx2.0[l], ly2.0[l], last);
        // d is in [0, last]: its floor is its truncation, one conversion in lanes (the
        // baseline x86-64 target makes a library call per lane of `floor` and `round`).
        // SAFETY: d is finite and below 2^31.
        let l0 = if NEAREST {
            d.round()
        } else {
            (unsafe { d.to_int_unchecked::<i32>() }) as f32
        };
        frac[l] = d - l0;
        blend[l] = (!NEAREST & !((frac[l] <= 0.0) | (l0 == last_f))) as u32;
        // SAFETY: l0 is an integer in [0, last], and `last` is below a chain's level count
        // (13 at most: sides up to `MAX_TEXTURE_SIZE`); `as u32` would add a saturating range
        // check per lane.
        level[l] = unsafe { l0.to_int_unchecked::<i32>() } as u32;
    }
    Levels { level, frac, blend }
}
