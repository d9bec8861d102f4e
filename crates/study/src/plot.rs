//! Plots of a speed-against-error sweep: total error against warm frame time, and total error
//! against the bytes a method stores, on log axes with ticks inside the data (`log_ticks`), one
//! colour per method, a thin line through each texture size's densities (coarse to fine),
//! circles for centre-placed texels and methods without textures, triangles for corner-placed
//! texels, and the Pareto front drawn as a thick line through its points. Two more plots follow
//! one line per method and texel placement: error against the solution's samples (the
//! quadtree-depth texture size at every density; against physics when the sweep has a truth
//! image, with the solution's own error as the floor beneath), and reconstruction error against
//! the textures' texels at the scene's own density (the direct method's as a level line). Each
//! plot is written as PNG and SVG.
//!
//! Drawn with `plotters` (no hand-made axes). Text uses DejaVu Sans, the font the application
//! ships ([`app::text::FONT`]), registered once, so the plots look the same on any machine and need no system fonts; the
//! PNG is encoded by [`imageio`] from plotters' RGB buffer. Files are written atomically.
//!
//! Invariant: the plot shows exactly the report's points and flags; nothing is recomputed here.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use plotters::prelude::*;
use plotters::style::{register_font, FontStyle};

use crate::sweep::{SweepPoint, SweepReport};
use base::error::{Error, Result};
use base::output::Outputs;

/// Plot size in pixels.
pub(crate) const PLOT_SIZE: (u32, u32) = (1000, 700);

fn font() -> Result<()> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED
        .get_or_init(|| register_font("sans-serif", FontStyle::Normal, app::text::FONT).is_ok());
    if ok {
        Ok(())
    } else {
        Err(Error::internal("the shipped plot font does not load"))
    }
}

/// The colour of a method's series (fixed per method, so plots of different scenes agree).
fn colour(method: &str) -> RGBColor {
    match method {
        "direct" => RGBColor(213, 62, 79),
        "texture-nearest" => RGBColor(102, 194, 165),
        "texture-bilinear" => RGBColor(50, 136, 189),
        "texture-bicubic" => RGBColor(94, 79, 162),
        "mesh" => RGBColor(244, 165, 66),
        _ => RGBColor(90, 90, 90),
    }
}

/// Which axis a plot puts the cost on.
#[derive(Clone, Copy)]
enum Cost {
    Time,
    Bytes,
}

impl Cost {
    fn of(self, p: &SweepPoint) -> f64 {
        match self {
            Cost::Time => p.frame_ms,
            Cost::Bytes => p.bytes as f64,
        }
    }
    fn on_front(self, p: &SweepPoint) -> bool {
        match self {
            Cost::Time => p.pareto_time,
            Cost::Bytes => p.pareto_memory,
        }
    }
    fn label(self) -> &'static str {
        match self {
            Cost::Time => "warm frame time (ms, log)",
            Cost::Bytes => "bytes stored by the method (log)",
        }
    }
    fn file(self) -> &'static str {
        match self {
            Cost::Time => "error-vs-time",
            Cost::Bytes => "error-vs-memory",
        }
    }
}

/// A tick label with at most 3 significant digits, large values with K / M / G (powers of 1000).
fn tick(x: f64) -> String {
    if !(x.is_finite() && x > 0.0) {
        return format!("{x}");
    }
    let (v, suffix) = match x {
        x if x >= 1e9 => (x / 1e9, "G"),
        x if x >= 1e6 => (x / 1e6, "M"),
        x if x >= 1e3 => (x / 1e3, "K"),
        x => (x, ""),
    };
    let decimals = (2 - v.log10().floor() as i32).clamp(0, 6) as usize;
    let s = format!("{v:.decimals$}");
    let s = if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    };
    s + suffix
}

/// A log axis range covering `xs` with a margin (a factor of 1.3 each side).
fn log_range(xs: impl Iterator<Item = f64>) -> std::ops::Range<f64> {
    let (lo, hi) = xs
        .filter(|x| x.is_finite() && *x > 0.0)
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), x| {
            (lo.min(x), hi.max(x))
        });
    if lo.is_finite() && hi > 0.0 {
        lo / 1.3..hi * 1.3
    } else {
        0.1..10.0
    }
}

