//! The direction of one piece of the impulse path: which contacts take normal
//! impulse, in what proportion, and the friction state of each.
//!
//! Along a piece the impulses grow linearly in a path parameter `lambda`:
//! `P(lambda) = P0 + lambda (x, y)`, so the contact velocities change by
//! `lambda W (x, y)` (Darboux-Keller in impulse space; Stronge 2000, ch. 5).
//! Two rules fix the normal rates `x`:
//!
//! - [`NormalRule::Target`]: the proportion that brings every active contact's
//!   normal velocity to its target `g` at `lambda = 1` (compression: `g = 0`, the
//!   paper's hypothesis that the impacts end together; Newton's restitution:
//!   `g = -R u_n0`). Contacts whose share would be negative are released, which
//!   makes it a linear complementarity problem:
//!   `x >= 0, v = u_n + (W_eff x) - g >= 0, x . v = 0`.
//!   Contacts above their target take no share (they join at an event of the
//!   path); [`NormalRule::TargetAll`] lets every contact take one (persistent
//!   contact at acceleration level).
//! - [`NormalRule::Fixed`]: `x` given (Poisson's and Stronge's restitution).
//!
//! Friction (Coulomb): a slipping contact's tangential rate is `y = -mu s x`; a
//! sticking one's `y` is whatever holds its tangential velocity, if
//! `|y| <= mu x`; a contact at zero slip sticks, or slips the way its tangential
//! velocity then moves.
//!
//! **The method.** Normal rates, friction states and the split of the friction
//! of contacts at zero slip between the cone's two edges are one linear
//! complementarity problem (Stewart & Trinkle's form, `ContactLcp`), solved by
//! Lemke's method ([`super::lemke`]) within its pivot cap: `O(m)` pivots of
//! `O(m^2)` each for `m <= 4` unknowns per contact, so polynomial in the contacts.
//! (The enumeration of active sets and friction states, `4^k` candidates for `k`
//! contacts at zero slip, is the tests' oracle.)
//! The modes are read off its solution with the enumeration's tie-breaks (larger
//! active sets, stick first), and the rates are then those of the modes'
//! equations ([`solve_states`]): where the equations leave the impulses
//! undetermined (a singular Delassus matrix), the weighted minimum-norm solution
//! with the contacts' weights ([`super::linalg`]), moved to the closest split
//! inside every cone where it leaves one ([`super::split`]). Lemke's own rates,
//! which are complementary, are taken where those fail the check at a boundary.
//! Where Lemke's path ends at a secondary ray or its cap, the direction is not
//! `consistent` (or, for a `Target` rule, does not end at one): with a slipping
//! contact the problem's matrix need not be copositive (Painleve's
//! `W_nn - mu s W_nt < 0`), and the callers apply their rule for it.

use super::lemke::{pivot_cap, Lcp, Lemke, Outcome};
use super::linalg::{solve_weighted_into, Solved, DIM};
use super::outcome::SlipState;
use super::problem::{slip_coeff, ImpactProblem};
use super::split::{within_cones, Split};
use super::MAX_CONTACTS;
use crate::real::Real;

#[cfg(test)]
mod oracle;
#[cfg(test)]
mod tests;

/// Tolerances of one impact, scaled to its velocities and impulses.
#[derive(Clone, Copy, Debug)]
pub struct Tolerances<T> {
    /// Velocities, m/s.
    pub velocity: T,
    /// Impulses, N s.
    pub impulse: T,
    /// Slip velocities within this may be taken as zero slip, m/s, when the
    /// states that the slips impose leave no consistent direction (0: never).
    /// A contact can keep a slip that no impulse can end: two feet of a rigid
    /// body have the same tangential velocity up to its rotation times their
    /// height difference, so when one sticks the other keeps what that leaves
    /// (seen: 6e-7 of the impact's velocities on a platform tilted by a
    /// micro-radian). Forced to slip there under large friction, it finds no
    /// consistent proportion; at zero slip its state is chosen like any other,
    /// which changes the velocities by at most this much.
    pub zero_slip: T,
}

