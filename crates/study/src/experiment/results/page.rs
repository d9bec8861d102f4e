//! The results page as Markdown: each scene's sweep table with its fronts, convergence, timing
//! and error budget, the texture memory at equal error, the walkthrough rates and errors, the
//! image gallery and the commands that regenerate it, all from the [`ResultsReport`] and
//! nothing recomputed.

use super::*;

fn fronts(p: &SweepPoint) -> &'static str {
    match (p.pareto_time, p.pareto_memory) {
        (true, true) => "time, memory",
        (true, false) => "time",
        (false, true) => "memory",
        (false, false) => "",
    }
}

fn point_row(p: &SweepPoint) -> String {
    format!(
        "| {} | {} | {} | {:.2} ({:.2}-{:.2}) | {} | {} | {:.3} | {:.4} | {:.0} % | {:.3} | {} | {} |\n",
        p.method,
        p.density,
        texture_label(p),
        p.frame_ms,
        p.frame_ms_interval[0],
        p.frame_ms_interval[1],
        mb(p.bytes),
        mb(p.working_bytes),
        p.error_reconstruction,
        p.reconstruction.relative_rmse,
        100.0 * p.reconstruction.near_edges_share,
        p.error_total,
        p.physics.map_or("-".into(), |e| e.perceptual_text(3)),
        fronts(p)
    )
}

const POINT_HEADER: &str = "| method | density | texture | frame ms (interval) | bytes stored | bytes held drawing | error recon. | rel. RMSE recon. | recon. near edges | error total | error physics | front |\n|---|---|---|---|---|---|---|---|---|---|---|---|\n";

/// How far each density's solution is from the converged one (exact images, the
/// reconstruction left out), and how much that moves from the coarsest density to the finest.
fn convergence_line(sw: &SweepReport) -> String {
    let d: Vec<f64> = sw.densities.iter().filter_map(|d| d.converged).collect();
    let (Some(first), Some(last)) = (d.first(), d.last()) else {
        return String::new();
    };
    let each: Vec<String> = d.iter().map(|e| format!("{e:.3}")).collect();
    let moved = if *first == 0.0 {
        "every solution's exact image is the converged one's (nothing here for the solver to \
         converge on)"
            .to_string()
    } else if *last > 0.0 {
        format!(
            "it moves {:.1}x from the coarsest density to the finest",
            first / last
        )
    } else {
        "the finest density reaches the converged image".to_string()
    };
    format!(
        "**Solution convergence** (each density's exact image against the converged solution's, \
         perceptual distance: the solver alone, no reconstruction), coarse to fine: {}; {}.\n\n",
        each.join(", "),
        moved
    )
}

/// How the sweep's frame times were measured: processes, the intervals' coverage, the load.
fn timing_line(sw: &SweepReport) -> String {
    let t = &sw.timing;
    if t.processes == 0 {
        return format!(
            "Frame times: {} repeats in one process; the range shown is their spread, which \
             is not a confidence interval of what another run would measure.",
            t.samples
        );
    }
    let mut s = format!(
        "Frame times: every point timed in {} separate processes (each loads the solution, \
         draws every point once to warm up, then times it); the time is the median over the \
         processes, the interval a {:.1} % confidence interval of that median (distribution-free: \
         order statistics of the process medians).",
        t.processes,
        100.0 * t.coverage
    );
    let others: Vec<f64> = t.load.iter().filter_map(|l| l.other_cores).collect();
    if others.is_empty() {
        s += " The machine's load was not recorded (no /proc, or every process ran under a \
               second, too short for the 10 ms counters).";
    } else {
        s += &format!(
            " Other work on the machine while they ran: median {:.2} cores, at most {:.2}; {} of {} \
             processes ran beside more than {} cores of other work{}.",
            app::rates::median(others.clone()),
            t.peak_load().unwrap_or(0.0),
            t.high_load(),
            t.load.len(),
            timing::HIGH_LOAD_CORES,
            if t.high_load() > 0 {
                " (**high load**: those times are slower than an idle machine's)"
            } else {
                ""
            }
        );
    }
    s
}

