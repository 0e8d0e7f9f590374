//! Identification on the WPI recordings (scratch ablation driver; the CLI is `dvrk identify`).
//! Env: EFFECTS (rigid|friction|all, default all), JF (joints with joint friction, `4,5,6`),
//! CUT (per-channel cut-offs), VSC (per-channel Coulomb velocities), STRIBECK (1), G (gravity),
//! SPRING (spring channels), DAHL (presliding channels), SIG (their presliding displacements),
//! MODEL (psm or mtmr: the MTM's recordings and IdentifyOptions::mtm), JS (joint springs
//! `joint:order,...`), CUTOFF (one cut-off for every channel), CABLE (the MTM platform's joint
//! test file: the prior of its cable spring).
//! Prints the fit on `one`, the two-fold cross-validation within `one` (the figure settings are
//! chosen by) and the held-out error on `two`.
use dvrk_calib::identify::problem::EffectTerm;
use dvrk_calib::identify::{identify, read_wpi_csv, IdentifyOptions, JointLog};
use std::path::Path;

fn list(var: &str) -> Option<Vec<f64>> {
    // `none`: an empty list.
    std::env::var(var).ok().filter(|v| !v.is_empty()).map(|v| if v == "none" { Vec::new() } else { v.split(',').map(|x| x.parse().unwrap()).collect() })
}

fn main() {
    let name = std::env::var("MODEL").unwrap_or_else(|_| "psm".into());
    let model = dvrk_kin::load(&name, None).unwrap();
    let ine = dvrk_sim::scene::builtin_inertials(&name, &model).unwrap().body_inertias(&model).unwrap();
    let dir = Path::new("../shared/data/external/wpi-dvrk-dynamics");
    let (one, two) = if name == "psm" { ("psm_one_results.csv", "psm_two_results.csv") } else { ("mtm/one_results.csv", "mtm/two_results.csv") };
    let one = read_wpi_csv(&dir.join(one), &model).unwrap();
    let two = read_wpi_csv(&dir.join(two), &model).unwrap();
    // BASE=psm starts from the chosen PSM options (IdentifyOptions::psm) instead of `full`; an
    // MTM always from IdentifyOptions::mtm.
    let mut o = if name != "psm" {
        IdentifyOptions::mtm()
    } else if std::env::var("BASE").as_deref() == Ok("psm") {
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
    if let (true, Some(sp)) = (std::env::var("BASE").as_deref() == Ok("psm") || name != "psm", list("SPRING")) {
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
    if let Ok(v) = std::env::var("JS") {
        o.terms.joint_springs = v.split(',').filter(|p| !p.is_empty()).map(|p| p.split_once(':').map(|(a, b)| (a.parse().unwrap(), b.parse().unwrap())).unwrap()).collect();
    }
    if let Some(c) = list("CUTOFF") {
        o.processing.cutoff = c[0];
        o.processing.channel_cutoff.clear();
    }
    // CABLE: the MTM platform's joint test as the prior of its cable spring.
    if let Ok(path) = std::env::var("CABLE") {
        let test = dvrk_calib::identify::cable_prior::from_joint_test(Path::new(&path), 3).unwrap();
        eprintln!("cable test: {:?} + {:.4}, range {:?}, misfit {:.4}, friction {:.4}", test.prior.value, test.constant, test.range, test.misfit_rms, test.friction);
        o.joint_spring_priors.push(test.prior);
    }
    if let Some(c) = list("ORDER") {
        o.processing.filter_order = c[0] as usize;
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
    let (v, _, published) = id.validate_all(&model, &two, &o).unwrap();
    let published = published.map(|p| p.relative_error).unwrap_or_default();
    let h = one.len() / 2;
    let halves: [(JointLog, JointLog); 2] = [(one.slice(0..h), one.slice(h..one.len())), (one.slice(h..one.len()), one.slice(0..h))];
    let mut cv = [0.0; 7];
    let mut cv_pub = [0.0; 7];
    for (a, b) in &halves {
        let (ida, _) = identify(&model, &ine, a, &o).unwrap();
        let (raw, _, p) = ida.validate_all(&model, b, &o).unwrap();
        for (c, e) in raw.iter().enumerate() {
            cv[c] += 0.5 * e;
        }
        for (c, e) in p.map(|p| p.relative_error).unwrap_or_default().iter().enumerate() {
            cv_pub[c] += 0.5 * e;
        }
    }
    println!("fit {:.3?}\ncv  {:.3?} mean {:.4}\nval {:.3?}  rounds {} base {} ({:.2} s)\npub {:.3?}\ncvp {:.3?} mean {:.4}", id.relative_error, cv, cv.iter().sum::<f64>() / 7.0, v, id.fit.rounds, id.base_parameters, t.elapsed().as_secs_f64(), published, cv_pub, cv_pub.iter().sum::<f64>() / 7.0);
}
