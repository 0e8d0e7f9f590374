//! Closed-loop kinematics: closures, RCM, serial equivalence, Jacobians and IK.

use crate::util::random_configurations;
use dvrk_kin::check::rotation_angle;
use dvrk_kin::{compute_frame_placements, frame_jacobian, inverse_kinematics, load, Data, FrameRef, IkOptions, Model};
use nalgebra::{Matrix6xX, Point3};

/// Every closure point stays fixed in its partner link and the insertion axis passes through one
/// fixed RCM, over 10,000 random configurations within the dVRK's joint limits.
fn closures_and_rcm_hold(name: &str) {
    let m = load(name, None).unwrap();
    assert_eq!(m.closures.len(), 2, "{name} has two loop closures");
    let rcm = m.rcm.as_ref().expect("an RCM");
    let mut data = Data::new(&m);
    let (mut worst_closure, mut worst_pivot) = (0.0f64, 0.0f64);
    for q in random_configurations(&m, 10_000, 7) {
        compute_frame_placements(&m, &mut data, &q);
        for c in &m.closures {
            // The closure point of link `frame`, seen from its partner link.
            let world = data.frames[c.frame] * Point3::from(c.point);
            let in_partner = data.frames[c.partner].inverse_transform_point(&world).coords;
            worst_closure = worst_closure.max((in_partner - c.partner_point).norm());
        }
        worst_pivot = worst_pivot.max(dvrk_kin::rcm::distance_to_axis(&data.frames[rcm.frame], &rcm.point));
    }
    eprintln!("{name}: closure residual {worst_closure:.2e} m, pivot residual {worst_pivot:.2e} m");
    assert!(worst_closure < 1e-12, "{name}: closure residual {worst_closure:e} m");
    assert!(worst_pivot < 1e-12, "{name}: pivot residual {worst_pivot:e} m");
}

#[test]
fn psm_closures_and_rcm_hold_over_the_joint_range() {
    closures_and_rcm_hold("psm");
}

#[test]
fn ecm_closures_and_rcm_hold_over_the_joint_range() {
    closures_and_rcm_hold("ecm");
}

/// The closed-loop frames equal the dVRK serial chain composed with one constant base transform.
fn matches_serial_chain(name: &str, serial: &str) -> (f64, f64) {
    let m = load(name, None).unwrap();
    let s = load(serial, None).unwrap();
    let pairs = &m.spec.serial_equivalent.as_ref().unwrap().pairs;
    let pairs: Vec<(usize, usize)> = pairs.iter().map(|[a, b]| (m.frame_id(a).unwrap(), s.frame_id(b).unwrap())).collect();
    assert_eq!(m.tip, pairs.last().unwrap().0, "the tool tip is compared");
    let base = dvrk_kin::compose::serial_base_transform(&m).unwrap();
    let (mut dm, mut ds) = (Data::new(&m), Data::new(&s));
    let (mut ep, mut eo) = (0.0f64, 0.0f64);
    for q in random_configurations(&m, 2000, 11) {
        compute_frame_placements(&m, &mut dm, &q);
        compute_frame_placements(&s, &mut ds, &q[..s.nq()]);
        for &(a, b) in &pairs {
            let expect = base * ds.frames[b];
            ep = ep.max((expect.translation.vector - dm.frames[a].translation.vector).norm());
            eo = eo.max(rotation_angle(&(expect.rotation.inverse() * dm.frames[a].rotation)));
        }
    }
    eprintln!("{name} vs {serial}: {ep:.2e} m, {eo:.2e} rad");
    assert!(ep < 1e-9 && eo < 1e-9, "{name} differs from {serial}: {ep:e} m, {eo:e} rad");
    (base.translation.vector.norm(), rotation_angle(&base.rotation))
}

#[test]
fn psm_tool_tip_equals_the_dvrk_serial_chain() {
    // The base transform is a pure translation along the yaw axis: 0.516 - 0.0296 m (Table 4).
    let (dist, angle) = matches_serial_chain("psm", "psm-serial");
    assert!((dist - 0.4864).abs() < 1e-12 && angle < 1e-12, "{dist} m, {angle} rad");
}

#[test]
fn ecm_endoscope_equals_the_dvrk_serial_chain() {
    // ECM frame 0 sits 0.3404 - 0.2722 = 0.0682 m from the RCM on the yaw axis (Table 5).
    let (dist, angle) = matches_serial_chain("ecm", "ecm-serial");
    assert!((dist - 0.0682).abs() < 1e-12 && angle < 1e-12, "{dist} m, {angle} rad");
}

#[test]
fn jacobians_match_finite_differences() {
    for name in ["psm", "ecm", "mtmr", "cart"] {
        let m = load(name, None).unwrap();
        let mut data = Data::new(&m);
        let mut jac = Matrix6xX::zeros(m.nq());
        for q in random_configurations(&m, 20, 3) {
            for frame in [m.tip, m.frames.len() / 2] {
                compute_frame_placements(&m, &mut data, &q);
                frame_jacobian(&m, &data, frame, &mut jac).unwrap();
                let t0 = data.frames[frame];
                for k in 0..m.nq() {
                    let h = 1e-7;
                    let mut qh = q.clone();
                    qh[k] += h;
                    compute_frame_placements(&m, &mut data, &qh);
                    let t1 = data.frames[frame];
                    let v = (t1.translation.vector - t0.translation.vector) / h;
                    let w = dvrk_kin::so3::log(&(t1.rotation * t0.rotation.inverse())) / h;
                    for r in 0..3 {
                        assert!((jac[(r, k)] - v[r]).abs() < 1e-5, "{name} frame {frame} joint {k}: linear {} vs {}", jac[(r, k)], v[r]);
                        assert!((jac[(r + 3, k)] - w[r]).abs() < 1e-5, "{name} frame {frame} joint {k}: angular");
                    }
                }
            }
        }
    }
}

