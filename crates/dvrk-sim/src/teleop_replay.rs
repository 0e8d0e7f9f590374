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
use dvrk_kin::{IkOptions, Model, Pose};
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

/// The IK of a servo command ([`crate::serve_cp`]'s): Newton from the current setpoints, no restarts.
fn servo_ik() -> IkOptions {
    IkOptions { frame: None, position_tolerance: 1e-7, orientation_tolerance: 1e-6, max_iterations: 50, restarts: 0 }
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

/// Replay `motion` into arm `psm` of `scene` from its start, in the camera frame `camera` (world
/// pose), with the follow mode's `config`. The PSM must stand on the world (not on setup
/// joints), so that its setpoints' poses are fixed in the camera frame.
pub fn plan(scene: &Scene, psm: usize, camera: &Pose, motion: &MtmMotion, config: &TeleopConfig) -> Result<FollowPlan> {
    let arm = &scene.arms[psm];
    if arm.parent.is_some() {
        return Err(SimError::field(scene.file.as_str(), arm.name.as_str(), "rides on setup joints: teleoperation replays into a PSM mounted on the world (scenes psm, 2psm-ecm, 3psm)".to_string()));
    }
    let n = motion.t.len();
    if n == 0 || motion.poses.len() != n || motion.clutch.len() != n || motion.gripper.is_some_and(|g| g.len() != n) {
        return Err(SimError::value("MTM samples", n as f64, "need poses, clutch (and gripper) for every sample, at least one"));
    }
    let model: &Model = &arm.model;
    let jaw = model.joints.iter().position(|j| j.name == "jaw");
    let ik = servo_ik();
    let mut teleop = Teleop::new(config.clone());
    let mut q = arm.start.clone();
    let tip = |q: &[f64]| -> Result<Pose> { Ok(model.fk(q)?[model.tip]) };
    let in_camera = |q: &[f64]| -> Result<Pose> { Ok(camera.inverse() * tip(q)?) };
    let mut report = FollowReport {
        psm: arm.name.clone(),
        samples: n,
        closest_alignment_deg: f64::INFINITY,
        ..FollowReport::default()
    };
    let mut qs = Vec::with_capacity(n);
    let mut jaw_now = jaw.map(|j| q[j]);
    let mut was_clutched = false;
    let mut last_tip = tip(&q)?.translation.vector;
    for k in 0..n {
        let dt = if k == 0 { 0.0 } else { motion.t[k] - motion.t[k - 1] };
        let gripper = motion.gripper.map_or(0.0, |g| g[k]);
        let sample = MtmSample { pose: motion.poses[k], gripper, clutch: motion.clutch[k] };
        let psm_pose = in_camera(&q)?;
        if k == 0 {
            let m_rot = config.display_from_mtm * sample.pose.rotation;
            report.misalignment_at_start_deg = angle_between(&m_rot, &psm_pose.rotation).to_degrees();
        }
        if sample.clutch && !was_clutched {
            report.clutch_presses += 1;
        }
        was_clutched = sample.clutch;
        match teleop.step(&sample, &psm_pose) {
            Some(c) => {
                report.following_from.get_or_insert(motion.t[k]);
                report.following_s += dt;
                let target = camera * c.tip_in_camera;
                match dvrk_kin::inverse_kinematics(model, &target, &q, &ik) {
                    Ok(s) => {
                        // The jaw is the gripper's, not the IK's.
                        let keep_jaw = jaw.map(|j| q[j]);
                        q = s.q;
                        if let (Some(j), Some(v)) = (jaw, keep_jaw) {
                            q[j] = v;
                        }
                    }
                    Err(e) => {
                        report.ik_misses += 1;
                        report.first_ik_miss.get_or_insert_with(|| format!("at {:.3} s: {e}", motion.t[k]));
                    }
                }
                if let (Some(j), Some(now), Some(_)) = (jaw, jaw_now.as_mut(), motion.gripper) {
                    // Towards the gripper's jaw at most `jaw_rate`, inside the joint's limits.
                    let want = c.jaw.clamp(model.joints[j].lower, model.joints[j].upper);
                    let step = config.jaw_rate * dt;
                    *now += (want - *now).clamp(-step, step);
                    q[j] = *now;
                    let r = report.jaw_range.get_or_insert([*now, *now]);
                    r[0] = r[0].min(*now);
                    r[1] = r[1].max(*now);
                }
            }
            None => match teleop.state {
                TeleopState::Misaligned(a) => {
                    report.misaligned_s += dt;
                    if a.to_degrees() < report.closest_alignment_deg {
                        report.closest_alignment_deg = a.to_degrees();
                        report.closest_alignment_at = motion.t[k];
                    }
                }
                _ => report.clutched_s += dt,
            },
        }
        let p = tip(&q)?.translation.vector;
        report.tip_path_m += (p - last_tip).norm();
        last_tip = p;
        qs.push(q.clone());
    }
    if !report.closest_alignment_deg.is_finite() {
        report.closest_alignment_deg = 0.0;
    }
    Ok(FollowPlan { trajectory: Trajectory::Samples { t: motion.t.to_vec(), q: qs }, report })
}
