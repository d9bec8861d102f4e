//! The samples-alone form of the RRPs, measured against the Hermite form that
//! [`super::compact`] holds and encodes: a polygon's solution quadtree (one bit per node) and its
//! radiosity samples quantized to `bits`-bit unsigned mantissas of one power-of-two step per
//! polygon and channel; the derivatives are not stored but estimated again when loading
//! (`estimate`, then `refine`, as [`super::Reconstruction::build`] does).
//!
//! **Why it is only measured.** It is 3-5x smaller than the encoded Hermite form, but a reader
//! must run the whole reconstruction (derivative estimation needs every neighbour of a vertex, so
//! a patch cannot be expanded from the samples of its own corners) and the result depends on the
//! estimator of the reading program. A solution file stores the samples (32-bit floats) and the
//! Hermite form, so a render from a file neither re-estimates nor depends on the reader's
//! estimator; `stats` reports this form's bytes beside it (`rrp_samples_bytes`).
//!
//! **Quantization and its bound.** Samples are non-negative (the solver's invariant). For channel
//! c of a polygon with largest sample M_c > 0 the step is 2^e, e the smallest integer with
//! `M_c / 2^e <= 2^bits - 1`, and a sample x is stored as `round(x / 2^e)`; dequantization
//! `m * 2^e` is exact in f64 and rounds once to f32. So each sample moves by at most
//! `2^(e-1) < M_c / (2^bits - 1)` plus half an f32 ulp of the result: at 16 bits, 1.5e-5 of the
//! polygon's largest value ([`sample_bound`]). A zero channel stays zero; the form of a form is
//! itself ([`quantize`] is idempotent).
//!
//! **Bytes** ([`encoded_len`]): 8 (magic) + 4 (polygon count), then per polygon a 4-byte node
//! count, one bit per node (the canonical node order of [`base::quadtree::Quadtree::grow`]
//! makes the bits the whole tree; vertex keys follow from it), three 2-byte exponents and
//! `3 * bits` bits per vertex, each section padded to a byte.

use glam::Vec3;

use base::quadtree::SampledQuadtree;

/// Bits per mantissa of the form the docs and `stats` report.
pub const DEFAULT_BITS: u32 = 16;

/// The step exponent of a channel whose largest sample is `max` (finite, > 0): the smallest e
/// with `max / 2^e <= 2^bits - 1`.
fn step_exponent(max: f64, bits: u32) -> i32 {
    let top = ((1u64 << bits) - 1) as f64;
    let mut e = (max / top).log2().ceil() as i32;
    while max / 2f64.powi(e) > top {
        e += 1;
    }
    while max / 2f64.powi(e - 1) <= top {
        e -= 1;
    }
    e
}

/// Per channel, the step 2^e of `p`'s samples (0 for a channel that is zero everywhere).
fn steps(p: &SampledQuadtree, bits: u32) -> [f64; 3] {
    let mut max = [0f64; 3];
    for v in &p.values {
        for (c, m) in max.iter_mut().enumerate() {
            *m = m.max(v[c] as f64);
        }
    }
    max.map(|m| {
        if m > 0.0 {
            2f64.powi(step_exponent(m, bits))
        } else {
            0.0
        }
    })
}

/// `polygons` with every sample replaced by its `bits`-bit quantization (module docs); trees
/// and keys unchanged. `bits` in 1..=24.
pub fn quantize(polygons: &[SampledQuadtree], bits: u32) -> Vec<SampledQuadtree> {
    assert!(
        (1..=24).contains(&bits),
        "mantissa bits {bits} out of 1..=24"
    );
    polygons
        .iter()
        .map(|p| {
            let step = steps(p, bits);
            let q = |x: f32, s: f64| {
                if s == 0.0 {
                    0.0
                } else {
                    ((x as f64 / s).round() * s) as f32
                }
            };
            SampledQuadtree {
                tree: p.tree.clone(),
                keys: p.keys.clone(),
                values: p
                    .values
                    .iter()
                    .map(|v| Vec3::new(q(v.x, step[0]), q(v.y, step[1]), q(v.z, step[2])))
                    .collect(),
            }
        })
        .collect()
}

