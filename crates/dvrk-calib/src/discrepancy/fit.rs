//! Least squares on the analysed rows, with or without the inertia nuisance: the one place that
//! knows how a residual's size, a bounded fit and a held-out prediction are taken.

use super::candidates::Table;
use super::nuisance::{fold_rows, Nuisance, FOLDS};
use super::signals::Prepared;
use super::signature::Series;
use super::stats::{bounded_least_squares, solve_normal_equations, Bounds};
use crate::error::Result;
use crate::linalg::tr_mul;
use nalgebra::{DMatrix, DVector};

/// Rows (train or held out) of the active joints, each divided by its noise floor, sample-major.
pub struct Rows<'a> {
    pub prep: &'a Prepared,
    pub range: std::ops::Range<usize>,
}

impl<'a> Rows<'a> {
    pub fn train(prep: &'a Prepared) -> Self {
        Rows { prep, range: 0..prep.split }
    }
    pub fn held_out(prep: &'a Prepared) -> Self {
        Rows { prep, range: prep.split..prep.t.len() }
    }
    pub fn len(&self) -> usize {
        self.range.len() * self.prep.active.len()
    }
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    pub fn vector<S: Series>(&self, t: &S) -> DVector<f64> {
        let p = self.prep;
        DVector::from_iterator(self.len(), self.range.clone().flat_map(|i| p.active.iter().map(move |&k| t.at(i, k) / p.floor[k])))
    }
    pub fn matrix<S: Series>(&self, columns: &[S]) -> DMatrix<f64> {
        // A column at a time: all of them as vectors first would hold the matrix twice.
        let mut m = DMatrix::zeros(self.len(), columns.len());
        for (c, col) in columns.iter().enumerate() {
            m.set_column(c, &self.vector(col));
        }
        m
    }
    /// The per-joint time series of a row vector (for the autocorrelation).
    pub fn series(&self, v: &DVector<f64>) -> Vec<Vec<f64>> {
        let na = self.prep.active.len();
        (0..na).map(|a| (0..self.range.len()).map(|i| v[i * na + a]).collect()).collect()
    }
}

/// Fits in the metric the nuisance leaves (plain least squares without it).
pub struct Fitter<'a> {
    pub prep: &'a Prepared,
    pub nuisance: Option<&'a Nuisance>,
    /// The nuisance fitted to the last few training vectors, and their whitening where taken
    /// ([`Fitter::theta`], [`Fitter::whitened`]).
    memo: std::sync::Mutex<Vec<Memo>>,
}

/// Training vectors whose nuisance fit is kept: every candidate of a round is scored against
/// the same residual, and its own refit's residual is whitened and held out in turn.
const MEMO: usize = 4;

/// A training vector, the nuisance fitted to it, and its whitened self once asked for.
struct Memo {
    v: DVector<f64>,
    theta: DVector<f64>,
    white: Option<DVector<f64>>,
}

impl<'a> Fitter<'a> {
    pub fn new(prep: &'a Prepared, nuisance: Option<&'a Nuisance>) -> Self {
        Fitter { prep, nuisance, memo: Default::default() }
    }
}

