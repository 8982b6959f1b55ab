//! Lemke's complementary pivoting method for the linear complementarity problem
//!
//! ```text
//!   find z in R^n:   w = q + M z >= 0,   z >= 0,   z . w = 0
//! ```
//!
//! (Lemke, *Bimatrix equilibrium points and mathematical programming*, Management
//! Science 11, 1965; Cottle, Pang & Stone, *The Linear Complementarity Problem*,
//! 1992, sec. 4.4 "Lemke's method" and sec. 4.9 for the lexicographic degeneracy
//! resolution). The problem is augmented by an artificial variable `z0 >= 0` with
//! the covering vector `d = (1, ..., 1)`:
//!
//! ```text
//!   w - M z - d z0 = q
//! ```
//!
//! Starting from the basis of the `w` (with `z0 = max(-q_i)` entering and the row
//! of the most negative `q_i` leaving), each pivot brings in the complement of the
//! variable that just left, the minimum-ratio test choosing the row that leaves.
//! The path ends when `z0` leaves (a solution), when nothing blocks the entering
//! variable (a **secondary ray**: no solution found), or at the pivot cap.
//!
//! **Termination.** Ties in the ratio test are broken lexicographically on the rows
//! of `(B^-1 q, B^-1)` divided by the entering column: every basis is then
//! non-degenerate in the lexicographic order, no almost-complementary basis repeats,
//! and since there are finitely many the path ends in finitely many pivots (Cottle,
//! Pang & Stone, Thm. 4.4.4 with sec. 4.9). Degenerate problems are the common case
//! here (friction rows with `q_i = 0`, redundant contacts), so the rule is needed.
//! The worst case is still exponential in `n` (Murty, *Computational complexity of
//! complementary pivot methods*, 1978), so the caller states a pivot cap: each pivot
//! costs `O(n^2)`, a solve at most `O(cap n^2)`.
//!
//! **What a ray means.** If `M` is copositive-plus (e.g. positive semi-definite) a
//! secondary ray proves the problem infeasible (Cottle, Pang & Stone, Thm. 4.4.13).
//! For a merely copositive `M` (the contact problem with friction) a ray is "no
//! solution found"; for a general `M` (a slipping contact whose normal coefficient
//! is negative, Painleve's case) it may be the only honest answer.
//!
//! **Storage.** The method keeps the basis inverse `B^-1` (`n x n`), in a workspace
//! the caller holds ([`Lemke`], capacity `C`), and reads the columns of `M` from the
//! problem ([`Lcp::column`]), so that a problem built from blocks (the contact
//! problem of [`super::lcp`]) is never stored densely.
//!
//! **Polish and check.** After `z0` leaves, the basic values are refined once
//! against the problem's own columns (`x_B += B^-1 (q - B x_B)`, one step of
//! iterative refinement, Golub & Van Loan, *Matrix Computations*, sec. 3.5.3), and
//! the answer is checked: `z >= -tol`, `w >= -tol`, and `z_i <= tol` or
//! `w_i <= tol` for every `i`, with `tol` relative to the scales of `q`, `M`, `z`.
//! A failed check is reported ([`Outcome::Inexact`]), never passed off as a
//! solution.

use crate::real::Real;

/// A linear complementarity problem `w = q + M z`, given by its entries.
pub trait Lcp<T> {
    /// Its size `n`.
    fn size(&self) -> usize;
    /// `q_i`.
    fn q(&self, i: usize) -> T;
    /// Column `j` of `M` into `out[..n]`.
    fn column(&self, j: usize, out: &mut [T]);
}

/// How a solve ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Outcome {
    /// A solution, checked; in [`Lemke::z`] and [`Lemke::w`].
    Solved {
        /// Pivots taken.
        pivots: usize,
    },
    /// A secondary ray: nothing blocks the entering variable. No solution found
    /// (none exists when `M` is copositive-plus).
    Ray {
        /// Pivots taken.
        pivots: usize,
        /// The entering variable: `j < n` is `w_j`, `n + j` is `z_j`.
        entering: usize,
    },
    /// The pivot cap was reached.
    Cap {
        /// Pivots taken (the cap).
        pivots: usize,
    },
    /// The path ended at `z0 = 0` but the answer failed the check (rounding).
    Inexact {
        /// Pivots taken.
        pivots: usize,
    },
}

