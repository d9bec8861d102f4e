//! Triangulated models load as the quads they were made of (`scene::triangle_pairs`): the
//! Cornell box written as triangles, split along either diagonal, is the same scene as the
//! quad one, so its solve, its seams and its exports are too; a floor cut into a fan of eight
//! is four quarters joined C1; and `radiosity.merge_triangles = false` keeps the triangles.

use std::path::Path;

use glam::DVec3;

const CORNELL: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes/cornell-box.toml");

/// The Cornell box with every quad face of its OBJ written as two triangles: along the diagonal
/// from the first corner when `first` is set, along the other one otherwise (as tools choose
/// either), and the scene file's lines `edits` (whole line, replacement) changed.
pub(crate) fn triangulated_cornell(first: bool, edits: &[(&str, &str)]) -> scene::Scene {
    let path = Path::new(CORNELL);
    let text = edited(edits);
    let read = move |p: &Path| -> std::io::Result<String> {
        let t = std::fs::read_to_string(p)?;
        if p.extension().is_some_and(|e| e == "obj") {
            return Ok(t.lines().map(|l| split_face(l, first) + "\n").collect());
        }
        Ok(t)
    };
    scene::parse_scene_with(&text, path, &read).expect("the triangulated box loads")
}

/// The Cornell box's scene file with the lines `edits` (whole line, replacement) changed.
fn edited(edits: &[(&str, &str)]) -> String {
    let text = std::fs::read_to_string(CORNELL).unwrap();
    let mut out = String::new();
    for l in text.lines() {
        let e = edits.iter().find(|e| e.0 == l);
        out += e.map_or(l, |e| e.1);
        out.push('\n');
    }
    for e in edits {
        assert!(
            text.lines().any(|l| l == e.0),
            "{} is a line of the scene",
            e.0
        );
    }
    out
}

/// An OBJ `f` line of four corners as two `f` lines of three; any other line as it is.
fn split_face(line: &str, first: bool) -> String {
    let w: Vec<&str> = line.split_whitespace().collect();
    if w.first() != Some(&"f") || w.len() != 5 {
        return line.to_string();
    }
    let (a, b, c, d) = (w[1], w[2], w[3], w[4]);
    if first {
        format!("f {a} {b} {c}\nf {a} {c} {d}")
    } else {
        format!("f {b} {c} {d}\nf {b} {d} {a}")
    }
}

/// Whether polygons `a` and `b` have the same corners within `tol`, whichever comes first.
fn same_corners(a: &scene::Polygon, b: &scene::Polygon, tol: f64) -> bool {
    let near = |p: &DVec3, q: &scene::Polygon| q.corners.iter().any(|c| c.distance(*p) <= tol);
    a.corners.iter().all(|p| near(p, b)) && b.corners.iter().all(|p| near(p, a))
}

#[test]
fn a_triangulated_cornell_box_loads_as_the_quad_one() {
    let quads = scene::load_scene(Path::new(CORNELL)).unwrap();
    for first in [true, false] {
        let tri = triangulated_cornell(first, &[]);
        // 16 faces once the 2 repeats are dropped; the left wall, not planar, is split by the
        // loader in either scene and its halves are not coplanar enough to merge.
        assert_eq!(tri.merged.triangles, 32);
        assert_eq!(tri.merged.pairs, 15);
        assert_eq!(tri.polygons.len(), quads.polygons.len());
        // The pieces a contact cut makes of one face follow its first corner, which a merged
        // face may take from the other triangle: each quad is matched by its corners, not its
        // place among its face's pieces.
        for a in &tri.polygons {
            if a.shape == scene::Shape::Triangle {
                // The left wall's halves: the loader splits it along the diagonal from its
                // first corner, the file here may have split it along the other.
                continue;
            }
            // The loader flattens a quad it reads onto its best-fit plane; a merged one keeps
            // the triangles' corners: the same points to rounding.
            let b = quads
                .polygons
                .iter()
                .find(|b| same_corners(a, b, 1e-12))
                .unwrap_or_else(|| panic!("no quad has the corners {:?}", a.corners));
            assert_eq!(a.shape, b.shape);
            assert_eq!(a.material, b.material);
            assert!((a.area - b.area).abs() <= 1e-12 * b.area);
        }
        assert!(tri
            .notes
            .iter()
            .any(|n| n.contains("15 pairs of the 32 triangles")));
    }
}

