//! Tests of the compact reconstruction: its quantization bound, relative precision, continuity
//! at T-vertices, scaling, encoding and patch cache, against the expanded [`Reconstruction`]
//! built from the same samples.

use super::*;
use crate::compact::{reference_polys, CompactReconstruction, PatchCache, CACHE_SLOTS};
use crate::hermite::HermiteData;
use crate::refine::MERGE_TOL;

const MAGIC: &[u8; 8] = b"PFRRPC02";

fn compact1(sq: &SampledQuadtree, e: Estimator) -> CompactReconstruction {
    CompactReconstruction::build(std::slice::from_ref(sq), e).unwrap()
}

/// Leaf id (rank among leaves in node order) of every leaf node of a one-polygon tree.
fn leaf_ids(tree: &Quadtree) -> std::collections::HashMap<u32, u32> {
    (0u32..)
        .zip(tree.nodes())
        .filter(|(_, n)| n.is_leaf())
        .map(|(id, _)| id)
        .zip(0u32..)
        .collect()
}

/// Sum of |coefficients| of channel `ch`: with all monomials in [0, 1], rounding the patch's
/// coefficients to f32 moves its value by at most 2^-24 times this.
fn abs_sum(p: &PatchCoeffs, ch: usize) -> f64 {
    p.c[ch].iter().map(|x| x.abs() as f64).sum()
}

/// Largest |f| + w |f_u| + w |f_v| + w^2 |f_uv| over the corners and channels of a patch of
/// width w: the size of its geometry entries.
fn geometry_size(corners: &[HermiteData; 4], w: f64) -> f64 {
    let mut g = 0.0f64;
    for d in corners {
        for ch in 0..3 {
            let x = d.f[ch].abs() + w * (d.fu[ch].abs() + d.fv[ch].abs()) + w * w * d.fuv[ch].abs();
            g = g.max(x);
        }
    }
    g
}

/// Allowance for a jump of the compact patches across the edge of leaves `a` and `b` (node ids
/// of `tree`), in value and size-scaled derivative. Where both sides share the edge's end
/// vertices the data are identical. Along an edge of a larger leaf X, the smaller leaf's edge
/// endpoints carry X's edge cubics rounded to f32, each quantity off by at most 2^-24 of
/// itself, so with G the larger of the two patches' geometry sizes the smaller side's edge
/// value moves by <= 2^-24 (1 + 1/4) G, its size-scaled along-edge derivative by
/// <= 2^-24 (3 + 1) G (sum |h00'| + |h01'| <= 3, |h10'| + |h11'| <= 1) and the cross
/// derivative by <= 2^-24 (1 + 1/4) G: 4 * 2^-24 G. Twice that covers the f64 evaluation of
/// both sides (relative 1e-15 of sums of at most 81 G).
fn rounding_jump<'a>(
    c: &'a CompactReconstruction,
    tree: &'a Quadtree,
) -> impl Fn(u32, u32, f64) -> (f64, f64) + 'a {
    let ids = leaf_ids(tree);
    move |a, b, _ws| {
        let g = |n: u32| geometry_size(&c.corner_data(ids[&n]), tree.node(n).cell.width());
        let allow = 8.0 * 2f64.powi(-24) * g(a).max(g(b));
        (allow, allow)
    }
}

