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

// ---------------------------------------------------------------------------------------------
// Shipped scenes.

#[test]
fn two_spots_scene_is_one_unit_square_filling_the_image() {
    let s = load_scene(&scenes().join("two-spots.toml")).unwrap();
    check_invariants(&s);
    assert!(s.warnings.is_empty());
    assert_eq!((s.width, s.height), (256, 256));
    assert_eq!(s.polygons.len(), 1);
    let p = &s.polygons[0];
    assert_eq!(p.shape, Shape::Quad);
    // (u, v) = world (x, y): image space = texture space, v = 0 on the bottom row (y = 0 is the
    // bottom of an image whose up is +y).
    // Exact at the corners; elsewhere to a few ulps of the bilinear blend.
    for (u, v) in [(0.0, 0.0), (0.25, 0.75), (1.0, 1.0), (0.3, 0.1)] {
        assert!((p.point(u, v) - DVec3::new(u, v, 0.0)).length() < 1e-15);
    }
    assert_eq!(p.normal, DVec3::Z);
    let c = s.camera;
    assert_eq!(c.look_at - c.eye, DVec3::new(0.0, 0.0, -2.0));
    assert_eq!(c.up, DVec3::Y);
    assert_eq!(
        c.projection,
        Projection::Orthographic {
            width: 1.0,
            height: 1.0
        }
    );
    assert_eq!(s.materials.len(), 1);
    assert_eq!(s.materials[0].reflectance, DVec3::splat(0.8));
    assert_eq!(s.emitter_count(), 0);
    assert_eq!(s.spots.len(), 2);
    let (small, large) = (&s.spots[0], &s.spots[1]);
    // The bright spot points at the upper-left quarter, the dim one elsewhere.
    assert!(small.position.x < 0.5 && small.position.y > 0.5);
    assert!(!(large.position.x < 0.5 && large.position.y > 0.5));
    // The bright spot's cone covers the whole plane (its farthest corner is 64.8 deg off the
    // axis), and the grid of Fig. 5 resolves it: falloff 5 (scenes/two-spots.toml).
    assert!((small.half_angle - 87f64.to_radians()).abs() < 1e-15);
    assert_eq!(small.falloff, 5.0);
    assert!((large.half_angle - 60f64.to_radians()).abs() < 1e-15);
    // On-axis radiosity B = rho I / h^2: 3.2 for the small spot, 0.5 for the large.
    let b = |l: &scene::SpotLight| 0.8 * l.intensity.x / l.position.z.powi(2);
    assert!((b(small) - 3.2).abs() < 1e-12 && (b(large) - 0.5).abs() < 1e-12);
    assert_eq!(s.radiosity.max_depth, 7);
}

#[test]
fn two_spots_narrow_differs_only_in_the_bright_spot() {
    // The hard case: the shipped scene with the bright spot of falloff 60 in a 40 deg cone,
    // whose edge cuts at cos^60(40 deg) = 1e-7 of the peak; everything else is the same.
    let wide = load_scene(&scenes().join("two-spots.toml")).unwrap();
    let s = load_scene(&scenes().join("two-spots-narrow.toml")).unwrap();
    check_invariants(&s);
    assert!(s.warnings.is_empty());
    assert_eq!(s.spots.len(), 2);
    let (n, w) = (&s.spots[0], &wide.spots[0]);
    assert_eq!(n.falloff, 60.0);
    assert!((n.half_angle - 40f64.to_radians()).abs() < 1e-15);
    assert!(n.half_angle.cos().powf(n.falloff) < 1e-6);
    assert_eq!(
        (n.position, n.direction, n.intensity),
        (w.position, w.direction, w.intensity)
    );
    assert_eq!(s.spots[1].falloff, wide.spots[1].falloff);
    assert_eq!(s.spots[1].half_angle, wide.spots[1].half_angle);
    assert_eq!(s.spots[1].position, wide.spots[1].position);
    assert_eq!(s.polygons.len(), 1);
    assert_eq!(s.polygons[0].vertices(), wide.polygons[0].vertices());
    assert_eq!(s.camera, wide.camera);
}

#[test]
fn cornell_box_loads_with_its_quirks() {
    let whole = scene::LoadOptions {
        overrides: vec![("radiosity.cut_contacts".into(), "false".into())],
        ..scene::LoadOptions::default()
    };
    let uncut = scene::load_scene_with(&scenes().join("cornell-box.toml"), &whole).unwrap();
    // 18 faces, two of them repeats (the short box's "Bottom Face" repeats its right face, the
    // tall box's last face its front), counted once; the left wall split in two.
    assert_eq!(uncut.polygons.len(), 17);
    let s = load_scene(&scenes().join("cornell-box.toml")).unwrap();
    check_invariants(&s);
    // The floor cut along the 8 lines where the boxes' sides stand on it (the arrangement of
    // their lines inside it): 30 pieces, of equal total area.
    assert_eq!(s.contacts.lines.len(), 8);
    assert_eq!(s.contacts.pieces, vec![(0, 30)]);
    assert_eq!(s.polygons.len(), 17 - 1 + 30);
    let floor: f64 = s.polygons[..30].iter().map(|p| p.area).sum();
    assert!((floor - uncut.polygons[0].area).abs() < 1e-12 * floor);
    let s = uncut;
    let tris = s
        .polygons
        .iter()
        .filter(|p| p.shape == Shape::Triangle)
        .count();
    assert_eq!(tris, 2);
    // The shipped OBJ's repairs are notes (they change nothing the image shows); no warning.
    assert!(s.warnings.is_empty(), "{:?}", s.warnings);
    assert_eq!(s.notes.len(), 3);
    let w = &s.notes[0];
    assert!(
        w.contains("CornellBox-Original.obj:62") && w.contains("leftWall"),
        "{w}"
    );
    assert!(w.contains("0.176%"), "{w}");
    for (w, line, first) in [(&s.notes[1], 107, 93), (&s.notes[2], 155, 148)] {
        assert!(
            w.contains(&format!("CornellBox-Original.obj:{line}"))
                && w.contains("repeats the one at")
                && w.contains(&format!("CornellBox-Original.obj:{first}")),
            "{w}"
        );
    }
    // Materials as in the MTL, exact to the decimal (the loader undoes tobj's f32).
    let m = |n: &str| s.materials.iter().find(|m| m.name == n).unwrap();
    assert_eq!(s.materials.len(), 8);
    assert_eq!(m("leftWall").reflectance, DVec3::new(0.63, 0.065, 0.05));
    assert_eq!(m("rightWall").reflectance, DVec3::new(0.14, 0.45, 0.091));
    assert_eq!(m("floor").reflectance, DVec3::new(0.725, 0.71, 0.68));
    assert_eq!(m("light").emission, DVec3::new(17.0, 12.0, 4.0));
    assert_eq!(s.emitter_count(), 1);
    let light = s
        .polygons
        .iter()
        .find(|p| s.materials[p.material as usize].name == "light")
        .unwrap();
    // 0.47 x 0.38 rectangle facing down.
    assert!((light.area - 0.47 * 0.38).abs() < 1e-12);
    assert!((light.normal - DVec3::NEG_Y).length() < 1e-12);
    // No two polygons with identical corners are left.
    let dup = s
        .polygons
        .iter()
        .enumerate()
        .any(|(i, a)| s.polygons[i + 1..].iter().any(|b| a.corners == b.corners));
    assert!(!dup);
    // Camera converted from the official data: fov 2 atan(0.0125 / 0.035).
    let Projection::Perspective { fov_y_deg } = s.camera.projection else {
        panic!("perspective expected")
    };
    let expect = 2.0 * (0.0125f64 / 0.035).atan().to_degrees();
    assert!((fov_y_deg - expect).abs() < 1e-4, "{fov_y_deg} vs {expect}");
    let s_mm = 1.99 / 548.8;
    assert!((s.camera.eye - DVec3::new(0.0, 273.0 * s_mm, 0.99 + 800.0 * s_mm)).length() < 1e-5);
    assert_eq!((s.width, s.height), (512, 512));
}

