//! Geometry: the first stage of the renderer. It turns each scene polygon into a screen-space
//! convex polygon plus the plane equations the rasterizer evaluates per pixel: the camera's view
//! transform and projection (perspective or orthographic, any aspect ratio), clipping against the
//! near plane in view space (so polygons crossing the eye plane render correctly), clipping against
//! a guard band far outside the image in screen space (so fixed-point edge functions cannot
//! overflow), and the back-face policy.
//!
//! Per pixel the rasterizer needs the depth and the polygon's (u, v). Neither is linear in screen
//! space under perspective, so this stage hands it linear expressions from which both follow
//! exactly: with the pixel's view ray P(px, py, w) = O(px, py) + w D(px, py) (perspective: O = 0;
//! orthographic: D = forward), the polygon's plane gives a quantity Q linear in (px, py) that is
//! 1/w (perspective) or w itself (orthographic), and the point's 2-D coordinates (s, t) in an
//! orthonormal frame of the polygon's plane are `Sa + w Sb`, `Ta + w Tb` with Sa, Sb, Ta, Tb linear
//! in (px, py). These are derived analytically from the unclipped polygon's plane, so clipping never
//! perturbs them. The rasterizer then inverts the polygon's bilinear map in that 2-D frame.
//!
//! Clip vertices on an edge shared by two polygons must be bit-identical in both, or the snapped
//! edges would differ and leave cracks: every intersection is computed from the edge's endpoints
//! in a canonical (lexicographic) order, whichever polygon asks.
//!
//! Back faces are NOT culled by default. Radiosity surfaces are one-sided, but they are also
//! opaque: culling a polygon seen from behind would let the viewer see through it, which is worse
//! than showing it with the radiosity of its front side (the only one the solver computes). In
//! closed scenes seen from inside (the Cornell box) every back face is hidden behind front faces, so
//! the default changes no pixel there; [`crate::frame::FrameOptions::cull_back_faces`] turns culling
//! on to save raster work in such scenes.
//!
//! A sealed polygon (`scene::seal`: faces lie over its front closer than the depth buffer or
//! any ray resolves, a lamp mounted flush on a wall) is left out where it faces the camera:
//! there its covers are in front of it, but their depths tie with its own, and the tie would
//! go to whichever polygon comes first (the dark wall under the lamp, drawn over the lamp).
//! From behind it is drawn as any polygon is (`culled`). The same tie at two faces back to
//! back in one plane (a two-sided polygon and its reversed twin, which the loader makes of a
//! two-sided material: every material of a glTF file from Blender) went to the first listed
//! whichever way it faced, so a room whose walls face outward, made two-sided, drew as the
//! black backs of its walls: a polygon backed by such a face is left out where it faces away.

use glam::DVec3;
use smallvec::SmallVec;

use base::error::{Error, Result};
use scene::{Camera, Polygon, Projection, Shape};

/// Whether polygon `p`, facing the camera if `front_facing`, is left out of a frame: seen from
/// in front when faces lying over it hide it (`Polygon::sealed`), seen from behind when back
/// faces are culled (`cull_back`) or a face back to back with it shows there instead
/// (`Polygon::backed`).
#[inline(always)]
pub(crate) fn culled(cull_back: bool, p: &Polygon, front_facing: bool) -> bool {
    if front_facing {
        p.sealed.hidden_from_front()
    } else {
        cull_back || p.backed
    }
}

/// Guard band, in pixels beyond each image edge: screen polygons are clipped to it, which bounds
/// fixed-point coordinates to below 2^26 (8 subpixel bits) and edge functions to below 2^56.
pub(crate) const GUARD_BAND: f64 = 65536.0;

/// Largest near plane distance relative to the scene's extent (perspective cameras).
pub(crate) const NEAR_RELATIVE: f64 = 1e-4;

/// Smallest near plane distance relative to the scene's extent: where the eye touches a
/// polygon. Depth is interpolated as 1/w in floating point, whose relative precision is the
/// same at every distance, so a small near plane costs no depth resolution. 1e-12 keeps the
/// near plane 1e4 times above the rounding of f64 view coordinates at the extent, and below
/// any geometry a camera looks at in a scene whose extent is one huge polygon (coordinates go
/// up to 1e9: at 1e-9 of the extent the near plane was 2.8 units and clipped the floor under
/// the camera).
pub(crate) const MIN_NEAR_RELATIVE: f64 = 1e-12;

