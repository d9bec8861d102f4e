//! Generated test scenes: an N-room building written as OBJ, MTL and a scene file that includes
//! them (`pixelflow-sim generate building`), so the solver and the renderers can be measured on
//! scenes of any size from about a hundred to a million polygons, which no hand-made scene covers.
//!
//! The building is a grid of `rooms_x` x `rooms_z` rooms on each of `floors` storeys. Every room
//! is closed (floor, ceiling and four walls, [`ROOM_WIDTH`] x [`ROOM_HEIGHT`] x [`ROOM_DEPTH`]
//! inside, walls and slabs [`WALL`] thick), every pair of neighbours on a storey is joined by a
//! doorway ([`DOOR_WIDTH`] x [`DOOR_HEIGHT`], centred in the wall, lined by its own floor, lintel
//! and two jambs), storeys are not connected, and there are no windows. Each room has one or two
//! emissive ceiling panels 1 cm below its ceiling and up to four boxes or pillars standing on its
//! floor, one per corner quadrant, so the cross of corridors between the doorways stays clear:
//! the generated camera stands in the first room and sees down the row of rooms through them.
//!
//! Invariants (tested in `tests/cli/generate.rs`):
//! - the polygon count is known before anything is built ([`BuildingOptions::polygon_count`], a
//!   closed form), so a request over [`MAX_POLYGONS`] is refused in microseconds;
//! - every face is an axis-aligned rectangle written counter-clockwise seen from the air it faces
//!   (room surfaces face into the room, furniture faces out), so every quad loads as a planar
//!   convex quad with no warning;
//! - no T-junctions inside a plane: each surface is first divided at the doorway edges (a wall
//!   with a doorway is the 3 x 2 grid of cells around its hole minus the hole, every floor the
//!   3 x 3 grid at the doorway lines) and each cell is then cut into `cut` x `cut` quads, so
//!   coplanar neighbours (a floor and its doorway's floor, the cells of a wall) share every
//!   corner along their common edge;
//! - the same options give the same bytes: coordinates are integers of 0.1 mm until they are
//!   printed (exact decimals, no float formatting), vertices are numbered in order of first use,
//!   and the furniture's pseudo-random numbers come from a fixed generator (SplitMix64) seeded
//!   per room from `seed` and the room's position, so a room's furniture does not change when the
//!   grid grows.
//!
//! Why this way: a generator in the library, rather than a test like the gallery's, lets users
//! dial scene sizes from the command line; quads rather than triangles because the loader keeps
//! quads whole and every polygon gets its own quadtree; furniture and light panels are never cut,
//! so `cut` scales only the shell (walls, floors, ceilings, doorways), which is what the solver's
//! cost grows with.

use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use glam::DVec3;

use base::error::{Error, Result};
use base::output::Outputs;

/// Most polygons a generated scene may have.
pub const MAX_POLYGONS: u64 = 1_000_000;
/// Most rooms along x or z (the polygon limit usually binds first).
pub(crate) const MAX_ROOMS_PER_AXIS: u32 = 1000;
/// Most storeys.
pub(crate) const MAX_FLOORS: u32 = 1000;
/// Largest `cut`.
pub(crate) const MAX_CUT: u32 = 1000;
/// Most furniture pieces per room (one per corner quadrant).
pub(crate) const MAX_FURNITURE: u32 = 4;

/// Default `cut`.
pub const DEFAULT_CUT: u32 = 1;
/// Default number of storeys.
pub const DEFAULT_FLOORS: u32 = 1;
/// Default number of ceiling light panels per room.
pub const DEFAULT_LIGHTS: u32 = 2;
/// Default number of furniture pieces per room.
pub const DEFAULT_FURNITURE: u32 = 3;
/// Default seed of the furniture's pseudo-random numbers.
pub const DEFAULT_SEED: u64 = 1;

/// Inside width of a room (along x), metres.
pub const ROOM_WIDTH: f64 = 6.0;
/// Inside depth of a room (along z), metres.
pub const ROOM_DEPTH: f64 = 6.0;
/// Inside height of a room (along y), metres.
pub const ROOM_HEIGHT: f64 = 3.0;
/// Thickness of walls and of the slabs between storeys, metres.
pub const WALL: f64 = 0.2;
/// Width of a doorway, metres.
pub const DOOR_WIDTH: f64 = 1.6;
/// Height of a doorway, metres.
pub const DOOR_HEIGHT: f64 = 2.2;

/// Faces of one furniture piece (four sides and a top; it stands on the floor).
const FURNITURE_FACES: u64 = 5;
/// Shell quads of a room before cutting: a floor of 3 x 3 cells, a ceiling and four walls.
const ROOM_CELLS: u64 = 9 + 1 + 4;
/// Extra cells per doorway: its two walls (5 cells instead of 1 each) and its lining (4).
const DOOR_CELLS: u64 = 2 * 4 + 4;

/// Coordinates are integers of this many metres (0.1 mm) until printed.
const UNIT: f64 = 1e-4;

