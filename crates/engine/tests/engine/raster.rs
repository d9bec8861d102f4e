//! Tests of the renderer: watertightness, clipping, perspective-correct (u, v), the direct
//! method against the patch source at pixel centres, antialiasing, and determinism over threads and
//! renderers. Scenes are built in code; the patch sources are analytic.

use engine::frame::{render_patches as render_frame, Frame, FrameOptions};
use engine::raster::geometry::{Plane, ScreenPolygon};
use engine::raster::region::coverage_counts;
use engine::raster::region::RegionGrid;
use engine::raster::setup::{setup, ONE};
use engine::raster::{
    bin_round_robin_into, build_and_bin_into, build_primitives, build_primitives_into,
};
use engine::shading::{PatchCoeffs, PatchSource};
use glam::{DVec3, Vec3};
use proptest::prelude::*;
use scene::{Camera, Polygon, Projection};

use crate::common::{busy_scene, mesh, oblique_camera, ortho_pixels, scene_with, GridSource};

/// One patch per polygon whose value is (u, v, 1): the image shows the rasterizer's (u, v).
struct UvSource(PatchCoeffs);

impl UvSource {
    fn new() -> Self {
        let mut c = [[0.0f32; 16]; 3];
        c[0][1] = 1.0; // s
        c[1][4] = 1.0; // t
        c[2][0] = 1.0;
        UvSource(PatchCoeffs::whole(c))
    }
}

impl PatchSource for UvSource {
    fn locate(&self, _polygon: u32, _u: f32, _v: f32) -> u32 {
        0
    }
    fn patch(&self, _id: u32) -> PatchCoeffs {
        self.0
    }
}

#[test]
fn mesh_with_vertices_on_pixel_centres_covers_every_pixel_exactly_once() {
    let (w, h) = (97, 61);
    let polys = mesh(w, h, 8, true, |x, y| DVec3::new(x, y, 0.0));
    let scene = scene_with(polys, ortho_pixels(w, h), w, h);
    let mut opts = FrameOptions::new(w, h);
    opts.region = 16;
    let prims = build_primitives(
        &scene,
        &scene.camera,
        opts.width,
        opts.height,
        opts.cull_back_faces,
    )
    .unwrap();
    let counts = coverage_counts(&prims, w, h, 16);
    let bad: Vec<_> = counts
        .iter()
        .enumerate()
        .filter(|(_, &c)| c != 1)
        .take(5)
        .collect();
    assert!(bad.is_empty(), "pixels not covered exactly once: {bad:?}");
}

#[test]
fn perspective_mesh_filling_the_view_covers_every_pixel_exactly_once() {
    let (w, h) = (80, 72);
    // The same mesh topology laid on the z = 0 plane, 40 x 40 units, seen obliquely.
    let polys = mesh(w, h, 8, false, |x, y| {
        DVec3::new(x / 96.0 * 40.0 - 20.0, y / 88.0 * 40.0 - 20.0, 0.0)
    });
    let camera = oblique_camera();
    let scene = scene_with(polys, camera, w, h);
    let prims = build_primitives(&scene, &camera, w, h, false).unwrap();
    let counts = coverage_counts(&prims, w, h, 128);
    let bad: Vec<_> = counts
        .iter()
        .enumerate()
        .filter(|(_, &c)| c != 1)
        .take(5)
        .collect();
    assert!(bad.is_empty(), "pixels not covered exactly once: {bad:?}");
}

fn uv_of(frame: &Frame, x: u32, y: u32) -> Vec3 {
    frame.pixels[(y * frame.width + x) as usize]
}

fn assert_finite_and_in_unit_square(frame: &Frame) {
    for p in &frame.pixels {
        assert!(p.is_finite(), "non-finite pixel {p}");
        assert!(
            p.x >= 0.0 && p.x <= 1.0 && p.y >= 0.0 && p.y <= 1.0,
            "(u, v) out of range: {p}"
        );
    }
}

