// The signature tests, included once per engine by `tests/sim/effects.rs`.

use dvrk_sim::{Gains, Scene, Sim, SimOptions};

/// Built-in scene `name` on the engine under test.
fn load(name: &str) -> Scene {
    let mut scene = Scene::load(name).unwrap();
    scene.engine = Some(ENGINE);
    scene
}
use std::path::Path;

/// The PSM scene with `effects` (TOML `[[effects]]` tables) added to its model.
fn psm_with(effects: &str) -> Scene {
    let text = format!("{}\n{effects}", dvrk_sim::dvrk_kin::load::builtin_text("psm").unwrap());
    let model = dvrk_sim::dvrk_kin::load::load_toml_text(&text, Path::new("psm-effects.toml"), None, None).unwrap();
    let mut scene = load("psm");
    scene.set_model(0, model).unwrap();
    scene
}

/// Steps of the yaw following `a sin(2 pi f t)` about home (others holding), gravity off:
/// per step (measured q, link q, link qd, yaw effort).
fn yaw_sine(scene: &Scene, a: f64, f: f64, seconds: f64) -> Vec<(f64, f64, f64, f64)> {
    let mut sim = Sim::new(scene, &SimOptions { no_gravity: true, ..Default::default() }).unwrap();
    let w = 2.0 * std::f64::consts::PI * f;
    let steps = (seconds / sim.dt) as usize;
    let mut out = Vec::with_capacity(steps);
    for s in 1..=steps {
        let t = s as f64 * sim.dt;
        sim.set_target(0, a * (w * t).sin(), a * w * (w * t).cos()).unwrap();
        sim.step();
        out.push((sim.q()[0], sim.q_link()[0], sim.qd()[0], sim.effort(0).unwrap()));
    }
    out
}

/// Steps of joint `joint` following `a sin(2 pi 0.2 t)` for 10 s (the others holding home),
/// gravity off: per step (measured q, measured qd, every joint's effort).
fn joint_sine(scene: &Scene, joint: usize, a: f64) -> Vec<(Vec<f64>, Vec<f64>, Vec<f64>)> {
    let mut sim = Sim::new(scene, &SimOptions { no_gravity: true, ..Default::default() }).unwrap();
    let w = 2.0 * std::f64::consts::PI * 0.2;
    let steps = (10.0 / sim.dt) as usize;
    (1..=steps)
        .map(|s| {
            let t = s as f64 * sim.dt;
            sim.set_target(joint, a * (w * t).sin(), a * w * (w * t).cos()).unwrap();
            sim.step();
            (sim.q().to_vec(), sim.qd().to_vec(), (0..sim.nq()).map(|i| sim.effort(i).unwrap()).collect())
        })
        .collect()
}

#[test]
fn coulomb_friction_is_a_torque_step_with_the_velocity_sign() {
    let fc = 0.3;
    let base = yaw_sine(&load("psm"), 0.3, 0.2, 10.0);
    let with = yaw_sine(&psm_with(&format!("[[effects]]\nname = \"coulomb_friction\"\njoint = \"outer_yaw\"\nparameters = {{ fc = {fc} }}\n")), 0.3, 0.2, 10.0);
    // Past the first second, wherever the yaw moves faster than 0.05 rad/s: the extra effort
    // the PID needs is fc with the velocity's sign.
    let steps: Vec<f64> = with.iter().zip(&base).skip(1000).filter(|(w, _)| w.2.abs() > 0.05).map(|(w, b)| (w.3 - b.3) * w.2.signum()).collect();
    let mean = steps.iter().sum::<f64>() / steps.len() as f64;
    let worst = steps.iter().map(|x| (x - fc).abs()).fold(0.0, f64::max);
    eprintln!("Coulomb: extra effort x sign(qd) = {mean:.4} N·m (fc {fc}), worst deviation {worst:.4} over {} samples", steps.len());
    assert!((mean - fc).abs() < 0.03 * fc && worst < 0.2 * fc, "{mean} {worst}");
}

