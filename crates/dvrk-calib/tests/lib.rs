//! Empty: the package is its integration tests (`calib/main.rs`).
