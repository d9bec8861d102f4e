//! Derivative estimation: the Hermite data (value, f_u, f_v, f_uv) of every original sample of one
//! polygon, computed from the samples alone, before any T-vertex refinement.
//!
//! Both estimators difference `g`, the piecewise-bilinear interpolant of the samples (the value of
//! the leaf containing a point, bilinear from that leaf's four corner samples; at a sample point it
//! is the sample itself), at a step `h` = width of the smallest leaf having the vertex as a corner.
//! Stepping by `h` keeps every probe on the lattice and inside leaves adjacent to the vertex, so:
//! - on a regular grid the plain estimator is exactly the usual central differences (the patches
//!   are tensor-product Catmull-Rom there);
//! - linear functions are reproduced exactly (g is exact for them, and so are its differences);
//! - an undivided polygon gets the one-sided differences of its corners, which with the twist
//!   (f11 - f10 - f01 + f00) are exactly the data of the bilinear interpolant.
//!
//! At the domain border the difference is one-sided. The monotone estimator replaces each axis'
//! central difference by the Fritsch-Butland harmonic mean of the two secants (0 when they differ
//! in sign), and sets the twist to 0 where either axis was limited (see [`limited`]).
//!
//! **Every leaf edge at a vertex.** The step `h` is the smallest leaf's, but the slope is also
//! used by every larger leaf that has the vertex as a corner, across that leaf's whole edge. An
//! unrestricted tree puts a level-2 leaf beside a level-9 band along a spot's cone edge: a slope
//! that is monotone over the band's tiny secants is many times the large leaf's own secant, and
//! the large patch overshot its corners by 6x the polygon's range. So the limited estimators then
//! clip each slope into Fritsch and Carlson's monotone region of *every* leaf edge it starts:
//! between 0 and 3 times that edge's secant ([`EdgeSecants`]; 0 where the secants differ in
//! sign), which keeps each edge cubic monotone between its corners (Fritsch & Carlson 1980: slopes
//! in [0, 3] times the secant at both ends suffice). On a uniform grid every edge at a vertex is
//! one of its two `h`-secants and the clip never acts.

use super::hermite::HermiteData;
use super::Estimator;
use base::quadtree::{Cell, Quadtree, VertexKey, LATTICE, MAX_DEPTH};

/// The samples of one polygon in f64, with lookups by lattice point.
pub(crate) struct Samples<'a> {
    tree: &'a Quadtree,
    keys: &'a [VertexKey],
    values: Vec<[f64; 3]>,
}

impl<'a> Samples<'a> {
    /// Wraps validated samples: `keys` sorted, unique, equal to `tree.vertex_keys()`.
    pub(crate) fn new(tree: &'a Quadtree, keys: &'a [VertexKey], values: Vec<[f64; 3]>) -> Self {
        Samples { tree, keys, values }
    }

    fn index(&self, k: VertexKey) -> Option<usize> {
        self.keys.binary_search(&k).ok()
    }

    /// The leaf cell containing lattice point (i, j); on shared edges the upper cell, at the
    /// domain's upper border the last cell (the convention of `Quadtree::find_leaf`).
    pub(crate) fn leaf_cell(&self, i: u32, j: u32) -> Cell {
        leaf_cell(self.tree, i, j)
    }

    fn value(&self, k: VertexKey) -> [f64; 3] {
        // Every leaf corner is a key (validated by the caller), so the fallback never runs.
        self.index(k).map_or([0.0; 3], |x| self.values[x])
    }

    /// The piecewise-bilinear interpolant g at lattice point (i, j).
    pub(crate) fn g(&self, i: u32, j: u32) -> [f64; 3] {
        let k = VertexKey::new(i, j);
        if let Some(x) = self.index(k) {
            return self.values[x];
        }
        let cell = self.leaf_cell(i, j);
        let o = cell.origin();
        let size = cell.size() as f64;
        let s = (i - o.i) as f64 / size;
        let t = (j - o.j) as f64 / size;
        let [c00, c10, c11, c01] = cell.corners().map(|c| self.value(c));
        let mut out = [0.0; 3];
        for ch in 0..3 {
            let bottom = c00[ch] + s * (c10[ch] - c00[ch]);
            let top = c01[ch] + s * (c11[ch] - c01[ch]);
            out[ch] = bottom + t * (top - bottom);
        }
        out
    }

    /// Width (lattice units) of the smallest leaf having each key as a corner.
    pub(crate) fn min_leaf_sizes(&self) -> Vec<u32> {
        let mut h = vec![LATTICE; self.keys.len()];
        for n in self.tree.nodes().iter().filter(|n| n.is_leaf()) {
            for c in n.cell.corners() {
                if let Some(x) = self.index(c) {
                    h[x] = h[x].min(n.cell.size());
                }
            }
        }
        h
    }
}