/// How the normal impulse rates of a piece are chosen.
#[derive(Clone, Copy, Debug)]
pub enum NormalRule<'a, T, const N: usize> {
    /// Complementarity toward these normal velocities at `lambda = 1`; contacts
    /// above their target (separating) take no share (they join at an event of the
    /// impulse path).
    Target(&'a [T; N]),
    /// Complementarity toward these targets with every contact able to take a
    /// share, also one above its target: persistent contact at acceleration level,
    /// where a touching contact at rest whose free acceleration separates it can
    /// still be held by the others' forces (there is no path for it to join later).
    TargetAll(&'a [T; N]),
    /// These normal rates.
    Fixed(&'a [T; N]),
}

/// The rates of one piece.
#[derive(Clone, Copy, Debug)]
pub struct Direction<T, const N: usize> {
    /// Normal impulse rates, N s per unit `lambda` (>= 0).
    pub x: [T; N],
    /// Tangential impulse rates.
    pub y: [T; N],
    /// Normal velocity rates `W_nn x + W_nt y`.
    pub du_n: [T; N],
    /// Tangential velocity rates `W_tn x + W_tt y`.
    pub du_t: [T; N],
    /// Friction state of each contact taking normal impulse.
    pub mode: [SlipState; N],
    /// The contacts of the active set: held at their target, with a normal rate
    /// `>= 0` that may be zero (a contact at the boundary of both conditions is
    /// active when the larger set is admissible: the enumeration's tie-break).
    pub active: [bool; N],
    /// The target is reached at `lambda = 1` (false for a fixed rule, and for the
    /// fallback where no complementary proportion exists).
    pub ends_at_one: bool,
    /// A consistent set of states was found.
    pub consistent: bool,
    /// How the last Lemke solve of the direction ended (its pivots; a ray or
    /// the cap where no consistent states were found).
    pub outcome: Outcome,
}

/// What the rates of a piece add to, and the slip velocities.
#[derive(Clone, Copy)]
pub(crate) struct Base<'a, T, const N: usize> {
    u_n: &'a [T; N],
    u_t: &'a [T; N],
    slip: &'a [T; N],
    /// Every contact may take a share ([`NormalRule::TargetAll`]).
    all: bool,
}

/// A candidate being assembled: active contacts and friction states.
struct Candidate<const N: usize> {
    active: [bool; N],
    mode: [SlipState; N],
}

impl<T: Real, const N: usize> Default for Direction<T, N> {
    /// No rates, every contact sticking and inactive, not consistent: storage for
    /// the `_into` functions, which write every field.
    fn default() -> Self {
        Direction {
            x: [T::ZERO; N],
            y: [T::ZERO; N],
            du_n: [T::ZERO; N],
            du_t: [T::ZERO; N],
            mode: [SlipState::Stick; N],
            active: [false; N],
            ends_at_one: false,
            consistent: false,
            outcome: Outcome::Solved { pivots: 0 },
        }
    }
}

/// Finds the direction of the next piece from the current contact velocities.
///
/// `u_n`, `u_t` are the values the rates add to (in an impact, the contact
/// velocities; in persistent contact, the contact accelerations without contact
/// forces); `slip` are the tangential velocities that fix each contact's slip
/// state (in an impact, `u_t` itself).
pub fn find_direction<T: Real, const N: usize>(
    p: &ImpactProblem<T, N>,
    u_n: &[T; N],
    u_t: &[T; N],
    slip: &[T; N],
    rule: NormalRule<'_, T, N>,
    tol: &Tolerances<T>,
) -> Direction<T, N> {
    let mut d = Direction::default();
    find_direction_into(p, u_n, u_t, slip, rule, tol, &mut d);
    d
}

/// [`find_direction`] written into `out` (every field), so that the candidates
/// are solved in place rather than passed up by value.
pub fn find_direction_into<T: Real, const N: usize>(
    p: &ImpactProblem<T, N>,
    u_n: &[T; N],
    u_t: &[T; N],
    slip: &[T; N],
    rule: NormalRule<'_, T, N>,
    tol: &Tolerances<T>,
    out: &mut Direction<T, N>,
) {
    #[cfg(test)]
    if tests::USE_ORACLE.with(|o| o.get()) {
        oracle::enumerated_direction(p, u_n, u_t, slip, rule, tol, out);
        onto_cones(p, out);
        return;
    }
    direction_by(
        p,
        (u_n, u_t, slip),
        rule,
        tol,
        out,
        complementary_direction,
        fixed_direction,
    );
    onto_cones(p, out);
}

/// Puts every contact's rates exactly inside its cone: `x_i >= 0` and
/// `|y_i| <= mu_i x_i`, and the velocity rates recomputed where a rate moved.
///
/// The candidates are accepted with a normal rate down to `-tol.impulse` and a
/// force up to `tol.impulse` outside the cone (round-off in the solve); summed
/// over the pieces of an impact, or written as a force in persistent contact,
/// such a rate is a contact that pulls (-1e-11 N s was seen at 16 feet). The
/// move is within the tolerance the candidate was accepted with, and the
/// velocities follow from the impulses (`u = u0 + W P`), so they stay exact.
fn onto_cones<T: Real, const N: usize>(p: &ImpactProblem<T, N>, d: &mut Direction<T, N>) {
    let mut moved = false;
    for i in 0..p.len {
        let x = d.x[i].max(T::ZERO);
        let limit = p.contacts[i].friction * x;
        let y = d.y[i].max(-limit).min(limit);
        if x != d.x[i] || y != d.y[i] {
            d.x[i] = x;
            d.y[i] = y;
            moved = true;
        }
    }
    if moved {
        p.velocity_change_into(&d.x, &d.y, &mut d.du_n, &mut d.du_t);
    }
}

/// The direction of a rule with the two solvers given, into `out`: `fixed` for a
/// `Fixed` rule; `complementary` for a `Target` rule, again with the slips within
/// `zero_slip` taken as zero where it finds nothing, and else the jamming
/// fallback: `fixed` with every contact short of its target pushed in proportion
/// to its weight (`ends_at_one` false), keeping the complementary solve's
/// `outcome` to say why.
#[allow(clippy::type_complexity)]
pub(crate) fn direction_by<T: Real, const N: usize>(
    p: &ImpactProblem<T, N>,
    (u_n, u_t, slip): (&[T; N], &[T; N], &[T; N]),
    rule: NormalRule<'_, T, N>,
    tol: &Tolerances<T>,
    out: &mut Direction<T, N>,
    mut complementary: impl FnMut(
        &ImpactProblem<T, N>,
        &Base<'_, T, N>,
        &[T; N],
        &Tolerances<T>,
        &mut Direction<T, N>,
    ) -> bool,
    mut fixed: impl FnMut(
        &ImpactProblem<T, N>,
        &Base<'_, T, N>,
        &[T; N],
        &Tolerances<T>,
        &mut Direction<T, N>,
    ),
) {
    let all = matches!(rule, NormalRule::TargetAll(_));
    let base = Base {
        u_n,
        u_t,
        slip,
        all,
    };
    match rule {
        NormalRule::Fixed(x) => fixed(p, &base, x, tol, out),
        NormalRule::Target(g) | NormalRule::TargetAll(g) => {
            if complementary(p, &base, g, tol, out) {
                return;
            }
            let outcome = out.outcome;
            // No consistent proportion with the states the slips impose: take the
            // slips within `zero_slip` as zero (their states then chosen), if any.
            let mut loose = *slip;
            let mut loosened = false;
            for s in loose.iter_mut().take(p.len) {
                if *s != T::ZERO && s.abs() <= tol.zero_slip {
                    *s = T::ZERO;
                    loosened = true;
                }
            }
            if loosened {
                let base = Base {
                    slip: &loose,
                    ..base
                };
                if complementary(p, &base, g, tol, out) {
                    return;
                }
            }
            // No complementary proportion (jamming: a slipping contact whose normal
            // velocity falls under its own impulse). Push every contact that is
            // short of its target in proportion to its weight until a friction
            // event changes the states.
            let mut x = [T::ZERO; N];
            for i in 0..p.len {
                if u_n[i] < g[i] - tol.velocity {
                    x[i] = p.contacts[i].weight;
                }
            }
            fixed(p, &base, &x, tol, out);
            out.ends_at_one = false;
            out.outcome = outcome;
        }
    }
}

/// The friction state a contact's tangential velocity imposes, or `None` at zero
/// slip (to be chosen).
fn kinematic_state<T: Real>(u_t: T, tol: T) -> Option<SlipState> {
    if u_t > tol {
        Some(SlipState::SlipPositive)
    } else if u_t < -tol {
        Some(SlipState::SlipNegative)
    } else {
        None
    }
}

impl<T: Real, const N: usize> Base<'_, T, N> {
    /// The friction state each of the first `len` contacts' slip imposes
    /// ([`kinematic_state`], slip velocities within `tol.velocity` being zero
    /// slip), and stick at zero slip: the first choice there, before its
    /// slipping alternatives.
    fn kinematic_modes(&self, len: usize, tol: &Tolerances<T>) -> [SlipState; N] {
        let mut mode = [SlipState::Stick; N];
        for (m, &u_t) in mode.iter_mut().zip(&self.slip[..len]) {
            if let Some(s) = kinematic_state(u_t, tol.velocity) {
                *m = s;
            }
        }
        mode
    }
}

