//! Texture memory of scenes' radiosity solutions under `SizePolicy::FromDepth`:
//! `cargo run --release --example texture_memory -- scenes/cornell-box.toml ...`
//! (a scene solves first; a `.pfsol` solution file is read).

use std::time::Instant;

use glam::Vec3;
use pixelflow_sim::pipeline;
use pixelflow_sim::texture::{Filter, RadiosityTexture, SizePolicy, TextureSet};

fn main() -> pixelflow_sim::Result<()> {
    println!("| input | textures | texels (L0) | with chain | 8 bit | 12 bit | 32 bit | 12 bit + chain | build |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for a in std::env::args().skip(1) {
        let p = pipeline::prepare(std::path::Path::new(&a), false)?;
        let depths = TextureSet::depths(&p.solution.polygons);
        let t = Instant::now();
        let set = TextureSet::build(&p.reconstruction, &depths, SizePolicy::FromDepth)?;
        let ms = t.elapsed().as_secs_f64() * 1e3;
        let m = set.memory;
        let mb = |b: u64| b as f64 / (1024.0 * 1024.0);
        println!(
            "| {a} | {} | {} | {} | {:.2} MiB | {:.2} MiB | {:.2} MiB | {:.2} MiB | {ms:.0} ms |",
            m.textures,
            m.texels,
            m.texels_with_chain,
            mb(m.bytes[0]),
            mb(m.bytes[1]),
            mb(m.bytes[2]),
            mb(m.bytes_with_chain[1])
        );
    }
    // Filter throughput on one 256 x 256 texture (1M samples each, one thread, pseudo-random
    // coherent runs): a rough cost ratio of the filters, not a benchmark.
    let texels = (0..256 * 256)
        .map(|k| Vec3::splat((k % 97) as f32 * 0.01))
        .collect();
    let tex = RadiosityTexture::from_texels(256, 256, texels)?;
    let uv: Vec<[f32; 2]> = (0..1_000_000u32)
        .map(|k| [(k % 1000) as f32 / 1000.0, (k / 1000) as f32 / 1000.0])
        .collect();
    let mut out = vec![Vec3::ZERO; uv.len()];
    for (name, f) in [
        ("nearest", Filter::Nearest),
        ("bilinear", Filter::Bilinear),
        ("bicubic (Mitchell)", Filter::MITCHELL),
    ] {
        let t = Instant::now();
        tex.sample_many(0, &uv, f, &mut out);
        let ms = t.elapsed().as_secs_f64() * 1e3;
        let sum: f32 = out.iter().map(|v| v.x).sum();
        println!("{name}: 1M samples in {ms:.1} ms (checksum {sum:.1})");
    }
    Ok(())
}
