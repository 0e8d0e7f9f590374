//! Whether a fitted parameter holds across the recording: the Particle Data Group's scale factor
//! of its estimates over groups of training samples. Interval widths from the noise alone miss a
//! candidate whose law is not the truth's (a Stribeck hump fitted as Coulomb friction, a play
//! element fitted as a smooth one): the estimate is then biased, and more data only narrows the
//! interval around the wrong value. Such an estimate moves with the motion's regime, so the
//! training samples are grouped four ways: consecutive time blocks (a model error that drifts),
//! and quartiles of the focus joint's |speed|, position and |effort| (a law that differs from the
//! truth's reads differently at low and high speed, load or pose). An effect shared by every
//! joint (a stream's latency) is also estimated joint by joint: each joint's own model error
//! pulls its estimate its own way.

use super::signals::{column, Prepared};
use super::stats::effective_fraction;

/// Groups per partition.
pub const GROUPS: usize = 4;

/// Partitions of the training rows (`per_sample` rows a sample, sample-major), each into groups
/// of row indices: [`GROUPS`] time blocks, then (with a focus joint) [`GROUPS`] quartiles of its
/// |speed|, position and |effort|; with `by_joint`, one group per analysed joint.
pub fn partitions(prep: &Prepared, focus: Option<usize>, by_joint: bool) -> Vec<Vec<Vec<usize>>> {
    let n = prep.split;
    let na = prep.active.len();
    let rows = |samples: Vec<usize>| samples.into_iter().flat_map(|s| s * na..(s + 1) * na).collect::<Vec<usize>>();
    let mut out = vec![(0..GROUPS).map(|b| rows((b * n / GROUPS..(b + 1) * n / GROUPS).collect())).collect::<Vec<_>>()];
    if let Some(k) = focus {
        let abs = |v: Vec<f64>| v.into_iter().map(f64::abs).collect::<Vec<_>>();
        for value in [abs(column(&prep.qd, k)), column(&prep.q, k), abs(column(&prep.effort, k))] {
            out.push(quartiles(&value[..n]).into_iter().map(rows).collect());
        }
    }
    if by_joint {
        out.push((0..na).map(|a| (0..n).map(|s| s * na + a).collect()).collect());
    }
    out
}

/// Indices of `value` in [`GROUPS`] groups of equal count by value, each in time order.
fn quartiles(value: &[f64]) -> Vec<Vec<usize>> {
    let mut order: Vec<usize> = (0..value.len()).collect();
    order.sort_by(|a, b| value[*a].total_cmp(&value[*b]));
    let n = order.len();
    (0..GROUPS)
        .map(|g| {
            let mut group = order[g * n / GROUPS..(g + 1) * n / GROUPS].to_vec();
            group.sort_unstable();
            group
        })
        .collect()
}

/// `max(1, chi2 / (K - 1))` of the groups' `(estimate, variance)` about the whole fit's `x`;
/// groups without a finite positive variance are left out (1 when fewer than two are left).
pub fn scale(groups: &[(f64, f64)], x: f64) -> f64 {
    let used: Vec<f64> = groups.iter().filter(|(e, v)| *v > 0.0 && v.is_finite() && e.is_finite()).map(|(e, v)| (e - x).powi(2) / v).collect();
    if used.len() < 2 {
        return 1.0;
    }
    (used.iter().sum::<f64>() / (used.len() - 1) as f64).max(1.0)
}

/// The minimum of a likelihood-ratio profile `points` (`(x, lr)`, ascending in `x`, lr 0 at the
/// best point of the whole fit but not necessarily at this group's): the parabola through the
/// lowest point and its neighbours, as `(x at its vertex, variance = 1 / curvature)`; `None` at
/// the grid's ends or without curvature.
pub fn parabola_minimum(points: &[(f64, f64)]) -> Option<(f64, f64)> {
    let i = (0..points.len()).min_by(|a, b| points[*a].1.total_cmp(&points[*b].1))?;
    if i == 0 || i + 1 >= points.len() {
        return None;
    }
    let ((x0, l0), (x1, l1), (x2, l2)) = (points[i - 1], points[i], points[i + 1]);
    let a = ((l2 - l1) / (x2 - x1) - (l1 - l0) / (x1 - x0)) / (x2 - x0);
    (a > 0.0).then(|| (0.5 * (x0 + x1) - (l1 - l0) / (2.0 * a * (x1 - x0)), 1.0 / a))
}

/// The variance (1 / curvature) of the parabola fitted by least squares to a profile's points
/// with likelihood ratio up to `within` (`points`: `(x, lr)`); `None` with fewer than four such
/// points or without curvature. Unlike [`parabola_minimum`] it sees the bowl, not the best
/// point's neighbourhood.
pub fn bowl_variance(points: &[(f64, f64)], within: f64) -> Option<f64> {
    let used: Vec<(f64, f64)> = points.iter().copied().filter(|p| p.1 <= within).collect();
    if used.len() < 4 {
        return None;
    }
    // lr = a x^2 + b x + c, centred on the mean x for conditioning.
    let mean = used.iter().map(|p| p.0).sum::<f64>() / used.len() as f64;
    let a = nalgebra::DMatrix::from_fn(used.len(), 3, |i, j| (used[i].0 - mean).powi(2 - j as i32));
    let y = nalgebra::DVector::from_iterator(used.len(), used.iter().map(|p| p.1));
    let coef = a.svd(true, true).solve(&y, 1e-12).ok()?;
    (coef[0] > 0.0).then(|| 1.0 / coef[0])
}

