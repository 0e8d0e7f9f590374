//! Identification on the WPI recordings (scratch ablation driver; the CLI is `dvrk identify`).
//! Env: EFFECTS (rigid|friction|all, default all), JF (joints with joint friction, `4,5,6`),
//! CUT (per-channel cut-offs), VSC (per-channel Coulomb velocities), STRIBECK (1), G (gravity),
//! SPRING (spring channels), DAHL (presliding channels), SIG (their presliding displacements).
//! Prints the fit on `one`, the two-fold cross-validation within `one` (the figure settings are
//! chosen by) and the held-out error on `two`.
use dvrk_calib::identify::problem::EffectTerm;
use dvrk_calib::identify::{identify, read_wpi_csv, IdentifyOptions, JointLog};
use std::path::Path;

fn list(var: &str) -> Option<Vec<f64>> {
    std::env::var(var).ok().filter(|v| !v.is_empty()).map(|v| v.split(',').map(|x| x.parse().unwrap()).collect())
}

fn main() {
    let model = dvrk_kin::load("psm", None).unwrap();
    let ine = dvrk_sim::scene::builtin_inertials("psm", &model).unwrap().body_inertias(&model).unwrap();
    let dir = Path::new("../shared/data/external/wpi-dvrk-dynamics");
    let one = read_wpi_csv(&dir.join("psm_one_results.csv"), &model).unwrap();
    let two = read_wpi_csv(&dir.join("psm_two_results.csv"), &model).unwrap();
    // BASE=psm starts from the chosen PSM options (IdentifyOptions::psm) instead of `full`.
    let mut o = if std::env::var("BASE").as_deref() == Ok("psm") {
        IdentifyOptions::psm()
    } else {
        IdentifyOptions::full(list("SPRING").map(|v| v.iter().map(|x| *x as usize).collect()).unwrap_or(vec![3, 4, 5, 6]))
    };
    match std::env::var("EFFECTS").as_deref() {
        Ok("rigid") => o.terms.effects.clear(),
        Ok("friction") => o.terms.effects = vec![EffectTerm::Coulomb, EffectTerm::Offset, EffectTerm::Viscous],
        _ => {}
    }
    if std::env::var("STRIBECK").is_ok() {
        o.terms.effects.push(EffectTerm::Stribeck);
    }
    // WIND: channels with the position-dependent (winding) Coulomb friction.
    if let Some(w) = list("WIND") {
        o.terms.winding_channels = w.iter().map(|x| *x as usize).collect();
    }
    // DAHL: channels with presliding (Dahl) friction; SIG: their presliding displacements.
    if let Some(w) = list("DAHL") {
        o.terms.dahl_channels = w.iter().map(|x| *x as usize).collect();
    }
    if let Some(s) = list("SIG") {
        o.processing.channel_dahl_displacement = s;
    }
    if let (Ok("psm"), Some(sp)) = (std::env::var("BASE").as_deref(), list("SPRING")) {
        o.terms.spring_channels = sp.iter().map(|x| *x as usize).collect();
    }
    if let Some(j) = list("JF") {
        o.terms.joint_friction = j.iter().map(|x| *x as usize).collect();
    }
    // XS / XV / XC: cross spring / viscous / Coulomb as `c:s,c:s`.
    for (var, term) in [("XS", EffectTerm::Spring), ("XV", EffectTerm::Viscous), ("XC", EffectTerm::Coulomb)] {
        if let Ok(v) = std::env::var(var) {
            for pair in v.split(',').filter(|p| !p.is_empty()) {
                let (a, b) = pair.split_once(':').unwrap();
                o.terms.cross.push((a.parse().unwrap(), b.parse().unwrap(), term));
            }
        }
    }
    if let Some(c) = list("CUT") {
        o.processing.channel_cutoff = c;
    }
    if let Some(c) = list("VSC") {
        o.processing.channel_coulomb_velocity = c;
    }
    if let Some(p) = list("PF") {
        o.prior_fraction = p[0];
    }
    if let Some(g) = list("G") {
        o.processing.gravity = nalgebra::Vector3::new(g[0], g[1], g[2]);
    }
    let t = std::time::Instant::now();
    let (id, _) = identify(&model, &ine, &one, &o).unwrap();
    let (v, _) = id.validate(&model, &two, &o).unwrap();
    let h = one.len() / 2;
    let halves: [(JointLog, JointLog); 2] = [(one.slice(0..h), one.slice(h..one.len())), (one.slice(h..one.len()), one.slice(0..h))];
    let mut cv = [0.0; 7];
    for (a, b) in &halves {
        let (ida, _) = identify(&model, &ine, a, &o).unwrap();
        for (c, e) in ida.validate(&model, b, &o).unwrap().0.iter().enumerate() {
            cv[c] += 0.5 * e;
        }
    }
    println!("fit {:.3?}\ncv  {:.3?} mean {:.4}\nval {:.3?}  rounds {} base {} ({:.2} s)", id.relative_error, cv, cv.iter().sum::<f64>() / 7.0, v, id.fit.rounds, id.base_parameters, t.elapsed().as_secs_f64());
}
