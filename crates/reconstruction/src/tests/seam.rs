//! Seams: one C1 function across the shared edges of coplanar polygons of one material.
//!
//! The polygons are floor rectangles (y = 0) sampling one world function, each with its own
//! adaptive tree, so their lattices along the shared edge differ. Jumps are measured in f64 from
//! the stored f32 patches: value against the function's peak, slopes across against its largest
//! slope. The tolerances are f32 coefficient rounding: about 2^-24 of a value times the patch's
//! inverse width (up to 2^7 here) and the few terms of a derivative, a few 1e-6 of the largest
//! slope; without seams the slope jumps by percents (one-sided estimates on each side).

use super::*;
use glam::DVec3;
use scene::adjacency::Adjacency;
use scene::{Material, Polygon};

/// A floor rectangle x0..x0+w, z0..z0+h facing up: c0 at (x0, z0+h), u along +x, v along -z.
fn floor(x0: f64, z0: f64, w: f64, h: f64, material: u32) -> Polygon {
    Polygon::quad(
        [
            DVec3::new(x0, 0.0, z0 + h),
            DVec3::new(x0 + w, 0.0, z0 + h),
            DVec3::new(x0 + w, 0.0, z0),
            DVec3::new(x0, 0.0, z0),
        ],
        material,
        0,
    )
    .expect("valid quad")
}

fn materials(n: usize) -> Vec<Material> {
    (0..n)
        .map(|k| Material {
            name: format!("m{k}"),
            reflectance: DVec3::splat(0.5 + 0.1 * k as f64),
            emission: DVec3::ZERO,
        })
        .collect()
}

/// A bright spot near the shared edges of the layouts below.
fn light(p: DVec3) -> f64 {
    let d2 = (p.x - 0.8).powi(2) + (p.z - 0.2).powi(2);
    0.05 + (-d2 / (2.0 * 0.15 * 0.15)).exp()
}

/// Largest |gradient| of [`light`]: e^(-1/2) / sigma.
const MAX_SLOPE: f64 = 4.043_653_6;

/// Samples `light` on each polygon with its own criterion tree (tolerance `tols[k]`).
fn sampled(polys: &[Polygon], tols: &[f64]) -> Vec<SampledQuadtree> {
    polys
        .iter()
        .zip(tols)
        .map(|(p, &tol)| {
            let f = |u: f64, v: f64| light(p.point(u, v));
            let tree = criterion_tree(&f, 1, 7, tol);
            SampledQuadtree::from_fn(tree, |u, v| Vec3::splat(f(u, v) as f32))
        })
        .collect()
}

/// Largest value jump and cross-slope jump (world units) between two polygons along a shared
/// line, at `n` points: `at(s)` gives each polygon's (u, v) at parameter s, `across` each one's
/// world length per unit of its parameter across the line (signed) and which parameter it is.
/// A polygon and its (u, v) at each parameter along the line.
type OnLine = (u32, fn(f64) -> (f64, f64));

struct Line {
    a: OnLine,
    b: OnLine,
    /// Per polygon: (index of the cross parameter: 0 = u, 1 = v; world length per unit).
    across: [(usize, f64); 2],
}

fn jumps(rec: &Reconstruction, line: &Line, n: usize) -> (f64, f64) {
    let (mut jv, mut jd) = (0.0f64, 0.0f64);
    for k in 1..n {
        let s = k as f64 / n as f64;
        let mut vals = [0.0f64; 2];
        let mut slopes = [0.0f64; 2];
        for (x, ((poly, at), (axis, len))) in
            [line.a, line.b].into_iter().zip(line.across).enumerate()
        {
            let (u, v) = at(s);
            let (f, fu, fv) = rec.eval_grad(poly, u, v);
            vals[x] = f.x as f64;
            slopes[x] = [fu.x, fv.x][axis] as f64 / len;
        }
        jv = jv.max((vals[0] - vals[1]).abs());
        jd = jd.max((slopes[0] - slopes[1]).abs());
    }
    (jv, jd / MAX_SLOPE)
}

fn build(sq: &[SampledQuadtree], seams: &Seams) -> Reconstruction {
    Reconstruction::build_with(sq, Estimator::default(), seams, None).expect("valid input")
}

