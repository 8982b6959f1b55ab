//! The Levenberg–Marquardt local search of `host-sim calibrate --capture`
//! (docs/calibration.md, "Motor keys from a capture"), in the box-normalised
//! coordinates `u` in [0, 1]^p of [`super::fit`], on its memo of evaluations.
//!
//! A capture's residuals (the replayed signals minus the recorded ones, summed
//! over windows, `capture::residuals`) move linearly with the motor keys over
//! a few percent of each, with a jitter on top where the replay has drifted
//! from the board by an encoder count; a gradient method on differences wider
//! than that jitter finds the least-squares point in a few iterations where a
//! compass search of `p` keys would poll `2p` points a step down to its
//! resolution.
//!
//! One iteration at `u`, with the weighted residuals `r` there and `S = |r|^2`:
//!
//! 1. the Jacobian `J = dr/du` by forward differences of step `h`
//!    ([`Settings::jacobian_step`]; backward where `u_i + h` leaves the box),
//!    `p` evaluations as one batch;
//! 2. with `A = J^T J` and `g = J^T r`, one step for each damping
//!    `lambda x` [`DAMPINGS`]:
//!
//!    ```text
//!    (A + lambda D) delta = -g,    D = diag(A)
//!    ```
//!
//!    (Marquardt, *J. SIAM* 11, 1963, eq. 29: the damping scaled by `A`'s
//!    diagonal, so the step does not depend on the keys' units; `lambda -> 0`
//!    is the Gauss–Newton step, a large `lambda` a short step down the
//!    gradient), each trial point `u + delta` clamped to the box, all evaluated
//!    as one batch (they run in parallel);
//! 3. the trial with the lowest `S` is taken when it lowers `S`, and its
//!    damping becomes `lambda`; else `lambda` grows by [`REJECTED_GROWTH`] and
//!    step 2 is tried again with the same Jacobian.
//!
//! It stops (converged) when a step taken moves every key by less than
//! [`Settings::last_step`] of its range, or when no step lowers `S` up to a
//! damping of [`MAX_DAMPING`] (a step of `g / (lambda D)`, vanishing); or, not
//! converged, at [`Settings::budget`] new evaluations.

use super::fit::{ssr, Memo, Search, Settings};
use crate::failure::Failure;

/// The first damping: nearly the Gauss–Newton step, which a smooth least-squares
/// problem takes from the first iteration (Nocedal & Wright, *Numerical
/// Optimization*, 2nd ed., 2006, section 10.3).
pub const FIRST_DAMPING: f64 = 1.0e-3;

/// The dampings tried at once, times the current one: a tenth (towards
/// Gauss–Newton), the same, ten times (towards the gradient).
pub const DAMPINGS: [f64; 3] = [0.1, 1.0, 10.0];

/// After a batch of trials none of which lowers `S`, the damping grows by this:
/// past the largest tried.
pub const REJECTED_GROWTH: f64 = 1000.0;

/// No step lowers `S` at this damping: the step, `g / (lambda D)` per key, is a
/// millionth of the Gauss–Newton step's scale or less.
pub const MAX_DAMPING: f64 = 1.0e6;