/// Per method, how many of its points lie on the time and on the memory front.
fn front_counts(r: &SweepReport) -> String {
    let methods = r.methods();
    let count = |f: fn(&SweepPoint) -> bool| -> String {
        let parts: Vec<String> = methods
            .iter()
            .filter_map(|m| {
                let (on, all) = r
                    .points
                    .iter()
                    .filter(|p| p.method == *m)
                    .fold((0, 0), |(on, all), p| (on + f(p) as usize, all + 1));
                (on > 0).then(|| format!("{m} {on} of {all}"))
            })
            .collect();
        parts.join(", ")
    };
    format!(
        "On the time front (no point at most as wrong is faster beyond both intervals): {}. \
         On the memory front: {}.",
        count(|p| p.pareto_time),
        count(|p| p.pareto_memory)
    )
}

/// Per method, the lowest total error at the finest density and where it is reached.
fn best_at_finest(r: &SweepReport) -> String {
    let finest = r.densities.len().saturating_sub(1);
    let mut parts = Vec::new();
    let mut seen: Vec<&str> = Vec::new();
    for p in r.points.iter().filter(|p| p.density == finest) {
        if seen.contains(&p.method.as_str()) {
            continue;
        }
        seen.push(&p.method);
        let best = r
            .points
            .iter()
            .filter(|q| q.density == finest && q.method == p.method)
            .min_by(|a, b| a.error_total.total_cmp(&b.error_total));
        if let Some(b) = best {
            parts.push(format!(
                "{} {:.3} ({:.2} ms, {})",
                b.method,
                b.error_total,
                b.frame_ms,
                mb(b.bytes)
            ));
        }
    }
    format!(
        "Lowest total error of each method at the finest density: {}.",
        parts.join("; ")
    )
}

fn reached_cell(p: Option<ScalePoint>, rrp: u64) -> String {
    match p {
        Some(p) => format!(
            "{} ({:.2}x the RRPs, scale 2^{})",
            mb(p.bytes),
            p.bytes as f64 / rrp.max(1) as f64,
            p.scale
        ),
        None => "not reached".into(),
    }
}

fn equal_error_markdown(e: &EqualError) -> String {
    let mut s = format!(
        "Direct method's reconstruction error {:.3} with {} of RRPs as stored (trees and \
         samples; {} as held) (density {}). Texture sides \
         tried: the quadtree-depth sides times 2^-3 to 2^4; the search stopped because {}.\n\n\
         | method | placement | mip-mapped | texture bytes at <= direct's error | at <= 1.1x | lowest error / direct's (bytes) |\n\
         |---|---|---|---|---|---|\n",
        e.direct_error,
        mb(e.rrp_bytes),
        mb(e.rrp_held_bytes),
        e.density,
        e.stopped
    );
    for r in &e.rows {
        let best = r.best().map_or("-".into(), |b| {
            format!(
                "{:.3} ({})",
                b.error / e.direct_error.max(1e-300),
                mb(b.bytes)
            )
        });
        s += &format!(
            "| {} | {} | {} | {} | {} | {} |\n",
            r.method,
            r.placement,
            if r.mip_mapped { "yes" } else { "no" },
            reached_cell(r.reached.first().copied().flatten(), e.rrp_bytes),
            reached_cell(r.reached.get(1).copied().flatten(), e.rrp_bytes),
            best
        );
    }
    // The findings, one sentence each for the textures as drawn (mip-mapped) and without mips.
    s += "\n";
    s += &cheapest_finding(e, true, "as the texture methods draw them (mip-mapped)");
    s += &cheapest_finding(e, false, "without mip chains (level 0 at every pixel)");
    s += "\n\n";
    s
}

