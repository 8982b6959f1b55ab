//! The H-bridge of each motor as it is wired (the machine file's `[drive]`): what
//! the winding is connected to at every instant, from the controller's duty, the
//! decay mode and the PWM period, by the same mapping the firmware drives the
//! bridge with (`shared::drive`).
//!
//! # The timer, as the board's
//!
//! - A **duty** takes effect at the next update event of the timer: the firmware
//!   writes preloaded compare values, which the timer loads there. The update
//!   comes at a period start (the valley of the centre-aligned counter), every
//!   period up to 50 kHz of PWM and every
//!   [`BridgeConfig::periods_per_update`] periods above.
//! - **Off** takes effect at once: the firmware clears the timer's main output
//!   enable, asynchronously to the counter. Turning on again goes through a
//!   coasting rest of the period: the outputs are enabled at once, but the compare
//!   values the cut zeroed are replaced only at the next update event.
//!
//! # The winding
//!
//! Each part of a PWM period ([`shared::drive::period`]) connects the winding to
//! `+V_s` (forward), `-V_s` (reverse), 0 V (short, brake) or nothing (coast: the
//! current freewheels through the body diodes, [`Winding::Coast`]). Where a
//! period has no coasting part (every period in slow decay) the circuit is linear
//! and driven by a voltage, so the mean current over a period follows the period's
//! mean voltage exactly: integrate `L di/dt = u - R i - k omega` over a period
//! with `k omega` constant in it (it changes by parts in 1e4 over a 50 us period).
//! The winding then sees that mean, `d V_s` ([`Winding::Voltage`]), and no edge
//! cuts the integrator's steps. Where a period coasts (fast decay, or a bridge
//! turned off) the circuit is not linear (the diodes), no average is exact, and
//! the PWM is resolved: every edge is a switch of the winding at a known time.
//!
//! The duty is taken in `f32`, as the firmware computes it; the timer's
//! quantisation of the high fractions (4200 steps at 20 kHz) is not modelled
//! (at most 1.2e-4 of the supply).

use shared::drive::{input_duties, period, BridgeConfig, Connection, Decay, Part};

use super::motor::Winding;

/// What drives a bridge: a signed duty, or off (its outputs disabled).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum BridgeCommand {
    /// A signed duty in `[-1, 1]` (clamped; a NaN coasts), `shared::drive`'s meaning.
    Duty(f64),
    /// Outputs off: every switch open, the winding coasts.
    Off,
}

/// What the winding sees for a command, over whole periods.
#[derive(Clone, Debug, PartialEq)]
enum Plan {
    /// A constant winding for the whole period: a coast, or a linear period's
    /// exact mean voltage.
    Constant(Winding),
    /// The period's parts, resolved: a switch at every part's end.
    Resolved(Vec<Part>),
}

/// One motor's bridge: its configuration, the command in force and the one
/// waiting for the next period, and where in the PWM period it stands.
#[derive(Clone, Debug)]
pub struct Bridge {
    config: BridgeConfig,
    supply: f64,
    /// PWM period, s.
    period: f64,
    /// The command in force, and its plan.
    active: BridgeCommand,
    plan: Plan,
    /// A duty waiting for the next update event.
    pending: Option<BridgeCommand>,
    /// PWM periods per update event.
    every: u64,
    /// The index of the current PWM period (its start is `n T`).
    n: u64,
    /// The part of the period in force (resolved plans).
    part: usize,
}

impl Bridge {
    /// A bridge of `config` on a supply of `supply` volts, off.
    pub fn new(config: BridgeConfig, supply: f64) -> Self {
        Bridge {
            config,
            supply,
            period: 1.0 / f64::from(config.pwm_hz),
            active: BridgeCommand::Off,
            plan: Plan::Constant(Winding::Coast(supply)),
            pending: None,
            every: u64::from(config.periods_per_update()),
            n: 0,
            part: 0,
        }
    }

    /// The bridge's configuration.
    pub fn config(&self) -> BridgeConfig {
        self.config
    }

    /// The PWM period, s.
    pub fn pwm_period(&self) -> f64 {
        self.period
    }

