//! Sharp light: the reconstruction follows the edges of light that jumps (a spot's cone rim,
//! the hard shadows of a point source) instead of interpolating samples across them.
//!
//! A quadtree can only approach such an edge by subdividing to its depth limit, and a C1
//! bicubic then spreads the jump over about two leaves on each side: the widest errors of an
//! image sit along these lines. But the light that jumps is known exactly at any point
//! ([`SharpLight`]: for a spot, `rho I(theta) cos / r^2` times a visibility of 0 or 1, one
//! shadow ray), so the reconstruction splits each polygon's light in two:
//!
//! 1. **the rest** (`residual`): every sample minus the sharp terms that light it. Indirect
//!    light and area lights, smooth across a spot's edges. Estimation, seams and T-vertex
//!    refinement run on it unchanged.
//! 2. **the sharp terms**, added back exactly (`sharpen`): every leaf of the refined tree
//!    whose corners are not lit by the same terms is split, down `levels` levels below its own
//!    (at most [`MAX_DEPTH`]), while its children still straddle. New points take the rest
//!    from the parent's polynomial of the rest (as refinement does), and their sharp terms
//!    from the light. Each vertex's Hermite data are then the rest's plus, for every term that
//!    lights it, the term's value and the derivatives of its smooth continuation (the term
//!    without its cuts, [`SharpLight::smooth`], by central differences at 1/64 of the smallest
//!    leaf at the vertex). Merging (`refine::merge`) then runs on these full data.
//!
//! Vertices inside a leaf's edge (T-vertices) take their data from that leaf's polynomial, as in
//! the compact form, so the result is C1 everywhere by the argument of `refine` (every leaf's
//! edge data lie on its neighbours' edge cubics): the jump is not a discontinuity of the patches
//! but a C1 ramp across the deepest straddling leaves, `2^-levels` of a solver leaf wide.
//! Inside lit and dark regions the terms are the exact smooth function, interpolated by
//! bicubics at the leaves' size. Storage grows only along the edges: about
//! `4 * 2^levels` leaves per straddling solver leaf.
//!
//! Invariants: a polygon no sharp term reaches is built exactly as without this module; every
//! original sample is still reproduced at its vertex (the rest plus the parts is the sample, to
//! f32 rounding of the rest); the derivatives are those of the terms' smooth continuation, so a
//! straight edge ramp has no overshoot beyond the estimator's on the rest. At most
//! [`MAX_TERMS`] terms per polygon are followed; further ones stay in the samples and are
//! reconstructed from them like any other light.

use base::quadtree::{Quadtree, SampledQuadtree, VertexKey, MAX_DEPTH};
use glam::Vec3;

use crate::compact::Layout;
use crate::hermite::HermiteData;
use crate::refine::{self, KeyMap, Refined};

/// Light known exactly at any point, whose value may jump: the reconstruction takes it out of
/// the samples and adds it back along its edges ([module docs](self)). Terms are numbered by
/// the implementor (for spot lights, the spot's index).
pub trait SharpLight: Sync {
    /// The terms that can light polygon `polygon`, ascending (empty: none).
    fn terms(&self, polygon: usize) -> Vec<u32>;
    /// Term `term`'s part of polygon `polygon`'s linear RGB radiosity at (u, v) where it lights
    /// the point; `None` where it does not. It must be the part the samples hold.
    fn part(&self, polygon: usize, term: u32, u: f64, v: f64) -> Option<[f64; 3]>;
    /// The term's smooth continuation at any real (u, v) (the polygon's parameterization
    /// extended): equal to [`SharpLight::part`] where that is `Some`, defined and smooth across
    /// the term's edges.
    fn smooth(&self, polygon: usize, term: u32, u: f64, v: f64) -> [f64; 3];
}

/// Sharp light and how far below the solver's leaves its edges are followed.
#[derive(Clone, Copy)]
pub struct Sharp<'a> {
    /// The light.
    pub light: &'a dyn SharpLight,
    /// Levels below a straddling leaf's own that it is split to (0: the light is only taken
    /// out and added back at the vertices, no splitting).
    pub levels: u32,
}

/// The default of [`Sharp::levels`]: an edge ramp 1/8 of a solver leaf wide. Chosen by
/// measurement on the gallery (docs/seams.md, `--example sharp_edges`): it cuts the direct
/// method's error near spot edges to 0.37x for 2.1x the RRP bytes; each further level halves the
/// ramp and doubles the added leaves.
pub const DEFAULT_LEVELS: u32 = 3;

/// Most terms followed per polygon (one bit each in a mask).
pub const MAX_TERMS: usize = 64;

/// Central-difference step of the smooth terms' derivatives, as a fraction of the smallest
/// leaf width at the vertex: the truncation error (~step^2 of the third derivative) stays far
/// below the bicubic's own error over the leaf, the rounding error (~1e-16 / step^2 for the
/// twist) far below f32 data.
const STEP_FRACTION: f64 = 1.0 / 64.0;

/// Which terms light a point (bit k: the polygon's k-th term) and the sum of their parts.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Lit {
    mask: u64,
    sum: [f64; 3],
}

