//! A frame context reused across frames must draw every frame exactly as a new context does: its
//! G-buffers, patch tables, primitive arrays and frame keep stale contents from earlier frames
//! (only depth and polygon are cleared per region; the frame is not cleared at all), so any read
//! of a stale value would show here. Frames of every method are drawn in one context in a mixed
//! order of sizes (growing and shrinking), sample counts, renderer counts and cameras, and each is
//! compared bit for bit with the same frame drawn in a fresh context. Each method's frames start
//! from a reservation, as `render`'s and `bench`'s do.

use app::context::Context;
use std::path::Path;

use glam::DVec3;

use app::context::TextureOptions;
use app::frames::render_frame;
use app::frames::render_frame_in;
use app::frames::reserve_frames;
use app::prepare::prepare_path;
use app::prepare::Prepared;
use base::method::Method;
use engine::frame::{FrameContext, FrameOptions};
use scene::Camera;

fn prepared(rel: &str) -> Prepared {
    let path = Path::new(crate::REPO).join(rel);
    prepare_path(&Context::default(), &path, &TextureOptions::default())
        .unwrap_or_else(|e| panic!("{rel}: {e}"))
}

fn moved(cam: &Camera, k: usize) -> Camera {
    let mut c = *cam;
    let d = (c.look_at - c.eye).length() * 0.05 * k as f64;
    c.eye += DVec3::new(d, 0.5 * d, -0.3 * d);
    c
}

/// Draws every method's frames of `rel` in one reused context and in fresh ones; `reference`
/// (the solver's oracle per pixel) only when `with_reference`, since on thousands of polygons it
/// costs seconds per frame and tests nothing of the rasterizer the scene is there for.
fn check_scene_methods(rel: &str, with_reference: bool) {
    let p = prepared(rel);
    // (width, height, aa, renderers, camera variant), in an order that grows and shrinks the
    // frame, changes the region count per row and the sample planes.
    let frames = [
        (96, 64, 1, 1, 0),
        (33, 97, 4, 3, 1),
        (128, 128, 1, 2, 2),
        (40, 24, 16, 1, 0),
        (129, 71, 1, 3, 1),
        (96, 64, 1, 1, 0),
    ];
    let mut ctx = FrameContext::new();
    let mut compared = 0;
    let methods: Vec<&str> = Method::NAMES
        .iter()
        .copied()
        .filter(|&n| with_reference || n != "reference")
        .collect();
    for &name in &methods {
        let m = Method::parse(name).unwrap();
        // Reserved as `render` and `bench` reserve (for the direct method, every worker's patch
        // cache claimed ahead of the frame): it must change no pixel either.
        reserve_frames(&mut ctx, &p, m, &FrameOptions::new(96, 64)).unwrap();
        for &(w, h, aa, r, k) in &frames {
            let mut o = FrameOptions::new(w, h);
            o.aa = base::method::Aa::new("aa", aa).unwrap();
            o.renderers = r;
            o.region = 32;
            let cam = moved(&p.scene.camera, k);
            let stats = render_frame_in(&mut ctx, &p, m, &cam, &o)
                .unwrap_or_else(|e| panic!("{rel} {name}: {e}"));
            let fresh = render_frame(&p, m, &cam, &o).unwrap();
            assert_eq!(ctx.pixels().len(), fresh.pixels.len());
            let differ = ctx
                .pixels()
                .iter()
                .zip(&fresh.pixels)
                .filter(|(a, b)| a.to_array().map(f32::to_bits) != b.to_array().map(f32::to_bits))
                .count();
            assert_eq!(
                differ, 0,
                "{rel} {name} {w}x{h} aa {aa} R {r} cam {k}: {differ} pixels differ"
            );
            assert_eq!(stats.pixels_shaded, fresh.stats.pixels_shaded);
            assert_eq!(stats.patch_table_entries, fresh.stats.patch_table_entries);
            assert_eq!(
                stats.composition_traffic_bytes,
                fresh.stats.composition_traffic_bytes
            );
            compared += 1;
        }
    }
    assert_eq!(compared, methods.len() * frames.len());
}

fn check_scene(rel: &str) {
    check_scene_methods(rel, true);
}

#[test]
fn a_reused_context_draws_the_two_spots_plane_as_a_new_one() {
    check_scene("scenes/two-spots.toml");
}

#[test]
fn a_reused_context_draws_many_small_quads_as_a_new_one() {
    // 2,500 sub-pixel quads: 32-bit edge lanes, mixed blocks, many table entries per region.
    check_scene_methods("scenes/hard/subpixel.toml", false);
}

#[test]
fn a_reused_context_draws_patch_borders_as_a_new_one() {
    check_scene("scenes/hard/patch-borders.toml");
}

/// The memory report counts the patch caches the frame's workspaces allocate: one per worker,
/// each what [`reconstruction::compact::CompactReconstruction::cache_bytes`] says.
#[test]
fn the_memory_report_counts_the_patch_caches_the_frame_allocates() {
    let p = prepared("scenes/two-spots.toml");
    let mut ctx = FrameContext::new();
    reserve_frames(&mut ctx, &p, Method::Direct, &FrameOptions::new(64, 48)).unwrap();
    let workers = rayon::current_num_threads();
    assert_eq!(ctx.patch_cache_bytes(), workers * p.compact.cache_bytes());
    let m = app::memory::Memory::of(&p).unwrap();
    assert_eq!(m.rrp_caches, ctx.patch_cache_bytes() as u64);
}
