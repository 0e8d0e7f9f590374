//! Rigid-body dynamics of the closed-loop trees against closed-form equations and against
//! independent computations (FK energies, Jacobian kinetic energy, finite differences).

use dvrk_kin::dynamics::PARAMETERS_PER_BODY;
use dvrk_kin::{
    compute_frame_placements, frame_bias_forces, frame_jacobian, gravity_torque, inverse_dynamics, mass_matrix, regressor, BodyInertia, Data, DynamicsData,
    DynamicsModel, Model,
};
use nalgebra::{DMatrix, DVector, Matrix6xX, Point3, Vector3};
use std::path::{Path, PathBuf};

const G: f64 = 9.81;

fn model_from(text: &str, name: &str) -> Model {
    dvrk_kin::load::load_toml_text(text, Path::new(name), None, None).unwrap()
}

/// A single revolute joint about the world z axis; gravity along -y makes it a pendulum.
const PENDULUM: &str = r#"
name = "pendulum"
[[joints]]
name = "q1"
type = "revolute"
lower = -10.0
upper = 10.0
[[frames]]
name = "link1"
parent = 0
body = "link1"
joint = "revolute"
theta = "q1"
"#;

/// A planar arm (both axes along world z, link lengths along x). `THETA2` is the second frame's
/// angle: `q2` (relative joint) or `q2 - q1` (absolute angle, as a parallelogram drives it).
const ARM2: &str = r#"
name = "arm2"
[[joints]]
name = "q1"
type = "revolute"
lower = -10.0
upper = 10.0
[[joints]]
name = "q2"
type = "revolute"
lower = -10.0
upper = 10.0
[[frames]]
name = "link1"
parent = 0
body = "link1"
joint = "revolute"
theta = "q1"
[[frames]]
name = "link2"
parent = "link1"
body = "link2"
joint = "revolute"
a = 0.4
theta = "THETA2"
"#;

/// Pendulum: com at `l` on the link's x axis, rod-like inertia `i0` about the com's z axis.
/// `tau = (i0 + m l^2) q'' + m g l cos q`.
#[test]
fn single_pendulum_matches_the_closed_form() {
    let model = model_from(PENDULUM, "pendulum.toml");
    let (m, l, i0) = (1.3, 0.25, 0.004);
    let dm = DynamicsModel::new(&model, vec![BodyInertia::new(m, [l, 0.0, 0.0], [[0.0, 0.0, 0.0], [0.0, i0, 0.0], [0.0, 0.0, i0]])]).unwrap();
    let mut data = DynamicsData::new(&model);
    let gravity = Vector3::new(0.0, -G, 0.0);
    let mut tau = [0.0];
    let mut worst: f64 = 0.0;
    for (q, qd, qdd) in [(0.0, 0.0, 0.0), (0.7, 1.5, -2.0), (-2.1, -3.0, 4.0), (3.0, 0.2, 0.0)] {
        inverse_dynamics(&model, &dm, &mut data, &[q], &[qd], &[qdd], &gravity, &mut tau).unwrap();
        let expected = (i0 + m * l * l) * qdd + m * G * l * f64::cos(q);
        worst = worst.max((tau[0] - expected).abs());
        assert!((tau[0] - expected).abs() < 1e-12, "q {q}: {} vs {expected}", tau[0]);
    }
    // The velocity does not enter a single joint's torque: check it is really zero, not cancelled.
    gravity_torque(&model, &dm, &mut data, &[0.7], &gravity, &mut tau).unwrap();
    assert!((tau[0] - m * G * l * 0.7_f64.cos()).abs() < 1e-12);
    println!("pendulum: largest error {worst:.2e} N·m");
}

struct Arm2 {
    m: [f64; 2],
    lc: [f64; 2],
    i: [f64; 2],
    l1: f64,
}

