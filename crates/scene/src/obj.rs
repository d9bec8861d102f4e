//! `[[obj]]` includes: Wavefront OBJ/MTL geometry loaded with tobj and turned into scene
//! polygons.
//!
//! tobj parses; this module validates and converts. Faces are loaded untriangulated
//! (`triangulate: false`) so quads stay quads: the radiosity quadtrees, patches and textures all
//! live in each polygon's (u, v) domain, and a quad split into two triangles would double the
//! work and put a C1 seam across a flat face. Faces with more than four corners are
//! fan-triangulated if convex and planar and refused otherwise (see
//! [`crate::face::build_face`]). Each face of an OBJ is numbered in file order and reported with
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
//! Memory: a file is read only up to the input cap (half of what the memory limit leaves past
//! the program), but its parsed form is larger (tobj's materials with their tables of unknown
//! statements, the scene's polygons and what loading builds from them), so each OBJ and MTL
//! text is measured by its statements before tobj sees it ([`check_parse_memory`]) and refused
//! as over the memory limit when the estimate passes it.
//!
//! tobj stores positions as `f32`. Each coordinate is turned back into the `f64` nearest to the
//! decimal tobj parsed by printing the `f32` in its shortest round-trip form and parsing that as
//! `f64`: `0.99` in the file becomes exactly `0.99_f64`, not `0.9900000095`. Files written with at
//! most 7 significant digits therefore load as written.

use super::format::{ObjSection, ScaleSpec};
use super::Material;
use crate::checks::{
    check_emission, check_reflectance, in_range, Cx, ReadText, Surfaces, MAX_MTL_FILES,
};
use base::error::{Error, Location, Result};
use glam::{DMat3, DVec3};
use std::cell::RefCell;
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use toml::Spanned;

mod normals;
use normals::{face_shading, FaceShading};

/// The largest reflectance a `Kd` of 1 or more is clamped to: the brightest diffuse white
/// paints reflect about 0.9, and a closed room of reflectance r needs about ln(0.01) / ln(r)
/// bounces to bring its unshot light under 1 % (90 at 0.95, 460 at 0.99), so the clamp keeps
/// the solve's length bounded while leaving a white surface white.
pub const MAX_OBJ_REFLECTANCE: f64 = 0.95;

/// Loads one `[[obj]]` include, appending to the scene's materials, objects and polygons.
pub(crate) fn include(
    cx: &mut Cx<'_>,
    section: &Spanned<ObjSection>,
    key: &str,
    surfaces: &mut Surfaces,
) -> Result<()> {
    let o = section.get_ref();
    let (obj_path, text) = read_obj(cx, o, key)?;
    let transform = Transform::of(cx, o, key)?;
    let mut parsed = parse_obj(cx, &text, &obj_path, &[])?;
    let default_material = default_material(cx, o, key, &surfaces.by_name)?;
    let undefined = undefined_usemtl(&text, &parsed);
    if !undefined.is_empty() {
        check_usemtl(&undefined, &obj_path, o, parsed.mtl_error.as_deref())?;
        let names: Vec<String> = undefined.iter().map(|(n, _)| n.clone()).collect();
        let why = parsed.mtl_error.clone();
        parsed = parse_obj(cx, &text, &obj_path, &names)?;
        parsed.mtl_error = why;
    }
    // The MTL materials' names, looked up once per `usemtl` and per override: a scan of the
    // materials for each would make a file with many of both quadratic to load.
    let mtl_names: BTreeSet<&str> = parsed.materials.iter().map(|m| m.name.as_str()).collect();
    let overrides = overrides(cx, o, key, (&mtl_names, "the OBJ's MTL"), &surfaces.by_name)?;
    for (name, line) in &undefined {
        if overrides.contains_key(name) {
            continue;
        }
        let default = o.default_material.as_ref().map_or("", |d| d.get_ref());
        let why = match &parsed.mtl_error {
            Some(e) => format!("its MTL file could not be loaded ({e})"),
            None => "no MTL file of this OBJ defines it".to_string(),
        };
        cx.warnings.push(format!(
            "{}:{line}: usemtl `{name}`: {why}: drawn with the default material `{default}` \
             (map it in the scene's [[obj]] `materials` table)",
            obj_path.display()
        ));
    }
    let mut converter = Converter {
        stem: obj_path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "obj".to_string()),
        obj_path: &obj_path,
        face_lines: face_lines(&text, &parsed.models),
        face_shading: face_shading(&text, &parsed.models),
        transform,
        parsed: &parsed,
        undefined: undefined.into_iter().map(|(n, _)| n).collect(),
        overrides,
        default_material,
        imported: BTreeMap::new(),
        object_ids: BTreeMap::new(),
        face_no: 0,
    };
    for model in &parsed.models {
        converter.add_model(cx, model, surfaces)?;
    }
    Ok(())
}

