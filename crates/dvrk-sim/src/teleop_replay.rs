//! A recorded master's motion replayed through the follow mode ([`crate::teleop`]) into a
//! PSM of a scene: the PSM's joint setpoints at each MTM sample, computed as the console computes
//! them, from the PSM's *setpoints* (the console anchors on `setpoint_cp`, not on the measured
//! pose), through the model's IK from the previous setpoints (as `servo_cp`). The setpoints are
//! then a replay the simulation tracks with the arm's own controllers ([`crate::run`]), so the
//! PSM's dynamics sit between the hand and the tool as on the real robot.
//!
//! The camera frame is the scene's ECM's tip (the camera) at its start, or, in a scene without
//! an ECM, the PSM's own `measured_cp` frame ([`crate::recording::writer::crtk_base`]).

use crate::error::{Result, SimError};
use crate::teleop::{angle_between, MtmSample, Teleop, TeleopConfig, TeleopState};
use crate::trajectory::Trajectory;
use crate::Scene;
use dvrk_kin::{Model, Pose};
use serde::Serialize;

/// The master's motion, one entry per sample (slices of equal length).
#[derive(Debug, Clone, Copy)]
pub struct MtmMotion<'a> {
    /// Sample times (s, increasing).
    pub t: &'a [f64],
    /// Tip poses in the MTM's base frame (m).
    pub poses: &'a [Pose],
    /// Gripper opening (rad); `None`: the jaw holds.
    pub gripper: Option<&'a [f64]>,
    /// Clutch pedal pressed.
    pub clutch: &'a [bool],
}

/// What the follow mode did over a replay.
#[derive(Debug, Clone, Default, Serialize)]
pub struct FollowReport {
    /// The PSM that followed and the frame it followed in.
    pub psm: String,
    pub camera_frame: String,
    /// MTM samples replayed.
    pub samples: usize,
    /// When following first started (s); `None`: never.
    pub following_from: Option<f64>,
    /// Time spent following, clutched, and waiting for alignment (s).
    pub following_s: f64,
    pub clutched_s: f64,
    pub misaligned_s: f64,
    /// Clutch presses.
    pub clutch_presses: usize,
    /// The orientation difference between MTM and PSM at the first sample (deg).
    pub misalignment_at_start_deg: f64,
    /// The smallest orientation difference while waiting for alignment (deg) and when (s).
    pub closest_alignment_deg: f64,
    pub closest_alignment_at: f64,
    /// Commands the PSM's IK could not reach (the PSM held its previous setpoints), the first
    /// with its reason.
    pub ik_misses: usize,
    pub first_ik_miss: Option<String>,
    /// Path length of the commanded tip (m) and the jaw command's range (rad).
    pub tip_path_m: f64,
    pub jaw_range: Option<[f64; 2]>,
}

/// The PSM's setpoints for a replay ([`Trajectory::Samples`] of all its joints) and the report.
#[derive(Debug, Clone)]
pub struct FollowPlan {
    pub trajectory: Trajectory,
    pub report: FollowReport,
}

/// The camera frame's world pose for PSM `psm` of `scene` and its description: ECM `ecm`'s tip
/// at its start, or the PSM's `measured_cp` frame when `ecm` is `None`.
pub fn camera_frame(scene: &Scene, psm: usize, ecm: Option<usize>) -> Result<(Pose, String)> {
    match ecm {
        Some(e) => {
            let arm = &scene.arms[e];
            let fk = arm.model.fk(&arm.start)?;
            Ok((fk[arm.model.tip], format!("{}'s camera (its tip, `{}`, at its start)", arm.name, arm.model.frames[arm.model.tip].name)))
        }
        None => {
            let arm = &scene.arms[psm];
            Ok((crate::recording::writer::crtk_base(&arm.model), format!("{}'s measured_cp frame ({}_base; the scene has no ECM)", arm.name, arm.name)))
        }
    }
}

/// The follow mode on one PSM, sample by sample: what [`plan`] runs over a recording and
/// `dvrk serve` runs on a live MTM's topics.
#[derive(Debug, Clone)]
pub struct Follower {
    model: Model,
    camera: Pose,
    jaw: Option<usize>,
    teleop: Teleop,
    jaw_now: Option<f64>,
    was_clutched: bool,
    last: Option<(f64, nalgebra::Vector3<f64>)>,
    /// What it did so far.
    pub report: FollowReport,
}

impl Follower {
    /// Follow with the PSM `model` (placed in the world) named `psm`, in the camera frame
    /// `camera` (world pose) described by `camera_name`.
    pub fn new(model: Model, psm: &str, camera: Pose, camera_name: &str, config: &TeleopConfig) -> Follower {
        let report = FollowReport { psm: psm.into(), camera_frame: camera_name.into(), closest_alignment_deg: f64::INFINITY, ..FollowReport::default() };
        let jaw = model.joints.iter().position(|j| j.name == "jaw");
        Follower { model, camera, jaw, teleop: Teleop::new(config.clone()), jaw_now: None, was_clutched: false, last: None, report }
    }

    /// The follow mode's state now.
    pub fn state(&self) -> &TeleopState {
        &self.teleop.state
    }

