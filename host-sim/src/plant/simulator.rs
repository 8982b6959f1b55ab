//! The hybrid simulation of the vibro driver: smooth motion between events, and
//! events located to high accuracy.
//!
//! Between events every contact is in a fixed **mode**: open, or closed and
//! sticking, or closed and slipping one way. In a mode the motion is smooth: closed
//! contacts are held at zero normal acceleration (and sticking ones at zero
//! tangential acceleration) by contact forces from a linear system, with friction
//! `-mu s lambda_n` on slipping ones; where sticking feet leave the forces
//! undetermined, the weighted minimum norm shares them by the contacts' `weight`
//! (`shared::impact::lcp::solve_states`). The state `(q, q', i)` is integrated by
//! Dormand-Prince 5(4) ([`super::integrator`]).
//!
//! Stages of [`Plant::advance_to`], per accepted step:
//! 1. evaluate the **event functions** at the step's end: an open contact's gap, a
//!    closed contact's normal force (lift-off), a slipping contact's slip velocity,
//!    a sticking contact's distance to the friction cone `mu lambda_n - |lambda_t|`;
//! 2. where one changed sign, locate the earliest crossing on the dense output
//!    (Illinois false position, to [`Settings::event_time_tolerance`]), cut the step
//!    there and **handle the event**: an impact (the `shared` solver, all contacts
//!    within [`Settings::together_gap`] of the fundament in one impact, the whole
//!    mechanism's Delassus matrix with the rotors free), then the new modes from
//!    the complementarity problem at acceleration level (contact, lift-off, stick,
//!    slip); a problem with no consistent solution is a **Painleve** configuration,
//!    resolved by a tangential impact;
//! 3. otherwise accept the step, project the closed contacts back onto their
//!    constraints (the integrator's drift, far below its tolerance) and record
//!    output rows.
//!
//! **Zeno**: an impact whose rebound is slower than [`Settings::zeno_velocity`] is
//! the tail of an accumulation of impacts. It is closed plastically at once and the
//! accumulation point is reported: the remaining bounces of a contact with
//! effective restitution `e = v+/v-` under a normal acceleration `a` last
//! `sum_k 2 v+ e^k / a = 2 v+ / (a (1 - e))` (a geometric series). The threshold is
//! far below every velocity that matters (1e-6 m/s by default): halving or doubling
//! it moves the rest point by less than the event tolerance.

use shared::impact::lcp::{find_direction, solve_states, Direction, NormalRule, Tolerances};
use shared::impact::linalg::{solve_weighted, Solved, Vector, DIM};
use shared::impact::split::within_cones;
use shared::impact::{solve, ImpactLaw, ImpactProblem, SlipState, MAX_CONTACTS};

use super::dynamics::{contact_kinematics, ContactKinematics, Frame, DOF};
use super::integrator::{attempt, Attempt, Step, Tolerance};
use super::model::PlantModel;
use super::motor::{DcMotor, Winding};
use crate::trace::{EventKind, EventRow, TraceRow};

/// Events handled at one instant without progress before the step is taken anyway.
const MAX_STALLED_EVENTS: u32 = 16;

/// Size of the integrated state: `q` (5), `q'` (5), winding currents (2).
pub const NY: usize = 2 * DOF + 2;

/// The mode of a contact between events.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ContactMode {
    /// Not touching, or touching and separating.
    Open,
    /// Touching, held by a normal force; tangential velocity held at zero.
    Stick,
    /// Touching, slipping along `+t`.
    SlipPositive,
    /// Touching, slipping along `-t`.
    SlipNegative,
}

impl ContactMode {
    fn from_slip(s: SlipState) -> Self {
        match s {
            SlipState::Stick => ContactMode::Stick,
            SlipState::SlipPositive => ContactMode::SlipPositive,
            SlipState::SlipNegative => ContactMode::SlipNegative,
        }
    }

    fn slip_state(self) -> SlipState {
        match self {
            ContactMode::SlipPositive => SlipState::SlipPositive,
            ContactMode::SlipNegative => SlipState::SlipNegative,
            _ => SlipState::Stick,
        }
    }

    fn closed(self) -> bool {
        self != ContactMode::Open
    }
}

/// What an event function watches: each is positive until its event, and one
/// function watches one condition.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Watch {
    /// Open contact `j`: its gap, m (impact, or the contact closes).
    Gap(usize),
    /// Closed contact `j`: its normal force plus `eps_F`, N (lift-off).
    NormalForce(usize),
    /// Sticking contact `j`: `mu lambda_n - |lambda_t| + eps_F`, N (the cone is
    /// exceeded).
    Cone(usize),
    /// Slipping contact `j`: `s u_t + eps_v`, m/s (the slip ends).
    SlipEnds(usize),
    /// Motor `k`'s driver: `I_lim - |i|`, A (the current limit is reached).
    CurrentLimit(usize),
    /// An unused slot (the second slot of an open contact).
    Nothing,
}

/// Numerical settings, with the reasons for their defaults.
#[derive(Clone, Copy, Debug)]
pub struct Settings {
    /// Relative tolerance of the integrator. 1e-8: the platform's travel per
    /// revolution is a small difference of large motions.
    pub rtol: f64,
    /// Largest step, s. 1e-3 s: no event hides inside a step (a foot that dips
    /// below the fundament and back within one is found at its gap's minimum), so
    /// the step is limited only for the dense output's sake.
    pub max_step: f64,
    /// Contacts within this gap of the fundament take part in the same impact, m.
    /// 1e-7 m: far below any flight height, far above the event location error
    /// (a contact approaching at 1 m/s moves 1e-12 m within the time tolerance).
    pub together_gap: f64,
    /// Rebound speed below which an impact ends an accumulation (Zeno), m/s.
    pub zeno_velocity: f64,
    /// Time tolerance of event location, s.
    pub event_time_tolerance: f64,
    /// Contact velocities within this are zero, m/s.
    pub velocity_tolerance: f64,
    /// The force tolerance of the contact modes, as a fraction of the machine's
    /// weight: a closed contact lifts off where its normal force goes below
    /// `-force_tolerance x weight`, a sticking one slips where its friction
    /// leaves its cone by as much. 1e-6 (2e-5 N for the reference machine): a
    /// thousand times the mode decision's tolerance, which must lie well above
    /// rounding (1e-13 of the forces) and well below this margin, so that the
    /// condition whose event fired is clearly violated at the decision; and small
    /// enough to change nothing that matters (a lift-off delayed by
    /// `eps_F / (d lambda_n / dt)`, 2e-9 s at 3000 rpm).
    pub force_tolerance: f64,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            rtol: 1e-8,
            max_step: 1e-3,
            together_gap: 1e-7,
            zeno_velocity: 1e-6,
            event_time_tolerance: 1e-12,
            velocity_tolerance: 1e-7,
            force_tolerance: 1e-6,
        }
    }
}

/// Coordinates held still (for tests against closed forms).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Holds {
    /// Hold the platform (x, y, theta).
    pub platform: bool,
    /// Hold both rotors at their current speed relative to the platform.
    pub rotors: bool,
    /// Rotor k jammed: held at rest relative to the platform (fault injection).
    pub jammed: [bool; 2],
}