/// The near plane of a perspective view: half the distance from the eye to the nearest
/// geometry (`nearest`, a lower bound of the distance to every polygon), so it never clips
/// anything, but at most `NEAR_RELATIVE` and at least `MIN_NEAR_RELATIVE` times `extent`.
/// A fixed fraction of the extent alone let one huge polygon far away push the near plane past
/// everything close to the camera (a black image).
pub fn near_plane(extent: f64, nearest: f64) -> f64 {
    let nearest = if nearest.is_nan() { 0.0 } else { nearest };
    (0.5 * nearest).clamp(MIN_NEAR_RELATIVE * extent, NEAR_RELATIVE * extent)
}

/// A lower bound of the distance from `eye` to polygon `p` whose corners span the box
/// `lo`..`hi`: the larger of the distance to its plane and the distance to the box. The box is
/// the one the frame computes anyway for the scene's bounds, so the bound costs one dot product
/// and one square root per polygon (a bounding sphere about the centroid would be a fifth of
/// the geometry stage of a 10^5-triangle mesh).
pub(crate) fn distance_lower_bound(p: &Polygon, lo: DVec3, hi: DVec3, eye: DVec3) -> f64 {
    let outside = (lo - eye).max(eye - hi).max(DVec3::ZERO);
    let plane = p.normal.dot(eye - p.corners[0]).abs();
    outside.length().max(plane)
}

/// A linear expression `a * px + b * py + c` over continuous pixel coordinates (pixel (i, j) has
/// its centre at (i + 0.5, j + 0.5), row 0 at the top).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Plane {
    /// Coefficient of px.
    pub a: f64,
    /// Coefficient of py.
    pub b: f64,
    /// Constant term.
    pub c: f64,
}

impl Plane {
    /// Value at (px, py).
    pub fn at(&self, px: f64, py: f64) -> f64 {
        self.a * px + self.b * py + self.c
    }
}

/// A polygon's plane in view space ([`View::plane_view`]).
pub(super) struct PlaneView {
    /// The unit normal.
    pub n: DVec3,
    /// `n . c0`, c0 the first corner.
    pub d: f64,
    /// An upper bound of [`corner_size`], the largest distance from the first corner to
    /// another (world units), found without a square root: only a plane nearly through the
    /// eye needs the distance itself.
    pub size_bound: f64,
    /// Whether the camera sees the front side.
    pub front_facing: bool,
}

/// The largest distance from polygon `poly`'s first corner to another, as one square root of the
/// largest square (the same value: the correctly rounded square root is monotonic).
pub(super) fn corner_size(poly: &Polygon) -> f64 {
    poly.vertices()
        .iter()
        .map(|c| (*c - poly.corners[0]).length_squared())
        .fold(0.0, f64::max)
        .sqrt()
}

/// The L1 norm of `v`: at least its Euclidean length.
#[inline(always)]
fn l1(v: DVec3) -> f64 {
    v.x.abs() + v.y.abs() + v.z.abs()
}

/// The camera's view transform and projection for one image size.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct View {
    eye: DVec3,
    right: DVec3,
    up: DVec3,
    forward: DVec3,
    perspective: bool,
    // px = sx * x + ox, py = sy * y + oy, with (x, y) = view (x, y) / w under perspective.
    sx: f64,
    sy: f64,
    ox: f64,
    oy: f64,
    // The view-space ray of pixel (px, py): X = ax px + bx, Y = ay py + by, i.e. (1 / sx,
    // -ox / sx, 1 / sy, -oy / sy), divided once per view instead of once per polygon.
    ray: [f64; 4],
    near: f64,
    width: u32,
    height: u32,
}

/// Index of each linear expression in [`ScreenPolygon::planes`].
pub mod plane {
    /// 1/w (perspective) or w (orthographic).
    pub const Q: usize = 0;
    /// s = SA + w * SB.
    pub const SA: usize = 1;
    /// See [`SA`].
    pub const SB: usize = 2;
    /// t = TA + w * TB.
    pub const TA: usize = 3;
    /// See [`TA`].
    pub const TB: usize = 4;
}

