//! The discrepancy workflow (issue 8): find where a model and a recording disagree, name the
//! physical effect the model lacks, with evidence, and close the gap.
//!
//! - [`generate`]: recordings with a hidden effect and their answers (`dvrk synth hidden-effect`),
//!   on an exciting multi-sine ([`excitation`]);
//! - [`read_log`]: setpoints, encoder positions and efforts read from a recording
//!   ([`dvrk_sim::recording::JointLog`], [`dvrk_sim::recording::read_joint_log`]);
//! - [`signals`]: filtering, the noise floor and the nominal model's effort;
//! - [`candidates`]: each candidate effect's signature from the model itself;
//! - [`stats`]: bounded fits, effective sample size, chi-square tails;
//! - [`workflow`]: the analysis top to bottom ([`discrepancy`]): the prediction (`baseline.rs`),
//!   the profiled effects (`profiles.rs`), the linear candidates, the verdict (`verdict.rs`), each
//!   effect's entry (`effect_report.rs`); [`report`] its JSON;
//! - [`tracking`]: the setpoints replayed through the simulator, before and after;
//! - [`plot`]: the residual before and after against time, velocity, load and position.
//!
//! Channels: torque (measured effort against inverse dynamics at the measured motion) carries
//! the evidence; tracking is replayed for the before/after gap; the kinematic channel (a tracker
//! on a link, [`kinematic`]) joins its evidence per candidate, and runs alone on a recording
//! without efforts ([`kinematic_only`]).

mod baseline;
pub mod candidate;
pub mod candidates;
pub mod consistency;
pub mod drive;
mod effect_report;
pub mod excitation;
mod explain;
pub mod fit;
pub mod friction_terms;
pub mod generate;
pub mod kinematic;
pub mod kinematic_only;
pub mod locate;
pub mod nuisance;
pub mod options;
pub mod payload;
pub mod payload_family;
pub mod plot;
mod profiles;
pub mod registration;
pub mod repeat;
pub mod report;
pub mod separation;
pub mod from_file;
mod scoring;
pub mod signals;
pub mod signature;
pub mod stats;
pub mod tracking;
mod verdict;
pub mod workflow;

pub use from_file::read_log;
pub use generate::{hidden_effect, Answer, Hidden, HiddenOptions, HiddenRecording};
pub use dvrk_sim::recording::JointLog;
pub use nuisance::InertiaPrior;
pub use plot::Residuals;
pub use repeat::{discrepancy_repeated, discrepancy_repeated_with, Repeated};
pub use report::Report;
pub use options::{Options, Outcome};
pub use workflow::discrepancy;

/// The built-in scene that carries arm `arm`'s inertials, drive and gains (`PSM1..3`: the psm
/// scene, `ECM`: the ecm scene), its arm renamed to `arm` (the recording's topic prefix).
pub fn scene_for_arm(arm: &str) -> crate::error::Result<dvrk_sim::Scene> {
    let name = if arm.starts_with("PSM") {
        "psm"
    } else if arm.starts_with("ECM") {
        "ecm"
    } else {
        return Err(crate::error::CalibError::field("arm", format!("`{arm}`: no built-in scene for it (PSM1..3, ECM)")));
    };
    let mut scene = dvrk_sim::Scene::load(name).map_err(|e| crate::error::CalibError::context("scene", e))?;
    scene.arms[0].name = arm.to_string();
    Ok(scene)
}