impl Outcome {
    /// The pivots taken.
    pub fn pivots(self) -> usize {
        match self {
            Outcome::Solved { pivots }
            | Outcome::Ray { pivots, .. }
            | Outcome::Cap { pivots }
            | Outcome::Inexact { pivots } => pivots,
        }
    }

    /// True for a checked solution.
    pub fn solved(self) -> bool {
        matches!(self, Outcome::Solved { .. })
    }
}

/// The pivot cap for a problem of size `n`: `10 n + 20`. Lemke's path takes
/// about `n` pivots on the contact problems measured (the tests record the
/// largest count); the cap bounds the exponential worst case.
pub const fn pivot_cap(n: usize) -> usize {
    10 * n + 20
}

/// The workspace of a solve of size at most `C`: the basis inverse, the basic
/// values and the answer.
pub struct Lemke<T, const C: usize> {
    /// `B^-1`, row by row.
    binv: [[T; C]; C],
    /// Basic values `B^-1 q`.
    xb: [T; C],
    /// The basic variable of each row: `j < n` is `w_j`, `n + j` is `z_j`, `2 n`
    /// is `z0`.
    basis: [usize; C],
    /// Scratch: the entering column, a column of `M`.
    col: [T; C],
    mcol: [T; C],
    /// The answer (after [`Outcome::Solved`]).
    z: [T; C],
    w: [T; C],
    n: usize,
}

impl<T: Real, const C: usize> Default for Lemke<T, C> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T: Real, const C: usize> Lemke<T, C> {
    /// An empty workspace.
    pub const fn new() -> Self {
        Lemke {
            binv: [[T::ZERO; C]; C],
            xb: [T::ZERO; C],
            basis: [0; C],
            col: [T::ZERO; C],
            mcol: [T::ZERO; C],
            z: [T::ZERO; C],
            w: [T::ZERO; C],
            n: 0,
        }
    }

    /// The capacity `C`.
    pub const fn capacity(&self) -> usize {
        C
    }

    /// `z` of the last solve (`n` entries).
    pub fn z(&self) -> &[T] {
        &self.z[..self.n]
    }

    /// `w = q + M z` of the last solve (`n` entries).
    pub fn w(&self) -> &[T] {
        &self.w[..self.n]
    }

    /// Solves `p` within `cap` pivots, with the covering vector `(1, ..., 1)`.
    /// Panics if `p.size() > C`.
    pub fn solve<P: Lcp<T>>(&mut self, p: &P, cap: usize) -> Outcome {
        self.solve_covering(p, cap, |_| T::ONE)
    }

    /// [`Lemke::solve`] with the covering vector `d` (`d(i) > 0` for every `i`):
    /// the start frees the row of the least `q_i / d_i`. Another covering vector
    /// starts another path: where `M` is not copositive, one path can end at a
    /// secondary ray while another reaches a solution (Cottle, Pang & Stone,
    /// sec. 4.4, the role of `d`).
    pub fn solve_covering<P: Lcp<T>>(
        &mut self,
        p: &P,
        cap: usize,
        d: impl Fn(usize) -> T,
    ) -> Outcome {
        let n = p.size();
        assert!(n <= C, "LCP of size {n} in a workspace of {C}");
        self.n = n;
        let mut q_scale = T::ZERO;
        let mut most_negative = T::ZERO;
        let mut r = usize::MAX;
        for i in 0..n {
            let qi = p.q(i);
            q_scale = q_scale.max(qi.abs());
            self.z[i] = T::ZERO;
            self.w[i] = qi;
            // The row that z0 = max(-q_i / d_i) frees first; ties: the later row
            // (the lexicographic rule on `(-q_i, -e_i)`).
            let ratio = qi / d(i);
            if ratio <= most_negative {
                most_negative = ratio;
                r = i;
            }
        }
        if r == usize::MAX || most_negative >= T::ZERO {
            return Outcome::Solved { pivots: 0 };
        }
        // The scale of M, for the pivot and tie tolerances.
        let mut m_scale = T::ZERO;
        for j in 0..n {
            p.column(j, &mut self.mcol[..n]);
            for i in 0..n {
                m_scale = m_scale.max(self.mcol[i].abs());
            }
        }
        let m_scale = if m_scale > T::ZERO { m_scale } else { T::ONE };
        // The start: B = I, x_B = q, then z0 in for the most negative row.
        for i in 0..n {
            self.binv[i][..n].fill(T::ZERO);
            self.binv[i][i] = T::ONE;
            self.xb[i] = p.q(i);
            self.basis[i] = i;
            self.col[i] = -d(i);
        }
        let z0 = 2 * n;
        self.pivot(r, n);
        let mut leaving = self.basis[r];
        self.basis[r] = z0;
        let mut pivots = 1;
        let tie = T::RANK_TOLERANCE;
        loop {
            if leaving == z0 {
                return self.finish(p, pivots, q_scale, m_scale);
            }
            if pivots >= cap {
                return Outcome::Cap { pivots };
            }
            // The entering variable: the complement of the one that left.
            let entering = if leaving < n {
                leaving + n
            } else {
                leaving - n
            };
            self.entering_column(p, entering, n);
            // Pivots below the rounding of the column are taken as zero: `B^-1`
            // is of the order of `1 / |M|`, a column of `M` times it of order one.
            let c_scale = (0..n).fold(T::ZERO, |s, i| s.max(self.col[i].abs()));
            let unit = if entering < n {
                T::ONE / m_scale
            } else {
                T::ONE
            };
            let piv_tol = tie * c_scale.max(unit);
            // The minimum-ratio test, lexicographic; z0 leaves on a tie.
            let mut best: Option<usize> = None;
            for i in 0..n {
                if self.col[i] <= piv_tol {
                    continue;
                }
                best = Some(match best {
                    None => i,
                    Some(b) => {
                        if self.lex_less(i, b, n, q_scale, m_scale, z0) {
                            i
                        } else {
                            b
                        }
                    }
                });
            }
            let Some(r) = best else {
                return Outcome::Ray { pivots, entering };
            };
            self.pivot(r, n);
            leaving = self.basis[r];
            self.basis[r] = entering;
            pivots += 1;
        }
    }

