//! Torque-driven replay of the WPI `two` recording on the CAD and the identified PSM (scratch).
use dvrk_calib::identify::replay::{identified_scene, torque_replay};
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
    let (scene, info) = identified_scene(&base, 0, &model, &id, &options.processing).unwrap();
    for (name, sc) in [("CAD", &base), ("identified", &scene)] {
        let m = &sc.arms[0].model;
        let ine = sc.arms[0].inertials.body_inertias(m).unwrap();
        let dm = dvrk_kin::DynamicsModel::new(m, ine).unwrap();
        let mut data = dvrk_kin::DynamicsData::new(m);
        let mut mm = nalgebra::DMatrix::zeros(7, 7);
        dvrk_kin::mass_matrix(m, &dm, &mut data, &two.q[0].iter().take(7).copied().collect::<Vec<_>>(), &mut mm).unwrap();
        println!("{name}: M diag {:.4?} armature {:.4?}", mm.diagonal().as_slice(), sc.arms[0].armature);
    }
    for e in id.estimates.iter().filter(|e| e.name.starts_with("outer_yaw")) { println!("{} = {:.4} +- {:.4}", e.name, e.value, e.std); }
    println!("not simulated: {:?}\nkept prior: {:?}", info.not_simulated, info.kept_prior);
    // Ablation: identified inertials with the CAD effects (none), and CAD inertials with the identified effects.
    let mut inert_only = base.clone();
    inert_only.arms[0].inertials = scene.arms[0].inertials.clone();
    let mut effects_only = scene.clone();
    effects_only.arms[0].inertials = base.arms[0].inertials.clone();
    for (name, sc) in [("identified inertials only", &inert_only), ("identified effects only", &effects_only)] {
        let r = torque_replay(sc, 0, &two, 0.3).unwrap();
        println!("{name}: rms {:.4?}", r.0);
    }
    for b in &scene.arms[0].inertials.bodies { println!("{} m {:.4} com {:.3?} I diag {:.2e} {:.2e} {:.2e}", b.name, b.mass, b.com, b.inertia[0][0], b.inertia[1][1], b.inertia[2][2]); }
    for fb in std::env::var("FB").unwrap_or("0.1,0.3,1.0".into()).split(',') {
        let fb: f64 = fb.parse().unwrap();
        let cad = torque_replay(&base, 0, &two, fb).unwrap();
        let idd = torque_replay(&scene, 0, &two, fb).unwrap();
        println!("feedback {fb}: CAD rms {:.4?} bias {:.4?}\n              identified rms {:.4?} bias {:.4?}", cad.0, cad.1, idd.0, idd.1);
    }
}
