//! The `[[effects]]` section: checking against the vocabulary and bounds, the kinematic effects
//! applied at compile time, and the friction / spring efforts in closed form.

use dvrk_kin::effects::{effort, EffectKind};
use dvrk_kin::load::{builtin_text, load_toml_text};
use dvrk_kin::{FrameRef, Model};
use std::path::Path;

fn psm_with(effects: &str) -> dvrk_kin::Result<Model> {
    load_toml_text(&format!("{}\n{effects}", builtin_text("psm").unwrap()), Path::new("psm-effects.toml"), None, None)
}

#[test]
fn joint_offset_is_the_encoder_zero() {
    let nominal = dvrk_kin::load("psm", None).unwrap();
    let m = psm_with("[[effects]]\nname = \"joint_offset\"\njoint = \"outer_pitch\"\nparameters = { offset = 0.02 }\n").unwrap();
    // The reading q puts every frame where the nominal model puts q + offset.
    let q = [0.3, -0.4, 0.12, 0.2, 0.1, -0.3, 0.5];
    let mut shifted = q;
    shifted[1] += 0.02;
    let (a, b) = (m.fk(&q).unwrap(), nominal.fk(&shifted).unwrap());
    let worst = a.iter().zip(&b).map(|(x, y)| (x.translation.vector - y.translation.vector).norm()).fold(0.0, f64::max);
    assert!(worst < 1e-14, "{worst}");
    // Closed loops stay closed.
    let mut data = dvrk_kin::Data::new(&m);
    dvrk_kin::forward_kinematics(&m, &mut data, &q).unwrap();
    assert!(dvrk_kin::max_closure_residual(&m, &data) < 1e-12);
}

#[test]
fn link_length_and_base_registration_move_the_frames() {
    let nominal = dvrk_kin::load("psm", None).unwrap();
    let m = psm_with("[[effects]]\nname = \"link_length\"\nlink = 8\nparameters = { a = 0.002 }\n[[effects]]\nname = \"base_registration\"\nparameters = { x = 0.1, rz = 0.5 }\n")
        .unwrap();
    let q = nominal.home();
    let (fm, fnom) = (m.fk(&q).unwrap(), nominal.fk(&q).unwrap());
    let id = |r: i64| m.frame_id(&FrameRef::Index(r)).unwrap();
    // Frame 8 sits 0.002 m further from its parent, frame 6 (its DH a: 0.516 -> 0.518 m).
    let d = |f: &[dvrk_kin::Pose], a: i64, b: i64| (f[id(a)].translation.vector - f[id(b)].translation.vector).norm();
    assert!((d(&fm, 6, 8) - d(&fnom, 6, 8) - 0.002).abs() < 1e-12, "{} {}", d(&fm, 6, 8), d(&fnom, 6, 8));
    // The base: rotated 0.5 rad about z and moved 0.1 m along x.
    let expect = nalgebra::Translation3::new(0.1, 0.0, 0.0) * nalgebra::Rotation3::from_axis_angle(&nalgebra::Vector3::z_axis(), 0.5);
    assert!((m.base.translation.vector - expect.translation.vector).norm() < 1e-15);
    assert!(dvrk_kin::so3::angle(&(m.base.rotation * expect.rotation.inverse())) < 1e-15);
    // The file keeps its own numbers (the spec is what `calib apply` and exports edit).
    assert_eq!(m.spec.frames, nominal.spec.frames);
}

