//! Compact reconstruction: the same RRPs as [`Reconstruction`], held as what they are made of
//! (each polygon's final refined, merged quadtree and the Hermite data of its vertices) instead
//! of expanded power-basis patches; a patch is expanded on demand
//! ([`CompactReconstruction::expand`]), the way the direct method asks for it (once per distinct
//! patch per screen region per frame).
//!
//! **Invariants.** Leaf ids, their order (polygon order, then the final tree's node order) and
//! [`CompactReconstruction::locate`] are exactly [`Reconstruction`]'s, and so are the cells
//! ([`PatchSource::cell`]); the trees are the same trees. A vertex's data are 12 quantities
//! (f, f_u, f_v, f_uv per RGB channel, global parameter units), held as f32. Vertices are of two
//! kinds, told apart by the tree alone:
//!
//! - a **derived** vertex (T-vertex) lies strictly inside an edge of some leaf X (exactly one:
//!   the leaves touching it from X's side are X alone, and on the other side it is a corner).
//!   Its data are X's patch polynomial and its derivatives at the vertex, evaluated in f64 from
//!   X's four corners' held data and rounded to f32; nothing of it is stored.
//! - a **stored** vertex (every other one) holds its quantities quantized. Per polygon and
//!   quantity q there is one f64 scale `S_q = M_q / 32767`, M_q the largest |x| of q over the
//!   polygon's stored vertices; per stored vertex and quantity a 4-bit shift s and an i16
//!   mantissa m: s is the largest in 0..=15 with `|x| / S_q * 2^s < 32767.5` and
//!   `m = round(|x| / S_q * 2^s)` with x's sign, so |m| >= 16384 whenever s < 15 (the mantissa
//!   is normalized: its half-step is at most 2^-15 of |x| for every |x| >= S_q / 2, that is
//!   down to 2^-16 of the polygon's largest |x|). The held value is `((m * S_q) * 2^-s) as f32`
//!   (the power-of-two multiply is exact). Two clamps store a quantity as m = 0: a held value
//!   that would be below the smallest normal f32 (2^-126; every nonzero held value then carries
//!   24 significant bits, which is what lets `encode` recover m and s from it), and a polygon
//!   whose M_q / 32767 underflows f64 (S_q = 0).
//!
//! Because the scales are not powers of two, multiplying every input by k > 0 multiplies each
//! S_q by k (to f64 rounding) and leaves every m and s unchanged, unless |x| / S_q * 2^s lies
//! within f64 rounding of a rounding boundary: the patches scale by k to f32 rounding when the
//! unquantized data do. Inputs that are themselves rounded to f32 after scaling differ from k
//! times the unscaled ones by up to 2^-24 relative, and the estimated derivatives, differences
//! of samples, by more; a mantissa within that distance of a rounding boundary then rounds the
//! other way, moving its quantity by one step (at most 2^-14 of itself when normalized).
//! Measured on five test polygons (3,223 stored vertices) scaled by 0.37 or 3.1 and rounded to
//! f32: 2-7 of the 9,669 values flip, and about 4,270 of the 29,007 derivative quantities.
//!
//! Leaves are processed larger first (ascending level), so X's own corners, possibly derived
//! from an even larger leaf, are known before X's derived vertices: a corner of X strictly inside
//! an edge of a leaf Z makes Z larger than X (a dyadic edge of X's size or longer cannot contain
//! X's corner in its interior). The vertices inside X's edge are found by a midpoint search on
//! the sorted vertex keys: if a vertex lies strictly inside an edge, the same-size cell across
//! it is split, so the edge's midpoint is a vertex (refine.rs's argument), and the search
//! recurses into both halves. [`CompactReconstruction::expand`] is a pure function of the held
//! f32 data, and those are a pure function of the stored integers and scales. Every held value
//! and every expanded coefficient is finite (checked at build and decode).
//!
//! **Continuity.** Two patches whose common edge has the same two end vertices see identical
//! data there and are C1 across it (to f64 rounding). Along an edge of a larger leaf X, the
//! smaller leaves' edge endpoints are X's corners or derived vertices, whose data lie on X's
//! edge cubics up to their rounding to f32; Hermite interpolation reproduces a cubic from its
//! endpoint data on any sub-interval (refine.rs), so value and first derivatives agree along the
//! whole edge to within that rounding (2^-24 of the data). Quantization opens no jump anywhere.
//!
//! **Error bound** ([`CompactReconstruction::error_bound`]), against the *reference*: the
//! unquantized vertex data with derived vertices taken from the larger leaf's unquantized patch
//! by the same rule. (The expanded [`Reconstruction`] keeps its own data at those vertices,
//! which refinement put on the larger leaf's cubics up to its merge tolerance, 1e-7 of the
//! polygon's largest value per merged level.) A stored quantity errs by at most its half-step
//! `S_q 2^-s / 2` plus the f32 rounding of the held value (2^-23 |x'| over-bounds 2^-24 |x'|
//! and the f64 products), or, for m = 0, by `S_q 2^-15 + 2^-124` (the rounding at s = 15 or a
//! clamp). A derived quantity errs by X's corner errors propagated through the Hermite basis
//! and its derivatives with absolute values (the triangle inequality), plus 2^-23 of its held
//! value and 2^-40 of the same |basis|-weighted sum of X's held data (f64 evaluation). A patch
//! of width w is `f(s, t) = sum_ab H_a(s) H_b(t) g_ab` with (H_0, H_1, H_2, H_3) = (h00, h01,
//! h10, h11) and the geometry g holding corner values, `w f_u`, `w f_v` and `w^2 f_uv`. On
//! [0, 1], h00 and h01 are non-negative with sum 1 and |h10| + |h11| = s(1-s) <= 1/4, so with dq
//! the largest error of quantity q over the leaf's four corners, per channel
//! `|value error| <= df + (w/4)(dfu + dfv) + (w^2/16) dfuv`, plus the f32 rounding of the two
//! expansions (at most 2^-24 times the sum of |coefficients| of each patch, the monomials
//! lying in [0, 1]). The property tests check the bound, and that the value is within 1e-3 of
//! itself (relative) wherever it is at least 1e-4 of the polygon's peak.
//!
//! **Layout, and why.** In memory: the locate tree as [`Reconstruction`] stores it (4 B per
//! node: `LEAF | leaf id` or the first child's index), so `locate` is the same code; one 24-byte
//! record per leaf (its four corners' global vertex indices in patch corner order, its cell's
//! lattice origin, level and polygon); 48 bytes of held f32 data per vertex, derived ones
//! included; per polygon its root, first vertex and 12 f64 scales. `expand` is therefore one
//! record read, four independent 48-byte vertex reads and the Hermite-to-power product: no
//! search and no dequantization (holding the 16-bit form would save 24 B per vertex and cost
//! 48 multiplies and the shift decoding per expand). The alternative, sorted vertex keys per
//! polygon (8 B per vertex) instead of the corner indices (16 B per leaf), found by four binary
//! searches per expand; direct indices keep `expand` free of searches.
//!
//! **Measured** (release build; the first three by the tests named, `--nocapture`):
//!
//! - `dark_values_keep_relative_precision` (a 1/(r^2+h^2)^2 falloff from 1 down to 7.7e-6 of
//!   its peak, 13,348 leaves, 301^2 points): largest relative error 3.3e-5 at every level down
//!   to 1e-4 of the peak, largest relative bound 1.2e-4. One power-of-two scale per polygon and
//!   quantity (absolute steps of 2^-16 of the largest value) gives 1.4e-4 above 1e-1 of the
//!   peak, 1.4e-3 at 1e-2..1e-1, 1.4e-2 at 1e-3..1e-2 and 0.17 at 1e-4..1e-3.
//! - `t_vertex_edges_are_c1_to_rounding` (random unrestricted trees of depth <= 12): jumps of
//!   at most 4.3e-8 of the sample range in value and 1.3e-7 in size-scaled derivative over 64
//!   trees and three estimators; T-vertex data quantized on their own give 1.4e-4 and 7.8e-3.
//! - `scaling_the_input_scales_the_compact_patches` (inputs scaled exactly by 0.369 and 3.09):
//!   identical integers, patch values k times the unscaled ones to 1.8e-7 of the peak (the
//!   unquantized patches: 1.0e-7); power-of-two scales give 4.1e-5. With the scaled inputs
//!   rounded to f32, the mantissas that flip give 3.1e-5 of the peak at worst (power-of-two
//!   scales: 3.9e-5; the unquantized patches: 2.6e-7).
//! - The shipped scenes' solutions (two-spots, cornell-box, gallery; every patch on a 5 x 5
//!   grid, against [`Reconstruction`]): largest error 1.5e-5 of the scene's largest sample (the
//!   half-step of the brightest vertex, 2^-16 of it), largest bound 1.6-2.7e-5; relative error
//!   wherever the value is at least 1e-4 of its polygon's peak at most 4.3e-4 (1.3e-4 above
//!   1e-3 of the peak), against 5.8e-2 and 0.18 (cornell-box, gallery) with power-of-two scales.
//! - Bytes: 76-101 B held per original sample on those scenes (140-263 B expanded); encoded
//!   2-2.8x smaller than held (docs/performance.md has the table). `expand` of a
//!   13,348-leaf polygon: 120-160 ns per patch against 180-220 ns when dequantizing 16-bit data
//!   (a shared two-core machine, best of 7 runs of 20 passes).
//!
//! **Encoding** ([`CompactReconstruction::encode`], little-endian): the 8-byte magic
//! `PFRRPC02`, the polygon count (u32), then per polygon its node count (u32), one bit per node
//! in the tree's node order (1 = split; LSB first, zero-padded to a byte), its 12 scales (f64),
//! then per stored vertex, in sorted key order, 6 bytes of shifts (4 bits per quantity in
//! quantity order, low nibble first) and 12 i16 mantissas: 30 bytes. The node order is
//! [`Quadtree::grow`]'s canonical order, which refinement produces, so the bits rebuild the tree
//! with identical node (and therefore leaf) indices; vertex keys, leaf corners and which
//! vertices are derived follow from the tree. [`CompactReconstruction::decode`] accepts only the
//! canonical form (below), so `encode(decode(b)) == b` for every `b` it accepts, and returns an
//! error, never panics, on anything else: wrong magic, truncation, trailing bytes, split bits
//! that are not a quadtree of depth <= 16 in canonical order, nonzero padding bits, a scale that
//! is negative, -0 or not finite, and per quantity: |m| > 32767, m = 0 with s != 0, s < 15 with
//! |m| < 16384, m != 0 with S_q = 0, a nonzero held value below 2^-126 or not finite; then held
//! or expanded data that are not finite.

