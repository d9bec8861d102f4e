//! The lightmap atlas: every polygon's radiosity texture (level 0 with its gutter, exactly the
//! texels the texture methods draw) packed as one rectangle ("chart") into a few power-of-two
//! pages.
//!
//! A chart is the polygon's texture of w x h texels plus its gutter g on each side, so its
//! rectangle is w + 2g by h + 2g texels; the gutter holds the polygon's RRP continued past its edge
//! (the odd reflection through the RRP's edge values, `reconstruction::texture`), so bilinear and
//! bicubic lookups at a polygon's border read the function's continuation, not a neighbour's
//! texels or a copied edge. Texel (i, j) of the polygon's parameter square, i along u and j along
//! v, is page texel (x + g + i, y + g + j) with row 0 the top of the image: the glTF texture
//! coordinate of parameter (u, v) is ((x + g + u w) / W, (y + g + v h) / H), which puts texel
//! centres where the texture methods put them.
//!
//! A triangle's chart (square, as its texture is: `reconstruction::texture::Extent`) is laid
//! out affinely instead: chart point (s, t) is the triangle's point c0 + s (c1 - c0) + t (c2 -
//! c0) (s + t <= 1, the lower-left half of the square), so an
//! engine's linear interpolation of texture coordinates over the one triangle drawn for it is
//! exact. Its texels are the RRP evaluated at the collapsed-quad parameters of the same point,
//! (u, v) = (s / (1 - t), t), the function the texture methods sample; a texel outside the
//! triangle (the gutter, and the half past the hypotenuse) holds the odd reflection through the
//! nearest point of the triangle, 2 f(q) - f(2 q - p), so a bilinear lookup on an edge returns
//! the edge's value to second order, as the square charts' gutters do.
//!
//! Packing uses the `crunch` packer (rectangles by decreasing area, best-fit into a split free
//! list), one page at a time: whatever does not fit in a page of the largest side goes to the
//! next; each page is then shrunk to the smallest power-of-two rectangle its charts fit in.
//! Deterministic: the packer sorts stably and the charts are offered in polygon order.

use glam::Vec3;

use base::error::{Error, Result};
use reconstruction::texture::{Placement, TextureSet};
use reconstruction::Reconstruction;
use scene::{Scene, Shape};

/// One polygon's rectangle in the atlas.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Chart {
    /// The page it lies on.
    pub page: u32,
    /// Left column of its rectangle, gutter included.
    pub x: u32,
    /// Top row of its rectangle, gutter included.
    pub y: u32,
    /// Texels of the chart along u (a triangle's: along its affine s; its chart is square),
    /// gutter excluded: the polygon's texture width.
    pub width: u32,
    /// Texels of the chart along v, gutter excluded.
    pub height: u32,
    /// Laid out affinely (a triangle, see the module docs), not by the (u, v) square.
    pub triangle: bool,
}

/// One page: linear radiosity texels, row-major, row 0 the top of the image.
#[derive(Debug, Clone, PartialEq)]
pub struct Page {
    /// Texels per row (a power of two).
    pub width: u32,
    /// Rows (a power of two).
    pub height: u32,
    /// The texels; those no chart covers are 0.
    pub texels: Vec<Vec3>,
}

/// The packed atlas of a scene.
#[derive(Debug, Clone, PartialEq)]
pub struct Atlas {
    /// Texels of every chart beyond each edge of its polygon's square.
    pub gutter: u32,
    /// One chart per polygon, in scene polygon order.
    pub charts: Vec<Chart>,
    /// The pages.
    pub pages: Vec<Page>,
}

