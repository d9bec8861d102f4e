//! A bare model as a scene: `render model.obj` without writing a scene file.
//!
//! A modelling tool exports geometry and materials (OBJ and MTL) but no camera, image size or,
//! usually, light (Blender's lamps are not part of OBJ). [`load_model`] wraps the OBJ in the scene
//! file a user would write for it, validates that like any scene (so every rule and message of
//! `[[obj]]` includes applies: faces, materials, the `Kd` clamp), and then fills in what the
//! model lacks:
//! - the **material** `default` (grey, reflectance [`DEFAULT_REFLECTANCE`]) for faces without
//!   `usemtl` or whose `usemtl` no MTL defines (the MTL is missing);
//! - a **camera** framing the model, unless `-D camera.*` sets one. Inside it when the model is
//!   closed around its centre (a room: nearly every direction from the centre meets a face): at
//!   mid height, at the most open of a grid of points that see only the fronts of faces (so an
//!   L-shaped room or one with furniture is handled), looking the way the view is longest, with a
//!   60 degree field; if no point sees only fronts (a room whose normals face out), near the +z
//!   wall looking along -z, and the orientation warnings say why the image is dark. Outside
//!   otherwise, from the front-right-above direction (1.2, 0.9, 2) of y-up models, at the
//!   distance where the bounding sphere fills a 40 degree view;
//! - a **light** when no material emits (no `Ke`): a spot light below the top of a room (or
//!   above an open model) pointing down (-y), 85 degree half-angle, cosine falloff, with the
//!   intensity that makes the irradiance straight below it 1, so a grey floor's radiosity is
//!   about [`DEFAULT_REFLECTANCE`]. Each default taken is said in a warning, so nothing is
//!   invented silently.
//!
//! The model's up axis is taken as +y (the OBJ convention, and Blender's exporter default).
//! The scene's path is the OBJ's, so a solution file of a model names the OBJ and renders from
//! it again with the same defaults.

use super::bvh::{Aabb, Bvh};
use super::load::{parse_scene_options, LoadOptions};
use super::orientation::{cast, sphere_directions};
use super::{Camera, Projection, Scene, SpotLight};
use base::error::{Error, Location, Result};
use glam::DVec3;
use std::path::Path;

/// Reflectance of the `default` material.
pub const DEFAULT_REFLECTANCE: f64 = 0.6;

/// Image width and height of a model's scene (4:3).
const IMAGE: (u32, u32) = (800, 600);

/// Vertical field of view of the outside view, degrees.
const OUTSIDE_FOV: f64 = 40.0;

/// Whether `path` names a bare model (by its extension, `.obj` in any case).
pub fn is_model(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("obj"))
}

/// The scene file a model stands for (see the module docs): a placeholder camera and spot light
/// that [`load_model`] replaces once the model's bounds are known.
fn scene_text(file_name: &str) -> String {
    let file = toml::Value::String(file_name.to_string());
    let (w, h) = IMAGE;
    format!(
        "[camera]\neye = [0, 0, 1]\nlook_at = [0, 0, 0]\nfov_y = {OUTSIDE_FOV}\n\n\
         [image]\nwidth = {w}\nheight = {h}\n\n\
         [[materials]]\nname = \"default\"\nreflectance = [{r}, {r}, {r}]\n\n\
         [[obj]]\nfile = {file}\ndefault_material = \"default\"\n\n\
         [[spots]]\nposition = [0, 0, 0]\ndirection = [0, -1, 0]\nintensity = [1, 1, 1]\n\
         half_angle = 85\n",
        r = DEFAULT_REFLECTANCE
    )
}

/// Loads the OBJ at `path` as a scene (see the module docs).
pub(crate) fn load_model(path: &Path, opts: &LoadOptions) -> Result<Scene> {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .ok_or_else(|| Error::input(Location::file(path), "not a file name"))?;
    // Read here first, so that a missing model is named as such and not as a key of the scene
    // this module writes for it.
    base::output::read_text(path)
        .map_err(|e| Error::input(Location::file(path), format!("cannot read OBJ file: {e}")))?;
    let text = scene_text(&name);
    let mut scene = parse_scene_options(&text, path, &base::output::read_text, opts)?;
    // The placeholder light is the last spot; any other was set by the user.
    scene.spots.pop();
    scene.spot_origins.pop();
    // The polygons' bounds (the spot lights left out) and one BVH for both ray tests.
    let bounds = scene
        .polygons
        .iter()
        .fold(Aabb::EMPTY, |b, p| b.union(Aabb::of(p.vertices())));
    let (lo, hi) = (bounds.lo, bounds.hi);
    let bvh = Bvh::build(&scene.polygons);
    let enclosed = is_enclosed(&scene, &bvh, (lo + hi) * 0.5, (hi - lo).length());
    let camera_set = opts.overrides.iter().any(|(k, _)| k.starts_with("camera."));
    if !camera_set {
        scene.camera = framing_camera(&scene, &bvh, lo, hi, enclosed);
        scene.warnings.push(format!(
            "{}: no camera in a model: looking from {} at {} ({}; set one with -D camera.eye=[x,y,z] \
             -D camera.look_at=[x,y,z], or --camera)",
            path.display(),
            fmt(scene.camera.eye),
            fmt(scene.camera.look_at),
            if enclosed { "inside: the model is closed around its centre" } else { "outside" }
        ));
    }
    if scene.emitter_count() == 0 && scene.spots.is_empty() {
        let spot = default_light(lo, hi, enclosed);
        scene.warnings.push(format!(
            "{}: no material emits light (no MTL `Ke`): lit by a default spot light at {} \
             pointing down; give a lamp's material a `Ke` to light it yourself",
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

/// A point as `[x, y, z]` with 3 decimals.
fn fmt(p: DVec3) -> String {
    format!("[{:.3}, {:.3}, {:.3}]", p.x, p.y, p.z)
}

/// Whether nearly every direction from `centre` meets a polygon (either side): a room.
fn is_enclosed(scene: &Scene, bvh: &Bvh, centre: DVec3, size: f64) -> bool {
    let dirs = sphere_directions(256);
    let f = cast(scene, bvh, centre, &dirs, 4.0 * size.max(1e-9), u32::MAX);
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