impl Holds {
    fn mask(self) -> [bool; DOF] {
        let p = self.platform;
        let r = self.rotors;
        [p, p, p, r || self.jammed[0], r || self.jammed[1]]
    }
}

/// An evaluation with the state and modes it was made at.
type CachedEvaluation = ([f64; NY], [ContactMode; MAX_CONTACTS], Evaluation);

/// Contact forces and accelerations at a state, in the current modes.
#[derive(Clone)]
struct Evaluation {
    ydot: [f64; NY],
    /// Normal force of each contact (0 when open), N.
    lambda_n: [f64; MAX_CONTACTS],
    /// Tangential force of each contact, N.
    lambda_t: [f64; MAX_CONTACTS],
}

/// The simulated machine: model, state, modes, inputs and what happened.
pub struct Plant {
    /// The constant model.
    pub model: PlantModel,
    /// Numerical settings.
    pub settings: Settings,
    /// Coordinates held still.
    pub holds: Holds,
    /// Time, s.
    pub t: f64,
    /// State `(q, q', i)`.
    pub y: [f64; NY],
    /// The contacts' modes.
    pub modes: Vec<ContactMode>,
    /// What the H-bridges put on the windings.
    pub winding: [Winding; 2],
    /// Events so far.
    pub events: Vec<EventRow>,
    /// Impact instants so far.
    pub impacts: usize,
    /// Warnings (deduplicated).
    pub warnings: Vec<String>,
    /// Accepted integration steps so far.
    pub steps: u64,
    motors: [DcMotor; 2],
    h: f64,
    fsal: Option<[f64; NY]>,
    /// Inside the resolution of a Painleve configuration.
    resolving_painleve: bool,
    /// Event functions of the state left by the last `advance_to`.
    ev_cache: Option<([f64; NY], Vec<f64>)>,
    /// The last evaluation in the current modes, with its state.
    last_evaluation: std::cell::RefCell<Option<CachedEvaluation>>,
    /// The windings of the last evaluation.
    last_winding: std::cell::Cell<[Winding; 2]>,
}

impl Plant {
    /// A plant at `t = 0` in state `y` (see [`NY`]), windings open, modes decided
    /// from the state.
    pub fn new(model: PlantModel, y: [f64; NY], settings: Settings, holds: Holds) -> Self {
        let motors = [
            DcMotor::new(model.rotors[0].motor.clone()),
            DcMotor::new(model.rotors[1].motor.clone()),
        ];
        let n = model.contacts.len();
        let mut plant = Plant {
            model,
            settings,
            holds,
            t: 0.0,
            y,
            modes: vec![ContactMode::Open; n],
            winding: [Winding::Open, Winding::Open],
            events: Vec::new(),
            impacts: 0,
            warnings: Vec::new(),
            steps: 0,
            motors,
            h: 1e-5,
            fsal: None,
            resolving_painleve: false,
            ev_cache: None,
            last_evaluation: std::cell::RefCell::new(None),
            last_winding: std::cell::Cell::new([Winding::Open, Winding::Open]),
        };
        plant.settle();
        plant
    }

    /// Sets what the H-bridges put on the windings (held until changed).
    pub fn set_winding(&mut self, winding: [Winding; 2]) {
        if winding != self.winding {
            self.winding = winding;
            self.fsal = None;
            self.ev_cache = None;
            self.clamp_currents();
        }
    }

    /// Jams rotor `k` (or frees it): a jammed rotor stops at once relative to the
    /// platform (the bearing seizes; the impulse of the stop on the platform is
    /// not modelled) and stays at rest; its motor then stalls against the jam.
    pub fn set_jam(&mut self, k: usize, jammed: bool) {
        if self.holds.jammed[k] != jammed {
            self.holds.jammed[k] = jammed;
            if jammed {
                self.y[DOF + 3 + k] = 0.0;
            }
            self.fsal = None;
            self.ev_cache = None;
        }
    }

    /// Generalized coordinates `q`.
    pub fn q(&self) -> [f64; DOF] {
        core::array::from_fn(|i| self.y[i])
    }

    /// Generalized velocities `q'`.
    pub fn v(&self) -> [f64; DOF] {
        core::array::from_fn(|i| self.y[DOF + i])
    }

    /// Winding currents, A.
    pub fn currents(&self) -> [f64; 2] {
        [self.y[2 * DOF], self.y[2 * DOF + 1]]
    }

    /// The configuration terms at `q` with the holds applied.
    fn frame(&self, q: &[f64; DOF]) -> Frame {
        Frame::locked(&self.model, q, &self.holds.mask())
    }

    /// Adds a warning once.
    fn warn(&mut self, w: String) {
        if !self.warnings.contains(&w) {
            self.warnings.push(w);
        }
    }

    /// Accelerations and contact forces at `y` in the current modes.
    fn evaluate(&self, y: &[f64; NY]) -> Evaluation {
        // The last evaluation is kept: the event functions at a step's end ask
        // for the state the integrator's last stage has just evaluated (FSAL).
        let mut modes = [ContactMode::Open; MAX_CONTACTS];
        modes[..self.modes.len()].copy_from_slice(&self.modes);
        if let Some((yc, mc, e)) = self.last_evaluation.borrow().as_ref() {
            if yc == y && *mc == modes && self.winding == self.last_winding.get() {
                return e.clone();
            }
        }
        let e = self.evaluate_with_modes(y, &self.modes);
        *self.last_evaluation.borrow_mut() = Some((*y, modes, e.clone()));
        self.last_winding.set(self.winding);
        e
    }

    /// Accelerations and contact forces at `y` with the contacts in `modes`.
    fn evaluate_with_modes(&self, y: &[f64; NY], modes: &[ContactMode]) -> Evaluation {
        let q: [f64; DOF] = core::array::from_fn(|i| y[i]);
        let v: [f64; DOF] = core::array::from_fn(|i| y[DOF + i]);
        let frame = self.frame(&q);

        // Motors: shaft speed relative to the platform in the driven sense.
        let mut tau = [0.0; 2];
        let mut di = [0.0; 2];
        for k in 0..2 {
            let s = self.model.rotors[k].sense;
            let omega_m = s * v[3 + k];
            let i = y[2 * DOF + k];
            tau[k] = s * self.motors[k].shaft_torque(i, omega_m);
            di[k] = self.motors[k].current_rate(self.winding[k], i, omega_m);
        }
        let mut f = frame.forces(&self.model, &v, tau);
        for (i, held) in self.holds.mask().iter().enumerate() {
            if *held {
                f[i] = 0.0;
            }
        }
        let mut acc = frame.solve(&f);

        // Closed contacts: forces from their mode's equations.
        let mut lambda_n = [0.0; MAX_CONTACTS];
        let mut lambda_t = [0.0; MAX_CONTACTS];
        // The closed contacts, without allocating (this runs at every stage).
        let mut closed_buf = [0usize; MAX_CONTACTS];
        let mut n_closed = 0;
        for (j, m) in modes.iter().enumerate() {
            if m.closed() {
                closed_buf[n_closed] = j;
                n_closed += 1;
            }
        }
        let closed = &closed_buf[..n_closed];
        if !closed.is_empty() {
            let sys = self.contact_system(&frame, &q, &v, closed, Some(&acc));
            let mut active = [false; MAX_CONTACTS];
            let mut mode = [SlipState::Stick; MAX_CONTACTS];
            for (r, &j) in closed.iter().enumerate() {
                active[r] = true;
                mode[r] = modes[j].slip_state();
            }
            let zeros = [0.0; MAX_CONTACTS];
            // No solution of the closed contacts' equations: no contact force (the
            // mode is re-decided at the next event).
            if let Some((_, d, how)) = solve_states(
                &sys.problem,
                &sys.base_n,
                &sys.base_t,
                &active,
                &mode,
                Some(&zeros),
                None,
            ) {
                let (x, y) = self.share_within_cones(closed, modes, &sys, &d, how);
                for (r, &j) in closed.iter().enumerate() {
                    lambda_n[j] = x[r];
                    lambda_t[j] = y[r];
                    // The internal forces do no work: accelerations from either split.
                    for i in 0..DOF {
                        acc[i] += d.x[r] * sys.minv_jn[r][i] + d.y[r] * sys.minv_jt[r][i];
                    }
                }
            }
        }
        let mut ydot = [0.0; NY];
        ydot[..DOF].copy_from_slice(&v);
        ydot[DOF..2 * DOF].copy_from_slice(&acc);
        ydot[2 * DOF] = di[0];
        ydot[2 * DOF + 1] = di[1];
        Evaluation {
            ydot,
            lambda_n,
            lambda_t,
        }
    }

