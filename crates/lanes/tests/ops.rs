//! Every operation of every token against its scalar definition, bit for bit, on awkward values
//! (signed zeros, subnormals, infinities, NaN, ids across the sign bit of i32), run inside the
//! token's own [`Simd::vectorize`] (compiled as the kernels are).
//!
//! Without the libtest harness, so that the report is shown: one line per token, `ok` or
//! `NOT RUN` with what this CPU lacks. Any mismatch panics (exit code 101).

use std::panic::{catch_unwind, AssertUnwindSafe};

use glam::Vec3;
use lanes::{sanitize1, Kernel, Level, Simd};

const F: [f32; 14] = [
    1.0,
    -1.5,
    0.0,
    -0.0,
    f32::INFINITY,
    f32::NEG_INFINITY,
    f32::NAN,
    f32::MAX,
    f32::MIN_POSITIVE,
    1e-45,
    -1e-45,
    0.7,
    3.0e38,
    2.5,
];
const U: [u32; 8] = [
    0,
    1,
    7,
    0x7fff_ffff,
    0x8000_0000,
    0x8000_0001,
    0xffff_fffe,
    u32::MAX,
];

/// A deterministic stream of indices, from the project's seeded generator.
struct Rng(base::rng::Rng);

impl Rng {
    fn next(&mut self, n: usize) -> usize {
        self.0.below(n as u32) as usize
    }
}

/// All the checks, for one token.
struct Checks;

