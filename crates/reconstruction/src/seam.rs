//! Seams: one C1 function across the borders of coplanar neighbours of one material, and one
//! C0 function across gentle folds ([`MAX_FOLD_DEGREES`]; `force_folds`).
//!
//! Each polygon's estimate sees only its own samples, so at its border the slope across is
//! one-sided and the two neighbours of a shared edge disagree: a kink at every polygon border of
//! a flat surface, as large as Gouraud's. A [`Seams`] lists the shared sides the scene's
//! adjacency found between coplanar polygons of equal material, and the reconstruction then:
//!
//! 1. **puts the same points on both sides**: every border vertex of one side becomes a vertex of
//!    the other (a *seam point*; the other polygon's leaves along its border are split down to it,
//!    as at a T-vertex inside a polygon), so both edges are cut at the same places;
//! 2. **gives every seam point one set of data**, computed once in world terms and handed to each
//!    polygon in its own (u, v) units. The value is the mean of the polygons' samples there (they
//!    differ by the solver's visibility noise only). The slope along the seam is the mean of the
//!    polygons' (each estimated from the seam's own points). The slope across is the estimator's
//!    rule applied to the two one-sided slopes, one from each polygon, which is the centred
//!    estimate an undivided surface would have had there (Hyman's filter keeps it monotone at a
//!    shadow edge lying on the seam). At a point where more than two polygons meet (a corner of
//!    a tiling) the world gradients are averaged. The twist is converted and averaged between
//!    polygons whose parameter axes are parallel or perpendicular in the plane (grids of
//!    rectangles, the common case), and zero where a filter limited the slope across;
//! 3. leaves everything else to refinement: a seam point is data the polygon's tree must have
//!    as a vertex, like an original sample.
//!
//! **Why the result is C1 across the seam.** Both edges are cut at the same points and carry the
//! same value and along-edge slope there, so their edge cubics are the same curve. The slope
//! across an edge is the cubic Hermite interpolant of the cross derivative and the twist at the
//! edge's ends; with the same world data at both ends and cross axes perpendicular to the seam,
//! both polygons' cross slopes are the same cubic in world units. Where a cross axis is tilted
//! from perpendicular by less than [`MAX_CROSS_TILT`] the data still agree at every seam point,
//! and between them the slope across differs by the twists' disagreement only; beyond it (the
//! hypotenuse of a triangle) the side is joined in value and along-edge slope only, C0, as a
//! gentle fold is.
//!
//! Only sides whose lattices line up are joined: the shared segment's ends are lattice points of
//! both sides and one side's parameter is a power of two times the other's, so every seam point
//! is a lattice point of both (always true for whole shared edges). A seam point that would need
//! more than the lattice's 2^16 intervals is dropped (the curves then agree to that depth's
//! cubic only). Other T-junctions are counted in [`Seams::unjoined`] and left as they are.

use std::collections::{BTreeMap, HashMap, HashSet};

use glam::DVec3;

use super::estimate::{fritsch_butland, hyman, limited};
use super::hermite::{HermiteData, PatchPoly};
use super::Estimator;
use base::quadtree::{SampledQuadtree, VertexKey, LATTICE};
use scene::adjacency::{side_endpoints, Adjacency, Junction, SharedEdge, Side};
use scene::contact::LineKind;
use scene::{Material, Polygon};

/// A shared side lies along a step when its middle is within this share of the step's length
/// of it: the loader snaps corners to a cut line within `scene::contact::SNAP` of the cut
/// polygon's size, and a piece's side along a step is never shorter than that.
const STEP_TOL: f64 = 2e-4;

/// A shared side joined by the reconstruction, in lattice units.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Link {
    a: Side,
    b: Side,
    /// Lattice indices along `a` of the shared segment's ends (increasing).
    ka: [i64; 2],
    /// Lattice indices along `b` of the same ends (in `a`'s order).
    kb: [i64; 2],
    /// Joined in value and slope along the edge only (C0), not across: a gentle fold (a crease
    /// of at most [`MAX_FOLD_DEGREES`]) or a side whose cross axis is slanted.
    c0: bool,
}

/// The seams a reconstruction joins, and the geometry it needs to convert derivatives.
#[derive(Debug, Clone, Default)]
pub struct Seams {
    links: Vec<Link>,
    /// Every polygon, indexed like the scene (empty without links): its parameter map converts
    /// derivatives.
    geometry: Vec<Polygon>,
    unjoined: usize,
    standing: usize,
    folds: usize,
    slants: usize,
}

impl Seams {
    /// No seams: every polygon reconstructed from its own samples alone.
    pub fn none() -> Seams {
        Seams::default()
    }

    /// The seams of a scene: every shared edge between coplanar polygons of equal material whose
    /// lattices line up ([`Adjacency::continuous`]), joined C1 (C0 where a cross axis is
    /// slanted), and the gentle folds between polygons of equal material (creases of at most
    /// [`MAX_FOLD_DEGREES`]), joined C0.
    pub fn of(polygons: &[Polygon], materials: &[Material], adjacency: &Adjacency) -> Seams {
        Seams::apart_along(polygons, materials, adjacency, &[])
    }

