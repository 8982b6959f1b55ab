//! The hybrid simulation of the vibro driver: smooth motion between events, and
//! events located to high accuracy.
//!
//! Between events every contact is in a fixed **mode**: open, or closed and
//! sticking, or closed and slipping one way. In a mode the motion is smooth: closed
//! contacts are held at zero normal acceleration (and sticking ones at zero
//! tangential acceleration) by contact forces from a linear system, with friction
//! `-mu s lambda_n` on slipping ones; where sticking feet leave the forces
//! undetermined, they are shared inside every cone (`simulator/forces.rs`). The state
//! `(q, q', i)` is integrated by Dormand-Prince 5(4) ([`super::integrator`]).
//!
//! **Contacts never pull**: a closed contact's normal force stays above `-eps_F`
//! ([`Plant::force_tolerance`], 1e-6 of the weight). Every condition has its own
//! event function (`simulator/events.rs`), every mode change solves the complementarity
//! problem of all touching contacts together (`simulator/modes.rs`), and that problem's
//! tolerance is a thousandth of `eps_F`, so the condition whose event fired cannot
//! be chosen again.
//!
//! Stages of [`Plant::advance_to`], per accepted step:
//! 1. evaluate the **event functions** at the step's end, one per condition: an
//!    open contact's gap; a closed contact's normal force (lift-off); a sticking
//!    contact's distance to its cone; a slipping contact's slip velocity; a
//!    driver's current limit;
//! 2. where one changed sign, or dipped below zero inside the step, or an open
//!    contact grazed or flew inside it, locate the earliest event on the dense
//!    output (Illinois false position, to [`Settings::event_time_tolerance`]), cut
//!    the step there and **handle the event** (`simulator/modes.rs`): impacts (the `shared`
//!    solver, all contacts within [`Settings::together_gap`] of their faces in
//!    one impact, the whole mechanism's Delassus matrix with the rotors free,
//!    `simulator/impacts.rs`), then the new modes from the complementarity problem at
//!    acceleration level (contact, lift-off, stick, slip); a problem with no
//!    consistent solution is a **Painleve** configuration, resolved by a
//!    tangential impact;
//! 3. otherwise accept the step, project the closed contacts back onto their
//!    constraints once the integrator's drift off them is measurable (it stays
//!    far below its tolerance; `Plant::drifted`) and record output rows.
//!
//! **Zeno**: an impact whose rebound is slower than [`Settings::zeno_velocity`] is
//! the tail of an accumulation of impacts. It is closed plastically at once and the
//! accumulation point is reported: the remaining bounces of a contact with
//! effective restitution `e = v+/v-` under a normal acceleration `a` last
//! `sum_k 2 v+ e^k / a = 2 v+ / (a (1 - e))` (a geometric series). The threshold is
//! far below every velocity that matters (1e-6 m/s by default): halving or doubling
//! it moves the rest point by less than the event tolerance.
//!
//! **Progress**: every integrator attempt and every event handled counts against
//! the budget of a simulated millisecond ([`super::progress`]); past it, or where
//! a rejected step would go below 1e-14 s, or once the caller's stop flag is set
//! ([`Plant::stop_when`], checked before every attempt), [`Plant::advance_to`]
//! ends at the state it reached and says why ([`Stop`]).

mod events;
mod forces;
mod impacts;
mod modes;

use std::sync::atomic::{AtomicUsize, Ordering};

use events::{Crossing, EventValues, StageForces};
use forces::CachedEvaluation;

use super::bridge::{Bridge, BridgeCommand};
use super::dynamics::{Frame, Pose, Vector};
use super::integrator::{attempt, Attempt, Step, Tolerance};
use super::model::{Face, Mount, PlantModel};
use super::motor::{DcMotor, Winding};
use super::progress::{ContactState, Progress, Situation, MIN_STEP};
use crate::event::{EventKind, EventRow};
use crate::machine::bodies::MAX_DOF;

/// Events handled at one instant without progress before the step is taken anyway.
const MAX_STALLED_EVENTS: u32 = 16;

/// The drift off the closed contacts' constraints, as a fraction of the
/// integrator's absolute tolerance, past which an accepted step is projected
/// back onto them ([`Plant::drifted`]).
const DRIFT_FRACTION: f64 = 1e-3;

use super::contact::{ContactForces, ContactMode};
use super::model::NY;
use super::progress::Stop;

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
    /// The progress guard's budget: integrator steps and events within one
    /// millisecond of simulated time ([`super::progress`]; the machine file's
    /// `[simulation] progress_budget`).
    pub progress_budget: u64,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            rtol: crate::machine::DEFAULT_RTOL,
            max_step: 1e-3,
            together_gap: 1e-7,
            zeno_velocity: 1e-6,
            event_time_tolerance: 1e-12,
            velocity_tolerance: 1e-7,
            force_tolerance: 1e-6,
            progress_budget: crate::machine::DEFAULT_PROGRESS_BUDGET,
        }
    }
}

