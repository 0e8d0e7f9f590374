//! Identification on the WPI recordings (scratch driver; the CLI is `dvrk identify`).
use dvrk_calib::identify::problem::EffectTerm;
use dvrk_calib::identify::{identify, read_wpi_csv, IdentifyOptions};
use std::path::Path;

fn main() {
    let model = dvrk_kin::load("psm", None).unwrap();
    let ine = dvrk_sim::scene::builtin_inertials("psm", &model).unwrap().body_inertias(&model).unwrap();
    let dir = Path::new("../shared/data/external/wpi-dvrk-dynamics");
    let one = read_wpi_csv(&dir.join("psm_one_results.csv"), &model).unwrap();
    let two = read_wpi_csv(&dir.join("psm_two_results.csv"), &model).unwrap();
    let full = IdentifyOptions::full(vec![3, 4, 5, 6]);
    let _ = &full;
    let sets: Vec<(&str, Vec<EffectTerm>)> = vec![
        ("rigid", vec![]),
        ("+coulomb/offset", vec![EffectTerm::Coulomb, EffectTerm::Offset]),
        ("+viscous", vec![EffectTerm::Coulomb, EffectTerm::Offset, EffectTerm::Viscous]),
        ("+armature", vec![EffectTerm::Coulomb, EffectTerm::Offset, EffectTerm::Viscous, EffectTerm::Armature]),
        ("+spring", EffectTerm::ALL.to_vec()),
    ];
    let gx: Vec<f64> = std::env::var("G").unwrap_or("0,0,-9.81".into()).split(',').map(|x| x.parse().unwrap()).collect();
    let only: usize = std::env::var("ONLY").map(|v| v.parse().unwrap()).unwrap_or(99);
    for (si, (name, e)) in sets.into_iter().enumerate() {
        if only != 99 && si != only && !(only == 5 && (si == 0 || si == 4)) { continue; }
        let mut o = full.with_effects(&e);
        o.processing.gravity = nalgebra::Vector3::new(gx[0], gx[1], gx[2]);
        if let Ok(c) = std::env::var("CUTOFF") { o.processing.cutoff = c.parse().unwrap(); }
        if let Ok(c) = std::env::var("VS") { o.processing.coulomb_velocity = c.parse().unwrap(); }
        if std::env::var("SPRING_ALL").is_ok() { o.terms.spring_channels = (0..7).collect(); }
        let t = std::time::Instant::now();
        let (id, _) = identify(&model, &ine, &one, &o).unwrap();
        let v = id.validate(&model, &two, &o).unwrap();
        println!("{name:18} fit {:.3?}\n{:18} val {:.3?}  rounds {} base {} ({:.2} s)", id.relative_error, "", v, id.fit.rounds, id.base_parameters, t.elapsed().as_secs_f64());
    }
}
