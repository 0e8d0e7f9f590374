//! The effect vocabulary: each effect's name, what it acts on, its parameters with units and
//! physical bounds, and a checked effect of a compiled model. Plain data: what the effects do is
//! in [`crate::effects`].

use serde::Serialize;
use std::collections::BTreeMap;

/// The vocabulary.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum EffectKind {
    JointOffset,
    LinkLength,
    BaseRegistration,
    Latency,
    ClockOffset,
    JointCompliance,
    Backlash,
    MotionPlay,
    CoulombFriction,
    ViscousFriction,
    PayloadMass,
    CouplingError,
    CounterweightError,
    Spring,
    ActuatorCoulombFriction,
    ActuatorViscousFriction,
    ActuatorSpring,
    MotorInertia,
    ActuatorCrossSpring,
    CableSpring,
}

/// What an effect is attached to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Target {
    Joint,
    Link,
    /// An actuator: a column of the model's coupling.
    Actuator,
    Model,
}

/// One parameter of an effect: name, unit (for a revolute joint / for a prismatic joint when
/// they differ), bounds, default (`None`: required).
#[derive(Debug, Clone, Copy)]
pub struct ParameterInfo {
    pub name: &'static str,
    pub unit: &'static str,
    pub prismatic_unit: &'static str,
    pub lower: f64,
    pub upper: f64,
    /// `[lower, upper]` on a prismatic joint where they differ (in `prismatic_unit`).
    pub prismatic_bounds: Option<[f64; 2]>,
    pub default: Option<f64>,
}

impl ParameterInfo {
    /// `[lower, upper]` on a joint of that kind.
    pub fn bounds(&self, prismatic: bool) -> [f64; 2] {
        match (prismatic, self.prismatic_bounds) {
            (true, Some(b)) => b,
            _ => [self.lower, self.upper],
        }
    }
}

const fn p(name: &'static str, unit: &'static str, prismatic_unit: &'static str, lower: f64, upper: f64, default: Option<f64>) -> ParameterInfo {
    ParameterInfo { name, unit, prismatic_unit, lower, upper, prismatic_bounds: None, default }
}

impl EffectKind {
    /// The whole vocabulary.
    pub const ALL: [EffectKind; 20] = [
        EffectKind::JointOffset,
        EffectKind::LinkLength,
        EffectKind::BaseRegistration,
        EffectKind::Latency,
        EffectKind::ClockOffset,
        EffectKind::JointCompliance,
        EffectKind::Backlash,
        EffectKind::MotionPlay,
        EffectKind::CoulombFriction,
        EffectKind::ViscousFriction,
        EffectKind::PayloadMass,
        EffectKind::CouplingError,
        EffectKind::CounterweightError,
        EffectKind::Spring,
        EffectKind::ActuatorCoulombFriction,
        EffectKind::ActuatorViscousFriction,
        EffectKind::ActuatorSpring,
        EffectKind::MotorInertia,
        EffectKind::ActuatorCrossSpring,
        EffectKind::CableSpring,
    ];

