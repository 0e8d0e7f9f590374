//! Identification on the real WPI recordings (../shared/data/external/wpi-dvrk-dynamics, skipped
//! with a message when absent): fit on `one`, predict `two`.

use crate::util::psm;
use dvrk_calib::identify::{identify, read_wpi_csv, report, IdentifyOptions};
use std::path::{Path, PathBuf};

/// `file` of the WPI recordings (`insertion-payload/...` for the second data set), or `None` with
/// a message when the external data are absent.
pub(crate) fn wpi(file: &str) -> Option<PathBuf> {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../../shared/data/external/wpi-dvrk-dynamics").join(file);
    if p.exists() {
        Some(p)
    } else {
        eprintln!("SKIPPED: {} is absent (external data, see ../shared/data/external/README.md)", p.display());
        None
    }
}

/// The CAD PSM identified on `one`, with both recordings (None, with a message, without them).
#[derive(Clone)]
struct Fitted {
    model: dvrk_kin::Model,
    prior: Vec<dvrk_kin::BodyInertia>,
    r1: dvrk_calib::identify::JointLog,
    r2: dvrk_calib::identify::JointLog,
    options: IdentifyOptions,
    id: dvrk_calib::identify::Identification,
}

/// [`Fitted`], identified once per test binary and shared by the tests that start from it.
fn fitted_on_one() -> Option<Fitted> {
    static FITTED: std::sync::OnceLock<Option<Fitted>> = std::sync::OnceLock::new();
    FITTED.get_or_init(fit_on_one).clone()
}

fn fit_on_one() -> Option<Fitted> {
    let (one, two) = (wpi("psm_one_results.csv")?, wpi("psm_two_results.csv")?);
    let model = psm();
    let prior = dvrk_sim::scene::builtin_inertials("psm", &model).unwrap().body_inertias(&model).unwrap();
    let (r1, r2) = (read_wpi_csv(&one, &model).unwrap(), read_wpi_csv(&two, &model).unwrap());
    let options = IdentifyOptions::for_model(&model);
    let (id, _) = identify(&model, &prior, &r1, &options).unwrap();
    Some(Fitted { model, prior, r1, r2, options, id })
}

/// Published by the recordings' authors for their model on `two` (q1..q7).
const PUBLISHED: [f64; 7] = [0.093, 0.178, 0.191, 0.134, 0.239, 0.213, 0.264];

