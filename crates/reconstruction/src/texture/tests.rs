//! Tests of the radiosity textures: analytic filter cases, memory arithmetic, RRP resampling.

use super::*;
use crate::Estimator;
use base::quadtree::Quadtree;
use proptest::prelude::*;

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

#[test]
fn mitchell_of_a_constant_is_the_constant_everywhere() {
    // Weights sum to 1 and clamp-to-edge fetches only the constant, so the result is the
    // constant up to a few f32 roundings of values near 2.5: 1e-5 relative is generous.
    let t = tex(8, |_, _| 2.5);
    for filter in [Filter::MITCHELL, Filter::CATMULL_ROM, Filter::Bilinear] {
        for a in 0..=40 {
            for b in 0..=40 {
                let (u, v) = (a as f32 / 40.0, b as f32 / 40.0 * 0.99 + 0.003);
                let s = t.sample(0, u, v, filter);
                assert!(
                    (s - Vec3::splat(2.5)).abs().max_element() < 2.5e-5,
                    "{u} {v} {s}"
                );
            }
        }
    }
}

proptest! {
    #[test]
    fn cubic_weights_sum_to_one(t in 0.0f32..1.0, b in 0.0f32..1.0, c in 0.0f32..1.0) {
        // Exactly 1 in real arithmetic for every (B, C); f32 evaluation of four cubics with
        // coefficients of order 10 leaves a few ulps: 1e-5.
        let w = Cubic::new(b, c).weights(t);
        prop_assert!((w.iter().sum::<f32>() - 1.0).abs() < 1e-5, "{w:?}");
        // And the branch-free weights agree with the kernel definition.
        let k = Cubic::new(b, c);
        let r = [k.k(1.0 + t), k.k(t), k.k(1.0 - t), k.k(2.0 - t)];
        for (x, y) in w.iter().zip(r) {
            prop_assert!((x - y).abs() < 1e-6);
        }
    }

    #[test]
    fn no_nan_for_any_coordinate(u in prop::num::f32::ANY, v in prop::num::f32::ANY,
                                 d in prop::num::f32::ANY) {
        let t = tex(4, |i, j| seq(i + 4 * j));
        for f in [Filter::Nearest, Filter::Bilinear, Filter::MITCHELL] {
            prop_assert!(t.sample(0, u, v, f).is_finite());
            prop_assert!(t.sample_lod(d, u, v, f).is_finite());
        }
        prop_assert!(lod(u, v, d, u, 16, 16).is_finite());
    }
}

#[test]
fn kernel_values_at_integers() {
    // Mitchell and Netravali 1988: k(0) = 8/9, k(1) = 1/18, k(2) = 0 for Mitchell.
    let k = Cubic::new(1.0 / 3.0, 1.0 / 3.0);
    assert!((k.k(0.0) - 8.0 / 9.0).abs() < 1e-6);
    assert!((k.k(1.0) - 1.0 / 18.0).abs() < 1e-6);
    assert!(k.k(2.0).abs() < 1e-6);
    // The branch-free weights at t = 0 are the same values; the f32 cubic at 2 cancels to a
    // few ulps of its O(1) terms, hence 1e-6.
    let want = [1.0 / 18.0, 8.0 / 9.0, 1.0 / 18.0, 0.0];
    for (w, x) in k.weights(0.0).iter().zip(want) {
        assert!((w - x).abs() < 1e-6, "{w} vs {x}");
    }
}

#[test]
fn mitchell_at_a_texel_centre_blurs_its_neighbours() {
    // Constant along v, so the vertical pass sums weights to 1 and the 1-D result remains:
    // (8/9) f_i + (1/18)(f_{i-1} + f_{i+1}); values are O(1), so 1e-5 absolute.
    let n = 16;
    let t = tex(n, |i, _| seq(i));
    for i in 1..n - 1 {
        let u = (i as f32 + 0.5) / n as f32;
        for v in [0.0, 0.3, 0.77, 1.0] {
            let s = t.sample(0, u, v, Filter::MITCHELL).x;
            let want = 8.0 / 9.0 * seq(i) + (seq(i - 1) + seq(i + 1)) / 18.0;
            assert!((s - want).abs() < 1e-5, "i {i}: {s} vs {want}");
        }
    }
    // At the edge the missing neighbour is the edge texel (clamp-to-edge).
    let s = t.sample(0, 0.5 / n as f32, 0.5, Filter::MITCHELL).x;
    let want = 8.0 / 9.0 * seq(0) + (seq(0) + seq(1)) / 18.0;
    assert!((s - want).abs() < 1e-5);
}

