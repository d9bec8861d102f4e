//! The solver against closed forms, each derived here independently of the solver's own code, in
//! f64, at the default settings unless a case says otherwise:
//! - a square emitter over a floor: the floor's radiosity is rho * E * F(x), F the point-to-polygon
//!   form factor by Lambert's contour formula, F = 1/(2 pi) sum_i theta_i n . (R_i x R_i+1) /
//!   |R_i x R_i+1| (R_i from x to the emitter's corners, theta_i the angle between consecutive
//!   ones); nothing else reflects, so that is exact. The reconstruction (what every method
//!   draws) must be within 1e-3 of the peak everywhere, and within 2 % of the local value
//!   wherever the radiosity is at least 1 % of the peak;
//! - a thin strip (100:1) under an off-centre area light, the same formula: within 2 % of the
//!   peak everywhere, and the strip refined along its length (the light's footprint is resolved,
//!   not a straight line between the initial samples);
//! - an RGB furnace (a closed box, every face emitting E = 1 with reflectance (0.5, 0.9, 0.2)):
//!   B = E / (1 - rho) per channel, every sample within the convergence setting in every channel
//!   (the unshot power left behind, u in channel c, leaves a relative error of rho_c u < u);
//! - a sharp shadow: a spot over a floor with a square occluder; the shadow's outline gets
//!   samples at the depth limit, and no method draws negative radiosity near it.

use app::context::Context;
use glam::DVec3;

use app::context::Input;
use app::frames::render_frame;
use app::prepare::prepare;
use base::method::{Method, Placement};
use base::quadtree::SampledQuadtree;
use engine::frame::FrameOptions;
use fixtures::closed_form::{
    camera, drawn_mean, lambert, lit_receiver, material, point_view_factor, quad, rect,
};
use radiosity::{solve, Solution, SolveOptions};
use reconstruction::texture::SizePolicy;
use reconstruction::{Estimator, Reconstruction};
use scene::{Camera, Projection, Scene, SpotLight};

fn solved(scene: &Scene) -> Solution {
    solve(scene, &SolveOptions::default()).unwrap()
}

/// Largest error (relative to the peak of the exact values) and largest relative error where
/// the exact value is at least 1 % of the peak, of the reconstruction of polygon `r` on an
/// n x n grid, channel 0.
fn errors(
    scene: &Scene,
    sol: &Solution,
    r: usize,
    n: u32,
    exact: impl Fn(DVec3) -> f64,
) -> (f64, f64, f64) {
    errors_with(scene, sol, r, n, Estimator::default(), exact)
}

fn errors_with(
    scene: &Scene,
    sol: &Solution,
    r: usize,
    n: u32,
    estimator: Estimator,
    exact: impl Fn(DVec3) -> f64,
) -> (f64, f64, f64) {
    let rec = Reconstruction::build(&sol.polygons, estimator).unwrap();
    let p = &scene.polygons[r];
    let mut pts = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let (u, v) = (i as f64 / n as f64, j as f64 / n as f64);
            pts.push((u, v, exact(p.point(u, v))));
        }
    }
    let peak = pts.iter().map(|t| t.2).fold(0.0, f64::max);
    let (mut abs, mut rel) = (0f64, 0f64);
    for (u, v, want) in pts {
        let got = rec.eval(r as u32, u as f32, v as f32).x as f64;
        abs = abs.max((got - want).abs() / peak);
        if want >= 0.01 * peak {
            rel = rel.max((got - want).abs() / want);
        }
    }
    (peak, abs, rel)
}

