//! Reconstruction: turns each polygon's adaptive radiosity samples ([`SampledQuadtree`]) into a
//! continuous, C1 function made of bicubic Hermite patches (the paper's reconstructed radiosity
//! patches, RRPs, sec. 3.3-3.5), which the rasterizer evaluates per pixel and the texture backend
//! resamples.
//!
//! Pipeline per polygon, all in f64:
//! 1. `estimate`: Hermite data (value, f_u, f_v, twist f_uv) at every original sample, in global
//!    parameter units, one set per vertex shared by every patch touching it ([`Estimator`]);
//! 2. [`seam`] (with [`Reconstruction::build_with`]): border points shared with coplanar
//!    neighbours of one material get one set of data, computed once across the polygons, so the
//!    neighbours are one C1 function (every polygon's estimate first, then this one ordered
//!    pass, then refinement in parallel again);
//! 3. `refine`: leaves with a T-vertex inside an edge are midpoint-subdivided, new points take
//!    their data from the parent polynomial (C1 argument in that module), and subtrees whose data
//!    equal their parent polynomial are merged back, so flat regions cost one patch. With
//!    [`Sharp`] light (spots, known exactly at any point), steps 1-3 run on the samples minus
//!    that light, and [`sharp`] adds it back before merging, splitting the leaves that straddle
//!    its edges (a cone's rim, hard shadows) a few levels deeper;
//! 4. each final leaf becomes a [`PatchCoeffs`]: the bicubic in power basis over local (s, t),
//!    stored as f32 (3 x 16 coefficients + origin and inverse width, 208 bytes).
//!
//! What is stored: the power-basis patches and a 4-byte-per-node tree for [`Reconstruction::locate`];
//! the per-vertex Hermite data are derived, used during construction and dropped
//! ([`ReconstructionStats`] reports what storing them instead would cost). [`compact`] holds the
//! same patches as the trees plus the vertex data (stored as 16-bit mantissas with a per-vertex
//! shift, T-vertices derived from their larger leaf) and expands them on demand.
//!
//! Invariants: every original sample is reproduced at its vertex (to f32 rounding, or to the merge
//! tolerance of 1e-7 of the polygon's largest value; on a joined seam, the mean of the two
//! polygons' samples there, which agree within [`seam::SAMPLE_AGREEMENT`]); linear functions are
//! reproduced exactly on any tree; an undivided polygon is the bilinear interpolant of its
//! corners (every estimator); no coefficient is NaN or infinite (checked; construction fails
//! otherwise). Evaluation clamps (u, v) into [0, 1]^2 (NaN to 0) and local (s, t) into
//! [0, 1]^2, so border values are the patch's edge values. Nothing is clamped in value: the plain estimator can overshoot (ring below zero) near
//! sharp shadow edges, the limited ones far less; the one clamp of an image (negative to 0) sits
//! in the shading stage's pixel resolve.
//!
//! Default estimator: [`Estimator::Hyman`], chosen by measurement
//! (`cargo test --release overshoot_report -- --nocapture`; depth-7 trees refined by a bilinear
//! error criterion of 1e-3, sampled values in [0, 1], 513^2 evaluation grid; overshoot is the
//! excursion beyond the sample range as a fraction of it, rms error against the true function):
//!
//! | function  | Plain overshoot | Plain rms | Monotone overshoot | Monotone rms | Hyman overshoot | Hyman rms |
//! |-----------|-----------------|-----------|--------------------|--------------|-----------------|-----------|
//! | step      | 118 %           | 2.8e-1    | 0 %                | 1.4e-2       | 0 %             | 1.4e-2    |
//! | spot      | 3.6 %           | 2.0e-3    | 0.18 %             | 1.5e-3       | 0.42 %          | 8.2e-4    |
//! | two-spots | 0.09 %          | 8.5e-5    | 0.03 %             | 1.1e-4       | 0.05 %          | 7.3e-5    |
//!
//! and on real solutions (`cargo test --release -p pixelflow-app --test library closed_form`
//! and `… reconstruction_scenes`, `--nocapture`): an area light over a floor, largest error
//! 3.1e-4 of the peak with Hyman, 2.9e-4 plain, 2.6e-3 Fritsch-Butland (whose harmonic mean
//! flattens every smooth maximum); the largest overshoot over every polygon of the shipped
//! scenes, relative to the polygon's sample range, Hyman 0 / 7e-9 / 7.0e-3 (two-spots,
//! cornell-box, gallery), Fritsch-Butland 0 / 1.4e-7 / 6.2e-3, plain 0 / 0.26 / 0.14. On the
//! paper's Fig. 6 data (an 8 x 8 grid) Hyman's image is 8 % further from the exact one than the
//! other two's: coarse samples of a peak are where its clipped central slope and zero twist cost.
//!
//! Hyman's filter keeps the central difference wherever it lies inside Fritsch and Carlson's
//! monotone box (|slope| <= 3x the smaller secant, secants of one sign), so it is as accurate as
//! central differences on smooth data and monotone in 1-D where the data turn or jump. The twist
//! is the central one unless an axis's secants differ in sign or by more than 2x (then 0): keeping
//! a central twist beside a clipped slope rang up to 5 % of a polygon's range on the Cornell box.
//!
//! On unrestricted trees the plain estimator is much worse than Catmull-Rom's 7.4 % on a uniform
//! step: a derivative estimated at the finest leaf width next to a discontinuity is scaled by the
//! width of a coarse neighbouring patch. At a vertex that is a corner of the leaves on both sides
//! along an axis, the limited estimators' secants are exactly those leaves' own secants (g is
//! bilinear inside each leaf), so a slope within 3x (Hyman) or 2x (Fritsch-Butland) the smaller
//! secant keeps every patch inside Fritsch-Carlson's monotone region and axis-aligned steps stay
//! in range; they ring slightly only in 2-D.

