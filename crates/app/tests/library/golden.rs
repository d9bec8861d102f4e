//! Golden images: every shipped scene (`scenes/*.toml`) but gallery-fine (see
//! [`every_shipped_scene_has_a_golden_test`]) rendered at 64 x 64 by every method (the
//! building's `reference` at 16 x 16), compared pixel by pixel with the EXR committed under
//! `crates/app/tests/golden/<scene>/<method>.exr`. The building is drawn from the generator
//! that wrote `scenes/building.toml`, with its options but 2 x 1 rooms instead of 8 x 8 and one
//! level shallower (see [`golden_building`]).
//!
//! The tolerance ([`pixels::DEFAULT_TOLERANCE`], 16 `f32` rounding steps relative to the pixel,
//! with an absolute floor for black pixels) passes a rebuild on the same CPU kind and breaks on
//! any one pixel that moves visibly, so an unintended change anywhere between the scene file and
//! the pixels fails here. On a failure the test names the pixels that moved and writes, under
//! `target/golden-diff/`, the image it got (`<scene>-<method>-got.exr`) and a difference image
//! (`<scene>-<method>-diff.png`, scaled so the largest difference is white).
//!
//! A change that is meant to move pixels regenerates the images on purpose, and the commit shows
//! them changing:
//!
//! ```text
//! PFS_UPDATE_GOLDEN=1 cargo test --release -p pixelflow-app --test library golden
//! ```
//!
//! The frames use 2 renderers (composition in the path) and no antialiasing; images are
//! bit-identical for any thread and renderer count, so the tolerance only absorbs what a
//! different build could round differently.

use std::path::{Path, PathBuf};

use app::frames::render_frame;
use app::prepare::Prepared;
use base::output::Outputs;
use base::Method;
use engine::frame::FrameOptions;
use imageio::{read_image, write_exr, write_png, LinearImage};
use metric::pixels::{self, DEFAULT_FLOOR, DEFAULT_TOLERANCE};

const SIZE: u32 = 64;

/// The image side for `method` on `scene`: [`SIZE`], but 16 for the building's `reference`,
/// which evaluates the solver's oracle (some 60,000 shots) at every pixel, 15 s at 64 x 64.
fn size_of(scene: &str, method: Method) -> u32 {
    if scene == "building" && method == Method::Reference {
        16
    } else {
        SIZE
    }
}

fn root() -> &'static Path {
    Path::new(crate::REPO)
}

fn updating() -> bool {
    std::env::var_os("PFS_UPDATE_GOLDEN").is_some_and(|v| v == "1")
}

/// Renders `scene` (a stem under `scenes/`) by every method and checks (or, when updating,
/// writes) its golden images; panics listing every method whose image moved.
fn check_scene(scene: &str) {
    check_prepared(scene, crate::shipped(scene));
}

/// Checks (or writes) the golden images of prepared scene `p` under the name `scene`.
fn check_prepared(scene: &str, p: &Prepared) {
    let dir = root().join("crates/app/tests/golden").join(scene);
    let out = root().join("target/golden-diff");
    let mut failures = Vec::new();
    for name in Method::NAMES {
        let method = Method::parse(name).expect("a method name");
        let size = size_of(scene, method);
        let opts = FrameOptions {
            renderers: 2,
            aa: base::method::Aa::ONE,
            ..FrameOptions::new(size, size)
        };
        let frame = render_frame(p, method, &p.scene.camera, &opts).expect("frame renders");
        let got = LinearImage::new(frame.width, frame.height, frame.view().pixels.to_vec())
            .expect("an image");
        let golden = dir.join(format!("{name}.exr"));
        if updating() {
            write_exr(&Outputs::new(), &golden, got.view()).expect("golden written");
            continue;
        }
        let want = match read_image(&golden) {
            Ok(w) => w,
            Err(e) => {
                failures.push(format!(
                    "{name}: no golden image ({e}); create it with \
                     PFS_UPDATE_GOLDEN=1 cargo test --release -p pixelflow-app --test library golden"
                ));
                continue;
            }
        };
        let d = pixels::diff(&got, &want, DEFAULT_TOLERANCE, DEFAULT_FLOOR).expect("same size");
        if d.differing > 0 {
            let stem = format!("{scene}-{name}");
            let got_path: PathBuf = out.join(format!("{stem}-got.exr"));
            let diff_path: PathBuf = out.join(format!("{stem}-diff.png"));
            write_exr(&Outputs::new(), &got_path, got.view()).expect("got written");
            write_png(
                &Outputs::new(),
                &diff_path,
                d.normalized_image().view(),
                0.0,
            )
            .expect("diff written");
            failures.push(format!(
                "{name}: {}\n  wrote {} and {}",
                d.summary(),
                got_path.display(),
                diff_path.display()
            ));
        }
    }
    assert!(
        failures.is_empty(),
        "{scene}: golden images differ (regenerate on purpose with \
         PFS_UPDATE_GOLDEN=1 cargo test --release -p pixelflow-app --test library golden):\n{}",
        failures.join("\n")
    );
}

