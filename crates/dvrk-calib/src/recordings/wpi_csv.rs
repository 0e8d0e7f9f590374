//! The WPI CSV joint log, read as recorded ([`super::JointLog`] in its channels, with velocities
//! and the map from the channels to the model's joints).
//!
//! `wpi-csv` (WPI-AIM/dvrk_dynamics_identification's `*_results.csv`): no header, 21 columns
//! q(7) qd(7) tau(7) at 200 Hz; channels 5..7 (wrist pitch, wrist yaw, jaw) are the tool's
//! *actuators* (the recording converted positions with M^-1 and efforts with M^T, M the tool's
//! actuator-to-joint coupling), channels 1..4 are joints (yaw, pitch rad; insertion m; roll rad).

use crate::error::{CalibError, Result};
use dvrk_kin::Model;
use super::JointLog;
use std::path::Path;

/// Sample rate of the wpi-csv recordings (Hz).
pub const WPI_RATE: f64 = 200.0;

/// Read a wpi-csv recording for `model` (which must have 7 joints and a tool coupling).
pub fn read(path: &Path, model: &Model) -> Result<JointLog> {
    let text = crate::recordings::read_csv_text(path)?;
    parse(&text, path, model)
}

/// Parse the text of a wpi-csv recording (see [`read`]).
pub fn parse(text: &str, path: &Path, model: &Model) -> Result<JointLog> {
    let n = model.nq();
    if n != 7 {
        return Err(CalibError::file(path, format!("wpi-csv holds a PSM's 7 joints; model `{}` has {n}", model.name)));
    }
    let coupling = model.coupling_matrix().ok_or_else(|| CalibError::file(path, format!("wpi-csv channels 5..7 are tool actuators, but model `{}` has no tool coupling", model.name)))?;
    // Only channels 5..7 were converted to actuators: the roll channel is the joint.
    let mut to_joint = coupling;
    for k in 0..n {
        to_joint[(3, k)] = if k == 3 { 1.0 } else { 0.0 };
        to_joint[(k, 3)] = if k == 3 { 1.0 } else { 0.0 };
    }
    let mut rec = JointLog {
        source: path.display().to_string(),
        names: model.joints.iter().enumerate().map(|(k, j)| if k >= 4 { format!("{} actuator", j.name) } else { j.name.clone() }).collect(),
        to_joint: Some(to_joint),
        ..JointLog::default()
    };
    for (line, row) in text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty()) {
        let cells: Vec<&str> = row.split(',').collect();
        if cells.len() != 3 * n {
            return Err(CalibError::file(path, format!("line {}: {} columns; wpi-csv has {} (q, qd, tau of {n} joints)", line + 1, cells.len(), 3 * n)));
        }
        let mut v = Vec::with_capacity(3 * n);
        for (c, cell) in cells.iter().enumerate() {
            let x: f64 = cell.trim().parse().map_err(|_| CalibError::file(path, format!("line {}, column {}: `{}` is not a number", line + 1, c + 1, cell.trim())))?;
            if !x.is_finite() {
                return Err(CalibError::file(path, format!("line {}, column {}: {x} is not finite", line + 1, c + 1)));
            }
            v.push(x);
        }
        rec.t.push(rec.t.len() as f64 / WPI_RATE);
        rec.position.push(v[..n].to_vec());
        rec.velocity.push(v[n..2 * n].to_vec());
        rec.effort.push(v[2 * n..].to_vec());
    }
    if rec.len() < 100 {
        return Err(CalibError::file(path, format!("{} samples; identification needs at least 100", rec.len())));
    }
    Ok(rec)
}
