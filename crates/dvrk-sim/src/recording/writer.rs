//! The MCAP writer of a run, in the dVRK's CRTK layout. Per arm (`PSM1`; a SUJ arm `SUJ-PSM1`
//! publishes under `/SUJ/PSM1`):
//!
//! - `/PSM1/measured_js`, sensor_msgs/msg/JointState: the arm's joints (a PSM's six, without the
//!   jaw), measured position (rad, m), velocity (rad/s, m/s) and effort (N·m, N; the actuator's
//!   applied effort: the sim has no torque sensor);
//! - `/PSM1/setpoint_js`, sensor_msgs/msg/JointState: the actuator's target position, velocity
//!   feed-forward and applied effort;
//! - `/PSM1/jaw/measured_js` and `/PSM1/jaw/setpoint_js`: the same for the jaw (joint `jaw`), on
//!   its own topics as the dVRK publishes it (an arm without a jaw has none);
//! - `/PSM1/operating_state`, crtk_msgs/msg/OperatingState: `ENABLED`, homed, not busy, once at
//!   the first sample (the dVRK publishes it when it changes, and a simulated arm starts enabled);
//! - `/PSM1/measured_cp`, geometry_msgs/msg/PoseStamped: the tool tip (the model's `tip` frame)
//!   in the ECM's camera frame ([`VIEW_FRAME`]) where the scene has an ECM, as the dVRK reports
//!   a PSM with setup joints; else
//!   in the arm's base frame `PSM1_base`, which is the base of the arm's serial dVRK kinematics
//!   (the RCM frame of a PSM or ECM, as the dVRK reports it) or frame 0 for other models;
//! - `/PSM1/setpoint_cp`, the same type and frame: the tip at the actuators' targets (FK);
//!
//! and on `/tf` one foxglove.FrameTransforms (the SDK's protobuf) per sample, a transform per
//! body: `PSM1/yaw_link` in `world`; once, the link geometry on `/scene` (foxglove.SceneUpdate,
//! [`super::scene_msgs`]) and per arm `/PSM1/robot_description` (std_msgs/msg/String,
//! [`super::description`]).
//!
//! The same channels go to a live view when one is given ([`Recorder::open`], `crate::live`).
//!
//! With a camera ([`Recorder::add_camera`]), per eye at the camera's own rate: `/camera/left/image`
//! (foxglove.CompressedImage, PNG colour), `/camera/left/depth` (foxglove.CompressedImage, 16-bit
//! PNG depth in mm, ROS `16UC1`), `/camera/left/calibration` (foxglove.CameraCalibration), all in
//! the frame `camera_left`, whose pose in `world` goes on `/tf` with each frame; the same for `right`.
//! Samples are taken every `1 / (rate dt)` steps, a whole number or the rate is refused
//! ([`sample_stride`]). The file is written beside
//! its destination and renamed over it by [`Recorder::finish`], so a reader never sees half a file.

use crate::error::{Result, SimError};
use crate::geometry::{arm_color, ArmGeometry};
use crate::live::Live;
use crate::recording::mcap_out::{ros2_schema, sdk_schema, McapOut};
use foxglove::messages::{CameraCalibration, CompressedImage, FrameTransforms};
use foxglove::Schema;
use crate::camera::{Eye, StereoCamera};
use crate::recording::{camera_msgs, description, frame_transform, scene_msgs};
use crate::recording::ros_msgs::{self, Header, JointState, PoseStamped, TransformStamped};
use crate::ros2::{Ros2, TopicQos};
use crate::sim::Sim;
use dvrk_kin::atomic::Staged;
use dvrk_kin::Pose;
use nalgebra::{Point3, UnitQuaternion};
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

/// What to record.
#[derive(Debug, Clone)]
pub struct RecordOptions {
    /// Destination `.mcap` file.
    pub path: PathBuf,
    /// Samples per second of simulated time (Hz); rounded to a whole number of steps.
    pub rate: f64,
}

impl RecordOptions {
    /// The default rate (Hz).
    pub const DEFAULT_RATE: f64 = 100.0;
}

/// Where an arm's base frame is in the world: fixed, or fixed to a body of the arm carrying it.
#[derive(Debug, Clone)]
enum BaseRef {
    World(Pose),
    /// (arm, body, base pose in that body's frame)
    Body(usize, usize, Pose),
}

/// The joint names the dVRK publishes on a sub-topic of their own (`/PSM1/jaw/measured_js`).
pub const TOOL_JOINTS: [&str; 2] = ["jaw", "gripper"];

/// The topic namespace of an arm: `PSM1`, and `SUJ/PSM1` for the scene's arm `SUJ-PSM1`.
pub fn topic_namespace(arm: &str) -> String {
    arm.replace('-', "/")
}

/// An arm's joints grouped as the dVRK publishes them: `(prefix, model joint indices)`, the
/// arm's own joints under `PSM1` first, then each tool joint under `PSM1/jaw`.
pub fn joint_groups(arm: &str, model: &dvrk_kin::Model) -> Vec<(String, Vec<usize>)> {
    let ns = topic_namespace(arm);
    let is_tool = |k: &usize| TOOL_JOINTS.contains(&model.joints[*k].name.as_str());
    let mut groups = vec![(ns.clone(), (0..model.nq()).filter(|k| !is_tool(k)).collect())];
    groups.extend((0..model.nq()).filter(is_tool).map(|k| (format!("{ns}/{}", model.joints[k].name), vec![k])));
    groups
}

