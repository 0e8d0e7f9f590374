//! A scene served as a live twin: simulated in real time, its arms published on ROS 2 as the
//! dVRK console publishes them (through the recorder, [`crate::Recorder::open_with`]), and
//! driven by the commands a dVRK client sends.
//!
//! Commands, per arm (`PSM1`; the jaw on its own topic, as the dVRK has it):
//! - `/PSM1/servo_jp`, `/PSM1/jaw/servo_jp` (sensor_msgs/msg/JointState): a position setpoint
//!   (rad, m) for the PID, with the velocity as feed-forward when the message has one;
//! - `/PSM1/servo_jr`, `/PSM1/jaw/servo_jr`: a step (rad, m) added to the current setpoint;
//! - `/PSM1/move_jp`, `/PSM1/jaw/move_jp`: a goal reached by an interpolated move under the
//!   console's velocity and acceleration limits ([`crate::joint_move`]); the arm is busy until
//!   it arrives, a new move replaces it and a servo command ends it;
//! - `/PSM1/servo_jf`, `/PSM1/jaw/servo_jf`: efforts (N·m, N), saturated at the joint's effort
//!   limit as the drive does (past ten times it, refused); the joint leaves PID until its next
//!   position command.
//!
//! - `/PSM1/servo_cp` (geometry_msgs/msg/PoseStamped): a tool-tip pose in `PSM1_base`, the ECM's
//!   camera (`ECM_view`) or `world`, through the IK from the current setpoints
//!   ([`crate::serve_cp`]); a pose out of reach, or in another frame, is refused;
//! - `/PSM1/move_cp`: the same goal, reached by the joints' interpolated move (as `move_jp`);
//! - `/PSM1/state_command` (crtk_msgs/msg/StringStamped): `enable` (hold where the arm is),
//!   `disable` (no effort: the arm hangs on its counterweight and cables), `pause` / `resume`
//!   (hold, commands refused, from and back to ENABLED), `fault` (no effort) / `clear_fault`
//!   (to DISABLED; `enable` is refused in FAULT), `home` (at once: the simulated encoders need no
//!   index search), `unhome`; motion commands to an arm that is not enabled are refused.
//!   `operating_state` and `state` say each change.
//!
//! A message may name its joints (in any order: each must be one of the topic's) or leave the
//! names empty (then it lists them in the arm's order). A command with an unknown name, the
//! wrong number of values or a value that is not finite is refused with a `/rosout` warning and
//! a line on stderr; the twin keeps running. Neither ever blocks the loop ([`crate::warnings`]):
//! a few lines a second are said as they are, a flood is summed up once a second by topic and
//! reason, stderr is written by a thread of its own through a bounded queue (a line it has no
//! room for is dropped and counted in [`ServeSummary::stderr_dropped`]) and `/rosout` is written
//! with no blocking time.

use crate::control::Mode;
use crate::command_mode::leave_effort;
use crate::error::{Result, SimError};
use crate::live::Live;
use crate::recording::ros_msgs::JointState;
use crate::recording::writer::{joint_groups, topic_namespace};
use crate::ros2::{Ros2, Ros2Options};
use crate::{RecordOptions, Recorder, Scene, Sim, SimOptions};
use std::sync::atomic::{AtomicBool, Ordering};
use crate::pace::Pacer;
use crate::warnings::Warnings;
use std::time::{SystemTime, UNIX_EPOCH};

/// What to serve and for how long.
#[derive(Debug, Clone)]
pub struct ServeOptions {
    /// Simulated seconds to run; until stopped when absent.
    pub duration: Option<f64>,
    /// Messages per second on every topic (Hz): the dVRK console's 200 by default.
    pub rate: f64,
    /// The DDS domain and interfaces.
    pub ros2: Ros2Options,
    /// Also record the run to this MCAP file.
    pub record: Option<RecordOptions>,
    /// Add the model's gravity torque to every arm's controllers (PID and `servo_jf` efforts),
    /// as the dVRK's gravity compensation does, whatever the scene says.
    pub gravity_compensation: bool,
    /// A console's MTM on ROS 2 driving one of the scene's PSMs ([`crate::serve_teleop`]).
    pub teleop: Option<crate::serve_teleop::ServeTeleop>,
}

