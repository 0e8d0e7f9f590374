//! Scoring a candidate on the torque channel: its fit with the inertia nuisance, the change in
//! BIC and a nested-model likelihood-ratio test on an effective sample size (the residuals'
//! autocorrelation), a block-bootstrap p-value where a bound is active, the profile of a
//! one-parameter effect (latency, a drive's compliance or play), and the choice between pairs.

use super::candidates::{self, Candidate, Table};
use super::options::Options;
use super::consistency;
use super::fit::{per_joint_ratio, Fitter, Rows};
use super::signals::{add, rms, sub, Prepared};
use super::signature::{Series, Signature};
use super::stats::{chi2_sf, effective_fraction};
use crate::error::{CalibError, Result};
use dvrk_kin::effects::{EffectKind, EffectSpec};
use nalgebra::{DMatrix, DVector};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use std::collections::BTreeMap;

/// Scores of one candidate.
#[derive(Debug, Clone)]
pub(super) struct Score {
    pub(super) x: Vec<f64>,
    pub(super) ci: Vec<[f64; 2]>,
    pub(super) delta_bic: f64,
    /// The likelihood ratio behind `delta_bic`.
    pub(super) stat: f64,
    pub(super) p_value: f64,
    /// The held-out test on the last part of the recording the fit never saw.
    pub(super) heldout_p: f64,
    /// A linear candidate's held-out test over the whole recording, each of
    /// [`super::nuisance::FOLDS`] parts predicted from the others: of an effect the inertias
    /// mostly mimic (an encoder offset on the pitch rotates its gravity torque as a first-moment
    /// change would) the last part alone can hold too little. `None` for a profile.
    pub(super) cv_p: Option<f64>,
    pub(super) effect_to_noise: f64,
    /// A profile's best grid point, where its signature is taken ([`Scored::efforts`]); `None`
    /// for a linear candidate.
    pub(super) signature_at: Option<f64>,
    /// The squared (scaled) residual one unit of chi-square is for a linear candidate's fit
    /// (its variance over the effective fraction); 0 for a profile.
    pub(super) chi2_unit: f64,
    /// The profiled parameter's value, for a candidate that has one.
    pub(super) profiled: Option<f64>,
    /// A profile whose best point is the grid's end, or a fit with a parameter held at a limit
    /// of its physical range other than the effect's absence (a coupling entry a fifth off): the
    /// value is not determined (the effect stands in for something outside its physical
    /// range), so it is never named.
    pub(super) at_edge: bool,
    /// How much of a linear candidate's signature (its first parameter's column, in the fit's
    /// metric) the inertia nuisance can take up within its prior, as a correlation: 1 - the
    /// share it leaves, square-rooted. Near 1 the recording cannot tell the effect from an
    /// inertia error. `None` for a profile or without a nuisance.
    pub(super) nuisance_correlation: Option<f64>,
}

impl Score {
    /// The held-out confirmation: the last part's test or the cross-validated one.
    pub(super) fn confirmed_p(&self) -> f64 {
        self.cv_p.map_or(self.heldout_p, |c| c.min(self.heldout_p))
    }
}

/// A scored candidate: a linear one (`candidate`) or a profile (latency, a drive's compliance or
/// play on `joint`).
pub(super) struct Scored<'a> {
    pub(super) candidate: Option<&'a Candidate>,
    pub(super) kind: EffectKind,
    pub(super) label: String,
    pub(super) score: Score,
    pub(super) joint: Option<usize>,
    /// A kinematic-channel-only candidate: its effect and intervals as that channel gives them.
    pub(super) kinematic: Option<(EffectSpec, BTreeMap<String, [f64; 2]>)>,
    /// Where its fitted effort comes from ([`Scored::efforts`]).
    pub(super) effort: Effort<'a>,
}

/// Where a scored effect's fitted effort comes from. Only the few a report shows need it: holding
/// every candidate's (two tables each, with and without the nuisance's share) took 220 MB on a
/// 5-minute recording, so it is rebuilt from the fit instead, with the same arithmetic.
pub(super) enum Effort<'a> {
    /// A linear candidate's: its columns (at its profiled value) times its fit.
    Linear,
    /// A profile's: its signature at the best grid point ([`Score::signature_at`]).
    Profile(Box<dyn Fn(f64) -> Result<Table> + 'a>),
    /// Taken when scored (latency, whose fit had a nuisance of its own: with it, and without).
    Held(Table, Table),
    /// None: a kinematic-channel-only candidate changes no predicted effort.
    Zero,
}

