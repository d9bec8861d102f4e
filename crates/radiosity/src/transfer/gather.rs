//! The gather: everything a receiver point gets from every shooter that reaches it, each
//! shooter's transfer times its radiosity, summed in shooter id order; where a shooter's light
//! shape puts its light unevenly, the corrections of its shape, judged again against the level
//! they bring the point to.

use rayon::prelude::*;

use super::seen::{Seen, SeenCache};
use super::*;
use base::quadtree::VertexKey;

impl Transfer<'_> {
    /// Total irradiance G at polygon `r`, (u, v) from every shooter with a non-zero total, in
    /// shooter id order: G = sum_s total_s * transfer(s). Radiosity is E + rho * G.
    ///
    /// Only the shooters whose pairs reach `r` are visited (a culled pair adds exactly zero),
    /// so a gather costs what the point can see. Every shooter with a non-zero total must have
    /// its pairs ([`Transfer::ensure_pairs`]) and the index must be sorted
    /// ([`Transfer::index_receivers`]).
    pub(crate) fn gather(&self, totals: &[DVec3], r: usize, u: f64, v: f64) -> DVec3 {
        debug_assert!(!self.unsorted, "index_receivers after new pairs");
        visible::with_pool(|pool| {
            self.gather_in(totals, r, (u, v), pool, &Seen::default(), None)
                .0
        })
    }

    /// [`Transfer::gather`] at lattice point `k` of polygon `r`, taking each shooter's
    /// geometry from `kept` (what the point's earlier gather saw, [`seen`]) where it holds it.
    /// The same G, bit for bit; and, if `record` and anything had to be computed, the
    /// point's entries to keep in place of `kept` (with the regions its corrections used, if
    /// `regions`).
    fn gather_kept(
        &self,
        totals: &[DVec3],
        r: usize,
        k: VertexKey,
        (kept, record, regions): (&Seen, bool, bool),
    ) -> (DVec3, Option<Seen>) {
        debug_assert!(!self.unsorted, "index_receivers after new pairs");
        SCRATCH.with(|scratch| {
            let mut scratch = scratch.borrow_mut();
            scratch.clear();
            let (g, fresh) = visible::with_pool(|pool| {
                let out = record.then_some((&mut *scratch, regions));
                self.gather_in(totals, r, (k.u(), k.v()), pool, kept, out)
            });
            // A copy at its exact size: the scratch grew to it, the copy is allocated once.
            (g, (fresh && record).then(|| scratch.to_kept()))
        })
    }

    /// G at each of `points` (polygon, lattice point), gathered in parallel with what `seen`
    /// holds of them, keeping what the gathers compute while it has room. The points go in
    /// runs of [`KEEP_RUN`] while it does, so that the entries waiting to be kept stay a small
    /// share of what it may keep (a whole refinement generation's at once passed a 22 MiB
    /// limit by 4 MiB).
    pub(crate) fn gather_points(
        &self,
        totals: &[DVec3],
        points: &[(u32, VertexKey)],
        seen: &mut SeenCache,
    ) -> Vec<DVec3> {
        let mut g = Vec::with_capacity(points.len());
        let mut rest = points;
        while !rest.is_empty() {
            let (record, regions) = (seen.has_room(), seen.keeps_regions());
            let run = if record { KEEP_RUN } else { rest.len() };
            let (now, later) = rest.split_at(run.min(rest.len()));
            let kept = &*seen;
            let found: Vec<_> = now
                .par_iter()
                .map(|&(r, k)| {
                    let kept = kept.get(r as usize, k);
                    self.gather_kept(totals, r as usize, k, (kept, record, regions))
                })
                .collect();
            for (&(r, k), (gk, fresh)) in now.iter().zip(found) {
                g.push(gk);
                if let Some(fresh) = fresh {
                    seen.keep(r as usize, k, fresh);
                }
            }
            rest = later;
        }
        g
    }

    /// [`Transfer::gather`] with the pool of views its shaped patches' regions are kept in
    /// between the two passes (found once per point and patch), the entries `kept` from an
    /// earlier gather at the point, and where to record the entries of this one (`out`, with
    /// whether to record the regions its corrections use).
    /// Returns G and whether anything was computed that `kept` did not hold.
    pub(super) fn gather_in(
        &self,
        totals: &[DVec3],
        r: usize,
        (u, v): (f64, f64),
        pool: &mut Vec<visible::View>,
        kept: &Seen,
        mut out: Option<(&mut Seen, bool)>,
    ) -> (DVec3, bool) {
        let x = self.receiver(r, u, v);
        let mut g = DVec3::ZERO;
        let mut pending: Vec<shape::Pending> = Vec::new();
        let mut used = 0usize;
        let (mut walk, mut fresh) = (kept.walk(), false);
        for &(s, i) in &self.by_receiver[r] {
            let t = totals[s as usize];
            if t == DVec3::ZERO {
                continue;
            }
            if matches!(self.shooters[s as usize].kind, ShooterKind::Spot { .. }) {
                g += t * self.transfer_at(s as usize, r, i as usize, u, v);
                continue;
            }
            if pool.len() == used {
                pool.push(visible::View::default());
            }
            // An emitter's or a patch's transfer is its uniform one (`transfer_at` computes
            // the same); a kept look has its region restored if it was kept, else none yet.
            let (uniform, f, look, ready, restored) = match walk.find(s) {
                Some((t, f, look)) => {
                    let region = (look == Look::Exact(Sight::Part))
                        .then(|| walk.region(s))
                        .flatten();
                    if let Some(kept) = &region {
                        let plane = &self.shooters[s as usize].plane;
                        pool[used].restore(plane, kept.which, kept.pieces());
                    }
                    let restored = region.is_some();
                    (DVec3::splat(t), f, look, restored, restored)
                }
                None => {
                    fresh = true;
                    let (t, f, look) =
                        self.uniform_look(s as usize, r, i as usize, (u, v), &mut pool[used]);
                    (t, f, look, true, false)
                }
            };
            if let Some((out, _)) = out.as_mut() {
                out.push(s, uniform.x, f, look);
            }
            g += t * uniform;
            let Some(shape) = &self.shapes[s as usize] else {
                continue;
            };
            let error = self.uniform_error(s as usize, shape, (uniform, f, look), x);
            if error > 0.0 {
                let part = look == Look::Exact(Sight::Part);
                pending.push(shape::Pending {
                    s,
                    i,
                    uniform,
                    error,
                    f,
                    look,
                    slot: used as u32,
                    ready: ready || !part,
                    restored,
                    keep: restored,
                });
                // A part seen keeps its region for the second pass.
                used += usize::from(part);
            }
        }
        let corrected = self.corrected(totals, r, (u, v), g, &mut pending, pool);
        if let Some((out, true)) = out {
            fresh |= keep_regions(out, &pending, pool);
        }
        (g + corrected, fresh)
    }

    /// The second pass of a gather that found `g` from the shooters' uniform light: the
    /// shaped patches whose uniform light may be off by more than the tolerance of what this
    /// point receives are refined (see `shape`). What it receives is first judged from the
    /// uniform light; where the corrections bring it below [`LEVEL_DROP`] of that, they are
    /// judged again against the corrected level. Returns the sum of the corrections.
    fn corrected(
        &self,
        totals: &[DVec3],
        r: usize,
        (u, v): (f64, f64),
        g: DVec3,
        pending: &mut [shape::Pending],
        pool: &mut [visible::View],
    ) -> DVec3 {
        let mut level = lum(g);
        let mut corrected = self.shaped_corrections(totals, r, (u, v), pending, pool, level);
        for _ in 0..LEVEL_PASSES {
            let seen = lum(g + corrected);
            if seen >= LEVEL_DROP * level {
                break;
            }
            level = seen;
            corrected = self.shaped_corrections(totals, r, (u, v), pending, pool, level);
        }
        corrected
    }

    /// The sum of the shaped corrections of the `pending` patches at the receiver point of
    /// polygon `r` at (u, v), each judged against `level`, the luminance of what the point
    /// receives (see [`Transfer::gather`]). A part seen whose region is not built yet (its
    /// look kept from an earlier gather) is built in its view when its correction needs it.
    pub(super) fn shaped_corrections(
        &self,
        totals: &[DVec3],
        r: usize,
        (u, v): (f64, f64),
        pending: &mut [shape::Pending],
        pool: &mut [visible::View],
        level: f64,
    ) -> DVec3 {
        let mut g = DVec3::ZERO;
        let mut xn: Option<(DVec3, DVec3)> = None;
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
                let (s, i, slot) = (p.s as usize, p.i as usize, p.slot as usize);
                if !p.ready {
                    let cands = self.pairs[s].as_ref().expect("the pair's table exists");
                    let x = self.receiver(r, u, v);
                    let look = self.look(s, r, cands.at(i).1, x, &mut pool[slot], (None, false));
                    debug_assert_eq!(look, p.look, "a kept look is what the point sees");
                    p.ready = true;
                }
                p.keep |= p.look == Look::Exact(Sight::Part);
                let shape = self.shapes[s].as_ref().expect("pending is shaped");
                let shaped = self.shaped_in_view(
                    s,
                    r,
                    i,
                    shape,
                    (u, v),
                    (p.f, shape::NODE_BUDGET * tau),
                    (p.look, &pool[slot]),
                );
                g += a * t * (shaped - p.uniform);
            }
            if a < 1.0 && sees_all(p.look) {
                let shape = self.shapes[p.s as usize]
                    .as_ref()
                    .expect("pending is shaped");
                let (x, n) = *xn.get_or_insert_with(|| {
                    let x = self.receiver(r, u, v);
                    (x, self.scene.polygons[r].shading_normal(x))
                });
                let normal = self.shooters[p.s as usize].normal;
                let far = (p.uniform + shape.far_dipole(x, n, normal)).max(DVec3::ZERO);
                g += (1.0 - a) * t * (far - p.uniform);
            }
        }
        g
    }
}

