//! Mip chains, placements and gutters: each level's texels from the RRP or the finer level,
//! corner placement, the gutters' reflection through the edge values, a stored level 0 rebuilt.

use super::*;

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
