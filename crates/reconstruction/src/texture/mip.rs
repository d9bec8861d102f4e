//! The mip chain of a radiosity texture: each level's texels over the parameter square, the box
//! filter that halves a level, and the gutters, filled by reflecting the texels through the
//! RRP's edge values so that a filter at a polygon's edge returns the RRP's value there.

use super::*;

/// One level of a mip chain (see `mip_chain`): `width` x `height` texels over the polygon's
/// parameter square, stored with `gutter` more texels beyond each edge.
///
/// Texel (i, j) of the level, with i in `-gutter..width + gutter` and j likewise, sits at the
/// position the placement gives index i (outside the square for the gutter's indices) and is
/// stored at row `j + gutter`, column `i + gutter`. The filters map coordinates with `width`
/// and `height` alone, so a gutter changes which texels an edge lookup reads (its own gutter
/// instead of a clamped copy of the edge texel), not where the texels sit.
#[derive(Debug, Clone, PartialEq)]
pub struct MipLevel {
    /// Texels per row over the parameter square.
    pub width: u32,
    /// Rows over the parameter square.
    pub height: u32,
    /// Texels stored beyond each of the four edges.
    pub gutter: u32,
    /// Row-major texels, [`MipLevel::stride`] x [`MipLevel::rows`] of them, gutters included.
    pub texels: Vec<Vec3>,
}

/// Area weights of a box filter from `src` texels to `dst` texels along one axis: destination
/// texel x covers source interval [x src / dst, (x + 1) src / dst); each entry lists the source
/// texels it overlaps with their overlap length divided by the footprint length (summing to 1).
fn box_weights(src: u32, dst: u32) -> Vec<Vec<(usize, f64)>> {
    let r = src as f64 / dst as f64;
    (0..dst)
        .map(|x| {
            let (a, b) = (x as f64 * r, (x + 1) as f64 * r);
            let lo = a.floor() as u32;
            let hi = (b.ceil() as u32).min(src);
            (lo..hi)
                .filter_map(|k| {
                    let ov = (b.min(k as f64 + 1.0) - a.max(k as f64)) / r;
                    (ov > 0.0).then_some((k as usize, ov))
                })
                .collect()
        })
        .collect()
}

impl MipLevel {
    /// Stored texels per row: `width + 2 gutter`.
    #[inline(always)]
    pub fn stride(&self) -> u32 {
        self.width + 2 * self.gutter
    }

    /// Stored rows: `height + 2 gutter`.
    #[inline(always)]
    pub fn rows(&self) -> u32 {
        self.height + 2 * self.gutter
    }

    /// Texel (i, j) in level coordinates (0..width is the square, the gutter's indices lie
    /// beyond), clamped to the stored texels (clamp-to-edge addressing past the gutter).
    #[inline(always)]
    pub fn texel(&self, i: i32, j: i32) -> Vec3 {
        let g = self.gutter as i32;
        let x = (i + g).clamp(0, self.stride() as i32 - 1) as usize;
        let y = (j + g).clamp(0, self.rows() as i32 - 1) as usize;
        self.texels[y * self.stride() as usize + x]
    }

    /// Texels stored, gutters included.
    pub fn stored(&self) -> u64 {
        self.stride() as u64 * self.rows() as u64
    }

    /// The next coarser level of a chain, box-filtered from this one's square (no gutter).
    fn downsample(&self) -> MipLevel {
        debug_assert_eq!(self.gutter, 0);
        let (w, h) = (self.width, self.height);
        let (nw, nh) = ((w / 2).max(1), (h / 2).max(1));
        let wx = box_weights(w, nw);
        let wy = box_weights(h, nh);
        let mut texels = Vec::with_capacity(nw as usize * nh as usize);
        for ys in &wy {
            for xs in &wx {
                let mut acc = [0.0f64; 3];
                for &(y, a) in ys {
                    for &(x, b) in xs {
                        let t = self.texels[y * w as usize + x];
                        for (c, tc) in acc.iter_mut().zip(t.to_array()) {
                            *c += a * b * tc as f64;
                        }
                    }
                }
                texels.push(Vec3::new(acc[0] as f32, acc[1] as f32, acc[2] as f32));
            }
        }
        MipLevel {
            width: nw,
            height: nh,
            gutter: 0,
            texels,
        }
    }
}