#[test]
fn emitter_square_over_a_floor_matches_lamberts_formula() {
    let floor = rect(-2.0, 2.0, -2.0, 2.0, 0.0, DVec3::Z, 0);
    let light = rect(-0.5, 0.5, -0.5, 0.5, 1.0, -DVec3::Z, 1);
    let corners = light.vertices().to_vec();
    let scene = lit_receiver(floor, 0.5, light, 1.0);
    let sol = solved(&scene);
    let (peak, abs, rel) = errors(&scene, &sol, 0, 200, |x| {
        0.5 * lambert(x, DVec3::Z, &corners)
    });
    eprintln!("emitter over floor: peak {peak:.5}, max error {abs:.2e} of the peak, max relative error {rel:.2e}, {} samples", sol.polygons[0].values.len());
    assert!(abs <= 1e-3, "max error {abs} of the peak");
    assert!(rel <= 0.02, "max relative error {rel}");
}

/// Regression: an emitter whose peak falls between quadtree vertices had 2.2-4.2e-3 of the
/// peak missing at the peak (centred on a vertex, 2.9e-4): the samples never saw its top and
/// the limited reconstruction does not rise above them. Refinement also tests where each
/// light peaks. Positions off every dyadic point; the peak of a square emitter parallel to the
/// floor lies under its centre. The aim, 1e-3 of the peak there, is the accuracy the default
/// tolerance buys elsewhere (module docs).
#[test]
// Positions off every dyadic point; their digits are not meant as 1 / sqrt(2).
#[allow(clippy::approx_constant)]
fn an_emitter_peak_between_vertices_is_resolved() {
    for &(cx, cy, h) in &[(0.3137, -0.2179, 0.5), (-0.7071, 0.4142, 0.3)] {
        let floor = rect(-2.0, 2.0, -2.0, 2.0, 0.0, DVec3::Z, 0);
        let light = rect(cx - 0.2, cx + 0.2, cy - 0.2, cy + 0.2, h, -DVec3::Z, 1);
        let corners = light.vertices().to_vec();
        let scene = lit_receiver(floor, 0.5, light, 1.0);
        let sol = solved(&scene);
        let rec = Reconstruction::build(&sol.polygons, Estimator::default()).unwrap();
        let at = DVec3::new(cx, cy, 0.0);
        let want = 0.5 * lambert(at, DVec3::Z, &corners);
        let (u, v) = ((cx + 2.0) / 4.0, (cy + 2.0) / 4.0);
        let got = rec.eval(0, u as f32, v as f32).x as f64;
        let (_, abs, _) = errors(&scene, &sol, 0, 200, |x| {
            0.5 * lambert(x, DVec3::Z, &corners)
        });
        eprintln!(
            "emitter at ({cx}, {cy}, {h}): at its peak {got:.6} of {want:.6} ({:.2e}), largest \
             error {abs:.2e} of the peak, {} samples",
            (got - want).abs() / want,
            sol.polygons[0].values.len()
        );
        // The peak test's own allowance: a tenth of the default tolerance (0.01) of the level.
        assert!((got - want).abs() <= 1e-3 * want, "peak {got} of {want}");
        // Elsewhere the ordinary test (0.01 of the level at the bilinear test points) holds,
        // and the bicubic patches recover most of it: the centred, higher light above is
        // within 3e-4; the light 0.3 up curves more sharply under its edges.
        assert!(abs <= 2e-3, "max error {abs} of the peak");
    }
}

