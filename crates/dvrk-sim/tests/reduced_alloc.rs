//! The reduced engine's step allocates nothing (issue 42): a counting global allocator around
//! 1000 steps of each arm scene, PID on the tracking sine. Its own test binary, one test: the
//! count is process-wide.

use dvrk_sim::{Engine, Scene, Sim, SimOptions};
use stats_alloc::{Region, StatsAlloc, INSTRUMENTED_SYSTEM};
use std::alloc::System;

#[global_allocator]
static GLOBAL: &StatsAlloc<System> = &INSTRUMENTED_SYSTEM;

#[test]
fn a_reduced_step_allocates_nothing() {
    for name in ["psm", "ecm", "3psm", "2psm-ecm"] {
        let scene = Scene::load(name).unwrap();
        let mut sim = Sim::new(&scene, &SimOptions { engine: Some(Engine::Reduced), ..Default::default() }).unwrap();
        let home: Vec<f64> = sim.q().to_vec();
        let region = Region::new(GLOBAL);
        for s in 0..1000 {
            let t = s as f64 * sim.dt;
            for (i, h) in home.iter().enumerate() {
                sim.set_target(i, h + 0.1 * (t * 3.0).sin(), 0.3 * (t * 3.0).cos()).unwrap();
            }
            sim.step();
        }
        let change = region.change();
        let n = change.allocations + change.reallocations;
        assert!(sim.check_finite().is_ok());
        assert_eq!(n, 0, "{name}: {n} allocations in 1000 steps");
    }
}