/// Compact patches are the reference patches (unquantized data, derived vertices from the larger
/// leaf) within the module docs' bound everywhere on a grid of points per leaf; the reference is
/// Reconstruction's patches up to refinement's merge tolerance; `locate` and the cells are
/// Reconstruction's; the compact patches are C1 to rounding.
fn check_compact_against_reconstruction(sq: &SampledQuadtree, e: Estimator, pts: &[(f32, f32)]) {
    use crate::PatchSource;
    let rec = build1(sq, e);
    let c = compact1(sq, e);
    let p = build_polygon(0, sq, e).unwrap();
    let reference = reference_polys(&p);
    let tree = &p.refined.tree;
    // Leaf ids are ranks in node order.
    let leaf_nodes: Vec<u32> = (0u32..)
        .zip(tree.nodes())
        .filter(|(_, n)| n.is_leaf())
        .map(|(id, _)| id)
        .collect();
    assert_eq!(c.polygon_count(), 1);
    assert_eq!(c.leaf_count(), rec.patches().len());
    assert_eq!(reference.len(), c.leaf_count());
    let scale = sq
        .values
        .iter()
        .map(|v| v.abs().max_element())
        .fold(0.0f32, f32::max) as f64;
    // Refinement keeps a merged node's inner data within MERGE_TOL * scale of its cubic (value
    // and size-scaled derivatives) per merged level, and inside a smaller patch the Hermite
    // basis weighs value, two derivatives and twist by at most 1 + 1/4 + 1/4 + 1/16 < 2: per
    // level of the tree at most 2 MERGE_TOL * scale between the reference and Reconstruction.
    let merge_allow = 2.0 * MERGE_TOL * scale * (tree.depth() + 1) as f64;
    let bounds = c.error_bounds(0);
    for id in 0..c.leaf_count() as u32 {
        let (a, b) = (c.expand(id), *rec.patch(id));
        assert_eq!(PatchSource::cell(&c, id), PatchSource::cell(&rec, id));
        assert_eq!((a.u0, a.v0, a.inv_w), (b.u0, b.v0, b.inv_w));
        assert!(a.is_finite());
        let bound = bounds[id as usize];
        assert_eq!(bound, c.error_bound(id));
        let unq = p.poly(leaf_nodes[id as usize]);
        let r = &reference[id as usize];
        let w = 1.0 / b.inv_w as f64;
        for i in 0..=6 {
            for j in 0..=6 {
                let (s, t) = (i as f64 / 6.0, j as f64 / 6.0);
                let (u, v) = (b.u0 as f64 + w * s, b.v0 as f64 + w * t);
                let (fa, _, _) = a.eval_grad_f64(u, v);
                let fr = r.eval_local(s, t)[0];
                let fu = unq.eval_local(s, t)[0];
                for ch in 0..3 {
                    // f32 coefficient rounding of the compact patch, plus f64 rounding (1e-12 of
                    // the same sums covers the f64 expansion and evaluation of O(100) terms).
                    let rsum: f64 = r.c[ch].iter().map(|x| x.abs()).sum();
                    let allow =
                        bound[ch] + abs_sum(&a, ch) * (2f64.powi(-24) + 1e-12) + rsum * 1e-12;
                    let d = (fa[ch] - fr[ch]).abs();
                    assert!(
                        d <= allow,
                        "leaf {id} ch {ch}: |{} - {}| > {allow}",
                        fa[ch],
                        fr[ch]
                    );
                    let m = (fr[ch] - fu[ch]).abs();
                    assert!(
                        m <= merge_allow + 1e-12 * rsum,
                        "leaf {id} ch {ch}: merge {m}"
                    );
                }
            }
        }
    }
    for &(u, v) in pts {
        assert_eq!(c.locate(0, u, v), rec.locate(0, u, v), "({u}, {v})");
    }
    let ids = leaf_ids(tree);
    let (jv, jd) = c1_excess(tree, |id| c.poly(ids[&id]), rounding_jump(&c, tree));
    assert!(jv <= 0.0 && jd <= 0.0, "{e:?}: {jv} {jd}");
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 32, ..ProptestConfig::default() })]

    #[test]
    fn compact_is_reconstruction_within_the_quantization_bound(
        choices in prop::collection::vec(any::<u32>(), 1..60),
        amp in prop::collection::vec(-3.0f64..3.0, 3),
        edge in 0.05f64..0.95,
        pts in prop::collection::vec((0.0f32..=1.0, 0.0f32..=1.0), 30),
    ) {
        let tree = random_tree(&choices, 12);
        let f = |u: f64, v: f64| {
            let s = if u + 0.3 * v < edge { 0.0 } else { 1.0 };
            Vec3::new(
                (1.5 + amp[0] * (3.0 * u + 1.0).sin() * (2.0 * v).cos()) as f32,
                (amp[1].abs() * two_spots(u, v) + 0.5 * s) as f32,
                (amp[2] * u * u * v + 0.2 * s) as f32,
            )
        };
        let sq = SampledQuadtree::from_fn(tree, f);
        for e in Estimator::ALL {
            check_compact_against_reconstruction(&sq, e, &pts);
        }
    }

    #[test]
    fn decode_of_garbage_is_an_error_or_a_valid_reconstruction(
        bytes in prop::collection::vec(any::<u8>(), 0..400),
        flips in prop::collection::vec((any::<usize>(), any::<u8>()), 1..8),
    ) {
        let mut with_magic = MAGIC.to_vec();
        with_magic.extend_from_slice(&bytes);
        for b in [&bytes, &with_magic] {
            if let Ok(c) = CompactReconstruction::decode(b) {
                prop_assert_eq!(&c.encode(), b);
            }
        }
        // Corrupt a real encoding: never a panic; whatever decodes re-encodes to the same bytes.
        let tree = random_tree(&[3, 5, 7, 9, 2, 4], 8);
        let sq = SampledQuadtree::from_fn(tree, grey(two_spots));
        let mut enc = compact1(&sq, Estimator::default()).encode();
        for (at, x) in flips {
            let n = enc.len();
            enc[at % n] ^= x | 1;
        }
        if let Ok(c) = CompactReconstruction::decode(&enc) {
            prop_assert_eq!(c.encode(), enc);
        }
    }

    /// Along every edge, T-vertex edges included, value and size-scaled derivatives of the
    /// compact patches agree to the rounding of the derived data (`rounding_jump`: 8 * 2^-24 of
    /// the patches' geometry size, O(1) here). T-vertex data quantized on their own, one
    /// power-of-two step of 2^-16 of the polygon's largest value each, give jumps of up to
    /// 1.4e-4 (value) and 7.8e-3 (size-scaled derivative) of the sample range on these trees,
    /// far beyond that allowance; derived data give 4.3e-8 and 1.3e-7 (64 trees, `--nocapture`
    /// of a measurement, not asserted).
    #[test]
    fn t_vertex_edges_are_c1_to_rounding(choices in prop::collection::vec(any::<u32>(), 1..50)) {
        let tree = random_tree(&choices, 12);
        let f = |u: f64, v: f64| {
            Vec3::new(
                (1.0 + 0.5 * (3.0 * u + 1.0).sin() * (2.0 * v).cos()) as f32,
                two_spots(u, v) as f32,
                (u * u * v + 0.2) as f32,
            )
        };
        let sq = SampledQuadtree::from_fn(tree, f);
        for e in Estimator::ALL {
            let p = build_polygon(0, &sq, e).unwrap();
            let tree = &p.refined.tree;
            let c = compact1(&sq, e);
            let ids = leaf_ids(tree);
            let (jv, jd) = c1_excess(tree, |id| c.poly(ids[&id]), rounding_jump(&c, tree));
            prop_assert!(jv <= 0.0 && jd <= 0.0, "{:?}: {} {}", e, jv, jd);
            // The derived vertices are exactly the tree's T-vertices.
            let st = c.stats();
            prop_assert_eq!(st.vertices - st.stored_vertices, tree.t_vertices().len());
        }
    }
}