/// Every shipped scene has a test below (so a new scene without goldens fails here), but
/// gallery-fine: the gallery's geometry, lights and camera solved at half the tolerance, whose
/// solve (90 s on 2 cores) does not fit the test command's time budget beside the building's.
/// The gallery's goldens draw the same scene by every method; gallery-fine's solve is measured
/// by `tools/performance.sh` and its images by `pixelflow-sim results`.
#[test]
fn every_shipped_scene_has_a_golden_test() {
    let mut stems: Vec<String> = std::fs::read_dir(root().join("scenes"))
        .unwrap()
        .filter_map(|e| {
            let p = e.unwrap().path();
            (p.extension().is_some_and(|x| x == "toml"))
                .then(|| p.file_stem().unwrap().to_string_lossy().into_owned())
        })
        .collect();
    stems.retain(|s| s != "gallery-fine");
    stems.sort();
    assert_eq!(stems, SCENES);
}

/// The shipped scenes solve at their own settings (the gallery one level coarser,
/// `crate::COARSER`) with nothing to warn about: no leaf where
/// refinement stopped at a guard misplaces more than the tolerance of the scene's light, the
/// energy account balances, and the light converged (what `render` and `solve` would print).
#[test]
fn shipped_scenes_solve_without_a_warning() {
    for name in SCENES.iter().filter(|&&n| n != "building") {
        let p = crate::shipped(name);
        let st = &p.solution.stats;
        assert_eq!(st.guard_stops.warning(&p.scene), None, "{name}");
        let light = st.light_warnings(p.scene.radiosity.convergence);
        assert!(light.is_empty(), "{name}: {light:?}");
    }
}

const SCENES: [&str; 8] = [
    "building",
    "cornell-box",
    "curved-wall",
    "gallery",
    "studio",
    "two-spots",
    "two-spots-narrow",
    "two-spots-paper",
];

/// The shipped building's generator and options (doorways, ceiling panels, furniture, shell
/// cut, camera down the first row of rooms) at 2 x 1 rooms, two rooms through a doorway, one
/// level shallower than the generator's depth limit: 64 rooms take over ten minutes to solve on
/// 2 cores, 2 x 1 rooms 22 s at the generator's depth and 12 s one level shallower, and the test
/// command's budget is ten minutes for everything; the shipped file is held equal to the
/// generator's output by the `generate` tests of the CLI.
#[test]
fn golden_building() {
    let mut scene = fixtures::generate::building_scene(2, 1, 2).unwrap();
    scene.radiosity.max_depth -= 1;
    check_built("building", "scenes/building.toml", scene);
}

/// Checks the golden images of `scene`, built in code, prepared as if loaded from `path`.
fn check_built(name: &str, path: &str, scene: scene::Scene) {
    let p = crate::prepare_scene(&root().join(path), scene);
    check_prepared(name, &p);
}

#[test]
fn golden_cornell_box() {
    check_scene("cornell-box");
}

/// A triangulated room: the Cornell box as a modelling tool's triangles, kept as triangles
/// (`merge_triangles = false`), so every method draws triangles joined across their diagonals;
/// solved one level coarser than the shipped box (`max_depth = 6`) to keep the test short.
#[test]
fn golden_cornell_box_triangles() {
    let edit = [
        ("seed = 1", "seed = 1\nmerge_triangles = false"),
        ("max_depth = 7", "max_depth = 6"),
    ];
    let scene = crate::triangles::triangulated_cornell(true, &edit);
    let triangles = scene
        .polygons
        .iter()
        .filter(|p| p.shape == scene::Shape::Triangle)
        .count();
    // Every face but the floor (cut along the boxes' feet) and the ceiling (along the lamp's
    // outline) stays the two triangles the file gives it: 14 faces, 28 triangles, and the cut
    // faces' pieces (some of them quads) on top.
    assert!(triangles > 28, "{triangles} triangles");
    check_built("cornell-box-triangles", "scenes/cornell-box.toml", scene);
}

/// A smooth surface: an OBJ wall of 32 facets with vertex normals, which receive light by
/// them (no step at the creases in any method).
#[test]
fn golden_curved_wall() {
    check_scene("curved-wall");
}

#[test]
fn golden_gallery() {
    check_scene("gallery");
}

/// The tutorial's model: an OBJ as a modelling tool writes it (concave n-gon floor and
/// ceiling, triangulated at load) included by a scene file.
#[test]
fn golden_studio() {
    check_scene("studio");
}

#[test]
fn golden_two_spots() {
    check_scene("two-spots");
}

#[test]
fn golden_two_spots_narrow() {
    check_scene("two-spots-narrow");
}

#[test]
fn golden_two_spots_paper() {
    check_scene("two-spots-paper");
}
