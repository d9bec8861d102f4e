//! `[[obj]]` includes: Wavefront OBJ/MTL geometry loaded with tobj and turned into scene
//! polygons.
//!
//! tobj parses; this module validates and converts. Faces are loaded untriangulated
//! (`triangulate: false`) so quads stay quads: the radiosity quadtrees, patches and textures all
//! live in each polygon's (u, v) domain, and a quad split into two triangles would double the
//! work and put a C1 seam across a flat face. Faces with more than four corners are
//! fan-triangulated if convex and planar and refused otherwise (see
//! [`super::load::build_face`]). Each face of an OBJ is numbered in file order and reported with
//! its line, found by matching the n-th `f`/`l` line of the text: tobj emits exactly one face per
//! such line when it does not triangulate.
//!
//! Transform: a point p of the OBJ becomes `translate + Rz * Ry * Rx * (scale * p)`, i.e. scale
//! first, then rotate about the fixed x axis, then y, then z (degrees, right-handed), then
//! translate. A transform with an odd number of negative scale factors mirrors the geometry;
//! the corner order of every face is then reversed so fronts stay fronts.
//!
//! Materials: an MTL material that a face uses becomes a scene material with the same name
//! (reflectance from `Kd`, emission from `Ke`, which tobj 4 parses into `emissive`), unless the
//! include's `materials` map overrides it with a scene material. If the name is already taken
//! (by a `[[materials]]` entry or an earlier include) the new material is named
//! `<obj file stem>/<name>`, then `<obj file stem>/<name>#2`, `#3`, ... until it is unique.
//!
//! tobj stores positions as `f32`. Each coordinate is turned back into the `f64` nearest to the
//! decimal tobj parsed by printing the `f32` in its shortest round-trip form and parsing that as
//! `f64`: `0.99` in the file becomes exactly `0.99_f64`, not `0.9900000095`. Files written with at
//! most 7 significant digits therefore load as written.

use super::format::{ObjSection, ScaleSpec};
use super::load::{build_face, check_emission, check_reflectance, in_range, Cx, MAX_MTL_FILES};
use super::{Material, Polygon};
use base::error::{Error, Location, Result};
use glam::{DMat3, DVec3};
use std::cell::RefCell;
use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;
use toml::Spanned;

