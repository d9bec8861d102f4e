//! Radiosity textures (RAT, paper sec. 3.4): the comparison backend that stores each polygon's
//! radiosity as a power-of-two texture with a mip chain and filters it on screen, instead of
//! evaluating the RRPs per pixel.
//!
//! Pipeline role: after [`crate`] has built the RRPs, [`TextureSet::build`]
//! resamples every polygon's RRP (not its raw samples) into an N x N level 0 and a mip chain
//! down to 1 x 1, with the texels placed by a [`Placement`]:
//!
//! - [`Placement::Centre`] (default): texel i at u = `(i + 0.5) / N`, the filters map u to
//!   x = u N - 0.5; the chain is box-filtered (`mip_chain`).
//! - [`Placement::Corner`] (the lightmap convention): texel i at u = `i / (N - 1)` (0.5 for
//!   N = 1), the filters map u to x = u (N - 1); the first and last texels lie on the edges.
//!   Each coarser level is resampled from the RRP at its own corner positions
//!   (`corner_chain`): box filtering would not keep the corner alignment. The level of detail
//!   is still log2 of N texels per unit (not N - 1), the same choice of level for both
//!   placements.
//!
//! **Gutters.** Every level of a built texture stores [`GUTTER`] texels beyond each edge
//! ([`MipLevel`]), the RRP reflected through its values on the edge (`MipLevel::reflected`):
//! gutter texel `2 E - T` for the texel T mirrored through the edge and the edge value E beside
//! it. The filters' weights are symmetric about an edge lookup, so the texels inside cancel and
//! the lookup returns the edge values, filtered along the edge: bilinear and Mitchell-Netravali
//! filters both reach the polygon's border, and two polygons whose RRPs share an edge curve
//! (joined seams) meet along it, instead of each clamping half a texel inside. Without the
//! gutter (clamp-to-edge) the two sides of a seam step by about the slope times a texel.
//! The reflection continues the function C1 past the edge and a linear one exactly.
//!
//! Both placements use the same filter code, and clamp-to-edge addressing past the gutter;
//! the placement is recorded in each [`RadiosityTexture`] and in the [`TextureSet`].
//! The deferred pass then calls [`RadiosityTexture::sample`] / [`RadiosityTexture::sample_lod`]
//! with a [`Filter`] and a level of detail from [`lod`]; its hot loop uses the lane form
//! [`Sampler::sample8`] (8 samples per call, module `sample8`), which returns the same bits.
//!
//! Invariants: each side of every texture is a power of two between 1 and
//! [`MAX_TEXTURE_SIZE`]; its chain has `log2(longer side) + 1` levels, the last 1 x 1, all at one
//! placement and one gutter (at most [`MAX_GUTTER`]); all texels are finite (the RRPs are).
//! Sampling never returns NaN or inf: coordinates are clamped to [0, 1] (NaN to 0) and texel
//! indices clamped to the stored texels. Memory ([`TextureMemory`]) counts every stored texel,
//! gutters included, 3 channels.
//!
//! Why this way: the filters are written out (separable 4 x 4 for the bicubic, Mitchell and Netravali 1988)
//! in f32 so that the cost comparison against the direct method measures the same kind of inner
//! loop; the sizes follow the quadtree depth so that a texture holds as many samples as the
//! solution had at its finest level, which is the paper's equal-quality comparison; and the
//! sides follow the polygon's shape ([`Extent`]), so that a texel is about square in the scene
//! and the level of detail, which follows a texel's longer footprint, does not blur a long,
//! narrow polygon along its length.

use glam::Vec3;
use rayon::prelude::*;

use crate::Reconstruction;
use base::error::{Error, Result};
use base::quadtree::SampledQuadtree;
pub use mip::MipLevel;
use mip::*;

mod anisotropic;
mod mip;
mod sample8;
#[cfg(test)]
mod tests;

pub use anisotropic::{Footprint8, MAX_ANISOTROPY};
pub use sample8::Rgb8;

/// The on-screen filters are named with the methods, which the scene loader parses.
pub use base::method::Filter;
/// Where the texels sit (texel centres or the lightmap's corner alignment), an option the scene
/// loader parses as well.
pub use base::method::Placement;
/// Largest texture side any policy produces (4096 x 4096 texels, 192 MiB at 32-bit floats).
/// Deeper quadtrees are clamped to this side under [`SizePolicy::FromDepth`].
pub use base::method::MAX_TEXTURE_SIZE;

