//! A joint log with efforts: what the discrepancy workflow reads from a recording (the arm's
//! `setpoint_js` and `measured_js`, positions and efforts), and what `dvrk synth hidden-effect`
//! writes. The MCAP reader of [`crate::mcap_io`] keeps positions only; this one keeps efforts.

use crate::error::{CalibError, Result};
use crate::ros_msgs::{self, Header, JointState};
use std::collections::BTreeMap;
use std::io::Cursor;
use std::path::Path;

/// Setpoints and measurements of one arm, on one clock.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct JointLog {
    /// Joint names (the arm's, in its order).
    pub names: Vec<String>,
    /// Sample times (s), strictly increasing.
    pub t: Vec<f64>,
    /// Commanded positions per sample (rad, m).
    pub setpoint: Vec<Vec<f64>>,
    /// Measured positions (encoders) per sample (rad, m).
    pub position: Vec<Vec<f64>>,
    /// Measured efforts per sample (N·m, N).
    pub effort: Vec<Vec<f64>>,
    /// A tracker's poses of a marker on one link (the kinematic channel), when recorded.
    pub markers: Option<super::markers::MarkerLog>,
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

    /// Mean sample period (s).
    pub fn period(&self) -> f64 {
        if self.t.len() < 2 {
            return 0.0;
        }
        (self.t[self.t.len() - 1] - self.t[0]) / (self.t.len() - 1) as f64
    }
}

/// A wpi-csv recording (`dvrk identify`'s reader) as a joint log of `model`'s joints: the tool's
/// actuator channels taken to joint space (positions through `to_joint`, efforts through its
/// transpose's inverse, by virtual work). It has no setpoints: the encoders stand in for them
/// (the tracking channel then compares the replay with the recording itself).
pub fn read_wpi_csv(path: &Path, model: &dvrk_kin::Model) -> Result<JointLog> {
    let rec = crate::identify::read_wpi_csv(path, model)?;
    let to_joint = &rec.to_joint;
    let effort_map = to_joint
        .transpose()
        .try_inverse()
        .ok_or_else(|| CalibError::data(path.display().to_string(), "the tool coupling is singular: actuator efforts cannot be taken to joint space"))?;
    let mut log = JointLog { names: model.joints.iter().map(|j| j.name.clone()).collect(), ..Default::default() };
    for i in 0..rec.len() {
        let q = to_joint * nalgebra::DVector::from_column_slice(&rec.q[i]);
        let tau = &effort_map * nalgebra::DVector::from_column_slice(&rec.tau[i]);
        log.t.push(rec.t[i]);
        log.position.push(q.iter().copied().collect());
        log.setpoint.push(q.iter().copied().collect());
        log.effort.push(tau.iter().copied().collect());
    }
    Ok(log)
}

/// Write `log` as MCAP: `/<arm>/setpoint_js` (position) and `/<arm>/measured_js` (position,
/// effort), sensor_msgs/msg/JointState in CDR; and the tracker's poses, if any, as
/// geometry_msgs/msg/PoseStamped on their topic.
pub fn write_mcap(log: &JointLog, arm: &str) -> Result<Vec<u8>> {
    let io = |e: mcap::McapError| CalibError::data("MCAP writer", e.to_string());
    let mut w = mcap::Writer::with_options(Cursor::new(Vec::new()), mcap::WriteOptions::new().profile("ros2")).map_err(io)?;
    let meta = BTreeMap::new();
    let (n, s) = ros_msgs::joint_state_schema();
    let sid = w.add_schema(n, "ros2msg", s.as_bytes()).map_err(io)?;
    let sp = w.add_channel(sid, &format!("/{arm}/setpoint_js"), "cdr", &meta).map_err(io)?;
    let me = w.add_channel(sid, &format!("/{arm}/measured_js"), "cdr", &meta).map_err(io)?;
    // The tracker's poses, interleaved in time order.
    let marker = match &log.markers {
        Some(m) => {
            let (n, s) = ros_msgs::pose_stamped_schema();
            let pid = w.add_schema(n, "ros2msg", s.as_bytes()).map_err(io)?;
            Some((m, w.add_channel(pid, &m.topic, "cdr", &meta).map_err(io)?))
        }
        None => None,
    };
    let mut next_pose = 0;
    for (i, t) in log.t.iter().enumerate() {
        while let Some((m, ch)) = marker.filter(|(m, _)| next_pose < m.t.len() && m.t[next_pose] <= *t) {
            let tp = m.t[next_pose];
            let msg = ros_msgs::PoseStamped::from_pose(tp, "tracker", &m.poses[next_pose]);
            let ns = (tp.max(0.0) * 1e9).round() as u64;
            w.write_to_known_channel(&mcap::records::MessageHeader { channel_id: ch, sequence: next_pose as u32 + 1, log_time: ns, publish_time: ns }, &msg.encode()).map_err(io)?;
            next_pose += 1;
        }
        let ns = (t.max(0.0) * 1e9).round() as u64;
        let seq = i as u32 + 1;
        let set = JointState { header: Header::at(*t, ""), name: log.names.clone(), position: log.setpoint[i].clone(), ..Default::default() };
        let meas = JointState { header: Header::at(*t, ""), name: log.names.clone(), position: log.position[i].clone(), effort: log.effort[i].clone(), ..Default::default() };
        for (ch, js) in [(sp, set), (me, meas)] {
            w.write_to_known_channel(&mcap::records::MessageHeader { channel_id: ch, sequence: seq, log_time: ns, publish_time: ns }, &js.encode()).map_err(io)?;
        }
    }
    w.finish().map_err(io)?;
    Ok(w.into_inner().into_inner())
}