#[test]
fn catmull_rom_interpolates_texel_centres() {
    // k(0) = 1, k(+-1) = k(+-2) = 0, so each texel centre returns its texel; only the f32
    // rounding of u n - 0.5 (which may give t = 1 ulp) remains: 1e-5 on O(1) values.
    let n = 8;
    let t = tex(n, |i, j| seq(i) * 1.5 + seq(j + 3));
    for j in 0..n {
        for i in 0..n {
            let (u, v) = ((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
            let s = t.sample(0, u, v, Filter::CATMULL_ROM).x;
            let want = seq(i) * 1.5 + seq(j + 3);
            assert!((s - want).abs() < 1e-5, "({i}, {j}): {s} vs {want}");
        }
    }
}

#[test]
fn bilinear_of_a_linear_function_is_exact_inside() {
    // Texel (i, j) = f at its centre, f linear; inside the texel-centre hull bilinear is exact
    // in real arithmetic; f32 rounding of values up to ~3 leaves < 1e-5.
    let n = 16;
    let f = |u: f32, v: f32| 0.5 + 1.25 * u - 0.75 * v;
    let t = tex(n, |i, j| {
        f((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32)
    });
    let (lo, hi) = (0.5 / n as f32, 1.0 - 0.5 / n as f32);
    for a in 0..=37 {
        for b in 0..=37 {
            let u = lo + (hi - lo) * a as f32 / 37.0;
            let v = lo + (hi - lo) * b as f32 / 37.0;
            let s = t.sample(0, u, v, Filter::Bilinear).x;
            assert!((s - f(u, v)).abs() < 1e-5, "{u} {v}");
        }
    }
}

#[test]
fn nearest_picks_the_containing_texel() {
    let t = tex(4, |i, j| (i + 10 * j) as f32);
    assert_eq!(t.sample(0, 0.3, 0.6, Filter::Nearest).x, 21.0);
    assert_eq!(t.sample(0, 1.0, 1.0, Filter::Nearest).x, 33.0);
    assert_eq!(t.sample(0, -5.0, f32::NAN, Filter::Nearest).x, 0.0);
}

#[test]
fn memory_of_known_sizes_is_hand_computed() {
    // Sides 1, 2, 16, 64.
    let m = TextureMemory::of_sides(&[1, 2, 16, 64], 0);
    let base: u64 = 1 + 4 + 256 + 4096; // 4357
    let chain: u64 = 1 + (4 + 1) + (256 + 64 + 16 + 4 + 1) + (4096 + 1024 + 256 + 64 + 16 + 4 + 1);
    assert_eq!(m.textures, 4);
    assert_eq!(m.texels, base);
    assert_eq!(m.texels_with_chain, chain); // 1 + 5 + 341 + 5461 = 5808
    assert_eq!(chain, 5808);
    // 8 bits: 3 bytes a texel.
    assert_eq!(m.bytes[0], 3 * 4357);
    // 12 bits: 4.5 bytes a texel, rounded up per texture: 1x1 -> 36 bits = 5 bytes, 2x2 -> 18,
    // 16x16 -> 1152, 64x64 -> 18432.
    assert_eq!(m.bytes[1], 5 + 18 + 1152 + 18432);
    // 32 bits: 12 bytes a texel.
    assert_eq!(m.bytes[2], 12 * 4357);
    assert_eq!(m.bytes_with_chain[0], 3 * 5808);
    // chains at 12 bits: 1 -> 5, 5 -> 22.5 -> 23, 341 -> 1534.5 -> 1535, 5461 -> 24574.5 -> 24575.
    assert_eq!(m.bytes_with_chain[1], 5 + 23 + 1535 + 24575);
    assert_eq!(m.bytes_with_chain[2], 12 * 5808);
    // A 2-texel gutter around every level: sides 1 and 2 store 5^2 = 25 and 6^2 = 36 texels
    // at level 0, and the 2 x 2 chain 36 + 25.
    let g = TextureMemory::of_sides(&[1, 2], 2);
    assert_eq!((g.texels, g.texels_with_chain), (25 + 36, 25 + 36 + 25));
    // 12 bits: 25 texels -> 112.5 -> 113 bytes, 36 -> 162; chains 113 + 61 x 4.5 = 274.5 -> 275.
    assert_eq!(g.bytes[1], 113 + 162);
    assert_eq!(g.bytes_with_chain[1], 113 + 275);
}

/// Extents of square polygons (aspect 0) at the given depths.
fn square(depths: &[u32]) -> Vec<Extent> {
    depths
        .iter()
        .map(|&depth| Extent { depth, aspect: 0 })
        .collect()
}

/// The sides of square textures (width = height), as a list.
fn sides(sizes: Vec<(u32, u32)>) -> Vec<u32> {
    sizes
        .into_iter()
        .map(|(w, h)| {
            assert_eq!(w, h);
            w
        })
        .collect()
}

#[test]
fn size_policies() {
    assert_eq!(
        [0, 1, 2, 3, 6, 20].map(side_from_depth),
        [2, 4, 8, 16, 128, MAX_TEXTURE_SIZE]
    );
    let d = square(&[1, 3, 6]);
    let sizes = |p| sides(TextureSet::sizes(&d, p).unwrap());
    assert_eq!(sizes(SizePolicy::FromDepth), [4, 16, 128]);
    assert_eq!(sizes(SizePolicy::Fixed(32)), [32; 3]);
    assert!(TextureSet::sizes(&d, SizePolicy::Fixed(24)).is_err());
    assert!(TextureSet::sizes(&d, SizePolicy::Fixed(0)).is_err());
    // Full FromDepth at 12 bits with chains: sides 4, 16, 128 fit exactly their own size.
    // The budget counts the gutters the built textures carry.
    let full = TextureMemory::of_sides(&[4, 16, 128], GUTTER).bytes_with_chain[1];
    assert_eq!(sizes(SizePolicy::Budget(full)), [4, 16, 128]);
    // One byte less: halve all -> 2, 8, 64.
    assert_eq!(sizes(SizePolicy::Budget(full - 1)), [2, 8, 64]);
    let ones = TextureMemory::of_sides(&[1, 1, 1], GUTTER).bytes_with_chain[1];
    assert_eq!(sizes(SizePolicy::Budget(ones)), [1, 1, 1]);
    assert!(TextureSet::sizes(&d, SizePolicy::Budget(ones - 1)).is_err());
    // Scaled: 2^k times the FromDepth sides, clamped to 1..=MAX_TEXTURE_SIZE.
    assert_eq!(sizes(SizePolicy::Scaled(0)), [4, 16, 128]);
    assert_eq!(sizes(SizePolicy::Scaled(3)), [32, 128, 1024]);
    assert_eq!(sizes(SizePolicy::Scaled(-3)), [1, 2, 16]);
    let deep = square(&[20]);
    let one = |p| sides(TextureSet::sizes(&deep, p).unwrap());
    assert_eq!(one(SizePolicy::Scaled(i32::MAX)), [MAX_TEXTURE_SIZE]);
    assert_eq!(one(SizePolicy::Scaled(i32::MIN)), [1]);
}

#[test]
fn every_policy_keeps_the_polygons_aspect() {
    // u 8x longer than v, v 2x longer than u, and a strip past the largest texture's ratio.
    let e = [
        Extent {
            depth: 6,
            aspect: 3,
        },
        Extent {
            depth: 3,
            aspect: -1,
        },
        Extent {
            depth: 20,
            aspect: MAX_ASPECT,
        },
    ];
    let wide = MAX_TEXTURE_SIZE >> MAX_ASPECT;
    let sizes = |p| TextureSet::sizes(&e, p).unwrap();
    assert_eq!(
        sizes(SizePolicy::FromDepth),
        [(128, 16), (8, 16), (MAX_TEXTURE_SIZE, wide)]
    );
    assert_eq!(sizes(SizePolicy::Fixed(64)), [(64, 8), (32, 64), (64, 1)]);
    assert_eq!(
        sizes(SizePolicy::Scaled(-2)),
        [(32, 4), (2, 4), (MAX_TEXTURE_SIZE / 4, 1)]
    );
    // The budget counts the rectangles: exactly their memory fits, a byte less halves them.
    let full = TextureMemory::of_sizes(&sizes(SizePolicy::FromDepth), GUTTER).bytes_with_chain[1];
    assert_eq!(
        sizes(SizePolicy::Budget(full)),
        sizes(SizePolicy::FromDepth)
    );
    assert_eq!(
        sizes(SizePolicy::Budget(full - 1)),
        [(64, 8), (4, 8), (MAX_TEXTURE_SIZE / 2, 1)]
    );
}

#[test]
fn a_quads_aspect_is_its_side_ratio_rounded_toward_zero() {
    let p = glam::DVec3::new;
    let quad = |w: f64, h: f64| {
        scene::Polygon::quad(
            [p(0., 0., 0.), p(w, 0., 0.), p(w, h, 0.), p(0., h, 0.)],
            0,
            0,
        )
        .unwrap()
    };
    assert_eq!(Extent::aspect_of(&quad(1.0, 1.0)), 0);
    assert_eq!(Extent::aspect_of(&quad(1.9, 1.0)), 0);
    assert_eq!(Extent::aspect_of(&quad(2.0, 1.0)), 1);
    assert_eq!(Extent::aspect_of(&quad(4.0, 0.05)), 6); // 80 = 2^6.3
    assert_eq!(Extent::aspect_of(&quad(0.05, 4.0)), -6);
    assert_eq!(Extent::aspect_of(&quad(1e6, 1e-3)), MAX_ASPECT);
    // A trapezoid: mean width 3 (sides 2 and 4) along u against height 1 along v.
    let trap = scene::Polygon::quad(
        [p(0., 0., 0.), p(4., 0., 0.), p(3., 1., 0.), p(1., 1., 0.)],
        0,
        0,
    )
    .unwrap();
    assert_eq!(Extent::aspect_of(&trap), 1);
    // Triangles stay square: a sliver 40 x 1, and a right triangle 1 x 8 whose tangents at
    // the centre of its collapsed square would say -3.
    for [a, b, c] in [
        [(0., 0.), (40., 0.), (0., 1.)],
        [(0., 0.), (1., 0.), (0., 8.)],
    ] {
        let corner = |q: (f64, f64)| p(q.0, q.1, 0.);
        let t = scene::Polygon::triangle([corner(a), corner(b), corner(c)], 0, 0).unwrap();
        assert_eq!(Extent::aspect_of(&t), 0);
    }
}

#[test]
fn a_rectangular_texture_reproduces_a_linear_function_to_its_edges() {
    // 16 x 4 texels with the gutter: bilinear lookups of a linear function are exact on the
    // whole square (the gutter continues it) at every level of the chain (16 x 4, 8 x 2, 4 x 1,
    // 2 x 1, 1 x 1) under centre placement; Mitchell-Netravali lookups, and corner placement,
    // where the level has two texels or more across (one texel has no second texel to mirror
    // for the cubic's outer taps, and a corner-placed single texel is one point sample, as at a
    // square chain's 1 x 1 level).
    let f = |u: f32, v: f32| Vec3::new(1.0 + 2.0 * u + v, 0.5 - u, 3.0 * v);
    for placement in [Placement::Centre, Placement::Corner] {
        let t = RadiosityTexture::from_fn_sized((16, 4), placement, GUTTER, f).unwrap();
        let sizes: Vec<_> = t.levels.iter().map(|l| (l.width, l.height)).collect();
        assert_eq!(sizes, [(16, 4), (8, 2), (4, 1), (2, 1), (1, 1)]);
        for (level, l) in t.levels.iter().enumerate() {
            let filters: &[Filter] = match (l.width.min(l.height) >= 2, placement) {
                (true, _) => &[Filter::Bilinear, Filter::MITCHELL],
                (false, Placement::Centre) => &[Filter::Bilinear],
                (false, Placement::Corner) => &[],
            };
            for a in 0..=10 {
                for b in 0..=10 {
                    let (u, v) = (a as f32 / 10.0, b as f32 / 10.0);
                    for &filter in filters {
                        let s = t.sample(level, u, v, filter);
                        assert!(
                            (s - f(u, v)).abs().max_element() < 2e-5,
                            "{placement:?} level {level} {filter:?} ({u}, {v}): {s}"
                        );
                    }
                }
            }
        }
    }
}

#[test]
fn rectangular_memory_counts_every_level_and_gutter() {
    // 4 x 1 without gutter: 4 + 2 + 1 texels; with a 2-texel gutter: 8 x 5 + 6 x 5 + 5 x 5.
    assert_eq!(TextureMemory::of_sizes(&[(4, 1)], 0).texels_with_chain, 7);
    let g = TextureMemory::of_sizes(&[(4, 1)], 2);
    assert_eq!((g.texels, g.texels_with_chain), (40, 40 + 30 + 25));
    // Squares agree with of_sides.
    assert_eq!(
        TextureMemory::of_sizes(&[(8, 8), (1, 1)], 2),
        TextureMemory::of_sides(&[8, 1], 2)
    );
}

#[test]
fn lod_from_derivatives() {
    // 64 texels, one pixel steps 1/16 in u: 4 texels a pixel -> lod 2.
    assert!((lod(1.0 / 16.0, 0.0, 0.0, 1.0 / 64.0, 64, 64) - 2.0).abs() < 1e-6);
    // Magnification clamps to 0, huge minification to the last level (6).
    assert_eq!(lod(1e-4, 0.0, 0.0, 1e-4, 64, 64), 0.0);
    assert_eq!(lod(10.0, 0.0, 0.0, 1.0, 64, 64), 6.0);
    assert_eq!(lod(f32::NAN, 0.0, 0.0, 0.0, 64, 64), 0.0);
    // Trilinear: halfway between levels blends them equally.
    let t = tex(2, |i, _| i as f32 * 2.0); // level 0: 0, 2; level 1: 1
    let s = t.sample_lod(0.5, 0.5 / 2.0, 0.5, Filter::Bilinear).x;
    assert!((s - 0.5).abs() < 1e-6);
}

#[test]
fn texture_from_a_linear_rrp_reproduces_it_bilinearly() {
    // A linear radiosity on a refined tree reconstructs exactly (linear functions have exact
    // Hermite data), texels are its values at centres, and bilinear of linear data is exact in
    // the texel-centre hull, and with the gutter on the whole square; f32 rounding on values up
    // to ~4: 2e-5.
    let mut tree = Quadtree::new();
    let c = tree.split(0);
    tree.split(c + 3);
    let f = |u: f64, v: f64| {
        Vec3::new(
            (1.0 + 2.0 * u + v) as f32,
            (0.5 - u) as f32,
            (v * 3.0) as f32,
        )
    };
    let sq = SampledQuadtree::from_fn(tree, f);
    let recon = Reconstruction::build(std::slice::from_ref(&sq), Estimator::default()).unwrap();
    let depths = square(&[sq.tree.depth()]);
    assert_eq!(depths[0].depth, 2);
    let set = TextureSet::build(&recon, &depths, SizePolicy::FromDepth, Placement::Centre).unwrap();
    let t = &set.textures[0];
    assert_eq!((t.width, t.levels.len()), (8, 4));
    // 8 x 8 with a 2-texel gutter: 12 x 12 stored.
    assert_eq!(set.memory.texels, 144);
    // The gutter continues the linear function past the edges, so the whole square is exact.
    let (lo, hi) = (0.0, 1.0);
    for a in 0..=23 {
        for b in 0..=23 {
            let u = lo + (hi - lo) * a as f32 / 23.0;
            let v = lo + (hi - lo) * b as f32 / 23.0;
            let s = t.sample(0, u, v, Filter::Bilinear);
            let want = f(u as f64, v as f64);
            assert!(
                (s - want).abs().max_element() < 2e-5,
                "{u} {v}: {s} vs {want}"
            );
        }
    }
    // Wrong depth count is an error, not a panic.
    assert!(TextureSet::build(&recon, &[], SizePolicy::FromDepth, Placement::Centre).is_err());
}

#[test]
fn from_texels_rejects_bad_input() {
    assert!(RadiosityTexture::from_texels(3, 4, vec![Vec3::ZERO; 12]).is_err());
    assert!(RadiosityTexture::from_texels(2, 2, vec![Vec3::ZERO; 3]).is_err());
    assert!(RadiosityTexture::from_texels(1, 1, vec![Vec3::splat(f32::NAN)]).is_err());
    let t = RadiosityTexture::from_texels(4, 2, vec![Vec3::ONE; 8]).unwrap();
    let sizes: Vec<_> = t.levels.iter().map(|l| (l.width, l.height)).collect();
    assert_eq!(sizes, [(4, 2), (2, 1), (1, 1)]);
}

#[test]
fn from_depth_memory_matches_the_reconstruction_stats() {
    // ReconstructionStats counts equal-quality textures with the same rule (2^depth + 1 rounded
    // up to a power of two, squared, 3 / 4.5 / 12 bytes a texel): the two must agree.
    let mut trees = Vec::new();
    for d in 0..4u32 {
        let mut t = Quadtree::new();
        let mut id = 0;
        for _ in 0..d {
            id = t.split(id);
        }
        trees.push(SampledQuadtree::from_fn(t, |u, v| {
            Vec3::new(u as f32, v as f32, 1.0)
        }));
    }
    let recon = Reconstruction::build(&trees, Estimator::default()).unwrap();
    let set = TextureSet::build(
        &recon,
        &square(&trees.iter().map(|t| t.tree.depth()).collect::<Vec<_>>()),
        SizePolicy::FromDepth,
        Placement::Centre,
    )
    .unwrap();
    let st = recon.stats();
    assert_eq!(set.memory.textures, 4);
    assert_eq!(set.memory.texels, st.texture_texels as u64);
    // Sides 2, 4, 8, 16 with a 2-texel gutter: 6^2 + 8^2 + 12^2 + 20^2.
    assert_eq!(set.memory.texels, 36 + 64 + 144 + 400);
    assert_eq!(set.memory.bytes[0], st.texture_bytes_8 as u64);
    assert_eq!(set.memory.bytes[2], st.texture_bytes_32 as u64);
    let sides: Vec<u32> = set.textures.iter().map(|t| t.width).collect();
    assert_eq!(sides, [2, 4, 8, 16]);
}

#[test]
fn sample_many_equals_sample() {
    // Same arithmetic in the same order, so bit-identical results.
    let t = tex(16, |i, j| seq(i) + 0.1 * seq(j + 5));
    let uv: Vec<[f32; 2]> = (0..200)
        .map(|k| [(k as f32 * 0.037) % 1.2 - 0.1, (k as f32 * 0.061) % 1.0])
        .collect();
    for f in [
        Filter::Nearest,
        Filter::Bilinear,
        Filter::MITCHELL,
        Filter::CATMULL_ROM,
    ] {
        for level in [0, 2, 9] {
            let mut out = vec![Vec3::ZERO; uv.len()];
            t.sample_many(level, &uv, f, &mut out);
            for (p, o) in uv.iter().zip(&out) {
                assert_eq!(*o, t.sample(level, p[0], p[1], f));
            }
        }
    }
}

#[test]
fn sampler_equals_sample_lod_and_nearest_takes_the_nearest_level() {
    let t = tex(16, |i, j| seq(i) + 2.0 * seq(j + 3));
    for filter in [Filter::Bilinear, Filter::MITCHELL, Filter::CATMULL_ROM] {
        let s = Sampler::new(filter);
        for &lod in &[0.0f32, 0.3, 1.0, 1.75, 3.5, 4.0, 9.0, -1.0, f32::NAN] {
            for &(u, v) in &[(0.1f32, 0.2f32), (0.5, 0.5), (0.93, 0.07), (1.0, 0.0)] {
                // Same operations in the same order: bit-identical.
                assert_eq!(
                    s.sample(&t, lod, u, v),
                    t.sample_lod(lod, u, v, filter),
                    "{filter:?} {lod} {u} {v}"
                );
            }
        }
    }
    let s = Sampler::new(Filter::Nearest);
    for (lod, level) in [(0.0f32, 0usize), (0.49, 0), (0.51, 1), (2.6, 3), (7.0, 4)] {
        assert_eq!(
            s.sample(&t, lod, 0.3, 0.6),
            t.sample(level, 0.3, 0.6, Filter::Nearest),
            "{lod}"
        );
    }
}

#[test]
fn lod_from_squares_agrees_with_lod() {
    // lod(...) = log2(max(hypot)) = 0.5 log2(max(squares)); f32 rounding of the two forms
    // differs by a few ulps of values below 12: 1e-5.
    for &(a, b, c, d) in &[
        (0.01f32, 0.0f32, 0.0f32, 0.01f32),
        (0.2, 0.1, -0.05, 0.3),
        (1.0, 0.0, 0.0, 1.0),
        (0.001, 0.0, 0.0, 0.001),
    ] {
        let (w, h) = (64u32, 64u32);
        let lx2 = (a * 64.0).powi(2) + (b * 64.0).powi(2);
        let ly2 = (c * 64.0).powi(2) + (d * 64.0).powi(2);
        let want = lod(a, b, c, d, w, h);
        assert!(
            (lod_from_squares(lx2, ly2, 6) - want).abs() < 1e-5,
            "{a} {want}"
        );
    }
    assert_eq!(lod_from_squares(f32::NAN, 0.0, 6), 0.0);
    assert_eq!(lod_from_squares(f32::INFINITY, 0.0, 6), 6.0);
}

proptest! {
    #[test]
    fn sample8_equals_sample_per_lane(
        side_log in 0u32..7,
        filter_kind in 0usize..3,
        b in 0.0f32..1.0,
        c in 0.0f32..1.0,
        uv in prop::array::uniform8((-0.1f32..1.1, -0.1f32..1.1)),
        lx2 in prop::array::uniform8(prop_oneof![Just(0.0f32), 0.0f32..4.0, 0.0f32..1e5]),
        ly2 in prop::array::uniform8(0.0f32..1e3),
        mask in prop::array::uniform8(any::<bool>()),
        corner in any::<bool>(),
        gutter in 0u32..3,
    ) {
        use ::lanes::F32x8;
        // The lane form promises the scalar sampler's bits in every masked lane, for every filter,
        // texture size and level of detail (magnified, blended, clamped to the last level).
        let n = 1u32 << side_log;
        // Distinct channels, so that a channel mix-up in the gathers shows.
        let texels = (0..n * n)
            .map(|k| Vec3::new(seq(k), seq(k * 7 + 3) + 2.0, 0.5 * seq(k * 13 + 5) - 3.0))
            .collect();
        // With a gutter of other values, which edge lookups read past the square.
        let mut t = match gutter {
            0 => RadiosityTexture::from_texels(n, n, texels).unwrap(),
            g => RadiosityTexture::from_fn(n, Placement::Centre, g, hashed).unwrap(),
        };
        // Both placements: the lanes map u to texels as the scalar code does for each.
        t.placement = if corner { Placement::Corner } else { Placement::Centre };
        let filter = [Filter::Nearest, Filter::Bilinear, Filter::Bicubic { b, c }][filter_kind];
        let s = Sampler::new(filter);
        let u = F32x8(uv.map(|p| p.0));
        let v = F32x8(uv.map(|p| p.1));
        // Every build of the lane form this CPU can run (the texture shader runs at most AVX2).
        let mut builds = Vec::new();
        for isa in ::lanes::Level::ALL.into_iter().filter_map(::lanes::Isa::at) {
            let k = Sample8 { sampler: &s, tex: &t, lx2: F32x8(lx2), ly2: F32x8(ly2), u, v, mask };
            builds.push((isa.name(), isa.run_avx2(k)));
        }
        let got = builds[0].1;
        for (name, b) in &builds {
            for l in (0..8).filter(|&l| mask[l]) {
                for ch in 0..3 {
                    prop_assert_eq!(b[ch].0[l].to_bits(), got[ch].0[l].to_bits(), "{}", name);
                }
            }
        }
        for l in 0..8 {
            if !mask[l] {
                continue;
            }
            let lod = lod_from_squares(lx2[l], ly2[l], t.last_level());
            let want = s.sample(&t, lod, u.0[l], v.0[l]);
            for ch in 0..3 {
                prop_assert_eq!(got[ch].0[l].to_bits(), want[ch].to_bits(), "lane {} ch {}", l, ch);
            }
        }
    }
}

#[test]
fn mip_chain_halves_and_keeps_the_mean() {
    let level = |w: u32, h: u32| MipLevel {
        width: w,
        height: h,
        gutter: 0,
        texels: (0..w * h).map(|i| Vec3::splat(seq(i) + 2.0)).collect(),
    };
    let chain = mip_chain(level(7, 5));
    let sizes: Vec<_> = chain.iter().map(|l| (l.width, l.height)).collect();
    assert_eq!(sizes, vec![(7, 5), (3, 2), (1, 1)]);
    assert_eq!(chain[0], level(7, 5));
    let mean =
        |l: &MipLevel| l.texels.iter().map(|t| t.x as f64).sum::<f64>() / l.texels.len() as f64;
    let m0 = mean(&chain[0]);
    for l in &chain {
        assert_eq!(l.texels.len(), (l.width * l.height) as usize);
        // Area weights sum to one per texel: the mean is kept up to f32 rounding of values
        // below 4 (a few ulps of 4 = 2.4e-7 each).
        assert!((mean(l) - m0).abs() < 1e-6, "{} vs {m0}", mean(l));
    }
    // Power of two: a level is the plain 2 x 2 average of the previous one (exact here: the
    // texels are multiples of 1/4, so their sums and quarters are exact in f32).
    let c = mip_chain(level(4, 4));
    let l0 = &c[0].texels;
    assert_eq!(c[1].texels[0], (l0[0] + l0[1] + l0[4] + l0[5]) * 0.25);
    assert_eq!(c.len(), 3);
    // One axis already 1: the plain pair average.
    let c = mip_chain(level(4, 1));
    assert_eq!(c[1].texels[0], (c[0].texels[0] + c[0].texels[1]) * 0.5);
    assert!(mip_chain(level(0, 3)).is_empty());
}

/// Corner placement: texel i of n at u = i / (n - 1), so the samples lie on the edges.
fn corner_pos(i: u32, n: u32) -> f32 {
    Placement::Corner.texel_position(i, n)
}

#[test]
fn corner_placement_preserves_a_constant_on_every_level() {
    // Every level is sampled from the constant, the filter weights sum to 1 and clamp-to-edge
    // fetches only the constant: the constant up to a few f32 roundings of values near 2.5.
    for side in [1, 2, 8, 16] {
        // With a gutter: it holds the constant too.
        let t =
            RadiosityTexture::from_fn(side, Placement::Corner, 2, |_, _| Vec3::splat(2.5)).unwrap();
        assert_eq!(t.levels.len(), side.ilog2() as usize + 1);
        for filter in [
            Filter::Nearest,
            Filter::Bilinear,
            Filter::MITCHELL,
            Filter::CATMULL_ROM,
        ] {
            let s = Sampler::new(filter);
            for a in 0..=40 {
                for b in 0..=40 {
                    let (u, v) = (a as f32 / 40.0, b as f32 / 40.0);
                    for lod in [0.0, 0.5, 1.0, 2.3, 9.0] {
                        let x = s.sample(&t, lod, u, v);
                        assert!(
                            (x - Vec3::splat(2.5)).abs().max_element() < 2.5e-5,
                            "{u} {v} {x}"
                        );
                    }
                }
            }
        }
    }
}

#[test]
fn corner_bilinear_reproduces_a_linear_function_everywhere() {
    // f linear, texels = f at the corner positions; bilinear interpolation of a linear function
    // between its samples is exact in real arithmetic, and with corner placement the samples
    // span all of [0, 1]^2, so the whole square, edges and corners included, is reproduced, on
    // every mip level; f32 rounding of values up to ~3: 1e-5.
    let f = |u: f32, v: f32| 0.5 + 1.25 * u - 0.75 * v;
    let g = |u: f32, v: f32| Vec3::new(f(u, v), 2.0 - u, 0.25 + v);
    for n in [2u32, 8, 16] {
        let t = RadiosityTexture::from_fn(n, Placement::Corner, 0, g).unwrap();
        // Every level of at least 2 x 2 texels, and blends of two such levels (the 1 x 1 last
        // level holds only the centre value, a constant).
        let fine = t.levels.iter().filter(|l| l.width >= 2).count();
        let lods = (0..fine).map(|l| l as f32);
        let blends = (1..fine).map(|l| l as f32 - 0.5);
        for lod in lods.chain(blends) {
            for a in 0..=37 {
                for b in 0..=37 {
                    let (u, v) = (a as f32 / 37.0, b as f32 / 37.0);
                    let s = Sampler::new(Filter::Bilinear).sample(&t, lod, u, v);
                    assert!(
                        (s - g(u, v)).abs().max_element() < 1e-5,
                        "n {n} lod {lod}: {u} {v}"
                    );
                }
            }
        }
    }
    // With centre placement and no gutter the same data is exact only inside the half-texel
    // margin (see bilinear_of_a_linear_function_is_exact_inside): at u = 0 it returns f at
    // u = 0.5 / n, off by 1.25 * 0.5 / n.
    let n = 16;
    let centre = RadiosityTexture::from_fn(n, Placement::Centre, 0, g).unwrap();
    let err = centre.sample(0, 0.0, 0.5, Filter::Bilinear).x - f(0.0, 0.5);
    assert!((err - 1.25 * 0.5 / n as f32).abs() < 1e-5, "{err}");
}

#[test]
fn corner_texture_returns_the_rrp_edge_values() {
    // A non-polynomial radiosity on a refined tree; the corner-placed texture's edge texels are
    // the RRP at the edge, so sampling at u = 0 or 1 (or v = 0 or 1) at a texel position gives
    // the RRP's edge value. At the four corners x = 0 or n - 1 exactly, the weights are 1 and
    // 0, so the value is the texel's bits; along the edges v_j (n - 1) may round 1 ulp below j,
    // blending the neighbour with weight ~1e-7: 1e-5 on values below ~3.
    let mut tree = Quadtree::new();
    let c = tree.split(0);
    tree.split(c + 1);
    let f = |u: f64, v: f64| {
        Vec3::new(
            (1.0 + (3.0 * u).sin() * v) as f32,
            (0.5 + u * u * u) as f32,
            (2.0 * v * v - u) as f32,
        )
    };
    let sq = SampledQuadtree::from_fn(tree, f);
    let recon = Reconstruction::build(std::slice::from_ref(&sq), Estimator::default()).unwrap();
    let set = TextureSet::build(
        &recon,
        &square(&[2]),
        SizePolicy::Fixed(16),
        Placement::Corner,
    )
    .unwrap();
    assert_eq!(set.placement, Placement::Corner);
    let t = &set.textures[0];
    assert_eq!(t.placement, Placement::Corner);
    let n = t.width;
    for filter in [Filter::Nearest, Filter::Bilinear] {
        for (u, v) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)] {
            assert_eq!(
                t.sample(0, u, v, filter),
                recon.eval(0, u, v),
                "{filter:?} {u} {v}"
            );
        }
        for j in 0..n {
            let w = corner_pos(j, n);
            for (u, v) in [(0.0, w), (1.0, w), (w, 0.0), (w, 1.0)] {
                let (got, want) = (t.sample(0, u, v, filter), recon.eval(0, u, v));
                assert!(
                    (got - want).abs().max_element() < 1e-5,
                    "{filter:?} {u} {v}: {got} {want}"
                );
            }
        }
    }
    // Every coarser level is the RRP at that level's own corner positions (not an average).
    for l in &t.levels {
        let m = l.width;
        for j in 0..m {
            for i in 0..m {
                let want = recon.eval(0, corner_pos(i, m), corner_pos(j, m));
                assert_eq!(l.texel(i as i32, j as i32), want, "{m}: {i} {j}");
            }
        }
    }
    // Centre placement without a gutter does not reach the corner: it returns the first texel
    // centre's value. With the gutter, bilinear weights of 1/4 on the four texels around the
    // corner return the value there to second order: the RRP's f_uu, f_vv, f_uv (below 20 on
    // this f) times h^2 / 8 with h = 1/16, i.e. within 0.1.
    let clamped = RadiosityTexture::from_rrp(&recon, 0, (16, 16), Placement::Centre, 0);
    let c0 = clamped.sample(0, 0.0, 0.0, Filter::Bilinear);
    assert_eq!(c0, recon.eval(0, 0.5 / 16.0, 0.5 / 16.0));
    assert_ne!(c0, recon.eval(0, 0.0, 0.0));
    let centre = TextureSet::build(
        &recon,
        &square(&[2]),
        SizePolicy::Fixed(16),
        Placement::Centre,
    )
    .unwrap();
    assert_eq!(centre.gutter, GUTTER);
    let corner = recon.eval(0, 0.0, 0.0);
    let g0 = centre.textures[0].sample(0, 0.0, 0.0, Filter::Bilinear);
    assert!(
        (g0 - corner).abs().max_element() < (c0 - corner).abs().max_element(),
        "{g0} {c0} {corner}"
    );
}

#[test]
fn corner_nearest_picks_the_nearest_corner_aligned_texel() {
    // n = 4: texels at 0, 1/3, 2/3, 1; nearest rounds u (n - 1).
    let t = RadiosityTexture::from_fn(4, Placement::Corner, 0, |u, v| {
        Vec3::splat((u * 3.0).round() + 10.0 * (v * 3.0).round())
    })
    .unwrap();
    assert_eq!(t.sample(0, 0.0, 0.0, Filter::Nearest).x, 0.0);
    assert_eq!(t.sample(0, 0.16, 0.17, Filter::Nearest).x, 10.0);
    assert_eq!(t.sample(0, 0.5, 0.84, Filter::Nearest).x, 32.0);
    assert_eq!(t.sample(0, 1.0, 1.0, Filter::Nearest).x, 33.0);
    assert_eq!(t.sample(0, -5.0, f32::NAN, Filter::Nearest).x, 0.0);
    // A 1 x 1 corner texture holds the centre value and returns it everywhere.
    let one =
        RadiosityTexture::from_fn(1, Placement::Corner, 2, |u, v| Vec3::new(u, v, 1.0)).unwrap();
    for filter in [Filter::Nearest, Filter::Bilinear] {
        assert_eq!(one.sample(0, 0.9, 0.1, filter), Vec3::new(0.5, 0.5, 1.0));
    }
    // The Mitchell weights sum to 1 up to a few ulps.
    let m = one.sample(0, 0.9, 0.1, Filter::MITCHELL);
    assert!(
        (m - Vec3::new(0.5, 0.5, 1.0)).abs().max_element() < 1e-5,
        "{m}"
    );
    assert!(RadiosityTexture::from_fn(3, Placement::Corner, 0, |_, _| Vec3::ONE).is_err());
    assert!(RadiosityTexture::from_fn(2, Placement::Corner, 0, |_, _| Vec3::NAN).is_err());
    assert!(
        RadiosityTexture::from_fn(2, Placement::Corner, MAX_GUTTER + 1, |_, _| Vec3::ONE).is_err()
    );
}

/// [`Sampler::sample8`] as a kernel, to run it with each instruction set.
struct Sample8<'a> {
    sampler: &'a Sampler,
    tex: &'a RadiosityTexture,
    lx2: ::lanes::F32x8,
    ly2: ::lanes::F32x8,
    u: ::lanes::F32x8,
    v: ::lanes::F32x8,
    mask: [bool; 8],
}

