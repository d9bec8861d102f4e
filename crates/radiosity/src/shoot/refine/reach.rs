//! The refinement's depth rules past its guards: how far below the smallest element a leaf may
//! split near a light (its distance and size), across a spot's cone edge, and beside the outline
//! of a polygon lying close over its polygon (the ramp of light there is as narrow as the gap).
//! The error tests of the parent module still decide each split; these only say how deep one
//! may go.

use glam::DVec3;
use scene::Scene;

/// How many times finer than the distance to a light (from its centre, plus its radius) a leaf
/// may be split past the guards (`Refinement::may_split`): the light of a small source at
/// distance h varies over about h, and elements of h / 4 hold an emitter 2 cm over a floor to
/// 0.8 % of its peak and 0.9 % of its energy (`a_small_close_emitter_is_resolved_at_the_default_depth`);
/// h / 8 gains 0.4 % there and doubles the generated building's solve (its ceiling panels light
/// the walls beside them).
pub(crate) const LIGHT_DEPTH_FACTOR: f64 = 4.0;

/// How many times finer than the radius of its footprint (its distance times the tangent of
/// its cone's half-angle, at most the distance) a leaf that a spot's cone edge crosses may be
/// split past the guards. The edge is a step the bicubic patches smear over about one element,
/// moving the footprint's light by roughly a sixth of the element over the radius: a spot 1 cm
/// from a wall (footprint 5.8 mm across) drew 3.9 % too much light at elements of a quarter of
/// its distance, within 0.1 % at a sixteenth of the footprint
/// (`a_spot_one_centimetre_from_a_wall_peaks_within_two_percent`).
pub(crate) const SPOT_EDGE_FACTOR: f64 = 16.0;

/// A light as the refinement's depth rule sees it: a sphere, and for a spot its cone.
pub(super) struct LightReach {
    centre: DVec3,
    radius: f64,
    /// A spot's axis, the cosine of its half-angle and the tangent of the half-angle (at
    /// most 1).
    cone: Option<(DVec3, f64, f64)>,
}

/// Every emitter as its bounding sphere, every spot as its position with its cone.
pub(super) fn light_reaches(scene: &Scene) -> Vec<LightReach> {
    let mut out: Vec<LightReach> = scene
        .spots
        .iter()
        .map(|s| LightReach {
            centre: s.position,
            radius: 0.0,
            cone: Some((
                s.direction,
                s.half_angle.cos(),
                s.half_angle.tan().clamp(1e-6, 1.0),
            )),
        })
        .collect();
    for (i, p) in scene.polygons.iter().enumerate() {
        if scene.material_of(i).is_emitter() {
            let (centre, radius) = p.bounding_sphere();
            out.push(LightReach {
                centre,
                radius,
                cone: None,
            });
        }
    }
    out
}

impl LightReach {
    /// Whether a leaf whose longer edge is `edge`, centred at `centre`, with world corners
    /// `corners`, may split for this light: its edge is more than 1 / [`LIGHT_DEPTH_FACTOR`]
    /// of the distance to the light plus its radius, or, for a spot whose cone's edge crosses
    /// the leaf (its corners lie on both sides), more than 1 / [`SPOT_EDGE_FACTOR`] of the
    /// footprint's radius.
    pub(super) fn reaches(&self, edge: f64, centre: DVec3, corners: &[DVec3; 4]) -> bool {
        let dist = (self.centre - centre).length();
        if LIGHT_DEPTH_FACTOR * edge > dist + self.radius {
            return true;
        }
        let Some((_, _, spread)) = self.cone else {
            return false;
        };
        if SPOT_EDGE_FACTOR * edge <= dist * spread {
            return false;
        }
        self.edge_crosses(corners)
    }

    /// Whether this light is a spot whose cone's edge crosses the leaf with world corners
    /// `corners` (they lie on both sides of it).
    pub(super) fn edge_crosses(&self, corners: &[DVec3; 4]) -> bool {
        let Some((axis, cos, _)) = self.cone else {
            return false;
        };
        let inside = |x: &DVec3| (*x - self.centre).normalize_or_zero().dot(axis) >= cos;
        let first = inside(&corners[0]);
        corners[1..].iter().any(|x| inside(x) != first)
    }
}

