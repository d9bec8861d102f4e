//! The resource budget: one estimator of the memory a job will hold, compared with one limit
//! before anything large is allocated, so a request that cannot fit is refused (exit code 2,
//! [`Error::Memory`], the estimate and what it is made of in the message) instead of growing
//! until the allocator aborts the process.
//!
//! **The limit** travels in the job's [`crate::context::Context`] (`memory_limit`): the binary sets it from
//! `--memory-limit`, by default [`default_limit`]: the smallest of three quarters of the
//! machine's physical memory (`/proc/meminfo`; 8 GiB where that cannot be read), three quarters
//! of the memory cgroup's limit (`memory.max`, or `memory.limit_in_bytes` under cgroup v1), and
//! half the process's address-space limit (`ulimit -v`: the address space also holds the
//! program, thread stacks and the allocator's reserved arenas, so a heap cannot use all of it);
//! a library caller that
//! sets none has no limit. Every allocation site a job reaches (solve, textures, mesh, frame,
//! outputs) checks its estimate against that one value.
//!
//! **What is estimated**, from the sizes each stage itself exports (never from a measurement):
//! - **solve**: the quadtrees and samples ([`sizes::state_bytes`]), the RRPs built from them,
//!   the cache of coarse transfers, the pair tables (every shooter against every polygon with
//!   exact visibility, against at most its probe rays' hits with sampled visibility:
//!   [`sizes::pair_table_bound`]) and the shooters' sample points, with every tree at its starting
//!   depth (`min_depth`, or its shooter-patch depth if deeper: what the solve surely allocates,
//!   checked before it starts) and, as the worst case, every tree as deep as its smallest
//!   element size lets it refine ([`sizes::depth_bound`]); splits past that depth (near small
//!   lights, at cone edges, around peaks) add at most [`sizes::DIVE_NODES`] nodes to a polygon,
//!   reported apart (`dive_bytes`). The worst case is reported, not
//!   refused: adaptive refinement rarely comes near it. Not estimable in advance: the occluder
//!   candidate lists of occluded pairs, which only the classification finds (the gallery:
//!   386,000 occluded pairs with 12 candidates each, 18 MB). So the solve also guards itself
//!   ([`radiosity::SolveOptions::memory_limit`]): its actual trees and pair tables,
//!   candidates included, are checked before every refinement pass and every new pair table,
//!   and it stops with [`Error::Memory`] before it would pass the limit.
//! - **textures**: every polygon's size under the size policy ([`TextureSet::sizes`]), 32-bit
//!   texels with mip chains, plus the expanded RRPs they are resampled from, checked before they
//!   are built, with what is held already (solution and compact RRPs);
//! - **mesh**: at most two triangles per leaf plus one per T-vertex, each with its vertices,
//!   indices and its primitive record in a frame (`MESH_TRIANGLE_BYTES`), checked likewise;
//! - **frame**: the image, and each worker thread's region G-buffers (one per renderer, at most
//!   two, of [`PIXEL_RECORD_BYTES`] a sample), reused region after region (`frame_bytes`);
//! - **outputs**: the 8-bit PNG buffer and the 32-bit EXR buffer, each held twice while encoding
//!   (`output_bytes`).
//!
//! These are the allocations that grow with the scene and the request; the program itself, its
//! thread stacks and the allocator's slack (4-8 MB resident on Linux, where the binary fixes
//! glibc's mmap threshold so that freed large buffers leave the resident set) are one constant,
//! [`PROGRAM_BYTES`], that every check adds and the solve's and loader's guards leave out of
//! their share ([`data_limit`]); short-lived buffers smaller than the largest counted one are
//! not counted. docs/performance.md compares
//! the estimates with measured peaks.
//!
//! Work is bounded where it can run away: the option limits of [`base::method`] and the binary
//! (threads, renderers, frame counts, image sides) cap it; the solve reports its progress.

use base::error::{human_bytes, Error, Result};
use engine::raster::gbuffer::PIXEL_RECORD_BYTES;
use radiosity::sizes;
use reconstruction::texture::{Extent, SizePolicy, TextureMemory, TextureSet, GUTTER};
use reconstruction::PatchCoeffs;
use scene::Scene;

