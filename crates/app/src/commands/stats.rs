//! The stats job: the paper's Table 1 for one scene (sizes of the original, mesh and RAT models,
//! texture and RRP memory) and, on request, frame times of the Table 1 methods measured in one
//! run.

use std::path::PathBuf;

use serde::Serialize;

use crate::commands::bench::{bench, BenchRow, Timed};
use crate::context::Context;
use crate::context::Input;
use crate::context::TextureOptions;
use crate::memory::Memory;
use crate::prepare::prepare;
use crate::prepare::Prepared;
use base::error::Result;
use base::method::{Filter, Method};
use engine::frame::FrameOptions;
use reconstruction::mesh::MeshStats;
use reconstruction::texture::TextureMemory;
use scene::Shape;

/// What `pixelflow-sim stats` was asked to do.
#[derive(Debug, Clone)]
pub struct StatsRequest {
    /// The scene's command-line options (`-D`, `--camera`, `--strict`).
    pub load: scene::LoadOptions,
    /// Scene file or solution file.
    pub input: PathBuf,
    /// The scene of a solution file, when it is no longer where the file says (`--scene`).
    pub scene: Option<PathBuf>,
    /// Frames timed per method (after one warm-up); 0 = sizes only.
    pub frames: u32,
    /// Frame options of the timings.
    pub frame: FrameOptions,
    /// Texture sizes and the bicubic filter's parameters.
    pub texture: TextureOptions,
}

/// Runs a stats job: load the input, check every option, then prepare once and tabulate.
pub fn run_stats(ctx: &Context<'_>, req: &StatsRequest) -> Result<ModelStats> {
    let input = Input::load_opts(&req.input, req.scene.as_deref(), &req.load)?;
    let bicubic = match req.texture.method(Method::Texture(Filter::MITCHELL))? {
        Method::Texture(f) => f,
        _ => Filter::MITCHELL,
    };
    req.frame.validate()?;
    crate::budget::check_frame_options(&req.frame, (false, false), ctx.memory_limit)?;
    let policy = req.texture.policy(&input.scene)?;
    let placement = req.texture.placement(&input.scene)?;
    let p = prepare(ctx, input, policy, placement)?;
    model_stats(&p, req.frames, &req.frame, bicubic)
}

/// The paper's Table 1 for one scene: sizes of the original, mesh ("poly") and RAT models, the
/// RRP memory, and optionally frame rates of each method measured in one run.
#[derive(Debug, Clone, Serialize)]
pub struct ModelStats {
    /// Scene file.
    pub scene: String,
    /// The SIMD build frames run with (`portable`, `avx2`, `avx512`; [`lanes::Level::name`]).
    pub simd: &'static str,
    /// Original model: triangles (2 per quad) and distinct corner positions.
    pub original: MeshStats,
    /// Mesh model: the adaptive quadtrees triangulated with T-vertex fans.
    pub mesh: MeshStats,
    /// RAT model triangles (the original triangles: textures replace the subdivision).
    pub rat_triangles: u64,
    /// RAT model vertices: corners are not shared between polygons, since each carries its own
    /// texture coordinates (4 per quad, 3 per triangle).
    pub rat_vertices: u64,
    /// RAT model geometry size: `rat_vertices` x (12 B position + 8 B texture coordinates) +
    /// `rat_triangles` x 12 B indices.
    pub rat_bytes: u64,
    /// Texture memory and texture count under the job's size policy.
    pub texture_memory: TextureMemory,
    /// RRP memory as the direct method holds it, bytes: the compact form (locate trees, leaf
    /// records, vertex Hermite data held as f32; [`reconstruction::compact::CompactStats`]).
    pub rrp_bytes: u64,
    /// The RRPs as stored, bytes: the trees (a bit per node) and samples (three f32 per vertex)
    /// they are built from, what a solution file spends on them
    /// ([`crate::memory::rrp_stored_bytes`]).
    pub rrp_stored_bytes: u64,
    /// The compact RRPs' Hermite data quantized to 16-bit mantissas with 4-bit shifts, bytes:
    /// measured, not stored.
    pub rrp_encoded_bytes: u64,
    /// The direct method's bounded caches of expanded patches, one per worker thread, bytes
    /// (working memory beside `rrp_bytes`, like frame buffers).
    pub rrp_cache_bytes: u64,
    /// The RRPs with every patch expanded (208-byte power-basis patches + locate trees), bytes.
    pub rrp_expanded_bytes: u64,
    /// RRP patches.
    pub rrp_patches: u64,
    /// Radiosity samples of the solution.
    pub samples: u64,
    /// Where the solve's guards stopped refinement with the error test still failing.
    pub guard_stops: GuardReport,
    /// Frame times per method (medians), if frames were measured.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub frames: Vec<BenchRow>,
}

