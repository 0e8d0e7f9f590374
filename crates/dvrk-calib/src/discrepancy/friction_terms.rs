//! The terms `dvrk identify` fits beyond a Coulomb level, viscous friction and a spring, as
//! candidates: a Coulomb friction's Stribeck (`fs`, its velocity `vs` profiled), winding (`fq`)
//! and presliding (`fd`, its displacement `sigma` profiled) terms on each analysed joint and on
//! each actuator whose cables move several joints, and the springs between the coupled
//! actuators (`actuator_cross_spring`, `kN`). Each is an effect of the vocabulary with these
//! parameters alone (a Stribeck or winding term written with `fc = 0`), added to the model's.
//!
//! A Stribeck or winding term is fitted as more friction of its shape (non-negative): written as
//! an effect of its own, a negative one would be clipped by the Coulomb level's floor at 0
//! ([`dvrk_kin::effects::coulomb_level`]). Presliding and cross springs take either sign.

use super::candidate::{focus_of, local, names, spread, Candidate};
use super::signals::{Prepared, COULOMB_SMOOTHING_DEFAULT};
use super::signature::Signature;
use dvrk_kin::effects::{actuator_transmission, EffectKind, CROSS_SPRING_RANGE};
use dvrk_kin::JointType;

/// Stribeck velocities tried (rad/s; a prismatic joint's a tenth, m/s): `dvrk identify`'s 0.05
/// and a factor of 3 either side (each grid point is a fit of every round).
const STRIBECK_VELOCITY: [f64; 3] = [0.0167, 0.05, 0.15];

/// Presliding displacements tried (rad; a prismatic joint's a tenth, m): `dvrk identify`'s 0.01
/// and a factor of 3 either side.
const DAHL_DISPLACEMENT: [f64; 3] = [0.0033, 0.01, 0.03];

/// The upper bound of a Stribeck level's change (N·m, N; the vocabulary's) and of a winding
/// term's (N·m/rad^2, N/m^2).
const STRIBECK_MAX: f64 = 100.0;
const WINDING_MAX: f64 = 1e5;

/// A sliding motion: its position at the analysed samples (rad, m), its velocity at the
/// recording's rate (rad/s, m/s), and how its force reaches the joints.
struct Slider<'a> {
    position: Vec<f64>,
    fast_velocity: Vec<f64>,
    prismatic: bool,
    joint: Option<usize>,
    actuator: Option<usize>,
    weights: &'a [(usize, f64)],
}

impl Slider<'_> {
    /// Per-sample signal `a` as joint efforts.
    fn to_joints(&self, prep: &Prepared, nq: usize, a: &[f64]) -> Signature {
        match self.joint {
            Some(j) => local(prep, nq, j, |i| a[i]),
            None => spread(nq, self.weights, a),
        }
    }

    /// `f(v)` at the recording's rate, band-limited as the measured effort was.
    fn band(&self, prep: &Prepared, f: impl Fn(f64) -> f64) -> Vec<f64> {
        prep.band(&self.fast_velocity.iter().map(|&v| f(v)).collect::<Vec<_>>())
    }

    fn candidate(&self, prep: &Prepared, kind: EffectKind, name: &str, grid: Vec<(f64, Signature)>, profile: Option<&'static str>, range: Option<[f64; 2]>, fixed: Vec<(&'static str, f64)>) -> Candidate {
        let middle = grid[grid.len() / 2].1.clone();
        let focus = focus_of(prep, &middle);
        Candidate {
            kind,
            joint: self.joint,
            link: None,
            actuator: self.actuator,
            names: names(&[name]),
            columns: vec![middle],
            at: vec![0.0],
            range: range.map(|r| vec![r]),
            focus,
            profile: profile.map(|p| (p, grid.into_iter().map(|(v, s)| (v, vec![s])).collect())),
            fixed,
        }
    }

    /// Its Stribeck, winding and presliding candidates.
    fn terms(&self, prep: &Prepared, nq: usize, kind: EffectKind) -> Vec<Candidate> {
        let scale = if self.prismatic { 0.1 } else { 1.0 };
        let s = COULOMB_SMOOTHING_DEFAULT;
        let stribeck: Vec<(f64, Signature)> = STRIBECK_VELOCITY
            .iter()
            .map(|&vs| {
                let vs = vs * scale;
                (vs, self.to_joints(prep, nq, &self.band(prep, |v| (-(v / vs).powi(2)).exp() * (v / s).tanh())))
            })
            .collect();
        let sign = self.band(prep, |v| (v / s).tanh());
        let winding: Vec<f64> = self.position.iter().zip(&sign).map(|(a, g)| a * a * g).collect();
        let presliding: Vec<(f64, Signature)> = DAHL_DISPLACEMENT
            .iter()
            .map(|&sigma| {
                let sigma = sigma * scale;
                (sigma, self.to_joints(prep, nq, &dvrk_kin::presliding::dahl_state(&self.position, sigma)))
            })
            .collect();
        let coulomb = [("fc", 0.0), ("smoothing", s)];
        vec![
            self.candidate(prep, kind, "fs", stribeck, Some("vs"), Some([0.0, STRIBECK_MAX]), coulomb.to_vec()),
            self.candidate(prep, kind, "fq", vec![(0.0, self.to_joints(prep, nq, &winding))], None, Some([0.0, WINDING_MAX]), coulomb.to_vec()),
            self.candidate(prep, kind, "fd", presliding, Some("sigma"), None, vec![("fc", 0.0)]),
        ]
    }
}

