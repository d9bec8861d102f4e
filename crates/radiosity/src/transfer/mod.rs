//! Light transfer from one shooter to one receiver point: the single function both the
//! progressive solver and the radiosity oracle call, so that a sample stored by the solve and the
//! oracle's answer at the same point are the same computation, bit for bit.
//!
//! A shooter is a spot light (a point source), an emissive polygon shooting as a whole, or a fixed
//! sub-patch of a reflecting polygon (a quadtree cell at a small fixed depth, planar because the
//! polygon is planar; for a collapsed-quad triangle the cells at v = 1 degenerate to triangles).
//! Its transfer to a receiver point x with normal n is the irradiance x receives per unit of the
//! shooter's radiosity: F(x -> shooter) * V for polygons (exact Lambert form factor times the
//! visible fraction of `shadow_rays` stratified points for an emitter, four times as many in
//! its penumbra, of [`patch_rays`] (a quarter as many) for a reflecting patch), I(theta) cos /
//! r^2 * V for spots (one shadow ray, binary). A reflecting patch's light may be distributed
//! over it by a shape (`shape`), which a gather refines where the receiver sees it large.
//!
//! Invariants and why:
//! - visibility depends only on (receiver point, shooter): the shadow-ray targets of a shooter are
//!   a stratified set seeded by (scene seed, shooter id) (see [`shooter_strata`]) and its fixed
//!   rotations ([`Transfer::targets`]), never a thread or the order of shots;
//! - receiver points are the polygon's parametric points pulled inside the domain by
//!   [`EDGE_INSET`], so a point on an edge shared with a perpendicular wall sees that wall as the
//!   limit from inside the polygon does (the exact edge point would see it edge-on, F = 0);
//! - each shooter's receivers are found once ([`Transfer::ensure_pairs`]): every polygon with
//!   exact visibility, or the polygons its probe rays hit, their corner neighbours and the
//!   polygons near it with sampled visibility ([`Transfer::probe`], chosen by
//!   `radiosity.visibility`). A polygon not found receives nothing from that shooter; the
//!   rays go on until the light such polygons would get is estimated below a bound;
//! - each (shooter, receiver) pair found is classified once: culled (no transfer possible:
//!   one faces the other's back, or one candidate occluder meets every segment between them,
//!   as a wall does between a room and a shooter in the next; dropped), open (no polygon can
//!   intersect the convex hull of the two, so V = 1 without rays), or occluded (cast rays,
//!   testing only the pair's candidates). A candidate must overlap the hull's bounding box,
//!   cross both polygons' planes, not be separated from the hull by its own plane, and not lie
//!   outside a side face of the hull (planes through an edge of one polygon and a vertex of the
//!   other); the BVH query itself skips subtrees outside those faces. The classification is
//!   conservative and deterministic;
//! - pair tables are sparse (only pairs that are not culled) with an index per receiver
//!   ([`Transfer::shooters_of`]), so a shot, a gather and the tables themselves cost what a
//!   shooter or a point reaches, never the number of polygons in the scene; a gather visits
//!   the receiver's shooters in id order, the order the sums were always taken in.

mod gather;
mod receivers;
pub(crate) mod seen;
pub(crate) mod shape;
mod visibility;

use std::sync::atomic::{AtomicU64, Ordering};

use glam::DVec3;

use super::formfactor::{point_to_polygon, SmallPoly};
use super::visible::{self, Sight};
use base::quadtree::Cell;
use base::rng::{seed_of, Rng};
use receivers::corner_neighbours;
pub use receivers::{pair_table_bound, PAIR_BYTES};
pub(crate) use receivers::{sampled_visibility, Pairs};
use scene::bvh::{Aabb, Bvh};
use scene::{Polygon, Scene, Shape};
use shape::{shape_tolerance, PatchShape};
pub(crate) use visibility::Look;
use visibility::{blocks_shaft, hull_faces};

/// Receiver points are evaluated at (u, v) clamped into [EDGE_INSET, 1 - EDGE_INSET]^2.
pub const EDGE_INSET: f64 = 1e-6;

/// What a shooter is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ShooterKind {
    /// Spot light `spot` of the scene.
    Spot {
        /// Index into `Scene::spots`.
        spot: u32,
    },
    /// An emissive polygon shooting its emission as a whole.
    Emitter {
        /// Index into `Scene::polygons`.
        polygon: u32,
    },
    /// A fixed sub-patch (quadtree cell) of a reflecting polygon, shooting reflected light.
    Patch {
        /// Index into `Scene::polygons`.
        polygon: u32,
        /// The cell of the polygon's domain the patch covers.
        cell: Cell,
    },
}

/// Class of a (shooter, receiver polygon) pair.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum PairClass {
    /// No light can go from the shooter to any point of the receiver.
    Culled,
    /// No polygon can block any segment between them: visibility is 1.
    Open,
    /// Shadow rays decide.
    Occluded,
}