/// An outline a polygon lying close over a receiver casts on it (`scene::contact`), as the
/// refinement's depth rule sees it: beside the outline the light climbs from the shadow's
/// half to the open value over a few gaps, a ramp as narrow as the light of an emitter that
/// close (a 0.5 m lamp 1 cm under a ceiling: 54 % of the ceiling's light 2 cm out at 0.75 mm,
/// 90 % at 1 cm, `the_ceiling_beside_a_lamp_hung_under_it_follows_its_ramp`).
pub(super) struct StepReach {
    a: DVec3,
    b: DVec3,
    gap: f64,
}

impl StepReach {
    /// Whether a leaf whose longer edge is `edge`, centred at `centre`, may split for this
    /// outline: it lies within [`STEP_REACH_GAPS`] gaps of the outline and its edge is more
    /// than 1 / [`STEP_DEPTH_FACTOR`] of its distance to the outline plus the gap (so the
    /// leaves along the outline come down to about a gap wide, and widen away from it).
    pub(super) fn reaches(&self, edge: f64, centre: DVec3) -> bool {
        let d = self.b - self.a;
        let t =
            ((centre - self.a).dot(d) / d.length_squared().max(f64::MIN_POSITIVE)).clamp(0.0, 1.0);
        // The leaf's nearest point to the outline, about.
        let near =
            ((self.a + d * t).distance(centre) - std::f64::consts::FRAC_1_SQRT_2 * edge).max(0.0);
        near <= STEP_REACH_GAPS * self.gap && STEP_DEPTH_FACTOR * edge > near + self.gap
    }
}

/// Per polygon, the outlines lying in its plane whose ramps may reach it: within a few gaps of
/// its box (the ramp has fallen below the tolerance by then).
pub(super) fn step_reaches(scene: &Scene) -> Vec<Vec<StepReach>> {
    let mut out: Vec<Vec<StepReach>> = (0..scene.polygons.len()).map(|_| Vec::new()).collect();
    let steps: Vec<(DVec3, DVec3, f64)> = scene
        .contacts
        .lines
        .iter()
        .filter_map(|l| match l.kind {
            scene::contact::LineKind::Outline { gap } if gap > 0.0 => Some((l.a, l.b, gap)),
            _ => None,
        })
        .collect();
    if steps.is_empty() {
        return out;
    }
    for (r, p) in scene.polygons.iter().enumerate() {
        let (lo, hi) = p.vertices().iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), v| (lo.min(*v), hi.max(*v)),
        );
        for &(a, b, gap) in &steps {
            let reach = STEP_REACH_GAPS * gap;
            let (slo, shi) = (
                a.min(b) - DVec3::splat(reach),
                a.max(b) + DVec3::splat(reach),
            );
            let in_plane = [a, b]
                .iter()
                .all(|x| p.normal.dot(*x - p.corners[0]).abs() <= 1e-6 * (hi - lo).length());
            if in_plane && slo.cmple(hi).all() && lo.cmple(shi).all() {
                out[r].push(StepReach { a, b, gap });
            }
        }
    }
    out
}

/// How many times finer than its distance to an outline plus the gap a leaf may be split past
/// the guards ([`StepReach::reaches`]). Twice as fine (judged by the leaf's centre) brought the
/// Cornell box's direct image 6 % closer to its exact evaluation and the gallery's no closer,
/// for 4 % and 40 % more solve time.
const STEP_DEPTH_FACTOR: f64 = 1.0;

/// How many levels past its guard depth a leaf beside an outline may split: enough to bring
/// the shipped scenes' guard elements (2.7 cm on the Cornell box, about 30 cm on the gallery
/// and the generated buildings) down to about the 1 cm gap of their lamps, and no further
/// when a coarse solve (a low `max_depth`) makes the guard elements large: there the ramp is
/// followed only as far as the coarse solve follows anything.
pub(super) const STEP_LEVELS: u32 = 5;

/// How many gaps from an outline its ramp is followed past the guards ([`step_reaches`]): the
/// share of the open light a point `x` from the outline misses falls about as `(gap / x)^2 / 4`,
/// 1.6 % at four gaps, where the guards' elements take over.
const STEP_REACH_GAPS: f64 = 4.0;