impl Arm2 {
    /// The textbook planar two-link equations (Spong, Hutchinson, Vidyasagar, section 7.4).
    fn tau(&self, q: [f64; 2], qd: [f64; 2], qdd: [f64; 2]) -> [f64; 2] {
        let Arm2 { m, lc, i, l1 } = self;
        let c2 = q[1].cos();
        let m11 = m[0] * lc[0] * lc[0] + i[0] + m[1] * (l1 * l1 + lc[1] * lc[1] + 2.0 * l1 * lc[1] * c2) + i[1];
        let m12 = m[1] * (lc[1] * lc[1] + l1 * lc[1] * c2) + i[1];
        let m22 = m[1] * lc[1] * lc[1] + i[1];
        let h = -m[1] * l1 * lc[1] * q[1].sin();
        let g1 = (m[0] * lc[0] + m[1] * l1) * G * q[0].cos() + m[1] * lc[1] * G * (q[0] + q[1]).cos();
        let g2 = m[1] * lc[1] * G * (q[0] + q[1]).cos();
        [
            m11 * qdd[0] + m12 * qdd[1] + h * (2.0 * qd[0] * qd[1] + qd[1] * qd[1]) + g1,
            m12 * qdd[0] + m22 * qdd[1] - h * qd[0] * qd[0] + g2,
        ]
    }
}

fn arm2_inertias(a: &Arm2) -> Vec<BodyInertia> {
    (0..2).map(|k| BodyInertia::new(a.m[k], [a.lc[k], 0.0, 0.0], [[0.0, 0.0, 0.0], [0.0, a.i[k], 0.0], [0.0, 0.0, a.i[k]]])).collect()
}

const ARM2_STATES: [([f64; 2], [f64; 2], [f64; 2]); 4] = [
    ([0.0, 0.0], [0.0, 0.0], [0.0, 0.0]),
    ([0.3, -1.1], [1.2, -0.7], [0.5, 2.0]),
    ([-2.0, 2.5], [-3.0, 4.0], [-1.0, 0.3]),
    ([1.4, 0.2], [0.0, 2.2], [0.0, 0.0]),
];

/// Relative second joint: RNEA equals the closed form (inertia, Coriolis, centrifugal, gravity).
#[test]
fn planar_two_link_arm_matches_the_closed_form() {
    let arm = Arm2 { m: [1.1, 0.8], lc: [0.2, 0.15], i: [0.012, 0.007], l1: 0.4 };
    let model = model_from(&ARM2.replace("THETA2", "q2"), "arm2.toml");
    let dm = DynamicsModel::new(&model, arm2_inertias(&arm)).unwrap();
    let mut data = DynamicsData::new(&model);
    let gravity = Vector3::new(0.0, -G, 0.0);
    let mut tau = [0.0; 2];
    for (q, qd, qdd) in ARM2_STATES {
        inverse_dynamics(&model, &dm, &mut data, &q, &qd, &qdd, &gravity, &mut tau).unwrap();
        let e = arm.tau(q, qd, qdd);
        for k in 0..2 {
            assert!((tau[k] - e[k]).abs() < 1e-12, "q {q:?} qd {qd:?} qdd {qdd:?}: joint {k} {} vs {}", tau[k], e[k]);
        }
    }
}

/// The same arm driven through an affine map (`theta2 = q2 - q1`: q2 is the second link's
/// absolute angle, as a parallelogram's passive joint sees its drive): `tau = C^T tau_rel` with
/// `phi = C q`, i.e. `tau1 = tau_rel1 - tau_rel2`, `tau2 = tau_rel2` at `q_rel = (q1, q2 - q1)`.
#[test]
fn affine_coupled_arm_maps_torques_by_the_transpose() {
    let arm = Arm2 { m: [1.1, 0.8], lc: [0.2, 0.15], i: [0.012, 0.007], l1: 0.4 };
    let model = model_from(&ARM2.replace("THETA2", "q2 - q1"), "arm2-absolute.toml");
    let dm = DynamicsModel::new(&model, arm2_inertias(&arm)).unwrap();
    let mut data = DynamicsData::new(&model);
    let gravity = Vector3::new(0.0, -G, 0.0);
    let mut tau = [0.0; 2];
    for (q, qd, qdd) in ARM2_STATES {
        inverse_dynamics(&model, &dm, &mut data, &q, &qd, &qdd, &gravity, &mut tau).unwrap();
        let rel = |x: [f64; 2]| [x[0], x[1] - x[0]];
        let t = arm.tau(rel(q), rel(qd), rel(qdd));
        let e = [t[0] - t[1], t[1]];
        for k in 0..2 {
            assert!((tau[k] - e[k]).abs() < 1e-12, "q {q:?}: joint {k} {} vs {}", tau[k], e[k]);
        }
    }
}

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../..")
}

