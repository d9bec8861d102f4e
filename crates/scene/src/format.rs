//! The scene file as written: serde structs that mirror the TOML sections one to one.
//!
//! This is the first half of loading a scene (`scene::parse` is the second): `toml` turns the
//! text into these structs, and nothing more. Every struct denies unknown fields, so a misspelt key
//! is an error with a line number instead of a silently ignored setting. Every field that
//! `scene::parse` checks semantically is wrapped in [`Spanned`], so the loader can name the line
//! of a bad value as well as its key path. Defaults are not filled in here: an absent optional key
//! stays `None` and the loader takes the default from the `Default` impls in [`super`], so there
//! is exactly one place where each default lives. `docs/scene-format.md` documents every key.

use serde::de::Error as _;
use serde::{Deserialize, Deserializer};
use std::collections::BTreeMap;
use toml::Spanned;

/// A 3-vector as written: `[x, y, z]`, exactly three numbers.
///
/// Not a plain `[f64; 3]`: toml's deserializer lets serde's array impl stop after three elements
/// and silently drops a fourth (`eye = [0, 0, 1, 3]`); this type refuses any other length.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Vec3(pub [f64; 3]);

impl<'de> Deserialize<'de> for Vec3 {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let v = Vec::<f64>::deserialize(d)?;
        <[f64; 3]>::try_from(v.as_slice())
            .map(Vec3)
            .map_err(|_| D::Error::invalid_length(v.len(), &"three numbers [x, y, z]"))
    }
}

/// The whole file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct SceneFile {
    /// `[camera]`, required.
    pub camera: Spanned<CameraSection>,
    /// `[image]`, optional (defaults 512 x 512).
    pub image: Option<ImageSection>,
    /// `[[materials]]`.
    #[serde(default)]
    pub materials: Vec<Spanned<MaterialSection>>,
    /// `[[polygons]]`: inline geometry.
    #[serde(default)]
    pub polygons: Vec<Spanned<PolygonSection>>,
    /// `[[obj]]`: OBJ includes.
    #[serde(default)]
    pub obj: Vec<Spanned<ObjSection>>,
    /// `[[gltf]]`: glTF 2.0 includes (`.gltf` or `.glb`), with the keys of `[[obj]]`.
    #[serde(default)]
    pub gltf: Vec<Spanned<ObjSection>>,
    /// `[[spots]]`: spot lights.
    #[serde(default)]
    pub spots: Vec<Spanned<SpotSection>>,
    /// `[radiosity]`.
    pub radiosity: Option<Spanned<RadiositySection>>,
    /// `[render]`.
    pub render: Option<Spanned<RenderSection>>,
    /// `[display]`.
    pub display: Option<Spanned<DisplaySection>>,
    /// `[camera_path]`.
    pub camera_path: Option<Spanned<CameraPathSection>>,
}

/// `[camera]`: perspective (`fov_y`) or orthographic (`ortho_width` and `ortho_height`).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct CameraSection {
    /// Eye position.
    pub eye: Spanned<Vec3>,
    /// Point looked at.
    pub look_at: Spanned<Vec3>,
    /// Up direction; default `[0, 1, 0]`.
    pub up: Option<Spanned<Vec3>>,
    /// Vertical field of view in degrees (perspective).
    pub fov_y: Option<Spanned<f64>>,
    /// Width of the view in scene units (orthographic).
    pub ortho_width: Option<Spanned<f64>>,
    /// Height of the view in scene units (orthographic).
    pub ortho_height: Option<Spanned<f64>>,
}

/// `[image]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct ImageSection {
    /// Width in pixels.
    pub width: Option<Spanned<i64>>,
    /// Height in pixels.
    pub height: Option<Spanned<i64>>,
}

/// One `[[materials]]` entry.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct MaterialSection {
    /// Unique name.
    pub name: Spanned<String>,
    /// Diffuse reflectance, each in [0, 1).
    pub reflectance: Spanned<Vec3>,
    /// Emission, each >= 0; default 0.
    pub emission: Option<Spanned<Vec3>>,
    /// Whether its polygons emit and reflect on both faces (default false).
    pub two_sided: Option<Spanned<bool>>,
}

