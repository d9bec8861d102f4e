//! Compact reconstruction: the same RRPs as [`Reconstruction`], held as what they are made of
//! (each polygon's final refined, merged quadtree and the Hermite data of its vertices) instead
//! of expanded power-basis patches; a patch is expanded on demand
//! ([`CompactReconstruction::expand`]), the way the direct method asks for it (once per distinct
//! patch per screen region per frame).
//!
//! **Invariants.** Leaf ids, their order and [`CompactReconstruction::locate`] are exactly
//! [`Reconstruction`]'s, and so are the cells ([`PatchSource::cell`]). A vertex holds 12
//! quantities (f, f_u, f_v, f_uv per RGB channel) as f32: a **stored** vertex quantized (per
//! polygon and quantity an f64 scale, per vertex a 4-bit shift and a normalized i16 mantissa),
//! a **derived** vertex (a T-vertex inside a larger leaf's edge) evaluated from that leaf's
//! patch, so quantization opens no jump anywhere and two patches sharing an edge are C1 across
//! it to f32 rounding. Every held value and expanded coefficient is finite;
//! [`CompactReconstruction::decode`] accepts only the canonical encoding
//! (`encode(decode(b)) == b`) and never panics.
//!
//! **Why this layout.** One 24-byte record per leaf and 48 bytes of held f32 data per vertex make
//! `expand` one record read, four vertex reads and the Hermite-to-power product: no search and
//! no dequantization. The quantization, the T-vertex rule, the error bound
//! ([`CompactReconstruction::error_bound`]) with its derivation, the encoding and the measured
//! errors and sizes are in `docs/compact-rrps.md`.

use rayon::prelude::*;

use crate::{Seams, Sharp};

use super::hermite::{HermiteData, PatchPoly};
use super::{
    build_polygons, lattice_f32, leaf_patch, locate_in, Estimator, PatchCoeffs, PatchSource,
    PolygonRrp, LEAF,
};
use base::error::{Error, Result};
use base::quadtree::{Cell, Quadtree, SampledQuadtree, VertexKey, MAX_DEPTH};

mod bound;
mod encoding;

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

    /// The locate tree nodes of polygon `p`.
    fn polygon_nodes(&self, p: usize) -> &[u32] {
        let end = self
            .roots
            .get(p + 1)
            .map_or(self.nodes.len(), |&r| r as usize);
        &self.nodes[self.roots[p] as usize..end]
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
