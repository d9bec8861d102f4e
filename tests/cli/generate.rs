//! `generate building`: the polygon count against a closed form, loading with the project's own
//! loader (from memory, no files), an emitter in every room, determinism, closed rooms (every
//! floor point under exactly one floor quad, surface areas), faces pointing into the air, no
//! T-junctions, the shipped buildings equal to the generator's output, and the
//! command line (exit codes, the polygon count printed, the files written).

use fixtures::generate::{
    generate_building, room_box, write_building, BuildingOptions, BuildingPaths, DOOR_HEIGHT,
    DOOR_WIDTH, MAX_POLYGONS, ROOM_DEPTH, ROOM_HEIGHT, ROOM_WIDTH, WALL,
};
use glam::DVec3;
use scene::{parse_scene_with, Scene, Shape};
use std::path::{Path, PathBuf};
use std::process::Output;

fn options(rooms_x: u32, rooms_z: u32, floors: u32, cut: u32) -> BuildingOptions {
    BuildingOptions {
        floors,
        cut,
        ..BuildingOptions::new(rooms_x, rooms_z)
    }
}

/// Generates `o` as `/virtual/b.toml` and loads it through the project's loader, the OBJ and MTL
/// read from memory.
fn load(o: &BuildingOptions) -> (fixtures::generate::Building, Scene) {
    let paths = BuildingPaths::for_output(Path::new("/virtual/b.toml")).unwrap();
    let b = generate_building(o, &paths).unwrap();
    let (obj, mtl) = (b.obj.clone(), b.mtl.clone());
    let (obj_path, mtl_path) = (paths.obj.clone(), paths.mtl.clone());
    let read = move |p: &Path| -> std::io::Result<String> {
        if p == obj_path {
            Ok(obj.clone())
        } else if p == mtl_path {
            Ok(mtl.clone())
        } else {
            Err(std::io::Error::new(
                std::io::ErrorKind::NotFound,
                "no such file",
            ))
        }
    };
    // The generator's own geometry: not cut along the contact lines of its furniture (which
    // the loader adds on load).
    let toml = b
        .toml
        .replace("[radiosity]", "[radiosity]\ncut_contacts = false");
    let scene = parse_scene_with(&toml, &paths.scene, &read).unwrap();
    (b, scene)
}

/// The closed form, written out independently of the library: every room has a floor of 3 x 3
/// cells, a ceiling and four walls; a doorway turns two walls of 1 cell into 5 each and adds 4
/// cells of lining; each cell is cut K x K; lights and furniture (5 faces each) are never cut.
fn expected_polygons(o: &BuildingOptions) -> u64 {
    let (x, z, f, k) = (
        o.rooms_x as u64,
        o.rooms_z as u64,
        o.floors as u64,
        o.cut as u64,
    );
    let rooms = x * z * f;
    let doors = f * ((x - 1) * z + x * (z - 1));
    k * k * (rooms * (9 + 1 + 4) + doors * (2 * 4 + 4))
        + rooms * (o.lights as u64 + 5 * o.furniture as u64)
}

/// The objects (`b/<group>`) of polygon `i`.
fn object(scene: &Scene, i: usize) -> &str {
    &scene.objects[scene.polygons[i].object as usize]
}

fn rooms(o: &BuildingOptions) -> Vec<(String, DVec3, DVec3)> {
    let mut out = Vec::new();
    for f in 0..o.floors {
        for iz in 0..o.rooms_z {
            for ix in 0..o.rooms_x {
                let (lo, hi) = room_box(f, ix, iz);
                out.push((format!("b/s{f}_x{ix}_z{iz}"), lo, hi));
            }
        }
    }
    out
}