/// Tick positions for a log axis over `r` (lo < hi, both > 0): the 1-2-5 sequence of each
/// decade inside the range when that gives at least 3 ticks; else 1 to 9 of each decade when
/// that gives at least 2 (a range within a decade or so); else 4 ticks evenly spaced in the
/// logarithm, rounded to the power of ten below a fifth of the range. Every tick lies inside
/// the range, so an axis whose data span less than a decade is still labelled inside its data.
fn log_ticks(r: &std::ops::Range<f64>) -> Vec<f64> {
    let (lo, hi) = (r.start, r.end);
    if !(lo > 0.0 && hi > lo && hi.is_finite()) {
        return Vec::new();
    }
    let within = |mantissas: &[f64]| -> Vec<f64> {
        let mut v = Vec::new();
        let mut e = lo.log10().floor() as i32;
        while 10f64.powi(e) <= hi {
            for m in mantissas {
                let t = m * 10f64.powi(e);
                if t >= lo && t <= hi {
                    v.push(t);
                }
            }
            e += 1;
        }
        v
    };
    let v = within(&[1.0, 2.0, 5.0]);
    if v.len() >= 3 {
        return v;
    }
    let v = within(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0]);
    if v.len() >= 2 {
        return v;
    }
    let (a, b) = (lo.ln(), hi.ln());
    let unit = 10f64.powi(((hi - lo) / 5.0).log10().floor() as i32);
    let mut v: Vec<f64> = (1..=4)
        .map(|k| ((a + (b - a) * k as f64 / 5.0).exp() / unit).round() * unit)
        .filter(|t| (lo..=hi).contains(t))
        .collect();
    v.dedup();
    v
}

/// A chart's title and axis labels.
struct Axes<'a> {
    title: &'a str,
    x_label: &'a str,
    y_label: &'a str,
}

/// Log-log chart coordinates with the ticks of [`log_ticks`].
type LogLog = Cartesian2d<
    plotters::coord::combinators::WithKeyPoints<LogCoord<f64>>,
    plotters::coord::combinators::WithKeyPoints<LogCoord<f64>>,
>;

/// A log-log chart over `x` and `y` on `area`, its mesh, ticks and labels drawn.
fn log_chart<'a, DB: DrawingBackend>(
    area: &'a DrawingArea<DB, plotters::coord::Shift>,
    axes: &Axes<'_>,
    x: &std::ops::Range<f64>,
    y: &std::ops::Range<f64>,
) -> std::result::Result<ChartContext<'a, DB, LogLog>, DrawingAreaErrorKind<DB::ErrorType>> {
    let mut chart = ChartBuilder::on(area)
        .caption(axes.title, ("sans-serif", 26))
        .margin(16)
        .x_label_area_size(50)
        .y_label_area_size(80)
        .build_cartesian_2d(
            x.clone().log_scale().with_key_points(log_ticks(x)),
            y.clone().log_scale().with_key_points(log_ticks(y)),
        )?;
    chart
        .configure_mesh()
        .x_desc(axes.x_label)
        .y_desc(axes.y_label)
        .label_style(("sans-serif", 15))
        .axis_desc_style(("sans-serif", 17))
        .x_label_formatter(&|x| tick(*x))
        .y_label_formatter(&|y| tick(*y))
        .draw()?;
    Ok(chart)
}

/// Draws the legend of `chart` at `corner`, its text `font` pixels high, on a pale box.
fn legend<'a, DB: DrawingBackend + 'a>(
    chart: &mut ChartContext<'a, DB, LogLog>,
    font: u32,
    corner: SeriesLabelPosition,
) -> std::result::Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    chart
        .configure_series_labels()
        .label_font(("sans-serif", font))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(corner)
        .draw()
}

/// A texture size and placement (halvings, placement), `None` for methods without textures.
type LineKey<'a> = Option<(u32, &'a str)>;

/// The marker of a texel placement: circles for centre placement (and methods without
/// textures), triangles for corner placement.
fn corner(p: &SweepPoint) -> bool {
    p.texture.is_some_and(|t| t.placement == "corner")
}

/// A sweep plot's title: the scene, the cost axis and the image size.
fn sweep_title(report: &SweepReport, cost: Cost) -> String {
    format!(
        "{}: error against {} ({} x {})",
        Path::new(&report.scene)
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default(),
        match cost {
            Cost::Time => "frame time",
            Cost::Bytes => "memory",
        },
        report.width,
        report.height
    )
}

