//! Bicubic Hermite patch maths in f64: the per-vertex Hermite data, the change from Hermite form
//! to power basis, and evaluation of a patch with its partial derivatives.
//!
//! Conventions: a patch over a square cell of width `w` uses local parameters
//! (s, t) in [0, 1]^2 with s = (u - u0) / w; its geometry matrix holds, at each corner, the value,
//! `w * f_u`, `w * f_v` and `w^2 * f_uv`, where f_u, f_v, f_uv are the *global* derivatives stored
//! once per vertex ([`HermiteData`]). Every patch touching a vertex therefore sees the same data,
//! only scaled to its own size, which is what makes the reconstruction C1 across patches of
//! different sizes. All of this runs in f64; only the finished power coefficients are stored as
//! f32.

use base::quadtree::Cell;

/// Hermite data of one vertex, per RGB channel, in global parameter units (derivatives with
/// respect to the polygon's u, v in [0, 1]).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(crate) struct HermiteData {
    /// Value.
    pub f: [f64; 3],
    /// df/du.
    pub fu: [f64; 3],
    /// df/dv.
    pub fv: [f64; 3],
    /// Twist d2f/dudv.
    pub fuv: [f64; 3],
}

/// Cubic Hermite basis in power form: row = basis function (value at 0, value at 1, derivative
/// at 0, derivative at 1), column = coefficient of t^0..t^3.
#[cfg(test)]
const HERMITE_TO_POWER: [[f64; 4]; 4] = [
    [1.0, 0.0, -3.0, 2.0],
    [0.0, 0.0, 3.0, -2.0],
    [0.0, 1.0, -2.0, 1.0],
    [0.0, 0.0, -1.0, 1.0],
];

/// The power coefficients (t^0..t^3) of the cubic with Hermite coefficients `x` (value at 0,
/// value at 1, derivative at 0, derivative at 1): `x` times the basis matrix (`HERMITE_TO_POWER`
/// in the tests), its zeros skipped.
#[inline(always)]
fn hermite_to_power(x: [f64; 4]) -> [f64; 4] {
    [
        x[0],
        x[2],
        -3.0 * x[0] + 3.0 * x[1] - 2.0 * x[2] - x[3],
        2.0 * x[0] - 2.0 * x[1] + x[2] + x[3],
    ]
}

/// One bicubic patch in f64 power basis: `c[ch][4 * j + i]` multiplies s^i t^j.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct PatchPoly {
    /// Power coefficients per channel.
    pub c: [[f64; 16]; 3],
    /// Lower-left corner u.
    pub u0: f64,
    /// Lower-left corner v.
    pub v0: f64,
    /// Cell width in parameter units.
    pub w: f64,
}

impl PatchPoly {
    /// The patch over `cell` interpolating `corners`, given in the order (0,0), (1,0), (0,1),
    /// (1,1) (index x + 2 y).
    pub(crate) fn from_corners(cell: Cell, corners: &[HermiteData; 4]) -> Self {
        let (u0, v0, _, _) = cell.bounds();
        let w = cell.width();
        let mut c = [[0.0f64; 16]; 3];
        for (ch, cc) in c.iter_mut().enumerate() {
            // Geometry matrix g[a][b]: a indexes the s basis, b the t basis.
            let mut g = [[0.0f64; 4]; 4];
            for y in 0..2 {
                for x in 0..2 {
                    let d = &corners[x + 2 * y];
                    g[x][y] = d.f[ch];
                    g[2 + x][y] = w * d.fu[ch];
                    g[x][2 + y] = w * d.fv[ch];
                    g[2 + x][2 + y] = w * w * d.fuv[ch];
                }
            }
            // c = H^T g H with H = HERMITE_TO_POWER, applied as its sparse closed form along t
            // (each row of g), then along s (each column): 64 operations instead of the dense
            // triple product, exact for the same inputs up to the order of two-term sums.
            let mut rows = [[0.0f64; 4]; 4];
            for (r, ga) in rows.iter_mut().zip(g.iter()) {
                *r = hermite_to_power(*ga);
            }
            for j in 0..4 {
                let col = hermite_to_power([rows[0][j], rows[1][j], rows[2][j], rows[3][j]]);
                for i in 0..4 {
                    cc[4 * j + i] = col[i];
                }
            }
        }
        PatchPoly { c, u0, v0, w }
    }

    /// Value and local partials `[f, f_s, f_t, f_st]` per channel at local (s, t).
    #[allow(clippy::needless_range_loop)] // one index over several per-channel arrays
    pub(crate) fn eval_local(&self, s: f64, t: f64) -> [[f64; 3]; 4] {
        let sp = [1.0, s, s * s, s * s * s];
        let tp = [1.0, t, t * t, t * t * t];
        let dsp = [0.0, 1.0, 2.0 * s, 3.0 * s * s];
        let dtp = [0.0, 1.0, 2.0 * t, 3.0 * t * t];
        let mut out = [[0.0f64; 3]; 4];
        for ch in 0..3 {
            let c = &self.c[ch];
            let (mut f, mut fs, mut ft, mut fst) = (0.0, 0.0, 0.0, 0.0);
            for j in 0..4 {
                for i in 0..4 {
                    let k = c[4 * j + i];
                    f += k * sp[i] * tp[j];
                    fs += k * dsp[i] * tp[j];
                    ft += k * sp[i] * dtp[j];
                    fst += k * dsp[i] * dtp[j];
                }
            }
            out[0][ch] = f;
            out[1][ch] = fs;
            out[2][ch] = ft;
            out[3][ch] = fst;
        }
        out
    }

