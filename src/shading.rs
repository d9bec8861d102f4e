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
//! The radiosity-texture (RAT) method runs the same block structure
//! ([`shade_region_texture_into`]): per block of 8 samples the (u, v) derivatives, the level of
//! detail and the filter are computed in lanes ([`crate::texture::Sampler::sample8`]) with the
//! texels gathered per lane, one lane group per distinct polygon of the block, so that the
//! direct-versus-texture comparison sets two equally careful inner loops against each other. It
//! too reproduces its scalar sample-by-sample form bit for bit (kept as the tests' reference).
//!
//! Antialiasing filter: every pixel's N samples (see [`crate::raster::sample_offsets`]) are
//! averaged with equal weights, a box filter over the pixel's own square; samples that see nothing
//! contribute the background colour.

// Lane loops index several fixed-width arrays with one lane index on purpose: that is the form
// the compiler vectorizes and the reader checks lane by lane.
#![allow(clippy::needless_range_loop)]

use glam::Vec3;
use rayon::prelude::*;

use crate::lanes::{F32x8, LANES};
use crate::raster::gbuffer::{RegionGBuffer, NO_POLYGON};
#[cfg(test)]
use crate::texture::lod_from_squares;
use crate::texture::{Filter, Sampler, TextureSet};

pub use crate::reconstruction::PatchCoeffs;

/// What the direct method needs from a reconstruction.
pub trait PatchSource: Sync {
    /// Global id of the patch covering (u, v) of scene polygon `polygon`; (u, v) in `[0, 1]^2`.
    fn locate(&self, polygon: u32, u: f32, v: f32) -> u32;
    /// The coefficients of patch `id`.
    fn patch(&self, id: u32) -> &PatchCoeffs;
    /// The half-open parameter rectangle `[u_lo, u_hi) x [v_lo, v_hi)`, as
    /// `[u_lo, u_hi, v_lo, v_hi]`, on which `locate` returns `id` (for the polygon `id` was located
    /// on), if the source knows it exactly. The rasterizer then skips `locate` for samples inside
    /// it, which cannot change any result. The default knows nothing: every sample asks `locate`.
    fn cell(&self, _id: u32) -> Option<[f32; 4]> {
        None
    }
}

/// Horner's scheme: rows in s, then the rows in t.
#[cfg(test)]
#[inline(always)]
fn eval_channel(k: &[f32; 16], s: f32, t: f32) -> f32 {
    let r = |j: usize| ((k[4 * j + 3] * s + k[4 * j + 2]) * s + k[4 * j + 1]) * s + k[4 * j];
    ((r(3) * t + r(2)) * t + r(1)) * t + r(0)
}

/// Evaluates one channel for 8 lanes with broadcast coefficients; same operations, in the same
/// order, as [`eval_channel`].
#[inline(always)]
fn eval_channel8(k: &[f32; 16], s: F32x8, t: F32x8) -> F32x8 {
    let c = |i: usize| F32x8::splat(k[i]);
    let r3 = ((c(15) * s + c(14)) * s + c(13)) * s + c(12);
    let r2 = ((c(11) * s + c(10)) * s + c(9)) * s + c(8);
    let r1 = ((c(7) * s + c(6)) * s + c(5)) * s + c(4);
    let r0 = ((c(3) * s + c(2)) * s + c(1)) * s + c(0);
    ((r3 * t + r2) * t + r1) * t + r0
}

/// The radiosity of a polygon at (u, v), for [`Shader::Exact`].
pub type ExactFn<'a> = dyn Fn(u32, f32, f32) -> Vec3 + Sync + 'a;

/// What the deferred pass evaluates at each visible sample: the one place where the rendering
/// methods differ (everything before it, rasterization and composition, is shared).
#[derive(Clone, Copy)]
pub enum Shader<'a> {
    /// The region's patch table, filled by the rasterizer from this source: the direct method
    /// (RRPs), and the Gouraud mesh (one degree-(1, 1) patch per triangle).
    Patches(&'a dyn PatchSource),
    /// The polygon's radiosity texture, filtered, at a per-sample level of detail (RAT).
    Texture {
        /// Every polygon's texture (the texture memory every shader board would hold).
        set: &'a TextureSet,
        /// The on-screen filter.
        filter: Filter,
    },
    /// A function of (polygon, u, v), evaluated per sample: the reference (the solver's oracle).
    Exact(&'a ExactFn<'a>),
}

impl Shader<'_> {
    /// The patch source whose patches the rasterizer must copy into the regions, if any.
    pub fn patch_source(&self) -> Option<&dyn PatchSource> {
        match self {
            Shader::Patches(s) => Some(*s),
            _ => None,
        }
    }
}

/// Counters of one shading pass.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ShadeCounts {
    /// Samples that saw a polygon and were evaluated.
    pub samples_shaded: u64,
    /// Blocks of 8 evaluated with one broadcast patch (texture methods: one polygon's texture).
    pub uniform_blocks: u64,
    /// Blocks that mix patches (texture methods: polygons) or contain empty samples.
    pub mixed_blocks: u64,
}

