//! Orientation checks: warnings for the scenes that render black without any error.
//!
//! Polygons are one-sided: light leaves and arrives on the side the normal points to (the
//! corners turn counter-clockwise seen from there); a surface seen from behind shows its front's
//! light, black when the front is unlit. A model whose winding is reversed (a modelling tool's cube has outward normals, so a
//! room built from one faces away from everything inside it), a camera behind a wall or inside a
//! closed object, or a lamp turned upside down is a valid scene that renders a black image. These
//! checks cast a few thousand rays through the scene's [`Bvh`] and count which side of the first
//! polygon hit faces the ray's origin:
//! - from the camera, a grid over the image: the share of the image that shows back sides;
//! - from the eye, a sphere of directions: whether the camera is enclosed by back sides;
//! - from the lights (emitting polygons over their front hemisphere, spot lights over their
//!   cone): the share of their light that lands on back sides, and emitters whose light all
//!   escapes while their back faces the model.
//!
//! Deterministic (fixed direction sets, no random numbers) and cheap: at most
//! [`MAX_CHECKED_LIGHTS`] lights are sampled, so the cost is a BVH build and about 10^4 rays for
//! any scene. The thresholds are set well above what a correct scene shows (a Cornell box seen
//! from its open side: no back side in view) and below what a flipped one does (all of it).

use crate::bvh::Bvh;
use crate::seal::Seals;
use crate::{Projection, Scene};
use glam::DVec3;
use std::collections::BTreeMap;

/// Image rays per side of the camera check's grid.
const CAMERA_GRID: usize = 48;

/// Directions of the eye's enclosure check and of each light.
const SPHERE_RAYS: usize = 256;

/// Most lights (emitting polygons and spot lights) whose rays are cast.
pub const MAX_CHECKED_LIGHTS: usize = 64;

/// Share of the image showing back sides from which the camera check warns.
pub const BACK_IN_VIEW_WARN: f64 = 0.2;

/// Share of a light's hits landing on back sides from which the light check warns.
pub const BACK_LIT_WARN: f64 = 0.5;

/// What a bundle of rays met: hits on front sides, on back sides (by object), and misses.
#[derive(Debug, Default, Clone)]
pub struct Facing {
    /// Rays whose first hit shows its front side to the origin.
    pub front: usize,
    /// Rays whose first hit shows its back side, per object index.
    pub back: BTreeMap<u32, usize>,
    /// Rays whose first hit shows its front side, per object index.
    pub front_by_object: BTreeMap<u32, usize>,
    /// Rays that hit nothing.
    pub missed: usize,
}

impl Facing {
    /// Rays that hit a back side.
    pub fn back_count(&self) -> usize {
        self.back.values().sum()
    }

    /// Rays that hit anything.
    pub fn hits(&self) -> usize {
        self.front + self.back_count()
    }

    /// Share of all rays that hit a back side.
    pub fn back_share(&self) -> f64 {
        ratio(self.back_count(), self.hits() + self.missed)
    }

    /// Share of the hits that are back sides.
    pub fn back_share_of_hits(&self) -> f64 {
        ratio(self.back_count(), self.hits())
    }

    /// The object whose back side most rays hit (ties: the smaller index).
    pub fn worst_object(&self) -> Option<u32> {
        let mut v: Vec<(u32, usize)> = self.back.iter().map(|(&o, &n)| (o, n)).collect();
        v.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(&b.0)));
        v.first().map(|&(o, _)| o)
    }

    fn add(&mut self, o: &Facing) {
        self.front += o.front;
        self.missed += o.missed;
        for (&k, &n) in &o.back {
            *self.back.entry(k).or_default() += n;
        }
        for (&k, &n) in &o.front_by_object {
            *self.front_by_object.entry(k).or_default() += n;
        }
    }
}

fn ratio(a: usize, b: usize) -> f64 {
    if b == 0 {
        0.0
    } else {
        a as f64 / b as f64
    }
}