    /// True when row `i` comes before row `b` in the ratio test: a smaller
    /// `x_B,i / c_i`, or on a tie `z0`'s row, or the lexicographically smaller row
    /// of `B^-1 / c`.
    #[allow(clippy::too_many_arguments)]
    fn lex_less(&self, i: usize, b: usize, n: usize, q_scale: T, m_scale: T, z0: usize) -> bool {
        let tie = T::RANK_TOLERANCE;
        let (ci, cb) = (self.col[i], self.col[b]);
        let (ri, rb) = (self.xb[i] / ci, self.xb[b] / cb);
        let z_scale = q_scale / m_scale;
        if (ri - rb).abs() > tie * z_scale.max(ri.abs()).max(rb.abs()) {
            return ri < rb;
        }
        if self.basis[i] == z0 {
            return true;
        }
        if self.basis[b] == z0 {
            return false;
        }
        let inv_scale = T::ONE / m_scale;
        for k in 0..n {
            let (ei, eb) = (self.binv[i][k] / ci, self.binv[b][k] / cb);
            if (ei - eb).abs() > tie * inv_scale.max(ei.abs()).max(eb.abs()) {
                return ei < eb;
            }
        }
        // Equal rows (a duplicated constraint): the earlier row.
        i < b
    }

    /// `B^-1` times the column of variable `v` in `w - M z - d z0 = q`, into `col`.
    fn entering_column<P: Lcp<T>>(&mut self, p: &P, v: usize, n: usize) {
        if v < n {
            for i in 0..n {
                self.col[i] = self.binv[i][v];
            }
            return;
        }
        p.column(v - n, &mut self.mcol[..n]);
        for i in 0..n {
            let row = &self.binv[i];
            let mut s = T::ZERO;
            for k in 0..n {
                s -= row[k] * self.mcol[k];
            }
            self.col[i] = s;
        }
    }

    /// The pivot on row `r` of the entering column `col`.
    fn pivot(&mut self, r: usize, n: usize) {
        let inv = T::ONE / self.col[r];
        for k in 0..n {
            self.binv[r][k] *= inv;
        }
        self.xb[r] *= inv;
        let (xr, row_r) = (self.xb[r], self.binv[r]);
        for i in 0..n {
            if i == r {
                continue;
            }
            let f = self.col[i];
            if f == T::ZERO {
                continue;
            }
            for k in 0..n {
                self.binv[i][k] -= f * row_r[k];
            }
            self.xb[i] -= f * xr;
        }
    }