/// How each polygon's texture size is chosen. Every policy sets the longer side; the shorter
/// follows the polygon's aspect ([`Extent`]), so texels are about square in the scene.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SizePolicy {
    /// Per polygon the smallest power of two `>= 2^depth + 1`, i.e. a texture with at least as
    /// many texels along its longer side as the polygon's quadtree has samples per side at its
    /// finest level (depth 0: 2 -> 2, depth 3: 9 -> 16). Clamped to [`MAX_TEXTURE_SIZE`].
    FromDepth,
    /// The same longer side for every polygon (the global `--texture-size`); must be a power of
    /// two in `1..=MAX_TEXTURE_SIZE`.
    Fixed(u32),
    /// The largest uniform scale `2^-k` (k >= 0) of the [`SizePolicy::FromDepth`] sides (each
    /// halved k times, not below 1) whose memory at 12 bits per channel **with** mip chains fits
    /// the given number of bytes. Power-of-two scales keep every side a power of two. An error if
    /// even all-1 x 1 textures do not fit.
    Budget(u64),
    /// The [`SizePolicy::FromDepth`] sides scaled by `2^k`: doubled `k` times for `k > 0`
    /// (clamped to [`MAX_TEXTURE_SIZE`]), halved `-k` times for `k < 0` (not below 1). Power-of-two
    /// scales keep every side a power of two; the speed-against-error sweep searches over `k`.
    Scaled(i32),
}

/// The Mitchell–Netravali kernel as polynomial coefficients (Mitchell and Netravali 1988), evaluated in f32.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cubic {
    /// |x| < 1: coefficients of |x|^3, |x|^2, |x|^1, 1 (already divided by 6).
    near: [f32; 4],
    /// 1 <= |x| < 2: coefficients of |x|^3, |x|^2, |x|^1, 1 (already divided by 6).
    far: [f32; 4],
}

impl Cubic {
    /// The kernel for (B, C).
    pub fn new(b: f32, c: f32) -> Cubic {
        Cubic {
            near: [
                (12.0 - 9.0 * b - 6.0 * c) / 6.0,
                (-18.0 + 12.0 * b + 6.0 * c) / 6.0,
                0.0,
                (6.0 - 2.0 * b) / 6.0,
            ],
            far: [
                (-b - 6.0 * c) / 6.0,
                (6.0 * b + 30.0 * c) / 6.0,
                (-12.0 * b - 48.0 * c) / 6.0,
                (8.0 * b + 24.0 * c) / 6.0,
            ],
        }
    }

    /// k(x): 0 outside (-2, 2).
    pub fn k(&self, x: f32) -> f32 {
        let a = x.abs();
        let p = if a < 1.0 {
            self.near
        } else if a < 2.0 {
            self.far
        } else {
            return 0.0;
        };
        ((p[0] * a + p[1]) * a + p[2]) * a + p[3]
    }

    /// The weights k(1 + t), k(t), k(1 - t), k(2 - t) of texels i - 1 .. i + 2 for the fraction
    /// t in [0, 1). Each argument lies in the branch its position fixes (1 + t and 2 - t in
    /// [1, 2], t and 1 - t in [0, 1]), so no branch is taken.
    #[inline(always)]
    pub fn weights(&self, t: f32) -> [f32; 4] {
        let n = |a: f32| ((self.near[0] * a + self.near[1]) * a + self.near[2]) * a + self.near[3];
        let f = |a: f32| ((self.far[0] * a + self.far[1]) * a + self.far[2]) * a + self.far[3];
        [f(1.0 + t), n(t), n(1.0 - t), f(2.0 - t)]
    }
}

/// One polygon's radiosity texture: a power-of-two level 0 (each side a power of two, in the
/// ratio of the polygon's sides, see [`Extent`]) and its mip chain to 1 x 1.
#[derive(Debug, Clone, PartialEq)]
pub struct RadiosityTexture {
    /// Level-0 texels per row.
    pub width: u32,
    /// Level-0 rows.
    pub height: u32,
    /// Levels, finest first; level l is `max(1, width >> l)` x `max(1, height >> l)`.
    pub levels: Vec<MipLevel>,
    /// Where every level's texels sit in (u, v); the filters map coordinates accordingly.
    pub placement: Placement,
}

/// Clamps a texture coordinate into [0, 1]; NaN goes to 0 (documented clamp: a point outside
/// the polygon's parameter square samples its edge).
#[inline(always)]
fn clamp01(x: f32) -> f32 {
    if x.is_nan() {
        0.0
    } else {
        x.clamp(0.0, 1.0)
    }
}

/// Fractional texel position of coordinate `u` on an `n`-texel axis under placement `p`:
/// x = u scale - offset with ([`Placement::texel_map`]) x = u n - 0.5 for centres and
/// x = u (n - 1) for corners; i = floor(x), t = x - i. u must be clamped already.
#[inline(always)]
fn split(u: f32, n: u32, p: Placement) -> (i32, f32) {
    let (scale, offset) = p.texel_map(n);
    let x = u * scale - offset;
    let i = x.floor();
    (i as i32, x - i)
}

/// Index of the texel nearest to coordinate `u` on an `n`-texel axis under placement `p`:
/// floor(x + 0.5) with x as in [`split`], i.e. floor(u n) for centres (u n + 0 has the bits of
/// u n) and floor(u (n - 1) + 0.5) for corners. Not yet clamped to the edge.
#[inline(always)]
fn nearest_index(u: f32, n: u32, p: Placement) -> i32 {
    let (scale, offset) = p.texel_map(n);
    (u * scale + (0.5 - offset)).floor() as i32
}