/// How well the atlas is packed and how densely it samples the scene.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct AtlasStats {
    /// Pages.
    pub pages: u32,
    /// Texels over every page.
    pub page_texels: u64,
    /// Texels of every chart, gutters included.
    pub chart_texels: u64,
    /// Texels of the polygons' parameter squares (what the texture methods filter inside a
    /// polygon).
    pub square_texels: u64,
    /// Chart texels over page texels: how tightly the packer filled the pages.
    pub packing: f64,
    /// Square texels over page texels: the share of the pages that samples a polygon.
    pub utilization: f64,
    /// Texels per scene unit along a polygon (sqrt(width height / area)): least, median,
    /// greatest.
    pub texels_per_unit: [f64; 3],
    /// Charts per longer texture side, smallest first: (side, count).
    pub sides: Vec<(u32, u32)>,
    /// Each page's width and height.
    pub page_sizes: Vec<(u32, u32)>,
}

/// Largest page side accepted.
pub const MAX_PAGE: u32 = 16384;

impl Atlas {
    /// Packs the textures of `set` (centre-placed, one per polygon of `scene`) into pages of at
    /// most `max_page` x `max_page` texels and copies each texture's level 0 with its gutter
    /// into its chart. Errors for a corner-placed set, a set that does not match the scene, a
    /// page side that is not a power of two in `64..=MAX_PAGE`, or a chart larger than a page.
    pub fn build(
        scene: &Scene,
        set: &TextureSet,
        recon: &Reconstruction,
        max_page: u32,
    ) -> Result<Atlas> {
        if set.placement != Placement::Centre {
            return Err(Error::internal(
                "the atlas holds centre-placed textures only",
            ));
        }
        if set.textures.len() != scene.polygons.len() {
            return Err(Error::internal(format!(
                "{} textures for {} polygons",
                set.textures.len(),
                scene.polygons.len()
            )));
        }
        check_page(max_page)?;
        let g = set.gutter;
        let dims: Vec<(u32, u32)> = set.textures.iter().map(|t| (t.width, t.height)).collect();
        if let Some(p) = (0..dims.len())
            .find(|&p| scene.polygons[p].shape == Shape::Triangle && dims[p].0 != dims[p].1)
        {
            return Err(Error::internal(format!(
                "triangle {p}'s texture is not square: {} x {}",
                dims[p].0, dims[p].1
            )));
        }
        let (mut charts, sizes) = pack(&dims, g, max_page)?;
        for (c, p) in charts.iter_mut().zip(&scene.polygons) {
            c.triangle = p.shape == Shape::Triangle;
        }
        let mut pages: Vec<Page> = sizes
            .iter()
            .map(|&(w, h)| Page {
                width: w,
                height: h,
                texels: vec![Vec3::ZERO; w as usize * h as usize],
            })
            .collect();
        for (polygon, (chart, tex)) in charts.iter().zip(&set.textures).enumerate() {
            let level = &tex.levels[0];
            let page = &mut pages[chart.page as usize];
            let (stride, rows): (usize, Vec<Vec3>) = if chart.triangle {
                let rows = triangle_chart(chart.width, g, |s, t| {
                    let (u, v) = square_of_affine(s, t);
                    recon.eval(polygon as u32, u as f32, v as f32)
                });
                ((chart.width + 2 * g) as usize, rows)
            } else {
                (level.stride() as usize, level.texels.clone())
            };
            for (r, row) in rows.chunks_exact(stride).enumerate() {
                let start = (chart.y as usize + r) * page.width as usize + chart.x as usize;
                page.texels[start..start + stride].copy_from_slice(row);
            }
        }
        Ok(Atlas {
            gutter: g,
            charts,
            pages,
        })
    }

    /// The texture coordinate on its page of parameter (u, v) of `polygon`.
    pub fn uv(&self, polygon: usize, u: f64, v: f64) -> [f32; 2] {
        let c = &self.charts[polygon];
        let (u, v) = if c.triangle {
            affine_of_square(u, v)
        } else {
            (u, v)
        };
        let p = &self.pages[c.page as usize];
        let g = self.gutter as f64;
        let (w, h) = (c.width as f64, c.height as f64);
        [
            ((c.x as f64 + g + u * w) / p.width as f64) as f32,
            ((c.y as f64 + g + v * h) / p.height as f64) as f32,
        ]
    }

