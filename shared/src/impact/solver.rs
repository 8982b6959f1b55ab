//! Darboux-Keller integration of an impact in impulse space, piecewise exactly
//! (docs/impact-model.md, "The method").
//!
//! Stages of [`solve`]:
//! 1. **Compression**: pieces of the complementarity rule toward zero normal
//!    velocity ([`NormalRule::Target`]), split at friction events, until every
//!    active contact's normal velocity is zero together (the paper's hypothesis).
//! 2. **Restitution** by the law:
//!    Poisson, each contact receives `R_i` times its compression impulse (the
//!    paper's eq. (4)), rates in that proportion so that all end together;
//!    Newton, the complementarity rule toward `u_n = -R_i u_n0`;
//!    Stronge, rates in proportion to `R_i` times the compression impulse, each
//!    contact ending when its restitution work reaches `R_i^2 |W_c,i|`.
//! 3. **Expansion** (Glocker 2001, sec. 7.4): more normal impulse only where a
//!    contact would still approach, by the complementarity rule toward zero.
//! 4. **Report**: totals by phase, the paper's interaction case of every contact,
//!    the energy change and the warnings.
//!
//! Along a piece everything is linear in the path parameter, so events (a slip
//! reaching zero, a target reached, a work target reached) are located exactly
//! as roots of linear or quadratic functions.

use super::lcp::{find_direction_into, Direction, NormalRule, Tolerances};
use super::outcome::{
    ContactOutcome, ImpactOutcome, InteractionCase, Phase, Segment, SlipState, Warnings,
};
use super::problem::{ImpactLaw, ImpactProblem};
use super::MAX_CONTACTS;
use crate::real::Real;

/// Most pieces of the impulse path before the solver gives up (each piece ends at
/// an event; a real impact has a few per contact).
const MAX_PIECES: u32 = 256;

/// Why an impact problem could not be solved.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ImpactError {
    /// No contact approaches: nothing to solve.
    NoApproach,
    /// The problem is malformed: no contact, more than capacity, a weight that is
    /// not positive, a coefficient out of range, or a number that is not finite.
    InvalidProblem,
    /// The impulse path needed more pieces than the solver allows (chattering between
    /// friction states).
    TooManyEvents,
}

/// The relative tolerance of events and checks: `1e-9` in `f64` (the threshold
/// for events at the end of compression, docs/impact-model.md, "The seven
/// interaction cases"), `64 eps` (7.6e-6) in `f32`, above the rounding of
/// velocities recomputed as `u0 + W P` and far enough below the `1e-4` agreement
/// of `f32` with `f64` (docs/impact-model.md, "Accuracy and limits").
fn relative_tolerance<T: Real>() -> T {
    T::from_f64(1e-9).max(T::from_f64(64.0) * T::EPSILON)
}

/// Solves one impact. See the module documentation for the stages.
#[inline]
pub fn solve<T: Real, const N: usize>(
    problem: &ImpactProblem<T, N>,
) -> Result<ImpactOutcome<T, N>, ImpactError> {
    const { assert!(N <= MAX_CONTACTS, "at most MAX_CONTACTS contacts") };
    check(problem)?;
    // The outcome is built in the value returned and the contacts' histories
    // written into it, not moved out of the solver's state (5.9 kB in f64).
    let mut result = Ok(ImpactOutcome {
        len: problem.len,
        contacts: core::array::from_fn(|_| ContactOutcome::default()),
        energy_change: T::ZERO,
        warnings: Warnings::default(),
    });
    if let Ok(outcome) = &mut result {
        integrate(problem, outcome)?;
    }
    result
}

/// [`solve`] into `outcome`, whatever it held before (every contact reset): a
/// caller that keeps its outcome where it reads it need not have one moved to
/// it (an outcome holds every contact's history at the capacity: 11.8 kB for 16
/// contacts in `f64`). On an error `outcome` is left unspecified.
pub fn solve_into<T: Real, const N: usize>(
    problem: &ImpactProblem<T, N>,
    outcome: &mut ImpactOutcome<T, N>,
) -> Result<(), ImpactError> {
    const { assert!(N <= MAX_CONTACTS, "at most MAX_CONTACTS contacts") };
    check(problem)?;
    outcome.len = problem.len;
    for c in outcome.contacts.iter_mut() {
        c.clear();
    }
    integrate(problem, outcome)
}