/// Regression: a spot 1 cm from a wall, its cone's footprint (a disc about 1 cm across) off
/// every initial vertex, was drawn at 0.72 of its peak. Closed form: the wall gets
/// rho I cos^falloff(theta) cos(theta) / r^2, at the foot of the spot's axis (normal to the wall)
/// rho I / h^2; the power reaching the wall is the whole cone's, 2 pi I (1 - cos^(falloff+1)
/// alpha) / (falloff + 1) (the footprint lies inside the wall), and the wall reflects rho of it.
#[test]
fn a_spot_one_centimetre_from_a_wall_peaks_within_two_percent() {
    let wall = quad(
        [
            DVec3::new(0.0, -1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 2.0),
            DVec3::new(0.0, -1.0, 2.0),
        ],
        DVec3::X,
        0,
    );
    let (h, y, z, rho, i0, falloff) = (0.01, 0.3137, 1.2179, 0.6, 2.0, 2.0);
    let alpha = 30f64.to_radians();
    let mut scene = Scene::new(
        camera(),
        64,
        64,
        vec![material("wall", [rho; 3], [0.0; 3])],
        vec![wall],
    );
    scene.spots.push(SpotLight {
        position: DVec3::new(h, y, z),
        direction: -DVec3::X,
        intensity: DVec3::splat(i0),
        half_angle: alpha,
        falloff,
    });
    let sol = solved(&scene);
    let rec = Reconstruction::build(&sol.polygons, Estimator::default()).unwrap();
    let p = &scene.polygons[0];
    // (u, v) of the foot (0, y, z): the wall's u runs along y from -1, v along z from 0 (or
    // the reverse, if the winding was flipped).
    let (mut best, mut at) = (f64::INFINITY, (0.0, 0.0));
    for j in 0..=400 {
        for i in 0..=400 {
            let (u, v) = (i as f64 / 400.0, j as f64 / 400.0);
            let d = (p.point(u, v) - DVec3::new(0.0, y, z)).length();
            if d < best {
                (best, at) = (d, (u, v));
            }
        }
    }
    // Refine the parameters of the foot by the wall's affine map (a rectangle).
    let (du, dv) = p.tangents(0.5, 0.5);
    let off = DVec3::new(0.0, y, z) - p.point(at.0, at.1);
    let (u, v) = (
        at.0 + off.dot(du) / du.length_squared(),
        at.1 + off.dot(dv) / dv.length_squared(),
    );
    let want = rho * i0 / (h * h);
    let got = rec.eval(0, u as f32, v as f32).x as f64;
    let power =
        2.0 * std::f64::consts::PI * i0 * (1.0 - alpha.cos().powf(falloff + 1.0)) / (falloff + 1.0);
    // What is drawn, integrated over a 4 cm square around the foot (the footprint is 1.2 cm
    // across) by a 2000 x 2000 midpoint rule.
    let (n, half) = (2000, 0.02);
    let (lu, lv) = (du.length(), dv.length());
    let mut sum = 0.0;
    for j in 0..n {
        for i in 0..n {
            let a = u + half / lu * (2.0 * (i as f64 + 0.5) / n as f64 - 1.0);
            let b = v + half / lv * (2.0 * (j as f64 + 0.5) / n as f64 - 1.0);
            sum += rec.eval(0, a as f32, b as f32).x as f64;
        }
    }
    let energy = sum / (n * n) as f64 * (2.0 * half) * (2.0 * half) / (rho * power);
    eprintln!(
        "spot 1 cm from a wall: peak {got:.2} of {want:.2} ({:.4}), drawn energy {energy:.4}, {} samples",
        got / want,
        sol.polygons[0].values.len()
    );
    assert!((got / want - 1.0).abs() <= 0.02, "peak {got} of {want}");
    assert!((energy - 1.0).abs() <= 0.01, "energy {energy}");
}

#[test]
fn a_thin_strip_refines_like_a_large_polygon() {
    // 4 x 0.04 (aspect 100:1) under a 0.5 m square light 0.5 m up, off the strip's centre.
    let strip = rect(-2.0, 2.0, -0.02, 0.02, 0.0, DVec3::Z, 0);
    let light = rect(0.35, 0.85, -0.25, 0.25, 0.5, -DVec3::Z, 1);
    let corners = light.vertices().to_vec();
    let scene = lit_receiver(strip, 0.6, light, 4.0);
    let sol = solved(&scene);
    let strip_tree: &SampledQuadtree = &sol.polygons[0];
    let (peak, abs, rel) = errors(&scene, &sol, 0, 400, |x| {
        0.6 * 4.0 * lambert(x, DVec3::Z, &corners)
    });
    eprintln!(
        "thin strip: peak {peak:.4}, max error {abs:.2e} of the peak, max relative error {rel:.2e}, depth {}, {} samples",
        strip_tree.tree.depth(),
        strip_tree.values.len()
    );
    assert!(abs <= 0.02, "max error {abs} of the peak");
    assert!(rel <= 0.02, "max relative error {rel}");
    assert!(strip_tree.tree.depth() >= 5, "the strip was not refined");
}

