//! Where each light's light peaks on each polygon it reaches: the points refinement tests
//! besides a leaf's centre and edge midpoints.
//!
//! The error test compares the radiosity at five fixed points of a leaf with the bilinear
//! prediction of its corners. A peak narrower than a leaf and off those points (a spot 1 cm
//! from a wall whose cone misses every vertex, an emitter over a floor off the lattice) passes
//! it, and the reconstruction, which cannot rise above samples that never saw the peak, draws
//! it low or not at all. So for every (light, receiver) pair the point where the light's
//! unoccluded contribution is largest is found once per refinement pass, and every leaf
//! holding it is also judged there ([`PEAK_SHARE`]).
//!
//! The search maximizes the light's unoccluded transfer (a spot's `I(theta) cos / r^2`, an
//! emitter's point-to-polygon form factor) over the receiver's (u, v) square by compass search
//! (Torczon 1997's pattern search: try a step along each axis, halve it when none improves,
//! down to the quadtree's lattice), started from the best of a 5 x 5 grid over the square and
//! the points where the light's centre projects onto the receiver's plane (the foot of the
//! perpendicular, and along the spot's axis or the emitter's normal). The search finds a local
//! maximum; one light's unoccluded transfer over a plane falls off away from one point (its
//! foot, pulled along the spot's axis or the emitter's normal), so that is the maximum over a
//! convex polygon, or on its border when the point lies outside. The projections start the
//! search inside a spot's footprint when that is smaller than the grid's spacing. Occluders are ignored: a peak in shadow has
//! nothing to find there, and the visibility test follows the shadow's edge.
//!
//! Only lights whose peak contribution could matter are searched: at least `threshold` (the
//! pass passes the smallest deviation its test could act on), so far lights cost a grid of
//! transfers per pair and nothing more.

use glam::DVec3;
use rayon::prelude::*;

use super::lum;
use super::poly::Poly;
use crate::transfer::{ShooterKind, Transfer};
use base::quadtree::{VertexKey, LATTICE};
use scene::{Polygon, Scene};

/// A light's peak may stand above the samples of the leaf holding it by at most this share of
/// the tolerance times the leaf's level before the leaf splits. The bilinear test allows a
/// deviation of the whole tolerance because the bicubic reconstruction recovers most of it
/// (at the default 0.01 an area light's floor comes out within 3e-4 of the peak); at a peak
/// missed by every sample there is nothing to recover (the limited reconstruction does not rise
/// above its samples), so the test there asks ten times more: 1e-3 of the level at the default.
pub(crate) const PEAK_SHARE: f64 = 0.1;

/// Grid of starting points per axis.
const GRID: usize = 5;

/// Per polygon, the lattice points where the lights that reach it (and have shot) peak, each at
/// least `threshold` there (reflected luminance), sorted and deduplicated.
pub(super) fn light_peaks(
    scene: &Scene,
    tr: &Transfer<'_>,
    totals: &[DVec3],
    polys: &[Poly],
    threshold: f64,
) -> Vec<Vec<VertexKey>> {
    (0..polys.len())
        .into_par_iter()
        .map(|r| {
            let rho = polys[r].rho;
            if rho.max_element() <= 0.0 {
                return Vec::new();
            }
            let mut keys: Vec<VertexKey> = tr
                .shooters_of(r)
                .iter()
                .filter(|&&(s, _)| {
                    !matches!(tr.shooters[s as usize].kind, ShooterKind::Patch { .. })
                        && totals[s as usize] != DVec3::ZERO
                })
                .filter_map(|&(s, _)| {
                    let s = s as usize;
                    let f = |u: f64, v: f64| lum(rho * totals[s] * tr.unoccluded(s, r, u, v));
                    let starts = projections(scene, tr, s, r);
                    let (u, v, best) = maximize(f, &starts);
                    (best >= threshold).then(|| lattice_key(u, v))
                })
                .collect();
            keys.sort_unstable();
            keys.dedup();
            keys
        })
        .collect()
}

/// The lattice point nearest (u, v) in [0, 1]^2.
fn lattice_key(u: f64, v: f64) -> VertexKey {
    let at = |x: f64| (x.clamp(0.0, 1.0) * LATTICE as f64).round() as u32;
    VertexKey::new(at(u), at(v))
}

/// Where light `s`'s centre projects onto polygon `r`'s plane, as (u, v) of `r`: the foot of
/// the perpendicular, and the hit of the spot's axis or the emitter's normal (if it meets the
/// plane in front of the light).
fn projections(scene: &Scene, tr: &Transfer<'_>, s: usize, r: usize) -> Vec<(f64, f64)> {
    let (centre, axis) = match tr.shooters[s].kind {
        ShooterKind::Spot { spot } => {
            let l = &scene.spots[spot as usize];
            (l.position, l.direction)
        }
        ShooterKind::Emitter { polygon } => {
            let p = &scene.polygons[polygon as usize];
            (p.centroid(), p.normal)
        }
        ShooterKind::Patch { .. } => return Vec::new(),
    };
    let p = &scene.polygons[r];
    let n = p.normal;
    let height = n.dot(centre - p.corners[0]);
    let mut out = vec![param_of(p, centre - height * n)];
    let along = n.dot(axis);
    if along != 0.0 && -height / along > 0.0 {
        out.push(param_of(p, centre - (height / along) * axis));
    }
    out
}