/// The fixed geometry of one shooter.
#[derive(Debug, Clone)]
pub(crate) struct ShooterGeom {
    /// What it is.
    pub kind: ShooterKind,
    /// Polygon index, or `u32::MAX` for a spot.
    pub polygon: u32,
    /// Parametric bounds (u0, v0, u1, v1) on its polygon (whole domain for an emitter).
    pub bounds: (f64, f64, f64, f64),
    /// Its outline (empty for a spot).
    pub outline: SmallPoly,
    /// Front normal (zero for a spot).
    pub normal: DVec3,
    /// Area (0 for a spot).
    pub area: f64,
    /// Its plane as the views of its visible part are built in (empty for a spot).
    pub plane: visible::ShooterPlane,
    /// Stratified positions of its shadow-ray targets in the unit square (empty for a spot),
    /// mapped onto `bounds` and rotated per receiver point ([`Transfer::targets`]).
    pub strata: Vec<(f64, f64)>,
}

/// `n` stratified (Latin hypercube) positions in the unit square, from a stream seeded by
/// (scene seed, shooter id) only: one per row and one per column of an n x n grid, jittered.
///
/// Every receiver point uses the same set, so visibility is a coherent function of the point
/// (it changes only where a target's shadow boundary is crossed): the refinement follows real
/// shadow edges, not per-point noise, and the result is the same at any scale. Its steps are
/// the price: with one set of 16, visibility moved in steps of 1/16 across a penumbra, which
/// lined up into bands. An emitter therefore casts [`PENUMBRA_PASSES`] sets where the first
/// is partly blocked, each rotated toroidally by an offset of its own (Cranley and Patterson
/// 1976; a rotated Latin hypercube is still stratified): steps of 1/64 there, at four times
/// the rays only where the visible fraction is between 0 and 1.
pub(crate) fn shooter_strata(n: usize, seed: u64, id: usize) -> Vec<(f64, f64)> {
    let mut rng = Rng::new(seed_of(&[seed, id as u64]));
    let mut perm: Vec<u32> = (0..n as u32).collect();
    for i in (1..n).rev() {
        let j = rng.below(i as u32 + 1) as usize;
        perm.swap(i, j);
    }
    perm.iter()
        .enumerate()
        .map(|(i, &pv)| {
            let su = (i as f64 + rng.next_f64()) / n as f64;
            let sv = (pv as f64 + rng.next_f64()) / n as f64;
            (su, sv)
        })
        .collect()
}

/// The point of polygon `p` at unit-square position (su, sv) of the cell `bounds`, with its
/// area weight (the area element there).
#[inline]
pub(crate) fn target(p: &Polygon, bounds: (f64, f64, f64, f64), su: f64, sv: f64) -> (DVec3, f64) {
    let (u0, v0, u1, v1) = bounds;
    let u = u0 + (u1 - u0) * su;
    let v = v0 + (v1 - v0) * sv;
    let w = match p.shape {
        // Collapsed quad: the area element is 2 A (1 - v).
        Shape::Triangle => 1.0 - v,
        Shape::Quad => p.area_element(u, v),
    };
    (p.point(u, v), w)
}

/// An emitter's visibility from a point in its penumbra (some of its rays blocked, some not)
/// is estimated from this many rotations of its sample set (see [`shooter_strata`]): direct
/// light, where shadows are sharp and seen, gets four times the rays where the visible
/// fraction is between 0 and 1.
pub(crate) const PENUMBRA_PASSES: u64 = 4;

/// How a visible fraction is sampled: the shape weighting the rays (a shaped patch's), and
/// whether only the shooter's first set is cast ([`Transfer::shadowed`]).
pub(crate) type Sampling<'s> = (Option<&'s PatchShape>, bool);

/// Divisor of the shadow-ray count for reflecting patches, see [`patch_rays`].
pub(crate) const PATCH_RAY_DIVISOR: usize = 4;

/// Shadow rays per receiver point for a reflecting patch when the scene asks for `shadow_rays`:
/// `max(1, shadow_rays / PATCH_RAY_DIVISOR)` (8 -> 2). Emitters keep the full count.
///
/// Why: after the direct pass almost every shooter is a patch (955 of 964 in the gallery), so the
/// final gather's cost is patch rays. A patch's light is indirect, weak and spread over many
/// shooters, so each patch's visibility needs few samples: the per-point error of one patch's
/// term is at most that term (V is in [0, 1] either way), and the terms of hundreds of patches
/// with independent sample sets average out. Hard shadows come from spots and emitters, which
/// keep `shadow_rays`. This is a coarser estimate of the same quantity, not a bias: every
/// sample set is stratified over the patch, and the same fixed set serves every receiver.
pub(crate) fn patch_rays(shadow_rays: usize) -> usize {
    (shadow_rays / PATCH_RAY_DIVISOR).max(1)
}

