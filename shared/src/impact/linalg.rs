//! Small dense linear algebra for the impact solver: square systems of at most
//! [`DIM`] unknowns (a normal and a tangential unknown per contact).
//!
//! A system `A x = b` is solved by LU with full pivoting, which also reveals its
//! rank. Where `A` is singular (more contacts than the motion can feel, the paper's
//! eq. (9)) but `b` lies in its range, the weighted minimum-norm solution is taken:
//!
//! ```text
//!   min x^T D^-1 x  subject to  A x = b,   D = diag(weights)
//! ```
//!
//! It is built from the LU factors that stopped at the rank `r` (Golub & Van Loan,
//! *Matrix Computations*, 4th ed., sec. 3.4.9 and 5.7): with row and column
//! permutations `P`, `Q`, `P A Q = L [U; 0]`, `U = [U11 U12]` of `r` rows, the
//! system reads `U x' = c` with `x' = Q^T x` and `c` the first `r` entries of
//! `L^-1 P b` (the others vanish when `b` is in the range). Then (Lagrange; Ben-Israel
//! & Greville, *Generalized Inverses*, ch. 3)
//!
//! ```text
//!   x' = D' U^T z,  (U D' U^T) z = c,   D' = Q^T D Q
//! ```
//!
//! with the `r x r` matrix `U D' U^T` factored by Cholesky. It is the same solution
//! as `x = D A^T z`, `(A D A^T) z = b` (the rows of `U` span those of `A`), without
//! starting over on the `n x n` matrix `A D A^T`.

use super::MAX_CONTACTS;
use crate::real::Real;

/// Largest system size: a normal and a tangential unknown per contact.
pub const DIM: usize = 2 * MAX_CONTACTS;

/// A square matrix of at most `DIM x DIM` (only the leading `n x n` block is used).
pub type Matrix<T> = [[T; DIM]; DIM];
/// A vector of at most `DIM` entries.
pub type Vector<T> = [T; DIM];

/// The relative tolerance below which a pivot counts as zero: `eps^(2/3)`
/// (3.7e-11 in `f64`, 2.4e-5 in `f32`), well above the rounding of a Delassus
/// matrix built from exact geometry and well below any physical coupling.
pub fn rank_tolerance<T: Real>() -> T {
    T::RANK_TOLERANCE
}

/// How a system was solved.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Solved {
    /// `A` had full rank: the unique solution.
    Unique,
    /// `A` was singular, `b` in its range: the weighted minimum-norm solution.
    MinimumNorm,
}

/// Solves the leading `n x n` block of `A x = b`, taking the weighted minimum-norm
/// solution where `A` is singular. Returns `None` where the system is inconsistent
/// (`b` not in the range of `A`) or a number is not finite.
pub fn solve_weighted<T: Real>(
    a: &Matrix<T>,
    b: &Vector<T>,
    weights: &Vector<T>,
    n: usize,
) -> Option<(Vector<T>, Solved)> {
    solve_weighted_in(a, b, weights, n)
}

/// [`solve_weighted`] in storage of `D x D` (`n <= D`): the same arithmetic in the
/// same order, with the copies and scratch matrices sized to the problem rather
/// than to [`DIM`] (a 4-contact system fits `D = 8`, a quarter of the storage).
pub fn solve_weighted_in<T: Real, const D: usize>(
    a: &[[T; D]; D],
    b: &[T; D],
    weights: &[T; D],
    n: usize,
) -> Option<([T; D], Solved)> {
    let mut x = [T::ZERO; D];
    let how = solve_weighted_into(a, b, weights, n, &mut x)?;
    Some((x, how))
}

/// [`solve_weighted_in`] into `x`: writes `x[..n]` only (the rest is left as it
/// is), so that the caller's storage is not copied back and forth. On `None`,
/// `x[..n]` is unspecified.
pub fn solve_weighted_into<T: Real, const D: usize>(
    a: &[[T; D]; D],
    b: &[T; D],
    weights: &[T; D],
    n: usize,
    x: &mut [T; D],
) -> Option<Solved> {
    if n == 0 {
        return Some(Solved::Unique);
    }
    // The scale and the first pivot in one pass over the block.
    let (scale, first_pivot) = scale_and_pivot(a, n);
    if scale == T::ZERO {
        // A = 0: consistent only for b = 0, and then x = 0 is the minimum norm.
        return if b[..n].iter().all(|v| *v == T::ZERO) {
            x[..n].fill(T::ZERO);
            Some(Solved::MinimumNorm)
        } else {
            None
        };
    }
    let mut lu = Lu {
        m: *a,
        rhs: *b,
        col_of: [0usize; D],
        n,
        rank: 0,
    };
    lu.factor(scale, first_pivot)?;
    if lu.rank == n {
        lu.back_substitute(x);
        return x[..n]
            .iter()
            .all(|v| v.is_finite())
            .then_some(Solved::Unique);
    }
    lu.minimum_norm(weights, x)?;
    // Accept only a consistent system: the residual must vanish to the tolerance.
    let b_scale = b[..n].iter().fold(T::ZERO, |m, v| m.max(v.abs()));
    let x_scale = x[..n].iter().fold(T::ZERO, |m, v| m.max(v.abs()));
    let tol = rank_tolerance::<T>() * (b_scale + scale * x_scale);
    for (row, bi) in a[..n].iter().zip(&b[..n]) {
        let mut r = -*bi;
        for (aij, xj) in row[..n].iter().zip(&x[..n]) {
            r += *aij * *xj;
        }
        if r.abs() > tol || !r.is_finite() {
            return None;
        }
    }
    Some(Solved::MinimumNorm)
}