    /// The seams of a loaded scene: [`Seams::of`] its polygons, left apart along the lines the
    /// loader cut them along because the light steps there (`scene::contact`: a polygon
    /// standing on or passing through a receiver, or lying close over it as a lamp under a
    /// ceiling). The pieces on either side of such a line share whole edges, coplanar and of
    /// one material, and nothing else tells them from a tiling of a flat wall; joined, the
    /// seam's mean would draw the lamp's outline half lit from both sides.
    pub fn of_scene(scene: &scene::Scene) -> Seams {
        let steps: Vec<(DVec3, DVec3)> = scene
            .contacts
            .lines
            .iter()
            .filter(|l| l.kind != LineKind::Junction)
            .map(|l| (l.a, l.b))
            .collect();
        let adjacency = scene.adjacency();
        Seams::apart_along(&scene.polygons, &scene.materials, &adjacency, &steps)
    }

    /// [`Seams::of`], leaving apart every shared side that lies along one of `steps` (segments
    /// across which the light steps), counted with [`Seams::standing`].
    pub fn apart_along(
        polygons: &[Polygon],
        materials: &[Material],
        adjacency: &Adjacency,
        steps: &[(DVec3, DVec3)],
    ) -> Seams {
        let mut links = Vec::new();
        let mut unjoined = 0;
        let mut standing = 0;
        let mut folds = 0;
        let mut slants = 0;
        let stands = adjacency.standing();
        let steps = StepIndex::new(steps);
        for (e, &stands) in adjacency.edges.iter().zip(&stands) {
            let fold = is_fold(e, polygons, materials);
            if !fold && !Adjacency::continuous(e, polygons, materials) {
                continue;
            }
            if stands || on_step(e, polygons, &steps) {
                standing += 1;
                continue;
            }
            let shape =
                |side: Side, range| conditioned(&polygons[side.polygon as usize], side.side, range);
            let (sa, sb) = (shape(e.a, e.a_range), shape(e.b, e.b_range));
            if sa == Shape::Degenerate || sb == Shape::Degenerate {
                unjoined += 1;
                continue;
            }
            // A slanted cross axis cannot carry the slope across from one polygon to the other
            // (module docs): such a side is joined in value only, like a fold.
            let slanted = !fold && (sa == Shape::Slanted || sb == Shape::Slanted);
            match link(e) {
                Some(l) => {
                    folds += usize::from(fold);
                    slants += usize::from(slanted);
                    links.push(Link {
                        c0: fold || slanted,
                        ..l
                    });
                }
                None => unjoined += 1,
            }
        }
        let geometry = if links.is_empty() {
            Vec::new()
        } else {
            polygons.to_vec()
        };
        Seams {
            links,
            geometry,
            unjoined,
            standing,
            folds,
            slants,
        }
    }

    /// Joined shared sides that are gentle folds (joined in value only, [`MAX_FOLD_DEGREES`]).
    pub fn folds(&self) -> usize {
        self.folds
    }

    /// Joined coplanar sides whose cross axis is slanted (the hypotenuse of a triangle), joined
    /// in value only.
    pub fn slanted(&self) -> usize {
        self.slants
    }

    /// Continuous shared sides left unjoined because the light steps across them: another
    /// polygon stands on them at an angle (a wall on the line where two floor polygons meet), or
    /// they lie along a step the loader cut along ([`Seams::of_scene`]).
    pub fn standing(&self) -> usize {
        self.standing
    }

    /// Number of joined shared sides.
    pub fn joined(&self) -> usize {
        self.links.len()
    }

    /// Continuous shared sides left unjoined because their lattices do not line up.
    pub fn unjoined(&self) -> usize {
        self.unjoined
    }

    /// Whether there is nothing to join.
    pub fn is_empty(&self) -> bool {
        self.links.is_empty()
    }

    /// [`Error::Inconsistent`] (naming `what`, the thing being built) unless the seams fit `count` polygons:
    /// seams made for another scene.
    pub(crate) fn check_fits(&self, count: usize, what: &str) -> base::error::Result<()> {
        if self.fits(count) {
            Ok(())
        } else {
            Err(base::error::Error::Inconsistent(format!(
                "{what}: seams built for another scene than these {count} polygons"
            )))
        }
    }

    /// Whether the seams refer only to polygons below `count`.
    pub(crate) fn fits(&self, count: usize) -> bool {
        self.links.is_empty()
            || (self.geometry.len() == count
                && self
                    .links
                    .iter()
                    .all(|l| (l.a.polygon as usize) < count && (l.b.polygon as usize) < count))
    }
}

/// Largest |cos| between a polygon's cross axis and the seam at a seam's end (30 degrees from
/// perpendicular): the slope across is converted between the two polygons through these axes.
pub const MAX_CROSS_TILT: f64 = 0.5;

