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
//!   `x >= 0, v = u_n + (W_eff x) - g >= 0, x . v = 0`,
//!   solved by enumerating active sets (at most 2^8), largest first.
//!   Contacts above their target take no share (they join at an event of the
//!   path); [`NormalRule::TargetAll`] lets every contact take one (persistent
//!   contact at acceleration level).
//! - [`NormalRule::Fixed`]: `x` given (Poisson's and Stronge's restitution).
//!
//! Friction (Coulomb): a slipping contact's tangential rate is `y = -mu s x`; a
//! sticking one's `y` is whatever holds its tangential velocity, if
//! `|y| <= mu x`. For a contact at zero slip the states stick, slip+, slip- are
//! tried in that order; a slip state is consistent when the tangential velocity
//! then moves in its direction. Where the equations leave the impulses
//! undetermined (a singular Delassus matrix), the weighted minimum-norm solution
//! with the contacts' weights is taken ([`super::linalg`]); where that split of
//! the internal forces puts a normal rate below zero or a sticking contact outside
//! its cone, the candidate is checked, and taken, at the closest split inside
//! every cone ([`super::split`]), so that several sticking contacts share their
//! friction as the cones allow rather than one cone at a time.

use super::linalg::{solve_weighted_into, Solved, DIM};
use super::outcome::SlipState;
use super::problem::ImpactProblem;
use super::split::{within_cones, Split};
use crate::real::Real;

/// Most candidate (active set, friction states) pairs tried for one direction.
const CANDIDATE_BUDGET: u32 = 20_000;

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
}