fn ik_round_trip(m: &Model, full_pose: bool) {
    let mut data = Data::new(m);
    let mut worst = 0.0f64;
    for q in random_configurations(m, 100, 5) {
        compute_frame_placements(m, &mut data, &q);
        let target = data.frames[m.tip];
        let sol = inverse_kinematics(m, &target, &m.home(), &IkOptions::default()).unwrap();
        compute_frame_placements(m, &mut data, &sol.q);
        let reached = data.frames[m.tip];
        let ep = (reached.translation.vector - target.translation.vector).norm();
        worst = worst.max(ep);
        if full_pose {
            assert!(rotation_angle(&(reached.rotation.inverse() * target.rotation)) < 1e-8);
        }
        m.check_q(&sol.q).unwrap();
    }
    eprintln!("{}: IK worst position error {worst:.2e} m over 100 targets", m.name);
    assert!(worst < 1e-9);
}

#[test]
fn ik_reaches_reachable_psm_and_ecm_targets() {
    ik_round_trip(&load("psm", None).unwrap(), true);
    ik_round_trip(&load("psm-serial", None).unwrap(), true);
    ik_round_trip(&load("ecm", None).unwrap(), true);
}

#[test]
fn ik_reports_unreachable_targets_and_limit_violations() {
    let m = load("psm", None).unwrap();
    let mut target = m.fk(&m.home()).unwrap()[m.tip];
    // 2 m away from the RCM: beyond any insertion.
    target.translation.vector.z += 2.0;
    let e = inverse_kinematics(&m, &target, &m.home(), &IkOptions::default()).unwrap_err().to_string();
    assert!(e.contains("out of reach") || e.contains("limits"), "{e}");
    // A tip pose reached only with the insertion below its lower limit (tip above the RCM).
    let mut q = m.home();
    q[2] = -0.05;
    let target = m.fk(&q).unwrap()[m.tip];
    let e = inverse_kinematics(&m, &target, &m.home(), &IkOptions::default()).unwrap_err().to_string();
    assert!(e.contains("outer_insertion") || e.contains("out of reach"), "{e}");
}

#[test]
fn rigid_parts_are_single_bodies() {
    let m = load("psm", None).unwrap();
    let body = |i: i64| m.bodies[m.frames[m.frame_id(&FrameRef::Index(i)).unwrap()].body].name.clone();
    // Frames 3, 5 and 10 turn together: the back link.
    assert_eq!(body(3), "pitch_back_link");
    assert_eq!(body(5), body(3));
    assert_eq!(body(10), body(3));
    assert_eq!(body(1), body(2));
    assert_ne!(body(4), body(3));
    assert_eq!(m.bodies.len(), 13, "{:?}", m.bodies.iter().map(|b| &b.name).collect::<Vec<_>>());
}

#[test]
fn counterweight_moves_against_the_insertion() {
    let m = load("psm", None).unwrap();
    let cw = m.frame_id(&FrameRef::Index(11)).unwrap();
    let ins = m.frame_id(&FrameRef::Index(9)).unwrap();
    let mut q = m.home();
    let f0 = m.fk(&q).unwrap();
    q[2] += 0.1;
    let f1 = m.fk(&q).unwrap();
    let d_cw = f1[cw].translation.vector - f0[cw].translation.vector;
    let d_ins = f1[ins].translation.vector - f0[ins].translation.vector;
    assert!((d_ins.norm() - 0.1).abs() < 1e-12);
    assert!((d_cw.norm() - 0.6025 * 0.1).abs() < 1e-12, "mu * dq3");
    assert!((d_cw.normalize().dot(&d_ins.normalize()) + 1.0).abs() < 1e-12, "opposite directions");
}

#[test]
fn cart_places_every_rcm_where_the_dvrk_puts_it() {
    // The dVRK computes PSM1's RCM as world_origin_to_SUJ * SUJ DH * SUJ_tip_to_tool_origin: the
    // system FK must put the closed-loop PSM1's RCM (and its serial base) there.
    let cart = load("cart", None).unwrap();
    let suj = load("suj-psm1", None).unwrap();
    let q = cart.home();
    let poses = cart.fk(&q).unwrap();
    let part = cart.parts.iter().find(|p| p.name == "PSM1").unwrap();
    let rcm = part.rcm.as_ref().unwrap();
    let rcm_world = poses[part.frames.start] * Point3::from(rcm.point);
    let mount = dvrk_kin::pose_from_rows(&[[-1.0, 0.0, 0.0, -0.1016], [0.0, -1.0, 0.0, -0.1016], [0.0, 0.0, 1.0, 0.43], [0.0, 0.0, 0.0, 1.0]], "t").unwrap();
    let suj_tip = mount * suj.fk(&suj.home()).unwrap()[suj.tip];
    let expect = suj_tip * Point3::new(0.4864, 0.0, 0.1524);
    assert!((rcm_world - expect).norm() < 1e-12, "{rcm_world} vs {expect}");
    // And the RCM stays put when PSM1's own joints move.
    let mut q2 = q.clone();
    for k in part.joints.clone() {
        q2[k] = 0.5 * (cart.joints[k].lower + cart.joints[k].upper) + 0.2 * (cart.joints[k].upper - cart.joints[k].lower);
    }
    let p2 = cart.fk(&q2).unwrap();
    assert!(dvrk_kin::rcm::distance_to_axis(&p2[rcm.frame], &rcm_world.coords) < 1e-12);
}
