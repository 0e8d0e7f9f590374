//! A master's (MTM's) recorded hand motion, as teleoperation reads it: its tip pose, its gripper
//! and the clutch pedal, from an MCAP file or a ROS 1 bag in the dVRK's layout.
//!
//! - Pose: `/MTMR/measured_cp` (dVRK 2.x, CRTK: geometry_msgs PoseStamped, or TransformStamped
//!   as later releases publish it), or `/dvrk/MTMR/position_cartesian_current` (dVRK 1.x,
//!   PoseStamped). Each message is a sample.
//! - Gripper: `/MTMR/gripper/measured_js` (or 1.x `/dvrk/MTMR/state_gripper_current`),
//!   sensor_msgs JointState, `position[0]` in rad; interpolated onto the pose samples.
//! - Clutch: `/footpedals/clutch` (or 1.x `/dvrk/footpedals/clutch`), sensor_msgs Joy,
//!   `buttons[0]` 1 while pressed (0 released, 2 a click, which ends released); the pedal's state at
//!   a sample is that of its last message at or before it.
//!
//! Times are the recorder's log times, common to every topic (the header stamps of different
//! publishers need not share a clock), counted from the first pose. A missing gripper or clutch
//! topic is not an error: the jaw holds, or the pedal is taken as never pressed, and a note says so.

use crate::recording::error::{RecordingError, Result};
use crate::recording::message_file::{self, Encoding, Message};
use crate::recording::ros_msgs::{Joy, PoseStamped, TransformStamped};
use dvrk_kin::Pose;
use nalgebra::{Quaternion, Translation3, UnitQuaternion};
use std::collections::BTreeMap;
use std::path::Path;

/// Where each part of an MTM's motion was read from.
#[derive(Debug, Clone, PartialEq)]
pub struct MtmTopics {
    pub pose: String,
    pub gripper: Option<String>,
    pub clutch: Option<String>,
}

/// An MTM's recorded motion, one sample per pose message.
#[derive(Debug, Clone)]
pub struct MtmLog {
    /// The arm (`MTMR`).
    pub arm: String,
    pub topics: MtmTopics,
    /// The pose messages' frame (`frame_id` of the first; empty when unset).
    pub frame_id: String,
    /// Sample times (s from the first pose).
    pub t: Vec<f64>,
    /// The MTM tip's pose in `frame_id` (m).
    pub poses: Vec<Pose>,
    /// The gripper's opening at each sample (rad); `None` without a gripper topic.
    pub gripper: Option<Vec<f64>>,
    /// The clutch pedal at each sample (true: pressed).
    pub clutch: Vec<bool>,
    /// What a user should know about how it was read.
    pub notes: Vec<String>,
}

/// The pose topics of an arm, newest layout first.
fn pose_topics(arm: &str) -> [String; 2] {
    [format!("/{arm}/measured_cp"), format!("/dvrk/{arm}/position_cartesian_current")]
}

fn gripper_topics(arm: &str) -> [String; 2] {
    [format!("/{arm}/gripper/measured_js"), format!("/dvrk/{arm}/state_gripper_current")]
}

const CLUTCH_TOPICS: [&str; 2] = ["/footpedals/clutch", "/dvrk/footpedals/clutch"];

/// Whether `topic` carries some arm's gripper ([`gripper_topics`]' layouts, any arm).
fn is_gripper_topic(topic: &str) -> bool {
    topic.ends_with("/gripper/measured_js") || topic.ends_with("/state_gripper_current")
}

/// The arm whose pose a topic carries (`/MTMR/measured_cp` -> `MTMR`), for any arm name.
fn pose_topic_arm(topic: &str) -> Option<&str> {
    let t = topic.strip_prefix("/dvrk").unwrap_or(topic);
    let (arm, kind) = t.strip_prefix('/')?.split_once('/')?;
    (kind == "measured_cp" || kind == "position_cartesian_current").then_some(arm)
}

