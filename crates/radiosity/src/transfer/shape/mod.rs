//! The shape of a reflecting patch's light: how its radiosity varies over the patch, so that a
//! receiver close to the patch is lit by the light where it is, not by the patch's average.
//!
//! A patch shoots its reflected radiosity as one number per channel (its total, the history the
//! gathers sum). Taken as uniform over the patch, that number lights a receiver next to the
//! patch with the patch's mean: a box face beside a floor patch half in its shadow received the
//! lit half's light (measured against a path tracer, +35 % on the Cornell box's short box, and
//! -10 % on the tall one, whose floor patch held the dark floor under the box). A [`PatchShape`]
//! splits the patch into a `2^k x 2^k` grid of cells, each with a weight per channel: the mean
//! radiosity over the cell over the mean over the patch (so the area-weighted mean of the
//! weights is 1 and a shape never changes the power a patch shoots).
//!
//! With weights `w_c = b + d_c` (`b` the area-weighted median weight, so that most cells
//! deviate little), the patch's transfer to a point is `b F_v + sum_c d_c F_c,v`: the exact
//! form factor `F_v` of the part of the patch the point sees (see `visible`), corrected by
//! each cell's deviation times the form factor of its part seen, summed in one pass over the
//! seen part (a difference of two sums, the whole patch's less the hidden part's, would be
//! mostly their errors where a bright spot is hidden). Where the region is beyond the exact
//! clipper, `(b F + sum_c d_c F_c) V_w` instead, with the visible fraction `V_w` of shadow rays
//! weighted by the shape where they land as well as by the kernel. A cell's form
//! factor is exact (Lambert's formula) where the point is closer than twice the cell's size,
//! and the point-to-point kernel `A_c cos cos / (pi r^2)` farther, where it is within a few
//! per cent of exact: only the correction uses it, and only the correction's own error
//! (`d_c` times a few per cent of `F_c`) comes from it. A cell's light is not flat: each leaf
//! has the slope of its neighbours' weights (limited, so it never stands beyond them), which
//! tilts the part of it a point sees and gives it a first moment, so a far cell counts as a
//! dipole; a far node is opened where the kernel's curvature across it could move its light
//! by more than the correction's budget (light piled against one side of a node, as on a
//! ceiling's rim beside a lamp hung under it). The correction costs a gather the
//! cells it looks at, so a gather applies it only where it matters, judged as hierarchical
//! radiosity judges a link (Hanrahan, Salzman and Aupperle 1991, brightness-weighted): the
//! shape's spread `s` (largest weight minus smallest) times `F` times `min(1, 2 h / d)` (size
//! over distance: the deviation integrates to zero over the patch, so far away its effect
//! fades) times the patch's total, against a fraction of what the point receives
//! ([`Transfer::gather`](super::Transfer::gather)); between `tau` and `2 tau` the corrected and
//! the uniform transfer are blended linearly, so the light stays a continuous function of the
//! point. Where the correction is left out (in part or whole) and the point sees all of the
//! patch, the uniform transfer takes the shape's dipole instead, its first moment about the
//! mean times the kernel's gradient ([`PatchShape::far_dipole`]): each correction left out is
//! small, but they share a sign over the far receivers of a patch, and without the dipole the
//! gallery's energy account lost 0.39 % of the emitted light (0.15 % with it).
//!
//! Energy: a patch's corrections integrate to nothing over a closed scene (its shape never
//! changes the power it shoots), so a gather that applies them only where they matter
//! delivers less or more than the patch shoots where the ones left out, or the approximations
//! of the ones applied, share a sign: docs/accuracy.md ("The energy account") measures each.
//!
//! Invariants: the weights are stored as `f32` and everything derived from them (the spread,
//! the cells' geometry) is a pure function of them and of the polygon, so the solver and an
//! [`Oracle`](crate::Oracle) built from a saved solution compute the same gather bit for bit.
//!
//! Code: the shape itself (its tree, weights, median and moments) is here; applying it to a
//! transfer (the uniform look and its error estimate, the correction over the part seen, the
//! coarse shots' rule) is in `shaped`.