/// The cheapest texture set, mip-mapped or not (`mip`), at the direct method's error, against
/// the RRPs' bytes as stored; `what` says how the textures are drawn.
fn cheapest_finding(e: &EqualError, mip: bool, what: &str) -> String {
    let cheapest = e
        .rows
        .iter()
        .filter(|r| r.mip_mapped == mip)
        .filter_map(|r| r.reached.first().copied().flatten().map(|p| (r, p)))
        .min_by_key(|(_, p)| p.bytes);
    match cheapest {
        Some((r, p)) => {
            // The same texels at the stored samples' precision (f32, 12 bytes against 4.5).
            let f32_bytes = p.bytes.saturating_mul(8) / 3;
            format!(
                "Textures {what}: the cheapest at the direct method's error is {} ({} texels, \
                 {} filtering), {} the RRPs' bytes as stored; with texels of the samples' own \
                 precision (f32) {}, {}. ",
                mb(p.bytes),
                r.placement,
                r.method.trim_start_matches("texture-"),
                ratio_words(p.bytes as f64 / e.rrp_bytes.max(1) as f64),
                mb(f32_bytes),
                ratio_words(f32_bytes as f64 / e.rrp_bytes.max(1) as f64)
            )
        }
        None => {
            format!("Textures {what}: none reaches the direct method's error at any size tried. ")
        }
    }
}

fn ratio_words(r: f64) -> String {
    if r >= 1.0 {
        format!("{r:.2} times")
    } else {
        format!("1/{:.1} of", 1.0 / r)
    }
}

/// The page.
pub fn markdown(r: &ResultsReport, req: &ResultsRequest) -> String {
    let mut s = introduction(r);
    s += &contents(r);
    for sc in &r.scenes {
        s += &scene_section(sc);
    }
    let sweeps: Vec<(&str, &SweepReport)> = r
        .scenes
        .iter()
        .map(|sc| (sc.name.as_str(), &sc.sweep))
        .collect();
    s += &crate::experiment::matched::section(&sweeps);
    s += &equal_error_section(r);
    s += &walkthrough_section(r);
    s += &walk_error_section(r);
    s += &gallery_section(r, req);
    s += &commands_section(r, req);
    s
}

/// The title, how the page was made and on what, and how the sweep is built.
fn introduction(r: &ResultsReport) -> String {
    let mut s = String::from("# Results: speed, error and memory of every method\n\n");
    s += &format!(
        "Generated by `{}` in {:.0} s on {}. Every number on this page, and every image, comes \
         from that one run; the data are in [results/](results/) (`results.json`, and per scene \
         `sweep.json`, `sweep.csv`, the plots and the images). Frame times are wall-clock \
         milliseconds of warm frames (see [performance.md](performance.md) for what a frame time \
         includes), each the median over separate processes with a confidence interval of that \
         median (each scene's section says how many processes and the machine's load while they \
         ran); a method is called faster than another only where their intervals do not \
         overlap. The errors and bytes do not vary from run to run.\n\n",
        r.command,
        r.seconds,
        r.machine.line()
    );
    s += "How the sweep is built and what its terms mean: [sweep.md](sweep.md). In short: each \
          scene is solved at four sampling densities (the solver's tolerance times 4, 2, 1, 1/2 \
          and its depth limit moved by -2, -1, 0, +1 levels, its minimum depth by as many of \
          the coarser ones, down to 0; density 0 is the coarsest); every \
          method is drawn at each, the texture methods at four \
          texture sizes (the quadtree-depth sides halved 0-3 times) and both texel placements. \
          **Every method draws the same data**: by default (`--sharp-levels 3`) each takes the \
          spot lights' direct light from the light model exactly, along the cones' edges, and \
          only the rest from the solver's samples (the mesh's vertices follow the cones' edges \
          as the patches do); `sweep --sharp-levels 0` draws every method from the samples \
          alone, as `render --sharp-levels 0` does. **Error recon.** is the perceptual distance ([metrics.md](metrics.md)) to the same \
          solution's exact image (the method's own error); beside it the same error as a \
          second metric with no model of vision, **rel. RMSE recon.** (the luminance RMSE over \
          the exact image's mean luminance), and **recon. near edges**, the share of its squared \
          luminance error within 2 px of the exact image's sharp edges (light and shadow edges, \
          emitters' outlines, silhouettes; [metrics.md](metrics.md#error-near-sharp-edges)); **error total** to a converged \
          solution's (tolerance 1/4, two levels deeper: the solver's convergence), **physics \
          error** to the independent path tracer's image (`pixelflow-sim truth`, its noise taken \
          out: what a user sees against the light), and **solution error** is the same \
          solution's exact image against that path tracer's: the physics error splits into the \
          solution error (the solver's) and the reconstruction error (the method's). The truth \
          is traced in 8 independent parts: every comparison made on these two figures (which \
          term is larger, which method is nearer the light) is called only where its 95 % \
          interval over the parts excludes 0, and stated as a tie otherwise; the errors against \
          the solver's own images carry no noise and need none. **Bytes \
          stored**: the RRPs' trees (a bit per node) and samples (three f32 per vertex), from \
          which a render builds them; 12-bit textures with mip chains and gutters; \
          the mesh's vertices and indices. **Bytes held drawing** (the working set): the RRPs \
          with the direct method's patch caches; the textures as f32 texels; the mesh's \
          triangles as the renderer holds them.\n\n";
    s
}