impl Scored<'_> {
    /// The fitted effect's effort `[sample][joint]` over the whole analysed span with the inertia
    /// nuisance refitted with it (`fit`, residual `r`), and without it (its own signature).
    pub(super) fn efforts(&self, fit: &Fitter, r: &Table) -> Result<(Table, Table)> {
        let prep = fit.prep;
        match (&self.effort, self.candidate, self.score.signature_at) {
            (Effort::Linear, Some(c), _) => {
                let columns = fitted_columns(c, self.score.profiled);
                // A candidate the report was not to show has let its columns go.
                if columns.len() != self.score.x.len() {
                    return Err(CalibError::data("discrepancy", format!("{}: its signature was let go once scored", self.label)));
                }
                let train = Rows::train(prep);
                let x = DVector::from_column_slice(&self.score.x);
                let e1 = train.vector(r) - train.matrix(columns) * &x;
                let own: Table = (0..prep.t.len()).map(|i| (0..r[0].len()).map(|k| columns.iter().zip(x.iter()).map(|(col, v)| col.at(i, k) * v).sum()).collect()).collect();
                let mut effect = own.clone();
                add(&mut effect, &fit.nuisance_effort(&e1));
                Ok((effect, own))
            }
            (Effort::Profile(make), _, Some(value)) => Ok(profile_efforts(fit, r, &make(value)?)),
            (Effort::Held(effect, own), _, _) => Ok((effect.clone(), own.clone())),
            _ => {
                let zero = vec![vec![0.0; r.first().map_or(0, Vec::len)]; prep.t.len()];
                Ok((zero.clone(), zero))
            }
        }
    }
}

/// A linear candidate's columns at its profiled value (`None`: its own).
pub(super) fn fitted_columns(c: &Candidate, profiled: Option<f64>) -> &[Signature] {
    match (&c.profile, profiled) {
        (Some((_, grid)), Some(v)) => grid.iter().find(|g| g.0 == v).map_or(&c.columns[..], |g| &g.1[..]),
        _ => &c.columns,
    }
}

/// A profile's fitted effort with the nuisance refitted to what its signature `sig` leaves of
/// residual `r`, and `sig` itself.
pub(super) fn profile_efforts(fit: &Fitter, r: &Table, sig: &Table) -> (Table, Table) {
    let own = sig.clone();
    let mut effect = sig.clone();
    add(&mut effect, &fit.nuisance_effort(&Rows::train(fit.prep).vector(&sub(r, sig))));
    (effect, own)
}

pub(super) fn lr(n_eff: f64, rss0: f64, rss1: f64) -> f64 {
    (n_eff * (rss0 / rss1.max(1e-300)).ln()).max(0.0)
}

/// Bootstrap resamples whitened together (16 columns of a recording's rows: a few MB).
const BOOTSTRAP_BATCH: usize = 16;

