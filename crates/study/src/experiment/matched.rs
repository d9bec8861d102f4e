//! The paper's Table 1 at matched error. The paper compared its mesh, RAT and RRP models at
//! whatever error each had; here every method is taken at the point of the sweep where it is as
//! accurate as the direct method at the scene's own density, and its geometry, frame rate and
//! memory are read there. Accuracy is the physics error (against the path tracer) when the sweep
//! has a truth image, else the total error (against the converged solution, a consistency
//! check); "as accurate" is within [`MATCH_SLACK`] of the direct method's error.
//!
//! Invariant: every number is a sweep point's; a method that reaches the target nowhere is
//! shown at its most accurate point and said so; a speed comparison is stated only where the
//! confidence intervals of the two frame times do not overlap.

use crate::sweep::{SweepPoint, SweepReport};

/// How much above the direct method's error a point may be and still match it.
pub const MATCH_SLACK: f64 = 1.1;

/// The error the matching uses for one sweep: the physics error where the truth resolves it at
/// every point (an unresolved one is within the truth's noise, and matching on it would rank
/// noise), else the total error for all of them, so that one scene's rows share one measure.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Measure {
    /// Every point's physics error, all resolved.
    Physics,
    /// Every point's total error.
    Total,
}

impl Measure {
    /// The measure of `sw`, decided once over all its points.
    fn of(sw: &SweepReport) -> Measure {
        let resolved = sw
            .points
            .iter()
            .all(|q| q.physics.is_some_and(|e| e.resolved));
        if resolved {
            Measure::Physics
        } else {
            Measure::Total
        }
    }

    /// Point `p`'s error in this measure.
    fn error(self, p: &SweepPoint) -> f64 {
        match (self, p.physics) {
            (Measure::Physics, Some(e)) => e.perceptual,
            _ => p.error_total,
        }
    }
}

/// One method at matched error.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Matched<'a> {
    /// The point chosen.
    pub point: &'a SweepPoint,
    /// Whether it is within [`MATCH_SLACK`] of the target (else it is the method's most accurate).
    pub reached: bool,
}

/// The direct method's point at the scene's own density: the target.
pub fn target(sw: &SweepReport) -> Option<&SweepPoint> {
    sw.points
        .iter()
        .find(|p| p.method == "direct" && p.density == sw.own_density)
}

/// For `method`, the point with the fewest stored bytes (then the fastest) among those within
/// [`MATCH_SLACK`] of `target_error`; else its most accurate point.
pub fn matched<'a>(sw: &'a SweepReport, method: &str, target_error: f64) -> Option<Matched<'a>> {
    let measure = Measure::of(sw);
    let of_method = || sw.points.iter().filter(move |p| p.method == method);
    let within = of_method()
        .filter(|p| measure.error(p) <= target_error * MATCH_SLACK)
        .min_by(|a, b| {
            a.bytes
                .cmp(&b.bytes)
                .then(a.frame_ms.total_cmp(&b.frame_ms))
        });
    match within {
        Some(point) => Some(Matched {
            point,
            reached: true,
        }),
        None => of_method()
            .min_by(|a, b| measure.error(a).total_cmp(&measure.error(b)))
            .map(|point| Matched {
                point,
                reached: false,
            }),
    }
}

/// Frames per second of a point, with the interval of its frame time turned into rates.
fn fps(p: &SweepPoint) -> String {
    let rate = app::rates::fps;
    format!(
        "{:.0} ({:.0}-{:.0})",
        rate(p.frame_ms),
        rate(p.frame_ms_interval[1]),
        rate(p.frame_ms_interval[0])
    )
}

/// How `a` compares with `b` in speed: faster or slower where the intervals are apart, else
/// no claim.
pub fn speed_words(a: &SweepPoint, b: &SweepPoint) -> &'static str {
    if a.frame_ms_interval[1] < b.frame_ms_interval[0] {
        "faster than"
    } else if b.frame_ms_interval[1] < a.frame_ms_interval[0] {
        "slower than"
    } else {
        "not distinguishable in speed (intervals overlap) from"
    }
}