#[test]
fn a_split_floor_is_c1_across_its_seam() {
    // Two unit squares side by side at x = 1; the right one sampled five times finer.
    let polys = [floor(0.0, 0.0, 1.0, 1.0, 0), floor(1.0, 0.0, 1.0, 1.0, 0)];
    let mats = materials(1);
    let sq = sampled(&polys, &[1e-3, 2e-4]);
    let seams = Seams::of(&polys, &mats, &Adjacency::of(&polys));
    assert_eq!((seams.joined(), seams.unjoined()), (1, 0));
    // Polygon 0's u = 1 side and polygon 1's u = 0 side, both with v from z = 1 to z = 0; the
    // slope across is d/du = d/dx on both.
    let line = Line {
        a: (0, |s| (1.0, s)),
        b: (1, |s| (0.0, s)),
        across: [(0, 1.0), (0, 1.0)],
    };
    let (jv, jd) = jumps(&build(&sq, &seams), &line, 997);
    assert!(jv <= 1e-6, "value jump {jv:.2e} of the peak");
    assert!(jd <= 2e-5, "slope jump {jd:.2e} of the largest slope");
    // Each polygon alone: the one-sided slopes disagree by percents.
    let (alone_v, alone) = jumps(&build(&sq, &Seams::none()), &line, 997);
    eprintln!("split floor: joined value {jv:.2e} slope {jd:.2e}; alone value {alone_v:.2e} slope {alone:.2e}");
    assert!(
        alone > 1e-3,
        "without seams the slope jump is only {alone:.2e}"
    );
    // And it is no further from the function near the seam than each polygon alone.
    let near = |rec: &Reconstruction| {
        let mut worst = 0.0f64;
        for k in 0..=200 {
            for (p, u) in [(0u32, 0.97), (0, 1.0), (1, 0.0), (1, 0.03)] {
                let v = k as f64 / 200.0;
                let x = polys[p as usize].point(u, v);
                worst = worst.max((rec.eval(p, u as f32, v as f32).x as f64 - light(x)).abs());
            }
        }
        worst
    };
    let (e_joined, e_alone) = (near(&build(&sq, &seams)), near(&build(&sq, &Seams::none())));
    eprintln!("split floor: error near the seam joined {e_joined:.2e}, alone {e_alone:.2e}");
    assert!(
        e_joined <= e_alone,
        "joined {e_joined:.2e}, alone {e_alone:.2e}"
    );
}

#[test]
fn an_l_corner_joins_a_half_edge() {
    // A 2 x 1 strip (z in 0..1) and a unit square below its first half (z in -1..0).
    let polys = [floor(0.0, 0.0, 2.0, 1.0, 0), floor(0.0, -1.0, 1.0, 1.0, 0)];
    let mats = materials(1);
    let sq = sampled(&polys, &[3e-4, 1e-3]);
    let seams = Seams::of(&polys, &mats, &Adjacency::of(&polys));
    assert_eq!((seams.joined(), seams.unjoined()), (1, 0));
    // World x in 0..1 along z = 0: the strip's v = 1 side at u = x / 2, the square's v = 0 side
    // at u = x; the slope across is d/dv = -d/dz on both (v along -z, unit length).
    let line = Line {
        a: (0, |s| (0.5 * s, 1.0)),
        b: (1, |s| (s, 0.0)),
        across: [(1, 1.0), (1, 1.0)],
    };
    let (jv, jd) = jumps(&build(&sq, &seams), &line, 997);
    assert!(jv <= 1e-6, "value jump {jv:.2e} of the peak");
    assert!(jd <= 2e-5, "slope jump {jd:.2e} of the largest slope");
    let (alone_v, alone_d) = jumps(&build(&sq, &Seams::none()), &line, 997);
    eprintln!("L corner: joined value {jv:.2e} slope {jd:.2e}; alone value {alone_v:.2e} slope {alone_d:.2e}");
    assert!(
        alone_d > 1e-3,
        "without seams the slope jump is only {alone_d:.2e}"
    );
    assert!(
        alone_v > jv,
        "without seams the value step is {alone_v:.2e}"
    );
}