/// What a served run did.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct ServeSummary {
    /// Simulated time (s).
    pub simulated: f64,
    /// Wall-clock time (s).
    pub wall: f64,
    /// Time steps taken.
    pub steps: u64,
    /// Messages published per topic.
    pub samples: u64,
    /// Commands applied, and refused.
    pub commands: u64,
    pub refused: u64,
    /// Refused commands said only in a once-a-second summary (a flood), not one by one.
    pub refusals_summarised: u64,
    /// Warning lines that did not reach stderr (it did not take them fast enough: nobody
    /// reading the pipe) and that `/rosout` refused (a full send window); the loop never waits.
    pub stderr_dropped: u64,
    pub rosout_dropped: u64,
    /// The furthest the simulation fell behind the wall clock (s), after its first second.
    pub worst_lag: f64,
    /// Whether every state stayed finite.
    pub finite: bool,
    /// What the follow mode did, when an MTM drove a PSM.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub teleop: Option<crate::teleop_replay::FollowReport>,
}

/// The kind of a command topic.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    ServoJp,
    ServoJr,
    ServoJf,
    MoveJp,
}

/// One command topic: the joints it moves (global indices) and their names.
struct CommandTopic {
    subscription: usize,
    kind: Kind,
    arm: usize,
    joints: Vec<usize>,
    names: Vec<String>,
}

/// An arm's `servo_cp` or `move_cp` subscription and the joints it sets (global and model
/// indices: the arm's own joints, not the jaw); a move runs in the slot of the arm's `move_jp`.
struct CartesianTopic {
    subscription: usize,
    arm: usize,
    joints: Vec<(usize, usize)>,
    /// `Some(slot)`: `move_cp`, an interpolated move in that command topic's slot.
    move_slot: Option<usize>,
}

/// An arm's `state_command` subscription and all its joints (global indices).
struct StateTopic {
    subscription: usize,
    arm: usize,
    joints: Vec<usize>,
}

/// Why a command is refused: a short, fixed `reason` that groups like refusals in the summary
/// of a flood, and the `detail` said when the refusal is said on its own.
#[derive(Debug, Clone, PartialEq)]
struct Refusal {
    reason: &'static str,
    detail: String,
}

fn refusal(reason: &'static str, detail: impl Into<String>) -> Refusal {
    Refusal { reason, detail: detail.into() }
}

/// The refusal of a command to an arm that is not enabled.
fn not_enabled(state: &str) -> Refusal {
    let way = match state {
        "PAUSED" => "send `resume` on state_command",
        "FAULT" => "send `clear_fault`, then `enable`, on state_command",
        _ => "send `enable` on state_command",
    };
    refusal("arm not enabled", format!("the arm is {state} ({way})"))
}

/// The values of a command in the topic's joint order, or why it is refused.
fn command_values(topic: &CommandTopic, msg: &JointState, kind: Kind) -> std::result::Result<(Vec<f64>, Vec<f64>), Refusal> {
    let (values, field) = if kind == Kind::ServoJf { (&msg.effort, "effort") } else { (&msg.position, "position") };
    let n = topic.joints.len();
    if values.len() != n {
        return Err(refusal("wrong length", format!("{} {field} values for {n} joints ({})", values.len(), topic.names.join(", "))));
    }
    let velocity = match (kind, msg.velocity.len()) {
        (Kind::ServoJp, len) if len == n => msg.velocity.clone(),
        (Kind::ServoJp, 0) | (Kind::ServoJr | Kind::ServoJf | Kind::MoveJp, _) => vec![0.0; n],
        (_, len) => return Err(refusal("wrong length", format!("{len} velocity values for {n} joints"))),
    };
    // Names, when given, say which value goes to which joint.
    let order: Vec<usize> = if msg.name.is_empty() {
        (0..n).collect()
    } else {
        if msg.name.len() != n {
            return Err(refusal("wrong length", format!("{} names for {n} {field} values", msg.name.len())));
        }
        let mut seen = vec![false; n];
        let mut order = vec![0; n];
        for (i, name) in msg.name.iter().enumerate() {
            let Some(k) = topic.names.iter().position(|x| x == name) else {
                return Err(refusal("unknown joint", format!("unknown joint `{name}` (this topic's: {})", topic.names.join(", "))));
            };
            if std::mem::replace(&mut seen[k], true) {
                return Err(refusal("joint named twice", format!("joint `{name}` named twice")));
            }
            order[k] = i;
        }
        order
    };
    let (v, vd): (Vec<f64>, Vec<f64>) = order.iter().map(|&i| (values[i], velocity[i])).unzip();
    if let Some((k, x)) = v.iter().chain(&vd).enumerate().find(|(_, x)| !x.is_finite()) {
        let name = &topic.names[k % n];
        return Err(refusal("not finite", format!("{x} for joint `{name}` is not a finite number")));
    }
    Ok((v, vd))
}