#[test]
fn floor_crossing_the_near_plane_renders_without_holes_and_with_exact_uv() {
    let (w, h) = (64, 64);
    // A floor from 50 units behind the camera to 1000 in front, 1 unit below the eye.
    let floor = Polygon::quad(
        [
            DVec3::new(-1000.0, -1.0, 50.0),
            DVec3::new(1000.0, -1.0, 50.0),
            DVec3::new(1000.0, -1.0, -1000.0),
            DVec3::new(-1000.0, -1.0, -1000.0),
        ],
        0,
        0,
    )
    .unwrap();
    let camera = Camera {
        eye: DVec3::ZERO,
        look_at: -DVec3::Z,
        up: DVec3::Y,
        projection: Projection::Perspective { fov_y_deg: 60.0 },
    };
    let scene = scene_with(vec![floor.clone()], camera, w, h);
    let frame = render_frame(&scene, &camera, &UvSource::new(), &FrameOptions::new(w, h)).unwrap();
    assert_finite_and_in_unit_square(&frame);
    let ty = (30f64).to_radians().tan();
    for y in 0..h {
        for x in 0..w {
            let p = uv_of(&frame, x, y);
            // Row centres above the horizon see nothing; below it (1000 units away the floor is
            // 0.057 degrees below the horizon, far less than a row) the floor covers everything.
            if y < 32 {
                assert_eq!(p.z, 0.0, "pixel ({x}, {y}) above the horizon is covered");
                continue;
            }
            assert_eq!(p.z, 1.0, "hole at ({x}, {y})");
            // Exact (u, v): intersect the pixel's ray with the floor.
            let nx = (x as f64 + 0.5) / w as f64 * 2.0 - 1.0;
            let ny = 1.0 - (y as f64 + 0.5) / h as f64 * 2.0;
            let dir = DVec3::new(nx * ty, ny * ty, -1.0);
            let t = -1.0 / dir.y;
            let hit = dir * t;
            let u = (hit.x + 1000.0) / 2000.0;
            let v = (50.0 - hit.z) / 1050.0;
            // f32 evaluation of s = w Sb - ks with |ks| ~ 1000: absolute error ~1e-4 units, over
            // a 2000 x 1050 quad: a few 1e-7 in (u, v); 1e-5 leaves room for the plane's rounding.
            assert!(
                (p.x as f64 - u).abs() < 1e-5,
                "u at ({x}, {y}): {} vs {u}",
                p.x
            );
            assert!(
                (p.y as f64 - v).abs() < 1e-5,
                "v at ({x}, {y}): {} vs {v}",
                p.y
            );
        }
    }
}

#[test]
fn grazing_quad_renders_without_holes_or_nan() {
    let (w, h) = (96, 96);
    // A quad turned 88 degrees away from the viewer.
    let a = 88f64.to_radians();
    let (c, s) = (a.cos(), a.sin());
    let quad = Polygon::quad(
        [
            DVec3::new(-1.0, -c, -s),
            DVec3::new(1.0, -c, -s),
            DVec3::new(1.3, c, s),
            DVec3::new(-0.8, c, s),
        ],
        0,
        0,
    )
    .unwrap();
    let camera = Camera {
        eye: DVec3::new(0.0, 0.0, 3.0),
        look_at: DVec3::ZERO,
        up: DVec3::Y,
        projection: Projection::Perspective { fov_y_deg: 50.0 },
    };
    let scene = scene_with(vec![quad], camera, w, h);
    let frame = render_frame(&scene, &camera, &UvSource::new(), &FrameOptions::new(w, h)).unwrap();
    assert_finite_and_in_unit_square(&frame);
    let mut covered_rows = 0;
    for y in 0..h {
        let row: Vec<bool> = (0..w).map(|x| uv_of(&frame, x, y).z == 1.0).collect();
        let first = row.iter().position(|&c| c);
        let last = row.iter().rposition(|&c| c);
        if let (Some(f), Some(l)) = (first, last) {
            covered_rows += 1;
            assert!(row[f..=l].iter().all(|&c| c), "hole in row {y}");
            // u runs from left to right across the row.
            assert!(uv_of(&frame, f as u32, y).x < uv_of(&frame, l as u32, y).x);
        }
    }
    // Its near edge (2 units away, 0.035 above the axis) projects 1.8 rows above the image centre
    // (48 rows per tan 25 deg), the far edge (4 away, 0.035 below) 0.9 rows below it: row
    // centres 46.5, 47.5 and 48.5 lie between, so exactly rows 46 to 48 are covered.
    assert_eq!(covered_rows, 3);
}

