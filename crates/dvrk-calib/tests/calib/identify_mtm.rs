//! Identification of the real MTM (WPI's recordings, ../shared/data/external/wpi-dvrk-dynamics/mtm,
//! skipped with a message when absent): the columns read as the arm's actuators, the model fitted
//! on `one` predicting `two` better than the recordings' authors' own model, physically.

use super::identify::wpi;
use dvrk_calib::identify::{identify, read_wpi_csv, IdentifyOptions, JointLog};
use dvrk_kin::dynamics::{mass_matrix, DynamicsData, DynamicsModel};
use nalgebra::DMatrix;

/// The WPI authors' SDP model on `two`, their MTM notebook's protocol (`main_mtm.ipynb`, cell 46:
/// `norm(tau_f_test - tau_p_sdp_test) / norm(tau_f_test)`, per joint q1..q7; their paper's
/// "below 16.3% on the first three joints" is their WLS model's 0.0818, 0.1631, 0.1906).
const WPI_SDP_TWO: [f64; 7] = [0.07691726, 0.14853754, 0.16953016, 0.223162, 0.27995774, 0.23416671, 0.33950312];

struct Fitted {
    model: dvrk_kin::Model,
    two: JointLog,
    options: IdentifyOptions,
    id: dvrk_calib::identify::Identification,
}

fn fit(model: dvrk_kin::Model, one: &JointLog, two: JointLog, options: IdentifyOptions) -> Fitted {
    let prior = dvrk_sim::scene::builtin_inertials("mtmr", &model).unwrap().body_inertias(&model).unwrap();
    let (id, _) = identify(&model, &prior, one, &options).unwrap();
    Fitted { model, two, options, id }
}

/// The recordings hold the arm's actuators (the elbow channel the forearm's angle from the
/// shoulder), as the authors' recording script wrote them: read as joints, the same rigid body and
/// friction predict `two`'s elbow and platform far worse.
#[test]
fn wpi_mtm_columns_are_the_arms_actuators() {
    let (Some(one), Some(two)) = (wpi("mtm/one_results.csv"), wpi("mtm/two_results.csv")) else { return };
    let model = dvrk_kin::load("mtmr", None).unwrap();
    let (r1, r2) = (read_wpi_csv(&one, &model).unwrap(), read_wpi_csv(&two, &model).unwrap());
    assert_eq!(r1.names[1..4], ["shoulder_pitch actuator", "elbow_pitch actuator", "wrist_platform actuator"]);
    assert_eq!((r1.names[0].as_str(), r1.names[4].as_str()), ("outer_yaw", "wrist_pitch"));
    assert_eq!(r1.to_joint.as_ref(), model.coupling.as_ref());
    let (_, notes) = dvrk_sim::recording::read_joint_log_parts(&one, "wpi-csv", &model, "MTMR", dvrk_sim::recording::Parts::Measured).unwrap();
    assert!(notes.iter().any(|n| n.starts_with("795 of 5999 rows (13.3%) repeat the row before")), "{notes:?}");
    let mut options = IdentifyOptions::full(Vec::new());
    options.processing.cutoff = 4.0;
    let as_actuators = fit(model.clone(), &r1, r2.clone(), options.clone());
    let as_joints = |r: &JointLog| JointLog { to_joint: Some(DMatrix::identity(7, 7)), ..r.clone() };
    let read_as_joints = fit(model, &as_joints(&r1), as_joints(&r2), options);
    let err = |f: &Fitted| f.id.validate(&f.model, &f.two, &f.options).unwrap().0;
    let (a, j) = (err(&as_actuators), err(&read_as_joints));
    eprintln!("held-out error on two, read as actuators {a:.3?}, as joints {j:.3?}");
    assert!(a[2] < 0.8 * j[2] && a[3] < 0.95 * j[3], "elbow, platform: {a:?} vs {j:?}");
    assert!(a[1] < j[1], "shoulder: {a:?} vs {j:?}");
}

