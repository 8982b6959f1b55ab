//! Motor identification: per rotor, the winding resistance, the torque constant,
//! Coulomb and viscous friction and the inertia (the eccentric included), with
//! their standard errors and the fits' residuals, as a pure state machine
//! ([`IdentifyRun`]) stepped by the control tick, as the self-test is.
//!
//! # Procedure
//!
//! Rotor 1, then rotor 2, one at a time; the rotor not under test has its winding
//! shorted (its bridge driven at duty 0). Per rotor:
//!
//! 1. **Settle**: both rotors at rest ([`REST_RPM`] for [`REST_TIME_S`]), at most
//!    [`SETTLE_TIMEOUT_S`].
//! 2. **Standstill**: duties too small to turn the rotor over, each held for
//!    [`HOLD_SETTLE_S`] until the rotor rests, then measured over
//!    [`HOLD_MEASURE_S`]: [`HOLD_LEVELS`] of the hold current
//!    `HOLD_FRACTION T_L / k` (half of what lifts the eccentric over its axis at
//!    the machine file's values), forward then reverse at each level. A rotor
//!    that turns more than a quarter turn away ends the standstill levels (the
//!    larger ones would turn it too); at least two each way must hold.
//! 3. **Speed**: from rest, open loop, at duties for [`SPEED_LEVELS`] of the top
//!    speed (below), the top first: the spin-up from rest gives the inertia
//!    (`energy.rs`: an energy balance between whole turns); each level settles for eight mechanical time constants (at
//!    least [`SPEED_SETTLE_MIN_S`]) and is measured over at least [`MIN_TURNS`]
//!    whole turns and [`MIN_MEASURE_S`].
//! 4. **Coast**: the bridge off until the rotor rests, at most
//!    [`COAST_TIMEOUT_S`]; then its result is put together
//!    (`assemble.rs`: the voltage fit, the friction fit, the inertia).
//!
//! The top speed is [`TOP_SPEED_FRACTION`] of the resonance band's low end, at
//! most the controller's top speed: one rotor alone excites the platform with
//! half the force of two, at a quarter of the band's square of the speed, so the
//! platform stays on its feet. The duties come from the machine file's motor, so
//! a motor unlike its file reaches other speeds; what counts is what is
//! measured. Reference machine: hold currents 0.018 to 0.074 A (duties 0.003 to
//! 0.012), top speed 750 rpm at duty 0.14, about 9 s a rotor (`shared/tests/identify.rs`:
//! 17.6 s for both).
//!
//! # Limits and faults
//!
//! The controller's fault checks keep running (E-stop, over-current, supply,
//! count jumps, the stall checks where the duty is at or above `stall_duty`); any
//! fault, or a stop command, aborts it with the motors off in the same tick. A
//! speed above the controller's top speed ends the rotor's run ([`Shortfall::TooFast`]);
//! every wait has a timeout, so it never waits for ever.

mod assemble;
mod energy;
mod fit;
mod result;

pub use assemble::INERTIA_SPEED_FRACTION;
pub use fit::{LeastSquares, Solution};
pub use result::{
    Estimate, IdentifyProgress, IdentifyReport, IdentifyStatus, Identity, RotorIdentity, Shortfall,
};

use super::angle::rpm_to_rad_s;
use super::io::Bridge;
use super::params::{Params, RotorCount};
use assemble::{Assembly, Gathered, SpeedRow, VoltageRow, VOLTAGE_ROWS};
use core::f64::consts::TAU;
use energy::{Counts, SpinUp};