/// A surface listed twice reflects its light twice: the same wall twice put x2.05 of its light
/// on the floor. The loader keeps the first copy (whatever corner the copy starts at) and names
/// both lines; a polygon overlapping another in the same plane is kept with a warning; the
/// two sides of a thin wall (back to back) are two surfaces.
#[test]
fn repeated_polygons_are_counted_once_and_overlaps_named() {
    let copy = "[[polygons]]\nvertices = [[1, 1, 0], [0, 1, 0], [0, 0, 0], [1, 0, 0]]\nmaterial = \"white\"\n";
    let text = format!("{BASE}\n{copy}");
    let s = parse_scene(&text, Path::new("test.toml")).unwrap();
    assert_eq!(s.polygons.len(), 2);
    assert_eq!(s.notes.len(), 1, "{:?}", s.notes);
    let (copy_line, first_line) = (
        line_of(&text, "[[1, 1, 0], [0, 1, 0]"),
        line_of(&text, "[[0, 0, 0], [1, 0, 0]"),
    );
    let w = &s.notes[0];
    assert!(
        w.starts_with(&format!(
            "test.toml:{copy_line}: polygons[2].vertices: this polygon repeats"
        )) && w.contains(&format!("test.toml:{first_line}")),
        "{w}"
    );
    let half = "[[polygons]]\nvertices = [[0.5, 0, 0], [1.5, 0, 0], [1.5, 1, 0], [0.5, 1, 0]]\nmaterial = \"white\"\n";
    let s = parse_scene(&format!("{BASE}\n{half}"), Path::new("test.toml")).unwrap();
    assert_eq!(s.polygons.len(), 3);
    assert!(s.warnings[0].contains("overlaps the one at") && s.warnings[0].contains("50.0 %"));
    let back = "[[polygons]]\nvertices = [[0, 0, 0], [0, 1, 0], [1, 1, 0], [1, 0, 0]]\nmaterial = \"white\"\n";
    let s = parse_scene(&format!("{BASE}\n{back}"), Path::new("test.toml")).unwrap();
    assert_eq!((s.polygons.len(), s.warnings.len()), (3, 0));
}

#[test]
fn gallery_loads() {
    let s = load_scene(&scenes().join("gallery.toml")).unwrap();
    check_invariants(&s);
    assert!(s.warnings.is_empty());
    // 946 quads, of which the floors and the pedestals' tops under what stands on them are cut
    // along 144 contact lines into 286 pieces.
    let (cut, pieces) = s.contacts.counts();
    assert_eq!((s.contacts.lines.len(), cut, pieces), (144, 72, 286));
    // The cut pieces' T-junctions with the tiles beside them do not line up: those tiles are
    // cut through them (`scene::junctions`).
    let (t_cut, t_pieces) = s.junctions.counts();
    assert!(t_cut > 0 && t_pieces > t_cut);
    assert_eq!(s.polygons.len(), 946 - cut + pieces - t_cut + t_pieces);
    assert_eq!(s.emitter_count(), 6);
    assert_eq!(s.spots.len(), 3);
    assert_eq!(s.materials.len(), 8);
    assert_eq!(s.radiosity.max_depth, 6);
    let light = s.materials.iter().find(|m| m.name == "light").unwrap();
    assert_eq!(light.emission, DVec3::new(12.0, 11.0, 9.0));
}

// ---------------------------------------------------------------------------------------------
// Repairs.

#[test]
fn nearly_planar_quad_is_projected_onto_its_plane() {
    // Corner 2 lifted by 0.001 over a diagonal of sqrt(2): the best-plane deviation is 0.00025,
    // 0.018% of the diagonal, within the 0.1% tolerance.
    let text = edit("[1, 1, 0], [0, 1, 0]]", "[1, 1, 0.001], [0, 1, 0]]");
    let s = parse_scene(&text, Path::new("test.toml")).unwrap();
    assert!(s.warnings.is_empty());
    check_invariants(&s);
    let q = &s.polygons[0];
    assert_eq!(q.shape, Shape::Quad);
    // Each corner moved by the deviation 0.00025 along the normal, no more.
    assert!((q.corners[2] - DVec3::new(1.0, 1.0, 0.001)).length() < 0.00025 + 1e-12);
    assert!((q.corners[2] - DVec3::new(1.0, 1.0, 0.001)).length() > 0.00025 - 1e-6);
}

#[test]
fn non_planar_quad_is_split_with_a_warning() {
    // Corner 2 lifted by 0.1: deviation 0.025 / 1.41 = 1.8% of the diagonal.
    let text = edit("[1, 1, 0], [0, 1, 0]]", "[1, 1, 0.1], [0, 1, 0]]");
    let s = parse_scene(&text, Path::new("test.toml")).unwrap();
    check_invariants(&s);
    assert_eq!(s.polygons.len(), 3);
    assert_eq!(s.polygons[0].shape, Shape::Triangle);
    assert_eq!(s.polygons[1].shape, Shape::Triangle);
    // The two triangles keep the original corners and together cover the original quad.
    assert_eq!(s.polygons[0].corners[2], DVec3::new(1.0, 1.0, 0.1));
    assert_eq!(s.notes.len(), 1);
    let w = &s.notes[0];
    let line = line_of(&text, "[1, 1, 0.1]");
    assert!(
        w.starts_with(&format!(
            "test.toml:{line}: polygons[0].vertices: quad is not planar"
        )),
        "{w}"
    );
}

#[test]
fn defaults_fill_absent_sections() {
    let s = parse_scene(BASE, Path::new("test.toml")).unwrap();
    assert_eq!((s.width, s.height), (512, 512));
    assert_eq!(s.radiosity, Default::default());
    assert_eq!(s.render, Default::default());
    assert_eq!(s.display, Default::default());
    assert_eq!(s.camera.up, DVec3::Y);
    assert_eq!(
        s.objects,
        vec!["polygons[0]".to_string(), "polygons[1]".to_string()]
    );
    assert!(s.camera_path.is_none());
}

// ---------------------------------------------------------------------------------------------
// Every kind of bad input, with file, line and key.

#[test]
fn unknown_keys_are_refused_with_their_line() {
    let text = edit("fov_y = 45.0", "fov_y = 45.0\nfocal = 3.0");
    assert_error(&text, "focal", &["unknown field `focal`"]);
    let text = edit("name = \"lamp\"", "name = \"lamp\"\nshiny = true");
    assert_error(&text, "shiny", &["unknown field `shiny`"]);
    let text = format!("{BASE}\n[lighting]\nx = 1\n");
    assert_error(&text, "[lighting]", &["unknown field `lighting`"]);
}

