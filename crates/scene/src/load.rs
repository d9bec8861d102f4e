//! Loading a scene file: TOML text in, a validated [`Scene`] out, or an [`Error::Input`] that
//! names the file, the line and the key of the first problem.
//!
//! Loading is two steps. [`super::format`] lets `toml` and serde turn the text into structs that
//! mirror the file (unknown keys and type errors are caught there, with a span); this module then
//! checks every value semantically, fills in the defaults of the `Default` impls in [`super`],
//! resolves material names to indices, loads the `[[obj]]` includes through `scene::obj` and the
//! `[[gltf]]` includes through `scene::gltf`, and turns every face into [`Polygon`]s with
//! `build_face`; the materials, objects and polygons
//! are collected in file order in `Surfaces`. The rules [`Scene`] promises to later stages
//! (finite numbers, reflectance in [0, 1), planar convex faces, at least one polygon and one
//! light) are all established here, and nothing is silently changed except two documented
//! repairs: quads within [`PLANARITY_TOLERANCE`] are projected onto their best-fit plane, and
//! quads beyond it are split into two triangles with a warning in [`Scene::warnings`] (OBJ
//! faces of more than four corners are projected and fan-triangulated, see `build_face`).
//!
//! Every input is untrusted: no value reaches arithmetic that could panic (indices, casts,
//! divisions) before it has been checked, and the property tests in
//! `crates/scene/tests/loading.rs` feed random and mutated files to
//! [`parse_scene`].

use super::format::{
    CameraPathSection, CameraSection, DisplaySection, ImageSection, MaterialSection,
    PolygonSection, RadiositySection, RenderSection, SceneFile, SpotSection, Vec3,
};
use super::{
    newell_normal, Camera, CameraPath, DisplaySettings, Keyframe, Material, Polygon, Projection,
    RadiositySettings, RenderSettings, Scene, SpotLight, MAX_IMAGE_DIM, PLANARITY_TOLERANCE,
};
use base::error::{Error, Location, Result};
use base::method::{Method, Placement, AA_SAMPLE_COUNTS, MAX_TEXTURE_SIZE};
use glam::DVec3;
use std::collections::BTreeMap;
use std::ops::Range;
use std::path::Path;
use toml::Spanned;

/// Image width and height when `[image]` does not give them.
pub(crate) const DEFAULT_IMAGE_DIM: u32 = 512;

/// Most shadow rays per receiver point and source accepted in `[radiosity] shadow_rays`.
pub const MAX_SHADOW_RAYS: u32 = 4096;

/// Largest magnitude of any number in a scene file (coordinates, intensities, ...): far beyond
/// any sensible scene, and small enough that squares and cross products of differences of
/// coordinates stay finite, so no later computation can overflow into inf or NaN.
pub(crate) const MAX_MAGNITUDE: f64 = 1.0e9;

/// Smallest perspective field of view accepted, degrees: narrower than any lens (a 0.01 degree
/// view of a 1 m object needs a camera 5.7 km away); a vanishing one would make every
/// projected coordinate overflow the rasterizer's guard band and draw nothing.
pub(crate) const MIN_FOV_Y: f64 = 0.01;

/// Most frames accepted in `[camera_path] frames`.
pub(crate) const MAX_FRAMES: u32 = 1_000_000;

/// Most corners of one face (an OBJ `f` statement; inline polygons have 3 or 4). Checking a
/// face compares every pair of its corners, so the limit bounds that work (for 30 000 corners
/// it would take seconds) and the fan triangles one face becomes.
pub const MAX_FACE_CORNERS: usize = 256;

/// Most MTL files one OBJ include may name (`mtllib`); each is read once, however often it is
/// named, so this bounds the MTL text read for one OBJ.
pub const MAX_MTL_FILES: usize = 64;

/// How a scene is loaded beyond its own text: the command line's part.
#[derive(Debug, Clone, Default)]
pub struct LoadOptions {
    /// `-D key=value`: TOML values set over the file's, in order (see `scene::overrides`).
    pub overrides: Vec<(String, String)>,
    /// `--strict`: refuse what is otherwise repaired with a warning (an OBJ's `Kd` of 1 or
    /// more).
    pub strict: bool,
}

/// Reads and validates the scene file at `path`.
///
/// A file that cannot be read is an [`Error::Input`] (exit code 2): it is the user's input.
pub fn load_scene(path: &Path) -> Result<Scene> {
    load_scene_with(path, &LoadOptions::default())
}

/// [`load_scene`] with the command line's options: a scene file (TOML) or a bare model (`.obj`,
/// `.gltf`, `.glb`, see `scene::model`), `-D` overrides applied, then the orientation checks of
/// `scene::orientation` added to its warnings.
pub fn load_scene_with(path: &Path, opts: &LoadOptions) -> Result<Scene> {
    let mut scene = if super::model::is_model(path) {
        super::model::load_model(path, opts)?
    } else {
        let text = base::output::read_text(path).map_err(|e| {
            Error::input(Location::file(path), format!("cannot read scene file: {e}"))
        })?;
        check_is_toml(&text, path)?;
        let parsed = parse_scene_options(&text, path, Readers::files(), opts)?;
        let mut scene = parsed.scene;
        if let Some(c) = parsed.camera {
            scene
                .notes
                .push(format!("{}: not used: the scene's [camera] is", c.origin));
        }
        scene
    };
    let facing = super::orientation::warnings(&scene);
    scene.warnings.extend(facing);
    Ok(scene)
}

/// A file not named `.toml` whose text is not TOML at all is most likely another format (a
/// model from a tool, an image): refused with what the commands read instead, rather than with
/// the TOML parser's complaint alone.
fn check_is_toml(text: &str, path: &Path) -> Result<()> {
    let toml_named = path
        .extension()
        .and_then(|x| x.to_str())
        .is_some_and(|x| x.eq_ignore_ascii_case("toml"));
    if toml_named {
        return Ok(());
    }
    match toml::from_str::<toml::Table>(text) {
        Err(e) => {
            let line = e.span().map_or(1, |s| line_of(text, s.start));
            Err(Error::input(
                Location::file(path),
                format!(
                    "is not a scene file: scenes are TOML (.toml), models Wavefront OBJ (.obj, \
                     with their .mtl) or glTF 2.0 (.gltf, .glb), solutions .pfsol; export other \
                     formats as OBJ or glTF (the TOML parser says, at line {line}: {})",
                    e.message().trim_end()
                ),
            ))
        }
        _ => Ok(()),
    }
}

/// Validates the scene text `text`; `path` names it in messages and is the base of relative
/// `[[obj]] file` and `[[gltf]] file` paths.
pub fn parse_scene(text: &str, path: &Path) -> Result<Scene> {
    parse_text(text, path, Readers::files(), false).map(|p| p.scene)
}