/// Inline capacity of a clipped polygon's vertex list: 4 corners, +1 at the near plane, +1 per
/// guard-band side, with room to spare.
pub(crate) const CLIP_CAPACITY: usize = 12;

/// A clipped polygon's screen vertices, held inline.
pub(crate) type Verts = SmallVec<[[f64; 2]; CLIP_CAPACITY]>;

/// A polygon after the geometry stage: a clipped convex screen polygon and its per-pixel
/// expressions.
#[derive(Clone, Debug)]
pub struct ScreenPolygon {
    /// Index of the polygon in the scene: the stable primitive id of every later tie-break.
    pub id: u32,
    /// Screen vertices (pixels), 3 to 9 of them, in polygon order (held inline: no allocation).
    pub verts: Verts,
    /// Q, Sa, Sb, Ta, Tb (see [`plane`]); with `barycentric`, Q, Ua, Ub, Va, Vb instead.
    pub planes: [Plane; 5],
    /// Corners c0..c3 in the polygon's 2-D frame (c0 at the origin); not computed (zero) with
    /// `barycentric`.
    pub corners: [[f64; 2]; 4],
    /// Whether `planes[SA..=TB]` already hold the triangle's barycentric U = u (1 - v) and v as
    /// `Ua + w Ub` and `Va + w Vb` (the geometry stage derives them directly for triangles, from
    /// the dual vectors of their edges), so setup has nothing to fold.
    pub barycentric: bool,
    /// Whether the polygon is a triangle (collapsed quad).
    pub triangle: bool,
    /// Whether Q is 1/w (perspective) rather than w.
    pub perspective: bool,
    /// Whether the camera sees the polygon's front side.
    pub front_facing: bool,
}

impl View {
    /// Builds the view of `camera` for a `width` x `height` image; `extent` is the scene's size
    /// and `nearest` a lower bound of the distance from the eye to any polygon (the near plane
    /// of a perspective camera is [`near_plane`]`(extent, nearest)`).
    ///
    /// Orthographic views map the camera's width x height rectangle onto the image exactly (pixels
    /// are not square when the two aspect ratios differ). Perspective views take the vertical field
    /// of view from the camera and the horizontal one from the image's aspect ratio.
    pub(crate) fn new(
        camera: &Camera,
        width: u32,
        height: u32,
        extent: f64,
        nearest: f64,
    ) -> Result<View> {
        if width == 0 || height == 0 {
            return Err(Error::invalid_option(
                "image size",
                format!("{width} x {height}"),
                "width and height must be at least 1",
            ));
        }
        let f = camera.look_at - camera.eye;
        if !f.is_finite() || !camera.eye.is_finite() || f.length() == 0.0 {
            return Err(Error::invalid_option(
                "the camera",
                "",
                "look_at must be finite and differ from eye",
            ));
        }
        let forward = f.normalize();
        let r = forward.cross(camera.up);
        if !r.is_finite() || r.length() <= 1e-9 * camera.up.length() || r.length() == 0.0 {
            return Err(Error::invalid_option(
                "the camera",
                "",
                "up must not be parallel to the view direction",
            ));
        }
        let right = r.normalize();
        let up = right.cross(forward);
        let (w, h) = (width as f64, height as f64);
        let extent = if extent.is_finite() && extent > 0.0 {
            extent
        } else {
            1.0
        };
        let (perspective, sx, sy, near) = match camera.projection {
            Projection::Perspective { fov_y_deg } => {
                if !(fov_y_deg > 0.0 && fov_y_deg < 180.0) {
                    return Err(Error::invalid_option(
                        "the camera",
                        "",
                        format!("field of view {fov_y_deg} must be in (0, 180) degrees"),
                    ));
                }
                let ty = (0.5 * fov_y_deg.to_radians()).tan();
                let tx = ty * w / h;
                (
                    true,
                    w / (2.0 * tx),
                    -h / (2.0 * ty),
                    near_plane(extent, nearest),
                )
            }
            Projection::Orthographic {
                width: vw,
                height: vh,
            } => {
                if !(vw > 0.0 && vh > 0.0 && vw.is_finite() && vh.is_finite()) {
                    return Err(Error::invalid_option(
                        "the camera",
                        "",
                        "orthographic width and height must be positive",
                    ));
                }
                (false, w / vw, -h / vh, 0.0)
            }
        };
        let (ox, oy) = (0.5 * w, 0.5 * h);
        Ok(View {
            eye: camera.eye,
            right,
            up,
            forward,
            perspective,
            sx,
            sy,
            ox,
            oy,
            ray: [1.0 / sx, -ox / sx, 1.0 / sy, -oy / sy],
            near,
            width,
            height,
        })
    }

