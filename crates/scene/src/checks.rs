//! The scene loader's toolbox, shared by every reader of a scene's parts (the TOML sections, the
//! OBJ and glTF includes, bare models, `-D` overrides): the limits every value is held to, the
//! readers files come through, the validation state [`Cx`] with its located errors, the
//! collected [`Surfaces`], and the value checks (finite and in range, reflectance, emission).
//!
//! It names no reader: each reader uses it, and [`crate::load`] strings the readers together, so
//! a reader can be read and tested from this file and its own.

use super::format::Vec3;
use super::{Camera, Material, Polygon, SpotLight};
use base::error::{Error, Location, Result};
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

/// How [`crate::parse_scene_with`] reads an included OBJ or MTL file: its path (the scene's directory
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
    /// The largest file read, bytes (what parsing one may hold is bounded by twice this).
    pub(crate) limit: u64,
}

/// Runs `f` with the file system's readers, each read capped at `limit` bytes.
pub(crate) fn with_files<T>(limit: u64, f: impl FnOnce(Readers<'_>) -> T) -> T {
    let text = move |p: &Path| base::output::read_text(p, limit);
    let bytes = move |p: &Path| base::output::read_limited(p, limit);
    f(Readers {
        text: &text,
        bytes: &bytes,
        limit,
    })
}

/// 1-based line of byte offset `offset` in `text` (clamped to the text's end).
pub(crate) fn line_of(text: &str, offset: usize) -> usize {
    let end = offset.min(text.len());
    text.as_bytes()[..end]
        .iter()
        .filter(|&&b| b == b'\n')
        .count()
        + 1
}

/// How a scene is loaded beyond its own text: the command line's part.
#[derive(Debug, Clone)]
pub struct LoadOptions {
    /// `-D key=value`: TOML values set over the file's, in order (see `scene::overrides`).
    pub overrides: Vec<(String, String)>,
    /// `--strict`: refuse what is otherwise repaired with a warning (an OBJ's `Kd` of 1 or
    /// more).
    pub strict: bool,
    /// The largest input file read, bytes ([`base::output::input_limit_for`] of the job's
    /// memory limit; by default [`base::output::MAX_INPUT_BYTES`]).
    pub input_limit: u64,
}

impl Default for LoadOptions {
    fn default() -> Self {
        LoadOptions {
            overrides: Vec::new(),
            strict: false,
            input_limit: base::output::MAX_INPUT_BYTES,
        }
    }
}

/// The first camera of a glTF include, for a bare model to look through (`scene::model`);
/// the glTF reader finds it.
#[derive(Debug, Clone)]
pub(crate) struct ModelCamera {
    /// The camera, in scene coordinates.
    pub(crate) camera: Camera,
    /// Width over height of its view, when the file gives it.
    pub(crate) aspect: Option<f64>,
    /// Where it is defined (`room.glb: nodes[3] camera "Camera"`, with the name in
    /// backticks), for messages.
    pub(crate) origin: String,
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
    /// The largest file read, bytes (of [`Readers::limit`]).
    pub(crate) input_limit: u64,
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
    pub(crate) included_camera: Option<ModelCamera>,
}

/// The materials, objects and polygons of a scene, as the `[[materials]]`, `[[polygons]]` and
/// `[[obj]]` sections add them in file order.
#[derive(Default)]
pub(crate) struct Surfaces {
    pub(crate) materials: Vec<Material>,
    /// The materials whose polygons emit and reflect on both faces (`two_sided`).
    pub(crate) two_sided: Vec<u32>,
    /// The materials a model file marks double-sided that stay one-sided (glTF `doubleSided`
    /// without emission): their objects may be turned inside out (`crate::inside_out`).
    pub(crate) double_sided: Vec<u32>,
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
    pub(crate) fn int(
        &self,
        v: &Spanned<i64>,
        key: &str,
        lo: i64,
        hi: i64,
        why: &str,
    ) -> Result<i64> {
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
}

/// What [`in_range`] demands, for messages.
pub(crate) const FINITE_RULE: &str = "every number must be finite and at most 1e9 in magnitude";

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

/// The material names a message offers when a name is not known.
pub(crate) fn known_names(by_name: &BTreeMap<String, u32>) -> String {
    if by_name.is_empty() {
        " (no materials are defined)".to_string()
    } else {
        let names: Vec<&str> = by_name.keys().map(|s| s.as_str()).collect();
        format!(" (known: {})", names.join(", "))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_are_one_based_and_clamped() {
        let t = "a\nbc\n\nd";
        assert_eq!(line_of(t, 0), 1);
        assert_eq!(line_of(t, 2), 2);
        assert_eq!(line_of(t, 5), 3);
        assert_eq!(line_of(t, 6), 4);
        assert_eq!(line_of(t, 1000), 4);
    }
}