/// How [`parse_scene_with`] reads an included OBJ or MTL file: its path (the scene's directory
/// joined with the include's name) in, its text out.
pub(crate) type ReadText<'r> = &'r dyn Fn(&Path) -> std::io::Result<String>;

/// How [`parse_scene_with_bytes`] reads an included file (a glTF file, a GLB, a glTF buffer):
/// its path in, its bytes out.
pub(crate) type ReadBytes<'r> = &'r dyn Fn(&Path) -> std::io::Result<Vec<u8>>;

/// How the loader reads the files a scene includes: OBJ and MTL files as text, glTF files and
/// their buffers as bytes.
#[derive(Clone, Copy)]
pub(crate) struct Readers<'r> {
    pub(crate) text: ReadText<'r>,
    pub(crate) bytes: ReadBytes<'r>,
}

impl Readers<'static> {
    /// The file system's, each read capped at [`base::output::input_limit`].
    pub(crate) fn files() -> Readers<'static> {
        Readers {
            text: &base::output::read_text,
            bytes: &read_bytes,
        }
    }
}

/// The file at `path`, read whole up to [`base::output::input_limit`] bytes.
pub(crate) fn read_bytes(path: &Path) -> std::io::Result<Vec<u8>> {
    base::output::read_limited(path, base::output::input_limit())
}

/// [`parse_scene`], reading the `[[obj]]` includes and their MTL files through `read` instead of
/// the file system: the entry point for parsing OBJ and MTL text held in memory (the fuzz
/// targets under `fuzz/` use it). The paths `read` is given are the ones messages name; an `Err`
/// from it is reported like an unreadable file. `[[gltf]]` files and their buffers are read
/// through it too, so they must be UTF-8 (a `.gltf` with `data:` buffers is; a GLB is not: see
/// [`parse_scene_with_bytes`]).
pub fn parse_scene_with(text: &str, path: &Path, read: ReadText<'_>) -> Result<Scene> {
    let bytes = |p: &Path| read(p).map(String::into_bytes);
    parse_text(
        text,
        path,
        Readers {
            text: read,
            bytes: &bytes,
        },
        false,
    )
    .map(|p| p.scene)
}

/// [`parse_scene_with`] for includes held in memory as bytes: `read` gives every included file's
/// bytes (OBJ and MTL files must be UTF-8 text; glTF files, GLBs and `.bin` buffers are read as
/// they are).
pub fn parse_scene_with_bytes(
    text: &str,
    path: &Path,
    read: &dyn Fn(&Path) -> std::io::Result<Vec<u8>>,
) -> Result<Scene> {
    let as_text = |p: &Path| {
        String::from_utf8(read(p)?)
            .map_err(|_| std::io::Error::new(std::io::ErrorKind::InvalidData, "not UTF-8 text"))
    };
    let readers = Readers {
        text: &as_text,
        bytes: read,
    };
    parse_text(text, path, readers, false).map(|p| p.scene)
}

/// A validated scene, and what its includes offer that a scene file does not take from them:
/// the first camera of its glTF includes (a bare model uses it, see `scene::model`).
pub(crate) struct Parsed {
    pub(crate) scene: Scene,
    pub(crate) camera: Option<super::gltf::ModelCamera>,
}

/// [`parse_scene_with`] with the `-D` overrides and `--strict` of `opts`. An error of the merged
/// scene that the file has without the overrides is reported at the file's own line; any other
/// names the overrides (`scene::overrides`).
pub(crate) fn parse_scene_options(
    text: &str,
    path: &Path,
    read: Readers<'_>,
    opts: &LoadOptions,
) -> Result<Parsed> {
    if opts.overrides.is_empty() {
        return parse_text(text, path, read, opts.strict);
    }
    let merged = super::overrides::apply(text, path, &opts.overrides)?;
    parse_text(&merged, path, read, opts.strict).or_else(|e| {
        parse_text(text, path, read, opts.strict)?;
        Err(super::overrides::blame(e, &opts.overrides))
    })
}

/// Parses and validates `text` (see [`parse_scene_with`]); `strict` refuses the repairs.
fn parse_text(text: &str, path: &Path, read: Readers<'_>, strict: bool) -> Result<Parsed> {
    let file: SceneFile = toml::from_str(text).map_err(|e| {
        let mut loc = Location::file(path);
        if let Some(span) = e.span() {
            loc = loc.at_line(line_of(text, span.start));
        }
        Error::input(loc, e.message().trim_end().to_string())
    })?;
    let mut cx = Cx {
        text,
        path,
        warnings: Vec::new(),
        notes: Vec::new(),
        inputs: vec![path.to_path_buf()],
        origins: Vec::new(),
        newlines: std::cell::OnceCell::new(),
        read: read.text,
        read_bytes: read.bytes,
        next_suffix: BTreeMap::new(),
        strict,
        included_spots: Vec::new(),
        included_camera: None,
    };
    let scene = cx.scene(file)?;
    Ok(Parsed {
        scene,
        camera: cx.included_camera.take(),
    })
}

/// 1-based line of byte offset `offset` in `text` (clamped to the text's end).
pub fn line_of(text: &str, offset: usize) -> usize {
    let end = offset.min(text.len());
    text.as_bytes()[..end]
        .iter()
        .filter(|&&b| b == b'\n')
        .count()
        + 1
}

/// Shared state while validating one file.
pub(crate) struct Cx<'a> {
    pub(crate) text: &'a str,
    pub(crate) path: &'a Path,
    pub(crate) warnings: Vec<String>,
    /// Repairs that change nothing the image shows (`Scene::notes`).
    pub(crate) notes: Vec<String>,
    /// Files read so far (the scene file first), for [`Scene::inputs`].
    pub(crate) inputs: Vec<std::path::PathBuf>,
    /// Where each polygon added so far was defined (aligned with the surfaces' polygons).
    pub(crate) origins: Vec<Location>,
    /// Byte offsets of the text's newlines, computed on first use by [`Cx::loc`].
    pub(crate) newlines: std::cell::OnceCell<Vec<usize>>,
    /// Reads the included OBJ and MTL files.
    pub(crate) read: ReadText<'a>,
    /// Reads the included glTF files and their buffers.
    pub(crate) read_bytes: ReadBytes<'a>,
    /// For each `<obj file stem>/<name>` an imported material was renamed to, the next `#k`
    /// suffix to try: every smaller one is taken, so renaming is not quadratic in the number
    /// of includes of one file.
    pub(crate) next_suffix: BTreeMap<String, usize>,
    /// Refuse what is otherwise repaired with a warning (`--strict`): an OBJ's `Kd` or a
    /// glTF's base colour of 1 or more.
    pub(crate) strict: bool,
    /// The lights of the glTF includes, as spot lights, each with where it was defined: they
    /// follow the `[[spots]]` entries in [`Scene::spots`].
    pub(crate) included_spots: Vec<(SpotLight, Location)>,
    /// The first camera of the glTF includes, for a bare model (`scene::model`).
    pub(crate) included_camera: Option<super::gltf::ModelCamera>,
}