//! The Gouraud mesh comparison backend (the paper's "poly" model) lives in [`mesh`]: the same
//! quadtrees triangulated without cracks, one degree-(1, 1) patch per triangle.
//!
//! Resampling ([`Reconstruction::resample`]) evaluates a polygon's RRP at texel centres; the
//! texture stage builds its mip chains from that.

pub mod compact;
mod estimate;
mod hermite;
pub mod mesh;
mod refine;
pub mod seam;
pub mod sharp;
pub mod texture;

pub use compact::PatchCache;
pub use seam::Seams;
pub use sharp::{Sharp, SharpLight};
#[cfg(test)]
mod tests;

use glam::Vec3;
use rayon::prelude::*;

use base::error::{Error, Result};
use base::method::Placement;
use base::quadtree::{SampledQuadtree, LATTICE, MAX_DEPTH};
use estimate::Samples;
use hermite::{HermiteData, PatchPoly};
use refine::Refined;

/// How vertex derivatives are estimated from the samples. [`Estimator::Monotone`] is the
/// default; the module docs give the measurement behind that choice.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Estimator {
    /// Central differences of the piecewise-bilinear interpolant at the smallest adjacent leaf
    /// width (Catmull-Rom on regular grids); one-sided at the border. Most accurate on smooth
    /// data, overshoots at steps.
    Plain,
    /// Fritsch-Butland harmonic mean of the two secants per axis (0 at extrema), twist 0 where an
    /// axis was limited; one-sided at the border. No overshoot on axis-aligned steps.
    Monotone,
    /// Hyman's filter of the central difference: the central slope where the data are monotone
    /// and it lies within 3x the smaller secant, clipped to that bound otherwise, 0 where the
    /// data turn; one-sided at the border; zero twist except at the domain's corners. About as
    /// accurate as central differences on smooth data, monotone at steps.
    #[default]
    Hyman,
}

impl Estimator {
    /// Every estimator, in documentation order.
    pub const ALL: [Estimator; 3] = [Estimator::Plain, Estimator::Monotone, Estimator::Hyman];

    /// The estimator's name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Estimator::Plain => "plain",
            Estimator::Monotone => "monotone",
            Estimator::Hyman => "hyman",
        }
    }

    /// The estimator named `name` ([`Estimator::name`]), if any.
    pub(crate) fn from_name(name: &str) -> Option<Estimator> {
        Estimator::ALL.into_iter().find(|e| e.name() == name)
    }

    /// The estimator named `name` given as the setting `option`; an unknown name is an
    /// [`Error::InvalidOption`] listing the names.
    pub fn parse_option(option: &str, name: &str) -> Result<Estimator> {
        Estimator::from_name(name)
            .ok_or_else(|| Error::invalid_option(option, name, "expected plain, monotone or hyman"))
    }
}

/// One bicubic patch in power basis over local (s, t) in `[0, 1]^2`, `s = (u - u0) * inv_w`,
/// `t = (v - v0) * inv_w`: `f_c(s, t) = sum_{i,j<4} c[c][4*j + i] * s^i * t^j`.
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C, align(16))]
pub struct PatchCoeffs {
    /// Power coefficients per channel (R, G, B); `c[ch][4 * j + i]` multiplies s^i t^j.
    pub c: [[f32; 16]; 3],
    /// Lower-left corner u of the patch's cell (a dyadic number, exact in f32).
    pub u0: f32,
    /// Lower-left corner v of the patch's cell.
    pub v0: f32,
    /// Inverse cell width, a power of two (exact).
    pub inv_w: f32,
    /// Whether the shader may evaluate this patch as the degree-(1, 1) polynomial
    /// `(k5 s + k4) t + (k1 s + k0)` per channel, bit-identical to the bicubic Horner scheme
    /// ([`PatchCoeffs::bilinear_exact`]). The constructors set it; `false` is always correct.
    pub bilinear: bool,
}

