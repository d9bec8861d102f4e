//! What each `[radiosity]` setting buys, measured against closed forms (not against the solver's
//! own output): the error of the reconstruction every method draws, and the samples it costs.
//!
//! ```text
//! cargo run --release -p pixelflow-study --example settings_error
//! ```
//!
//! Cases (all f64 closed forms, derived independently of the solver):
//! - **area light**: a 1 m square emitter (E = 1) 1 m over a 4 m floor (rho = 0.5): the floor's
//!   radiosity is rho E F(x), F by Lambert's contour formula; largest error over a 201 x 201 grid
//!   relative to the peak, and largest relative error where the light is at least 1 % of it;
//! - **off-lattice peak**: a 0.4 m square emitter 0.3 m up, centred off every dyadic point: the
//!   error at the point under its centre (its peak), relative to the peak;
//! - **small close emitter**: a 1 mm square emitter (E = 1000) 2 cm over a 1 m floor: the energy
//!   the reconstruction draws (4000 x 4000 midpoint rule) against rho E A F (F the view factor
//!   from the source, a point at this size, to the floor), and the value at its foot;
//! - **furnace**: a closed unit box, every face emitting 1 with reflectance (0.5, 0.9, 0.2):
//!   B = E / (1 - rho) per channel; the largest relative error of any sample, any channel.
//!
//! Each row changes one setting from the defaults and prints a markdown table (docs/accuracy.md
//! quotes it).

use fixtures::closed_form::{
    drawn_mean, lambert, lit_receiver, material, point_view_factor, quad, rect,
};
use glam::DVec3;
use radiosity::{solve, Solution, SolveOptions};
use reconstruction::{Estimator, Reconstruction};
use scene::{Camera, Projection, Scene};

/// One changed setting.
#[derive(Clone, Copy)]
enum Setting {
    Defaults,
    Tolerance(f64),
    MaxDepth(u32),
    Convergence(f64),
}

impl Setting {
    fn apply(self, scene: &mut Scene) {
        let r = &mut scene.radiosity;
        match self {
            Setting::Defaults => {}
            Setting::Tolerance(t) => r.tolerance = t,
            Setting::MaxDepth(d) => r.max_depth = d,
            Setting::Convergence(c) => r.convergence = c,
        }
    }

    fn label(self) -> String {
        match self {
            Setting::Defaults => "defaults".into(),
            Setting::Tolerance(t) => format!("tolerance = {t}"),
            Setting::MaxDepth(d) => format!("max_depth = {d}"),
            Setting::Convergence(c) => format!("convergence = {c}"),
        }
    }
}

fn solved(mut scene: Scene, s: Setting) -> (Scene, Solution, Reconstruction) {
    s.apply(&mut scene);
    let sol = solve(&scene, &SolveOptions::default()).expect("the case solves");
    let rec = Reconstruction::build(&sol.polygons, Estimator::default()).expect("RRPs build");
    (scene, sol, rec)
}

/// Area light: (largest error / peak, largest relative error above 1 % of the peak, samples).
fn area_light(s: Setting) -> (f64, f64, usize) {
    let floor = rect(-2.0, 2.0, -2.0, 2.0, 0.0, DVec3::Z, 0);
    let light = rect(-0.5, 0.5, -0.5, 0.5, 1.0, -DVec3::Z, 1);
    let corners = light.vertices().to_vec();
    let (scene, sol, rec) = solved(lit_receiver(floor, 0.5, light, 1.0), s);
    let p = &scene.polygons[0];
    let n = 200;
    let pts: Vec<(f64, f64, f64)> = (0..=n)
        .flat_map(|j| (0..=n).map(move |i| (i as f64 / n as f64, j as f64 / n as f64)))
        .map(|(u, v)| (u, v, 0.5 * lambert(p.point(u, v), DVec3::Z, &corners)))
        .collect();
    let peak = pts.iter().map(|t| t.2).fold(0.0, f64::max);
    let (mut abs, mut rel) = (0f64, 0f64);
    for (u, v, want) in pts {
        let got = rec.eval(0, u as f32, v as f32).x as f64;
        abs = abs.max((got - want).abs() / peak);
        if want >= 0.01 * peak {
            rel = rel.max((got - want).abs() / want);
        }
    }
    (abs, rel, sol.polygons[0].values.len())
}

