//! Sealed faces: polygons lying over others closer than the scene's rays can tell apart.
//!
//! A light panel modelled a hair in front of a wall and facing it (a lamp mounted with its
//! winding reversed), a poster a hair in front of a wall, a rug on a floor: one face lies over
//! another across a gap far below what the rays resolve. Every ray and segment starts past a
//! blind zone of about 1e-7 of the scene's size (so that a polygon touching its origin does not
//! shadow it), and passes straight through the other face. Physically the surface under the
//! cover sees only the cover: the wall under a panel facing it exchanges all its light with the
//! panel, and the wall under a poster (which turns its black back to it) sees nothing at all.
//! Left to the rays, the wall under the panel also lit the room through the panel (light
//! created: 156 % too much in a test room), the panel's light counted as escaping the scene as
//! well, and the wall under a poster reflected the room's light a second time (14 % created).
//!
//! So the loader's contact pass cuts a receiver along the outline of a polygon lying over it
//! however close (module `contact`), and [`sealed`] names the polygons wholly covered by such
//! faces: a *sealed* polygon exchanges light only with the covers that face it (none under a
//! poster), and the light that reaches its covers' backs is absorbed there. The solver culls
//! every other pair, and the rays that account for the light skip what they cannot see.
//!
//! Two polygons in one plane facing one way that overlap (a light panel snapped onto a
//! ceiling, a rug on a floor) are the limit of a gap of zero: the one on top
//! (`crate::coincident::Stacking`) buries the piece of the other under it, as a face a hair in
//! front of it would.
//!
//! Invariants: the result depends only on the polygons and their materials (candidates visited
//! in index order), so it is the same for any thread count; two polygons in one plane facing
//! each other (a two-sided polygon and its reversed twin, a thin wall's two sides) are never
//! sealed: with no gap, they are back to back.

use glam::{DVec2, DVec3};

use crate::bvh::{Aabb, Bvh, T_EPS};
use crate::coincident::{area_abs, clip, diameter, rounding_tolerance, Stacking};
use crate::contact::{Frame, PLANE_TOL};
use crate::Scene;

/// The share of a polygon's area its covers must cover for it to be sealed: the contact cut
/// places a piece's corners within `contact::SNAP` (1e-4) of the polygon's size of the cover's
/// outline, so a piece under a cover is covered to within about that.
pub const SEALED_COVER: f64 = 0.999;

/// The rays' blind zone the seal must reach past, as a share of the scene's core diagonal: the
/// solver's and the path tracer's rays start [`Scene::ray_t0`] along rays up to four scene
/// diagonals long (4 `T_EPS` of the core), the checks' a little longer with the camera beyond
/// the scene; twice that.
pub const SEAL_REACH: f64 = 8.0 * T_EPS;

/// The largest gap at which a face of size `a` covering one of size `b` counts as sealing it,
/// in a scene whose core diagonal is `core`: the contact pass's plane tolerance ([`PLANE_TOL`]
/// of the larger face) or the rays' blind zone ([`SEAL_REACH`]), whichever is larger.
pub fn seal_gap(a: f64, b: f64, core: f64) -> f64 {
    (PLANE_TOL * a.max(b)).max(SEAL_REACH * core)
}

/// What lies over a polygon's front closer than rays resolve ([`Polygon::sealed`]): what the
/// renderers need to know of its seal.
///
/// [`Polygon::sealed`]: crate::Polygon::sealed
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum Sealed {
    /// Nothing: it is drawn from either side.
    #[default]
    Open,
    /// Faces facing it (a light panel a hair in front of a wall, facing it): every eye in
    /// front of the polygon sees their backs first, so it is drawn only from behind.
    Faced,
    /// Faces turning their backs to it, over most of its area (the wall under a poster or a
    /// lamp mounted flush): hidden from every eye in front of it whether or not back faces are
    /// drawn, and it takes and gives no light; an export leaves it out.
    Buried,
}

impl Sealed {
    /// Whether an eye on the polygon's front side sees its covers instead of it.
    pub fn hidden_from_front(self) -> bool {
        self != Sealed::Open
    }
}

/// The sealed polygons of a scene ([`sealed`]), and those backed by a face in their plane.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Seals {
    /// Per polygon: `None` if it is not sealed; else the covers that face it (ascending,
    /// possibly none) and the share of its covered area under covers that turn their backs
    /// to it.
    of: Vec<Option<(Vec<u32>, f64)>>,
    /// Per polygon: whether faces in its plane turned the other way cover it (its two-sided
    /// twin, a thin wall's other side), so that from behind they show instead of it.
    backed: Vec<bool>,
}