/// The program's own resident memory, which every check adds to its estimate and the solve's
/// and the loader's guards keep out of the limit: code and libraries, thread stacks, the
/// allocator's slack (measured resident: 4.3 MiB for `--version`, 7.7 MiB for `check` of the
/// Cornell box; a texture render of the gallery admitted under a 42 MiB limit by the data's
/// estimate alone peaked at 47.6 MiB). With it, a job admitted under `--memory-limit` stays
/// under it as a resident set, not only as counted data.
pub const PROGRAM_BYTES: u64 = 8 << 20;

/// What the stages may hold under `limit`: the limit less [`PROGRAM_BYTES`].
pub fn data_limit(limit: u64) -> u64 {
    limit.saturating_sub(PROGRAM_BYTES)
}

/// Physical memory of this machine in bytes (`MemTotal` of `/proc/meminfo`), if it can be read.
pub(crate) fn machine_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    kib.checked_mul(1024)
}

/// Used when the machine's memory cannot be read.
pub(crate) const FALLBACK_LIMIT: u64 = 8 << 30;

/// The default limit (module doc): the smallest of 3/4 of the physical memory (or
/// `FALLBACK_LIMIT`), 3/4 of the memory cgroup's limit and 1/2 of the address-space limit.
pub fn default_limit() -> u64 {
    let mut limit = machine_memory().map_or(FALLBACK_LIMIT, |m| m / 4 * 3);
    let read = |p: &str| std::fs::read_to_string(p).ok();
    if let Some(c) = read("/proc/self/cgroup").and_then(|t| cgroup_limit(&t, read)) {
        limit = limit.min(c / 4 * 3);
    }
    if let Some(a) = read("/proc/self/limits").and_then(|t| address_space_limit(&t)) {
        limit = limit.min(a / 2);
    }
    limit.max(1)
}

/// Limits at or above this are "no limit" (cgroup v1 writes 2^63 rounded down to a page).
const UNLIMITED: u64 = 1 << 62;

/// The soft address-space limit in bytes from the text of `/proc/self/limits`; `None` when
/// unlimited or unreadable.
pub(crate) fn address_space_limit(limits: &str) -> Option<u64> {
    let line = limits
        .lines()
        .find(|l| l.starts_with("Max address space"))?;
    let soft = line["Max address space".len()..]
        .split_whitespace()
        .next()?;
    soft.parse().ok().filter(|&b| b < UNLIMITED)
}

/// The memory limit of this process's cgroup, given the text of `/proc/self/cgroup` and a
/// reader of files: cgroup v2 (`0::<path>`, `/sys/fs/cgroup<path>/memory.max`), else v1 (the
/// `memory` controller's `memory.limit_in_bytes` under its path, or at the hierarchy's root as
/// a container sees it). `None` when unlimited or unreadable.
pub(crate) fn cgroup_limit(cgroups: &str, read: impl Fn(&str) -> Option<String>) -> Option<u64> {
    let value =
        |text: String| -> Option<u64> { text.trim().parse().ok().filter(|&b: &u64| b < UNLIMITED) };
    for line in cgroups.lines() {
        let mut parts = line.splitn(3, ':');
        let (id, controllers, path) = (parts.next()?, parts.next()?, parts.next()?);
        let path = path.trim_end_matches('/');
        if id == "0" && controllers.is_empty() {
            if let Some(v) = read(&format!("/sys/fs/cgroup{path}/memory.max")).and_then(value) {
                return Some(v);
            }
        } else if controllers.split(',').any(|c| c == "memory") {
            // The process's own cgroup if visible (its value, limited or not), else the root
            // of the hierarchy as mounted (a container's own cgroup).
            let own = read(&format!(
                "/sys/fs/cgroup/memory{path}/memory.limit_in_bytes"
            ));
            let text = own.or_else(|| read("/sys/fs/cgroup/memory/memory.limit_in_bytes"));
            if let Some(v) = text.and_then(value) {
                return Some(v);
            }
        }
    }
    None
}