#[test]
fn merging_is_refused_by_the_setting_and_said_by_check() {
    let kept = triangulated_cornell(true, &[("seed = 1", "seed = 1\nmerge_triangles = false")]);
    assert_eq!(kept.merged.pairs, 0);
    let triangles = kept
        .polygons
        .iter()
        .filter(|p| p.shape == scene::Shape::Triangle)
        .count();
    // The box's floor is cut at the boxes' feet into pieces; every other face stays 2 triangles.
    assert!(triangles >= 30, "{triangles} triangles");
    let text = app::report::summarize(&kept).to_string();
    assert!(text.contains("triangle pairs not merged"), "{text}");
    let merged = app::report::summarize(&triangulated_cornell(true, &[])).to_string();
    assert!(
        merged.contains("; 15 triangle pairs merged into quads"),
        "{merged}"
    );
}

/// A 2 x 2 floor as a fan of eight triangles about its centre (one OBJ object, as a modelling
/// tool writes it), under a small light.
fn fan_floor() -> scene::Scene {
    let b = [
        [1.0, 0.0],
        [1.0, 1.0],
        [0.0, 1.0],
        [-1.0, 1.0],
        [-1.0, 0.0],
        [-1.0, -1.0],
        [0.0, -1.0],
        [1.0, -1.0],
    ];
    // (x, z) in the floor y = 0; faces counter-clockwise seen from above (+y).
    let mut obj = String::from("o floor\nv 0 0 0\n");
    for p in b {
        obj += &format!("v {} 0 {}\n", p[0], p[1]);
    }
    for i in 0..8 {
        obj += &format!("f 1 {} {}\n", 2 + (i + 1) % 8, 2 + i);
    }
    let text = "[camera]\neye = [0.0, 3.0, 0.1]\nlook_at = [0.0, 0.0, 0.0]\nfov_y = 60.0\n\n\
         [[materials]]\nname = \"light\"\nreflectance = [0.0, 0.0, 0.0]\nemission = [5.0, 5.0, 5.0]\n\n\
         [[polygons]]\nmaterial = \"light\"\n\
         vertices = [[0.3, 1.0, -0.2], [0.7, 1.0, -0.2], [0.7, 1.0, 0.2], [0.3, 1.0, 0.2]]\n\n\
         [[materials]]\nname = \"floor\"\nreflectance = [0.5, 0.5, 0.5]\n\n\
         [[obj]]\nfile = \"fan.obj\"\ndefault_material = \"floor\"\n";
    let read = move |_: &Path| -> std::io::Result<String> { Ok(obj.clone()) };
    scene::parse_scene_with(text, Path::new("fan.toml"), &read).expect("loads")
}

#[test]
fn a_fan_of_eight_is_four_quarters_joined_c1() {
    let scene = fan_floor();
    assert_eq!(scene.merged.pairs, 4);
    let floor: Vec<&scene::Polygon> = scene.polygons.iter().skip(1).collect();
    assert_eq!(floor.len(), 4);
    for q in &floor {
        assert_eq!(q.shape, scene::Shape::Quad);
        assert!((q.area - 1.0).abs() < 1e-12);
        assert!((q.normal - DVec3::Y).length() < 1e-12);
    }
    // The quarters meet along two whole lines through the centre: four whole coplanar edges of
    // one material, all joined C1 (none C0, none apart).
    let s = app::report::summarize(&scene);
    assert_eq!(s.seams, (4, 0, 0, 0), "{}", s);
}

#[test]
fn a_triangulated_box_solves_at_the_quad_box_size() {
    // Coarse settings: what is compared is the size of the work, not the light.
    let coarse = [
        ("max_depth = 7", "max_depth = 4"),
        ("tolerance = 0.01", "tolerance = 0.05"),
        ("convergence = 0.01", "convergence = 0.05"),
    ];
    let sizes = |scene: &scene::Scene| {
        let sol = radiosity::solve(scene, &radiosity::SolveOptions::default()).expect("solves");
        (
            sol.stats.elements,
            radiosity::file::encode(&sol).len() as u64,
        )
    };
    let tri = sizes(&triangulated_cornell(false, &coarse));
    let quad = sizes(&scene::parse_scene(&edited(&coarse), Path::new(CORNELL)).unwrap());
    let ratio = |a: u64, b: u64| a as f64 / b as f64;
    assert!(ratio(tri.0, quad.0) <= 1.2, "{tri:?} against {quad:?}");
    assert!(ratio(tri.1, quad.1) <= 1.2, "{tri:?} against {quad:?}");
}
