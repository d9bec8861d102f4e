//! Compact reconstruction: the same RRPs as [`Reconstruction`], held as what they are made of
//! (each polygon's final refined, merged quadtree and the Hermite data of its vertices, quantized
//! to 16 bits) instead of expanded power-basis patches; a patch is expanded on demand
//! ([`CompactReconstruction::expand`]), the way the direct method asks for it (once per distinct
//! patch per screen region per frame).
//!
//! **Invariants.** Leaf ids, their order (polygon order, then the final tree's node order) and
//! [`CompactReconstruction::locate`] are exactly [`Reconstruction`]'s, and so are the cells
//! ([`PatchSource::cell`]); the trees are the same trees. Each of the 12 quantities of a vertex
//! (f, f_u, f_v, f_uv per RGB channel, global parameter units) is `m * 2^e`: one power-of-two
//! scale per polygon and quantity, e the smallest (not below -1074) with
//! `max |x| / 2^e <= 32767`, and an i16 mantissa `m = round(x / 2^e)`, |m| <= 32767; a quantity
//! that is zero at every vertex of its polygon has the exponent `ZERO_EXPONENT` and scale 0.
//! Dequantization (`m as f64 * 2^e`) is exact, so `expand` is a pure function of the stored
//! integers: the patch of a leaf goes through `PatchPoly::from_corners` and the same f64 to f32
//! conversion as [`Reconstruction`], and with unquantized data it would be bit-identical to
//! Reconstruction's patch. Every expanded coefficient is finite (checked at build and decode).
//!
//! **Error bound.** A patch of width w (global units) is
//! `f(s, t) = sum_ab H_a(s) H_b(t) g_ab` with the cubic Hermite basis
//! (H_0, H_1, H_2, H_3) = (h00, h01, h10, h11) and the geometry g holding corner values,
//! `w f_u`, `w f_v` and `w^2 f_uv`. On [0, 1], h00 = (1-s)^2 (1+2s) and h01 = s^2 (3-2s) are
//! non-negative with sum 1, and |h10| + |h11| = s(1-s)^2 + s^2(1-s) = s(1-s) <= 1/4. Rounding
//! quantity q moves each corner's entry by at most its half-step dq = 2^(e_q - 1) (0 for a zero
//! quantity), so per channel, at any (s, t) in the cell,
//! `|value error| <= df + s(1-s) w dfu + t(1-t) w dfv + s(1-s) t(1-t) w^2 dfuv
//!                <= df + (w/4)(dfu + dfv) + (w^2/16) dfuv`
//! ([`CompactReconstruction::error_bound`]), plus the f32 rounding of the two expansions (at most
//! 2^-24 times the sum of |coefficients| of each patch, the monomials lying in [0, 1]). Because
//! the scales are per polygon, derivative steps are relative to the polygon's steepest vertex
//! while w is the patch's own width: on a polygon with one sharp feature at depth d, a root-sized
//! patch's bound carries (w / w_min) 2^-15 of the largest f_u and (w / w_min)^2 2^-15 of the
//! largest twist. The property tests check the bound; on the shipped scenes the largest error
//! measured over every patch (a 5 x 5 grid each) is 1.9-2.7e-5 of the scene's largest sample, the
//! largest bound 1.9-3.0e-5: the value half-step (2^-16 of a polygon's largest value) dominates.
//!
//! **Continuity.** Vertices are shared, so two patches whose common edge has the same two end
//! vertices see identical quantized data there and stay C1 exactly as before (to f64 rounding;
//! tested on a conforming grid). Where a vertex lies inside the edge of a larger leaf (a
//! T-vertex), refinement had given it data on the larger leaf's edge cubics; quantized
//! independently of the larger leaf's corners, those data leave the cubics, so along such an
//! edge the value may jump by up to the sum of both sides' value bounds and the size-scaled
//! derivative by up to the sum of both sides' derivative bounds
//! `3 df + w (dfu + dfv) + (w^2/4) dfuv` (from sum |h00'| + |h01'| = 12 s(1-s) <= 3 and
//! |h10'| + |h11'| <= 1), plus the unquantized merge tolerance; the tests check exactly that.
//! Deriving such vertices' data from the larger leaf's dequantized polynomial when loading (not
//! done) would make the quantized reconstruction exactly C1 again and store fewer vertices.
//!
//! **Layout, and why.** In memory: the locate tree as [`Reconstruction`] stores it (4 B per
//! node: `LEAF | leaf id` or the first child's index), so `locate` is the same code; one 24-byte
//! record per leaf (its four corners' global vertex indices in patch corner order, its cell's
//! lattice origin, level and polygon); 24 bytes of mantissas per vertex; per polygon its root,
//! first vertex, 12 exponents and their 12 f64 scales. `expand` is therefore one record read, four
//! independent 24-byte vertex reads, 48 exact multiplies and the Hermite-to-power product: no
//! search. Measured on the shipped scenes (release build, one core): ~180 ns per `expand`, almost
//! all of it `PatchPoly::from_corners` (copying an expanded patch out of [`Reconstruction`]
//! takes ~5-10 ns). The alternative, sorted vertex keys per polygon (8 B per vertex) instead of
//! the corner indices (16 B per leaf), found by four binary searches per expand, measured 20-70 ns
//! more per expand (+10-40 %) to save 3-14 % of the bytes; direct indices were chosen. Memory is
//! 54-74 B per original sample against 138-281 B for the expanded patches.
//!
//! **Encoding** ([`CompactReconstruction::encode`], little-endian): the 8-byte magic
//! `PFRRPC01`, the polygon count (u32), then per polygon its node count (u32), one bit per node
//! in the tree's node order (1 = split; LSB first, zero-padded to a byte), its 12 exponents (i16)
//! and 12 i16 mantissas per vertex, vertices in sorted key order. The node order is
//! [`Quadtree::grow`]'s canonical order, which refinement produces, so the bits rebuild the tree
//! with identical node (and therefore leaf) indices; vertex keys and leaf corners are derived
//! from the tree. [`CompactReconstruction::decode`] checks everything (lengths, tree shape,
//! depth, exponent range, canonical zero quantities and padding, finite expansions) and returns
//! an error, never panics, on malformed bytes.