/// Metres to units (every constant above is a whole number of units).
fn units(m: f64) -> i64 {
    (m / UNIT).round() as i64
}

/// The options of `generate building`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BuildingOptions {
    /// Rooms along x on each storey, 1 ..= `MAX_ROOMS_PER_AXIS`.
    pub rooms_x: u32,
    /// Rooms along z on each storey, 1 ..= `MAX_ROOMS_PER_AXIS`.
    pub rooms_z: u32,
    /// Storeys, 1 ..= `MAX_FLOORS`.
    pub floors: u32,
    /// Every shell cell is cut into `cut` x `cut` quads, 1 ..= `MAX_CUT`.
    pub cut: u32,
    /// Ceiling light panels per room, 1 or 2.
    pub lights: u32,
    /// Furniture pieces per room, 0 ..= `MAX_FURNITURE`.
    pub furniture: u32,
    /// Seed of the furniture's sizes and places.
    pub seed: u64,
}

impl BuildingOptions {
    /// A building of `rooms_x` x `rooms_z` rooms with every other option at its default.
    pub fn new(rooms_x: u32, rooms_z: u32) -> Self {
        BuildingOptions {
            rooms_x,
            rooms_z,
            floors: DEFAULT_FLOORS,
            cut: DEFAULT_CUT,
            lights: DEFAULT_LIGHTS,
            furniture: DEFAULT_FURNITURE,
            seed: DEFAULT_SEED,
        }
    }

    /// Checks every option, then the polygon count against [`MAX_POLYGONS`]. Errors name the
    /// command-line option ([`Error::InvalidOption`] or [`Error::ResourceLimit`], exit code 2).
    pub fn validate(&self) -> Result<()> {
        let at_least_one = |option: &str, v: u32, limit: u32| {
            if v == 0 {
                Err(Error::invalid_option(option, "0", "must be at least 1"))
            } else if v > limit {
                Err(Error::limit(option, v.into(), limit.into()))
            } else {
                Ok(())
            }
        };
        at_least_one("--rooms-x", self.rooms_x, MAX_ROOMS_PER_AXIS)?;
        at_least_one("--rooms-z", self.rooms_z, MAX_ROOMS_PER_AXIS)?;
        at_least_one("--floors", self.floors, MAX_FLOORS)?;
        at_least_one("--cut", self.cut, MAX_CUT)?;
        if !(1..=2).contains(&self.lights) {
            return Err(Error::invalid_option(
                "--lights",
                self.lights.to_string(),
                "a room has 1 or 2 ceiling light panels",
            ));
        }
        if self.furniture > MAX_FURNITURE {
            return Err(Error::invalid_option(
                "--furniture",
                self.furniture.to_string(),
                format!("at most {MAX_FURNITURE} pieces per room, one per corner quadrant"),
            ));
        }
        let n = self.polygon_count();
        if n > MAX_POLYGONS {
            return Err(Error::limit("generated polygons", n, MAX_POLYGONS));
        }
        Ok(())
    }

    /// Rooms in the whole building.
    pub fn room_count(&self) -> u64 {
        u64::from(self.rooms_x) * u64::from(self.rooms_z) * u64::from(self.floors)
    }

    /// Doorways in the whole building: one between every two neighbours on a storey.
    pub(crate) fn doorway_count(&self) -> u64 {
        let (x, z) = (u64::from(self.rooms_x), u64::from(self.rooms_z));
        ((x - 1) * z + x * (z - 1)) * u64::from(self.floors)
    }

    /// The number of polygons the building has, from the options alone:
    /// `cut^2 (14 rooms + 12 doorways) + rooms (lights + 5 furniture)`. Saturates instead of
    /// overflowing (options within their limits never come near).
    pub fn polygon_count(&self) -> u64 {
        let (rooms, doors) = (self.room_count(), self.doorway_count());
        let k2 = u64::from(self.cut) * u64::from(self.cut);
        let shell = (ROOM_CELLS * rooms)
            .saturating_add(DOOR_CELLS * doors)
            .saturating_mul(k2);
        let per_room = u64::from(self.lights) + FURNITURE_FACES * u64::from(self.furniture);
        shell.saturating_add(rooms.saturating_mul(per_room))
    }

    /// The command line that generates this building into `scene`, every option spelt out.
    pub fn command(&self, scene: &Path) -> String {
        format!(
            "pixelflow-sim generate building --rooms-x {} --rooms-z {} --floors {} --cut {} \
             --lights {} --furniture {} --seed {} -o {}",
            self.rooms_x,
            self.rooms_z,
            self.floors,
            self.cut,
            self.lights,
            self.furniture,
            self.seed,
            shell_word(&scene.display().to_string())
        )
    }
}

/// `text` quoted for a POSIX shell when it holds anything but safe characters.
fn shell_word(text: &str) -> String {
    let safe = |c: char| c.is_ascii_alphanumeric() || "-_./+,:=@%".contains(c);
    if !text.is_empty() && text.chars().all(safe) {
        text.to_string()
    } else {
        format!("'{}'", text.replace('\'', r"'\''"))
    }
}

