//! Settling the shapes of the patches' light before a round gathers with them.
//!
//! A round gathers every point with the shapes measured from the previous round's samples, so
//! a shape lags the light it describes by one round. Where the light of a corner depends on the
//! shapes of the patches around it (a nook between a cabinet and a wall, a floor in the shadow
//! between two boxes), each round closes only part of the gap: in a 30 cm nook beside a
//! cabinet about half of it was left after every round, and after four rounds the nook's
//! floor read 2.5 % brighter than a path tracer (0.2 % after nine rounds). The light
//! converged globally long before (the shapes' change scaled by the brightest patch's light
//! was 0.04), because a corner's light is a small share of the scene's.
//!
//! So once the light has converged (the unshot light below `convergence`) and only the shapes
//! keep the rounds going, the shapes a round measured are settled before they are installed:
//! where a patch's shape moves the light where it falls by more than the scene's `tolerance`
//! (relative, over the cells of a 16 x 16 grid on the patch, light darker than [`DARK`] of the
//! brightest patch's counting as that level), the points in those cells gather again with the
//! new shapes (vertices, and the inner points the integrals use: the refinement's test points
//! and the ramps' centres), and the patches' shapes are measured again, while any of them
//! still moves by more than the tolerance, at most [`SETTLE_PASSES`] times. It is the rounds'
//! own iteration, run only where it has not converged and without shooting, refining or
//! gathering the whole scene. Measured: the nook's floor 2.5 % -> 1.3 % bright; the studio's
//! dark floor pieces under its furniture 26 % -> 16 % (RMS over its faces 6.7 % -> 4.3 %).
//! Settling does not decide when the rounds end: a solve whose shapes settle before its light
//! converges (the Cornell box) never settles, and a round that only the patches' residuals ask
//! for takes the shapes as measured (`Solver::indirect_round`); making every round wait for
//! the light where it falls took the Cornell box's worst piece from 3.0 % to 0.6 % for twice
//! the solve time, which is not done here.
//!
//! Invariant: the passes change nothing but the shapes the next round installs. The samples
//! they gather are put back and the shapes in use restored before the caller installs the
//! settled ones, so every stored sample still comes from a full gather with the shapes then
//! installed (the oracle's answer), and the rounds' bookkeeping of changed shapes (the
//! reshooting of concentrated patches) sees the same change it would without the passes.

use glam::DVec3;

use super::super::refine::test_points;
use super::super::shapes;
use super::Solver;
use crate::transfer::shape::{absolute, PatchShape};
use crate::transfer::ShooterKind;
use base::quadtree::{Cell, VertexKey};

/// Light below this share of the brightest patch's total counts as that level when a shape's
/// change is measured against the light where it falls (see the module doc): a change in
/// light darker than that is a small share of what any receiver gets.
const DARK: f64 = 0.01;

/// Most passes of gathering again and measuring the shapes between two rounds.
const SETTLE_PASSES: usize = 4;

