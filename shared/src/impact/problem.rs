//! The impact problem in contact coordinates.
//!
//! For a mechanism with generalized velocities `q'`, mass matrix `M` and contact
//! Jacobian rows `J_n,i` (normal) and `J_t,i` (tangential), the contact velocities
//! are `u = J q'` and an impulse `P` changes them by `W P`, with the Delassus matrix
//! `W = J M^-1 J^T` (Moreau; Glocker 2001, ch. 7). The solver needs only `W`, the
//! pre-impact contact velocities and the laws; the mechanics stays with the caller.

use super::outcome::SlipState;
use crate::real::Real;
use crate::Enumerated;

/// The impact law that ends the restitution phase.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ImpactLaw {
    /// Poisson (the paper's eq. (4)): restitution normal impulse = `R` times the
    /// compression normal impulse.
    Poisson,
    /// Newton (kinematic): normal velocity after = `-R` times normal velocity before.
    Newton,
    /// Stronge (energetic): work of the normal impulse in restitution = `R^2` times
    /// the magnitude of its work in compression.
    Stronge,
}

/// Every law in the order the docs list them, named as case and machine files
/// write them.
impl Enumerated for ImpactLaw {
    const ALL: &'static [ImpactLaw] = &[ImpactLaw::Poisson, ImpactLaw::Newton, ImpactLaw::Stronge];

    fn name(self) -> &'static str {
        match self {
            ImpactLaw::Poisson => "poisson",
            ImpactLaw::Newton => "newton",
            ImpactLaw::Stronge => "stronge",
        }
    }
}

/// The law of one contact.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContactLaw<T> {
    /// Coefficient of restitution `R`, in [0, 1] (meaning set by [`ImpactLaw`]).
    pub restitution: T,
    /// Coulomb friction coefficient `mu`, >= 0.
    pub friction: T,
    /// Relative contact stiffness, > 0: shares the impulse where the contacts alone
    /// leave it undetermined (weighted minimum norm).
    pub weight: T,
}

impl<T: Real> Default for ContactLaw<T> {
    fn default() -> Self {
        ContactLaw {
            restitution: T::ZERO,
            friction: T::ZERO,
            weight: T::ONE,
        }
    }
}

/// One impact: `len` contacts (at most `N`), their Delassus matrix, their velocities
/// before the impact and their laws. Unused entries (index >= `len`) are ignored.
///
/// Sign conventions (docs/impact-model.md, "Conventions"): a contact's normal impulse
/// `P_n >= 0` acts along its normal `n`, its tangential impulse `P_t` along
/// `t = (-n_y, n_x)`; `u_n < 0` is approaching.
#[derive(Clone, Debug)]
pub struct ImpactProblem<T, const N: usize> {
    /// Number of contacts in use.
    pub len: usize,
    /// `w_nn[i][j]`: change of contact i's normal velocity (m/s) per unit normal
    /// impulse (N s) at contact j.
    pub w_nn: [[T; N]; N],
    /// `w_nt[i][j]`: change of contact i's normal velocity per unit tangential
    /// impulse at contact j. The tangential-normal block is its transpose.
    pub w_nt: [[T; N]; N],
    /// `w_tt[i][j]`: change of contact i's tangential velocity per unit tangential
    /// impulse at contact j.
    pub w_tt: [[T; N]; N],
    /// Normal velocities before the impact, m/s (negative: approaching).
    pub u_n: [T; N],
    /// Tangential velocities before the impact, m/s.
    pub u_t: [T; N],
    /// The contacts' laws.
    pub contacts: [ContactLaw<T>; N],
    /// The impact law.
    pub law: ImpactLaw,
}

impl<T: Real, const N: usize> ImpactProblem<T, N> {
    /// An empty problem (no contacts) under `law`.
    pub fn new(law: ImpactLaw) -> Self {
        ImpactProblem {
            len: 0,
            w_nn: [[T::ZERO; N]; N],
            w_nt: [[T::ZERO; N]; N],
            w_tt: [[T::ZERO; N]; N],
            u_n: [T::ZERO; N],
            u_t: [T::ZERO; N],
            contacts: [ContactLaw::default(); N],
            law,
        }
    }

    /// Normal and tangential velocity changes of every contact for the impulses
    /// `p_n`, `p_t`: `du = W P`.
    pub fn velocity_change(&self, p_n: &[T; N], p_t: &[T; N]) -> ([T; N], [T; N]) {
        let mut du_n = [T::ZERO; N];
        let mut du_t = [T::ZERO; N];
        self.velocity_change_into(p_n, p_t, &mut du_n, &mut du_t);
        (du_n, du_t)
    }

    /// [`ImpactProblem::velocity_change`] written into `du_n`, `du_t` (entries from
    /// `len` on set to zero), without the arrays returned by value.
    pub fn velocity_change_into(
        &self,
        p_n: &[T; N],
        p_t: &[T; N],
        du_n: &mut [T; N],
        du_t: &mut [T; N],
    ) {
        let n = self.len;
        for i in 0..n {
            let (a, b) = self.row_times(i, p_n, p_t);
            du_n[i] = a;
            du_t[i] = b;
        }
        du_n[n..].fill(T::ZERO);
        du_t[n..].fill(T::ZERO);
    }

    /// The contact velocities after the impulses `p_n`, `p_t` from the velocities
    /// before: `u = u0 + W P` (the same sums as [`ImpactProblem::velocity_change`]),
    /// for the first `len` contacts.
    pub fn velocities_after(&self, p_n: &[T; N], p_t: &[T; N], u_n: &mut [T; N], u_t: &mut [T; N]) {
        for i in 0..self.len {
            let (a, b) = self.row_times(i, p_n, p_t);
            u_n[i] = self.u_n[i] + a;
            u_t[i] = self.u_t[i] + b;
        }
    }

    /// Row `i` of `W P`: the changes of contact `i`'s normal and tangential
    /// velocities, summed over the contacts in order.
    #[inline(always)]
    fn row_times(&self, i: usize, p_n: &[T; N], p_t: &[T; N]) -> (T, T) {
        let n = self.len;
        let (p_n, p_t) = (&p_n[..n], &p_t[..n]);
        let (w_nn, w_nt, w_tt) = (&self.w_nn[i][..n], &self.w_nt[i][..n], &self.w_tt[i][..n]);
        let mut a = T::ZERO;
        let mut b = T::ZERO;
        for j in 0..n {
            a += w_nn[j] * p_n[j] + w_nt[j] * p_t[j];
            b += self.w_nt[j][i] * p_n[j] + w_tt[j] * p_t[j];
        }
        (a, b)
    }
}

/// Contact `j`'s tangential impulse per unit normal impulse in its friction
/// state `mode[j]` (Coulomb): `-mu_j s_j` while it slips with the sign `s_j`
/// (the friction opposes the slip), 0 while it sticks (its tangential impulse
/// is then an unknown of its own).
pub(crate) fn slip_coeff<T: Real, const N: usize>(
    p: &ImpactProblem<T, N>,
    mode: &[SlipState; N],
    j: usize,
) -> T {
    match mode[j] {
        SlipState::Stick => T::ZERO,
        s => -p.contacts[j].friction * s.sign::<T>(),
    }
}
