//! Quadtree: the adaptive subdivision of one polygon's parametric domain [0, 1]^2, shared by the
//! radiosity solver (which builds it), the reconstruction (which turns it into patches), the
//! texture resampler and the mesh backend.
//!
//! Invariants:
//! - the tree is *unrestricted*: neighbouring leaves may differ by any number of levels, and the
//!   T-vertices that follows are kept, never balanced away;
//! - every cell and vertex lives on one integer lattice of (2^[`MAX_DEPTH`] + 1)^2 points, so
//!   vertices shared by cells of different depths have one exact key ([`VertexKey`]) and no
//!   floating-point comparison ever decides identity;
//! - node 0 is the root; a node is a leaf or has exactly four children, stored consecutively in
//!   the order (x, y) = (0,0), (1,0), (0,1), (1,1); traversal order is therefore deterministic;
//! - a [`SampledQuadtree`] holds one RGB sample at every vertex of every leaf (corners and
//!   T-vertices alike), sorted by key; each is a true sample of the radiosity, never interpolated.

use glam::Vec3;

/// Deepest level a quadtree may reach: the lattice has 2^MAX_DEPTH intervals per side.
pub const MAX_DEPTH: u32 = 16;

/// Lattice intervals per side of the domain.
pub const LATTICE: u32 = 1 << MAX_DEPTH;

/// A lattice point of the domain: (u, v) = (i, j) / [`LATTICE`]. Ordered by (j, i): row-major.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct VertexKey {
    /// Row (v) index, 0..=LATTICE. First, so that the derived order is row-major.
    pub j: u32,
    /// Column (u) index, 0..=LATTICE.
    pub i: u32,
}

impl VertexKey {
    /// The key at lattice column `i`, row `j`.
    pub const fn new(i: u32, j: u32) -> Self {
        VertexKey { j, i }
    }

    /// Parameter u of this lattice point.
    #[inline]
    pub fn u(self) -> f64 {
        self.i as f64 / LATTICE as f64
    }

    /// Parameter v of this lattice point.
    #[inline]
    pub fn v(self) -> f64 {
        self.j as f64 / LATTICE as f64
    }
}

/// A square cell of the domain: at `level` L it spans lattice columns [x, x + 1] * 2^(MAX_DEPTH - L)
/// and rows [y, y + 1] * 2^(MAX_DEPTH - L), with x, y in 0..2^L.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Cell {
    /// Depth; 0 is the whole domain.
    pub level: u32,
    /// Column of the cell among the 2^level cells of its level.
    pub x: u32,
    /// Row of the cell among the 2^level cells of its level.
    pub y: u32,
}

impl Cell {
    /// The whole domain.
    pub const ROOT: Cell = Cell {
        level: 0,
        x: 0,
        y: 0,
    };

    /// Side length in lattice units.
    #[inline]
    pub fn size(self) -> u32 {
        LATTICE >> self.level
    }

    /// Side length in parameter units.
    #[inline]
    pub fn width(self) -> f64 {
        1.0 / (1u64 << self.level) as f64
    }

    /// Lower-left lattice point.
    #[inline]
    pub fn origin(self) -> VertexKey {
        VertexKey::new(self.x * self.size(), self.y * self.size())
    }

    /// The four corners in the order (0,0), (1,0), (1,1), (0,1): counter-clockwise.
    pub fn corners(self) -> [VertexKey; 4] {
        let s = self.size();
        let o = self.origin();
        [
            o,
            VertexKey::new(o.i + s, o.j),
            VertexKey::new(o.i + s, o.j + s),
            VertexKey::new(o.i, o.j + s),
        ]
    }

    /// The centre point (a lattice point for level < MAX_DEPTH).
    pub fn centre(self) -> VertexKey {
        let h = self.size() / 2;
        let o = self.origin();
        VertexKey::new(o.i + h, o.j + h)
    }

