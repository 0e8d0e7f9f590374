//! Payload candidates on every moving body: a point mass `m` at `p` (m, in the body's first
//! frame) changes the body's inertial parameters by `m phi(p)`, `phi(p) = [1, p, |p|^2 1 - p p^T]`
//! (dvrk-kin's linear form), so its effort is the body's regressor columns times `m phi(p)`:
//! exact, and linear in `m` for a given `p`. The place is found by profiling the mass out
//! (`m(p) = max(0, b.phi / phi^T G phi)` from the normal equations of the body's ten columns in
//! the metric the inertia nuisance leaves) over a grid of places, then refined by a pattern
//! search; the candidate is that fit linearised at its place, `(m, m dx, m dy, m dz)`, so the
//! workflow scores and bounds it as any linear candidate.
//!
//! Why not the first-order form `(m, m x, m y, m z)` about the frame's origin: a weight 0.5 m
//! out changes its body's inertia by `m |p|^2`, a tenth of its effect, and that fit put the WPI
//! arm's 205 g on the insertion stage at zero mass.

use super::candidates::{focus_of, Candidate, Table};
use super::fit::{Fitter, Rows};
use super::signals::Prepared;
use super::signature::{Series, Signature};
use crate::error::Result;
use dvrk_kin::dynamics::PARAMETERS_PER_BODY;
use dvrk_kin::effects::EffectKind;
use dvrk_kin::{DynamicsData, DynamicsModel, Model};
use nalgebra::{DMatrix, DVector, Vector3};

/// Each body's regressor columns over the analysed samples (N·m or N per kg, kg m, kg m^2),
/// computed a few bodies at a time ([`BodyColumns::of_range`]): all of them at once are ten
/// tables per body, 300 MB on a 5-minute recording.
pub struct BodyColumns<'a> {
    pub model: &'a Model,
    pub dynamics: &'a DynamicsModel,
    /// m/s^2
    pub gravity: &'a Vector3<f64>,
    pub prep: &'a Prepared,
    /// Applied to each column where the model has a latency (as to every other signature).
    pub shift: Option<&'a dyn Fn(Table) -> Table>,
}

impl BodyColumns<'_> {
    /// Moving bodies.
    pub fn bodies(&self) -> usize {
        self.dynamics.inertias().len()
    }

    /// The ten columns of each body in `bodies`: dvrk-kin's regressor at every analysed sample
    /// (one pass for them all), through `shift`.
    pub fn of_range(&self, bodies: std::ops::Range<usize>) -> Result<Vec<Vec<Signature>>> {
        let (model, prep) = (self.model, self.prep);
        let (nq, n) = (model.nq(), prep.t.len());
        let mut data = DynamicsData::new(model);
        let mut y = DMatrix::zeros(nq, self.bodies() * PARAMETERS_PER_BODY);
        // `[body][parameter][joint]`, each a series over the samples.
        let mut series = vec![vec![vec![vec![0.0; n]; nq]; PARAMETERS_PER_BODY]; bodies.len()];
        for i in 0..n {
            dvrk_kin::regressor(model, self.dynamics, &mut data, &prep.q[i], &prep.qd[i], &prep.qdd[i], self.gravity, &mut y)?;
            for (b, body) in bodies.clone().zip(series.iter_mut()) {
                for (k, joints) in body.iter_mut().enumerate() {
                    for (j, s) in joints.iter_mut().enumerate() {
                        s[i] = y[(j, b * PARAMETERS_PER_BODY + k)];
                    }
                }
            }
        }
        Ok(series
            .into_iter()
            .map(|body| {
                body.into_iter()
                    .map(|joints| {
                        let column = Signature::from_joints(n, joints);
                        match self.shift {
                            Some(shift) => Signature::from_table(&shift(column.to_table()), nq),
                            None => column,
                        }
                    })
                    .collect()
            })
            .collect())
    }

    /// How many bodies' columns [`BodyColumns::of_range`] takes at once: as many as fit in
    /// [`COLUMNS_BUDGET`] (the regressor's pass is shared by them).
    pub fn chunk(&self) -> usize {
        let per_body = self.prep.t.len() * self.model.nq() * PARAMETERS_PER_BODY * std::mem::size_of::<f64>();
        (COLUMNS_BUDGET / per_body.max(1)).max(1)
    }
}

