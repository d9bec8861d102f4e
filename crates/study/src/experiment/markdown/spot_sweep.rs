//! The spot-width sweep of `docs/experiments.md`: its table, the sensitivity of the figures'
//! ratios to the setting, and which spot width each figure's ratio fits or predicts, all computed
//! from the sweep's rows.

use super::*;

/// The sweep as a Markdown table.
pub fn sweep_markdown(rows: &[SweepRow]) -> String {
    let mut t = String::from(
        "| spot falloff | half angle | 10% radius / sample spacing | grid neighbours / peak | \
         fig5 bilinear | fig5 bicubic | fig5 direct | fig5 bicubic / bilinear | \
         fig6 centre bilinear | fig6 centre bicubic | fig6 centre bicubic / bilinear | \
         fig6 corner bilinear | fig6 corner bicubic | fig6 corner bicubic / bilinear | \
         fig6 clamped bilinear | fig6 clamped bicubic | fig6 clamped bicubic / bilinear | fig6 direct | \
         paper's ordering (bicubic < bilinear) | misfit to the paper (gutter / clamped) |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        let ok = |b: f64, l: f64| if b < l { "holds" } else { "fails" };
        t += &format!(
            "| {} | {:.1} | {:.2} | {:.2} % | {:.4} | {:.4} | {:.4} | {:.3} | {:.4} | {:.4} | {:.3} | \
             {:.4} | {:.4} | {:.3} | {:.4} | {:.4} | {:.3} | {:.4} | fig5 {}, fig6 centre {}, \
             corner {}, clamped {} | {:.3} / {:.3} |\n",
            r.falloff,
            r.half_angle_deg,
            r.radius_in_spacings,
            100.0 * r.neighbour_fraction,
            r.fig5.0,
            r.fig5.1,
            r.fig5.2,
            r.fig5.1 / r.fig5.0,
            r.fig6.0,
            r.fig6.1,
            r.fig6.1 / r.fig6.0,
            r.fig6_corner.0,
            r.fig6_corner.1,
            r.fig6_corner.1 / r.fig6_corner.0,
            r.fig6_clamp.0,
            r.fig6_clamp.1,
            r.fig6_clamp.1 / r.fig6_clamp.0,
            r.fig6.2,
            ok(r.fig5.1, r.fig5.0),
            ok(r.fig6.1, r.fig6.0),
            ok(r.fig6_corner.1, r.fig6_corner.0),
            ok(r.fig6_clamp.1, r.fig6_clamp.0),
            r.misfit,
            r.misfit_clamp,
        );
    }
    t
}

/// The spot sweep: how it is built, its table and its findings.
pub(super) fn sweep_section(r: &Results, fo: &FigureOptions) -> Result<String> {
    let mut t = format!(
        "## How wide must the spot be? A sweep\n\n\
         {} The sweep below reruns both figures (images not written) with the first spot's \
         falloff exponent varied, from narrow to wide; its cone is widened with it (to where \
         cos^falloff falls to 1e-6 of the axis, at most 89 deg, never narrower than the \
         scene's) so that only the spot's width changes, not its edge. `grid neighbours / \
         peak` is what the spot alone leaves one sample spacing from its peak.",
        own_spot(r, fo)?
    );
    if r.sweep.iter().any(|r| r.falloff == 60.0) {
        t += " The falloff-60 row is the hard case `scenes/two-spots-narrow.toml` (its 40 deg \
              cone cuts at 1e-7 of the peak, so widening it changes nothing measurable): a \
              spot narrower than the spacing, of which the 5 x 5 samples hold one spike and \
              nothing of its shape, so no reconstruction can recover it (`pixelflow-sim \
              experiment fig5 --scene scenes/two-spots-narrow.toml` draws its images).";
    }
    t += "\n\n";
    t += &sweep_markdown(&r.sweep);
    t += "\n";
    t += &sweep_findings(&r.sweep);
    t += "\n";
    Ok(t)
}

