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
//! - each (shooter, receiver) pair found is classified once: culled (no transfer possible,
//!   dropped), open (no polygon can intersect the convex hull of the two, so V = 1 without
//!   rays), or occluded (cast rays, testing only the pair's candidates). A candidate must
//!   overlap the hull's bounding box, cross both polygons' planes, not be separated from the
//!   hull by its own plane, and not lie outside a side face of the hull (planes through an edge
//!   of one polygon and a vertex of the other); the BVH query itself skips subtrees outside
//!   those faces. The classification is conservative and deterministic;
//! - pair tables are sparse (only pairs that are not culled) with an index per receiver
//!   ([`Transfer::shooters_of`]), so a shot, a gather and the tables themselves cost what a
//!   shooter or a point reaches, never the number of polygons in the scene; a gather visits
//!   the receiver's shooters in id order, the order the sums were always taken in.

mod receivers;
pub(crate) mod shape;

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
        let candidates: Vec<u32> =
            found.unwrap_or_else(|| (0..self.scene.polygons.len() as u32).collect());
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

    /// Class of the pair (shooter `s`, receiver polygon `r`), see [`PairClass`], and for an
    /// occluded pair the polygons (in index order) that may intersect the convex hull of the two.
    pub(crate) fn classify(&self, s: usize, r: usize) -> (PairClass, Vec<u32>) {
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
                    return (PairClass::Culled, Vec::new());
                }
                hull.push(pos);
            }
            _ => {
                if sg.polygon as usize == r {
                    return (PairClass::Culled, Vec::new());
                }
                let s0 = sg.outline.v[0];
                let tol = facing_tolerance(rv.iter().chain(sg.outline.verts()));
                if !rv.iter().any(|&p| sg.normal.dot(p - s0) > tol) {
                    return (PairClass::Culled, Vec::new());
                }
                if !sg
                    .outline
                    .verts()
                    .iter()
                    .any(|&p| rp.normal.dot(p - r0) > tol)
                {
                    return (PairClass::Culled, Vec::new());
                }
                hull.extend_from_slice(sg.outline.verts());
            }
        }
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

    /// [`Transfer::transfer`] in two factors: the transfer without occluders, and the visible
    /// fraction of the shooter (1 where no occluder can block; 0 or 1 for a spot, which casts
    /// one ray). `transfer` is their product. Used by refinement to find elements that a shadow
    /// boundary crosses. Requires [`Transfer::ensure_pairs`] for `s`.
    ///
    /// It casts only the shooter's first set, without the penumbra's extra passes: what the
    /// refinement compares across a leaf's points is then one coherent function of the
    /// shadow's geometry.
    pub(crate) fn shadowed(&self, s: usize, r: usize, u: f64, v: f64) -> (DVec3, f64) {
        self.shadowed_with(s, r, self.pair_of(s, r), u, v, true)
    }

    fn shadowed_with(
        &self,
        s: usize,
        r: usize,
        (class, cands): (PairClass, Candidates<'_>),
        u: f64,
        v: f64,
        coherent: bool,
    ) -> (DVec3, f64) {
        let cands: &[u32] = match &cands {
            Candidates::Table(l) => l,
            Candidates::Owned(v) => v,
        };
        if class == PairClass::Culled {
            return (DVec3::ZERO, 1.0);
        }
        let x = self.receiver(r, u, v);
        let open = self.unoccluded_at(s, x, self.scene.polygons[r].shading_normal(x));
        if open == DVec3::ZERO || class != PairClass::Occluded {
            return (open, 1.0);
        }
        let vis = match self.shooters[s].kind {
            ShooterKind::Spot { spot } => {
                self.rays.fetch_add(1, Ordering::Relaxed);
                let d = self.scene.spots[spot as usize].position - x;
                if cands.iter().any(|&q| self.bvh.hits(q as usize, x, d)) {
                    0.0
                } else {
                    1.0
                }
            }
            _ => self.visibility_weighted(s, r, cands, x, open.x, (None, coherent)),
        };
        (open, vis)
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

    /// The visible fraction of shooter `s` from point `x` of receiver `r` given the pair's
    /// occluder candidates `cands` and the shooter's unoccluded form factor `open` there: the
    /// form factor of the part of the shooter `x` sees ([`crate::visible`], exact) over
    /// `open`. Candidates that cannot meet the pyramid from `x` over the shooter are dropped
    /// first; with none left, visibility is 1. Where more than [`MAX_NEAR`] remain or the
    /// visible region's description would not fit, the fraction is estimated from shadow rays
    /// instead ([`Transfer::visible_fraction`], sampled as `how` says: a shape weighting the
    /// rays, and whether only the first set is cast), and counted in `ray_fallbacks`.
    pub(crate) fn visibility_weighted(
        &self,
        s: usize,
        r: usize,
        cands: &[u32],
        x: DVec3,
        open: f64,
        how: Sampling<'_>,
    ) -> f64 {
        let n = self.scene.polygons[r].shading_normal(x);
        visible::with_arena(|view| {
            let look = self.look(s, r, cands, x, view, how);
            look.fraction(view, x, n, open)
        })
    }

    /// What point `x` of receiver `r` sees of shooter `s` past the pair's candidates `cands`
    /// (see [`Transfer::visibility_weighted`]): nothing that may block, the exact region (left
    /// in `view`), or where that does not apply the visible fraction from shadow rays sampled
    /// as `how` says.
    pub(crate) fn look(
        &self,
        s: usize,
        r: usize,
        cands: &[u32],
        x: DVec3,
        view: &mut visible::View,
        how: Sampling<'_>,
    ) -> Look {
        let near = self.near_occluders(s, cands, x);
        if near.len == 0 && !near.many {
            return Look::Clear;
        }
        if !near.many {
            self.exact_queries.fetch_add(1, Ordering::Relaxed);
            let sg = &self.shooters[s];
            let polys = &self.scene.polygons;
            let occ = near.ids[..near.len]
                .iter()
                .map(|&q| polys[q as usize].vertices());
            match visible::see(view, x, sg.outline.verts(), sg.normal, occ, self.eps) {
                Sight::Complex => {}
                sight => return Look::Exact(sight),
            }
        }
        Look::Rays(self.visibility_by_rays(s, r, cands, x, &near, how))
    }

    /// The visible fraction of shooter `s` from `x` estimated from shadow rays (the exact
    /// query's fallback, counted), `near` being the pair's candidates that may block.
    pub(crate) fn visibility_by_rays(
        &self,
        s: usize,
        r: usize,
        cands: &[u32],
        x: DVec3,
        near: &Near,
        how: Sampling<'_>,
    ) -> f64 {
        self.ray_fallbacks.fetch_add(1, Ordering::Relaxed);
        let sg = &self.shooters[s];
        if sg.strata.len() <= FEW_RAYS {
            return self.visibility_unfiltered(s, r, cands, x, how);
        }
        self.visible_fraction(s, r, x, how, |y| {
            if near.many {
                self.bvh.occluded(x, y, r as u32, sg.polygon)
            } else {
                near.ids[..near.len]
                    .iter()
                    .any(|&q| self.bvh.hits(q as usize, x, y - x))
            }
        })
    }

    /// The candidates of a pair that may meet the pyramid from `x` over shooter `s`'s outline
    /// (at most [`MAX_NEAR`]; `many` when there are more).
    pub(crate) fn near_occluders(&self, s: usize, cands: &[u32], x: DVec3) -> Near {
        let sg = &self.shooters[s];
        let mut near = Near {
            ids: [0; MAX_NEAR],
            len: 0,
            many: false,
        };
        let sides = pyramid_sides(x, &sg.outline);
        let mut consider = |q: u32| {
            if near.many || !self.may_block(q, x, sg, &sides) {
                return;
            }
            if near.len < MAX_NEAR {
                near.ids[near.len] = q;
                near.len += 1;
            } else {
                near.many = true;
            }
        };
        if cands.len() <= LONG_CANDIDATE_LIST {
            cands.iter().for_each(|&q| consider(q));
        } else {
            // A long list (a large room): only polygons whose boxes meet the pyramid's box can
            // meet the pyramid; the BVH finds them without walking the whole list.
            let mut pts = [x; 9];
            pts[1..=sg.outline.len].copy_from_slice(sg.outline.verts());
            let b = Aabb::of(&pts[..=sg.outline.len]);
            // Pruned by the pyramid's side planes with may_block's own tolerances: a box
            // wholly outside one holds only polygons may_block rejects.
            let mut planes = [(DVec3::ZERO, DVec3::ZERO, 0.0); 8];
            for (k, pl) in planes.iter_mut().enumerate().take(sides.len) {
                *pl = (sides.n[k], x, sides.tol[k]);
            }
            self.bvh.for_each_in(&b, &planes[..sides.len], |q| {
                if cands.binary_search(&q).is_ok() {
                    consider(q);
                }
            });
        }
        near
    }

    /// [`Transfer::visibility_weighted`] for a shooter with few sample points: filtering the candidates
    /// per receiver point costs about as much as the rays it would save, so the rays test the
    /// pair's candidates directly (a short list) or go through the BVH (a long one). The answer
    /// is the same as with filtering: a polygon the filter drops cannot meet any of the rays, and
    /// one outside the pair's candidates cannot meet the hull that holds them; the weights are
    /// summed in the same order, so even the rounding is the same.
    fn visibility_unfiltered(
        &self,
        s: usize,
        r: usize,
        cands: &[u32],
        x: DVec3,
        how: Sampling<'_>,
    ) -> f64 {
        let sg = &self.shooters[s];
        self.visible_fraction(s, r, x, how, |y| {
            if cands.len() <= LONG_CANDIDATE_LIST {
                cands.iter().any(|&q| self.bvh.hits(q as usize, x, y - x))
            } else {
                self.bvh.occluded(x, y, r as u32, sg.polygon)
            }
        })
    }

    /// Fraction of shooter `s`'s light at point `x` that `blocked` lets through: over its ray
    /// targets for `x` ([`Transfer::targets`]), each weighted by its area element times the
    /// point-to-point kernel cos(x) cos(y) / r^2, the visible weight over the whole (a ratio
    /// estimator of the form-factor-weighted visibility); one pass, and for an emitter whose
    /// first pass is partly blocked [`PENUMBRA_PASSES`] in all, summed in a fixed order.
    /// Counts the rays cast.
    ///
    /// Why the kernel: the transfer is F x V, and F weights each part of the shooter by the
    /// kernel, so V must too. An area-weighted fraction counts a blocked part far from `x` or
    /// at a grazing angle as much as a visible part straight above it: on a floor beside a box
    /// under a ceiling light it gave 0.70 where the light's visible share is 0.82, and the
    /// solver lost 1.5 % of the light in a closed room.
    ///
    /// Only targets in front of the receiver's plane count: the form factor is that of the
    /// shooter clipped to the receiver's front half-space, so visibility must be the fraction
    /// of that same part; a point behind the receiver is not seen by it, and the pair's
    /// occluder candidates (which exclude polygons wholly behind the receiver) say nothing
    /// about rays to it. When no target is in front, the front part is a sliver the targets
    /// miss: it is taken as visible (documented bias, bounded by that sliver's small form
    /// factor).
    fn visible_fraction(
        &self,
        s: usize,
        r: usize,
        x: DVec3,
        (shape, coherent): Sampling<'_>,
        blocked: impl Fn(DVec3) -> bool,
    ) -> f64 {
        let n = self.scene.polygons[r].shading_normal(x);
        let ns = self.shooters[s].normal;
        let pass = |k: u64| {
            let (mut seen, mut total) = (0.0, 0.0);
            for (y, w, su, sv) in self.targets(s, k) {
                let w = w * kernel(x, n, y, ns) * shape::shape_weight(shape, su, sv);
                if w <= 0.0 {
                    continue;
                }
                total += w;
                if !blocked(y) {
                    seen += w;
                }
            }
            (seen, total)
        };
        let (mut seen, mut total) = pass(0);
        let mut passes = 1;
        let emitter = matches!(self.shooters[s].kind, ShooterKind::Emitter { .. });
        if emitter && !coherent && seen > 0.0 && seen < total {
            passes = PENUMBRA_PASSES;
            for k in 1..passes {
                let (a, b) = pass(k);
                seen += a;
                total += b;
            }
        }
        self.rays.fetch_add(
            passes * self.shooters[s].strata.len() as u64,
            Ordering::Relaxed,
        );
        if total > 0.0 {
            (seen / total).clamp(0.0, 1.0)
        } else {
            1.0
        }
    }

    /// Shooter `s`'s shadow-ray targets in pass `k`, with their area weights and unit-square
    /// positions on the shooter: its stratified set, as it is in pass 0, rotated toroidally
    /// in later passes by an offset seeded by (scene seed, shooter, pass). The same targets for
    /// every receiver point: visibility is a coherent function of the point, which the
    /// refinement can follow, and the same at any scale of the scene.
    pub(crate) fn targets(
        &self,
        s: usize,
        k: u64,
    ) -> impl Iterator<Item = (DVec3, f64, f64, f64)> + '_ {
        let sg = &self.shooters[s];
        let p = &self.scene.polygons[sg.polygon as usize];
        let (du, dv) = if k == 0 {
            (0.0, 0.0)
        } else {
            let mut rng = Rng::new(seed_of(&[self.scene.radiosity.seed, s as u64, k]));
            (rng.next_f64(), rng.next_f64())
        };
        let wrap = |a: f64| if a >= 1.0 { a - 1.0 } else { a };
        sg.strata.iter().map(move |&(su, sv)| {
            let (su, sv) = (wrap(su + du), wrap(sv + dv));
            let (y, w) = target(p, sg.bounds, su, sv);
            (y, w, su, sv)
        })
    }

    /// Whether polygon `q` may intersect the pyramid with apex `x` over the shooter's outline
    /// (conservative separating-plane test: the pyramid's side planes, the shooter's plane and
    /// q's own plane).
    fn may_block(&self, q: u32, x: DVec3, sg: &ShooterGeom, sides: &Sides) -> bool {
        let qp = &self.scene.polygons[q as usize];
        let qv = qp.vertices();
        for k in 0..sides.len {
            let n = sides.n[k];
            if qv.iter().all(|&p| n.dot(p - x) < -sides.tol[k]) {
                return false;
            }
        }
        let s0 = sg.outline.v[0];
        if qv.iter().all(|&p| sg.normal.dot(p - s0) <= self.eps) {
            return false;
        }
        let q0 = qv[0];
        let dx = qp.normal.dot(x - q0);
        let ds = sg.outline.verts().iter().map(|&p| qp.normal.dot(p - q0));
        let (lo, hi) = ds.fold((dx, dx), |(a, b), d| (a.min(d), b.max(d)));
        !(lo >= -self.eps || hi <= self.eps)
    }

    /// Total irradiance G at polygon `r`, (u, v) from every shooter with a non-zero total, in
    /// shooter id order: G = sum_s total_s * transfer(s). Radiosity is E + rho * G.
    ///
    /// Only the shooters whose pairs reach `r` are visited (a culled pair adds exactly zero),
    /// so a gather costs what the point can see. Every shooter with a non-zero total must have
    /// its pairs ([`Transfer::ensure_pairs`]) and the index must be sorted
    /// ([`Transfer::index_receivers`]).
    pub(crate) fn gather(&self, totals: &[DVec3], r: usize, u: f64, v: f64) -> DVec3 {
        debug_assert!(!self.unsorted, "index_receivers after new pairs");
        visible::with_pool(|pool| self.gather_in(totals, r, (u, v), pool))
    }

    /// [`Transfer::gather`] with the pool of views its shaped patches' regions are kept in
    /// between the two passes (found once per point and patch).
    fn gather_in(
        &self,
        totals: &[DVec3],
        r: usize,
        (u, v): (f64, f64),
        pool: &mut Vec<visible::View>,
    ) -> DVec3 {
        let mut g = DVec3::ZERO;
        let mut pending: Vec<shape::Pending> = Vec::new();
        let mut used = 0usize;
        for &(s, i) in &self.by_receiver[r] {
            let t = totals[s as usize];
            if t == DVec3::ZERO {
                continue;
            }
            match &self.shapes[s as usize] {
                None => g += t * self.transfer_at(s as usize, r, i as usize, u, v),
                Some(shape) => {
                    if pool.len() == used {
                        pool.push(visible::View::default());
                    }
                    let (uniform, error, f, look) = self.uniform_with_error(
                        s as usize,
                        r,
                        i as usize,
                        shape,
                        (u, v),
                        &mut pool[used],
                    );
                    g += t * uniform;
                    if error > 0.0 {
                        pending.push(shape::Pending {
                            s,
                            i,
                            uniform,
                            error,
                            f,
                            look,
                            slot: used as u32,
                        });
                        // A part seen keeps its region for the second pass.
                        used += usize::from(look == Look::Exact(Sight::Part));
                    }
                }
            }
        }
        // Second pass: the shaped patches whose uniform light may be off by more than the
        // tolerance of what this point receives are refined (see `shape`). What it receives
        // is first judged from the uniform light; where the corrections bring it below
        // [`LEVEL_DROP`] of that, they are judged again against the corrected level.
        let mut level = lum(g);
        let mut corrected = self.shaped_corrections(totals, r, (u, v), &pending, pool, level);
        for _ in 0..LEVEL_PASSES {
            let seen = lum(g + corrected);
            if seen >= LEVEL_DROP * level {
                break;
            }
            level = seen;
            corrected = self.shaped_corrections(totals, r, (u, v), &pending, pool, level);
        }
        g + corrected
    }

    /// The sum of the shaped corrections of the `pending` patches at the receiver point of
    /// polygon `r` at (u, v), each judged against `level`, the luminance of what the point
    /// receives (see [`Transfer::gather`]).
    fn shaped_corrections(
        &self,
        totals: &[DVec3],
        r: usize,
        (u, v): (f64, f64),
        pending: &[shape::Pending],
        pool: &[visible::View],
        level: f64,
    ) -> DVec3 {
        let mut g = DVec3::ZERO;
        for p in pending {
            let t = totals[p.s as usize];
            let lt = lum(t);
            if lt <= 0.0 {
                continue;
            }
            // Per unit of the patch's total: the error this point tolerates from it.
            let tau = self.shape_tau * level / lt;
            let a = shape::blend(p.error, tau);
            if a > 0.0 {
                let shape = self.shapes[p.s as usize]
                    .as_ref()
                    .expect("pending is shaped");
                let shaped = self.shaped_in_view(
                    p.s as usize,
                    r,
                    p.i as usize,
                    shape,
                    (u, v),
                    (p.f, shape::NODE_BUDGET * tau),
                    (p.look, &pool[p.slot as usize]),
                );
                g += a * t * (shaped - p.uniform);
            }
        }
        g
    }

    /// Shooters whose pairs reach receiver `r`, ascending, each with its entry in the
    /// shooter's table (see [`Transfer::index_receivers`]).
    pub(crate) fn shooters_of(&self, r: usize) -> &[(u32, u32)] {
        &self.by_receiver[r]
    }
}

