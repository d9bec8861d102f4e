//! Empty: the comparison is the bench `benches/pulp.rs`.
