//! The candidate effects of the torque channel and their signatures, taken from the model itself:
//! the change of the model's predicted effort when the effect is added (finite differences of
//! dvrk-kin's inverse dynamics on a model compiled with the effect), per unit of each parameter.
//! Every signature is linear in its parameters here (a coupling entry's to first order: the
//! workflow re-takes it as a secant, [`secant`]) except latency, whose 1-D profile (the
//! prediction shifted in time) is scanned in [`super::workflow`].

use super::signals::{Predictor, Prepared, COULOMB_SMOOTHING_DEFAULT};
use super::signature::Signature;
use crate::error::Result;
use dvrk_kin::effects::{EffectKind, EffectSpec};
use std::collections::BTreeMap;

pub(crate) use super::candidate::focus_of;
pub use super::candidate::{payload_at, Candidate};
use super::candidate::{local, names, spread};
pub use super::signals::Table;

fn diff(a: &Table, b: &Table, h: f64) -> Table {
    a.iter().zip(b).map(|(x, y)| x.iter().zip(y).map(|(u, v)| (u - v) / h).collect()).collect()
}


/// The Coulomb smoothing velocities tried (rad/s, m/s).
pub const COULOMB_SMOOTHING: [f64; 6] = [5e-4, 1e-3, 2e-3, 4e-3, 8e-3, 1.6e-2];

/// Joint `j`'s Coulomb signature, `tanh(qd_j / v)` (`v`: the smoothing, rad/s or m/s): the sign
/// taken at the recording's rate, then band-limited as the measured effort was. Inverse dynamics
/// on the band-limited velocity gives another signal: its sign flips sharply where this one is
/// spread over the band's impulse response (a Coulomb friction named by one round and evaluated
/// that way by the next left 3.3x the floor where the fit had left 1.07; seed 7013).
pub fn friction_sign(prep: &Prepared, nq: usize, j: usize, v: f64) -> Signature {
    let s = prep.band(&prep.fast_qd[j].iter().map(|x| (x / v).tanh()).collect::<Vec<_>>());
    local(prep, nq, j, |i| s[i])
}

/// An actuator's Coulomb signature: `tanh(a' / v)` of its velocity `a' = w . q'` (`w`: its
/// [`dvrk_kin::effects::Effect::transmission`]) band-limited as [`friction_sign`], reaching joint
/// `j` as `w_j` times that.
pub fn actuator_friction_sign(prep: &Prepared, nq: usize, w: &[(usize, f64)], v: f64) -> Signature {
    let raw = prep.fast_qd.first().map_or(0, Vec::len);
    let a: Vec<f64> = (0..raw).map(|i| (w.iter().map(|(j, c)| c * prep.fast_qd[*j][i]).sum::<f64>() / v).tanh()).collect();
    spread(nq, w, &prep.band(&a))
}

/// The actuator candidates of `model`: friction (Coulomb, its smoothing profiled; viscous),
/// spring and motor inertia on each actuator whose cables move several joints, one of them
/// active (an actuator of one joint is that joint: its joint effects are the candidates). Each
/// acts at the actuator's position `w . q` and loads the joints by `w` (virtual work).
fn actuators(model: &dvrk_kin::Model, prep: &Prepared) -> Vec<Candidate> {
    let nq = model.nq();
    let mut out = Vec::new();
    for a in 0..nq {
        let Ok((_, w)) = dvrk_kin::effects::actuator_transmission(model, a + 1) else { continue };
        if w.len() < 2 || !w.iter().any(|(j, _)| prep.active.contains(j)) {
            continue;
        }
        let at = |x: &dyn Fn(&[f64]) -> f64, rows: &[Vec<f64>]| -> Vec<f64> { rows.iter().map(|r| x(r)).collect() };
        let dot = |r: &[f64]| w.iter().map(|(j, c)| c * r[*j]).sum::<f64>();
        let sign = |v: f64| vec![actuator_friction_sign(prep, nq, &w, v)];
        let grid: Vec<(f64, Vec<Signature>)> = COULOMB_SMOOTHING.iter().map(|&v| (v, sign(v))).collect();
        let one = |kind, n: &[&str], columns: Vec<Signature>, profile| {
            let focus = focus_of(prep, &columns[0]);
            Candidate { kind, joint: None, link: None, actuator: Some(a), names: names(n), columns, at: vec![0.0; n.len()], range: None, focus, profile, fixed: vec![] }
        };
        out.push(one(EffectKind::ActuatorCoulombFriction, &["fc"], sign(COULOMB_SMOOTHING_DEFAULT), Some(("smoothing", grid))));
        out.push(one(EffectKind::ActuatorViscousFriction, &["fv"], vec![spread(nq, &w, &at(&dot, &prep.qd))], None));
        out.push(one(EffectKind::ActuatorSpring, &["k", "k_rest"], vec![spread(nq, &w, &at(&dot, &prep.q)), spread(nq, &w, &vec![-1.0; prep.t.len()])], None));
        out.push(one(EffectKind::MotorInertia, &["inertia"], vec![spread(nq, &w, &at(&dot, &prep.qdd))], None));
    }
    out
}

