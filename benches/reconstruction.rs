//! Reconstruction benchmarks: construction of a depth-7 adaptive two-spots tree, and eval_many
//! throughput on a coherent scanline-like point stream.

// `criterion_group!` defines a public function it cannot document.
#![allow(missing_docs)]

use base::quadtree::{Quadtree, SampledQuadtree};
use criterion::{criterion_group, Criterion, Throughput};
use glam::Vec3;
use reconstruction::{Estimator, Reconstruction};
use std::hint::black_box;

fn two_spots(u: f64, v: f64) -> f64 {
    let g =
        |cu: f64, cv: f64, s: f64| (-((u - cu).powi(2) + (v - cv).powi(2)) / (2.0 * s * s)).exp();
    0.05 + 0.9 * g(0.3, 0.35, 0.08) + 0.6 * g(0.7, 0.65, 0.05)
}

/// Depth-7 tree refined where the bilinear interpolant of a cell's corners misses the function
/// at its centre by more than 1e-3 (at least 2 levels everywhere).
fn tree() -> SampledQuadtree {
    let mut t = Quadtree::new();
    let mut stack = vec![0u32];
    while let Some(id) = stack.pop() {
        let c = t.node(id).cell;
        let (u0, v0, u1, v1) = c.bounds();
        let bil =
            0.25 * (two_spots(u0, v0) + two_spots(u1, v0) + two_spots(u0, v1) + two_spots(u1, v1));
        let err = (two_spots(0.5 * (u0 + u1), 0.5 * (v0 + v1)) - bil).abs();
        if c.level < 7 && (c.level < 2 || err > 1e-3) {
            let f = t.split(id);
            stack.extend(f..f + 4);
        }
    }
    SampledQuadtree::from_fn(t, |u, v| Vec3::splat(two_spots(u, v) as f32))
}

fn bench(c: &mut Criterion) {
    let sq = tree();
    let polys = vec![sq];
    c.bench_function("build depth-7 two-spots (monotone)", |b| {
        b.iter(|| Reconstruction::build(black_box(&polys), Estimator::Monotone).unwrap())
    });
    let rec = Reconstruction::build(&polys, Estimator::Monotone).unwrap();
    let st = rec.stats();
    eprintln!(
        "tree: {} leaves, depth {}; RRP: {} patches, {} B stored, full grid {} B, \
         texture 8/12/32 bit {}/{}/{} B",
        st.input_leaves,
        polys[0].tree.depth(),
        st.patches,
        st.bytes,
        st.full_grid_bytes,
        st.texture_bytes_8,
        st.texture_bytes_12,
        st.texture_bytes_32
    );
    let n = 256usize;
    let uv: Vec<[f32; 2]> = (0..n * n)
        .map(|k| {
            [
                ((k % n) as f32 + 0.5) / n as f32,
                ((k / n) as f32 + 0.5) / n as f32,
            ]
        })
        .collect();
    let mut out = vec![Vec3::ZERO; uv.len()];
    let mut g = c.benchmark_group("eval_many");
    g.throughput(Throughput::Elements(uv.len() as u64));
    g.bench_function("256x256 row-major", |b| {
        b.iter(|| rec.eval_many(0, black_box(&uv), &mut out))
    });
    g.finish();
}

criterion_group!(benches, bench);
fn main() {
    pixelflow_bench::require_optimized_engine(engine::OPT_LEVEL);
    benches();
    Criterion::default().configure_from_args().final_summary();
}
