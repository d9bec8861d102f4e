//! The energy account of a solve: where the emitted power went. Per channel, in watts:
//! - emitted: spots' power (intensity over the cone's solid angle) plus emitters' E A;
//! - absorbed: (1 - rho) times the power arriving on each polygon's front, the integral of
//!   its irradiance G over it (its leaves' rule, `Poly::integral`: Simpson's where a leaf
//!   keeps its test points; polygons that reflect nothing are integrated by adaptive Simpson
//!   on their own points, since they keep no samples), plus all the power arriving on
//!   back faces (a polygon is one-sided: its back is black), estimated with the escape rays
//!   below (the solver delivers no light to a back face, so no sample holds it);
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

use std::collections::HashMap;

use base::quadtree::{Cell, VertexKey};
use glam::DVec3;
use rayon::prelude::*;

use super::poly::Poly;
use crate::transfer::{spot_power3, sub_area, ShooterKind, Transfer};
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

/// The light that left the scene and the light absorbed on back faces, per channel: over
/// every shooter that shot (in id order), its power shot times its shares
/// ([`Transfer::escape_share`]).
fn escaped(tr: &Transfer<'_>, totals: &[DVec3]) -> (DVec3, DVec3) {
    let power = |s: usize| match tr.shooters[s].kind {
        ShooterKind::Spot { spot } => spot_power3(&tr.scene.spots[spot as usize]),
        _ => totals[s] * tr.shooters[s].area,
    };
    let is_light = |s: usize| !matches!(tr.shooters[s].kind, ShooterKind::Patch { .. });
    let lights: f64 = (0..tr.shooters.len())
        .filter(|&s| is_light(s))
        .map(|s| power(s).element_sum())
        .sum();
    let shares: Vec<(DVec3, DVec3)> = (0..tr.shooters.len())
        .into_par_iter()
        .map(|s| {
            if totals[s] == DVec3::ZERO {
                return (DVec3::ZERO, DVec3::ZERO);
            }
            let p = power(s);
            let rays = if is_light(s) {
                light_rays(p.element_sum() / lights)
            } else {
                ESCAPE_RAYS
            };
            let (out, behind) = tr.escape_share(s, rays);
            (p * out, p * behind)
        })
        .collect();
    shares
        .into_iter()
        .fold((DVec3::ZERO, DVec3::ZERO), |(a, b), (o, k)| (a + o, b + k))
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

/// The error the integrals of G over the black polygons (which keep no samples) are held to,
/// in all, as a share of the emitted power. Their light can be most of it: a lamp facing a
/// ceiling 2 cm away absorbs two thirds of its own light reflected back, peaked in its middle
/// and falling off within 2 cm of its edges, which a trapezoid rule on its coarse grid
/// underestimated by a quarter of the emitted power.
const BLACK_TOLERANCE: f64 = 1e-3;

/// Finest cell level the black polygons' quadrature splits to: 1/64 of a polygon's side, at
/// most 4,225 gathers per polygon. Where the light falls off at an edge within 2 % of the
/// polygon's side (the lamp 2 cm under a ceiling), the integral at level 4 is already within
/// 0.03 % of the emitted power of its value at level 12.
const BLACK_MAX_LEVEL: u32 = 6;

/// The integral of G over black polygon `r`: [`gathered_integral`] from its leaves.
fn black_integral(tr: &Transfer<'_>, totals: &[DVec3], r: usize, p: &Poly, tol: f64) -> DVec3 {
    gathered_integral(tr, totals, r, p.leaf_cells().collect(), tol)
}

/// The integral over polygon `r` of the G that `totals` give its points, from `cells`:
/// adaptive Simpson, a cell split into four while its 9-point Simpson and 4-point trapezoid
/// estimates differ by more than `tol` times its area (down to [`BLACK_MAX_LEVEL`]), and G
/// gathered once per lattice point.
pub(crate) fn gathered_integral(
    tr: &Transfer<'_>,
    totals: &[DVec3],
    r: usize,
    mut cells: Vec<Cell>,
    tol: f64,
) -> DVec3 {
    let poly = &tr.scene.polygons[r];
    let mut seen: HashMap<VertexKey, DVec3> = HashMap::new();
    let mut g = |k: VertexKey| {
        *seen
            .entry(k)
            .or_insert_with(|| tr.gather(totals, r, k.u(), k.v()))
    };
    let mut sum = DVec3::ZERO;
    while let Some(c) = cells.pop() {
        let [a, b, cc, d] = c.corners();
        let mid = |x: VertexKey, y: VertexKey| VertexKey::new((x.i + y.i) / 2, (x.j + y.j) / 2);
        let corners = g(a) + g(b) + g(cc) + g(d);
        let mids = g(mid(a, b)) + g(mid(b, cc)) + g(mid(cc, d)) + g(mid(d, a));
        let area = sub_area(poly, c);
        let trapezoid = area * 0.25 * corners;
        let simpson = area * (corners + 4.0 * mids + 16.0 * g(c.centre())) / 36.0;
        let off = (simpson - trapezoid).abs().max_element();
        if off <= tol * area || c.level >= BLACK_MAX_LEVEL || !tol.is_finite() {
            sum += simpson;
        } else {
            cells.extend(c.children());
        }
    }
    sum
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
    let black_area: f64 = polys
        .iter()
        .enumerate()
        .filter(|(_, p)| !p.reflects())
        .map(|(r, _)| tr.scene.polygons[r].area)
        .sum();
    let arriving: Vec<DVec3> = polys
        .par_iter()
        .enumerate()
        .map(|(r, p)| {
            if p.reflects() {
                p.integral()
            } else {
                // A black polygon keeps no samples: G is gathered where the quadrature needs
                // it, to a share of the emitted power proportional to the polygon's area.
                let tol = BLACK_TOLERANCE * emitted.max_element() / black_area;
                black_integral(tr, totals, r, p, tol)
            }
        })
        .collect();
    let (escaped, behind) = escaped(tr, totals);
    let absorbed = arriving
        .iter()
        .zip(polys)
        .fold(behind, |a, (g, p)| a + (DVec3::ONE - p.rho) * *g);
    EnergyAccount {
        emitted,
        absorbed,
        unshot,
        lost: emitted - absorbed - unshot,
        escaped,
    }
}