/// Smallest length of the cross axis relative to the side's own length (a 100:1 strip): below
/// it the one-sided slope across is taken over a sliver and the conversion divides by its
/// height.
pub const MIN_CROSS_RATIO: f64 = 1e-2;

/// How well a polygon's side carries a seam ([`conditioned`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Shape {
    /// The cross axis is within [`MAX_CROSS_TILT`] of perpendicular: joined C1.
    Square,
    /// The cross axis is slanted beyond it (most triangles' sides): joined C0.
    Slanted,
    /// A sliver or needle (cross axis under [`MIN_CROSS_RATIO`] of the side, or at an angle
    /// to it whose sine is under that ratio, or a side of length 0): left apart.
    Degenerate,
}

/// The steps in a uniform grid of cells about as wide as a step is long, each listed in the
/// cells of points along it half a cell apart: the steps near a point are in the few cells
/// around it. A large model has tens of thousands of contact lines and millions of shared
/// edges; testing every edge against every line made loading a 580,000-polygon building take
/// 160 s in this one loop.
pub(crate) struct StepIndex<'s> {
    steps: &'s [(DVec3, DVec3)],
    /// The cells' side.
    cell: f64,
    /// The longest step's length.
    longest: f64,
    grid: HashMap<[i64; 3], Vec<u32>>,
}

