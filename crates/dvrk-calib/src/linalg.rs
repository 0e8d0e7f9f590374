//! Products of tall matrices (a recording's rows, tens of thousands, by a few to a hundred
//! columns), taken over blocks of rows. nalgebra's `tr_mul`, and its `*` when a factor has five
//! columns or fewer, take one dot product or one column update at a time over the whole height,
//! reading the tall factor once per column of the other: on a matrix larger than the cache that
//! is one pass over memory per column. Here each block of rows is read once and used for every
//! column while it is in the cache; a product of wider factors goes to nalgebra's kernel.

use nalgebra::{allocator::Allocator, DefaultAllocator, Dim, Matrix, OMatrix, Storage};

/// Rows per block: 512 rows of a hundred columns (400 kB) stay in a core's cache.
const BLOCK: usize = 512;

/// nalgebra hands a product to its blocked kernel (matrixmultiply) when no side is this small
/// or smaller; with a side this small the product is a few columns, done here by blocks of rows.
const SMALL: usize = 5;

/// `A^T B` (`A`: n x k, `B`: n x m): a k x m matrix (a `DVector` for a vector `B`).
pub fn tr_mul<RA: Dim, CA: Dim, SA, RB: Dim, CB: Dim, SB>(a: &Matrix<f64, RA, CA, SA>, b: &Matrix<f64, RB, CB, SB>) -> OMatrix<f64, CA, CB>
where
    SA: Storage<f64, RA, CA>,
    SB: Storage<f64, RB, CB>,
    DefaultAllocator: Allocator<CA, CB>,
{
    let (n, k, m) = (a.nrows(), a.ncols(), b.ncols());
    assert_eq!(n, b.nrows(), "tr_mul: {n} rows against {}", b.nrows());
    let mut out = OMatrix::<f64, CA, CB>::zeros_generic(a.shape_generic().1, b.shape_generic().1);
    if k > SMALL && m > SMALL {
        // nalgebra's blocked kernel (matrixmultiply) takes products with no side of `SMALL` or
        // less: `(B^T A)^T`, at the cost of one copy of `B`.
        let p = b.view((0, 0), (n, m)).transpose() * a.view((0, 0), (n, k));
        for (j, mut col) in out.column_iter_mut().enumerate() {
            col.iter_mut().enumerate().for_each(|(i, x)| *x = p[(j, i)]);
        }
        return out;
    }
    for start in (0..n).step_by(BLOCK) {
        let len = BLOCK.min(n - start);
        for j in 0..m {
            let bj = b.column(j);
            let bj = bj.rows(start, len);
            for i in 0..k {
                out[(i, j)] += a.column(i).rows(start, len).dot(&bj);
            }
        }
    }
    out
}

/// `A B` (`A`: n x k tall, `B`: k x m small): an n x m matrix (a `DVector` for a vector `B`).
pub fn mul<RA: Dim, CA: Dim, SA, RB: Dim, CB: Dim, SB>(a: &Matrix<f64, RA, CA, SA>, b: &Matrix<f64, RB, CB, SB>) -> OMatrix<f64, RA, CB>
where
    SA: Storage<f64, RA, CA>,
    SB: Storage<f64, RB, CB>,
    DefaultAllocator: Allocator<RA, CB>,
{
    let (n, k, m) = (a.nrows(), a.ncols(), b.ncols());
    assert_eq!(k, b.nrows(), "mul: {k} columns against {} rows", b.nrows());
    let mut out = OMatrix::<f64, RA, CB>::zeros_generic(a.shape_generic().0, b.shape_generic().1);
    if k > SMALL && m > SMALL {
        let p = a.view((0, 0), (n, k)) * b.view((0, 0), (k, m));
        out.iter_mut().zip(p.iter()).for_each(|(o, x)| *o = *x);
        return out;
    }
    for start in (0..n).step_by(BLOCK) {
        let len = BLOCK.min(n - start);
        for j in 0..m {
            let mut oj = out.column_mut(j);
            let mut oj = oj.rows_mut(start, len);
            for l in 0..k {
                oj.axpy(b[(l, j)], &a.column(l).rows(start, len), 1.0);
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{DMatrix, DVector};

    fn filled(n: usize, m: usize, seed: f64) -> DMatrix<f64> {
        DMatrix::from_fn(n, m, |i, j| ((i * 31 + j * 17) as f64 * seed).sin())
    }

    #[test]
    fn the_blocked_products_are_nalgebras() {
        for n in [3, 300, 1000] {
            let (a, b) = (filled(n, 7, 0.37), filled(n, 3, 0.11));
            let y = DVector::from_fn(n, |i, _| (i as f64 * 0.7).cos());
            assert!((tr_mul(&a, &b) - a.tr_mul(&b)).amax() < 1e-9 * n as f64);
            assert!((tr_mul(&a, &y) - a.tr_mul(&y)).amax() < 1e-9 * n as f64);
            // Wider factors, through nalgebra's kernel.
            let w = filled(n, 9, 0.23);
            assert!((tr_mul(&a, &w) - a.tr_mul(&w)).amax() < 1e-9 * n as f64);
            assert!((mul(&a, &filled(7, 8, 0.3)) - &a * filled(7, 8, 0.3)).amax() < 1e-12 * n as f64);
            // Views with row strides: the first and last rows of a taller matrix.
            let (av, bv) = (a.rows(1, n - 2), b.rows(1, n - 2));
            assert!((tr_mul(&av, &bv) - av.tr_mul(&bv)).amax() < 1e-9 * n as f64);
            let x = filled(7, 2, 0.5);
            assert!((mul(&a, &x) - &a * &x).amax() < 1e-12 * n as f64);
            assert!((mul(&av, &x.column(1)) - av * x.column(1)).amax() < 1e-12 * n as f64);
        }
    }
}
