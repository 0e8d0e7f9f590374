//! A million steps of random commands: modes, targets, efforts and gains redrawn every 50 ms
//! leave every state finite. Its own module so that, the longest test of this binary (about a
//! minute), it starts among the first and the others run beside it.

use dvrk_sim::{Gains, Mode, Scene, Sim, SimOptions};
use rand::{Rng, SeedableRng};

fn psm() -> Scene {
    Scene::load("psm").unwrap()
}

/// Random modes, targets, efforts and gains every 50 ms leave every state finite.
fn random_commands(steps: u64) {
    let mut sim = Sim::new(&psm(), &SimOptions::default()).unwrap();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let lim: Vec<(f64, f64)> = sim.arms[0].model.joints.iter().map(|j| (j.lower - 0.5, j.upper + 0.5)).collect();
    for s in 0..steps {
        if s % 50 == 0 {
            for (k, (lo, hi)) in lim.iter().enumerate() {
                let mode = [Mode::Pid, Mode::Effort, Mode::Position][rng.random_range(0..3)];
                sim.set_mode(k, mode).unwrap();
                sim.set_target(k, rng.random_range(*lo..*hi), rng.random_range(-2.0..2.0)).unwrap();
                sim.set_effort(k, rng.random_range(-100.0..100.0)).unwrap();
                let g = Gains { kp: rng.random_range(0.0..400.0), ki: rng.random_range(0.0..1.0), kd: rng.random_range(0.0..10.0) };
                sim.set_gains(k, g).unwrap();
            }
        }
        sim.step();
        assert!(sim.q().iter().chain(sim.qd()).all(|x| x.is_finite()), "step {s}: {:?}", sim.q());
    }
    assert!(sim.closure_error().is_finite());
}

/// The million steps (about a minute in release on 2 cores).
#[test]
fn a_million_random_commands_leave_no_nan() {
    random_commands(1_000_000);
}