/// The polygons one face became, and a warning if it was repaired.
pub(crate) struct BuiltFace {
    pub(crate) polygons: Vec<Polygon>,
    pub(crate) warning: Option<String>,
}

impl BuiltFace {
    /// A face that is one polygon as it stands.
    fn single(polygon: Polygon) -> BuiltFace {
        BuiltFace {
            polygons: vec![polygon],
            warning: None,
        }
    }
}

/// The materials, objects and polygons of a scene, as the `[[materials]]`, `[[polygons]]` and
/// `[[obj]]` sections add them in file order.
#[derive(Default)]
pub(crate) struct Surfaces {
    pub(crate) materials: Vec<Material>,
    /// The materials whose polygons emit and reflect on both faces (`two_sided`).
    pub(crate) two_sided: Vec<u32>,
    /// The index of every material in `materials`, by name.
    pub(crate) by_name: BTreeMap<String, u32>,
    pub(crate) objects: Vec<String>,
    pub(crate) polygons: Vec<Polygon>,
}

impl Surfaces {
    /// Appends `material` (its name not yet taken) and returns its index.
    pub(crate) fn add_material(&mut self, material: Material) -> u32 {
        let idx = self.materials.len() as u32;
        self.by_name.insert(material.name.clone(), idx);
        self.materials.push(material);
        idx
    }

    /// Appends an object named `name` and returns its index.
    pub(crate) fn add_object(&mut self, name: String) -> u32 {
        let idx = self.objects.len() as u32;
        self.objects.push(name);
        idx
    }
}

impl<'a> Cx<'a> {
    pub(crate) fn loc(&self, span: Range<usize>, key: impl Into<String>) -> Location {
        // The offsets of the text's newlines, found once: a location costs a binary search,
        // not a scan of the text (locations are made per polygon, so a scan for each would make
        // loading quadratic in the number of inline polygons).
        let newlines = self.newlines.get_or_init(|| {
            self.text
                .bytes()
                .enumerate()
                .filter(|&(_, b)| b == b'\n')
                .map(|(k, _)| k)
                .collect()
        });
        let end = span.start.min(self.text.len());
        Location::file(self.path)
            .at_line(newlines.partition_point(|&k| k < end) + 1)
            .with_key(key)
    }

    pub(crate) fn err(
        &self,
        span: Range<usize>,
        key: impl Into<String>,
        msg: impl Into<String>,
    ) -> Error {
        Error::input(self.loc(span, key), msg)
    }

    /// A finite 3-vector.
    pub(crate) fn vec3(&self, v: &Spanned<Vec3>, key: &str) -> Result<DVec3> {
        let a = v.get_ref().0;
        for (i, x) in a.iter().enumerate() {
            if !in_range(*x) {
                return Err(self.err(
                    v.span(),
                    key,
                    format!("component {i} is {x}; {FINITE_RULE}"),
                ));
            }
        }
        Ok(DVec3::from_array(a))
    }

    /// A finite number.
    pub(crate) fn num(&self, v: &Spanned<f64>, key: &str) -> Result<f64> {
        let x = *v.get_ref();
        if !in_range(x) {
            return Err(self.err(v.span(), key, format!("is {x}; {FINITE_RULE}")));
        }
        Ok(x)
    }

    /// An integer in `lo..=hi`.
    fn int(&self, v: &Spanned<i64>, key: &str, lo: i64, hi: i64, why: &str) -> Result<i64> {
        let x = *v.get_ref();
        if x < lo || x > hi {
            return Err(self.err(
                v.span(),
                key,
                format!("is {x}, must be in {lo}..={hi}{why}"),
            ));
        }
        Ok(x)
    }

    fn scene(&mut self, file: SceneFile) -> Result<Scene> {
        let camera = self.camera(&file.camera)?;
        let (width, height) = self.image(file.image.as_ref())?;
        let mut surfaces = Surfaces::default();
        for (i, m) in file.materials.iter().enumerate() {
            self.material(m, &format!("materials[{i}]"), &mut surfaces)?;
        }
        for (i, p) in file.polygons.iter().enumerate() {
            self.inline_polygon(p, &format!("polygons[{i}]"), &mut surfaces)?;
        }
        for (i, o) in file.obj.iter().enumerate() {
            super::obj::include(self, o, &format!("obj[{i}]"), &mut surfaces)?;
        }
        for (i, g) in file.gltf.iter().enumerate() {
            super::gltf::include(self, g, &format!("gltf[{i}]"), &mut surfaces)?;
        }
        let (mut spots, mut spot_origins) = (Vec::new(), Vec::new());
        for (i, s) in file.spots.iter().enumerate() {
            let key = format!("spots[{i}]");
            spots.push(self.spot(s, &key)?);
            spot_origins.push(self.loc(s.get_ref().position.span(), format!("{key}.position")));
        }
        for (spot, origin) in std::mem::take(&mut self.included_spots) {
            spots.push(spot);
            spot_origins.push(origin);
        }
        let radiosity = self.radiosity(file.radiosity.as_ref())?;
        let render = self.render(file.render.as_ref())?;
        let display = self.display(file.display.as_ref())?;
        let camera_path = match &file.camera_path {
            Some(cp) => Some(self.camera_path(cp)?),
            None => None,
        };
        let merged = self.repair(&mut surfaces, radiosity.merge_triangles);
        self.check_polygons_and_light(&surfaces, &spots)?;
        let Surfaces {
            materials,
            objects,
            polygons,
            ..
        } = surfaces;
        let mut scene = Scene {
            source: self.path.to_path_buf(),
            camera,
            width,
            height,
            materials,
            objects,
            polygons,
            spots,
            spot_origins,
            radiosity,
            render,
            display,
            camera_path,
            warnings: std::mem::take(&mut self.warnings),
            notes: std::mem::take(&mut self.notes),
            inputs: std::mem::take(&mut self.inputs),
            origins: std::mem::take(&mut self.origins),
            contacts: crate::contact::Cuts::default(),
            merged,
            junctions: crate::contact::Cuts::default(),
            adjacency_cache: Default::default(),
        };
        cut(&mut scene);
        Ok(scene)
    }

    /// The repairs of the loaded polygons that change nothing the image shows, each said in a
    /// note: coincident polygons counted once, coplanar triangle pairs merged into quads (when
    /// `merge_triangles`), two-sided materials' polygons given reversed twins. Returns what was
    /// merged.
    fn repair(
        &mut self,
        surfaces: &mut Surfaces,
        merge_triangles: bool,
    ) -> super::triangle_pairs::Merged {
        let (notes, warnings) = super::coincident::merge(&mut surfaces.polygons, &mut self.origins);
        self.notes.extend(notes);
        self.warnings.extend(warnings);
        let merged = if merge_triangles {
            super::triangle_pairs::merge(&mut surfaces.polygons, &mut self.origins)
        } else {
            super::triangle_pairs::Merged::default()
        };
        self.notes.extend(merged.note());
        let doubled = two_sided(
            &mut surfaces.polygons,
            &mut self.origins,
            &surfaces.two_sided,
        );
        if doubled > 0 {
            self.notes.push(format!(
                "{doubled} polygons of two-sided materials given a twin facing the other way, \
                 so that they emit and reflect on both faces"
            ));
        }
        merged
    }

