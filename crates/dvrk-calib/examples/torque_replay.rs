//! Torque-driven replay of the WPI `two` recording on the CAD and the identified PSM (issue 6,
//! must-show 3): per-joint RMS of simulated minus recorded motion, with the CAD scene as shipped
//! and with the identified scene's solver sweeps, and the ablation (identified inertials or
//! identified effects alone). `FB=0.1,0.3,1` sets the feedback fractions.
use dvrk_calib::identify::output::identified_model;
use dvrk_calib::identify::replay::{identified_scene, torque_replay, IDENTIFIED_PGS_ITERATIONS};
use dvrk_calib::identify::{identify, read_wpi_csv, IdentifyOptions};
use std::path::Path;

fn main() {
    let model = dvrk_kin::load("psm", None).unwrap();
    let prior = dvrk_sim::scene::builtin_inertials("psm", &model).unwrap().body_inertias(&model).unwrap();
    let dir = Path::new("../shared/data/external/wpi-dvrk-dynamics");
    let one = read_wpi_csv(&dir.join("psm_one_results.csv"), &model).unwrap();
    let two = read_wpi_csv(&dir.join("psm_two_results.csv"), &model).unwrap();
    let options = IdentifyOptions::for_model(&model);
    let (id, _) = identify(&model, &prior, &one, &options).unwrap();
    let base = dvrk_sim::Scene::load("psm").unwrap();
    let identified = identified_model(&model, &id, &options.processing, &one.joint_map(), &prior, "one").unwrap();
    let scene = identified_scene(&base, 0, &identified).unwrap();
    let mut cad_sweeps = base.clone();
    cad_sweeps.arms[0].pgs_iterations = Some(IDENTIFIED_PGS_ITERATIONS);
    println!("not expressed as effects: {:#?}\nkept prior: {:?}", identified.not_expressed, identified.kept_prior);
    for b in &scene.arms[0].inertials.bodies {
        println!("{:20} m {:.4} com {:.3?} I diag {:.2e} {:.2e} {:.2e}", b.name, b.mass, b.com, b.inertia[0][0], b.inertia[1][1], b.inertia[2][2]);
    }
    let mut inert_only = cad_sweeps.clone();
    inert_only.arms[0].inertials = scene.arms[0].inertials.clone();
    let mut effects_only = scene.clone();
    effects_only.arms[0].inertials = base.arms[0].inertials.clone();
    for (name, sc) in [("identified inertials only", &inert_only), ("identified effects only", &effects_only)] {
        println!("{name:28} rms {:.4?}", torque_replay(sc, 0, &two, 0.3).unwrap().0);
    }
    for fb in std::env::var("FB").unwrap_or("0.1,0.3,1.0".into()).split(',') {
        let fb: f64 = fb.parse().unwrap();
        println!("feedback {fb}:");
        for (name, sc) in [("CAD (12 sweeps)", &base), ("CAD (identified's sweeps)", &cad_sweeps), ("identified", &scene)] {
            let (rms, bias) = torque_replay(sc, 0, &two, fb).unwrap();
            println!("  {name:26} rms {rms:.4?} bias {bias:.4?}");
        }
    }
}