/// Casts rays from `origin` along `dirs` (unit) and sorts the first hits by side; `reach` goes
/// beyond the scene, `skip` is a polygon not to hit (the emitter itself).
pub(crate) fn cast(
    scene: &Scene,
    bvh: &Bvh,
    origin: DVec3,
    dirs: &[DVec3],
    reach: Reach,
    skip: u32,
) -> Facing {
    cast_rays(scene, bvh, dirs.iter().map(|&d| (origin, d)), reach, skip)
}

/// How far the checks' rays go: `len`, past the scene from anywhere in it, and the segment
/// parameter `t0` their hits count from ([`Scene::ray_t0`]: a backdrop a million times a
/// room's size, which sets `len`, must not hide what lies within a metre of a ray's origin).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Reach {
    pub len: f64,
    pub t0: f64,
}

impl Reach {
    /// Rays `len` long in `scene`.
    pub(crate) fn of(scene: &Scene, len: f64) -> Reach {
        Reach {
            len,
            t0: scene.ray_t0(),
        }
    }
}

/// [`cast`] of rays with their own origins: (origin, unit direction).
fn cast_rays(
    scene: &Scene,
    bvh: &Bvh,
    rays: impl Iterator<Item = (DVec3, DVec3)>,
    reach: Reach,
    skip: u32,
) -> Facing {
    let mut f = Facing::default();
    for (origin, d) in rays {
        match bvh.first_hit_from(origin, d * reach.len, reach.t0, [skip, u32::MAX]) {
            None => f.missed += 1,
            Some((i, _)) => {
                let p = &scene.polygons[i as usize];
                if p.normal.dot(d) < 0.0 {
                    f.front += 1;
                    *f.front_by_object.entry(p.object).or_default() += 1;
                } else {
                    *f.back.entry(p.object).or_default() += 1;
                }
            }
        }
    }
    f
}

/// `n` directions spread evenly over the unit sphere (a Fibonacci lattice).
pub fn sphere_directions(n: usize) -> Vec<DVec3> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|k| {
            let z = 1.0 - (2 * k + 1) as f64 / n as f64;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let a = golden * k as f64;
            DVec3::new(r * a.cos(), r * a.sin(), z)
        })
        .collect()
}

/// The directions of the sphere lattice within `half_angle` of the unit axis `axis`.
pub(crate) fn cone_directions(axis: DVec3, half_angle: f64) -> Vec<DVec3> {
    let c = half_angle.cos();
    sphere_directions(4 * SPHERE_RAYS)
        .into_iter()
        .filter(|d| d.dot(axis) > c.max(1e-3))
        .collect()
}

/// The camera rays of a `CAMERA_GRID`-wide grid over the scene's image: (origin, direction).
fn camera_rays(scene: &Scene) -> Vec<(DVec3, DVec3)> {
    let c = &scene.camera;
    let forward = (c.look_at - c.eye).normalize();
    let right = forward.cross(c.up).normalize();
    let up = right.cross(forward);
    let aspect = scene.width as f64 / scene.height as f64;
    let (nx, ny) = (
        CAMERA_GRID,
        (CAMERA_GRID as f64 / aspect).ceil().max(1.0) as usize,
    );
    let mut rays = Vec::with_capacity(nx * ny);
    for j in 0..ny {
        for i in 0..nx {
            let sx = 2.0 * (i as f64 + 0.5) / nx as f64 - 1.0;
            let sy = 1.0 - 2.0 * (j as f64 + 0.5) / ny as f64;
            rays.push(match c.projection {
                Projection::Perspective { fov_y_deg } => {
                    let t = (0.5 * fov_y_deg.to_radians()).tan();
                    let d = forward + right * (sx * t * aspect) + up * (sy * t);
                    (c.eye, d.normalize())
                }
                Projection::Orthographic { width, height } => {
                    let o = c.eye + right * (0.5 * sx * width) + up * (0.5 * sy * height);
                    (o, forward)
                }
            });
        }
    }
    rays
}

