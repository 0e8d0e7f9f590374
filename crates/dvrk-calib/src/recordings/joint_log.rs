//! The joint log: one arm's recorded joints, with efforts, as every product reads it
//! (identification fits its channels, the discrepancy workflow analyses it in the model's joints,
//! `dvrk synth hidden-effect` writes it). The readers: the WPI CSV ([`super::torque_log`]), the
//! dVRK's topics in MCAP files and ROS 1 bags ([`read_mcap`] here; identification's own
//! measured-only reader in [`super::torque_log`]), the plain CSV layout ([`super::joint_log_csv`]).

use crate::error::{CalibError, Result};
use crate::ros_msgs::{self, Header, JointState};
use dvrk_sim::recording::mcap_out::{ros2_schema, McapOut};
use nalgebra::{DMatrix, DVector};
use std::io::Cursor;
use std::path::Path;

/// The note when the file has no setpoint columns.
pub const NO_SETPOINTS: &str = "no setpoint columns: the encoder positions stand in for the setpoints (the tracking channel then replays the recording's own motion)";

/// Setpoints and measurements of one arm's recorded channels, on one clock.
///
/// The channels are the model's joints unless [`JointLog::to_joint`] says otherwise (the WPI
/// recordings hold the tool's actuators); [`JointLog::in_joint_space`] takes such a log to the
/// joints.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct JointLog {
    /// Where it was read from (the file), for messages and reports: identification's readers
    /// ([`super::read_wpi_csv`], [`super::read_mcap_joint_states`]) set it; empty otherwise.
    pub source: String,
    /// Channel names (the arm's joints, in the recording's order; `wrist_pitch actuator` for an
    /// actuator channel).
    pub names: Vec<String>,
    /// Sample times (s), strictly increasing.
    pub t: Vec<f64>,
    /// Commanded positions per sample (rad, m).
    pub setpoint: Vec<Vec<f64>>,
    /// Measured positions (encoders) per sample (rad, m).
    pub position: Vec<Vec<f64>>,
    /// Measured velocities per sample (rad/s, m/s); empty when the reader kept none.
    pub velocity: Vec<Vec<f64>>,
    /// Measured efforts per sample (N·m, N).
    pub effort: Vec<Vec<f64>>,
    /// Model joints = `to_joint` * channels, for positions and velocities; channel efforts =
    /// `to_joint^T` * joint efforts (virtual work). `None`: the channels are the model's joints.
    pub to_joint: Option<DMatrix<f64>>,
    /// A tracker's poses of a marker on one link (the kinematic channel), when recorded.
    pub markers: Option<super::marker_log::MarkerLog>,
}

impl JointLog {
    /// Samples.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// True when there is no sample.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// Whether the recording measured efforts (every sample one per joint); a recording of
    /// encoders alone has none (every sample's list empty).
    pub fn has_efforts(&self) -> bool {
        !self.effort.is_empty() && self.effort.iter().all(|e| e.len() == self.names.len())
    }

    /// Mean sample period (s).
    pub fn period(&self) -> f64 {
        if self.t.len() < 2 {
            return 0.0;
        }
        (self.t[self.t.len() - 1] - self.t[0]) / (self.t.len() - 1) as f64
    }

    /// Mean sample rate (Hz) over the recording; `None` with fewer than two samples or a time
    /// span that is not positive.
    pub fn rate(&self) -> Option<f64> {
        let n = self.len();
        (n >= 2 && self.t[n - 1] > self.t[0]).then(|| (n - 1) as f64 / (self.t[n - 1] - self.t[0]))
    }

    /// The channel-to-joint map ([`JointLog::to_joint`]), the identity when the channels are the
    /// model's joints.
    pub fn joint_map(&self) -> DMatrix<f64> {
        self.to_joint.clone().unwrap_or_else(|| DMatrix::identity(self.names.len(), self.names.len()))
    }

