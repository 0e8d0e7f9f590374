//! The discrepancy workflow on recordings with a hidden effect (`dvrk synth hidden-effect`'s
//! generator): the truth at 0.125 ms with perturbed inertias and noisy efforts, the workflow on the
//! nominal PSM. Each supported class is named on a seeded trial at an effect-to-noise ratio of 5,
//! with its parameter; an effect-free recording gives `none`; bad recordings are refused.
//! The full detection-rate table is the ignored `detection_rate_table`.

use dvrk_calib::discrepancy::generate::HIDDEN_KINDS;
use dvrk_calib::discrepancy::{discrepancy, hidden_effect, Hidden, HiddenOptions, HiddenRecording, Options};
use dvrk_sim::recording;
use dvrk_kin::effects::EffectKind;

/// The generator's settings for these regression nets: the truth on the reduced engine (dvrk-kin's
/// forward dynamics at the same 0.125 ms step), 18x faster than on rapier (a 12 s spring: 0.84 s
/// against 15.5 s) and as close to the truth (its stiffness found 0.07% off, rapier's 0.15%). The
/// truth then shares dynamics code with the analysis: the detection tables (ignored below) and
/// `scripts/independent_table.py` keep truths that do not.
fn fast() -> HiddenOptions {
    HiddenOptions { engine: dvrk_sim::Engine::Reduced, ..Default::default() }
}

/// The table tests' settings: environment variable `name` parsed, else `default`.
fn env_or<T: std::str::FromStr>(name: &str, default: T) -> T {
    std::env::var(name).ok().and_then(|s| s.parse().ok()).unwrap_or(default)
}

/// The hidden-effect recording of these settings, generated once per test binary: tests that
/// ask for the same one (seed 11's latency: the named-with-its-parameter sweep and the repeated
/// workflow) share it, the first caller generating while the others wait.
fn trial(hidden: Hidden, seed: u64, enr: Option<f64>, duration: f64) -> std::sync::Arc<HiddenRecording> {
    type Slot = std::sync::Arc<std::sync::OnceLock<std::sync::Arc<HiddenRecording>>>;
    static MADE: std::sync::Mutex<Vec<(String, Slot)>> = std::sync::Mutex::new(Vec::new());
    let key = format!("{hidden:?} {seed} {enr:?} {duration}");
    let slot = {
        let mut made = MADE.lock().unwrap();
        match made.iter().find(|(k, _)| *k == key) {
            Some((_, slot)) => slot.clone(),
            None => {
                let slot = Slot::default();
                made.push((key, slot.clone()));
                slot
            }
        }
    };
    slot.get_or_init(|| std::sync::Arc::new(hidden_effect("psm", &HiddenOptions { hidden, seed, enr, duration, ..fast() }).unwrap())).clone()
}

/// A truth whose controller sits at an effort limit is not a recording the dVRK makes: seed
/// 7017's pair (a 4 ms loop latency with a 7.2 mrad play on the outer pitch) chattered at 61 Hz
/// against the pitch's limit on 9% of the samples (10 s, noise-free). Its effects are drawn
/// again (another random pair) until no joint is at its limit on more than 1% of the samples
/// past the fade-in.
#[test]
fn a_truth_in_a_limit_cycle_is_drawn_again() {
    let quiet = HiddenOptions { hidden: Hidden::RandomPair, seed: 7017, duration: 10.0, effort_noise: Some(vec![0.0; 7]), position_noise: 0.0, ..fast() };
    let h = hidden_effect("psm", &quiet).unwrap();
    let model = dvrk_kin::load("psm", None).unwrap();
    let skip = h.log.t.iter().position(|t| *t >= 2.0).unwrap();
    let n = (h.log.len() - skip) as f64;
    eprintln!("{:?}", h.answer.effects.iter().map(|e| (&e.spec.name, &e.spec.joint, &e.spec.parameters)).collect::<Vec<_>>());
    assert_eq!(h.answer.effects.len(), 2);
    for (k, joint) in model.joints.iter().enumerate() {
        let at = h.log.effort[skip..].iter().filter(|e| e[k].abs() >= joint.effort_limit * (1.0 - 1e-9)).count() as f64;
        assert!(at <= 0.01 * n, "{} at its limit on {:.1}% of the samples", joint.name, 100.0 * at / n);
    }
}

fn analyse(h: &HiddenRecording, tracking: bool) -> dvrk_calib::discrepancy::Outcome {
    let scene = dvrk_sim::Scene::load("psm").unwrap();
    let model = dvrk_kin::load("psm", None).unwrap();
    discrepancy(&model, &scene, "PSM1", &h.log, &Options { tracking, ..Default::default() }).unwrap()
}

/// An offset of the outer pitch rotates its gravity torque, as a first-moment change of its
/// bodies would: the inertias' nuisance takes up most of it, and the rest is too little for the
/// last 30% of the recording alone. Seed 1048 (30 s, ENR 3.6, as in the detection table: offset 10.9 mrad)
/// leaves the held-out last 30% no evidence (p 0.015, the gate 0.01); each fifth of the recording
/// predicted from the other four confirms it. Measured: named, 12.2 mrad in [8.2, 16.3],
/// last-part p 0.015, cross-validated p ~4e-11.
#[test]
fn an_offset_the_inertias_mimic_is_confirmed_across_the_recording() {
    let h = trial(Hidden::Kind(EffectKind::JointOffset), 1048, Some(3.6), 30.0);
    let r = analyse(&h, false).report;
    let truth = &h.answer.effects[0].spec;
    let c = &r.candidates[0];
    eprintln!("{} {:?} {:?}: held-out p {:.3e}, cross-validated {:?}; truth {:?}", r.verdict, c.effect.parameters, c.effect.ci95, c.heldout_p_value, c.heldout_cv_p_value, truth.parameters);
    assert_eq!((truth.joint.as_deref(), r.verdict.as_str()), (Some("outer_pitch"), "named"));
    let e = &r.effects[0];
    assert_eq!((e.name.as_str(), e.joint.as_deref()), ("joint_offset", Some("outer_pitch")));
    let ([lo, hi], t) = (e.ci95["offset"], truth.parameters["offset"]);
    assert!(lo <= t && t <= hi, "{t} outside [{lo}, {hi}]");
    // The last part alone would not have named it; the whole recording does, by far.
    assert!(c.heldout_p_value > 0.01 && c.heldout_cv_p_value.unwrap() < 1e-6, "{} {:?}", c.heldout_p_value, c.heldout_cv_p_value);
}

/// The parameter the test compares for the hidden effect `truth` (the truth's name and the
/// report's): per kind; a coupling error's entry `dRC` (its only parameter).
fn main_parameter(truth: &dvrk_kin::effects::EffectSpec) -> String {
    if truth.name == EffectKind::CouplingError.name() {
        return truth.parameters.keys().next().cloned().unwrap_or_default();
    }
    match truth.name.as_str() {
        "coulomb_friction" | "actuator_coulomb_friction" => "fc",
        "viscous_friction" | "actuator_viscous_friction" => "fv",
        "spring" => "k",
        "latency" | "clock_offset" => "seconds",
        "joint_offset" => "offset",
        "payload_mass" => "mass",
        "joint_compliance" => "stiffness",
        "link_length" => "a",
        _ => "b",
    }
    .to_string()
}