/// The path of the include's OBJ file (relative to the scene file's directory) and its text,
/// which is recorded as an input of the scene.
fn read_obj(cx: &mut Cx<'_>, o: &ObjSection, key: &str) -> Result<(PathBuf, String)> {
    let obj_path = base::output::folder_of(cx.path).join(o.file.get_ref());
    let text = (cx.read)(&obj_path).map_err(|e| {
        cx.err(
            o.file.span(),
            format!("{key}.file"),
            format!("cannot read OBJ file {}: {e}", obj_path.display()),
        )
    })?;
    cx.inputs.push(obj_path.clone());
    Ok((obj_path, text))
}

/// Where an include puts the model's points (see the module docs); `[[gltf]]` includes use the
/// same transform, after the glTF's own node transforms.
pub(crate) struct Transform {
    scale: DVec3,
    rotation: DMat3,
    translate: DVec3,
}

impl Transform {
    /// The include's `scale`, `rotate` and `translate`, checked.
    pub(crate) fn of(cx: &Cx<'_>, o: &ObjSection, key: &str) -> Result<Transform> {
        let scale = match &o.scale {
            None => DVec3::ONE,
            Some(s) => scale(cx, s, key)?,
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
        Ok(Transform {
            scale,
            rotation,
            translate,
        })
    }

    /// Whether the transform mirrors (an odd number of negative scale factors).
    pub(crate) fn mirrors(&self) -> bool {
        self.scale.x * self.scale.y * self.scale.z < 0.0
    }

    /// Where the model's point `p` goes.
    pub(crate) fn apply(&self, p: DVec3) -> DVec3 {
        self.translate + self.rotation * (self.scale * p)
    }

    /// What the transform makes of the surface normal `n` (the inverse transpose of its
    /// linear part: rotation times the reciprocal scale), not normalised.
    pub(crate) fn normal(&self, n: DVec3) -> DVec3 {
        self.rotation * (n / self.scale)
    }

    /// What the transform makes of the direction `v` (no translation).
    pub(crate) fn linear(&self, v: DVec3) -> DVec3 {
        self.rotation * (self.scale * v)
    }
}

/// The scale factors of `scale`: each non-zero and in range.
fn scale(cx: &Cx<'_>, s: &Spanned<ScaleSpec>, key: &str) -> Result<DVec3> {
    let v = match s.get_ref() {
        ScaleSpec::Uniform(x) => DVec3::splat(*x),
        ScaleSpec::PerAxis(a) => DVec3::from_array(a.0),
    };
    if !v.to_array().iter().all(|x| in_range(*x)) || v.x == 0.0 || v.y == 0.0 || v.z == 0.0 {
        return Err(cx.err(
            s.span(),
            format!("{key}.scale"),
            format!("is {v}; every factor must be non-zero, finite and at most 1e9"),
        ));
    }
    Ok(v)
}

/// What tobj made of an OBJ file and its MTL files.
struct ParsedObj {
    models: Vec<tobj::Model>,
    /// The materials of the MTL files; empty if they could not be loaded.
    materials: Vec<tobj::Material>,
    /// Why the MTL files could not be loaded, if they could not.
    mtl_error: Option<String>,
    /// Where the MTL files define each material.
    sources: BTreeMap<String, MtlSource>,
}

/// Parses the OBJ `text` (the file at `obj_path`) and its MTL files with tobj, recording the
/// MTL files read as inputs of the scene.
///
/// A problem that [`MtlLoader`] found in an MTL file is reported as such; an MTL file that
/// cannot be read is not an error here: its materials are missing, and `mtl_error` says why
/// for the messages about faces that need them.
///
/// `placeholders` are `usemtl` names no MTL file defines: they are declared first, through a
/// `mtllib` line naming [`PLACEHOLDER_MTL`] put before the text, as materials without values,
/// so that tobj keeps their faces apart and the converter can map them (the include's
/// `materials` map or default material). The line numbers of the text are unaffected: faces
/// are located by counting `f` lines of the original text.
fn parse_obj(
    cx: &mut Cx<'_>,
    text: &str,
    obj_path: &Path,
    placeholders: &[String],
) -> Result<ParsedObj> {
    check_parse_memory(text, obj_path, Parse::Obj, cx.input_limit)?;
    // Untriangulated, so quads stay quads (see the module docs).
    let opts = tobj::LoadOptions {
        triangulate: false,
        single_index: false,
        ..Default::default()
    };
    let mut loader = MtlLoader::new(obj_path, cx.read, cx.input_limit);
    loader.placeholders = placeholders.to_vec();
    let prefixed;
    let text = if placeholders.is_empty() {
        text
    } else {
        prefixed = format!("mtllib {PLACEHOLDER_MTL}\n{text}");
        &prefixed
    };
    let parsed = tobj::load_obj_buf(&mut text.as_bytes(), &opts, |name| loader.load(name));
    if placeholders.is_empty() {
        cx.inputs.extend(loader.files_read.into_inner());
    }
    if let Some(e) = loader.problem.into_inner() {
        return Err(e);
    }
    let (models, mtl) = parsed.map_err(|e| {
        Error::input(
            Location::file(obj_path),
            format!("cannot parse OBJ file: {e}"),
        )
    })?;
    let mtl = match (mtl, loader.unreadable.into_inner()) {
        (Err(_), Some(why)) => Err(why),
        (m, _) => m.map_err(|e| e.to_string()),
    };
    let (materials, mtl_error) = match mtl {
        Ok(m) => (m, None),
        Err(e) => (Vec::new(), Some(e)),
    };
    Ok(ParsedObj {
        models,
        materials,
        mtl_error,
        sources: loader.sources.into_inner(),
    })
}

/// Reads the MTL files of one OBJ for tobj, so that each MTL is checked first (see
/// [`check_mtl`]) and an unreadable MTL is reported by name.
///
/// Each MTL file is read once: tobj calls the loader for every `mtllib` statement, and reading
/// the file again for each would make an OBJ that repeats one `mtllib` line quadratic to load
/// and duplicate every material at each repeat. A file named again adds no materials (tobj
/// already has them), and an OBJ names at most [`MAX_MTL_FILES`] files (the bound on reading
/// one file under several spellings of its path). tobj calls the loader through a shared
/// reference, hence the cells.
struct MtlLoader<'a> {
    obj_path: &'a Path,
    /// The OBJ file's directory, which MTL names are relative to.
    dir: PathBuf,
    read: ReadText<'a>,
    /// The largest file read, bytes.
    input_limit: u64,
    /// The MTL paths named so far, by their components.
    seen: RefCell<BTreeSet<PathBuf>>,
    /// The first problem found in an MTL file (or in the OBJ's list of them).
    problem: RefCell<Option<Error>>,
    /// Why an MTL file could not be read (the last one that could not).
    unreadable: RefCell<Option<String>>,
    /// The MTL files read, in order.
    files_read: RefCell<Vec<PathBuf>>,
    /// Where each material is defined (the first definition of a name).
    sources: RefCell<BTreeMap<String, MtlSource>>,
    /// The materials [`PLACEHOLDER_MTL`] declares.
    placeholders: Vec<String>,
}

