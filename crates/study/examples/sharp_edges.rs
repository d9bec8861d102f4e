//! What following the spots' edges buys: the direct method's error near spot-cone rims and hard
//! shadows, for each `--sharp-levels`, with what it costs (patches, bytes, points where the light
//! was evaluated beyond the samples, build and frame time).
//!
//! ```text
//! cargo run --release -p pixelflow-study --example sharp_edges [scene.toml] [frames of its path]
//! ```
//!
//! Defaults: `scenes/gallery.toml`, its camera and frames 24 and 40 of its camera path. One
//! solve; per level the compact RRPs are built from the same samples. Errors are against the
//! per-pixel evaluation of the same solution (the `reference` method: the solver's own answer at
//! each pixel, exact at a spot's edges), so they are the reconstruction's error, not the
//! solve's. A pixel is **near a spot edge** when a pixel within 2 px (Chebyshev) and the pixel
//! beside it (4-neighbours) see the same polygon lit by different sets of spots (cone rims and
//! shadow lines, read from the solution's spot terms at the pixel centres; silhouettes are not
//! edges here). Frame times: median of 15 frames of the scene's camera per level, and the median
//! of 5 walks of the camera path (mean frame time per walk), levels interleaved, after a warm-up.

use std::path::PathBuf;
use std::time::Instant;

use app::context::Context;
use app::context::Input;
use app::prepare::prepare;
use app::prepare::spot_light;
use glam::Vec3;
use reconstruction::compact::CompactReconstruction;
use reconstruction::texture::SizePolicy;
use reconstruction::Estimator;

use base::method::{Method, Placement};
use engine::frame::{render, FrameContext, FrameOptions};
use engine::shading::Shader;

