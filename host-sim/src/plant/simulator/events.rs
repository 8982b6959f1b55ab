//! The event functions and where they cross zero.
//!
//! One function per condition ([`Watch`]), each positive until its event, never
//! combined; a mode just decided starts with each at least its margin from zero.
//! [`Plant::first_crossing`] finds the earliest event in a step: a change of sign,
//! or one of the cases without one (grazing, a whole flight, a dip inside the
//! step), located by Illinois false position on the dense output
//! ([`Plant::locate`]).

use shared::impact::MAX_CONTACTS;

use super::super::dynamics::{ContactKinematics, Pose, Vector};
use super::super::integrator::{Step, INTERIOR_STAGES};
use super::super::motor::Winding;
use super::forces::Evaluation;
use super::{ContactMode, Plant, NY};
use crate::machine::bodies::MAX_ROTORS;

/// What an event function watches: each is positive until its event, and one
/// function watches one condition.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Watch {
    /// Open contact `j`: its gap, m (impact, or the contact closes).
    Gap(usize),
    /// Closed contact `j`: its normal force plus `eps_F`, N (lift-off).
    NormalForce(usize),
    /// Sticking contact `j`: `mu lambda_n - |lambda_t| + eps_F`, N (the cone is
    /// exceeded).
    Cone(usize),
    /// Slipping contact `j`: `s u_t + eps_v`, m/s (the slip ends).
    SlipEnds(usize),
    /// Slipping contact `j` with friction: its normal coefficient relative to its
    /// normal compliance less [`JAM_RATIO`], `(W_nn - mu s W_nt) / W_nn - JAM_RATIO`
    /// (the dynamic jam: its normal force would grow without bound).
    Jam(usize),
    /// Motor `k`'s current, A: driven, `I_lim - |i|` (the current limit is
    /// reached); coasting with a current, `s i` (it dies through the diodes).
    Current(usize),
    /// An unused slot (the second slot of an open contact).
    Nothing,
}

/// The earliest event of a step: its time, the state there, and whether only a
/// winding's current crossed (a coasting current dying, a current reaching its
/// driver's limit): such an event changes no contact and takes no trace rows.
pub(super) struct Crossing {
    pub(super) t: f64,
    pub(super) y: [f64; NY],
    pub(super) current_only: bool,
}

/// Event function slots: three per contact, one per motor driver.
const EVENT_SLOTS: usize = SLOTS_PER_CONTACT * MAX_CONTACTS + MAX_ROTORS;

/// Event function slots of one contact.
const SLOTS_PER_CONTACT: usize = 3;

/// Where a slipping contact's normal coefficient `(W_nn - mu s W_nt) / W_nn` falls
/// to this, its dynamic jam's event: 1e-6, so that its force `-B / A` is still
/// finite there (Painleve's rod: some 1 800 N, against 43 N 15 ms before) and the
/// event is within `1e-6 / (dA / dt)` of the singular point (the rod: 2e-7 s). The
/// mode decision ([`super::modes`]) never leaves a contact slipping below twice
/// it, so the function starts at least its margin from zero.
pub(super) const JAM_RATIO: f64 = 1e-6;

/// The event functions at a state ([`Plant::event_values`]), in place (no
/// allocation: they are made at every step).
#[derive(Clone, Copy)]
pub(super) struct EventValues {
    values: [f64; EVENT_SLOTS],
    len: usize,
}

impl std::ops::Deref for EventValues {
    type Target = [f64];
    fn deref(&self) -> &[f64] {
        &self.values[..self.len]
    }
}

/// The contact forces the integrator's interior stages computed in an attempt
/// ([`INTERIOR_STAGES`]: 1/5, 3/10, 4/5 and 8/9 of the step): the dip test of a
/// force or cone function reads them instead of evaluating the step's middle.
#[derive(Clone, Copy, Default)]
pub(super) struct StageForces {
    /// Stages recorded so far.
    count: usize,
    /// Normal force of each contact at each stage, N.
    lambda_n: [[f64; MAX_CONTACTS]; 4],
    /// Tangential force of each contact at each stage, N.
    lambda_t: [[f64; MAX_CONTACTS]; 4],
}