/// See [`PatchCoeffs::bilinear_exact`].
/// Written without early exits (the bits ORed, the tests ANDed): the Gouraud mesh builds a
/// patch for every visible triangle of every region, and the short-circuit form's branches
/// were a visible part of that.
fn bilinear_exact(c: &[[f32; 16]; 3]) -> bool {
    const NEG_ZERO: u32 = 0x8000_0000;
    c.iter().fold(true, |ok, k| {
        let mut higher = 0u32;
        for i in [2, 3, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15] {
            higher |= k[i].to_bits();
        }
        let signed = (k[1].to_bits() != NEG_ZERO)
            & (k[4].to_bits() != NEG_ZERO)
            & (k[5].to_bits() != NEG_ZERO);
        ok & (higher == 0) & signed
    })
}

/// Clamps into [0, 1], NaN to 0 (NaN fails the comparison; `f32::clamp` would keep it).
#[inline(always)]
fn clamp01(x: f32) -> f32 {
    if x >= 0.0 {
        x.min(1.0)
    } else {
        0.0
    }
}

impl PatchCoeffs {
    /// A patch over the whole polygon domain (u0 = v0 = 0, side 1) with the given coefficients.
    pub fn whole(c: [[f32; 16]; 3]) -> PatchCoeffs {
        PatchCoeffs {
            c,
            u0: 0.0,
            v0: 0.0,
            inv_w: 1.0,
            bilinear: bilinear_exact(&c),
        }
    }

    /// Whether coefficients `c` let the degree-(1, 1) evaluation stand in for the bicubic one
    /// with the same bits (the Gouraud mesh's patches, constant patches). Horner's scheme
    /// evaluates row j as `((k[4j+3] s + k[4j+2]) s + k[4j+1]) s + k[4j]` and the rows as
    /// `((r3 t + r2) t + r1) t + r0`. When every coefficient of s^2, s^3, t^2 and t^3 is +0
    /// (bit pattern 0), for finite s and t every product with one of them is +-0 and
    /// `+-0 + +0 = +0` (round to nearest), so r3 = r2 = +0 and the terms they feed add a
    /// signed zero: `+-0 + x = x` for every x except x = -0. Excluding -0 for k1, k5 (each
    /// added to such a zero) and k4 (which keeps r1 = k5 s + k4 from being -0) leaves exactly
    /// `r1 = k5 s + k4`, `r0 = k1 s + k0`, `f = r1 t + r0`, with the same roundings.
    pub fn bilinear_exact(&self) -> bool {
        bilinear_exact(&self.c)
    }

    /// The local coordinates (s, t) of (u, v), unclamped.
    #[inline(always)]
    pub fn local(&self, u: f32, v: f32) -> (f32, f32) {
        ((u - self.u0) * self.inv_w, (v - self.v0) * self.inv_w)
    }

    /// Value at global (u, v). Local (s, t) are clamped into [0, 1] (NaN to 0), so a point outside
    /// the cell evaluates the nearest edge. With u0 dyadic and inv_w a power of two, s is exact for
    /// u inside the cell, so the cell's edges are evaluated at exactly s = 0 or 1.
    #[inline(always)]
    pub fn eval(&self, u: f32, v: f32) -> Vec3 {
        let s = clamp01((u - self.u0) * self.inv_w);
        let t = clamp01((v - self.v0) * self.inv_w);
        // The 16 monomials s^i t^j once, then one 16-wide dot product per channel: independent
        // multiply-adds the compiler vectorizes (Horner would be a 6-deep dependency chain).
        // All monomials lie in [0, 1], so the sum is as accurate as Horner's.
        let (s2, t2) = (s * s, t * t);
        let sp = [1.0, s, s2, s2 * s];
        let tp = [1.0, t, t2, t2 * t];
        let mut m = [0.0f32; 16];
        for (j, tj) in tp.iter().enumerate() {
            for (i, si) in sp.iter().enumerate() {
                m[4 * j + i] = si * tj;
            }
        }
        let mut out = [0.0f32; 3];
        for (o, c) in out.iter_mut().zip(self.c.iter()) {
            // Four lanes of partial sums (one 4-wide vector), added in a fixed order.
            let mut acc = [0.0f32; 4];
            for (cq, mq) in c.chunks_exact(4).zip(m.chunks_exact(4)) {
                for l in 0..4 {
                    acc[l] += cq[l] * mq[l];
                }
            }
            *o = (acc[0] + acc[1]) + (acc[2] + acc[3]);
        }
        Vec3::from_array(out)
    }