    /// The near plane's distance (perspective; 0 for orthographic views).
    pub(super) fn near(&self) -> f64 {
        self.near
    }

    /// Whether the view is a perspective one.
    pub(super) fn is_perspective(&self) -> bool {
        self.perspective
    }

    /// The image size in pixels.
    pub(super) fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// View coordinates (right, up, forward distance w) of a world point.
    pub(crate) fn view_coords(&self, p: DVec3) -> DVec3 {
        let d = p - self.eye;
        DVec3::new(d.dot(self.right), d.dot(self.up), d.dot(self.forward))
    }

    pub(super) fn dir_to_view(&self, d: DVec3) -> DVec3 {
        DVec3::new(d.dot(self.right), d.dot(self.up), d.dot(self.forward))
    }

    /// Screen position (pixels) of a view-space point in front of the near plane.
    pub(crate) fn project(&self, v: DVec3) -> [f64; 2] {
        if self.perspective {
            [self.sx * v.x / v.z + self.ox, self.sy * v.y / v.z + self.oy]
        } else {
            [self.sx * v.x + self.ox, self.sy * v.y + self.oy]
        }
    }

    /// Transforms, clips and sets up polygon `id`; `None` when nothing of it can be seen (behind
    /// the near plane, outside the guard band, or edge-on: a plane through the eye projects to a
    /// line and covers no pixel centre).
    pub(crate) fn transform(&self, poly: &Polygon, id: u32) -> Option<ScreenPolygon> {
        let cv: [DVec3; 4] = poly.corners.map(|c| self.view_coords(c));
        let k = poly.shape.corner_count();
        // Trivial rejection before any setup: every corner behind the near plane (the clip
        // below would return nothing). Cheap culling matters for meshes of 10^5 triangles.
        if cv[..k].iter().all(|p| p.z < self.near) {
            return None;
        }
        let c0 = cv[0];
        let PlaneView {
            n,
            d,
            size_bound,
            front_facing,
        } = self.plane_view(poly, c0);
        let size = (size_bound, || corner_size(poly));
        let triangle = poly.shape == Shape::Triangle;
        let (planes, corners) = if triangle {
            let (b, c) = (cv[1] - c0, cv[2] - c0);
            let (m1, m2) = barycentric_duals(n, b, c)?;
            let frame = self.pixel_planes(n, d, c0, size, m1, m2)?;
            (frame, [[0.0; 2]; 4])
        } else {
            let (e1, e2, corners) = plane_frame(&cv, n)?;
            (self.pixel_planes(n, d, c0, size, e1, e2)?, corners)
        };
        let verts = self.clip_to_screen(&cv[..k])?;
        Some(ScreenPolygon {
            id,
            verts,
            planes,
            corners,
            triangle,
            perspective: self.perspective,
            front_facing,
            barycentric: triangle,
        })
    }

    /// The plane of polygon `poly` in view space, its first corner at `c0` (view coordinates).
    #[inline(always)]
    pub(super) fn plane_view(&self, poly: &Polygon, c0: DVec3) -> PlaneView {
        let n = self.dir_to_view(poly.normal);
        let d = n.dot(c0);
        // The largest corner distance's bound: the L1 norm is at least the Euclidean one.
        let size_bound = poly
            .vertices()
            .iter()
            .map(|c| l1(*c - poly.corners[0]))
            .fold(0.0, f64::max);
        let front_facing = if self.perspective { d < 0.0 } else { n.z < 0.0 };
        PlaneView {
            n,
            d,
            size_bound,
            front_facing,
        }
    }