/// Bytes of body columns held at once (a 30 s recording's 20 bodies fit in one pass; a
/// 5-minute one takes several).
const COLUMNS_BUDGET: usize = 64 << 20;

/// `phi(p)`: a unit point mass at `p` as a body's linear-form parameters.
fn phi(p: &[f64; 3]) -> [f64; PARAMETERS_PER_BODY] {
    let [x, y, z] = *p;
    [1.0, x, y, z, y * y + z * z, -x * y, -x * z, x * x + z * z, -y * z, x * x + y * y]
}

/// `d phi / d p_k`.
fn dphi(p: &[f64; 3], k: usize) -> [f64; PARAMETERS_PER_BODY] {
    let [x, y, z] = *p;
    match k {
        0 => [0.0, 1.0, 0.0, 0.0, 0.0, -y, -z, 2.0 * x, 0.0, 2.0 * x],
        1 => [0.0, 0.0, 1.0, 0.0, 2.0 * y, -x, 0.0, 0.0, -z, 2.0 * y],
        _ => [0.0, 0.0, 0.0, 1.0, 2.0 * z, 0.0, -x, 2.0 * z, -y, 0.0],
    }
}

/// The effort of parameter weights `w` over a body's columns (`nq` joints).
fn combine(columns: &[Signature], w: &[f64; PARAMETERS_PER_BODY], nq: usize) -> Signature {
    let n = columns[0].samples();
    Signature::from_joints(n, (0..nq).map(|j| (0..n).map(|i| columns.iter().zip(w).map(|(c, wk)| c.at(i, j) * wk).sum()).collect()))
}

/// Half-width (m) of the box a payload's place is searched in: the vocabulary's +-1 m less the
/// margin a place needs to be written back (the effect's range check).
const REACH: f64 = 0.95;

/// The grid's step (m) before the pattern search.
const GRID_STEP: f64 = 0.1;

/// The best place and mass of a payload on a body whose ten columns have normal equations `g`,
/// `b` (in the nuisance's metric): the place that explains most (`(b.phi)^2 / phi^T G phi`,
/// with a non-negative mass), and its mass (kg). `None` where no place takes up any residual.
pub fn best_place(g: &DMatrix<f64>, b: &DVector<f64>) -> Option<([f64; 3], f64)> {
    let gain = |p: &[f64; 3]| -> (f64, f64) {
        let f = DVector::from_column_slice(&phi(p));
        let (num, den) = (b.dot(&f), (g * &f).dot(&f));
        if num > 0.0 && den > 0.0 {
            (num * num / den, num / den)
        } else {
            (0.0, 0.0)
        }
    };
    let steps = (REACH / GRID_STEP).floor() as i32;
    let mut best = ([0.0; 3], 0.0);
    for i in -steps..=steps {
        for j in -steps..=steps {
            for k in -steps..=steps {
                let p = [i as f64 * GRID_STEP, j as f64 * GRID_STEP, k as f64 * GRID_STEP];
                let v = gain(&p).0;
                if v > best.1 {
                    best = (p, v);
                }
            }
        }
    }
    if best.1 <= 0.0 {
        return None;
    }
    let (place, _) = pattern_search(best.0, best.1, GRID_STEP / 2.0, &|p| gain(p).0);
    Some((place, gain(&place).1))
}

/// Pattern search for the maximum of `f` from `p` (where it is `value`): each axis in turn, a
/// move kept when it raises `f` (beyond round-off), the step halved when none does, down to 0.1
/// mm; the place stays in the search box. The place and `f` there.
fn pattern_search(mut p: [f64; 3], mut value: f64, mut step: f64, f: &dyn Fn(&[f64; 3]) -> f64) -> ([f64; 3], f64) {
    while step > 1e-4 {
        let mut moved = false;
        for axis in 0..3 {
            for sign in [-1.0, 1.0] {
                let mut q = p;
                q[axis] = (q[axis] + sign * step).clamp(-REACH, REACH);
                let v = f(&q);
                if v > value + 1e-12 * value.abs() {
                    (p, value, moved) = (q, v, true);
                }
            }
        }
        if !moved {
            step /= 2.0;
        }
    }
    (p, value)
}

