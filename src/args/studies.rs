//! The options of the subcommands that measure or make inputs: `experiment`, `sweep`,
//! `results`, `truth`, `compare` and `generate` (see the parent module).

use super::*;

#[derive(Args, Debug)]
pub(crate) struct ExperimentArgs {
    /// `fig5`, `fig6`, `table1` or `all`.
    pub which: String,
    /// Directory for the images (default: `out/experiments`).
    #[arg(long, default_value = "out/experiments")]
    pub out_dir: PathBuf,
    /// With `all`: write the Markdown report to this file (`docs/experiments.md`); image
    /// links are relative to its directory.
    #[arg(long)]
    pub doc: Option<PathBuf>,
    /// The texture-space scene of fig5 and fig6 (default: the one fitted to the paper's
    /// distances; `scenes/two-spots.toml` and `scenes/two-spots-narrow.toml` are variants).
    #[arg(long, default_value = "scenes/two-spots-paper.toml")]
    pub scene: PathBuf,
    /// Image side of fig5 and fig6.
    #[arg(long, default_value_t = 256)]
    pub size: u32,
    /// Pixels per degree of the perceptual metric.
    #[arg(long, default_value_t = metric::DEFAULT_PPD)]
    pub ppd: f64,
    /// fig5, fig6: the RRPs' derivative estimator, `hyman` (default), `monotone` or
    /// `plain` (central differences).
    #[arg(long, default_value = "hyman")]
    pub estimator: String,
    /// table1: the scenes (default: the three shipped scenes).
    #[arg(long, value_delimiter = ',')]
    pub scenes: Vec<PathBuf>,
    /// table1: frames timed per method at 1024 x 1024 (0 = sizes only).
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u32).range(0..=MAX_TIMED_FRAMES))]
    pub frames: u32,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// JSON instead of the table: to FILE, or to standard output when no FILE (or `-`) is
    /// given (the same `--json [FILE]` in every command).
    #[arg(long, value_name = "FILE", num_args = 0..=1, default_missing_value = "-")]
    pub json: Option<PathBuf>,
}

#[derive(Args, Debug)]
pub(crate) struct SweepArgs {
    /// A scene file or a solution file (its scene is solved again at every density).
    pub input: PathBuf,
    /// Methods, comma-separated (default: direct and every texture method, and mesh).
    #[arg(long, value_delimiter = ',', default_values_t = study::sweep::DEFAULT_METHODS.map(String::from))]
    pub methods: Vec<String>,
    /// Image size, `WxH`.
    #[arg(long, default_value = "256x256", value_parser = parse_size)]
    pub size: (u32, u32),
    /// Density levels as factors f of the scene's solver tolerance, coarse to fine; each also
    /// moves radiosity.max_depth by -round(log2 f) levels (and, for f > 1, min_depth likewise,
    /// down to 0).
    #[arg(long, value_delimiter = ',', default_values_t = study::sweep::DEFAULT_DENSITIES)]
    pub densities: Vec<f64>,
    /// Tolerance factor of the converged reference solution (its depth limit moved likewise:
    /// two levels deeper at 1/4).
    #[arg(long, default_value_t = 0.25)]
    pub reference_density: f64,
    /// Texture sizes per density: the quadtree-depth sizes halved 0 .. N-1 times.
    #[arg(long, default_value_t = 4)]
    pub texture_levels: u32,
    /// Frames timed per point and repeat (after a warm-up).
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(0..=MAX_TIMED_FRAMES))]
    pub frames: u32,
    /// Timing repeats within each timing process.
    #[arg(long, default_value_t = 1)]
    pub repeats: u32,
    /// Separate processes each point is timed in (its time: the median over them, with a 95 %
    /// confidence interval from 6 on); 0: the repeats of this process alone.
    #[arg(long, default_value_t = study::timing::DEFAULT_PROCESSES, value_parser = clap::value_parser!(u32).range(0..=MAX_TIMING_PROCESSES))]
    pub processes: u32,
    /// Pixels per degree of the perceptual metric.
    #[arg(long, default_value_t = metric::DEFAULT_PPD)]
    pub ppd: f64,
    /// Every point as JSON: to FILE, or to standard output instead of the table when no FILE
    /// (or `-`) is given.
    #[arg(long, value_name = "FILE", num_args = 0..=1, default_missing_value = "-")]
    pub json: Option<PathBuf>,
    /// Write every point as CSV to this file.
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// Write the plots (error against frame time and against memory, PNG and SVG) into this
    /// directory.
    #[arg(long)]
    pub plots: Option<PathBuf>,
    /// Skip the equal-error memory search.
    #[arg(long)]
    pub no_equal_error: bool,
    /// Samples per pixel of the path-traced truth image the error budget is measured against
    /// (physics error, solution error, the truth's noise); 0: no truth image.
    #[arg(long, default_value_t = study::sweep::DEFAULT_TRUTH_SAMPLES)]
    pub truth_samples: u32,
    /// How many levels below the solver's leaves every method (the RRPs, the textures
    /// resampled from them, the mesh's vertices) follows the edges of the spot lights' light:
    /// 3 by default; 0 draws the spots' light from the solver's samples for every method
    /// (docs/sweep.md).
    #[arg(long, value_name = "N")]
    pub sharp_levels: Option<u32>,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// No progress bar.
    #[arg(short, long)]
    pub quiet: bool,
    /// Print the solver's trace lines.
    #[arg(long)]
    pub trace: bool,
}

