//! `dvrk discrepancy` and `dvrk_twin.discrepancy` share this: read the recording in its format,
//! take the arm's built-in scene, run the repeated workflow.

use super::joint_log::{self, JointLog};
use super::repeat::{discrepancy_repeated_with, Repeated};
use super::options::Options;
use crate::error::{CalibError, Result};
use dvrk_kin::Model;
use std::path::Path;

/// Read `path` in `format` (`auto`: told from the file, [`crate::recording_format`]) for
/// `model`'s arm `arm`; with what the reader assumed (notes for the report).
pub fn read_log(path: &Path, format: &str, model: &Model, arm: &str) -> Result<(JointLog, Vec<String>)> {
    let resolved = crate::recording_format::resolve(path, format)?;
    let (log, mut notes) = match resolved {
        "mcap" | "bag" => joint_log::read_mcap(path, arm)?,
        "wpi-csv" => (joint_log::read_wpi_csv(path, model)?, vec![format!("{}: {}", path.display(), joint_log::NO_SETPOINTS)]),
        _ => super::csv_log::read(path, model).map(|c| (c.log, c.notes))?,
    };
    notes.splice(0..0, crate::recording_format::auto_note(path, format, resolved));
    // Measured data past the model's limits is analysed as measured, and said.
    notes.extend(dvrk_kin::LimitTally::of(model, &log.position).summary(model).map(|s| format!("{}: {s}", path.display())));
    Ok((log, notes))
}

/// The kinematic channel's input: a pose topic and the link (frame name or paper number) its
/// marker is on.
#[derive(Debug, Clone, PartialEq)]
pub struct MarkerSource {
    pub topic: String,
    pub link: String,
}

/// The repeated workflow on recording `path` of arm `arm` against `model`, with the tracked
/// marker `marker` if given; the reader's notes lead the report's.
pub fn run(path: &Path, format: &str, model: &Model, arm: &str, marker: Option<&MarkerSource>, options: &Options, max_rounds: usize) -> Result<Repeated> {
    run_with(path, format, model, arm, marker, options, max_rounds, &mut |_| {})
}

/// [`run`], telling `progress` what it is doing.
#[allow(clippy::too_many_arguments)]
pub fn run_with(path: &Path, format: &str, model: &Model, arm: &str, marker: Option<&MarkerSource>, options: &Options, max_rounds: usize, progress: &mut dyn FnMut(&str)) -> Result<Repeated> {
    progress("reading the recording");
    let (mut log, notes) = read_log(path, format, model, arm)?;
    if let Some(m) = marker {
        let frame = super::markers::marker_frame(model, &m.link)?;
        log.markers = Some(match crate::recording_format::resolve(path, format)? {
            "mcap" | "bag" => super::markers::read_mcap(path, &m.topic, frame)?,
            "csv" => super::csv_log::read_markers(path, &m.topic, frame)?,
            other => return Err(CalibError::field("--marker-topic", format!("tracked poses are read from MCAP, bag or CSV recordings; a {other} recording has none"))),
        });
    }
    if !log.has_efforts() && log.markers.is_none() {
        return Err(CalibError::file(
            path,
            format!("/{arm}/measured_js carries no efforts and no tracked marker was given (--marker-topic, --marker-link): the discrepancy workflow needs measured efforts (the torque channel) or a tracker's poses of a marker on a link (the kinematic channel)"),
        ));
    }
    let scene = super::scene_for_arm(arm)?;
    let mut out = discrepancy_repeated_with(model, &scene, arm, &log, options, max_rounds, progress).map_err(|e| CalibError::data(path.display().to_string(), e.to_string()))?;
    out.report.notes.splice(0..0, notes);
    Ok(out)
}
