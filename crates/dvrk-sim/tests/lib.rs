//! Empty: the package is its integration tests (`sim/main.rs`) and the library's own unit
//! tests (`sim_unit`).
