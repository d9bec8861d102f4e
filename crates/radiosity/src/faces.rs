//! Per-polygon means of a solution: what an independent reference (a path tracer's per-polygon
//! estimates) is compared with, face by face. The mean of a polygon is the area-weighted
//! integral of its samples over its leaves (trapezoid rule on each leaf's four corners, the
//! leaf's world-space area as weight) over the polygon's area; its direct part is the same
//! integral of the light that came straight from spots and emitters, gathered again from the
//! solution's history with every reflecting patch's total set to zero.
//!
//! Invariants: the result depends only on the solution and the scene; the direct part is
//! computed by the oracle's own gather (bit-for-bit the solver's transfer), in a fixed order.

use glam::DVec3;
use rayon::prelude::*;

use crate::transfer::{sub_area, ShooterKind};
use crate::{radiosity_from_g, Oracle, Solution};
use base::error::Result;
use scene::Scene;

/// The mean radiosity of one polygon.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FaceMean {
    /// Mean radiosity over the polygon (linear RGB, emission included).
    pub total: DVec3,
    /// Its part that came straight from spots and emitters (emission included).
    pub direct: DVec3,
    /// World-space area.
    pub area: f64,
}

/// Every polygon's [`FaceMean`] under `sol` (which must solve `scene`).
pub fn face_means(sol: &Solution, scene: &Scene) -> Result<Vec<FaceMean>> {
    let direct_only = direct_solution(sol);
    let oracle = Oracle::new(&direct_only, scene)?;
    Ok((0..scene.polygons.len())
        .into_par_iter()
        .map(|i| face_mean(sol, scene, &oracle, i))
        .collect())
}

/// `sol` with every reflecting patch's total zeroed: its oracle answers the direct light.
fn direct_solution(sol: &Solution) -> Solution {
    let mut d = Solution {
        polygons: Vec::new(),
        shooters: sol.shooters.clone(),
        stats: Default::default(),
        scene_hash: sol.scene_hash,
    };
    for s in d.shooters.iter_mut() {
        if matches!(s.kind, ShooterKind::Patch { .. }) {
            s.total = DVec3::ZERO;
        }
    }
    d
}

fn face_mean(sol: &Solution, scene: &Scene, direct: &Oracle<'_>, i: usize) -> FaceMean {
    let q = &sol.polygons[i];
    let p = &scene.polygons[i];
    let m = scene.material_of(i);
    let (mut total, mut dir, mut area) = (DVec3::ZERO, DVec3::ZERO, 0.0);
    for id in q.tree.leaves() {
        let cell = q.tree.node(id).cell;
        let a = sub_area(p, cell);
        let mut t = DVec3::ZERO;
        let mut d = DVec3::ZERO;
        for k in cell.corners() {
            if let Ok(j) = q.keys.binary_search(&k) {
                t += q.values[j].as_dvec3();
            }
            let g = if m.reflectance.max_element() > 0.0 {
                direct.irradiance(i, k.u(), k.v())
            } else {
                DVec3::ZERO
            };
            d += radiosity_from_g(m, g).as_dvec3();
        }
        total += 0.25 * a * t;
        dir += 0.25 * a * d;
        area += a;
    }
    let k = if area > 0.0 { 1.0 / area } else { 0.0 };
    FaceMean {
        total: total * k,
        direct: dir * k,
        area,
    }
}
