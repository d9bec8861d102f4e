//! The compact RRPs' error bound against the unquantized reference: each stored quantity's
//! quantization error, propagated to derived vertices through the Hermite basis in absolute
//! value, then to a patch's values over its cell (docs/compact-rrps.md, Error bound).

use super::*;

impl CompactReconstruction {
    /// Per vertex of polygon `p` (local indices) and quantity, a bound on |held - reference|:
    /// `seed(global vertex, q)` at stored vertices; at derived ones the larger leaf's corner
    /// bounds through [`hermite_abs`], plus `rounding` times the held value and 2^-40 times
    /// the |basis|-weighted sum of the larger leaf's held data (its f64 evaluation).
    pub(crate) fn propagated_errors(
        &self,
        p: usize,
        seed: impl Fn(usize, usize) -> f64,
        rounding: f64,
    ) -> Vec<[f64; QUANTITIES]> {
        let layout = Layout::of(&self.polygon_tree(p));
        let first = self.first_vertex[p] as usize;
        let held = |v: usize| self.vertices[first + v].map(|x| (x as f64).abs());
        let mut err: Vec<[f64; QUANTITIES]> = (0..layout.keys.len())
            .map(|v| std::array::from_fn(|q| seed(first + v, q)))
            .collect();
        for &(l, v) in &layout.derived {
            let (cell, corners) = layout.leaves[l as usize];
            let (u0, v0, _, _) = cell.bounds();
            let w = cell.width();
            let k = layout.keys[v as usize];
            let (s, t) = ((k.u() - u0) / w, (k.v() - v0) / w);
            let own = held(v as usize);
            let mut out = [0.0f64; QUANTITIES];
            for ch in 0..3 {
                let e = corners.map(|c| channel(&err[c as usize], ch));
                let m = corners.map(|c| channel(&held(c as usize), ch));
                let (pe, pm) = (hermite_abs(w, s, t, &e), hermite_abs(w, s, t, &m));
                for kind in 0..4 {
                    let q = 3 * kind + ch;
                    out[q] = pe[kind] + rounding * own[q] + 2f64.powi(-40) * pm[kind];
                }
            }
            err[v as usize] = out;
        }
        err
    }

    /// Per vertex of polygon `p`, the module docs' bound on |held - reference| per quantity.
    fn vertex_errors(&self, p: usize) -> Vec<[f64; QUANTITIES]> {
        let scales = self.scales[p];
        let seed = |v: usize, q: usize| {
            let x = self.vertices[v][q] as f64;
            match quantize(x, scales[q]) {
                (0, _) => scales[q] * 2f64.powi(-15) + 2f64.powi(-124),
                (_, s) => 0.5 * scales[q] * pow2_neg(s) + 2f64.powi(-23) * x.abs(),
            }
        };
        self.propagated_errors(p, seed, 2f64.powi(-23))
    }

    /// The module docs' bound on |expanded patch - reference patch| per channel over leaf `id`'s
    /// cell, in exact arithmetic (f32 rounding of the expansions not included):
    /// `df + (w/4)(dfu + dfv) + (w^2/16) dfuv`, dq the largest error of quantity q over the
    /// leaf's corners. Computed on demand from the whole polygon (for tests and measurements;
    /// [`Self::error_bounds`] gives every leaf of a polygon at once).
    pub fn error_bound(&self, id: u32) -> [f64; 3] {
        let p = self.leaves[id as usize].polygon();
        self.leaf_bound(id, &self.vertex_errors(p))
    }

    /// [`Self::error_bound`] of every leaf of `polygon`, in leaf id order.
    pub fn error_bounds(&self, polygon: u32) -> Vec<[f64; 3]> {
        let p = polygon as usize;
        let err = self.vertex_errors(p);
        self.polygon_nodes(p)
            .iter()
            .filter(|&&e| e & LEAF != 0)
            .map(|&e| self.leaf_bound(e & !LEAF, &err))
            .collect()
    }

    /// The bound of leaf `id` from its polygon's vertex errors.
    fn leaf_bound(&self, id: u32, err: &[[f64; QUANTITIES]]) -> [f64; 3] {
        let l = &self.leaves[id as usize];
        let first = self.first_vertex[l.polygon()];
        let w = l.cell().width();
        let worst = |q: usize| {
            l.corners
                .iter()
                .map(|&c| err[(c - first) as usize][q])
                .fold(0.0f64, f64::max)
        };
        std::array::from_fn(|ch| {
            worst(ch) + w / 4.0 * (worst(3 + ch) + worst(6 + ch)) + w * w / 16.0 * worst(9 + ch)
        })
    }
}

/// The cubic Hermite basis (h00, h01, h10, h11) at s and its derivative, in absolute value.
fn abs_basis(s: f64) -> ([f64; 4], [f64; 4]) {
    let (s2, s3) = (s * s, s * s * s);
    let h = [
        2.0 * s3 - 3.0 * s2 + 1.0,
        -2.0 * s3 + 3.0 * s2,
        s3 - 2.0 * s2 + s,
        s3 - s2,
    ];
    let d = [
        6.0 * s2 - 6.0 * s,
        -6.0 * s2 + 6.0 * s,
        3.0 * s2 - 4.0 * s + 1.0,
        3.0 * s2 - 2.0 * s,
    ];
    (h.map(f64::abs), d.map(f64::abs))
}

/// `sum_ab |B_a(s)| |B_b(t)| e_ab` for the value and the partials (f, f_u, f_v, f_uv, global
/// units) of a patch of width `w` at local (s, t), where e holds non-negative per-corner
/// magnitudes (corner order x + 2y) of one channel's (f, f_u, f_v, f_uv): the triangle
/// inequality's bound on the change of the patch's Hermite data at (s, t) when each corner
/// quantity changes by at most its e.
fn hermite_abs(w: f64, s: f64, t: f64, e: &[[f64; 4]; 4]) -> [f64; 4] {
    let ((hs, ds), (ht, dt)) = (abs_basis(s), abs_basis(t));
    let mut out = [0.0f64; 4];
    for (c, ec) in e.iter().enumerate() {
        let (x, y) = (c & 1, c >> 1);
        // Geometry entries (s basis index, t basis index, magnitude).
        let g = [
            (x, y, ec[0]),
            (2 + x, y, w * ec[1]),
            (x, 2 + y, w * ec[2]),
            (2 + x, 2 + y, w * w * ec[3]),
        ];
        for (a, b, m) in g {
            out[0] += hs[a] * ht[b] * m;
            out[1] += ds[a] * ht[b] * m;
            out[2] += hs[a] * dt[b] * m;
            out[3] += ds[a] * dt[b] * m;
        }
    }
    [out[0], out[1] / w, out[2] / w, out[3] / (w * w)]
}

/// One channel's (f, f_u, f_v, f_uv) of 12 per-vertex numbers.
fn channel(x: &[f64; QUANTITIES], ch: usize) -> [f64; 4] {
    [x[ch], x[3 + ch], x[6 + ch], x[9 + ch]]
}