/// One JointState topic pair (measured, setpoint) and the model joints it carries.
#[derive(Debug, Clone)]
struct JointChannels {
    measured_js: usize,
    setpoint_js: usize,
    /// Model joint indices, in the message's order.
    joints: Vec<usize>,
    names: Vec<String>,
}

/// Channels and constant placements of one arm.
#[derive(Debug, Clone)]
struct ArmChannels {
    /// The arm's own joints first, then each tool joint's topics.
    topics: Vec<JointChannels>,
    measured_cp: usize,
    setpoint_cp: usize,
    measured_cv: usize,
    operating_state: usize,
    /// The CRTK contract's topics on ROS 2 alone (jhu-dvrk/dvrk_simulator_base): `state`
    /// (the state's name, an event like `operating_state`), `warning`, and for a PSM
    /// `tool_type` (latched) and `local/measured_cp`, `local/setpoint_cp` (its own base frame).
    contract: ContractChannels,
    /// What `operating_state` says now.
    state: ArmState,
    base_frame_id: String,
    base: BaseRef,
    /// The tip frame's body and its placement in that body.
    tip_body: usize,
    tip_rel: Pose,
    /// The CRTK base in the model's own placement ([`crtk_base`]), for `setpoint_cp`.
    base_in_model: Pose,
    /// The actuators' targets (scratch for `setpoint_cp`).
    targets: Vec<f64>,
    /// Kinematics workspace for the tip's Jacobian (`measured_cv`) and `setpoint_cp`.
    kin: dvrk_kin::Data,
    jacobian: nalgebra::Matrix6xX<f64>,
}

/// An arm's topics of the dVRK simulators' CRTK contract beyond what the file records.
#[derive(Debug, Clone)]
struct ContractChannels {
    state: usize,
    warning: usize,
    /// `tool_type` and its value (a PSM's).
    tool_type: Option<(usize, String)>,
    /// `local/measured_cp`, `local/setpoint_cp` (a PSM's).
    local: Option<(usize, usize)>,
}

/// Where the recorder's messages go: an MCAP file ([`McapOut`]), a live view ([`Live`]), a
/// ROS 2 domain ([`Ros2`]), any of them. Every channel is added to each, under one index of the
/// recorder's own.
struct Sinks {
    file: Option<McapOut<BufWriter<File>>>,
    live: Option<Live>,
    ros2: Option<Ros2>,
    /// Per recorder channel: its index in the file, the live view and ROS 2 (`None`: not there).
    channels: Vec<[Option<usize>; 3]>,
}

impl Sinks {
    /// Whether a message on recorder channel `channel` goes anywhere: always into a file and
    /// onto ROS 2 (when it carries the channel), live only while a client subscribes (a run
    /// that is only served encodes nothing unwatched).
    fn wanted(&self, channel: usize) -> bool {
        let [file, live, ros2] = self.channels[channel];
        (self.file.is_some() && file.is_some())
            || self.ros2.as_ref().zip(ros2).is_some_and(|(r, c)| r.carries(c))
            || self.live.as_ref().zip(live).is_some_and(|(l, c)| l.subscribed(c))
    }

    /// Send `data` to the live sinks only: the Foxglove view and ROS 2 (what a file holds once
    /// and a late subscriber needs again).
    fn log_live(&self, channel: usize, ns: u64, data: &[u8]) {
        let [_, live, ros2] = self.channels[channel];
        if let Some((l, c)) = self.live.as_ref().zip(live) {
            l.log(c, ns, data);
        }
        if let Some((r, c)) = self.ros2.as_ref().zip(ros2) {
            r.log(c, data);
        }
    }

    /// Send `data` to every sink.
    fn log(&self, channel: usize, ns: u64, data: &[u8]) {
        self.log_live(channel, ns, data);
        if let Some((f, c)) = self.file.as_ref().zip(self.channels[channel][0]) {
            f.log(c, ns, data);
        }
    }

    /// Add a channel to every sink (`ros2_only`: to ROS 2 alone, for what the file and the
    /// Foxglove view carry in Foxglove's own schema).
    fn add(&mut self, topic: &str, schema: &Schema, encoding: &str, ros2_only: bool) -> Result<usize> {
        self.add_qos(topic, schema, encoding, ros2_only, TopicQos::Stream)
    }

    /// [`Sinks::add`] with the topic's QoS on ROS 2.
    fn add_qos(&mut self, topic: &str, schema: &Schema, encoding: &str, ros2_only: bool, qos: TopicQos) -> Result<usize> {
        let file = match self.file.as_mut().filter(|_| !ros2_only) {
            Some(f) => Some(f.add_channel(topic, schema.clone(), encoding).map_err(|e| SimError::Build(format!("recording channel {topic}: {e}")))?),
            None => None,
        };
        let live = match self.live.as_mut().filter(|_| !ros2_only) {
            Some(l) => Some(l.add_channel(topic, schema.clone(), encoding)?),
            None => None,
        };
        let ros2 = match self.ros2.as_mut() {
            Some(r) => Some(r.add_channel_qos(topic, &schema.name, &schema.encoding, encoding, qos)?),
            None => None,
        };
        self.channels.push([file, live, ros2]);
        Ok(self.channels.len() - 1)
    }