/// The contacts that the normal rates `x` of a `Fixed` rule push: those of a
/// positive rate (N s per unit `lambda`) among the first `p.len`.
fn pushed<T: Real, const N: usize>(p: &ImpactProblem<T, N>, x: &[T; N]) -> [bool; N] {
    let mut active = [false; N];
    for i in 0..p.len {
        active[i] = x[i] > T::ZERO;
    }
    active
}

/// The largest contact problem: a normal force and three friction unknowns (two
/// cone edges and the slip rate) per contact.
pub const MAX_LCP: usize = 4 * MAX_CONTACTS;

/// The complementarity problem of a `Target` rule by Lemke's method, into `out`.
/// Returns false when no consistent solution was found (`out.outcome` says why;
/// the rest of `out` then unspecified).
fn complementary_direction<T: Real, const N: usize>(
    p: &ImpactProblem<T, N>,
    base: &Base<'_, T, N>,
    g: &[T; N],
    tol: &Tolerances<T>,
    out: &mut Direction<T, N>,
) -> bool {
    let lcp = ContactLcp::new(p, base, Some(g), None, tol);
    decide(&lcp, base, tol, out)
}

/// The direction of a `Fixed` rule: friction states only, by Lemke's method on
/// the friction unknowns, into `out`.
fn fixed_direction<T: Real, const N: usize>(
    p: &ImpactProblem<T, N>,
    base: &Base<'_, T, N>,
    x: &[T; N],
    tol: &Tolerances<T>,
    out: &mut Direction<T, N>,
) {
    let lcp = ContactLcp::new(p, base, None, Some(x), tol);
    if decide(&lcp, base, tol, out) {
        return;
    }
    let outcome = out.outcome;
    clipped_direction(p, base, x, tol, out);
    out.outcome = outcome;
}

/// The fallback of a `Fixed` rule with no consistent friction states, into `out`:
/// every contact at zero slip taken as sticking, with its force clipped to the
/// cone (the closest admissible), and `consistent` false to say so.
fn clipped_direction<T: Real, const N: usize>(
    p: &ImpactProblem<T, N>,
    base: &Base<'_, T, N>,
    x: &[T; N],
    tol: &Tolerances<T>,
    out: &mut Direction<T, N>,
) {
    let active = pushed(p, x);
    let mode = base.kinematic_modes(p.len, tol);
    if solve_states_into(p, base.u_n, base.u_t, &active, &mode, None, Some(x), out).is_none() {
        zero_direction(p, x, out);
    }
    for i in 0..p.len {
        if mode[i] == SlipState::Stick {
            let limit = p.contacts[i].friction * out.x[i];
            out.y[i] = out.y[i].max(-limit).min(limit);
        }
    }
    let d = out;
    p.velocity_change_into(&d.x, &d.y, &mut d.du_n, &mut d.du_t);
    d.consistent = false;
}