/// What the rates of a piece add to, and the slip velocities.
#[derive(Clone, Copy)]
struct Base<'a, T, const N: usize> {
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
    let mut budget = CANDIDATE_BUDGET;
    let all = matches!(rule, NormalRule::TargetAll(_));
    let base = Base {
        u_n,
        u_t,
        slip,
        all,
    };
    match rule {
        NormalRule::Fixed(x) => fixed_direction(p, &base, x, tol, &mut budget, out),
        NormalRule::Target(g) | NormalRule::TargetAll(g) => {
            if complementary_direction(p, &base, g, tol, &mut budget, out) {
                return;
            }
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
                let mut budget = CANDIDATE_BUDGET;
                let base = Base {
                    slip: &loose,
                    ..base
                };
                if complementary_direction(p, &base, g, tol, &mut budget, out) {
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
            let mut budget = CANDIDATE_BUDGET;
            fixed_direction(p, &base, &x, tol, &mut budget, out);
            out.ends_at_one = false;
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

/// The complementarity problem of a `Target` rule, by enumeration of active sets
/// from the largest, into `out`. Returns false when no consistent solution exists
/// (`out` then unspecified).
fn complementary_direction<T: Real, const N: usize>(
    p: &ImpactProblem<T, N>,
    base: &Base<'_, T, N>,
    g: &[T; N],
    tol: &Tolerances<T>,
    budget: &mut u32,
    out: &mut Direction<T, N>,
) -> bool {
    let n = p.len;
    // Only contacts at or below their target can take impulse; a contact above it
    // (separating) joins when its normal velocity comes down to the target, which
    // is an event of the path (see `released_event`), not a choice made here.
    let mut candidate_mask = 0u32;
    for i in 0..n {
        if base.all || base.u_n[i] <= g[i] + tol.velocity {
            candidate_mask |= 1 << i;
        }
    }
    // The candidates after the first of a size are solved here, and copied to
    // `out` only when better.
    let mut scratch: Option<Direction<T, N>> = None;
    for size in (0..=candidate_mask.count_ones() as usize).rev() {
        // The weighted norm of the best candidate of this size, held in `out`.
        let mut best: Option<T> = None;
        for mask in 0u32..(1u32 << n) {
            if mask & !candidate_mask != 0 || mask.count_ones() as usize != size {
                continue;
            }
            let mut active = [false; N];
            for (i, a) in active.iter_mut().enumerate().take(n) {
                *a = mask & (1 << i) != 0;
            }
            let first = best.is_none();
            let d = if first {
                &mut *out
            } else {
                scratch.get_or_insert_with(Direction::default)
            };
            let Some((score, how)) =
                first_consistent_states(p, base, &active, Some(g), None, tol, budget, d)
            else {
                if *budget == 0 {
                    return false;
                }
                continue;
            };
            // A unique solution of a full-rank system is the answer; where the
            // system was singular, keep the weighted minimum norm of this size.
            if how == Solved::Unique && first {
                return true;
            }
            if best.is_none_or(|s| score < s) {
                if !first {
                    if let Some(d) = &scratch {
                        *out = *d;
                    }
                }
                best = Some(score);
            }
        }
        if best.is_some() {
            return true;
        }
    }
    false
}

/// The direction of a `Fixed` rule: friction states only, into `out`.
fn fixed_direction<T: Real, const N: usize>(
    p: &ImpactProblem<T, N>,
    base: &Base<'_, T, N>,
    x: &[T; N],
    tol: &Tolerances<T>,
    budget: &mut u32,
    out: &mut Direction<T, N>,
) {
    let mut active = [false; N];
    for i in 0..p.len {
        active[i] = x[i] > T::ZERO;
    }
    if first_consistent_states(p, base, &active, None, Some(x), tol, budget, out).is_some() {
        return;
    }
    // No consistent friction states: take every undecided contact as sticking,
    // with its force clipped to the cone (the closest admissible), and say so.
    let mut mode = [SlipState::Stick; N];
    for i in 0..p.len {
        if let Some(s) = kinematic_state(base.slip[i], tol.velocity) {
            mode[i] = s;
        }
    }
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
    d.active = core::array::from_fn(|i| i < p.len && x[i] > T::ZERO);
    d.ends_at_one = false;
    d.consistent = false;
}

/// For one active set, tries the friction states of the contacts at zero slip
/// (stick first) and returns the weighted norm of the first consistent solution
/// and how its system was solved, the solution in `d`; `None` (with `d`
/// unspecified) where no state is consistent.
#[allow(clippy::too_many_arguments)]
fn first_consistent_states<T: Real, const N: usize>(
    p: &ImpactProblem<T, N>,
    base: &Base<'_, T, N>,
    active: &[bool; N],
    target: Option<&[T; N]>,
    fixed: Option<&[T; N]>,
    tol: &Tolerances<T>,
    budget: &mut u32,
    d: &mut Direction<T, N>,
) -> Option<(T, Solved)> {
    let n = p.len;
    let mut cand = Candidate {
        active: *active,
        mode: [SlipState::Stick; N],
    };
    let mut undecided = [0usize; N];
    let mut count = 0;
    for i in 0..n {
        match kinematic_state(base.slip[i], tol.velocity) {
            Some(s) => cand.mode[i] = s,
            None if active[i] => {
                undecided[count] = i;
                count += 1;
            }
            None => {}
        }
    }
    let combos = 3u32.pow(count as u32);
    for code in 0..combos {
        if *budget == 0 {
            return None;
        }
        *budget -= 1;
        let mut c = code;
        for &i in undecided.iter().take(count) {
            cand.mode[i] = match c % 3 {
                0 => SlipState::Stick,
                1 => SlipState::SlipPositive,
                _ => SlipState::SlipNegative,
            };
            c /= 3;
        }
        let Some((score, how)) = solve_states_into(
            p,
            base.u_n,
            base.u_t,
            &cand.active,
            &cand.mode,
            target,
            fixed,
            d,
        ) else {
            continue;
        };
        match admissible(p, base, &cand, target, fixed.is_none(), how, d, tol) {
            // The split moved along the internal forces: its norm.
            Some(Split::Moved) => return Some((weighted_norm(p, &cand.active, &d.x, &d.y), how)),
            Some(_) => return Some((score, how)),
            None => {}
        }
    }
    None
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
    // Storage sized to the system (a 4-contact problem fits 8 x 8): the same
    // arithmetic, a quarter of the copies of the largest size. The solution goes
    // straight into the rates.
    let how = match nx + nk {
        0..=4 => system.solve::<4>(&mut d.x, &mut d.y)?,
        5..=8 => system.solve::<8>(&mut d.x, &mut d.y)?,
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

/// Friction coupling of contact `j` in state `mode[j]`: `y_j = -mu_j s_j x_j`
/// when slipping, 0 when sticking.
fn slip_coeff<T: Real, const N: usize>(
    p: &ImpactProblem<T, N>,
    mode: &[SlipState; N],
    j: usize,
) -> T {
    match mode[j] {
        SlipState::Stick => T::ZERO,
        s => -p.contacts[j].friction * s.sign::<T>(),
    }
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
/// Where the candidate's system was singular and it has a sticking contact, the
/// normal rates and the sticking forces are checked on the best split of the
/// internal forces ([`super::split`]): the minimum-norm split may overload one
/// sticking contact while another has friction to spare. When a split inside every
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
    let sticking = (0..p.len).any(|i| cand.active[i] && cand.mode[i] == SlipState::Stick);
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