    /// The name model files use.
    pub fn name(self) -> &'static str {
        match self {
            EffectKind::JointOffset => "joint_offset",
            EffectKind::LinkLength => "link_length",
            EffectKind::BaseRegistration => "base_registration",
            EffectKind::Latency => "latency",
            EffectKind::ClockOffset => "clock_offset",
            EffectKind::JointCompliance => "joint_compliance",
            EffectKind::Backlash => "backlash",
            EffectKind::MotionPlay => "motion_play",
            EffectKind::CoulombFriction => "coulomb_friction",
            EffectKind::ViscousFriction => "viscous_friction",
            EffectKind::PayloadMass => "payload_mass",
            EffectKind::CouplingError => "coupling_error",
            EffectKind::CounterweightError => "counterweight_error",
            EffectKind::Spring => "spring",
            EffectKind::ActuatorCoulombFriction => "actuator_coulomb_friction",
            EffectKind::ActuatorViscousFriction => "actuator_viscous_friction",
            EffectKind::ActuatorSpring => "actuator_spring",
            EffectKind::MotorInertia => "motor_inertia",
            EffectKind::ActuatorCrossSpring => "actuator_cross_spring",
            EffectKind::CableSpring => "cable_spring",
        }
    }

    /// The kind called `name`.
    pub fn from_name(name: &str) -> Option<EffectKind> {
        EffectKind::ALL.into_iter().find(|k| k.name() == name)
    }

    /// What it acts on.
    pub fn target(self) -> Target {
        match self {
            EffectKind::JointOffset | EffectKind::JointCompliance | EffectKind::Backlash | EffectKind::MotionPlay | EffectKind::CoulombFriction | EffectKind::ViscousFriction | EffectKind::Spring | EffectKind::CableSpring => {
                Target::Joint
            }
            EffectKind::LinkLength | EffectKind::PayloadMass => Target::Link,
            EffectKind::BaseRegistration | EffectKind::Latency | EffectKind::ClockOffset | EffectKind::CouplingError | EffectKind::CounterweightError => Target::Model,
            EffectKind::ActuatorCoulombFriction | EffectKind::ActuatorViscousFriction | EffectKind::ActuatorSpring | EffectKind::MotorInertia | EffectKind::ActuatorCrossSpring => Target::Actuator,
        }
    }

    /// Its parameters (a `coupling_error` takes `dRC`, 1-based row and column of the coupling
    /// matrix, checked against the model's, instead; an `actuator_cross_spring` takes `kN`, the
    /// stiffness from 1-based actuator N's position, [`CROSS_SPRING_RANGE`]).
    pub fn parameters(self) -> &'static [ParameterInfo] {
        match self {
            EffectKind::JointOffset => JOINT_OFFSET,
            EffectKind::LinkLength => LINK_LENGTH,
            EffectKind::BaseRegistration => BASE_REGISTRATION,
            EffectKind::Latency => LATENCY,
            EffectKind::ClockOffset => CLOCK_OFFSET,
            EffectKind::JointCompliance => JOINT_COMPLIANCE,
            EffectKind::Backlash => BACKLASH,
            EffectKind::MotionPlay => BACKLASH,
            EffectKind::CoulombFriction => COULOMB,
            EffectKind::ViscousFriction => VISCOUS,
            EffectKind::PayloadMass => PAYLOAD,
            EffectKind::CouplingError => &[],
            EffectKind::CounterweightError => COUNTERWEIGHT,
            EffectKind::Spring => SPRING,
            EffectKind::ActuatorCoulombFriction => COULOMB,
            EffectKind::ActuatorViscousFriction => VISCOUS,
            EffectKind::ActuatorSpring => SPRING,
            EffectKind::MotorInertia => MOTOR_INERTIA,
            EffectKind::ActuatorCrossSpring => &[],
            EffectKind::CableSpring => CABLE_SPRING,
        }
    }

    /// The physical range `[lower, upper]` of parameter `name`, `None` for a name that is not
    /// one of this effect's parameters (and for a coupling error's, whose range is the model's:
    /// [`coupling_error_range`]).
    pub fn range(self, name: &str) -> Option<[f64; 2]> {
        self.range_on(name, false)
    }

    /// [`EffectKind::range`] on a joint of that kind (a prismatic joint's offset: in m).
    pub fn range_on(self, name: &str, prismatic: bool) -> Option<[f64; 2]> {
        self.parameters().iter().find(|p| p.name == name).map(|p| p.bounds(prismatic))
    }
}

/// The largest error of a coupling entry, as a fraction of the largest entry of its row: a
/// coupling is a ratio of capstan and pulley radii, known to a few percent; a fifth off is
/// another instrument, not this one's cables.
pub const COUPLING_ERROR_FRACTION: f64 = 0.2;

/// The physical range of the error of entry (`row`, any column) (0-based) of coupling `c`
/// (dimensionless, as the entries).
pub fn coupling_error_range(c: &nalgebra::DMatrix<f64>, row: usize) -> [f64; 2] {
    let limit = COUPLING_ERROR_FRACTION * c.row(row).amax();
    [-limit, limit]
}