/// Shooter depth of a reflecting polygon: its patches have at most about `1/16` of the total scene
/// area (so a room of six walls gets four patches per wall),
/// never more than 16 per polygon (depth 2) and never deeper than `max_depth`.
pub fn patch_depth(area: f64, total_area: f64, max_depth: u32) -> u32 {
    let target = total_area / 16.0;
    let mut d = 0;
    while d < 2 && area / 4f64.powi(d as i32) > target {
        d += 1;
    }
    d.min(max_depth)
}

/// Builds every shooter of a scene in id order: spots, then emitters (polygon order), then the
/// patches of reflecting polygons (polygon order, cells row-major). `patch_base[p]` is the id of
/// polygon p's first patch (or `u32::MAX` if it does not reflect) and `patch_depth[p]` its depth.
pub(crate) fn build_shooters(scene: &Scene) -> (Vec<ShooterGeom>, Vec<u32>, Vec<u32>) {
    let mut out = Vec::new();
    let nrays = scene.radiosity.shadow_rays.max(1) as usize;
    let seed = scene.radiosity.seed;
    for (i, _) in scene.spots.iter().enumerate() {
        out.push(ShooterGeom {
            kind: ShooterKind::Spot { spot: i as u32 },
            polygon: u32::MAX,
            bounds: (0.0, 0.0, 1.0, 1.0),
            outline: SmallPoly::from_corners(&[]),
            normal: DVec3::ZERO,
            area: 0.0,
            plane: visible::ShooterPlane::of(&[], DVec3::ZERO),
            strata: Vec::new(),
        });
    }
    for (i, p) in scene.polygons.iter().enumerate() {
        if scene.material_of(i).is_emitter() {
            out.push(ShooterGeom {
                kind: ShooterKind::Emitter { polygon: i as u32 },
                polygon: i as u32,
                bounds: (0.0, 0.0, 1.0, 1.0),
                outline: SmallPoly::from_corners(p.vertices()),
                normal: p.normal,
                area: p.area,
                plane: visible::ShooterPlane::of(p.vertices(), p.normal),
                strata: shooter_strata(nrays, seed, out.len()),
            });
        }
    }
    let total_area: f64 = scene.polygons.iter().map(|p| p.area).sum();
    let mut base = vec![u32::MAX; scene.polygons.len()];
    let mut depth = vec![0u32; scene.polygons.len()];
    for (i, p) in scene.polygons.iter().enumerate() {
        if scene.material_of(i).reflectance.max_element() <= 0.0 {
            continue;
        }
        let d = patch_depth(p.area, total_area, scene.radiosity.max_depth);
        base[i] = out.len() as u32;
        depth[i] = d;
        let n = 1u32 << d;
        for y in 0..n {
            for x in 0..n {
                let cell = Cell { level: d, x, y };
                let (u0, v0, u1, v1) = cell.bounds();
                let outline = SmallPoly::from_corners(&cell_corners(p, cell));
                let plane = visible::ShooterPlane::of(outline.verts(), p.normal);
                let area = sub_area(p, cell);
                out.push(ShooterGeom {
                    kind: ShooterKind::Patch {
                        polygon: i as u32,
                        cell,
                    },
                    polygon: i as u32,
                    bounds: (u0, v0, u1, v1),
                    outline,
                    normal: p.normal,
                    area,
                    plane,
                    strata: shooter_strata(patch_rays(nrays), seed, out.len()),
                });
            }
        }
    }
    (out, base, depth)
}

/// The corners of cell `cell` of polygon `p`'s domain, in the order (0,0), (1,0), (1,1), (0,1)
/// (for a collapsed quad, the two at v = 1 coincide in its last row of cells).
#[inline]
pub(crate) fn cell_corners(p: &Polygon, cell: Cell) -> [DVec3; 4] {
    let (u0, v0, u1, v1) = cell.bounds();
    [
        p.point(u0, v0),
        p.point(u1, v0),
        p.point(u1, v1),
        p.point(u0, v1),
    ]
}

/// Area of a cell of a polygon's domain. The area element of a planar quad's bilinear map (and of
/// a collapsed quad) is linear in u and v, so the midpoint rule is exact.
pub(crate) fn sub_area(p: &Polygon, cell: Cell) -> f64 {
    let (u0, v0, u1, v1) = cell.bounds();
    p.area_element(0.5 * (u0 + u1), 0.5 * (v0 + v1)) * (u1 - u0) * (v1 - v0)
}

