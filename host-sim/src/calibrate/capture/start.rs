//! The start angles' part of a capture fit's standard errors
//! (docs/calibration.md, "Motor keys from a capture").
//!
//! A count says a rotor's angle at the capture's start only to within its span
//! (`2 pi / N`); the twin starts each rotor in the middle of it
//! (`replay::twin::MIDDLE_OF_THE_COUNT`), and a start anywhere else in the span
//! is as good a replay. Replays from elsewhere cross the counts at other ticks,
//! so their residuals differ by the counts' rounding that the windows leave
//! ([`super::residuals`]), and each would have given its own fit. With the
//! Jacobian `J` at the fit and the residuals `r_i` of the replays from the
//! middle (`i = 0`, the fit's own) and from 1/8, 3/8, 5/8 and 7/8 of each
//! count's span ([`WITHIN`]), the fit each would have given lies, linearised, a
//! Gauss–Newton step away:
//!
//! ```text
//! d_i = -(J^T J)^-1 J^T r_i
//! ```
//!
//! (`d_0` is the step left at the fit itself), and the standard deviation of
//! `d_0 .. d_4` key by key is the start angles' part of its standard error,
//! added to the residuals' part ([`super::super::serial`]) in quadrature. Where
//! the twin is the board's machine itself (a simulated board) the residuals at
//! the fit are the counts' rounding alone, and this part is what remains.

use super::super::levenberg::{damped_step, normal_equations};

/// Where in each count's span the replays again start.
pub const WITHIN: [f64; 4] = [0.125, 0.375, 0.625, 0.875];

/// The fits the replays from the start counts' middle and from [`WITHIN`]
/// would have given.
#[derive(Clone, Debug, PartialEq)]
pub struct Spread {
    /// Each replay's sum of squares at the fit (the fit's own first).
    pub ssr: Vec<f64>,
    /// Each replay's Gauss–Newton step from the fit, normalised (`None` where
    /// `J^T J` is singular), the fit's own first.
    pub steps: Vec<Option<Vec<f64>>>,
}

impl Spread {
    /// The spread of the replays `residuals` (the fit's own first) at the fit,
    /// whose Jacobian is `j`.
    pub fn new(j: &[Vec<f64>], residuals: &[Vec<f64>]) -> Spread {
        Spread {
            ssr: residuals
                .iter()
                .map(|r| r.iter().map(|x| x * x).sum())
                .collect(),
            steps: residuals
                .iter()
                .map(|r| {
                    let (a, g) = normal_equations(j, r);
                    damped_step(&a, &g, 0.0)
                })
                .collect(),
        }
    }

    /// Key by key, the sample standard deviation of the steps, normalised;
    /// `None` where a step is not known.
    pub fn sd(&self) -> Option<Vec<f64>> {
        let steps: Vec<&Vec<f64>> = self
            .steps
            .iter()
            .map(Option::as_ref)
            .collect::<Option<_>>()?;
        let n = steps.len() as f64;
        let p = steps.first().map_or(0, |s| s.len());
        Some(
            (0..p)
                .map(|k| {
                    let mean = steps.iter().map(|s| s[k]).sum::<f64>() / n;
                    let ss: f64 = steps.iter().map(|s| (s[k] - mean).powi(2)).sum();
                    (ss / (n - 1.0)).sqrt()
                })
                .collect(),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One key, `J = [1, 1]`: the step of residuals `r` is `-(r_1 + r_2) / 2`;
    /// residuals `(1, 1)`, `(0, 0)`, `(-1, -1)` step -1, 0 and 1: their
    /// standard deviation is 1.
    #[test]
    fn the_fits_the_replays_would_give() {
        let j = vec![vec![1.0], vec![1.0]];
        let s = Spread::new(&j, &[vec![1.0, 1.0], vec![0.0, 0.0], vec![-1.0, -1.0]]);
        assert_eq!(s.ssr, vec![2.0, 0.0, 2.0]);
        let steps: Vec<f64> = s.steps.iter().map(|d| d.as_ref().unwrap()[0]).collect();
        for (d, expected) in steps.iter().zip([-1.0, 0.0, 1.0]) {
            assert!((d - expected).abs() < 1e-12, "{steps:?}");
        }
        assert!((s.sd().unwrap()[0] - 1.0).abs() < 1e-12);
        // A Jacobian of zeros moves nothing: the key's step is 0.
        let s = Spread::new(&[vec![0.0], vec![0.0]], &[vec![1.0, 1.0], vec![2.0, 0.0]]);
        assert_eq!(s.sd(), Some(vec![0.0]));
    }
}