use rayon::prelude::*;

use crate::{Seams, Sharp};

use super::hermite::{HermiteData, PatchPoly};
use super::{
    build_polygons, lattice_f32, leaf_patch, locate_in, Estimator, PatchCoeffs, PatchSource,
    PolygonRrp, LEAF,
};
use base::error::{Error, Result};
use base::quadtree::{Cell, Quadtree, SampledQuadtree, VertexKey, MAX_DEPTH};

/// Quantities per vertex: index `3 * kind + channel`, kind 0 = f, 1 = f_u, 2 = f_v, 3 = f_uv.
pub(crate) const QUANTITIES: usize = 12;

/// Largest |mantissa|; the scale of a quantity is its largest |x| over this.
const MANTISSA_MAX: f64 = 32767.0;

/// Smallest |mantissa| at a shift below [`MAX_SHIFT`] (normalized).
const MANTISSA_MIN: u16 = 16384;

/// Largest shift.
const MAX_SHIFT: u8 = 15;

/// Bytes of one stored vertex: 6 bytes of packed shifts and 12 i16 mantissas.
const RECORD_BYTES: usize = QUANTITIES / 2 + 2 * QUANTITIES;

/// Bytes of a polygon's scales.
const SCALE_BYTES: usize = 8 * QUANTITIES;

/// Magic at the start of an encoding.
const MAGIC: &[u8; 8] = b"PFRRPC02";

/// Largest polygon count (the polygon index shares a u32 with the level in a leaf record).
const MAX_POLYGONS: usize = 1 << 27;

/// 2^-s exactly, for a shift s in 0..=16.
fn pow2_neg(s: u8) -> f64 {
    debug_assert!(s <= 16);
    f64::from_bits(((1023 - s as i64) as u64) << 52)
}

/// The dequantized f64 value `(m * S) * 2^-s`.
fn dequantize(m: i16, s: u8, scale: f64) -> f64 {
    (m as f64 * scale) * pow2_neg(s)
}

/// The held value of a stored quantity.
fn held_value(m: i16, s: u8, scale: f64) -> f32 {
    dequantize(m, s, scale) as f32
}

