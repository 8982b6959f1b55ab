//! How well the measurements fix the fitted keys: standard errors from the
//! Jacobian at the optimum, and which keys they cannot identify
//! (docs/calibration.md, "Uncertainty and identifiability").
//!
//! With the weighted residuals `r = W^(1/2) (v_sim - v_meas)` and their Jacobian
//! `J = d r / d u` (`n x p`, normalised coordinates; `J^T J = J_raw^T W J_raw`),
//! the linearised least-squares covariance (Seber & Wild, *Nonlinear Regression*,
//! 1989, eq. 2.21 with weights, section 2.2.3):
//!
//! ```text
//! cov(u) = s^2 (J^T J)^-1,    s^2 = S / (n - p)
//! ```
//!
//! `S` the weighted sum of squares at the optimum, `n` the rows (a repeated row
//! counts once for each time it is listed), `p` the keys. A key's standard error
//! is `(HIGH - LOW) sqrt(cov_ii)`. A local, linear estimate: it says nothing of
//! other minima, and little where the speed jumps between gaits.
//!
//! The search's own resolution: where a compass search of step `h` stops, no
//! poll point `u +- h e_i` lowers `S`; for `S` quadratic about its minimum `u*`,
//! `S(u) = S* + (u - u*)^T A (u - u*)` with `A = J^T J`, that is
//! `|(A (u - u*))_i| <= h A_ii / 2`, so
//!
//! ```text
//! |u - u*|_i <= sum_k |(A^-1)_ik| h A_kk / 2
//! ```
//!
//! (the tests' tolerance on a recovered key is 3 standard errors plus this).
//!
//! The inverse goes through the eigenvalues of the scaled matrix
//! `C = D^-1 J^T J D^-1`, `D = diag(sqrt((J^T J)_ii))` (unit diagonal: its
//! condition number measures how nearly the columns are proportional, not their
//! units), by Jacobi's rotations (Golub & Van Loan, *Matrix Computations*, 4th ed.,
//! algorithm 8.5.2).

/// A key is not identified when its standard error exceeds this share of its
/// range: then `+-2` standard errors (about 95 %) span the whole range.
pub const UNIDENTIFIED_SHARE: f64 = 0.25;

/// Keys cannot be told apart when the condition number of the scaled `J^T J`
/// exceeds this: for two keys, a correlation of their columns above
/// `(K - 1) / (K + 1) = 0.998`; their standard errors grow by `sqrt(K) = 32`
/// over independent ones.
pub const MAX_CONDITION: f64 = 1.0e3;

/// A key is weak in a near-singular direction when its share of the
/// eigenvector exceeds this (`1 / sqrt(2)` is an even share of two).
pub const WEAK_COMPONENT: f64 = 0.3;

/// What the measurements say of the fitted keys.
#[derive(Clone, Debug, PartialEq)]
pub struct Precision {
    /// Standard error of each key, normalised (`None`: not estimable: no degrees
    /// of freedom, or a column zero or not a number).
    pub std_error_u: Vec<Option<f64>>,
    /// How far the search's end may lie from the least-squares point, normalised
    /// (`None` where `J^T J` is singular): see the module doc.
    pub resolution_u: Vec<Option<f64>>,
    /// `s^2 = S / (n - p)`, `None` when `n <= p`.
    pub s2: Option<f64>,
    /// `n - p`.
    pub dof: isize,
    /// Condition number of the scaled `J^T J` (infinite with a zero column).
    pub condition: f64,
    /// The norm of each column of `J`: how much the whole range of the key moves
    /// the weighted residuals, m/s.
    pub column_norm: Vec<f64>,
    /// The keys with a large share of the direction of the smallest eigenvalue.
    pub weak: Vec<usize>,
}