/// Everything a transfer needs: the scene, its BVH, the shooters and the pair classes.
pub(crate) struct Transfer<'a> {
    /// The scene.
    pub scene: &'a Scene,
    /// Ray-casting structure over the scene's polygons.
    pub bvh: Bvh,
    /// Shooters in id order.
    pub shooters: Vec<ShooterGeom>,
    /// Per shooter, its receivers with their classes and occluder candidates (computed when
    /// first needed).
    pub pairs: Vec<Option<Pairs>>,
    /// Plane-test tolerance, relative to the scene size.
    eps: f64,
    /// Shadow rays cast so far (a sum of integers: independent of scheduling).
    pub rays: AtomicU64,
    /// Visibility queries answered exactly (the visible region clipped, [`crate::visible`]),
    /// and those that fell back to shadow rays (more near occluders or pieces than the exact
    /// query's fixed buffers hold).
    pub exact_queries: AtomicU64,
    pub ray_fallbacks: AtomicU64,
    /// Whether [`Transfer::classify`] drops candidates outside a face of the receiver/shooter
    /// hull (always on; off only in the test that checks it changes no transfer).
    use_hull_faces: bool,
    /// Bytes of the pair tables built so far ([`Transfer::pair_bytes`]).
    pair_bytes: u64,
    /// Shooters whose probe rays could not bound the light they miss, given every polygon
    /// as a candidate receiver ([`receivers::MISSED_LIGHT`]).
    exact_fallbacks: u64,
    /// Sampled visibility: per patch shooter, the polygons its probe rays hit (computed when
    /// it or a patch beside it first needs its receivers; see [`Transfer::probe`]).
    probe_cache: Vec<Option<Vec<(u32, u32)>>>,
    /// Per polygon, its patch shooters' ids, ascending.
    patches_of: Vec<Vec<u32>>,
    /// Whether receivers are found by probe rays ([`Visibility::Sampled`](scene::Visibility::Sampled), or `Auto` on a
    /// scene past [`EXACT_PAIRS_LIMIT`]).
    sampled: bool,
    /// Sampled visibility only: per polygon, the polygons that share a corner with it.
    neighbours: Vec<Vec<u32>>,
    /// Per receiver polygon, the shooters whose pairs reach it with the pair's entry in the
    /// shooter's table; ascending once [`Transfer::index_receivers`] has run after the last
    /// new pair table.
    by_receiver: Vec<Vec<(u32, u32)>>,
    /// Whether `by_receiver` has entries appended since it was last sorted.
    unsorted: bool,
    /// Length of a probe ray: four times the scene's diagonal.
    reach: f64,
    /// The segment parameter a probe or escape ray's hits start from ([`Scene::ray_t0`]), so
    /// that a ground plane a million times a room's size does not blind the room's rays to
    /// everything within a metre of their origins.
    ray_t0: f64,
    /// The sealed polygons ([`scene::seal`]; none in most scenes): a polygon wholly covered
    /// by faces lying over it closer than rays resolve exchanges light only with those that
    /// face it.
    sealed: std::sync::Arc<scene::seal::Seals>,
    /// Per shooter, the shape of its light over the patch (`None`: uniform; see [`shape`]).
    shapes: Vec<Option<PatchShape>>,
    /// A gather refines a patch's node while spread x F x min(1, size / distance) passes
    /// this ([`shape`]).
    shape_tau: f64,
}

impl<'a> Transfer<'a> {
    /// Builds the BVH and the shooters of `scene`.
    pub(crate) fn new(scene: &'a Scene) -> Self {
        let (shooters, _, _) = build_shooters(scene);
        let n = shooters.len();
        let mut patches_of = vec![Vec::new(); scene.polygons.len()];
        for (t, sg) in shooters.iter().enumerate() {
            if let ShooterKind::Patch { polygon, .. } = sg.kind {
                patches_of[polygon as usize].push(t as u32);
            }
        }
        let eps = plane_tolerance(scene);
        let sampled = sampled_visibility(scene, shooters.len() as u64);
        Transfer {
            scene,
            bvh: Bvh::build(&scene.polygons),
            pairs: vec![None; shooters.len()],
            shooters,
            eps,
            rays: AtomicU64::new(0),
            exact_queries: AtomicU64::new(0),
            ray_fallbacks: AtomicU64::new(0),
            use_hull_faces: true,
            pair_bytes: 0,
            exact_fallbacks: 0,
            probe_cache: vec![None; n],
            patches_of,
            sampled,
            neighbours: if sampled {
                corner_neighbours(scene)
            } else {
                Vec::new()
            },
            by_receiver: vec![Vec::new(); scene.polygons.len()],
            unsorted: false,
            reach: {
                let (lo, hi) = scene.bounds();
                4.0 * (hi - lo).length().max(1e-300)
            },
            ray_t0: scene.ray_t0(),
            sealed: scene.seals(),
            shapes: vec![None; n],
            shape_tau: shape_tolerance(scene.radiosity.tolerance),
        }
    }