#[derive(Args, Debug)]
pub(crate) struct ResultsArgs {
    /// The Markdown page to write (no default: in a checkout, `docs/results.md` is the committed
    /// page, replaced only when asked for by name).
    #[arg(long)]
    pub doc: PathBuf,
    /// Scene files, comma-separated (default: two-spots, cornell-box, gallery, studio,
    /// accuracy/furnished-room, accuracy/building-2x1).
    #[arg(long, value_delimiter = ',')]
    pub scenes: Vec<PathBuf>,
    /// Side of the sweeps' square images.
    #[arg(long, default_value_t = 256)]
    pub size: u32,
    /// Width of the gallery's images.
    #[arg(long, default_value_t = 192)]
    pub gallery_width: u32,
    /// Frames timed per sweep point and repeat.
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(0..=MAX_TIMED_FRAMES))]
    pub frames: u32,
    /// Sweep timing repeats within each timing process.
    #[arg(long, default_value_t = 1)]
    pub repeats: u32,
    /// Separate processes each sweep point is timed in (the median over them, with a 95 %
    /// confidence interval from 6 on); 0: the repeats of this process alone.
    #[arg(long, default_value_t = study::timing::DEFAULT_PROCESSES, value_parser = clap::value_parser!(u32).range(0..=MAX_TIMING_PROCESSES))]
    pub processes: u32,
    /// Samples per pixel of each sweep's path-traced truth image (the error budget); 0: none.
    #[arg(long, default_value_t = study::sweep::DEFAULT_TRUTH_SAMPLES)]
    pub truth_samples: u32,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// No progress bar.
    #[arg(short, long)]
    pub quiet: bool,
    /// Print the solver's trace lines.
    #[arg(long)]
    pub trace: bool,
}

#[derive(Args, Debug)]
pub(crate) struct TruthArgs {
    /// A scene file (`.toml`), or a solution file (its scene is traced).
    pub input: PathBuf,
    #[command(flatten)]
    pub options: SceneOptions,
    /// OpenEXR of the mean radiosity per pixel; the standard errors go to `<stem>.stderr.exr`
    /// beside it.
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// JSON of every polygon's estimates (mean B, direct, indirect, standard errors, object,
    /// material, area): to FILE (and printed as a table), or to standard output instead of the
    /// table when no FILE (or `-`) is given.
    #[arg(long, value_name = "FILE", num_args = 0..=1, default_missing_value = "-")]
    pub json: Option<PathBuf>,
    /// OpenEXR mask of the pixels within 2 of a shadow boundary (1, else 0), for `compare
    /// --mask`: where, at a pixel's centre, the share of the direct light that arrives unblocked
    /// changes between lit, penumbra and umbra on one face (docs/truth.md).
    #[arg(long, value_name = "FILE")]
    pub shadow_mask: Option<PathBuf>,
    /// Camera samples per pixel, at most (default 64).
    #[arg(long)]
    pub spp: Option<u32>,
    /// Image width (default: the scene's).
    #[arg(long)]
    pub width: Option<u32>,
    /// Image height (default: the scene's).
    #[arg(long)]
    pub height: Option<u32>,
    /// Sample the renderer's `--aa` positions (1, 4 or 16) instead of the whole pixel box.
    #[arg(long)]
    pub aa: Option<u32>,
    /// Seed of the random streams.
    #[arg(long)]
    pub seed: Option<u64>,
    /// Samples per polygon, at most (default 4096).
    #[arg(long, value_name = "N")]
    pub polygon_samples: Option<u64>,
    /// Strata per side of each polygon's (u, v) grid (default 4: 16 cells).
    #[arg(long)]
    pub strata: Option<u32>,
    /// Stop once the relative standard error is at most this: every polygon's (against its
    /// luminance), and the image's root-mean-square over the pixels (against its mean).
    #[arg(long, value_name = "X")]
    pub max_error: Option<f64>,
    /// Most reflections a path follows (default: no limit; Russian roulette ends paths).
    #[arg(long)]
    pub max_bounces: Option<u32>,
    /// Also solve the scene (or read the solution file given as input) and report each
    /// polygon's solver mean beside the truth: ratio and distance in standard errors (JSON
    /// `solver`, `solver_ratio`, `solver_z`; a column of the table). Needs --json.
    #[arg(long)]
    pub compare_solver: bool,
    /// Worker threads (default: all cores). The results are identical for any count.
    #[arg(long)]
    pub threads: Option<usize>,
    /// No progress bar, no "wrote" lines, no table.
    #[arg(short, long)]
    pub quiet: bool,
    /// Print a line per pass (samples so far, error reached).
    #[arg(long)]
    pub trace: bool,
}