/// Links to every scene's section and to the sections after them.
fn contents(r: &ResultsReport) -> String {
    let mut s = String::from("## Contents\n\n");
    for sc in &r.scenes {
        s += &format!("- [{0}](#{0})\n", sc.name);
    }
    s += "- [Table 1 at matched error](#table-1-at-matched-error)\n- [Equal-error memory](#equal-error-memory)\n- [Walkthrough frame rates](#walkthrough-frame-rates)\n- [Error along the walkthrough at fixed memory](#error-along-the-walkthrough-at-fixed-memory)\n- [Image gallery](#image-gallery)\n\n";
    s
}

/// One scene's sweep: its densities, plots and fronts, every method at the scene's own density,
/// and every point on a front.
fn scene_section(sc: &SceneResults) -> String {
    let sw = &sc.sweep;
    let mut s = format!("## {}\n\n", sc.name);
    let dens: Vec<String> = sw
        .densities
        .iter()
        .map(|d| format!("tolerance {} ({} samples)", d.tolerance, d.samples))
        .collect();
    s += &format!(
        "`{}` at {} x {}; densities: {}; converged reference: tolerance {}, depth {}, {} \
         samples. ({:.0} s for this scene.)\n\n",
        sc.path,
        sw.width,
        sw.height,
        dens.join(", "),
        sw.reference.tolerance,
        sw.reference.max_depth,
        sw.reference.samples,
        sc.seconds
    );
    s += &format!(
        "| error against frame time | error against memory |\n|---|---|\n| ![](results/{0}/error-vs-time.png) | ![](results/{0}/error-vs-memory.png) |\n| **error against samples** | **error against texture size** |\n| ![](results/{0}/error-vs-samples.png) | ![](results/{0}/error-vs-texture-size.png) |\n\n",
        sc.name
    );
    s += &convergence_line(sw);
    s += &format!(
        "{}\n\n{}\n\n{}\n\n",
        timing_line(sw),
        front_counts(sw),
        best_at_finest(sw)
    );
    s += &budget::budget_section(sw);
    s += &regions::region_section(sw);
    s += &own_density_table(sw);
    s += "\nEvery point on a front, all densities:\n\n";
    s += POINT_HEADER;
    for p in sw
        .points
        .iter()
        .filter(|p| p.pareto_time || p.pareto_memory)
    {
        s += &point_row(p);
    }
    s + "\n"
}

/// Every method at the scene's own density (the equal-error search's, else the middle one), the
/// textures at the quadtree-depth size.
fn own_density_table(sw: &SweepReport) -> String {
    let own = sw
        .equal_error
        .as_ref()
        .map_or(sw.densities.len().saturating_sub(1) / 2, |e| e.density);
    let mut s = format!(
        "At the scene's own density ({}), every method, the textures at the quadtree-depth size:\n\n{}",
        own, POINT_HEADER
    );
    for p in sw
        .points
        .iter()
        .filter(|p| p.density == own && p.texture.is_none_or(|l| l.halvings == 0))
    {
        s += &point_row(p);
    }
    s
}