/// The standstill levels, as fractions of the hold current.
pub const HOLD_LEVELS: [f32; 4] = [0.25, 0.5, 0.75, 1.0];
/// The hold current's fraction of the current that lifts the eccentric over
/// (`T_L / k`, the machine file's values).
pub const HOLD_FRACTION: f32 = 0.5;
/// The speed levels, as fractions of the top speed, in the order run.
pub const SPEED_LEVELS: [f32; 4] = [1.0, 0.8, 0.6, 0.4];
/// The top speed's fraction of the resonance band's low end.
pub const TOP_SPEED_FRACTION: f32 = 0.5;
/// A rotor rests below this speed, rpm.
pub const REST_RPM: f32 = 10.0;
/// Both rotors resting this long end a settle, s.
pub const REST_TIME_S: f32 = 0.2;
/// A settle that has not seen rest after this long ends the rotor's run, s.
pub const SETTLE_TIMEOUT_S: f32 = 3.0;
/// A standstill level is held at least this long before it is measured, s.
pub const HOLD_SETTLE_S: f32 = 0.3;
/// A standstill level is measured over this long, s.
pub const HOLD_MEASURE_S: f32 = 0.2;
/// A standstill level whose rotor has not rested after this long ends the
/// standstill levels, s.
pub const HOLD_TIMEOUT_S: f32 = 2.0;
/// The least settle of a speed level, s.
pub const SPEED_SETTLE_MIN_S: f32 = 0.3;
/// Mechanical time constants `J R / k^2` a speed level settles for.
pub const SETTLE_TIME_CONSTANTS: f32 = 8.0;
/// Whole turns a speed level is measured over, at least.
pub const MIN_TURNS: u32 = 4;
/// A speed level is measured over at least this long, s.
pub const MIN_MEASURE_S: f32 = 0.3;
/// A speed level that has not made [`MIN_TURNS`] after this long ends the
/// rotor's run, s.
pub const MAX_MEASURE_S: f32 = 4.0;
/// The coast to rest ends after this long whatever the rotor does, s.
pub const COAST_TIMEOUT_S: f32 = 6.0;
/// The longest one rotor's identification can take with every wait at its
/// timeout, s: two settles, every standstill level held to its timeout, every
/// speed level settling and measuring to theirs, and the coast [60 s; about 9 s
/// on the reference machine].
pub const WORST_ROTOR_S: f32 = 2.0 * SETTLE_TIMEOUT_S
    + 2.0 * HOLD_LEVELS.len() as f32 * HOLD_TIMEOUT_S
    + SPEED_LEVELS.len() as f32 * 2.0 * MAX_MEASURE_S
    + COAST_TIMEOUT_S;

/// The identification never drives harder than this duty.
pub const MAX_DUTY: f32 = 0.9;

/// The identification's settings, derived from the controller's parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IdentifyConfig {
    /// The standstill duties per rotor, magnitudes, in [`HOLD_LEVELS`]' order.
    pub hold_duty: [[f32; HOLD_LEVELS.len()]; 2],
    /// The speed levels' duties per rotor, in [`SPEED_LEVELS`]' order.
    pub speed_duty: [[f32; SPEED_LEVELS.len()]; 2],
    /// A speed level's settle per rotor, s.
    pub settle_s: [f32; 2],
    /// The largest load torque at low speed per rotor, N m (the machine file's
    /// `m e g + T_c`).
    pub load_torque_nm: [f32; 2],
    /// The machine file's resistance, ohm, and torque constant, N m/A, per rotor:
    /// what weighs the voltage fit's rows by their errors.
    pub motor: [(f32, f32); 2],
    /// Configured counts per revolution `N`.
    pub counts_per_rev: u32,
    /// A rotor faster than this ends its run, rpm.
    pub max_speed_rpm: f32,
    /// The rotors identified: rotor 1, then rotor 2 if the machine has one.
    pub rotor_count: RotorCount,
}

impl IdentifyConfig {
    /// The settings for `p` (module documentation).
    pub fn from_params(p: &Params) -> Self {
        let v = p.supply_nominal_v;
        let top_rpm = (TOP_SPEED_FRACTION * p.resonance_band_rpm[0]).min(p.max_speed_rpm);
        let duty = |d: f32| {
            if d.is_finite() {
                d.clamp(0.0, MAX_DUTY)
            } else {
                0.0
            }
        };
        let hold_duty = p.rotors.map(|r| {
            let amps = HOLD_FRACTION * r.load_torque_nm / r.torque_constant;
            HOLD_LEVELS.map(|f| duty(f * amps * r.resistance_ohm / v))
        });
        let speed_duty = p.rotors.map(|r| {
            // The back-EMF at the level's speed, and half the load's current.
            let friction_amps = 0.5 * r.load_torque_nm / r.torque_constant;
            SPEED_LEVELS.map(|f| {
                let w = rpm_to_rad_s(f * top_rpm);
                duty((r.torque_constant * w + r.resistance_ohm * friction_amps) / v)
            })
        });
        let settle_s = p.rotors.map(|r| {
            let tau = r.inertia_kg_m2 * r.resistance_ohm / (r.torque_constant * r.torque_constant);
            let s = SETTLE_TIME_CONSTANTS * tau;
            if s.is_finite() {
                s.clamp(SPEED_SETTLE_MIN_S, MAX_MEASURE_S)
            } else {
                SPEED_SETTLE_MIN_S
            }
        });
        IdentifyConfig {
            hold_duty,
            speed_duty,
            settle_s,
            load_torque_nm: p.rotors.map(|r| r.load_torque_nm),
            motor: p.rotors.map(|r| (r.resistance_ohm, r.torque_constant)),
            counts_per_rev: p.encoder_counts.max(1),
            max_speed_rpm: p.max_speed_rpm,
            rotor_count: p.rotor_count,
        }
    }
}

