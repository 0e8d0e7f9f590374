//! `dvrk synth hidden-effect`: a recording from a "truth" arm that has one or two physical
//! effects the nominal model lacks (or none), and a separate answer. The truth avoids the inverse crime where
//! it is cheap: it is integrated at a finer step (0.125 ms against the analysis' 1 ms samples),
//! the bodies' rotational inertias are perturbed by a few percent, the effects are dvrk-sim's
//! physics (a two-mass drive with play, a delayed measurement stream) while the workflow's
//! candidates are dvrk-kin's inverse dynamics with linearised signatures, and noise is added to
//! the recorded positions and efforts.

use super::excitation::MultiSine;
use dvrk_sim::recording::JointLog;
use crate::error::{CalibError, Result};
use dvrk_kin::effects::EffectKind;
use dvrk_kin::spec::FrameRef;
use dvrk_kin::Model;
use dvrk_kin::effects::EffectSpec;
use dvrk_sim::{Engine, Scene, Sim, SimOptions};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::Serialize;
use std::collections::BTreeMap;

/// The effects the generator draws at random (those dvrk-sim simulates that the torque channel
/// can tell from the inertias the workflow refits).
pub const HIDDEN_KINDS: [EffectKind; 9] = [
    EffectKind::CoulombFriction,
    EffectKind::ViscousFriction,
    EffectKind::Spring,
    EffectKind::JointCompliance,
    EffectKind::Backlash,
    EffectKind::Latency,
    EffectKind::JointOffset,
    EffectKind::PayloadMass,
    EffectKind::CouplingError,
];

/// Effects only a tracker on the link sees (hidden only with [`HiddenOptions::marker`]): a DH
/// length, the tracker's clock against the joint stream's, and a lightly loaded drive's play by
/// motion direction (the last two applied to the tracked link, not to the simulated arm, whose
/// efforts they leave as they are).
pub const TRACKED_KINDS: [EffectKind; 3] = [EffectKind::LinkLength, EffectKind::ClockOffset, EffectKind::MotionPlay];

/// The tracked kinds the tracker applies (to its stamps, to the link it sees), not the arm.
fn applied_by_tracker(spec: &EffectSpec) -> bool {
    spec.name == EffectKind::ClockOffset.name() || spec.name == EffectKind::MotionPlay.name()
}

/// Effects hidden only by name: the inertias the workflow refits take most of them. A
/// counterweight's mass is itself an inertial parameter, and its travel ratio moves the
/// insertion's load as a change of that mass does (seeds 1000, 1001: `none`, the refitted
/// inertias leaving 0.99-1.01 of the noise floor).
pub const ABSORBED_KINDS: [EffectKind; 1] = [EffectKind::CounterweightError];

/// The tool's actuator-space friction (hidden only by name, so that the random draws and the
/// tables' seeds stay as they were): at one of the wrist's actuators (5..7), whose cables move
/// the wrist pitch, yaw and jaw together.
pub const ACTUATOR_KINDS: [EffectKind; 2] = [EffectKind::ActuatorCoulombFriction, EffectKind::ActuatorViscousFriction];

/// Which effect(s) to hide.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Hidden {
    None,
    Kind(EffectKind),
    /// Two different kinds, both in the truth.
    Pair(EffectKind, EffectKind),
    /// One of [`HIDDEN_KINDS`], drawn from the seed.
    Random,
    /// Two different ones of [`HIDDEN_KINDS`], drawn from the seed.
    RandomPair,
}

impl std::str::FromStr for Hidden {
    type Err = String;
    /// `none`, `random`, `random-pair`, a kind (`backlash`) or two joined by `+`
    /// (`coulomb_friction+payload_mass`).
    fn from_str(s: &str) -> std::result::Result<Hidden, String> {
        let kind = |name: &str| match EffectKind::from_name(name) {
            Some(k) if HIDDEN_KINDS.contains(&k) || TRACKED_KINDS.contains(&k) || ABSORBED_KINDS.contains(&k) || ACTUATOR_KINDS.contains(&k) => Ok(k),
            _ => Err(format!(
                "`{name}` is not an effect the generator hides (valid: none, random, random-pair, {}, {}, {}, {} (with a marker), or two joined by +)",
                HIDDEN_KINDS.map(|k| k.name()).join(", "),
                ACTUATOR_KINDS.map(|k| k.name()).join(", "),
                ABSORBED_KINDS.map(|k| k.name()).join(", "),
                TRACKED_KINDS.map(|k| k.name()).join(", ")
            )),
        };
        match s {
            "none" => Ok(Hidden::None),
            "random" => Ok(Hidden::Random),
            "random-pair" => Ok(Hidden::RandomPair),
            _ => match s.split_once('+') {
                Some((a, b)) => {
                    let (a, b) = (kind(a.trim())?, kind(b.trim())?);
                    if a == b {
                        return Err(format!("`{s}`: a pair is two different effects"));
                    }
                    Ok(Hidden::Pair(a, b))
                }
                None => Ok(Hidden::Kind(kind(s)?)),
            },
        }
    }
}