#[test]
fn an_rgb_furnace_converges_in_every_channel() {
    let rho = [0.5, 0.9, 0.2];
    let (lo, hi) = (DVec3::ZERO, DVec3::ONE);
    let c = 0.5 * (lo + hi);
    let mut faces = Vec::new();
    for axis in 0..3 {
        for side in [lo[axis], hi[axis]] {
            let mut pts = [DVec3::ZERO; 4];
            let (a, b) = ((axis + 1) % 3, (axis + 2) % 3);
            for (k, (s, t)) in [(0, 0), (1, 0), (1, 1), (0, 1)].into_iter().enumerate() {
                pts[k][axis] = side;
                pts[k][a] = if s == 0 { lo[a] } else { hi[a] };
                pts[k][b] = if t == 0 { lo[b] } else { hi[b] };
            }
            let mut inward = DVec3::ZERO;
            inward[axis] = c[axis] - side;
            faces.push(quad(pts, inward, 0));
        }
    }
    let scene = Scene::new(
        Camera {
            eye: DVec3::splat(0.5),
            look_at: DVec3::new(0.5, 0.5, 0.0),
            up: DVec3::Y,
            projection: Projection::Perspective { fov_y_deg: 60.0 },
        },
        64,
        64,
        vec![material("furnace", rho, [1.0; 3])],
        faces,
    );
    let conv = scene.radiosity.convergence;
    let sol = solved(&scene);
    let mut worst = [0f64; 3];
    for p in &sol.polygons {
        for v in &p.values {
            for ch in 0..3 {
                let want = 1.0 / (1.0 - rho[ch]);
                worst[ch] = worst[ch].max((v[ch] as f64 - want).abs() / want);
            }
        }
    }
    eprintln!(
        "furnace: worst relative error per channel {worst:?}, unshot {}",
        sol.stats.unshot_fraction
    );
    for (ch, w) in worst.iter().enumerate() {
        assert!(*w <= conv, "channel {ch}: {w} > convergence {conv}");
    }
}

