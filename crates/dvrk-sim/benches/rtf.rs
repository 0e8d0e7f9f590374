//! Real-time factor of the Table 9 scenes built so far (psm, ecm): one simulated second of the
//! section 4.3 tracking test per iteration, single thread, dt = 1 ms. RTF = 1 s / time per iteration.

use criterion::{criterion_group, criterion_main, Criterion};
use dvrk_sim::trajectory::Trajectory;
use dvrk_sim::{Scene, Sim, SimOptions};

fn one_second(c: &mut Criterion) {
    let mut group = c.benchmark_group("rtf");
    group.sample_size(10);
    for name in ["psm", "ecm"] {
        let scene = Scene::load(name).unwrap();
        let mut sim = Sim::new(&scene, &SimOptions::default()).unwrap();
        let (traj, _) = Trajectory::tracking_test(&sim.arms[0].model);
        let n = sim.nq();
        let (mut q, mut qd) = (vec![0.0; n], vec![0.0; n]);
        group.bench_function(format!("{name}_1s_sine"), |b| {
            b.iter(|| {
                for _ in 0..1000 {
                    traj.sample(sim.time + sim.dt, &mut q, &mut qd);
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
