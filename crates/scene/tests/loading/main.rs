//! Scene loading: the three shipped scenes load with the exact contents their files describe,
//! every kind of bad input is refused with a message that names file, line
//! and key, and no input makes the loader panic (property tests on random and mutated files).

use base::error::EXIT_BAD_INPUT;
use base::Error;
use glam::DVec3;
use proptest::prelude::*;
use scene::{load_scene, parse_scene, Projection, Scene, Shape, MAX_IMAGE_DIM};
use std::path::{Path, PathBuf};

/// The repository's root: the shipped scenes and the scene format's documentation.
const REPO: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../..");

fn scenes() -> PathBuf {
    Path::new(REPO).join("scenes")
}

/// A small valid scene: a quad lit by an emitting triangle.
const BASE: &str = r#"[camera]
eye = [0.5, 0.5, 2.0]
look_at = [0.5, 0.5, 0.0]
fov_y = 45.0

[[materials]]
name = "white"
reflectance = [0.5, 0.5, 0.5]

[[materials]]
name = "lamp"
reflectance = [0.5, 0.5, 0.5]
emission = [1.0, 1.0, 1.0]

[[polygons]]
vertices = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]
material = "white"

[[polygons]]
vertices = [[0, 0, 1], [0, 1, 1], [1, 1, 1]]
material = "lamp"
"#;

/// `BASE` with `from` replaced by `to` (which must occur exactly once).
fn edit(from: &str, to: &str) -> String {
    assert_eq!(
        BASE.matches(from).count(),
        1,
        "`{from}` must occur once in BASE"
    );
    BASE.replacen(from, to, 1)
}

/// 1-based line of the first line of `text` containing `needle`.
fn line_of(text: &str, needle: &str) -> usize {
    text.lines()
        .position(|l| l.contains(needle))
        .unwrap_or_else(|| panic!("`{needle}` not in text"))
        + 1
}

/// Parses `text` as `test.toml`, expects an input error, and returns its message.
fn error_of(text: &str) -> String {
    match parse_scene(text, Path::new("test.toml")) {
        Ok(_) => panic!("accepted:\n{text}"),
        Err(e) => {
            assert_eq!(e.exit_code(), EXIT_BAD_INPUT, "{e}");
            assert!(matches!(e, Error::Input { .. }), "{e:?}");
            e.to_string()
        }
    }
}

/// Asserts the error for `text` is at `test.toml:<line of needle>` and contains every fragment.
fn assert_error(text: &str, needle: &str, fragments: &[&str]) {
    let msg = error_of(text);
    let at = format!("test.toml:{}:", line_of(text, needle));
    assert!(msg.starts_with(&at), "expected `{at}` in: {msg}");
    for f in fragments {
        assert!(msg.contains(f), "expected `{f}` in: {msg}");
    }
}

/// The promises `Scene` makes to later stages.
fn check_invariants(s: &Scene) {
    assert!(!s.polygons.is_empty());
    assert!((1..=MAX_IMAGE_DIM).contains(&s.width) && (1..=MAX_IMAGE_DIM).contains(&s.height));
    for m in &s.materials {
        assert!(m.reflectance.cmpge(DVec3::ZERO).all() && m.reflectance.cmplt(DVec3::ONE).all());
        assert!(m.emission.is_finite() && m.emission.cmpge(DVec3::ZERO).all());
    }
    for p in &s.polygons {
        assert!((p.material as usize) < s.materials.len());
        assert!((p.object as usize) < s.objects.len());
        assert!(p.corners.iter().all(|c| c.is_finite()));
        assert!(p.area.is_finite() && p.area > 0.0);
        // A unit normal to rounding.
        assert!((p.normal.length() - 1.0).abs() < 1e-9);
        if p.shape == Shape::Quad {
            // Projected onto their plane: exactly planar up to f64 rounding of the projection.
            let diag = (p.corners[2] - p.corners[0]).length();
            let c = p.centroid();
            for q in p.corners {
                assert!((q - c).dot(p.normal).abs() <= 1e-9 * diag.max(1.0));
            }
        }
    }
    let has_light =
        s.emitter_count() > 0 || s.spots.iter().any(|l| l.intensity.max_element() > 0.0);
    assert!(has_light);
    for l in &s.spots {
        assert!(l.position.is_finite() && (l.direction.length() - 1.0).abs() < 1e-12);
    }
}

/// A scratch directory for one test, removed and recreated.
fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("pfs-scene-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

mod no_panic;
mod obj;
mod refusals;
mod shipped;