/// A Coulomb friction at the jaw's actuator (7), which the wrist yaw's motion turns (the
/// coupling's `a7 = (C^-1 q)_7` holds the wrist yaw): driving the wrist yaw alone, the PID needs
/// `w_j fc sign(a7')` more on each joint `j` the actuator's cables reach (`w`: the actuator's row
/// of `C^-1`, virtual work), on the jaw too although the jaw holds still.
#[test]
fn an_actuator_friction_loads_every_joint_its_cables_reach() {
    let fc = 0.05;
    let run = |scene: &Scene| joint_sine(scene, 5, 0.3).into_iter().map(|(_, qd, e)| (qd, e[5], e[6])).collect::<Vec<_>>();
    let with_effect = psm_with(&format!("[[effects]]\nname = \"actuator_coulomb_friction\"\nactuator = 7\nparameters = {{ fc = {fc} }}\n"));
    let inv = with_effect.arms[0].model.coupling_matrix().unwrap().try_inverse().unwrap();
    let (base, with) = (run(&load("psm")), run(&with_effect));
    for (j, pick) in [(5, 1), (6, 2)] {
        let steps: Vec<f64> = with
            .iter()
            .zip(&base)
            .skip(1000)
            .filter_map(|(x, b)| {
                let a7: f64 = (0..7).map(|k| inv[(6, k)] * x.0[k]).sum();
                let (ex, eb) = if pick == 1 { (x.1, b.1) } else { (x.2, b.2) };
                (a7.abs() > 0.05).then(|| (ex - eb) * a7.signum())
            })
            .collect();
        let mean = steps.iter().sum::<f64>() / steps.len() as f64;
        let want = inv[(6, j)] * fc;
        eprintln!("jaw actuator friction on joint {j}: extra effort x sign(a7') = {mean:.5} N·m (w fc = {want:.5}) over {} samples", steps.len());
        assert!((mean - want).abs() < 0.05 * want.abs(), "joint {j}: {mean} vs {want}");
    }
}

/// The Coulomb level's winding term (`fq`: `fc + fq q^2`, what `dvrk identify` fits on the
/// pitch and insertion) and a cross spring between the wrist's actuators (`actuator_cross_spring`
/// on actuator 6 from actuator 5's position) are physics: driving the yaw, the PID's extra
/// effort times the velocity's sign is `fc + fq q^2`; driving the wrist pitch, the wrist yaw's
/// extra effort follows `w k5 a5` (`w` actuator 6's row of `C^-1` at the wrist yaw).
#[test]
fn a_winding_friction_and_a_cross_spring_load_the_drives_as_their_laws_say() {
    // (The sim smooths the sign over the level's largest value in the joint's range, 0.48 N·m
    // here, to keep its explicit step stable: faster than 0.2 rad/s the sign is whole.)
    let (fc, fq) = (0.1, 0.15);
    let base = yaw_sine(&load("psm"), 0.4, 0.2, 10.0);
    let with = yaw_sine(&psm_with(&format!("[[effects]]\nname = \"coulomb_friction\"\njoint = \"outer_yaw\"\nparameters = {{ fc = {fc}, fq = {fq} }}\n")), 0.4, 0.2, 10.0);
    let off: Vec<f64> = with.iter().zip(&base).skip(1000).filter(|(w, _)| w.2.abs() > 0.2).map(|(w, b)| (w.3 - b.3) * w.2.signum() - (fc + fq * w.1 * w.1)).collect();
    let worst = off.iter().map(|x| x.abs()).fold(0.0, f64::max);
    let mean = off.iter().sum::<f64>() / off.len() as f64;
    eprintln!("winding: extra effort x sign(qd) - (fc + fq q^2): mean {mean:.4}, worst {worst:.4} N·m over {} samples", off.len());
    assert!(mean.abs() < 0.03 * fc && worst < 0.2 * (fc + fq * 0.16), "{mean} {worst}");
    let k5 = 0.05;
    let run = |scene: &Scene| joint_sine(scene, 4, 0.4).into_iter().map(|(q, _, e)| (q, e[5])).collect::<Vec<_>>();
    let with_effect = psm_with(&format!("[[effects]]\nname = \"actuator_cross_spring\"\nactuator = 6\nparameters = {{ k5 = {k5} }}\n"));
    let inv = with_effect.arms[0].model.coupling_matrix().unwrap().try_inverse().unwrap();
    let (base, with) = (run(&load("psm")), run(&with_effect));
    // Least squares slope of the extra effort on a5 (through 0: a5 is 0 at home).
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for (x, b) in with.iter().zip(&base).skip(1000) {
        let a5: f64 = (0..7).map(|k| inv[(4, k)] * x.0[k]).sum();
        sxy += a5 * (x.1 - b.1);
        sxx += a5 * a5;
    }
    let (slope, want) = (sxy / sxx, inv[(5, 5)] * k5);
    eprintln!("cross spring: wrist yaw extra effort / a5 = {slope:.5} N·m/rad (w k5 = {want:.5})");
    assert!(want.abs() > 1e-3 && (slope - want).abs() < 0.05 * want.abs(), "{slope} vs {want}");
}

