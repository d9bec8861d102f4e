//! `docs/experiments.md`: the figures, the sweep and Table 1 as Markdown, with the findings
//! computed from the numbers, so a regenerated report cannot keep a claim its numbers no longer
//! support. The figures' sections are here; the spot-width sweep and its predictions are in
//! [`spot_sweep`], Table 1 and the discussion of what agrees with the paper in [`models`].

use super::{table1_markdown, Figure, FigureOptions, Request, Results, SweepRow, PAPER_TABLE1};
use app::commands::stats::ModelStats;
use base::error::Result;
use metric::Comparison;
use reconstruction::Estimator;
use std::path::{Path, PathBuf};

mod models;
mod spot_sweep;

use models::*;
pub use spot_sweep::sweep_markdown;
use spot_sweep::*;

/// `target` relative to directory `base` when it lies below it, else as given.
fn relative_to(target: &Path, base: &Path) -> PathBuf {
    target
        .strip_prefix(base)
        .map(Path::to_path_buf)
        .unwrap_or_else(|_| target.to_path_buf())
}

fn images_row(f: &Figure, dir: &Path) -> String {
    images_row_of(f, dir, |_| true)
}

/// The images row of the panels whose key `keep` accepts.
fn images_row_of(f: &Figure, dir: &Path, keep: impl Fn(&str) -> bool) -> String {
    let mut head = String::from("|");
    let mut sep = String::from("|");
    let mut imgs = String::from("|");
    for p in f.panels.iter().filter(|p| keep(&p.key)) {
        head += &format!(" {} |", p.label);
        sep += "---|";
        imgs += &if p.file.is_empty() {
            " (not written) |".to_string()
        } else {
            format!(" ![{}]({}) |", p.key, dir.join(&p.file).display())
        };
    }
    format!("{head}\n{sep}\n{imgs}\n")
}

fn measures_table(f: &Figure) -> String {
    let mut t = String::from(
        "| panel | perceptual distance | RMSE | max abs error | relative luminance error | Mach band |\n\
         |---|---|---|---|---|---|\n",
    );
    for p in &f.panels {
        if let Some(c) = &p.versus_reference {
            t += &format!(
                "| {} | {:.4} | {:.5} | {:.5} | {:.5} | {:.3e} |\n",
                p.label,
                c.perceptual_distance,
                c.rmse,
                c.max_abs_error,
                c.relative_luminance_error,
                c.mach_band
            );
        }
    }
    t
}

fn distance_table(f: &Figure) -> String {
    let d = |k: &str| f.distance(k).map_or("-".into(), |x| format!("{x:.4}"));
    let (pb, pl) = f.paper;
    format!(
        "| | reference | bicubic | bilinear | direct |\n|---|---|---|---|---|\n\
         | reference (ours) | 0 | {} | {} | {} |\n\
         | reference (paper) | 0.0 | {pb:.2} | {pl:.2} | (not in the paper) |\n",
        d("bicubic"),
        d("bilinear"),
        d("direct")
    )
}

/// Sentences on what agrees with the paper, computed from the numbers (so a regenerated report
/// cannot keep a claim its numbers no longer support).
fn figure_findings(f: &Figure) -> String {
    let mut t = String::new();
    if let (Some(b), Some(l), Some(d)) = (
        f.distance("bicubic"),
        f.distance("bilinear"),
        f.distance("direct"),
    ) {
        t += &ordering_finding(f, b, l);
        t += &closest_finding(f, d);
        t += &mach_band_finding(f);
    }
    if let Some(c) = f.panel("full").and_then(|p| p.versus_reference.as_ref()) {
        t += &format!(
            "- The paper's own reference (the full sampling, shown bilinearly) is {:.4} from the \
             oracle reference. At 256 x 256 with depth 9 the 513 x 513 samples include every \
             pixel centre, so the two references are the same image and the paper's choice of \
             reference changes nothing here.\n",
            c.perceptual_distance
        );
    }
    t
}