/// The leaf cell of `tree` containing lattice point (i, j); on shared edges the upper cell, at
/// the domain's upper border the last cell (the convention of `Quadtree::find_leaf`).
pub(crate) fn leaf_cell(tree: &Quadtree, i: u32, j: u32) -> Cell {
    let (i, j) = (i.min(LATTICE - 1), j.min(LATTICE - 1));
    let nodes = tree.nodes();
    let mut id = 0usize;
    loop {
        let n = nodes[id];
        if n.is_leaf() {
            return n.cell;
        }
        let sh = MAX_DEPTH - 1 - n.cell.level;
        id = n.first_child as usize + ((i >> sh) & 1) as usize + 2 * ((j >> sh) & 1) as usize;
    }
}

/// Fritsch-Butland slope from the two secants: their harmonic mean when they have the same sign,
/// else 0. Written as `d0 * (2 d1 / (d0 + d1))`: with equal signs |d0 + d1| >= |d1|, so the
/// factor lies in (0, 2) and nothing overflows or divides by zero, however small or large the
/// secants are.
pub(crate) fn fritsch_butland(d0: f64, d1: f64) -> f64 {
    if (d0 > 0.0 && d1 > 0.0) || (d0 < 0.0 && d1 < 0.0) {
        d0 * (2.0 * d1 / (d0 + d1))
    } else {
        0.0
    }
}

/// Whether the limiter acted on this axis enough to distrust the twist: the secants differ in
/// sign or one is zero (slope forced to 0), or one is more than twice the other (the harmonic
/// mean is then more than 11 % below the central difference: a kink, not a smooth slope).
pub(crate) fn limited(d0: f64, d1: f64) -> bool {
    let (a, b) = (d0.abs(), d1.abs());
    fritsch_butland(d0, d1) == 0.0 || a > 2.0 * b || b > 2.0 * a
}

/// Hyman's filter of the central slope (Hyman 1983): the central difference `(d0 + d1) / 2`
/// where the two secants have the same sign, clipped to `3 min(|d0|, |d1|)` (the radius of
/// Fritsch and Carlson's monotone region), and 0 where they differ in sign or one is zero (the
/// data turn there, and a zero slope cannot overshoot them). Returns the slope and whether the
/// filter changed the central difference (then the twist is not trusted either). Written as
/// `0.5 d0 + 0.5 d1` so nothing overflows for finite secants.
pub(crate) fn hyman(d0: f64, d1: f64) -> (f64, bool) {
    let c = 0.5 * d0 + 0.5 * d1;
    if (d0 > 0.0 && d1 > 0.0) || (d0 < 0.0 && d1 < 0.0) {
        let m = 3.0 * d0.abs().min(d1.abs());
        if c.abs() > m {
            (m.copysign(c), true)
        } else {
            (c, false)
        }
    } else if d0 == 0.0 && d1 == 0.0 {
        (0.0, false)
    } else {
        (0.0, true)
    }
}

/// Per vertex, axis (u, v) and channel: the smallest and largest secant of the leaf edges that
/// start at the vertex along that axis (either direction), over every leaf having the vertex as
/// a corner.
struct EdgeSecants(Vec<[[(f64, f64); 3]; 2]>);

impl EdgeSecants {
    fn of(s: &Samples<'_>) -> Self {
        let mut out = vec![[[(f64::INFINITY, f64::NEG_INFINITY); 3]; 2]; s.keys.len()];
        let l = LATTICE as f64;
        for n in s.tree.nodes().iter().filter(|n| n.is_leaf()) {
            let [c00, c10, c11, c01] = n.cell.corners().map(|c| s.index(c));
            let w = n.cell.size() as f64 / l;
            // Each edge once, along its axis; its secant is the same from either end.
            for (a, b, axis) in [(c00, c10, 0), (c01, c11, 0), (c00, c01, 1), (c10, c11, 1)] {
                let (Some(a), Some(b)) = (a, b) else { continue };
                let (va, vb) = (s.values[a], s.values[b]);
                let secants: [f64; 3] = std::array::from_fn(|ch| (vb[ch] - va[ch]) / w);
                for x in [a, b] {
                    for (range, sec) in out[x][axis].iter_mut().zip(secants) {
                        range.0 = range.0.min(sec);
                        range.1 = range.1.max(sec);
                    }
                }
            }
        }
        EdgeSecants(out)
    }

    /// Clips slope `d` of vertex `x` on `axis`, channel `ch`, into the monotone region of every
    /// leaf edge it starts; returns the slope and whether the clip changed it.
    fn clip(&self, x: usize, axis: usize, ch: usize, d: f64) -> (f64, bool) {
        let (lo, hi) = self.0[x][axis][ch];
        let c = if lo > 0.0 {
            d.clamp(0.0, 3.0 * lo)
        } else if hi < 0.0 {
            d.clamp(3.0 * hi, 0.0)
        } else if lo > hi {
            // No leaf edge along this axis (never for a validated tree): nothing to clip to.
            d
        } else {
            0.0
        };
        (c, c != d)
    }
}

