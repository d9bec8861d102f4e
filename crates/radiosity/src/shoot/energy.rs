//! The energy account of a solve: where the emitted power went. Per channel, in watts:
//! - emitted: spots' power (intensity over the cone's solid angle) plus emitters' E A;
//! - absorbed: (1 - rho) times the power arriving on each polygon, the integral of its
//!   irradiance G over it (trapezoid rule on its leaves; polygons that reflect nothing are
//!   sampled on their own grid, since they keep no samples);
//! - unshot: reflected light the solve stopped before shooting (its patches' unshot radiosity
//!   times their area);
//! - lost: the rest, emitted - absorbed - unshot: light that left an open scene, plus what the
//!   discretization lost or invented (quadrature of G, visibility estimates);
//! - escaped: the light that left the scene, estimated on its own: every shooter's power shot
//!   times the share of its light that hits no polygon ([`ESCAPE_RAYS`] stratified rays per
//!   patch, [`LIGHT_ESCAPE_RAYS`] at most per light, shared by power, weighted by the light each
//!   carries). lost - escaped is then the solve's energy error, on
//!   any scene (on a closed one, escaped is 0).
//!
//! Why it holds: every watt a shooter sends arrives somewhere (a polygon, or nowhere in an
//! open scene); what arrives is absorbed (1 - rho) or reflected (rho), and what is reflected
//! was shot (a patch's total) or is still unshot. Summed over the scene, reflected - shot =
//! unshot, so emitted = absorbed + unshot + lost exactly when the transfers conserve energy.

use glam::DVec3;
use rayon::prelude::*;

use super::poly::Poly;
use crate::transfer::{spot_power3, ShooterKind, Transfer};
use crate::EnergyAccount;

/// Rays per reflecting patch of the escape estimate: the error of a share p is about
/// sqrt(p (1 - p) / 4096) < 0.8 % of that patch's light, independent between patches (a room's
/// light is spread over tens to thousands of them).
pub(crate) const ESCAPE_RAYS: usize = 4096;

/// Most rays per light (emitter or spot): a light that carries all the emitted power gets them,
/// and the error of its share is below 0.2 % of its light.
pub(crate) const LIGHT_ESCAPE_RAYS: usize = 65536;

/// Rays shared by all the lights in proportion to their power (each gets at least
/// [`MIN_LIGHT_ESCAPE_RAYS`], at most [`LIGHT_ESCAPE_RAYS`]): with `n_s = N w_s` rays for a light
/// carrying the share `w_s` of the light, the errors `w_s sqrt(p_s / n_s)` add in quadrature to
/// at most `sqrt(1 / N)` = 0.2 % of the emitted light, however many lights there are. A fixed
/// count per light made the account cost 82 million rays (8 s, most of the solve) on a
/// checkerboard of 1,250 tiny emitters.
const LIGHTS_ESCAPE_RAYS: f64 = 262_144.0;

/// Fewest rays per light (its share's error at most 1.6 % of its own, small, light).
const MIN_LIGHT_ESCAPE_RAYS: usize = 1024;

/// The light that left the scene per channel: over every shooter that shot (in id order), its
/// power shot times its escape share ([`Transfer::escape_share`]).
fn escaped(tr: &Transfer<'_>, totals: &[DVec3]) -> DVec3 {
    let power = |s: usize| match tr.shooters[s].kind {
        ShooterKind::Spot { spot } => spot_power3(&tr.scene.spots[spot as usize]),
        _ => totals[s] * tr.shooters[s].area,
    };
    let is_light = |s: usize| !matches!(tr.shooters[s].kind, ShooterKind::Patch { .. });
    let lights: f64 = (0..tr.shooters.len())
        .filter(|&s| is_light(s))
        .map(|s| power(s).element_sum())
        .sum();
    let shares: Vec<DVec3> = (0..tr.shooters.len())
        .into_par_iter()
        .map(|s| {
            if totals[s] == DVec3::ZERO {
                return DVec3::ZERO;
            }
            let p = power(s);
            let rays = if is_light(s) {
                light_rays(p.element_sum() / lights)
            } else {
                ESCAPE_RAYS
            };
            p * tr.escape_share(s, rays)
        })
        .collect();
    shares.into_iter().sum()
}

/// Escape rays of a light carrying the share `w` of all the lights' power (see
/// [`LIGHTS_ESCAPE_RAYS`]).
fn light_rays(w: f64) -> usize {
    let n = if w.is_finite() {
        LIGHTS_ESCAPE_RAYS * w
    } else {
        0.0
    };
    (n.ceil() as usize).clamp(MIN_LIGHT_ESCAPE_RAYS, LIGHT_ESCAPE_RAYS)
}

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
        escaped: escaped(tr, totals),
    }
}