    fn add_channel(&mut self, topic: &str, schema: &Schema, encoding: &str) -> Result<usize> {
        self.add(topic, schema, encoding, false)
    }
}

/// Writes a run as MCAP, serves it live, or both; see the module documentation for the topics.
pub struct Recorder {
    sinks: Sinks,
    /// The file being written (removed if the recorder is dropped unfinished).
    staged: Option<Staged>,
    tmp: PathBuf,
    path: PathBuf,
    /// Steps between samples.
    stride: u64,
    arms: Vec<ArmChannels>,
    tf: usize,
    /// Child frame name of every body, per arm.
    body_names: Vec<Vec<String>>,
    samples: u64,
    camera: Option<CameraChannels>,
    /// Messages that do not change (`/scene`, the robot descriptions) with their channels, and
    /// when they last went to the live view.
    statics: Vec<(usize, Vec<u8>)>,
    statics_sent: Option<std::time::Instant>,
    /// The `/tf` message's buffer, reused between samples.
    tf_buf: Vec<u8>,
    /// ROS 2's `/tf` (tf2_msgs/msg/TFMessage), when there is a ROS 2 sink.
    tf_ros2: Option<usize>,
    /// Added to simulated time in every stamp (s): 0 for a recording, the wall clock's start
    /// for a served twin ([`Recorder::set_stamp_origin`]).
    stamp_origin: f64,
    /// The scene's arm named `ECM`: its camera is the frame a PSM's `measured_cp` and
    /// `setpoint_cp` are reported in ([`VIEW_FRAME`]), as the dVRK does with setup joints.
    view_arm: Option<usize>,
}

/// The `frame_id` of a PSM's Cartesian reports in a scene with an ECM: the ECM's camera frame
/// (its tool tip, the dVRK's `ECM-SUJ * DH * tooltip-offset`), followed live.
pub const VIEW_FRAME: &str = "ECM_view";

/// An arm's CRTK operating state: `ENABLED` and homed, as a simulated arm starts.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ArmState {
    /// `ENABLED`, `DISABLED`, ...
    pub state: String,
    pub homed: bool,
    pub busy: bool,
}

impl Default for ArmState {
    fn default() -> Self {
        ArmState { state: "ENABLED".into(), homed: true, busy: false }
    }
}

impl ArmState {
    fn message(&self, t: f64) -> ros_msgs::OperatingState {
        ros_msgs::OperatingState { header: Header::at(t, ""), state: self.state.clone(), is_homed: self.homed, is_busy: self.busy }
    }
}

/// Channels of the camera: per eye (left, right) image, depth and calibration.
struct CameraChannels {
    image: [usize; 2],
    depth: [usize; 2],
    calibration: [usize; 2],
    /// Encoding buffers reused between frames.
    png: Vec<u8>,
    scratch: Vec<u8>,
    message: Vec<u8>,
}

/// A message stamp: simulated time `t` (s) in ns.
fn stamp_ns(t: f64) -> u64 {
    (t.max(0.0) * 1e9).round() as u64
}

fn io_error(path: &Path, e: std::io::Error) -> SimError {
    SimError::Io { path: path.display().to_string(), source: e }
}

/// Steps of `dt` seconds between two samples at `rate_hz`: the rate must be one sample every
/// whole number of steps (1e-6 relative), so that what a client receives is what it asked for.
/// Anything else is refused with the two rates on either side (`what` names the option).
pub fn sample_stride(what: &str, rate_hz: f64, dt: f64) -> Result<u64> {
    // Rates as a user reads them: to 1 mHz (1 / 0.001 s is 1000, not 1000.0000000000001).
    let hz = |x: f64| dvrk_kin::fmt_number((x * 1e3).round() / 1e3);
    let top = 1.0 / dt;
    if !(rate_hz.is_finite() && rate_hz > 0.0 && rate_hz <= top * (1.0 + 1e-9)) {
        return Err(SimError::value(what, rate_hz, format!("must be in (0, {}] (one sample per step of {} s at most)", hz(top), dvrk_kin::fmt_number(dt))));
    }
    let steps = top / rate_hz;
    let stride = steps.round().max(1.0);
    if (steps - stride).abs() > 1e-6 * steps {
        let near = |k: f64| if k == 1.0 { format!("{} Hz (every step)", hz(top)) } else { format!("{} Hz (every {k} steps)", hz(top / k)) };
        return Err(SimError::value(what, rate_hz, format!("not one sample every whole number of {} s steps; the rates on either side are {} and {}", dvrk_kin::fmt_number(dt), near(steps.floor().max(1.0)), near(steps.ceil()))));
    }
    Ok(stride as u64)
}

impl Recorder {
    /// Open a recording of `sim` (channels for each of its arms). Nothing appears at `options.path`
    /// until [`Recorder::finish`].
    pub fn create(sim: &Sim, options: &RecordOptions) -> Result<Recorder> {
        Self::open(sim, Some(options), None, options.rate)
    }

