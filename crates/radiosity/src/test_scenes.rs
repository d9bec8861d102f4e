//! Scenes built in code for the solver's tests and timings (the scene loader is a separate
//! stage): a spot over a plane, the furnace box, a two-spots room, the Cornell box from the
//! McGuire OBJ data.

use glam::DVec3;

use scene::{Camera, Material, Polygon, Projection, Scene, SpotLight, PLANARITY_TOLERANCE};

/// A material.
pub(crate) fn mat(name: &str, rho: [f64; 3], e: [f64; 3]) -> Material {
    Material {
        name: name.to_string(),
        reflectance: DVec3::from_array(rho),
        emission: DVec3::from_array(e),
    }
}

/// A scene from parts, with default settings.
pub(crate) fn scene(
    polygons: Vec<Polygon>,
    materials: Vec<Material>,
    spots: Vec<SpotLight>,
) -> Scene {
    let camera = Camera {
        eye: DVec3::new(0.0, 0.0, 5.0),
        look_at: DVec3::ZERO,
        up: DVec3::Y,
        projection: Projection::Perspective { fov_y_deg: 45.0 },
    };
    let mut scene = Scene::new(camera, 64, 64, materials, polygons);
    scene.spots = spots;
    scene
}

/// A quad with its winding chosen so the normal points towards `toward`.
pub(crate) fn quad_facing(mut c: [DVec3; 4], toward: DVec3, material: u32) -> Polygon {
    let p = Polygon::quad(c, material, 0).expect("test quad");
    if p.normal.dot(toward - p.centroid()) < 0.0 {
        c.reverse();
        return Polygon::quad(c, material, 0).expect("test quad");
    }
    p
}

/// The unit square in the plane z = 0, facing +z (material 0).
pub(crate) fn unit_square() -> Polygon {
    let c = [
        DVec3::new(0.0, 0.0, 0.0),
        DVec3::new(1.0, 0.0, 0.0),
        DVec3::new(1.0, 1.0, 0.0),
        DVec3::new(0.0, 1.0, 0.0),
    ];
    quad_facing(c, DVec3::new(0.5, 0.5, 1.0), 0)
}

/// The six inward faces of an axis-aligned cube of side `size` centred at the origin, with their
/// inward normals.
pub(crate) fn cube_faces(size: f64) -> Vec<([DVec3; 4], DVec3)> {
    box_faces(DVec3::splat(-size / 2.0), DVec3::splat(size / 2.0), true)
        .into_iter()
        .map(|p| (p.corners, p.normal))
        .collect()
}

/// The six faces of the box [lo, hi], facing inwards or outwards, material 0.
pub(crate) fn box_faces(lo: DVec3, hi: DVec3, inward: bool) -> Vec<Polygon> {
    let c = 0.5 * (lo + hi);
    let p = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
    let faces = [
        [
            p(lo.x, lo.y, lo.z),
            p(hi.x, lo.y, lo.z),
            p(hi.x, hi.y, lo.z),
            p(lo.x, hi.y, lo.z),
        ],
        [
            p(lo.x, lo.y, hi.z),
            p(hi.x, lo.y, hi.z),
            p(hi.x, hi.y, hi.z),
            p(lo.x, hi.y, hi.z),
        ],
        [
            p(lo.x, lo.y, lo.z),
            p(lo.x, hi.y, lo.z),
            p(lo.x, hi.y, hi.z),
            p(lo.x, lo.y, hi.z),
        ],
        [
            p(hi.x, lo.y, lo.z),
            p(hi.x, hi.y, lo.z),
            p(hi.x, hi.y, hi.z),
            p(hi.x, lo.y, hi.z),
        ],
        [
            p(lo.x, lo.y, lo.z),
            p(hi.x, lo.y, lo.z),
            p(hi.x, lo.y, hi.z),
            p(lo.x, lo.y, hi.z),
        ],
        [
            p(lo.x, hi.y, lo.z),
            p(hi.x, hi.y, lo.z),
            p(hi.x, hi.y, hi.z),
            p(lo.x, hi.y, hi.z),
        ],
    ];
    faces
        .into_iter()
        .map(|f| {
            let fc = f.iter().copied().sum::<DVec3>() / 4.0;
            // Inward faces look at the centre; outward faces look away from it.
            let toward = if inward { c } else { fc + (fc - c) };
            quad_facing(f, toward, 0)
        })
        .collect()
}