impl RadiosityTexture {
    /// Resamples polygon `polygon` of `recon` at `width` x `height` with a full mip chain, texels
    /// placed by `placement`, every level with `gutter` texels beyond each edge holding the RRP
    /// reflected through its border values (`MipLevel::reflected`). Each side must be a power
    /// of two in `1..=MAX_TEXTURE_SIZE` and `gutter` at most [`MAX_GUTTER`] (checked by the
    /// callers).
    ///
    /// Centre: level 0 at the texel centres, the chain box-filtered (`mip_chain`); a coarse
    /// texel's footprint is exactly the 2 x 2 fine texels it averages. Corner: every level is
    /// resampled from the RRP at its own corner-aligned positions (`corner_chain`), because
    /// the corner positions i / (n - 1) of a level are not those of the finer level (for n = 8
    /// and 4: sevenths and thirds), so averaging fine texels would move the samples off the
    /// edges and corners.
    pub fn from_rrp(
        recon: &Reconstruction,
        polygon: u32,
        (width, height): (u32, u32),
        placement: Placement,
        gutter: u32,
    ) -> RadiosityTexture {
        let inside = |w: u32, h: u32| match placement {
            Placement::Centre => recon.resample(polygon, w, h),
            Placement::Corner => recon.resample_placed(polygon, w, h, Placement::Corner),
        };
        let edge = |u: f32, v: f32| recon.eval(polygon, u, v);
        RadiosityTexture {
            width,
            height,
            levels: placed_chain((width, height), placement, gutter, inside, edge),
            placement,
        }
    }

    /// A texture of `side` x `side` sampling `f`: [`RadiosityTexture::from_fn_sized`] with both
    /// sides `side`.
    pub fn from_fn(
        side: u32,
        placement: Placement,
        gutter: u32,
        f: impl Fn(f32, f32) -> Vec3,
    ) -> Result<RadiosityTexture> {
        Self::from_fn_sized((side, side), placement, gutter, f)
    }

    /// A texture of `width` x `height` (each a power of two in `1..=MAX_TEXTURE_SIZE`) sampling
    /// the function `f(u, v)` at the texel positions of `placement`
    /// ([`Placement::texel_position`]), with the chain and the gutters
    /// [`RadiosityTexture::from_rrp`] builds (`f` is called on [0, 1]^2 only, its border
    /// included). Errors for a bad side, a gutter above [`MAX_GUTTER`] or a non-finite value.
    pub fn from_fn_sized(
        (width, height): (u32, u32),
        placement: Placement,
        gutter: u32,
        f: impl Fn(f32, f32) -> Vec3,
    ) -> Result<RadiosityTexture> {
        check_side(width)?;
        check_side(height)?;
        check_gutter(gutter)?;
        let inside = |w: u32, h: u32| -> Vec<Vec3> {
            let mut t = Vec::with_capacity(w as usize * h as usize);
            for j in 0..h {
                let v = placement.texel_position(j, h);
                for i in 0..w {
                    t.push(f(placement.texel_position(i, w), v));
                }
            }
            t
        };
        let levels = placed_chain((width, height), placement, gutter, inside, &f);
        if levels
            .iter()
            .any(|l| l.texels.iter().any(|t| !t.is_finite()))
        {
            return Err(Error::Inconsistent("texture texel is not finite".into()));
        }
        Ok(RadiosityTexture {
            width,
            height,
            levels,
            placement,
        })
    }

    /// A texture from a given level 0 at the texel centres ([`Placement::Centre`]; mip chain
    /// box-filtered down to 1 x 1). Errors if the size
    /// is not a power of two in `1..=MAX_TEXTURE_SIZE` per axis, if `texels.len()` is not
    /// `width * height`, or if a texel is not finite.
    pub fn from_texels(width: u32, height: u32, texels: Vec<Vec3>) -> Result<RadiosityTexture> {
        for n in [width, height] {
            check_side(n)?;
        }
        if texels.len() != width as usize * height as usize {
            return Err(Error::Inconsistent(format!(
                "texture of {width} x {height} needs {} texels, got {}",
                width as usize * height as usize,
                texels.len()
            )));
        }
        if texels.iter().any(|t| !t.is_finite()) {
            return Err(Error::Inconsistent("texture texel is not finite".into()));
        }
        Ok(RadiosityTexture {
            width,
            height,
            levels: mip_chain(MipLevel {
                width,
                height,
                gutter: 0,
                texels,
            }),
            placement: Placement::Centre,
        })
    }

