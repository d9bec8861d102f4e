//! A bare model as a scene: `render model.obj` (or `model.gltf`, `model.glb`) without writing a
//! scene file.
//!
//! A modelling tool exports geometry and materials (OBJ and MTL, or glTF) but no image size and,
//! in OBJ, no camera or light (Blender's lamps are not part of OBJ; glTF carries cameras and
//! lights). [`load_model`] wraps the model in the scene file a user would write for it
//! (`[[obj]]` or `[[gltf]]`), validates that like any scene (so every rule and message of the
//! includes applies: faces, materials, the `Kd` and base colour clamp), and then fills in what
//! the model lacks:
//! - the **material** `default` (grey, reflectance [`DEFAULT_REFLECTANCE`]) for faces without
//!   `usemtl` or whose `usemtl` no MTL defines (the MTL is missing), and glTF primitives without
//!   a material;
//! - the glTF's first **camera** when it has one (and `-D camera.*` sets none), its
//!   `aspectRatio` giving the image width; else a **camera** framing the model, unless
//!   `-D camera.*` sets one. Inside it when the model is
//!   closed around its centre (a room: nearly every direction from the centre meets a face): at
//!   mid height, at the most open of a grid of points that see only the fronts of faces (so an
//!   L-shaped room or one with furniture is handled), looking the way the view is longest, with a
//!   60 degree field; if no point sees only fronts (a room whose normals face out), near the +z
//!   wall looking along -z, and the orientation warnings say why the image is dark. Outside
//!   otherwise, from the front-right-above direction (1.2, 0.9, 2) of y-up models, at the
//!   distance where the bounding sphere fills a 40 degree view;
//! - a **light** when no material emits (no `Ke`, no glTF `emissiveFactor`) and the glTF has no
//!   light: a spot light below the top of a room (or
//!   above an open model) pointing down (-y), 85 degree half-angle, cosine falloff, with the
//!   intensity that makes the irradiance straight below it 1, so a grey floor's radiosity is
//!   about [`DEFAULT_REFLECTANCE`]. Each default taken is said in a warning, so nothing is
//!   invented silently.
//!
//! The model's up axis is taken as +y (the OBJ convention, glTF's rule, and Blender's exporter
//! default). The scene's path is the model's, so a solution file of a model names the model and
//! renders from it again with the same defaults.

use super::bvh::{Aabb, Bvh};
use super::orientation::{cast, sphere_directions};
use super::{Camera, Projection, Scene, SpotLight};
use crate::checks::with_files;
use crate::checks::LoadOptions;
use crate::checks::ModelCamera;
use crate::parse::parse_scene_options;
use crate::parse::Parsed;
use base::error::{Error, Location, Result};
use glam::DVec3;
use std::path::Path;

/// Reflectance of the `default` material.
pub(crate) const DEFAULT_REFLECTANCE: f64 = 0.6;

/// Image width and height of a model's scene (4:3).
const IMAGE: (u32, u32) = (800, 600);

/// Vertical field of view of the outside view, degrees.
const OUTSIDE_FOV: f64 = 40.0;

/// The model formats, by extension.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Format {
    /// Wavefront OBJ (`.obj`), with its MTL files.
    Obj,
    /// glTF 2.0 (`.gltf` with its buffers, or `.glb`).
    Gltf,
}

impl Format {
    /// The format of the model at `path`, by its extension in any case; `None` if it is not a
    /// model's.
    fn of(path: &Path) -> Option<Format> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "obj" => Some(Format::Obj),
            "gltf" | "glb" => Some(Format::Gltf),
            _ => None,
        }
    }

    /// The name of the format, for messages.
    fn name(self) -> &'static str {
        match self {
            Format::Obj => "OBJ",
            Format::Gltf => "glTF",
        }
    }
}

/// Whether `path` names a bare model (by its extension, `.obj`, `.gltf` or `.glb` in any case).
pub fn is_model(path: &Path) -> bool {
    Format::of(path).is_some()
}

/// The scene file a model stands for (see the module docs): a placeholder camera and spot light
/// that [`load_model`] replaces once the model's bounds are known.
fn scene_text(file_name: &str, format: Format) -> String {
    let file = toml::Value::String(file_name.to_string());
    let (w, h) = IMAGE;
    let include = match format {
        Format::Obj => "obj",
        Format::Gltf => "gltf",
    };
    format!(
        "[camera]\neye = [0, 0, 1]\nlook_at = [0, 0, 0]\nfov_y = {OUTSIDE_FOV}\n\n\
         [image]\nwidth = {w}\nheight = {h}\n\n\
         [[materials]]\nname = \"default\"\nreflectance = [{r}, {r}, {r}]\n\n\
         [[{include}]]\nfile = {file}\ndefault_material = \"default\"\n\n\
         [[spots]]\nposition = [0, 0, 0]\ndirection = [0, -1, 0]\nintensity = [1, 1, 1]\n\
         half_angle = 85\n",
        r = DEFAULT_REFLECTANCE
    )
}