/// f64 Newton inverse of a quad's bilinear map (independent of the renderer's closed form).
fn newton_uv(q: &Polygon, p: DVec3) -> (f64, f64) {
    let (mut u, mut v) = (0.5, 0.5);
    for _ in 0..50 {
        let r = q.point(u, v) - p;
        let (du, dv) = q.tangents(u, v);
        // Least squares on the plane: solve [du dv]^T [du dv] x = [du dv]^T r.
        let (a, b, c) = (du.dot(du), du.dot(dv), dv.dot(dv));
        let (e, f) = (du.dot(r), dv.dot(r));
        let det = a * c - b * b;
        u -= (c * e - b * f) / det;
        v -= (a * f - b * e) / det;
    }
    (u, v)
}

#[test]
fn orthographic_direct_render_equals_the_patch_source_at_pixel_centres() {
    let (w, h) = (72, 56);
    // A trapezoid (not a parallelogram) larger than the view, on the z = 0 plane.
    let quad = Polygon::quad(
        [
            DVec3::new(-3.0, -2.0, 0.0),
            DVec3::new(77.0, -5.0, 0.0),
            DVec3::new(74.0, 60.0, 0.0),
            DVec3::new(-1.0, 58.0, 0.0),
        ],
        0,
        0,
    )
    .unwrap();
    let source = GridSource::new(1, 4);
    let scene = scene_with(vec![quad.clone()], ortho_pixels(w, h), w, h);
    let mut opts = FrameOptions::new(w, h);
    opts.region = 32;
    let frame = render_frame(&scene, &scene.camera, &source, &opts).unwrap();
    let mut worst = 0.0f64;
    for y in 0..h {
        for x in 0..w {
            let p = DVec3::new(x as f64 + 0.5, h as f64 - (y as f64 + 0.5), 0.0);
            let (u, v) = newton_uv(&quad, p);
            let id = source.locate(0, u as f32, v as f32);
            let pc = source.patch(id);
            let (s, t) = (
                (u - pc.u0 as f64) * pc.inv_w as f64,
                (v - pc.v0 as f64) * pc.inv_w as f64,
            );
            for ch in 0..3 {
                let mut want = 0.0;
                for j in 0..4 {
                    for i in 0..4 {
                        want += pc.c[ch][4 * j + i] as f64 * s.powi(i as i32) * t.powi(j as i32);
                    }
                }
                let got = uv_of(&frame, x, y)[ch] as f64;
                worst = worst.max((got - want).abs());
            }
        }
    }
    // (u, v) from f32 planes over ~80 units carries ~1e-6 error, times the patch's gradient
    // (coefficients <= 1, times inv_w = 4, times 3 powers): below 1e-4; f32 Horner adds ~1e-6.
    assert!(worst < 1e-4, "largest deviation {worst}");
}

#[test]
fn sixteen_samples_resolve_a_pixel_centred_edge_to_half_coverage() {
    let (w, h) = (16, 8);
    // Constant colour 1 left of x = 8.5 (an edge through the centres of column 8).
    let quad = Polygon::quad(
        [
            DVec3::new(-1.0, -1.0, 0.0),
            DVec3::new(8.5, -1.0, 0.0),
            DVec3::new(8.5, 9.0, 0.0),
            DVec3::new(-1.0, 9.0, 0.0),
        ],
        0,
        0,
    )
    .unwrap();
    let mut c = [[0.0f32; 16]; 3];
    c[0][0] = 1.0;
    c[1][0] = 1.0;
    c[2][0] = 1.0;
    struct Const(PatchCoeffs);
    impl PatchSource for Const {
        fn locate(&self, _: u32, _: f32, _: f32) -> u32 {
            0
        }
        fn patch(&self, _: u32) -> PatchCoeffs {
            self.0
        }
    }
    let mut scene = scene_with(vec![quad], ortho_pixels(w, h), w, h);
    scene.display.background = DVec3::new(0.0, 0.5, 0.25);
    // AA 1: the centre lies exactly on the quad's right edge, which the top-left rule excludes.
    for (aa, expect) in [(16u32, 0.5f32), (4, 0.5), (1, 0.0)] {
        let mut opts = FrameOptions::new(w, h);
        opts.aa = base::method::Aa::new("aa", aa).unwrap();
        let f = render_frame(&scene, &scene.camera, &Const(PatchCoeffs::whole(c)), &opts).unwrap();
        for y in 0..h {
            // Exact: sample weights are 1/aa and the values dyadic.
            let bg = Vec3::new(0.0, 0.5, 0.25);
            assert_eq!(uv_of(&f, 7, y), Vec3::ONE);
            assert_eq!(uv_of(&f, 8, y), Vec3::ONE * expect + bg * (1.0 - expect));
            assert_eq!(uv_of(&f, 9, y), bg);
        }
        assert_eq!(
            f.stats.pixels_shaded,
            (h as f32 * aa as f32 * (8.0 + expect)) as u64
        );
    }
}

