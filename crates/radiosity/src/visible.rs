//! Exact visibility of a polygonal shooter from a receiver point (Nishita and Nakamae 1985,
//! "Half-tone representation of 3-D objects illuminated by area or polyhedron sources"): the
//! part of a convex, planar shooter that the point sees past convex occluders, as convex pieces
//! in the shooter's plane, and its form factor in closed form (Lambert's formula over the
//! pieces).
//!
//! How: every occluder is clipped to the pyramid with apex at the receiver point over the
//! shooter (its side planes through the point and the shooter's edges, and the shooter's own
//! plane), so what is left lies between the two and projects, from the point, inside the
//! shooter; the projection is a convex polygon (a hole). The visible region is the shooter
//! minus the union of the holes, kept as a list of convex pieces: each piece is cut by the
//! lines of each hole's edges, the parts outside stay, the part inside is dropped. Clipping in
//! 3-D before projecting keeps every coordinate finite and near the shooter, however close an
//! occluder comes to the point (a receiver 4 micrometres from a wall standing beside it sees
//! that wall cover exactly the half of the light behind its plane).
//!
//! Why exact: sampled visibility (a fixed set of shadow rays per light) places a penumbra's
//! edges where the outermost rays are blocked, inside the light's outline, so penumbrae come
//! out narrower than they are (7.6 % on a box under an area light) and their light off by the
//! ray set's steps; the error of a fixed set is shared by every point of a face, so the seed
//! moves whole faces; and a patch whose light is concentrated where an occluder hides it (a
//! ceiling lit by a panel just under it, seen from the floor past that panel) delivered its
//! bright part through the rays' average, creating light. The exact region has none of these
//! errors, and it tells the refinement where a penumbra starts and ends (visibility exactly 1
//! or 0 outside it).
//!
//! Invariants: pieces are convex, wound like the shooter, inside it and disjoint (they tile the
//! visible region); a region whose description would pass [`MAX_PIECES`] pieces or holes, or
//! [`MAX_VERTS`] vertices in one polygon, is [`Seen::Complex`] and the caller falls back to
//! rays (counted). Everything is `f64`. The region is built in a view the caller keeps or in a
//! per-thread arena ([`with_arena`], [`with_pool`]), so a query allocates nothing once a thread
//! has served one; what it returns depends only on its arguments.

use std::cell::RefCell;
use std::ops::Range;

use glam::{DVec2, DVec3};

// A convex polygon here has at most as many vertices as the form factor takes.
use crate::formfactor::{polygon_form_factor, MAX_VERTS};

/// Most pieces of a visible region, and most holes (projected occluders) in one query (at most
/// 64: [`View::classify`] keeps a mask of them).
pub(crate) const MAX_PIECES: usize = 48;

/// A region's description would not fit its bounds.
#[derive(Debug, Clone, Copy)]
struct Overflow;

/// A polygon of at most [`MAX_VERTS`] vertices on the stack.
#[derive(Debug, Clone, Copy)]
struct Buf {
    v: [DVec2; MAX_VERTS],
    len: usize,
}

impl Buf {
    fn new() -> Buf {
        Buf {
            v: [DVec2::ZERO; MAX_VERTS],
            len: 0,
        }
    }

    #[inline]
    fn push(&mut self, p: DVec2) -> Result<(), Overflow> {
        if self.len == MAX_VERTS {
            return Err(Overflow);
        }
        self.v[self.len] = p;
        self.len += 1;
        Ok(())
    }

    #[inline]
    fn verts(&self) -> &[DVec2] {
        &self.v[..self.len]
    }
}

/// A signed distance within `eps` of 0 is 0 (the point is on the line).
#[inline]
fn snap(s: f64, eps: f64) -> f64 {
    if s.abs() <= eps {
        0.0
    } else {
        s
    }
}

/// The index after `i` in a cycle of `n` (no division: these loops are the solver's hottest).
#[inline(always)]
fn next(i: usize, n: usize) -> usize {
    if i + 1 == n {
        0
    } else {
        i + 1
    }
}

/// The edges of a polygon as (start, end) pairs, in order from the edge at vertex 0 to the
/// closing one (no index arithmetic or bounds checks: these loops are the solver's hottest).
#[inline(always)]
fn edges(vs: &[DVec2]) -> impl Iterator<Item = (DVec2, DVec2)> + '_ {
    let closing = match vs {
        [first, .., last] => Some((*last, *first)),
        [only] => Some((*only, *only)),
        [] => None,
    };
    vs.windows(2).map(|w| (w[0], w[1])).chain(closing)
}

/// Twice the signed area of a polygon (positive counter-clockwise).
fn area2(vs: &[DVec2]) -> f64 {
    let mut a = 0.0;
    for (p, q) in edges(vs) {
        a += p.perp_dot(q);
    }
    a
}

/// Twice the area of a polygon and its first moment times six (`sum (p + q) (p x q)`): the
/// centroid is the second over three times the first.
fn area_moment(vs: &[DVec2]) -> (f64, DVec2) {
    let (mut a, mut m) = (0.0, DVec2::ZERO);
    for (p, q) in edges(vs) {
        let c = p.perp_dot(q);
        a += c;
        m += (p + q) * c;
    }
    (a, m)
}

