//! Solution files: how a solve is kept between `solve` and `render`, so a walkthrough never solves
//! twice. The format is little-endian binary:
//!
//! ```text
//! magic        8 bytes  "PFSOLN\r\n"
//! version      u32      FORMAT_VERSION
//! path_len     u32      bytes of the scene path (0: none)
//! payload_len  u64      bytes of payload
//! scene_hash   u64      radiosity::scene_hash of the scene solved
//! scene_path   path_len path of the scene file, its bytes (so `render <solution>` works):
//!                       relative to the solution file's folder when the two share a root
//!                       (a solution copied with its scene keeps finding it), else absolute
//! payload      ...      per polygon its quadtree (node count, one split bit per node in the
//!                       canonical order of `Quadtree::grow`) and its samples (three f32 per
//!                       vertex, in vertex-key order); then the shooters and the statistics
//!                       (see `encode_payload`)
//! checksum     u64      FNV-1a 64 of every byte before it
//! ```
//!
//! Invariants: the bytes are a pure function of the solution (the solve time and the rays cast
//! are not stored: the first depends on the machine, the second on how much geometry the solve
//! could keep under its memory limit; so solving one scene twice, under any limit, writes
//! identical files); files are written atomically through
//! [`base::output::Outputs::write_atomic`]; reading checks, in order, magic, version, length (truncation),
//! checksum (corruption), scene hash (another scene), then rebuilds every quadtree from its split
//! bits ([`Quadtree::from_split_bits`], which accepts one form per tree) and takes its vertex keys
//! from the tree. Every failure is an [`Error::Solution`] naming the file, the
//! [`SolutionProblem`] and what is wrong.
//!
//! **No RRPs are stored.** The trees and samples are what the RRPs are made of: a render from a
//! file builds them again with the same function a render after a solve uses, so the two draw
//! identical images, and the RRPs cost a file nothing beyond the solution itself
//! ([`samples_bytes`]: one bit per node and 12 bytes per vertex).

use std::path::Path;

use glam::{DVec3, Vec3};

use super::transfer::shape::MAX_SHAPE_LEVELS;
use super::transfer::{build_shooters, ShooterKind};
use super::{fill_tree_stats, scene_hash, Fnv, PatchShape, Shooter, Solution, SolveStats};
use base::error::{Error, Result, SolutionProblem};
use base::quadtree::{Cell, Quadtree, SampledQuadtree};
use scene::Scene;

/// File magic.
pub const MAGIC: &[u8; 8] = b"PFSOLN\r\n";
/// Current format version. Version 2 added the compact RRPs after the statistics; version 3
/// marks solutions of the local refinement criterion with per-channel convergence, their RRPs
/// built with the Hyman estimator; version 4 stores the shapes of the patches' light; version 6
/// stores the compact RRPs with a per-vertex shift per quantity (relative precision) and without
/// the T-vertices' data (`PFRRPC02`); version 7 stores RRPs that follow the spot lights' edges
/// (split three levels deeper where a spot's rim or hard shadow crosses a leaf), so an older
/// file's RRPs would be silently smoother there; version 8 stores the light that escaped the
/// scene in the energy account, from solves with exact visibility; version 9 stores how much
/// light the leaves refinement stopped at a guard may misplace, and the light the scene
/// reflects; version 10 stores each quadtree as split bits in canonical order with no vertex
/// keys, and no RRPs (they are built from the samples on load). Older files are refused (solve
/// again).
pub const FORMAT_VERSION: u32 = 10;
/// Most nodes a stored patch shape may have: a full tree of [`MAX_SHAPE_LEVELS`] levels.
const MAX_SHAPE_NODES: usize = ((1 << (2 * (MAX_SHAPE_LEVELS + 1))) - 1) / 3;
const HEADER: usize = 8 + 4 + 4 + 8 + 8;

/// Serializes a solution to bytes (the exact file content), naming no scene file.
pub fn encode(sol: &Solution) -> Vec<u8> {
    encode_with_scene(sol, None)
}

