//! Headless dynamic simulation of dvrk-kin models (work in progress: see issue 3).
pub use dvrk_kin;
