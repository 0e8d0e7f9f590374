//! Joint space: the actuator-to-joint couplings of the MTM and the PSM, and the tally of
//! measured configurations outside the joints' limits.

use dvrk_kin::LimitTally;

#[test]
fn mtm_elbow_and_psm_wrist_couplings() {
    let mtm = dvrk_kin::load("mtmr", None).unwrap();
    // Elbow parallelogram: joint 3 = actuator 3 - actuator 2; platform: + 0.6697 (a2 - a3).
    let q = mtm.joints_from_actuators(&[0.1, 0.2, 0.5, 0.3, 0.0, 0.0, 0.0]).unwrap();
    assert!((q[2] - 0.3).abs() < 1e-15 && (q[3] - (0.3 + 0.6697 * (0.2 - 0.5))).abs() < 1e-15);
    let back = mtm.actuators_from_joints(&q).unwrap();
    assert!((back[2] - 0.5).abs() < 1e-12);
    let psm = dvrk_kin::load("psm", None).unwrap();
    let q = psm.joints_from_actuators(&[0.1, 0.2, 0.1, 1.0, 0.5, 0.2, 0.4]).unwrap();
    assert_eq!(&q[..3], &[0.1, 0.2, 0.1]);
    assert!((q[3] + 1.5632).abs() < 1e-15, "roll = -1.5632 a4");
    assert!((q[6] - 1.2177 * (0.4 - 0.2)).abs() < 1e-15, "jaw = 1.2177 (a7 - a6)");
    assert!(dvrk_kin::load("ecm", None).unwrap().joints_from_actuators(&[0.0; 4]).is_err());
}


#[test]
fn a_hair_past_is_counted_with_its_distance() {
    let m = dvrk_kin::load("psm", None).unwrap();
    let mut tally = LimitTally::new(&m);
    let mut q = m.home();
    assert!(!tally.add(&m, &q));
    let k = m.joint_id("outer_wrist_yaw").unwrap();
    q[k] = m.joints[k].upper + 0.001;
    assert!(tally.add(&m, &q));
    q[k] = m.joints[k].lower - 0.0004;
    assert!(tally.add(&m, &q));
    assert_eq!((tally.samples, tally.samples_outside), (3, 2));
    assert_eq!(tally.joints[k].0, 2);
    assert!((tally.joints[k].1 - 0.001).abs() < 1e-12);
    let s = tally.summary(&m).unwrap();
    assert!(s.starts_with("2 of 3 measured configuration(s) outside the limits of model psm"), "{s}");
    assert!(s.contains("outer_wrist_yaw: 2 of 3 sample(s) outside") && s.contains("at most 1.000e-3 rad past"), "{s}");
}