/// What the equal-error search measures and why mip-mapping keeps the textures' error up, then
/// each scene's comparison.
fn equal_error_section(r: &ResultsReport) -> String {
    let mut s = String::from("## Equal-error memory\n\n");
    s += "How many bytes of texture each texture method needs to be as accurate as the direct \
          method, beside the bytes of the RRPs the direct method evaluates: the smallest texture \
          set tried (every polygon's quadtree-depth side scaled by the same power of two) whose \
          reconstruction error is at most the direct method's, or within 10 % of it; each set \
          drawn as the texture methods draw it (mip-mapped, 12-bit bytes with chains) and with \
          its mip chain dropped (level 0 at every pixel, 12-bit bytes of level 0). The textures \
          are resampled from the same RRPs, so as they grow they approach the direct method's \
          image; but once a texel is smaller than a pixel, mip-mapping averages over the pixel's \
          footprint (isotropically, so over more than the footprint where a surface is seen \
          obliquely) where the direct method and the exact image sample the pixel centre, and \
          that error does not fall with the texture's size. Without mip chains the error does \
          converge to the direct method's, at the price of aliasing under minification, which a \
          point-sampled error measure does not see.\n\n";
    for sc in &r.scenes {
        if let Some(e) = &sc.sweep.equal_error {
            s += &format!("**{}**. {}\n", sc.name, equal_error_markdown(e));
        }
    }
    s += &views_section(r);
    s
}

/// The equal-error curves across views and image sizes.
fn views_section(r: &ResultsReport) -> String {
    let mut s = format!(
        "### Across views and image sizes\n\nThe answer above is for one view at one image \
         size. Here the same texture sets (the scene's texel placement, mip-mapped as drawn) are \
         measured from the scene's camera and {} frames spread over its camera path, at the \
         sweep's size and twice it, each against the same solution's exact image there. Each \
         cell is the texture's reconstruction error over the direct method's at that view and \
         size, at the quadtree-depth sides times the column's scale: the whole error-size \
         curve. The last column is the bytes of the smallest scale within {:.0} % of the direct \
         method.\n\n",
        crate::equal_views::PATH_VIEWS,
        100.0 * (crate::equal_views::VIEW_RATIO - 1.0)
    );
    for sc in &r.scenes {
        let table = crate::equal_views::markdown(&sc.sweep.equal_views, mb);
        if !table.is_empty() {
            s += &format!("**{}**\n\n{}\n", sc.name, table);
        }
    }
    s
}

/// Every walked scene's frame rates and stage times per method, and which scenes were walked.
fn walkthrough_section(r: &ResultsReport) -> String {
    let mut s = String::from("## Walkthrough frame rates\n\n");
    s += "Every frame of the scene's camera path, at the scene's image size, one method after \
          the other (one warm-up frame each, which also builds the textures or the mesh). \
          **fps over processes**: the path flown by each method in separate processes (each \
          loads the solution, warms up and flies every frame); per process the median frame's \
          rate, then the median over the processes with its confidence interval (as the \
          sweep's, see [sweep.md](sweep.md)). Then, in this one process: frames per second of \
          the slowest, median and fastest frame (a spread over the path's views, not an \
          interval) and the median stage times. Scenes without a `[camera_path]` are not \
          walked.\n\n\
          | scene | method | size | frames | fps over processes (interval) | fps min / median / max, one process | median ms: geometry / raster / composition / shading |\n\
          |---|---|---|---|---|---|---|\n";
    for sc in &r.scenes {
        for w in &sc.walkthrough {
            let m = &w.summary;
            let over = w.processes.map_or("-".into(), |p| {
                format!("{:.0} ({:.0}-{:.0})", p.fps, p.interval[0], p.interval[1])
            });
            s += &format!(
                "| {} | {} | {} x {} | {} | {} | {:.0} / {:.0} / {:.0} | {:.2} / {:.2} / {:.2} / {:.2} |\n",
                sc.name,
                w.method,
                w.width,
                w.height,
                m.frames,
                over,
                m.fps_min,
                m.fps_median,
                m.fps_max,
                m.median_geometry_ms,
                m.median_raster_ms,
                m.median_composition_ms,
                m.median_shading_ms
            );
        }
    }
    for sc in r.scenes.iter().filter(|sc| !sc.walkthrough_load.is_empty()) {
        let load = &sc.walkthrough_load;
        let high = timing::high_load(load);
        let peak = timing::peak_load(load);
        s += &format!(
            "\n{}: {} processes, {}; {} beside more than {} cores of other work{}.",
            sc.name,
            load.len(),
            peak.map_or("load not recorded".into(), |p| format!(
                "other work at most {p:.2} cores"
            )),
            high,
            timing::HIGH_LOAD_CORES,
            if high > 0 { " (**high load**)" } else { "" }
        );
    }
    s += "\n";
    let walked: Vec<&str> = r
        .scenes
        .iter()
        .filter(|sc| !sc.walkthrough.is_empty())
        .map(|sc| sc.name.as_str())
        .collect();
    s += &format!(
        "\nWalked: {}. The same with images written, per method: `pixelflow-sim render <scene> \
         --walkthrough --method <method> --stats stats.json`.\n\n",
        if walked.is_empty() {
            "none".to_string()
        } else {
            walked.join(", ")
        }
    );
    s
}

