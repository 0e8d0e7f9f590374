//! Real-time factor of the Table 9 scenes (psm, ecm, 2psm-ecm, 3psm, full): one simulated second
//! of the section 4.3 tracking test per iteration (each arm as its scene says: the PSMs on the
//! sines, the ECM of the cart scenes and the setup joints holding), dt = 1 ms: single thread
//! (`{scene}_1s_sine`), and for the multi-arm scenes with the arm groups stepped in parallel
//! (`{scene}_1s_sine_parallel`, `SimOptions::parallel`). RTF = 1 s / time per iteration.

use criterion::{criterion_group, criterion_main, Criterion};
use dvrk_sim::scene::Tracking;
use dvrk_sim::trajectory::Trajectory;
use dvrk_sim::{Scene, Sim, SimOptions};

fn one_second(c: &mut Criterion) {
    let mut group = c.benchmark_group("rtf");
    group.sample_size(10);
    let runs = [("psm", false), ("ecm", false), ("2psm-ecm", false), ("3psm", false), ("full", false), ("2psm-ecm", true), ("3psm", true), ("full", true)];
    for (name, parallel) in runs {
        let scene = Scene::load(name).unwrap();
        let mut sim = Sim::new(&scene, &SimOptions { parallel, ..SimOptions::default() }).unwrap();
        let trajectories: Vec<(usize, usize, Trajectory)> = sim
            .arms
            .iter()
            .map(|a| {
                let t = match a.tracking {
                    Tracking::Sine => Trajectory::tracking_test(&a.model).0,
                    Tracking::Hold => Trajectory::Hold { q: a.model.home() },
                };
                (a.q_offset, a.model.nq(), t)
            })
            .collect();
        let n = sim.nq();
        let (mut q, mut qd) = (vec![0.0; n], vec![0.0; n]);
        group.bench_function(format!("{name}_1s_sine{}", if parallel { "_parallel" } else { "" }), |b| {
            b.iter(|| {
                for _ in 0..1000 {
                    for (off, nk, traj) in &trajectories {
                        traj.sample(sim.time + sim.dt, &mut q[*off..off + nk], &mut qd[*off..off + nk]);
                    }
                    for i in 0..n {
                        sim.set_target(i, q[i], qd[i]).unwrap();
                    }
                    sim.step();
                }
            })
        });
    }
    group.finish();
}

criterion_group!(benches, one_second);
criterion_main!(benches);