#[test]
fn a_tiled_floor_is_c1_at_its_four_way_corner() {
    // Four tiles of width 1 and depth 0.5 meeting at x = 1, z = 0.5.
    let polys = [
        floor(0.0, 0.5, 1.0, 0.5, 0),
        floor(1.0, 0.5, 1.0, 0.5, 0),
        floor(0.0, 0.0, 1.0, 0.5, 0),
        floor(1.0, 0.0, 1.0, 0.5, 0),
    ];
    let mats = materials(1);
    let sq = sampled(&polys, &[1e-3, 3e-4, 5e-4, 2e-4]);
    let seams = Seams::of(&polys, &mats, &Adjacency::of(&polys));
    assert_eq!(seams.joined(), 4);
    let rec = build(&sq, &seams);
    // The vertical seam x = 1 between the lower tiles and between the upper tiles, and the
    // horizontal seam z = 0.5 (v across, world length 0.5 per unit of v).
    let lines = [
        Line {
            a: (0, |s| (1.0, s)),
            b: (1, |s| (0.0, s)),
            across: [(0, 1.0), (0, 1.0)],
        },
        Line {
            a: (2, |s| (1.0, s)),
            b: (3, |s| (0.0, s)),
            across: [(0, 1.0), (0, 1.0)],
        },
        Line {
            a: (0, |s| (s, 1.0)),
            b: (2, |s| (s, 0.0)),
            across: [(1, 0.5), (1, 0.5)],
        },
    ];
    for line in &lines {
        let (jv, jd) = jumps(&rec, line, 499);
        assert!(jv <= 1e-6, "value jump {jv:.2e} of the peak");
        assert!(jd <= 2e-5, "slope jump {jd:.2e} of the largest slope");
    }
    // The corner itself: one value from all four.
    let at = [(0, 1.0, 1.0), (1, 0.0, 1.0), (2, 1.0, 0.0), (3, 0.0, 0.0)];
    let vals: Vec<f64> = at
        .iter()
        .map(|&(p, u, v)| rec.eval(p, u, v).x as f64)
        .collect();
    let spread = vals.iter().cloned().fold(f64::MIN, f64::max)
        - vals.iter().cloned().fold(f64::MAX, f64::min);
    assert!(spread <= 1e-6, "corner values {vals:?}");
}

#[test]
fn different_materials_are_not_joined() {
    let polys = [floor(0.0, 0.0, 1.0, 1.0, 0), floor(1.0, 0.0, 1.0, 1.0, 1)];
    let mats = materials(2);
    let seams = Seams::of(&polys, &mats, &Adjacency::of(&polys));
    assert_eq!((seams.joined(), seams.unjoined()), (0, 0));
    assert!(seams.is_empty());
}

#[test]
fn a_non_dyadic_t_junction_is_counted_not_joined() {
    // A 3 x 1 strip and a unit square under its first third.
    let polys = [floor(0.0, 0.0, 3.0, 1.0, 0), floor(0.0, -1.0, 1.0, 1.0, 0)];
    let seams = Seams::of(&polys, &materials(1), &Adjacency::of(&polys));
    assert_eq!((seams.joined(), seams.unjoined()), (0, 1));
}

#[test]
fn compact_and_expanded_rrps_join_alike() {
    let polys = [floor(0.0, 0.0, 1.0, 1.0, 0), floor(1.0, 0.0, 1.0, 1.0, 0)];
    let sq = sampled(&polys, &[1e-3, 2e-4]);
    let seams = Seams::of(&polys, &materials(1), &Adjacency::of(&polys));
    let rec = build(&sq, &seams);
    let c =
        crate::compact::CompactReconstruction::build_with(&sq, Estimator::default(), &seams, None)
            .expect("valid input");
    let mut worst = 0.0f64;
    for p in 0..2u32 {
        for k in 0..=64 {
            let v = k as f32 / 64.0;
            let u = if p == 0 { 1.0 } else { 0.0 };
            let id = c.locate(p, u, v);
            let a = c.expand(id).eval(u, v).x as f64;
            worst = worst.max((a - rec.eval(p, u, v).x as f64).abs());
        }
    }
    // Quantized vertex data: at most 2^-15 of each quantity (the compact RRPs' bound, docs/compact-rrps.md), here well
    // below 1e-4 of the peak.
    assert!(
        worst <= 1e-4,
        "compact differs from expanded by {worst:.2e}"
    );
}

#[test]
fn slivers_and_needles_are_left_apart() {
    // A 1 x 1e-6 strip under a unit square, and a needle triangle beside the square.
    let polys = [
        floor(0.0, 0.0, 1.0, 1.0, 0),
        floor(0.0, 1.0, 1.0, 1e-6, 0),
        Polygon::triangle(
            [
                DVec3::new(1.0, 0.0, 1.0),
                DVec3::new(1.0 + 1e-6, 0.0, 0.5),
                DVec3::new(1.0, 0.0, 0.0),
            ],
            0,
            0,
        )
        .expect("valid triangle"),
    ];
    let adj = Adjacency::of(&polys);
    assert!(adj.edges.len() >= 2, "{adj:?}");
    let seams = Seams::of(&polys, &materials(1), &adj);
    assert_eq!(seams.joined(), 0);
    assert!(seams.unjoined() >= 2);
}