/// Serializes a solution to bytes, naming the scene file it solves (so `render <solution>` can
/// load it). The path is stored between the header and the payload as the system gives its
/// bytes (on Unix any bytes but zero, so a path that is not UTF-8 still names its scene;
/// elsewhere its UTF-8).
pub fn encode_with_scene(sol: &Solution, scene_path: Option<&Path>) -> Vec<u8> {
    let payload = encode_payload(sol);
    let path: Vec<u8> = scene_path.map(path_bytes).unwrap_or_default();
    let mut out = Vec::with_capacity(HEADER + path.len() + payload.len() + 8);
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    out.extend_from_slice(&(path.len() as u32).to_le_bytes());
    out.extend_from_slice(&(payload.len() as u64).to_le_bytes());
    out.extend_from_slice(&sol.scene_hash.to_le_bytes());
    out.extend_from_slice(&path);
    out.extend_from_slice(&payload);
    let mut h = Fnv::default();
    h.bytes(&out);
    out.extend_from_slice(&h.0.to_le_bytes());
    out
}

/// Makes the envelope of the damaged solution file bytes `b` valid for `scene` (magic, format
/// version, the path and payload lengths, the scene hash, the checksum), so that only the
/// payload stays damaged: the hostile-input tests and the fuzz target use it to reach the
/// payload's decoder instead of stopping at the checksum. Bytes too short to hold a header and
/// a checksum are left as they are.
pub fn reseal(b: &mut [u8], scene: &Scene) {
    if b.len() < HEADER + 8 {
        return;
    }
    let avail = b.len() - HEADER - 8;
    let path_len = (u32::from_le_bytes([b[12], b[13], b[14], b[15]]) as usize).min(avail);
    b[..8].copy_from_slice(MAGIC);
    b[8..12].copy_from_slice(&FORMAT_VERSION.to_le_bytes());
    b[12..16].copy_from_slice(&(path_len as u32).to_le_bytes());
    b[16..24].copy_from_slice(&((avail - path_len) as u64).to_le_bytes());
    b[24..32].copy_from_slice(&scene_hash(scene).to_le_bytes());
    let body = b.len() - 8;
    let mut h = Fnv::default();
    h.bytes(&b[..body]);
    b[body..].copy_from_slice(&h.0.to_le_bytes());
}

/// Writes `sol` to `path` atomically through `outputs`. `scene_path`, if given, is stored
/// relative to the solution file's folder ([`relative_to`]; absolute when they share no root)
/// so that the solution file alone is enough to render, also after both are copied elsewhere
/// together.
pub fn write_solution(
    outputs: &base::output::Outputs,
    path: &Path,
    sol: &Solution,
    scene_path: Option<&Path>,
) -> Result<()> {
    let stored = match scene_path {
        Some(p) => {
            let scene = std::fs::canonicalize(p).map_err(|e| Error::io(p, e))?;
            let folder = solution_folder(path)?;
            Some(relative_to(&scene, &folder).unwrap_or(scene))
        }
        None => None,
    };
    outputs.write_atomic(path, &encode_with_scene(sol, stored.as_deref()))
}

/// The canonical folder a solution file at `path` lives in (created if missing, as writing the
/// file would).
fn solution_folder(path: &Path) -> Result<std::path::PathBuf> {
    let parent = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => std::path::PathBuf::from("."),
    };
    std::fs::create_dir_all(&parent).map_err(|e| Error::io(&parent, e))?;
    std::fs::canonicalize(&parent).map_err(|e| Error::io(&parent, e))
}