impl<'s> StepIndex<'s> {
    pub(crate) fn new(steps: &'s [(DVec3, DVec3)]) -> StepIndex<'s> {
        let lengths: Vec<f64> = steps.iter().map(|&(p, q)| p.distance(q)).collect();
        let longest = lengths.iter().copied().fold(0.0, f64::max);
        let mean = lengths.iter().sum::<f64>() / lengths.len().max(1) as f64;
        let cell = if mean.is_finite() && mean > 0.0 {
            mean
        } else {
            1.0
        };
        let mut grid: HashMap<[i64; 3], Vec<u32>> = HashMap::new();
        for (i, (&(p, q), &len)) in steps.iter().zip(&lengths).enumerate() {
            let n = (2.0 * len / cell).ceil().clamp(1.0, 1e6) as usize;
            let mut last = None;
            for k in 0..=n {
                let key = Self::key(p + (q - p) * (k as f64 / n as f64), cell);
                if last != Some(key) {
                    grid.entry(key).or_default().push(i as u32);
                    last = Some(key);
                }
            }
        }
        StepIndex {
            steps,
            cell,
            longest,
            grid,
        }
    }

    fn key(x: DVec3, cell: f64) -> [i64; 3] {
        (x / cell).floor().as_i64vec3().to_array()
    }

    /// Whether any step passes `test`, of those that may pass within `reach` of `x` (each
    /// step tested at most once; every step when the cells around `x` would outnumber them).
    pub(crate) fn any(
        &self,
        x: DVec3,
        reach: f64,
        mut test: impl FnMut(&(DVec3, DVec3)) -> bool,
    ) -> bool {
        // A step within `reach` of x has a listed point within reach + a quarter cell of it.
        let r = reach + 0.25 * self.cell;
        let (lo, hi) = (Self::key(x - r, self.cell), Self::key(x + r, self.cell));
        let cells: i64 = (0..3).map(|k| hi[k] - lo[k] + 1).product();
        if !reach.is_finite() || cells > self.steps.len() as i64 {
            return self.steps.iter().any(test);
        }
        let mut seen: Vec<u32> = Vec::new();
        for i in lo[0]..=hi[0] {
            for j in lo[1]..=hi[1] {
                for k in lo[2]..=hi[2] {
                    if let Some(l) = self.grid.get(&[i, j, k]) {
                        seen.extend_from_slice(l);
                    }
                }
            }
        }
        seen.sort_unstable();
        seen.dedup();
        seen.iter().any(|&s| test(&self.steps[s as usize]))
    }
}

/// Whether the shared segment of `e` lies along one of `steps`: its middle within a small
/// share of the step's length of the step (the loader's cut put the pieces' corners on the
/// line, to rounding and its snap), and its direction along the step's.
fn on_step(e: &SharedEdge, polygons: &[Polygon], steps: &StepIndex<'_>) -> bool {
    if steps.steps.is_empty() {
        return false;
    }
    let (s0, s1) = side_endpoints(&polygons[e.a.polygon as usize], e.a.side);
    let (a, b) = (s0 + (s1 - s0) * e.a_range[0], s0 + (s1 - s0) * e.a_range[1]);
    let (mid, dir) = (0.5 * (a + b), (b - a).normalize_or_zero());
    let reach = STEP_TOL * steps.longest.max((b - a).length());
    steps.any(mid, reach, |&(p, q)| {
        let d = q - p;
        let len = d.length();
        let t = ((mid - p).dot(d) / (len * len).max(f64::MIN_POSITIVE)).clamp(0.0, 1.0);
        let tol = STEP_TOL * len.max((b - a).length());
        (p + d * t).distance(mid) <= tol
            && dir.cross(d / len.max(f64::MIN_POSITIVE)).length() <= 1e-3
    })
}

/// How well `side` of `p` carries a seam over `range`, the worst of its two ends and its
/// middle. A triangle's apex (v = 1, where its cross axis vanishes by construction) is not
/// tested: it is never a seam point.
fn conditioned(p: &Polygon, side: u8, range: [f64; 2]) -> Shape {
    let mut worst = Shape::Square;
    for s in [range[0], 0.5 * (range[0] + range[1]), range[1]] {
        let (u, v) = scene::adjacency::side_uv(side, s);
        if p.shape == scene::Shape::Triangle && v >= 1.0 {
            continue;
        }
        let (xu, xv) = p.tangents(u, v);
        let (along, cross) = if side.is_multiple_of(2) {
            (xu, xv)
        } else {
            (xv, xu)
        };
        let (la, lc) = (along.length(), cross.length());
        // A sliver (short cross axis) or a needle (cross axis nearly along the side).
        if !(la > 0.0 && lc >= MIN_CROSS_RATIO * la)
            || along.cross(cross).length() < MIN_CROSS_RATIO * la * lc
        {
            return Shape::Degenerate;
        }
        if along.dot(cross).abs() > MAX_CROSS_TILT * la * lc {
            worst = Shape::Slanted;
        }
    }
    worst
}

/// Largest angle between two polygons' normals, in degrees, at which a crease between polygons
/// of one material is joined in value ([`Seams::folds`]): a tessellated curve or a shallow ramp,
/// where the light turns with the surface but does not step. Sharper creases (a floor meeting a
/// wall) keep their step: the two sides see different hemispheres, and the light there does
/// step. A fold whose two sides' samples disagree (beyond [`SAMPLE_AGREEMENT`]) stays apart too.
pub const MAX_FOLD_DEGREES: f64 = 30.0;

/// Whether `e` is a gentle fold between polygons of one material.
fn is_fold(e: &SharedEdge, polygons: &[Polygon], materials: &[Material]) -> bool {
    let Junction::Crease { degrees } = e.junction else {
        return false;
    };
    let ma = &materials[polygons[e.a.polygon as usize].material as usize];
    let mb = &materials[polygons[e.b.polygon as usize].material as usize];
    degrees <= MAX_FOLD_DEGREES && ma.reflectance == mb.reflectance && ma.emission == mb.emission
}

/// The link of shared edge `e`, if its two lattices line up
/// ([`SharedEdge::lattice_link`]).
fn link(e: &SharedEdge) -> Option<Link> {
    let (ka, kb) = e.lattice_link()?;
    Some(Link {
        a: e.a,
        b: e.b,
        ka,
        kb,
        c0: false,
    })
}

/// The vertex key at lattice index `k` along `side`.
fn side_key(side: u8, k: u32) -> VertexKey {
    match side {
        0 => VertexKey::new(k, 0),
        1 => VertexKey::new(LATTICE, k),
        2 => VertexKey::new(k, LATTICE),
        _ => VertexKey::new(0, k),
    }
}

/// The lattice index along `side` of a key on it.
fn side_index(side: u8, k: VertexKey) -> Option<u32> {
    match side {
        0 if k.j == 0 => Some(k.i),
        1 if k.i == LATTICE => Some(k.j),
        2 if k.j == LATTICE => Some(k.i),
        3 if k.i == 0 => Some(k.j),
        _ => None,
    }
}

/// `x` mapped from one side's lattice interval to the other's, if it lands on a lattice point.
fn map_index(x: i64, from: [i64; 2], to: [i64; 2]) -> Option<u32> {
    let num = (x - from[0]) * (to[1] - to[0]);
    let den = from[1] - from[0];
    (num % den == 0).then(|| (to[0] + num / den) as u32)
}

/// What the reconstruction knows of one polygon before seams: its samples and their estimated
/// data (in key order).
pub(crate) struct Own<'a> {
    pub sq: &'a SampledQuadtree,
    pub data: &'a [HermiteData],
}

impl Own<'_> {
    fn keys(&self) -> &[VertexKey] {
        &self.sq.keys
    }

    /// The polygon's data at `k`: its estimate at a sample; elsewhere the patch of its
    /// unrefined tree's leaf holding `k`, through that leaf's corners' estimates.
    fn at(&self, k: VertexKey) -> (HermiteData, bool) {
        if let Ok(x) = self.sq.keys.binary_search(&k) {
            return (self.data[x], true);
        }
        let cell = super::estimate::leaf_cell(&self.sq.tree, k.i, k.j);
        let [c00, c10, c11, c01] = cell.corners();
        let corner = |c| {
            self.sq
                .keys
                .binary_search(&c)
                .map_or(HermiteData::default(), |x| self.data[x])
        };
        let patch =
            PatchPoly::from_corners(cell, &[corner(c00), corner(c10), corner(c01), corner(c11)]);
        (patch.hermite_at(k.u(), k.v()), false)
    }
}

