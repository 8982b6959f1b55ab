//! What a simulation run records: trace rows and the summary, with what held
//! the windings at its end ([`EndState`]); the event rows are [`crate::event`]'s.

use shared::controller::{Faults, State};
use shared::impact::MAX_CONTACTS;

use crate::machine::bodies::MAX_BODIES;
use crate::numbers::sig;
use crate::plant::contact::ContactForces;
use crate::plant::model::{PlantModel, NY};
use crate::simulation::breach::Breach;

/// Fastest travel either way, m/s: the eccentric's own speed at 60 000 rpm and
/// 2 cm is 126 m/s, but travel by impacts is a small part of it (the reference
/// machine: 20 to 50 mm/s); 10 m/s is 200 times that. A run's mean velocity
/// beyond it is no travel ([`Summary::not_a_travel`]), and a measured file's
/// row beyond it is refused (it catches mm/s written as m/s: 30 for 0.03).
pub const MAX_VELOCITY_MPS: f64 = 10.0;

/// One row of the `--out` trace. On a machine with one rotor, rotor 2's columns
/// (`phi2`, `omega2`, `i2`, `duty2`) stay, as 0 (the columns are fixed:
/// docs/cli-run.md, `--out`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TraceRow {
    /// Time, s.
    pub t: f64,
    /// Platform centre of mass, m.
    pub x: f64,
    /// Platform centre of mass, m.
    pub y: f64,
    /// Platform angle (pitch), rad.
    pub angle: f64,
    /// Velocity of the platform's centre of mass, m/s.
    pub vx: f64,
    /// Velocity of the platform's centre of mass, m/s.
    pub vy: f64,
    /// Platform angular velocity, rad/s.
    pub omega: f64,
    /// Eccentric angles in the platform frame, rad, not wrapped.
    pub phi1: f64,
    /// Eccentric angles in the platform frame, rad, not wrapped.
    pub phi2: f64,
    /// Their rates, rad/s.
    pub omega1: f64,
    /// Their rates, rad/s.
    pub omega2: f64,
    /// Winding currents, A.
    pub i1: f64,
    /// Winding currents, A.
    pub i2: f64,
    /// Duties, in [-1, 1].
    pub duty1: f64,
    /// Duties, in [-1, 1].
    pub duty2: f64,
    /// Normal force of persistent contact per contact in file order, N (0 while
    /// open; impacts are in the events); entries past the machine's contacts are 0.
    pub normal_force: [f64; MAX_CONTACTS],
    /// Tangential force of persistent contact per contact, N, along the
    /// fundament's tangent `t = (-n_y, n_x)`.
    pub tangential_force: [f64; MAX_CONTACTS],
    /// Every body after the platform, in file order: centre of mass (m, m),
    /// angle (rad), its velocity (m/s, m/s) and angular velocity (rad/s); entries
    /// past the machine's bodies are 0.
    pub bodies: [[f64; 6]; MAX_BODIES - 1],
}

impl TraceRow {
    /// The row of `model`'s state `y` at `t` with duties `duty` and the contact
    /// forces `forces` at that state; a rotor the machine does not have reads 0,
    /// its duty included (the trace's columns are fixed: docs/cli-run.md, `--out`).
    pub fn of(
        model: &PlantModel,
        t: f64,
        y: &[f64; NY],
        duty: [f64; 2],
        forces: &ContactForces,
    ) -> TraceRow {
        let n = model.dof;
        let [x, yc, angle, vx, vy, omega] = model.body_motion(0, y);
        let rotor = |k: usize| match model.rotors.get(k) {
            Some(r) => (y[r.phi], y[n + r.phi], y[model.current(k)]),
            None => (0.0, 0.0, 0.0),
        };
        let ((phi1, omega1, i1), (phi2, omega2, i2)) = (rotor(0), rotor(1));
        let mut bodies = [[0.0; 6]; MAX_BODIES - 1];
        for (b, row) in bodies.iter_mut().enumerate().take(model.bodies.len() - 1) {
            *row = model.body_motion(b + 1, y);
        }
        TraceRow {
            t,
            x,
            y: yc,
            angle,
            vx,
            vy,
            omega,
            phi1,
            phi2,
            omega1,
            omega2,
            i1,
            i2,
            duty1: duty[0],
            duty2: if model.rotors.len() > 1 { duty[1] } else { 0.0 },
            normal_force: forces.normal,
            tangential_force: forces.tangential,
            bodies,
        }
    }
}