#[test]
fn syntax_errors_name_the_line() {
    let text = edit("look_at = [0.5, 0.5, 0.0]", "look_at = [0.5, 0.5, 0.0");
    let msg = error_of(&text);
    assert!(msg.starts_with("test.toml:"), "{msg}");
    let text = edit(
        "reflectance = [0.5, 0.5, 0.5]\n\n[[materials]]",
        "reflectance = \"grey\"\n\n[[materials]]",
    );
    assert_error(&text, "\"grey\"", &["invalid type"]);
}

#[test]
fn missing_files_are_input_errors() {
    let e = load_scene(Path::new("/nonexistent/scene.toml")).unwrap_err();
    assert_eq!(e.exit_code(), EXIT_BAD_INPUT);
    assert!(
        e.to_string()
            .starts_with("/nonexistent/scene.toml: cannot read scene file"),
        "{e}"
    );
    let text = format!("{BASE}\n[[obj]]\nfile = \"nope/missing.obj\"\n");
    assert_error(
        &text,
        "missing.obj",
        &["obj[0].file", "cannot read OBJ file", "missing.obj"],
    );
}

#[test]
fn nan_and_inf_are_refused() {
    let text = edit(
        "reflectance = [0.5, 0.5, 0.5]\n\n[[materials]]",
        "reflectance = [nan, 0.5, 0.5]\n\n[[materials]]",
    );
    assert_error(
        &text,
        "nan",
        &["materials[0].reflectance", "component 0 is NaN", "finite"],
    );
    let text = edit("eye = [0.5, 0.5, 2.0]", "eye = [0.5, inf, 2.0]");
    assert_error(&text, "inf", &["camera.eye", "component 1 is inf"]);
    let text = edit("[0, 0, 1], [0, 1, 1]", "[0, 0, -inf], [0, 1, 1]");
    assert_error(&text, "-inf", &["polygons[1].vertices[0]", "-inf"]);
    let text = edit("fov_y = 45.0", "fov_y = nan");
    assert_error(&text, "fov_y", &["camera.fov_y", "NaN"]);
    let text = edit("eye = [0.5, 0.5, 2.0]", "eye = [0.5, 0.5, 2e300]");
    assert_error(&text, "2e300", &["camera.eye", "at most 1e9"]);
}

#[test]
fn degenerate_polygons_are_refused() {
    let text = edit(
        "[0, 0, 1], [0, 1, 1], [1, 1, 1]",
        "[0, 0, 1], [0, 1, 1], [0, 2, 1]",
    );
    assert_error(&text, "[0, 2, 1]", &["polygons[1]", "zero area"]);
    let text = edit(
        "[0, 0, 1], [0, 1, 1], [1, 1, 1]",
        "[0, 0, 1], [0, 0, 1], [1, 1, 1]",
    );
    assert_error(&text, "[0, 0, 1], [0, 0, 1]", &["polygons[1]", "zero area"]);
    // A quad with all four corners on a line.
    let text = edit(
        "[[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]",
        "[[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]]",
    );
    assert_error(&text, "[3, 0, 0]", &["polygons[0]", "zero net area"]);
    let text = edit(
        "[[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]",
        "[[0, 0, 0], [1, 0, 0]]",
    );
    assert_error(
        &text,
        "[[0, 0, 0], [1, 0, 0]]",
        &["polygons[0].vertices", "has 2 points"],
    );
}

/// Total area of the polygons of `s` made of material `material`.
fn area_of_material(s: &Scene, material: u32) -> f64 {
    s.polygons
        .iter()
        .filter(|p| p.material == material)
        .map(|p| 0.5 * scene::newell_normal(p.vertices()).length())
        .sum()
}

#[test]
fn concave_quads_and_collinear_corners_are_triangulated_with_a_note() {
    // Corner 2 pulled inside the triangle of the others: a dart, cut into two triangles.
    let text = edit("[1, 1, 0], [0, 1, 0]]", "[0.3, 0.3, 0], [0, 1, 0]]");
    let s = parse_scene(&text, Path::new("test.toml")).unwrap();
    check_invariants(&s);
    let white = s.polygons.iter().filter(|p| p.material == 0).count();
    assert_eq!(white, 2);
    // Shoelace: (0,0) (1,0) (0.3,0.3) (0,1) -> 0.5 * (0.3 + 0.3) = 0.3.
    assert!((area_of_material(&s, 0) - 0.3).abs() < 1e-12);
    let line = line_of(&text, "[0.3, 0.3, 0]");
    let note = format!("test.toml:{line}: polygons[0].vertices: 4-corner face is concave");
    assert!(
        s.notes
            .iter()
            .any(|w| w.starts_with(&note) && w.contains("ear clipping")),
        "{:?}",
        s.notes
    );
    // Three collinear corners (a triangle written as a quad): cut into triangles covering it.
    let text = edit("[1, 1, 0], [0, 1, 0]]", "[2, 0, 0], [0, 1, 0]]");
    let s = parse_scene(&text, Path::new("test.toml")).unwrap();
    check_invariants(&s);
    assert!(s.polygons.iter().filter(|p| p.material == 0).count() <= 2);
    assert!((area_of_material(&s, 0) - 1.0).abs() < 1e-12);
}

#[test]
fn self_intersecting_quads_are_refused() {
    // A bow tie: its signed areas cancel, zero net area.
    let text = edit("[1, 1, 0], [0, 1, 0]]", "[0, 1, 0], [1, 1, 0]]");
    assert_error(
        &text,
        "[0, 1, 0], [1, 1, 0]]",
        &["polygons[0]", "crosses itself"],
    );
    // A bow tie with unequal lobes has a net area but crosses itself: no triangulation.
    let text = edit(
        "[1, 0, 0], [1, 1, 0], [0, 1, 0]]",
        "[2, 0, 0], [0, 1, 0], [1, 1, 0]]",
    );
    assert_error(
        &text,
        "[2, 0, 0], [0, 1, 0]",
        &["polygons[0]", "crosses itself"],
    );
}

#[test]
fn material_values_out_of_range_are_refused() {
    let at = "reflectance = [0.5, 0.5, 0.5]\nemission";
    let text = edit(at, "reflectance = [0.5, 1.0, 0.5]\nemission");
    assert_error(
        &text,
        "1.0, 0.5]",
        &[
            "materials[1].reflectance",
            "component 1 is 1",
            "[0, 1)",
            "converge",
        ],
    );
    let text = edit(at, "reflectance = [-0.1, 0.5, 0.5]\nemission");
    assert_error(
        &text,
        "-0.1",
        &["materials[1].reflectance", "component 0 is -0.1"],
    );
    let text = edit("emission = [1.0, 1.0, 1.0]", "emission = [1.0, -2.0, 1.0]");
    assert_error(
        &text,
        "-2.0",
        &["materials[1].emission", "component 1 is -2", ">= 0"],
    );
}

#[test]
fn image_sizes_out_of_range_are_refused() {
    let text = format!("{BASE}\n[image]\nwidth = 0\nheight = 10\n");
    assert_error(&text, "width = 0", &["image.width", "is 0", "1..=16384"]);
    let text = format!("{BASE}\n[image]\nwidth = 10\nheight = 16385\n");
    assert_error(&text, "16385", &["image.height", "is 16385"]);
}

#[test]
fn unknown_and_duplicate_materials_are_refused() {
    let text = edit("material = \"lamp\"", "material = \"lmap\"");
    assert_error(
        &text,
        "lmap",
        &[
            "polygons[1].material",
            "unknown material `lmap`",
            "known: lamp, white",
        ],
    );
    let text = edit("name = \"lamp\"", "name = \"white\"");
    let msg = error_of(&text);
    let line = line_of(&text, "emission") - 2; // the second `name = "white"`
    assert!(
        msg.starts_with(&format!(
            "test.toml:{line}: materials[1].name: duplicate material name `white`"
        )),
        "{msg}"
    );
}