/// The stages of [`solve`] on a checked problem, into `outcome`.
fn integrate<T: Real, const N: usize>(
    problem: &ImpactProblem<T, N>,
    outcome: &mut ImpactOutcome<T, N>,
) -> Result<(), ImpactError> {
    let mut run = Run::new(problem, &mut outcome.contacts);
    if (0..problem.len).all(|i| problem.u_n[i] >= -run.tol.velocity) {
        return Err(ImpactError::NoApproach);
    }

    // 1. Compression: all active normal velocities to zero together.
    run.drive_to_target(&[T::ZERO; N])?;
    run.end_compression();

    // 2. Restitution by the law.
    match problem.law {
        ImpactLaw::Poisson => run.poisson()?,
        ImpactLaw::Newton => run.newton()?,
        ImpactLaw::Stronge => run.stronge()?,
    }

    // 3. Expansion: stop any penetration left.
    run.drive_to_target(&[T::ZERO; N])?;

    // 4. Report.
    let (energy, warnings) = run.report();
    outcome.energy_change = energy;
    outcome.warnings = warnings;
    Ok(())
}

/// Refuses malformed problems.
fn check<T: Real, const N: usize>(p: &ImpactProblem<T, N>) -> Result<(), ImpactError> {
    if p.len == 0 || p.len > N {
        return Err(ImpactError::InvalidProblem);
    }
    for i in 0..p.len {
        let c = &p.contacts[i];
        let numbers_finite = [p.u_n[i], p.u_t[i], c.restitution, c.friction, c.weight]
            .iter()
            .all(|v| v.is_finite())
            && (0..p.len).all(|j| {
                p.w_nn[i][j].is_finite() && p.w_nt[i][j].is_finite() && p.w_tt[i][j].is_finite()
            });
        let in_range = c.restitution >= T::ZERO
            && c.restitution <= T::ONE
            && c.friction >= T::ZERO
            && c.weight > T::ZERO;
        if !numbers_finite || !in_range {
            return Err(ImpactError::InvalidProblem);
        }
    }
    Ok(())
}

/// The state of an impact being integrated.
struct Run<'a, T, const N: usize> {
    p: &'a ImpactProblem<T, N>,
    tol: Tolerances<T>,
    /// Relative tolerance on the path parameter and on energies.
    rel: T,
    phase: Phase,
    /// Accumulated impulses, N s.
    p_n: [T; N],
    p_t: [T; N],
    /// Current contact velocities, m/s.
    u_n: [T; N],
    u_t: [T; N],
    /// Work of each normal impulse in the current phase, J.
    work: [T; N],
    /// Compression totals and work.
    p_c_n: [T; N],
    p_c_t: [T; N],
    work_c: [T; N],
    out: &'a mut [ContactOutcome<T>; N],
    warnings: Warnings,
    pieces: u32,
}

impl<'a, T: Real, const N: usize> Run<'a, T, N> {
    fn new(p: &'a ImpactProblem<T, N>, out: &'a mut [ContactOutcome<T>; N]) -> Self {
        let rel = relative_tolerance::<T>();
        // Scales: the largest contact speed and the impulse that changes it.
        let mut v_scale = T::ZERO;
        let mut w_scale = T::ZERO;
        for i in 0..p.len {
            v_scale = v_scale.max(p.u_n[i].abs()).max(p.u_t[i].abs());
            w_scale = w_scale.max(p.w_nn[i][i].abs()).max(p.w_tt[i][i].abs());
        }
        let p_scale = if w_scale > T::ZERO {
            v_scale / w_scale
        } else {
            v_scale
        };
        Run {
            p,
            tol: Tolerances {
                velocity: rel * v_scale,
                impulse: rel * p_scale,
                // A thousand times the velocity tolerance: 1e-6 of the impact's
                // velocities in f64 (7.6e-3 in f32 would be too coarse: 1e-4).
                zero_slip: (T::from_f64(1e3) * rel).min(T::from_f64(1e-4)) * v_scale,
            },
            rel,
            phase: Phase::Compression,
            p_n: [T::ZERO; N],
            p_t: [T::ZERO; N],
            u_n: p.u_n,
            u_t: p.u_t,
            work: [T::ZERO; N],
            p_c_n: [T::ZERO; N],
            p_c_t: [T::ZERO; N],
            work_c: [T::ZERO; N],
            out,
            warnings: Warnings::default(),
            pieces: 0,
        }
    }