#[test]
fn image_is_bit_identical_across_threads_and_renderers() {
    let (w, h) = (150, 100);
    let scene = busy_scene(w, h);
    let source = GridSource::new(scene.polygons.len() as u32, 3);
    let render = |threads: usize, renderers: u32| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let mut opts = FrameOptions::new(w, h);
        opts.aa = base::method::Aa::new("aa", 4).unwrap();
        opts.renderers = renderers;
        opts.region = 64;
        pool.install(|| render_frame(&scene, &scene.camera, &source, &opts))
            .unwrap()
    };
    let base = render(1, 1);
    assert!(base.pixels.iter().all(|p| p.is_finite()));
    assert!(
        base.stats.pixels_shaded > (w * h) as u64,
        "the scene covers most of the image"
    );
    let bits = |f: &Frame| {
        f.pixels
            .iter()
            .flat_map(|p| p.to_array().map(f32::to_bits))
            .collect::<Vec<_>>()
    };
    // 5 renderers: the composition's second G-buffer is reused by four reports in a row.
    for (threads, renderers) in [(2, 1), (1, 3), (2, 3), (2, 2), (2, 5)] {
        let f = render(threads, renderers);
        assert!(
            bits(&f) == bits(&base),
            "threads {threads}, renderers {renderers} differ"
        );
        assert_eq!(f.stats.pixels_shaded, base.stats.pixels_shaded);
        assert_eq!(f.stats.patch_table_entries, base.stats.patch_table_entries);
        assert_eq!(f.stats.pixels_rasterized, base.stats.pixels_rasterized);
        if renderers > 1 {
            assert!(f.stats.composition_traffic_bytes > base.stats.composition_traffic_bytes);
        }
    }
    // With 3 renderers the coplanar pair (ids 24, 25) lands on different renderers, so equal
    // images also show the compositor's polygon-id tie-break agrees with a single renderer's.
    assert_eq!(base.stats.primitives, scene.polygons.len() as u32);
}

/// Binning chunk by chunk during setup gives the bins (and records) of setting everything up
/// and then binning in one sequential round-robin pass, for any renderer count: a mesh of
/// several chunks (some polygons off screen, so chunks hold different counts), a region size
/// that is not a power of two, and renderer counts that do not divide the chunks' counts.
#[test]
fn chunked_binning_equals_the_sequential_round_robin() {
    let (w, h) = (150, 100);
    let mut polys = mesh(w + 60, h, 2, false, |x, y| DVec3::new(x, y, 0.0));
    polys.extend(busy_scene(w, h).polygons);
    let chunk = engine::raster::binning::chunk_size(polys.len());
    assert!(
        polys.len() > 8 * chunk,
        "{} polygons, chunks of {chunk}",
        polys.len()
    );
    let scene = scene_with(polys, ortho_pixels(w, h), w, h);
    let grid = RegionGrid::new(w, h, 40);
    let mut want_prims = Vec::new();
    build_primitives_into(&scene, &scene.camera, w, h, false, &mut want_prims).unwrap();
    let (mut prims, mut chunks) = (Vec::new(), Vec::new());
    for renderers in [1, 2, 3, 7] {
        let mut want = Vec::new();
        let n_want = bin_round_robin_into(&grid, &want_prims, renderers, &mut want);
        let mut got = Vec::new();
        let n_got = build_and_bin_into(
            &scene,
            &scene.camera,
            (w, h),
            false,
            &grid,
            renderers,
            &mut prims,
            &mut chunks,
            &mut got,
            &mut None,
        )
        .unwrap();
        assert_eq!(n_got, n_want, "{renderers} renderers");
        assert!(got == want, "{renderers} renderers: the bins differ");
        assert_eq!(format!("{prims:?}"), format!("{want_prims:?}"));
    }
}