#[test]
fn bad_cameras_are_refused() {
    let text = edit("look_at = [0.5, 0.5, 0.0]", "look_at = [0.5, 0.5, 2.0]");
    assert_error(&text, "look_at", &["camera.look_at", "equals camera.eye"]);
    let text = edit("fov_y = 45.0", "fov_y = 45.0\nup = [0.0, 0.0, -3.0]");
    assert_error(&text, "up =", &["camera.up", "parallel"]);
    for fov in ["0.0", "180.0", "-5.0", "200.0"] {
        let text = edit("fov_y = 45.0", &format!("fov_y = {fov}"));
        assert_error(&text, "fov_y", &["camera.fov_y", "[0.01, 180)"]);
    }
    let text = edit(
        "fov_y = 45.0",
        "fov_y = 45.0\northo_width = 1.0\northo_height = 1.0",
    );
    assert_error(&text, "[camera]", &["camera", "either `fov_y`"]);
    let text = edit("fov_y = 45.0", "ortho_width = 1.0");
    assert_error(&text, "[camera]", &["either `fov_y`"]);
    let text = edit("fov_y = 45.0", "ortho_width = 1.0\northo_height = 0.0");
    assert_error(
        &text,
        "ortho_height",
        &["camera.ortho_height", "must be > 0"],
    );
}

#[test]
fn bad_radiosity_depths_are_refused() {
    let text = format!("{BASE}\n[radiosity]\nmin_depth = 5\nmax_depth = 3\n");
    assert_error(
        &text,
        "min_depth",
        &["radiosity.min_depth", "is 5, larger than max_depth 3"],
    );
    let text = format!("{BASE}\n[radiosity]\nmax_depth = 17\n");
    assert_error(
        &text,
        "max_depth",
        &["radiosity.max_depth", "is 17", "0..=16"],
    );
    let text = format!("{BASE}\n[radiosity]\nconvergence = 1.5\n");
    assert_error(
        &text,
        "convergence",
        &["radiosity.convergence", "[1e-7, 1)"],
    );
    // Settings no 32-bit sample can meet: refused, not left to refine or shoot forever.
    let text = format!("{BASE}\n[radiosity]\nconvergence = 1e-12\n");
    assert_error(
        &text,
        "convergence",
        &["radiosity.convergence", "is 0.000000000001"],
    );
    let text = format!("{BASE}\n[radiosity]\ntolerance = 1e-9\n");
    assert_error(
        &text,
        "tolerance",
        &["radiosity.tolerance", "at least 1e-6", "max_depth"],
    );
    let text = format!("{BASE}\n[radiosity]\nseed = -1\n");
    assert_error(&text, "seed", &["radiosity.seed", "is -1"]);
    let text = format!("{BASE}\n[radiosity]\nvisibility = \"approximate\"\n");
    assert_error(
        &text,
        "visibility",
        &[
            "radiosity.visibility",
            "`approximate`",
            "`auto`, `exact` or `sampled`",
        ],
    );
}

/// `radiosity.visibility` reads its three values (`auto` the default); whether each is part of
/// the scene's hash is the solver's test (`the_visibility_setting_is_hashed_unless_auto`).
#[test]
fn visibility_setting_is_read() {
    use scene::Visibility;
    let load = |v: &str| {
        let text = format!("{BASE}\n[radiosity]\n{v}\n");
        scene::parse_scene_with(&text, Path::new("/virtual/s.toml"), &|_: &Path| {
            Err(std::io::Error::new(std::io::ErrorKind::NotFound, "none"))
        })
        .unwrap()
    };
    assert_eq!(load("").radiosity.visibility, Visibility::Auto);
    let auto = load("visibility = \"auto\"");
    assert_eq!(auto.radiosity.visibility, Visibility::Auto);
    let exact = load("visibility = \"exact\"");
    assert_eq!(exact.radiosity.visibility, Visibility::Exact);
    let sampled = load("visibility = \"sampled\"");
    assert_eq!(sampled.radiosity.visibility, Visibility::Sampled);
}

#[test]
fn other_settings_are_checked() {
    let text = format!("{BASE}\n[render]\ntexture_size = 300\n");
    assert_error(
        &text,
        "texture_size",
        &["render.texture_size", "power of two"],
    );
    let text = format!("{BASE}\n[render]\naa = 0\n");
    assert_error(&text, "aa", &["render.aa", "is 0"]);
    let text = format!("{BASE}\n[render]\ntexel_placement = \"edge\"\n");
    assert_error(
        &text,
        "edge",
        &[
            "render.texel_placement",
            "`edge` is not a texel placement",
            "corner",
        ],
    );
    let s = parse_scene(
        &format!("{BASE}\n[render]\ntexel_placement = \"corner\"\n"),
        Path::new("test.toml"),
    )
    .unwrap();
    assert_eq!(s.render.texel_placement, base::method::Placement::Corner);
    // The renderer has sample patterns for 1, 4 and 16 samples only.
    let text = format!("{BASE}\n[render]\naa = 3\n");
    assert_error(&text, "aa", &["render.aa", "is 3", "1, 4 or 16"]);
    // A misspelt method is refused at load time (so `check` catches it), with its line.
    let text = format!("{BASE}\n[render]\nmethod = \"texturebilinear\"\n");
    assert_error(
        &text,
        "texturebilinear",
        &[
            "render.method",
            "`texturebilinear` is not a method",
            "texture-bilinear",
        ],
    );
    let s = parse_scene(
        &format!("{BASE}\n[render]\nmethod = \"texture-bicubic\"\n"),
        Path::new("test.toml"),
    )
    .unwrap();
    assert_eq!(s.render.method.name(), "texture-bicubic");
    let text = format!("{BASE}\n[display]\nbackground = [0, -1, 0]\n");
    assert_error(&text, "background", &["display.background", ">= 0"]);
    let text = format!("{BASE}\n[[spots]]\nposition = [0, 0, 1]\ndirection = [0, 0, 0]\nintensity = [1, 1, 1]\nhalf_angle = 30\n");
    assert_error(&text, "direction", &["spots[0].direction", "non-zero"]);
    let text = format!("{BASE}\n[[spots]]\nposition = [0, 0, 1]\ndirection = [0, 0, -1]\nintensity = [1, 1, 1]\nhalf_angle = 95\n");
    assert_error(&text, "half_angle", &["spots[0].half_angle", "(0, 90]"]);
    let text = format!("{BASE}\n[camera_path]\nframes = 10\nkeyframes = [{{ eye = [0, 0, 1], look_at = [0, 0, 0] }}]\n");
    assert_error(&text, "keyframes", &["camera_path.keyframes", "at least 2"]);
}

#[test]
fn camera_path_loads() {
    let text = format!(
        "{BASE}\n[camera_path]\nframes = 10\nkeyframes = [\n  {{ eye = [0, 0, 3], look_at = [0, 0, 0] }},\n  {{ eye = [1, 0, 3], look_at = [0, 0, 0], up = [0, 0, 1] }},\n]\n"
    );
    let s = parse_scene(&text, Path::new("test.toml")).unwrap();
    let cp = s.camera_path.unwrap();
    assert_eq!(cp.frames, 10);
    assert_eq!(cp.keyframes.len(), 2);
    assert_eq!(cp.keyframes[0].up, DVec3::Y);
    assert_eq!(cp.keyframes[1].up, DVec3::Z);
}