/// Fitted on `one` with the MTM options, `two` is predicted better than the authors' own model on
/// every joint, with their protocol; the identified bodies are physical and the mass matrix
/// positive definite over the joint space.
#[test]
fn real_mtm_identified_on_one_predicts_two_better_than_published() {
    let (Some(one), Some(two)) = (wpi("mtm/one_results.csv"), wpi("mtm/two_results.csv")) else { return };
    let model = dvrk_kin::load("mtmr", None).unwrap();
    let (r1, r2) = (read_wpi_csv(&one, &model).unwrap(), read_wpi_csv(&two, &model).unwrap());
    let options = IdentifyOptions::for_model(&model);
    assert_eq!(options, IdentifyOptions::mtm());
    let f = fit(model, &r1, r2, options);
    let (raw, _, published) = f.id.validate_all(&f.model, &f.two, &f.options).unwrap();
    let published = published.unwrap();
    assert!(published.cable_removed && (published.cutoff_hz - 5.655).abs() < 0.01, "{published:?}");
    eprintln!("two, WPI's MTM protocol {:.3?} (theirs {WPI_SDP_TWO:.3?}); as recorded {raw:.3?}", published.relative_error);
    for (c, (ours, theirs)) in published.relative_error.iter().zip(WPI_SDP_TWO).enumerate() {
        assert!(*ours < theirs, "channel {c}: {ours} against the published {theirs}");
    }
    // Measured 0.052, 0.133, 0.113: the yaw within 0.10, the shoulder and elbow not (docs/mtm.md).
    assert!(published.relative_error[..3].iter().all(|e| *e < 0.14), "{:?}", published.relative_error);
    assert!(f.id.fit.min_eigen.iter().all(|l| *l > -1e-9), "pseudo-inertias {:?}", f.id.fit.min_eigen);
    // The identified inertials: every body physical, M(q) positive definite at 10,000 poses.
    let inertias: Vec<_> = f.model.bodies.iter().enumerate().map(|(b, body)| f.id.body_inertia(b, &body.name).unwrap()).collect();
    let dm = DynamicsModel::new(&f.model, inertias).unwrap();
    let mut data = DynamicsData::new(&f.model);
    let mut m = DMatrix::zeros(7, 7);
    let mut lowest = f64::INFINITY;
    // A fixed low-discrepancy walk over the joint ranges (Weyl sequence: no random crate here).
    for i in 0..10_000 {
        let q: Vec<f64> = f.model.joints.iter().enumerate().map(|(j, jt)| jt.lower + (jt.upper - jt.lower) * ((i as f64 + 0.5) * (2.0f64.sqrt() * (j + 1) as f64 + 0.1 * j as f64)).fract()).collect();
        mass_matrix(&f.model, &dm, &mut data, &q, &mut m).unwrap();
        lowest = lowest.min(m.clone().symmetric_eigenvalues().min());
    }
    eprintln!("smallest eigenvalue of M(q) over 10,000 poses: {lowest:.3e} kg m^2");
    assert!(lowest > 1e-7, "{lowest}");
}

/// Gravity compensation as a user calibrates it: the MTM identified on `two` feeds its holding
/// torque forward (effort mode) to the twin of the MTM identified on `one` (the `mtm` scene), at
/// ten poses inside the middle 60% of the joint ranges `two` covers. Measured: the arm's joints
/// (yaw, shoulder, elbow) drift 0.007 to 0.25 rad in 5 s (median 0.027) where without
/// compensation they fall 0.59 to 0.93 rad; the wrist pitch is not held (up to 1.3 rad): its
/// identified static torque differs between the two sessions (docs/mtm.md).
#[test]
fn gravity_compensation_identified_on_two_holds_the_twin_identified_on_one() {
    let Some(two) = wpi("mtm/two_results.csv") else { return };
    let (model, r2, options, prior, id) = identified_on(&two);
    let identified = dvrk_calib::identify::output::identified_model(&model, &id, &options.processing, &r2.joint_map(), &prior, "two").unwrap();
    let gc_model = dvrk_kin::Model::compile(identified.spec).unwrap();
    let gc_inertias: Vec<_> = model.bodies.iter().enumerate().map(|(b, body)| id.body_inertia(b, &body.name).unwrap()).collect();
    // The scene's arm is the built-in identification on `one` (models/mtmr-wpi.toml).
    let mut scene = dvrk_sim::Scene::load("mtm").unwrap();
    scene.arms[0].gravity_compensation = false;
    let dm = DynamicsModel::new(&gc_model, gc_inertias).unwrap();
    let mut data = DynamicsData::new(&gc_model);
    let g = nalgebra::Vector3::from(scene.gravity);
    let (mut held, mut fell, mut ratio) = (0.0f64, f64::INFINITY, 0.0f64);
    // The joint ranges the recordings cover (joint space), their middle 60%.
    let joints: Vec<Vec<f64>> = r2.position.iter().map(|a| model.joints_from_actuators(a).unwrap()).collect();
    let range: Vec<(f64, f64)> = (0..7).map(|j| joints.iter().fold((f64::MAX, f64::MIN), |(lo, hi), q| (lo.min(q[j]), hi.max(q[j])))).collect();
    for (i, q0) in (0..10).map(|i| (i, pose(&range, i))) {
        let run = |compensate: bool, data: &mut DynamicsData| {
            let mut s = scene.clone();
            s.set_start(0, &q0).unwrap();
            let mut sim = dvrk_sim::Sim::new(&s, &dvrk_sim::SimOptions::default()).unwrap();
            for j in 0..7 {
                sim.set_mode(j, dvrk_sim::Mode::Effort).unwrap();
            }
            let mut tau = [0.0; 7];
            for _ in 0..5000 {
                if compensate {
                    dvrk_kin::dynamics::holding_torque(&gc_model, &dm, data, &sim.q()[..7], &g, &mut tau).unwrap();
                }
                for (j, t) in tau.iter().enumerate() {
                    sim.set_effort(j, *t).unwrap();
                }
                sim.step();
            }
            let d: Vec<f64> = sim.q()[..7].iter().zip(&q0).map(|(q, q0)| (q - q0).abs()).collect();
            eprintln!("    {} per joint {d:.3?}", if compensate { "with   " } else { "without" });
            // The arm's joints: yaw, shoulder, elbow.
            d[..3].iter().fold(0.0, |a: f64, b| a.max(*b))
        };
        let (with, without) = (run(true, &mut data), run(false, &mut data));
        eprintln!("pose {i} {q0:.2?}: arm drift after 5 s {with:.3e} rad with two's compensation, {without:.3e} rad without");
        held = held.max(with);
        fell = fell.min(without);
        ratio = ratio.max(with / without);
    }
    assert!(fell > 0.5, "uncompensated {fell}");
    assert!(held < 0.3 && ratio < 0.5, "compensated {held} rad, at worst {ratio} of the uncompensated drift");
}

