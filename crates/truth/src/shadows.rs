//! Shadow boundaries in the image: which pixels lie where a shadow starts or ends, so that an
//! image's error there can be told apart from its error elsewhere.
//!
//! At the centre of every pixel the camera's first front surface is found and the share of the
//! direct light that reaches it unblocked is computed (`Tracer::unblocked_share`: spot lights
//! exactly, area emitters on a fixed lattice of [`LIGHT_GRID`]^2 points each). A point is
//! **lit** (share 1), in **umbra** (share 0) or in **penumbra** (between). Two 4-neighbouring
//! pixels are a **shadow boundary** where their states differ and both lie on one plane
//! (parallel faces at the same offset, so the pieces a polygon was cut into count as one face):
//! the outer and inner edges of a penumbra and the line of a hard shadow, but not a silhouette
//! or a crease, whose pixels lie on different planes. Pixels that no light reaches (a face
//! turned from every light) or that see the background or a back face take no part.
//!
//! Invariants: no random numbers (the lattice is fixed), rows are computed in parallel and
//! each pixel independently, so the map is the same bits for any thread count. Why a lattice
//! and not exact clipping: this module shares nothing of the solver's exact visibility, so it
//! can judge it; a lattice of 16 x 16 points locates a penumbra's edges to a sixteenth of its
//! width, well inside the two pixels the boundary band is dilated by.

use glam::DVec3;
use rayon::prelude::*;

use crate::camera::CameraRays;
use crate::tracer::{Surface, Tracer};
use base::error::Result;
use scene::Scene;

/// Points per side of the lattice each area emitter is sampled on.
pub const LIGHT_GRID: u32 = 16;

/// Relative tolerance of "on one plane": normals within this of each other (1 - cosine) and
/// offsets within this of the scene's diagonal.
const SAME_PLANE: f64 = 1e-6;

/// The direct light's visibility over an image and where its shadows' boundaries lie.
#[derive(Debug, Clone, PartialEq)]
pub struct ShadowMap {
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Per pixel (row-major): the unblocked share of the direct light at the surface seen
    /// through the pixel's centre, `None` where there is no such surface or no light reaches
    /// it.
    pub share: Vec<Option<f64>>,
    /// Per pixel: on a shadow boundary (one of a pair of 4-neighbours whose states differ).
    pub boundary: Vec<bool>,
}

impl ShadowMap {
    /// Pixels on a shadow boundary.
    pub fn boundary_pixels(&self) -> usize {
        self.boundary.iter().filter(|&&b| b).count()
    }
}

/// What a pixel's centre sees: the plane of its surface (unit normal, offset) and the share.
#[derive(Debug, Clone, Copy)]
struct Seen {
    normal: DVec3,
    offset: f64,
    share: f64,
}

impl Seen {
    /// 0 in umbra, 2 lit, 1 in penumbra.
    fn state(&self) -> u8 {
        if self.share <= 0.0 {
            0
        } else if self.share >= 1.0 {
            2
        } else {
            1
        }
    }

    fn same_plane(&self, other: &Seen, diagonal: f64) -> bool {
        1.0 - self.normal.dot(other.normal) <= SAME_PLANE
            && (self.offset - other.offset).abs() <= SAME_PLANE * diagonal
    }
}