/// A body's ten columns' normal equations in the nuisance's metric (`G`, `b`), for the payload's
/// profile ([`profile`]).
pub type Normal = (DMatrix<f64>, DVector<f64>);

/// The payload candidate of every body whose payload some analysed joint feels, each at its
/// best place ([`best_place`]) for residual `r` (`[sample][joint]`, N·m, N), with its body's
/// normal equations (keyed by the candidate's link).
pub fn candidates(model: &Model, bodies: &BodyColumns, fit: &Fitter, r: &Table, prep: &Prepared) -> Result<(Vec<Candidate>, std::collections::BTreeMap<String, Normal>)> {
    let train = Rows::train(prep);
    let y = train.vector(r);
    let mut out = Vec::new();
    let mut normals = std::collections::BTreeMap::new();
    let chunk = bodies.chunk();
    let mut taken = Vec::new();
    for b in 0..bodies.bodies() {
        if taken.is_empty() {
            taken = bodies.of_range(b..(b + chunk).min(bodies.bodies()))?;
            taken.reverse();
        }
        let cols = taken.pop().unwrap_or_default();
        let cols = &cols;
        let a = train.matrix(cols);
        let link = model.frames[model.bodies[b].frames[0]].name.clone();
        let (g, bv) = fit.normal_equations(&a, &y);
        // A body whose frame's origin lies on the axes that move it (the PSM's parallelogram's
        // back and front links, on the pitch's and the yaw's) is no candidate of its own: it
        // turns as `pitch_end` does about a point of the same axes, so a load on it is one on
        // `pitch_end` exactly (the report lists it as that load's equivalent).
        let candidate = a.column(0).amax() >= 1e-12;
        let at = if candidate { best_place(&g, &bv).map_or([0.0; 3], |(p, _)| p) } else { [0.0; 3] };
        normals.insert(link.clone(), (g, bv));
        if !candidate {
            continue;
        }
        let mut columns = vec![combine(cols, &phi(&at), model.nq())];
        columns.extend((0..3).map(|k| combine(cols, &dphi(&at, k), model.nq())));
        let focus = focus_of(prep, &columns[0]);
        out.push(Candidate {
            kind: EffectKind::PayloadMass,
            joint: None,
            link: Some(link),
            actuator: None,
            names: ["mass", "mx", "my", "mz"].map(String::from).to_vec(),
            columns,
            at: vec![0.0, at[0], at[1], at[2]],
            range: None,
            focus,
            profile: None,
            fixed: vec![],
        });
    }
    Ok((out, normals))
}

/// A payload's profile likelihood over its mass: at each mass the place that explains most
/// (a pattern search from the last), kept while the fit is within a 95% likelihood ratio of the
/// best (`chi2_unit`: the squared residual one unit of chi-square is, autocorrelation
/// included). The ranges of the mass, the place, the first moment about `pivot` and the
/// distance from it over the kept points are their intervals: a mass and distance that trade
/// show as wide ranges beside a narrow first moment.
#[derive(Debug, Clone, Copy)]
pub struct Profile {
    pub mass: [f64; 2],
    /// The place (m, link frame) of the lightest mass kept: with it, an equivalent placement
    /// within the interval when the best mass runs to the vocabulary's bound.
    pub lightest_place: [f64; 3],
    pub position: [[f64; 2]; 3],
    pub first_moment: [f64; 2],
    pub distance: [f64; 2],
}

/// The residual's drop (the fit's squared units) of a point mass `mass` (kg) at `place` (m) on
/// a body with normal equations `normal`, the inertias refitted within their prior.
pub fn gain(normal: &Normal, mass: f64, place: &[f64; 3]) -> f64 {
    let (g, b) = normal;
    let f = DVector::from_column_slice(&phi(place));
    2.0 * mass * b.dot(&f) - mass * mass * (g * &f).dot(&f)
}