    /// Pieces of the complementarity rule toward the normal velocities `g`, until
    /// every contact's normal velocity is at or above its target.
    fn drive_to_target(&mut self, g: &[T; N]) -> Result<(), ImpactError> {
        if (0..self.p.len).all(|i| self.u_n[i] >= g[i] - self.tol.velocity) {
            return Ok(());
        }
        let mut d = Direction::default();
        loop {
            if (0..self.p.len).all(|i| self.u_n[i] >= g[i] - self.tol.velocity) {
                return Ok(());
            }
            find_direction_into(
                self.p,
                &self.u_n,
                &self.u_t,
                &self.u_t,
                NormalRule::Target(g),
                &self.tol,
                &mut d,
            );
            if !d.consistent {
                self.warnings.insert(Warnings::INCONSISTENT);
            }
            let end = if d.ends_at_one { Some(T::ONE) } else { None };
            match self.next_event(&d, end, Some(g)) {
                Some(lambda) => {
                    let reached_end = end.is_some_and(|e| lambda >= e);
                    self.advance(&d, lambda)?;
                    if reached_end {
                        // Active contacts reach their targets (to rounding).
                        for i in 0..self.p.len {
                            if d.x[i] > T::ZERO && (self.u_n[i] - g[i]).abs() <= self.tol.velocity {
                                self.u_n[i] = g[i];
                            }
                        }
                    }
                }
                None => {
                    // No event ahead and no proportion that reaches the targets: the
                    // contacts are self-locked (jamming) if their would-be slip cannot
                    // separate them; record the state they hold, and stop.
                    self.advance(&d, T::ZERO)?;
                    if !self.warnings.contains(Warnings::JAMMING) {
                        self.warnings.insert(Warnings::INCONSISTENT);
                    }
                    return Ok(());
                }
            }
        }
    }

    /// The end of the next piece: the earliest friction event, or a separating
    /// contact coming down to its target (complementarity rules), or `end` if it
    /// comes first; events within the tolerance of `end` belong to the next phase.
    fn next_event(
        &self,
        d: &Direction<T, N>,
        end: Option<T>,
        target: Option<&[T; N]>,
    ) -> Option<T> {
        let mut lambda = end;
        let events = [
            self.friction_event(d),
            target.and_then(|g| self.released_event(d, g)),
        ];
        for l in events.into_iter().flatten() {
            let belongs_to_end = end.is_some_and(|e| l >= e - self.rel);
            if !belongs_to_end && lambda.is_none_or(|e| l < e) {
                lambda = Some(l);
            }
        }
        lambda
    }

    /// The earliest `lambda > 0` at which a contact above its target without
    /// impulse comes down to it (it then joins the complementarity problem).
    fn released_event(&self, d: &Direction<T, N>, g: &[T; N]) -> Option<T> {
        let mut first: Option<T> = None;
        for i in 0..self.p.len {
            let above = self.u_n[i] - g[i];
            if d.x[i] == T::ZERO && above > self.tol.velocity && d.du_n[i] < T::ZERO {
                let l = -above / d.du_n[i];
                if first.is_none_or(|f| l < f) {
                    first = Some(l);
                }
            }
        }
        first
    }

    /// The earliest `lambda > 0` at which a slipping contact's slip reaches zero.
    fn friction_event(&self, d: &Direction<T, N>) -> Option<T> {
        let mut first: Option<T> = None;
        for i in 0..self.p.len {
            if d.x[i] <= T::ZERO || d.mode[i] == SlipState::Stick {
                continue;
            }
            let (u, du) = (self.u_t[i], d.du_t[i]);
            if u != T::ZERO && u * du < T::ZERO {
                let l = -u / du;
                if first.is_none_or(|f| l < f) {
                    first = Some(l);
                }
            }
        }
        first
    }