/// The error along each walked scene's camera path at fixed memory.
fn walk_error_section(r: &ResultsReport) -> String {
    let mut s = String::from(
        "## Error along the walkthrough at fixed memory

",
    );
    s += &format!(
        "Frames spread evenly over each scene's camera path (at most {}, the first and last \
         included), at the scene's image size, each method's image against the same solution's \
         exact image at that frame (the reconstruction error: the solution is the same for every \
         method). Memory is fixed: the texture methods' textures are sized by a budget equal to \
         the bytes the direct method's RRPs are stored in (their trees and f32 samples; the \
         textures at 12-bit texels with mip chains and gutters, the scene's texel placement); \
         the mesh has the bytes its subdivision needs.\n\n",
        walk_error::MAX_WALK_FRAMES
    );
    let mut any = false;
    for sc in &r.scenes {
        if let Some(e) = &sc.walk_errors {
            s += &walk_error::markdown(&sc.name, e);
            any = true;
        }
    }
    if !any {
        s += "No scene has a camera path.\n\n";
    }
    s
}

/// Every scene by every method, each image's distance to the exact image beneath it.
fn gallery_section(r: &ResultsReport, req: &ResultsRequest) -> String {
    let mut s = String::from("## Image gallery\n\n");
    s += &format!(
        "Every scene by every method at {} pixels wide, with the scene's own settings (its \
         solution, texture sizes and placement); under each image its perceptual distance to \
         the exact image (`reference`, the solver's exact radiosity at every pixel centre).\n\n",
        req.gallery_width
    );
    s += "| scene |";
    for m in GALLERY_METHODS {
        s += &format!(" {m} |");
    }
    s += "\n|---|";
    for _ in GALLERY_METHODS {
        s += "---|";
    }
    s += "\n";
    for sc in &r.scenes {
        s += &format!("| {} |", sc.name);
        for g in &sc.gallery {
            s += &format!(" ![{}]({}) |", g.method, g.file);
        }
        s += "\n|  |";
        for g in &sc.gallery {
            if g.method == "reference" {
                s += " exact |";
            } else {
                s += &format!(" {:.3} |", g.error);
            }
        }
        s += "\n";
    }
    s
}

/// The command that makes the page, the commands of its parts per scene, and a link to the
/// paper's experiments.
fn commands_section(r: &ResultsReport, req: &ResultsRequest) -> String {
    let mut s = String::from("\n## Commands\n\n");
    s += &format!("The whole page: `{}`. Per scene, the parts:\n\n", r.command);
    for sc in &r.scenes {
        s += &format!(
            "    pixelflow-sim sweep {0} --size {1}x{1} --json sweep.json --csv sweep.csv --plots DIR\n",
            sc.path, req.sweep_size
        );
        if !sc.walkthrough.is_empty() {
            s += &format!(
                "    pixelflow-sim render {} --walkthrough --method METHOD --stats walk.json\n",
                sc.path
            );
        }
    }
    s += "\nThe paper's Fig. 5, Fig. 6 and Table 1: [experiments.md](experiments.md).\n";
    s
}
