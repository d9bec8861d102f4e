//! Tests of the reconstruction: analytic cases (bilinear, linear, samples), C1 on random
//! unrestricted trees, overshoot of both estimators, resampling, numerical extremes.

use super::*;
use base::quadtree::{Cell, Quadtree, VertexKey};
use proptest::prelude::*;

/// Splits leaves (depth-first) while `want(cell)` says so, up to `max_depth`.
fn adaptive_tree(max_depth: u32, want: impl Fn(Cell) -> bool) -> Quadtree {
    let mut t = Quadtree::new();
    let mut stack = vec![0u32];
    while let Some(id) = stack.pop() {
        let cell = t.node(id).cell;
        if cell.level < max_depth && want(cell) {
            let f = t.split(id);
            stack.extend(f..f + 4);
        }
    }
    t
}

/// The test helper's refinement criterion: split while the function at the cell's centre and
/// edge midpoints differs from the bilinear interpolant of the corners by more than `tol`, with
/// at least `min_depth` levels everywhere.
fn criterion_tree(
    f: &impl Fn(f64, f64) -> f64,
    min_depth: u32,
    max_depth: u32,
    tol: f64,
) -> Quadtree {
    adaptive_tree(max_depth, |c| {
        if c.level < min_depth {
            return true;
        }
        let (u0, v0, u1, v1) = c.bounds();
        let (a, b, cc, d) = (f(u0, v0), f(u1, v0), f(u0, v1), f(u1, v1));
        let bil =
            |s: f64, t: f64| (1.0 - t) * ((1.0 - s) * a + s * b) + t * ((1.0 - s) * cc + s * d);
        [
            (0.5, 0.5),
            (0.5, 0.0),
            (0.0, 0.5),
            (1.0, 0.5),
            (0.5, 1.0),
            (0.25, 0.25),
            (0.75, 0.75),
        ]
        .iter()
        .any(|&(s, t)| (f(u0 + s * (u1 - u0), v0 + t * (v1 - v0)) - bil(s, t)).abs() > tol)
    })
}

fn two_spots(u: f64, v: f64) -> f64 {
    let g =
        |cu: f64, cv: f64, s: f64| (-((u - cu).powi(2) + (v - cv).powi(2)) / (2.0 * s * s)).exp();
    0.05 + 0.9 * g(0.3, 0.35, 0.08) + 0.6 * g(0.7, 0.65, 0.05)
}

/// Spot-light-like: flat 1 inside radius 0.2, a smoothstep penumbra of width 0.03, 0.02 outside.
fn spot(u: f64, v: f64) -> f64 {
    let r = ((u - 0.45).powi(2) + (v - 0.55).powi(2)).sqrt();
    let x = ((0.23 - r) / 0.03).clamp(0.0, 1.0);
    0.02 + 0.98 * x * x * (3.0 - 2.0 * x)
}

fn step(u: f64, _v: f64) -> f64 {
    if u < 0.37 {
        0.0
    } else {
        1.0
    }
}

fn grey(f: impl Fn(f64, f64) -> f64) -> impl Fn(f64, f64) -> Vec3 {
    move |u, v| Vec3::splat(f(u, v) as f32)
}

/// A random unrestricted tree: each choice splits either one of the four children made by the
/// previous split (odd choices: deep chains beside shallow leaves, many-level T-vertex jumps) or
/// any leaf (even choices), never beyond `max_depth`.
fn random_tree(choices: &[u32], max_depth: u32) -> Quadtree {
    let mut t = Quadtree::new();
    let mut last: Option<u32> = None;
    for &r in choices {
        let id = match last {
            Some(first) if r & 1 == 1 => first + (r >> 1) % 4,
            _ => {
                let leaves = t.leaves();
                leaves[(r >> 1) as usize % leaves.len()]
            }
        };
        if t.node(id).is_leaf() && t.node(id).cell.level < max_depth {
            last = Some(t.split(id));
        }
    }
    t
}

/// Largest value jump and size-scaled derivative jump across every interior edge of the final
/// patch tree, in f64 from the patches' Hermite data; checks the right and top edge of every leaf,
/// which covers every interior edge once from at least one side.
fn c1_jumps(p: &PolygonRrp) -> (f64, f64) {
    c1_excess(&p.refined.tree, |id| p.poly(id), |_, _, _| (0.0, 0.0))
}