/// What the identification reads each tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IdentifySample {
    /// Encoder counters ([`super::Inputs::encoder`]).
    pub encoder: [u32; 2],
    /// Winding currents, A, each the mean over the tick just ended
    /// ([`super::Inputs::current`]).
    pub current: [f32; 2],
    /// Supply voltage, V ([`super::Inputs::supply_voltage`]).
    pub supply_voltage: f32,
    /// Filtered speeds, rpm.
    pub speed_rpm: [f32; 2],
}

/// What one tick of the identification gives.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IdentifyStep {
    /// The bridges for this tick.
    pub bridges: [Bridge; 2],
    /// It has finished (every bridge off).
    pub done: bool,
}

/// The tested rotor's tick just sampled: its interval's mean voltage (the duty
/// written in the previous tick times the supply), V, its mean current, A, its
/// travel, counts, and its count now.
#[derive(Clone, Copy, Debug)]
struct Tick {
    volts: f32,
    amps: f32,
    d_count: i32,
    count: u32,
}

/// Means over a level's measured ticks; a speed level's last tick counts only
/// up to the whole turn it ends at.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Window {
    /// Ticks, the last one's fraction included.
    ticks: f64,
    /// `sum V`, V.
    volts: f64,
    /// `sum i`, A.
    amps: f64,
    /// `sum (i_n - i_(n-1))^2` over the measured ticks, A^2, and how many.
    amps_steps_sq: f64,
    amps_steps: f64,
    /// The last tick's current, A.
    last_amps: Option<f32>,
    /// Counts travelled.
    travel: f64,
    /// `sum i dtheta`, A rad.
    amps_by_angle: f64,
    /// `sum w dtheta`, rad^2/s.
    speed_by_angle: f64,
}

impl Window {
    fn add(&mut self, t: Tick, n: u32, dt: f32) {
        self.add_part(t, 1.0, n, dt);
    }

    /// The first `fraction` of tick `t` (its means held over the tick).
    fn add_part(&mut self, t: Tick, fraction: f64, n: u32, dt: f32) {
        // A non-finite reading (an ADC glitch the fault checks let pass for a
        // tick or two) is left out of the means.
        if !(t.volts.is_finite() && t.amps.is_finite()) {
            return;
        }
        let counts = fraction * f64::from(t.d_count);
        let d_theta = TAU * counts / f64::from(n);
        let speed = TAU * f64::from(t.d_count) / (f64::from(n) * f64::from(dt));
        self.ticks += fraction;
        self.volts += fraction * f64::from(t.volts);
        self.amps += fraction * f64::from(t.amps);
        if let Some(last) = self.last_amps {
            let step = f64::from(t.amps) - f64::from(last);
            self.amps_steps_sq += fraction * step * step;
            self.amps_steps += fraction;
        }
        self.last_amps = Some(t.amps);
        self.travel += counts;
        self.amps_by_angle += f64::from(t.amps) * d_theta;
        self.speed_by_angle += speed * d_theta;
    }

    fn seconds(&self, dt: f32) -> f32 {
        (self.ticks * f64::from(dt)) as f32
    }

    /// `(V, i, w)`: the time means, V, A, rad/s.
    fn means(&self, n: u32, dt: f32) -> (f64, f64, f64) {
        let ticks = self.ticks.max(1.0);
        let time = ticks * f64::from(dt);
        (
            self.volts / ticks,
            self.amps / ticks,
            TAU * self.travel / (f64::from(n) * time),
        )
    }

    /// `(<w>_theta, <i>_theta)`: the means over the angle, rad/s and A.
    fn by_angle(&self, n: u32) -> (f64, f64) {
        let theta = TAU * self.travel / f64::from(n);
        (self.speed_by_angle / theta, self.amps_by_angle / theta)
    }