use rayon::prelude::*;

use super::hermite::{HermiteData, PatchPoly};
use super::{
    build_polygons, lattice_f32, leaf_patch, locate_in, Estimator, PatchCoeffs, PatchSource,
    PolygonRrp, LEAF,
};
use base::error::{Error, Result};
use base::quadtree::{Cell, Quadtree, SampledQuadtree, VertexKey, MAX_DEPTH};

/// Quantities per vertex: index `3 * kind + channel`, kind 0 = f, 1 = f_u, 2 = f_v, 3 = f_uv.
pub(crate) const QUANTITIES: usize = 12;

/// Exponent of a quantity that is zero at every vertex of its polygon (scale 0).
pub(crate) const ZERO_EXPONENT: i16 = i16::MIN;

/// Largest |mantissa|.
const MANTISSA_MAX: f64 = 32767.0;

/// Exponent range of nonzero quantities: 2^e is an f64 (subnormal below -1022).
const MIN_EXP: i32 = -1074;
const MAX_EXP: i32 = 1023;

/// Magic at the start of an encoding.
const MAGIC: &[u8; 8] = b"PFRRPC01";

/// Largest polygon count (the polygon index shares a u32 with the level in a leaf record).
const MAX_POLYGONS: usize = 1 << 27;

/// 2^e exactly, for e in [MIN_EXP, MAX_EXP].
fn pow2(e: i32) -> f64 {
    debug_assert!((MIN_EXP..=MAX_EXP).contains(&e));
    if e >= -1022 {
        f64::from_bits(((e + 1023) as u64) << 52)
    } else {
        f64::from_bits(1u64 << (e + 1074))
    }
}

/// The scale of exponent `e` (0 for [`ZERO_EXPONENT`]).
fn scale_of(e: i16) -> f64 {
    if e == ZERO_EXPONENT {
        0.0
    } else {
        pow2(e as i32)
    }
}