/// The inertials file of a model (models/inertials/NAME.toml), read here without dvrk-sim: one
/// entry per body, matched by name, in the model's body order.
fn file_inertias(model: &Model, name: &str) -> Vec<BodyInertia> {
    let text = std::fs::read_to_string(root().join(format!("models/inertials/{name}.toml"))).unwrap();
    let table: toml::Table = toml::from_str(&text).unwrap();
    let bodies = table["bodies"].as_array().unwrap();
    let num = |v: &toml::Value| v.as_float().or_else(|| v.as_integer().map(|i| i as f64)).unwrap();
    model
        .bodies
        .iter()
        .map(|b| {
            let e = bodies.iter().find(|e| e["name"].as_str() == Some(&b.name)).unwrap_or_else(|| panic!("no inertials for {}", b.name));
            assert_eq!(e["frame"].as_integer().unwrap(), model.frames[b.frames[0]].index, "{}: not the body's first frame", b.name);
            let com = e["com"].as_array().unwrap();
            let rows = e["inertia"].as_array().unwrap();
            let row = |i: usize| {
                let r = rows[i].as_array().unwrap();
                [num(&r[0]), num(&r[1]), num(&r[2])]
            };
            BodyInertia::new(num(&e["mass"]), [num(&com[0]), num(&com[1]), num(&com[2])], [row(0), row(1), row(2)])
        })
        .collect()
}

/// Made-up but physical inertias for any model: different per body, off the frame origins,
/// with products of inertia.
/// Built-in model `name` with the inertials file `file` (`models/inertials/<file>.toml`), or
/// the made-up [`test_inertias`] when there is none.
fn model_and_inertias(name: &str, file: Option<&str>) -> (Model, Vec<BodyInertia>) {
    let model = dvrk_kin::load(name, None).unwrap();
    let inertias = match file {
        Some(f) => file_inertias(&model, f),
        None => test_inertias(&model),
    };
    (model, inertias)
}

fn test_inertias(model: &Model) -> Vec<BodyInertia> {
    (0..model.bodies.len())
        .map(|b| {
            let x = b as f64;
            let com = [0.01 * (x % 3.0) - 0.012, 0.02 - 0.007 * x, 0.015 * (x % 2.0) + 0.003];
            let inertia = [[0.002 + 0.0001 * x, 0.0002, -0.0001], [0.0002, 0.003, 0.00015], [-0.0001, 0.00015, 0.004 - 0.0001 * x]];
            BodyInertia::new(0.2 + 0.1 * x, com, inertia)
        })
        .collect()
}

/// A deterministic state within the joint limits (velocities and accelerations of order 1).
fn state(model: &Model, i: usize) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let q = dvrk_kin::sample_configurations(&model.joints, i + 1).pop().unwrap();
    let n = model.nq();
    let qd = (0..n).map(|k| ((i * 7 + k * 3) as f64 * 0.77).sin() * 1.2).collect();
    let qdd = (0..n).map(|k| ((i * 5 + k * 11) as f64 * 0.53).cos() * 2.0).collect();
    (q, qd, qdd)
}

/// Gravity in the base frame of a model standing as the PSM scene places it (world -z).
fn gravity() -> Vector3<f64> {
    Vector3::new(0.0, 0.0, -G)
}

