//! The direct method end to end on the shipped scenes: scene file -> solve -> RRPs -> rasterizer
//! -> composition -> deferred shading. Each scene is solved once per test binary.

use app::frames::render_frame;
use app::prepare::Prepared;
use base::method::Method;
use engine::frame::{Frame, FrameOptions};

fn prepared(name: &str) -> &'static Prepared {
    crate::shipped(name)
}

fn render_with(p: &Prepared, opts: &FrameOptions, threads: usize) -> Frame {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(|| render_frame(p, Method::Direct, &p.scene.camera, opts))
        .expect("render")
}

#[test]
fn direct_two_spots_equals_the_rrp_at_pixel_centres() {
    // The orthographic camera maps the unit square onto the 256 x 256 image exactly, with v = 0 on
    // the bottom row: pixel (x, y) sees (u, v) = ((x + 0.5) / 256, 1 - (y + 0.5) / 256).
    let p = prepared("two-spots");
    let f = render_with(p, &FrameOptions::new(256, 256), 2);
    let c = &p.compact;
    let expanded = p.expanded().unwrap().0;
    // The quantization bound of the compact RRPs, largest over the polygon's leaves
    // (reconstruction::compact's module docs).
    let bound = (0..c.leaf_count() as u32)
        .map(|id| c.error_bound(id).into_iter().fold(0.0f64, f64::max))
        .fold(0.0f64, f64::max) as f32;
    let (mut worst, mut worst_expanded) = (0.0f32, 0.0f32);
    for y in 0..256 {
        for x in 0..256 {
            let u = (x as f32 + 0.5) / 256.0;
            let v = 1.0 - (y as f32 + 0.5) / 256.0;
            let want = c.expand(c.locate(0, u, v)).eval(u, v);
            let got = f.pixels[y * 256 + x];
            worst = worst.max((got - want).abs().max_element());
            let unquantized = expanded.eval(0, u, v);
            worst_expanded = worst_expanded.max((got - unquantized).abs().max_element());
        }
    }
    // The image of the compact RRPs against the unquantized, expanded ones: within the
    // quantization bound plus the same rasterizer allowance as below.
    assert!(bound > 0.0 && bound < 1e-3, "bound {bound}");
    assert!(
        worst_expanded < bound + 1e-4,
        "largest difference {worst_expanded}, bound {bound}"
    );
    // The rasterizer's (u, v) comes from f32 plane coordinates: a few ulps of 1 (~1e-6). The
    // steepest slope of the bright spot (3.2 cos^8(theta), h = 0.5) is about 10 per unit of u,
    // 0.17 from the peak, so the value error is ~1e-5, plus f32 evaluation rounding (~1e-6 of
    // 3.2): 1e-4 leaves a margin and would still catch a half-pixel shift (10 / 512 = 0.02).
    assert!(worst < 1e-4, "largest difference {worst}");
}

/// Every pixel is finite, background where nothing is seen, and inside the range of the
/// solution's samples widened by the reconstruction's measured ringing.
fn assert_in_range(p: &Prepared, f: &Frame) {
    let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
    for poly in &p.solution.polygons {
        for v in &poly.values {
            lo = lo.min(v.min_element());
            hi = hi.max(v.max_element());
        }
    }
    // The monotone estimator rings by at most 0.18 % of a polygon's sample range in 2-D
    // (reconstruction module docs); 1 % of the scene's range is a safe bound for every polygon.
    let slack = 0.01 * (hi - lo);
    let bg = p.scene.display.background.as_vec3();
    let mut seen = 0usize;
    for (i, px) in f.pixels.iter().enumerate() {
        assert!(px.is_finite(), "pixel {i} is {px}");
        if *px != bg {
            seen += 1;
        }
        assert!(
            px.min_element() >= lo - slack && px.max_element() <= hi + slack,
            "pixel {i} = {px} outside [{lo}, {hi}] +- {slack}"
        );
    }
    assert!(
        seen > f.pixels.len() / 2,
        "only {seen} pixels see a polygon"
    );
}

#[test]
fn shipped_scenes_render_finite_and_in_range() {
    for name in ["two-spots", "cornell-box", "gallery"] {
        let p = prepared(name);
        let mut opts = FrameOptions::new(p.scene.width, p.scene.height);
        opts.aa = base::method::Aa::new("aa", 4).unwrap();
        let f = render_with(p, &opts, 2);
        assert_in_range(p, &f);
    }
}

#[test]
fn cornell_pixels_are_identical_for_any_threads_and_renderers() {
    let p = prepared("cornell-box");
    let mut opts = FrameOptions::new(160, 120);
    opts.aa = base::method::Aa::new("aa", 4).unwrap();
    opts.region = 32;
    let reference = render_with(p, &opts, 1);
    for (threads, renderers) in [(2, 1), (1, 3), (2, 3)] {
        opts.renderers = renderers;
        let f = render_with(p, &opts, threads);
        let same = f
            .pixels
            .iter()
            .zip(&reference.pixels)
            .all(|(a, b)| a.to_array().map(f32::to_bits) == b.to_array().map(f32::to_bits));
        assert!(same, "threads {threads}, renderers {renderers} differ");
        assert_eq!(f.stats.pixels_shaded, reference.stats.pixels_shaded);
    }
}