/// Coordinates held: for tests against closed forms, and the rotors-only bench
/// (every body held, the rotors free). A held coordinate has zero acceleration: a
/// held body stays still at its start pose ([`Plant::new`] zeroes its
/// velocities), a held rotor keeps its speed; the contacts between held bodies
/// and the fundament move nothing.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Holds {
    /// Hold the platform (x, y, theta).
    pub platform: bool,
    /// Hold every body: the platform and the bodies hinged to it or to the
    /// fundament (each one's angle, and a free root's centre of mass).
    pub bodies: bool,
    /// Hold the rotors at their current speed relative to their bodies.
    pub rotors: bool,
    /// Rotor k jammed: held at rest relative to its body (fault injection).
    pub jammed: [bool; 2],
}

impl Holds {
    /// The held coordinates of `model`: the held bodies' ([`Holds::body_mask`]),
    /// the rotors'.
    fn mask(self, model: &PlantModel) -> [bool; MAX_DOF] {
        let mut mask = self.body_mask(model);
        for (k, rotor) in model.rotors.iter().enumerate() {
            mask[rotor.phi] = self.rotors || self.jammed[k];
        }
        mask
    }

    /// The held bodies' coordinates of `model`: a body's angle, and its centre of
    /// mass when it is a free root.
    fn body_mask(self, model: &PlantModel) -> [bool; MAX_DOF] {
        let mut mask = [false; MAX_DOF];
        let held_bodies = if self.bodies {
            model.bodies.len()
        } else {
            usize::from(self.platform)
        };
        for body in &model.bodies[..held_bodies] {
            mask[body.angle] = true;
            if let Mount::Free { x } = body.mount {
                mask[x] = true;
                mask[x + 1] = true;
            }
        }
        mask
    }
}

/// The simulated machine: model, state, modes, inputs and what happened.
pub struct Plant {
    /// The constant model.
    pub model: PlantModel,
    /// Numerical settings.
    pub settings: Settings,
    /// Coordinates held still ([`Plant::set_jam`] changes them).
    holds: Holds,
    /// The coordinates `holds` holds ([`Holds::mask`]), kept with them: the mass
    /// matrix's factor and the forces of every evaluation need them.
    held: [bool; MAX_DOF],
    /// Time, s.
    pub t: f64,
    /// State `(q, q', i)`.
    pub y: [f64; NY],
    /// The contacts' modes.
    pub modes: Vec<ContactMode>,
    /// What the H-bridges put on the windings now.
    pub winding: [Winding; 2],
    /// The H-bridges, once a driver commands them ([`Plant::set_bridges`]); `None`
    /// while the windings are set directly ([`Plant::set_winding`]).
    bridges: Option<[Bridge; 2]>,
    /// Sign of each coasting winding's current (0: none flowing): its event is the
    /// current reaching zero.
    coast_sign: [f64; 2],
    /// Events so far.
    pub events: Vec<EventRow>,
    /// Impact instants so far.
    pub impacts: usize,
    /// Warnings (deduplicated).
    pub warnings: Vec<String>,
    /// Accepted integration steps so far.
    pub steps: u64,
    /// Integrator attempts so far, accepted or rejected (six evaluations each).
    pub attempts: u64,
    /// Evaluations of the equations of motion so far (the integrator's stages,
    /// and those the events and mode decisions make).
    evaluations: std::cell::Cell<u64>,
    motors: Vec<DcMotor>,
    h: f64,
    fsal: Option<[f64; NY]>,
    /// Inside the resolution of a Painleve configuration.
    resolving_painleve: bool,
    /// Event functions of the state left by the last `advance_to`.
    ev_cache: Option<([f64; NY], events::EventValues)>,
    /// The last evaluation in the current modes, with its state.
    last_evaluation: std::cell::RefCell<Option<CachedEvaluation>>,
    /// The windings of the last evaluation.
    last_winding: std::cell::Cell<[Winding; 2]>,
    /// The mass matrix and contact problem every evaluation fills in place.
    scratch: std::cell::RefCell<Box<forces::Scratch>>,
    /// `(integral i dt, duration)` of the winding currents over the current (or
    /// last) `advance_to`, A s and s.
    current_integral: ([f64; 2], f64),
    /// The work of the current window against the budget ([`super::progress`]).
    progress: Progress,
    /// The last contact event handled, and its time, s (the events themselves go
    /// to whoever takes [`Plant::events`]).
    last_event: Option<(EventKind, f64)>,
    /// When set (non-zero), [`Plant::advance_to`] stops before its next attempt.
    stop_flag: Option<&'static AtomicUsize>,
    /// Why the plant stopped, once it has.
    stopped: Option<Stop>,
}

