//! Real-time factor of the Table 9 scenes (psm, ecm, 2psm-ecm, 3psm, full, full-camera): one simulated second
//! of the section 4.3 tracking test per iteration (each arm as its scene says: the PSMs on the
//! sines, the ECM of the cart scenes and the setup joints holding), dt = 1 ms: single thread
//! (`{scene}_1s_sine`), and for the multi-arm scenes with the arm groups stepped in parallel
//! (`{scene}_1s_sine_parallel`, `SimOptions::parallel`), on rapier; and on the reduced engine
//! (`{scene}_1s_sine_reduced`, one thread). RTF = 1 s / time per iteration.
//! full-camera is full plus the stereo camera rendering both eyes at 30 Hz inside the loop (no
//! files written); `camera/stereo_frame` times one frame of it (both eyes, with noise).

use criterion::{criterion_group, criterion_main, Criterion};
use dvrk_sim::camera::StereoCamera;
use dvrk_sim::scene::Tracking;
use dvrk_sim::trajectory::Trajectory;
use dvrk_sim::{Engine, Scene, Sim, SimOptions};

fn one_second(c: &mut Criterion) {
    let mut group = c.benchmark_group("rtf");
    group.sample_size(10);
    let (rapier, reduced) = (Engine::Rapier, Engine::Reduced);
    let runs = [
        ("psm", false, rapier),
        ("ecm", false, rapier),
        ("2psm-ecm", false, rapier),
        ("3psm", false, rapier),
        ("full", false, rapier),
        ("full-camera", false, rapier),
        ("2psm-ecm", true, rapier),
        ("3psm", true, rapier),
        ("full", true, rapier),
        ("full-camera", true, rapier),
        ("psm", false, reduced),
        ("ecm", false, reduced),
        ("2psm-ecm", false, reduced),
        ("3psm", false, reduced),
        ("full", false, reduced),
    ];
    for (name, parallel, engine) in runs {
        let scene = Scene::load(name).unwrap();
        let mut sim = Sim::new(&scene, &SimOptions { parallel, engine: Some(engine), ..SimOptions::default() }).unwrap();
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
        let mut camera = scene.camera.as_ref().map(|c| StereoCamera::new(c, &sim, name).unwrap());
        if let Some(c) = camera.as_mut() {
            c.parallel = parallel;
        }
        let n = sim.nq();
        let (mut q, mut qd) = (vec![0.0; n], vec![0.0; n]);
        let suffix = match (parallel, engine) {
            (_, Engine::Reduced) => "_reduced",
            (true, _) => "_parallel",
            _ => "",
        };
        group.bench_function(format!("{name}_1s_sine{suffix}"), |b| {
            b.iter(|| {
                for _ in 0..1000 {
                    for (off, nk, traj) in &trajectories {
                        traj.sample(sim.time + sim.dt, &mut q[*off..off + nk], &mut qd[*off..off + nk]);
                    }
                    for i in 0..n {
                        sim.set_target(i, q[i], qd[i]).unwrap();
                    }
                    sim.step();
                    if let Some(c) = camera.as_mut() {
                        c.after_step(&sim);
                    }
                }
            })
        });
    }
    group.finish();
}

fn stereo_frame(c: &mut Criterion) {
    let scene = Scene::load("full-camera").unwrap();
    let sim = Sim::new(&scene, &SimOptions::default()).unwrap();
    let mut camera = StereoCamera::new(scene.camera.as_ref().unwrap(), &sim, "full-camera").unwrap();
    let mut group = c.benchmark_group("camera");
    group.sample_size(20);
    group.bench_function("stereo_frame", |b| b.iter(|| camera.capture(&sim)));
    group.finish();
}

criterion_group!(benches, one_second, stereo_frame);
criterion_main!(benches);
