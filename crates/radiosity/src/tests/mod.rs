//! Tests of the solver against analytic cases (closed-form form factors, furnaces) and of its
//! guarantees, by what they check; the helpers here are shared by all of them.

use std::sync::OnceLock;

use glam::{DVec3, Vec3};

use super::test_scenes::*;
use super::*;
use base::progress::{Event, Recorder, Stage, SILENT};
use base::quadtree::{Quadtree, VertexKey};
use scene::{Polygon, SpotLight};

mod analytic;
mod files;
mod progress;
mod refinement;
mod settle;

fn solve_quiet(scene: &Scene) -> Solution {
    solve(scene, &SolveOptions::default()).expect("solve")
}

fn cornell_solution() -> &'static (Scene, Solution) {
    static S: OnceLock<(Scene, Solution)> = OnceLock::new();
    S.get_or_init(|| {
        let s = cornell();
        let sol = solve_quiet(&s);
        (s, sol)
    })
}

/// Every (polygon, key, value) of a solution.
fn samples(sol: &Solution) -> impl Iterator<Item = (usize, VertexKey, Vec3)> + '_ {
    sol.polygons
        .iter()
        .enumerate()
        .flat_map(|(p, q)| q.keys.iter().zip(&q.values).map(move |(k, v)| (p, *k, *v)))
}
