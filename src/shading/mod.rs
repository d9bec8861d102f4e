//! Shading: the deferred pass, the last stage before the image is written. It reads only a
//! composited region G-buffer ([`RegionGBuffer`]: per sample a polygon id, (u, v) and a slot into
//! the region-local patch table) and evaluates the bicubic radiosity reconstruction patch (RRP) of
//! each sample, then resolves the samples of each pixel with a box filter. It never sees the scene,
//! as PixelFlow's shader boards never saw it: everything a sample needs was written into the region
//! by the rasterizer, so shading cost depends on pixels, not on scene complexity.
//!
//! Invariants: a patch is a power-basis bicubic over local (s, t) in [0, 1]^2; a sample with
//! [`NO_POLYGON`] takes the background colour; the result is a finite, non-negative linear RGB
//! value per pixel. The only clamp of the image sits in the pixel resolve (`sanitize8`): after
//! the box filter, a negative or non-finite channel becomes 0 (bicubic patches and the Mitchell
//! filter can ring below zero next to a sharp shadow; every method passes through it).
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
//!
//! The module is split by shader: [`patches`] (the direct method and the Gouraud mesh: patch
//! tables) and [`texture`] (the RAT filters); this file holds what every shader shares: the
//! [`Shader`] choice, the plane-order accumulation and box-filter resolve every lane shader ends
//! its blocks and rows with, the per-sample form used by the reference shader, and the frame pass over
//! all regions. The two lane shaders keep their own row and block loops: folding them into one
//! generic block driver measured 25-40 % slower on the RRP pass (criterion, `deferred/rrp-1024`),
//! so the loops stay written out.

// Lane loops index several fixed-width arrays with one lane index on purpose: that is the form
// the compiler vectorizes and the reader checks lane by lane.
#![allow(clippy::needless_range_loop)]

pub mod patches;
pub mod texture;

use glam::Vec3;
use rayon::prelude::*;

use crate::lanes::{F32x8, LANES};
use crate::raster::gbuffer::{RegionGBuffer, NO_POLYGON};
use crate::texture::{Filter, TextureSet};

pub use crate::reconstruction::{PatchCoeffs, PatchSource};
pub use patches::{shade_region, shade_region_into};
pub use texture::shade_region_texture_into;

/// The radiosity of a polygon at (u, v), for [`Shader::Reference`].
pub type ReferenceFn<'a> = dyn Fn(u32, f32, f32) -> Vec3 + Sync + 'a;

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
    Reference(&'a ReferenceFn<'a>),
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
        Shader::Reference(func) => {
            let f = |i: usize, _: usize, _: usize| func(gb.polygon[i], gb.u[i], gb.v[i]);
            shade_region_per_sample(gb, background, dst, pitch, f)
        }
    }
}

/// Shades one region sample by sample with `f(index, x, y)` (index into the G-buffer's planes,
/// region-local column and row; called only for samples that see a polygon), accumulating the
/// samples of each pixel in plane order and resolving them exactly as the patch path does (box
/// filter, then the clamp of [`sanitize8`]).
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
            *o = Vec3::from_array(c.to_array().map(sanitize1));
        }
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
/// clamp of [`sanitize8`], and the write of the row's `out.len()` pixels.
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

/// Replaces non-finite and negative lanes (-0.0 included) by +0.0: the one clamp of every image, applied to each
/// resolved pixel. Radiosity is never negative, but a bicubic (a patch next to a sharp shadow
/// edge, or the Mitchell filter across one) can ring below zero, and a patch source with
/// non-finite coefficients must not put NaN or inf into an image.
#[inline(always)]
fn sanitize8(c: F32x8) -> F32x8 {
    let m: [bool; LANES] = std::array::from_fn(|l| c.0[l].is_finite() && c.0[l] > 0.0);
    F32x8::select(&m, c, F32x8::splat(0.0))
}

/// [`sanitize8`] for one value.
#[inline(always)]
fn sanitize1(x: f32) -> f32 {
    if x.is_finite() && x > 0.0 {
        x
    } else {
        0.0
    }
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
        if band < bands && (r.y0 as usize).is_multiple_of(size) && r.x0 + r.width <= width {
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

    #[test]
    fn sanitize_zeroes_exactly_the_non_finite_and_negative_lanes() {
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
        // -0.0 becomes +0.0: no image holds a negative zero either.
        let want = [1.0, 0.0, 0.0, 0.0, 0.0, f32::MAX, sub, 0.0];
        for l in 0..LANES {
            assert_eq!(got.0[l].to_bits(), want[l].to_bits(), "lane {l}");
            assert_eq!(sanitize1(x.0[l]).to_bits(), want[l].to_bits(), "lane {l}");
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
            fn patch(&self, _: u32) -> PatchCoeffs {
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
}