/// A `move_jp` goal past a joint's limits (by more than a micrometre or microradian, a client's
/// rounding) is refused: the move interpolated to it would reach the limit early and then sit
/// there while the arm still says busy, and the client would never learn why.
fn goal_within_limits(sim: &Sim, topic: &CommandTopic, goal: &[f64]) -> std::result::Result<(), Refusal> {
    const TOLERANCE: f64 = 1e-6;
    for (&i, &x) in topic.joints.iter().zip(goal) {
        let j = sim.joint(i).map_err(|e| refusal("not taken", e.to_string()))?;
        if x < j.lower - TOLERANCE || x > j.upper + TOLERANCE {
            let unit = j.unit();
            return Err(refusal("goal outside the limits", format!("goal {x} {unit} for joint `{}` is outside its limits [{}, {}] {unit}", j.name, j.lower, j.upper)));
        }
    }
    Ok(())
}

/// How many times the console's move velocity limit a `servo_jp` velocity (the PID's
/// feed-forward) may be: a teleoperation's servo stream may be faster than a console move, but
/// not an order of magnitude past what the drive can do (1e308 rad/s drove every joint to its
/// limit while `setpoint_js` showed the commanded position).
const SERVO_VELOCITY_FACTOR: f64 = 10.0;

/// A `servo_jp` velocity past [`SERVO_VELOCITY_FACTOR`] times the joint's console velocity
/// limit `v_max` (global indices) is refused, naming the joint, the value and the bound.
fn velocity_within_bounds(sim: &Sim, topic: &CommandTopic, velocity: &[f64], v_max: &[f64]) -> std::result::Result<(), Refusal> {
    for (&i, &v) in topic.joints.iter().zip(velocity) {
        let bound = SERVO_VELOCITY_FACTOR * v_max[i];
        if v.abs() > bound {
            let j = sim.joint(i).map_err(|e| refusal("not taken", e.to_string()))?;
            return Err(refusal("velocity too large", format!("velocity {} {}/s for joint `{}` is past {bound:.3} {}/s (ten times the console's move limit)", dvrk_kin::fmt_number(v), j.unit(), j.name, j.unit())));
        }
    }
    Ok(())
}

/// A `servo_jf` effort past [`SERVO_EFFORT_FACTOR`] times the joint's effort limit is a client's
/// bug, not a command: refused, naming the joint, the value and the bound (within it, the drive
/// saturates at its limit as the dVRK's does).
const SERVO_EFFORT_FACTOR: f64 = 10.0;

fn effort_within_bounds(sim: &Sim, topic: &CommandTopic, effort: &[f64]) -> std::result::Result<(), Refusal> {
    for (&i, &f) in topic.joints.iter().zip(effort) {
        let j = sim.joint(i).map_err(|e| refusal("not taken", e.to_string()))?;
        let bound = SERVO_EFFORT_FACTOR * j.effort_limit;
        if j.effort_limit > 0.0 && f.abs() > bound {
            let unit = j.effort_unit();
            return Err(refusal("effort too large", format!("effort {} {unit} for joint `{}` is past {bound:.3} {unit} (ten times its effort limit)", dvrk_kin::fmt_number(f), j.name)));
        }
    }
    Ok(())
}