use glam::{DVec2, DVec3, Vec2, Vec3};

use super::Look;
use super::{cell_corners, sub_area, PairClass, ShooterKind, Transfer};
use crate::formfactor::{point_to_polygon, SmallPoly};
use crate::visible::{self, CellIn, PlaneCell, Region, Sight, View};
use base::quadtree::{Cell, Quadtree};
use scene::Polygon;

mod shaped;

pub(crate) use shaped::{blend, concentrates, Pending};

/// Relative margin of the geometric thresholds of the correction (`shaped`): a distance that equals a
/// threshold in exact arithmetic lands on one side of it whatever its rounding (which differs
/// between two scales of one scene, where the light must be the same).
const TIE: f64 = 1e-9;

/// Most levels a shape's tree may have below its patch (4,096 leaves at most): the source
/// polygon's leaves deeper than this are merged.
pub(crate) const MAX_SHAPE_LEVELS: u32 = 6;

/// A patch's shape: a quadtree over the patch (the source polygon's own leaves under it, so
/// it is as fine as the solution where the light varies) with a weight per leaf.
#[derive(Debug, Clone, PartialEq)]
pub struct PatchShape {
    /// The tree, its root the whole patch (cells relative to the patch).
    pub tree: Quadtree,
    /// Per leaf, in node order, its weight per channel.
    pub leaves: Vec<[f32; 3]>,
    /// Per node: the area-weighted mean weight of its leaves and its area (derived).
    mean: Vec<(DVec3, f64)>,
    /// Per channel, the area-weighted median of the leaves' weights (derived): the weight
    /// [`correction`] measures deviations from. Most of the patch's area lies near it, so the
    /// far nodes' terms are small; measured from the mean (1), a patch whose light is one
    /// bright spot had every node around the spot count as a large negative deviation, and
    /// the far-field errors of those terms outgrew the light a point beside the spot receives.
    base: DVec3,
    /// Per node, per channel: the first moment of its leaves' deviations about the node's
    /// centre, `sum_c (M_c + A_c (w_c - base) (p_c - centre))`, `M_c` a leaf's own moment
    /// from its slope, `I_c g_c` (derived), per unit of the node's area times its size (so
    /// that f32 holds it at any scale). With it a far node counts as a dipole, not only a
    /// monopole (see [`correction`]).
    moment: Vec<[Vec3; 3]>,
    /// Per channel: the first moment of the leaves' deviations from the patch's mean weight
    /// (1) about the patch's centre, `sum_c A_c (w_c - 1) (p_c - centre)` (derived): the
    /// dipole a far point sees of the shape ([`PatchShape::far_dipole`]).
    far_moment: [DVec3; 3],
    /// Per node, per channel: the slope of its weights across it in the 2-D coordinates of
    /// the patch's views (derived): for a leaf, from its neighbours' weights
    /// ([`leaf_slopes`]); for an inner node, the gradient of a linear light with the node's
    /// first moment, `I^-1 m` with `I` the node's second moment of area. How much brighter
    /// than its mean the part of a far node a point sees in part is, given where that part
    /// lies (see `correction`).
    slope: Vec<[Vec2; 3]>,
    /// Per node: the index of its weight in `leaves` (leaves only; derived).
    leaf_index: Vec<u32>,
    /// Per node: its cell's centre on the polygon and the longer of its diagonals (derived):
    /// what [`correction`] needs of every node it visits at every receiver point, the same
    /// at all of them (taken from the cell's corners there, a correction spent an eighth of
    /// its time on the diagonal's square root alone).
    centre_size: Vec<(DVec3, f64)>,
    /// Per node: its cell in the 2-D coordinates of the patch's views (derived; what a
    /// correction classifies against the visible region, the same from every point).
    plane: Vec<PlaneCell>,
    /// Per node: the largest difference between two of its leaves' weights in one channel
    /// (derived; 0 for a leaf): how far the light of a part of it can stand from its mean.
    node_spread: Vec<f32>,
    /// Largest difference between two leaves' weights in one channel.
    spread: f64,
}