#[test]
fn compact_on_a_conforming_grid_is_c1_to_rounding() {
    // A uniform tree has no T-vertex: every edge joins two patches with the same (shared,
    // quantized) corner data, so quantization cannot open a jump.
    let tree = adaptive_tree(4, |_| true);
    let f = |u: f64, v: f64| {
        Vec3::new(
            (1.0 + 0.5 * (3.0 * u + 1.0).sin() * (2.0 * v).cos()) as f32,
            two_spots(u, v) as f32,
            (u * u * v + 0.2) as f32,
        )
    };
    let sq = SampledQuadtree::from_fn(tree, f);
    for e in Estimator::ALL {
        let p = build_polygon(0, &sq, e).unwrap();
        let ids = leaf_ids(&p.refined.tree);
        let c = compact1(&sq, e);
        assert_eq!(p.refined.tree.t_vertices(), vec![]);
        assert_eq!(c.stats().stored_vertices, c.stats().vertices);
        let (jv, jd) = c1_excess(&p.refined.tree, |id| c.poly(ids[&id]), |_, _, _| (0.0, 0.0));
        // f64 rounding of O(10) numbers, as for the unquantized patches.
        assert!(jv < 1e-12 && jd < 1e-12, "{e:?}: {jv} {jd}");
    }
}

#[test]
fn compact_step_stays_within_the_value_half_step_of_its_range() {
    let lo = 0.1f32;
    let hi = 0.83f32;
    let f = |u: f64, _: f64| if u < 0.37 { lo } else { hi };
    let tree = criterion_tree(&|u, v| f(u, v) as f64, 2, 8, 1e-3);
    let sq = SampledQuadtree::from_fn(tree, |u, v| Vec3::splat(f(u, v)));
    let c = compact1(&sq, Estimator::Monotone);
    // Fritsch-Butland gives zero slopes and twists at a step (one secant is 0), so only values
    // are rounded, each by at most half a step of the largest value's mantissa (S_f / 2, s = 0)
    // plus its f32 rounding; f32 evaluation of coefficients summing to O(1): a few ulps of 1.
    assert_eq!(c.scales(0)[3..], [0.0; 9]);
    let df = (0.5 * c.scales(0)[0]) as f32 + hi * f32::EPSILON;
    let allow = df + 8.0 * f32::EPSILON;
    let n = 257;
    for j in 0..=n {
        for i in 0..=n {
            let (u, v) = (i as f32 / n as f32, j as f32 / n as f32);
            let x = c.expand(c.locate(0, u, v)).eval(u, v);
            assert!(
                x.min_element() >= lo - allow && x.max_element() <= hi + allow,
                "({u}, {v}): {x}"
            );
        }
    }
}