impl Plant {
    /// A plant at `t = 0` in state `y` (see [`NY`]), windings open, modes decided
    /// from the state; a held body is held still, its velocities in `y` taken as
    /// zero, and a contact whose body and face are held (or the fundament) left out
    /// of the model: it moves nothing.
    pub fn new(mut model: PlantModel, mut y: [f64; NY], settings: Settings, holds: Holds) -> Self {
        let still = holds.body_mask(&model);
        for (i, held) in still.into_iter().enumerate() {
            if held {
                y[model.dof + i] = 0.0;
            }
        }
        let bodies = &model.bodies;
        let held = |b: usize| still[bodies[b].angle];
        model.contacts.retain(|c| match c.face {
            Face::Fundament => !held(c.body),
            Face::Body { body, .. } => !(held(c.body) && held(body)),
        });
        let motors = model
            .rotors
            .iter()
            .map(|r| DcMotor::new(r.motor.clone()))
            .collect();
        let n = model.contacts.len();
        let held = holds.mask(&model);
        let scratch = std::cell::RefCell::new(Box::new(forces::Scratch::new(&model)));
        let mut plant = Plant {
            model,
            settings,
            holds,
            held,
            t: 0.0,
            y,
            modes: vec![ContactMode::Open; n],
            winding: [Winding::Open, Winding::Open],
            bridges: None,
            coast_sign: [0.0; 2],
            events: Vec::new(),
            impacts: 0,
            warnings: Vec::new(),
            steps: 0,
            attempts: 0,
            evaluations: std::cell::Cell::new(0),
            motors,
            h: 1e-5,
            fsal: None,
            resolving_painleve: false,
            ev_cache: None,
            last_evaluation: std::cell::RefCell::new(None),
            last_winding: std::cell::Cell::new([Winding::Open, Winding::Open]),
            scratch,
            current_integral: ([0.0; 2], 0.0),
            progress: Progress::new(settings.progress_budget),
            last_event: None,
            stop_flag: None,
            stopped: None,
        };
        plant.settle();
        plant
    }

    /// Sets what is on the windings directly, held until changed (tests; a driver
    /// commands the bridges with [`Plant::set_bridges`]).
    pub fn set_winding(&mut self, winding: [Winding; 2]) {
        self.bridges = None;
        self.use_winding(winding);
    }

    /// Commands the H-bridges as wired ([`super::bridge`]): a duty takes effect at
    /// the next PWM period start, off at once.
    pub fn set_bridges(&mut self, commands: [BridgeCommand; 2]) {
        // A switch due now (an integration that ended exactly on it) first.
        if let Some(ts) = self.next_switch().filter(|ts| *ts <= self.t) {
            self.switch_bridges(ts);
        }
        let (config, supply) = (self.model.bridge, self.model.supply_voltage);
        let t = self.t;
        let bridges = self
            .bridges
            .get_or_insert_with(|| [Bridge::new(config, supply), Bridge::new(config, supply)]);
        for (b, c) in bridges.iter_mut().zip(commands) {
            b.command(c, t);
        }
        let winding = [bridges[0].winding(), bridges[1].winding()];
        self.use_winding(winding);
    }

    /// The bridges' supply voltage changes (a sag injected by a test): the
    /// windings see it at once.
    pub fn set_supply(&mut self, supply: f64) {
        if let Some(bridges) = self.bridges.as_mut() {
            bridges[0].set_supply(supply);
            bridges[1].set_supply(supply);
            let winding = [bridges[0].winding(), bridges[1].winding()];
            self.use_winding(winding);
        }
        self.model.supply_voltage = supply;
    }

    /// Puts `winding` on the windings, restarting the integrator where it changes;
    /// whether it changed.
    fn use_winding(&mut self, mut winding: [Winding; 2]) -> bool {
        // A rotor the machine does not have: nothing is wired to its bridge.
        for w in winding.iter_mut().skip(self.model.rotors.len()) {
            *w = Winding::Open;
        }
        let changed = winding != self.winding;
        if changed {
            for k in 0..self.model.rotors.len() {
                if matches!(winding[k], Winding::Coast(_))
                    && !matches!(self.winding[k], Winding::Coast(_))
                {
                    let i = self.y[self.model.current(k)];
                    self.coast_sign[k] = i.signum() * f64::from(i != 0.0);
                }
            }
            self.winding = winding;
            self.fsal = None;
            self.ev_cache = None;
            self.clamp_currents();
        }
        changed
    }

    /// The next time a bridge switches its winding, s (PWM edges, a duty taking
    /// effect), if any.
    fn next_switch(&self) -> Option<f64> {
        let b = self.bridges.as_ref()?;
        match (b[0].next_switch(), b[1].next_switch()) {
            (Some(a), Some(c)) => Some(a.min(c)),
            (a, c) => a.or(c),
        }
    }

    /// At time `t_switch`: every bridge switching then moves on, and the windings
    /// follow; whether they changed.
    fn switch_bridges(&mut self, t_switch: f64) -> bool {
        let Some(bridges) = self.bridges.as_mut() else {
            return false;
        };
        for b in bridges.iter_mut() {
            // Every bridge whose switch falls at this instant (to rounding).
            while b
                .next_switch()
                .is_some_and(|t| t <= t_switch + 1e-12 * t_switch.max(1.0))
            {
                b.switch();
            }
        }
        let winding = [bridges[0].winding(), bridges[1].winding()];
        self.use_winding(winding)
    }