impl PatchShape {
    /// The shape with tree `tree` (relative to cell `patch` of polygon `poly`) and leaf weights
    /// `leaves` (node order); `None` if their counts differ.
    pub fn new(poly: &Polygon, patch: Cell, tree: Quadtree, leaves: Vec<[f32; 3]>) -> Option<Self> {
        let nodes = tree.nodes();
        let mut leaf_index = vec![u32::MAX; nodes.len()];
        let mut k = 0u32;
        for (i, n) in nodes.iter().enumerate() {
            if n.is_leaf() {
                leaf_index[i] = k;
                k += 1;
            }
        }
        if k as usize != leaves.len() {
            return None;
        }
        let mut mean = vec![(DVec3::ZERO, 0.0); nodes.len()];
        // Children always come after their parent: from the last node back, every node's
        // children are done before it.
        for i in (0..nodes.len()).rev() {
            let n = nodes[i];
            mean[i] = if n.is_leaf() {
                let w = leaves[leaf_index[i] as usize];
                let area = sub_area(poly, absolute(patch, n.cell));
                (DVec3::new(w[0] as f64, w[1] as f64, w[2] as f64), area)
            } else {
                let f = n.first_child as usize;
                let (mut w, mut a) = (DVec3::ZERO, 0.0);
                for &(cw, ca) in &mean[f..f + 4] {
                    w += ca * cw;
                    a += ca;
                }
                (if a > 0.0 { w / a } else { DVec3::ONE }, a)
            };
        }
        let base = median_weight(&leaves, &leaf_index, &mean);
        let centre_size: Vec<(DVec3, f64)> = nodes
            .iter()
            .map(|n| {
                let c = cell_corners(poly, absolute(patch, n.cell));
                // The longer diagonal, as one square root of the larger square (the same
                // value: the correctly rounded square root is monotonic).
                let size = (c[2] - c[0])
                    .length_squared()
                    .max((c[3] - c[1]).length_squared())
                    .sqrt();
                (0.25 * (c[0] + c[1] + c[2] + c[3]), size)
            })
            .collect();
        // The patch's views are made from its outline as a shooter has it.
        let outline = SmallPoly::from_corners(&cell_corners(poly, patch));
        let axes = visible::plane_axes(outline.verts(), poly.normal);
        // The leaves' slopes first: a leaf's light is its mean tilted by them, which gives
        // every node's first moment its leaves' own part.
        let mut slope = leaf_slopes(&tree, (poly, patch), (&leaves, &leaf_index), axes);
        let leaf_moment = leaf_moments(&tree, (poly, patch), &mean, &slope, axes);
        let moment = moments(&tree, &centre_size, (&mean, &leaf_moment), base);
        let far_moment = far_moment(&tree, &centre_size, (&mean, &leaf_moment));
        let plane = visible::plane_cells(
            outline.verts(),
            poly.normal,
            nodes
                .iter()
                .map(|n| cell_corners(poly, absolute(patch, n.cell))),
        );
        inner_slopes(&tree, (poly, patch), &mean, &moment, axes, &mut slope);
        let moment = scaled_moments(&moment, &centre_size, &mean);
        let node_spread = node_spreads(&tree, &leaves, &leaf_index);
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        for c in &leaves {
            for k in 0..3 {
                lo[k] = lo[k].min(c[k]);
                hi[k] = hi[k].max(c[k]);
            }
        }
        let spread = (0..3)
            .map(|k| (hi[k] - lo[k]) as f64)
            .fold(0.0f64, f64::max)
            .max(0.0);
        Some(PatchShape {
            tree,
            leaves,
            mean,
            moment,
            far_moment,
            slope,
            leaf_index,
            centre_size,
            plane,
            node_spread,
            spread,
            base,
        })
    }

