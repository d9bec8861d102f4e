//! OBJ includes: faces and materials validated at their line, imported and transformed as
//! the including scene says, and large or repetitive files checked in linear time.

use super::*;

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