/// The MTL name [`parse_obj`] declares `usemtl` names without a definition through (not a file:
/// no file name contains a NUL).
const PLACEHOLDER_MTL: &str = "\u{0}pixelflow-sim-undefined-materials";

impl<'a> MtlLoader<'a> {
    fn new(obj_path: &'a Path, read: ReadText<'a>, input_limit: u64) -> Self {
        MtlLoader {
            obj_path,
            dir: base::output::folder_of(obj_path),
            read,
            input_limit,
            seen: RefCell::new(BTreeSet::new()),
            problem: RefCell::new(None),
            unreadable: RefCell::new(None),
            files_read: RefCell::new(Vec::new()),
            sources: RefCell::new(BTreeMap::new()),
            placeholders: Vec::new(),
        }
    }

    /// tobj's material loader: the materials of the MTL file `name`.
    fn load(&self, name: &Path) -> tobj::MTLLoadResult {
        if name == Path::new(PLACEHOLDER_MTL) {
            let materials: Vec<tobj::Material> = self
                .placeholders
                .iter()
                .map(|n| tobj::Material {
                    name: n.clone(),
                    ..Default::default()
                })
                .collect();
            let map = self
                .placeholders
                .iter()
                .enumerate()
                .map(|(i, n)| (n.clone(), i))
                .collect();
            return Ok((materials, map));
        }
        let mtl_path = self.dir.join(name);
        {
            let mut seen = self.seen.borrow_mut();
            if !seen.insert(mtl_path.components().collect()) {
                return Ok((Vec::new(), Default::default()));
            }
            if seen.len() > MAX_MTL_FILES {
                self.problem.borrow_mut().get_or_insert(Error::input(
                    Location::file(self.obj_path).with_key("mtllib"),
                    format!("names more than {MAX_MTL_FILES} MTL files"),
                ));
                return Err(tobj::LoadError::MaterialParseError);
            }
        }
        let mtl_text = match (self.read)(&mtl_path) {
            Ok(t) => {
                self.files_read.borrow_mut().push(mtl_path.clone());
                t
            }
            Err(e) => {
                *self.unreadable.borrow_mut() =
                    Some(format!("cannot read MTL file {}: {e}", mtl_path.display()));
                return Err(tobj::LoadError::OpenFileFailed);
            }
        };
        let checked = check_mtl(&mtl_text, &mtl_path)
            .and_then(|()| check_parse_memory(&mtl_text, &mtl_path, Parse::Mtl, self.input_limit));
        if let Err(e) = checked {
            self.problem.borrow_mut().get_or_insert(e);
            return Err(tobj::LoadError::MaterialParseError);
        }
        mtl_sources(&mtl_text, &mtl_path, &mut self.sources.borrow_mut());
        tobj::load_mtl_buf(&mut mtl_text.as_bytes())
    }
}