    /// Value and global partials d/du, d/dv at (u, v), computed in f64 from the f32 coefficients.
    pub fn eval_grad_f64(&self, u: f64, v: f64) -> ([f64; 3], [f64; 3], [f64; 3]) {
        let iw = self.inv_w as f64;
        let cl = |x: f64| if x.is_nan() { 0.0 } else { x.clamp(0.0, 1.0) };
        let s = cl((u - self.u0 as f64) * iw);
        let t = cl((v - self.v0 as f64) * iw);
        let (mut f, mut fu, mut fv) = ([0.0; 3], [0.0; 3], [0.0; 3]);
        for ch in 0..3 {
            let c = &self.c[ch];
            let k = |i: usize, j: usize| c[4 * j + i] as f64;
            let mut rows = [0.0f64; 4];
            let mut drows = [0.0f64; 4];
            for (j, (r, dr)) in rows.iter_mut().zip(drows.iter_mut()).enumerate() {
                *r = ((k(3, j) * s + k(2, j)) * s + k(1, j)) * s + k(0, j);
                *dr = (3.0 * k(3, j) * s + 2.0 * k(2, j)) * s + k(1, j);
            }
            f[ch] = ((rows[3] * t + rows[2]) * t + rows[1]) * t + rows[0];
            fu[ch] = (((drows[3] * t + drows[2]) * t + drows[1]) * t + drows[0]) * iw;
            fv[ch] = ((3.0 * rows[3] * t + 2.0 * rows[2]) * t + rows[1]) * iw;
        }
        (f, fu, fv)
    }

    fn from_poly(p: &PatchPoly, level: u32) -> PatchCoeffs {
        let mut c = [[0.0f32; 16]; 3];
        for (dst, src) in c.iter_mut().zip(p.c.iter()) {
            for (d, s) in dst.iter_mut().zip(src.iter()) {
                *d = *s as f32;
            }
        }
        PatchCoeffs {
            c,
            u0: p.u0 as f32,
            v0: p.v0 as f32,
            inv_w: (1u32 << level) as f32,
            bilinear: bilinear_exact(&c),
        }
    }

    fn is_finite(&self) -> bool {
        self.c.iter().flatten().all(|x| x.is_finite())
    }
}

/// Sizes and memory of a reconstruction, summed over polygons. Bytes are what is stored unless
/// the field says otherwise.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ReconstructionStats {
    /// Number of polygons.
    pub polygons: usize,
    /// Patches stored (leaves of the refined, merged trees).
    pub patches: usize,
    /// Distinct patch corners (vertices of the final trees).
    pub vertices: usize,
    /// Samples given (vertices of the input trees).
    pub original_samples: usize,
    /// Final vertices made by T-vertex refinement or by splitting along sharp light (not
    /// samples).
    pub derived_points: usize,
    /// Points where sharp light ([`sharp`]) was evaluated beyond the samples (one shadow ray
    /// per term each).
    pub sharp_points: usize,
    /// Tree nodes turned back into leaves because their children reproduced them.
    pub merged_nodes: usize,
    /// Leaves of the input trees.
    pub input_leaves: usize,
    /// Nodes of the stored locate trees.
    pub tree_nodes: usize,
    /// Stored bytes: patches (208 B each) + locate tree (4 B per node) + polygon roots.
    pub bytes: usize,
    /// Bytes if Hermite vertex data were stored instead of patches (48 B of f32 data + 8 B key per
    /// vertex, + the tree); patches would then be derived at load time.
    pub hermite_bytes: usize,
    /// Patches of full grids at each polygon's input depth (4^depth per polygon).
    pub full_grid_patches: usize,
    /// Bytes of those full-grid patches (208 B each).
    pub full_grid_bytes: usize,
    /// Texels of equal-quality radiosity textures: per polygon (2^depth + 1)^2 samples rounded up
    /// to a power-of-two square, stored with the texture module's gutter
    /// ([`texture::GUTTER`] texels beyond each edge), level 0 only.
    pub texture_texels: usize,
    /// Those textures at 3 x 8 bits.
    pub texture_bytes_8: usize,
    /// Those textures at 3 x 12 bits.
    pub texture_bytes_12: usize,
    /// Those textures at 3 x 32-bit float.
    pub texture_bytes_32: usize,
}

/// Tag of a leaf in the encoded locate tree.
const LEAF: u32 = 1 << 31;

/// The RRPs of every polygon of a scene, in scene polygon order.
///
/// Methods taking a `polygon` index panic if it is `>= polygon_count()`: that is a caller bug,
/// like an out-of-range slice index, not bad input.
#[derive(Debug, Clone)]
pub struct Reconstruction {
    patches: Vec<PatchCoeffs>,
    /// Locate trees of all polygons: a leaf is `LEAF | global patch id`, an internal node the
    /// absolute index of its first child (children in the quadtree's (0,0),(1,0),(0,1),(1,1) order).
    nodes: Vec<u32>,
    /// Index in `nodes` of each polygon's root.
    roots: Vec<u32>,
    stats: ReconstructionStats,
}