#[cfg(test)]
thread_local! {
    /// Set while a test solves without settling (to compare).
    static OFF: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Whether the solve on this thread settles shapes (always, but in a test that asks not to).
pub(super) fn enabled() -> bool {
    #[cfg(test)]
    {
        !OFF.with(|o| o.get())
    }
    #[cfg(not(test))]
    {
        true
    }
}

/// Runs `f` (a solve on this thread) without settling shapes.
#[cfg(test)]
pub(crate) fn without_settling<T>(f: impl FnOnce() -> T) -> T {
    OFF.with(|o| o.set(true));
    let out = f();
    OFF.with(|o| o.set(false));
    out
}

/// A polygon and the indices of its vertices, test points and centres to gather again.
type PointsOf = (usize, Vec<usize>, Vec<usize>, Vec<usize>);

/// One polygon's samples as a round left them: G at its vertices, test points and centres.
type Samples = (Vec<DVec3>, Vec<(Cell, [DVec3; 5])>, Vec<(Cell, DVec3)>);

/// The level below which light counts as dark, per channel: [`DARK`] of the largest total
/// of the patches of `new`.
pub(super) fn dark_floor(new: &[(usize, Option<PatchShape>)], totals: &[DVec3]) -> DVec3 {
    DARK * shapes::brightest_patch(new, totals)
}

impl Solver<'_, '_, '_> {
    /// The patches (ascending) whose shape in `new` moves the light where it falls by more
    /// than the tolerance from the shape in use (`shapes::relative_change`, with `floor`),
    /// each with the cells of its grid that move (polygon cells), and the largest move.
    pub(super) fn moved_patches(
        &self,
        new: &[(usize, Option<PatchShape>)],
        floor: DVec3,
    ) -> (Vec<(usize, Vec<Cell>)>, f64) {
        let limit = self.scene.radiosity.tolerance;
        let mut worst = 0.0f64;
        let mut out = Vec::new();
        for (s, shape) in new {
            let old = self.tr.shape(*s);
            let Some((_, patch)) = self.patch_of(*s) else {
                continue;
            };
            if old.is_none() && shape.is_none() {
                continue;
            }
            let changes = shapes::cell_changes(old, shape.as_ref(), self.totals[*s], floor);
            let cells: Vec<Cell> = (0u32..)
                .zip(&changes)
                .filter(|(_, &c)| c > limit)
                .map(|(i, _)| absolute(patch, shapes::grid_cell(i)))
                .collect();
            worst = changes.into_iter().fold(worst, f64::max);
            if !cells.is_empty() {
                out.push((*s, cells));
            }
        }
        (out, worst)
    }

    /// The shapes `new` (every patch's, as [`shapes::measure`] gives them) settled on the
    /// patches `moved` (see the module doc), and the passes it took. On return the shapes in
    /// use and every sample are as they were.
    pub(super) fn settle_shapes(
        &mut self,
        mut new: Vec<(usize, Option<PatchShape>)>,
        cells: &[(usize, Vec<Cell>)],
        floor: DVec3,
    ) -> (Vec<(usize, Option<PatchShape>)>, usize) {
        let moved: Vec<usize> = cells.iter().map(|(s, _)| *s).collect();
        let moved = &moved[..];
        let limit = self.scene.radiosity.tolerance;
        // Install the new shapes; `new` keeps the ones in use meanwhile.
        for (s, shape) in new.iter_mut() {
            *shape = self.tr.replace_shape(*s, shape.take());
        }
        let polygons = self.polygons_of(moved);
        let kept: Vec<(usize, Samples)> = polygons
            .iter()
            .map(|&r| {
                let p = &self.polys[r];
                (r, (p.g.clone(), p.tests.clone(), p.centres.clone()))
            })
            .collect();
        let mut passes = 0;
        while passes < SETTLE_PASSES {
            passes += 1;
            self.gather_again(cells);
            let again = shapes::measure_of(self.scene, self.tr, &self.polys, moved);
            let mut worst = 0.0f64;
            for (s, shape) in again {
                let change = shapes::relative_change(
                    self.tr.shape(s),
                    shape.as_ref(),
                    self.totals[s],
                    floor,
                );
                worst = worst.max(change);
                self.tr.set_shape(s, shape);
            }
            if worst <= limit {
                break;
            }
        }
        for (r, (g, tests, centres)) in kept {
            let p = &mut self.polys[r];
            (p.g, p.tests, p.centres) = (g, tests, centres);
        }
        // Put the shapes in use back; `new` gets the settled ones.
        for (s, shape) in new.iter_mut() {
            *shape = self.tr.replace_shape(*s, shape.take());
        }
        (new, passes)
    }

    /// The polygons (ascending) the patches `moved` lie on.
    fn polygons_of(&self, moved: &[usize]) -> Vec<usize> {
        let mut out: Vec<usize> = moved
            .iter()
            .filter_map(|&s| self.patch_of(s).map(|(r, _)| r))
            .collect();
        out.sort_unstable();
        out.dedup();
        out
    }

    /// The polygon and cell of patch shooter `s`.
    fn patch_of(&self, s: usize) -> Option<(usize, Cell)> {
        match self.tr.shooters[s].kind {
            ShooterKind::Patch { polygon, cell } => Some((polygon as usize, cell)),
            _ => None,
        }
    }

    /// G gathered again, with the shapes installed now, at every point in the cells of `moved`
    /// (patch, polygon cells in it) that the patches' integrals use: vertices, test points and
    /// centres (of leaves that meet a cell).
    fn gather_again(&mut self, moved: &[(usize, Vec<Cell>)]) {
        let mut cells: Vec<(usize, Cell)> = moved
            .iter()
            .filter_map(|(s, cells)| self.patch_of(*s).map(|(r, _)| (r, cells)))
            .flat_map(|(r, cells)| cells.iter().map(move |&c| (r, c)))
            .collect();
        cells.sort_by_key(|&(r, _)| r);
        // Per polygon: the indices of its vertices, test points and centres in a cell.
        let mut at: Vec<PointsOf> = Vec::new();
        for group in cells.chunk_by(|a, b| a.0 == b.0) {
            let r = group[0].0;
            let p = &self.polys[r];
            let set = CellSet::new(group.iter().map(|&(_, c)| c));
            let keys = (0..p.keys.len())
                .filter(|&i| set.holds(p.keys[i]))
                .collect();
            let tests = (0..p.tests.len())
                .filter(|&i| set.meets(p.tests[i].0))
                .collect();
            let centres = (0..p.centres.len())
                .filter(|&i| set.meets(p.centres[i].0))
                .collect();
            at.push((r, keys, tests, centres));
        }
        let mut points: Vec<(u32, VertexKey)> = Vec::new();
        for (r, keys, tests, centres) in &at {
            let (p, r32) = (&self.polys[*r], *r as u32);
            points.extend(keys.iter().map(|&i| (r32, p.keys[i])));
            for &i in tests {
                points.extend(test_points(p.tests[i].0).map(|k| (r32, k)));
            }
            points.extend(centres.iter().map(|&i| (r32, p.centres[i].0.centre())));
        }
        let g = self.tr.gather_points(&self.totals, &points, &mut self.seen);
        let mut g = g.into_iter();
        let mut next = || g.next().expect("one G per point");
        for (r, keys, tests, centres) in at {
            let p = &mut self.polys[r];
            keys.into_iter().for_each(|i| p.g[i] = next());
            for i in tests {
                p.tests[i].1.iter_mut().for_each(|x| *x = next());
            }
            centres.into_iter().for_each(|i| p.centres[i].1 = next());
        }
    }
}