    /// The four children, in the order (0,0), (1,0), (0,1), (1,1). Only for level < MAX_DEPTH.
    pub fn children(self) -> [Cell; 4] {
        let l = self.level + 1;
        let (x, y) = (2 * self.x, 2 * self.y);
        [
            Cell { level: l, x, y },
            Cell {
                level: l,
                x: x + 1,
                y,
            },
            Cell {
                level: l,
                x,
                y: y + 1,
            },
            Cell {
                level: l,
                x: x + 1,
                y: y + 1,
            },
        ]
    }

    /// Parameter bounds (u0, v0, u1, v1).
    pub fn bounds(self) -> (f64, f64, f64, f64) {
        let w = self.width();
        let u0 = self.x as f64 * w;
        let v0 = self.y as f64 * w;
        (u0, v0, u0 + w, v0 + w)
    }

    /// Whether lattice point `k` lies on the closed boundary of this cell but is not a corner.
    #[cfg(test)]
    pub(crate) fn has_on_edge_interior(self, k: VertexKey) -> bool {
        let s = self.size();
        let o = self.origin();
        let inside_i = k.i >= o.i && k.i <= o.i + s;
        let inside_j = k.j >= o.j && k.j <= o.j + s;
        if !(inside_i && inside_j) {
            return false;
        }
        let on_vertical = k.i == o.i || k.i == o.i + s;
        let on_horizontal = k.j == o.j || k.j == o.j + s;
        (on_vertical && k.j != o.j && k.j != o.j + s)
            || (on_horizontal && k.i != o.i && k.i != o.i + s)
    }
}

/// A node of a [`Quadtree`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Node {
    /// The cell this node covers.
    pub cell: Cell,
    /// Index of the first of the four consecutive children, or 0 for a leaf (the root, index 0,
    /// is never a child).
    pub first_child: u32,
}

impl Node {
    /// Whether the node is a leaf.
    #[inline]
    pub fn is_leaf(&self) -> bool {
        self.first_child == 0
    }
}

/// The topology of an unrestricted quadtree over [0, 1]^2.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Quadtree {
    nodes: Vec<Node>,
}

impl Default for Quadtree {
    fn default() -> Self {
        Self::new()
    }
}

impl Quadtree {
    /// A tree with only the root, a leaf.
    pub fn new() -> Self {
        Quadtree {
            nodes: vec![Node {
                cell: Cell::ROOT,
                first_child: 0,
            }],
        }
    }

    /// Rebuilds a tree from its nodes, checking every invariant; `None` if any is broken.
    pub fn from_nodes(nodes: Vec<Node>) -> Option<Self> {
        if nodes.first()?.cell != Cell::ROOT {
            return None;
        }
        // Every non-root node must be reached exactly once, as a child of its parent.
        let mut reached = vec![false; nodes.len()];
        reached[0] = true;
        for n in &nodes {
            if n.is_leaf() {
                continue;
            }
            let f = n.first_child as usize;
            if n.cell.level >= MAX_DEPTH || f + 4 > nodes.len() {
                return None;
            }
            for (k, child) in n.cell.children().iter().enumerate() {
                if nodes[f + k].cell != *child || reached[f + k] {
                    return None;
                }
                reached[f + k] = true;
            }
        }
        reached.iter().all(|&r| r).then_some(Quadtree { nodes })
    }

