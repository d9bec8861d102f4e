//! What the solve holds per polygon: its quadtree, the vertices with their irradiance G, the
//! coarse receiver points of the indirect pass, and the leaves with the patch each lies in; and
//! where each polygon's patches are among the shooters.

use std::ops::Range;

use glam::DVec3;

use super::centre_rule;
use crate::transfer::{build_shooters, sub_area};
use base::quadtree::{Cell, Quadtree, VertexKey};
use scene::Scene;

/// Which light of a polygon an integral is of.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Light {
    /// G at the fine vertices: the direct pass's or the last full gather's (Simpson's rule on
    /// the leaves the refinement tested, the trapezoid rule on the others).
    Fine,
    /// G at the coarse receivers from the shots since (trapezoid rule on the coarse cells).
    Coarse,
    /// G at the fine vertices from the concentrated shots since (trapezoid rule).
    Concentrated,
}

/// One leaf (or coarse cell), with what the unshot estimate needs.
#[derive(Debug, Clone, Copy)]
pub(super) struct Leaf {
    /// Its corners, as indices into the polygon's keys (or coarse keys).
    corners: [u32; 4],
    /// World-space area.
    area: f64,
    /// The patch shooter it lies in (`u32::MAX` in a polygon that does not reflect).
    patch: u32,
    /// Its cell of the polygon's domain, and its node in the tree.
    cell: Cell,
    node: u32,
}

/// Per-polygon solve state.
pub(super) struct Poly {
    pub(super) tree: Quadtree,
    /// The tree's vertices, sorted, and G at each.
    pub(super) keys: Vec<VertexKey>,
    pub(super) g: Vec<DVec3>,
    /// The tree's leaves.
    leaves: Vec<Leaf>,
    /// Coarse receiver points of the indirect pass, their G since the last full gather, and the
    /// cells between them.
    pub(super) ckeys: Vec<VertexKey>,
    pub(super) cg: Vec<DVec3>,
    cleaves: Vec<Leaf>,
    /// The spacing of the coarse receivers in the scene's units (the longest side of a coarse
    /// cell): light that a shooter concentrates on less than this goes to the fine vertices
    /// instead (`ng`; see [`crate::transfer::Transfer::concentrated`]).
    pub(super) coarse_spacing: f64,
    /// G at the fine vertices from the shots concentrated on this polygon since the last full
    /// gather.
    pub(super) ng: Vec<DVec3>,
    /// Reflectance.
    pub(super) rho: DVec3,
    /// Leaves the last refinement pass judged and kept, sorted by cell, with G at their five
    /// test points (centre, then the midpoints of the edges at v0, u1, v1, u0): with the
    /// corners, the nine points of Simpson's rule on the leaf.
    pub(super) tests: Vec<(Cell, [DVec3; 5])>,
    /// Leaves no refinement generation judged whose light varies steeply across them, sorted
    /// by cell, with G at their centre (`refine`'s ramps): with the corners, the centre rule
    /// of their integral.
    pub(super) centres: Vec<(Cell, DVec3)>,
}

/// Where each polygon's reflecting patches are among the shooters (see [`build_shooters`]):
/// `2^depth x 2^depth` patches, row-major, from the polygon's first patch id on.
pub(super) struct PatchLayout {
    /// Per polygon: the id of its first patch, `u32::MAX` if it does not reflect.
    first: Vec<u32>,
    /// Per polygon: its patch depth.
    pub(super) depth: Vec<u32>,
}

impl PatchLayout {
    /// The patches of `scene`'s polygons.
    pub(super) fn of(scene: &Scene) -> Self {
        let (_, first, depth) = build_shooters(scene);
        PatchLayout { first, depth }
    }

    /// Patch shooter ids of polygon `r` (empty for one that does not reflect).
    pub(super) fn ids(&self, r: usize) -> Range<usize> {
        match self.first(r) {
            None => 0..0,
            Some(b) => b..b + (1usize << (2 * self.depth[r])),
        }
    }

    /// Id of polygon `r`'s first patch, if it reflects.
    fn first(&self, r: usize) -> Option<usize> {
        (self.first[r] != u32::MAX).then_some(self.first[r] as usize)
    }

