//! One function per subcommand: each turns its arguments into the library's request, runs the
//! job with the shared [`Settings`] (in a pool of `--threads` workers where it has the option)
//! and prints the result. Errors go back to `main`, which prints them and picks the exit code.

use std::path::{Path, PathBuf};

use app::budget;
use app::commands::bench::{bench_table, run_bench, BenchRequest};
use app::commands::render::{run_render, RenderEvent, RenderRequest};
use app::commands::solve::solve_scene_to_file;
use app::commands::stats::{run_stats, StatsRequest};
use app::commands::truth::{run_truth, TruthEvent, TruthRequest};
use base::output::Outputs;
use base::progress::Observer;
use base::Error;
use engine::frame::FrameOptions;
use study::experiment;
use study::sweep;

use crate::args::{
    BenchArgs, BuildingArgs, CheckArgs, CompareArgs, ExperimentArgs, ExportArgs, RenderArgs,
    ResultsArgs, SolveArgs, StatsArgs, SweepArgs, TimeWorkerArgs, TruthArgs,
};
use crate::terminal::Terminal;
use crate::{json, note, out};

/// The environment variable that caps the lane build.
const LANES_ENV: &str = "PIXELFLOW_SIM_LANES";

/// Most worker threads `--threads` accepts: far above any machine this runs on, far below what
/// would exhaust the process's thread and stack limits.
const MAX_THREADS: usize = 1024;

/// What every job runs with: the memory limit and the instruction set of the frames' kernels.
pub(crate) struct Settings {
    limit: u64,
    isa: lanes::Isa,
    outputs: Outputs,
}

impl Settings {
    /// The limit of `--memory-limit` (default: [`budget::default_limit`]) and the widest
    /// instruction set of this CPU, capped by [`LANES_ENV`]; every file is written through
    /// `outputs`.
    pub(crate) fn new(memory_limit: Option<u64>, outputs: Outputs) -> anyhow::Result<Settings> {
        let limit = memory_limit.unwrap_or_else(budget::default_limit);
        Ok(Settings {
            limit,
            isa: isa_from_env()?,
            outputs,
        })
    }

    /// The largest input file read: an input file is held at least once as bytes and once
    /// parsed, so half of what the program's own memory leaves each.
    pub(crate) fn input_limit(&self) -> u64 {
        base::output::input_limit_for(budget::data_limit(self.limit))
    }

    /// The library's scene load options: `options` (`-D`, `--camera`, `--strict`) with this
    /// run's input cap.
    pub(crate) fn load_options(&self, options: &crate::args::SceneOptions) -> scene::LoadOptions {
        scene::LoadOptions {
            input_limit: self.input_limit(),
            ..options.load_options()
        }
    }

    /// The instruction set frames run with.
    pub(crate) fn isa(&self) -> lanes::Isa {
        self.isa
    }

    /// A job context reporting progress to `observer`.
    pub(crate) fn context<'a>(&self, observer: &'a dyn Observer) -> app::context::Context<'a> {
        app::context::Context::new(observer)
            .with_memory_limit(self.limit)
            .with_isa(self.isa)
            .with_outputs(self.outputs.clone())
    }
}

/// The detected instruction set, capped by [`LANES_ENV`] (portable, avx2, avx512, auto) to time
/// the builds against each other; the images are the same. A cap this CPU cannot run prints one
/// warning naming what was asked and what runs instead (a timing run must not measure another
/// build unawares); an unknown value is an error.
fn isa_from_env() -> anyhow::Result<lanes::Isa> {
    let isa = lanes::Isa::detect();
    let Some(v) = std::env::var_os(LANES_ENV) else {
        return Ok(isa);
    };
    let v = v.to_string_lossy();
    let cap = lanes::Level::parse_cap(&v).map_err(|reason| Error::InvalidOption {
        option: LANES_ENV.to_string(),
        value: v.to_string(),
        reason,
    })?;
    let Some(cap) = cap else {
        return Ok(isa);
    };
    let (isa, warning) = isa.capped_or_warn(cap);
    if let Some(w) = warning {
        note(&format!("warning: {LANES_ENV}={v}: {w}"));
    }
    Ok(isa)
}

