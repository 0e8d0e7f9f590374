//! Joint states as recorded: every sensor_msgs JointState message of chosen topics (MCAP or ROS 1
//! bag), and an arm's joints in the dVRK's CRTK layout.
//!
//! The dVRK publishes a PSM's six arm joints on `/PSM1/measured_js` and its jaw on
//! `/PSM1/jaw/measured_js` (an MTM's gripper on `/MTML/gripper/measured_js`; the ECM has neither);
//! likewise `setpoint_js`. [`read_arm`] merges them by time stamp: the arm topic's stamps are the
//! samples, and the tool topic is interpolated linearly onto them, whatever its rate. A file that
//! carries all joints on one topic (as `dvrk sim --out` did before) is read as it is.
//!
//! Time: a message's header stamp, or its log time where the stamp is zero (counted in the
//! notes). Duplicated stamps keep the first message, out-of-order messages are sorted, and arm
//! samples that fall in a gap of the tool topic are dropped rather than bridged; each is counted
//! in [`ArmStates::notes`].

use crate::recording::error::{RecordingError, Result};
use crate::recording::message_file::{self, Encoding};
use std::collections::BTreeMap;
use std::path::Path;

/// The sub-topics (under `/ARM/`) on which the dVRK publishes a tool's joint: the PSM's jaw, the
/// MTM's gripper (named as the joint; `dvrk sim --out` writes them so).
pub const TOOL_TOPICS: [&str; 2] = crate::recording::writer::TOOL_JOINTS;

/// A JointState from `m`'s bytes in its wire encoding.
pub(crate) fn decode_joint_state(m: &message_file::Message) -> std::result::Result<crate::recording::ros_msgs::JointState, String> {
    if m.encoding == Encoding::Ros1 {
        crate::recording::ros_msgs::JointState::decode_ros1(m.data)
    } else {
        crate::recording::ros_msgs::JointState::decode(m.data)
    }
}

/// True when `topic` is a tool sub-topic of the arm topic `main` (`/PSM1/jaw/measured_js` of
/// `/PSM1/measured_js`).
pub fn is_tool_topic_of(main: &str, topic: &str) -> bool {
    main.rsplit_once('/').is_some_and(|(arm, kind)| TOOL_TOPICS.iter().any(|s| topic == format!("{arm}/{s}/{kind}")))
}

/// A gap in the tool topic longer than this many of its median periods is not bridged.
const GAP_PERIODS: f64 = 10.0;

/// The messages of one JointState topic, in time order.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct JointStates {
    /// Joint names (every message must carry the same).
    pub names: Vec<String>,
    /// Header stamps (the log time where a stamp is 0), s.
    pub t: Vec<f64>,
    /// Positions (rad, m).
    pub position: Vec<Vec<f64>>,
    /// Velocities (rad/s, m/s); empty per message when the message carries none.
    pub velocity: Vec<Vec<f64>>,
    /// Efforts (N·m, N); empty per message when the message carries none.
    pub effort: Vec<Vec<f64>>,
    /// Messages whose header stamp was zero (their log time was used).
    pub log_timed: usize,
}

impl JointStates {
    /// Messages.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// True without messages.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// Sort by time (stable) and drop messages whose stamp repeats the one before; returns how
    /// many were out of order and how many were dropped.
    fn order(&mut self) -> (usize, usize) {
        let unordered = self.t.windows(2).filter(|w| w[1] < w[0]).count();
        let mut idx: Vec<usize> = (0..self.len()).collect();
        if unordered > 0 {
            idx.sort_by(|a, b| self.t[*a].total_cmp(&self.t[*b]));
        }
        let mut keep: Vec<usize> = Vec::with_capacity(idx.len());
        for i in idx {
            if keep.last().is_none_or(|&k| self.t[i] > self.t[k]) {
                keep.push(i);
            }
        }
        let dropped = self.len() - keep.len();
        if unordered > 0 || dropped > 0 {
            let pick = |v: &Vec<Vec<f64>>| keep.iter().map(|&i| v[i].clone()).collect::<Vec<_>>();
            self.position = pick(&self.position);
            self.velocity = pick(&self.velocity);
            self.effort = pick(&self.effort);
            self.t = keep.iter().map(|&i| self.t[i]).collect();
        }
        (unordered, dropped)
    }

