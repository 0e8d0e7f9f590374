//! The loop-closure options table: closure gap, RCM error and real-time factor of the section 4.3
//! tracking test for each solver configuration and closing-link placement.
//!
//! `cargo run --release -p dvrk-sim --example closure_study -- [SCENE] [DURATION_S] [CONFIG...]`
//! CONFIG is `placement:iterations:pgs:stabilization:warmstart`, e.g. `mb:4:1:1:0` (placement
//! `mb` = closing links in the multibody, `free` = free bodies on two impulse joints). Without
//! configs a fixed list is run. The RTF here is one wall-clock sample, indicative only; the
//! criterion bench `rtf` is the reference.

use dvrk_sim::run::TrajectoryKind;
use dvrk_sim::{run, ClosingLinks, RunOptions, Scene, SimOptions};

fn parse(c: &str) -> Option<SimOptions> {
    let f: Vec<&str> = c.split(':').collect();
    let [p, it, pgs, stab, ws] = f.as_slice() else { return None };
    Some(SimOptions {
        closing_links: match *p {
            "mb" => ClosingLinks::InMultibody,
            "free" => ClosingLinks::FreeBodies,
            _ => return None,
        },
        solver_iterations: Some(it.parse().ok()?),
        pgs_iterations: Some(pgs.parse().ok()?),
        stabilization_iterations: Some(stab.parse().ok()?),
        warmstart_joints: Some(*ws == "1"),
        ..Default::default()
    })
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let scene_name = args.first().map(String::as_str).unwrap_or("psm");
    let duration: f64 = args.get(1).and_then(|d| d.parse().ok()).unwrap_or(10.0);
    let default = ["free:4:1:1:0", "free:4:1:1:1", "mb:4:1:1:0", "mb:4:1:1:1", "mb:1:4:1:1", "mb:2:2:1:1", "mb:8:1:1:1"];
    let configs: Vec<String> = if args.len() > 2 { args[2..].to_vec() } else { default.iter().map(|s| s.to_string()).collect() };
    let scene = match Scene::load(scene_name) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(2);
        }
    };
    println!("scene {scene_name}, {duration} s of the tracking test, dt {} s", scene.dt);
    println!("| config | max closure (mm) at (s) | last 10% (mm) | max RCM (mm) | RTF | tracking RMS of joints 1-3 (rad, rad, m) |");
    println!("|---|---|---|---|---|---|");
    for c in &configs {
        let Some(sim) = parse(c) else {
            eprintln!("bad config `{c}` (placement:iterations:pgs:stabilization:warmstart)");
            std::process::exit(2);
        };
        match run(&scene, &RunOptions { duration, trajectory: TrajectoryKind::Sine, sim }, |_| {}) {
            Ok(s) => println!(
                "| {c} | {:.5} at {:.3} | {:.5} | {:.5} | {:.1}{} | {:.2e} {:.2e} {:.2e} |",
                s.max_closure_error * 1e3,
                s.max_closure_time,
                s.final_closure_error * 1e3,
                s.max_rcm_error * 1e3,
                s.real_time_factor,
                if s.finite { "" } else { " (non-finite)" },
                s.joints[0].rms_error,
                s.joints[1].rms_error,
                s.joints[2].rms_error,
            ),
            Err(e) => println!("| {c} | error: {e} | | | |"),
        }
    }
}