#[test]
fn real_psm_recordings_identify_physically_and_predict_the_held_out_one() {
    let Some(params) = wpi("psm_params.json") else { return };
    let Some(Fitted { model, prior, r1, r2, options, id }) = fitted_on_one() else { return };
    assert_eq!((r1.len(), r2.len()), (5999, 5999));
    assert_eq!(IdentifyOptions::psm(), options);
    let (held_out, in_band, as_published) = id.validate_all(&model, &r2, &options).unwrap();
    let as_published = as_published.unwrap().relative_error;
    let rigid_options = options.rigid_only();
    let (rigid, _) = identify(&model, &prior, &r1, &rigid_options).unwrap();
    let (rigid_held_out, _) = rigid.validate(&model, &r2, &rigid_options).unwrap();
    eprintln!("held-out relative error: {held_out:.4?}\nin the analysis band:    {in_band:.4?}\nas published:            {as_published:.4?}\nrigid body only:         {rigid_held_out:.3?}\npublished:               {PUBLISHED:.3?}");
    // Every body's pseudo-inertia is positive semidefinite (the published parameters were not).
    assert!(id.fit.min_eigen.iter().all(|l| *l > -1e-9), "{:?}", id.fit.min_eigen);
    for (b, body) in model.bodies.iter().enumerate() {
        if !id.fit.degenerate_bodies.contains(&b) {
            id.body_inertia(b, &body.name).unwrap();
        }
    }
    // Measured 0.052 0.107 0.185 0.158 0.105 0.140 0.155 (in band 0.048 0.106 0.162 0.121 0.098
    // 0.132 0.144): at or below the published figures on every channel but the roll, 18% above
    // them against the raw efforts (the authors' own published roll parameters give 0.172 on
    // `two` with this metric; their 0.134 is against filtered efforts over one period, see
    // `the_authors_protocol_reproduces...`). With their protocol: 0.049 0.100 0.165 0.120 0.102
    // 0.130 0.148, below theirs on every channel. The effects matter on every channel.
    for c in 0..7 {
        // The sensor noise above the analysis band is part of the raw figure, not of the banded one.
        assert!(in_band[c] < held_out[c], "channel {c}: in band {} vs raw {}", in_band[c], held_out[c]);
        assert!(in_band[c] <= PUBLISHED[c], "channel {c}: in band {} vs published {}", in_band[c], PUBLISHED[c]);
        assert!(as_published[c] <= PUBLISHED[c], "channel {c}: as published {} vs published {}", as_published[c], PUBLISHED[c]);
        assert!(held_out[c] < 0.75 * rigid_held_out[c], "channel {c}: {} vs rigid {}", held_out[c], rigid_held_out[c]);
        let bound = if c == 3 { 1.2 * PUBLISHED[c] } else { PUBLISHED[c] };
        assert!(held_out[c] <= bound, "channel {c}: {} vs published {} (bound {bound})", held_out[c], PUBLISHED[c]);
    }
    // Friction of the first three joints agrees with the original authors' own identification
    // (psm_params.json links 1, 2 and 8: Fc, Fv) to 15%, for the friction model they used (a
    // sharp Coulomb sign: the chosen options smooth the pitch and insertion signs more, which
    // moves effort from fc to fv).
    let sharp = IdentifyOptions::full(vec![3, 4, 5, 6]);
    let (id_sharp, _) = identify(&model, &prior, &r1, &sharp).unwrap();
    let p: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(params).unwrap()).unwrap();
    let effects = report::effects(&id_sharp);
    for (channel, link) in [("outer_yaw", "1"), ("outer_pitch", "2"), ("outer_insertion", "8")] {
        for (ours, theirs) in [("coulomb_friction", "Fc"), ("viscous_friction", "Fv")] {
            let e = effects.iter().find(|e| e.name == ours && e.joint == channel).unwrap();
            let v = e.parameters.values().next().unwrap().as_f64().unwrap();
            let w = p[link][theirs].as_f64().unwrap();
            eprintln!("{channel} {ours}: ours {v:.4}, WPI {w:.4}");
            assert!((v / w - 1.0).abs() < 0.15, "{channel} {ours}: {v} vs {w}");
        }
    }
    // (That the ablation ends at these options with these figures is `dvrk identify`'s test,
    // `identify_json_and_output_file` in tests/cli.rs: the CLI runs it anyway.)
}

/// The WPI authors' protocol (`identify::as_published`: efforts low-passed by a sixth-order
/// zero-phase Butterworth at 17 Hz, 200 samples trimmed, the excitation's first period)
/// reproduces their published roll error on `two` from their own published roll parameters
/// (`psm_params.json` link 10: `Fc sign(qd) + Fo + Fv qd + Im qdd + K q`, positions and velocities
/// low-passed like the efforts): 0.1356 against their 0.134 (0.1345 over the 1111 samples of
/// their nominal 0.18 Hz base frequency). Against the raw efforts over the whole recording the
/// same parameters give 0.172: the published figures are not `relative_error`.
#[test]
fn the_authors_protocol_reproduces_their_published_roll_error_from_their_parameters() {
    use dvrk_calib::identify::as_published::{relative_error, window, Protocol};
    use dvrk_calib::filter::{derivative, Butterworth};
    let (Some(two), Some(params)) = (wpi("psm_two_results.csv"), wpi("psm_params.json")) else { return };
    let rec = read_wpi_csv(&two, &psm()).unwrap();
    let protocol = Protocol::default();
    let w = window(&rec, 0, rec.len(), &protocol).unwrap();
    assert_eq!((w.start, w.stop, w.period), (200, 1496, Some(1296)));
    let p: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(params).unwrap()).unwrap();
    let k = |name: &str| p["10"][name].as_f64().unwrap();
    let roll = |x: &[Vec<f64>]| x.iter().map(|v| v[3]).collect::<Vec<f64>>();
    let (q, qd, tau) = (roll(&rec.position), roll(&rec.velocity), roll(&rec.effort));
    let f = Butterworth::new(protocol.order, protocol.cutoff_hz, w.rate);
    let pad = 40;
    let (qf, qdf, qddf) = (f.filtfilt(&q, pad), f.filtfilt(&qd, pad), f.filtfilt(&derivative(&qd, 1.0 / w.rate), pad));
    let model = |q: f64, qd: f64, qdd: f64| k("Fc") * qd.signum() + k("Fo") + k("Fv") * qd + k("Im") * qdd + k("K") * q;
    let e = relative_error(&tau, |i| model(qf[i], qdf[i], qddf[i]), &w, &protocol);
    let qdd = derivative(&qd, 1.0 / w.rate);
    let (num, den) = (0..rec.len()).fold((0.0, 0.0), |(n, d), i| (n + (tau[i] - model(q[i], qd[i], qdd[i])).powi(2), d + tau[i] * tau[i]));
    let raw = (num / den).sqrt();
    eprintln!("the authors' roll parameters on two: {e:.4} with their protocol (published 0.134), {raw:.4} against the raw efforts");
    assert!((e - PUBLISHED[3]).abs() < 0.003, "{e}");
    assert!(raw > 0.165, "{raw}");
}