impl ::lanes::Kernel for Sample8<'_> {
    type Output = super::Rgb8;
    #[inline(always)]
    fn run<S: ::lanes::Simd>(self, simd: S) -> super::Rgb8 {
        let Sample8 {
            sampler,
            tex,
            lx2,
            ly2,
            u,
            v,
            mask,
        } = self;
        sampler.sample8(simd, tex, lx2, ly2, u, v, &mask)
    }
}

/// A smooth non-polynomial function with distinct channels, for the gutter tests.
fn wavy(u: f32, v: f32) -> Vec3 {
    Vec3::new(
        1.0 + (3.0 * u).sin() * v,
        0.5 + u * u * u - 0.3 * (2.0 * v).cos(),
        2.0 * v * v - u + 1.5,
    )
}

#[test]
fn gutters_make_edge_lookups_depend_on_the_edge_values_alone() {
    // At an edge lookup the filters weigh each gutter texel and its mirror alike, and the
    // gutter holds 2 E - T: every texel inside cancels, and the lookup is the filter along the
    // edge of the edge values E. So a texture of f and one of the function constant across the
    // edge with f's values on it agree along that edge, on every level 2 x 2 texels, for every filter (f32 rounding of sums of values up to ~4 with
    // weights up to 1.2: 4e-6). This is what
    // makes two polygons of one edge curve meet. The interpolating filters (bilinear,
    // Catmull-Rom) also return E itself at the rows (level 0: f at the edge, at the rows).
    let n = 16u32;
    for placement in [Placement::Centre, Placement::Corner] {
        let t = RadiosityTexture::from_fn(n, placement, GUTTER, wavy).unwrap();
        for edge in [0.0f32, 1.0] {
            let along =
                RadiosityTexture::from_fn(n, placement, GUTTER, |_, v| wavy(edge, v)).unwrap();
            let across =
                RadiosityTexture::from_fn(n, placement, GUTTER, |u, _| wavy(u, edge)).unwrap();
            for filter in [Filter::Bilinear, Filter::MITCHELL, Filter::CATMULL_ROM] {
                // Levels of at least 2 x 2: on 1 x 1 the mirrors of a 2-texel gutter clamp.
                for level in (0..t.levels.len()).filter(|&l| t.levels[l].width >= 2) {
                    for k in 0..=97 {
                        let w = k as f32 / 97.0;
                        // The u edge against `along`, the v edge against `across`.
                        for (other, (u, v)) in [(&along, (edge, w)), (&across, (w, edge))] {
                            let (a, b) = (
                                t.sample(level, u, v, filter),
                                other.sample(level, u, v, filter),
                            );
                            assert!(
                                (a - b).abs().max_element() < 4e-6,
                                "{placement:?} {filter:?} level {level} ({u}, {v}): {a} {b}"
                            );
                        }
                    }
                }
                if matches!(filter, Filter::MITCHELL) {
                    continue;
                }
                for j in 0..n {
                    let v = placement.texel_position(j, n);
                    let got = t.sample(0, edge, v, filter);
                    assert!(
                        (got - wavy(edge, v)).abs().max_element() < 4e-6,
                        "{placement:?} {filter:?} row {j}: {got}"
                    );
                }
            }
        }
    }
}

