//! Rooms modelled inside out: objects of double-sided materials that enclose the lights with
//! their backs, turned to face them.
//!
//! Polygons here are one-sided, but a modelling tool draws both sides of a face: a room made
//! of Blender's cube faces outward, and Blender still lights and shows its inside. Its glTF
//! export marks every such material `doubleSided`. Making every double-sided polygon two-sided
//! would double every wall; taking the winding as it stands makes the room black from inside
//! (the orientation checks warn). So where a file says a material is double-sided and an
//! object of it closes around a light with its backs (every ray from the light meets a face,
//! and the object's backs take a tenth of them or more, more than its fronts), the object is
//! turned to face the light, as the tool showed it.
//! A one-sided material (Blender's Backface Culling ticked) and a scene file's own materials
//! are taken as written.
//!
//! Invariants: deterministic (the orientation checks' fixed directions, lights in index
//! order); a turned polygon keeps its corners, material, object and place in the list, its
//! corners listed the other way round; nothing is turned in a scene without double-sided
//! materials.

use std::collections::BTreeSet;

use glam::DVec3;

use crate::bvh::Bvh;
use crate::checks::Surfaces;
use crate::orientation::{cast, cone_directions, sphere_directions, Reach, MAX_CHECKED_LIGHTS};
use crate::{Camera, Projection, Scene, SpotLight};

/// Share of a light's rays that must meet an object's backs (more of them than meet its
/// fronts, and none escaping) for the object to be a room turned inside out around it: a
/// room's walls take most of the rays of a light inside it, whatever furniture stands in it.
pub(crate) const ENCLOSED_BACK: f64 = 0.1;

/// Directions of each light's rays (its front hemisphere takes half of them).
const RAYS: usize = 256;

/// Turns the objects of double-sided materials that enclose a light (an emitter of
/// `surfaces` or one of `spots`) with their backs (see the module docs); the note saying which,
/// if any was turned.
pub(crate) fn turn(surfaces: &mut Surfaces, spots: &[SpotLight]) -> Option<String> {
    if surfaces.double_sided.is_empty() || surfaces.polygons.is_empty() {
        return None;
    }
    let camera = Camera {
        eye: DVec3::ZERO,
        look_at: DVec3::Z,
        up: DVec3::Y,
        projection: Projection::Perspective { fov_y_deg: 60.0 },
    };
    let mut scene = Scene::new(
        camera,
        1,
        1,
        surfaces.materials.clone(),
        std::mem::take(&mut surfaces.polygons),
    );
    scene.spots = spots.to_vec();
    let turnable: BTreeSet<u32> = enclosing(&scene)
        .into_iter()
        .filter(|&o| {
            scene
                .polygons
                .iter()
                .filter(|p| p.object == o)
                .all(|p| surfaces.double_sided.contains(&p.material))
        })
        .collect();
    surfaces.polygons = scene.polygons;
    if turnable.is_empty() {
        return None;
    }
    let mut turned = 0;
    for p in surfaces.polygons.iter_mut() {
        if turnable.contains(&p.object) {
            if let Some(t) = p.reversed() {
                *p = t;
                turned += 1;
            }
        }
    }
    let names: Vec<String> = turnable
        .iter()
        .map(|&o| {
            format!(
                "`{}`",
                surfaces.objects.get(o as usize).map_or("?", String::as_str)
            )
        })
        .collect();
    Some(format!(
        "{turned} polygons of {} turned to face the lights they enclose: their backs faced \
         them (a room made of a modelling tool's cube faces outward), and their materials are \
         double-sided in the file, so the tool showed their insides lit (a material with \
         Backface Culling ticked is one-sided and kept as it is)",
        names.join(", ")
    ))
}