/// A small-part prior names a body the model has, with a positive size.
#[test]
fn a_small_part_prior_on_an_unknown_body_or_of_no_size_is_refused() {
    use dvrk_calib::identify::{SmallBody, JointLog};
    let model = psm();
    let prior = dvrk_sim::scene::builtin_inertials("psm", &model).unwrap().body_inertias(&model).unwrap();
    let t: Vec<f64> = (0..400).map(|i| i as f64 / 200.0).collect();
    let q: Vec<Vec<f64>> = t.iter().map(|t| (0..7).map(|j| 0.2 * (t * (1.0 + j as f64)).sin() + if j == 2 { 0.12 } else { 0.0 }).collect()).collect();
    let qd: Vec<Vec<f64>> = t.iter().map(|t| (0..7).map(|j| 0.2 * (1.0 + j as f64) * (t * (1.0 + j as f64)).cos()).collect()).collect();
    let rec = JointLog { source: "r.csv".into(), effort: qd.clone(), position: q, velocity: qd, t, names: model.joints.iter().map(|j| j.name.clone()).collect(), ..JointLog::default() };
    let mut options = IdentifyOptions::psm();
    options.small_bodies.push(SmallBody { name: "tool_shaft".into(), mass_kg: 0.002, radius_m: 0.01 });
    let e = identify(&model, &prior, &rec, &options).unwrap_err().to_string();
    assert!(e.contains("small body `tool_shaft`: model psm has no such body"), "{e}");
    options.small_bodies.pop();
    options.small_bodies[0].radius_m = 0.0;
    let e = identify(&model, &prior, &rec, &options).unwrap_err().to_string();
    assert!(e.contains("small body `tool_pitch_link`: mass 0.002 kg and radius 0 m must be positive"), "{e}");
}

#[test]
fn bad_wpi_files_name_the_line_and_column() {
    let model = psm();
    let row = vec!["0.1"; 21].join(",");
    let e = dvrk_sim::recording::parse_wpi_csv(&format!("{row}\n0.1,0.2\n"), Path::new("r.csv"), &model).unwrap_err().to_string();
    assert_eq!(e, "r.csv: line 2: 2 columns; wpi-csv has 21 (q, qd, tau of 7 joints)");
    let bad = row.replacen("0.1", "nan", 1);
    let e = dvrk_sim::recording::parse_wpi_csv(&format!("{row}\n{bad}\n"), Path::new("r.csv"), &model).unwrap_err().to_string();
    assert_eq!(e, "r.csv: line 2, column 1: NaN is not finite");
    let e = dvrk_sim::recording::parse_wpi_csv(&format!("{row}\n"), Path::new("r.csv"), &model).unwrap_err().to_string();
    assert_eq!(e, "r.csv: 1 samples; identification needs at least 100");
    let ecm = dvrk_kin::load("ecm", None).unwrap();
    let e = dvrk_sim::recording::parse_wpi_csv(&row, Path::new("r.csv"), &ecm).unwrap_err().to_string();
    assert_eq!(e, "r.csv: wpi-csv holds a PSM's or an MTM's 7 joints; model `ecm` has 4");
}