/// Off-lattice peak: error at the peak / peak.
// A position off every dyadic point; its digits are not meant as 1 / sqrt(2).
#[allow(clippy::approx_constant)]
fn off_lattice_peak(s: Setting) -> f64 {
    let (cx, cy, h) = (-0.7071, 0.4142, 0.3);
    let floor = rect(-2.0, 2.0, -2.0, 2.0, 0.0, DVec3::Z, 0);
    let light = rect(cx - 0.2, cx + 0.2, cy - 0.2, cy + 0.2, h, -DVec3::Z, 1);
    let corners = light.vertices().to_vec();
    let (_, _, rec) = solved(lit_receiver(floor, 0.5, light, 1.0), s);
    let want = 0.5 * lambert(DVec3::new(cx, cy, 0.0), DVec3::Z, &corners);
    let (u, v) = ((cx + 2.0) / 4.0, (cy + 2.0) / 4.0);
    let got = rec.eval(0, u as f32, v as f32).x as f64;
    (got - want).abs() / want
}

/// Small close emitter: (drawn energy / closed form, value at the foot / closed form, samples).
fn small_emitter(s: Setting) -> (f64, f64, usize) {
    let (side, h, u, v) = (1e-3, 0.02, 0.4137, 0.5821);
    let floor = rect(0.0, 1.0, 0.0, 1.0, 0.0, DVec3::Z, 0);
    let hs = 0.5 * side;
    let light = rect(u - hs, u + hs, v - hs, v + hs, h, -DVec3::Z, 1);
    let corners = light.vertices().to_vec();
    let (_, sol, rec) = solved(lit_receiver(floor, 0.5, light, 1000.0), s);
    let drawn = drawn_mean(&rec, 0, 4000);
    let want = 0.5 * 1000.0 * side * side * point_view_factor(h, -u, 1.0 - u, -v, 1.0 - v);
    let foot = 0.5 * 1000.0 * lambert(DVec3::new(u, v, 0.0), DVec3::Z, &corners);
    let got = rec.eval(0, u as f32, v as f32).x as f64;
    (drawn / want, got / foot, sol.polygons[0].values.len())
}

/// Furnace: the largest relative error of any sample in any channel.
fn furnace(s: Setting) -> f64 {
    let rho = [0.5, 0.9, 0.2];
    let mut faces = Vec::new();
    for axis in 0..3 {
        for side in [0.0, 1.0] {
            let (a, b) = ((axis + 1) % 3, (axis + 2) % 3);
            let mut pts = [DVec3::ZERO; 4];
            for (k, (x, y)) in [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]
                .into_iter()
                .enumerate()
            {
                pts[k][axis] = side;
                pts[k][a] = x;
                pts[k][b] = y;
            }
            let mut inward = DVec3::ZERO;
            inward[axis] = 0.5 - side;
            faces.push(quad(pts, inward, 0));
        }
    }
    let cam = Camera {
        eye: DVec3::splat(0.5),
        look_at: DVec3::new(0.5, 0.5, 0.0),
        up: DVec3::Y,
        projection: Projection::Perspective { fov_y_deg: 60.0 },
    };
    let scene = Scene::new(cam, 64, 64, vec![material("furnace", rho, [1.0; 3])], faces);
    let (_, sol, _) = solved(scene, s);
    let mut worst = 0f64;
    for p in &sol.polygons {
        for v in &p.values {
            for (ch, r) in rho.iter().enumerate() {
                let want = 1.0 / (1.0 - r);
                worst = worst.max((v[ch] as f64 - want).abs() / want);
            }
        }
    }
    worst
}

fn main() {
    let settings = [
        Setting::Defaults,
        Setting::Tolerance(0.04),
        Setting::Tolerance(0.02),
        Setting::Tolerance(0.005),
        Setting::MaxDepth(3),
        Setting::MaxDepth(5),
        Setting::MaxDepth(9),
        Setting::Convergence(0.1),
        Setting::Convergence(0.03),
        Setting::Convergence(0.003),
    ];
    println!(
        "| setting | area light: max error / peak | max relative error (>= 1 % of peak) | \
         samples | off-lattice peak: error / peak | small emitter: drawn energy | \
         at its foot | samples | furnace: max relative error |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for s in settings {
        let (abs, rel, n_area) = area_light(s);
        let off = off_lattice_peak(s);
        let (energy, foot, n_small) = small_emitter(s);
        let f = furnace(s);
        println!(
            "| {} | {abs:.1e} | {rel:.1e} | {n_area} | {off:.1e} | {energy:.4} | {foot:.4} | \
             {n_small} | {f:.1e} |",
            s.label()
        );
    }
}