    /// Record `sim` to the file `file` asks for, serve it on `live`, or both, sampled at `rate`
    /// (Hz of simulated time). Nothing appears at the file's path until [`Recorder::finish`].
    pub fn open(sim: &Sim, file: Option<&RecordOptions>, live: Option<Live>, rate: f64) -> Result<Recorder> {
        Self::open_with(sim, file, live, None, rate)
    }

    /// [`Recorder::open`] with a ROS 2 domain too ([`Ros2`]): it gets the CRTK topics and, on
    /// `/tf`, a tf2_msgs/msg/TFMessage of every body.
    pub fn open_with(sim: &Sim, file: Option<&RecordOptions>, live: Option<Live>, ros2: Option<Ros2>, rate: f64) -> Result<Recorder> {
        let stride = sample_stride("recording rate (Hz)", rate, sim.dt)?;
        let (staged, path, tmp, writer) = match file {
            Some(options) => {
                let path = options.path.clone();
                dvrk_kin::atomic::check_outputs(&[], &[("recording", &path)]).map_err(|e| SimError::Io { path: path.display().to_string(), source: std::io::Error::other(e.to_string()) })?;
                let (staged, file) = Staged::create(&path).map_err(|e| SimError::Io { path: path.display().to_string(), source: std::io::Error::other(e.to_string()) })?;
                let tmp = staged.temp().to_path_buf();
                let w = McapOut::new(BufWriter::new(file)).map_err(|e| io_error(&tmp, e))?;
                (Some(staged), path, tmp, Some(w))
            }
            None => {
                let url = match (live.as_ref(), ros2.as_ref()) {
                    (Some(l), _) => l.url(),
                    (None, Some(r)) => format!("ROS 2 domain {}", r.domain()),
                    (None, None) => String::new(),
                };
                let url = PathBuf::from(url);
                (None, url.clone(), url, None)
            }
        };
        let mut w = Sinks { file: writer, live, ros2, channels: Vec::new() };
        let ros2 = |(name, text): (&str, String)| ros2_schema(name, &text);
        let js_schema = ros2(ros_msgs::joint_state_schema());
        let cp_schema = ros2(ros_msgs::pose_stamped_schema());
        let state_schema = ros2(ros_msgs::operating_state_schema());
        let cv_schema = ros2(ros_msgs::twist_stamped_schema());
        let (tf_schema, tf_encoding) = sdk_schema::<FrameTransforms>();
        let tf = w.add_channel("/tf", &tf_schema, &tf_encoding)?;
        let tf_ros2 = match w.ros2.is_some() {
            true => Some(w.add("/tf", &ros2(ros_msgs::tf_schema()), "cdr", true)?),
            false => None,
        };
        let mut arms = Vec::with_capacity(sim.arms.len());
        let mut body_names = Vec::with_capacity(sim.arms.len());
        for arm in &sim.arms {
            let ns = topic_namespace(&arm.name);
            let m = &arm.model;
            let base_world = crtk_base(m);
            let base = match arm.parent {
                None => BaseRef::World(base_world),
                Some((pa, pf)) => {
                    let body = sim.arms[pa].model.frames[pf].body;
                    BaseRef::Body(pa, body, sim.body_pose(pa, body).inverse() * base_world)
                }
            };
            let fk = m.fk(&m.home())?;
            let tip_body = m.frames[m.tip].body;
            let tip_rel = fk[m.bodies[tip_body].frames[0]].inverse() * fk[m.tip];
            let groups = joint_groups(&arm.name, m);
            let mut topics = Vec::with_capacity(groups.len());
            for (prefix, joints) in groups {
                topics.push(JointChannels {
                    measured_js: w.add_channel(&format!("/{prefix}/measured_js"), &js_schema, "cdr")?,
                    setpoint_js: w.add_channel(&format!("/{prefix}/setpoint_js"), &js_schema, "cdr")?,
                    names: joints.iter().map(|k| m.joints[*k].name.clone()).collect(),
                    joints,
                });
            }
            let string_stamped = ros2(ros_msgs::string_stamped_schema());
            let is_psm = m.joints.iter().any(|j| j.name == "jaw");
            let state = w.add_qos(&format!("/{ns}/state"), &string_stamped, "cdr", true, TopicQos::Event)?;
            let warning = w.add_qos(&format!("/{ns}/warning"), &string_stamped, "cdr", true, TopicQos::Warning)?;
            // Exposed as the contract has them; nothing is said on them yet (as its reference).
            w.add_qos(&format!("/{ns}/info"), &string_stamped, "cdr", true, TopicQos::Warning)?;
            w.add_qos(&format!("/{ns}/error"), &string_stamped, "cdr", true, TopicQos::Warning)?;
            let tool_type = match is_psm {
                true => {
                    let name = m.spec.tool.as_ref().map_or(String::new(), |t| t.name.clone());
                    Some((w.add_qos(&format!("/{ns}/tool_type"), &ros2(ros_msgs::string_schema()), "cdr", true, TopicQos::Latched)?, name))
                }
                false => None,
            };
            let local = match is_psm {
                true => Some((w.add(&format!("/{ns}/local/measured_cp"), &cp_schema, "cdr", true)?, w.add(&format!("/{ns}/local/setpoint_cp"), &cp_schema, "cdr", true)?)),
                false => None,
            };
            arms.push(ArmChannels {
                contract: ContractChannels { state, warning, tool_type, local },
                topics,
                measured_cp: w.add_channel(&format!("/{ns}/measured_cp"), &cp_schema, "cdr")?,
                setpoint_cp: w.add_channel(&format!("/{ns}/setpoint_cp"), &cp_schema, "cdr")?,
                measured_cv: w.add_channel(&format!("/{ns}/measured_cv"), &cv_schema, "cdr")?,
                operating_state: w.add_qos(&format!("/{ns}/operating_state"), &state_schema, "cdr", false, TopicQos::Event)?,
                state: ArmState::default(),
                base_frame_id: format!("{}_base", arm.name.replace('-', "_")),
                base,
                tip_body,
                tip_rel,
                base_in_model: base_world,
                targets: vec![0.0; m.nq()],
                kin: dvrk_kin::Data::new(m),
                jacobian: nalgebra::Matrix6xX::zeros(m.nq()),
            });
            body_names.push(m.bodies.iter().map(|b| format!("{}/{}", arm.name, b.name)).collect());
        }
        // What does not change: the link geometry for a 3D panel, a description per arm for the
        // panels that want a URDF.
        let geometries = sim.arms.iter().map(|a| ArmGeometry::new(&a.model)).collect::<Result<Vec<_>>>()?;
        let has_rcm: Vec<bool> = sim.arms.iter().map(|a| a.model.rcm.is_some()).collect();
        let colors: Vec<[f32; 3]> = (0..sim.arms.len()).map(|a| arm_color(&has_rcm, a)).collect();
        let (scene_schema, scene_encoding) = scene_msgs::schema();
        let mut statics = vec![(w.add_channel("/scene", &scene_schema, &scene_encoding)?, scene_msgs::scene_update(&geometries, &colors, &body_names)?)];
        let string_schema = ros2(ros_msgs::string_schema());
        for (a, arm) in sim.arms.iter().enumerate() {
            let urdf = description::arm_urdf(&arm.name, &geometries[a], &body_names[a], colors[a]);
            let topic = format!("/{}/robot_description", topic_namespace(&arm.name));
            statics.push((w.add_channel(&topic, &string_schema, "cdr")?, ros_msgs::encode_string(&urdf)));
        }
        let view_arm = sim.arms.iter().position(|a| a.name == "ECM");
        Ok(Recorder { sinks: w, staged, tmp, path, stride, arms, tf, tf_ros2, body_names, samples: 0, camera: None, statics, statics_sent: None, tf_buf: Vec::new(), stamp_origin: 0.0, view_arm })
    }