/// Must-show 3: the identified model in the simulator, driven by `two`'s recorded efforts under
/// weak feedback (0.3 x the scene's kp, kd), follows `two`'s motion better than the CAD model on
/// every joint, whether the CAD scene runs its own 12 Gauss-Seidel sweeps or the identified
/// scene's 30. Measured (RMS, CAD 12 sweeps / CAD 30 sweeps -> identified, with its [drive]):
/// yaw 0.0330 / 0.0320 -> 0.0061 rad, pitch 0.086 / 0.090 -> 0.0087 rad, insertion 6.5 / 6.5 ->
/// 2.1 mm, roll 0.0261 -> 0.0062, wrist pitch 0.0213 -> 0.0116, wrist yaw 0.0201 -> 0.0092, jaw
/// 0.0205 -> 0.0090 rad. With the scene's joint damping on top of the identified friction (before
/// the model file carried its drive): yaw 0.0076, pitch 0.024, insertion 1.9 mm, roll 0.025,
/// wrist 0.021 / 0.019, jaw 0.0115.
///
/// Regression guard: at the scene's 12 sweeps the identified yaw stuck at zero velocity for
/// 30% of the recording (the under-converged loop closure; RMS 0.126 rad, worse than CAD).
#[test]
fn identified_model_replays_the_held_out_efforts_closer_than_cad() {
    use dvrk_calib::identify::output::identified_model;
    use dvrk_calib::identify::replay::{identified_scene, torque_replay, IDENTIFIED_PGS_ITERATIONS};
    let Some(Fitted { model, prior, r1, r2, options, id }) = fitted_on_one() else { return };
    let base = dvrk_sim::Scene::load("psm").unwrap();
    let identified = identified_model(&model, &id, &options.processing, &r1.joint_map(), &prior, "one").unwrap();
    assert!(identified.kept_prior.is_empty(), "{:?}", identified.kept_prior);
    let scene = identified_scene(&base, 0, &identified).unwrap();
    assert_eq!(scene.arms[0].pgs_iterations, Some(IDENTIFIED_PGS_ITERATIONS));
    let mut cad_sweeps = base.clone();
    cad_sweeps.arms[0].pgs_iterations = Some(IDENTIFIED_PGS_ITERATIONS);
    let (cad, _) = torque_replay(&base, 0, &r2, 0.3).unwrap();
    let (cad30, _) = torque_replay(&cad_sweeps, 0, &r2, 0.3).unwrap();
    let (ident, _) = torque_replay(&scene, 0, &r2, 0.3).unwrap();
    eprintln!("torque-driven replay of two, RMS per joint: CAD {cad:.5?}\n  CAD at {IDENTIFIED_PGS_ITERATIONS} sweeps {cad30:.5?}\n  identified {ident:.5?}");
    for k in 0..7 {
        assert!(ident[k] <= cad[k].min(cad30[k]), "joint {k}: identified {} vs CAD {} / {}", ident[k], cad[k], cad30[k]);
    }
    // The arm's joints whose load is inertia, gravity and the arm's friction: several times closer.
    for k in [0, 1, 2, 6] {
        assert!(ident[k] < 0.6 * cad[k].min(cad30[k]), "joint {k}: identified {} vs CAD {} / {}", ident[k], cad[k], cad30[k]);
    }
}