/// Where the solve's guards (`max_depth`, the smallest element) stopped refinement while the
/// error test still failed ([`radiosity::GuardStops`]), as `--stats` and `stats` report it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GuardReport {
    /// Leaves split to a guard with their light still failing the error test.
    pub leaves: u64,
    /// Leaves split to a guard only because a shadow boundary crosses them (not warned about).
    pub shadow_leaves: u64,
    /// Leaves split to a guard with the test failing where a spot's cone edge crosses them
    /// (drawn exactly from the spot's light; not warned about).
    pub edge_leaves: u64,
    /// The worst leaf's polygon, as file:line (`None` when no leaf stopped).
    pub worst: Option<String>,
    /// Its estimated error relative to the leaf's level.
    pub worst_excess: f64,
    /// The share of the scene's reflected light the stopped leaves may misplace (an upper
    /// bound; the warning fires above `radiosity.tolerance`).
    pub error_share: f64,
    /// The warning `solve` and `render` print (`None` when no leaf stopped).
    pub warning: Option<String>,
}

impl GuardReport {
    /// The report of `g`, a solve of `scene`.
    pub fn of(g: &radiosity::GuardStops, scene: &scene::Scene) -> GuardReport {
        GuardReport {
            leaves: g.leaves,
            shadow_leaves: g.shadow_leaves,
            edge_leaves: g.edge_leaves,
            worst: (g.leaves > 0).then(|| g.worst_origin(scene)),
            worst_excess: g.worst_excess,
            error_share: g.error_share(),
            warning: g.warning(scene),
        }
    }
}

/// For a solution file, where its solve's guards stopped refinement (`None` for a scene file,
/// which has not been solved).
pub fn solution_guards(input: &Input) -> Result<Option<GuardReport>> {
    let Some(path) = &input.solution_file else {
        return Ok(None);
    };
    let sol = radiosity::file::read_solution_up_to(path, &input.scene, input.input_limit)?;
    Ok(Some(GuardReport::of(&sol.stats.guard_stops, &input.scene)))
}

/// Bytes per RAT vertex in [`ModelStats::rat_bytes`]: position (3 x f32) + (u, v) (2 x f32).
pub(crate) const RAT_BYTES_PER_VERTEX: u64 = 20;

/// The methods `stats --frames` measures, in the paper's Table 1 order plus the direct method.
pub(crate) const STATS_METHODS: [Method; 4] = [
    Method::Mesh,
    Method::Texture(Filter::Bilinear),
    Method::Texture(Filter::MITCHELL),
    Method::Direct,
];

/// The original polygons as the RAT model (and the direct method) draw them: triangles (2 per
/// quad) and vertices, corners not shared between polygons since each carries its own texture
/// coordinates (4 per quad, 3 per triangle).
pub fn rat_geometry(scene: &scene::Scene) -> (u64, u64) {
    scene
        .polygons
        .iter()
        .fold((0, 0), |(t, v), poly| match poly.shape {
            Shape::Triangle => (t + 1, v + 3),
            Shape::Quad => (t + 2, v + 4),
        })
}

/// Table 1 for a prepared scene; with `frames > 0`, each of `STATS_METHODS` is rendered
/// `frames` times (after a warm-up) at `opts`'s size and the medians are reported. The bicubic
/// filter is `bicubic`'s (Mitchell–Netravali unless given).
pub fn model_stats(
    p: &Prepared,
    frames: u32,
    opts: &FrameOptions,
    bicubic: Filter,
) -> Result<ModelStats> {
    let (mesh, _) = p.mesh()?;
    let original = MeshStats::original(&p.scene);
    let (rat_triangles, rat_vertices) = rat_geometry(&p.scene);
    let memory = Memory::of(p)?;
    let mut rows = Vec::new();
    if frames > 0 {
        for m in STATS_METHODS {
            let m = match m {
                Method::Texture(Filter::Bicubic { .. }) => Method::Texture(bicubic),
                m => m,
            };
            rows.extend(bench(
                p,
                Timed::Method(m),
                &[(opts.width, opts.height)],
                frames,
                opts,
            )?);
        }
    }
    Ok(ModelStats {
        scene: p.scene.source.display().to_string(),
        simd: opts.isa.name(),
        original,
        mesh: mesh.stats,
        rat_triangles,
        rat_vertices,
        rat_bytes: rat_vertices * RAT_BYTES_PER_VERTEX + rat_triangles * 12,
        texture_memory: memory.textures,
        rrp_bytes: memory.rrp_compact,
        rrp_stored_bytes: memory.rrp_stored,
        rrp_encoded_bytes: memory.rrp_encoded,
        rrp_cache_bytes: memory.rrp_caches,
        rrp_expanded_bytes: memory.rrp_expanded,
        rrp_patches: p.compact.leaf_count() as u64,
        samples: p.solution.stats.vertices,
        guard_stops: GuardReport::of(&p.solution.stats.guard_stops, &p.scene),
        frames: rows,
    })
}