    /// The standard error of the mean speed, rad/s: a count of quantization at
    /// each end of the window, each uniform over one count (`1 / sqrt 12`), over
    /// its time.
    fn speed_std_error(&self, n: u32, dt: f32) -> f64 {
        let counts = libm::sqrt(2.0 / 12.0);
        TAU * counts / (f64::from(n) * self.ticks.max(1.0) * f64::from(dt))
    }

    /// The standard error of the mean current, A: the sense's noise from the
    /// tick-to-tick steps, `sigma^2 = <(i_n - i_(n-1))^2> / 2` (von Neumann's
    /// estimator: the current's swing over a turn, tens of ticks long, hardly
    /// enters a step, and whole turns average it out of the mean), over
    /// `sqrt(ticks)`.
    fn amps_std_error(&self) -> f64 {
        let steps = self.amps_steps.max(1.0);
        libm::sqrt(self.amps_steps_sq / (2.0 * steps) / self.ticks.max(1.0))
    }
}

/// What a settle leads to.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Next {
    Standstill,
    Speed,
}

/// A standstill level in progress.
#[derive(Clone, Copy, Debug, PartialEq)]
struct HoldLevel {
    /// Which: magnitude `level / 2` of [`HOLD_LEVELS`], forward when even.
    level: usize,
    /// The count where it started.
    start: u32,
    elapsed_s: f32,
    /// Time both rotors have rested, s.
    rest_s: f32,
    /// Its measurement, once it has settled.
    window: Option<Window>,
}

/// Where the identification stands.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Phase {
    /// Both rotors braked, waiting for rest.
    Settle {
        rest_s: f32,
        elapsed_s: f32,
        next: Next,
    },
    /// A standstill level.
    Hold(HoldLevel),
    /// Speed level `level`.
    Speed {
        level: usize,
        elapsed_s: f32,
        window: Option<Window>,
    },
    /// The bridge off until rest; then the rotor's result (`shortfall` if it fell
    /// short).
    Coast {
        rest_s: f32,
        elapsed_s: f32,
        shortfall: Option<Shortfall>,
    },
    /// Finished (or aborted).
    Done,
}

/// The identification in progress. See the module documentation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IdentifyRun {
    config: IdentifyConfig,
    /// The rotor under test (the rotor count after the last).
    rotor: usize,
    phase: Phase,
    /// The bridges written in the previous tick: what drove the interval whose
    /// means this tick's sample holds.
    last: [Bridge; 2],
    /// The tested rotor's counts.
    counts: Counts,
    /// The tested rotor's count in the previous tick (`None` before the first).
    last_count: Option<u32>,
    /// The control tick, s.
    dt: f32,
    /// The tested rotor's voltage rows (standstill levels, then speed levels).
    voltage: [VoltageRow; VOLTAGE_ROWS],
    voltage_rows: usize,
    /// Standstill levels measured, forward and reverse.
    holds: [u8; 2],
    /// Its speed levels.
    speeds: [SpeedRow; SPEED_LEVELS.len()],
    speed_rows: usize,
    /// Its spin-up from rest.
    spin: Option<SpinUp>,
    /// Its measurements put together, a share a tick while it coasts.
    assembly: Assembly,
    result: Identity,
}

impl IdentifyRun {
    /// An identification about to settle before rotor 1.
    pub fn new(config: IdentifyConfig) -> Self {
        IdentifyRun {
            config,
            rotor: 0,
            phase: Phase::Settle {
                rest_s: 0.0,
                elapsed_s: 0.0,
                next: Next::Standstill,
            },
            last: [Bridge::Off; 2],
            counts: Counts::default(),
            last_count: None,
            dt: 0.0,
            voltage: [VoltageRow::default(); VOLTAGE_ROWS],
            voltage_rows: 0,
            holds: [0; 2],
            speeds: [SpeedRow::default(); SPEED_LEVELS.len()],
            speed_rows: 0,
            spin: None,
            assembly: Assembly::new(),
            result: Identity {
                rotors: [RotorIdentity::default(); 2],
                rotors_run: config.rotor_count.count() as u8,
            },
        }
    }

    /// The settings.
    pub fn config(&self) -> &IdentifyConfig {
        &self.config
    }