/// One polygon's finished f64 reconstruction (before f32 conversion); also used by tests.
#[derive(Debug, Clone)]
pub(crate) struct PolygonRrp {
    refined: Refined,
    /// Depth and leaf count of the input tree, samples given.
    input_depth: u32,
    input_leaves: usize,
    samples: usize,
    /// Points where the sharp light was evaluated beyond the samples.
    sharp_points: usize,
}

impl PolygonRrp {
    /// The f64 patch of leaf node `id` of the final tree.
    pub(crate) fn poly(&self, id: u32) -> PatchPoly {
        let cell = self.refined.tree.node(id).cell;
        PatchPoly::from_corners(cell, &refine::corner_data(&self.refined.data, cell))
    }
}

/// One polygon's samples checked and converted, with their estimated Hermite data: what the
/// seams need from every polygon before any polygon is refined.
pub(crate) struct Estimated {
    data: Vec<HermiteData>,
    /// Largest |value| of the samples.
    scale: f64,
}

/// Checks one polygon's samples and estimates their Hermite data. `index` only labels errors.
fn estimate_polygon(index: usize, sq: &SampledQuadtree, estimator: Estimator) -> Result<Estimated> {
    let bad =
        |msg: String| Error::Inconsistent(format!("reconstruction of polygon {index}: {msg}"));
    if sq.keys.len() != sq.values.len() {
        return Err(bad(format!(
            "{} sample keys but {} values",
            sq.keys.len(),
            sq.values.len()
        )));
    }
    if sq.keys != sq.tree.vertex_keys() {
        return Err(bad(
            "sample keys are not exactly the sorted vertices of the tree's leaves".into(),
        ));
    }
    let mut scale = 0.0f64;
    let mut values = Vec::with_capacity(sq.values.len());
    for (k, v) in sq.keys.iter().zip(&sq.values) {
        if !v.is_finite() {
            return Err(bad(format!(
                "sample at (u, v) = ({}, {}) is not finite: {v}",
                k.u(),
                k.v()
            )));
        }
        let a = [v.x as f64, v.y as f64, v.z as f64];
        scale = a.iter().fold(scale, |m, x| m.max(x.abs()));
        values.push(a);
    }
    let samples = Samples::new(&sq.tree, &sq.keys, values);
    let data = estimate::estimate(&samples, estimator);
    Ok(Estimated { data, scale })
}

/// Builds one polygon's RRP in f64 from its own samples alone. `index` only labels errors.
#[cfg(test)]
pub(crate) fn build_polygon(
    index: usize,
    sq: &SampledQuadtree,
    estimator: Estimator,
) -> Result<PolygonRrp> {
    let e = estimate_polygon(index, sq, estimator)?;
    Ok(finish_polygon(sq, &e, &[], None))
}

/// Refines one polygon with its seam points' data; with sharp light, `sq` holds the rest of
/// the light and the sharp terms are added back along their edges ([`sharp`]).
fn finish_polygon(
    sq: &SampledQuadtree,
    e: &Estimated,
    forced: &[(base::quadtree::VertexKey, HermiteData)],
    light: Option<(sharp::PolygonLight<'_>, refine::KeyMap<sharp::Lit>)>,
) -> PolygonRrp {
    let (refined, sharp_points) = match light {
        Some((light, lit)) => {
            let (tree, rest) = refine::split(&sq.tree, &sq.keys, &e.data, forced);
            sharp::sharpen(tree, rest, &light, lit, &sq.keys)
        }
        None => (
            refine::refine(&sq.tree, &sq.keys, &e.data, forced, e.scale),
            0,
        ),
    };
    PolygonRrp {
        refined,
        input_depth: sq.tree.depth(),
        input_leaves: sq.tree.leaf_count(),
        samples: sq.keys.len(),
        sharp_points,
    }
}

/// One polygon's sharp terms, its samples without them and which terms light each sample.
struct SharpPolygon<'a> {
    light: sharp::PolygonLight<'a>,
    rest: SampledQuadtree,
    lit: refine::KeyMap<sharp::Lit>,
}

