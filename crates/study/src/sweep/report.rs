//! What a sweep reports: its points (each method at each density and texture size, with its
//! errors against the same solution, the converged one and the light, its time and bytes), the
//! solutions it drew from, how the times were measured, and the report as CSV and as a table.

use super::*;

/// The four error measures of one image against one reference.
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct Errors {
    /// Perceptual distance (`docs/metrics.md`).
    pub perceptual: f64,
    /// RMSE of luminance.
    pub rmse: f64,
    /// Largest absolute luminance error.
    pub max_abs: f64,
    /// Mach-band measure of the difference.
    pub mach_band: f64,
    /// RMSE of luminance over the reference's mean luminance (0 where that mean is 0): a second
    /// metric beside the perceptual distance, with no model of vision in it.
    pub relative_rmse: f64,
    /// Share of the squared luminance error within a few pixels of the reference's sharp edges
    /// (light and shadow edges, emitters' outlines, silhouettes: [`metric::edges`]), in [0, 1].
    pub near_edges_share: f64,
}

impl From<&Comparison> for Errors {
    fn from(c: &Comparison) -> Errors {
        Errors {
            perceptual: c.perceptual_distance,
            rmse: c.rmse,
            max_abs: c.max_abs_error,
            mach_band: c.mach_band,
            relative_rmse: if c.mean_luminance_b > 0.0 {
                c.rmse / c.mean_luminance_b
            } else {
                0.0
            },
            near_edges_share: c.edges.near_share,
        }
    }
}

/// A texture method's texture size and texel placement at a point.
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct TextureLevel {
    /// How many times the quadtree-depth sides were halved (0: as deep as the quadtree).
    pub halvings: u32,
    /// Where the texels sit: `centre` (u = (i + 0.5) / N) or `corner` (u = i / (N - 1)).
    pub placement: &'static str,
    /// Level-0 texels of all textures.
    pub texels: u64,
    /// Bytes at 12 bits per channel with mip chains.
    pub bytes: u64,
}

/// One measured point.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct SweepPoint {
    /// Method name.
    pub method: String,
    /// Density level, 0 the coarsest.
    pub density: usize,
    /// The solver tolerance of that level.
    pub tolerance: f64,
    /// Radiosity samples of that level's solution.
    pub samples: u64,
    /// Texture size (texture methods only).
    pub texture: Option<TextureLevel>,
    /// Median warm frame time, ms: the median over processes (or repeats) of each one's median.
    pub frame_ms: f64,
    /// Confidence interval of that median, ms ([`timing::median_interval`]; its coverage is the
    /// report's [`Timing::coverage`]).
    pub frame_ms_interval: [f64; 2],
    /// Triangles the method draws: the mesh's, or the original polygons' (2 per quad).
    pub triangles: u64,
    /// Vertices of those triangles: the mesh's distinct vertices, or the original polygons'
    /// corners, each polygon's own (they carry its texture coordinates or patch).
    pub vertices: u64,
    /// Bytes the method stores ([`memory::Memory::method_bytes`]: the RRPs' trees and samples,
    /// 12-bit textures with mip chains, the mesh's vertices and indices).
    pub bytes: u64,
    /// Bytes the method holds in memory while it draws ([`memory::working_bytes`]: with the
    /// direct method's patch caches, f32 textures, the mesh's triangles as drawn).
    pub working_bytes: u64,
    /// Perceptual distance to the same solution's exact image.
    pub error_reconstruction: f64,
    /// Perceptual distance to the converged solution's exact image.
    pub error_total: f64,
    /// Every measure against the same solution's exact image.
    pub reconstruction: Errors,
    /// Every measure against the converged solution's exact image.
    pub total: Errors,
    /// Perceptual distance to the truth image, its noise taken out (with a truth image).
    pub error_physics: Option<f64>,
    /// Perceptual distance and RMSE against the truth image (with a truth image).
    pub physics: Option<PhysicsErrors>,
    /// The luminance error split by where it lies ([`metric::regions`]).
    pub regions: RegionSplit,
    /// On the Pareto front of total error against frame time.
    pub pareto_time: bool,
    /// On the Pareto front of total error against bytes.
    pub pareto_memory: bool,
}

/// A point's luminance error split by region ([`metric::regions`]: the emitters, a band
/// around them, near the sharp edges, the interior; the regions of the sweep's converged exact
/// image, the same pixels for every point).
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct RegionSplit {
    /// Against the same solution's exact image: the method's own error.
    pub reconstruction: [RegionError; REGIONS],
    /// Against the truth, its noise taken out per region (with a truth image).
    pub physics: Option<[RegionError; REGIONS]>,
}

