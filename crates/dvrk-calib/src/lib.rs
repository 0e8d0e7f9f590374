//! Motion-capture calibration of dvrk-kin models (work in progress: see issue 4).
pub use dvrk_kin;