/// Axis-aligned bounds of a polygon.
#[inline]
fn bounds(vs: &[DVec2]) -> (DVec2, DVec2) {
    let mut lo = DVec2::splat(f64::INFINITY);
    let mut hi = DVec2::splat(f64::NEG_INFINITY);
    for p in vs {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    (lo, hi)
}

/// Whether two boxes overlap by more than `eps`.
#[inline]
fn boxes_overlap((alo, ahi): (DVec2, DVec2), (blo, bhi): (DVec2, DVec2), eps: f64) -> bool {
    alo.x < bhi.x - eps && blo.x < ahi.x - eps && alo.y < bhi.y - eps && blo.y < ahi.y - eps
}

/// Where `p` lies against the counter-clockwise convex polygon `vs`: inside it or within `eps`
/// of it (on the inner side of every edge's line, within `eps` times the edge's L1 length),
/// and inside by more than `eps` from every edge's line; neither for an empty `vs` (a list of
/// no edges would hold every point). Stops at the first edge `p` lies outside.
#[inline]
fn point_in(vs: &[DVec2], p: DVec2, eps: f64) -> (bool, bool) {
    let Some(&last) = vs.last() else {
        return (false, false);
    };
    let mut within = true;
    let mut a = last;
    for &b in vs {
        let e = b - a;
        let tol = eps * (e.x.abs() + e.y.abs());
        let d = e.perp_dot(p - a);
        if d < -tol {
            return (false, false);
        }
        within &= d > tol;
        a = b;
    }
    (true, within)
}

/// Whether every vertex of `c` lies inside or within `eps` of the counter-clockwise convex
/// polygon `vs` ([`point_in`]), stopping at the first vertex outside.
fn holds(vs: &[DVec2], c: &[DVec2], eps: f64) -> bool {
    c.iter().all(|&p| point_in(vs, p, eps).0)
}

/// Whether every vertex of `c` lies inside or within `eps` of the counter-clockwise convex
/// polygon `vs`, and whether one lies inside it by more than `eps` from every edge's line (so
/// that the two overlap in more than a boundary): [`point_in`] over the vertices, stopping
/// once the answer is known.
fn corners_in(vs: &[DVec2], c: &[DVec2], eps: f64) -> (bool, bool) {
    let (mut all_in, mut one_within) = (true, false);
    for &p in c {
        let (inside, within) = point_in(vs, p, eps);
        all_in &= inside;
        one_within |= within;
        if !all_in && one_within {
            break;
        }
    }
    (all_in, one_within)
}

/// Whether every vertex of `q` lies on or outside the line of an edge of the
/// counter-clockwise convex polygon `p`, within `eps` times the edge's L1 length.
fn separated_by(p: &[DVec2], q: &[DVec2], eps: f64) -> bool {
    let Some(&last) = p.last() else {
        return false;
    };
    let mut a = last;
    for &b in p {
        let e = b - a;
        // eps times the edge's length, its L1 norm for a square root.
        let tol = eps * (e.x.abs() + e.y.abs());
        if q.iter().all(|&x| e.perp_dot(x - a) <= tol) {
            return true;
        }
        a = b;
    }
    false
}

/// Whether two counter-clockwise convex polygons, whose boxes overlap, overlap in more than a
/// boundary within `eps` (the separating-axis test on both polygons' edges).
fn overlaps(a: &[DVec2], b: &[DVec2], eps: f64) -> bool {
    !separated_by(a, b, eps) && !separated_by(b, a, eps)
}

/// The parts of the convex polygon `src` on each side of the line through `a` with normal
/// `m`, written to `pos` (`m . (p - a) >= 0`) and `neg` (`<= 0`); vertices within `eps` of the
/// line count as on it and join both parts.
fn split(
    src: &[DVec2],
    a: DVec2,
    m: DVec2,
    eps: f64,
    pos: &mut Buf,
    neg: &mut Buf,
) -> Result<(), Overflow> {
    pos.len = 0;
    neg.len = 0;
    let (d, _) = sides(src, a, m, eps)?;
    for i in 0..src.len() {
        let j = next(i, src.len());
        let (p, q, dp, dq) = (src[i], src[j], d[i], d[j]);
        if dp >= 0.0 {
            pos.push(p)?;
        }
        if dp <= 0.0 {
            neg.push(p)?;
        }
        if (dp > 0.0 && dq < 0.0) || (dp < 0.0 && dq > 0.0) {
            let x = p + (q - p) * (dp / (dp - dq));
            pos.push(x)?;
            neg.push(x)?;
        }
    }
    Ok(())
}

/// The signed distances `m . (p - a)` of the vertices of `src` from the line through `a` with
/// normal `m`, snapped to 0 within `eps` (in `m`'s units: eps times its L1 norm), each computed
/// once for the two edges it ends; and whether none is negative (nothing to cut).
#[inline]
fn sides(
    src: &[DVec2],
    a: DVec2,
    m: DVec2,
    eps: f64,
) -> Result<([f64; MAX_VERTS], bool), Overflow> {
    if src.len() > MAX_VERTS {
        return Err(Overflow);
    }
    let tol = eps * (m.x.abs() + m.y.abs());
    let mut d = [0.0; MAX_VERTS];
    let mut inside = true;
    for (d, &p) in d.iter_mut().zip(src) {
        *d = snap(m.dot(p - a), tol);
        inside &= *d >= 0.0;
    }
    Ok((d, inside))
}

/// The part of the convex polygon `src` on the non-negative side of the line whose signed
/// distances `d` ([`sides`]) it has, written to `out`.
fn clip_half(src: &[DVec2], d: &[f64; MAX_VERTS], out: &mut Buf) -> Result<(), Overflow> {
    out.len = 0;
    for i in 0..src.len() {
        let j = next(i, src.len());
        let (p, q, dp, dq) = (src[i], src[j], d[i], d[j]);
        if dp >= 0.0 {
            out.push(p)?;
        }
        if (dp > 0.0 && dq < 0.0) || (dp < 0.0 && dq > 0.0) {
            out.push(p + (q - p) * (dp / (dp - dq)))?;
        }
    }
    Ok(())
}

/// The convex polygon `src` clipped to the counter-clockwise convex polygon `clip` (vertices
/// within `eps` of a clip line on it), in `out` (fewer than three vertices: nothing left). A
/// line with every vertex on its inner side leaves the polygon as it is.
fn clip_convex(src: &[DVec2], clip: &[DVec2], eps: f64, out: &mut Buf) -> Result<(), Overflow> {
    let mut other = Buf::new();
    out.len = 0;
    for &p in src {
        out.push(p)?;
    }
    // The polygon so far is in `out` or in `other`, whichever the last cut wrote: the cuts
    // alternate between the two instead of swapping their contents.
    let mut in_out = true;
    for i in 0..clip.len() {
        let (a, b) = (clip[i], clip[next(i, clip.len())]);
        let e = b - a;
        let (cur, dst) = if in_out {
            (&*out, &mut other)
        } else {
            (&other, &mut *out)
        };
        let (d, inside) = sides(cur.verts(), a, DVec2::new(-e.y, e.x), eps)?;
        if inside {
            continue;
        }
        clip_half(cur.verts(), &d, dst)?;
        in_out = !in_out;
        if dst.len < 3 {
            break;
        }
    }
    if !in_out {
        out.v[..other.len].copy_from_slice(other.verts());
        out.len = other.len;
    }
    Ok(())
}

/// The shooter's plane: origin and in-plane axes (`e1 x e2` is the front normal, so a polygon
/// wound counter-clockwise seen from its front is counter-clockwise in 2-D).
#[derive(Debug, Clone, Copy, Default)]
struct Frame {
    o: DVec3,
    e1: DVec3,
    e2: DVec3,
}

impl Frame {
    /// The frame of a convex polygon `outline` (at least two distinct vertices) with front
    /// normal `n`.
    fn of(outline: &[DVec3], n: DVec3) -> Frame {
        let o = outline[0];
        let e1 = (outline[1] - o).normalize();
        Frame {
            o,
            e1,
            e2: n.cross(e1),
        }
    }

    /// 2-D coordinates of `p` (projected onto the plane).
    #[inline]
    fn to2(&self, p: DVec3) -> DVec2 {
        let d = p - self.o;
        DVec2::new(d.dot(self.e1), d.dot(self.e2))
    }

    /// The point of the plane at 2-D coordinates `q`.
    #[inline]
    fn to3(&self, q: DVec2) -> DVec3 {
        self.o + q.x * self.e1 + q.y * self.e2
    }
}

/// A partly visible shooter: its plane, the holes the occluders cast on it, and the visible
/// and the hidden pieces (each set disjoint, convex, counter-clockwise; together they tile the
/// shooter), all in the plane's 2-D coordinates, in one vertex arena.
#[derive(Default)]
pub(crate) struct View {
    frame: Frame,
    /// Every polygon's vertices; the lists below are ranges of it, with their bounds.
    verts: Vec<DVec2>,
    holes: Vec<Piece>,
    pieces: Vec<Piece>,
    hidden: Vec<Piece>,
    /// The list of visible pieces being built by a cut.
    next: Vec<Piece>,
    /// Lengths below this are rounding (1e-12 of the shooter's size).
    eps: f64,
    /// The smaller of its two regions by area ([`View::smaller`]), found once per view.
    small: Region,
    /// Whether it holds only that region, restored from a kept copy ([`View::restore`]).
    restored: bool,
}

/// A convex polygon of a [`View`]'s arena and its bounds.
#[derive(Debug, Clone)]
struct Piece {
    range: Range<usize>,
    bounds: (DVec2, DVec2),
}

thread_local! {
    /// Each thread's arena for [`with_arena`].
    static ARENA: RefCell<View> = RefCell::new(View::default());
}

/// How a cell of a shooter lies against a set of pieces of it ([`View::classify`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum CellIn {
    /// Inside one of them.
    Inside,
    /// Meets none.
    Outside,
    /// Meets some (the mask says which) without lying inside one.
    Partly,
}