/// Default effort noise per joint (N·m; N for the insertion): about 1% of each joint's RMS effort
/// in the exciting motion (measured: 0.92, 1.54, 0.32 N, 0.16, 0.15, 0.14 N·m), the order of the
/// dVRK's current-sense noise.
pub const EFFORT_NOISE: [f64; 7] = [0.01, 0.015, 0.005, 0.0015, 0.0015, 0.0015, 0.0015];
/// Default encoder noise (rad, m).
pub const POSITION_NOISE: f64 = 2e-6;

/// Start of the recording the effects' sizes are taken over (s): the excitation's fade-in is
/// left out.
const FADE_IN: f64 = 2.0;

/// Largest share of the samples past [`FADE_IN`] at which a joint's effort may sit at its limit.
/// A truth beyond it is a controller in a limit cycle, not a recording the dVRK makes (its
/// tracking-error check powers the arm off): seed 7017's 4 ms loop latency with a 7.2 mrad play
/// on the outer pitch made the PID chatter at 61 Hz, at the limit on 9% of the samples, and no
/// candidate's signature (each assumes a controller that tracks) could follow it. The effects'
/// parameters are then drawn again, and random kinds too (that latency with a play on any
/// joint, as drawn, saturated 8 times in 8).
const MAX_SATURATED: f64 = 0.01;

/// Draws of the effects' parameters before a truth that keeps saturating is an error.
const DRAWS: usize = 8;

/// The largest share, over the joints, of the samples from index `skip` on at which the joint's
/// recorded effort is at its limit (limits of 0: none), and that joint.
fn saturated_share(log: &JointLog, limits: &[f64], skip: usize) -> (f64, usize) {
    let n = log.len().saturating_sub(skip).max(1) as f64;
    (0..limits.len())
        .filter(|&k| limits[k] > 0.0)
        .map(|k| (log.effort[skip..].iter().filter(|e| e[k].abs() >= limits[k] * (1.0 - 1e-9)).count() as f64 / n, k))
        .fold((0.0, 0), |best, x| if x.0 > best.0 { x } else { best })
}

/// How to generate.
#[derive(Debug, Clone)]
pub struct HiddenOptions {
    pub hidden: Hidden,
    pub seed: u64,
    /// Recorded time (s).
    pub duration: f64,
    /// The truth's integration step (s); 1/8 of the sim's 1 ms by default. The loops' impulse
    /// joints carry the gravity load along a constraint direction one step old, which the yaw
    /// feels as a negative damping of its gravity stiffness times dt (measured: -1.1e-3 N·m s/rad
    /// at 0.25 ms, 0.4 of its effort noise floor, halving with the step). Such O(dt) errors are
    /// what the workflow's finest estimates see of the truth: an effect-free recording shows an
    /// apparent latency of 67, 38, 24 us at 0.25, 0.125, 0.0625 ms (seed 1000, no inertia
    /// perturbation; 31.5 us at 0.125 ms since the drives' damping is trapezoidal, see dvrk-sim),
    /// and a spring on the wrist yaw comes out 0.77% weak at 0.125 ms, 0.40% at 0.0625 ms (seed
    /// 1035, a tenth of the noise).
    pub truth_dt: f64,
    /// The engine the truth runs on. rapier (the default) shares no dynamics code with the
    /// analysis, which uses dvrk-kin's; the reduced engine is dvrk-kin's forward dynamics, about
    /// 16x faster at the same step, for regression nets that need many recordings.
    pub engine: Engine,
    /// Recording rate (Hz).
    pub rate: f64,
    /// Effort noise per joint (N·m, N); [`EFFORT_NOISE`] when `None`.
    pub effort_noise: Option<Vec<f64>>,
    /// Encoder noise (rad, m).
    pub position_noise: f64,
    /// Scale the effort noise of the effect's joint so that the effect's RMS over it is this
    /// (the effect-to-noise ratio); `None`: keep the noise.
    pub enr: Option<f64>,
    /// Relative standard deviation of the truth's rotational inertias (mass and centre kept).
    pub inertia_perturbation: f64,
    /// Scale of the drawn effect's parameters (1: the realistic range).
    pub magnitude: f64,
    /// A tracker on one link (the kinematic channel); `None`: joints only.
    pub marker: Option<MarkerOptions>,
    /// Where a hidden payload sits: `None` on the tool's yaw link ([`payload_frame`]);
    /// [`ANY_BODY`] on a moving body drawn by the seed; else on that frame's body. Off the tool,
    /// within 3 cm of the body's centre of mass in each axis.
    pub payload_link: Option<String>,
}