/// Shades one composited region: returns its `width * height` resolved linear pixels (row-major,
/// row 0 at the region's top) and the counters.
pub fn shade_region(gb: &RegionGBuffer, background: Vec3) -> (Vec<Vec3>, ShadeCounts) {
    let mut out = vec![Vec3::ZERO; (gb.width * gb.height) as usize];
    let counts = shade_region_into(gb, background, &mut out, gb.width as usize);
    (out, counts)
}

/// Shades one composited region into `dst`, whose element 0 is the region's top-left pixel and
/// whose rows are `pitch` pixels apart (a frame: pitch = frame width).
///
/// On x86-64 CPUs with AVX2 the same code is compiled a second time with 8-wide registers and
/// chosen at run time; without FMA the two builds perform identical IEEE operations, so the image
/// does not depend on the CPU.
pub fn shade_region_into(
    gb: &RegionGBuffer,
    background: Vec3,
    dst: &mut [Vec3],
    pitch: usize,
) -> ShadeCounts {
    assert!(
        gb.height == 0 || dst.len() >= (gb.height as usize - 1) * pitch + gb.width as usize,
        "destination too small for the region"
    );
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2, checked just above.
            return unsafe { shade_region_avx2(gb, background, dst, pitch) };
        }
    }
    shade_region_body(gb, background, dst, pitch)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn shade_region_avx2(gb: &RegionGBuffer, bg: Vec3, dst: &mut [Vec3], pitch: usize) -> ShadeCounts {
    shade_region_body(gb, bg, dst, pitch)
}

#[inline(always)]
fn shade_region_body(
    gb: &RegionGBuffer,
    background: Vec3,
    dst: &mut [Vec3],
    pitch: usize,
) -> ShadeCounts {
    let (w, h, stride) = (gb.width as usize, gb.height as usize, gb.stride as usize);
    let plane = stride * h;
    // One row of per-channel accumulators (structure of arrays: lanes store contiguously).
    let mut acc = [
        vec![0.0f32; stride],
        vec![0.0f32; stride],
        vec![0.0f32; stride],
    ];
    let mut counts = ShadeCounts::default();
    let bg = background.to_array();
    let bg8 = [
        F32x8::splat(bg[0]),
        F32x8::splat(bg[1]),
        F32x8::splat(bg[2]),
    ];
    let inv = F32x8::splat(1.0 / gb.samples as f32);
    for y in 0..h {
        for si in 0..gb.samples as usize {
            let row = si * plane + y * stride;
            for bx in (0..w).step_by(LANES) {
                let i0 = row + bx;
                let polys: &[u32; LANES] = gb.polygon[i0..i0 + LANES].try_into().unwrap();
                let slots: &[u32; LANES] = gb.slot[i0..i0 + LANES].try_into().unwrap();
                let u8x = F32x8(gb.u[i0..i0 + LANES].try_into().unwrap());
                let v8x = F32x8(gb.v[i0..i0 + LANES].try_into().unwrap());
                let mut empty = [false; LANES];
                let mut same = true;
                let mut n_empty = 0;
                for l in 0..LANES {
                    empty[l] = polys[l] == NO_POLYGON;
                    n_empty += empty[l] as usize;
                    same &= slots[l] == slots[0];
                }
                let out = if n_empty == 0 && same {
                    // The common case: one patch, its coefficients broadcast over the 8 lanes.
                    counts.uniform_blocks += 1;
                    counts.samples_shaded += LANES as u64;
                    let p = &gb.table[slots[0] as usize];
                    let s = (u8x - F32x8::splat(p.u0)) * F32x8::splat(p.inv_w);
                    let t = (v8x - F32x8::splat(p.v0)) * F32x8::splat(p.inv_w);
                    [
                        eval_channel8(&p.c[0], s, t),
                        eval_channel8(&p.c[1], s, t),
                        eval_channel8(&p.c[2], s, t),
                    ]
                } else if n_empty == LANES {
                    bg8
                } else {
                    // Mixed: one broadcast evaluation per distinct patch, committed through masks.
                    counts.mixed_blocks += 1;
                    counts.samples_shaded += (LANES - n_empty) as u64;
                    let mut out = bg8;
                    let mut done = empty;
                    while let Some(first) = done.iter().position(|&d| !d) {
                        let slot = slots[first];
                        let p = &gb.table[slot as usize];
                        let s = (u8x - F32x8::splat(p.u0)) * F32x8::splat(p.inv_w);
                        let t = (v8x - F32x8::splat(p.v0)) * F32x8::splat(p.inv_w);
                        let mut m = [false; LANES];
                        for l in 0..LANES {
                            m[l] = !done[l] && slots[l] == slot;
                            done[l] |= m[l];
                        }
                        for ch in 0..3 {
                            out[ch] = F32x8::select(&m, eval_channel8(&p.c[ch], s, t), out[ch]);
                        }
                    }
                    out
                };
                accumulate8(&mut acc, bx, si, &out);
            }
        }
        // Box filter: equal weights over the pixel's samples, then the non-finite clamp. Padding
        // lanes beyond the region's width hold NO_POLYGON and are never written out.
        resolve_row(
            &mut acc,
            gb.samples,
            inv,
            &mut dst[y * pitch..y * pitch + w],
        );
    }
    counts
}

