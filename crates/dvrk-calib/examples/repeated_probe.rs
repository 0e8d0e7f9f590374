//! The repeated workflow on one hidden-effect trial at ENR 5, printed round by round: `cargo run --release -p dvrk-calib --example repeated_probe -- viscous_friction+payload_mass 11`.
use dvrk_calib::discrepancy::*;
fn main() {
    let a: Vec<String> = std::env::args().collect();
    let hidden: Hidden = a[1].parse().unwrap();
    let seed: u64 = a[2].parse().unwrap();
    let h = hidden_effect("psm", &HiddenOptions { hidden, seed, enr: Some(5.0), duration: 20.0, ..Default::default() }).unwrap();
    let scene = dvrk_sim::Scene::load("psm").unwrap();
    let model = dvrk_kin::load("psm", None).unwrap();
    let out = discrepancy_repeated(&model, &scene, "PSM1", &h.log, &Options { tracking: false, ..Default::default() }, 4).unwrap();
    let r = &out.report;
    println!("hidden {:?}", h.answer.effects.iter().map(|e| (&e.spec.name, &e.spec.joint, &e.spec.link, &e.spec.parameters)).collect::<Vec<_>>());
    println!(
        "steps {:?}",
        r.steps.iter().map(|s| (&s.verdict, &s.named, (s.rms_heldout_before * 100.0).round() / 100.0, (s.rms_heldout_after * 100.0).round() / 100.0)).collect::<Vec<_>>()
    );
    println!("effects {:?}", r.effects.iter().map(|e| (&e.name, &e.joint, &e.link, &e.parameters)).collect::<Vec<_>>());
}