/// The inside of a room: storey `floor`, column `ix` (along x), row `iz` (along z), as the box
/// (min, max) in metres. Room (0, 0, 0) spans x and z from 0, y from 0.
pub fn room_box(floor: u32, ix: u32, iz: u32) -> (DVec3, DVec3) {
    let lo = DVec3::new(
        f64::from(ix) * (ROOM_WIDTH + WALL),
        f64::from(floor) * (ROOM_HEIGHT + WALL),
        f64::from(iz) * (ROOM_DEPTH + WALL),
    );
    (lo, lo + DVec3::new(ROOM_WIDTH, ROOM_HEIGHT, ROOM_DEPTH))
}

/// Where a generated scene goes: the scene file and the OBJ and MTL files it includes (in a
/// directory named after the scene, beside it).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BuildingPaths {
    /// The scene file, `<dir>/<name>.toml`.
    pub scene: PathBuf,
    /// `<dir>/<name>/<name>.obj`.
    pub obj: PathBuf,
    /// `<dir>/<name>/<name>.mtl`.
    pub mtl: PathBuf,
}

impl BuildingPaths {
    /// The paths for `-o out`: a path ending in `.toml` names the scene file; any other path is
    /// a directory, and the scene is `<out>/building.toml`. The scene's name becomes the OBJ's
    /// directory and file names, so it must be letters, digits, `-` and `_`.
    pub fn for_output(out: &Path) -> Result<BuildingPaths> {
        let is_toml = out.extension().is_some_and(|e| e == "toml");
        let scene = if is_toml {
            out.to_path_buf()
        } else {
            out.join("building.toml")
        };
        let name = scene
            .file_stem()
            .and_then(|s| s.to_str())
            .filter(|s| {
                !s.is_empty()
                    && s.chars()
                        .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_')
            })
            .ok_or_else(|| {
                Error::invalid_option(
                    "-o",
                    out.display().to_string(),
                    "the scene's file name must be letters, digits, `-` and `_` before `.toml` \
                     (it also names the OBJ and MTL files)",
                )
            })?;
        let dir = scene.parent().unwrap_or(Path::new("")).join(name);
        Ok(BuildingPaths {
            obj: dir.join(format!("{name}.obj")),
            mtl: dir.join(format!("{name}.mtl")),
            scene,
        })
    }

    /// The scene's name (the file stem shared by all three files).
    fn name(&self) -> &str {
        self.obj.file_stem().and_then(|s| s.to_str()).unwrap_or("")
    }
}

/// A generated building: the three files' texts and what they hold.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Building {
    /// The scene file (camera, `[[obj]]` include, `[radiosity]`, `[render]`, `[display]`,
    /// `[camera_path]`), its first comment line the command that generates it.
    pub toml: String,
    /// The OBJ: every vertex once, one group per room surface, doorway or piece of furniture.
    pub obj: String,
    /// The MTL: the materials the OBJ uses, emitters with `Ke`.
    pub mtl: String,
    /// One line: rooms, doorways, lights, furniture and polygons (`2 rooms (2 x 1 on 1 storey),
    /// 1 doorway, ...: 74 polygons`).
    pub summary: String,
    /// Polygons (faces of the OBJ), equal to [`BuildingOptions::polygon_count`].
    pub polygons: u64,
    /// Rooms.
    pub rooms: u64,
    /// Doorways.
    pub doorways: u64,
    /// Emissive ceiling panels.
    pub lights: u64,
    /// Pieces of furniture.
    pub furniture: u64,
}

/// What [`write_building`] wrote.
#[derive(Debug, Clone)]
pub struct Written {
    /// The three paths.
    pub paths: BuildingPaths,
    /// The building (its texts, counts).
    pub building: Building,
}

/// The facing of an axis-aligned face: its normal's axis and sign.
#[derive(Clone, Copy, Debug)]
enum Facing {
    PosX,
    NegX,
    PosY,
    NegY,
    PosZ,
    NegZ,
}

impl Facing {
    /// (u axis, v axis, normal axis) as indices 0..3, with u x v along the facing.
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

/// The materials, in MTL order: (name, Kd, Ke).
const MATERIALS: [(&str, &str, &str); 8] = [
    ("floor", "0.45 0.42 0.38", "0 0 0"),
    ("ceiling", "0.75 0.75 0.75", "0 0 0"),
    ("wall", "0.7 0.68 0.62", "0 0 0"),
    ("stone", "0.55 0.52 0.48", "0 0 0"),
    ("crate_red", "0.6 0.2 0.15", "0 0 0"),
    ("crate_blue", "0.2 0.3 0.6", "0 0 0"),
    ("crate_green", "0.25 0.5 0.25", "0 0 0"),
    ("light", "0.78 0.78 0.78", "12 11 9"),
];
const FLOOR: u8 = 0;
const CEILING: u8 = 1;
const WALL_MAT: u8 = 2;
const STONE: u8 = 3;
const CRATES: [u8; 3] = [4, 5, 6];
const LIGHT: u8 = 7;

/// SplitMix64: small, fast, and fixed forever (the scene's bytes depend on it).
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// A value in `lo ..= hi` in steps of `step` (all in units).
    fn pick(&mut self, lo: i64, hi: i64, step: i64) -> i64 {
        let n = ((hi - lo) / step + 1) as u64;
        lo + step * (self.next() % n) as i64
    }
}