#[test]
fn compact_exact_data_expand_to_reconstructions_bits() {
    // Constant channels on an adaptive tree with T-vertices: every value is its quantity's
    // largest, stored as m = 32767 at s = 0, and (32767 * (M / 32767)) is M to within f64
    // rounding, which the f32 conversion removes (M is an f32); the derivatives are zero
    // quantities (scale 0) and derived vertices take the constant. So the held data are the
    // unquantized data and the expansion is the same arithmetic on the same numbers as
    // Reconstruction's.
    let tree = criterion_tree(&spot, 1, 6, 1e-3);
    assert!(!tree.t_vertices().is_empty());
    let sq = SampledQuadtree::from_fn(tree, |_, _| Vec3::new(3.0, 0.7, 1e-3));
    for e in Estimator::ALL {
        let rec = build1(&sq, e);
        let c = compact1(&sq, e);
        for id in 0..c.leaf_count() as u32 {
            assert_eq!(c.expand(id), *rec.patch(id));
        }
        assert_eq!(c.scales(0)[3..], [0.0; 9]);
    }
}

/// 1 / (r^2 + h^2)^2 around (0.3, 0.35), h = 0.06, normalized to a peak of 1: 1.5e-5 at the far
/// corner.
fn falloff(u: f64, v: f64) -> f64 {
    let h2 = 0.06f64 * 0.06;
    let r2 = (u - 0.3).powi(2) + (v - 0.35).powi(2);
    (h2 / (r2 + h2)).powi(2)
}

#[test]
fn dark_values_keep_relative_precision() {
    // Tolerance: the aim, 1e-3 of the local value wherever it is at least 1e-4 of the
    // polygon's peak. What the format gives: each stored value there has a normalized mantissa
    // (|x| >= 2^-16 of the polygon's largest), so it errs by at most 2^-15 of itself, and the
    // patch by at most `error_bound`, 2^-15 times its corners' |f| + (w/4)(|f_u| + |f_v|) +
    // (w^2/16)|f_uv| (module docs). That bound is asserted below the aim as well, so the aim
    // holds by the format's guarantee, not by chance. One absolute power-of-two step per
    // polygon gave 2^-16 of the peak everywhere: ~1e-2 relative at 1e-3 of the peak, ~0.2 at
    // 1e-4.
    let tree = criterion_tree(&falloff, 2, 9, 1e-4);
    let sq = SampledQuadtree::from_fn(tree, |u, v| {
        let f = falloff(u, v);
        Vec3::new(f as f32, (0.5 * f) as f32, (f * (0.2 + u)) as f32)
    });
    let peak = sq
        .values
        .iter()
        .map(|v| v.max_element())
        .fold(0.0f32, f32::max) as f64;
    let darkest = sq
        .values
        .iter()
        .map(|v| v.min_element())
        .fold(f32::MAX, f32::min) as f64;
    assert!(darkest < 2e-5 * peak, "{darkest}");
    let (mut worst, mut worst_bound) = (0.0f64, 0.0f64);
    for e in Estimator::ALL {
        let rec = build1(&sq, e);
        let c = compact1(&sq, e);
        let bounds = c.error_bounds(0);
        let n = 300;
        for j in 0..=n {
            for i in 0..=n {
                let (u, v) = (i as f64 / n as f64, j as f64 / n as f64);
                let id = c.locate(0, u as f32, v as f32);
                let a = c.expand(id).eval_grad_f64(u, v).0;
                let b = rec
                    .patch(rec.locate(0, u as f32, v as f32))
                    .eval_grad_f64(u, v)
                    .0;
                for ch in 0..3 {
                    if b[ch].abs() >= 1e-4 * peak {
                        let rel = (a[ch] - b[ch]).abs() / b[ch].abs();
                        assert!(
                            rel <= 1e-3,
                            "{e:?} ({u}, {v}) ch {ch}: {} vs {}",
                            a[ch],
                            b[ch]
                        );
                        let guaranteed = bounds[id as usize][ch] / b[ch].abs();
                        assert!(
                            guaranteed <= 1e-3,
                            "{e:?} ({u}, {v}) ch {ch}: bound {guaranteed}"
                        );
                        worst = worst.max(rel);
                        worst_bound = worst_bound.max(guaranteed);
                    }
                }
            }
        }
    }
    eprintln!("dark values: largest relative error {worst:.2e}, relative bound {worst_bound:.2e}");
}