/// Whether bicubic (distance `b`) is closer to the reference than bilinear (`l`), as in the
/// paper, with both ratios.
fn ordering_finding(f: &Figure, b: f64, l: f64) -> String {
    let (pb, pl) = f.paper;
    let ours = b / l;
    let paper = pb / pl;
    if b < l {
        format!(
            "- **Agrees**: bicubic reconstruction is closer to the reference than bilinear \
             ({b:.4} < {l:.4}). The ratio bicubic / bilinear is {ours:.3} here and {paper:.3} \
             in the paper.\n"
        )
    } else {
        format!(
            "- **Disagrees**: bilinear is at least as close to the reference as bicubic here \
             ({l:.4} <= {b:.4}; the paper found {pb:.2} < {pl:.2}).\n"
        )
    }
}

/// Which reconstruction of the coarse data comes closest to the reference, beside the direct
/// method's distance `d` (empty when no panel is measured).
fn closest_finding(f: &Figure, d: f64) -> String {
    let best = f
        .panels
        .iter()
        .filter(|p| p.key != "full")
        .filter_map(|p| p.versus_reference.as_ref().map(|c| (p.key.as_str(), c)))
        .min_by(|a, b| a.1.perceptual_distance.total_cmp(&b.1.perceptual_distance));
    let Some((k, c)) = best else {
        return String::new();
    };
    let bd = c.perceptual_distance;
    if k == "direct" {
        format!(
            "- The direct method ({d:.4}) is the closest reconstruction of the coarse data to the \
             reference.\n"
        )
    } else if d <= bd * (1.0 + 1e-4) {
        format!(
            "- The direct method ({d:.4}) is the closest reconstruction of the coarse data to the \
             reference, tied to rounding with `{k}` ({bd:.4}).\n"
        )
    } else {
        format!(
            "- The direct method's distance is {d:.4}; the closest reconstruction of the coarse \
             data is `{k}` ({bd:.4}).\n"
        )
    }
}

/// The Mach-band energy of bicubic against bilinear (empty unless both are measured).
fn mach_band_finding(f: &Figure) -> String {
    let measured = |k: &str| f.panel(k).and_then(|p| p.versus_reference.as_ref());
    let (Some(cb), Some(cl)) = (measured("bicubic"), measured("bilinear")) else {
        return String::new();
    };
    format!(
        "- Mach-band energy: bicubic {:.3e}, bilinear {:.3e} ({}).\n",
        cb.mach_band,
        cl.mach_band,
        if cb.mach_band < cl.mach_band {
            "the C1 reconstruction has less, as the paper argues"
        } else {
            "the C1 reconstruction does not have less here"
        }
    )
}

/// Fig. 6's texel placements and edge rules compared: centre (panels (c), (d)) against corner
/// (panels (f), (g)) and against centre texels clamped to the edge (panels (h), (i)), with the
/// findings computed from the numbers.
fn placement_section(f: &Figure, img_dir: &Path, ts: u32) -> String {
    let Some(pl) = Placements::of(f) else {
        return String::new();
    };
    let m = ts.saturating_sub(1).max(1);
    let mut t = format!(
        "### Texel placement and edge rule: centre, corner, clamped\n\n\
         Panels (c) and (d) place texel i at u = (i + 0.5) / {ts} (texel centres, the default); \
         within half a texel of an edge the filters read the texture's gutter, the RRP continued \
         past the edge. With `--texel-placement corner` texel i sits at u = i / {m}, so the \
         first and last texels lie on the edges and the corner texels on the corners (every mip \
         level is resampled from the RRPs at its own corner positions). Panels (h) and (i) keep \
         centre texels without the gutter, so a filter reaching past the last texel reads it \
         again (clamp to edge): how the paper's RealityEngine addressed its textures, the \
         faithful variant of the paper's figure. Same {ts} x {ts} texels, same filters:\n\n"
    );
    t += &images_row_of(f, img_dir, |k| {
        k.starts_with("corner-") || k.starts_with("clamp-")
    });
    t += &pl.table(ts, m);
    t += "\n(perceptual distance to the reference, then the other measures; \
          `pixelflow-sim experiment fig6` prints them as the panels `corner-bilinear`, \
          `corner-bicubic`, `clamp-bilinear` and `clamp-bicubic`.)\n\n";
    t += &pl.findings(ts, f.paper);
    t + "\n"
}