/// Shades one region sample by sample with `f(index, x, y)` (index into the G-buffer's planes,
/// region-local column and row; called only for samples that see a polygon), accumulating the
/// samples of each pixel in plane order and resolving them exactly as the patch path does (box
/// filter, then the non-finite clamp).
fn shade_region_per_sample(
    gb: &RegionGBuffer,
    background: Vec3,
    dst: &mut [Vec3],
    pitch: usize,
    mut f: impl FnMut(usize, usize, usize) -> Vec3,
) -> ShadeCounts {
    let (w, h, stride) = (gb.width as usize, gb.height as usize, gb.stride as usize);
    let plane = stride * h;
    let mut counts = ShadeCounts::default();
    let mut acc = vec![Vec3::ZERO; w];
    let inv = 1.0 / gb.samples as f32;
    for y in 0..h {
        for si in 0..gb.samples as usize {
            let row = si * plane + y * stride;
            for (x, a) in acc.iter_mut().enumerate() {
                let i = row + x;
                let c = if gb.polygon[i] == NO_POLYGON {
                    background
                } else {
                    counts.samples_shaded += 1;
                    f(i, x, y)
                };
                *a = if si == 0 { c } else { *a + c };
            }
        }
        let out = &mut dst[y * pitch..y * pitch + w];
        for (o, a) in out.iter_mut().zip(&acc) {
            let c = if gb.samples == 1 { *a } else { *a * inv };
            *o = Vec3::from_array(c.to_array().map(|x| if x.is_finite() { x } else { 0.0 }));
        }
    }
    counts
}

/// Screen-space derivatives of (u, v) at sample `i` (column `x`, row `y` of its plane) by finite
/// differences with the neighbouring samples of the same polygon in the same plane: forward
/// where the right (lower) neighbour shows the same polygon, else backward, else 0 (a polygon
/// one sample wide in that direction, or at the region's edge on both sides: level 0 then).
/// Returns (du/dx, dv/dx, du/dy, dv/dy), in parameter units per pixel. This is how graphics
/// hardware has long derived its level of detail (differences within pixel quads). The deferred
/// pass uses its lane form `uv_derivatives8`; this scalar form is the tests' reference.
#[cfg(test)]
fn uv_derivatives(gb: &RegionGBuffer, i: usize, x: usize, y: usize) -> [f32; 4] {
    let (w, h, stride) = (gb.width as usize, gb.height as usize, gb.stride as usize);
    let p = gb.polygon[i];
    let diff = |a: usize, b: usize| [gb.u[b] - gb.u[a], gb.v[b] - gb.v[a]];
    let dx = if x + 1 < w && gb.polygon[i + 1] == p {
        diff(i, i + 1)
    } else if x > 0 && gb.polygon[i - 1] == p {
        diff(i - 1, i)
    } else {
        [0.0; 2]
    };
    let dy = if y + 1 < h && gb.polygon[i + stride] == p {
        diff(i, i + stride)
    } else if y > 0 && gb.polygon[i - stride] == p {
        diff(i - stride, i)
    } else {
        [0.0; 2]
    };
    [dx[0], dx[1], dy[0], dy[1]]
}

/// Shades one composited region with any [`Shader`] into `dst` (see [`shade_region_into`]).
pub fn shade_region_with(
    shader: &Shader<'_>,
    gb: &RegionGBuffer,
    background: Vec3,
    dst: &mut [Vec3],
    pitch: usize,
) -> ShadeCounts {
    match *shader {
        Shader::Patches(_) => shade_region_into(gb, background, dst, pitch),
        Shader::Texture { set, filter } => {
            shade_region_texture_into(set, filter, gb, background, dst, pitch)
        }
        Shader::Exact(func) => {
            let f = |i: usize, _: usize, _: usize| func(gb.polygon[i], gb.u[i], gb.v[i]);
            shade_region_per_sample(gb, background, dst, pitch, f)
        }
    }
}

/// The texture (RAT) deferred pass over one region, sample by sample: the reference form of
/// [`shade_region_texture_into`], which must reproduce its bits (kept for the tests).
#[cfg(test)]
fn shade_region_texture_scalar(
    set: &TextureSet,
    filter: Filter,
    gb: &RegionGBuffer,
    background: Vec3,
    dst: &mut [Vec3],
    pitch: usize,
) -> ShadeCounts {
    let sampler = Sampler::new(filter);
    let f = |i: usize, x: usize, y: usize| {
        let Some(tex) = set.textures.get(gb.polygon[i] as usize) else {
            return Vec3::ZERO;
        };
        let [ux, vx, uy, vy] = uv_derivatives(gb, i, x, y);
        let (tw, th) = (tex.width as f32, tex.height as f32);
        let lx2 = (ux * tw) * (ux * tw) + (vx * th) * (vx * th);
        let ly2 = (uy * tw) * (uy * tw) + (vy * th) * (vy * th);
        let lod = lod_from_squares(lx2, ly2, tex.last_level());
        sampler.sample(tex, lod, gb.u[i], gb.v[i])
    };
    shade_region_per_sample(gb, background, dst, pitch, f)
}