/// Measured (seed 11, ENR 5, 12 s; 20 s for the offset): every class below named on its true
/// joint or link, its main parameter within 6% of the truth (10% for an offset), held-out band
/// RMS cut by at least half. At 12 s the eight others are within 2% (at most 0.1 of the held-out
/// RMS left); the offset, whose gravity term shares the refitted mass moments, is +13.9% at
/// 12 s (the test fails, as it should) and +6.6% at 20 s.
#[test]
fn each_supported_effect_is_named_with_its_parameter() {
    let kinds = HIDDEN_KINDS;
    for kind in kinds {
        let seconds = if kind == EffectKind::JointOffset { 20.0 } else { 12.0 };
        let h = trial(Hidden::Kind(kind), 11, Some(5.0), seconds);
        let out = analyse(&h, false);
        let r = &out.report;
        let truth = &h.answer.effects[0].spec;
        eprintln!(
            "{}: verdict {} {:?}; truth {:?}; rms held out {:.2} -> {:.2}",
            kind.name(),
            r.verdict,
            r.effects.first().map(|e| (&e.name, &e.joint, &e.link, &e.parameters, &e.ci95)),
            truth.parameters,
            r.rms_heldout_nominal,
            r.rms_heldout_after
        );
        assert_eq!(r.verdict, "named", "{}: {:?}", kind.name(), r.candidates.first());
        let e = &r.effects[0];
        assert_eq!(e.name, truth.name);
        assert_eq!(e.joint, truth.joint);
        // A payload: on the truth's body, or on one the report gives as equivalent (a point on
        // the wrist's yaw axis rides the wrist's pitch link and the jaws alike).
        let truth_link = truth.link.as_ref().map(|l| l.to_string());
        let equivalent = e.payload.as_ref().is_some_and(|p| p.equivalent.iter().any(|q| Some(&q.link) == truth_link.as_ref()));
        assert!(e.link == truth_link || equivalent, "{}: {:?} vs {truth_link:?}", kind.name(), e.link);
        let p = &main_parameter(truth);
        let (got, want) = (e.parameters[p], truth.parameters[p]);
        // The drives' profiles come from a reduced (one-joint) link behind the transmission, the
        // truth is the full multibody: measured +0.05% (play), -0.04% (compliance). An offset's
        // gravity term shares the refitted mass moments: measured +6.6%, its 95% interval +-11%.
        let tol = if kind == EffectKind::JointOffset { 0.1 } else { 0.06 };
        assert!(((got - want) / want).abs() < tol, "{}: {p} = {got}, truth {want}", e.name);
        // Against the model as given (the offset is partly absorbed by the refitted inertias).
        assert!(r.rms_heldout_after < 0.5 * r.rms_heldout_nominal, "{} -> {}", r.rms_heldout_nominal, r.rms_heldout_after);
        assert!(e.delta_bic > 10.0 && e.p_value < 1e-3);
        // Located: viscous friction's residual lives at speed and vanishes at reversals
        // (measured 1.76 and 0.08 of the joint's RMS on the wrist pitch).
        if kind == EffectKind::ViscousFriction {
            let l = r.location.iter().find(|l| Some(&l.joint) == truth.joint.as_ref()).unwrap();
            assert!(l.worst.as_deref() == Some("high_speed") && l.reversals < 0.3, "{l:?}");
        }
    }
}

/// An effect-free recording (rotational inertias 3% off the nominal's): nothing is named, and the
/// tracking channel is replayed (no named effect: no after).
#[test]
fn an_effect_free_recording_names_nothing() {
    let h = trial(Hidden::None, 3, None, 20.0);
    let out = analyse(&h, true);
    let r = &out.report;
    eprintln!("none: best candidate {:?}", r.candidates.first().map(|c| (&c.label, c.effect.delta_bic, c.effect_to_noise)));
    assert_eq!(r.verdict, "none");
    assert!(r.effects.is_empty() && out.named.is_none());
    let t = r.tracking.as_ref().unwrap();
    // The arm tracks the setpoints with the nominal model within the recorded errors' size.
    assert!(t.rms_before[..6].iter().all(|x| *x > 0.0 && *x < 0.05), "{:?}", t.rms_before);
    assert!(t.rms_after.is_none());
}

/// An effect just under the size gate is not replaced by a stand-in that clears it. Seed 1000
/// (30 s, ENR 1: a compliance of 44.5 N·m/rad on the outer pitch, its RMS 0.95 of the noise):
/// the right candidate's delta BIC is 5609 at size 0.95 (held back, the gate is 1); compliance
/// on the wrist pitch (delta BIC 22.8, size 1.32) clears every gate and was named before the
/// rule. Measured: `none`.
#[test]
fn a_stand_in_for_an_effect_too_small_to_matter_is_not_named() {
    let h = trial(Hidden::Kind(EffectKind::JointCompliance), 1000, Some(1.0), 30.0);
    let r = analyse(&h, false).report;
    let top: Vec<_> = r.candidates.iter().take(5).map(|c| (&c.label, c.effect.delta_bic, c.effect_to_noise, c.supported)).collect();
    eprintln!("{} {top:?}", r.verdict);
    let c = &r.candidates[0];
    assert_eq!(c.label, "joint_compliance on outer_pitch");
    assert!(c.effect.delta_bic > 1000.0 && c.effect_to_noise < 1.0 && !c.supported, "{top:?}");
    // A weaker candidate is supported on its own; the rule, not the gates, holds it back.
    assert!(r.candidates.iter().any(|c| c.supported), "{top:?}");
    assert_eq!(r.verdict, "none");
    assert!(r.effects.is_empty());
}

/// The dVRK's topics with the joints in another order than the model's read in the model's
/// order (matched by name), the same log as one written in order.
#[test]
fn an_mcap_in_another_joint_order_reads_in_the_models() {
    let dir = tempfile::tempdir().unwrap();
    let h = trial(Hidden::None, 5, None, 5.0);
    let psm = dvrk_kin::load("psm", None).unwrap();
    let order = [6, 0, 5, 1, 4, 2, 3];
    let shuffle = |v: &Vec<Vec<f64>>| -> Vec<Vec<f64>> { v.iter().map(|s| order.iter().map(|&k| s[k]).collect()).collect() };
    let shuffled = dvrk_sim::recording::JointLog {
        names: order.iter().map(|&k| h.log.names[k].clone()).collect(),
        setpoint: shuffle(&h.log.setpoint),
        position: shuffle(&h.log.position),
        effort: shuffle(&h.log.effort),
        ..h.log.clone()
    };
    let (a, b) = (dir.path().join("a.mcap"), dir.path().join("b.mcap"));
    std::fs::write(&a, recording::write_joint_log_mcap(&h.log, "PSM1").unwrap()).unwrap();
    std::fs::write(&b, recording::write_joint_log_mcap(&shuffled, "PSM1").unwrap()).unwrap();
    let read = |p: &std::path::Path| dvrk_calib::discrepancy::read_log(p, "mcap", &psm, "PSM1").unwrap().0;
    let (in_order, reordered) = (read(&a), read(&b));
    assert_eq!(reordered.names, psm.joints.iter().map(|j| j.name.clone()).collect::<Vec<_>>());
    assert_eq!((&reordered.t, &reordered.setpoint, &reordered.position, &reordered.effort), (&in_order.t, &in_order.setpoint, &in_order.position, &in_order.effort));
    assert!(reordered.len() > 1000);
}

/// The MCAP written for a hidden-effect recording reads back with its efforts; recordings the
/// workflow cannot use are refused with the file, topic and value.
#[test]
fn joint_logs_round_trip_and_bad_recordings_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let h = trial(Hidden::None, 5, None, 8.0);
    let psm = dvrk_kin::load("psm", None).unwrap();
    let path = dir.path().join("rec.mcap");
    std::fs::write(&path, recording::write_joint_log_mcap(&h.log, "PSM1").unwrap()).unwrap();
    let back = dvrk_calib::discrepancy::read_log(&path, "mcap", &psm, "PSM1").unwrap().0;
    assert_eq!(back.names, h.log.names);
    assert_eq!(back.len(), h.log.len());
    assert!((back.effort[100][1] - h.log.effort[100][1]).abs() < 1e-12);
    let e = dvrk_calib::discrepancy::read_log(&path, "mcap", &psm, "PSM2").unwrap_err().to_string();
    assert!(e.contains("/PSM2/measured_js") && e.contains("rec.mcap"), "{e}");
    let bad = dir.path().join("bad.mcap");
    std::fs::write(&bad, b"not an mcap").unwrap();
    let e = dvrk_calib::discrepancy::read_log(&bad, "mcap", &psm, "PSM1").unwrap_err().to_string();
    assert!(e.contains("bad.mcap") && e.contains("MCAP"), "{e}");
    // Too short for the analysis (8 s: 2 s fade-in, 0.5 s edge, at least 5 s of data needed).
    let mut short = h.log.clone();
    short.t.truncate(5000);
    short.setpoint.truncate(5000);
    short.position.truncate(5000);
    short.effort.truncate(5000);
    let scene = dvrk_sim::Scene::load("psm").unwrap();
    let model = dvrk_kin::load("psm", None).unwrap();
    let e = discrepancy(&model, &scene, "PSM1", &short, &Options::default()).unwrap_err().to_string();
    assert!(e.contains("5.0 s long") && e.contains("7.5"), "{e}");
    // A recording of another arm's joints.
    let mut other = h.log.clone();
    other.names[0] = "yaw".into();
    let e = discrepancy(&model, &scene, "PSM1", &other, &Options::default()).unwrap_err().to_string();
    assert!(e.contains("yaw") && e.contains("outer_yaw"), "{e}");
    let e = discrepancy(&model, &scene, "PSM7", &h.log, &Options::default()).unwrap_err().to_string();
    assert!(e.contains("PSM7"), "{e}");
    let e = hidden_effect("psm", &HiddenOptions { enr: Some(-1.0), ..Default::default() }).unwrap_err().to_string();
    assert!(e.contains("enr") && e.contains("-1"), "{e}");
}

