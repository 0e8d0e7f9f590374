//! Empty: the package is its integration tests (`sim/main.rs`).