    /// The shape of shooter `s`'s light (`None`: uniform).
    pub(crate) fn shape(&self, s: usize) -> Option<&PatchShape> {
        self.shapes[s].as_ref()
    }

    /// Scales the tolerance the shaped corrections are judged against (a test compares a
    /// gather with one whose every correction is opened to its cells).
    #[cfg(test)]
    pub(crate) fn scale_shape_tolerance(&mut self, k: f64) {
        self.shape_tau *= k;
    }

    /// Sets the shape of shooter `s`'s light; gathers from then on use it.
    pub(crate) fn set_shape(&mut self, s: usize, shape: Option<PatchShape>) {
        self.shapes[s] = shape;
    }

    /// Sets the shape of shooter `s`'s light and returns the one it replaces.
    pub(crate) fn replace_shape(
        &mut self,
        s: usize,
        shape: Option<PatchShape>,
    ) -> Option<PatchShape> {
        std::mem::replace(&mut self.shapes[s], shape)
    }

    /// Whether receivers are found by probe rays (see [`Visibility`](scene::Visibility)).
    #[cfg(test)]
    pub(crate) fn sampled(&self) -> bool {
        self.sampled
    }

    /// Bytes of the pair tables built so far: per shooter with a table, a receiver id and a
    /// candidate range (two `u32`) per receiver it reaches, plus its candidate lists, and the
    /// per-receiver index (two `u32` per pair).
    pub(crate) fn pair_bytes(&self) -> u64 {
        self.pair_bytes
    }

    /// Shooters given every polygon as a candidate because their probe rays could not bound
    /// the light they would miss (sampled visibility; 0 with exact).
    pub(crate) fn exact_fallbacks(&self) -> u64 {
        self.exact_fallbacks
    }

    /// Computes the receivers of shooter `s` and their classes, if not done yet: every polygon
    /// (exact visibility) or the polygons its probe rays hit and their neighbours (sampled),
    /// classified in parallel; culled pairs are dropped.
    pub(crate) fn ensure_pairs(&mut self, s: usize) {
        if self.pairs[s].is_some() {
            return;
        }
        use rayon::prelude::*;
        let found = if self.sampled {
            let siblings = self.sibling_hits(s);
            let found = self.probe(s, &siblings);
            if found.is_none() {
                self.exact_fallbacks += 1;
            }
            found
        } else {
            None
        };
        let this = &*self;
        let own = self.shooters[s].polygon;
        let candidates: Vec<u32> = if self.sealed.is_sealed(own) {
            self.sealed.partners(own).to_vec()
        } else {
            found.unwrap_or_else(|| (0..self.scene.polygons.len() as u32).collect())
        };
        let per: Vec<(PairClass, Vec<u32>)> = candidates
            .par_iter()
            .map(|&r| this.classify(s, r as usize))
            .collect();
        let mut pairs = Pairs::default();
        for (&r, (c, cands)) in candidates.iter().zip(per) {
            if c == PairClass::Culled {
                continue;
            }
            pairs.recv.push(r);
            pairs
                .range
                .push((pairs.cands.len() as u32, cands.len() as u32));
            pairs.cands.extend(cands);
        }
        for (i, &r) in pairs.recv.iter().enumerate() {
            let list = &mut self.by_receiver[r as usize];
            if list.last().is_some_and(|&(l, _)| l as usize > s) {
                self.unsorted = true;
            }
            list.push((s as u32, i as u32));
        }
        self.pair_bytes += pairs.bytes() + 8 * pairs.recv.len() as u64;
        self.pairs[s] = Some(pairs);
    }

    /// Sampled visibility, a reflecting patch `s`: the polygons the probe rays of `s` and of
    /// the patches around it on its polygon (the 3 x 3 cells of its level centred on its own)
    /// hit, ascending. Each patch's hits are probed once and kept (counted in
    /// [`Transfer::pair_bytes`]). Empty for a light.
    fn sibling_hits(&mut self, s: usize) -> Vec<(u32, u32)> {
        use rayon::prelude::*;
        let ShooterKind::Patch { polygon, cell } = self.shooters[s].kind else {
            return Vec::new();
        };
        let around: Vec<usize> = self.patches_of[polygon as usize]
            .iter()
            .map(|&t| t as usize)
            .filter(|&t| match self.shooters[t].kind {
                ShooterKind::Patch { cell: c, .. } => {
                    c.level == cell.level && c.x.abs_diff(cell.x) <= 1 && c.y.abs_diff(cell.y) <= 1
                }
                _ => false,
            })
            .collect();
        let missing: Vec<usize> = around
            .iter()
            .copied()
            .filter(|&t| self.probe_cache[t].is_none())
            .collect();
        let this = &*self;
        let probed: Vec<Vec<(u32, u32)>> = missing
            .par_iter()
            .map(|&t| this.probe_hits(t).unwrap_or_default())
            .collect();
        for (t, h) in missing.into_iter().zip(probed) {
            self.pair_bytes += 8 * h.len() as u64;
            self.probe_cache[t] = Some(h);
        }
        let mut hits: Vec<(u32, u32)> = around
            .iter()
            .flat_map(|&t| self.probe_cache[t].iter().flatten().copied())
            .collect();
        hits.sort_unstable();
        let mut merged: Vec<(u32, u32)> = Vec::with_capacity(hits.len());
        for (h, c) in hits {
            match merged.last_mut() {
                Some((last, n)) if *last == h => *n += c,
                _ => merged.push((h, c)),
            }
        }
        merged
    }

