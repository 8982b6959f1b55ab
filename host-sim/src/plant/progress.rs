//! The progress guard: a run that stops advancing in simulated time ends, and
//! says where and in what state, instead of running on for ever.
//!
//! The plant's work is counted in units, each an integrator attempt (a step
//! accepted or rejected) or an event handled (a contact event, a winding current
//! reaching its limit or zero). At most [`Progress::budget`] units may fall within
//! one [`WINDOW`] of simulated time: a window begins at the first attempt at or
//! after the last window's start plus [`WINDOW`], so each holds at least that much
//! simulated time once the run moves on. Legitimate runs need a few dozen units a
//! millisecond (a step every 0.1 ms, an impact or two), at most some thousands
//! (steps cut at every PWM edge at 50 kHz); a run that stops advancing (steps
//! shrinking to 1e-10 s, an event handled again and again at one instant) spends
//! any budget in seconds. Counting units, not the clock, gives every machine the
//! same stop at the same simulated instant.
//!
//! Why a run ended before its target ([`Stop`]): the guard, a step size below what
//! the integrator can take, or the caller's stop flag (a signal).

use std::fmt;

use super::contact::ContactMode;
use crate::event::EventKind;

/// The span of simulated time over which the budget counts, s: 1 ms.
pub const WINDOW: f64 = 1e-3;

/// The smallest integrator step, s: a rejected step that would go below it ends
/// the run ([`Stop::StepUnderflow`]). 1e-14 s: near t = 10 s the spacing of f64
/// is 1.8e-15 s, so such a step moves the time by a handful of roundings.
pub const MIN_STEP: f64 = 1e-14;

/// The work done in the current window.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Progress {
    /// Units allowed within one window.
    pub budget: u64,
    /// Where the current window began, s.
    start: f64,
    /// Units spent since.
    spent: u64,
}

impl Progress {
    /// A guard allowing `budget` units a window, its first window at `t = 0`.
    pub fn new(budget: u64) -> Self {
        Progress {
            budget,
            start: 0.0,
            spent: 0,
        }
    }

    /// Before an attempt at time `t`, s: a window that has lasted [`WINDOW`] gives
    /// way to a new one beginning at `t`.
    pub fn at(&mut self, t: f64) {
        if t >= self.start + WINDOW {
            self.start = t;
            self.spent = 0;
        }
    }

    /// One unit of work; whether the window's budget still holds.
    pub fn spend(&mut self) -> bool {
        self.spent += 1;
        self.spent <= self.budget
    }
}

/// A contact as the plant left it.
#[derive(Clone, Debug, PartialEq)]
pub struct ContactState {
    /// The contact's name.
    pub name: String,
    /// Its mode.
    pub mode: ContactMode,
    /// Its gap to the fundament, m.
    pub gap: f64,
}

/// Where the plant stopped: the time, every contact's mode, the last event.
#[derive(Clone, Debug, PartialEq)]
pub struct Situation {
    /// Time, s.
    pub t: f64,
    /// Every contact, in file order.
    pub contacts: Vec<ContactState>,
    /// The last contact event handled, and its time, s.
    pub last_event: Option<(EventKind, f64)>,
}

/// Why [`super::simulator::Plant::advance_to`] ended before its target. The plant
/// stays where it stopped, in a consistent state (the trace written up to there is
/// whole), and every later call ends the same way.
#[derive(Clone, Debug, PartialEq)]
pub enum Stop {
    /// The stop flag was set (a signal), seen at time `t`, s.
    Interrupted {
        /// Time, s.
        t: f64,
    },
    /// More than `budget` units of work within one [`WINDOW`]: the run stopped
    /// advancing.
    NoProgress {
        /// Where.
        at: Situation,
        /// The budget, units a window.
        budget: u64,
    },
    /// A rejected step would have gone below [`MIN_STEP`].
    StepUnderflow {
        /// Where.
        at: Situation,
        /// The step it would have taken next, s.
        h: f64,
    },
}

impl Stop {
    /// The time the plant stopped at, s.
    pub fn t(&self) -> f64 {
        match self {
            Stop::Interrupted { t } => *t,
            Stop::NoProgress { at, .. } | Stop::StepUnderflow { at, .. } => at.t,
        }
    }

    /// Whether the caller's stop flag (a signal) ended the run, not the plant:
    /// the command reports the signal; a sweep ends, it does not count the run.
    pub fn is_signal(&self) -> bool {
        matches!(self, Stop::Interrupted { .. })
    }
}

impl fmt::Display for Situation {
    /// `contacts K1 stick, K2 open (gap 1.250e-3 m); last event impact at t = ... s`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "contacts")?;
        for (i, c) in self.contacts.iter().enumerate() {
            let sep = if i == 0 { " " } else { ", " };
            write!(f, "{sep}{} {}", c.name, c.mode.name())?;
            if c.mode == ContactMode::Open {
                write!(f, " (gap {:.3e} m)", c.gap)?;
            }
        }
        match self.last_event {
            Some((kind, t)) => write!(f, "; last event {} at t = {t:.9} s", kind.name()),
            None => write!(f, "; no contact event yet"),
        }
    }
}

impl fmt::Display for Stop {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Stop::Interrupted { t } => write!(f, "interrupted at t = {t:.9} s"),
            Stop::NoProgress { at, budget } => write!(
                f,
                "no progress at t = {:.9} s: more than {budget} integrator steps and events within {} ms of simulated time (simulation.progress_budget); {at}",
                at.t,
                WINDOW * 1e3
            ),
            Stop::StepUnderflow { at, h } => write!(
                f,
                "integrator step size underflow at t = {:.9} s: the next step, {h:.3e} s, is below {MIN_STEP:e} s; {at}",
                at.t
            ),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_budget_holds_within_a_window_and_a_new_window_starts_afresh() {
        let mut p = Progress::new(3);
        p.at(0.0);
        assert!(p.spend() && p.spend() && p.spend());
        assert!(!p.spend(), "a fourth unit within the first millisecond");
        // Still inside the window (it began at 0): nothing is given back.
        p.at(0.5e-3);
        assert!(!p.spend());
        // A millisecond after its start, a new window begins where the run is.
        p.at(1.2e-3);
        assert!(p.spend() && p.spend() && p.spend());
        assert!(!p.spend());
        // That window runs to 2.2 ms, not to 2 ms.
        p.at(2.1e-3);
        assert!(!p.spend());
        p.at(2.2e-3);
        assert!(p.spend());
    }

    #[test]
    fn the_message_names_the_time_the_contacts_their_modes_and_the_last_event() {
        let at = Situation {
            t: 0.544,
            contacts: vec![
                ContactState {
                    name: "K1".into(),
                    mode: ContactMode::Stick,
                    gap: 0.0,
                },
                ContactState {
                    name: "K2".into(),
                    mode: ContactMode::Open,
                    gap: 1.25e-3,
                },
                ContactState {
                    name: "K3".into(),
                    mode: ContactMode::SlipNegative,
                    gap: 0.0,
                },
            ],
            last_event: Some((EventKind::Painleve, 0.54397)),
        };
        let stop = Stop::NoProgress { at, budget: 100 };
        assert_eq!(
            stop.to_string(),
            "no progress at t = 0.544000000 s: more than 100 integrator steps and events within 1 ms of simulated time (simulation.progress_budget); contacts K1 stick, K2 open (gap 1.250e-3 m), K3 slip-; last event painleve at t = 0.543970000 s"
        );
        assert_eq!(stop.t(), 0.544);
    }
}