/// A level-of-detail chain from its finest level: each next level half the size
/// (`max(1, size / 2)` per axis) down to 1 x 1, box-filtered from the previous one with area
/// weights (exact for odd sizes; for powers of two the plain 2 x 2 or 2 x 1 average). Box filtering
/// keeps every level's mean equal to level 0's and averages sharp shadow edges instead of aliasing
/// them, which point-resampling the RRP at 1 x 1 would do. Empty if level 0 is empty.
pub(crate) fn mip_chain(level0: MipLevel) -> Vec<MipLevel> {
    if level0.width == 0 || level0.height == 0 {
        return Vec::new();
    }
    let mut levels = vec![level0];
    while let Some(last) = levels.last().filter(|l| l.width > 1 || l.height > 1) {
        let next = last.downsample();
        levels.push(next);
    }
    levels
}

/// The chain of a corner-aligned texture of `width` x `height`: level l (`max(1, width >> l)` x
/// `max(1, height >> l)`, down to 1 x 1) is `sample(w, h)`, the w x h values at the corner
/// positions i / (n - 1) (0.5 for n = 1) of that level. Point samples, not averages: a coarse
/// corner-aligned texel stands for the value at its position, and no average of the finer level
/// sits there.
pub(crate) fn corner_chain(
    width: u32,
    height: u32,
    mut sample: impl FnMut(u32, u32) -> Vec<Vec3>,
) -> Vec<MipLevel> {
    let mut levels = Vec::new();
    let (mut w, mut h) = (width.max(1), height.max(1));
    loop {
        levels.push(MipLevel {
            width: w,
            height: h,
            gutter: 0,
            texels: sample(w, h),
        });
        if w == 1 && h == 1 {
            return levels;
        }
        (w, h) = ((w / 2).max(1), (h / 2).max(1));
    }
}

/// The chain of a texture of `width` x `height` under `placement` with `gutter` texels beyond
/// each edge of every level. `inside(w, h)` gives the w x h values at the placement's positions
/// ([`mip_chain`] box-filters Centre level 0; [`corner_chain`] samples every Corner level);
/// `edge(u, v)` gives the function's value at a point of the square's border (Centre only:
/// corner-placed levels hold their edge values as texels). The gutters are filled by
/// [`MipLevel::reflected`] through the edge values of each level ([`EdgeValues`]).
pub(super) fn placed_chain(
    (width, height): (u32, u32),
    placement: Placement,
    gutter: u32,
    mut inside: impl FnMut(u32, u32) -> Vec<Vec3>,
    edge: impl Fn(f32, f32) -> Vec3,
) -> Vec<MipLevel> {
    match placement {
        Placement::Centre => {
            let square = mip_chain(MipLevel {
                width,
                height,
                gutter: 0,
                texels: inside(width, height),
            });
            if gutter == 0 {
                return square;
            }
            centre_gutters(square, gutter, EdgeValues::centre(width, height, &edge))
        }
        Placement::Corner => corner_chain(width, height, inside)
            .into_iter()
            .map(|level| {
                let e = EdgeValues::of_corner_level(&level);
                level.reflected(gutter, &e, Placement::Corner)
            })
            .collect(),
    }
}

/// A centre-placed chain with `gutter` texels reflected beyond every level's edges through `e`,
/// level 0's edge values, halved along each axis as the levels halve it
/// ([`EdgeValues::halved`]).
pub(super) fn centre_gutters(
    square: Vec<MipLevel>,
    gutter: u32,
    mut e: EdgeValues,
) -> Vec<MipLevel> {
    let mut levels = Vec::with_capacity(square.len());
    for level in square {
        e = e.halved(level.width, level.height);
        levels.push(level.reflected(gutter, &e, Placement::Centre));
    }
    levels
}

/// The values a level's gutters are reflected through: along the edges u = 0 (`u0[j]`, row j),
/// u = 1, v = 0 (`v0[i]`, column i) and v = 1, and at the corners (0, 0), (1, 0), (0, 1),
/// (1, 1) in that order.
#[derive(Debug, Clone)]
pub(super) struct EdgeValues {
    u0: Vec<Vec3>,
    u1: Vec<Vec3>,
    v0: Vec<Vec3>,
    v1: Vec<Vec3>,
    corners: [Vec3; 4],
}

