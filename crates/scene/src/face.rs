//! One face of a scene (an inline polygon, an OBJ or glTF face) turned into valid polygons:
//! planar quads projected onto their best-fit plane, quads beyond the planarity tolerance and
//! larger convex faces fanned into triangles, concave faces ear-clipped, degenerate and
//! self-crossing faces refused with what is wrong.

use super::{newell_normal, Polygon, PLANARITY_TOLERANCE};
use crate::checks::{in_range, Cx, FINITE_RULE, MAX_FACE_CORNERS};
use base::error::{Error, Location, Result};
use glam::DVec3;

/// The polygons one face became, and a warning if it was repaired.
pub(crate) struct BuiltFace {
    pub(crate) polygons: Vec<Polygon>,
    pub(crate) warning: Option<String>,
}

impl BuiltFace {
    /// A face that is one polygon as it stands.
    fn single(polygon: Polygon) -> BuiltFace {
        BuiltFace {
            polygons: vec![polygon],
            warning: None,
        }
    }
}

/// Turns one face (3 or more finite corners, counter-clockwise seen from the front) into valid
/// polygons, or says what is wrong with it.
///
/// - 3 corners: a triangle; refused if (near) zero area.
/// - 4 corners, convex: its deviation from planarity is the largest distance of a corner from
///   the best-fit plane (Newell normal through the centroid) over the longest diagonal. Within
///   [`PLANARITY_TOLERANCE`] the corners are projected onto that plane; beyond it the quad is
///   split along the c0-c2 diagonal into two triangles, with a warning.
/// - 5 or more (OBJ faces only, at most [`MAX_FACE_CORNERS`]), convex and planar within the same
///   tolerance: projected and fan-triangulated from the first corner.
/// - Concave faces, faces with three collinear consecutive corners, and non-planar faces of 5
///   or more corners: triangulated by ear clipping with a note (`build_clipped`). Refused:
///   zero net area, or a face that crosses itself.
pub(crate) fn build_face(
    corners: &[DVec3],
    material: u32,
    object: u32,
) -> std::result::Result<BuiltFace, String> {
    check_corners(corners)?;
    if corners.len() == 3 {
        let t = Polygon::triangle([corners[0], corners[1], corners[2]], material, object)
            .ok_or("has zero area (its corners are collinear or coincide)")?;
        return Ok(BuiltFace::single(t));
    }
    let plane = BestFitPlane::of(corners)?;
    match plane.check_convex() {
        Ok(()) if corners.len() == 4 => build_quad(corners, &plane, material, object),
        Ok(()) if plane.is_planar() => build_fan(&plane, material, object),
        Ok(()) => build_clipped(
            corners,
            &plane,
            material,
            object,
            "is convex but not planar",
        ),
        Err(why) => build_clipped(corners, &plane, material, object, &why),
    }
}

/// A face the parametric map cannot take as one polygon (concave, or of 5 or more corners off
/// its plane): cut into triangles by ear clipping on its best-fit plane, with a note. A planar
/// face's triangles use its projected corners; a non-planar one's keep the original corners, so
/// the surface follows the model. Refused if the face, projected on its plane, crosses or
/// touches itself.
fn build_clipped(
    corners: &[DVec3],
    plane: &BestFitPlane,
    material: u32,
    object: u32,
    why: &str,
) -> std::result::Result<BuiltFace, String> {
    let n = corners.len();
    let flat = plane.flattened();
    let area2 = super::triangulate::area2(&flat);
    let refuse = || {
        format!(
            "{why}, and cannot be triangulated: it crosses itself or repeats a corner \
             (faces must be simple polygons)"
        )
    };
    if area2 <= 0.0 || !super::triangulate::is_simple(&flat) {
        return Err(refuse());
    }
    let tris = super::triangulate::ear_clip(&flat, 1e-9 * plane.size2).ok_or_else(refuse)?;
    let source = if plane.is_planar() {
        &plane.projected
    } else {
        corners
    };
    let mut polygons = Vec::with_capacity(tris.len());
    for [a, b, c] in tris {
        let t = Polygon::triangle([source[a], source[b], source[c]], material, object)
            .ok_or_else(refuse)?;
        polygons.push(t);
    }
    let count = polygons.len();
    Ok(BuiltFace {
        polygons,
        warning: Some(format!(
            "{n}-corner face {why}: triangulated by ear clipping into {count} triangles"
        )),
    })
}