    /// One `[[materials]]` entry: a unique, non-empty name and values in range.
    fn material(
        &self,
        m: &Spanned<MaterialSection>,
        key: &str,
        surfaces: &mut Surfaces,
    ) -> Result<()> {
        let m = m.get_ref();
        let name = m.name.get_ref().clone();
        if name.is_empty() {
            return Err(self.err(m.name.span(), format!("{key}.name"), "is empty"));
        }
        if surfaces.by_name.contains_key(&name) {
            return Err(self.err(
                m.name.span(),
                format!("{key}.name"),
                format!("duplicate material name `{name}`"),
            ));
        }
        let reflectance = self.vec3(&m.reflectance, &format!("{key}.reflectance"))?;
        check_reflectance(reflectance)
            .map_err(|msg| self.err(m.reflectance.span(), format!("{key}.reflectance"), msg))?;
        let emission = match &m.emission {
            Some(e) => {
                let v = self.vec3(e, &format!("{key}.emission"))?;
                check_emission(v)
                    .map_err(|msg| self.err(e.span(), format!("{key}.emission"), msg))?;
                v
            }
            None => DVec3::ZERO,
        };
        let index = surfaces.add_material(Material {
            name,
            reflectance,
            emission,
        });
        if m.two_sided.as_ref().is_some_and(|t| *t.get_ref()) {
            surfaces.two_sided.push(index);
        }
        Ok(())
    }

    /// One `[[polygons]]` entry: 3 or 4 finite corners and a known material, one object of its
    /// own (named by `name`, else by its key).
    fn inline_polygon(
        &mut self,
        p: &Spanned<PolygonSection>,
        key: &str,
        surfaces: &mut Surfaces,
    ) -> Result<()> {
        let p = p.get_ref();
        let vs = p.vertices.get_ref();
        if vs.len() != 3 && vs.len() != 4 {
            return Err(self.err(
                p.vertices.span(),
                format!("{key}.vertices"),
                format!("has {} points; a polygon has 3 or 4", vs.len()),
            ));
        }
        let mut corners = Vec::with_capacity(4);
        for (j, v) in vs.iter().enumerate() {
            if let Some(x) = v.0.iter().find(|x| !in_range(**x)) {
                return Err(self.err(
                    p.vertices.span(),
                    format!("{key}.vertices[{j}]"),
                    format!("has {x}; {FINITE_RULE}"),
                ));
            }
            corners.push(DVec3::from_array(v.0));
        }
        let mname = p.material.get_ref();
        let Some(&material) = surfaces.by_name.get(mname) else {
            return Err(self.err(
                p.material.span(),
                format!("{key}.material"),
                format!(
                    "unknown material `{mname}`{}",
                    known_names(&surfaces.by_name)
                ),
            ));
        };
        let object = surfaces.add_object(p.name.clone().unwrap_or_else(|| key.to_string()));
        // Geometry problems are reported at the vertex list.
        let location = self.loc(p.vertices.span(), format!("{key}.vertices"));
        self.add_face(&corners, material, object, location, &mut surfaces.polygons)
    }

    /// Turns one face into polygons with [`build_face`] and appends them to `polygons`; a
    /// problem is an input error at `location`, a repair a warning there.
    pub(crate) fn add_face(
        &mut self,
        corners: &[DVec3],
        material: u32,
        object: u32,
        location: Location,
        polygons: &mut Vec<Polygon>,
    ) -> Result<()> {
        let built = build_face(corners, material, object)
            .map_err(|msg| Error::input(location.clone(), msg))?;
        if let Some(w) = built.warning {
            self.notes.push(format!("{location}: {w}"));
        }
        for _ in &built.polygons {
            self.origins.push(location.clone());
        }
        polygons.extend(built.polygons);
        Ok(())
    }

    /// One `[[spots]]` entry.
    fn spot(&self, s: &Spanned<SpotSection>, key: &str) -> Result<SpotLight> {
        let s = s.get_ref();
        let position = self.vec3(&s.position, &format!("{key}.position"))?;
        let direction = self.vec3(&s.direction, &format!("{key}.direction"))?;
        let len = direction.length();
        if !(len > 0.0 && len.is_finite()) {
            return Err(self.err(
                s.direction.span(),
                format!("{key}.direction"),
                "must be a non-zero vector",
            ));
        }
        let intensity = self.vec3(&s.intensity, &format!("{key}.intensity"))?;
        if intensity.min_element() < 0.0 {
            return Err(self.err(
                s.intensity.span(),
                format!("{key}.intensity"),
                "must be >= 0 in every channel",
            ));
        }
        let half = self.num(&s.half_angle, &format!("{key}.half_angle"))?;
        if !(half > 0.0 && half <= 90.0) {
            return Err(self.err(
                s.half_angle.span(),
                format!("{key}.half_angle"),
                format!("is {half} degrees, must be in (0, 90]"),
            ));
        }
        let falloff = match &s.falloff {
            Some(f) => {
                let x = self.num(f, &format!("{key}.falloff"))?;
                if !(0.0..=1.0e4).contains(&x) {
                    return Err(self.err(
                        f.span(),
                        format!("{key}.falloff"),
                        format!("is {x}, must be in [0, 10000]"),
                    ));
                }
                x
            }
            None => 1.0,
        };
        Ok(SpotLight {
            position,
            direction: direction / len,
            intensity,
            half_angle: half.to_radians(),
            falloff,
        })
    }

    /// Refuses a scene without polygons, or without any light (its image would be black).
    fn check_polygons_and_light(&self, surfaces: &Surfaces, spots: &[SpotLight]) -> Result<()> {
        let whole = Location::file(self.path);
        if surfaces.polygons.is_empty() {
            return Err(Error::input(
                whole,
                "the scene has no polygons: add [[polygons]], [[obj]] or [[gltf]] entries",
            ));
        }
        let has_emitter = surfaces
            .polygons
            .iter()
            .any(|p| surfaces.materials[p.material as usize].is_emitter());
        let has_spot = spots.iter().any(|s| s.intensity.max_element() > 0.0);
        if !has_emitter && !has_spot {
            return Err(Error::input(
                whole,
                "the scene has no light (no polygon with an emitting material and no spot light \
                 with intensity > 0): the image would be black",
            ));
        }
        Ok(())
    }