#[derive(Args, Debug)]
pub(crate) struct CompareArgs {
    /// The image under test.
    pub a: PathBuf,
    /// The reference image.
    pub b: PathBuf,
    /// Pixels per degree of visual angle (viewing distance) for the contrast sensitivity.
    #[arg(long, default_value_t = metric::DEFAULT_PPD)]
    pub ppd: f64,
    /// The visual angle the image's width spans, in degrees, instead of --ppd (ppd = width /
    /// DEG): every resolution of one picture is then seen alike, for thresholds that hold at
    /// any image size.
    #[arg(long, value_name = "DEG", conflicts_with = "ppd")]
    pub view_degrees: Option<f64>,
    /// JSON instead of the table: to FILE, or to standard output when no FILE (or `-`) is
    /// given (the same `--json [FILE]` in every command).
    #[arg(long, value_name = "FILE", num_args = 0..=1, default_missing_value = "-")]
    pub json: Option<PathBuf>,
    /// Regression check: compare pixel by pixel; a pixel differs when a channel moves by more
    /// than this times max(|reference|, --floor) (`default` = 2^-19, 16 f32 rounding steps).
    /// Lists the first differing pixels; exit 1 if more than --fail-percent of them differ.
    #[arg(long, value_name = "REL|default", value_parser = parse_tolerance)]
    pub tolerance: Option<f32>,
    /// With --tolerance: fail (exit 1) only when more than P % of the pixels differ (0, the
    /// default: any differing pixel fails).
    #[arg(long, value_name = "P", default_value_t = 0.0, requires = "tolerance")]
    pub fail_percent: f64,
    /// With --tolerance: the reference level under which the tolerance is absolute.
    #[arg(long, default_value_t = metric::pixels::DEFAULT_FLOOR)]
    pub floor: f32,
    /// With --tolerance: write the difference image here (PNG scaled so the largest
    /// difference is white, or EXR with the raw |a - b|).
    #[arg(long, value_name = "PATH", requires = "tolerance")]
    pub diff: Option<PathBuf>,
    /// Fail (exit 1) when the perceptual distance is above this (an L2 norm over the pixels:
    /// it grows with the image size; see --max-distance-per-pixel).
    #[arg(long, value_name = "D")]
    pub max_distance: Option<f64>,
    /// Fail (exit 1) when the perceptual distance per pixel (distance / sqrt(width x height))
    /// is above this; with --view-degrees the same for any image size.
    #[arg(long, value_name = "D")]
    pub max_distance_per_pixel: Option<f64>,
    /// Compare a PNG (sRGB, after the render's exposure) with a linear float image (EXR, HDR,
    /// PFM) by decoding the PNG to linear; without it such a pair is refused.
    #[arg(long)]
    pub convert: bool,
    /// Also split the luminance error at a mask image of the same size (pixels above one half
    /// are in it), e.g. `truth --shadow-mask`: RMSE inside and outside and their ratio.
    #[arg(long, value_name = "FILE")]
    pub mask: Option<PathBuf>,
    /// With --mask: a second, independent estimate of the reference (`truth` at another
    /// `--seed`); the split is then also given free of the references' noise, from the product
    /// of the two differences (docs/metrics.md).
    #[arg(long, value_name = "FILE")]
    pub second_reference: Option<PathBuf>,
}

/// The scenes `generate` makes.
#[derive(Subcommand, Debug)]
pub(crate) enum Generate {
    /// A building: a grid of closed rooms on one or more storeys, doorways between all
    /// neighbours on a storey, one or two emissive ceiling panels and up to four boxes or
    /// pillars per room.
    ///
    /// Writes `<name>.toml` and `<name>/<name>.obj` and `.mtl` beside it (atomically, all three
    /// together) and prints the polygon count: cut^2 (14 rooms + 12 doorways) + rooms (lights +
    /// 5 furniture). The same options give the same bytes. Exit code 2 for a bad option or over
    /// 1,000,000 polygons.
    Building(BuildingArgs),
}

#[derive(Args, Debug)]
pub(crate) struct BuildingArgs {
    /// Rooms along x on each storey.
    #[arg(long, value_name = "N")]
    pub rooms_x: u32,
    /// Rooms along z on each storey.
    #[arg(long, value_name = "M")]
    pub rooms_z: u32,
    /// Storeys (not connected to each other).
    #[arg(long, value_name = "F", default_value_t = generate::DEFAULT_FLOORS)]
    pub floors: u32,
    /// Cut every wall, floor, ceiling and doorway cell into K x K quads.
    #[arg(long, value_name = "K", default_value_t = generate::DEFAULT_CUT)]
    pub cut: u32,
    /// Emissive ceiling panels per room, 1 or 2.
    #[arg(long, default_value_t = generate::DEFAULT_LIGHTS)]
    pub lights: u32,
    /// Boxes or pillars per room, 0 to 4.
    #[arg(long, default_value_t = generate::DEFAULT_FURNITURE)]
    pub furniture: u32,
    /// Seed of the furniture's sizes and places.
    #[arg(long, default_value_t = generate::DEFAULT_SEED)]
    pub seed: u64,
    /// The scene file to write (`scenes/building.toml`), or a directory (the scene is then
    /// `<dir>/building.toml`).
    #[arg(short, long)]
    pub output: PathBuf,
}