/// One polygon's sharp terms.
pub(crate) struct PolygonLight<'a> {
    sharp: Sharp<'a>,
    polygon: usize,
    terms: Vec<u32>,
}

impl<'a> PolygonLight<'a> {
    /// The sharp terms of polygon `polygon`, or `None` if none reaches it.
    pub(crate) fn of(sharp: Sharp<'a>, polygon: usize) -> Option<PolygonLight<'a>> {
        let mut terms = sharp.light.terms(polygon);
        terms.truncate(MAX_TERMS);
        (!terms.is_empty()).then_some(PolygonLight {
            sharp,
            polygon,
            terms,
        })
    }

    /// The terms lighting lattice point `k`.
    fn at(&self, k: VertexKey) -> Lit {
        let mut lit = Lit::default();
        for (bit, &t) in self.terms.iter().enumerate() {
            if let Some(p) = self.sharp.light.part(self.polygon, t, k.u(), k.v()) {
                lit.mask |= 1 << bit;
                for (acc, x) in lit.sum.iter_mut().zip(p) {
                    *acc += x;
                }
            }
        }
        lit
    }

    /// The derivatives (f_u, f_v, f_uv in global units; f left 0) of the smooth continuations
    /// of the terms in `mask` at `k`, by central differences of step `h`.
    fn derivatives(&self, mask: u64, k: VertexKey, h: f64) -> HermiteData {
        let (u, v) = (k.u(), k.v());
        let mut d = HermiteData::default();
        for (bit, &t) in self.terms.iter().enumerate() {
            if mask & (1 << bit) == 0 {
                continue;
            }
            let f = |du: f64, dv: f64| self.sharp.light.smooth(self.polygon, t, u + du, v + dv);
            let (e, w, n, s) = (f(h, 0.0), f(-h, 0.0), f(0.0, h), f(0.0, -h));
            let (ne, nw, se, sw) = (f(h, h), f(-h, h), f(h, -h), f(-h, -h));
            for ch in 0..3 {
                d.fu[ch] += (e[ch] - w[ch]) / (2.0 * h);
                d.fv[ch] += (n[ch] - s[ch]) / (2.0 * h);
                d.fuv[ch] += (ne[ch] - nw[ch] - se[ch] + sw[ch]) / (4.0 * h * h);
            }
        }
        d
    }
}

/// A polygon's samples with its sharp terms taken out (same tree and keys), and which terms
/// light each sample.
pub(crate) fn residual(
    sq: &SampledQuadtree,
    pl: &PolygonLight<'_>,
) -> (SampledQuadtree, KeyMap<Lit>) {
    let mut lit = KeyMap::default();
    let values = sq
        .keys
        .iter()
        .zip(&sq.values)
        .map(|(&k, b)| {
            let l = pl.at(k);
            lit.insert(k, l);
            Vec3::new(
                (b.x as f64 - l.sum[0]) as f32,
                (b.y as f64 - l.sum[1]) as f32,
                (b.z as f64 - l.sum[2]) as f32,
            )
        })
        .collect();
    let out = SampledQuadtree {
        tree: sq.tree.clone(),
        keys: sq.keys.clone(),
        values,
    };
    (out, lit)
}

/// The T-vertex-split tree of the rest and its data (`refine::split`), split along the sharp
/// terms' edges, with the full light's Hermite data, then merged (`refine::merge`; [module
/// docs](self)); also the number of points where the light was evaluated beyond the samples.
/// `originals` are the polygon's sample keys, sorted.
pub(crate) fn sharpen(
    mut t: Quadtree,
    mut rest_data: KeyMap<HermiteData>,
    pl: &PolygonLight<'_>,
    mut lit: KeyMap<Lit>,
    originals: &[VertexKey],
) -> (Refined, usize) {
    let samples = lit.len();
    let mut lit_at = |k: VertexKey| *lit.entry(k).or_insert_with(|| pl.at(k));

    split_straddling(
        &mut t,
        pl.sharp.levels,
        |k| lit_at(k).mask,
        |t, id| refine::split_leaf(t, &mut rest_data, id),
    );
    // Full data at every vertex that is a corner of all its leaves; T-vertices from their leaf.
    let layout = Layout::of(&t);
    let mut width = vec![f64::INFINITY; layout.keys.len()];
    for (cell, corners) in &layout.leaves {
        for &c in corners {
            width[c as usize] = width[c as usize].min(cell.width());
        }
    }
    let mut data = vec![HermiteData::default(); layout.keys.len()];
    for (x, &k) in layout.keys.iter().enumerate() {
        if layout.is_derived[x] {
            continue;
        }
        let r = rest_data.get(&k).copied().unwrap_or_default();
        let l = lit_at(k);
        let s = pl.derivatives(l.mask, k, width[x] * STEP_FRACTION);
        let d = &mut data[x];
        for ch in 0..3 {
            d.f[ch] = r.f[ch] + l.sum[ch];
            d.fu[ch] = r.fu[ch] + s.fu[ch];
            d.fv[ch] = r.fv[ch] + s.fv[ch];
            d.fuv[ch] = r.fuv[ch] + s.fuv[ch];
        }
    }
    layout.derive(&mut data, |d| d);
    let scale = data
        .iter()
        .flat_map(|d| d.f)
        .fold(0.0f64, |m, x| m.max(x.abs()));
    let evaluated = lit.len() - samples;
    let map = layout.keys.iter().copied().zip(data).collect();
    (refine::merge(&t, map, originals, scale), evaluated)
}

/// Splits every leaf of `t` whose corners `mask_at` finds lit by different terms, depth-first
/// (a stack: a deterministic order), while it is less than `levels` below its own original
/// level (at most [`MAX_DEPTH`]); `split(t, id)` splits leaf `id`, giving the new points their
/// data, and returns its first child.
fn split_straddling(
    t: &mut Quadtree,
    levels: u32,
    mut mask_at: impl FnMut(VertexKey) -> u64,
    mut split: impl FnMut(&mut Quadtree, u32) -> u32,
) {
    let mut stack: Vec<(u32, u32)> = t
        .leaves()
        .into_iter()
        .rev()
        .map(|id| (id, (t.node(id).cell.level + levels).min(MAX_DEPTH)))
        .collect();
    while let Some((id, limit)) = stack.pop() {
        let cell = t.node(id).cell;
        if cell.level >= limit {
            continue;
        }
        let masks = cell.corners().map(&mut mask_at);
        if masks.iter().all(|&m| m == masks[0]) {
            continue;
        }
        let first = split(t, id);
        for q in (0..4).rev() {
            stack.push((first + q, limit));
        }
    }
}

/// Every polygon's samples with its sharp terms' edges followed, for the Gouraud mesh: the
/// mesh then draws the same light as the patches built with `sharp` (the terms exact along
/// their edges, the rest from the samples), not the samples alone.
///
/// Per polygon some term reaches, every leaf whose corners are not lit by the same terms is
/// split as the patches' leaves are ([module docs](self)): down `sharp.levels` below its own
/// level, at most [`MAX_DEPTH`]. A new vertex's value is the rest interpolated bilinearly over
/// the leaf that was split (the mesh's own interpolation of the rest: its value there without
/// the terms) plus the terms that light it, taken from the light. Original samples keep their values bit
/// for bit, and a polygon no term reaches is returned unchanged; every vertex of the new tree
/// has a value (each split gives values to all its children's corners), so the mesh's
/// T-vertex fans find every vertex they need. Values are clamped at 0 (the rest is a
/// difference and may round below it).
pub fn followed_samples(polygons: &[SampledQuadtree], sharp: Sharp<'_>) -> Vec<SampledQuadtree> {
    use rayon::prelude::*;
    polygons
        .par_iter()
        .enumerate()
        .map(|(i, sq)| match PolygonLight::of(sharp, i) {
            Some(pl) => follow(sq, &pl),
            None => sq.clone(),
        })
        .collect()
}

/// [`followed_samples`] for one polygon the terms of `pl` reach.
fn follow(sq: &SampledQuadtree, pl: &PolygonLight<'_>) -> SampledQuadtree {
    let mut lit: KeyMap<Lit> = KeyMap::default();
    let mut rest: KeyMap<[f64; 3]> = KeyMap::default();
    for (&k, b) in sq.keys.iter().zip(&sq.values) {
        let l = pl.at(k);
        lit.insert(k, l);
        rest.insert(k, std::array::from_fn(|ch| b[ch] as f64 - l.sum[ch]));
    }
    let mut lit_at = |k: VertexKey| *lit.entry(k).or_insert_with(|| pl.at(k));
    let mut t = sq.tree.clone();
    split_straddling(
        &mut t,
        pl.sharp.levels,
        |k| lit_at(k).mask,
        |t, id| {
            let cell = t.node(id).cell;
            // A leaf's corners always have values (the tree's vertices, or a split's children).
            let r = cell
                .corners()
                .map(|k| rest.get(&k).copied().unwrap_or_default());
            let (u0, v0, _, _) = cell.bounds();
            let w = cell.width();
            for child in cell.children() {
                for k in child.corners() {
                    rest.entry(k).or_insert_with(|| {
                        let (s, t) = ((k.u() - u0) / w, (k.v() - v0) / w);
                        std::array::from_fn(|ch| {
                            (1.0 - s) * (1.0 - t) * r[0][ch]
                                + s * (1.0 - t) * r[1][ch]
                                + s * t * r[2][ch]
                                + (1.0 - s) * t * r[3][ch]
                        })
                    });
                }
            }
            t.split(id)
        },
    );
    let keys = t.vertex_keys();
    let values = keys
        .iter()
        .map(|&k| match sq.sample(k) {
            Some(b) => b,
            None => {
                let (r, l) = (rest.get(&k).copied().unwrap_or_default(), lit_at(k));
                Vec3::from_array(std::array::from_fn(|ch| {
                    ((r[ch] + l.sum[ch]) as f32).max(0.0)
                }))
            }
        })
        .collect();
    SampledQuadtree {
        tree: t,
        keys,
        values,
    }
}
