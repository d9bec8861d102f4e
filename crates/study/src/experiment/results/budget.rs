//! The error budget against physics on the results page: per density the solution's error and
//! every method's physics and reconstruction error, which term dominates, which method is nearer
//! the light at the scene's own density, and what the solver's seed changes. Every comparison is
//! called only where its 95 % interval (the jackknife over the truth's independent parts,
//! [`Interval`]) excludes 0, and stated as a tie otherwise: the truth's noise alone moves a
//! figure by a few hundredths, more than some differences between methods.

use super::*;
use crate::physics::{Interval, PhysicsErrors, Sign};

/// The error budget against the path-traced truth: per density, the solution's error and every
/// method's physics and reconstruction error (the textures at the quadtree-depth size, the
/// placement nearer the truth), then which term dominates. Empty without a truth image.
pub(super) fn budget_section(sw: &SweepReport) -> String {
    let Some(t) = &sw.truth else {
        return String::new();
    };
    let methods = sw.methods();
    let mut s = format!(
        "**Error budget against physics** (perceptual distance; truth: {} samples per pixel, its \
         noise {:.3} taken out in quadrature, see [sweep.md](sweep.md#error-budget)). Each cell \
         is *physics error (reconstruction error)*; the solution error is the same solution's \
         exact image against the truth, with its 95 % interval from the truth's {} independent \
         parts (the jackknife, see [sweep.md](sweep.md#error-budget)). A value marked ≤ is within \
         the truth's noise: the \
         correction does not resolve it, so the measured distance is given as its bound and no \
         comparison is made on it. Converged reference (tolerance {}): solution error {}.\n\n",
        t.samples_per_pixel,
        t.perceptual,
        t.parts,
        sw.reference.tolerance,
        sw.reference
            .solution
            .map_or("-".into(), |e| e.perceptual_text(3)),
    );
    s += &format!(
        "| density | tolerance | solution error | {} |\n",
        methods.join(" | ")
    );
    s += &format!("|---|---|---|{}\n", "---|".repeat(methods.len()));
    for (level, d) in sw.densities.iter().enumerate() {
        let sol = d.solution.map_or("-".into(), |e| with_interval(&e));
        s += &format!("| {level} | {} | {sol} |", d.tolerance);
        for m in &methods {
            let best = sw
                .points
                .iter()
                .filter(|p| p.density == level && p.method == *m)
                .filter(|p| p.texture.is_none_or(|l| l.halvings == 0))
                .min_by(|a, b| physics_of(a).total_cmp(&physics_of(b)));
            s += &match best {
                Some(p) => format!(
                    " {} ({:.3}) |",
                    p.physics.map_or("-".into(), |e| e.perceptual_text(3)),
                    p.error_reconstruction
                ),
                None => " - |".into(),
            };
        }
        s += "\n";
    }
    s + "\n" + &budget_finding(sw) + "\n\n" + &closer_section(sw) + &seed_line(sw)
}

/// A point's physics error (infinite without one, so it sorts last).
fn physics_of(p: &SweepPoint) -> f64 {
    p.error_physics.unwrap_or(f64::INFINITY)
}

/// A resolved figure with its 95 % interval; an unresolved one as its bound.
fn with_interval(e: &PhysicsErrors) -> String {
    if !e.resolved {
        return e.perceptual_text(3);
    }
    let i = Interval::own(e);
    format!("{:.3} ({:.3}-{:.3})", e.perceptual, i.low.max(0.0), i.high)
}