/// The section: per scene, one row per method at matched error, then the speed findings.
pub fn section(scenes: &[(&str, &SweepReport)]) -> String {
    let mut s = String::from("## Table 1 at matched error\n\n");
    s += &format!(
        "The paper's Table 1 compares its models at whatever error each had. Here each method \
         is read where it is as accurate as the direct method at the scene's own density \
         (within {:.0} %): the sweep point with the fewest bytes stored among those (over every \
         density, texture size and placement), or, when none is, its most accurate point \
         (*not reached*). Accuracy is the physics error (against the path tracer) where the truth \
         resolves it at every point of the scene's sweep, else the total error. Triangles and vertices are what the method \
         draws (the mesh's, or the original polygons with their own corners); frames per \
         second at the sweep's image size, with the confidence interval of the frame time.\n\n",
        100.0 * (MATCH_SLACK - 1.0)
    );
    s += "| scene | method | point | error (target) | triangles | vertices | fps (interval) | \
          texture bytes | bytes stored | bytes held drawing |\n\
          |---|---|---|---|---|---|---|---|---|---|\n";
    let mut findings = Vec::new();
    for (name, sw) in scenes {
        let Some(t) = target(sw) else { continue };
        let measure = Measure::of(sw);
        let target_error = measure.error(t);
        // The direct method at matched error (its cheapest point as accurate as the target).
        let direct = matched(sw, "direct", target_error).map_or(t, |d| d.point);
        for m in sw.methods() {
            let Some(mt) = matched(sw, m, target_error) else {
                continue;
            };
            let p = mt.point;
            s += &format!(
                "| {} | {} | density {}, {} | {:.3} ({:.3}){} | {} | {} | {} | {} | {} | {} |\n",
                name,
                m,
                p.density,
                super::labels::texture_label(p),
                measure.error(p),
                target_error,
                if mt.reached { "" } else { " *not reached*" },
                app::report::grouped(p.triangles),
                app::report::grouped(p.vertices),
                fps(p),
                p.texture.map_or("-".into(), |_| super::labels::mb(p.bytes)),
                super::labels::mb(p.bytes),
                super::labels::mb(p.working_bytes),
            );
            if m != "direct" && mt.reached {
                findings.push(format!(
                    "on {name}, direct is {} {m}",
                    speed_words(direct, p)
                ));
            }
        }
    }
    if !findings.is_empty() {
        s += &format!(
            "\nSpeed at matched error, each method's row against the direct method's (a claim \
             only where the frame-time intervals are apart): {}.\n",
            findings.join("; ")
        );
    }
    s + "\n"
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::sweep::{Errors, RegionSplit, Timing};
    use metric::regions::RegionError;

    /// A point of a test sweep: its method, density, bytes, frame-time interval and error
    /// (every error measure alike); no physics error.
    pub(crate) fn point(
        method: &str,
        density: usize,
        bytes: u64,
        ms: [f64; 2],
        error: f64,
    ) -> SweepPoint {
        let e = Errors {
            perceptual: error,
            rmse: 0.0,
            max_abs: 0.0,
            mach_band: 0.0,
            relative_rmse: 0.0,
            near_edges_share: 0.0,
        };
        SweepPoint {
            method: method.into(),
            density,
            tolerance: 0.01,
            samples: 100,
            texture: None,
            frame_ms: 0.5 * (ms[0] + ms[1]),
            frame_ms_interval: ms,
            triangles: 2,
            vertices: 4,
            bytes,
            working_bytes: bytes,
            error_reconstruction: error,
            error_total: error,
            reconstruction: e,
            total: e,
            error_physics: None,
            physics: None,
            regions: RegionSplit {
                reconstruction: [RegionError {
                    pixels: 1,
                    share: 0.25,
                    rmse: 0.0,
                    reference_mean: 1.0,
                    measured_rmse: 0.0,
                    noise_rmse: 0.0,
                }; metric::regions::REGIONS],
                physics: None,
            },
            pareto_time: false,
            pareto_memory: false,
        }
    }

    /// A test sweep of `points`: own density 1, no densities, no truth.
    pub(crate) fn report(points: Vec<SweepPoint>) -> SweepReport {
        SweepReport {
            scene: "x.toml".into(),
            width: 8,
            height: 8,
            threads: 1,
            sharp_levels: 3,
            densities: Vec::new(),
            reference: crate::sweep::SolutionLevel {
                tolerance: 0.01,
                max_depth: 4,
                samples: 1,
                solution: None,
                solution_regions: None,
                converged: None,
            },
            truth: None,
            solver_seed: None,
            points,
            equal_error: None,
            timing: Timing {
                processes: 6,
                samples: 6,
                coverage: 0.96875,
                load: Vec::new(),
            },
            own_density: 1,
            equal_views: Vec::new(),
        }
    }

    #[test]
    fn the_cheapest_point_within_the_slack_is_chosen() {
        let sw = report(vec![
            point("direct", 1, 100, [1.0, 2.0], 1.0),
            point("mesh", 0, 10, [5.0, 6.0], 2.0),  // too wrong
            point("mesh", 1, 50, [5.0, 6.0], 1.09), // within 10 %: cheapest that matches
            point("mesh", 2, 80, [5.0, 6.0], 0.5),
        ]);
        let t = target(&sw).unwrap();
        let m = matched(&sw, "mesh", Measure::of(&sw).error(t)).unwrap();
        assert!(m.reached);
        assert_eq!(m.point.bytes, 50);
        assert_eq!(speed_words(t, m.point), "faster than");
        assert_eq!(speed_words(m.point, t), "slower than");
    }

    #[test]
    fn an_unreached_target_gives_the_most_accurate_point() {
        let sw = report(vec![
            point("direct", 1, 100, [1.0, 2.0], 1.0),
            point("texture-bilinear", 1, 10, [1.5, 2.5], 3.0),
            point("texture-bilinear", 1, 20, [1.5, 2.5], 2.0),
        ]);
        let m = matched(&sw, "texture-bilinear", 1.0).unwrap();
        assert!(!m.reached);
        assert_eq!(m.point.bytes, 20);
        assert_eq!(
            speed_words(target(&sw).unwrap(), m.point),
            "not distinguishable in speed (intervals overlap) from"
        );
        let page = section(&[("x", &sw)]);
        assert!(page.contains("*not reached*"), "{page}");
        assert!(!page.contains("Speed at matched error"), "{page}");
    }
}