    /// Simulated time between samples (s) for a sim of time step `dt`.
    pub fn period(&self, dt: f64) -> f64 {
        self.stride as f64 * dt
    }

    /// Samples written so far.
    pub fn samples(&self) -> u64 {
        self.samples
    }

    /// Record `sim` if step number `step` (1 after the first step) falls on a sample.
    pub fn after_step(&mut self, sim: &Sim, step: u64) -> Result<()> {
        if step % self.stride == 0 {
            self.sample(sim)?;
        }
        Ok(())
    }

    /// The `frame_id` of arm `a`'s `measured_cp` (`PSM1_base`).
    pub fn base_frame_id(&self, a: usize) -> &str {
        &self.arms[a].base_frame_id
    }

    /// World pose of arm `a`'s base frame (the `frame_id` of its `measured_cp`).
    pub fn base_pose(&self, sim: &Sim, a: usize) -> Pose {
        match &self.arms[a].base {
            BaseRef::World(p) => *p,
            BaseRef::Body(pa, body, rel) => sim.body_pose(*pa, *body) * rel,
        }
    }

    /// Arm `a`'s operating state.
    pub fn state(&self, a: usize) -> &ArmState {
        &self.arms[a].state
    }

    /// Change arm `a`'s operating state and say so at once (at simulated time `time`, s) on
    /// every sink, as the dVRK publishes `operating_state` when it changes.
    pub fn set_state(&mut self, a: usize, time: f64, state: ArmState) -> Result<()> {
        let t = time + self.stamp_origin;
        self.arms[a].state = state;
        let bytes = self.arms[a].state.message(t).encode();
        self.write(self.arms[a].operating_state, t, &bytes)?;
        let c = &self.arms[a];
        self.write(c.contract.state, t, &ros_msgs::encode_string_stamped(t, &c.state.state))
    }

    /// Say `text` on arm `a`'s `warning` topic (ROS 2; the write never waits) at simulated time
    /// `time` (s).
    pub fn warn(&self, a: usize, time: f64, text: &str) {
        let t = time + self.stamp_origin;
        self.sinks.log(self.arms[a].contract.warning, stamp_ns(t), &ros_msgs::encode_string_stamped(t, text));
    }