/// [`HiddenOptions::payload_link`]: a body drawn by the seed among every body the joints move.
pub const ANY_BODY: &str = "any";

/// A motion tracker following a marker body on one link: it sees the link itself (after any
/// play or compliance of its drive, and without the joint stream's latency).
#[derive(Debug, Clone, PartialEq)]
pub struct MarkerOptions {
    /// The link: frame name, or the paper's frame number.
    pub link: String,
    /// Tracker rate (Hz).
    pub rate: f64,
    /// Noise per axis: position (m) and rotation (rad).
    pub position_noise: f64,
    pub rotation_noise: f64,
}

impl Default for MarkerOptions {
    /// On the instrument's shaft, at an optical tracker's 100 Hz, 0.1 mm and 1 mrad.
    fn default() -> Self {
        MarkerOptions { link: "tool_roll".into(), rate: 100.0, position_noise: 1e-4, rotation_noise: 1e-3 }
    }
}

impl Default for HiddenOptions {
    fn default() -> Self {
        HiddenOptions { hidden: Hidden::Random, seed: 1, duration: 30.0, truth_dt: 1.25e-4, engine: Engine::Rapier, rate: 1000.0, effort_noise: None, position_noise: POSITION_NOISE, enr: None, inertia_perturbation: 0.03, magnitude: 1.0, marker: None, payload_link: None }
    }
}

/// One hidden effect and how strongly it shows.
#[derive(Debug, Clone, Serialize)]
pub struct HiddenEffect {
    /// The effect as a model file writes it.
    #[serde(flatten)]
    pub spec: EffectSpec,
    /// Joint index of a joint effect; the joint most affected for the others.
    pub joint_index: usize,
    /// RMS of what the effect adds to the recorded effort of `joint_index` (N·m, N): the truth
    /// against the truth without this effect (the other one kept).
    pub effect_rms: f64,
    /// `effect_rms` over that joint's effort noise.
    pub enr: f64,
}

/// What was hidden, for the test to compare with (never read by the workflow).
#[derive(Debug, Clone, Serialize)]
pub struct Answer {
    pub seed: u64,
    pub scene: String,
    /// The hidden effects (none: effect-free).
    pub effects: Vec<HiddenEffect>,
    /// The tracked marker's pose topic, when a tracker was simulated.
    pub marker_topic: Option<String>,
    /// Effort noise per joint (N·m, N) and encoder noise (rad, m).
    pub effort_noise: Vec<f64>,
    pub position_noise: f64,
    pub truth_dt: f64,
    /// The truth's engine; written only when it is not rapier (the answers' long-standing layout).
    #[serde(skip_serializing_if = "is_rapier")]
    pub truth_engine: Engine,
    pub inertia_perturbation: f64,
}

fn is_rapier(e: &Engine) -> bool {
    *e == Engine::Rapier
}

/// A hidden-effect recording.
#[derive(Debug, Clone)]
pub struct HiddenRecording {
    pub log: JointLog,
    pub answer: Answer,
}

/// The joints (positions in the arm) on which `kind` is drawn: where the encoder-and-effort
/// channels can see it (an offset only where gravity loads the joint; compliance and play on the
/// loaded outer drives; springs on the tool).
fn joints_for(kind: EffectKind) -> &'static [usize] {
    match kind {
        EffectKind::JointOffset => &[1],
        EffectKind::JointCompliance => &[1],
        EffectKind::Backlash => &[0, 1],
        // Where a PSM has springs: the tool's cables (roll, wrist). On an outer joint a spring is
        // not what a robot has, and over its motion it reads as a centre-of-mass error the
        // refitted inertias take.
        EffectKind::Spring => &[3, 4, 5],
        _ => &[0, 1, 2, 3, 4, 5],
    }
}