impl Fitter<'_> {
    /// `read` of training vector `v`'s entry (the nuisance fitted to it), made if not kept: each
    /// fit reads the nuisance's whole matrix, larger than the cache.
    fn memo<T>(&self, n: &Nuisance, v: &DVector<f64>, read: impl FnOnce(&mut Memo) -> T) -> T {
        let mut memo = self.memo.lock().unwrap_or_else(|e| e.into_inner());
        let at = match memo.iter().position(|m| &m.v == v) {
            Some(at) => at,
            None => {
                if memo.len() == MEMO {
                    memo.remove(0);
                }
                memo.push(Memo { v: v.clone(), theta: n.theta(v), white: None });
                memo.len() - 1
            }
        };
        read(&mut memo[at])
    }

    /// The nuisance fitted to training vector `v` (scaled units).
    fn theta(&self, n: &Nuisance, v: &DVector<f64>) -> DVector<f64> {
        self.memo(n, v, |m| m.theta.clone())
    }

    /// Squared size of a training residual, the nuisance refitted to it.
    pub fn rss(&self, v: &DVector<f64>) -> f64 {
        match self.nuisance {
            Some(n) => n.wnorm2(v),
            None => v.norm_squared(),
        }
    }

    /// `C^T W C`, `C^T W y` on the training rows.
    pub fn normal_equations(&self, c: &DMatrix<f64>, y: &DVector<f64>) -> (DMatrix<f64>, DVector<f64>) {
        match self.nuisance {
            Some(n) => n.normal_equations(c, y),
            None => (tr_mul(c, c), tr_mul(c, y)),
        }
    }

    /// `min |y - C x|` with `bounds` on `x`, the nuisance refitted.
    pub fn solve(&self, c: &DMatrix<f64>, y: &DVector<f64>, bounds: &[Bounds]) -> Result<DVector<f64>> {
        if self.nuisance.is_none() {
            return bounded_least_squares(c, y, bounds);
        }
        let (g, b) = self.normal_equations(c, y);
        solve_normal_equations(g, b, bounds).unwrap_or_else(|| bounded_least_squares(c, y, bounds))
    }

    /// [`Fitter::solve`] with `g = C^T W C` ([`Fitter::normal_equations`]) and `wy = W y`
    /// ([`Fitter::whitened`]) given: the same fit without projecting `C` again (a bootstrap
    /// refits one `C` to many `y`; `C^T W y = C^T wy`, `W` being a projection).
    pub fn solve_given(&self, g: &DMatrix<f64>, c: &DMatrix<f64>, y: &DVector<f64>, wy: &DVector<f64>, bounds: &[Bounds]) -> Result<DVector<f64>> {
        if self.nuisance.is_none() {
            return bounded_least_squares(c, y, bounds);
        }
        solve_normal_equations(g.clone(), tr_mul(c, wy), bounds).unwrap_or_else(|| bounded_least_squares(c, y, bounds))
    }

    /// Columns `C` (training rows) with the nuisance's fit taken out of each: `W C`.
    pub fn whitened_columns(&self, c: &DMatrix<f64>) -> DMatrix<f64> {
        match self.nuisance {
            Some(n) => n.whitened_columns(c),
            None => c.clone(),
        }
    }

    /// The training residual with the nuisance's fit taken out (what is left to look white).
    pub fn whitened(&self, v: &DVector<f64>) -> DVector<f64> {
        match self.nuisance {
            Some(n) => self.memo(n, v, |m| m.white.get_or_insert_with(|| v - n.predict(&m.theta, 0, v.len())).clone()),
            None => v.clone(),
        }
    }
}

/// The likelihood-ratio statistic of residuals `e0` (null) against `e1` (alternative), both
/// already cleared of the nuisance ([`Fitter::whitened`], or held out), with a variance and an
/// effective sample size per joint (a joint the model misses badly does not drown the evidence
/// on another): `sum_k n_eff,k ln(rss0_k / rss1_k)`, and the total effective sample size.
pub fn per_joint_ratio(rows: &Rows, e0: &DVector<f64>, e1: &DVector<f64>) -> (f64, f64) {
    let (w0, w1) = (rows.series(e0), rows.series(e1));
    let (mut stat, mut n_eff) = (0.0, 0.0);
    for (a, b) in w0.iter().zip(&w1) {
        let (r0, r1): (f64, f64) = (a.iter().map(|x| x * x).sum(), b.iter().map(|x| x * x).sum());
        let n = b.len() as f64 * super::stats::effective_fraction(std::slice::from_ref(b));
        if r1 > 0.0 && r0 > 0.0 {
            stat += n * (r0 / r1).ln();
        }
        n_eff += n;
    }
    (stat.max(0.0), n_eff)
}

