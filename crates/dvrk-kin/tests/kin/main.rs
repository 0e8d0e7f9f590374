//! Integration tests of dvrk-kin: one binary, one module per concern. What a signal handler does
//! with staged outputs is its own binary (`tests/staged_files.rs`: the registry is process-wide).
//!
//! - `dynamics`: rigid-body dynamics against closed forms and independent computations.
//! - `effects`: the `[[effects]]` section, its checks, and the friction / spring efforts.
//! - `interchange`: URDF and SDF export and import.
//! - `check`: `dvrk model check` on models no robot has.
//! - `files`, `expressions`, `effect_laws`, `joints`: the library's small pieces (text inputs and
//!   staged outputs, frame expressions, play and presliding, couplings and limits), through the
//!   public API: the library has no unit tests of its own, so `cargo test` compiles it once.

mod check;
mod dynamics;
mod effect_laws;
mod effects;
mod expressions;
mod files;
mod interchange;
mod joints;