/// The figures on the shipped variants, with the spot moved and the viewer nearer and farther.
pub(super) fn sensitivity_section(r: &Results, fo: &FigureOptions) -> String {
    let mut t = format!(
        "## How much do the ratios depend on the setting?\n\n\
         The figures' scene is fitted to the paper by the spot's width alone (the sweep above). \
         Below, the same figures on the shipped variants of `{}`, with the bright spot moved \
         diagonally by a quarter and a half of the coarse sample spacing (its peak between \
         samples), and with the metric's viewing distance halved and doubled (pixels per \
         degree; {} by default). A ratio is bicubic / bilinear; `direct closest` means the \
         direct method's distance is the smallest of the figure's reconstructions (within 1e-4 \
         of the bicubic one in Fig. 5, which evaluates the same RRPs).\n\n\
         | varied | value | spot falloff | fig5 ratio | fig6 ratio, centre | fig6 ratio, corner \
         | fig6 ratio, clamped | direct closest | misfit to the paper (gutter / clamped) |\n\
         |---|---|---|---|---|---|---|---|---|\n",
        fo.scene.display(),
        fo.ppd
    );
    let line = |what: &str, value: &str, r: &SweepRow| {
        format!(
            "| {what} | {value} | {} | {:.3} | {:.3} | {:.3} | {:.3} | {} | {:.3} / {:.3} |\n",
            r.falloff,
            r.fig5.1 / r.fig5.0,
            r.fig6.1 / r.fig6.0,
            r.fig6_corner.1 / r.fig6_corner.0,
            ratio(r.fig6_clamp),
            if r.direct_closest() { "yes" } else { "no" },
            r.misfit,
            r.misfit_clamp
        )
    };
    let own_falloff = scene::load_scene(&fo.scene)
        .ok()
        .and_then(|s| s.spots.first().map(|s| s.falloff));
    if let Some(own) = r.sweep.iter().find(|row| Some(row.falloff) == own_falloff) {
        t += &line("(the figures' scene)", &fo.scene.display().to_string(), own);
    }
    for s in &r.sensitivity {
        t += &line(&s.parameter, &s.value, &s.row);
    }
    let fig5_range = |what: &str| {
        let v: Vec<f64> = r
            .sensitivity
            .iter()
            .filter(|s| s.parameter == what)
            .map(|s| s.row.fig5.1 / s.row.fig5.0)
            .collect();
        let lo = v.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        format!("{lo:.3}-{hi:.3}")
    };
    t += &format!(
        "\nThe paper's ratios: {:.3} (Fig. 5) and {:.3} (Fig. 6). Moving the spot moves the \
         Fig. 5 ratio to {}; changing the viewing distance to {}.\n\n",
        super::super::PAPER_FIG5.0 / super::super::PAPER_FIG5.1,
        super::super::PAPER_FIG6.0 / super::super::PAPER_FIG6.1,
        fig5_range("spot shift"),
        fig5_range("pixels per degree"),
    );
    t
}

/// A sentence on the scene's own bright spot, from its sweep row.
pub(super) fn own_spot(r: &Results, fo: &FigureOptions) -> Result<String> {
    let scene = scene::load_scene(&fo.scene)?;
    let own = scene.spots.first().map(|s| s.falloff);
    Ok(match r.sweep.iter().find(|row| Some(row.falloff) == own) {
        Some(row) => format!(
            "The bright spot of `{}` (falloff {}) has a 10 % radius of {:.2} sample spacings of \
             the coarse grid, and its four grid neighbours hold {:.0} % of its peak: {}.",
            fo.scene.display(),
            row.falloff,
            row.radius_in_spacings,
            100.0 * row.neighbour_fraction,
            if row.radius_in_spacings >= 0.9 {
                "the coarse grid resolves it"
            } else {
                "the spot lies between the coarse grid's samples"
            }
        ),
        None => format!("The figures above use `{}`.", fo.scene.display()),
    })
}

/// Falloffs of the sweep rows for which `fails` holds, as text ("none" when there are none).
pub(super) fn falloffs_where(rows: &[SweepRow], fails: impl Fn(&SweepRow) -> bool) -> String {
    let v: Vec<String> = rows
        .iter()
        .filter(|r| fails(r))
        .map(|r| format!("{} ({:.2} spacings)", r.falloff, r.radius_in_spacings))
        .collect();
    if v.is_empty() {
        "none".into()
    } else {
        v.join(", ")
    }
}