/// Per polygon, the seam points' data in its own units (sorted by key): samples' data replaced,
/// new points added.
pub(crate) type Forced = Vec<Vec<(VertexKey, HermiteData)>>;

/// A member of a seam point: a polygon and its key there.
type Member = (u32, VertexKey);

/// World-frame data of one member: value, gradient (in the plane), twist against the member's
/// unit axes, those axes, and whether the point is a corner of the member's domain.
struct World {
    /// The member's partials X_u, X_v at the point.
    partials: (DVec3, DVec3),
    /// The member's own twist, kept where no joint twist applies.
    own_twist: [f64; 3],
    f: [f64; 3],
    grad: [DVec3; 3],
    twist: [f64; 3],
    axes: (DVec3, DVec3),
    lengths: (f64, f64),
    sampled: bool,
}

/// The world data of `d` for a polygon with partials (xu, xv); `None` where the map is singular
/// (a triangle's apex).
fn to_world(d: &HermiteData, xu: DVec3, xv: DVec3, sampled: bool) -> Option<World> {
    let (a, b, c) = (xu.dot(xu), xu.dot(xv), xv.dot(xv));
    let det = a * c - b * b;
    // Singular (or NaN) when det is not clearly positive.
    if det.is_nan() || det <= 1e-18 * a * c {
        return None;
    }
    let (lu, lv) = (a.sqrt(), c.sqrt());
    let grad = std::array::from_fn(|ch| {
        // G = J (J^T J)^-1 [f_u, f_v]: the in-plane gradient with these two directional slopes.
        let (fu, fv) = (d.fu[ch], d.fv[ch]);
        let p = (c * fu - b * fv) / det;
        let q = (a * fv - b * fu) / det;
        p * xu + q * xv
    });
    Some(World {
        partials: (xu, xv),
        own_twist: d.fuv,
        f: d.f,
        grad,
        twist: std::array::from_fn(|ch| d.fuv[ch] / (lu * lv)),
        axes: (xu / lu, xv / lv),
        lengths: (lu, lv),
        sampled,
    })
}

/// How member `m`'s axes relate to `r`'s: the factor turning `r`'s unit twist into `m`'s, if
/// the axes are parallel or perpendicular (within 1e-6).
fn twist_factor(m: &World, r: &World) -> Option<f64> {
    let (mu, mv) = m.axes;
    let (ru, rv) = r.axes;
    let near = |x: f64, y: f64| (x.abs() - y).abs() <= 1e-6;
    let ortho = |a: DVec3, b: DVec3| a.dot(b).abs() <= 1e-6;
    if !ortho(mu, mv) || !ortho(ru, rv) {
        return None;
    }
    let (uu, uv, vu, vv) = (mu.dot(ru), mu.dot(rv), mv.dot(ru), mv.dot(rv));
    if near(uu, 1.0) && near(vv, 1.0) {
        Some(uu.signum() * vv.signum())
    } else if near(uv, 1.0) && near(vu, 1.0) {
        Some(uv.signum() * vu.signum())
    } else {
        None
    }
}

/// Two members joined by one link (its index in [`Seams::links`]).
type Joined = (Member, Member, usize);