#[test]
fn a_wall_standing_on_the_seam_keeps_the_floors_apart() {
    let wall = Polygon::quad(
        [
            DVec3::new(1.0, 0.0, 1.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(1.0, 1.0, 1.0),
        ],
        0,
        0,
    )
    .expect("valid quad");
    let polys = [
        floor(0.0, 0.0, 1.0, 1.0, 0),
        floor(1.0, 0.0, 1.0, 1.0, 0),
        wall,
    ];
    let seams = Seams::of(&polys, &materials(1), &Adjacency::of(&polys));
    assert_eq!((seams.joined(), seams.standing()), (0, 1));
}

/// Two floor polygons side by side are one surface unless the light steps where they meet:
/// along a step the loader cut (a lamp's outline on a ceiling, `scene::contact`) they stay
/// apart, whether the step covers the shared side or reaches past it; a step beside the side,
/// across it, or along only its continuation past the polygons joins them as before.
#[test]
fn a_cut_step_along_the_seam_keeps_the_floors_apart() {
    let polys = [floor(0.0, 0.0, 1.0, 1.0, 0), floor(1.0, 0.0, 1.0, 1.0, 0)];
    let adjacency = Adjacency::of(&polys);
    let joined = |steps: &[(DVec3, DVec3)]| {
        let s = Seams::apart_along(&polys, &materials(1), &adjacency, steps);
        (s.joined(), s.standing())
    };
    let p = |x: f64, z: f64| DVec3::new(x, 0.0, z);
    assert_eq!(joined(&[]), (1, 0));
    assert_eq!(joined(&[(p(1.0, 0.0), p(1.0, 1.0))]), (0, 1));
    assert_eq!(joined(&[(p(1.0, 1.5), p(1.0, -0.5))]), (0, 1));
    assert_eq!(joined(&[(p(1.01, 0.0), p(1.01, 1.0))]), (1, 0));
    assert_eq!(joined(&[(p(0.5, 0.5), p(1.5, 0.5))]), (1, 0));
    assert_eq!(joined(&[(p(1.0, 1.2), p(1.0, 3.0))]), (1, 0));
}

#[test]
fn a_shadow_line_on_the_seam_keeps_the_floors_apart() {
    // Lit left of x = 1, a tenth as bright right of it: the samples on the seam disagree, so
    // the light is discontinuous there and each polygon keeps its own reconstruction.
    let polys = [floor(0.0, 0.0, 1.0, 1.0, 0), floor(1.0, 0.0, 1.0, 1.0, 0)];
    let sq: Vec<SampledQuadtree> = polys
        .iter()
        .enumerate()
        .map(|(k, p)| {
            let level = if k == 0 { 1.0 } else { 0.1 };
            let f = |u: f64, v: f64| level * light(p.point(u, v));
            SampledQuadtree::from_fn(criterion_tree(&f, 2, 6, 1e-3), |u, v| {
                Vec3::splat(f(u, v) as f32)
            })
        })
        .collect();
    let seams = Seams::of(&polys, &materials(1), &Adjacency::of(&polys));
    assert_eq!(seams.joined(), 1);
    let joined = build(&sq, &seams);
    let apart = build(&sq, &Seams::none());
    assert_eq!(joined.patches(), apart.patches());
}

/// Vertices (z, colour) of polygon `p`'s mesh triangles lying on the line x = 1, in z order.
fn mesh_seam_vertices(mesh: &mesh::MeshModel, p: u32) -> Vec<(f64, f32)> {
    let mut out = Vec::new();
    for (k, tri) in mesh.scene.polygons.iter().enumerate() {
        if mesh.source_polygon[k] != p {
            continue;
        }
        let c = mesh.patch(k).c[0];
        let colours = [c[0], c[0] + c[1], c[0] + c[4]];
        for (corner, colour) in tri.corners[..3].iter().zip(colours) {
            if (corner.x - 1.0).abs() < 1e-12 {
                out.push((corner.z, colour));
            }
        }
    }
    out.sort_by(|a, b| a.0.total_cmp(&b.0));
    out.dedup_by(|a, b| (a.0 - b.0).abs() < 1e-12);
    out
}

#[test]
fn the_mesh_shares_its_vertices_across_a_seam() {
    let polys = [floor(0.0, 0.0, 1.0, 1.0, 0), floor(1.0, 0.0, 1.0, 1.0, 0)];
    let sq = sampled(&polys, &[1e-3, 2e-4]);
    let camera = scene::Camera {
        eye: DVec3::new(1.0, 2.0, 0.5),
        look_at: DVec3::new(1.0, 0.0, 0.5),
        up: DVec3::Z,
        projection: scene::Projection::Orthographic {
            width: 2.0,
            height: 1.0,
        },
    };
    let scene = scene::Scene::new(camera, 64, 32, materials(1), polys.to_vec());
    let seams = Seams::of(&polys, &materials(1), &Adjacency::of(&polys));
    let joined = mesh::MeshModel::build_with(&scene, &sq, &seams).expect("mesh");
    let (a, b) = (
        mesh_seam_vertices(&joined, 0),
        mesh_seam_vertices(&joined, 1),
    );
    assert!(a.len() > 8, "{a:?}");
    assert_eq!(a.len(), b.len(), "both sides carry every seam point");
    for ((za, ca), (zb, cb)) in a.iter().zip(&b) {
        assert!((za - zb).abs() < 1e-12);
        // Gouraud colours recovered from f32 power coefficients: a few ulps.
        assert!(
            (ca - cb).abs() <= 4e-7 * ca.abs().max(1e-3),
            "{za}: {ca} vs {cb}"
        );
    }
    // Apart, the finer side has points the coarser lacks: T-junctions across the seam.
    let apart = mesh::MeshModel::build(&scene, &sq).expect("mesh");
    assert_ne!(
        mesh_seam_vertices(&apart, 0).len(),
        mesh_seam_vertices(&apart, 1).len()
    );
}

/// Largest value step across the x = 1 seam of the split floor between the two polygons'
/// textures of sides `sides` (level 0, `filter`, `gutter` texels beyond each edge), in units of
/// the light's peak (about 1.05: the step itself is a bound on the relative step).
fn texture_step(
    rec: &Reconstruction,
    sides: (u32, u32),
    placement: Placement,
    filter: texture::Filter,
    gutter: u32,
) -> f64 {
    let a = texture::RadiosityTexture::from_rrp(rec, 0, (sides.0, sides.0), placement, gutter);
    let b = texture::RadiosityTexture::from_rrp(rec, 1, (sides.1, sides.1), placement, gutter);
    (1..500)
        .map(|k| {
            let v = k as f32 / 500.0;
            let (x, y) = (a.sample(0, 1.0, v, filter).x, b.sample(0, 0.0, v, filter).x);
            (x - y).abs() as f64
        })
        .fold(0.0, f64::max)
}

#[test]
fn lightmap_textures_meet_at_a_joined_seam() {
    let polys = [floor(0.0, 0.0, 1.0, 1.0, 0), floor(1.0, 0.0, 1.0, 1.0, 0)];
    let sq = sampled(&polys, &[1e-3, 2e-4]);
    let seams = Seams::of(&polys, &materials(1), &Adjacency::of(&polys));
    let (joined, apart) = (build(&sq, &seams), build(&sq, &Seams::none()));
    let bilinear = texture::Filter::Bilinear;
    let mitchell = texture::Filter::MITCHELL;
    // Corner placement puts texels on the edge: the joined RRPs' one edge curve, sampled at the
    // same points on both sides, so bilinear textures meet to f32 rounding of the resampling.
    let corner = texture_step(&joined, (64, 64), Placement::Corner, bilinear, 0);
    let corner_apart = texture_step(&apart, (64, 64), Placement::Corner, bilinear, 0);
    assert!(corner <= 1e-6, "corner-placed seam step {corner:.2e}");
    assert!(corner_apart > 100.0 * corner, "apart {corner_apart:.2e}");
    // Without gutters, centre placement clamps half a texel inside each polygon (a step of
    // about the slope times one texel) and the Mitchell-Netravali filter (B = 1/3, which does
    // not interpolate) blends clamped texels differently on the two sides. With the gutters
    // (texels reflected through the RRP's edge values) either filter returns, at the edge, the
    // edge values interpolated along it: on one lattice the two sides agree to f32 rounding.
    for (placement, filter) in [
        (Placement::Centre, bilinear),
        (Placement::Centre, mitchell),
        (Placement::Corner, mitchell),
    ] {
        let clamped = texture_step(&joined, (64, 64), placement, filter, 0);
        let gutter = texture_step(&joined, (64, 64), placement, filter, texture::GUTTER);
        eprintln!(
            "textures 64^2 {placement:?} {filter:?}: step {clamped:.2e} clamped to the edge, \
             {gutter:.2e} with gutters"
        );
        assert!(gutter <= 1e-6, "{placement:?} {filter:?}: {gutter:.2e}");
        assert!(clamped >= 1e-3, "{placement:?} {filter:?}: {clamped:.2e}");
    }
    // Sides of different sizes sample the edge at different points: what is left is the
    // coarser texture's own interpolation error along the edge (about h^2 |f_vv| / 8 for
    // bilinear, up to 5e-3 at h = 1/32 for this light), not a seam of the gutters' making.
    for (sides, placement, filter) in [
        ((64, 32), Placement::Centre, bilinear),
        ((64, 32), Placement::Centre, mitchell),
        ((32, 16), Placement::Corner, bilinear),
    ] {
        let gutter = texture_step(&joined, sides, placement, filter, texture::GUTTER);
        let coarse = texture::RadiosityTexture::from_rrp(
            &joined,
            1,
            (sides.1, sides.1),
            placement,
            texture::GUTTER,
        );
        let own = (1..500)
            .map(|k| {
                let v = k as f32 / 500.0;
                (coarse.sample(0, 0.0, v, filter).x - joined.eval(1, 0.0, v).x).abs() as f64
            })
            .fold(0.0, f64::max);
        eprintln!(
            "textures {sides:?} {placement:?} {filter:?}: step {gutter:.2e} with gutters, \
             the coarser side's own error along the edge {own:.2e}"
        );
        assert!(gutter <= own + 1e-6, "{sides:?}: {gutter:.2e} > {own:.2e}");
    }
}

/// A unit floor square and a square hinged to it at x = 1, rising at `degrees`.
fn hinged(degrees: f64) -> [Polygon; 2] {
    let (c, s) = (degrees.to_radians().cos(), degrees.to_radians().sin());
    let ramp = Polygon::quad(
        [
            DVec3::new(1.0, 0.0, 1.0),
            DVec3::new(1.0 + c, s, 1.0),
            DVec3::new(1.0 + c, s, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
        ],
        0,
        0,
    )
    .expect("valid quad");
    [floor(0.0, 0.0, 1.0, 1.0, 0), ramp]
}

/// The fold line of [`hinged`]: polygon 0's u = 1 side, polygon 1's u = 0 side.
const HINGE: Line = Line {
    a: (0, |s| (1.0, s)),
    b: (1, |s| (0.0, s)),
    across: [(0, 1.0), (0, 1.0)],
};

/// A gentle fold (10 degrees) of one material under light that is continuous across it: joined
/// in value (C0: the two edge cubics are one curve, to f32 rounding) while each side keeps its
/// slope across. Apart, the two sides' edge cubics (different lattices, one-sided along-edge
/// slopes) step by about 1e-4 of the peak between samples.
#[test]
fn a_gentle_fold_is_c0() {
    let polys = hinged(10.0);
    let mats = materials(1);
    let sq = sampled(&polys, &[1e-3, 2e-4]);
    let seams = Seams::of(&polys, &mats, &Adjacency::of(&polys));
    assert_eq!((seams.joined(), seams.folds()), (1, 1));
    let (jv, _) = jumps(&build(&sq, &seams), &HINGE, 997);
    let (apart, _) = jumps(&build(&sq, &Seams::none()), &HINGE, 997);
    eprintln!("gentle fold: value step joined {jv:.2e}, apart {apart:.2e}");
    assert!(jv <= 1e-6, "value step {jv:.2e} of the peak");
    assert!(apart >= 10.0 * jv.max(1e-7), "apart only {apart:.2e}");
}

/// A sharp crease (45 degrees, a wall on a floor) is not joined: the light there steps. Nor is a
/// gentle fold whose two sides' samples disagree (a light that steps at the fold): it keeps its
/// step.
#[test]
fn sharp_creases_and_stepping_folds_stay_apart() {
    let polys = hinged(45.0);
    let seams = Seams::of(&polys, &materials(1), &Adjacency::of(&polys));
    assert_eq!((seams.joined(), seams.folds()), (0, 0));

    let polys = hinged(10.0);
    let seams = Seams::of(&polys, &materials(1), &Adjacency::of(&polys));
    let mut sq = sampled(&polys, &[1e-3, 1e-3]);
    for v in &mut sq[1].values {
        *v *= 1.1;
    }
    let (step, _) = jumps(&build(&sq, &seams), &HINGE, 997);
    // The light there is about 0.05-1.05; a 10 % step stays a step of at least 0.5 % of the peak.
    assert!(step >= 5e-3, "the step was smoothed away: {step:.2e}");
}

/// A unit square split along its diagonal into two triangles (the diagonal is each one's u = 0
/// side, slanted 45 degrees from its cross axis): joined C0, the value along the diagonal is one
/// curve (to f32 rounding) where apart the two sides' edge cubics step by about 1e-4 of the peak.
#[test]
fn triangles_are_joined_c0_along_a_slanted_side() {
    let (p, q) = (DVec3::new(0.0, 0.0, 1.0), DVec3::new(1.0, 0.0, 0.0));
    let polys = [
        Polygon::triangle([p, DVec3::new(1.0, 0.0, 1.0), q], 0, 0).expect("valid triangle"),
        Polygon::triangle([q, DVec3::new(0.0, 0.0, 0.0), p], 0, 0).expect("valid triangle"),
    ];
    let seams = Seams::of(&polys, &materials(1), &Adjacency::of(&polys));
    assert_eq!(
        (seams.joined(), seams.slanted(), seams.unjoined()),
        (1, 1, 0)
    );
    let sq = sampled(&polys, &[1e-3, 2e-4]);
    // Polygon 0 runs from p (v = 0) to q (v = 1) along u = 0, polygon 1 the other way.
    let line = Line {
        a: (0, |s| (0.0, s)),
        b: (1, |s| (0.0, 1.0 - s)),
        across: [(0, 1.0), (0, 1.0)],
    };
    let (jv, _) = jumps(&build(&sq, &seams), &line, 997);
    let (apart, _) = jumps(&build(&sq, &Seams::none()), &line, 997);
    eprintln!("triangles: value step joined {jv:.2e}, apart {apart:.2e}");
    assert!(jv <= 1e-6, "value step {jv:.2e} of the peak");
    assert!(apart >= 10.0 * jv.max(1e-7), "apart only {apart:.2e}");
}

/// The step index finds what testing every step finds: for random segments (long and short,
/// any direction) and random points near and far, every step within the query's reach of the
/// point is among those it tests, so `any` with a distance predicate answers as the linear
/// scan does.
mod step_index {
    use crate::seam::StepIndex;
    use glam::DVec3;
    use proptest::prelude::*;

    fn v() -> impl Strategy<Value = DVec3> {
        (-10.0f64..10.0, -10.0f64..10.0, -10.0f64..10.0).prop_map(|(x, y, z)| DVec3::new(x, y, z))
    }

    fn distance(x: DVec3, (p, q): (DVec3, DVec3)) -> f64 {
        let d = q - p;
        let t = ((x - p).dot(d) / d.length_squared().max(f64::MIN_POSITIVE)).clamp(0.0, 1.0);
        (p + d * t).distance(x)
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]
        #[test]
        fn finds_what_a_linear_scan_finds(
            ends in prop::collection::vec((v(), v(), 0.001f64..1.0), 1..40),
            points in prop::collection::vec((v(), 0usize..40, 0.0f64..1.0), 1..40),
            reach in 1e-6f64..0.5,
        ) {
            // Steps of every length: the second end pulled toward the first.
            let steps: Vec<(DVec3, DVec3)> =
                ends.iter().map(|&(p, q, s)| (p, p + (q - p) * s)).collect();
            let index = StepIndex::new(&steps);
            for &(x, near, f) in &points {
                // Half the points on or beside a step, the rest anywhere.
                let x = if f < 0.5 {
                    let (p, q) = steps[near % steps.len()];
                    p + (q - p) * (2.0 * f) + DVec3::splat(reach * 0.5)
                } else {
                    x
                };
                let within = |s: &(DVec3, DVec3)| distance(x, *s) <= reach;
                prop_assert_eq!(index.any(x, reach, within), steps.iter().any(within));
            }
        }
    }
}