impl StageForces {
    /// Keeps the forces of the first `contacts` contacts of `e`, the evaluation of
    /// the next interior stage (the calls after the fourth are the step's end,
    /// which the event functions at the end already have).
    pub(super) fn record(&mut self, e: &Evaluation, contacts: usize) {
        if self.count < INTERIOR_STAGES.len() {
            self.lambda_n[self.count][..contacts].copy_from_slice(&e.lambda_n[..contacts]);
            self.lambda_t[self.count][..contacts].copy_from_slice(&e.lambda_t[..contacts]);
            self.count += 1;
        }
    }
}

/// Where an event function gets its contacts' kinematics: a pose (and the
/// velocities) its caller built once for all the functions at a state, or built
/// from the state for the one function asked for.
#[derive(Clone, Copy)]
pub(super) enum Kinematics<'a> {
    Pose(&'a Pose, &'a Vector),
    FromState,
}

impl Plant {
    /// What event function `i` watches (see [`Watch`]): three slots per contact,
    /// then one per motor driver.
    pub(super) fn watch(&self, i: usize) -> Watch {
        let n = self.modes.len();
        if i >= SLOTS_PER_CONTACT * n {
            return Watch::Current(i - SLOTS_PER_CONTACT * n);
        }
        let j = i / SLOTS_PER_CONTACT;
        match (self.modes[j], i % SLOTS_PER_CONTACT) {
            (ContactMode::Open, 0) => Watch::Gap(j),
            (ContactMode::Open, _) => Watch::Nothing,
            (_, 0) => Watch::NormalForce(j),
            (ContactMode::Stick, 1) => Watch::Cone(j),
            (ContactMode::Stick, _) => Watch::Nothing,
            // Without friction the slip's direction changes no force and the
            // normal coefficient is W_nn: no event.
            (_, _) if self.model.contacts[j].law.friction == 0.0 => Watch::Nothing,
            (_, 1) => Watch::SlipEnds(j),
            (_, _) => Watch::Jam(j),
        }
    }

    /// The event functions at `y`, each positive until its event and `<= 0`
    /// once it happened, one function per condition (never combined: a function
    /// that cannot change sign must not hide another's crossing). Slots `3j`,
    /// `3j + 1` and `3j + 2` are contact `j`'s:
    ///
    /// | mode | slot `3j` | slot `3j + 1` | slot `3j + 2` |
    /// | --- | --- | --- | --- |
    /// | open | gap, m | (none: `+inf`) | (none) |
    /// | stick | `lambda_n + eps_F`, N (lift-off) | `mu lambda_n - abs(lambda_t) + eps_F`, N (cone exceeded) | (none) |
    /// | slip | `lambda_n + eps_F`, N (lift-off) | `s u_t + eps_v`, m/s (slip ends) | `(W_nn - mu s W_nt) / W_nn - JAM_RATIO` (dynamic jam) |
    ///
    /// then each motor driver's `I_lim - |i|` (the current limit: the current's
    /// equation switches there). `eps_F` is [`Plant::force_tolerance`] and
    /// `eps_v` the velocity tolerance: a mode just decided starts with every
    /// function at least that far from zero (the mode decision's own tolerance is
    /// a thousandth of it), so a crossing is a change of sign, never a value that
    /// was already zero.
    pub(super) fn event_values(&self, y: &[f64; NY]) -> EventValues {
        // One pose for every contact's kinematics at `y`.
        let v = self.model.v(y);
        let pose = Pose::new(&self.model, &self.model.q(y));
        let at = Kinematics::Pose(&pose, &v);
        let values = |ev: Option<&Evaluation>| {
            let mut values = EventValues {
                values: [f64::INFINITY; EVENT_SLOTS],
                len: SLOTS_PER_CONTACT * self.modes.len() + self.model.rotors.len(),
            };
            for i in 0..values.len {
                values.values[i] = self.event_value(self.watch(i), y, at, ev);
            }
            values
        };
        // The forces read where the evaluation is kept (`event_value` evaluates
        // nothing when given them).
        if self.modes.iter().any(|m| m.closed()) {
            self.with_evaluation(y, |e| values(Some(e)))
        } else {
            values(None)
        }
    }