    /// Median time between messages (s); 0 with fewer than two.
    fn median_period(&self) -> f64 {
        let mut d: Vec<f64> = self.t.windows(2).map(|w| w[1] - w[0]).collect();
        if d.is_empty() {
            return 0.0;
        }
        let mid = d.len() / 2;
        *d.select_nth_unstable_by(mid, f64::total_cmp).1
    }
}

/// Every JointState message on the topics `wanted` of an MCAP file or ROS 1 bag, in file order
/// (see [`JointStates`]), and the names of all the file's topics (for messages). A wanted topic of
/// another type, a changing joint list or a damaged file is an error naming the file, topic and
/// message.
pub fn read_topics(path: &Path, wanted: &[&str]) -> Result<(BTreeMap<String, JointStates>, Vec<String>)> {
    let mut topics: BTreeMap<String, JointStates> = BTreeMap::new();
    let mut seen: Vec<String> = Vec::new();
    message_file::for_each(path, |m| {
        let topic = m.topic;
        if !seen.iter().any(|s| s == topic) {
            seen.push(topic.to_string());
        }
        if !wanted.contains(&topic) {
            return Ok(());
        }
        if m.schema != "sensor_msgs/msg/JointState" || !matches!(m.encoding, Encoding::Cdr | Encoding::Ros1) {
            // (The encoding too: a JointState in JSON read "carries JointState; expected JointState".)
            return Err(RecordingError::file(path, format!("topic {topic} carries {} ({}); expected sensor_msgs/msg/JointState (cdr or ros1)", m.schema, m.encoding.name())));
        }
        let js = decode_joint_state(m).map_err(|e| RecordingError::file(path, format!("message {} on {topic}: {e}", m.index)))?;
        let tp = topics.entry(topic.to_string()).or_default();
        if tp.names.is_empty() {
            tp.names = js.name.clone();
        }
        if js.name != tp.names || js.position.len() != tp.names.len() {
            return Err(RecordingError::file(path, format!("message {} on {topic}: joints {:?} ({} positions), earlier messages had {:?}", m.index, js.name, js.position.len(), tp.names)));
        }
        let stamp = js.header.time();
        if stamp > 0.0 {
            tp.t.push(stamp);
        } else {
            tp.t.push(m.log_time());
            tp.log_timed += 1;
        }
        tp.position.push(js.position);
        tp.velocity.push(js.velocity);
        tp.effort.push(js.effort);
        Ok(())
    })?;
    Ok((topics, seen))
}

/// An arm's joint states of several kinds, each merged from the CRTK topics.
#[derive(Debug, Clone, Default)]
pub struct ArmStates {
    /// Per kind (`measured_js`, `setpoint_js`) found: the merged states.
    pub kinds: BTreeMap<String, JointStates>,
    /// Per kind found: the topics it came from (`/PSM1/measured_js + /PSM1/jaw/measured_js`).
    pub sources: BTreeMap<String, String>,
    /// Every topic of the file.
    pub seen: Vec<String>,
    /// What the reader did that a user should know (time sources, sorting, gaps).
    pub notes: Vec<String>,
}

impl ArmStates {
    /// The topics of the file, for messages.
    pub fn listing(&self) -> String {
        self.seen.join(", ")
    }
}

/// The topics of `arm`'s joint states of kind `kind`: `/ARM/kind` and its tool sub-topics.
pub fn arm_topics(arm: &str, kind: &str) -> Vec<String> {
    std::iter::once(format!("/{arm}/{kind}")).chain(TOOL_TOPICS.iter().map(|s| format!("/{arm}/{s}/{kind}"))).collect()
}

/// Read `arm`'s joint states of each of `kinds` from `path` (MCAP or bag), the tool's sub-topic
/// merged into the arm's (see the module doc). A kind with no arm topic is absent from the
/// result; a tool topic without its arm topic is an error naming both.
pub fn read_arm(path: &Path, arm: &str, kinds: &[&str]) -> Result<ArmStates> {
    Ok(read_arms(path, &[arm], kinds)?.remove(arm).unwrap_or_default())
}