/// Loads one `[[obj]]` include, appending to the scene's materials, objects and polygons.
pub(crate) fn include(
    cx: &mut Cx<'_>,
    section: &Spanned<ObjSection>,
    key: &str,
    materials: &mut Vec<Material>,
    by_name: &mut BTreeMap<String, u32>,
    objects: &mut Vec<String>,
    polygons: &mut Vec<Polygon>,
) -> Result<()> {
    let o = section.get_ref();
    let file = o.file.get_ref();
    let base = cx.path.parent().unwrap_or_else(|| Path::new(""));
    let obj_path = base.join(file);
    let read = cx.read;
    let text = read(&obj_path).map_err(|e| {
        cx.err(
            o.file.span(),
            format!("{key}.file"),
            format!("cannot read OBJ file {}: {e}", obj_path.display()),
        )
    })?;
    cx.inputs.push(obj_path.clone());

    // The transform.
    let scale = match &o.scale {
        None => DVec3::ONE,
        Some(s) => {
            let v = match s.get_ref() {
                ScaleSpec::Uniform(x) => DVec3::splat(*x),
                ScaleSpec::PerAxis(a) => DVec3::from_array(a.0),
            };
            if !v.to_array().iter().all(|x| in_range(*x)) || v.x == 0.0 || v.y == 0.0 || v.z == 0.0
            {
                return Err(cx.err(
                    s.span(),
                    format!("{key}.scale"),
                    format!("is {v}; every factor must be non-zero, finite and at most 1e9"),
                ));
            }
            v
        }
    };
    let rotate = match &o.rotate {
        None => DVec3::ZERO,
        Some(r) => cx.vec3(r, &format!("{key}.rotate"))?,
    };
    let translate = match &o.translate {
        None => DVec3::ZERO,
        Some(t) => cx.vec3(t, &format!("{key}.translate"))?,
    };
    let rotation = DMat3::from_rotation_z(rotate.z.to_radians())
        * DMat3::from_rotation_y(rotate.y.to_radians())
        * DMat3::from_rotation_x(rotate.x.to_radians());
    let mirrored = scale.x * scale.y * scale.z < 0.0;
    let transform = |p: DVec3| translate + rotation * (scale * p);

    let opts = tobj::LoadOptions {
        triangulate: false,
        single_index: false,
        ..Default::default()
    };
    // tobj reads the MTL through this loader so that each MTL is checked first (see
    // `check_mtl`), and an unreadable MTL is reported by name. Each MTL file is read once:
    // tobj calls the loader for every `mtllib` statement, and reading the file again for each
    // made an OBJ repeating one `mtllib` line quadratic (2000 lines of a 2000-material MTL took
    // 15 s, and each repeat duplicated every material). A file named again adds no materials
    // (tobj already has them), and an OBJ names at most `MAX_MTL_FILES` files (the bound on
    // reading one file under several spellings of its path).
    let mtl_seen: RefCell<BTreeSet<std::path::PathBuf>> = RefCell::new(BTreeSet::new());
    let mtl_problem: RefCell<Option<Error>> = RefCell::new(None);
    let mtl_unreadable: RefCell<Option<String>> = RefCell::new(None);
    let mtl_read: RefCell<Vec<std::path::PathBuf>> = RefCell::new(Vec::new());
    let mtl_defined: RefCell<BTreeMap<String, MtlSource>> = RefCell::new(BTreeMap::new());
    let obj_dir = obj_path
        .parent()
        .unwrap_or_else(|| Path::new(""))
        .to_path_buf();
    let load_mtl = |name: &Path| -> tobj::MTLLoadResult {
        let mtl_path = obj_dir.join(name);
        {
            let mut seen = mtl_seen.borrow_mut();
            if !seen.insert(mtl_path.components().collect()) {
                return Ok((Vec::new(), Default::default()));
            }
            if seen.len() > MAX_MTL_FILES {
                mtl_problem.borrow_mut().get_or_insert(Error::input(
                    Location::file(&obj_path).with_key("mtllib"),
                    format!("names more than {MAX_MTL_FILES} MTL files"),
                ));
                return Err(tobj::LoadError::MaterialParseError);
            }
        }
        let mtl_text = match read(&mtl_path) {
            Ok(t) => {
                mtl_read.borrow_mut().push(mtl_path.clone());
                t
            }
            Err(e) => {
                *mtl_unreadable.borrow_mut() =
                    Some(format!("cannot read MTL file {}: {e}", mtl_path.display()));
                return Err(tobj::LoadError::OpenFileFailed);
            }
        };
        if let Err(e) = check_mtl(&mtl_text, &mtl_path) {
            mtl_problem.borrow_mut().get_or_insert(e);
            return Err(tobj::LoadError::MaterialParseError);
        }
        mtl_sources(&mtl_text, &mtl_path, &mut mtl_defined.borrow_mut());
        tobj::load_mtl_buf(&mut mtl_text.as_bytes())
    };
    let parsed = tobj::load_obj_buf(&mut text.as_bytes(), &opts, load_mtl);
    cx.inputs.extend(mtl_read.into_inner());
    let mtl_defined = mtl_defined.into_inner();
    if let Some(e) = mtl_problem.into_inner() {
        return Err(e);
    }
    let (models, mtl) = parsed.map_err(|e| {
        Error::input(
            Location::file(&obj_path),
            format!("cannot parse OBJ file: {e}"),
        )
    })?;
    let mtl = match (mtl, mtl_unreadable.into_inner()) {
        (Err(_), Some(why)) => Err(why),
        (m, _) => m.map_err(|e| e.to_string()),
    };
    let (mtl_materials, mtl_error) = match mtl {
        Ok(m) => (m, None),
        Err(e) => (Vec::new(), Some(e)),
    };

    // The MTL materials' names, looked up once per `usemtl` and per override (a scan of the
    // materials for each made a file with many of both quadratic: 50 000 of each took 13 s).
    let mtl_names: BTreeSet<&str> = mtl_materials.iter().map(|m| m.name.as_str()).collect();

    // Material overrides: every key must be an MTL material, every value a scene material.
    let mut overrides: BTreeMap<String, u32> = BTreeMap::new();
    if let Some(map) = &o.materials {
        for (from, to) in map.get_ref() {
            let mkey = format!("{key}.materials.{from}");
            if !mtl_names.contains(from.as_str()) {
                return Err(cx.err(
                    map.span(),
                    mkey,
                    format!("the OBJ's MTL has no material `{from}`"),
                ));
            }
            let Some(&idx) = by_name.get(to) else {
                return Err(cx.err(map.span(), mkey, format!("unknown material `{to}`")));
            };
            overrides.insert(from.clone(), idx);
        }
    }
    let default_material = match &o.default_material {
        None => None,
        Some(d) => match by_name.get(d.get_ref()) {
            Some(&i) => Some(i),
            None => {
                return Err(cx.err(
                    d.span(),
                    format!("{key}.default_material"),
                    format!("unknown material `{}`", d.get_ref()),
                ))
            }
        },
    };

    // Lines of the `f` and `l` statements, in order: face k of the file is on face_lines[k].
    let face_lines: Vec<usize> = text
        .lines()
        .enumerate()
        .filter(|(_, l)| matches!(l.split_whitespace().next(), Some("f") | Some("l")))
        .map(|(i, _)| i + 1)
        .collect();
    // Every `usemtl` must name a material an MTL file defined: tobj would leave the faces
    // without a material (then the default material, or an error) without saying why.
    for (i, line) in text.lines().enumerate() {
        let t = line.trim();
        if t.split_whitespace().next() != Some("usemtl") {
            continue;
        }
        let name = t["usemtl".len()..].trim();
        if !mtl_names.contains(name) {
            let why = match &mtl_error {
                Some(e) => format!("its MTL file could not be loaded: {e}"),
                None => "no MTL file of this OBJ defines it".to_string(),
            };
            return Err(Error::input(
                Location::file(&obj_path)
                    .at_line(i + 1)
                    .with_key(format!("usemtl `{name}`")),
                format!("unknown material: {why}"),
            ));
        }
    }
    let total_faces: usize = models.iter().map(|m| arities(&m.mesh).len()).sum();
    let lines_known = total_faces == face_lines.len();

    let stem = obj_path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "obj".to_string());
    let mut imported: BTreeMap<usize, u32> = BTreeMap::new();
    let mut object_ids: BTreeMap<String, u32> = BTreeMap::new();
    let mut face_no = 0usize;

    for model in &models {
        let mesh = &model.mesh;
        let face_loc = |face_no: usize, local: usize| {
            let mut loc = Location::file(&obj_path);
            if let Some(&line) = face_lines.get(face_no).filter(|_| lines_known) {
                loc = loc.at_line(line);
            }
            loc.with_key(format!(
                "face {} (group `{}`, face {})",
                face_no + 1,
                model.name,
                local + 1
            ))
        };
        // The material of every face of this model.
        let material = match mesh.material_id {
            Some(id) => {
                let Some(m) = mtl_materials.get(id) else {
                    return Err(Error::input(
                        face_loc(face_no, 0),
                        format!("material index {id} is out of range"),
                    ));
                };
                if let Some(&idx) = overrides.get(&m.name) {
                    idx
                } else if let Some(&idx) = imported.get(&id) {
                    idx
                } else {
                    // Problems of a material's values are the MTL file's, at their line.
                    let src = mtl_defined.get(&m.name);
                    let mloc = |line: Option<usize>, what: &str| match src {
                        Some(src) => Location::file(&src.path)
                            .at_line(line.unwrap_or(src.newmtl))
                            .with_key(format!("material `{}` {what}", m.name)),
                        None => Location::file(&obj_path)
                            .with_key(format!("material `{}` {what}", m.name)),
                    };
                    let Some(kd) = m.diffuse else {
                        return Err(Error::input(
                            mloc(None, "Kd"),
                            "is missing (diffuse reflectance)",
                        ));
                    };
                    let reflectance = DVec3::new(
                        decimal(kd[0] as f64),
                        decimal(kd[1] as f64),
                        decimal(kd[2] as f64),
                    );
                    check_reflectance(reflectance)
                        .map_err(|msg| Error::input(mloc(src.and_then(|s| s.kd), "Kd"), msg))?;
                    // tobj 4 parses `Ke` into `emissive` (`check_mtl` made sure it has three
                    // values); absent means 0.
                    let emission = m.emissive.map_or(DVec3::ZERO, |ke| {
                        DVec3::new(
                            decimal(ke[0] as f64),
                            decimal(ke[1] as f64),
                            decimal(ke[2] as f64),
                        )
                    });
                    check_emission(emission)
                        .map_err(|msg| Error::input(mloc(src.and_then(|s| s.ke), "Ke"), msg))?;
                    let mut name = m.name.clone();
                    if by_name.contains_key(&name) {
                        // `<stem>/<name>`, then `#2`, `#3`, ...: the search resumes where the
                        // last one for this base stopped (scanning from 1 again made 8000
                        // includes of one OBJ take 10 s).
                        let base = format!("{stem}/{}", m.name);
                        let k = cx.next_suffix.entry(base.clone()).or_insert(1);
                        loop {
                            name = if *k == 1 {
                                base.clone()
                            } else {
                                format!("{base}#{k}")
                            };
                            *k += 1;
                            if !by_name.contains_key(&name) {
                                break;
                            }
                        }
                    }
                    let idx = materials.len() as u32;
                    by_name.insert(name.clone(), idx);
                    materials.push(Material {
                        name,
                        reflectance,
                        emission,
                    });
                    imported.insert(id, idx);
                    idx
                }
            }
            None => match default_material {
                Some(i) => i,
                None => {
                    let why = match &mtl_error {
                        Some(e) => format!(" (its MTL file could not be loaded: {e})"),
                        None => String::new(),
                    };
                    return Err(Error::input(
                        face_loc(face_no, 0),
                        format!(
                            "faces have no material{why}; add `usemtl` or set \
                             `default_material` in the scene's [[obj]] entry"
                        ),
                    ));
                }
            },
        };
        // One object per tobj model (a group, split again where `usemtl` changes inside it),
        // named `<stem>/<group>`, or `<stem>/<group>/<material>` if that name is taken.
        let mut object_name = format!("{stem}/{}", model.name);
        if object_ids.contains_key(&object_name) {
            object_name = format!("{object_name}/{}", materials[material as usize].name);
        }
        let object = match object_ids.get(&object_name) {
            Some(&i) => i,
            None => {
                let i = objects.len() as u32;
                objects.push(object_name.clone());
                object_ids.insert(object_name, i);
                i
            }
        };

        let mut start = 0usize;
        for (local, &arity) in arities(mesh).iter().enumerate() {
            let arity = arity as usize;
            let loc = face_loc(face_no, local);
            face_no += 1;
            let Some(idx) = mesh.indices.get(start..start + arity) else {
                return Err(Error::input(loc, "face indices out of range"));
            };
            start += arity;
            if arity < 3 {
                cx.warnings.push(format!(
                    "{loc}: a point or line element ({arity} vertices) is not a surface: skipped"
                ));
                continue;
            }
            let mut corners = Vec::with_capacity(arity);
            for &i in idx {
                let i = i as usize;
                let Some(p) = mesh.positions.get(3 * i..3 * i + 3) else {
                    return Err(Error::input(
                        loc,
                        format!("vertex index {} is out of range", i + 1),
                    ));
                };
                let p = DVec3::new(
                    decimal(p[0] as f64),
                    decimal(p[1] as f64),
                    decimal(p[2] as f64),
                );
                let q = transform(p);
                if !q.is_finite() {
                    return Err(Error::input(
                        loc,
                        format!("vertex {p} is not finite after the transform"),
                    ));
                }
                corners.push(q);
            }
            if mirrored {
                corners.reverse();
            }
            let built = build_face(&corners, material, object)
                .map_err(|msg| Error::input(loc.clone(), msg))?;
            if let Some(w) = built.warning {
                cx.warnings.push(format!("{loc}: {w}"));
            }
            polygons.extend(built.polygons);
        }
    }
    Ok(())
}

