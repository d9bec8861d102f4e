//! The shipped scenes load with the exact contents their files describe (the documented example
//! too), and the repairs a loader makes to real input (a nearly planar quad flattened, a folded
//! one split, absent sections defaulted, two-sided materials twinned) keep what the file means.

use super::*;

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
    // their lines inside it): 30 pieces, of equal total area; the ceiling along the outline of
    // the lamp hanging 1 cm under it: a 3 x 3 grid.
    assert_eq!(s.contacts.lines.len(), 12);
    assert_eq!(s.contacts.outlines(), 4);
    assert_eq!(s.contacts.pieces, vec![(0, 30), (1, 9)]);
    assert_eq!(s.polygons.len(), 17 - 2 + 30 + 9);
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
/// both lines; a polygon overlapping another in the same plane is kept with a warning, and
/// buries the part of the other under it; the two sides of a thin wall (back to back) are two
/// surfaces.
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
    assert!(s.warnings[0].contains("overlaps the one at") && s.warnings[0].contains("50.0 %"));
    // The later of the two (the same size) lies on top: the first is cut along its outline,
    // and the half under it is buried.
    assert_eq!(s.polygons.len(), 4);
    let buried: Vec<f64> = s
        .polygons
        .iter()
        .filter(|p| p.sealed == scene::seal::Sealed::Buried)
        .map(|p| p.area)
        .collect();
    assert!(
        buried.len() == 1 && (buried[0] - 0.5).abs() < 1e-9,
        "{buried:?}"
    );
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
    // along 144 contact lines, and the ceiling tiles over the six 1 m light panels hung 1 cm
    // under them along the panels' outlines (48 lines), into 390 pieces.
    let (cut, pieces) = s.contacts.counts();
    assert_eq!((s.contacts.lines.len(), cut, pieces), (192, 88, 390));
    assert_eq!(s.contacts.outlines(), 48);
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
