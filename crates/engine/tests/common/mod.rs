//! Scenes and patch sources shared by the engine's test binaries (the integration tests and the
//! instruction-set variant checks).

#![allow(dead_code)]

use engine::shading::{PatchCoeffs, PatchSource};
use glam::DVec3;
use scene::{Camera, Material, Polygon, Projection, Scene};

pub(crate) fn scene_with(polygons: Vec<Polygon>, camera: Camera, width: u32, height: u32) -> Scene {
    let grey = Material {
        name: "grey".into(),
        reflectance: DVec3::splat(0.5),
        emission: DVec3::ZERO,
    };
    Scene::new(camera, width, height, vec![grey], polygons)
}

/// n x n patches per polygon, each with its own (discontinuous) bicubic coefficients.
pub(crate) struct GridSource {
    pub n: u32,
    pub patches: Vec<PatchCoeffs>,
}

impl GridSource {
    pub(crate) fn new(polygons: u32, n: u32) -> Self {
        let mut patches = Vec::new();
        for p in 0..polygons {
            for j in 0..n {
                for i in 0..n {
                    let mut c = [[0.0f32; 16]; 3];
                    for (ch, row) in c.iter_mut().enumerate() {
                        for (k, x) in row.iter_mut().enumerate() {
                            let h = (p * 131 + j * 31 + i * 17 + ch as u32 * 7 + k as u32 * 3) % 13;
                            *x = h as f32 / 13.0 - 0.25 + if k == 0 { 1.0 } else { 0.0 };
                        }
                    }
                    patches.push(PatchCoeffs {
                        c,
                        u0: i as f32 / n as f32,
                        v0: j as f32 / n as f32,
                        inv_w: n as f32,
                        bilinear: false,
                    });
                }
            }
        }
        GridSource { n, patches }
    }
}

impl PatchSource for GridSource {
    fn locate(&self, polygon: u32, u: f32, v: f32) -> u32 {
        let n = self.n;
        let i = ((u * n as f32) as u32).min(n - 1);
        let j = ((v * n as f32) as u32).min(n - 1);
        polygon * n * n + j * n + i
    }
    fn patch(&self, id: u32) -> PatchCoeffs {
        self.patches[id as usize]
    }
}

/// Orthographic camera looking down -z at the z = 0 plane, world (x, y) -> pixel (x, h - y).
pub(crate) fn ortho_pixels(w: u32, h: u32) -> Camera {
    let (cx, cy) = (w as f64 / 2.0, h as f64 / 2.0);
    Camera {
        eye: DVec3::new(cx, cy, 10.0),
        look_at: DVec3::new(cx, cy, 0.0),
        up: DVec3::Y,
        projection: Projection::Orthographic {
            width: w as f64,
            height: h as f64,
        },
    }
}

/// A mesh of quads and triangles over [-8, w + 8] x [-8, h + 8] with jittered vertices; `centre`
/// puts every vertex on a pixel centre (world x = i + 0.5, y = h - (j + 0.5)).
pub(crate) fn mesh(
    w: u32,
    h: u32,
    cell: i32,
    centre: bool,
    map: impl Fn(f64, f64) -> DVec3,
) -> Vec<Polygon> {
    let nx = (w as i32 + 16) / cell + 1;
    let ny = (h as i32 + 16) / cell + 1;
    let vert = |i: i32, j: i32| {
        let jx = ((i * 7 + j * 13) % 3) - 1;
        let jy = ((i * 11 + j * 5) % 3) - 1;
        let (px, py) = ((i * cell - 8 + jx) as f64, (j * cell - 8 + jy) as f64);
        let (px, py) = if centre {
            (px + 0.5, py + 0.5)
        } else {
            (px + 0.37 * jx as f64, py + 0.21 * jy as f64)
        };
        map(px, h as f64 - py)
    };
    let mut polys = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            // Counter-clockwise in world (y up): (i, j+1) bottom-left in world terms.
            let a = vert(i, j + 1);
            let b = vert(i + 1, j + 1);
            let c = vert(i + 1, j);
            let d = vert(i, j);
            match (i + 2 * j) % 3 {
                0 => polys.push(Polygon::quad([a, b, c, d], 0, 0).unwrap()),
                1 => {
                    polys.push(Polygon::triangle([a, b, c], 0, 0).unwrap());
                    polys.push(Polygon::triangle([a, c, d], 0, 0).unwrap());
                }
                _ => {
                    polys.push(Polygon::triangle([a, b, d], 0, 0).unwrap());
                    polys.push(Polygon::triangle([b, c, d], 0, 0).unwrap());
                }
            }
        }
    }
    polys
}

