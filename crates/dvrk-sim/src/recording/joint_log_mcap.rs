//! The joint log in MCAP files and ROS 1 bags, in the dVRK's CRTK layout: `/<arm>/measured_js`
//! and `/<arm>/setpoint_js` (sensor_msgs/JointState), the jaw or gripper on its own topic
//! (merged by [`crate::recording::read_arm`]) or every joint on one topic.

use super::JointLog;
use crate::recording::error::{RecordingError, Result};
use crate::recording::ros_msgs::{self, Header, JointState};
use dvrk_kin::Model;
use crate::recording::mcap_out::{ros2_schema, McapOut};
use std::io::Cursor;
use std::path::Path;

/// Write `log` as MCAP: `/<arm>/setpoint_js` (position) and `/<arm>/measured_js` (position,
/// effort), sensor_msgs/msg/JointState in CDR; and the tracker's poses, if any, as
/// geometry_msgs/msg/PoseStamped on their topic.
pub fn write_mcap(log: &JointLog, arm: &str) -> Result<Vec<u8>> {
    let io = |e: std::io::Error| RecordingError::data("MCAP writer", e.to_string());
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

/// Read arm `arm`'s joint log from an MCAP file or ROS 1 bag as recorded, in `model`'s joints
/// (matched by name: every model joint must be there; others are left out): every message of
/// `/<arm>/measured_js` with its efforts (none: every sample's list empty, a recording of
/// encoders alone) and its velocities where it carries them, and the latest `/<arm>/setpoint_js`
/// at or before each (none before the first; none at all without the topic, or when it lacks a
/// model joint: said in the notes; not read at all without `setpoints`). With what the reader did
/// (notes for the report); errors name the file, the topic and the message.
pub fn read(path: &Path, model: &Model, arm: &str, setpoints: bool) -> Result<(JointLog, Vec<String>)> {
    let (set_kind, meas_kind) = ("setpoint_js", "measured_js");
    let kinds: &[&str] = if setpoints { &[meas_kind, set_kind] } else { &[meas_kind] };
    let mut states = crate::recording::joint_states::read_arm(path, arm, kinds)?;
    let Some(mut meas) = states.kinds.remove(meas_kind) else {
        return Err(RecordingError::file(path, format!("no topic /{arm}/{meas_kind}; topics: {}", states.listing())));
    };
    let source = states.sources.remove(meas_kind).unwrap_or_else(|| format!("/{arm}/{meas_kind}"));
    let mut notes = std::mem::take(&mut states.notes);
    let joints: Vec<String> = model.joints.iter().map(|j| j.name.clone()).collect();
    let index_of = |names: &[String]| joints.iter().map(|j| names.iter().position(|x| x == j)).collect::<Option<Vec<usize>>>();
    let Some(index) = index_of(&meas.names) else {
        let missing = joints.iter().find(|j| !meas.names.contains(j)).map_or("", String::as_str);
        return Err(RecordingError::file(path, format!("{source} has no joint `{missing}` (joints: {})", meas.names.join(", "))));
    };
    let set = match states.kinds.remove(set_kind) {
        Some(set) => match index_of(&set.names) {
            Some(k) => Some((set, k)),
            None => {
                notes.push(format!("{}: /{arm}/{set_kind} joints {:?} are not the model's {:?}: its setpoints are not used", path.display(), set.names, joints));
                None
            }
        },
        None => None,
    };
    let (nq, nr) = (joints.len(), meas.names.len());
    // The recorded order is the model's (the dVRK's, and `dvrk sim --out`'s): samples are moved,
    // not copied, so a 5-minute recording is held once.
    let in_order = nr == nq && index.iter().enumerate().all(|(k, &i)| k == i);
    let pick = |v: &mut Vec<f64>| if in_order || v.is_empty() { std::mem::take(v) } else { index.iter().map(|&k| v[k]).collect() };
    let without_efforts = meas.effort.iter().all(Vec::is_empty);
    let mut log = JointLog { source: path.display().to_string(), names: joints.clone(), ..Default::default() };
    let m = meas.t.len();
    // Exactly `m` samples each: grown by doubling they held 18 MB more on a 5-minute recording.
    log.t = std::mem::take(&mut meas.t);
    log.t.shrink_to_fit();
    log.position.reserve_exact(m);
    log.effort.reserve_exact(m);
    log.velocity.reserve_exact(m);
    if set.is_some() {
        log.setpoint.reserve_exact(m);
    }
    let mut j = 0;
    for i in 0..m {
        let t = log.t[i];
        if !without_efforts && meas.effort[i].len() != nr {
            return Err(RecordingError::file(path, format!("{source} at t = {t} s: {} efforts for {nr} joints (a message carries an effort for every joint or none)", meas.effort[i].len())));
        }
        // Velocities are optional message by message (a jaw merged from its own topic has them
        // only where both topics do), but a message that carries some carries one per joint.
        let nv = meas.velocity[i].len();
        if nv != 0 && nv != nr {
            return Err(RecordingError::file(path, format!("{source} at t = {t} s: {nv} velocities for {nr} joints (a message carries a velocity for every joint or none)")));
        }
        let (q, tau, qd) = (pick(&mut meas.position[i]), pick(&mut meas.effort[i]), pick(&mut meas.velocity[i]));
        if let Some(x) = q.iter().chain(&tau).chain(&qd).find(|x| !x.is_finite()) {
            return Err(RecordingError::file(path, format!("{source} at t = {t} s: {x} is not finite")));
        }
        log.position.push(q);
        log.effort.push(tau);
        log.velocity.push(qd);
        if let Some((set, k)) = &set {
            while j + 1 < set.t.len() && set.t[j + 1] <= t + 1e-9 {
                j += 1;
            }
            let started = set.t.first().is_some_and(|t0| *t0 <= t + 1e-9);
            log.setpoint.push(if started { k.iter().map(|&c| set.position[j][c]).collect() } else { Vec::new() });
        }
    }
    Ok((log, notes))
}
