//! The lights (`KHR_lights_punctual`) and the camera of a glTF include.
//!
//! **Units.** glTF's light units are photometric: a light's intensity is in candela, and the
//! emissive product of a material (`emissiveFactor` times `emissiveStrength`) is a luminance in
//! cd/m^2. The scene's are radiometric, with a free scale (the image's exposure sets it): a
//! material's emission is an exitance, a spot's intensity a radiant intensity per channel. One
//! scale serves both, so a glTF's lights keep their proportions: a luminance of L is taken as a
//! scene radiance of L / pi, so an emitting surface's exitance (pi times its radiance) is the
//! glTF's emissive product as it stands, and a light of I candela (times its `color`) becomes a
//! spot of intensity I / pi. The 683 lm/W of the photometric units is left out of both: scaled
//! in, every light would be 683 times weaker and the same image 9.4 stops darker.
//!
//! **Spots.** A glTF spot shines evenly inside its `innerConeAngle` and fades to nothing at its
//! `outerConeAngle` (the extension's recommended fade: the square of a ramp in the cosine). A
//! scene spot is `intensity cos(theta)^falloff` inside a hard cone. The scene spot keeps the
//! position, the axis (the node's -z), the outer cone as its half-angle and the on-axis
//! intensity, and its falloff is chosen so that it emits the glTF spot's power (see
//! [`cone_falloff`]); equal cones give falloff 0.
//!
//! **Points.** The scene has no point light; a point light is two spots back to back, up and
//! down, each with a 90 degree half-angle and no falloff: together they emit the same intensity
//! in every direction, as the point light does. **Directional** lights (a sun at infinity) have
//! no scene counterpart and are skipped with a warning naming them. `range` is ignored (the
//! light falls off with the square of the distance everywhere), with a note.
//!
//! **Camera.** The first node with a camera, in walk order, gives the eye (the node's origin),
//! the view direction (its -z axis) and up (its y axis); a perspective camera's `yfov` (radians)
//! is the vertical field of view, an orthographic one's `xmag` and `ymag` half its width and
//! height. A camera that cannot be used is skipped with a note saying why.

use super::super::obj::{decimal, decimal3};
use super::super::{Camera, Projection, SpotLight};
use super::{scene_axis, Converter, ModelCamera};
use crate::checks::{in_range, Cx, FINITE_RULE, MIN_FOV_Y};
use base::error::{Error, Result};
use glam::{DAffine3, DVec3};
use std::f64::consts::{FRAC_PI_2, PI};

/// Largest falloff exponent a scene spot takes (`[[spots]] falloff`'s limit).
const MAX_FALLOFF: f64 = 1.0e4;