/// [`c1_jumps`] for any f64 patches `poly(node id)` on `tree`: the largest excess of each jump over
/// its allowance `allow(node a, node b, ws)` (value, size-scaled derivative; ws = the smaller
/// width).
fn c1_excess(
    tree: &Quadtree,
    poly: impl Fn(u32) -> PatchPoly,
    allow: impl Fn(u32, u32, f64) -> (f64, f64),
) -> (f64, f64) {
    let (mut jv, mut jd) = (0.0f64, 0.0f64);
    for id in tree.leaves() {
        let cell = tree.node(id).cell;
        let (u0, v0, u1, v1) = cell.bounds();
        let w = cell.width();
        let me = poly(id);
        for q in [0.03, 0.25, 0.5, 0.61, 0.97] {
            for (u, v) in [(u1, v0 + q * w), (u0 + q * w, v1)] {
                if u >= 1.0 || v >= 1.0 {
                    continue;
                }
                // find_leaf puts points on an edge into the upper (other) cell.
                let other = tree.find_leaf(u, v);
                assert_ne!(other, id);
                let wo = tree.node(other).cell.width();
                let (a, b) = (me.hermite_at(u, v), poly(other).hermite_at(u, v));
                let ws = w.min(wo);
                let (av, ad) = allow(id, other, ws);
                for ch in 0..3 {
                    jv = jv.max((a.f[ch] - b.f[ch]).abs() - av);
                    jd = jd.max(ws * (a.fu[ch] - b.fu[ch]).abs() - ad);
                    jd = jd.max(ws * (a.fv[ch] - b.fv[ch]).abs() - ad);
                }
            }
        }
    }
    (jv, jd)
}

fn sample_range(sq: &SampledQuadtree) -> f64 {
    let (mut lo, mut hi) = (f32::MAX, f32::MIN);
    for v in &sq.values {
        lo = lo.min(v.min_element());
        hi = hi.max(v.max_element());
    }
    (hi - lo) as f64
}

/// Min and max of the reconstruction of polygon 0 over an (n+1)^2 grid including the borders.
fn grid_min_max(rec: &Reconstruction, n: u32) -> (f32, f32) {
    let (mut lo, mut hi) = (f32::MAX, f32::MIN);
    for j in 0..=n {
        for i in 0..=n {
            let x = rec.eval(0, i as f32 / n as f32, j as f32 / n as f32);
            lo = lo.min(x.min_element());
            hi = hi.max(x.max_element());
        }
    }
    (lo, hi)
}

fn build1(sq: &SampledQuadtree, e: Estimator) -> Reconstruction {
    Reconstruction::build(std::slice::from_ref(sq), e).expect("valid input")
}

#[test]
fn every_sample_is_reproduced_at_its_vertex() {
    let tree = criterion_tree(&two_spots, 2, 7, 2e-3);
    let sq = SampledQuadtree::from_fn(tree, |u, v| {
        Vec3::new(two_spots(u, v) as f32, 0.5 * two_spots(v, u) as f32, 0.1)
    });
    assert!(
        !sq.tree.t_vertices().is_empty(),
        "the test tree must have T-vertices"
    );
    for e in Estimator::ALL {
        let rec = build1(&sq, e);
        for (k, want) in sq.keys.iter().zip(&sq.values) {
            let got = rec.eval(0, k.u() as f32, k.v() as f32);
            // f32 Horner over 16 coefficients of size ~ the data (<= 1): a few ulps of 1, i.e.
            // well below 1e-6; the merge tolerance adds at most 1e-7.
            assert!(
                (got - *want).abs().max_element() <= 1e-6,
                "{e:?} at ({}, {}): {got} vs {want}",
                k.u(),
                k.v()
            );
        }
    }
}

#[test]
fn undivided_polygon_is_the_bilinear_interpolant() {
    let c = [
        Vec3::new(0.2, 5.0, 1e-3),
        Vec3::new(1.0, 0.0, 3.0),
        Vec3::new(0.7, 2.0, 0.0),
        Vec3::new(0.1, 9.0, 2.0),
    ];
    let bil = |u: f64, v: f64| {
        let a = c.map(|x| x.as_dvec3());
        ((1.0 - v) * ((1.0 - u) * a[0] + u * a[1]) + v * ((1.0 - u) * a[2] + u * a[3])).as_vec3()
    };
    let sq = SampledQuadtree::from_fn(Quadtree::new(), bil);
    for e in Estimator::ALL {
        let rec = build1(&sq, e);
        assert_eq!(rec.stats().patches, 1);
        for j in 0..=16 {
            for i in 0..=16 {
                let (u, v) = (i as f64 / 16.0, j as f64 / 16.0);
                let got = rec.eval(0, u as f32, v as f32);
                // Coefficients of size <= 9 (only 4 non-zero), f32 Horner: ~1e-6 absolute.
                assert!(
                    (got - bil(u, v)).abs().max_element() < 1e-5,
                    "{e:?} {u} {v}"
                );
            }
        }
    }
}