    fn pose(
        &self,
        eye: DVec3,
        look_at: DVec3,
        up: DVec3,
        span: Range<usize>,
        key: &str,
    ) -> Result<()> {
        if !view_direction_is_distinct(eye, look_at) {
            return Err(self.err(span, format!("{key}.look_at"), "equals the eye position"));
        }
        let d = look_at - eye;
        let c = d.normalize().cross(up).length();
        if up.length() == 0.0 || c <= 1e-9 * up.length() {
            return Err(self.err(
                span,
                format!("{key}.up"),
                "is zero or parallel to the view direction (look_at - eye)",
            ));
        }
        Ok(())
    }

    fn camera(&self, c: &Spanned<CameraSection>) -> Result<Camera> {
        let span = c.span();
        let c = c.get_ref();
        let eye = self.vec3(&c.eye, "camera.eye")?;
        let look_at = self.vec3(&c.look_at, "camera.look_at")?;
        let (up, up_span) = match &c.up {
            Some(u) => (self.vec3(u, "camera.up")?, u.span()),
            None => (DVec3::Y, span.clone()),
        };
        if !view_direction_is_distinct(eye, look_at) {
            return Err(self.err(c.look_at.span(), "camera.look_at", "equals camera.eye"));
        }
        self.pose(eye, look_at, up, up_span, "camera")?;
        let projection =
            match (&c.fov_y, &c.ortho_width, &c.ortho_height) {
                (Some(f), None, None) => {
                    let fov = self.num(f, "camera.fov_y")?;
                    if !(MIN_FOV_Y..180.0).contains(&fov) {
                        return Err(self.err(
                            f.span(),
                            "camera.fov_y",
                            format!("is {fov} degrees, must be in [{MIN_FOV_Y}, 180)"),
                        ));
                    }
                    Projection::Perspective { fov_y_deg: fov }
                }
                (None, Some(w), Some(h)) => {
                    let width = self.num(w, "camera.ortho_width")?;
                    let height = self.num(h, "camera.ortho_height")?;
                    for (x, s, k) in [
                        (width, w.span(), "camera.ortho_width"),
                        (height, h.span(), "camera.ortho_height"),
                    ] {
                        if x <= 0.0 {
                            return Err(self.err(s, k, format!("is {x}, must be > 0")));
                        }
                    }
                    Projection::Orthographic { width, height }
                }
                _ => return Err(self.err(
                    span,
                    "camera",
                    "give either `fov_y` (perspective) or both `ortho_width` and `ortho_height` \
                     (orthographic), not both forms",
                )),
            };
        Ok(Camera {
            eye,
            look_at,
            up,
            projection,
        })
    }

    fn image(&self, im: Option<&ImageSection>) -> Result<(u32, u32)> {
        let max = i64::from(MAX_IMAGE_DIM);
        let mut dims = [DEFAULT_IMAGE_DIM; 2];
        if let Some(im) = im {
            for (slot, v, k) in [
                (0, &im.width, "image.width"),
                (1, &im.height, "image.height"),
            ] {
                if let Some(v) = v {
                    dims[slot] = self.int(v, k, 1, max, " pixels")? as u32;
                }
            }
        }
        Ok((dims[0], dims[1]))
    }

    fn radiosity(&self, r: Option<&Spanned<RadiositySection>>) -> Result<RadiositySettings> {
        let mut s = RadiositySettings::default();
        let Some(r) = r else { return Ok(s) };
        let span = r.span();
        let r = r.get_ref();
        if let Some(t) = &r.tolerance {
            let x = self.num(t, "radiosity.tolerance")?;
            if x < crate::MIN_TOLERANCE {
                return Err(self.err(
                    t.span(),
                    "radiosity.tolerance",
                    format!(
                        "is {x}, must be at least {:e}: the samples are 32-bit floats (7 \
                         digits), so a finer test cannot converge and would refine every \
                         polygon to max_depth",
                        crate::MIN_TOLERANCE
                    ),
                ));
            }
            s.tolerance = x;
        }
        let md = i64::from(base::quadtree::MAX_DEPTH);
        if let Some(v) = &r.min_depth {
            s.min_depth = self.int(v, "radiosity.min_depth", 0, md, "")? as u32;
        }
        if let Some(v) = &r.max_depth {
            s.max_depth =
                self.int(v, "radiosity.max_depth", 0, md, " (quadtree::MAX_DEPTH)")? as u32;
        }
        if s.min_depth > s.max_depth {
            let sp = r.min_depth.as_ref().map_or(span, |v| v.span());
            return Err(self.err(
                sp,
                "radiosity.min_depth",
                format!("is {}, larger than max_depth {}", s.min_depth, s.max_depth),
            ));
        }
        if let Some(c) = &r.convergence {
            let x = self.num(c, "radiosity.convergence")?;
            if !(crate::MIN_CONVERGENCE..1.0).contains(&x) {
                return Err(self.err(
                    c.span(),
                    "radiosity.convergence",
                    format!(
                        "is {x}, must be in [{:e}, 1): below that the light left unshot is \
                         under what the 32-bit samples hold, and shooting would not end",
                        crate::MIN_CONVERGENCE
                    ),
                ));
            }
            s.convergence = x;
        }
        if let Some(v) = &r.shadow_rays {
            s.shadow_rays = self.int(
                v,
                "radiosity.shadow_rays",
                1,
                i64::from(MAX_SHADOW_RAYS),
                "",
            )? as u32;
        }
        if let Some(v) = &r.seed {
            s.seed = self.int(v, "radiosity.seed", 0, i64::MAX, "")? as u64;
        }
        if let Some(v) = &r.visibility {
            s.visibility = self.visibility(v)?;
        }
        if let Some(v) = &r.cut_contacts {
            s.cut_contacts = *v.get_ref();
        }
        if let Some(v) = &r.merge_triangles {
            s.merge_triangles = *v.get_ref();
        }
        Ok(s)
    }

    /// `radiosity.visibility`: `auto`, `exact` or `sampled`.
    fn visibility(&self, v: &Spanned<String>) -> Result<crate::Visibility> {
        match v.get_ref().as_str() {
            "auto" => Ok(crate::Visibility::Auto),
            "exact" => Ok(crate::Visibility::Exact),
            "sampled" => Ok(crate::Visibility::Sampled),
            other => Err(self.err(
                v.span(),
                "radiosity.visibility",
                format!("is `{other}`, must be `auto`, `exact` or `sampled`"),
            )),
        }
    }