    /// The tool tip's velocity of arm `a` in its base frame's axes (what `measured_cv` holds):
    /// linear (m/s, of the tip point) and angular (rad/s), from the model's Jacobian of the
    /// tip at the measured joints (the carrying arm, if any, held still).
    fn tip_velocity(&mut self, sim: &Sim, a: usize) -> Result<([f64; 3], [f64; 3])> {
        let arm = &sim.arms[a];
        let (off, n) = (arm.q_offset, arm.model.nq());
        let (q, qd) = (&sim.q()[off..off + n], &sim.qd()[off..off + n]);
        if !q.iter().chain(qd).all(|x| x.is_finite()) {
            // A run gone non-finite is the run's error to report, not the kinematics'.
            return Ok(([f64::NAN; 3], [f64::NAN; 3]));
        }
        let base = self.base_pose(sim, a).rotation;
        let c = &mut self.arms[a];
        dvrk_kin::forward_kinematics(&arm.model, &mut c.kin, q)?;
        dvrk_kin::frame_jacobian(&arm.model, &c.kin, arm.model.tip, &mut c.jacobian)?;
        // J qd, row by row (no temporary vectors: this runs at the publishing rate).
        let twist = |r: usize| (0..n).map(|k| c.jacobian[(r, k)] * qd[k]).sum::<f64>();
        // The Jacobian's axes are the scene's world (the model's FK places it with its base);
        // the base frame's rotation takes them into the base.
        let to_base = base.inverse();
        let v = to_base * nalgebra::Vector3::new(twist(0), twist(1), twist(2));
        let w = to_base * nalgebra::Vector3::new(twist(3), twist(4), twist(5));
        Ok(([v.x, v.y, v.z], [w.x, w.y, w.z]))
    }

    /// The tool tip at arm `a`'s actuator targets in its base frame (what `setpoint_cp` holds, m):
    /// the model's FK at the targets, relative to its CRTK base in the model's own placement
    /// (exact for an arm carried by setup joints too: base and tip ride on the arm's frame 0).
    /// `None` when a target is not finite.
    fn setpoint_tip(&mut self, sim: &Sim, a: usize) -> Result<Option<Pose>> {
        let arm = &sim.arms[a];
        let c = &mut self.arms[a];
        for (k, act) in arm.actuators.iter().enumerate() {
            c.targets[k] = act.target;
        }
        if !c.targets.iter().all(|x| x.is_finite()) {
            return Ok(None);
        }
        dvrk_kin::forward_kinematics(&arm.model, &mut c.kin, &c.targets)?;
        Ok(Some(c.base_in_model.inverse() * c.kin.frames[arm.model.tip]))
    }

    /// The world pose of the ECM's camera ([`VIEW_FRAME`]) now, if the scene has an ECM.
    pub fn view_pose(&self, sim: &Sim) -> Option<Pose> {
        self.view_arm.map(|e| sim.body_pose(e, self.arms[e].tip_body) * self.arms[e].tip_rel)
    }

    /// The frame arm `a`'s `measured_cp` and `setpoint_cp` are in, and its world pose now: a
    /// PSM's (an arm with `local/*` topics) is the ECM's camera where the scene has an ECM, any
    /// other arm's its base frame.
    pub fn report_frame(&self, sim: &Sim, a: usize) -> (&str, Pose) {
        match self.view_pose(sim).filter(|_| self.arms[a].contract.local.is_some() && Some(a) != self.view_arm) {
            Some(view) => (VIEW_FRAME, view),
            None => (&self.arms[a].base_frame_id, self.base_pose(sim, a)),
        }
    }

    /// The tool tip of arm `a` in its base frame (what `local/measured_cp` holds), m.
    pub fn tip_in_base(&self, sim: &Sim, a: usize) -> Pose {
        let c = &self.arms[a];
        self.base_pose(sim, a).inverse() * sim.body_pose(a, c.tip_body) * c.tip_rel
    }

    /// Send one message to the file and the live view; fails with the file's first write error
    /// (a full disk stops the run rather than leaving a hole in the recording).
    fn write(&self, channel: usize, t: f64, data: &[u8]) -> Result<()> {
        self.sinks.log(channel, stamp_ns(t), data);
        match self.sinks.file.as_ref() {
            Some(f) => f.check().map_err(|e| io_error(&self.tmp, e)),
            None => Ok(()),
        }
    }