/// The messages kept on one pass: every pose-like topic (its arm is chosen after), every
/// gripper-like and clutch topic.
#[derive(Default)]
struct Collected {
    poses: BTreeMap<String, Vec<(f64, String, Pose, bool)>>,
    grippers: BTreeMap<String, Vec<(f64, f64)>>,
    clutch: BTreeMap<String, Vec<(f64, bool)>>,
    seen: Vec<String>,
    /// The first message of a topic that could not be read (wrong type, damaged), as an error
    /// raised only if the topic is one the chosen arm needs: another arm's odd topic is no fault.
    bad: BTreeMap<String, RecordingError>,
}

fn pose_of(path: &Path, m: &Message) -> Result<(String, Pose, bool)> {
    let bad = |e: String| RecordingError::file(path, format!("message {} on {}: {e}", m.index, m.topic));
    let ros1 = m.encoding == Encoding::Ros1;
    let (frame, p, q) = match m.schema {
        "geometry_msgs/msg/PoseStamped" => {
            let s = if ros1 { PoseStamped::decode_ros1(m.data) } else { PoseStamped::decode(m.data) }.map_err(bad)?;
            (s.header.frame_id, s.position, s.orientation)
        }
        "geometry_msgs/msg/TransformStamped" => {
            let s = if ros1 { TransformStamped::decode_ros1(m.data) } else { TransformStamped::decode(m.data) }.map_err(bad)?;
            (s.header.frame_id, s.translation, s.rotation)
        }
        other => {
            return Err(RecordingError::file(path, format!("{} carries {other} ({}); an MTM's pose is a geometry_msgs PoseStamped or TransformStamped", m.topic, m.encoding.name())));
        }
    };
    if !p.iter().chain(&q).all(|v| v.is_finite()) {
        return Err(bad("the pose has a value that is not a finite number".into()));
    }
    let norm = q.iter().map(|v| v * v).sum::<f64>().sqrt();
    if norm < 0.5 {
        return Err(bad(format!("the orientation's quaternion has norm {norm:.6}, not 1")));
    }
    let rotation = UnitQuaternion::from_quaternion(Quaternion::new(q[3], q[0], q[1], q[2])).to_rotation_matrix();
    Ok((frame, Pose::from_parts(Translation3::new(p[0], p[1], p[2]), rotation), (norm - 1.0).abs() > 1e-3))
}

fn collect(path: &Path) -> Result<Collected> {
    let mut c = Collected::default();
    message_file::for_each(path, |m| {
        if !c.seen.iter().any(|s| s == m.topic) {
            c.seen.push(m.topic.to_string());
        }
        if c.bad.contains_key(m.topic) {
            return Ok(());
        }
        if let Err(e) = keep(path, m, &mut c) {
            c.bad.insert(m.topic.to_string(), e);
        }
        Ok(())
    })?;
    Ok(c)
}