/// Five polygons whose samples have at most 16 significant bits, times `k`.
fn scaled_scene(k: f32) -> Vec<SampledQuadtree> {
    (0..5)
        .map(|p| {
            let tree = criterion_tree(&two_spots, p % 3, 4 + p % 3, 2e-3);
            SampledQuadtree::from_fn(tree, |u, v| {
                let base = [
                    two_spots(u, v) + p as f64,
                    spot(u, v),
                    3.0 * falloff(u, v) + 0.1 * u,
                ];
                let x = base.map(|b| k * f32::from_bits((b as f32).to_bits() & !0xff));
                Vec3::new(x[0], x[1], x[2])
            })
        })
        .collect()
}

/// `sum_ab |W_ia| |W_jb| x_ab` for the power coefficient (i, j) of a patch whose geometry has
/// non-negative magnitudes x: the Hermite-to-power change (`hermite::HERMITE_TO_POWER`) with
/// absolute weights, applied along t, then along s, as `PatchPoly::from_corners` does.
fn abs_power(x: &[[f64; 4]; 4]) -> [f64; 16] {
    let h = |y: [f64; 4]| {
        [
            y[0],
            y[2],
            3.0 * y[0] + 3.0 * y[1] + 2.0 * y[2] + y[3],
            2.0 * y[0] + 2.0 * y[1] + y[2] + y[3],
        ]
    };
    let rows = x.map(h);
    let mut out = [0.0; 16];
    for j in 0..4 {
        let col = h([rows[0][j], rows[1][j], rows[2][j], rows[3][j]]);
        for i in 0..4 {
            out[4 * j + i] = col[i];
        }
    }
    out
}

/// The geometry magnitudes of one channel of a patch of width w from per-corner
/// (f, f_u, f_v, f_uv) magnitudes `m(corner)`, indexed as in `PatchPoly::from_corners`.
fn abs_geometry(w: f64, m: impl Fn(usize) -> [f64; 4]) -> [[f64; 4]; 4] {
    let mut g = [[0.0f64; 4]; 4];
    for y in 0..2 {
        for x in 0..2 {
            let d = m(x + 2 * y);
            g[x][y] = d[0];
            g[2 + x][y] = w * d[1];
            g[x][2 + y] = w * d[2];
            g[2 + x][2 + y] = w * w * d[3];
        }
    }
    g
}

#[test]
fn scaling_the_input_scales_the_compact_patches() {
    // k is 0.37 and 3.1 to 8 significant bits, so k times a 16-bit sample is exact in f32: the
    // inputs scale exactly, and what is checked is the compact form, not the f32 rounding of
    // scaled inputs (which moves a mantissa lying within 2^-23 of a rounding boundary by one
    // step, and the unquantized patches by 2^-24 amplified by the estimation).
    for k in [189.0f32 / 512.0, 99.0 / 32.0] {
        let (one, kk) = (scaled_scene(1.0), scaled_scene(k));
        let e = Estimator::default();
        let c1 = CompactReconstruction::build(&one, e).unwrap();
        let ck = CompactReconstruction::build(&kk, e).unwrap();
        let k = k as f64;
        // The f64 estimation and refinement are scale-equivariant to rounding far below any
        // decision: the same trees, and the same stored integers (only S_q scales).
        assert_eq!(c1.leaf_count(), ck.leaf_count());
        for p in 0..5 {
            assert_eq!(c1.stored_integers(p), ck.stored_integers(p), "polygon {p}");
        }
        // Per held quantity |held_k - k held_1|: both are f32 roundings of the same product
        // (m S_k 2^-s = k m S 2^-s to f64 rounding), each within 2^-24 of it: 2^-22 |held_k|
        // covers both; derived vertices add X's corner differences through the |basis| and
        // the same two roundings.
        let seed = |v: usize, q: usize| 2f64.powi(-22) * (ck.held(v)[q] as f64).abs();
        let diffs: Vec<_> = (0..5)
            .map(|p| ck.propagated_errors(p, seed, 2f64.powi(-22)))
            .collect();
        let (mut worst, mut beyond_own, mut beyond_patch, mut coefficients) = (0.0f64, 0, 0, 0);
        for id in 0..c1.leaf_count() as u32 {
            let (a, b) = (c1.expand(id), ck.expand(id));
            let (p, corners) = ck.leaf_vertices(id);
            let cd = ck.corner_data(id);
            let w = 1.0 / a.inv_w as f64;
            for ch in 0..3 {
                let dg = abs_geometry(w, |c| {
                    let x = &diffs[p][corners[c]];
                    [x[ch], x[3 + ch], x[6 + ch], x[9 + ch]]
                });
                let gg = abs_geometry(w, |c| {
                    let d = &cd[c];
                    [
                        d.f[ch].abs(),
                        d.fu[ch].abs(),
                        d.fv[ch].abs(),
                        d.fuv[ch].abs(),
                    ]
                });
                let (dc, gc) = (abs_power(&dg), abs_power(&gg));
                let largest = b.c[ch].iter().fold(0.0f64, |m, x| m.max(x.abs() as f64));
                for q in 0..16 {
                    let (x, y) = (k * a.c[ch][q] as f64, b.c[ch][q] as f64);
                    // The two coefficients' f32 roundings, the held differences through the
                    // absolute basis change, f64 rounding of the two expansions.
                    let allow =
                        2f64.powi(-23) * (x.abs() + y.abs()) + dc[q] + 2f64.powi(-40) * gc[q];
                    assert!(
                        (x - y).abs() <= allow,
                        "k {k} leaf {id}: {x} vs {y} ({allow})"
                    );
                    worst = worst.max((x - y).abs() / allow.max(f64::MIN_POSITIVE));
                    beyond_own += usize::from((x - y).abs() > 2f64.powi(-22) * y.abs());
                    beyond_patch += usize::from((x - y).abs() > 2f64.powi(-22) * largest);
                    coefficients += 1;
                }
            }
        }
        eprintln!(
            "scaling by {k}: largest coefficient difference {worst:.2} of its allowance; of \
             {coefficients} coefficients {beyond_own} differ by more than 2 ulps of their own \
             magnitude, {beyond_patch} by more than 2 ulps of their patch's largest"
        );
    }
}