    /// One event function, `watch`, at `y` (see [`Plant::event_values`]); `at`
    /// the pose there where the caller has it; `ev` the evaluation at `y` where
    /// the caller has it, else the contact forces are computed here, and only for
    /// the functions that need them (a normal force, a cone): locating a gap's or
    /// a slip's zero solves no contact problem.
    pub(super) fn event_value(
        &self,
        watch: Watch,
        y: &[f64; NY],
        at: Kinematics<'_>,
        ev: Option<&super::forces::Evaluation>,
    ) -> f64 {
        let kinematics = |j| match at {
            Kinematics::Pose(pose, v) => pose.contact(&self.model, j, v),
            Kinematics::FromState => self.contact_at(y, j),
        };
        let gap = |j| match at {
            Kinematics::Pose(pose, _) => pose.gap(&self.model, j),
            Kinematics::FromState => self.gap_at(y, j),
        };
        let forces = |j: usize| match ev {
            Some(e) => (e.lambda_n[j], e.lambda_t[j]),
            None => self.with_evaluation(y, |e| (e.lambda_n[j], e.lambda_t[j])),
        };
        let jam = |j: usize| match ev {
            Some(e) => e.jam[j],
            None => self.with_evaluation(y, |e| e.jam[j]),
        };
        match watch {
            Watch::Gap(j) => gap(j),
            Watch::NormalForce(j) | Watch::Cone(j) => {
                let (ln, lt) = forces(j);
                self.force_value(watch, ln, lt)
            }
            Watch::SlipEnds(j) => {
                let s = if self.modes[j] == ContactMode::SlipNegative {
                    -1.0
                } else {
                    1.0
                };
                s * kinematics(j).u_t + self.settings.velocity_tolerance
            }
            Watch::Jam(j) => jam(j) - JAM_RATIO,
            Watch::Current(k) => match self.winding[k] {
                Winding::Voltage(_) => {
                    self.model.rotors[k].motor.current_limit - y[self.model.current(k)].abs()
                }
                Winding::Coast(_) if self.coast_sign[k] != 0.0 => {
                    self.coast_sign[k] * y[self.model.current(k)]
                }
                Winding::Coast(_) | Winding::Open => f64::INFINITY,
            },
            Watch::Nothing => f64::INFINITY,
        }
    }

    /// A force or cone function (`watch`) of a contact whose forces are
    /// `lambda_n`, `lambda_t`, N: `lambda_n + eps_F`, or
    /// `mu lambda_n - |lambda_t| + eps_F` (see [`Plant::event_values`]).
    fn force_value(&self, watch: Watch, lambda_n: f64, lambda_t: f64) -> f64 {
        let eps_f = self.force_tolerance();
        match watch {
            Watch::NormalForce(_) => lambda_n + eps_f,
            Watch::Cone(j) => {
                self.model.contacts[j].law.friction * lambda_n - lambda_t.abs() + eps_f
            }
            // Not a force function (never asked for one).
            _ => f64::INFINITY,
        }
    }