    /// The answer from the final basis: refined once, then checked.
    fn finish<P: Lcp<T>>(&mut self, p: &P, pivots: usize, q_scale: T, m_scale: T) -> Outcome {
        let n = self.n;
        for _ in 0..2 {
            self.read_answer(p, n);
            // Residual of `w - M z = q` at the basic values; `w` holds q + M z.
            // For a basic w_i the equation is exact by construction of `w`; the
            // residual of the rows is `w_i - (q + M z)_i` for basic w_i, and
            // `-(q + M z)_i` where w_i is not basic (it should be zero).
            for i in 0..n {
                let basic_w = (0..n).find(|&r| self.basis[r] == i).map(|r| self.xb[r]);
                self.col[i] = basic_w.unwrap_or(T::ZERO) - self.w[i];
            }
            // x_B += B^-1 r; the residual's sign: B x_B = q + (B x_B - q), and
            // B x_B - q = (w_basic - M z) - q = w_basic - (q + M z) = col.
            for r in 0..n {
                let mut s = T::ZERO;
                for k in 0..n {
                    s += self.binv[r][k] * self.col[k];
                }
                self.xb[r] -= s;
            }
        }
        self.read_answer(p, n);
        let z_scale = (0..n).fold(T::ZERO, |s, i| s.max(self.z[i].abs()));
        let tol = T::RANK_TOLERANCE * T::from_f64(100.0);
        let tol_z = tol * z_scale.max(q_scale / m_scale);
        let tol_w = tol * (q_scale + m_scale * z_scale);
        for i in 0..n {
            let (z, w) = (self.z[i], self.w[i]);
            let ok = z.is_finite()
                && w.is_finite()
                && z >= -tol_z
                && w >= -tol_w
                && (z <= tol_z || w <= tol_w);
            if !ok {
                return Outcome::Inexact { pivots };
            }
            self.z[i] = z.max(T::ZERO);
        }
        Outcome::Solved { pivots }
    }

    /// `z` from the basic values and `w = q + M z` from the problem.
    fn read_answer<P: Lcp<T>>(&mut self, p: &P, n: usize) {
        for i in 0..n {
            self.z[i] = T::ZERO;
        }
        for r in 0..n {
            let v = self.basis[r];
            if v >= n && v < 2 * n {
                self.z[v - n] = self.xb[r];
            }
        }
        for i in 0..n {
            self.w[i] = p.q(i);
        }
        for j in 0..n {
            let zj = self.z[j];
            if zj == T::ZERO {
                continue;
            }
            p.column(j, &mut self.mcol[..n]);
            for i in 0..n {
                self.w[i] += self.mcol[i] * zj;
            }
        }
    }
}

/// A dense problem: `M` row by row in `C x C` storage (tests, small problems).
pub struct Dense<'a, T, const C: usize> {
    /// `M`.
    pub m: &'a [[T; C]; C],
    /// `q`.
    pub q: &'a [T; C],
    /// The size `n <= C`.
    pub n: usize,
}