/// `target` as a path relative to the folder `base` (both absolute and canonical): `..` for each
/// component of `base` past their common prefix, then the rest of `target`. `None` when they
/// share no root (another drive or prefix).
pub fn relative_to(target: &Path, base: &Path) -> Option<std::path::PathBuf> {
    use std::path::Component;
    let t: Vec<Component> = target.components().collect();
    let b: Vec<Component> = base.components().collect();
    if t.first() != b.first() {
        return None;
    }
    let common = t.iter().zip(&b).take_while(|(x, y)| x == y).count();
    let mut rel = std::path::PathBuf::new();
    for _ in common..b.len() {
        rel.push("..");
    }
    for c in &t[common..] {
        rel.push(c.as_os_str());
    }
    Some(rel)
}

/// The scene file a solution file names (checked: magic, version, length, checksum): a relative
/// stored path is taken from the solution file's folder (for a symbolic link, the folder of the
/// file it leads to: see [`base::output::folder_of`]).
pub fn read_scene_path(path: &Path) -> Result<std::path::PathBuf> {
    read_scene_path_up_to(path, base::output::MAX_INPUT_BYTES)
}

/// [`read_scene_path`] refusing a file over `max` bytes before it is read whole.
pub fn read_scene_path_up_to(path: &Path, max: u64) -> Result<std::path::PathBuf> {
    let stored = read_stored_scene_path(path, max)?;
    if stored.is_absolute() {
        return Ok(stored);
    }
    Ok(base::output::folder_of(path).join(stored))
}

/// The scene path as the solution file stores it.
fn read_stored_scene_path(path: &Path, max: u64) -> Result<std::path::PathBuf> {
    let bytes = read(path, max)?;
    let env = envelope(&bytes).map_err(|b| b.at(path))?;
    let name = &bytes[HEADER..HEADER + env.path_len];
    if name.is_empty() {
        return Err(Error::solution(
            path,
            SolutionProblem::SceneMismatch,
            "this solution file names no scene file; render the scene itself",
        ));
    }
    path_of_bytes(name).ok_or_else(|| {
        Error::solution(
            path,
            SolutionProblem::Corrupt,
            "corrupt solution file: the scene path is not a path of this system",
        )
    })
}

/// A path's bytes as stored (see [`encode_with_scene`]).
fn path_bytes(p: &Path) -> Vec<u8> {
    #[cfg(unix)]
    {
        use std::os::unix::ffi::OsStrExt;
        p.as_os_str().as_bytes().to_vec()
    }
    #[cfg(not(unix))]
    {
        p.to_string_lossy().into_owned().into_bytes()
    }
}

/// The path stored as `bytes`; `None` if no path of this system has them (a zero byte; not
/// UTF-8 outside Unix).
fn path_of_bytes(bytes: &[u8]) -> Option<std::path::PathBuf> {
    if bytes.contains(&0) {
        return None;
    }
    #[cfg(unix)]
    {
        use std::os::unix::ffi::OsStrExt;
        Some(std::path::PathBuf::from(std::ffi::OsStr::from_bytes(bytes)))
    }
    #[cfg(not(unix))]
    {
        std::str::from_utf8(bytes)
            .ok()
            .map(std::path::PathBuf::from)
    }
}

/// Reads a solution of `scene` from `path`; a file over [`base::output::MAX_INPUT_BYTES`] is
/// refused ([`read_solution_up_to`] takes a job's smaller cap).
pub fn read_solution(path: &Path, scene: &Scene) -> Result<Solution> {
    read_solution_up_to(path, scene, base::output::MAX_INPUT_BYTES)
}

/// Bytes a decoded solution holds per byte of its file, rounded up: a vertex takes 12 bytes in
/// the file and, decoded, its samples (12), its key (8) and about 21 bytes of tree nodes.
pub const DECODED_PER_FILE_BYTE: u64 = 4;

/// [`read_solution`] under a job's input cap `max` ([`base::output::input_limit_for`]: what an
/// input may take read and parsed, counted as twice its bytes). A solution file is held as bytes
/// and decoded to about [`DECODED_PER_FILE_BYTE`] times as many, so a file over
/// `2 max / (1 + DECODED_PER_FILE_BYTE)` bytes is refused before it is read whole.
pub fn read_solution_up_to(path: &Path, scene: &Scene, max: u64) -> Result<Solution> {
    let bytes = read(path, max.saturating_mul(2) / (1 + DECODED_PER_FILE_BYTE))?;
    decode(&bytes, scene).map_err(|b| b.at(path))
}