#[test]
fn friction_and_spring_efforts_in_closed_form() {
    let m = psm_with(
        "[[effects]]\nname = \"coulomb_friction\"\njoint = \"outer_yaw\"\nparameters = { fc = 0.05, offset = 0.01 }\n\
         [[effects]]\nname = \"viscous_friction\"\njoint = \"outer_yaw\"\nparameters = { fv = 0.09 }\n\
         [[effects]]\nname = \"spring\"\njoint = \"outer_roll\"\nparameters = { k = 0.002, rest = 0.1 }\n",
    )
    .unwrap();
    assert_eq!(m.effects.iter().map(|e| e.kind).collect::<Vec<_>>(), [EffectKind::CoulombFriction, EffectKind::ViscousFriction, EffectKind::Spring]);
    let (q, qd) = ([0.0, 0.0, 0.1, 0.6, 0.0, 0.0, 0.0], [0.5, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
    let mut out = [0.0; 7];
    effort(&m.effects, &q, &qd, 0.0, &mut out);
    assert_eq!(out[0], -(0.05 + 0.01) - 0.09 * 0.5);
    assert!((out[3] + 0.002 * 0.5).abs() < 1e-18);
    assert!(out.iter().enumerate().all(|(k, x)| k == 0 || k == 3 || *x == 0.0));
    // The inverse dynamics with effects: the rigid-body effort plus what friction and springs take.
    let ine: Vec<dvrk_kin::BodyInertia> =
        m.bodies.iter().map(|_| dvrk_kin::BodyInertia::new(0.5, [0.01, 0.0, 0.0], [[1e-3, 0.0, 0.0], [0.0, 1e-3, 0.0], [0.0, 0.0, 1e-3]])).collect();
    let dm = dvrk_kin::DynamicsModel::new(&m, ine).unwrap();
    let mut data = dvrk_kin::DynamicsData::new(&m);
    let g = nalgebra::Vector3::new(0.0, 0.0, -9.81);
    let (mut rigid, mut with) = ([0.0; 7], [0.0; 7]);
    dvrk_kin::inverse_dynamics(&m, &dm, &mut data, &q, &qd, &[0.0; 7], &g, &mut rigid).unwrap();
    dvrk_kin::dynamics::actuator_effort(&m, &dm, &mut data, &q, &qd, &[0.0; 7], &g, 0.0, &mut with).unwrap();
    for k in 0..7 {
        assert!((with[k] - (rigid[k] - out[k])).abs() < 1e-15, "joint {k}");
    }
}

/// The tool's actuator-space effects (PSM coupling, joints = C actuators): the jaw's actuator
/// (7) moves as `a7 = (C^-1 q)_7`, and its friction loads the wrist yaw and the jaw by virtual
/// work, `C^-T` times the actuator's force; its motor's inertia adds `C^-T diag(I) C^-1 qdd`.
#[test]
fn actuator_effects_act_through_the_coupling() {
    let m = psm_with(
        "[[effects]]\nname = \"actuator_viscous_friction\"\nactuator = 7\nparameters = { fv = 0.02 }\n\
         [[effects]]\nname = \"actuator_coulomb_friction\"\nactuator = 6\nparameters = { fc = 0.03, offset = 0.005 }\n\
         [[effects]]\nname = \"actuator_spring\"\nactuator = 5\nparameters = { k = 0.01, rest = 0.2 }\n\
         [[effects]]\nname = \"motor_inertia\"\nactuator = 7\nparameters = { inertia = 5e-5 }\n",
    )
    .unwrap();
    let c = m.coupling_matrix().unwrap();
    let inv = c.clone().try_inverse().unwrap();
    let (q, qd, qdd) = ([0.1, -0.2, 0.1, 0.3, 0.4, -0.3, 0.6], [0.0, 0.0, 0.0, 0.0, 0.7, -0.5, 0.9], [0.0, 0.0, 0.0, 0.0, 2.0, 1.0, -3.0]);
    let a = |x: &[f64; 7], k: usize| (0..7).map(|j| inv[(k, j)] * x[j]).sum::<f64>();
    // Each actuator's force, then C^-T to the joints.
    let mut f = [0.0; 7];
    f[6] = -0.02 * a(&qd, 6);
    f[5] = -(0.03 * a(&qd, 5).signum() + 0.005);
    f[4] = -0.01 * (a(&q, 4) - 0.2);
    let expect: Vec<f64> = (0..7).map(|j| (0..7).map(|k| inv[(k, j)] * f[k]).sum()).collect();
    let mut out = [0.0; 7];
    effort(&m.effects, &q, &qd, 0.0, &mut out);
    for j in 0..7 {
        assert!((out[j] - expect[j]).abs() < 1e-15, "joint {j}: {} vs {}", out[j], expect[j]);
    }
    // The jaw actuator's friction loads both the wrist yaw and the jaw (a7 = (q7 / 1.2177 + ...)).
    assert!(out[5].abs() > 1e-3 && out[6].abs() > 1e-3 && out[..4].iter().all(|x| *x == 0.0), "{out:?}");
    // The motor's inertia, cross terms included: -I w (w . qdd), w the jaw actuator's row of C^-1.
    let mut inertial = [0.0; 7];
    dvrk_kin::effects::inertial_effort(&m.effects, &qdd, &mut inertial);
    let mut mat = nalgebra::DMatrix::zeros(7, 7);
    dvrk_kin::effects::motor_inertia_matrix(&m.effects, &mut mat);
    for j in 0..7 {
        let want = -5e-5 * inv[(6, j)] * a(&qdd, 6);
        assert!((inertial[j] - want).abs() < 1e-18, "joint {j}");
        let row: f64 = (0..7).map(|k| mat[(j, k)] * qdd[k]).sum();
        assert!((row + inertial[j]).abs() < 1e-18);
    }
    assert!(mat[(5, 6)].abs() > 0.1 * mat[(6, 6)], "the coupled inertia has cross terms: {mat}");
    // The drive's effort carries it (actuator_effort = inverse dynamics - effects' forces).
    let ine: Vec<dvrk_kin::BodyInertia> = m.bodies.iter().map(|_| dvrk_kin::BodyInertia::new(0.01, [0.0; 3], [[1e-5, 0.0, 0.0], [0.0, 1e-5, 0.0], [0.0, 0.0, 1e-5]])).collect();
    let dm = dvrk_kin::DynamicsModel::new(&m, ine).unwrap();
    let mut data = dvrk_kin::DynamicsData::new(&m);
    let g = nalgebra::Vector3::zeros();
    let (mut rigid, mut with) = ([0.0; 7], [0.0; 7]);
    dvrk_kin::inverse_dynamics(&m, &dm, &mut data, &q, &qd, &qdd, &g, &mut rigid).unwrap();
    dvrk_kin::dynamics::actuator_effort(&m, &dm, &mut data, &q, &qd, &qdd, &g, 0.0, &mut with).unwrap();
    for k in 0..7 {
        assert!((with[k] - (rigid[k] - out[k] - inertial[k])).abs() < 1e-14, "joint {k}");
    }
}

#[test]
fn actuator_effects_name_a_bad_actuator() {
    let err = |text: &str| psm_with(text).unwrap_err().to_string();
    let e = err("[[effects]]\nname = \"actuator_viscous_friction\"\nactuator = 8\nparameters = { fv = 0.02 }\n");
    assert!(e.contains("effects[0] (actuator_viscous_friction).actuator") && e.contains("8 is not an actuator") && e.contains("1..=7"), "{e}");
    let e = err("[[effects]]\nname = \"motor_inertia\"\nparameters = { inertia = 1e-5 }\n");
    assert!(e.contains("effects[0] (motor_inertia).actuator") && e.contains("missing"), "{e}");
    let e = err("[[effects]]\nname = \"viscous_friction\"\njoint = \"jaw\"\nactuator = 7\nparameters = { fv = 0.02 }\n");
    assert!(e.contains("does not act on an actuator"), "{e}");
    let e = err("[[effects]]\nname = \"motor_inertia\"\nactuator = 7\nparameters = { inertia = 3.0 }\n");
    assert!(e.contains("parameters.inertia") && e.contains("[0, 1]"), "{e}");
    // A model without a coupling has its actuators on its joints.
    let ecm = load_toml_text(
        &format!("{}\n[[effects]]\nname = \"actuator_viscous_friction\"\nactuator = 2\nparameters = {{ fv = 0.5 }}\n", builtin_text("ecm").unwrap()),
        Path::new("ecm.toml"),
        None,
        None,
    )
    .unwrap();
    assert_eq!(ecm.effects[0].transmission, vec![(1, 1.0)]);
}

/// `counterweight_error`: frame 11 (the counterweight) slides `mu` per metre of insertion, and the
/// insertion's gravity torque carries the new mass times the new travel (closed form: the
/// counterweight moves along its frame's z, so it adds `-m mu g . z11`).
#[test]
fn a_counterweight_error_sets_the_travel_and_the_mass() {
    let (mu, mass) = (0.7, 0.6);
    let nominal = dvrk_kin::load("psm", None).unwrap();
    let m = psm_with(&format!("[[effects]]\nname = \"counterweight_error\"\nparameters = {{ mu = {mu}, mass = {mass} }}\n")).unwrap();
    let cw = m.frame_id(&FrameRef::Index(11)).unwrap();
    let (mut q0, mut q1) = (m.home(), m.home());
    q0[2] = 0.05;
    q1[2] = 0.15;
    let travel = |model: &Model| (model.fk(&q1).unwrap()[cw].translation.vector - model.fk(&q0).unwrap()[cw].translation.vector).norm() / 0.1;
    assert!((travel(&m) - mu).abs() < 1e-12 && (travel(&nominal) - 0.6025).abs() < 1e-12, "{} {}", travel(&m), travel(&nominal));
    assert_eq!(m.spec.parameters["mu"].value, 0.6025, "the file keeps its own mu");
    // Every body 0.5 kg: the counterweight's becomes `mass`, its inertia scaled alike.
    let ine: Vec<dvrk_kin::BodyInertia> =
        m.bodies.iter().map(|_| dvrk_kin::BodyInertia::new(0.5, [0.0, 0.0, 0.01], [[1e-3, 0.0, 0.0], [0.0, 1e-3, 0.0], [0.0, 0.0, 2e-4]])).collect();
    let with = dvrk_kin::effects::effect_inertias(&m, &m.effects, &ine).unwrap();
    let b = m.frames[cw].body;
    assert_eq!(with[b].mass, mass);
    assert!((with[b].inertia[(2, 2)] - 2e-4 * mass / 0.5).abs() < 1e-18);
    assert!(with.iter().enumerate().all(|(k, x)| k == b || *x == ine[k]));
    let g = nalgebra::Vector3::new(0.0, 0.0, -9.81);
    let q = [0.3, -0.2, 0.15, 0.0, 0.0, 0.0, 0.3];
    let hold = |model: &Model, inertias: Vec<dvrk_kin::BodyInertia>| {
        let dm = dvrk_kin::DynamicsModel::new(model, inertias).unwrap();
        let mut out = [0.0; 7];
        dvrk_kin::gravity_torque(model, &dm, &mut dvrk_kin::DynamicsData::new(model), &q, &g, &mut out).unwrap();
        out
    };
    let (a, b0) = (hold(&m, with), hold(&nominal, ine));
    let z = m.fk(&q).unwrap()[cw].rotation * nalgebra::Vector3::z();
    let expect = -(mass * mu - 0.5 * 0.6025) * g.dot(&z);
    assert!((a[2] - b0[2] - expect).abs() < 1e-12, "{} vs {expect}", a[2] - b0[2]);
}

/// `coupling_error`: the controller reads joints through the model's coupling `C`, the mechanism
/// moves by `C + dC`, so the true joints are `B q` with `B = (C + dC) C^-1`. The compiled model
/// puts every frame where the nominal one puts `B q`, reports the efforts `B^T tau(B q)` (virtual
/// work), and `without_coupling_error` is the nominal mechanism in the true joints.
#[test]
fn a_coupling_error_maps_the_joints_read_to_the_true_ones() {
    let nominal = dvrk_kin::load("psm", None).unwrap();
    let m = psm_with("[[effects]]\nname = \"coupling_error\"\nparameters = { d65 = 0.05, d55 = 0.02 }\n").unwrap();
    let c = nominal.coupling_matrix().unwrap();
    assert_eq!((c[(5, 4)], c[(4, 4)]), (-0.8306, 1.0186), "the wrist yaw's coupling on the pitch actuator, the pitch's own");
    let mut truth = c.clone();
    truth[(5, 4)] += 0.05;
    truth[(4, 4)] += 0.02;
    let b = &truth * c.clone().try_inverse().unwrap();
    assert!((m.coupling_error_map().unwrap() - &b).amax() < 1e-15);
    let map = |x: &[f64; 7]| -> [f64; 7] { std::array::from_fn(|k| (0..7).map(|j| b[(k, j)] * x[j]).sum()) };
    let (q, qd, qdd) = ([0.3, -0.4, 0.12, 0.2, 0.5, -0.3, 0.4], [0.2, 0.1, 0.05, -0.3, 0.6, 0.4, 0.1], [1.0, -0.5, 0.2, 0.3, -2.0, 1.5, 0.5]);
    let worst = |a: Vec<dvrk_kin::Pose>, b: Vec<dvrk_kin::Pose>| a.iter().zip(&b).map(|(x, y)| (x.to_homogeneous() - y.to_homogeneous()).amax()).fold(0.0, f64::max);
    assert!(worst(m.fk(&q).unwrap(), nominal.fk(&map(&q)).unwrap()) < 1e-14);
    let link = m.without_coupling_error();
    assert!(link.coupling_error_map().is_none() && worst(link.fk(&map(&q)).unwrap(), nominal.fk(&map(&q)).unwrap()) < 1e-14);
    let ine: Vec<dvrk_kin::BodyInertia> =
        m.bodies.iter().map(|_| dvrk_kin::BodyInertia::new(0.05, [0.01, 0.0, 0.01], [[1e-4, 0.0, 0.0], [0.0, 1e-4, 0.0], [0.0, 0.0, 5e-5]])).collect();
    let g = nalgebra::Vector3::new(0.0, 0.0, -9.81);
    let effort = |model: &Model, q: &[f64; 7], qd: &[f64; 7], qdd: &[f64; 7]| {
        let dm = dvrk_kin::DynamicsModel::new(model, ine.clone()).unwrap();
        let mut out = [0.0; 7];
        dvrk_kin::inverse_dynamics(model, &dm, &mut dvrk_kin::DynamicsData::new(model), q, qd, qdd, &g, &mut out).unwrap();
        out
    };
    let read = effort(&m, &q, &qd, &qdd);
    let true_tau = effort(&nominal, &map(&q), &map(&qd), &map(&qdd));
    for k in 0..7 {
        let expect: f64 = (0..7).map(|j| b[(j, k)] * true_tau[j]).sum();
        assert!((read[k] - expect).abs() < 1e-12 * (1.0 + expect.abs()), "joint {k}: {} vs {expect}", read[k]);
    }
}

#[test]
fn bad_effects_name_the_effect_the_field_and_the_value() {
    let err = |t: &str| psm_with(t).unwrap_err().to_string();
    assert!(err("[[effects]]\nname = \"stiction\"\n").contains("effects[0].name`: `stiction` is not an effect (vocabulary: joint_offset, link_length"));
    assert!(err("[[effects]]\nname = \"backlash\"\nparameters = { b = 0.01 }\n").contains("effects[0] (backlash).joint`: missing: this effect acts on a joint"));
    assert!(err("[[effects]]\nname = \"backlash\"\njoint = \"outer_yaw\"\nparameters = { b = -0.01 }\n")
        .contains("effects[0] (backlash).parameters.b`: -0.01 rad is outside its physical bounds [0, 0.2]"));
    assert!(err("[[effects]]\nname = \"viscous_friction\"\njoint = \"outer_insertion\"\nparameters = { fc = 1 }\n")
        .contains("parameters.fc`: not a parameter of viscous_friction (parameters: fv)"));
    assert!(err("[[effects]]\nname = \"latency\"\njoint = \"outer_yaw\"\nparameters = { seconds = 0.01 }\n").contains("`outer_yaw` given, but latency does not act on a joint"));
    assert!(err("[[effects]]\nname = \"spring\"\njoint = \"elbow\"\nparameters = { k = 1 }\n").contains("effects[0] (spring).joint"));
    assert!(err("[[effects]]\nname = \"joint_compliance\"\njoint = \"outer_insertion\"\n").contains("parameters.stiffness`: missing (N/m)"));
    assert!(err("[[effects]]\nname = \"counterweight_error\"\nparameters = { mu = 2.5, mass = 0.5 }\n")
        .contains("(counterweight_error).parameters.mu`: 2.5 1 is outside its physical bounds [0, 2]"));
    let ecm = |t: &str| load_toml_text(&format!("{}\n{t}", builtin_text("ecm").unwrap()), Path::new("ecm-effects.toml"), None, None).unwrap_err().to_string();
    let e = ecm("[[effects]]\nname = \"counterweight_error\"\nparameters = { mu = 0.5, mass = 0.5 }\n");
    assert!(e.contains("effects[0] (counterweight_error).parameters.mu`: the model has no parameter `mu`"), "{e}");
    assert!(err("[[effects]]\nname = \"coupling_error\"\nparameters = { d68 = 0.1 }\n")
        .contains("(coupling_error).parameters.d68`: 0.1: expected dRC (1-based row, column of the 7x7 coupling)"));
    // Row 6's largest entry is 0.8306 (the wrist pitch's), so its errors stay within 0.2 x 0.8306.
    let e = err("[[effects]]\nname = \"coupling_error\"\nparameters = { d66 = 0.17 }\n");
    assert!(e.contains("(coupling_error).parameters.d66`: 0.17 is outside [-0.16612") && e.contains("of row 6's largest coupling entry"), "{e}");
    assert!(psm_with("[[effects]]\nname = \"coupling_error\"\nparameters = { d66 = 0.166 }\n").is_ok());
    // An offset's bounds: +-pi rad on a revolute joint, +-5 cm on the insertion.
    let offset = |joint: &str, v: f64| psm_with(&format!("[[effects]]\nname = \"joint_offset\"\njoint = \"{joint}\"\nparameters = {{ offset = {v} }}\n"));
    assert!(offset("outer_insertion", -0.06).unwrap_err().to_string().contains("(joint_offset).parameters.offset`: -0.06 m is outside its physical bounds [-0.05, 0.05]"));
    assert!(offset("outer_insertion", 0.04).is_ok() && offset("outer_pitch", 0.5).is_ok() && offset("outer_pitch", 3.2).is_err());
}

/// `[[inertials]]` (what `dvrk identify -o` writes): read back per body, written back by
/// `to_toml`, and refused with the body and field named when the body is unknown, repeated or
/// not physical.
#[test]
fn model_file_inertials_are_read_checked_and_written_back() {
    let body = "[[inertials]]\nbody = \"yaw_link\"\nmass = 1.5\ncom = [0.01, 0.0, -0.04]\ninertia = [[0.018, 0.0, 0.0], [0.0, 0.016, 0.0], [0.0, 0.0, 0.008]]\nsource = \"test\"\n";
    let m = psm_with(body).unwrap();
    let yaw = m.bodies.iter().position(|b| b.name == "yaw_link").unwrap();
    let ine = m.file_inertia(yaw).unwrap();
    assert_eq!((ine.mass, ine.com.z, ine.inertia[(2, 2)]), (1.5, -0.04, 0.008));
    assert!(m.file_inertia(yaw + 1).is_none());
    let again = load_toml_text(&m.spec.to_toml().unwrap(), Path::new("again.toml"), None, None).unwrap();
    assert_eq!(again.spec.inertials, m.spec.inertials);
    let err = |s: &str| psm_with(s).unwrap_err().to_string();
    assert!(
        err(&body.replace("yaw_link", "elbow")).contains("inertials[0] (elbow).body`: model psm has no body `elbow` (valid: yaw_link,"),
        "{}",
        err(&body.replace("yaw_link", "elbow"))
    );
    assert!(err(&format!("{body}{body}")).contains("inertials[1] (yaw_link).body`: body appears twice"));
    assert!(err(&body.replace("mass = 1.5", "mass = -1.5")).contains("inertials[0] (yaw_link).mass"));
    // 0.018 > 0.016 + 0.001: no mass distribution has these moments.
    assert!(err(&body.replace("0.008]]", "0.001]]")).contains("triangle inequality"));
}

/// `[drive]` (the damping and motor inertias an identified model was fitted with): read, written
/// back by `to_toml`, and refused with the field named when an entry is missing or not physical.
#[test]
fn model_file_drive_is_read_checked_and_written_back() {
    let drive = "[drive]\ndamping = 0.0\narmature = [1e-6, 0.0, 0.128, 0.0, 3e-4, 1e-4, 2.5e-5]\nsource = \"test\"\n";
    let m = psm_with(drive).unwrap();
    let d = m.spec.drive.as_ref().unwrap();
    assert_eq!((d.damping, d.armature[2], d.armature.len()), (0.0, 0.128, 7));
    let again = load_toml_text(&m.spec.to_toml().unwrap(), Path::new("again.toml"), None, None).unwrap();
    assert_eq!(again.spec.drive, m.spec.drive);
    assert!(psm_with("").unwrap().spec.drive.is_none());
    let err = |s: &str| psm_with(s).unwrap_err().to_string();
    let short = err(&drive.replace(", 2.5e-5]", "]"));
    assert!(short.contains("drive.armature`: has 6 entries, model psm has 7 joints"), "{short}");
    let negative = err(&drive.replace("0.128", "-0.128"));
    assert!(negative.contains("drive.armature[2] (outer_insertion)`: -0.128 is not a finite non-negative number"), "{negative}");
    assert!(err(&drive.replace("damping = 0.0", "damping = -1.0")).contains("drive.damping"));
}

/// `[inertial_covariance]` (how well an identification determined the inertials): read, written
/// back exactly, its factor giving back the covariance `L L^T` of any subset of bodies, and
/// refused with the field named when a body is unknown or the factor is not one.
#[test]
fn model_file_inertial_covariance_is_read_checked_and_written_back() {
    // One body, a diagonal factor 1e-3 .. 1e-2 and one off-diagonal entry.
    let rows: Vec<String> = (0..10)
        .map(|i| {
            let mut r = vec![0.0; i + 1];
            r[i] = 1e-3 * (i + 1) as f64;
            if i == 3 {
                r[0] = 2e-3;
            }
            format!("[{}]", r.iter().map(|x| format!("{x:e}")).collect::<Vec<_>>().join(", "))
        })
        .collect();
    let cov = format!("[inertial_covariance]\nbodies = [\"pitch_end_link\"]\ncholesky = [{}]\nsource = \"test\"\n", rows.join(", "));
    let m = psm_with(&cov).unwrap();
    let again = load_toml_text(&m.spec.to_toml().unwrap(), Path::new("again.toml"), None, None).unwrap();
    assert_eq!(again.spec.inertial_covariance, m.spec.inertial_covariance);
    let b = m.bodies.iter().position(|b| b.name == "pitch_end_link").unwrap();
    let l = m.inertial_covariance_factor(&[b]).unwrap();
    let c = &l * l.transpose();
    // Var(mcz) = 2e-3^2 + 4e-3^2; Cov(m, mcz) = 1e-3 * 2e-3.
    assert!((c[(3, 3)] - 2e-5).abs() < 1e-18 && (c[(0, 3)] - 2e-6).abs() < 1e-18, "{c}");
    // A body it does not cover: no prior from the file.
    assert!(m.inertial_covariance_factor(&[0]).is_none());
    let err = |s: &str| psm_with(s).unwrap_err().to_string();
    assert!(err(&cov.replace("pitch_end_link", "elbow")).contains("inertial_covariance.bodies[0]`: model psm has no body `elbow`"));
    let short = err(&cov.replace(&format!(", {}]", rows[9]), "]"));
    assert!(short.contains("inertial_covariance.cholesky`: has 9 rows; 1 bodies need 10"), "{short}");
    let negative = err(&cov.replace("[1e-3]", "[-1e-3]"));
    assert!(negative.contains("inertial_covariance.cholesky[0][0]`: -1.000000e-3: the diagonal of a Cholesky factor is positive"), "{negative}");
}

/// The Coulomb level's winding and Stribeck terms and the tool's cross springs (the terms
/// `dvrk identify` fits beyond fc, fv, k): `(fc + fq q^2 + fs exp(-(qd / vs)^2)) sign(qd)`,
/// never below zero; an `actuator_cross_spring` on actuator 6 pulled by actuators 5 and 7,
/// `-(k5 a5 + k7 a7)` on actuator 6 and `C^-T` to the joints. Bad `kN` names are refused.
#[test]
fn winding_stribeck_and_cross_springs_in_closed_form() {
    let m = psm_with(
        "[[effects]]\nname = \"coulomb_friction\"\njoint = \"outer_pitch\"\nparameters = { fc = 0.05, fq = 0.2, fs = 0.03, vs = 0.1 }\n\
         [[effects]]\nname = \"coulomb_friction\"\njoint = \"outer_yaw\"\nparameters = { fc = 0.05, fq = -1.0 }\n\
         [[effects]]\nname = \"actuator_cross_spring\"\nactuator = 6\nparameters = { k5 = 0.004, k7 = -0.002 }\n",
    )
    .unwrap();
    let inv = m.coupling_matrix().unwrap().try_inverse().unwrap();
    let (q, qd) = ([0.8, -0.6, 0.1, 0.3, 0.4, -0.3, 0.6], [0.5, 0.08, 0.0, 0.0, 0.0, 0.0, 0.0]);
    let a = |k: usize| (0..7).map(|j| inv[(k, j)] * q[j]).sum::<f64>();
    let mut out = [0.0; 7];
    effort(&m.effects, &q, &qd, 0.0, &mut out);
    // Pitch: 0.05 + 0.2 * 0.36 + 0.03 exp(-0.64) = 0.13782... against its motion.
    let pitch = 0.05 + 0.2 * 0.36 + 0.03 * (-(0.08f64 / 0.1).powi(2)).exp();
    assert!((out[1] + pitch).abs() < 1e-15, "{} vs {}", out[1], -pitch);
    // Yaw: 0.05 - 0.64 is below zero: no friction (it would push).
    assert_eq!(out[0], 0.0);
    // The cross spring on actuator 6, through C^-T.
    let f6 = -(0.004 * a(4) - 0.002 * a(6));
    for j in 3..7 {
        let want = inv[(5, j)] * f6;
        assert!((out[j] - want).abs() < 1e-17, "joint {j}: {} vs {want}", out[j]);
    }
    assert!(out[5].abs() > 1e-4, "{out:?}");
    for (bad, says) in [("k9 = 0.1", "k9"), ("kx = 0.1", "kx"), ("k5 = 1e6", "outside its physical bounds")] {
        let e = psm_with(&format!("[[effects]]\nname = \"actuator_cross_spring\"\nactuator = 6\nparameters = {{ {bad} }}\n")).unwrap_err().to_string();
        assert!(e.contains("effects[0] (actuator_cross_spring).parameters.") && e.contains(says), "{e}");
    }
    let e = psm_with("[[effects]]\nname = \"actuator_cross_spring\"\nactuator = 6\n").unwrap_err().to_string();
    assert!(e.contains("at least one kN"), "{e}");
}

/// A presliding level `fd`: stateless, its sliding limit `fd sign(qd)` joins the Coulomb force;
/// with Dahl states, `fd z` in its place, an actuator's through `C^-T`; a state steps by the
/// exact Dahl law from where the effect last was.
#[test]
fn presliding_is_the_sliding_limit_without_a_state_and_fd_z_with_one() {
    use dvrk_kin::presliding::{dahl_step, effort_with_presliding, PreslidingState};
    let m = psm_with(
        "[[effects]]\nname = \"coulomb_friction\"\njoint = \"outer_pitch\"\nparameters = { fc = 0.05, fd = 0.1, sigma = 0.02 }\n\
         [[effects]]\nname = \"actuator_coulomb_friction\"\nactuator = 6\nparameters = { fc = 0.0, fd = 0.01, sigma = 0.05 }\n",
    )
    .unwrap();
    let inv = m.coupling_matrix().unwrap().try_inverse().unwrap();
    let (q0, q, qd) = ([0.0; 7], [0.0, 0.01, 0.0, 0.0, 0.0, 0.03, 0.0], [0.0, -0.2, 0.0, 0.0, 0.0, 0.5, 0.0]);
    let mut out = [0.0; 7];
    effort(&m.effects, &q, &qd, 0.0, &mut out);
    assert!((out[1] + 0.05 * -1.0 + 0.1 * -1.0).abs() < 1e-15, "{out:?}");
    let mut states = PreslidingState::new(&m.effects, &q0);
    states.advance(&m.effects, &q);
    let a6: f64 = (0..7).map(|j| inv[(5, j)] * q[j]).sum();
    let (z_pitch, z6) = (dahl_step(0.0, 0.01, 0.02), dahl_step(0.0, a6, 0.05));
    assert_eq!((states.z[0], states.z[1]), (z_pitch, z6));
    let mut with = [0.0; 7];
    effort_with_presliding(&m.effects, &q, &qd, &states, 0.0, &mut with);
    // Moving down while the state still holds the way up: presliding pulls against the slide.
    assert!((with[1] - (0.05 - 0.1 * z_pitch)).abs() < 1e-15, "{} vs {}", with[1], 0.05 - 0.1 * z_pitch);
    for j in 3..7 {
        let want = -inv[(5, j)] * 0.01 * z6;
        assert!((with[j] - want).abs() < 1e-17, "joint {j}: {} vs {want}", with[j]);
    }
    assert!(z_pitch > 0.3 && z6.abs() > 0.1, "{z_pitch} {z6}");
}
