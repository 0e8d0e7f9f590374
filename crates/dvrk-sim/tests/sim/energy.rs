//! Issue 3, must-show 4b: with the actuators and all damping off (joint damping and the cables'
//! dampers), the total energy (bodies, drive armature, cable springs) is conserved over 10 s on
//! rapier; issue 42: over 60 s on the reduced engine, with no secular drift.
//!
//! Gravity is off: under gravity every arm of these scenes falls onto a joint limit within a
//! second (the PSM pitch onto +0.93 rad, the ECM pitch likewise), and a limit is an inelastic
//! contact that takes energy out by design. The gravity side of the dynamics is checked against
//! the independent inverse dynamics in the `sim` module (steady PID efforts = gravity torques).
//! Each joint gets a 0.1 s effort kick sized so that nothing reaches a limit in 10 s; the motion
//! then runs free: the yaw spins the pitch loops, the insertion drives the counterweight cable,
//! the wrist and both jaw blades move (the second blade by its cable).

use dvrk_sim::{Engine, Mode, Scene, Sim, SimOptions};

/// Energy (J) sampled every 10 ms over `seconds` after the kick on `engine`, and the joint
/// ranges seen.
fn free_run(scene: &str, kick: &[f64], seconds: f64, cable_damping: f64, engine: Engine) -> (Vec<f64>, Vec<(f64, f64)>) {
    let scene = Scene::load(scene).unwrap();
    let mut sim = Sim::new(&scene, &SimOptions { no_gravity: true, engine: Some(engine), ..Default::default() }).unwrap();
    sim.set_damping_and_armature(0.0, 1.0).unwrap();
    sim.set_cable_damping_scale(cable_damping).unwrap();
    for (i, f) in kick.iter().enumerate() {
        sim.set_mode(i, Mode::Effort).unwrap();
        sim.set_effort(i, *f).unwrap();
    }
    for _ in 0..100 {
        sim.step();
    }
    for i in 0..sim.nq() {
        sim.set_effort(i, 0.0).unwrap();
    }
    // One step with the kick gone: rapier's body velocities lag the efforts by a step.
    sim.step();
    let mut range: Vec<(f64, f64)> = sim.q().iter().map(|q| (*q, *q)).collect();
    let mut energy = vec![sim.energy()];
    let steps = (seconds / sim.dt).round() as usize;
    for s in 1..=steps {
        sim.step();
        for (r, q) in range.iter_mut().zip(sim.q()) {
            *r = (r.0.min(*q), r.1.max(*q));
        }
        if s % 10 == 0 {
            energy.push(sim.energy());
        }
    }
    (energy, range)
}

fn check_limits(scene: &str, range: &[(f64, f64)]) {
    let scene = Scene::load(scene).unwrap();
    for (j, (lo, hi)) in scene.arms[0].model.joints.iter().zip(range) {
        assert!(*lo > j.lower + 1e-3 && *hi < j.upper - 1e-3, "{} reached a limit: [{lo}, {hi}] in [{}, {}]", j.name, j.lower, j.upper);
    }
}

fn span(e: &[f64]) -> f64 {
    let (lo, hi) = e.iter().fold((f64::MAX, f64::MIN), |(a, b), x| (a.min(*x), b.max(*x)));
    (hi - lo) / e[0]
}

#[test]
fn psm_energy_is_conserved_with_actuators_and_damping_off() {
    let kick = [0.05, 0.05, 0.05, 0.005, 0.003, 0.003, 0.001];
    let (e, range) = free_run("psm", &kick, 10.0, 0.0, Engine::Rapier);
    check_limits("psm", &range);
    let moved: Vec<f64> = range.iter().map(|(a, b)| b - a).collect();
    eprintln!("PSM: E0 {:.4e} J, energy span over 10 s {:.4}%, joint travel {moved:.3?}", e[0], span(&e) * 100.0);
    // Every joint moves (the loops, both cables and the wrist all take part).
    assert!(moved.iter().all(|m| *m > 0.05), "{moved:?}");
    assert!(span(&e) < 0.005, "{}", span(&e));
    // The cables' dampers, on, put no energy in (a damper fed forward on one side only did, and
    // the arm blew up within a second once the joint damping was off).
    let (e, _) = free_run("psm", &kick, 10.0, 1.0, Engine::Rapier);
    let end = e[e.len() - 1] / e[0] - 1.0;
    eprintln!("PSM with cable dampers: energy {:.6e} -> {:.6e} J over 10 s ({:+.4}%)", e[0], e[e.len() - 1], end * 100.0);
    assert!(end < 1e-4 && span(&e) < 0.005, "{end}");
}

#[test]
fn ecm_energy_is_conserved_with_actuators_and_damping_off() {
    let (e, range) = free_run("ecm", &[0.5, 0.0, 0.0, 0.0], 10.0, 0.0, Engine::Rapier);
    check_limits("ecm", &range);
    eprintln!("ECM: E0 {:.4e} J, energy span over 10 s {:.4}%", e[0], span(&e) * 100.0);
    assert!(range[0].1 - range[0].0 > 0.3 && range[1].1 - range[1].0 > 0.05, "{range:?}");
    assert!(span(&e) < 0.005, "{}", span(&e));
}

/// Relative change of the mean energy from the first to the last tenth of the run (the drift),
/// and the largest excursion from the start (the semi-implicit step's bounded oscillation).
fn drift(e: &[f64]) -> (f64, f64) {
    let k = e.len() / 10;
    let mean = |s: &[f64]| s.iter().sum::<f64>() / s.len() as f64;
    let excursion = e.iter().map(|x| (x / e[0] - 1.0).abs()).fold(0.0, f64::max);
    (mean(&e[e.len() - k..]) / mean(&e[..k]) - 1.0, excursion)
}

/// Issue 42: the reduced engine, actuators and damping off, shows no secular drift over 60 s.
#[test]
fn the_reduced_engine_shows_no_energy_drift_over_60_s() {
    // Kicks small enough that nothing meets a stop (an inelastic stop) in 60 s.
    for (scene, kick) in [("psm", &[0.012, 0.012, 0.004, 0.0012, 0.0008, 0.0008, 0.0003][..]), ("ecm", &[0.1, 0.05, 0.005, 0.01][..])] {
        let (e, range) = free_run(scene, kick, 60.0, 0.0, Engine::Reduced);
        check_limits(scene, &range);
        assert!(range.iter().all(|(a, b)| b - a > 0.01), "{scene}: a joint did not move: {range:?}");
        let (d, x) = drift(&e);
        eprintln!("{scene} (reduced): E0 {:.4e} J; 60 s: drift {:+.2e}, largest excursion {:.2e}", e[0], d, x);
        assert!(e[0] > 1e-6, "{scene}: the kick moved nothing");
        assert!(d.abs() < 1e-3 && x < 5e-3, "{scene}: drift {d}, excursion {x}");
    }
}