    /// Per channel and per unit of the patch's total, what a receiver point `x` (normal `n`)
    /// that sees all of the patch (front normal `normal`) receives from its shape beyond its
    /// mean, to first order in the patch's size over the distance: the weights' deviation
    /// from 1 integrates to zero over the patch, so far away its light is the dipole, the
    /// first moment times the kernel's gradient at the patch's centre, over pi (0 where the
    /// centre is behind either side).
    pub(crate) fn far_dipole(&self, x: DVec3, n: DVec3, normal: DVec3) -> DVec3 {
        let Some((_, grad)) = kernel_and_gradient(x, n, self.centre_size[0].0, normal) else {
            return DVec3::ZERO;
        };
        let m = &self.far_moment;
        DVec3::new(grad.dot(m[0]), grad.dot(m[1]), grad.dot(m[2])) * std::f64::consts::FRAC_1_PI
    }

    /// The mean weight over `cell` (relative to the patch): its node's mean, or the weight of
    /// the leaf that holds it where the tree is coarser. A tree refined inside the cell gives
    /// the same mean as a coarser one would (both are the light's integral over it), so a mean
    /// compares shapes measured on different trees without counting their detail.
    pub(crate) fn mean_in(&self, cell: Cell) -> DVec3 {
        let mut id = 0u32;
        loop {
            let n = self.tree.node(id);
            if n.is_leaf() || n.cell.level >= cell.level {
                return self.mean[id as usize].0;
            }
            let shift = cell.level - n.cell.level - 1;
            let (cx, cy) = ((cell.x >> shift) & 1, (cell.y >> shift) & 1);
            id = n.first_child + cx + 2 * cy;
        }
    }

    /// The weight of the leaf at unit-square position (su, sv) of the patch.
    #[inline]
    pub(crate) fn weight_at(&self, su: f64, sv: f64) -> [f32; 3] {
        let id = self.tree.find_leaf(su, sv) as usize;
        self.leaves[self.leaf_index[id] as usize]
    }

    /// Luminance of the weight of the leaf at unit-square position (su, sv) of the patch.
    #[inline]
    fn luminance_at(&self, su: f64, sv: f64) -> f64 {
        let c = self.weight_at(su, sv);
        0.2126 * c[0] as f64 + 0.7152 * c[1] as f64 + 0.0722 * c[2] as f64
    }
}

/// Per node, the largest difference between two of its leaves' weights in one channel (0 for
/// a leaf), from each node's lowest and highest leaf weight per channel.
fn node_spreads(tree: &Quadtree, leaves: &[[f32; 3]], leaf_index: &[u32]) -> Vec<f32> {
    let nodes = tree.nodes();
    let mut range = vec![([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]); nodes.len()];
    for i in (0..nodes.len()).rev() {
        let n = nodes[i];
        range[i] = if n.is_leaf() {
            let w = leaves[leaf_index[i] as usize];
            (w, w)
        } else {
            let f = n.first_child as usize;
            let mut r = range[f];
            for c in &range[f + 1..f + 4] {
                for k in 0..3 {
                    r.0[k] = r.0[k].min(c.0[k]);
                    r.1[k] = r.1[k].max(c.1[k]);
                }
            }
            r
        };
    }
    range
        .iter()
        .map(|(lo, hi)| (0..3).map(|k| hi[k] - lo[k]).fold(0.0f32, f32::max))
        .collect()
}

