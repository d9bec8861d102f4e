//! The criterion benchmarks of pixelflow-sim (`frame.rs`: whole frames and each stage per
//! method and instruction set; `reconstruction.rs`: building RRPs). This library is empty: a
//! package needs a target, and the benchmarks are the point. Run them with
//! `cargo bench -p pixelflow-bench --bench frame` (or `--bench reconstruction`).