    fn render(&self, r: Option<&Spanned<RenderSection>>) -> Result<RenderSettings> {
        let mut s = RenderSettings::default();
        let Some(r) = r else { return Ok(s) };
        let r = r.get_ref();
        if let Some(m) = &r.method {
            s.method = Method::parse_option("render.method", m.get_ref()).map_err(|e| {
                let reason = match e {
                    Error::InvalidOption { value, reason, .. } => format!("`{value}` {reason}"),
                    e => e.to_string(),
                };
                self.err(m.span(), "render.method", reason)
            })?;
        }
        if let Some(v) = &r.aa {
            let x = *v.get_ref();
            if !AA_SAMPLE_COUNTS.iter().any(|&n| i64::from(n) == x) {
                return Err(self.err(
                    v.span(),
                    "render.aa",
                    format!("is {x}, must be 1, 4 or 16 samples per pixel"),
                ));
            }
            s.aa_samples = x as u32;
        }
        if let Some(v) = &r.texture_size {
            let max = i64::from(MAX_TEXTURE_SIZE);
            let x = self.int(v, "render.texture_size", 0, max, "")?;
            if x != 0 && (x as u64).count_ones() != 1 {
                return Err(self.err(
                    v.span(),
                    "render.texture_size",
                    format!("is {x}, must be 0 (automatic) or a power of two"),
                ));
            }
            s.texture_size = x as u32;
        }
        if let Some(p) = &r.texel_placement {
            s.texel_placement = Placement::parse_option("render.texel_placement", p.get_ref())
                .map_err(|e| {
                    let reason = match e {
                        Error::InvalidOption { value, reason, .. } => format!("`{value}` {reason}"),
                        e => e.to_string(),
                    };
                    self.err(p.span(), "render.texel_placement", reason)
                })?;
        }
        Ok(s)
    }

    fn display(&self, d: Option<&Spanned<DisplaySection>>) -> Result<DisplaySettings> {
        let mut s = DisplaySettings::default();
        let Some(d) = d else { return Ok(s) };
        let d: &DisplaySection = d.get_ref();
        if let Some(e) = &d.exposure {
            let x = self.num(e, "display.exposure")?;
            if !(-64.0..=64.0).contains(&x) {
                return Err(self.err(
                    e.span(),
                    "display.exposure",
                    format!("is {x} stops, must be in [-64, 64]"),
                ));
            }
            s.exposure = x;
        }
        if let Some(b) = &d.background {
            let v = self.vec3(b, "display.background")?;
            if v.min_element() < 0.0 {
                return Err(self.err(
                    b.span(),
                    "display.background",
                    "must be >= 0 in every channel",
                ));
            }
            s.background = v;
        }
        Ok(s)
    }

    fn camera_path(&self, cp: &Spanned<CameraPathSection>) -> Result<CameraPath> {
        let cp = cp.get_ref();
        let frames = self.int(
            &cp.frames,
            "camera_path.frames",
            2,
            i64::from(MAX_FRAMES),
            "",
        )?;
        let kspan = cp.keyframes.span();
        let ks = cp.keyframes.get_ref();
        if ks.len() < 2 {
            return Err(self.err(
                kspan,
                "camera_path.keyframes",
                format!("has {} keyframes, needs at least 2", ks.len()),
            ));
        }
        let mut keyframes = Vec::with_capacity(ks.len());
        for (i, k) in ks.iter().enumerate() {
            let key = format!("camera_path.keyframes[{i}]");
            let up = k.up.map_or([0.0, 1.0, 0.0], |u| u.0);
            for (name, v) in [("eye", &k.eye.0), ("look_at", &k.look_at.0), ("up", &up)] {
                if let Some(x) = v.iter().find(|x| !in_range(**x)) {
                    return Err(self.err(
                        kspan.clone(),
                        format!("{key}.{name}"),
                        format!("has {x}; {FINITE_RULE}"),
                    ));
                }
            }
            let (eye, look_at, up) = (
                DVec3::from_array(k.eye.0),
                DVec3::from_array(k.look_at.0),
                DVec3::from_array(up),
            );
            self.pose(eye, look_at, up, kspan.clone(), &key)?;
            keyframes.push(Keyframe { eye, look_at, up });
        }
        Ok(CameraPath {
            keyframes,
            frames: frames as u32,
        })
    }
}

/// What [`in_range`] demands, for messages.
pub(crate) const FINITE_RULE: &str = "every number must be finite and at most 1e9 in magnitude";

/// The loader's cuts of a built scene, each said in a note: along its contact lines (when
/// `radiosity.cut_contacts`), then through the T-junctions whose lattices do not line up.
fn cut(scene: &mut Scene) {
    if scene.radiosity.cut_contacts {
        scene.cut_contacts();
        if let Some(note) = scene.contacts.note() {
            scene.notes.push(note);
        }
    }
    scene.cut_t_junctions();
    if !scene.junctions.pieces.is_empty() {
        let (cut, pieces) = scene.junctions.counts();
        scene.notes.push(format!(
            "{} T-junctions whose sides' lattices do not line up (a side split other than \
             in halves, quarters, ...): {cut} polygons cut through them into {pieces} pieces, \
             so that neighbours share whole sides and their light is joined C1",
            scene.junctions.lines.len()
        ));
    }
}

/// Gives every polygon whose material is in `materials` a twin right after it, the same
/// corners wound the other way (so facing the other way), keeping `origins` aligned; the
/// number of twins. A polygon is one-sided (it emits and reflects on its front): its twin is
/// its back face, a separate surface in its plane, which no light crosses.
fn two_sided(polygons: &mut Vec<Polygon>, origins: &mut Vec<Location>, materials: &[u32]) -> usize {
    if materials.is_empty() {
        return 0;
    }
    let old = std::mem::take(polygons);
    let old_origins = std::mem::take(origins);
    let mut n = 0;
    for (i, p) in old.into_iter().enumerate() {
        let twin = materials.contains(&p.material).then(|| {
            let c = p.corners;
            match p.shape {
                crate::Shape::Triangle => {
                    Polygon::triangle([c[0], c[2], c[1]], p.material, p.object)
                }
                crate::Shape::Quad => Polygon::quad([c[0], c[3], c[2], c[1]], p.material, p.object),
            }
            .map(|q| q.with_shading(p.shading.clone()))
        });
        polygons.push(p);
        if let Some(o) = old_origins.get(i) {
            origins.push(o.clone());
        }
        if let Some(Some(t)) = twin {
            polygons.push(t);
            if let Some(o) = old_origins.get(i) {
                origins.push(o.clone());
            }
            n += 1;
        }
    }
    n
}

/// Whether `x` is finite and within [`MAX_MAGNITUDE`].
pub(crate) fn in_range(x: f64) -> bool {
    x.is_finite() && x.abs() <= MAX_MAGNITUDE
}

/// `Ok` if every channel is in [0, 1), else the message.
pub(crate) fn check_reflectance(v: DVec3) -> std::result::Result<(), String> {
    for (i, x) in v.to_array().iter().enumerate() {
        if !(*x >= 0.0 && *x < 1.0) {
            return Err(format!(
                "component {i} is {x}, must be in [0, 1) (at 1 or above the solve would not \
                 converge)"
            ));
        }
    }
    Ok(())
}