#[test]
fn c1_across_t_vertices_on_a_spot_tree() {
    let tree = criterion_tree(&spot, 1, 8, 1e-3);
    let depths = tree.depth_histogram();
    assert!(depths.iter().filter(|&&n| n > 0).count() >= 4, "{depths:?}");
    let sq = SampledQuadtree::from_fn(tree, grey(spot));
    let range = sample_range(&sq);
    for e in Estimator::ALL {
        let p = build_polygon(0, &sq, e).unwrap();
        let (jv, jd) = c1_jumps(&p);
        // Exact maths gives 0; f64 rounding adds ~1e-15 and merging up to a few times 1e-7 of
        // the largest value (1, range 0.98): 1e-6 is the bound, tighter than the 1e-5.
        assert!(jv <= 1e-6 * range && jd <= 1e-6 * range, "{e:?}: {jv} {jd}");
    }
}

#[test]
fn monotone_keeps_a_step_in_range_and_plain_overshoots() {
    let tree = criterion_tree(&step, 2, 7, 1e-3);
    let sq = SampledQuadtree::from_fn(tree, grey(step));
    let (plo, phi) = grid_min_max(&build1(&sq, Estimator::Plain), 512);
    let (mlo, mhi) = grid_min_max(&build1(&sq, Estimator::Monotone), 512);
    // Catmull-Rom on a unit step undershoots by 4/54 = 0.074 at s = 2/3 of the cell before it;
    // on the adaptive tree it is far worse (the steep derivative estimated at the finest leaf
    // width is scaled up by the width of a coarse neighbour patch: measured max 2.18).
    assert!(plo < -0.07 && phi > 1.07, "plain {plo} {phi}");
    // Samples are 0 and 1; f32 evaluation errs by a few ulps.
    assert!(mlo >= -1e-6 && mhi <= 1.0 + 1e-6, "monotone {mlo} {mhi}");
}

/// A narrow bright strip along the border v = 0 (0.30 on it, 0.26 beyond v = 0.01), sampled on
/// a tree that is level 2 everywhere but for a dive to level 7 at (0.73, 0): the coarse leaves
/// beside the dive have T-vertices with steep light on their edges.
fn strip(u: f64, v: f64) -> f64 {
    0.26 + 0.04 / (1.0 + ((v - 0.01) / 0.002).exp()) + 0.01 * u
}

#[test]
fn a_coarse_leaf_beside_a_deep_dive_stays_in_range() {
    let tree = adaptive_tree(7, |c| {
        let (u0, v0, u1, v1) = c.bounds();
        c.level < 2 || ((u0..=u1).contains(&0.73) && (v0..=v1).contains(&0.0))
    });
    assert_eq!(tree.depth(), 7);
    let sq = SampledQuadtree::from_fn(tree, grey(strip));
    let lo = sq.values.iter().map(|v| v.x).fold(f32::MAX, f32::min);
    let hi = sq.values.iter().map(|v| v.x).fold(f32::MIN, f32::max);
    for e in [Estimator::Monotone, Estimator::Hyman] {
        let (a, b) = grid_min_max(&build1(&sq, e), 512);
        // Each slope is clipped into the monotone region of every leaf edge it starts, so the
        // edge cubics stay within their corners; what is left is the interior's 2-D ringing
        // (none here; the slopes estimated at the dive's width,
        // unclipped, put the monotone estimator 54 % of the range outside it).
        let over = (lo - a).max(b - hi).max(0.0) / (hi - lo);
        assert!(
            over <= 1e-2,
            "{e:?}: [{a}, {b}] vs samples [{lo}, {hi}]: {over}"
        );
    }
}

