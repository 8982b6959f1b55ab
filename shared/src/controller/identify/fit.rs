//! Ordinary least squares over a few unknowns, accumulated row by row without a
//! heap: the normal equations `X^T X b = X^T y` (Björck, *Numerical Methods for
//! Least Squares Problems*, SIAM 1996, sec. 1.1 and 2.2), solved by Cholesky.
//!
//! With `n` rows of `P` unknowns, the estimate and its statistics are
//!
//! ```text
//!   b     = (X^T X)^-1 X^T y
//!   RSS   = y^T y - b^T X^T y                 (the residual sum of squares)
//!   s^2   = RSS / (n - P)                     (the residual variance)
//!   se_j  = s sqrt([(X^T X)^-1]_jj)           (the standard error of b_j)
//! ```
//!
//! (Björck, sec. 1.1.4; any regression text, e.g. Draper & Smith, *Applied
//! Regression Analysis*, 3rd ed., sec. 5.2). The sums are kept in `f64`: a few
//! rows per measurement, and the identification's rows are means over many ticks,
//! so the cost is nothing next to the control step, and forming `X^T X` in `f32`
//! would square the condition number of a fit in the single precision.

/// The normal equations of a least-squares fit of `P` unknowns.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LeastSquares<const P: usize> {
    /// `X^T X`.
    xtx: [[f64; P]; P],
    /// `X^T y`.
    xty: [f64; P],
    /// `y^T y`.
    yty: f64,
    /// Rows added.
    n: u32,
}

/// A solved fit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Solution<const P: usize> {
    /// The estimates `b`.
    pub coefficients: [f64; P],
    /// Their standard errors `se_j`; 0 when the fit has no degree of freedom left
    /// (`n = P`: an exact fit says nothing of its error).
    pub std_errors: [f64; P],
    /// The root-mean-square residual `sqrt(RSS / n)`, in the units of `y`.
    pub residual_rms: f64,
    /// The residual's scale `s = sqrt(RSS / (n - P))` (0 without a degree of
    /// freedom): for rows weighted by their own standard errors, about 1 when
    /// the model fits within them.
    pub residual_scale: f64,
    /// `sqrt([(X^T X)^-1]_jj)`: the standard errors for rows weighted by their own
    /// standard errors (known variances), whatever the residual.
    pub unit_errors: [f64; P],
    /// Rows used.
    pub rows: u32,
}

impl<const P: usize> Default for LeastSquares<P> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const P: usize> LeastSquares<P> {
    /// No rows yet.
    pub const fn new() -> Self {
        LeastSquares {
            xtx: [[0.0; P]; P],
            xty: [0.0; P],
            yty: 0.0,
            n: 0,
        }
    }

    /// Rows added.
    pub fn rows(&self) -> u32 {
        self.n
    }

    /// Adds the row `x . b = y`. A row with a non-finite entry is left out.
    pub fn add(&mut self, x: [f64; P], y: f64) {
        if !y.is_finite() || x.iter().any(|v| !v.is_finite()) {
            return;
        }
        for i in 0..P {
            for j in 0..P {
                self.xtx[i][j] += x[i] * x[j];
            }
            self.xty[i] += x[i] * y;
        }
        self.yty += y * y;
        self.n += 1;
    }

    /// The fit, or `None` with fewer rows than unknowns or with `X^T X` singular
    /// (a Cholesky pivot at or below `1e-12` of its diagonal entry: the rows do
    /// not tell the unknowns apart).
    pub fn solve(&self) -> Option<Solution<P>> {
        if (self.n as usize) < P {
            return None;
        }
        let l = cholesky(&self.xtx)?;
        let coefficients = cholesky_solve(&l, &self.xty);
        let explained: f64 = (0..P).map(|j| coefficients[j] * self.xty[j]).sum();
        // Rounding can take RSS a hair below 0 on an exact fit.
        let rss = (self.yty - explained).max(0.0);
        let dof = self.n as usize - P;
        let s2 = if dof > 0 { rss / dof as f64 } else { 0.0 };
        let mut std_errors = [0.0; P];
        let mut unit_errors = [0.0; P];
        for j in 0..P {
            let mut e = [0.0; P];
            e[j] = 1.0;
            // [(X^T X)^-1]_jj = e_j^T (X^T X)^-1 e_j.
            let column = cholesky_solve(&l, &e);
            unit_errors[j] = libm::sqrt(column[j].max(0.0));
            std_errors[j] = libm::sqrt(s2) * unit_errors[j];
        }
        Some(Solution {
            coefficients,
            std_errors,
            residual_rms: libm::sqrt(rss / f64::from(self.n)),
            residual_scale: libm::sqrt(s2),
            unit_errors,
            rows: self.n,
        })
    }
}

/// The lower triangle `L` of `A = L L^T` for a symmetric `A`, or `None` when a
/// pivot is at or below `1e-12` of its diagonal entry (singular to working
/// precision) or not finite.
fn cholesky<const P: usize>(a: &[[f64; P]; P]) -> Option<[[f64; P]; P]> {
    let mut l = [[0.0; P]; P];
    for j in 0..P {
        let mut d = a[j][j];
        for k in 0..j {
            d -= l[j][k] * l[j][k];
        }
        if !d.is_finite() || d <= 1e-12 * a[j][j].abs() || d <= 0.0 {
            return None;
        }
        let root = libm::sqrt(d);
        l[j][j] = root;
        for i in j + 1..P {
            let mut s = a[i][j];
            for k in 0..j {
                s -= l[i][k] * l[j][k];
            }
            l[i][j] = s / root;
        }
    }
    Some(l)
}

