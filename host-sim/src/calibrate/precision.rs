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
//! counts once for each time it is listed), `p` the keys. A local, linear
//! estimate: it says nothing of other minima, and little where the speed jumps
//! between gaits.
//!
//! The simulator's numerical noise (`tau_k`, m/s, at each measured point,
//! [`super::numerical`]) is a second error in every residual, shared by the `W_k`
//! of weight at the point: the linearised fit moves by `-(J^T J)^-1 J^T e` for
//! residual errors `e`, and a point's `e_k = sqrt(W_k) tau_k` (its row of `J`
//! being `sqrt(W_k) dg_k/du`) adds the "sandwich" term (White, *Econometrica* 48,
//! 1980, for errors of unequal variance):
//!
//! ```text
//! cov(u) = s^2 (J^T J)^-1 + (J^T J)^-1 B (J^T J)^-1,    B = sum_k W_k tau_k^2 J_k J_k^T
//! ```
//!
//! That is the noise's effect on a smooth `S`. But the noise makes `S` rough:
//! the search ends at the trial point whose noise lowered `S` most, not at the
//! minimum `u*` of the noise-free `S`. With `q = G + sigma_S`
//! ([`super::numerical`]: the search's gain from the noise at the fit `u0`, and
//! one standard deviation of the noise of `S` at `u*`), the search preferring
//! `u0` means `S(u0) - S(u*) = (u0 - u*)^T J^T J (u0 - u*) <= q`, an ellipsoid
//! whose extent along key `i` is
//!
//! ```text
//! d_i = sqrt(q ((J^T J)^-1)_ii)
//! ```
//!
//! taken as one more standard deviation of the numerical error (generous: three
//! of them allow `9 q`). The numerical part of a key's standard error is
//! `sqrt(sandwich_ii + d_i^2)`; its standard error is the root sum of squares of
//! that and the measurements' part, `sqrt(s^2 ((J^T J)^-1)_ii)`, both reported, in
//! the key's units (times `HIGH - LOW`). Where the residuals already show the
//! numerical noise (measurements of a real machine), `s^2` counts it once more:
//! the standard error errs on the wide side.
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
    /// of freedom, or a column zero or not a number): the root sum of squares of
    /// the next two.
    pub std_error_u: Vec<Option<f64>>,
    /// Its part from the measurements' scatter, `sqrt(s^2 ((J^T J)^-1)_ii)`.
    pub measurement_u: Vec<Option<f64>>,
    /// Its part from the simulator's numerical noise, `sqrt(sandwich_ii + d_i^2)`
    /// (also where `n <= p`).
    pub numerical_u: Vec<Option<f64>>,
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

/// The simulator's numerical noise at the fit, for [`precision`] (module doc).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Numerical {
    /// Per row of the Jacobian, the variance `W_k tau_k^2` the noise adds to its
    /// residual, m^2/s^2.
    pub variance: Vec<f64>,
    /// `q = G + sigma_S`, m^2/s^2.
    pub indifference: f64,
}

/// How the measurements' errors are taken for their part of the standard error.
#[derive(Clone, Debug, Default, PartialEq)]
pub enum Errors {
    /// Independent, of the variance `sigma^2 / w` of each row (the weights in
    /// the residuals): `s^2 (J^T J)^-1` (module doc).
    #[default]
    Independent,
    /// Serially correlated (a capture's windows): the sandwich
    /// `T / (T - p) (J^T J)^-1 M (J^T J)^-1` with `M` the long-run covariance
    /// of the residuals' `T` scores, `sum_k J_k^T r_k` by window
    /// ([`super::serial`]); `T / (T - p)` is the sandwich's correction for the
    /// `p` keys fitted to the `T` scores `M` is estimated from (MacKinnon &
    /// White, *J. Econometrics* 29, 1985, "HC1"). None where `T <= p`.
    Serial {
        /// `M`, `p x p`, in the normalised coordinates.
        middle: Vec<Vec<f64>>,
        /// `T`, the scores summed in `M`.
        samples: usize,
    },
}

