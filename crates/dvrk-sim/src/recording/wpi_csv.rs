//! The WPI CSV joint log, read as recorded ([`super::JointLog`] in its channels, with velocities
//! and the map from the channels to the model's joints).
//!
//! `wpi-csv` (WPI-AIM/dvrk_dynamics_identification's `*_results.csv`): no header, 21 columns
//! q(7) qd(7) tau(7) at 200 Hz.
//! - A PSM's (a model with a tool): channels 5..7 (wrist pitch, wrist yaw, jaw) are the tool's
//!   *actuators* (the recording converted positions with M^-1 and efforts with M^T, M the tool's
//!   actuator-to-joint coupling), channels 1..4 are joints (yaw, pitch rad; insertion m; roll rad).
//! - An MTM's (a model with an arm coupling): every channel is the arm's *actuator* (rad, N·m):
//!   the elbow channel is the forearm's angle from the shoulder (joint 3 = a3 - a2) and the
//!   platform's is its motor (joint 4 = a4 + 0.6697 (a2 - a3)). Measured on WPI's MTM `one`
//!   and `two`: read so, a rigid body with friction predicts `two` better on every arm channel
//!   than read as joints (elbow 0.495 against 0.641 relative error, `docs/mtm.md`), and it is the
//!   WPI authors' own reading (their recording script writes motor coordinates; their DH takes
//!   q3 - q2 as the elbow angle).
//!
//! A row equal to the row before in all 21 columns is a repeated sample (the logger ran ahead
//! of the stream: 13% of WPI's MTM rows, none of the PSM's); it is filled by linear
//! interpolation between its measured neighbours, keeping the 200 Hz grid, and said.

use crate::recording::error::{RecordingError, Result};
use dvrk_kin::Model;
use nalgebra::DMatrix;
use super::JointLog;
use std::path::Path;

/// Sample rate of the wpi-csv recordings (Hz).
pub const WPI_RATE: f64 = 200.0;

/// Read a wpi-csv recording for `model` (a PSM with its tool coupling, or an MTM with its arm
/// coupling: 7 joints).
pub fn read(path: &Path, model: &Model) -> Result<JointLog> {
    Ok(read_with_notes(path, model)?.0)
}

/// [`read`], with what the reader did (repeated rows filled) as notes.
pub fn read_with_notes(path: &Path, model: &Model) -> Result<(JointLog, Vec<String>)> {
    let text = crate::recording::read_csv_text(path)?;
    parse_with_notes(&text, path, model)
}

/// Parse the text of a wpi-csv recording (see [`read`]).
pub fn parse(text: &str, path: &Path, model: &Model) -> Result<JointLog> {
    Ok(parse_with_notes(text, path, model)?.0)
}

/// The map from the recorded channels to `model`'s joints: a PSM's tool channels 5..7 are
/// actuators (the roll channel is the joint), an MTM's channels are all its actuators.
fn channel_map(path: &Path, model: &Model) -> Result<DMatrix<f64>> {
    let n = model.nq();
    if n != 7 {
        return Err(RecordingError::file(path, format!("wpi-csv holds a PSM's or an MTM's 7 joints; model `{}` has {n}", model.name)));
    }
    let coupling = model
        .coupling_matrix()
        .ok_or_else(|| RecordingError::file(path, format!("wpi-csv channels are actuators (a PSM's tool channels 5..7, an MTM's all), but model `{}` has no coupling", model.name)))?;
    if model.spec.tool.is_none() {
        return Ok(coupling);
    }
    // Only channels 5..7 were converted to actuators: the roll channel is the joint.
    let mut to_joint = coupling;
    for k in 0..n {
        to_joint[(3, k)] = if k == 3 { 1.0 } else { 0.0 };
        to_joint[(k, 3)] = if k == 3 { 1.0 } else { 0.0 };
    }
    Ok(to_joint)
}

