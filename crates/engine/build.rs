//! Records the optimization level the engine is compiled at ([`OPT_LEVEL`] in the library, with
//! the `bench` feature), so that the benchmarks can refuse a build that is not fully optimized:
//! `cargo bench` compiles the workspace's libraries with the `bench` profile, whose per-package
//! overrides lower them to keep test builds short (see the workspace's Cargo.toml).
fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    let level = std::env::var("OPT_LEVEL").unwrap_or_default();
    println!("cargo:rustc-env=PIXELFLOW_ENGINE_OPT_LEVEL={level}");
}