const PI: f64 = std::f64::consts::PI;
/// A prismatic joint's encoder zero is known to within a DH length's range (5 cm, as
/// [`LINK_LENGTH`]'s), not to +-pi m: an insertion offset of -0.2 m once fitted the WPI recording
/// (an interval +-0.7 m wide), standing in for what its model lacks.
const JOINT_OFFSET: &[ParameterInfo] = &[ParameterInfo { prismatic_bounds: Some([-0.05, 0.05]), ..p("offset", "rad", "m", -PI, PI, None) }];
const LINK_LENGTH: &[ParameterInfo] = &[p("a", "m", "m", -0.05, 0.05, Some(0.0)), p("d", "m", "m", -0.05, 0.05, Some(0.0))];
const BASE_REGISTRATION: &[ParameterInfo] = &[
    p("x", "m", "m", -10.0, 10.0, Some(0.0)),
    p("y", "m", "m", -10.0, 10.0, Some(0.0)),
    p("z", "m", "m", -10.0, 10.0, Some(0.0)),
    p("rx", "rad", "rad", -PI, PI, Some(0.0)),
    p("ry", "rad", "rad", -PI, PI, Some(0.0)),
    p("rz", "rad", "rad", -PI, PI, Some(0.0)),
];
const LATENCY: &[ParameterInfo] = &[p("seconds", "s", "s", 0.0, 1.0, None)];
/// A tracker's clock against the joint stream's, either sign (positive: the tracker late, its pose
/// stamped `t` shows the link at the encoders' `t - seconds`); a second off is another recording.
const CLOCK_OFFSET: &[ParameterInfo] = &[p("seconds", "s", "s", -1.0, 1.0, None)];
const JOINT_COMPLIANCE: &[ParameterInfo] = &[p("stiffness", "N·m/rad", "N/m", 1e-3, 1e8, None)];
const BACKLASH: &[ParameterInfo] = &[p("b", "rad", "m", 0.0, 0.2, None)];
const COULOMB: &[ParameterInfo] = &[
    p("fc", "N·m", "N", 0.0, 100.0, None),
    p("offset", "N·m", "N", -100.0, 100.0, Some(0.0)),
    // Velocity scale of the smoothed sign, tanh(qd / smoothing) (0: the user's default); an
    // identification's Coulomb level belongs with the smoothing it was fitted with.
    p("smoothing", "rad/s", "m/s", 0.0, 1.0, Some(0.0)),
    // Winding: the level grows by fq q^2 (cables that tighten as the joint winds away from its
    // zero; `dvrk identify`'s winding term). Either sign: the level never goes below 0.
    p("fq", "N·m/rad^2", "N/m^2", -1e5, 1e5, Some(0.0)),
    // Stribeck: fs more at rest, fading as exp(-(qd / vs)^2) (either sign: what the fit found).
    p("fs", "N·m", "N", -100.0, 100.0, Some(0.0)),
    p("vs", "rad/s", "m/s", 1e-4, 10.0, Some(0.05)),
    // Presliding (Dahl): fd z, z the Dahl state that saturates after a displacement sigma
    // (crate::presliding); where no state is carried (a pose, dvrk-kin's stateless effort) the
    // sliding limit fd sgn(qd). Either sign: what the fit found.
    p("fd", "N·m", "N", -100.0, 100.0, Some(0.0)),
    p("sigma", "rad", "m", 1e-6, 1.0, Some(0.01)),
];
const VISCOUS: &[ParameterInfo] = &[p("fv", "N·m s/rad", "N s/m", 0.0, 1000.0, None)];
const PAYLOAD: &[ParameterInfo] =
    &[p("mass", "kg", "kg", 0.0, 20.0, None), p("x", "m", "m", -1.0, 1.0, Some(0.0)), p("y", "m", "m", -1.0, 1.0, Some(0.0)), p("z", "m", "m", -1.0, 1.0, Some(0.0))];
