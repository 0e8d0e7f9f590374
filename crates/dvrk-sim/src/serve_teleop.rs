//! Teleoperation for the served twin ([`crate::serve`]): a console's MTM, live on ROS 2, driving
//! one of the twin's PSMs through the follow mode ([`crate::teleop_replay::Follower`]).
//!
//! The twin subscribes to what a dVRK console publishes: `/MTMR/measured_cp`
//! (geometry_msgs/msg/PoseStamped, the MTM's tip in its base frame), `/MTMR/gripper/measured_js`
//! (sensor_msgs/msg/JointState, `position[0]` rad) and `/footpedals/clutch` (sensor_msgs/msg/Joy,
//! `buttons[0]` 1 while pressed). Each step, the latest pose (servo semantics: the newest wins)
//! goes through the follow mode with the PSM's current setpoints, and the IK's answer becomes
//! its setpoints, as a `servo_cp` would. Only an enabled PSM follows. A message that cannot be
//! read is refused with a warning, as any command; the follow mode's changes (following,
//! clutched, waiting for alignment) are said on `/rosout` at info level.

use crate::control::Mode;
use crate::error::{Result, SimError};
use crate::recording::ros_msgs::{Joy, PoseStamped};
use crate::ros2::Ros2;
use crate::teleop::{MtmSample, TeleopConfig, TeleopState};
use crate::teleop_replay::{camera_frame, check_fixed, FollowReport, Follower};
use crate::{Scene, Sim};
use dvrk_kin::Pose;

/// Which MTM drives which PSM, and how.
#[derive(Debug, Clone)]
pub struct ServeTeleop {
    /// The MTM's namespace on ROS 2 (`MTMR`).
    pub mtm: String,
    /// The PSM of the scene that follows (`PSM1`).
    pub psm: String,
    /// The scene's ECM whose camera frame the motion is in; `None`: the PSM's `measured_cp` frame.
    pub ecm: Option<String>,
    /// The clutch pedal's topic (the console's `/footpedals/clutch`).
    pub clutch_topic: String,
    pub config: TeleopConfig,
}

/// A refused MTM message: its topic, a short reason and the detail.
pub(crate) struct Refused {
    pub topic: String,
    pub reason: &'static str,
    pub detail: String,
}

/// The live follow mode: subscriptions, the latest gripper and clutch, the follower.
pub(crate) struct LiveTeleop {
    mtm: String,
    pose: usize,
    gripper: usize,
    clutch: usize,
    /// The PSM (arm index) and its joints (global indices, model order).
    pub arm: usize,
    pub joints: Vec<usize>,
    follower: Follower,
    gripper_value: Option<f64>,
    pressed: bool,
    /// The PSM's setpoints (scratch, model order).
    q: Vec<f64>,
    /// The follow mode's state last said on `/rosout` (its kind).
    said: Option<&'static str>,
}

fn state_name(s: &TeleopState) -> &'static str {
    match s {
        TeleopState::Following { .. } => "following",
        TeleopState::Clutched => "clutched",
        TeleopState::Misaligned(_) => "waiting for alignment",
    }
}

