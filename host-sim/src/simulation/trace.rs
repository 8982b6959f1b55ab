//! What a simulation run records: trace rows, events and the summary.

use shared::impact::MAX_CONTACTS;

use crate::machine::bodies::MAX_BODIES;
use crate::simulation::breach::Breach;

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

/// The kind of an event (docs/cli-run.md, `--events`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EventKind {
    /// An impact at a contact.
    Impact,
    /// A contact closes (persistent contact begins).
    Contact,
    /// A contact opens.
    Liftoff,
    /// A slipping contact sticks.
    Stick,
    /// A sticking contact slips.
    Slip,
    /// An accumulation of impacts ends in persistent contact.
    Zeno,
    /// A controller fault.
    Fault,
    /// A controller state change.
    State,
    /// A Painleve configuration (no or several consistent contact forces).
    Painleve,
}

impl EventKind {
    /// The name in the events CSV.
    pub fn name(self) -> &'static str {
        match self {
            EventKind::Impact => "impact",
            EventKind::Contact => "contact",
            EventKind::Liftoff => "liftoff",
            EventKind::Stick => "stick",
            EventKind::Slip => "slip",
            EventKind::Zeno => "zeno",
            EventKind::Fault => "fault",
            EventKind::State => "state",
            EventKind::Painleve => "painleve",
        }
    }
}

/// One row of the `--events` CSV: one contact at one event.
#[derive(Clone, Debug, PartialEq)]
pub struct EventRow {
    /// Time, s (the rows of one simultaneous impact share it).
    pub t: f64,
    /// What happened.
    pub kind: EventKind,
    /// The contact's name (empty for controller events).
    pub contact: String,
    /// Normal velocity of the contact point before, m/s.
    pub normal_velocity_before: f64,
    /// Normal velocity after, m/s.
    pub normal_velocity_after: f64,
    /// Normal impulse, N s (impacts).
    pub normal_impulse: f64,
    /// Tangential impulse, N s (impacts).
    pub tangential_impulse: f64,
    /// The paper's interaction case (impacts), else `None`.
    pub case: Option<u8>,
    /// The state or fault name, or other detail.
    pub detail: String,
}

impl EventRow {
    /// A controller event at `t`: no contact, no velocities, impulses or case.
    pub fn controller(t: f64, kind: EventKind, detail: String) -> Self {
        EventRow {
            t,
            kind,
            contact: String::new(),
            normal_velocity_before: 0.0,
            normal_velocity_after: 0.0,
            normal_impulse: 0.0,
            tangential_impulse: 0.0,
            case: None,
            detail,
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
    /// Controller state at the end (`open-loop` without it).
    pub state: String,
    /// Whether a phase loop held the offset: a controller run on two rotors;
    /// false in open loop, and on one rotor, whose controller holds speed only.
    pub phase_loop: bool,
    /// Faults latched at the end.
    pub faults: Vec<String>,
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
    /// not: the first breach ([`crate::simulation::breach`]), in a few words.
    pub fn not_a_travel(&self) -> Option<String> {
        self.breaches.first().map(Breach::short)
    }

    /// The machine's rotors, 1 or 2: one speed each.
    pub fn rotors(&self) -> usize {
        self.rotor_speed_rpm.len()
    }
}