/// The contact problem of one piece as a linear complementarity problem
/// (Stewart & Trinkle, *An implicit time-stepping scheme for rigid body dynamics
/// with inelastic collisions and Coulomb friction*, 1996, in the plane). The
/// contacts that can take a share (`all` of them, or those at or below their
/// target) are split by their slip: slipping ones (`S`, sign `s`) have their
/// friction fixed, `y = -mu s x`; those at zero slip (`Z`) have theirs as two
/// cone edges `y = b+ - b-` with the slip rate `sigma`:
///
/// ```text
///   w_n   =  W^_nn x + W_nZ (b+ - b-)       + u_n - g   >= 0  _|_  x   >= 0
///   w_+   =  W^_Zn x + W_ZZ (b+ - b-) + sig + u_t       >= 0  _|_  b+  >= 0
///   w_-   = -W^_Zn x - W_ZZ (b+ - b-) + sig - u_t       >= 0  _|_  b-  >= 0
///   w_sig =  mu x - b+ - b-                             >= 0  _|_  sig >= 0
/// ```
///
/// with `W^_.n[:, j] = W_.n[:, j] - mu_j s_j W_.t[:, j]` (a slipping contact's
/// friction folded into its normal column). `sig` is the slip rate `|du_t|`: where
/// it is positive the friction is on the cone's edge against it; where zero the
/// contact sticks with `|y| <= mu x`. With the normal rates `fixed`, the unknowns
/// are the friction ones only and `mu x` is part of `q`. The forces are scaled by
/// `s = max_i W_nn,ii` (`x' = s x`), so that every entry is a velocity (or an
/// acceleration) and the pivots compare like with like.
struct ContactLcp<'a, T, const N: usize> {
    p: &'a ImpactProblem<T, N>,
    /// The contacts with a normal unknown (empty when fixed).
    xs: [usize; N],
    nx: usize,
    /// The contacts at zero slip taking a share: friction unknowns.
    zs: [usize; N],
    nz: usize,
    /// Contacts in the problem (a share possible).
    member: [bool; N],
    /// [`slip_coeff`] of the slipping members (0 at zero slip).
    coeff: [T; N],
    /// `q` of the normal rows, the `b+` rows and the `sigma` rows.
    q_n: [T; N],
    q_t: [T; N],
    q_s: [T; N],
    /// The force scale `s`.
    scale: T,
    target: Option<&'a [T; N]>,
    fixed: Option<&'a [T; N]>,
}

impl<'a, T: Real, const N: usize> ContactLcp<'a, T, N> {
    fn new(
        p: &'a ImpactProblem<T, N>,
        base: &Base<'_, T, N>,
        target: Option<&'a [T; N]>,
        fixed: Option<&'a [T; N]>,
        tol: &Tolerances<T>,
    ) -> Self {
        let n = p.len;
        let mut lcp = ContactLcp {
            p,
            xs: [0; N],
            nx: 0,
            zs: [0; N],
            nz: 0,
            member: [false; N],
            coeff: [T::ZERO; N],
            q_n: [T::ZERO; N],
            q_t: [T::ZERO; N],
            q_s: [T::ZERO; N],
            scale: T::ONE,
            target,
            fixed,
        };
        let mut scale = T::ZERO;
        for i in 0..n {
            scale = scale.max(p.w_nn[i][i].abs()).max(p.w_tt[i][i].abs());
            lcp.member[i] = match (target, fixed) {
                // Only contacts at or below their target can take impulse; one
                // above it (separating) joins when its normal velocity comes down
                // to the target, an event of the path, not a choice made here.
                (Some(g), _) => base.all || base.u_n[i] <= g[i] + tol.velocity,
                (None, Some(x)) => x[i] > T::ZERO,
                (None, None) => false,
            };
            let state = kinematic_state(base.slip[i], tol.velocity);
            if let Some(s) = state {
                lcp.coeff[i] = -p.contacts[i].friction * s.sign::<T>();
            }
            if !lcp.member[i] {
                continue;
            }
            if let Some(g) = target {
                lcp.xs[lcp.nx] = i;
                lcp.nx += 1;
                lcp.q_n[i] = base.u_n[i] - g[i];
            }
            if state.is_none() {
                lcp.zs[lcp.nz] = i;
                lcp.nz += 1;
            }
        }
        if scale > T::ZERO && scale.is_finite() {
            lcp.scale = scale;
        }
        for l in 0..lcp.nz {
            let c = lcp.zs[l];
            let mut q = base.u_t[c];
            if let Some(x) = fixed {
                // The fixed normal rates' share: (W^_tn x)_c, and mu x in the sigma row.
                for j in 0..n {
                    if x[j] != T::ZERO {
                        q += lcp.w_tn(c, j) * x[j];
                    }
                }
                lcp.q_s[l] = p.contacts[c].friction * x[c] * lcp.scale;
            }
            lcp.q_t[l] = q;
        }
        lcp
    }