/// A frame set up from the previous frame's scene bounds (a guessed view, checked against the
/// bounds the setup measures) gives the records and bins of a frame set up from scratch:
/// with no guess, with the right one, with the bounds of another scene (a wrong extent), and
/// when the camera comes so close to a polygon that the near plane is not the guessed one
/// (the frame is set up again); the guess is kept only while it would give the frame's view.
#[test]
fn a_guessed_view_gives_the_records_of_the_true_one() {
    let (w, h) = (120, 90);
    let polys = mesh(w, h, 6, false, |x, y| {
        DVec3::new(x / 96.0 * 40.0 - 20.0, y / 88.0 * 40.0 - 20.0, 0.0)
    });
    let far = oblique_camera();
    // 1e-5 units above the plane: within twice the largest near plane (1e-4 of the extent).
    let close = Camera {
        eye: DVec3::new(0.3, -2.0, 1e-5),
        look_at: DVec3::new(0.3, 0.0, -1.0),
        ..far
    };
    let scene = scene_with(polys, far, w, h);
    let small = scene_with(busy_scene(w, h).polygons, far, w, h);
    let grid = RegionGrid::new(w, h, 32);
    let run = |scene: &scene::Scene, camera: &Camera, guess: &mut Option<_>| {
        let (mut prims, mut chunks, mut bins) = (Vec::new(), Vec::new(), Vec::new());
        build_and_bin_into(
            scene,
            camera,
            (w, h),
            false,
            &grid,
            2,
            &mut prims,
            &mut chunks,
            &mut bins,
            guess,
        )
        .unwrap();
        (format!("{prims:?}"), bins)
    };
    for camera in [far, close] {
        let mut want_prims = Vec::new();
        build_primitives_into(&scene, &camera, w, h, false, &mut want_prims).unwrap();
        let mut want_bins = Vec::new();
        bin_round_robin_into(&grid, &want_prims, 2, &mut want_bins);
        let want = (format!("{want_prims:?}"), want_bins);
        let mut guess = None;
        assert!(run(&scene, &camera, &mut guess) == want, "no guess");
        assert_eq!(
            guess.is_some(),
            camera.eye == far.eye,
            "kept only when it holds"
        );
        let mut right = None;
        run(&scene, &far, &mut right);
        assert!(right.is_some());
        assert!(
            run(&scene, &camera, &mut right) == want,
            "the far view's guess"
        );
        let mut wrong = None;
        run(&small, &far, &mut wrong);
        assert!(wrong.is_some());
        assert!(
            run(&scene, &camera, &mut wrong) == want,
            "another scene's guess"
        );
    }
}

#[test]
fn bad_options_are_usage_errors() {
    let scene = busy_scene(8, 8);
    let src = UvSource::new();
    // A sample count other than 1, 4 or 16 cannot reach a frame: it is refused where it is
    // made, naming the option.
    let e = base::method::Aa::new("aa", 3).unwrap_err();
    assert_eq!(e.exit_code(), 2, "{e}");
    assert!(e.to_string().contains("aa"), "{e}");
    for f in [
        |o: &mut FrameOptions| o.renderers = 0,
        |o: &mut FrameOptions| o.region = 12,
        |o: &mut FrameOptions| o.width = 0,
    ] {
        let mut o = FrameOptions::new(8, 8);
        f(&mut o);
        let e = render_frame(&scene, &scene.camera, &src, &o).unwrap_err();
        assert_eq!(e.exit_code(), 2, "{e}");
    }
}

fn screen_triangle(v: [[i64; 2]; 3]) -> ScreenPolygon {
    ScreenPolygon {
        id: 0,
        verts: v
            .iter()
            .map(|p| [p[0] as f64 / ONE as f64, p[1] as f64 / ONE as f64])
            .collect(),
        planes: [Plane::default(); 5],
        corners: [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [0.0, 1.0]],
        triangle: true,
        perspective: false,
        front_facing: true,
        barycentric: false,
    }
}