/// Fit and score a linear candidate (the inertia nuisance refitted with it).
pub(super) fn score_linear(c: &Candidate, fit: &Fitter, r: &Table, o: &Options, rng: &mut ChaCha8Rng) -> Result<Score> {
    let prep = fit.prep;
    let (train, hold) = (Rows::train(prep), Rows::held_out(prep));
    let y = train.vector(r);
    let bounds = c.bounds();
    // A profiled parameter: the grid value whose fit leaves the least.
    let (profiled, columns) = match &c.profile {
        None => (None, &c.columns),
        Some((_, grid)) => {
            let mut best = (f64::INFINITY, None, &c.columns);
            for (v, cols) in grid {
                let a = train.matrix(cols);
                let x = fit.solve(&a, &y, &bounds)?;
                let rss = fit.rss(&(&y - &a * &x));
                if rss < best.0 {
                    best = (rss, Some(*v), cols);
                }
            }
            (best.1, best.2)
        }
    };
    let p = columns.len();
    let a = train.matrix(columns);
    let x = fit.solve(&a, &y, &bounds)?;
    let e1 = &y - &a * &x;
    let rss1 = fit.rss(&e1);
    let n = train.len() as f64;
    let white = fit.whitened(&e1);
    let frac = effective_fraction(&train.series(&white));
    let (stat, n_eff) = per_joint_ratio(&train, &fit.whitened(&y), &white);
    let delta_bic = stat - (p + profiled.is_some() as usize) as f64 * n_eff.ln();
    // A payload's mass at its upper bound (unfixed, see `at_edge` below) is far from the
    // effect's absence: the regular test holds there.
    let unfixed_mass = |i: usize, b: &super::stats::Bounds, v: f64| c.kind == EffectKind::PayloadMass && i == 0 && b.held_at(v).is_some_and(|b| b != 0.0);
    let on_bound = bounds.iter().zip(x.iter()).enumerate().any(|(i, (b, v))| b.active(*v) && !unfixed_mass(i, b, *v));
    let (g, _) = fit.normal_equations(&a, &y);
    let aw = fit.whitened_columns(&a);
    let p_value = if on_bound && o.bootstrap > 0 {
        // Block bootstrap under the null: the fitted model's residual resampled in blocks as
        // long as its correlation, refitted.
        let block = (1.0 / frac).ceil().max(1.0) as usize;
        let na = prep.active.len();
        let steps = train.range.len();
        let mut exceed = 0;
        // Resamples whitened a batch at a time: one pass over the nuisance's rows for the batch.
        let mut done = 0;
        while done < o.bootstrap {
            let batch = BOOTSTRAP_BATCH.min(o.bootstrap - done);
            let mut ys = DMatrix::zeros(y.len(), batch);
            for mut col in ys.column_iter_mut() {
                let mut i = 0;
                while i < steps {
                    let s = rng.random_range(0..steps.saturating_sub(block).max(1));
                    for d in 0..block.min(steps - i) {
                        for k in 0..na {
                            col[(i + d) * na + k] = white[(s + d) * na + k];
                        }
                    }
                    i += block;
                }
            }
            let wys = fit.whitened_columns(&ys);
            for (ys, wys) in ys.column_iter().zip(wys.column_iter()) {
                let (ys, wys) = (ys.into_owned(), wys.into_owned());
                // `W` is linear: the refit's whitened residual is `W ys - (W a) xs`.
                let xs = fit.solve_given(&g, &a, &ys, &wys, &bounds)?;
                if per_joint_ratio(&train, &wys, &(&wys - &aw * &xs)).0 >= stat {
                    exceed += 1;
                }
            }
            done += batch;
        }
        (1 + exceed) as f64 / (o.bootstrap + 1) as f64
    } else {
        chi2_sf(stat, p)
    };
    // Intervals: the least-squares covariance, inflated for the autocorrelation.
    let s2 = rss1 / (n - p as f64).max(1.0);
    let cov = g.try_inverse().unwrap_or_else(|| DMatrix::from_element(p, p, f64::INFINITY)) * (s2 / frac);
    // A model error that changes along the recording, or a law that is not the truth's, moves
    // the estimate between parts of the motion more than the noise would: widen by that.
    let mut cov = cov * block_scale(&train, &a, &(&white + &a * &x), &x, &bounds, frac, c.focus)?;
    // Not narrower than the score's scatter ([`consistency::sandwich_variance`]), each parameter
    // through its column less the others' share of it.
    for i in 0..p {
        let own = aw.column(i).into_owned();
        let others = aw.clone().remove_column(i);
        let partial = match (p > 1).then(|| others.clone().svd(true, true).solve(&own, 1e-12).ok()).flatten() {
            Some(beta) => &own - &others * beta,
            None => own,
        };
        if let Some(v) = consistency::sandwich_variance(partial.as_slice(), white.as_slice(), &(0..train.len()).collect::<Vec<_>>(), prep.active.len()) {
            cov[(i, i)] = cov[(i, i)].max(v);
        }
    }
    let ci = (0..p).map(|i| {
        let h = 1.96 * cov[(i, i)].max(0.0).sqrt();
        [x[i] - h, x[i] + h]
    });
    let ci: Vec<[f64; 2]> = ci.collect();
    let ah = hold.matrix(columns);
    let yh = hold.vector(r);
    let eh0 = fit.held_out(&y, &yh);
    let eh1 = fit.held_out(&e1, &(&yh - &ah * &x));
    let heldout_p = chi2_sf(per_joint_ratio(&hold, &eh0, &eh1).0, p);
    let cv_p = Some(chi2_sf(fit.cross_validated(r, columns, &bounds)?.0, p));
    // The effect's own effort on its focus joint over the training rows.
    let at_focus = |i: usize| -> f64 { columns.iter().zip(x.iter()).map(|(col, v)| col.at(i, c.focus) * v).sum() };
    let size = ((0..prep.split).map(|i| at_focus(i).powi(2)).sum::<f64>() / prep.split as f64).sqrt() / prep.noise[c.focus];
    // Held at zero change is the effect's absence (friction's lower bound): the bootstrap's case.
    // A payload's mass at its upper bound is not an implausible fit but an unfixed one: the mass
    // trades with its distance from the axis, gravity fixing their product (reported with an
    // equivalent placement, [`super::payload::report`]).
    let at_edge = bounds.iter().zip(x.iter()).enumerate().any(|(i, (b, v))| b.held_at(*v).is_some_and(|b| b != 0.0) && !unfixed_mass(i, b, *v))
        || (c.kind == EffectKind::PayloadMass && !candidates::payload_is_a_point_mass(&c.at, x.as_slice()));
    let nuisance_correlation = fit.nuisance.and_then(|_| {
        let c0 = a.column(0).into_owned();
        let n2 = c0.norm_squared();
        (n2 > 0.0).then(|| (1.0 - fit.rss(&c0) / n2).clamp(0.0, 1.0).sqrt())
    });
    Ok(Score {
        x: x.iter().copied().collect(),
        ci,
        delta_bic,
        stat,
        p_value,
        heldout_p,
        cv_p,
        effect_to_noise: size,
        signature_at: None,
        chi2_unit: chi2_unit(&train, &a, &white),
        profiled,
        at_edge,
        nuisance_correlation,
    })
}