/// One message into `c` if its topic is one an MTM's motion uses.
fn keep(path: &Path, m: &Message, c: &mut Collected) -> Result<()> {
    let t = m.log_time();
    if !matches!(m.encoding, Encoding::Cdr | Encoding::Ros1) {
        if pose_topic_arm(m.topic).is_some() || CLUTCH_TOPICS.contains(&m.topic) || is_gripper_topic(m.topic) {
            return Err(RecordingError::file(path, format!("{} is in {} encoding; a ROS message (cdr or ros1) is read", m.topic, m.encoding.name())));
        }
        return Ok(());
    }
    if pose_topic_arm(m.topic).is_some() {
        let (frame, pose, renormalised) = pose_of(path, m)?;
        c.poses.entry(m.topic.to_string()).or_default().push((t, frame, pose, renormalised));
    } else if is_gripper_topic(m.topic) {
        if m.schema != "sensor_msgs/msg/JointState" {
            return Err(RecordingError::file(path, format!("{} carries {}; a gripper's state is a sensor_msgs JointState", m.topic, m.schema)));
        }
        let js = crate::recording::joint_states::decode_joint_state(m).map_err(|e| RecordingError::file(path, format!("message {} on {}: {e}", m.index, m.topic)))?;
        let Some(&g) = js.position.first() else {
            return Err(RecordingError::file(path, format!("message {} on {}: no position (the gripper's opening is position[0])", m.index, m.topic)));
        };
        if g.is_finite() {
            c.grippers.entry(m.topic.to_string()).or_default().push((t, g));
        }
    } else if CLUTCH_TOPICS.contains(&m.topic) {
        if m.schema != "sensor_msgs/msg/Joy" {
            return Err(RecordingError::file(path, format!("{} carries {}; the dVRK's pedals are sensor_msgs Joy", m.topic, m.schema)));
        }
        let joy = if m.encoding == Encoding::Ros1 { Joy::decode_ros1(m.data) } else { Joy::decode(m.data) }.map_err(|e| RecordingError::file(path, format!("message {} on {}: {e}", m.index, m.topic)))?;
        let Some(&b) = joy.buttons.first() else {
            return Err(RecordingError::file(path, format!("message {} on {}: no buttons (the pedal is buttons[0])", m.index, m.topic)));
        };
        c.clutch.entry(m.topic.to_string()).or_default().push((t, b == 1));
    }
    Ok(())
}

/// A short list of topics for a message.
fn listing(topics: &[String]) -> String {
    let shown: Vec<&str> = topics.iter().take(12).map(String::as_str).collect();
    let more = topics.len().saturating_sub(shown.len());
    if more > 0 {
        format!("{} and {more} more", shown.join(", "))
    } else if shown.is_empty() {
        "none".into()
    } else {
        shown.join(", ")
    }
}