/// [`Profile`] of a payload best at `place`, `mass` on a body with normal equations `normal`.
pub fn profile(normal: &Normal, place: [f64; 3], mass: f64, pivot: [f64; 3], chi2_unit: f64) -> Profile {
    let gain = |m: f64, p: &[f64; 3]| gain(normal, m, p);
    let best = gain(mass, &place);
    let c = Vector3::from(pivot);
    let mut out = Profile { mass: [mass; 2], lightest_place: place, position: std::array::from_fn(|k| [place[k]; 2]), first_moment: [0.0; 2], distance: [0.0; 2] };
    let d0 = (Vector3::from(place) - c).norm();
    (out.first_moment, out.distance) = ([mass * d0; 2], [d0; 2]);
    let mut extend = |m: f64, p: &[f64; 3]| {
        let d = (Vector3::from(*p) - c).norm();
        if m < out.mass[0] {
            out.lightest_place = *p;
        }
        out.mass = [out.mass[0].min(m), out.mass[1].max(m)];
        for k in 0..3 {
            out.position[k] = [out.position[k][0].min(p[k]), out.position[k][1].max(p[k])];
        }
        out.first_moment = [out.first_moment[0].min(m * d), out.first_moment[1].max(m * d)];
        out.distance = [out.distance[0].min(d), out.distance[1].max(d)];
    };
    let upper = EffectKind::PayloadMass.range("mass").map_or(20.0, |r| r[1]);
    for dir in [-1.0, 1.0] {
        let mut p = place;
        for i in 1..=PROFILE_STEPS {
            let m = mass * (PROFILE_SPAN.ln() * dir * i as f64 / PROFILE_STEPS as f64).exp();
            if m > upper {
                break;
            }
            // The place that explains most at this mass.
            let here;
            (p, here) = pattern_search(p, gain(m, &p), GRID_STEP, &|q| gain(m, q));
            if (best - here) / chi2_unit.max(1e-300) > 3.841 {
                break;
            }
            extend(m, &p);
        }
    }
    out
}

/// Steps of a payload's mass profile each way, and the factor it spans each way.
const PROFILE_STEPS: usize = 40;
const PROFILE_SPAN: f64 = 30.0;

/// The point of a body that moves least over the recorded motion (m, in the body's first
/// frame; dvrk-sim's pivot fit of its poses in `frames`, every frame's pose at the sampled
/// configurations, [`super::payload_family::sampled_frames`]), and the RMS of its motion (m):
/// for a body that turns about a fixed point (the parallelogram's links about the remote
/// centre) that point, still to round-off.
pub fn pivot(model: &Model, body: usize, frames: &[Vec<dvrk_kin::Pose>]) -> ([f64; 3], f64) {
    let frame = model.bodies[body].frames[0];
    let poses: Vec<_> = frames.iter().map(|f| f[frame]).collect();
    match dvrk_sim::pivot::pivot_fit(&poses) {
        Some(f) => ([f.tip.x, f.tip.y, f.tip.z], f.rms),
        // Orientations that fix no point (a body turning about one axis only): the frame's
        // origin, and how much it moves about its mean.
        None => {
            let mean = poses.iter().map(|p| p.translation.vector).sum::<Vector3<f64>>() / poses.len().max(1) as f64;
            ([0.0; 3], (poses.iter().map(|p| (p.translation.vector - mean).norm_squared()).sum::<f64>() / poses.len().max(1) as f64).sqrt())
        }
    }
}