/// The largest movement of a sample of `p` per channel under [`quantize`] at `bits`: half the
/// step plus half an f32 ulp of the largest value.
pub fn sample_bound(p: &SampledQuadtree, bits: u32) -> [f64; 3] {
    let step = steps(p, bits);
    let mut max = [0f64; 3];
    for v in &p.values {
        for (c, m) in max.iter_mut().enumerate() {
            *m = m.max(v[c] as f64);
        }
    }
    [0, 1, 2].map(|c| 0.5 * step[c] + max[c] * f32::EPSILON as f64)
}

/// Bytes of the samples-alone encoding of `polygons` at `bits` bits per sample and channel.
pub fn encoded_len(polygons: &[SampledQuadtree], bits: u32) -> usize {
    8 + 4
        + polygons
            .iter()
            .map(|p| {
                4 + p.tree.nodes().len().div_ceil(8)
                    + 3 * 2
                    + (3 * bits as usize * p.values.len()).div_ceil(8)
            })
            .sum::<usize>()
}

#[cfg(test)]
mod tests {
    use super::*;
    use base::quadtree::Quadtree;
    use proptest::prelude::*;

    fn polygon(values: Vec<[f32; 3]>, splits: &[u32]) -> SampledQuadtree {
        let mut tree = Quadtree::new();
        for &s in splits {
            if (s as usize) < tree.nodes().len() && tree.node(s).is_leaf() {
                tree.split(s);
            }
        }
        let keys = tree.vertex_keys();
        let values = (0..keys.len())
            .map(|k| Vec3::from(values[k % values.len()]))
            .collect();
        SampledQuadtree { tree, keys, values }
    }

    proptest! {
        #[test]
        fn quantization_stays_within_its_bound_and_is_idempotent(
            values in proptest::collection::vec(
                prop_oneof![Just([0f32; 3]), (0f32..1e3, 0f32..1.0, 0f32..1e-20).prop_map(|(a, b, c)| [a, b, c])],
                1..40),
            splits in proptest::collection::vec(0u32..40, 0..12),
            bits in prop_oneof![Just(8u32), Just(12), Just(16)],
        ) {
            let p = polygon(values, &splits);
            let q = quantize(std::slice::from_ref(&p), bits);
            let bound = sample_bound(&p, bits);
            let top = ((1u64 << bits) - 1) as f64;
            for (a, b) in p.values.iter().zip(&q[0].values) {
                for c in 0..3 {
                    let (x, y) = (a[c] as f64, b[c] as f64);
                    prop_assert!((x - y).abs() <= bound[c], "{x} -> {y}, bound {}", bound[c]);
                    prop_assert!(y >= 0.0 && y.is_finite());
                    if x == 0.0 { prop_assert_eq!(y, 0.0); }
                }
            }
            // The bound is at most the largest value over 2^bits - 1, plus the f32 rounding.
            for c in 0..3 {
                let max = p.values.iter().map(|v| v[c] as f64).fold(0.0, f64::max);
                prop_assert!(bound[c] <= max / top + max * f32::EPSILON as f64);
            }
            prop_assert_eq!(&quantize(&q, bits)[0].values, &q[0].values);
        }
    }

    #[test]
    fn the_encoding_counts_bits_per_node_and_per_sample() {
        // A root split once: 5 nodes (1 byte of bits), 9 vertices: 27 samples of 16 bits.
        let p = polygon(vec![[1.0, 2.0, 3.0]], &[0]);
        assert_eq!(p.tree.nodes().len(), 5);
        assert_eq!(p.values.len(), 9);
        assert_eq!(
            encoded_len(std::slice::from_ref(&p), 16),
            12 + 4 + 1 + 6 + 54
        );
        // 12 bits: 324 bits, 40.5 bytes, padded to 41.
        assert_eq!(encoded_len(&[p], 12), 12 + 4 + 1 + 6 + 41);
    }
}