/// `dvrk identify -o`: the output is a model file. Loaded back with `dvrk_kin::load` it carries
/// every body's identified inertial and the identified effects in the model's vocabulary (the
/// yaw's friction as identified; the wrist actuators' friction and springs as actuator effects),
/// and the drive they were fitted with; put on the scene's arm the way `dvrk sim --model
/// PSM1=FILE` does it, it replays `two` exactly as the identified scene does.
#[test]
fn identify_output_is_a_model_file_the_simulator_loads() {
    use dvrk_calib::identify::output::{identified_model, output_toml};
    use dvrk_calib::identify::replay::{identified_scene, torque_replay};
    let Some(Fitted { model, prior, r1, r2, options, id }) = fitted_on_one() else { return };
    let identified = identified_model(&model, &id, &options.processing, &r1.joint_map(), &prior, "one").unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("psm-identified.toml");
    std::fs::write(&path, output_toml(&identified, "one").unwrap()).unwrap();
    let loaded = dvrk_kin::load(path.to_str().unwrap(), None).unwrap();
    assert_eq!(loaded.spec.inertials.len(), model.bodies.len());
    for (b, body) in model.bodies.iter().enumerate() {
        // Mass and first moment as identified (the moments may move by the solver's round-off to
        // obey the triangle inequality exactly).
        let file = loaded.file_inertia(b).unwrap();
        let p = &id.theta.as_slice()[b * 10..b * 10 + 4];
        assert!((file.mass - p[0]).abs() <= 1e-12 * p[0] && (file.com * file.mass - nalgebra::Vector3::new(p[1], p[2], p[3])).norm() < 1e-12, "{}", body.name);
    }
    // Yaw friction at 0.5 rad/s: the model's effort is the identified (fc + fd) tanh(v / vc) + fo
    // + fv v (the presliding level fd joins the Coulomb one: the vocabulary has no presliding).
    let est = |name: &str| id.estimates.iter().find(|e| e.name == name).unwrap().value;
    let mut tau = vec![0.0; 7];
    let mut qd = vec![0.0; 7];
    qd[0] = 0.5;
    dvrk_kin::effects::effort(&loaded.effects, &loaded.home(), &qd, 0.0, &mut tau);
    let expected = (est("outer_yaw.fc") + est("outer_yaw.fd")) * (0.5 / options.processing.coulomb_velocity_of(0)).tanh() + est("outer_yaw.fo") + est("outer_yaw.fv") * 0.5;
    assert!((-tau[0] - expected).abs() < 1e-12, "{} vs {expected}", -tau[0]);
    // The pitch's winding term (issue 62 item 4): its Coulomb level grows by fq q^2 (and its
    // spring pulls it back to 0).
    let mut q = loaded.home();
    q[1] = -0.5;
    let mut qd = vec![0.0; 7];
    qd[1] = 0.3;
    let mut tau = vec![0.0; 7];
    dvrk_kin::effects::effort(&loaded.effects, &q, &qd, 0.0, &mut tau);
    let level = est("outer_pitch.fc") + est("outer_pitch.fd") + est("outer_pitch.fq") * 0.25;
    let expected = level * (0.3 / options.processing.coulomb_velocity_of(1)).tanh() + est("outer_pitch.fo") + est("outer_pitch.fv") * 0.3 + est("outer_pitch.k") * -0.5;
    assert!(est("outer_pitch.fq") != 0.0 && (-tau[1] - expected).abs() < 1e-12, "{} vs {expected}", -tau[1]);
    // The wrist actuators' friction and springs are actuator effects (issue 40 item 4): their
    // joint efforts are to_joint^-T of the channels' identified efforts, (fc + fd) tanh(a' / vc)
    // + fo + fv a' + k a at the actuators' positions a and velocities a' (to_joint^-1 q, q').
    let (q, qd) = (loaded.home(), [0.0, 0.0, 0.0, 0.0, 0.4, -0.3, 0.5]);
    let inv = r1.joint_map().try_inverse().unwrap();
    let (a, ad) = (&inv * nalgebra::DVector::from_column_slice(&q), &inv * nalgebra::DVector::from_column_slice(&qd));
    let channel = nalgebra::DVector::from_fn(7, |c, _| {
        if c < 4 {
            return 0.0;
        }
        let n = |t: &str| est(&format!("{} actuator.{t}", model.joints[c].name));
        (n("fc") + n("fd")) * (ad[c] / options.processing.coulomb_velocity_of(c)).tanh() + n("fo") + n("fv") * ad[c] + n("k") * a[c]
    });
    let expected = inv.transpose() * channel;
    // (The cross springs between actuators: `cross_springs_are_effects`.)
    let actuator_effects: Vec<_> = loaded.effects.iter().filter(|e| e.actuator.is_some() && e.kind != dvrk_kin::effects::EffectKind::ActuatorCrossSpring).cloned().collect();
    assert_eq!(actuator_effects.len(), 12, "friction (Coulomb, viscous), spring, motor inertia on actuators 5..7");
    let mut tau = vec![0.0; 7];
    dvrk_kin::effects::effort(&actuator_effects, &q, &qd, 0.0, &mut tau);
    for j in 0..7 {
        assert!((-tau[j] - expected[j]).abs() < 1e-12, "joint {j}: {} vs {}", -tau[j], expected[j]);
    }
    assert!(!loaded.spec.notes.contains("actuator.fv = "), "no actuator friction is left in the notes: {}", loaded.spec.notes);
    // The winding, presliding and cross-channel spring terms are effects (issue 62 item 4): the
    // notes list none of them, and each presliding level sits on its Coulomb effect with the
    // displacement its state was fitted with.
    for term in [".fq = ", ".fd = ", ".k from "] {
        assert!(!loaded.spec.notes.contains(term), "{term} left in the notes: {}", loaded.spec.notes);
    }
    let coulomb = |name: &str, joint: Option<&str>, actuator: Option<usize>| {
        loaded.spec.effects.iter().find(|e| e.name == name && e.joint.as_deref() == joint && e.actuator == actuator).unwrap_or_else(|| panic!("{name} {joint:?} {actuator:?}")).parameters.clone()
    };
    let yaw = coulomb("coulomb_friction", Some("outer_yaw"), None);
    assert_eq!((yaw["fd"], yaw["sigma"]), (est("outer_yaw.fd"), options.processing.dahl_displacement_of(0)));
    let wrist_yaw = coulomb("actuator_coulomb_friction", None, Some(6));
    assert_eq!((wrist_yaw["fd"], wrist_yaw["sigma"]), (est("outer_wrist_yaw actuator.fd"), options.processing.dahl_displacement_of(5)));
    // In the simulator, as `dvrk sim --model PSM1=FILE` puts it: the file's [drive] replaces
    // the scene's joint damping (the identified viscous frictions hold it) and raises the
    // armature where the identified motor inertia is larger (the insertion), the loop gets the
    // sweeps identified inertias need, and the arm replays `two` exactly as the identified scene
    // does.
    let base = dvrk_sim::Scene::load("psm").unwrap();
    let mut from_file = base.clone();
    from_file.set_model(0, loaded).unwrap();
    assert!(from_file.arms[0].inertials.bodies.iter().all(|b| b.provenance == "dvrk identify from one"));
    let a = &from_file.arms[0];
    let im = identified.armature[2].unwrap();
    assert_eq!(a.damping, 0.0);
    assert!(im > base.arms[0].armature[2] && a.armature[2] == im, "insertion armature {} (identified {im})", a.armature[2]);
    assert_eq!(a.armature[0], base.arms[0].armature[0]);
    assert_eq!(a.pgs_iterations, Some(dvrk_calib::identify::replay::IDENTIFIED_PGS_ITERATIONS));
    let reference = identified_scene(&base, 0, &identified).unwrap();
    let (a, _) = torque_replay(&from_file, 0, &r2, 0.3).unwrap();
    let (b, _) = torque_replay(&reference, 0, &r2, 0.3).unwrap();
    assert_eq!(a, b);
}

