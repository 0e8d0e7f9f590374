//! The statistics of the workflow: a least-squares fit with bounds (clarabel), the
//! effective sample size of autocorrelated residuals, and the chi-square tail.

use crate::error::{CalibError, Result};
use clarabel::algebra::CscMatrix;
use clarabel::solver::{DefaultSettingsBuilder, DefaultSolver, IPSolver, NonnegativeConeT, SolverStatus};
use nalgebra::{DMatrix, DVector};

/// A parameter's physical bounds (`None`: free on that side), in the parameter's own unit.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Bounds {
    pub lower: Option<f64>,
    pub upper: Option<f64>,
}

impl Bounds {
    /// No bound.
    pub const FREE: Bounds = Bounds { lower: None, upper: None };

    /// `x >= lower`.
    pub fn at_least(lower: f64) -> Bounds {
        Bounds { lower: Some(lower), upper: None }
    }

    /// `lower <= x <= upper`.
    pub fn within(lower: f64, upper: f64) -> Bounds {
        Bounds { lower: Some(lower), upper: Some(upper) }
    }

    /// Whether `x` satisfies both bounds.
    pub fn holds(&self, x: f64) -> bool {
        self.lower.is_none_or(|lo| x >= lo) && self.upper.is_none_or(|hi| x <= hi)
    }

    /// `x` moved inside the bounds (a solver's round-off outside them).
    pub fn clamp(&self, x: f64) -> f64 {
        x.max(self.lower.unwrap_or(f64::NEG_INFINITY)).min(self.upper.unwrap_or(f64::INFINITY))
    }

    /// The bound `x` sits on (to round-off), if any.
    pub fn held_at(&self, x: f64) -> Option<f64> {
        let near = |b: f64| (x - b).abs() <= 1e-12 * (1.0 + b.abs());
        self.lower.filter(|&lo| x <= lo || near(lo)).or(self.upper.filter(|&hi| x >= hi || near(hi)))
    }

    /// Whether `x` sits on either bound (to round-off).
    pub fn active(&self, x: f64) -> bool {
        self.held_at(x).is_some()
    }
}

/// `min x^T G x - 2 b^T x` within `bounds`, as the small least squares
/// `|L^T x - L^-1 b|^2` (`G = L L^T`, a trace-relative jitter on its diagonal); `None` when `G`
/// is not positive definite.
pub fn solve_normal_equations(mut g: DMatrix<f64>, b: DVector<f64>, bounds: &[Bounds]) -> Option<Result<DVector<f64>>> {
    let jitter = 1e-12 * g.trace().abs().max(1e-300) / g.nrows().max(1) as f64;
    for d in 0..g.nrows() {
        g[(d, d)] += jitter;
    }
    let l = g.cholesky()?.l();
    let r = l.solve_lower_triangular(&b).unwrap_or(b);
    Some(bounded_least_squares(&l.transpose(), &r, bounds))
}

/// `min |A x - r|^2` subject to `bounds` on each `x_i`. The columns are scaled to unit norm first
/// (clarabel's tolerances are absolute). Only the bounds a fit crosses are given to the solver,
/// side by side, added until none is crossed (a relaxation whose optimum is feasible is the
/// optimum): a far bound (a spring's 1e5 N·m/rad) would otherwise stall the interior point.
/// Returns `x`, inside its bounds.
pub fn bounded_least_squares(a: &DMatrix<f64>, r: &DVector<f64>, bounds: &[Bounds]) -> Result<DVector<f64>> {
    let p = a.ncols();
    let scale: Vec<f64> = (0..p).map(|j| a.column(j).norm().max(1e-300)).collect();
    let mut s = a.clone();
    for (j, sc) in scale.iter().enumerate() {
        s.column_mut(j).scale_mut(1.0 / sc);
    }
    let h = s.transpose() * &s;
    let g = s.transpose() * r;
    let free = h.clone().cholesky().map(|c| c.solve(&g));
    // A singular problem: every bound at once.
    let mut given: Vec<Bounds> = if free.is_some() { vec![Bounds::FREE; p] } else { bounds.to_vec() };
    let mut z = match free {
        Some(z) => z,
        None => scaled_fit(&h, &g, &given, &scale)?,
    };
    loop {
        let mut crossed = false;
        for (j, (b, gv)) in bounds.iter().zip(given.iter_mut()).enumerate() {
            let x = z[j] / scale[j];
            if gv.lower.is_none() && b.lower.is_some_and(|lo| x < lo) {
                (gv.lower, crossed) = (b.lower, true);
            }
            if gv.upper.is_none() && b.upper.is_some_and(|hi| x > hi) {
                (gv.upper, crossed) = (b.upper, true);
            }
        }
        if !crossed {
            let z = polish(&h, &g, z, &given, &scale);
            return Ok(DVector::from_iterator(p, (0..p).map(|j| bounds[j].clamp(z[j] / scale[j]))));
        }
        z = scaled_fit(&h, &g, &given, &scale)?;
    }
}

