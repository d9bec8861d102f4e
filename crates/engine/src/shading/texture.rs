//! The texture (RAT) shader: every visible sample filters its polygon's radiosity texture at a
//! level of detail from the finite differences of (u, v) between neighbouring samples of the same
//! polygon, taken over one sample's share of the pixel ([`crate::raster::sample_spacing`]:
//! the pixel's samples are averaged afterwards, so a lookup filtered over the whole pixel
//! would filter twice).
//!
//! It runs in the same lane blocks as the patch shader: per block of
//! 8 samples the derivatives, the level of detail and the filter are computed in lanes
//! ([`Sampler::sample8`]) with the texels gathered per lane, one lane group per distinct polygon
//! of the block, so that the direct-versus-texture comparison sets two equally careful inner
//! loops against each other. It reproduces its scalar sample-by-sample form bit for bit (kept as
//! the tests' reference).

#![allow(clippy::needless_range_loop)]

use glam::Vec3;

#[cfg(test)]
use super::shade_region_per_sample;
use super::{RowOut, Rows, ShadeCounts};
use crate::raster::gbuffer::{RegionGBuffer, NO_POLYGON};
use crate::raster::sample_spacing;
use lanes::{F32x8, Isa, Kernel, Simd, LANES};
#[cfg(test)]
use reconstruction::texture::lod_from_squares;
use reconstruction::texture::{Filter, Footprint8, RadiosityTexture, Sampler, TextureSet};

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

/// The texture (RAT) deferred pass over one region, sample by sample: the reference form of
/// [`shade_region_texture_rows`], which must reproduce its bits (kept for the tests).
#[cfg(test)]
fn shade_region_texture_scalar(
    set: &TextureSet,
    (filter, anisotropy): (Filter, u32),
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
        let spacing = sample_spacing(gb.samples);
        if anisotropy > 1 {
            let d = [ux * spacing, vx * spacing, uy * spacing, vy * spacing];
            return sampler.sample_anisotropic(tex, d, (gb.u[i], gb.v[i]), anisotropy);
        }
        let (tw, th) = (tex.width as f32 * spacing, tex.height as f32 * spacing);
        let lx2 = (ux * tw) * (ux * tw) + (vx * th) * (vx * th);
        let ly2 = (uy * tw) * (uy * tw) + (vy * th) * (vy * th);
        let lod = lod_from_squares(lx2, ly2, tex.last_level());
        sampler.sample(tex, lod, gb.u[i], gb.v[i])
    };
    let mut rows = Rows::new(dst, pitch, gb.width as usize, gb.height as usize);
    shade_region_per_sample(gb, background, &mut rows, f)
}

/// The texture (RAT) deferred pass over one region into `rows` (`gb.width` x `gb.height`
/// pixels): every visible sample gets its polygon's texture filtered with `filter` at the level
/// of detail from the finite differences of (u, v) between neighbouring samples of the same
/// polygon (`uv_derivatives`), then the samples of each pixel are box-filtered.
///
/// Built like the direct path: blocks of 8 samples of a row, derivatives and texture lookups in
/// [`F32x8`] lanes ([`Sampler::sample8`]), one lane group per distinct polygon of the block
/// (nearly always one), run with the instruction set `isa` (at most AVX2: an AVX-512 build of
/// this pass measured no faster). Every lane performs the scalar operations in the scalar order,
/// so the image has the bits of the sample-by-sample form and does not depend on `isa`.
pub(crate) fn shade_region_texture_rows(
    isa: Isa,
    set: &TextureSet,
    (filter, anisotropy): (Filter, u32),
    gb: &RegionGBuffer,
    background: Vec3,
    rows: &mut Rows<'_>,
) -> ShadeCounts {
    let sampler = Sampler::new(filter);
    isa.run_avx2(TexturePass {
        set,
        sampler: &sampler,
        anisotropy,
        gb,
        background,
        rows,
    })
}

