//! Sharp light: a term with a circular rim (a spot's cone on a plane) and a rectangular hard
//! shadow inside it, over a smooth rest, sampled on a solver-like tree (the bilinear criterion
//! down to depth 6, so the finest leaf is w6 = 1/64 wide). Errors are against the exact
//! function, in units of its peak (about 1.2).

use super::*;
use crate::compact::CompactReconstruction;
use crate::sharp::{Sharp, SharpLight};

const CENTRE: (f64, f64) = (0.45, 0.5);
const RADIUS: f64 = 0.3;
/// The shadow: u in SHADOW_U, v in SHADOW_V.
const SHADOW_U: (f64, f64) = (0.55, 0.62);
const SHADOW_V: (f64, f64) = (0.35, 0.9);
/// Finest solver leaf.
const W6: f64 = 1.0 / 64.0;

fn lit(u: f64, v: f64) -> bool {
    let r = ((u - CENTRE.0).powi(2) + (v - CENTRE.1).powi(2)).sqrt();
    let shadow = (SHADOW_U.0..=SHADOW_U.1).contains(&u) && (SHADOW_V.0..=SHADOW_V.1).contains(&v);
    r <= RADIUS && !shadow
}

/// The term's smooth continuation: a falloff from the centre.
fn term(u: f64, v: f64) -> f64 {
    1.0 / (1.0 + 4.0 * ((u - CENTRE.0).powi(2) + (v - CENTRE.1).powi(2)))
}

fn rest(u: f64, v: f64) -> f64 {
    0.1 + 0.05 * u + 0.08 * v * v
}

fn total(u: f64, v: f64) -> f64 {
    rest(u, v) + if lit(u, v) { term(u, v) } else { 0.0 }
}

/// Distance from (u, v) to the nearest edge of the lit region (a lower bound: the disc's rim
/// and the whole shadow rectangle's outline).
fn edge_distance(u: f64, v: f64) -> f64 {
    let r = ((u - CENTRE.0).powi(2) + (v - CENTRE.1).powi(2)).sqrt();
    let inside_u = (SHADOW_U.0..=SHADOW_U.1).contains(&u);
    let inside_v = (SHADOW_V.0..=SHADOW_V.1).contains(&v);
    let du = (u - SHADOW_U.0).abs().min((u - SHADOW_U.1).abs());
    let dv = (v - SHADOW_V.0).abs().min((v - SHADOW_V.1).abs());
    let gap = |x: f64, (a, b): (f64, f64)| (a - x).max(x - b).max(0.0);
    let rect = match (inside_u, inside_v) {
        (true, true) => du.min(dv),
        (true, false) => dv,
        (false, true) => du,
        (false, false) => gap(u, SHADOW_U).hypot(gap(v, SHADOW_V)),
    };
    (r - RADIUS).abs().min(rect)
}

struct Disc;

impl SharpLight for Disc {
    fn terms(&self, polygon: usize) -> Vec<u32> {
        if polygon == 0 {
            vec![0]
        } else {
            Vec::new()
        }
    }
    fn part(&self, _: usize, _: u32, u: f64, v: f64) -> Option<[f64; 3]> {
        lit(u, v).then(|| [term(u, v); 3])
    }
    fn smooth(&self, _: usize, _: u32, u: f64, v: f64) -> [f64; 3] {
        [term(u, v); 3]
    }
}

fn samples() -> SampledQuadtree {
    let tree = criterion_tree(&total, 3, 6, 1e-3);
    SampledQuadtree::from_fn(tree, grey(total))
}

fn sharp(levels: u32) -> Option<Sharp<'static>> {
    Some(Sharp {
        light: &Disc,
        levels,
    })
}

fn build(sq: &SampledQuadtree, sharp: Option<Sharp<'_>>) -> Reconstruction {
    Reconstruction::build_with(
        std::slice::from_ref(sq),
        Estimator::default(),
        &Seams::none(),
        sharp,
    )
    .expect("valid input")
}

/// Over a 1024^2 grid of cell centres: the mean absolute error, and the largest error at points
/// at least `d` from every edge.
fn errors(rec: &Reconstruction, d: f64) -> (f64, f64) {
    let n = 1024;
    let (mut sum, mut far) = (0.0f64, 0.0f64);
    for j in 0..n {
        for i in 0..n {
            let (u, v) = ((i as f64 + 0.5) / n as f64, (j as f64 + 0.5) / n as f64);
            let e = (rec.eval(0, u as f32, v as f32).x as f64 - total(u, v)).abs();
            sum += e;
            if edge_distance(u, v) >= d {
                far = far.max(e);
            }
        }
    }
    (sum / (n * n) as f64, far)
}

