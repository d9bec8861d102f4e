//! Tests of the compact reconstruction: its quantization bound, continuity, encoding and patch
//! cache, against the expanded [`Reconstruction`] built from the same samples.

use super::*;
use crate::compact::{CompactReconstruction, PatchCache, CACHE_SLOTS, ZERO_EXPONENT};

fn compact1(sq: &SampledQuadtree, e: Estimator) -> CompactReconstruction {
    CompactReconstruction::build(std::slice::from_ref(sq), e).unwrap()
}

/// The half-steps dq of `polygon`'s 12 quantities (0 for a zero quantity).
fn half_steps(c: &CompactReconstruction, polygon: u32) -> [f64; 12] {
    c.exponents(polygon).map(|e| {
        if e == ZERO_EXPONENT {
            0.0
        } else {
            0.5 * 2f64.powi(e as i32)
        }
    })
}

/// Bound on the size-scaled derivative error of a quantized patch of width w, scaled by
/// ws <= w: with sum |h00'| + |h01'| = 12 s(1-s) <= 3 and |h10'| + |h11'| <= 1 on [0, 1],
/// ws |d f_u| <= 3 df + w dfu + (3/4) w dfv + (w^2/4) dfuv (and f_v symmetrically), so
/// 3 df + w (dfu + dfv) + (w^2/4) dfuv bounds both; the largest over channels.
fn derivative_bound(dq: &[f64; 12], w: f64) -> f64 {
    (0..3)
        .map(|ch| 3.0 * dq[ch] + w * (dq[3 + ch] + dq[6 + ch]) + w * w / 4.0 * dq[9 + ch])
        .fold(0.0, f64::max)
}

/// Leaf id (rank among leaves in node order) of every leaf node of a one-polygon tree.
fn leaf_ids(tree: &Quadtree) -> std::collections::HashMap<u32, u32> {
    (0u32..)
        .zip(tree.nodes())
        .filter(|(_, n)| n.is_leaf())
        .map(|(id, _)| id)
        .zip(0u32..)
        .collect()
}

/// Sum of |coefficients| of channel `ch`: with all monomials in [0, 1], rounding the patch's
/// coefficients to f32 moves its value by at most 2^-24 times this.
fn abs_sum(p: &PatchCoeffs, ch: usize) -> f64 {
    p.c[ch].iter().map(|x| x.abs() as f64).sum()
}