    /// `W^_nn[i][j]`: contact i's normal rate per unit normal rate at j, with j's
    /// friction when it slips.
    fn w_nn(&self, i: usize, j: usize) -> T {
        self.p.w_nn[i][j] + self.p.w_nt[i][j] * self.coeff[j]
    }

    /// `W^_tn[i][j]`: contact i's tangential rate per unit normal rate at j.
    fn w_tn(&self, i: usize, j: usize) -> T {
        self.p.w_nt[j][i] + self.p.w_tt[i][j] * self.coeff[j]
    }

    /// The tangential-normal block's transpose: contact i's normal rate per unit
    /// tangential rate at j.
    fn w_nt(&self, i: usize, j: usize) -> T {
        self.p.w_nt[i][j]
    }

    /// The rates of the modes `c` ([`solve_states_into`]: the weighted
    /// minimum-norm split, moved within the cones) into `d` where admissible.
    fn take(
        &self,
        base: &Base<'_, T, N>,
        c: &Candidate<N>,
        tol: &Tolerances<T>,
        d: &mut Direction<T, N>,
    ) -> bool {
        let p = self.p;
        let (g, fixed) = (self.target, self.fixed);
        match solve_states_into(p, base.u_n, base.u_t, &c.active, &c.mode, g, fixed, d) {
            Some((_, how)) => admissible(p, base, c, g, fixed.is_none(), how, d, tol).is_some(),
            None => false,
        }
    }

    /// The enumeration's first candidate, which it took when admissible: every
    /// member active, those at zero slip sticking.
    fn first_candidate(&self, base: &Base<'_, T, N>, tol: &Tolerances<T>) -> Candidate<N> {
        Candidate {
            active: self.member,
            mode: base.kinematic_modes(self.p.len, tol),
        }
    }

    /// Offsets of the `b+`, `b-`, `sigma` blocks.
    fn blocks(&self) -> (usize, usize, usize) {
        (self.nx, self.nx + self.nz, self.nx + 2 * self.nz)
    }
}

impl<T: Real, const N: usize> Lcp<T> for ContactLcp<'_, T, N> {
    fn size(&self) -> usize {
        self.nx + 3 * self.nz
    }

    fn q(&self, r: usize) -> T {
        let (bp, bm, sg) = self.blocks();
        if r < bp {
            self.q_n[self.xs[r]]
        } else if r < bm {
            self.q_t[r - bp]
        } else if r < sg {
            -self.q_t[r - bm]
        } else {
            self.q_s[r - sg]
        }
    }

    fn column(&self, c: usize, out: &mut [T]) {
        let (bp, bm, sg) = self.blocks();
        let inv = T::ONE / self.scale;
        out.fill(T::ZERO);
        if c < bp {
            // x'_j: W^_nn / s in the normal rows, W^_Zn / s in b+, minus in b-, mu
            // in its own sigma row.
            let j = self.xs[c];
            for (r, &i) in self.xs[..self.nx].iter().enumerate() {
                out[r] = self.w_nn(i, j) * inv;
            }
            for (l, &k) in self.zs[..self.nz].iter().enumerate() {
                let v = self.w_tn(k, j) * inv;
                out[bp + l] = v;
                out[bm + l] = -v;
                if k == j {
                    out[sg + l] = self.p.contacts[j].friction;
                }
            }
        } else if c < sg {
            // b+'_l (sign 1) or b-'_l (sign -1).
            let (l, sign) = if c < bm {
                (c - bp, T::ONE)
            } else {
                (c - bm, -T::ONE)
            };
            let j = self.zs[l];
            for (r, &i) in self.xs[..self.nx].iter().enumerate() {
                out[r] = sign * self.w_nt(i, j) * inv;
            }
            for (l2, &k) in self.zs[..self.nz].iter().enumerate() {
                let v = sign * self.p.w_tt[k][j] * inv;
                out[bp + l2] = v;
                out[bm + l2] = -v;
            }
            out[sg + l] = -T::ONE;
        } else {
            // sigma_l: 1 in its b+ and b- rows.
            let l = c - sg;
            out[bp + l] = T::ONE;
            out[bm + l] = T::ONE;
        }
    }
}

/// Solves the contact problem by Lemke's method in a workspace sized to it, and
/// reads the direction off a solution into `d`: true when consistent.
///
/// First the one candidate that the enumeration tried first and took when
/// admissible (every member active, stick at zero slip: the common case of feet
/// at rest), so that the decision is the enumeration's wherever that holds; then
/// Lemke's method.
///
/// The workspace lives on the stack of a call that is not inlined, sized to the
/// problem (`8`, `16`, `32` or [`MAX_LCP`] unknowns), so that a small problem never
/// reserves the largest one's basis inverse.
fn decide<T: Real, const N: usize>(
    lcp: &ContactLcp<'_, T, N>,
    base: &Base<'_, T, N>,
    tol: &Tolerances<T>,
    d: &mut Direction<T, N>,
) -> bool {
    if lcp.take(base, &lcp.first_candidate(base, tol), tol, d) {
        d.outcome = Outcome::Solved { pivots: 0 };
        return true;
    }
    match lcp.size() {
        0..=8 => decide_in::<T, N, 8>(lcp, base, tol, d),
        9..=16 => decide_in::<T, N, 16>(lcp, base, tol, d),
        17..=32 => decide_in::<T, N, 32>(lcp, base, tol, d),
        _ => decide_in::<T, N, MAX_LCP>(lcp, base, tol, d),
    }
}