/// The include's `materials` map: every key must be a material of the included file (`names`;
/// `holder` says where they are, "the OBJ's MTL", "the glTF"), every value a scene material.
/// Shared by the OBJ and glTF includes.
pub(crate) fn overrides(
    cx: &Cx<'_>,
    o: &ObjSection,
    key: &str,
    (names, holder): (&BTreeSet<&str>, &str),
    by_name: &BTreeMap<String, u32>,
) -> Result<BTreeMap<String, u32>> {
    let mut overrides = BTreeMap::new();
    let Some(map) = &o.materials else {
        return Ok(overrides);
    };
    for (from, to) in map.get_ref() {
        let mkey = format!("{key}.materials.{from}");
        if !names.contains(from.as_str()) {
            return Err(cx.err(
                map.span(),
                mkey,
                format!("{holder} has no material `{from}`"),
            ));
        }
        let Some(&idx) = by_name.get(to) else {
            return Err(cx.err(map.span(), mkey, format!("unknown material `{to}`")));
        };
        overrides.insert(from.clone(), idx);
    }
    Ok(overrides)
}

/// The include's `default_material`, which must be a scene material.
pub(crate) fn default_material(
    cx: &Cx<'_>,
    o: &ObjSection,
    key: &str,
    by_name: &BTreeMap<String, u32>,
) -> Result<Option<u32>> {
    let Some(d) = &o.default_material else {
        return Ok(None);
    };
    match by_name.get(d.get_ref()) {
        Some(&i) => Ok(Some(i)),
        None => Err(cx.err(
            d.span(),
            format!("{key}.default_material"),
            format!("unknown material `{}`", d.get_ref()),
        )),
    }
}