fn compact_scene() -> Vec<SampledQuadtree> {
    (0..5)
        .map(|k| {
            let tree = criterion_tree(&two_spots, k % 3, 4 + k % 3, 2e-3);
            SampledQuadtree::from_fn(tree, |u, v| {
                Vec3::new(
                    (two_spots(u, v) + k as f64) as f32,
                    spot(u, v) as f32,
                    step(u, v) as f32 * 0.5,
                )
            })
        })
        .collect()
}

#[test]
fn compact_encode_decode_round_trip_is_bit_exact() {
    let polys = compact_scene();
    let c = CompactReconstruction::build(&polys, Estimator::default()).unwrap();
    let enc = c.encode();
    assert_eq!(enc.len(), c.encoded_len());
    assert_eq!(c.stats().encoded_bytes, enc.len());
    let d = CompactReconstruction::decode(&enc).unwrap();
    assert_eq!(d, c);
    assert_eq!(d.polygon_count(), 5);
    for id in 0..c.leaf_count() as u32 {
        let (a, b) = (c.expand(id), d.expand(id));
        let bits = |p: &PatchCoeffs| p.c.map(|ch| ch.map(f32::to_bits));
        assert_eq!(bits(&a), bits(&b));
    }
    assert_eq!(d.encode(), enc);
    // Locate agrees with Reconstruction over all polygons.
    let rec = Reconstruction::build(&polys, Estimator::default()).unwrap();
    assert_eq!(rec.patches().len(), c.leaf_count());
    for p in 0..5u32 {
        for k in 0..200 {
            let (u, v) = ((k as f32 * 0.618).fract(), (k as f32 * 0.377).fract());
            assert_eq!(d.locate(p, u, v), rec.locate(p, u, v));
        }
    }
    let st = c.stats();
    assert_eq!(st.total_bytes, c.bytes());
    assert_eq!(st.leaves, rec.stats().patches);
    assert_eq!(st.vertices, rec.stats().vertices);
    assert_eq!(st.nodes, rec.stats().tree_nodes);
    // The encoding stores the vertices that are not T-vertices of the final trees, 30 bytes
    // each, besides 8 + 4 bytes of header and per polygon 4 + split bits + 96.
    let mut stored = 0;
    let mut fixed = 12;
    for sq in &polys {
        let p = build_polygon(0, sq, Estimator::default()).unwrap();
        let t = &p.refined.tree;
        stored += t.vertex_keys().len() - t.t_vertices().len();
        fixed += 4 + t.nodes().len().div_ceil(8) + 96;
    }
    assert!(stored < st.vertices);
    assert_eq!(st.stored_vertices, stored);
    assert_eq!(enc.len(), fixed + 30 * stored);
}

/// A one-polygon encoding: node count, split bits, scales, then raw vertex records.
fn one(nodes: u32, bits: &[u8], scales: [f64; 12], records: &[u8]) -> Vec<u8> {
    let mut b = MAGIC.to_vec();
    b.extend_from_slice(&1u32.to_le_bytes());
    b.extend_from_slice(&nodes.to_le_bytes());
    b.extend_from_slice(bits);
    for s in scales {
        b.extend_from_slice(&s.to_le_bytes());
    }
    b.extend_from_slice(records);
    b
}