/// The faces being built: corners in units, a group and a material each.
struct Mesh {
    groups: Vec<String>,
    faces: Vec<(u32, u8, [[i64; 3]; 4])>,
}

impl Mesh {
    fn group(&mut self, name: String) -> u32 {
        self.groups.push(name);
        (self.groups.len() - 1) as u32
    }

    /// A rectangle facing `facing` at `level` on its normal axis, over the grid of cells that
    /// `breaks[axis]` draws on its two in-plane axes (the normal axis's entry is ignored); cells
    /// whose centre lies strictly inside `hole` are left out, every other cell is cut into
    /// `cut` x `cut` quads (`cut` = 1 for furniture and lights).
    fn rect(
        &mut self,
        (group, material): (u32, u8),
        facing: Facing,
        level: i64,
        breaks: [&[i64]; 3],
        hole: Option<([i64; 3], [i64; 3])>,
        cut: i64,
    ) {
        let (ua, va, na) = facing.axes();
        let (us, vs) = (breaks[ua], breaks[va]);
        let split = |a: i64, b: i64, k: i64| a + ((b - a) * 2 * k + cut) / (2 * cut);
        for cv in vs.windows(2) {
            for cu in us.windows(2) {
                if let Some((lo, hi)) = hole {
                    let (mu, mv) = (cu[0] + cu[1], cv[0] + cv[1]);
                    if 2 * lo[ua] < mu && mu < 2 * hi[ua] && 2 * lo[va] < mv && mv < 2 * hi[va] {
                        continue;
                    }
                }
                for j in 0..cut {
                    let (t0, t1) = (split(cv[0], cv[1], j), split(cv[0], cv[1], j + 1));
                    for i in 0..cut {
                        let (s0, s1) = (split(cu[0], cu[1], i), split(cu[0], cu[1], i + 1));
                        let p = |s: i64, t: i64| {
                            let mut c = [0; 3];
                            c[ua] = s;
                            c[va] = t;
                            c[na] = level;
                            c
                        };
                        let q = [p(s0, t0), p(s1, t0), p(s1, t1), p(s0, t1)];
                        self.faces.push((group, material, q));
                    }
                }
            }
        }
    }

    /// The outward faces of a box standing on the floor (four sides and a top), uncut.
    fn solid(&mut self, group: u32, material: u8, lo: [i64; 3], hi: [i64; 3]) {
        let xs: &[i64] = &[lo[0], hi[0]];
        let ys: &[i64] = &[lo[1], hi[1]];
        let zs: &[i64] = &[lo[2], hi[2]];
        let b = [xs, ys, zs];
        self.rect((group, material), Facing::NegX, lo[0], b, None, 1);
        self.rect((group, material), Facing::PosX, hi[0], b, None, 1);
        self.rect((group, material), Facing::NegZ, lo[2], b, None, 1);
        self.rect((group, material), Facing::PosZ, hi[2], b, None, 1);
        self.rect((group, material), Facing::PosY, hi[1], b, None, 1);
    }
}

/// Builds the building's faces: room after room, storey by storey, row by row.
fn build(o: &BuildingOptions) -> Mesh {
    let mut m = Mesh {
        groups: Vec::new(),
        faces: Vec::with_capacity(usize::try_from(o.polygon_count()).unwrap_or(0)),
    };
    for f in 0..o.floors {
        for iz in 0..o.rooms_z {
            for ix in 0..o.rooms_x {
                Room::new(o, (f, ix, iz)).build(&mut m, o);
            }
        }
    }
    m
}

/// One room of the building, in units: its inside box, the lines of its doorways, and which of
/// its walls have one.
struct Room {
    /// Storey, column (along x) and row (along z).
    at: (u32, u32, u32),
    /// The inside box's lower corner.
    lo: [i64; 3],
    /// The inside box's upper corner.
    hi: [i64; 3],
    /// A doorway in a z wall spans x in `door_x`.
    door_x: [i64; 2],
    /// A doorway in an x wall spans z in `door_z`.
    door_z: [i64; 2],
    /// Doorways in the west, east, south and north walls (towards the neighbours).
    doors: [bool; 4],
    /// Every shell cell is cut into `cut` x `cut` quads.
    cut: i64,
}