/// [`decide`] in a workspace of `C` unknowns.
#[inline(never)]
fn decide_in<T: Real, const N: usize, const C: usize>(
    lcp: &ContactLcp<'_, T, N>,
    base: &Base<'_, T, N>,
    tol: &Tolerances<T>,
    d: &mut Direction<T, N>,
) -> bool {
    let mut work: Lemke<T, C> = Lemke::new();
    let n = lcp.size();
    let mut outcome = work.solve(lcp, pivot_cap(n));
    // Where the path ends without a solution (a ray: the matrix is not
    // copositive with a slipping contact; the cap; a failed check), the paths of
    // two other covering vectors, rising and falling along the unknowns: a
    // bounded number of extra solves, so the cost stays polynomial.
    let rising = |i: usize| T::ONE + T::from_f64(i as f64 / n as f64);
    let falling = |i: usize| T::ONE + T::from_f64((n - i) as f64 / n as f64);
    if !outcome.solved() {
        let first = outcome;
        outcome = work.solve_covering(lcp, pivot_cap(n), rising);
        if !outcome.solved() {
            outcome = work.solve_covering(lcp, pivot_cap(n), falling);
        }
        if !outcome.solved() {
            outcome = first;
        }
    }
    d.outcome = outcome;
    if !outcome.solved() {
        return false;
    }
    read_direction(lcp, base, work.z(), work.w(), tol, d);
    true
}

/// The direction from a solution `(z, w)` of the contact problem, into `d`.
///
/// The modes: a contact is active (held at its target) where its normal rate is
/// positive, and also where both its rate and its normal row are zero (the larger
/// set, as the enumeration's tie-break was); a contact at zero slip slips where its
/// slip rate `sigma` is positive, the way its tangential row then moves, and
/// sticks otherwise (stick first). The rates are then those of
/// [`solve_states_into`] for these modes (the weighted minimum-norm split, moved
/// within the cones), as for a given set of modes; where those fail the check
/// (rounding at a boundary), Lemke's own rates, which are complementary.
fn read_direction<T: Real, const N: usize>(
    lcp: &ContactLcp<'_, T, N>,
    base: &Base<'_, T, N>,
    z: &[T],
    w: &[T],
    tol: &Tolerances<T>,
    d: &mut Direction<T, N>,
) {
    let p = lcp.p;
    let inv = T::ONE / lcp.scale;
    let (bp, bm, sg) = lcp.blocks();
    let mut cand = Candidate {
        active: [false; N],
        mode: base.kinematic_modes(p.len, tol),
    };
    let mut x = lcp.fixed.copied().unwrap_or([T::ZERO; N]);
    let mut y = [T::ZERO; N];
    for i in 0..p.len {
        cand.active[i] = lcp.fixed.is_some() && lcp.member[i];
    }
    for (r, &i) in lcp.xs[..lcp.nx].iter().enumerate() {
        x[i] = z[r] * inv;
        cand.active[i] = x[i] > tol.impulse || w[r] <= tol.velocity;
    }
    for (l, &i) in lcp.zs[..lcp.nz].iter().enumerate() {
        let sigma = z[sg + l];
        y[i] = (z[bp + l] - z[bm + l]) * inv;
        if sigma > tol.velocity {
            // w_+ = du_t + sigma: the tangential row's sign.
            let du_t = w[bp + l] - sigma;
            cand.mode[i] = if du_t > T::ZERO {
                SlipState::SlipPositive
            } else {
                SlipState::SlipNegative
            };
        }
    }
    for i in 0..p.len {
        if cand.active[i] && cand.mode[i] != SlipState::Stick {
            y[i] = slip_coeff(p, &cand.mode, i) * x[i];
        }
        if !cand.active[i] {
            x[i] = T::ZERO;
            y[i] = T::ZERO;
        }
    }
    let outcome = d.outcome;
    let g = lcp.target;
    // Stick first: where Lemke's solution slips a contact from zero slip, the
    // same set with those contacts sticking, if admissible (a problem with
    // several solutions; the enumeration tried stick first).
    let mut sticking = Candidate {
        active: cand.active,
        mode: cand.mode,
    };
    let mut slipped = false;
    for &i in &lcp.zs[..lcp.nz] {
        if sticking.mode[i] != SlipState::Stick {
            sticking.mode[i] = SlipState::Stick;
            slipped = true;
        }
    }
    let tries = if slipped {
        [Some(&sticking), Some(&cand)]
    } else {
        [Some(&cand), None]
    };
    for c in tries.into_iter().flatten() {
        if lcp.take(base, c, tol, d) {
            d.outcome = outcome;
            return;
        }
    }
    d.x = x;
    d.y = y;
    p.velocity_change_into(&d.x, &d.y, &mut d.du_n, &mut d.du_t);
    d.mode = cand.mode;
    d.active = cand.active;
    d.ends_at_one = g.is_some();
    d.consistent = true;
    d.outcome = outcome;
}

/// A direction with normal rates `x` and no friction, into `d`.
fn zero_direction<T: Real, const N: usize>(
    p: &ImpactProblem<T, N>,
    x: &[T; N],
    d: &mut Direction<T, N>,
) {
    d.x = *x;
    d.y = [T::ZERO; N];
    p.velocity_change_into(&d.x, &d.y, &mut d.du_n, &mut d.du_t);
    d.mode = [SlipState::Stick; N];
    d.active = pushed(p, x);
    d.ends_at_one = false;
    d.consistent = false;
}

