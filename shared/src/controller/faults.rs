//! Faults: the named flags ([`Faults`]) and the checks that raise them
//! ([`FaultMonitor`]).
//!
//! Every fault has the same safe state: both H-bridges off (driver disabled,
//! windings open), in the tick that detects it, latched until
//! [`super::Command::ResetFaults`] (see [`super::Controller::step`]). The checks are timers: a condition must hold in
//! consecutive ticks for its time `T` (a limit in [`FaultLimits`]); it fires in the
//! tick whose accumulated duration reaches `T - dt/2` (half a tick of slack absorbs
//! the rounding of the sum), i.e. at a constant `dt` in the `round(T/dt)`-th
//! consecutive tick that sees it (the first counting as one), never later than the
//! `ceil(T/dt)`-th: at most `T` after the first tick that shows it. A tick without
//! the condition restarts the timer.

use core::fmt;
use core::ops::{BitOr, BitOrAssign};

use super::encoder::EncoderAnomaly;
use super::params::FaultLimits;
use super::State;

/// Latched faults as bit flags (`u16`); empty means healthy.
///
/// In defmt logs (feature `defmt`) it prints as the set flags' constant names in bit
/// order joined by `|` (`ESTOP`, `STALL|ENCODER`), or `none`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Faults(u16);

impl Faults {
    /// No fault.
    pub const NONE: Faults = Faults(0);
    /// A rotor driven at duty >= `stall_duty` stayed below `stall_speed_rpm` while its
    /// current said it was pushing against a load (>= `stall_current_a`).
    pub const STALL: Faults = Faults(1 << 0);
    /// A winding current above `over_current_a`, or not a number.
    pub const OVER_CURRENT: Faults = Faults(1 << 1);
    /// The encoder disagrees with the motor: a count jump faster than the rotor can
    /// turn, an index pulse away from a whole turn or outside the counts travelled, a
    /// turn and more without an index, or a driven rotor that reads slow while its
    /// low current says it turns freely (no counts).
    pub const ENCODER: Faults = Faults(1 << 2);
    /// The phase error stayed above `phase_error_max_deg` while running.
    pub const PHASE_LOCK_LOST: Faults = Faults(1 << 3);
    /// No command or heartbeat for `link_timeout_s` while starting or running.
    pub const LINK_LOST: Faults = Faults(1 << 4);
    /// Supply voltage outside [`supply_min_v`, `supply_max_v`] (or not a number).
    pub const SUPPLY: Faults = Faults(1 << 5);
    /// The E-stop input is active.
    pub const ESTOP: Faults = Faults(1 << 6);
    /// The processor restarted after a watchdog reset.
    pub const WATCHDOG_RESET: Faults = Faults(1 << 7);
    /// The parameters failed [`super::Params::validate`]; never clears (the
    /// controller runs on the reference parameters with the motors off).
    pub const PARAMS: Faults = Faults(1 << 8);
    /// A control tick started late or worked too long (`tick_late_max_s`,
    /// `tick_busy_max_s`) while the motors were driven: the loop was starved.
    pub const DEADLINE: Faults = Faults(1 << 9);

    /// Every flag with its display name, in bit order.
    pub const ALL: [(Faults, &'static str); 10] = [
        (Faults::STALL, "stall"),
        (Faults::OVER_CURRENT, "over_current"),
        (Faults::ENCODER, "encoder"),
        (Faults::PHASE_LOCK_LOST, "phase_lock_lost"),
        (Faults::LINK_LOST, "link_lost"),
        (Faults::SUPPLY, "supply"),
        (Faults::ESTOP, "estop"),
        (Faults::WATCHDOG_RESET, "watchdog_reset"),
        (Faults::PARAMS, "params"),
        (Faults::DEADLINE, "deadline"),
    ];

    /// The raw bits.
    pub const fn bits(self) -> u16 {
        self.0
    }

    /// From raw bits; bits without a name are dropped.
    pub const fn from_bits(bits: u16) -> Faults {
        // The named flags are the bits 0 .. ALL.len().
        Faults(bits & ((1 << Faults::ALL.len()) - 1))
    }

    /// No flag set.
    pub const fn is_empty(self) -> bool {
        self.0 == 0
    }

    /// Every flag of `other` is set.
    pub const fn contains(self, other: Faults) -> bool {
        self.0 & other.0 == other.0
    }

    /// Some flag of `other` is set.
    pub const fn intersects(self, other: Faults) -> bool {
        self.0 & other.0 != 0
    }

    /// The flags of `self` not in `other`.
    pub const fn without(self, other: Faults) -> Faults {
        Faults(self.0 & !other.0)
    }

    /// The names of the set flags, in bit order (`"stall"`, `"over_current"`, ...).
    pub fn names(self) -> impl Iterator<Item = &'static str> {
        Faults::ALL
            .into_iter()
            .filter(move |(flag, _)| self.contains(*flag))
            .map(|(_, name)| name)
    }
}