/// One method's lines: one per texture size and placement (the method's points when it has
/// neither), through its densities coarse to fine, as (cost, error) points.
fn method_lines<'a>(
    of_method: &[&&'a SweepPoint],
    cost: Cost,
) -> Vec<(LineKey<'a>, Vec<(f64, f64)>)> {
    let mut lines: Vec<(LineKey, Vec<(f64, f64)>)> = Vec::new();
    for p in of_method {
        let key = p.texture.map(|t| (t.halvings, t.placement));
        match lines.iter_mut().find(|(k, _)| *k == key) {
            Some((_, v)) => v.push((cost.of(p), p.error_total)),
            None => lines.push((key, vec![(cost.of(p), p.error_total)])),
        }
    }
    lines
}

fn draw<DB: DrawingBackend>(
    area: DrawingArea<DB, plotters::coord::Shift>,
    report: &SweepReport,
    cost: Cost,
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| Error::Runtime(format!("plotting: {e:?}"));
    area.fill(&WHITE).map_err(err)?;
    let pts: Vec<&SweepPoint> = report
        .points
        .iter()
        .filter(|p| cost.of(p) > 0.0 && p.error_total > 0.0)
        .collect();
    let x = log_range(pts.iter().map(|p| cost.of(p)));
    let y = log_range(pts.iter().map(|p| p.error_total));
    let all: Vec<(f64, f64)> = pts.iter().map(|p| (cost.of(p), p.error_total)).collect();
    let title = sweep_title(report, cost);
    let axes = Axes {
        title: &title,
        x_label: cost.label(),
        y_label: "perceptual distance to the converged solution (log)",
    };
    let mut chart = log_chart(&area, &axes, &x, &y).map_err(err)?;
    let mut methods: Vec<&str> = Vec::new();
    for p in &pts {
        if !methods.contains(&p.method.as_str()) {
            methods.push(&p.method);
        }
    }
    for m in methods {
        let c = colour(m);
        let of_method: Vec<&&SweepPoint> = pts.iter().filter(|p| p.method == m).collect();
        for (_, line) in &method_lines(&of_method, cost) {
            chart
                .draw_series(LineSeries::new(line.iter().copied(), c.stroke_width(1)))
                .map_err(err)?;
        }
        chart
            .draw_series(
                of_method
                    .iter()
                    .filter(|p| !corner(p))
                    .map(|p| Circle::new((cost.of(p), p.error_total), 5, c.filled())),
            )
            .map_err(err)?
            .label(m)
            .legend(move |(x, y)| Circle::new((x + 10, y), 5, c.filled()));
        chart
            .draw_series(
                of_method
                    .iter()
                    .filter(|p| corner(p))
                    .map(|p| TriangleMarker::new((cost.of(p), p.error_total), 6, c.filled())),
            )
            .map_err(err)?;
    }
    let mut front: Vec<(f64, f64)> = pts
        .iter()
        .filter(|p| cost.on_front(p))
        .map(|p| (cost.of(p), p.error_total))
        .collect();
    front.sort_by(|a, b| a.0.total_cmp(&b.0).then(b.1.total_cmp(&a.1)));
    chart
        .draw_series(LineSeries::new(
            front.iter().copied(),
            BLACK.stroke_width(2),
        ))
        .map_err(err)?
        .label("Pareto front")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK.stroke_width(2)));
    chart
        .draw_series(
            front
                .iter()
                .map(|&xy| Circle::new(xy, 9, BLACK.stroke_width(2))),
        )
        .map_err(err)?;
    legend(&mut chart, 15, legend_corner(&all, &x, &y)).map_err(err)?;
    area.present().map_err(err)?;
    Ok(())
}

/// The plots of a sweep, by file stem.
const CURVE_FILES: [&str; 2] = ["error-vs-samples", "error-vs-texture-size"];

/// The files [`sweep_plots`] writes into `dir`, for checking them before the sweep runs.
pub fn sweep_plot_files(dir: &Path) -> Vec<PathBuf> {
    [Cost::Time.file(), Cost::Bytes.file()]
        .into_iter()
        .chain(CURVE_FILES)
        .flat_map(|f| ["png", "svg"].map(|ext| dir.join(format!("{f}.{ext}"))))
        .collect()
}

/// One line of a curve plot: its legend, colour, marker and points `(x, y)`.
struct Series {
    label: String,
    colour: RGBColor,
    corner: bool,
    points: Vec<(f64, f64)>,
}