/// A gather whose shaped corrections leave it below this share of the level they were judged
/// against judges them again against the corrected level: the uniform light over-states what
/// a point receives where a patch's bright part is hidden from it (a floor under a lamp 2 cm
/// below a ceiling: the ceiling's patches read 13 times the light the floor gets, so every
/// correction was held to a tolerance 13 times too loose and the floor read 1.37 of a path
/// tracer's light; judged again, 1.28).
const LEVEL_DROP: f64 = 0.5;

/// Most times a gather judges its corrections again (each pass at most halves the level).
const LEVEL_PASSES: usize = 3;

/// Luminance of linear RGB (Rec. 709 weights): the level refinement criteria compare with.
#[inline]
fn lum(c: DVec3) -> f64 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
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

/// Shooters with at most this many sample points skip the per-point candidate filter when
/// their visibility falls back to rays (see [`Transfer::visibility_unfiltered`]).
const FEW_RAYS: usize = 2;

/// What a receiver point sees of a polygon shooter ([`Transfer::look`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Look {
    /// No occluder may block it: all of it.
    Clear,
    /// The exact region (the pieces in the view it was built in; never `Complex`).
    Exact(Sight),
    /// Its visible fraction, from shadow rays (the exact query did not apply).
    Rays(f64),
}

impl Look {
    /// The visible fraction of a shooter whose unoccluded form factor at `x` (normal `n`) is
    /// `open`, `view` holding the region of an exact part.
    pub(crate) fn fraction(self, view: &visible::View, x: DVec3, n: DVec3, open: f64) -> f64 {
        match self {
            Look::Clear | Look::Exact(Sight::All) => 1.0,
            Look::Exact(Sight::Nothing) => 0.0,
            Look::Exact(_) if open <= 0.0 => 1.0,
            Look::Exact(_) => (view.form_factor(x, n, open) / open).clamp(0.0, 1.0),
            Look::Rays(f) => f,
        }
    }
}

