//! A T-junction whose lattices do not line up, end to end: an L of floor, a 3 x 1 strip with a
//! unit square on the first third of its side, under an area light across the seam. The loader
//! cuts the strip through the T-vertex (`scene::junctions`), so the square and the strip's
//! first third share a whole side and the reconstruction joins them C1. Measured from the RRPs
//! on either side of the seam: the value step against the floor's peak, and the jump of the
//! slope across the seam against the same one-sided difference quotients across the same line
//! inside one rectangle under the same light (step 1/256: the curvature term a C1 function has
//! too, well above f32 rounding). A floor cut into a fan of eight triangles, which the loader
//! merges into quarters (`scene::triangle_pairs`), is measured the same way against one
//! square. Run with `--nocapture` for the numbers.

use glam::DVec3;

use app::context::Context;
use app::context::Input;
use app::prepare::prepare;
use base::method::Placement;
use fixtures::closed_form::{camera, material, rect};
use reconstruction::texture::SizePolicy;
use reconstruction::{Estimator, Reconstruction};
use scene::{Polygon, Scene};

/// The L, or (`whole`) one 3 x 2 rectangle under the same light: the floor reflects onto
/// nothing, so its light is the light's direct light in both, and the rectangle's is one RRP.
fn floor(whole: bool) -> Scene {
    let polygons = if whole {
        vec![rect(0.0, 3.0, 0.0, 2.0, 0.0, DVec3::Z, 0)]
    } else {
        vec![
            rect(0.0, 3.0, 0.0, 1.0, 0.0, DVec3::Z, 0),
            rect(0.0, 1.0, 1.0, 2.0, 0.0, DVec3::Z, 0),
        ]
    };
    // Off-centre along the seam and across it, so the light varies both ways there.
    lit(polygons, rect(0.15, 0.85, 0.55, 1.35, 0.6, -DVec3::Z, 1))
}

/// Floor `polygons` (material 0) under `light` (material 1).
fn lit(mut polygons: Vec<Polygon>, light: Polygon) -> Scene {
    let materials = vec![
        material("floor", [0.6; 3], [0.0; 3]),
        material("light", [0.0; 3], [4.0; 3]),
    ];
    polygons.push(light);
    Scene::new(camera(), 64, 64, materials, polygons)
}

/// `scene` solved and reconstructed as `render` does it.
fn prepared(scene: &Scene) -> app::prepare::Prepared {
    let input = Input {
        path: "l-floor.toml".into(),
        scene: scene.clone(),
        solution_file: None,
        estimator: Estimator::default(),
        sharp_levels: reconstruction::sharp::DEFAULT_LEVELS,
        input_limit: base::output::MAX_INPUT_BYTES,
    };
    prepare(
        &Context::default(),
        input,
        SizePolicy::FromDepth,
        Placement::Centre,
    )
    .expect("solves")
}

/// (u, v) of point `x` on the axis-aligned rectangle `p`.
fn uv_of(p: &Polygon, x: DVec3) -> (f32, f32) {
    let [c0, c1, _, c3] = p.corners;
    let (e1, e2) = (c1 - c0, c3 - c0);
    let u = (x - c0).dot(e1) / e1.length_squared();
    let v = (x - c0).dot(e2) / e2.length_squared();
    (u as f32, v as f32)
}

/// The reconstruction's value at `x`, from the first floor polygon that contains `x` and whose
/// centre's y passes `pick`.
fn value(scene: &Scene, rec: &Reconstruction, x: DVec3, pick: impl Fn(f64) -> bool) -> f64 {
    let e = 1e-9;
    let (i, p) = scene
        .polygons
        .iter()
        .enumerate()
        .filter(|(_, p)| p.material == 0)
        .find(|(_, p)| {
            let (lo, hi) = p.corners.iter().fold(
                (DVec3::splat(f64::MAX), DVec3::splat(f64::MIN)),
                |(lo, hi), c| (lo.min(*c), hi.max(*c)),
            );
            let inside = x.x >= lo.x - e && x.x <= hi.x + e && x.y >= lo.y - e && x.y <= hi.y + e;
            inside && pick((lo.y + hi.y) / 2.0)
        })
        .expect("a floor polygon there");
    let (u, v) = uv_of(p, x);
    rec.eval(i as u32, u, v).x as f64
}

/// Largest value step and largest slope jump across the line y = `line` for x in (0, 1), the
/// step in radiosity and the jump per unit length (`h` is the difference quotients' step). A
/// seam's two sides are read from the polygons whose centres lie on either side of the line;
/// inside a polygon (`seam` false) both from the one there.
fn jumps(scene: &Scene, rec: &Reconstruction, line: f64, seam: bool, h: f64) -> (f64, f64) {
    let (mut step, mut kink) = (0.0f64, 0.0f64);
    for k in 1..200 {
        let x = k as f64 / 200.0;
        let at = |y: f64, side: f64| {
            let pick = |centre: f64| !seam || (centre - line) * side > 0.0;
            value(scene, rec, DVec3::new(x, y, 0.0), pick)
        };
        let (below, above) = (at(line, -1.0), at(line, 1.0));
        step = step.max((above - below).abs());
        let slope_above = (at(line + h, 1.0) - above) / h;
        let slope_below = (below - at(line - h, -1.0)) / h;
        kink = kink.max((slope_above - slope_below).abs());
    }
    (step, kink)
}

