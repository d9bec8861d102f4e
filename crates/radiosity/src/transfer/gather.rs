//! The gather: everything a receiver point gets from every shooter that reaches it, each
//! shooter's transfer times its radiosity, summed in shooter id order; where a shooter's light
//! shape puts its light unevenly, the corrections of its shape, judged again against the level
//! they bring the point to.

use super::*;

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
        visible::with_pool(|pool| self.gather_in(totals, r, (u, v), pool))
    }

    /// [`Transfer::gather`] with the pool of views its shaped patches' regions are kept in
    /// between the two passes (found once per point and patch).
    pub(super) fn gather_in(
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
    pub(super) fn shaped_corrections(
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
}

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