/// `tau` from Newton-Euler equals `Y pi` from the regressor (different formulations: world
/// spatial inertias from the centre of mass vs. body-frame wrench columns linear in pi).
#[test]
fn regressor_times_parameters_equals_newton_euler() {
    for (name, file) in [("psm", Some("psm")), ("ecm", Some("ecm")), ("mtmr", None), ("suj-psm1", None)] {
        let (model, inertias) = model_and_inertias(name, file);
        let dm = DynamicsModel::new(&model, inertias).unwrap();
        let pi = DVector::from_vec(dm.parameters());
        assert_eq!(pi.len(), PARAMETERS_PER_BODY * model.bodies.len());
        let mut data = DynamicsData::new(&model);
        let mut y = DMatrix::zeros(model.nq(), pi.len());
        let mut tau = vec![0.0; model.nq()];
        let mut worst: f64 = 0.0;
        let mut scale: f64 = 0.0;
        for i in 0..8 {
            let (q, qd, qdd) = state(&model, i);
            inverse_dynamics(&model, &dm, &mut data, &q, &qd, &qdd, &gravity(), &mut tau).unwrap();
            regressor(&model, &dm, &mut data, &q, &qd, &qdd, &gravity(), &mut y).unwrap();
            let ypi = &y * &pi;
            for k in 0..model.nq() {
                worst = worst.max((ypi[k] - tau[k]).abs());
                scale = scale.max(tau[k].abs());
            }
        }
        println!("{name}: |Y pi - tau| <= {worst:.2e} (|tau| up to {scale:.2e})");
        assert!(worst < 1e-10, "{name}: {worst}");
        assert!(scale > 0.1, "{name}: the check needs non-trivial torques ({scale})");
    }
}

/// Kinetic energy from the frame Jacobians of each body's inertial frame (J), and potential
/// energy from FK (J): independent of the dynamics code.
fn energies(model: &Model, inertias: &[BodyInertia], q: &[f64], qd: &[f64], g: &Vector3<f64>) -> (f64, f64) {
    let mut data = Data::new(model);
    compute_frame_placements(model, &mut data, q);
    let mut jac = Matrix6xX::zeros(model.nq());
    let qd = DVector::from_column_slice(qd);
    let (mut kinetic, mut potential) = (0.0, 0.0);
    for (b, ine) in model.bodies.iter().zip(inertias) {
        let f = b.frames[0];
        let pose = data.frames[f];
        frame_jacobian(model, &data, f, &mut jac).unwrap();
        let twist = &jac * &qd;
        let (v_origin, w) = (Vector3::new(twist[0], twist[1], twist[2]), Vector3::new(twist[3], twist[4], twist[5]));
        let r = pose.rotation.matrix();
        let c = pose * Point3::from(ine.com);
        let v_com = v_origin + w.cross(&(c.coords - pose.translation.vector));
        kinetic += 0.5 * ine.mass * v_com.norm_squared() + 0.5 * w.dot(&(r * ine.inertia * r.transpose() * w));
        potential -= ine.mass * g.dot(&c.coords);
    }
    (kinetic, potential)
}

/// `M(q)` is symmetric positive definite, `q'^T M q' / 2` is the kinetic energy from the
/// Jacobians, and `tau(q, 0, q'') - g(q) = M q''` (CRBA against Newton-Euler).
#[test]
fn mass_matrix_is_spd_and_agrees_with_newton_euler_and_energy() {
    for (name, file) in [("psm", Some("psm")), ("ecm", Some("ecm")), ("mtmr", None)] {
        let (model, inertias) = model_and_inertias(name, file);
        let dm = DynamicsModel::new(&model, inertias.clone()).unwrap();
        let mut data = DynamicsData::new(&model);
        let n = model.nq();
        let mut m = DMatrix::zeros(n, n);
        let (mut tau, mut g) = (vec![0.0; n], vec![0.0; n]);
        let zero = vec![0.0; n];
        let (mut worst_sym, mut worst_id, mut worst_ke, mut min_eig) = (0.0_f64, 0.0_f64, 0.0_f64, f64::INFINITY);
        for i in 0..8 {
            let (q, qd, qdd) = state(&model, i);
            mass_matrix(&model, &dm, &mut data, &q, &mut m).unwrap();
            worst_sym = worst_sym.max((&m - m.transpose()).abs().max());
            let eig = m.clone().symmetric_eigen().eigenvalues;
            min_eig = min_eig.min(eig.min());
            assert!(m.clone().cholesky().is_some(), "{name}: M not positive definite at {q:?}: {eig:?}");
            inverse_dynamics(&model, &dm, &mut data, &q, &zero, &qdd, &gravity(), &mut tau).unwrap();
            gravity_torque(&model, &dm, &mut data, &q, &gravity(), &mut g).unwrap();
            let mqdd = &m * DVector::from_column_slice(&qdd);
            for k in 0..n {
                worst_id = worst_id.max((tau[k] - g[k] - mqdd[k]).abs());
            }
            let qdv = DVector::from_column_slice(&qd);
            let ke = 0.5 * qdv.dot(&(&m * &qdv));
            let (ke_jac, _) = energies(&model, &inertias, &q, &qd, &gravity());
            worst_ke = worst_ke.max((ke - ke_jac).abs() / ke_jac);
        }
        println!("{name}: |M - M^T| {worst_sym:.1e}, min eigenvalue {min_eig:.3e}, |tau - g - M qdd| {worst_id:.1e}, KE rel. err {worst_ke:.1e}");
        assert!(worst_sym < 1e-14, "{name}: {worst_sym}");
        assert!(min_eig > 0.0, "{name}: {min_eig}");
        assert!(worst_id < 1e-10, "{name}: {worst_id}");
        assert!(worst_ke < 1e-12, "{name}: {worst_ke}");
    }
}