/// Exact orientation of the sample (x, y) against edge a -> b (i128, no rounding).
fn orient(a: [i64; 2], b: [i64; 2], p: [i64; 2]) -> i128 {
    (b[0] - a[0]) as i128 * (p[1] - a[1]) as i128 - (b[1] - a[1]) as i128 * (p[0] - a[0]) as i128
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    /// Random triangles on the 1/256 grid: a pixel centre strictly inside (exact rational test) is
    /// covered, one strictly outside is not, and one on the edge shared with a second triangle on
    /// the other side of it is covered by exactly one of the two.
    #[test]
    fn coverage_matches_exact_point_in_triangle_tests(
        a in (-1000i64..6000, -1000i64..6000),
        b in (-1000i64..6000, -1000i64..6000),
        c in (-1000i64..6000, -1000i64..6000),
        d in (-1000i64..6000, -1000i64..6000),
        snap in 0u8..3,
    ) {
        let (w, h) = (20u32, 20u32);
        // Some cases put vertices on pixel centres so shared edges pass through centres.
        let q = |p: (i64, i64)| if snap == 0 { [p.0 / ONE * ONE + ONE / 2, p.1 / ONE * ONE + ONE / 2] } else { [p.0, p.1] };
        let (a, b, c, d) = (q(a), q(b), q(c), q(d));
        let side_b = orient(a, c, b).signum();
        let side_d = orient(a, c, d).signum();
        prop_assume!(side_b != 0 && side_d != 0 && side_b != side_d);
        let t1 = setup(&screen_triangle([a, b, c]), w, h);
        let t2 = setup(&screen_triangle([a, c, d]), w, h);
        let c1 = t1.map(|p| coverage_counts(&[p], w, h, 8)).unwrap_or(vec![0; (w * h) as usize]);
        let c2 = t2.map(|p| coverage_counts(&[p], w, h, 8)).unwrap_or(vec![0; (w * h) as usize]);
        for y in 0..h as i64 {
            for x in 0..w as i64 {
                let s = [x * ONE + ONE / 2, y * ONE + ONE / 2];
                let i = (y * w as i64 + x) as usize;
                for (tri, cov) in [([a, b, c], &c1), ([a, c, d], &c2)] {
                    let o = orient(tri[0], tri[1], tri[2]).signum();
                    let e = [orient(tri[0], tri[1], s), orient(tri[1], tri[2], s), orient(tri[2], tri[0], s)];
                    if e.iter().all(|&v| v.signum() == o) {
                        prop_assert_eq!(cov[i], 1, "interior centre ({}, {}) not covered", x, y);
                    }
                    if e.iter().any(|&v| v.signum() == -o) {
                        prop_assert_eq!(cov[i], 0, "exterior centre ({}, {}) covered", x, y);
                    }
                }
                // On the shared edge a-c strictly between a and c: exactly one owner.
                let on = orient(a, c, s) == 0
                    && (s[0] - a[0]) * (s[0] - c[0]) + (s[1] - a[1]) * (s[1] - c[1]) < 0;
                if on {
                    prop_assert_eq!(c1[i] + c2[i], 1, "shared-edge centre ({}, {})", x, y);
                }
            }
        }
    }
}