/// A presliding (Dahl) friction on the yaw: the extra effort the PID needs is `fd z`, `z` the Dahl
/// state along the link's own path, through each reversal too, where a sliding friction (`fd
/// sign(qd)`, what a stateless law gives) would jump.
#[test]
fn a_presliding_friction_turns_over_along_the_dahl_state_at_each_reversal() {
    let (fd, sigma) = (0.2, 0.02);
    let base = yaw_sine(&load("psm"), 0.3, 0.2, 10.0);
    let with = yaw_sine(&psm_with(&format!("[[effects]]\nname = \"coulomb_friction\"\njoint = \"outer_yaw\"\nparameters = {{ fc = 0.0, fd = {fd}, sigma = {sigma} }}\n")), 0.3, 0.2, 10.0);
    let path: Vec<f64> = with.iter().map(|w| w.1).collect();
    let z = dvrk_sim::dvrk_kin::presliding::dahl_state(&path, sigma);
    let (mut worst, mut turning) = (0.0f64, 0);
    for ((w, b), z) in with.iter().zip(&base).zip(&z).skip(1000) {
        worst = worst.max((w.3 - b.3 - fd * z).abs());
        turning += (z.abs() < 0.5) as usize;
    }
    eprintln!("presliding: extra effort - fd z worst {worst:.4} N·m over {} samples, {turning} of them turning over", with.len() - 1000);
    assert!(turning > 100 && worst < 0.1 * fd, "{worst} over {turning} turning samples");
}

#[test]
fn compliance_deflects_in_proportion_to_the_load() {
    // The pitch holds home against gravity (1.12 N·m): the motor (encoder) holds the target,
    // the link sags by load / stiffness.
    let mut ratios = Vec::new();
    for k in [200.0, 400.0] {
        let scene = psm_with(&format!("[[effects]]\nname = \"joint_compliance\"\njoint = \"outer_pitch\"\nparameters = {{ stiffness = {k} }}\n"));
        let mut sim = Sim::new(&scene, &SimOptions::default()).unwrap();
        for i in 0..sim.nq() {
            let g = sim.actuator(i).unwrap().gains;
            sim.set_gains(i, Gains { ki: g.kp * 2.0, ..g }).unwrap();
        }
        for _ in 0..8000 {
            sim.step();
        }
        let deflection = sim.q()[1] - sim.q_link()[1];
        let load = sim.effort(1).unwrap();
        eprintln!("compliance k = {k}: deflection {deflection:.5} rad under {load:.4} N·m (load / k = {:.5})", load / k);
        assert!((deflection * k / load - 1.0).abs() < 0.02, "{deflection} {load}");
        ratios.push(deflection);
    }
    // Twice as stiff, half the deflection.
    assert!((ratios[0] / ratios[1] - 2.0).abs() < 0.04, "{ratios:?}");
}