    /// Packing and density figures (`scene` gives the polygons' areas).
    pub fn stats(&self, scene: &Scene) -> AtlasStats {
        let page_texels: u64 = self
            .pages
            .iter()
            .map(|p| p.width as u64 * p.height as u64)
            .sum();
        let g = 2 * self.gutter as u64;
        let chart_texels: u64 = self
            .charts
            .iter()
            .map(|c| (c.width as u64 + g) * (c.height as u64 + g))
            .sum();
        let square_texels: u64 = self
            .charts
            .iter()
            .map(|c| c.width as u64 * c.height as u64)
            .sum();
        let mut density: Vec<f64> = self
            .charts
            .iter()
            .zip(&scene.polygons)
            .map(|(c, p)| (c.width as f64 * c.height as f64 / p.area).sqrt())
            .collect();
        density.sort_by(f64::total_cmp);
        let texels_per_unit = match density.len() {
            0 => [0.0; 3],
            n => [density[0], density[n / 2], density[n - 1]],
        };
        let share = |t: u64| t as f64 / page_texels.max(1) as f64;
        let mut sides = std::collections::BTreeMap::new();
        for c in &self.charts {
            *sides.entry(c.width.max(c.height)).or_insert(0u32) += 1;
        }
        AtlasStats {
            pages: self.pages.len() as u32,
            page_texels,
            chart_texels,
            square_texels,
            packing: share(chart_texels),
            utilization: share(square_texels),
            texels_per_unit,
            sides: sides.into_iter().collect(),
            page_sizes: self.pages.iter().map(|p| (p.width, p.height)).collect(),
        }
    }
}

/// A triangle's affine chart coordinates (s, t) of its collapsed-quad parameters (u, v): the
/// barycentric weights of c1 and c2, (u (1 - v), v).
pub fn affine_of_square(u: f64, v: f64) -> (f64, f64) {
    (u * (1.0 - v), v)
}

/// A triangle's collapsed-quad parameters (u, v) of its affine chart coordinates (s, t): (s /
/// (1 - t), t), u held within the gutter's reach (it grows without bound towards the apex,
/// where every u is the same point).
pub fn square_of_affine(s: f64, t: f64) -> (f64, f64) {
    let u = if t < 1.0 { s / (1.0 - t) } else { 0.5 };
    (u.clamp(-1.0, 2.0), t)
}

/// The texels of a triangle's affine chart of side `n` with gutter `g` (see the module docs):
/// `f(s, t)` at texel centres inside the triangle s, t >= 0, s + t <= 1, the odd reflection
/// through the nearest point of the triangle outside it (linear extrapolation along the same
/// line from a nearer point where the mirror point would leave the triangle, the gradient
/// inside the triangle beyond a corner).
pub fn triangle_chart(n: u32, g: u32, f: impl Fn(f64, f64) -> Vec3) -> Vec<Vec3> {
    let e = (n + 2 * g) as usize;
    let (nf, gf) = (n as f64, g as f64);
    let mut out = Vec::with_capacity(e * e);
    for j in 0..e {
        for i in 0..e {
            let p = ((i as f64 - gf + 0.5) / nf, (j as f64 - gf + 0.5) / nf);
            let q = nearest_in_triangle(p);
            if q == p {
                out.push(f(p.0, p.1));
                continue;
            }
            // The mirror point q - (p - q), or nearer q where that leaves the triangle (by a
            // corner, across another edge): the extrapolation f(q) + (f(q) - f(m)) / k along
            // the same line is exact for a linear function whatever k.
            let mut k = 1.0;
            let inside = |k: f64| {
                let m = (q.0 + k * (q.0 - p.0), q.1 + k * (q.1 - p.1));
                (nearest_in_triangle(m) == m).then_some(m)
            };
            let mut m = inside(k);
            while m.is_none() && k > 0.25 {
                k *= 0.5;
                m = inside(k);
            }
            let fq = f(q.0, q.1);
            out.push(match m {
                Some(m) => fq + (fq - f(m.0, m.1)) / k as f32,
                None => fq + corner_slope(&f, q, p),
            });
        }
    }
    out
}