    /// One MTM sample at time `t` (s; increasing): the PSM's setpoints `q` (its model's joints,
    /// rad and m) are moved when following, and left when not (clutched, waiting for alignment,
    /// or a pose the IK cannot reach). `gripper` false: the jaw holds. Returns whether it followed.
    pub fn step(&mut self, t: f64, sample: &MtmSample, gripper: bool, q: &mut [f64]) -> Result<bool> {
        let dt = self.last.map_or(0.0, |(t0, _)| (t - t0).max(0.0));
        let r = &mut self.report;
        let tip = self.model.fk(q)?[self.model.tip];
        let psm_pose = self.camera.inverse() * tip;
        if r.samples == 0 {
            let m_rot = self.teleop.config.display_from_mtm * sample.pose.rotation;
            r.misalignment_at_start_deg = angle_between(&m_rot, &psm_pose.rotation).to_degrees();
        }
        r.samples += 1;
        if sample.clutch && !self.was_clutched {
            r.clutch_presses += 1;
        }
        self.was_clutched = sample.clutch;
        let jaw_now = *self.jaw_now.get_or_insert_with(|| self.jaw.map_or(0.0, |j| q[j]));
        let followed = match self.teleop.step(sample, &psm_pose) {
            Some(c) => {
                r.following_from.get_or_insert(t);
                r.following_s += dt;
                let target = self.camera * c.tip_in_camera;
                match dvrk_kin::inverse_kinematics(&self.model, &target, q, &crate::serve_cp::servo_ik()) {
                    Ok(s) => {
                        // The jaw is the gripper's, not the IK's.
                        for (k, x) in s.q.iter().enumerate().filter(|(k, _)| Some(*k) != self.jaw) {
                            q[k] = *x;
                        }
                    }
                    Err(e) => {
                        r.ik_misses += 1;
                        r.first_ik_miss.get_or_insert_with(|| format!("at {t:.3} s: {e}"));
                    }
                }
                if let (Some(j), true) = (self.jaw, gripper) {
                    // Towards the gripper's jaw at most `jaw_rate`, inside the joint's limits.
                    let want = c.jaw.clamp(self.model.joints[j].lower, self.model.joints[j].upper);
                    let step = self.teleop.config.jaw_rate * dt;
                    let now = jaw_now + (want - jaw_now).clamp(-step, step);
                    self.jaw_now = Some(now);
                    q[j] = now;
                    let range = r.jaw_range.get_or_insert([now, now]);
                    range[0] = range[0].min(now);
                    range[1] = range[1].max(now);
                }
                true
            }
            None => {
                match self.teleop.state {
                    TeleopState::Misaligned(a) => {
                        r.misaligned_s += dt;
                        if a.to_degrees() < r.closest_alignment_deg {
                            r.closest_alignment_deg = a.to_degrees();
                            r.closest_alignment_at = t;
                        }
                    }
                    _ => r.clutched_s += dt,
                }
                false
            }
        };
        let p = self.model.fk(q)?[self.model.tip].translation.vector;
        if let Some((_, last)) = self.last {
            r.tip_path_m += (p - last).norm();
        }
        self.last = Some((t, p));
        Ok(followed)
    }

    /// The report, with the closest alignment 0 when it never waited.
    pub fn finish(mut self) -> FollowReport {
        if !self.report.closest_alignment_deg.is_finite() {
            self.report.closest_alignment_deg = 0.0;
        }
        self.report
    }
}

/// Replay `motion` into arm `psm` of `scene` from its start, in the camera frame `camera` (world
/// pose), with the follow mode's `config`. The PSM must stand on the world (not on setup
/// joints), so that its setpoints' poses are fixed in the camera frame.
pub fn plan(scene: &Scene, psm: usize, camera: &Pose, camera_name: &str, motion: &MtmMotion, config: &TeleopConfig) -> Result<FollowPlan> {
    let arm = &scene.arms[psm];
    check_fixed(scene, psm)?;
    let n = motion.t.len();
    if n == 0 || motion.poses.len() != n || motion.clutch.len() != n || motion.gripper.is_some_and(|g| g.len() != n) {
        return Err(SimError::value("MTM samples", n as f64, "need poses, clutch (and gripper) for every sample, at least one"));
    }
    let mut follower = Follower::new(arm.model.clone(), &arm.name, *camera, camera_name, config);
    let mut q = arm.start.clone();
    let mut qs = Vec::with_capacity(n);
    for k in 0..n {
        let sample = MtmSample { pose: motion.poses[k], gripper: motion.gripper.map_or(0.0, |g| g[k]), clutch: motion.clutch[k] };
        follower.step(motion.t[k], &sample, motion.gripper.is_some(), &mut q)?;
        qs.push(q.clone());
    }
    Ok(FollowPlan { trajectory: Trajectory::Samples { t: motion.t.to_vec(), q: qs }, report: follower.finish() })
}

/// A PSM carried by setup joints has no fixed place in the camera frame: refused.
pub fn check_fixed(scene: &Scene, psm: usize) -> Result<()> {
    let arm = &scene.arms[psm];
    if arm.parent.is_some() {
        return Err(SimError::field(scene.file.as_str(), arm.name.as_str(), "rides on setup joints: teleoperation drives a PSM mounted on the world (scenes psm, 2psm-ecm, 3psm)".to_string()));
    }
    Ok(())
}