/// One solution of a sweep: its tolerance, maximum depth and sample count.
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct SolutionLevel {
    /// The solver's subdivision tolerance.
    pub tolerance: f64,
    /// The quadtrees' maximum depth.
    pub max_depth: u32,
    /// Radiosity samples.
    pub samples: u64,
    /// Its exact image against the truth image: the solution error (with a truth image).
    pub solution: Option<PhysicsErrors>,
    /// The solution error split by region, the truth's noise taken out per region (with a
    /// truth image).
    pub solution_regions: Option<[RegionError; REGIONS]>,
    /// Its exact image against the converged solution's (perceptual distance): how far the
    /// solver is from its own convergence, the reconstruction left out (`None` for the
    /// converged solution itself).
    pub converged: Option<f64>,
}

impl SolutionLevel {
    pub(super) fn of(
        p: &Prepared,
        exact: &LinearImage,
        (truth, regions): (Option<&TruthReference>, &Regions),
        converged: Option<&LinearImage>,
        ppd: f64,
    ) -> Result<SolutionLevel> {
        Ok(SolutionLevel {
            solution_regions: truth.map(|t| t.region_errors(exact, regions)).transpose()?,
            converged: converged
                .map(|c| compare(exact, c, ppd).map(|d| d.perceptual_distance))
                .transpose()?,
            tolerance: p.scene.radiosity.tolerance,
            max_depth: p.scene.radiosity.max_depth,
            samples: p.solution.stats.vertices,
            solution: truth.map(|t| t.errors(exact, ppd)).transpose()?,
        })
    }
}

/// The scene's own density solved again with the next solver seed: what the seed changes. The
/// solver's only random numbers pick shadow rays, cast where an exact visibility query does not
/// apply; a solve with none gives the same bits at any seed.
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct SeedCheck {
    /// The scene's seed and the one it was solved again with.
    pub seeds: [u64; 2],
    /// Shadow rays the second solve cast.
    pub rays: u64,
    /// Whether the two solutions' exact images are the same bits.
    pub same_image: bool,
    /// The perceptual distance between the two exact images.
    pub distance: f64,
    /// The second solution's exact image against the truth (with a truth image).
    pub solution: Option<PhysicsErrors>,
}

/// A sweep's result.
#[derive(Debug, Clone, Serialize)]
pub struct SweepReport {
    /// The scene file swept.
    pub scene: String,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Worker threads.
    pub threads: usize,
    /// The levels the RRPs follow the spots' light edges to (0: the spots' light drawn from
    /// the samples by every method; [`SweepRequest::sharp_levels`]).
    pub sharp_levels: u32,
    /// Each density level's solution, coarse to fine.
    pub densities: Vec<SolutionLevel>,
    /// The converged reference solution.
    pub reference: SolutionLevel,
    /// The truth image's samples and noise (with a truth image).
    pub truth: Option<TruthNoise>,
    /// The own density solved with another seed (with a truth image).
    pub solver_seed: Option<SeedCheck>,
    /// The points, density-major, then method, then texture size.
    pub points: Vec<SweepPoint>,
    /// The equal-error memory comparison (with texture methods and the search asked for).
    pub equal_error: Option<EqualError>,
    /// How the frame times were measured.
    pub timing: Timing,
    /// The scene's own density level (the factor nearest 1: the equal-error search's).
    pub own_density: usize,
    /// The equal-error curves of the texture methods across views and image sizes, at the
    /// scene's own density ([`crate::equal_views`]; with the equal-error search).
    pub equal_views: Vec<ViewCurve>,
}

/// How a sweep's frame times were measured.
#[derive(Debug, Clone, Serialize)]
pub struct Timing {
    /// Separate processes per point (0: the repeats of the sweep's own process).
    pub processes: u32,
    /// Frame-time samples per point: one per process, or one per repeat.
    pub samples: u32,
    /// Coverage of every point's interval (the same for every point: it depends on the count).
    pub coverage: f64,
    /// The machine's load while each process ran (none for repeats in one process).
    pub load: Vec<LoadSample>,
}

impl SweepReport {
    /// The methods of the points, in the order they first appear.
    pub fn methods(&self) -> Vec<&str> {
        let mut methods: Vec<&str> = Vec::new();
        for p in &self.points {
            if !methods.contains(&p.method.as_str()) {
                methods.push(&p.method);
            }
        }
        methods
    }
}