/// The line of every face of the OBJ `text`, in order (face k of the file is on line
/// `lines[k]`): the lines of its `f` and `l` statements, if they are as many as the faces of
/// `models`, else `None`.
fn face_lines(text: &str, models: &[tobj::Model]) -> Option<Vec<usize>> {
    let lines: Vec<usize> = text
        .lines()
        .enumerate()
        .filter(|(_, l)| matches!(l.split_whitespace().next(), Some("f") | Some("l")))
        .map(|(i, _)| i + 1)
        .collect();
    let faces: usize = models.iter().map(|m| arities(&m.mesh).len()).sum();
    (faces == lines.len()).then_some(lines)
}

/// The `usemtl` names of the OBJ `text` that no MTL file of `parsed` defines, each with the
/// line of its first use, in order of first use.
fn undefined_usemtl(text: &str, parsed: &ParsedObj) -> Vec<(String, usize)> {
    let defined: BTreeSet<&str> = parsed.materials.iter().map(|m| m.name.as_str()).collect();
    let mut seen = BTreeSet::new();
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let t = line.trim();
        if t.split_whitespace().next() != Some("usemtl") {
            continue;
        }
        let name = t["usemtl".len()..].trim();
        if !name.is_empty() && !defined.contains(name) && seen.insert(name.to_string()) {
            out.push((name.to_string(), i + 1));
        }
    }
    out
}

/// `Ok` if every undefined `usemtl` name is mapped by the include's `materials` table or can
/// take its `default_material`; else the error at the first one's line (tobj would leave the
/// faces without a material without saying why).
fn check_usemtl(
    undefined: &[(String, usize)],
    obj_path: &Path,
    o: &ObjSection,
    mtl_error: Option<&str>,
) -> Result<()> {
    let mapped = |n: &str| {
        o.materials
            .as_ref()
            .is_some_and(|m| m.get_ref().contains_key(n))
    };
    if o.default_material.is_some() {
        return Ok(());
    }
    if let Some((name, line)) = undefined.iter().find(|(n, _)| !mapped(n)) {
        let why = match mtl_error {
            Some(e) => format!("its MTL file could not be loaded: {e}"),
            None => "no MTL file of this OBJ defines it".to_string(),
        };
        return Err(Error::input(
            Location::file(obj_path)
                .at_line(*line)
                .with_key(format!("usemtl `{name}`")),
            format!(
                "unknown material: {why}; map it to a scene material in the [[obj]] entry's \
                 `materials` table, or set its `default_material`"
            ),
        ));
    }
    Ok(())
}

/// Turns the models of one parsed OBJ into scene materials, objects and polygons.
struct Converter<'o> {
    obj_path: &'o Path,
    /// The OBJ file's stem, which names its objects and renamed materials.
    stem: String,
    /// The line of every face, if the `f`/`l` lines match tobj's faces one to one.
    face_lines: Option<Vec<usize>>,
    /// How every face is shaded, if the `f`/`l` lines match tobj's faces one to one.
    face_shading: Option<Vec<FaceShading>>,
    transform: Transform,
    parsed: &'o ParsedObj,
    /// `usemtl` names no MTL defines: their faces take the default material unless mapped.
    undefined: BTreeSet<String>,
    /// MTL material name -> scene material, from the include's `materials` map.
    overrides: BTreeMap<String, u32>,
    default_material: Option<u32>,
    /// MTL material index -> the scene material made of it.
    imported: BTreeMap<usize, u32>,
    /// Object name -> index, for the objects of this include.
    object_ids: BTreeMap<String, u32>,
    /// Faces of the file converted so far.
    face_no: usize,
}