/// The estimates from the Jacobian `j` (rows) and the sum of squares `ssr` at the
/// end of a compass search of last step `step`.
pub fn precision(j: &[Vec<f64>], ssr: f64, step: f64) -> Precision {
    let n = j.len();
    let p = j.first().map_or(0, Vec::len);
    let dof = n as isize - p as isize;
    let s2 = (dof > 0).then(|| ssr / dof as f64);
    // J^T J.
    let mut a = vec![vec![0.0; p]; p];
    for row in j {
        for i in 0..p {
            for k in 0..p {
                a[i][k] += row[i] * row[k];
            }
        }
    }
    let column_norm: Vec<f64> = (0..p).map(|i| a[i][i].sqrt()).collect();
    // A column not a number (a difference to a point the machine reader refused)
    // says as little as a zero one.
    let live: Vec<usize> = (0..p).filter(|&i| informative(column_norm[i])).collect();
    // The scaled matrix of the columns that are not zero.
    let c: Vec<Vec<f64>> = live
        .iter()
        .map(|&i| {
            live.iter()
                .map(|&k| a[i][k] / (column_norm[i] * column_norm[k]))
                .collect()
        })
        .collect();
    let (values, vectors) = jacobi_eigen(c);
    let (lo, hi) = values.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), v| {
        (lo.min(*v), hi.max(*v))
    });
    let condition = if live.len() < p || lo <= 0.0 {
        f64::INFINITY
    } else {
        hi / lo
    };
    // cov_u = s^2 D^-1 C^-1 D^-1; C^-1 = V diag(1 / lambda) V^T.
    let m = live.len();
    let c_inv: Vec<Vec<f64>> = (0..m)
        .map(|x| {
            (0..m)
                .map(|y| {
                    values
                        .iter()
                        .enumerate()
                        .map(|(e, l)| vectors[x][e] * vectors[y][e] / l)
                        .sum()
                })
                .collect()
        })
        .collect();
    let invertible = lo > 0.0 && condition.is_finite();
    let mut std_error_u = vec![None; p];
    let mut resolution_u = vec![None; p];
    for (x, &i) in live.iter().enumerate() {
        if !invertible {
            break;
        }
        if let Some(s2) = s2 {
            std_error_u[i] = Some((s2 * c_inv[x][x]).sqrt() / column_norm[i]);
        }
        // |u - u*|_i <= sum_k |(A^-1)_ik| (h/2) A_kk, (A^-1)_ik = (C^-1)_ik / (d_i d_k).
        resolution_u[i] = Some(
            0.5 * step
                * live
                    .iter()
                    .enumerate()
                    .map(|(y, &k)| c_inv[x][y].abs() * column_norm[k] / column_norm[i])
                    .sum::<f64>(),
        );
    }
    // The keys of the weakest direction, when it is weak.
    let mut weak: Vec<usize> = (0..p).filter(|&i| !informative(column_norm[i])).collect();
    if condition > MAX_CONDITION && live.len() == p {
        if let Some(m) = (0..values.len()).min_by(|&x, &y| values[x].total_cmp(&values[y])) {
            weak.extend(
                live.iter()
                    .enumerate()
                    .filter(|(a_, _)| vectors[*a_][m].abs() > WEAK_COMPONENT)
                    .map(|(_, &i)| i),
            );
        }
    }
    Precision {
        std_error_u,
        resolution_u,
        s2,
        dof,
        condition,
        column_norm,
        weak,
    }
}

/// Whether a column of norm `norm` carries information: above 0 and finite.
pub fn informative(norm: f64) -> bool {
    norm > 0.0 && norm.is_finite()
}