/// Every polygon's f64 reconstruction, in polygon order: estimates in parallel, the seams'
/// joint data in one ordered pass, refinement (and sharpening) in parallel (each step's result
/// depends on no thread count). Shared by [`Reconstruction::build_with`] and
/// [`compact::CompactReconstruction::build_with`].
pub(crate) fn build_polygons(
    polygons: &[SampledQuadtree],
    estimator: Estimator,
    seams: &Seams,
    sharp: Option<Sharp<'_>>,
) -> Vec<Result<PolygonRrp>> {
    let lights: Vec<Option<SharpPolygon<'_>>> = polygons
        .par_iter()
        .enumerate()
        .map(|(i, sq)| {
            let light = sharp::PolygonLight::of(sharp?, i)?;
            let (rest, lit) = sharp::residual(sq, &light);
            Some(SharpPolygon { light, rest, lit })
        })
        .collect();
    let input = |i: usize| lights[i].as_ref().map_or(&polygons[i], |l| &l.rest);
    let estimated: Vec<Result<Estimated>> = (0..polygons.len())
        .into_par_iter()
        .map(|i| estimate_polygon(i, input(i), estimator))
        .collect();
    let forced = if seams.is_empty()
        || !seams.fits(polygons.len())
        || estimated.iter().any(|e| e.is_err())
    {
        vec![Vec::new(); polygons.len()]
    } else {
        let own: Vec<seam::Own<'_>> = (0..polygons.len())
            .zip(&estimated)
            .map(|(i, e)| seam::Own {
                sq: input(i),
                data: &e.as_ref().expect("checked above").data,
            })
            .collect();
        seam::force(seams, &own, estimator)
    };
    polygons
        .par_iter()
        .zip(estimated)
        .zip(forced)
        .zip(lights)
        .map(|(((sq, e), f), light)| {
            let e = e?;
            Ok(match light {
                Some(SharpPolygon { light, rest, lit }) => {
                    finish_polygon(&rest, &e, &f, Some((light, lit)))
                }
                None => finish_polygon(sq, &e, &f, None),
            })
        })
        .collect()
}

/// The stored f32 patch of an f64 leaf polynomial at `level`; an error (naming polygon `index`)
/// if a coefficient overflows f32.
fn leaf_patch(index: usize, p: &PatchPoly, level: u32) -> Result<PatchCoeffs> {
    let pc = PatchCoeffs::from_poly(p, level);
    if pc.is_finite() {
        Ok(pc)
    } else {
        Err(Error::Inconsistent(format!(
            "reconstruction of polygon {index}: a patch coefficient overflows f32 (sample values \
             too large)"
        )))
    }
}

/// Descends a locate tree (entries `LEAF | leaf id` or the absolute index of the first child)
/// from `root` to the leaf holding lattice point (i, j).
#[inline(always)]
fn locate_in(nodes: &[u32], root: u32, i: u32, j: u32) -> u32 {
    let mut n = root as usize;
    let mut level = 0u32;
    loop {
        let e = nodes[n];
        if e & LEAF != 0 {
            return e & !LEAF;
        }
        let sh = MAX_DEPTH - 1 - level;
        n = e as usize + ((i >> sh) & 1) as usize + 2 * ((j >> sh) & 1) as usize;
        level += 1;
    }
}

#[inline(always)]
fn lattice_f32(x: f32) -> u32 {
    // x * 2^16 is exact; `as` saturates, and NaN fails the comparison and maps to 0.
    let y = (x * LATTICE as f32).floor();
    if y >= 0.0 {
        (y as u32).min(LATTICE - 1)
    } else {
        0
    }
}

#[inline(always)]
fn lattice_f64(x: f64) -> u32 {
    let y = (x * LATTICE as f64).floor();
    if y >= 0.0 {
        (y as u32).min(LATTICE - 1)
    } else {
        0
    }
}

impl Reconstruction {
    /// Reconstructs every polygon (in parallel; the result does not depend on the thread count).
    ///
    /// Errors ([`Error::Inconsistent`], naming the first bad polygon in order): sample keys that are
    /// not the tree's vertices, non-finite samples, or values so large that a coefficient
    /// overflows f32.
    pub fn build(polygons: &[SampledQuadtree], estimator: Estimator) -> Result<Reconstruction> {
        Reconstruction::build_with(polygons, estimator, &Seams::none(), None)
    }