impl Room {
    fn new(o: &BuildingOptions, (f, ix, iz): (u32, u32, u32)) -> Room {
        let (w, h, d, t) = (
            units(ROOM_WIDTH),
            units(ROOM_HEIGHT),
            units(ROOM_DEPTH),
            units(WALL),
        );
        let dw = units(DOOR_WIDTH);
        let x0 = i64::from(ix) * (w + t);
        let y0 = i64::from(f) * (h + t);
        let z0 = i64::from(iz) * (d + t);
        Room {
            at: (f, ix, iz),
            lo: [x0, y0, z0],
            hi: [x0 + w, y0 + h, z0 + d],
            door_x: [x0 + (w - dw) / 2, x0 + (w + dw) / 2],
            door_z: [z0 + (d - dw) / 2, z0 + (d + dw) / 2],
            doors: [ix > 0, ix + 1 < o.rooms_x, iz > 0, iz + 1 < o.rooms_z],
            cut: i64::from(o.cut),
        }
    }

    /// The group name of one of the room's surfaces or pieces: `s0_x1_z2_floor`.
    fn name(&self, what: &str) -> String {
        let (f, ix, iz) = self.at;
        format!("s{f}_x{ix}_z{iz}_{what}")
    }

    /// The top of the room's doorways.
    fn door_top(&self) -> i64 {
        self.lo[1] + units(DOOR_HEIGHT)
    }

    /// Everything in and around the room, in group order: floor, ceiling, walls, the linings of
    /// the doorways to the east and north, the ceiling lights, the furniture.
    fn build(&self, m: &mut Mesh, o: &BuildingOptions) {
        self.floor_and_ceiling(m);
        self.walls(m);
        self.doorway_linings(m);
        self.ceiling_lights(m, o.lights);
        furnish(m, o, self.at, self.lo, |what: &str| self.name(what));
    }

    /// The floor, divided at the doorway lines on both axes, and the ceiling, undivided.
    fn floor_and_ceiling(&self, m: &mut Mesh) {
        let ([x0, y0, z0], [x1, y1, z1]) = (self.lo, self.hi);
        let ([xa, xb], [za, zb]) = (self.door_x, self.door_z);
        let door_x: &[i64] = &[x0, xa, xb, x1];
        let door_z: &[i64] = &[z0, za, zb, z1];
        let full_x: &[i64] = &[x0, x1];
        let full_z: &[i64] = &[z0, z1];
        let g = m.group(self.name("floor"));
        m.rect(
            (g, FLOOR),
            Facing::PosY,
            y0,
            [door_x, &[], door_z],
            None,
            self.cut,
        );
        let g = m.group(self.name("ceiling"));
        m.rect(
            (g, CEILING),
            Facing::NegY,
            y1,
            [full_x, &[], full_z],
            None,
            self.cut,
        );
    }

    /// The four walls. A wall with a doorway is the grid of cells around its hole (the box of
    /// the doorway's cell in the wall's plane) minus the hole.
    fn walls(&self, m: &mut Mesh) {
        let ([x0, y0, z0], [x1, y1, z1]) = (self.lo, self.hi);
        let ([xa, xb], [za, zb], top) = (self.door_x, self.door_z, self.door_top());
        let full_x: &[i64] = &[x0, x1];
        let full_y: &[i64] = &[y0, y1];
        let full_z: &[i64] = &[z0, z1];
        let door_x: &[i64] = &[x0, xa, xb, x1];
        let door_y: &[i64] = &[y0, top, y1];
        let door_z: &[i64] = &[z0, za, zb, z1];
        let [west, east, south, north] = self.doors;
        // (name, facing, level, has a doorway)
        let walls = [
            ("wall_west", Facing::PosX, x0, west),
            ("wall_east", Facing::NegX, x1, east),
            ("wall_south", Facing::PosZ, z0, south),
            ("wall_north", Facing::NegZ, z1, north),
        ];
        for (what, facing, level, door) in walls {
            let g = m.group(self.name(what));
            let along_x = matches!(facing, Facing::PosZ | Facing::NegZ);
            let (breaks, hole): ([&[i64]; 3], _) = match (door, along_x) {
                (false, false) => ([&[], full_y, full_z], None),
                (false, true) => ([full_x, full_y, &[]], None),
                (true, false) => ([&[], door_y, door_z], Some(([0, y0, za], [0, top, zb]))),
                (true, true) => ([door_x, door_y, &[]], Some(([xa, y0, 0], [xb, top, 0]))),
            };
            m.rect((g, WALL_MAT), facing, level, breaks, hole, self.cut);
        }
    }

    /// The linings of the doorways to the east and north neighbours (each doorway once, by the
    /// room to its west or south): floor, lintel and two jambs through the wall's thickness.
    fn doorway_linings(&self, m: &mut Mesh) {
        let ([x1, z1], t) = ([self.hi[0], self.hi[2]], units(WALL));
        let ([xa, xb], [za, zb]) = (self.door_x, self.door_z);
        let [_, east, _, north] = self.doors;
        if east {
            let jambs = [(Facing::PosZ, za), (Facing::NegZ, zb)];
            self.lining(m, "door_east", [&[x1, x1 + t], &[za, zb]], jambs);
        }
        if north {
            let jambs = [(Facing::PosX, xa), (Facing::NegX, xb)];
            self.lining(m, "door_north", [&[xa, xb], &[z1, z1 + t]], jambs);
        }
    }