/// Serve `scene` on ROS 2 until `options.duration` of simulated time has run or `stop` is set.
/// `ready` is called once the topics exist (before the first step), with the node.
pub fn serve(scene: &Scene, sim_options: &SimOptions, options: &ServeOptions, stop: &AtomicBool, live: Option<Live>, ready: impl FnOnce(&Ros2)) -> Result<(ServeSummary, Option<dvrk_kin::atomic::Staged>)> {
    if let Some(d) = options.duration {
        if !(d.is_finite() && d > 0.0) {
            return Err(SimError::value("duration (s)", d, "must be a positive finite number"));
        }
    }
    let compensated;
    let scene = match options.gravity_compensation {
        true => {
            let mut s = scene.clone();
            s.arms.iter_mut().for_each(|a| a.gravity_compensation = true);
            compensated = s;
            &compensated
        }
        false => scene,
    };
    let mut sim = Sim::new(scene, sim_options)?;
    crate::recording::sample_stride("publishing rate (Hz)", options.rate, sim.dt)?;
    let node = Ros2::start(&options.ros2)?;
    let mut recorder = Recorder::open_with(&sim, options.record.as_ref(), live, Some(node), options.rate)?;
    let epoch = SystemTime::now().duration_since(UNIX_EPOCH).map(|d| d.as_secs_f64()).unwrap_or(0.0);
    recorder.set_stamp_origin(epoch);
    // Hold every joint where it starts until told otherwise.
    for i in 0..sim.nq() {
        let q = sim.q()[i];
        sim.set_target(i, q, 0.0)?;
    }
    let mut topics = Vec::new();
    let mut states = Vec::new();
    let mut cartesian = Vec::new();
    {
        let ros2 = recorder.ros2_mut().expect("opened with ROS 2");
        for (a, arm) in sim.arms.iter().enumerate() {
            // The command topics mirror the published ones: the arm's joints, then the jaw's.
            let groups = joint_groups(&arm.name, &arm.model);
            for (prefix, local) in &groups {
                let joints: Vec<usize> = local.iter().map(|k| arm.q_offset + k).collect();
                let names: Vec<String> = local.iter().map(|k| arm.model.joints[*k].name.clone()).collect();
                for (kind, verb) in [(Kind::ServoJp, "servo_jp"), (Kind::ServoJr, "servo_jr"), (Kind::ServoJf, "servo_jf"), (Kind::MoveJp, "move_jp")] {
                    let subscription = ros2.subscribe(&format!("/{prefix}/{verb}"), "sensor_msgs/msg/JointState")?;
                    topics.push(CommandTopic { subscription, kind, arm: a, joints: joints.clone(), names: names.clone() });
                }
            }
            let ns = topic_namespace(&arm.name);
            let joints: Vec<(usize, usize)> = groups[0].1.iter().map(|&k| (arm.q_offset + k, k)).collect();
            let subscription = ros2.subscribe(&format!("/{ns}/servo_cp"), "geometry_msgs/msg/PoseStamped")?;
            cartesian.push(CartesianTopic { subscription, arm: a, joints: joints.clone(), move_slot: None });
            // move_cp: the IK's goal reached by the joints' interpolated move (as the console's),
            // in the slot of the arm's own move_jp (one replaces the other).
            let slot = topics.iter().position(|t: &CommandTopic| t.arm == a && t.kind == Kind::MoveJp && t.joints.first() == joints.first().map(|j| &j.0));
            let subscription = ros2.subscribe(&format!("/{ns}/move_cp"), "geometry_msgs/msg/PoseStamped")?;
            cartesian.push(CartesianTopic { subscription, arm: a, joints, move_slot: slot });
            let subscription = ros2.subscribe(&format!("/{ns}/state_command"), "crtk_msgs/msg/StringStamped")?;
            states.push(StateTopic { subscription, arm: a, joints: (arm.q_offset..arm.q_offset + arm.model.nq()).collect() });
        }
    }
    let mut teleop = match &options.teleop {
        Some(t) => Some(crate::serve_teleop::LiveTeleop::new(scene, &sim, recorder.ros2_mut().expect("opened with ROS 2"), t)?),
        None => None,
    };
    let mut teleop_refused = Vec::new();
    ready(recorder.ros2().expect("opened with ROS 2"));
    let modes: Vec<Mode> = (0..sim.nq()).map(|i| sim.actuator(i).map(|a| a.mode)).collect::<Result<_>>()?;
    let (mut v_max, mut a_max) = (Vec::with_capacity(sim.nq()), Vec::with_capacity(sim.nq()));
    for arm in &sim.arms {
        let (v, a) = crate::joint_move::limits(&arm.model);
        v_max.extend(v);
        a_max.extend(a);
    }
    let mut moves = Moves { active: vec![None; topics.len()], v_max, a_max };
    let mut summary = ServeSummary { finite: true, ..Default::default() };
    let steps = options.duration.map(|d| (d / sim.dt).round().max(1.0) as u64);
    let mut pacer = Pacer::new(1.0);
    // Refusals go to stderr and /rosout without ever blocking this loop (`warnings`).
    let mut warnings = Warnings::new("commands refused", std::io::stderr());
    let mut step = 0u64;
    while steps.is_none_or(|n| step < n) && !stop.load(Ordering::Relaxed) {
        let mut said = Said { summary: &mut summary, warnings: &mut warnings };
        apply_states(&mut sim, &mut recorder, &states, &topics, &modes, &mut moves, &mut said)?;
        apply_commands(&mut sim, &mut recorder, &topics, &modes, &mut moves, &mut said)?;
        apply_cartesian(&mut sim, &mut recorder, &cartesian, &topics, &modes, &mut moves, &mut said)?;
        if let Some(t) = teleop.as_mut() {
            apply_teleop(&mut sim, &mut recorder, t, &topics, &modes, &mut moves, &mut said, &mut teleop_refused)?;
        }
        warnings.tick(|line| rosout_warning(&recorder, line));
        moves.advance(&mut sim, &mut recorder, &topics)?;
        sim.step();
        step += 1;
        recorder.after_step(&sim, step)?;
        if !sim.q().iter().all(|x| x.is_finite()) {
            summary.finite = false;
            break;
        }
        pacer.wait(step as f64 * sim.dt);
    }
    summary.teleop = teleop.map(|t| t.finish());
    summary.worst_lag = pacer.worst_lag();
    summary.steps = step;
    summary.simulated = step as f64 * sim.dt;
    summary.wall = pacer.elapsed();
    summary.samples = recorder.samples();
    let counts = warnings.finish(|line| rosout_warning(&recorder, line));
    summary.refusals_summarised = counts.summarised;
    summary.stderr_dropped = counts.stderr_dropped;
    summary.rosout_dropped = counts.rosout_dropped;
    let staged = recorder.finish_staged()?;
    if !summary.finite {
        return Err(SimError::Build(format!("the simulation went non-finite at {:.3} s", summary.simulated)));
    }
    Ok((summary, staged))
}