#[test]
fn centre_gutters_reproduce_a_linear_function_everywhere() {
    // Without a gutter a centre-placed texture is exact for a linear function only inside its
    // half-texel margin. The reflected gutter continues a linear function exactly, and the
    // box chain of a linear function is linear at each level's centres, so bilinear and the
    // Mitchell-Netravali and Catmull-Rom filters (which reproduce linear functions: B + 2C = 1)
    // reproduce it on the whole square, edges and corners included, on every level of at
    // least 2 x 2 texels (the gutter's mirrors stay inside) and their blends; f32 rounding of
    // values up to ~3 through 16 weights: 2e-5.
    let g = |u: f32, v: f32| Vec3::new(0.5 + 1.25 * u - 0.75 * v, 2.0 - u, 0.25 + v);
    for n in [2u32, 8, 32] {
        let t = RadiosityTexture::from_fn(n, Placement::Centre, GUTTER, g).unwrap();
        let fine = t.levels.iter().filter(|l| l.width >= 2).count();
        let lods = (0..fine).map(|l| l as f32);
        let blends = (1..fine).map(|l| l as f32 - 0.5);
        for lod in lods.chain(blends) {
            for filter in [Filter::Bilinear, Filter::MITCHELL, Filter::CATMULL_ROM] {
                let s = Sampler::new(filter);
                for a in 0..=37 {
                    for b in 0..=37 {
                        let (u, v) = (a as f32 / 37.0, b as f32 / 37.0);
                        let x = s.sample(&t, lod, u, v);
                        assert!(
                            (x - g(u, v)).abs().max_element() < 2e-5,
                            "n {n} lod {lod} {filter:?}: {u} {v}: {x}"
                        );
                    }
                }
            }
        }
    }
}