    /// [`Reconstruction::build`], joining the polygons along `seams` ([`seam`]): one C1 function
    /// across the borders of coplanar neighbours of one material; and following the edges of
    /// `sharp` light ([`sharp`]), which the samples must hold. Seams that do not fit the
    /// polygons (built for another scene) are an [`Error::Inconsistent`].
    pub fn build_with(
        polygons: &[SampledQuadtree],
        estimator: Estimator,
        seams: &Seams,
        sharp: Option<Sharp<'_>>,
    ) -> Result<Reconstruction> {
        seams.check_fits(polygons.len(), "reconstruction")?;
        let built = build_polygons(polygons, estimator, seams, sharp);
        let mut patches = Vec::new();
        let mut nodes: Vec<u32> = Vec::new();
        let mut roots = Vec::with_capacity(polygons.len());
        let mut st = ReconstructionStats {
            polygons: polygons.len(),
            ..Default::default()
        };
        for (index, b) in built.into_iter().enumerate() {
            let p = b?;
            let tree = &p.refined.tree;
            let base = nodes.len();
            roots.push(base as u32);
            for (id, n) in tree.nodes().iter().enumerate() {
                if n.is_leaf() {
                    let pc = leaf_patch(index, &p.poly(id as u32), n.cell.level)?;
                    nodes.push(LEAF | patches.len() as u32);
                    patches.push(pc);
                } else {
                    nodes.push((base + n.first_child as usize) as u32);
                }
                if patches.len() >= LEAF as usize || nodes.len() >= LEAF as usize {
                    return Err(Error::Inconsistent(
                        "reconstruction: more than 2^31 patches or tree nodes".into(),
                    ));
                }
            }
            st.patches += tree.leaf_count();
            st.vertices += p.refined.data.len();
            st.original_samples += p.samples;
            st.derived_points += p.refined.derived_points;
            st.sharp_points += p.sharp_points;
            st.merged_nodes += p.refined.merged_nodes;
            st.input_leaves += p.input_leaves;
            st.full_grid_patches += 1usize << (2 * p.input_depth);
            let side =
                ((1usize << p.input_depth) + 1).next_power_of_two() + 2 * texture::GUTTER as usize;
            st.texture_texels += side * side;
        }
        let patch_size = std::mem::size_of::<PatchCoeffs>();
        st.tree_nodes = nodes.len();
        st.bytes = patches.len() * patch_size + 4 * nodes.len() + 4 * roots.len();
        st.hermite_bytes = st.vertices * (48 + 8) + 4 * nodes.len() + 4 * roots.len();
        st.full_grid_bytes = st.full_grid_patches * patch_size;
        st.texture_bytes_8 = st.texture_texels * 3;
        st.texture_bytes_12 = st.texture_texels * 3 * 12 / 8;
        st.texture_bytes_32 = st.texture_texels * 12;
        Ok(Reconstruction {
            patches,
            nodes,
            roots,
            stats: st,
        })
    }

    /// Number of polygons.
    pub fn polygon_count(&self) -> usize {
        self.roots.len()
    }

    #[inline(always)]
    fn locate_lattice(&self, polygon: u32, i: u32, j: u32) -> u32 {
        locate_in(&self.nodes, self.roots[polygon as usize], i, j)
    }

    /// Global patch id of the patch covering (u, v) of `polygon` (u, v clamped to `[0, 1]`, NaN to
    /// 0). On a shared edge the patch on the upper side is returned (both evaluate equally there),
    /// at u or v = 1 the last patch. Panics if `polygon >= polygon_count()` (a caller bug, like an
    /// out-of-range slice index).
    #[inline]
    pub fn locate(&self, polygon: u32, u: f32, v: f32) -> u32 {
        self.locate_lattice(polygon, lattice_f32(u), lattice_f32(v))
    }

    /// The patch's coefficients. Panics if `id` is not a patch id returned by [`Self::locate`].
    #[inline]
    pub fn patch(&self, id: u32) -> &PatchCoeffs {
        &self.patches[id as usize]
    }

    /// All patches, in global id order.
    pub fn patches(&self) -> &[PatchCoeffs] {
        &self.patches
    }

    /// Value at (u, v), clamped into [0, 1]^2 (NaN to 0).
    #[inline]
    pub fn eval(&self, polygon: u32, u: f32, v: f32) -> Vec3 {
        let (u, v) = (clamp01(u), clamp01(v));
        self.patch(self.locate(polygon, u, v)).eval(u, v)
    }

    /// Value, d/du and d/dv per channel at (u, v) (clamped into [0, 1]^2, NaN to 0), evaluated in
    /// f64 from the stored coefficients; derivatives in global parameter units.
    pub fn eval_grad(&self, polygon: u32, u: f64, v: f64) -> (Vec3, Vec3, Vec3) {
        let cl = |x: f64| if x.is_nan() { 0.0 } else { x.clamp(0.0, 1.0) };
        let (u, v) = (cl(u), cl(v));
        let id = self.locate_lattice(polygon, lattice_f64(u), lattice_f64(v));
        let (f, fu, fv) = self.patch(id).eval_grad_f64(u, v);
        let to = |a: [f64; 3]| Vec3::new(a[0] as f32, a[1] as f32, a[2] as f32);
        (to(f), to(fu), to(fv))
    }

    /// Evaluates `uv.len().min(out.len())` points: `out[k] = eval(polygon, uv[k])`. The patch
    /// found for one point is reused while the next points stay inside it (coherent pixel runs
    /// skip the tree descent).
    pub fn eval_many(&self, polygon: u32, uv: &[[f32; 2]], out: &mut [Vec3]) {
        debug_assert_eq!(uv.len(), out.len());
        let mut cur: Option<(&PatchCoeffs, f32, f32, f32, f32)> = None;
        for (p, o) in uv.iter().zip(out.iter_mut()) {
            let (u, v) = (clamp01(p[0]), clamp01(p[1]));
            // Reuse only for points strictly inside the cached cell's half-open range, which is
            // exactly where locate would return it again.
            let pc = match cur {
                Some((pc, u0, v0, u1, v1)) if u >= u0 && u < u1 && v >= v0 && v < v1 => pc,
                _ => {
                    let pc = self.patch(self.locate(polygon, u, v));
                    let w = 1.0 / pc.inv_w;
                    cur = Some((pc, pc.u0, pc.v0, pc.u0 + w, pc.v0 + w));
                    pc
                }
            };
            *o = pc.eval(u, v);
        }
    }

