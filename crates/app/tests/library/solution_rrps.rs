//! Solution files carry the compact RRPs their solve built: a render from the file decodes them
//! instead of rebuilding, draws exactly what a render from the scene draws, and a file whose RRP
//! bytes are damaged (behind a valid checksum) is refused as corrupt.

use app::context::Context;
use std::path::{Path, PathBuf};

use app::commands::solve::solve_to_file;
use app::context::TextureOptions;
use app::frames::render_frame;
use app::prepare::prepare_path;
use base::error::{Error, SolutionProblem};
use base::method::Method;
use engine::frame::FrameOptions;
use radiosity::file;
use reconstruction::compact::CompactReconstruction;
use reconstruction::Estimator;
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
fn the_file_holds_the_rrps_and_renders_like_the_scene() {
    let out = tmp("two-spots.pfsol");
    let sol = solve_to_file(&Context::default(), &scene(), &out).unwrap();
    let s = load_scene(&scene()).unwrap();
    let (_, rrps) = file::read_solution(&out, &s).unwrap();
    // What a solve stores: the RRPs with the default estimator, the scene's seams and the spots'
    // edges followed at the default levels.
    let spots = app::prepare::spot_light(&s, &sol, reconstruction::sharp::DEFAULT_LEVELS).unwrap();
    let built = CompactReconstruction::build_with(
        &sol.polygons,
        Estimator::default(),
        &app::prepare::seams_of(&s),
        spots.as_ref().map(|l| l.sharp()),
    )
    .unwrap();
    assert_eq!(rrps, built.encode());
    assert_eq!(CompactReconstruction::decode(&rrps).unwrap(), built);

    let from_file = prepare_path(&Context::default(), &out, &TextureOptions::default()).unwrap();
    let from_scene =
        prepare_path(&Context::default(), &scene(), &TextureOptions::default()).unwrap();
    assert_eq!(from_file.compact, from_scene.compact);
    let opts = FrameOptions::new(96, 96);
    let a = render_frame(&from_file, Method::Direct, &from_file.scene.camera, &opts).unwrap();
    let b = render_frame(&from_scene, Method::Direct, &from_scene.scene.camera, &opts).unwrap();
    assert_eq!(a.pixels, b.pixels);
}