/// Parses a memory size: a number of bytes with an optional unit, `K`/`M`/`G`/`T` (binary,
/// also written `KiB` .. `TiB`, or with a `B`), case-insensitive, a decimal fraction allowed
/// (`1.5G`); or `none` / `unlimited` for no limit (`u64::MAX`). Zero, negative sizes and
/// sizes of 2^64 bytes or more are refused, each with its own message.
pub fn parse_size(text: &str) -> std::result::Result<u64, String> {
    let lower = text.trim().to_ascii_lowercase();
    if lower == "none" || lower == "unlimited" {
        return Ok(u64::MAX);
    }
    base::method::size_in_bytes(text).map_err(|e| {
        if e.contains("2^64") {
            e + "; write `none` for no limit"
        } else {
            e
        }
    })
}

/// One estimate: what it is for, its parts (name, bytes) and what to change if it is too big.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Estimate {
    /// The job or stage (`the solve of scenes/a.toml`).
    pub what: String,
    /// Named parts in bytes, in the order they were added.
    pub parts: Vec<(String, u64)>,
    /// What lowers it.
    pub hint: String,
}

impl Estimate {
    /// An empty estimate.
    pub fn new(what: impl Into<String>, hint: impl Into<String>) -> Estimate {
        Estimate {
            what: what.into(),
            parts: Vec::new(),
            hint: hint.into(),
        }
    }

    /// Adds a part.
    pub fn add(&mut self, name: impl Into<String>, bytes: u64) -> &mut Estimate {
        self.parts.push((name.into(), bytes));
        self
    }

    /// The sum of the parts (saturating).
    pub fn total(&self) -> u64 {
        self.parts
            .iter()
            .fold(0u64, |a, (_, b)| a.saturating_add(*b))
    }

    /// `quadtrees 1.2 GiB + pair tables 3.0 MiB`.
    pub fn detail(&self) -> String {
        self.parts
            .iter()
            .map(|(n, b)| format!("{n} {}", human_bytes(*b)))
            .collect::<Vec<_>>()
            .join(" + ")
    }

    /// `Ok` if the total and the program's own [`PROGRAM_BYTES`] are at most `limit`, else
    /// [`Error::Memory`] with that estimate, the program named among its parts.
    pub fn check(&self, limit: u64) -> Result<()> {
        let total = self.total().saturating_add(PROGRAM_BYTES);
        if total <= limit {
            return Ok(());
        }
        Err(Error::Memory {
            what: self.what.clone(),
            estimate: total,
            limit,
            detail: format!("program {} + {}", human_bytes(PROGRAM_BYTES), self.detail()),
            hint: self.hint.clone(),
        })
    }
}

/// Nodes and samples of one quadtree refined uniformly to `depth` (saturating).
fn uniform_tree(depth: u32) -> (u64, u64) {
    let d = depth.min(30);
    let nodes = ((1u64 << (2 * d + 2)) - 1) / 3;
    let side = (1u64 << d) + 1;
    (nodes, side * side)
}

/// Which depth `solve_parts` puts every quadtree at.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Depth {
    /// The starting depth: `min_depth`, or the polygon's shooter-patch depth if deeper (what
    /// the solve surely allocates).
    Start,
    /// The deepest a polygon's leaves can reach ([`sizes::depth_bound`], at most `max_depth`),
    /// uniformly: the worst case.
    Worst,
}

/// Per polygon, the uniform depth of its quadtree under `depth`.
pub(crate) fn polygon_depths(scene: &Scene, depth: Depth) -> Vec<u32> {
    let st = &scene.radiosity;
    let total_area: f64 = scene.polygons.iter().map(|p| p.area).sum();
    let min_size = sizes::min_element_size(scene);
    scene
        .polygons
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let pd = if scene.material_of(i).reflectance.max_element() > 0.0 {
                sizes::patch_depth(p.area, total_area, st.max_depth)
            } else {
                0
            };
            let start = st.min_depth.max(pd).min(st.max_depth.max(pd));
            match depth {
                Depth::Start => start,
                Depth::Worst => start.max(sizes::depth_bound(scene, i, min_size)),
            }
        })
        .collect()
}

