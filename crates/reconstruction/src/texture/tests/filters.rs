//! The filters and the level of detail: the kernels' analytic values, what each filter returns
//! on constant and linear data, the lane sampler against the scalar one.

use super::*;

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
    assert_eq!(lod_from_squares(0.5, f32::NAN, 6), 0.0);
    assert_eq!(lod_from_squares(1.0, 1.0, 6), 0.0);
    assert_eq!(lod_from_squares(16.0, 3.0, 6), 2.0);
    assert_eq!(lod_from_squares(1e30, 3.0, 6), 6.0);
}

/// The branch-free logarithm of the levels of detail against f64's: the series leaves under
/// 1e-9, the reduction is exact, and the f32 steps of the mantissa's part (|log2 m| <= 0.5)
/// round to a few of its ulps (6e-8 each), so 2e-7 plus half an ulp of the result, from the
/// last addition of the exponent. Checked at the edges of the reduction (sqrt 2, powers of
/// two, the first float above 1) and across the range.
#[test]
fn log2_above_one_is_within_its_bound() {
    let mut xs = vec![
        1.0f32 + f32::EPSILON,
        std::f32::consts::SQRT_2,
        std::f32::consts::SQRT_2.next_up(),
        std::f32::consts::SQRT_2.next_down(),
        2.0,
        2.0f32.next_down(),
        2.0f32.next_up(),
        f32::MAX,
    ];
    let mut x = 1.0f32 + f32::EPSILON;
    while x < 1e38 {
        xs.push(x);
        x *= 1.0137;
    }
    for x in xs {
        let got = log2_above_one(x);
        let want = (x as f64).log2();
        let bound = 2e-7 + got.abs() as f64 * f64::from(f32::EPSILON) / 2.0;
        assert!(
            got > 0.0 && ((got as f64) - want).abs() <= bound,
            "log2({x}) = {got}, {want}"
        );
    }
    assert_eq!(log2_above_one(f32::INFINITY), 128.0);
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