/// Draw `kind` with realistic magnitudes (times `scale`); a DH length on a link the tracker on
/// frame `marker` can see.
fn draw(kind: EffectKind, model: &Model, inertials: &dvrk_sim::inertials::Inertials, rng: &mut ChaCha8Rng, scale: f64, marker: Option<usize>, payload_link: Option<&str>) -> Result<EffectSpec> {
    if kind == EffectKind::LinkLength {
        let frames: Vec<usize> = marker.map(|f| super::kinematic::observable_lengths(model, f)).unwrap_or_default().into_iter().map(|(k, _)| k).collect();
        if frames.is_empty() {
            return Err(CalibError::field("effect", "link_length is hidden only with a tracker on a link beyond a moving joint (--marker-link)"));
        }
        let k = frames[rng.random_range(0..frames.len())];
        let s: f64 = if rng.random::<bool>() { 1.0 } else { -1.0 };
        let mut e = super::kinematic::length_effect(model, k, s * scale * rng.random_range(0.5e-3..2e-3));
        e.source = "dvrk synth hidden-effect".into();
        return Ok(e);
    }
    if kind == EffectKind::ClockOffset || kind == EffectKind::MotionPlay {
        if marker.is_none() {
            return Err(CalibError::field("effect", format!("{} is hidden only with a tracker (--marker-link)", kind.name())));
        }
        let s: f64 = if rng.random::<bool>() { 1.0 } else { -1.0 };
        // A motion-capture system's clock 5-30 ms off either way; a cable drive's play of
        // 0.2-0.6 deg (b half of it) on the outer yaw or pitch.
        let (joint, p) = match kind {
            EffectKind::ClockOffset => (None, ("seconds", s * scale * rng.random_range(5e-3..30e-3))),
            _ => (Some(model.joints[rng.random_range(0..2usize)].name.clone()), ("b", scale * rng.random_range(0.1..0.3_f64).to_radians())),
        };
        return Ok(EffectSpec { name: kind.name().into(), joint, link: None, actuator: None, parameters: BTreeMap::from([(p.0.to_string(), p.1)]), source: "dvrk synth hidden-effect".into() });
    }
    if ACTUATOR_KINDS.contains(&kind) {
        // One of the wrist's actuators (5..7: 1-based), at the WPI tool's magnitudes (its
        // identified actuator friction: Coulomb 0.008-0.025 N·m with the presliding level,
        // viscous 0.0009-0.003 N·m s/rad).
        let a = rng.random_range(5..=7usize);
        let (name, range) = match kind {
            EffectKind::ActuatorCoulombFriction => ("fc", (0.005, 0.02)),
            _ => ("fv", (0.001, 0.004)),
        };
        let p = BTreeMap::from([(name.to_string(), scale * rng.random_range(range.0..range.1))]);
        return Ok(EffectSpec { name: kind.name().into(), joint: None, link: None, actuator: Some(a), parameters: p, source: "dvrk synth hidden-effect".into() });
    }
    let js = joints_for(kind);
    let j = js[rng.random_range(0..js.len())];
    let prismatic = model.joints[j].kind == dvrk_kin::JointType::Prismatic;
    let wrist = j >= 3;
    // Per joint class: outer revolute, insertion (N, N s/m, N/m), wrist.
    let pick = |rng: &mut ChaCha8Rng, outer: (f64, f64), ins: (f64, f64), wr: (f64, f64)| {
        let (lo, hi) = if prismatic { ins } else if wrist { wr } else { outer };
        scale * rng.random_range(lo..hi)
    };
    let mut p = BTreeMap::new();
    let (joint, link) = match kind {
        EffectKind::CoulombFriction => {
            p.insert("fc".into(), pick(rng, (0.03, 0.1), (0.2, 0.6), (0.003, 0.01)));
            (Some(j), None)
        }
        EffectKind::ViscousFriction => {
            p.insert("fv".into(), pick(rng, (0.05, 0.2), (1.0, 4.0), (0.004, 0.015)));
            (Some(j), None)
        }
        EffectKind::Spring => {
            p.insert("k".into(), pick(rng, (0.1, 0.4), (10.0, 40.0), (0.01, 0.03)));
            p.insert("rest".into(), if prismatic { rng.random_range(0.08..0.16) } else { rng.random_range(-0.3..0.3) });
            (Some(j), None)
        }
        EffectKind::JointCompliance => {
            p.insert("stiffness".into(), rng.random_range(40.0..120.0) / scale);
            (Some(j), None)
        }
        EffectKind::Backlash => {
            p.insert("b".into(), scale * rng.random_range(0.004..0.012));
            (Some(j), None)
        }
        EffectKind::JointOffset => {
            let s: f64 = if rng.random::<bool>() { 1.0 } else { -1.0 };
            p.insert("offset".into(), s * scale * rng.random_range(0.01..0.04));
            (Some(j), None)
        }
        EffectKind::Latency => {
            // Whole milliseconds: the sim delays by whole steps.
            p.insert("seconds".into(), (scale * rng.random_range(3.0..12.0_f64)).round().max(1.0) * 1e-3);
            (None, None)
        }
        EffectKind::CounterweightError => {
            // Its travel ratio off by a few percent (pulley radii), its mass by up to a fifth
            // (the CAD has no counterweight: balance is what sets it).
            let at = inertials.counterweight(model).ok_or_else(|| CalibError::field("effect", "counterweight_error needs a model with a counterweight (a frame moving by its parameter mu)"))?;
            let sign = |rng: &mut ChaCha8Rng| if rng.random::<bool>() { 1.0 } else { -1.0 };
            p.insert("mu".into(), at[0] * (1.0 + sign(rng) * scale * rng.random_range(0.03..0.1)));
            p.insert("mass".into(), at[1] * (1.0 + sign(rng) * scale * rng.random_range(0.05..0.2)));
            (None, None)
        }
        EffectKind::CouplingError => {
            // One coupling entry of the wrist off by 2-8% (a cable's pulley or pretension), among
            // the joints the excitation moves (not the jaw).
            let c = model.coupling_matrix().ok_or_else(|| CalibError::field("effect", "coupling_error needs a model with an actuator coupling"))?;
            let entries = super::candidates::coupling_entries(&c, joints_for(kind));
            let (r, k) = entries[rng.random_range(0..entries.len())];
            let s: f64 = if rng.random::<bool>() { 1.0 } else { -1.0 };
            p.insert(dvrk_kin::effects::coupling_entry_name(r, k), s * scale * rng.random_range(0.02..0.08) * c[(r, k)].abs());
            (None, None)
        }
        EffectKind::PayloadMass => {
            p.insert("mass".into(), scale * rng.random_range(0.05..0.2));
            match payload_link {
                None => {
                    p.insert("z".into(), rng.random_range(0.0..0.03));
                    (None, Some(FrameRef::Name(payload_frame(model).to_string())))
                }
                Some(link) => {
                    let b = if link == ANY_BODY {
                        rng.random_range(0..model.bodies.len())
                    } else {
                        let f = model.frame_id(&FrameRef::Name(link.into())).map_err(|e| CalibError::field("payload link", e.to_string()))?;
                        model.frames[f].body
                    };
                    // Near the body's own centre of mass (its first frame's coordinates).
                    let com = inertials.body_inertias(model).map_err(|e| CalibError::context("inertials", e))?[b].com;
                    for (k, axis) in ["x", "y", "z"].iter().enumerate() {
                        p.insert((*axis).into(), com[k] + rng.random_range(-0.03..0.03));
                    }
                    (None, Some(FrameRef::Name(model.frames[model.bodies[b].frames[0]].name.clone())))
                }
            }
        }
        _ => unreachable!("not a hidden kind"),
    };
    Ok(EffectSpec { name: kind.name().into(), joint: joint.map(|j| model.joints[j].name.clone()), link, actuator: None, parameters: p, source: "dvrk synth hidden-effect".into() })
}

