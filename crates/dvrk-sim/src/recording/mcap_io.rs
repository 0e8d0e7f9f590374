//! MCAP recordings and ROS 1 bags: PoseStamped, TFMessage and JointState (ROS 2 `cdr` or ROS 1
//! serialization), and Foxglove PoseInFrame / FrameTransform(s) in JSON or protobuf; read into a
//! [`Recording`] (through [`crate::recording::message_file`]), and written by the synthetic tracker.

use crate::recording::error::{RecordingError, Result};
use crate::recording::foxglove::{self, FoxglovePose};
use crate::recording::message_file::{self, Encoding, Message};
use crate::recording::tracks::{BodyTrack, JointTrack, Recording};
use crate::recording::ros_msgs::{self, Header, JointState, PoseStamped, TransformStamped};
use crate::recording::mcap_out::{ros2_schema, sdk_schema, McapOut};
use dvrk_kin::Pose;
use nalgebra::{Translation3, UnitQuaternion};
use std::collections::BTreeMap;
use std::io::Cursor;
use std::path::Path;

/// Which topics to read.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct McapOptions {
    /// Pose topics to read (all supported ones when empty); each must exist.
    pub topics: Vec<String>,
    /// The JointState topic (the first one found when `None`).
    pub joint_topic: Option<String>,
}

/// What a channel carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    PoseStamped,
    Tf,
    JointState,
    FoxPose,
    FoxTransforms,
    /// The same three in protobuf: PoseInFrame, FrameTransform, FrameTransforms.
    ProtoPose,
    ProtoTransform,
    ProtoTransforms,
}

fn kind(schema: &str, encoding: Encoding) -> Option<Kind> {
    use Encoding::*;
    match (schema, encoding) {
        ("geometry_msgs/msg/PoseStamped", Cdr | Ros1) => Some(Kind::PoseStamped),
        ("tf2_msgs/msg/TFMessage", Cdr | Ros1) => Some(Kind::Tf),
        ("sensor_msgs/msg/JointState", Cdr | Ros1) => Some(Kind::JointState),
        ("foxglove.PoseInFrame", Json) => Some(Kind::FoxPose),
        ("foxglove.FrameTransform" | "foxglove.FrameTransforms", Json) => Some(Kind::FoxTransforms),
        ("foxglove.PoseInFrame", Protobuf) => Some(Kind::ProtoPose),
        ("foxglove.FrameTransform", Protobuf) => Some(Kind::ProtoTransform),
        ("foxglove.FrameTransforms", Protobuf) => Some(Kind::ProtoTransforms),
        _ => None,
    }
}

fn pose(position: [f64; 3], q: [f64; 4]) -> std::result::Result<Pose, String> {
    let u = crate::recording::plain_csv::unit_quaternion(q[0], q[1], q[2], q[3])?;
    if !position.iter().all(|x| x.is_finite()) {
        return Err(format!("position ({}, {}, {}) is not finite", position[0], position[1], position[2]));
    }
    Ok(Pose::from_parts(Translation3::new(position[0], position[1], position[2]), u.to_rotation_matrix()))
}

/// Read an MCAP file or a ROS 1 bag (told by its first bytes).
pub fn read(path: &Path, options: &McapOptions) -> Result<Recording> {
    let mut r = Reader::new(path, options);
    let count = message_file::for_each(path, |m| r.visit(m))?;
    r.finish(count)
}

/// Read MCAP bytes; `path` names them in errors.
pub fn parse(bytes: &[u8], path: &Path, options: &McapOptions) -> Result<Recording> {
    let mut r = Reader::new(path, options);
    let count = message_file::for_each_mcap(bytes, path, |m| r.visit(m))?;
    r.finish(count)
}

/// What [`read`] gathers message by message.
struct Reader<'a> {
    path: &'a Path,
    options: &'a McapOptions,
    bodies: BTreeMap<String, BodyTrack>,
    topics: BTreeMap<String, (String, Encoding)>,
    joints: BTreeMap<String, JointTrack>,
    bad: BTreeMap<String, usize>,
}