/// Most occluders an exact visibility query takes ([`Transfer::visibility_weighted`]); beyond
/// them it falls back to shadow rays.
pub(crate) const MAX_NEAR: usize = 16;

/// The occluders that may meet the pyramid from a receiver point over a shooter.
pub(crate) struct Near {
    pub(crate) ids: [u32; MAX_NEAR],
    pub(crate) len: usize,
    /// More than [`MAX_NEAR`] (then `ids` is incomplete).
    pub(crate) many: bool,
}

/// Occluder lists longer than this are searched through the BVH per receiver point.
const LONG_CANDIDATE_LIST: usize = 24;

/// Inward normals of the side planes of the pyramid from an apex over a convex outline.
struct Sides {
    n: [DVec3; 8],
    tol: [f64; 8],
    len: usize,
}

fn pyramid_sides(x: DVec3, outline: &SmallPoly) -> Sides {
    let vs = outline.verts();
    let c = vs.iter().copied().sum::<DVec3>() / vs.len().max(1) as f64;
    let mut sides = Sides {
        n: [DVec3::ZERO; 8],
        tol: [0.0; 8],
        len: 0,
    };
    for i in 0..vs.len() {
        let a = vs[i] - x;
        let b = vs[(i + 1) % vs.len()] - x;
        let mut n = a.cross(b);
        let scale = a.length() * b.length();
        if n.length() <= 1e-12 * scale {
            continue; // apex on the edge's line: no usable plane
        }
        if n.dot(c - x) < 0.0 {
            n = -n;
        }
        sides.n[sides.len] = n;
        sides.tol[sides.len] = 1e-9 * n.length() * (a.length() + b.length());
        sides.len += 1;
    }
    sides
}