    /// Builds a tree top-down in the *canonical node order*: nodes are visited depth-first from
    /// the root, the last child first (a stack), and a visited node that is split gets the next
    /// four indices for its children. `split(id, cell, tag)` decides for node `id` (covering
    /// `cell`, carrying the caller's `tag`) whether it is split, returning the children's tags in
    /// child order; it must not split a cell at [`MAX_DEPTH`] (panics, a caller bug).
    ///
    /// The node order is a function of the tree's shape alone, so one bit per node in node order
    /// ("is split") determines the whole tree: replaying `grow` with `split` reading bit `id`
    /// rebuilds it with identical indices (bit `id` is always read after node `id` exists).
    pub fn grow<T>(root: T, mut split: impl FnMut(u32, Cell, T) -> Option<[T; 4]>) -> Quadtree {
        let mut out = Quadtree::new();
        let mut work = vec![(root, 0u32)];
        while let Some((tag, id)) = work.pop() {
            let Some(children) = split(id, out.node(id).cell, tag) else {
                continue;
            };
            let first = out.split(id);
            for (q, c) in (0u32..).zip(children) {
                work.push((c, first + q));
            }
        }
        out
    }

    /// The same tree in the canonical node order of [`Quadtree::grow`]: the same cells split,
    /// nodes renumbered. Equal to `self` when `self` was grown.
    pub fn canonical(&self) -> Quadtree {
        Quadtree::grow(0u32, |_, _, old| {
            let f = self.node(old).first_child;
            (f != 0).then(|| [f, f + 1, f + 2, f + 3])
        })
    }

    /// The canonical tree's shape as one bit per node ("is split"), in canonical node order,
    /// least significant bit first, padded with zero bits to a whole byte: with the node count,
    /// the whole tree ([`Quadtree::from_split_bits`]).
    pub fn split_bits(&self) -> Vec<u8> {
        let c = self.canonical();
        let mut out = vec![0u8; c.nodes.len().div_ceil(8)];
        for (k, n) in c.nodes.iter().enumerate() {
            out[k / 8] |= u8::from(!n.is_leaf()) << (k % 8);
        }
        out
    }

    /// The canonical tree of `nodes` nodes whose split bits are `bits` ([`Quadtree::split_bits`]).
    /// `None` unless `bits` is exactly that encoding of a tree of depth at most [`MAX_DEPTH`]
    /// (length, node count, zero padding), so decoding never panics and accepts one form per tree.
    pub fn from_split_bits(nodes: usize, bits: &[u8]) -> Option<Quadtree> {
        if nodes % 4 != 1 || bits.len() != nodes.div_ceil(8) {
            return None;
        }
        let bit = |k: usize| bits[k / 8] >> (k % 8) & 1 == 1;
        if (nodes..bits.len() * 8).any(bit) {
            return None;
        }
        let mut malformed = false;
        let tree = Quadtree::grow((), |id, cell, ()| {
            let id = id as usize;
            if id >= nodes || malformed || !bit(id) {
                malformed |= id >= nodes;
                return None;
            }
            if cell.level >= MAX_DEPTH {
                malformed = true;
                return None;
            }
            Some([(); 4])
        });
        (!malformed && tree.nodes.len() == nodes).then_some(tree)
    }

    /// All nodes; node 0 is the root.
    pub fn nodes(&self) -> &[Node] {
        &self.nodes
    }

    /// Node `id`.
    pub fn node(&self, id: u32) -> &Node {
        &self.nodes[id as usize]
    }

    /// Splits leaf `id` into four children and returns the index of the first. Panics if `id` is
    /// not a leaf or is at [`MAX_DEPTH`]: callers bound the depth.
    pub fn split(&mut self, id: u32) -> u32 {
        let node = self.nodes[id as usize];
        assert!(node.is_leaf(), "split of an internal node");
        assert!(node.cell.level < MAX_DEPTH, "split beyond MAX_DEPTH");
        let first = self.nodes.len() as u32;
        for cell in node.cell.children() {
            self.nodes.push(Node {
                cell,
                first_child: 0,
            });
        }
        self.nodes[id as usize].first_child = first;
        first
    }

    /// Indices of the leaves in depth-first order (children in stored order).
    pub fn leaves(&self) -> Vec<u32> {
        let mut out = Vec::new();
        let mut stack = vec![0u32];
        while let Some(id) = stack.pop() {
            let n = self.nodes[id as usize];
            if n.is_leaf() {
                out.push(id);
            } else {
                for k in (0..4).rev() {
                    stack.push(n.first_child + k);
                }
            }
        }
        out
    }