/// One vertex record with every quantity (m, s).
fn record(m: i16, s: u8) -> Vec<u8> {
    let mut r = vec![s | s << 4; 6];
    for _ in 0..12 {
        r.extend_from_slice(&m.to_le_bytes());
    }
    r
}

#[test]
fn compact_decode_rejects_malformed_bytes() {
    let polys = compact_scene();
    let enc = CompactReconstruction::build(&polys[..2], Estimator::default())
        .unwrap()
        .encode();
    // Truncations: every one in the first and last KiB (the header, the first tree and its
    // records, the last polygon's end), and every 61st between (a stride prime to the record
    // sizes, so each field of a record is cut somewhere); every one of the 26 KB took 5 s.
    let len = enc.len();
    for n in (0..len).filter(|&n| n < 1024 || n + 1024 >= len || n % 61 == 0) {
        assert!(
            CompactReconstruction::decode(&enc[..n]).is_err(),
            "prefix {n}"
        );
    }
    // Trailing bytes, wrong magic.
    let mut longer = enc.clone();
    longer.push(0);
    assert!(CompactReconstruction::decode(&longer).is_err());
    let mut magic = enc.clone();
    magic[7] = b'1';
    assert!(CompactReconstruction::decode(&magic).is_err());
    // A polygon count far beyond the data.
    let mut count = enc.clone();
    count[8..12].copy_from_slice(&u32::MAX.to_le_bytes());
    assert!(CompactReconstruction::decode(&count).is_err());
    // Node count not 1 mod 4; the root's split bit set on a one-node tree; a padding bit.
    let zero = [0.0f64; 12];
    let four = |r: Vec<u8>| r.repeat(4);
    assert!(CompactReconstruction::decode(&one(2, &[0], zero, &four(record(0, 0)))).is_err());
    assert!(CompactReconstruction::decode(&one(1, &[1], zero, &four(record(0, 0)))).is_err());
    assert!(CompactReconstruction::decode(&one(1, &[2], zero, &four(record(0, 0)))).is_err());
    // A chain of splits of child 3 down to level 17: 1 + 4 * 17 nodes, split bits at 0, 4, 8, ...
    let n = 1 + 4 * 17;
    let mut bits = vec![0u8; (n as usize).div_ceil(8)];
    for k in 0..17 {
        bits[4 * k / 8] |= 1 << ((4 * k) % 8);
    }
    assert!(CompactReconstruction::decode(&one(n, &bits, zero, &[])).is_err());
    // A one-node tree with zero scales and mantissas decodes (4 stored vertices).
    let c = CompactReconstruction::decode(&one(1, &[0], zero, &four(record(0, 0)))).unwrap();
    assert_eq!(
        (
            c.leaf_count(),
            c.stats().vertices,
            c.stats().stored_vertices
        ),
        (1, 4, 4)
    );
    // Canonical quantities decode: normalized at any shift, anything nonzero at shift 15.
    let unit = [1.0f64; 12];
    for (m, s) in [(16384, 0), (-32767, 3), (16384, 14), (1, 15), (-16383, 15)] {
        let b = one(1, &[0], unit, &four(record(m, s)));
        let c = CompactReconstruction::decode(&b).unwrap_or_else(|e| panic!("{m} {s}: {e}"));
        assert_eq!(c.encode(), b);
    }
    // Not canonical: a zero mantissa with a shift, an unnormalized mantissa below shift 15,
    // -32768, a nonzero mantissa of a zero scale.
    for (m, s, scale) in [
        (0, 1, 1.0),
        (16383, 14, 1.0),
        (i16::MIN, 0, 1.0),
        (5, 15, 0.0),
    ] {
        let b = one(1, &[0], [scale; 12], &four(record(m, s)));
        assert!(
            CompactReconstruction::decode(&b).is_err(),
            "{m} {s} {scale}"
        );
    }
    // Scales that are negative, -0 or not finite.
    for scale in [-1.0, -0.0, f64::NAN, f64::INFINITY] {
        let b = one(1, &[0], [scale; 12], &four(record(0, 0)));
        assert!(CompactReconstruction::decode(&b).is_err(), "{scale}");
    }
    // A held value beyond f32 (a huge scale) or below the smallest normal f32 (a tiny one).
    for scale in [1e36, 1e-45] {
        let b = one(1, &[0], [scale; 12], &four(record(16384, 0)));
        assert!(CompactReconstruction::decode(&b).is_err(), "{scale}");
    }
    // A tree with a T-vertex (the root split, child 3 split: (1/2, 3/4) and (3/4, 1/2) lie
    // inside edges of children 1 and 2): 9 + 5 vertices, 2 derived, 12 records.
    let b = |records: usize| {
        one(
            9,
            &[0b0001_0001, 0],
            unit,
            &record(16384, 0).repeat(records),
        )
    };
    let c = CompactReconstruction::decode(&b(12)).unwrap();
    assert_eq!((c.stats().vertices, c.stats().stored_vertices), (14, 12));
    assert!(CompactReconstruction::decode(&b(13)).is_err());
    assert!(CompactReconstruction::decode(&b(11)).is_err());
}