    /// Moves along the piece `d` by `lambda`, recording history, work and warnings,
    /// and snapping to zero the slips that end within the tolerance of `lambda`.
    fn advance(&mut self, d: &Direction<T, N>, lambda: T) -> Result<(), ImpactError> {
        self.pieces += 1;
        if self.pieces > MAX_PIECES {
            return Err(ImpactError::TooManyEvents);
        }
        let half = T::from_f64(0.5);
        for i in 0..self.p.len {
            // Work of the normal impulse: integral of u_n dP_n, u_n linear in lambda.
            self.work[i] += d.x[i] * (self.u_n[i] * lambda + half * d.du_n[i] * lambda * lambda);
            self.p_n[i] += d.x[i] * lambda;
            self.p_t[i] += d.y[i] * lambda;
        }
        // Velocities from the impulses, u = u0 + W P (exact, no drift).
        self.refresh_velocities();
        for i in 0..self.p.len {
            let (pn0, pt0) = (self.p_n[i] - d.x[i] * lambda, self.p_t[i] - d.y[i] * lambda);
            let u_t_before = self.u_t[i] - d.du_t[i] * lambda;
            if d.x[i] > T::ZERO {
                self.record(i, d.mode[i], [pn0, self.p_n[i]], [pt0, self.p_t[i]]);
                self.check_jamming(i, d);
                // A slip that ends at this lambda, and a stick, hold zero slip.
                let ends_here = d.mode[i] != SlipState::Stick
                    && u_t_before != T::ZERO
                    && u_t_before * d.du_t[i] < T::ZERO
                    && (-u_t_before / d.du_t[i]) <= lambda + self.rel;
                if (ends_here || d.mode[i] == SlipState::Stick)
                    && self.u_t[i].abs() <= self.tol.velocity
                {
                    self.u_t[i] = T::ZERO;
                }
            }
        }
        Ok(())
    }

    /// `u = u0 + W P` for every contact.
    fn refresh_velocities(&mut self) {
        self.p
            .velocities_after(&self.p_n, &self.p_t, &mut self.u_n, &mut self.u_t);
    }

    /// Appends a piece to contact `i`'s history, merging it with the last segment
    /// when phase and state are the same.
    fn record(&mut self, i: usize, state: SlipState, pn: [T; 2], pt: [T; 2]) {
        let phase = self.phase;
        let o = &mut self.out[i];
        if let Some(last) = o.segments.last_mut() {
            if last.phase == phase && last.state == state {
                last.normal_impulse[1] = pn[1];
                last.tangential_impulse[1] = pt[1];
                return;
            }
        }
        let seg = Segment {
            phase,
            state,
            normal_impulse: pn,
            tangential_impulse: pt,
        };
        if o.segments.push(seg).is_err() {
            o.truncated = true;
        }
    }

    /// Jamming (self-locking, Stronge 2000 sec. 5.2; the paper's `h < f d`): slip of
    /// contact `i` in the direction `s` would not separate it, because its own
    /// normal velocity rate `W_nn,ii - mu s W_nt,ii` is not positive. Checked for a
    /// slipping contact, and for a contact held by friction in restitution (the
    /// slip it is held from is opposite to its friction force).
    fn check_jamming(&mut self, i: usize, d: &Direction<T, N>) {
        let s: T = match d.mode[i] {
            SlipState::Stick => {
                if self.phase != Phase::Restitution || d.y[i].abs() <= self.tol.impulse {
                    return;
                }
                if d.y[i] > T::ZERO {
                    -T::ONE
                } else {
                    T::ONE
                }
            }
            m => m.sign(),
        };
        let w = self.p.w_nn[i][i];
        let rate = w - self.p.contacts[i].friction * s * self.p.w_nt[i][i];
        if rate <= self.rel * w.abs() {
            self.warnings.insert(Warnings::JAMMING);
        }
    }

    /// Closes compression: records its totals and work, starts restitution.
    fn end_compression(&mut self) {
        self.p_c_n = self.p_n;
        self.p_c_t = self.p_t;
        self.work_c = self.work;
        self.work = [T::ZERO; N];
        self.phase = Phase::Restitution;
    }