    /// A centre-placed texture from a stored level 0 with its gutter (as a texture atlas holds
    /// it, see [`RadiosityTexture::from_rrp`]): the chain is box-filtered from the level's
    /// texels inside the gutter and every coarser level's gutter reflected through the edge
    /// values read back from level 0's gutter, so the texture equals the one `from_rrp` built
    /// (to within a rounding of each gutter texel) without the RRP. Errors for a side that is
    /// not a power of two in `1..=MAX_TEXTURE_SIZE`, a gutter above [`MAX_GUTTER`], a texel
    /// count other than stride x rows, or a non-finite texel.
    pub fn from_stored_level0(level0: MipLevel) -> Result<RadiosityTexture> {
        check_side(level0.width)?;
        check_side(level0.height)?;
        check_gutter(level0.gutter)?;
        if level0.texels.len() as u64 != level0.stored() {
            return Err(Error::Inconsistent(format!(
                "stored texture needs {} texels with its gutter, got {}",
                level0.stored(),
                level0.texels.len()
            )));
        }
        if level0.texels.iter().any(|t| !t.is_finite()) {
            return Err(Error::Inconsistent("texture texel is not finite".into()));
        }
        let (w, h, g) = (level0.width, level0.height, level0.gutter);
        let mut inside = Vec::with_capacity(w as usize * h as usize);
        for j in 0..h as i32 {
            inside.extend((0..w as i32).map(|i| level0.texel(i, j)));
        }
        let square = mip_chain(MipLevel {
            width: w,
            height: h,
            gutter: 0,
            texels: inside,
        });
        let levels = if g == 0 {
            square
        } else {
            centre_gutters(square, g, EdgeValues::of_centre_gutter(&level0))
        };
        Ok(RadiosityTexture {
            width: w,
            height: h,
            levels,
            placement: Placement::Centre,
        })
    }

    /// Index of the last (1 x 1) level.
    pub fn last_level(&self) -> usize {
        self.levels.len() - 1
    }

    /// Texels stored over all levels, gutters included.
    pub fn texels_with_chain(&self) -> u64 {
        self.levels.iter().map(MipLevel::stored).sum()
    }

    /// Filtered value at (u, v) of level `level` (clamped to the last level). u and v are clamped
    /// to [0, 1] (NaN to 0) and texel fetches clamp to the edge, so the result is finite.
    pub fn sample(&self, level: usize, u: f32, v: f32, filter: Filter) -> Vec3 {
        let l = &self.levels[level.min(self.last_level())];
        let (u, v) = (clamp01(u), clamp01(v));
        let p = self.placement;
        match filter {
            Filter::Nearest => nearest(l, p, u, v),
            Filter::Bilinear => bilinear(l, p, u, v),
            Filter::Bicubic { b, c } => bicubic(l, p, u, v, &Cubic::new(b, c)),
        }
    }

    /// Samples `uv.len().min(out.len())` points of level `level`: `out[k] = sample(level, uv[k])`,
    /// with the level lookup, the filter match and the cubic's coefficients hoisted out of the
    /// loop (the form the deferred pass uses for a run of pixels).
    pub fn sample_many(&self, level: usize, uv: &[[f32; 2]], filter: Filter, out: &mut [Vec3]) {
        let l = &self.levels[level.min(self.last_level())];
        let pl = self.placement;
        let pts = uv.iter().zip(out.iter_mut());
        match filter {
            Filter::Nearest => {
                pts.for_each(|(p, o)| *o = nearest(l, pl, clamp01(p[0]), clamp01(p[1])))
            }
            Filter::Bilinear => {
                pts.for_each(|(p, o)| *o = bilinear(l, pl, clamp01(p[0]), clamp01(p[1])))
            }
            Filter::Bicubic { b, c } => {
                let k = Cubic::new(b, c);
                pts.for_each(|(p, o)| *o = bicubic(l, pl, clamp01(p[0]), clamp01(p[1]), &k))
            }
        }
    }

    /// Trilinear-style sampling at a fractional level of detail (from [`lod`]): the filtered
    /// values of levels floor(lod) and floor(lod) + 1 blended linearly by the fraction. `lod` is
    /// clamped to [0, last level] (NaN to 0). Chosen over nearest-level selection because it has
    /// no visible seams where the selected level changes across a polygon.
    pub fn sample_lod(&self, lod_value: f32, u: f32, v: f32, filter: Filter) -> Vec3 {
        let last = self.last_level();
        let d = if lod_value.is_nan() {
            0.0
        } else {
            lod_value.clamp(0.0, last as f32)
        };
        let l0 = (d.floor() as usize).min(last);
        let f = d - l0 as f32;
        let a = self.sample(l0, u, v, filter);
        if f <= 0.0 || l0 == last {
            return a;
        }
        let b = self.sample(l0 + 1, u, v, filter);
        a + (b - a) * f
    }
}

/// A [`Filter`] prepared for many lookups (the cubic's coefficients computed once), with the
/// level-of-detail policy of the deferred pass: nearest filtering takes the nearest mip level
/// (`round(lod)`, like `GL_NEAREST_MIPMAP_NEAREST`); bilinear and bicubic blend the two nearest
/// levels ([`RadiosityTexture::sample_lod`], like `GL_LINEAR_MIPMAP_LINEAR`). Under magnification
/// (lod 0) every filter reads level 0 once.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sampler {
    /// The filter.
    pub filter: Filter,
    cubic: Cubic,
}