/// Mantissa and shift of `x` (finite) under `scale` (module docs), clamps included.
///
/// Applied to a held value `x' = held_value(m, s, scale)` of canonical (m, s) it returns (m, s)
/// again: x' = m S 2^-s (1 + e) with |e| <= 2^-24 + 2^-52 (x' is a normal f32), so
/// `|x'| / S * 2^s` is within 32767 * 2^-23 < 0.004 of |m|, below 32767.5 at shift s and, when
/// |m| >= 16384, at least 32767.99 at shift s + 1. [`CompactReconstruction::encode`] relies on
/// this to recover the integers from what is held.
fn quantize(x: f64, scale: f64) -> (i16, u8) {
    if scale.is_nan() || scale <= 0.0 {
        return (0, 0);
    }
    let r = x.abs() / scale;
    let mut s = 0u8;
    while s < MAX_SHIFT && r / pow2_neg(s + 1) < MANTISSA_MAX + 0.5 {
        s += 1;
    }
    let m = (r / pow2_neg(s)).round();
    if m.is_nan() || m < 1.0 {
        return (0, 0);
    }
    // r <= 32767 (1 + 2^-52) for every x up to the largest: the clamp never moves a mantissa.
    let m = m.min(MANTISSA_MAX) as i16;
    let m = if x < 0.0 { -m } else { m };
    if held_value(m, s, scale).abs() < f32::MIN_POSITIVE {
        return (0, 0);
    }
    (m, s)
}

/// Whether (m, s) is the canonical form of a stored quantity of scale `scale` with a finite
/// held value (module docs, Encoding).
fn canonical(m: i16, s: u8, scale: f64) -> bool {
    if m == 0 {
        return s == 0;
    }
    if m == i16::MIN || scale == 0.0 || (s < MAX_SHIFT && m.unsigned_abs() < MANTISSA_MIN) {
        return false;
    }
    let x = held_value(m, s, scale);
    x.is_finite() && x.abs() >= f32::MIN_POSITIVE
}

fn quantity(d: &HermiteData, q: usize) -> f64 {
    let ch = q % 3;
    match q / 3 {
        0 => d.f[ch],
        1 => d.fu[ch],
        2 => d.fv[ch],
        _ => d.fuv[ch],
    }
}

/// Held f32 data as f64 Hermite data (exact).
fn to_hermite(h: &[f32; QUANTITIES]) -> HermiteData {
    let x = |q: usize| h[q] as f64;
    HermiteData {
        f: [x(0), x(1), x(2)],
        fu: [x(3), x(4), x(5)],
        fv: [x(6), x(7), x(8)],
        fuv: [x(9), x(10), x(11)],
    }
}

/// Hermite data rounded to f32, the held form.
fn to_held(d: &HermiteData) -> [f32; QUANTITIES] {
    std::array::from_fn(|q| quantity(d, q) as f32)
}

/// One leaf: corners (global vertex indices, order (0,0), (1,0), (0,1), (1,1)), the cell's lattice
/// origin `i | j << 16` and `polygon << 5 | level`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Leaf {
    corners: [u32; 4],
    origin: u32,
    tag: u32,
}

impl Leaf {
    #[inline(always)]
    fn level(&self) -> u32 {
        self.tag & 31
    }

    #[inline(always)]
    fn polygon(&self) -> usize {
        (self.tag >> 5) as usize
    }

    #[inline(always)]
    fn cell(&self) -> Cell {
        let level = self.level();
        let sh = MAX_DEPTH - level;
        // Origins are multiples of the cell size; at level 0 the origin is 0 and sh = 16.
        Cell {
            level,
            x: (self.origin & 0xffff) >> sh,
            y: (self.origin >> 16) >> sh,
        }
    }
}

/// What one polygon's tree alone determines: its vertices, its leaves and which vertices are
/// derived, from which leaf, in which order (module docs).
pub(crate) struct Layout {
    /// Vertex keys, sorted.
    pub(crate) keys: Vec<VertexKey>,
    /// Per leaf in node order: its cell and corner vertex indices in patch corner order.
    pub(crate) leaves: Vec<(Cell, [u32; 4])>,
    /// Derived vertices in derivation order, each with the leaf (index in `leaves`) inside whose
    /// edge it lies; one leaf's entries are consecutive, leaves in ascending level.
    derived: Vec<(u32, u32)>,
    /// Per vertex: whether it is derived.
    pub(crate) is_derived: Vec<bool>,
}

impl Layout {
    pub(crate) fn of(tree: &Quadtree) -> Layout {
        let keys = tree.vertex_keys();
        // Every corner of a leaf is a vertex: the default never shows up.
        let rank = |k: VertexKey| keys.binary_search(&k).unwrap_or_default() as u32;
        let leaves: Vec<(Cell, [u32; 4])> = tree
            .nodes()
            .iter()
            .filter(|n| n.is_leaf())
            .map(|n| {
                let [c00, c10, c11, c01] = n.cell.corners();
                (n.cell, [c00, c10, c01, c11].map(rank))
            })
            .collect();
        let mut order: Vec<u32> = (0..leaves.len() as u32).collect();
        order.sort_by_key(|&l| leaves[l as usize].0.level);
        let mut is_derived = vec![false; keys.len()];
        let mut derived = Vec::new();
        let mut stack = Vec::new();
        for l in order {
            let [c00, c10, c11, c01] = leaves[l as usize].0.corners();
            // Edges from their lower to their upper end: bottom, right, top, left.
            for edge in [(c00, c10), (c10, c11), (c01, c11), (c00, c01)] {
                stack.push(edge);
                while let Some((a, b)) = stack.pop() {
                    let (di, dj) = (b.i - a.i, b.j - a.j);
                    if di + dj < 2 {
                        continue;
                    }
                    let mid = VertexKey::new(a.i + di / 2, a.j + dj / 2);
                    if let Ok(v) = keys.binary_search(&mid) {
                        // Exactly one leaf has a vertex inside an edge (module docs).
                        if !is_derived[v] {
                            is_derived[v] = true;
                            derived.push((l, v as u32));
                        }
                        stack.push((mid, b));
                        stack.push((a, mid));
                    }
                }
            }
        }
        Layout {
            keys,
            leaves,
            derived,
            is_derived,
        }
    }

    /// Number of stored (not derived) vertices.
    fn stored(&self) -> usize {
        self.keys.len() - self.derived.len()
    }

    /// Fills the derived vertices of `data` (every vertex, stored ones given) from their leaves'
    /// patches, in derivation order, passing each through `round` before it is used further.
    pub(crate) fn derive(
        &self,
        data: &mut [HermiteData],
        round: impl Fn(HermiteData) -> HermiteData,
    ) {
        let mut current: Option<(u32, PatchPoly)> = None;
        for &(l, v) in &self.derived {
            let poly = match current {
                Some((at, p)) if at == l => p,
                _ => {
                    let (cell, corners) = self.leaves[l as usize];
                    let p = PatchPoly::from_corners(cell, &corners.map(|c| data[c as usize]));
                    current = Some((l, p));
                    p
                }
            };
            let k = self.keys[v as usize];
            data[v as usize] = round(poly.hermite_at(k.u(), k.v()));
        }
    }
}