/// What the sweep shows, computed from its rows.
pub(super) fn sweep_findings(rows: &[SweepRow]) -> String {
    let mut t = String::new();
    t += &format!(
        "- Fig. 5's ordering (bicubic < bilinear) fails at falloff {}; Fig. 6's with centre \
         texels fails at {}; with corner texels at {}; clamped to the edge at {}. (Falloff, \
         then the 10 % radius in sample spacings.)\n",
        falloffs_where(rows, |r| r.fig5.1 >= r.fig5.0),
        falloffs_where(rows, |r| r.fig6.1 >= r.fig6.0),
        falloffs_where(rows, |r| r.fig6_corner.1 >= r.fig6_corner.0),
        falloffs_where(rows, |r| r.fig6_clamp.1 >= r.fig6_clamp.0)
    );
    let resolved: Vec<&SweepRow> = rows
        .iter()
        .filter(|r| r.radius_in_spacings >= 1.0)
        .collect();
    if !resolved.is_empty() {
        let range = |f: &dyn Fn(&SweepRow) -> f64| {
            let v: Vec<f64> = resolved.iter().map(|r| f(r)).collect();
            (
                v.iter().copied().fold(f64::INFINITY, f64::min),
                v.iter().copied().fold(f64::NEG_INFINITY, f64::max),
            )
        };
        let a = range(&|r| r.fig5.1 / r.fig5.0);
        let b = range(&|r| r.fig6.1 / r.fig6.0);
        let c = range(&|r| r.fig6_corner.1 / r.fig6_corner.0);
        let e = range(&|r| r.fig6_clamp.1 / r.fig6_clamp.0);
        t += &format!(
            "- Where the 10 % radius is at least one spacing, bicubic / bilinear is {:.3}-{:.3} in \
             Fig. 5, {:.3}-{:.3} in Fig. 6 with centre texels, {:.3}-{:.3} with corner texels \
             and {:.3}-{:.3} clamped to the edge (the paper: {:.3} and {:.3}).\n",
            a.0,
            a.1,
            b.0,
            b.1,
            c.0,
            c.1,
            e.0,
            e.1,
            super::super::PAPER_FIG5.0 / super::super::PAPER_FIG5.1,
            super::super::PAPER_FIG6.0 / super::super::PAPER_FIG6.1
        );
    }
    t += &format!(
        "- The direct method is the closest to the reference in both figures (within rounding of \
         the bicubic reconstruction in Fig. 5, which evaluates the same RRPs) at every falloff \
         except {}.\n",
        falloffs_where(rows, |r| !r.direct_closest())
    );
    if let Some(best) = rows
        .iter()
        .filter(|r| r.misfit.is_finite())
        .min_by(|a, b| a.misfit.total_cmp(&b.misfit))
    {
        t += &format!(
            "- The paper's four distances (Fig. 5 and Fig. 6, bicubic and bilinear) are matched \
             best, up to one common scale, at falloff {} (misfit {:.3}: the log-rms of ours over \
             the paper's after removing their mean; the ratios there {:.3} and {:.3}, the \
             paper's {:.3} and {:.3}).\n",
            best.falloff,
            best.misfit,
            best.fig5.1 / best.fig5.0,
            best.fig6.1 / best.fig6.0,
            super::super::PAPER_FIG5.0 / super::super::PAPER_FIG5.1,
            super::super::PAPER_FIG6.0 / super::super::PAPER_FIG6.1
        );
    }
    t + &prediction_findings(rows)
}

/// The ratio bicubic / bilinear of a (bilinear, bicubic) pair.
pub(super) fn ratio(d: (f64, f64)) -> f64 {
    d.1 / d.0
}

/// The row whose `ratio_of` is nearest `target` (in log terms), among finite ones.
pub(super) fn fitted(
    rows: &[SweepRow],
    ratio_of: fn(&SweepRow) -> f64,
    target: f64,
) -> Option<&SweepRow> {
    rows.iter()
        .filter(|r| ratio_of(r).is_finite() && ratio_of(r) > 0.0)
        .min_by(|a, b| {
            let off = |r: &SweepRow| (ratio_of(r) / target).ln().abs();
            off(a).total_cmp(&off(b))
        })
}

/// The figures as prediction: the one free parameter (the spot's falloff) fitted to one
/// figure's ratio, the other figure's ratio read at that falloff, both ways, with Fig. 6 drawn
/// as the paper's hardware drew it (clamp to edge) and, beside it, with the gutters.
pub(super) fn prediction_findings(rows: &[SweepRow]) -> String {
    let (p5, p6) = (
        super::super::PAPER_FIG5.0 / super::super::PAPER_FIG5.1,
        super::super::PAPER_FIG6.0 / super::super::PAPER_FIG6.1,
    );
    let mut t = String::new();
    if let Some(best) = rows
        .iter()
        .filter(|r| r.misfit_clamp.is_finite())
        .min_by(|a, b| a.misfit_clamp.total_cmp(&b.misfit_clamp))
    {
        t += &format!(
            "- With Fig. 6 clamped to the edge, the four distances are matched best at falloff \
             {} (misfit {:.3}; the ratios there {:.3} and {:.3}).\n",
            best.falloff,
            best.misfit_clamp,
            ratio((best.fig5.0, best.fig5.1)),
            ratio(best.fig6_clamp)
        );
    }
    let on5 = fitted(rows, |r| ratio((r.fig5.0, r.fig5.1)), p5);
    let on6 = fitted(rows, |r| ratio(r.fig6_clamp), p6);
    if let (Some(a), Some(b)) = (on5, on6) {
        t += &format!(
            "- **Fitted on one figure, the other predicted.** The spot's falloff is the one \
             parameter, fitted as the sweep's falloff whose ratio is nearest the paper's (no \
             interpolation between falloffs). Fitted on Fig. 5 (ratio {:.3} at falloff {}, the \
             paper {:.3}), Fig. 6 is predicted at {:.3} clamped to the edge ({:.3} with the \
             gutters) against the paper's {:.3}. Fitted on Fig. 6 clamped to the edge (ratio \
             {:.3} at falloff {}, the paper {:.3}), Fig. 5 is predicted at {:.3} against the \
             paper's {:.3}.\n",
            ratio((a.fig5.0, a.fig5.1)),
            a.falloff,
            p5,
            ratio(a.fig6_clamp),
            ratio((a.fig6.0, a.fig6.1)),
            p6,
            ratio(b.fig6_clamp),
            b.falloff,
            p6,
            ratio((b.fig5.0, b.fig5.1)),
            p5
        );
    }
    t
}
