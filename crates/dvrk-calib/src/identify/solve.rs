//! The constrained fit: weighted least squares with a pull toward the prior (the CAD inertials),
//! every body's 4 x 4 pseudo-inertia positive semidefinite (physical consistency: a real mass
//! distribution has one), non-negative friction, armature and stiffness. Solved with clarabel.
//!
//! The pseudo-inertia cones are imposed by cutting planes on a QP: solve, find each body whose
//! pseudo-inertia has a negative eigenvalue, add the linear cut `v' J(theta) v >= 0` at its
//! eigenvector `v`, solve again. The cuts are valid for the PSD cone (it is the intersection of
//! all of them), so the iteration converges to the same optimum as the SDP. clarabel's native PSD
//! cone would need system BLAS/LAPACK (OpenBLAS, gfortran), which a fresh machine lacks.

use super::problem::{Layout, Param};
use crate::error::{CalibError, Result};
use clarabel::algebra::CscMatrix;
use clarabel::solver::{DefaultSettingsBuilder, DefaultSolver, IPSolver, NonnegativeConeT, SolverStatus};
use dvrk_kin::dynamics::PARAMETERS_PER_BODY;
use nalgebra::{DMatrix, DVector, Matrix4, SymmetricEigen, Vector4};

/// The quadratic objective `(theta - theta0)' P0 (theta - theta0) + sum_c w_c |Y_c theta - tau_c|^2`
/// as `theta' H theta - 2 g' theta + const`.
#[derive(Debug, Clone)]
pub struct Objective {
    pub h: DMatrix<f64>,
    pub g: DVector<f64>,
}

/// Result of the constrained fit.
#[derive(Debug, Clone)]
pub struct Fit {
    pub theta: DVector<f64>,
    /// Cutting-plane rounds (QP solves).
    pub rounds: usize,
    /// Indices of the parameters held at their bound (0).
    pub at_bound: Vec<usize>,
    /// Bodies whose pseudo-inertia is on the boundary of the cone (smallest eigenvalue ~0:
    /// the mass distribution is degenerate, e.g. all mass on a plane).
    pub degenerate_bodies: Vec<usize>,
    /// Smallest eigenvalue of each body's pseudo-inertia, relative to its largest.
    pub min_eigen: Vec<f64>,
}

/// The pseudo-inertia `[[0.5 tr(I) 1 - I, h], [h', m]]` of parameters
/// `[m, hx, hy, hz, Ixx, Ixy, Ixz, Iyy, Iyz, Izz]` (inertia entries about the frame origin).
pub fn pseudo_inertia(p: &[f64]) -> Matrix4<f64> {
    let (m, h, i) = (p[0], [p[1], p[2], p[3]], [[p[4], p[5], p[6]], [p[5], p[7], p[8]], [p[6], p[8], p[9]]]);
    let half_trace = 0.5 * (i[0][0] + i[1][1] + i[2][2]);
    let mut j = Matrix4::zeros();
    for r in 0..3 {
        for c in 0..3 {
            j[(r, c)] = if r == c { half_trace } else { 0.0 } - i[r][c];
        }
        j[(r, 3)] = h[r];
        j[(3, r)] = h[r];
    }
    j[(3, 3)] = m;
    j
}

