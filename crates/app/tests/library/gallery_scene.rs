//! The generator of `scenes/gallery/gallery.obj` and `gallery.mtl`, and the test that keeps the
//! committed files equal to its output.
//!
//! The gallery is three rooms in a row along +x (each 8 m x 4 m x 6 m inside, 0.2 m walls)
//! joined by 2 m x 3 m doorways, with pillars, pedestals, a free-standing partition and a
//! hanging baffle as occluders, two window openings in the middle room's front wall, and two
//! emissive ceiling panels per room. Spot lights live in `scenes/gallery.toml`. Floors, ceilings
//! and walls are tiled in 1 m quads, so the scene has about 900 polygons, nearly all quads.
//!
//! Orientation: every face is written counter-clockwise seen from the air it faces, so room
//! surfaces face inward and the surfaces of pillars and other solids face outward. The test
//! `gallery_faces_point_into_the_air` checks this on the loaded scene: a point just in front of
//! each polygon is in the air, a point just behind it is not.
//!
//! To regenerate after changing the generator, run
//! `PFS_REGENERATE=1 cargo test --release -p pixelflow-app --test library gallery_scene`: with
//! that variable set the test writes the files instead of comparing them.

use glam::DVec3;
use scene::{load_scene_with, LoadOptions, Shape};
use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::Path;

/// Inside size of a room: x, y (height), z.
const ROOM: [f64; 3] = [8.0, 4.0, 6.0];
/// Wall thickness between rooms and of the outer walls' openings.
const WALL: f64 = 0.2;
/// Number of rooms.
const ROOMS: usize = 3;

/// An axis-aligned box (min, max).
#[derive(Clone, Copy)]
struct Aabb(DVec3, DVec3);

impl Aabb {
    fn contains(&self, p: DVec3) -> bool {
        p.cmpge(self.0).all() && p.cmple(self.1).all()
    }
}

fn room_x0(k: usize) -> f64 {
    k as f64 * (ROOM[0] + WALL)
}

/// The outward normal of a face and its two in-plane axes (du x dv = normal).
#[derive(Clone, Copy)]
enum Facing {
    PosX,
    NegX,
    PosY,
    NegY,
    PosZ,
    NegZ,
}

impl Facing {
    /// (axis along u, axis along v, normal axis), as indices 0..3.
    fn axes(self) -> (usize, usize, usize) {
        match self {
            Facing::PosX => (1, 2, 0),
            Facing::NegX => (2, 1, 0),
            Facing::PosY => (2, 0, 1),
            Facing::NegY => (0, 2, 1),
            Facing::PosZ => (0, 1, 2),
            Facing::NegZ => (1, 0, 2),
        }
    }
}

struct Builder {
    faces: Vec<(String, &'static str, [DVec3; 4])>,
    air: Vec<Aabb>,
    solids: Vec<Aabb>,
}

impl Builder {
    /// A rectangle facing `facing` at `level` on its normal axis, spanning `a` on the u axis
    /// and `b` on the v axis, tiled in `na` x `nb` quads; `skip(i, j)` leaves a tile out.
    #[allow(clippy::too_many_arguments)]
    fn rect(
        &mut self,
        group: &str,
        material: &'static str,
        facing: Facing,
        level: f64,
        a: (f64, f64),
        b: (f64, f64),
        na: usize,
        nb: usize,
        skip: impl Fn(usize, usize) -> bool,
    ) {
        let (ua, va, na_axis) = facing.axes();
        let point = |s: f64, t: f64| {
            let mut p = [0.0; 3];
            p[ua] = s;
            p[va] = t;
            p[na_axis] = level;
            DVec3::from_array(p)
        };
        for j in 0..nb {
            for i in 0..na {
                if skip(i, j) {
                    continue;
                }
                let s0 = a.0 + (a.1 - a.0) * i as f64 / na as f64;
                let s1 = a.0 + (a.1 - a.0) * (i + 1) as f64 / na as f64;
                let t0 = b.0 + (b.1 - b.0) * j as f64 / nb as f64;
                let t1 = b.0 + (b.1 - b.0) * (j + 1) as f64 / nb as f64;
                let q = [point(s0, t0), point(s1, t0), point(s1, t1), point(s0, t1)];
                self.faces.push((group.to_string(), material, q));
            }
        }
    }