/// One `[[polygons]]` entry.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct PolygonSection {
    /// Optional name (for messages and `Scene::objects`).
    pub name: Option<String>,
    /// 3 or 4 corners, counter-clockwise seen from the front.
    pub vertices: Spanned<Vec<Vec3>>,
    /// Material name.
    pub material: Spanned<String>,
}

/// `scale` of an `[[obj]]` or `[[gltf]]`: a number or one factor per axis.
#[derive(Debug, Deserialize)]
#[serde(untagged, expecting = "a number or three numbers [x, y, z]")]
pub(crate) enum ScaleSpec {
    /// The same factor on every axis.
    Uniform(f64),
    /// One factor per axis.
    PerAxis(Vec3),
}

/// One `[[obj]]` include, or one `[[gltf]]` include (the same keys: a model file, where it
/// goes, and how its materials map to the scene's).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct ObjSection {
    /// Path of the OBJ or glTF file, relative to the scene file's directory.
    pub file: Spanned<String>,
    /// Scale, applied first.
    pub scale: Option<Spanned<ScaleSpec>>,
    /// Rotation in degrees about x, then y, then z (fixed axes), applied after scaling.
    pub rotate: Option<Spanned<Vec3>>,
    /// Translation, applied last.
    pub translate: Option<Spanned<Vec3>>,
    /// Override map: OBJ (MTL) or glTF material name -> scene material name.
    pub materials: Option<Spanned<BTreeMap<String, String>>>,
    /// Scene material for faces that have no material (no `usemtl`; a glTF primitive without
    /// `material`).
    pub default_material: Option<Spanned<String>>,
}

/// One `[[spots]]` entry.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct SpotSection {
    /// Position of the point source.
    pub position: Spanned<Vec3>,
    /// Axis of the cone (normalised by the loader).
    pub direction: Spanned<Vec3>,
    /// Radiant intensity on the axis, W/sr per channel.
    pub intensity: Spanned<Vec3>,
    /// Cone half-angle in degrees, in (0, 90].
    pub half_angle: Spanned<f64>,
    /// Exponent of the cosine falloff, >= 0; default 1.
    pub falloff: Option<Spanned<f64>>,
}

/// `[radiosity]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RadiositySection {
    /// Subdivision tolerance.
    pub tolerance: Option<Spanned<f64>>,
    /// Minimum quadtree depth.
    pub min_depth: Option<Spanned<i64>>,
    /// Maximum quadtree depth.
    pub max_depth: Option<Spanned<i64>>,
    /// Convergence threshold (fraction of emitted power left unshot).
    pub convergence: Option<Spanned<f64>>,
    /// Shadow rays per receiver point and source.
    pub shadow_rays: Option<Spanned<i64>>,
    /// Seed.
    pub seed: Option<Spanned<i64>>,
    /// Receiver search: "auto", "exact" or "sampled".
    pub visibility: Option<Spanned<String>>,
    /// Whether polygons are cut along their contact lines.
    pub cut_contacts: Option<Spanned<bool>>,
    /// Whether coplanar triangle pairs are merged into quads.
    pub merge_triangles: Option<Spanned<bool>>,
}

/// `[render]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RenderSection {
    /// Default method.
    pub method: Option<Spanned<String>>,
    /// Antialiasing samples per pixel.
    pub aa: Option<Spanned<i64>>,
    /// Texture size for the texture methods (0 = automatic).
    pub texture_size: Option<Spanned<i64>>,
    /// Texel placement of the texture methods (`centre` or `corner`).
    pub texel_placement: Option<Spanned<String>>,
}

/// `[display]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct DisplaySection {
    /// Exposure in stops.
    pub exposure: Option<Spanned<f64>>,
    /// Background linear RGB.
    pub background: Option<Spanned<Vec3>>,
}

/// `[camera_path]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct CameraPathSection {
    /// Frames along the whole path.
    pub frames: Spanned<i64>,
    /// Keyframes, at least two.
    pub keyframes: Spanned<Vec<KeyframeSection>>,
}

/// One keyframe of `[camera_path]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct KeyframeSection {
    /// Eye.
    pub eye: Vec3,
    /// Point looked at.
    pub look_at: Vec3,
    /// Up; default `[0, 1, 0]`.
    pub up: Option<Vec3>,
}