/// Whether a payload fit `x = (m, m dx, m dy, m dz)` linearised at `at` is a point mass: 1 g
/// or more, at a place within the vocabulary's range. Outside, the fit's first-moment columns
/// explain what no mass on the body can (WPI 105 g: a refit put 1 g on the tool's roll link at
/// 100 m from it, clamped to the range's edge, and the report lost the weight).
pub fn payload_is_a_point_mass(at: &[f64], x: &[f64]) -> bool {
    let r = EffectKind::PayloadMass.range("x").unwrap_or([-1.0, 1.0]);
    x[0] > 1e-3 && (0..3).all(|k| (r[0]..=r[1]).contains(&(at[k + 1] + x[k + 1] / x[0])))
}

/// Per moving joint where an offset shows (gravity or coupling load it), the change of every
/// joint's effort per unit offset of that joint (the joint's true position is the reading plus
/// the offset): the model's own sensitivity, by finite difference.
pub fn offset_sensitivities(predictor: &Predictor, arm: &dvrk_sim::scene::Arm, gravity: [f64; 3], prep: &Prepared, base: &Table) -> Result<Vec<(usize, Signature)>> {
    let model = &predictor.model;
    let mut out = Vec::new();
    for &j in &prep.active {
        let h = 1e-4;
        let spec = EffectSpec {
            name: "joint_offset".into(),
            joint: Some(model.joints[j].name.clone()),
            link: None,
            actuator: None,
            parameters: BTreeMap::from([("offset".into(), h)]),
            source: String::new(),
        };
        let shifted = Predictor::new(&model.with_effect(&spec)?, arm, gravity)?.series(prep)?;
        let d = diff(&shifted, base, h);
        if super::signals::rms(&d, j, 0..d.len()) > 1e-6 {
            out.push((j, Signature::from_table(&d, model.nq())));
        }
    }
    Ok(out)
}

/// For each joint in `joints`, the change of every joint's effort per unit velocity of that joint
/// (N·m s/rad, N s/m; Coriolis, centrifugal and damping coupling), by finite difference on the
/// model's prediction `base`: a drive's lag rate changes the other joints' load through it.
pub fn rate_sensitivities(predictor: &mut Predictor, prep: &Prepared, base: &Table, joints: &[usize]) -> Result<Vec<(usize, Signature)>> {
    let h = 1e-4;
    let mut moved = prep.qd.clone();
    let mut out = Vec::with_capacity(joints.len());
    for &j in joints {
        moved.iter_mut().zip(&prep.qd).for_each(|(m, q)| m[j] = q[j] + h);
        out.push((j, Signature::from_table(&diff(&predictor.series_at(&prep.q, &moved, &prep.qdd)?, base, h), base.first().map_or(0, Vec::len))));
        moved.iter_mut().zip(&prep.qd).for_each(|(m, q)| m[j] = q[j]);
    }
    Ok(out)
}

