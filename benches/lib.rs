//! The criterion benchmarks of pixelflow-sim (`frame.rs`: whole frames and each stage per
//! method and instruction set; `reconstruction.rs`: building RRPs). Run them with
//! `cargo bench -p pixelflow-bench --profile release --bench frame` (or `--bench
//! reconstruction`). `--profile release` matters: plain `cargo bench` compiles the workspace's
//! libraries with the `bench` profile, whose per-package overrides (there to keep test builds
//! short) leave the engine at optimization level 1 and its base crate unoptimized, so it would
//! time code 2 to 10 times slower than a release build runs. The benchmarks refuse such a
//! build ([`require_optimized_engine`]).

/// Panics, naming the command to use, unless `level` (the engine's `OPT_LEVEL`) is `"3"`.
pub fn require_optimized_engine(level: &str) {
    assert!(
        level == "3",
        "the engine was compiled at optimization level {level}, not 3: these benchmarks would \
         time unoptimized code. Run `cargo bench -p pixelflow-bench --profile release` (plain \
         `cargo bench` takes the workspace's `bench` profile overrides for test builds)"
    );
}