#[test]
fn polygon_count_matches_the_closed_form_and_the_loaded_scene() {
    let mut cases = vec![
        options(1, 1, 1, 1),
        options(2, 1, 1, 1),
        options(1, 3, 1, 2),
        options(3, 2, 1, 3),
        options(2, 2, 2, 2),
        options(4, 4, 1, 5),
    ];
    cases.push(BuildingOptions {
        lights: 1,
        furniture: 0,
        ..options(2, 3, 1, 2)
    });
    cases.push(BuildingOptions {
        furniture: 4,
        seed: 99,
        ..options(3, 1, 2, 1)
    });
    for o in &cases {
        let (b, scene) = load(o);
        let n = expected_polygons(o);
        assert_eq!(o.polygon_count(), n, "{o:?}");
        assert_eq!(b.polygons, n, "{o:?}");
        assert_eq!(scene.polygons.len() as u64, n, "{o:?}");
        assert!(
            b.summary.ends_with(&format!(": {n} polygons")),
            "{}",
            b.summary
        );
        // Every face is a planar convex quad: nothing split, refused or warned about.
        assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
        assert!(scene.polygons.iter().all(|p| p.shape == Shape::Quad));
        assert_eq!(
            scene.emitter_count() as u64,
            o.room_count() * o.lights as u64
        );
    }
    // The shipped sizes: about 1k, 4k, 10k and 40k polygons are one option away.
    assert_eq!(options(4, 4, 1, 1).polygon_count(), 784);
    assert_eq!(options(4, 4, 1, 3).polygon_count(), 4_880);
    assert_eq!(options(4, 4, 1, 5).polygon_count(), 13_072);
    assert_eq!(options(4, 4, 1, 9).polygon_count(), 41_744);
}

#[test]
fn every_room_has_a_ceiling_panel_facing_down() {
    let o = options(3, 2, 2, 1);
    let (_, scene) = load(&o);
    for (name, lo, hi) in rooms(&o) {
        let panels = (0..scene.polygons.len())
            .filter(|&i| {
                let p = &scene.polygons[i];
                let c = p.centroid();
                scene.material_of(i).is_emitter()
                    && c.cmpgt(lo).all()
                    && c.cmplt(hi).all()
                    && p.normal.y < -0.999
                    && hi.y - c.y < 0.02
            })
            .count();
        assert_eq!(panels, 2, "{name}");
    }
    let o1 = BuildingOptions {
        lights: 1,
        ..options(2, 1, 1, 1)
    };
    assert_eq!(load(&o1).1.emitter_count(), 2);
}