/// The linear candidates (friction, springs, offsets, the actuators' friction, springs and motor
/// inertia, the counterweight, the coupling's entries;
/// payloads are [`super::payload`]'s) for the joints `prep.active`,
/// with `base` the nominal prediction and `offsets` from [`offset_sensitivities`]. The drives'
/// compliance and play are profiles ([`super::drive`]), latency too.
pub fn build(predictor: &Predictor, arm: &dvrk_sim::scene::Arm, gravity: [f64; 3], prep: &Prepared, base: &Table, offsets: &[(usize, Signature)]) -> Result<Vec<Candidate>> {
    let model = &predictor.model;
    let nq = model.nq();
    let mut out = Vec::new();
    for &j in &prep.active {
        // Its smoothing (how soon the force saturates: stick, a Stribeck hump) profiled.
        let sign = |v: f64| vec![friction_sign(prep, nq, j, v)];
        let grid: Vec<(f64, Vec<Signature>)> = COULOMB_SMOOTHING.iter().map(|&v| (v, sign(v))).collect();
        out.push(Candidate {
            kind: EffectKind::CoulombFriction,
            joint: Some(j),
            link: None,
            actuator: None,
            names: names(&["fc"]),
            columns: sign(COULOMB_SMOOTHING_DEFAULT),
            at: vec![0.0],
            range: None,
            focus: j,
            profile: Some(("smoothing", grid)),
            fixed: vec![],
        });
        out.push(Candidate {
            kind: EffectKind::ViscousFriction,
            joint: Some(j),
            link: None,
            actuator: None,
            names: names(&["fv"]),
            columns: vec![local(prep, nq, j, |i| prep.qd[i][j])],
            at: vec![0.0],
            range: None,
            focus: j,
            profile: None,
            fixed: vec![],
        });
        // k (q - rest) = k q - (k rest): linear in (k, k rest).
        out.push(Candidate {
            kind: EffectKind::Spring,
            joint: Some(j),
            link: None,
            actuator: None,
            names: names(&["k", "k_rest"]),
            columns: vec![local(prep, nq, j, |i| prep.q[i][j]), local(prep, nq, j, |_| -1.0)],
            at: vec![0.0; 2],
            range: None,
            focus: j,
            profile: None,
            fixed: vec![],
        });
        if let Some((_, d)) = offsets.iter().find(|(k, _)| *k == j) {
            out.push(Candidate {
                kind: EffectKind::JointOffset,
                joint: Some(j),
                link: None,
                actuator: None,
                names: names(&["offset"]),
                columns: vec![d.clone()],
                at: vec![0.0],
                // A prismatic joint's in m, not the revolute +-pi.
                range: (model.joints[j].kind == dvrk_kin::JointType::Prismatic).then(|| EffectKind::JointOffset.range_on("offset", true).into_iter().collect()),
                focus: j,
                profile: None,
                fixed: vec![],
            });
        }
    }
    out.extend(actuators(model, prep));
    out.extend(super::friction_terms::candidates(model, prep));
    out.extend(counterweight(predictor, arm, gravity, prep, base)?);
    out.extend(coupling(predictor, arm, gravity, prep, base)?);
    Ok(out)
}

/// An effect on the whole model (no joint, no link) with `parameters`.
fn model_effect(kind: EffectKind, parameters: BTreeMap<String, f64>) -> EffectSpec {
    EffectSpec { name: kind.name().into(), joint: None, link: None, actuator: None, parameters, source: String::new() }
}

/// The signature of `effect` with parameters `at + h e_k` against `base`, per unit of each.
fn finite_differences(
    predictor: &Predictor,
    arm: &dvrk_sim::scene::Arm,
    gravity: [f64; 3],
    prep: &Prepared,
    base: &Table,
    effect: &EffectSpec,
    steps: &[(String, f64)],
) -> Result<Vec<Signature>> {
    let nq = predictor.model.nq();
    steps
        .iter()
        .map(|(name, h)| {
            let mut e = effect.clone();
            *e.parameters.entry(name.clone()).or_insert(0.0) += h;
            Ok(Signature::from_table(&diff(&Predictor::new(&predictor.model.with_effect(&e)?, arm, gravity)?.series(prep)?, base, *h), nq))
        })
        .collect()
}

/// A counterweight's travel per unit insertion `mu` and mass (kg), changed from the model's
/// (a model without a counterweight has no candidate). Linear in the two changes to first order.
fn counterweight(predictor: &Predictor, arm: &dvrk_sim::scene::Arm, gravity: [f64; 3], prep: &Prepared, base: &Table) -> Result<Vec<Candidate>> {
    let model = &predictor.model;
    let kind = EffectKind::CounterweightError;
    // The model's own: its counterweight_error if it has one, else its mu and the inertials' mass.
    let at = match model.effects.iter().rfind(|e| e.kind == kind) {
        Some(e) => [e.get("mu"), e.get("mass")],
        None => match arm.inertials.counterweight(model) {
            Some(at) => at,
            None => return Ok(vec![]),
        },
    };
    let effect = model_effect(kind, BTreeMap::from([("mu".into(), at[0]), ("mass".into(), at[1])]));
    let columns = finite_differences(predictor, arm, gravity, prep, base, &effect, &[("mu".into(), 1e-3), ("mass".into(), 1e-3)])?;
    let focus = focus_of(prep, &columns[1]);
    Ok(vec![Candidate { kind, joint: None, link: None, actuator: None, names: names(&["mu", "mass"]), columns, at: at.to_vec(), range: None, focus, profile: None, fixed: vec![] }])
}

/// The coupling entries a recording can show: non-zero, in a row that couples (not the
/// identity's), between joints that move (a held joint's actuator moves with the others, so its
/// entries read as theirs: the jaw's, when only the wrist moves). 0-based (row, column).
pub fn coupling_entries(c: &nalgebra::DMatrix<f64>, moving: &[usize]) -> Vec<(usize, usize)> {
    (0..c.nrows())
        .filter(|&r| moving.contains(&r) && (0..c.ncols()).any(|k| c[(r, k)] != if k == r { 1.0 } else { 0.0 }))
        .flat_map(|r| (0..c.ncols()).map(move |k| (r, k)))
        .filter(|&(r, k)| moving.contains(&k) && c[(r, k)] != 0.0)
        .collect()
}

