//! The `mtm` scene: the MTMR identified on the real robot (built-in `mtmr-wpi`), held by a gravity
//! compensation fed forward in effort mode (dvrk-kin's `holding_torque` of the same model), and
//! falling without it. The same model on both sides: the hold is exact when the feed-forward
//! takes every static term the physics has (weight, cable springs, cross springs, offsets); the
//! compensation from another recording's identification is tested in dvrk-calib (identify_mtm).

use dvrk_kin::dynamics::{holding_torque, DynamicsData, DynamicsModel};
use dvrk_sim::{Mode, Scene, Sim, SimOptions};
use nalgebra::Vector3;

/// Ten poses spread over the middle 60% of each joint's range (a fixed Weyl sequence).
pub(crate) fn poses(model: &dvrk_kin::Model) -> Vec<Vec<f64>> {
    (0..10)
        .map(|i| model.joints.iter().enumerate().map(|(j, jt)| jt.lower + (jt.upper - jt.lower) * (0.2 + 0.6 * ((i as f64 + 0.5) * (2.0f64.sqrt() * (j + 1) as f64)).fract())).collect())
        .collect()
}

/// Drift (rad, the largest joint's) after `seconds` in effort mode from rest at `q0`, the
/// effort each step the holding torque at the measured joints (`compensate`) or zero.
pub(crate) fn drift(scene: &Scene, q0: &[f64], compensate: bool, seconds: f64) -> f64 {
    let mut scene = scene.clone();
    scene.set_start(0, q0).unwrap();
    let arm = &scene.arms[0];
    let model = arm.model.clone();
    let dm = DynamicsModel::new(&model, arm.inertials.body_inertias(&model).unwrap()).unwrap();
    let mut data = DynamicsData::new(&model);
    let g = Vector3::from(scene.gravity);
    let mut sim = Sim::new(&scene, &SimOptions::default()).unwrap();
    let n = model.nq();
    for i in 0..n {
        sim.set_mode(i, Mode::Effort).unwrap();
    }
    let mut tau = vec![0.0; n];
    for _ in 0..(seconds / scene.dt).round() as usize {
        if compensate {
            holding_torque(&model, &dm, &mut data, &sim.q()[..n], &g, &mut tau).unwrap();
        }
        for (i, t) in tau.iter().enumerate() {
            sim.set_effort(i, *t).unwrap();
        }
        sim.step();
    }
    sim.q()[..n].iter().zip(q0).map(|(q, q0)| (q - q0).abs()).fold(0.0, f64::max)
}

#[test]
fn the_identified_mtm_holds_ten_poses_with_gravity_compensation_and_falls_without() {
    let mut scene = Scene::load("mtm").unwrap();
    // Feed-forward only, computed here each step: the scene's own controller adds nothing.
    scene.arms[0].gravity_compensation = false;
    let (mut held, mut fell) = (0.0f64, f64::INFINITY);
    for q0 in poses(&scene.arms[0].model) {
        let (with, without) = (drift(&scene, &q0, true, 5.0), drift(&scene, &q0, false, 5.0));
        eprintln!("pose {q0:.2?}: drift after 5 s {with:.2e} rad compensated, {without:.2e} rad without");
        held = held.max(with);
        fell = fell.min(without);
    }
    assert!(held < 1e-9, "compensated drift {held} rad");
    assert!(fell > 0.1, "uncompensated drift {fell} rad");
}