    /// Samples `range` as a recording of its own (for cross-validation: choose settings on
    /// one half, judge them on the other).
    pub fn slice(&self, range: std::ops::Range<usize>) -> JointLog {
        let part = |v: &Vec<Vec<f64>>| if v.is_empty() { Vec::new() } else { v[range.clone()].to_vec() };
        JointLog {
            source: format!("{}[{}..{}]", self.source, range.start, range.end),
            names: self.names.clone(),
            t: self.t[range.clone()].to_vec(),
            setpoint: part(&self.setpoint),
            position: part(&self.position),
            velocity: part(&self.velocity),
            effort: part(&self.effort),
            to_joint: self.to_joint.clone(),
            markers: None,
        }
    }

    /// The log in `model`'s joints: positions, setpoints and velocities through `to_joint`,
    /// efforts through its transpose's inverse (virtual work); a log already in the joints as it
    /// is. An error naming [`JointLog::source`] if the map is singular.
    pub fn in_joint_space(&self, model: &dvrk_kin::Model) -> Result<JointLog> {
        let Some(to_joint) = &self.to_joint else { return Ok(self.clone()) };
        let effort_map =
            to_joint.transpose().try_inverse().ok_or_else(|| CalibError::data(&self.source, "the tool coupling is singular: actuator efforts cannot be taken to joint space"))?;
        let maps = |m: &DMatrix<f64>, rows: &[Vec<f64>]| -> Vec<Vec<f64>> { rows.iter().map(|v| if v.is_empty() { Vec::new() } else { (m * DVector::from_column_slice(v)).iter().copied().collect() }).collect() };
        Ok(JointLog {
            source: self.source.clone(),
            names: model.joints.iter().map(|j| j.name.clone()).collect(),
            t: self.t.clone(),
            setpoint: maps(to_joint, &self.setpoint),
            position: maps(to_joint, &self.position),
            velocity: maps(to_joint, &self.velocity),
            effort: maps(&effort_map, &self.effort),
            to_joint: None,
            markers: self.markers.clone(),
        })
    }
}

/// A wpi-csv recording (`dvrk identify`'s reader) as a joint log of `model`'s joints: the tool's
/// actuator channels taken to joint space (positions through `to_joint`, efforts through its
/// transpose's inverse, by virtual work). It has no setpoints: the encoders stand in for them
/// (the tracking channel then compares the replay with the recording itself).
pub fn read_wpi_csv(path: &Path, model: &dvrk_kin::Model) -> Result<JointLog> {
    let mut rec = super::torque_log::read_wpi_csv(path, model)?;
    // The discrepancy workflow differentiates the positions itself: the recorded velocities
    // are not taken along.
    rec.velocity = Vec::new();
    let mut log = rec.in_joint_space(model)?;
    log.setpoint = log.position.clone();
    Ok(log)
}

/// Write `log` as MCAP: `/<arm>/setpoint_js` (position) and `/<arm>/measured_js` (position,
/// effort), sensor_msgs/msg/JointState in CDR; and the tracker's poses, if any, as
/// geometry_msgs/msg/PoseStamped on their topic.
pub fn write_mcap(log: &JointLog, arm: &str) -> Result<Vec<u8>> {
    let io = |e: std::io::Error| CalibError::data("MCAP writer", e.to_string());
    let mut w = McapOut::new(Cursor::new(Vec::new())).map_err(io)?;
    let (n, s) = ros_msgs::joint_state_schema();
    let sp = w.add_channel(&format!("/{arm}/setpoint_js"), ros2_schema(n, &s), "cdr").map_err(io)?;
    let me = w.add_channel(&format!("/{arm}/measured_js"), ros2_schema(n, &s), "cdr").map_err(io)?;
    // The tracker's poses, interleaved in time order.
    let marker = match &log.markers {
        Some(m) => {
            let (n, s) = ros_msgs::pose_stamped_schema();
            Some((m, w.add_channel(&m.topic, ros2_schema(n, &s), "cdr").map_err(io)?))
        }
        None => None,
    };
    let ns = |t: f64| (t.max(0.0) * 1e9).round() as u64;
    let mut next_pose = 0;
    for (i, t) in log.t.iter().enumerate() {
        while let Some((m, ch)) = marker.filter(|(m, _)| next_pose < m.t.len() && m.t[next_pose] <= *t) {
            let tp = m.t[next_pose];
            w.log(ch, ns(tp), &ros_msgs::PoseStamped::from_pose(tp, "tracker", &m.poses[next_pose]).encode());
            next_pose += 1;
        }
        let set = JointState { header: Header::at(*t, ""), name: log.names.clone(), position: log.setpoint[i].clone(), ..Default::default() };
        let meas = JointState { header: Header::at(*t, ""), name: log.names.clone(), position: log.position[i].clone(), effort: log.effort[i].clone(), ..Default::default() };
        for (ch, js) in [(sp, set), (me, meas)] {
            w.log(ch, ns(*t), &js.encode());
        }
    }
    Ok(w.finish().map_err(io)?.into_inner())
}