impl fmt::Display for Faults {
    /// The names separated by `, `, or `none`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.is_empty() {
            return f.write_str("none");
        }
        for (i, name) in self.names().enumerate() {
            if i > 0 {
                f.write_str(", ")?;
            }
            f.write_str(name)?;
        }
        Ok(())
    }
}

#[cfg(feature = "defmt")]
impl defmt::Format for Faults {
    /// The set flags' constant names in bit order joined by `|`, or `none`. Each
    /// name is a literal format string: interned, a few bytes on the wire, no heap.
    fn format(&self, f: defmt::Formatter<'_>) {
        if self.is_empty() {
            defmt::write!(f, "none");
            return;
        }
        let mut first = true;
        for (flag, _) in Faults::ALL {
            if !self.contains(flag) {
                continue;
            }
            if !first {
                defmt::write!(f, "|");
            }
            first = false;
            match flag {
                Faults::STALL => defmt::write!(f, "STALL"),
                Faults::OVER_CURRENT => defmt::write!(f, "OVER_CURRENT"),
                Faults::ENCODER => defmt::write!(f, "ENCODER"),
                Faults::PHASE_LOCK_LOST => defmt::write!(f, "PHASE_LOCK_LOST"),
                Faults::LINK_LOST => defmt::write!(f, "LINK_LOST"),
                Faults::SUPPLY => defmt::write!(f, "SUPPLY"),
                Faults::ESTOP => defmt::write!(f, "ESTOP"),
                Faults::WATCHDOG_RESET => defmt::write!(f, "WATCHDOG_RESET"),
                Faults::PARAMS => defmt::write!(f, "PARAMS"),
                Faults::DEADLINE => defmt::write!(f, "DEADLINE"),
                _ => defmt::write!(f, "{=u16:#x}", flag.0),
            }
        }
    }
}

impl BitOr for Faults {
    type Output = Faults;
    fn bitor(self, rhs: Faults) -> Faults {
        Faults(self.0 | rhs.0)
    }
}

impl BitOrAssign for Faults {
    fn bitor_assign(&mut self, rhs: Faults) {
        self.0 |= rhs.0;
    }
}

/// What the checks see in one tick (measured before this tick's commands).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Observation {
    /// The state at the start of the tick.
    pub state: State,
    /// Duties applied over the interval just ended (the previous tick's outputs).
    pub duty: [f32; 2],
    /// Filtered rotor speeds, rpm, driven sense.
    pub speed_rpm: [f32; 2],
    /// Winding currents as measured this tick, A.
    pub current: [f32; 2],
    /// Winding currents low-pass filtered (`current_filter_tau_s`), A.
    pub current_filtered: [f32; 2],
    /// Encoder inconsistencies found this tick.
    pub encoder_anomaly: [Option<EncoderAnomaly>; 2],
    /// Phase error, degrees, when the phase loop is closed: *unwrapped* (the sum of
    /// its wrapped tick-to-tick changes since the loop closed), so that a rotor
    /// slipping whole turns keeps it large instead of bringing it back through 0
    /// once a turn.
    pub phase_error_deg: Option<f32>,
    /// Supply voltage, V.
    pub supply_voltage: f32,
    /// E-stop input, true when active.
    pub estop: bool,
    /// Time since the last command or heartbeat, s.
    pub link_age_s: f32,
    /// The tick missed its deadline ([`FaultMonitor::missed_deadline`] on the
    /// measured timing).
    pub deadline_missed: bool,
}