#[test]
fn compact_same_bytes_for_any_thread_count_and_bad_input_errors() {
    let polys = compact_scene();
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| CompactReconstruction::build(&polys, Estimator::default()).unwrap())
    };
    assert_eq!(run(1).encode(), run(3).encode());
    let mut nan = polys[1].clone();
    nan.values[2].x = f32::NAN;
    let err = CompactReconstruction::build(&[polys[0].clone(), nan], Estimator::Plain).unwrap_err();
    assert!(err.to_string().contains("polygon 1"), "{err}");
    // Values near f32::MAX: slopes beyond f32 are an error naming the polygon, not a panic.
    let mut t = Quadtree::new();
    t.split(0);
    let huge =
        SampledQuadtree::from_fn(t, |u, _| Vec3::splat(if u > 0.7 { f32::MAX } else { 0.0 }));
    let err =
        CompactReconstruction::build(&[polys[0].clone(), huge], Estimator::Plain).unwrap_err();
    assert!(err.to_string().contains("polygon 1"), "{err}");
    assert_eq!(
        CompactReconstruction::build(&[], Estimator::Plain)
            .unwrap()
            .polygon_count(),
        0
    );
}

#[test]
fn the_patch_cache_returns_exactly_the_expanded_patch() {
    // Two reconstructions used alternately with one cache (the cache must not serve one's
    // patches for the other's ids), every id visited twice (misses, then hits).
    let a = compact1(
        &SampledQuadtree::from_fn(criterion_tree(&spot, 1, 7, 1e-3), grey(spot)),
        Estimator::Monotone,
    );
    let b = compact1(
        &SampledQuadtree::from_fn(criterion_tree(&step, 1, 7, 1e-3), grey(step)),
        Estimator::Monotone,
    );
    assert!(a.leaf_count() > 64 && b.leaf_count() > 64);
    for c in [&a, &b] {
        // Below the cap, every leaf has a slot of its own.
        let slots = c.cache_slots();
        assert!(slots.is_power_of_two() && slots >= c.leaf_count() && slots < 2 * c.leaf_count());
    }
    let mut cache = PatchCache::default();
    for _ in 0..2 {
        for c in [&a, &b] {
            for id in 0..c.leaf_count() as u32 {
                assert_eq!(c.cached_patch(id, &mut cache), c.expand(id));
                assert_eq!(PatchSource::patch(c, id), c.expand(id));
            }
        }
    }
}

#[test]
fn a_patch_cache_allocates_what_its_accounting_says() {
    let small = compact1(
        &SampledQuadtree::from_fn(criterion_tree(&spot, 1, 7, 1e-3), grey(spot)),
        Estimator::Monotone,
    );
    let mut cache = PatchCache::default();
    assert_eq!(cache.bytes(), 0);
    small.warm(&mut cache);
    assert_eq!(cache.bytes(), small.cache_bytes());
    assert!(small.cache_bytes() < CACHE_SLOTS * std::mem::size_of::<crate::PatchCoeffs>());
    // More leaves than the cap (a full depth-8 tree, 65,536 leaves): CACHE_SLOTS slots, shared
    // by several leaves each, every patch still the expanded one.
    let mut t = Quadtree::new();
    let mut level = vec![0u32];
    for _ in 0..8 {
        level = level
            .iter()
            .flat_map(|&n| {
                let c = t.split(n);
                [c, c + 1, c + 2, c + 3]
            })
            .collect();
    }
    let wavy = |u: f64, v: f64| 2.0 + (37.0 * u).sin() * (29.0 * v).cos();
    let big = compact1(
        &SampledQuadtree::from_fn(t, grey(wavy)),
        Estimator::Monotone,
    );
    assert_eq!(big.leaf_count(), 65_536);
    assert_eq!(big.cache_slots(), CACHE_SLOTS);
    big.warm(&mut cache);
    assert_eq!(cache.bytes(), big.cache_bytes());
    for id in (0..big.leaf_count() as u32).step_by(97) {
        assert_eq!(big.cached_patch(id, &mut cache), big.expand(id));
    }
    // Back to the small one: the cache is resized to its slots again.
    small.warm(&mut cache);
    assert_eq!(cache.bytes(), small.cache_bytes());
}