    /// The per-pixel expressions of a polygon with view normal `n`, plane offset `d = n . c0`,
    /// corner c0, size `(bound, exact)` (an upper bound of its size and the size itself, asked
    /// for only where the bound cannot decide) and in-plane linear forms (e1, e2): Q (1/w in
    /// perspective, w in orthographic) and the coordinates `e1 . (P - c0)`, `e2 . (P - c0)` of the pixel's point
    /// P as [`plane`] orders them. (e1, e2) is an orthonormal frame for quads, the barycentric
    /// duals for triangles. `None` when the plane is edge-on or an expression is not finite.
    /// Always inlined: its 120-byte result, returned through memory, was read back by wider
    /// loads than the stores that wrote it (a store-forwarding stall on every triangle).
    #[inline(always)]
    pub(super) fn pixel_planes(
        &self,
        n: DVec3,
        d: f64,
        c0: DVec3,
        (size_bound, size): (f64, impl FnOnce() -> f64),
        e1: DVec3,
        e2: DVec3,
    ) -> Option<[Plane; 5]> {
        // View-space ray of pixel (px, py): X(px) = (px - ox) / sx, Y(py) = (py - oy) / sy.
        let [ax, bx, ay, by] = self.ray;
        let lin = |e: DVec3, z: f64| Plane {
            a: e.x * ax,
            b: e.y * ay,
            c: e.x * bx + e.y * by + z,
        };
        let constant = |c: f64| Plane { a: 0.0, b: 0.0, c };
        let planes = if self.perspective {
            // P = w (X, Y, 1); n . P = d  =>  1/w = (n . (X, Y, 1)) / d. Edge-on when |d| is
            // at most 1e-12 of |c0| + size; the L1 bounds (at least the Euclidean lengths, and
            // doubled against rounding) rule that out without a square root for all but planes
            // nearly through the eye, which take the exact test: the same decision always.
            let maybe_edge_on = d.abs() <= 2e-12 * (l1(c0) + size_bound);
            if maybe_edge_on && d.abs() <= 1e-12 * (c0.length() + size()) {
                return None;
            }
            let q = lin(n, n.z);
            let q = Plane {
                a: q.a / d,
                b: q.b / d,
                c: q.c / d,
            };
            let (ks, kt) = (e1.dot(c0), e2.dot(c0));
            [
                q,
                constant(-ks),
                lin(e1, e1.z),
                constant(-kt),
                lin(e2, e2.z),
            ]
        } else {
            // P = (X, Y, w); n . P = d  =>  w = (d - n.x X - n.y Y) / n.z.
            if n.z.abs() <= 1e-12 {
                return None;
            }
            let q = lin(-n, d);
            let q = Plane {
                a: q.a / n.z,
                b: q.b / n.z,
                c: q.c / n.z,
            };
            let sa = lin(e1, -e1.dot(c0));
            let ta = lin(e2, -e2.dot(c0));
            [q, sa, constant(e1.z), ta, constant(e2.z)]
        };
        planes
            .iter()
            .all(|p| p.a.is_finite() && p.b.is_finite() && p.c.is_finite())
            .then_some(planes)
    }

    /// The screen polygon of the view-space corners `cv`: clipped at the near plane, projected,
    /// rejected when entirely beyond one side of the image, clipped at the guard band. `None`
    /// when fewer than 3 vertices remain or one is not finite.
    fn clip_to_screen(&self, cv: &[DVec3]) -> Option<Verts> {
        // Near plane clip in view space (w >= near), then project. With every corner in front
        // of the plane the clip returns its input, so it is skipped (the common case).
        let near = self.near;
        let mut verts: Verts = if cv.iter().all(|p| p.z - near >= 0.0) {
            cv.iter().map(|&p| self.project(p)).collect()
        } else {
            let clipped = clip(
                cv,
                |p| p.z - near,
                |a, b, t| {
                    let mut p = a + t * (b - a);
                    p.z = p.z.max(near);
                    p
                },
                |p| [p.x, p.y, p.z],
            );
            if clipped.len() < 3 {
                return None;
            }
            clipped.iter().map(|&p| self.project(p)).collect()
        };
        // Trivial rejection: entirely beyond one side of the image, where no sample lies (sample
        // positions are strictly inside (0, width) x (0, height)); setup would reject it later.
        let (w, h) = (self.width as f64, self.height as f64);
        if verts.iter().all(|p| p[0] < 0.0)
            || verts.iter().all(|p| p[0] > w)
            || verts.iter().all(|p| p[1] < 0.0)
            || verts.iter().all(|p| p[1] > h)
        {
            return None;
        }
        // Guard band clip in screen space: the projective map keeps straight lines straight.
        // Skipped when every vertex is inside the band, where each clip returns its input.
        let (lo_x, hi_x) = (-GUARD_BAND, w + GUARD_BAND);
        let (lo_y, hi_y) = (-GUARD_BAND, h + GUARD_BAND);
        let inside = |p: &[f64; 2]| p[0] >= lo_x && p[0] <= hi_x && p[1] >= lo_y && p[1] <= hi_y;
        if !verts.iter().all(inside) {
            let lerp2 = |a: [f64; 2], b: [f64; 2], t: f64| {
                [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]
            };
            let key2 = |p: &[f64; 2]| [p[0], p[1], 0.0];
            verts = clip(&verts, |p| p[0] - lo_x, lerp2, key2);
            verts = clip(&verts, |p| hi_x - p[0], lerp2, key2);
            verts = clip(&verts, |p| p[1] - lo_y, lerp2, key2);
            verts = clip(&verts, |p| hi_y - p[1], lerp2, key2);
        }
        if verts.len() < 3 || !verts.iter().all(|p| p[0].is_finite() && p[1].is_finite()) {
            return None;
        }
        Some(verts)
    }
}