    /// Number of leaves.
    pub fn leaf_count(&self) -> usize {
        // Each split turns one leaf into four.
        1 + 3 * (self.nodes.len() - 1) / 4
    }

    /// Depth of the deepest leaf.
    pub fn depth(&self) -> u32 {
        self.nodes.iter().map(|n| n.cell.level).max().unwrap_or(0)
    }

    /// Number of leaves at each depth, index = depth.
    pub fn depth_histogram(&self) -> Vec<usize> {
        let mut h = vec![0usize; self.depth() as usize + 1];
        for n in self.nodes.iter().filter(|n| n.is_leaf()) {
            h[n.cell.level as usize] += 1;
        }
        h
    }

    /// The leaf whose closed cell contains (u, v), clamped into [0, 1]^2. Points on a shared edge go
    /// to the cell on the upper side (the child with the larger index), except at u or v = 1.
    pub fn find_leaf(&self, u: f64, v: f64) -> u32 {
        let (i, j) = lattice_coords(u, v);
        let mut id = 0u32;
        loop {
            let n = self.nodes[id as usize];
            if n.is_leaf() {
                return id;
            }
            let c = n.cell.centre();
            let cx = u32::from(i >= c.i);
            let cy = u32::from(j >= c.j);
            id = n.first_child + cx + 2 * cy;
        }
    }

    /// Every vertex of every leaf (corners; T-vertices are corners of the smaller neighbours),
    /// sorted and unique.
    pub fn vertex_keys(&self) -> Vec<VertexKey> {
        let mut keys: Vec<VertexKey> = self
            .nodes
            .iter()
            .filter(|n| n.is_leaf())
            .flat_map(|n| n.cell.corners())
            .collect();
        keys.sort_unstable();
        keys.dedup();
        keys
    }

    /// Vertices that lie inside an edge of some leaf (not at its corners): the T-vertices, in
    /// the vertices' (row-major) order.
    ///
    /// Each leaf edge's interior is a run of the keys sorted along the edge's line (rows for
    /// horizontal edges, columns for vertical ones), found by binary search: O(n log n) in the
    /// leaves. Asking every leaf about every vertex took 37 s on a tree of depth 12 beside a
    /// single leaf (40,848 vertices, 30,689 leaves).
    pub fn t_vertices(&self) -> Vec<VertexKey> {
        let rows = self.vertex_keys();
        // The same keys column-major, each with its index in `rows`.
        let mut cols: Vec<(u32, u32, usize)> = rows
            .iter()
            .enumerate()
            .map(|(n, k)| (k.i, k.j, n))
            .collect();
        cols.sort_unstable();
        let mut t = vec![false; rows.len()];
        for c in self.nodes.iter().filter(|n| n.is_leaf()).map(|n| n.cell) {
            let (s, o) = (c.size(), c.origin());
            if s < 2 {
                continue;
            }
            for j in [o.j, o.j + s] {
                let lo = rows.partition_point(|&k| k <= VertexKey::new(o.i, j));
                let hi = rows.partition_point(|&k| k < VertexKey::new(o.i + s, j));
                t[lo..hi.max(lo)].iter_mut().for_each(|m| *m = true);
            }
            for i in [o.i, o.i + s] {
                let lo = cols.partition_point(|&(ci, cj, _)| (ci, cj) <= (i, o.j));
                let hi = cols.partition_point(|&(ci, cj, _)| (ci, cj) < (i, o.j + s));
                for &(_, _, n) in &cols[lo..hi.max(lo)] {
                    t[n] = true;
                }
            }
        }
        rows.into_iter()
            .zip(t)
            .filter_map(|(k, m)| m.then_some(k))
            .collect()
    }
}