    /// One doorway's lining over `[xs, zs]`: its floor, its lintel at the doorway's top and its
    /// two jambs (facing and level each).
    fn lining(&self, m: &mut Mesh, what: &str, [xs, zs]: [&[i64]; 2], jambs: [(Facing, i64); 2]) {
        let (y0, top) = (self.lo[1], self.door_top());
        let g = m.group(self.name(what));
        let ys: &[i64] = &[y0, top];
        let b = [xs, ys, zs];
        m.rect((g, FLOOR), Facing::PosY, y0, b, None, self.cut);
        m.rect((g, WALL_MAT), Facing::NegY, top, b, None, self.cut);
        for (facing, level) in jambs {
            m.rect((g, WALL_MAT), facing, level, b, None, self.cut);
        }
    }

    /// Ceiling panels, 1 cm below the ceiling, facing down: one of 1.4 m square in the middle,
    /// or two of 1 m square at a quarter and three quarters of the width (the same emitting
    /// area, 2 m^2, within 2 %).
    fn ceiling_lights(&self, m: &mut Mesh, lights: u32) {
        let ([x0, _, z0], y1) = (self.lo, self.hi[1]);
        let (w, d) = (units(ROOM_WIDTH), units(ROOM_DEPTH));
        let below = y1 - units(0.01);
        let (zc, half) = (z0 + d / 2, units(if lights == 1 { 0.7 } else { 0.5 }));
        let centres: &[i64] = if lights == 1 {
            &[x0 + w / 2]
        } else {
            &[x0 + w / 4, x0 + 3 * w / 4]
        };
        for (k, xc) in centres.iter().enumerate() {
            let g = m.group(self.name(&format!("light{k}")));
            let xs: &[i64] = &[xc - half, xc + half];
            let zs: &[i64] = &[zc - half, zc + half];
            m.rect((g, LIGHT), Facing::NegY, below, [xs, &[], zs], None, 1);
        }
    }
}

/// Up to four pieces of furniture in a room whose inside starts at `lo`: each in its own corner
/// quadrant (clear of the walls by 0.3 m and of the room's centre lines by 1 m, so doorways and
/// the corridors between them stay free), either a pillar (0.3 - 0.5 m square, 2 - 2.6 m high)
/// or a crate (0.4 - 1.2 m wide and deep, 0.4 - 1.2 m high), sizes and places on a 5 cm grid.
fn furnish(
    m: &mut Mesh,
    o: &BuildingOptions,
    (f, ix, iz): (u32, u32, u32),
    lo: [i64; 3],
    name: impl Fn(&str) -> String,
) {
    let room_key = (u64::from(f) << 42) | (u64::from(ix) << 21) | u64::from(iz);
    let mut rng = Rng(o.seed.wrapping_mul(0xD6E8_FEB8_6659_FD93) ^ room_key);
    let step = units(0.05);
    // The quadrants in a seeded order; the first `furniture` get a piece.
    let mut quadrants = [0usize, 1, 2, 3];
    for i in (1..4).rev() {
        let j = (rng.next() % (i as u64 + 1)) as usize;
        quadrants.swap(i, j);
    }
    let (w, d) = (units(ROOM_WIDTH), units(ROOM_DEPTH));
    let (margin, corridor) = (units(0.3), units(1.0));
    for (k, &q) in quadrants.iter().take(o.furniture as usize).enumerate() {
        let pillar = rng.next().is_multiple_of(3);
        let (sx, sz, sy, material, what) = if pillar {
            let s = rng.pick(units(0.3), units(0.5), step);
            (
                s,
                s,
                rng.pick(units(2.0), units(2.6), step),
                STONE,
                "pillar",
            )
        } else {
            let sx = rng.pick(units(0.4), units(1.2), step);
            let sz = rng.pick(units(0.4), units(1.2), step);
            let sy = rng.pick(units(0.4), units(1.2), step);
            let c = CRATES[(rng.next() % 3) as usize];
            (sx, sz, sy, c, "crate")
        };
        // The quadrant's free span on each axis, in room coordinates.
        let span = |high: bool, size: i64| {
            if high {
                (size / 2 + corridor, size - margin)
            } else {
                (margin, size / 2 - corridor)
            }
        };
        let (qx, qz) = (span(q & 1 == 1, w), span(q & 2 == 2, d));
        let px = rng.pick(qx.0, qx.1 - sx, step);
        let pz = rng.pick(qz.0, qz.1 - sz, step);
        let g = m.group(name(&format!("{what}{k}")));
        let blo = [lo[0] + px, lo[1], lo[2] + pz];
        let bhi = [blo[0] + sx, lo[1] + sy, blo[2] + sz];
        m.solid(g, material, blo, bhi);
    }
}

/// `1 room`, `2 rooms`.
fn plural(n: u64, one: &str, many: &str) -> String {
    format!("{n} {}", if n == 1 { one } else { many })
}

