//! The bodies' inertial parameters as nuisance: a CAD model's inertias are never exact, and their
//! error leaves a residual that would otherwise be named as an effect (or hide one). Every fit of
//! the workflow re-estimates them next to the candidate, pulled toward the model's values by a
//! Gaussian prior (ridge), so an effect that inertias could explain only with implausible values
//! still stands out, and a payload (a mass change far beyond the prior) is still seen.
//!
//! With `N` the regressor rows (each over its joint's noise floor, each column times its prior
//! standard deviation) and `lambda` the prior's weight, eliminating the nuisance from
//! `min |y - N t - C x|^2 + lambda |t|^2` leaves `|y - C x|_W^2` with
//! `W = I - N (N^T N + lambda I)^-1 N^T`: everything below works in that metric, through the
//! Cholesky factor `L` of `N^T N + lambda I` (`v^T W v = |v|^2 - |L^-1 N^T v|^2`).
//!
//! A model identified from a recording (`dvrk identify -o`) carries how well that recording
//! determined its inertias (`[inertial_covariance]`): the prior is then that covariance, `S S^T`,
//! and `N`'s columns are the regressor times `S`. The inertias then move only where the
//! identification left them free; a relative prior on an identified model let them take up a
//! 205 g weight on the WPI arm (the pitch's residual 0.52 -> 0.10 N·m, no payload named).

use super::candidates::Table;
use super::signals::Prepared;
use crate::error::{CalibError, Result};
use crate::linalg::{mul, tr_mul};
use dvrk_kin::dynamics::PARAMETERS_PER_BODY;
use dvrk_kin::{BodyInertia, DynamicsData, DynamicsModel, Model};
use nalgebra::{Cholesky, DMatrix, DVector, Dyn, Vector3};

/// Prior standard deviations of the inertial parameters, relative to the model's values (a CAD
/// model's), unless the model carries its own covariance and [`InertiaPrior::from_model`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InertiaPrior {
    /// Take the model file's `[inertial_covariance]` as the prior where it has one.
    pub from_model: bool,
    /// Of each body's rotational inertia (its six entries, relative to the largest moment about
    /// the centre of mass); 0 holds them at the model's values.
    pub rotational: f64,
    /// Of each body's mass and first moments (relative to `m` and to `m (|c| + 1 cm)`).
    pub mass: f64,
}

impl Default for InertiaPrior {
    fn default() -> Self {
        InertiaPrior { from_model: true, rotational: 0.1, mass: 0.02 }
    }
}

impl InertiaPrior {
    /// Nothing re-estimated.
    pub fn none() -> Self {
        InertiaPrior { from_model: false, rotational: 0.0, mass: 0.0 }
    }

    /// Relative standard deviations (see the fields), whatever the model carries.
    pub fn relative(rotational: f64, mass: f64) -> Self {
        InertiaPrior { from_model: false, rotational, mass }
    }

    fn is_off(&self) -> bool {
        self.rotational <= 0.0 && self.mass <= 0.0
    }

    /// Each linear-form parameter's standard deviation for `body` (kg, kg m, kg m^2).
    fn stds(&self, body: &BodyInertia) -> [f64; PARAMETERS_PER_BODY] {
        let m = body.mass;
        let first = self.mass * m * (body.com.norm() + 0.01);
        let rot = self.rotational * body.inertia.symmetric_eigenvalues().amax();
        [self.mass * m, first, first, first, rot, rot, rot, rot, rot, rot]
    }
}

/// The nuisance of one analysis (see the module's text).
#[derive(Clone)]
pub struct Nuisance {
    /// Scaled regressor rows of every analysed sample (sample-major, the active joints).
    n: DMatrix<f64>,
    /// Rows `0..train` are the fitted part.
    train: usize,
    chol: Cholesky<f64, Dyn>,
    /// The prior's square root: the inertial parameters' change (every body's, dvrk-kin's
    /// regressor order) is `scale * theta`, `theta` one entry per column of `n`.
    scale: DMatrix<f64>,
    /// Whether `scale` is the model's own covariance ([`InertiaPrior::from_model`]).
    pub from_model: bool,
    /// The prior's weight and the analysed joints per sample (see [`Nuisance::new`]).
    lambda: f64,
    na: usize,
    /// `N^T N` over every row, and over each of the [`FOLDS`] parts (cross-validation).
    gram: DMatrix<f64>,
    fold_grams: Vec<DMatrix<f64>>,
}

/// The parts a recording is cut into for the cross-validated held-out test.
pub const FOLDS: usize = 5;

/// The rows of fold `f` of [`FOLDS`] over `samples` samples of `na` rows each (whole samples).
pub fn fold_rows(f: usize, samples: usize, na: usize) -> std::ops::Range<usize> {
    f * samples / FOLDS * na..(f + 1) * samples / FOLDS * na
}

