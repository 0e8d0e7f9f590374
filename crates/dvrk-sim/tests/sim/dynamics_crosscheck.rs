//! dvrk-kin's rigid-body gravity torques (Newton-Euler on the closed-loop tree, mapped to the
//! actuated joints by the affine maps) against the physics engine: the PSM scene holding still
//! under PID, where the steady efforts are what rapier needs to hold the arm against gravity.
//! The two share only the model and the inertials.

use dvrk_sim::dvrk_kin::{gravity_torque, inverse_dynamics, DynamicsData, DynamicsModel};
use dvrk_sim::{Coriolis, Gains, Scene, Sim, SimOptions};
use nalgebra::Vector3;

/// Hold `target` under PID (integral stiffened as in the sim's own steady-hold test, so it
/// settles within 8 s), then compare the efforts with `gravity_torque` at the measured q.
///
/// Per joint: `|PID - g| <= 1% |g| + 1e-9` (N·m, N); the floor only matters for joints that carry
/// no gravity load (roll at home: g = 2e-17 N·m). Excluded from the relative check: the insertion,
/// whose gravity load the counterweight cancels identically (counterweight mass x mu = the moving
/// insertion mass, on parallel axes), so g = 0 there; it is checked to be zero in both. Joint
/// damping (0.1 N·m s/rad on every tree joint) does not enter: the arm is still (|qd| < 1e-6).
///
/// Measured (home; second pose): yaw 3.58e-2 N·m agree to 7e-12; 9.29e-1 to 3.7e-4 (0.04%);
/// pitch -1.119 N·m to 9e-12; -2.29e-1 to 2.7e-4 (0.12%); wrist and jaw (1e-6 - 5e-4 N·m) to
/// 2e-5 relative. The 1e-4 N·m level at the second pose is the sim's counterweight cable: a
/// spring (200 rad/s on the counterweight's 0.47 kg, k = 1.9e4 N/m) that sags along the
/// counterweight axis by m g cos(tilt) / k = 2.45e-4 m at home and 2.16e-4 m at the second pose
/// (printed below, matching). At home the axis is vertical, so the sag is along gravity and moves
/// no torque; tilted, its horizontal part (~6e-5 m) times 0.47 kg x 9.81 m/s^2 is the 3e-4 N·m
/// seen on yaw and pitch. The rigid model has no such compliance.
#[test]
fn steady_pid_efforts_equal_newton_euler_gravity_torques() {
    let scene = Scene::load("psm").unwrap();
    let arm = &scene.arms[0];
    let model = &arm.model;
    let inertias = arm.inertials.body_inertias(model).unwrap();
    let dm = DynamicsModel::new(model, inertias).unwrap();
    let mut data = DynamicsData::new(model);
    let insertion = model.joint_id("outer_insertion").unwrap();
    let counterweight = model.bodies.iter().position(|b| b.name == "counterweight_link").unwrap();
    let gravity = Vector3::from(scene.gravity);
    for target in [model.home(), vec![0.4, -0.3, 0.2, 0.5, 0.3, -0.4, 0.5]] {
        let mut sim = Sim::new(&scene, &SimOptions::default()).unwrap();
        for (k, x) in target.iter().enumerate() {
            sim.set_target(k, *x, 0.0).unwrap();
            let g = sim.actuator(k).unwrap().gains;
            sim.set_gains(k, Gains { ki: g.kp * 2.0, ..g }).unwrap();
        }
        for _ in 0..8000 {
            sim.step();
        }
        let q = sim.q().to_vec();
        let speed = sim.qd().iter().fold(0.0_f64, |a, x| a.max(x.abs()));
        assert!(speed < 1e-6, "not still: |qd| = {speed}");
        let pid: Vec<f64> = (0..model.nq()).map(|k| sim.effort(k).unwrap()).collect();
        let mut g = vec![0.0; model.nq()];
        gravity_torque(model, &dm, &mut data, &q, &gravity, &mut g).unwrap();
        let fk = model.fk(&q).unwrap();
        let sag = (sim.body_pose(0, counterweight).translation.vector - fk[model.bodies[counterweight].frames[0]].translation.vector).norm();
        println!("held at q = {q:.4?} (|qd| <= {speed:.1e}); counterweight {sag:.2e} m off mu q3");
        for (k, j) in model.joints.iter().enumerate() {
            println!("  {:18} PID {:+.6e}  Newton-Euler {:+.6e}  diff {:+.2e}", j.name, pid[k], g[k], pid[k] - g[k]);
        }
        for (k, j) in model.joints.iter().enumerate() {
            if k == insertion {
                assert!(g[k].abs() < 1e-9 && pid[k].abs() < 1e-6, "insertion not balanced: PID {} N, Newton-Euler {} N", pid[k], g[k]);
                continue;
            }
            assert!((pid[k] - g[k]).abs() <= 0.01 * g[k].abs() + 1e-9, "{} at {q:?}: PID {} vs Newton-Euler {}", j.name, pid[k], g[k]);
        }
        // The comparison is not vacuous: the pitch carries a real load at both poses.
        assert!(g[1].abs() > 0.2, "{}", g[1]);
    }
}