/// The squared residual (scaled units) one unit of chi-square is for a fit of columns `a`: each
/// joint's residual variance over its effective fraction, weighed by the columns' energy on
/// that joint. A pooled variance would be the wrist's on the WPI arm (180 times its floor, a
/// residual no effect expresses) and would widen a payload on the arm by that.
pub(super) fn chi2_unit(train: &Rows, a: &DMatrix<f64>, white: &DVector<f64>) -> f64 {
    let series = train.series(white);
    let na = series.len();
    let energy: Vec<f64> = (0..na).map(|k| a.row_iter().skip(k).step_by(na).map(|r| r.norm_squared()).sum()).collect();
    let total: f64 = energy.iter().sum();
    if !(total > 0.0) {
        return 0.0;
    }
    series
        .iter()
        .zip(&energy)
        .map(|(e, w)| {
            let var = e.iter().map(|x| x * x).sum::<f64>() / e.len().max(1) as f64;
            w / total * var / super::stats::effective_fraction(std::slice::from_ref(e)).max(1e-6)
        })
        .sum()
}

/// The Particle Data Group's scale factor of a linear candidate's first parameter over the
/// groups of [`consistency::partitions`] (the largest over the partitions): each group of
/// training rows fitted alone (`y`: the rows with the nuisance's fit taken out), each estimate
/// with its own noise variance (inflated by `1 / frac` for correlation), against the whole fit `x`.
pub(super) fn block_scale(train: &Rows, a: &DMatrix<f64>, y: &DVector<f64>, x: &DVector<f64>, bounds: &[super::stats::Bounds], frac: f64, focus: usize) -> Result<f64> {
    let p = a.ncols();
    let mut worst: f64 = 1.0;
    for partition in consistency::partitions(train.prep, Some(focus), false) {
        let mut estimates = Vec::with_capacity(partition.len());
        for rows in &partition {
            let (ab, yb) = (a.select_rows(rows), y.select_rows(rows));
            let xb = super::stats::bounded_least_squares(&ab, &yb, bounds)?;
            let rss = (&yb - &ab * &xb).norm_squared();
            let Some(inv) = ab.tr_mul(&ab).try_inverse() else { continue };
            estimates.push((xb[0], inv[(0, 0)] * rss / (rows.len() as f64 - p as f64).max(1.0) / frac));
        }
        worst = worst.max(consistency::scale(&estimates, x[0]));
    }
    Ok(worst)
}