/// The timers of the checks that need a condition to persist.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FaultMonitor {
    /// Per rotor: driven, slow and loaded, s.
    stall_s: [f32; 2],
    /// Per rotor: driven, slow and not loaded, s.
    encoder_s: [f32; 2],
    /// Per rotor: driven and slow, whatever the current, s.
    not_turning_s: [f32; 2],
    /// Per rotor: current above the limit, s.
    over_current_s: [f32; 2],
    /// Phase error above the limit while running, s.
    phase_s: f32,
    /// Supply out of range, s.
    supply_s: f32,
}

/// Advance a persistence timer: `timer += dt` while `condition` holds, else 0;
/// true once `timer >= limit - dt/2`.
fn persists(timer: &mut f32, condition: bool, dt: f32, limit: f32) -> bool {
    if condition {
        *timer += dt;
        *timer >= limit - 0.5 * dt
    } else {
        *timer = 0.0;
        false
    }
}

impl FaultMonitor {
    /// All timers at 0.
    pub fn new() -> Self {
        FaultMonitor::default()
    }

    /// Restart every timer (after a reset of the faults).
    pub fn clear(&mut self) {
        *self = FaultMonitor::default();
    }

    /// Run every check on one tick's observation; returns the faults detected in
    /// this tick (the caller latches them). `dt` is the tick's duration, s, > 0.
    ///
    /// - E-stop and encoder anomalies: at once.
    /// - Over-current (any state), supply (any state), phase (running): their timers.
    /// - A driven rotor that reads slow (`speed x sign(duty) < stall_speed_rpm` with
    ///   `|duty| >= stall_duty`), told apart by its filtered current: loaded
    ///   (`|i| >= stall_current_a`, it pushes against something) is a stall after
    ///   `stall_time_s`; unloaded (it should be turning, so the counts are wrong) is
    ///   an encoder fault after `encoder_time_s`; and whatever the current does,
    ///   slow for `stall_time_s + encoder_time_s` is one of the two (by the current
    ///   of that tick), so a current hovering at the threshold cannot postpone it.
    /// - Link: `link_age_s >= link_timeout_s - dt/2` while starting or running.
    /// - Deadline: a tick late or over its budget while the motors are driven, at
    ///   once ([`FaultMonitor::missed_deadline`]).
    pub fn check(&mut self, obs: &Observation, limits: &FaultLimits, dt: f32) -> Faults {
        let mut found = Faults::NONE;

        // E-stop: no delay.
        if obs.estop {
            found |= Faults::ESTOP;
        }

        // Supply out of range (NaN counts as out of range).
        let v = obs.supply_voltage;
        let supply_bad = !(v >= limits.supply_min_v && v <= limits.supply_max_v);
        if persists(&mut self.supply_s, supply_bad, dt, limits.supply_time_s) {
            found |= Faults::SUPPLY;
        }

        // Per rotor, written out for both (straight-line code, constant indices),
        // with whether the state drives the motors worked out once.
        let driving = obs.state.drives();
        found |= self.check_rotor(0, obs, driving, limits, dt);
        found |= self.check_rotor(1, obs, driving, limits, dt);

        // Phase lock: only while running with the loop closed.
        let phase_bad = obs.state == State::Running
            && obs
                .phase_error_deg
                .is_some_and(|e| e.is_nan() || libm::fabsf(e) > limits.phase_error_max_deg);
        if persists(&mut self.phase_s, phase_bad, dt, limits.phase_lost_time_s) {
            found |= Faults::PHASE_LOCK_LOST;
        }

        // Deadline: a starved loop while the motors are driven, at once.
        if driving && obs.deadline_missed {
            found |= Faults::DEADLINE;
        }

        // Command link: while a run is being started or held.
        if matches!(obs.state, State::Starting | State::Running)
            && obs.link_age_s >= limits.link_timeout_s - 0.5 * dt
        {
            found |= Faults::LINK_LOST;
        }

        found
    }