    /// Sorts the per-receiver index after pair tables were added out of shooter order; the
    /// gathers need it ascending (they sum in shooter id order).
    pub(crate) fn index_receivers(&mut self) {
        if self.unsorted {
            use rayon::prelude::*;
            self.by_receiver
                .par_iter_mut()
                .for_each(|l| l.sort_unstable());
            self.unsorted = false;
        }
    }

    /// The receiver `r`'s corners followed by shooter `s`'s (its outline, or a spot's
    /// position): the points whose convex hull holds every segment between the two; `None`
    /// when one faces the other's back (or the shooter is the receiver), so that no light can
    /// pass between them.
    fn facing_hull(&self, s: usize, r: usize) -> Option<Vec<DVec3>> {
        let eps = self.eps;
        let sg = &self.shooters[s];
        let rp = &self.scene.polygons[r];
        let rv = rp.vertices();
        let r0 = rv[0];
        let above_r = |p: DVec3| rp.normal.dot(p - r0) > eps;
        let mut hull: Vec<DVec3> = rv.to_vec();
        match sg.kind {
            ShooterKind::Spot { spot } => {
                let pos = self.scene.spots[spot as usize].position;
                // A spot within the scene tolerance of the receiver's plane counts as on it
                // (unlike an emitter, see [`facing_tolerance`]): its 1/d^2 peak on the wall is a
                // disc ~d wide, whose reflected power is negligible, but the solver would
                // integrate the peak sample over a whole leaf: a spot 1e-9 from a wall made the
                // room 1000 times too bright. Its light on that wall is dropped instead.
                if !above_r(pos) {
                    return None;
                }
                hull.push(pos);
            }
            _ => {
                if sg.polygon as usize == r {
                    return None;
                }
                let s0 = sg.outline.v[0];
                let tol = facing_tolerance(rv.iter().chain(sg.outline.verts()));
                if !rv.iter().any(|&p| sg.normal.dot(p - s0) > tol) {
                    return None;
                }
                if !sg
                    .outline
                    .verts()
                    .iter()
                    .any(|&p| rp.normal.dot(p - r0) > tol)
                {
                    return None;
                }
                hull.extend_from_slice(sg.outline.verts());
            }
        }
        Some(hull)
    }

    /// The sealed polygons ([`scene::seal`]).
    pub(crate) fn seals(&self) -> &scene::seal::Seals {
        &self.sealed
    }

    /// Class of the pair (shooter `s`, receiver polygon `r`), see [`PairClass`], and for an
    /// occluded pair the polygons (in index order) that may intersect the convex hull of the two.
    pub(crate) fn classify(&self, s: usize, r: usize) -> (PairClass, Vec<u32>) {
        let eps = self.eps;
        let sg = &self.shooters[s];
        let rp = &self.scene.polygons[r];
        let rv = rp.vertices();
        let above_r = |p: DVec3| rp.normal.dot(p - rv[0]) > eps;
        if !self.sealed.may_exchange(sg.polygon, r as u32) {
            return (PairClass::Culled, Vec::new());
        }
        let Some(hull) = self.facing_hull(s, r) else {
            return (PairClass::Culled, Vec::new());
        };
        let b = Aabb::of(&hull);
        let b = Aabb {
            lo: b.lo - DVec3::splat(eps),
            hi: b.hi + DVec3::splat(eps),
        };
        let faces = if self.use_hull_faces {
            hull_faces(rv, &hull[rv.len()..], eps)
        } else {
            Vec::new()
        };
        // The same half-spaces the tests below apply per polygon (hull faces, strictly outside
        // by more than eps), so pruning BVH nodes by them drops only polygons those tests drop.
        let planes: Vec<(DVec3, DVec3, f64)> = faces
            .iter()
            .map(|(n, p0)| (*n, *p0, eps * n.length()))
            .collect();
        let mut cands = Vec::new();
        self.bvh.for_each_in(&b, &planes, |q| {
            if q as usize == r || q == sg.polygon {
                return;
            }
            let qp = &self.scene.polygons[q as usize];
            let qv = qp.vertices();
            // Entirely behind or on the receiver's plane: segments leave the receiver forwards.
            if !qv.iter().any(|&p| above_r(p)) {
                return;
            }
            if sg.polygon != u32::MAX {
                let s0 = sg.outline.v[0];
                if !qv.iter().any(|&p| sg.normal.dot(p - s0) > eps) {
                    return;
                }
            }
            if separated_by_plane(qp.normal, qv[0], &hull, eps) {
                return;
            }
            // Entirely outside a face of the convex hull of receiver and shooter: no segment
            // between them (both inside the hull) can meet q.
            if faces
                .iter()
                .any(|(n, p0)| qv.iter().all(|&p| n.dot(p - *p0) < -eps * n.length()))
            {
                return;
            }
            cands.push(q);
        });
        cands.sort_unstable();
        // One occluder across every segment between the two: nothing can pass (a wall
        // between a room and a shooter in the next one).
        let (rs, ss) = hull.split_at(rv.len());
        let polys = &self.scene.polygons;
        if cands.iter().any(|&q| {
            blocks_shaft(
                polys[q as usize].vertices(),
                polys[q as usize].normal,
                (rs, ss),
                eps,
            )
        }) {
            return (PairClass::Culled, Vec::new());
        }
        if cands.is_empty() {
            (PairClass::Open, cands)
        } else {
            (PairClass::Occluded, cands)
        }
    }