impl EdgeValues {
    /// Level 0 of a centre-placed texture of `w` x `h`: the function on the border at the
    /// texel rows' and columns' centres, and at the corners.
    fn centre(w: u32, h: u32, edge: &impl Fn(f32, f32) -> Vec3) -> EdgeValues {
        let at = |k: u32, n: u32| Placement::Centre.texel_position(k, n);
        EdgeValues {
            u0: (0..h).map(|j| edge(0.0, at(j, h))).collect(),
            u1: (0..h).map(|j| edge(1.0, at(j, h))).collect(),
            v0: (0..w).map(|i| edge(at(i, w), 0.0)).collect(),
            v1: (0..w).map(|i| edge(at(i, w), 1.0)).collect(),
            corners: [
                edge(0.0, 0.0),
                edge(1.0, 0.0),
                edge(0.0, 1.0),
                edge(1.0, 1.0),
            ],
        }
    }

    /// The edge values of a centre-placed level of `w` x `h` whose chain these values (of the
    /// same or the next finer level) belong to: along each axis the level halved, each edge
    /// value is the mean of the two it covers, as the box filter averages the texels beside
    /// the edge (an axis the level did not halve, and the corners, which are points, stay).
    fn halved(self, w: u32, h: u32) -> EdgeValues {
        let half = |e: Vec<Vec3>, n: u32| -> Vec<Vec3> {
            if e.len() <= n as usize {
                return e;
            }
            e.chunks_exact(2)
                .map(|p| ((p[0].as_dvec3() + p[1].as_dvec3()) * 0.5).as_vec3())
                .collect()
        };
        EdgeValues {
            u0: half(self.u0, h),
            u1: half(self.u1, h),
            v0: half(self.v0, w),
            v1: half(self.v1, w),
            corners: self.corners,
        }
    }

    /// The edge values a centre-placed level with a gutter of at least 1 was reflected through,
    /// read back from its texels: `E = (g + t) / 2` for the gutter texel g beside texel t
    /// (`g = 2 E - t`), and each corner from the corner gutter texel, which reflects the
    /// already reflected row through `2 c - v0[0]` (and likewise at the other corners). Equal to
    /// the values written to within the one rounding of each gutter texel.
    pub(super) fn of_centre_gutter(l: &MipLevel) -> EdgeValues {
        let (w, h) = (l.width as i32, l.height as i32);
        let mean = |a: Vec3, b: Vec3| ((a.as_dvec3() + b.as_dvec3()) * 0.5).as_vec3();
        let u0: Vec<Vec3> = (0..h)
            .map(|j| mean(l.texel(-1, j), l.texel(0, j)))
            .collect();
        let u1: Vec<Vec3> = (0..h)
            .map(|j| mean(l.texel(w, j), l.texel(w - 1, j)))
            .collect();
        let v0: Vec<Vec3> = (0..w)
            .map(|i| mean(l.texel(i, -1), l.texel(i, 0)))
            .collect();
        let v1: Vec<Vec3> = (0..w)
            .map(|i| mean(l.texel(i, h), l.texel(i, h - 1)))
            .collect();
        // Corner (i, j) outside both edges: t = 2 (2 c - along) - beside.
        let corner = |i: i32, j: i32, beside_j: i32, along: Vec3| -> Vec3 {
            let row = mean(l.texel(i, j), l.texel(i, beside_j));
            mean(row, along)
        };
        let corners = [
            corner(-1, -1, 0, v0[0]),
            corner(w, -1, 0, v0[w as usize - 1]),
            corner(-1, h, h - 1, v1[0]),
            corner(w, h, h - 1, v1[w as usize - 1]),
        ];
        EdgeValues {
            u0,
            u1,
            v0,
            v1,
            corners,
        }
    }

    /// A corner-placed level holds its border: the first and last rows and columns.
    fn of_corner_level(l: &MipLevel) -> EdgeValues {
        let (w, h) = (l.width as i32, l.height as i32);
        EdgeValues {
            u0: (0..h).map(|j| l.texel(0, j)).collect(),
            u1: (0..h).map(|j| l.texel(w - 1, j)).collect(),
            v0: (0..w).map(|i| l.texel(i, 0)).collect(),
            v1: (0..w).map(|i| l.texel(i, h - 1)).collect(),
            corners: [
                l.texel(0, 0),
                l.texel(w - 1, 0),
                l.texel(0, h - 1),
                l.texel(w - 1, h - 1),
            ],
        }
    }
}