/// Which term of the budget dominates: at how many points (every method, density and texture
/// size) the solution error exceeds the reconstruction error beyond the truth's interval, at
/// how many it falls short of it, and how many are ties; per method as well.
fn budget_finding(sw: &SweepReport) -> String {
    // Only resolved solution errors are compared (see `PhysicsErrors::resolved`).
    let solution = |p: &SweepPoint| {
        sw.densities
            .get(p.density)
            .and_then(|d| d.solution)
            .filter(|e| e.resolved)
    };
    let mut by_method = Vec::new();
    let mut total = [0usize; 3];
    for m in sw.methods() {
        let mut n = [0usize; 3];
        for p in sw.points.iter().filter(|p| p.method == m) {
            if let Some(e) = solution(p) {
                n[match Interval::above(&e, p.error_reconstruction).sign() {
                    Sign::Positive => 0,
                    Sign::Negative => 1,
                    Sign::Tie => 2,
                }] += 1;
            }
        }
        by_method.push(format!("{m} {}/{}/{}", n[0], n[1], n[2]));
        (0..3).for_each(|i| total[i] += n[i]);
    }
    let [sol, recon, ties] = total;
    let all = sol + recon + ties;
    if all == 0 {
        let noise = sw.truth.as_ref().map_or(0.0, |t| t.perceptual);
        return format!(
            "The truth's noise ({noise:.3}) is larger than the solution error at every point, so \
             this budget cannot tell which term dominates; a truth with more samples per pixel \
             (`--truth-samples`) would."
        );
    }
    let verdict = if sol == 0 && ties == 0 {
        "The reconstruction error dominates everywhere: at this image size every method's \
         distance from the light is mostly how it draws the solution, not the solution."
    } else if recon == 0 && ties == 0 {
        "The solution error dominates everywhere: a better reconstruction cannot bring these \
         images nearer the light; only a better solution can."
    } else {
        "Where the solution error is the larger, a better reconstruction cannot bring the image \
         nearer the light; only a better solution can. A tie is a point where the truth cannot \
         tell the two terms apart."
    };
    format!(
        "Where the truth resolves the solution error ({all} points: every density and texture \
         size), it is the larger term at {sol}, the reconstruction error at {recon}, and {ties} \
         are ties (the difference's 95 % interval holds 0); per method, solution larger / \
         reconstruction larger / tie: {}. {verdict}",
        by_method.join(", ")
    )
}

/// Which method is nearer the light at the scene's own density (each method's point with the
/// least physics error, the textures at the quadtree-depth size): every pair, by the difference
/// of their squared distances from the truth, called only where its 95 % interval, paired over
/// the truth's parts, excludes 0. That difference needs neither distance resolved
/// ([`Interval::squares`]), so methods are ranked where the truth's noise hides the figures
/// themselves.
fn closer_section(sw: &SweepReport) -> String {
    let own = sw.own_density;
    let best: Vec<(&str, PhysicsErrors)> = sw
        .methods()
        .into_iter()
        .filter_map(|m| {
            let e = sw
                .points
                .iter()
                .filter(|p| p.density == own && p.method == m)
                .filter(|p| p.texture.is_none_or(|l| l.halvings == 0))
                .filter_map(|p| p.physics)
                .min_by(|a, b| a.perceptual_measured.total_cmp(&b.perceptual_measured))?;
            Some((m, e))
        })
        .collect();
    if best.len() < 2 {
        return String::new();
    }
    let mut s = format!(
        "**Which method is nearer the light** at the scene's own density ({own}), each method's \
         point nearest the truth (textures at the quadtree-depth size): the difference of the \
         two images' squared distances from the truth, with its 95 % interval, called only \
         where the interval excludes 0. The truth's noise adds the same power to both squares, \
         so their difference is the difference from the light itself, and it is resolved even \
         where the distances are not (see [sweep.md](sweep.md#error-budget)).\n\n\
         | pair | physics errors | difference of squares (95 % interval) | nearer the light |\n\
         |---|---|---|---|\n"
    );
    let (mut called, mut pairs) = (0, 0);
    for (i, (a, ea)) in best.iter().enumerate() {
        for (b, eb) in &best[i + 1..] {
            let d = Interval::squares(ea, eb);
            let verdict = match d.sign() {
                Sign::Negative => a.to_string(),
                Sign::Positive => b.to_string(),
                Sign::Tie => "tie".to_string(),
            };
            called += usize::from(d.sign() != Sign::Tie);
            pairs += 1;
            s += &format!(
                "| {a} / {b} | {} / {} | {:+.4} ({:+.4} to {:+.4}) | {verdict} |\n",
                ea.perceptual_text(3),
                eb.perceptual_text(3),
                d.value,
                d.low,
                d.high
            );
        }
    }
    s + &if called == pairs {
        format!("\nAll {pairs} pairs are called.\n\n")
    } else {
        format!("\n{called} of {pairs} pairs are called; the rest are ties.\n\n")
    }
}