impl<'a> Reader<'a> {
    fn new(path: &'a Path, options: &'a McapOptions) -> Self {
        Reader { path, options, bodies: BTreeMap::new(), topics: BTreeMap::new(), joints: BTreeMap::new(), bad: BTreeMap::new() }
    }

    fn visit(&mut self, m: &Message) -> Result<()> {
        let (path, options) = (self.path, self.options);
        let bodies = &mut self.bodies;
        let joints = &mut self.joints;
        let bad = &mut self.bad;
        let wanted = |topic: &str| options.topics.is_empty() || options.topics.iter().any(|t| t == topic);
        let (count, schema) = (m.index, m.schema);
        let ch_topic = m.topic;
        self.topics.entry(ch_topic.to_string()).or_insert_with(|| (schema.to_string(), m.encoding));
        let Some(k) = kind(schema, m.encoding) else {
            return Ok(());
        };
        let ros1 = m.encoding == Encoding::Ros1;
        let log_time = m.log_time();
        let stamp = |h: f64| if h > 0.0 { h } else { log_time };
        let what = |e: String| format!("message {count} on {ch_topic} ({schema}): {e}");
        let mut add = |name: &str, frame: &str, t: f64, p: std::result::Result<Pose, String>| -> Result<()> {
            let tr = bodies.entry(name.to_string()).or_insert_with(|| BodyTrack::new(name, frame));
            match p {
                Ok(p) => {
                    tr.t.push(t);
                    tr.poses.push(p);
                }
                Err(e) if e.contains("not finite") || e.contains("NaN") => tr.occluded += 1,
                Err(e) => return Err(RecordingError::file(path, what(e))),
            }
            Ok(())
        };
        match k {
            Kind::JointState => {
                // The asked-for topic, and its tool's (the dVRK's `/PSM1/jaw/measured_js`).
                if options.joint_topic.as_ref().is_some_and(|t| t != ch_topic && !crate::recording::joint_states::is_tool_topic_of(t, ch_topic)) {
                    return Ok(());
                }
                let js = crate::recording::joint_states::decode_joint_state(m).map_err(|e| RecordingError::file(path, what(e)))?;
                let jt = joints.entry(ch_topic.to_string()).or_insert_with(|| JointTrack { source: ch_topic.to_string(), names: js.name.clone(), ..Default::default() });
                if js.position.len() != jt.names.len() || js.name != jt.names {
                    *bad.entry(ch_topic.to_string()).or_default() += 1;
                    return Ok(());
                }
                jt.t.push(stamp(js.header.time()));
                jt.q.push(js.position);
            }
            _ if !wanted(ch_topic) && !matches!(k, Kind::Tf | Kind::FoxTransforms | Kind::ProtoTransform | Kind::ProtoTransforms) => {}
            Kind::PoseStamped => {
                let p = if ros1 { PoseStamped::decode_ros1(m.data) } else { PoseStamped::decode(m.data) }.map_err(|e| RecordingError::file(path, what(e)))?;
                add(ch_topic, &p.header.frame_id, stamp(p.header.time()), pose(p.position, p.orientation))?;
            }
            Kind::FoxPose | Kind::ProtoPose => {
                let p = if k == Kind::FoxPose { foxglove::decode_pose_in_frame(m.data) } else { foxglove::decode_pose_in_frame_protobuf(m.data) };
                let p = p.map_err(|e| RecordingError::file(path, what(e)))?;
                add(ch_topic, &p.frame_id, stamp(p.time), pose(p.position, p.orientation))?;
            }
            Kind::Tf | Kind::FoxTransforms | Kind::ProtoTransform | Kind::ProtoTransforms => {
                let list: Vec<FoxglovePose> = match k {
                    Kind::Tf => (if ros1 { ros_msgs::decode_tf_ros1(m.data) } else { ros_msgs::decode_tf(m.data) })
                        .map_err(|e| RecordingError::file(path, what(e)))?
                        .into_iter()
                        .map(|t| FoxglovePose { time: t.header.time(), frame_id: t.header.frame_id, child_frame_id: t.child_frame_id, position: t.translation, orientation: t.rotation })
                        .collect(),
                    Kind::FoxTransforms => foxglove::decode_frame_transforms(m.data).map_err(|e| RecordingError::file(path, what(e)))?,
                    _ => foxglove::decode_frame_transforms_protobuf(m.data, k == Kind::ProtoTransforms).map_err(|e| RecordingError::file(path, what(e)))?,
                };
                for t in list {
                    // A TF child frame is a body; `--topic` may name it or the topic.
                    if wanted(&t.child_frame_id) || wanted(ch_topic) {
                        add(&t.child_frame_id, &t.frame_id, stamp(t.time), pose(t.position, t.orientation))?;
                    }
                }
            }
        }
        Ok(())
    }