/// Overlapping quads and triangles at several depths, two of them coplanar and overlapping
/// (the polygon-id tie-break decides), one crossing the near plane.
pub(crate) fn busy_scene(w: u32, h: u32) -> Scene {
    let mut polys = Vec::new();
    for k in 0..24 {
        let f = k as f64;
        let z = -2.0 - (k % 5) as f64 * 0.7;
        let (x, y) = ((f * 0.37).sin() * 1.5, (f * 0.53).cos() * 1.2);
        let tilt = 0.3 * (f * 0.7).sin();
        let p = |dx: f64, dy: f64| DVec3::new(x + dx, y + dy, z + tilt * dx);
        if k % 3 == 0 {
            polys
                .push(Polygon::triangle([p(-0.9, -0.7), p(1.1, -0.5), p(0.1, 1.0)], 0, 0).unwrap());
        } else {
            polys.push(
                Polygon::quad(
                    [p(-1.0, -0.8), p(0.9, -0.9), p(1.2, 0.8), p(-0.8, 1.0)],
                    0,
                    0,
                )
                .unwrap(),
            );
        }
    }
    // Coplanar pair.
    let q = |x0: f64| {
        Polygon::quad(
            [
                DVec3::new(x0, -0.5, -1.5),
                DVec3::new(x0 + 1.0, -0.5, -1.5),
                DVec3::new(x0 + 1.0, 0.5, -1.5),
                DVec3::new(x0, 0.5, -1.5),
            ],
            0,
            0,
        )
        .unwrap()
    };
    polys.push(q(-0.6));
    polys.push(q(-0.2));
    // Floor through the eye plane.
    polys.push(
        Polygon::quad(
            [
                DVec3::new(-5.0, -1.5, 3.0),
                DVec3::new(5.0, -1.5, 3.0),
                DVec3::new(5.0, -1.5, -9.0),
                DVec3::new(-5.0, -1.5, -9.0),
            ],
            0,
            0,
        )
        .unwrap(),
    );
    let camera = Camera {
        eye: DVec3::ZERO,
        look_at: -DVec3::Z,
        up: DVec3::Y,
        projection: Projection::Perspective { fov_y_deg: 70.0 },
    };
    scene_with(polys, camera, w, h)
}

/// A perspective camera looking obliquely down at the origin of the z = 0 plane from above
/// and in front, 60 degrees vertical field of view: the test meshes' oblique view.
pub(crate) fn oblique_camera() -> Camera {
    Camera {
        eye: DVec3::new(0.3, -2.0, 4.0),
        look_at: DVec3::ZERO,
        up: DVec3::Y,
        projection: Projection::Perspective { fov_y_deg: 60.0 },
    }
}

/// busy_scene (perspective: quads, triangles, a floor clipped at the near plane), the jittered
/// mesh seen orthographically (with a parallelogram over it) and the same mesh seen obliquely.
pub(crate) fn lane_test_scenes() -> Vec<(&'static str, Scene)> {
    let (w, h) = (97, 61);
    let mut flat = mesh(w, h, 8, false, |x, y| DVec3::new(x, y, 0.0));
    // A parallelogram in front of the mesh: the orthographic linear-inverse kernel.
    let p = |x: f64, y: f64| DVec3::new(x, y, 0.5);
    flat.push(
        Polygon::quad(
            [p(10.3, 5.2), p(60.7, 5.2), p(70.1, 40.9), p(19.7, 40.9)],
            0,
            0,
        )
        .unwrap(),
    );
    let ortho = scene_with(flat, ortho_pixels(w, h), w, h);
    let oblique = mesh(w, h, 8, false, |x, y| {
        DVec3::new(x / 113.0 * 40.0 - 20.0, y / 77.0 * 40.0 - 20.0, 0.0)
    });
    let camera = oblique_camera();
    vec![
        ("busy", busy_scene(150, 100)),
        ("ortho mesh", ortho),
        ("oblique mesh", scene_with(oblique, camera, w, h)),
    ]
}

impl GridSource {
    /// The same grid with awkward patches mixed in: every 5th polygon's patches are degree
    /// (1, 1) (flagged `bilinear`, the Gouraud mesh's form), and one patch in 7 has an
    /// infinite, a NaN or a huge coefficient (the shaders' clamp must give 0 for what is not
    /// finite and positive, alike in every build).
    pub(crate) fn with_awkward_patches(mut self) -> Self {
        let n2 = (self.n * self.n) as usize;
        for (k, p) in self.patches.iter_mut().enumerate() {
            if (k / n2) % 5 == 1 {
                let mut c = p.c;
                for row in c.iter_mut() {
                    for (i, x) in row.iter_mut().enumerate() {
                        if ![0, 1, 4, 5].contains(&i) {
                            *x = 0.0;
                        }
                    }
                }
                let (u0, v0, inv_w) = (p.u0, p.v0, p.inv_w);
                *p = PatchCoeffs::whole(c);
                (p.u0, p.v0, p.inv_w) = (u0, v0, inv_w);
                assert!(p.bilinear);
            }
            match k % 7 {
                2 => p.c[0][3] = f32::INFINITY,
                4 => p.c[1][0] = f32::NAN,
                6 => p.c[2][5] = -3e38,
                _ => {}
            }
        }
        self
    }
}