/// `x` with `L L^T x = b`: forward then back substitution.
fn cholesky_solve<const P: usize>(l: &[[f64; P]; P], b: &[f64; P]) -> [f64; P] {
    let mut y = [0.0; P];
    for i in 0..P {
        let mut s = b[i];
        for k in 0..i {
            s -= l[i][k] * y[k];
        }
        y[i] = s / l[i][i];
    }
    let mut x = [0.0; P];
    for i in (0..P).rev() {
        let mut s = y[i];
        for k in i + 1..P {
            s -= l[k][i] * x[k];
        }
        x[i] = s / l[i][i];
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A straight line through exact points is recovered to rounding, with zero
    /// residual and zero standard errors.
    #[test]
    fn an_exact_line_is_recovered() {
        let mut ls = LeastSquares::<2>::new();
        for x in [-2.0, 0.5, 1.0, 4.0] {
            ls.add([1.0, x], 3.0 - 0.25 * x);
        }
        let s = ls.solve().unwrap();
        assert!((s.coefficients[0] - 3.0).abs() < 1e-12);
        assert!((s.coefficients[1] + 0.25).abs() < 1e-12);
        assert!(s.residual_rms < 1e-7);
        assert!(s.std_errors.iter().all(|e| *e < 1e-7));
    }

    /// The simple regression's closed forms (Draper & Smith, sec. 1.2 and 1.4):
    /// `b = Sxy / Sxx`, `a = ybar - b xbar`, `se(b) = s / sqrt(Sxx)`,
    /// `se(a) = s sqrt(1/n + xbar^2 / Sxx)`, `s^2 = RSS / (n - 2)`.
    #[test]
    fn a_noisy_line_matches_the_closed_forms() {
        let xs = [0.0, 1.0, 2.0, 3.0, 5.0, 8.0];
        let ys = [1.1, 2.9, 5.2, 6.8, 11.3, 16.7];
        let mut ls = LeastSquares::<2>::new();
        for (x, y) in xs.iter().zip(&ys) {
            ls.add([1.0, *x], *y);
        }
        let s = ls.solve().unwrap();
        let n = xs.len() as f64;
        let xbar = xs.iter().sum::<f64>() / n;
        let ybar = ys.iter().sum::<f64>() / n;
        let sxx: f64 = xs.iter().map(|x| (x - xbar) * (x - xbar)).sum();
        let sxy: f64 = xs
            .iter()
            .zip(&ys)
            .map(|(x, y)| (x - xbar) * (y - ybar))
            .sum();
        let b = sxy / sxx;
        let a = ybar - b * xbar;
        let rss: f64 = xs
            .iter()
            .zip(&ys)
            .map(|(x, y)| (y - a - b * x) * (y - a - b * x))
            .sum();
        let sigma = (rss / (n - 2.0)).sqrt();
        let close = |u: f64, v: f64| (u - v).abs() <= 1e-9 * v.abs().max(1.0);
        assert!(close(s.coefficients[1], b), "{s:?}");
        assert!(close(s.coefficients[0], a), "{s:?}");
        assert!(close(s.std_errors[1], sigma / sxx.sqrt()), "{s:?}");
        assert!(
            close(
                s.std_errors[0],
                sigma * (1.0 / n + xbar * xbar / sxx).sqrt()
            ),
            "{s:?}"
        );
        assert!(close(s.residual_rms, (rss / n).sqrt()), "{s:?}");
    }

    /// Fewer rows than unknowns, or rows that cannot tell two unknowns apart,
    /// give no fit; a non-finite row is left out.
    #[test]
    fn an_undetermined_fit_is_refused() {
        let mut ls = LeastSquares::<2>::new();
        ls.add([1.0, 2.0], 1.0);
        assert!(ls.solve().is_none());
        ls.add([2.0, 4.0], 2.0);
        assert!(ls.solve().is_none(), "collinear rows");
        ls.add([1.0, f64::NAN], 0.0);
        assert_eq!(ls.rows(), 2);
        ls.add([0.0, 1.0], 5.0);
        assert!(ls.solve().is_some());
    }

    /// Three unknowns through the normal equations agree with the exact solution
    /// of a square system, and a fourth row's residual shows in the statistics.
    #[test]
    fn three_unknowns() {
        let mut ls = LeastSquares::<3>::new();
        let truth = [2.0, -0.5, 0.125];
        let rows = [
            [1.0, 0.0, 1.0],
            [0.0, 1.0, 1.0],
            [1.0, 1.0, 0.0],
            [2.0, -1.0, 3.0],
        ];
        for x in rows {
            let y: f64 = (0..3).map(|j| x[j] * truth[j]).sum();
            ls.add(x, y);
        }
        let s = ls.solve().unwrap();
        for j in 0..3 {
            assert!((s.coefficients[j] - truth[j]).abs() < 1e-12, "{s:?}");
        }
        ls.add([1.0, 1.0, 1.0], 1.625 + 0.1);
        let s = ls.solve().unwrap();
        assert!(s.residual_rms > 0.01 && s.std_errors.iter().all(|e| *e > 0.0));
    }
}