fn read(path: &Path, max: u64) -> Result<Vec<u8>> {
    base::output::read_limited(path, max).map_err(|e| {
        Error::solution(
            path,
            SolutionProblem::NotASolution,
            format!("cannot read the solution file: {e}"),
        )
    })
}

/// A decoding failure: what kind, and the message for the user. A plain message (from the
/// payload reader) is a corrupt file.
#[derive(Debug)]
pub struct Bad(pub SolutionProblem, pub String);

impl From<String> for Bad {
    fn from(m: String) -> Bad {
        Bad(SolutionProblem::Corrupt, m)
    }
}

impl Bad {
    fn at(self, path: &Path) -> Error {
        Error::solution(path, self.0, self.1)
    }
}

/// Lengths of the checked envelope of a solution file.
struct Envelope {
    path_len: usize,
    body: usize,
}

/// Checks magic, version, length (truncation) and checksum (corruption).
fn envelope(bytes: &[u8]) -> std::result::Result<Envelope, Bad> {
    check_header(bytes)?;
    let path_len = le_u32(bytes, 12) as u64;
    let payload_len = le_u64(bytes, 16);
    let expect = (HEADER as u64)
        .saturating_add(path_len)
        .saturating_add(payload_len)
        .saturating_add(8);
    if (bytes.len() as u64) < expect {
        return Err(Bad(
            SolutionProblem::Truncated,
            format!(
                "truncated solution file: {} bytes, expected {expect}",
                bytes.len()
            ),
        ));
    }
    if (bytes.len() as u64) > expect {
        return Err(format!(
            "corrupt solution file: {} bytes, expected {expect} (trailing data)",
            bytes.len()
        )
        .into());
    }
    let body = bytes.len() - 8;
    let mut h = Fnv::default();
    h.bytes(&bytes[..body]);
    if h.0 != le_u64(bytes, body) {
        return Err("corrupt solution file: checksum mismatch"
            .to_string()
            .into());
    }
    Ok(Envelope {
        path_len: path_len as usize,
        body,
    })
}

/// Checks the magic, that the header is whole, and the format version.
fn check_header(bytes: &[u8]) -> std::result::Result<(), Bad> {
    if bytes.len() < 8 || &bytes[..8] != MAGIC {
        return Err(Bad(
            SolutionProblem::NotASolution,
            "not a pixelflow-sim solution file (bad magic bytes)".to_string(),
        ));
    }
    if bytes.len() < HEADER {
        return Err(Bad(
            SolutionProblem::Truncated,
            format!(
                "truncated solution file: {} bytes, the header alone is {HEADER}",
                bytes.len()
            ),
        ));
    }
    let version = le_u32(bytes, 8);
    if version != FORMAT_VERSION {
        return Err(Bad(
            SolutionProblem::Version {
                found: version,
                supported: FORMAT_VERSION,
            },
            format!(
                "solution file format version {version}, this program reads version {FORMAT_VERSION}; solve the scene again"
            ),
        ));
    }
    Ok(())
}

/// The little-endian `u32` at byte `o` (the caller has checked that `bytes` reaches it).
fn le_u32(bytes: &[u8], o: usize) -> u32 {
    u32::from_le_bytes(bytes[o..o + 4].try_into().unwrap_or([0; 4]))
}

/// The little-endian `u64` at byte `o` (the caller has checked that `bytes` reaches it).
fn le_u64(bytes: &[u8], o: usize) -> u64 {
    u64::from_le_bytes(bytes[o..o + 8].try_into().unwrap_or([0; 8]))
}

/// Little-endian writer of the payload.
struct W(Vec<u8>);