    /// The closed contacts' forces with the internal forces chosen so that every
    /// sticking contact is inside its cone, where the equations left them
    /// undetermined ([`shared::impact::split`], the same split the mode decision's
    /// stick check uses). Where no split holds every cone, the forces are left where
    /// the largest violation is smallest, and the stick event function
    /// (`mu lambda_n - |lambda_t|`) reports it.
    fn share_within_cones(
        &self,
        closed: &[usize],
        modes: &[ContactMode],
        sys: &ContactSystem,
        d: &Direction<f64, MAX_CONTACTS>,
        how: Solved,
    ) -> ([f64; MAX_CONTACTS], [f64; MAX_CONTACTS]) {
        let (mut x, mut y) = (d.x, d.y);
        let mut active = [false; MAX_CONTACTS];
        let mut mode = [SlipState::Stick; MAX_CONTACTS];
        for (r, &j) in closed.iter().enumerate() {
            active[r] = true;
            mode[r] = modes[j].slip_state();
        }
        let inside = |x: &[f64; MAX_CONTACTS], y: &[f64; MAX_CONTACTS]| {
            (0..closed.len()).all(|r| {
                let tol = 1e-9 * (x[r].abs() + y[r].abs());
                x[r] >= -tol
                    && (mode[r] != SlipState::Stick
                        || y[r].abs() <= sys.problem.contacts[r].friction * x[r] + tol)
            })
        };
        if inside(&x, &y)
            || how == Solved::Unique
            || !mode[..closed.len()].contains(&SlipState::Stick)
        {
            return (x, y);
        }
        let scale =
            (0..closed.len()).fold(f64::MIN_POSITIVE, |s, r| s.max(x[r].abs()).max(y[r].abs()));
        within_cones(
            &sys.problem,
            &active,
            &mode,
            true,
            &mut x,
            &mut y,
            1e-9 * scale,
        );
        (x, y)
    }

    /// The contact problem of the contacts `set`: Delassus matrix
    /// `W = J M^-1 J^T` (rotors free unless held), `M^-1 J^T`, and, given the
    /// accelerations without contact forces, the contact accelerations they add to.
    fn contact_system(
        &self,
        frame: &Frame,
        q: &[f64; DOF],
        v: &[f64; DOF],
        set: &[usize],
        acc_free: Option<&[f64; DOF]>,
    ) -> ContactSystem {
        let mut sys = ContactSystem {
            problem: ImpactProblem::new(self.model.law),
            minv_jn: [[0.0; DOF]; MAX_CONTACTS],
            minv_jt: [[0.0; DOF]; MAX_CONTACTS],
            kin: [ContactKinematics::default(); MAX_CONTACTS],
            base_n: [0.0; MAX_CONTACTS],
            base_t: [0.0; MAX_CONTACTS],
        };
        sys.problem.len = set.len();
        for (r, &j) in set.iter().enumerate() {
            let k = frame.contact(&self.model, j, q, v);
            sys.minv_jn[r] = frame.solve(&k.j_n);
            sys.minv_jt[r] = frame.solve(&k.j_t);
            sys.problem.u_n[r] = k.u_n;
            sys.problem.u_t[r] = k.u_t;
            sys.problem.contacts[r] = self.model.contacts[j].law;
            if let Some(a) = acc_free {
                let row = |jr: &[f64; DOF]| (0..DOF).map(|i| jr[i] * a[i]).sum::<f64>();
                sys.base_n[r] = row(&k.j_n) + k.bias_n;
                sys.base_t[r] = row(&k.j_t) + k.bias_t;
            }
            sys.kin[r] = k;
        }
        for r in 0..set.len() {
            for c in 0..set.len() {
                let (jn, jt) = (&sys.kin[r].j_n, &sys.kin[r].j_t);
                let dotp =
                    |a: &[f64; DOF], b: &[f64; DOF]| (0..DOF).map(|i| a[i] * b[i]).sum::<f64>();
                sys.problem.w_nn[r][c] = dotp(jn, &sys.minv_jn[c]);
                sys.problem.w_nt[r][c] = dotp(jn, &sys.minv_jt[c]);
                sys.problem.w_tt[r][c] = dotp(jt, &sys.minv_jt[c]);
            }
        }
        sys
    }

    /// What event function `i` watches (see [`Watch`]): two slots per contact,
    /// then one per motor driver.
    fn watch(&self, i: usize) -> Watch {
        let n = self.modes.len();
        if i >= 2 * n {
            return Watch::CurrentLimit(i - 2 * n);
        }
        let j = i / 2;
        match (self.modes[j], i % 2) {
            (ContactMode::Open, 0) => Watch::Gap(j),
            (ContactMode::Open, _) => Watch::Nothing,
            (_, 0) => Watch::NormalForce(j),
            (ContactMode::Stick, _) => Watch::Cone(j),
            // Without friction the slip's direction changes no force: no event.
            (_, _) if self.model.contacts[j].law.friction == 0.0 => Watch::Nothing,
            (_, _) => Watch::SlipEnds(j),
        }
    }

