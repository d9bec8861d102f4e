//! Per-polygon means of a solution: what an independent reference (a path tracer's per-polygon
//! estimates) is compared with, face by face. The mean of a polygon is the area-weighted
//! integral of its samples over its leaves over the polygon's area: the trapezoid rule on each
//! leaf's four corners, or, on a leaf across which the light falls steeply (its corners'
//! spread above [`STEEP`] of their mean and of the polygon's mean), the centre rule with G
//! gathered again at its centre: beside a panel hung 2 cm in front of a ceiling the trapezoid
//! rule read the ceiling's strip 8 % over what it receives, and the piece of ceiling above the
//! panel, seen through the gap, 10 % over. The direct part is the same integral of the light
//! that came straight from spots and emitters, gathered again from the solution's history with
//! every reflecting patch's total set to zero.
//!
//! Invariants: the result depends only on the solution and the scene; every gather is the
//! oracle's own (bit-for-bit the solver's transfer), in a fixed order.

use glam::DVec3;
use rayon::prelude::*;

use crate::shoot::{centre_rule, lum, spread};
use crate::transfer::{sub_area, ShooterKind};
use crate::{radiosity_from_g, Oracle, Solution};
use base::error::Result;
use base::quadtree::{VertexKey, MAX_DEPTH};
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

/// Share of a leaf's corner mean (and of its polygon's mean) its corners' spread must pass
/// for the leaf's integral to gather G at its centre ([`face_means`]).
pub(crate) const STEEP: f64 = 0.05;

/// Every polygon's [`FaceMean`] under `sol` (which must solve `scene`).
pub fn face_means(sol: &Solution, scene: &Scene) -> Result<Vec<FaceMean>> {
    let direct_only = direct_solution(sol);
    let oracles = (Oracle::new(sol, scene)?, Oracle::new(&direct_only, scene)?);
    Ok((0..scene.polygons.len())
        .into_par_iter()
        .map(|i| face_mean(sol, scene, &oracles, i))
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

fn face_mean(
    sol: &Solution,
    scene: &Scene,
    (full, direct): &(Oracle<'_>, Oracle<'_>),
    i: usize,
) -> FaceMean {
    let q = &sol.polygons[i];
    let p = &scene.polygons[i];
    let m = scene.material_of(i);
    let reflects = m.reflectance.max_element() > 0.0;
    let b_at = |k: VertexKey| {
        q.keys
            .binary_search(&k)
            .map_or(DVec3::ZERO, |j| q.values[j].as_dvec3())
    };
    let d_at = |u: f64, v: f64| {
        let g = if reflects {
            direct.irradiance(i, u, v)
        } else {
            DVec3::ZERO
        };
        radiosity_from_g(m, g).as_dvec3()
    };
    let leaves: Vec<_> = q
        .tree
        .leaves()
        .into_iter()
        .map(|id| {
            let cell = q.tree.node(id).cell;
            (cell, sub_area(p, cell), cell.corners().map(b_at))
        })
        .collect();
    let area: f64 = leaves.iter().map(|l| l.1).sum();
    let mean = leaves
        .iter()
        .map(|(_, a, b)| 0.25 * a * lum(b.iter().sum()))
        .sum::<f64>()
        / area.max(f64::MIN_POSITIVE);
    let (mut total, mut dir) = (DVec3::ZERO, DVec3::ZERO);
    for (cell, a, b) in &leaves {
        let d = cell.corners().map(|k| d_at(k.u(), k.v()));
        let corner_mean = 0.25 * b.iter().sum::<DVec3>();
        let steep = reflects
            && cell.level < MAX_DEPTH
            && spread(b.map(lum)) > STEEP * lum(corner_mean).max(mean);
        if steep {
            let c = cell.centre();
            let centre = full.radiosity(i, c.u(), c.v()).as_dvec3();
            total += centre_rule(*a, b.iter().sum(), centre);
            dir += centre_rule(*a, d.iter().sum(), d_at(c.u(), c.v()));
        } else {
            total += 0.25 * a * b.iter().sum::<DVec3>();
            dir += 0.25 * a * d.iter().sum::<DVec3>();
        }
    }
    let k = if area > 0.0 { 1.0 / area } else { 0.0 };
    FaceMean {
        total: total * k,
        direct: dir * k,
        area,
    }
}
