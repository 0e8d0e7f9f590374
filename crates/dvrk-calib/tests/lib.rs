//! Empty: the package is its integration tests (`calib/main.rs`) and the library's own unit
//! tests (`calib_unit`).