    /// The patch of polygon `r` that `cell` lies in (`u32::MAX` if `r` does not reflect).
    pub(super) fn patch_at(&self, r: usize, cell: Cell) -> u32 {
        if self.first[r] == u32::MAX {
            return u32::MAX;
        }
        let d = self.depth[r];
        let sh = cell.level.saturating_sub(d);
        let n = 1u32 << d;
        self.first[r] + (cell.y >> sh) * n + (cell.x >> sh)
    }
}

impl Poly {
    /// Polygon `i` at the start of a solve: its tree uniform to `max(min_depth, patch depth)`
    /// (at most `max_depth`, so a shooter patch is a union of leaves), its coarse receivers the
    /// vertices of the uniform grid one level below its patch depth, G zero everywhere.
    pub(super) fn new(scene: &Scene, i: usize, patches: &PatchLayout) -> Poly {
        let st = &scene.radiosity;
        let patch_depth = patches.depth[i];
        let tree = uniform_tree(st.min_depth.max(patch_depth).min(st.max_depth));
        let keys = tree.vertex_keys();
        let coarse_depth = (patch_depth + 1).min(st.max_depth.max(patch_depth));
        let coarse = uniform_tree(coarse_depth);
        let ckeys = coarse.vertex_keys();
        let vs = scene.polygons[i].vertices();
        let longest = (0..vs.len())
            .map(|k| (vs[(k + 1) % vs.len()] - vs[k]).length())
            .fold(0.0f64, f64::max);
        let cleaves = leaves_of(scene, i, &coarse, &ckeys, patches);
        let leaves = leaves_of(scene, i, &tree, &keys, patches);
        Poly {
            g: vec![DVec3::ZERO; keys.len()],
            ng: vec![DVec3::ZERO; keys.len()],
            coarse_spacing: longest / (1u32 << coarse_depth) as f64,
            leaves,
            tree,
            keys,
            cg: vec![DVec3::ZERO; ckeys.len()],
            ckeys,
            cleaves,
            rho: scene.material_of(i).reflectance,
            tests: Vec::new(),
            centres: Vec::new(),
        }
    }

    /// Whether the polygon reflects light (only then do its points receive).
    pub(super) fn reflects(&self) -> bool {
        self.rho.max_element() > 0.0
    }

    /// Recomputes the leaves of polygon `i` after its tree changed.
    pub(super) fn rebuild_leaves(&mut self, scene: &Scene, i: usize, patches: &PatchLayout) {
        self.leaves = leaves_of(scene, i, &self.tree, &self.keys, patches);
    }

    /// The integral over each patch of polygon `r` of the light `which` says into `out`,
    /// indexed by shooter id. Nothing for a polygon that does not reflect.
    pub(super) fn integrate(
        &self,
        r: usize,
        patches: &PatchLayout,
        which: Light,
        out: &mut [DVec3],
    ) {
        let Some(first) = patches.first(r) else {
            return;
        };
        let (leaves, g) = match which {
            Light::Coarse => (&self.cleaves, &self.cg),
            Light::Fine => (&self.leaves, &self.g),
            Light::Concentrated => (&self.leaves, &self.ng),
        };
        let last = leaves
            .iter()
            .map(|l| l.patch as usize)
            .max()
            .unwrap_or(first);
        out[first..=last].iter_mut().for_each(|x| *x = DVec3::ZERO);
        // The test points hold the light of the last gather only.
        let points = if which == Light::Fine {
            (&self.tests[..], &self.centres[..])
        } else {
            (&[][..], &[][..])
        };
        for l in leaves {
            out[l.patch as usize] += leaf_integral(l, g, points);
        }
    }

    /// The integral of G over every node of the tree: Simpson's rule (or the trapezoid rule) on
    /// each leaf, the sum of its children's for an interior node. Indexed by node id.
    pub(super) fn node_integrals(&self) -> Vec<DVec3> {
        let nodes = self.tree.nodes();
        let mut out = vec![DVec3::ZERO; nodes.len()];
        for l in &self.leaves {
            out[l.node as usize] = leaf_integral(l, &self.g, (&self.tests, &self.centres));
        }
        // Children come after their parent in node order.
        for i in (0..nodes.len()).rev() {
            let n = nodes[i];
            if !n.is_leaf() {
                let f = n.first_child as usize;
                out[i] = out[f] + out[f + 1] + out[f + 2] + out[f + 3];
            }
        }
        out
    }