#[test]
fn overshoot_report() {
    // Measures over- and undershoot beyond the sample range and the RMS error against the true
    // function for both estimators; prints them (run with --nocapture) and asserts the ordering.
    type Case = (&'static str, fn(f64, f64) -> f64);
    let cases: [Case; 3] = [("step", step), ("spot", spot), ("two-spots", two_spots)];
    for (name, f) in cases {
        let tree = criterion_tree(&f, 2, 7, 1e-3);
        let sq = SampledQuadtree::from_fn(tree, grey(f));
        let lo = sq.values.iter().map(|v| v.x).fold(f32::MAX, f32::min);
        let hi = sq.values.iter().map(|v| v.x).fold(f32::MIN, f32::max);
        let mut over = Vec::new();
        for e in Estimator::ALL {
            let rec = build1(&sq, e);
            let (a, b) = grid_min_max(&rec, 512);
            let mut se = 0.0f64;
            let n = 256;
            for j in 0..n {
                for i in 0..n {
                    let (u, v) = ((i as f64 + 0.5) / n as f64, (j as f64 + 0.5) / n as f64);
                    se += (rec.eval(0, u as f32, v as f32).x as f64 - f(u, v)).powi(2);
                }
            }
            let o = (lo - a).max(b - hi).max(0.0) / (hi - lo);
            eprintln!(
                "{name:9} {e:?}: {} patches, range [{a:.4}, {b:.4}] vs samples [{lo:.4}, {hi:.4}], \
                 overshoot {:.2} % of range, rms error {:.2e}",
                rec.stats().patches,
                100.0 * o,
                (se / (n * n) as f64).sqrt()
            );
            over.push(o);
        }
        assert!(
            over[1] <= over[0] && over[2] <= over[0],
            "{name}: a limited estimator overshoots more than plain: {over:?}"
        );
    }
}

#[test]
fn linear_functions_collapse_to_one_patch() {
    let tree = criterion_tree(&two_spots, 3, 6, 1e-3);
    let lin = |u: f64, v: f64| Vec3::new((1.0 + 2.0 * u - v) as f32, (3.0 * v) as f32, 0.25);
    let sq = SampledQuadtree::from_fn(tree, lin);
    let rec = build1(&sq, Estimator::default());
    // Every vertex's data equal the root polynomial, so everything merges back.
    assert_eq!(rec.stats().patches, 1);
    assert!(rec.stats().full_grid_patches >= 64);
}

#[test]
fn resample_matches_direct_evaluation_at_texel_centres() {
    let tree = criterion_tree(&two_spots, 1, 6, 2e-3);
    let sq = SampledQuadtree::from_fn(tree, grey(two_spots));
    let rec = build1(&sq, Estimator::default());
    for (n, m) in [(1, 1), (7, 5), (16, 16), (33, 2)] {
        let tex = rec.resample(0, n, m);
        assert_eq!(tex.len(), (n * m) as usize);
        for j in 0..m {
            for i in 0..n {
                let want = rec.eval(0, texel_centre(i, n), texel_centre(j, m));
                // Same point, same patch, same arithmetic: bitwise equal.
                assert_eq!(tex[(j * n + i) as usize], want, "{n}x{m} texel ({i}, {j})");
            }
        }
    }
    assert!(rec.resample(0, 0, 4).is_empty());
}

#[test]
fn extremes_stay_finite() {
    // Radiosity spanning 1e-8 .. 1e8 with a sharp ridge; depth 12 beside depth 1 along u = 0.5;
    // and an undivided polygon with extreme corners, all in one build.
    let ridge = |u: f64, v: f64| {
        let x = 1e-8 + 1e8 * (-((u - 0.5) * 300.0).powi(2)).exp() * (1.0 + v);
        Vec3::new(x as f32, (1e-8 + 1e8 * u * v) as f32, 1e-8)
    };
    let deep = adaptive_tree(12, |c| {
        let (u0, _, u1, _) = c.bounds();
        c.level == 0 || (u0 < 0.5 && u1 >= 0.5)
    });
    assert_eq!(deep.depth(), 12);
    let flat = SampledQuadtree::from_fn(Quadtree::new(), |u, v| {
        Vec3::new((1e8 * u) as f32, 1e-8, (1e8 * v * u) as f32)
    });
    let polys = vec![SampledQuadtree::from_fn(deep, ridge), flat];
    for e in Estimator::ALL {
        let rec = Reconstruction::build(&polys, e).unwrap();
        assert_eq!(rec.polygon_count(), 2);
        assert!(rec.patches().iter().all(|p| p.is_finite()));
        for p in 0..2u32 {
            for j in 0..=64 {
                for i in 0..=64 {
                    let (u, v) = (i as f32 / 64.0, j as f32 / 64.0);
                    assert!(rec.eval(p, u, v).is_finite());
                    let (a, b, c) = rec.eval_grad(p, u as f64, v as f64);
                    assert!(a.is_finite() && b.is_finite() && c.is_finite());
                }
            }
        }
        for (p, sq) in polys.iter().enumerate() {
            for (k, want) in sq.keys.iter().zip(&sq.values) {
                let got = rec.eval(p as u32, k.u() as f32, k.v() as f32);
                // Relative to the data range (2e8): f32 rounding of O(1e8) coefficients.
                assert!(
                    (got - *want).abs().max_element() <= 1e-6 * 2e8,
                    "{got} {want}"
                );
            }
        }
        let p = build_polygon(0, &polys[0], e).unwrap();
        let (jv, jd) = c1_jumps(&p);
        assert!(jv <= 1e-5 * 2e8 && jd <= 1e-5 * 2e8, "{jv} {jd}");
    }
}

#[test]
fn bad_input_is_an_error_not_a_panic() {
    let mut t = Quadtree::new();
    t.split(0);
    let good = SampledQuadtree::from_fn(t, |u, v| Vec3::splat((u + v) as f32));
    let mut nan = good.clone();
    nan.values[3].y = f32::NAN;
    assert!(Reconstruction::build(&[good.clone(), nan], Estimator::Plain).is_err());
    let mut missing = good.clone();
    missing.keys.pop();
    missing.values.pop();
    let err = Reconstruction::build(&[missing], Estimator::Plain).unwrap_err();
    assert!(err.to_string().contains("polygon 0"), "{err}");
    let mut wrong = good.clone();
    wrong.keys[1] = VertexKey::new(1, 1);
    assert!(Reconstruction::build(&[wrong], Estimator::Plain).is_err());
    // Values near f32::MAX: either a clean error or finite patches, never NaN/inf.
    let huge = SampledQuadtree::from_fn(good.tree.clone(), |u, _| {
        Vec3::splat(if u > 0.7 { f32::MAX } else { 0.0 })
    });
    if let Ok(rec) = Reconstruction::build(&[huge], Estimator::Plain) {
        assert!(rec.patches().iter().all(|p| p.is_finite()));
    }
    assert_eq!(
        Reconstruction::build(&[], Estimator::Plain)
            .unwrap()
            .polygon_count(),
        0
    );
}

#[test]
fn locate_and_eval_clamp_and_hit_borders_exactly() {
    let tree = criterion_tree(&spot, 2, 6, 2e-3);
    let sq = SampledQuadtree::from_fn(tree, grey(spot));
    let rec = build1(&sq, Estimator::default());
    assert_eq!(rec.locate(0, -3.0, f32::NAN), rec.locate(0, 0.0, 0.0));
    assert_eq!(rec.locate(0, 7.0, 1.0), rec.locate(0, 1.0, 1.0));
    assert_eq!(rec.eval(0, 2.0, -1.0), rec.eval(0, 1.0, 0.0));
    // Corner samples at the border are hit to f32 rounding.
    for k in [
        VertexKey::new(0, 0),
        VertexKey::new(LATTICE, LATTICE),
        VertexKey::new(LATTICE, 0),
    ] {
        let want = sq.sample(k).unwrap();
        assert!(
            (rec.eval(0, k.u() as f32, k.v() as f32) - want)
                .abs()
                .max_element()
                < 1e-6
        );
    }
    // eval_many equals eval, including the reuse of the previous patch.
    let uv: Vec<[f32; 2]> = (0..500)
        .map(|k| [k as f32 / 499.0, 0.3 + 0.4 * (k % 7) as f32 / 7.0])
        .collect();
    let mut out = vec![Vec3::ZERO; uv.len()];
    rec.eval_many(0, &uv, &mut out);
    for (p, o) in uv.iter().zip(&out) {
        assert_eq!(*o, rec.eval(0, p[0], p[1]));
    }
    // Gradient of a linear function is exact: d/du = 2, d/dv = -1.
    let lin = SampledQuadtree::from_fn(sq.tree.clone(), |u, v| {
        Vec3::splat((1.0 + 2.0 * u - v) as f32)
    });
    let (f, fu, fv) = build1(&lin, Estimator::Plain).eval_grad(0, 0.3, 0.6);
    assert!((f.x - 1.0).abs() < 1e-6 && (fu.x - 2.0).abs() < 1e-5 && (fv.x + 1.0).abs() < 1e-5);
}

#[test]
fn two_spots_compactness_report() {
    let tree = criterion_tree(&two_spots, 2, 7, 1e-3);
    let sq = SampledQuadtree::from_fn(tree, grey(two_spots));
    let t0 = std::time::Instant::now();
    let rec = build1(&sq, Estimator::default());
    let dt = t0.elapsed();
    let s = rec.stats();
    eprintln!(
        "two-spots depth {}: build {:.2} ms; {s:#?}",
        sq.tree.depth(),
        dt.as_secs_f64() * 1e3
    );
    assert_eq!(sq.tree.depth(), 7);
    assert!(s.patches < s.full_grid_patches / 2, "{s:?}");
    assert!(s.bytes < s.full_grid_bytes / 2);
    assert!(s.original_samples == sq.keys.len() && s.vertices >= s.derived_points);
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    #[test]
    fn linear_functions_are_reproduced_on_random_trees(
        choices in prop::collection::vec(any::<u32>(), 0..60),
        a in -5.0f64..5.0, b in -5.0f64..5.0, c in -5.0f64..5.0,
        pts in prop::collection::vec((0.0f32..=1.0, 0.0f32..=1.0), 20),
    ) {
        let tree = random_tree(&choices, 12);
        let depth = tree.depth();
        let f = |u: f64, v: f64| a + b * u + c * v;
        let scale = 1.0 + a.abs() + b.abs() + c.abs();
        // Tolerance. The samples are f32 roundings of f (error <= u32 * scale, u32 = 2^-24), and
        // a vertex's slopes and twist are differences of samples at the smallest adjacent leaf
        // width h_min, so their errors are <= u32 scale / h_min and u32 scale / h_min^2. Inside
        // a patch of width H the Hermite basis weighs slope terms by at most 4/27 H (4 of them)
        // and twist terms by (4/27)^2 H^2 (4 of them): the value error is at most
        // u32 scale (0.6 r + 0.09 r^2) with r = H / h_min <= 2^(depth - level). Regression: a
        // depth-3 leaf beside depth-12 leaves (r = 512) missed a flat 1e-5 bound by 5x
        // (3.8e-4 against scale 7.9), an amplification of f32 rounding, not a reconstruction
        // error; 1e-5 scale still covers the f32 evaluation of shallow trees.
        let tol_at_level = |level: u32| {
            let r = (1u64 << (depth - level.min(depth))) as f64;
            scale * (1e-5 + 2f64.powi(-24) * (0.6 * r + 0.09 * r * r))
        };
        let sq = SampledQuadtree::from_fn(tree, |u, v| Vec3::new(f(u, v) as f32, f(v, u) as f32, 1.0));
        for e in Estimator::ALL {
            // f64 before merging: check the refined patches directly.
            let p = build_polygon(0, &sq, e).unwrap();
            for id in p.refined.tree.leaves() {
                let poly = p.poly(id);
                let cell = p.refined.tree.node(id).cell;
                let (u0, v0, u1, v1) = cell.bounds();
                let (u, v) = (0.3 * u0 + 0.7 * u1, 0.6 * v0 + 0.4 * v1);
                // The refined leaf may be deeper than the sample leaf it came from: take the
                // input tree's leaf level there.
                let level = sq.tree.node(sq.tree.find_leaf(u, v)).cell.level;
                prop_assert!((poly.hermite_at(u, v).f[0] - f(u, v)).abs() < tol_at_level(level));
            }
            let rec = build1(&sq, e);
            for &(u, v) in &pts {
                let got = rec.eval(0, u, v);
                let level = sq.tree.node(sq.tree.find_leaf(u as f64, v as f64)).cell.level;
                let tol = tol_at_level(level);
                prop_assert!((got.x as f64 - f(u as f64, v as f64)).abs() < tol);
                prop_assert!((got.y as f64 - f(v as f64, u as f64)).abs() < tol);
            }
        }
    }

    /// `PatchSource::cell` is what lets the rasterizer skip `locate`: it must be exactly the set
    /// where `locate` answers the patch. Every located point lies in its patch's cell (closed at
    /// u or v = 1, where `locate` clamps), and the cell's extreme floats (its lower corner and the
    /// largest f32 below its upper sides) all locate to the same patch, down to depth-16 cells.
    #[test]
    fn cells_are_exactly_where_locate_answers(
        choices in prop::collection::vec(any::<u32>(), 1..80),
        pts in prop::collection::vec((0.0f32..=1.0, 0.0f32..=1.0), 1..40),
    ) {
        use crate::PatchSource;
        let tree = random_tree(&choices, MAX_DEPTH);
        let sq = SampledQuadtree::from_fn(tree, |u, v| Vec3::splat((u + 2.0 * v) as f32));
        let rec = build1(&sq, Estimator::Plain);
        let below = |x: f32| f32::from_bits(x.to_bits() - 1);
        for (u, v) in pts.into_iter().chain([(1.0, 1.0), (0.0, 1.0), (1.0, 0.0)]) {
            let id = rec.locate(0, u, v);
            let [u0, u1, v0, v1] = PatchSource::cell(&rec, id).unwrap();
            prop_assert!(u >= u0 && (u < u1 || (u == 1.0 && u1 == 1.0)), "u {u} in [{u0}, {u1})");
            prop_assert!(v >= v0 && (v < v1 || (v == 1.0 && v1 == 1.0)), "v {v} in [{v0}, {v1})");
            for (cu, cv) in [(u0, v0), (below(u1), v0), (u0, below(v1)), (below(u1), below(v1))] {
                prop_assert_eq!(rec.locate(0, cu, cv), id);
            }
        }
    }

    #[test]
    fn c1_on_random_unrestricted_trees(choices in prop::collection::vec(any::<u32>(), 1..50)) {
        let tree = random_tree(&choices, 12);
        let f = |u: f64, v: f64| {
            Vec3::new(
                (1.0 + 0.5 * (3.0 * u + 1.0).sin() * (2.0 * v).cos()) as f32,
                two_spots(u, v) as f32,
                (u * u * v + 0.2) as f32,
            )
        };
        let sq = SampledQuadtree::from_fn(tree, f);
        let range = sample_range(&sq).max(1e-3);
        for e in Estimator::ALL {
            let p = build_polygon(0, &sq, e).unwrap();
            let (jv, jd) = c1_jumps(&p);
            prop_assert!(jv <= 1e-5 * range && jd <= 1e-5 * range, "{:?}: {} {}", e, jv, jd);
            // The stored f32 patches agree across edges to f32 rounding of O(1) coefficients.
            let rec = build1(&sq, e);
            for id in p.refined.tree.leaves() {
                let (_, v0, u1, _) = p.refined.tree.node(id).cell.bounds();
                if u1 >= 1.0 { continue; }
                let v = (v0 + 0.37 * p.refined.tree.node(id).cell.width()) as f32;
                let left = rec.patch(rec.locate(0, u1 as f32 - 1e-6, v));
                let right = rec.patch(rec.locate(0, u1 as f32, v));
                let d = (left.eval(u1 as f32, v) - right.eval(u1 as f32, v)).abs().max_element();
                prop_assert!(d as f64 <= 1e-5 * range, "f32 jump {}", d);
            }
        }
    }
}

/// RMS error against the true function over a 512^2 grid of points.
fn rms_error(f: impl Fn(f64, f64) -> f64, approx: impl Fn(f64, f64) -> f64) -> f64 {
    let n = 512;
    let mut se = 0.0;
    for j in 0..n {
        for i in 0..n {
            let (u, v) = ((i as f64 + 0.37) / n as f64, (j as f64 + 0.61) / n as f64);
            se += (approx(u, v) - f(u, v)).powi(2);
        }
    }
    (se / (n * n) as f64).sqrt()
}

/// Bilinear texture lookup (clamp to edge) of an n x n texture sampled from `f` at texel centres,
/// its values quantized to `bits` (0: float).
fn texture_lookup(f: &impl Fn(f64, f64) -> f64, n: usize, bits: u32) -> impl Fn(f64, f64) -> f64 {
    let q = |x: f64| {
        if bits == 0 {
            x
        } else {
            let l = ((1u32 << bits) - 1) as f64;
            (x * l).round() / l
        }
    };
    let tex: Vec<f64> = (0..n * n)
        .map(|k| {
            q(f(
                ((k % n) as f64 + 0.5) / n as f64,
                ((k / n) as f64 + 0.5) / n as f64,
            ))
        })
        .collect();
    move |u, v| {
        let x = (u * n as f64 - 0.5).clamp(0.0, (n - 1) as f64);
        let y = (v * n as f64 - 0.5).clamp(0.0, (n - 1) as f64);
        let (i, j) = ((x as usize).min(n - 2), (y as usize).min(n - 2));
        let (s, t) = (x - i as f64, y - j as f64);
        let at = |a: usize, b: usize| tex[b * n + a];
        (1.0 - t) * ((1.0 - s) * at(i, j) + s * at(i + 1, j))
            + t * ((1.0 - s) * at(i, j + 1) + s * at(i + 1, j + 1))
    }
}

#[test]
fn equal_quality_texture_report() {
    // Which bilinearly filtered radiosity texture matches the RRP's accuracy on two-spots? The
    // textures sample the *true* function (the best a texture can do); prints the comparison.
    let tree = criterion_tree(&two_spots, 2, 7, 1e-3);
    let sq = SampledQuadtree::from_fn(tree, grey(two_spots));
    let rec = build1(&sq, Estimator::default());
    let s = rec.stats();
    let rrp = rms_error(two_spots, |u, v| rec.eval(0, u as f32, v as f32).x as f64);
    eprintln!(
        "RRP (monotone): rms {rrp:.2e}, {} patches, {} B stored ({} B as Hermite vertex data)",
        s.patches, s.bytes, s.hermite_bytes
    );
    let mut errs = Vec::new();
    for n in [64usize, 128, 256, 512] {
        for bits in [8u32, 12, 0] {
            let e = rms_error(two_spots, texture_lookup(&two_spots, n, bits));
            let bytes = n * n * 3 * if bits == 0 { 32 } else { bits as usize } / 8;
            eprintln!(
                "texture {n:4}^2 x {:>5}: rms {e:.2e}, {bytes} B",
                if bits == 0 {
                    "f32".to_string()
                } else {
                    format!("{bits} b")
                }
            );
            errs.push((n, bits, e));
        }
    }
    // 8-bit quantization alone costs about 1/255/sqrt(12) = 1.1e-3 rms (measured 8.6e-4 at
    // 256^2), several times the RRP's error (~1e-4).
    assert!(errs.iter().filter(|e| e.1 == 8).all(|e| e.2 > 4.0 * rrp));
    // The texture sampled at the input's own resolution class (128^2) is less accurate.
    assert!(errs.iter().filter(|e| e.0 <= 128).all(|e| e.2 > rrp));
}

#[test]
fn figure_2_t_vertices_keep_their_samples() {
    // Paper fig. 2 in small: the upper-right quadrant refined once more makes T-vertices at
    // (1/2, 3/4) and (3/4, 1/2) on the edges of the upper-left and lower-right quadrants. Those
    // two are midpoint-subdivided (4 + 4 patches), the lower-left quadrant and the refined one
    // stay: 1 + 4 + 4 + 4 = 13 patches. The T-vertex samples are kept, not replaced by the coarse
    // edge's interpolation (the paper's first, lossy approach).
    let mut t = Quadtree::new();
    let c = t.split(0);
    t.split(c + 3);
    let f = |u: f64, v: f64| Vec3::splat((1.0 + (4.0 * u).sin() * (3.0 * v).cos()) as f32);
    let sq = SampledQuadtree::from_fn(t, f);
    let p = build_polygon(0, &sq, Estimator::Plain).unwrap();
    assert_eq!(p.refined.tree.leaf_count(), 13);
    assert_eq!(p.refined.tree.depth_histogram(), vec![0, 1, 12]);
    let rec = build1(&sq, Estimator::Plain);
    assert_eq!(rec.stats().patches, 13);
    // Each T-vertex with an offset that steps into the coarse side it splits.
    for (u, v, du, dv) in [(0.5f32, 0.75f32, -1e-3f32, 0.0f32), (0.75, 0.5, 0.0, -1e-3)] {
        let want = f(u as f64, v as f64);
        // f32 evaluation of O(1) coefficients: a few ulps.
        assert!((rec.eval(0, u, v) - want).abs().max_element() < 1e-6);
        // The refined coarse side, evaluated at its edge, gives the sample too.
        let coarse_side = rec.patch(rec.locate(0, u + du, v + dv));
        assert!((coarse_side.eval(u, v) - want).abs().max_element() < 1e-6);
    }
    let (jv, jd) = c1_jumps(&p);
    // f64 rounding of O(10) numbers.
    assert!(jv < 1e-12 && jd < 1e-12, "{jv} {jd}");
}

#[test]
fn same_bytes_for_any_thread_count() {
    let polys: Vec<SampledQuadtree> = (0..6)
        .map(|k| {
            let tree = criterion_tree(&two_spots, k % 3, 5 + k % 2, 2e-3);
            SampledQuadtree::from_fn(tree, |u, v| {
                Vec3::splat((two_spots(u, v) + k as f64) as f32)
            })
        })
        .collect();
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| Reconstruction::build(&polys, Estimator::default()).unwrap())
    };
    let (a, b) = (run(1), run(3));
    assert_eq!(a.stats(), b.stats());
    let bits = |r: &Reconstruction| -> Vec<u32> {
        r.patches()
            .iter()
            .flat_map(|p| p.c.iter().flatten().map(|x| x.to_bits()))
            .collect()
    };
    assert_eq!(bits(&a), bits(&b));
    assert_eq!(a.polygon_count(), 6);
}