#[test]
fn scenes_without_polygons_or_light_are_refused() {
    let no_polys = BASE.split("[[polygons]]").next().unwrap().to_string();
    let msg = error_of(&no_polys);
    assert_eq!(
        msg,
        "test.toml: the scene has no polygons: add [[polygons]], [[obj]] or [[gltf]] entries"
    );
    let dark = edit("material = \"lamp\"", "material = \"white\"");
    let msg = error_of(&dark);
    assert!(
        msg.starts_with("test.toml: the scene has no light"),
        "{msg}"
    );
    assert!(msg.contains("black"), "{msg}");
    // A spot with zero intensity is no light either; one with intensity is.
    let spot = |i: &str| {
        format!("{dark}\n[[spots]]\nposition = [0.5, 0.5, 1]\ndirection = [0, 0, -1]\nintensity = [{i}, {i}, {i}]\nhalf_angle = 30\n")
    };
    assert!(error_of(&spot("0")).contains("no light"));
    assert!(parse_scene(&spot("1"), Path::new("test.toml")).is_ok());
}

// ---------------------------------------------------------------------------------------------
// OBJ includes.

/// A scratch directory for one test, removed and recreated.
fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("pfs-scene-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

const OBJ_SCENE: &str = r#"[camera]
eye = [0, 0, 5]
look_at = [0, 0, 0]
fov_y = 40

[[materials]]
name = "grey"
reflectance = [0.5, 0.5, 0.5]

[[obj]]
file = "m.obj"
"#;

fn write_obj(dir: &Path, obj: &str, mtl: &str) -> PathBuf {
    std::fs::write(dir.join("m.obj"), obj).unwrap();
    std::fs::write(dir.join("m.mtl"), mtl).unwrap();
    let scene = dir.join("s.toml");
    std::fs::write(&scene, OBJ_SCENE).unwrap();
    scene
}

const MTL: &str = "newmtl lamp\nKd 0.5 0.5 0.5\nKe 2 2 2\n\nnewmtl grey\nKd 0.25 0.25 0.25\n";

#[test]
fn obj_faces_are_validated_with_their_line() {
    let dir = scratch("obj-bad");
    // Face 2 is a bow tie: it crosses itself.
    let obj = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0.3 0.3 0\ng a\nusemtl lamp\nf 1 2 3 4\nf 1 2 4 3\n";
    let scene = write_obj(&dir, obj, MTL);
    let e = load_scene(&scene).unwrap_err();
    let msg = e.to_string();
    let expect = format!(
        "{}:10: face 2 (group `a`, face 2)",
        dir.join("m.obj").display()
    );
    assert!(msg.starts_with(&expect), "{msg}");
    assert!(msg.contains("crosses itself"), "{msg}");
    assert_eq!(e.exit_code(), EXIT_BAD_INPUT);
}

/// Asserts that loading a large input took `t` or less than the bound of the regression tests
/// of quadratic loading: 2 s in release builds (those inputs loaded in 5 to 15 s before their
/// fixes and in 0.3 s after), 30 s in debug builds.
fn assert_linear_time(t: std::time::Instant) {
    let bound = if cfg!(debug_assertions) { 30.0 } else { 2.0 };
    assert!(t.elapsed().as_secs_f64() < bound, "{:?}", t.elapsed());
}

/// An OBJ with one convex planar face of `n` corners on the unit circle.
fn polygon_obj(n: usize) -> String {
    let mut obj = String::from("mtllib m.mtl\n");
    for k in 0..n {
        let a = std::f64::consts::TAU * k as f64 / n as f64;
        obj += &format!("v {:.7} {:.7} 0\n", a.cos(), a.sin());
    }
    obj += "g a\nusemtl lamp\nf";
    for k in 1..=n {
        obj += &format!(" {k}");
    }
    obj + "\n"
}

/// Regression: checking a face compares every pair of its corners, so one OBJ face of 30 000
/// corners (a 200 kB file) took seconds to load; faces have at most `MAX_FACE_CORNERS`.
#[test]
fn huge_obj_face_is_refused_quickly_not_checked_quadratically() {
    use scene::load::MAX_FACE_CORNERS;
    let dir = scratch("obj-huge-face");
    let scene = write_obj(&dir, &polygon_obj(MAX_FACE_CORNERS), MTL);
    let s = load_scene(&scene).unwrap();
    check_invariants(&s);
    assert_eq!(s.polygons.len(), MAX_FACE_CORNERS - 2);

    for n in [MAX_FACE_CORNERS + 1, 30_000] {
        let scene = write_obj(&dir, &polygon_obj(n), MTL);
        let t = std::time::Instant::now();
        let msg = load_scene(&scene).unwrap_err().to_string();
        assert_linear_time(t);
        let expect = format!(
            "{}:{}: face 1 (group `a`, face 1): has {n} corners; a face has at most {MAX_FACE_CORNERS}",
            dir.join("m.obj").display(),
            n + 4
        );
        assert!(msg.starts_with(&expect), "{msg}");
    }
}

/// Regression: every `usemtl` (and every `materials` override) was checked by scanning all the
/// MTL's materials, so 50 000 of each (a 1.4 MB OBJ and MTL) took 13 s to load in release.
#[test]
fn many_usemtl_statements_are_checked_in_linear_time() {
    let n = 50_000;
    let dir = scratch("obj-many-usemtl");
    let mut mtl = String::new();
    let mut obj = String::from("mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\n");
    for k in 0..n {
        mtl += &format!("newmtl m{k}\nKd 0.5 0.5 0.5\nKe 1 1 1\n");
        obj += &format!("usemtl m{k}\n");
    }
    obj += "f 1 2 3\n";
    let scene = write_obj(&dir, &obj, &mtl);
    let t = std::time::Instant::now();
    let s = load_scene(&scene).unwrap();
    assert_linear_time(t);
    assert_eq!(s.polygons.len(), 1);
    assert_eq!(
        s.materials[s.polygons[0].material as usize].name,
        format!("m{}", n - 1)
    );
}

/// Regression: each include of an OBJ whose material name is taken searched `<stem>/<name>`,
/// `#2`, `#3`, ... from the start, so 8000 includes of one OBJ (a 200 kB scene) took 10 s.
#[test]
fn many_includes_of_one_obj_are_named_in_linear_time() {
    let n = 8000;
    let dir = scratch("obj-many-includes");
    let obj = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nusemtl lamp\nf 1 2 3\n";
    write_obj(&dir, obj, MTL);
    let mut text = String::from(OBJ_SCENE);
    for _ in 1..n {
        text += "\n[[obj]]\nfile = \"m.obj\"\n";
    }
    let scene = dir.join("s.toml");
    std::fs::write(&scene, text).unwrap();
    let t = std::time::Instant::now();
    let s = load_scene(&scene).unwrap();
    assert_linear_time(t);
    // The same triangle 8000 times is one surface, and each repeat is named.
    assert_eq!(s.polygons.len(), 1);
    // Each repeat has another material (`m/lamp#k`): a warning, not a note.
    assert_eq!(s.warnings.len(), n - 1);
    let names: Vec<&str> = s.materials.iter().map(|m| m.name.as_str()).collect();
    assert_eq!(names[..4], ["grey", "lamp", "m/lamp", "m/lamp#2"]);
    assert_eq!(names.last(), Some(&format!("m/lamp#{}", n - 1).as_str()));
}

/// Regression: tobj calls the MTL loader for every `mtllib` statement, and each call read and
/// parsed the file again (and duplicated its materials), so an OBJ repeating `mtllib` 2000 times
/// with a 2000-material MTL (80 kB in all) took 15 s. Each MTL is now read once per OBJ, and an
/// OBJ names at most `MAX_MTL_FILES` files.
#[test]
fn repeated_mtllib_reads_the_mtl_once() {
    use scene::load::MAX_MTL_FILES;
    let dir = scratch("obj-repeated-mtllib");
    let mut mtl = String::from(MTL);
    for k in 0..2000 {
        mtl += &format!("newmtl m{k}\nKd 0.5 0.5 0.5\n");
    }
    let mut obj = String::from("v 0 0 0\nv 1 0 0\nv 1 1 0\n");
    for _ in 0..2000 {
        obj += "mtllib m.mtl\nmtllib ./m.mtl\n";
    }
    obj += "usemtl lamp\nf 1 2 3\nmtllib m.mtl\nusemtl lamp\nf 1 3 2\n";
    let scene = write_obj(&dir, &obj, &mtl);
    let t = std::time::Instant::now();
    let s = load_scene(&scene).unwrap();
    assert_linear_time(t);
    // Both faces share the one imported `lamp` (a second read made a second copy, `m/lamp`).
    let names: Vec<&str> = s.materials.iter().map(|m| m.name.as_str()).collect();
    assert_eq!(names, ["grey", "lamp"]);
    assert_eq!(s.polygons.len(), 2);
    assert_eq!(s.inputs.len(), 3, "{:?}", s.inputs);

    // More distinct MTL files than the limit.
    let mut obj = String::from("v 0 0 0\nv 1 0 0\nv 1 1 0\n");
    for k in 0..=MAX_MTL_FILES {
        std::fs::write(dir.join(format!("a{k}.mtl")), MTL).unwrap();
        obj += &format!("mtllib a{k}.mtl\n");
    }
    obj += "usemtl lamp\nf 1 2 3\n";
    let scene = write_obj(&dir, &obj, MTL);
    let msg = load_scene(&scene).unwrap_err().to_string();
    let expect = format!(
        "{}: mtllib: names more than {MAX_MTL_FILES} MTL files",
        dir.join("m.obj").display()
    );
    assert_eq!(msg, expect);
}

#[test]
fn obj_materials_are_imported_and_prefixed_on_clash() {
    let dir = scratch("obj-mat");
    // A quad, a convex planar pentagon (fan-triangulated into 3) and a triangle.
    let obj = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 1.5 0.5 0\ng a\nusemtl lamp\nf 1 2 3 4\ng b\nusemtl grey\nf 1 2 5 3 4\nf 1 2 3\n";
    let scene = write_obj(&dir, obj, MTL);
    let s = load_scene(&scene).unwrap();
    check_invariants(&s);
    // The pentagon's fan of 3 triangles keeps one triangle and merges two into a quad
    // (`scene::triangle_pairs`); the lone triangle is another object's.
    assert_eq!(s.polygons.len(), 1 + 2 + 1);
    assert_eq!(s.merged.pairs, 1);
    let names: Vec<&str> = s.materials.iter().map(|m| m.name.as_str()).collect();
    // `grey` is taken by the scene's own material, so the MTL's becomes `m/grey`.
    assert_eq!(names, ["grey", "lamp", "m/grey"]);
    assert_eq!(s.materials[1].emission, DVec3::splat(2.0));
    assert_eq!(s.materials[2].reflectance, DVec3::splat(0.25));
    assert_eq!(s.objects, ["m/a", "m/b"]);
    // The pentagon's fan covers its area: quad 1 + pentagon (unit square plus a triangle of
    // 0.25) + triangle 0.5.
    let area: f64 = s.polygons.iter().map(|p| p.area).sum();
    assert!((area - (1.0 + 1.25 + 0.5)).abs() < 1e-12, "{area}");
}

#[test]
fn obj_transform_and_overrides_apply() {
    let dir = scratch("obj-xform");
    let obj = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\ng a\nusemtl grey\nf 1 2 3 4\ng b\nusemtl lamp\nf 1 2 3\n";
    write_obj(&dir, obj, MTL);
    let text = OBJ_SCENE.replace(
        "file = \"m.obj\"",
        "file = \"m.obj\"\nscale = [2, 1, -1]\nrotate = [0, 0, 90]\ntranslate = [10, 0, 0]\nmaterials = { grey = \"grey\" }",
    );
    let scene = dir.join("t.toml");
    std::fs::write(&scene, &text).unwrap();
    let s = load_scene(&scene).unwrap();
    check_invariants(&s);
    // Scale (2, 1, -1) then 90 degrees about z: (x, y, z) -> (-y, 2x, -z), then +10 in x.
    // The mirror (one negative factor) reverses the corner order: (0,1,0) -> (9, 0, 0) is first.
    let q = &s.polygons[0];
    assert_eq!(q.material, 0, "overridden to the scene's grey");
    let expect = [(9.0, 0.0), (9.0, 2.0), (10.0, 2.0), (10.0, 0.0)];
    for (c, (x, y)) in q.corners.iter().zip(expect) {
        assert!((*c - DVec3::new(x, y, 0.0)).length() < 1e-12, "{c}");
    }
    // Normals transform with the inverse transpose: M^-T (0, 0, 1) for M = diag(2, 1, -1) is
    // (0, 0, -1), and the rotation about z keeps it. The face's front is -z now, which only the
    // reversed corner order gives (the mapped corners in file order would wind to +z).
    assert!((q.normal - DVec3::NEG_Z).length() < 1e-12, "{}", q.normal);
    assert_eq!(s.materials[s.polygons[1].material as usize].name, "lamp");
    // An override naming a material the MTL does not have is an error.
    let bad = text.replace("grey = \"grey\"", "gray = \"grey\"");
    std::fs::write(&scene, &bad).unwrap();
    let msg = load_scene(&scene).unwrap_err().to_string();
    assert!(
        msg.contains("obj[0].materials.gray") && msg.contains("no material `gray`"),
        "{msg}"
    );
}

#[test]
fn obj_material_values_are_checked() {
    let dir = scratch("obj-kd");
    let obj = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\ng a\nusemtl lamp\nf 1 2 3\n";
    let scene = write_obj(&dir, obj, "newmtl lamp\nKd 1.0 0.5 0.5\nKe 1 1 1\n");
    // `Kd 1` (what modelling tools write for white) is clamped with a warning at its line...
    let mtl = dir.join("m.mtl").display().to_string();
    let s = load_scene(&scene).unwrap();
    assert_eq!(
        s.materials[1].reflectance,
        DVec3::new(scene::MAX_OBJ_REFLECTANCE, 0.5, 0.5)
    );
    assert!(
        s.warnings.iter().any(
            |w| w.starts_with(&format!("{mtl}:2: material `lamp` Kd")) && w.contains("clamped")
        ),
        "{:?}",
        s.warnings
    );
    // ... and refused under --strict. A value's problem is the MTL file's, at its line
    // (regression: it used to name the OBJ).
    let strict = scene::LoadOptions {
        strict: true,
        ..Default::default()
    };
    let msg = scene::load_scene_with(&scene, &strict)
        .unwrap_err()
        .to_string();
    assert!(
        msg.starts_with(&format!("{mtl}:2: material `lamp` Kd"))
            && msg.contains("component 0 is 1"),
        "{msg}"
    );
    let scene = write_obj(&dir, obj, "newmtl lamp\nKd 0.5 0.5 0.5\nKe 1 -1 1\n");
    let msg = load_scene(&scene).unwrap_err().to_string();
    assert!(
        msg.starts_with(&format!("{mtl}:3: material `lamp` Ke"))
            && msg.contains("component 1 is -1"),
        "{msg}"
    );
    // Four values are not a colour (regression: the fourth was ignored).
    let scene = write_obj(&dir, obj, "newmtl lamp\nKd 0.5 0.5 0.5 0.5\nKe 1 1 1\n");
    let msg = load_scene(&scene).unwrap_err().to_string();
    assert!(
        msg.starts_with(&format!("{mtl}:2: Kd: has 4 values, needs exactly three")),
        "{msg}"
    );
    // A `usemtl` no MTL defines is an error at its line (regression: the faces fell back to
    // the default material silently).
    let scene = write_obj(
        &dir,
        "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\ng a\nusemtl lmap\nf 1 2 3\n",
        MTL,
    );
    let text = OBJ_SCENE.replace(
        "file = \"m.obj\"",
        "file = \"m.obj\"\ndefault_material = \"grey\"",
    );
    std::fs::write(&scene, &text).unwrap();
    // With a default material, the faces take it, said at the `usemtl` line (never silently).
    // (A second face, of the MTL's lamp, lights the scene.)
    std::fs::write(
        dir.join("m.obj"),
        "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\ng a\nusemtl lmap\nf 1 2 3\nusemtl lamp\nf 1 3 2\n",
    )
    .unwrap();
    let s = load_scene(&scene).unwrap();
    let obj_path = dir.join("m.obj").display().to_string();
    assert!(
        s.warnings
            .iter()
            .any(|w| w.starts_with(&format!("{obj_path}:6: usemtl `lmap`"))
                && w.contains("no MTL file of this OBJ defines it")
                && w.contains("default material `grey`")),
        "{:?}",
        s.warnings
    );
    assert_eq!(s.materials[s.polygons[0].material as usize].name, "grey");
    // No usemtl and no default_material.
    let scene = write_obj(&dir, "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\n", MTL);
    let msg = load_scene(&scene).unwrap_err().to_string();
    assert!(
        msg.contains(":4: face 1") && msg.contains("no material"),
        "{msg}"
    );
}

// ---------------------------------------------------------------------------------------------
// No input makes the loader panic.

/// Either a scene that keeps every promise, or an input error at `test.toml`.
fn loads_or_refuses(text: &str) {
    match parse_scene(text, Path::new("test.toml")) {
        Ok(s) => check_invariants(&s),
        Err(e) => {
            assert_eq!(e.exit_code(), EXIT_BAD_INPUT, "{e}");
            assert!(e.to_string().starts_with("test.toml"), "{e}");
        }
    }
}

/// Every number literal in `BASE`, as byte ranges.
fn number_spans(text: &str) -> Vec<(usize, usize)> {
    let b = text.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        let starts =
            b[i].is_ascii_digit() || (b[i] == b'-' && i + 1 < b.len() && b[i + 1].is_ascii_digit());
        if starts && (i == 0 || !b[i - 1].is_ascii_alphanumeric()) {
            let j0 = i;
            i += 1;
            while i < b.len()
                && (b[i].is_ascii_digit() || b[i] == b'.' || b[i] == b'e' || b[i] == b'-')
            {
                i += 1;
            }
            out.push((j0, i));
        } else {
            i += 1;
        }
    }
    out
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

    #[test]
    fn random_text_never_panics(text in "[\\[\\]a-z_=.,0-9\" \n{}#-]{0,300}") {
        loads_or_refuses(&text);
    }

    #[test]
    fn mutated_scene_never_panics(
        edits in prop::collection::vec((0usize..1000, 0u8..3, "[\\[\\]a-z=.,0-9\" \n-]{0,4}"), 1..6)
    ) {
        let mut text = BASE.as_bytes().to_vec();
        for (pos, kind, ins) in edits {
            let p = pos % (text.len() + 1);
            match kind {
                0 => { text.splice(p..p, ins.bytes()); }
                1 => { let e = (p + ins.len().max(1)).min(text.len()); text.drain(p..e); }
                _ => { let e = (p + ins.len()).min(text.len()); text.splice(p..e, ins.bytes()); }
            }
        }
        loads_or_refuses(&String::from_utf8_lossy(&text));
    }

    #[test]
    fn mutated_numbers_never_panic(
        picks in prop::collection::vec((0usize..100, prop_oneof![
            Just("nan".to_string()), Just("inf".to_string()), Just("-inf".to_string()),
            Just("0".to_string()), Just("-0.0".to_string()), Just("1e300".to_string()),
            Just("-1e-300".to_string()), Just("1".to_string()), Just("0.999999".to_string()),
            Just("9223372036854775807".to_string()),
            (-1.0e3f64..1.0e3).prop_map(|x| format!("{x:?}")),
            (-5i64..20).prop_map(|x| x.to_string()),
        ]), 1..4)
    ) {
        let spans = number_spans(BASE);
        let mut chosen: Vec<(usize, String)> = picks.into_iter().map(|(i, v)| (i % spans.len(), v)).collect();
        chosen.sort_by_key(|c| std::cmp::Reverse(c.0));
        chosen.dedup_by_key(|c| c.0);
        let mut text = BASE.to_string();
        for (i, v) in chosen {
            let (a, b) = spans[i];
            text.replace_range(a..b, &v);
        }
        loads_or_refuses(&text);
    }
}