/// Read an arm's setpoints and measurements (with efforts, or without any: then every sample's
/// list is empty, [`JointLog::has_efforts`]) from an MCAP file or ROS 1 bag, in
/// the dVRK's layout (`/<arm>/setpoint_js`, `/<arm>/measured_js`, the jaw or gripper on its own
/// topic, merged by [`crate::recordings::joint_states::read_arm`]) or with every joint on one topic. The
/// setpoints are matched to the measurements by time (the latest setpoint at or before each
/// measurement); without setpoints the encoders stand in for them (said in the notes). Errors
/// name the file, the topic and the message.
pub fn read_mcap(path: &Path, arm: &str) -> Result<(JointLog, Vec<String>)> {
    let (set_kind, meas_kind) = ("setpoint_js", "measured_js");
    let mut states = crate::recordings::joint_states::read_arm(path, arm, &[set_kind, meas_kind])?;
    let meas_topic = format!("/{arm}/{meas_kind}");
    let Some(mut meas) = states.kinds.remove(meas_kind) else {
        return Err(CalibError::file(path, format!("no topic {meas_topic}; topics: {}", states.listing())));
    };
    let mut notes = std::mem::take(&mut states.notes);
    let set = match states.kinds.remove(set_kind) {
        Some(set) if set.names != meas.names => {
            return Err(CalibError::file(path, format!("/{arm}/{set_kind} joints {:?} differ from {meas_topic} joints {:?}", set.names, meas.names)));
        }
        Some(set) => set,
        None => {
            notes.push(format!("{}: {}", path.display(), NO_SETPOINTS));
            meas.clone()
        }
    };
    let nq = meas.names.len();
    meas.velocity = Vec::new();
    let mut log = JointLog { names: std::mem::take(&mut meas.names), ..Default::default() };
    let mut j = 0;
    // Encoders alone (no message carries efforts): the kinematic channel can still run.
    let without_efforts = meas.effort.iter().all(Vec::is_empty);
    if without_efforts {
        notes.push(format!("{}: {meas_topic} carries no efforts: only the kinematic channel (a tracked marker) can be analysed", path.display()));
    }
    for (i, t) in meas.t.iter().enumerate() {
        if !without_efforts && meas.effort[i].len() != nq {
            return Err(CalibError::file(path, format!("{meas_topic} at t = {t} s: {} efforts for {nq} joints (the discrepancy workflow needs measured efforts)", meas.effort[i].len())));
        }
        if let Some(k) = meas.position[i].iter().chain(&meas.effort[i]).position(|x| !x.is_finite()) {
            return Err(CalibError::file(path, format!("{meas_topic} at t = {t} s: value {k} is not finite")));
        }
        while j + 1 < set.t.len() && set.t[j + 1] <= *t + 1e-9 {
            j += 1;
        }
        if set.t.first().is_none_or(|t0| *t0 > *t + 1e-9) {
            continue;
        }
        log.t.push(*t);
        log.setpoint.push(set.position[j].clone());
        // Moved, not copied: a 5-minute recording's samples are held once.
        log.position.push(std::mem::take(&mut meas.position[i]));
        log.effort.push(std::mem::take(&mut meas.effort[i]));
    }
    if log.len() < 100 {
        return Err(CalibError::file(path, format!("{} usable samples on {meas_topic} (need at least 100)", log.len())));
    }
    Ok((log, notes))
}