/// Identify on `one`, then the discrepancy workflow on `two` (the recording the fit never saw):
/// the identified model (with its [drive]) leaves less band-limited effort residual than the
/// CAD model on every joint. Without the drive the workflow added the scene's joint damping
/// (0.1 N·m s/rad on every tree joint) to friction identified with it inside, and the
/// identified model came out worse than CAD on the yaw, pitch and wrist (yaw 0.187 vs 0.084
/// N·m on `one` itself). Measured on `two`, held-out band RMS identified / CAD (N·m, N): yaw
/// 0.0475 / 0.0835, pitch 0.0837 / 0.2843, insertion 0.1325 / 0.6222, roll 0.0006 / 0.0746,
/// wrist pitch 0.0037 / 0.0786, wrist yaw 0.0032 / 0.0532, jaw 0.0019 / 0.0458 (the same to
/// the last digit with one candidate analysed as with all of them: 1.9 s against 15.6 s).
#[test]
fn the_identified_model_leaves_less_discrepancy_than_cad_on_the_held_out_recording() {
    use dvrk_calib::discrepancy::read_log;
    use dvrk_calib::discrepancy::{discrepancy, scene_for_arm};
    use dvrk_calib::identify::output::identified_model;
    let Some(Fitted { model, prior, r1, options, id, .. }) = fitted_on_one() else { return };
    let Some(two) = wpi("psm_two_results.csv") else { return };
    let identified = dvrk_kin::Model::compile(identified_model(&model, &id, &options.processing, &r1.joint_map(), &prior, "one").unwrap().spec).unwrap();
    let scene = scene_for_arm("PSM1").unwrap();
    // Only the residual before any effect is compared, which the search over the candidates
    // does not change: one candidate is analysed, not the forty.
    let o = crate::util::residual_before_only();
    let band = |m: &dvrk_kin::Model| {
        let (log, _) = read_log(&two, "wpi-csv", m, "PSM1").unwrap();
        let r = discrepancy(m, &scene, "PSM1", &log, &o).unwrap().report;
        r.joints.iter().map(|j| (j.joint.clone(), j.band_rms_heldout_before)).collect::<Vec<_>>()
    };
    let (cad, ident) = (band(&model), band(&identified));
    eprintln!("held-out band RMS on two (N·m, N): CAD {cad:.4?}\n  identified {ident:.4?}");
    assert_eq!(cad.len(), 7);
    for ((joint, c), (_, i)) in cad.iter().zip(&ident) {
        assert!(i < c, "{joint}: identified {i} vs CAD {c}");
    }
}