/// The texture pass over one region, as a kernel.
struct TexturePass<'a, 'r> {
    set: &'a TextureSet,
    sampler: &'a Sampler,
    anisotropy: u32,
    gb: &'a RegionGBuffer,
    background: Vec3,
    rows: &'a mut Rows<'r>,
}

impl Kernel for TexturePass<'_, '_> {
    type Output = ShadeCounts;
    #[inline(always)]
    fn run<S: Simd>(self, simd: S) -> ShadeCounts {
        shade_texture_body(
            simd,
            self.set,
            (self.sampler, self.anisotropy),
            self.gb,
            self.background,
            self.rows,
        )
    }
}

/// The squared level-of-detail footprints (`lx2`, `ly2` of [`reconstruction::texture::lod_from_squares`],
/// texels per sample footprint) of `tex` for the lane derivatives `d` = (du/dx, dv/dx, du/dy,
/// dv/dy) per pixel and the samples' `spacing` in pixels ([`sample_spacing`]).
#[inline(always)]
fn footprint8(tex: &RadiosityTexture, d: [F32x8; 4], spacing: f32) -> (F32x8, F32x8) {
    let [ux, vx, uy, vy] = d;
    let tw = F32x8::splat(tex.width as f32 * spacing);
    let th = F32x8::splat(tex.height as f32 * spacing);
    let lx2 = (ux * tw) * (ux * tw) + (vx * th) * (vx * th);
    let ly2 = (uy * tw) * (uy * tw) + (vy * th) * (vy * th);
    (lx2, ly2)
}