/// A one-parameter effect scanned on a grid (ascending), refined between the best point's
/// neighbours: `make(value)` is the effect's change of the predicted effort. The null is the
/// model without it; the interval is where the profile's likelihood ratio stays under 3.84.
pub(super) fn score_profile(fit: &Fitter, r: &Table, grid: &[f64], make: &dyn Fn(f64) -> Table, focus: Option<usize>) -> Score {
    let prep = fit.prep;
    let (train, hold) = (Rows::train(prep), Rows::held_out(prep));
    // The groups the estimate's consistency is checked on (latency: on the joint it shows most).
    let focus_or_worst =
        focus.or_else(|| prep.active.iter().copied().max_by(|a, b| (rms(r, *a, 0..prep.split) / prep.floor[*a]).total_cmp(&(rms(r, *b, 0..prep.split) / prep.floor[*b]))));
    let partitions = consistency::partitions(prep, focus_or_worst, focus.is_none());
    // rss of the training rows, then of each group's rows (the nuisance fitted on all of them).
    let eval = |v: f64| -> (f64, Vec<f64>) {
        let e = train.vector(&sub(r, &make(v)));
        let w = fit.whitened(&e);
        let groups = partitions.iter().flatten().map(|g| g.iter().map(|&i| w[i] * w[i]).sum()).collect();
        (fit.rss(&e), groups)
    };
    let mut points: Vec<(f64, f64, Vec<f64>)> = grid
        .iter()
        .map(|&v| {
            let (rss, groups) = eval(v);
            (v, rss, groups)
        })
        .collect();
    let geometric = grid[0] > 0.0;
    // The best point's neighbourhood filled in, each time 4 times finer: twice, then until its
    // neighbours are close enough in likelihood (ratio 15, with the noise's effective sample size)
    // for the parabola through them to give the interval, at most 6 times.
    let n_eff_noise = train.len() as f64 * prep.noise_fraction;
    for pass in 0..6 {
        points.sort_by(|a, b| a.0.total_cmp(&b.0));
        let best = (0..points.len()).min_by(|a, b| points[*a].1.total_cmp(&points[*b].1)).unwrap_or(0);
        let (lo, hi) = (points[best.saturating_sub(1)].0, points[(best + 1).min(points.len() - 1)].0);
        let apart = |i: usize| lr(n_eff_noise, points[i].1, points[best].1);
        if pass >= 2 && apart(best.saturating_sub(1)) < 15.0 && apart((best + 1).min(points.len() - 1)) < 15.0 {
            break;
        }
        for i in 1..8 {
            let w = i as f64 / 8.0;
            let v = if geometric { lo * (hi / lo).powf(w) } else { lo + (hi - lo) * w };
            // The ends of a refinement land on existing points up to rounding.
            if !points.iter().any(|p| (p.0 - v).abs() <= 1e-9 * v.abs().max(1e-12)) {
                let (rss, groups) = eval(v);
                points.push((v, rss, groups));
            }
        }
    }
    points.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (value, rss1) = points.iter().map(|p| (p.0, p.1)).min_by(|a, b| a.1.total_cmp(&b.1)).unwrap_or((grid[0], f64::INFINITY));
    let sig = make(value);
    let rr = sub(r, &sig);
    let (y, e1, h0, h1) = (train.vector(r), train.vector(&rr), hold.vector(r), hold.vector(&rr));
    let white = fit.whitened(&e1);
    let n_eff_pooled = train.len() as f64 * effective_fraction(&train.series(&white));
    let (stat, n_eff) = per_joint_ratio(&train, &fit.whitened(&y), &white);
    let inside: Vec<f64> = points.iter().filter(|p| lr(n_eff_pooled, p.1, rss1) <= 3.841).map(|p| p.0).collect();
    let mut ci = [inside.first().copied().unwrap_or(value), inside.last().copied().unwrap_or(value)];
    // Between grid points: the profile's parabola through the best point and its neighbours (in
    // ln v on a geometric grid) where the likelihood ratio reaches 3.84.
    let x = |v: f64| if geometric { v.ln() } else { v };
    let back = |x: f64| if geometric { x.exp() } else { x };
    let profile: Vec<(f64, f64)> = points.iter().map(|p| (x(p.0), lr(n_eff_pooled, p.1, rss1))).collect();
    // The interval's centre: the parabola's vertex between grid points, else the best point.
    let mut centre = x(value);
    // The residual's derivative in x at the vertex (whitened) and the score's variance
    // ([`consistency::sandwich_variance`]): a residual each event (a play's impact) leaves its
    // own way says more about the estimate's error than the noise's variance does.
    let mut sandwich: Option<(DVector<f64>, f64)> = None;
    let (all, na): (Vec<usize>, usize) = ((0..train.len()).collect(), prep.active.len());
    if let Some((xm, var)) = consistency::parabola_minimum(&profile) {
        // Not narrower than the profile's bowl: a play's profile is jagged (each impact's timing
        // jumps with b), and its best point's neighbours gave the wiggle's curvature.
        let var = consistency::bowl_variance(&profile, BOWL_LR).map_or(var, |b| b.max(var));
        let half = (3.841 * var).sqrt();
        ci = [ci[0].min(back(xm - half)), ci[1].max(back(xm + half))];
        centre = xm;
        let h = if geometric { var.sqrt().max(SANDWICH_STEP) } else { var.sqrt() };
        let slope = fit.whitened(&(train.vector(&sub(&make(back(xm + h)), &make(back(xm - h)))) / (2.0 * h)));
        sandwich = consistency::sandwich_variance(slope.as_slice(), white.as_slice(), &all, na).map(|v| (slope, v));
    }
    // Widened by the estimate's disagreement between the groups of the training samples.
    let frac = n_eff_pooled / train.len() as f64;
    // Each group's profile minimum, in the order `eval` summed the groups.
    let minima: Vec<Option<(f64, f64)>> = partitions
        .iter()
        .flatten()
        .enumerate()
        .map(|(g, group)| {
            let least = points.iter().map(|p| p.2[g]).fold(f64::INFINITY, f64::min);
            let n_eff = group.len() as f64 * frac;
            consistency::parabola_minimum(&points.iter().map(|p| (x(p.0), lr(n_eff, p.2[g], least))).collect::<Vec<_>>())
        })
        .collect();
    // The groups' scale against the profile's variances, and against the sandwich's (each group's
    // own): each widens the interval it scales, and the wider of the two is kept.
    let (mut widen, mut widen_sandwich): (f64, f64) = (1.0, 1.0);
    let mut rest = &minima[..];
    for partition in &partitions {
        let (these, next) = rest.split_at(partition.len());
        widen = widen.max(consistency::scale(&these.iter().flatten().copied().collect::<Vec<_>>(), centre));
        if let Some((slope, _)) = &sandwich {
            let groups: Vec<(f64, f64)> =
                these.iter().zip(partition).filter_map(|(m, rows)| Some((m.as_ref()?.0, consistency::sandwich_variance(slope.as_slice(), white.as_slice(), rows, na)?))).collect();
            widen_sandwich = widen_sandwich.max(consistency::scale(&groups, centre));
        }
        rest = next;
    }
    let stretch = |end: f64| back(centre + (x(end) - centre) * widen.sqrt());
    let scatter = sandwich.as_ref().map_or(0.0, |(_, v)| (3.841 * v * widen_sandwich).sqrt());
    // Not below the grid's start: a physical bound (no negative latency, stiffness or play).
    let ci = [stretch(ci[0]).min(back(centre - scatter)).max(grid[0]), stretch(ci[1]).max(back(centre + scatter))];
    let (eh0, eh1) = (fit.held_out(&y, &h0), fit.held_out(&e1, &h1));
    let size_at = |k: usize| (sig[..prep.split].iter().map(|e| e[k] * e[k]).sum::<f64>() / prep.split as f64).sqrt() / prep.noise[k];
    let size = match focus {
        Some(k) => size_at(k),
        None => prep.active.iter().map(|&k| size_at(k)).fold(0.0, f64::max),
    };
    let p_value = if stat > 0.0 { chi2_sf(stat, 1) } else { 1.0 };
    Score {
        // The vertex, not the best grid point: the grid's last refinement is still 1/64 of its
        // step (latency: 16 us, comparable to its interval).
        x: vec![back(centre)],
        ci: vec![ci],
        delta_bic: stat - n_eff.ln(),
        stat,
        p_value,
        heldout_p: chi2_sf(per_joint_ratio(&hold, &eh0, &eh1).0, 1),
        cv_p: None,
        effect_to_noise: size,
        signature_at: Some(value),
        chi2_unit: 0.0,
        profiled: None,
        at_edge: value <= grid[0] || value >= grid[grid.len() - 1],
        nuisance_correlation: None,
    }
}