    /// Resamples `polygon` into an n x m texture: texel (i, j) is the value at
    /// u = (i + 0.5) / n, v = (j + 0.5) / m (computed in f64, rounded to f32), row-major with
    /// j = row (v). Empty if n or m is 0.
    pub fn resample(&self, polygon: u32, n: u32, m: u32) -> Vec<Vec3> {
        self.resample_placed(polygon, n, m, Placement::Centre)
    }

    /// [`Reconstruction::resample`] with the texels at the positions of `placement`
    /// ([`Placement::texel_position`]): texel (i, j) is the value at
    /// `(placement.texel_position(i, n), placement.texel_position(j, m))`.
    pub(crate) fn resample_placed(
        &self,
        polygon: u32,
        n: u32,
        m: u32,
        placement: Placement,
    ) -> Vec<Vec3> {
        let mut uv = Vec::with_capacity(n as usize * m as usize);
        for j in 0..m {
            let v = placement.texel_position(j, m);
            for i in 0..n {
                uv.push([placement.texel_position(i, n), v]);
            }
        }
        let mut out = vec![Vec3::ZERO; uv.len()];
        self.eval_many(polygon, &uv, &mut out);
        out
    }

    /// Sizes and memory.
    pub fn stats(&self) -> ReconstructionStats {
        self.stats
    }
}

/// Texel centre coordinate (k + 0.5) / n, in f64 rounded to f32.
#[inline]
pub fn texel_centre(k: u32, n: u32) -> f32 {
    Placement::Centre.texel_position(k, n)
}

/// What the direct method needs from a reconstruction.
pub trait PatchSource: Sync {
    /// Global id of the patch covering (u, v) of scene polygon `polygon`; (u, v) in `[0, 1]^2`.
    fn locate(&self, polygon: u32, u: f32, v: f32) -> u32;
    /// The coefficients of patch `id`, by value: a source may hold patches expanded (a copy) or
    /// derive them on demand from compact data ([`compact::CompactReconstruction`]).
    fn patch(&self, id: u32) -> PatchCoeffs;
    /// The half-open parameter rectangle `[u_lo, u_hi) x [v_lo, v_hi)`, as
    /// `[u_lo, u_hi, v_lo, v_hi]`, on which `locate` returns `id` (for the polygon `id` was located
    /// on), if the source knows it exactly. The rasterizer then skips `locate` for samples inside
    /// it, which cannot change any result. The default knows nothing: every sample asks `locate`.
    fn cell(&self, _id: u32) -> Option<[f32; 4]> {
        None
    }
    /// [`PatchSource::patch`] through a worker's `cache` of expanded patches (the same value:
    /// a cache changes times, never results). The default does not cache.
    fn patch_cached(&self, id: u32, cache: &mut PatchCache) -> PatchCoeffs {
        let _ = cache;
        self.patch(id)
    }
    /// Fills a worker's `cache` for this source ahead of a first frame (allocated, first
    /// touched, patches expanded). The default has nothing to prepare.
    fn warm(&self, cache: &mut PatchCache) {
        let _ = cache;
    }
}

/// The direct method's view of a reconstruction: the rasterizer locates each pixel's patch and
/// copies its coefficients into the region's patch table.
impl PatchSource for Reconstruction {
    #[inline]
    fn locate(&self, polygon: u32, u: f32, v: f32) -> u32 {
        Reconstruction::locate(self, polygon, u, v)
    }

    #[inline]
    fn patch(&self, id: u32) -> PatchCoeffs {
        *Reconstruction::patch(self, id)
    }

    /// The patch's cell `[u0, u0 + w) x [v0, v0 + w)`: u0 is a multiple of 2^-16 and w = 1 / inv_w
    /// a power of two, all exact in f32, and `u * 2^16` is exact, so `u >= u0 && u < u0 + w` holds
    /// exactly when `locate`'s lattice coordinate falls in the leaf's lattice range (the same
    /// reasoning as in [`Reconstruction::eval_many`]).
    #[inline]
    fn cell(&self, id: u32) -> Option<[f32; 4]> {
        let p = self.patch(id);
        let w = 1.0 / p.inv_w;
        Some([p.u0, p.u0 + w, p.v0, p.v0 + w])
    }
}
