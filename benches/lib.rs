//! Nothing: the package's benchmarks are its `[[bench]]` targets (`fk.rs`, `rtf.rs`, `fit.rs`),
//! run with `cargo bench -p dvrk-benches`.