/// The (u, v) in [0, 1]^2 whose point of `p` is nearest `x` (a point of its plane), by
/// Gauss-Newton on the bilinear map from the centre, clamped to the square: exact for a
/// parallelogram in one step, a few steps otherwise. Only a starting point for the search, so
/// an approximate answer near a triangle's collapsed corner is harmless.
fn param_of(p: &Polygon, x: DVec3) -> (f64, f64) {
    let (mut u, mut v) = (0.5, 0.5);
    for _ in 0..8 {
        let d = p.point(u, v) - x;
        let (a, b) = p.tangents(u, v);
        let (aa, ab, bb) = (a.dot(a), a.dot(b), b.dot(b));
        let det = aa * bb - ab * ab;
        // A degenerate (or NaN) metric ends the iteration.
        if det.is_nan() || det <= 0.0 {
            break;
        }
        let (ra, rb) = (a.dot(d), b.dot(d));
        u = (u - (bb * ra - ab * rb) / det).clamp(0.0, 1.0);
        v = (v - (aa * rb - ab * ra) / det).clamp(0.0, 1.0);
    }
    (u, v)
}

/// The largest value of `f` over [0, 1]^2 and where: compass search from the best of a
/// [`GRID`] x [`GRID`] grid and `starts`, steps from 1/8 halved to one lattice step.
fn maximize(f: impl Fn(f64, f64) -> f64, starts: &[(f64, f64)]) -> (f64, f64, f64) {
    let grid = (0..GRID * GRID).map(|k| {
        let at = |i: usize| i as f64 / (GRID - 1) as f64;
        (at(k % GRID), at(k / GRID))
    });
    let mut best = (0.5, 0.5, f64::NEG_INFINITY);
    for (u, v) in grid.chain(starts.iter().copied()) {
        let y = f(u, v);
        if y > best.2 {
            best = (u, v, y);
        }
    }
    if best.2 <= 0.0 {
        return best;
    }
    let mut step = 0.125;
    let finest = 0.5 / LATTICE as f64;
    while step >= finest {
        let (u, v, y) = best;
        let moves = [(step, 0.0), (-step, 0.0), (0.0, step), (0.0, -step)];
        let better = moves
            .iter()
            .map(|&(du, dv)| {
                let (a, b) = ((u + du).clamp(0.0, 1.0), (v + dv).clamp(0.0, 1.0));
                (a, b, f(a, b))
            })
            .filter(|c| c.2 > y)
            .fold(None, |m: Option<(f64, f64, f64)>, c| match m {
                Some(m) if m.2 >= c.2 => Some(m),
                _ => Some(c),
            });
        match better {
            Some(c) => best = c,
            None => step *= 0.5,
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn compass_search_finds_a_narrow_peak_from_a_start_inside_it() {
        // A bump of width 1e-3 at (0.4137, 0.5821): the grid sees 0 everywhere, the start
        // inside the bump climbs to it within a lattice step.
        let (pu, pv) = (0.4137, 0.5821);
        let f = |u: f64, v: f64| {
            let r2 = (u - pu).powi(2) + (v - pv).powi(2);
            (1.0 - r2 / 1e-6).max(0.0)
        };
        let (u, v, y) = maximize(f, &[(0.4139, 0.5818)]);
        assert!((u - pu).abs() <= 1.0 / LATTICE as f64, "{u}");
        assert!((v - pv).abs() <= 1.0 / LATTICE as f64, "{v}");
        assert!(y > 0.99, "{y}");
        // Without the start, nothing is found (and nothing is claimed).
        assert_eq!(maximize(f, &[]).2, 0.0);
    }

    #[test]
    fn compass_search_finds_a_peak_on_the_border() {
        // Increasing in u, peaked in v at 0.3: the maximum sits on the edge u = 1.
        let f = |u: f64, v: f64| u - (v - 0.3).powi(2);
        let (u, v, _) = maximize(f, &[]);
        assert_eq!(u, 1.0);
        assert!((v - 0.3).abs() <= 1.0 / LATTICE as f64, "{v}");
    }

    #[test]
    fn param_of_inverts_the_bilinear_map() {
        let p = Polygon::quad(
            [
                DVec3::new(0.0, 0.0, 0.0),
                DVec3::new(2.0, 0.0, 0.0),
                DVec3::new(2.5, 1.5, 0.0),
                DVec3::new(-0.3, 1.0, 0.0),
            ],
            0,
            0,
        )
        .unwrap();
        for &(u, v) in &[(0.2, 0.7), (0.9, 0.1), (0.5, 0.5)] {
            let (a, b) = param_of(&p, p.point(u, v));
            assert!((a - u).abs() < 1e-9 && (b - v).abs() < 1e-9, "({a}, {b})");
        }
    }
}