/// One polygon on its way in (from a build or a decode), with polygon-local vertex indices.
struct Part {
    tree: Quadtree,
    scales: [f64; QUANTITIES],
    /// Held data of every vertex, sorted key order.
    held: Vec<[f32; QUANTITIES]>,
    /// Per leaf in node order: its cell and local corner indices.
    leaves: Vec<(Cell, [u32; 4])>,
    /// Stored (not derived) vertices.
    stored: usize,
}

impl Part {
    /// Completes a polygon from its tree, layout, scales and the held data of its stored
    /// vertices (in sorted key order): derives the rest; an error if a held value is not finite.
    fn assemble(
        tree: Quadtree,
        layout: Layout,
        scales: [f64; QUANTITIES],
        stored: Vec<[f32; QUANTITIES]>,
    ) -> std::result::Result<Part, &'static str> {
        debug_assert_eq!(stored.len(), layout.stored());
        let mut data = vec![HermiteData::default(); layout.keys.len()];
        let slots = data.iter_mut().zip(&layout.is_derived).filter(|(_, &d)| !d);
        for ((slot, _), h) in slots.zip(&stored) {
            *slot = to_hermite(h);
        }
        layout.derive(&mut data, |d| to_hermite(&to_held(&d)));
        let held: Vec<[f32; QUANTITIES]> = data.iter().map(to_held).collect();
        if held.iter().flatten().any(|x| !x.is_finite()) {
            return Err("vertex data overflow f32 (sample values too large)");
        }
        Ok(Part {
            tree,
            scales,
            held,
            leaves: layout.leaves,
            stored: stored.len(),
        })
    }

    /// Quantizes one polygon's f64 reconstruction.
    fn quantize(index: usize, p: &PolygonRrp) -> Result<Part> {
        let err = |msg: &str| {
            Error::Inconsistent(format!("compact reconstruction of polygon {index}: {msg}"))
        };
        let tree = p.refined.tree.clone();
        let layout = Layout::of(&tree);
        let mut data = Vec::with_capacity(layout.stored());
        for (k, _) in layout
            .keys
            .iter()
            .zip(&layout.is_derived)
            .filter(|(_, &d)| !d)
        {
            // Refinement keeps data for every corner of every final leaf.
            data.push(
                p.refined
                    .data
                    .get(k)
                    .copied()
                    .ok_or_else(|| err("no data at a vertex"))?,
            );
        }
        let mut scales = [0.0f64; QUANTITIES];
        for (q, scale) in scales.iter_mut().enumerate() {
            let max = data.iter().fold(0.0f64, |m, d| m.max(quantity(d, q).abs()));
            if !max.is_finite() {
                return Err(err("vertex data not finite"));
            }
            *scale = max / MANTISSA_MAX;
        }
        let stored = data
            .iter()
            .map(|d| {
                std::array::from_fn(|q| {
                    let (m, s) = quantize(quantity(d, q), scales[q]);
                    held_value(m, s, scales[q])
                })
            })
            .collect();
        Part::assemble(tree, layout, scales, stored).map_err(err)
    }

    /// Every leaf expands to finite f32 coefficients (else an error naming polygon `index`).
    fn check(&self, index: usize) -> Result<()> {
        for (cell, corners) in &self.leaves {
            let data = corners.map(|v| to_hermite(&self.held[v as usize]));
            leaf_patch(index, &PatchPoly::from_corners(*cell, &data), cell.level)?;
        }
        Ok(())
    }
}

/// Sizes and memory of a [`CompactReconstruction`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct CompactStats {
    /// Number of polygons.
    pub polygons: usize,
    /// Vertices held (each with 12 f32), derived ones included.
    pub vertices: usize,
    /// Vertices stored in the encoding (not derived).
    pub stored_vertices: usize,
    /// Leaves (patches).
    pub leaves: usize,
    /// Nodes of the locate trees.
    pub nodes: usize,
    /// Locate trees (4 B per node), polygon roots (4 B each) and each leaf's cell and polygon
    /// (8 B).
    pub topology_bytes: usize,
    /// Held data (48 B per vertex) and per polygon its 12 f64 scales (96 B) and first vertex
    /// (4 B).
    pub vertex_bytes: usize,
    /// Each leaf's four corner vertex indices (16 B).
    pub corner_bytes: usize,
    /// Everything held: the sum of the three.
    pub total_bytes: usize,
    /// Length of [`CompactReconstruction::encode`]'s output.
    pub encoded_bytes: usize,
}

/// Every polygon's RRPs in compact form, in scene polygon order. See the module docs.
///
/// Methods taking a `polygon` index or a leaf `id` panic if it is out of range: that is a caller
/// bug, like an out-of-range slice index, not bad input.
#[derive(Debug, Clone, PartialEq)]
pub struct CompactReconstruction {
    /// Locate trees, encoded as in [`Reconstruction`].
    nodes: Vec<u32>,
    /// Index in `nodes` of each polygon's root.
    roots: Vec<u32>,
    /// Per global leaf id.
    leaves: Vec<Leaf>,
    /// Held data of every vertex, polygon by polygon, each polygon's in sorted key order.
    vertices: Vec<[f32; QUANTITIES]>,
    /// Per polygon: first vertex in `vertices`.
    first_vertex: Vec<u32>,
    /// Per polygon: the 12 scales S_q.
    scales: Vec<[f64; QUANTITIES]>,
    /// Stored (not derived) vertices over all polygons.
    stored_vertices: usize,
    /// A hash of the held data, naming the reconstruction whose patches a [`PatchCache`]
    /// holds (equal data expands to equal patches, so equal reconstructions may share a cache).
    content_id: u64,
}

/// Most slots of a patch cache (a power of two): 16384 x 212 bytes, 3.5 MB. A reconstruction
/// with fewer leaves gets the smallest power of two holding them all
/// ([`CompactReconstruction::cache_slots`]), so no two of its patches share a slot. Measured
/// (callgrind, cornell-box at 512 x 512, one thread): 8192 slots thrash on its ~18,000 leaves
/// (+15 % instructions per frame over stored patches), 16384 slots cost +1.5 %.
pub(crate) const CACHE_SLOTS: usize = 16384;

/// A worker's direct-mapped cache of expanded patches, owned by the caller (the frame stage
/// keeps one per worker, [`crate::PatchSource::warm`] fills it): leaf `id` lives in slot
/// `id % slots` (neighbouring leaves have neighbouring ids, so a region's patches rarely
/// collide). Expansion is a pure function of the stored integers, so a hit returns exactly what
/// [`CompactReconstruction::expand`] would: the cache changes times, never pixels.
#[derive(Debug, Default)]
pub struct PatchCache {
    /// The content id of the reconstruction whose patches the slots hold (0: none).
    owner: u64,
    ids: Vec<u32>,
    patches: Vec<PatchCoeffs>,
}