/// [`parse`], with notes (see [`read_with_notes`]).
pub fn parse_with_notes(text: &str, path: &Path, model: &Model) -> Result<(JointLog, Vec<String>)> {
    let n = model.nq();
    let to_joint = channel_map(path, model)?;
    // A channel is a joint when the map leaves it alone (its row and column are the unit's).
    let is_joint = |k: usize| (0..n).all(|i| to_joint[(k, i)] == f64::from(u8::from(i == k)) && to_joint[(i, k)] == f64::from(u8::from(i == k)));
    let mut rec = JointLog {
        source: path.display().to_string(),
        names: model.joints.iter().enumerate().map(|(k, j)| if is_joint(k) { j.name.clone() } else { format!("{} actuator", j.name) }).collect(),
        to_joint: Some(to_joint.clone()),
        ..JointLog::default()
    };
    for (line, row) in text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty()) {
        let cells: Vec<&str> = row.split(',').collect();
        if cells.len() != 3 * n {
            return Err(RecordingError::file(path, format!("line {}: {} columns; wpi-csv has {} (q, qd, tau of {n} joints)", line + 1, cells.len(), 3 * n)));
        }
        let mut v = Vec::with_capacity(3 * n);
        for (c, cell) in cells.iter().enumerate() {
            v.push(super::finite_cell(path, line + 1, c + 1, cell.trim())?);
        }
        rec.t.push(rec.t.len() as f64 / WPI_RATE);
        rec.position.push(v[..n].to_vec());
        rec.velocity.push(v[n..2 * n].to_vec());
        rec.effort.push(v[2 * n..].to_vec());
    }
    if rec.len() < 100 {
        return Err(RecordingError::file(path, format!("{} samples; identification needs at least 100", rec.len())));
    }
    let mut notes = Vec::new();
    if model.spec.tool.is_none() {
        let actuators: Vec<&str> = rec.names.iter().filter(|c| c.ends_with(" actuator")).map(String::as_str).collect();
        notes.push(format!("wpi-csv for {}: every column is the arm's actuator, as the WPI recordings hold them ({} differ from the joints; read through the model's coupling)", model.name, actuators.join(", ")));
    }
    let repeated = fill_repeated_rows(&mut rec);
    if repeated > 0 {
        notes.push(format!(
            "{repeated} of {} rows ({:.1}%) repeat the row before in all {} columns (samples the logger took twice): filled by linear interpolation between their measured neighbours",
            rec.len(),
            100.0 * repeated as f64 / rec.len() as f64,
            3 * n
        ));
    }
    Ok((rec, notes))
}

/// In each of the three series (positions, velocities, efforts) on its own, replace each row
/// equal to its predecessor in every channel by the linear interpolation between the nearest
/// distinct rows before and after it (held at the end); the number of rows repeated in all three.
fn fill_repeated_rows(rec: &mut JointLog) -> usize {
    let n = rec.len();
    let whole = (1..n).filter(|&i| rec.position[i] == rec.position[i - 1] && rec.velocity[i] == rec.velocity[i - 1] && rec.effort[i] == rec.effort[i - 1]).count();
    for series in [&mut rec.position, &mut rec.velocity, &mut rec.effort] {
        let repeated: Vec<bool> = (0..n).map(|i| i > 0 && series[i] == series[i - 1]).collect();
        let mut i = 0;
        while i < n {
            if !repeated[i] {
                i += 1;
                continue;
            }
            // Rows i..end repeat row i - 1; row `end` (if any) is the next measured one.
            let end = (i..n).find(|&k| !repeated[k]).unwrap_or(n);
            if end < n {
                let (a, span) = (i - 1, (end - (i - 1)) as f64);
                for k in i..end {
                    let w = (k - a) as f64 / span;
                    series[k] = series[a].iter().zip(&series[end]).map(|(x, y)| x + w * (y - x)).collect();
                }
            }
            i = end;
        }
    }
    whole
}