impl Seals {
    /// Whether faces in polygon `p`'s plane, turned the other way, cover it: back to back with
    /// it (its two-sided twin, a thin wall's other side), they show instead of it from behind.
    pub fn is_backed(&self, p: u32) -> bool {
        self.backed.get(p as usize).copied().unwrap_or(false)
    }

    /// Whether polygon `p` is sealed.
    pub fn is_sealed(&self, p: u32) -> bool {
        self.of.get(p as usize).is_some_and(Option::is_some)
    }

    /// The faces sealed polygon `p` exchanges light with (empty if it is not sealed, or if
    /// every cover turns its back to it).
    pub fn partners(&self, p: u32) -> &[u32] {
        match self.of.get(p as usize) {
            Some(Some((l, _))) => l,
            _ => &[],
        }
    }

    /// The share of sealed polygon `p`'s light that lands on the backs of its covers (0 if it
    /// is not sealed).
    pub fn behind(&self, p: u32) -> f64 {
        match self.of.get(p as usize) {
            Some(Some((_, b))) => *b,
            _ => 0.0,
        }
    }

    /// How polygon `p` is sealed: `Buried` where covers turned away from it cover more of it
    /// than covers facing it.
    pub fn kind(&self, p: u32) -> Sealed {
        match self.of.get(p as usize) {
            Some(Some((_, b))) if *b > 0.5 => Sealed::Buried,
            Some(Some(_)) => Sealed::Faced,
            _ => Sealed::Open,
        }
    }

    /// Whether light may pass between polygons `a` and `b` (either `u32::MAX`: a spot light):
    /// not when either is sealed and the other is not one of its partners.
    pub fn may_exchange(&self, a: u32, b: u32) -> bool {
        let admits =
            |x: u32, y: u32| !self.is_sealed(x) || self.partners(x).binary_search(&y).is_ok();
        admits(a, b) && admits(b, a)
    }
}

/// How a cover lies over a polygon.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Cover {
    /// Facing it: the two exchange light.
    Facing,
    /// Turning its back to it: the cover's back takes the polygon's light and gives none.
    Backing,
    /// In its plane, back to back with it (a two-sided polygon's reversed twin, a thin wall's
    /// other side): no light passes between them, and from behind the polygon the cover's
    /// front is what shows.
    BackToBack,
}

/// The sealed polygons of `scene`: those whose covers (polygons parallel to them, in front of
/// them by more than rounding and at most [`seal_gap`], facing them or turning their backs to
/// them, or in their plane facing their way and on top of them) cover at least
/// [`SEALED_COVER`] of them, projected onto their plane.
pub fn sealed(scene: &Scene) -> Seals {
    let polygons = &scene.polygons;
    let mut out = Seals {
        of: vec![None; polygons.len()],
        backed: vec![false; polygons.len()],
    };
    if polygons.len() < 2 {
        return out;
    }
    let core = scene.core_diagonal();
    let bvh = Bvh::build(polygons);
    let stacking = Stacking::of(polygons, &scene.materials);
    // A cover lies over `p` within the gap of the larger of the two, so its box meets p's
    // grown by the gap the scene's largest polygon may leave.
    let largest = polygons.iter().map(diameter).fold(0.0, f64::max);
    for (i, p) in polygons.iter().enumerate() {
        let grow = seal_gap(diameter(p), largest, core);
        let b = Aabb::of(p.vertices());
        let b = Aabb {
            lo: b.lo - DVec3::splat(grow),
            hi: b.hi + DVec3::splat(grow),
        };
        let mut near = Vec::new();
        bvh.for_each_overlapping(&b, |q| {
            if q as usize != i {
                near.push(q);
            }
        });
        near.sort_unstable();
        let frame = Frame::of(p);
        let flat: Vec<DVec2> = p.vertices().iter().map(|v| frame.to2(*v)).collect();
        let (mut partners, mut facing, mut backing, mut back) = (Vec::new(), 0.0, 0.0, 0.0);
        for q in near {
            match cover(scene, (i, q as usize), (core, &stacking), (&frame, &flat)) {
                Some((Cover::Facing, a)) => {
                    partners.push(q);
                    facing += a;
                }
                Some((Cover::Backing, a)) => backing += a,
                Some((Cover::BackToBack, a)) => back += a,
                None => {}
            }
        }
        out.backed[i] = back >= SEALED_COVER * p.area;
        if facing + backing >= SEALED_COVER * p.area {
            let behind = (backing / (facing + backing)).clamp(0.0, 1.0);
            out.of[i] = Some((partners, behind));
        }
    }
    out
}