impl Converter<'_> {
    /// Where the next face of the file is, for messages: face `local` of `model`.
    fn face_loc(&self, model: &tobj::Model, local: usize) -> Location {
        let mut loc = Location::file(self.obj_path);
        if let Some(&line) = self.face_lines.as_ref().and_then(|l| l.get(self.face_no)) {
            loc = loc.at_line(line);
        }
        loc.with_key(format!(
            "face {} (group `{}`, face {})",
            self.face_no + 1,
            model.name,
            local + 1
        ))
    }

    /// Adds the faces of one tobj model: one group, split again where `usemtl` changes inside
    /// it, so one material for all of them.
    fn add_model(
        &mut self,
        cx: &mut Cx<'_>,
        model: &tobj::Model,
        surfaces: &mut Surfaces,
    ) -> Result<()> {
        let material = self.model_material(cx, model, surfaces)?;
        let object = self.object(model, material, surfaces);
        self.add_faces(cx, model, material, object, surfaces)
    }

    /// The scene material of the faces of `model`: its `usemtl` material (overridden, or
    /// imported once), else the include's default material.
    fn model_material(
        &mut self,
        cx: &mut Cx<'_>,
        model: &tobj::Model,
        surfaces: &mut Surfaces,
    ) -> Result<u32> {
        let Some(id) = model.mesh.material_id else {
            return self.default_material.ok_or_else(|| {
                let why = match &self.parsed.mtl_error {
                    Some(e) => format!(" (its MTL file could not be loaded: {e})"),
                    None => String::new(),
                };
                Error::input(
                    self.face_loc(model, 0),
                    format!(
                        "faces have no material{why}; add `usemtl` or set \
                         `default_material` in the scene's [[obj]] entry"
                    ),
                )
            });
        };
        let Some(m) = self.parsed.materials.get(id) else {
            return Err(Error::input(
                self.face_loc(model, 0),
                format!("material index {id} is out of range"),
            ));
        };
        if let Some(&idx) = self.overrides.get(&m.name) {
            return Ok(idx);
        }
        if let Some(&idx) = self.imported.get(&id) {
            return Ok(idx);
        }
        if self.undefined.contains(&m.name) {
            // `check_usemtl` made sure an undefined name is mapped or has the default.
            return self.default_material.ok_or_else(|| {
                Error::input(
                    self.face_loc(model, 0),
                    format!("material `{}` is undefined", m.name),
                )
            });
        }
        let (reflectance, emission) = self.material_values(m, cx.strict, &mut cx.warnings)?;
        let name = unique_name(cx, &self.stem, &m.name, &surfaces.by_name);
        let idx = surfaces.add_material(Material {
            name,
            reflectance,
            emission,
        });
        self.imported.insert(id, idx);
        Ok(idx)
    }

    /// The reflectance (`Kd`) and emission (`Ke`) of the MTL material `m`, checked; a problem
    /// is the MTL file's, at the line of the statement. A `Kd` of 1 or more in some channel
    /// (modelling tools write `Kd 1 1 1` for "white") is clamped to [`MAX_OBJ_REFLECTANCE`] with
    /// a warning, unless `strict`; values above [`crate::checks::MAX_MAGNITUDE`] or negative are
    /// refused as before.
    fn material_values(
        &self,
        m: &tobj::Material,
        strict: bool,
        warnings: &mut Vec<String>,
    ) -> Result<(DVec3, DVec3)> {
        let src = self.parsed.sources.get(&m.name);
        let mloc = |line: Option<usize>, what: &str| match src {
            Some(src) => Location::file(&src.path)
                .at_line(line.unwrap_or(src.newmtl))
                .with_key(format!("material `{}` {what}", m.name)),
            None => Location::file(self.obj_path).with_key(format!("material `{}` {what}", m.name)),
        };
        let Some(kd) = m.diffuse else {
            return Err(Error::input(
                mloc(None, "Kd"),
                "is missing (diffuse reflectance)",
            ));
        };
        let kd_loc = mloc(src.and_then(|s| s.kd), "Kd");
        let reflectance = clamp_reflectance(decimal3(kd), &kd_loc, strict, warnings);
        check_reflectance(reflectance).map_err(|msg| Error::input(kd_loc, msg))?;
        // tobj 4 parses `Ke` into `emissive` (`check_mtl` made sure it has three values);
        // absent means 0.
        let emission = m.emissive.map_or(DVec3::ZERO, decimal3);
        check_emission(emission)
            .map_err(|msg| Error::input(mloc(src.and_then(|s| s.ke), "Ke"), msg))?;
        Ok((reflectance, emission))
    }

    /// The object of the faces of `model`, named `<stem>/<group>`, or
    /// `<stem>/<group>/<material>` if that name is taken; the first model of a name creates it.
    fn object(&mut self, model: &tobj::Model, material: u32, surfaces: &mut Surfaces) -> u32 {
        let mut object_name = format!("{}/{}", self.stem, model.name);
        if self.object_ids.contains_key(&object_name) {
            object_name = format!(
                "{object_name}/{}",
                surfaces.materials[material as usize].name
            );
        }
        if let Some(&i) = self.object_ids.get(&object_name) {
            return i;
        }
        let i = surfaces.add_object(object_name.clone());
        self.object_ids.insert(object_name, i);
        i
    }

    /// Adds the faces of `model`: points and lines are skipped with a warning, every other face
    /// becomes polygons through [`Cx::add_face`].
    fn add_faces(
        &mut self,
        cx: &mut Cx<'_>,
        model: &tobj::Model,
        material: u32,
        object: u32,
        surfaces: &mut Surfaces,
    ) -> Result<()> {
        let mesh = &model.mesh;
        let smoothed = self.smoothing_groups(model);
        let mut start = 0usize;
        for (local, &arity) in arities(mesh).iter().enumerate() {
            let arity = arity as usize;
            let shading = self.shading_of(self.face_no);
            let loc = self.face_loc(model, local);
            self.face_no += 1;
            let range = start..start + arity;
            let Some(idx) = mesh.indices.get(range.clone()) else {
                return Err(Error::input(loc, "face indices out of range"));
            };
            start += arity;
            if arity < 3 {
                cx.notes.push(format!(
                    "{loc}: a point or line element ({arity} vertices) is not a surface: skipped"
                ));
                continue;
            }
            let corners = self.corners(mesh, idx, &loc)?;
            let normals = self.face_normals(mesh, range, shading, &smoothed);
            let first = surfaces.polygons.len();
            cx.add_face(&corners, material, object, loc, &mut surfaces.polygons)?;
            if let Some(normals) = normals {
                crate::shading::shade_pieces(&mut surfaces.polygons[first..], &corners, &normals);
            }
        }
        Ok(())
    }

    /// The transformed corners of the face with vertex indices `idx`, in the scene's winding.
    fn corners(&self, mesh: &tobj::Mesh, idx: &[u32], loc: &Location) -> Result<Vec<DVec3>> {
        let mut corners = Vec::with_capacity(idx.len());
        for &i in idx {
            let i = i as usize;
            let Some(p) = mesh.positions.get(3 * i..3 * i + 3) else {
                return Err(Error::input(
                    loc.clone(),
                    format!("vertex index {} is out of range", i + 1),
                ));
            };
            let p = decimal3([p[0], p[1], p[2]]);
            let q = self.transform.apply(p);
            if !q.is_finite() {
                return Err(Error::input(
                    loc.clone(),
                    format!("vertex {p} is not finite after the transform"),
                ));
            }
            corners.push(q);
        }
        if self.transform.mirrors() {
            corners.reverse();
        }
        Ok(corners)
    }
}