    /// Jams rotor `k` (or frees it): a jammed rotor stops at once relative to its
    /// body (the bearing seizes; the impulse of the stop on the body is
    /// not modelled) and stays at rest; its motor then stalls against the jam.
    pub fn set_jam(&mut self, k: usize, jammed: bool) {
        if self.holds.jammed[k] != jammed {
            self.holds.jammed[k] = jammed;
            self.held = self.holds.mask(&self.model);
            if jammed {
                self.y[self.model.dof + self.model.rotors[k].phi] = 0.0;
            }
            self.fsal = None;
            self.ev_cache = None;
        }
    }

    /// Generalized coordinates `q` (the first [`PlantModel::dof`]; the rest 0).
    pub fn q(&self) -> Vector {
        self.model.q(&self.y)
    }

    /// Generalized velocities `q'`.
    pub fn v(&self) -> Vector {
        self.model.v(&self.y)
    }

    /// The platform's centre of mass (x, y, m), angle (rad) and their rates (m/s,
    /// rad/s), whatever mount the machine gives it.
    pub fn platform_motion(&self) -> [f64; 6] {
        self.model.body_motion(0, &self.y)
    }

    /// Rotor `k`'s eccentric angle in its body's frame, rad, and its rate, rad/s:
    /// what its encoder reads (`phi_k`, wherever the machine's coordinates put it).
    pub fn rotor_angle(&self, k: usize) -> (f64, f64) {
        let phi = self.model.rotors[k].phi;
        (self.y[phi], self.y[self.model.dof + phi])
    }

    /// Winding currents, A (0 for a rotor the machine does not have).
    pub fn currents(&self) -> [f64; 2] {
        self.model.currents(&self.y)
    }

    /// The winding currents' means over the last [`Plant::advance_to`], A (the
    /// instantaneous currents before the first): what the firmware's current
    /// sensing gives a control tick, its ADC buffer averaged over the tick
    /// (`shared::controller::Inputs::current`).
    pub fn mean_currents(&self) -> [f64; 2] {
        let (integral, span) = self.current_integral;
        if span > 0.0 {
            integral.map(|x| x / span)
        } else {
            self.currents()
        }
    }

    /// Adds `integral i dt` over `[step.t0, t_end]` of `step`'s dense output
    /// (Simpson's rule on the 4th-order interpolant: its error is far below the
    /// integrator's tolerance at these step sizes).
    fn integrate_currents(&mut self, step: &Step<NY>, t_end: f64) {
        let h = t_end - step.t0;
        if h <= 0.0 {
            return;
        }
        let mid = step.at(step.t0 + 0.5 * h);
        let end = if t_end >= step.t1() {
            step.y1
        } else {
            step.at(t_end)
        };
        let (integral, span) = &mut self.current_integral;
        for k in 0..self.model.rotors.len() {
            let c = self.model.current(k);
            integral[k] += h / 6.0 * (step.y0[c] + 4.0 * mid[c] + end[c]);
        }
        *span += h;
    }

    /// The configuration terms at `q` with the holds applied.
    fn frame(&self, q: &Vector) -> Frame {
        Frame::locked(&self.model, q, &self.held)
    }

    /// Adds a warning once.
    fn warn(&mut self, w: String) {
        if !self.warnings.contains(&w) {
            self.warnings.push(w);
        }
    }

    /// From now on, [`Plant::advance_to`] stops before its next integrator
    /// attempt once `flag` is non-zero (a signal's flag: within one attempt, even
    /// where a control tick takes minutes).
    pub fn stop_when(&mut self, flag: &'static AtomicUsize) {
        self.stop_flag = Some(flag);
    }