/// Issue 63: velocities were kept only where a message had one per joint and dropped silently
/// otherwise, and a NaN velocity went on into the identification's filters. A message with some
/// velocities but not one per joint, or a non-finite one, is refused as efforts are, naming the
/// topic and time; messages without velocities still read.
#[test]
fn malformed_velocities_are_refused_as_efforts_are() {
    use dvrk_sim::recording::ros_msgs::{joint_state_schema, Header, JointState};
    use dvrk_sim::recording::mcap_out::{ros2_schema, McapOut};
    let psm = dvrk_kin::load("psm", None).unwrap();
    let names: Vec<String> = psm.joints.iter().map(|j| j.name.clone()).collect();
    let dir = tempfile::tempdir().unwrap();
    // 200 messages at 100 Hz with their setpoints (the reader wants 100 at least); message
    // 100's velocities as `bad` makes them, every other message's none.
    let write = |file: &str, bad: Vec<f64>| {
        let mut w = McapOut::new(std::io::Cursor::new(Vec::new())).unwrap();
        let (n, d) = joint_state_schema();
        let set = w.add_channel("/PSM1/setpoint_js", ros2_schema(n, &d), "cdr").unwrap();
        let meas = w.add_channel("/PSM1/measured_js", ros2_schema(n, &d), "cdr").unwrap();
        for i in 0..200 {
            let t = 0.01 * i as f64;
            let velocity = if i == 100 { bad.clone() } else if i % 2 == 0 { vec![0.1; 7] } else { vec![] };
            let js = |velocity: Vec<f64>, effort: Vec<f64>| JointState { header: Header::at(t, ""), name: names.clone(), position: vec![0.1; 7], velocity, effort }.encode();
            w.log(set, (t * 1e9).round() as u64, &js(vec![], vec![]));
            w.log(meas, (t * 1e9).round() as u64, &js(velocity, vec![0.0; 7]));
        }
        let path = dir.path().join(file);
        std::fs::write(&path, w.finish().unwrap().into_inner()).unwrap();
        path
    };
    let read = |path: &std::path::Path| dvrk_calib::discrepancy::read_log(path, "mcap", &psm, "PSM1").map(|(log, _)| log).map_err(|e| e.to_string());
    let good = read(&write("good.mcap", vec![0.1; 7])).unwrap();
    assert_eq!(good.len(), 200);
    let e = read(&write("short.mcap", vec![0.1; 3])).unwrap_err();
    assert!(e.contains("short.mcap") && e.contains("/PSM1/measured_js at t = 1 s") && e.contains("3 velocities for 7 joints"), "{e}");
    // Too many is as wrong as too few (the probe's 7 for 6 joints read as if absent).
    let e = read(&write("long.mcap", vec![0.1; 9])).unwrap_err();
    assert!(e.contains("long.mcap") && e.contains("9 velocities for 7 joints"), "{e}");
    let mut nan = vec![0.1; 7];
    nan[2] = f64::NAN;
    let e = read(&write("nan.mcap", nan)).unwrap_err();
    assert!(e.contains("nan.mcap") && e.contains("at t = 1 s") && e.contains("NaN is not finite"), "{e}");
}