/// Largest `|a_ij|` of the leading block (folded as `m.max(|a_ij|)`, row by row),
/// and the full pivot of the first step ([`largest_entry`] at `k = 0`): one pass.
fn scale_and_pivot<T: Real, const D: usize>(a: &[[T; D]; D], n: usize) -> (T, Pivot<T>) {
    let mut m = T::ZERO;
    let mut pivot = Pivot {
        row: 0,
        col: 0,
        size: T::ZERO,
    };
    for (i, row) in a[..n].iter().enumerate() {
        for (j, v) in row[..n].iter().enumerate() {
            let v = v.abs();
            m = m.max(v);
            if v > pivot.size {
                pivot = Pivot {
                    row: i,
                    col: j,
                    size: v,
                };
            }
        }
    }
    (m, pivot)
}

/// A full pivot: its row, column and magnitude.
#[derive(Clone, Copy)]
struct Pivot<T> {
    row: usize,
    col: usize,
    size: T,
}

/// Gaussian elimination with full pivoting, stopped at the numerical rank.
struct Lu<T, const D: usize> {
    /// Rows `0..rank`: `U` (upper trapezoidal, in permuted columns); below them
    /// the remainder, every entry within the tolerance.
    m: [[T; D]; D],
    /// `L^-1 P b`.
    rhs: [T; D],
    /// Column `k` of the permuted system is unknown `col_of[k]` of the original.
    col_of: [usize; D],
    n: usize,
    /// Pivots above `rank_tolerance * scale`.
    rank: usize,
}

impl<T: Real, const D: usize> Lu<T, D> {
    /// Factors the leading `n x n` block in place, stopping at the first pivot at or
    /// below `rank_tolerance * scale`; `pivot` is the first step's. Each step's
    /// elimination finds the next step's pivot as it writes the rows (the same
    /// entries in the same order as a separate search). `None` on a non-finite
    /// pivot.
    fn factor(&mut self, scale: T, mut pivot: Pivot<T>) -> Option<()> {
        let n = self.n;
        for (k, c) in self.col_of[..n].iter_mut().enumerate() {
            *c = k;
        }
        let tol = rank_tolerance::<T>() * scale;
        for k in 0..n {
            let Pivot {
                row: pr,
                col: pc,
                size: best,
            } = pivot;
            if !best.is_finite() {
                return None;
            }
            if best <= tol {
                break;
            }
            self.m.swap(k, pr);
            self.rhs.swap(k, pr);
            if pc != k {
                for row in &mut self.m[..n] {
                    row.swap(k, pc);
                }
                self.col_of.swap(k, pc);
            }
            pivot = eliminate_below(&mut self.m, &mut self.rhs, k, n);
            self.rank = k + 1;
        }
        Some(())
    }

    /// The unique solution of a full-rank block: back substitution, then the
    /// column permutation undone.
    fn back_substitute(&self, x: &mut [T; D]) {
        let (m, n) = (&self.m, self.n);
        let mut y = [T::ZERO; D];
        for k in (0..n).rev() {
            let mut s = self.rhs[k];
            for (mkj, yj) in m[k][k + 1..n].iter().zip(&y[k + 1..n]) {
                s -= *mkj * *yj;
            }
            y[k] = s / m[k][k];
        }
        for (c, yk) in self.col_of[..n].iter().zip(&y[..n]) {
            x[*c] = *yk;
        }
    }