/// The `move_jp` under way on each command topic, and every joint's limits.
struct Moves {
    active: Vec<Option<crate::joint_move::JointMove>>,
    v_max: Vec<f64>,
    a_max: Vec<f64>,
}

impl Moves {
    /// Start a move of `joints` (global indices) from their setpoints to `goal` under the
    /// console's limits, in command slot `slot` (replacing the move there), and say the arm busy.
    #[allow(clippy::too_many_arguments)]
    fn start(&mut self, sim: &mut Sim, recorder: &mut Recorder, topics: &[CommandTopic], slot: usize, joints: &[usize], goal: &[f64], modes: &[Mode]) -> Result<()> {
        for &i in joints {
            leave_effort(sim, i, modes)?;
        }
        let start: Vec<f64> = joints.iter().map(|&i| sim.actuator(i).map(|a| a.target)).collect::<Result<_>>()?;
        let pick = |l: &[f64]| joints.iter().map(|&i| l[i]).collect::<Vec<f64>>();
        self.active[slot] = Some(crate::joint_move::JointMove::new(joints.to_vec(), start, goal, &pick(&self.v_max), &pick(&self.a_max), sim.time));
        self.say_busy(sim, recorder, topics, topics[slot].arm)
    }

    /// Set the targets of the moves under way for the step about to be taken; end those that
    /// arrived, and say when an arm is no longer busy.
    fn advance(&mut self, sim: &mut Sim, recorder: &mut Recorder, topics: &[CommandTopic]) -> Result<()> {
        let t = sim.time + sim.dt;
        let mut ended = Vec::new();
        for (slot, topic) in self.active.iter_mut().zip(topics) {
            let Some(m) = slot.as_ref() else { continue };
            for (i, &joint) in m.joints.iter().enumerate() {
                let (q, qd) = m.at(i, t);
                sim.set_target(joint, q, qd)?;
            }
            if m.done(t) {
                *slot = None;
                ended.push(topic.arm);
            }
        }
        for arm in ended {
            self.say_busy(sim, recorder, topics, arm)?;
        }
        Ok(())
    }

    /// End the moves under way on any of `joints` (a servo command takes them over).
    fn cancel(&mut self, sim: &Sim, recorder: &mut Recorder, topics: &[CommandTopic], joints: &[usize], arm: usize) -> Result<()> {
        let mut cancelled = false;
        for m in self.active.iter_mut() {
            if m.as_ref().is_some_and(|m| m.joints.iter().any(|j| joints.contains(j))) {
                *m = None;
                cancelled = true;
            }
        }
        if cancelled {
            self.say_busy(sim, recorder, topics, arm)?;
        }
        Ok(())
    }