    /// The outward faces of a solid box (no bottom if it stands on the floor, no top if it
    /// touches the ceiling), tiled so no tile is much longer than `tile`.
    fn solid(&mut self, group: &str, material: &'static str, b: Aabb, tile: f64) {
        let (lo, hi) = (b.0, b.1);
        let n = |len: f64| ((len / tile).round() as usize).max(1);
        let (nx, ny, nz) = (n(hi.x - lo.x), n(hi.y - lo.y), n(hi.z - lo.z));
        let all = |_: usize, _: usize| false;
        self.rect(
            group,
            material,
            Facing::NegX,
            lo.x,
            (lo.z, hi.z),
            (lo.y, hi.y),
            nz,
            ny,
            all,
        );
        self.rect(
            group,
            material,
            Facing::PosX,
            hi.x,
            (lo.y, hi.y),
            (lo.z, hi.z),
            ny,
            nz,
            all,
        );
        self.rect(
            group,
            material,
            Facing::NegZ,
            lo.z,
            (lo.y, hi.y),
            (lo.x, hi.x),
            ny,
            nx,
            all,
        );
        self.rect(
            group,
            material,
            Facing::PosZ,
            hi.z,
            (lo.x, hi.x),
            (lo.y, hi.y),
            nx,
            ny,
            all,
        );
        if hi.y < ROOM[1] {
            self.rect(
                group,
                material,
                Facing::PosY,
                hi.y,
                (lo.z, hi.z),
                (lo.x, hi.x),
                nz,
                nx,
                all,
            );
        }
        if lo.y > 0.0 {
            self.rect(
                group,
                material,
                Facing::NegY,
                lo.y,
                (lo.x, hi.x),
                (lo.z, hi.z),
                nx,
                nz,
                all,
            );
        }
        self.solids.push(b);
    }
}

/// Builds the whole gallery: faces (group, material, corners) plus the air and solid boxes the
/// orientation test uses.
fn build() -> Builder {
    let mut g = Builder {
        faces: Vec::new(),
        air: Vec::new(),
        solids: Vec::new(),
    };
    let [w, h, d] = ROOM;
    let never = |_: usize, _: usize| false;
    // Doorway between room k and k + 1: z in [2, 4], y in [0, 3]; wall tiles are 1 m, so tiles
    // (z index 2..4, y index 0..3) are left out.
    let door = |i_z: usize, j_y: usize| (2..4).contains(&i_z) && j_y < 3;
    for k in 0..ROOMS {
        let x0 = room_x0(k);
        let x1 = x0 + w;
        let r = format!("room{k}");
        g.air
            .push(Aabb(DVec3::new(x0, 0.0, 0.0), DVec3::new(x1, h, d)));
        g.rect(
            &format!("{r}_floor"),
            "floor",
            Facing::PosY,
            0.0,
            (0.0, d),
            (x0, x1),
            6,
            8,
            never,
        );
        g.rect(
            &format!("{r}_ceiling"),
            "ceiling",
            Facing::NegY,
            h,
            (x0, x1),
            (0.0, d),
            8,
            6,
            never,
        );
        // -x wall faces +x: u along y, v along z.
        let door_left = k > 0;
        g.rect(
            &format!("{r}_wall_west"),
            "wall",
            Facing::PosX,
            x0,
            (0.0, h),
            (0.0, d),
            4,
            6,
            |i, j| door_left && door(j, i),
        );
        // +x wall faces -x: u along z, v along y.
        let door_right = k + 1 < ROOMS;
        g.rect(
            &format!("{r}_wall_east"),
            "wall",
            Facing::NegX,
            x1,
            (0.0, d),
            (0.0, h),
            6,
            4,
            |i, j| door_right && door(i, j),
        );
        // z = 0 wall faces +z: u along x, v along y. The middle room has two windows.
        let windows = k == 1;
        let window = |i: usize, j: usize| windows && j == 2 && matches!(i, 1 | 2 | 5 | 6);
        g.rect(
            &format!("{r}_wall_south"),
            "wall",
            Facing::PosZ,
            0.0,
            (x0, x1),
            (0.0, h),
            8,
            4,
            window,
        );
        // z = d wall faces -z: u along y, v along x.
        g.rect(
            &format!("{r}_wall_north"),
            "wall",
            Facing::NegZ,
            d,
            (0.0, h),
            (x0, x1),
            4,
            8,
            never,
        );
        // Window reveals in the south wall (openings to the outside, 0.2 m deep).
        if windows {
            for (a, b) in [(1.0, 3.0), (5.0, 7.0)] {
                let (xa, xb) = (x0 + a, x0 + b);
                let gr = format!("{r}_window_{a}");
                g.rect(
                    &gr,
                    "wall",
                    Facing::PosY,
                    2.0,
                    (-WALL, 0.0),
                    (xa, xb),
                    1,
                    2,
                    never,
                );
                g.rect(
                    &gr,
                    "wall",
                    Facing::NegY,
                    3.0,
                    (xa, xb),
                    (-WALL, 0.0),
                    2,
                    1,
                    never,
                );
                g.rect(
                    &gr,
                    "wall",
                    Facing::PosX,
                    xa,
                    (2.0, 3.0),
                    (-WALL, 0.0),
                    1,
                    1,
                    never,
                );
                g.rect(
                    &gr,
                    "wall",
                    Facing::NegX,
                    xb,
                    (-WALL, 0.0),
                    (2.0, 3.0),
                    1,
                    1,
                    never,
                );
                g.air
                    .push(Aabb(DVec3::new(xa, 2.0, -WALL), DVec3::new(xb, 3.0, 0.0)));
            }
        }
        // Doorway passage through the wall to the next room.
        if door_right {
            let (xa, xb) = (x1, x1 + WALL);
            let gr = format!("{r}_doorway");
            g.rect(
                &gr,
                "floor",
                Facing::PosY,
                0.0,
                (2.0, 4.0),
                (xa, xb),
                2,
                1,
                never,
            );
            g.rect(
                &gr,
                "wall",
                Facing::NegY,
                3.0,
                (xa, xb),
                (2.0, 4.0),
                1,
                2,
                never,
            );
            g.rect(
                &gr,
                "wall",
                Facing::PosZ,
                2.0,
                (xa, xb),
                (0.0, 3.0),
                1,
                3,
                never,
            );
            g.rect(
                &gr,
                "wall",
                Facing::NegZ,
                4.0,
                (0.0, 3.0),
                (xa, xb),
                3,
                1,
                never,
            );
            g.air
                .push(Aabb(DVec3::new(xa, 0.0, 2.0), DVec3::new(xb, 3.0, 4.0)));
        }
        // Two ceiling light panels, 1 m square, 1 cm below the ceiling, facing down.
        for a in [1.5, 5.5] {
            g.rect(
                &format!("{r}_light_{a}"),
                "light",
                Facing::NegY,
                h - 0.01,
                (x0 + a, x0 + a + 1.0),
                (2.5, 3.5),
                1,
                1,
                never,
            );
        }
    }
    // Pillars (0.4 m square, floor to ceiling) at lattice corners, so tile centres stay free.
    let pillar = |x: f64, z: f64| {
        Aabb(
            DVec3::new(x - 0.2, 0.0, z - 0.2),
            DVec3::new(x + 0.2, ROOM[1], z + 0.2),
        )
    };
    let x1 = room_x0(1);
    for (i, (x, z)) in [
        (4.0, 1.0),
        (4.0, 5.0),
        (x1 + 2.0, 2.0),
        (x1 + 2.0, 4.0),
        (x1 + 6.0, 2.0),
        (x1 + 6.0, 4.0),
    ]
    .into_iter()
    .enumerate()
    {
        g.solid(&format!("pillar{i}"), "stone", pillar(x, z), 0.5);
    }
    // Pedestals (0.6 m square, 1 m high).
    let pedestal = |x: f64, z: f64| {
        Aabb(
            DVec3::new(x - 0.3, 0.0, z - 0.3),
            DVec3::new(x + 0.3, 1.0, z + 0.3),
        )
    };
    let x2 = room_x0(2);
    for (i, (x, z)) in [
        (2.0, 4.0),
        (6.0, 2.0),
        (x1 + 4.0, 3.0),
        (x2 + 6.0, 1.0),
        (x2 + 6.0, 5.0),
    ]
    .into_iter()
    .enumerate()
    {
        g.solid(&format!("pedestal{i}"), "pedestal", pedestal(x, z), 1.0);
    }
    // A free-standing partition in the last room and a baffle hung under a light of the middle
    // room: occluders with sharp shadows.
    g.solid(
        "partition",
        "partition",
        Aabb(
            DVec3::new(x2 + 3.0, 0.0, 1.0),
            DVec3::new(x2 + 3.2, 2.5, 3.5),
        ),
        0.5,
    );
    g.solid(
        "baffle",
        "baffle",
        Aabb(
            DVec3::new(x1 + 5.4, 3.2, 2.4),
            DVec3::new(x1 + 6.6, 3.3, 3.6),
        ),
        0.4,
    );
    g
}

/// A coordinate in the shortest decimal form with at most 4 decimals, `-0` written as `0`.
fn num(x: f64) -> String {
    let s = format!("{:.4}", x + 0.0);
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" || s.is_empty() {
        "0".to_string()
    } else {
        s.to_string()
    }
}

