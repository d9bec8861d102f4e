//! T-vertex refinement (paper sec. 3.5) and merging: turns one polygon's unrestricted sample tree
//! plus the estimated Hermite data into the tree of patches that is finally stored.
//!
//! **Refinement.** A leaf with an *original sample* strictly inside one of its edges (a T-vertex
//! carrying its own data) is midpoint-subdivided. Child corners that already carry data (original
//! samples, or points made earlier) keep it; new points take value, f_u, f_v and f_uv from the
//! parent patch polynomial; data, once given to a point, never change. This repeats until no leaf
//! has an original sample inside an edge. If an original sample lies inside an edge of a cell,
//! the same-size cell across that edge was split in the input, so the edge midpoint is an
//! original sample too: checking the four edge midpoints is enough.
//!
//! **Why the result is C1.** On an edge of a bicubic Hermite patch, the value and the
//! cross-derivative are cubic Hermite interpolants of the data at the edge's two endpoints (value
//! and along-edge derivative; cross-derivative and twist). So two patches whose shared edge has
//! the same endpoint data agree to first order along it, and a patch agrees to first order with
//! any data taken from points of its own edge cubics (Hermite interpolation reproduces a cubic
//! from its endpoint data on any sub-interval).
//!
//! Claim: every *new* point M strictly inside an edge of a final leaf X carries data on X's edge
//! cubic. M was made by splitting some cell Y, from Y's polynomial. M is not Y's centre and X does
//! not lie inside Y (then M would be a corner of X), so M is the midpoint of Y's edge E_Y and X
//! lies across E_Y; X is not smaller than Y (a smaller dyadic edge cannot contain the midpoint of
//! E_Y in its interior), so E_Y lies within X's edge. Each endpoint of E_Y is a corner of X, or a
//! point strictly inside X's edge that existed before M; such a point is not an original sample
//! (X, a final leaf, has none inside its edges), so by induction on creation order its data lie
//! on X's edge cubic. Then Y's edge cubic is X's restricted to E_Y, and M's data lie on it.
//!
//! Now take two final leaves sharing an edge segment, A not larger than B: A's edge endpoints are
//! corners of B or new points inside B's edge, all on B's edge cubics by the claim, so A's edge
//! cubics are B's restricted: value and first derivatives agree along the whole edge, T-vertex
//! edges included. No cascade of splits is needed: only leaves touching real T-vertices are
//! refined. (The `c1_on_random_unrestricted_trees` proptest checks this on deep random trees.)
//!
//! **Merging.** A fully conforming refinement would also split the neighbours of new points; all
//! those children would reproduce their parent polynomial. More generally, any node whose four
//! children are leaves and whose new child corners (centre, edge midpoints) carry data equal to
//! the node's polynomial (within `MERGE_TOL` times the polygon's largest |value|, comparing
//! value and size-scaled derivatives) needs no patches of its own: the children are merged into
//! it, bottom-up. This also collapses original subdivision wherever the samples are reproduced
//! by a coarser patch (e.g. linear regions). C1 then holds up to that tolerance.

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

use super::hermite::{HermiteData, PatchPoly};
use base::quadtree::{Cell, Quadtree, VertexKey};

/// A fast hasher for lattice keys (two u32 of at most 17 bits): a multiplicative hash of the
/// packed pair. Keys are not attacker-controlled, so SipHash's DoS resistance is not needed; the
/// map is only ever looked up, never iterated in an order that matters, so output stays
/// deterministic.
#[derive(Default)]
pub(crate) struct KeyHasher(u64);

impl Hasher for KeyHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(b as u64);
        }
    }
    fn write_u32(&mut self, x: u32) {
        self.write_u64(x as u64);
    }
    fn write_u64(&mut self, x: u64) {
        self.0 = (self.0.rotate_left(21) ^ x).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    }
}

