//! Our tokens against `pulp`'s, on the patch shader's arithmetic: a bicubic patch evaluated by
//! Horner's scheme (separate multiplies and adds) at a million (u, v) pairs, three channels, at
//! each instruction set both crates have (16 lanes with AVX-512, 8 with AVX2). The choice of our
//! own token set over `pulp` rests on this comparison (docs/performance.md).
//!
//! Run: `cargo bench --manifest-path tools/compare-pulp/Cargo.toml`.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use lanes::{Kernel, Simd};
use pulp::{Simd as PulpSimd, WithSimd};

const N: usize = 1 << 20;

/// Patch coefficients: three channels of 16 power coefficients, and the local map.
#[derive(Clone, Copy)]
struct Patch {
    c: [[f32; 16]; 3],
    u0: f32,
    v0: f32,
    inv_w: f32,
}

fn patch() -> Patch {
    let mut c = [[0.0f32; 16]; 3];
    for (ch, row) in c.iter_mut().enumerate() {
        for (k, x) in row.iter_mut().enumerate() {
            *x = ((k * 7 + ch * 3) % 11) as f32 * 0.125 - 0.5;
        }
    }
    Patch { c, u0: 0.25, v0: 0.5, inv_w: 4.0 }
}

struct Ours<'a> {
    p: Patch,
    u: &'a [f32],
    v: &'a [f32],
    out: &'a mut [Vec<f32>; 3],
}

// Written without closures, in both versions: a closure is compiled without the target
// features of the kernel it sits in unless the optimizer inlines it.
#[inline(always)]
fn ma<S: Simd>(s: S, a: S::F, b: S::F, d: S::F) -> S::F {
    s.add(s.mul(a, b), d)
}

#[inline(always)]
fn row<S: Simd>(s: S, k: &[f32; 16], j: usize, x: S::F) -> S::F {
    let r = ma(s, s.splat(k[4 * j + 3]), x, s.splat(k[4 * j + 2]));
    let r = ma(s, r, x, s.splat(k[4 * j + 1]));
    ma(s, r, x, s.splat(k[4 * j]))
}

#[inline(always)]
fn horner<S: Simd>(s: S, k: &[f32; 16], x: S::F, y: S::F) -> S::F {
    let (r3, r2) = (row(s, k, 3, x), row(s, k, 2, x));
    let (r1, r0) = (row(s, k, 1, x), row(s, k, 0, x));
    ma(s, ma(s, ma(s, r3, y, r2), y, r1), y, r0)
}

impl Kernel for Ours<'_> {
    type Output = ();
    #[inline(always)]
    fn run<S: Simd>(self, s: S) {
        let w = s.splat(self.p.inv_w);
        let n = self.u.len() / S::LANES * S::LANES;
        let [r, g, b] = self.out;
        for i in (0..n).step_by(S::LANES) {
            let x = s.mul(s.sub(s.load(&self.u[i..]), s.splat(self.p.u0)), w);
            let y = s.mul(s.sub(s.load(&self.v[i..]), s.splat(self.p.v0)), w);
            s.store(horner(s, &self.p.c[0], x, y), &mut r[i..]);
            s.store(horner(s, &self.p.c[1], x, y), &mut g[i..]);
            s.store(horner(s, &self.p.c[2], x, y), &mut b[i..]);
        }
    }
}

struct Pulp<'a> {
    p: Patch,
    u: &'a [f32],
    v: &'a [f32],
    out: &'a mut [Vec<f32>; 3],
}

#[inline(always)]
fn ma_pulp<S: PulpSimd>(s: S, a: S::f32s, b: S::f32s, d: S::f32s) -> S::f32s {
    s.add_f32s(s.mul_f32s(a, b), d)
}