/// Which pieces of a [`View`] a query is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub(crate) enum Region {
    /// The part of the shooter the point sees.
    #[default]
    Visible,
    /// The part the occluders hide.
    Hidden,
}

impl View {
    fn poly(&self, r: &Range<usize>) -> &[DVec2] {
        &self.verts[r.clone()]
    }

    fn region(&self, which: Region) -> &[Piece] {
        debug_assert!(
            !self.restored || which == self.small,
            "a restored view holds only its smaller region"
        );
        match which {
            Region::Visible => &self.pieces,
            Region::Hidden => &self.hidden,
        }
    }

    /// The smaller of the visible and the hidden region, by area: a sum over a region is
    /// cheapest over the smaller one (the other follows from the whole shooter's). Equal
    /// areas (a shooter half hidden by an occluder on its grid), to within a relative 1e-9,
    /// give the visible one: rounding, which differs between two scales of one scene, must not
    /// decide which sum (and so which approximation) a point gets. Found when the view is
    /// built ([`View::smaller_by_area`]).
    pub(crate) fn smaller(&self) -> Region {
        self.small
    }

    /// [`View::smaller`] from the regions' areas.
    fn smaller_by_area(&self) -> Region {
        let area = |l: &[Piece]| l.iter().map(|p| area2(self.poly(&p.range))).sum::<f64>();
        if area(&self.hidden) < area(&self.pieces) * (1.0 - 1e-9) {
            Region::Hidden
        } else {
            Region::Visible
        }
    }