    /// The earliest event in `step`, located on its dense output.
    ///
    /// A function that changes sign between the step's ends is located by
    /// [`Plant::locate`]. Three cases are found although both ends are positive,
    /// or both are past the event:
    /// - an open contact **grazing** the fundament inside the step, or making a
    ///   **whole flight** inside it (its gap, below);
    /// - a closed contact's function (normal force, cone, slip) that **dips**
    ///   below zero and comes back inside the step ([`Plant::dip`]): a force or
    ///   cone function sampled at the integrator's interior stages (`stages`, the
    ///   forces that came with the step), a slip at the step's middle;
    /// - a closed contact whose normal force is already below `-eps_F` at the
    ///   step's start (a mode left inconsistent, which the mode decision should
    ///   never produce): the event is at the start, so a contact never stays
    ///   closed while its mode's equations make it pull.
    pub(super) fn first_crossing(
        &self,
        step: &Step<NY>,
        ev0: &[f64],
        ev1: &[f64],
        stages: &StageForces,
    ) -> Option<Crossing> {
        // The earliest time, and whether only a winding's current crossed there.
        let mut best: Option<(f64, bool)> = None;
        let mut consider_kind = |te: f64, current: bool| match &mut best {
            Some((b, only)) if te == *b => *only &= current,
            Some((b, _)) if te > *b => {}
            _ => best = Some((te, current)),
        };
        // The state at the step's middle, made once if a slip needs it.
        let mut mid: Option<[f64; NY]> = None;
        for i in 0..ev0.len() {
            let watch = self.watch(i);
            let f = |y: &[f64; NY]| self.event_value(watch, y, Kinematics::FromState, None);
            let mut consider = |te: f64| consider_kind(te, false);
            if ev0[i] > 0.0 && ev1[i] <= 0.0 {
                // A gap that starts at rounding size while the contact separates
                // lands after its apex: false position from there would stop
                // within rounding of the start, where the gap is rounding too.
                if let Watch::Gap(j) = watch {
                    if ev0[i] <= self.settings.together_gap {
                        if let Some(te) = self.landing_after_apex(step, j, ev1[i]) {
                            consider(te);
                            continue;
                        }
                    }
                }
                let te = self.locate(step, &f, step.t0, step.t1(), ev0[i], ev1[i]);
                consider_kind(te, matches!(watch, Watch::Current(_)));
                continue;
            }
            match watch {
                Watch::Gap(j) => {
                    if let Some(te) = self.gap_event_inside(step, j, ev0[i], ev1[i]) {
                        consider(te);
                    }
                }
                Watch::NormalForce(_) | Watch::Cone(_) | Watch::SlipEnds(_) => {
                    if ev0[i] > 0.0 && ev1[i] > 0.0 {
                        let mut samples = [(0.0, ev0[i]); 6];
                        let n = match watch {
                            Watch::NormalForce(j) | Watch::Cone(j) if stages.count == 4 => {
                                for (k, &c) in INTERIOR_STAGES.iter().enumerate() {
                                    let (ln, lt) = (stages.lambda_n[k][j], stages.lambda_t[k][j]);
                                    samples[k + 1] = (c, self.force_value(watch, ln, lt));
                                }
                                6
                            }
                            _ => {
                                let ym = mid.get_or_insert_with(|| step.at(step.t0 + 0.5 * step.h));
                                samples[1] = (0.5, f(ym));
                                3
                            }
                        };
                        samples[n - 1] = (1.0, ev1[i]);
                        if let Some(te) = self.dip(step, &f, &samples[..n]) {
                            consider(te);
                        }
                    } else if ev0[i] <= 0.0 && matches!(watch, Watch::NormalForce(_)) {
                        consider(step.t0);
                    }
                }
                // A normal coefficient depends on the configuration only: smooth
                // over a step, no dip to look for.
                Watch::Jam(_) | Watch::Current(_) | Watch::Nothing => {}
            }
        }
        best.map(|(te, current_only)| {
            let (t, y) = if te >= step.t1() {
                (step.t1(), step.y1)
            } else if te <= step.t0 {
                (step.t0, step.y0)
            } else {
                (te, step.at(te))
            };
            Crossing { t, y, current_only }
        })
    }

    /// A dip of a function below zero inside `step` although it is positive at
    /// both ends: `samples` are `(s, f)` at fractions `s` of the step, from the
    /// start (`s = 0`) to the end (`s = 1`), the inner ones possibly from the
    /// integrator's stages rather than the dense output. Around the smallest
    /// inner sample `(s_k, f_k)` and its neighbours, the parabola through the
    /// three (Newton's divided differences: `d_1 = (f_k - f_a) / (s_k - s_a)`,
    /// `d_2 = (f_b - f_k) / (s_b - s_k)`, `c = (d_2 - d_1) / (s_b - s_a)`,
    /// `p(s) = f_a + d_1 (s - s_a) + c (s - s_a)(s - s_k)`) has its minimum at
    /// `s* = (s_a + s_k) / 2 - d_1 / (2 c)`; where the sample itself is `<= 0`, or
    /// the minimum is inside `(s_a, s_b)` and `p(s*) <= 0`, the function is
    /// evaluated there on the dense output and, if it is past its event, the
    /// crossing before it is located.
    pub(super) fn dip(
        &self,
        step: &Step<NY>,
        f: &dyn Fn(&[f64; NY]) -> f64,
        samples: &[(f64, f64)],
    ) -> Option<f64> {
        let t_at = |s: f64| step.t0 + s * step.h;
        let f0 = samples[0].1;
        let inner = 1..samples.len() - 1;
        let k = inner.min_by(|&a, &b| samples[a].1.total_cmp(&samples[b].1))?;
        let ((sa, fa), (sk, fk), (sb, fb)) = (samples[k - 1], samples[k], samples[k + 1]);
        if fk <= 0.0 {
            let fd = f(&step.at(t_at(sk)));
            if fd <= 0.0 {
                return Some(self.locate(step, f, step.t0, t_at(sk), f0, fd));
            }
        }
        let d1 = (fk - fa) / (sk - sa);
        let d2 = (fb - fk) / (sb - sk);
        let c = (d2 - d1) / (sb - sa);
        if c <= 0.0 {
            return None;
        }
        let s_min = 0.5 * (sa + sk) - d1 / (2.0 * c);
        if !(s_min > sa && s_min < sb)
            || fa + d1 * (s_min - sa) + c * (s_min - sa) * (s_min - sk) > 0.0
        {
            return None;
        }
        let f_min = f(&step.at(t_at(s_min)));
        (f_min <= 0.0).then(|| self.locate(step, f, step.t0, t_at(s_min), f0, f_min))
    }