/// The orientation warnings of `scene` (see the module docs), in a fixed order.
pub fn warnings(scene: &Scene) -> Vec<String> {
    if scene.polygons.is_empty() {
        return Vec::new();
    }
    let bvh = Bvh::build(&scene.polygons);
    let (lo, hi) = scene.bounds();
    let (lo, hi) = (lo.min(scene.camera.eye), hi.max(scene.camera.eye));
    let reach = Reach::of(scene, 4.0 * (hi - lo).length().max(1e-9));
    let mut out = Vec::new();
    let object = |o: Option<u32>| {
        o.and_then(|o| scene.objects.get(o as usize))
            .map_or(String::new(), |n| format!("; most in object `{n}`"))
    };
    let view = cast_rays(scene, &bvh, camera_rays(scene).into_iter(), reach, u32::MAX);
    let enclosed = cast(
        scene,
        &bvh,
        scene.camera.eye,
        &sphere_directions(SPHERE_RAYS),
        reach,
        u32::MAX,
    );
    if enclosed.missed == 0 && enclosed.back_share_of_hits() >= 0.9 {
        out.push(format!(
            "the camera at {} is enclosed by the back sides of faces ({:.0} % of the directions \
             around it){}: it is inside a closed object, or in a room whose normals point \
             outward (a modelling tool's cube; flip its normals); the image will be black",
            scene.camera.eye,
            100.0 * enclosed.back_share_of_hits(),
            object(enclosed.worst_object())
        ));
    } else if view.back_share() >= BACK_IN_VIEW_WARN {
        out.push(format!(
            "{:.0} % of the image shows the back side of faces{}: polygons are one-sided (lit \
             on the side their corners turn counter-clockwise around), so the camera sees the \
             light of the other side, black where that side is unlit; flip their normals \
             (winding), or move the camera out from behind them",
            100.0 * view.back_share(),
            object(view.worst_object())
        ));
    }
    let sealed = scene.seals();
    out.extend(light_warnings(scene, &bvh, reach, &sealed));
    out.extend(trapped_lights(scene, &bvh, reach, &sealed));
    out
}

/// Whether polygon `i` has a two-sided material's twin beside it (the loader puts the twin,
/// the same corners wound the other way, right after its original).
fn has_twin(scene: &Scene, i: usize) -> bool {
    let p = &scene.polygons[i];
    let twin = |j: usize| {
        scene.polygons.get(j).is_some_and(|q| {
            q.material == p.material
                && q.normal.dot(p.normal) < -0.999
                && q.vertices().iter().all(|a| p.vertices().contains(a))
        })
    };
    twin(i + 1) || (i > 0 && twin(i - 1))
}

/// Share of an emitter's light (cosine-weighted) landing within its own size of it from which
/// `trapped_lights` warns.
pub const TRAPPED_WARN: f64 = 0.5;

/// Distance, as a share of an emitter's size (its bounding sphere's diameter), within which a
/// surface it faces traps its light (`trapped_lights`). Far less than the size itself: a
/// ceiling lamp as wide as the room is high sends all its light to the floor within its size,
/// and an uplight 20 cm under a ceiling is a design; a panel a few centimetres from what it
/// faces sends its light back and forth between the two.
pub const TRAPPED_GAP: f64 = 0.125;