/// A payload's place and what the recording fixes of it (intervals: the ranges of
/// [`Profile`]).
#[derive(Debug, Clone, serde::Serialize)]
pub struct PayloadReport {
    /// kg, with its 95% interval.
    pub mass: f64,
    pub mass_ci95: [f64; 2],
    /// m, in the link's frame, each coordinate with its 95% interval.
    pub position: [f64; 3],
    pub position_ci95: [[f64; 2]; 3],
    /// The point of the body that moves least over the recording (m, link frame), and how much
    /// it moves (RMS, m): the point the body turns about when that is near 0.
    pub pivot: [f64; 3],
    pub pivot_motion_rms: f64,
    /// The mass times its distance from the pivot (kg m), with its 95% interval: what gravity
    /// alone fixes of a payload on a body turning about a point.
    pub first_moment: f64,
    pub first_moment_ci95: [f64; 2],
    /// The distance from the pivot (m), with its 95% interval.
    pub distance: f64,
    pub distance_ci95: [f64; 2],
    /// What the recording cannot fix (coordinates whose 95% interval is wider than +-5 cm, a
    /// mass known to less than +-20%), in words.
    pub cannot_fix: Vec<String>,
    /// Bodies the recording cannot tell from this one (their payload explains as much, within
    /// the ambiguity threshold in BIC) and the other bodies of its family whose payload the
    /// recording supports on its own (same gravitational signature up to placement), each with
    /// its own equivalent placement and how far behind it is.
    pub equivalent: Vec<Placement>,
    /// The crank radius (m) of a body that translates (its first moment is the mass times it),
    /// `None` for a body that turns.
    pub crank: Option<f64>,
    /// What the family's members share and which one the inertia prefers, in words.
    pub family: Option<String>,
    /// The joint of the family whose axis `axis_first_moment` is about (the PSM's
    /// `outer_pitch`): the family's last, `None` outside a family.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub axis_joint: Option<String>,
    /// The mass times its distance from that joint's axis through the pivot (kg m; a
    /// translating body's: the mass times its crank), with its 95% interval: what that joint's
    /// gravity load fixes, wherever along the axis the weight sits.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub axis_first_moment: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub axis_first_moment_ci95: Option<[f64; 2]>,
}

/// A payload's equivalent placement on another body.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Placement {
    pub link: String,
    /// kg; m in the link's frame.
    pub mass: f64,
    pub position: [f64; 3],
    pub delta_bic: f64,
    /// Its first moment (kg m) about its body's pivot, or the mass times the crank of a body
    /// that translates ([`super::payload_family::crank`]).
    pub first_moment: f64,
    /// How much less this placement explains than the named one (delta BIC): what the load's
    /// inertia (its gravity being the same) says against it; below the ambiguity threshold the
    /// recording cannot tell them apart.
    pub behind_bic: f64,
}

/// Half-width (m) beyond which a coordinate counts as not fixed, and the relative half-width of
/// a mass or first moment.
const FIXED_POSITION: f64 = 0.05;
const FIXED_RELATIVE: f64 = 0.2;