/// Compact patches are the unquantized ones within the module docs' bound, everywhere on a grid
/// of points per leaf; `locate` and the cells are Reconstruction's; C1 holds up to both sides'
/// quantization bounds (exactly at shared corners).
fn check_compact_against_reconstruction(sq: &SampledQuadtree, e: Estimator, pts: &[(f32, f32)]) {
    use crate::PatchSource;
    let rec = build1(sq, e);
    let c = compact1(sq, e);
    assert_eq!(c.polygon_count(), 1);
    assert_eq!(c.leaf_count(), rec.patches().len());
    for id in 0..c.leaf_count() as u32 {
        let (a, b) = (c.expand(id), *rec.patch(id));
        assert_eq!(PatchSource::cell(&c, id), PatchSource::cell(&rec, id));
        assert_eq!((a.u0, a.v0, a.inv_w), (b.u0, b.v0, b.inv_w));
        assert!(a.is_finite());
        let bound = c.error_bound(id);
        let w = 1.0 / b.inv_w as f64;
        for i in 0..=6 {
            for j in 0..=6 {
                let u = b.u0 as f64 + w * i as f64 / 6.0;
                let v = b.v0 as f64 + w * j as f64 / 6.0;
                let (fa, _, _) = a.eval_grad_f64(u, v);
                let (fb, _, _) = b.eval_grad_f64(u, v);
                for ch in 0..3 {
                    // f32 coefficient rounding of both patches, plus f64 rounding (1e-12 of the
                    // same sums covers the f64 expansion and evaluation of O(100) terms).
                    let sums = abs_sum(&a, ch) + abs_sum(&b, ch);
                    let allow = bound[ch] + sums * (2f64.powi(-24) + 1e-12);
                    let d = (fa[ch] - fb[ch]).abs();
                    assert!(
                        d <= allow,
                        "leaf {id} ch {ch}: |{} - {}| > {allow}",
                        fa[ch],
                        fb[ch]
                    );
                }
            }
        }
    }
    for &(u, v) in pts {
        assert_eq!(c.locate(0, u, v), rec.locate(0, u, v), "({u}, {v})");
    }
    let p = build_polygon(0, sq, e).unwrap();
    let tree = &p.refined.tree;
    let ids = leaf_ids(tree);
    let dq = half_steps(&c, 0);
    let range = sample_range(sq).max(1e-3);
    let (jv, jd) = c1_excess(
        tree,
        |id| c.poly(ids[&id]),
        |a, b, _ws| {
            let bv = |id: u32| c.error_bound(ids[&id]).into_iter().fold(0.0, f64::max);
            let bd = |id: u32| derivative_bound(&dq, tree.node(id).cell.width());
            (bv(a) + bv(b), bd(a) + bd(b))
        },
    );
    assert!(jv <= 1e-5 * range && jd <= 1e-5 * range, "{e:?}: {jv} {jd}");
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 32, ..ProptestConfig::default() })]

    #[test]
    fn compact_is_reconstruction_within_the_quantization_bound(
        choices in prop::collection::vec(any::<u32>(), 1..60),
        amp in prop::collection::vec(-3.0f64..3.0, 3),
        edge in 0.05f64..0.95,
        pts in prop::collection::vec((0.0f32..=1.0, 0.0f32..=1.0), 30),
    ) {
        let tree = random_tree(&choices, 12);
        let f = |u: f64, v: f64| {
            let s = if u + 0.3 * v < edge { 0.0 } else { 1.0 };
            Vec3::new(
                (1.5 + amp[0] * (3.0 * u + 1.0).sin() * (2.0 * v).cos()) as f32,
                (amp[1].abs() * two_spots(u, v) + 0.5 * s) as f32,
                (amp[2] * u * u * v + 0.2 * s) as f32,
            )
        };
        let sq = SampledQuadtree::from_fn(tree, f);
        for e in Estimator::ALL {
            check_compact_against_reconstruction(&sq, e, &pts);
        }
    }

    #[test]
    fn decode_of_garbage_is_an_error_or_a_valid_reconstruction(
        bytes in prop::collection::vec(any::<u8>(), 0..400),
        flips in prop::collection::vec((any::<usize>(), any::<u8>()), 1..8),
    ) {
        let mut with_magic = b"PFRRPC01".to_vec();
        with_magic.extend_from_slice(&bytes);
        for b in [&bytes, &with_magic] {
            if let Ok(c) = CompactReconstruction::decode(b) {
                prop_assert_eq!(&c.encode(), b);
            }
        }
        // Corrupt a real encoding: never a panic; whatever decodes re-encodes to the same bytes.
        let tree = random_tree(&[3, 5, 7, 9, 2, 4], 8);
        let sq = SampledQuadtree::from_fn(tree, grey(two_spots));
        let mut enc = compact1(&sq, Estimator::default()).encode();
        for (at, x) in flips {
            let n = enc.len();
            enc[at % n] ^= x | 1;
        }
        if let Ok(c) = CompactReconstruction::decode(&enc) {
            prop_assert_eq!(c.encode(), enc);
        }
    }
}