/// Per channel, the area-weighted median of the leaves' weights (`leaf_index` maps nodes to
/// `leaves`; `mean` holds each node's area): the smallest weight at which the leaves at or
/// below it cover more than half the patch.
fn median_weight(leaves: &[[f32; 3]], leaf_index: &[u32], mean: &[(DVec3, f64)]) -> DVec3 {
    let area: Vec<(usize, f64)> = leaf_index
        .iter()
        .enumerate()
        .filter(|(_, &k)| k != u32::MAX)
        .map(|(i, &k)| (k as usize, mean[i].1))
        .collect();
    let total: f64 = area.iter().map(|(_, a)| a).sum();
    let mut base = DVec3::ONE;
    for ch in 0..3 {
        let mut by: Vec<(f32, f64)> = area.iter().map(|&(k, a)| (leaves[k][ch], a)).collect();
        by.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut acc = 0.0;
        for (w, a) in by {
            acc += a;
            // Equal cells reach half the area exactly at a leaf's end: the margin puts that
            // tie on the same side at any scale (see `TIE`).
            if acc >= 0.5 * total * (1.0 + TIE) {
                base[ch] = w as f64;
                break;
            }
        }
    }
    base
}

/// The first moment of the leaves' deviations from the mean weight 1 about the root's centre
/// (see [`PatchShape::far_moment`]), each leaf's light taken at its centre.
fn far_moment(
    tree: &Quadtree,
    centre_size: &[(DVec3, f64)],
    (mean, leaf_moment): (&[(DVec3, f64)], &[[DVec3; 3]]),
) -> [DVec3; 3] {
    let root = centre_size[0].0;
    let mut m = [DVec3::ZERO; 3];
    for (i, n) in tree.nodes().iter().enumerate() {
        if n.is_leaf() {
            let (w, a) = mean[i];
            let arm = centre_size[i].0 - root;
            for k in 0..3 {
                m[k] += leaf_moment[i][k] + a * (w[k] - 1.0) * arm;
            }
        }
    }
    m
}

/// Each node's slope (see [`PatchShape::slope`]) from its first moment `moment`, its area and
/// its cell's edges, in the views' coordinates along `axes`: a cell with edges `e1`, `e2` has
/// the second moment `A (e1 e1^T + e2 e2^T) / 12` about its centre (a parallelogram's; the
/// moment sums its leaves' own moments beside their means', so a linear light reads its slope
/// exactly). Leaves keep theirs ([`leaf_slopes`]).
fn inner_slopes(
    tree: &Quadtree,
    (poly, patch): (&Polygon, Cell),
    mean: &[(DVec3, f64)],
    moment: &[[DVec3; 3]],
    (f1, f2): (DVec3, DVec3),
    slope: &mut [[Vec2; 3]],
) {
    let nodes = tree.nodes();
    for (i, n) in nodes.iter().enumerate() {
        if n.is_leaf() {
            continue;
        }
        let (ixx, ixy, iyy) = second_moment((poly, patch), n.cell, mean[i].1, (f1, f2));
        let det = ixx * iyy - ixy * ixy;
        if !(det.is_finite() && det > 1e-12 * ixx * iyy) {
            continue;
        }
        for ch in 0..3 {
            let m = moment[i][ch];
            let (mx, my) = (m.dot(f1), m.dot(f2));
            let g = DVec2::new(iyy * mx - ixy * my, ixx * my - ixy * mx) / det;
            slope[i][ch] = g.as_vec2();
        }
    }
}

/// The mean edges `e1` (along u) and `e2` (along v) of cell `cell` of patch `patch` of `poly`
/// in the views' coordinates along `axes`, as `(e1 . f1, e1 . f2, e2 . f1, e2 . f2)`.
fn plane_edges(
    (poly, patch): (&Polygon, Cell),
    cell: Cell,
    (f1, f2): (DVec3, DVec3),
) -> (f64, f64, f64, f64) {
    let c = cell_corners(poly, absolute(patch, cell));
    let e1 = 0.5 * ((c[1] - c[0]) + (c[2] - c[3]));
    let e2 = 0.5 * ((c[3] - c[0]) + (c[2] - c[1]));
    (e1.dot(f1), e1.dot(f2), e2.dot(f1), e2.dot(f2))
}