/// A curve plot: its title, axis labels and lines.
struct Curves {
    file: &'static str,
    title: String,
    x_label: &'static str,
    y_label: &'static str,
    series: Vec<Series>,
}

/// The scene's name as the plots title it.
fn scene_name(report: &SweepReport) -> String {
    Path::new(&report.scene)
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// The label of a method's line at a placement (`None`: no textures).
fn line_label(method: &str, placement: Option<&str>) -> String {
    match placement {
        Some(pl) => format!("{method}, {pl}"),
        None => method.to_string(),
    }
}

/// Error against samples: per method and placement, the quadtree-depth texture size at every
/// density; against physics (with the solution error's line) when there is a truth image,
/// else against the converged solution.
fn samples_curves(report: &SweepReport) -> Curves {
    let physics = report.truth.is_some();
    let y = |p: &SweepPoint| {
        if physics {
            p.error_physics.unwrap_or(p.error_total)
        } else {
            p.error_total
        }
    };
    let mut series = Vec::new();
    for m in report.methods() {
        for placement in [None, Some("centre"), Some("corner")] {
            let points: Vec<(f64, f64)> = report
                .points
                .iter()
                .filter(|p| p.method == m)
                .filter(|p| match (p.texture, placement) {
                    (None, None) => true,
                    (Some(t), Some(pl)) => t.halvings == 0 && t.placement == pl,
                    _ => false,
                })
                .map(|p| (p.samples as f64, y(p)))
                .collect();
            if !points.is_empty() {
                series.push(Series {
                    label: line_label(m, placement),
                    colour: colour(m),
                    corner: placement == Some("corner"),
                    points,
                });
            }
        }
    }
    if physics {
        series.push(Series {
            label: "solution's exact image".into(),
            colour: BLACK,
            corner: false,
            points: report
                .densities
                .iter()
                .filter_map(|d| d.solution.map(|e| (d.samples as f64, e.perceptual)))
                .collect(),
        });
    }
    Curves {
        file: CURVE_FILES[0],
        title: format!(
            "{}: error against samples ({} x {})",
            scene_name(report),
            report.width,
            report.height
        ),
        x_label: "radiosity samples of the solution (log)",
        y_label: if physics {
            "perceptual distance to the path tracer (log)"
        } else {
            "perceptual distance to the converged solution (log)"
        },
        series,
    }
}

/// Reconstruction error against texture texels at the scene's own density, per texture method
/// and placement, with the direct method's error as a level line across them.
fn texture_curves(report: &SweepReport) -> Curves {
    let own = report.own_density;
    let at_own = || report.points.iter().filter(move |p| p.density == own);
    let mut series = Vec::new();
    for m in report.methods() {
        for pl in ["centre", "corner"] {
            let mut points: Vec<(f64, f64)> = at_own()
                .filter(|p| p.method == m)
                .filter_map(|p| p.texture.filter(|t| t.placement == pl).map(|t| (t, p)))
                .map(|(t, p)| (t.texels as f64, p.error_reconstruction))
                .collect();
            points.sort_by(|a, b| a.0.total_cmp(&b.0));
            if !points.is_empty() {
                series.push(Series {
                    label: line_label(m, Some(pl)),
                    colour: colour(m),
                    corner: pl == "corner",
                    points,
                });
            }
        }
    }
    let texels = series.iter().flat_map(|s| s.points.iter().map(|p| p.0));
    let (lo, hi) = texels.fold((f64::INFINITY, 0.0f64), |(lo, hi), x| {
        (lo.min(x), hi.max(x))
    });
    if let Some(d) = at_own().find(|p| p.method == "direct") {
        if lo.is_finite() {
            series.push(Series {
                label: "direct (no textures)".into(),
                colour: colour("direct"),
                corner: false,
                points: vec![(lo, d.error_reconstruction), (hi, d.error_reconstruction)],
            });
        }
    }
    Curves {
        file: CURVE_FILES[1],
        title: format!(
            "{}: error against texture size, density {} ({} x {})",
            scene_name(report),
            own,
            report.width,
            report.height
        ),
        x_label: "level-0 texels of all textures (log)",
        y_label: "perceptual distance to the same solution's exact image (log)",
        series,
    }
}

/// Draws a curve plot: log axes with ticks inside the data, one line per series, circles or
/// triangles at its points. Points at zero error (exact) are left out: a log axis has no zero.
fn draw_curves<DB: DrawingBackend>(
    area: DrawingArea<DB, plotters::coord::Shift>,
    c: &Curves,
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| Error::Runtime(format!("plotting: {e:?}"));
    area.fill(&WHITE).map_err(err)?;
    let positive = |s: &Series| -> Vec<(f64, f64)> {
        s.points
            .iter()
            .copied()
            .filter(|&(x, y)| x > 0.0 && y > 0.0 && x.is_finite() && y.is_finite())
            .collect()
    };
    let all: Vec<(f64, f64)> = c.series.iter().flat_map(positive).collect();
    let x = log_range(all.iter().map(|p| p.0));
    let y = log_range(all.iter().map(|p| p.1));
    let axes = Axes {
        title: &c.title,
        x_label: c.x_label,
        y_label: c.y_label,
    };
    let mut chart = log_chart(&area, &axes, &x, &y).map_err(err)?;
    for s in &c.series {
        let pts = positive(s);
        if pts.is_empty() {
            continue;
        }
        let col = s.colour;
        let width = if s.corner { 1 } else { 2 };
        chart
            .draw_series(LineSeries::new(
                pts.iter().copied(),
                col.stroke_width(width),
            ))
            .map_err(err)?;
        let corner = s.corner;
        let markers = pts.iter().map(move |&xy| -> DynElement<DB, (f64, f64)> {
            if corner {
                TriangleMarker::new(xy, 6, col.filled()).into_dyn()
            } else {
                Circle::new(xy, 5, col.filled()).into_dyn()
            }
        });
        chart
            .draw_series(markers)
            .map_err(err)?
            .label(&s.label)
            .legend(move |(x, y)| -> DynElement<DB, (i32, i32)> {
                if corner {
                    TriangleMarker::new((x + 10, y), 6, col.filled()).into_dyn()
                } else {
                    Circle::new((x + 10, y), 5, col.filled()).into_dyn()
                }
            });
    }
    legend(&mut chart, 14, legend_corner(&all, &x, &y)).map_err(err)?;
    area.present().map_err(err)?;
    Ok(())
}

/// The corner of the plot where the legend hides the fewest points: each corner's box (the
/// outer 40 % of the width, 45 % of the height, in log coordinates) is counted.
fn legend_corner(
    points: &[(f64, f64)],
    x: &std::ops::Range<f64>,
    y: &std::ops::Range<f64>,
) -> SeriesLabelPosition {
    let unit =
        |v: f64, r: &std::ops::Range<f64>| (v.ln() - r.start.ln()) / (r.end.ln() - r.start.ln());
    let count = |right: bool, upper: bool| {
        points
            .iter()
            .filter(|&&(px, py)| {
                let (u, v) = (unit(px, x), unit(py, y));
                (if right { u > 0.6 } else { u < 0.4 }) && (if upper { v > 0.55 } else { v < 0.45 })
            })
            .count()
    };
    let corners = [
        (SeriesLabelPosition::UpperRight, count(true, true)),
        (SeriesLabelPosition::UpperLeft, count(false, true)),
        (SeriesLabelPosition::LowerRight, count(true, false)),
        (SeriesLabelPosition::LowerLeft, count(false, false)),
    ];
    // The first of the emptiest, so equal counts keep the upper right.
    let least = corners.iter().map(|c| c.1).min().unwrap_or(0);
    corners
        .into_iter()
        .find(|c| c.1 == least)
        .map_or(SeriesLabelPosition::UpperRight, |c| c.0)
}

/// Encodes plotters' RGB buffer as PNG.
fn png_of(rgb: Vec<u8>) -> Result<Vec<u8>> {
    let (w, h) = PLOT_SIZE;
    imageio::write::srgb_png_bytes(w, h, rgb)
}

/// Writes one plot as `dir/<stem>.png` (drawn by `png` into an RGB buffer of [`PLOT_SIZE`])
/// and `dir/<stem>.svg` (drawn by `svg`); returns both paths.
fn write_plot(
    outputs: &Outputs,
    dir: &Path,
    stem: &str,
    png: impl FnOnce(&mut [u8]) -> Result<()>,
    svg: impl FnOnce(&mut String) -> Result<()>,
) -> Result<[PathBuf; 2]> {
    let (w, h) = PLOT_SIZE;
    let mut rgb = vec![0u8; w as usize * h as usize * 3];
    png(&mut rgb)?;
    let png_path = dir.join(format!("{stem}.png"));
    outputs.write_atomic(&png_path, &png_of(rgb)?)?;
    let mut text = String::new();
    svg(&mut text)?;
    let svg_path = dir.join(format!("{stem}.svg"));
    outputs.write_atomic(&svg_path, text.as_bytes())?;
    Ok([png_path, svg_path])
}

/// Writes `error-vs-time`, `error-vs-memory`, `error-vs-samples` and `error-vs-texture-size`,
/// each `.png` and `.svg`, for `report` into `dir` (created if missing). Returns the files
/// written.
pub fn sweep_plots(outputs: &Outputs, report: &SweepReport, dir: &Path) -> Result<Vec<PathBuf>> {
    font()?;
    let (w, h) = PLOT_SIZE;
    let mut written = Vec::new();
    for cost in [Cost::Time, Cost::Bytes] {
        written.extend(write_plot(
            outputs,
            dir,
            cost.file(),
            |rgb| {
                draw(
                    BitMapBackend::with_buffer(rgb, (w, h)).into_drawing_area(),
                    report,
                    cost,
                )
            },
            |svg| {
                draw(
                    SVGBackend::with_string(svg, (w, h)).into_drawing_area(),
                    report,
                    cost,
                )
            },
        )?);
    }
    for curves in [samples_curves(report), texture_curves(report)] {
        written.extend(write_plot(
            outputs,
            dir,
            curves.file,
            |rgb| {
                draw_curves(
                    BitMapBackend::with_buffer(rgb, (w, h)).into_drawing_area(),
                    &curves,
                )
            },
            |svg| {
                draw_curves(
                    SVGBackend::with_string(svg, (w, h)).into_drawing_area(),
                    &curves,
                )
            },
        )?);
    }
    Ok(written)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_ticks_lie_inside_the_data() {
        // Several decades: 1-2-5.
        assert_eq!(log_ticks(&(0.3..30.0)), [0.5, 1.0, 2.0, 5.0, 10.0, 20.0]);
        // Within a decade: 1 to 9 when two of them fall inside.
        assert_eq!(log_ticks(&(1.3..3.6)), [2.0, 3.0]);
        // Narrower (the gallery's error axis, 1.3 to 2.6): 4 ticks evenly spaced in the log,
        // at 0.1 (a fifth of the range is 0.26).
        let t = log_ticks(&(1.3..2.6));
        assert_eq!(t.len(), 4);
        for (got, want) in t.iter().zip([1.5, 1.7, 2.0, 2.3]) {
            assert!((got - want).abs() < 1e-12, "{t:?}");
        }
        // Narrower still: at 0.01.
        let t = log_ticks(&(1.41..1.52));
        for (got, want) in t.iter().zip([1.43, 1.45, 1.48, 1.5]) {
            assert!((got - want).abs() < 1e-12, "{t:?}");
        }
        assert!(log_ticks(&(0.0..1.0)).is_empty());
    }

    #[test]
    fn the_legend_goes_where_the_points_are_not() {
        let (x, y) = (1.0..100.0, 1.0..100.0);
        // Crowded upper right: the upper left is free.
        let pts = [(90.0, 90.0), (80.0, 70.0), (2.0, 2.0)];
        assert!(matches!(
            legend_corner(&pts, &x, &y),
            SeriesLabelPosition::UpperLeft
        ));
        // Both upper corners taken: the lower right.
        let pts = [(90.0, 90.0), (1.5, 90.0), (1.5, 1.5)];
        assert!(matches!(
            legend_corner(&pts, &x, &y),
            SeriesLabelPosition::LowerRight
        ));
        // Nothing anywhere: the upper right.
        assert!(matches!(
            legend_corner(&[], &x, &y),
            SeriesLabelPosition::UpperRight
        ));
    }

    #[test]
    fn tick_labels_have_three_significant_digits() {
        assert_eq!(tick(0.30000000000000004), "0.3");
        assert_eq!(tick(0.1234), "0.123");
        assert_eq!(tick(2.0), "2");
        assert_eq!(tick(12.5), "12.5");
        assert_eq!(tick(150.0), "150");
        assert_eq!(tick(26339.0), "26.3K");
        assert_eq!(tick(2_855_597.0), "2.86M");
        assert_eq!(tick(4e9), "4G");
    }
}
