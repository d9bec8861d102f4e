//! The triangle fast path: geometry and setup fused for a triangle that needs no clipping (every
//! corner in front of the near plane and inside the guard band), the common case of a mesh of
//! 10^5 triangles, where the general path's per-polygon costs (a clipped vertex list, a screen
//! polygon record passed between the stages, a vertex list for the snap) are most of a frame.
//!
//! Invariant: for every triangle it accepts, the record it writes is the one the general path
//! ([`super::geometry::View::transform`] then [`super::setup::setup_into`]) writes, bit for bit,
//! and it rejects exactly the triangles the general path rejects: it evaluates the same functions
//! on the same inputs (pure functions: it tests the cheap rejections first, the general path
//! last), and hands every case it does not cover (a corner behind
//! the near plane or beyond the guard band) back to the general path. A test holds it to this on
//! random triangles and views.

use scene::{Polygon, Shape};

use super::geometry::{barycentric_duals, PlaneView, View, GUARD_BAND};
use super::setup::Prim;
use super::setup::{edge, edges_fit_i32, pixel_box, snap, BilinearInverse, Edge, InverseKind};

/// What the fast path did with a triangle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Outcome {
    /// Set up into the record.
    Set,
    /// Reaches no sample (or culled): the caller marks the record empty.
    Rejected,
    /// Needs clipping: the caller runs the general path.
    General,
}

/// Geometry and setup of triangle `poly` (scene polygon `id`) into `out`, or [`Outcome::General`]
/// when it needs clipping; with `cull`, a triangle facing away is rejected, as is a sealed one
/// facing the camera or a backed one facing away ([`super::geometry::culled`]).
pub(crate) fn triangle_into(
    view: &View,
    poly: &Polygon,
    id: u32,
    cull: bool,
    out: &mut Prim,
) -> Outcome {
    debug_assert_eq!(poly.shape, Shape::Triangle);
    // Arrays written out rather than `map`ped: `map` stayed an out-of-line call here, whose
    // results came back through memory in narrower stores than the loads that read them (a
    // store-forwarding stall per triangle; the same below for the projected and snapped
    // points).
    let c = &poly.corners;
    let cv = [
        view.view_coords(c[0]),
        view.view_coords(c[1]),
        view.view_coords(c[2]),
    ];
    let near = view.near();
    if cv.iter().all(|p| p.z < near) {
        return Outcome::Rejected;
    }
    if !cv.iter().all(|p| p.z - near >= 0.0) {
        return Outcome::General;
    }
    let c0 = cv[0];
    let PlaneView {
        n,
        d,
        size_bound,
        front_facing,
    } = view.plane_view(poly, c0);
    // The cheap rejections first (culled, off screen, covering no sample: a sixth of a mesh
    // in a typical view), the per-pixel expressions only for a triangle that is drawn.
    if super::geometry::culled(cull, poly, front_facing) {
        return Outcome::Rejected;
    }
    let verts = [
        view.project(cv[0]),
        view.project(cv[1]),
        view.project(cv[2]),
    ];
    match screen_outcome(&verts, view.size()) {
        Outcome::Set => {}
        other => return other,
    }
    if !setup_triangle(&verts, view.size(), out) {
        return Outcome::Rejected;
    }
    let Some((m1, m2)) = barycentric_duals(n, cv[1] - c0, cv[2] - c0) else {
        return Outcome::Rejected;
    };
    let size = (size_bound, || super::geometry::corner_size(poly));
    let Some(planes) = view.pixel_planes(n, d, c0, size, m1, m2) else {
        return Outcome::Rejected;
    };
    out.id = id;
    out.planes = planes;
    out.inverse = BilinearInverse {
        triangle: true,
        ..BilinearInverse::default()
    };
    out.kind = InverseKind::Triangle;
    out.perspective = view.is_perspective();
    Outcome::Set
}

/// The general path's screen tests on unclipped vertices: rejected when entirely beyond one side
/// of the image, handed back when a vertex lies beyond the guard band (it clips there), rejected
/// when a vertex is not finite; [`Outcome::Set`] when setup may go on.
fn screen_outcome(verts: &[[f64; 2]; 3], (width, height): (u32, u32)) -> Outcome {
    let (w, h) = (width as f64, height as f64);
    if verts.iter().all(|p| p[0] < 0.0)
        || verts.iter().all(|p| p[0] > w)
        || verts.iter().all(|p| p[1] < 0.0)
        || verts.iter().all(|p| p[1] > h)
    {
        return Outcome::Rejected;
    }
    let (lo_x, hi_x) = (-GUARD_BAND, w + GUARD_BAND);
    let (lo_y, hi_y) = (-GUARD_BAND, h + GUARD_BAND);
    let inside = |p: &[f64; 2]| p[0] >= lo_x && p[0] <= hi_x && p[1] >= lo_y && p[1] <= hi_y;
    if !verts.iter().all(inside) {
        return Outcome::General;
    }
    if !verts.iter().all(|p| p[0].is_finite() && p[1].is_finite()) {
        return Outcome::Rejected;
    }
    Outcome::Set
}