    fn finish(self, count: usize) -> Result<Recording> {
        let Reader { path, options, bodies, topics, joints, bad } = self;
        let mut rec = Recording { source: path.display().to_string(), ..Default::default() };
        if count == 0 {
            return Err(RecordingError::file(path, "the file holds no message"));
        }
        let listing = || topics.iter().map(|(t, (s, e))| format!("{t} ({s}, {})", e.name())).collect::<Vec<_>>().join(", ");
        for t in &options.topics {
            if !bodies.contains_key(t) && !topics.contains_key(t) {
                return Err(RecordingError::file(path, format!("no topic or TF child frame `{t}`; topics: {}", listing())));
            }
            if topics.get(t).is_some_and(|(s, e)| kind(s, *e).is_none()) {
                let (s, e) = &topics[t];
                return Err(RecordingError::file(path, format!("topic `{t}` carries {s} ({}); supported: geometry_msgs/msg/PoseStamped, tf2_msgs/msg/TFMessage, sensor_msgs/msg/JointState (cdr or ros1), foxglove.PoseInFrame, foxglove.FrameTransform(s) (json or protobuf)", e.name())));
            }
        }
        if let Some(jt) = &options.joint_topic {
            if !joints.contains_key(jt) {
                return Err(RecordingError::file(path, format!("no JointState topic `{jt}`; topics: {}", listing())));
            }
        }
        let unsupported: Vec<String> = topics.iter().filter(|(_, (s, e))| kind(s, *e).is_none()).map(|(t, (s, _))| format!("{t} ({s})")).collect();
        if !unsupported.is_empty() {
            rec.warnings.push(format!("{}: skipped topic(s) of other types: {}", path.display(), unsupported.join(", ")));
        }
        for b in bodies.values().filter(|b| b.occluded > 0) {
            rec.warnings.push(format!("{}: {}: {} message(s) hold NaN; treated as occluded", path.display(), b.name, b.occluded));
        }
        for (t, n) in bad {
            rec.warnings.push(format!("{}: {n} JointState message(s) on {t} changed their joint names or sizes; skipped", path.display()));
        }
        rec.bodies = bodies
            .into_values()
            .map(|mut b| {
                b.sort_by_time();
                b
            })
            .collect();
        rec.joints = crate::recording::joint_states::arm_track(path, joints, &mut rec.warnings)?;
        Ok(rec)
    }
}

/// How the synthetic tracker lays out its MCAP.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum McapLayout {
    /// geometry_msgs/msg/PoseStamped on `/mocap/NAME/pose` (one topic per rigid body).
    #[default]
    PoseStamped,
    /// tf2_msgs/msg/TFMessage on `/tf`, one transform per visible body and frame.
    Tf,
    /// foxglove.PoseInFrame in JSON on `/mocap/NAME/pose`.
    FoxgloveJson,
    /// foxglove.PoseInFrame in protobuf (the Foxglove SDK's schema) on `/mocap/NAME/pose`.
    Foxglove,
}

/// The topic of a rigid body in [`McapLayout::PoseStamped`] and the Foxglove layouts.
pub fn pose_topic(body: &str) -> String {
    format!("/mocap/{body}/pose")
}