/// The variance of a one-parameter estimate from its score, robust to a residual that is neither
/// white nor independent of the motion (a sandwich with the score's autocorrelation, as in
/// Newey and West): `sum(u)^2`'s expectation `sum u_t^2 / f` over `(d^T d)^2`, where `u_t` is
/// sample t's share of `d^T e` and `f` [`effective_fraction`] of the `u_t`. `d` is the residual's
/// derivative in the parameter and `e` the residual at the estimate (`per_sample` rows a sample,
/// sample-major, both with the nuisance taken out), over `rows` (in time order: all of them, or
/// a group of [`partitions`]). Unlike a profile's curvature, which scales the noise's variance
/// alone, it grows where the residual left at each event (a play's impact) varies with the
/// event. `None` without sensitivity.
pub fn sandwich_variance(d: &[f64], e: &[f64], rows: &[usize], per_sample: usize) -> Option<f64> {
    let info: f64 = rows.iter().map(|&i| d[i] * d[i]).sum();
    if !(info > 0.0) || per_sample == 0 {
        return None;
    }
    // Each sample's share, summed over its rows (consecutive in `rows`).
    let mut u: Vec<f64> = Vec::new();
    let mut last = usize::MAX;
    for &i in rows {
        if i / per_sample != last {
            u.push(0.0);
            last = i / per_sample;
        }
        if let Some(x) = u.last_mut() {
            *x += d[i] * e[i];
        }
    }
    let energy: f64 = u.iter().map(|x| x * x).sum();
    Some(energy / effective_fraction(std::slice::from_ref(&u)) / (info * info))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn agreeing_groups_keep_the_interval_and_disagreeing_ones_widen_it() {
        // Four estimates one standard deviation apart around 0: chi2 = 1 + 1 + 1 + 1 = 4, / 3.
        assert_eq!(scale(&[(1.0, 1.0), (-1.0, 1.0), (0.5, 0.25), (-0.5, 0.25)], 0.0), 4.0 / 3.0);
        assert_eq!(scale(&[(0.1, 1.0), (-0.1, 1.0)], 0.0), 1.0);
        assert_eq!(scale(&[(3.0, 1.0), (f64::NAN, 1.0), (1.0, 0.0)], 0.0), 1.0);
    }

    #[test]
    fn a_parabola_profile_gives_its_vertex_and_curvature() {
        // lr = 4 (x - 0.3)^2 sampled at 0, 0.25, 0.5, 0.75.
        let pts: Vec<(f64, f64)> = [0.0, 0.25, 0.5, 0.75].iter().map(|&x| (x, 4.0 * (x - 0.3f64).powi(2))).collect();
        let (xm, var) = parabola_minimum(&pts).unwrap();
        assert!((xm - 0.3).abs() < 1e-12 && (var - 0.25).abs() < 1e-12, "{xm} {var}");
        assert!(parabola_minimum(&pts[1..3]).is_none());
    }

    #[test]
    fn a_jagged_profile_gets_its_bowl_width() {
        // lr = (x / 0.5)^2 plus a wiggle that makes the best point's neighbours steep.
        let pts: Vec<(f64, f64)> = (-20..=20).map(|i| i as f64 * 0.1).map(|x| (x, 4.0 * x * x + if x.abs() < 1e-9 { 0.0 } else { 3.0 })).collect();
        let local = parabola_minimum(&pts).unwrap().1;
        let bowl = bowl_variance(&pts, 30.0).unwrap();
        assert!((bowl - 0.25).abs() < 0.02 && local < 0.01, "{bowl} {local}");
        assert!(bowl_variance(&pts[..3], 30.0).is_none());
    }

    #[test]
    fn the_sandwich_is_the_least_squares_variance_for_white_noise_and_wider_for_events() {
        // d = 1 everywhere, e white with unit variance: var = n / n^2 = 1 / n (to sampling error).
        let n = 4000;
        let mut state = 12345u64;
        let mut unit = || {
            // Two uniforms summed, centred and scaled: variance 1.
            let mut u = || {
                state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                (state >> 11) as f64 / (1u64 << 53) as f64
            };
            (u() + u() - 1.0) * 6f64.sqrt()
        };
        let e: Vec<f64> = (0..n).map(|_| unit()).collect();
        let d = vec![1.0; n];
        let all: Vec<usize> = (0..n).collect();
        let white = sandwich_variance(&d, &e, &all, 1).unwrap() * n as f64;
        assert!((white - 1.0).abs() < 0.1, "{white}");
        // The same residual held over events 20 samples long: 20 times the variance.
        let held: Vec<f64> = (0..n).map(|i| e[i / 20 * 20]).collect();
        let events = sandwich_variance(&d, &held, &all, 1).unwrap() * n as f64;
        assert!(events > 10.0 && events < 30.0, "{events}");
        // Two rows a sample: the same as their sums' one row a sample, here 2 d e each.
        let two: Vec<f64> = e.iter().flat_map(|x| [*x, *x]).collect();
        let rows: Vec<usize> = (0..2 * n).collect();
        let paired = sandwich_variance(&vec![1.0; 2 * n], &two, &rows, 2).unwrap() * n as f64;
        assert!((paired - white).abs() < 1e-9 * white, "{paired} {white}");
        assert!(sandwich_variance(&[0.0; 4], &[1.0; 4], &[0, 1, 2, 3], 2).is_none());
    }

    #[test]
    fn quartiles_split_by_value_and_keep_time_order() {
        let g = quartiles(&[5.0, 1.0, 7.0, 3.0, 2.0, 8.0, 6.0, 4.0]);
        assert_eq!(g, vec![vec![1, 4], vec![3, 7], vec![0, 6], vec![2, 5]]);
    }
}