/// Runs `f` in a rayon pool of `threads` workers (all cores when `None`).
pub(crate) fn in_pool<T: Send>(
    threads: Option<usize>,
    f: impl FnOnce() -> T + Send,
) -> anyhow::Result<T> {
    match threads {
        None => Ok(f()),
        Some(0) => Err(Error::invalid_option("--threads", "0", "needs at least one thread").into()),
        Some(n) if n > MAX_THREADS => Err(Error::invalid_option(
            "--threads",
            n.to_string(),
            format!("at most {MAX_THREADS} worker threads"),
        )
        .into()),
        Some(n) => {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(n)
                .build()
                .map_err(|e| Error::Runtime(format!("cannot start {n} threads: {e}")))?;
            Ok(pool.install(f))
        }
    }
}

/// A command's `--json [FILE]`: the document on standard output for `-`, else written to FILE
/// (atomically, never over an input: checked by [`check_json_path`] before the work).
fn emit_json<T: serde::Serialize>(
    settings: &Settings,
    path: &Path,
    value: &T,
) -> anyhow::Result<()> {
    let text = json(value)?;
    if path == Path::new("-") {
        return out(&text);
    }
    settings.outputs.write_atomic(path, text.as_bytes())?;
    wrote(path, false);
    Ok(())
}

/// Refuses a `--json FILE` that would replace one of `inputs` (or is not a writable regular
/// file), before any work.
fn check_json_path(json: &Option<PathBuf>, inputs: &[&Path]) -> anyhow::Result<()> {
    if let Some(path) = json.as_deref().filter(|p| *p != Path::new("-")) {
        let inputs: Vec<PathBuf> = inputs.iter().map(|p| p.to_path_buf()).collect();
        base::output::check_outputs(&inputs, &[("--json", path)])?;
        app::commands::render::check_extension("--json", path, "json", "JSON")?;
    }
    Ok(())
}

/// A "wrote" line on stderr, unless `quiet`.
pub(crate) fn wrote(path: &Path, quiet: bool) {
    if !quiet {
        note(&format!("wrote {}", path.display()));
    }
}

/// `check`: the scene's warnings, summary and memory estimate against the limit.
pub(crate) fn check(settings: &Settings, args: CheckArgs) -> anyhow::Result<()> {
    let input =
        app::context::Input::load_opts(&args.scene, None, &settings.load_options(&args.options))?;
    let s = &input.scene;
    for w in &s.warnings {
        note(&format!("warning: {w}"));
    }
    for n in &s.notes {
        note(&format!("note: {n}"));
    }
    let summary = app::report::summarize(s);
    let b = budget::scene_budget(s)?;
    let text = app::report::budget_text(s, &b, settings.limit);
    out(&format!("{summary}{text}"))?;
    if let Some(g) = app::commands::stats::solution_guards(&input)? {
        match &g.warning {
            Some(w) => note(&format!("warning: {w}")),
            None => out(&format!(
                "guard stops: none with the error test failing ({} leaves only for a shadow \
                 boundary)\n",
                g.shadow_leaves
            ))?,
        }
    }
    // Over the limit: the same refusal a solve or render of this scene would give.
    b.check(settings.limit)?;
    Ok(())
}

/// `solve`: solves the scene into the solution file and reports the solver's statistics.
pub(crate) fn solve(settings: &Settings, args: SolveArgs) -> anyhow::Result<()> {
    let observer = Terminal::new(!args.quiet, args.trace);
    let opts = settings.load_options(&args.options);
    let sol = in_pool(args.threads, || {
        solve_scene_to_file(
            &settings.context(&observer),
            &args.scene,
            &args.output,
            &opts,
            &mut |line| observer.note(line),
        )
    })??;
    // The scene again, for a guard stop's file and line and the convergence the light
    // warnings compare against; loading costs little next to the solve.
    let scene = scene::load_scene_with(&args.scene, &opts)?;
    if let Some(w) = sol.stats.guard_stops.warning(&scene) {
        note(&format!("warning: {w}"));
    }
    for w in sol.stats.light_warnings(scene.radiosity.convergence) {
        note(&format!("warning: {w}"));
    }
    if !args.quiet {
        let s = &sol.stats;
        note(&format!(
            "solved {} in {:.0} ms: {} elements, {} samples ({} T-vertices), {} shots, unshot {:.3}%; wrote {}",
            args.scene.display(),
            s.solve_ms,
            s.elements,
            s.vertices,
            s.t_vertices,
            s.shots,
            100.0 * s.unshot_fraction,
            args.output.display()
        ));
    }
    Ok(())
}