/// Emitters that face a surface closer than [`TRAPPED_GAP`] of their size, which catches more
/// than [`TRAPPED_WARN`] of their light (a light panel a modelling tool left 2 cm under a ceiling,
/// facing it, because the tool lit both sides): the light bounces between the two, and little
/// reaches the room. One warning per such emitter, naming the surface, for the first few.
///
/// A sealed emitter with faces facing it ([`crate::seal`]: wholly covered by faces lying over
/// it closer than the rays resolve) traps all of its light by construction.
fn trapped_lights(scene: &Scene, bvh: &Bvh, reach: Reach, sealed: &Seals) -> Vec<String> {
    let sphere = sphere_directions(SPHERE_RAYS);
    let mut out = Vec::new();
    let mut more = 0;
    let emitters = (0..scene.polygons.len()).filter(|&i| scene.material_of(i).is_emitter());
    for i in emitters.take(4 * MAX_CHECKED_LIGHTS) {
        let p = &scene.polygons[i];
        let (c, r) = p.bounding_sphere();
        let size = 2.0 * r;
        let gap = TRAPPED_GAP * size;
        let o = c + p.normal * (1e-6 * r.max(1e-9));
        let (mut total, mut near) = (0.0, 0.0);
        let mut by: BTreeMap<u32, f64> = BTreeMap::new();
        let partners = sealed.partners(i as u32);
        if let Some(&q) = partners.first() {
            (total, near) = (1.0, 1.0);
            by.insert(q, 1.0);
        }
        for d in sphere
            .iter()
            .filter(|d| d.dot(p.normal) > 0.0 && !sealed.is_sealed(i as u32))
        {
            let w = d.dot(p.normal);
            total += w;
            let skip = [i as u32, u32::MAX];
            if let Some((q, t)) = bvh.first_hit_from(o, *d * reach.len, reach.t0, skip) {
                if t * reach.len < gap {
                    near += w;
                    *by.entry(q).or_insert(0.0) += w;
                }
            }
        }
        if total <= 0.0 || near < TRAPPED_WARN * total {
            continue;
        }
        if out.len() >= 3 {
            more += 1;
            continue;
        }
        let (q, _) = by.iter().fold(
            (0u32, 0.0f64),
            |b, (&q, &w)| if w > b.1 { (q, w) } else { b },
        );
        let distance = scene.polygons[q as usize]
            .normal
            .dot(c - scene.polygons[q as usize].corners[0]);
        let fix = if has_twin(scene, i) {
            "its material is two-sided: if only the face toward the scene should shine, make \
             it one-sided and turn it to face the scene (a glTF material's `doubleSided`: in \
             Blender, tick the material's Backface Culling before exporting, or map it in the \
             include's `materials` table to a one-sided scene material)"
        } else {
            "a modelling tool that lights both faces of a panel leaves it so: turn it to face \
             the scene (reverse its corners), or give its material `two_sided = true` to emit \
             from both faces"
        };
        let away = if distance.abs() >= 1e-3 * size {
            format!("{:.3}", distance.abs())
        } else {
            format!("{:.1e}", distance.abs())
        };
        let share = if partners.is_empty() {
            format!(
                "{:.0} % of its light lands within {gap:.3} of it, bouncing between the two, \
                 and little reaches the rest of the scene",
                100.0 * near / total
            )
        } else {
            "all of its light lands on it (the two lie face to face closer than rays resolve), \
             bouncing between the two, and none reaches the rest of the scene"
                .to_string()
        };
        out.push(format!(
            "the light {} faces {} {away} away, close for its size ({:.3}): {share}; {fix}",
            scene.origin(i),
            scene.origin(q as usize),
            size,
        ));
    }
    if more > 0 {
        out.push(format!(
            "{more} more lights face a surface close for their size"
        ));
    }
    out
}