/// The OBJ and MTL texts.
fn generate() -> (String, String) {
    let g = build();
    let mut obj = String::new();
    obj.push_str(
        "# Gallery: three rooms joined by doorways, with pillars, pedestals, a partition, a\n\
         # hanging baffle, two window openings and emissive ceiling panels.\n\
         # GENERATED by crates/app/tests/library/gallery_scene.rs; regenerate with\n\
         # PFS_REGENERATE=1 cargo test --release -p pixelflow-app --test library gallery_scene\n\
         mtllib gallery.mtl\n",
    );
    let mut index: HashMap<String, usize> = HashMap::new();
    let mut order: Vec<String> = Vec::new();
    let mut faces: Vec<(String, &str, [usize; 4])> = Vec::new();
    for (group, mat, q) in &g.faces {
        let mut ids = [0; 4];
        for (slot, c) in q.iter().enumerate() {
            let key = format!("{} {} {}", num(c.x), num(c.y), num(c.z));
            let next = order.len() + 1;
            let id = *index.entry(key.clone()).or_insert_with(|| {
                order.push(key);
                next
            });
            ids[slot] = id;
        }
        faces.push((group.clone(), mat, ids));
    }
    for v in &order {
        let _ = writeln!(obj, "v {v}");
    }
    let mut current = (String::new(), "");
    for (group, mat, ids) in &faces {
        if *group != current.0 {
            let _ = writeln!(obj, "g {group}\nusemtl {mat}");
        } else if *mat != current.1 {
            let _ = writeln!(obj, "usemtl {mat}");
        }
        current = (group.clone(), mat);
        let _ = writeln!(obj, "f {} {} {} {}", ids[0], ids[1], ids[2], ids[3]);
    }
    let mtl = "# Materials of the gallery.\n\
               # GENERATED by crates/app/tests/library/gallery_scene.rs.\n\
               newmtl floor\nKd 0.45 0.42 0.38\nKe 0 0 0\n\n\
               newmtl ceiling\nKd 0.75 0.75 0.75\nKe 0 0 0\n\n\
               newmtl wall\nKd 0.7 0.68 0.62\nKe 0 0 0\n\n\
               newmtl stone\nKd 0.55 0.52 0.48\nKe 0 0 0\n\n\
               newmtl pedestal\nKd 0.6 0.2 0.15\nKe 0 0 0\n\n\
               newmtl partition\nKd 0.2 0.3 0.6\nKe 0 0 0\n\n\
               newmtl baffle\nKd 0.5 0.5 0.5\nKe 0 0 0\n\n\
               newmtl light\nKd 0.78 0.78 0.78\nKe 12 11 9\n"
        .to_string();
    (obj, mtl)
}