impl Fitter<'_> {
    /// A held-out residual `h` with the nuisance fitted to training residual `v` taken out.
    pub fn held_out(&self, v: &DVector<f64>, h: &DVector<f64>) -> DVector<f64> {
        match self.nuisance {
            Some(n) => h - n.predict(&self.theta(n, v), v.len(), h.len()),
            None => h.clone(),
        }
    }

    /// The inertial parameters' change the nuisance fits to training residual `v`
    /// ([`Nuisance::parameters`]); `None` without a nuisance.
    pub fn nuisance_parameters(&self, v: &DVector<f64>) -> Option<DVector<f64>> {
        self.nuisance.map(|n| n.parameters(&self.theta(n, v)))
    }

    /// The nuisance fitted to training residual `v`, as efforts `[sample][joint]` at every sample
    /// (zero on joints that are not analysed; all zero without a nuisance).
    pub fn nuisance_effort(&self, v: &DVector<f64>) -> Table {
        let p = self.prep;
        let nq = p.q.first().map_or(0, |r| r.len());
        let mut out = vec![vec![0.0; nq]; p.t.len()];
        if let Some(n) = self.nuisance {
            let na = p.active.len();
            let all = n.predict(&self.theta(n, v), 0, p.t.len() * na);
            for (i, row) in out.iter_mut().enumerate() {
                for (a, &k) in p.active.iter().enumerate() {
                    row[k] = all[i * na + a] * p.floor[k];
                }
            }
        }
        out
    }
}

impl Fitter<'_> {
    /// The held-out likelihood-ratio statistic over the whole recording: each of
    /// [`FOLDS`] contiguous parts predicted from the others, without and with `columns`
    /// (bounded by `bounds`), the nuisance refitted each time; and the total effective sample size.
    pub fn cross_validated<S: Series>(&self, r: &Table, columns: &[S], bounds: &[Bounds]) -> Result<(f64, f64)> {
        let all = Rows { prep: self.prep, range: 0..self.prep.t.len() };
        let (y, c) = (all.vector(r), all.matrix(columns));
        let (e0, e1) = match self.nuisance {
            Some(n) => n.cross_validated(&y, &c, bounds)?,
            None => {
                let mut e1 = DVector::zeros(y.len());
                for f in 0..FOLDS {
                    let part = fold_rows(f, self.prep.t.len(), self.prep.active.len());
                    let keep: Vec<usize> = (0..y.len()).filter(|i| !part.contains(i)).collect();
                    let x = bounded_least_squares(&c.select_rows(&keep), &y.select_rows(&keep), bounds)?;
                    e1.rows_mut(part.start, part.len()).copy_from(&(y.rows(part.start, part.len()) - c.rows(part.start, part.len()) * x));
                }
                (y, e1)
            }
        };
        Ok(per_joint_ratio(&all, &e0, &e1))
    }

    /// `columns`' fit (bounded by `bounds`) to residual `r` on all of the recording but each of
    /// [`FOLDS`] contiguous parts in turn, the nuisance refitted each time; `None` for a part
    /// without which the columns are not determined.
    pub fn fold_fits<S: Series>(&self, r: &Table, columns: &[S], bounds: &[Bounds]) -> Result<Vec<Option<DVector<f64>>>> {
        let all = Rows { prep: self.prep, range: 0..self.prep.t.len() };
        let (y, c) = (all.vector(r), all.matrix(columns));
        match self.nuisance {
            Some(n) => n.fold_fits(&y, &c, bounds),
            None => (0..FOLDS)
                .map(|f| {
                    let part = fold_rows(f, self.prep.t.len(), self.prep.active.len());
                    let keep: Vec<usize> = (0..y.len()).filter(|i| !part.contains(i)).collect();
                    bounded_least_squares(&c.select_rows(&keep), &y.select_rows(&keep), bounds).map(Some)
                })
                .collect(),
        }
    }
}