impl Sampler {
    /// A sampler for `filter`.
    pub fn new(filter: Filter) -> Sampler {
        let cubic = match filter {
            Filter::Bicubic { b, c } => Cubic::new(b, c),
            _ => Cubic::new(1.0 / 3.0, 1.0 / 3.0),
        };
        Sampler { filter, cubic }
    }

    #[inline(always)]
    fn level(&self, l: &MipLevel, p: Placement, u: f32, v: f32) -> Vec3 {
        let (u, v) = (clamp01(u), clamp01(v));
        match self.filter {
            Filter::Nearest => nearest(l, p, u, v),
            Filter::Bilinear => bilinear(l, p, u, v),
            Filter::Bicubic { .. } => bicubic(l, p, u, v, &self.cubic),
        }
    }

    /// The filtered value of `tex` at (u, v) and level of detail `lod` (clamped to the chain, NaN
    /// to 0). Equals [`RadiosityTexture::sample_lod`] for bilinear and bicubic filters, and
    /// [`RadiosityTexture::sample`] at level `round(lod)` for the nearest filter.
    #[inline]
    pub fn sample(&self, tex: &RadiosityTexture, lod: f32, u: f32, v: f32) -> Vec3 {
        let last = tex.last_level();
        let d = if lod.is_nan() {
            0.0
        } else {
            lod.clamp(0.0, last as f32)
        };
        if let Filter::Nearest = self.filter {
            return self.level(
                &tex.levels[(d.round() as usize).min(last)],
                tex.placement,
                u,
                v,
            );
        }
        let l0 = (d.floor() as usize).min(last);
        let f = d - l0 as f32;
        let a = self.level(&tex.levels[l0], tex.placement, u, v);
        if f <= 0.0 || l0 == last {
            return a;
        }
        let b = self.level(&tex.levels[l0 + 1], tex.placement, u, v);
        a + (b - a) * f
    }
}

/// [`lod`] from squared footprint lengths: `lx2 = |(W du/dx, H dv/dx)|^2` and `ly2` likewise in
/// y (texels per pixel, squared), for a chain whose last level is `last`. Magnification (both
/// <= 1) gives 0; NaN gives 0 and infinity the last level. The result is in [0, last], never
/// NaN.
///
/// Branch-free, with the logarithm of [`log2_above_one`], so that the deferred pass computes
/// it for 8 lanes at once with the bits of this scalar form (the library's `log2` is a call
/// per lane).
#[inline(always)]
pub fn lod_from_squares(lx2: f32, ly2: f32, last: usize) -> f32 {
    // `f32::max` skips a NaN; `r2 > 1` is false for a NaN.
    let r2 = lx2.max(ly2);
    let minified = r2 > 1.0;
    let lod = (0.5 * log2_above_one(if minified { r2 } else { 2.0 })).min(last as f32);
    if minified {
        lod
    } else {
        0.0
    }
}

/// log2(x) for x > 1 (+inf gives 128), within 2e-7 of the exact value, written in plain
/// arithmetic and bit operations so that a loop over lanes vectorizes: x = 2^e m with m in
/// [sqrt(1/2), sqrt(2)), and log2(m) = 2 / ln 2 artanh(t) with t = (m - 1) / (m + 1), |t| <=
/// 0.172, by its series to t^9 (the next term is below 1e-9). Positive for every x > 1.
#[inline(always)]
pub fn log2_above_one(x: f32) -> f32 {
    use std::f32::consts::{LN_2, SQRT_2};
    let bits = x.to_bits();
    let m = f32::from_bits((bits & 0x007f_ffff) | 0x3f80_0000);
    let high = m > SQRT_2;
    let e = (bits >> 23) as i32 - 127 + high as i32;
    let m = if high { m * 0.5 } else { m };
    let t = (m - 1.0) / (m + 1.0);
    let t2 = t * t;
    let c = |k: f32| 2.0 / (k * LN_2);
    let series = c(1.0) + t2 * (c(3.0) + t2 * (c(5.0) + t2 * (c(7.0) + t2 * c(9.0))));
    e as f32 + t * series
}

/// Level of detail from screen-space derivatives of (u, v): with the texture of `width` x
/// `height` texels at level 0, rho = max(|(du/dx, dv/dx)|, |(du/dy, dv/dy)|) in texels per pixel
/// and lod = log2(rho), clamped to [0, log2(max(width, height))] (the last level of a
/// power-of-two chain). Non-finite derivatives or rho give 0 (the finest level).
pub fn lod(du_dx: f32, dv_dx: f32, du_dy: f32, dv_dy: f32, width: u32, height: u32) -> f32 {
    let (w, h) = (width.max(1) as f32, height.max(1) as f32);
    let lx = (du_dx * w).hypot(dv_dx * h);
    let ly = (du_dy * w).hypot(dv_dy * h);
    let rho = lx.max(ly);
    let last = width.max(height).max(1).ilog2() as f32;
    let d = rho.log2();
    if d.is_nan() {
        0.0
    } else {
        d.clamp(0.0, last)
    }
}