/// Solves the equations of given contact states, without checking inequalities:
/// the active contacts' normal rows reach `target` (zero if `None`) at
/// `lambda = 1` unless the normal rates are `fixed`; sticking contacts hold their
/// tangential rows at zero; slipping ones take `y = -mu s x`. Unknowns: the normal
/// rates of the active contacts (unless fixed), then the tangential rates of the
/// sticking ones. Returns the weighted norm of the rates, the direction and how
/// the system was solved; `None` where it is inconsistent.
pub fn solve_states<T: Real, const N: usize>(
    p: &ImpactProblem<T, N>,
    u_n: &[T; N],
    u_t: &[T; N],
    active: &[bool; N],
    mode: &[SlipState; N],
    target: Option<&[T; N]>,
    fixed: Option<&[T; N]>,
) -> Option<(T, Direction<T, N>, Solved)> {
    let mut d = Direction::default();
    let (score, how) = solve_states_into(p, u_n, u_t, active, mode, target, fixed, &mut d)?;
    Some((score, d, how))
}

/// [`solve_states`] with the direction written into `d` (every field; unspecified
/// on `None`): the weighted norm of the rates and how the system was solved.
#[allow(clippy::too_many_arguments)]
pub fn solve_states_into<T: Real, const N: usize>(
    p: &ImpactProblem<T, N>,
    u_n: &[T; N],
    u_t: &[T; N],
    active: &[bool; N],
    mode: &[SlipState; N],
    target: Option<&[T; N]>,
    fixed: Option<&[T; N]>,
    d: &mut Direction<T, N>,
) -> Option<(T, Solved)> {
    let n = p.len;
    // Index lists: normal unknowns (when not fixed) and stick unknowns; the
    // friction coupling of every contact, y_j = -mu_j s_j x_j when slipping.
    let mut xs = [0usize; N];
    let mut nx = 0;
    let mut ks = [0usize; N];
    let mut nk = 0;
    let mut coeff = [T::ZERO; N];
    for i in 0..n {
        coeff[i] = slip_coeff(p, mode, i);
        if !active[i] {
            continue;
        }
        if fixed.is_none() {
            xs[nx] = i;
            nx += 1;
        }
        if mode[i] == SlipState::Stick {
            ks[nk] = i;
            nk += 1;
        }
    }
    let zeros = [T::ZERO; N];
    let system = System {
        p,
        u_n,
        u_t,
        active,
        coeff: &coeff,
        xs: &xs[..nx],
        ks: &ks[..nk],
        target,
        fixed_x: fixed.unwrap_or(&zeros),
    };
    // Storage sized to the system (a 4-contact problem fits 8 x 8, an 8-contact
    // one 16 x 16): the same arithmetic without the copies and zero fills of the
    // largest size. The solution goes straight into the rates.
    let how = match nx + nk {
        0..=4 => system.solve::<4>(&mut d.x, &mut d.y)?,
        5..=8 => system.solve::<8>(&mut d.x, &mut d.y)?,
        9..=16 => system.solve::<16>(&mut d.x, &mut d.y)?,
        _ => system.solve::<DIM>(&mut d.x, &mut d.y)?,
    };
    let score = weighted_norm(p, active, &d.x, &d.y);
    p.velocity_change_into(&d.x, &d.y, &mut d.du_n, &mut d.du_t);
    d.mode = *mode;
    d.active = *active;
    d.ends_at_one = target.is_some();
    d.consistent = true;
    Some((score, how))
}

/// The equations of one candidate's states (see [`solve_states`]): unknowns the
/// normal rates of `xs`, then the tangential rates of the sticking `ks`.
struct System<'a, T, const N: usize> {
    p: &'a ImpactProblem<T, N>,
    u_n: &'a [T; N],
    u_t: &'a [T; N],
    active: &'a [bool; N],
    /// [`slip_coeff`] of every contact.
    coeff: &'a [T; N],
    xs: &'a [usize],
    ks: &'a [usize],
    target: Option<&'a [T; N]>,
    fixed_x: &'a [T; N],
}