/// Where no line from `p` through its nearest point `q` runs on inside the triangle (`q` a
/// corner, `p` across both its edges): `f`'s gradient from differences inside the triangle
/// (about the point a quarter of the way from `q` to the centroid, steps 0.05 along s and t,
/// which stay inside) times `p - q`, a linear continuation.
fn corner_slope(f: &impl Fn(f64, f64) -> Vec3, q: (f64, f64), p: (f64, f64)) -> Vec3 {
    let third = 1.0 / 3.0;
    let a = (q.0 + 0.25 * (third - q.0), q.1 + 0.25 * (third - q.1));
    let h = 0.05;
    let f0 = f(a.0, a.1);
    let ds = (f(a.0 + h, a.1) - f0) / h as f32;
    let dt = (f(a.0, a.1 + h) - f0) / h as f32;
    ds * (p.0 - q.0) as f32 + dt * (p.1 - q.1) as f32
}

/// The point of the triangle s, t >= 0, s + t <= 1 nearest `p` (`p` itself inside).
fn nearest_in_triangle((s, t): (f64, f64)) -> (f64, f64) {
    if s >= 0.0 && t >= 0.0 && s + t <= 1.0 {
        return (s, t);
    }
    // Onto the hypotenuse's line, then clamped to the triangle's edges in turn: for a right
    // isosceles triangle this is the Euclidean projection.
    let (mut s, mut t) = (s, t);
    if s + t > 1.0 {
        let d = 0.5 * (s + t - 1.0);
        (s, t) = (s - d, t - d);
    }
    if s < 0.0 {
        s = 0.0;
    }
    if t < 0.0 {
        t = 0.0;
    }
    (s.min(1.0), t.min(1.0 - s.min(1.0)))
}

/// A level of side `n` with gutter `g` (row-major `texels`, `n + 2g` a side) resampled texel by
/// texel: texel (i, j) of the result, at coordinates (a, b) = ((i - g + 1/2) / n, (j - g +
/// 1/2) / n), is the bilinear lookup of the source at `map(a, b)` (texel centres at (k + 1/2) /
/// n, clamped to the stored texels).
pub fn resample(texels: &[Vec3], n: u32, g: u32, map: fn(f64, f64) -> (f64, f64)) -> Vec<Vec3> {
    let e = (n + 2 * g) as usize;
    let (nf, gf) = (n as f64, g as f64);
    let at = |i: usize, j: usize| texels[j.min(e - 1) * e + i.min(e - 1)];
    let mut out = Vec::with_capacity(e * e);
    for j in 0..e {
        for i in 0..e {
            let (a, b) = ((i as f64 - gf + 0.5) / nf, (j as f64 - gf + 0.5) / nf);
            let (u, v) = map(a, b);
            // Continuous texel coordinates of the stored level (centre of texel k at k + 1/2).
            let x = (u * nf + gf - 0.5).clamp(0.0, (e - 1) as f64);
            let y = (v * nf + gf - 0.5).clamp(0.0, (e - 1) as f64);
            let (x0, y0) = (x.floor() as usize, y.floor() as usize);
            let (fx, fy) = ((x - x0 as f64) as f32, (y - y0 as f64) as f32);
            let top = at(x0, y0) * (1.0 - fx) + at(x0 + 1, y0) * fx;
            let bottom = at(x0, y0 + 1) * (1.0 - fx) + at(x0 + 1, y0 + 1) * fx;
            out.push(top * (1.0 - fy) + bottom * fy);
        }
    }
    out
}