    /// Whether the tick started later than `tick_late_max_s` after its nominal
    /// time, or the previous one worked longer than `tick_busy_max_s` (NaN counts
    /// as missed).
    pub fn missed_deadline(t: super::TickTiming, limits: &FaultLimits) -> bool {
        !(t.late_s <= limits.tick_late_max_s && t.busy_s <= limits.tick_busy_max_s)
    }

    /// The checks of rotor `k` (see [`FaultMonitor::check`]); `driving`: whether
    /// `obs.state` drives the motors.
    #[inline(always)]
    fn check_rotor(
        &mut self,
        k: usize,
        obs: &Observation,
        driving: bool,
        limits: &FaultLimits,
        dt: f32,
    ) -> Faults {
        let mut found = Faults::NONE;

        // Encoder inconsistencies: no delay.
        if obs.encoder_anomaly[k].is_some() {
            found |= Faults::ENCODER;
        }

        // Over-current on the raw reading (NaN counts as over).
        let i = obs.current[k];
        let over = i.is_nan() || libm::fabsf(i) > limits.over_current_a;
        if persists(
            &mut self.over_current_s[k],
            over,
            dt,
            limits.over_current_time_s,
        ) {
            found |= Faults::OVER_CURRENT;
        }

        // Driven but not turning: stall or encoder, by the current.
        let duty = obs.duty[k];
        let driven = driving && libm::fabsf(duty) >= limits.stall_duty;
        let forward = if duty < 0.0 {
            -obs.speed_rpm[k]
        } else {
            obs.speed_rpm[k]
        };
        // NaN speed counts as slow (it cannot prove motion).
        let slow = driven && (forward.is_nan() || forward < limits.stall_speed_rpm);
        let loaded = libm::fabsf(obs.current_filtered[k]) >= limits.stall_current_a;
        if persists(
            &mut self.stall_s[k],
            slow && loaded,
            dt,
            limits.stall_time_s,
        ) {
            found |= Faults::STALL;
        }
        if persists(
            &mut self.encoder_s[k],
            slow && !loaded,
            dt,
            limits.encoder_time_s,
        ) {
            found |= Faults::ENCODER;
        }
        if persists(
            &mut self.not_turning_s[k],
            slow,
            dt,
            limits.stall_time_s + limits.encoder_time_s,
        ) {
            found |= if loaded {
                Faults::STALL
            } else {
                Faults::ENCODER
            };
        }
        found
    }

    /// The faults whose cause is present right now (not timed): these survive a
    /// [`super::Command::ResetFaults`]. E-stop active, supply out of range, a current
    /// above the over-current limit.
    pub fn present(obs: &Observation, limits: &FaultLimits) -> Faults {
        let mut present = Faults::NONE;
        if obs.estop {
            present |= Faults::ESTOP;
        }
        let v = obs.supply_voltage;
        if !(v >= limits.supply_min_v && v <= limits.supply_max_v) {
            present |= Faults::SUPPLY;
        }
        if obs
            .current
            .iter()
            .any(|i| i.is_nan() || libm::fabsf(*i) > limits.over_current_a)
        {
            present |= Faults::OVER_CURRENT;
        }
        present
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_follow_the_bits() {
        let f = Faults::ESTOP | Faults::STALL;
        let mut names = f.names();
        assert_eq!(names.next(), Some("stall"));
        assert_eq!(names.next(), Some("estop"));
        assert_eq!(names.next(), None);
        assert!(Faults::NONE.names().next().is_none());
        assert_eq!(Faults::from_bits(0xffff).bits(), 0x03ff);
    }

    #[test]
    fn a_timer_fires_in_the_ceil_t_over_dt_th_tick() {
        let mut t = 0.0;
        let fired: usize = (1..=10)
            .find(|_| persists(&mut t, true, 0.001, 0.003))
            .unwrap();
        assert_eq!(fired, 3);
        let mut t = 0.0;
        assert!(persists(&mut t, true, 0.001, 0.0));
    }
}