fn scenes_dir() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes"))
}

#[test]
fn gallery_files_match_the_generator() {
    let (obj, mtl) = generate();
    let dir = scenes_dir().join("gallery");
    if std::env::var_os("PFS_REGENERATE").is_some_and(|v| v == "1") {
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("gallery.obj"), &obj).unwrap();
        std::fs::write(dir.join("gallery.mtl"), &mtl).unwrap();
    }
    let on_disk_obj = std::fs::read_to_string(dir.join("gallery.obj")).unwrap();
    let on_disk_mtl = std::fs::read_to_string(dir.join("gallery.mtl")).unwrap();
    assert!(
        on_disk_obj == obj,
        "scenes/gallery/gallery.obj differs from the generator; run \
         PFS_REGENERATE=1 cargo test --release -p pixelflow-app --test library gallery_scene"
    );
    assert!(
        on_disk_mtl == mtl,
        "scenes/gallery/gallery.mtl differs from the generator"
    );
}

/// The gallery as the generator wrote it: not cut along its contact lines (the loader cuts the
/// floors under the pillars, pedestals and partition, which the generator does not know of).
fn load_uncut() -> scene::Scene {
    let opts = LoadOptions {
        overrides: vec![("radiosity.cut_contacts".into(), "false".into())],
        ..LoadOptions::default()
    };
    load_scene_with(&scenes_dir().join("gallery.toml"), &opts).unwrap()
}