/// [`read_arm`] for several arms in one pass over the file.
pub fn read_arms(path: &Path, arms: &[&str], kinds: &[&str]) -> Result<BTreeMap<String, ArmStates>> {
    let wanted: Vec<String> = arms.iter().flat_map(|a| kinds.iter().flat_map(move |k| arm_topics(a, k))).collect();
    let (mut topics, seen) = read_topics(path, &wanted.iter().map(String::as_str).collect::<Vec<_>>())?;
    arms.iter().map(|arm| Ok((arm.to_string(), assemble(path, &mut topics, &seen, arm, kinds)?))).collect()
}

/// One arm's kinds out of the topics read.
fn assemble(path: &Path, topics: &mut BTreeMap<String, JointStates>, seen: &[String], arm: &str, kinds: &[&str]) -> Result<ArmStates> {
    let mut out = ArmStates { seen: seen.to_vec(), ..Default::default() };
    let where_ = path.display().to_string();
    for kind in kinds {
        let names = arm_topics(arm, kind);
        let (main, subs) = (names[0].clone(), &names[1..]);
        let tools: Vec<(String, JointStates)> = subs.iter().filter_map(|s| topics.remove(s).map(|js| (s.clone(), js))).collect();
        let Some(mut states) = topics.remove(&main) else {
            if let Some((t, _)) = tools.first() {
                return Err(RecordingError::file(path, format!("topic {t} is there but its arm topic {main} is not; topics: {}", out.listing())));
            }
            continue;
        };
        let mut source = main.clone();
        note_order(&mut out.notes, &where_, &main, &mut states);
        for (topic, mut tool) in tools {
            note_order(&mut out.notes, &where_, &topic, &mut tool);
            if let Some(dup) = tool.names.iter().find(|n| states.names.contains(n)) {
                return Err(RecordingError::file(path, format!("joint `{dup}` is on both {main} and {topic}")));
            }
            let dropped = merge(&mut states, &tool, path, &main, &topic)?;
            if dropped.0 + dropped.1 > 0 {
                out.notes.push(format!(
                    "{where_}: {} sample(s) of {main} outside the time span of {topic} and {} in its gaps (longer than {GAP_PERIODS} of its periods) were left out",
                    dropped.0, dropped.1
                ));
            }
            if (tool.median_period() - states.median_period()).abs() > 0.05 * states.median_period() {
                out.notes.push(format!(
                    "{where_}: {topic} ({:.1} Hz) was interpolated onto the times of {main} ({:.1} Hz)",
                    1.0 / tool.median_period().max(f64::MIN_POSITIVE),
                    1.0 / states.median_period().max(f64::MIN_POSITIVE)
                ));
            }
            source = format!("{source} + {topic}");
        }
        out.sources.insert(kind.to_string(), source);
        out.kinds.insert(kind.to_string(), states);
    }
    Ok(out)
}

/// The joint track a pose-and-joints recording offers (`mcap_io`'s [`crate::recording::tracks::Recording`]):
/// of the JointState topics read, an arm's `measured_js` first, then `setpoint_js`, then any
/// other; a tool sub-topic (`/ARM/jaw/...`) is never chosen alone but merged into its arm's.
pub fn arm_track(path: &Path, mut tracks: BTreeMap<String, crate::recording::tracks::JointTrack>, notes: &mut Vec<String>) -> Result<Option<crate::recording::tracks::JointTrack>> {
    let is_tool = |t: &str| TOOL_TOPICS.iter().any(|s| t.contains(&format!("/{s}/")));
    let rank = |t: &str| {
        if t.ends_with("/measured_js") {
            0
        } else if t.ends_with("/setpoint_js") {
            1
        } else {
            2
        }
    };
    let Some(main) = tracks.keys().filter(|t| !is_tool(t)).min_by_key(|t| rank(t)).cloned().or_else(|| tracks.keys().next().cloned()) else {
        return Ok(None);
    };
    let to_states = |j: crate::recording::tracks::JointTrack| JointStates { names: j.names, velocity: vec![Vec::new(); j.t.len()], effort: vec![Vec::new(); j.t.len()], t: j.t, position: j.q, log_timed: 0 };
    let Some(track) = tracks.remove(&main) else {
        return Ok(None);
    };
    let source = track.source.clone();
    let mut states = to_states(track);
    note_order(notes, &path.display().to_string(), &main, &mut states);
    let mut sources = vec![source];
    if let Some((arm, kind)) = main.strip_prefix('/').and_then(|m| m.split_once('/')) {
        for sub in TOOL_TOPICS {
            let topic = format!("/{arm}/{sub}/{kind}");
            if let Some(tool) = tracks.remove(&topic) {
                let mut tool = to_states(tool);
                note_order(notes, &path.display().to_string(), &topic, &mut tool);
                merge(&mut states, &tool, path, &main, &topic)?;
                sources.push(topic);
            }
        }
    }
    Ok(Some(crate::recording::tracks::JointTrack { source: sources.join(" + "), names: states.names, t: states.t, q: states.position, ..Default::default() }))
}

