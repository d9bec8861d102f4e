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

/// [`measure`] for the patch shooters `which` only (in their order).
pub(super) fn measure_of(
    scene: &Scene,
    tr: &Transfer<'_>,
    polys: &[Poly],
    which: &[usize],
) -> Vec<(usize, Option<PatchShape>)> {
    let flat = crate::transfer::shape::shape_tolerance(scene.radiosity.tolerance);
    which
        .par_iter()
        .map(|&s| {
            let ShooterKind::Patch { polygon, cell } = tr.shooters[s].kind else {
                return (s, None);
            };
            let r = polygon as usize;
            let p = &polys[r];
            (s, shape_of(scene, r, p, &p.node_integrals(), cell, flat))
        })
        .collect()
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

/// The largest relative change of a patch's light between the shapes `old` and `new` of a
/// patch whose total is `total` (a missing shape counts as all weights 1), over the cells of
/// a 16 x 16 grid on the patch, per channel: `|b_new - b_old| / max(b_old, b_new, floor)` with
/// `b` the total times the shape's mean over the cell and `floor` the level below which light
/// counts as dark. Where [`change`] asks how much a stale shape moves the brightest light in
/// the scene, this asks how much it moves the light where it falls: a dark corner whose light
/// is a third too bright in the shapes reads 0.33 here and a few hundredths there. Means over
/// cells, not weights at points: a refinement that splits a leaf changes the weights at its
/// points, not the light over the cells, and is not a change of the light.
pub(super) fn relative_change(
    old: Option<&PatchShape>,
    new: Option<&PatchShape>,
    total: DVec3,
    floor: DVec3,
) -> f64 {
    cell_changes(old, new, total, floor)
        .into_iter()
        .fold(0.0, f64::max)
}

/// The cells of the grid [`relative_change`] measures on (level 4 of the patch's tree, row by
/// row), and each one's relative change.
pub(super) fn cell_changes(
    old: Option<&PatchShape>,
    new: Option<&PatchShape>,
    total: DVec3,
    floor: DVec3,
) -> Vec<f64> {
    let mean = |s: Option<&PatchShape>, c: Cell| s.map_or(DVec3::ONE, |s| s.mean_in(c));
    (0..256u32)
        .map(|i| {
            let c = grid_cell(i);
            let (a, b) = (total * mean(old, c), total * mean(new, c));
            (0..3)
                .map(|k| {
                    let level = a[k].max(b[k]).max(floor[k]);
                    if level > 0.0 {
                        (a[k] - b[k]).abs() / level
                    } else {
                        0.0
                    }
                })
                .fold(0.0, f64::max)
        })
        .collect()
}

/// Cell `i` (row by row) of the 16 x 16 grid on a patch, relative to the patch.
pub(super) fn grid_cell(i: u32) -> Cell {
    Cell {
        level: 4,
        x: i % 16,
        y: i / 16,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_scenes::unit_square;

    /// A unit square patch whose light is `light(x, y)` on a full tree of `levels` levels
    /// (weights: each leaf's light at its centre over the mean).
    fn shape_of_light(levels: u32, light: impl Fn(f64, f64) -> f64) -> PatchShape {
        let poly = unit_square();
        let tree = Quadtree::grow((), |_, cell, _| (cell.level < levels).then_some([(); 4]));
        let raw: Vec<f64> = tree
            .nodes()
            .iter()
            .filter(|n| n.is_leaf())
            .map(|n| {
                let w = n.cell.width();
                let (x, y) = ((n.cell.x as f64 + 0.5) * w, (n.cell.y as f64 + 0.5) * w);
                light(x, y)
            })
            .collect();
        let mean = raw.iter().sum::<f64>() / raw.len() as f64;
        let leaves = raw.iter().map(|&l| [(l / mean) as f32; 3]).collect();
        let root = Cell {
            level: 0,
            x: 0,
            y: 0,
        };
        PatchShape::new(&poly, root, tree, leaves).expect("counts agree")
    }

    /// A patch lit evenly but for a dark corner (a sixteenth of it at a tenth of the light)
    /// whose light falls by a third from one round to the next: the change where the light
    /// falls reads a third, while the change scaled by the brightest light reads a twentieth
    /// (the weight's own move, 0.05: below what keeps the rounds going).
    #[test]
    fn a_dark_corner_that_moves_by_a_third_reads_a_third() {
        let before = shape_of_light(4, |x, y| if x < 0.25 && y < 0.25 { 0.15 } else { 1.0 });
        let after = shape_of_light(4, |x, y| if x < 0.25 && y < 0.25 { 0.1 } else { 1.0 });
        let total = DVec3::ONE;
        let floor = DVec3::splat(0.01);
        let rel = relative_change(Some(&before), Some(&after), total, floor);
        // Weights are light over the mean: the corner's 0.15 / 0.947 against 0.1 / 0.944.
        let (b, a) = (0.15 / (15.0 + 0.15) * 16.0, 0.1 / (15.0 + 0.1) * 16.0);
        assert!((rel - (b - a) / b).abs() < 1e-3, "{rel}");
        let scaled = patch_change(Some(&before), Some(&after), total, total);
        assert!(
            scaled < 0.2 * rel && scaled < shapes_change_limit(),
            "{scaled} against {rel}"
        );
    }

    fn shapes_change_limit() -> f64 {
        // The rounds stop on a change up to this.
        super::SHAPE_CHANGE + 0.01
    }

    /// Splitting a leaf changes the weights at points inside it, not its mean: a shape on a
    /// finer tree of the same light reads no change where the light falls.
    #[test]
    fn a_finer_tree_of_the_same_light_is_no_change() {
        let light = |x: f64, _y: f64| if x < 0.5 { 1.0 } else { 3.0 };
        let coarse = shape_of_light(4, light);
        let fine = shape_of_light(6, light);
        let rel = relative_change(Some(&coarse), Some(&fine), DVec3::ONE, DVec3::splat(0.01));
        assert!(rel < 1e-6, "{rel}");
        assert_eq!(
            grid_cell(17),
            Cell {
                level: 4,
                x: 1,
                y: 1
            }
        );
    }
}