    /// Poisson (the paper's eq. (4)): `P_n,i^R = R_i P_n,i^C`, all contacts in that
    /// proportion so that they end together.
    fn poisson(&mut self) -> Result<(), ImpactError> {
        let mut target = [T::ZERO; N];
        for (i, t) in target.iter_mut().enumerate().take(self.p.len) {
            *t = self.p.contacts[i].restitution * self.p_c_n[i];
        }
        let mut d = Direction::default();
        loop {
            let mut remaining = [T::ZERO; N];
            let mut any = false;
            for i in 0..self.p.len {
                let r = target[i] - (self.p_n[i] - self.p_c_n[i]);
                if r > self.rel * target[i] {
                    remaining[i] = r;
                    any = true;
                }
            }
            if !any {
                return Ok(());
            }
            self.fixed_direction(&remaining, &mut d);
            let lambda = self.next_event(&d, Some(T::ONE), None).unwrap_or(T::ONE);
            self.advance(&d, lambda)?;
            if lambda >= T::ONE {
                for i in 0..self.p.len {
                    if remaining[i] > T::ZERO {
                        self.p_n[i] = self.p_c_n[i] + target[i];
                    }
                }
                self.refresh_velocities();
                return Ok(());
            }
        }
    }

    /// Newton: the complementarity rule toward `u_n,i = -R_i u_n0,i` for the
    /// contacts that took part in compression (the others only may not penetrate).
    fn newton(&mut self) -> Result<(), ImpactError> {
        let mut g = [T::ZERO; N];
        for (i, gi) in g.iter_mut().enumerate().take(self.p.len) {
            if self.p_c_n[i] > self.tol.impulse && self.p.u_n[i] < T::ZERO {
                *gi = -self.p.contacts[i].restitution * self.p.u_n[i];
            }
        }
        self.drive_to_target(&g)
    }

    /// Stronge: rates `R_i P_n,i^C`; contact `i` ends when its restitution work
    /// reaches `R_i^2 |W_c,i|` (or when it can do no more work).
    fn stronge(&mut self) -> Result<(), ImpactError> {
        let n = self.p.len;
        let mut ended = [true; N];
        let mut target = [T::ZERO; N];
        for i in 0..n {
            let r = self.p.contacts[i].restitution;
            target[i] = r * r * self.work_c[i].abs();
            ended[i] = !(r > T::ZERO && self.p_c_n[i] > self.tol.impulse);
        }
        let mut d = Direction::default();
        loop {
            if ended.iter().take(n).all(|e| *e) {
                return Ok(());
            }
            let mut x = [T::ZERO; N];
            for i in 0..n {
                if !ended[i] {
                    x[i] = self.p.contacts[i].restitution * self.p_c_n[i];
                }
            }
            self.fixed_direction(&x, &mut d);
            // Earliest work event.
            let mut work_at = [None; N];
            let mut lambda: Option<T> = None;
            for i in 0..n {
                if !ended[i] {
                    let l = self.work_event(i, &d, target[i]);
                    work_at[i] = Some(l);
                    lambda = Some(lambda.map_or(l, |m: T| m.min(l)));
                }
            }
            let Some(mut lambda) = lambda else {
                return Ok(());
            };
            if let Some(l) = self.friction_event(&d) {
                if l < lambda - self.rel * lambda.max(T::ONE) {
                    lambda = l;
                }
            }
            self.advance(&d, lambda)?;
            for i in 0..n {
                if let Some(l) = work_at[i] {
                    if l <= lambda + self.rel * lambda.max(T::ONE) {
                        ended[i] = true;
                    }
                }
            }
        }
    }

    /// The `lambda` at which contact `i`'s restitution work reaches `target` along
    /// `d`: root of `a l^2 + b l = dW` with `a = x du_n / 2`, `b = x u_n`; where the
    /// work peaks below the target, the peak (normal velocity back to zero); 0
    /// where it cannot grow.
    fn work_event(&self, i: usize, d: &Direction<T, N>, target: T) -> T {
        let dw = target - self.work[i];
        if dw <= self.rel * target {
            return T::ZERO;
        }
        // A contact held at zero normal velocity (stuck, jammed) releases nothing.
        if self.u_n[i] <= self.tol.velocity && d.du_n[i] <= self.tol.velocity {
            return T::ZERO;
        }
        let half = T::from_f64(0.5);
        let a = half * d.x[i] * d.du_n[i];
        let b = d.x[i] * self.u_n[i];
        if a == T::ZERO {
            return if b > T::ZERO { dw / b } else { T::ZERO };
        }
        let disc = b * b + T::from_f64(4.0) * a * dw;
        if disc < T::ZERO {
            // a < 0: the work peaks at l = -b / 2a (u_n = 0) below the target.
            let peak = -b / (a + a);
            return peak.max(T::ZERO);
        }
        // Roots without cancellation: q = -(b + sign(b) sqrt(disc)) / 2.
        let sq = disc.sqrt();
        let q = if b >= T::ZERO {
            -half * (b + sq)
        } else {
            -half * (b - sq)
        };
        let r1 = q / a;
        let r2 = if q != T::ZERO { -dw / q } else { r1 };
        let mut best: Option<T> = None;
        for r in [r1, r2] {
            if r > T::ZERO && best.is_none_or(|b| r < b) {
                best = Some(r);
            }
        }
        best.unwrap_or(T::ZERO)
    }