impl<T: Real, const N: usize> System<'_, T, N> {
    /// Builds the system in `D x D` storage, solves it and assembles the full
    /// rates: `x` the fixed rates with the normal unknowns, `y` the slipping
    /// contacts' `-mu s x` with the stick unknowns. `None` where the system is
    /// inconsistent (`x`, `y` then unspecified).
    fn solve<const D: usize>(&self, x: &mut [T; N], y: &mut [T; N]) -> Option<Solved> {
        let (p, xs, ks, coeff) = (self.p, self.xs, self.ks, self.coeff);
        let (nx, nk) = (xs.len(), ks.len());
        let w_tn = |k: usize, j: usize| p.w_nt[j][k];
        let mut a = [[T::ZERO; D]; D];
        let mut b = [T::ZERO; D];
        let mut wts = [T::ONE; D];
        // Normal rows: (W_nn + W_nt S) x + W_nt,K y_K = g - u_n.
        for (r, &i) in xs.iter().enumerate() {
            let row = &mut a[r];
            for (c, &j) in xs.iter().enumerate() {
                row[c] = p.w_nn[i][j] + p.w_nt[i][j] * coeff[j];
            }
            for (q, &k) in ks.iter().enumerate() {
                row[nx + q] = p.w_nt[i][k];
            }
            let g = self.target.map_or(T::ZERO, |g| g[i]);
            b[r] = g - self.u_n[i];
            wts[r] = p.contacts[i].weight;
        }
        // Stick rows: (W_tn + W_tt S) x + W_tt,KK y_K = -u_t.
        for (q, &k) in ks.iter().enumerate() {
            let r = nx + q;
            let row = &mut a[r];
            for (c, &j) in xs.iter().enumerate() {
                row[c] = w_tn(k, j) + p.w_tt[k][j] * coeff[j];
            }
            for (q2, &k2) in ks.iter().enumerate() {
                row[nx + q2] = p.w_tt[k][k2];
            }
            let mut rhs = -self.u_t[k];
            for j in 0..p.len {
                if self.fixed_x[j] != T::ZERO {
                    rhs -= (w_tn(k, j) + p.w_tt[k][j] * coeff[j]) * self.fixed_x[j];
                }
            }
            b[r] = rhs;
            wts[r] = p.contacts[k].weight;
        }
        let mut sol = [T::ZERO; D];
        let how = solve_weighted_into(&a, &b, &wts, nx + nk, &mut sol)?;
        // The full rates.
        *x = *self.fixed_x;
        for (r, &i) in xs.iter().enumerate() {
            x[i] = sol[r];
        }
        *y = [T::ZERO; N];
        for (j, yj) in y.iter_mut().enumerate().take(p.len) {
            if self.active[j] {
                *yj = coeff[j] * x[j];
            }
        }
        for (q, &k) in ks.iter().enumerate() {
            y[k] = sol[nx + q];
        }
        Some(how)
    }
}

/// The weighted norm `sum (x_i^2 + y_i^2) / w_i` of the active contacts' rates.
fn weighted_norm<T: Real, const N: usize>(
    p: &ImpactProblem<T, N>,
    active: &[bool; N],
    x: &[T; N],
    y: &[T; N],
) -> T {
    let mut score = T::ZERO;
    for i in 0..p.len {
        if active[i] {
            score += (x[i] * x[i] + y[i] * y[i]) / p.contacts[i].weight;
        }
    }
    score
}

/// Checks a candidate's solution: non-negative normal rates, released contacts
/// reaching their targets, sticking forces inside the cones, slips moving their way.
/// `None` when it fails; else whether the rates were moved ([`Split::Moved`]).
///
/// Where the candidate's system was singular, the normal rates and the sticking
/// forces are checked on the best split of the internal forces
/// ([`super::split`]): the minimum-norm split may overload one sticking contact
/// while another has friction to spare, or pull at one of several slipping
/// contacts while the others could push more. When a split inside every
/// cone exists, `d` takes it (its velocity rates are unchanged: internal forces
/// change no contact velocity). `normals_free`: the normal rates were unknowns.
/// `d`'s rates are unspecified when it fails.
#[allow(clippy::too_many_arguments)]
fn admissible<T: Real, const N: usize>(
    p: &ImpactProblem<T, N>,
    base: &Base<'_, T, N>,
    cand: &Candidate<N>,
    target: Option<&[T; N]>,
    normals_free: bool,
    how: Solved,
    d: &mut Direction<T, N>,
    tol: &Tolerances<T>,
) -> Option<Split> {
    // Internal forces exist among slipping contacts too (three slipping feet of
    // one rigid body): their normal rates are then moved to >= 0 as well.
    let sticking = (0..p.len).any(|i| cand.active[i]);
    let mut split = Split::Inside;
    if how == Solved::MinimumNorm && sticking {
        split = within_cones(
            p,
            &cand.active,
            &cand.mode,
            normals_free,
            &mut d.x,
            &mut d.y,
            tol.impulse,
        );
        if !split.feasible() {
            return None;
        }
    }
    admissible_as_is(p, base, cand, target, d, tol).then_some(split)
}

/// [`admissible`] on the rates as they are.
fn admissible_as_is<T: Real, const N: usize>(
    p: &ImpactProblem<T, N>,
    base: &Base<'_, T, N>,
    cand: &Candidate<N>,
    target: Option<&[T; N]>,
    d: &Direction<T, N>,
    tol: &Tolerances<T>,
) -> bool {
    for i in 0..p.len {
        if cand.active[i] {
            if d.x[i] < -tol.impulse {
                return false;
            }
            match cand.mode[i] {
                SlipState::Stick => {
                    if d.y[i].abs() > p.contacts[i].friction * d.x[i].max(T::ZERO) + tol.impulse {
                        return false;
                    }
                }
                s => {
                    // A contact at zero slip may slip only the way it then moves.
                    if kinematic_state(base.slip[i], tol.velocity).is_none()
                        && s.sign::<T>() * (base.u_t[i] + d.du_t[i]) < -tol.velocity
                    {
                        return false;
                    }
                }
            }
        } else if let Some(g) = target {
            // A released candidate must end at or above its target; a separating
            // contact may come down to it within the piece (an event), except in
            // persistent contact (`TargetAll`), where there is no piece.
            if (base.all || base.u_n[i] <= g[i] + tol.velocity)
                && base.u_n[i] + d.du_n[i] < g[i] - tol.velocity
            {
                return false;
            }
        }
    }
    true
}