    /// The mask of every piece of a region (bit k: piece k; see [`View::classify`]).
    pub(crate) fn all(&self, which: Region) -> u64 {
        let n = self.region(which).len();
        if n >= 64 {
            u64::MAX
        } else {
            (1u64 << n) - 1
        }
    }

    /// How the convex `cell` of the shooter ([`plane_cells`]) lies against the pieces of region
    /// `which` in `mask` (a cell inside its parent meets only the pieces its parent met), with
    /// the mask of those it meets. Conservative: a cell that several pieces cover together but
    /// none alone counts as partly in.
    pub(crate) fn classify(&self, which: Region, cell: &PlaneCell, mask: u64) -> (CellIn, u64) {
        let c = cell.verts();
        let cb = cell.bounds;
        let e = self.eps;
        let mut met = 0u64;
        for (k, p) in self.region(which).iter().enumerate().take(64) {
            if mask & (1 << k) == 0 || !boxes_overlap(cb, p.bounds, e) {
                continue;
            }
            let pv = self.poly(&p.range);
            let (all_in, one_within) = corners_in(pv, c, e);
            if all_in {
                return (CellIn::Inside, 0);
            }
            // A corner well inside the piece is an overlap: the separating-axis test only
            // where none is.
            if one_within || overlaps(pv, c, e) {
                met |= 1 << k;
            }
        }
        if met != 0 {
            (CellIn::Partly, met)
        } else {
            (CellIn::Outside, 0)
        }
    }

    /// The share of the convex `cell`'s area ([`plane_cells`]) in the pieces of region `which`
    /// in `mask` (disjoint, so their overlaps with it add up), and where that part lies: the
    /// offset of its centroid from the whole cell's, in the plane's 2-D coordinates (those of
    /// [`plane_axes`]); a share of 0.5 and no offset where the clip overflows. A piece whose
    /// box misses the cell's is not clipped, and one that holds the cell (as
    /// [`View::classify`] finds it) makes the share 1 with no offset.
    pub(crate) fn share_offset(&self, which: Region, cell: &PlaneCell, mask: u64) -> (f64, DVec2) {
        let c = cell.verts();
        let (area, moment) = cell.area_moment;
        if area <= 0.0 {
            return (0.0, DVec2::ZERO);
        }
        let centre = moment / (3.0 * area);
        let cb = cell.bounds;
        let mut part = Buf::new();
        let (mut within, mut m) = (0.0, DVec2::ZERO);
        for (k, p) in self.region(which).iter().enumerate().take(64) {
            if mask & (1 << k) == 0 || !boxes_overlap(cb, p.bounds, self.eps) {
                continue;
            }
            let pv = self.poly(&p.range);
            if holds(pv, c, self.eps) {
                return (1.0, DVec2::ZERO);
            }
            match clip_convex(pv, c, self.eps, &mut part) {
                Ok(()) if part.len >= 3 => {
                    let (a, pm) = area_moment(part.verts());
                    within += a;
                    m += pm;
                }
                Ok(()) => {}
                Err(Overflow) => return (0.5, DVec2::ZERO),
            }
        }
        if within <= 0.0 {
            return (0.0, DVec2::ZERO);
        }
        let share = (within / area).clamp(0.0, 1.0);
        (share, m / (3.0 * within) - centre)
    }