/// The texture lookups of 8 samples with (u, v) derivatives `d` per pixel and the samples'
/// `spacing`: isotropic at the footprint's level of detail ([`footprint8`]), or with more than one
/// tap allowed, anisotropic over the footprint (derivatives scaled to one sample's step), both
/// through one inlined sampler.
#[inline(always)]
fn lookup8<S: Simd>(
    simd: S,
    (sampler, anisotropy): (&Sampler, u32),
    tex: &RadiosityTexture,
    (d, spacing): ([F32x8; 4], f32),
    (u, v): (F32x8, F32x8),
    mask: &[bool; LANES],
) -> [F32x8; 3] {
    let fp = if anisotropy > 1 {
        let s = F32x8::splat(spacing);
        Footprint8::Anisotropic {
            d: [d[0] * s, d[1] * s, d[2] * s, d[3] * s],
            max: anisotropy,
        }
    } else {
        let (lx2, ly2) = footprint8(tex, d, spacing);
        Footprint8::Isotropic { lx2, ly2 }
    };
    sampler.sample8_footprint(simd, tex, fp, (u, v), mask)
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
    // `&`, not `&&`: both sides are cheap and a short circuit keeps the loop out of lanes.
    for l in 0..LANES {
        fwd[l] = (bx + l + 1 < w) & (pr[l] == polys[l]);
        bwd[l] = (bx + l > 0) & (pl[l] == polys[l]);
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
        down[l] = (y + 1 < h) & (pd[l] == polys[l]);
        up[l] = (y > 0) & (pu[l] == polys[l]);
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

/// The block of samples showing `polys` at column `bx` of a region `w` wide: whether one
/// polygon covers all 8 lanes inside the region (the common case, tested first in lanes), and
/// otherwise which lanes are empty (no polygon, or padding beyond the region's width, which the
/// scalar pass never reads), as bits (lane l is bit l; 0 for a uniform block).
#[inline(always)]
fn classify<S: Simd>(simd: S, polys: &[u32; LANES], bx: usize, w: usize) -> (bool, u32) {
    let p0 = polys[0];
    let uniform = p0 != NO_POLYGON
        && bx + LANES <= w
        && simd.bits(simd.eq_u(simd.load_u(polys), simd.splat_u(p0))) == ALL_LANES;
    let mut empty = 0u32;
    if !uniform {
        for l in 0..LANES {
            empty |= (((polys[l] == NO_POLYGON) | (bx + l >= w)) as u32) << l;
        }
    }
    (uniform, empty)
}

/// Every lane of a block, as bits.
const ALL_LANES: u32 = (1 << LANES) - 1;

/// The texture pass body, in blocks of 8 with the 8-lane token `simd` (its gather loads the
/// texels).
#[inline(always)]
fn shade_texture_body<S: Simd>(
    simd: S,
    set: &TextureSet,
    (sampler, anisotropy): (&Sampler, u32),
    gb: &RegionGBuffer,
    background: Vec3,
    dst: &mut Rows<'_>,
) -> ShadeCounts {
    const { assert!(S::LANES == LANES, "the texture pass works in blocks of 8") };
    let (w, h, stride) = (gb.width as usize, gb.height as usize, gb.stride as usize);
    let plane = stride * h;
    let spacing = sample_spacing(gb.samples);
    let mut rows = RowOut::new(gb.samples, stride);
    let mut counts = ShadeCounts::default();
    let bg = background.to_array();
    let bg8 = [
        F32x8::splat(bg[0]),
        F32x8::splat(bg[1]),
        F32x8::splat(bg[2]),
    ];
    for y in 0..h {
        let out_row = dst.row(y);
        for si in 0..gb.samples as usize {
            let row = si * plane + y * stride;
            for bx in (0..w).step_by(LANES) {
                let i0 = row + bx;
                let polys: &[u32; LANES] = gb.polygon[i0..i0 + LANES].try_into().unwrap();
                let p0 = polys[0];
                let (uniform, empty) = classify(simd, polys, bx, w);
                let out = if empty == ALL_LANES {
                    bg8
                } else if let (true, Some(tex)) = (uniform, set.textures.get(p0 as usize)) {
                    // The common case: one polygon over the whole block.
                    counts.uniform_blocks += 1;
                    counts.samples_shaded += LANES as u64;
                    let u8x = F32x8(gb.u[i0..i0 + LANES].try_into().unwrap());
                    let v8x = F32x8(gb.v[i0..i0 + LANES].try_into().unwrap());
                    let d = uv_derivatives8_uniform(gb, i0, bx, y, p0);
                    lookup8(
                        simd,
                        (sampler, anisotropy),
                        tex,
                        (d, spacing),
                        (u8x, v8x),
                        &[true; LANES],
                    )
                } else {
                    // Mixed polygons or empty lanes: one lane group per distinct polygon.
                    let u8x = F32x8(gb.u[i0..i0 + LANES].try_into().unwrap());
                    let v8x = F32x8(gb.v[i0..i0 + LANES].try_into().unwrap());
                    let d = uv_derivatives8(gb, i0, bx, y, polys);
                    counts.samples_shaded += (LANES as u32 - empty.count_ones()) as u64;
                    let mut out = bg8;
                    // The empty lanes start done.
                    let mut done = empty;
                    let lanes = simd.load_u(polys);
                    while done != ALL_LANES {
                        let p = polys[(!done & ALL_LANES).trailing_zeros() as usize];
                        let bits = simd.bits(simd.eq_u(lanes, simd.splat_u(p))) & !done;
                        done |= bits;
                        let m: [bool; LANES] = std::array::from_fn(|l| bits >> l & 1 != 0);
                        let c = match set.textures.get(p as usize) {
                            None => [F32x8::splat(0.0); 3],
                            Some(tex) => lookup8(
                                simd,
                                (sampler, anisotropy),
                                tex,
                                (d, spacing),
                                (u8x, v8x),
                                &m,
                            ),
                        };
                        for ch in 0..3 {
                            out[ch] = F32x8::select(&m, c[ch], out[ch]);
                        }
                    }
                    counts.mixed_blocks += 1;
                    out
                };
                rows.block(simd, out_row, bx, si, &out.map(|c| simd.load(&c.0)));
            }
        }
        // Box filter and non-finite clamp, as in the patch path.
        rows.finish_row(simd, out_row);
    }
    counts
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A region mixing three textured polygons of different sizes, a polygon without texture,
    /// empty samples, padding lanes (width 37), 2 samples per pixel, parameters slightly outside
    /// [0, 1] and a NaN, and (u, v) maps whose scale grows across the region so that the level of
    /// detail runs from magnification over fractional levels to the last level.
    fn mixed_texture_region() -> (TextureSet, RegionGBuffer) {
        use reconstruction::texture::{Placement, RadiosityTexture, TextureMemory};
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
                if k != 1 {
                    return RadiosityTexture::from_texels(n, n, t).unwrap();
                }
                // The middle texture with a 2-texel gutter of other values, which edge lookups
                // read instead of clamped copies of the edge texels.
                RadiosityTexture::from_fn(n, Placement::Centre, 2, |u, v| {
                    let h = (u.to_bits() ^ v.to_bits().rotate_left(13)).wrapping_mul(2654435761);
                    Vec3::new((h >> 20) as f32 * 1e-3, (h % 89) as f32 * 0.02 - 0.3, 0.5)
                })
                .unwrap()
            })
            .collect();
        let set = TextureSet {
            textures,
            memory: TextureMemory::of_sides(&sides, 0),
            placement: Placement::Centre,
            gutter: 0,
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
                    // Scale grows with x and y: footprints from 1/16 texel to many texels; the
                    // last two rows step v by 2 a row, past the whole texture even for a
                    // sample's share of a pixel (the last level).
                    let k = 0.002 * (1.0 + 0.05 * xf * xf + 0.3 * yf * yf);
                    let mut u = (xf * k).fract() * 1.04 - 0.02;
                    let v = match y {
                        11.. => 2.0 * yf - 22.5,
                        _ => (yf * k * 0.7 + 0.1 * xf * k).fract() * 1.04 - 0.02,
                    };
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
        use reconstruction::texture::Placement;
        for placement in [Placement::Centre, Placement::Corner] {
            let (mut set, gb) = mixed_texture_region();
            set.placement = placement;
            for t in &mut set.textures {
                t.placement = placement;
            }
            lane_path_equals_scalar_path(&set, &gb);
        }
    }

    fn lane_path_equals_scalar_path(set: &TextureSet, gb: &RegionGBuffer) {
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
                    let [ux, vx, uy, vy] = uv_derivatives(gb, i, x, y);
                    let spacing = sample_spacing(gb.samples);
                    let (tw, th) = (tex.width as f32 * spacing, tex.height as f32 * spacing);
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
        let filters = [
            (Filter::Nearest, 1),
            (Filter::Bilinear, 1),
            (Filter::MITCHELL, 1),
            (Filter::CATMULL_ROM, 1),
            (Filter::Bicubic { b: 0.9, c: 0.05 }, 1),
            // Anisotropic: up to 3 and up to the most taps (lanes of one block take different
            // counts, some one tap).
            (Filter::Bilinear, 3),
            (Filter::MITCHELL, 16),
            (Filter::Nearest, 16),
        ];
        for filter in filters {
            let pitch = w + 3;
            let mut want = vec![Vec3::splat(-7.0); pitch * h];
            let c_want = shade_region_texture_scalar(set, filter, gb, bg, &mut want, pitch);
            for isa in lanes::Level::ALL.into_iter().filter_map(Isa::at) {
                let mut got = vec![Vec3::splat(-7.0); pitch * h];
                let mut rows = Rows::new(&mut got, pitch, w, h);
                let c_got = shade_region_texture_rows(isa, set, filter, gb, bg, &mut rows);
                assert_eq!(c_got.samples_shaded, c_want.samples_shaded, "{filter:?}");
                assert!(
                    c_got.uniform_blocks > 0 && c_got.mixed_blocks > 0,
                    "{c_got:?}"
                );
                for k in 0..pitch * h {
                    assert_eq!(
                        got[k].to_array().map(f32::to_bits),
                        want[k].to_array().map(f32::to_bits),
                        "{filter:?} {}: pixel ({}, {}): {} vs {}",
                        isa.name(),
                        k % pitch,
                        k / pitch,
                        got[k],
                        want[k]
                    );
                }
            }
        }
    }
}