    /// The event of open contact `j` inside `step` where its gap does not change
    /// sign between the ends (`g0`, `g1`): grazing, or a whole flight.
    pub(super) fn gap_event_inside(
        &self,
        step: &Step<NY>,
        j: usize,
        g0: f64,
        g1: f64,
    ) -> Option<f64> {
        let gap = |y: &[f64; NY]| self.gap_at(y, j);
        let un = |y: &[f64; NY]| self.contact_at(y, j).u_n;
        let (u0, u1) = (un(&step.y0), un(&step.y1));
        if g0 > 0.0 && g1 > 0.0 {
            // Grazing: the gap may dip below zero and come back inside the step.
            // Its minimum is where u_n goes from - to +; check the gap there.
            if u0 < 0.0 && u1 > 0.0 {
                let neg_un = |y: &[f64; NY]| -un(y);
                let t_min = self.locate(step, &neg_un, step.t0, step.t1(), -u0, -u1);
                let g_min = gap(&step.at(t_min));
                if g_min <= 0.0 {
                    return Some(self.locate(step, &gap, step.t0, t_min, g0, g_min));
                }
            }
            return None;
        }
        if g0 > 0.0 || g1 > 0.0 || u1 >= -self.settings.velocity_tolerance {
            return None;
        }
        // An open contact that starts at the fundament (just after an impact or a
        // lift-off) and ends the step below it, approaching: a whole flight inside
        // the step, located after its apex.
        let apex = match self.apex(step, j, u0, u1, g1) {
            Ok(te) => return Some(te),
            Err(apex) => apex,
        };
        // Touching at the apex and sinking from there (a contact left open with
        // zero velocity whose force would have been negligible): the event is
        // where it sinks below the together gap, which it may not do within this
        // step.
        let below = |y: &[f64; NY]| gap(y) + self.settings.together_gap;
        let (b0, b1) = (below(&step.at(apex)), below(&step.y1));
        if b0 > 0.0 && b1 <= 0.0 {
            return Some(self.locate(step, &below, apex, step.t1(), b0, b1));
        }
        if b0 > 0.0 {
            return None;
        }
        // Already at the together gap's edge: the event is where it starts to
        // approach measurably (then an impact, however slow, which an
        // accumulation closes).
        let tol = self.settings.velocity_tolerance;
        let approach = |y: &[f64; NY]| un(y) + tol;
        let (a0, a1) = (approach(&step.at(apex)), approach(&step.y1));
        if a0 > 0.0 && a1 <= 0.0 {
            Some(self.locate(step, &approach, apex, step.t1(), a0, a1))
        } else {
            Some(apex)
        }
    }

    /// The landing of open contact `j` inside `step` whose gap starts at rounding
    /// size (within the together gap) and ends at `g1 <= 0`, when the contact
    /// separates at the step's start (`u_n > 0`) and approaches at its end: a
    /// flight shorter than the step (a rocking foot's hop). `None` where it does
    /// not separate, or does not come back (then the crossing is the gap's own).
    fn landing_after_apex(&self, step: &Step<NY>, j: usize, g1: f64) -> Option<f64> {
        let un = |y: &[f64; NY]| self.contact_at(y, j).u_n;
        let (u0, u1) = (un(&step.y0), un(&step.y1));
        if u0 <= 0.0 || u1 >= 0.0 {
            return None;
        }
        self.apex(step, j, u0, u1, g1).ok()
    }