impl PatchCache {
    /// Bytes the cache has allocated (its slots' patches and ids).
    pub fn bytes(&self) -> usize {
        self.ids.capacity() * std::mem::size_of::<u32>()
            + self.patches.capacity() * std::mem::size_of::<PatchCoeffs>()
    }
}

impl CompactReconstruction {
    /// Slots of a patch cache for this reconstruction: the smallest power of two holding every
    /// leaf, at most [`CACHE_SLOTS`] (at least 1).
    pub(crate) fn cache_slots(&self) -> usize {
        self.leaves
            .len()
            .max(1)
            .next_power_of_two()
            .min(CACHE_SLOTS)
    }

    /// Bytes a patch cache allocates for this reconstruction (slots x (patch + id)): what
    /// [`PatchCache::bytes`] reports once it holds this reconstruction's patches.
    pub fn cache_bytes(&self) -> usize {
        self.cache_slots() * (std::mem::size_of::<PatchCoeffs>() + std::mem::size_of::<u32>())
    }

    /// The patch of leaf `id` through `cache`: what the direct method's region tables are filled
    /// from. Equal to [`CompactReconstruction::expand`].
    #[inline]
    pub(crate) fn cached_patch(&self, id: u32, cache: &mut PatchCache) -> PatchCoeffs {
        self.claim(cache);
        let slot = id as usize & (cache.ids.len() - 1);
        if cache.ids[slot] != id {
            cache.patches[slot] = self.expand(id);
            cache.ids[slot] = id;
        }
        cache.patches[slot]
    }

    /// Makes `cache` this reconstruction's: emptied and sized to [`Self::cache_slots`] exactly
    /// (allocated and first touched) when it held another's patches or none.
    #[inline]
    fn claim(&self, cache: &mut PatchCache) {
        if cache.owner != self.content_id || cache.ids.is_empty() {
            let slots = self.cache_slots();
            cache.owner = self.content_id;
            cache.ids = vec![u32::MAX; slots];
            cache.patches = vec![PatchCoeffs::whole([[0.0; 16]; 3]); slots];
        }
    }

    /// Fills `cache` with this reconstruction's patches ahead of the first frame: its memory
    /// allocated and first touched, and every leaf expanded into its slot in id order (with more
    /// leaves than slots, the later ids keep the shared slots), so that frame neither pays the
    /// page faults nor expands each visible patch on first use, as PixelFlow's renderers had
    /// every patch in memory before the first frame. It changes times, never pixels (an
    /// expansion is a pure function of the stored integers).
    pub fn warm(&self, cache: &mut PatchCache) {
        self.claim(cache);
        let mask = cache.ids.len() - 1;
        for id in 0..self.leaves.len() as u32 {
            let slot = id as usize & mask;
            if cache.ids[slot] != id {
                cache.patches[slot] = self.expand(id);
                cache.ids[slot] = id;
            }
        }
    }

    /// The content id: FNV-1a over every held array (never 0, the empty cache's owner).
    fn content_hash(&self) -> u64 {
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        let mut eat = |x: u64| {
            for b in x.to_le_bytes() {
                h = (h ^ b as u64).wrapping_mul(0x0000_0100_0000_01b3);
            }
        };
        self.nodes.iter().for_each(|&n| eat(n as u64));
        self.roots.iter().for_each(|&r| eat(r as u64));
        for l in &self.leaves {
            l.corners.iter().for_each(|&c| eat(c as u64));
            eat(l.origin as u64);
            eat(l.tag as u64);
        }
        self.vertices
            .iter()
            .flatten()
            .for_each(|&x| eat(x.to_bits() as u64));
        self.scales.iter().flatten().for_each(|&s| eat(s.to_bits()));
        self.first_vertex.iter().for_each(|&f| eat(f as u64));
        eat(self.stored_vertices as u64);
        h.max(1)
    }
}

fn limit_error() -> Error {
    Error::Inconsistent("compact reconstruction: more than 2^31 leaves, nodes or vertices".into())
}

/// The cubic Hermite basis (h00, h01, h10, h11) at s and its derivative, in absolute value.
fn abs_basis(s: f64) -> ([f64; 4], [f64; 4]) {
    let (s2, s3) = (s * s, s * s * s);
    let h = [
        2.0 * s3 - 3.0 * s2 + 1.0,
        -2.0 * s3 + 3.0 * s2,
        s3 - 2.0 * s2 + s,
        s3 - s2,
    ];
    let d = [
        6.0 * s2 - 6.0 * s,
        -6.0 * s2 + 6.0 * s,
        3.0 * s2 - 4.0 * s + 1.0,
        3.0 * s2 - 2.0 * s,
    ];
    (h.map(f64::abs), d.map(f64::abs))
}

/// `sum_ab |B_a(s)| |B_b(t)| e_ab` for the value and the partials (f, f_u, f_v, f_uv, global
/// units) of a patch of width `w` at local (s, t), where e holds non-negative per-corner
/// magnitudes (corner order x + 2y) of one channel's (f, f_u, f_v, f_uv): the triangle
/// inequality's bound on the change of the patch's Hermite data at (s, t) when each corner
/// quantity changes by at most its e.
fn hermite_abs(w: f64, s: f64, t: f64, e: &[[f64; 4]; 4]) -> [f64; 4] {
    let ((hs, ds), (ht, dt)) = (abs_basis(s), abs_basis(t));
    let mut out = [0.0f64; 4];
    for (c, ec) in e.iter().enumerate() {
        let (x, y) = (c & 1, c >> 1);
        // Geometry entries (s basis index, t basis index, magnitude).
        let g = [
            (x, y, ec[0]),
            (2 + x, y, w * ec[1]),
            (x, 2 + y, w * ec[2]),
            (2 + x, 2 + y, w * w * ec[3]),
        ];
        for (a, b, m) in g {
            out[0] += hs[a] * ht[b] * m;
            out[1] += ds[a] * ht[b] * m;
            out[2] += hs[a] * dt[b] * m;
            out[3] += ds[a] * dt[b] * m;
        }
    }
    [out[0], out[1] / w, out[2] / w, out[3] / (w * w)]
}

/// One channel's (f, f_u, f_v, f_uv) of 12 per-vertex numbers.
fn channel(x: &[f64; QUANTITIES], ch: usize) -> [f64; 4] {
    [x[ch], x[3 + ch], x[6 + ch], x[9 + ch]]
}

impl CompactReconstruction {
    fn empty() -> Self {
        CompactReconstruction {
            nodes: Vec::new(),
            roots: Vec::new(),
            leaves: Vec::new(),
            vertices: Vec::new(),
            first_vertex: Vec::new(),
            scales: Vec::new(),
            stored_vertices: 0,
            content_id: 0,
        }
    }