    /// The form factor from `x` (normal `n`) of the part of the convex `cell` ([`plane_cells`])
    /// in the pieces of region `which` in `mask`.
    pub(crate) fn form_factor_in(
        &self,
        which: Region,
        (x, n): (DVec3, DVec3),
        cell: &PlaneCell,
        mask: u64,
    ) -> f64 {
        let c = cell.verts();
        let mut part = Buf::new();
        let mut f = 0.0;
        for (k, p) in self.region(which).iter().enumerate().take(64) {
            if mask & (1 << k) == 0 {
                continue;
            }
            if clip_convex(self.poly(&p.range), c, self.eps, &mut part).is_ok() && part.len >= 3 {
                f += form_factor_2d(&self.frame, x, n, part.verts());
            }
        }
        f
    }

    /// The form factor from `x` (normal `n`) of region `which`.
    pub(crate) fn region_form_factor(&self, which: Region, x: DVec3, n: DVec3) -> f64 {
        self.region(which)
            .iter()
            .map(|p| form_factor_2d(&self.frame, x, n, self.poly(&p.range)))
            .sum::<f64>()
    }

    /// The form factor from `x` (normal `n`) of the whole visible region, given the whole
    /// shooter's (`open`): summed over the smaller of it and the hidden region.
    pub(crate) fn form_factor(&self, x: DVec3, n: DVec3, open: f64) -> f64 {
        let f = match self.smaller() {
            Region::Visible => self.region_form_factor(Region::Visible, x, n),
            Region::Hidden => open - self.region_form_factor(Region::Hidden, x, n),
        };
        f.clamp(0.0, open.max(0.0))
    }

    /// The smaller region ([`View::smaller`]) and its pieces' vertices: all that a correction
    /// reads of a partly seen shooter, to keep in place of building the view again.
    pub(crate) fn smaller_pieces(&self) -> (Region, impl Iterator<Item = &[DVec2]>) {
        let which = self.smaller();
        let pieces = self.region(which).iter().map(|p| self.poly(&p.range));
        (which, pieces)
    }

    /// Makes this the view of the shooter of plane `plane` holding only its region `which`,
    /// the pieces `pieces` as [`View::smaller_pieces`] gave them: the same frame, tolerance,
    /// pieces and bounds, bit for bit, as the view they were taken from, so every query on
    /// that region answers as it did there.
    pub(crate) fn restore<'p>(
        &mut self,
        plane: &ShooterPlane,
        which: Region,
        pieces: impl Iterator<Item = &'p [DVec2]>,
    ) {
        self.reset(plane.frame, plane.size);
        for vs in pieces {
            let p = self.add(vs);
            match which {
                Region::Visible => self.pieces.push(p),
                Region::Hidden => self.hidden.push(p),
            }
        }
        self.small = which;
        self.restored = true;
    }

    /// Empties it for a shooter of frame `frame` and size `size`: its tolerance, no pieces,
    /// both regions held.
    fn reset(&mut self, frame: Frame, size: f64) {
        self.frame = frame;
        self.eps = 1e-12 * size.max(f64::MIN_POSITIVE);
        self.verts.clear();
        self.holes.clear();
        self.pieces.clear();
        self.hidden.clear();
        self.small = Region::Visible;
        self.restored = false;
    }

    /// Appends a polygon to the arena.
    fn add(&mut self, vs: &[DVec2]) -> Piece {
        let start = self.verts.len();
        self.verts.extend_from_slice(vs);
        Piece {
            range: start..self.verts.len(),
            bounds: bounds(vs),
        }
    }

    /// Removes the last hole from every visible piece: each piece is cut along the hole's
    /// edges; the parts outside stay visible, the part inside every edge becomes hidden.
    fn subtract(&mut self, min_area2: f64) -> Result<(), Overflow> {
        let eps = self.eps;
        let mut next = std::mem::take(&mut self.next);
        next.clear();
        let hole = self.holes.last().expect("the hole was added").clone();
        let (mut rem, mut ins, mut outs) = (Buf::new(), Buf::new(), Buf::new());
        for k in 0..self.pieces.len() {
            let piece = self.pieces[k].clone();
            let pv = self.poly(&piece.range);
            // A piece the hole misses stays whole (cut along the hole's edges it would be
            // split in parts for nothing).
            if !boxes_overlap(piece.bounds, hole.bounds, eps)
                || !overlaps(pv, self.poly(&hole.range), eps)
            {
                next.push(piece);
                continue;
            }
            // Left of each edge is inside the (counter-clockwise) hole: the part right of an
            // edge is visible, the rest goes on to the next edge, and what is left inside every
            // edge is hidden.
            rem.len = 0;
            for &p in pv {
                rem.push(p)?;
            }
            // What is left inside the edges so far: `rem` or `ins`, whichever the last cut
            // wrote (the cuts alternate between the two instead of swapping their contents).
            let mut in_rem = true;
            let mut inside = true;
            for i in hole.range.clone() {
                let j = if i + 1 == hole.range.end {
                    hole.range.start
                } else {
                    i + 1
                };
                let (a, b) = (self.verts[i], self.verts[j]);
                let e = b - a;
                let (cur, dst) = if in_rem {
                    (&rem, &mut ins)
                } else {
                    (&ins, &mut rem)
                };
                split(cur.verts(), a, DVec2::new(-e.y, e.x), eps, dst, &mut outs)?;
                if outs.len >= 3 && area2(outs.verts()).abs() > min_area2 {
                    if next.len() == MAX_PIECES {
                        return Err(Overflow);
                    }
                    let r = self.add(outs.verts());
                    next.push(r);
                }
                if dst.len < 3 || area2(dst.verts()).abs() <= min_area2 {
                    inside = false;
                    break;
                }
                in_rem = !in_rem;
            }
            if inside {
                if self.hidden.len() == MAX_PIECES {
                    return Err(Overflow);
                }
                let left = if in_rem { &rem } else { &ins };
                let r = self.add(left.verts());
                self.hidden.push(r);
            }
        }
        std::mem::swap(&mut self.pieces, &mut next);
        self.next = next;
        Ok(())
    }
}