/// `Ok` if every channel is finite and >= 0, else the message.
pub(crate) fn check_emission(v: DVec3) -> std::result::Result<(), String> {
    for (i, x) in v.to_array().iter().enumerate() {
        if !(x.is_finite() && *x >= 0.0) {
            return Err(format!("component {i} is {x}, must be finite and >= 0"));
        }
    }
    Ok(())
}

fn known_names(by_name: &BTreeMap<String, u32>) -> String {
    if by_name.is_empty() {
        " (no materials are defined)".to_string()
    } else {
        let names: Vec<&str> = by_name.keys().map(|s| s.as_str()).collect();
        format!(" (known: {})", names.join(", "))
    }
}

/// Turns one face (3 or more finite corners, counter-clockwise seen from the front) into valid
/// polygons, or says what is wrong with it.
///
/// - 3 corners: a triangle; refused if (near) zero area.
/// - 4 corners, convex: its deviation from planarity is the largest distance of a corner from
///   the best-fit plane (Newell normal through the centroid) over the longest diagonal. Within
///   [`PLANARITY_TOLERANCE`] the corners are projected onto that plane; beyond it the quad is
///   split along the c0-c2 diagonal into two triangles, with a warning.
/// - 5 or more (OBJ faces only, at most [`MAX_FACE_CORNERS`]), convex and planar within the same
///   tolerance: projected and fan-triangulated from the first corner.
/// - Concave faces, faces with three collinear consecutive corners, and non-planar faces of 5
///   or more corners: triangulated by ear clipping with a note (`build_clipped`). Refused:
///   zero net area, or a face that crosses itself.
pub(crate) fn build_face(
    corners: &[DVec3],
    material: u32,
    object: u32,
) -> std::result::Result<BuiltFace, String> {
    check_corners(corners)?;
    if corners.len() == 3 {
        let t = Polygon::triangle([corners[0], corners[1], corners[2]], material, object)
            .ok_or("has zero area (its corners are collinear or coincide)")?;
        return Ok(BuiltFace::single(t));
    }
    let plane = BestFitPlane::of(corners)?;
    match plane.check_convex() {
        Ok(()) if corners.len() == 4 => build_quad(corners, &plane, material, object),
        Ok(()) if plane.is_planar() => build_fan(&plane, material, object),
        Ok(()) => build_clipped(
            corners,
            &plane,
            material,
            object,
            "is convex but not planar",
        ),
        Err(why) => build_clipped(corners, &plane, material, object, &why),
    }
}

/// A face the parametric map cannot take as one polygon (concave, or of 5 or more corners off
/// its plane): cut into triangles by ear clipping on its best-fit plane, with a note. A planar
/// face's triangles use its projected corners; a non-planar one's keep the original corners, so
/// the surface follows the model. Refused if the face, projected on its plane, crosses or
/// touches itself.
fn build_clipped(
    corners: &[DVec3],
    plane: &BestFitPlane,
    material: u32,
    object: u32,
    why: &str,
) -> std::result::Result<BuiltFace, String> {
    let n = corners.len();
    let flat = plane.flattened();
    let area2 = super::triangulate::area2(&flat);
    let refuse = || {
        format!(
            "{why}, and cannot be triangulated: it crosses itself or repeats a corner \
             (faces must be simple polygons)"
        )
    };
    if area2 <= 0.0 || !super::triangulate::is_simple(&flat) {
        return Err(refuse());
    }
    let tris = super::triangulate::ear_clip(&flat, 1e-9 * plane.size2).ok_or_else(refuse)?;
    let source = if plane.is_planar() {
        &plane.projected
    } else {
        corners
    };
    let mut polygons = Vec::with_capacity(tris.len());
    for [a, b, c] in tris {
        let t = Polygon::triangle([source[a], source[b], source[c]], material, object)
            .ok_or_else(refuse)?;
        polygons.push(t);
    }
    let count = polygons.len();
    Ok(BuiltFace {
        polygons,
        warning: Some(format!(
            "{n}-corner face {why}: triangulated by ear clipping into {count} triangles"
        )),
    })
}

/// `Ok` if a face has between 3 and [`MAX_FACE_CORNERS`] corners, all in range.
fn check_corners(corners: &[DVec3]) -> std::result::Result<(), String> {
    let n = corners.len();
    if n < 3 {
        return Err(format!("has {n} corners; a face needs at least 3"));
    }
    if n > MAX_FACE_CORNERS {
        return Err(format!(
            "has {n} corners; a face has at most {MAX_FACE_CORNERS} (split it into smaller faces)"
        ));
    }
    if let Some(c) = corners
        .iter()
        .find(|c| !c.to_array().iter().all(|x| in_range(*x)))
    {
        return Err(format!("corner {c}: {FINITE_RULE}"));
    }
    Ok(())
}

/// The best-fit plane of a face of 4 or more corners (Newell normal through the centroid) and
/// how far the face is from it.
struct BestFitPlane {
    /// Unit normal.
    normal: DVec3,
    /// Largest squared distance between two corners.
    size2: f64,
    /// Largest distance of a corner from the plane over the face's longest diagonal.
    relative: f64,
    /// The corners projected onto the plane.
    projected: Vec<DVec3>,
}

impl BestFitPlane {
    /// The plane of `corners` (4 or more, in range); refused if the face has zero net area.
    fn of(corners: &[DVec3]) -> std::result::Result<BestFitPlane, String> {
        let n = corners.len();
        let normal = newell_normal(corners);
        let len = normal.length();
        let size2 = corners
            .iter()
            .flat_map(|a| corners.iter().map(move |b| (*a - *b).length_squared()))
            .fold(0.0, f64::max);
        // Same degeneracy threshold as `Polygon::build`: twice the area against the squared size.
        if len <= 1e-12 * size2 {
            return Err(
                "has zero net area (its corners are collinear or coincide, or it crosses itself)"
                    .to_string(),
            );
        }
        let nh = normal / len;
        let centroid = corners.iter().copied().sum::<DVec3>() / n as f64;
        let deviation = corners
            .iter()
            .map(|c| (*c - centroid).dot(nh).abs())
            .fold(0.0, f64::max);
        // The quad's longest diagonal (the polygon's diameter for more corners) is the size that
        // the planarity tolerance is relative to.
        let diagonal = if n == 4 {
            (corners[2] - corners[0])
                .length()
                .max((corners[3] - corners[1]).length())
        } else {
            size2.sqrt()
        };
        let projected = corners
            .iter()
            .map(|c| *c - (*c - centroid).dot(nh) * nh)
            .collect();
        Ok(BestFitPlane {
            normal: nh,
            size2,
            relative: deviation / diagonal,
            projected,
        })
    }

