//! The joint log: one arm's recorded joints, with efforts, as every product reads it
//! (identification fits its channels, the discrepancy workflow analyses it in the model's joints,
//! `dvrk synth hidden-effect` writes it). [`crate::recording::read_joint_log`] reads it as
//! recorded, whatever the format (the WPI CSV `wpi_csv.rs`, the dVRK's topics in MCAP files and
//! ROS 1 bags `joint_log_mcap.rs`, the plain CSV layout `joint_log_csv.rs`); each product then
//! takes what it needs with the operations here.

use crate::recording::error::{RecordingError, Result};
use nalgebra::{DMatrix, DVector};

/// The note when the file has no setpoint columns.
pub const NO_SETPOINTS: &str = "no setpoint columns: the encoder positions stand in for the setpoints (the tracking channel then replays the recording's own motion)";

/// Setpoints and measurements of one arm's recorded channels, on one clock.
///
/// The channels are the model's joints unless [`JointLog::to_joint`] says otherwise (the WPI
/// recordings hold the tool's actuators); [`JointLog::in_joint_space`] takes such a log to the
/// joints.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct JointLog {
    /// Where it was read from (the file), for messages and reports; empty for a log made in
    /// memory.
    pub source: String,
    /// Channel names (the arm's joints, in the recording's order; `wrist_pitch actuator` for an
    /// actuator channel).
    pub names: Vec<String>,
    /// Sample times (s), strictly increasing.
    pub t: Vec<f64>,
    /// Commanded positions per sample (rad, m): the latest setpoint at or before each sample, a
    /// sample's list empty before the first one; no sample at all when the recording has none
    /// ([`JointLog::setpoints_or_encoders`]).
    pub setpoint: Vec<Vec<f64>>,
    /// Measured positions (encoders) per sample (rad, m).
    pub position: Vec<Vec<f64>>,
    /// Measured velocities per sample (rad/s, m/s), a sample's list empty where its message
    /// carried none ([`JointLog::fill_missing_velocities`]); no sample at all when not kept.
    pub velocity: Vec<Vec<f64>>,
    /// Measured efforts per sample (N·m, N); every sample's list empty for a recording of
    /// encoders alone ([`JointLog::has_efforts`]).
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
            to_joint.transpose().try_inverse().ok_or_else(|| RecordingError::data(&self.source, "the tool coupling is singular: actuator efforts cannot be taken to joint space"))?;
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

    /// [`JointLog::in_joint_space`], consuming the log: one already in the joints is returned
    /// as it is, not copied (a long recording's samples are held once).
    pub fn into_joint_space(self, model: &dvrk_kin::Model) -> Result<JointLog> {
        match self.to_joint {
            None => Ok(self),
            Some(_) => self.in_joint_space(model),
        }
    }

    /// Velocities by central differences of the positions for every sample whose message
    /// carried none (one-sided at the ends).
    pub fn fill_missing_velocities(&mut self) {
        let (m, n) = (self.len(), self.names.len());
        self.velocity.resize(m, Vec::new());
        for i in 0..m {
            if self.velocity[i].len() != n {
                let (a, b) = (i.saturating_sub(1), (i + 1).min(m - 1));
                self.velocity[i] = (0..n).map(|k| (self.position[b][k] - self.position[a][k]) / (self.t[b] - self.t[a])).collect();
            }
        }
    }

    /// A setpoint for every sample: the samples before the first setpoint are dropped; a
    /// recording without setpoints gets its encoder positions in their place, and the note
    /// saying so ([`NO_SETPOINTS`], after `path`).
    pub fn setpoints_or_encoders(&mut self, path: &std::path::Path) -> Option<String> {
        if self.setpoint.is_empty() {
            self.setpoint = self.position.clone();
            return Some(format!("{}: {}", path.display(), NO_SETPOINTS));
        }
        let first = self.setpoint.iter().position(|s| !s.is_empty()).unwrap_or(self.len());
        if first > 0 {
            let drop_front = |v: &mut Vec<Vec<f64>>| {
                if !v.is_empty() {
                    v.drain(..first);
                }
            };
            self.t.drain(..first);
            for v in [&mut self.setpoint, &mut self.position, &mut self.velocity, &mut self.effort] {
                drop_front(v);
            }
        }
        None
    }

    /// What `model`'s limits say of the measured positions (taken to the joints), after `path`;
    /// `None` when every sample is within them. Measured data past a limit is analysed as
    /// measured, and said.
    pub fn limits_note(&self, model: &dvrk_kin::Model, path: &std::path::Path) -> Option<String> {
        let summary = match &self.to_joint {
            None => dvrk_kin::LimitTally::of(model, &self.position).summary(model),
            Some(m) => dvrk_kin::LimitTally::of(model, self.position.iter().map(|q| m * DVector::from_column_slice(q))).summary(model),
        };
        summary.map(|s| format!("{}: {s}", path.display()))
    }
}