/// The detection-rate table: TRIALS seeded trials per class at ENR drawn in [3, 8], and
/// effect-free trials. `DVRK_TRIALS=60 cargo test --release -p dvrk-calib-tests --test calib
/// detection_rate_table -- --ignored --nocapture` (about 16 s a trial on 2 cores).
/// `DVRK_TRACKER=1` adds a tracked marker on the tool shaft (the kinematic channel; link_length joins the classes),
/// `DVRK_KINDS=backlash,latency` picks classes (the tool's `actuator_coulomb_friction` and `actuator_viscous_friction` only this way), `DVRK_FREE=N` the number of effect-free trials,
/// `DVRK_ENR=1,3` draws the ENR in [1, 3] instead (for the detection-rate curve's low end), and
/// `DVRK_FIRST_SEED=1030` starts the class trials there (a table grown in parts; each seed's
/// ENR is fixed by the seed), `DVRK_TRUTH_DT=6.25e-5` sets the truth's step (s). The curve,
/// by ENR bins of 1, closes the table.
#[test]
#[ignore]
fn detection_rate_table() {
    let trials: u64 = env_or("DVRK_TRIALS", 10);
    let first: u64 = env_or("DVRK_FIRST_SEED", 1000).max(1000);
    let tracker = std::env::var("DVRK_TRACKER").is_ok_and(|v| v == "1");
    let mut kinds: Vec<EffectKind> = HIDDEN_KINDS.to_vec();
    if tracker {
        kinds.extend(dvrk_calib::discrepancy::generate::TRACKED_KINDS);
    }
    if let Ok(list) = std::env::var("DVRK_KINDS") {
        // The tool's actuator-space friction is hidden by name only.
        kinds.extend(dvrk_calib::discrepancy::generate::ACTUATOR_KINDS);
        kinds.retain(|k| list.split(',').any(|n| n.trim() == k.name()));
    }
    let truth_dt: f64 = env_or("DVRK_TRUTH_DT", HiddenOptions::default().truth_dt);
    let make = |hidden: Hidden, seed: u64, enr: Option<f64>| {
        let marker = tracker.then(dvrk_calib::discrepancy::generate::MarkerOptions::default);
        hidden_effect("psm", &HiddenOptions { hidden, seed, enr, duration: 30.0, marker, truth_dt, ..Default::default() }).unwrap()
    };
    let (enr_lo, enr_hi) = match std::env::var("DVRK_ENR").ok().and_then(|v| v.split_once(',').and_then(|(a, b)| Some((a.parse::<f64>().ok()?, b.parse::<f64>().ok()?)))) {
        Some(range) => range,
        None => (3.0, 8.0),
    };
    // (ENR, named correctly) of every trial, for the curve.
    let mut curve: Vec<(f64, bool)> = Vec::new();
    println!("| class | trials | named correctly | named wrong | ambiguous | none | CI covers | error mean / RMS | CI half-width median | error / sigma RMS | held-out after / band floor (median) | raw held-out after / noise (median) | tracker held-out after / noise (median) |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    // Trials in parallel (one per core), counted in seed order.
    use rayon::prelude::*;
    let run = |hidden: Hidden, seeds: std::ops::Range<u64>, enr: &(dyn Fn(u64) -> Option<f64> + Sync)| -> Vec<(u64, dvrk_calib::discrepancy::generate::Answer, dvrk_calib::discrepancy::Report)> {
        seeds.into_par_iter().map(|s| {
            let h = make(hidden, s, enr(s));
            let r = analyse(&h, false).report;
            (s, h.answer, r)
        }).collect()
    };
    for kind in kinds {
        let (mut right, mut wrong, mut amb, mut none, mut covered, mut ratios, mut raw, mut kin) = (0, 0, 0, 0, 0, Vec::new(), Vec::new(), Vec::new());
        // Per correctly named trial: estimate / truth - 1, the interval's half-width over
        // |truth|, and the error over the interval's sigma (half-width / 1.96).
        let mut accuracy = IntervalAccuracy::default();
        for (seed, answer, r) in run(Hidden::Kind(kind), first..first + trials, &|s| Some(enr_lo + (enr_hi - enr_lo) * (((s - 1000) * 7919) % 100) as f64 / 100.0)) {
            let truth = &answer.effects[0].spec;
            let correct = r.verdict == "named"
                && r.effects[0].name == truth.name
                && r.effects[0].joint == truth.joint
                && r.effects[0].actuator == truth.actuator
                && (r.effects[0].link == truth.link.as_ref().map(|l| l.to_string())
                    || r.effects[0].payload.as_ref().is_some_and(|p| p.equivalent.iter().any(|q| Some(&q.link) == truth.link.as_ref().map(|l| l.to_string()).as_ref())))
                && r.effects[0].parameters.contains_key(&main_parameter(truth));
            // One line a trial, for the detection-rate curve against ENR.
            let on = truth.joint.clone().or(truth.link.as_ref().map(|l| l.to_string())).or(truth.actuator.map(|a| format!("actuator {a}"))).unwrap_or_else(|| "-".into());
            println!("  trial {} seed {seed} on {on} enr {:.2} verdict {} correct {correct} held-out {:.3}", kind.name(), answer.effects[0].enr, r.verdict, r.rms_heldout_after);
            curve.push((answer.effects[0].enr, correct));
            match r.verdict.as_str() {
                "named" => {
                    let e = &r.effects[0];
                    if correct {
                        right += 1;
                        let p = &main_parameter(truth);
                        if let Some([lo, hi]) = e.ci95.get(p) {
                            if truth.parameters[p] >= *lo && truth.parameters[p] <= *hi {
                                covered += 1;
                            }
                            println!("    {p} {:.5e} in [{lo:.5e}, {hi:.5e}], truth {:.5e}", e.parameters[p], truth.parameters[p]);
                            accuracy.push(e.parameters[p], [*lo, *hi], truth.parameters[p]);
                        }
                        ratios.push(r.rms_heldout_after);
                        raw.push(r.raw_rms_heldout_after);
                        kin.extend(r.kinematic.as_ref().map(|k| k.rms_heldout_after));
                    } else {
                        wrong += 1;
                        println!("  {} seed {seed}: named {} {:?} {:?}", kind.name(), e.name, e.joint, e.link);
                    }
                }
                "ambiguous" => amb += 1,
                _ => none += 1,
            }
        }
        let (m, rm, km) = (median(&mut ratios), median(&mut raw), median(&mut kin));
        println!("| {} | {trials} | {right} | {wrong} | {amb} | {none} | {covered}/{right} | {} | {m:.2} | {rm:.3} | {km:.2} |", kind.name(), accuracy.columns());
    }
    println!("| ENR | trials | named correctly |\n|---|---|---|");
    for bin in (enr_lo.floor() as i64)..(enr_hi.ceil() as i64) {
        let inside: Vec<bool> = curve.iter().filter(|(e, _)| e.floor() as i64 == bin).map(|(_, c)| *c).collect();
        println!("| {bin}-{} | {} | {} |", bin + 1, inside.len(), inside.iter().filter(|c| **c).count());
    }
    let (mut alarms, mut floor_ratios) = (0, Vec::new());
    // DVRK_FREE: how many effect-free trials (default twice the trials per class).
    let free: u64 = env_or("DVRK_FREE", 2 * trials);
    for (seed, _, r) in run(Hidden::None, 5000..5000 + free, &|_| None) {
        floor_ratios.push(r.rms_heldout_after);
        if r.verdict != "none" {
            alarms += 1;
            println!("  effect-free seed {seed}: {} {:?}", r.verdict, r.candidates.first().map(|c| &c.label));
        }
    }
    println!("effect-free: {alarms} false alarms in {free} trials; held-out / band floor median {:.3}", median(&mut floor_ratios));
}

/// The upper median (NaN when empty); sorts `v`.
fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

/// How close the named parameters are to the truth over a table's trials, and whether their
/// intervals are as wide as their errors say they should be (error / sigma RMS near 1).
#[derive(Default)]
struct IntervalAccuracy {
    /// estimate / truth - 1, in percent.
    error_percent: Vec<f64>,
    /// Interval half-width / |truth|, in percent.
    half_width_percent: Vec<f64>,
    /// (estimate - truth) / (half-width / 1.96).
    z: Vec<f64>,
}

impl IntervalAccuracy {
    fn push(&mut self, estimate: f64, [lo, hi]: [f64; 2], truth: f64) {
        let half = (hi - lo) / 2.0;
        self.error_percent.push((estimate / truth - 1.0) * 100.0);
        self.half_width_percent.push(half / truth.abs() * 100.0);
        self.z.push((estimate - truth) / (half / 1.96));
    }

    /// The table's three columns: error mean / RMS, half-width median, error / sigma RMS.
    fn columns(&self) -> String {
        let rms = |v: &[f64]| (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt();
        let mean = self.error_percent.iter().sum::<f64>() / self.error_percent.len() as f64;
        let width = median(&mut self.half_width_percent.clone());
        format!("{mean:+.2}% / {:.2}% | {width:.2}% | {:.2}", rms(&self.error_percent), rms(&self.z))
    }
}

/// A 12 ms latency on a truth whose inertias are a few percent off (seed 1039, 30 s, ENR 5.05,
/// as in the detection table): the inertias' nuisance is refitted on the prediction's timeline,
/// so their error does not move the estimate. Measured: 12.006 ms, interval [11.990, 12.022] ms
/// (the detection table's trial). With the nuisance left on the
/// measured timeline it was 12.077 ms, interval [12.026, 12.129] ms: the truth outside.
#[test]
fn a_latency_is_not_moved_by_the_inertias_error() {
    let h = hidden_effect("psm", &HiddenOptions { hidden: Hidden::Kind(EffectKind::Latency), seed: 1039, enr: Some(5.05), ..fast() }).unwrap();
    let r = analyse(&h, false).report;
    let truth = h.answer.effects[0].spec.parameters["seconds"];
    let e = &r.effects[0];
    let (got, [lo, hi]) = (e.parameters["seconds"], e.ci95["seconds"]);
    eprintln!("latency {got:.6e} s in [{lo:.6e}, {hi:.6e}], truth {truth:.6e}");
    assert_eq!(e.name, "latency");
    assert!(lo <= truth && truth <= hi, "{got} in [{lo}, {hi}], truth {truth}");
    assert!((got - truth).abs() < 20e-6, "{got}, truth {truth}");
}

/// The repeated workflow: a hidden latency is named in round one, the model with it (whose
/// prediction the workflow then shifts) leaves nothing to name in round two, and the named
/// latency is within 5% of the truth (measured 3.987 ms against 4 ms on this 12 s recording,
/// the one the sweep above names; 10.00 ms against 10 ms on 20 s; it was 2.5% short while the
/// generator paired each state with the next step's effort).
#[test]
fn the_repeated_workflow_adds_the_effect_and_stops() {
    use dvrk_calib::discrepancy::discrepancy_repeated;
    let h = trial(Hidden::Kind(EffectKind::Latency), 11, Some(5.0), 12.0);
    let scene = dvrk_sim::Scene::load("psm").unwrap();
    let model = dvrk_kin::load("psm", None).unwrap();
    let out = discrepancy_repeated(&model, &scene, "PSM1", &h.log, &Options { tracking: false, ..Default::default() }, 3).unwrap();
    let r = &out.report;
    eprintln!("steps {:?}", r.steps.iter().map(|s| (&s.verdict, &s.named, s.rms_heldout_before, s.rms_heldout_after)).collect::<Vec<_>>());
    assert_eq!(r.steps.len(), 2, "{:?}", r.steps);
    assert_eq!(r.steps[0].named.as_deref(), Some("latency"));
    assert_eq!(r.steps[1].verdict, "none");
    assert_eq!(out.named.len(), 1);
    assert_eq!(out.model.effects.len(), 1);
    // Round two starts where round one ended (the model's latency applied by the workflow).
    assert!((r.steps[1].rms_heldout_before - r.steps[0].rms_heldout_after).abs() < 0.05 * r.steps[0].rms_heldout_after, "{:?}", r.steps);
    let truth = &h.answer.effects[0].spec.parameters["seconds"];
    let got = r.effects[0].parameters["seconds"];
    assert!((got - truth).abs() < 0.05 * truth, "{got}, truth {truth}");
}

/// The names the repeated workflow gave, as (name, joint or link), sorted.
/// A payload named on a body the report gives as equivalent to the hidden one's (the recording
/// cannot tell them apart) counts under the hidden one's link.
fn named_set(r: &dvrk_calib::discrepancy::Report, h: &HiddenRecording) -> Vec<(String, Option<String>)> {
    let hidden_links: Vec<String> = h.answer.effects.iter().filter_map(|e| e.spec.link.as_ref().map(|l| l.to_string())).collect();
    let as_hidden = |e: &dvrk_calib::discrepancy::report::EffectReport| {
        let equivalent = e.payload.as_ref().and_then(|p| p.equivalent.iter().find(|q| hidden_links.contains(&q.link)));
        e.joint.clone().or(equivalent.map(|q| q.link.clone())).or(e.link.clone())
    };
    let mut v: Vec<_> = r.effects.iter().map(|e| (e.name.clone(), as_hidden(e))).collect();
    v.sort();
    v
}

/// The hidden effects of an answer, as [`named_set`] gives them.
fn hidden_set(h: &HiddenRecording) -> Vec<(String, Option<String>)> {
    let mut v: Vec<_> = h.answer.effects.iter().map(|e| (e.spec.name.clone(), e.spec.joint.clone().or(e.spec.link.as_ref().map(|l| l.to_string())))).collect();
    v.sort();
    v
}

/// Two effects hidden at once (seed 11, 20 s, ENR 5 each): the repeated workflow names one per
/// round, both on their true joint or link with their parameters, then stops with `none`.
#[test]
fn two_hidden_effects_are_named_one_round_each() {
    use dvrk_calib::discrepancy::discrepancy_repeated;
    let h = trial(Hidden::Pair(EffectKind::ViscousFriction, EffectKind::PayloadMass), 11, Some(5.0), 20.0);
    let scene = dvrk_sim::Scene::load("psm").unwrap();
    let model = dvrk_kin::load("psm", None).unwrap();
    let out = discrepancy_repeated(&model, &scene, "PSM1", &h.log, &Options { tracking: false, ..Default::default() }, 4).unwrap();
    let r = &out.report;
    eprintln!("hidden {:?}; steps {:?}", hidden_set(&h), r.steps.iter().map(|s| (&s.verdict, &s.named, s.rms_heldout_before, s.rms_heldout_after)).collect::<Vec<_>>());
    assert_eq!(named_set(r, &h), hidden_set(&h));
    assert_eq!(r.steps.len(), 3, "{:?}", r.steps);
    assert_eq!(r.steps[2].verdict, "none");
    for truth in &h.answer.effects {
        let e = r.effects.iter().find(|e| e.name == truth.spec.name).unwrap();
        let p = &main_parameter(&truth.spec);
        let (got, want) = (e.parameters[p], truth.spec.parameters[p]);
        assert!(((got - want) / want).abs() < 0.1, "{}: {p} = {got}, truth {want}", e.name);
    }
    // Each round closes part of the gap.
    assert!(r.steps[1].rms_heldout_after < r.steps[0].rms_heldout_after && r.steps[0].rms_heldout_after < r.steps[0].rms_heldout_before);
}

/// The repeated workflow on `hidden` (seed 11, 20 s, ENR 5 each), up to 4 rounds.
fn repeated_pair(a: EffectKind, b: EffectKind) -> (std::sync::Arc<HiddenRecording>, dvrk_calib::discrepancy::Report) {
    use dvrk_calib::discrepancy::discrepancy_repeated;
    let h = trial(Hidden::Pair(a, b), 11, Some(5.0), 20.0);
    let scene = dvrk_sim::Scene::load("psm").unwrap();
    let model = dvrk_kin::load("psm", None).unwrap();
    let out = discrepancy_repeated(&model, &scene, "PSM1", &h.log, &Options { tracking: false, ..Default::default() }, 4).unwrap();
    eprintln!("hidden {:?}; steps {:?}; effects {:?}", hidden_set(&h), out.report.steps, out.report.effects);
    (h, out.report)
}

/// A Coulomb friction named in one round is in the next round's model as its fit had it: the
/// next round starts where the last one ended (measured 1.038 and 1.038; with the friction's
/// sign taken on the band-limited velocity instead, 1.08 -> 3.3 on seed 7013's pair), and the
/// second effect then brings the held-out residual to the floor (measured 1.045).
#[test]
fn a_named_friction_carries_into_the_next_round_as_fitted() {
    let (h, r) = repeated_pair(EffectKind::CoulombFriction, EffectKind::JointOffset);
    assert_eq!(named_set(&r, &h), hidden_set(&h));
    let (first, second) = (&r.steps[0], &r.steps[1]);
    assert!((second.rms_before - first.rms_after).abs() < 0.01 * first.rms_after, "{} then {}", first.rms_after, second.rms_before);
    assert!(r.steps.last().unwrap().rms_heldout_after < 1.1);
}

/// Two effects fitted one round each leave the first fitted with the second's signature in
/// the residual (a latency named first, the compliance second: held-out 4.13x the floor after
/// round 2); the refits of every named effect given the others bring both to the truth
/// (measured -0.6% and +1.2%) and the residual to the floor (measured 1.100).
#[test]
fn named_effects_are_refitted_given_each_other() {
    let (h, r) = repeated_pair(EffectKind::JointCompliance, EffectKind::Latency);
    assert_eq!(named_set(&r, &h), hidden_set(&h));
    for truth in &h.answer.effects {
        let e = r.effects.iter().find(|e| e.name == truth.spec.name).unwrap();
        let p = &main_parameter(&truth.spec);
        let (got, want) = (e.parameters[p], truth.spec.parameters[p]);
        assert!(((got - want) / want).abs() < 0.02, "{}: {p} = {got}, truth {want}", e.name);
    }
    assert!(r.steps.last().unwrap().rms_heldout_after < 1.2, "{:?}", r.steps);
}

/// Two-effect trials: TRIALS random pairs at ENR drawn in [3, 8] each, analysed by the repeated
/// workflow. `DVRK_TRIALS=40 cargo test --release -p dvrk-calib-tests --test calib two_effect_table --
/// --ignored --nocapture` (`DVRK_FIRST_SEED`: the first trial's seed, 7000 and up).
#[test]
#[ignore]
fn two_effect_table() {
    use dvrk_calib::discrepancy::discrepancy_repeated;
    let trials: u64 = env_or("DVRK_TRIALS", 10);
    let scene = dvrk_sim::Scene::load("psm").unwrap();
    let model = dvrk_kin::load("psm", None).unwrap();
    // DVRK_FIRST_SEED: where the trials' seeds start (7000), to rerun one.
    let first: u64 = env_or("DVRK_FIRST_SEED", 7000);
    let (mut both, mut one, mut wrong) = (0, 0, 0);
    let start = first.saturating_sub(7000);
    // Trials in parallel (one per core), counted in seed order.
    use rayon::prelude::*;
    let done: Vec<_> = (start..start + trials)
        .into_par_iter()
        .map(|s| {
            let enr = 3.0 + 5.0 * ((s * 7919) % 100) as f64 / 100.0;
            let h = trial(Hidden::RandomPair, 7000 + s, Some(enr), 30.0);
            let out = discrepancy_repeated(&model, &scene, "PSM1", &h.log, &Options { tracking: false, ..Default::default() }, 4).unwrap();
            (s, h, out)
        })
        .collect();
    for (s, h, out) in done {
        let (got, want) = (named_set(&out.report, &h), hidden_set(&h));
        let right = got.iter().filter(|g| want.contains(g)).count();
        let extra = got.len() - right;
        match (right, extra) {
            (2, 0) => both += 1,
            (1, 0) => one += 1,
            _ => {}
        }
        wrong += extra.min(1);
        let last = out.report.steps.last().map(|s| s.rms_heldout_after).unwrap_or(f64::NAN);
        println!("  pair seed {} enr {:?}: hidden {want:?} named {got:?} held-out after {last:.2}", 7000 + s, h.answer.effects.iter().map(|e| (e.enr * 100.0).round() / 100.0).collect::<Vec<_>>());
    }
    println!("two effects: both named {both}, one named (no wrong) {one}, a wrong name {wrong}, of {trials}");
}

fn tracked(hidden: Hidden, seed: u64, enr: Option<f64>) -> HiddenRecording {
    use dvrk_calib::discrepancy::generate::MarkerOptions;
    hidden_effect("psm", &HiddenOptions { hidden, seed, enr, duration: 20.0, marker: Some(MarkerOptions::default()), ..fast() }).unwrap()
}

/// With a tracker on the tool shaft (100 Hz, 0.1 mm, 1 mrad, placed at random; seed 11, 20 s,
/// ENR 5 on the torque channel): the drive's play and compliance and an encoder offset are named
/// with both channels' evidence, within 5% of the truth (7% for the play: measured -3.9%, the
/// torque profile's bias dominates the joint value), and the tracker's held-out residual after
/// the fix is at its noise floor (measured 1.32, 1.02, 1.02; the play's is its profile's bias).
#[test]
fn a_tracker_on_the_shaft_confirms_drive_effects_down_to_its_noise() {
    for (kind, tol, floor) in [(EffectKind::Backlash, 0.07, 1.4), (EffectKind::JointCompliance, 0.05, 1.1), (EffectKind::JointOffset, 0.05, 1.15)] {
        let h = tracked(Hidden::Kind(kind), 11, Some(5.0));
        let r = analyse(&h, false).report;
        let k = r.kinematic.as_ref().unwrap();
        let truth = &h.answer.effects[0].spec;
        eprintln!("{}: {:?}; tracker {:.2} -> {:.2} held out {:.2} -> {:.2}", kind.name(), r.effects.first().map(|e| (&e.name, &e.joint, &e.parameters, &e.ci95)), k.rms_before, k.rms_after, k.rms_heldout_before, k.rms_heldout_after);
        assert_eq!((r.verdict.as_str(), r.channel.as_str()), ("named", "torque+kinematic"));
        let e = &r.effects[0];
        assert_eq!((&e.name, &e.joint), (&truth.name, &truth.joint));
        let p = &main_parameter(truth);
        assert!(((e.parameters[p] - truth.parameters[p]) / truth.parameters[p]).abs() < tol, "{p} {} truth {}", e.parameters[p], truth.parameters[p]);
        assert!(k.rms_heldout_before > 3.0 && k.rms_heldout_after < floor, "{} -> {}", k.rms_heldout_before, k.rms_heldout_after);
        // The tracker's noise is estimated, not given: 0.1 mm and 1 mrad per axis.
        assert!((k.noise_position / 1e-4 - 1.0).abs() < 0.05 && (k.noise_rotation / 1e-3 - 1.0).abs() < 0.05, "{} {}", k.noise_position, k.noise_rotation);
    }
}

/// A DH length hidden on the insertion stage (the one length between moving joints that a shaft
/// marker sees without opening a loop: the parallelogram's links change together or not at
/// all): the torque channel cannot see it, the tracker can, and names it within 2% of the truth
/// (measured -1.8259 against -1.8162 mm). Effect-free, the tracker's residual is at its noise
/// and nothing is named.
#[test]
fn a_length_only_the_tracker_sees_is_found() {
    let h = tracked(Hidden::Kind(EffectKind::LinkLength), 11, None);
    let r = analyse(&h, false).report;
    let truth = &h.answer.effects[0].spec;
    let link = truth.link.as_ref().map(|l| l.to_string());
    eprintln!("{} {:?} truth {:?} {:?}; first candidate {:?}", r.verdict, r.effects.first().map(|e| (&e.link, &e.parameters, &e.ci95)), link, truth.parameters, r.candidates.first());
    assert_eq!(r.verdict, "named");
    let e = &r.effects[0];
    assert_eq!((e.name.as_str(), &e.link), ("link_length", &link));
    assert!(((e.parameters["a"] - truth.parameters["a"]) / truth.parameters["a"]).abs() < 0.02);
    let free = analyse(&tracked(Hidden::None, 3, None), false).report;
    let k = free.kinematic.as_ref().unwrap();
    assert_eq!(free.verdict, "none", "{:?}", free.candidates.first().map(|c| &c.label));
    assert!(k.rms_heldout_before < 1.1 && k.rms_before < 1.1, "{} {}", k.rms_before, k.rms_heldout_before);
}

/// A tracker's clock off either way and a cable drive's play by motion direction (issue 62 items
/// 1 and 2; synth's tracker-only kinds, 12 s, a tracker on the tool shaft, the efforts removed):
/// each named on the kinematic channel with its sign and joint, its interval holding the truth,
/// the tracker's held-out residual brought to its noise, and the report saying which stream is
/// late or which play and why. Measured (seed: truth -> estimate): clock 3: -29.07 -> -29.07 ms,
/// clock 4: +14.06 -> +14.07 ms, play 3: outer_pitch 4.557 -> 4.556 mrad. The independent
/// generator's table (tests/python/independent_psm.py): docs/discrepancy-validation.md.
#[test]
fn a_trackers_clock_either_way_and_a_motion_play_are_named_without_efforts() {
    for (kind, seed, note) in [(EffectKind::ClockOffset, 3, "the joint stream is"), (EffectKind::ClockOffset, 4, "the tracker's poses"), (EffectKind::MotionPlay, 3, "play on outer_pitch: by motion direction")] {
        use dvrk_calib::discrepancy::generate::MarkerOptions;
        let mut h = hidden_effect("psm", &HiddenOptions { hidden: Hidden::Kind(kind), seed, duration: 12.0, marker: Some(MarkerOptions::default()), ..fast() }).unwrap();
        for e in &mut h.log.effort {
            e.clear();
        }
        let r = analyse(&h, false).report;
        let truth = &h.answer.effects[0].spec;
        let p = main_parameter(truth);
        eprintln!("{kind:?} {seed}: {} {:?} truth {}", r.verdict, r.effects.first().map(|e| (&e.joint, e.parameters[&p], e.ci95[&p])), truth.parameters[&p]);
        let top: Vec<_> = r.candidates.iter().take(3).map(|c| (&c.label, c.effect.delta_bic)).collect();
        assert_eq!((r.verdict.as_str(), r.channel.as_str()), ("named", "kinematic"), "{kind:?} {seed}: {top:?}");
        let e = &r.effects[0];
        assert_eq!((&e.name, &e.joint), (&truth.name, &truth.joint), "{top:?}");
        let [lo, hi] = e.ci95[&p];
        assert!(lo <= truth.parameters[&p] && truth.parameters[&p] <= hi, "{p} {} in [{lo}, {hi}], truth {}", e.parameters[&p], truth.parameters[&p]);
        let k = r.kinematic.as_ref().unwrap();
        assert!(k.rms_heldout_before > 2.0 && k.rms_heldout_after < 1.1, "{} -> {}", k.rms_heldout_before, k.rms_heldout_after);
        assert!(r.notes.iter().any(|n| n.contains(note)), "{:?}", r.notes);
    }
}

/// The tool's actuator-space friction hidden (issue 40 items 4 and 6; seed 11, 12 s, ENR 5, on
/// the jaw's actuator 7, which the wrist pitch and yaw turn): a Coulomb friction is named on its
/// actuator within 1%; a viscous one is `ambiguous` between actuators 6 and 7, which move alike
/// while the jaw holds, and the experiment asks for the jaw to move. (Measured with the CLI at
/// 20 s: fc 0.015873 against 0.015870 N·m; the viscous pair's delta BIC 2420 and 2417.)
#[test]
fn the_tools_actuator_friction_is_named_at_its_actuator() {
    let h = trial(Hidden::Kind(EffectKind::ActuatorCoulombFriction), 11, Some(5.0), 12.0);
    let r = analyse(&h, false).report;
    let truth = &h.answer.effects[0].spec;
    let top: Vec<_> = r.candidates.iter().take(3).map(|c| (&c.label, c.effect.delta_bic)).collect();
    assert_eq!(r.verdict, "named", "{top:?}");
    let e = &r.effects[0];
    assert_eq!((e.name.as_str(), e.actuator), ("actuator_coulomb_friction", truth.actuator), "{top:?}");
    assert!((e.parameters["fc"] / truth.parameters["fc"] - 1.0).abs() < 0.01, "{:?} {:?}", e.parameters, truth.parameters);
    assert_eq!(e.label(), format!("actuator_coulomb_friction on actuator {}", truth.actuator.unwrap()));
    let h = trial(Hidden::Kind(EffectKind::ActuatorViscousFriction), 11, Some(5.0), 12.0);
    let r = analyse(&h, false).report;
    let top: Vec<_> = r.candidates.iter().take(3).map(|c| (&c.label, c.effect.delta_bic)).collect();
    assert_eq!(r.verdict, "ambiguous", "{top:?}");
    assert!(top[..2].iter().all(|(l, _)| l.starts_with("actuator_viscous_friction on actuator ")), "{top:?}");
    assert!(r.experiment.as_deref().is_some_and(|x| x.contains("open and close the jaw")), "{:?}", r.experiment);
}

/// A recording of encoders and a tracked marker without efforts (issue 40 item 5): the kinematic
/// channel runs alone, names the hidden insertion-stage length as with efforts (within 2% of
/// the truth), and the report says which channel and why. Without the marker as well there is
/// nothing to analyse: a one-line error.
#[test]
fn a_recording_without_efforts_runs_the_kinematic_channel_alone() {
    let mut h = tracked(Hidden::Kind(EffectKind::LinkLength), 11, None);
    for e in &mut h.log.effort {
        e.clear();
    }
    assert!(!h.log.has_efforts());
    let r = analyse(&h, false).report;
    let truth = &h.answer.effects[0].spec;
    eprintln!("{} {} {:?}", r.verdict, r.channel, r.effects.first().map(|e| (&e.link, &e.parameters)));
    assert_eq!((r.verdict.as_str(), r.channel.as_str()), ("named", "kinematic"));
    let e = &r.effects[0];
    assert_eq!((e.name.as_str(), &e.link), ("link_length", &truth.link.as_ref().map(|l| l.to_string())));
    assert!(((e.parameters["a"] - truth.parameters["a"]) / truth.parameters["a"]).abs() < 0.02, "{:?} {:?}", e.parameters, truth.parameters);
    assert!(r.notes.iter().any(|n| n.starts_with("no measured efforts in the recording: the kinematic channel alone")), "{:?}", r.notes);
    assert!(r.joints.is_empty() && r.raw_rms_heldout_before.is_nan() && r.rms_heldout_after < r.rms_heldout_before);
    // As a file: the MCAP reader takes a measured_js without efforts, says so, and the run
    // without the marker is a one-line error naming the file and topic.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("no-efforts.mcap");
    std::fs::write(&path, dvrk_sim::recording::write_joint_log_mcap(&h.log, "PSM1").unwrap()).unwrap();
    let model = dvrk_kin::load("psm", None).unwrap();
    let (log, notes) = dvrk_calib::discrepancy::read_log(&path, "auto", &model, "PSM1").unwrap();
    assert!(!log.has_efforts() && notes.iter().any(|n| n.contains("/PSM1/measured_js carries no efforts")), "{notes:?}");
    let e = dvrk_calib::discrepancy::from_file::run(&path, "auto", &model, "PSM1", None, &Options::default(), 1).err().unwrap().to_string();
    assert!(e.contains("no-efforts.mcap") && e.contains("carries no efforts and no tracked marker was given") && !e.contains('\n'), "{e}");
    h.log.markers = None;
    let scene = dvrk_sim::Scene::load("psm").unwrap();
    let e = discrepancy(&model, &scene, "PSM1", &h.log, &Options::default()).err().unwrap().to_string();
    assert!(e.contains("no efforts and no tracked marker") && !e.contains('\n'), "{e}");
}

/// A payload on the parallelogram's bottom link (issue 62 item 3; seed 5, 20 s, 80 g near its
/// centre of mass, the inertias held near the model's: `--inertia-prior 0.1,0.002`): the link
/// translates (its orientation is fixed while the pitch moves), so every point of it circles on
/// its crank, frame 6's a = 0.150 m, and gravity fixes the mass times the crank wherever the
/// weight sits. The pitch linkage's bodies carry the same load alike: whichever the inertia
/// prefers is named and the others are listed as equivalent, the bottom link among them with
/// the crank's first moment (measured: pitch_bottom named, 0.01198 against 0.01207 kg m;
/// pitch_end 1.0 and pitch_top 4.9 behind in delta BIC).
#[test]
fn a_payload_on_a_translating_link_has_the_cranks_first_moment() {
    use dvrk_calib::discrepancy::nuisance::InertiaPrior;
    let h = hidden_effect("psm", &HiddenOptions { hidden: Hidden::Kind(EffectKind::PayloadMass), seed: 5, duration: 20.0, payload_link: Some("pitch_bottom".into()), ..fast() }).unwrap();
    let truth = &h.answer.effects[0].spec;
    let moment = truth.parameters["mass"] * 0.150;
    let scene = dvrk_sim::Scene::load("psm").unwrap();
    let model = dvrk_kin::load("psm", None).unwrap();
    let o = Options { inertia_prior: InertiaPrior { from_model: true, rotational: 0.1, mass: 0.002 }, ..Default::default() };
    let r = discrepancy(&model, &scene, "PSM1", &h.log, &o).unwrap().report;
    assert_eq!(r.verdict, "named", "{:?}", r.candidates.iter().take(3).map(|c| (&c.label, c.effect.delta_bic)).collect::<Vec<_>>());
    let e = &r.effects[0];
    let p = e.payload.as_ref().unwrap();
    eprintln!("{:?} {} {:?} crank {:?}; {:?}; {:?}", e.link, p.first_moment, p.first_moment_ci95, p.crank, p.equivalent.iter().map(|q| (&q.link, q.first_moment, q.behind_bic)).collect::<Vec<_>>(), p.family);
    let family = ["pitch_back", "pitch_bottom", "pitch_top", "pitch_front", "pitch_end", "main_insertion", "counterweight"];
    assert!(e.link.as_deref().is_some_and(|l| family.contains(&l)), "{:?}", e.link);
    let bottom = match e.link.as_deref() {
        Some("pitch_bottom") => {
            assert!((p.crank.unwrap() - 0.150).abs() < 1e-6 && p.cannot_fix[0].contains("translates"), "{:?} {:?}", p.crank, p.cannot_fix);
            assert!(p.first_moment_ci95[0] <= p.first_moment && p.first_moment <= p.first_moment_ci95[1]);
            p.first_moment
        }
        _ => p.equivalent.iter().find(|q| q.link == "pitch_bottom").expect("the bottom link among the equivalents").first_moment,
    };
    assert!((bottom / moment - 1.0).abs() < 0.05, "{bottom} against {moment}");
    assert!(!p.equivalent.is_empty() && p.family.as_deref().is_some_and(|f| f.contains("outer_yaw and outer_pitch")), "{:?}", p.family);
    // About the pitch's axis, whichever family body is named: the crank's first moment.
    let (axis, ci) = (p.axis_first_moment.unwrap(), p.axis_first_moment_ci95.unwrap());
    assert_eq!(p.axis_joint.as_deref(), Some("outer_pitch"));
    assert!((axis / moment - 1.0).abs() < 0.05 && ci[0] <= axis && axis <= ci[1], "{axis} {ci:?} against {moment}");
}

/// A payload hidden on a moving body drawn by the seed (any of the PSM's 13, the parallelogram's
/// links included), within 3 cm of its centre of mass, at an ENR drawn in [3, 8], as a user meets
/// it: the robot identified first (`dvrk identify` on the same seed's effect-free recording: the
/// same truth and motion), then the weighted recording analysed with that model (one round). Is
/// the payload named, on its body or one the report gives as equivalent, with its mass within
/// 20%? `DVRK_TRIALS=30 DVRK_FIRST_SEED=2000 cargo test --release -p dvrk-calib-tests --test calib
/// payload_anywhere_table -- --ignored --nocapture` (about a minute a trial). `DVRK_CAD=1`
/// analyses with the CAD model instead (its relative inertia prior).
#[test]
#[ignore]
fn payload_anywhere_table() {
    use dvrk_calib::discrepancy::generate::ANY_BODY;
    use dvrk_calib::identify::{identify, output::identified_model, IdentifyOptions};
    let trials: u64 = env_or("DVRK_TRIALS", 30);
    let first: u64 = env_or("DVRK_FIRST_SEED", 2000);
    let cad = std::env::var("DVRK_CAD").is_ok_and(|v| v == "1");
    let dir = tempfile::tempdir().unwrap();
    let scene = dvrk_sim::Scene::load("psm").unwrap();
    let psm = dvrk_kin::load("psm", None).unwrap();
    let (mut named, mut body_set, mut mass_ok) = (0, 0, 0);
    println!("| seed | truth body | truth mass (kg) | ENR | verdict | named | set | mass (kg) |\n|---|---|---|---|---|---|---|---|");
    for seed in first..first + trials {
        let enr = 3.0 + 5.0 * (((seed * 7919) % 100) as f64 / 100.0);
        let h = hidden_effect("psm", &HiddenOptions { hidden: Hidden::Kind(EffectKind::PayloadMass), seed, enr: Some(enr), duration: 30.0, payload_link: Some(ANY_BODY.into()), ..Default::default() }).unwrap();
        let model = if cad {
            psm.clone()
        } else {
            let free = hidden_effect("psm", &HiddenOptions { hidden: Hidden::None, seed, duration: 30.0, ..Default::default() }).unwrap();
            let path = dir.path().join(format!("free{seed}.mcap"));
            std::fs::write(&path, recording::write_joint_log_mcap(&free.log, "PSM1").unwrap()).unwrap();
            let rec = dvrk_calib::identify::read_log(&path, "mcap", &psm, "PSM1").unwrap().0;
            let prior = dvrk_sim::scene::builtin_inertials("psm", &psm).unwrap().body_inertias(&psm).unwrap();
            let options = IdentifyOptions::full(Vec::new());
            let (id, _) = identify(&psm, &prior, &rec, &options).unwrap();
            dvrk_kin::Model::compile(identified_model(&psm, &id, &options.processing, &rec.joint_map(), &prior, "effect-free").unwrap().spec).unwrap()
        };
        let r = discrepancy(&model, &scene, "PSM1", &h.log, &Options { tracking: false, ..Default::default() }).unwrap().report;
        let truth = &h.answer.effects[0].spec;
        let link = truth.link.as_ref().map(|l| l.to_string());
        let e = r.effects.first().filter(|e| e.name == "payload_mass");
        let in_set = e.is_some_and(|e| e.link == link || e.payload.as_ref().is_some_and(|p| p.equivalent.iter().any(|q| Some(&q.link) == link.as_ref())));
        let (want, got) = (truth.parameters["mass"], e.map_or(0.0, |e| e.parameters["mass"]));
        let close = in_set && ((got - want) / want).abs() < 0.2;
        named += e.is_some() as usize;
        body_set += in_set as usize;
        mass_ok += close as usize;
        println!("| {seed} | {} | {want:.3} | {:.1} | {} | {} | {in_set} | {got:.3} |", link.as_deref().unwrap_or("-"), h.answer.effects[0].enr, r.verdict, e.map_or("-".into(), |e| e.label()));
    }
    println!("\n{trials} trials: payload named {named}, on its body set {body_set}, mass within 20% {mass_ok}");
}

/// The identification's Stribeck term is a candidate (issue 62 item 4): an effect-free recording
/// with a Stribeck hump added to the outer yaw's effort, computed here from the recording's own
/// positions (`fs exp(-(v / vs)^2) sign(v)`, 0.15 N·m at vs 0.05 rad/s: 1.5 times the noise, the motor supplying it),
/// is named a Coulomb friction's `fs` on the outer yaw with its level and velocity.
#[test]
fn a_stribeck_hump_is_named_as_the_coulomb_frictions_term() {
    let h = trial(Hidden::None, 3, None, 20.0);
    let mut log = h.log.clone();
    let (fs, vs) = (0.15, 0.05);
    let n = log.t.len();
    for i in 0..n {
        let (a, b) = (i.saturating_sub(1), (i + 1).min(n - 1));
        let v = (log.position[b][0] - log.position[a][0]) / (log.t[b] - log.t[a]);
        log.effort[i][0] += fs * (-(v / vs).powi(2)).exp() * (v / 1e-3).tanh();
    }
    let scene = dvrk_sim::Scene::load("psm").unwrap();
    let model = dvrk_kin::load("psm", None).unwrap();
    let r = discrepancy(&model, &scene, "PSM1", &log, &Options { tracking: false, ..Default::default() }).unwrap().report;
    let top: Vec<_> = r.candidates.iter().take(4).map(|c| (&c.label, c.effect.delta_bic, c.effect_to_noise, c.supported, c.heldout_p_value, &c.effect.parameters)).collect();
    assert_eq!(r.verdict, "named", "{top:?}");
    let e = &r.effects[0];
    assert_eq!((e.name.as_str(), e.joint.as_deref()), ("coulomb_friction", Some("outer_yaw")), "{top:?}");
    assert_eq!(r.candidates[0].label, "coulomb_friction fs on outer_yaw", "{top:?}");
    assert!((e.parameters["fs"] / fs - 1.0).abs() < 0.2, "{:?}", e.parameters);
    assert!((e.parameters["vs"] / vs - 1.0).abs() < 0.6, "{:?}", e.parameters);
}

/// A spring between the tool's coupled actuators is a candidate (issue 62 item 4): an effect-free
/// recording with a cable of actuator 7 pulled by actuator 5's position (its force `k a5` at
/// actuator 7, 0.02 N·m/rad, reaching the joints as `C^-T` does, computed here from the model's
/// coupling matrix) is the best candidate, `actuator_cross_spring` with `k5` within 20%, supported.
/// The recording's jaw holds still (its joint is not analysed), and a force at actuator 6 or 7
/// then loads the analysed joints alike: the two are `ambiguous` (measured: the same delta BIC).
#[test]
fn a_spring_between_the_tools_actuators_is_named_with_its_source() {
    let h = trial(Hidden::None, 3, None, 20.0);
    let model = dvrk_kin::load("psm", None).unwrap();
    let c = model.coupling_matrix().unwrap();
    let inv = c.clone().try_inverse().unwrap();
    let k = 0.02;
    let mut log = h.log.clone();
    for (q, tau) in log.position.iter().zip(log.effort.iter_mut()) {
        let a = &inv * nalgebra::DVector::from_column_slice(q);
        // Actuator 7 (index 6) carries k a5; the joints feel C^-T of it.
        let mut f = nalgebra::DVector::zeros(q.len());
        f[6] = k * a[4];
        let joint = inv.transpose() * f;
        tau.iter_mut().zip(joint.iter()).for_each(|(t, d)| *t += d);
    }
    let scene = dvrk_sim::Scene::load("psm").unwrap();
    let r = discrepancy(&model, &scene, "PSM1", &log, &Options { tracking: false, ..Default::default() }).unwrap().report;
    let top: Vec<_> = r.candidates.iter().take(4).map(|c| (&c.label, c.effect.delta_bic, c.effect_to_noise, &c.effect.parameters)).collect();
    assert_eq!(r.verdict, "ambiguous", "{top:?}");
    let best = &r.candidates[0];
    assert!(["actuator_cross_spring k5 on actuator 7", "actuator_cross_spring k5 on actuator 6"].contains(&best.label.as_str()) && best.supported, "{top:?}");
    assert!((best.effect.parameters["k5"] / k - 1.0).abs() < 0.2, "{:?}", best.effect.parameters);
}
