//! Small dense linear algebra for the impact solver: square systems of at most
//! [`DIM`] unknowns (a normal and a tangential unknown per contact).
//!
//! A system `A x = b` is solved by LU with full pivoting, which also reveals its
//! rank. Where `A` is singular (more contacts than the motion can feel, the paper's
//! eq. (9)) but `b` lies in its range, the weighted minimum-norm solution is taken:
//!
//! ```text
//!   min x^T D^-1 x  subject to  A x = b,   D = diag(weights)
//!   =>  x = D A^T z,  (A D A^T) z = b
//! ```
//!
//! (Lagrange; Ben-Israel & Greville, *Generalized Inverses*, ch. 3), with
//! `A D A^T` factored by Cholesky with diagonal pivoting, truncated at its rank.

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
    if n == 0 {
        return Some((x, Solved::Unique));
    }
    let scale = max_abs(a, n);
    if scale == T::ZERO {
        // A = 0: consistent only for b = 0, and then x = 0 is the minimum norm.
        return if b[..n].iter().all(|v| *v == T::ZERO) {
            Some((x, Solved::MinimumNorm))
        } else {
            None
        };
    }
    if lu_full_pivot(a, b, n, scale, &mut x) {
        return Some((x, Solved::Unique));
    }
    minimum_norm(a, b, weights, n, &mut x)?;
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
    Some((x, Solved::MinimumNorm))
}

/// Largest `|a_ij|` of the leading block.
fn max_abs<T: Real, const D: usize>(a: &[[T; D]; D], n: usize) -> T {
    let mut m = T::ZERO;
    for row in &a[..n] {
        for v in &row[..n] {
            m = m.max(v.abs());
        }
    }
    m
}

/// Gaussian elimination with full pivoting. Writes the solution and returns true
/// when the block has full rank (every pivot above `rank_tolerance * scale`).
fn lu_full_pivot<T: Real, const D: usize>(
    a: &[[T; D]; D],
    b: &[T; D],
    n: usize,
    scale: T,
    x: &mut [T; D],
) -> bool {
    let mut m = *a;
    let mut rhs = *b;
    let mut col_of = [0usize; D];
    for (k, c) in col_of[..n].iter_mut().enumerate() {
        *c = k;
    }
    let tol = rank_tolerance::<T>() * scale;
    for k in 0..n {
        let (pr, pc, best) = largest_entry(&m, k, n);
        if best <= tol || !best.is_finite() {
            return false;
        }
        m.swap(k, pr);
        rhs.swap(k, pr);
        if pc != k {
            for row in &mut m[..n] {
                row.swap(k, pc);
            }
            col_of.swap(k, pc);
        }
        eliminate_below(&mut m, &mut rhs, k, n);
    }
    // Back substitution, then undo the column permutation.
    let mut y = [T::ZERO; D];
    for k in (0..n).rev() {
        let mut s = rhs[k];
        for (mkj, yj) in m[k][k + 1..n].iter().zip(&y[k + 1..n]) {
            s -= *mkj * *yj;
        }
        y[k] = s / m[k][k];
    }
    for (c, yk) in col_of[..n].iter().zip(&y[..n]) {
        x[*c] = *yk;
    }
    x[..n].iter().all(|v| v.is_finite())
}

/// The full pivot of step `k`: the largest `|m_ij|` with `i, j` in `k..n` (the
/// first one met, row by row), as (row, column, magnitude).
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
/// right-hand side.
fn eliminate_below<T: Real, const D: usize>(
    m: &mut [[T; D]; D],
    rhs: &mut [T; D],
    k: usize,
    n: usize,
) {
    let (upper, lower) = m.split_at_mut(k + 1);
    let pivot_row = &upper[k];
    let pivot = pivot_row[k];
    let rk = rhs[k];
    for (row, ri) in lower[..n - k - 1].iter_mut().zip(&mut rhs[k + 1..n]) {
        let f = row[k] / pivot;
        if f != T::ZERO {
            for (mij, mkj) in row[k + 1..n].iter_mut().zip(&pivot_row[k + 1..n]) {
                *mij -= f * *mkj;
            }
            *ri -= f * rk;
        }
        row[k] = T::ZERO;
    }
}

