//! Tests of the radiosity textures, by concern: the filters and the level of detail (`filters`),
//! anisotropic lookups (`anisotropic`),
//! sizes and memory (`sizes`), mip chains, placements and gutters (`chains`); the helpers they
//! share are here.

use super::*;
use crate::Estimator;
use base::quadtree::Quadtree;
use proptest::prelude::*;

mod anisotropic;
mod chains;
mod filters;
mod sizes;

/// A texture whose texel (i, j) holds f(i, j) in all three channels.
fn tex(n: u32, f: impl Fn(u32, u32) -> f32) -> RadiosityTexture {
    let mut t = Vec::new();
    for j in 0..n {
        for i in 0..n {
            t.push(Vec3::splat(f(i, j)));
        }
    }
    RadiosityTexture::from_texels(n, n, t).unwrap()
}

/// A deterministic irregular 1-D sequence (no symmetry that could hide an index error).
fn seq(i: u32) -> f32 {
    ((i * 37 + 11) % 17) as f32 * 0.25 - 1.0
}

/// Irregular distinct channels from the bits of (u, v), for textures with gutters.
fn hashed(u: f32, v: f32) -> Vec3 {
    let h = (u.to_bits() ^ v.to_bits().rotate_left(13)).wrapping_mul(2654435761);
    Vec3::new(
        seq(h >> 20),
        seq((h >> 8) & 0xfff) + 2.0,
        0.5 * seq(h & 0xff) - 3.0,
    )
}

/// Extents of square polygons (aspect 0) at the given depths.
fn square(depths: &[u32]) -> Vec<Extent> {
    depths
        .iter()
        .map(|&depth| Extent { depth, aspect: 0 })
        .collect()
}