    /// Publish arm `arm`'s busy flag if it changed.
    fn say_busy(&self, sim: &Sim, recorder: &mut Recorder, topics: &[CommandTopic], arm: usize) -> Result<()> {
        let busy = self.active.iter().zip(topics).any(|(m, t)| m.is_some() && t.arm == arm);
        if recorder.state(arm).busy != busy {
            let mut state = recorder.state(arm).clone();
            state.busy = busy;
            recorder.set_state(arm, sim.time, state)?;
        }
        Ok(())
    }
}

/// Take every waiting command and apply the valid ones.
fn apply_commands(sim: &mut Sim, recorder: &mut Recorder, topics: &[CommandTopic], modes: &[Mode], moves: &mut Moves, said: &mut Said) -> Result<()> {
    for (slot, topic) in topics.iter().enumerate() {
        loop {
            let ros2 = recorder.ros2().expect("opened with ROS 2");
            let Some(message) = ros2.take(topic.subscription) else { break };
            let topic_name = ros2.command_topic(topic.subscription).to_string();
            let disabled = recorder.state(topic.arm).state != "ENABLED";
            let values = message
                .map_err(|e| refusal("not taken", e))
                .and_then(|bytes| JointState::decode(&bytes).map_err(|e| refusal("not a JointState", format!("not a sensor_msgs/JointState: {e}"))))
                .and_then(|msg| if disabled { Err(not_enabled(&recorder.state(topic.arm).state)) } else { command_values(topic, &msg, topic.kind) })
                .and_then(|(v, vd)| match topic.kind {
                    Kind::MoveJp => goal_within_limits(sim, topic, &v).map(|()| (v, vd)),
                    Kind::ServoJp => velocity_within_bounds(sim, topic, &vd, &moves.v_max).map(|()| (v, vd)),
                    Kind::ServoJf => effort_within_bounds(sim, topic, &v).map(|()| (v, vd)),
                    _ => Ok((v, vd)),
                });
            match values {
                Ok((v, _)) if topic.kind == Kind::MoveJp => {
                    moves.start(sim, recorder, topics, slot, &topic.joints, &v, modes)?;
                    said.summary.commands += 1;
                }
                Ok((v, vd)) => {
                    // A servo command takes over the joints from a move under way.
                    moves.cancel(sim, recorder, topics, &topic.joints, topic.arm)?;
                    for ((&i, x), xd) in topic.joints.iter().zip(v).zip(vd) {
                        match topic.kind {
                            Kind::ServoJp | Kind::ServoJr => {
                                leave_effort(sim, i, modes)?;
                                let target = if topic.kind == Kind::ServoJr { sim.actuator(i)?.target + x } else { x };
                                sim.set_target(i, target, xd)?;
                            }
                            Kind::ServoJf => {
                                sim.set_mode(i, Mode::Effort)?;
                                sim.set_effort(i, x)?;
                            }
                            // A move is taken by the arm above.
                            Kind::MoveJp => {}
                        }
                    }
                    said.summary.commands += 1;
                }
                Err(why) => said.refuse(recorder, sim.time, Some(topic.arm), &topic_name, why),
            }
        }
    }
    Ok(())
}

/// Take every waiting `servo_cp` and servo the arm's joints to the IK's setpoints.
fn apply_cartesian(sim: &mut Sim, recorder: &mut Recorder, cartesian: &[CartesianTopic], topics: &[CommandTopic], modes: &[Mode], moves: &mut Moves, said: &mut Said) -> Result<()> {
    for topic in cartesian {
        loop {
            let ros2 = recorder.ros2().expect("opened with ROS 2");
            let Some(message) = ros2.take(topic.subscription) else { break };
            let name = ros2.command_topic(topic.subscription).to_string();
            let state = &recorder.state(topic.arm).state;
            let q = match message {
                Ok(_) if state != "ENABLED" => Err(not_enabled(state)),
                Ok(bytes) => crate::serve_cp::setpoints(sim, recorder, topic.arm, &bytes).map_err(|e| refusal("pose refused", e)),
                Err(e) => Err(refusal("not taken", e)),
            };
            match q {
                Ok(q) if topic.move_slot.is_some() => {
                    let global: Vec<usize> = topic.joints.iter().map(|(g, _)| *g).collect();
                    let goal: Vec<f64> = topic.joints.iter().map(|&(_, k)| q[k]).collect();
                    moves.start(sim, recorder, topics, topic.move_slot.expect("a move's slot"), &global, &goal, modes)?;
                    said.summary.commands += 1;
                }
                Ok(q) => {
                    let global: Vec<usize> = topic.joints.iter().map(|(g, _)| *g).collect();
                    moves.cancel(sim, recorder, topics, &global, topic.arm)?;
                    for &(i, k) in &topic.joints {
                        leave_effort(sim, i, modes)?;
                        sim.set_target(i, q[k], 0.0)?;
                    }
                    said.summary.commands += 1;
                }
                Err(why) => said.refuse(recorder, sim.time, Some(topic.arm), &name, why),
            }
        }
    }
    Ok(())
}