/// The solve's memory with every quadtree uniformly at `depth`, as parts: quadtrees and
/// samples, the RRPs built from them, the cache of coarse transfers (at most
/// [`sizes::COARSE_CACHE_ENTRIES`]), pair tables, shooters.
pub(crate) fn solve_parts(scene: &Scene, depth: Depth) -> Vec<(String, u64)> {
    let st = &scene.radiosity;
    let total_area: f64 = scene.polygons.iter().map(|p| p.area).sum();
    let nrays = u64::from(st.shadow_rays.max(1));
    let (mut nodes, mut vertices, mut leaves) = (0u64, 0u64, 0u64);
    let (mut shooters, mut shooter_points, mut coarse) = (0u64, 0u64, 0u64);
    shooters += scene.spots.len() as u64;
    let mut lights = shooters;
    for (i, d) in polygon_depths(scene, depth).into_iter().enumerate() {
        let (n, v) = uniform_tree(d);
        nodes = nodes.saturating_add(n);
        vertices = vertices.saturating_add(v);
        leaves = leaves.saturating_add(1u64 << (2 * d.min(30)));
        let m = scene.material_of(i);
        if m.is_emitter() {
            shooters += 1;
            lights += 1;
            shooter_points += nrays;
        }
        if m.reflectance.max_element() > 0.0 {
            let pd = sizes::patch_depth(scene.polygons[i].area, total_area, st.max_depth);
            let patches = 1u64 << (2 * pd);
            shooters += patches;
            shooter_points += patches * nrays.div_ceil(4);
            coarse += uniform_tree(pd + 1).1;
        }
    }
    vec![
        (
            "quadtrees and samples".to_string(),
            sizes::state_bytes(nodes, vertices),
        ),
        (
            // Built from the finished solution (solve and render jobs): one expanded patch
            // per leaf while the compact form is made.
            "RRP build".to_string(),
            leaves.saturating_mul(std::mem::size_of::<PatchCoeffs>() as u64),
        ),
        (
            "coarse transfer cache".to_string(),
            4 * shooters
                .saturating_mul(coarse)
                .min(sizes::COARSE_CACHE_ENTRIES as u64),
        ),
        (
            "pair tables".to_string(),
            sizes::pair_table_bound(scene, shooters, lights),
        ),
        ("shooters".to_string(), shooter_points.saturating_mul(3 * 8)),
    ]
}

/// The solve's estimate: what it surely allocates ([`Depth::Start`]) as an [`Estimate`], and
/// the worst case ([`Depth::Worst`]) in bytes.
pub(crate) fn solve_estimate(scene: &Scene) -> (Estimate, u64) {
    let mut e = Estimate::new(
        format!("the solve of {}", scene.source.display()),
        "lower radiosity.min_depth, use fewer polygons, or raise `memory-limit`",
    );
    for (name, b) in solve_parts(scene, Depth::Start) {
        e.add(name, b);
    }
    let worst = solve_parts(scene, Depth::Worst)
        .iter()
        .fold(0u64, |a, (_, b)| a.saturating_add(*b));
    (e, worst)
}

/// Bytes the splits past the guards may add to the solve: [`sizes::DIVE_NODES`] nodes (each
/// split 4 nodes and at most 5 samples) on every reflecting polygon.
pub(crate) fn dive_bytes(scene: &Scene) -> u64 {
    let reflecting = (0..scene.polygons.len())
        .filter(|&i| scene.material_of(i).reflectance.max_element() > 0.0)
        .count() as u64;
    let per_polygon = sizes::state_bytes(sizes::DIVE_NODES, sizes::DIVE_NODES / 4 * 5);
    reflecting.saturating_mul(per_polygon)
}

/// The worst case of the methods' own data: textures (under `policy`) and mesh with every
/// quadtree uniformly at its [`Depth::Worst`] depth, in bytes.
pub(crate) fn worst_method_bytes(scene: &Scene, policy: SizePolicy) -> Result<(u64, u64)> {
    let depths = polygon_depths(scene, Depth::Worst);
    let (mut nodes, mut leaves) = (0u64, 0u64);
    for &d in &depths {
        let (n, _) = uniform_tree(d);
        nodes = nodes.saturating_add(n);
        leaves = leaves.saturating_add(1u64 << (2 * d.min(30)));
    }
    let extents: Vec<Extent> = depths
        .iter()
        .zip(&scene.polygons)
        .map(|(&depth, p)| Extent {
            depth,
            aspect: Extent::aspect_of(p),
        })
        .collect();
    let textures = texture_bytes(&extents, policy, leaves, nodes)?;
    Ok((textures, mesh_bytes(leaves, 0)))
}