/// How polygon `q` covers polygon `i`, and the area it covers, if it lies over it within the
/// seal gap: parallel (facing it or turning its back to it), every corner in front of `i` by
/// more than rounding and at most the gap (or, facing its way, every corner in its plane and
/// `q` on top in the `stacking` order), covering a positive share of it.
fn cover(
    scene: &Scene,
    (i, q): (usize, usize),
    (core, stacking): (f64, &Stacking),
    (frame, flat): (&Frame, &[DVec2]),
) -> Option<(Cover, f64)> {
    let (p, qp) = (&scene.polygons[i], &scene.polygons[q]);
    let c = p.normal.dot(qp.normal);
    let kind = if c < -(1.0 - 1e-9) {
        Cover::Facing
    } else if c > 1.0 - 1e-9 {
        Cover::Backing
    } else {
        return None;
    };
    let gap = seal_gap(diameter(p), diameter(qp), core);
    let tiny = rounding_tolerance(p.vertices().iter().chain(qp.vertices()).copied());
    let height = |v: DVec3| p.normal.dot(v - p.corners[0]);
    let over = |v: &DVec3| {
        let h = height(*v);
        h > tiny && h <= gap
    };
    let in_plane = qp.vertices().iter().all(|v| height(*v).abs() <= tiny);
    let kind = match kind {
        Cover::Facing if in_plane => Cover::BackToBack,
        Cover::Backing if in_plane && stacking.over(q, i) => kind,
        _ if qp.vertices().iter().all(over) => kind,
        _ => return None,
    };
    let footprint: Vec<DVec2> = qp.vertices().iter().map(|v| frame.to2(*v)).collect();
    let a = area_abs(&clip(&footprint, flat));
    (a > 0.0).then_some((kind, a))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Camera, Material, Polygon, Projection};

    fn quad(c: [[f64; 3]; 4]) -> Polygon {
        Polygon::quad(c.map(DVec3::from_array), 0, 0).expect("quad")
    }

    fn scene_of(polygons: Vec<Polygon>) -> Scene {
        let camera = Camera {
            eye: DVec3::new(1.0, 1.0, 5.0),
            look_at: DVec3::ONE,
            up: DVec3::Y,
            projection: Projection::Perspective { fov_y_deg: 45.0 },
        };
        let m = Material {
            name: "white".into(),
            reflectance: DVec3::splat(0.5),
            emission: DVec3::ZERO,
        };
        Scene::new(camera, 8, 8, vec![m], polygons)
    }

    /// The 1 x 1 square of the plane x = `x` over y, z in [0.5, 1.5], facing +x if `plus`.
    fn square(x: f64, plus: bool) -> Polygon {
        let mut c = [[x, 0.5, 0.5], [x, 1.5, 0.5], [x, 1.5, 1.5], [x, 0.5, 1.5]];
        let p = quad(c);
        if (p.normal.x > 0.0) != plus {
            c.reverse();
            return quad(c);
        }
        p
    }

    /// A 2 m room's right wall: x = 2, facing into the room (-x).
    fn right_wall() -> Polygon {
        quad([
            [2.0, 0.0, 0.0],
            [2.0, 0.0, 2.0],
            [2.0, 2.0, 2.0],
            [2.0, 2.0, 0.0],
        ])
    }

    /// A 2 m room's right wall (x = 2, facing into the room) and a square panel `gap` in front
    /// of it facing it: the panel is sealed with the wall at every gap up to the seal gap; the
    /// wall, covered a quarter, is not.
    #[test]
    fn a_panel_facing_a_wall_a_hair_away_is_sealed_with_it() {
        let wall = right_wall();
        assert!(wall.normal.x < 0.0);
        for gap in [1e-10, 1e-9, 1e-7, 1e-6] {
            let l = sealed(&scene_of(vec![wall.clone(), square(2.0 - gap, true)]));
            assert!(!l.is_sealed(0) && l.is_sealed(1), "gap {gap}: {l:?}");
            assert_eq!((l.partners(1), l.behind(1)), (&[0][..], 0.0));
            assert_eq!((l.kind(0), l.kind(1)), (Sealed::Open, Sealed::Faced));
            assert!(!l.may_exchange(1, u32::MAX) && l.may_exchange(0, u32::MAX));
        }
        // The piece of the wall under the panel (what the contact cut leaves) and the panel
        // are sealed with each other; the rest of the wall exchanges with the panel only.
        let piece = square(2.0, false);
        let l = sealed(&scene_of(vec![piece, square(2.0 - 1e-9, true), wall]));
        assert_eq!((l.partners(0), l.partners(1)), (&[1][..], &[0, 2][..]));
        assert!(!l.is_sealed(2));
        assert!(l.may_exchange(0, 1) && l.may_exchange(1, 0) && l.may_exchange(1, 2));
        assert!(!l.may_exchange(0, 2) && !l.may_exchange(2, 0));
    }

    /// A poster a hair in front of a wall, facing the room: the piece of the wall under it is
    /// sealed with nothing (the poster's back takes all of its light), the poster is free.
    #[test]
    fn the_wall_under_a_poster_is_sealed_with_nothing() {
        let piece = square(2.0, false);
        let l = sealed(&scene_of(vec![piece, square(2.0 - 1e-9, false)]));
        assert!(l.is_sealed(0) && !l.is_sealed(1), "{l:?}");
        assert!(l.partners(0).is_empty() && l.behind(0) == 1.0);
        assert_eq!((l.kind(0), l.kind(1)), (Sealed::Buried, Sealed::Open));
        // The loader's marks, and the seals kept for the polygons they were found for only.
        let mut s = scene_of(vec![square(2.0, false), square(2.0 - 1e-9, false)]);
        s.mark_sealed();
        assert_eq!(s.polygons[0].sealed, Sealed::Buried);
        assert!(s.seals().is_sealed(0));
        s.polygons[1] = square(2.0 - 1e-3, false);
        assert!(!s.seals().is_sealed(0), "found again for the moved poster");
        assert!(!l.may_exchange(0, 1) && !l.may_exchange(1, 0) && l.may_exchange(1, u32::MAX));
    }

    /// Faces that are not a hair apart one over the other are never sealed: a polygon and its
    /// reversed twin in one plane (a two-sided surface: back to back), the same faces farther
    /// apart than the seal gap (the rays resolve them), and faces behind it.
    #[test]
    fn only_faces_a_hair_over_another_are_sealed() {
        let none = |polys: Vec<Polygon>| {
            let l = sealed(&scene_of(polys));
            assert!(!l.is_sealed(0) && !l.is_sealed(1), "{l:?}");
        };
        none(vec![square(2.0, false), square(2.0, true)]);
        none(vec![square(2.0, false), square(2.0 - 1e-3, true)]);
        none(vec![square(2.0, false), square(2.0 - 1e-3, false)]);
        none(vec![square(2.0, false), square(2.0 + 1e-9, true)]);
        assert!(seal_gap(1.0, 1.0, 3.0) < 1e-5);
    }

    /// Two faces in one plane facing one way, one over the other (a light panel snapped onto a
    /// ceiling, a rug on a floor): the one on top buries the other, as a face a hair in front
    /// would. On top: the emitter, else the smaller object, else the one listed later.
    #[test]
    fn a_face_on_top_in_anothers_plane_buries_it() {
        let wall = right_wall();
        let on_wall = square(2.0, false);
        let mut lamp = scene_of(vec![wall.clone(), on_wall.clone()]);
        lamp.materials.push(Material {
            name: "lamp".into(),
            reflectance: DVec3::ZERO,
            emission: DVec3::ONE,
        });
        // The piece of the wall under the square and the square, both of object 0.
        let piece = square(2.0, false);
        let kinds = |s: &Scene| {
            (0..s.polygons.len() as u32)
                .map(|i| s.seals().kind(i))
                .collect::<Vec<_>>()
        };
        let both = |first: Polygon, second: Polygon| {
            let mut s = lamp.clone();
            s.polygons = vec![first, second];
            kinds(&s)
        };
        use Sealed::{Buried, Open};
        // Same object, no emitter: the later one lies on top.
        assert_eq!(both(piece.clone(), on_wall.clone()), [Buried, Open]);
        // The emitter lies on top, listed first or last.
        let mut lit = on_wall.clone();
        lit.material = 1;
        assert_eq!(both(lit.clone(), piece.clone()), [Open, Buried]);
        assert_eq!(both(piece.clone(), lit), [Buried, Open]);
        // The smaller object lies on top: the wall's other pieces make its object larger.
        let mut s = lamp.clone();
        let mut poster = on_wall.clone();
        poster.object = 1;
        s.polygons = vec![poster, piece.clone(), wall];
        s.polygons[2].object = 0;
        assert_eq!(kinds(&s)[..2], [Open, Buried]);
        // Faces in one plane facing each other are back to back, neither on top: each shows
        // instead of the other from behind it. A quarter of the wall is not backed by it.
        assert_eq!(both(piece.clone(), square(2.0, true)), [Open, Open]);
        s.polygons = vec![piece, square(2.0, true), s.polygons[2].clone()];
        let l = s.seals();
        assert!(l.is_backed(0) && l.is_backed(1) && !l.is_backed(2), "{l:?}");
    }
}