/// The forward-dynamics pair in one pass equals the two separate calls: `M` from CRBA and the
/// bias `h = tau(q, q', 0)` from Newton-Euler.
#[test]
fn mass_matrix_and_bias_in_one_pass_equal_the_separate_calls() {
    for (name, file) in [("psm", Some("psm")), ("ecm", Some("ecm")), ("mtmr", None)] {
        let (model, inertias) = model_and_inertias(name, file);
        let dm = DynamicsModel::new(&model, inertias).unwrap();
        let mut data = DynamicsData::new(&model);
        let n = model.nq();
        let (mut m1, mut m2) = (DMatrix::zeros(n, n), DMatrix::zeros(n, n));
        let (mut h1, mut h2) = (vec![0.0; n], vec![0.0; n]);
        let zero = vec![0.0; n];
        for i in 0..8 {
            let (q, qd, _) = state(&model, i);
            dvrk_kin::mass_matrix_and_bias(&model, &dm, &mut data, &q, &qd, &gravity(), &mut h1, &mut m1).unwrap();
            mass_matrix(&model, &dm, &mut data, &q, &mut m2).unwrap();
            inverse_dynamics(&model, &dm, &mut data, &q, &qd, &zero, &gravity(), &mut h2).unwrap();
            assert_eq!(m1, m2, "{name}");
            assert_eq!(h1, h2, "{name}");
            // On placements already made at q: the same.
            dvrk_kin::compute_frame_placements(&model, &mut data.kin, &q);
            dvrk_kin::mass_matrix_and_bias_placed(&model, &dm, &mut data, &qd, &gravity(), &mut h1, &mut m1).unwrap();
            assert_eq!(m1, m2, "{name}");
            assert_eq!(h1, h2, "{name}");
        }
        let mut small = DMatrix::zeros(n - 1, n - 1);
        let e = dvrk_kin::mass_matrix_and_bias(&model, &dm, &mut data, &zero, &zero, &gravity(), &mut h1, &mut small).unwrap_err().to_string();
        assert!(e.contains("mass matrix"), "{e}");
    }
}

/// Power balance along a smooth trajectory: `q'^T tau = d/dt (T + V)`, with `T` from the
/// Jacobians and `V` from FK, differentiated by a 4th-order central difference in time.
#[test]
fn power_equals_rate_of_energy_along_a_trajectory() {
    for (name, file) in [("psm", Some("psm")), ("ecm", Some("ecm")), ("mtmr", None)] {
        let (model, inertias) = model_and_inertias(name, file);
        let dm = DynamicsModel::new(&model, inertias.clone()).unwrap();
        let mut data = DynamicsData::new(&model);
        let n = model.nq();
        let home = model.home();
        // q_k(t) = home_k + A_k sin(w_k t + p_k), amplitudes a quarter of the range.
        let traj = |t: f64| -> (Vec<f64>, Vec<f64>, Vec<f64>) {
            let mut out = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
            for (k, j) in model.joints.iter().enumerate() {
                let (a, w, p) = (0.25 * (j.upper - j.lower).min(2.0), 1.0 + 0.37 * k as f64, 0.3 * k as f64);
                let s = (w * t + p).sin();
                out.0[k] = home[k] + a * s;
                out.1[k] = a * w * (w * t + p).cos();
                out.2[k] = -a * w * w * s;
            }
            out
        };
        let energy = |t: f64| {
            let (q, qd, _) = traj(t);
            let (k, v) = energies(&model, &inertias, &q, &qd, &gravity());
            k + v
        };
        let h = 1e-3;
        let mut tau = vec![0.0; n];
        let (mut worst, mut scale) = (0.0_f64, 0.0_f64);
        for i in 0..10 {
            let t = 0.31 * i as f64;
            let (q, qd, qdd) = traj(t);
            inverse_dynamics(&model, &dm, &mut data, &q, &qd, &qdd, &gravity(), &mut tau).unwrap();
            let power: f64 = qd.iter().zip(&tau).map(|(a, b)| a * b).sum();
            let rate = (-energy(t + 2.0 * h) + 8.0 * energy(t + h) - 8.0 * energy(t - h) + energy(t - 2.0 * h)) / (12.0 * h);
            worst = worst.max((power - rate).abs());
            scale = scale.max(power.abs());
        }
        println!("{name}: |q'.tau - dE/dt| <= {worst:.2e} W (power up to {scale:.2e} W)");
        assert!(scale > 0.05, "{name}: the check needs real power ({scale})");
        assert!(worst < 1e-8 * scale.max(1.0), "{name}: {worst}");
    }
}