/// `N^T N` over every row and over each fold's rows.
fn grams(n: &DMatrix<f64>, na: usize) -> (DMatrix<f64>, Vec<DMatrix<f64>>) {
    let samples = n.nrows() / na.max(1);
    let parts: Vec<DMatrix<f64>> = (0..FOLDS).map(|f| {
        let r = fold_rows(f, samples, na);
        let nf = n.rows(r.start, r.len());
        tr_mul(&nf, &nf)
    }).collect();
    (parts.iter().fold(DMatrix::zeros(n.ncols(), n.ncols()), |a, g| a + g), parts)
}

impl Nuisance {
    /// The nuisance for `model` with `dm`'s inertias (the prior's centre) on `prep`, or `None`
    /// when the prior holds everything. `lambda`: the prior's weight against a row
    /// (`1 / (n_eff / n)` of the band-limited noise: rows are correlated, the prior is not).
    pub fn new(model: &Model, dm: &DynamicsModel, gravity: &Vector3<f64>, prep: &Prepared, prior: &InertiaPrior, lambda: f64) -> Result<Option<Nuisance>> {
        let nb = dm.inertias().len();
        let np = nb * PARAMETERS_PER_BODY;
        let own = if prior.from_model { model.inertial_covariance_factor(&(0..nb).collect::<Vec<_>>()) } else { None };
        let from_model = own.is_some();
        let scale = match own {
            Some(l) => l,
            None if prior.is_off() => return Ok(None),
            None => DMatrix::from_diagonal(&DVector::from_iterator(np, dm.inertias().iter().flat_map(|b| prior.stds(b)))),
        };
        // `N` is the regressor rows (each over its joint's floor) times `scale`, reduced to the
        // directions the recording sees. Built in two passes over the samples, never whole at
        // the regressor's width (a 5-minute recording's is 190 MB, several copies 430 MB): the
        // first sums the rows' Gram matrix, the second writes the reduced rows.
        let mut data = DynamicsData::new(model);
        let nq = model.nq();
        let mut y = DMatrix::zeros(nq, np);
        let na = prep.active.len();
        let mut rows = DMatrix::zeros(na, np);
        let mut regressor_rows = |i: usize, rows: &mut DMatrix<f64>| -> Result<()> {
            dvrk_kin::regressor(model, dm, &mut data, &prep.q[i], &prep.qd[i], &prep.qdd[i], gravity, &mut y)?;
            for (a, &k) in prep.active.iter().enumerate() {
                for c in 0..np {
                    rows[(a, c)] = y[(k, c)] / prep.floor[k];
                }
            }
            Ok(())
        };
        let mut gram_full = DMatrix::zeros(np, np);
        for i in 0..prep.t.len() {
            regressor_rows(i, &mut rows)?;
            gram_full += rows.tr_mul(&rows);
        }
        let gram_scaled = scale.tr_mul(&(&gram_full * &scale));
        // Only directions that change some effort and have room to move.
        let keep: Vec<usize> = (0..np).filter(|&c| gram_scaled[(c, c)] > 0.0).collect();
        if keep.is_empty() {
            return Ok(None);
        }
        let scale = scale.select_columns(&keep);
        // Only the directions the recording sees matter (`N = U S V^T`: `W` is `U S`'s, the
        // parameters `scale V theta'`): a full model's 130 columns fall to their numerical rank,
        // and every fit's projection costs that much less. The Gram matrix's eigenvectors give
        // `V`; directions with `s^2` under 1e-9 of the prior's weight change no fit.
        let eig = nalgebra::SymmetricEigen::new(gram_scaled.select_rows(&keep).select_columns(&keep));
        let seen: Vec<usize> = (0..eig.eigenvalues.len()).filter(|&i| eig.eigenvalues[i] > 1e-9 * lambda).collect();
        if seen.is_empty() {
            return Ok(None);
        }
        let scale = &scale * eig.eigenvectors.select_columns(&seen);
        let mut n = DMatrix::zeros(prep.t.len() * na, scale.ncols());
        for i in 0..prep.t.len() {
            regressor_rows(i, &mut rows)?;
            n.rows_mut(i * na, na).copy_from(&(&rows * &scale));
        }
        let train = prep.split * na;
        let chol = factor(&n, train, lambda)?;
        let (gram, fold_grams) = grams(&n, na);
        Ok(Some(Nuisance { n, train, chol, scale, from_model, lambda, na, gram, fold_grams }))
    }