fn nearest(l: &MipLevel, p: Placement, u: f32, v: f32) -> Vec3 {
    // Centre: floor(u n), with u = 1 mapped onto the last texel of the square (never the
    // gutter: the nearest texel of a point of the square is in the square).
    let i = nearest_index(u, l.width, p).clamp(0, l.width as i32 - 1);
    let j = nearest_index(v, l.height, p).clamp(0, l.height as i32 - 1);
    l.texel(i, j)
}

fn bilinear(l: &MipLevel, p: Placement, u: f32, v: f32) -> Vec3 {
    let (i, s) = split(u, l.width, p);
    let (j, t) = split(v, l.height, p);
    let a = l.texel(i, j) * (1.0 - s) + l.texel(i + 1, j) * s;
    let b = l.texel(i, j + 1) * (1.0 - s) + l.texel(i + 1, j + 1) * s;
    a * (1.0 - t) + b * t
}

/// Separable 4 x 4: each of the 4 rows j - 1 .. j + 2 is filtered horizontally with the u
/// weights, then the 4 row results vertically with the v weights. The column indices are clamped
/// once; the row loop is fixed-length so the compiler unrolls it.
fn bicubic(l: &MipLevel, p: Placement, u: f32, v: f32, k: &Cubic) -> Vec3 {
    let (i, s) = split(u, l.width, p);
    let (j, t) = split(v, l.height, p);
    let wu = k.weights(s);
    let wv = k.weights(t);
    let (g, stride) = (l.gutter as i32, l.stride() as usize);
    let wmax = stride as i32 - 1;
    let hmax = l.rows() as i32 - 1;
    let cols: [usize; 4] = std::array::from_fn(|a| (i - 1 + a as i32 + g).clamp(0, wmax) as usize);
    let mut acc = Vec3::ZERO;
    for (b, &wy) in wv.iter().enumerate() {
        let row = (j - 1 + b as i32 + g).clamp(0, hmax) as usize * stride;
        let r = &l.texels[row..row + stride];
        let h = r[cols[0]] * wu[0] + r[cols[1]] * wu[1] + r[cols[2]] * wu[2] + r[cols[3]] * wu[3];
        acc += h * wy;
    }
    acc
}

/// Largest gutter a texture may have (texels beyond each edge).
pub const MAX_GUTTER: u32 = 4;

/// The gutter of the textures [`TextureSet::build`] makes: 2 texels beyond each edge of every
/// level, what the 4 x 4 bicubic footprint reaches at an edge (under centre placement u = 0
/// maps to x = -0.5, the taps run from -2 to 1); bilinear filtering reads the first of them.
/// Filled by `MipLevel::reflected` (module docs), the filters at a polygon's edge return the RRP's value
/// on the edge, from both polygons of a seam, instead of the value half a texel inside
/// (clamp-to-edge).
pub const GUTTER: u32 = 2;

fn check_gutter(g: u32) -> Result<()> {
    if g > MAX_GUTTER {
        return Err(Error::invalid_option(
            "gutter",
            g.to_string(),
            format!("is above {MAX_GUTTER} texels"),
        ));
    }
    Ok(())
}

fn check_side(n: u32) -> Result<()> {
    base::method::check_texture_side("texture-size", n)
}

/// Side chosen by [`SizePolicy::FromDepth`] for a quadtree of the given depth: the smallest power
/// of two `>= 2^depth + 1`, clamped to [`MAX_TEXTURE_SIZE`].
pub(crate) fn side_from_depth(depth: u32) -> u32 {
    if depth >= MAX_TEXTURE_SIZE.ilog2() {
        return MAX_TEXTURE_SIZE;
    }
    ((1u32 << depth) + 1).next_power_of_two()
}

/// `n` (a power of two) times `2^k`, within `1..=MAX_TEXTURE_SIZE`.
fn scale_side(n: u32, k: i32) -> u32 {
    let n = n.clamp(1, MAX_TEXTURE_SIZE) as u64;
    let shift = k.unsigned_abs().min(32);
    let s = if k >= 0 { n << shift } else { n >> shift };
    s.clamp(1, MAX_TEXTURE_SIZE as u64) as u32
}

/// Largest [`Extent::aspect`] (in either direction): a polygon 4096 times longer than wide
/// already has one texel across at the largest side.
pub const MAX_ASPECT: i32 = 12;

/// What one polygon's texture size is chosen from: the depth of its quadtree and the shape of
/// its parameter square in the scene.
///
/// Why the shape: a texture's level of detail follows the larger of its two texel footprints
/// on screen, so a square texture on a polygon 20 times longer than wide (a strip of floor
/// beside a table leg, cut off by the leg's contact lines) is filtered at the level where one
/// texel spans the strip's width, which is 20 pixels along its length: a shadow crossing the
/// strip was drawn 20 pixels wide. With the sides in the ratio of the polygon's, a texel
/// covers about a square of the scene and the level of detail blurs neither axis more than a
/// pixel.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Extent {
    /// Quadtree depth (see [`TextureSet::extents`]): sets the longer side.
    pub depth: u32,
    /// log2 of how many times longer the u axis is than the v axis in the scene, rounded toward
    /// zero (negative: v is the longer), within `-MAX_ASPECT..=MAX_ASPECT`: the shorter side is
    /// the longer one halved `|aspect|` times (not below 1), so a texel is never longer across
    /// than along.
    pub aspect: i32,
}