/// The setup of three screen vertices (inside the guard band): snapped, rejected when two
/// coincide or the snapped area is zero, wound counter-clockwise, edges and pixel box written
/// into `out`. Returns whether the triangle covers a pixel of the image.
fn setup_triangle(verts: &[[f64; 2]; 3], (width, height): (u32, u32), out: &mut Prim) -> bool {
    let s = |p: [f64; 2]| [snap(p[0]), snap(p[1])];
    let mut pts = [s(verts[0]), s(verts[1]), s(verts[2])];
    if pts[0] == pts[1] || pts[1] == pts[2] || pts[2] == pts[0] {
        return false;
    }
    // Twice the signed area, exact: coordinates stay below 2^26 in the guard band, so each
    // product stays below 2^54.
    let cross = (pts[1][0] - pts[0][0]) * (pts[2][1] - pts[0][1])
        - (pts[1][1] - pts[0][1]) * (pts[2][0] - pts[0][0]);
    if cross == 0 {
        return false;
    }
    if cross < 0 {
        pts.reverse();
    }
    let Some(bbox) = pixel_box(&pts, width, height) else {
        return false;
    };
    // Written in place (a local array assigned whole was a 180-byte copy per triangle); the
    // unused edges are the constant 0, as every record's are.
    for i in 0..3 {
        out.edges[i] = edge(pts[i], pts[(i + 1) % 3]);
    }
    out.edges[3..].fill(Edge::default());
    out.n_edges = 3;
    out.bbox = bbox;
    out.i32_edges = edges_fit_i32(&out.edges[..3], bbox);
    true
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::raster::setup::setup;
    use base::rng::Rng;
    use glam::DVec3;
    use scene::{Camera, Projection};

    fn random_point(rng: &mut Rng, scale: f64) -> DVec3 {
        DVec3::new(
            (rng.next_f64() - 0.5) * scale,
            (rng.next_f64() - 0.5) * scale,
            (rng.next_f64() - 0.5) * scale,
        )
    }

    /// The fast path writes the general path's record bit for bit and rejects what it rejects,
    /// on random triangles (from 1e-7 to 1e12 across, grazing, partly behind the eye, beyond
    /// the image) seen
    /// by random perspective and orthographic cameras, culling on and off.
    #[test]
    fn the_triangle_path_matches_the_general_path_bit_for_bit() {
        let mut rng = Rng::new(7);
        let (mut set, mut rejected, mut general) = (0, 0, 0);
        for case in 0..20_000 {
            let projection = if case % 5 == 0 {
                Projection::Orthographic {
                    width: 2.0 + 6.0 * rng.next_f64(),
                    height: 2.0 + 6.0 * rng.next_f64(),
                }
            } else {
                Projection::Perspective {
                    fov_y_deg: 20.0 + 120.0 * rng.next_f64(),
                }
            };
            let camera = Camera {
                eye: random_point(&mut rng, 8.0),
                look_at: random_point(&mut rng, 2.0),
                up: DVec3::Y,
                projection,
            };
            let (w, h) = (
                1 + (rng.next_f64() * 96.0) as u32,
                1 + (rng.next_f64() * 96.0) as u32,
            );
            let Ok(view) = View::new(&camera, w, h, 10.0, 1e-3) else {
                continue;
            };
            let scale = [1e-7, 0.01, 1.0, 6.0, 1e4, 1e12][case % 6];
            let a = random_point(&mut rng, 6.0);
            let Some(poly) = Polygon::triangle(
                [
                    a,
                    a + random_point(&mut rng, scale),
                    a + random_point(&mut rng, scale),
                ],
                0,
                0,
            ) else {
                continue;
            };
            let cull = case % 3 == 0;
            let want = view
                .transform(&poly, 5)
                .filter(|sp| !cull || sp.front_facing)
                .and_then(|sp| setup(&sp, w, h));
            let mut got = Prim::default();
            match triangle_into(&view, &poly, 5, cull, &mut got) {
                Outcome::Set => {
                    set += 1;
                    let want = want.expect("the general path sets it up too");
                    assert_eq!(format!("{got:?}"), format!("{want:?}"), "case {case}");
                }
                Outcome::Rejected => {
                    rejected += 1;
                    assert!(want.is_none(), "case {case}: the general path sets it up");
                }
                Outcome::General => general += 1,
            }
        }
        // Every outcome is exercised.
        assert!(
            set > 1000 && rejected > 1000 && general > 100,
            "{set} {rejected} {general}"
        );
    }
}