/// `--format mcap`: a simulated PSM tracking test recorded by dvrk-sim (measured_js with
/// efforts, 200 Hz) identifies the simulator's own drive terms in closed form: on the wrist
/// joints the viscous term is the joint damping (0.1 N·m s/rad) and the motor inertia the scene's
/// armature (0.004 kg m^2; the roll's together with the tool links', see below), the Coulomb
/// level ~0 (the simulator has none).
#[test]
fn a_simulated_recording_gives_back_the_simulators_damping_and_armature() {
    use dvrk_calib::identify::read_log;
    use dvrk_calib::identify::output::identified_model;
    use dvrk_calib::identify::report::effects;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("psm.mcap");
    let scene = dvrk_sim::Scene::load("psm").unwrap();
    // Explicit Coriolis: rapier's implicit term adds dt dc/dv to the mass the drives see, and the
    // roll's whole inertia came out 16% high with it (8.6% without).
    let sim = dvrk_sim::SimOptions { coriolis: dvrk_sim::Coriolis::Explicit, ..Default::default() };
    let options = dvrk_sim::RunOptions { duration: 20.0, trajectory: dvrk_sim::run::TrajectoryKind::Sine, sim };
    dvrk_sim::run_recorded(&scene, &options, Some(&dvrk_sim::RecordOptions { path: path.clone(), rate: 200.0 }), |_| {}).unwrap();
    let model = psm();
    let rec = read_log(&path, "mcap", &model, "PSM1").unwrap().0;
    assert_eq!(rec.names[0], "outer_yaw");
    let prior = dvrk_sim::scene::builtin_inertials("psm", &model).unwrap().body_inertias(&model).unwrap();
    let options = IdentifyOptions::full(vec![3, 4, 5, 6]);
    let (id, _) = identify(&model, &prior, &rec, &options).unwrap();
    assert!(id.fit.min_eigen.iter().all(|l| *l > -1e-9));
    let all = effects(&id);
    let get = |name: &str, joint: &str, p: &str| all.iter().find(|e| e.name == name && e.joint == joint).unwrap().parameters[p].as_f64().unwrap();
    for joint in ["outer_roll", "outer_wrist_pitch", "outer_wrist_yaw"] {
        let (fv, im, fc) = (get("viscous_friction", joint, "fv"), get("armature", joint, "im"), get("coulomb_friction", joint, "fc"));
        eprintln!("{joint}: fv {fv:.5} N·m s/rad (damping 0.1), im {im:.5} kg m^2 (armature 0.004), fc {fc:.2e} N·m");
        assert!((fv - 0.1).abs() < 0.005 && fc < 1e-3, "{joint}: fv {fv}, fc {fc}");
        if joint != "outer_roll" {
            assert!((im - 0.004).abs() < 0.0002, "{joint}: im {im}");
        }
    }
    // The roll's motor inertia is not separable from the tool links': their inertias are
    // isotropic (the SDF's 0.001 kg m^2), so their share about the roll axis does not change with
    // the wrist. Their sum is: the roll's whole inertia, identified against the simulator's
    // (0.0090 kg m^2 = 0.005 links + 0.004 armature; the sim's roll row matches Newton-Euler to
    // 1e-5). Measured: 0.00978 at both poses, 8.6% high. The recording barely shows it (the
    // sine's inertial torque is 6% of the damping's, in quadrature) and a single frequency cannot
    // tell an inertia from a spring (k q = -k a / w^2): the fit puts 6.6e-4 N m/rad on the roll's
    // spring (the simulator has none) and the inertia follows; without the roll's spring term the
    // roll comes out 0.00858 (-4.7%). Hence 12%.
    let identified = identified_model(&model, &id, &options.processing, &rec.joint_map(), &prior, "sim").unwrap();
    let ident_model = dvrk_kin::Model::compile(identified.spec.clone()).unwrap();
    let ident_scene = dvrk_calib::identify::replay::identified_scene(&scene, 0, &identified).unwrap();
    let roll = model.joint_id("outer_roll").unwrap();
    let inertia = |m: &dvrk_kin::Model, bodies: Vec<dvrk_kin::BodyInertia>, armature: f64, q: &[f64]| {
        let dm = dvrk_kin::DynamicsModel::new(m, bodies).unwrap();
        let mut mass = nalgebra::DMatrix::zeros(m.nq(), m.nq());
        dvrk_kin::mass_matrix(m, &dm, &mut dvrk_kin::DynamicsData::new(m), q, &mut mass).unwrap();
        mass[(roll, roll)] + armature
    };
    for q in [model.home(), vec![0.3, -0.2, 0.12, 0.7, -0.5, 0.4, 0.6]] {
        let truth = inertia(&model, prior.clone(), scene.arms[0].armature[roll], &q);
        let got = inertia(&ident_model, ident_scene.arms[0].inertials.body_inertias(&ident_model).unwrap(), identified.armature[roll].unwrap(), &q);
        eprintln!("roll inertia at {q:.2?}: identified {got:.5} kg m^2, simulated {truth:.5}");
        assert!((got - truth).abs() < 0.12 * truth, "roll inertia {got} vs {truth}");
    }
    // A missing topic and a wrong arm name are named.
    let e = read_log(&path, "mcap", &model, "PSM2").unwrap_err().to_string();
    assert!(e.contains("no topic /PSM2/measured_js; topics:"), "{e}");
}

