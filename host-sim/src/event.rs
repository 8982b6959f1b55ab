//! What happened at an instant of a run: one row of the `--events` record per
//! contact at an event (impact, contact, lift-off, stick, slip, Zeno, Painleve),
//! or per controller event (fault, state change). The plant and the controller in
//! the loop both write them; they are plain values, below both.

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
