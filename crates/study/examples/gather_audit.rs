//! A gather audit: the solver's irradiance G at points of a polygon against a Monte Carlo
//! gather of the solver's own radiosity (cosine-weighted rays from the point, the radiosity at
//! each hit evaluated exactly by the oracle), split by the polygon each ray hits, and with
//! `--by-patch`, by the patches of one source polygon (each with its total, what it shoots,
//! against the mean of the exact radiosity over it). Both sides use the same solution, so a
//! difference is the solver's transport (its form factors, visibility and the patches' shapes)
//! or a patch shooting other light than it has, not the solution's light against physics: a
//! consistency check of the transfer, with the Monte Carlo standard error beside it.
//!
//! ```text
//! cargo run --release -p pixelflow-study --example gather_audit -- \
//!     SCENE POLYGON U,V [U,V ...] [--rays N] [--by-patch SOURCE]
//! ```
//!
//! The scene is solved at its own settings. A hit's (u, v) inverts its polygon's bilinear map
//! of the corners (Newton's method). The rays are an R2 low-discrepancy set over the
//! cosine-weighted hemisphere, the same for every point, so two runs give the same numbers.

use std::collections::BTreeMap;
use std::path::PathBuf;

use base::quadtree::Cell;
use glam::DVec3;
use radiosity::{solve, Oracle, ShooterKind, Solution, SolveOptions};
use rayon::prelude::*;
use scene::bvh::Bvh;
use scene::{Polygon, Scene};

/// What to audit.
struct Args {
    scene: PathBuf,
    polygon: usize,
    points: Vec<(f64, f64)>,
    rays: u64,
    by_patch: Option<u32>,
}

const USAGE: &str =
    "usage: gather_audit SCENE POLYGON U,V [U,V ...] [--rays N] [--by-patch SOURCE]";

fn parse_args() -> Result<Args, String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (Some(scene), Some(polygon)) = (args.first(), args.get(1)) else {
        return Err(USAGE.into());
    };
    let number = |s: &str| s.parse::<f64>().map_err(|e| format!("{s}: {e}"));
    let mut out = Args {
        scene: PathBuf::from(scene),
        polygon: polygon
            .parse()
            .map_err(|e| format!("POLYGON {polygon}: {e}"))?,
        points: Vec::new(),
        rays: 200_000,
        by_patch: None,
    };
    let mut rest = args[2..].iter();
    while let Some(a) = rest.next() {
        let mut value = || rest.next().ok_or(format!("{a} needs a value"));
        match a.as_str() {
            "--rays" => out.rays = value()?.parse().map_err(|e| format!("--rays: {e}"))?,
            "--by-patch" => {
                out.by_patch = Some(value()?.parse().map_err(|e| format!("--by-patch: {e}"))?)
            }
            uv => {
                let (u, v) = uv
                    .split_once(',')
                    .ok_or(format!("{uv}: not U,V\n{USAGE}"))?;
                out.points.push((number(u)?, number(v)?));
            }
        }
    }
    if out.points.is_empty() || out.rays < 2 {
        return Err(USAGE.into());
    }
    Ok(out)
}

fn lum(c: DVec3) -> f64 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

/// (u, v) of `x` on `p`: the bilinear map of its corners ([`Polygon::point`]) inverted by
/// Newton's method from the parallelogram of corners 0, 1 and 3 (exact there in one step).
fn uv_of(p: &Polygon, x: DVec3) -> (f64, f64) {
    let solve = |a: DVec3, b: DVec3, d: DVec3| {
        let (aa, ab, bb) = (a.dot(a), a.dot(b), b.dot(b));
        let (da, db) = (d.dot(a), d.dot(b));
        let det = aa * bb - ab * ab;
        ((da * bb - db * ab) / det, (db * aa - da * ab) / det)
    };
    let (mut u, mut v) = (0.5, 0.5);
    for _ in 0..12 {
        let (a, b) = p.tangents(u, v);
        let (du, dv) = solve(a, b, x - p.point(u, v));
        (u, v) = (u + du, v + dv);
        if du.abs() + dv.abs() < 1e-14 {
            break;
        }
    }
    (u, v)
}

/// Point `i` of the R2 sequence in the unit square.
fn r2(i: u64) -> (f64, f64) {
    const G: f64 = 1.324_717_957_244_746;
    let (a1, a2) = (1.0 / G, 1.0 / (G * G));
    ((0.5 + a1 * i as f64).fract(), (0.5 + a2 * i as f64).fract())
}

