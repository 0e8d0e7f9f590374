//! The tracking channel: the recording's setpoints replayed through the simulated arm under its
//! PID, the simulated encoder positions against the recorded ones; with the nominal model, then
//! with the named effects added (the gap should shrink).

use dvrk_sim::recording::JointLog;
use super::report::TrackingReport;
use crate::error::{CalibError, Result};
use dvrk_sim::trajectory::Trajectory;
use dvrk_sim::{Scene, Sim, SimOptions};

/// RMS per joint of recorded minus replayed encoder positions (rad, m), past the first 2 s.
fn replay(scene: &Scene, arm: usize, log: &JointLog) -> Result<Vec<f64>> {
    let nq = log.names.len();
    let traj = Trajectory::samples("recording", &log.t, log.setpoint.clone(), nq).map_err(|e| CalibError::data("replay", e))?;
    let mut scene = scene.clone();
    scene.set_start_recorded(arm, &log.setpoint[0], dvrk_sim::scene::RECORDED_START_SLACK).map_err(CalibError::simulation)?;
    // A named drive compliance can be stiffer than the scene's step resolves: the replay takes
    // the largest step, an integer fraction of the scene's, that holds its motor's mode.
    let stable = scene.max_stable_dt();
    if stable < scene.dt {
        scene.dt /= (scene.dt / stable).ceil();
    }
    // The reduced engine: exact loops, ten times rapier's speed; the hidden-effect truth is
    // rapier's (`generate`), so no table grades an engine against itself.
    let options = SimOptions { engine: Some(dvrk_sim::Engine::Reduced), ..SimOptions::default() };
    let mut sim = Sim::new(&scene, &options).map_err(CalibError::simulation)?;
    let off = sim.arms[arm].q_offset;
    let (mut q, mut qd) = (vec![0.0; nq], vec![0.0; nq]);
    let t0 = log.t[0];
    let mut sum = vec![0.0; nq];
    let mut count = 0usize;
    let mut next = 0usize;
    while next < log.len() {
        let t = sim.time + sim.dt;
        traj.sample(t, &mut q, &mut qd);
        for k in 0..nq {
            sim.set_target(off + k, q[k], qd[k]).map_err(CalibError::simulation)?;
        }
        sim.step();
        // Compare at the recorded samples the step reached.
        while next < log.len() && log.t[next] - t0 <= sim.time + 1e-9 {
            if log.t[next] - t0 >= 2.0 {
                for k in 0..nq {
                    sum[k] += (log.position[next][k] - sim.q()[off + k]).powi(2);
                }
                count += 1;
            }
            next += 1;
        }
    }
    Ok(sum.iter().map(|s| (s / count.max(1) as f64).sqrt()).collect())
}

/// Tracking RMS with model `before` on arm `arm` of `scene`, and with `after` if given (each
/// put on the arm's mount).
pub fn compare(scene: &Scene, arm: usize, log: &JointLog, before: &dvrk_kin::Model, after: Option<&dvrk_kin::Model>) -> Result<TrackingReport> {
    let with = |m: &dvrk_kin::Model| -> Result<Vec<f64>> {
        let mut s = scene.clone();
        s.set_model(arm, m.clone()).map_err(CalibError::simulation)?;
        replay(&s, arm, log)
    };
    Ok(TrackingReport { joints: log.names.clone(), rms_before: with(before)?, rms_after: after.map(with).transpose()? })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A log holding the scene's start with the jaw `past` its upper limit (rad), 2.5 s at 100 Hz.
    fn log_past_jaw_limit(scene: &Scene, past: f64) -> JointLog {
        let model = &scene.arms[0].model;
        let jaw = model.joints.iter().position(|j| j.name == "jaw").unwrap();
        let mut q = scene.arms[0].start.clone();
        q[jaw] = model.joints[jaw].upper + past;
        let n = 250;
        JointLog {
            names: model.joints.iter().map(|j| j.name.clone()).collect(),
            t: (0..n).map(|i| i as f64 * 0.01).collect(),
            setpoint: vec![q.clone(); n],
            position: vec![q.clone(); n],
            effort: vec![vec![0.0; q.len()]; n],
            ..JointLog::default()
        }
    }

    #[test]
    fn a_start_a_hair_past_a_limit_replays_from_the_limit_and_one_far_past_is_refused() {
        let scene = Scene::load("psm").unwrap();
        let jaw = scene.arms[0].model.joints.iter().position(|j| j.name == "jaw").unwrap();
        // WPI `two`'s jaw: 0.33 mrad past; the replayed jaw holds at the limit.
        let rms = replay(&scene, 0, &log_past_jaw_limit(&scene, 3.3e-4)).unwrap();
        assert!(rms[jaw] > 2e-4 && rms[jaw] < 2e-3, "jaw RMS {}", rms[jaw]);
        let e = replay(&scene, 0, &log_past_jaw_limit(&scene, 0.1)).unwrap_err().to_string();
        assert!(e.contains("start configuration") && e.contains("jaw = 1.49"), "{e}");
    }

    #[test]
    fn a_drive_stiffer_than_the_scenes_step_replays_at_a_finer_step() {
        // WPI `two`: a joint_compliance on the yaw named with an 80 kN·m/rad stiffness, a 2000
        // rad/s motor mode that a 1 ms step cannot hold.
        let mut scene = Scene::load("psm").unwrap();
        let dt = scene.dt;
        let log = log_past_jaw_limit(&scene, 0.0);
        let rigid = replay(&scene, 0, &log).unwrap();
        let inertia = dvrk_sim::effects::drive_armature(&scene.arms[0].model, &scene.arms[0].armature)[0];
        let stiffness = inertia * (1.0 / dt).powi(2);
        let spec = dvrk_kin::effects::EffectSpec {
            name: "joint_compliance".into(),
            joint: Some("outer_yaw".into()),
            link: None,
            actuator: None,
            parameters: [("stiffness".to_string(), stiffness)].into(),
            source: String::new(),
        };
        let stiff = scene.arms[0].model.with_effect(&spec).unwrap();
        scene.set_model(0, stiff).unwrap();
        assert!(scene.max_stable_dt() < 0.6 * dt, "{}", scene.max_stable_dt());
        let reduced = SimOptions { engine: Some(dvrk_sim::Engine::Reduced), ..SimOptions::default() };
        assert!(Sim::new(&scene, &reduced).is_err(), "the scene's own step should not hold the mode");
        // So stiff a drive holds the arm as the rigid one does.
        let rms = replay(&scene, 0, &log).unwrap();
        for (k, (s, r)) in rms.iter().zip(&rigid).enumerate() {
            assert!((s - r).abs() <= 0.05 * r + 1e-5, "joint {k}: {s} stiff, {r} rigid");
        }
    }
}