impl Extent {
    /// The aspect of a quad: `trunc(log2(|dP/du| / |dP/dv|))` at the centre of its parameter
    /// square (the vector means of its opposite sides), clamped to [`MAX_ASPECT`]; 0 for a
    /// degenerate quad. For a parallelogram with sides a (along u) and b this makes the texels'
    /// footprints in the scene about square: a texel is |a| / width by |b| / height.
    ///
    /// A triangle is 0, square: its collapsed square is skewed (near its apex both axes run
    /// the same way), which no choice of sides undoes, and its lightmap chart is an affine
    /// square (`export::atlas`) whose gutters reflect through the nearest point in a square
    /// metric.
    pub fn aspect_of(polygon: &scene::Polygon) -> i32 {
        if polygon.shape == scene::Shape::Triangle {
            return 0;
        }
        let (du, dv) = polygon.tangents(0.5, 0.5);
        let r = (du.length() / dv.length()).log2();
        if !r.is_finite() {
            return 0;
        }
        (r.trunc() as i32).clamp(-MAX_ASPECT, MAX_ASPECT)
    }

    /// The texture size (width along u, height along v) whose longer side is `long` (a power of
    /// two) and whose shorter is `long` halved `|aspect|` times, not below 1.
    pub fn size(self, long: u32) -> (u32, u32) {
        let short = (long >> self.aspect.unsigned_abs().min(31)).max(1);
        if self.aspect >= 0 {
            (long, short)
        } else {
            (short, long)
        }
    }
}

/// Texture memory: every texel stored, 3 channels, at 8, 12 and 32 bits per channel. The
/// textures are power-of-two blocks as the paper's hardware stored them; the gutters
/// ([`GUTTER`]) add `2 g (w + h) + 4 g^2` texels to a level of w x h, counted here (a 2 x 2
/// texture with a 2-texel gutter stores 36 texels at level 0, a 64 x 64 one 4,624). Bytes are
/// rounded up to whole bytes per texture (matters only for 12 bits and odd texel counts, e.g. a
/// 1 x 1 texture without gutter: 36 bits -> 5 bytes).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
pub struct TextureMemory {
    /// Number of textures (one per polygon).
    pub textures: usize,
    /// Level-0 texels of all textures, gutters included.
    pub texels: u64,
    /// Texels including every mip level and its gutter (without gutters, for square
    /// power-of-two sides n: (4 n^2 - 1) / 3 each, i.e. level 0 plus about 1/3).
    pub texels_with_chain: u64,
    /// Level 0 only, [8, 12, 32] bits per channel, bytes.
    pub bytes: [u64; 3],
    /// With mip chains, [8, 12, 32] bits per channel, bytes.
    pub bytes_with_chain: [u64; 3],
}

/// Bits per channel of [`TextureMemory::bytes`] entries, in order.
pub(crate) const CHANNEL_BITS: [u64; 3] = [8, 12, 32];

impl TextureMemory {
    /// Memory of square textures with the given sides (each a power of two), every level with
    /// `gutter` texels beyond each edge.
    pub fn of_sides(sides: &[u32], gutter: u32) -> TextureMemory {
        let sizes: Vec<(u32, u32)> = sides.iter().map(|&n| (n, n)).collect();
        Self::of_sizes(&sizes, gutter)
    }

    /// Memory of textures of the given sizes (width, height; each a power of two), every level
    /// with `gutter` texels beyond each edge; level l of w x h is `max(1, w >> l)` x
    /// `max(1, h >> l)`, down to 1 x 1.
    pub fn of_sizes(sizes: &[(u32, u32)], gutter: u32) -> TextureMemory {
        let mut m = TextureMemory {
            textures: sizes.len(),
            ..Default::default()
        };
        let g = 2 * gutter as u64;
        let stored = |w: u64, h: u64| (w + g) * (h + g);
        for &(w, h) in sizes {
            let (mut w, mut h) = (w.max(1) as u64, h.max(1) as u64);
            let base = stored(w, h);
            let mut chain = 0u64;
            loop {
                chain += stored(w, h);
                if w == 1 && h == 1 {
                    break;
                }
                (w, h) = ((w / 2).max(1), (h / 2).max(1));
            }
            m.texels += base;
            m.texels_with_chain += chain;
            for (k, bits) in CHANNEL_BITS.iter().enumerate() {
                m.bytes[k] += (base * 3 * bits).div_ceil(8);
                m.bytes_with_chain[k] += (chain * 3 * bits).div_ceil(8);
            }
        }
        m
    }
}