/// Coefficients `c` with `v' J(p) v = c . p` (the cut of direction `v`).
fn cut(v: &Vector4<f64>) -> [f64; PARAMETERS_PER_BODY] {
    let (u, w) = ([v[0], v[1], v[2]], v[3]);
    let uu = 0.5 * (u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
    [
        w * w,
        2.0 * w * u[0],
        2.0 * w * u[1],
        2.0 * w * u[2],
        uu - u[0] * u[0],
        -2.0 * u[0] * u[1],
        -2.0 * u[0] * u[2],
        uu - u[1] * u[1],
        -2.0 * u[1] * u[2],
        uu - u[2] * u[2],
    ]
}

/// Upper triangle of a dense symmetric matrix as clarabel's CSC.
fn upper_csc(m: &DMatrix<f64>) -> CscMatrix<f64> {
    let n = m.ncols();
    let (mut colptr, mut rowval, mut nzval) = (vec![0], Vec::new(), Vec::new());
    for c in 0..n {
        for r in 0..=c {
            let v = m[(r, c)];
            if v != 0.0 {
                rowval.push(r);
                nzval.push(v);
            }
        }
        colptr.push(rowval.len());
    }
    CscMatrix::new(n, n, colptr, rowval, nzval)
}

/// Dense rows as clarabel's CSC.
fn rows_csc(rows: &[Vec<(usize, f64)>], n: usize) -> CscMatrix<f64> {
    let mut cols: Vec<Vec<(usize, f64)>> = vec![Vec::new(); n];
    for (r, row) in rows.iter().enumerate() {
        for &(c, v) in row {
            cols[c].push((r, v));
        }
    }
    let (mut colptr, mut rowval, mut nzval) = (vec![0], Vec::new(), Vec::new());
    for col in cols {
        for (r, v) in col {
            rowval.push(r);
            nzval.push(v);
        }
        colptr.push(rowval.len());
    }
    CscMatrix::new(rows.len(), n, colptr, rowval, nzval)
}

/// Minimise the objective subject to the physical constraints. `scale` (one per parameter, > 0:
/// the prior standard deviations) normalises the variables for the solver. `margin` keeps every
/// body's pseudo-inertia at least that fraction of the prior's, `J(theta) >= margin J(theta0)`
/// (0: plain physical consistency; > 0 keeps bodies the data cannot see from collapsing onto
/// the cone's boundary, point-like masses that a simulation cannot carry well).
pub fn solve(layout: &Layout, objective: &Objective, theta0: &DVector<f64>, scale: &DVector<f64>, margin: f64) -> Result<Fit> {
    let n = layout.len();
    // Variables z = (theta - theta0) / scale: objective z' (S H S) z - 2 (S (g - H theta0))' z.
    let s = DMatrix::from_diagonal(scale);
    let hz = &s * &objective.h * &s;
    let gz = &s * (&objective.g - &objective.h * theta0);
    let p = upper_csc(&(&hz * 2.0));
    let q: Vec<f64> = (-2.0 * &gz).iter().copied().collect();
    // Each row r: (coefficients on theta, lower) meaning coeffs . theta >= lower, i.e.
    // s = coeffs . theta0 - lower + (coeffs o scale) . z >= 0. A body's cut has
    // lower = margin coeffs . theta0_body.
    let mut rows: Vec<Vec<(usize, f64)>> = Vec::new();
    let mut lower: Vec<f64> = Vec::new();
    let body_cut = |row: &Vec<(usize, f64)>| margin * row.iter().map(|&(i, c)| c * theta0[i]).sum::<f64>();
    let mut bounds: Vec<usize> = Vec::new();
    for (i, param) in layout.params.iter().enumerate() {
        if let Param::Effect { term, .. } | Param::Joint { term, .. } = param {
            if term.nonnegative() {
                rows.push(vec![(i, 1.0)]);
                lower.push(0.0);
                bounds.push(i);
            }
        }
    }
    // Start every body with cuts along the axes of its own frame: mass >= 0 and the principal
    // second moments >= 0.
    for b in 0..layout.nbodies {
        for k in 0..4 {
            let mut v = Vector4::zeros();
            v[k] = 1.0;
            let row: Vec<(usize, f64)> = cut(&v).iter().enumerate().map(|(j, c)| (b * PARAMETERS_PER_BODY + j, *c)).filter(|(_, c)| *c != 0.0).collect();
            lower.push(body_cut(&row));
            rows.push(row);
        }
    }
    let settings = DefaultSettingsBuilder::default().verbose(false).max_iter(200).build().map_err(|e| CalibError::context("identification solver settings", e))?;
    let mut rounds = 0;
    loop {
        rounds += 1;
        let a_rows: Vec<Vec<(usize, f64)>> = rows.iter().map(|r| r.iter().map(|&(i, c)| (i, -c * scale[i])).collect()).collect();
        let b: Vec<f64> = rows.iter().zip(&lower).map(|(r, lo)| r.iter().map(|&(i, c)| c * theta0[i]).sum::<f64>() - lo).collect();
        let a = rows_csc(&a_rows, n);
        let cones = [NonnegativeConeT(rows.len())];
        let mut solver = DefaultSolver::new(&p, &q, &a, &b, &cones, settings.clone()).map_err(|e| CalibError::data("identification solver", format!("{e:?}")))?;
        solver.solve();
        match solver.solution.status {
            SolverStatus::Solved | SolverStatus::AlmostSolved => {}
            status => return Err(CalibError::data("identification solver", format!("clarabel stopped: {status:?} after {rounds} cutting-plane round(s)"))),
        }
        let theta: DVector<f64> = theta0 + scale.component_mul(&DVector::from_column_slice(&solver.solution.x));
        // Cuts for every body with a negative eigenvalue (relative to the body's scale).
        let mut added = 0;
        let mut min_eigen = Vec::with_capacity(layout.nbodies);
        for bi in 0..layout.nbodies {
            let base = bi * PARAMETERS_PER_BODY;
            let j = pseudo_inertia(&theta.as_slice()[base..base + PARAMETERS_PER_BODY]) - pseudo_inertia(&theta0.as_slice()[base..base + PARAMETERS_PER_BODY]) * margin;
            let eig = SymmetricEigen::new(j);
            let top = eig.eigenvalues.amax().max(1e-12);
            let rel = eig.eigenvalues.min() / top;
            min_eigen.push(rel);
            for (k, l) in eig.eigenvalues.iter().enumerate() {
                if *l < -1e-10 * top {
                    let v: Vector4<f64> = eig.eigenvectors.column(k).into();
                    let row: Vec<(usize, f64)> = cut(&v).iter().enumerate().map(|(jj, c)| (base + jj, *c)).filter(|(_, c)| *c != 0.0).collect();
                    lower.push(body_cut(&row));
                    rows.push(row);
                    added += 1;
                }
            }
        }
        if added == 0 || rounds >= 200 {
            let at_bound = bounds.iter().copied().filter(|&i| theta[i] <= 1e-9 * scale[i]).collect();
            let degenerate_bodies = (0..layout.nbodies).filter(|&b| min_eigen[b] < 1e-6).collect();
            if added > 0 {
                return Err(CalibError::data("identification solver", format!("pseudo-inertias not positive semidefinite after {rounds} cutting-plane rounds (smallest relative eigenvalue {:.2e})", min_eigen.iter().copied().fold(f64::MAX, f64::min))));
            }
            return Ok(Fit { theta, rounds, at_bound, degenerate_bodies, min_eigen });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use dvrk_kin::BodyInertia;

    #[test]
    fn pseudo_inertia_of_a_real_body_is_positive_and_the_cut_is_its_quadratic_form() {
        let b = BodyInertia::new(2.0, [0.1, -0.05, 0.2], [[0.02, 0.001, 0.0], [0.001, 0.03, -0.002], [0.0, -0.002, 0.025]]);
        let p = b.parameters();
        let j = pseudo_inertia(&p);
        assert!(SymmetricEigen::new(j).eigenvalues.min() > 0.0);
        // J = sum m [r; 1][r; 1]' for point masses: its (3,3) entry is the mass, (0..3, 3) the first moment.
        assert_eq!(j[(3, 3)], 2.0);
        assert!((j[(0, 3)] - 0.2).abs() < 1e-15);
        let v = Vector4::new(0.3, -0.7, 0.2, 0.5);
        let c = cut(&v);
        let quad = (v.transpose() * j * v)[0];
        let lin: f64 = c.iter().zip(&p).map(|(a, b)| a * b).sum();
        assert!((quad - lin).abs() < 1e-14, "{quad} {lin}");
    }

    /// An objective that pulls every parameter to zero: with no margin each body collapses onto
    /// the cone's boundary (zero mass); with margin 0.5 each keeps at least half the prior's
    /// pseudo-inertia in every direction.
    #[test]
    fn the_margin_keeps_bodies_inside_the_cone() {
        use crate::identify::problem::{Layout, Terms};
        let model = dvrk_kin::load("psm", None).unwrap();
        let layout = Layout::new(&model, 7, &Terms::default());
        let prior = dvrk_sim::scene::builtin_inertials("psm", &model).unwrap().body_inertias(&model).unwrap();
        let theta0 = DVector::from_iterator(layout.len(), prior.iter().flat_map(|b| b.parameters()));
        let scale = theta0.map(|x| x.abs() + 1e-3);
        let objective = Objective { h: DMatrix::from_diagonal(&scale.map(|s| 1.0 / (s * s))), g: DVector::zeros(layout.len()) };
        for margin in [0.0, 0.5] {
            let fit = solve(&layout, &objective, &theta0, &scale, margin).unwrap();
            for b in 0..layout.nbodies {
                let r = b * PARAMETERS_PER_BODY..(b + 1) * PARAMETERS_PER_BODY;
                let (j, j0) = (pseudo_inertia(&fit.theta.as_slice()[r.clone()]), pseudo_inertia(&theta0.as_slice()[r]));
                let l = SymmetricEigen::new(j - j0 * margin).eigenvalues.min();
                assert!(l > -1e-9 * j0.norm(), "margin {margin}, body {b}: {l}");
                if margin == 0.0 {
                    assert!(j[(3, 3)] < 1e-3 * j0[(3, 3)], "body {b} kept mass {}", j[(3, 3)]);
                } else {
                    // The mass at least half the prior's (other directions of the bound can ask a bit more).
                    let ratio = j[(3, 3)] / j0[(3, 3)];
                    assert!(ratio > 0.5 - 1e-6 && ratio < 0.6, "body {b}: mass ratio {ratio}");
                }
            }
        }
    }
}