/// The estimates from the Jacobian `j` (one row per measured point, `J^T J` the
/// rows' own: [`super::points`]) and the sum of squares `ssr` over `n` rows at the
/// end of a compass search of last step `step`, with the simulator's `numerical`
/// noise; the measurements' errors independent ([`Errors::Independent`]).
pub fn precision(
    j: &[Vec<f64>],
    ssr: f64,
    n: usize,
    step: f64,
    numerical: &Numerical,
) -> Precision {
    with_errors(j, ssr, n, step, numerical, &Errors::Independent)
}

/// [`precision`] with the measurements' errors taken as `errors` says.
pub fn with_errors(
    j: &[Vec<f64>],
    ssr: f64,
    n: usize,
    step: f64,
    numerical: &Numerical,
    errors: &Errors,
) -> Precision {
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
    // (J^T J)^-1 B (J^T J)^-1 on the live columns; (A^-1)_xy = (C^-1)_xy / (d_x d_y).
    let a_inv: Vec<Vec<f64>> = (0..m)
        .map(|x| {
            (0..m)
                .map(|y| c_inv[x][y] / (column_norm[live[x]] * column_norm[live[y]]))
                .collect()
        })
        .collect();
    let mut b = vec![vec![0.0; m]; m];
    for (row, v) in j.iter().zip(&numerical.variance) {
        for x in 0..m {
            for y in 0..m {
                b[x][y] += v * row[live[x]] * row[live[y]];
            }
        }
    }
    let sandwich = |x: usize, b: &dyn Fn(usize, usize) -> f64| -> f64 {
        (0..m)
            .flat_map(|y| (0..m).map(move |z| (y, z)))
            .map(|(y, z)| a_inv[x][y] * b(y, z) * a_inv[z][x])
            .sum()
    };
    let sandwich_diagonal = |x: usize| sandwich(x, &|y, z| b[y][z]);
    // The measurements' standard deviation of key x, normalised (none
    // without the degrees of freedom).
    let measurement_sd = |x: usize, s2: f64| -> Option<f64> {
        match errors {
            Errors::Independent => Some((s2 * c_inv[x][x]).sqrt() / column_norm[live[x]]),
            Errors::Serial { middle, samples } => (*samples > p).then(|| {
                let scale = *samples as f64 / (samples - p) as f64;
                (scale * sandwich(x, &|y, z| middle[live[y]][live[z]]).max(0.0)).sqrt()
            }),
        }
    };
    let mut std_error_u = vec![None; p];
    let mut measurement_u = vec![None; p];
    let mut numerical_u = vec![None; p];
    let mut resolution_u = vec![None; p];
    for (x, &i) in live.iter().enumerate() {
        if !invertible {
            break;
        }
        let indifference = numerical.indifference.max(0.0) * a_inv[x][x];
        let numerical = (sandwich_diagonal(x).max(0.0) + indifference).sqrt();
        numerical_u[i] = Some(numerical);
        if let Some(measurement) = s2.and_then(|s2| measurement_sd(x, s2)) {
            measurement_u[i] = Some(measurement);
            std_error_u[i] = Some(measurement.hypot(numerical));
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
        measurement_u,
        numerical_u,
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
        let p = precision(&j, ssr, 4, 0.1, &Numerical::default());
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

    /// Numerical noise of variance `v` at the last of the straight line's points
    /// moves the fit by `(J^T J)^-1 j_3 e_3`: its standard deviation is
    /// `|(J^T J)^-1 j_3| sqrt(v)`, with `(J^T J)^-1 j_3 = [14 - 18, -6 + 12] / 20 =
    /// [-0.2, 0.3]`; the noise of `S`, `q`, adds `q ((J^T J)^-1)_ii = q [14, 4] /
    /// 20`; both add to the measurements' part in quadrature.
    #[test]
    fn numerical_noise_adds_its_two_terms() {
        let j: Vec<Vec<f64>> = [0.0, 1.0, 2.0, 3.0].iter().map(|x| vec![1.0, *x]).collect();
        let none = Numerical {
            variance: vec![0.0; 4],
            indifference: 0.0,
        };
        let plain = precision(&j, 0.5, 4, 0.1, &none);
        assert_eq!(plain.numerical_u, vec![Some(0.0), Some(0.0)]);
        assert_eq!(plain.std_error_u, plain.measurement_u);
        let v = 0.25;
        let q = 0.1;
        for (numerical, expected) in [
            (
                Numerical {
                    variance: vec![0.0, 0.0, 0.0, v],
                    indifference: 0.0,
                },
                [0.04 * v, 0.09 * v],
            ),
            (
                Numerical {
                    variance: vec![0.0; 4],
                    indifference: q,
                },
                [0.7 * q, 0.2 * q],
            ),
            (
                Numerical {
                    variance: vec![0.0, 0.0, 0.0, v],
                    indifference: q,
                },
                [0.04 * v + 0.7 * q, 0.09 * v + 0.2 * q],
            ),
        ] {
            let noisy = precision(&j, 0.5, 4, 0.1, &numerical);
            assert_eq!(noisy.measurement_u, plain.measurement_u);
            for (i, variance) in expected.iter().enumerate() {
                let num = noisy.numerical_u[i].unwrap();
                let meas = noisy.measurement_u[i].unwrap();
                assert!((num - variance.sqrt()).abs() < 1e-12, "{num}");
                assert!((noisy.std_error_u[i].unwrap() - meas.hypot(num)).abs() < 1e-15);
            }
        }
        // No degrees of freedom: no standard error, but the numerical part.
        let numerical = Numerical {
            variance: vec![0.0, 1.0],
            indifference: 0.0,
        };
        let p = precision(&j[..2], 0.0, 2, 0.1, &numerical);
        assert_eq!(p.std_error_u, vec![None, None]);
        assert!(p.numerical_u.iter().all(Option::is_some));
    }

    /// A zero column and proportional columns are flagged; no degrees of freedom,
    /// no standard error.
    #[test]
    fn unidentifiable_keys_are_flagged() {
        let p = precision(
            &[vec![1.0, 0.0], vec![2.0, 0.0], vec![3.0, 0.0]],
            1.0,
            3,
            0.1,
            &Numerical::default(),
        );
        assert_eq!(p.weak, vec![1]);
        assert_eq!(p.std_error_u[1], None);
        assert!(p.condition.is_infinite());
        let p = precision(
            &[vec![1.0, 2.0], vec![2.0, 4.0 + 1e-6], vec![3.0, 6.0]],
            1.0,
            3,
            0.1,
            &Numerical::default(),
        );
        assert!(p.condition > MAX_CONDITION);
        assert_eq!(p.weak, vec![0, 1]);
        // A difference to a refused point (not a number) is no information.
        let p = precision(
            &[vec![1.0, f64::NAN], vec![2.0, 1.0], vec![3.0, 0.5]],
            1.0,
            3,
            0.1,
            &Numerical::default(),
        );
        assert_eq!(p.weak, vec![1]);
        assert_eq!(p.std_error_u[1], None);
        let p = precision(
            &[vec![1.0, 0.0], vec![0.0, 1.0]],
            1.0,
            2,
            0.1,
            &Numerical::default(),
        );
        assert_eq!((p.s2, p.std_error_u.clone()), (None, vec![None, None]));
    }

    #[test]
    fn eigenvalues_of_a_symmetric_matrix() {
        let (mut values, _) = jacobi_eigen(vec![vec![2.0, 1.0], vec![1.0, 2.0]]);
        values.sort_by(f64::total_cmp);
        assert!((values[0] - 1.0).abs() < 1e-12 && (values[1] - 3.0).abs() < 1e-12);
    }
}
