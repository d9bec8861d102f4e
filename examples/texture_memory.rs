//! Texture memory of scenes' radiosity solutions under `SizePolicy::FromDepth`:
//! `cargo run --release --example texture_memory -- scenes/cornell-box.toml ...`
//! (a scene solves first; a `.pfsol` solution file is read).

use std::time::Instant;

use pixelflow_sim::pipeline;
use pixelflow_sim::texture::{SizePolicy, TextureSet};

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
    Ok(())
}