/// Whether a look sees all of its shooter (so that its far light is the shape's dipole).
fn sees_all(look: Look) -> bool {
    match look {
        Look::Clear | Look::Exact(Sight::All) => true,
        Look::Exact(_) => false,
        Look::Rays(v) => v >= 1.0,
    }
}

/// Records in `out` the regions of the `pending` patches seen in part that a gather keeps
/// (see [`shape::Pending::keep`]), from their views in `pool`; whether any was not kept
/// before (the point's entries are then worth keeping again).
fn keep_regions(out: &mut Seen, pending: &[shape::Pending], pool: &[visible::View]) -> bool {
    let mut new = false;
    for p in pending.iter().filter(|p| p.keep) {
        debug_assert!(p.ready, "a region kept or used is built");
        let (which, pieces) = pool[p.slot as usize].smaller_pieces();
        out.push_region(p.s, which, pieces);
        new |= !p.restored;
    }
    new
}

thread_local! {
    /// Each thread's entries of the point it gathers, before they are copied to be kept.
    static SCRATCH: std::cell::RefCell<Seen> = std::cell::RefCell::new(Seen::default());
}

/// Points a [`Transfer::gather_points`] run gathers while it keeps what they see.
const KEEP_RUN: usize = 256;

/// A gather whose shaped corrections leave it below this share of the level they were judged
/// against judges them again against the corrected level: the uniform light over-states what
/// a point receives where a patch's bright part is hidden from it (a floor under a lamp 2 cm
/// below a ceiling: the ceiling's patches read 13 times the light the floor gets, so every
/// correction was held to a tolerance 13 times too loose and the floor read 1.37 of a path
/// tracer's light; judged again, 1.28).
pub(super) const LEVEL_DROP: f64 = 0.5;

/// Most times a gather judges its corrections again (each pass at most halves the level).
pub(super) const LEVEL_PASSES: usize = 3;

/// Luminance of linear RGB (Rec. 709 weights): the level refinement criteria compare with.
#[inline]
pub(super) fn lum(c: DVec3) -> f64 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}