/// Loads the model at `path` as a scene (see the module docs).
pub(crate) fn load_model(path: &Path, opts: &LoadOptions) -> Result<Scene> {
    let format = Format::of(path)
        .ok_or_else(|| Error::input(Location::file(path), "is not a model (.obj, .gltf, .glb)"))?;
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .ok_or_else(|| Error::input(Location::file(path), "not a file name"))?;
    // Read here first, so that a missing model is named as such and not as a key of the scene
    // this module writes for it.
    with_files(opts.input_limit, |readers| {
        let readable = match format {
            Format::Obj => (readers.text)(path).map(drop),
            Format::Gltf => (readers.bytes)(path).map(drop),
        };
        readable.map_err(|e| {
            Error::input(
                Location::file(path),
                format!("cannot read {} file: {e}", format.name()),
            )
        })?;
        let text = scene_text(&name, format);
        parse_scene_options(&text, path, readers, opts)
    })
    .and_then(|parsed| finish_model(path, format, opts, parsed))
}

/// A bare model's parsed scene made whole: the placeholder light dropped, then lit and framed
/// (see the module docs).
fn finish_model(path: &Path, format: Format, opts: &LoadOptions, parsed: Parsed) -> Result<Scene> {
    let mut scene = parsed.scene;
    // The placeholder light is the first spot (the scene text's only `[[spots]]` entry, which
    // `-D` cannot add to); the glTF's lights follow it.
    if !scene.spots.is_empty() {
        scene.spots.remove(0);
        scene.spot_origins.remove(0);
    }
    // The polygons' bounds (the spot lights left out) and one BVH for both ray tests.
    let bounds = scene
        .polygons
        .iter()
        .fold(Aabb::EMPTY, |b, p| b.union(Aabb::of(p.vertices())));
    let (lo, hi) = (bounds.lo, bounds.hi);
    let bvh = Bvh::build(&scene.polygons);
    let enclosed = is_enclosed(&scene, &bvh, (lo + hi) * 0.5, (hi - lo).length());
    let camera_set = opts.overrides.iter().any(|(k, _)| k.starts_with("camera."));
    if let (false, Some(c)) = (camera_set, &parsed.camera) {
        use_model_camera(&mut scene, c, opts);
    } else if !camera_set {
        scene.camera = framing_camera(&scene, &bvh, lo, hi, enclosed);
        scene.warnings.push(format!(
            "{}: no camera in a model: looking from {} at {} ({}; set one with camera.eye and \
             camera.look_at)",
            path.display(),
            fmt(scene.camera.eye),
            fmt(scene.camera.look_at),
            if enclosed {
                "inside: the model is closed around its centre"
            } else {
                "outside"
            }
        ));
    }
    if scene.emitter_count() == 0 && scene.spots.is_empty() {
        let spot = default_light(lo, hi, enclosed);
        let (none, fix) = match format {
            Format::Obj => ("no MTL `Ke`", "give a lamp's material a `Ke`"),
            Format::Gltf => (
                "no `emissiveFactor`, no KHR_lights_punctual light",
                "give a lamp's material an emission (Blender: Emission strength) or add a light",
            ),
        };
        scene.warnings.push(format!(
            "{}: no material emits light ({none}): lit by a default spot light at {} pointing \
             down; {fix} to light it yourself",
            path.display(),
            fmt(spot.position)
        ));
        scene.spot_origins.push(
            Location::file(path).with_key("the default light (the model has none)".to_string()),
        );
        scene.spots.push(spot);
    }
    Ok(scene)
}

/// Makes the glTF camera `c` the scene's camera. Its aspect ratio, when it gives one, sets the
/// image width for the model's image height (unless `-D image.*` sets the size): the glTF's
/// vertical field of view then shows what the author framed.
fn use_model_camera(scene: &mut Scene, c: &ModelCamera, opts: &LoadOptions) {
    scene.camera = c.camera;
    let size_set = opts.overrides.iter().any(|(k, _)| k.starts_with("image."));
    if let (false, Some(aspect)) = (size_set, c.aspect) {
        let width = (f64::from(scene.height) * aspect).round();
        scene.width = width.clamp(1.0, f64::from(super::MAX_IMAGE_DIM)) as u32;
    }
}

/// A point as `[x, y, z]` with 3 decimals.
fn fmt(p: DVec3) -> String {
    format!("[{:.3}, {:.3}, {:.3}]", p.x, p.y, p.z)
}

