//! The options of the subcommands that work on one scene and its frames: `check`, `solve`,
//! `render`, `stats`, `bench`, `view` and `export` (see the parent module).

use super::*;

#[derive(Args, Debug)]
pub(crate) struct ExportArgs {
    /// A scene file or a solution file (a scene is solved first).
    pub input: PathBuf,
    #[command(flatten)]
    pub options: SceneOptions,
    /// The glTF to write: `.glb` or `.gltf`.
    #[arg(short, long)]
    pub output: PathBuf,
    /// The adaptive mesh with Gouraud vertex colours (COLOR_0) instead of the lightmap.
    #[arg(long)]
    pub mesh: bool,
    /// Largest atlas page side, a power of two from 64 to 16384; charts that do not fit one
    /// page go to more.
    #[arg(long, default_value_t = app::commands::export::DEFAULT_PAGE)]
    pub page_size: u32,
    /// Exposure in stops of the PNG pages and vertex colours (default: the scene's
    /// `[display] exposure`).
    #[arg(long, allow_hyphen_values = true)]
    pub exposure: Option<f64>,
    /// The scene of a solution file, when it is no longer where the file says.
    #[arg(long)]
    pub scene: Option<PathBuf>,
    #[command(flatten)]
    pub texture: TextureArgs,
    /// Worker threads (default: all cores). The files are identical for any count.
    #[arg(long)]
    pub threads: Option<usize>,
    /// JSON instead of the table: to FILE, or to standard output when no FILE (or `-`) is
    /// given (the same `--json [FILE]` in every command).
    #[arg(long, value_name = "FILE", num_args = 0..=1, default_missing_value = "-")]
    pub json: Option<PathBuf>,
}

#[derive(Args, Debug)]
pub(crate) struct ViewArgs {
    /// A scene file or a solution file (a scene is solved first).
    pub input: PathBuf,
    #[command(flatten)]
    pub options: SceneOptions,
    /// Window width.
    #[arg(long, default_value_t = 1280)]
    pub width: u32,
    /// Window height.
    #[arg(long, default_value_t = 720)]
    pub height: u32,
    /// Virtual renderers at the start.
    #[arg(long, default_value_t = 1)]
    pub renderers: u32,
    /// Region side at the start, pixels.
    #[arg(long, default_value_t = 128)]
    pub region: u32,
    /// The scene of a solution file, when it is no longer where the file says.
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// No window: replay this recorded session (`press ACTION`, `hold ACTION[,ACTION] SECONDS`,
    /// `wait SECONDS` per line; docs/viewer.md) at 60 steps a second, then draw one frame.
    #[arg(long, requires = "screenshot")]
    pub script: Option<PathBuf>,
    /// With `--script`: the PNG of the last frame (as `render` would write it).
    #[arg(long, requires = "script")]
    pub screenshot: Option<PathBuf>,
    /// With `--script`: frames drawn after the session, each as the window would show it
    /// (frame, sRGB, status line), timed; prints their median.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=10000))]
    pub frames: u32,
    #[command(flatten)]
    pub texture: TextureArgs,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
}

#[derive(Args, Debug)]
pub(crate) struct CheckArgs {
    /// The scene file (`scenes/cornell-box.toml`), a model (`room.obj`: a camera, material
    /// and light are chosen for it), or a solution file (`.pfsol`): then also where its solve's
    /// guards stopped refinement with the error test still failing.
    pub scene: PathBuf,
    #[command(flatten)]
    pub options: SceneOptions,
}

#[derive(Args, Debug)]
pub(crate) struct SolveArgs {
    /// The scene file, or a model (`room.obj`).
    pub scene: PathBuf,
    #[command(flatten)]
    pub options: SceneOptions,
    /// Where to write the solution (written atomically).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Worker threads (default: all cores). The solution is identical for any count.
    #[arg(long)]
    pub threads: Option<usize>,
    /// No progress bar.
    #[arg(short, long)]
    pub quiet: bool,
    /// Print the solver's trace lines (phase times, shots, vertices, unshot) to stderr.
    #[arg(long)]
    pub trace: bool,
}