/// One local search from the start `index` (`u0`, where `S = f0`), its
/// evaluations through `memo`.
pub fn search(
    memo: &mut Memo<'_, '_>,
    u0: &[f64],
    f0: f64,
    index: usize,
    settings: &Settings,
) -> Result<Search, Failure> {
    let p = u0.len();
    let before = memo.len();
    let (mut u, mut f) = (u0.to_vec(), f0);
    let mut r = memo.get(std::slice::from_ref(&u))?.remove(0);
    let mut lambda = FIRST_DAMPING;
    let mut iterations = 0;
    let converged = 'outer: loop {
        if memo.len() - before >= settings.budget {
            break false;
        }
        // 1. The Jacobian at u.
        let (points, steps) = differences(&u, settings.jacobian_step);
        let got = memo.get(&points)?;
        iterations += 1;
        let mut jacobian = vec![vec![0.0; p]; r.len()];
        for (i, (shifted, du)) in got.iter().zip(&steps).enumerate() {
            for (row, (a, b)) in jacobian.iter_mut().zip(shifted.iter().zip(&r)) {
                row[i] = (a - b) / du;
            }
        }
        let (a, g) = normal_equations(&jacobian, &r);
        // 2. and 3. Trial steps until one lowers S, or the damping is spent.
        loop {
            if memo.len() - before >= settings.budget {
                break 'outer false;
            }
            let trials: Vec<(f64, Vec<f64>)> = DAMPINGS
                .iter()
                .filter_map(|m| {
                    let l = lambda * m;
                    let delta = damped_step(&a, &g, l)?;
                    let v: Vec<f64> = u
                        .iter()
                        .zip(&delta)
                        .map(|(x, d)| (x + d).clamp(0.0, 1.0))
                        .collect();
                    Some((l, v))
                })
                .collect();
            let points: Vec<Vec<f64>> = trials.iter().map(|(_, v)| v.clone()).collect();
            let got = memo.get(&points)?;
            let best = got
                .iter()
                .map(|r| ssr(r))
                .enumerate()
                .min_by(|x, y| x.1.total_cmp(&y.1).then(x.0.cmp(&y.0)));
            match best {
                Some((k, s)) if s < f => {
                    let moved = u
                        .iter()
                        .zip(&trials[k].1)
                        .map(|(x, y)| (x - y).abs())
                        .fold(0.0, f64::max);
                    lambda = trials[k].0;
                    u = trials[k].1.clone();
                    f = s;
                    r = got[k].clone();
                    if moved < settings.last_step {
                        break 'outer true;
                    }
                    break;
                }
                _ => {
                    lambda *= REJECTED_GROWTH;
                    if lambda > MAX_DAMPING {
                        break 'outer true;
                    }
                }
            }
        }
    };
    Ok(Search {
        start: index,
        u,
        from: f0,
        to: f,
        polls: iterations,
        converged,
    })
}

/// The points of forward differences of step `h` from `u` (backward where
/// `u_i + h` leaves the box), and each one's signed step.
pub fn differences(u: &[f64], h: f64) -> (Vec<Vec<f64>>, Vec<f64>) {
    let mut points = Vec::new();
    let mut steps = Vec::new();
    for i in 0..u.len() {
        let mut v = u.to_vec();
        v[i] = if u[i] + h <= 1.0 { u[i] + h } else { u[i] - h };
        steps.push(v[i] - u[i]);
        points.push(v);
    }
    (points, steps)
}

/// `A = J^T J` and `g = J^T r` of the Jacobian `j` (a row per residual) and the
/// residuals `r`.
pub fn normal_equations(j: &[Vec<f64>], r: &[f64]) -> (Vec<Vec<f64>>, Vec<f64>) {
    let p = j.first().map_or(0, Vec::len);
    let mut a = vec![vec![0.0; p]; p];
    let mut g = vec![0.0; p];
    for (row, ri) in j.iter().zip(r) {
        for x in 0..p {
            g[x] += row[x] * ri;
            for y in 0..p {
                a[x][y] += row[x] * row[y];
            }
        }
    }
    (a, g)
}

/// The step `delta` of `(A + lambda diag(A)) delta = -g`, `delta_i = 0` for a
/// key whose column is zero (it moves nothing); `None` where the system is not
/// positive definite or not finite (a difference to a refused point).
pub fn damped_step(a: &[Vec<f64>], g: &[f64], lambda: f64) -> Option<Vec<f64>> {
    let live: Vec<usize> = (0..g.len()).filter(|&i| a[i][i] > 0.0).collect();
    let m: Vec<Vec<f64>> = live
        .iter()
        .map(|&x| {
            live.iter()
                .map(|&y| a[x][y] + if x == y { lambda * a[x][x] } else { 0.0 })
                .collect()
        })
        .collect();
    let b: Vec<f64> = live.iter().map(|&x| -g[x]).collect();
    let solved = cholesky_solve(m, &b)?;
    let mut delta = vec![0.0; g.len()];
    for (&x, d) in live.iter().zip(solved) {
        delta[x] = d;
    }
    delta.iter().all(|d| d.is_finite()).then_some(delta)
}