    /// The plan of `command` over a whole period.
    fn plan(&self, command: BridgeCommand) -> Plan {
        let d = match command {
            BridgeCommand::Off => return Plan::Constant(Winding::Coast(self.supply)),
            BridgeCommand::Duty(d) => d as f32,
        };
        let parts = period(input_duties(d, self.config.decay));
        if parts.iter().any(|p| p.connection == Connection::Open) {
            if parts.len() == 1 {
                return Plan::Constant(Winding::Coast(self.supply));
            }
            return Plan::Resolved(parts.to_vec());
        }
        // A linear period: its mean voltage.
        let mut start = 0.0f64;
        let mut mean = 0.0f64;
        for p in &parts {
            let end = f64::from(p.end);
            mean += (end - start) * self.volts(p.connection);
            start = end;
        }
        Plan::Constant(Winding::Voltage(mean))
    }

    /// The voltage of a conducting connection, V.
    fn volts(&self, c: Connection) -> f64 {
        match c {
            Connection::Forward => self.supply,
            Connection::Reverse => -self.supply,
            Connection::Short | Connection::Open => 0.0,
        }
    }

    /// The PWM period index containing `t` and whether `t` is its start (to
    /// rounding).
    fn period_at(&self, t: f64) -> (u64, bool) {
        let x = t / self.period;
        let n = (x + 1e-9).floor().max(0.0);
        (n as u64, (x - n).abs() <= 1e-9)
    }

    /// Command the bridge at time `t`: off at once; a duty from the next update
    /// event (at once if `t` is one), coasting until then if the bridge was off.
    pub fn command(&mut self, command: BridgeCommand, t: f64) {
        let (n, at_start) = self.period_at(t);
        let at_start = at_start && n.is_multiple_of(self.every);
        match command {
            BridgeCommand::Off => {
                self.active = command;
                self.plan = Plan::Constant(Winding::Coast(self.supply));
                self.pending = None;
            }
            BridgeCommand::Duty(_) if at_start => {
                self.n = n;
                self.start_period(command);
                self.pending = None;
            }
            BridgeCommand::Duty(_) => {
                // The rest of this period as it was (resolved: from the part that
                // contains `t`), then the new duty.
                if let Plan::Resolved(parts) = &self.plan {
                    let phase = t / self.period - n as f64;
                    self.n = n;
                    self.part = parts
                        .iter()
                        .position(|p| f64::from(p.end) > phase)
                        .unwrap_or(parts.len() - 1);
                }
                self.n = n;
                self.pending = Some(command);
            }
        }
    }

    /// Make `command`'s plan the one in force from the start of period `self.n`.
    fn start_period(&mut self, command: BridgeCommand) {
        self.active = command;
        self.plan = self.plan(command);
        self.part = 0;
    }

    /// The supply sags or recovers: the windings see the new voltage at once (the
    /// same parts of the period).
    pub fn set_supply(&mut self, supply: f64) {
        if supply != self.supply {
            self.supply = supply;
            let part = self.part;
            self.plan = self.plan(self.active);
            if let Plan::Resolved(parts) = &self.plan {
                self.part = part.min(parts.len() - 1);
            }
        }
    }

    /// What the winding is connected to now.
    pub fn winding(&self) -> Winding {
        match &self.plan {
            Plan::Constant(w) => *w,
            Plan::Resolved(parts) => match parts[self.part].connection {
                Connection::Open => Winding::Coast(self.supply),
                c => Winding::Voltage(self.volts(c)),
            },
        }
    }

    /// The time of the next switch, s: a part's end (resolved), or the next update
    /// event for a pending duty; `None` if nothing changes.
    pub fn next_switch(&self) -> Option<f64> {
        match &self.plan {
            Plan::Resolved(parts) => {
                Some((self.n as f64 + f64::from(parts[self.part].end)) * self.period)
            }
            Plan::Constant(_) => self
                .pending
                .map(|_| ((self.n / self.every + 1) * self.every) as f64 * self.period),
        }
    }

    /// Move to the next part (at the time [`Bridge::next_switch`] gave): the next
    /// part of the period, or the first of the next period, with a pending duty
    /// taking effect there if an update event falls on it (a constant plan with a
    /// duty pending moves straight to that update).
    pub fn switch(&mut self) {
        let last = match &self.plan {
            Plan::Resolved(parts) => self.part + 1 >= parts.len(),
            Plan::Constant(_) => true,
        };
        if !last {
            self.part += 1;
            return;
        }
        self.n = match (&self.plan, self.pending) {
            (Plan::Constant(_), Some(_)) => (self.n / self.every + 1) * self.every,
            _ => self.n + 1,
        };
        match self.pending {
            Some(command) if self.n.is_multiple_of(self.every) => {
                self.pending = None;
                self.start_period(command);
            }
            _ => self.part = 0,
        }
    }

    /// The decay mode.
    pub fn decay(&self) -> Decay {
        self.config.decay
    }
}