impl W {
    fn u8(&mut self, x: u8) {
        self.0.push(x);
    }
    fn u32(&mut self, x: u32) {
        self.0.extend_from_slice(&x.to_le_bytes());
    }
    fn u64(&mut self, x: u64) {
        self.0.extend_from_slice(&x.to_le_bytes());
    }
    fn f64(&mut self, x: f64) {
        self.0.extend_from_slice(&x.to_le_bytes());
    }
    fn f32(&mut self, x: f32) {
        self.0.extend_from_slice(&x.to_le_bytes());
    }

    /// A polygon: its node count and split bits ([`Quadtree::split_bits`], canonical order),
    /// then the RGB f32 value of every vertex in key order (the keys follow from the tree).
    fn polygon(&mut self, p: &SampledQuadtree) {
        self.u32(p.tree.nodes().len() as u32);
        self.0.extend_from_slice(&p.tree.split_bits());
        for v in &p.values {
            self.f32(v.x);
            self.f32(v.y);
            self.f32(v.z);
        }
    }

    /// A shooter: kind tag (0 spot, 1 emitter, 2 patch), its spot or polygon, its cell (the
    /// root but for a patch), its RGB f64 total, and its shape: a u8 tag (0: none, 1: a
    /// shape, see [`W::shape`]).
    fn shooter(&mut self, s: &Shooter) {
        let (tag, a, cell) = match s.kind {
            ShooterKind::Spot { spot } => (0u8, spot, Cell::ROOT),
            ShooterKind::Emitter { polygon } => (1, polygon, Cell::ROOT),
            ShooterKind::Patch { polygon, cell } => (2, polygon, cell),
        };
        self.u8(tag);
        self.u32(a);
        self.u32(cell.level);
        self.u32(cell.x);
        self.u32(cell.y);
        self.f64(s.total.x);
        self.f64(s.total.y);
        self.f64(s.total.z);
        match &s.shape {
            None => self.u8(0),
            Some(shape) => {
                self.u8(1);
                self.shape(shape);
            }
        }
    }

    /// A patch's shape: its node count (u32), one bit per node in node order ("is split",
    /// which rebuilds the tree, see [`Quadtree::grow`]), packed little-endian in bytes, then
    /// every leaf's RGB f32 weight in node order.
    fn shape(&mut self, shape: &PatchShape) {
        let nodes = shape.tree.nodes();
        self.u32(nodes.len() as u32);
        let mut bits = vec![0u8; nodes.len().div_ceil(8)];
        for (i, n) in nodes.iter().enumerate() {
            if !n.is_leaf() {
                bits[i / 8] |= 1 << (i % 8);
            }
        }
        self.0.extend_from_slice(&bits);
        for c in &shape.leaves {
            c.iter().for_each(|&x| self.f32(x));
        }
    }

    /// The statistics a solution file keeps (not those of its trees, recomputed when read, nor
    /// those of the run: its time and its rays cast, which depend on the machine).
    fn stats(&mut self, st: &SolveStats) {
        self.u64(st.shots);
        self.u32(st.refined_after.len() as u32);
        for &x in &st.refined_after {
            self.u64(x);
        }
        self.f64(st.emitted_power);
        self.f64(st.unshot_fraction);
        self.u64(st.guard_stops.leaves);
        self.u32(st.guard_stops.worst_polygon);
        self.f64(st.guard_stops.worst_excess);
        self.u64(st.guard_stops.shadow_leaves);
        self.u64(st.guard_stops.edge_leaves);
        self.f64(st.guard_stops.error_power);
        self.f64(st.guard_stops.reflected_power);
        let e = &st.energy;
        for v in [e.emitted, e.absorbed, e.unshot, e.lost, e.escaped] {
            self.f64(v.x);
            self.f64(v.y);
            self.f64(v.z);
        }
        self.u32(st.unshot_history.len() as u32);
        for &x in &st.unshot_history {
            self.f64(x);
        }
    }
}