/// Vertex data keyed by lattice point.
pub(crate) type KeyMap<V> = HashMap<VertexKey, V, BuildHasherDefault<KeyHasher>>;

/// Merge tolerance relative to the polygon's largest |value|: just below one f32 ulp of that
/// value (1.2e-7), so merging only drops detail the f32 samples and coefficients cannot carry
/// anyway; far above f64 rounding (~1e-15) and far below the 1e-5 C1 requirement.
pub(crate) const MERGE_TOL: f64 = 1e-7;

/// The refined, merged patch tree of one polygon, with the Hermite data of its vertices.
#[derive(Debug, Clone)]
pub(crate) struct Refined {
    /// Final tree: its leaves are the patches.
    pub tree: Quadtree,
    /// Hermite data at every corner of every final leaf (global units).
    pub data: KeyMap<HermiteData>,
    /// Points created by refinement (not original samples) that survive as final corners.
    pub derived_points: usize,
    /// Nodes turned back into leaves by merging.
    pub merged_nodes: usize,
}

/// The Hermite data of `cell`'s corners in patch order (0,0), (1,0), (0,1), (1,1).
pub(crate) fn corner_data(data: &KeyMap<HermiteData>, cell: Cell) -> [HermiteData; 4] {
    let [c00, c10, c11, c01] = cell.corners();
    // Callers keep every corner of every leaf in `data`; the default never shows up.
    [c00, c10, c01, c11].map(|k| data.get(&k).copied().unwrap_or_default())
}

/// The four edge midpoints of `cell` (bottom, right, top, left). Only for size >= 2.
fn edge_midpoints(cell: Cell) -> [VertexKey; 4] {
    let o = cell.origin();
    let s = cell.size();
    let h = s / 2;
    [
        VertexKey::new(o.i + h, o.j),
        VertexKey::new(o.i + s, o.j + h),
        VertexKey::new(o.i + h, o.j + s),
        VertexKey::new(o.i, o.j + h),
    ]
}

/// Whether a border point of `forced` (sorted by key) lies strictly inside a side of `cell`
/// that is on the domain's border.
fn forced_inside(cell: Cell, forced: &[(VertexKey, HermiteData)]) -> bool {
    if forced.is_empty() {
        return false;
    }
    let o = cell.origin();
    let s = cell.size();
    let l = base::quadtree::LATTICE;
    let inside = |a: VertexKey, b: VertexKey| {
        // Keys are ordered by (j, i): on a row the run between a and b; on a column each key.
        let lo = forced.partition_point(|e| e.0 <= a);
        let hi = forced.partition_point(|e| e.0 < b);
        forced[lo..hi.max(lo)]
            .iter()
            .any(|e| (a.i == b.i && e.0.i == a.i) || (a.j == b.j && e.0.j == a.j))
    };
    (o.j == 0 && inside(VertexKey::new(o.i, 0), VertexKey::new(o.i + s, 0)))
        || (o.j + s == l && inside(VertexKey::new(o.i, l), VertexKey::new(o.i + s, l)))
        || (o.i == 0 && inside(VertexKey::new(0, o.j), VertexKey::new(0, o.j + s)))
        || (o.i + s == l && inside(VertexKey::new(l, o.j), VertexKey::new(l, o.j + s)))
}

/// Refines and merges one polygon. `keys` (sorted) and `data` are the original samples and their
/// estimated Hermite data; `forced` (sorted) are seam points on the domain's border with the
/// data they must carry (replacing a sample's, or new points the tree is split down to, as
/// original samples are); `scale` is the largest |value| of the polygon (for the merge test).
pub(crate) fn refine(
    tree: &Quadtree,
    keys: &[VertexKey],
    data: &[HermiteData],
    forced: &[(VertexKey, HermiteData)],
    scale: f64,
) -> Refined {
    let (t, map) = split(tree, keys, data, forced);
    merge(&t, map, keys, scale)
}