/// A model's diffuse colour as a reflectance: a colour of 1 or more in some channel (modelling
/// tools write 1 for "white") is clamped to [`MAX_OBJ_REFLECTANCE`] with a warning at `loc`,
/// unless `strict`; anything else is returned as it is, for [`check_reflectance`] to judge.
pub(crate) fn clamp_reflectance(
    reflectance: DVec3,
    loc: &Location,
    strict: bool,
    warnings: &mut Vec<String>,
) -> DVec3 {
    if strict || !reflectance.is_finite() || reflectance.max_element() < 1.0 {
        return reflectance;
    }
    let clamped = reflectance.min(DVec3::splat(MAX_OBJ_REFLECTANCE));
    if check_reflectance(clamped).is_err() {
        return reflectance;
    }
    warnings.push(format!(
        "{loc}: {reflectance} is 1 or more (a surface reflecting all its light or more; a \
         closed room would never converge): clamped to {clamped} (strict loading refuses it)"
    ));
    clamped
}

/// A name for a material imported from a model (an MTL file, a glTF): its own name if free,
/// else `<stem>/<name>`, then `<stem>/<name>#2`, `#3`, ...
///
/// The search resumes where the last one for the same base stopped (`cx.next_suffix`), so
/// many includes of one model do not rescan the suffixes already taken.
pub(crate) fn unique_name(
    cx: &mut Cx<'_>,
    stem: &str,
    mtl_name: &str,
    by_name: &BTreeMap<String, u32>,
) -> String {
    if !by_name.contains_key(mtl_name) {
        return mtl_name.to_string();
    }
    let base = format!("{stem}/{mtl_name}");
    let k = cx.next_suffix.entry(base.clone()).or_insert(1);
    loop {
        let name = if *k == 1 {
            base.clone()
        } else {
            format!("{base}#{k}")
        };
        *k += 1;
        if !by_name.contains_key(&name) {
            return name;
        }
    }
}