const LEVELS: [u32; 6] = [0, 1, 2, 3, 4, 5];
const FRAMES: usize = 15;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let scene = PathBuf::from(args.next().unwrap_or_else(|| {
        concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes/gallery.toml").into()
    }));
    let path_frames: Vec<u32> = {
        let rest: Vec<u32> = args.filter_map(|a| a.parse().ok()).collect();
        if rest.is_empty() {
            vec![24, 40]
        } else {
            rest
        }
    };
    let ctx = Context::default();
    let mut input = Input::load(&scene)?;
    input.sharp_levels = 0;
    let t = Instant::now();
    let p = prepare(&ctx, input, SizePolicy::FromDepth, Placement::Centre)?;
    eprintln!("solved in {:.1} s", t.elapsed().as_secs_f64());
    let mut cameras = vec![p.scene.camera];
    if let Some(path) = &p.scene.camera_path {
        cameras.extend(
            path_frames
                .iter()
                .map(|&k| path.camera(p.scene.camera.projection, k)),
        );
    }
    let opts = FrameOptions::new(p.scene.width, p.scene.height);

    // The compact RRPs per level.
    let mut builds = Vec::new();
    for &levels in &LEVELS {
        let t = Instant::now();
        let spots = spot_light(&p.scene, &p.solution, levels)?;
        let sharp = spots.as_ref().map(|s| s.sharp());
        let c = CompactReconstruction::build_with(
            &p.solution.polygons,
            Estimator::default(),
            &p.seams,
            sharp,
        )?;
        let ms = t.elapsed().as_secs_f64() * 1e3;
        let rec = reconstruction::Reconstruction::build_with(
            &p.solution.polygons,
            Estimator::default(),
            &p.seams,
            sharp,
        )?;
        builds.push((levels, c, ms, rec.stats().sharp_points));
    }

    // The reference and the spot-edge mask per view.
    let oracle = radiosity::Oracle::new(&p.solution, &p.scene)?;
    let parts = radiosity::SpotParts::new(&p.solution, &p.scene)?;
    let mut views = Vec::new();
    for cam in &cameras {
        let t = Instant::now();
        let f = |poly: u32, u: f32, v: f32| oracle.radiosity(poly as usize, u as f64, v as f64);
        let reference = render(
            &p.scene,
            cam,
            &Shader::Reference(&f),
            Method::Reference,
            &opts,
        )?;
        let lit = |poly: u32, u: f32, v: f32| {
            let mut mask = 0u32;
            for s in parts.reaching(poly as usize) {
                if parts.part(poly as usize, s, u as f64, v as f64).is_some() {
                    mask |= 1 << s.min(31);
                }
            }
            Vec3::new(mask as f32, poly as f32 + 1.0, 0.0)
        };
        let ids = render(
            &p.scene,
            cam,
            &Shader::Reference(&lit),
            Method::Reference,
            &opts,
        )?;
        let mask = near_spot_edges(&ids.pixels, opts.width as usize, opts.height as usize);
        eprintln!(
            "view: reference in {:.1} s, {} px near spot edges",
            t.elapsed().as_secs_f64(),
            mask.iter().filter(|&&m| m).count()
        );
        views.push((reference, mask));
    }

    // Frame times, levels interleaved: the scene's camera (median of FRAMES frames) and the
    // whole camera path (median of 5 walks, each the sum of its frames).
    let mut times = vec![Vec::new(); builds.len()];
    let mut walks = vec![Vec::new(); builds.len()];
    let path: Vec<scene::Camera> = p.scene.camera_path.as_ref().map_or_else(Vec::new, |cp| {
        (0..cp.frames)
            .map(|k| cp.camera(p.scene.camera.projection, k))
            .collect()
    });
    let mut fc = FrameContext::new();
    for round in 0..=FRAMES {
        for (b, (_, c, _, _)) in builds.iter().enumerate() {
            let s = fc.render(
                &p.scene,
                &cameras[0],
                &Shader::Patches(c),
                Method::Direct,
                &opts,
            )?;
            if round > 0 {
                times[b].push(s.frame_ms);
            }
            if round > 0 && round <= 5 {
                let mut sum = 0.0;
                for cam in &path {
                    sum += fc
                        .render(&p.scene, cam, &Shader::Patches(c), Method::Direct, &opts)?
                        .frame_ms;
                }
                walks[b].push(sum / path.len().max(1) as f64);
            }
        }
    }

    println!(
        "| levels | patches | RRP bytes | light evaluated (points) | build ms | frame ms (median) \
         | walkthrough ms per frame (median of 5) | rmse near spot edges | rmse elsewhere \
         | share of squared error near spot edges |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for (b, (levels, c, ms, evaluated)) in builds.iter().enumerate() {
        let (mut near, mut far, mut n_near, mut n_far) = (0.0f64, 0.0f64, 0usize, 0usize);
        for ((reference, mask), cam) in views.iter().zip(&cameras) {
            let img = render(&p.scene, cam, &Shader::Patches(c), Method::Direct, &opts)?;
            for ((a, r), &m) in img.pixels.iter().zip(&reference.pixels).zip(mask) {
                let d = (metric::luminance(*a) - metric::luminance(*r)).powi(2);
                if m {
                    near += d;
                    n_near += 1;
                } else {
                    far += d;
                    n_far += 1;
                }
            }
        }
        times[b].sort_by(f64::total_cmp);
        walks[b].sort_by(f64::total_cmp);
        let st = c.stats();
        println!(
            "| {levels} | {} | {} | {} | {ms:.0} | {:.2} | {:.2} | {:.3e} | {:.3e} | {:.1} % |",
            st.leaves,
            st.total_bytes,
            evaluated,
            times[b][times[b].len() / 2],
            walks[b].get(walks[b].len() / 2).copied().unwrap_or(0.0),
            (near / n_near.max(1) as f64).sqrt(),
            (far / n_far.max(1) as f64).sqrt(),
            100.0 * near / (near + far).max(f64::MIN_POSITIVE),
        );
    }
    println!(
        "\nsamples (solver vertices): {}; views: {}; image {} x {}",
        p.solution.stats.vertices,
        cameras.len(),
        opts.width,
        opts.height
    );
    Ok(())
}

/// Pixels within 2 px of a pair of 4-neighbours that see one polygon (green channel: id + 1)
/// under different sets of spots (red channel: the lit mask).
fn near_spot_edges(ids: &[Vec3], w: usize, h: usize) -> Vec<bool> {
    let edge = metric::edges::mark_pairs(w, h, |i, j| {
        let (a, b) = (ids[i], ids[j]);
        a.y > 0.0 && a.y == b.y && a.x != b.x
    });
    metric::edges::dilate(&edge, w, h, 2)
}