#[test]
fn backlash_gives_dead_travel_at_reversals() {
    // The link carries Coulomb friction, so the transmission pushes it in the direction of its
    // motion and the contact changes sides when the motion reverses (on a frictionless inertial
    // load it would change sides where the acceleration reverses, mid-stroke).
    let b = 0.01;
    let effects = format!("[[effects]]\nname = \"backlash\"\njoint = \"outer_yaw\"\nparameters = {{ b = {b} }}\n[[effects]]\nname = \"coulomb_friction\"\njoint = \"outer_yaw\"\nparameters = {{ fc = 0.3 }}\n");
    let run = yaw_sine(&psm_with(&effects), 0.3, 0.2, 10.0);
    // Moving, the motor leads the link by the half play (plus the contact's small stretch).
    let lead = run.iter().skip(1000).filter(|r| r.2.abs() > 0.1).map(|r| (r.0 - r.1).abs()).fold(0.0, f64::max);
    // At each reversal of the motor the link stands while the motor crosses the play: the
    // motor's travel between its reversal and the link's is the dead travel, 2 b.
    let mut travels = Vec::new();
    for i in 1001..run.len() - 1 {
        let (v0, v1) = (run[i - 1].0 - run[i - 2].0, run[i].0 - run[i - 1].0);
        if v0.signum() != v1.signum() && v0 != 0.0 {
            let turn = run[i - 1].0;
            // The link starts back when the motor is 2 b past its turning point: find where
            // the link itself turns (its extreme).
            let sign = -v0.signum();
            let j = (i..run.len().min(i + 2000)).find(|&j| (run[j].1 - run[j - 1].1) * sign > 1e-6).unwrap_or(i);
            travels.push((run[j].0 - turn).abs());
        }
    }
    eprintln!("backlash b = {b}: motor lead while moving {lead:.5} rad; dead travel at reversals {travels:.5?} rad (2b = {})", 2.0 * b);
    assert!(lead > b && lead < 1.2 * b, "{lead}");
    assert!(!travels.is_empty() && travels.iter().all(|t| (t - 2.0 * b).abs() < 0.2 * 2.0 * b), "{travels:?}");
}

#[test]
fn latency_leaves_a_residual_parallel_to_the_velocity() {
    // 10 ms, a tracker-to-encoder latency of the usual size (50 ms would destabilise Table 8's
    // yaw loop, which sees the delayed measurement too).
    let tau = 0.01;
    let run = yaw_sine(&psm_with(&format!("[[effects]]\nname = \"latency\"\nparameters = {{ seconds = {tau} }}\n")), 0.3, 0.2, 10.0);
    // measured - link against the link's velocity (finite differences): slope -tau.
    let dt = 1e-3;
    let pts: Vec<(f64, f64)> = run.windows(2).skip(1000).map(|w| ((w[1].1 - w[0].1) / dt, w[1].0 - w[1].1)).collect();
    let (sxx, sxy) = pts.iter().fold((0.0, 0.0), |(a, b), (x, y)| (a + x * x, b + x * y));
    let slope = sxy / sxx;
    let resid = (pts.iter().map(|(x, y)| (y - slope * x).powi(2)).sum::<f64>() / pts.len() as f64).sqrt();
    let size = (pts.iter().map(|(_, y)| y * y).sum::<f64>() / pts.len() as f64).sqrt();
    eprintln!("latency {tau} s: residual = {slope:.4} s x velocity, unexplained {resid:.2e} of {size:.2e} rad RMS");
    assert!((slope + tau).abs() < 0.03 * tau && resid < 0.05 * size, "{slope} {resid} {size}");
    // Exactly: the measurement is the link's state tau ago.
    let lag = (tau / dt).round() as usize;
    let worst = (1000 + lag..run.len()).map(|i| (run[i].0 - run[i - lag].1).abs()).fold(0.0, f64::max);
    assert!(worst < 1e-12, "{worst}");
}

