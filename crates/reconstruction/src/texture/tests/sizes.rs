//! Texture sizes and memory: the size policies, the polygons' aspects, rectangular textures and
//! the memory they count.

use super::*;

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