#[inline(always)]
fn row_pulp<S: PulpSimd>(s: S, k: &[f32; 16], j: usize, x: S::f32s) -> S::f32s {
    let r = ma_pulp(s, s.splat_f32s(k[4 * j + 3]), x, s.splat_f32s(k[4 * j + 2]));
    let r = ma_pulp(s, r, x, s.splat_f32s(k[4 * j + 1]));
    ma_pulp(s, r, x, s.splat_f32s(k[4 * j]))
}

#[inline(always)]
fn horner_pulp<S: PulpSimd>(s: S, k: &[f32; 16], x: S::f32s, y: S::f32s) -> S::f32s {
    let (r3, r2) = (row_pulp(s, k, 3, x), row_pulp(s, k, 2, x));
    let (r1, r0) = (row_pulp(s, k, 1, x), row_pulp(s, k, 0, x));
    ma_pulp(s, ma_pulp(s, ma_pulp(s, r3, y, r2), y, r1), y, r0)
}

impl WithSimd for Pulp<'_> {
    type Output = ();
    #[inline(always)]
    fn with_simd<S: PulpSimd>(self, s: S) {
        let (u, _) = S::as_simd_f32s(self.u);
        let (v, _) = S::as_simd_f32s(self.v);
        let [r, g, b] = self.out;
        let (r, _) = S::as_mut_simd_f32s(r);
        let (g, _) = S::as_mut_simd_f32s(g);
        let (b, _) = S::as_mut_simd_f32s(b);
        let w = s.splat_f32s(self.p.inv_w);
        for i in 0..u.len() {
            let x = s.mul_f32s(s.sub_f32s(u[i], s.splat_f32s(self.p.u0)), w);
            let y = s.mul_f32s(s.sub_f32s(v[i], s.splat_f32s(self.p.v0)), w);
            r[i] = horner_pulp(s, &self.p.c[0], x, y);
            g[i] = horner_pulp(s, &self.p.c[1], x, y);
            b[i] = horner_pulp(s, &self.p.c[2], x, y);
        }
    }
}

fn compare(c: &mut Criterion) {
    let u: Vec<f32> = (0..N).map(|i| 0.25 + (i % 1021) as f32 / 4096.0).collect();
    let v: Vec<f32> = (0..N).map(|i| 0.5 + (i % 997) as f32 / 4096.0).collect();
    let mut out = [vec![0.0f32; N], vec![0.0f32; N], vec![0.0f32; N]];
    let p = patch();
    let mut g = c.benchmark_group("patch-eval");
    g.throughput(Throughput::Elements(N as u64));
    g.sample_size(30);
    if let Some(s) = lanes::Avx512::try_new() {
        g.bench_function("ours-avx512", |b| {
            b.iter(|| s.vectorize(Ours { p, u: &u, v: &v, out: &mut out }))
        });
    }
    if let Some(s) = pulp::x86::V4::try_new() {
        g.bench_function("pulp-v4", |b| {
            b.iter(|| PulpSimd::vectorize(s, Pulp { p, u: &u, v: &v, out: &mut out }))
        });
    }
    if let Some(s) = lanes::Avx2::try_new() {
        g.bench_function("ours-avx2", |b| {
            b.iter(|| s.vectorize(Ours { p, u: &u, v: &v, out: &mut out }))
        });
    }
    if let Some(s) = pulp::x86::V3::try_new() {
        g.bench_function("pulp-v3", |b| {
            b.iter(|| PulpSimd::vectorize(s, Pulp { p, u: &u, v: &v, out: &mut out }))
        });
    }
    g.finish();
    // Both compute the same bits (separate IEEE operations in the same order).
    let mut a = [vec![0.0f32; N], vec![0.0f32; N], vec![0.0f32; N]];
    lanes::Isa::detect().run(Ours { p, u: &u, v: &v, out: &mut a });
    pulp::Arch::new().dispatch(Pulp { p, u: &u, v: &v, out: &mut out });
    assert!(a.iter().zip(&out).all(|(x, y)| x.iter().zip(y).all(|(p, q)| p.to_bits() == q.to_bits())));
}

criterion_group!(benches, compare);
criterion_main!(benches);