/// The second moment of area `(ixx, ixy, iyy)` about its centre of cell `cell` of patch `patch`
/// of `poly` (area `area`), in the views' coordinates along `axes`: a parallelogram with edges
/// `e1`, `e2` has `A (e1 e1^T + e2 e2^T) / 12`.
fn second_moment(
    (poly, patch): (&Polygon, Cell),
    cell: Cell,
    area: f64,
    axes: (DVec3, DVec3),
) -> (f64, f64, f64) {
    let (a1, b1, a2, b2) = plane_edges((poly, patch), cell, axes);
    let k = area / 12.0;
    (
        k * (a1 * a1 + a2 * a2),
        k * (a1 * b1 + a2 * b2),
        k * (b1 * b1 + b2 * b2),
    )
}

/// Each leaf's first moment of its light about its centre, per channel, from its slope
/// ([`leaf_slopes`]): a light `w + g . q` over the cell has the moment `I g` (`I` its second
/// moment of area), taken back from the views' coordinates along `axes` to 3-D; 0 for an
/// inner node (its moment is its children's, [`moments`]).
fn leaf_moments(
    tree: &Quadtree,
    (poly, patch): (&Polygon, Cell),
    mean: &[(DVec3, f64)],
    slope: &[[Vec2; 3]],
    (f1, f2): (DVec3, DVec3),
) -> Vec<[DVec3; 3]> {
    let nodes = tree.nodes();
    let mut out = vec![[DVec3::ZERO; 3]; nodes.len()];
    for (i, n) in nodes.iter().enumerate() {
        if !n.is_leaf() || slope[i] == [Vec2::ZERO; 3] {
            continue;
        }
        let (ixx, ixy, iyy) = second_moment((poly, patch), n.cell, mean[i].1, (f1, f2));
        for ch in 0..3 {
            let g = slope[i][ch].as_dvec2();
            let (mx, my) = (ixx * g.x + ixy * g.y, ixy * g.x + iyy * g.y);
            out[i][ch] = mx * f1 + my * f2;
        }
    }
    out
}

/// Each leaf's slope (see [`PatchShape::slope`]), from the weights of the leaves beside it
/// in the shape: along each of its cell's axes the central difference, limited to twice
/// either one-sided difference and 0 where they differ in sign (van Leer's monotonized
/// central limiter, as MUSCL schemes reconstruct cell means: a leaf at a peak or a dip has no
/// slope and a tilted leaf never stands beyond its neighbours, while a smooth fall keeps its
/// steepness; the smaller one-sided difference alone left a light falling exponentially
/// toward a rim 1 % bright), the one difference there is at the patch's border. A leaf is the
/// finest the shape knows of its light, but where the light falls steeply over a few leaves
/// (a ceiling's rim beside a lamp hung under it, seen from across the room past the lamp),
/// the part of a leaf a point sees is brighter or darker than its mean by that fall: as the
/// mean alone, the walls of a room lit that way read 5-9 % more of a rim strip's light than it
/// sends them.
fn leaf_slopes(
    tree: &Quadtree,
    (poly, patch): (&Polygon, Cell),
    (leaves, leaf_index): (&[[f32; 3]], &[u32]),
    (f1, f2): (DVec3, DVec3),
) -> Vec<[Vec2; 3]> {
    let mut slope = vec![[Vec2::ZERO; 3]; tree.nodes().len()];
    let weight = |su: f64, sv: f64| -> Option<[f32; 3]> {
        let inside = (0.0..1.0).contains(&su) && (0.0..1.0).contains(&sv);
        inside.then(|| leaves[leaf_index[tree.find_leaf(su, sv) as usize] as usize])
    };
    for (i, n) in tree.nodes().iter().enumerate() {
        if !n.is_leaf() {
            continue;
        }
        let w = leaves[leaf_index[i] as usize];
        let (u0, v0, u1, v1) = n.cell.bounds();
        let (cu, cv, step) = (0.5 * (u0 + u1), 0.5 * (v0 + v1), u1 - u0);
        // Per channel, the change of weight across one cell width along u and along v.
        let across = |a: Option<[f32; 3]>, b: Option<[f32; 3]>, ch: usize| -> f64 {
            let fwd = a.map(|a| f64::from(a[ch] - w[ch]));
            let bwd = b.map(|b| f64::from(w[ch] - b[ch]));
            match (fwd, bwd) {
                (Some(f), Some(b)) if f * b > 0.0 => {
                    f.signum() * (0.5 * (f + b).abs()).min(2.0 * f.abs()).min(2.0 * b.abs())
                }
                (Some(_), Some(_)) | (None, None) => 0.0,
                (Some(d), None) | (None, Some(d)) => d,
            }
        };
        let (east, west) = (weight(cu + step, cv), weight(cu - step, cv));
        let (north, south) = (weight(cu, cv + step), weight(cu, cv - step));
        let (a1, b1, a2, b2) = plane_edges((poly, patch), n.cell, (f1, f2));
        let det = a1 * b2 - b1 * a2;
        if !(det.is_finite() && det.abs() > 1e-12 * a1.hypot(b1) * a2.hypot(b2)) {
            continue;
        }
        // Per channel the plane gradient g with g . e1 = change along u, g . e2 = along v.
        slope[i] = std::array::from_fn(|ch| {
            let (du, dv) = (across(east, west, ch), across(north, south, ch));
            (DVec2::new(b2 * du - b1 * dv, a1 * dv - a2 * du) / det).as_vec2()
        });
    }
    slope
}