    /// The receiver point and normal of polygon `r` at (u, v) (pulled inside by [`EDGE_INSET`]).
    #[inline]
    pub(crate) fn receiver(&self, r: usize, u: f64, v: f64) -> DVec3 {
        let p = &self.scene.polygons[r];
        let u = u.clamp(EDGE_INSET, 1.0 - EDGE_INSET);
        let v = v.clamp(EDGE_INSET, 1.0 - EDGE_INSET);
        p.point(u, v)
    }

    /// Irradiance at the receiver point of polygon `r` at (u, v) per unit radiosity of shooter `s`
    /// (per unit intensity scale for a spot). Requires [`Transfer::ensure_pairs`] for `s`.
    #[cfg(test)]
    pub(crate) fn transfer(&self, s: usize, r: usize, u: f64, v: f64) -> DVec3 {
        self.transfer_with(s, r, self.pair_of(s, r), u, v)
    }

    /// The class and occluder candidates of pair (s, r): from the table if built, classified
    /// now otherwise.
    fn pair_of(&self, s: usize, r: usize) -> (PairClass, Candidates<'_>) {
        match &self.pairs[s] {
            Some(p) => match p.find(r) {
                Some(i) => {
                    let (c, l) = p.at(i);
                    (c, Candidates::Table(l))
                }
                None => (PairClass::Culled, Candidates::Table(&[])),
            },
            None => {
                let (c, l) = self.classify(s, r);
                (c, Candidates::Owned(l))
            }
        }
    }

    /// The entry of receiver polygon `r` in shooter `s`'s pair table (`None`: culled, or no
    /// table built for `s`).
    pub(crate) fn pair_entry(&self, s: usize, r: usize) -> Option<usize> {
        self.pairs[s].as_ref().and_then(|p| p.find(r))
    }

    /// [`Transfer::transfer`] given the pair's entry `i` in shooter `s`'s table (as the
    /// per-receiver index and the shots hold it), without looking it up.
    pub(crate) fn transfer_at(&self, s: usize, r: usize, i: usize, u: f64, v: f64) -> DVec3 {
        let p = self.pairs[s].as_ref().expect("the pair's table exists");
        let (c, l) = p.at(i);
        self.transfer_with(s, r, (c, Candidates::Table(l)), u, v)
    }