/// The shadow map of `scene`'s camera at `width` x `height` pixels.
pub fn shadow_map(scene: &Scene, width: u32, height: u32) -> Result<ShadowMap> {
    let cam = CameraRays::new(&scene.camera, width, height)?;
    let tracer = Tracer::new(scene, Some(0));
    let (w, h) = (width as usize, height as usize);
    let seen: Vec<Option<Seen>> = (0..h)
        .into_par_iter()
        .flat_map_iter(|y| {
            let (cam, tracer) = (&cam, &tracer);
            (0..w).map(move |x| {
                let (o, d) = cam.ray(x as f64 + 0.5, y as f64 + 0.5);
                let Surface::Front { polygon, point } = tracer.trace_from_outside(o, d) else {
                    return None;
                };
                let normal = scene.polygons[polygon as usize].normal;
                let share = tracer.unblocked_share(polygon, point, LIGHT_GRID)?;
                Some(Seen {
                    normal,
                    offset: normal.dot(point),
                    share,
                })
            })
        })
        .collect();
    let (lo, hi) = scene.bounds();
    let diagonal = (hi - lo).length().max(f64::MIN_POSITIVE);
    let mut boundary = vec![false; w * h];
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            let right = (x + 1 < w).then_some(i + 1);
            let below = (y + 1 < h).then_some(i + w);
            for j in [right, below].into_iter().flatten() {
                if let (Some(a), Some(b)) = (seen[i], seen[j]) {
                    if a.state() != b.state() && a.same_plane(&b, diagonal) {
                        boundary[i] = true;
                        boundary[j] = true;
                    }
                }
            }
        }
    }
    Ok(ShadowMap {
        width,
        height,
        share: seen.iter().map(|s| s.map(|s| s.share)).collect(),
        boundary,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use scene::{Camera, Material, Polygon, Projection};

    fn quad(corners: [[f64; 3]; 4], material: u32) -> Polygon {
        Polygon::quad(corners.map(DVec3::from), material, 0).unwrap()
    }

    /// A floor under a square light, with a wall standing across it, seen from straight
    /// above by an orthographic camera: the umbra and penumbra the wall's top edge casts
    /// behind it lie where the similar triangles put them, and the boundary's pixels at their
    /// edges (and at the wall's foot, the line of a hard shadow).
    #[test]
    fn a_walls_penumbra_has_the_width_of_similar_triangles() {
        // The floor z = 0 over [-2, 2]^2, facing up; a light of side 1 at height 2 facing
        // down, centred at x = -1; a wall x = 0 of height 1 across the floor.
        let light = quad(
            [
                [-1.5, -0.5, 2.0],
                [-1.5, 0.5, 2.0],
                [-0.5, 0.5, 2.0],
                [-0.5, -0.5, 2.0],
            ],
            1,
        );
        let floor = quad(
            [
                [-2.0, -2.0, 0.0],
                [2.0, -2.0, 0.0],
                [2.0, 2.0, 0.0],
                [-2.0, 2.0, 0.0],
            ],
            0,
        );
        let wall = quad(
            [
                [0.0, -2.0, 0.0],
                [0.0, 2.0, 0.0],
                [0.0, 2.0, 1.0],
                [0.0, -2.0, 1.0],
            ],
            0,
        );
        let m = |r: f64, e: f64| Material {
            name: format!("m{r}{e}"),
            reflectance: DVec3::splat(r),
            emission: DVec3::splat(e),
        };
        let camera = Camera {
            eye: DVec3::new(0.0, 0.0, 1.5),
            look_at: DVec3::new(0.0, 0.0, 0.0),
            up: DVec3::Y,
            projection: Projection::Orthographic {
                width: 4.0,
                height: 4.0,
            },
        };
        // 400 pixels across 4 m: 1 cm each, pixel x covers [-2 + x / 100, -2 + (x + 1) / 100).
        let scene = Scene::new(
            camera,
            400,
            4,
            vec![m(0.5, 0.0), m(0.0, 5.0)],
            vec![floor, wall, light],
        );
        let map = shadow_map(&scene, 400, 4).unwrap();
        // A floor point at x > 0 sees the light past the wall's top (0, 1) where the light's
        // x > -x (similar triangles, light at twice the wall's height): umbra up to x = 0.5,
        // penumbra to 1.5, lit beyond. The lattice's outermost points lie 1/32 inside the
        // light's edges, so the exact states hold outside a lattice cell of each edge.
        let row: Vec<Option<f64>> = map.share[..400].to_vec();
        let centre = |x: usize| -2.0 + (x as f64 + 0.5) / 100.0;
        let cell = 1.0 / 16.0;
        for (x, s) in row.iter().enumerate() {
            let cx = centre(x);
            let s = s.unwrap_or_else(|| panic!("pixel {x} sees the lit floor"));
            if cx < -0.01 || cx > 1.5 + cell {
                assert_eq!(s, 1.0, "pixel {x} at {cx} is lit");
            } else if cx > 0.01 && cx < 0.5 - cell {
                assert_eq!(s, 0.0, "pixel {x} at {cx} is in umbra");
            } else if cx > 0.5 + cell && cx < 1.5 - cell {
                assert!(s > 0.0 && s < 1.0, "pixel {x} at {cx} is in penumbra: {s}");
                // The visible share grows from 0 to 1 across the penumbra, not linearly
                // (the cosines and distances change), but within a quarter of linear.
                assert!((s - (cx - 0.5)).abs() < 0.25, "pixel {x} at {cx}: {s}");
            }
        }
        // Boundary pixels behind the wall lie at the penumbra's two edges, each within a
        // lattice cell of the light (1/16 of its width, projected: at most 0.0625 m).
        let edges: Vec<f64> = (0..400)
            .filter(|&x| map.boundary[x])
            .map(centre)
            .filter(|&cx| cx > 0.02)
            .collect();
        assert!(!edges.is_empty());
        for cx in &edges {
            let near = (cx - 0.5).abs().min((cx - 1.5).abs());
            assert!(
                near <= 0.07,
                "boundary pixel at {cx}: not at a penumbra edge"
            );
        }
        assert!(edges.iter().any(|cx| (cx - 0.5).abs() <= 0.07));
        assert!(edges.iter().any(|cx| (cx - 1.5).abs() <= 0.07));
    }
}