/// `render`: one image or a walkthrough, with its warnings, "wrote" lines and statistics.
pub(crate) fn render(settings: &Settings, args: RenderArgs) -> anyhow::Result<()> {
    let req = RenderRequest {
        input: args.input,
        output: args.output,
        exr: args.exr,
        method: args.method,
        width: args.width,
        height: args.height,
        aa: args.aa,
        renderers: args.renderers,
        region: args.region,
        stats: args.stats,
        walkthrough: args.walkthrough,
        scene: args.scene,
        texture: args.texture.options(),
        estimator: args.estimator,
        sharp_levels: args.sharp_levels,
        load: settings.load_options(&args.options),
        exposure: args.exposure,
        auto_exposure: args.auto_exposure,
    };
    let (verbose, quiet) = (args.verbose, args.quiet);
    let observer = Terminal::new(!quiet, args.trace);
    let mut stdout_closed = false;
    let mut on_event = |event: RenderEvent| match event {
        RenderEvent::Warning(w) => observer.note(&format!("warning: {w}")),
        RenderEvent::Note(n) if !quiet => observer.note(&format!("note: {n}")),
        // Above the walkthrough's bar, not into it.
        RenderEvent::Wrote(path) if !quiet => observer.note(&format!("wrote {}", path.display())),
        RenderEvent::Frame(report) if verbose && !stdout_closed => {
            // A closed stdout stops the printing, not the render.
            stdout_closed = out(&(report.to_json() + "\n")).is_err();
        }
        RenderEvent::Walkthrough(summary) if !quiet => observer.note(&summary.line()),
        RenderEvent::Luminance(path, l) if !quiet => {
            observer.note(&format!("{}: {}", path.display(), l.line()))
        }
        _ => {}
    };
    in_pool(args.threads, || {
        run_render(&settings.context(&observer), &req, &mut on_event)
    })??;
    Ok(())
}

/// `stats`: the paper's Table 1 for one scene, as a table or JSON.
pub(crate) fn stats(settings: &Settings, args: StatsArgs) -> anyhow::Result<()> {
    check_json_path(&args.json, &[&args.input])?;
    in_pool(args.threads, || -> anyhow::Result<()> {
        let texture = args.texture.options();
        let req = StatsRequest {
            load: settings.load_options(&args.options),
            input: args.input,
            scene: args.scene,
            frames: args.frames,
            frame: FrameOptions {
                aa: base::method::Aa::new("--aa", args.aa)?,
                isa: settings.isa,
                anisotropy: texture.anisotropy(),
                ..FrameOptions::new(args.width, args.height)
            },
            texture,
        };
        let stats = run_stats(&settings.context(&Terminal::new(false, args.trace)), &req)?;
        if let Some(path) = &args.json {
            emit_json(settings, path, &stats)
        } else {
            out(&app::report::model_stats_text(&stats))
        }
    })?
}

/// `export`: a scene or solution to glTF, then what was written and how well the atlas packs.
pub(crate) fn export(settings: &Settings, args: ExportArgs) -> anyhow::Result<()> {
    check_json_path(&args.json, &[&args.input, &args.output])?;
    in_pool(args.threads, || -> anyhow::Result<()> {
        let req = app::commands::export::ExportRequest {
            load: settings.load_options(&args.options),
            input: args.input,
            scene: args.scene,
            output: args.output,
            mesh: args.mesh,
            page_size: args.page_size,
            texture: args.texture.options(),
            exposure: args.exposure,
        };
        let report = app::commands::export::run_export(
            &settings.context(&Terminal::new(false, false)),
            &req,
        )?;
        if let Some(path) = &args.json {
            return emit_json(settings, path, &report);
        }
        for f in &report.files {
            wrote(f, false);
        }
        out(&app::report::export_text(&report))
    })?
}

