//! The Gouraud mesh through the rasterizer: a polygon's adaptive mesh (T-vertex fans) covers
//! exactly the pixels the polygon covers. Seen so that pixel = 128 u, lattice points down to
//! depth 7 land on exact fixed-point positions, so the coverage must be identical, with no
//! crack and no double cover along the T-junctions.

use base::quadtree::{Quadtree, SampledQuadtree};
use engine::raster::build_primitives;
use engine::raster::region::coverage_counts;
use glam::{DVec3, Vec3};
use proptest::prelude::*;
use reconstruction::mesh::MeshModel;
use scene::{Camera, Material, Polygon, Projection, Scene};

/// A scene with one polygon, seen orthographically from +z over [0, 1]^2 at `size` pixels.
fn scene_of(polygon: Polygon, size: u32) -> Scene {
    let camera = Camera {
        eye: DVec3::new(0.5, 0.5, 2.0),
        look_at: DVec3::new(0.5, 0.5, 0.0),
        up: DVec3::Y,
        projection: Projection::Orthographic {
            width: 1.0,
            height: 1.0,
        },
    };
    let m = Material {
        name: "white".into(),
        reflectance: DVec3::splat(0.5),
        emission: DVec3::ZERO,
    };
    Scene::new(camera, size, size, vec![m], vec![polygon])
}

fn unit_square(size: u32) -> Scene {
    let q = [DVec3::ZERO, DVec3::X, DVec3::new(1.0, 1.0, 0.0), DVec3::Y];
    scene_of(Polygon::quad(q, 0, 0).unwrap(), size)
}

fn unit_triangle(size: u32) -> Scene {
    scene_of(
        Polygon::triangle([DVec3::ZERO, DVec3::X, DVec3::Y], 0, 0).unwrap(),
        size,
    )
}

fn coverage(scene: &Scene, size: u32) -> Vec<u32> {
    let prims = build_primitives(scene, &scene.camera, size, size, false).unwrap();
    coverage_counts(&prims, size, size, 32)
}

/// A tree grown by splitting, in turn, the leaf `sel % leaf_count` (if above `max_level`).
fn grow(sels: &[u32], max_level: u32) -> Quadtree {
    let mut t = Quadtree::new();
    for &s in sels {
        let leaves = t.leaves();
        let id = leaves[s as usize % leaves.len()];
        if t.node(id).cell.level < max_level {
            t.split(id);
        }
    }
    t
}

/// The mesh of `scene`'s one polygon under `tree` covers what the polygon covers.
fn check(scene: &Scene, tree: Quadtree, size: u32) {
    let sq = SampledQuadtree::from_fn(tree, |u, v| Vec3::new(u as f32, v as f32, 1.0));
    let mesh = MeshModel::build(scene, std::slice::from_ref(&sq)).unwrap();
    assert_eq!(coverage(&mesh.scene, size), coverage(scene, size));
}

#[test]
fn t_vertices_of_a_level_three_grid_leave_no_crack() {
    // A level-2 grid with two leaves split again: 7 T-vertices.
    let mut t = Quadtree::new();
    let c = t.split(0);
    for k in 0..4 {
        t.split(c + k);
    }
    for (x, y) in [(0, 1), (2, 1)] {
        let id = (0..t.nodes().len() as u32)
            .find(|&i| t.node(i).cell == base::quadtree::Cell { level: 2, x, y })
            .unwrap();
        t.split(id);
    }
    assert_eq!(t.t_vertices().len(), 7);
    check(&unit_square(64), t, 64);
}

#[test]
fn a_triangle_parent_covers_like_the_triangle() {
    let mut t = Quadtree::new();
    let c = t.split(0);
    for k in 0..4 {
        t.split(c + k);
    }
    check(&unit_triangle(32), t, 32);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn random_trees_cover_like_the_square(sels in prop::collection::vec(any::<u32>(), 0..60)) {
        check(&unit_square(128), grow(&sels, 7), 128);
    }

    /// The triangle (0,0), (1,0), (0,1): its map (x, y) = ((1 - v) u, v) takes lattice points to
    /// dyadic positions, exact on the fixed-point grid.
    #[test]
    fn random_trees_cover_like_the_triangle(sels in prop::collection::vec(any::<u32>(), 0..60)) {
        check(&unit_triangle(128), grow(&sels, 7), 128);
    }
}