/// The lights' part of [`warnings`]: light landing on back sides, emitters facing away.
fn light_warnings(scene: &Scene, bvh: &Bvh, reach: Reach, sealed: &Seals) -> Vec<String> {
    let emitters: Vec<usize> = (0..scene.polygons.len())
        .filter(|&i| scene.material_of(i).is_emitter())
        .collect();
    let total = emitters.len() + scene.spots.len();
    let step = total.div_ceil(MAX_CHECKED_LIGHTS).max(1);
    let sphere = sphere_directions(SPHERE_RAYS);
    let mut lit = Facing::default();
    let mut upside_down = Vec::new();
    // Faces of two-sided emitters whose light all leaves the model (a panel snapped onto a
    // ceiling, lit both ways because the tool marks every material double-sided).
    let mut one_way = Vec::new();
    let mut covered = Vec::new();
    for &i in emitters.iter().step_by(step) {
        // A sealed emitter's rays start past the faces that take all its light: those facing
        // it (`trapped_lights` names it), or the backs of those that do not.
        if sealed.is_sealed(i as u32) {
            if sealed.partners(i as u32).is_empty() {
                covered.push(scene.origin(i));
            }
            continue;
        }
        let p = &scene.polygons[i];
        let (c, r) = p.bounding_sphere();
        let o = c + p.normal * (1e-6 * r.max(1e-9));
        let front: Vec<DVec3> = sphere
            .iter()
            .copied()
            .filter(|d| d.dot(p.normal) > 0.0)
            .collect();
        let back: Vec<DVec3> = sphere
            .iter()
            .copied()
            .filter(|d| d.dot(p.normal) < 0.0)
            .collect();
        let f = cast(scene, bvh, o, &front, reach, i as u32);
        if f.missed == front.len() {
            let b = cast(
                scene,
                bvh,
                c - p.normal * (1e-6 * r.max(1e-9)),
                &back,
                reach,
                i as u32,
            );
            if b.hits() * 2 >= back.len() {
                if has_twin(scene, i) {
                    one_way.push(scene.origin(i));
                } else {
                    upside_down.push(scene.origin(i));
                }
            }
        }
        lit.add(&f);
    }
    let first_spot = emitters.len();
    for (k, s) in scene.spots.iter().enumerate() {
        if !(first_spot + k).is_multiple_of(step) {
            continue;
        }
        let dirs = cone_directions(s.direction, s.half_angle);
        lit.add(&cast(scene, bvh, s.position, &dirs, reach, u32::MAX));
    }
    let mut out = Vec::new();
    if lit.hits() > 0 && lit.back_share_of_hits() >= BACK_LIT_WARN {
        let worst = lit
            .worst_object()
            .and_then(|o| scene.objects.get(o as usize))
            .map_or(String::new(), |n| format!("; most on object `{n}`"));
        out.push(format!(
            "{:.0} % of the light that reaches a surface lands on its back side, which reflects \
             nothing{worst}: a closed room with outward normals (flip them), or lights behind \
             walls",
            100.0 * lit.back_share_of_hits()
        ));
    }
    out.extend(emitter_warnings(&covered, &upside_down, &one_way));
    out
}

/// The warnings naming emitters whose light goes astray (origins of each, the first named):
/// `covered` under a face over them, `upside_down` sending all their light away while their
/// back faces the model, `one_way` the same for a face of a two-sided emitter.
fn emitter_warnings(covered: &[String], upside_down: &[String], one_way: &[String]) -> Vec<String> {
    let mut out = Vec::new();
    if let Some(first) = covered.first() {
        out.push(format!(
            "{} emitting polygon(s) lie under a face closer than rays resolve (or under one on \
             top of them in their plane), whose back takes all their light (first: {first}): is \
             the lamp upside down (reversed winding), sunk a hair behind a surface, or under a \
             face left over it?",
            covered.len()
        ));
    }
    if let Some(first) = upside_down.first() {
        out.push(format!(
            "{} emitting polygon(s) send all their light away from the model while their back \
             faces it (first: {first}): is the lamp upside down (reversed winding)?",
            upside_down.len()
        ));
    }
    if let Some(first) = one_way.first() {
        out.push(format!(
            "{} face(s) of two-sided emitters send all their light away from the model (first: \
             {first}): half of the lamp's light is lost; to light one way, make its material \
             one-sided (Blender: tick the material's Backface Culling; a scene file: \
             two_sided = false)",
            one_way.len()
        ));
    }
    out
}