/// `experiment`: reruns the paper's figures and tables, printing the results.
pub(crate) fn experiment(settings: &Settings, args: ExperimentArgs) -> anyhow::Result<()> {
    check_json_path(&args.json, &[&args.scene])?;
    in_pool(args.threads, || -> anyhow::Result<()> {
        let req = experiment::Request {
            which: experiment::Which::parse(&args.which)?,
            figures: experiment::FigureOptions {
                size: args.size,
                ppd: args.ppd,
                estimator: experiment::parse_estimator(&args.estimator)?,
                out_dir: Some(args.out_dir),
                ..experiment::FigureOptions::paper(&args.scene)
            },
            scenes: if args.scenes.is_empty() {
                experiment::SHIPPED_SCENES
                    .iter()
                    .map(PathBuf::from)
                    .collect()
            } else {
                args.scenes
            },
            frames: args.frames,
            doc: args.doc,
        };
        // Every figure and the page appear together, or none does.
        let hold = settings.outputs.hold()?;
        let results = experiment::run(
            &settings.context(&base::progress::SILENT),
            &req,
            &mut |_| {},
        )?;
        for path in hold.commit()? {
            wrote(&path, false);
        }
        if let Some(path) = &args.json {
            emit_json(settings, path, &results)
        } else {
            out(&experiment::results_text(&results))
        }
    })?
}

/// `bench`: frame times of the methods at every size, as a table or JSON.
pub(crate) fn bench(settings: &Settings, args: BenchArgs) -> anyhow::Result<()> {
    check_json_path(&args.json, &[&args.input])?;
    in_pool(args.threads, || -> anyhow::Result<()> {
        let req = BenchRequest {
            load: settings.load_options(&args.options),
            input: args.input,
            scene: args.scene,
            methods: args.methods,
            texture: args.texture.options(),
            sizes: args.sizes,
            frames: args.frames,
            aa: args.aa,
            renderers: args.renderers,
            region: args.region,
        };
        let report = run_bench(&settings.context(&Terminal::new(false, args.trace)), &req)?;
        if let Some(path) = &args.json {
            emit_json(settings, path, &report.rows)
        } else {
            out(&format!(
                "{}: {} polygons, {} samples, {} RRP patches, {} threads\n{}",
                report.input,
                report.polygons,
                report.samples,
                report.patches,
                report.threads,
                bench_table(&report.rows)
            ))
        }
    })?
}

/// `sweep`: speed against error over densities and methods; the table on stdout, the points
/// and plots in the files asked for.
pub(crate) fn sweep(settings: &Settings, args: SweepArgs) -> anyhow::Result<()> {
    in_pool(args.threads, || -> anyhow::Result<()> {
        check_sweep_outputs(&args)?;
        let req = sweep::SweepRequest {
            input: args.input.clone(),
            methods: args.methods.clone(),
            width: args.size.0,
            height: args.size.1,
            densities: args.densities.clone(),
            reference_density: args.reference_density,
            texture_levels: args.texture_levels,
            frames: args.frames,
            repeats: args.repeats,
            processes: timing_processes(args.processes)?,
            ppd: args.ppd,
            equal_error: !args.no_equal_error,
            truth_samples: args.truth_samples,
            sharp_levels: args.sharp_levels,
        };
        let observer = Terminal::new(!args.quiet, args.trace);
        let report = sweep::run_sweep(&settings.context(&observer), &req)?;
        let hold = settings.outputs.hold()?;
        write_sweep_outputs(&settings.outputs, &report, &args)?;
        for path in hold.commit()? {
            wrote(&path, args.quiet);
        }
        // `--json -` puts the JSON on stdout instead of the table: one document.
        if args.json.as_deref() == Some(Path::new("-")) {
            return Ok(());
        }
        out(&sweep::table(&report))
    })?
}

/// Checks the `--json` and `--csv` paths ([`base::output::check_outputs`]) against the input and
/// the scene's includes (through the scene the plan loads) before the sweep's minutes of work.
fn check_sweep_outputs(args: &SweepArgs) -> anyhow::Result<()> {
    let mut inputs = vec![args.input.clone()];
    if let Ok(i) = app::context::Input::load(&args.input) {
        inputs.extend(i.scene.inputs);
    }
    let outputs: Vec<(&str, &Path)> = args
        .json
        .as_deref()
        .filter(|p| *p != Path::new("-"))
        .map(|p| ("--json", p))
        .into_iter()
        .chain(args.csv.as_deref().map(|p| ("--csv", p)))
        .collect();
    let plots: Vec<PathBuf> = args
        .plots
        .iter()
        .flat_map(|dir| study::plot::sweep_plot_files(dir))
        .collect();
    let outputs: Vec<(&str, &Path)> = outputs
        .into_iter()
        .chain(plots.iter().map(|p| ("--plots", p.as_path())))
        .collect();
    base::output::check_outputs(&inputs, &outputs)?;
    if let Some(j) = args.json.as_deref().filter(|p| *p != Path::new("-")) {
        app::commands::render::check_extension("--json", j, "json", "JSON")?;
    }
    if let Some(c) = &args.csv {
        app::commands::render::check_extension("--csv", c, "csv", "CSV")?;
    }
    Ok(())
}