impl Converter<'_> {
    /// Adds the light of `node` (placed by `world` and the include's transform) to the scene's
    /// spot lights, converted as the module docs say.
    pub(super) fn light(
        &mut self,
        cx: &mut Cx<'_>,
        node: &::gltf::Node<'_>,
        light: &::gltf::khr_lights_punctual::Light<'_>,
        world: &DAffine3,
    ) -> Result<()> {
        use ::gltf::khr_lights_punctual::Kind;
        let key = format!("extensions.KHR_lights_punctual.lights[{}]", light.index());
        let name = light.name().map_or_else(|| key.clone(), str::to_string);
        let origin = self.loc(format!("nodes[{}] light `{name}`", node.index()));
        let intensity = self.radiant_intensity(light, &key)?;
        if light.range().is_some() {
            cx.notes.push(format!(
                "{origin}: `range` ignored: the light falls off with the square of the distance \
                 everywhere"
            ));
        }
        let position = self.transform.apply(world.transform_point3(DVec3::ZERO));
        if !position.to_array().iter().all(|x| in_range(*x)) {
            return Err(Error::input(
                origin,
                format!("is placed at {position}; {FINITE_RULE}"),
            ));
        }
        let (inner, outer) = match light.kind() {
            Kind::Directional => {
                cx.warnings.push(format!(
                    "{origin}: a directional light (a sun at infinity) has no counterpart in a \
                     scene: skipped; light the model with an emitting surface or a spot"
                ));
                return Ok(());
            }
            Kind::Point => {
                for direction in [DVec3::Y, DVec3::NEG_Y] {
                    let spot = SpotLight {
                        position,
                        direction,
                        intensity,
                        half_angle: FRAC_PI_2,
                        falloff: 0.0,
                    };
                    cx.included_spots.push((spot, origin.clone()));
                }
                cx.notes.push(format!(
                    "{origin}: a point light: two spots back to back (up and down, 90 degree \
                     half-angles, no falloff), which emit alike in every direction"
                ));
                return Ok(());
            }
            Kind::Spot {
                inner_cone_angle,
                outer_cone_angle,
            } => (
                decimal(f64::from(inner_cone_angle)),
                decimal(f64::from(outer_cone_angle)),
            ),
        };
        if !(outer > 0.0 && outer <= FRAC_PI_2 + 1e-6 && inner.is_finite()) {
            return Err(Error::input(
                self.loc(format!("{key}.spot")),
                format!(
                    "has cone angles {inner} and {outer} radians; the outer one must be in \
                     (0, pi/2], the inner one at most the outer"
                ),
            ));
        }
        let outer = outer.min(FRAC_PI_2);
        let inner = inner.clamp(0.0, outer);
        let Some(direction) = scene_axis(&self.transform, world, DVec3::NEG_Z) else {
            cx.warnings.push(format!(
                "{origin}: its node's transform flattens its axis (a zero scale): skipped"
            ));
            return Ok(());
        };
        let spot = SpotLight {
            position,
            direction,
            intensity,
            half_angle: outer,
            falloff: cone_falloff(inner, outer),
        };
        cx.included_spots.push((spot, origin));
        Ok(())
    }

    /// A light's `color` times its `intensity` (candela) over pi: the scene spot's intensity
    /// per channel (see the module docs), checked.
    fn radiant_intensity(
        &self,
        light: &::gltf::khr_lights_punctual::Light<'_>,
        key: &str,
    ) -> Result<DVec3> {
        let intensity = decimal(f64::from(light.intensity()));
        let color = decimal3(light.color());
        if !(intensity.is_finite() && intensity >= 0.0) {
            return Err(Error::input(
                self.loc(format!("{key}.intensity")),
                format!("is {intensity}; it must be finite and >= 0 (candela)"),
            ));
        }
        if !color.to_array().iter().all(|c| c.is_finite() && *c >= 0.0) {
            return Err(Error::input(
                self.loc(format!("{key}.color")),
                format!("is {color}; every channel must be finite and >= 0"),
            ));
        }
        let radiant = color * (intensity / PI);
        if !radiant.to_array().iter().all(|x| in_range(*x)) {
            return Err(Error::input(
                self.loc(format!("{key}.intensity")),
                format!("gives {radiant} per channel; {FINITE_RULE}"),
            ));
        }
        Ok(radiant)
    }

    /// Offers the camera `index` of `node` (placed by `world` and the include's transform) as
    /// the include's camera, unless an earlier include offered one; a camera that cannot be
    /// used is skipped with a note.
    pub(super) fn camera(
        &mut self,
        cx: &mut Cx<'_>,
        node: &::gltf::Node<'_>,
        index: usize,
        world: &DAffine3,
    ) {
        let json = self.file.gltf.document.as_json().cameras.get(index);
        let name = json
            .and_then(|c| c.name.clone())
            .unwrap_or_else(|| format!("cameras[{index}]"));
        let origin = self
            .loc(format!("nodes[{}] camera `{name}`", node.index()))
            .to_string();
        let made = json
            .ok_or_else(|| "it is out of range".to_string())
            .and_then(projection)
            .and_then(|(projection, aspect)| {
                let camera = self.pose(world, projection)?;
                Ok(ModelCamera {
                    camera,
                    aspect,
                    origin: origin.clone(),
                })
            });
        match made {
            Ok(c) => {
                if cx.included_camera.is_none() {
                    cx.included_camera = Some(c);
                }
            }
            Err(why) => cx.notes.push(format!("{origin}: not used: {why}")),
        }
    }

    /// The camera at the node placed by `world` (and the include's transform): eye at its
    /// origin, looking along its -z axis, up its y axis.
    fn pose(&self, world: &DAffine3, projection: Projection) -> Result<Camera, String> {
        let eye = self.transform.apply(world.transform_point3(DVec3::ZERO));
        let forward = scene_axis(&self.transform, world, DVec3::NEG_Z);
        let up = scene_axis(&self.transform, world, DVec3::Y);
        let (Some(forward), Some(up)) = (forward, up) else {
            return Err("its node's transform flattens its axes (a zero scale)".to_string());
        };
        if !eye.to_array().iter().all(|x| in_range(*x)) {
            return Err(format!("its eye {eye} is out of range; {FINITE_RULE}"));
        }
        if forward.cross(up).length() < 1e-6 {
            return Err("its up axis is parallel to its view direction".to_string());
        }
        Ok(Camera {
            eye,
            look_at: eye + forward,
            up,
            projection,
        })
    }
}

