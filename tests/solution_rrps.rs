//! Solution files carry the compact RRPs their solve built: a render from the file decodes them
//! instead of rebuilding, draws exactly what a render from the scene draws, and a file whose RRP
//! bytes are damaged (behind a valid checksum) is refused as corrupt.

use std::path::{Path, PathBuf};

use pixelflow_sim::error::{Error, SolutionProblem};
use pixelflow_sim::frame::FrameOptions;
use pixelflow_sim::jobs::solve::solve_to_file;
use pixelflow_sim::jobs::{prepare_path, render_frame, TextureOptions};
use pixelflow_sim::method::Method;
use pixelflow_sim::progress::SILENT;
use pixelflow_sim::radiosity::file;
use pixelflow_sim::reconstruction::compact::CompactReconstruction;
use pixelflow_sim::reconstruction::Estimator;
use pixelflow_sim::scene::load_scene;

fn tmp(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join("solution_rrps");
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

fn scene() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/two-spots.toml")
}

#[test]
fn the_file_holds_the_rrps_and_renders_like_the_scene() {
    let out = tmp("two-spots.pfsol");
    let sol = solve_to_file(&scene(), &out, &SILENT).unwrap();
    let s = load_scene(&scene()).unwrap();
    let (_, rrps) = file::read_solution(&out, &s).unwrap();
    let built = CompactReconstruction::build(&sol.polygons, Estimator::default()).unwrap();
    assert_eq!(rrps, built.encode());
    assert_eq!(CompactReconstruction::decode(&rrps).unwrap(), built);

    let from_file = prepare_path(&out, &TextureOptions::default(), &SILENT).unwrap();
    let from_scene = prepare_path(&scene(), &TextureOptions::default(), &SILENT).unwrap();
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
    let sol = solve_to_file(&scene(), &out, &SILENT).unwrap();
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
        match prepare_path(&out, &TextureOptions::default(), &SILENT) {
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
    use pixelflow_sim::jobs::memory::{expanded_rrp_bytes, texture_bytes, Memory};
    use pixelflow_sim::method::Filter;
    let p = prepare_path(&scene(), &TextureOptions::default(), &SILENT).unwrap();
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