/// The texture (RAT) deferred pass over one region into `dst` (see [`shade_region_into`]): every
/// visible sample gets its polygon's texture filtered with `filter` at the level of detail from
/// the finite differences of (u, v) between neighbouring samples of the same polygon
/// (`uv_derivatives`), then the samples of each pixel are box-filtered.
///
/// Built like the direct path: blocks of 8 samples of a row, derivatives and texture lookups in
/// [`F32x8`] lanes ([`Sampler::sample8`]), one lane group per distinct polygon of the block
/// (nearly always one), compiled a second time for AVX2 and chosen at run time. Every lane
/// performs the scalar operations in the scalar order, so the image has the bits of the
/// sample-by-sample form and does not depend on the CPU.
pub fn shade_region_texture_into(
    set: &TextureSet,
    filter: Filter,
    gb: &RegionGBuffer,
    background: Vec3,
    dst: &mut [Vec3],
    pitch: usize,
) -> ShadeCounts {
    assert!(
        gb.height == 0 || dst.len() >= (gb.height as usize - 1) * pitch + gb.width as usize,
        "destination too small for the region"
    );
    let sampler = Sampler::new(filter);
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2, checked just above.
            return unsafe { shade_texture_avx2(set, &sampler, gb, background, dst, pitch) };
        }
    }
    // SAFETY: HW = false: portable code only.
    unsafe { shade_texture_body::<false>(set, &sampler, gb, background, dst, pitch) }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn shade_texture_avx2(
    set: &TextureSet,
    sampler: &Sampler,
    gb: &RegionGBuffer,
    bg: Vec3,
    dst: &mut [Vec3],
    pitch: usize,
) -> ShadeCounts {
    // SAFETY: this function is only called on CPUs with AVX2, which HW = true requires.
    unsafe { shade_texture_body::<true>(set, sampler, gb, bg, dst, pitch) }
}

/// Lane form of `uv_derivatives` for the 8 samples starting at plane index `i0` (column `bx`,
/// row `y`), whose polygons are `polys`: (du/dx, dv/dx, du/dy, dv/dy) per lane, each the same
/// difference of the same two samples as the scalar function picks (forward, else backward, else
/// 0). Lanes showing no polygon get unspecified finite-or-not values; the caller ignores them.
#[inline(always)]
fn uv_derivatives8(
    gb: &RegionGBuffer,
    i0: usize,
    bx: usize,
    y: usize,
    polys: &[u32; LANES],
) -> [F32x8; 4] {
    let (w, h, stride) = (gb.width as usize, gb.height as usize, gb.stride as usize);
    let (us, vs, ps) = (&gb.u, &gb.v, &gb.polygon);
    let u = F32x8(us[i0..i0 + LANES].try_into().unwrap());
    let v = F32x8(vs[i0..i0 + LANES].try_into().unwrap());
    let zero = F32x8::splat(0.0);
    // Horizontal neighbours: within the block, plus one sample on each side when it exists.
    let mut pr = [NO_POLYGON; LANES];
    let (mut ur, mut vr) = ([0.0f32; LANES], [0.0f32; LANES]);
    let mut pl = [NO_POLYGON; LANES];
    let (mut ul, mut vl) = ([0.0f32; LANES], [0.0f32; LANES]);
    pr[..LANES - 1].copy_from_slice(&polys[1..]);
    ur[..LANES - 1].copy_from_slice(&u.0[1..]);
    vr[..LANES - 1].copy_from_slice(&v.0[1..]);
    pl[1..].copy_from_slice(&polys[..LANES - 1]);
    ul[1..].copy_from_slice(&u.0[..LANES - 1]);
    vl[1..].copy_from_slice(&v.0[..LANES - 1]);
    if bx + LANES < w {
        let k = i0 + LANES;
        (pr[LANES - 1], ur[LANES - 1], vr[LANES - 1]) = (ps[k], us[k], vs[k]);
    }
    if bx > 0 {
        let k = i0 - 1;
        (pl[0], ul[0], vl[0]) = (ps[k], us[k], vs[k]);
    }
    let (mut fwd, mut bwd) = ([false; LANES], [false; LANES]);
    for l in 0..LANES {
        fwd[l] = bx + l + 1 < w && pr[l] == polys[l];
        bwd[l] = bx + l > 0 && pl[l] == polys[l];
    }
    let (ur, vr, ul, vl) = (F32x8(ur), F32x8(vr), F32x8(ul), F32x8(vl));
    let ux = F32x8::select(&fwd, ur - u, F32x8::select(&bwd, u - ul, zero));
    let vx = F32x8::select(&fwd, vr - v, F32x8::select(&bwd, v - vl, zero));
    // Vertical neighbours: the same columns one row down and one row up, when those rows exist.
    let row = |k: usize| {
        let p: [u32; LANES] = ps[k..k + LANES].try_into().unwrap();
        let uu = F32x8(us[k..k + LANES].try_into().unwrap());
        let vv = F32x8(vs[k..k + LANES].try_into().unwrap());
        (p, uu, vv)
    };
    let none = ([NO_POLYGON; LANES], zero, zero);
    let (pd, ud, vd) = if y + 1 < h { row(i0 + stride) } else { none };
    let (pu, uu, vu) = if y > 0 { row(i0 - stride) } else { none };
    let (mut down, mut up) = ([false; LANES], [false; LANES]);
    for l in 0..LANES {
        down[l] = y + 1 < h && pd[l] == polys[l];
        up[l] = y > 0 && pu[l] == polys[l];
    }
    let uy = F32x8::select(&down, ud - u, F32x8::select(&up, u - uu, zero));
    let vy = F32x8::select(&down, vd - v, F32x8::select(&up, v - vu, zero));
    [ux, vx, uy, vy]
}