/// `x` of `M x = b` for a symmetric positive definite `M`, by Cholesky's
/// factorisation `M = L L^T` (Golub & Van Loan, *Matrix Computations*, 4th ed.,
/// algorithm 4.2.2); `None` when a pivot is not positive.
pub fn cholesky_solve(mut m: Vec<Vec<f64>>, b: &[f64]) -> Option<Vec<f64>> {
    let n = b.len();
    for k in 0..n {
        let pivot = m[k][k] - (0..k).map(|j| m[k][j] * m[k][j]).sum::<f64>();
        if pivot.is_nan() || pivot <= 0.0 {
            return None;
        }
        m[k][k] = pivot.sqrt();
        for i in k + 1..n {
            let s = m[i][k] - (0..k).map(|j| m[i][j] * m[k][j]).sum::<f64>();
            m[i][k] = s / m[k][k];
        }
    }
    // L y = b, then L^T x = y.
    let mut y = vec![0.0; n];
    for i in 0..n {
        y[i] = (b[i] - (0..i).map(|j| m[i][j] * y[j]).sum::<f64>()) / m[i][i];
    }
    let mut x = vec![0.0; n];
    for i in (0..n).rev() {
        x[i] = (y[i] - (i + 1..n).map(|j| m[j][i] * x[j]).sum::<f64>()) / m[i][i];
    }
    Some(x)
}

#[cfg(test)]
mod tests {
    use super::super::fit::{fit, Settings};
    use super::*;

    /// `M = [[4, 2], [2, 3]]`, `b = [2, 1]`: `x = [0.5, 0]`.
    #[test]
    fn a_small_system_is_solved() {
        let x = cholesky_solve(vec![vec![4.0, 2.0], vec![2.0, 3.0]], &[2.0, 1.0]).unwrap();
        assert!((x[0] - 0.5).abs() < 1e-15 && x[1].abs() < 1e-15, "{x:?}");
        assert_eq!(
            cholesky_solve(vec![vec![1.0, 2.0], vec![2.0, 1.0]], &[1.0, 1.0]),
            None
        );
    }

    /// A linear model `r = A (u - u*) + e` is solved in one Gauss–Newton step:
    /// the least-squares point `u* + (A^T A)^-1 A^T e`, to the differences'
    /// rounding; the search stops at its next step, below the last step.
    #[test]
    fn a_linear_model_is_solved_in_one_step() {
        let star = [0.3, 0.7];
        let a = [[1.0, 0.5], [0.2, 1.0], [1.0, -1.0]];
        let e = [0.01, -0.02, 0.005];
        let mut f = |batch: &[Vec<f64>]| -> Result<Vec<Vec<f64>>, Failure> {
            Ok(batch
                .iter()
                .map(|u| {
                    a.iter()
                        .zip(&e)
                        .map(|(row, e)| row[0] * (u[0] - star[0]) + row[1] * (u[1] - star[1]) + e)
                        .collect()
                })
                .collect())
        };
        let s = Settings::for_capture(2);
        let found = fit(2, &[vec![0.5, 0.5]], &s, &mut f).unwrap();
        // A^T A = [[2.04, -0.3], [-0.3, 2.25]] (det 4.5), A^T e = [0.011, -0.02]:
        // (A^T A)^-1 A^T e = [2.25 x 0.011 + 0.3 x -0.02, 0.3 x 0.011 + 2.04 x
        // -0.02] / 4.5 = [0.0041667, -0.0083333]; the least-squares point is u*
        // minus that.
        let expected = [0.3 - 0.0041667, 0.7 + 0.0083333];
        for (u, e) in found.u.iter().zip(expected) {
            assert!((u - e).abs() < 1e-5, "{:?}", found.u);
        }
        assert!(found.searches.iter().all(|s| s.converged && s.polls <= 3));
    }

    /// A minimum beyond a face of the box: the search ends on the face.
    #[test]
    fn the_box_holds() {
        let mut f = |batch: &[Vec<f64>]| -> Result<Vec<Vec<f64>>, Failure> {
            Ok(batch.iter().map(|u| vec![u[0] + 1.0, u[1] - 0.4]).collect())
        };
        let found = fit(2, &[vec![0.5, 0.5]], &Settings::for_capture(2), &mut f).unwrap();
        assert_eq!(found.u[0], 0.0);
        assert!((found.u[1] - 0.4).abs() < 1e-9, "{:?}", found.u);
    }

    /// A key that moves nothing stays where it is; the others are solved.
    #[test]
    fn a_key_without_effect_stays() {
        let mut f = |batch: &[Vec<f64>]| -> Result<Vec<Vec<f64>>, Failure> {
            Ok(batch
                .iter()
                .map(|u| vec![u[0] - 0.2, 2.0 * (u[0] - 0.2)])
                .collect())
        };
        let found = fit(2, &[vec![0.5, 0.5]], &Settings::for_capture(2), &mut f).unwrap();
        assert!((found.u[0] - 0.2).abs() < 1e-9, "{:?}", found.u);
    }
}