#[test]
fn gallery_loads_with_every_face_a_valid_quad() {
    let g = build();
    let scene = load_uncut();
    // Every generated face is a planar convex quad, so none is split or refused.
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    assert_eq!(scene.polygons.len(), g.faces.len());
    assert!(scene.polygons.iter().all(|p| p.shape == Shape::Quad));
    assert!(
        (800..=1500).contains(&scene.polygons.len()),
        "{}",
        scene.polygons.len()
    );
    // Two 1 m^2 panels per room, all emitting.
    assert_eq!(scene.emitter_count(), 2 * ROOMS);
    for (p, (_, mat, q)) in scene.polygons.iter().zip(&g.faces) {
        assert_eq!(scene.materials[p.material as usize].name, *mat);
        // Coordinates are written with 4 decimals and are multiples of 0.01: exact after the
        // loader's decimal round trip, up to f64 rounding of the sums that built them.
        for (a, b) in p.corners.iter().zip(q) {
            assert!((*a - *b).abs().max_element() < 1e-9, "{a} vs {b}");
        }
    }
}

#[test]
fn gallery_faces_point_into_the_air() {
    let g = build();
    let scene = load_uncut();
    let is_air =
        |p: DVec3| g.air.iter().any(|b| b.contains(p)) && !g.solids.iter().any(|b| b.contains(p));
    // 2 cm is less than every thickness in the scene (walls 0.2, the baffle 0.1, the light's
    // gap to the ceiling 0.01 is only crossed forwards) and more than rounding.
    for (i, p) in scene.polygons.iter().enumerate() {
        let c = p.centroid();
        assert!(
            is_air(c + 0.02 * p.normal),
            "polygon {i} ({}) faces a solid: c {c} n {}",
            scene.objects[p.object as usize],
            p.normal
        );
        assert!(
            !is_air(c - 0.02 * p.normal),
            "polygon {i} ({}) has air behind it: c {c} n {}",
            scene.objects[p.object as usize],
            p.normal
        );
    }
}
