//! Outlines of polygons lying close over a receiver (a lamp hung 1 cm under a ceiling, a
//! picture on a wall, a rug on a floor): the lines along which the parent module cuts the
//! receiver, as it does along the feet of the polygons standing on it.
//!
//! What lies over a receiver is a *sheet*: polygons in one plane, facing one way, joined along
//! whole shared sides. A lamp modelled as one quad is a sheet of one; a round lamp a modelling
//! tool exported as a fan of sixteen thin triangles is one sheet too, whose outline is the
//! rim, not the spokes. Judged triangle by triangle, each spoke's triangle is too thin for its
//! 1 cm gap to count as close (its half-width is 5 cm), and if it did count, the spokes would
//! cut the ceiling along lines across which the light is smooth. So the sheet's size (twice
//! its area over its border's length) decides whether it is close, and only its border sides
//! are outlines.
//!
//! A sheet in the receiver's very plane, facing the same way (a light panel snapped onto a
//! ceiling), cuts it too where it lies on top of it (`crate::coincident::Stacking`): the
//! piece under it is then buried, as under a sheet a hair in front of it.
//!
//! Invariants: the sheets and the lines depend only on the polygons (members ascending,
//! sheets by their first member, candidates sorted), so the result is the same for any thread
//! count; sides are matched by the exact bits of their corners, as a mesh's shared vertices
//! are written.

use std::collections::HashMap;

use glam::{DVec2, DVec3};

use super::{clip_to_polygon, on_border, ContactLine, Frame, LineKind, PLANE_TOL};
use crate::bvh::{Aabb, Bvh};
use crate::coincident::{area_abs, clip, diameter, Stacking, ROUNDING};
use crate::Polygon;

/// A sheet in front of a receiver by at most this share of its half-width (twice its area
/// over its border's length: a square's half side, a long strip's half width, a disc's
/// radius) and nowhere behind it cuts the receiver along its projected outline. The light
/// under such a sheet falls from the step at its outline to almost nothing within a few gaps
/// (a point a distance `x` inside sees the room only below an elevation of about `gap / x`, a
/// cosine-weighted share of about `(gap / x)^2 / 2`), so the outline is a step on the scale of
/// the sheet; the Cornell box's lamp, 1 cm under a ceiling, is at 0.05 of its 0.21
/// half-width, a gallery's 1 m ceiling panels at 0.02. By a quarter of the half-width the
/// ramps from both sides fill most of the shadow, a soft penumbra that refinement follows (a
/// box floating 10 cm over a floor, at 0.25, is left whole).
pub const OUTLINE_GAP: f64 = 0.125;

/// The share of a close sheet's area that must lie over the receiver for its outline to cut
/// it: a lamp straddling two ceiling polygons cuts both, a neighbour folded up by a hair from
/// the receiver's side (whose projection overlaps it in slivers) cuts neither.
pub const OUTLINE_OVER: f64 = 0.01;

/// Polygons in one plane, facing one way, joined along whole shared sides.
struct Sheet {
    /// Indices of the polygons, ascending.
    members: Vec<u32>,
    /// The sides on the sheet's border: polygon and side (from corner `k` to the next).
    border: Vec<(u32, usize)>,
    /// Twice the area over the border's length.
    half_width: f64,
    /// The largest coordinate of its corners, in absolute value (what rounding scales with).
    magnitude: f64,
}

/// The largest coordinate of `p`'s corners, in absolute value.
fn magnitude(p: &Polygon) -> f64 {
    p.vertices()
        .iter()
        .map(|v| v.abs().max_element())
        .fold(0.0, f64::max)
}

/// A side's key: the bits of its two corners, in a fixed order (either direction).
type SideKey = ([u64; 3], [u64; 3]);

fn side_key(a: DVec3, b: DVec3) -> SideKey {
    let (ka, kb) = (
        a.to_array().map(f64::to_bits),
        b.to_array().map(f64::to_bits),
    );
    if ka <= kb {
        (ka, kb)
    } else {
        (kb, ka)
    }
}

/// Whether `p` and `q` lie in one plane and face one way.
fn coplanar(p: &Polygon, q: &Polygon) -> bool {
    let tol = PLANE_TOL * diameter(p).max(diameter(q));
    p.normal.dot(q.normal) > 1.0 - 1e-9
        && q.vertices()
            .iter()
            .all(|v| p.normal.dot(*v - p.corners[0]).abs() <= tol)
}

fn root(parent: &mut [u32], mut x: u32) -> u32 {
    while parent[x as usize] != x {
        let up = parent[parent[x as usize] as usize];
        parent[x as usize] = up;
        x = up;
    }
    x
}