#[test]
fn documented_example_loads() {
    // The complete example of docs/scene-format.md, with the chair OBJ it includes.
    let doc = std::fs::read_to_string(Path::new(REPO).join("docs/scene-format.md")).unwrap();
    let start = doc.find("```toml\n").unwrap() + "```toml\n".len();
    let example = &doc[start..start + doc[start..].find("```").unwrap()];
    let dir = scratch("doc-example");
    std::fs::create_dir_all(dir.join("props")).unwrap();
    std::fs::write(
        dir.join("props/chair.obj"),
        "mtllib chair.mtl\nv 0 0 0\nv 50 0 0\nv 50 0 50\nv 0 0 50\ng seat\nusemtl fabric\nf 4 3 2 1\n",
    )
    .unwrap();
    std::fs::write(
        dir.join("props/chair.mtl"),
        "newmtl fabric\nKd 0.3 0.3 0.3\n",
    )
    .unwrap();
    let path = dir.join("example.toml");
    std::fs::write(&path, example).unwrap();
    let s = load_scene(&path).unwrap();
    check_invariants(&s);
    assert_eq!(s.polygons.len(), 4);
    assert_eq!(s.emitter_count(), 1);
    assert_eq!(s.render.aa_samples.samples(), 4);
    assert_eq!(s.camera_path.as_ref().unwrap().keyframes.len(), 2);
    // The chair's seat: 0.5 x 0.5 after scale 0.01, overridden to `red`, facing up.
    let seat = &s.polygons[3];
    assert!((seat.area - 0.25).abs() < 1e-12);
    assert_eq!(s.materials[seat.material as usize].name, "red");
    assert!((seat.normal - DVec3::Y).length() < 1e-12);
}