/// Checks a largest page side: a power of two in `64..=MAX_PAGE`.
pub fn check_page(side: u32) -> Result<()> {
    if !(64..=MAX_PAGE).contains(&side) || !side.is_power_of_two() {
        return Err(Error::invalid_option(
            "page-size",
            side.to_string(),
            format!("must be a power of two from 64 to {MAX_PAGE}"),
        ));
    }
    Ok(())
}

/// Where every chart lies and each page's size, as the packers return them.
type Packing = (Vec<Chart>, Vec<(u32, u32)>);

/// Pages a packing leaves no emptier than this when a smaller page can take the rest.
pub const FILL_AIM: f64 = 0.7;

/// Places charts of the given sizes (width, height; plus `g` on each side) on pages of at most
/// `max_page` texels a side: the charts (in polygon order) and each page's size.
///
/// Two packings are made and the one whose pages are fuller kept (fewer pages on a tie): all
/// charts on the smallest power-of-two page that holds them, when one within `max_page` does;
/// and page by page ([`pack_pages`]).
fn pack(dims: &[(u32, u32)], g: u32, max_page: u32) -> Result<Packing> {
    let edge = |s: u32| (s + 2 * g) as usize;
    if let Some((p, &(w, h))) = dims
        .iter()
        .enumerate()
        .find(|(_, &(w, h))| edge(w.max(h)) > max_page as usize)
    {
        return Err(Error::invalid_option(
            "page-size",
            max_page.to_string(),
            format!(
                "is smaller than polygon {p}'s chart ({} x {} texels with its gutter)",
                edge(w),
                edge(h)
            ),
        ));
    }
    let paged = pack_pages(dims, g, max_page);
    let items = (0..dims.len())
        .map(|p| crunch::Item::new(p, edge(dims[p].0), edge(dims[p].1), crunch::Rotation::None));
    let Ok(one) = crunch::pack_into_po2(max_page as usize, items) else {
        return Ok(paged);
    };
    let area: usize = dims.iter().map(|&(w, h)| edge(w) * edge(h)).sum();
    let paged_area: usize = paged.1.iter().map(|&(w, h)| (w * h) as usize).sum();
    if one.w * one.h > paged_area
        || (one.w * one.h == paged_area && paged.1.len() == 1)
        || area == 0
    {
        return Ok(paged);
    }
    let mut charts = unplaced(dims.len());
    place(&mut charts, 0, &one.items, dims);
    Ok((charts, vec![(one.w as u32, one.h as u32)]))
}

/// `n` charts not placed yet.
fn unplaced(n: usize) -> Vec<Chart> {
    let none = Chart {
        page: 0,
        x: 0,
        y: 0,
        width: 0,
        height: 0,
        triangle: false,
    };
    vec![none; n]
}

/// Records where the packer put `items` (polygon indices) on page `page`.
fn place(
    charts: &mut [Chart],
    page: u32,
    items: &[crunch::PackedItem<usize>],
    dims: &[(u32, u32)],
) {
    for it in items {
        charts[it.data] = Chart {
            page,
            x: it.rect.x as u32,
            y: it.rect.y as u32,
            width: dims[it.data].0,
            height: dims[it.data].1,
            triangle: false,
        };
    }
}