    /// The weighted minimum-norm solution of `U x' = c` (module docs):
    /// `H = U D' U^T` (`r x r`), `H = R R^T` by Cholesky, `H z = c`,
    /// `x' = D' U^T z`. `None` on a non-positive or non-finite Cholesky pivot.
    fn minimum_norm(&mut self, weights: &[T; D], x: &mut [T; D]) -> Option<()> {
        let (u, n, r) = (&self.m, self.n, self.rank);
        let mut w = [T::ZERO; D];
        for (wk, c) in w[..n].iter_mut().zip(&self.col_of[..n]) {
            *wk = weights[*c];
        }
        // H_ab = sum_j U_aj D'_j U_bj over j >= max(a, b) (U is zero left of its
        // diagonal), then its Cholesky factor in place (lower triangle).
        let mut h = [[T::ZERO; D]; D];
        for a in 0..r {
            for b in 0..=a {
                let mut s = T::ZERO;
                for j in a..n {
                    s += u[a][j] * w[j] * u[b][j];
                }
                h[a][b] = s;
            }
        }
        cholesky_in_place(&mut h, r)?;
        // z in place of c (the factors are not used again).
        let z = &mut self.rhs;
        cholesky_solve(&h, r, z);
        // x' = D' U^T z; x[col_of[j]] = x'_j.
        for j in 0..n {
            let mut s = T::ZERO;
            for a in 0..r.min(j + 1) {
                s += u[a][j] * z[a];
            }
            let xj = w[j] * s;
            if !xj.is_finite() {
                return None;
            }
            x[self.col_of[j]] = xj;
        }
        Some(())
    }
}

/// `H = R R^T` in the lower triangle of the leading `r x r` block (Golub & Van Loan,
/// alg. 4.2.1). `None` where a pivot is not positive and finite.
fn cholesky_in_place<T: Real, const D: usize>(h: &mut [[T; D]; D], r: usize) -> Option<()> {
    for k in 0..r {
        let mut d = h[k][k];
        for m in 0..k {
            d -= h[k][m] * h[k][m];
        }
        if d <= T::ZERO || !d.is_finite() {
            return None;
        }
        let rkk = d.sqrt();
        h[k][k] = rkk;
        for i in (k + 1)..r {
            let mut s = h[i][k];
            for m in 0..k {
                s -= h[i][m] * h[k][m];
            }
            h[i][k] = s / rkk;
        }
    }
    Some(())
}

/// Solves `R R^T z = c` in place on the first `r` entries (forward, then back
/// substitution with the factor of [`cholesky_in_place`]).
fn cholesky_solve<T: Real, const D: usize>(h: &[[T; D]; D], r: usize, z: &mut [T; D]) {
    for k in 0..r {
        let mut s = z[k];
        for m in 0..k {
            s -= h[k][m] * z[m];
        }
        z[k] = s / h[k][k];
    }
    for k in (0..r).rev() {
        let mut s = z[k];
        for m in (k + 1)..r {
            s -= h[m][k] * z[m];
        }
        z[k] = s / h[k][k];
    }
}

/// The full pivot of step `k`: the largest `|m_ij|` with `i, j` in `k..n` (the
/// first one met, row by row), as (row, column, magnitude). The reference for the
/// search that [`eliminate_below`] does as it goes (tests).
#[cfg(test)]
fn largest_entry<T: Real, const D: usize>(
    m: &[[T; D]; D],
    k: usize,
    n: usize,
) -> (usize, usize, T) {
    let (mut pr, mut pc, mut best) = (k, k, T::ZERO);
    for (i, row) in m[k..n].iter().enumerate() {
        for (j, v) in row[k..n].iter().enumerate() {
            if v.abs() > best {
                best = v.abs();
                pr = k + i;
                pc = k + j;
            }
        }
    }
    (pr, pc, best)
}