/// The furnace: a closed unit cube, every face E = 1, rho = 0.5.
pub(crate) fn furnace() -> Scene {
    let polys = box_faces(DVec3::ZERO, DVec3::ONE, true);
    let mut s = scene(polys, vec![mat("f", [0.5; 3], [1.0; 3])], vec![]);
    s.radiosity.convergence = 1e-3;
    s
}

/// A 4 x 4 floor at z = 0 (facing +z) under one spot at height 2, no other surfaces.
pub(crate) fn spot_over_plane() -> Scene {
    let floor = quad_facing(
        [
            DVec3::new(-2.0, -2.0, 0.0),
            DVec3::new(2.0, -2.0, 0.0),
            DVec3::new(2.0, 2.0, 0.0),
            DVec3::new(-2.0, 2.0, 0.0),
        ],
        DVec3::Z,
        0,
    );
    let spot = SpotLight {
        position: DVec3::new(0.3, -0.2, 2.0),
        direction: DVec3::new(0.1, 0.05, -1.0).normalize(),
        intensity: DVec3::new(10.0, 8.0, 6.0),
        half_angle: 50f64.to_radians(),
        falloff: 3.0,
    };
    scene(
        vec![floor],
        vec![mat("grey", [0.6, 0.5, 0.4], [0.0; 3])],
        vec![spot],
    )
}

/// A room 6 x 6 x 3 (inward faces, grey) with two narrow spots on the floor.
pub(crate) fn two_spots() -> Scene {
    let polys = box_faces(DVec3::new(-3.0, -3.0, 0.0), DVec3::new(3.0, 3.0, 3.0), true);
    let spot = |x: f64| SpotLight {
        position: DVec3::new(x, 0.0, 2.9),
        direction: -DVec3::Z,
        intensity: DVec3::splat(20.0),
        half_angle: 20f64.to_radians(),
        falloff: 1.0,
    };
    scene(
        polys,
        vec![mat("grey", [0.5; 3], [0.0; 3])],
        vec![spot(-1.5), spot(1.5)],
    )
}

/// The Cornell box's quads, (material, corners) in OBJ order: floor, ceiling, back, right, left,
/// short box, tall box, light.
const CORNELL_QUADS: [(u32, [[f64; 3]; 4]); 18] = [
    (
        0,
        [
            [-1.01, 0.0, 0.99],
            [1.0, 0.0, 0.99],
            [1.0, 0.0, -1.04],
            [-0.99, 0.0, -1.04],
        ],
    ),
    (
        0,
        [
            [-1.02, 1.99, 0.99],
            [-1.02, 1.99, -1.04],
            [1.0, 1.99, -1.04],
            [1.0, 1.99, 0.99],
        ],
    ),
    (
        0,
        [
            [-0.99, 0.0, -1.04],
            [1.0, 0.0, -1.04],
            [1.0, 1.99, -1.04],
            [-1.02, 1.99, -1.04],
        ],
    ),
    (
        2,
        [
            [1.0, 0.0, -1.04],
            [1.0, 0.0, 0.99],
            [1.0, 1.99, 0.99],
            [1.0, 1.99, -1.04],
        ],
    ),
    (
        1,
        [
            [-1.01, 0.0, 0.99],
            [-0.99, 0.0, -1.04],
            [-1.02, 1.99, -1.04],
            [-1.02, 1.99, 0.99],
        ],
    ),
    (
        0,
        [
            [0.53, 0.6, 0.75],
            [0.7, 0.6, 0.17],
            [0.13, 0.6, 0.0],
            [-0.05, 0.6, 0.57],
        ],
    ),
    (
        0,
        [
            [-0.05, 0.0, 0.57],
            [-0.05, 0.6, 0.57],
            [0.13, 0.6, 0.0],
            [0.13, 0.0, 0.0],
        ],
    ),
    (
        0,
        [
            [0.53, 0.0, 0.75],
            [0.53, 0.6, 0.75],
            [-0.05, 0.6, 0.57],
            [-0.05, 0.0, 0.57],
        ],
    ),
    (
        0,
        [
            [0.7, 0.0, 0.17],
            [0.7, 0.6, 0.17],
            [0.53, 0.6, 0.75],
            [0.53, 0.0, 0.75],
        ],
    ),
    (
        0,
        [
            [0.13, 0.0, 0.0],
            [0.13, 0.6, 0.0],
            [0.7, 0.6, 0.17],
            [0.7, 0.0, 0.17],
        ],
    ),
    (
        0,
        [
            [-0.05, 0.0, 0.57],
            [0.13, 0.0, 0.0],
            [0.7, 0.0, 0.17],
            [0.53, 0.0, 0.75],
        ],
    ),
    (
        0,
        [
            [-0.53, 1.2, 0.09],
            [0.04, 1.2, -0.09],
            [-0.14, 1.2, -0.67],
            [-0.71, 1.2, -0.49],
        ],
    ),
    (
        0,
        [
            [-0.53, 0.0, 0.09],
            [-0.53, 1.2, 0.09],
            [-0.71, 1.2, -0.49],
            [-0.71, 0.0, -0.49],
        ],
    ),
    (
        0,
        [
            [-0.71, 0.0, -0.49],
            [-0.71, 1.2, -0.49],
            [-0.14, 1.2, -0.67],
            [-0.14, 0.0, -0.67],
        ],
    ),
    (
        0,
        [
            [-0.14, 0.0, -0.67],
            [-0.14, 1.2, -0.67],
            [0.04, 1.2, -0.09],
            [0.04, 0.0, -0.09],
        ],
    ),
    (
        0,
        [
            [0.04, 0.0, -0.09],
            [0.04, 1.2, -0.09],
            [-0.53, 1.2, 0.09],
            [-0.53, 0.0, 0.09],
        ],
    ),
    (
        0,
        [
            [-0.53, 0.0, 0.09],
            [0.04, 0.0, -0.09],
            [-0.14, 0.0, -0.67],
            [-0.71, 0.0, -0.49],
        ],
    ),
    (
        3,
        [
            [-0.24, 1.98, 0.16],
            [-0.24, 1.98, -0.22],
            [0.23, 1.98, -0.22],
            [0.23, 1.98, 0.16],
        ],
    ),
];

