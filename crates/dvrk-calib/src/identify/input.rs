//! What identification reads: a joint log with measured efforts and velocities, in its recorded
//! channels ([`read_log`]).

use crate::error::{CalibError, Result};
use dvrk_sim::recording::{JointLog, Parts};
use dvrk_kin::Model;
use std::path::Path;

/// Fewest samples identification fits.
pub const MIN_SAMPLES: usize = 100;

/// Read the recording `path` in `format` (`auto`: told from the file, see
/// [`dvrk_sim::recording::resolve_format`]; `wpi-csv`, `mcap` or `bag`) for `model`, the arm `arm`
/// for MCAP and bags ([`dvrk_sim::recording::read_joint_log`]), as identification fits it: every
/// measured sample, with efforts, and velocities from the messages where they carry them, else by
/// central differences of the positions. With what the reader did (notes for the report).
pub fn read_log(path: &Path, format: &str, model: &Model, arm: &str) -> Result<(JointLog, Vec<String>)> {
    match dvrk_sim::recording::resolve_format(path, format)? {
        "wpi-csv" | "mcap" | "bag" => {}
        other => {
            return Err(CalibError::file(
                path,
                format!("identification reads wpi-csv, mcap and bag recordings, not {other}{}", if format == "auto" { " (told from the file; give --format)" } else { "" }),
            ))
        }
    }
    let (mut log, mut notes) = dvrk_sim::recording::read_joint_log_parts(path, format, model, arm, Parts::Measured)?;
    if !log.has_efforts() {
        return Err(CalibError::file(path, format!("/{arm}/measured_js carries no efforts: identification needs measured efforts")));
    }
    if log.len() < MIN_SAMPLES {
        return Err(CalibError::file(path, format!("{} samples; identification needs at least {MIN_SAMPLES}", log.len())));
    }
    log.fill_missing_velocities();
    // Measured data past the model's limits is fitted as measured, and said.
    notes.extend(log.limits_note(model, path));
    Ok((log, notes))
}