/// The orthonormal frame (e1, e2) of a polygon's plane in view coordinates, origin at the first
/// corner, e1 towards the farther of corners 1 and 2, and the four corners in that frame. `None`
/// when the frame is not finite (a degenerate polygon).
fn plane_frame(cv: &[DVec3; 4], n: DVec3) -> Option<(DVec3, DVec3, [[f64; 2]; 4])> {
    let c0 = cv[0];
    let far = if (cv[1] - c0).length_squared() >= (cv[2] - c0).length_squared() {
        cv[1]
    } else {
        cv[2]
    };
    let e1 = (far - c0).normalize();
    let e2 = n.cross(e1).normalize();
    if !e1.is_finite() || !e2.is_finite() {
        return None;
    }
    let mut corners = [[0.0; 2]; 4];
    for (k, c) in cv.iter().enumerate() {
        corners[k] = [e1.dot(*c - c0), e2.dot(*c - c0)];
    }
    Some((e1, e2, corners))
}

/// The dual vectors (m1, m2) of a triangle's edges b = c1 - c0 and c = c2 - c0 in its plane
/// (unit normal `n`): m1 . b = 1, m1 . c = 0, m2 . b = 0, m2 . c = 1, both orthogonal to `n`.
/// A point P of the plane is then c0 + U b + v c with U = m1 . (P - c0) and v = m2 . (P - c0),
/// the barycentric coordinates the rasterizer needs (u = U / (1 - v) of the collapsed quad), so
/// a triangle needs neither a normalized frame nor the setup's Cramer solve: m1 = (c x n) / D,
/// m2 = (n x b) / D with D = n . (b x c), plus or minus twice the area (view coordinates are
/// left-handed, which flips every cross product and D alike, so the quotients hold in either
/// handedness). `None` when D is zero or not finite (a degenerate triangle).
pub(super) fn barycentric_duals(n: DVec3, b: DVec3, c: DVec3) -> Option<(DVec3, DVec3)> {
    let det = n.dot(b.cross(c));
    if !(det != 0.0 && det.is_finite()) {
        return None;
    }
    let k = 1.0 / det;
    let (m1, m2) = (c.cross(n) * k, n.cross(b) * k);
    (m1.is_finite() && m2.is_finite()).then_some((m1, m2))
}