#[test]
fn cornell_light_is_the_brightest_thing_and_walls_keep_their_colour() {
    // A sanity check with physical meaning: the light (emission 17, 12, 4) is seen near the top
    // centre; the left wall is red (its reflectance is 0.63, 0.065, 0.05) and the right wall green.
    let p = prepared("cornell-box");
    let f = render_with(p, &FrameOptions::new(128, 128), 2);
    let at = |x: usize, y: usize| f.pixels[y * 128 + x];
    let light = at(64, 17);
    assert!(light.x >= 17.0 - 1e-3, "light pixel {light}");
    let left = at(12, 64);
    assert!(left.x > 4.0 * left.y, "left wall {left}");
    let right = at(116, 64);
    assert!(right.y > 2.0 * right.x, "right wall {right}");
    // The light's radiosity is E + rho H, and its irradiance H is at most the brightest other
    // surface (its form factors sum to at most 1): 17 <= B <= 17 + 0.78 * max(other B).
    let other = (0..p.scene.polygons.len())
        .filter(|&i| !p.scene.material_of(i).is_emitter())
        .flat_map(|i| p.solution.polygons[i].values.iter().map(|v| v.x))
        .fold(0.0, f32::max);
    let max = f.pixels.iter().map(|p| p.x).fold(0.0, f32::max);
    assert!(
        max >= 17.0 - 1e-3 && max <= 17.0 + 0.78 * other + 1e-3,
        "brightest red {max}, brightest non-emitter {other}"
    );
}

#[test]
fn every_method_is_identical_for_any_threads_and_renderers() {
    // The texture, mesh and reference methods share the rasterizer and compositor; their
    // deferred passes read only composited regions (textures: level of detail from differences
    // inside a region), so threads and renderers must not change a bit either.
    use base::method::Filter;
    let p = prepared("cornell-box");
    for method in [
        Method::Texture(Filter::Nearest),
        Method::Texture(Filter::Bilinear),
        Method::Texture(Filter::MITCHELL),
        Method::Mesh,
        Method::Reference,
    ] {
        let mut opts = FrameOptions::new(64, 48);
        opts.aa = base::method::Aa::new("aa", 4).unwrap();
        opts.region = 16;
        let run = |opts: &FrameOptions, threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| render_frame(p, method, &p.scene.camera, opts))
                .expect("render")
        };
        let reference = run(&opts, 1);
        assert!(reference.pixels.iter().all(|c| c.is_finite()));
        for (threads, renderers) in [(2, 1), (2, 3)] {
            opts.renderers = renderers;
            let f = run(&opts, threads);
            let same = f
                .pixels
                .iter()
                .zip(&reference.pixels)
                .all(|(a, b)| a.to_array().map(f32::to_bits) == b.to_array().map(f32::to_bits));
            assert!(
                same,
                "{method:?}: threads {threads}, renderers {renderers} differ"
            );
        }
    }
}

/// No method carries the light fixture's radiosity into the surfaces beside it. Every pixel
/// within 3 px of the Cornell box's emitter that does not show the emitter itself stays below
/// 1.5 times the brightest non-emitter pixel of the reference image within 3 px of it. A
/// lookup of nearest or bilinear filtering blends only its polygon's own texels, the mesh only
/// its triangle's vertices, the direct method its patch; none can reach the emitter's 17
/// (3.5 times the brightest surface of the box, 200 times the ceiling beside the light) unless
/// the emitter's light leaks into another polygon's texels or patches. (An audit of the
/// texture methods' errors once found the row beside the emitter 3-100 times too bright.)
#[test]
fn no_method_bleeds_the_emitter_into_the_pixels_beside_it() {
    use base::method::Filter;
    const R: i64 = 3;
    let p = prepared("cornell-box");
    let opts = FrameOptions::new(256, 256);
    let (w, h) = (256i64, 256i64);
    let red = |f: &Frame, x: i64, y: i64| f.pixels[(y * w + x) as usize].x;
    let reference = render_with_method(p, Method::Reference, &opts);
    let is_emitter = |x: i64, y: i64| red(&reference, x, y) >= 17.0 - 1e-3;
    let window = |x: i64, y: i64| {
        (-R..=R)
            .flat_map(move |dy| (-R..=R).map(move |dx| (x + dx, y + dy)))
            .filter(|&(a, b)| a >= 0 && b >= 0 && a < w && b < h)
    };
    // The ring: non-emitter pixels with an emitter pixel in their window, with the brightest
    // non-emitter reference value of that window.
    let ring: Vec<(i64, i64, f32)> = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .filter(|&(x, y)| !is_emitter(x, y) && window(x, y).any(|(a, b)| is_emitter(a, b)))
        .map(|(x, y)| {
            let top = window(x, y)
                .filter(|&(a, b)| !is_emitter(a, b))
                .map(|(a, b)| red(&reference, a, b))
                .fold(0.0f32, f32::max);
            (x, y, top)
        })
        .collect();
    assert!(
        ring.len() > 100,
        "the emitter's ring has {} pixels",
        ring.len()
    );
    for method in [
        Method::Direct,
        Method::Texture(Filter::Nearest),
        Method::Texture(Filter::Bilinear),
        Method::Texture(Filter::MITCHELL),
        Method::Mesh,
    ] {
        let f = render_with_method(p, method, &opts);
        let (x, y, got, top) = ring
            .iter()
            .map(|&(x, y, top)| (x, y, red(&f, x, y), top))
            .max_by(|a, b| (a.2 / a.3).total_cmp(&(b.2 / b.3)))
            .unwrap();
        assert!(
            got <= 1.5 * top,
            "{method:?}: pixel ({x}, {y}) beside the emitter reads {got}, its neighbourhood at most {top}"
        );
    }
}

fn render_with_method(p: &Prepared, method: Method, opts: &FrameOptions) -> Frame {
    rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .unwrap()
        .install(|| render_frame(p, method, &p.scene.camera, opts))
        .expect("render")
}