/// The refinement half of [`refine`]: the split tree and the data of every leaf corner.
pub(crate) fn split(
    tree: &Quadtree,
    keys: &[VertexKey],
    data: &[HermiteData],
    forced: &[(VertexKey, HermiteData)],
) -> (Quadtree, KeyMap<HermiteData>) {
    let mut t = tree.clone();
    let mut map: KeyMap<HermiteData> = keys.iter().copied().zip(data.iter().copied()).collect();
    map.extend(forced.iter().copied());
    let is_original = |k: VertexKey| keys.binary_search(&k).is_ok();

    // Depth-first over the leaves (a stack: deterministic order).
    let mut stack: Vec<u32> = t.leaves();
    stack.reverse();
    while let Some(id) = stack.pop() {
        let cell = t.node(id).cell;
        if cell.size() < 2
            || !(edge_midpoints(cell).into_iter().any(is_original) || forced_inside(cell, forced))
        {
            continue;
        }
        let first = split_leaf(&mut t, &mut map, id);
        for q in (0..4).rev() {
            stack.push(first + q);
        }
    }
    (t, map)
}

/// Splits leaf `id` of `t` at its midpoints; child corners without data take the leaf's patch
/// polynomial there (points that have data keep it). Returns the first child's id.
pub(crate) fn split_leaf(t: &mut Quadtree, map: &mut KeyMap<HermiteData>, id: u32) -> u32 {
    let cell = t.node(id).cell;
    let poly = PatchPoly::from_corners(cell, &corner_data(map, cell));
    let first = t.split(id);
    for child in cell.children() {
        for k in child.corners() {
            map.entry(k)
                .or_insert_with(|| poly.hermite_at(k.u(), k.v()));
        }
    }
    first
}

/// The merging half of [`refine`] on any tree whose leaf corners all carry data in `map`
/// (`keys`: the original samples, sorted, for the count of derived points).
pub(crate) fn merge(
    t: &Quadtree,
    map: KeyMap<HermiteData>,
    keys: &[VertexKey],
    scale: f64,
) -> Refined {
    let is_original = |k: VertexKey| keys.binary_search(&k).is_ok();
    // Merge bottom-up: children always have larger indices than their parent.
    let tol = MERGE_TOL * scale.max(f64::MIN_POSITIVE);
    let nodes = t.nodes();
    let mut leaf_now: Vec<bool> = nodes.iter().map(|n| n.is_leaf()).collect();
    let mut merged_nodes = 0usize;
    for id in (0..nodes.len()).rev() {
        let n = nodes[id];
        if n.is_leaf() || !(0..4).all(|q| leaf_now[n.first_child as usize + q]) {
            continue;
        }
        let poly = PatchPoly::from_corners(n.cell, &corner_data(&map, n.cell));
        let mut inner = edge_midpoints(n.cell).to_vec();
        inner.push(n.cell.centre());
        let agrees = inner.iter().all(|k| {
            map.get(k)
                .is_some_and(|d| poly.agrees_with(k.u(), k.v(), d, tol))
        });
        if agrees {
            leaf_now[id] = true;
            merged_nodes += 1;
        }
    }

    // Compact: rebuild the tree without the merged-away subtrees, in the canonical node order of
    // `Quadtree::grow` (which the compact encoding relies on to store 1 bit per node).
    let out = Quadtree::grow(0u32, |_, _, old| {
        if leaf_now[old as usize] {
            return None;
        }
        let of = t.node(old).first_child;
        Some([of, of + 1, of + 2, of + 3])
    });
    let mut data_out = KeyMap::default();
    for n in out.nodes().iter().filter(|n| n.is_leaf()) {
        for k in n.cell.corners() {
            if let Some(d) = map.get(&k) {
                data_out.insert(k, *d);
            }
        }
    }
    let derived_points = data_out.keys().filter(|&&k| !is_original(k)).count();
    Refined {
        tree: out,
        data: data_out,
        derived_points,
        merged_nodes,
    }
}