/// Order `js` in time and say what that took, and where its times came from.
fn note_order(notes: &mut Vec<String>, file: &str, topic: &str, js: &mut JointStates) {
    let (unordered, dropped) = js.order();
    if unordered > 0 {
        notes.push(format!("{file}: {topic}: {unordered} message(s) out of time order were sorted"));
    }
    if dropped > 0 {
        notes.push(format!("{file}: {topic}: {dropped} message(s) repeating the time stamp before them were dropped (the first was kept)"));
    }
    if js.log_timed > 0 {
        notes.push(format!("{file}: {topic}: {} of {} message(s) have no header stamp; their log time was used", js.log_timed, js.log_timed.max(js.len())));
    }
}

/// Interpolate `tool` onto `arm`'s times and append its joints; arm samples outside `tool`'s
/// span or in its long gaps are removed. Returns (outside, in gaps).
fn merge(arm: &mut JointStates, tool: &JointStates, path: &Path, arm_topic: &str, tool_topic: &str) -> Result<(usize, usize)> {
    if tool.is_empty() {
        return Err(RecordingError::file(path, format!("{tool_topic} holds no message")));
    }
    let max_gap = GAP_PERIODS * tool.median_period();
    let nt = tool.names.len();
    let (mut outside, mut gaps) = (0, 0);
    let mut keep = vec![false; arm.len()];
    let mut k = 0usize;
    for i in 0..arm.len() {
        let t = arm.t[i];
        if t < tool.t[0] || t > tool.t[tool.len() - 1] {
            outside += 1;
            continue;
        }
        while k + 1 < tool.len() && tool.t[k + 1] <= t {
            k += 1;
        }
        let (a, b) = (k, (k + 1).min(tool.len() - 1));
        // A sample on a tool message needs no bridge.
        if t > tool.t[a] && tool.t[b] - tool.t[a] > max_gap && tool.len() > 2 {
            gaps += 1;
            continue;
        }
        let w = if b > a { (t - tool.t[a]) / (tool.t[b] - tool.t[a]) } else { 0.0 };
        let lerp = |v: &Vec<Vec<f64>>| -> Option<Vec<f64>> { (v[a].len() == nt && v[b].len() == nt).then(|| (0..nt).map(|j| v[a][j] + w * (v[b][j] - v[a][j])).collect()) };
        let Some(q) = lerp(&tool.position) else {
            return Err(RecordingError::file(path, format!("{tool_topic} at t = {} s: {} positions for {nt} joints", tool.t[a], tool.position[a].len())));
        };
        arm.position[i].extend(q);
        // Velocities and efforts exist only where both topics carry them.
        for (mine, theirs) in [(&mut arm.velocity[i], &tool.velocity), (&mut arm.effort[i], &tool.effort)] {
            match lerp(theirs) {
                Some(v) if !mine.is_empty() => mine.extend(v),
                _ => mine.clear(),
            }
        }
        keep[i] = true;
    }
    let mut it = keep.iter();
    arm.t.retain(|_| *it.next().unwrap_or(&false));
    for v in [&mut arm.position, &mut arm.velocity, &mut arm.effort] {
        let mut it = keep.iter();
        v.retain(|_| *it.next().unwrap_or(&false));
    }
    arm.names.extend(tool.names.iter().cloned());
    if arm.is_empty() {
        return Err(RecordingError::file(path, format!("{arm_topic} and {tool_topic} do not overlap in time ({arm_topic}: {outside} message(s) outside {tool_topic}'s span)")));
    }
    Ok((outside, gaps))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn states(names: &[&str], t: &[f64], q: impl Fn(f64) -> Vec<f64>) -> JointStates {
        JointStates {
            names: names.iter().map(|s| s.to_string()).collect(),
            t: t.to_vec(),
            position: t.iter().map(|&t| q(t)).collect(),
            velocity: vec![Vec::new(); t.len()],
            effort: t.iter().map(|&t| q(t)).collect(),
            log_timed: 0,
        }
    }

    #[test]
    fn a_slower_jaw_is_interpolated_onto_the_arm_times() {
        let ta: Vec<f64> = (0..=100).map(|i| i as f64 * 0.01).collect();
        let tj: Vec<f64> = (0..=33).map(|i| 0.005 + i as f64 * 0.03).collect();
        let mut arm = states(&["a", "b"], &ta, |t| vec![t, 2.0 * t]);
        let jaw = states(&["jaw"], &tj, |t| vec![3.0 * t + 1.0]);
        let (outside, gaps) = merge(&mut arm, &jaw, Path::new("x.mcap"), "/A/measured_js", "/A/jaw/measured_js").unwrap();
        // 0.00 before the first jaw sample; 0.995 is the last jaw time: 0.99 in, 1.00 out.
        assert_eq!((outside, gaps), (2, 0));
        assert_eq!(arm.names, ["a", "b", "jaw"]);
        for (t, q) in arm.t.iter().zip(&arm.position) {
            assert!((q[2] - (3.0 * t + 1.0)).abs() < 1e-12, "{t} {q:?}");
        }
        assert_eq!(arm.effort[0].len(), 3);
        assert!(arm.velocity[0].is_empty());
    }

    #[test]
    fn gaps_are_not_bridged_and_disjoint_topics_are_named() {
        let ta: Vec<f64> = (0..100).map(|i| i as f64 * 0.01).collect();
        let tj: Vec<f64> = (0..100).map(|i| i as f64 * 0.01).filter(|t| !(0.3..0.6).contains(t)).collect();
        let mut arm = states(&["a"], &ta, |t| vec![t]);
        let jaw = states(&["jaw"], &tj, |t| vec![t]);
        let (_, gaps) = merge(&mut arm, &jaw, Path::new("x.mcap"), "/A/measured_js", "/A/jaw/measured_js").unwrap();
        assert_eq!(gaps, 30);
        let mut arm = states(&["a"], &ta, |t| vec![t]);
        let late = states(&["jaw"], &[5.0, 5.1], |t| vec![t]);
        let e = merge(&mut arm, &late, Path::new("x.mcap"), "/A/measured_js", "/A/jaw/measured_js").unwrap_err().to_string();
        assert!(e.contains("x.mcap") && e.contains("do not overlap in time"), "{e}");
    }

    #[test]
    fn tool_topics_belong_to_their_arm_topic() {
        assert!(is_tool_topic_of("/PSM1/measured_js", "/PSM1/jaw/measured_js"));
        assert!(is_tool_topic_of("/MTML/setpoint_js", "/MTML/gripper/setpoint_js"));
        assert!(!is_tool_topic_of("/PSM1/measured_js", "/PSM2/jaw/measured_js"));
        assert!(!is_tool_topic_of("/PSM1/measured_js", "/PSM1/jaw/setpoint_js"));
    }

    #[test]
    fn order_sorts_and_drops_repeated_stamps() {
        let mut js = states(&["a"], &[0.0, 0.02, 0.01, 0.02, 0.03], |t| vec![t]);
        assert_eq!(js.order(), (1, 1));
        assert_eq!(js.t, [0.0, 0.01, 0.02, 0.03]);
        assert_eq!(js.position[1], [0.01]);
    }
}