/// Lattice coordinates of (u, v), clamped into the domain; NaN maps to 0.
#[inline]
pub(crate) fn lattice_coords(u: f64, v: f64) -> (u32, u32) {
    let f = |t: f64| {
        let x = (t * LATTICE as f64).floor();
        if x.is_nan() {
            0
        } else {
            x.clamp(0.0, LATTICE as f64) as u32
        }
    };
    (f(u), f(v))
}

/// A quadtree with one RGB radiosity sample at every vertex of every leaf.
#[derive(Debug, Clone, PartialEq)]
pub struct SampledQuadtree {
    /// The topology.
    pub tree: Quadtree,
    /// Vertex keys, sorted and unique: exactly `tree.vertex_keys()`.
    pub keys: Vec<VertexKey>,
    /// Linear RGB radiosity at `keys[k]`, finite and >= 0.
    pub values: Vec<Vec3>,
}

impl SampledQuadtree {
    /// Samples `tree` at its vertices with `f(u, v)`.
    pub fn from_fn(tree: Quadtree, mut f: impl FnMut(f64, f64) -> Vec3) -> Self {
        let keys = tree.vertex_keys();
        let values = keys.iter().map(|k| f(k.u(), k.v())).collect();
        SampledQuadtree { tree, keys, values }
    }

    /// The sample at `key`, if it is a vertex of the tree.
    pub fn sample(&self, key: VertexKey) -> Option<Vec3> {
        self.keys
            .binary_search(&key)
            .ok()
            .map(|idx| self.values[idx])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn split_and_find() {
        let mut t = Quadtree::new();
        let c = t.split(0);
        t.split(c + 3); // upper-right quadrant
        assert_eq!(t.leaf_count(), 7);
        assert_eq!(t.depth(), 2);
        assert_eq!(t.depth_histogram(), vec![0, 3, 4]);
        let leaf = t.find_leaf(0.9, 0.9);
        assert_eq!(
            t.node(leaf).cell,
            Cell {
                level: 2,
                x: 3,
                y: 3
            }
        );
        assert_eq!(t.node(t.find_leaf(0.1, 0.8)).cell.level, 1);
        // u = 1 and v = 1 stay in the last cell.
        assert_eq!(t.node(t.find_leaf(1.0, 1.0)).cell, t.node(leaf).cell);
        assert_eq!(t.node(t.find_leaf(f64::NAN, -3.0)).cell.x, 0);
    }

    /// The T-vertices found by range queries are exactly the vertices inside some leaf's edge,
    /// asked of every leaf, on trees refined at random (a regression: the all-pairs form took
    /// 37 s at depth 12).
    #[test]
    fn t_vertices_are_the_vertices_inside_a_leafs_edge() {
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut draw = |n: u64| {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 33) % n
        };
        let mut found = 0;
        for round in 0..40 {
            let mut t = Quadtree::new();
            for _ in 0..(round % 13) * 4 {
                let leaves: Vec<u32> = (0..t.nodes.len() as u32)
                    .filter(|&i| t.node(i).is_leaf() && t.node(i).cell.level < 9)
                    .collect();
                let pick = leaves[draw(leaves.len() as u64) as usize];
                t.split(pick);
            }
            let leaves: Vec<Cell> = t
                .nodes
                .iter()
                .filter(|n| n.is_leaf())
                .map(|n| n.cell)
                .collect();
            let want: Vec<VertexKey> = t
                .vertex_keys()
                .into_iter()
                .filter(|&k| leaves.iter().any(|c| c.has_on_edge_interior(k)))
                .collect();
            assert_eq!(t.t_vertices(), want, "round {round}");
            found += want.len();
        }
        assert!(
            found > 100,
            "the random trees had {found} T-vertices in all"
        );
    }

