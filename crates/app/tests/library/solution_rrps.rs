//! Solution files carry the trees and samples the RRPs are built from, not the RRPs: a render
//! from the file builds them with the function a render after a solve uses, so it draws exactly
//! what a render from the scene draws, and the RRPs' stored bytes are the samples'.

use app::context::Context;
use std::path::{Path, PathBuf};

use app::commands::solve::solve_to_file;
use app::context::TextureOptions;
use app::frames::render_frame;
use app::prepare::prepare_path;
use base::error::Error;
use base::method::Method;
use engine::frame::FrameOptions;
use radiosity::file;
use scene::load_scene;

fn tmp(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join("solution_rrps");
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

fn scene() -> PathBuf {
    Path::new(crate::REPO).join("scenes/two-spots.toml")
}

#[test]
fn a_render_from_the_file_draws_what_a_render_from_the_scene_draws() {
    let out = tmp("two-spots.pfsol");
    let sol = solve_to_file(&Context::default(), &scene(), &out).unwrap();
    let s = load_scene(&scene()).unwrap();
    let mut back = file::read_solution(&out, &s).unwrap();
    back.stats.solve_ms = sol.stats.solve_ms;
    back.stats.rays_cast = sol.stats.rays_cast;
    assert_eq!(back, sol);

    let from_file = prepare_path(&Context::default(), &out, &TextureOptions::default()).unwrap();
    let from_scene =
        prepare_path(&Context::default(), &scene(), &TextureOptions::default()).unwrap();
    assert_eq!(from_file.compact, from_scene.compact);
    let opts = FrameOptions::new(96, 96);
    for method in ["direct", "texture-bicubic", "mesh"] {
        let m = Method::parse(method).unwrap();
        let a = render_frame(&from_file, m, &from_file.scene.camera, &opts).unwrap();
        let b = render_frame(&from_scene, m, &from_scene.scene.camera, &opts).unwrap();
        assert_eq!(a.pixels, b.pixels, "{method}");
    }
}

#[test]
fn memory_accounting_agrees_with_what_is_built() {
    use app::memory::{expanded_rrp_bytes, texture_bytes, Memory};
    use base::method::Filter;
    let p = prepare_path(&Context::default(), &scene(), &TextureOptions::default()).unwrap();
    let m = Memory::of(&p).unwrap();
    // The expanded bytes, computed from the compact form's counts, are the built expansion's.
    assert_eq!(
        expanded_rrp_bytes(&p.compact),
        p.expanded().unwrap().0.stats().bytes as u64
    );
    assert_eq!(m.rrp_expanded, expanded_rrp_bytes(&p.compact));
    // Each method is charged its own representation, by the one rule: the direct method what a
    // solution file spends on the trees and samples.
    assert_eq!(m.method_bytes(Method::Direct), m.rrp_stored);
    assert_eq!(m.rrp_stored, file::samples_bytes(&p.solution));
    assert_eq!(
        m.method_bytes(Method::Texture(Filter::Bilinear)),
        texture_bytes(&p.textures().unwrap().0.memory)
    );
    assert_eq!(
        m.method_bytes(Method::Mesh),
        p.mesh().unwrap().0.stats.bytes
    );
    // The paper's compactness claim, at equal sampling: the RRPs as stored take at most half the
    // 12-bit textures (12 bytes per vertex of an adaptive tree against 4.5 per texel of a
    // texture as fine as the tree's deepest level everywhere; measured 0.032).
    assert!(
        2 * m.rrp_stored <= m.textures.bytes[1],
        "{} stored against {} of 12-bit textures",
        m.rrp_stored,
        m.textures.bytes[1]
    );
    // Three f32 per vertex against twelve quantized Hermite quantities (30 bytes per vertex
    // that is not a T-vertex), the held f32 form and the expanded patches.
    assert!(
        m.rrp_stored < m.rrp_encoded
            && m.rrp_encoded < m.rrp_compact
            && m.rrp_compact < m.rrp_expanded,
        "{m:?}"
    );
}

/// Samples behind a valid checksum that cannot be reconstructed (so large that the patches
/// overflow f32) are a corrupt file, exit 2. Regression: this exited 1, as a program failure.
#[test]
fn unreconstructable_samples_behind_a_valid_checksum_are_bad_input() {
    let out = tmp("huge.pfsol");
    let mut sol = solve_to_file(&Context::default(), &scene(), &out).unwrap();
    let v = &mut sol.polygons[0].values;
    let mid = v.len() / 2;
    v[mid] = glam::Vec3::splat(3.0e38);
    let bytes = file::encode_with_scene(&sol, Some(&std::fs::canonicalize(scene()).unwrap()));
    std::fs::write(&out, bytes).unwrap();
    match prepare_path(&Context::default(), &out, &TextureOptions::default()) {
        Err(e @ Error::Solution { .. }) => {
            assert_eq!(e.exit_code(), 2);
            assert!(e.to_string().contains("cannot be reconstructed"), "{e}");
        }
        Err(e) => panic!("expected a corrupt solution file, got {e:?}"),
        Ok(_) => panic!("an unreconstructable solution was accepted"),
    }
}