    /// The event functions at `y`, each positive until its event and `<= 0`
    /// once it happened, one function per condition (never combined: a function
    /// that cannot change sign must not hide another's crossing). Slots `2j` and
    /// `2j + 1` are contact `j`'s:
    ///
    /// | mode | slot `2j` | slot `2j + 1` |
    /// | --- | --- | --- |
    /// | open | gap, m | (none: `+inf`) |
    /// | closed | `lambda_n + eps_F`, N (lift-off) | stick: `mu lambda_n - abs(lambda_t) + eps_F`, N (cone exceeded); slip: `s u_t + eps_v`, m/s (slip ends) |
    ///
    /// then each motor driver's `I_lim - |i|` (the current limit: the current's
    /// equation switches there). `eps_F` is [`Plant::force_tolerance`] and
    /// `eps_v` the velocity tolerance: a mode just decided starts with every
    /// function at least that far from zero (the mode decision's own tolerance is
    /// a thousandth of it), so a crossing is a change of sign, never a value that
    /// was already zero.
    fn event_values(&self, y: &[f64; NY]) -> Vec<f64> {
        let q: [f64; DOF] = core::array::from_fn(|i| y[i]);
        let v: [f64; DOF] = core::array::from_fn(|i| y[DOF + i]);
        let needs_forces = self.modes.iter().any(|m| m.closed());
        let ev = needs_forces.then(|| self.evaluate(y));
        let cs = q[2].sin_cos();
        let eps_f = self.force_tolerance();
        let eps_v = self.settings.velocity_tolerance;
        let mut values = Vec::with_capacity(2 * self.modes.len() + 2);
        for j in 0..self.modes.len() {
            let k = contact_kinematics(&self.model, cs, j, &q, &v);
            let mu = self.model.contacts[j].law.friction;
            let (ln, lt) = ev
                .as_ref()
                .map_or((0.0, 0.0), |e| (e.lambda_n[j], e.lambda_t[j]));
            let (normal, tangential) = match self.modes[j] {
                ContactMode::Open => (k.gap, f64::INFINITY),
                ContactMode::Stick => (ln + eps_f, mu * ln - lt.abs() + eps_f),
                // Without friction the slip's direction changes no force.
                _ if mu == 0.0 => (ln + eps_f, f64::INFINITY),
                ContactMode::SlipPositive => (ln + eps_f, k.u_t + eps_v),
                ContactMode::SlipNegative => (ln + eps_f, -k.u_t + eps_v),
            };
            values.push(normal);
            values.push(tangential);
        }
        for k in 0..2 {
            values.push(match self.winding[k] {
                Winding::Voltage(_) => {
                    self.model.rotors[k].motor.current_limit - y[2 * DOF + k].abs()
                }
                Winding::Open => f64::INFINITY,
            });
        }
        values
    }