/// Pose `i` of ten spread over the middle 60% of each joint's `(lower, upper)` (a fixed Weyl sequence).
fn pose(range: &[(f64, f64)], i: usize) -> Vec<f64> {
    range.iter().enumerate().map(|(j, (lo, hi))| lo + (hi - lo) * (0.2 + 0.6 * ((i as f64 + 0.5) * (2.0f64.sqrt() * (j + 1) as f64)).fract())).collect()
}

/// The built-in `mtmr-wpi` (models/mtmr-wpi.toml, the `mtm` scene's arm) is what `dvrk identify
/// --model mtmr --format wpi-csv --recording one_results.csv -o` writes today: regenerate it with
/// that command when the identification changes.
#[test]
fn the_builtin_mtmr_wpi_is_todays_identification_on_one() {
    let Some(one) = wpi("mtm/one_results.csv") else { return };
    let (model, _, _, _, id) = identified_on(&one);
    let builtin = dvrk_kin::load("mtmr-wpi", None).unwrap();
    assert_eq!(builtin.spec.inertials.len(), model.bodies.len());
    for (b, body) in model.bodies.iter().enumerate() {
        let (now, shipped) = (id.body_inertia(b, &body.name).unwrap(), builtin.spec.inertials.iter().find(|i| i.body == body.name).unwrap());
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-6 * (1e-3 + a.abs().max(b.abs()));
        assert!(close(now.mass, shipped.mass) && (0..3).all(|k| close(now.com[k], shipped.com[k])), "{}: {now:?} vs {shipped:?} (regenerate models/mtmr-wpi.toml)", body.name);
    }
}

/// The MTMR identified on the WPI recording `path` with the MTM options: the model, the
/// recording, the options, the prior and the identification.
fn identified_on(path: &std::path::Path) -> (dvrk_kin::Model, JointLog, IdentifyOptions, Vec<dvrk_kin::BodyInertia>, dvrk_calib::identify::Identification) {
    let model = dvrk_kin::load("mtmr", None).unwrap();
    let rec = read_wpi_csv(path, &model).unwrap();
    let options = IdentifyOptions::mtm();
    let prior = dvrk_sim::scene::builtin_inertials("mtmr", &model).unwrap().body_inertias(&model).unwrap();
    let (id, _) = identify(&model, &prior, &rec, &options).unwrap();
    (model, rec, options, prior, id)
}

/// The platform's joint test read as recorded: the cubic fitted to the mean of its two sweeps
/// follows the authors' own 7th-order fit of it (`main_mtm.ipynb`) over 0..2.8 rad (the range the
/// recordings use) within 5 mN·m RMS; a file that is not a joint test is refused naming its line.
#[test]
fn the_platform_joint_test_gives_the_cable_prior_the_authors_fitted() {
    let Some(test) = wpi("mtm/joint_test_cable.csv") else { return };
    let fit = dvrk_calib::identify::cable_prior::from_joint_test(&test, 3).unwrap();
    assert!(fit.range.0 < -1.0 && fit.range.1 > 3.0, "{fit:?}");
    let cubic = |q: f64| fit.constant + q * (fit.prior.value[0] + q * (fit.prior.value[1] + q * fit.prior.value[2]));
    let theirs = dvrk_calib::identify::as_published::wpi_mtm_cable;
    let grid: Vec<f64> = (0..=28).map(|k| 0.1 * k as f64).collect();
    let rms = (grid.iter().map(|q| (cubic(*q) - theirs(*q)).powi(2)).sum::<f64>() / grid.len() as f64).sqrt();
    eprintln!("joint test: cubic {:?} + {:.4}, misfit {:.4} N·m, friction {:.4} N·m; against the authors' polynomial {rms:.4} N·m RMS", fit.prior.value, fit.constant, fit.misfit_rms, fit.friction);
    assert!(rms < 0.005 && fit.misfit_rms < 0.01 && fit.friction > 0.0, "{rms} {fit:?}");
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.csv");
    std::fs::write(&bad, "0.1,0.0,0.2\n0.2,0.3\n").unwrap();
    let e = dvrk_calib::identify::cable_prior::from_joint_test(&bad, 3).unwrap_err().to_string();
    assert!(e.contains("line 2") && e.contains("2 columns"), "{e}");
}