    /// A fixed-rate direction, flagging inconsistent friction states.
    fn fixed_direction(&mut self, x: &[T; N], d: &mut Direction<T, N>) {
        find_direction_into(
            self.p,
            &self.u_n,
            &self.u_t,
            &self.u_t,
            NormalRule::Fixed(x),
            &self.tol,
            d,
        );
        if !d.consistent {
            self.warnings.insert(Warnings::INCONSISTENT);
        }
    }

    /// Totals and cases into the contacts' outcomes; the energy change and the
    /// warnings.
    fn report(&mut self) -> (T, Warnings) {
        let half = T::from_f64(0.5);
        let mut energy = T::ZERO;
        let mut energy_scale = T::ZERO;
        for i in 0..self.p.len {
            let (un0, ut0) = (self.p.u_n[i], self.p.u_t[i]);
            // Kinetic energy change: P . (u_before + u_after) / 2.
            energy +=
                half * (self.p_n[i] * (un0 + self.u_n[i]) + self.p_t[i] * (ut0 + self.u_t[i]));
            energy_scale += (self.p_n[i] * un0).abs() + (self.p_t[i] * ut0).abs();
            if self.u_n[i] < -self.tol.velocity {
                self.warnings.insert(Warnings::PENETRATION_LEFT);
            }
            let case = classify(&self.out[i].segments, ut0, self.tol.velocity);
            let o = &mut self.out[i];
            o.normal_impulse = self.p_n[i];
            o.tangential_impulse = self.p_t[i];
            o.compression = [self.p_c_n[i], self.p_c_t[i]];
            o.restitution = [self.p_n[i] - self.p_c_n[i], self.p_t[i] - self.p_c_t[i]];
            o.normal_velocity_before = un0;
            o.normal_velocity_after = self.u_n[i];
            o.tangential_velocity_before = ut0;
            o.tangential_velocity_after = self.u_t[i];
            o.case = case;
        }
        if energy > self.rel * T::from_f64(10.0) * energy_scale {
            self.warnings.insert(Warnings::ENERGY_GAINED);
        }
        (energy, self.warnings)
    }
}

/// The paper's interaction case of a contact from its history (the numbering of
/// docs/impact-model.md): the first switch out of a slip decides (stick: 3 in
/// compression, 4 in restitution; reversal: 5 or 6); without one, stick throughout is
/// 7, slip from zero tangential velocity 2, slip one way 1; no impulse 0.
fn classify<T: Real>(segments: &[Segment<T>], u_t0: T, tol: T) -> InteractionCase {
    let Some(first) = segments.first() else {
        return InteractionCase::Inactive;
    };
    for pair in segments.windows(2) {
        let (a, b) = (pair[0], pair[1]);
        if a.state == SlipState::Stick || a.state == b.state {
            continue;
        }
        return match (b.state, b.phase) {
            (SlipState::Stick, Phase::Compression) => InteractionCase::StickInCompression,
            (SlipState::Stick, Phase::Restitution) => InteractionCase::StickInRestitution,
            (_, Phase::Compression) => InteractionCase::ReversalInCompression,
            (_, Phase::Restitution) => InteractionCase::ReversalInRestitution,
        };
    }
    if segments.iter().all(|s| s.state == SlipState::Stick) {
        InteractionCase::NoSlip
    } else if first.state == SlipState::Stick || u_t0.abs() <= tol {
        InteractionCase::SlipFromRest
    } else {
        InteractionCase::Slip
    }
}