/// The tool's cross-channel springs (issue 62 item 4), fitted beside the wrist's presliding
/// states: the model file carries them as `actuator_cross_spring`s, exactly. Each channel's
/// effort (roll's included: its channel is a joint, its actuator's a scaled copy) takes `k x_s`
/// from every other channel's position `x_s`, and the file's effects give `to_joint^-T` of that
/// to 1e-12.
#[test]
fn cross_springs_are_effects() {
    use dvrk_calib::identify::output::identified_model;
    let Some(Fitted { model, prior, r1, options, id, .. }) = fitted_on_one() else { return };
    let identified = identified_model(&model, &id, &options.processing, &r1.joint_map(), &prior, "one").unwrap();
    let mut spec = model.spec.clone();
    spec.effects = identified.effects.iter().filter(|e| e.name == "actuator_cross_spring").cloned().collect();
    assert!(spec.effects.len() >= 4, "cross springs on the roll's and the wrist's actuators: {:?}", spec.effects);
    assert!(identified.not_expressed.iter().all(|s| !s.contains(".k from ")), "{:?}", identified.not_expressed);
    let m = dvrk_kin::Model::compile(spec).unwrap();
    let q = [0.1, -0.2, 0.12, 0.4, 0.3, -0.25, 0.5];
    let inv = r1.joint_map().try_inverse().unwrap();
    let x = &inv * nalgebra::DVector::from_column_slice(&q);
    let channel = nalgebra::DVector::from_fn(7, |c, _| {
        (0..7).filter(|&s| s != c).filter_map(|s| id.estimates.iter().find(|e| e.name == format!("{}.k from {}", id.channels[c], id.channels[s])).map(|e| e.value * x[s])).sum::<f64>()
    });
    assert!((3..7).all(|c| channel[c] != 0.0), "{channel}");
    let expected = inv.transpose() * channel;
    let mut tau = vec![0.0; 7];
    dvrk_kin::effects::effort(&m.effects, &q, &[0.0; 7], 0.0, &mut tau);
    for j in 0..7 {
        assert!((-tau[j] - expected[j]).abs() < 1e-12, "joint {j}: {} vs {}", -tau[j], expected[j]);
    }
}