    /// The projected corners in 2D coordinates of the plane, counter-clockwise seen from the
    /// front (the side the normal points to).
    fn flattened(&self) -> Vec<glam::DVec2> {
        let e1 = self.normal.any_orthonormal_vector();
        let e2 = self.normal.cross(e1);
        let o = self.projected[0];
        self.projected
            .iter()
            .map(|p| glam::DVec2::new((*p - o).dot(e1), (*p - o).dot(e2)))
            .collect()
    }

    /// Whether the face is within [`PLANARITY_TOLERANCE`] of the plane.
    fn is_planar(&self) -> bool {
        self.relative <= PLANARITY_TOLERANCE
    }

    /// Convexity on the projected polygon: every turn must be to the left of the normal. A zero
    /// turn means three collinear consecutive corners, which the parametric map cannot use.
    fn check_convex(&self) -> std::result::Result<(), String> {
        let p = &self.projected;
        let n = p.len();
        for i in 0..n {
            let (a, b, c) = (p[i], p[(i + 1) % n], p[(i + 2) % n]);
            let turn = (b - a).cross(c - b).dot(self.normal);
            if turn <= 1e-9 * self.size2 {
                return Err(format!(
                    "is concave or has three collinear corners (at corner {})",
                    (i + 1) % n
                ));
            }
        }
        Ok(())
    }
}

/// A convex quad: projected onto its plane if planar, else split along its c0-c2 diagonal into
/// two triangles of the original corners, with a warning.
fn build_quad(
    corners: &[DVec3],
    plane: &BestFitPlane,
    material: u32,
    object: u32,
) -> std::result::Result<BuiltFace, String> {
    if plane.is_planar() {
        let p = &plane.projected;
        let q = Polygon::quad([p[0], p[1], p[2], p[3]], material, object).ok_or("has zero area")?;
        return Ok(BuiltFace::single(q));
    }
    let t0 = Polygon::triangle([corners[0], corners[1], corners[2]], material, object);
    let t1 = Polygon::triangle([corners[0], corners[2], corners[3]], material, object);
    let (Some(t0), Some(t1)) = (t0, t1) else {
        return Err("is not planar and cannot be split into two valid triangles".to_string());
    };
    Ok(BuiltFace {
        polygons: vec![t0, t1],
        warning: Some(format!(
            "quad is not planar (a corner is {:.3}% of its longest diagonal off the best-fit \
             plane, tolerance {}%): split into two triangles along its c0-c2 diagonal",
            100.0 * plane.relative,
            100.0 * PLANARITY_TOLERANCE
        )),
    })
}

/// A convex planar face of 5 or more corners: projected and fan-triangulated from its first
/// corner.
fn build_fan(
    plane: &BestFitPlane,
    material: u32,
    object: u32,
) -> std::result::Result<BuiltFace, String> {
    let p = &plane.projected;
    let n = p.len();
    let mut polygons = Vec::with_capacity(n - 2);
    for i in 1..n - 1 {
        let t = Polygon::triangle([p[0], p[i], p[i + 1]], material, object)
            .ok_or("has a degenerate fan triangle")?;
        polygons.push(t);
    }
    Ok(BuiltFace {
        polygons,
        warning: None,
    })
}

/// Whether `look_at` is far enough from `eye` to give a view direction: apart by more than
/// 1e-12 of their size (rounding cannot tell closer points apart), and the difference
/// normalizable. The size has no floor, so a scene at any scale has a valid camera (a floor of
/// one scene unit would refuse every camera of a scene 1e-12 units across as "equals the eye").
fn view_direction_is_distinct(eye: DVec3, look_at: DVec3) -> bool {
    let d = look_at - eye;
    let size = eye.length().max(look_at.length());
    d.length() > 1e-12 * size && d.normalize_or_zero().is_normalized()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn lines_are_one_based_and_clamped() {
        let t = "a\nbc\n\nd";
        assert_eq!(line_of(t, 0), 1);
        assert_eq!(line_of(t, 2), 2);
        assert_eq!(line_of(t, 5), 3);
        assert_eq!(line_of(t, 6), 4);
        assert_eq!(line_of(t, 1000), 4);
    }

    #[test]
    fn cornell_left_wall_deviation_is_0_176_percent() {
        // The McGuire left wall. Worked by hand: the Newell normal is close to +x, the corners
        // are about +-0.005 off the best plane and the diagonals 2.843 long: 0.176%.
        let c = [
            DVec3::new(-1.01, 0.0, 0.99),
            DVec3::new(-0.99, 0.0, -1.04),
            DVec3::new(-1.02, 1.99, -1.04),
            DVec3::new(-1.02, 1.99, 0.99),
        ];
        let built = build_face(&c, 0, 0).unwrap();
        assert_eq!(built.polygons.len(), 2);
        let w = built.warning.unwrap();
        assert!(w.contains("0.176%"), "{w}");
        let area: f64 = built.polygons.iter().map(|p| p.area).sum();
        // Nearly the 2.03 x 1.99 rectangle (corners are off by at most 0.03 in x).
        assert!((area - 2.03 * 1.99).abs() < 0.01, "{area}");
    }

    #[test]
    fn convex_planar_pentagon_is_fanned() {
        let c = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(3.0, 1.0, 0.0),
            DVec3::new(1.0, 2.0, 0.0),
            DVec3::new(-1.0, 1.0, 0.0),
        ];
        let built = build_face(&c, 0, 0).unwrap();
        assert_eq!(built.polygons.len(), 3);
        // Shoelace: sum of x_i y_{i+1} - x_{i+1} y_i = 0 + 2 + 5 + 3 + 0 = 10, area 5.
        let area: f64 = built.polygons.iter().map(|p| p.area).sum();
        assert!((area - 5.0).abs() < 1e-12);
    }

    proptest! {
        /// Any rectangle, in any orientation and at any scale from 1e-3 to 1e3, is a valid
        /// quad with area w h (to rounding: a few ulps of the largest coordinate squared).
        #[test]
        fn rectangles_in_any_plane_are_accepted(
            w in 1e-3f64..1e3, h in 1e-3f64..1e3,
            ax in -3.2f64..3.2, ay in -3.2f64..3.2, az in -3.2f64..3.2,
            t in prop::array::uniform3(-1e3f64..1e3),
        ) {
            let r = glam::DMat3::from_euler(glam::EulerRot::XYZ, ax, ay, az);
            let o = DVec3::from_array(t);
            let c = [
                o,
                o + r * DVec3::new(w, 0.0, 0.0),
                o + r * DVec3::new(w, h, 0.0),
                o + r * DVec3::new(0.0, h, 0.0),
            ];
            let built = build_face(&c, 0, 0).unwrap();
            prop_assert!(built.warning.is_none());
            prop_assert_eq!(built.polygons.len(), 1);
            let q = &built.polygons[0];
            let scale = (o.length() + w + h).powi(2);
            prop_assert!((q.area - w * h).abs() <= 1e-12 * scale);
            prop_assert!((q.normal - r * DVec3::Z).length() < 1e-6);
        }
    }
}