/// Write a recording (poses and joint states; raw markers have no message here) as MCAP.
/// `joint_topic` names the JointState topic (`/PSM1/measured_js`).
pub fn write(rec: &Recording, layout: McapLayout, joint_topic: &str) -> Result<Vec<u8>> {
    let io = |e: std::io::Error| RecordingError::data("MCAP writer", e.to_string());
    let mut w = McapOut::new(Cursor::new(Vec::new())).map_err(io)?;
    // Messages are written in time order across topics, as a recorder would.
    let mut events: Vec<(f64, usize, Vec<u8>)> = Vec::new();
    match layout {
        McapLayout::PoseStamped | McapLayout::FoxgloveJson | McapLayout::Foxglove => {
            let (schema, enc) = match layout {
                McapLayout::PoseStamped => {
                    let (n, t) = ros_msgs::pose_stamped_schema();
                    (ros2_schema(n, &t), "cdr".to_string())
                }
                McapLayout::Foxglove => sdk_schema::<::foxglove::messages::PoseInFrame>(),
                _ => (::foxglove::Schema::new("foxglove.PoseInFrame", "jsonschema", foxglove::POSE_IN_FRAME_SCHEMA.as_bytes().to_vec()), "json".to_string()),
            };
            for b in &rec.bodies {
                let ch = w.add_channel(&pose_topic(&b.name), schema.clone(), &enc).map_err(io)?;
                let frame = if b.frame_id.is_empty() { "tracker" } else { &b.frame_id };
                for (t, p) in b.t.iter().zip(&b.poses) {
                    let ps = PoseStamped::from_pose(*t, frame, p);
                    let fp = || FoxglovePose { time: *t, frame_id: frame.into(), child_frame_id: String::new(), position: ps.position, orientation: ps.orientation };
                    let bytes = match layout {
                        McapLayout::PoseStamped => ps.encode(),
                        McapLayout::Foxglove => foxglove::encode_pose_in_frame_protobuf(&fp()),
                        _ => foxglove::encode_pose_in_frame(&fp()),
                    };
                    events.push((*t, ch, bytes));
                }
            }
        }
        McapLayout::Tf => {
            let (n, t) = ros_msgs::tf_schema();
            let ch = w.add_channel("/tf", ros2_schema(n, &t), "cdr").map_err(io)?;
            let mut by_time: BTreeMap<u64, Vec<TransformStamped>> = BTreeMap::new();
            for b in &rec.bodies {
                let frame = if b.frame_id.is_empty() { "tracker" } else { &b.frame_id };
                for (t, p) in b.t.iter().zip(&b.poses) {
                    let q = UnitQuaternion::from_rotation_matrix(&p.rotation);
                    let v = p.translation.vector;
                    by_time.entry(t.to_bits()).or_default().push(TransformStamped {
                        header: Header::at(*t, frame),
                        child_frame_id: b.name.clone(),
                        translation: [v.x, v.y, v.z],
                        rotation: [q.i, q.j, q.k, q.w],
                    });
                }
            }
            for (t, list) in by_time {
                events.push((f64::from_bits(t), ch, ros_msgs::encode_tf(&list)));
            }
        }
    }
    if let Some(j) = &rec.joints {
        let (n, t) = ros_msgs::joint_state_schema();
        let ch = w.add_channel(joint_topic, ros2_schema(n, &t), "cdr").map_err(io)?;
        for (t, q) in j.t.iter().zip(&j.q) {
            let js = JointState { header: Header::at(*t, ""), name: j.names.clone(), position: q.clone(), ..Default::default() };
            events.push((*t, ch, js.encode()));
        }
    }
    events.sort_by(|a, b| a.0.total_cmp(&b.0));
    for (t, ch, data) in events {
        w.log(ch, (t.max(0.0) * 1e9).round() as u64, &data);
    }
    Ok(w.finish().map_err(io)?.into_inner())
}