    /// What has been measured so far (the rotors finished).
    pub fn result(&self) -> Identity {
        self.result
    }

    /// Finished (or aborted).
    pub fn is_done(&self) -> bool {
        self.phase == Phase::Done
    }

    /// How many rotors have finished (their results final).
    pub fn rotors_finished(&self) -> u8 {
        self.rotor as u8
    }

    /// The rotor under test, while one is.
    pub fn rotor(&self) -> Option<usize> {
        (self.phase != Phase::Done).then_some(self.rotor)
    }

    /// Stop where it stands: the rotor under test and those after it are marked
    /// [`Shortfall::Aborted`], the finished ones are kept.
    pub fn abort(&mut self) {
        if self.phase != Phase::Done {
            // The rotor under test and every one after it: none was measured.
            let count = self.config.rotor_count.count();
            for r in self.result.rotors.iter_mut().take(count).skip(self.rotor) {
                *r = RotorIdentity::short(Shortfall::Aborted);
            }
        }
        self.phase = Phase::Done;
    }

    /// One tick, `dt` s after the previous one (> 0): the bridges to write now.
    /// Kept out of line: its frame is on the stack only while an identification
    /// runs, not in every control tick's.
    #[inline(never)]
    #[cold]
    pub fn step(&mut self, s: &IdentifySample, dt: f32) -> IdentifyStep {
        if self.phase == Phase::Done {
            return self.finish_step(None);
        }
        self.dt = dt;
        let r = self.rotor;
        let count = s.encoder[r];
        let tick = self.counts.push(count);
        let d_count = count.wrapping_sub(self.last_count.unwrap_or(count)) as i32;
        self.last_count = Some(count);
        let sampled = Tick {
            volts: self.last[r].duty() * s.supply_voltage,
            amps: s.current[r],
            d_count,
            count,
        };
        let n = self.config.counts_per_rev;
        if let Some(spin) = &mut self.spin {
            spin.step(tick, count, sampled.amps, &self.counts, n, dt);
        }
        let drive = match self.phase {
            Phase::Done => None,
            Phase::Settle {
                rest_s,
                elapsed_s,
                next,
            } => self.settle(s, rest_s, elapsed_s, next, count),
            Phase::Hold(level) => self.hold(s, level, sampled),
            Phase::Speed {
                level,
                elapsed_s,
                window,
            } => self.speed(s, level, elapsed_s, window, sampled),
            Phase::Coast {
                rest_s,
                elapsed_s,
                shortfall,
            } => self.coast(s, rest_s, elapsed_s, shortfall),
        };
        self.finish_step(drive)
    }

    /// The bridges of a tick: the tested rotor's `drive` (`None`: off), the other
    /// rotor's winding shorted (off on a one-rotor machine, whose rotor 2 is not
    /// driven).
    fn finish_step(&mut self, drive: Option<f32>) -> IdentifyStep {
        let done = self.phase == Phase::Done;
        let mut bridges = [Bridge::Off; 2];
        if !done {
            let two = self.config.rotor_count == RotorCount::Two;
            for (k, b) in bridges.iter_mut().enumerate() {
                *b = if k == self.rotor {
                    drive.map_or(Bridge::Off, Bridge::Driven)
                } else if two {
                    Bridge::Driven(0.0)
                } else {
                    Bridge::Off
                };
            }
        }
        self.last = bridges;
        IdentifyStep { bridges, done }
    }

    fn at_rest(s: &IdentifySample) -> bool {
        s.speed_rpm.iter().all(|w| libm::fabsf(*w) <= REST_RPM)
    }

    /// Phase 1 (and before the speed levels): both braked until rest.
    fn settle(
        &mut self,
        s: &IdentifySample,
        rest_s: f32,
        elapsed_s: f32,
        next: Next,
        count: u32,
    ) -> Option<f32> {
        let dt = self.dt;
        let rest_s = if Self::at_rest(s) { rest_s + dt } else { 0.0 };
        let elapsed_s = elapsed_s + dt;
        if rest_s >= REST_TIME_S - 0.5 * dt {
            return match next {
                Next::Standstill => self.start_hold(0, count),
                Next::Speed => {
                    self.spin = Some(SpinUp::new(count));
                    self.start_speed(0)
                }
            };
        }
        if elapsed_s >= SETTLE_TIMEOUT_S {
            return self.start_coast(Some(Shortfall::NoRest));
        }
        self.phase = Phase::Settle {
            rest_s,
            elapsed_s,
            next,
        };
        Some(0.0)
    }