/// Each node's first moment of deviation from `base` about its centre (see
/// [`PatchShape::moment`]), from the nodes' mean weights and areas: a leaf's is its own
/// (`leaf_moment`, from its slope); a parent's is its children's, each moved to the parent's
/// centre, `sum_children (D_child + A_child (w_child - base) (centre_child - centre))`.
fn moments(
    tree: &Quadtree,
    centre_size: &[(DVec3, f64)],
    (mean, leaf_moment): (&[(DVec3, f64)], &[[DVec3; 3]]),
    base: DVec3,
) -> Vec<[DVec3; 3]> {
    let nodes = tree.nodes();
    let centre = |i: usize| centre_size[i].0;
    let mut moment = vec![[DVec3::ZERO; 3]; nodes.len()];
    for i in (0..nodes.len()).rev() {
        let n = nodes[i];
        if n.is_leaf() {
            moment[i] = leaf_moment[i];
            continue;
        }
        let f = n.first_child as usize;
        let mut m = [DVec3::ZERO; 3];
        for c in f..f + 4 {
            let (w, a) = mean[c];
            let arm = centre(c) - centre(i);
            for k in 0..3 {
                m[k] += moment[c][k] + a * (w[k] - base[k]) * arm;
            }
        }
        moment[i] = m;
    }
    moment
}

/// Each node's first moment (`moment`) per unit of its area times its size, in f32: the
/// moments of a scene drawn a trillion times smaller (1e-42 m^3 for a leaf) are below f32's
/// normal range, while the ratio is the same at every scale.
fn scaled_moments(
    moment: &[[DVec3; 3]],
    centre_size: &[(DVec3, f64)],
    mean: &[(DVec3, f64)],
) -> Vec<[Vec3; 3]> {
    moment
        .iter()
        .zip(centre_size.iter().zip(mean))
        .map(|(m, ((_, size), (_, area)))| {
            let unit = area * size;
            if unit > 0.0 && unit.is_finite() {
                [
                    (m[0] / unit).as_vec3(),
                    (m[1] / unit).as_vec3(),
                    (m[2] / unit).as_vec3(),
                ]
            } else {
                [Vec3::ZERO; 3]
            }
        })
        .collect()
}