/// `Ok` if a face has between 3 and [`MAX_FACE_CORNERS`] corners, all in range.
fn check_corners(corners: &[DVec3]) -> std::result::Result<(), String> {
    let n = corners.len();
    if n < 3 {
        return Err(format!("has {n} corners; a face needs at least 3"));
    }
    if n > MAX_FACE_CORNERS {
        return Err(format!(
            "has {n} corners; a face has at most {MAX_FACE_CORNERS} (split it into smaller faces)"
        ));
    }
    if let Some(c) = corners
        .iter()
        .find(|c| !c.to_array().iter().all(|x| in_range(*x)))
    {
        return Err(format!("corner {c}: {FINITE_RULE}"));
    }
    Ok(())
}

/// The best-fit plane of a face of 4 or more corners (Newell normal through the centroid) and
/// how far the face is from it.
struct BestFitPlane {
    /// Unit normal.
    normal: DVec3,
    /// Largest squared distance between two corners.
    size2: f64,
    /// Largest distance of a corner from the plane over the face's longest diagonal.
    relative: f64,
    /// The corners projected onto the plane.
    projected: Vec<DVec3>,
}

impl BestFitPlane {
    /// The plane of `corners` (4 or more, in range); refused if the face has zero net area.
    fn of(corners: &[DVec3]) -> std::result::Result<BestFitPlane, String> {
        let n = corners.len();
        let normal = newell_normal(corners);
        let len = normal.length();
        let size2 = corners
            .iter()
            .flat_map(|a| corners.iter().map(move |b| (*a - *b).length_squared()))
            .fold(0.0, f64::max);
        // Same degeneracy threshold as `Polygon::build`: twice the area against the squared size.
        if len <= 1e-12 * size2 {
            return Err(
                "has zero net area (its corners are collinear or coincide, or it crosses itself)"
                    .to_string(),
            );
        }
        let nh = normal / len;
        let centroid = corners.iter().copied().sum::<DVec3>() / n as f64;
        let deviation = corners
            .iter()
            .map(|c| (*c - centroid).dot(nh).abs())
            .fold(0.0, f64::max);
        // The quad's longest diagonal (the polygon's diameter for more corners) is the size that
        // the planarity tolerance is relative to.
        let diagonal = if n == 4 {
            (corners[2] - corners[0])
                .length()
                .max((corners[3] - corners[1]).length())
        } else {
            size2.sqrt()
        };
        let projected = corners
            .iter()
            .map(|c| *c - (*c - centroid).dot(nh) * nh)
            .collect();
        Ok(BestFitPlane {
            normal: nh,
            size2,
            relative: deviation / diagonal,
            projected,
        })
    }

    /// The projected corners in 2D coordinates of the plane, counter-clockwise seen from the
    /// front (the side the normal points to).
    fn flattened(&self) -> Vec<glam::DVec2> {
        let e1 = self.normal.any_orthonormal_vector();
        let e2 = self.normal.cross(e1);
        let o = self.projected[0];
        self.projected
            .iter()
            .map(|p| glam::DVec2::new((*p - o).dot(e1), (*p - o).dot(e2)))
            .collect()
    }

    /// Whether the face is within [`PLANARITY_TOLERANCE`] of the plane.
    fn is_planar(&self) -> bool {
        self.relative <= PLANARITY_TOLERANCE
    }

    /// Convexity on the projected polygon: every turn must be to the left of the normal. A zero
    /// turn means three collinear consecutive corners, which the parametric map cannot use.
    fn check_convex(&self) -> std::result::Result<(), String> {
        let p = &self.projected;
        let n = p.len();
        for i in 0..n {
            let (a, b, c) = (p[i], p[(i + 1) % n], p[(i + 2) % n]);
            let turn = (b - a).cross(c - b).dot(self.normal);
            if turn <= 1e-9 * self.size2 {
                return Err(format!(
                    "is concave or has three collinear corners (at corner {})",
                    (i + 1) % n
                ));
            }
        }
        Ok(())
    }
}

/// A convex quad: projected onto its plane if planar, else split along its c0-c2 diagonal into
/// two triangles of the original corners, with a warning.
fn build_quad(
    corners: &[DVec3],
    plane: &BestFitPlane,
    material: u32,
    object: u32,
) -> std::result::Result<BuiltFace, String> {
    if plane.is_planar() {
        let p = &plane.projected;
        let q = Polygon::quad([p[0], p[1], p[2], p[3]], material, object).ok_or("has zero area")?;
        return Ok(BuiltFace::single(q));
    }
    let t0 = Polygon::triangle([corners[0], corners[1], corners[2]], material, object);
    let t1 = Polygon::triangle([corners[0], corners[2], corners[3]], material, object);
    let (Some(t0), Some(t1)) = (t0, t1) else {
        return Err("is not planar and cannot be split into two valid triangles".to_string());
    };
    Ok(BuiltFace {
        polygons: vec![t0, t1],
        warning: Some(format!(
            "quad is not planar (a corner is {:.3}% of its longest diagonal off the best-fit \
             plane, tolerance {}%): split into two triangles along its c0-c2 diagonal",
            100.0 * plane.relative,
            100.0 * PLANARITY_TOLERANCE
        )),
    })
}