fn encode_payload(sol: &Solution) -> Vec<u8> {
    let mut w = W(Vec::new());
    w.u32(sol.polygons.len() as u32);
    for p in &sol.polygons {
        w.polygon(p);
    }
    w.u32(sol.shooters.len() as u32);
    for s in &sol.shooters {
        w.shooter(s);
    }
    w.stats(&sol.stats);
    w.0
}

/// Bytes a solution file spends on the trees and samples of `sol`'s polygons (the polygon count
/// included): everything the RRPs are built from, so what storing them costs.
pub fn samples_bytes(sol: &Solution) -> u64 {
    4 + sol
        .polygons
        .iter()
        .map(|p| (4 + p.tree.nodes().len().div_ceil(8) + 12 * p.values.len()) as u64)
        .sum::<u64>()
}

/// Little-endian reader of the payload; every failure is a message for a corrupt file.
struct R<'a> {
    b: &'a [u8],
    at: usize,
}

type Decoded<T> = std::result::Result<T, String>;

impl R<'_> {
    fn take(&mut self, n: usize) -> Decoded<&[u8]> {
        if self.b.len() - self.at < n {
            return Err("corrupt payload: a count runs past the end of the data".to_string());
        }
        let s = &self.b[self.at..self.at + n];
        self.at += n;
        Ok(s)
    }
    fn u8(&mut self) -> Decoded<u8> {
        Ok(self.take(1)?[0])
    }
    fn u32(&mut self) -> Decoded<u32> {
        let mut a = [0u8; 4];
        a.copy_from_slice(self.take(4)?);
        Ok(u32::from_le_bytes(a))
    }
    fn u64(&mut self) -> Decoded<u64> {
        let mut a = [0u8; 8];
        a.copy_from_slice(self.take(8)?);
        Ok(u64::from_le_bytes(a))
    }
    fn f64(&mut self) -> Decoded<f64> {
        Ok(f64::from_bits(self.u64()?))
    }
    fn f32(&mut self) -> Decoded<f32> {
        Ok(f32::from_bits(self.u32()?))
    }
    /// A count of items of `size` bytes each that must fit in the remaining data.
    fn count(&mut self, size: usize) -> Decoded<usize> {
        let n = self.u32()? as usize;
        if n.saturating_mul(size) > self.b.len() - self.at {
            return Err("corrupt payload: a count runs past the end of the data".to_string());
        }
        Ok(n)
    }

    /// Polygon `pi` (see [`W::polygon`]): its split bits must be a quadtree's, in the one form
    /// [`Quadtree::from_split_bits`] accepts, and its values (one per vertex of that tree)
    /// finite and >= 0.
    fn polygon(&mut self, pi: usize) -> Decoded<SampledQuadtree> {
        let tree = self.tree(pi)?;
        let keys = tree.vertex_keys();
        let nk = keys.len();
        if nk.saturating_mul(12) > self.b.len() - self.at {
            return Err("corrupt payload: a count runs past the end of the data".to_string());
        }
        let mut values = Vec::with_capacity(nk);
        for _ in 0..nk {
            let v = Vec3::new(self.f32()?, self.f32()?, self.f32()?);
            if !v.is_finite() || v.min_element() < 0.0 {
                return Err(format!(
                    "corrupt payload: polygon {pi}: a sample is negative or not finite"
                ));
            }
            values.push(v);
        }
        Ok(SampledQuadtree { tree, keys, values })
    }

    /// The quadtree of polygon `pi`.
    fn tree(&mut self, pi: usize) -> Decoded<Quadtree> {
        let nn = self.u32()? as usize;
        // Bound the count by the data before the tree is grown: a tree of nn nodes has
        // 3 (nn - 1) / 4 + 1 leaves and at least as many vertices (no two leaves share their
        // lower-left corner), each 12 bytes of samples after the bits. One bit per node alone
        // would let a few bytes of bits grow a tree a hundred times their size.
        let leaves = 3 * (nn.saturating_sub(1) / 4) + 1;
        let least = nn.div_ceil(8).saturating_add(leaves.saturating_mul(12));
        if least > self.b.len() - self.at {
            return Err("corrupt payload: a count runs past the end of the data".to_string());
        }
        let bits = self.take(nn.div_ceil(8))?;
        Quadtree::from_split_bits(nn, bits)
            .ok_or_else(|| format!("corrupt payload: polygon {pi}: invalid quadtree"))
    }

    /// A patch's shape (see [`W::shape`]): its tree replayed from the split bits, at most
    /// [`MAX_SHAPE_LEVELS`] deep, with as many weights as leaves, finite and >= 0.
    fn shape(&mut self, scene: &Scene, polygon: u32, patch: Cell) -> Decoded<PatchShape> {
        let bad = |m: &str| format!("corrupt payload: a patch shape {m}");
        let n = self.u32()? as usize;
        if n == 0 || n > MAX_SHAPE_NODES || n.div_ceil(8) > self.b.len() - self.at {
            return Err(bad("has an impossible node count"));
        }
        let bits = self.take(n.div_ceil(8))?.to_vec();
        let mut ok = true;
        let tree = Quadtree::grow((), |id, cell, ()| {
            let i = id as usize;
            let split = i < n && bits[i / 8] & (1 << (i % 8)) != 0;
            if split && cell.level >= MAX_SHAPE_LEVELS {
                ok = false;
                return None;
            }
            split.then_some([(); 4])
        });
        if !ok || tree.nodes().len() != n {
            return Err(bad("tree does not match its node count"));
        }
        let leaves = tree.nodes().iter().filter(|x| x.is_leaf()).count();
        if leaves * 12 > self.b.len() - self.at {
            return Err(bad("runs past the end of the data"));
        }
        let mut w = Vec::with_capacity(leaves);
        for _ in 0..leaves {
            let c = [self.f32()?, self.f32()?, self.f32()?];
            if c.iter().any(|x| !x.is_finite() || *x < 0.0) {
                return Err(bad("weight is negative or not finite"));
            }
            w.push(c);
        }
        PatchShape::new(&scene.polygons[polygon as usize], patch, tree, w)
            .ok_or_else(|| bad("has as many weights as leaves"))
    }

    /// A shooter (see [`W::shooter`]), which must be `expected` (the scene's shooter of its id)
    /// and have a finite total >= 0, and a shape only if it is a patch.
    fn shooter(&mut self, expected: ShooterKind, scene: &Scene) -> Decoded<Shooter> {
        let tag = self.u8()?;
        let a = self.u32()?;
        let cell = Cell {
            level: self.u32()?,
            x: self.u32()?,
            y: self.u32()?,
        };
        let kind = match tag {
            0 => ShooterKind::Spot { spot: a },
            1 => ShooterKind::Emitter { polygon: a },
            2 => ShooterKind::Patch { polygon: a, cell },
            t => return Err(format!("corrupt payload: unknown shooter kind {t}")),
        };
        if kind != expected {
            return Err("corrupt payload: shooters do not match the scene".to_string());
        }
        let total = DVec3::new(self.f64()?, self.f64()?, self.f64()?);
        if !total.is_finite() || total.min_element() < 0.0 {
            return Err("corrupt payload: a shooter total is negative or not finite".to_string());
        }
        let shape = match (self.u8()?, kind) {
            (0, _) => None,
            (1, ShooterKind::Patch { polygon, cell }) => Some(self.shape(scene, polygon, cell)?),
            (t, _) => return Err(format!("corrupt payload: shape tag {t} on a {kind:?}")),
        };
        Ok(Shooter { kind, total, shape })
    }

    /// The statistics (see [`W::stats`]); those of the trees are left to fill.
    fn stats(&mut self) -> Decoded<SolveStats> {
        let mut stats = SolveStats {
            shots: self.u64()?,
            ..SolveStats::default()
        };
        let nr = self.count(8)?;
        for _ in 0..nr {
            stats.refined_after.push(self.u64()?);
        }
        stats.emitted_power = self.f64()?;
        stats.unshot_fraction = self.f64()?;
        stats.guard_stops = crate::GuardStops {
            leaves: self.u64()?,
            worst_polygon: self.u32()?,
            worst_excess: self.f64()?,
            shadow_leaves: self.u64()?,
            edge_leaves: self.u64()?,
            error_power: self.f64()?,
            reflected_power: self.f64()?,
        };
        let mut v = [DVec3::ZERO; 5];
        for x in v.iter_mut() {
            *x = DVec3::new(self.f64()?, self.f64()?, self.f64()?);
        }
        if v.iter().any(|x| !x.is_finite()) {
            return Err("corrupt payload: the energy account is not finite".to_string());
        }
        stats.energy = crate::EnergyAccount {
            emitted: v[0],
            absorbed: v[1],
            unshot: v[2],
            lost: v[3],
            escaped: v[4],
        };
        let nh = self.count(8)?;
        for _ in 0..nh {
            stats.unshot_history.push(self.f64()?);
        }
        Ok(stats)
    }

    /// The end of the payload: nothing may follow the statistics.
    fn end(&self) -> Decoded<()> {
        if self.at != self.b.len() {
            return Err("corrupt payload: trailing bytes".to_string());
        }
        Ok(())
    }
}