const COUNTERWEIGHT: &[ParameterInfo] = &[p("mu", "1", "1", 0.0, 2.0, None), p("mass", "kg", "kg", 0.0, 10.0, None)];
const SPRING: &[ParameterInfo] = &[p("k", "N·m/rad", "N/m", 0.0, 1e5, None), p("rest", "rad", "m", -10.0, 10.0, Some(0.0))];
/// A configuration-dependent spring on a joint, its effort `k1 q + k2 q^2 + k3 q^3` (the force
/// on the joint its negative), each coefficient of either sign: a cable or spring whose torque
/// is not a line in the joint's position (the MTM's platform cable, which the WPI authors fitted
/// as a polynomial of the platform angle, and its wrist-pitch spring). Its constant term is the
/// joint's effort offset (`coulomb_friction`'s `offset`).
const CABLE_SPRING: &[ParameterInfo] = &[
    p("k1", "N·m/rad", "N/m", -1e5, 1e5, Some(0.0)),
    p("k2", "N·m/rad^2", "N/m^2", -1e5, 1e5, Some(0.0)),
    p("k3", "N·m/rad^3", "N/m^3", -1e5, 1e5, Some(0.0)),
];
/// A dVRK motor's rotor reflected through its gearhead is 1e-6..1e-3 kg m^2 at the actuator
/// (the WPI fit: 2e-5..1e-4); 1 kg m^2 is a flywheel.
const MOTOR_INERTIA: &[ParameterInfo] = &[p("inertia", "kg m^2", "kg", 0.0, 1.0, None)];

/// The range of an `actuator_cross_spring`'s stiffness `kN` (N·m/rad, N/m; either sign: a cable
/// routed over another's pulley pulls or slackens it).
pub const CROSS_SPRING_RANGE: [f64; 2] = [-1e5, 1e5];

/// The 1-based source actuator an `actuator_cross_spring` parameter `kN` names.
pub fn cross_spring_source(name: &str) -> Option<usize> {
    name.strip_prefix('k')?.parse().ok()
}

/// A checked effect of a compiled model.
#[derive(Debug, Clone, PartialEq)]
pub struct Effect {
    pub kind: EffectKind,
    /// The joint (position in [`crate::Model::joints`]) of a joint effect.
    pub joint: Option<usize>,
    /// The frame (position in [`crate::Model::frames`]) of a link effect.
    pub frame: Option<usize>,
    /// The actuator (0-based column of the coupling) of an actuator effect.
    pub actuator: Option<usize>,
    /// An actuator effect's transmission: its row of `C^-1`, as (joint, weight) for every joint
    /// it moves with: the actuator's position is `sum w q_j`, its force `f` loads joint `j` with
    /// `w f`. Empty for other effects.
    pub transmission: Vec<(usize, f64)>,
    /// An `actuator_cross_spring`'s stretch as joint weights, `sum_N kN (C^-1 q)_N = u . q`
    /// (N·m, N per unit joint motion): its force is `-u . q`. Empty for other effects.
    pub cross: Vec<(usize, f64)>,
    /// Every parameter, defaults filled in.
    pub parameters: BTreeMap<String, f64>,
}

impl Effect {
    /// Parameter `name` (it exists: checked at compile time; 0 otherwise).
    pub fn get(&self, name: &str) -> f64 {
        self.parameters.get(name).copied().unwrap_or(0.0)
    }
}

/// The `coupling_error` parameter `dRC` of 0-based coupling entry (`row`, `col`).
pub fn coupling_entry_name(row: usize, col: usize) -> String {
    format!("d{}{}", row + 1, col + 1)
}

/// The 1-based (row, column) a `coupling_error` parameter `dRC` names.
pub(crate) fn coupling_entry(name: &str) -> Option<(usize, usize)> {
    let s = name.strip_prefix('d')?;
    let (r, c) = s.split_at(s.len() / 2);
    Some((r.parse::<usize>().ok()?, c.parse::<usize>().ok()?))
}