/// The candidates of the module's terms for `prep.active` and the model's coupled actuators.
pub fn candidates(model: &dvrk_kin::Model, prep: &Prepared) -> Vec<Candidate> {
    let nq = model.nq();
    let mut out = Vec::new();
    for &j in &prep.active {
        let slider = Slider {
            position: prep.q.iter().map(|q| q[j]).collect(),
            fast_velocity: prep.fast_qd[j].clone(),
            prismatic: model.joints[j].kind == JointType::Prismatic,
            joint: Some(j),
            actuator: None,
            weights: &[],
        };
        out.extend(slider.terms(prep, nq, EffectKind::CoulombFriction));
    }
    // The actuators (0-based) and their transmissions; the coupled group: the joints some
    // actuator's cables move together, and the actuators that move only those.
    let transmissions: Vec<(usize, Vec<(usize, f64)>)> = (0..nq).filter_map(|a| actuator_transmission(model, a + 1).ok().map(|(_, w)| (a, w))).collect();
    let group: Vec<usize> = transmissions.iter().filter(|(_, w)| w.len() >= 2).flat_map(|(_, w)| w.iter().map(|(j, _)| *j)).collect();
    let moving = |w: &[(usize, f64)]| w.iter().any(|(j, _)| prep.active.contains(j));
    let coupled: Vec<&(usize, Vec<(usize, f64)>)> = transmissions.iter().filter(|(_, w)| moving(w) && w.iter().all(|(j, _)| group.contains(j))).collect();
    let position = |w: &[(usize, f64)]| -> Vec<f64> { prep.q.iter().map(|q| w.iter().map(|(j, c)| c * q[*j]).sum()).collect() };
    for (a, w) in &coupled {
        if w.len() >= 2 {
            let raw = prep.fast_qd.first().map_or(0, Vec::len);
            let slider = Slider {
                position: position(w),
                fast_velocity: (0..raw).map(|i| w.iter().map(|(j, c)| c * prep.fast_qd[*j][i]).sum()).collect(),
                prismatic: false,
                joint: None,
                actuator: Some(*a),
                weights: w,
            };
            out.extend(slider.terms(prep, nq, EffectKind::ActuatorCoulombFriction));
        }
        // A spring on actuator a from actuator n's position: force k a_n at a (the fit's sign:
        // the motor supplies it), reaching the joints through a's cables.
        for (n, wn) in coupled.iter().filter(|(n, _)| n != a) {
            let column = spread(nq, w, &position(wn));
            let focus = focus_of(prep, &column);
            out.push(Candidate {
                kind: EffectKind::ActuatorCrossSpring,
                joint: None,
                link: None,
                actuator: Some(*a),
                names: vec![format!("k{}", n + 1)],
                columns: vec![column],
                at: vec![0.0],
                range: Some(vec![CROSS_SPRING_RANGE]),
                focus,
                profile: None,
                fixed: vec![],
            });
        }
    }
    out
}
