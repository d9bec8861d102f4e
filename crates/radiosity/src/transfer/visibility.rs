//! Visibility between a shooter and a receiver point: the shooter's part a point sees, exactly
//! (`visible`: its occluders' shadows clipped out) or by its stratified shadow rays; the
//! occluder candidates a pair keeps (the pyramid from the point over the shooter, the convex
//! hull of the two polygons); and the fraction of a shooter a point sees, weighted by the
//! shooter's light shape where it has one.

use super::*;
use std::ops::ControlFlow;

impl Transfer<'_> {
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

    pub(super) fn shadowed_with(
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
            let shooter = (sg.outline.verts(), sg.normal, &sg.plane);
            match visible::see_in(view, x, shooter, occ, self.eps) {
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
        // Whether there are more than MAX_NEAR once `q` is considered.
        let mut consider = |q: u32| {
            if near.many || !self.may_block(q, x, sg, &sides) {
                return near.many;
            }
            if near.len < MAX_NEAR {
                near.ids[near.len] = q;
                near.len += 1;
            } else {
                near.many = true;
            }
            near.many
        };
        if cands.len() <= LONG_CANDIDATE_LIST {
            cands.iter().for_each(|&q| {
                consider(q);
            });
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
            // Past MAX_NEAR of them the answer is `many` whatever else the tree holds.
            self.bvh.try_for_each_in(&b, &planes[..sides.len], |q| {
                if cands.binary_search(&q).is_ok() && consider(q) {
                    ControlFlow::Break(())
                } else {
                    ControlFlow::Continue(())
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
    pub(super) fn visibility_unfiltered(
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
    pub(super) fn visible_fraction(
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
    pub(super) fn may_block(&self, q: u32, x: DVec3, sg: &ShooterGeom, sides: &Sides) -> bool {
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
}

/// Shooters with at most this many sample points skip the per-point candidate filter when
/// their visibility falls back to rays (see [`Transfer::visibility_unfiltered`]).
pub(super) const FEW_RAYS: usize = 2;

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
/// them it falls back to shadow rays. A furnished room needs more than a bare one: from the
/// floor under a table, a wall patch is seen past the table's top and sides, four legs and
/// whatever stands beyond. With 16, such points fell back to rays, whose fixed set per patch
/// is shared by every receiver, so its error is one per face: the floor under a table read
/// 1-2.6 % dark against a path tracer and a leg's face 4.5 %; with 48, within 0.8 %, and the
/// room solves faster (its noisy light had asked for more refinement). A building's rooms
/// cost 14 % more (its rays fell from 9.1 million to 23,000).
pub(crate) const MAX_NEAR: usize = 48;

/// The occluders that may meet the pyramid from a receiver point over a shooter.
pub(crate) struct Near {
    pub(crate) ids: [u32; MAX_NEAR],
    pub(crate) len: usize,
    /// More than [`MAX_NEAR`] (then `ids` is incomplete).
    pub(crate) many: bool,
}

/// Occluder lists longer than this are searched through the BVH per receiver point.
pub(super) const LONG_CANDIDATE_LIST: usize = 24;

/// Inward normals of the side planes of the pyramid from an apex over a convex outline.
pub(super) struct Sides {
    n: [DVec3; 8],
    tol: [f64; 8],
    len: usize,
}

pub(super) fn pyramid_sides(x: DVec3, outline: &SmallPoly) -> Sides {
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

/// Whether the convex planar polygon `q` (normal `n`) meets every segment between the convex
/// point sets `a` and `b` (a polygon and a polygon or a point): both lie strictly on opposite
/// sides of its plane, and the point where each segment between a vertex of `a` and one of `b`
/// crosses the plane lies inside `q` by more than `eps` of its edges' lengths.
///
/// Why the vertices suffice: seen from a fixed point of `a`, the crossings of the segments to
/// `b` are the central projection of `b` onto the plane, the convex hull of its vertices'
/// projections; over the points of `a` the same holds with the roles swapped, so every
/// crossing lies in the convex hull of the crossings of vertex pairs, and `q` holds that hull
/// if it holds its points.
pub(super) fn blocks_shaft(q: &[DVec3], n: DVec3, (a, b): (&[DVec3], &[DVec3]), eps: f64) -> bool {
    let Some(&q0) = q.first() else {
        return false;
    };
    if a.len() > 8 || b.len() > 8 {
        return false;
    }
    let nl = n.length();
    let tol = eps * nl;
    let mut da = [0.0; 8];
    let mut db = [0.0; 8];
    let side = |pts: &[DVec3], d: &mut [f64; 8]| {
        for (d, &p) in d.iter_mut().zip(pts) {
            *d = n.dot(p - q0);
        }
        let d = &d[..pts.len()];
        if d.iter().all(|&x| x > tol) {
            1
        } else if d.iter().all(|&x| x < -tol) {
            -1
        } else {
            0
        }
    };
    let (sa, sb) = (side(a, &mut da), side(b, &mut db));
    if sa * sb != -1 {
        return false;
    }
    // The outline's winding about `n` (a triangle cut from a folded quad keeps the quad's).
    let edges = || (0..q.len()).map(|i| (q[i], q[(i + 1) % q.len()]));
    let w = edges()
        .map(|(p, r)| (p - q0).cross(r - q0).dot(n))
        .sum::<f64>()
        .signum();
    let inside = |x: DVec3| {
        edges().all(|(p, r)| {
            let e = r - p;
            w * e.cross(x - p).dot(n) > eps * e.length() * nl
        })
    };
    a.iter().zip(da).all(|(&pa, dpa)| {
        b.iter()
            .zip(db)
            .all(|(&pb, dpb)| inside(pa + (pb - pa) * (dpa / (dpa - dpb))))
    })
}

/// Side faces of the convex hull of two convex point sets `a` and `b` (a polygon and a polygon or
/// a point) that pass through an edge of one and a vertex of the other: planes (n, p0) with every
/// point of both sets on the side `n . (p - p0) >= -eps |n|`. Together with the two polygons' own
/// planes these are the faces of the hull (edge-edge faces are missed, which only makes the
/// occluder test that uses them more conservative, never wrong).
pub(super) fn hull_faces(a: &[DVec3], b: &[DVec3], eps: f64) -> Vec<(DVec3, DVec3)> {
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