    fn transfer_with(
        &self,
        s: usize,
        r: usize,
        pair: (PairClass, Candidates<'_>),
        u: f64,
        v: f64,
    ) -> DVec3 {
        let (open, vis) = self.shadowed_with(s, r, pair, u, v, false);
        match self.shooters[s].kind {
            // A spot's visibility is 0 or 1: the unoccluded transfer or nothing.
            ShooterKind::Spot { .. } => {
                if vis > 0.0 {
                    open
                } else {
                    DVec3::ZERO
                }
            }
            _ => DVec3::splat(open.x * vis),
        }
    }

    /// What shooter `s` sends to polygon `r` at (u, v) with nothing in between: irradiance
    /// per unit radiosity (per unit intensity scale for a spot), 0 where either faces away or
    /// outside a spot's cone. No pair table needed.
    pub(crate) fn unoccluded(&self, s: usize, r: usize, u: f64, v: f64) -> DVec3 {
        let x = self.receiver(r, u, v);
        self.unoccluded_at(s, x, self.scene.polygons[r].shading_normal(x))
    }

    /// [`Transfer::unoccluded`] at point `x` with normal `n`.
    fn unoccluded_at(&self, s: usize, x: DVec3, n: DVec3) -> DVec3 {
        let sg = &self.shooters[s];
        match sg.kind {
            ShooterKind::Spot { spot } => {
                let spot = &self.scene.spots[spot as usize];
                let d = spot.position - x;
                let r2 = d.length_squared();
                if r2 <= 0.0 {
                    return DVec3::ZERO;
                }
                let dist = r2.sqrt();
                let cos = n.dot(d) / dist;
                if cos <= 0.0 {
                    return DVec3::ZERO;
                }
                spot.intensity_towards(-d / dist) * (cos / r2)
            }
            _ => DVec3::splat(point_to_polygon(x, n, &sg.outline, sg.normal).max(0.0)),
        }
    }

    /// Shooters whose pairs reach receiver `r`, ascending, each with its entry in the
    /// shooter's table (see [`Transfer::index_receivers`]).
    pub(crate) fn shooters_of(&self, r: usize) -> &[(u32, u32)] {
        &self.by_receiver[r]
    }
}

/// A pair's occluder candidates: borrowed from its table, or classified for this call.
enum Candidates<'t> {
    Table(&'t [u32]),
    Owned(Vec<u32>),
}

/// The point-to-point kernel cos(x) cos(y) / r^2 between receiver point `x` (normal `n`) and
/// shooter point `y` (normal `ny`), 0 where either faces away.
#[inline]
pub(crate) fn kernel(x: DVec3, n: DVec3, y: DVec3, ny: DVec3) -> f64 {
    let d = y - x;
    let r2 = d.length_squared();
    let (cx, cy) = (n.dot(d), -ny.dot(d));
    if cx <= 0.0 || cy <= 0.0 || r2 <= 0.0 {
        return 0.0;
    }
    cx * cy / (r2 * r2)
}

/// The solver's plane tolerance: 1e-9 of the diagonal of the scene's core (its bounds without
/// backdrops, [`Scene::core_diagonal`]: a 1e6-wide ground plane would make it 2 mm). Points
/// closer than this to a plane count as on it (occluder pruning; a spot this close to a
/// receiver's plane lights nothing on it).
pub(crate) fn plane_tolerance(scene: &Scene) -> f64 {
    1e-9 * scene.core_diagonal().max(1e-300)
}

/// The tolerance of the tests that decide whether an emitting polygon and a receiver face each
/// other at all, for a pair with the corners `pts`: 1e-12 times their largest coordinate. A
/// signed distance between points of magnitude m carries a rounding error of a few ulps of m
/// (~1e-16 m; the loader makes every polygon planar to rounding), so this decides only what
/// rounding cannot, at any scale and however close an emitter is to a wall it faces. An
/// emitter's irradiance is bounded (by its radiosity), so a receiver however close gets a
/// finite, correctly integrated share.
///
/// The scene-relative plane tolerance (1e-9 of the scene's diagonal) is right for pruning
/// occluder candidates, where a wider margin only keeps more candidates; as a facing test it
/// culled an emitter 1e-9 in front of a wall, and the wall facing it showed 0.34 where it
/// receives at least rho E = 2.1 (`scenes/hard/light-touching.toml`).
fn facing_tolerance<'p>(pts: impl Iterator<Item = &'p DVec3>) -> f64 {
    1e-12
        * pts
            .map(|p| p.abs().max_element())
            .fold(f64::MIN_POSITIVE, f64::max)
}

/// Whether all `pts` lie on one closed side of the plane (n, p0), within `eps`.
fn separated_by_plane(n: DVec3, p0: DVec3, pts: &[DVec3], eps: f64) -> bool {
    let all_front = pts.iter().all(|&p| n.dot(p - p0) >= -eps);
    let all_back = pts.iter().all(|&p| n.dot(p - p0) <= eps);
    all_front || all_back
}

/// Power of a spot light summed over channels: 2 pi I (1 - cos^(f+1) alpha) / (f + 1).
pub(crate) fn spot_power(s: &scene::SpotLight) -> f64 {
    let p = spot_power3(s);
    p.x + p.y + p.z
}

/// A spot's power per channel (W): its intensity times the solid-angle integral of its
/// `cos^falloff` profile over the cone; 0 if that is not finite.
pub(crate) fn spot_power3(s: &scene::SpotLight) -> DVec3 {
    let f = s.falloff;
    let ca = s.half_angle.cos().max(0.0);
    let p = 2.0 * std::f64::consts::PI * (1.0 - ca.powf(f + 1.0)) / (f + 1.0);
    let out = p * s.intensity;
    if out.is_finite() {
        out
    } else {
        DVec3::ZERO
    }
}

#[cfg(test)]
mod tests;