#[test]
fn same_options_give_the_same_bytes() {
    let paths = BuildingPaths::for_output(Path::new("scenes/x.toml")).unwrap();
    let o = options(3, 2, 2, 2);
    let a = generate_building(&o, &paths).unwrap();
    let b = generate_building(&o, &paths).unwrap();
    assert_eq!(a, b);
    // Another seed moves the furniture, not the count.
    let c = generate_building(
        &BuildingOptions {
            seed: 7,
            ..o.clone()
        },
        &paths,
    )
    .unwrap();
    assert_ne!(a.obj, c.obj);
    assert_eq!(a.polygons, c.polygons);
    // A room's furniture does not depend on the size of the grid: room (0, 0)'s group lines
    // and vertices are the same in a 1 x 1 and a 3 x 2 building.
    let small = generate_building(&options(1, 1, 1, 2), &paths).unwrap();
    let crates = |b: &fixtures::generate::Building| -> Vec<String> {
        b.obj
            .lines()
            .filter(|l| l.starts_with("g s0_x0_z0_crate") || l.starts_with("g s0_x0_z0_pillar"))
            .map(str::to_string)
            .collect()
    };
    assert_eq!(crates(&small), crates(&a));
    // The files on disk are the same bytes, written twice.
    let dir = scratch("determinism");
    let mut seen = Vec::new();
    for _ in 0..2 {
        let w = write_building(&base::output::Outputs::new(), &o, &dir.join("b.toml")).unwrap();
        let p = &w.paths;
        seen.push(
            [p.scene.clone(), p.obj.clone(), p.mtl.clone()].map(|f| std::fs::read(f).unwrap()),
        );
    }
    assert_eq!(seen[0], seen[1]);
    // Nothing but the three files (no temporaries left).
    let mut names: Vec<_> = walk(&dir);
    names.sort();
    assert_eq!(names.len(), 3, "{names:?}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Whether the axis-aligned quad `p` covers the point (x, z) of its plane, strictly inside.
fn covers_xz(p: &scene::Polygon, x: f64, z: f64) -> bool {
    let (lo, hi) = p
        .corners
        .iter()
        .fold((DVec3::MAX, DVec3::MIN), |(a, b), c| (a.min(*c), b.max(*c)));
    lo.x < x && x < hi.x && lo.z < z && z < hi.z
}

#[test]
fn rooms_are_closed_floors_covered_once_and_areas_add_up() {
    for o in [options(2, 2, 2, 3), options(3, 1, 1, 1)] {
        let (_, scene) = load(&o);
        let area_of = |object_name: &str| -> (f64, Vec<usize>) {
            let ids: Vec<usize> = (0..scene.polygons.len())
                .filter(|&i| object(&scene, i) == object_name)
                .collect();
            (ids.iter().map(|&i| scene.polygons[i].area).sum(), ids)
        };
        let door = DOOR_WIDTH * DOOR_HEIGHT;
        let (w, h, d) = (ROOM_WIDTH, ROOM_HEIGHT, ROOM_DEPTH);
        for (name, lo, hi) in rooms(&o) {
            let (floor, ids) = area_of(&format!("{name}_floor"));
            assert!(
                (floor - w * d).abs() < 1e-9 * w * d,
                "{name}: floor {floor}"
            );
            let (ceiling, _) = area_of(&format!("{name}_ceiling"));
            assert!(
                (ceiling - w * d).abs() < 1e-9 * w * d,
                "{name}: ceiling {ceiling}"
            );
            // Every point of the floor (on a grid that avoids the cut lines) lies in exactly
            // one floor quad, and every floor quad lies in the room.
            for &i in &ids {
                let p = &scene.polygons[i];
                assert!(p.normal.y > 0.999 && (p.corners[0].y - lo.y).abs() < 1e-12);
                for c in p.corners {
                    assert!(
                        c.cmpge(lo - 1e-9).all() && c.cmple(hi + 1e-9).all(),
                        "{name}"
                    );
                }
            }
            for a in 0..37 {
                for b in 0..37 {
                    let (x, z) = (
                        lo.x + w * (a as f64 + 0.5) / 37.0,
                        lo.z + d * (b as f64 + 0.5) / 37.0,
                    );
                    let n = ids
                        .iter()
                        .filter(|&&i| covers_xz(&scene.polygons[i], x, z))
                        .count();
                    assert_eq!(n, 1, "{name}: floor point ({x}, {z}) under {n} quads");
                }
            }
            // Walls: full, or full minus one doorway.
            let parts: Vec<&str> = name.split('_').collect();
            let ix: u32 = parts[1][1..].parse().unwrap();
            let iz: u32 = parts[2][1..].parse().unwrap();
            for (wall, span, door_here) in [
                ("west", d, ix > 0),
                ("east", d, ix + 1 < o.rooms_x),
                ("south", w, iz > 0),
                ("north", w, iz + 1 < o.rooms_z),
            ] {
                let (a, _) = area_of(&format!("{name}_wall_{wall}"));
                let want = span * h - if door_here { door } else { 0.0 };
                assert!(
                    (a - want).abs() < 1e-9 * want,
                    "{name} {wall}: {a} != {want}"
                );
            }
        }
    }
}

/// An axis-aligned box.
#[derive(Clone, Copy, Debug)]
struct Aabb(DVec3, DVec3);

impl Aabb {
    fn contains(&self, p: DVec3) -> bool {
        p.cmpgt(self.0).all() && p.cmplt(self.1).all()
    }
}

#[test]
fn faces_point_into_the_air() {
    let o = BuildingOptions {
        furniture: 4,
        ..options(3, 2, 2, 2)
    };
    let (_, scene) = load(&o);
    // Air: the rooms and the doorways between them, minus the furniture.
    let mut air: Vec<Aabb> = Vec::new();
    for f in 0..o.floors {
        for iz in 0..o.rooms_z {
            for ix in 0..o.rooms_x {
                let (lo, hi) = room_box(f, ix, iz);
                air.push(Aabb(lo, hi));
                let (cx, cz) = ((lo.x + hi.x) / 2.0, (lo.z + hi.z) / 2.0);
                let half = DOOR_WIDTH / 2.0;
                let top = lo.y + DOOR_HEIGHT;
                if ix + 1 < o.rooms_x {
                    air.push(Aabb(
                        DVec3::new(hi.x - 0.01, lo.y, cz - half),
                        DVec3::new(hi.x + WALL + 0.01, top, cz + half),
                    ));
                }
                if iz + 1 < o.rooms_z {
                    air.push(Aabb(
                        DVec3::new(cx - half, lo.y, hi.z - 0.01),
                        DVec3::new(cx + half, top, hi.z + WALL + 0.01),
                    ));
                }
            }
        }
    }
    let mut solids: Vec<Aabb> = Vec::new();
    for obj in 0..scene.objects.len() {
        let name = &scene.objects[obj];
        if !(name.contains("_crate") || name.contains("_pillar")) {
            continue;
        }
        let (lo, hi) = scene
            .polygons
            .iter()
            .filter(|p| p.object as usize == obj)
            .flat_map(|p| p.corners)
            .fold((DVec3::MAX, DVec3::MIN), |(a, b), c| (a.min(c), b.max(c)));
        solids.push(Aabb(lo, hi));
    }
    assert_eq!(solids.len() as u64, o.room_count() * 4);
    let is_air =
        |p: DVec3| air.iter().any(|b| b.contains(p)) && !solids.iter().any(|b| b.contains(p));
    for (i, p) in scene.polygons.iter().enumerate() {
        let c = p.centroid();
        // 5 mm: less than the light panels' 1 cm gap below the ceiling, more than rounding.
        // Furniture stands on the floor, so a floor quad may face the bottom of a box: floors
        // need only face a room.
        let front = c + 0.005 * p.normal;
        let floor = object(&scene, i).ends_with("_floor");
        assert!(
            is_air(front) || (floor && air.iter().any(|b| b.contains(front))),
            "polygon {i} ({}) faces no air",
            object(&scene, i)
        );
        let lit_panel = scene.material_of(i).is_emitter();
        if !lit_panel {
            assert!(
                !is_air(c - 0.005 * p.normal),
                "polygon {i} ({}) has air behind it",
                object(&scene, i)
            );
        }
    }
}

#[test]
fn coplanar_neighbours_share_corners() {
    // No corner of a quad lies inside an edge of a coplanar quad (a T-junction), within 1e-9.
    let (_, scene) = load(&options(2, 2, 1, 2));
    let key = |p: &scene::Polygon| {
        let axis = p.normal.abs().max_position();
        (axis, (p.corners[0][axis] * 1e4).round() as i64)
    };
    let mut planes: std::collections::HashMap<(usize, i64), Vec<usize>> = Default::default();
    for (i, p) in scene.polygons.iter().enumerate() {
        planes.entry(key(p)).or_default().push(i);
    }
    for ids in planes.values() {
        for &a in ids {
            let pa = &scene.polygons[a];
            for k in 0..4 {
                let (e0, e1) = (pa.corners[k], pa.corners[(k + 1) % 4]);
                let len = (e1 - e0).length();
                for &b in ids {
                    for c in scene.polygons[b].corners {
                        let t = (c - e0).dot(e1 - e0) / (len * len);
                        let off = (e0 + t * (e1 - e0) - c).length();
                        let inside = t * len > 1e-9 && (1.0 - t) * len > 1e-9;
                        assert!(
                            !(inside && off < 1e-9),
                            "T-junction: corner {c} of polygon {b} inside an edge of {a} ({})",
                            object(&scene, a)
                        );
                    }
                }
            }
        }
    }
}

#[test]
fn a_one_room_building_solves() {
    let (_, scene) = load(&options(1, 1, 1, 1));
    let sol = radiosity::solve(&scene, &Default::default()).unwrap();
    assert!(sol.stats.unshot_fraction <= scene.radiosity.convergence);
    // Light reaches every polygon of the closed room.
    for (i, tree) in sol.polygons.iter().enumerate() {
        let lit = tree.values.iter().any(|v| v.max_element() > 0.0);
        assert!(lit, "polygon {i} ({}) is black", object(&scene, i));
    }
}

/// The shipped buildings: `scenes/building.toml` (8 x 8 rooms, the scale benchmark) and
/// `scenes/accuracy/building-2x1.toml` (two rooms through a doorway, the results page's
/// building), each the generator's output for the command on its first line.
#[test]
fn the_shipped_buildings_are_the_generator_output() {
    check_shipped_building("scenes/building.toml", options(8, 8, 1, 2), 10_000);
    check_shipped_building(
        "scenes/accuracy/building-2x1.toml",
        options(2, 1, 1, 2),
        190,
    );
}

/// The shipped scene `rel` (with its OBJ and MTL) is what the generator writes for `o`, holds at
/// least `min_polygons` and loads with the floors cut where furniture stands on them.
fn check_shipped_building(rel: &str, o: BuildingOptions, min_polygons: u64) {
    let root = Path::new(crate::REPO);
    let scene_path = root.join(rel);
    let toml = std::fs::read_to_string(&scene_path).unwrap();
    // Its first line is the command that made it; run that command's options here.
    let first = toml.lines().next().unwrap();
    let paths = BuildingPaths::for_output(Path::new(rel)).unwrap();
    assert_eq!(
        first,
        format!("# GENERATED by: {}", o.command(&paths.scene))
    );
    let b = generate_building(&o, &paths).unwrap();
    assert!(b.polygons >= min_polygons, "{rel}: {}", b.polygons);
    assert!(
        toml == b.toml,
        "{rel} differs from the generator; run the command on its first line"
    );
    for (file, generated) in [(&paths.obj, &b.obj), (&paths.mtl, &b.mtl)] {
        let text = std::fs::read_to_string(root.join(file)).unwrap();
        assert!(
            &text == generated,
            "{} differs from the generator",
            file.display()
        );
    }
    let scene = scene::load_scene(&scene_path).unwrap();
    // Loaded, the floors are cut where the furniture stands on them, and the tiles beside the
    // cut pieces through the T-junctions that leaves.
    let (cut, pieces) = scene.contacts.counts();
    let (t_cut, t_pieces) = scene.junctions.counts();
    assert!(cut > 0, "{rel}");
    assert_eq!(
        scene.polygons.len() as u64,
        b.polygons - cut as u64 + pieces as u64 - t_cut as u64 + t_pieces as u64,
        "{rel}"
    );
}

// The command line.

fn run(args: &[&str]) -> Output {
    crate::bin()
        .args(args)
        .current_dir(crate::REPO)
        .output()
        .expect("the binary runs")
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("pfs-gen-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn walk(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            out.extend(walk(&p));
        } else {
            out.push(p);
        }
    }
    out
}

#[test]
fn cli_writes_the_files_and_prints_the_polygon_count() {
    let dir = scratch("cli");
    let out = run(&[
        "generate",
        "building",
        "--rooms-x",
        "2",
        "--rooms-z",
        "3",
        "--cut",
        "2",
        "-o",
        dir.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let n = options(2, 3, 1, 2).polygon_count();
    assert!(
        text(&out.stdout)
            .trim_end()
            .ends_with(&format!(": {n} polygons")),
        "{}",
        text(&out.stdout)
    );
    for f in [
        "building.toml",
        "building/building.obj",
        "building/building.mtl",
    ] {
        assert!(dir.join(f).is_file(), "{f}");
        assert!(text(&out.stderr).contains(&format!("wrote {}", dir.join(f).display())));
    }
    // The written scene passes `check`.
    let check = run(&[
        "check",
        dir.join("building.toml").to_str().unwrap(),
        "-D",
        "radiosity.cut_contacts=false",
    ]);
    assert_eq!(check.status.code(), Some(0), "{}", text(&check.stderr));
    assert!(text(&check.stdout).contains(&format!("polygons        {n} ({n} quads, 0 triangles)")));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn cli_bad_options_exit_2_and_write_nothing() {
    let dir = scratch("bad");
    let o = dir.join("b.toml");
    let o = o.to_str().unwrap();
    let cases: &[(&[&str], &str)] = &[
        (
            &["--rooms-x", "0", "--rooms-z", "1"],
            "--rooms-x 0: must be at least 1",
        ),
        (
            &["--rooms-x", "1", "--rooms-z", "0"],
            "--rooms-z 0: must be at least 1",
        ),
        (
            &["--rooms-x", "2", "--rooms-z", "2", "--floors", "0"],
            "--floors 0",
        ),
        (
            &["--rooms-x", "2", "--rooms-z", "2", "--cut", "0"],
            "--cut 0: must be at least 1",
        ),
        (
            &["--rooms-x", "2", "--rooms-z", "2", "--lights", "3"],
            "--lights 3: a room has 1 or 2",
        ),
        (
            &["--rooms-x", "2", "--rooms-z", "2", "--furniture", "5"],
            "--furniture 5: at most 4",
        ),
        (
            &["--rooms-x", "1001", "--rooms-z", "1"],
            "--rooms-x: 1001 exceeds the limit of 1000",
        ),
        (
            &["--rooms-x", "100", "--rooms-z", "100", "--cut", "10"],
            "generated polygons: 37930000 exceeds the limit of 1000000",
        ),
        (
            &["--rooms-x", "-1", "--rooms-z", "1"],
            "unexpected argument '-1'",
        ),
        (
            &["--rooms-x", "two", "--rooms-z", "1"],
            "invalid value 'two'",
        ),
        (&["--rooms-z", "1"], "--rooms-x <N>"),
    ];
    for (args, message) in cases {
        let mut all = vec!["generate", "building"];
        all.extend_from_slice(args);
        all.extend_from_slice(&["-o", o]);
        let out = run(&all);
        assert_eq!(
            out.status.code(),
            Some(2),
            "{args:?}: {}",
            text(&out.stderr)
        );
        assert!(
            text(&out.stderr).contains(message),
            "{args:?}: {}",
            text(&out.stderr)
        );
        assert!(text(&out.stdout).is_empty());
    }
    // A scene name that cannot name the OBJ, and an output that is a directory.
    let bad = dir.join("a b.toml");
    let out = run(&[
        "generate",
        "building",
        "--rooms-x",
        "1",
        "--rooms-z",
        "1",
        "-o",
        bad.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out.stderr));
    std::fs::create_dir_all(dir.join("d.toml")).unwrap();
    let out = run(&[
        "generate",
        "building",
        "--rooms-x",
        "1",
        "--rooms-z",
        "1",
        "-o",
        dir.join("d.toml").to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out.stderr));
    assert!(
        text(&out.stderr).contains("is a directory"),
        "{}",
        text(&out.stderr)
    );
    assert!(walk(&dir).is_empty(), "{:?}", walk(&dir));
    assert_eq!(MAX_POLYGONS, 1_000_000);
    std::fs::remove_dir_all(&dir).unwrap();
}