/// The live MTM's messages through the follow mode into its PSM (`crate::serve_teleop`): a PSM
/// that follows leaves any move under way, as under a servo command.
#[allow(clippy::too_many_arguments)]
fn apply_teleop(
    sim: &mut Sim,
    recorder: &mut Recorder,
    teleop: &mut crate::serve_teleop::LiveTeleop,
    topics: &[CommandTopic],
    modes: &[Mode],
    moves: &mut Moves,
    said: &mut Said,
    refused: &mut Vec<crate::serve_teleop::Refused>,
) -> Result<()> {
    let enabled = recorder.state(teleop.arm).state == "ENABLED";
    refused.clear();
    let followed = teleop.apply(sim, recorder.ros2().expect("opened with ROS 2"), enabled, modes, refused)?;
    for r in refused.drain(..) {
        said.refuse(recorder, sim.time, None, &r.topic, refusal(r.reason, r.detail));
    }
    if followed {
        moves.cancel(sim, recorder, topics, &teleop.joints, teleop.arm)?;
        said.summary.commands += 1;
    }
    Ok(())
}

/// Where the loop counts commands and says why it refused one.
struct Said<'a> {
    summary: &'a mut ServeSummary,
    warnings: &'a mut Warnings,
}

impl Said<'_> {
    /// Count a refused command and say why, on stderr and `/rosout` (a warning), rate-limited
    /// and without waiting for either, and on arm `arm`'s own `warning` topic (each refusal, as
    /// the CRTK contract has it: `rejected <topic>: <why>`; a write that never waits).
    fn refuse(&mut self, recorder: &Recorder, time: f64, arm: Option<usize>, topic: &str, why: Refusal) {
        self.summary.refused += 1;
        if let Some(a) = arm {
            recorder.warn(a, time, &format!("rejected {topic}: {}", why.detail));
        }
        let line = format!("{topic}: command refused: {}", why.detail);
        self.warnings.warn(&format!("{topic} ({})", why.reason), &line, |l| rosout_warning(recorder, l));
    }
}

/// A warning on `/rosout`; whether it was taken (it is never waited for).
fn rosout_warning(recorder: &Recorder, line: &str) -> bool {
    recorder.ros2().is_none_or(|r| r.log_line(30, line))
}

