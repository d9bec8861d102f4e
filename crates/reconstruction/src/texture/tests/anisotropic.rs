//! Anisotropic lookups: what they return on known functions at grazing footprints, and the lane
//! form against the scalar one.

use super::*;

/// A `n` x `n` texture of `f` at its texel centres.
fn of_fn(n: u32, f: impl Fn(f32, f32) -> f32) -> RadiosityTexture {
    let h = 1.0 / n as f32;
    tex(n, |i, j| f((i as f32 + 0.5) * h, (j as f32 + 0.5) * h))
}

#[test]
fn a_grazing_footprint_keeps_the_light_across_it_sharp() {
    // Light varying across a footprint 16 texels long and 1 wide (a ceiling beside a lamp seen
    // from across a room): f = sin(8 pi v), constant along the footprint's length (u).
    let n = 256;
    let w = 8.0 * std::f32::consts::PI;
    let t = of_fn(n, |_, v| (w * v).sin());
    let d = [16.0 / n as f32, 0.0, 0.0, 1.0 / n as f32];
    let s = Sampler::new(Filter::Bilinear);
    let (mut iso, mut aniso) = (0.0f32, 0.0f32);
    for a in 0..50 {
        let (u, v) = (0.3 + 0.0071 * a as f32, 0.2 + 0.0123 * a as f32);
        let want = (w * v).sin();
        iso = iso.max((s.sample_anisotropic(&t, d, (u, v), 1).x - want).abs());
        aniso = aniso.max((s.sample_anisotropic(&t, d, (u, v), 16).x - want).abs());
    }
    // 16 taps along u, each at level 0 (a 1 x 1 texel footprint): bilinear interpolation of
    // texel-centre samples, off by at most h^2 / 8 max|f''| = (1/256)^2 / 8 (8 pi)^2 = 1.2e-3.
    let bound = (1.0 / n as f32).powi(2) / 8.0 * w * w;
    assert!(aniso <= bound * 1.01, "{aniso} > {bound}");
    // Isotropically the level of detail follows the footprint's length (level 4, 16 texels a
    // texel): four periods over 16 texels are mostly averaged away.
    assert!(iso > 50.0 * bound, "{iso}");
}

#[test]
fn taps_along_a_linear_function_average_to_its_value_at_the_centre() {
    // Bilinear filtering reproduces a linear function inside the texture, and the taps lie
    // symmetrically about the sample, so their mean is the function at the sample: exact in
    // real arithmetic, a few f32 roundings of values near 1 here (1e-5).
    let n = 64;
    let f = |u: f32, v: f32| 0.3 + 2.0 * u + 0.5 * v;
    let t = of_fn(n, f);
    let s = Sampler::new(Filter::Bilinear);
    // Diagonal footprints 5 to 40 texels long and 1 to 2 wide, in either axis.
    for (k, d) in [
        [5.0, 3.0, -0.5, 1.0],
        [-1.0, 0.5, 20.0, -30.0],
        [12.0, 12.0, 1.0, -1.0],
    ]
    .into_iter()
    .enumerate()
    {
        let d = d.map(|x: f32| x / n as f32);
        for max in [2, 4, 7, 16] {
            let (u, v) = (0.45 + 0.01 * k as f32, 0.5 - 0.02 * k as f32);
            let got = s.sample_anisotropic(&t, d, (u, v), max).x;
            assert!(
                (got - f(u, v)).abs() < 1e-5,
                "{k} {max}: {got} vs {}",
                f(u, v)
            );
        }
    }
}

proptest! {
    #[test]
    fn sample8_footprint_anisotropic_equals_the_scalar_form_per_lane(
        side_log in 0u32..8,
        filter_kind in 0usize..3,
        uv in prop::array::uniform8((-0.1f32..1.1, -0.1f32..1.1)),
        d in prop::array::uniform8(prop::array::uniform4(prop_oneof![
            Just(0.0f32), -0.01f32..0.01, -0.5f32..0.5
        ])),
        mask in prop::array::uniform8(any::<bool>()),
        max in 1u32..=16,
    ) {
        use ::lanes::F32x8;
        // The lane form promises the scalar form's bits in every masked lane: lanes of one
        // block with different tap counts, one tap, magnified and clamped to the last level.
        let n = 1u32 << side_log;
        let t = RadiosityTexture::from_fn(n, Placement::Centre, 1, hashed).unwrap();
        let filter = [Filter::Nearest, Filter::Bilinear, Filter::MITCHELL][filter_kind];
        let s = Sampler::new(filter);
        let lanes = |c: usize| F32x8(d.map(|x| x[c]));
        let k = Aniso8 {
            sampler: &s,
            tex: &t,
            d: [lanes(0), lanes(1), lanes(2), lanes(3)],
            u: F32x8(uv.map(|p| p.0)),
            v: F32x8(uv.map(|p| p.1)),
            mask,
            max,
        };
        for isa in ::lanes::Level::ALL.into_iter().filter_map(::lanes::Isa::at) {
            let got = isa.run_avx2(k);
            for l in (0..8).filter(|&l| mask[l]) {
                let want = s.sample_anisotropic(&t, d[l], uv[l], max);
                for ch in 0..3 {
                    prop_assert_eq!(
                        got[ch].0[l].to_bits(), want[ch].to_bits(),
                        "{} lane {} ch {}", isa.name(), l, ch
                    );
                }
            }
        }
    }
}

/// [`Sampler::sample8_footprint`] with an anisotropic footprint as a kernel, to run it with each instruction set.
#[derive(Clone, Copy)]
struct Aniso8<'a> {
    sampler: &'a Sampler,
    tex: &'a RadiosityTexture,
    d: [::lanes::F32x8; 4],
    u: ::lanes::F32x8,
    v: ::lanes::F32x8,
    mask: [bool; 8],
    max: u32,
}

impl ::lanes::Kernel for Aniso8<'_> {
    type Output = super::Rgb8;
    #[inline(always)]
    fn run<S: ::lanes::Simd>(self, simd: S) -> super::Rgb8 {
        let Aniso8 {
            sampler,
            tex,
            d,
            u,
            v,
            mask,
            max,
        } = self;
        let fp = super::Footprint8::Anisotropic { d, max };
        sampler.sample8_footprint(simd, tex, fp, (u, v), &mask)
    }
}