/// The projection of a glTF camera and its aspect ratio (width over height) if it gives one; why
/// not, if it cannot be used.
fn projection(c: &::gltf::json::Camera) -> std::result::Result<(Projection, Option<f64>), String> {
    use ::gltf::json::camera::Type;
    use ::gltf::json::validation::Checked;
    match (&c.type_, &c.perspective, &c.orthographic) {
        (Checked::Valid(Type::Perspective), Some(p), _) => {
            let fov = decimal(f64::from(p.yfov)).to_degrees();
            if !(MIN_FOV_Y..180.0).contains(&fov) {
                return Err(format!(
                    "its yfov is {fov} degrees, outside [{MIN_FOV_Y}, 180)"
                ));
            }
            let aspect = p
                .aspect_ratio
                .map(|a| decimal(f64::from(a)))
                .filter(|a| a.is_finite() && (1e-3..=1e3).contains(a));
            Ok((Projection::Perspective { fov_y_deg: fov }, aspect))
        }
        (Checked::Valid(Type::Orthographic), _, Some(o)) => {
            let width = 2.0 * decimal(f64::from(o.xmag)).abs();
            let height = 2.0 * decimal(f64::from(o.ymag)).abs();
            if !(width > 0.0 && height > 0.0 && in_range(width) && in_range(height)) {
                return Err(format!(
                    "its view is {width} x {height}; both must be > 0 and at most 1e9"
                ));
            }
            Ok((
                Projection::Orthographic { width, height },
                Some(width / height),
            ))
        }
        _ => Err("its `type` names a projection it does not give".to_string()),
    }
}

/// The falloff exponent n of a scene spot (`I cos(theta)^n` inside the half-angle `outer`)
/// that emits the power of a glTF spot of the same on-axis intensity I with cones `inner` and
/// `outer` (radians, 0 <= inner <= outer <= pi/2).
///
/// The glTF spot's power is 2 pi I (1 - cos inner + (cos inner - cos outer) / 3): full
/// intensity inside the inner cone, then the square of a ramp in the cosine, whose mean is a
/// third. The scene spot's is 2 pi I (1 - cos(outer)^(n + 1)) / (n + 1), which falls from
/// 2 pi I (1 - cos outer) at n = 0 as n grows; the n where the two are equal is found by
/// bisection (0 when the cones are equal, at most [`MAX_FALLOFF`]).
pub(super) fn cone_falloff(inner: f64, outer: f64) -> f64 {
    let (ci, co) = (inner.cos(), outer.cos());
    let target = (1.0 - ci) + (ci - co) / 3.0;
    let power = |n: f64| (1.0 - co.powf(n + 1.0)) / (n + 1.0);
    if power(0.0) <= target {
        return 0.0;
    }
    if power(MAX_FALLOFF) >= target {
        return MAX_FALLOFF;
    }
    let (mut lo, mut hi) = (0.0, MAX_FALLOFF);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if power(mid) > target {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}