    /// Integrates until `t_target`, handling every event on the way; `record` is
    /// called with the states to output (see [`Output`]). Ends early, at a
    /// consistent state, where the run stops advancing (the progress guard), the
    /// step size underflows or the stop flag is set ([`Stop`]); every later call
    /// ends the same way.
    pub fn advance_to(
        &mut self,
        t_target: f64,
        record: &mut dyn FnMut(Output<'_>),
    ) -> Result<(), Stop> {
        if let Some(stop) = &self.stopped {
            return Err(stop.clone());
        }
        let tol = self.tolerance();
        // The event functions at the start: kept from the last call while the state
        // and the windings are unchanged (a control tick does not move the state).
        let mut ev0 = match self.ev_cache.take() {
            Some((y, v)) if y == self.y => v,
            _ => self.event_values(&self.y),
        };
        let mut stalled = 0u32;
        self.current_integral = ([0.0; 2], 0.0);
        while self.t < t_target {
            if self
                .stop_flag
                .is_some_and(|f| f.load(Ordering::Relaxed) != 0)
            {
                return self.stop(Stop::Interrupted { t: self.t });
            }
            self.progress.at(self.t);
            // A bridge switching now (a PWM edge, a duty taking effect).
            if let Some(ts) = self.next_switch().filter(|ts| *ts <= self.t) {
                if self.switch_bridges(ts) {
                    ev0 = self.event_values(&self.y);
                }
            }
            let f0 = self.start_derivative();
            // Steps end at the target and at every switch of a bridge.
            let t_switch = self.next_switch().filter(|ts| *ts < t_target);
            let t_stop = t_switch.unwrap_or(t_target);
            let remaining = t_stop - self.t;
            let h = self.h.min(self.settings.max_step).min(remaining);
            let (outcome, stages) = self.attempt_step(&f0, h, &tol);
            self.attempts += 1;
            self.charge()?;
            match outcome {
                Attempt::Rejected(next) => self.reject(next)?,
                Attempt::Accepted(step, next) => {
                    self.steps += 1;
                    // Keep the suggested size unless the step was cut by the target
                    // or a switch.
                    if h < remaining || next < self.h {
                        self.h = next;
                    }
                    let at_switch = h == remaining && t_switch.is_some();
                    let ev1 = self.event_values(&step.y1);
                    match self.first_crossing(&step, &ev0, &ev1, &stages) {
                        Some(c) if c.current_only && c.t > step.t0 => {
                            stalled = 0;
                            ev0 = self.cut_at_winding_event(&step, c, record)?;
                        }
                        Some(c) if c.t > step.t0 || stalled < MAX_STALLED_EVENTS => {
                            stalled = if c.t > step.t0 { 0 } else { stalled + 1 };
                            ev0 = self.cut_at_event(&step, c, record)?;
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
                            let switch = at_switch.then_some(t_stop);
                            ev0 = self.take_whole_step(&step, ev1, switch, record);
                        }
                    }
                }
            }
        }
        self.ev_cache = Some((self.y, ev0));
        Ok(())
    }

    /// The derivative at the current state: the last accepted step's at its end
    /// (first same as last) while the state has not moved since, else evaluated
    /// and kept.
    fn start_derivative(&mut self) -> [f64; NY] {
        match self.fsal {
            Some(f) => f,
            None => {
                let f = self.with_evaluation(&self.y, |e| e.ydot);
                self.fsal = Some(f);
                f
            }
        }
    }

    /// One integrator attempt of size `h`, s, from the current state with its
    /// derivative `f0`, and the contact forces at its interior stages (for the dip
    /// test of [`Plant::first_crossing`]).
    fn attempt_step(
        &self,
        f0: &[f64; NY],
        h: f64,
        tol: &Tolerance<NY>,
    ) -> (Attempt<NY>, StageForces) {
        let (t, y) = (self.t, self.y);
        // The contact forces at the interior stages, for the dip test.
        let mut stages = StageForces::default();
        let outcome = {
            let mut rhs = |_t: f64, yy: &[f64; NY]| {
                self.with_evaluation(yy, |e| {
                    stages.record(e, self.modes.len());
                    e.ydot
                })
            };
            attempt(&mut rhs, t, &y, f0, h, tol)
        };
        (outcome, stages)
    }

    /// A rejected attempt: the next try with the smaller size `next`, s; below
    /// [`MIN_STEP`] the run stops ([`Stop::StepUnderflow`]).
    fn reject(&mut self, next: f64) -> Result<(), Stop> {
        self.h = next;
        if self.h < MIN_STEP {
            let stop = Stop::StepUnderflow {
                at: self.situation(),
                h: self.h,
            };
            return self.stop(stop);
        }
        Ok(())
    }

    /// Takes `step` up to a winding's event `c`: the current clamped (held at its
    /// limit, or zero behind the diodes), nothing else; no contact changes, so no
    /// impact check and no rows. The event functions at the new state.
    fn cut_at_winding_event(
        &mut self,
        step: &Step<NY>,
        c: Crossing,
        record: &mut dyn FnMut(Output<'_>),
    ) -> Result<EventValues, Stop> {
        self.integrate_currents(step, c.t);
        record(Output::Dense(self.dense(step), c.t));
        self.t = c.t;
        self.y = c.y;
        self.fsal = None;
        self.clamp_currents();
        let ev0 = self.event_values(&self.y);
        self.charge()?;
        Ok(ev0)
    }

    /// Takes `step` up to the event `c` and handles it ([`Plant::settle`]:
    /// impacts, then the new modes), recording the states just before and just
    /// after. The event functions at the new state.
    fn cut_at_event(
        &mut self,
        step: &Step<NY>,
        c: Crossing,
        record: &mut dyn FnMut(Output<'_>),
    ) -> Result<EventValues, Stop> {
        let Crossing { t: te, y: ye, .. } = c;
        self.integrate_currents(step, te);
        record(Output::Dense(self.dense(step), te));
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
        let ev0 = self.event_values(&self.y);
        self.charge()?;
        Ok(ev0)
    }

    /// Takes the whole of `step` (no event in it), its end projected back onto
    /// the closed contacts' constraints where it drifted, and the bridges switched
    /// at `switch`, s, if the step ends at a switch. The event functions at the
    /// new state: `ev1`, the step end's, unless the projection or the windings
    /// moved it since.
    fn take_whole_step(
        &mut self,
        step: &Step<NY>,
        ev1: EventValues,
        switch: Option<f64>,
        record: &mut dyn FnMut(Output<'_>),
    ) -> EventValues {
        self.integrate_currents(step, step.t1());
        record(Output::Dense(self.dense(step), step.t1()));
        self.t = step.t1();
        self.y = step.y1;
        self.clamp_currents();
        // The projection moves the state back onto the closed contacts'
        // constraints, and only once the integrator's drift off them is
        // measurable ([`Plant::drifted`]). Without it the derivative at the
        // step's end is the next step's first (FSAL), which saves an evaluation a
        // step; with it, the state is no longer the one `step.f1` and `ev1` were
        // evaluated at, so both are evaluated again at the projected state.
        let projected = self.drifted();
        if projected {
            self.project();
            self.fsal = None;
        } else {
            self.fsal = Some(step.f1);
        }
        // Exactly at the switch, whatever the rounding of t.
        let switched = match switch {
            Some(t_stop) => {
                self.t = t_stop;
                self.switch_bridges(t_stop)
            }
            None => false,
        };
        if projected || switched {
            self.event_values(&self.y)
        } else {
            ev1
        }
    }

    /// Whether the state has drifted off a closed contact's constraints by
    /// [`DRIFT_FRACTION`] of the integrator's absolute tolerance: a gap beyond it
    /// times the positions' (`1e-3 rtol` m), a normal velocity, or a sticking
    /// contact's slip, beyond it times the velocities' (`rtol` m/s). Below, the
    /// projection ([`Plant::project`]) would move the state by less than that,
    /// and is not worth its mass matrix and solves (over 1 s of the reference
    /// machine's closed loop the largest drift of an accepted step was 7e-7 of
    /// the tolerance, the median 3e-11: rounding).
    fn drifted(&self) -> bool {
        if !self.modes.iter().any(|m| m.closed()) {
            return false;
        }
        let pose = Pose::new(&self.model, &self.q());
        let v = self.v();
        let velocity = DRIFT_FRACTION * self.settings.rtol;
        let gap = 1e-3 * velocity;
        self.modes.iter().enumerate().any(|(j, mode)| {
            if !mode.closed() {
                return false;
            }
            let k = pose.contact(&self.model, j, &v);
            k.gap.abs() > gap
                || k.u_n.abs() > velocity
                || (*mode == ContactMode::Stick && k.u_t.abs() > velocity)
        })
    }

    /// Evaluations of the equations of motion so far ([`Plant::attempts`] takes
    /// six each; the rest are the events' and the mode decisions').
    pub fn evaluations(&self) -> u64 {
        self.evaluations.get()
    }

    /// Ends the run at the current state with `stop`, for good.
    fn stop(&mut self, stop: Stop) -> Result<(), Stop> {
        self.stopped = Some(stop.clone());
        Err(stop)
    }

    /// One unit of work against the progress guard's budget; past it, the
    /// guard's stop ([`super::progress`]).
    fn charge(&mut self) -> Result<(), Stop> {
        if self.progress.spend() {
            Ok(())
        } else {
            self.no_progress()
        }
    }

    /// The progress guard's stop ([`super::progress`]).
    fn no_progress(&mut self) -> Result<(), Stop> {
        let stop = Stop::NoProgress {
            at: self.situation(),
            budget: self.progress.budget,
        };
        self.stop(stop)
    }

    /// The time, every contact's mode and gap, and the last event.
    fn situation(&self) -> Situation {
        let q = self.q();
        let pose = Pose::new(&self.model, &q);
        let contacts = self
            .model
            .contacts
            .iter()
            .zip(&self.modes)
            .enumerate()
            .map(|(j, (c, mode))| ContactState {
                name: c.name.clone(),
                mode: *mode,
                gap: pose.gap(&self.model, j),
            })
            .collect();
        Situation {
            t: self.t,
            contacts,
            last_event: self.last_event,
        }
    }

    /// The integrator's tolerances: relative `rtol`; absolute `1e-3 rtol` m on the
    /// position of every free body (the travel per impact is a small difference
    /// of large motions), `rtol` rad, rad/s, m/s elsewhere, and `rtol` times the current
    /// limit on the winding currents (their natural scale; tighter only adds steps
    /// to follow the 0.25 ms electrical transient: about 10 % more accepted steps
    /// for the reference machine with `rtol` amperes).
    fn tolerance(&self) -> Tolerance<NY> {
        let r = self.settings.rtol;
        let mut atol = [r; NY];
        for body in &self.model.bodies {
            if let Mount::Free { x } = body.mount {
                atol[x] = 1e-3 * r;
                atol[x + 1] = 1e-3 * r;
            }
        }
        for (k, rotor) in self.model.rotors.iter().enumerate() {
            atol[self.model.current(k)] = r * rotor.motor.current_limit;
        }
        Tolerance {
            rtol: r,
            atol,
            len: self.model.ny(),
        }
    }

    /// Clamps the winding currents to the drivers' limits; a coasting current
    /// that has reached zero (its event) stops there.
    fn clamp_currents(&mut self) {
        for k in 0..self.model.rotors.len() {
            let c = self.model.current(k);
            let i = self.y[c];
            if let Winding::Coast(_) = self.winding[k] {
                if self.coast_sign[k] == 0.0 {
                    // A current that starts flowing (the back-EMF above the supply).
                    self.coast_sign[k] = i.signum() * f64::from(i != 0.0);
                } else if self.coast_sign[k] * i <= 0.0 {
                    // It died: the diodes block.
                    self.y[c] = 0.0;
                    self.coast_sign[k] = 0.0;
                }
            }
            self.y[c] = self.motors[k].project_current(self.winding[k], self.y[c]);
        }
    }

    /// The dense output of `step` as the plant reports it.
    fn dense<'a>(&'a self, step: &'a Step<NY>) -> Dense<'a> {
        Dense {
            t0: step.t0,
            step,
            plant: self,
        }
    }

    /// The generalized force that the holds exert at the current state: on the
    /// platform's coordinates the force (N) and moment (N m) holding it, on each
    /// `phi_k` the torque holding the rotor's speed; zero where nothing is held.
    /// `Q_hold = M q'' - Q` with the true mass matrix and the accelerations the
    /// holds allow (zero on held coordinates); contact forces included in `Q`.
    pub fn holding_force(&self) -> Vector {
        let n = self.model.dof;
        let q = self.q();
        let v = self.v();
        let e = self.evaluate(&self.y);
        let mut acc = [0.0; MAX_DOF];
        acc[..n].copy_from_slice(&e.ydot[n..2 * n]);
        let (tau, _) = self.motor_rates(&self.y, &v);
        let (frame, mut f) = Frame::with_forces(&self.model, &q, &v, &tau);
        // Contact forces: J^T lambda.
        for j in 0..self.modes.len() {
            if self.modes[j].closed() {
                let k = frame.contact(&self.model, j, &v);
                for i in 0..n {
                    f[i] += k.j_n[i] * e.lambda_n[j] + k.j_t[i] * e.lambda_t[j];
                }
            }
        }
        core::array::from_fn(|i| {
            if !self.held[i] {
                return 0.0;
            }
            (0..n).map(|j| frame.mass[i][j] * acc[j]).sum::<f64>() - f[i]
        })
    }

    /// The motors at state `y` (velocities `v`): each shaft's torque on its
    /// rotor's `phi`, N m, and the rate of its winding current, A/s; zero for a
    /// rotor the machine does not have.
    pub(super) fn motor_rates(&self, y: &[f64; NY], v: &Vector) -> ([f64; 2], [f64; 2]) {
        let mut tau = [0.0; 2];
        let mut di = [0.0; 2];
        for (k, rotor) in self.model.rotors.iter().enumerate() {
            // Shaft speed relative to its body in the driven sense.
            let s = rotor.sense;
            let omega_m = s * v[rotor.phi];
            let i = y[self.model.current(k)];
            tau[k] = s * self.motors[k].shaft_torque(i, omega_m);
            di[k] = self.motors[k].current_rate(self.winding[k], i, omega_m);
        }
        (tau, di)
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
        self.with_evaluation(y, |e| ContactForces {
            normal: e.lambda_n,
            tangential: e.lambda_t,
        })
    }

    /// Total mechanical energy (kinetic plus gravity's potential), J.
    pub fn mechanical_energy(&self) -> f64 {
        let q = self.q();
        let frame = Frame::new(&self.model, &q);
        frame.kinetic_energy(&self.v()) + frame.potential_energy(&self.model, &q)
    }
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
        for k in 0..self.plant.model.rotors.len() {
            let c = self.plant.model.current(k);
            y[c] = self.plant.motors[k].project_current(self.plant.winding[k], y[c]);
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::machine::Machine;

    /// A step with closed contacts and no event costs the integrator's six
    /// evaluations and nothing more: the dip test reads the stages' forces, and
    /// the step's last stage is the next step's first (the projection, after
    /// which the first stage and the event functions are evaluated again, does
    /// not run: the drift stays below its threshold, [`Plant::drifted`]). The
    /// reference machine at rest on both feet (windings open) for 0.2 s: beyond
    /// six an attempt, only the first event functions' evaluation, which the
    /// first step's derivative reuses (before: two more a step, the middle's and
    /// the projected state's, 421 over 210 attempts).
    #[test]
    fn a_step_in_persistent_contact_costs_six_evaluations() {
        let mut plant = resting();
        // The contacts' closing at t = 0 (the start's mode decision).
        plant.events.clear();
        let at_start = plant.evaluations();
        plant.advance_to(0.2, &mut |_| {}).unwrap();
        assert!(plant.events.is_empty(), "{:?}", plant.events);
        assert!(plant.attempts > 100, "{} attempts", plant.attempts);
        let beyond_stages = plant.evaluations() - at_start - 6 * plant.attempts;
        assert!(
            beyond_stages <= 1,
            "{} evaluations beyond the stages over {} attempts",
            beyond_stages,
            plant.attempts
        );
    }

    /// The reference machine at rest on both feet (windings open), its start's
    /// mode decision made: every contact closed.
    fn resting() -> Plant {
        resting_with(&[], Settings::default())
    }

    /// [`resting`] with the machine file's keys `sets` (`KEY=VALUE`, as
    /// `--set` takes them) and the plant's `settings`.
    pub(super) fn resting_with(sets: &[&str], settings: Settings) -> Plant {
        let text = std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../examples/vibro-driver.toml"
        ))
        .unwrap();
        let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
        let m = Machine::from_text("m.toml", &text, std::path::Path::new("."), &sets).unwrap();
        let model = PlantModel::new(&m);
        let y0 = model.initial_state(&m);
        let plant = Plant::new(model, y0, settings, Holds::default());
        assert!(plant.modes.iter().all(|m| m.closed()), "{:?}", plant.modes);
        plant
    }

    /// The resting machine with its platform's height raised by `dy`, m, and its
    /// upward velocity set to `du`, m/s (every foot's gap and normal velocity
    /// then `dy` and `du`), advanced by one step (the first, 1e-5 s): the largest
    /// gap and normal velocity of a foot after it, and the plant.
    fn pushed(dy: f64, du: f64) -> (f64, f64, Plant) {
        let mut plant = resting();
        let n = plant.model.dof;
        plant.y[1] += dy;
        plant.y[n + 1] += du;
        plant.fsal = None;
        plant.ev_cache = None;
        plant.events.clear();
        let h = plant.h;
        plant.advance_to(h, &mut |_| {}).unwrap();
        assert_eq!(plant.steps, 1, "one step");
        assert!(plant.events.is_empty(), "{:?}", plant.events);
        let (mut gap, mut u_n) = (0.0f64, 0.0f64);
        for j in 0..plant.modes.len() {
            let k = plant.contact_at(&plant.y, j);
            gap = gap.max(k.gap.abs());
            u_n = u_n.max(k.u_n.abs());
        }
        (gap, u_n, plant)
    }

    /// A resting machine pushed off its feet' constraints beyond the drift
    /// threshold ([`Plant::drifted`]: a gap beyond `1e-6 rtol` m, a normal
    /// velocity beyond `1e-3 rtol` m/s, 1e-14 m and 1e-11 m/s at the default
    /// 1e-8) is projected back after one step; pushed below it, it is left as
    /// it is (the step keeps a closed contact's normal velocity: its
    /// acceleration is zero). And after a projection the next step starts from
    /// the projected state: its first stage (FSAL) and its event functions are
    /// the projected state's, not the step's end's before the projection.
    #[test]
    fn a_drifted_state_is_projected_back_and_the_next_step_starts_there() {
        let rtol = Settings::default().rtol;
        let (gap_limit, velocity_limit) = (1e-6 * rtol, 1e-3 * rtol);
        // Beyond: gap 5 times, velocity 10 times the threshold, each alone.
        for (dy, du) in [(5.0 * gap_limit, 0.0), (0.0, 10.0 * velocity_limit)] {
            let (gap, u_n, plant) = pushed(dy, du);
            assert!(
                gap < 0.1 * gap_limit,
                "pushed by {dy:e} m: gap {gap:e} m left"
            );
            assert!(
                u_n < 0.1 * velocity_limit,
                "pushed by {du:e} m/s: normal velocity {u_n:e} m/s left"
            );
            let here = plant.evaluate(&plant.y).ydot;
            let first = plant.fsal.unwrap_or(here);
            assert_eq!(
                first, here,
                "the next step's first stage is not the projected state's"
            );
            let (y, ev) = plant.ev_cache.expect("event functions kept");
            assert_eq!(y, plant.y);
            assert_eq!(
                *ev,
                *plant.event_values(&plant.y),
                "event functions of another state"
            );
        }
        // Below: half the threshold, kept (to the step's rounding).
        let (gap, _, _) = pushed(0.5 * gap_limit, 0.0);
        assert!(
            (gap - 0.5 * gap_limit).abs() < 1e-2 * gap_limit,
            "pushed by half the gap threshold: gap {gap:e} m"
        );
        let (_, u_n, _) = pushed(0.0, 0.5 * velocity_limit);
        assert!(
            (u_n - 0.5 * velocity_limit).abs() < 1e-3 * velocity_limit,
            "pushed by half the velocity threshold: normal velocity {u_n:e} m/s"
        );
    }
}
