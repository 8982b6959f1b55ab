//! The measurements' part of the standard errors where the residuals are
//! correlated from one tick to the next (a capture's fit, docs/calibration.md,
//! "Motor keys from a capture").
//!
//! With the weighted residuals `r` and their Jacobian `J` at the fit, the
//! score of tick `k` is `g_k = sum J_row^T r_row` over the tick's rows. The
//! least-squares fit moves by `-(J^T J)^-1 sum_k g_k` for errors in the
//! residuals, so its covariance is `(J^T J)^-1 M (J^T J)^-1` with `M` the
//! covariance of `sum_k g_k`: `s^2 J^T J` for independent residuals of one
//! variance ([`super::precision`]), and for scores correlated over `L` ticks
//! the long-run covariance, estimated with Bartlett's weights (Newey & West,
//! *Econometrica* 55, 1987, eq. 2):
//!
//! ```text
//! M = G_0 + sum_(l = 1..L) (1 - l / (L + 1)) (G_l + G_l^T),    G_l = sum_(k >= l) g_k g_(k-l)^T
//! ```
//!
//! positive semi-definite for any `L`. A twin that drifts from the board by an
//! encoder count drifts for as long as its loops take to pull it back, so its
//! residuals are correlated over the loops' settling; `L` is chosen to cover
//! the slowest of them ([`super::capture`]).

/// The score of each tick: `g_k = sum J_row^T r_row` over its `per_tick` rows
/// (consecutive), `p` numbers each.
pub fn scores(j: &[Vec<f64>], r: &[f64], per_tick: usize) -> Vec<Vec<f64>> {
    let p = j.first().map_or(0, Vec::len);
    j.chunks(per_tick.max(1))
        .zip(r.chunks(per_tick.max(1)))
        .map(|(rows, rs)| {
            let mut g = vec![0.0; p];
            for (row, ri) in rows.iter().zip(rs) {
                for (gi, x) in g.iter_mut().zip(row) {
                    *gi += x * ri;
                }
            }
            g
        })
        .collect()
}

/// `M` of the module doc from the ticks' `scores`, over `lags` ticks.
pub fn newey_west(scores: &[Vec<f64>], lags: usize) -> Vec<Vec<f64>> {
    let p = scores.first().map_or(0, Vec::len);
    let mut m = vec![vec![0.0; p]; p];
    for l in 0..=lags.min(scores.len().saturating_sub(1)) {
        // Bartlett's weight; G_0 counts once, G_l and its transpose each lag.
        let w = 1.0 - l as f64 / (lags as f64 + 1.0);
        for k in l..scores.len() {
            let (a, b) = (&scores[k], &scores[k - l]);
            for x in 0..p {
                for y in 0..p {
                    let term = if l == 0 {
                        a[x] * b[y]
                    } else {
                        a[x] * b[y] + b[x] * a[y]
                    };
                    m[x][y] += w * term;
                }
            }
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibrate::precision::{precision, with_errors, Errors, Numerical};

    /// Without lags the middle is `sum g_k g_k^T`; for one key and scores
    /// `1, -1, 2` with one lag: `G_0 = 6`, `G_1 = -1 - 2 = -3`, weight 1/2:
    /// `M = 6 + 0.5 (-6) = 3`.
    #[test]
    fn bartletts_weights() {
        let g = vec![vec![1.0], vec![-1.0], vec![2.0]];
        assert_eq!(newey_west(&g, 0), vec![vec![6.0]]);
        assert_eq!(newey_west(&g, 1), vec![vec![3.0]]);
        // Two keys: symmetric.
        let g = vec![vec![1.0, 0.0], vec![0.0, 1.0]];
        let m = newey_west(&g, 1);
        assert_eq!(m, vec![vec![1.0, 0.5], vec![0.5, 1.0]]);
    }

    /// Scores of rows two a tick, summed by tick.
    #[test]
    fn scores_by_tick() {
        let j = vec![
            vec![1.0, 0.0],
            vec![0.0, 2.0],
            vec![1.0, 1.0],
            vec![3.0, 0.0],
        ];
        let r = [1.0, 1.0, -1.0, 2.0];
        assert_eq!(scores(&j, &r, 2), vec![vec![1.0, 2.0], vec![5.0, -1.0]]);
    }

    /// With residuals that are in fact independent and the middle `s^2 J^T J`,
    /// the sandwich is `s^2 (J^T J)^-1`: the straight line's standard errors,
    /// times `sqrt(T / (T - p))` (the sandwich's degrees of freedom), here 4
    /// scores for 2 keys.
    #[test]
    fn the_sandwich_of_independent_errors_is_the_plain_estimate() {
        let j: Vec<Vec<f64>> = [0.0, 1.0, 2.0, 3.0].iter().map(|x| vec![1.0, *x]).collect();
        let ssr = 0.5;
        let s2 = ssr / 2.0;
        let middle = vec![vec![4.0 * s2, 6.0 * s2], vec![6.0 * s2, 14.0 * s2]];
        let plain = precision(&j, ssr, 4, 0.1, &Numerical::default());
        let serial = with_errors(
            &j,
            ssr,
            4,
            0.1,
            &Numerical::default(),
            &Errors::Serial { middle, samples: 4 },
        );
        for i in 0..2 {
            let (a, b) = (
                plain.std_error_u[i].unwrap(),
                serial.std_error_u[i].unwrap(),
            );
            assert!((b - a * 2f64.sqrt()).abs() < 1e-12, "{a} {b}");
        }
        // As many scores as keys: no standard error.
        let none = with_errors(
            &j,
            ssr,
            4,
            0.1,
            &Numerical::default(),
            &Errors::Serial {
                middle: vec![vec![1.0, 0.0], vec![0.0, 1.0]],
                samples: 2,
            },
        );
        assert_eq!(none.std_error_u, vec![None, None]);
    }
}