/// Writes the sweep's `--json`, `--csv` and `--plots` files (under the caller's hold).
fn write_sweep_outputs(
    files: &Outputs,
    report: &sweep::SweepReport,
    args: &SweepArgs,
) -> anyhow::Result<()> {
    match &args.json {
        Some(path) if path == Path::new("-") => out(&json(report)?)?,
        Some(path) => files.write_atomic(path, json(report)?.as_bytes())?,
        None => {}
    }
    if let Some(path) = &args.csv {
        files.write_atomic(path, sweep::csv(report).as_bytes())?;
    }
    if let Some(dir) = &args.plots {
        study::plot::sweep_plots(files, report, dir)?;
    }
    Ok(())
}

/// `count` timing processes of this very binary (none for 0).
fn timing_processes(count: u32) -> anyhow::Result<Option<study::timing::TimingProcesses>> {
    if count == 0 {
        return Ok(None);
    }
    let exe = std::env::current_exe()
        .map_err(|e| anyhow::anyhow!("cannot find this program to start timing processes: {e}"))?;
    Ok(Some(study::timing::TimingProcesses { exe, count }))
}

/// `time-worker`: one timing process of a sweep; its reply (JSON) on stdout.
pub(crate) fn time_worker(settings: &Settings, args: TimeWorkerArgs) -> anyhow::Result<()> {
    let observer = Terminal::new(false, false);
    let reply = study::worker::run_worker(&settings.context(&observer), &args.request)?;
    out(&(reply + "\n"))
}

/// `results`: writes the results page and its data, then a one-line summary.
pub(crate) fn results(settings: &Settings, args: ResultsArgs) -> anyhow::Result<()> {
    use study::experiment::results;
    in_pool(args.threads, || -> anyhow::Result<()> {
        let mut req = results::ResultsRequest::new(args.doc);
        if !args.scenes.is_empty() {
            req.scenes = args.scenes;
        }
        req.sweep_size = args.size;
        req.gallery_width = args.gallery_width;
        req.frames = args.frames;
        req.repeats = args.repeats;
        req.processes = timing_processes(args.processes)?;
        req.truth_samples = args.truth_samples;
        let observer = Terminal::new(!args.quiet, args.trace);
        // The page, its data, plots and images appear together, or none does.
        let hold = settings.outputs.hold()?;
        let report = results::run_results(&settings.context(&observer), &req, &mut |_| {})?;
        for path in hold.commit()? {
            wrote(&path, args.quiet);
        }
        out(&format!(
            "{} scenes in {:.0} s on {}; wrote {}\n",
            report.scenes.len(),
            report.seconds,
            report.machine.line(),
            req.doc.display()
        ))
    })?
}

/// `generate building`: writes the scene and its OBJ and MTL, then the polygon count.
pub(crate) fn generate_building(settings: &Settings, args: BuildingArgs) -> anyhow::Result<()> {
    use fixtures::generate::{write_building, BuildingOptions};
    let options = BuildingOptions {
        rooms_x: args.rooms_x,
        rooms_z: args.rooms_z,
        floors: args.floors,
        cut: args.cut,
        lights: args.lights,
        furniture: args.furniture,
        seed: args.seed,
    };
    let written = write_building(&settings.outputs, &options, &args.output)?;
    let p = &written.paths;
    for path in [&p.scene, &p.obj, &p.mtl] {
        wrote(path, false);
    }
    out(&format!("{}\n", written.building.summary))
}