    /// Integrates until `t_target`, handling every event on the way; `record` is
    /// called with the states to output (see [`Output`]).
    pub fn advance_to(&mut self, t_target: f64, record: &mut dyn FnMut(Output<'_>)) {
        let tol = self.tolerance();
        // The event functions at the start: kept from the last call while the state
        // and the windings are unchanged (a control tick does not move the state).
        let mut ev0 = match self.ev_cache.take() {
            Some((y, v)) if y == self.y => v,
            _ => self.event_values(&self.y),
        };
        let mut stalled = 0u32;
        while self.t < t_target {
            let f0 = match self.fsal {
                Some(f) => f,
                None => {
                    let f = self.evaluate(&self.y).ydot;
                    self.fsal = Some(f);
                    f
                }
            };
            let remaining = t_target - self.t;
            let h = self.h.min(self.settings.max_step).min(remaining);
            let (t, y) = (self.t, self.y);
            let outcome = {
                let this = &*self;
                let mut rhs = |_t: f64, yy: &[f64; NY]| this.evaluate(yy).ydot;
                attempt(&mut rhs, t, &y, &f0, h, &tol)
            };
            match outcome {
                Attempt::Rejected(next) => {
                    self.h = next;
                    if self.h < 1e-14 {
                        self.warn(format!(
                            "integrator: step size underflow at t = {:.9} s; state held",
                            self.t
                        ));
                        self.t = t_target;
                        return;
                    }
                }
                Attempt::Accepted(step, next) => {
                    self.steps += 1;
                    // Keep the suggested size unless the step was cut by the target.
                    if h < remaining || next < self.h {
                        self.h = next;
                    }
                    let ev1 = self.event_values(&step.y1);
                    match self.first_crossing(&step, &ev0, &ev1) {
                        Some((te, ye)) if te > step.t0 || stalled < MAX_STALLED_EVENTS => {
                            stalled = if te > step.t0 { 0 } else { stalled + 1 };
                            record(Output::Dense(self.dense(&step), te));
                            self.t = te;
                            self.y = ye;
                            record(Output::Before(At {
                                t: self.t,
                                y: &self.y,
                                plant: self,
                            }));
                            self.fsal = None;
                            self.settle();
                            record(Output::After(At {
                                t: self.t,
                                y: &self.y,
                                plant: self,
                            }));
                            ev0 = self.event_values(&self.y);
                        }
                        found => {
                            if found.is_some() {
                                // The same event at the same instant, handled again
                                // and again without effect: take the step as it is.
                                self.warn(format!(
                                    "events: no progress at t = {:.9} s; a step was taken past an event",
                                    self.t
                                ));
                                stalled = 0;
                            }
                            record(Output::Dense(self.dense(&step), step.t1()));
                            self.t = step.t1();
                            self.y = step.y1;
                            self.fsal = Some(step.f1);
                            self.clamp_currents();
                            if self.modes.iter().any(|m| m.closed()) {
                                self.project();
                                self.fsal = None;
                                ev0 = self.event_values(&self.y);
                            } else {
                                ev0 = ev1;
                            }
                        }
                    }
                }
            }
        }
        self.ev_cache = Some((self.y, ev0));
    }

    /// The integrator's tolerances: relative `rtol`; absolute `1e-3 rtol` m on the
    /// platform's position (the travel per impact is a small difference of large
    /// motions), `rtol` rad, rad/s, m/s elsewhere, and `rtol` times the current
    /// limit on the winding currents (their natural scale; tighter only adds steps
    /// to follow the 0.25 ms electrical transient: about 10 % more accepted steps
    /// for the reference machine with `rtol` amperes).
    fn tolerance(&self) -> Tolerance<NY> {
        let r = self.settings.rtol;
        let mut atol = [r; NY];
        for a in atol.iter_mut().take(2) {
            *a = 1e-3 * r;
        }
        for k in 0..2 {
            atol[2 * DOF + k] = r * self.model.rotors[k].motor.current_limit;
        }
        Tolerance { rtol: r, atol }
    }

    /// Clamps the winding currents to the drivers' limits.
    fn clamp_currents(&mut self) {
        for k in 0..2 {
            self.y[2 * DOF + k] =
                self.motors[k].project_current(self.winding[k], self.y[2 * DOF + k]);
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
    ///   below zero and comes back inside the step: the parabola through its
    ///   values at the step's start, middle and end ([`dip`]) predicts the
    ///   minimum, and the function there is checked on the dense output;
    /// - a closed contact whose normal force is already below `-eps_F` at the
    ///   step's start (a mode left inconsistent, which the mode decision should
    ///   never produce): the event is at the start, so a contact never stays
    ///   closed while its mode's equations make it pull.
    fn first_crossing(
        &self,
        step: &Step<NY>,
        ev0: &[f64],
        ev1: &[f64],
    ) -> Option<(f64, [f64; NY])> {
        let mut best: Option<f64> = None;
        let mut consider = |te: f64| {
            if best.is_none_or(|b| te < b) {
                best = Some(te);
            }
        };
        // The event functions at the step's middle, computed once if needed.
        let t_mid = step.t0 + 0.5 * step.h;
        let mut mid: Option<Vec<f64>> = None;
        for i in 0..ev0.len() {
            let f = |y: &[f64; NY]| self.event_values(y)[i];
            let watch = self.watch(i);
            if ev0[i] > 0.0 && ev1[i] <= 0.0 {
                consider(self.locate(step, &f, step.t0, step.t1(), ev0[i], ev1[i]));
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
                        let fm = mid.get_or_insert_with(|| self.event_values(&step.at(t_mid)))[i];
                        if let Some(te) = self.dip(step, &f, [ev0[i], fm, ev1[i]]) {
                            consider(te);
                        }
                    } else if ev0[i] <= 0.0 && matches!(watch, Watch::NormalForce(_)) {
                        consider(step.t0);
                    }
                }
                Watch::CurrentLimit(_) | Watch::Nothing => {}
            }
        }
        best.map(|te| {
            if te >= step.t1() {
                (step.t1(), step.y1)
            } else if te <= step.t0 {
                (step.t0, step.y0)
            } else {
                (te, step.at(te))
            }
        })
    }

    /// A dip of a function below zero inside `step` although it is positive at
    /// both ends: `values` at the start, the middle and the end. The parabola
    /// through them, `f(s) = f0 + b s + c s^2` on `s in [0, 1]` with
    /// `c = 2 (f1 - 2 fm + f0)`, `b = f1 - f0 - c`, has its minimum
    /// `f0 - b^2 / (4 c)` at `s = -b / (2 c)`; where that is `<= 0` inside the step
    /// (or the middle value itself is), the function is evaluated there on the
    /// dense output and, if it is past its event, the crossing before it is
    /// located.
    fn dip(&self, step: &Step<NY>, f: &dyn Fn(&[f64; NY]) -> f64, values: [f64; 3]) -> Option<f64> {
        let [f0, fm, f1] = values;
        let t_at = |s: f64| step.t0 + s * step.h;
        if fm <= 0.0 {
            return Some(self.locate(step, f, step.t0, t_at(0.5), f0, fm));
        }
        let c = 2.0 * (f1 - 2.0 * fm + f0);
        if c <= 0.0 {
            return None;
        }
        let b = f1 - f0 - c;
        let s_min = -b / (2.0 * c);
        if !(s_min > 0.0 && s_min < 1.0) || f0 - b * b / (4.0 * c) > 0.0 {
            return None;
        }
        let f_min = f(&step.at(t_at(s_min)));
        (f_min <= 0.0).then(|| self.locate(step, f, step.t0, t_at(s_min), f0, f_min))
    }

    /// The event of open contact `j` inside `step` where its gap does not change
    /// sign between the ends (`g0`, `g1`): grazing, or a whole flight.
    fn gap_event_inside(&self, step: &Step<NY>, j: usize, g0: f64, g1: f64) -> Option<f64> {
        let gap = |y: &[f64; NY]| self.contact_at(y, j).gap;
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
        // the step. Bracket its apex (u_n from + to -), then the gap's root after
        // it.
        let apex = if u0 > 0.0 {
            self.locate(step, &un, step.t0, step.t1(), u0, u1)
        } else {
            step.t0
        };
        let g_apex = gap(&step.at(apex));
        if g_apex > 0.0 {
            return Some(self.locate(step, &gap, apex, step.t1(), g_apex, g1));
        }
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

    /// The force tolerance `eps_F` of the contact modes, N:
    /// [`Settings::force_tolerance`] of the machine's weight (of its mass times
    /// 1 m/s^2 where gravity is weaker). A closed contact's normal force stays
    /// above `-eps_F`; a sticking contact's friction within `eps_F` of its cone.
    pub fn force_tolerance(&self) -> f64 {
        let g = self.model.gravity;
        let g = (g[0] * g[0] + g[1] * g[1]).sqrt().max(1.0);
        self.settings.force_tolerance * self.model.total_mass() * g
    }

    /// The dense output of `step` as the plant reports it.
    fn dense<'a>(&'a self, step: &'a Step<NY>) -> Dense<'a> {
        Dense {
            t0: step.t0,
            step,
            plant: self,
        }
    }

    /// Contact `j`'s kinematics at state `y`.
    fn contact_at(&self, y: &[f64; NY], j: usize) -> ContactKinematics {
        let q: [f64; DOF] = core::array::from_fn(|i| y[i]);
        let v: [f64; DOF] = core::array::from_fn(|i| y[DOF + i]);
        contact_kinematics(&self.model, q[2].sin_cos(), j, &q, &v)
    }

    /// Illinois false position on the dense output for the function `f`, from
    /// `f(a) = fa > 0` to `f(b) = fb <= 0`; returns a time where `f <= 0`.
    fn locate(
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

    /// At an event: impacts where contacts approach, then the contacts' modes from
    /// the complementarity problem at acceleration level.
    fn settle(&mut self) {
        // A current that reached its driver's limit is held there.
        self.clamp_currents();
        for _ in 0..16 {
            let q = self.q();
            let v = self.v();
            let frame = Frame::new(&self.model, &q);
            let kin: Vec<ContactKinematics> = (0..self.model.contacts.len())
                .map(|j| frame.contact(&self.model, j, &q, &v))
                .collect();
            let touching: Vec<usize> = (0..kin.len())
                .filter(|j| kin[*j].gap <= self.settings.together_gap)
                .collect();
            if touching
                .iter()
                .any(|j| kin[*j].u_n < -self.settings.velocity_tolerance)
            {
                self.impact(&touching);
                continue;
            }
            self.decide_modes(&touching, &kin);
            return;
        }
        self.warn(format!(
            "contacts: no consistent state after 16 impacts at t = {:.9} s",
            self.t
        ));
    }

    /// One impact of the contacts `set` (all within the together gap).
    fn impact(&mut self, set: &[usize]) {
        let q = self.q();
        let v = self.v();
        let frame = self.frame(&q);
        let sys = self.contact_system(&frame, &q, &v, set, None);
        let outcome = match solve(&sys.problem) {
            Ok(o) => o,
            Err(e) => {
                self.warn(format!("impact at t = {:.9} s not solved: {e:?}", self.t));
                return;
            }
        };
        let approach = (0..set.len())
            .map(|r| -sys.problem.u_n[r])
            .fold(0.0, f64::max);
        let rebound = (0..set.len())
            .filter(|r| outcome.contacts[*r].normal_impulse > 0.0)
            .map(|r| outcome.contacts[r].normal_velocity_after)
            .fold(0.0, f64::max);

        // Zeno: a rebound slower than the threshold ends an accumulation; close it
        // plastically and report the accumulation point.
        let zeno = rebound > 0.0 && rebound < self.settings.zeno_velocity;
        let outcome = if zeno {
            let mut plastic = sys.problem.clone();
            for r in 0..set.len() {
                plastic.contacts[r].restitution = 0.0;
            }
            solve(&plastic).unwrap_or(outcome)
        } else {
            outcome
        };

        // Velocity jump: q'+ = q'- + M^-1 J^T P.
        for (r, &j) in set.iter().enumerate() {
            let c = &outcome.contacts[r];
            for i in 0..DOF {
                self.y[DOF + i] +=
                    c.normal_impulse * sys.minv_jn[r][i] + c.tangential_impulse * sys.minv_jt[r][i];
            }
            if c.normal_impulse > 0.0 || sys.problem.u_n[r] < 0.0 {
                self.events.push(EventRow {
                    t: self.t,
                    kind: EventKind::Impact,
                    contact: self.model.contacts[j].name.clone(),
                    normal_velocity_before: c.normal_velocity_before,
                    normal_velocity_after: c.normal_velocity_after,
                    normal_impulse: c.normal_impulse,
                    tangential_impulse: c.tangential_impulse,
                    case: Some(c.case.number()),
                    detail: String::new(),
                });
            }
        }
        self.impacts += 1;
        self.fsal = None;
        if !outcome.warnings.is_empty() {
            let w = outcome.warnings;
            use shared::impact::Warnings as W;
            if w.contains(W::ENERGY_GAINED) && self.model.law != ImpactLaw::Newton {
                self.warn(
                    "impacts: energy gained at an impact (unequal restitution at several contacts)"
                        .into(),
                );
            }
            if w.contains(W::PENETRATION_LEFT) {
                self.warn("impacts: a contact still approached after an impact".into());
            }
            if w.contains(W::INCONSISTENT) {
                self.warn("impacts: inconsistent contact states inside an impact".into());
            }
        }
        if zeno {
            // Remaining flight time of the accumulation: 2 v+ / (a (1 - e)).
            let e = (rebound / approach).clamp(0.0, 0.999_999);
            let acc = self.free_normal_acceleration(set);
            let remaining = if acc < 0.0 {
                2.0 * rebound / (-acc * (1.0 - e))
            } else {
                0.0
            };
            let at = self.t + remaining;
            for &j in set {
                self.events.push(EventRow {
                    t: self.t,
                    kind: EventKind::Zeno,
                    contact: self.model.contacts[j].name.clone(),
                    normal_velocity_before: 0.0,
                    normal_velocity_after: 0.0,
                    normal_impulse: 0.0,
                    tangential_impulse: 0.0,
                    case: None,
                    detail: format!("accumulation_time={at:.12}"),
                });
            }
        }
    }

    /// The largest (least negative) normal acceleration without contact forces
    /// among `set`, m/s^2.
    fn free_normal_acceleration(&self, set: &[usize]) -> f64 {
        let q = self.q();
        let v = self.v();
        let frame = self.frame(&q);
        let open = vec![ContactMode::Open; self.modes.len()];
        let e = self.evaluate_with_modes(&self.y, &open);
        set.iter()
            .map(|&j| {
                let k = frame.contact(&self.model, j, &q, &v);
                (0..DOF).map(|i| k.j_n[i] * e.ydot[DOF + i]).sum::<f64>() + k.bias_n
            })
            .fold(f64::NEG_INFINITY, f64::max)
    }

    /// The modes of the touching contacts (not approaching) from the
    /// complementarity problem at acceleration level; the rest open.
    fn decide_modes(&mut self, touching: &[usize], kin: &[ContactKinematics]) {
        let old = self.modes.clone();
        // A slip that ended (its event fires within the velocity tolerance of zero)
        // ends exactly: the least mass-weighted velocity change that zeroes its
        // slip and keeps the closed contacts' normal velocities, so the choice
        // between stick and slip starts from zero slip and cannot chatter. Still
        // needed with the cone-aware stick check (it is about the slip velocity,
        // not the split): without it `closed_loop` takes 89 s instead of 1.6 s,
        // `plant_references` 332 s instead of 0.3 s, and
        // `both_feet_sticking_stay_inside_their_cones` fails.
        // Only where friction can stop the slip: the snap is the friction impulse
        // that would have ended it; a frictionless contact has none (and no
        // slip-end event), so nothing may change its slip.
        let ending: Vec<usize> = (0..old.len())
            .filter(|&j| {
                matches!(
                    old[j],
                    ContactMode::SlipPositive | ContactMode::SlipNegative
                ) && kin[j].u_t.abs() <= 2.0 * self.settings.velocity_tolerance
                    && self.model.contacts[j].law.friction > 0.0
            })
            .collect();
        let refreshed: Vec<ContactKinematics>;
        let kin = if ending.is_empty() {
            kin
        } else {
            let q = self.q();
            let v = self.v();
            let frame = self.frame(&q);
            let mut rows = Vec::new();
            for j in 0..old.len() {
                if old[j].closed() {
                    let k = frame.contact(&self.model, j, &q, &v);
                    rows.push((k.j_n, frame.solve(&k.j_n), k.u_n));
                    if ending.contains(&j) || old[j] == ContactMode::Stick {
                        rows.push((k.j_t, frame.solve(&k.j_t), k.u_t));
                    }
                }
            }
            self.project_rows(&rows);
            let (q, v) = (self.q(), self.v());
            refreshed = (0..old.len())
                .map(|j| frame.contact(&self.model, j, &q, &v))
                .collect();
            &refreshed
        };
        let mut new = vec![ContactMode::Open; self.modes.len()];
        let candidates: Vec<usize> = touching
            .iter()
            .copied()
            .filter(|j| kin[*j].u_n <= self.settings.velocity_tolerance)
            .collect();
        if !candidates.is_empty() {
            // The contact problem at acceleration level: with every contact open,
            // the accelerations a_0 = M^-1 Q, and the contact accelerations they
            // give (`base_n`, `base_t`); W = J M^-1 J^T.
            let open = vec![ContactMode::Open; self.modes.len()];
            let free = self.evaluate_with_modes(&self.y, &open);
            let acc: [f64; DOF] = core::array::from_fn(|i| free.ydot[DOF + i]);
            let q = self.q();
            let v = self.v();
            let frame = self.frame(&q);
            let sys = self.contact_system(&frame, &q, &v, &candidates, Some(&acc));
            // Slip states from the slip velocities, with zero below the tolerance.
            let mut slip = [0.0; MAX_CONTACTS];
            for (r, &j) in candidates.iter().enumerate() {
                if kin[j].u_t.abs() > self.settings.velocity_tolerance {
                    slip[r] = kin[j].u_t;
                }
            }
            // The complementarity problem (normal force >= 0, normal acceleration
            // >= 0, one of them zero; a sticking force inside its cone, a slipping
            // one on its edge against the slip, a contact at zero slip slipping
            // only the way it then moves), solved for all candidates together,
            // whatever event brought us here. Its tolerance is a thousandth of the
            // event functions' margin `eps_F` (and never below rounding), so the
            // condition whose event fired is violated by a thousand times the
            // tolerance and cannot be chosen again: a contact whose normal force
            // reached -eps_F opens, a sticking contact whose friction left its
            // cone by eps_F slips.
            let eps_f = self.force_tolerance();
            let scale_a = sys
                .base_n
                .iter()
                .chain(sys.base_t.iter())
                .fold(1.0, |m: f64, a| m.max(a.abs()));
            let mass = self.model.total_mass();
            let tol_f = (1e-3 * eps_f).max(1e-13 * scale_a * mass);
            // (The slips are already zero below the velocity tolerance.)
            let tol = Tolerances {
                velocity: tol_f / mass,
                impulse: tol_f,
                zero_slip: 0.0,
            };
            let zeros = [0.0; MAX_CONTACTS];
            let d = find_direction(
                &sys.problem,
                &sys.base_n,
                &sys.base_t,
                &slip,
                NormalRule::TargetAll(&zeros),
                &tol,
            );
            if !d.consistent || !d.ends_at_one {
                self.painleve(&candidates);
                return;
            }
            // The active set is closed, in its friction states; the rest open. A
            // contact at the boundary (no force and no acceleration) is active
            // when it can be (the enumeration tries the larger sets first): its
            // lift-off is then the event where its force goes below -eps_F.
            for (r, &j) in candidates.iter().enumerate() {
                if d.active[r] {
                    new[j] = ContactMode::from_slip(d.mode[r]);
                }
            }
        }
        // Events for the changes.
        for j in 0..new.len() {
            let (a, b) = (old[j], new[j]);
            if a == b {
                continue;
            }
            let kind = match (a.closed(), b.closed(), b) {
                (false, true, _) => EventKind::Contact,
                (true, false, _) => EventKind::Liftoff,
                (true, true, ContactMode::Stick) => EventKind::Stick,
                (true, true, _) => EventKind::Slip,
                (false, false, _) => continue,
            };
            self.events.push(EventRow {
                t: self.t,
                kind,
                contact: self.model.contacts[j].name.clone(),
                normal_velocity_before: kin[j].u_n,
                normal_velocity_after: kin[j].u_n,
                normal_impulse: 0.0,
                tangential_impulse: 0.0,
                case: None,
                detail: mode_name(b).into(),
            });
        }
        self.modes = new;
        self.fsal = None;
        self.project();
    }

    /// A Painleve configuration: the contact problem has no consistent solution
    /// (or its only way out is unbounded). Reported, and resolved by a tangential
    /// impact: the impulse-space problem of the touching contacts, which under
    /// friction develops a normal impulse even from zero normal velocity until the
    /// slip stops (Genot & Brogliato 1999).
    fn painleve(&mut self, set: &[usize]) {
        for &j in set {
            self.events.push(EventRow {
                t: self.t,
                kind: EventKind::Painleve,
                contact: self.model.contacts[j].name.clone(),
                normal_velocity_before: 0.0,
                normal_velocity_after: 0.0,
                normal_impulse: 0.0,
                tangential_impulse: 0.0,
                case: None,
                detail: "no consistent contact force; tangential impact".into(),
            });
        }
        self.warn(format!(
            "contacts: Painleve configuration at t = {:.9} s, resolved by a tangential impact",
            self.t
        ));
        // Tangential impact (Genot & Brogliato 1999): the impulse-space problem of
        // the touching contacts started at zero normal velocity (a tiny approach,
        // 1e-6 of the slip speed, so that the solver runs its compression). Under
        // the jam the normal impulse grows, with friction at the cone, until the
        // slip stops; plastic (restitution 0): nothing was stored by an approach.
        if self.resolving_painleve {
            for &j in set {
                self.modes[j] = ContactMode::Stick;
            }
            self.project();
            self.fsal = None;
            return;
        }
        let q = self.q();
        let v = self.v();
        let frame = self.frame(&q);
        let sys = self.contact_system(&frame, &q, &v, set, None);
        let mut problem = sys.problem.clone();
        let slip = (0..set.len())
            .map(|r| problem.u_t[r].abs())
            .fold(0.0, f64::max);
        for r in 0..set.len() {
            problem.u_n[r] = problem.u_n[r].min(-1e-6 * slip.max(self.settings.velocity_tolerance));
            problem.contacts[r].restitution = 0.0;
        }
        match solve(&problem) {
            Ok(outcome) => {
                for (r, &j) in set.iter().enumerate() {
                    let c = &outcome.contacts[r];
                    for i in 0..DOF {
                        self.y[DOF + i] += c.normal_impulse * sys.minv_jn[r][i]
                            + c.tangential_impulse * sys.minv_jt[r][i];
                    }
                    self.events.push(EventRow {
                        t: self.t,
                        kind: EventKind::Impact,
                        contact: self.model.contacts[j].name.clone(),
                        normal_velocity_before: sys.problem.u_n[r],
                        normal_velocity_after: c.normal_velocity_after,
                        normal_impulse: c.normal_impulse,
                        tangential_impulse: c.tangential_impulse,
                        case: Some(c.case.number()),
                        detail: "tangential impact".into(),
                    });
                }
                self.impacts += 1;
            }
            Err(e) => {
                // The solver could not resolve it: hold the contacts stuck by the
                // least velocity change (a plastic tangential impulse without the
                // cone), and say so.
                self.warn(format!(
                    "contacts: tangential impact at t = {:.9} s not solved ({e:?}); contacts held",
                    self.t
                ));
                let mut rows: Vec<([f64; DOF], [f64; DOF], f64)> = Vec::new();
                for r in 0..set.len() {
                    rows.push((sys.kin[r].j_n, sys.minv_jn[r], sys.kin[r].u_n.min(0.0)));
                    rows.push((sys.kin[r].j_t, sys.minv_jt[r], sys.kin[r].u_t));
                }
                self.project_rows(&rows);
            }
        }
        self.fsal = None;
        // The modes from the velocities after the tangential impact; a second
        // Painleve configuration at the same instant holds the contacts stuck.
        self.resolving_painleve = true;
        self.settle();
        self.resolving_painleve = false;
    }

    /// Projects the state onto the closed contacts' constraints: velocities
    /// (`u_n = 0`, and `u_t = 0` when sticking) by the mass-weighted least change
    /// `dq' = -M^-1 J^T W^+ (J q')`, and positions (`gap = 0`) likewise.
    fn project(&mut self) {
        let closed: Vec<usize> = (0..self.modes.len())
            .filter(|j| self.modes[*j].closed())
            .collect();
        if closed.is_empty() {
            return;
        }
        let q = self.q();
        let v = self.v();
        let frame = self.frame(&q);
        let mut vel_rows = Vec::new();
        let mut pos_rows = Vec::new();
        for &j in &closed {
            let k = frame.contact(&self.model, j, &q, &v);
            let minv_n = frame.solve(&k.j_n);
            vel_rows.push((k.j_n, minv_n, k.u_n));
            pos_rows.push((k.j_n, minv_n, k.gap));
            if self.modes[j] == ContactMode::Stick {
                vel_rows.push((k.j_t, frame.solve(&k.j_t), k.u_t));
            }
        }
        self.project_rows(&vel_rows);
        // Positions: one Gauss-Newton step on the gaps.
        if let Some(dq) = least_change(&pos_rows) {
            for i in 0..DOF {
                self.y[i] += dq[i];
            }
        }
    }

    /// Applies the least mass-weighted velocity change that zeroes the rows.
    fn project_rows(&mut self, rows: &[([f64; DOF], [f64; DOF], f64)]) {
        if let Some(dv) = least_change(rows) {
            for i in 0..DOF {
                self.y[DOF + i] += dv[i];
            }
        }
    }

    /// The trace row of state `y` at `t` with duties `duty` and the contact
    /// forces `forces` at that state.
    pub fn row(t: f64, y: &[f64; NY], duty: [f64; 2], forces: &ContactForces) -> TraceRow {
        TraceRow {
            t,
            x: y[0],
            y: y[1],
            angle: y[2],
            vx: y[DOF],
            vy: y[DOF + 1],
            omega: y[DOF + 2],
            phi1: y[3],
            phi2: y[4],
            omega1: y[DOF + 3],
            omega2: y[DOF + 4],
            i1: y[2 * DOF],
            i2: y[2 * DOF + 1],
            duty1: duty[0],
            duty2: duty[1],
            normal_force: forces.normal,
            tangential_force: forces.tangential,
        }
    }

    /// The generalized force that the holds exert at the current state: on
    /// `(x, y, theta)` the force (N, N) and moment (N m) holding the platform, on
    /// `(phi_1, phi_2)` the torques holding the rotors' speeds; zero where nothing
    /// is held. `Q_hold = M q'' - Q` with the true mass matrix and the accelerations
    /// the holds allow (zero on held coordinates); contact forces included in `Q`.
    pub fn holding_force(&self) -> [f64; DOF] {
        let q = self.q();
        let v = self.v();
        let e = self.evaluate(&self.y);
        let acc: [f64; DOF] = core::array::from_fn(|i| e.ydot[DOF + i]);
        let frame = Frame::new(&self.model, &q);
        let mut tau = [0.0; 2];
        for k in 0..2 {
            let s = self.model.rotors[k].sense;
            tau[k] = s * self.motors[k].shaft_torque(self.y[2 * DOF + k], s * v[3 + k]);
        }
        let mut f = frame.forces(&self.model, &v, tau);
        // Contact forces: J^T lambda.
        for j in 0..self.modes.len() {
            if self.modes[j].closed() {
                let k = frame.contact(&self.model, j, &q, &v);
                for i in 0..DOF {
                    f[i] += k.j_n[i] * e.lambda_n[j] + k.j_t[i] * e.lambda_t[j];
                }
            }
        }
        let mask = self.holds.mask();
        core::array::from_fn(|i| {
            if !mask[i] {
                return 0.0;
            }
            (0..DOF).map(|j| frame.mass[i][j] * acc[j]).sum::<f64>() - f[i]
        })
    }

    /// Contact forces of the closed contacts at the current state: (normal,
    /// tangential) per contact, N; zero for open ones.
    pub fn contact_forces(&self) -> Vec<[f64; 2]> {
        let f = self.forces_at(&self.y);
        (0..self.modes.len())
            .map(|j| [f.normal[j], f.tangential[j]])
            .collect()
    }

    /// The contact forces at state `y` in the current modes.
    pub fn forces_at(&self, y: &[f64; NY]) -> ContactForces {
        if !self.modes.iter().any(|m| m.closed()) {
            return ContactForces::default();
        }
        let e = self.evaluate(y);
        ContactForces {
            normal: e.lambda_n,
            tangential: e.lambda_t,
        }
    }

    /// Total mechanical energy (kinetic plus gravity's potential), J.
    pub fn mechanical_energy(&self) -> f64 {
        let q = self.q();
        let frame = Frame::new(&self.model, &q);
        frame.kinetic_energy(&self.v()) + frame.potential_energy(&self.model, &q)
    }
}

/// The contact forces of persistent contact at a state, in the modes of that
/// moment: per contact in file order, N (0 for open contacts; impacts are
/// impulses, reported as events).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ContactForces {
    /// Normal force `lambda_n` of each contact, N (along the fundament's normal).
    pub normal: [f64; MAX_CONTACTS],
    /// Tangential force `lambda_t` of each contact, N (along `t = (-n_y, n_x)`).
    pub tangential: [f64; MAX_CONTACTS],
}

/// An accepted step's dense output, as the plant reports states: the 4th-order
/// interpolant with the winding currents held to their drivers (within the
/// current limit, zero on open windings; the interpolant of a step along the
/// limit can overshoot it by the step's error).
pub struct Dense<'a> {
    /// Start of the step, s.
    pub t0: f64,
    step: &'a Step<NY>,
    plant: &'a Plant,
}

impl Dense<'_> {
    /// The state at `t` in `[t0, t1]`.
    pub fn at(&self, t: f64) -> [f64; NY] {
        let mut y = if t >= self.step.t1() {
            self.step.y1
        } else {
            self.step.at(t)
        };
        for k in 0..2 {
            y[2 * DOF + k] =
                self.plant.motors[k].project_current(self.plant.winding[k], y[2 * DOF + k]);
        }
        y
    }