#[test]
fn compact_on_a_conforming_grid_is_c1_to_rounding() {
    // A uniform tree has no T-vertex: every edge joins two patches with the same (shared,
    // quantized) corner data, so quantization cannot open a jump.
    let tree = adaptive_tree(4, |_| true);
    let f = |u: f64, v: f64| {
        Vec3::new(
            (1.0 + 0.5 * (3.0 * u + 1.0).sin() * (2.0 * v).cos()) as f32,
            two_spots(u, v) as f32,
            (u * u * v + 0.2) as f32,
        )
    };
    let sq = SampledQuadtree::from_fn(tree, f);
    for e in Estimator::ALL {
        let p = build_polygon(0, &sq, e).unwrap();
        let ids = leaf_ids(&p.refined.tree);
        let c = compact1(&sq, e);
        assert_eq!(p.refined.tree.t_vertices(), vec![]);
        let (jv, jd) = c1_excess(&p.refined.tree, |id| c.poly(ids[&id]), |_, _, _| (0.0, 0.0));
        // f64 rounding of O(10) numbers, as for the unquantized patches.
        assert!(jv < 1e-12 && jd < 1e-12, "{e:?}: {jv} {jd}");
    }
}

#[test]
fn compact_step_stays_within_the_value_half_step_of_its_range() {
    let lo = 0.1f32;
    let hi = 0.83f32;
    let f = |u: f64, _: f64| if u < 0.37 { lo } else { hi };
    let tree = criterion_tree(&|u, v| f(u, v) as f64, 2, 8, 1e-3);
    let sq = SampledQuadtree::from_fn(tree, |u, v| Vec3::splat(f(u, v)));
    let c = compact1(&sq, Estimator::Monotone);
    let df = half_steps(&c, 0)[0] as f32;
    // f32 evaluation of coefficients summing to O(1): a few ulps of 1.
    let allow = df + 8.0 * f32::EPSILON;
    let n = 257;
    for j in 0..=n {
        for i in 0..=n {
            let (u, v) = (i as f32 / n as f32, j as f32 / n as f32);
            let x = c.expand(c.locate(0, u, v)).eval(u, v);
            assert!(
                x.min_element() >= lo - allow && x.max_element() <= hi + allow,
                "({u}, {v}): {x}"
            );
        }
    }
}

#[test]
fn compact_exact_data_expand_to_reconstructions_bits() {
    // Bilinear data with dyadic coefficients on a shallow uniform tree: values, derivatives and
    // twists are multiples of 2^-8 below 8, so quantization is exact and the expansion is the
    // same arithmetic on the same numbers as Reconstruction's.
    let tree = adaptive_tree(3, |_| true);
    let sq = SampledQuadtree::from_fn(tree, |u, v| {
        Vec3::new(
            (1.0 + 2.0 * u - v + 0.5 * u * v) as f32,
            (0.25 + u) as f32,
            3.0,
        )
    });
    for e in Estimator::ALL {
        let rec = build1(&sq, e);
        let c = compact1(&sq, e);
        for id in 0..c.leaf_count() as u32 {
            assert_eq!(c.expand(id), *rec.patch(id));
        }
        // A constant channel: its derivatives are zero quantities.
        let ex = c.exponents(0);
        for kind in 1..4 {
            assert_eq!(ex[3 * kind + 2], ZERO_EXPONENT);
        }
    }
}

fn compact_scene() -> Vec<SampledQuadtree> {
    (0..5)
        .map(|k| {
            let tree = criterion_tree(&two_spots, k % 3, 4 + k % 3, 2e-3);
            SampledQuadtree::from_fn(tree, |u, v| {
                Vec3::new(
                    (two_spots(u, v) + k as f64) as f32,
                    spot(u, v) as f32,
                    step(u, v) as f32 * 0.5,
                )
            })
        })
        .collect()
}