/// Fig. 6's textured panels by texel placement, and its direct panel, each against the
/// reference.
struct Placements<'a> {
    /// Centre texels, bilinear.
    bl: &'a Comparison,
    /// Centre texels, bicubic (Mitchell).
    bc: &'a Comparison,
    /// Corner texels, bilinear.
    cbl: &'a Comparison,
    /// Corner texels, bicubic (Mitchell).
    cbc: &'a Comparison,
    /// Centre texels clamped to the edge: bilinear, bicubic (Mitchell), when drawn.
    clamped: Option<(&'a Comparison, &'a Comparison)>,
    /// The direct method, when drawn.
    direct: Option<&'a Comparison>,
}

/// A comparison's perceptual distance.
fn pd(x: &Comparison) -> f64 {
    x.perceptual_distance
}

impl<'a> Placements<'a> {
    /// The panels of `f`; `None` unless all four textured ones are measured.
    fn of(f: &'a Figure) -> Option<Placements<'a>> {
        let c = |k: &str| f.panel(k).and_then(|p| p.versus_reference.as_ref());
        Some(Placements {
            bl: c("bilinear")?,
            bc: c("bicubic")?,
            cbl: c("corner-bilinear")?,
            cbc: c("corner-bicubic")?,
            clamped: c("clamp-bilinear").zip(c("clamp-bicubic")),
            direct: c("direct"),
        })
    }

    /// One row per placement (then the direct method's): both filters' measures.
    fn table(&self, ts: u32, m: u32) -> String {
        let mut t = String::from(
            "\n| placement | bicubic (Mitchell) | bilinear | bicubic / bilinear | RMSE bicubic / bilinear \
             | max abs bicubic / bilinear | Mach band bicubic / bilinear |\n\
             |---|---|---|---|---|---|---|\n",
        );
        let row = |name: String, b: &Comparison, l: &Comparison| {
            format!(
                "| {name} | {:.4} | {:.4} | {:.3} | {:.5} / {:.5} | {:.5} / {:.5} | {:.3e} / {:.3e} |\n",
                b.perceptual_distance,
                l.perceptual_distance,
                b.perceptual_distance / l.perceptual_distance,
                b.rmse,
                l.rmse,
                b.max_abs_error,
                l.max_abs_error,
                b.mach_band,
                l.mach_band
            )
        };
        t += &row(format!("centre, u = (i + 0.5) / {ts}"), self.bc, self.bl);
        t += &row(format!("corner, u = i / {m}"), self.cbc, self.cbl);
        if let Some((kbl, kbc)) = self.clamped {
            t += &row(
                "centre, clamped to the edge (the paper's hardware)".to_string(),
                kbc,
                kbl,
            );
        }
        if let Some(d) = self.direct {
            t += &format!(
                "| direct (no texture) | {:.4} | | | {:.5} | {:.5} | {:.3e} |\n",
                d.perceptual_distance, d.rmse, d.max_abs_error, d.mach_band
            );
        }
        t
    }

    /// What corner placement changes, whether the paper's ordering holds with each placement,
    /// the better placement's ratio beside the paper's, and the direct method against them.
    fn findings(&self, ts: u32, (pb, pl): (f64, f64)) -> String {
        let (bl, bc, cbl, cbc) = (self.bl, self.bc, self.cbl, self.cbc);
        let mut t = format!(
            "- With corner placement bilinear's distance is {} and Mitchell's {}; the {ts} x {ts} \
             samples span the whole plane, so the outer half-texel ring is interpolated instead \
             of clamped.\n",
            change_words(pd(bl), pd(cbl)),
            change_words(pd(bc), pd(cbc))
        );
        t += &format!(
            "- The paper's ordering with centre texels {}; with corner texels it {}.\n",
            ordering_words(bc, bl),
            ordering_words(cbc, cbl)
        );
        if let Some((kbl, kbc)) = self.clamped {
            t += &format!(
                "- Clamped to the edge, as the paper's hardware drew it, Mitchell / bilinear is \
                 {:.3} (the paper's {:.3}); the ordering {}.\n",
                pd(kbc) / pd(kbl),
                pb / pl,
                ordering_words(kbc, kbl)
            );
        }
        let (name, b, l) = if pd(cbc) < pd(bc) {
            ("corner", cbc, cbl)
        } else {
            ("centre", bc, bl)
        };
        t += &format!(
            "- With the better placement for Mitchell ({name}), Mitchell / bilinear is {:.3}; the \
             paper's is {:.3}.\n",
            pd(b) / pd(l),
            pb / pl
        );
        if let Some(d) = self.direct {
            t += &self.direct_finding(d, ts);
        }
        t
    }

    /// Whether the direct method (`d`) is closer to the reference than every texture.
    fn direct_finding(&self, d: &Comparison, ts: u32) -> String {
        let clamped = self.clamped.map(|(a, b)| [a, b]).into_iter().flatten();
        let best = [self.bl, self.bc, self.cbl, self.cbc]
            .into_iter()
            .chain(clamped)
            .map(pd)
            .fold(f64::INFINITY, f64::min);
        if pd(d) < best {
            format!(
                "- The direct method ({:.4}) is closer to the reference than every texture \
                 ({best:.4} at best): it needs no {ts} x {ts} resampling.\n",
                pd(d)
            )
        } else {
            format!(
                "- A texture ({best:.4}) comes at least as close to the reference as the direct \
                 method ({:.4}).\n",
                pd(d)
            )
        }
    }
}

/// A distance's change from `from` to `to` in words: `12 % shorter (0.1000 -> 0.0880)`.
fn change_words(from: f64, to: f64) -> String {
    if to < from {
        format!(
            "{:.0} % shorter ({from:.4} -> {to:.4})",
            100.0 * (1.0 - to / from)
        )
    } else {
        format!(
            "{:.0} % longer ({from:.4} -> {to:.4})",
            100.0 * (to / from - 1.0)
        )
    }
}

/// Whether Mitchell (`b`) is closer to the reference than bilinear (`l`), in words.
fn ordering_words(b: &Comparison, l: &Comparison) -> String {
    if pd(b) < pd(l) {
        format!("holds (Mitchell {:.4} < bilinear {:.4})", pd(b), pd(l))
    } else {
        format!("fails (bilinear {:.4} <= Mitchell {:.4})", pd(l), pd(b))
    }
}

/// The whole `docs/experiments.md`, from the results of [`super::Which::All`].
pub fn markdown(r: &Results, req: &Request, doc: &Path) -> Result<String> {
    let doc_dir = doc.parent().unwrap_or(Path::new(""));
    let img_dir = req
        .figures
        .out_dir
        .as_deref()
        .map(|d| relative_to(d, doc_dir))
        .unwrap_or_default();
    let fo = &req.figures;
    let mut t = introduction(fo);
    if let Some(f) = &r.fig5 {
        t += &fig5_section(f, fo, &img_dir);
    }
    if let Some(f) = &r.fig6 {
        t += &fig6_section(f, fo, &img_dir);
    }
    if !r.sweep.is_empty() {
        t += &sweep_section(r, fo)?;
    }
    if !r.sensitivity.is_empty() {
        t += &sensitivity_section(r, fo);
    }
    if !r.table1.is_empty() {
        t += &table1_section(&r.table1);
    }
    t += "## What agrees with the paper and what does not\n\n";
    t += &discussion(&r.table1, &r.sweep);
    Ok(t)
}

/// The title, how to regenerate the page, the machine and what the distances are.
fn introduction(fo: &FigureOptions) -> String {
    let mut t = String::from(
        "# Experiments: the paper's Fig. 5, Fig. 6 and Table 1, rerun\n\n\
         Generated by `pixelflow-sim experiment all` (do not edit by hand); regenerate with\n\n\
         ```sh\ncargo run --release -- experiment all --out-dir docs/experiments --doc docs/experiments.md\n```\n\n",
    );
    t += &format!(
        "Machine: {} worker threads (the project's reference machine has 2 cores and 24 GB). \
         Perceptual distance: `docs/metrics.md` at {} pixels per degree; the \
         paper's absolute values cannot be reproduced (its viewing geometry and scaling are \
         unknown), so compare orderings and ratios. All distances are to **the oracle \
         reference**: the solver's exact radiosity at every pixel centre. Nothing on the page \
         is sampled at random (the solves' visibility is exact, the images are drawn \
         deterministically, and every run gives the same bits), so an ordering of two distances \
         is exact for the setting it was measured in, with no interval to put on it; what moves \
         the orderings is the setting, which the spot-width sweep and the sensitivity table \
         vary. Frame rates are the exception: they are medians of one run.\n\n",
        rayon::current_num_threads(),
        fo.ppd
    );
    t
}

/// A figure's distances in the paper's layout, every measure, and the findings.
fn figure_tables(f: &Figure) -> String {
    let mut t = String::from("\nPerceptual distance to the reference, in the paper's layout:\n\n");
    t += &distance_table(f);
    t += "\nEvery measure:\n\n";
    t += &measures_table(f);
    t += "\n";
    t += &figure_findings(f);
    t
}

/// Fig. 5: what it shows, its images, tables and findings.
fn fig5_section(f: &Figure, fo: &FigureOptions, img_dir: &Path) -> String {
    let mut t = format!(
        "## Fig. 5: reconstructing a coarse quadtree in texture space\n\n\
         The two-spots plane (`{}`) is solved, and the oracle is sampled on a full depth-{} \
         quadtree ({s} x {s} samples, the paper's 5 x 5). That coarse data is reconstructed at \
         {n} x {n}: (c) bilinearly, as a RAT texture would be resampled; (d) with the C1 \
         bicubic RRPs (slopes by the `{}` estimator{}) resampled at texel centres; (e) by the \
         direct method, the rasterizer evaluating the RRPs per pixel. (a') is the paper's \
         reference, a depth-{} full sampling shown bilinearly.\n\n",
        fo.scene.display(),
        fo.coarse_depth,
        fo.estimator.name(),
        if fo.estimator == Estimator::default() {
            ", the project default"
        } else {
            ""
        },
        fo.reference_depth,
        s = (1u32 << fo.coarse_depth) + 1,
        n = fo.size
    );
    t += &images_row(f, img_dir);
    t += &figure_tables(f);
    if let (Some(b), Some(d)) = (f.distance("bicubic"), f.distance("direct")) {
        if (b - d).abs() <= 1e-4 * b.max(d) {
            t += "- (d) and (e) evaluate the same RRPs at the same points (texel centres of a \
                  texture drawn 1:1 are pixel centres), so their distances agree to rounding: \
                  the direct method is the bicubic reconstruction without the texture.\n";
        }
    }
    t + "\n"
}

/// Fig. 6: what it shows, its images, tables and findings, then the texel placements compared.
fn fig6_section(f: &Figure, fo: &FigureOptions, img_dir: &Path) -> String {
    let mut t = format!(
        "## Fig. 6: a small bicubic-resampled texture, filtered on screen\n\n\
         The RRPs of the same coarse data are resampled to a {ts} x {ts} texture (the paper: \
         8 x 8, the power-of-two size the SGI hardware allocated), then drawn at {n} x {n}: (b) \
         nearest, (c) bilinear, (d) Mitchell-Netravali B = C = 1/3 filtering, and (e) the \
         direct method, which needs no texture.\n\n",
        ts = fo.texture_size,
        n = fo.size
    );
    t += &images_row_of(f, img_dir, |k| {
        !k.starts_with("corner-") && !k.starts_with("clamp-")
    });
    t += &figure_tables(f);
    t += "\n";
    t += &placement_section(f, img_dir, fo.texture_size);
    t
}