/// Renders `poly` alone in perspective with the (u, v) source and checks every covered pixel
/// against the exact parameters of the point its centre ray hits, `exact(p)`.
fn check_perspective_uv(poly: Polygon, exact: impl Fn(DVec3) -> (f64, f64)) -> usize {
    let (w, h) = (90, 70);
    let camera = Camera {
        eye: DVec3::new(0.4, 0.3, 4.0),
        look_at: DVec3::new(0.0, 0.0, 0.0),
        up: DVec3::Y,
        projection: Projection::Perspective { fov_y_deg: 45.0 },
    };
    let scene = scene_with(vec![poly.clone()], camera, w, h);
    let frame = render_frame(&scene, &camera, &UvSource::new(), &FrameOptions::new(w, h)).unwrap();
    assert_finite_and_in_unit_square(&frame);
    let f = (camera.look_at - camera.eye).normalize();
    let r = f.cross(camera.up).normalize();
    let up = r.cross(f);
    let ty = (22.5f64).to_radians().tan();
    let tx = ty * w as f64 / h as f64;
    let mut checked = 0;
    for y in 0..h {
        for x in 0..w {
            let px = uv_of(&frame, x, y);
            if px.z != 1.0 {
                continue;
            }
            let nx = (x as f64 + 0.5) / w as f64 * 2.0 - 1.0;
            let ny = 1.0 - (y as f64 + 0.5) / h as f64 * 2.0;
            let d = f + r * (nx * tx) + up * (ny * ty);
            let t = (poly.corners[0] - camera.eye).dot(poly.normal) / d.dot(poly.normal);
            let (u, v) = exact(camera.eye + d * t);
            // Pixels covered only through the 1/512-pixel snap of the edges are skipped.
            if !(0.01..=0.99).contains(&u) || !(0.01..=0.99).contains(&v) {
                continue;
            }
            // Tolerance: f32 plane evaluation at distance ~4 over a ~2-unit polygon gives ~1e-6
            // relative errors in (s, t); 1e-4 leaves a wide margin yet catches any affine
            // (not perspective-correct) interpolation, which is off by ~1e-2 here.
            assert!(
                (px.x as f64 - u).abs() < 1e-4,
                "u at ({x}, {y}): {} vs {u}",
                px.x
            );
            assert!(
                (px.y as f64 - v).abs() < 1e-4,
                "v at ({x}, {y}): {} vs {v}",
                px.y
            );
            checked += 1;
        }
    }
    checked
}

#[test]
fn perspective_uv_of_a_general_quad_is_the_exact_bilinear_inverse() {
    let quad = Polygon::quad(
        [
            DVec3::new(-1.2, -1.0, -0.5),
            DVec3::new(1.0, -0.8, 0.3),
            DVec3::new(1.3, 1.1, 0.5),
            DVec3::new(-0.9, 0.9, -0.5),
        ],
        0,
        0,
    );
    // Make it exactly planar: put c2 on the plane of c0, c1, c3.
    let q = quad.unwrap();
    let n = (q.corners[1] - q.corners[0]).cross(q.corners[3] - q.corners[0]);
    let mut c2 = q.corners[2];
    c2.z -= (c2 - q.corners[0]).dot(n) / n.z;
    let quad = Polygon::quad([q.corners[0], q.corners[1], c2, q.corners[3]], 0, 0).unwrap();
    let checked = check_perspective_uv(quad.clone(), |p| newton_uv(&quad, p));
    assert!(checked > 1000, "only {checked} pixels checked");
}

#[test]
fn perspective_uv_of_a_triangle_is_the_collapsed_quad_inverse() {
    let tri = Polygon::triangle(
        [
            DVec3::new(-1.3, -1.0, -0.4),
            DVec3::new(1.2, -0.7, 0.2),
            DVec3::new(0.1, 1.2, 0.0),
        ],
        0,
        0,
    )
    .unwrap();
    let [c0, c1, c2, _] = tri.corners;
    let checked = check_perspective_uv(tri.clone(), |p| {
        // Barycentrics by areas; v = b2, u = b1 / (b0 + b1).
        let a = (c1 - c0).cross(c2 - c0).length();
        let b1 = (p - c0).cross(c2 - c0).length() / a;
        let b2 = (c1 - c0).cross(p - c0).length() / a;
        let b0 = 1.0 - b1 - b2;
        (b1 / (b0 + b1), b2)
    });
    assert!(checked > 500, "only {checked} pixels checked");
}

#[test]
fn empty_scene_renders_the_background_everywhere() {
    let mut scene = scene_with(vec![], ortho_pixels(24, 10), 24, 10);
    scene.display.background = DVec3::new(0.1, 0.2, 0.3);
    let f = render_frame(
        &scene,
        &scene.camera,
        &UvSource::new(),
        &FrameOptions::new(24, 10),
    )
    .unwrap();
    assert!(f.pixels.iter().all(|&p| p == Vec3::new(0.1, 0.2, 0.3)));
    assert_eq!(
        (
            f.stats.primitives,
            f.stats.regions_touched,
            f.stats.pixels_shaded
        ),
        (0, 0, 0)
    );
    assert_eq!(f.stats.composition_traffic_bytes, 0);
}