/// `uv_derivatives8` for a block whose 8 samples all show polygon `p` (the common case): lanes
/// 0..7 take the forward difference to the next lane, lane 7 forward to the next block when it
/// shows `p`, else backward to lane 6; vertically as in the general form. The same differences of
/// the same samples as the general form, with the horizontal masks known in advance.
#[inline(always)]
fn uv_derivatives8_uniform(
    gb: &RegionGBuffer,
    i0: usize,
    bx: usize,
    y: usize,
    p: u32,
) -> [F32x8; 4] {
    let (w, h, stride) = (gb.width as usize, gb.height as usize, gb.stride as usize);
    let (us, vs, ps) = (&gb.u, &gb.v, &gb.polygon);
    let u = F32x8(us[i0..i0 + LANES].try_into().unwrap());
    let v = F32x8(vs[i0..i0 + LANES].try_into().unwrap());
    let zero = F32x8::splat(0.0);
    let (mut ur, mut vr) = ([0.0f32; LANES], [0.0f32; LANES]);
    ur[..LANES - 1].copy_from_slice(&u.0[1..]);
    vr[..LANES - 1].copy_from_slice(&v.0[1..]);
    let right = bx + LANES < w && ps[i0 + LANES] == p;
    if right {
        (ur[LANES - 1], vr[LANES - 1]) = (us[i0 + LANES], vs[i0 + LANES]);
    }
    let (mut ux, mut vx) = (F32x8(ur) - u, F32x8(vr) - v);
    if !right {
        ux.0[LANES - 1] = u.0[LANES - 1] - u.0[LANES - 2];
        vx.0[LANES - 1] = v.0[LANES - 1] - v.0[LANES - 2];
    }
    let mut uy = zero;
    let mut vy = zero;
    let mut set = [false; LANES];
    if y + 1 < h {
        let k = i0 + stride;
        let pd: &[u32; LANES] = ps[k..k + LANES].try_into().unwrap();
        let ud = F32x8(us[k..k + LANES].try_into().unwrap());
        let vd = F32x8(vs[k..k + LANES].try_into().unwrap());
        for l in 0..LANES {
            set[l] = pd[l] == p;
        }
        uy = F32x8::select(&set, ud - u, uy);
        vy = F32x8::select(&set, vd - v, vy);
    }
    if y > 0 {
        let k = i0 - stride;
        let pu: &[u32; LANES] = ps[k..k + LANES].try_into().unwrap();
        let uu = F32x8(us[k..k + LANES].try_into().unwrap());
        let vu = F32x8(vs[k..k + LANES].try_into().unwrap());
        let mut m = [false; LANES];
        for l in 0..LANES {
            m[l] = !set[l] & (pu[l] == p);
        }
        uy = F32x8::select(&m, u - uu, uy);
        vy = F32x8::select(&m, v - vu, vy);
    }
    [ux, vx, uy, vy]
}

