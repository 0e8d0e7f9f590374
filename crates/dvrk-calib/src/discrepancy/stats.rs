//! The statistics of the workflow: a least-squares fit with lower bounds (clarabel), the
//! effective sample size of autocorrelated residuals, and the chi-square tail.

use crate::error::{CalibError, Result};
use clarabel::algebra::CscMatrix;
use clarabel::solver::{DefaultSettingsBuilder, DefaultSolver, IPSolver, NonnegativeConeT, SolverStatus};
use nalgebra::{DMatrix, DVector};

/// `min |A x - r|^2` subject to `x_i >= lower_i` where `lower_i` is given. The columns are
/// scaled to unit norm first (clarabel's tolerances are absolute). Returns `x`.
pub fn bounded_least_squares(a: &DMatrix<f64>, r: &DVector<f64>, lower: &[Option<f64>]) -> Result<DVector<f64>> {
    let p = a.ncols();
    let scale: Vec<f64> = (0..p).map(|j| a.column(j).norm().max(1e-300)).collect();
    let mut s = a.clone();
    for (j, sc) in scale.iter().enumerate() {
        s.column_mut(j).scale_mut(1.0 / sc);
    }
    let h = s.transpose() * &s;
    let g = s.transpose() * r;
    // The unconstrained solution, used as is when it satisfies the bounds.
    if let Some(z) = h.clone().cholesky().map(|c| c.solve(&g)) {
        if lower.iter().enumerate().all(|(j, lo)| lo.is_none_or(|lo| z[j] / scale[j] >= lo)) {
            return Ok(DVector::from_iterator(p, (0..p).map(|j| z[j] / scale[j])));
        }
    }
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
    // Rows -z_j <= -lo_j scale_j (z = x scale).
    let rows: Vec<(usize, f64)> = lower.iter().enumerate().filter_map(|(j, lo)| lo.map(|lo| (j, lo * scale[j]))).collect();
    let (mut colptr, mut rowval, mut nzval) = (vec![0], Vec::new(), Vec::new());
    for j in 0..p {
        for (i, (jj, _)) in rows.iter().enumerate() {
            if *jj == j {
                rowval.push(i);
                nzval.push(-1.0);
            }
        }
        colptr.push(rowval.len());
    }
    let am = CscMatrix::new(rows.len(), p, colptr, rowval, nzval);
    let b: Vec<f64> = rows.iter().map(|(_, lo)| -lo).collect();
    let settings = DefaultSettingsBuilder::default().verbose(false).max_iter(100).build().map_err(|e| CalibError::data("bounded fit settings", e.to_string()))?;
    let cones = [NonnegativeConeT(rows.len())];
    let mut solver = DefaultSolver::new(&pm, &q, &am, &b, &cones, settings).map_err(|e| CalibError::data("bounded fit", format!("{e:?}")))?;
    solver.solve();
    match solver.solution.status {
        SolverStatus::Solved | SolverStatus::AlmostSolved => {}
        status => return Err(CalibError::data("bounded fit", format!("clarabel stopped: {status:?}"))),
    }
    Ok(DVector::from_iterator(p, (0..p).map(|j| solver.solution.x[j] / scale[j])))
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
        let c0: f64 = x.iter().map(|v| (v - mean).powi(2)).sum();
        if c0 <= 0.0 {
            continue;
        }
        let mut sum = 0.0;
        for k in 1..n / 4 {
            let ck: f64 = (0..n - k).map(|i| (x[i] - mean) * (x[i + k] - mean)).sum::<f64>() / c0;
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

/// ln Gamma(x), x > 0 (Lanczos, g = 7).
fn ln_gamma(x: f64) -> f64 {
    const C: [f64; 9] = [0.999_999_999_999_809_9, 676.5203681218851, -1259.1392167224028, 771.323_428_777_653_1, -176.615_029_162_140_6, 12.507343278686905, -0.13857109526572012, 9.984_369_578_019_572e-6, 1.5056327351493116e-7];
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
        let free = bounded_least_squares(&a, &r, &[None, None]).unwrap();
        assert!((free - &x).norm() < 1e-12);
        let b = bounded_least_squares(&a, &r, &[None, Some(0.0)]).unwrap();
        assert!(b[1] >= -1e-8 && b[1] < 1e-6, "{b}");
        // The bound active, the other coordinate is the 1-D least squares: sum(a0 r) / sum(a0^2).
        let a0 = a.column(0);
        assert!((b[0] - a0.dot(&r) / a0.dot(&a0)).abs() < 1e-6, "{b}");
    }
}