    /// Hermite data of the patch polynomial at global (u, v), derivatives in global units.
    #[allow(clippy::needless_range_loop)] // one index over several per-channel arrays
    pub(crate) fn hermite_at(&self, u: f64, v: f64) -> HermiteData {
        let r = self.eval_local((u - self.u0) / self.w, (v - self.v0) / self.w);
        let inv = 1.0 / self.w;
        let mut d = HermiteData::default();
        for ch in 0..3 {
            d.f[ch] = r[0][ch];
            d.fu[ch] = r[1][ch] * inv;
            d.fv[ch] = r[2][ch] * inv;
            d.fuv[ch] = r[3][ch] * inv * inv;
        }
        d
    }

    /// Whether `d` equals this polynomial's data at (u, v) within `tol`, comparing the value and
    /// the derivatives scaled to this patch (w f_u, w f_v, w^2 f_uv), so that all four are in
    /// units of the value.
    pub(crate) fn agrees_with(&self, u: f64, v: f64, d: &HermiteData, tol: f64) -> bool {
        let p = self.hermite_at(u, v);
        let w = self.w;
        (0..3).all(|ch| {
            (p.f[ch] - d.f[ch]).abs() <= tol
                && (w * (p.fu[ch] - d.fu[ch])).abs() <= tol
                && (w * (p.fv[ch] - d.fv[ch])).abs() <= tol
                && (w * w * (p.fuv[ch] - d.fuv[ch])).abs() <= tol
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn data(f: f64, fu: f64, fv: f64, fuv: f64) -> HermiteData {
        HermiteData {
            f: [f; 3],
            fu: [fu; 3],
            fv: [fv; 3],
            fuv: [fuv; 3],
        }
    }

    #[test]
    fn patch_interpolates_its_corner_data() {
        // A level-2 cell: w = 1/4, so local derivatives are w times the global ones.
        let cell = Cell {
            level: 2,
            x: 1,
            y: 2,
        };
        let corners = [
            data(1.0, 2.0, -1.0, 0.5),
            data(-3.0, 0.25, 4.0, -2.0),
            data(0.5, -1.5, 3.0, 8.0),
            data(2.0, 1.0, 1.0, 1.0),
        ];
        let p = PatchPoly::from_corners(cell, &corners);
        let (u0, v0, u1, v1) = cell.bounds();
        for (k, (u, v)) in [(u0, v0), (u1, v0), (u0, v1), (u1, v1)].iter().enumerate() {
            let d = p.hermite_at(*u, *v);
            // Sums of a dozen O(10) terms in f64: error well below 1e-12.
            for ch in 0..3 {
                assert!((d.f[ch] - corners[k].f[ch]).abs() < 1e-12);
                assert!((d.fu[ch] - corners[k].fu[ch]).abs() < 1e-11);
                assert!((d.fv[ch] - corners[k].fv[ch]).abs() < 1e-11);
                assert!((d.fuv[ch] - corners[k].fuv[ch]).abs() < 1e-10);
            }
        }
    }

    #[test]
    fn bilinear_data_give_the_bilinear_polynomial() {
        // f = 1 + 2u + 3v + 4uv over the root: Hermite data exact, so the power coefficients are
        // exactly those of f (c00 = 1, c10 = 2, c01 = 3, c11 = 4, rest 0).
        let f = |u: f64, v: f64| {
            data(
                1.0 + 2.0 * u + 3.0 * v + 4.0 * u * v,
                2.0 + 4.0 * v,
                3.0 + 4.0 * u,
                4.0,
            )
        };
        let p = PatchPoly::from_corners(Cell::ROOT, &[f(0., 0.), f(1., 0.), f(0., 1.), f(1., 1.)]);
        let mut want = [0.0; 16];
        want[0] = 1.0;
        want[1] = 2.0;
        want[4] = 3.0;
        want[5] = 4.0;
        for ch in 0..3 {
            for (k, (got, want)) in p.c[ch].iter().zip(want).enumerate() {
                assert!((got - want).abs() < 1e-14, "c[{k}] = {got}");
            }
        }
    }
}

#[cfg(test)]
mod sparse_tests {
    use super::*;

    #[test]
    fn sparse_basis_change_equals_the_matrix_product() {
        // Dyadic inputs: every product and sum is exact, so the two forms agree bit for bit.
        for k in 0..64u32 {
            let x = [
                (k % 5) as f64 - 2.0,
                (k % 7) as f64 * 0.5,
                (k % 3) as f64 - 0.25,
                (k / 8) as f64 * 0.125,
            ];
            let mut want = [0.0f64; 4];
            for (j, w) in want.iter_mut().enumerate() {
                for (b, xb) in x.iter().enumerate() {
                    *w += xb * HERMITE_TO_POWER[b][j];
                }
            }
            assert_eq!(hermite_to_power(x), want, "{x:?}");
        }
    }
}