#[test]
fn compact_encode_decode_round_trip_is_bit_exact() {
    let polys = compact_scene();
    let c = CompactReconstruction::build(&polys, Estimator::default()).unwrap();
    let enc = c.encode();
    assert_eq!(enc.len(), c.encoded_len());
    assert_eq!(c.stats().encoded_bytes, enc.len());
    let d = CompactReconstruction::decode(&enc).unwrap();
    assert_eq!(d, c);
    assert_eq!(d.polygon_count(), 5);
    for id in 0..c.leaf_count() as u32 {
        let (a, b) = (c.expand(id), d.expand(id));
        let bits = |p: &PatchCoeffs| p.c.map(|ch| ch.map(f32::to_bits));
        assert_eq!(bits(&a), bits(&b));
    }
    assert_eq!(d.encode(), enc);
    // Locate agrees with Reconstruction over all polygons.
    let rec = Reconstruction::build(&polys, Estimator::default()).unwrap();
    assert_eq!(rec.patches().len(), c.leaf_count());
    for p in 0..5u32 {
        for k in 0..200 {
            let (u, v) = ((k as f32 * 0.618).fract(), (k as f32 * 0.377).fract());
            assert_eq!(d.locate(p, u, v), rec.locate(p, u, v));
        }
    }
    let st = c.stats();
    assert_eq!(st.total_bytes, c.bytes());
    assert_eq!(st.leaves, rec.stats().patches);
    assert_eq!(st.vertices, rec.stats().vertices);
    assert_eq!(st.nodes, rec.stats().tree_nodes);
}

#[test]
fn compact_decode_rejects_malformed_bytes() {
    let polys = compact_scene();
    let enc = CompactReconstruction::build(&polys[..2], Estimator::default())
        .unwrap()
        .encode();
    // Every truncation.
    for n in 0..enc.len() {
        assert!(
            CompactReconstruction::decode(&enc[..n]).is_err(),
            "prefix {n}"
        );
    }
    // Trailing bytes, wrong magic.
    let mut longer = enc.clone();
    longer.push(0);
    assert!(CompactReconstruction::decode(&longer).is_err());
    let mut magic = enc.clone();
    magic[0] ^= 1;
    assert!(CompactReconstruction::decode(&magic).is_err());
    // A polygon count far beyond the data.
    let mut count = enc.clone();
    count[8..12].copy_from_slice(&u32::MAX.to_le_bytes());
    assert!(CompactReconstruction::decode(&count).is_err());
    // Node count not 1 mod 4; the root's split bit set on a one-node tree; depth beyond 16.
    let one = |nodes: u32, bits: &[u8]| {
        let mut b = b"PFRRPC01".to_vec();
        b.extend_from_slice(&1u32.to_le_bytes());
        b.extend_from_slice(&nodes.to_le_bytes());
        b.extend_from_slice(bits);
        b.extend_from_slice(&[0u8; 24]);
        b
    };
    assert!(CompactReconstruction::decode(&one(2, &[0])).is_err());
    assert!(CompactReconstruction::decode(&one(1, &[1])).is_err());
    assert!(CompactReconstruction::decode(&one(1, &[2])).is_err());
    // A chain of splits of child 3 down to level 17: 1 + 4 * 17 nodes, split bits at 0, 4, 8, ...
    let n = 1 + 4 * 17;
    let mut bits = vec![0u8; (n as usize).div_ceil(8)];
    for k in 0..17 {
        bits[4 * k / 8] |= 1 << ((4 * k) % 8);
    }
    assert!(CompactReconstruction::decode(&one(n, &bits)).is_err());
    // A one-node tree with all-zero exponents and mantissas decodes (4 vertices).
    let mut ok = one(1, &[0]);
    ok.extend_from_slice(&[0u8; 4 * 24]);
    let c = CompactReconstruction::decode(&ok).unwrap();
    assert_eq!((c.leaf_count(), c.stats().vertices), (1, 4));
    // Nonzero mantissa under a zero exponent; exponent out of range.
    let zero_exp = ZERO_EXPONENT.to_le_bytes();
    let mut z = one(1, &[0]);
    let at = z.len() - 24;
    z[at..at + 2].copy_from_slice(&zero_exp);
    let mut zm = z.clone();
    zm.extend_from_slice(&[1u8; 4 * 24]);
    assert!(CompactReconstruction::decode(&zm).is_err());
    let mut big = one(1, &[0]);
    big[at..at + 2].copy_from_slice(&2000i16.to_le_bytes());
    big.extend_from_slice(&[0u8; 4 * 24]);
    assert!(CompactReconstruction::decode(&big).is_err());
    // Huge exponent with nonzero mantissas overflows f32 when expanded: an error.
    let mut inf = one(1, &[0]);
    inf[at..at + 2].copy_from_slice(&1000i16.to_le_bytes());
    inf.extend_from_slice(&[1u8; 4 * 24]);
    assert!(CompactReconstruction::decode(&inf).is_err());
}