/// With the term followed 4 levels down, the error lies within a quarter of a solver leaf of
/// the edges: beyond it the largest error is 2e-3 of the peak (the bicubics' own error on the
/// smooth parts at the criterion's 1e-3), while the samples alone smear the jump over about a
/// leaf on each side (errors of tens of percents there), and the mean error drops more than 8x
/// (the ramp is 16x narrower; the smooth parts' error is common to both).
#[test]
fn a_followed_edge_is_sharp_within_a_quarter_leaf() {
    let sq = samples();
    let plain = build(&sq, None);
    let followed = build(&sq, sharp(4));
    let (mean_plain, far_plain) = errors(&plain, W6 / 4.0);
    let (mean_followed, far_followed) = errors(&followed, W6 / 4.0);
    println!(
        "mean error {mean_plain:.3e} -> {mean_followed:.3e}; beyond w/4 of an edge \
         {far_plain:.3e} -> {far_followed:.3e}; patches {} -> {}",
        plain.stats().patches,
        followed.stats().patches
    );
    assert!(far_followed <= 2e-3, "{far_followed}");
    assert!(far_plain >= 10.0 * far_followed, "{far_plain}");
    assert!(
        mean_followed * 8.0 <= mean_plain,
        "{mean_followed} vs {mean_plain}"
    );
    // Storage grows along the edges only: within 4 x 2^4 leaves per straddling solver leaf.
    let straddling = plain.stats().patches;
    assert!(
        followed.stats().patches <= straddling * 64,
        "{}",
        followed.stats().patches
    );
}

/// Following the term keeps every sample at its vertex (rest plus part is the sample, to f32
/// rounding of the rest: 2^-24 of the peak), keeps the patches C1 across every leaf edge,
/// T-vertices of the split leaves included (to the merge tolerance, 1e-7 of the peak), and
/// evaluates the light beyond the samples.
#[test]
fn followed_light_keeps_samples_and_c1() {
    let sq = samples();
    let built = build_polygons(
        std::slice::from_ref(&sq),
        Estimator::default(),
        &Seams::none(),
        sharp(4),
    );
    let p = built.into_iter().next().unwrap().expect("valid input");
    let (jv, jd) = c1_jumps(&p);
    let tol = crate::refine::MERGE_TOL * 1.4;
    assert!(jv <= tol && jd <= tol, "value jump {jv}, slope jump {jd}");
    for (k, b) in sq.keys.iter().zip(&sq.values) {
        let got = p.refined.data[k].f[0];
        assert!(
            (got - b.x as f64).abs() <= 2e-7,
            "at {k:?}: {got} vs {}",
            b.x
        );
    }
    assert!(p.sharp_points > 0);
    let rec = build(&sq, sharp(4));
    assert!(rec.stats().sharp_points == p.sharp_points);
}

/// A light that reaches no polygon changes nothing: the same patches, bit for bit.
#[test]
fn no_term_no_change() {
    let sq = samples();
    struct None_;
    impl SharpLight for None_ {
        fn terms(&self, _: usize) -> Vec<u32> {
            Vec::new()
        }
        fn part(&self, _: usize, _: u32, _: f64, _: f64) -> Option<[f64; 3]> {
            None
        }
        fn smooth(&self, _: usize, _: u32, _: f64, _: f64) -> [f64; 3] {
            [0.0; 3]
        }
    }
    let a = build(&sq, None);
    let b = build(
        &sq,
        Some(Sharp {
            light: &None_,
            levels: 4,
        }),
    );
    assert_eq!(a.patches(), b.patches());
}

/// The compact form holds the same followed patches, within its quantization (its documented
/// bound: 2^-16 of the polygon's largest value and a few f32 roundings).
#[test]
fn compact_holds_the_followed_patches() {
    let sq = samples();
    let rec = build(&sq, sharp(3));
    let c = CompactReconstruction::build_with(
        std::slice::from_ref(&sq),
        Estimator::default(),
        &Seams::none(),
        sharp(3),
    )
    .expect("valid input");
    assert_eq!(c.leaf_count(), rec.patches().len());
    let mut worst = 0.0f32;
    for j in 0..=200 {
        for i in 0..=200 {
            let (u, v) = (i as f32 / 200.0, j as f32 / 200.0);
            let id = c.locate(0, u, v);
            assert_eq!(id, rec.locate(0, u, v));
            let a = c.expand(id).eval(u, v).x;
            worst = worst.max((a - rec.eval(0, u, v).x).abs());
        }
    }
    assert!(worst <= 1e-4, "{worst}");
}