/// A one-parameter finite-difference candidate (a coupling error) re-linearised through its
/// estimate `value`: the secant `(f(value) - f(0)) / value`, so that a refit is exact for the
/// signature's curvature (`B^T A B` is quadratic in the entry: the tangent alone under-reads a
/// 5% error by 2.4%).
pub fn secant(c: &Candidate, value: f64, predictor: &Predictor, arm: &dvrk_sim::scene::Arm, gravity: [f64; 3], prep: &Prepared, base: &Table) -> Result<Candidate> {
    let mut out = c.clone();
    out.columns = finite_differences(predictor, arm, gravity, prep, base, &model_effect(c.kind, BTreeMap::new()), &[(c.names[0].clone(), value)])?;
    Ok(out)
}

/// Each entry of [`coupling_entries`]: its error `dRC`, from the model's (a model without a
/// coupling has none).
fn coupling(predictor: &Predictor, arm: &dvrk_sim::scene::Arm, gravity: [f64; 3], prep: &Prepared, base: &Table) -> Result<Vec<Candidate>> {
    let model = &predictor.model;
    let kind = EffectKind::CouplingError;
    let Some(c) = model.coupling_matrix() else { return Ok(vec![]) };
    let mut out = Vec::new();
    for (r, k) in coupling_entries(&c, &prep.active) {
        let name = dvrk_kin::effects::coupling_entry_name(r, k);
        let at: f64 = model.effects.iter().filter(|e| e.kind == kind).map(|e| e.get(&name)).sum();
        let columns = finite_differences(predictor, arm, gravity, prep, base, &model_effect(kind, BTreeMap::new()), &[(name.clone(), 1e-3 * c[(r, k)].abs())])?;
        if columns[0].is_below(1e-12) {
            continue;
        }
        let focus = focus_of(prep, &columns[0]);
        out.push(Candidate {
            kind,
            joint: None,
            link: None,
            actuator: None,
            names: vec![name],
            columns,
            at: vec![at],
            range: Some(vec![dvrk_kin::effects::coupling_error_range(&c, r)]),
            focus,
            profile: None,
            fixed: vec![],
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::discrepancy::stats::Bounds;

    #[test]
    fn a_payload_fit_is_a_point_mass_only_with_a_mass_at_a_place_in_range() {
        let at = [0.0, 0.1, -0.5, 0.0];
        // 0.2 kg moved 5 cm: a point mass at (0.15, -0.5, 0).
        assert!(payload_is_a_point_mass(&at, &[0.2, 0.01, 0.0, 0.0]));
        // The WPI 105 g refit: 1.25 g whose first-moment columns move it 56 m.
        assert!(!payload_is_a_point_mass(&at, &[0.00125, 0.0, 0.0, -0.07]));
        // A place past the range's 1 m, and no mass at all.
        assert!(!payload_is_a_point_mass(&at, &[0.2, 0.0, -0.11, 0.0]));
        assert!(!payload_is_a_point_mass(&at, &[0.0, 0.0, 0.0, 0.0]));
    }

    fn candidate(kind: EffectKind, names: &[&str], at: &[f64]) -> Candidate {
        Candidate { kind, joint: None, link: None, actuator: None, names: super::names(names), columns: vec![], at: at.to_vec(), range: None, focus: 0, profile: None, fixed: vec![] }
    }

    /// A fit's bounds are the physical ranges less the model's own value: a coupling entry
    /// within a fifth of its row's largest (the WPI recording once fitted d44 = 0.74, a model
    /// that then did not load), a spring's stiffness in [0, 1e5] N·m/rad with its `k rest` free.
    #[test]
    fn fits_are_bounded_by_the_vocabulary() {
        let psm = dvrk_kin::load("psm", None).unwrap();
        let mut c = candidate(EffectKind::CouplingError, &["d55"], &[0.1]);
        c.range = Some(vec![dvrk_kin::effects::coupling_error_range(&psm.coupling_matrix().unwrap(), 4)]);
        let [b] = c.bounds()[..] else { panic!() };
        // Row 5's largest entry is 1.0186.
        assert!((b.lower.unwrap() + 0.30372).abs() < 1e-12 && (b.upper.unwrap() - 0.10372).abs() < 1e-12, "{b:?}");
        let s = candidate(EffectKind::Spring, &["k", "k_rest"], &[0.0, 0.0]);
        assert_eq!(s.bounds(), vec![Bounds::within(0.0, 1e5), Bounds::FREE]);
        let cw = candidate(EffectKind::CounterweightError, &["mu", "mass"], &[0.7, 1.5]);
        let b = cw.bounds();
        assert!((b[0].lower.unwrap() + 0.7).abs() < 1e-15 && (b[1].upper.unwrap() - 8.5).abs() < 1e-15, "{b:?}");
    }
}