#[test]
fn damaged_rrps_behind_a_valid_checksum_are_refused() {
    let s = load_scene(&scene()).unwrap();
    let out = tmp("damaged.pfsol");
    let sol = solve_to_file(&Context::default(), &scene(), &out).unwrap();
    let (_, rrps) = file::read_solution(&out, &s).unwrap();
    // Truncated RRPs, garbage, and RRPs of another polygon count: each re-encoded with a valid
    // envelope and checksum, so only the RRP decoder can notice.
    let two = CompactReconstruction::build(
        &[sol.polygons[0].clone(), sol.polygons[0].clone()],
        Estimator::default(),
    )
    .unwrap()
    .encode();
    for bad in [rrps[..rrps.len() / 2].to_vec(), vec![7u8; 64], two] {
        let bytes =
            file::encode_with_scene(&sol, Some(&std::fs::canonicalize(scene()).unwrap()), &bad);
        std::fs::write(&out, bytes).unwrap();
        match prepare_path(&Context::default(), &out, &TextureOptions::default()) {
            Err(Error::Solution {
                problem, message, ..
            }) => {
                assert_eq!(problem, SolutionProblem::Corrupt, "{message}");
                assert!(message.contains("RRPs"), "{message}");
            }
            Err(e) => panic!("expected a corrupt solution file, got {e:?}"),
            Ok(_) => panic!("damaged RRPs were accepted"),
        }
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
    // Each method is charged its own representation, by the one rule.
    assert_eq!(m.method_bytes(Method::Direct), m.rrp_compact);
    assert_eq!(
        m.method_bytes(Method::Texture(Filter::Bilinear)),
        texture_bytes(&p.textures().unwrap().0.memory)
    );
    assert_eq!(
        m.method_bytes(Method::Mesh),
        p.mesh().unwrap().0.stats.bytes
    );
    // Compact is smaller than expanded, encoded smaller than held.
    assert!(m.rrp_encoded < m.rrp_compact && m.rrp_compact < m.rrp_expanded);
}

/// The samples-alone form (16-bit samples, derivatives re-estimated on load) is measured beside
/// the Hermite form: its bytes are what `stats` reports, and rendering from it moves the direct
/// image by a perceptual distance of at most 1.5e-3 (measured 8.2e-4 on two-spots, 4.1e-4 on
/// cornell-box), and where the direct image is visibly off the exact one (cornell-box, 0.40) its
/// distance to it by at most 2 %. On two-spots, whose light is all spots followed exactly, the
/// direct image is only 3.7e-4 from exact, so the quantization's move is of that order there.
/// Not less: the estimator's limiter is not linear in the samples (a sample moved by 1/65535 can
/// change where it acts), which is one reason files keep the Hermite form, quantized after the
/// estimate.
#[test]
fn samples_alone_at_16_bits_barely_move_the_direct_image() {
    use app::memory::Memory;
    use engine::frame::render_patches;
    use imageio::LinearImage;
    use metric::{perceptual_distance, DEFAULT_PPD};
    use reconstruction::samples_form;
    let root = Path::new(crate::REPO);
    for name in ["two-spots", "cornell-box"] {
        let p = prepare_path(
            &Context::default(),
            &root.join(format!("scenes/{name}.toml")),
            &TextureOptions::default(),
        )
        .unwrap();
        let m = Memory::of(&p).unwrap();
        assert_eq!(
            m.rrp_samples as usize,
            samples_form::encoded_len(&p.solution.polygons, 16)
        );
        // Three 16-bit samples per vertex against twelve 16-bit Hermite quantities.
        assert!(m.rrp_samples * 3 < m.rrp_encoded, "{name}: {m:?}");

        let q = samples_form::quantize(&p.solution.polygons, 16);
        for (a, b) in p.solution.polygons.iter().zip(&q) {
            let bound = samples_form::sample_bound(a, 16);
            for (x, y) in a.values.iter().zip(&b.values) {
                for c in 0..3 {
                    assert!((x[c] as f64 - y[c] as f64).abs() <= bound[c]);
                }
            }
        }
        let spots = app::prepare::spot_light(&p.scene, &p.solution, p.sharp_levels).unwrap();
        let from_samples = CompactReconstruction::build_with(
            &q,
            Estimator::default(),
            &p.seams,
            spots.as_ref().map(|l| l.sharp()),
        )
        .unwrap();
        let opts = FrameOptions::new(128, 128);
        let cam = &p.scene.camera;
        let image =
            |f: engine::frame::Frame| LinearImage::new(f.width, f.height, f.pixels).unwrap();
        let exact = image(render_frame(&p, Method::Reference, cam, &opts).unwrap());
        let held = image(render_frame(&p, Method::Direct, cam, &opts).unwrap());
        let alone = image(render_patches(&p.scene, cam, &from_samples, &opts).unwrap());
        let d_held = perceptual_distance(&held, &exact, DEFAULT_PPD).unwrap();
        let d_alone = perceptual_distance(&alone, &exact, DEFAULT_PPD).unwrap();
        let change = (d_alone - d_held).abs() / d_held;
        let moved = perceptual_distance(&alone, &held, DEFAULT_PPD).unwrap();
        eprintln!(
            "{name}: distance to exact {d_held:.5} -> {d_alone:.5} ({:.4} %), moved {moved:.5}",
            100.0 * change
        );
        assert!(
            moved <= 1.5e-3,
            "{name}: moved {moved} ({d_held} -> {d_alone})"
        );
        if d_held > 0.05 {
            assert!(change < 0.02, "{name}: {d_held} -> {d_alone}");
        }
    }
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
    let bytes = file::encode_with_scene(&sol, Some(&std::fs::canonicalize(scene()).unwrap()), &[]);
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

/// The same class later in the pipeline: a file whose stored RRPs are sound (so it loads and
/// the direct method draws it) but whose samples are not. The texture methods expand the
/// samples and fail there; that failure is the file's (exit 2), not the program's (exit 1).
#[test]
fn bad_samples_found_by_a_later_stage_are_still_bad_input() {
    let out = tmp("huge-later.pfsol");
    solve_to_file(&Context::default(), &scene(), &out).unwrap();
    let s = load_scene(&scene()).unwrap();
    let (mut sol, rrps) = file::decode(&std::fs::read(&out).unwrap(), &s).unwrap();
    assert!(!rrps.is_empty(), "the file stores its RRPs");
    let v = &mut sol.polygons[0].values;
    let mid = v.len() / 2;
    v[mid] = glam::Vec3::splat(3.0e38);
    let path = std::fs::canonicalize(scene()).unwrap();
    std::fs::write(&out, file::encode_with_scene(&sol, Some(&path), &rrps)).unwrap();
    let p =
        prepare_path(&Context::default(), &out, &TextureOptions::default()).expect("RRPs decode");
    let opts = FrameOptions::new(16, 16);
    assert!(render_frame(&p, Method::Direct, &p.scene.camera, &opts).is_ok());
    let method = Method::parse("texture-bilinear").unwrap();
    match render_frame(&p, method, &p.scene.camera, &opts) {
        Err(e @ Error::Solution { .. }) => {
            assert_eq!(e.exit_code(), 2);
            assert!(e.to_string().contains("corrupt solution file"), "{e}");
        }
        Err(e) => panic!("expected a corrupt solution file, got {e:?}"),
        Ok(_) => panic!("unreconstructable samples were drawn"),
    }
}