/// Sutherland-Hodgman clip of a convex polygon against `dist >= 0`. The intersection on an edge is
/// computed from its endpoints in lexicographic order of `key`, so two polygons sharing the edge
/// get bit-identical points.
fn clip<T: Copy>(
    poly: &[T],
    dist: impl Fn(&T) -> f64,
    lerp: impl Fn(T, T, f64) -> T,
    key: impl Fn(&T) -> [f64; 3],
) -> SmallVec<[T; CLIP_CAPACITY]> {
    let mut out = SmallVec::new();
    if poly.is_empty() {
        return out;
    }
    for i in 0..poly.len() {
        let a = poly[i];
        let b = poly[(i + 1) % poly.len()];
        let (da, db) = (dist(&a), dist(&b));
        if da >= 0.0 {
            out.push(a);
        }
        if (da >= 0.0) != (db >= 0.0) {
            let (p, q, dp, dq) = if key(&a) <= key(&b) {
                (a, b, da, db)
            } else {
                (b, a, db, da)
            };
            out.push(lerp(p, q, dp / (dp - dq)));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn persp() -> Camera {
        Camera {
            eye: DVec3::new(0.0, 0.0, 5.0),
            look_at: DVec3::ZERO,
            up: DVec3::Y,
            projection: Projection::Perspective { fov_y_deg: 90.0 },
        }
    }

    #[test]
    fn perspective_maps_the_look_at_point_to_the_centre_and_the_fov_to_the_edges() {
        let v = View::new(&persp(), 200, 100, 10.0, f64::INFINITY).unwrap();
        let c = v.project(v.view_coords(DVec3::ZERO));
        assert_eq!(c, [100.0, 50.0]);
        // fov 90: at distance 5 the top edge is at y = 5; the image is twice as wide.
        let top = v.project(v.view_coords(DVec3::new(0.0, 5.0, 0.0)));
        assert!((top[1] - 0.0).abs() < 1e-12);
        let right = v.project(v.view_coords(DVec3::new(10.0, 0.0, 0.0)));
        assert!((right[0] - 200.0).abs() < 1e-12, "{right:?}");
    }

    #[test]
    fn q_plane_is_the_reciprocal_depth_of_the_polygon() {
        let v = View::new(&persp(), 64, 64, 10.0, f64::INFINITY).unwrap();
        let p = Polygon::quad(
            [
                DVec3::new(-1.0, -1.0, 0.0),
                DVec3::new(1.0, -1.0, -1.0),
                DVec3::new(1.0, 1.0, -1.0),
                DVec3::new(-1.0, 1.0, 0.0),
            ],
            0,
            0,
        )
        .unwrap();
        let sp = v.transform(&p, 0).unwrap();
        for &(u, w) in &[(0.5, 0.5), (0.1, 0.9), (0.8, 0.3)] {
            let world = p.point(u, w);
            let vw = v.view_coords(world);
            let [px, py] = v.project(vw);
            let q = sp.planes[plane::Q].at(px, py);
            assert!((1.0 / q - vw.z).abs() < 1e-9, "{} vs {}", 1.0 / q, vw.z);
            let wd = 1.0 / q;
            let s = sp.planes[plane::SA].at(px, py) + wd * sp.planes[plane::SB].at(px, py);
            let t = sp.planes[plane::TA].at(px, py) + wd * sp.planes[plane::TB].at(px, py);
            // (s, t) must be the point's coordinates in the frame, |P - c0| = |(s, t)|.
            let dist = (world - p.corners[0]).length();
            assert!(((s * s + t * t).sqrt() - dist).abs() < 1e-9);
        }
    }

    #[test]
    fn near_clip_of_a_polygon_through_the_eye_plane_keeps_the_front_part() {
        let v = View::new(&persp(), 64, 64, 10.0, f64::INFINITY).unwrap();
        // A floor quad reaching from behind the camera to the far side.
        let p = Polygon::quad(
            [
                DVec3::new(-1.0, -1.0, 10.0),
                DVec3::new(1.0, -1.0, 10.0),
                DVec3::new(1.0, -1.0, -10.0),
                DVec3::new(-1.0, -1.0, -10.0),
            ],
            0,
            0,
        )
        .unwrap();
        let sp = v.transform(&p, 0).unwrap();
        assert!(sp.verts.len() >= 3);
        assert!(sp
            .verts
            .iter()
            .all(|q| q[0].is_finite() && q[1].is_finite()));
        assert!(
            sp.verts.iter().all(|q| q[1] >= 32.0 - 1e-9),
            "{:?}",
            sp.verts
        );
    }

    #[test]
    fn bad_cameras_are_usage_errors() {
        let mut c = persp();
        c.up = DVec3::Z;
        assert!(View::new(&c, 8, 8, 1.0, f64::INFINITY).is_err());
        let mut c = persp();
        c.look_at = c.eye;
        assert!(View::new(&c, 8, 8, 1.0, f64::INFINITY).is_err());
        let mut c = persp();
        c.projection = Projection::Perspective { fov_y_deg: 180.0 };
        assert!(View::new(&c, 8, 8, 1.0, f64::INFINITY).is_err());
    }
}