#[test]
fn a_joint_spring_needs_effort_in_proportion_to_the_displacement() {
    let k = 0.05;
    let hold = |scene: &Scene| {
        let mut sim = Sim::new(scene, &SimOptions { no_gravity: true, ..Default::default() }).unwrap();
        sim.set_target(3, 0.5, 0.0).unwrap();
        let g = sim.actuator(3).unwrap().gains;
        sim.set_gains(3, Gains { ki: g.kp * 2.0, ..g }).unwrap();
        for _ in 0..6000 {
            sim.step();
        }
        (sim.q()[3], sim.effort(3).unwrap())
    };
    let (q0, e0) = hold(&load("psm"));
    let (q1, e1) = hold(&psm_with(&format!("[[effects]]\nname = \"spring\"\njoint = \"outer_roll\"\nparameters = {{ k = {k} }}\n")));
    eprintln!("spring k = {k}: roll at {q1:.5} rad needs {e1:.5} N·m (without: {e0:.2e} at {q0:.5}); k q = {:.5}", k * q1);
    assert!(((e1 - e0) / (k * q1) - 1.0).abs() < 0.01, "{e0} {e1}");
}

/// The PID's efforts on joints 0-2 holding `scene`'s PSM at a pose against gravity (integral
/// gain raised so the hold settles), and dvrk-kin's Newton-Euler gravity torque there with the
/// model's effect inertias.
fn held_against_gravity(scene: &Scene) -> ([f64; 3], [f64; 3]) {
    let (pid, ne, _) = hold_pose(scene);
    (std::array::from_fn(|k| pid[k]), std::array::from_fn(|k| ne[k]))
}

/// The pose the gravity tests hold (rad, m).
const HOLD: [f64; 7] = [0.3, -0.2, 0.15, 0.0, 0.4, 0.0, 0.3];

/// [`held_against_gravity`] on every joint, with the true joints (`Sim::q_link`) held at.
fn hold_pose(scene: &Scene) -> ([f64; 7], [f64; 7], [f64; 7]) {
    use dvrk_sim::dvrk_kin::{gravity_torque, DynamicsData, DynamicsModel};
    let arm = &scene.arms[0];
    let model = &arm.model;
    let inertias = dvrk_sim::dvrk_kin::effects::effect_inertias(model, &model.effects, &arm.inertials.body_inertias(model).unwrap()).unwrap();
    let dm = DynamicsModel::new(model, inertias).unwrap();
    let mut data = DynamicsData::new(model);
    let mut sim = Sim::new(scene, &SimOptions::default()).unwrap();
    for (i, x) in HOLD.iter().enumerate() {
        sim.set_target(i, *x, 0.0).unwrap();
        let g = sim.actuator(i).unwrap().gains;
        sim.set_gains(i, Gains { ki: g.kp * 2.0, ..g }).unwrap();
    }
    for _ in 0..8000 {
        sim.step();
    }
    let mut g = vec![0.0; model.nq()];
    gravity_torque(model, &dm, &mut data, sim.q(), &nalgebra::Vector3::from(scene.gravity), &mut g).unwrap();
    (std::array::from_fn(|k| sim.effort(k).unwrap()), std::array::from_fn(|k| g[k]), std::array::from_fn(|k| sim.q_link()[k]))
}

#[test]
fn a_payload_adds_the_gravity_torque_of_its_mass() {
    let (pid, ne) = held_against_gravity(&psm_with("[[effects]]\nname = \"payload_mass\"\nlink = 7\nparameters = { mass = 0.2, z = 0.05 }\n"));
    for k in 0..3 {
        eprintln!("payload 0.2 kg: joint {k}: PID {:.5}, Newton-Euler {:.5}", pid[k], ne[k]);
        assert!((pid[k] - ne[k]).abs() < 0.01 * ne[k].abs() + 2e-3, "joint {k}: {} vs {}", pid[k], ne[k]);
    }
}