    /// Record the state of `sim` now.
    pub fn sample(&mut self, sim: &Sim) -> Result<()> {
        let t = sim.time + self.stamp_origin;
        for a in 0..self.arms.len() {
            let arm = &sim.arms[a];
            let (off, n) = (arm.q_offset, arm.model.nq());
            let (q, qd) = (&sim.q()[off..off + n], &sim.qd()[off..off + n]);
            let c = &self.arms[a];
            let mut messages = Vec::with_capacity(2 * c.topics.len());
            for g in c.topics.iter().filter(|g| self.sinks.wanted(g.measured_js) || self.sinks.wanted(g.setpoint_js)) {
                let pick = |f: &dyn Fn(usize) -> f64| g.joints.iter().map(|&k| f(k)).collect::<Vec<f64>>();
                let effort = pick(&|k| arm.actuators[k].effort);
                let measured = JointState { header: Header::at(t, ""), name: g.names.clone(), position: pick(&|k| q[k]), velocity: pick(&|k| qd[k]), effort: effort.clone() };
                let setpoint = JointState {
                    header: Header::at(t, ""),
                    name: g.names.clone(),
                    position: pick(&|k| arm.actuators[k].target),
                    velocity: pick(&|k| arm.actuators[k].target_velocity),
                    effort,
                };
                messages.push((g.measured_js, measured.encode()));
                messages.push((g.setpoint_js, setpoint.encode()));
            }
            let local = c.contract.local;
            let mc = c.measured_cp;
            let in_base = self.tip_in_base(sim, a);
            // The report frame (once per sample: the ECM's camera moves), and from the base to
            // it where it is not the base.
            let (frame, frame_pose) = self.report_frame(sim, a);
            let frame = frame.to_string();
            let base_to_frame = (frame != c.base_frame_id).then(|| frame_pose.inverse() * self.base_pose(sim, a));
            let in_frame = base_to_frame.map_or(in_base, |m| m * in_base);
            let cp = (self.sinks.wanted(mc) || local.is_some()).then(|| (PoseStamped::from_pose(t, &frame, &in_frame), PoseStamped::from_pose(t, &c.base_frame_id, &in_base)));
            if self.samples == 0 {
                messages.insert(0, (c.operating_state, c.state.message(t).encode()));
                messages.push((c.contract.state, ros_msgs::encode_string_stamped(t, &c.state.state)));
                if let Some((ch, name)) = &c.contract.tool_type {
                    messages.push((*ch, ros_msgs::encode_string(name)));
                }
            }
            for (ch, bytes) in messages {
                self.write(ch, t, &bytes)?;
            }
            if let Some((cp, cp_local)) = cp {
                let bytes = cp.encode();
                if self.sinks.wanted(mc) {
                    self.write(mc, t, &bytes)?;
                }
                // The PSM's own base frame (the same bytes while measured_cp is in it).
                if let Some((lm, _)) = local.filter(|(lm, _)| self.sinks.wanted(*lm)) {
                    let local_bytes = if cp_local.header.frame_id == cp.header.frame_id { bytes } else { cp_local.encode() };
                    self.write(lm, t, &local_bytes)?;
                }
            }
            let sc = self.arms[a].setpoint_cp;
            let ls = local.map(|(_, ls)| ls).filter(|ls| self.sinks.wanted(*ls));
            if self.sinks.wanted(sc) || ls.is_some() {
                if let Some(p) = self.setpoint_tip(sim, a)? {
                    let base_frame = self.arms[a].base_frame_id.clone();
                    let local_bytes = PoseStamped::from_pose(t, &base_frame, &p).encode();
                    if self.sinks.wanted(sc) {
                        let bytes = match base_to_frame {
                            None => local_bytes.clone(),
                            Some(m) => PoseStamped::from_pose(t, &frame, &(m * p)).encode(),
                        };
                        self.write(sc, t, &bytes)?;
                    }
                    if let Some(ls) = ls {
                        self.write(ls, t, &local_bytes)?;
                    }
                }
            }
            let cv = self.arms[a].measured_cv;
            if self.sinks.wanted(cv) {
                let (linear, angular) = self.tip_velocity(sim, a)?;
                let frame = self.arms[a].base_frame_id.clone();
                self.write(cv, t, &ros_msgs::encode_twist_stamped(t, &frame, linear, angular))?;
            }
        }
        // What does not change: once in the file, and to the live view every wall-clock second
        // (not latched: a client that subscribes later gets it within a second).
        if self.samples == 0 {
            for (channel, bytes) in &self.statics {
                self.write(*channel, t, bytes)?;
            }
            self.statics_sent = Some(std::time::Instant::now());
        } else if self.statics_sent.is_none_or(|s| s.elapsed().as_secs_f64() >= 1.0) {
            for (channel, bytes) in &self.statics {
                self.sinks.log_live(*channel, stamp_ns(t), bytes);
            }
            // The arm's state too: a ROS 2 client that joins later waits for it.
            for c in &self.arms {
                self.sinks.log_live(c.operating_state, stamp_ns(t), &c.state.message(t).encode());
            }
            self.statics_sent = Some(std::time::Instant::now());
        }
        let ros2_tf = self.tf_ros2.filter(|c| self.sinks.wanted(*c));
        if self.sinks.wanted(self.tf) || ros2_tf.is_some() {
            let mut poses = Vec::with_capacity(self.body_names.iter().map(Vec::len).sum());
            for a in 0..self.arms.len() {
                for b in 0..self.body_names[a].len() {
                    let p = sim.body_pose(a, b);
                    let q = UnitQuaternion::from_rotation_matrix(&p.rotation);
                    let o = p * Point3::origin();
                    poses.push((&self.body_names[a][b], [o.x, o.y, o.z], [q.i, q.j, q.k, q.w]));
                }
            }
            if let Some(channel) = ros2_tf {
                let list: Vec<TransformStamped> =
                    poses.iter().map(|(name, o, q)| TransformStamped { header: Header::at(t, "world"), child_frame_id: (*name).clone(), translation: *o, rotation: *q }).collect();
                self.write(channel, t, &ros_msgs::encode_tf(&list))?;
            }
            if self.sinks.wanted(self.tf) {
                let transforms = poses.iter().map(|(name, o, q)| frame_transform::transform(t, "world", name, *o, *q)).collect();
                let mut buf = std::mem::take(&mut self.tf_buf);
                frame_transform::encode(transforms, &mut buf);
                let sent = self.write(self.tf, t, &buf);
                self.tf_buf = buf;
                sent?;
            }
        }
        self.samples += 1;
        Ok(())
    }