    /// The same nuisance on another timeline: each column, as a series over the samples (one
    /// entry per analysed joint), passed through `shift` (the workflow's latency shift of the
    /// prediction). A latency moves the whole predicted effort, the inertias' share included:
    /// the nuisance left on the measured timeline fits its inertias' error `tau` apart, and the
    /// latency estimate absorbs the difference (`tau` times the error's share of the effort's
    /// rate: 3% inertia errors moved 12 ms estimates by up to 80 us).
    pub fn retimed(&self, shift: &dyn Fn(&Table) -> Table) -> Result<Nuisance> {
        self.clone().into_retimed(shift)
    }

    /// [`Nuisance::retimed`] in place: on a long recording a copy would hold the nuisance twice.
    pub fn into_retimed(mut self, shift: &dyn Fn(&Table) -> Table) -> Result<Nuisance> {
        let (na, samples) = (self.na, self.n.nrows() / self.na.max(1));
        for c in 0..self.n.ncols() {
            let series: Table = (0..samples).map(|i| (0..na).map(|a| self.n[(i * na + a, c)]).collect()).collect();
            for (i, row) in shift(&series).iter().enumerate() {
                for (a, x) in row.iter().enumerate() {
                    self.n[(i * na + a, c)] = *x;
                }
            }
        }
        self.chol = factor(&self.n, self.train, self.lambda)?;
        (self.gram, self.fold_grams) = grams(&self.n, na);
        Ok(self)
    }

    /// `L^-1 N_train^T v` for a training-row vector `v`.
    fn project(&self, v: &DVector<f64>) -> DVector<f64> {
        let g = tr_mul(&self.n.rows(0, self.train), v);
        self.chol.l_dirty().solve_lower_triangular(&g).unwrap_or(g)
    }

    /// `L^-1 N_train^T C` for training-row columns `C`.
    fn project_columns(&self, c: &DMatrix<f64>) -> DMatrix<f64> {
        let g = tr_mul(&self.n.rows(0, self.train), c);
        self.chol.l_dirty().solve_lower_triangular(&g).unwrap_or(g)
    }

    /// `v^T W v`: the residual's squared norm with the nuisance refitted (prior cost included).
    pub fn wnorm2(&self, v: &DVector<f64>) -> f64 {
        (v.norm_squared() - self.project(v).norm_squared()).max(0.0)
    }

    /// The nuisance fitted to training residual `v` (scaled units).
    pub fn theta(&self, v: &DVector<f64>) -> DVector<f64> {
        self.chol.solve(&tr_mul(&self.n.rows(0, self.train), v))
    }

    /// Training-row columns `C` less the nuisance fitted to each: `W C`.
    pub fn whitened_columns(&self, c: &DMatrix<f64>) -> DMatrix<f64> {
        let nt = self.n.rows(0, self.train);
        c - mul(&nt, &self.chol.solve(&tr_mul(&nt, c)))
    }

    /// The inertial parameters' change of a fitted nuisance `theta` (kg, kg m, kg m^2; every
    /// body's, in dvrk-kin's regressor order).
    pub fn parameters(&self, theta: &DVector<f64>) -> DVector<f64> {
        &self.scale * theta
    }

    /// The fitted nuisance's contribution on rows `start..start + len` (scaled units).
    pub fn predict(&self, theta: &DVector<f64>, start: usize, len: usize) -> DVector<f64> {
        mul(&self.n.rows(start, len), theta)
    }

    /// The Gram matrix and right-hand side of `min |y - C x|_W^2` over `x`: `C^T W C`, `C^T W y`.
    pub fn normal_equations(&self, c: &DMatrix<f64>, y: &DVector<f64>) -> (DMatrix<f64>, DVector<f64>) {
        let (zc, zy) = (self.project_columns(c), self.project(y));
        (tr_mul(c, c) - zc.tr_mul(&zc), tr_mul(c, y) - zc.tr_mul(&zy))
    }
}

/// The Cholesky factor of `N_train^T N_train + lambda I` (`train` rows).
fn factor(n: &DMatrix<f64>, train: usize, lambda: f64) -> Result<Cholesky<f64, Dyn>> {
    // `tr_mul`: no transposed copy of the rows (as large as `N` itself on a long recording).
    let nt = n.rows(0, train);
    let mut p = tr_mul(&nt, &nt);
    for d in 0..p.nrows() {
        p[(d, d)] += lambda;
    }
    p.cholesky().ok_or_else(|| CalibError::data("inertia nuisance", "the prior's normal matrix is not positive definite"))
}

