//! Reading a recording whatever its format: poses ([`read_recording`]: MCAP or a ROS 1 bag, told
//! by their first bytes whatever the name, a Motive CSV export, recognised by its `Format Version`
//! first line, or the plain CSV format) and joint logs with efforts ([`read_joint_log`]).

use crate::recording::error::{RecordingError, Result};
use crate::recording::mcap_io::McapOptions;
use crate::recording::tracks::Recording;
use std::path::Path;

/// Read `path`; `options` select MCAP topics (CSV files name their bodies in columns).
pub fn read_recording(path: &Path, options: &McapOptions) -> Result<Recording> {
    if !path.exists() {
        return Err(RecordingError::file(path, "no such file"));
    }
    if crate::recording::message_file::container(path)?.is_some() {
        return crate::recording::mcap_io::read(path, options);
    }
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    match ext.as_str() {
        "mcap" | "bag" => crate::recording::mcap_io::read(path, options),
        "csv" | "txt" => {
            let text = crate::recording::read_csv_text(path)?;
            let rec = if crate::recording::motive_csv::looks_like_motive(&text) { crate::recording::motive_csv::parse(&text, path)? } else { crate::recording::plain_csv::parse(&text, path)? };
            if let Some(t) = &options.joint_topic {
                if rec.joints.is_none() {
                    return Err(RecordingError::file(path, format!("joint states `{t}` asked for, but the file has no q1..qN columns")));
                }
            }
            Ok(rec)
        }
        _ => Err(RecordingError::file(path, format!("unknown recording format `.{ext}`; valid: .mcap, .bag (ROS 1), .csv (Motive export or plain)"))),
    }
}

/// Read arm `arm`'s joint log from `path` in `format` (`auto`: told from the file,
/// [`crate::recording::resolve_format`]) for `model`, as recorded: `wpi-csv` in its channels
/// (the tool's actuators, [`super::JointLog::to_joint`]) with its velocities and no setpoints;
/// `mcap` and `bag` in the model's joints, velocities where the messages carry them, setpoints
/// where the arm's topic has them; `csv` in the model's joints with its setpoint columns (the
/// encoders in their place, said in the notes, when it has none).
/// Each product takes what it needs from it (the discrepancy workflow and identification have
/// their `read_log`). With what the reader did (notes for the report).
pub fn read_joint_log(path: &Path, format: &str, model: &dvrk_kin::Model, arm: &str) -> Result<(super::JointLog, Vec<String>)> {
    read_joint_log_parts(path, format, model, arm, Parts::All)
}

/// Which parts of a joint log to read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Parts {
    /// Setpoints and measurements.
    All,
    /// The measurements alone: a fit of what was measured needs no setpoints, and on MCAP and
    /// bags they are a topic as large as the measurements (34 MB more at the peak of a 5-minute
    /// 1 kHz recording).
    Measured,
}

/// [`read_joint_log`], of `parts` only.
pub fn read_joint_log_parts(path: &Path, format: &str, model: &dvrk_kin::Model, arm: &str, parts: Parts) -> Result<(super::JointLog, Vec<String>)> {
    let resolved = super::format::resolve(path, format)?;
    let (mut log, mut notes) = match resolved {
        "mcap" | "bag" => super::joint_log_mcap::read(path, model, arm, parts == Parts::All)?,
        "wpi-csv" => super::wpi_csv::read_with_notes(path, model)?,
        _ => super::joint_log_csv::read(path, model).map(|c| (c.log, c.notes))?,
    };
    if parts == Parts::Measured {
        log.setpoint = Vec::new();
    }
    notes.splice(0..0, super::format::auto_note(path, format, resolved));
    Ok((log, notes))
}
