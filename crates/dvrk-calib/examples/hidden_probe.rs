//! One hidden-effect trial, printed: `[DVRK_SCENE=psm] [DVRK_PERTURB=0.03] [DVRK_NOISE=1] [DVRK_POS_NOISE=1] [DVRK_TRUTH_DT=1.25e-4] [DVRK_DURATION=30] [DVRK_DUMP=residual.csv] cargo run --release -p dvrk-calib --example hidden_probe -- KIND SEED [ENR]`.
//! DVRK_ORACLE=1 analyses with the hidden effects in the model (or a comma list of their names);
//! DVRK_ORACLE_SCALE=k with their parameters times k.
//! DVRK_ROUNDS=4 runs the repeated workflow (KIND `random-pair` for the two-effect trials).
//! DVRK_DUMP writes the band-limited residual before and after, with each joint's position,
//! velocity and load, one row per analysed sample.
use dvrk_calib::discrepancy::*;
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let hidden: Hidden = args.get(1).map(|s| s.parse().unwrap()).unwrap_or(Hidden::None);
    let seed: u64 = args.get(2).map(|s| s.parse().unwrap()).unwrap_or(3);
    let enr: Option<f64> = args.get(3).map(|s| s.parse().unwrap());
    let t0 = std::time::Instant::now();
    // DVRK_PERTURB: the truth's relative inertia perturbation (default 0.03).
    let inertia_perturbation = std::env::var("DVRK_PERTURB").ok().and_then(|s| s.parse().ok()).unwrap_or(0.03);
    let mut o = HiddenOptions { hidden, seed, enr, inertia_perturbation, ..Default::default() };
    // DVRK_DURATION: the recording's length (s).
    if let Some(d) = std::env::var("DVRK_DURATION").ok().and_then(|s| s.parse().ok()) {
        o.duration = d;
    }
    // DVRK_TRUTH_DT: the truth's time step (s).
    if let Some(dt) = std::env::var("DVRK_TRUTH_DT").ok().and_then(|s| s.parse().ok()) {
        o.truth_dt = dt;
    }
    // DVRK_NOISE: the sensor noises' scale (ENR is relative to the effort noise: scale it too);
    // DVRK_POS_NOISE: the encoder noise's alone.
    if let Some(k) = std::env::var("DVRK_NOISE").ok().and_then(|s| s.parse::<f64>().ok()) {
        o.effort_noise = Some(generate::EFFORT_NOISE.iter().map(|x| x * k).collect());
        o.position_noise = generate::POSITION_NOISE * k;
    }
    if let Some(k) = std::env::var("DVRK_POS_NOISE").ok().and_then(|s| s.parse::<f64>().ok()) {
        o.position_noise = generate::POSITION_NOISE * k;
    }
    // DVRK_SCENE: the truth's and the analysis' scene (a file or built-in name).
    let truth_scene = std::env::var("DVRK_SCENE").unwrap_or_else(|_| "psm".into());
    let h = hidden_effect(&truth_scene, &o).unwrap();
    println!("generate {:.2} s; answer {}", t0.elapsed().as_secs_f64(), serde_json::to_string(&h.answer).unwrap());
    let t1 = std::time::Instant::now();
    let scene = dvrk_sim::Scene::load(&truth_scene).unwrap();
    let mut model = dvrk_kin::load("psm", None).unwrap();
    // DVRK_ORACLE: analyse with the hidden effects already in the model (what the held-out data
    // can tell at best).
    if let Ok(which) = std::env::var("DVRK_ORACLE") {
        // DVRK_ORACLE_SCALE: their parameters scaled (an estimate's error, without the fit's).
        let scale = std::env::var("DVRK_ORACLE_SCALE").ok().and_then(|s| s.parse::<f64>().ok()).unwrap_or(1.0);
        for e in h.answer.effects.iter().filter(|e| which == "1" || which.split(',').any(|n| n == e.spec.name)) {
            let mut spec = e.spec.clone();
            spec.parameters.values_mut().for_each(|v| *v *= scale);
            model = model.with_effect(&spec).unwrap();
        }
    }
    let o = Options { tracking: args.get(4).is_some(), ..Default::default() };
    // DVRK_ROUNDS: the repeated workflow (step 4), its steps and named effects printed.
    if let Some(rounds) = std::env::var("DVRK_ROUNDS").ok().and_then(|s| s.parse().ok()) {
        let rep = discrepancy_repeated(&model, &scene, "PSM1", &h.log, &o, rounds).unwrap();
        for s in &rep.report.steps {
            println!("  round {} {} {:?}: {:.3} -> {:.3}, held out {:.3} -> {:.3}", s.round, s.verdict, s.named, s.rms_before, s.rms_after, s.rms_heldout_before, s.rms_heldout_after);
        }
        for e in &rep.report.effects {
            println!("  named {} {:?} {:?} ci {:?} dBIC {:.1}", e.name, e.joint, e.parameters, e.ci95, e.delta_bic);
        }
        println!("analyse {:.2} s", t1.elapsed().as_secs_f64());
        // DVRK_LAST: the candidates of one more round on the final model.
        if std::env::var("DVRK_LAST").is_ok() {
            let last = discrepancy(&rep.model, &scene, "PSM1", &h.log, &o).unwrap().report;
            for c in last.candidates.iter().take(8) {
                println!("  last cand {:40} dBIC {:10.1} p {:.1e} hold p {:.1e} size {:.2} {:?}", c.label, c.effect.delta_bic, c.effect.p_value, c.heldout_p_value, c.effect_to_noise, c.effect.parameters);
            }
        }
        return;
    }
    let out = discrepancy(&model, &scene, "PSM1", &h.log, &o).unwrap();
    let r = &out.report;
    println!("analyse {:.2} s: verdict {} {:?}", t1.elapsed().as_secs_f64(), r.verdict, r.experiment);
    for e in &r.effects {
        println!("  named {} {:?} {:?} ci {:?} dBIC {:.1} p {:.2e}", e.name, e.joint, e.parameters, e.ci95, e.delta_bic, e.p_value);
    }
    for c in r.candidates.iter().take(5) {
        println!("  cand {:40} dBIC {:10.1} p {:.1e} hold p {:.1e} size {:.2} {:?}", c.label, c.effect.delta_bic, c.effect.p_value, c.heldout_p_value, c.effect_to_noise, c.effect.parameters);
    }
    println!("  rms nominal {:.3} ho {:.3}; {:.3} -> {:.3}; held out {:.3} -> {:.3}", r.rms_nominal, r.rms_heldout_nominal, r.rms_before, r.rms_after, r.rms_heldout_before, r.rms_heldout_after);
    for j in &r.joints {
        println!("  {:18} noise {:.2e} band {:.2e} -> {:.2e} floor {:.2e}", j.joint, j.noise, j.band_rms_heldout_before, j.band_rms_heldout_after, j.band_floor);
    }
    for l in &r.location {
        println!("  located {:18} rms {:.2} reversals {:.2} speed {:.2} load {:.2} deep {:?} worst {:?}", l.joint, l.rms, l.reversals, l.high_speed, l.high_load, l.deep_insertion.map(|d| (d * 100.0).round() / 100.0), l.worst);
    }
    if let Some(t) = &r.tracking { println!("  tracking {:?} -> {:?}", t.rms_before, t.rms_after); }
    if let Ok(path) = std::env::var("DVRK_DUMP") {
        let r = &out.residuals;
        let mut csv = String::from("t");
        for j in &r.joints {
            csv += &format!(",q_{j},qd_{j},load_{j},before_{j},after_{j}");
        }
        csv += "\n";
        for i in 0..r.t.len() {
            csv += &format!("{}", r.t[i]);
            for k in 0..r.joints.len() {
                csv += &format!(",{},{},{},{},{}", r.q[k][i], r.qd[k][i], r.load[k][i], r.before[k][i], r.after[k][i]);
            }
            csv += "\n";
        }
        std::fs::write(&path, csv).unwrap();
    }
}
