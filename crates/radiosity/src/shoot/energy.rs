//! The energy account of a solve: where the emitted power went. Per channel, in watts:
//! - emitted: spots' power (intensity over the cone's solid angle) plus emitters' E A;
//! - absorbed: (1 - rho) times the power arriving on each polygon, the integral of its
//!   irradiance G over it (trapezoid rule on its leaves; polygons that reflect nothing are
//!   sampled on their own grid, since they keep no samples);
//! - unshot: reflected light the solve stopped before shooting (its patches' unshot radiosity
//!   times their area);
//! - lost: the rest, emitted - absorbed - unshot: light that left an open scene, plus what the
//!   discretization lost or invented (quadrature of G, visibility estimates). On a closed
//!   scene it is the solve's own energy error.
//!
//! Why it holds: every watt a shooter sends arrives somewhere (a polygon, or nowhere in an
//! open scene); what arrives is absorbed (1 - rho) or reflected (rho), and what is reflected
//! was shot (a patch's total) or is still unshot. Summed over the scene, reflected - shot =
//! unshot, so emitted = absorbed + unshot + lost exactly when the transfers conserve energy.

use glam::DVec3;
use rayon::prelude::*;

use super::poly::Poly;
use crate::transfer::Transfer;
use crate::EnergyAccount;

/// The account of a solve whose samples hold the final G (`polys`), whose patches'
/// integrals of G are `fine` (indexed by shooter) and whose unshot and emitted power per
/// channel are `unshot` and `emitted`.
pub(super) fn account(
    tr: &Transfer<'_>,
    polys: &[Poly],
    totals: &[DVec3],
    emitted: DVec3,
    unshot: DVec3,
) -> EnergyAccount {
    let arriving: Vec<DVec3> = polys
        .par_iter()
        .enumerate()
        .map(|(r, p)| {
            if p.reflects() {
                p.integral()
            } else {
                // No samples are kept on a black polygon: gather G at its grid's vertices.
                let g: Vec<DVec3> = p
                    .keys
                    .iter()
                    .map(|k| tr.gather(totals, r, k.u(), k.v()))
                    .collect();
                p.integral_of(&g)
            }
        })
        .collect();
    let absorbed = arriving
        .iter()
        .zip(polys)
        .fold(DVec3::ZERO, |a, (g, p)| a + (DVec3::ONE - p.rho) * *g);
    EnergyAccount {
        emitted,
        absorbed,
        unshot,
        lost: emitted - absorbed - unshot,
    }
}