/// Side faces of the convex hull of two convex point sets `a` and `b` (a polygon and a polygon or
/// a point) that pass through an edge of one and a vertex of the other: planes (n, p0) with every
/// point of both sets on the side `n . (p - p0) >= -eps |n|`. Together with the two polygons' own
/// planes these are the faces of the hull (edge-edge faces are missed, which only makes the
/// occluder test that uses them more conservative, never wrong).
fn hull_faces(a: &[DVec3], b: &[DVec3], eps: f64) -> Vec<(DVec3, DVec3)> {
    let mut faces = Vec::new();
    let all: Vec<DVec3> = a.iter().chain(b).copied().collect();
    let mut try_plane = |e0: DVec3, e1: DVec3, v: DVec3| {
        let n = (e1 - e0).cross(v - e0);
        let len = n.length();
        if len.is_nan() || len <= 1e-12 * (e1 - e0).length() * (v - e0).length() {
            return; // degenerate: v on the edge's line
        }
        let tol = eps * len;
        let d = all.iter().map(|&p| n.dot(p - e0));
        let (lo, hi) = d.fold((0.0f64, 0.0f64), |(l, h), x| (l.min(x), h.max(x)));
        let n = if lo >= -tol {
            n
        } else if hi <= tol {
            -n
        } else {
            return;
        };
        // A face is found from several (edge, vertex) choices; keep one copy (same direction
        // and the new point on the kept plane) so queries test each face once.
        let dup = faces.iter().any(|(m, q): &(DVec3, DVec3)| {
            let ml = m.length();
            m.dot(n) >= (1.0 - 1e-12) * ml * len && m.dot(e0 - *q).abs() <= eps * ml
        });
        if !dup {
            faces.push((n, e0));
        }
    };
    for (p, q) in [(a, b), (b, a)] {
        if p.len() < 2 {
            continue;
        }
        for i in 0..p.len() {
            let (e0, e1) = (p[i], p[(i + 1) % p.len()]);
            if e0 == e1 {
                continue;
            }
            for &v in q {
                try_plane(e0, e1, v);
            }
        }
    }
    faces
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