    /// Add the camera's channels (see the module documentation).
    pub fn add_camera(&mut self) -> Result<()> {
        let w = &mut self.sinks;
        let (img, img_encoding) = sdk_schema::<CompressedImage>();
        let (cal, cal_encoding) = sdk_schema::<CameraCalibration>();
        let mut ch = CameraChannels { image: [0; 2], depth: [0; 2], calibration: [0; 2], png: Vec::new(), scratch: Vec::new(), message: Vec::new() };
        for (i, eye) in [Eye::Left, Eye::Right].into_iter().enumerate() {
            let e = eye.name();
            ch.image[i] = w.add_channel(&format!("/camera/{e}/image"), &img, &img_encoding)?;
            ch.depth[i] = w.add_channel(&format!("/camera/{e}/depth"), &img, &img_encoding)?;
            ch.calibration[i] = w.add_channel(&format!("/camera/{e}/calibration"), &cal, &cal_encoding)?;
        }
        self.camera = Some(ch);
        Ok(())
    }

    /// Record the camera's current frame (both eyes), taken at `camera.time`.
    pub fn write_camera(&mut self, sim: &Sim, camera: &StereoCamera) -> Result<()> {
        let Some(mut ch) = self.camera.take() else {
            return Err(SimError::Build("write_camera before add_camera".into()));
        };
        let t = camera.time + self.stamp_origin;
        let k = camera.intrinsics;
        let tmp = self.tmp.display().to_string();
        let png_err = |e: png::EncodingError| SimError::Io { path: tmp.clone(), source: std::io::Error::other(e.to_string()) };
        let result = (|| {
            for (i, eye) in [Eye::Left, Eye::Right].into_iter().enumerate() {
                let frame = format!("camera_{}", eye.name());
                let img = camera.image(eye);
                ch.png.clear();
                img.encode_rgb_png(&mut ch.png).map_err(png_err)?;
                camera_msgs::compressed_image(t, &frame, "png", &ch.png, &mut ch.message);
                self.write(ch.image[i], t, &ch.message)?;
                ch.png.clear();
                img.encode_depth_png(&mut ch.png, &mut ch.scratch).map_err(png_err)?;
                camera_msgs::compressed_image(t, &frame, "png", &ch.png, &mut ch.message);
                self.write(ch.depth[i], t, &ch.message)?;
                // ROS stereo: the right eye's P[3] = -fx * (baseline between the eyes).
                let tx = if eye == Eye::Right { -k.fx * 2.0 * camera.params.baseline_m } else { 0.0 };
                self.write(ch.calibration[i], t, &camera_msgs::camera_calibration(t, &frame, &k, tx))?;
                let p = camera.eye_pose(sim, eye);
                let q = UnitQuaternion::from_rotation_matrix(&p.rotation);
                let o = p.translation.vector;
                frame_transform::encode(vec![frame_transform::transform(t, "world", &frame, [o.x, o.y, o.z], [q.i, q.j, q.k, q.w])], &mut ch.message);
                self.write(self.tf, t, &ch.message)?;
            }
            Ok(())
        })();
        self.camera = Some(ch);
        result
    }

    /// Close the file and move it to its destination.
    pub fn finish(self) -> Result<PathBuf> {
        let path = self.path.clone();
        if let Some(staged) = self.finish_staged()? {
            staged.commit().map_err(|e| SimError::Io { path: path.display().to_string(), source: std::io::Error::other(e.to_string()) })?;
        }
        Ok(path)
    }

    /// The live view, if the run is served.
    pub fn live(&self) -> Option<&Live> {
        self.sinks.live.as_ref()
    }

    /// The ROS 2 domain, if the run is served on one.
    pub fn ros2(&self) -> Option<&Ros2> {
        self.sinks.ros2.as_ref()
    }

    /// Mutable access to the ROS 2 domain (to subscribe to commands).
    pub fn ros2_mut(&mut self) -> Option<&mut Ros2> {
        self.sinks.ros2.as_mut()
    }

    /// Stamp every message at `origin + simulated time` (s): a served twin stamps with the wall
    /// clock (seconds since the Unix epoch at its start), as the dVRK does.
    pub fn set_stamp_origin(&mut self, origin: f64) {
        self.stamp_origin = origin;
    }

    /// Stop serving, close the file, complete and synced, but leave it staged beside its
    /// destination: the caller commits it with its other outputs (all or none), or drops it.
    /// `None` for a run that was only served.
    pub fn finish_staged(mut self) -> Result<Option<Staged>> {
        if let Some(l) = self.sinks.live.take() {
            l.stop();
        }
        if let Some(w) = self.sinks.file.take() {
            let buf = w.finish().map_err(|e| io_error(&self.tmp, e))?;
            let file = buf.into_inner().map_err(|e| SimError::Io { path: self.tmp.display().to_string(), source: e.into_error() })?;
            file.sync_all().map_err(|e| SimError::Io { path: self.tmp.display().to_string(), source: e })?;
        }
        Ok(self.staged.take())
    }
}

/// Where `measured_cp` is reported for a model placed in the world (its `base`): the base of its
/// serial dVRK kinematics (a PSM's or ECM's RCM frame), or frame 0 when it has no serial
/// equivalent.
pub fn crtk_base(m: &dvrk_kin::Model) -> Pose {
    let mut unplaced = m.clone();
    unplaced.base = Pose::identity();
    m.base * dvrk_kin::compose::serial_base_transform(&unplaced).unwrap_or_else(|_| Pose::identity())
}