#[test]
fn an_l_split_at_a_third_is_joined_c1() {
    let mut scene = floor(false);
    scene.cut_t_junctions();
    assert_eq!(scene.junctions.counts(), (1, 2), "the strip cut in two");
    let p = prepared(&scene);
    let (rec, _) = p.expanded().unwrap();
    assert_eq!(p.seams.unjoined(), 0, "every seam lines up");
    let peak = (0..=64)
        .flat_map(|j| (0..=64).map(move |i| (i, j)))
        .flat_map(|(i, j)| (0..3).map(move |q| (q, i, j)))
        .map(|(q, i, j)| rec.eval(q, i as f32 / 64.0, j as f32 / 64.0).x as f64)
        .fold(0.0, f64::max);
    let h = 1.0 / 256.0;
    let (step, kink) = jumps(&scene, rec, 1.0, true, h);
    // The same quotients across the same line inside one rectangle: no seam there.
    let whole = floor(true);
    let pw = prepared(&whole);
    let (_, one) = jumps(&whole, pw.expanded().unwrap().0, 1.0, false, h);
    // And the L left uncut: its seam apart.
    let uncut = floor(false);
    let pu = prepared(&uncut);
    let (apart_step, apart_kink) = jumps(&uncut, pu.expanded().unwrap().0, 1.0, true, h);
    eprintln!(
        "L at 1/3: value step {:.2e} of the peak, slope jump {:.3e} per unit against {:.3e} \
         inside one rectangle ({:.2}x); uncut {:.2e} and {:.3e}",
        step / peak,
        kink,
        one,
        kink / one,
        apart_step / peak,
        apart_kink
    );
    assert!(step / peak <= 1e-4, "value step {:.2e}", step / peak);
    assert!(kink <= 2.0 * one, "slope jump {kink:.3e} against {one:.3e}");
}

/// A 2 x 2 floor as a fan of eight triangles about its centre (the loader's `triangle_pairs`
/// makes it four quarters), or as one square, under a light across the quarters' seam y = 0.
fn fan(whole: bool) -> Scene {
    let light = rect(0.1, 0.8, -0.45, 0.35, 0.6, -DVec3::Z, 1);
    if whole {
        return lit(vec![rect(-1.0, 1.0, -1.0, 1.0, 0.0, DVec3::Z, 0)], light);
    }
    let b = [
        [1.0, 0.0],
        [1.0, 1.0],
        [0.0, 1.0],
        [-1.0, 1.0],
        [-1.0, 0.0],
        [-1.0, -1.0],
        [0.0, -1.0],
        [1.0, -1.0],
    ];
    let mut polygons: Vec<Polygon> = (0..8)
        .map(|i| {
            let (u, v) = (b[i], b[(i + 1) % 8]);
            let c = [
                DVec3::ZERO,
                DVec3::new(u[0], u[1], 0.0),
                DVec3::new(v[0], v[1], 0.0),
            ];
            Polygon::triangle(c, 0, 0).unwrap()
        })
        .collect();
    let merged = scene::triangle_pairs::merge(&mut polygons, &mut Vec::new());
    assert_eq!(merged.pairs, 4);
    lit(polygons, light)
}

#[test]
fn a_fan_of_eight_is_as_smooth_as_one_square() {
    let h = 1.0 / 256.0;
    let (s, w) = (fan(false), fan(true));
    let (ps, pw) = (prepared(&s), prepared(&w));
    let (rs, rw) = (ps.expanded().unwrap().0, pw.expanded().unwrap().0);
    assert_eq!(ps.seams.joined(), 4, "the quarters' four seams are joined");
    let peak = (0..=64)
        .flat_map(|j| (0..=64).map(move |i| (i, j)))
        .map(|(i, j)| rw.eval(0, i as f32 / 64.0, j as f32 / 64.0).x as f64)
        .fold(0.0, f64::max);
    let (step, kink) = jumps(&s, rs, 0.0, true, h);
    let (_, one) = jumps(&w, rw, 0.0, false, h);
    eprintln!(
        "fan of 8: value step {:.2e} of the peak, slope jump {:.3e} per unit against {:.3e} \
         inside one square ({:.2}x)",
        step / peak,
        kink,
        one,
        kink / one
    );
    assert!(step / peak <= 1e-4, "value step {:.2e}", step / peak);
    assert!(kink <= 2.0 * one, "slope jump {kink:.3e} against {one:.3e}");
}
