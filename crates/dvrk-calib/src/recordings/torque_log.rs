//! Joint logs with efforts as identification reads them ([`super::JointLog`] in the recorded
//! channels, with velocities and the map from the channels to the model's joints).
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
pub fn read_wpi_csv(path: &Path, model: &Model) -> Result<JointLog> {
    let text = std::fs::read_to_string(path).map_err(|e| CalibError::file(path, format!("cannot read: {e}")))?;
    parse_wpi_csv(&text, path, model)
}

/// Parse the text of a wpi-csv recording (see [`read_wpi_csv`]).
pub fn parse_wpi_csv(text: &str, path: &Path, model: &Model) -> Result<JointLog> {
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

/// Read `/<arm>/measured_js` (sensor_msgs/JointState with efforts, as the dVRK and `dvrk sim
/// --out` record it) from an MCAP file or ROS 1 bag for `model`, with the jaw or gripper on its
/// own topic merged by time ([`crate::recordings::joint_states::read_arm`]) or on the same topic: joints
/// matched by name (every model joint must be there), velocities from the messages where they
/// carry them, else by central differences of the positions. The channels are the model's
/// joints. With what the reader did (notes for the report).
pub fn read_mcap_joint_states(path: &Path, model: &Model, arm: &str) -> Result<(JointLog, Vec<String>)> {
    let mut states = crate::recordings::joint_states::read_arm(path, arm, &["measured_js"])?;
    let topic = format!("/{arm}/measured_js");
    let Some(js) = states.kinds.remove("measured_js") else {
        return Err(CalibError::file(path, format!("no topic {topic}; topics: {}", states.listing())));
    };
    let source = states.sources.remove("measured_js").unwrap_or_else(|| topic.clone());
    let n = model.nq();
    let index: Vec<usize> = model
        .joints
        .iter()
        .map(|j| js.names.iter().position(|x| *x == j.name).ok_or_else(|| CalibError::file(path, format!("{source} has no joint `{}` (joints: {})", j.name, js.names.join(", ")))))
        .collect::<Result<_>>()?;
    let m = js.t.len();
    if m < 100 {
        return Err(CalibError::file(path, format!("{source}: {m} messages; identification needs at least 100")));
    }
    let mut rec = JointLog {
        source: path.display().to_string(),
        t: js.t.clone(),
        position: Vec::with_capacity(m),
        velocity: Vec::with_capacity(m),
        effort: Vec::with_capacity(m),
        names: model.joints.iter().map(|j| j.name.clone()).collect(),
        ..JointLog::default()
    };
    for i in 0..m {
        if js.effort[i].len() != js.names.len() {
            return Err(CalibError::file(path, format!("{source} at t = {} s: {} efforts for {} joints (identification needs measured efforts)", js.t[i], js.effort[i].len(), js.names.len())));
        }
        let pick = |v: &[f64]| index.iter().map(|&k| v[k]).collect::<Vec<f64>>();
        let (q, tau) = (pick(&js.position[i]), pick(&js.effort[i]));
        if let Some(x) = q.iter().chain(&tau).find(|x| !x.is_finite()) {
            return Err(CalibError::file(path, format!("{source} at t = {} s: {x} is not finite", js.t[i])));
        }
        rec.position.push(q);
        rec.effort.push(tau);
    }
    for i in 0..m {
        let qd = if js.velocity[i].len() == js.names.len() {
            index.iter().map(|&k| js.velocity[i][k]).collect()
        } else {
            let (a, b) = (i.saturating_sub(1), (i + 1).min(m - 1));
            (0..n).map(|k| (rec.position[b][k] - rec.position[a][k]) / (rec.t[b] - rec.t[a])).collect()
        };
        rec.velocity.push(qd);
    }
    Ok((rec, states.notes))
}

/// Read the recording `path` in `format` (`auto`: told from the file, see
/// [`crate::recordings::resolve_format`]; `wpi-csv`, `mcap` or `bag`) for `model`, the arm `arm` for
/// MCAP and bags; with what the reader did (notes for the report).
pub fn read_joint_recording(path: &Path, format: &str, model: &Model, arm: &str) -> Result<(JointLog, Vec<String>)> {
    let resolved = crate::recordings::format::resolve(path, format)?;
    let (rec, mut notes) = match resolved {
        "wpi-csv" => (read_wpi_csv(path, model)?, Vec::new()),
        "mcap" | "bag" => read_mcap_joint_states(path, model, arm)?,
        other => {
            return Err(CalibError::file(
                path,
                format!("identification reads wpi-csv, mcap and bag recordings, not {other}{}", if format == "auto" { " (told from the file; give --format)" } else { "" }),
            ))
        }
    };
    notes.splice(0..0, crate::recordings::format::auto_note(path, format, resolved));
    // Measured data past the model's limits is fitted as measured, and said.
    let to_joint = rec.joint_map();
    let joints = rec.position.iter().map(|q| &to_joint * nalgebra::DVector::from_column_slice(q));
    notes.extend(dvrk_kin::LimitTally::of(model, joints).summary(model).map(|s| format!("{}: {s}", path.display())));
    Ok((rec, notes))
}