/// What the solver's seed changes at the scene's own density.
fn seed_line(sw: &SweepReport) -> String {
    let Some(c) = &sw.solver_seed else {
        return String::new();
    };
    let [first, second] = c.seeds;
    if c.same_image {
        return format!(
            "**Solver seed.** Solved again with seed {second}, the own density's solution draws \
             the same image bits as with seed {first} ({} shadow rays cast: every visibility \
             query was exact), so the seed adds nothing to the intervals above.\n\n",
            c.rays
        );
    }
    let own = sw.densities.get(sw.own_density).and_then(|d| d.solution);
    let change = match (own, c.solution) {
        (Some(a), Some(b)) if a.resolved && b.resolved => {
            let d = Interval::difference(&b, &a);
            format!(
                "; its solution error is {:.3} against {:.3}, a difference of {:+.3} ({:+.3} to \
                 {:+.3}), {}",
                b.perceptual,
                a.perceptual,
                d.value,
                d.low,
                d.high,
                if d.sign() != Sign::Tie {
                    "beyond the truth's noise: the intervals above, which hold the truth's noise \
                     alone, are too narrow for differences of solution errors by about this much"
                } else {
                    "within the truth's noise"
                }
            )
        }
        _ => String::new(),
    };
    format!(
        "**Solver seed.** Solved again with seed {second} ({} shadow rays cast), the own density's \
         exact image is {:.3} from seed {first}'s (perceptual distance){change}. Every method at a \
         density draws the same solution, so the seed moves their physics errors together.\n\n",
        c.rays, c.distance
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::experiment::matched::tests::{point, report};
    use crate::physics::PARTS;
    use crate::sweep::SeedCheck;

    /// A resolved physics error `value` whose replicates are `value + noise[k]` (the measured
    /// ones alike: no noise taken out).
    fn physics(value: f64, noise: [f64; PARTS]) -> PhysicsErrors {
        PhysicsErrors {
            perceptual: value,
            rmse: 0.0,
            perceptual_measured: value,
            rmse_measured: 0.0,
            resolved: true,
            replicates: noise.map(|n| value + n),
            measured_replicates: noise.map(|n| value + n),
        }
    }

    /// Replicates 0.01 either side: a 95 % interval of +-2.36 x 0.0265 = +-0.063.
    const SPREAD: [f64; PARTS] = [0.01, -0.01, 0.01, -0.01, 0.01, -0.01, 0.01, -0.01];

    #[test]
    fn a_term_is_called_larger_only_beyond_its_interval() {
        let mut sw = report(vec![
            point("direct", 0, 1, [1.0, 1.0], 0.3), // 0.5 +- 0.063 above: solution larger
            point("mesh", 0, 1, [1.0, 1.0], 0.7),   // below: reconstruction larger
            point("mesh", 0, 1, [1.0, 1.0], 0.45),  // within: a tie
        ]);
        let mut level = sw.reference;
        level.solution = Some(physics(0.5, SPREAD));
        sw.densities = vec![level];
        let text = budget_finding(&sw);
        assert!(
            text.contains(
                "it is the larger term at 1, the reconstruction error at 1, and 1 are ties"
            ),
            "{text}"
        );
        assert!(text.contains("direct 1/0/0, mesh 0/1/1"), "{text}");
        assert_eq!(with_interval(&physics(0.5, SPREAD)), "0.500 (0.437-0.563)");
    }

    #[test]
    fn a_method_is_nearer_the_light_only_where_the_paired_interval_excludes_zero() {
        let mut sw = report(vec![
            point("direct", 1, 1, [1.0, 1.0], 0.1),
            point("mesh", 1, 1, [1.0, 1.0], 0.1),
            point("texture-bilinear", 1, 1, [1.0, 1.0], 0.1),
        ]);
        let against = [
            // Shares the truth's noise with direct: 0.02 apart beyond doubt.
            ("direct", physics(0.40, SPREAD)),
            ("mesh", physics(0.42, SPREAD)),
            // The opposite noise: 0.01 from direct, a tie.
            ("texture-bilinear", physics(0.41, SPREAD.map(|n| -n))),
        ];
        for (p, (_, e)) in sw.points.iter_mut().zip(against) {
            p.physics = Some(e);
            p.error_physics = Some(e.perceptual);
        }
        let text = closer_section(&sw);
        // 0.40^2 - 0.42^2 = -0.0164; the replicates' differ by -0.0164 +- 0.0004, a standard
        // error of 0.00106 and a half width of 0.0025.
        assert!(
            text.contains(
                "| direct / mesh | 0.400 / 0.420 | -0.0164 (-0.0189 to -0.0139) | direct |"
            ),
            "{text}"
        );
        assert!(
            text.contains("| direct / texture-bilinear | 0.400 / 0.410 | -0.0081"),
            "{text}"
        );
        assert!(text.contains("| tie |"), "{text}");
        assert!(text.contains("1 of 3 pairs are called"), "{text}");
    }

    #[test]
    fn a_seed_that_changes_nothing_is_said_to() {
        let mut sw = report(Vec::new());
        sw.solver_seed = Some(SeedCheck {
            seeds: [1, 2],
            rays: 0,
            same_image: true,
            distance: 0.0,
            solution: None,
        });
        assert!(seed_line(&sw).contains("the same image bits as with seed 1"));
        sw.solver_seed.as_mut().unwrap().same_image = false;
        sw.solver_seed.as_mut().unwrap().distance = 0.25;
        assert!(seed_line(&sw).contains("is 0.250 from seed 1's"));
    }
}