/// A cell of a shooter's plane in the 2-D coordinates its views use ([`plane_cells`]): a
/// counter-clockwise quad or triangle, the same from every receiver point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct PlaneCell {
    c: [DVec2; 4],
    len: usize,
    /// Its bounds, and twice its area with its first moment ([`area_moment`]): what every
    /// query on it starts from, the same at every receiver point.
    bounds: (DVec2, DVec2),
    area_moment: (f64, DVec2),
}

impl PlaneCell {
    fn new(c: [DVec2; 4], len: usize) -> PlaneCell {
        let vs = &c[..len];
        PlaneCell {
            c,
            len,
            bounds: bounds(vs),
            area_moment: area_moment(vs),
        }
    }

    fn verts(&self) -> &[DVec2] {
        &self.c[..self.len]
    }
}

/// The axes of the 2-D coordinates every [`View`] of the shooter with outline `outline` (at
/// least two distinct vertices) and front normal `ns` is built in.
pub(crate) fn plane_axes(outline: &[DVec3], ns: DVec3) -> (DVec3, DVec3) {
    if outline.len() < 2 {
        return (DVec3::ZERO, DVec3::ZERO);
    }
    let f = Frame::of(outline, ns);
    (f.e1, f.e2)
}

/// The quads `cells` (3-D corners in the plane of the shooter with outline `outline` and front
/// normal `ns`) in the 2-D coordinates of every [`View`] of that shooter: what
/// [`View::classify`], [`View::share`] and [`View::form_factor_in`] take, computed once per
/// cell instead of at every receiver point (the same bits: the views' frame is made from the
/// same outline and normal).
pub(crate) fn plane_cells(
    outline: &[DVec3],
    ns: DVec3,
    cells: impl Iterator<Item = [DVec3; 4]>,
) -> Vec<PlaneCell> {
    if outline.len() < 2 {
        return cells.map(|_| PlaneCell::new([DVec2::ZERO; 4], 0)).collect();
    }
    let frame = Frame::of(outline, ns);
    cells
        .map(|cell| {
            let (c, len) = cell_2d(&frame, &cell);
            PlaneCell::new(c, len)
        })
        .collect()
}

/// A 3-D quad of the plane as a counter-clockwise 2-D polygon (repeated corners dropped: a
/// collapsed quad's cell is a triangle) and its length.
fn cell_2d(frame: &Frame, cell: &[DVec3; 4]) -> ([DVec2; 4], usize) {
    let mut c = [DVec2::ZERO; 4];
    let mut len = 0;
    for p in cell {
        let q = frame.to2(*p);
        if len == 0 || c[len - 1] != q {
            c[len] = q;
            len += 1;
        }
    }
    while len > 1 && c[len - 1] == c[0] {
        len -= 1;
    }
    if area2(&c[..len]) < 0.0 {
        c[..len].reverse();
    }
    (c, len)
}

/// Lambert's form factor from `x` (normal `n`) of a polygon of the frame's plane.
fn form_factor_2d(frame: &Frame, x: DVec3, n: DVec3, piece: &[DVec2]) -> f64 {
    let mut v = [DVec3::ZERO; MAX_VERTS];
    for (out, q) in v.iter_mut().zip(piece) {
        *out = frame.to3(*q);
    }
    polygon_form_factor(x, n, &v[..piece.len().min(MAX_VERTS)])
}

/// Calls `f` with this thread's arena view, for a query whose region is used at once.
pub(crate) fn with_arena<R>(f: impl FnOnce(&mut View) -> R) -> R {
    ARENA.with(|cell| f(&mut cell.borrow_mut()))
}

thread_local! {
    /// Each thread's views for a gather's shaped patches ([`with_pool`]).
    static POOL: RefCell<Vec<View>> = const { RefCell::new(Vec::new()) };
}

/// Calls `f` with this thread's pool of views, which a gather fills in its first pass and
/// reads in its second (the calls on one thread never nest: a gather gathers nothing).
pub(crate) fn with_pool<R>(f: impl FnOnce(&mut Vec<View>) -> R) -> R {
    POOL.with(|cell| f(&mut cell.borrow_mut()))
}

/// What a receiver point sees of a shooter, the region itself left in a [`View`] (see
/// [`see`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Sight {
    /// No occluder covers any of it.
    All,
    /// Occluders cover all of it.
    Nothing,
    /// Part of it: the view holds the visible pieces.
    Part,
    /// The description would pass its bounds: estimate with rays instead.
    Complex,
}