/// The texture pass body; `HW` selects the AVX2 gather instruction for the texel loads.
///
/// # Safety
/// With `HW = true` the CPU must support AVX2.
#[inline(always)]
unsafe fn shade_texture_body<const HW: bool>(
    set: &TextureSet,
    sampler: &Sampler,
    gb: &RegionGBuffer,
    background: Vec3,
    dst: &mut [Vec3],
    pitch: usize,
) -> ShadeCounts {
    let (w, h, stride) = (gb.width as usize, gb.height as usize, gb.stride as usize);
    let plane = stride * h;
    let mut acc = [
        vec![0.0f32; stride],
        vec![0.0f32; stride],
        vec![0.0f32; stride],
    ];
    let mut counts = ShadeCounts::default();
    let bg = background.to_array();
    let bg8 = [
        F32x8::splat(bg[0]),
        F32x8::splat(bg[1]),
        F32x8::splat(bg[2]),
    ];
    let inv = F32x8::splat(1.0 / gb.samples as f32);
    for y in 0..h {
        for si in 0..gb.samples as usize {
            let row = si * plane + y * stride;
            for bx in (0..w).step_by(LANES) {
                let i0 = row + bx;
                let polys: &[u32; LANES] = gb.polygon[i0..i0 + LANES].try_into().unwrap();
                let mut empty = [false; LANES];
                let mut n_empty = 0;
                for l in 0..LANES {
                    // Lanes beyond the region's width (padding) are treated as empty even if
                    // they held a polygon, as the scalar pass never reads them.
                    empty[l] = (polys[l] == NO_POLYGON) | (bx + l >= w);
                    n_empty += empty[l] as usize;
                }
                let p0 = polys[0];
                let mut uniform = n_empty == 0;
                for l in 0..LANES {
                    uniform &= polys[l] == p0;
                }
                let out = if n_empty == LANES {
                    bg8
                } else if let (true, Some(tex)) = (uniform, set.textures.get(p0 as usize)) {
                    // The common case: one polygon over the whole block.
                    counts.uniform_blocks += 1;
                    counts.samples_shaded += LANES as u64;
                    let u8x = F32x8(gb.u[i0..i0 + LANES].try_into().unwrap());
                    let v8x = F32x8(gb.v[i0..i0 + LANES].try_into().unwrap());
                    let [ux, vx, uy, vy] = uv_derivatives8_uniform(gb, i0, bx, y, p0);
                    let tw = F32x8::splat(tex.width as f32);
                    let th = F32x8::splat(tex.height as f32);
                    let lx2 = (ux * tw) * (ux * tw) + (vx * th) * (vx * th);
                    let ly2 = (uy * tw) * (uy * tw) + (vy * th) * (vy * th);
                    {
                        // SAFETY: as required of this function's caller.
                        unsafe {
                            sampler.sample8_with::<HW>(tex, lx2, ly2, u8x, v8x, &[true; LANES])
                        }
                    }
                } else {
                    // Mixed polygons or empty lanes: one lane group per distinct polygon.
                    let u8x = F32x8(gb.u[i0..i0 + LANES].try_into().unwrap());
                    let v8x = F32x8(gb.v[i0..i0 + LANES].try_into().unwrap());
                    let [ux, vx, uy, vy] = uv_derivatives8(gb, i0, bx, y, polys);
                    counts.samples_shaded += (LANES - n_empty) as u64;
                    let mut out = bg8;
                    let mut done = empty;
                    while let Some(first) = done.iter().position(|&d| !d) {
                        let p = polys[first];
                        let mut m = [false; LANES];
                        for l in 0..LANES {
                            m[l] = !done[l] && polys[l] == p;
                            done[l] |= m[l];
                        }
                        let c = match set.textures.get(p as usize) {
                            None => [F32x8::splat(0.0); 3],
                            Some(tex) => {
                                let tw = F32x8::splat(tex.width as f32);
                                let th = F32x8::splat(tex.height as f32);
                                let lx2 = (ux * tw) * (ux * tw) + (vx * th) * (vx * th);
                                let ly2 = (uy * tw) * (uy * tw) + (vy * th) * (vy * th);
                                // SAFETY: as required of this function's caller.
                                unsafe { sampler.sample8_with::<HW>(tex, lx2, ly2, u8x, v8x, &m) }
                            }
                        };
                        for ch in 0..3 {
                            out[ch] = F32x8::select(&m, c[ch], out[ch]);
                        }
                    }
                    counts.mixed_blocks += 1;
                    out
                };
                accumulate8(&mut acc, bx, si, &out);
            }
        }
        // Box filter and non-finite clamp, as in the patch path.
        resolve_row(
            &mut acc,
            gb.samples,
            inv,
            &mut dst[y * pitch..y * pitch + w],
        );
    }
    counts
}

/// Adds one block's 8 lanes of RGB to the row accumulators at column `bx` (the first sample
/// plane `si == 0` stores instead of adding): the same IEEE operations in the same order for every
/// shader, so samples are always summed in plane order.
#[inline(always)]
fn accumulate8(acc: &mut [Vec<f32>; 3], bx: usize, si: usize, out: &[F32x8; 3]) {
    for ch in 0..3 {
        let a: &mut [f32; LANES] = (&mut acc[ch][bx..bx + LANES]).try_into().unwrap();
        *a = if si == 0 {
            out[ch].0
        } else {
            (F32x8(*a) + out[ch]).0
        };
    }
}

/// Resolves one row: the box filter (the mean of `samples` planes, `inv = 1 / samples`), the
/// non-finite clamp, and the write of the row's `out.len()` pixels.
#[inline(always)]
fn resolve_row(acc: &mut [Vec<f32>; 3], samples: u32, inv: F32x8, out: &mut [Vec3]) {
    for a in acc.iter_mut() {
        for chunk in a.chunks_exact_mut(LANES) {
            let c: &mut [f32; LANES] = chunk.try_into().unwrap();
            let v = if samples == 1 {
                F32x8(*c)
            } else {
                F32x8(*c) * inv
            };
            *c = sanitize8(v).0;
        }
    }
    let [r, g, b] = &*acc;
    for (o, ((r, g), b)) in out.iter_mut().zip(r.iter().zip(g).zip(b)) {
        *o = Vec3::new(*r, *g, *b);
    }
}

/// Replaces non-finite lanes by 0 (documented clamp: a patch source with non-finite coefficients
/// must not put NaN or inf into an image).
#[inline(always)]
fn sanitize8(c: F32x8) -> F32x8 {
    let m: [bool; LANES] = std::array::from_fn(|l| c.0[l].is_finite());
    F32x8::select(&m, c, F32x8::splat(0.0))
}