    /// A flight of open contact `j` inside `step` whose normal velocity goes
    /// from `u0` to `u1 < 0` and whose gap ends at `g1 <= 0`: its apex (the root
    /// of `u_n` from + to -, or the step's start where `u0 <= 0`), then, where
    /// the gap there is positive, `Ok` with the gap's root after it (the
    /// landing); `Err` with the apex where the gap is not positive there.
    fn apex(&self, step: &Step<NY>, j: usize, u0: f64, u1: f64, g1: f64) -> Result<f64, f64> {
        let gap = |y: &[f64; NY]| self.gap_at(y, j);
        let un = |y: &[f64; NY]| self.contact_at(y, j).u_n;
        let apex = if u0 > 0.0 {
            self.locate(step, &un, step.t0, step.t1(), u0, u1)
        } else {
            step.t0
        };
        let g_apex = gap(&step.at(apex));
        if g_apex > 0.0 {
            Ok(self.locate(step, &gap, apex, step.t1(), g_apex, g1))
        } else {
            Err(apex)
        }
    }

    /// The force tolerance `eps_F` of the contact modes, N:
    /// [`super::Settings::force_tolerance`] of the machine's weight (of its mass times
    /// 1 m/s^2 where gravity is weaker). A closed contact's normal force stays
    /// above `-eps_F`; a sticking contact's friction within `eps_F` of its cone.
    pub fn force_tolerance(&self) -> f64 {
        let g = self.model.gravity;
        let g = (g[0] * g[0] + g[1] * g[1]).sqrt().max(1.0);
        self.settings.force_tolerance * self.model.total_mass() * g
    }

    /// Contact `j`'s gap at state `y`, m ([`Pose::gap`]).
    pub(super) fn gap_at(&self, y: &[f64; NY], j: usize) -> f64 {
        Pose::new(&self.model, &self.model.q(y)).gap(&self.model, j)
    }

    /// Contact `j`'s kinematics at state `y`.
    pub(super) fn contact_at(&self, y: &[f64; NY], j: usize) -> ContactKinematics {
        let (q, v) = (self.model.q(y), self.model.v(y));
        Pose::new(&self.model, &q).contact(&self.model, j, &v)
    }

    /// Illinois false position on the dense output for the function `f`, from
    /// `f(a) = fa > 0` to `f(b) = fb <= 0`; returns a time where `f <= 0`.
    pub(super) fn locate(
        &self,
        step: &Step<NY>,
        f: &dyn Fn(&[f64; NY]) -> f64,
        a: f64,
        b: f64,
        fa: f64,
        fb: f64,
    ) -> f64 {
        let (mut a, mut b, mut fa, mut fb) = (a, b, fa, fb);
        let mut side = 0i8;
        for _ in 0..200 {
            if b - a <= self.settings.event_time_tolerance {
                break;
            }
            let mut c = (a * fb - b * fa) / (fb - fa);
            if !(c > a && c < b) {
                c = 0.5 * (a + b);
            }
            let fc = f(&step.at(c));
            if fc > 0.0 {
                a = c;
                fa = fc;
                if side == 1 {
                    fb *= 0.5;
                }
                side = 1;
            } else {
                b = c;
                fb = fc;
                if side == -1 {
                    fa *= 0.5;
                }
                side = -1;
            }
        }
        b
    }
}

#[cfg(test)]
mod tests {
    use std::f64::consts::{FRAC_PI_2, PI};

    use super::super::super::integrator::{attempt, Attempt, Tolerance};
    use super::super::tests::resting_with;
    use super::super::{Output, Settings};
    use super::*;
    use crate::event::EventKind;

    /// A step of 1 ms from t0 = 2 s along which the state's first component goes
    /// from 0 to 1 at a constant rate: the dense output there is `s`, the
    /// fraction of the step, exactly.
    fn linear_step() -> Step<NY> {
        let (t0, h) = (2.0, 1e-3);
        let mut rate = [0.0; NY];
        rate[0] = 1.0 / h;
        let tol = Tolerance {
            rtol: 1e-8,
            atol: [1e-8; NY],
            len: NY,
        };
        match attempt(&mut |_, _| rate, t0, &[0.0; NY], &rate, h, &tol) {
            Attempt::Accepted(step, _) => *step,
            Attempt::Rejected(_) => panic!("a step of constant slope rejected"),
        }
    }