/// PSM closed loops with simple test inertias: the gravity torque is the gradient of the
/// potential energy of the body centres of mass from FK (central differences, h = 1e-6).
#[test]
fn psm_gravity_torque_is_the_gradient_of_the_potential() {
    let model = dvrk_kin::load("psm", None).unwrap();
    let inertias = test_inertias(&model);
    let dm = DynamicsModel::new(&model, inertias.clone()).unwrap();
    let mut data = DynamicsData::new(&model);
    let n = model.nq();
    let mut g = vec![0.0; n];
    let potential = |q: &[f64]| energies(&model, &inertias, q, &vec![0.0; n], &gravity()).1;
    let (mut worst, mut scale) = (0.0_f64, 0.0_f64);
    for i in 0..10 {
        let (q, _, _) = state(&model, i);
        gravity_torque(&model, &dm, &mut data, &q, &gravity(), &mut g).unwrap();
        for k in 0..n {
            let (mut a, mut b) = (q.clone(), q.clone());
            a[k] += 1e-6;
            b[k] -= 1e-6;
            let fd = (potential(&a) - potential(&b)) / 2e-6;
            worst = worst.max((fd - g[k]).abs());
            scale = scale.max(g[k].abs());
        }
    }
    println!("psm: |g - dV/dq| <= {worst:.2e} N·m (g up to {scale:.2e})");
    assert!(scale > 0.5, "{scale}");
    assert!(worst < 1e-7, "{worst}");
}