/// Whether nearly every direction from `centre` meets a polygon (either side): a room.
fn is_enclosed(scene: &Scene, bvh: &Bvh, centre: DVec3, size: f64) -> bool {
    let dirs = sphere_directions(256);
    let reach = crate::orientation::Reach::of(scene, 4.0 * size.max(1e-9));
    let f = cast(scene, bvh, centre, &dirs, reach, u32::MAX);
    f.missed * 20 <= dirs.len()
}

/// An eye point inside a room: of a 7 x 7 grid of points at mid height, the one whose
/// surroundings are most open (largest mean distance to the first hit) among those that see only
/// front sides and no gap, and the horizontal direction (of 16) with the farthest view from it.
/// `None` if no grid point qualifies (the room faces outward, or it is not a room).
fn inside_view(scene: &Scene, bvh: &Bvh, lo: DVec3, hi: DVec3) -> Option<(DVec3, DVec3)> {
    let size = hi - lo;
    let reach = 4.0 * size.length().max(1e-9);
    let dirs = sphere_directions(64);
    let first = |o: DVec3, d: DVec3| -> Option<(bool, f64)> {
        bvh.first_hit(o, d * reach, u32::MAX).map(|(i, t)| {
            let front = scene.polygons[i as usize].normal.dot(d) < 0.0;
            (front, t * reach)
        })
    };
    let mut best: Option<(f64, DVec3)> = None;
    for i in 0..7 {
        for k in 0..7 {
            let o = DVec3::new(
                lo.x + size.x * (i as f64 + 0.5) / 7.0,
                lo.y + 0.5 * size.y,
                lo.z + size.z * (k as f64 + 0.5) / 7.0,
            );
            let mut sum = 0.0;
            let mut ok = true;
            for &d in &dirs {
                match first(o, d) {
                    Some((true, t)) if t > 0.02 * size.length() => sum += t,
                    _ => {
                        ok = false;
                        break;
                    }
                }
            }
            if ok && best.is_none_or(|(b, _)| sum > b) {
                best = Some((sum, o));
            }
        }
    }
    let (_, eye) = best?;
    let (mut far, mut dir) = (0.0, DVec3::NEG_Z);
    for j in 0..16 {
        let a = std::f64::consts::TAU * j as f64 / 16.0;
        let d = DVec3::new(a.sin(), 0.0, -a.cos());
        if let Some((_, t)) = first(eye, d) {
            if t > far {
                (far, dir) = (t, d);
            }
        }
    }
    // Step back from the farthest view, so the eye stands off the wall behind it.
    let back = first(eye, -dir).map_or(0.0, |(_, t)| t);
    let eye = eye - dir * (0.6 * back);
    Some((eye, eye + dir * (0.5 * (far + 0.6 * back))))
}

/// The default camera of a model with bounds (`lo`, `hi`) (see the module docs).
fn framing_camera(scene: &Scene, bvh: &Bvh, lo: DVec3, hi: DVec3, enclosed: bool) -> Camera {
    let c = (lo + hi) * 0.5;
    let size = (hi - lo).max(DVec3::splat(1e-9));
    if let Some((eye, look_at)) = enclosed.then(|| inside_view(scene, bvh, lo, hi)).flatten() {
        return Camera {
            eye,
            look_at,
            up: DVec3::Y,
            projection: Projection::Perspective { fov_y_deg: 60.0 },
        };
    }
    if enclosed {
        let eye = DVec3::new(c.x, c.y, lo.z + 0.9 * size.z);
        let look_at = DVec3::new(c.x, c.y, lo.z);
        let depth = 0.9 * size.z;
        let fov = (2.0 * (0.5 * size.y / depth).atan().to_degrees()).clamp(40.0, 90.0);
        return Camera {
            eye,
            look_at,
            up: DVec3::Y,
            projection: Projection::Perspective { fov_y_deg: fov },
        };
    }
    let radius = 0.5 * size.length();
    let dist = radius / (0.5 * OUTSIDE_FOV.to_radians()).sin();
    let dir = DVec3::new(1.2, 0.9, 2.0).normalize();
    Camera {
        eye: c + dir * dist,
        look_at: c,
        up: DVec3::Y,
        projection: Projection::Perspective {
            fov_y_deg: OUTSIDE_FOV,
        },
    }
}

/// The default light of a model with bounds (`lo`, `hi`) (see the module docs).
fn default_light(lo: DVec3, hi: DVec3, enclosed: bool) -> SpotLight {
    let c = (lo + hi) * 0.5;
    let size = (hi - lo).max(DVec3::splat(1e-9));
    let y = if enclosed {
        lo.y + 0.95 * size.y
    } else {
        hi.y + 0.5 * size.length()
    };
    let h = y - lo.y;
    SpotLight {
        position: DVec3::new(c.x, y, c.z),
        direction: DVec3::NEG_Y,
        intensity: DVec3::splat(h * h),
        half_angle: 85f64.to_radians(),
        falloff: 1.0,
    }
}