/// A coordinate in units written as its exact decimal in metres (at most 4 decimals).
fn decimal(q: i64, out: &mut String) {
    let (sign, a) = if q < 0 { ("-", -q) } else { ("", q) };
    let (whole, frac) = (a / 10_000, a % 10_000);
    if frac == 0 {
        let _ = write!(out, "{sign}{whole}");
    } else {
        let f = format!("{frac:04}");
        let _ = write!(out, "{sign}{whole}.{}", f.trim_end_matches('0'));
    }
}

fn metres(q: i64) -> String {
    let mut s = String::new();
    decimal(q, &mut s);
    s
}

/// Generates the building of `o` whose scene file will be `paths.scene` (its name names the OBJ
/// and MTL files; its path appears in the command written at the top of the scene). Validates
/// `o` first.
pub fn generate_building(o: &BuildingOptions, paths: &BuildingPaths) -> Result<Building> {
    o.validate()?;
    let m = build(o);
    let polygons = m.faces.len() as u64;
    if polygons != o.polygon_count() {
        return Err(Error::internal(format!(
            "building generator: {polygons} polygons built, {} counted",
            o.polygon_count()
        )));
    }
    let name = paths.name();
    let (rooms, doorways) = (o.room_count(), o.doorway_count());
    let lights = rooms * u64::from(o.lights);
    let furniture = rooms * u64::from(o.furniture);
    let summary = format!(
        "{} ({} x {} on {}), {}, {}, {}, shell cut {} x {}: {}",
        plural(rooms, "room", "rooms"),
        o.rooms_x,
        o.rooms_z,
        plural(o.floors.into(), "storey", "storeys"),
        plural(doorways, "doorway", "doorways"),
        plural(lights, "ceiling light panel", "ceiling light panels"),
        plural(furniture, "piece of furniture", "pieces of furniture"),
        o.cut,
        o.cut,
        plural(polygons, "polygon", "polygons"),
    );
    let command = o.command(&paths.scene);
    let header = format!("# {summary}.\n# GENERATED by: {command}\nmtllib {name}.mtl\n");
    Ok(Building {
        toml: scene_toml(o, name, &summary, &paths.scene),
        obj: header + &obj_body(&m),
        mtl: mtl_text(&command),
        summary,
        polygons,
        rooms,
        doorways,
        lights,
        furniture,
    })
}

/// The OBJ's vertices, numbered in order of first use, then its faces by group, each group and
/// each change of material announced once.
fn obj_body(m: &Mesh) -> String {
    let mut index: HashMap<[i64; 3], u32> = HashMap::new();
    let mut vertices = String::new();
    let mut faces = String::new();
    let mut current: Option<(u32, u8)> = None;
    for (group, mat, q) in &m.faces {
        let mut ids = [0u32; 4];
        for (slot, c) in q.iter().enumerate() {
            let next = index.len() as u32 + 1;
            ids[slot] = *index.entry(*c).or_insert_with(|| {
                vertices.push('v');
                for &x in c {
                    vertices.push(' ');
                    decimal(x, &mut vertices);
                }
                vertices.push('\n');
                next
            });
        }
        match current {
            Some((g, _)) if g == *group => {}
            _ => {
                let _ = writeln!(faces, "g {}", m.groups[*group as usize]);
            }
        }
        if current.map(|(_, mm)| mm) != Some(*mat) || current.map(|(g, _)| g) != Some(*group) {
            let _ = writeln!(faces, "usemtl {}", MATERIALS[*mat as usize].0);
        }
        current = Some((*group, *mat));
        let _ = writeln!(faces, "f {} {} {} {}", ids[0], ids[1], ids[2], ids[3]);
    }
    vertices + &faces
}

/// The MTL: every material of [`MATERIALS`], emitters with their `Ke`.
fn mtl_text(command: &str) -> String {
    let mut mtl = format!("# Materials of the building. GENERATED by: {command}\n");
    for (k, (n, kd, ke)) in MATERIALS.iter().enumerate() {
        if k > 0 {
            mtl.push('\n');
        }
        let _ = writeln!(mtl, "newmtl {n}\nKd {kd}\nKe {ke}");
    }
    mtl
}