#[test]
fn parameters_round_trip_and_inconsistent_inertias_are_named() {
    let b = BodyInertia::new(0.7, [0.01, -0.02, 0.03], [[0.002, 0.0001, 0.0], [0.0001, 0.003, -0.0002], [0.0, -0.0002, 0.004]]);
    let back = BodyInertia::from_parameters(&b.parameters(), "link").unwrap();
    assert!((back.com - b.com).norm() < 1e-15 && (back.inertia - b.inertia).abs().max() < 1e-15);
    // Parallel-axis theorem by hand for one entry: Jxx = Ixx + m (cy^2 + cz^2).
    assert!((b.parameters()[4] - (0.002 + 0.7 * (0.0004 + 0.0009))).abs() < 1e-15);
    let e = BodyInertia { mass: -1.0, ..b }.check("body yaw_link").unwrap_err().to_string();
    assert!(e.contains("yaw_link.mass") && e.contains("-1"), "{e}");
    let e = BodyInertia::new(1.0, [0.0; 3], [[0.01, 0.0, 0.0], [0.0, 0.001, 0.0], [0.0, 0.0, 0.001]]).check("b").unwrap_err().to_string();
    assert!(e.contains("b.inertia") && e.contains("triangle"), "{e}");
    let e = BodyInertia::new(1.0, [f64::NAN, 0.0, 0.0], [[0.01; 3]; 3]).check("b").unwrap_err().to_string();
    assert!(e.contains("b.com") && e.contains("NaN"), "{e}");
    let e = BodyInertia::new(1.0, [0.0; 3], [[0.01, 0.001, 0.0], [0.0, 0.01, 0.0], [0.0, 0.0, 0.01]]).check("b").unwrap_err().to_string();
    assert!(e.contains("symmetric"), "{e}");

    let model = dvrk_kin::load("psm", None).unwrap();
    let e = DynamicsModel::new(&model, test_inertias(&model)[1..].to_vec()).unwrap_err().to_string();
    assert!(e.contains("body inertias") && e.contains("expected 13"), "{e}");
    let dm = DynamicsModel::new(&model, test_inertias(&model)).unwrap();
    let mut data = DynamicsData::new(&model);
    let (q, mut qd, qdd) = state(&model, 1);
    let mut tau = vec![0.0; 7];
    qd[2] = f64::NAN;
    let e = inverse_dynamics(&model, &dm, &mut data, &q, &qd, &qdd, &gravity(), &mut tau).unwrap_err().to_string();
    assert!(e.contains("qd[2]") && e.contains("NaN"), "{e}");
    let e = gravity_torque(&model, &dm, &mut data, &q, &Vector3::new(0.0, f64::INFINITY, 0.0), &mut tau).unwrap_err().to_string();
    assert!(e.contains("gravity"), "{e}");
    let ecm = dvrk_kin::load("ecm", None).unwrap();
    let e = gravity_torque(&ecm, &dm, &mut data, &[0.0; 4], &gravity(), &mut tau).unwrap_err().to_string();
    assert!(e.contains("built for model psm"), "{e}");
    let mut small = DMatrix::zeros(7, 6);
    assert!(mass_matrix(&model, &dm, &mut data, &q, &mut small).unwrap_err().to_string().contains("mass matrix"));
}

/// The tree's own velocity products at frame rates the actuated map does not give (the affine
/// arm, `theta2 = q2 - q1`, at independent rates of its two frames): the relative closed form's
/// Coriolis and centrifugal torques at those rates; frames without a variable get 0.
#[test]
fn frame_bias_forces_are_the_trees_velocity_products_at_any_frame_rates() {
    let arm = Arm2 { m: [1.1, 0.8], lc: [0.2, 0.15], i: [0.012, 0.007], l1: 0.4 };
    let model = model_from(&ARM2.replace("THETA2", "q2 - q1"), "arm2-absolute.toml");
    let dm = DynamicsModel::new(&model, arm2_inertias(&arm)).unwrap();
    let mut data = DynamicsData::new(&model);
    let nf = model.frames.len();
    let moving: Vec<usize> = (0..nf).filter(|&i| model.frames[i].variable().is_some_and(|v| !v.is_constant())).collect();
    assert_eq!(moving.len(), 2);
    let (mut phi, mut out) = (vec![0.0; nf], vec![0.0; nf]);
    let mut checked = 0;
    for (q, rates, _) in ARM2_STATES {
        phi[moving[0]] = rates[0];
        phi[moving[1]] = rates[1];
        frame_bias_forces(&model, &dm, &mut data, &q, &phi, &mut out).unwrap();
        let q_rel = [q[0], q[1] - q[0]];
        let (with, without) = (arm.tau(q_rel, rates, [0.0; 2]), arm.tau(q_rel, [0.0; 2], [0.0; 2]));
        for k in 0..2 {
            let e = with[k] - without[k];
            assert!((out[moving[k]] - e).abs() < 1e-12, "q {q:?} rates {rates:?}: frame {} {} vs {e}", moving[k], out[moving[k]]);
            checked += usize::from(e.abs() > 0.01);
        }
        assert!((0..nf).filter(|i| !moving.contains(i)).all(|i| out[i] == 0.0));
    }
    // Not vacuous: the moving states have real velocity products.
    assert!(checked >= 4, "{checked}");
    let err = frame_bias_forces(&model, &dm, &mut data, &[0.0; 2], &[0.0; 1], &mut out).unwrap_err().to_string();
    assert!(err.contains("frame rates"), "{err}");
    phi[moving[0]] = f64::NAN;
    let err = frame_bias_forces(&model, &dm, &mut data, &[0.0; 2], &phi, &mut out).unwrap_err().to_string();
    assert!(err.contains("frame rate") && err.contains("NaN"), "{err}");
}