impl LiveTeleop {
    /// Subscribe to the MTM's topics on `ros2` for `options.psm` of `scene` (simulated by `sim`).
    pub fn new(scene: &Scene, sim: &Sim, ros2: &mut Ros2, options: &ServeTeleop) -> Result<LiveTeleop> {
        let arm = scene.arm_index(&options.psm)?;
        check_fixed(scene, arm)?;
        let ecm = options.ecm.as_deref().map(|e| scene.arm_index(e)).transpose()?;
        let (camera, camera_name) = camera_frame(scene, arm, ecm)?;
        if options.mtm.is_empty() || !options.mtm.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
            return Err(SimError::value(format!("teleoperation MTM name `{}`", options.mtm), f64::NAN, "must be letters, digits or _ (MTML, MTMR)"));
        }
        let m = &options.mtm;
        let pose = ros2.subscribe(&format!("/{m}/measured_cp"), "geometry_msgs/msg/PoseStamped")?;
        let gripper = ros2.subscribe(&format!("/{m}/gripper/measured_js"), "sensor_msgs/msg/JointState")?;
        let clutch = ros2.subscribe(&options.clutch_topic, "sensor_msgs/msg/Joy")?;
        let a = &sim.arms[arm];
        let follower = Follower::new(a.model.clone(), &a.name, camera, &camera_name, &options.config);
        Ok(LiveTeleop {
            mtm: m.clone(),
            pose,
            gripper,
            clutch,
            arm,
            joints: (a.q_offset..a.q_offset + a.model.nq()).collect(),
            follower,
            gripper_value: None,
            pressed: false,
            q: vec![0.0; a.model.nq()],
            said: None,
        })
    }

    /// Take the waiting MTM messages and, when a pose came and the PSM is `enabled`, step the
    /// follow mode: the PSM's targets move when it follows (a joint under `servo_jf` returns to
    /// its mode in `modes`). Returns whether it followed; refusals go to `refused`.
    pub fn apply(&mut self, sim: &mut Sim, ros2: &Ros2, enabled: bool, modes: &[Mode], refused: &mut Vec<Refused>) -> Result<bool> {
        let topic = |s: usize| ros2.command_topic(s).to_string();
        while let Some(m) = ros2.take(self.gripper) {
            match m.and_then(|b| crate::recording::ros_msgs::JointState::decode(&b)) {
                Ok(js) => match js.position.first() {
                    Some(g) if g.is_finite() => self.gripper_value = Some(*g),
                    _ => refused.push(Refused { topic: topic(self.gripper), reason: "no gripper position", detail: "no finite position[0] (the gripper's opening, rad)".into() }),
                },
                Err(e) => refused.push(Refused { topic: topic(self.gripper), reason: "not a JointState", detail: format!("not a sensor_msgs/JointState: {e}") }),
            }
        }
        while let Some(m) = ros2.take(self.clutch) {
            match m.and_then(|b| Joy::decode(&b)) {
                Ok(joy) => match joy.buttons.first() {
                    Some(b) => self.pressed = *b == 1,
                    None => refused.push(Refused { topic: topic(self.clutch), reason: "no button", detail: "no buttons[0] (the pedal)".into() }),
                },
                Err(e) => refused.push(Refused { topic: topic(self.clutch), reason: "not a Joy", detail: format!("not a sensor_msgs/Joy: {e}") }),
            }
        }
        let mut latest = None;
        while let Some(m) = ros2.take(self.pose) {
            match m.and_then(|b| mtm_pose(&b)) {
                Ok(p) => latest = Some(p),
                Err(e) => refused.push(Refused { topic: topic(self.pose), reason: "pose refused", detail: e }),
            }
        }
        let Some(pose) = latest else { return Ok(false) };
        if !enabled {
            return Ok(false);
        }
        for (k, &i) in self.joints.iter().enumerate() {
            self.q[k] = sim.actuator(i)?.target;
        }
        let sample = MtmSample { pose, gripper: self.gripper_value.unwrap_or(0.0), clutch: self.pressed };
        let followed = self.follower.step(sim.time, &sample, self.gripper_value.is_some(), &mut self.q)?;
        if followed {
            for (k, &i) in self.joints.iter().enumerate() {
                crate::command_mode::leave_effort(sim, i, modes)?;
                sim.set_target(i, self.q[k], 0.0)?;
            }
        }
        let now = state_name(self.follower.state());
        if self.said != Some(now) {
            self.said = Some(now);
            let line = format!("{} -> {}: {now}", self.mtm, self.follower.report.psm);
            ros2.log_line(20, &line);
        }
        Ok(followed)
    }

    /// What the follow mode did.
    pub fn finish(self) -> FollowReport {
        self.follower.finish()
    }
}

/// An MTM pose from a PoseStamped's CDR bytes, or why not.
fn mtm_pose(bytes: &[u8]) -> std::result::Result<Pose, String> {
    PoseStamped::decode(bytes).map_err(|e| format!("not a geometry_msgs/PoseStamped: {e}"))?.pose()
}