/// The Gouraud mesh of `sq` on the unit square, evaluated on an `n`^2 grid of cell centres:
/// (mean absolute error against the exact function, largest error at points at least `d`
/// from every edge). Each point is shaded by the triangle that holds it, at its barycentric
/// weights (the triangle's (s, t) map: t = b2, s = b1 / (1 - t)).
fn mesh_errors(sq: &SampledQuadtree, n: usize, d: f64) -> (f64, f64) {
    let scene = crate::mesh::tests::unit_square(8);
    let mesh = crate::mesh::MeshModel::build(&scene, std::slice::from_ref(sq)).unwrap();
    let mut value = vec![f64::NAN; n * n];
    let cell = |x: f64| ((x * n as f64 - 0.5).ceil().max(0.0) as usize).min(n);
    for (k, uv) in mesh.parent_uv.iter().enumerate() {
        let p = mesh.patch(k);
        let [a, b, c] = uv.map(glam::DVec2::from_array);
        let (lo, hi) = (a.min(b).min(c), a.max(b).max(c));
        let area = (b - a).perp_dot(c - a);
        for j in cell(lo.y)..cell(hi.y) {
            for i in cell(lo.x)..cell(hi.x) {
                let q = glam::DVec2::new((i as f64 + 0.5) / n as f64, (j as f64 + 0.5) / n as f64);
                let b1 = (q - a).perp_dot(c - a) / area;
                let b2 = (b - a).perp_dot(q - a) / area;
                if b1 < -1e-12 || b2 < -1e-12 || b1 + b2 > 1.0 + 1e-12 {
                    continue;
                }
                let s = if b2 < 1.0 { b1 / (1.0 - b2) } else { 0.0 };
                value[j * n + i] = p.eval(s as f32, b2 as f32).x as f64;
            }
        }
    }
    let (mut sum, mut far) = (0.0f64, 0.0f64);
    for j in 0..n {
        for i in 0..n {
            let (u, v) = ((i as f64 + 0.5) / n as f64, (j as f64 + 0.5) / n as f64);
            let got = value[j * n + i];
            assert!(got.is_finite(), "no triangle covers ({u}, {v})");
            let e = (got - total(u, v)).abs();
            sum += e;
            if edge_distance(u, v) >= d {
                far = far.max(e);
            }
        }
    }
    (sum / (n * n) as f64, far)
}

/// The mesh follows the sharp light as the patches do: its vertices along the term's edges
/// split down `levels` below the solver's leaves, each new vertex the rest (interpolated as the
/// mesh interpolates it) plus the exact term. The ramp across an edge narrows from a solver
/// leaf to 1/16 of one, so the mean error (nearly all of it in the ramps) falls by more than
/// 8x, as the patches' does; away from the edges the
/// error stays the linear interpolation's on the smooth parts (the criterion's 1e-3 per leaf,
/// a few times that between its test points); every original sample keeps its bits.
#[test]
fn the_mesh_follows_the_sharp_edges_too() {
    let sq = samples();
    let followed = crate::sharp::followed_samples(std::slice::from_ref(&sq), sharp(4).unwrap());
    let f = &followed[0];
    assert_eq!(f.keys, f.tree.vertex_keys(), "every vertex has a value");
    for (k, b) in sq.keys.iter().zip(&sq.values) {
        assert_eq!(f.sample(*k), Some(*b), "sample at {k:?} kept");
    }
    let n = 512;
    let (mean_plain, far_plain) = mesh_errors(&sq, n, W6);
    let (mean_followed, far_followed) = mesh_errors(f, n, W6);
    println!(
        "mesh mean error {mean_plain:.3e} -> {mean_followed:.3e}; beyond a leaf of an edge \
         {far_plain:.3e} -> {far_followed:.3e}; leaves {} -> {}",
        sq.tree.leaf_count(),
        f.tree.leaf_count()
    );
    assert!(
        mean_followed * 8.0 <= mean_plain,
        "{mean_followed} vs {mean_plain}"
    );
    assert!(far_followed <= 5e-3, "{far_followed}");
    // Storage along the edges only: at most 4 x 2^4 leaves per straddling solver leaf.
    assert!(f.tree.leaf_count() <= 64 * sq.tree.leaf_count());
}

/// A polygon no term reaches keeps its samples and tree exactly, and so does every polygon
/// when the light is not followed at all.
#[test]
fn the_mesh_without_terms_is_unchanged() {
    let sq = samples();
    let other = SampledQuadtree::from_fn(Quadtree::new(), |_, _| Vec3::ONE);
    let both = [sq.clone(), other.clone()];
    let followed = crate::sharp::followed_samples(&both, sharp(4).unwrap());
    assert_eq!(followed[1], other, "polygon 1 has no term");
    assert_ne!(followed[0], sq, "polygon 0 has the disc");
}