/// The `f64` nearest to the shortest decimal that round-trips `x` (see the module docs); `x`
/// itself if that fails (it cannot for a finite `f32`).
fn decimal(x: f64) -> f64 {
    let f = x as f32;
    if !f.is_finite() {
        return x;
    }
    format!("{f}").parse::<f64>().unwrap_or(x)
}

/// Checks what tobj 4.0.5 would panic on rather than refuse: a colour statement (`Ka`, `Kd`,
/// `Ks`, `Ke`) with fewer than three values (found by the property test
/// `mutated_obj_never_panics`). The values themselves are parsed and checked later.
fn check_mtl(text: &str, path: &Path) -> Result<()> {
    for (i, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        if let Some(k @ ("Ka" | "Kd" | "Ks" | "Ke")) = words.next() {
            let n = words.take_while(|w| !w.starts_with('#')).count();
            if n != 3 {
                return Err(Error::input(
                    Location::file(path).at_line(i + 1).with_key(k),
                    format!("has {n} values, needs exactly three (r g b)"),
                ));
            }
        }
    }
    Ok(())
}

/// Where an MTL file defines a material: the file, the line of its `newmtl` and of its `Kd`
/// and `Ke` statements (the last of each, as tobj keeps the last).
#[derive(Debug, Clone)]
struct MtlSource {
    path: std::path::PathBuf,
    newmtl: usize,
    kd: Option<usize>,
    ke: Option<usize>,
}