/// What `x` sees of the convex shooter `outline` (front normal `ns`, `x` in front of it) past
/// the convex `occluders` (each a polygon's vertices), the region built in `v` (a gather keeps
/// the views of its shaped patches between its two passes). `eps_plane` is the distance within
/// which an occluder point counts as on the shooter's plane (it cannot block light leaving that
/// plane).
#[cfg(test)]
pub(crate) fn see<'o>(
    v: &mut View,
    x: DVec3,
    outline: &[DVec3],
    ns: DVec3,
    occluders: impl Iterator<Item = &'o [DVec3]>,
    eps_plane: f64,
) -> Sight {
    let plane = ShooterPlane::of(outline, ns);
    see_in(v, x, (outline, ns, &plane), occluders, eps_plane)
}

/// [`see`] with the shooter's plane computed once for all its views ([`ShooterPlane::of`]).
pub(crate) fn see_in<'o>(
    v: &mut View,
    x: DVec3,
    shooter: (&[DVec3], DVec3, &ShooterPlane),
    occluders: impl Iterator<Item = &'o [DVec3]>,
    eps_plane: f64,
) -> Sight {
    match build(v, x, shooter, occluders, eps_plane) {
        Ok(Built::All) => Sight::All,
        Ok(Built::Nothing) => Sight::Nothing,
        Ok(Built::Part) => Sight::Part,
        Err(Overflow) => Sight::Complex,
    }
}

/// What [`build`] found.
enum Built {
    All,
    Nothing,
    Part,
}

/// Builds in `v` the region `x` sees of the shooter (see [`with_seen`]).
fn build<'o>(
    v: &mut View,
    x: DVec3,
    (outline, ns, plane): (&[DVec3], DVec3, &ShooterPlane),
    occluders: impl Iterator<Item = &'o [DVec3]>,
    eps_plane: f64,
) -> Result<Built, Overflow> {
    if outline.len() < 3 || outline.len() > MAX_VERTS {
        return Ok(Built::All);
    }
    let hx = ns.dot(x - outline[0]);
    if hx <= 0.0 {
        return Ok(Built::All);
    }
    let (frame, shooter, size) = (plane.frame, &plane.outline, plane.size);
    v.reset(frame, size);
    let min_area2 = v.eps * size;
    let whole = v.add(shooter.verts());
    v.pieces.push(whole);
    let sides = pyramid(x, outline);
    let mut hole = Buf::new();
    for q in occluders {
        if !project(
            x,
            q,
            &sides,
            (outline[0], ns, hx, eps_plane),
            (&frame, v.eps),
            &mut hole,
        )? {
            continue;
        }
        if area2(hole.verts()) <= min_area2 {
            continue;
        }
        if v.holes.len() == MAX_PIECES {
            return Err(Overflow);
        }
        let h = v.add(hole.verts());
        v.holes.push(h);
        v.subtract(min_area2)?;
        if v.pieces.is_empty() {
            return Ok(Built::Nothing);
        }
    }
    if v.holes.is_empty() {
        return Ok(Built::All);
    }
    let untouched =
        v.hidden.is_empty() && v.pieces.len() == 1 && v.pieces[0].range.len() == shooter.len && {
            let a = area2(v.poly(&v.pieces[0].range));
            (a - area2(shooter.verts())).abs() <= 1e-12 * a.abs()
        };
    if untouched {
        return Ok(Built::All);
    }
    v.small = v.smaller_by_area();
    Ok(Built::Part)
}

/// A shooter's plane as every view of it is built in: its frame, its outline there
/// (counter-clockwise) and its size, the larger side of the outline's bounds. The same for every
/// receiver point, so a solve computes it once per shooter.
#[derive(Debug, Clone, Copy)]
pub(crate) struct ShooterPlane {
    frame: Frame,
    outline: Buf,
    size: f64,
}

impl ShooterPlane {
    /// The plane of the convex shooter `outline` with front normal `ns` (empty if it has
    /// fewer than 3 or more than [`MAX_VERTS`] vertices: a view of it sees all of it).
    pub(crate) fn of(outline: &[DVec3], ns: DVec3) -> ShooterPlane {
        if outline.len() < 3 || outline.len() > MAX_VERTS {
            return ShooterPlane {
                frame: Frame::default(),
                outline: Buf::new(),
                size: 0.0,
            };
        }
        let frame = Frame::of(outline, ns);
        let mut shooter = Buf::new();
        for p in outline {
            shooter.v[shooter.len] = frame.to2(*p);
            shooter.len += 1;
        }
        // Counter-clockwise, as the cuts and the overlap tests assume (an outline's winding
        // need not agree with the normal a polygon was given: a triangle cut from a folded
        // quad keeps the quad's).
        if area2(shooter.verts()) < 0.0 {
            shooter.v[..shooter.len].reverse();
        }
        let (lo, hi) = bounds(shooter.verts());
        ShooterPlane {
            frame,
            outline: shooter,
            size: (hi - lo).max_element(),
        }
    }
}

