//! The error tests a leaf is judged by, from the light at its corners and test points: how far
//! the light departs from the corners' bilinear prediction, how far it peaks between them, and
//! how large a step a shadow's boundary (and the edge of an area light's penumbra) makes across
//! it. Pure functions of the sampled values, so that what decides a split reads in one place;
//! the parent module applies them against the tolerance and the guards.

use glam::DVec3;

use super::{leaf_points, lum, Probes};
use base::quadtree::Cell;

/// Whether rho * G at the test points `tests` (centre, edge midpoints) differs from the
/// bilinear prediction of the `corners` by more than `threshold` (luminance of the per-channel
/// difference) at any of them.
pub(super) fn deviation(rho: DVec3, corners: &[DVec3; 4], tests: &[DVec3; 5]) -> f64 {
    let c = corners;
    let predicted = [
        0.25 * (c[0] + c[1] + c[2] + c[3]),
        0.5 * (c[0] + c[1]),
        0.5 * (c[1] + c[2]),
        0.5 * (c[2] + c[3]),
        0.5 * (c[3] + c[0]),
    ];
    tests
        .iter()
        .zip(predicted)
        .map(|(g, pr)| lum((rho * (*g - pr)).abs()))
        .fold(0.0, f64::max)
}

/// How far an extremum inside a leaf stands beyond the samples its corners give, estimated
/// from the parabola through the three points of each of its six lines (the four edges and the
/// two lines through the centre; `corners` and `tests` are luminances in [`leaf_points`]
/// order): 0 where each line's middle value lies between its ends. The reconstruction's
/// limiter sets the slope to zero at a sample whose neighbours both lie below it (or both
/// above), so such a leaf is drawn no higher than its highest corner: a maximum or a minimum
/// between the samples (a light's peak or the ridge through it, off the lattice) would be
/// clipped by this much. With ends a, b and middle m at t = -1, 1, 0, the parabola's extremum
/// is m + (b - a)^2 / (8 (2m - a - b)), and the excess is its distance beyond a and b.
pub(super) fn extremum_between(corners: &[f64], tests: &[f64]) -> f64 {
    let (c, t) = (corners, tests);
    let lines = [
        (c[0], t[1], c[1]),
        (c[3], t[3], c[2]),
        (c[0], t[4], c[3]),
        (c[1], t[2], c[2]),
        (t[4], t[0], t[2]),
        (t[1], t[0], t[3]),
    ];
    lines
        .iter()
        .map(|&(a, m, b)| {
            let (lo, hi) = (a.min(b), a.max(b));
            let curve = 2.0 * m - a - b;
            if m > hi {
                m - hi + (b - a) * (b - a) / (8.0 * curve)
            } else if m < lo {
                lo - m + (b - a) * (b - a) / (8.0 * -curve)
            } else {
                0.0
            }
        })
        .fold(0.0, f64::max)
}

/// The largest step a shadow boundary makes across leaf `cell` of polygon `r`: over its shadow
/// lights, the light's largest unshadowed contribution at the leaf's points times the spread of
/// its visible fraction there (0 where no boundary crosses); and the same over the area
/// emitters (`area(j)` of shadow light `j`) whose shadow's **edge** crosses the leaf: the
/// leaf's points are not all in one state of lit (fraction 1), umbra (0) and penumbra
/// (between), so a penumbra's outer or inner edge lies in it. There the light has a kink or a
/// step, which the C1 patches round off over about one element; inside a penumbra it is
/// smooth. A spot's hard shadow is not counted there: the reconstruction draws it exactly from
/// the spot's own light (`reconstruction::sharp`).
pub(super) fn shadow_step(
    probes: &Probes,
    r: u32,
    cell: Cell,
    area: impl Fn(usize) -> bool,
) -> (f64, f64) {
    let points: Vec<&[(f64, f64)]> = leaf_points(cell).map(|k| probes.shadows_at(r, k)).collect();
    let lights = points.first().map_or(0, |v| v.len());
    let state = |v: f64| {
        if v <= SHADOW_STATE_EPS {
            0u8
        } else if v >= 1.0 - SHADOW_STATE_EPS {
            2
        } else {
            1
        }
    };
    (0..lights)
        .map(|j| {
            let (mut lo, mut hi, mut open) = (f64::INFINITY, f64::NEG_INFINITY, 0f64);
            let mut states = 0u8;
            for q in &points {
                let (a, v) = q[j];
                lo = lo.min(v);
                hi = hi.max(v);
                open = open.max(a);
                states |= 1 << state(v);
            }
            let step = if hi > lo { open * (hi - lo) } else { 0.0 };
            let edge = if states.count_ones() > 1 && area(j) {
                step
            } else {
                0.0
            };
            (step, edge)
        })
        .fold((0.0, 0.0), |(s, e), (a, b)| (s.max(a), e.max(b)))
}

/// Visible fractions within this of 0 or 1 count as umbra or lit ([`shadow_step`]): the exact
/// visibility gives 0 and 1 there, up to rounding.
const SHADOW_STATE_EPS: f64 = 1e-9;