#[test]
fn vectors_must_have_exactly_three_numbers() {
    // Regression: serde's `[f64; 3]` silently dropped a fourth element under toml.
    let text = edit("eye = [0.5, 0.5, 2.0]", "eye = [0.5, 0.5, 2.0, 7.0]");
    assert_error(&text, "7.0", &["invalid length 4", "three numbers"]);
    let text = edit("[1, 1, 0], [0, 1, 0]]", "[1, 1], [0, 1, 0]]");
    assert_error(&text, "[1, 1], [0, 1, 0]]", &["invalid length 2"]);
    let text = format!("{BASE}\n[[obj]]\nfile = \"x.obj\"\nscale = \"big\"\n");
    assert_error(&text, "big", &["a number or three numbers"]);
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    /// Mutated copies of the Cornell OBJ (and MTL) are loaded or refused, never a panic.
    /// Regression: this found tobj 4.0.5 panicking on an MTL colour with fewer than three
    /// values, and an out-of-range face-line lookup for a model without faces.
    #[test]
    fn mutated_obj_never_panics(
        edits in prop::collection::vec((0usize..4000, 0u8..3, "[fvglusemtKd0-9 ./\n-]{0,5}"), 1..8),
        mtl_edits in prop::collection::vec((0usize..2000, "[Kde0-9 .\n-]{0,4}"), 0..3),
    ) {
        let src = scenes().join("cornell-box");
        let mut obj = std::fs::read(src.join("CornellBox-Original.obj")).unwrap();
        for (pos, kind, ins) in edits {
            let p = pos % (obj.len() + 1);
            match kind {
                0 => { obj.splice(p..p, ins.bytes()); }
                1 => { let e = (p + ins.len().max(1)).min(obj.len()); obj.drain(p..e); }
                _ => { let e = (p + ins.len()).min(obj.len()); obj.splice(p..e, ins.bytes()); }
            }
        }
        let mut mtl = std::fs::read(src.join("CornellBox-Original.mtl")).unwrap();
        for (pos, ins) in mtl_edits {
            let p = pos % (mtl.len() + 1);
            mtl.splice(p..p, ins.bytes());
        }
        let dir = std::env::temp_dir().join(format!("pfs-scene-{}-objfuzz", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("CornellBox-Original.obj"), &obj).unwrap();
        std::fs::write(dir.join("CornellBox-Original.mtl"), &mtl).unwrap();
        let scene = "[camera]\neye = [0, 1, 4]\nlook_at = [0, 1, 0]\nfov_y = 40\n\n[[obj]]\nfile = \"CornellBox-Original.obj\"\n";
        let path = dir.join("s.toml");
        std::fs::write(&path, scene).unwrap();
        match load_scene(&path) {
            Ok(s) => check_invariants(&s),
            Err(e) => prop_assert_eq!(e.exit_code(), EXIT_BAD_INPUT, "{}", e),
        }
    }
}

#[test]
fn short_mtl_colour_is_an_error_not_a_tobj_panic() {
    let dir = scratch("obj-short-kd");
    let obj = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\ng a\nusemtl lamp\nf 1 2 3\n";
    let scene = write_obj(&dir, obj, "newmtl lamp\nKd 0.5 0.5 0.5\nKe 2\n");
    let msg = load_scene(&scene).unwrap_err().to_string();
    let expect = format!(
        "{}:3: Ke: has 1 values, needs exactly three",
        dir.join("m.mtl").display()
    );
    assert!(msg.starts_with(&expect), "{msg}");
}

/// A 1 m light panel 2 cm under a ceiling, facing it (the panel of a tool that lit both of its
/// faces, exported one-sided the wrong way round): named in a warning with the surface it
/// faces, the gap and the fix. The shipped-style lamp of `BASE`, 1 m over what it lights, is
/// not: its light reaches the floor within its size, but not within an eighth of it.
#[test]
fn a_light_facing_a_close_surface_is_named_with_the_fix() {
    let ceiling = "[[polygons]]\nname = \"ceiling\"\nvertices = [[-1, -1, 1.02], [-1, 2, 1.02], [2, 2, 1.02], [2, -1, 1.02]]\nmaterial = \"white\"\n";
    let up = edit(
        "[[0, 0, 1], [0, 1, 1], [1, 1, 1]]",
        "[[0, 0, 1], [1, 1, 1], [0, 1, 1]]",
    );
    let text = format!("{up}\n{ceiling}");
    // The orientation checks, as `load_scene` adds them to a file's warnings.
    let warned = |text: &str| {
        let s = parse_scene(text, Path::new("test.toml")).unwrap();
        scene::orientation::warnings(&s)
    };
    let warnings = warned(&text);
    let trapped: Vec<&String> = warnings
        .iter()
        .filter(|w| w.contains("close for its size"))
        .collect();
    assert_eq!(trapped.len(), 1, "{warnings:?}");
    let w = trapped[0];
    let (lamp, ceiling_line) = (
        line_of(&text, "[[0, 0, 1], [1, 1, 1]"),
        line_of(&text, "1.02]"),
    );
    assert!(
        w.contains(&format!("test.toml:{lamp}"))
            && w.contains(&format!("test.toml:{ceiling_line}"))
            && w.contains("0.020 away")
            && w.contains("two_sided = true"),
        "{w}"
    );
    // Nearly all its light: all but the rays from near its corners that pass the ceiling's
    // edge within the distance it checks.
    let share: f64 = w
        .split(" % of its light")
        .next()
        .and_then(|h| h.rsplit(' ').next())
        .and_then(|n| n.parse().ok())
        .expect("a share");
    assert!(share >= 95.0, "{w}");
    let base = warned(BASE);
    assert!(
        base.iter().all(|w| !w.contains("close for its size")),
        "{base:?}"
    );
    // Two-sided, the face toward the ceiling is still trapped; the fix offered is the other.
    let two = text.replace(
        "emission = [1.0, 1.0, 1.0]",
        "emission = [1.0, 1.0, 1.0]\ntwo_sided = true",
    );
    let warnings = warned(&two);
    let w = warnings
        .iter()
        .find(|w| w.contains("close for its size"))
        .expect("warned");
    assert!(w.contains("its material is two-sided"), "{w}");
}

/// A two-sided material's polygon becomes two, the second its mirror (same corners wound the
/// other way, the opposite normal, the same material and area), named by the same line; a
/// note says how many; one-sided polygons stay single.
#[test]
fn two_sided_materials_get_a_reversed_twin() {
    let text = edit(
        "emission = [1.0, 1.0, 1.0]",
        "emission = [1.0, 1.0, 1.0]\ntwo_sided = true",
    );
    let s = parse_scene(&text, Path::new("test.toml")).unwrap();
    assert_eq!(s.polygons.len(), 3);
    let (a, b) = (&s.polygons[1], &s.polygons[2]);
    assert_eq!(a.material, b.material);
    assert!(
        (a.normal + b.normal).length() < 1e-12,
        "{} vs {}",
        a.normal,
        b.normal
    );
    assert!((a.area - b.area).abs() < 1e-12);
    assert!(a.vertices().iter().all(|v| b.vertices().contains(v)));
    assert_eq!(s.origin(1), s.origin(2));
    assert!(
        s.notes
            .iter()
            .any(|n| n.starts_with("1 polygons of two-sided materials")),
        "{:?}",
        s.notes
    );
    let s = parse_scene(BASE, Path::new("test.toml")).unwrap();
    assert_eq!(s.polygons.len(), 2);
}