/// The PSM tracking smooth sines under its PID (joint damping off), its links'
/// positions read every step; the efforts that Newton-Euler needs for that motion, with the
/// step's velocity and acceleration from the positions (`v = (q_n - q_n-1) / dt`,
/// `a = (q_n+1 - 2 q_n + q_n-1) / dt^2`: exactly what symplectic Euler applied at step n) and the
/// drives' armature, minus the efforts applied. Per joint: the RMS of that difference over the
/// efforts' RMS.
fn tracking_residual(coriolis: Coriolis) -> Vec<f64> {
    let scene = Scene::load("psm").unwrap();
    let model = &scene.arms[0].model;
    let inertias = scene.arms[0].inertials.body_inertias(model).unwrap();
    let dm = DynamicsModel::new(model, inertias).unwrap();
    let mut data = DynamicsData::new(model);
    let mut sim = Sim::new(&scene, &SimOptions { coriolis, ..Default::default() }).unwrap();
    sim.set_damping_and_armature(0.0, 1.0).unwrap();
    let nq = sim.nq();
    // About home (insertion 0.12 m in): amplitudes (rad, m) and frequencies (Hz).
    let home = sim.q().to_vec();
    let (centre, amp, hz) = ([0.0, 0.0, 0.12, 0.0, 0.0, 0.0, 0.3], [0.6, 0.4, 0.05, 0.8, 0.6, 0.6, 0.0], [0.5, 0.7, 0.6, 0.9, 1.1, 1.3, 1.0]);
    let target = |k: usize, t: f64| {
        let w = 2.0 * std::f64::consts::PI * hz[k];
        // Eased in from home over the first second.
        let ease = (t.min(1.0) * std::f64::consts::PI / 2.0).sin().powi(2);
        (home[k] + (centre[k] - home[k]) * ease + amp[k] * (w * t).sin() * ease, amp[k] * w * (w * t).cos() * ease)
    };
    let (dt, steps) = (sim.dt, 4000);
    let (mut q, mut tau) = (vec![sim.q_link().to_vec()], Vec::new());
    for n in 0..steps {
        for k in 0..nq {
            let (x, v) = target(k, n as f64 * dt);
            sim.set_target(k, x, v).unwrap();
        }
        sim.step();
        q.push(sim.q_link().to_vec());
        tau.push((0..nq).map(|k| sim.effort(k).unwrap()).collect::<Vec<f64>>());
    }
    // From 1.5 s: the ease-in and the PID's start-up transient are over.
    let (mut err, mut size) = (vec![0.0; nq], vec![0.0; nq]);
    let (mut pred, gravity) = (vec![0.0; nq], Vector3::from(scene.gravity));
    for n in 1500..steps {
        let v: Vec<f64> = (0..nq).map(|k| (q[n][k] - q[n - 1][k]) / dt).collect();
        let a: Vec<f64> = (0..nq).map(|k| (q[n + 1][k] - 2.0 * q[n][k] + q[n - 1][k]) / (dt * dt)).collect();
        inverse_dynamics(model, &dm, &mut data, &q[n], &v, &a, &gravity, &mut pred).unwrap();
        for k in 0..nq {
            pred[k] += scene.arms[0].armature[k] * a[k];
            err[k] += (pred[k] - tau[n][k]).powi(2);
            size[k] += tau[n][k].powi(2);
        }
    }
    err.iter().zip(&size).map(|(e, s)| (e / s.max(1e-300)).sqrt()).collect()
}

/// rapier's implicit Coriolis acts on the tree's free accelerations, before the loop constraints
/// correct them (the parallelogram's links falling freely under gravity); `Coriolis::Explicit`
/// moves it back onto the velocity a step starts with. Measured at the scene's 1 ms, relative
/// residual (yaw, pitch, insertion, roll, wrist pitch, wrist yaw): implicit 3.6e-3 7.5e-4 2.9e-3
/// 6.6e-3 1.8e-3 1.3e-2, explicit 1.4e-3 9.2e-4 5.0e-3 6.3e-3 3.4e-4 1.3e-2. The insertion's gets
/// worse (the counterweight cable's 200 rad/s mode in the free acceleration, which the
/// compensation applies a step late); the roll's and wrist yaw's are something else.
#[test]
fn explicit_coriolis_efforts_match_newton_euler_in_motion() {
    let implicit = tracking_residual(Coriolis::Implicit);
    let explicit = tracking_residual(Coriolis::Explicit);
    let show = |v: &[f64]| v.iter().map(|x| format!("{x:.2e}")).collect::<Vec<_>>().join(" ");
    println!("relative residual per joint, implicit {}\n                             explicit {}", show(&implicit), show(&explicit));
    assert!(explicit[0] < 0.5 * implicit[0] && explicit[0] < 2e-3, "yaw: {} vs {}", explicit[0], implicit[0]);
    assert!(explicit[4] < 0.3 * implicit[4] && explicit[4] < 5e-4, "wrist pitch: {} vs {}", explicit[4], implicit[4]);
}