/// Bytes of a frame of `width` x `height` pixels with `samples` samples per pixel,
/// `renderers` renderers and regions of side `region`, as the frame engine holds them: the
/// RGB `f32` image, and per worker thread of the current pool the region G-buffers it reuses
/// region after region (one per renderer, at most two: a later renderer's report is merged as
/// soon as it is drawn), each `region^2` pixels (less for a smaller image) of `samples`
/// records. Measured against it: a 4096 x 4096 frame with 16 samples and EXR output peaks at
/// 0.58 GiB, this and [`output_bytes`] say 0.62 GiB (the whole-frame bound this replaced said
/// 13.7 GiB).
pub(crate) fn frame_bytes(
    width: u32,
    height: u32,
    samples: u32,
    renderers: u32,
    region: u32,
) -> u64 {
    let pixels = u64::from(width) * u64::from(height);
    let side = u64::from(region.min(width.max(height)).max(1));
    let workers = rayon::current_num_threads() as u64;
    let per_worker = (side * side)
        .saturating_mul(u64::from(samples.max(1)))
        .saturating_mul(PIXEL_RECORD_BYTES)
        .saturating_mul(u64::from(renderers.clamp(1, 2)));
    pixels
        .saturating_mul(12)
        .saturating_add(workers.saturating_mul(per_worker))
}

/// Bytes of the output buffers: the 8-bit RGB PNG (3 B per pixel) and the 32-bit RGB EXR
/// (12 B per pixel), each counted twice (the pixels and the encoder's copy), and the luminance
/// summary's `f32` per pixel (`imageio::exposure`).
pub(crate) fn output_bytes(width: u32, height: u32, png: bool, exr: bool) -> u64 {
    let pixels = u64::from(width) * u64::from(height);
    let per = if png { 3 } else { 0 } + if exr { 12 } else { 0 };
    pixels.saturating_mul(2 * per + 4)
}

/// Bytes of the radiosity textures under `policy` for polygons of the given `extents` (32-bit
/// texels with mip chains, as they are held), plus the expanded RRPs with `leaves` leaves and
/// `nodes` nodes they are resampled from.
pub fn texture_bytes(
    extents: &[Extent],
    policy: SizePolicy,
    leaves: u64,
    nodes: u64,
) -> Result<u64> {
    let sizes = TextureSet::sizes(extents, policy)?;
    let m = TextureMemory::of_sizes(&sizes, GUTTER);
    let rrps = leaves
        .saturating_mul(std::mem::size_of::<PatchCoeffs>() as u64)
        .saturating_add(nodes.saturating_mul(4))
        .saturating_add(4 * extents.len() as u64);
    Ok(m.bytes_with_chain[2].saturating_add(rrps))
}

/// Bytes one Gouraud mesh triangle takes: its polygon record in the mesh's scene, its compact
/// patch, its source polygon and parent (u, v), and while a frame draws it its primitive record
/// and a bin entry.
pub(crate) const MESH_TRIANGLE_BYTES: u64 = (std::mem::size_of::<scene::Polygon>()
    + std::mem::size_of::<reconstruction::mesh::GouraudPatch>()
    + 4
    + 48
    + std::mem::size_of::<engine::raster::setup::Prim>()
    + 4) as u64;

/// Bytes of the Gouraud mesh of a solution with `leaves` leaves and `t_vertices` T-vertices.
/// A leaf with `k` T-vertices on its edges becomes `2 + k` triangles fanned from a corner, or
/// `4 + k` fanned from its centre when `k >= 2`; both are at most `2 + 2k`, so the mesh has at
/// most `2 leaves + 2 t_vertices` triangles.
pub(crate) fn mesh_bytes(leaves: u64, t_vertices: u64) -> u64 {
    leaves
        .saturating_add(t_vertices)
        .saturating_mul(2)
        .saturating_mul(MESH_TRIANGLE_BYTES)
}

/// Refuses a solve of `scene` whose sure allocation is over `limit`.
pub(crate) fn check_solve(scene: &Scene, limit: u64) -> Result<()> {
    solve_estimate(scene).0.check(limit)
}

