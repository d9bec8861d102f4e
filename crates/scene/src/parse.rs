//! A scene file's text parsed and validated: [`crate::format`] lets `toml` and serde turn the
//! text into structs that mirror the file (unknown keys and type errors are caught there, with a
//! span); this module checks every value semantically, fills in the defaults, resolves material
//! names, reads the `[[obj]]` and `[[gltf]]` includes and turns every face into polygons, then
//! makes the loader's cuts (contact lines, T-junctions).

use super::format::{
    CameraPathSection, CameraSection, DisplaySection, ImageSection, MaterialSection,
    PolygonSection, RadiositySection, RenderSection, SceneFile, SpotSection,
};
use super::{
    Camera, CameraPath, DisplaySettings, Keyframe, Material, Polygon, Projection,
    RadiositySettings, RenderSettings, Scene, SpotLight, MAX_IMAGE_DIM,
};
use crate::checks::LoadOptions;
use crate::checks::{
    check_emission, check_reflectance, in_range, known_names, line_of, with_files, Cx, ReadText,
    Readers, Surfaces, DEFAULT_IMAGE_DIM, FINITE_RULE, MAX_FRAMES, MAX_SHADOW_RAYS, MIN_FOV_Y,
};
use base::error::{Error, Location, Result};
use base::method::{Aa, Method, Placement, MAX_TEXTURE_SIZE};
use glam::DVec3;
use std::collections::BTreeMap;
use std::ops::Range;
use std::path::Path;
use toml::Spanned;

/// Validates the scene text `text`; `path` names it in messages and is the base of relative
/// `[[obj]] file` and `[[gltf]] file` paths.
pub fn parse_scene(text: &str, path: &Path) -> Result<Scene> {
    with_files(base::output::MAX_INPUT_BYTES, |r| {
        parse_text(text, path, r, false)
    })
    .map(|p| p.scene)
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
            limit: base::output::MAX_INPUT_BYTES,
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
        limit: base::output::MAX_INPUT_BYTES,
    };
    parse_text(text, path, readers, false).map(|p| p.scene)
}

/// A validated scene, and what its includes offer that a scene file does not take from them:
/// the first camera of its glTF includes (a bare model uses it, see `scene::model`).
pub(crate) struct Parsed {
    pub(crate) scene: Scene,
    pub(crate) camera: Option<crate::checks::ModelCamera>,
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
        input_limit: read.limit,
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

impl<'a> Cx<'a> {
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
        let merged = self.repair(&mut surfaces, &spots, radiosity.merge_triangles);
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
            seal_cache: Default::default(),
        };
        cut(&mut scene);
        Ok(scene)
    }

    /// The repairs of the loaded polygons, each said in a note: rooms of double-sided
    /// materials modelled inside out around `spots` or emitters turned to face them
    /// (`inside_out`), coincident polygons counted once, coplanar triangle pairs merged into
    /// quads (when `merge_triangles`), two-sided materials' polygons given reversed twins.
    /// Returns what was merged.
    fn repair(
        &mut self,
        surfaces: &mut Surfaces,
        spots: &[super::SpotLight],
        merge_triangles: bool,
    ) -> super::triangle_pairs::Merged {
        self.notes.extend(super::inside_out::turn(surfaces, spots));
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
            let checked = u32::try_from(x)
                .ok()
                .and_then(|n| Aa::new("render.aa", n).ok());
            s.aa_samples = checked.ok_or_else(|| {
                self.err(
                    v.span(),
                    "render.aa",
                    format!("is {x}, must be 1, 4 or 16 samples per pixel"),
                )
            })?;
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

/// The loader's cuts of a built scene, each said in a note: along its contact lines (when
/// `radiosity.cut_contacts`), then through the T-junctions whose lattices do not line up; then
/// the sealed polygons among the pieces marked.
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
    scene.mark_sealed();
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
        let twin = materials.contains(&p.material).then(|| p.reversed());
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

/// Whether `look_at` is far enough from `eye` to give a view direction: apart by more than
/// 1e-12 of their size (rounding cannot tell closer points apart), and the difference
/// normalizable. The size has no floor, so a scene at any scale has a valid camera (a floor of
/// one scene unit would refuse every camera of a scene 1e-12 units across as "equals the eye").
fn view_direction_is_distinct(eye: DVec3, look_at: DVec3) -> bool {
    let d = look_at - eye;
    let size = eye.length().max(look_at.length());
    d.length() > 1e-12 * size && d.normalize_or_zero().is_normalized()
}