/// The tracker's poses of a marker on link `mo.link` of the truth `truth` (its own kinematics at
/// the links' joint positions `link`, sampled at `t`), at the tracker's rate, placed by a drawn
/// tracker-to-base and link-to-marker transform, with noise; the tracker's own effects of
/// `specs` applied: its clock's offset to its stamps, a motion play to the link it sees.
fn track_marker(truth: &Model, specs: &[EffectSpec], t: &[f64], link: &[Vec<f64>], mo: &MarkerOptions, rng: &mut ChaCha8Rng) -> Result<dvrk_sim::recording::MarkerLog> {
    use super::registration::pose_exp;
    use nalgebra::Vector6;
    if !(mo.rate.is_finite() && mo.rate > 0.0 && mo.position_noise.is_finite() && mo.position_noise >= 0.0 && mo.rotation_noise.is_finite() && mo.rotation_noise >= 0.0) {
        return Err(CalibError::field("marker", format!("rate {} Hz, noise {} m, {} rad: rate > 0 and noise >= 0", mo.rate, mo.position_noise, mo.rotation_noise)));
    }
    let frame = dvrk_sim::recording::marker_frame(truth, &mo.link)?;
    let mut u = |lo: f64, hi: f64| rng.random_range(lo..hi);
    // A tracker 1-2 m away, any orientation; the marker body a few cm off the link's frame.
    let x = pose_exp(&Vector6::new(u(-1.0, 1.0), u(-1.0, 1.0), u(1.0, 2.0), u(-3.0, 3.0), u(-3.0, 3.0), u(-3.0, 3.0)));
    let y = pose_exp(&Vector6::new(u(-0.05, 0.05), u(-0.05, 0.05), u(-0.05, 0.05), u(-3.0, 3.0), u(-3.0, 3.0), u(-3.0, 3.0)));
    let unit = Normal::new(0.0, 1.0).expect("unit normal");
    let mut data = dvrk_kin::Data::new(truth);
    let mut out = dvrk_sim::recording::MarkerLog { topic: dvrk_sim::recording::synthetic_topic(&truth.frames[frame].name), frame, t: Vec::new(), poses: Vec::new() };
    let mut late = 0.0;
    let mut link = link.to_vec();
    for e in specs.iter().filter(|e| applied_by_tracker(e)) {
        match e.joint.as_deref() {
            None => late += e.parameters["seconds"],
            Some(name) => {
                let j = truth.joint_id(name)?;
                let motor: Vec<f64> = link.iter().map(|q| q[j]).collect();
                let (mut behind, mut side) = (vec![0.0; motor.len()], vec![0.0; motor.len()]);
                dvrk_kin::effects::motion_play(e.parameters["b"], &motor, &mut behind, &mut side);
                link.iter_mut().zip(behind).for_each(|(q, l)| q[j] = l);
            }
        }
    }
    let mut next = t.first().copied().unwrap_or(0.0);
    for (ti, q) in t.iter().zip(&link) {
        if *ti + 1e-9 < next {
            continue;
        }
        next += 1.0 / mo.rate;
        dvrk_kin::compute_frame_placements(truth, &mut data, q);
        let mut n = Vector6::zeros();
        for k in 0..6 {
            n[k] = unit.sample(rng) * if k < 3 { mo.position_noise } else { mo.rotation_noise };
        }
        out.t.push(*ti + late);
        let p = x * data.frames[frame] * y;
        let r = nalgebra::Rotation3::new(n.fixed_rows::<3>(3).into_owned()) * p.rotation;
        out.poses.push(dvrk_kin::Pose::from_parts((p.translation.vector + n.fixed_rows::<3>(0)).into(), r));
    }
    Ok(out)
}