/// Refuses frames under `opts` (and outputs: PNG, EXR) over `limit`.
pub fn check_frame_options(
    opts: &engine::frame::FrameOptions,
    outputs: (bool, bool),
    limit: u64,
) -> Result<()> {
    check_frame(
        (opts.width, opts.height, opts.region),
        opts.aa.samples(),
        opts.renderers,
        outputs,
        limit,
    )
}

/// The estimate of a frame of `width` x `height` pixels in regions of side `region` with
/// `samples` samples per pixel and `renderers` renderers, and its outputs (`outputs`: PNG, EXR).
pub(crate) fn frame_estimate(
    (width, height, region): (u32, u32, u32),
    samples: u32,
    renderers: u32,
    outputs: (bool, bool),
) -> Estimate {
    let mut e = Estimate::new(
        format!("a {width} x {height} frame with {samples} samples per pixel"),
        "lower `width`/`height`, `aa` or `renderers`, or raise `memory-limit`",
    );
    e.add(
        "G-buffers and image",
        frame_bytes(width, height, samples, renderers, region),
    );
    e.add("outputs", output_bytes(width, height, outputs.0, outputs.1));
    e
}

/// Refuses a frame (and its outputs) over `limit`.
pub(crate) fn check_frame(
    size: (u32, u32, u32),
    samples: u32,
    renderers: u32,
    outputs: (bool, bool),
    limit: u64,
) -> Result<()> {
    frame_estimate(size, samples, renderers, outputs).check(limit)
}

/// What `check` reports for a scene: the solve (what it surely allocates, and the worst case),
/// one frame at the scene's image size with a PNG, and the worst cases of the textures and the
/// mesh.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SceneBudget {
    /// The solve at its starting depth (refused over the limit).
    pub solve: Estimate,
    /// The solve with every tree as deep as it can refine, bytes (reported only).
    pub solve_worst: u64,
    /// One frame at the scene's size, samples and the default renderer count, with a PNG
    /// (refused over the limit).
    pub frame: Estimate,
    /// Renderers the frame estimate assumes.
    pub renderers: u32,
    /// Textures under the scene's size policy at the worst depths, bytes (reported only).
    pub textures_worst: u64,
    /// The mesh at the worst depths, bytes (reported only).
    pub mesh_worst: u64,
}

impl SceneBudget {
    /// Refuses what a solve or render of the scene would refuse: the solve's or the frame's
    /// estimate over `limit`.
    pub fn check(&self, limit: u64) -> Result<()> {
        self.solve.check(limit)?;
        self.frame.check(limit)
    }
}