    /// The samples of `f` at the step's ends and at the integrator's interior
    /// stages (1/5, 3/10, 4/5, 8/9), as [`Plant::first_crossing`] hands them over.
    fn stage_samples(f: impl Fn(f64) -> f64) -> Vec<(f64, f64)> {
        let mut s = vec![(0.0, f(0.0))];
        s.extend(INTERIOR_STAGES.iter().map(|&c| (c, f(c))));
        s.push((1.0, f(1.0)));
        s
    }

    /// [`Plant::dip`] on synthetic functions of the fraction `s` of a step:
    /// - `(s - 1/2)^2 - 0.01` is positive at every sample (the stages are at
    ///   least 0.2 from 1/2) and below zero from 0.4 to 0.6: the parabola through
    ///   the smallest stage (3/10) and its neighbours (1/5, 4/5) has its minimum
    ///   at 1/2, below zero, so the dip is found and located at its start, 0.4;
    /// - `(s - 6/5)^2 - 0.01` has its minimum beyond the step's end: the
    ///   parabola's minimum lies outside the neighbours of the smallest inner
    ///   sample (8/9, between 4/5 and 1), nothing is found (and there is nothing);
    /// - a stage sample `<= 0` where the dense output there is `> 0` (a stage's
    ///   evaluation is not the dense output's) is not taken for a dip: the
    ///   function, `(s - 1/2)^2 + 0.01`, never dips.
    #[test]
    fn dip_finds_a_dip_between_stage_samples_and_nothing_else() {
        let plant = resting_with(&[], Settings::default());
        let step = linear_step();
        let s_of = |y: &[f64; NY]| y[0];
        let t_of = |s: f64| step.t0 + s * step.h;

        let dips = |s: f64| (s - 0.5) * (s - 0.5) - 0.01;
        let f = |y: &[f64; NY]| dips(s_of(y));
        let samples = stage_samples(dips);
        assert!(samples.iter().all(|&(_, v)| v > 0.0), "{samples:?}");
        let te = plant
            .dip(&step, &f, &samples)
            .expect("the dip between the stages");
        assert!(
            (te - t_of(0.4)).abs() <= 1e-9,
            "located at s = {}, not 0.4",
            (te - step.t0) / step.h
        );
        assert!(f(&step.at(te)) <= 0.0);

        let beyond = |s: f64| (s - 1.2) * (s - 1.2) - 0.01;
        let f = |y: &[f64; NY]| beyond(s_of(y));
        assert_eq!(plant.dip(&step, &f, &stage_samples(beyond)), None);

        let above = |s: f64| (s - 0.5) * (s - 0.5) + 0.01;
        let f = |y: &[f64; NY]| above(s_of(y));
        let mut samples = stage_samples(above);
        samples[2].1 = -1e-3;
        assert_eq!(plant.dip(&step, &f, &samples), None);
    }

    /// The lowest normal force function of a foot at `y`, `lambda_n + eps_F`, N,
    /// in `plant`'s modes.
    fn lowest(plant: &Plant, y: &[f64; NY]) -> f64 {
        let e = plant.evaluate(y);
        let eps_f = plant.force_tolerance();
        (0..plant.modes.len())
            .map(|j| e.lambda_n[j] + eps_f)
            .fold(f64::INFINITY, f64::min)
    }