    fn start_hold(&mut self, level: usize, count: u32) -> Option<f32> {
        self.phase = Phase::Hold(HoldLevel {
            level,
            start: count,
            elapsed_s: 0.0,
            rest_s: 0.0,
            window: None,
        });
        Some(self.hold_duty(level))
    }

    fn hold_duty(&self, level: usize) -> f32 {
        let magnitude = self.config.hold_duty[self.rotor][level / 2];
        if level.is_multiple_of(2) {
            magnitude
        } else {
            -magnitude
        }
    }

    /// Phase 2: one standstill level.
    fn hold(&mut self, s: &IdentifySample, mut h: HoldLevel, sampled: Tick) -> Option<f32> {
        let dt = self.dt;
        let n = self.config.counts_per_rev;
        h.elapsed_s += dt;
        let travel = sampled.count.wrapping_sub(h.start) as i32;
        if travel.unsigned_abs() > n / 4 || h.elapsed_s >= HOLD_TIMEOUT_S {
            return self.end_holds();
        }
        h.rest_s = if Self::at_rest(s) { h.rest_s + dt } else { 0.0 };
        if h.window.is_none() && h.elapsed_s >= HOLD_SETTLE_S && h.rest_s >= 0.5 * REST_TIME_S {
            h.window = Some(Window::default());
        }
        if let Some(w) = &mut h.window {
            w.add(sampled, n, dt);
            if w.seconds(dt) >= HOLD_MEASURE_S - 0.5 * dt {
                let forward = h.level.is_multiple_of(2);
                let sign = if forward { 1.0 } else { -1.0 };
                self.add_voltage_row(w, sign);
                self.holds[h.level % 2] += 1;
                return if h.level + 1 < 2 * HOLD_LEVELS.len() {
                    self.start_hold(h.level + 1, sampled.count)
                } else {
                    self.end_holds()
                };
            }
        }
        self.phase = Phase::Hold(h);
        Some(self.hold_duty(h.level))
    }

    /// After the standstill levels: on to the speed levels if at least two held
    /// each way.
    fn end_holds(&mut self) -> Option<f32> {
        if self.holds.iter().all(|h| *h >= 2) {
            self.phase = Phase::Settle {
                rest_s: 0.0,
                elapsed_s: 0.0,
                next: Next::Speed,
            };
            Some(0.0)
        } else {
            self.start_coast(Some(Shortfall::NoStandstill))
        }
    }

    fn start_speed(&mut self, level: usize) -> Option<f32> {
        if level > 0 {
            if let Some(spin) = &mut self.spin {
                spin.stop_taking();
            }
        }
        self.phase = Phase::Speed {
            level,
            elapsed_s: 0.0,
            window: None,
        };
        Some(self.config.speed_duty[self.rotor][level])
    }

    /// Phase 3: one speed level.
    fn speed(
        &mut self,
        s: &IdentifySample,
        level: usize,
        elapsed_s: f32,
        window: Option<Window>,
        sampled: Tick,
    ) -> Option<f32> {
        let dt = self.dt;
        let n = self.config.counts_per_rev;
        let elapsed_s = elapsed_s + dt;
        if libm::fabsf(s.speed_rpm[self.rotor]) > self.config.max_speed_rpm {
            return self.start_coast(Some(Shortfall::TooFast));
        }
        let settle_s = self.config.settle_s[self.rotor];
        let mut window = window;
        if window.is_none() && elapsed_s >= settle_s {
            window = Some(Window::default());
        }
        if let Some(w) = &mut window {
            // The level ends at the first whole turn (from the window's start)
            // after both MIN_TURNS turns and MIN_MEASURE_S: that tick counts up
            // to it, so the eccentric's weight does no net work over the window.
            let n_f = f64::from(n);
            let next_turn = (libm::floor(w.travel / n_f) + 1.0).max(f64::from(MIN_TURNS)) * n_f;
            let d = f64::from(sampled.d_count);
            let timed = w.seconds(dt) + dt >= MIN_MEASURE_S - 0.5 * dt;
            if timed && d > 0.0 && w.travel + d >= next_turn {
                w.add_part(sampled, (next_turn - w.travel) / d, n, dt);
                let (_, _, speed) = w.means(n, dt);
                let (speed_by_angle, amps_by_angle) = w.by_angle(n);
                self.add_voltage_row(w, 1.0);
                self.speeds[self.speed_rows] = SpeedRow {
                    speed_by_angle,
                    amps_by_angle,
                    amps_std_error: w.amps_std_error(),
                    speed,
                };
                self.speed_rows += 1;
                return if level + 1 < SPEED_LEVELS.len() {
                    self.start_speed(level + 1)
                } else {
                    self.start_coast(None)
                };
            }
            w.add(sampled, n, dt);
            if w.seconds(dt) >= MAX_MEASURE_S {
                return self.start_coast(Some(Shortfall::NoSpeed));
            }
        }
        self.phase = Phase::Speed {
            level,
            elapsed_s,
            window,
        };
        Some(self.config.speed_duty[self.rotor][level])
    }