    #[test]
    fn t_vertices_of_one_refined_quadrant() {
        let mut t = Quadtree::new();
        let c = t.split(0);
        t.split(c + 3);
        // Level-1 grid has 9 vertices; refining the upper-right quadrant adds its centre and four
        // edge midpoints; the two on the shared edges with coarser leaves are T-vertices.
        assert_eq!(t.vertex_keys().len(), 14);
        let h = LATTICE / 2;
        let q = LATTICE / 4;
        let tv = t.t_vertices();
        assert_eq!(
            tv,
            vec![VertexKey::new(h, h + q), VertexKey::new(h + q, h)]
                .into_iter()
                .collect::<std::collections::BTreeSet<_>>()
                .into_iter()
                .collect::<Vec<_>>()
        );
    }

    #[test]
    fn from_nodes_checks_invariants() {
        let mut t = Quadtree::new();
        t.split(0);
        let nodes = t.nodes().to_vec();
        assert_eq!(Quadtree::from_nodes(nodes.clone()), Some(t));
        let mut bad = nodes.clone();
        bad[2].cell.x = 0;
        assert_eq!(Quadtree::from_nodes(bad), None);
        let mut bad = nodes;
        bad[0].first_child = 3;
        assert_eq!(Quadtree::from_nodes(bad), None);
    }

    /// A tree split at random leaves, in split order (not canonical).
    fn random_tree(rng: &mut crate::rng::Rng, splits: usize) -> Quadtree {
        let mut t = Quadtree::new();
        for _ in 0..splits {
            let leaves: Vec<u32> = (0..t.nodes.len() as u32)
                .filter(|&i| t.node(i).is_leaf() && t.node(i).cell.level < 6)
                .collect();
            t.split(leaves[rng.below(leaves.len() as u32) as usize]);
        }
        t
    }

    #[test]
    fn split_bits_rebuild_the_same_cells_in_canonical_order() {
        let mut rng = crate::rng::Rng::new(7);
        for case in 0..200 {
            let t = random_tree(&mut rng, case % 40);
            let c = t.canonical();
            let cells = |t: &Quadtree| {
                let mut v: Vec<(Cell, bool)> =
                    t.nodes.iter().map(|n| (n.cell, n.is_leaf())).collect();
                v.sort_by_key(|(c, l)| (c.level, c.x, c.y, *l));
                v
            };
            assert_eq!(cells(&c), cells(&t), "case {case}");
            assert_eq!(c.vertex_keys(), t.vertex_keys());
            assert_eq!(c.canonical(), c, "canonical order is a fixed point");
            let bits = t.split_bits();
            assert_eq!(Quadtree::from_split_bits(t.nodes.len(), &bits), Some(c));
        }
    }

    #[test]
    fn split_bits_refuse_every_other_form() {
        let mut t = Quadtree::new();
        t.split(0);
        let bits = t.split_bits();
        assert_eq!(bits, vec![1]);
        // A node count that is no quadtree's, or disagrees with the bits.
        assert_eq!(Quadtree::from_split_bits(4, &bits), None);
        assert_eq!(Quadtree::from_split_bits(1, &bits), None);
        assert_eq!(Quadtree::from_split_bits(9, &[1, 0]), None);
        // Nonzero padding, a byte too many or too few.
        assert_eq!(Quadtree::from_split_bits(5, &[1 | 1 << 6]), None);
        assert_eq!(Quadtree::from_split_bits(5, &[1, 0]), None);
        assert_eq!(Quadtree::from_split_bits(5, &[]), None);
        // Every node split: deeper than MAX_DEPTH before the count runs out.
        let n = 4 * (MAX_DEPTH as usize + 1) + 1;
        let all = vec![0xFFu8; n.div_ceil(8)];
        let mut all = all;
        let last = n.div_ceil(8) - 1;
        all[last] &= (1u16 << (n - 8 * last)).wrapping_sub(1) as u8;
        assert_eq!(Quadtree::from_split_bits(n, &all), None);
        assert_eq!(Quadtree::from_split_bits(5, &bits), Some(t));
    }
}