/// Page by page: when everything left fits the smallest power-of-two page that holds it
/// ([`crunch::pack_into_po2`]) at least [`FILL_AIM`] full, or no smaller page could be filled
/// better, that page is the last. Otherwise the page is the largest power-of-two rectangle
/// (square, or twice as wide as high) no larger than what is left, and it is filled largest
/// chart first, a chart that does not fit waiting for the next page while smaller ones are
/// tried ([`fill`]). Every chart fits a page (checked by [`pack`]).
fn pack_pages(dims: &[(u32, u32)], g: u32, max_page: u32) -> Packing {
    let edge = |s: u32| (s + 2 * g) as usize;
    let mut charts = unplaced(dims.len());
    let mut sizes = Vec::new();
    // Largest area first, then longest side, ties in polygon order (crunch sorts stably by
    // area and side, so its order is this one).
    let mut left: Vec<usize> = (0..dims.len()).collect();
    let key = |p: usize| {
        let (w, h) = (edge(dims[p].0), edge(dims[p].1));
        std::cmp::Reverse((w * h, w.max(h)))
    };
    left.sort_by_key(|&p| key(p));
    while !left.is_empty() {
        let item = |&p: &usize| {
            crunch::Item::new(p, edge(dims[p].0), edge(dims[p].1), crunch::Rotation::None)
        };
        let area: usize = left
            .iter()
            .map(|&p| edge(dims[p].0) * edge(dims[p].1))
            .sum();
        let largest = left
            .iter()
            .map(|&p| (edge(dims[p].0), edge(dims[p].1)))
            .fold((0, 0), |a, b| (a.0.max(b.0), a.1.max(b.1)));
        let last = crunch::pack_into_po2(max_page as usize, left.iter().map(item)).ok();
        let page = fill_page(area, largest, max_page as usize);
        let (w, h, placed, rest) = match last {
            Some(p)
                if area as f64 >= FILL_AIM * (p.w * p.h) as f64 || page.0 * page.1 >= p.w * p.h =>
            {
                (p.w, p.h, p.items, Vec::new())
            }
            _ => {
                let (placed, rest) = fill(page, &left, &item);
                (page.0, page.1, placed, rest)
            }
        };
        place(&mut charts, sizes.len() as u32, &placed, dims);
        sizes.push((w as u32, h as u32));
        left = rest;
    }
    (charts, sizes)
}

/// The largest power-of-two page (square, or twice as wide as high; at most `max` a side) of at
/// most `area` texels that holds the widest and the tallest chart (`largest`, width and
/// height); the smallest square page that holds them when none is that small.
fn fill_page(area: usize, largest: (usize, usize), max: usize) -> (usize, usize) {
    let (lw, lh) = largest;
    let mut side = max;
    while side >= lw.max(lh) {
        for (w, h) in [(side, side), (side, side / 2)] {
            if w >= lw && h >= lh && w * h <= area {
                return (w, h);
            }
        }
        side /= 2;
    }
    let s = lw.max(lh).next_power_of_two().min(max);
    (s, s)
}