/// Eigenvalues and eigenvectors (columns: `vectors[i][m]` is component `i` of
/// vector `m`) of the symmetric matrix `a`, by cyclic Jacobi rotations.
pub fn jacobi_eigen(mut a: Vec<Vec<f64>>) -> (Vec<f64>, Vec<Vec<f64>>) {
    let n = a.len();
    let mut v: Vec<Vec<f64>> = (0..n)
        .map(|i| (0..n).map(|k| if i == k { 1.0 } else { 0.0 }).collect())
        .collect();
    for _sweep in 0..100 {
        let off: f64 = (0..n)
            .flat_map(|i| (0..n).filter(move |&k| k != i).map(move |k| (i, k)))
            .map(|(i, k)| a[i][k] * a[i][k])
            .sum();
        if off <= 1e-30 {
            break;
        }
        for pi in 0..n {
            for q in pi + 1..n {
                if a[pi][q] == 0.0 {
                    continue;
                }
                // The rotation that zeroes a[p][q] (Golub & Van Loan, alg. 8.5.1).
                let tau = (a[q][q] - a[pi][pi]) / (2.0 * a[pi][q]);
                let t = tau.signum() / (tau.abs() + (1.0 + tau * tau).sqrt());
                let c = 1.0 / (1.0 + t * t).sqrt();
                let s = t * c;
                // A J (columns p and q), then J^T (A J) (rows p and q).
                for row in a.iter_mut() {
                    let (akp, akq) = (row[pi], row[q]);
                    row[pi] = c * akp - s * akq;
                    row[q] = s * akp + c * akq;
                }
                let (rp, rq) = (a[pi].clone(), a[q].clone());
                a[pi] = rp.iter().zip(&rq).map(|(x, y)| c * x - s * y).collect();
                a[q] = rp.iter().zip(&rq).map(|(x, y)| s * x + c * y).collect();
                for row in v.iter_mut() {
                    let (vp, vq) = (row[pi], row[q]);
                    row[pi] = c * vp - s * vq;
                    row[q] = s * vp + c * vq;
                }
            }
        }
    }
    ((0..n).map(|i| a[i][i]).collect(), v)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Straight-line regression `y = b0 + b1 x` at x = 0, 1, 2, 3: the closed
    /// forms `se(b1) = s / sqrt(Sxx)`, `se(b0) = s sqrt(1/n + xbar^2 / Sxx)`.
    #[test]
    fn standard_errors_of_a_straight_line() {
        let x = [0.0, 1.0, 2.0, 3.0];
        let j: Vec<Vec<f64>> = x.iter().map(|x| vec![1.0, *x]).collect();
        let ssr = 0.5;
        let p = precision(&j, ssr, 0.1);
        let s = (ssr / 2.0f64).sqrt();
        let sxx: f64 = 5.0;
        assert!((p.std_error_u[1].unwrap() - s / sxx.sqrt()).abs() < 1e-12);
        assert!((p.std_error_u[0].unwrap() - s * (0.25 + 2.25 / sxx).sqrt()).abs() < 1e-12);
        assert_eq!(p.dof, 2);
        assert!(p.weak.is_empty());
        // A = [[4, 6], [6, 14]], A^-1 = [[14, -6], [-6, 4]] / 20; h = 0.1:
        // (14 4 + 6 14) / 20 x 0.05 = 0.35, (6 4 + 4 14) / 20 x 0.05 = 0.2.
        assert!((p.resolution_u[0].unwrap() - 0.35).abs() < 1e-12);
        assert!((p.resolution_u[1].unwrap() - 0.2).abs() < 1e-12);
    }

    /// A zero column and proportional columns are flagged; no degrees of freedom,
    /// no standard error.
    #[test]
    fn unidentifiable_keys_are_flagged() {
        let p = precision(&[vec![1.0, 0.0], vec![2.0, 0.0], vec![3.0, 0.0]], 1.0, 0.1);
        assert_eq!(p.weak, vec![1]);
        assert_eq!(p.std_error_u[1], None);
        assert!(p.condition.is_infinite());
        let p = precision(
            &[vec![1.0, 2.0], vec![2.0, 4.0 + 1e-6], vec![3.0, 6.0]],
            1.0,
            0.1,
        );
        assert!(p.condition > MAX_CONDITION);
        assert_eq!(p.weak, vec![0, 1]);
        // A difference to a refused point (not a number) is no information.
        let p = precision(
            &[vec![1.0, f64::NAN], vec![2.0, 1.0], vec![3.0, 0.5]],
            1.0,
            0.1,
        );
        assert_eq!(p.weak, vec![1]);
        assert_eq!(p.std_error_u[1], None);
        let p = precision(&[vec![1.0, 0.0], vec![0.0, 1.0]], 1.0, 0.1);
        assert_eq!((p.s2, p.std_error_u.clone()), (None, vec![None, None]));
    }

    #[test]
    fn eigenvalues_of_a_symmetric_matrix() {
        let (mut values, _) = jacobi_eigen(vec![vec![2.0, 1.0], vec![1.0, 2.0]]);
        values.sort_by(f64::total_cmp);
        assert!((values[0] - 1.0).abs() < 1e-12 && (values[1] - 3.0).abs() < 1e-12);
    }
}