    /// Builds from the same per-polygon f64 reconstructions as [`Reconstruction::build`] (in
    /// parallel; the result does not depend on the thread count). Errors as
    /// [`Reconstruction::build`]'s, naming the first bad polygon in order, and also if a held
    /// value or a quantized patch overflows f32.
    pub fn build(
        polygons: &[SampledQuadtree],
        estimator: Estimator,
    ) -> Result<CompactReconstruction> {
        CompactReconstruction::build_with(polygons, estimator, &Seams::none(), None)
    }

    /// [`CompactReconstruction::build`], joining the polygons along `seams` and following the
    /// edges of `sharp` light (the same patches as [`Reconstruction::build_with`]).
    pub fn build_with(
        polygons: &[SampledQuadtree],
        estimator: Estimator,
        seams: &Seams,
        sharp: Option<Sharp<'_>>,
    ) -> Result<CompactReconstruction> {
        seams.check_fits(polygons.len(), "compact reconstruction")?;
        if polygons.len() > MAX_POLYGONS {
            return Err(Error::Inconsistent(
                "compact reconstruction: more than 2^27 polygons".into(),
            ));
        }
        let parts: Vec<Result<Part>> = build_polygons(polygons, estimator, seams, sharp)
            .into_par_iter()
            .enumerate()
            .map(|(index, b)| {
                let part = Part::quantize(index, &b?)?;
                part.check(index)?;
                Ok(part)
            })
            .collect();
        let mut out = CompactReconstruction::empty();
        for part in parts {
            out.push(part?)?;
        }
        out.content_id = out.content_hash();
        Ok(out)
    }

    /// Appends one polygon.
    fn push(&mut self, part: Part) -> Result<()> {
        let polygon = self.roots.len() as u32;
        let base = self.nodes.len();
        let vbase = self.vertices.len();
        if base + part.tree.nodes().len() >= LEAF as usize
            || self.leaves.len() + part.leaves.len() >= LEAF as usize
            || vbase + part.held.len() >= LEAF as usize
        {
            return Err(limit_error());
        }
        self.roots.push(base as u32);
        self.first_vertex.push(vbase as u32);
        let mut leaf_id = self.leaves.len() as u32;
        for n in part.tree.nodes() {
            if n.is_leaf() {
                self.nodes.push(LEAF | leaf_id);
                leaf_id += 1;
            } else {
                self.nodes.push((base + n.first_child as usize) as u32);
            }
        }
        for (cell, corners) in &part.leaves {
            let o = cell.origin();
            self.leaves.push(Leaf {
                corners: corners.map(|c| c + vbase as u32),
                origin: o.i | o.j << 16,
                tag: polygon << 5 | cell.level,
            });
        }
        self.vertices.extend_from_slice(&part.held);
        self.scales.push(part.scales);
        self.stored_vertices += part.stored;
        Ok(())
    }

    /// Number of polygons.
    pub fn polygon_count(&self) -> usize {
        self.roots.len()
    }

    /// Number of leaves (patches); ids are `0..leaf_count()`.
    pub fn leaf_count(&self) -> usize {
        self.leaves.len()
    }

    /// Global leaf id of the patch covering (u, v) of `polygon`: exactly
    /// [`Reconstruction::locate`]'s answer (same clamping, same edge rule, same ids).
    #[inline]
    pub fn locate(&self, polygon: u32, u: f32, v: f32) -> u32 {
        locate_in(
            &self.nodes,
            self.roots[polygon as usize],
            lattice_f32(u),
            lattice_f32(v),
        )
    }

    /// The held data of leaf `id`'s four corners (patch corner order), in f64 (exact).
    #[inline]
    pub(crate) fn corner_data(&self, id: u32) -> [HermiteData; 4] {
        self.leaves[id as usize]
            .corners
            .map(|v| to_hermite(&self.vertices[v as usize]))
    }

    /// The f64 patch of leaf `id` from its corners' held data.
    #[inline]
    pub(crate) fn poly(&self, id: u32) -> PatchPoly {
        PatchPoly::from_corners(self.leaves[id as usize].cell(), &self.corner_data(id))
    }

    /// The patch of leaf `id`, expanded from its four corners' held data, converted to f32 as
    /// [`Reconstruction`] does.
    #[inline]
    pub fn expand(&self, id: u32) -> PatchCoeffs {
        PatchCoeffs::from_poly(&self.poly(id), self.leaves[id as usize].level())
    }

    /// The 12 scales S_q of `polygon` (index `3 * kind + channel`, see `QUANTITIES`).
    pub fn scales(&self, polygon: u32) -> [f64; QUANTITIES] {
        self.scales[polygon as usize]
    }

    /// The final tree of polygon `p`, rebuilt from its locate tree (stored in canonical order).
    fn polygon_tree(&self, p: usize) -> Quadtree {
        let nodes = self.polygon_nodes(p);
        Quadtree::grow((), |id, _, ()| {
            (nodes.get(id as usize).is_some_and(|&e| e & LEAF == 0)).then_some([(); 4])
        })
    }

    /// Per vertex of polygon `p` (local indices) and quantity, a bound on |held - reference|:
    /// `seed(global vertex, q)` at stored vertices; at derived ones the larger leaf's corner
    /// bounds through [`hermite_abs`], plus `rounding` times the held value and 2^-40 times
    /// the |basis|-weighted sum of the larger leaf's held data (its f64 evaluation).
    pub(crate) fn propagated_errors(
        &self,
        p: usize,
        seed: impl Fn(usize, usize) -> f64,
        rounding: f64,
    ) -> Vec<[f64; QUANTITIES]> {
        let layout = Layout::of(&self.polygon_tree(p));
        let first = self.first_vertex[p] as usize;
        let held = |v: usize| self.vertices[first + v].map(|x| (x as f64).abs());
        let mut err: Vec<[f64; QUANTITIES]> = (0..layout.keys.len())
            .map(|v| std::array::from_fn(|q| seed(first + v, q)))
            .collect();
        for &(l, v) in &layout.derived {
            let (cell, corners) = layout.leaves[l as usize];
            let (u0, v0, _, _) = cell.bounds();
            let w = cell.width();
            let k = layout.keys[v as usize];
            let (s, t) = ((k.u() - u0) / w, (k.v() - v0) / w);
            let own = held(v as usize);
            let mut out = [0.0f64; QUANTITIES];
            for ch in 0..3 {
                let e = corners.map(|c| channel(&err[c as usize], ch));
                let m = corners.map(|c| channel(&held(c as usize), ch));
                let (pe, pm) = (hermite_abs(w, s, t, &e), hermite_abs(w, s, t, &m));
                for kind in 0..4 {
                    let q = 3 * kind + ch;
                    out[q] = pe[kind] + rounding * own[q] + 2f64.powi(-40) * pm[kind];
                }
            }
            err[v as usize] = out;
        }
        err
    }