/// Read the motion of MTM `arm` (or of the only MTM in the file when `None`) from `path` (MCAP
/// or ROS 1 bag). Errors are one line naming the file: no MTM pose topic (with the file's pose
/// topics, as when a PSM's recording is given), the asked arm absent (with the arms present),
/// two MTMs and no `arm`, a topic of the wrong type, a damaged message.
pub fn read_mtm(path: &Path, arm: Option<&str>) -> Result<MtmLog> {
    let mut c = collect(path)?;
    let mtm_arms: Vec<String> = {
        let mut a: Vec<String> = c.seen.iter().filter_map(|t| pose_topic_arm(t)).filter(|a| a.starts_with("MTM")).map(String::from).collect();
        a.sort();
        a.dedup();
        a
    };
    let pose_topics_seen: Vec<String> = c.seen.iter().filter(|t| pose_topic_arm(t).is_some()).cloned().collect();
    let arm = match arm {
        Some(a) => a.to_string(),
        None => match mtm_arms.as_slice() {
            [one] => one.clone(),
            [] => {
                return Err(RecordingError::file(path, format!(
                    "no MTM's pose (/MTML/measured_cp or /MTMR/measured_cp); its pose topics: {}; all topics: {}",
                    listing(&pose_topics_seen),
                    listing(&c.seen)
                )))
            }
            many => return Err(RecordingError::file(path, format!("it holds the poses of {}: choose one with --arm", many.join(" and ")))),
        },
    };
    // A needed topic that could not be read is the error, whoever else is in the file.
    let needed: Vec<String> = pose_topics(&arm).into_iter().chain(gripper_topics(&arm)).chain(CLUTCH_TOPICS.map(String::from)).collect();
    if let Some(e) = needed.iter().find_map(|t| c.bad.remove(t)) {
        return Err(e);
    }
    let Some((pose_topic, samples)) = pose_topics(&arm).into_iter().find_map(|t| c.poses.remove(&t).map(|s| (t, s))) else {
        let hint = if mtm_arms.is_empty() { String::new() } else { format!(" (--arm {}?)", mtm_arms.join(" or --arm ")) };
        return Err(RecordingError::file(path, format!("no pose of {arm} (/{arm}/measured_cp); its pose topics: {}{hint}", listing(&pose_topics_seen))));
    };
    let mut notes = Vec::new();
    // Log times in file order; sorted (stable) when the recorder wrote them out of order.
    let mut samples = samples;
    let unordered = samples.windows(2).filter(|w| w[1].0 < w[0].0).count();
    if unordered > 0 {
        samples.sort_by(|a, b| a.0.total_cmp(&b.0));
        notes.push(format!("{unordered} pose message(s) logged out of time order were sorted"));
    }
    let renormalised = samples.iter().filter(|s| s.3).count();
    if renormalised > 0 {
        notes.push(format!("{renormalised} pose message(s) had a quaternion of norm off 1 by more than 1e-3; normalised"));
    }
    let t0 = samples[0].0;
    let frame_id = samples[0].1.clone();
    let t: Vec<f64> = samples.iter().map(|s| s.0 - t0).collect();
    let poses: Vec<Pose> = samples.iter().map(|s| s.2).collect();

    let gripper_topic = gripper_topics(&arm).into_iter().find(|g| c.grippers.contains_key(g));
    let gripper = gripper_topic.as_ref().map(|g| {
        let mut series = c.grippers.remove(g).unwrap_or_default();
        series.sort_by(|a, b| a.0.total_cmp(&b.0));
        t.iter().map(|&ti| interpolate(&series, ti + t0)).collect::<Vec<f64>>()
    });
    if gripper_topic.is_none() {
        notes.push(format!("no gripper topic (/{arm}/gripper/measured_js): the jaw holds"));
    }
    let clutch_topic = CLUTCH_TOPICS.iter().find(|c2| c.clutch.contains_key(**c2)).map(|s| s.to_string());
    let clutch = match &clutch_topic {
        Some(ct) => {
            let mut events = c.clutch.remove(ct).unwrap_or_default();
            events.sort_by(|a, b| a.0.total_cmp(&b.0));
            t.iter()
                .map(|&ti| {
                    let k = events.partition_point(|e| e.0 <= ti + t0);
                    k > 0 && events[k - 1].1
                })
                .collect()
        }
        None => {
            notes.push("no clutch topic (/footpedals/clutch): the pedal is taken as never pressed".into());
            vec![false; t.len()]
        }
    };
    Ok(MtmLog { arm, topics: MtmTopics { pose: pose_topic, gripper: gripper_topic, clutch: clutch_topic }, frame_id, t, poses, gripper, clutch, notes })
}

/// `series` (time-sorted (s, value)) at `t`, linear between samples, held past either end.
fn interpolate(series: &[(f64, f64)], t: f64) -> f64 {
    let i = series.partition_point(|s| s.0 <= t);
    match i {
        0 => series[0].1,
        i if i == series.len() => series[i - 1].1,
        i => {
            let (a, b) = (series[i - 1], series[i]);
            a.1 + (b.1 - a.1) * (t - a.0) / (b.0 - a.0)
        }
    }
}

impl MtmLog {
    /// Samples.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// True without samples (never, once read).
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// Recorded duration (s).
    pub fn duration(&self) -> f64 {
        self.t.last().copied().unwrap_or(0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pose_topics_name_their_arm() {
        assert_eq!(pose_topic_arm("/MTMR/measured_cp"), Some("MTMR"));
        assert_eq!(pose_topic_arm("/dvrk/MTML/position_cartesian_current"), Some("MTML"));
        assert_eq!(pose_topic_arm("/PSM1/measured_cp"), Some("PSM1"));
        assert_eq!(pose_topic_arm("/MTMR/gripper/measured_js"), None);
        assert_eq!(pose_topic_arm("/MTMR/local/measured_cp"), None);
    }

    #[test]
    fn interpolation_holds_past_the_ends() {
        let s = [(1.0, 0.0), (2.0, 1.0)];
        assert_eq!(interpolate(&s, 0.0), 0.0);
        assert_eq!(interpolate(&s, 1.5), 0.5);
        assert_eq!(interpolate(&s, 3.0), 1.0);
    }
}