/// A heavier counterweight travelling further: the insertion's and the pitch's holding efforts
/// move by what Newton-Euler gives for the new mass and `mu`; on the insertion, by the closed
/// form `-(m' mu' - m mu) g . z11` (the counterweight slides along its frame's z, `mu` per metre
/// of insertion).
#[test]
fn a_counterweight_error_moves_the_gravity_efforts_by_its_mass_and_travel() {
    let (mu, mass) = (0.7, 0.6);
    let nominal = load("psm");
    let scene = psm_with(&format!("[[effects]]\nname = \"counterweight_error\"\nparameters = {{ mu = {mu}, mass = {mass} }}\n"));
    let (pid0, _) = held_against_gravity(&nominal);
    let (pid, ne) = held_against_gravity(&scene);
    for k in 0..3 {
        eprintln!("counterweight mu {mu}, {mass} kg: joint {k}: PID {:.5} (nominal {:.5}), Newton-Euler {:.5}", pid[k], pid0[k], ne[k]);
        assert!((pid[k] - ne[k]).abs() < 0.01 * ne[k].abs() + 2e-3, "joint {k}: {} vs {}", pid[k], ne[k]);
    }
    let model = &nominal.arms[0].model;
    let cw = model.frame_id(&dvrk_sim::dvrk_kin::FrameRef::Index(11)).unwrap();
    let m0 = nominal.arms[0].inertials.body_inertias(model).unwrap()[model.frames[cw].body].mass;
    let z = model.fk(&HOLD).unwrap()[cw].rotation * nalgebra::Vector3::z();
    let expect = -(mass * mu - m0 * model.spec.parameters["mu"].value) * nalgebra::Vector3::from(nominal.gravity).dot(&z);
    eprintln!("insertion: {:.5} N more (closed form {expect:.5})", pid[2] - pid0[2]);
    assert!(expect.abs() > 0.3 && (pid[2] - pid0[2] - expect).abs() < 0.01 * expect.abs(), "{} vs {expect}", pid[2] - pid0[2]);
}

/// A coupling error (the wrist yaw's cable pulls 0.05 more per radian of the pitch actuator): the
/// controller holds the joints it reads while the true ones sit at `B q` (dvrk-kin's map), and
/// the efforts it needs are the true joints' gravity efforts through `B^T`, which dvrk-kin's
/// inverse dynamics of the model with the error gives. A 0.2 kg payload on the jaw's link
/// makes the wrist's gravity efforts large enough to show it.
#[test]
fn a_coupling_error_moves_the_true_joints_and_maps_the_efforts() {
    let payload = "[[effects]]\nname = \"payload_mass\"\nlink = 16\nparameters = { mass = 0.2, x = 0.03 }\n";
    let (pid0, _, link0) = hold_pose(&psm_with(payload));
    let scene = psm_with(&format!("{payload}[[effects]]\nname = \"coupling_error\"\nparameters = {{ d65 = 0.05 }}\n"));
    let (pid, ne, link) = hold_pose(&scene);
    let b = scene.arms[0].model.coupling_error_map().unwrap();
    for k in 0..7 {
        let expect: f64 = (0..7).map(|j| b[(k, j)] * HOLD[j]).sum();
        eprintln!(
            "coupling error: joint {k}: true {:.6} (B q {expect:.6}, without {:.6}); PID {:.6} (without {:.6}), Newton-Euler {:.6}",
            link[k], link0[k], pid[k], pid0[k], ne[k]
        );
        assert!((link[k] - expect).abs() < 1e-4, "joint {k}: {} vs {expect}", link[k]);
        assert!((pid[k] - ne[k]).abs() < 0.01 * ne[k].abs() + 2e-4, "joint {k}: {} vs {}", pid[k], ne[k]);
    }
}