/// The deferred pass over a frame: shades every region with `shader` into a `width` x `height` frame of
/// `background`, in parallel (rayon) over bands of `region_size` rows; regions are placed by their
/// own origin, and every pixel no region covers keeps the background. Returns the frame (row-major,
/// row 0 at the top) and the summed counters (summed in band order: deterministic).
pub fn shade_regions(
    shader: &Shader<'_>,
    regions: &[RegionGBuffer],
    background: Vec3,
    width: u32,
    height: u32,
    region_size: u32,
) -> (Vec<Vec3>, ShadeCounts) {
    let (w, size) = (width as usize, region_size.max(1) as usize);
    // Zeroed memory comes from the allocator without a fill pass; only pixels no region covers
    // are then written with the background.
    let mut frame = vec![Vec3::ZERO; w * height as usize];
    let bands = (height as usize).div_ceil(size);
    let mut by_band: Vec<Vec<&RegionGBuffer>> = vec![Vec::new(); bands];
    for r in regions {
        let band = r.y0 as usize / size;
        if band < bands && r.y0 as usize % size == 0 && r.x0 + r.width <= width {
            by_band[band].push(r);
        }
    }
    let per_band: Vec<ShadeCounts> = frame
        .par_chunks_mut(w * size)
        .zip(by_band.par_iter())
        .map(|(rows, regs)| {
            let mut c = ShadeCounts::default();
            let rows_here = rows.len() / w;
            let mut covered = vec![false; w];
            for r in regs {
                if r.height as usize != rows_here {
                    continue;
                }
                let k = shade_region_with(shader, r, background, &mut rows[r.x0 as usize..], w);
                covered[r.x0 as usize..(r.x0 + r.width) as usize].fill(true);
                c.samples_shaded += k.samples_shaded;
                c.uniform_blocks += k.uniform_blocks;
                c.mixed_blocks += k.mixed_blocks;
            }
            if covered.iter().any(|&c| !c) {
                for row in rows.chunks_exact_mut(w) {
                    for (p, &cov) in row.iter_mut().zip(&covered) {
                        if !cov {
                            *p = background;
                        }
                    }
                }
            }
            c
        })
        .collect();
    let mut total = ShadeCounts::default();
    for c in per_band {
        total.samples_shaded += c.samples_shaded;
        total.uniform_blocks += c.uniform_blocks;
        total.mixed_blocks += c.mixed_blocks;
    }
    (frame, total)
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
    fn sanitize_zeroes_exactly_the_non_finite_lanes() {
        let sub = f32::from_bits(1); // smallest subnormal: finite, must survive
        let x = F32x8([
            1.0,
            -0.0,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            f32::MAX,
            sub,
            -3.5,
        ]);
        let got = sanitize8(x);
        for l in 0..LANES {
            let want = if x.0[l].is_finite() { x.0[l] } else { 0.0 };
            assert_eq!(got.0[l].to_bits(), want.to_bits(), "lane {l}");
        }
    }

    #[test]
    fn lane_path_and_scalar_path_agree_bit_for_bit() {
        let p = poly_patch();
        let s: [f32; 8] = std::array::from_fn(|l| l as f32 * 0.13);
        let t: [f32; 8] = std::array::from_fn(|l| 1.0 - l as f32 * 0.11);
        let r = eval_channel8(&p.c[1], F32x8(s), F32x8(t));
        for l in 0..8 {
            assert_eq!(
                r.0[l].to_bits(),
                eval_channel(&p.c[1], s[l], t[l]).to_bits()
            );
        }
    }

    #[test]
    fn frame_pass_places_regions_and_fills_the_rest_with_background() {
        use crate::raster::gbuffer::RegionGBuffer;
        // A 20 x 10 frame of 8 x 8 regions: only region (1, 0) (x 8..16, y 0..8) is present; its
        // sample at local (2, 3) sees polygon 0 with the constant patch 0.25.
        let mut gb = RegionGBuffer::new(1, 8, 0, 8, 8, 1);
        let i = 3 * gb.stride as usize + 2;
        gb.polygon[i] = 0;
        gb.depth[i] = 1.0;
        let mut c = [[0.0f32; 16]; 3];
        c[0][0] = 0.25;
        gb.table.push(PatchCoeffs::whole(c));
        gb.table_ids.push(7);
        let bg = Vec3::new(1.0, 2.0, 3.0);
        struct Unused;
        impl PatchSource for Unused {
            fn locate(&self, _: u32, _: f32, _: f32) -> u32 {
                unreachable!("the pass reads the region's table")
            }
            fn patch(&self, _: u32) -> &PatchCoeffs {
                unreachable!("the pass reads the region's table")
            }
        }
        let (frame, counts) = shade_regions(&Shader::Patches(&Unused), &[gb], bg, 20, 10, 8);
        assert_eq!(counts.samples_shaded, 1);
        for y in 0..10 {
            for x in 0..20 {
                let want = if (x, y) == (10, 3) {
                    Vec3::new(0.25, 0.0, 0.0)
                } else {
                    bg
                };
                assert_eq!(frame[y * 20 + x], want, "({x}, {y})");
            }
        }
    }

    /// A region mixing three textured polygons of different sizes, a polygon without texture,
    /// empty samples, padding lanes (width 37), 2 samples per pixel, parameters slightly outside
    /// [0, 1] and a NaN, and (u, v) maps whose scale grows across the region so that the level of
    /// detail runs from magnification over fractional levels to the last level.
    fn mixed_texture_region() -> (TextureSet, RegionGBuffer) {
        use crate::texture::{RadiosityTexture, TextureMemory};
        let sides = [4u32, 16, 64];
        let textures: Vec<RadiosityTexture> = sides
            .iter()
            .enumerate()
            .map(|(k, &n)| {
                let t = (0..n * n)
                    .map(|i| {
                        let h = (i * 2654435761u32.wrapping_add(k as u32)) >> 7;
                        Vec3::new(
                            (h % 97) as f32 * 0.01,
                            (h % 89) as f32 * 0.02 - 0.3,
                            (h % 83) as f32 * 0.5,
                        )
                    })
                    .collect();
                RadiosityTexture::from_texels(n, n, t).unwrap()
            })
            .collect();
        let set = TextureSet {
            textures,
            memory: TextureMemory::of_sides(&sides),
        };
        let (w, h, spp) = (37u32, 13u32, 2u32);
        let mut gb = RegionGBuffer::new(0, 0, 0, w, h, spp);
        let (stride, plane) = (gb.stride as usize, (gb.stride * h) as usize);
        for si in 0..spp as usize {
            for y in 0..h as usize {
                for x in 0..w as usize {
                    let i = si * plane + y * stride + x;
                    let poly = match (x + 3 * si, y) {
                        (_, 5) if x % 7 == 3 => NO_POLYGON,
                        (a, _) if a < 11 => 0,
                        (a, b) if a < 24 && b < 9 => 1,
                        (a, _) if a < 24 => 7, // no texture: black
                        _ => 2,
                    };
                    if poly == NO_POLYGON {
                        continue;
                    }
                    let (xf, yf) = (x as f32 + 0.5 * si as f32, y as f32);
                    // Scale grows with x and y: footprints from 1/16 texel to many texels.
                    let k = 0.002 * (1.0 + 0.05 * xf * xf + 0.3 * yf * yf);
                    let mut u = (xf * k).fract() * 1.04 - 0.02;
                    let v = (yf * k * 0.7 + 0.1 * xf * k).fract() * 1.04 - 0.02;
                    if (x, y, si) == (30, 7, 1) {
                        u = f32::NAN;
                    }
                    gb.polygon[i] = poly;
                    gb.u[i] = u;
                    gb.v[i] = v;
                    gb.depth[i] = 1.0;
                }
            }
        }
        (set, gb)
    }

    #[test]
    fn texture_lane_path_equals_the_scalar_path_bit_for_bit() {
        let (set, gb) = mixed_texture_region();
        let (w, h) = (gb.width as usize, gb.height as usize);
        // The region does exercise every level-of-detail case: magnified samples, fractional
        // levels (trilinear blends) and samples clamped to the last level.
        let plane = (gb.stride * gb.height) as usize;
        let (mut magnified, mut blended, mut last) = (0, 0, 0);
        for si in 0..gb.samples as usize {
            for y in 0..h {
                for x in 0..w {
                    let i = si * plane + y * gb.stride as usize + x;
                    let Some(tex) = set.textures.get(gb.polygon[i] as usize) else {
                        continue;
                    };
                    let [ux, vx, uy, vy] = uv_derivatives(&gb, i, x, y);
                    let (tw, th) = (tex.width as f32, tex.height as f32);
                    let lx2 = (ux * tw) * (ux * tw) + (vx * th) * (vx * th);
                    let ly2 = (uy * tw) * (uy * tw) + (vy * th) * (vy * th);
                    let d = lod_from_squares(lx2, ly2, tex.last_level());
                    magnified += (d == 0.0) as usize;
                    blended += (d > 0.0 && d.fract() > 0.0 && d < tex.last_level() as f32) as usize;
                    last += (d == tex.last_level() as f32) as usize;
                }
            }
        }
        assert!(
            magnified > 50 && blended > 50 && last > 5,
            "{magnified} {blended} {last}"
        );
        let bg = Vec3::new(0.5, -1.0, 2.0);
        for filter in [
            Filter::Nearest,
            Filter::Bilinear,
            Filter::MITCHELL,
            Filter::CATMULL_ROM,
            Filter::Bicubic { b: 0.9, c: 0.05 },
        ] {
            let pitch = w + 3;
            let mut want = vec![Vec3::splat(-7.0); pitch * h];
            let c_want = shade_region_texture_scalar(&set, filter, &gb, bg, &mut want, pitch);
            let mut got = vec![Vec3::splat(-7.0); pitch * h];
            let c_got = shade_region_texture_into(&set, filter, &gb, bg, &mut got, pitch);
            // The portable build of the body too (the dispatcher above picks AVX2 if present).
            let mut port = vec![Vec3::splat(-7.0); pitch * h];
            // SAFETY: HW = false: portable code only.
            unsafe {
                shade_texture_body::<false>(&set, &Sampler::new(filter), &gb, bg, &mut port, pitch)
            };
            assert_eq!(c_got.samples_shaded, c_want.samples_shaded, "{filter:?}");
            assert!(
                c_got.uniform_blocks > 0 && c_got.mixed_blocks > 0,
                "{c_got:?}"
            );
            for k in 0..pitch * h {
                for (name, img) in [("dispatched", &got), ("portable", &port)] {
                    assert_eq!(
                        img[k].to_array().map(f32::to_bits),
                        want[k].to_array().map(f32::to_bits),
                        "{filter:?} {name}: pixel ({}, {}): {} vs {}",
                        k % pitch,
                        k / pitch,
                        img[k],
                        want[k]
                    );
                }
            }
        }
    }
}
