//! `dvrk discrepancy` and `dvrk_twin.discrepancy` share this: read the recording in its format,
//! take the arm's built-in scene, run the repeated workflow.

use super::joint_log::{self, JointLog};
use super::repeat::{discrepancy_repeated, Repeated};
use super::workflow::Options;
use crate::error::{CalibError, Result};
use dvrk_kin::Model;
use std::path::Path;

/// The recording formats `dvrk discrepancy` reads.
pub const FORMATS: [&str; 2] = ["mcap", "wpi-csv"];

/// Read `path` in `format` for `model`'s arm `arm`.
pub fn read_log(path: &Path, format: &str, model: &Model, arm: &str) -> Result<JointLog> {
    match format {
        "mcap" => joint_log::read_mcap(path, arm),
        "wpi-csv" => joint_log::read_wpi_csv(path, model),
        "csv" => Err(CalibError::field("--format", "csv: not read by dvrk discrepancy yet (use mcap or wpi-csv)")),
        other => Err(CalibError::field("--format", format!("`{other}` is not a format; valid: {}", FORMATS.join(", ")))),
    }
}

/// The kinematic channel's input: a pose topic and the link (frame name or paper number) its
/// marker is on.
#[derive(Debug, Clone, PartialEq)]
pub struct MarkerSource {
    pub topic: String,
    pub link: String,
}

/// The repeated workflow on recording `path` of arm `arm` against `model`, with the tracked
/// marker `marker` if given.
pub fn run(path: &Path, format: &str, model: &Model, arm: &str, marker: Option<&MarkerSource>, options: &Options, max_rounds: usize) -> Result<Repeated> {
    let mut log = read_log(path, format, model, arm)?;
    if let Some(m) = marker {
        let frame = super::markers::marker_frame(model, &m.link)?;
        log.markers = Some(match format {
            "mcap" => super::markers::read_mcap(path, &m.topic, frame)?,
            other => return Err(CalibError::field("--marker-topic", format!("tracked poses are read from MCAP recordings; --format {other} has none"))),
        });
    }
    let scene = super::scene_for_arm(arm)?;
    discrepancy_repeated(model, &scene, arm, &log, options, max_rounds).map_err(|e| CalibError::data(path.display().to_string(), e.to_string()))
}