/// Index of the texel mirrored through the edge nearest to index `i` on an axis of `n` texels
/// under `p` (the identity inside): centre placement mirrors through the half-way point
/// between texels -1 and 0 (so -1 <-> 0, -2 <-> 1), corner placement through texel 0 itself
/// (-1 <-> 1), and likewise at the far edge. Clamped to the axis when the gutter is wider than
/// the level (coarse levels of a few texels).
fn mirror(i: i32, n: i32, p: Placement) -> i32 {
    let m = match (p, i < 0, i >= n) {
        (Placement::Centre, true, _) => -1 - i,
        (Placement::Centre, _, true) => 2 * n - 1 - i,
        (Placement::Corner, true, _) => -i,
        (Placement::Corner, _, true) => 2 * (n - 1) - i,
        _ => i,
    };
    m.clamp(0, n - 1)
}

/// `2 e - t` in f64, rounded once: the odd reflection of texel `t` through edge value `e`.
fn reflect(e: Vec3, t: Vec3) -> Vec3 {
    (e.as_dvec3() * 2.0 - t.as_dvec3()).as_vec3()
}

impl MipLevel {
    /// This level (which has no gutter yet) with `g` texels beyond each edge holding the odd
    /// reflection of the texels through the edge values `e`: a gutter texel is `2 E - T` for
    /// the mirrored texel T ([`mirror`]) and the edge value E beside it. Rows first (the u
    /// gutters through `u0` and `u1`), then whole columns (the v gutters through `v0` and `v1`,
    /// themselves reflected past the corners through the corner values).
    ///
    /// Why: the filters' weights are symmetric about an edge lookup (bilinear 1/2 and 1/2 on
    /// texels -1 and 0 at u = 0 under centre placement; Mitchell-Netravali k(1.5), k(0.5),
    /// k(0.5), k(1.5) on -2 .. 1; under corner placement k(1), k(0), k(1) on -1 .. 1), so each
    /// mirrored pair contributes its edge value and the lookup returns E exactly (to f32
    /// rounding), for either filter and whatever the texels inside. Two polygons joined at a
    /// seam have one edge curve, so their textures return one value along it wherever their
    /// texels line up. The reflection also continues the function C1 past the edge (a linear
    /// function is continued exactly). Gutter texels may be negative where the light falls
    /// steeply toward an edge; no lookup in the square returns one alone.
    fn reflected(self, g: u32, e: &EdgeValues, p: Placement) -> MipLevel {
        debug_assert_eq!(self.gutter, 0);
        if g == 0 {
            return self;
        }
        let (w, h, gi) = (self.width as i32, self.height as i32, g as i32);
        let stride = (w + 2 * gi) as usize;
        let at = |i: i32, j: i32| (j + gi) as usize * stride + (i + gi) as usize;
        let mut t = vec![Vec3::ZERO; stride * (h + 2 * gi) as usize];
        for j in 0..h {
            for i in 0..w {
                t[at(i, j)] = self.texels[(j * w + i) as usize];
            }
            for i in (-gi..0).chain(w..w + gi) {
                let edge = if i < 0 {
                    e.u0[j as usize]
                } else {
                    e.u1[j as usize]
                };
                t[at(i, j)] = reflect(edge, t[at(mirror(i, w, p), j)]);
            }
        }
        // The v edges' values continued past the corners, as the rows were.
        let row = |along: &[Vec3], c0: Vec3, c1: Vec3, i: i32| -> Vec3 {
            match i {
                i if i < 0 => reflect(c0, along[mirror(i, w, p) as usize]),
                i if i >= w => reflect(c1, along[mirror(i, w, p) as usize]),
                i => along[i as usize],
            }
        };
        let [c00, c10, c01, c11] = e.corners;
        for j in (-gi..0).chain(h..h + gi) {
            let mj = mirror(j, h, p);
            for i in -gi..w + gi {
                let edge = if j < 0 {
                    row(&e.v0, c00, c10, i)
                } else {
                    row(&e.v1, c01, c11, i)
                };
                t[at(i, j)] = reflect(edge, t[at(i, mj)]);
            }
        }
        MipLevel {
            width: self.width,
            height: self.height,
            gutter: g,
            texels: t,
        }
    }
}