/// Hermite data of every sample, in key order.
pub(crate) fn estimate(s: &Samples<'_>, estimator: Estimator) -> Vec<HermiteData> {
    let h_of = s.min_leaf_sizes();
    let secants = match estimator {
        Estimator::Plain => None,
        Estimator::Monotone | Estimator::Hyman => Some(EdgeSecants::of(s)),
    };
    let l = LATTICE as f64;
    s.keys
        .iter()
        .enumerate()
        .map(|(x, &k)| {
            let h = h_of[x];
            // k is a corner of a leaf of width h, so its coordinates are multiples of h and the
            // probes k +- h stay on the lattice; at the border they collapse onto k.
            let ip = (k.i + h).min(LATTICE);
            let im = k.i.saturating_sub(h);
            let jp = (k.j + h).min(LATTICE);
            let jm = k.j.saturating_sub(h);
            let du = (ip - im) as f64 / l;
            let dv = (jp - jm) as f64 / l;
            let hh = h as f64 / l;
            let fc = s.values[x];
            let (gi_p, gi_m) = (s.g(ip, k.j), s.g(im, k.j));
            let (gj_p, gj_m) = (s.g(k.i, jp), s.g(k.i, jm));
            let (gpp, gpm) = (s.g(ip, jp), s.g(ip, jm));
            let (gmp, gmm) = (s.g(im, jp), s.g(im, jm));
            let mut d = HermiteData {
                f: fc,
                ..HermiteData::default()
            };
            for ch in 0..3 {
                let twist = (gpp[ch] - gpm[ch] - gmp[ch] + gmm[ch]) / (du * dv);
                match estimator {
                    Estimator::Plain => {
                        d.fu[ch] = (gi_p[ch] - gi_m[ch]) / du;
                        d.fv[ch] = (gj_p[ch] - gj_m[ch]) / dv;
                        d.fuv[ch] = twist;
                    }
                    Estimator::Monotone | Estimator::Hyman => {
                        let axis = |gm: f64, gp: f64, lo: bool, hi: bool, step: f64| {
                            if lo || hi {
                                // One-sided secant at the border: never limited.
                                ((gp - gm) / step, false)
                            } else {
                                let d0 = (fc[ch] - gm) / hh;
                                let d1 = (gp - fc[ch]) / hh;
                                if estimator == Estimator::Hyman {
                                    (hyman(d0, d1).0, limited(d0, d1))
                                } else {
                                    (fritsch_butland(d0, d1), limited(d0, d1))
                                }
                            }
                        };
                        let (fu, lu) = axis(gi_m[ch], gi_p[ch], im == k.i, ip == k.i, du);
                        let (fv, lv) = axis(gj_m[ch], gj_p[ch], jm == k.j, jp == k.j, dv);
                        let edges = secants.as_ref().expect("limited estimators have secants");
                        let (fu, cu) = edges.clip(x, 0, ch, fu);
                        let (fv, cv) = edges.clip(x, 1, ch, fv);
                        d.fu[ch] = fu;
                        d.fv[ch] = fv;
                        d.fuv[ch] = if lu || lv || cu || cv { 0.0 } else { twist };
                    }
                }
            }
            d
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fritsch_butland_is_guarded() {
        assert_eq!(fritsch_butland(1.0, 1.0), 1.0);
        // Harmonic mean of 1 and 3 is 1.5.
        assert!((fritsch_butland(1.0, 3.0) - 1.5).abs() < 1e-15);
        assert_eq!(fritsch_butland(1.0, -1.0), 0.0);
        assert_eq!(fritsch_butland(0.0, 5.0), 0.0);
        assert_eq!(fritsch_butland(-0.0, 0.0), 0.0);
        let tiny = fritsch_butland(1e-300, 1e-300);
        assert!(tiny.is_finite() && (tiny - 1e-300).abs() < 1e-310);
        let huge = fritsch_butland(1e300, 1e300);
        assert!(huge.is_finite() && (huge / 1e300 - 1.0).abs() < 1e-15);
        assert!(limited(1.0, 2.5) && !limited(1.0, 1.9) && limited(0.0, 1.0));
    }

    #[test]
    fn hyman_keeps_smooth_slopes_and_clips_steps() {
        // Smooth: the central difference, untouched.
        assert_eq!(hyman(1.0, 2.0), (1.5, false));
        assert_eq!(hyman(-2.0, -1.0), (-1.5, false));
        // A step next to flat data: clipped to 3x the smaller secant.
        assert_eq!(hyman(0.1, 10.0), (0.30000000000000004, true));
        // Turning or starting: 0.
        assert_eq!(hyman(1.0, -1.0), (0.0, true));
        assert_eq!(hyman(0.0, 1.0), (0.0, true));
        assert_eq!(hyman(0.0, 0.0), (0.0, false));
        // No overflow at the ends of the f64 range.
        let (s, _) = hyman(1e308, 1.5e308);
        assert!(s.is_finite() && s > 1e308);
    }
}