/// The Cornell box from the McGuire archive data (CornellBox-Original.obj), 18 quads including the
/// light (Ke 17 12 4). Quads farther from planar than [`PLANARITY_TOLERANCE`] are split into two
/// triangles like the loader does; the short box's bottom face, which the OBJ writes with the
/// right face's vertices, is built from its own corner list instead (it lies on the floor and
/// receives nothing either way).
pub(crate) fn cornell() -> Scene {
    let quads = CORNELL_QUADS
        .iter()
        .map(|&(m, c)| (m, c.map(DVec3::from_array)));
    let mut polys = Vec::new();
    for (m, c) in quads {
        let diag = (c[2] - c[0]).length().max((c[3] - c[1]).length());
        let n = scene::newell_normal(&c).normalize();
        let off = n.dot(c[3] - c[0]).abs().max(n.dot(c[2] - c[0]).abs());
        if off > PLANARITY_TOLERANCE * diag {
            polys.push(Polygon::triangle([c[0], c[1], c[2]], m, 0).expect("tri"));
            polys.push(Polygon::triangle([c[0], c[2], c[3]], m, 0).expect("tri"));
        } else {
            polys.push(Polygon::quad(c, m, 0).expect("quad"));
        }
    }
    let white = [0.725, 0.71, 0.68];
    scene(
        polys,
        vec![
            mat("white", white, [0.0; 3]),
            mat("red", [0.63, 0.065, 0.05], [0.0; 3]),
            mat("green", [0.14, 0.45, 0.091], [0.0; 3]),
            mat("light", [0.78; 3], [17.0, 12.0, 4.0]),
        ],
        vec![],
    )
}

/// A closed room 2 x 2 x 2 (z up, inward faces, rho 0.5 0.6 0.7) whose ceiling emits 3 2 1,
/// with a closed box (outward faces, rho 0.8) floating 0.3 above the floor: no light can leave
/// and no back face can be seen, so every emitted watt is absorbed or still unshot.
pub(crate) fn closed_room_with_box() -> Scene {
    let mut polys = box_faces(DVec3::ZERO, DVec3::splat(2.0), true);
    // Face 1 is the ceiling (z = 2).
    polys[1].material = 1;
    let inner = box_faces(DVec3::new(0.5, 0.6, 0.3), DVec3::new(1.2, 1.3, 1.0), false);
    polys.extend(inner.into_iter().map(|mut p| {
        p.material = 2;
        p
    }));
    scene(
        polys,
        vec![
            mat("walls", [0.5, 0.6, 0.7], [0.0; 3]),
            mat("ceiling", [0.5, 0.6, 0.7], [3.0, 2.0, 1.0]),
            mat("box", [0.8; 3], [0.0; 3]),
        ],
        vec![],
    )
}