/// Weighted minimum-norm solution `x = D A^T z`, `(A D A^T) z = b`, by pivoted
/// Cholesky truncated at the numerical rank. Returns `None` on non-finite numbers.
fn minimum_norm<T: Real, const D: usize>(
    a: &[[T; D]; D],
    b: &[T; D],
    weights: &[T; D],
    n: usize,
    x: &mut [T; D],
) -> Option<()> {
    let g = weighted_gram(a, weights, n);
    // Pivoted Cholesky: P^T G P = L L^T, stopping where the remaining diagonal
    // falls below the tolerance (the rank r).
    let mut perm = [0usize; D];
    for (k, p) in perm[..n].iter_mut().enumerate() {
        *p = k;
    }
    let g_scale = (0..n).fold(T::ZERO, |m, i| m.max(g[i][i]));
    let tol = rank_tolerance::<T>() * g_scale;
    let mut l = [[T::ZERO; D]; D];
    let mut rank = 0;
    for k in 0..n {
        // Remaining diagonal d_i = G_ii - sum_{m<k} L_im^2, choose the largest.
        let mut best = k;
        let mut best_d = -T::ONE;
        for i in k..n {
            let pi = perm[i];
            let mut d = g[pi][pi];
            for lm in &l[i][..k] {
                d -= *lm * *lm;
            }
            if d > best_d {
                best_d = d;
                best = i;
            }
        }
        if best_d <= tol || !best_d.is_finite() {
            break;
        }
        perm.swap(k, best);
        l.swap(k, best);
        let lkk = best_d.sqrt();
        l[k][k] = lkk;
        let (upper, lower) = l.split_at_mut(k + 1);
        let lk = &upper[k];
        for (li, pi) in lower[..n - k - 1].iter_mut().zip(&perm[k + 1..n]) {
            let mut s = g[*pi][perm[k]];
            for (lim, lkm) in li[..k].iter().zip(&lk[..k]) {
                s -= *lim * *lkm;
            }
            li[k] = s / lkk;
        }
        rank = k + 1;
    }
    // Solve L11 L11^T z1 = b1 on the first `rank` pivots, z2 = 0.
    let mut z = [T::ZERO; D];
    for k in 0..rank {
        let mut s = b[perm[k]];
        for m in 0..k {
            s -= l[k][m] * z[m];
        }
        z[k] = s / l[k][k];
    }
    for k in (0..rank).rev() {
        let mut s = z[k];
        for m in (k + 1)..rank {
            s -= l[m][k] * z[m];
        }
        z[k] = s / l[k][k];
    }
    let mut zf = [T::ZERO; D];
    for k in 0..rank {
        zf[perm[k]] = z[k];
    }
    // x = D A^T z.
    for (j, xj) in x[..n].iter_mut().enumerate() {
        let mut s = T::ZERO;
        for (row, zi) in a[..n].iter().zip(&zf[..n]) {
            s += row[j] * *zi;
        }
        *xj = weights[j] * s;
        if !xj.is_finite() {
            return None;
        }
    }
    Some(())
}

/// `G = A D A^T` of the leading block (symmetric, positive semi-definite).
fn weighted_gram<T: Real, const D: usize>(
    a: &[[T; D]; D],
    weights: &[T; D],
    n: usize,
) -> [[T; D]; D] {
    let mut g = [[T::ZERO; D]; D];
    for i in 0..n {
        for j in 0..=i {
            let mut s = T::ZERO;
            for ((aik, wk), ajk) in a[i][..n].iter().zip(&weights[..n]).zip(&a[j][..n]) {
                s += *aik * *wk * *ajk;
            }
            g[i][j] = s;
            g[j][i] = s;
        }
    }
    g
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

    #[test]
    fn inconsistent_singular_system_is_refused() {
        let a = mat(&[&[1.0, 1.0], &[1.0, 1.0]]);
        assert!(solve_weighted(&a, &vec(&[1.0, 2.0]), &vec(&[1.0, 1.0]), 2).is_none());
    }
}