/// The objects whose backs enclose a light: every ray over an emitter's front hemisphere (or
/// a spot's cone) meets a face, and the object's backs take at least [`ENCLOSED_BACK`] of
/// them, more than its fronts do.
fn enclosing(scene: &Scene) -> BTreeSet<u32> {
    let bvh = Bvh::build(&scene.polygons);
    let (lo, hi) = scene.bounds();
    let reach = Reach::of(scene, 4.0 * (hi - lo).length().max(1e-9));
    let sphere = sphere_directions(RAYS);
    let mut lights: Vec<(DVec3, Vec<DVec3>, u32)> = Vec::new();
    for (i, p) in scene.polygons.iter().enumerate() {
        if lights.len() >= MAX_CHECKED_LIGHTS {
            break;
        }
        if scene.material_of(i).is_emitter() {
            let (c, r) = p.bounding_sphere();
            let front = sphere.iter().copied().filter(|d| d.dot(p.normal) > 0.0);
            lights.push((
                c + p.normal * (1e-6 * r.max(1e-9)),
                front.collect(),
                i as u32,
            ));
        }
    }
    for s in scene.spots.iter().take(MAX_CHECKED_LIGHTS) {
        lights.push((
            s.position,
            cone_directions(s.direction, s.half_angle),
            u32::MAX,
        ));
    }
    let mut out = BTreeSet::new();
    for (origin, dirs, skip) in lights {
        let f = cast(scene, &bvh, origin, &dirs, reach, skip);
        if f.missed > 0 || f.hits() == 0 {
            continue;
        }
        let least = ENCLOSED_BACK * f.hits() as f64;
        for (&o, &n) in &f.back {
            if n as f64 >= least && n > f.front_by_object.get(&o).copied().unwrap_or(0) {
                out.insert(o);
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Material, Polygon};

    fn material(name: &str, emission: f64) -> Material {
        Material {
            name: name.into(),
            reflectance: DVec3::splat(0.5),
            emission: DVec3::splat(emission),
        }
    }

    /// The six faces of the box from `lo` to `hi`, facing out, of object `object`.
    fn boxed(lo: DVec3, hi: DVec3, material: u32, object: u32) -> Vec<Polygon> {
        let c = |x: usize, y: usize, z: usize| {
            DVec3::new([lo.x, hi.x][x], [lo.y, hi.y][y], [lo.z, hi.z][z])
        };
        let faces = [
            [c(0, 0, 0), c(0, 0, 1), c(0, 1, 1), c(0, 1, 0)],
            [c(1, 0, 0), c(1, 1, 0), c(1, 1, 1), c(1, 0, 1)],
            [c(0, 0, 0), c(1, 0, 0), c(1, 0, 1), c(0, 0, 1)],
            [c(0, 1, 0), c(0, 1, 1), c(1, 1, 1), c(1, 1, 0)],
            [c(0, 0, 0), c(0, 1, 0), c(1, 1, 0), c(1, 0, 0)],
            [c(0, 0, 1), c(1, 0, 1), c(1, 1, 1), c(0, 1, 1)],
        ];
        let out: Vec<Polygon> = faces
            .iter()
            .map(|f| Polygon::quad(*f, material, object).expect("quad"))
            .collect();
        for p in &out {
            let outward = p.centroid() - (lo + hi) * 0.5;
            assert!(p.normal.dot(outward) > 0.0);
        }
        out
    }

    /// A 2 m room facing outward (object 0, material 0), a box on its floor facing outward
    /// (object 1, material 0) and a lamp under its ceiling facing down (object 2, material 1),
    /// material 0 double-sided in the file if `double_sided`.
    fn room(double_sided: bool) -> Surfaces {
        let mut s = Surfaces {
            materials: vec![material("walls", 0.0), material("lamp", 5.0)],
            objects: vec!["room".into(), "box".into(), "lamp".into()],
            ..Default::default()
        };
        if double_sided {
            s.double_sided.push(0);
        }
        s.polygons = boxed(DVec3::ZERO, DVec3::splat(2.0), 0, 0);
        s.polygons
            .extend(boxed(DVec3::new(0.3, 0.0, 0.3), DVec3::splat(0.9), 0, 1));
        let (a, b, y) = (0.8, 1.2, 1.9);
        let lamp = [[a, y, a], [b, y, a], [b, y, b], [a, y, b]].map(DVec3::from_array);
        s.polygons.push(Polygon::quad(lamp, 1, 2).expect("lamp"));
        assert!(s.polygons[12].normal.y < 0.0);
        s
    }

    /// The room around the lamp is turned to face it, its face towards the floor's first corner
    /// kept; the box, whose fronts the lamp sees, and the lamp stay as they were.
    #[test]
    fn a_double_sided_room_facing_away_from_its_lamp_is_turned() {
        let before = room(true).polygons;
        let mut s = room(true);
        let note = turn(&mut s, &[]).expect("turned");
        assert!(note.starts_with("6 polygons of `room` turned"), "{note}");
        for (k, (a, b)) in before.iter().zip(&s.polygons).enumerate() {
            if k < 6 {
                assert!((a.normal + b.normal).length() < 1e-12, "face {k}");
                assert_eq!(a.corners[0], b.corners[0]);
                assert!((a.area - b.area).abs() < 1e-12);
            } else {
                assert_eq!(a, b, "polygon {k}");
            }
        }
    }

    /// Nothing is turned where the file says the material is one-sided, where no light is
    /// enclosed (the lamp outside the room), or lit by a spot inside it but one-sided; a spot
    /// inside the double-sided room turns it as the lamp does.
    #[test]
    fn only_double_sided_rooms_around_a_light_are_turned() {
        let mut s = room(false);
        assert_eq!(turn(&mut s, &[]), None);
        let mut s = room(true);
        for p in &mut s.polygons[12..] {
            for c in &mut p.corners {
                c.y += 3.0;
            }
        }
        assert_eq!(turn(&mut s, &[]), None, "the lamp above the room");
        let spot = SpotLight {
            position: DVec3::new(1.0, 1.5, 1.0),
            direction: DVec3::NEG_Y,
            intensity: DVec3::ONE,
            half_angle: 1.2,
            falloff: 0.0,
        };
        let mut s = room(false);
        s.polygons.pop();
        assert_eq!(turn(&mut s, std::slice::from_ref(&spot)), None);
        let mut s = room(true);
        s.polygons.pop();
        assert!(turn(&mut s, &[spot]).is_some_and(|n| n.contains("`room`")));
    }
}
