//! `dvrk discrepancy` and `dvrk_twin.discrepancy` share this: read the recording in its format
//! ([`read_log`]), take the arm's built-in scene, run the repeated workflow.

use super::repeat::{discrepancy_repeated_prepared, discrepancy_repeated_with, prepare_rounds, Repeated};
use dvrk_sim::recording::JointLog;
use super::options::Options;
use crate::error::{CalibError, Result};
use dvrk_kin::Model;
use std::path::Path;

/// The kinematic channel's input: a pose topic and the link (frame name or paper number) its
/// marker is on.
#[derive(Debug, Clone, PartialEq)]
pub struct MarkerSource {
    pub topic: String,
    pub link: String,
}

/// Fewest samples with a setpoint the workflow reads.
pub const MIN_SAMPLES: usize = 100;

/// Read arm `arm`'s recording `path` in `format` (`auto`: told from the file, see
/// [`dvrk_sim::recording::resolve_format`]) for `model` ([`dvrk_sim::recording::read_joint_log`]), as
/// the workflow analyses it: in the model's joints (the WPI recordings' actuator channels taken
/// there), from the first setpoint on, the encoders standing in for the setpoints when the
/// recording has none; efforts as measured, or none at all (a recording of encoders alone, for the
/// kinematic channel); velocities not kept (the workflow differentiates the positions itself).
/// With what the reader did (notes for the report).
pub fn read_log(path: &Path, format: &str, model: &Model, arm: &str) -> Result<(JointLog, Vec<String>)> {
    let (mut log, mut notes) = dvrk_sim::recording::read_joint_log(path, format, model, arm)?;
    log.velocity = Vec::new();
    let mut log = log.into_joint_space(model)?;
    notes.extend(log.setpoints_or_encoders(path));
    if !log.has_efforts() {
        notes.push(format!("{}: /{arm}/measured_js carries no efforts: only the kinematic channel (a tracked marker) can be analysed", path.display()));
    }
    if log.len() < MIN_SAMPLES {
        return Err(CalibError::file(path, format!("{} samples with a setpoint (need at least {MIN_SAMPLES})", log.len())));
    }
    // Measured data past the model's limits is analysed as measured, and said.
    notes.extend(log.limits_note(model, path));
    Ok((log, notes))
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
        let frame = dvrk_sim::recording::marker_frame(model, &m.link)?;
        log.markers = Some(match dvrk_sim::recording::resolve_format(path, format)? {
            "mcap" | "bag" => dvrk_sim::recording::read_marker_mcap(path, &m.topic, frame)?,
            "csv" => dvrk_sim::recording::read_marker_csv(path, &m.topic, frame)?,
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
    let in_file = |e| CalibError::context(path.display().to_string(), e);
    // The torque channel alone reads the samples once, prepared: the recording's own (3 values
    // per joint and sample, 90 MB for 5 minutes at 1 kHz) are let go before the analysis.
    let mut out = match prepare_rounds(model, &log, options).map_err(in_file)? {
        Some(mut prep) if log.markers.is_none() && !options.tracking => {
            let names_only = JointLog { names: std::mem::take(&mut log.names), ..Default::default() };
            drop(log);
            discrepancy_repeated_prepared(model, &scene, arm, &names_only, &mut prep, options, max_rounds, progress)
        }
        Some(mut prep) => discrepancy_repeated_prepared(model, &scene, arm, &log, &mut prep, options, max_rounds, progress),
        None => discrepancy_repeated_with(model, &scene, arm, &log, options, max_rounds, progress),
    }
    .map_err(in_file)?;
    out.report.notes.splice(0..0, notes);
    Ok(out)
}
