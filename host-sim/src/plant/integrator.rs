//! Dormand-Prince 5(4) with its continuous extension, for a state of `N` numbers.
//!
//! The embedded pair and the dense output are those of Dormand & Prince (1980)
//! and Shampine (1986), as tabulated in Hairer, Norsett & Wanner, *Solving Ordinary
//! Differential Equations I*, 2nd ed., sec. II.5 (Table 5.2, and eq. (6.12) for
//! the 4th-order interpolant). Step size control: the standard controller
//! `h_new = h * min(5, max(0.2, 0.9 * err^(-1/5)))` with the error measured in the
//! weighted RMS norm `sqrt(mean((e_i / (atol_i + rtol |y_i|))^2))` (HNW eq. (4.11)).
//! FSAL: the last stage of an accepted step is the first of the next.

/// A Dormand-Prince step that was accepted: start and end, with what the dense
/// output needs.
#[derive(Clone, Debug)]
pub struct Step<const N: usize> {
    /// Start time, s.
    pub t0: f64,
    /// Step size, s.
    pub h: f64,
    /// State at the start.
    pub y0: [f64; N],
    /// State at the end.
    pub y1: [f64; N],
    /// Dense output coefficients (HNW `rcont1..5`).
    rcont: [[f64; N]; 5],
    /// Derivative at the end (FSAL).
    pub f1: [f64; N],
    /// Components in use ([`Tolerance::len`]).
    len: usize,
}

impl<const N: usize> Step<N> {
    /// End time.
    pub fn t1(&self) -> f64 {
        self.t0 + self.h
    }

    /// The 4th-order continuous extension at `t` in `[t0, t0 + h]` (HNW II eq. (6.12)).
    pub fn at(&self, t: f64) -> [f64; N] {
        let theta = ((t - self.t0) / self.h).clamp(0.0, 1.0);
        let theta1 = 1.0 - theta;
        let r = &self.rcont;
        let mut y = [0.0; N];
        for i in 0..self.len {
            y[i] = r[0][i]
                + theta * (r[1][i] + theta1 * (r[2][i] + theta * (r[3][i] + theta1 * r[4][i])));
        }
        y
    }
}

/// Tolerances of the step size control.
#[derive(Clone, Copy, Debug)]
pub struct Tolerance<const N: usize> {
    /// Relative tolerance.
    pub rtol: f64,
    /// Absolute tolerance per component.
    pub atol: [f64; N],
    /// Components in use: the first `len` of the `N` (a state sized for the
    /// largest machine); the rest stay zero and take no part in the error norm.
    pub len: usize,
}

// Butcher tableau of DOPRI5 (HNW II Table 5.2).
const C2: f64 = 1.0 / 5.0;
const C3: f64 = 3.0 / 10.0;
const C4: f64 = 4.0 / 5.0;
const C5: f64 = 8.0 / 9.0;
const A21: f64 = 1.0 / 5.0;
const A31: f64 = 3.0 / 40.0;
const A32: f64 = 9.0 / 40.0;
const A41: f64 = 44.0 / 45.0;
const A42: f64 = -56.0 / 15.0;
const A43: f64 = 32.0 / 9.0;
const A51: f64 = 19372.0 / 6561.0;
const A52: f64 = -25360.0 / 2187.0;
const A53: f64 = 64448.0 / 6561.0;
const A54: f64 = -212.0 / 729.0;
const A61: f64 = 9017.0 / 3168.0;
const A62: f64 = -355.0 / 33.0;
const A63: f64 = 46732.0 / 5247.0;
const A64: f64 = 49.0 / 176.0;
const A65: f64 = -5103.0 / 18656.0;
const A71: f64 = 35.0 / 384.0;
const A73: f64 = 500.0 / 1113.0;
const A74: f64 = 125.0 / 192.0;
const A75: f64 = -2187.0 / 6784.0;
const A76: f64 = 11.0 / 84.0;
// Error estimate: 5th minus 4th order weights.
const E1: f64 = 71.0 / 57600.0;
const E3: f64 = -71.0 / 16695.0;
const E4: f64 = 71.0 / 1920.0;
const E5: f64 = -17253.0 / 339200.0;
const E6: f64 = 22.0 / 525.0;
const E7: f64 = -1.0 / 40.0;
// Dense output (Shampine).
const D1: f64 = -12715105075.0 / 11282082432.0;
const D3: f64 = 87487479700.0 / 32700410799.0;
const D4: f64 = -10690763975.0 / 1880347072.0;
const D5: f64 = 701980252875.0 / 199316789632.0;
const D6: f64 = -1453857185.0 / 822651844.0;
const D7: f64 = 69997945.0 / 29380423.0;

/// The fractions of the step at which [`attempt`] calls `rhs` first, in this
/// order (stages 2 to 5: `c_2 .. c_5` of the tableau); its last two calls are at
/// the step's end (stage 6, then the accepted state, FSAL). A caller's `rhs` can
/// keep what it computes at these interior stages (the plant's dip test reads the
/// contact forces there).
pub const INTERIOR_STAGES: [f64; 4] = [C2, C3, C4, C5];

/// Result of one attempted step.
pub enum Attempt<const N: usize> {
    /// Accepted; the next step size to try.
    Accepted(Box<Step<N>>, f64),
    /// Rejected; the smaller step size to try.
    Rejected(f64),
}