/// The radiosity textures of every polygon of a scene, in scene polygon order.
#[derive(Debug, Clone, PartialEq)]
pub struct TextureSet {
    /// One texture per polygon.
    pub textures: Vec<RadiosityTexture>,
    /// Their memory.
    pub memory: TextureMemory,
    /// Where the texels of every texture sit (all textures of a set share it).
    pub placement: Placement,
    /// Texels beyond each edge of every level of every texture ([`GUTTER`] when built).
    pub gutter: u32,
}

impl TextureSet {
    /// Drops every texture's mip chain, keeping level 0: every lookup then reads level 0 whatever
    /// the footprint (the level of detail clamps to the last level), as with mip-mapping off.
    /// [`TextureSet::memory`] is unchanged; a chainless set holds `memory.bytes`.
    pub fn drop_mip_chains(&mut self) {
        for t in &mut self.textures {
            t.levels.truncate(1);
        }
    }

    /// The [`Extent`] of each polygon of a solution: its quadtree depth capped at `max_depth`
    /// (the scene's `radiosity.max_depth`) and its aspect in the scene (`polygons`, in the same
    /// order): the input of [`TextureSet::build`]. Leaves past the cap are the solver's dives
    /// to a light's peak, a spot's cone edge or a penumbra's edge over a small area; a texture
    /// as fine as them would hold the whole polygon at that resolution (the gallery's textures
    /// grew from 0.2 MB to 142 MB that way), while the texture methods' error is set by the
    /// bulk of the polygon. Errors if the two lists differ in length.
    pub fn extents(
        trees: &[SampledQuadtree],
        polygons: &[scene::Polygon],
        max_depth: u32,
    ) -> Result<Vec<Extent>> {
        if trees.len() != polygons.len() {
            return Err(Error::Inconsistent(format!(
                "{} quadtrees for {} polygons",
                trees.len(),
                polygons.len()
            )));
        }
        Ok(trees
            .iter()
            .zip(polygons)
            .map(|(t, p)| Extent {
                depth: t.tree.depth().min(max_depth),
                aspect: Extent::aspect_of(p),
            })
            .collect())
    }

    /// The per-polygon sizes (width, height) `policy` chooses for the given extents: the
    /// policy sets the longer side, the aspect the shorter ([`Extent::size`]).
    ///
    /// Errors ([`Error::InvalidOption`]): a `Fixed` size that is not a power of two in
    /// `1..=MAX_TEXTURE_SIZE`; a `Budget` that even 1 x 1 textures exceed.
    pub fn sizes(extents: &[Extent], policy: SizePolicy) -> Result<Vec<(u32, u32)>> {
        let scaled = |k: u32| -> Vec<(u32, u32)> {
            extents
                .iter()
                .map(|e| e.size((side_from_depth(e.depth) >> k).max(1)))
                .collect()
        };
        match policy {
            SizePolicy::FromDepth => Ok(scaled(0)),
            SizePolicy::Fixed(n) => {
                check_side(n)?;
                Ok(extents.iter().map(|e| e.size(n)).collect())
            }
            SizePolicy::Budget(bytes) => {
                for k in 0..=MAX_TEXTURE_SIZE.ilog2() {
                    let s = scaled(k);
                    if TextureMemory::of_sizes(&s, GUTTER).bytes_with_chain[1] <= bytes {
                        return Ok(s);
                    }
                }
                Err(Error::invalid_option(
                    "texture-budget",
                    bytes.to_string(),
                    format!(
                        "is below {} bytes, the size of {} 1 x 1 textures at 12 bits per channel",
                        TextureMemory::of_sides(&vec![1; extents.len()], GUTTER).bytes_with_chain
                            [1],
                        extents.len()
                    ),
                ))
            }
            SizePolicy::Scaled(k) => Ok(extents
                .iter()
                .map(|e| e.size(scale_side(side_from_depth(e.depth), k)))
                .collect()),
        }
    }

    /// Builds every polygon's texture by resampling its RRP at the size `policy` chooses from
    /// `extents` (one per polygon, see [`TextureSet::extents`]) at the texel positions of
    /// `placement`, with mip chains ([`RadiosityTexture::from_rrp`]), in parallel. Errors if
    /// `extents.len()` differs from the polygon count or as [`TextureSet::sizes`].
    pub fn build(
        recon: &Reconstruction,
        extents: &[Extent],
        policy: SizePolicy,
        placement: Placement,
    ) -> Result<TextureSet> {
        if extents.len() != recon.polygon_count() {
            return Err(Error::Inconsistent(format!(
                "{} texture extents for {} polygons",
                extents.len(),
                recon.polygon_count()
            )));
        }
        let sizes = Self::sizes(extents, policy)?;
        // One independent job per polygon; collect keeps polygon order, so the result does not
        // depend on the thread count.
        let textures = sizes
            .par_iter()
            .enumerate()
            .map(|(p, &n)| RadiosityTexture::from_rrp(recon, p as u32, n, placement, GUTTER))
            .collect();
        Ok(TextureSet {
            textures,
            memory: TextureMemory::of_sizes(&sizes, GUTTER),
            placement,
            gutter: GUTTER,
        })
    }
}