/// The interior point's `z` (which stops short of an active bound by its tolerance) made exact:
/// the coordinates within 1e-6 of a bound put on it, the others solved for with them held. Kept
/// only if the others stay inside their bounds.
fn polish(h: &DMatrix<f64>, g: &DVector<f64>, z: DVector<f64>, bounds: &[Bounds], scale: &[f64]) -> DVector<f64> {
    let p = z.len();
    let near = |v: f64, b: f64| (v - b).abs() <= 1e-6 * (1.0 + b.abs());
    let held: Vec<Option<f64>> = (0..p).map(|j| [bounds[j].lower, bounds[j].upper].into_iter().flatten().map(|b| b * scale[j]).find(|b| near(z[j], *b))).collect();
    if held.iter().all(Option::is_none) {
        return z;
    }
    let free: Vec<usize> = (0..p).filter(|&j| held[j].is_none()).collect();
    let mut out = DVector::from_iterator(p, held.iter().zip(z.iter()).map(|(b, v)| b.unwrap_or(*v)));
    if !free.is_empty() {
        let hu = DMatrix::from_fn(free.len(), free.len(), |a, b| h[(free[a], free[b])]);
        let gu = DVector::from_iterator(free.len(), free.iter().map(|&i| g[i] - (0..p).filter_map(|k| held[k].map(|b| h[(i, k)] * b)).sum::<f64>()));
        let Some(zu) = hu.cholesky().map(|c| c.solve(&gu)) else { return z };
        for (a, &j) in free.iter().enumerate() {
            out[j] = zu[a];
        }
    }
    if free.iter().all(|&j| bounds[j].holds(out[j] / scale[j])) {
        out
    } else {
        z
    }
}

/// `min z^T H z / 2 - g^T z` with `bounds` on `x = z / scale` (clarabel). Returns `z`.
fn scaled_fit(h: &DMatrix<f64>, g: &DVector<f64>, bounds: &[Bounds], scale: &[f64]) -> Result<DVector<f64>> {
    let p = h.ncols();
    let (mut colptr, mut rowval, mut nzval) = (vec![0], Vec::new(), Vec::new());
    for j in 0..p {
        for i in 0..=j {
            rowval.push(i);
            nzval.push(h[(i, j)]);
        }
        colptr.push(rowval.len());
    }
    let pm = CscMatrix::new(p, p, colptr, rowval, nzval);
    let q: Vec<f64> = g.iter().map(|x| -x).collect();
    // Rows `sign z_j <= sign bound_j scale_j`: -z_j <= -lo, z_j <= hi.
    let rows: Vec<(usize, f64, f64)> =
        bounds.iter().enumerate().flat_map(|(j, b)| [b.lower.map(|lo| (j, -1.0, -lo * scale[j])), b.upper.map(|hi| (j, 1.0, hi * scale[j]))]).flatten().collect();
    let (mut colptr, mut rowval, mut nzval) = (vec![0], Vec::new(), Vec::new());
    for j in 0..p {
        for (i, (jj, sign, _)) in rows.iter().enumerate() {
            if *jj == j {
                rowval.push(i);
                nzval.push(*sign);
            }
        }
        colptr.push(rowval.len());
    }
    let am = CscMatrix::new(rows.len(), p, colptr, rowval, nzval);
    let b: Vec<f64> = rows.iter().map(|(_, _, v)| *v).collect();
    let settings = DefaultSettingsBuilder::default().verbose(false).max_iter(100).build().map_err(|e| CalibError::context("bounded fit settings", e))?;
    let cones = [NonnegativeConeT(rows.len())];
    let mut solver = DefaultSolver::new(&pm, &q, &am, &b, &cones, settings).map_err(|e| CalibError::data("bounded fit", format!("{e:?}")))?;
    solver.solve();
    match solver.solution.status {
        SolverStatus::Solved | SolverStatus::AlmostSolved => {}
        status => return Err(CalibError::data("bounded fit", format!("clarabel stopped: {status:?}"))),
    }
    Ok(DVector::from_column_slice(&solver.solution.x))
}

/// The fraction `n_eff / n` of a residual made of `series` (each one joint's residual in time
/// order): `1 / (1 + 2 sum rho_k)` over the lags until the autocorrelation first drops below
/// 0.05 (Bartlett), averaged over the series weighted by their energy. 1 for white residuals.
pub fn effective_fraction(series: &[Vec<f64>]) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for x in series {
        let n = x.len();
        if n < 10 {
            continue;
        }
        let mean = x.iter().sum::<f64>() / n as f64;
        let centred: Vec<f64> = x.iter().map(|v| v - mean).collect();
        let c0 = dot(&centred, &centred);
        if c0 <= 0.0 {
            continue;
        }
        let mut sum = 0.0;
        for k in 1..n / 4 {
            let ck = dot(&centred[..n - k], &centred[k..]) / c0;
            if ck < 0.05 {
                break;
            }
            sum += ck;
        }
        num += c0 / (1.0 + 2.0 * sum);
        den += c0;
    }
    if den > 0.0 {
        (num / den).clamp(1e-3, 1.0)
    } else {
        1.0
    }
}