/// The frame a payload is hidden on: the instrument's wrist (what a grasped object loads).
pub fn payload_frame(model: &Model) -> &'static str {
    if model.frames.iter().any(|f| f.name == "tool_yaw") {
        "tool_yaw"
    } else {
        "tool_tip"
    }
}

/// The largest |effort| per joint (N·m, N) the predictor needs to follow `x` over one period,
/// sampled at 100 Hz.
fn peak_efforts(x: &MultiSine, predictor: &mut super::signals::Predictor) -> Result<Vec<f64>> {
    let nq = x.center.len();
    let n = (x.period() * 100.0) as usize;
    let (mut q, mut qd, mut qdd) = (vec![vec![0.0; nq]; n], vec![vec![0.0; nq]; n], vec![vec![0.0; nq]; n]);
    for i in 0..n {
        x.steady(i as f64 * 0.01, &mut q[i], &mut qd[i], &mut qdd[i]);
    }
    let effort = predictor.series_at(&q, &qd, &qdd)?;
    Ok((0..nq).map(|k| effort.iter().map(|e| e[k].abs()).fold(0.0, f64::max)).collect())
}

/// Simulate `scene` (arm 0) tracking `excitation` for `duration`, sampling setpoints, encoder
/// positions and efforts at `rate`; and the links' own joint positions at the same samples.
pub fn simulate(scene: &Scene, excitation: &MultiSine, duration: f64, rate: f64, engine: Engine) -> Result<(JointLog, Vec<Vec<f64>>)> {
    let mut scene = scene.clone();
    let nq = scene.arms[0].model.nq();
    let (mut q, mut qd) = (vec![0.0; nq], vec![0.0; nq]);
    excitation.sample(0.0, &mut q, &mut qd);
    scene.set_start(0, &q).map_err(CalibError::simulation)?;
    // Explicit Coriolis: rapier's implicit one reads late in a recording (the yaw's by half a
    // truth step), an apparent latency of the truth's integrator.
    let options = SimOptions { coriolis: dvrk_sim::Coriolis::Explicit, engine: Some(engine), ..SimOptions::default() };
    let mut sim = Sim::new(&scene, &options).map_err(CalibError::simulation)?;
    let dt = sim.dt;
    let stride = ((1.0 / (rate * dt)).round() as usize).max(1);
    let steps = (duration / dt).round() as usize;
    let names = scene.arms[0].model.joints.iter().map(|j| j.name.clone()).collect();
    let mut log = JointLog { names, ..Default::default() };
    let mut link = Vec::new();
    // A sample pairs the state at t with the effort the drives apply from t on (computed from
    // that state): simultaneous samples. The state after the step would lag its effort by one
    // step, a latency of -dt the workflow would rightly see in an effect-free recording.
    for s in 1..=steps {
        let t = s as f64 * dt;
        excitation.sample(t, &mut q, &mut qd);
        for i in 0..nq {
            sim.set_target(i, q[i], qd[i]).map_err(CalibError::simulation)?;
        }
        let sampled = s % stride == 0;
        if sampled {
            log.t.push(t);
            log.setpoint.push(q.clone());
            log.position.push(sim.q()[..nq].to_vec());
            link.push(sim.q_link()[..nq].to_vec());
        }
        sim.step();
        if sampled {
            log.effort.push((0..nq).map(|i| sim.effort(i).unwrap_or(f64::NAN)).collect());
        }
    }
    if log.position.iter().flatten().chain(log.effort.iter().flatten()).any(|x| !x.is_finite()) {
        return Err(CalibError::data("simulation", "the truth went non-finite (an effect too strong for the step?)"));
    }
    Ok((log, link))
}