impl Timing {
    /// Processes that ran while other work took more than [`timing::HIGH_LOAD_CORES`].
    pub fn high_load(&self) -> usize {
        timing::high_load(&self.load)
    }

    /// The largest other-work load seen, in cores (`None` when none was recorded).
    pub fn peak_load(&self) -> Option<f64> {
        timing::peak_load(&self.load)
    }
}

/// The points as CSV, one row per point, with a header.
pub fn csv(report: &SweepReport) -> String {
    let mut s = String::from(
        "method,density,tolerance,samples,texture_halvings,texture_placement,texture_texels,frame_ms,frame_ms_lo,\
         frame_ms_hi,bytes,working_bytes,error_reconstruction,error_total,rmse_reconstruction,\
         rmse_total,max_abs_reconstruction,max_abs_total,mach_band_reconstruction,mach_band_total,\
         pareto_time,pareto_memory,error_physics,rmse_physics,error_solution,rmse_solution\n",
    );
    let opt = |v: Option<f64>| v.map(|v| v.to_string()).unwrap_or_default();
    for p in &report.points {
        let solution = report.densities.get(p.density).and_then(|d| d.solution);
        let (h, pl, t) = match p.texture {
            Some(l) => (l.halvings.to_string(), l.placement, l.texels.to_string()),
            None => (String::new(), "", String::new()),
        };
        s += &format!(
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}\n",
            p.method,
            p.density,
            p.tolerance,
            p.samples,
            h,
            pl,
            t,
            p.frame_ms,
            p.frame_ms_interval[0],
            p.frame_ms_interval[1],
            p.bytes,
            p.working_bytes,
            p.error_reconstruction,
            p.error_total,
            p.reconstruction.rmse,
            p.total.rmse,
            p.reconstruction.max_abs,
            p.total.max_abs,
            p.reconstruction.mach_band,
            p.total.mach_band,
            p.pareto_time,
            p.pareto_memory,
            opt(p.error_physics),
            opt(p.physics.map(|e| e.rmse)),
            opt(solution.map(|e| e.perceptual)),
            opt(solution.map(|e| e.rmse)),
        );
    }
    s
}

/// The truth image's line of the table's header: its samples, noise and each solution's
/// error against it; empty without a truth image.
fn truth_line(report: &SweepReport) -> String {
    let Some(t) = &report.truth else {
        return String::new();
    };
    let per_level: Vec<String> = report
        .densities
        .iter()
        .chain([&report.reference])
        .map(|d| d.solution.map_or("-".into(), |e| e.perceptual_text(4)))
        .collect();
    format!(
        "truth: {} samples per pixel, noise {:.4} (perceptual), {:.3e} (rmse); \
         solution error per density, then the converged reference (≤: within the truth's \
         noise, measured distance shown): {}\n",
        t.samples_per_pixel,
        t.perceptual,
        t.rmse,
        per_level.join(", ")
    )
}

/// The points as a fixed-width table.
pub fn table(report: &SweepReport) -> String {
    let mut s = format!(
        "{}: {} x {}, {} threads, sharp levels {}; reference: tolerance {}, max depth {}, {} \
         samples\n\
         {}\
         method            dens  samples  texture   frame_ms       bytes  err_recon  err_total   err_phys  front\n",
        report.scene,
        report.width,
        report.height,
        report.threads,
        report.sharp_levels,
        report.reference.tolerance,
        report.reference.max_depth,
        report.reference.samples,
        truth_line(report),
    );
    for p in &report.points {
        let tex = p
            .texture
            .map(|l| format!("/{} {}", 1u64 << l.halvings, &l.placement[..3]))
            .unwrap_or_default();
        let front = match (p.pareto_time, p.pareto_memory) {
            (true, true) => "time+mem",
            (true, false) => "time",
            (false, true) => "mem",
            (false, false) => "",
        };
        s += &format!(
            "{:<17} {:>4} {:>8} {:>8} {:>10.3} {:>11} {:>10.4} {:>10.4} {:>10}  {}\n",
            p.method,
            p.density,
            p.samples,
            tex,
            p.frame_ms,
            p.bytes,
            p.error_reconstruction,
            p.error_total,
            p.physics
                .map_or_else(|| "-".into(), |e| e.perceptual_text(4)),
            front
        );
    }
    if let Some(e) = &report.equal_error {
        s += "\n";
        s += &equal_error::table(e);
    }
    s
}