/// [`decimal`] of every component of a tobj triple.
pub(crate) fn decimal3(v: [f32; 3]) -> DVec3 {
    DVec3::new(
        decimal(v[0] as f64),
        decimal(v[1] as f64),
        decimal(v[2] as f64),
    )
}

/// The `f64` nearest to the shortest decimal that round-trips `x` (see the module docs); `x`
/// itself if that fails (it cannot for a finite `f32`).
pub(crate) fn decimal(x: f64) -> f64 {
    let f = x as f32;
    if !f.is_finite() {
        return x;
    }
    format!("{f}").parse::<f64>().unwrap_or(x)
}

/// Which text [`check_parse_memory`] measures.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Parse {
    Obj,
    Mtl,
}

/// Bytes an MTL material holds once parsed, whatever its statements (tobj's `Material` with its
/// strings and table of unknown statements): measured, 400,000 two-line materials (11.9 MB)
/// peaked at 394 MB in `check`.
const MTL_MATERIAL_BYTES: u64 = 1024;

/// Bytes any other MTL statement may hold (an unknown one is a key and value in its material's
/// table): measured, 1.5 million one-word statements (15.4 MB) peaked at 224 MB.
const MTL_STATEMENT_BYTES: u64 = 160;

/// Bytes an OBJ face holds once loaded, before its corners: tobj's index lists, the scene's
/// polygon, its adjacency and seams as `check` builds them (measured: a grid of a million
/// quads, 41 MB of OBJ, peaked at 704 MB, 680 bytes a face); plus [`OBJ_CORNER_BYTES`] per
/// corner.
const OBJ_FACE_BYTES: u64 = 512;

/// Bytes per corner of an OBJ face (three tobj indices and the `f64` point).
const OBJ_CORNER_BYTES: u64 = 48;

/// Bytes per OBJ vertex, normal or texture coordinate (tobj's `f32`s, the converter's `f64`s):
/// 1.5 million `v` lines peaked at 41 MB.
const OBJ_VERTEX_BYTES: u64 = 32;

/// Refuses the OBJ or MTL `text` of the file at `path` when what parsing and loading it holds
/// (estimated from its statements, plus the text itself) passes the memory limit: twice the
/// input cap `input_limit` (at most 2 GiB for one file).
fn check_parse_memory(text: &str, path: &Path, kind: Parse, input_limit: u64) -> Result<()> {
    let limit = input_limit.saturating_mul(2);
    let (mut big, mut small, mut corners) = (0u64, 0u64, 0u64);
    for line in text.lines() {
        let mut words = line.split_whitespace();
        match (kind, words.next()) {
            (Parse::Mtl, Some("newmtl")) => big += 1,
            (Parse::Mtl, Some(w)) if !w.starts_with('#') => small += 1,
            (Parse::Obj, Some("f" | "l" | "p")) => {
                big += 1;
                corners += words.count() as u64;
            }
            (Parse::Obj, Some("v" | "vn" | "vt")) => small += 1,
            _ => {}
        }
    }
    let (parsed, detail) = match kind {
        Parse::Mtl => (
            big * MTL_MATERIAL_BYTES + small * MTL_STATEMENT_BYTES,
            format!("{big} materials, {small} other statements"),
        ),
        Parse::Obj => (
            big * OBJ_FACE_BYTES + corners * OBJ_CORNER_BYTES + small * OBJ_VERTEX_BYTES,
            format!("{big} faces with {corners} corners, {small} vertices"),
        ),
    };
    let estimate = parsed.saturating_add(text.len() as u64);
    if estimate > limit {
        return Err(Error::Memory {
            what: format!("loading {}", path.display()),
            estimate,
            limit,
            detail,
            hint: "raise `memory-limit`, or split the model into smaller files".into(),
        });
    }
    Ok(())
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
    path: PathBuf,
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