/// The report of a payload at `place` with `mass` (kg), its intervals from its [`Profile`], on
/// a body whose pivot is `pivot` (link frame, m) moving `pivot_rms` (m).
///
/// `unbounded`: the best fit's mass (kg) and distance from the pivot (m) when that mass ran to the
/// vocabulary's bound; `place` and `mass` are then an equivalent placement within the interval.
///
/// `crank`: the crank radius (m) of a body that translates: every point of it circles on it, so
/// the first moment is the mass times it, wherever on the link the weight sits.
#[allow(clippy::too_many_arguments)]
pub fn report(place: [f64; 3], mass: f64, pr: &Profile, pivot: [f64; 3], pivot_rms: f64, crank: Option<f64>, equivalent: Vec<Placement>, unbounded: Option<(f64, f64)>) -> PayloadReport {
    let (distance, distance_ci95, moment_ci95) = match crank {
        Some(r) => (r, [r; 2], [pr.mass[0] * r, pr.mass[1] * r]),
        None => ((Vector3::from(place) - Vector3::from(pivot)).norm(), pr.distance, pr.first_moment),
    };
    let moment = mass * distance;
    let half = |r: [f64; 2]| 0.5 * (r[1] - r[0]);
    let mut cannot_fix = Vec::new();
    let unfixed_mass = half(pr.mass) > FIXED_RELATIVE * mass;
    if let Some(r) = crank {
        cannot_fix.push(format!(
            "the place on the link: the body translates (its orientation is fixed while the pitch moves) and every point of it circles on the crank's {r:.4} m: gravity fixes the mass times the crank, {moment:.4} kg m [{:.4}, {:.4}], wherever on the link the weight sits",
            moment_ci95[0], moment_ci95[1]
        ));
    } else if let Some(best) = unbounded {
        cannot_fix.push(format!(
            "the mass: the fit runs to the vocabulary's {:.0} kg at {:.3} m from the pivot (a first moment and almost no inertia: this motion does not excite the payload's inertia, or the model's inertia is off by more); gravity fixes the first moment, {moment:.4} kg m [{:.4}, {:.4}], and any mass of at least {mass:.3} kg placed to give it (here: the lightest within the 95% interval)",
            best.0, best.1, pr.first_moment[0], pr.first_moment[1]
        ));
    } else if unfixed_mass && half(pr.first_moment) < FIXED_RELATIVE * moment && pivot_rms < 0.01 {
        cannot_fix.push(format!(
            "the mass and its distance from the pivot trade (the body turns about a point that moves {:.1} mm RMS): gravity fixes their product, the first moment, {moment:.4} kg m [{:.4}, {:.4}]; the mass alone rests on the payload's inertia, which this motion excites too little: {mass:.3} kg [{:.3}, {:.3}] at {distance:.3} m [{:.3}, {:.3}]",
            1e3 * pivot_rms, pr.first_moment[0], pr.first_moment[1], pr.mass[0], pr.mass[1], pr.distance[0], pr.distance[1]
        ));
    } else if unfixed_mass {
        cannot_fix.push(format!("mass: {mass:.3} kg [{:.3}, {:.3}]", pr.mass[0], pr.mass[1]));
    }
    for (k, axis) in ["x", "y", "z"].iter().enumerate().filter(|_| crank.is_none()) {
        if half(pr.position[k]) > FIXED_POSITION {
            cannot_fix.push(format!("{axis}: {:.3} m [{:.3}, {:.3}]", place[k], pr.position[k][0], pr.position[k][1]));
        }
    }
    PayloadReport {
        mass,
        mass_ci95: pr.mass,
        position: place,
        position_ci95: pr.position,
        pivot,
        pivot_motion_rms: pivot_rms,
        first_moment: moment,
        first_moment_ci95: moment_ci95,
        distance,
        distance_ci95,
        cannot_fix,
        equivalent,
        crank,
        family: None,
        axis_joint: None,
        axis_first_moment: None,
        axis_first_moment_ci95: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A point mass's parameters are dvrk-kin's own: `phi` agrees with
    /// [`dvrk_kin::BodyInertia::with_point_mass`] on an empty body, and `dphi` with `phi`'s
    /// central differences.
    #[test]
    fn a_unit_point_mass_is_the_linear_form_of_a_point_mass() {
        let p = [0.3, -0.2, 0.45];
        let empty = dvrk_kin::BodyInertia { mass: 0.0, com: Vector3::zeros(), inertia: nalgebra::Matrix3::zeros() };
        let reference = empty.with_point_mass(1.0, &Vector3::from(p)).parameters();
        for (a, b) in phi(&p).iter().zip(reference.iter()) {
            assert!((a - b).abs() < 1e-12, "{:?} vs {reference:?}", phi(&p));
        }
        for k in 0..3 {
            let h = 1e-6;
            let (mut lo, mut hi) = (p, p);
            lo[k] -= h;
            hi[k] += h;
            for ((d, a), b) in dphi(&p, k).iter().zip(phi(&hi)).zip(phi(&lo)) {
                assert!((d - (a - b) / (2.0 * h)).abs() < 1e-8, "axis {k}");
            }
        }
    }

    /// On normal equations made by a known point mass (any full-rank Gram matrix), the search
    /// finds its place and mass.
    #[test]
    fn the_search_finds_a_known_point_mass() {
        let g = DMatrix::from_fn(10, 10, |i, j| if i == j { 2.0 + i as f64 } else { 0.3 / (1.0 + (i as f64 - j as f64).abs()) });
        let (truth, m) = ([0.123, -0.456, 0.533], 0.205);
        let b = &g * DVector::from_column_slice(&phi(&truth)) * m;
        let (p, mass) = best_place(&g, &b).unwrap();
        assert!((mass - m).abs() < 1e-3 * m, "mass {mass}");
        for k in 0..3 {
            assert!((p[k] - truth[k]).abs() < 1e-3, "{p:?}");
        }
    }
}