#[test]
fn compact_same_bytes_for_any_thread_count_and_bad_input_errors() {
    let polys = compact_scene();
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| CompactReconstruction::build(&polys, Estimator::default()).unwrap())
    };
    assert_eq!(run(1).encode(), run(3).encode());
    let mut nan = polys[1].clone();
    nan.values[2].x = f32::NAN;
    let err = CompactReconstruction::build(&[polys[0].clone(), nan], Estimator::Plain).unwrap_err();
    assert!(err.to_string().contains("polygon 1"), "{err}");
    assert_eq!(
        CompactReconstruction::build(&[], Estimator::Plain)
            .unwrap()
            .polygon_count(),
        0
    );
}

#[test]
fn the_patch_cache_returns_exactly_the_expanded_patch() {
    // Two reconstructions used alternately with one cache (the cache must not serve one's
    // patches for the other's ids), every id visited twice (misses, then hits).
    let a = compact1(
        &SampledQuadtree::from_fn(criterion_tree(&spot, 1, 7, 1e-3), grey(spot)),
        Estimator::Monotone,
    );
    let b = compact1(
        &SampledQuadtree::from_fn(criterion_tree(&step, 1, 7, 1e-3), grey(step)),
        Estimator::Monotone,
    );
    assert!(a.leaf_count() > 64 && b.leaf_count() > 64);
    for c in [&a, &b] {
        // Below the cap, every leaf has a slot of its own.
        let slots = c.cache_slots();
        assert!(slots.is_power_of_two() && slots >= c.leaf_count() && slots < 2 * c.leaf_count());
    }
    let mut cache = PatchCache::default();
    for _ in 0..2 {
        for c in [&a, &b] {
            for id in 0..c.leaf_count() as u32 {
                assert_eq!(c.cached_patch(id, &mut cache), c.expand(id));
                assert_eq!(PatchSource::patch(c, id), c.expand(id));
            }
        }
    }
}

#[test]
fn a_patch_cache_allocates_what_its_accounting_says() {
    let small = compact1(
        &SampledQuadtree::from_fn(criterion_tree(&spot, 1, 7, 1e-3), grey(spot)),
        Estimator::Monotone,
    );
    let mut cache = PatchCache::default();
    assert_eq!(cache.bytes(), 0);
    small.warm(&mut cache);
    assert_eq!(cache.bytes(), small.cache_bytes());
    assert!(small.cache_bytes() < CACHE_SLOTS * std::mem::size_of::<crate::PatchCoeffs>());
    // More leaves than the cap (a full depth-8 tree, 65,536 leaves): CACHE_SLOTS slots, shared
    // by several leaves each, every patch still the expanded one.
    let mut t = Quadtree::new();
    let mut level = vec![0u32];
    for _ in 0..8 {
        level = level
            .iter()
            .flat_map(|&n| {
                let c = t.split(n);
                [c, c + 1, c + 2, c + 3]
            })
            .collect();
    }
    let wavy = |u: f64, v: f64| 2.0 + (37.0 * u).sin() * (29.0 * v).cos();
    let big = compact1(
        &SampledQuadtree::from_fn(t, grey(wavy)),
        Estimator::Monotone,
    );
    assert_eq!(big.leaf_count(), 65_536);
    assert_eq!(big.cache_slots(), CACHE_SLOTS);
    big.warm(&mut cache);
    assert_eq!(cache.bytes(), big.cache_bytes());
    for id in (0..big.leaf_count() as u32).step_by(97) {
        assert_eq!(big.cached_patch(id, &mut cache), big.expand(id));
    }
    // Back to the small one: the cache is resized to its slots again.
    small.warm(&mut cache);
    assert_eq!(cache.bytes(), small.cache_bytes());
}