#[test]
fn eval_grad_matches_finite_differences() {
    let tree = criterion_tree(&two_spots, 2, 6, 2e-3);
    let sq = SampledQuadtree::from_fn(tree, grey(two_spots));
    let rec = build1(&sq, Estimator::Plain);
    let h = 1e-4;
    for k in 0..200 {
        let (u, v) = (
            0.01 + 0.98 * ((k * 37) % 200) as f64 / 200.0,
            0.01 + 0.98 * k as f64 / 200.0,
        );
        let (f, fu, fv) = rec.eval_grad(0, u, v);
        let g = |a: f64, b: f64| rec.eval_grad(0, a, b).0.x as f64;
        let (du, dv) = (
            (g(u + h, v) - g(u - h, v)) / (2.0 * h),
            (g(u, v + h) - g(u, v - h)) / (2.0 * h),
        );
        // C1 patches: the central difference errs by h^2/6 f''' (|f'''| < ~1e5 here: ~2e-4) plus
        // f32 rounding of the values (1e-7 / h = 1e-3); gradients reach ~10.
        assert!(
            (fu.x as f64 - du).abs() < 5e-3 && (fv.x as f64 - dv).abs() < 5e-3,
            "{u} {v}: {fu} {du}"
        );
        assert!((f.x - rec.eval(0, u as f32, v as f32).x).abs() < 1e-6);
    }
}

mod compact;
mod seam;
mod sharp;