/// The messages of one JointState topic, in file order.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct JointStates {
    /// Joint names (every message must carry the same).
    pub names: Vec<String>,
    /// Header stamps (the log time where a stamp is 0), s.
    pub t: Vec<f64>,
    pub position: Vec<Vec<f64>>,
    /// Empty per message when the message carries none.
    pub velocity: Vec<Vec<f64>>,
    pub effort: Vec<Vec<f64>>,
}

/// Every sensor_msgs/msg/JointState message on the topics `wanted` of an MCAP file, and the
/// names of all the file's topics (for messages). A wanted topic of another type, a changing
/// joint list or a damaged file is an error naming the file, topic and message.
pub fn read_joint_states(path: &Path, wanted: &[&str]) -> Result<(BTreeMap<String, JointStates>, Vec<String>)> {
    let bytes = std::fs::read(path).map_err(|e| CalibError::file(path, format!("cannot read: {e}")))?;
    let stream = mcap::MessageStream::new(&bytes).map_err(|e| CalibError::file(path, format!("not an MCAP file: {e}")))?;
    let mut topics: BTreeMap<String, JointStates> = BTreeMap::new();
    let mut seen: Vec<String> = Vec::new();
    for (count, m) in stream.enumerate() {
        let m = m.map_err(|e| match e {
            mcap::McapError::BadMagic if count == 0 => CalibError::file(path, "not an MCAP file (it does not start with the MCAP magic bytes)"),
            e => CalibError::file(path, format!("damaged after {count} message(s): {e}")),
        })?;
        let topic = &m.channel.topic;
        if !seen.contains(topic) {
            seen.push(topic.clone());
        }
        if !wanted.contains(&topic.as_str()) {
            continue;
        }
        let schema = m.channel.schema.as_ref().map_or("", |s| s.name.as_str());
        if schema != "sensor_msgs/msg/JointState" || m.channel.message_encoding != "cdr" {
            return Err(CalibError::file(path, format!("topic {topic} carries {schema} ({}); expected sensor_msgs/msg/JointState (cdr)", m.channel.message_encoding)));
        }
        let js = JointState::decode(&m.data).map_err(|e| CalibError::file(path, format!("message {} on {topic}: {e}", count + 1)))?;
        let tp = topics.entry(topic.clone()).or_default();
        if tp.names.is_empty() {
            tp.names = js.name.clone();
        }
        if js.name != tp.names || js.position.len() != tp.names.len() {
            return Err(CalibError::file(
                path,
                format!("message {} on {topic}: joints {:?} ({} positions), earlier messages had {:?}", count + 1, js.name, js.position.len(), tp.names),
            ));
        }
        let t = if js.header.time() > 0.0 { js.header.time() } else { m.log_time as f64 * 1e-9 };
        tp.t.push(t);
        tp.position.push(js.position);
        tp.velocity.push(js.velocity);
        tp.effort.push(js.effort);
    }
    Ok((topics, seen))
}

/// Read `/<arm>/setpoint_js` and `/<arm>/measured_js` (with efforts) from an MCAP file. The
/// setpoints are matched to the measurements by time (the latest setpoint at or before each
/// measurement). Errors name the file, the topic and the message.
pub fn read_mcap(path: &Path, arm: &str) -> Result<JointLog> {
    let (set_topic, meas_topic) = (format!("/{arm}/setpoint_js"), format!("/{arm}/measured_js"));
    let (mut topics, seen) = read_joint_states(path, &[&set_topic, &meas_topic])?;
    let Some(meas) = topics.remove(&meas_topic) else {
        return Err(CalibError::file(path, format!("no topic {meas_topic}; topics: {}", seen.join(", "))));
    };
    let Some(set) = topics.remove(&set_topic) else {
        return Err(CalibError::file(path, format!("no topic {set_topic}; topics: {}", seen.join(", "))));
    };
    if set.names != meas.names {
        return Err(CalibError::file(path, format!("{set_topic} joints {:?} differ from {meas_topic} joints {:?}", set.names, meas.names)));
    }
    let nq = meas.names.len();
    let mut log = JointLog { names: meas.names, ..Default::default() };
    let mut j = 0;
    for (i, t) in meas.t.iter().enumerate() {
        if meas.effort[i].len() != nq {
            return Err(CalibError::file(
                path,
                format!("{meas_topic} message {}: {} efforts for {nq} joints (the discrepancy workflow needs measured efforts)", i + 1, meas.effort[i].len()),
            ));
        }
        if let Some(k) = meas.position[i].iter().chain(&meas.effort[i]).position(|x| !x.is_finite()) {
            return Err(CalibError::file(path, format!("{meas_topic} message {} (t = {t} s): value {k} is not finite", i + 1)));
        }
        if i > 0 && *t <= meas.t[i - 1] {
            return Err(CalibError::file(path, format!("{meas_topic} message {}: time {t} s does not increase", i + 1)));
        }
        while j + 1 < set.t.len() && set.t[j + 1] <= *t + 1e-9 {
            j += 1;
        }
        if set.t.first().is_none_or(|t0| *t0 > *t + 1e-9) {
            continue;
        }
        log.t.push(*t);
        log.setpoint.push(set.position[j].clone());
        log.position.push(meas.position[i].clone());
        log.effort.push(meas.effort[i].clone());
    }
    if log.len() < 100 {
        return Err(CalibError::file(path, format!("{} usable samples on {meas_topic} (need at least 100)", log.len())));
    }
    Ok(log)
}