/// [`kernel`](super::kernel) `c_x c_y / r^4` and its gradient with respect to the source point `y`, from one
/// set of dot products: with `d = y - x`, `c_x = n . d`, `c_y = -n_y . d`,
/// `grad = (n c_y - n_y c_x - 4 c_x c_y d / |d|^2) / |d|^4`. `None` where a cosine is not
/// positive (the kernel is 0 there).
#[inline]
fn kernel_and_gradient(x: DVec3, n: DVec3, y: DVec3, ny: DVec3) -> Option<(f64, DVec3)> {
    let d = y - x;
    let r2 = d.length_squared();
    let (cx, cy) = (n.dot(d), -ny.dot(d));
    if cx <= 0.0 || cy <= 0.0 || r2 <= 0.0 {
        return None;
    }
    let r4 = r2 * r2;
    Some((
        cx * cy / r4,
        (n * cy - ny * cx - d * (4.0 * cx * cy / r2)) / r4,
    ))
}

/// The cell of the polygon's domain that cell `rel` of a tree rooted at `patch` covers.
#[inline]
pub(crate) fn absolute(patch: Cell, rel: Cell) -> Cell {
    Cell {
        level: patch.level + rel.level,
        x: (patch.x << rel.level) + rel.x,
        y: (patch.y << rel.level) + rel.y,
    }
}

/// Weights of a patch's leaves from the integrals of its radiosity over them (`sums`) and their
/// areas: each leaf's mean over the patch's mean, per channel (1 in a channel the patch does
/// not reflect), rounded to `f32`. `None` when every weight is within `flat` of 1: the patch is
/// as good as uniform and costs a gather nothing more.
pub(crate) fn weights(sums: &[DVec3], areas: &[f64], flat: f64) -> Option<Vec<[f32; 3]>> {
    let total: DVec3 = sums.iter().sum();
    let area: f64 = areas.iter().sum();
    if area.is_nan() || area <= 0.0 {
        return None;
    }
    let mean = total / area;
    let mut spread = 0.0f64;
    let cells: Vec<[f32; 3]> = sums
        .iter()
        .zip(areas)
        .map(|(s, &a)| {
            let m = if a > 0.0 { *s / a } else { mean };
            let ch = |k: usize| {
                if mean[k] > 0.0 && m[k].is_finite() {
                    (m[k] / mean[k]).max(0.0) as f32
                } else {
                    1.0
                }
            };
            let w = [ch(0), ch(1), ch(2)];
            for x in w {
                spread = spread.max((x as f64 - 1.0).abs());
            }
            w
        })
        .collect();
    (spread > flat).then_some(cells)
}

/// Share of a gather's tolerance for one patch ([`SHAPE_TAU`]) that one far, partly hidden
/// node of its shape may leave (see `correction`): nodes along a hole's outline are opened
/// until each one's possible error is below it.
pub(crate) const NODE_BUDGET: f64 = 4.0;

/// A gather corrects a shaped patch's transfer where its error estimate passes this fraction
/// of the scene's `radiosity.tolerance` times what the point receives (see
/// [`Transfer::gather`](super::Transfer::gather)). A point sees tens of patches whose errors
/// can share a sign, so the budget per patch is a small part of the tolerance. The
/// corrections are most of a solve's time (a Cornell box gather corrects about 40 patches per
/// vertex): at 0.1 the shipped scenes' solves take 0.8-0.9 of the time they take at 0.05 and
/// no polygon's mean moves by more than 0.23 % of it (the studio's dark pieces; 0.08 % in the
/// furnished room, 0.06 % on the Cornell box), a tenth of the path tracer's standard error at
/// 16,384 samples; at 0.2 the studio's pieces lose 0.26 % together for 0.96 of the time.
pub(crate) const SHAPE_TAU: f64 = 0.1;

/// See [`SHAPE_TAU`].
pub(crate) fn shape_tolerance(tolerance: f64) -> f64 {
    SHAPE_TAU * tolerance
}

/// Luminance of the shape's weight where the ray target at unit-square position (su, sv) of
/// the patch lands (1 without a shape): the visibility estimate's extra weight.
#[inline]
pub(crate) fn shape_weight(shape: Option<&PatchShape>, su: f64, sv: f64) -> f64 {
    shape.map_or(1.0, |s| s.luminance_at(su, sv))
}