/// The scene file: the camera in the first room looking down the longer row of rooms, the
/// include, the gallery's radiosity settings and a walk down the row.
fn scene_toml(o: &BuildingOptions, name: &str, summary: &str, scene: &Path) -> String {
    let (w, d, t) = (units(ROOM_WIDTH), units(ROOM_DEPTH), units(WALL));
    // Along x when the row along x is at least as long, else along z; `far` is the inside of
    // the last room's far wall on the centre line.
    let along_x = o.rooms_x >= o.rooms_z;
    let (n, size) = if along_x {
        (i64::from(o.rooms_x), w)
    } else {
        (i64::from(o.rooms_z), d)
    };
    let start = units(0.8);
    let far = (n - 1) * (size + t) + size;
    let last = far - size / 2;
    let (eye_y, look_y) = (units(1.6), units(1.4));
    let point = |along: i64, y: i64| {
        let (x, z) = if along_x {
            (along, d / 2)
        } else {
            (w / 2, along)
        };
        format!("[{}, {}, {}]", metres(x), metres(y), metres(z))
    };
    let eye = point(start, eye_y);
    let look = point(far, look_y);
    let end = point(last.max(start + units(1.0)), eye_y);
    let axis = if along_x { "+x" } else { "+z" };
    format!(
        "# GENERATED by: {command}\n\
         # {summary}.\n\
         # Rooms are {rw} m x {rh} m x {rd} m inside (x, y, z), walls {wall} m thick, doorways \
         {dw} m x {dh} m between all neighbours on a storey. Units: metres, y up.\n\
         \n\
         # Standing in the first room, looking {axis} through the doorways down the row of rooms.\n\
         [camera]\n\
         eye = {eye}\n\
         look_at = {look}\n\
         up = [0.0, 1.0, 0.0]\n\
         fov_y = 60.0\n\
         \n\
         [image]\n\
         width = 640\n\
         height = 480\n\
         \n\
         [[obj]]\n\
         file = \"{name}/{name}.obj\"\n\
         \n\
         [radiosity]\n\
         tolerance = 0.01\n\
         min_depth = 1\n\
         max_depth = 6\n\
         convergence = 0.01\n\
         shadow_rays = 8\n\
         seed = 1\n\
         \n\
         [render]\n\
         method = \"direct\"\n\
         aa = 1\n\
         texture_size = 0\n\
         \n\
         [display]\n\
         exposure = -1.0\n\
         background = [0.0, 0.0, 0.0]\n\
         \n\
         # A walk down the row of rooms (`render --walkthrough`), to the middle of the last room.\n\
         [camera_path]\n\
         frames = 48\n\
         keyframes = [\n  \
         {{ eye = {eye}, look_at = {look}, up = [0.0, 1.0, 0.0] }},\n  \
         {{ eye = {end}, look_at = {look}, up = [0.0, 1.0, 0.0] }},\n\
         ]\n",
        command = o.command(scene),
        rw = ROOM_WIDTH,
        rh = ROOM_HEIGHT,
        rd = ROOM_DEPTH,
        wall = WALL,
        dw = DOOR_WIDTH,
        dh = DOOR_HEIGHT,
    )
}

/// Generates the building of `o` and writes it for `-o out` ([`BuildingPaths::for_output`]):
/// the OBJ, the MTL and the scene file, each through a temporary renamed over its target, all
/// renamed together after all three are written ([`base::output::Batch`]). Options and
/// outputs are checked before anything is built.
pub fn write_building(outputs: &Outputs, o: &BuildingOptions, out: &Path) -> Result<Written> {
    o.validate()?;
    let paths = BuildingPaths::for_output(out)?;
    base::output::check_outputs(
        &[],
        &[
            ("-o", &paths.scene),
            ("-o (OBJ)", &paths.obj),
            ("-o (MTL)", &paths.mtl),
        ],
    )?;
    let building = generate_building(o, &paths)?;
    let mut batch = outputs.batch();
    batch.stage(&paths.obj, building.obj.as_bytes())?;
    batch.stage(&paths.mtl, building.mtl.as_bytes())?;
    batch.stage(&paths.scene, building.toml.as_bytes())?;
    batch.commit()?;
    Ok(Written { paths, building })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decimals_are_exact() {
        for (q, s) in [
            (0, "0"),
            (10_000, "1"),
            (62_000, "6.2"),
            (6_667, "0.6667"),
            (-500, "-0.05"),
            (1_234_567_891, "123456.7891"),
        ] {
            assert_eq!(metres(q), s);
        }
    }

    #[test]
    fn cells_split_without_gaps() {
        let mut m = Mesh {
            groups: vec!["g".into()],
            faces: Vec::new(),
        };
        let xs: &[i64] = &[0, 10, 20];
        let zs: &[i64] = &[0, 7];
        m.rect((0, FLOOR), Facing::PosY, 0, [xs, &[], zs], None, 3);
        assert_eq!(m.faces.len(), 2 * 9);
        let area: i64 = m
            .faces
            .iter()
            .map(|(_, _, q)| (q[2][0] - q[0][0]).abs() * (q[2][2] - q[0][2]).abs())
            .sum();
        assert_eq!(area, 20 * 7);
    }

    #[test]
    fn output_paths() {
        let p = BuildingPaths::for_output(Path::new("scenes/building.toml")).unwrap();
        assert_eq!(p.obj, Path::new("scenes/building/building.obj"));
        assert_eq!(p.mtl, Path::new("scenes/building/building.mtl"));
        let p = BuildingPaths::for_output(Path::new("out/big")).unwrap();
        assert_eq!(p.scene, Path::new("out/big/building.toml"));
        assert_eq!(p.obj, Path::new("out/big/building/building.obj"));
        let e = BuildingPaths::for_output(Path::new("a b.toml")).unwrap_err();
        assert_eq!(e.exit_code(), 2);
        assert_eq!(shell_word("a b"), "'a b'");
    }
}