/// `a . b` over the shorter length, in sixteen running sums (which the compiler vectorises into
/// independent chains: one sum in order cannot be reordered, and four wait on each other's adds).
fn dot(a: &[f64], b: &[f64]) -> f64 {
    const W: usize = 16;
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut s = [0.0; W];
    let (ca, cb) = (a.chunks_exact(W), b.chunks_exact(W));
    let tail: f64 = ca.remainder().iter().zip(cb.remainder()).map(|(x, y)| x * y).sum();
    for (x, y) in ca.zip(cb) {
        for i in 0..W {
            s[i] += x[i] * y[i];
        }
    }
    s.iter().sum::<f64>() + tail
}

/// ln Gamma(x), x > 0 (Lanczos, g = 7).
fn ln_gamma(x: f64) -> f64 {
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.5203681218851,
        -1259.1392167224028,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507343278686905,
        -0.13857109526572012,
        9.984_369_578_019_572e-6,
        1.5056327351493116e-7,
    ];
    if x < 0.5 {
        return (std::f64::consts::PI / (std::f64::consts::PI * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let mut a = C[0];
    let t = x + 7.5;
    for (i, c) in C.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// Regularised upper incomplete gamma Q(a, x).
fn gamma_q(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 1.0;
    }
    let gln = ln_gamma(a);
    if x < a + 1.0 {
        // Series for P.
        let (mut sum, mut del, mut ap) = (1.0 / a, 1.0 / a, a);
        for _ in 0..500 {
            ap += 1.0;
            del *= x / ap;
            sum += del;
            if del.abs() < sum.abs() * 1e-15 {
                break;
            }
        }
        1.0 - sum * (-x + a * x.ln() - gln).exp()
    } else {
        // Continued fraction for Q (modified Lentz).
        let tiny = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..500 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < tiny {
                d = tiny;
            }
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < 1e-15 {
                break;
            }
        }
        (-x + a * x.ln() - gln).exp() * h
    }
}

/// P(chi-square with `dof` degrees of freedom > x).
pub fn chi2_sf(x: f64, dof: usize) -> f64 {
    gamma_q(dof as f64 / 2.0, x / 2.0).clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chi_square_tail_matches_tables() {
        // 3.841 and 6.635 are the 5% and 1% points of one degree of freedom; 9.488 the 5% of four.
        assert!((chi2_sf(3.841, 1) - 0.05).abs() < 2e-4);
        assert!((chi2_sf(6.635, 1) - 0.01).abs() < 1e-4);
        assert!((chi2_sf(9.488, 4) - 0.05).abs() < 2e-4);
        assert!((chi2_sf(2.0, 2) - (-1.0f64).exp()).abs() < 1e-12);
    }

    #[test]
    fn bounds_hold_and_free_fits_are_exact() {
        let a = DMatrix::from_row_slice(4, 2, &[1.0, 0.0, 0.0, 1.0, 1.0, 1.0, 2.0, -1.0]);
        let x = DVector::from_vec(vec![0.5, -0.3]);
        let r = &a * &x;
        let free = bounded_least_squares(&a, &r, &[Bounds::FREE, Bounds::FREE]).unwrap();
        assert!((free - &x).norm() < 1e-12);
        let b = bounded_least_squares(&a, &r, &[Bounds::FREE, Bounds::at_least(0.0)]).unwrap();
        assert!(b[1] >= -1e-8 && b[1] < 1e-6, "{b}");
        // The bound active, the other coordinate is the 1-D least squares: sum(a0 (r - a1 x1)) / sum(a0^2).
        let (a0, a1) = (a.column(0), a.column(1));
        let rest = |x1: f64| a0.dot(&(&r - a1 * x1)) / a0.dot(&a0);
        assert!((b[0] - rest(0.0)).abs() < 1e-6, "{b}");
        // An upper bound below the free value: x0 held at 0.2, x1 the 1-D fit of what is left.
        let u = bounded_least_squares(&a, &r, &[Bounds::within(-1.0, 0.2), Bounds::FREE]).unwrap();
        assert!((u[0] - 0.2).abs() < 1e-6, "{u}");
        assert!((u[1] - a1.dot(&(&r - a0 * 0.2)) / a1.dot(&a1)).abs() < 1e-6, "{u}");
        assert!(Bounds::within(-1.0, 0.2).active(u[0]) && !Bounds::within(-1.0, 0.2).active(0.0));
        assert_eq!((Bounds::within(-1.0, 0.2).held_at(u[0]), Bounds::at_least(0.0).held_at(1e-14)), (Some(0.2), Some(0.0)));
    }
}