/// A convex planar face of 5 or more corners: projected and fan-triangulated from its first
/// corner.
fn build_fan(
    plane: &BestFitPlane,
    material: u32,
    object: u32,
) -> std::result::Result<BuiltFace, String> {
    let p = &plane.projected;
    let n = p.len();
    let mut polygons = Vec::with_capacity(n - 2);
    for i in 1..n - 1 {
        let t = Polygon::triangle([p[0], p[i], p[i + 1]], material, object)
            .ok_or("has a degenerate fan triangle")?;
        polygons.push(t);
    }
    Ok(BuiltFace {
        polygons,
        warning: None,
    })
}

impl Cx<'_> {
    /// Turns one face into polygons with [`build_face`] and appends them to `polygons`; a
    /// problem is an input error at `location`, a repair a warning there.
    pub(crate) fn add_face(
        &mut self,
        corners: &[DVec3],
        material: u32,
        object: u32,
        location: Location,
        polygons: &mut Vec<Polygon>,
    ) -> Result<()> {
        let built = build_face(corners, material, object)
            .map_err(|msg| Error::input(location.clone(), msg))?;
        if let Some(w) = built.warning {
            self.notes.push(format!("{location}: {w}"));
        }
        for _ in &built.polygons {
            self.origins.push(location.clone());
        }
        polygons.extend(built.polygons);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn cornell_left_wall_deviation_is_0_176_percent() {
        // The McGuire left wall. Worked by hand: the Newell normal is close to +x, the corners
        // are about +-0.005 off the best plane and the diagonals 2.843 long: 0.176%.
        let c = [
            DVec3::new(-1.01, 0.0, 0.99),
            DVec3::new(-0.99, 0.0, -1.04),
            DVec3::new(-1.02, 1.99, -1.04),
            DVec3::new(-1.02, 1.99, 0.99),
        ];
        let built = build_face(&c, 0, 0).unwrap();
        assert_eq!(built.polygons.len(), 2);
        let w = built.warning.unwrap();
        assert!(w.contains("0.176%"), "{w}");
        let area: f64 = built.polygons.iter().map(|p| p.area).sum();
        // Nearly the 2.03 x 1.99 rectangle (corners are off by at most 0.03 in x).
        assert!((area - 2.03 * 1.99).abs() < 0.01, "{area}");
    }

    #[test]
    fn convex_planar_pentagon_is_fanned() {
        let c = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(3.0, 1.0, 0.0),
            DVec3::new(1.0, 2.0, 0.0),
            DVec3::new(-1.0, 1.0, 0.0),
        ];
        let built = build_face(&c, 0, 0).unwrap();
        assert_eq!(built.polygons.len(), 3);
        // Shoelace: sum of x_i y_{i+1} - x_{i+1} y_i = 0 + 2 + 5 + 3 + 0 = 10, area 5.
        let area: f64 = built.polygons.iter().map(|p| p.area).sum();
        assert!((area - 5.0).abs() < 1e-12);
    }

    proptest! {
        /// Any rectangle, in any orientation and at any scale from 1e-3 to 1e3, is a valid
        /// quad with area w h (to rounding: a few ulps of the largest coordinate squared).
        #[test]
        fn rectangles_in_any_plane_are_accepted(
            w in 1e-3f64..1e3, h in 1e-3f64..1e3,
            ax in -3.2f64..3.2, ay in -3.2f64..3.2, az in -3.2f64..3.2,
            t in prop::array::uniform3(-1e3f64..1e3),
        ) {
            let r = glam::DMat3::from_euler(glam::EulerRot::XYZ, ax, ay, az);
            let o = DVec3::from_array(t);
            let c = [
                o,
                o + r * DVec3::new(w, 0.0, 0.0),
                o + r * DVec3::new(w, h, 0.0),
                o + r * DVec3::new(0.0, h, 0.0),
            ];
            let built = build_face(&c, 0, 0).unwrap();
            prop_assert!(built.warning.is_none());
            prop_assert_eq!(built.polygons.len(), 1);
            let q = &built.polygons[0];
            let scale = (o.length() + w + h).powi(2);
            prop_assert!((q.area - w * h).abs() <= 1e-12 * scale);
            prop_assert!((q.normal - r * DVec3::Z).length() < 1e-6);
        }
    }
}