/// Inward side planes (normal, through the apex) of the pyramid from `x` over `outline`.
fn pyramid(x: DVec3, outline: &[DVec3]) -> ([DVec3; MAX_VERTS], usize) {
    let c = outline.iter().copied().sum::<DVec3>() / outline.len() as f64;
    let mut n = [DVec3::ZERO; MAX_VERTS];
    let mut len = 0;
    for i in 0..outline.len().min(MAX_VERTS) {
        let a = outline[i] - x;
        let b = outline[next(i, outline.len())] - x;
        let mut m = a.cross(b);
        if m.length_squared() == 0.0 {
            continue;
        }
        if m.dot(c - x) < 0.0 {
            m = -m;
        }
        n[len] = m;
        len += 1;
    }
    (n, len)
}

/// The hole occluder `q` casts on the shooter seen from `x`, written to `hole`: `q` clipped to
/// the pyramid from `x` over the shooter and to the space in front of the shooter's plane (a
/// point `s0` of it, normal `ns`) by more than `eps_plane`, projected from `x` (at height `hx`
/// over the plane) onto the plane; counter-clockwise, vertices closer than `eps` merged.
/// Whether anything of `q` is left.
fn project(
    x: DVec3,
    q: &[DVec3],
    (sides, n_sides): &([DVec3; MAX_VERTS], usize),
    (s0, ns, hx, eps_plane): (DVec3, DVec3, f64, f64),
    (frame, eps): (&Frame, f64),
    hole: &mut Buf,
) -> Result<bool, Overflow> {
    let mut a = [DVec3::ZERO; MAX_VERTS];
    let mut b = [DVec3::ZERO; MAX_VERTS];
    let mut len = q.len();
    if len > MAX_VERTS {
        return Err(Overflow);
    }
    a[..len].copy_from_slice(q);
    let (mut src, mut dst) = (&mut a, &mut b);
    // Each plane clips only if some vertex lies outside it (most occluders lie wholly inside
    // most of the pyramid's faces).
    let above = |p: DVec3| ns.dot(p - s0) - eps_plane;
    if src[..len].iter().any(|&p| above(p) < 0.0) {
        len = clip3(src, len, dst, above)?;
        std::mem::swap(&mut src, &mut dst);
    }
    for m in &sides[..*n_sides] {
        if len < 3 {
            return Ok(false);
        }
        let side = |p: DVec3| m.dot(p - x);
        if src[..len].iter().any(|&p| side(p) < 0.0) {
            len = clip3(src, len, dst, side)?;
            std::mem::swap(&mut src, &mut dst);
        }
    }
    if len < 3 {
        return Ok(false);
    }
    hole.len = 0;
    for &p in &src[..len] {
        let denom = hx - ns.dot(p - s0);
        if denom <= 0.0 {
            // At or beyond the receiver's height: only the apex itself can be (the pyramid
            // holds nothing else there), and it casts nothing.
            continue;
        }
        hole.push(frame.to2(x + (p - x) * (hx / denom)))?;
    }
    dedup(hole, eps);
    if hole.len < 3 {
        return Ok(false);
    }
    if area2(hole.verts()) < 0.0 {
        hole.v[..hole.len].reverse();
    }
    Ok(true)
}

/// Drops vertices within `eps` of the one before them (and a last one within `eps` of the
/// first): an edge of zero length has no direction to cut along or test against (a point of
/// the pyramid's apex line clipped twice lands on one spot).
fn dedup(p: &mut Buf, eps: f64) {
    let mut n = 0;
    for i in 0..p.len {
        let q = p.v[i];
        if n == 0 || (q - p.v[n - 1]).length_squared() > eps * eps {
            p.v[n] = q;
            n += 1;
        }
    }
    while n > 1 && (p.v[n - 1] - p.v[0]).length_squared() <= eps * eps {
        n -= 1;
    }
    p.len = n;
}

/// Clips the polygon `src[..len]` to `d(p) >= 0` into `dst` (Sutherland-Hodgman); the new
/// length. Each vertex's `d` is computed once, for both edges it ends.
fn clip3(
    src: &[DVec3; MAX_VERTS],
    len: usize,
    dst: &mut [DVec3; MAX_VERTS],
    d: impl Fn(DVec3) -> f64,
) -> Result<usize, Overflow> {
    let mut dist = [0.0; MAX_VERTS];
    for (di, &p) in dist.iter_mut().zip(&src[..len]) {
        *di = d(p);
    }
    let mut n = 0;
    for i in 0..len {
        let j = next(i, len);
        let (a, b, da, db) = (src[i], src[j], dist[i], dist[j]);
        if da >= 0.0 {
            if n == MAX_VERTS {
                return Err(Overflow);
            }
            dst[n] = a;
            n += 1;
        }
        if (da >= 0.0) != (db >= 0.0) {
            if n == MAX_VERTS {
                return Err(Overflow);
            }
            dst[n] = a + (b - a) * (da / (da - db));
            n += 1;
        }
    }
    Ok(n)
}

#[cfg(test)]
mod tests;