    /// The cells of its leaves.
    pub(super) fn leaf_cells(&self) -> impl Iterator<Item = Cell> + '_ {
        self.leaves.iter().map(|l| l.cell)
    }

    /// The integral of G over the polygon, Simpson's rule on the leaves the refinement kept.
    pub(super) fn integral(&self) -> DVec3 {
        self.leaves
            .iter()
            .map(|l| leaf_integral(l, &self.g, (&self.tests, &self.centres)))
            .sum()
    }

    /// Forgets the light shot to the coarse receivers and the concentrated light (a full
    /// gather has superseded them).
    pub(super) fn clear_coarse(&mut self) {
        self.cg.iter_mut().for_each(|g| *g = DVec3::ZERO);
        self.ng.clear();
        self.ng.resize(self.keys.len(), DVec3::ZERO);
    }
}

/// G inside leaves, each list sorted by cell: at the five test points ([`Poly::tests`]) and at
/// the centre ([`Poly::centres`]).
type InnerPoints<'a> = (&'a [(Cell, [DVec3; 5])], &'a [(Cell, DVec3)]);

/// The integral over leaf `l` of the values `g` at its corners: Simpson's rule (corners 1/36,
/// edge midpoints 4/36, centre 16/36 of the area) when `tests` holds G at its test points; the
/// centre rule (corners 1/12, centre 2/3) when `centres` holds G at its centre; the trapezoid
/// rule otherwise. Simpson's rule is exact for a biquadratic light, the centre rule for a
/// quadratic one (Simpson's rule along a ramp that varies in one direction); the trapezoid
/// rule misses a bump's curvature: under a lamp the light is concave at its top, and the
/// trapezoid rule put 1-3 % less reflected light into the patches than there is.
fn leaf_integral(l: &Leaf, g: &[DVec3], (tests, centres): InnerPoints<'_>) -> DVec3 {
    let corners = l.corners.iter().map(|&c| g[c as usize]).sum::<DVec3>();
    if let Some(t) = at_cell(tests, l.cell) {
        let mids = t[1] + t[2] + t[3] + t[4];
        return l.area * (corners + 4.0 * mids + 16.0 * t[0]) / 36.0;
    }
    if let Some(&centre) = at_cell(centres, l.cell) {
        return centre_rule(l.area, corners, centre);
    }
    l.area * 0.25 * corners
}

/// The value kept for `cell` in `list` (sorted by [`cell_order`]), if any.
pub(super) fn at_cell<T>(list: &[(Cell, T)], cell: Cell) -> Option<&T> {
    let key = cell_order(cell);
    list.binary_search_by(|(c, _)| cell_order(*c).cmp(&key))
        .ok()
        .map(|i| &list[i].1)
}

/// The order `Poly::tests` is sorted in.
pub(super) fn cell_order(c: Cell) -> (u32, u32, u32) {
    (c.level, c.y, c.x)
}

/// A quadtree split uniformly to `depth`.
fn uniform_tree(depth: u32) -> Quadtree {
    let mut tree = Quadtree::new();
    let mut frontier = vec![0u32];
    for _ in 0..depth {
        let mut next = Vec::new();
        for id in frontier {
            let f = tree.split(id);
            next.extend(f..f + 4);
        }
        frontier = next;
    }
    tree
}

/// The leaves of `tree` on polygon `i`, their corners indexed in `keys`.
fn leaves_of(
    scene: &Scene,
    i: usize,
    tree: &Quadtree,
    keys: &[VertexKey],
    patches: &PatchLayout,
) -> Vec<Leaf> {
    let poly = &scene.polygons[i];
    let idx = |k: VertexKey| keys.binary_search(&k).map_or(0, |x| x as u32);
    tree.leaves()
        .into_iter()
        .map(|id| {
            let cell = tree.node(id).cell;
            Leaf {
                corners: cell.corners().map(idx),
                area: sub_area(poly, cell),
                patch: patches.patch_at(i, cell),
                cell,
                node: id,
            }
        })
        .collect()
}