/// Eliminates column `k` below the pivot `m_kk` from the rows `k+1..n` and the
/// right-hand side, and returns the pivot of step `k + 1`: the largest `|m_ij|`
/// with `i, j` in `k+1..n`, the first one met row by row (each row is searched
/// once it is written).
fn eliminate_below<T: Real, const D: usize>(
    m: &mut [[T; D]; D],
    rhs: &mut [T; D],
    k: usize,
    n: usize,
) -> Pivot<T> {
    let mut pivot = Pivot {
        row: k + 1,
        col: k + 1,
        size: T::ZERO,
    };
    let (upper, lower) = m.split_at_mut(k + 1);
    let pivot_row = &upper[k];
    let pk = pivot_row[k];
    let rk = rhs[k];
    for (i, (row, ri)) in lower[..n - k - 1]
        .iter_mut()
        .zip(&mut rhs[k + 1..n])
        .enumerate()
    {
        let f = row[k] / pk;
        if f != T::ZERO {
            for (mij, mkj) in row[k + 1..n].iter_mut().zip(&pivot_row[k + 1..n]) {
                *mij -= f * *mkj;
            }
            *ri -= f * rk;
        }
        row[k] = T::ZERO;
        for (j, v) in row[k + 1..n].iter().enumerate() {
            let v = v.abs();
            if v > pivot.size {
                pivot = Pivot {
                    row: k + 1 + i,
                    col: k + 1 + j,
                    size: v,
                };
            }
        }
    }
    pivot
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mat(rows: &[&[f64]]) -> Matrix<f64> {
        let mut m = [[0.0; DIM]; DIM];
        for (i, r) in rows.iter().enumerate() {
            for (j, v) in r.iter().enumerate() {
                m[i][j] = *v;
            }
        }
        m
    }

    fn vec(v: &[f64]) -> Vector<f64> {
        let mut out = [0.0; DIM];
        out[..v.len()].copy_from_slice(v);
        out
    }

    #[test]
    fn rank_tolerance_is_eps_to_two_thirds() {
        assert!((f64::RANK_TOLERANCE / f64::EPSILON.powf(2.0 / 3.0) - 1.0).abs() < 1e-12);
        assert!((f32::RANK_TOLERANCE / f32::EPSILON.powf(2.0 / 3.0) - 1.0).abs() < 1e-6);
    }

    #[test]
    fn full_rank_system_matches_cramer() {
        // [2 1; 1 3] x = [3; 5]: det 5, x = [(9-5)/5, (10-3)/5] = [0.8, 1.4].
        let a = mat(&[&[2.0, 1.0], &[1.0, 3.0]]);
        let (x, how) = solve_weighted(&a, &vec(&[3.0, 5.0]), &vec(&[1.0, 1.0]), 2).unwrap();
        assert_eq!(how, Solved::Unique);
        assert!((x[0] - 0.8).abs() < 1e-15 && (x[1] - 1.4).abs() < 1e-15);
    }

    #[test]
    fn rank_one_system_takes_weighted_minimum_norm() {
        // A = l l^T with l = [1, 2, 3]: A x = b with b = l * c has solutions with
        // l.x = c; the minimum of sum x_i^2 / w_i is x_i = w_i l_i c / sum(w l^2).
        let l = [1.0, 2.0, 3.0];
        let w = [1.0, 0.5, 2.0];
        let mut a = [[0.0; DIM]; DIM];
        for i in 0..3 {
            for j in 0..3 {
                a[i][j] = l[i] * l[j];
            }
        }
        let c = 1.7;
        let b = vec(&[l[0] * c, l[1] * c, l[2] * c]);
        let (x, how) = solve_weighted(&a, &b, &vec(&w), 3).unwrap();
        assert_eq!(how, Solved::MinimumNorm);
        let s: f64 = (0..3).map(|i| w[i] * l[i] * l[i]).sum();
        for i in 0..3 {
            assert!((x[i] - w[i] * l[i] * c / s).abs() < 1e-12, "{x:?}");
        }
    }

    /// The pivots found along the elimination and in the first pass are the ones a
    /// separate search finds (the same entry, ties to the first met).
    #[test]
    fn fused_pivot_search_matches_a_separate_search() {
        let mut a = [[0.0; DIM]; DIM];
        let n = 7;
        let mut v = 0.37f64;
        for (i, row) in a.iter_mut().enumerate().take(n) {
            for (j, x) in row.iter_mut().enumerate().take(n) {
                v = (v * 3.7 + 0.11).fract();
                // Ties: repeat some magnitudes with both signs.
                *x = if (i + j) % 3 == 0 { 0.5 } else { v - 0.5 };
                if (i * j) % 4 == 1 {
                    *x = -0.5;
                }
            }
        }
        let (scale, first) = scale_and_pivot(&a, n);
        assert_eq!(scale, max_abs_reference(&a, n));
        assert_eq!((first.row, first.col, first.size), largest_entry(&a, 0, n));
        let mut m = a;
        let mut rhs = [0.0; DIM];
        let mut pivot = first;
        for k in 0..n - 1 {
            let (pr, pc) = (pivot.row, pivot.col);
            m.swap(k, pr);
            if pc != k {
                for row in &mut m[..n] {
                    row.swap(k, pc);
                }
            }
            pivot = eliminate_below(&mut m, &mut rhs, k, n);
            assert_eq!(
                (pivot.row, pivot.col, pivot.size),
                largest_entry(&m, k + 1, n),
                "step {k}"
            );
        }
    }

    fn max_abs_reference(a: &Matrix<f64>, n: usize) -> f64 {
        let mut m = 0.0f64;
        for row in &a[..n] {
            for v in &row[..n] {
                m = Real::max(m, v.abs());
            }
        }
        m
    }

    #[test]
    fn inconsistent_singular_system_is_refused() {
        let a = mat(&[&[1.0, 1.0], &[1.0, 1.0]]);
        assert!(solve_weighted(&a, &vec(&[1.0, 2.0]), &vec(&[1.0, 1.0]), 2).is_none());
    }
}