#[test]
fn gutter_layout_and_nearest_filter() {
    // Stored rows of n + 2 g texels; texel(i, j) addresses the square from 0 and the gutter
    // below it; the nearest filter never returns a gutter texel (the nearest texel of a point
    // of the square is in the square), so it is unchanged by the gutter.
    let n = 8u32;
    let plain = RadiosityTexture::from_fn(n, Placement::Centre, 0, wavy).unwrap();
    let t = RadiosityTexture::from_fn(n, Placement::Centre, GUTTER, wavy).unwrap();
    let l = &t.levels[0];
    assert_eq!((l.stride(), l.rows()), (n + 2 * GUTTER, n + 2 * GUTTER));
    assert_eq!(l.texels.len() as u64, l.stored());
    for j in 0..n as i32 {
        for i in 0..n as i32 {
            assert_eq!(l.texel(i, j), plain.levels[0].texel(i, j));
        }
    }
    // Gutter texel -1 of row 3 mirrors texel 0 through the edge value.
    let v3 = Placement::Centre.texel_position(3, n);
    let want = wavy(0.0, v3) * 2.0 - l.texel(0, 3);
    assert!((l.texel(-1, 3) - want).abs().max_element() < 1e-6);
    for a in 0..=50 {
        for b in 0..=50 {
            let (u, v) = (a as f32 / 50.0, b as f32 / 50.0);
            assert_eq!(
                t.sample(0, u, v, Filter::Nearest),
                plain.sample(0, u, v, Filter::Nearest)
            );
        }
    }
    // Memory counts the stored texels.
    assert_eq!(
        t.texels_with_chain(),
        TextureMemory::of_sides(&[n], GUTTER).texels_with_chain
    );
}