/// One Dormand-Prince step of size `h` from `(t, y)` with derivative `f0`.
pub fn attempt<const N: usize>(
    rhs: &mut dyn FnMut(f64, &[f64; N]) -> [f64; N],
    t: f64,
    y: &[f64; N],
    f0: &[f64; N],
    h: f64,
    tol: &Tolerance<N>,
) -> Attempt<N> {
    let len = tol.len;
    let stage = |coef: &[(f64, &[f64; N])]| -> [f64; N] {
        let mut out = *y;
        for (c, k) in coef {
            for i in 0..len {
                out[i] += h * c * k[i];
            }
        }
        out
    };
    let k1 = *f0;
    let k2 = rhs(t + C2 * h, &stage(&[(A21, &k1)]));
    let k3 = rhs(t + C3 * h, &stage(&[(A31, &k1), (A32, &k2)]));
    let k4 = rhs(t + C4 * h, &stage(&[(A41, &k1), (A42, &k2), (A43, &k3)]));
    let k5 = rhs(
        t + C5 * h,
        &stage(&[(A51, &k1), (A52, &k2), (A53, &k3), (A54, &k4)]),
    );
    let k6 = rhs(
        t + h,
        &stage(&[(A61, &k1), (A62, &k2), (A63, &k3), (A64, &k4), (A65, &k5)]),
    );
    let y1 = stage(&[(A71, &k1), (A73, &k3), (A74, &k4), (A75, &k5), (A76, &k6)]);
    let k7 = rhs(t + h, &y1);

    // Error in the weighted RMS norm.
    let mut sum = 0.0;
    for i in 0..len {
        let e = h * (E1 * k1[i] + E3 * k3[i] + E4 * k4[i] + E5 * k5[i] + E6 * k6[i] + E7 * k7[i]);
        let sc = tol.atol[i] + tol.rtol * y[i].abs().max(y1[i].abs());
        sum += (e / sc) * (e / sc);
    }
    let err = (sum / len as f64).sqrt();
    if !err.is_finite() {
        return Attempt::Rejected(0.2 * h);
    }
    let factor = (0.9 * err.powf(-0.2)).clamp(0.2, 5.0);
    if err > 1.0 {
        return Attempt::Rejected(h * factor.min(1.0));
    }
    // Dense output coefficients (HNW II, dopri5 contd5).
    let mut rcont = [[0.0; N]; 5];
    for i in 0..len {
        let ydiff = y1[i] - y[i];
        let bspl = h * k1[i] - ydiff;
        rcont[0][i] = y[i];
        rcont[1][i] = ydiff;
        rcont[2][i] = bspl;
        rcont[3][i] = ydiff - h * k7[i] - bspl;
        rcont[4][i] =
            h * (D1 * k1[i] + D3 * k3[i] + D4 * k4[i] + D5 * k5[i] + D6 * k6[i] + D7 * k7[i]);
    }
    Attempt::Accepted(
        Box::new(Step {
            t0: t,
            h,
            y0: *y,
            y1,
            rcont,
            f1: k7,
            len,
        }),
        h * factor,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Integrates y' = f from 0 to t_end with the controller; returns y(t_end).
    fn integrate<const N: usize>(
        f: &mut dyn FnMut(f64, &[f64; N]) -> [f64; N],
        y0: [f64; N],
        t_end: f64,
        rtol: f64,
    ) -> ([f64; N], Vec<Box<Step<N>>>) {
        let tol = Tolerance {
            rtol,
            atol: [rtol; N],
            len: N,
        };
        let (mut t, mut y, mut h): (f64, _, f64) = (0.0, y0, 1e-3);
        let mut f0 = f(0.0, &y);
        let mut steps = Vec::new();
        while t < t_end {
            h = h.min(t_end - t);
            match attempt(f, t, &y, &f0, h, &tol) {
                Attempt::Accepted(s, next) => {
                    t = s.t1();
                    y = s.y1;
                    f0 = s.f1;
                    h = next;
                    steps.push(s);
                }
                Attempt::Rejected(next) => h = next,
            }
        }
        (y, steps)
    }

    #[test]
    fn harmonic_oscillator_matches_closed_form() {
        // y'' = -y, y(0) = 1, y'(0) = 0: y = cos t.
        let mut f = |_t: f64, y: &[f64; 2]| [y[1], -y[0]];
        let (y, steps) = integrate(&mut f, [1.0, 0.0], 10.0, 1e-10);
        assert!((y[0] - 10f64.cos()).abs() < 1e-8, "{}", y[0] - 10f64.cos());
        // The dense output is 4th order: check mid-step values.
        let worst = steps
            .iter()
            .map(|s| {
                let tm = s.t0 + 0.37 * s.h;
                (s.at(tm)[0] - tm.cos()).abs()
            })
            .fold(0.0, f64::max);
        assert!(worst < 1e-8, "dense output error {worst}");
    }

    #[test]
    fn exponential_decay_fifth_order() {
        // y' = -y: halving rtol by 2^5 should shrink the error roughly in step.
        let mut f = |_t: f64, y: &[f64; 1]| [-y[0]];
        let (y, _) = integrate(&mut f, [1.0], 5.0, 1e-12);
        assert!((y[0] - (-5f64).exp()).abs() < 1e-11);
    }
}