/// Every polygon's sheet (see the module docs), ordered by first member.
fn sheets(polygons: &[Polygon]) -> Vec<Sheet> {
    let mut sides: HashMap<SideKey, Vec<u32>> = HashMap::new();
    for (i, p) in polygons.iter().enumerate() {
        let vs = p.vertices();
        for k in 0..vs.len() {
            let key = side_key(vs[k], vs[(k + 1) % vs.len()]);
            sides.entry(key).or_default().push(i as u32);
        }
    }
    let mut parent: Vec<u32> = (0..polygons.len() as u32).collect();
    for owners in sides.values() {
        if let [a, b] = owners[..] {
            if coplanar(&polygons[a as usize], &polygons[b as usize]) {
                let (ra, rb) = (root(&mut parent, a), root(&mut parent, b));
                parent[ra.max(rb) as usize] = ra.min(rb);
            }
        }
    }
    let mut by_root: HashMap<u32, usize> = HashMap::new();
    let mut out: Vec<Sheet> = Vec::new();
    let mut area: Vec<f64> = Vec::new();
    let mut perimeter: Vec<f64> = Vec::new();
    for (i, p) in polygons.iter().enumerate() {
        let r = root(&mut parent, i as u32);
        let s = *by_root.entry(r).or_insert_with(|| {
            out.push(Sheet {
                members: Vec::new(),
                border: Vec::new(),
                half_width: 0.0,
                magnitude: 0.0,
            });
            area.push(0.0);
            perimeter.push(0.0);
            out.len() - 1
        });
        out[s].members.push(i as u32);
        out[s].magnitude = out[s].magnitude.max(magnitude(p));
        area[s] += p.area;
        let vs = p.vertices();
        for k in 0..vs.len() {
            let (a, b) = (vs[k], vs[(k + 1) % vs.len()]);
            let shared = sides[&side_key(a, b)]
                .iter()
                .any(|&o| o != i as u32 && root(&mut parent, o) == r);
            if !shared {
                out[s].border.push((i as u32, k));
                perimeter[s] += a.distance(b);
            }
        }
    }
    for (s, sheet) in out.iter_mut().enumerate() {
        sheet.half_width = 2.0 * area[s] / perimeter[s].max(f64::MIN_POSITIVE);
    }
    out
}

/// Appends the outline lines of every sheet lying close over a polygon ([`OUTLINE_GAP`]), or
/// in its plane on top of it (`stacking`): each sheet's box, grown by the gap it may leave,
/// finds its receivers.
pub(super) fn outlines(
    polygons: &[Polygon],
    bvh: &Bvh,
    stacking: &Stacking,
    lines: &mut Vec<ContactLine>,
) {
    for sheet in sheets(polygons) {
        let reach = OUTLINE_GAP * sheet.half_width;
        let corners: Vec<DVec3> = sheet
            .members
            .iter()
            .flat_map(|&m| polygons[m as usize].vertices().to_vec())
            .collect();
        let b = Aabb::of(&corners);
        let b = Aabb {
            lo: b.lo - DVec3::splat(reach),
            hi: b.hi + DVec3::splat(reach),
        };
        let mut near = Vec::new();
        bvh.for_each_overlapping(&b, |p| {
            if sheet.members.binary_search(&p).is_err() {
                near.push(p);
            }
        });
        near.sort_unstable();
        let size = sheet
            .members
            .iter()
            .map(|&m| diameter(&polygons[m as usize]))
            .fold(0.0f64, f64::max);
        for pi in near {
            let p = &polygons[pi as usize];
            let tol = PLANE_TOL * diameter(p).max(size);
            let on_top = sheet.members.iter().all(|&m| {
                polygons[m as usize].normal.dot(p.normal) > 1.0 - 1e-9
                    && stacking.over(m as usize, pi as usize)
            });
            for (by, a, b, gap) in outline(p, polygons, &sheet, (reach, tol), on_top) {
                lines.push(ContactLine {
                    receiver: pi,
                    by,
                    a,
                    b,
                    kind: LineKind::Outline { gap },
                });
            }
        }
    }
}

/// The border sides of `sheet` projected onto `p`, clipped to `p`, if the sheet lies in front
/// of `p` within `reach` of its plane, nowhere behind it (beyond `tol`), and over it
/// ([`OUTLINE_OVER`]), or if it lies in `p`'s plane and `on_top` of it (facing the same way and
/// above it in the stacking order); sides on `p`'s border, and sides the sheet touches `p`
/// along (contact lines), are left out. Each side comes with the polygon it belongs to and its
/// mean gap.
fn outline(
    p: &Polygon,
    polygons: &[Polygon],
    sheet: &Sheet,
    (reach, tol): (f64, f64),
    on_top: bool,
) -> Vec<(u32, DVec3, DVec3, f64)> {
    let n = p.normal;
    let height = |v: DVec3| n.dot(v - p.corners[0]);
    let members = || sheet.members.iter().map(|&m| &polygons[m as usize]);
    // A sheet in front of `p` is over it however close (above rounding): the receiver under
    // it sees only the sheet, or nothing (module `seal`), so it is its own piece. Most sheets
    // near `p` are not in front of it: the first corner behind it or out of reach says so.
    let on = ROUNDING * sheet.magnitude.max(magnitude(p));
    let (mut above, mut flush) = (false, on_top);
    for q in members() {
        for v in q.vertices() {
            let h = height(*v);
            if h < -tol || h > reach {
                return Vec::new();
            }
            above |= h > on;
            flush &= h.abs() <= on;
        }
    }
    if !above && !flush {
        return Vec::new();
    }
    // Over the receiver, not beside it: a neighbour folded up from `p`'s side by a hair (two
    // triangles of a quad that is not quite planar) projects onto `p` in slivers only.
    let frame = Frame::of(p);
    let receiver: Vec<DVec2> = p.vertices().iter().map(|v| frame.to2(*v)).collect();
    let (mut over, mut all) = (0.0, 0.0);
    for q in members() {
        let footprint: Vec<DVec2> = q
            .vertices()
            .iter()
            .map(|v| frame.to2(*v - n * height(*v)))
            .collect();
        over += area_abs(&clip(&footprint, &receiver));
        all += area_abs(&footprint);
    }
    if over < OUTLINE_OVER * all {
        return Vec::new();
    }
    let mut out = Vec::new();
    for &(m, k) in &sheet.border {
        let vs = polygons[m as usize].vertices();
        let (a, b) = (vs[k], vs[(k + 1) % vs.len()]);
        let (da, db) = (height(a), height(b));
        if da <= on && db <= on && !flush {
            continue;
        }
        if let Some((a, b)) = clip_to_polygon(p, a - n * da, b - n * db, tol) {
            if !on_border(p, a, b, tol) {
                out.push((m, a, b, 0.5 * (da + db).max(0.0)));
            }
        }
    }
    out
}