/// Cells of one level of a polygon's domain (the grid cells of its patches, which share the
/// polygon's patch depth), sorted, so that a vertex or a leaf finds the ones it meets by
/// search, not by a pass over all of them.
struct CellSet {
    level: u32,
    /// (y, x) of each cell, sorted.
    at: Vec<(u32, u32)>,
}

impl CellSet {
    fn new(cells: impl Iterator<Item = Cell>) -> CellSet {
        let mut level = 0;
        let mut at: Vec<(u32, u32)> = cells
            .map(|c| {
                debug_assert!(level == 0 || level == c.level, "one level per polygon");
                level = c.level;
                (c.y, c.x)
            })
            .collect();
        at.sort_unstable();
        at.dedup();
        CellSet { level, at }
    }

    fn has(&self, x: u32, y: u32) -> bool {
        self.at.binary_search(&(y, x)).is_ok()
    }

    /// Whether lattice point `k` lies in one of the (closed) cells: the cells around it are
    /// those whose index is its coordinate over the cell size, or one less on a cell's edge.
    fn holds(&self, k: VertexKey) -> bool {
        let size = Cell {
            level: self.level,
            x: 0,
            y: 0,
        }
        .size();
        let around = |c: u32| {
            let i = c / size;
            [Some(i), (c.is_multiple_of(size) && i > 0).then(|| i - 1)]
        };
        around(k.i)
            .into_iter()
            .flatten()
            .any(|x| around(k.j).into_iter().flatten().any(|y| self.has(x, y)))
    }

    /// Whether leaf `l` meets one of the cells: lies in one, or holds one.
    fn meets(&self, l: Cell) -> bool {
        if l.level >= self.level {
            let d = l.level - self.level;
            return self.has(l.x >> d, l.y >> d);
        }
        let d = self.level - l.level;
        let (x0, x1) = (l.x << d, (l.x + 1) << d);
        ((l.y << d)..((l.y + 1) << d)).any(|y| {
            let from = self.at.partition_point(|&c| c < (y, x0));
            self.at
                .get(from)
                .is_some_and(|&(cy, cx)| cy == y && cx < x1)
        })
    }
}
