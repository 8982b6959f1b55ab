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
//!   [`BridgeConfig::periods_per_update`] periods above. (The board's update
//!   falls on the extreme its repetition counter selects, by the reference
//!   manual's note the peak: half a period of phase against this, the same
//!   means; `docs/plant-model.md`.)
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
//! for a duty (at most 1.2e-4 of the supply). A command of the inputs' high
//! fractions themselves ([`BridgeCommand::Inputs`], the processor in the loop's:
//! compare values over `ARR`) is taken as it is, quantised as the timer holds it.

use shared::drive::{input_duties, period, BridgeConfig, Period};

use super::motor::Winding;

/// What drives a bridge: a signed duty, or off (its outputs disabled).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum BridgeCommand {
    /// A signed duty in `[-1, 1]` (clamped; a NaN coasts), `shared::drive`'s meaning.
    Duty(f64),
    /// The high fractions `[IN1, IN2]` in `[0, 1]` of the two inputs, as the
    /// timer holds them (its compare values over `ARR`), outputs enabled.
    Inputs([f32; 2]),
    /// Outputs off: every switch open, the winding coasts.
    Off,
}

/// What the winding sees for a command, over whole periods, as fractions of the
/// supply (the supply itself is the bridge's, read when the winding is asked for).
#[derive(Clone, Debug, PartialEq)]
enum Plan {
    /// Every switch open for the whole period.
    Coast,
    /// A linear period (no part coasts): its exact mean voltage, a fraction of
    /// the supply.
    Mean(f64),
    /// The period's parts, resolved: a switch at every part's end.
    Resolved(Period),
}

/// One motor's bridge: its configuration, the plan in force and the duty waiting
/// for the next update event, and where in the PWM period it stands.
#[derive(Clone, Debug)]
pub struct Bridge {
    config: BridgeConfig,
    supply: f64,
    /// PWM period, s.
    period: f64,
    plan: Plan,
    /// The inputs' high fractions waiting for the next update event.
    pending: Option<[f32; 2]>,
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
            plan: Plan::Coast,
            pending: None,
            every: u64::from(config.periods_per_update()),
            n: 0,
            part: 0,
        }
    }

    /// The high fractions of the inputs for `command` (`None`: off).
    fn inputs(&self, command: BridgeCommand) -> Option<[f32; 2]> {
        match command {
            BridgeCommand::Duty(d) => Some(input_duties(d as f32, self.config.decay)),
            BridgeCommand::Inputs(f) => Some(f),
            BridgeCommand::Off => None,
        }
    }

    /// The plan of the inputs' high fractions `inputs` over a whole period.
    fn plan(&self, inputs: [f32; 2]) -> Plan {
        let parts = period(inputs);
        // A linear period: its mean voltage, `sum_j l_j u_j` of the supply
        // (`shared::drive::mean_fraction`, here in f64 from the parts' ends).
        let mut start = 0.0f64;
        let mut mean = 0.0f64;
        for p in &parts {
            let Some(u) = p.connection.fraction() else {
                return if parts.len() == 1 {
                    Plan::Coast
                } else {
                    Plan::Resolved(parts)
                };
            };
            let end = f64::from(p.end);
            mean += (end - start) * f64::from(u);
            start = end;
        }
        Plan::Mean(mean)
    }

    /// The PWM period index containing `t` and whether `t` is its start (to
    /// rounding).
    fn period_at(&self, t: f64) -> (u64, bool) {
        let x = t / self.period;
        let n = (x + 1e-9).floor().max(0.0);
        (n as u64, (x - n).abs() <= 1e-9)
    }

    /// Command the bridge at time `t`, every switch before or at `t` already
    /// taken ([`Bridge::switch`]; the plant does that first): off at once; a duty
    /// from the next update event (at once if `t` is one), the period running on
    /// as it was until then (coasting if the bridge was off).
    pub fn command(&mut self, command: BridgeCommand, t: f64) {
        let (n, at_start) = self.period_at(t);
        match self.inputs(command) {
            None => {
                self.plan = Plan::Coast;
                self.pending = None;
            }
            Some(f) if at_start && n.is_multiple_of(self.every) => {
                self.n = n;
                self.start_period(f);
                self.pending = None;
            }
            Some(f) => {
                if !matches!(self.plan, Plan::Resolved(_)) {
                    // A constant plan has no switches to keep its period count.
                    self.n = n;
                }
                self.pending = Some(f);
            }
        }
    }

    /// Make the plan of the inputs' high fractions `inputs` the one in force from
    /// the start of period `self.n`.
    fn start_period(&mut self, inputs: [f32; 2]) {
        self.plan = self.plan(inputs);
        self.part = 0;
    }

    /// The supply sags or recovers: the windings see the new voltage at once.
    pub fn set_supply(&mut self, supply: f64) {
        self.supply = supply;
    }

    /// What the winding is connected to now.
    pub fn winding(&self) -> Winding {
        let fraction = match &self.plan {
            Plan::Coast => None,
            Plan::Mean(f) => Some(*f),
            Plan::Resolved(parts) => parts[self.part].connection.fraction().map(f64::from),
        };
        match fraction {
            Some(f) => Winding::Voltage(f * self.supply),
            None => Winding::Coast(self.supply),
        }
    }

    /// Whether the next period start passes without a switch: the last part of
    /// a resolved period goes on into the first of the next (the same
    /// connection), and no duty takes effect there.
    fn runs_through_period_start(&self) -> bool {
        let Plan::Resolved(parts) = &self.plan else {
            return false;
        };
        let update_due = self.pending.is_some() && (self.n + 1).is_multiple_of(self.every);
        self.part + 1 == parts.len()
            && parts.len() > 1
            && parts[0].connection == parts[self.part].connection
            && !update_due
    }

    /// The time of the next switch, s: a part's end (resolved; past a period
    /// start that changes nothing), or the next update event for a pending duty;
    /// `None` if nothing changes.
    pub fn next_switch(&self) -> Option<f64> {
        match &self.plan {
            Plan::Resolved(parts) => {
                let end = if self.runs_through_period_start() {
                    1.0 + f64::from(parts[0].end)
                } else {
                    f64::from(parts[self.part].end)
                };
                Some((self.n as f64 + end) * self.period)
            }
            Plan::Coast | Plan::Mean(_) => self
                .pending
                .map(|_| ((self.n / self.every + 1) * self.every) as f64 * self.period),
        }
    }

    /// Move to the next part (at the time [`Bridge::next_switch`] gave): the next
    /// part of the period, or the first of the next period (its second, if the
    /// first only continued the last), with a pending duty taking effect there if
    /// an update event falls on it (a constant plan with a duty pending moves
    /// straight to that update).
    pub fn switch(&mut self) {
        if self.runs_through_period_start() {
            self.n += 1;
            self.part = 1;
            return;
        }
        let last = match &self.plan {
            Plan::Resolved(parts) => self.part + 1 >= parts.len(),
            Plan::Coast | Plan::Mean(_) => true,
        };
        if !last {
            self.part += 1;
            return;
        }
        self.n = match (&self.plan, self.pending) {
            (Plan::Resolved(_), _) | (_, None) => self.n + 1,
            _ => (self.n / self.every + 1) * self.every,
        };
        match self.pending {
            Some(f) if self.n.is_multiple_of(self.every) => {
                self.pending = None;
                self.start_period(f);
            }
            _ => self.part = 0,
        }
    }
}