/// Least half-step (in ln of the value) of a geometric profile's derivative for its sandwich
/// variance: a play's profile is jagged below it (each impact's timing jumps with b).
pub(super) const SANDWICH_STEP: f64 = 0.005;

/// Likelihood ratio (to the best point) up to which a profile's points give its bowl's width.
pub(super) const BOWL_LR: f64 = 30.0;

/// Supported linear candidates [`pair_choice`] fits two at a time.
pub(super) const PAIR_POOL: usize = 6;

/// Pairs of effects (step 2): the supported linear candidates fitted two at a time. When the
/// best pair beats the best single candidate by strong evidence, two effects are present, and the
/// round names the pair's stronger member: greedily, a candidate that clears some joints of a
/// second effect's residual (a payload on the insertion link standing in for one on the tool,
/// next to friction on the wrist) outscores one that clears most of its own joint and leaves the
/// other effect's share there. `None`: keep the best single candidate.
pub(super) fn pair_choice(scored: &[Scored], winners: &[usize], fit: &Fitter, r: &Table, o: &Options) -> Result<Option<usize>> {
    let train = Rows::train(fit.prep);
    // Each candidate's training rows (at its profiled value), built once for all its pairs.
    // Not a coupling error: its signature mixes its joints' inertia, damping and gravity, so
    // beside another effect it takes up part of that one's (seed 11, viscous friction on the
    // wrist pitch with a payload on the jaw's link: the payload named on the roll link beside
    // d55). A coupling error is named on its own.
    let pool: Vec<(usize, &Candidate, DMatrix<f64>)> = winners
        .iter()
        .filter_map(|&i| {
            let c = scored[i].candidate.filter(|c| c.kind != EffectKind::CouplingError)?;
            Some((i, c, train.matrix(fitted_columns(c, scored[i].score.profiled))))
        })
        .take(PAIR_POOL)
        .collect();
    let Some(&first) = winners.first() else { return Ok(None) };
    let y = train.vector(r);
    let y_white = fit.whitened(&y);
    let mut best: Option<(f64, usize, usize)> = None;
    for (a, (i, ci, mi)) in pool.iter().enumerate() {
        for (j, cj, mj) in &pool[a + 1..] {
            // Two candidates of one kind on one joint or link are one effect.
            if ci.kind == cj.kind && ci.joint == cj.joint && ci.link == cj.link && ci.actuator == cj.actuator {
                continue;
            }
            let m = DMatrix::from_columns(&mi.column_iter().chain(mj.column_iter()).collect::<Vec<_>>());
            let bounds: Vec<_> = ci.bounds().into_iter().chain(cj.bounds()).collect();
            let x = fit.solve(&m, &y, &bounds)?;
            let (stat, n_eff) = per_joint_ratio(&train, &y_white, &fit.whitened(&(&y - &m * &x)));
            let dbic = stat - m.ncols() as f64 * n_eff.ln();
            if best.is_none_or(|b| dbic > b.0) {
                best = Some((dbic, *i, *j));
            }
        }
    }
    Ok(best.and_then(|(dbic, i, j)| {
        let stronger = if scored[i].score.delta_bic >= scored[j].score.delta_bic { i } else { j };
        (dbic > scored[first].score.delta_bic + o.min_delta_bic && stronger != first).then_some(stronger)
    }))
}

/// Two effects whose efforts are this little alike (|cosine| over the fitted rows, each joint
/// over its noise floor) explain different things, and are not rivals.
pub(super) const RIVAL_OVERLAP: f64 = 0.2;

/// |cosine| of two efforts over the training rows (floor-scaled); 1 when either is zero (a
/// kinematic-only candidate, which changes no effort).
pub(super) fn overlap(prep: &Prepared, a: &Table, b: &Table) -> f64 {
    let rows = Rows::train(prep);
    let (x, y) = (rows.vector(a), rows.vector(b));
    let (nx, ny) = (x.norm(), y.norm());
    if nx == 0.0 || ny == 0.0 {
        1.0
    } else {
        (x.dot(&y) / (nx * ny)).abs()
    }
}

/// `n` points from `lo` to `hi`, geometric.
pub(super) fn geometric(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    (0..n).map(|i| lo * (hi / lo).powf(i as f64 / (n - 1) as f64)).collect()
}
