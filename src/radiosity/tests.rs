//! Tests of the solver against analytic cases (FACTS.md sec. 6) and of its guarantees.

use super::test_scenes::*;
use super::*;

fn solve_quiet(scene: &Scene) -> Solution {
    solve(scene, &SolveOptions::default()).expect("solve")
}

#[test]
fn timing_report() {
    for (name, s) in [("two-spots", two_spots()), ("cornell", cornell())] {
        let sol = solve_quiet(&s);
        let st = &sol.stats;
        eprintln!(
            "{name}: polys {} ms {:.0} verts {} leaves {} tv {} shots {} rays {} unshot {:.4} hist {:?}",
            s.polygons.len(), st.solve_ms, st.vertices, st.elements, st.t_vertices, st.shots, st.rays_cast, st.unshot_fraction, st.depth_histogram
        );
    }
}