/// The materials `text` (the MTL file at `path`) defines, with their lines; the first
/// definition of a name is kept in `out`.
fn mtl_sources(text: &str, path: &Path, out: &mut BTreeMap<String, MtlSource>) {
    let mut current: Option<(String, MtlSource)> = None;
    let flush = |c: Option<(String, MtlSource)>, out: &mut BTreeMap<String, MtlSource>| {
        if let Some((name, src)) = c {
            out.entry(name).or_insert(src);
        }
    };
    for (i, line) in text.lines().enumerate() {
        let t = line.trim();
        let mut words = t.split_whitespace();
        match words.next() {
            Some("newmtl") => {
                flush(current.take(), out);
                let name = t["newmtl".len()..].trim().to_string();
                current = Some((
                    name,
                    MtlSource {
                        path: path.to_path_buf(),
                        newmtl: i + 1,
                        kd: None,
                        ke: None,
                    },
                ));
            }
            Some("Kd") => {
                if let Some((_, src)) = &mut current {
                    src.kd = Some(i + 1);
                }
            }
            Some("Ke") => {
                if let Some((_, src)) = &mut current {
                    src.ke = Some(i + 1);
                }
            }
            _ => {}
        }
    }
    flush(current.take(), out);
}

/// The vertex count of every face of `mesh`. tobj leaves `face_arities` empty when every face
/// of a mesh is a triangle, even with `triangulate: false`.
fn arities(mesh: &tobj::Mesh) -> Vec<u32> {
    if mesh.face_arities.is_empty() {
        vec![3; mesh.indices.len() / 3]
    } else {
        mesh.face_arities.clone()
    }
}