impl<T: Real, const C: usize> Lcp<T> for Dense<'_, T, C> {
    fn size(&self) -> usize {
        self.n
    }
    fn q(&self, i: usize) -> T {
        self.q[i]
    }
    fn column(&self, j: usize, out: &mut [T]) {
        for (i, o) in out.iter_mut().enumerate().take(self.n) {
            *o = self.m[i][j];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    extern crate std;
    use std::vec::Vec;

    /// Solves a dense problem of size `n <= 8`.
    fn solve_dense<T: Real>(m: &[[T; 8]; 8], q: &[T; 8], n: usize) -> (Outcome, [T; 8], [T; 8]) {
        let mut work: Lemke<T, 8> = Lemke::new();
        let out = work.solve(&Dense { m, q, n }, pivot_cap(n));
        let mut z = [T::ZERO; 8];
        let mut w = [T::ZERO; 8];
        z[..n].copy_from_slice(work.z());
        w[..n].copy_from_slice(work.w());
        (out, z, w)
    }

    /// `w >= -tol`, `z >= -tol`, `z_i w_i <= tol` (relative to the problem's
    /// scales), and `w = q + M z`.
    fn assert_complementary(m: &[[f64; 8]; 8], q: &[f64; 8], n: usize, z: &[f64; 8], w: &[f64; 8]) {
        let scale = (0..n).fold(1.0f64, |s, i| {
            (0..n).fold(s.max(q[i].abs()).max(z[i].abs()), |s, j| {
                s.max(m[i][j].abs())
            })
        });
        let tol = 1e-8 * scale * scale;
        for i in 0..n {
            let wi = q[i] + (0..n).map(|j| m[i][j] * z[j]).sum::<f64>();
            assert!(
                (wi - w[i]).abs() <= tol,
                "w[{i}] = {} but q + M z = {wi}",
                w[i]
            );
            assert!(z[i] >= -tol, "z[{i}] = {}", z[i]);
            assert!(w[i] >= -tol, "w[{i}] = {}", w[i]);
            assert!(
                (z[i] * w[i]).abs() <= tol,
                "z[{i}] w[{i}] = {}",
                z[i] * w[i]
            );
        }
    }

    fn one<T: Real>(a: f64, b: f64) -> (Outcome, T) {
        let mut m = [[T::ZERO; 8]; 8];
        let mut q = [T::ZERO; 8];
        m[0][0] = T::from_f64(a);
        q[0] = T::from_f64(b);
        let (out, z, _) = solve_dense(&m, &q, 1);
        (out, z[0])
    }

    /// One contact, `w = A lambda + B`: lift-off (`lambda = 0`) for `B >= 0`,
    /// `lambda = -B / A` for `A > 0 > B`, and a ray exactly when `A <= 0` and
    /// `B < 0` (Painleve's inconsistent case).
    #[test]
    fn one_contact_closed_forms() {
        for (a, b) in [
            (2.0, -3.0),
            (0.5, -1e-9),
            (7.0, 4.0),
            (-2.0, 3.0),
            (-2.0, 0.0),
            (2.0, 0.0),
        ] {
            let (out, z) = one::<f64>(a, b);
            assert!(out.solved(), "A = {a}, B = {b}: {out:?}");
            let expected = if b < 0.0 { -b / a } else { 0.0 };
            assert!(
                (z - expected).abs() <= 1e-15 * expected.abs().max(1.0),
                "A = {a}, B = {b}: {z}"
            );
            let (out32, z32) = one::<f32>(a, b);
            assert!(out32.solved());
            assert!((z32.to_f64() - expected).abs() <= 1e-6 * expected.abs().max(1.0));
        }
        for (a, b) in [(-2.0, -3.0), (0.0, -1.0), (-1e-3, -1e-3)] {
            let (out, _) = one::<f64>(a, b);
            assert!(
                matches!(
                    out,
                    Outcome::Ray {
                        pivots: 1,
                        entering: 1
                    }
                ),
                "A = {a}, B = {b}: {out:?}"
            );
        }
        // B >= 0 takes no pivot; A > 0 > B takes two (z0 in, then lambda in and
        // z0 out).
        assert_eq!(one::<f64>(-2.0, 3.0).0, Outcome::Solved { pivots: 0 });
        assert_eq!(one::<f64>(2.0, -3.0).0, Outcome::Solved { pivots: 2 });
    }

    /// A degenerate problem (equal rows, `q` ties) ends at a solution, not in a
    /// cycle: `M = [[1, 1], [1, 1]]`, `q = (-1, -1)` has the solutions
    /// `z1 + z2 = 1`.
    #[test]
    fn degenerate_ties_end() {
        let mut m = [[0.0; 8]; 8];
        let mut q = [0.0; 8];
        for i in 0..2 {
            for j in 0..2 {
                m[i][j] = 1.0;
            }
            q[i] = -1.0;
        }
        let (out, z, w) = solve_dense(&m, &q, 2);
        assert!(out.solved(), "{out:?}");
        assert!((z[0] + z[1] - 1.0).abs() < 1e-14);
        assert_complementary(&m, &q, 2, &z, &w);
        // Murty's degenerate 3 x 3 with a zero q: z = 0 at once.
        let q0 = [0.0; 8];
        assert_eq!(solve_dense(&m, &q0, 3).0, Outcome::Solved { pivots: 0 });
    }

    /// A problem with no solution and a positive semi-definite `M`: a ray.
    /// `M = [[1, -1], [-1, 1]]`, `q = (-1, -1)`: `w1 + w2 = -2 < 0` for any z.
    #[test]
    fn infeasible_psd_rays() {
        let mut m = [[0.0; 8]; 8];
        m[0][0] = 1.0;
        m[0][1] = -1.0;
        m[1][0] = -1.0;
        m[1][1] = 1.0;
        let mut q = [0.0; 8];
        q[0] = -1.0;
        q[1] = -1.0;
        assert!(matches!(solve_dense(&m, &q, 2).0, Outcome::Ray { .. }));
    }

    /// A cap of one pivot stops a problem that needs two.
    #[test]
    fn the_cap_stops() {
        let mut m = [[0.0; 8]; 8];
        let mut q = [0.0; 8];
        m[0][0] = 2.0;
        q[0] = -3.0;
        let mut work: Lemke<f64, 8> = Lemke::new();
        assert_eq!(
            work.solve(&Dense { m: &m, q: &q, n: 1 }, 1),
            Outcome::Cap { pivots: 1 }
        );
    }

    fn matrix(n: usize) -> impl Strategy<Value = Vec<f64>> {
        prop::collection::vec(-1.0f64..1.0, n * n)
    }

    proptest! {
        /// `M = R R^T + S - S^T + eps I` (positive definite, not symmetric): Lemke
        /// always solves it, in at most `2 n + 2` pivots here (recorded), and the
        /// answer is complementary.
        #[test]
        fn positive_definite_is_solved(
            n in 1usize..=8,
            r in matrix(8),
            s in matrix(8),
            q in prop::collection::vec(-1.0f64..1.0, 8),
        ) {
            let mut m = [[0.0; 8]; 8];
            for i in 0..n {
                for j in 0..n {
                    let rr: f64 = (0..n).map(|k| r[i * 8 + k] * r[j * 8 + k]).sum();
                    m[i][j] = rr + s[i * 8 + j] - s[j * 8 + i] + if i == j { 1e-3 } else { 0.0 };
                }
            }
            let q: [f64; 8] = core::array::from_fn(|i| q[i]);
            let (out, z, w) = solve_dense(&m, &q, n);
            prop_assert!(out.solved(), "{:?}", out);
            prop_assert!(out.pivots() <= pivot_cap(n));
            assert_complementary(&m, &q, n, &z, &w);
        }

        /// Strictly copositive, not positive semi-definite: a positive matrix plus
        /// a small indefinite symmetric part. Solved and complementary.
        #[test]
        fn strictly_copositive_is_solved(
            n in 1usize..=8,
            p in prop::collection::vec(0.1f64..1.0, 64),
            s in matrix(8),
            q in prop::collection::vec(-1.0f64..1.0, 8),
        ) {
            let mut m = [[0.0; 8]; 8];
            for i in 0..n {
                for j in 0..n {
                    m[i][j] = p[i * 8 + j] + 0.05 * (s[i * 8 + j] + s[j * 8 + i]);
                }
            }
            let q: [f64; 8] = core::array::from_fn(|i| q[i]);
            let (out, z, w) = solve_dense(&m, &q, n);
            prop_assert!(out.solved(), "{:?}", out);
            assert_complementary(&m, &q, n, &z, &w);
        }

        /// Positive semi-definite of rank 1 or 2 with duplicated rows (the
        /// redundant contacts' degeneracy) and a feasible `q`: `q = -M x + v` with
        /// `x, v >= 0` and `x . v = 0` has the solution `z = x`, so Lemke's path
        /// must end at a solution (a ray would prove it infeasible, `M` being
        /// copositive-plus), and the answer is complementary.
        #[test]
        fn semidefinite_feasible_is_solved(
            n in 2usize..=8,
            r in matrix(8),
            x in prop::collection::vec(0.0f64..1.0, 8),
            v in prop::collection::vec(0.0f64..1.0, 8),
            sign in prop::collection::vec(prop::bool::ANY, 8),
        ) {
            let rank = 1 + n % 2;
            let mut m = [[0.0; 8]; 8];
            for i in 0..n {
                for j in 0..n {
                    m[i][j] = (0..rank).map(|k| r[(i % 3) * 8 + k] * r[(j % 3) * 8 + k]).sum();
                }
            }
            // q = -M x' + v' with x' >= 0 complementary to v' >= 0 gives the
            // solution z = x'; keep it feasible but let the signs vary.
            let mut q = [0.0; 8];
            for i in 0..n {
                let xi = if sign[i] { x[i] } else { 0.0 };
                let vi = if sign[i] { 0.0 } else { v[i] };
                q[i] += vi;
                for k in 0..n {
                    q[k] -= m[k][i] * xi;
                }
            }
            let (out, z, w) = solve_dense(&m, &q, n);
            prop_assert!(out.solved(), "{:?}", out);
            assert_complementary(&m, &q, n, &z, &w);
        }
    }
}
