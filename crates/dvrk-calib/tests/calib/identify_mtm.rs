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
    let (_, notes) = dvrk_calib::recordings::read_joint_log_parts(&one, "wpi-csv", &model, "MTMR", dvrk_calib::recordings::Parts::Measured).unwrap();
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