/// The [`SceneBudget`] of `scene`.
pub fn scene_budget(scene: &Scene) -> Result<SceneBudget> {
    let (solve, solve_worst) = solve_estimate(scene);
    let opts = engine::frame::FrameOptions::new(scene.width, scene.height);
    let frame = frame_estimate(
        (scene.width, scene.height, opts.region),
        scene.render.aa_samples.samples(),
        opts.renderers,
        (true, false),
    );
    let (textures_worst, mesh_worst) =
        worst_method_bytes(scene, crate::context::scene_texture_policy(scene))?;
    Ok(SceneBudget {
        solve,
        solve_worst,
        frame,
        renderers: opts.renderers,
        textures_worst,
        mesh_worst,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_address_space_and_cgroup_limits_are_read() {
        let limits = "Limit                     Soft Limit           Hard Limit           Units\n\
                      Max stack size            8388608              unlimited            bytes\n\
                      Max address space         4294967296           unlimited            bytes\n";
        assert_eq!(address_space_limit(limits), Some(4 << 30));
        let open = limits.replace("4294967296", "unlimited");
        assert_eq!(address_space_limit(&open), None);
        // cgroup v2: the process's own cgroup's memory.max; "max" is no limit.
        let files = |p: &str| match p {
            "/sys/fs/cgroup/jobs/a/memory.max" => Some("1073741824\n".to_string()),
            "/sys/fs/cgroup/jobs/b/memory.max" => Some("max\n".to_string()),
            "/sys/fs/cgroup/memory/memory.limit_in_bytes" => Some("536870912\n".to_string()),
            "/sys/fs/cgroup/memory/x/memory.limit_in_bytes" => {
                Some("9223372036854771712\n".to_string())
            }
            _ => None,
        };
        assert_eq!(cgroup_limit("0::/jobs/a\n", files), Some(1 << 30));
        assert_eq!(cgroup_limit("0::/jobs/b\n", files), None);
        // cgroup v1: the memory controller's path, else the root a container sees; v1's
        // "unlimited" (2^63 less a page) is no limit.
        assert_eq!(
            cgroup_limit("4:memory:/not/visible\n0::/\n", files),
            Some(512 << 20)
        );
        assert_eq!(cgroup_limit("4:memory:/x\n", files), None);
        assert_eq!(cgroup_limit("", files), None);
    }

    #[test]
    fn sizes_parse_with_binary_units() {
        assert_eq!(parse_size("123"), Ok(123));
        assert_eq!(parse_size("4k"), Ok(4096));
        assert_eq!(parse_size("512M"), Ok(512 << 20));
        assert_eq!(parse_size("8GiB"), Ok(8 << 30));
        assert_eq!(parse_size("1.5 G"), Ok(3 << 29));
        assert_eq!(parse_size("2tb"), Ok(2 << 40));
        assert_eq!(parse_size("none"), Ok(u64::MAX));
        assert_eq!(
            parse_size("1e300T"),
            Err("unknown unit `e300t`: write bytes, or a number with K, M, G or T".into())
        );
        assert!(parse_size("0").is_err());
        assert!(parse_size("-5G").unwrap_err().contains("negative"));
        assert!(parse_size("").is_err());
        assert!(parse_size("5X").is_err());
        // Overflow is refused, not taken as "no limit".
        assert!(parse_size("99999999999999999999T")
            .unwrap_err()
            .contains("2^64 bytes or more"));
        assert!(parse_size("16384P").is_err());
    }

    #[test]
    fn uniform_tree_counts_match_a_built_tree() {
        for d in 0..5 {
            let mut t = base::quadtree::Quadtree::new();
            let mut frontier = vec![0u32];
            for _ in 0..d {
                let mut next = Vec::new();
                for id in frontier {
                    let f = t.split(id);
                    next.extend(f..f + 4);
                }
                frontier = next;
            }
            assert_eq!(
                uniform_tree(d),
                (t.nodes().len() as u64, t.vertex_keys().len() as u64)
            );
        }
    }

    #[test]
    fn an_estimate_over_the_limit_names_its_parts() {
        let mut e = Estimate::new("the solve of a.toml", "lower it");
        e.add("quadtrees", 3 << 30).add("pair tables", 1 << 20);
        assert_eq!(e.total(), (3 << 30) + (1 << 20));
        assert!(e.check(4 << 30).is_ok());
        let err = e.check(1 << 30).unwrap_err();
        assert_eq!(err.exit_code(), base::error::EXIT_BAD_INPUT);
        assert_eq!(
            err.to_string(),
            "the solve of a.toml needs an estimated 3.0 GiB (program 8.0 MiB + quadtrees 3.0 GiB \
             + pair tables 1.0 MiB), over the memory limit of 1.0 GiB; lower it"
        );
        // The program's own memory is part of every check.
        let total = e.total() + PROGRAM_BYTES;
        assert!(e.check(total).is_ok());
        assert!(e.check(total - 1).is_err());
        assert_eq!(data_limit(total), e.total());
        assert_eq!(data_limit(PROGRAM_BYTES / 2), 0);
    }

    #[test]
    fn the_largest_frame_is_refused_under_a_machine_sized_limit() {
        // 16384^2 pixels: the image (12 B a pixel) and the PNG and EXR buffers (2 x 15 B) are
        // 10.5 GiB; the region G-buffers add little.
        let size = (16384, 16384, 128);
        let e = check_frame(size, 16, 2, (true, true), 8 << 30).unwrap_err();
        assert!(e.to_string().contains("16384 x 16384"), "{e}");
        assert!(check_frame(size, 16, 2, (true, true), 12 << 30).is_ok());
        assert!(check_frame((1024, 1024, 128), 4, 2, (true, true), 24 << 30).is_ok());
    }
}