/// `compare`: the pixel-by-pixel check (with `--tolerance`) and the perceptual measures
/// (without it, or with a distance threshold), as one table or one JSON document; an error
/// naming every failed check.
pub(crate) fn compare(settings: &Settings, args: CompareArgs) -> anyhow::Result<()> {
    if let Some(d) = &args.diff {
        use imageio::OutputFormat::{Exr, Png};
        if !matches!(imageio::OutputFormat::of(d), Some(Png | Exr)) {
            return Err(Error::invalid_option(
                "--diff",
                d.display().to_string(),
                "must end in .png (scaled so the largest difference is white) or .exr (|a - b|)",
            )
            .into());
        }
    }
    check_json_path(&args.json, &[&args.a, &args.b])?;
    use app::commands::compare::{run_compare, CompareRequest};
    if let Some(path) = &args.diff {
        base::output::check_outputs(&[args.a.clone(), args.b.clone()], &[("--diff", path)])?;
    }
    let req = CompareRequest {
        a: args.a.clone(),
        b: args.b.clone(),
        ppd: args.ppd,
        view_degrees: args.view_degrees,
        tolerance: args.tolerance,
        floor: args.floor,
        fail_percent: args.fail_percent,
        max_distance: args.max_distance,
        max_distance_per_pixel: args.max_distance_per_pixel,
        convert: args.convert,
        mask: args.mask.clone(),
        second_reference: args.second_reference.clone(),
    };
    let report = run_compare(&req, settings.limit)?;
    if let (Some(path), Some(d)) = (&args.diff, &report.pixels) {
        write_diff(&settings.outputs, path, d)?;
    }
    if let Some(path) = &args.json {
        emit_json(settings, path, &report)?;
    } else {
        out(&report.text())?;
    }
    if report.passed {
        return Ok(());
    }
    Err(Error::Runtime(format!(
        "{} differs from {}: {}",
        args.a.display(),
        args.b.display(),
        report.failures().join("; ")
    ))
    .into())
}

/// Writes `--diff`: an EXR of the raw `|a - b|`, or a PNG scaled so the largest difference is
/// white.
fn write_diff(files: &Outputs, path: &Path, d: &metric::pixels::PixelDiff) -> anyhow::Result<()> {
    let exr = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("exr"));
    if exr {
        imageio::write_exr(files, path, d.image.view())?;
    } else {
        imageio::write_png(files, path, d.normalized_image().view(), 0.0)?;
    }
    Ok(())
}

/// `truth`: the path tracer's image and per-polygon estimates; "wrote" lines and a summary on
/// stderr, the polygon table on stdout.
pub(crate) fn truth(settings: &Settings, args: TruthArgs) -> anyhow::Result<()> {
    let req = TruthRequest {
        load: settings.load_options(&args.options),
        input: args.input,
        output: args.output,
        json: args.json,
        shadow_mask: args.shadow_mask,
        spp: args.spp,
        width: args.width,
        height: args.height,
        aa: args.aa,
        seed: args.seed,
        polygon_samples: args.polygon_samples,
        strata: args.strata,
        max_error: args.max_error,
        max_bounces: args.max_bounces,
        compare_solver: args.compare_solver,
    };
    let quiet = args.quiet;
    let to_stdout = req.json.as_deref() == Some(Path::new("-"));
    let observer = Terminal::new(!quiet, args.trace);
    let mut on_event = |event: TruthEvent| match event {
        TruthEvent::Warning(w) => observer.note(&format!("warning: {w}")),
        TruthEvent::Wrote(path) if !quiet => observer.note(&format!("wrote {}", path.display())),
        _ => {}
    };
    let outcome = in_pool(args.threads, || {
        run_truth(&settings.context(&observer), &req, &mut on_event)
    })??;
    if let (true, Some((report, _))) = (to_stdout, &outcome.polygons) {
        out(&json(report)?)?;
    }
    if quiet {
        return Ok(());
    }
    if let Some((img, seconds)) = &outcome.image {
        note(&format!(
            "truth image: {} x {}, {} samples per pixel, relative error {:.4} (rms over pixels), \
             {} back-face samples, {seconds:.1} s",
            img.mean.width,
            img.mean.height,
            img.samples_per_pixel,
            img.relative_error,
            img.back_face_samples
        ));
    }
    if let Some((report, seconds)) = &outcome.polygons {
        if !to_stdout {
            out(&report.table())?;
        }
        note(&format!(
            "truth polygons: {} polygons, largest relative standard error {:.3} %, {seconds:.1} s",
            report.polygons.len(),
            100.0 * report.largest_relative_error()
        ));
    }
    if let Some((on_boundary, near, seconds)) = outcome.shadows {
        note(&format!(
            "shadow mask: {on_boundary} pixels on a shadow boundary, {near} within {} of one, \
             {seconds:.1} s",
            metric::edges::EDGE_RADIUS
        ));
    }
    Ok(())
}