impl Kernel for Checks {
    type Output = usize;
    fn run<S: Simd>(self, s: S) -> usize {
        let n = S::LANES;
        let mut rng = Rng(base::rng::Rng::new(7));
        let mut checked = 0;
        for _ in 0..2000 {
            let a: Vec<f32> = (0..n).map(|_| F[rng.next(F.len())]).collect();
            let b: Vec<f32> = (0..n).map(|_| F[rng.next(F.len())]).collect();
            let p: Vec<u32> = (0..n).map(|_| U[rng.next(U.len())]).collect();
            let q: Vec<u32> = (0..n).map(|_| U[rng.next(U.len())]).collect();
            let bits = rng.next(1 << n) as u32;
            let (va, vb, vp, vq) = (s.load(&a), s.load(&b), s.load_u(&p), s.load_u(&q));
            let out = |x: S::F| {
                let mut o = vec![0.0f32; n];
                s.store(x, &mut o);
                o.iter().map(|x| x.to_bits()).collect::<Vec<_>>()
            };
            let want = |f: &dyn Fn(f32, f32) -> f32| {
                (0..n).map(|l| f(a[l], b[l]).to_bits()).collect::<Vec<_>>()
            };
            assert_eq!(out(s.add(va, vb)), want(&|x, y| x + y), "add");
            assert_eq!(out(s.sub(va, vb)), want(&|x, y| x - y), "sub");
            assert_eq!(out(s.mul(va, vb)), want(&|x, y| x * y), "mul");
            assert_eq!(out(s.sanitize(va)), want(&|x, _| sanitize1(x)), "sanitize");
            assert_eq!(
                out(s.min(va, vb)),
                want(&|x, y| if x < y { x } else { y }),
                "min"
            );
            assert_eq!(
                out(s.max(va, vb)),
                want(&|x, y| if x > y { x } else { y }),
                "max"
            );
            assert_eq!(out(s.floor(va)), want(&|x, _| x.floor()), "floor");
            // Truncation of values in i32's range: these and their fractions' neighbours.
            let ints: Vec<f32> = (0..n)
                .map(|l| {
                    [-2.5f32, -1.0, -0.5, 0.0, 0.7, 3.0, 8191.9, -2.0e9][(l + rng.next(8)) % 8]
                })
                .collect();
            let ti: Vec<u32> = (0..n).map(|l| ints[l] as i32 as u32).collect();
            let mut got = vec![0u32; n];
            s.blend_store_u(&mut got, s.to_i32(s.load(&ints)), s.mask(u32::MAX));
            assert_eq!(got, ti, "to_i32");
            let prod: Vec<u32> = (0..n).map(|l| p[l].wrapping_mul(q[l])).collect();
            s.blend_store_u(&mut got, s.mul_i(vp, vq), s.mask(u32::MAX));
            assert_eq!(got, prod, "mul_i");
            assert_eq!(out(s.splat(a[0])), want(&|_, _| a[0]), "splat");
            let lane_bits =
                |f: &dyn Fn(usize) -> bool| (0..n).fold(0u32, |m, l| m | ((f(l) as u32) << l));
            assert_eq!(s.bits(s.lt(va, vb)), lane_bits(&|l| a[l] < b[l]), "lt");
            assert_eq!(s.bits(s.eq(va, vb)), lane_bits(&|l| a[l] == b[l]), "eq");
            assert_eq!(s.bits(s.eq_u(vp, vq)), lane_bits(&|l| p[l] == q[l]), "eq_u");
            assert_eq!(s.bits(s.lt_u(vp, vq)), lane_bits(&|l| p[l] < q[l]), "lt_u");
            let sum: Vec<u32> = (0..n).map(|l| p[l].wrapping_add(q[l])).collect();
            assert_eq!(
                s.nonneg_bits(s.add_i(vp, vq)),
                lane_bits(&|l| sum[l] as i32 >= 0),
                "add_i"
            );
            let or: Vec<u32> = (0..n).map(|l| p[l] | q[l]).collect();
            assert_eq!(
                s.nonneg_bits(s.or_u(vp, vq)),
                lane_bits(&|l| or[l] as i32 >= 0),
                "or_u"
            );
            let m = s.mask(bits);
            assert_eq!(s.bits(m), bits, "mask and bits");
            assert_eq!(s.any(m), bits != 0, "any");
            let m2 = s.lt(va, vb);
            let b2 = s.bits(m2);
            assert_eq!(s.bits(s.and_m(m, m2)), bits & b2, "and_m");
            assert_eq!(s.bits(s.or_m(m, m2)), bits | b2, "or_m");
            let on = |l: usize| (bits >> l) & 1 != 0;
            assert_eq!(
                out(s.select(m, va, vb)),
                (0..n)
                    .map(|l| if on(l) { a[l] } else { b[l] }.to_bits())
                    .collect::<Vec<_>>(),
                "select"
            );
            let mut dst = b.clone();
            s.blend_store(&mut dst, va, m);
            for l in 0..n {
                let w = if on(l) { a[l] } else { b[l] };
                assert_eq!(dst[l].to_bits(), w.to_bits(), "blend_store");
            }
            let mut dst = q.clone();
            s.blend_store_u(&mut dst, vp, m);
            for l in 0..n {
                assert_eq!(dst[l], if on(l) { p[l] } else { q[l] }, "blend_store_u");
            }
            let c = [va, vb, s.sub(va, vb)];
            let mut px = vec![Vec3::splat(9.0); n];
            s.store_rgb(&c, &mut px);
            for l in 0..n {
                let want = [a[l], b[l], a[l] - b[l]].map(sanitize1).map(f32::to_bits);
                assert_eq!(
                    px[l].to_array().map(f32::to_bits),
                    want,
                    "store_rgb lane {l}"
                );
            }
            checked += 1;
        }
        // The gather, over arrays of several lengths, every index, bits untouched: blocks with
        // the last texel (which the loads of the 8-lane tokens leave to the gather instruction)
        // and blocks without it.
        for len in [1usize, 2, 7, 8, 9, 64, 1000, 4096] {
            let texels: Vec<Vec3> = (0..len)
                .map(|k| Vec3::new(F[k % F.len()], F[(k * 3 + 1) % F.len()], k as f32))
                .collect();
            let mut blocks: Vec<Vec<u32>> = (0..len.max(n))
                .step_by(n)
                .map(|k0| (0..n).map(|l| ((k0 + l) * 7919 % len) as u32).collect())
                .collect();
            blocks.push((0..n).map(|l| (len - 1 - l.min(len - 1)) as u32).collect());
            blocks.push((0..n).map(|l| (l * 3 % len) as u32).collect());
            for idx in blocks {
                // SAFETY: every index is below `len`, the array's length.
                let g = unsafe { s.gather_rgb(&texels, s.load_u(&idx)) };
                let g = g.map(|c| {
                    let mut o = vec![0.0f32; n];
                    s.store(c, &mut o);
                    o
                });
                for l in 0..n {
                    let t = texels[idx[l] as usize].to_array().map(f32::to_bits);
                    let got = [g[0][l], g[1][l], g[2][l]].map(f32::to_bits);
                    assert_eq!(got, t, "gather, length {len}, indices {idx:?}");
                }
            }
        }
        checked
    }
}

/// The checks with the token at `level` and its 8-lane half, if this CPU has it.
fn run(level: Level) -> Option<usize> {
    match level {
        Level::Portable => Some(lanes::Portable::new().vectorize(Checks)),
        #[cfg(target_arch = "x86_64")]
        Level::Avx2 => lanes::Avx2::try_new().map(|s| s.vectorize(Checks)),
        #[cfg(target_arch = "x86_64")]
        Level::Avx512 => {
            lanes::Avx512::try_new().map(|s| s.vectorize(Checks) + s.half().vectorize(Checks))
        }
        #[cfg(not(target_arch = "x86_64"))]
        _ => None,
    }
}

fn main() {
    println!("\nlane operations against their scalar definitions, bit for bit:");
    let mut failed = Vec::new();
    for level in Level::ALL {
        match catch_unwind(AssertUnwindSafe(|| run(level))) {
            Ok(Some(n)) => println!("  {:<9} ok ({n} checks)", level.name()),
            Ok(None) => println!(
                "  {:<9} NOT RUN (this CPU lacks {})",
                level.name(),
                level.requirement()
            ),
            Err(_) => {
                println!("  {:<9} FAILED", level.name());
                failed.push(level.name());
            }
        }
    }
    if !failed.is_empty() {
        panic!("tokens whose operations differ from their definitions: {failed:?}");
    }
}