    /// The contact forces at state `y` of this step, in the step's modes.
    pub fn forces(&self, y: &[f64; NY]) -> ContactForces {
        self.plant.forces_at(y)
    }

    /// End of the step, s.
    pub fn t1(&self) -> f64 {
        self.step.t1()
    }
}

/// A state at an event, as [`Plant::advance_to`] reports it.
pub struct At<'a> {
    /// Time, s.
    pub t: f64,
    /// The state.
    pub y: &'a [f64; NY],
    plant: &'a Plant,
}

impl At<'_> {
    /// The contact forces at this state, in the modes of that moment (before the
    /// event: the old modes; after it: the new ones).
    pub fn forces(&self) -> ContactForces {
        self.plant.forces_at(self.y)
    }
}

/// What [`Plant::advance_to`] hands the recorder.
pub enum Output<'a> {
    /// An accepted step, valid up to this time (inclusive): sample its dense output.
    Dense(Dense<'a>, f64),
    /// The state just before an event.
    Before(At<'a>),
    /// The state just after an event.
    After(At<'a>),
}

/// A contact problem assembled for a set of contacts.
struct ContactSystem {
    problem: ImpactProblem<f64, MAX_CONTACTS>,
    minv_jn: [[f64; DOF]; MAX_CONTACTS],
    minv_jt: [[f64; DOF]; MAX_CONTACTS],
    kin: [ContactKinematics; MAX_CONTACTS],
    base_n: [f64; MAX_CONTACTS],
    base_t: [f64; MAX_CONTACTS],
}

/// The least change `dx = -M^-1 J^T W^+ r` that zeroes `J x + r` for rows
/// `(J, M^-1 J^T, r)`, with `W = J M^-1 J^T` (weighted minimum norm where singular).
fn least_change(rows: &[([f64; DOF], [f64; DOF], f64)]) -> Option<[f64; DOF]> {
    let n = rows.len().min(DIM);
    if n == 0 {
        return None;
    }
    let mut w = [[0.0; DIM]; DIM];
    let mut b: Vector<f64> = [0.0; DIM];
    for r in 0..n {
        for c in 0..n {
            w[r][c] = (0..DOF).map(|i| rows[r].0[i] * rows[c].1[i]).sum();
        }
        b[r] = -rows[r].2;
    }
    let (x, _) = solve_weighted(&w, &b, &[1.0; DIM], n)?;
    let mut dx = [0.0; DOF];
    for r in 0..n {
        for i in 0..DOF {
            dx[i] += x[r] * rows[r].1[i];
        }
    }
    Some(dx)
}

/// The name of a mode in the events CSV's detail.
fn mode_name(m: ContactMode) -> &'static str {
    match m {
        ContactMode::Open => "open",
        ContactMode::Stick => "stick",
        ContactMode::SlipPositive => "slip+",
        ContactMode::SlipNegative => "slip-",
    }
}