/// Fills a page of `page` = (w, h) from `left` (largest first): packs them all, and when one
/// does not fit, sets it aside for the next page and packs again without it, until everything
/// not set aside fits. Returns what was placed and what waits, in order.
fn fill(
    page: (usize, usize),
    left: &[usize],
    item: &dyn Fn(&usize) -> crunch::Item<usize>,
) -> (Vec<crunch::PackedItem<usize>>, Vec<usize>) {
    let rect = crunch::Rect::of_size(page.0, page.1);
    let mut trying: Vec<usize> = left.to_vec();
    let mut waiting = Vec::new();
    loop {
        match crunch::pack(rect, trying.iter().map(item)) {
            Ok(all) => {
                waiting.sort_by_key(|&p| left.iter().position(|&q| q == p));
                return (all, waiting);
            }
            Err(some) => {
                // crunch places in the order given and stops at the first that fails; every
                // later chart of its width and height meets the same free space after the same placements,
                // so all of them wait.
                let first = item(&trying[some.len()]);
                let e = (first.w, first.h);
                let end = some.len()
                    + trying[some.len()..]
                        .iter()
                        .take_while(|p| {
                            let it = item(p);
                            (it.w, it.h) == e
                        })
                        .count();
                waiting.extend(trying.drain(some.len()..end));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn overlap(a: &Chart, b: &Chart, g: u32) -> bool {
        let (wa, wb) = (a.width + 2 * g, b.width + 2 * g);
        let (ha, hb) = (a.height + 2 * g, b.height + 2 * g);
        a.page == b.page && a.x < b.x + wb && b.x < a.x + wa && a.y < b.y + hb && b.y < a.y + ha
    }

    /// Charts of mixed power-of-two sizes, squares and rectangles both ways, with a 2-texel
    /// gutter: none overlaps another, all lie inside their page, pages are powers of two, and a
    /// page too small for everything spills onto more pages.
    #[test]
    fn charts_are_disjoint_and_inside_their_pages() {
        let dims: Vec<(u32, u32)> = (0..300)
            .map(|k| {
                let n = 1 << (k % 6);
                match k % 3 {
                    0 => (n, n),
                    1 => (n, (n >> (k % 4)).max(1)),
                    _ => ((n >> (k % 5)).max(1), n),
                }
            })
            .collect();
        for max in [64, 256, 4096] {
            let (charts, sizes) = pack(&dims, 2, max).unwrap();
            for (i, a) in charts.iter().enumerate() {
                let (w, h) = sizes[a.page as usize];
                assert!(w.is_power_of_two() && h.is_power_of_two() && w <= max && h <= max);
                assert!(a.x + a.width + 4 <= w && a.y + a.height + 4 <= h);
                assert_eq!((a.width, a.height), dims[i]);
                for b in &charts[i + 1..] {
                    assert!(!overlap(a, b, 2), "{a:?} overlaps {b:?}");
                }
            }
            // No page holds more than its area; everything fits one 4096 page.
            let area: u64 = dims
                .iter()
                .map(|&(w, h)| (w as u64 + 4) * (h as u64 + 4))
                .sum();
            assert!(sizes.len() as u64 >= area.div_ceil((max as u64).pow(2)));
            if max == 4096 {
                assert_eq!(sizes.len(), 1);
            }
        }
    }

    /// The odd reflection continues a linear function linearly: every texel of a triangle's
    /// chart, inside, in the gutter and past the hypotenuse, is the function at its centre, so
    /// a bilinear lookup anywhere on the triangle, its edges included, is exact.
    #[test]
    fn a_triangle_chart_continues_a_linear_function_past_every_edge() {
        let f = |s: f64, t: f64| Vec3::new((1.0 + 2.0 * s - 3.0 * t) as f32, s as f32, t as f32);
        let (n, g) = (8, 2);
        let texels = triangle_chart(n, g, f);
        let e = (n + 2 * g) as usize;
        for j in 0..e {
            for i in 0..e {
                let (s, t) = ((i as f64 - 1.5) / 8.0, (j as f64 - 1.5) / 8.0);
                let d = (texels[j * e + i] - f(s, t)).abs().max_element();
                assert!(d < 1e-5, "texel ({i}, {j}): {d}");
            }
        }
        // The projection onto the triangle: inside unchanged, outside onto the nearest point.
        for (p, want) in [
            ((0.2, 0.3), (0.2, 0.3)),
            ((0.9, 0.3), (0.8, 0.2)),
            ((-0.5, 1.2), (0.0, 1.0)),
            ((1.2, 0.1), (1.0, 0.0)),
            ((-0.1, -0.1), (0.0, 0.0)),
            ((0.3, -0.5), (0.3, 0.0)),
        ] {
            let got = nearest_in_triangle(p);
            assert!(
                (got.0 - want.0).abs() + (got.1 - want.1).abs() < 1e-12,
                "{p:?}: {got:?}"
            );
        }
    }

    #[test]
    fn a_chart_larger_than_a_page_is_refused() {
        let e = pack(&[(64, 64)], 2, 64).unwrap_err();
        assert!(e.to_string().contains("page-size"), "{e}");
        // Too tall as well as too wide.
        let e = pack(&[(1, 64)], 2, 64).unwrap_err();
        assert!(e.to_string().contains("5 x 68"), "{e}");
        assert!(pack(&[(60, 4)], 2, 64).is_ok());
        assert!(check_page(100).is_err() && check_page(32).is_err() && check_page(128).is_ok());
    }
}