/// One ray's hit: the polygon (`u32::MAX`: none), the luminance of its radiosity there (0 on
/// a polygon's back, which sends nothing), and where.
#[derive(Clone, Copy)]
struct Hit {
    polygon: u32,
    light: f64,
    uv: (f64, f64),
}

/// The polygons `rays` cosine-weighted rays from point (u, v) of polygon `r` hit.
fn cast(
    scene: &Scene,
    (oracle, bvh): (&Oracle<'_>, &Bvh),
    r: usize,
    (u, v): (f64, f64),
    rays: u64,
) -> Vec<Hit> {
    let p = &scene.polygons[r];
    let (x, n) = (p.point(u, v), p.normal);
    let t = if n.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
    let t1 = n.cross(t).normalize();
    let t2 = n.cross(t1);
    let reach = 1e3 * p.bounding_sphere().1.max(10.0);
    let none = Hit {
        polygon: u32::MAX,
        light: 0.0,
        uv: (0.0, 0.0),
    };
    (0..rays)
        .into_par_iter()
        .map(|i| {
            let (s1, s2) = r2(i);
            let (rad, phi) = (s1.sqrt(), std::f64::consts::TAU * s2);
            let d = t1 * (rad * phi.cos()) + t2 * (rad * phi.sin()) + n * (1.0 - s1).sqrt();
            let Some((h, t)) = bvh.first_hit_from(x, d * reach, 1e-9, [r as u32, r as u32]) else {
                return none;
            };
            let q = &scene.polygons[h as usize];
            if d.dot(q.normal) >= 0.0 {
                return Hit { polygon: h, ..none };
            }
            let uv = uv_of(q, x + d * reach * t);
            let light = lum(oracle.radiosity(h as usize, uv.0, uv.1).as_dvec3());
            Hit {
                polygon: h,
                light,
                uv,
            }
        })
        .collect()
}

/// Mean and standard error over `n` rays of the light of the hits `which` selects (the others
/// count as 0).
fn mean_se(hits: &[Hit], which: impl Fn(&Hit) -> bool) -> (f64, f64) {
    let n = hits.len() as f64;
    let (s1, s2) = hits
        .iter()
        .filter(|h| which(h))
        .fold((0.0, 0.0), |(a, b), h| (a + h.light, b + h.light * h.light));
    let m = s1 / n;
    (m, ((s2 / n - m * m) / (n - 1.0)).max(0.0).sqrt())
}

/// The solver's G at (u, v) of polygon `r` from the shooters of polygon `source` alone (of its
/// patch `cell` alone if given): the solution with every other shooter's total set to 0.
fn solver_share(
    scene: &Scene,
    sol: &Solution,
    (r, u, v): (usize, f64, f64),
    source: u32,
    cell: Option<Cell>,
) -> f64 {
    solver_share_of(scene, sol.clone(), (r, u, v), source, cell)
}

/// [`solver_share`] of the solution `only` (taken by value, so a caller can change it first).
fn solver_share_of(
    scene: &Scene,
    mut only: Solution,
    (r, u, v): (usize, f64, f64),
    source: u32,
    cell: Option<Cell>,
) -> f64 {
    for sh in only.shooters.iter_mut() {
        let keep = match sh.kind {
            ShooterKind::Patch { polygon, cell: c } => {
                polygon == source && cell.is_none_or(|want| want == c)
            }
            ShooterKind::Emitter { polygon } => polygon == source && cell.is_none(),
            ShooterKind::Spot { .. } => false,
        };
        if !keep {
            sh.total = DVec3::ZERO;
        }
    }
    let oracle = Oracle::new(&only, scene).expect("the solution is this scene's");
    g_at(scene, &oracle, (r, u, v))
}

/// Irradiance G (luminance) at (u, v) of polygon `r`: its radiosity less its emission, over
/// its reflectance.
fn g_at(scene: &Scene, oracle: &Oracle<'_>, (r, u, v): (usize, f64, f64)) -> f64 {
    let m = scene.material_of(r);
    let b = oracle.radiosity(r, u, v).as_dvec3();
    lum((b - m.emission) / m.reflectance.max(DVec3::splat(1e-30)))
}

/// Per patch of polygon `source`: its total against the area-weighted mean of the exact
/// radiosity over it (64 x 64 midpoints), and its share of the point's light against the rays
/// that hit it.
fn report_patches(
    scene: &Scene,
    (sol, oracle): (&Solution, &Oracle<'_>),
    hits: &[Hit],
    at: (usize, f64, f64),
    source: u32,
) {
    let q = &scene.polygons[source as usize];
    for sh in &sol.shooters {
        let ShooterKind::Patch { polygon, cell } = sh.kind else {
            continue;
        };
        if polygon != source {
            continue;
        }
        let (u0, v0, u1, v1) = cell.bounds();
        let m = 64;
        let (mut sb, mut sa) = (0.0, 0.0);
        for i in 0..m * m {
            let pu = u0 + (u1 - u0) * ((i % m) as f64 + 0.5) / m as f64;
            let pv = v0 + (v1 - v0) * ((i / m) as f64 + 0.5) / m as f64;
            let a = q.area_element(pu, pv);
            sb += a * lum(oracle.radiosity(source as usize, pu, pv).as_dvec3());
            sa += a;
        }
        let total = lum(sh.total);
        let inside = |h: &Hit| {
            h.polygon == source && (u0..u1).contains(&h.uv.0) && (v0..v1).contains(&h.uv.1)
        };
        let (mc, se) = mean_se(hits, inside);
        let g = solver_share(scene, sol, at, source, Some(cell));
        // The same with the patch's light taken as uniform on both sides: what is left is the
        // geometry (visibility and form factors), not the shape.
        let hit_share = hits.iter().filter(|h| inside(h)).count() as f64 / hits.len() as f64;
        let mut flat = sol.clone();
        for f in flat.shooters.iter_mut() {
            if matches!(f.kind, ShooterKind::Patch { polygon: p, cell: c } if p == source && c == cell)
            {
                f.shape = None;
            }
        }
        let g_flat = solver_share_of(scene, flat, at, source, Some(cell));
        println!(
            "      its light taken as uniform: Monte Carlo {:.4e}, solver {g_flat:.4e}, ratio {:.4}",
            hit_share * total,
            g_flat / (hit_share * total)
        );
        println!(
            "    patch u {u0:.3}-{u1:.3} v {v0:.3}-{v1:.3}: total {total:.5e} against the exact mean {:.5e} ({:.4}); Monte Carlo {mc:.4e} +- {se:.1e}, solver {g:.4e}, ratio {:.4}",
            sb / sa,
            total / (sb / sa),
            g / mc
        );
    }
}

fn main() {
    let args = match parse_args() {
        Ok(a) => a,
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(2);
        }
    };
    let scene = scene::load_scene(&args.scene).unwrap_or_else(|e| {
        eprintln!("{e}");
        std::process::exit(2);
    });
    let r = args.polygon;
    if r >= scene.polygons.len() {
        eprintln!(
            "POLYGON {r}: the scene has {} polygons",
            scene.polygons.len()
        );
        std::process::exit(2);
    }
    let sol = solve(&scene, &SolveOptions::default()).expect("the scene solves");
    let oracle = Oracle::new(&sol, &scene).expect("the solution is this scene's");
    let bvh = Bvh::build(&scene.polygons);
    for &(u, v) in &args.points {
        let hits = cast(&scene, (&oracle, &bvh), r, (u, v), args.rays);
        let (mc, se) = mean_se(&hits, |_| true);
        let g = g_at(&scene, &oracle, (r, u, v));
        println!(
            "point ({u:.4}, {v:.4}) of polygon {r}: solver G {g:.6e}, Monte Carlo {mc:.6e} +- {se:.2e}, ratio {:.4}",
            g / mc
        );
        let sources: BTreeMap<u32, ()> = hits.iter().map(|h| (h.polygon, ())).collect();
        for &h in sources.keys() {
            let (mc, se) = mean_se(&hits, |x| x.polygon == h);
            if h == u32::MAX {
                println!("  escaped    Monte Carlo {mc:.6e}");
                continue;
            }
            let g = solver_share(&scene, &sol, (r, u, v), h, None);
            println!(
                "  from {h:<5} Monte Carlo {mc:.6e} +- {se:.1e}, solver {g:.6e}, ratio {:.4}",
                g / mc
            );
        }
        if let Some(source) = args.by_patch {
            report_patches(&scene, (&sol, &oracle), &hits, (r, u, v), source);
        }
    }
}
