//! Empty: the package is its integration tests (`kin/main.rs`).