/// The smallest exponent (not below [`MIN_EXP`]) with `max / 2^e <= 32767`; [`ZERO_EXPONENT`]
/// for 0. `max` is finite and >= 0.
fn exponent_for(max: f64) -> i16 {
    if max == 0.0 {
        return ZERO_EXPONENT;
    }
    let fits = |e: i32| max / pow2(e) <= MANTISSA_MAX;
    // log2 estimate, then exact correction by the (exact) power-of-two divisions.
    let mut e = ((max / MANTISSA_MAX).log2().ceil() as i32).clamp(MIN_EXP, MAX_EXP);
    while e < MAX_EXP && !fits(e) {
        e += 1;
    }
    while e > MIN_EXP && fits(e - 1) {
        e -= 1;
    }
    e as i16
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

fn dequantize(m: &[i16; QUANTITIES], scale: &[f64; QUANTITIES]) -> HermiteData {
    let x = |q: usize| m[q] as f64 * scale[q];
    HermiteData {
        f: [x(0), x(1), x(2)],
        fu: [x(3), x(4), x(5)],
        fv: [x(6), x(7), x(8)],
        fuv: [x(9), x(10), x(11)],
    }
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

/// One polygon on its way in (from a build or a decode), with polygon-local vertex indices.
struct Part {
    tree: Quadtree,
    exponents: [i16; QUANTITIES],
    mantissas: Vec<[i16; QUANTITIES]>,
    /// Per leaf in node order: its cell and local corner indices.
    leaves: Vec<(Cell, [u32; 4])>,
}

impl Part {
    /// Derives the leaves' corners from the tree (vertices in sorted key order).
    fn new(
        tree: Quadtree,
        exponents: [i16; QUANTITIES],
        mantissas: Vec<[i16; QUANTITIES]>,
    ) -> Part {
        let keys = tree.vertex_keys();
        debug_assert_eq!(keys.len(), mantissas.len());
        let rank = |k: VertexKey| keys.binary_search(&k).unwrap_or_default() as u32;
        let leaves = tree
            .nodes()
            .iter()
            .filter(|n| n.is_leaf())
            .map(|n| {
                let [c00, c10, c11, c01] = n.cell.corners();
                (n.cell, [c00, c10, c01, c11].map(rank))
            })
            .collect();
        Part {
            tree,
            exponents,
            mantissas,
            leaves,
        }
    }

    /// Quantizes one polygon's f64 reconstruction.
    fn quantize(index: usize, p: &PolygonRrp) -> Result<Part> {
        let tree = p.refined.tree.clone();
        let keys = tree.vertex_keys();
        let mut data = Vec::with_capacity(keys.len());
        for k in &keys {
            // Refinement keeps data for every corner of every final leaf.
            let d = p.refined.data.get(k).copied().ok_or_else(|| {
                Error::Inconsistent(format!(
                    "compact reconstruction of polygon {index}: no data at a vertex"
                ))
            })?;
            data.push(d);
        }
        let mut exponents = [ZERO_EXPONENT; QUANTITIES];
        let mut scales = [0.0f64; QUANTITIES];
        for q in 0..QUANTITIES {
            let max = data.iter().fold(0.0f64, |m, d| m.max(quantity(d, q).abs()));
            if !max.is_finite() {
                return Err(Error::Inconsistent(format!(
                    "compact reconstruction of polygon {index}: vertex data not finite"
                )));
            }
            exponents[q] = exponent_for(max);
            scales[q] = scale_of(exponents[q]);
        }
        let mantissas = data
            .iter()
            .map(|d| {
                std::array::from_fn(|q| {
                    if scales[q] == 0.0 {
                        0
                    } else {
                        // Exact division by a power of two; |x / 2^e| <= 32767 by the choice of e.
                        (quantity(d, q) / scales[q]).round() as i16
                    }
                })
            })
            .collect();
        Ok(Part::new(tree, exponents, mantissas))
    }

    /// Every leaf expands to finite f32 coefficients (else an error naming polygon `index`).
    fn check(&self, index: usize) -> Result<()> {
        let scales = self.exponents.map(scale_of);
        for (cell, corners) in &self.leaves {
            let data = corners.map(|v| dequantize(&self.mantissas[v as usize], &scales));
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
    /// Vertices (each with 12 mantissas).
    pub vertices: usize,
    /// Leaves (patches).
    pub leaves: usize,
    /// Nodes of the locate trees.
    pub nodes: usize,
    /// Locate trees (4 B per node), polygon roots (4 B each) and each leaf's cell and polygon
    /// (8 B).
    pub topology_bytes: usize,
    /// Mantissas (24 B per vertex) and per polygon its 12 exponents (24 B), 12 f64 scales (96 B)
    /// and first vertex (4 B).
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
    /// 12 mantissas per vertex, polygon by polygon, each polygon's in sorted key order.
    mantissas: Vec<[i16; QUANTITIES]>,
    /// Per polygon: first vertex in `mantissas`.
    first_vertex: Vec<u32>,
    /// Per polygon: the 12 exponents.
    exponents: Vec<[i16; QUANTITIES]>,
    /// Per polygon: the 12 scales 2^e (0 for a zero quantity).
    scales: Vec<[f64; QUANTITIES]>,
    /// A hash of the stored data, naming the reconstruction whose patches a [`PatchCache`]
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

    /// The content id: FNV-1a over every stored array (never 0, the empty cache's owner).
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
        for m in self.mantissas.iter().chain(&self.exponents) {
            m.iter().for_each(|&x| eat(x as u16 as u64));
        }
        self.first_vertex.iter().for_each(|&f| eat(f as u64));
        h.max(1)
    }
}

fn limit_error() -> Error {
    Error::Inconsistent("compact reconstruction: more than 2^31 leaves, nodes or vertices".into())
}

impl CompactReconstruction {
    fn empty() -> Self {
        CompactReconstruction {
            nodes: Vec::new(),
            roots: Vec::new(),
            leaves: Vec::new(),
            mantissas: Vec::new(),
            first_vertex: Vec::new(),
            exponents: Vec::new(),
            scales: Vec::new(),
            content_id: 0,
        }
    }

    /// Builds from the same per-polygon f64 reconstructions as [`Reconstruction::build`] (in
    /// parallel; the result does not depend on the thread count). Errors as
    /// [`Reconstruction::build`]'s, naming the first bad polygon in order, and also if a
    /// quantized patch overflows f32.
    pub fn build(
        polygons: &[SampledQuadtree],
        estimator: Estimator,
    ) -> Result<CompactReconstruction> {
        if polygons.len() > MAX_POLYGONS {
            return Err(Error::Inconsistent(
                "compact reconstruction: more than 2^27 polygons".into(),
            ));
        }
        let parts: Vec<Result<Part>> = build_polygons(polygons, estimator)
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
        let vbase = self.mantissas.len();
        if base + part.tree.nodes().len() >= LEAF as usize
            || self.leaves.len() + part.leaves.len() >= LEAF as usize
            || vbase + part.mantissas.len() >= LEAF as usize
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
        self.mantissas.extend_from_slice(&part.mantissas);
        self.exponents.push(part.exponents);
        self.scales.push(part.exponents.map(scale_of));
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

    /// The f64 patch of leaf `id` from its corners' dequantized data.
    #[inline]
    pub(crate) fn poly(&self, id: u32) -> PatchPoly {
        let l = &self.leaves[id as usize];
        let scale = &self.scales[l.polygon()];
        let corners = l
            .corners
            .map(|v| dequantize(&self.mantissas[v as usize], scale));
        PatchPoly::from_corners(l.cell(), &corners)
    }

    /// The patch of leaf `id`, expanded from its four corners' dequantized Hermite data, converted
    /// to f32 as [`Reconstruction`] does.
    #[inline]
    pub fn expand(&self, id: u32) -> PatchCoeffs {
        PatchCoeffs::from_poly(&self.poly(id), self.leaves[id as usize].level())
    }

    /// The 12 exponents of `polygon` (index `3 * kind + channel`, see `QUANTITIES`).
    pub fn exponents(&self, polygon: u32) -> [i16; QUANTITIES] {
        self.exponents[polygon as usize]
    }

    /// The module docs' bound on |expanded patch - unquantized patch| per channel over leaf `id`'s
    /// cell, in exact arithmetic (f32 rounding of the expansions not included):
    /// `df + (w/4)(dfu + dfv) + (w^2/16) dfuv`, dq = half the scale of quantity q.
    pub fn error_bound(&self, id: u32) -> [f64; 3] {
        let l = &self.leaves[id as usize];
        let half = self.scales[l.polygon()].map(|s| 0.5 * s);
        let w = l.cell().width();
        std::array::from_fn(|ch| {
            half[ch] + w / 4.0 * (half[3 + ch] + half[6 + ch]) + w * w / 16.0 * half[9 + ch]
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
        let vertex_bytes = 2 * QUANTITIES * self.mantissas.len()
            + polygons * (2 * QUANTITIES + 8 * QUANTITIES + 4);
        let corner_bytes = 16 * self.leaves.len();
        CompactStats {
            polygons,
            vertices: self.mantissas.len(),
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

    fn polygon_vertices(&self, p: usize) -> &[[i16; QUANTITIES]] {
        let end = self
            .first_vertex
            .get(p + 1)
            .map_or(self.mantissas.len(), |&r| r as usize);
        &self.mantissas[self.first_vertex[p] as usize..end]
    }

    /// Length of [`Self::encode`]'s output, without encoding.
    pub fn encoded_len(&self) -> usize {
        let mut n = MAGIC.len() + 4;
        for p in 0..self.roots.len() {
            n += 4 + self.polygon_nodes(p).len().div_ceil(8) + 2 * QUANTITIES;
            n += 2 * QUANTITIES * self.polygon_vertices(p).len();
        }
        n
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
            for e in self.exponents[p] {
                out.extend_from_slice(&e.to_le_bytes());
            }
            for m in self.polygon_vertices(p).iter().flatten() {
                out.extend_from_slice(&m.to_le_bytes());
            }
        }
        debug_assert_eq!(out.len(), self.encoded_len());
        out
    }

    /// Decodes [`Self::encode`]'s output. Malformed bytes (wrong magic, truncation, trailing
    /// bytes, a bit pattern that is not a quadtree of depth <= 16 in canonical order, nonzero
    /// padding bits, exponents out of range, nonzero mantissas of a zero quantity, a mantissa of
    /// -32768, expansions that overflow f32) are an [`Error::Inconsistent`], never a panic.
    pub fn decode(bytes: &[u8]) -> Result<CompactReconstruction> {
        let mut r = Reader { bytes, at: 0 };
        if r.take(MAGIC.len())? != MAGIC {
            return Err(bad("not a compact reconstruction (wrong magic)"));
        }
        let count = r.u32()? as usize;
        // Each polygon takes at least 4 + 1 + 24 bytes: bound the count before allocating.
        if count > MAX_POLYGONS || count > r.left() / 29 {
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

    fn i16s<const N: usize>(&mut self) -> Result<[i16; N]> {
        let b = self.take(2 * N)?;
        Ok(std::array::from_fn(|k| {
            i16::from_le_bytes([b[2 * k], b[2 * k + 1]])
        }))
    }
}

fn decode_part(r: &mut Reader) -> Result<Part> {
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
    let exponents: [i16; QUANTITIES] = r.i16s()?;
    if exponents
        .iter()
        .any(|&e| e != ZERO_EXPONENT && !(MIN_EXP..=MAX_EXP).contains(&(e as i32)))
    {
        return Err(bad("exponent out of range"));
    }
    let vertices = tree.vertex_keys().len();
    if vertices > r.left() / (2 * QUANTITIES) {
        return Err(bad("truncated"));
    }
    let mut mantissas = Vec::with_capacity(vertices);
    for _ in 0..vertices {
        let m: [i16; QUANTITIES] = r.i16s()?;
        for (q, &x) in m.iter().enumerate() {
            if x == i16::MIN || (exponents[q] == ZERO_EXPONENT && x != 0) {
                return Err(bad("mantissa out of range"));
            }
        }
        mantissas.push(m);
    }
    Ok(Part::new(tree, exponents, mantissas))
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