/// The longest recording [`hidden_effect`] makes (s): 30 min, about 2 GB while it is made.
pub const MAX_DURATION: f64 = 1800.0;

/// Generate a hidden-effect recording of scene `scene_name` (its first arm).
pub fn hidden_effect(scene_name: &str, o: &HiddenOptions) -> Result<HiddenRecording> {
    // The generator keeps its whole recording in memory, about 1.2 MB per simulated second.
    if !(o.duration.is_finite() && (5.0..=MAX_DURATION).contains(&o.duration)) {
        return Err(CalibError::field("duration", format!("{} s: from 5 s to {MAX_DURATION} s (the generator keeps about 1.2 MB per simulated second in memory)", dvrk_kin::fmt_number(o.duration))));
    }
    if !(o.truth_dt.is_finite() && o.truth_dt > 0.0 && o.truth_dt <= 1e-3) {
        return Err(CalibError::field("truth dt", format!("{} s: must be in (0, 0.001]", o.truth_dt)));
    }
    if !(o.rate.is_finite() && o.rate > 0.0 && o.rate * o.truth_dt <= 1.0 + 1e-9) {
        return Err(CalibError::field("rate", format!("{} Hz: must be positive and at most 1 / truth dt", o.rate)));
    }
    if let Some(e) = o.enr {
        if !(e.is_finite() && e > 0.0) {
            return Err(CalibError::field("enr", format!("{e}: must be a positive number")));
        }
    }
    if !(o.position_noise.is_finite() && o.position_noise >= 0.0) {
        return Err(CalibError::field("position noise", format!("{}: must be >= 0", o.position_noise)));
    }
    let mut scene = Scene::load(scene_name).map_err(CalibError::simulation)?;
    scene.dt = o.truth_dt;
    let nominal = scene.arms[0].model.clone();
    let nq = nominal.nq();
    let mut effort_noise = o.effort_noise.clone().unwrap_or_else(|| EFFORT_NOISE.iter().copied().cycle().take(nq).collect());
    if effort_noise.len() != nq || effort_noise.iter().any(|x| !(x.is_finite() && *x >= 0.0)) {
        return Err(CalibError::field("effort noise", format!("{effort_noise:?}: one finite value >= 0 per joint ({nq})")));
    }
    let mut rng = ChaCha8Rng::seed_from_u64(o.seed);
    // The truth's inertias: rotational inertia scaled per body (a few percent), mass and centre kept.
    let perturb = Normal::new(0.0, o.inertia_perturbation.max(0.0)).map_err(|e| CalibError::field("inertia perturbation", e.to_string()))?;
    for b in &mut scene.arms[0].inertials.bodies {
        let s = (1.0 + perturb.sample(&mut rng)).clamp(0.8, 1.2);
        for row in &mut b.inertia {
            for x in row.iter_mut() {
                *x *= s;
            }
        }
    }
    let random = |rng: &mut ChaCha8Rng| HIDDEN_KINDS[rng.random_range(0..HIDDEN_KINDS.len())];
    let pick = |rng: &mut ChaCha8Rng| match o.hidden {
        Hidden::None => vec![],
        Hidden::Kind(k) => vec![k],
        Hidden::Pair(a, b) => vec![a, b],
        Hidden::Random => vec![random(rng)],
        Hidden::RandomPair => {
            let a = random(rng);
            let mut b = random(rng);
            while b == a {
                b = random(rng);
            }
            vec![a, b]
        }
    };
    let mut kinds = pick(&mut rng);
    let marker_frame = o.marker.as_ref().map(|m| dvrk_sim::recording::marker_frame(&nominal, &m.link)).transpose()?;
    let mut excitation = MultiSine::new(&nominal, o.seed);
    let limits: Vec<f64> = nominal.joints.iter().map(|j| j.effort_limit).collect();
    let mut predictor = super::signals::Predictor::new(&scene.arms[0].model, &scene.arms[0], scene.gravity)?;
    excitation.within_effort_limits(&limits, |x| peak_efforts(x, &mut predictor))?;
    // The truth with the effects `specs[keep]`.
    let truth_model = |specs: &[EffectSpec], keep: &[usize]| -> Result<Model> {
        let mut m = nominal.clone();
        for &i in keep.iter().filter(|&&i| !applied_by_tracker(&specs[i])) {
            m = m.with_effect(&specs[i])?;
        }
        m.base = scene.arms[0].original_base;
        Ok(m)
    };
    let run = |specs: &[EffectSpec], keep: &[usize]| -> Result<(JointLog, Vec<Vec<f64>>)> {
        let mut truth = scene.clone();
        truth.set_model(0, truth_model(specs, keep)?).map_err(CalibError::simulation)?;
        simulate(&truth, &excitation, o.duration, o.rate, o.engine)
    };
    let all: Vec<usize> = (0..kinds.len()).collect();
    // The effects' parameters (and random kinds), drawn again while their truth saturates a
    // drive (a loop latency with a play did on every one of 8 draws of their parameters).
    let mut draws = 0;
    let (specs, log, link, skip) = loop {
        let specs: Vec<EffectSpec> = kinds.iter().map(|&k| draw(k, &nominal, &scene.arms[0].inertials, &mut rng, o.magnitude, marker_frame, o.payload_link.as_deref())).collect::<Result<_>>()?;
        let (log, link) = run(&specs, &all)?;
        // Past the fade-in.
        let skip = log.t.iter().position(|t| *t >= FADE_IN).unwrap_or(0);
        let (share, joint) = saturated_share(&log, &limits, skip);
        draws += 1;
        if share <= MAX_SATURATED || kinds.is_empty() {
            break (specs, log, link, skip);
        }
        if draws == DRAWS {
            let names: Vec<&str> = kinds.iter().map(|k| k.name()).collect();
            return Err(CalibError::data("hidden effect", format!("{} drawn {DRAWS} times, and each time a joint sat at its effort limit on more than {:.1}% of the samples (a limit cycle; {} {:.1}% the last time)", names.join(" + "), 100.0 * MAX_SATURATED, nominal.joints[joint].name, 100.0 * share)));
        }
        if matches!(o.hidden, Hidden::Random | Hidden::RandomPair) {
            kinds = pick(&mut rng);
        }
    };
    // What each effect adds to each joint's effort (the truth against the truth without it),
    // past the fade-in.
    let mut shown = Vec::new();
    for (i, e) in specs.iter().enumerate() {
        let (without, _) = run(&specs, &all.iter().copied().filter(|&k| k != i).collect::<Vec<_>>())?;
        let n = (log.len() - skip) as f64;
        let rms: Vec<f64> = (0..nq).map(|k| (log.effort[skip..].iter().zip(&without.effort[skip..]).map(|(a, b)| (a[k] - b[k]).powi(2)).sum::<f64>() / n).sqrt()).collect();
        let j = match e.joint.as_deref() {
            Some(name) => nominal.joint_id(name)?,
            // Largest relative to the joint's noise.
            None => (0..nq.min(6)).max_by(|a, b| (rms[*a] / effort_noise[*a]).total_cmp(&(rms[*b] / effort_noise[*b]))).unwrap_or(0),
        };
        shown.push((j, rms[j]));
    }
    if let Some(target) = o.enr {
        // Each effect at least `target` times its joint's noise (two on one joint: the weaker sets
        // it); a length only the tracker sees keeps the effort noise.
        for j in 0..nq {
            let on_j = shown.iter().zip(&specs).filter(|((k, _), e)| *k == j && !TRACKED_KINDS.iter().any(|t| t.name() == e.name));
            if let Some(r) = on_j.map(|((_, r), _)| *r).min_by(f64::total_cmp) {
                effort_noise[j] = r / target;
            }
        }
    }
    let markers = match &o.marker {
        Some(mo) => Some(track_marker(&truth_model(&specs, &all)?, &specs, &log.t, &link, mo, &mut rng)?),
        None => None,
    };
    let effects = specs
        .into_iter()
        .zip(shown)
        .map(|(spec, (j, r))| HiddenEffect { spec, joint_index: j, effect_rms: r, enr: if effort_noise[j] > 0.0 { r / effort_noise[j] } else { f64::INFINITY } })
        .collect();
    let mut log = log;
    log.markers = markers;
    let unit = Normal::new(0.0, 1.0).expect("unit normal");
    for i in 0..log.len() {
        for k in 0..nq {
            log.position[i][k] += o.position_noise * unit.sample(&mut rng);
            log.effort[i][k] += effort_noise[k] * unit.sample(&mut rng);
        }
    }
    let answer = Answer {
        seed: o.seed,
        scene: scene_name.to_string(),
        effects,
        marker_topic: log.markers.as_ref().map(|m| m.topic.clone()),
        effort_noise,
        position_noise: o.position_noise,
        truth_dt: o.truth_dt,
        truth_engine: o.engine,
        inertia_perturbation: o.inertia_perturbation,
    };
    Ok(HiddenRecording { log, answer })
}