/// The seam points of the links `take` accepts, grouped (members that are one point of the
/// surface), and every joined pair.
fn seam_points(
    seams: &Seams,
    own: &[Own<'_>],
    take: impl Fn(&Link) -> bool,
) -> (Vec<Vec<Member>>, Vec<Joined>) {
    // Union-find over members.
    let mut id: HashMap<Member, usize> = HashMap::new();
    let mut members: Vec<Member> = Vec::new();
    let mut parent: Vec<usize> = Vec::new();
    fn find(parent: &mut [usize], mut x: usize) -> usize {
        while parent[x] != x {
            parent[x] = parent[parent[x]];
            x = parent[x];
        }
        x
    }
    let mut node = |m: Member, members: &mut Vec<Member>, parent: &mut Vec<usize>| {
        *id.entry(m).or_insert_with(|| {
            members.push(m);
            parent.push(parent.len());
            parent.len() - 1
        })
    };
    let mut joined = Vec::new();
    for (li, l) in seams.links.iter().enumerate() {
        if !take(l) {
            continue;
        }
        let mut pairs = Vec::new();
        // Points of a's side mapped to b's, and of b's side mapped to a's.
        for (from, to, kf, kt) in [(l.a, l.b, l.ka, l.kb), (l.b, l.a, l.kb, l.ka)] {
            let (lo, hi) = (kf[0].min(kf[1]), kf[0].max(kf[1]));
            for &k in own[from.polygon as usize].keys() {
                let Some(x) = side_index(from.side, k) else {
                    continue;
                };
                if (x as i64) < lo || (x as i64) > hi {
                    continue;
                }
                let Some(y) = map_index(x as i64, kf, kt) else {
                    continue;
                };
                if apex(seams, from.polygon, k) || apex(seams, to.polygon, side_key(to.side, y)) {
                    continue;
                }
                pairs.push(((from.polygon, k), (to.polygon, side_key(to.side, y))));
            }
        }
        if !agree(own, &pairs) {
            continue;
        }
        for (p, q) in pairs {
            joined.push((p, q, li));
            let (x, y) = (
                node(p, &mut members, &mut parent),
                node(q, &mut members, &mut parent),
            );
            let (rx, ry) = (find(&mut parent, x), find(&mut parent, y));
            if rx != ry {
                parent[rx.max(ry)] = rx.min(ry);
            }
        }
    }
    let mut groups: BTreeMap<usize, Vec<Member>> = BTreeMap::new();
    for (x, &m) in members.iter().enumerate() {
        let r = find(&mut parent, x);
        groups.entry(r).or_default().push(m);
    }
    let groups = groups
        .into_values()
        .map(|mut g| {
            g.sort_unstable();
            g
        })
        .collect();
    (groups, joined)
}

/// Largest difference, relative to the larger value, that two polygons' samples of one seam
/// point may have and still be one continuous light. Both sample the same point with the same
/// normal; they differ by the visibility estimate (sampled shadow rays) only.
pub const SAMPLE_AGREEMENT: f64 = 0.02;

/// Whether both polygons' samples at every seam point both have agree within
/// [`SAMPLE_AGREEMENT`] (of the larger value, and of a 1e-3 floor of the larger polygon's peak
/// for dark points): otherwise the light is discontinuous along the seam (a shadow line, an
/// occluder standing on it) and the polygons are left apart.
fn agree(own: &[Own<'_>], pairs: &[(Member, Member)]) -> bool {
    let value = |(p, k): Member| {
        let o = &own[p as usize];
        o.keys().binary_search(&k).ok().map(|x| o.data[x].f)
    };
    let peak = |p: u32| {
        own[p as usize]
            .data
            .iter()
            .flat_map(|d| d.f)
            .fold(0.0f64, |m, x| m.max(x.abs()))
    };
    let Some(&((pa, _), (pb, _))) = pairs.first() else {
        return true;
    };
    let floor = 1e-3 * peak(pa).max(peak(pb));
    pairs.iter().all(|&(m, n)| {
        let (Some(a), Some(b)) = (value(m), value(n)) else {
            return true;
        };
        (0..3).all(|ch| {
            let d = (a[ch] - b[ch]).abs();
            let scale = a[ch].abs().max(b[ch].abs()).max(floor);
            d <= SAMPLE_AGREEMENT * scale
        })
    })
}

/// Whether `k` is the apex of a triangle (its v = 1 side collapsed), where (u, v) is singular.
fn apex(seams: &Seams, polygon: u32, k: VertexKey) -> bool {
    seams.geometry[polygon as usize].shape == scene::Shape::Triangle && k.j == LATTICE
}

/// Whether `k` is a corner of the domain.
fn domain_corner(k: VertexKey) -> bool {
    (k.i == 0 || k.i == LATTICE) && (k.j == 0 || k.j == LATTICE)
}

/// Per polygon (sorted by key), the seam points its Gouraud mesh must carry for the mesh to be
/// one continuous surface across every joined seam: each seam point with the mean of the
/// samples there. Points that are not samples of the polygon become extra vertices on its
/// border; at its own samples the colour is that mean.
pub(crate) fn mesh_points(
    seams: &Seams,
    polygons: &[SampledQuadtree],
) -> Vec<Vec<(VertexKey, glam::Vec3)>> {
    let mut out = vec![Vec::new(); polygons.len()];
    if seams.is_empty() || !seams.fits(polygons.len()) {
        return out;
    }
    let data: Vec<Vec<HermiteData>> = polygons
        .iter()
        .map(|sq| {
            sq.values
                .iter()
                .map(|v| HermiteData {
                    f: [v.x as f64, v.y as f64, v.z as f64],
                    ..HermiteData::default()
                })
                .collect()
        })
        .collect();
    let own: Vec<Own<'_>> = polygons
        .iter()
        .zip(&data)
        .map(|(sq, d)| Own { sq, data: d })
        .collect();
    for group in seam_points(seams, &own, |_| true).0 {
        let sampled: Vec<[f64; 3]> = group
            .iter()
            .filter_map(|&(p, k)| {
                let o = &own[p as usize];
                o.keys().binary_search(&k).ok().map(|x| o.data[x].f)
            })
            .collect();
        if sampled.is_empty() {
            continue;
        }
        let n = sampled.len() as f64;
        let mean: [f64; 3] =
            std::array::from_fn(|ch| sampled.iter().map(|f| f[ch]).sum::<f64>() / n);
        let colour = glam::Vec3::new(mean[0] as f32, mean[1] as f32, mean[2] as f32);
        for &(p, k) in &group {
            out[p as usize].push((k, colour));
        }
    }
    for f in &mut out {
        f.sort_unstable_by_key(|e| e.0);
        f.dedup_by_key(|e| e.0);
    }
    out
}

/// Member `(p, k)`'s own data at its seam point in world terms (`None` where its map is
/// singular).
fn member_world(seams: &Seams, own: &[Own<'_>], (p, k): Member) -> Option<World> {
    let (d, sampled) = own[p as usize].at(k);
    let (xu, xv) = seams.geometry[p as usize].tangents(k.u(), k.v());
    to_world(&d, xu, xv, sampled)
}

/// The joint data of every seam point, handed to each member polygon in its own units.
pub(crate) fn force(seams: &Seams, own: &[Own<'_>], estimator: Estimator) -> Forced {
    let mut out: Forced = vec![Vec::new(); own.len()];
    if seams.is_empty() {
        return out;
    }
    let mut smooth = HashSet::new();
    for group in seam_points(seams, own, |l| !l.c0).0 {
        smooth.extend(group.iter().copied());
        let worlds: Vec<Option<World>> =
            group.iter().map(|&m| member_world(seams, own, m)).collect();
        let Some(joint) = joint(seams, &group, &worlds, estimator) else {
            continue;
        };
        for (&(p, k), w) in group.iter().zip(&worlds) {
            let Some(w) = w else { continue };
            let (xu, xv) = w.partials;
            let mut d = HermiteData {
                f: joint.f,
                ..HermiteData::default()
            };
            for ch in 0..3 {
                d.fu[ch] = joint.grad[ch].dot(xu);
                d.fv[ch] = joint.grad[ch].dot(xv);
                d.fuv[ch] = match (
                    joint.twist,
                    joint.reference.and_then(|r| twist_factor(w, r)),
                ) {
                    (Some(t), Some(factor)) => t[ch] * factor * w.lengths.0 * w.lengths.1,
                    _ => w.own_twist[ch],
                };
            }
            out[p as usize].push((k, d));
        }
    }
    force_folds(seams, own, &smooth, &mut out);
    for f in &mut out {
        f.sort_unstable_by_key(|e| e.0);
        f.dedup_by_key(|e| e.0);
    }
    out
}

/// The joint data of the folds' seam points ([`MAX_FOLD_DEGREES`]): one value (the mean of the
/// members' samples) and, along each folded edge, one slope (the mean of the two members'),
/// each member keeping its own slope across and twist: the two edge cubics are then one curve
/// (C0), while the light may turn with the surface. A point also on a coplanar seam (where the
/// coplanar joint already fixed the data) is left as that seam made it.
fn force_folds(seams: &Seams, own: &[Own<'_>], smooth: &HashSet<Member>, out: &mut Forced) {
    let (groups, joined) = seam_points(seams, own, |l| l.c0);
    let mut world: HashMap<Member, (World, [f64; 3])> = HashMap::new();
    for group in groups {
        if group.iter().any(|m| smooth.contains(m)) {
            continue;
        }
        let worlds: Option<Vec<World>> =
            group.iter().map(|&m| member_world(seams, own, m)).collect();
        let Some(worlds) = worlds else { continue };
        let Some(f) = sampled_mean(&worlds.iter().collect::<Vec<_>>()) else {
            continue;
        };
        for (m, w) in group.into_iter().zip(worlds) {
            world.insert(m, (w, f));
        }
    }
    // Per member, the slopes along its folded edges: (unit direction, slope per channel).
    let mut along: HashMap<Member, Vec<(DVec3, [f64; 3])>> = HashMap::new();
    for (m, n, li) in joined {
        let (Some((wm, _)), Some((wn, _))) = (world.get(&m), world.get(&n)) else {
            continue;
        };
        let l = &seams.links[li];
        let (p0, p1) = side_endpoints(&seams.geometry[l.a.polygon as usize], l.a.side);
        let t = (p1 - p0).normalize_or_zero();
        let slope = std::array::from_fn(|ch| 0.5 * (wm.grad[ch].dot(t) + wn.grad[ch].dot(t)));
        along.entry(m).or_default().push((t, slope));
        along.entry(n).or_default().push((t, slope));
    }
    for (m, (w, f)) in world {
        let (p, k) = m;
        let constraints = along.remove(&m).unwrap_or_default();
        let (xu, xv) = w.partials;
        let mut d = HermiteData {
            f,
            fuv: w.own_twist,
            ..HermiteData::default()
        };
        for ch in 0..3 {
            let g = with_slopes(w.grad[ch], &constraints, ch);
            d.fu[ch] = g.dot(xu);
            d.fv[ch] = g.dot(xv);
        }
        out[p as usize].push((k, d));
    }
}

/// The in-plane gradient `g` changed as little as possible (within the span of the directions)
/// to have the given slopes along at most two independent directions of the plane (channel
/// `ch` of each constraint). Parallel repeats are skipped.
fn with_slopes(g: DVec3, constraints: &[(DVec3, [f64; 3])], ch: usize) -> DVec3 {
    let mut picked: Vec<(DVec3, f64)> = Vec::new();
    for &(t, s) in constraints {
        if picked.len() < 2 && picked.iter().all(|(q, _)| q.cross(t).length() > 1e-6) {
            picked.push((t, s[ch]));
        }
    }
    match picked.as_slice() {
        [] => g,
        [(t, a)] => g + (a - g.dot(*t)) * *t,
        [(t1, a1), (t2, a2), ..] => {
            // g + x t1 + y t2 with (g + x t1 + y t2) . t_i = a_i.
            let (r1, r2) = (a1 - g.dot(*t1), a2 - g.dot(*t2));
            let (m11, m12, m22) = (t1.dot(*t1), t1.dot(*t2), t2.dot(*t2));
            let det = m11 * m22 - m12 * m12;
            if det.abs() <= 1e-12 {
                return g + (a1 - g.dot(*t1)) * *t1;
            }
            let x = (r1 * m22 - r2 * m12) / det;
            let y = (m11 * r2 - m12 * r1) / det;
            g + x * *t1 + y * *t2
        }
    }
}

/// A seam point's data in world terms.
struct Joint<'w> {
    f: [f64; 3],
    grad: [DVec3; 3],
    /// Unit twist against `reference`'s axes, if one applies to every aligned member.
    twist: Option<[f64; 3]>,
    reference: Option<&'w World>,
}

/// A seam point's value: the mean of its members' samples, or of all its members' values where
/// none is a sample (`None` without members).
fn sampled_mean(members: &[&World]) -> Option<[f64; 3]> {
    let sampled: Vec<&World> = members.iter().copied().filter(|w| w.sampled).collect();
    let from = if sampled.is_empty() {
        members
    } else {
        &sampled[..]
    };
    if from.is_empty() {
        return None;
    }
    let n = from.len() as f64;
    Some(std::array::from_fn(|ch| {
        from.iter().map(|w| w.f[ch]).sum::<f64>() / n
    }))
}

/// The joint data of one seam point from its members' world data.
fn joint<'w>(
    seams: &Seams,
    group: &[Member],
    worlds: &'w [Option<World>],
    estimator: Estimator,
) -> Option<Joint<'w>> {
    let live: Vec<&World> = worlds.iter().flatten().collect();
    let f = sampled_mean(&live)?;
    let nl = live.len() as f64;
    let mut grad: [DVec3; 3] =
        std::array::from_fn(|ch| live.iter().map(|w| w.grad[ch]).sum::<DVec3>() / nl);
    let reference = live.first().copied();
    let mut limited_across = [false; 3];
    // Two polygons meeting inside their sides: the slope across from the estimator's rule.
    if live.len() == 2 && group.len() == 2 && !group.iter().any(|&(_, k)| domain_corner(k)) {
        let (pa, ka) = group[0];
        let (wa, wb) = (live[0], live[1]);
        let (p0, p1) = side_endpoints_of(seams, pa, ka);
        let t = (p1 - p0).normalize_or_zero();
        // Across, pointing into a's polygon: a's inward axis minus its part along the seam.
        let inward = inward_axis(wa, ka);
        let across = (inward - inward.dot(t) * t).normalize_or_zero();
        for ch in 0..3 {
            let along = 0.5 * (wa.grad[ch].dot(t) + wb.grad[ch].dot(t));
            // Secant on b's side (arriving at the seam) and on a's side (leaving it).
            let (d0, d1) = (wb.grad[ch].dot(across), wa.grad[ch].dot(across));
            let (slope, lim) = match estimator {
                Estimator::Plain => (0.5 * d0 + 0.5 * d1, false),
                Estimator::Monotone => (fritsch_butland(d0, d1), limited(d0, d1)),
                Estimator::Hyman => (hyman(d0, d1).0, limited(d0, d1)),
            };
            grad[ch] = along * t + slope * across;
            limited_across[ch] = lim;
        }
    }
    let twist = reference.and_then(|r| {
        let mut sum = [0.0f64; 3];
        let mut count = 0.0;
        for w in &live {
            let factor = twist_factor(w, r)?;
            for (acc, t) in sum.iter_mut().zip(w.twist) {
                *acc += t * factor;
            }
            count += 1.0;
        }
        Some(std::array::from_fn(|ch| {
            if limited_across[ch] {
                0.0
            } else {
                sum[ch] / count
            }
        }))
    });
    Some(Joint {
        f,
        grad,
        twist,
        reference,
    })
}

/// The unit axis pointing from the border at `k` into the domain (k lies inside a side).
fn inward_axis(w: &World, k: VertexKey) -> DVec3 {
    if k.j == 0 {
        w.axes.1
    } else if k.j == LATTICE {
        -w.axes.1
    } else if k.i == 0 {
        w.axes.0
    } else {
        -w.axes.0
    }
}

/// The 3D endpoints of the side of `polygon` that `k` lies inside.
fn side_endpoints_of(seams: &Seams, polygon: u32, k: VertexKey) -> (DVec3, DVec3) {
    let side = (0..4u8).find(|&s| side_index(s, k).is_some()).unwrap_or(0);
    side_endpoints(&seams.geometry[polygon as usize], side)
}