/// Level 0 with its gutter is all an atlas keeps: the chain rebuilt from it alone equals the one
/// built from the function, every level and gutter, to within the rounding of a gutter texel
/// (the edge values are read back as `(g + t) / 2`, exact but for the half ulp the gutter texel
/// was rounded by; reflected again, that is doubled: a few ulps of the level's largest value).
#[test]
fn stored_level0_rebuilds_the_chain_and_its_gutters() {
    for side in [1, 2, 8, 32] {
        let built = RadiosityTexture::from_fn(side, Placement::Centre, GUTTER, hashed).unwrap();
        let rebuilt = RadiosityTexture::from_stored_level0(built.levels[0].clone()).unwrap();
        assert_eq!(rebuilt.levels.len(), built.levels.len());
        for (a, b) in rebuilt.levels.iter().zip(&built.levels) {
            assert_eq!((a.width, a.height, a.gutter), (b.width, b.height, b.gutter));
            let largest = b
                .texels
                .iter()
                .fold(1.0f32, |m, t| m.max(t.abs().max_element()));
            let bound = 4.0 * f32::EPSILON * largest;
            for (x, y) in a.texels.iter().zip(&b.texels) {
                assert!(
                    (*x - *y).abs().max_element() <= bound,
                    "side {side}: {x} vs {y}"
                );
            }
        }
    }
    let mut bad = RadiosityTexture::from_fn(4, Placement::Centre, GUTTER, hashed)
        .unwrap()
        .levels[0]
        .clone();
    bad.texels.pop();
    assert!(RadiosityTexture::from_stored_level0(bad.clone()).is_err());
    bad.texels.push(Vec3::NAN);
    assert!(RadiosityTexture::from_stored_level0(bad).is_err());
}
