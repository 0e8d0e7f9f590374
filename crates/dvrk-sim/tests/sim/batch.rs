//! `BatchSim`: copies that share nothing, each stepping exactly as a lone `Sim` given the same
//! commands, whatever the thread count; per-copy reset and models; bad commands refused whole.

use dvrk_sim::{BatchSim, Engine, Scene, Sim, SimOptions};
use std::path::Path;

fn reduced() -> SimOptions {
    SimOptions { engine: Some(Engine::Reduced), ..Default::default() }
}

/// Copy `c`'s commands at step `s`: a different sine per copy and joint about home.
fn command(home: &[f64], c: usize, s: usize, dt: f64) -> Vec<(f64, f64)> {
    let t = s as f64 * dt;
    home.iter().enumerate().map(|(j, h)| {
        let w = 2.0 + c as f64 + 0.3 * j as f64;
        (h + 0.05 * (w * t).sin(), 0.05 * w * (w * t).cos())
    }).collect()
}

/// Run `n` copies for `steps` steps of 10 on `threads` threads; the flat q after each call.
fn run_batch(scene: &Scene, n: usize, threads: usize, steps: usize) -> (Vec<Vec<f64>>, BatchSim) {
    let mut b = BatchSim::new(scene, n, &reduced(), threads).unwrap();
    let (nq, dt, home) = (b.nq(), b.dt(), b.q()[..b.nq()].to_vec());
    let mut out = Vec::new();
    for s in 0..steps {
        for c in 0..n {
            for (j, (p, v)) in command(&home, c, s * 10, dt).into_iter().enumerate() {
                b.target_mut()[c * nq + j] = p;
                b.target_velocity_mut()[c * nq + j] = v;
            }
        }
        b.step(10).unwrap();
        out.push(b.q().to_vec());
    }
    (out, b)
}

#[test]
fn each_copy_steps_exactly_as_a_lone_sim_on_any_thread_count() {
    let scene = Scene::load("psm").unwrap();
    let (n, steps) = (5, 30);
    let (one, _) = run_batch(&scene, n, 1, steps);
    let (two, b) = run_batch(&scene, n, 2, steps);
    assert_eq!(b.threads(), 2);
    assert_eq!(one, two, "the thread count changed a result");
    let nq = b.nq();
    for c in 0..n {
        let mut sim = Sim::new(&scene, &reduced()).unwrap();
        let home = sim.q().to_vec();
        for s in 0..steps {
            for (j, (p, v)) in command(&home, c, s * 10, sim.dt).into_iter().enumerate() {
                sim.set_target(j, p, v).unwrap();
            }
            for _ in 0..10 {
                sim.step();
            }
            assert_eq!(sim.q(), &one[s][c * nq..(c + 1) * nq], "copy {c}, call {s}");
        }
    }
    // The copies did move, and differently.
    let last = &one[steps - 1];
    assert!((0..nq).any(|j| (last[j] - last[nq + j]).abs() > 1e-3), "{last:?}");
}

#[test]
fn a_copy_resets_and_takes_its_own_model_without_touching_the_others() {
    let scene = Scene::load("psm").unwrap();
    let (_, mut b) = run_batch(&scene, 3, 2, 5);
    let nq = b.nq();
    let before: Vec<f64> = b.q().to_vec();
    let start: Vec<f64> = {
        let home = Sim::new(&scene, &reduced()).unwrap().q().to_vec();
        home.iter().enumerate().map(|(j, h)| if j < 2 { h + 0.2 } else { *h }).collect()
    };
    b.reset(1, Some(&start)).unwrap();
    assert_eq!(&b.q()[nq..2 * nq], &start[..], "copy 1 at its new start");
    assert_eq!(b.sim(1).unwrap().time, 0.0);
    assert_eq!((&b.q()[..nq], &b.q()[2 * nq..]), (&before[..nq], &before[2 * nq..]), "the others untouched");
    b.reset(1, None).unwrap();
    assert_eq!(&b.q()[nq..2 * nq], &Sim::new(&scene, &reduced()).unwrap().q()[..], "back to the scene's own start");
    // A 300 g payload on copy 2's instrument: holding home needs more pitch effort there only.
    let text = format!("{}\n[[effects]]\nname = \"payload_mass\"\nlink = \"pitch_end\"\nparameters = {{ mass = 0.3, y = -0.2 }}\n", dvrk_sim::dvrk_kin::load::builtin_text("psm").unwrap());
    let model = dvrk_sim::dvrk_kin::load::load_toml_text(&text, Path::new("payload.toml"), None, None).unwrap();
    b.set_model(2, 0, model).unwrap();
    b.reset(0, None).unwrap();
    b.step(3000).unwrap();
    let (e0, e2) = (b.effort()[1], b.effort()[2 * nq + 1]);
    eprintln!("pitch effort holding home: {e0:.4} N·m; with the payload {e2:.4} N·m");
    assert!((e2 - e0).abs() > 0.1, "{e0} {e2}");
    assert_eq!(b.effort()[nq..2 * nq], b.effort()[..nq], "copies 0 and 1, both reset to home, alike");
    // Bad input: named, nothing moved.
    let q = b.q().to_vec();
    b.target_mut()[2 * nq + 4] = f64::NAN;
    let e = b.step(1).unwrap_err().to_string();
    assert!(e.contains("target[2, 4]") && e.contains("NaN"), "{e}");
    assert_eq!(b.q(), &q[..]);
    assert!(b.reset(3, None).unwrap_err().to_string().contains("3 copies"));
    assert!(b.reset(0, Some(&[0.0; 3])).unwrap_err().to_string().contains("joints"));
    assert!(BatchSim::new(&scene, 0, &reduced(), 1).is_err());
}