/// The final state in the summary.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FinalState {
    /// Platform centre of mass, m.
    pub position: [f64; 2],
    /// Platform angle, rad.
    pub angle: f64,
    /// Velocity, m/s.
    pub velocity: [f64; 2],
    /// Angular velocity, rad/s.
    pub angular_velocity: f64,
}

/// What held the windings at the end of a run, as its summary names it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum EndState {
    /// Constant voltages or open windings: no controller.
    #[default]
    OpenLoop,
    /// The controller, in its state at its last tick ([`State::Idle`] before
    /// its first).
    Controller(State),
}

impl EndState {
    /// Its name in the outputs: `open-loop`, or the controller state's name.
    pub fn name(self) -> &'static str {
        match self {
            EndState::OpenLoop => "open-loop",
            EndState::Controller(s) => s.name(),
        }
    }
}

impl std::fmt::Display for EndState {
    /// [`EndState::name`].
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// The `--format json` summary of a run (docs/cli-run.md, "Outputs").
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Summary {
    /// Simulated end time, s.
    pub t_end: f64,
    /// `(x_C(T) - x_C(T/2)) / (T/2)`, m/s.
    pub mean_velocity: f64,
    /// `x_C(T) - x_C(0)`, m.
    pub distance: f64,
    /// Number of impact instants.
    pub impacts: usize,
    /// Mean speeds over the second half in each rotor's driven sense, rpm: one
    /// per rotor of the machine (rotor 1, then rotor 2 if it has two).
    pub rotor_speed_rpm: Vec<f64>,
    /// Circular mean of the measured phase offset over the second half, degrees;
    /// `None` on a one-rotor machine, which has no offset.
    pub phase_offset_deg: Option<f64>,
    /// RMS of (measured - commanded) offset over the second half, degrees (0
    /// without a commanded offset: open loop, one rotor).
    pub phase_error_deg_rms: f64,
    /// What held the windings at the end: the controller in its state, or open
    /// loop.
    pub state: EndState,
    /// Whether a phase loop held the offset: a controller run on two rotors;
    /// false in open loop, and on one rotor, whose controller holds speed only.
    pub phase_loop: bool,
    /// Faults the controller latched at the end (none in open loop).
    pub faults: Faults,
    /// The final state.
    pub final_state: FinalState,
    /// Warnings (each [`Summary::breaches`]' among them).
    pub warnings: Vec<String>,
    /// The bodies that went through the fundament or tipped over, by time
    /// ([`crate::simulation::breach`]).
    pub breaches: Vec<Breach>,
}

impl Summary {
    /// Why the run's `mean_velocity` and `distance` are no travel, if they are
    /// not, in a few words: the first breach ([`crate::simulation::breach`]), or
    /// a mean velocity beyond [`MAX_VELOCITY_MPS`] either way. The one rule of
    /// `run`, `scenario`, `tune`, `merge` and `calibrate`.
    pub fn not_a_travel(&self) -> Option<String> {
        self.breaches.first().map(Breach::short).or_else(|| {
            (self.mean_velocity.abs() > MAX_VELOCITY_MPS).then(|| {
                format!(
                    "mean velocity {} m/s, beyond the {} m/s of any travel by impacts",
                    sig(self.mean_velocity),
                    sig(MAX_VELOCITY_MPS)
                )
            })
        })
    }

    /// The machine's rotors, 1 or 2: one speed each.
    pub fn rotors(&self) -> usize {
        self.rotor_speed_rpm.len()
    }
}