impl Nuisance {
    /// Out-of-fold residuals over every row: the recording cut into [`FOLDS`] contiguous parts,
    /// each predicted by the nuisance alone (`e0`) and by the nuisance with columns `c`
    /// (bounded by `bounds`; `e1`) fitted on the other parts. `y`, `c`: every row (scaled).
    pub fn cross_validated(&self, y: &DVector<f64>, c: &DMatrix<f64>, bounds: &[super::stats::Bounds]) -> Result<(DVector<f64>, DVector<f64>)> {
        let rows = self.n.nrows();
        let totals = Totals::new(&self.n, c, y);
        let (mut e0, mut e1) = (DVector::zeros(rows), DVector::zeros(rows));
        for f in 0..FOLDS {
            let fold = self.fold_fit(f, &totals, c, y, bounds)?;
            let r = fold.rows.clone();
            let (nf, cf, yf) = (self.n.rows(r.start, r.len()), c.rows(r.start, r.len()), y.rows(r.start, r.len()));
            e0.rows_mut(r.start, r.len()).copy_from(&(yf - mul(&nf, &fold.ch.solve(&fold.nty))));
            match &fold.x {
                // Columns the other parts do not determine: the fold gets the null's prediction.
                None => {
                    let null = e0.rows(r.start, r.len()).into_owned();
                    e1.rows_mut(r.start, r.len()).copy_from(&null);
                }
                Some(x) => {
                    let t1 = fold.ch.solve(&(&fold.nty - &fold.ntc * x));
                    e1.rows_mut(r.start, r.len()).copy_from(&(yf - mul(&cf, x) - mul(&nf, &t1)));
                }
            }
        }
        Ok((e0, e1))
    }

    /// The columns' fit `x` (bounded by `bounds`) on all parts but each of the [`FOLDS`]
    /// contiguous ones in turn, the nuisance refitted each time (`None` where the other parts do
    /// not determine them): the spread of a fitted value over the recording's parts.
    pub fn fold_fits(&self, y: &DVector<f64>, c: &DMatrix<f64>, bounds: &[super::stats::Bounds]) -> Result<Vec<Option<DVector<f64>>>> {
        let totals = Totals::new(&self.n, c, y);
        (0..FOLDS).map(|f| Ok(self.fold_fit(f, &totals, c, y, bounds)?.x)).collect()
    }

    /// Fold `f`'s fit from the other parts: its rows, the nuisance's factor and right-hand sides
    /// without them, and the columns' fit in the metric the nuisance leaves.
    fn fold_fit(&self, f: usize, t: &Totals, c: &DMatrix<f64>, y: &DVector<f64>, bounds: &[super::stats::Bounds]) -> Result<FoldFit> {
        let r = fold_rows(f, self.n.nrows() / self.na.max(1), self.na);
        let (nf, cf, yf) = (self.n.rows(r.start, r.len()), c.rows(r.start, r.len()), y.rows(r.start, r.len()));
        // Each fold's training sums are the totals less the fold's own.
        let mut g = &self.gram - &self.fold_grams[f];
        for d in 0..g.nrows() {
            g[(d, d)] += self.lambda;
        }
        let ch = g.cholesky().ok_or_else(|| CalibError::data("inertia nuisance", "a fold's prior normal matrix is not positive definite"))?;
        let (ntc, nty) = (&t.nc - tr_mul(&nf, &cf), &t.ny - tr_mul(&nf, &yf));
        // The candidate's normal equations in the metric the nuisance leaves (as
        // [`Nuisance::normal_equations`]).
        let l = ch.l();
        let (zc, zy) = (l.solve_lower_triangular(&ntc).unwrap_or_else(|| ntc.clone()), l.solve_lower_triangular(&nty).unwrap_or_else(|| nty.clone()));
        let gc = &t.cc - tr_mul(&cf, &cf) - zc.tr_mul(&zc);
        let bc = &t.cy - tr_mul(&cf, &yf) - zc.tr_mul(&zy);
        let x = super::stats::solve_normal_equations(gc, bc, bounds).transpose()?;
        Ok(FoldFit { rows: r, ch, ntc, nty, x })
    }
}

/// Sums over every row, once for all folds: `N^T C`, `N^T y`, `C^T C`, `C^T y`.
struct Totals {
    nc: DMatrix<f64>,
    ny: DVector<f64>,
    cc: DMatrix<f64>,
    cy: DVector<f64>,
}

impl Totals {
    fn new(n: &DMatrix<f64>, c: &DMatrix<f64>, y: &DVector<f64>) -> Totals {
        Totals { nc: tr_mul(n, c), ny: tr_mul(n, y), cc: tr_mul(c, c), cy: tr_mul(c, y) }
    }
}

/// One fold's fit from the other parts ([`Nuisance::fold_fit`]).
struct FoldFit {
    rows: std::ops::Range<usize>,
    ch: Cholesky<f64, Dyn>,
    ntc: DMatrix<f64>,
    nty: DVector<f64>,
    x: Option<DVector<f64>>,
}