/// A spot's hard shadow is a step at any depth: the leaves its edge crosses split to the depth
/// limit and no further (the reconstruction draws the step exactly from the spot's own light,
/// `reconstruction::sharp`; only area lights' shadow edges split past it); and what is drawn
/// beside it never rings below zero.
#[test]
fn a_sharp_shadow_is_refined_to_the_depth_limit_and_never_negative() {
    let floor = rect(-2.0, 2.0, -2.0, 2.0, 0.0, DVec3::Z, 0);
    // A square occluder between the spot and the floor, seen from below as black.
    let occluder = rect(-0.3, 0.3, -0.3, 0.3, 1.0, -DVec3::Z, 1);
    let mut scene = Scene::new(
        camera(),
        64,
        64,
        vec![
            material("floor", [0.7; 3], [0.0; 3]),
            material("black", [0.0; 3], [0.0; 3]),
        ],
        vec![floor, occluder],
    );
    scene.spots.push(SpotLight {
        position: DVec3::new(0.1, 0.05, 2.0),
        direction: -DVec3::Z,
        intensity: DVec3::splat(10.0),
        half_angle: 60f64.to_radians(),
        falloff: 1.0,
    });
    let sol = solved(&scene);
    let tree = &sol.polygons[0].tree;
    let max_depth = scene.radiosity.max_depth;
    // The shadow of the occluder's edge x = 0.3 on the floor: from the spot at (0.1, .., 2)
    // through z = 1 it lands at x = 0.1 + (0.3 - 0.1) * 2 = 0.5, for |y| under the shadow.
    let (u, v) = ((0.5 + 2.0) / 4.0, (0.0 + 2.0) / 4.0);
    let leaf = tree.find_leaf(u, v);
    assert_eq!(
        tree.node(leaf).cell.level,
        max_depth,
        "the leaf on the shadow edge is not at the depth limit"
    );
    // The bicubic reconstruction may ring slightly below zero beside the edge; what every
    // method draws is clamped at the pixel resolve, so no image holds a negative value.
    let rec = Reconstruction::build(&sol.polygons, Estimator::default()).unwrap();
    let mut lowest = f32::INFINITY;
    for j in 0..=300 {
        for i in 0..=300 {
            let v = rec.eval(0, i as f32 / 300.0, j as f32 / 300.0);
            lowest = lowest.min(v.min_element());
        }
    }
    let peak = sol.polygons[0]
        .values
        .iter()
        .map(|v| v.x)
        .fold(0.0, f32::max);
    eprintln!("sharp shadow: lowest reconstructed value {lowest} (peak {peak})");
    assert!(
        lowest > -0.01 * peak,
        "ringing of {lowest} against a peak of {peak}"
    );
    let input = Input {
        path: "sharp-shadow.toml".into(),
        scene: scene.clone(),
        solution_file: None,
        estimator: Estimator::default(),
        sharp_levels: reconstruction::sharp::DEFAULT_LEVELS,
        input_limit: base::output::MAX_INPUT_BYTES,
    };
    let p = prepare(
        &Context::default(),
        input,
        SizePolicy::FromDepth,
        Placement::Centre,
    )
    .unwrap();
    let mut cam = scene.camera;
    cam.eye = DVec3::new(0.5, -0.6, 1.2);
    cam.look_at = DVec3::new(0.5, 0.0, 0.0);
    for name in Method::NAMES {
        let method = Method::parse(name).unwrap();
        let f = render_frame(&p, method, &cam, &FrameOptions::new(96, 96)).unwrap();
        let low = f
            .pixels
            .iter()
            .map(|c| c.min_element())
            .fold(f32::INFINITY, f32::min);
        assert!(
            f.pixels
                .iter()
                .all(|c| c.is_finite() && c.min_element() >= 0.0 && c.x.is_sign_positive()),
            "{name}: lowest pixel {low}"
        );
    }
}

/// Regression: an emitter 1/1000 of a floor's width 1-2 cm above it lost 10 % of its energy at
/// the default depth. What every method draws, the reconstruction, integrated over the floor
/// (a 4000 x 4000 midpoint rule, far finer than the leaves near the light), holds rho M A F
/// within 1 %: F is the view factor from the source (small enough to be a point: its
/// size is 1/10 to 1/20 of its height) to the floor.
#[test]
fn a_small_close_emitter_keeps_its_energy_where_it_is_drawn() {
    for &(side, h, u, v) in &[(1e-3, 0.02, 0.4137, 0.5821), (2e-3, 0.01, 0.3, 0.7)] {
        let floor = rect(0.0, 1.0, 0.0, 1.0, 0.0, DVec3::Z, 0);
        let hs = 0.5 * side;
        let light = rect(u - hs, u + hs, v - hs, v + hs, h, -DVec3::Z, 1);
        let scene = lit_receiver(floor, 0.5, light, 1000.0);
        let sol = solved(&scene);
        let rec = Reconstruction::build(&sol.polygons, Estimator::default()).unwrap();
        let drawn = drawn_mean(&rec, 0, 4000);
        let want = 0.5 * 1000.0 * side * side * point_view_factor(h, -u, 1.0 - u, -v, 1.0 - v);
        eprintln!(
            "small emitter at ({u}, {v}, {h}): drawn energy {:.5} of the closed form, {} samples",
            drawn / want,
            sol.polygons[0].values.len()
        );
        assert!(
            (drawn / want - 1.0).abs() <= 0.01,
            "energy {}",
            drawn / want
        );
    }
}
