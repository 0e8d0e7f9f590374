//! The experiment that tells two candidates apart when one recording cannot: the report's advice
//! for an ambiguous verdict and for what the inertias can mimic.

use dvrk_kin::effects::EffectKind;

/// The experiment that separates two candidates whose signatures look alike.
pub fn separating_experiment(a: EffectKind, b: EffectKind) -> String {
    use EffectKind::*;
    let pair = |x: EffectKind, y: EffectKind| (a == x && b == y) || (a == y && b == x);
    if a == CouplingError && b == CouplingError {
        "a motion that moves the two entries' actuators apart (each coupled joint on its own, the jaw against the wrist): a held joint's actuator moves with the others, and its entries read as theirs".into()
    } else if a == b && matches!(a, ActuatorCoulombFriction | ActuatorViscousFriction | ActuatorSpring | MotorInertia) {
        format!("a motion that moves the two actuators apart: an actuator turns with every joint its cables couple, so two actuators differing only by a held joint's weight (the wrist yaw's and the jaw's, the jaw held) move alike; open and close the jaw (or move the joint that tells them apart) to separate the two places of {}", a.name())
    } else if pair(ViscousFriction, ActuatorViscousFriction) || pair(CoulombFriction, ActuatorCoulombFriction) || pair(Spring, ActuatorSpring) {
        "a motion that moves the joints the actuator couples in other proportions (each wrist joint on its own, then together): a joint's friction follows that joint alone, an actuator's its cables' combination".into()
    } else if pair(CounterweightError, PayloadMass) {
        "a slow insertion sweep at two pitch angles: the counterweight moves against the insertion by its travel ratio, a payload with it".into()
    } else if a == b {
        format!("a motion or a tracker that moves the two places of {} separately (another marker link, other poses)", a.name())
    } else if pair(ViscousFriction, Latency) {
        "a speed sweep: viscous friction grows with speed at any frequency, a latency's residual with speed times frequency".into()
    } else if pair(JointCompliance, LinkLength) || pair(JointCompliance, JointOffset) || pair(JointCompliance, PayloadMass) {
        "a payload change: a compliant drive's deflection follows the load, a geometric error does not".into()
    } else if pair(CoulombFriction, Backlash) || pair(Backlash, JointOffset) || pair(Backlash, JointCompliance) {
        "a tracker on the link: play shows as dead travel between encoder and link at reversals, friction and offsets do not".into()
    } else if pair(Spring, JointOffset) || pair(Spring, PayloadMass) || pair(JointOffset, PayloadMass) {
        "a slow sweep of the joint at two other poses of the arm: gravity's torque changes with the pose, a spring's does not".into()
    } else {
        format!("a recording that excites {} and {} independently (different speeds, loads and poses)", a.name(), b.name())
    }
}
