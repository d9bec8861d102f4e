//! The shapes of the patches' light (see `transfer::shape`), measured from the solve's own
//! samples: after a full gather, each patch's shape is the radiosity of the polygon's leaves
//! under it over the patch's mean, on the polygon's own tree (merged below
//! [`MAX_SHAPE_LEVELS`]). A round's gather uses the shapes measured after the previous one,
//! so the solve goes on until the shapes it gathered with and the shapes its result implies
//! agree within [`SHAPE_CHANGE`]; the shapes kept are the ones the final samples were gathered
//! with.

use glam::DVec3;
use rayon::prelude::*;

use super::poly::{PatchLayout, Poly};
pub(super) use crate::transfer::shape::concentrates;
use crate::transfer::shape::{absolute, weights, PatchShape, MAX_SHAPE_LEVELS};
use crate::transfer::{sub_area, ShooterKind, Transfer};
use base::quadtree::{Cell, Quadtree};
use scene::Scene;

/// Largest change of a weight between two rounds for which the solve stops, scaled by the
/// patch's total over the brightest patch's: the error a stale shape leaves at a receiver is at
/// most this times the patch's share of its light.
pub(crate) const SHAPE_CHANGE: f64 = 0.05;

/// Per patch shooter (in id order, from the first patch of the first reflecting polygon on),
/// its shape from the samples of `polys`; `None` where the light is flat within the
/// transfer's tolerance.
pub(super) fn measure(
    scene: &Scene,
    tr: &Transfer<'_>,
    polys: &[Poly],
    patches: &PatchLayout,
) -> Vec<(usize, Option<PatchShape>)> {
    let flat = crate::transfer::shape::shape_tolerance(scene.radiosity.tolerance);
    let per: Vec<Vec<(usize, Option<PatchShape>)>> = (0..polys.len())
        .into_par_iter()
        .map(|r| {
            let p = &polys[r];
            if !p.reflects() {
                return Vec::new();
            }
            let integrals = p.node_integrals();
            patches
                .ids(r)
                .map(|s| {
                    let ShooterKind::Patch { cell, .. } = tr.shooters[s].kind else {
                        return (s, None);
                    };
                    (s, shape_of(scene, r, p, &integrals, cell, flat))
                })
                .collect()
        })
        .collect();
    per.into_iter().flatten().collect()
}

/// The shape of patch `patch` of polygon `r` (`p`, its nodes' integrals of G `integrals`):
/// the polygon's subtree under the patch, cut at [`MAX_SHAPE_LEVELS`], each leaf weighted by
/// its mean G over the patch's; `None` if flat within `flat`.
fn shape_of(
    scene: &Scene,
    r: usize,
    p: &Poly,
    integrals: &[DVec3],
    patch: Cell,
    flat: f64,
) -> Option<PatchShape> {
    let poly = &scene.polygons[r];
    let nodes = p.tree.nodes();
    let top = node_of(&p.tree, patch)?;
    let mut source = Vec::new();
    let tree = Quadtree::grow(top, |id, cell, n: u32| {
        if source.len() <= id as usize {
            source.resize(id as usize + 1, 0);
        }
        source[id as usize] = n;
        let node = nodes[n as usize];
        (!node.is_leaf() && cell.level < MAX_SHAPE_LEVELS).then(|| {
            let f = node.first_child;
            [f, f + 1, f + 2, f + 3]
        })
    });
    let (mut sums, mut areas) = (Vec::new(), Vec::new());
    for (id, n) in tree.nodes().iter().enumerate() {
        if n.is_leaf() {
            sums.push(integrals[source[id] as usize]);
            areas.push(sub_area(poly, absolute(patch, n.cell)));
        }
    }
    let w = weights(&sums, &areas, flat)?;
    PatchShape::new(poly, patch, tree, w)
}

/// The node of `tree` that covers `cell` exactly (the patch's cell is always a node: trees
/// start uniform at the patch depth or deeper).
fn node_of(tree: &Quadtree, cell: Cell) -> Option<u32> {
    let mut id = 0u32;
    loop {
        let n = tree.node(id);
        if n.cell == cell {
            return Some(id);
        }
        if n.is_leaf() || n.cell.level >= cell.level {
            return None;
        }
        let shift = cell.level - n.cell.level - 1;
        let (cx, cy) = ((cell.x >> shift) & 1, (cell.y >> shift) & 1);
        id = n.first_child + cx + 2 * cy;
    }
}

/// A patch whose shape changes by more than this share of [`SHAPE_CHANGE`] (measured as
/// [`shooter_change`]) and whose light is concentrated ([`concentrates`], before or after)
/// delivers its total again with the new shape when the shape is installed (the solver's
/// `install_shapes`). Shapes that move less, or light that is not concentrated, change what
/// the coarse shots estimate by little, and the next gather corrects it.
pub(crate) const RESHOOT_SHARE: f64 = 0.25;

/// The change of shooter `s`'s shape from the one in use to `new`, as [`change`] measures it
/// for every patch (`brightest`: [`brightest_patch`]).
pub(super) fn shooter_change(
    tr: &Transfer<'_>,
    s: usize,
    new: Option<&PatchShape>,
    totals: &[DVec3],
    brightest: DVec3,
) -> f64 {
    if !concentrates(tr.shape(s)) && !concentrates(new) {
        return 0.0;
    }
    patch_change(tr.shape(s), new, totals[s], brightest)
}

/// Largest change of a weight in one channel between the shapes `old` and `new` (a missing
/// shape counts as all weights 1), sampled on a 16 x 16 grid over the patch, scaled by the
/// patch's total over `brightest`, per channel.
fn patch_change(
    old: Option<&PatchShape>,
    new: Option<&PatchShape>,
    total: DVec3,
    brightest: DVec3,
) -> f64 {
    let at = |s: Option<&PatchShape>, su: f64, sv: f64| s.map_or([1.0; 3], |s| s.weight_at(su, sv));
    let mut worst = 0.0f64;
    for i in 0..256 {
        let (su, sv) = (
            (i % 16) as f64 / 16.0 + 1.0 / 32.0,
            (i / 16) as f64 / 16.0 + 1.0 / 32.0,
        );
        let (a, b) = (at(old, su, sv), at(new, su, sv));
        for k in 0..3 {
            let scale = if brightest[k] > 0.0 {
                total[k] / brightest[k]
            } else {
                0.0
            };
            worst = worst.max(scale * (a[k] as f64 - b[k] as f64).abs());
        }
    }
    worst
}

/// Largest change of a weight in one channel between the shapes in use and `new` (a missing
/// shape counts as all weights 1), sampled on a 16 x 16 grid over each patch, each patch's
/// change scaled by its total over the largest patch total in that channel: what a stale
/// shape can change at a receiver, relative to the brightest patch's light.
pub(super) fn change(
    tr: &Transfer<'_>,
    new: &[(usize, Option<PatchShape>)],
    totals: &[DVec3],
) -> f64 {
    let brightest = brightest_patch(new, totals);
    new.iter()
        .filter(|(s, shape)| tr.shape(*s).is_some() || shape.is_some())
        .map(|(s, shape)| patch_change(tr.shape(*s), shape.as_ref(), totals[*s], brightest))
        .fold(0.0, f64::max)
}

/// The largest total of the patches of `new`, per channel.
pub(super) fn brightest_patch(new: &[(usize, Option<PatchShape>)], totals: &[DVec3]) -> DVec3 {
    new.iter().fold(DVec3::ZERO, |m, (s, _)| m.max(totals[*s]))
}