    /// A level's row of the voltage fit: its means and their errors, `sign` the
    /// current's direction (the bridge's drop follows it).
    fn add_voltage_row(&mut self, w: &Window, sign: f64) {
        let (n, dt) = (self.config.counts_per_rev, self.dt);
        let (volts, amps, speed) = w.means(n, dt);
        if let Some(row) = self.voltage.get_mut(self.voltage_rows) {
            *row = VoltageRow {
                volts,
                amps,
                speed,
                sign,
                amps_std_error: w.amps_std_error(),
                speed_std_error: w.speed_std_error(n, dt),
            };
            self.voltage_rows += 1;
        }
    }

    fn start_coast(&mut self, shortfall: Option<Shortfall>) -> Option<f32> {
        if let Some(spin) = &mut self.spin {
            spin.stop_taking();
        }
        self.phase = Phase::Coast {
            rest_s: 0.0,
            elapsed_s: 0.0,
            shortfall,
        };
        None
    }

    /// Phase 4: the bridge off until rest, then the rotor's result and the next
    /// rotor.
    fn coast(
        &mut self,
        s: &IdentifySample,
        rest_s: f32,
        elapsed_s: f32,
        shortfall: Option<Shortfall>,
    ) -> Option<f32> {
        let dt = self.dt;
        let rest_s = if libm::fabsf(s.speed_rpm[self.rotor]) <= REST_RPM {
            rest_s + dt
        } else {
            0.0
        };
        let elapsed_s = elapsed_s + dt;
        // The measurements put together a share a tick meanwhile.
        let identity = match shortfall {
            Some(why) => Some(RotorIdentity::short(why)),
            None => self.assemble_share(),
        };
        let rested = rest_s >= REST_TIME_S - 0.5 * dt || elapsed_s >= COAST_TIMEOUT_S;
        match identity {
            Some(identity) if rested => {
                self.result.rotors[self.rotor] = identity;
                self.next_rotor(s);
            }
            _ => {
                self.phase = Phase::Coast {
                    rest_s,
                    elapsed_s,
                    shortfall,
                };
            }
        }
        None
    }

    /// One tick's share of putting the rotor's measurements together
    /// ([`Assembly`]); its identity once done.
    fn assemble_share(&mut self) -> Option<RotorIdentity> {
        let snapshots = self.spin.as_ref().map_or(&[][..], |s| s.snapshots());
        self.assembly.step(&Gathered {
            voltage: &self.voltage[..self.voltage_rows],
            file_motor: self.config.motor[self.rotor],
            speeds: &self.speeds[..self.speed_rows],
            snapshots,
            levels: (self.holds[0].min(self.holds[1]), self.speed_rows as u8),
            load_torque_nm: self.config.load_torque_nm[self.rotor],
            counts_per_rev: self.config.counts_per_rev,
            dt: self.dt,
        })
    }

    /// The next rotor's settle, its measurements empty; or done after the last.
    fn next_rotor(&mut self, s: &IdentifySample) {
        self.rotor += 1;
        if self.rotor >= self.config.rotor_count.count() {
            self.phase = Phase::Done;
            return;
        }
        self.counts = Counts::default();
        self.last_count = Some(s.encoder[self.rotor]);
        self.voltage_rows = 0;
        self.assembly = Assembly::new();
        self.holds = [0; 2];
        self.speed_rows = 0;
        self.spin = None;
        self.phase = Phase::Settle {
            rest_s: 0.0,
            elapsed_s: 0.0,
            next: Next::Standstill,
        };
    }
}