    /// Per vertex of polygon `p`, the module docs' bound on |held - reference| per quantity.
    fn vertex_errors(&self, p: usize) -> Vec<[f64; QUANTITIES]> {
        let scales = self.scales[p];
        let seed = |v: usize, q: usize| {
            let x = self.vertices[v][q] as f64;
            match quantize(x, scales[q]) {
                (0, _) => scales[q] * 2f64.powi(-15) + 2f64.powi(-124),
                (_, s) => 0.5 * scales[q] * pow2_neg(s) + 2f64.powi(-23) * x.abs(),
            }
        };
        self.propagated_errors(p, seed, 2f64.powi(-23))
    }

    /// The module docs' bound on |expanded patch - reference patch| per channel over leaf `id`'s
    /// cell, in exact arithmetic (f32 rounding of the expansions not included):
    /// `df + (w/4)(dfu + dfv) + (w^2/16) dfuv`, dq the largest error of quantity q over the
    /// leaf's corners. Computed on demand from the whole polygon (for tests and measurements;
    /// [`Self::error_bounds`] gives every leaf of a polygon at once).
    pub fn error_bound(&self, id: u32) -> [f64; 3] {
        let p = self.leaves[id as usize].polygon();
        self.leaf_bound(id, &self.vertex_errors(p))
    }

    /// [`Self::error_bound`] of every leaf of `polygon`, in leaf id order.
    pub fn error_bounds(&self, polygon: u32) -> Vec<[f64; 3]> {
        let p = polygon as usize;
        let err = self.vertex_errors(p);
        self.polygon_nodes(p)
            .iter()
            .filter(|&&e| e & LEAF != 0)
            .map(|&e| self.leaf_bound(e & !LEAF, &err))
            .collect()
    }

    /// The bound of leaf `id` from its polygon's vertex errors.
    fn leaf_bound(&self, id: u32, err: &[[f64; QUANTITIES]]) -> [f64; 3] {
        let l = &self.leaves[id as usize];
        let first = self.first_vertex[l.polygon()];
        let w = l.cell().width();
        let worst = |q: usize| {
            l.corners
                .iter()
                .map(|&c| err[(c - first) as usize][q])
                .fold(0.0f64, f64::max)
        };
        std::array::from_fn(|ch| {
            worst(ch) + w / 4.0 * (worst(3 + ch) + worst(6 + ch)) + w * w / 16.0 * worst(9 + ch)
        })
    }

    /// The half-open rectangle `[u_lo, u_hi, v_lo, v_hi]` where `locate` answers `id`, computed
    /// exactly as [`Reconstruction`]'s [`PatchSource::cell`].
    #[inline]
    pub fn cell(&self, id: u32) -> [f32; 4] {
        let l = &self.leaves[id as usize];
        let c = l.cell();
        let (u0, v0, _, _) = c.bounds();
        let w = 1.0 / (1u32 << c.level) as f32;
        let (u0, v0) = (u0 as f32, v0 as f32);
        [u0, u0 + w, v0, v0 + w]
    }

    /// Sizes and memory (see [`CompactStats`]).
    pub fn stats(&self) -> CompactStats {
        let polygons = self.roots.len();
        let topology_bytes = 4 * self.nodes.len() + 4 * polygons + 8 * self.leaves.len();
        let vertex_bytes = std::mem::size_of::<[f32; QUANTITIES]>() * self.vertices.len()
            + polygons * (SCALE_BYTES + 4);
        let corner_bytes = 16 * self.leaves.len();
        CompactStats {
            polygons,
            vertices: self.vertices.len(),
            stored_vertices: self.stored_vertices,
            leaves: self.leaves.len(),
            nodes: self.nodes.len(),
            topology_bytes,
            vertex_bytes,
            corner_bytes,
            total_bytes: topology_bytes + vertex_bytes + corner_bytes,
            encoded_bytes: self.encoded_len(),
        }
    }

    /// Bytes held in memory ([`CompactStats::total_bytes`]).
    pub fn bytes(&self) -> usize {
        self.stats().total_bytes
    }

    fn polygon_nodes(&self, p: usize) -> &[u32] {
        let end = self
            .roots
            .get(p + 1)
            .map_or(self.nodes.len(), |&r| r as usize);
        &self.nodes[self.roots[p] as usize..end]
    }

    /// Length of [`Self::encode`]'s output, without encoding.
    pub fn encoded_len(&self) -> usize {
        let mut n = MAGIC.len() + 4 + RECORD_BYTES * self.stored_vertices;
        for p in 0..self.roots.len() {
            n += 4 + self.polygon_nodes(p).len().div_ceil(8) + SCALE_BYTES;
        }
        n
    }

    /// Mantissas and shifts of polygon `p`'s stored vertices in sorted key order, recovered
    /// from the held data (see [`quantize`]).
    pub(crate) fn stored_integers(&self, p: usize) -> Vec<([i16; QUANTITIES], [u8; QUANTITIES])> {
        let layout = Layout::of(&self.polygon_tree(p));
        let first = self.first_vertex[p] as usize;
        let scales = &self.scales[p];
        (0..layout.keys.len())
            .filter(|&v| !layout.is_derived[v])
            .map(|v| {
                let x = &self.vertices[first + v];
                let ms: [(i16, u8); QUANTITIES] =
                    std::array::from_fn(|q| quantize(x[q] as f64, scales[q]));
                (ms.map(|(m, _)| m), ms.map(|(_, s)| s))
            })
            .collect()
    }