#[derive(Args, Debug)]
pub(crate) struct RenderArgs {
    /// A scene file (`.toml`), a model (`room.obj`, with its MTL: a camera framing it, a grey
    /// default material and, if nothing emits, a default light are chosen and said), or a
    /// solution file written by `solve`.
    pub input: PathBuf,
    /// The image to write; the format follows the name: `.png` (8-bit sRGB after the exposure),
    /// `.exr`, `.hdr` or `.pfm` (linear radiosity) (default: `out/<scene>-<method>.png`,
    /// followed by every option given that changes the method's pixels, e.g. `-640x480-aa4-t64`).
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    #[command(flatten)]
    pub options: SceneOptions,
    /// Exposure of the PNG in stops: radiosity times 2^N before sRGB (default: the scene's
    /// `[display] exposure`).
    #[arg(
        long,
        value_name = "N",
        allow_hyphen_values = true,
        conflicts_with = "auto_exposure"
    )]
    pub exposure: Option<f64>,
    /// Choose the exposure that maps the image's log-average luminance to middle grey (0.18);
    /// a walkthrough uses its first frame's.
    #[arg(long)]
    pub auto_exposure: bool,
    /// Also write the linear radiosity of every pixel as OpenEXR, named `.exr`.
    #[arg(long)]
    pub exr: Option<PathBuf>,
    /// Rendering method: `direct` (the RRPs per pixel, the PixelFlow path), `texture-nearest`,
    /// `texture-bilinear`, `texture-bicubic` (radiosity textures), `mesh` (the Gouraud mesh) or
    /// `reference` (the solution exact per pixel) (default: the scene's `[render] method`).
    #[arg(long)]
    pub method: Option<String>,
    /// Image width (default: the scene's).
    #[arg(long)]
    pub width: Option<u32>,
    /// Image height (default: the scene's).
    #[arg(long)]
    pub height: Option<u32>,
    /// Samples per pixel: 1, 4 or 16 (default: the scene's `[render] aa`).
    #[arg(long)]
    pub aa: Option<u32>,
    /// Worker threads (default: all cores). The image is identical for any count.
    #[arg(long)]
    pub threads: Option<usize>,
    /// Virtual PixelFlow renderers merged by image composition. The image is identical for
    /// any count.
    #[arg(long, default_value_t = 1)]
    pub renderers: u32,
    /// Side of the screen regions in pixels (a multiple of 8).
    #[arg(long, default_value_t = 128)]
    pub region: u32,
    /// Write the frame statistics as JSON to this file (for a walkthrough: the summary and
    /// every frame).
    #[arg(long)]
    pub stats: Option<PathBuf>,
    /// Render every frame of the scene's `[camera_path]` (files `<output stem>-NNNN.png`; without
    /// `-o`, in their own folder `out/<scene>-<method>/`) and print a frame-rate summary (fps
    /// min / median / max, median stage times).
    #[arg(long)]
    pub walkthrough: bool,
    /// The scene of a solution file, when it is no longer where the file says.
    #[arg(long)]
    pub scene: Option<PathBuf>,
    #[command(flatten)]
    pub texture: TextureArgs,
    /// The RRPs' derivative estimator: `hyman` (default: Hyman-filtered central
    /// differences), `monotone` (Fritsch-Butland) or `plain` (central differences).
    #[arg(long)]
    pub estimator: Option<String>,
    /// How many levels below the solver's leaves the RRPs and the mesh's vertices follow the
    /// edges of the spot lights' light (cone rims, hard shadows): 3 by default, 0 to
    /// reconstruct it from the samples like any other light (docs/seams.md).
    #[arg(long, value_name = "N")]
    pub sharp_levels: Option<u32>,
    /// Print the statistics.
    #[arg(short, long)]
    pub verbose: bool,
    /// No progress bar, no "wrote" lines, no walkthrough summary.
    #[arg(short, long)]
    pub quiet: bool,
    /// Print the solver's trace lines (phase times, shots, vertices, unshot) to stderr.
    #[arg(long)]
    pub trace: bool,
}

#[derive(Args, Debug)]
pub(crate) struct StatsArgs {
    /// A scene file or a solution file.
    pub input: PathBuf,
    #[command(flatten)]
    pub options: SceneOptions,
    /// The scene of a solution file, when it is no longer where the file says.
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// Frames timed per method (after one warm-up); 0 = sizes only.
    #[arg(long, default_value_t = 0, value_parser = clap::value_parser!(u32).range(0..=MAX_TIMED_FRAMES))]
    pub frames: u32,
    /// Frame width for the timings.
    #[arg(long, default_value_t = 1024)]
    pub width: u32,
    /// Frame height for the timings.
    #[arg(long, default_value_t = 1024)]
    pub height: u32,
    /// Samples per pixel: 1, 4 or 16.
    #[arg(long, default_value_t = 1)]
    pub aa: u32,
    #[command(flatten)]
    pub texture: TextureArgs,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// JSON instead of the table: to FILE, or to standard output when no FILE (or `-`) is
    /// given (the same `--json [FILE]` in every command).
    #[arg(long, value_name = "FILE", num_args = 0..=1, default_missing_value = "-")]
    pub json: Option<PathBuf>,
    /// When solving a scene, print the solver's trace lines (phase times, shots, vertices, unshot) to stderr.
    #[arg(long)]
    pub trace: bool,
}

#[derive(Args, Debug)]
pub(crate) struct BenchArgs {
    /// A scene file or a solution file.
    pub input: PathBuf,
    #[command(flatten)]
    pub options: SceneOptions,
    /// The scene of a solution file, when it is no longer where the file says.
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// Methods to measure, comma-separated (`direct`, `texture-bilinear`, ...), each at
    /// every size, interleaved per size so they see the same machine state.
    #[arg(long, value_delimiter = ',', default_values_t = [String::from("direct")])]
    pub methods: Vec<String>,
    #[command(flatten)]
    pub texture: TextureArgs,
    /// Square image sizes to measure, comma-separated.
    #[arg(long, value_delimiter = ',', default_values_t = [512u32, 1024, 2048])]
    pub sizes: Vec<u32>,
    /// Frames timed per size (after one warm-up frame).
    #[arg(long, default_value_t = 20, value_parser = clap::value_parser!(u32).range(0..=MAX_TIMED_FRAMES))]
    pub frames: u32,
    /// Samples per pixel: 1, 4 or 16.
    #[arg(long, default_value_t = 1)]
    pub aa: u32,
    /// Virtual PixelFlow renderers.
    #[arg(long, default_value_t = 1)]
    pub renderers: u32,
    /// Side of the screen regions in pixels (a multiple of 8).
    #[arg(long, default_value_t = 128)]
    pub region: u32,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// JSON instead of the table: to FILE, or to standard output when no FILE (or `-`) is
    /// given (the same `--json [FILE]` in every command).
    #[arg(long, value_name = "FILE", num_args = 0..=1, default_missing_value = "-")]
    pub json: Option<PathBuf>,
    /// When solving a scene, print the solver's trace lines (phase times, shots, vertices, unshot) to stderr.
    #[arg(long)]
    pub trace: bool,
}