    /// A closed contact's normal force that goes below zero and comes back inside
    /// one step is a lift-off, located: the reference machine resting on both
    /// feet (rotors without friction, `rtol` 1e-6: steps of `max_step`, 1 ms),
    /// its rotors set at t_a = 10 ms to turn in mirror image at the speed whose
    /// upward pull `2 m e w^2 sin psi` exceeds the weight only for 0.3 ms around
    /// `psi = 90 deg`, which it reaches at t_a + 0.5 ms. The step from t_a to
    /// t_a + 1 ms has every foot's normal force positive at its ends and at its
    /// stages (at 1/5, 3/10, 4/5, 8/9 of it) and negative from 0.35 to 0.65 of it:
    /// only the dip test ([`Plant::dip`]) finds the lift-off, at t_a + 0.35 ms.
    #[test]
    fn a_normal_force_dipping_below_zero_inside_a_step_lifts_the_foot() {
        let settings = Settings {
            rtol: 1e-6,
            ..Settings::default()
        };
        let sets = ["motor.coulomb_friction=0", "motor.viscous_friction=0"];
        let mut plant = resting_with(&sets, settings);
        // The contacts' closing at t = 0 (the start's mode decision).
        plant.events.clear();
        let (t_a, h) = (0.01, plant.settings.max_step);
        plant.advance_to(t_a, &mut |_| {}).unwrap();
        assert!(plant.events.is_empty(), "{:?}", plant.events);
        let n = plant.model.dof;
        let (p1, p2) = (plant.model.rotors[0].phi, plant.model.rotors[1].phi);
        // The rotors at angle psi (the right one mirrored: pi - psi) turning at
        // w (the right one the other way): the upward pull is 2 m e w^2 sin psi.
        let at = |y0: &[f64; NY], psi: f64, w: f64| {
            let mut y = *y0;
            (y[p1], y[p2], y[n + p1], y[n + p2]) = (psi, PI - psi, w, -w);
            y
        };
        let y0 = plant.y;
        // At psi = 90 deg it is a - b w^2 (two speeds give a and b); the pull
        // exceeds the weight within alpha of 90 deg where
        // a - b w^2 cos(alpha) = 0, alpha = w 0.15 ms.
        let (w1, w2) = (200.0, 240.0);
        let (l1, l2) = (
            lowest(&plant, &at(&y0, FRAC_PI_2, w1)),
            lowest(&plant, &at(&y0, FRAC_PI_2, w2)),
        );
        let b = (l1 - l2) / (w2 * w2 - w1 * w1);
        let a = l1 + b * w1 * w1;
        let mut w = (a / b).sqrt();
        for _ in 0..20 {
            w = (a / (b * (w * 0.15e-3).cos())).sqrt();
        }
        let psi0 = FRAC_PI_2 - w * 0.5 * h;
        // The premise: positive at the step's ends and its stages, negative at
        // its middle (at the speed w throughout: the slowing below only makes
        // the ends and stages more positive).
        let sampled: Vec<f64> = [0.0, 0.2, 0.3, 0.8, 8.0 / 9.0, 1.0]
            .iter()
            .map(|s| lowest(&plant, &at(&y0, psi0 + w * s * h, w)))
            .collect();
        assert!(sampled.iter().all(|&v| v > 0.0), "{sampled:?}");
        assert!(lowest(&plant, &at(&y0, FRAC_PI_2, w)) < 0.0);

        // Where the pull first exceeds the weight (in the modes at t_a, all
        // closed): the rotors' speed there from their energy (gravity on the
        // eccentrics slows them on the way up:
        // w(psi)^2 = w^2 - c (sin psi - sin psi0), c = -2 psi'' / cos psi at
        // psi0, 4e-5 of w^2 by 90 deg, which moves the crossing by 6 us), the
        // crossing by bisection, the time at the mean speed of the way there.
        let c = -2.0 * plant.evaluate(&at(&y0, psi0, w)).ydot[n + p1] / psi0.cos();
        let speed = |psi: f64| (w * w - c * (psi.sin() - psi0.sin())).sqrt();
        let (mut lo, mut hi) = (psi0, FRAC_PI_2);
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if lowest(&plant, &at(&y0, mid, speed(mid))) > 0.0 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let expected = t_a + (hi - psi0) / (0.5 * (w + speed(hi)));
        plant.y = at(&y0, psi0, w);
        plant.fsal = None;
        plant.ev_cache = None;
        // The first step's start and size, from its dense output.
        let mut first = None;
        plant
            .advance_to(t_a + h, &mut |out| {
                if let Output::Dense(d, _) = out {
                    first.get_or_insert((d.t0, d.step.h));
                }
            })
            .unwrap();
        let (t0, h0) = first.expect("a step");
        assert!(
            t0 == t_a && (h0 - h).abs() < 1e-15,
            "the first step from {t0} s of {h0} s, not the 1 ms from t_a the premise is of"
        );
        let lift = plant
            .events
            .iter()
            .find(|e| e.kind == EventKind::Liftoff)
            .unwrap_or_else(|| panic!("no lift-off; events {:?}", plant.events));
        assert!(
            (lift.t - expected).abs() < 1e-7,
            "lift-off at t_a + {:.5} ms, expected t_a + {:.5} ms",
            (lift.t - t_a) * 1e3,
            (expected - t_a) * 1e3
        );
        assert!(lift.t - t_a > 0.3 * h && lift.t - t_a < 0.8 * h);
    }
}