/// Take every waiting `state_command` and apply it.
fn apply_states(sim: &mut Sim, recorder: &mut Recorder, states: &[StateTopic], topics: &[CommandTopic], modes: &[Mode], moves: &mut Moves, said: &mut Said) -> Result<()> {
    for topic in states {
        loop {
            let ros2 = recorder.ros2().expect("opened with ROS 2");
            let Some(message) = ros2.take(topic.subscription) else { break };
            let name = ros2.command_topic(topic.subscription).to_string();
            let command = message
                .map_err(|e| refusal("not taken", e))
                .and_then(|b| crate::recording::ros_msgs::decode_string_stamped(&b).map_err(|e| refusal("not a StringStamped", format!("not a crtk_msgs/StringStamped: {e}"))));
            let mut state = recorder.state(topic.arm).clone();
            // Hold where the arm is now, under the controllers it started with.
            let hold = |sim: &mut Sim| -> std::result::Result<(), Refusal> {
                for &i in &topic.joints {
                    sim.set_mode(i, modes[i]).map_err(|e| refusal("failed", e.to_string()))?;
                    let q = sim.q()[i];
                    sim.set_target(i, q, 0.0).map_err(|e| refusal("failed", e.to_string()))?;
                }
                Ok(())
            };
            // No effort: the arm hangs on its counterweight and cables.
            let limp = |sim: &mut Sim| -> std::result::Result<(), Refusal> {
                for &i in &topic.joints {
                    sim.set_mode(i, Mode::Effort).map_err(|e| refusal("failed", e.to_string()))?;
                    sim.set_effort(i, 0.0).map_err(|e| refusal("failed", e.to_string()))?;
                }
                Ok(())
            };
            // The CRTK contract's state machine (jhu-dvrk/dvrk_simulator_base): ENABLED, DISABLED,
            // PAUSED, FAULT; a move under way ends with any change.
            let from = state.state.clone();
            let outcome = command.and_then(|(_, c)| match c.trim().to_ascii_lowercase().as_str() {
                "enable" if from == "FAULT" => Err(refusal("not from this state", "cannot enable while in FAULT; issue clear_fault first")),
                "enable" => hold(sim).map(|()| state.state = "ENABLED".into()),
                "disable" => limp(sim).map(|()| state.state = "DISABLED".into()),
                "pause" if from != "ENABLED" => Err(refusal("not from this state", format!("cannot pause from {from}"))),
                "pause" => hold(sim).map(|()| state.state = "PAUSED".into()),
                "resume" if from != "PAUSED" => Err(refusal("not from this state", format!("cannot resume from {from}"))),
                "resume" => hold(sim).map(|()| state.state = "ENABLED".into()),
                "fault" => limp(sim).map(|()| state.state = "FAULT".into()),
                "clear_fault" if from != "FAULT" => Err(refusal("not from this state", format!("cannot clear fault from {from}"))),
                "clear_fault" => {
                    state.state = "DISABLED".into();
                    Ok(())
                }
                "home" if state.state != "ENABLED" => Err(refusal("arm not enabled", format!("home: the arm is {} (enable it first)", state.state))),
                "home" => {
                    state.homed = true;
                    Ok(())
                }
                "unhome" => {
                    state.homed = false;
                    Ok(())
                }
                other => Err(refusal("unknown state command", format!("unknown state command `{other}` (valid: enable, disable, pause, resume, fault, clear_fault, home, unhome)"))),
            });
            if outcome.is_ok() && state.state != from {
                let joints: Vec<usize> = topic.joints.clone();
                moves.cancel(sim, recorder, topics, &joints, topic.arm)?;
            }
            match outcome {
                Ok(()) => {
                    said.summary.commands += 1;
                    recorder.set_state(topic.arm, sim.time, state)?;
                }
                Err(why) => said.refuse(recorder, sim.time, Some(topic.arm), &name, why),
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn topic() -> CommandTopic {
        CommandTopic { subscription: 0, kind: Kind::ServoJp, arm: 0, joints: vec![0, 1, 2], names: vec!["outer_yaw".into(), "outer_pitch".into(), "outer_insertion".into()] }
    }

    #[test]
    fn commands_are_read_by_name_or_position_and_bad_ones_say_why() {
        let t = topic();
        let js = |name: &[&str], position: &[f64]| JointState { name: name.iter().map(|s| s.to_string()).collect(), position: position.to_vec(), ..Default::default() };
        assert_eq!(command_values(&t, &js(&[], &[0.1, 0.2, 0.05]), Kind::ServoJp).unwrap().0, vec![0.1, 0.2, 0.05]);
        let named = js(&["outer_insertion", "outer_yaw", "outer_pitch"], &[0.05, 0.1, 0.2]);
        assert_eq!(command_values(&t, &named, Kind::ServoJp).unwrap().0, vec![0.1, 0.2, 0.05]);
        let refused = command_values(&t, &js(&[], &[0.1, 0.2]), Kind::ServoJp).unwrap_err();
        assert_eq!(refused.reason, "wrong length"); // what a flood's summary groups by
        let e = refused.detail;
        assert_eq!(e, "2 position values for 3 joints (outer_yaw, outer_pitch, outer_insertion)");
        let e = command_values(&t, &js(&["outer_yaw", "wrist", "outer_pitch"], &[0.0; 3]), Kind::ServoJp).unwrap_err().detail;
        assert!(e.starts_with("unknown joint `wrist`"), "{e}");
        let e = command_values(&t, &js(&[], &[0.0, f64::NAN, 0.0]), Kind::ServoJp).unwrap_err().detail;
        assert_eq!(e, "NaN for joint `outer_pitch` is not a finite number");
        let e = command_values(&t, &js(&["outer_yaw", "outer_yaw", "outer_pitch"], &[0.0; 3]), Kind::ServoJp).unwrap_err().detail;
        assert_eq!(e, "joint `outer_yaw` named twice");
    }
}