/// Decodes file bytes for `scene` into the solution; the error says what kind of problem, with a
/// message for the user.
pub fn decode(bytes: &[u8], scene: &Scene) -> std::result::Result<Solution, Bad> {
    let Envelope { path_len, body } = envelope(bytes)?;
    let hash = le_u64(bytes, 24);
    if hash != scene_hash(scene) {
        return Err(Bad(
            SolutionProblem::SceneMismatch,
            "solution file is for another scene (or other radiosity settings); solve this scene again"
                .to_string(),
        ));
    }
    Ok(decode_payload(
        &bytes[HEADER + path_len..body],
        scene,
        hash,
    )?)
}

/// Decodes the payload (trees, values, shooters, stats) for `scene`; every failure is a corrupt
/// file.
fn decode_payload(payload: &[u8], scene: &Scene, hash: u64) -> Decoded<Solution> {
    let mut r = R { b: payload, at: 0 };
    let np = r.u32()? as usize;
    if np != scene.polygons.len() {
        return Err(format!(
            "corrupt payload: {np} polygons, the scene has {}",
            scene.polygons.len()
        ));
    }
    let polygons = (0..np)
        .map(|pi| r.polygon(pi))
        .collect::<Decoded<Vec<_>>>()?;
    let (geoms, _, _) = build_shooters(scene);
    let ns = r.count(30)?;
    if ns != geoms.len() {
        return Err(format!(
            "corrupt payload: {ns} shooters, the scene has {}",
            geoms.len()
        ));
    }
    let shooters = geoms
        .iter()
        .map(|g| r.shooter(g.kind, scene))
        .collect::<Decoded<Vec<_>>>()?;
    let mut stats = r.stats()?;
    r.end()?;
    fill_tree_stats(&mut stats, &polygons);
    Ok(Solution {
        polygons,
        shooters,
        stats,
        scene_hash: hash,
    })
}

#[cfg(test)]
mod path_tests {
    use super::relative_to;
    use std::path::{Path, PathBuf};

    #[test]
    fn scene_paths_are_stored_relative_to_the_solution_folder() {
        let rel = |t: &str, b: &str| relative_to(Path::new(t), Path::new(b));
        assert_eq!(rel("/a/b/s.toml", "/a/b"), Some(PathBuf::from("s.toml")));
        assert_eq!(
            rel("/a/scenes/s.toml", "/a/out/x"),
            Some(PathBuf::from("../../scenes/s.toml"))
        );
        assert_eq!(rel("/s.toml", "/"), Some(PathBuf::from("s.toml")));
        // Relative against absolute: no common root.
        assert_eq!(rel("s.toml", "/a"), None);
    }
}