    /// The little-endian encoding described in the module docs.
    pub fn encode(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(self.encoded_len());
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&(self.roots.len() as u32).to_le_bytes());
        for p in 0..self.roots.len() {
            let nodes = self.polygon_nodes(p);
            out.extend_from_slice(&(nodes.len() as u32).to_le_bytes());
            for chunk in nodes.chunks(8) {
                let byte = chunk
                    .iter()
                    .enumerate()
                    .fold(0u8, |b, (k, &e)| b | (u8::from(e & LEAF == 0) << k));
                out.push(byte);
            }
            for s in self.scales[p] {
                out.extend_from_slice(&s.to_le_bytes());
            }
            for (m, s) in self.stored_integers(p) {
                for pair in s.chunks(2) {
                    out.push(pair[0] | pair[1] << 4);
                }
                for x in m {
                    out.extend_from_slice(&x.to_le_bytes());
                }
            }
        }
        debug_assert_eq!(out.len(), self.encoded_len());
        out
    }

    /// Decodes [`Self::encode`]'s output. Anything but the canonical form (module docs,
    /// Encoding) is an [`Error::Inconsistent`], never a panic.
    pub fn decode(bytes: &[u8]) -> Result<CompactReconstruction> {
        let mut r = Reader { bytes, at: 0 };
        if r.take(MAGIC.len())? != MAGIC {
            return Err(bad("not a compact reconstruction (wrong magic)"));
        }
        let count = r.u32()? as usize;
        // Each polygon takes at least 4 + 1 + 96 bytes: bound the count before allocating.
        if count > MAX_POLYGONS || count > r.left() / (5 + SCALE_BYTES) {
            return Err(bad("polygon count larger than the data"));
        }
        let mut out = CompactReconstruction::empty();
        for index in 0..count {
            let part = decode_part(&mut r)?;
            part.check(index)
                .map_err(|_| bad("a patch coefficient overflows f32"))?;
            out.push(part)?;
        }
        if r.left() != 0 {
            return Err(bad("trailing bytes"));
        }
        out.content_id = out.content_hash();
        Ok(out)
    }
}

fn bad(msg: &str) -> Error {
    Error::Inconsistent(format!("compact reconstruction decode: {msg}"))
}

struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    fn left(&self) -> usize {
        self.bytes.len() - self.at
    }

    fn take(&mut self, n: usize) -> Result<&'a [u8]> {
        if n > self.left() {
            return Err(bad("truncated"));
        }
        let s = &self.bytes[self.at..self.at + n];
        self.at += n;
        Ok(s)
    }

    fn u32(&mut self) -> Result<u32> {
        let b = self.take(4)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }
}

/// The tree of one polygon from its node count and split bits.
fn decode_tree(r: &mut Reader) -> Result<Quadtree> {
    let n = r.u32()? as usize;
    if n % 4 != 1 || n.div_ceil(8) > r.left() {
        return Err(bad(
            "node count is not that of a quadtree or exceeds the data",
        ));
    }
    let bits = r.take(n.div_ceil(8))?;
    let bit = |k: usize| bits[k / 8] >> (k % 8) & 1 == 1;
    if (n..bits.len() * 8).any(bit) {
        return Err(bad("nonzero padding bits"));
    }
    let mut malformed = false;
    let tree = Quadtree::grow((), |id, cell, ()| {
        let id = id as usize;
        if id >= n || malformed {
            malformed = true;
            return None;
        }
        if !bit(id) {
            return None;
        }
        if cell.level >= MAX_DEPTH {
            malformed = true;
            return None;
        }
        Some([(); 4])
    });
    if malformed || tree.nodes().len() != n {
        return Err(bad("split bits do not describe a quadtree of depth <= 16"));
    }
    Ok(tree)
}

fn decode_part(r: &mut Reader) -> Result<Part> {
    let tree = decode_tree(r)?;
    let b = r.take(SCALE_BYTES)?;
    let scales: [f64; QUANTITIES] =
        std::array::from_fn(|q| f64::from_le_bytes(std::array::from_fn(|k| b[8 * q + k])));
    if scales
        .iter()
        .any(|s| !s.is_finite() || s.is_sign_negative())
    {
        return Err(bad("a scale is negative, -0 or not finite"));
    }
    let layout = Layout::of(&tree);
    let stored = layout.stored();
    if stored > r.left() / RECORD_BYTES {
        return Err(bad("truncated"));
    }
    let mut held = Vec::with_capacity(stored);
    for _ in 0..stored {
        let rec = r.take(RECORD_BYTES)?;
        let shift = |q: usize| rec[q / 2] >> (4 * (q % 2)) & 15;
        let at = QUANTITIES / 2;
        let mantissa = |q: usize| i16::from_le_bytes([rec[at + 2 * q], rec[at + 2 * q + 1]]);
        let mut h = [0.0f32; QUANTITIES];
        for (q, x) in h.iter_mut().enumerate() {
            let (m, s) = (mantissa(q), shift(q));
            if !canonical(m, s, scales[q]) {
                return Err(bad(
                    "a stored quantity is not in canonical form or overflows f32",
                ));
            }
            *x = held_value(m, s, scales[q]);
        }
        held.push(h);
    }
    Part::assemble(tree, layout, scales, held).map_err(bad)
}

impl CompactReconstruction {
    /// The held data of global vertex `v`.
    #[cfg(test)]
    pub(crate) fn held(&self, v: usize) -> [f32; QUANTITIES] {
        self.vertices[v]
    }

    /// Leaf `id`'s polygon and its corners' polygon-local vertex indices.
    #[cfg(test)]
    pub(crate) fn leaf_vertices(&self, id: u32) -> (usize, [usize; 4]) {
        let l = &self.leaves[id as usize];
        let first = self.first_vertex[l.polygon()];
        (l.polygon(), l.corners.map(|c| (c - first) as usize))
    }
}

/// The reference patches of one polygon (module docs, Error bound), in leaf order: its
/// unquantized vertex data with derived vertices taken from the larger leaf's patch in f64.
#[cfg(test)]
pub(crate) fn reference_polys(p: &PolygonRrp) -> Vec<PatchPoly> {
    let layout = Layout::of(&p.refined.tree);
    let mut data: Vec<HermiteData> = layout
        .keys
        .iter()
        .map(|k| p.refined.data.get(k).copied().unwrap_or_default())
        .collect();
    layout.derive(&mut data, |d| d);
    layout
        .leaves
        .iter()
        .map(|(cell, c)| PatchPoly::from_corners(*cell, &c.map(|v| data[v as usize])))
        .collect()
}

/// The direct method's view: `patch` comes through the thread's bounded cache of expanded
/// patches (`CompactReconstruction::cached_patch`).
impl PatchSource for CompactReconstruction {
    #[inline]
    fn locate(&self, polygon: u32, u: f32, v: f32) -> u32 {
        CompactReconstruction::locate(self, polygon, u, v)
    }

    #[inline]
    fn patch(&self, id: u32) -> PatchCoeffs {
        self.expand(id)
    }

    #[inline]
    fn patch_cached(&self, id: u32, cache: &mut PatchCache) -> PatchCoeffs {
        self.cached_patch(id, cache)
    }

    fn warm(&self, cache: &mut PatchCache) {
        CompactReconstruction::warm(self, cache);
    }

    /// Exactly [`Reconstruction`]'s cells (the same trees, the same f32 arithmetic).
    #[inline]
    fn cell(&self, id: u32) -> Option<[f32; 4]> {
        Some(CompactReconstruction::cell(self, id))
    }
}

#[cfg(doc)]
use super::Reconstruction;
