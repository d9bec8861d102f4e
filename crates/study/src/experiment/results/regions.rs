//! Where the error lies, on the results page: at the scene's own density, the solution's error
//! and every method's split by region ([`metric::regions`]: the emitters, a band around them,
//! near the sharp edges, the interior), as relative RMSE of luminance, with the findings (where each
//! term's squared error sits) computed from the same numbers.
//!
//! The solution error (its exact image against the truth) is the part every method shares; a
//! method's reconstruction error (against that exact image) is what its drawing adds; its
//! physics error (against the truth) is what a user sees. All three are split on the same
//! pixels: the regions of the converged exact image.

use super::*;
use crate::physics;
use metric::regions::{Region, RegionError, REGIONS};

/// The section, empty for a sweep without points at its own density.
pub(super) fn region_section(sw: &SweepReport) -> String {
    let own = sw.own_density;
    let points: Vec<&SweepPoint> = sw
        .methods()
        .into_iter()
        .filter_map(|m| {
            sw.points
                .iter()
                .filter(|p| p.density == own && p.method == m)
                .filter(|p| p.texture.is_none_or(|l| l.halvings == 0))
                .min_by(|a, b| a.reconstruction.rmse.total_cmp(&b.reconstruction.rmse))
        })
        .collect();
    let Some(first) = points.first() else {
        return String::new();
    };
    let pixels = first.regions.reconstruction.map(|e| e.pixels);
    let all: usize = pixels.iter().sum::<usize>().max(1);
    let solution = sw.densities.get(own).and_then(|d| d.solution_regions);
    let mut s = format!(
        "**Where the error lies** at the scene's own density ({own}): the luminance error split \
         by region, as RMSE over the region's mean exact luminance. The regions are those of the \
         converged exact image: the **emitters** (pixels showing an emitting polygon), the \
         **emitter band** (within {} px of them, not showing one), **edges** (within {} px of a \
         sharp edge of the light or a silhouette, outside the band) and the **interior** (the \
         rest). Each method's cell \
         is *physics error (reconstruction error)*, the textures at the quadtree-depth size and \
         the placement nearer the exact image; **solution** is the solution's exact image \
         against the truth, the part every method shares. The truth's noise is taken out of \
         the physics and solution figures per region, from the variance of its {} parts; where \
         that noise is not below the figure it corrects, the measured figure is given as its \
         bound (≤).\n\n",
        metric::regions::BAND_RADIUS,
        metric::edges::EDGE_RADIUS,
        physics::PARTS,
    );
    s += &format!(
        "| region | pixels | solution | {} |\n|---|---|---|{}\n",
        points
            .iter()
            .map(|p| p.method.as_str())
            .collect::<Vec<_>>()
            .join(" | "),
        "---|".repeat(points.len())
    );
    for (k, r) in Region::ALL.into_iter().enumerate() {
        s += &format!(
            "| {} | {:.1} % | {} |",
            r.name(),
            100.0 * pixels[k] as f64 / all as f64,
            solution.map_or("-".into(), |e| percent(&e[k]))
        );
        for p in &points {
            let phys = p.regions.physics.map_or("-".into(), |e| percent(&e[k]));
            s += &format!(" {phys} ({}) |", percent(&p.regions.reconstruction[k]));
        }
        s += "\n";
    }
    s + "\n" + &findings(&points, solution.as_ref()) + "\n\n"
}

/// A region's relative RMSE as a percentage; where the truth's noise there is not below the
/// corrected error, the measured one as its bound (`≤`), as the budget shows an unresolved
/// figure.
fn percent(e: &RegionError) -> String {
    if e.pixels == 0 {
        return "-".into();
    }
    if e.resolved() {
        format!("{:.2} %", 100.0 * e.relative_rmse())
    } else {
        format!("≤{:.2} %", 100.0 * e.relative_measured_rmse())
    }
}

/// Where each term's squared error mostly lies: the region with the largest share, and that
/// share, for the solution and for every method's reconstruction error.
fn findings(points: &[&SweepPoint], solution: Option<&[RegionError; REGIONS]>) -> String {
    let largest = |e: &[RegionError; REGIONS]| {
        let k = (0..REGIONS)
            .max_by(|&a, &b| e[a].share.total_cmp(&e[b].share))
            .unwrap_or(0);
        (Region::ALL[k].name(), 100.0 * e[k].share)
    };
    let methods: Vec<String> = points
        .iter()
        .map(|p| {
            let (r, share) = largest(&p.regions.reconstruction);
            if share > 0.0 {
                format!("{} {r} ({share:.0} %)", p.method)
            } else {
                format!("{} none (equal to the exact image)", p.method)
            }
        })
        .collect();
    let sol = match solution.map(largest) {
        Some((r, share)) if share > 0.0 => format!(
            "The solution's own error (against the truth, its noise taken out) has its largest \
             share of squared error in the {r} ({share:.0} %). "
        ),
        Some(_) => "The truth resolves no solution error in any region. ".into(),
        None => String::new(),
    };
    format!(
        "{sol}Each method's reconstruction error has its largest share of squared error in: {}.",
        methods.join(", ")
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::experiment::matched::tests::{point, report};

    /// The table has a row per region and a column per method, its pixel shares come from the
    /// points' split, and the finding names the region holding the largest share.
    #[test]
    fn the_region_table_and_its_finding_follow_the_numbers() {
        let e = |pixels, share, rmse| RegionError {
            pixels,
            share,
            rmse,
            reference_mean: 2.0,
            measured_rmse: rmse,
            noise_rmse: 0.0,
        };
        let mut a = point("direct", 1, 10, [1.0, 1.1], 0.2);
        a.regions.reconstruction = [
            e(2, 0.0, 0.0),
            e(8, 0.1, 0.02),
            e(30, 0.7, 0.04),
            e(60, 0.2, 0.01),
        ];
        let mut b = point("mesh", 1, 10, [1.0, 1.1], 0.3);
        b.regions.reconstruction = [
            e(2, 0.0, 0.0),
            e(8, 0.6, 0.2),
            e(30, 0.3, 0.05),
            e(60, 0.1, 0.01),
        ];
        let sw = report(vec![a, b]);
        let s = region_section(&sw);
        assert!(
            s.contains("| emitter band | 8.0 % | - | - (1.00 %) | - (10.00 %) |"),
            "{s}"
        );
        assert!(s.contains("| interior | 60.0 % |"), "{s}");
        assert!(
            s.contains("direct edges (70 %), mesh emitter band (60 %)"),
            "{s}"
        );
        assert!(!s.contains("solution's own error"), "{s}");
    }
}
