//! The motor controller of the vibro driver: a pure state machine,
//! `step(inputs, dt) -> outputs`, run at [`CONTROL_RATE_HZ`] by the firmware and in
//! lockstep by host-sim. Time is passed in, never read from a clock; there is no
//! heap and no panic on any input.
//!
//! # What it does
//!
//! Two counter-rotating unbalance rotors are run at a commanded speed while a
//! phase-lock loop holds their phase offset `theta_1 - theta_2` (docs/machine-file.md,
//! "Conventions") where the exciting force pushes the platform the commanded
//! way: the offset of the tuning table for the direction and speed
//! ([`Command::Travel`]), or an explicit one ([`Command::HoldOffset`]).
//!
//! A machine may have one rotor ([`RotorCount::One`] in [`Params::rotor_count`],
//! from its machine file): the controller then holds rotor 1's speed only, with
//! the same ramps, speed loop, states and fault checks, and no phase loop:
//! - a run command ([`Command::Travel`] or [`Command::HoldOffset`]) is accepted
//!   as on two rotors (the same checks of speed and offset), its direction or
//!   offset ignored: rotor 1 runs at the speed, and `Starting` becomes `Running`
//!   once the ramp reaches it;
//! - rotor 2 is not driven: its duty is exactly 0 in every state (the self-test
//!   included) and its bridge stays off ([`RotorCount::bridges_on`]);
//! - its encoder, index and current inputs are not read: no fault, no speed, no
//!   current of rotor 2, which reads 0 in the telemetry; the phase offset is never
//!   valid and the phase loop never closes (`PHASE_LOCK_LOST` cannot fire);
//! - the self-test tests rotor 1 only.
//!
//! Two-rotor machines run exactly as without this (every one-rotor branch is
//! taken only on [`RotorCount::One`]).
//!
//! Modules, one job each:
//! - [`io`]: inputs, commands, outputs, telemetry, states;
//! - [`params`]: parameters and the design rules of their defaults;
//! - [`machine`]: the machine's physical values mapped to [`MachineConstants`];
//! - [`encoder`]: speed from counts, angle from the index pulse, encoder checks;
//! - [`ramp`]: speed ramp (soft start, fast through the resonance band) and offset
//!   ramp (direction changes through the vertical-force offset);
//! - [`speed_loop`]: feedforward + PI per rotor, anti-windup;
//! - [`phase_loop`]: PI on the phase error, giving the rotors a speed difference;
//! - [`faults`]: the fault flags and their checks;
//! - [`tuning`]: the offset table, interpolated circularly;
//! - [`self_test`]: the first-run self-test (polarities, index, counts per turn) and
//!   its result;
//! - [`stopped`]: whether the motors are stopped for a flash write;
//! - [`angle`]: wrapping and units.
//!
//! # States
//!
//! ```text
//!   Idle --Travel/HoldOffset--> Starting --ramp done, phase loop closed--> Running
//!   Starting/Running --Stop--> Stopping --ramp at 0, rotors slow--> Idle
//!   Stopping --Travel/HoldOffset--> Starting
//!   Idle --start_self_test()--> SelfTest --done--> Idle
//!   SelfTest --Stop--> Idle (aborted)
//!   any --fault--> Fault --ResetFaults, causes gone--> Idle   (a self-test: aborted)
//! ```
//!
//! A run starts from the measured speed (0 at rest) and ramps at
//! [`Params::speed_ramp_rpm_s`], at [`Params::resonance_ramp_rpm_s`] inside
//! [`Params::resonance_band_rpm`]. The phase offset is known once both rotors have
//! shown their index pulse (the angle `theta_k` is counted from it); until then, and
//! below [`Params::phase_loop_min_rpm`], the phase loop is open and both rotors get
//! the same reference. When it closes, the offset reference starts at the measured
//! offset (no bump) and ramps to the target along the shorter arc at
//! [`Params::offset_ramp_deg_s`]; a later change of side (right to left or back,
//! while running) passes 180 degrees, the vertical force
//! ([`ramp::OffsetRamp`]). After a fault is reset the controller is idle: only a new
//! run command starts the motors again, never the reset itself.
//!
//! # Faults: safe state and detection bounds
//!
//! Every fault's safe state is the same: both H-bridges off ([`Bridge::Off`]: driver
//! disabled, windings open), written in the very tick that detects it, latched until
//! [`Command::ResetFaults`]. A reset clears only the faults whose cause is gone: the
//! E-stop released, the supply back in range, the currents back under the limit;
//! [`Faults::PARAMS`] never clears.
//!
//! Worst-case detection times, counted in the time passed in as `dt`, from the first
//! tick whose inputs show the condition (reference parameters at 1 kHz in brackets).
//! A timed condition fires at the latest in the `ceil(T/dt)`-th consecutive tick that
//! shows it, i.e. at most `T` after the first one ([`faults`]):
//!
//! | fault | condition | detected within |
//! | --- | --- | --- |
//! | `ESTOP` | E-stop input active | the same tick |
//! | `OVER_CURRENT` | `\|i\| > over_current_a` or NaN | `over_current_time_s` [2 ms] |
//! | `SUPPLY` | supply outside [min, max] or NaN | `supply_time_s` [10 ms] |
//! | `ENCODER` | count jump above `encoder_max_speed_rpm`, index off a whole turn or outside the counts travelled (the index: not in [`State::SelfTest`], which measures it) | the same tick |
//! | `ENCODER` | no index after `N + tol` counts (not in [`State::SelfTest`]) | the tick the travel passes `N + tol` [21 ms at 3000 rpm] |
//! | `ENCODER` | driven, reads slow, current low (no counts) | `t_fall + encoder_time_s` [18 + 50 ms]; any current: `t_fall + stall_time_s + encoder_time_s` |
//! | `STALL` | driven, slow, current high | `t_fall + stall_time_s` [18 + 300 ms]; any current: `t_fall + stall_time_s + encoder_time_s` |
//! | `PHASE_LOCK_LOST` | `\|phase error\| > phase_error_max_deg` while running, the error unwrapped so that slipping whole turns keeps it large | `phase_lost_time_s` [0.5 s] |
//! | `LINK_LOST` | no command or heartbeat while starting or running (a stop heads for rest on its own; idle needs no link) | `link_timeout_s` after the last one [0.5 s] |
//! | `WATCHDOG_RESET` | built with [`ResetCause::Watchdog`] | at construction |
//! | `PARAMS` | [`Params::validate`] fails | at construction |
//! | `DEADLINE` | while the motors are driven, the tick started later than `tick_late_max_s` or the previous one worked longer than `tick_busy_max_s` ([`Inputs::timing`]) | the same tick |
//!
//! `t_fall` is the time the filtered speed takes to fall from `w0` below the stall
//! speed once the counts stop: `ceil(ln(w0 / w_stall) / ln(1 + dt / tau_f))` ticks,
//! about `tau_f ln(w0 / w_stall)` [18 ticks from 3000 rpm to 100 rpm]. "Driven"
//! means `|duty| >= stall_duty` in the previous tick; the speed loop gets there
//! within a tick or two of a rotor stopping under load.
//!
//! The phase error the checks, the phase loop and the telemetry see is measured
//! against the offset reference in force over the tick just ended.
//!
//! # Odd inputs
//!
//! - `dt`: NaN, infinite or <= 0 is taken as one nominal tick; otherwise it is
//!   clamped to [0.1, 10] nominal ticks. A broken tick source is the watchdog's to
//!   catch; the controller stays defined.
//! - A NaN or infinite current is an over-current; it is left out of the current
//!   filter. A NaN supply voltage is out of range; the feedforward then uses the
//!   nominal supply.
//! - Any encoder values are accepted; inconsistent ones raise `ENCODER`.
//! - A command with a NaN, infinite or out-of-range speed or offset is refused
//!   ([`Telemetry::command_rejected`]) and changes nothing.

pub mod angle;
pub mod encoder;
pub mod faults;
pub mod io;
pub mod machine;
pub mod params;
pub mod phase_loop;
pub mod ramp;
pub mod self_test;
pub mod speed_loop;
pub mod stopped;
pub mod tuning;

pub use encoder::{EncoderAnomaly, EncoderSample, EncoderTracker, SpeedEstimator};
pub use faults::{FaultMonitor, Faults, Observation};
pub use io::{
    Bridge, Command, Direction, Inputs, Outputs, ResetCause, State, Telemetry, TickTiming,
};
pub use machine::{MachinePhysics, RotorPhysics};
pub use params::{
    FaultLimits, MachineConstants, ParamError, Params, RotorCount, RotorModel, SpeedGains,
    CONTROL_RATE_HZ,
};
pub use self_test::{RotorSelfTest, SelfTest, SelfTestReport, SelfTestStatus};
pub use stopped::{may_write_table, WRITE_MAX_SPEED_RPM};
pub use tuning::{
    RowField, TableError, TuningRow, TuningTable, DEFAULT_ROW_SPEED_RPM, MAX_TUNING_ROWS,
};

use angle::{rad_s_to_rpm, rpm_to_rad_s, wrap_deg, wrap_deg_signed, DEG_PER_RAD, TURN_DEG};
use phase_loop::PhaseLoop;
use ramp::{ramp_speed, OffsetRamp, SpeedRampRates};
use self_test::{SelfTestConfig, SelfTestRun, SelfTestSample};
use speed_loop::{SpeedLoop, SpeedLoopInput};

/// Where a run's offset comes from.
#[derive(Clone, Copy, Debug, PartialEq)]
enum OffsetSource {
    /// The tuning table's offset for this direction at the ramped speed.
    Table(Direction),
    /// A fixed offset, degrees in [0, 360).
    Fixed(f32),
}

/// What the current run command asks for.
#[derive(Clone, Copy, Debug, PartialEq)]
struct RunTarget {
    /// Rotor speed, rpm.
    speed_rpm: f32,
    /// Offset source.
    offset: OffsetSource,
}

/// One tick's measurements.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Measurement {
    /// Filtered speeds, rad/s.
    speed_rad_s: [f32; 2],
    /// Encoder inconsistencies.
    anomaly: [Option<EncoderAnomaly>; 2],
    /// Measured offset `theta_1 - theta_2`, degrees in [0, 360), once both index
    /// pulses are known.
    offset_deg: Option<f32>,
}

/// Constants of one `dt`, computed when the `dt` passed to a tick differs from the
/// previous tick's and reused while it stays the same (every tick at a steady
/// rate), so that a tick does not redo their checks and divisions.
#[derive(Clone, Copy, Debug)]
struct DtConstants {
    /// The `dt` passed to [`Controller::step`], s; NaN before the first tick (a
    /// NaN never matches, so it is always worked out).
    given_dt: f32,
    /// The usable `dt` made of it (stage 1 of [`Controller::step`]), s.
    dt: f32,
    /// [`Params::max_counts`] of `dt`.
    max_counts: f32,
    /// The current filter's `alpha = dt / (tau_i + dt)`.
    current_alpha: f32,
}

/// The tuning table's offset at one speed, kept while neither changes.
#[derive(Clone, Copy, Debug, PartialEq)]
struct TableOffset {
    /// The direction asked for.
    direction: Direction,
    /// The speed asked for (its bits: a NaN never matches), rpm.
    speed_bits: u32,
    /// [`TuningTable::offset`] of both, degrees.
    offset_deg: f32,
}

/// `[f(a[0]), f(a[1])]`: `<[T; 2]>::map` written out. The array method goes
/// through a generic loop that `opt-level = "s"` leaves in place (with its stack
/// copies); this is straight-line code for the rotor pairs of a tick.
#[inline(always)]
fn map2<T: Copy, U>(a: [T; 2], f: impl Fn(T) -> U) -> [U; 2] {
    [f(a[0]), f(a[1])]
}

/// The vibro driver's motor controller. See the module documentation.
#[derive(Clone, Debug)]
pub struct Controller {
    /// The parameters in use (the reference ones if those given were invalid).
    params: Params,
    /// The nominal tick, [`Params::tick_s`], s (computed once: the parameters other
    /// than the tuning table never change).
    tick_s: f32,
    /// Degrees per encoder count, `360 / N` (computed once).
    deg_per_count: f32,
    /// [`Params::phase_trim_max_rpm`] in rad/s (computed once).
    phase_trim_max_rad_s: f32,
    /// The machine has one rotor ([`RotorCount::One`]): rotor 2 is neither read
    /// nor driven (computed once).
    one_rotor: bool,
    /// The constants of the last tick's `dt`, recomputed when `dt` changes.
    dt_constants: DtConstants,
    /// The last table offset looked up, cleared when the table changes
    /// ([`Controller::set_tuning`]): while the speed reference stays put (running
    /// at the commanded speed) the table is not interpolated again every tick.
    table_offset: Option<TableOffset>,
    /// Why the given parameters were refused.
    params_error: Option<ParamError>,
    /// Current state.
    state: State,
    /// Latched faults.
    faults: Faults,
    /// Encoder tracking, per rotor.
    encoders: [EncoderTracker; 2],
    /// Filtered currents, A.
    current_filtered: [f32; 2],
    /// Fault timers.
    monitor: FaultMonitor,
    /// Time since the last command or heartbeat, s.
    link_age_s: f32,
    /// Ticks that missed their deadline since the start (saturating).
    overruns: u16,
    /// The run command in force (starting, running).
    target: Option<RunTarget>,
    /// The ramped speed reference, rpm.
    ramp_rpm: f32,
    /// The offset reference.
    offset: OffsetRamp,
    /// Whether the phase loop is closed.
    phase_closed: bool,
    /// The phase error unwrapped since the loop closed (the sum of its wrapped
    /// tick-to-tick changes), degrees, with the last wrapped error.
    phase_error_unwrapped: Option<(f32, f32)>,
    /// Phase loop state.
    phase_loop: PhaseLoop,
    /// Speed loop states.
    speed_loops: [SpeedLoop; 2],
    /// Time since a stop's ramp reached 0, s.
    stop_elapsed_s: f32,
    /// Duties written in the previous tick.
    last_duty: [f32; 2],
    /// Filtered speeds of the previous tick, rpm (whether a self-test may start).
    last_speed_rpm: [f32; 2],
    /// The self-test in progress ([`State::SelfTest`]).
    self_test: Option<SelfTestRun>,
    /// The last self-test's status and result (not run: all zero).
    self_test_status: SelfTestStatus,
    self_test_result: SelfTest,
}

impl Controller {
    /// A controller at rest: [`State::Idle`] after a power-on, [`State::Fault`] with
    /// [`Faults::WATCHDOG_RESET`] after a watchdog reset. Invalid `params` are
    /// replaced by [`Params::reference`] and latch [`Faults::PARAMS`], which never
    /// clears ([`Controller::params_error`] says why).
    pub fn new(params: &Params, reset: ResetCause) -> Self {
        let (params, params_error) = match params.validate() {
            Ok(()) => (params.clone(), None),
            Err(e) => (Params::reference(), Some(e)),
        };
        let mut faults = Faults::NONE;
        if params_error.is_some() {
            faults |= Faults::PARAMS;
        }
        if reset == ResetCause::Watchdog {
            faults |= Faults::WATCHDOG_RESET;
        }
        let encoder = EncoderTracker::new(
            params.encoder_counts,
            params.limits.index_tolerance_counts,
            params.speed_filter_tau_s,
        );
        Controller {
            state: if faults.is_empty() {
                State::Idle
            } else {
                State::Fault
            },
            faults,
            params_error,
            encoders: [encoder; 2],
            current_filtered: [0.0; 2],
            monitor: FaultMonitor::new(),
            link_age_s: 0.0,
            overruns: 0,
            target: None,
            ramp_rpm: 0.0,
            offset: OffsetRamp::new(ramp::VERTICAL_OFFSET_DEG),
            phase_closed: false,
            phase_error_unwrapped: None,
            phase_loop: PhaseLoop::new(),
            speed_loops: [SpeedLoop::new(); 2],
            stop_elapsed_s: 0.0,
            last_duty: [0.0; 2],
            last_speed_rpm: [0.0; 2],
            self_test: None,
            self_test_status: SelfTestStatus::NotRun,
            self_test_result: SelfTest::default(),
            tick_s: params.tick_s(),
            deg_per_count: TURN_DEG / params.encoder_counts as f32,
            phase_trim_max_rad_s: rpm_to_rad_s(params.phase_trim_max_rpm),
            one_rotor: params.rotor_count == RotorCount::One,
            dt_constants: DtConstants {
                given_dt: f32::NAN,
                dt: 0.0,
                max_counts: 0.0,
                current_alpha: 0.0,
            },
            table_offset: None,
            params,
        }
    }

    /// The parameters in use.
    pub fn params(&self) -> &Params {
        &self.params
    }

    /// Why the parameters given to [`Controller::new`] were refused, if they were.
    pub fn params_error(&self) -> Option<ParamError> {
        self.params_error
    }

    /// Use `table` from now on (a table written over the link and stored). Only
    /// with the motors off ([`State::Idle`] or [`State::Fault`]): a running
    /// machine keeps its table, and `false` says the table was not taken.
    pub fn set_tuning(&mut self, table: TuningTable) -> bool {
        if matches!(self.state, State::Idle | State::Fault) {
            self.params.tuning = table;
            self.table_offset = None;
            true
        } else {
            false
        }
    }

    /// Start the first-run self-test ([`self_test`]): only from [`State::Idle`]
    /// with no fault latched and both rotors at rest (the last tick's speeds within
    /// [`self_test::REST_RPM`]); `false` says it did not start and changes nothing.
    /// The state is [`State::SelfTest`] until it finishes ([`State::Idle`], status
    /// `Done`) or is aborted by a fault ([`State::Fault`]) or [`Command::Stop`]
    /// ([`State::Idle`]), both with status `Aborted`.
    pub fn start_self_test(&mut self) -> bool {
        let at_rest = self
            .last_speed_rpm
            .iter()
            .all(|w| libm::fabsf(*w) <= self_test::REST_RPM);
        if self.state != State::Idle || !self.faults.is_empty() || !at_rest {
            return false;
        }
        self.stop_run();
        self.self_test = Some(SelfTestRun::new(SelfTestConfig::from_params(&self.params)));
        self.self_test_status = SelfTestStatus::Running;
        self.self_test_result = SelfTest::default();
        self.state = State::SelfTest;
        true
    }

    /// The self-test's status and result: `NotRun` (all zero) until one is started
    /// on this controller, then `Running` with what it has measured so far, then
    /// `Done` or `Aborted` with its measurements.
    pub fn self_test_report(&self) -> SelfTestReport {
        let result = match (&self.self_test, self.self_test_status) {
            (Some(run), SelfTestStatus::Running) => run.result(),
            _ => self.self_test_result,
        };
        SelfTestReport {
            status: self.self_test_status,
            result,
        }
    }

    /// End the self-test in progress, if one is, with `status`.
    fn end_self_test(&mut self, status: SelfTestStatus) {
        if let Some(mut run) = self.self_test.take() {
            run.abort();
            self.self_test_result = run.result();
            self.self_test_status = status;
        }
    }

    /// The current state.
    pub fn state(&self) -> State {
        self.state
    }

    /// The latched faults.
    pub fn faults(&self) -> Faults {
        self.faults
    }

    /// One control tick: `inputs` sampled now, `dt` s since the previous tick.
    ///
    /// Stages, in order:
    /// 1. **Time**: `dt` made usable (module documentation, "Odd inputs").
    /// 2. **Measure**: encoder speeds, index checks, the measured phase offset and
    ///    its error against the offset reference in force over the last tick;
    ///    current filter; link age.
    /// 3. **Check faults** on those measurements and the previous tick's duties;
    ///    new faults are latched and the state becomes [`State::Fault`].
    /// 4. **Command**: this tick's command moves the state machine
    ///    ([`Command::ResetFaults`] clears what it may, [`Command::Stop`] aborts a
    ///    self-test); in [`State::SelfTest`] the self-test then steps and gives
    ///    the duties (or ends: [`State::Idle`]).
    /// 5. **References**: the speed ramp; the phase loop opens or closes; the
    ///    offset reference ramps; starting becomes running, a finished stop idle.
    /// 6. **Phase loop**: the speed difference that corrects the phase error, split
    ///    between the rotors' speed references.
    /// 7. **Speed loops**: feedforward + PI to duties (the self-test's duties in
    ///    [`State::SelfTest`]).
    /// 8. **Output**, built afresh: with any fault latched, or idle, the safe state
    ///    (every bridge off) overrides whatever the loops computed.
    pub fn step(&mut self, inputs: &Inputs, dt: f32) -> Outputs {
        // 1. Time.
        if self.dt_constants.given_dt != dt {
            let tick = self.tick_s;
            let usable = if dt.is_finite() && dt > 0.0 {
                dt.clamp(0.1 * tick, 10.0 * tick)
            } else {
                tick
            };
            let p = &self.params;
            self.dt_constants = DtConstants {
                given_dt: dt,
                dt: usable,
                max_counts: p.max_counts(usable),
                current_alpha: usable / (p.current_filter_tau_s + usable),
            };
        }
        let dt = self.dt_constants.dt;

        // One rotor: rotor 2's inputs are not read; every stage sees it at rest
        // (its counter standing at 0, no index pulse, no current), so none of them
        // needs its own exception.
        let one_rotor_inputs;
        let inputs = if self.one_rotor {
            one_rotor_inputs = Inputs {
                encoder: [inputs.encoder[0], 0],
                index: [inputs.index[0], None],
                current: [inputs.current[0], 0.0],
                ..*inputs
            };
            &one_rotor_inputs
        } else {
            inputs
        };

        // 2. Measure.
        let m = self.measure(inputs, dt);
        let phase_error_deg = match (self.phase_closed, m.offset_deg) {
            (true, Some(o)) => Some(wrap_deg_signed(self.offset.reference_deg() - o)),
            _ => None,
        };
        // Unwrapped for the lock check: a rotor slipping whole turns would otherwise
        // bring the wrapped error back through 0 every turn and restart the timer.
        self.phase_error_unwrapped = phase_error_deg.map(|e| match self.phase_error_unwrapped {
            Some((sum, last)) => (sum + wrap_deg_signed(e - last), e),
            None => (e, e),
        });
        self.link_age_s = if inputs.command.is_some() {
            0.0
        } else {
            self.link_age_s + dt
        };

        // 3. Check faults.
        // The self-test measures the index itself: only count jumps are faults.
        let testing = self.state == State::SelfTest;
        let encoder_anomaly = map2(m.anomaly, |a| match a {
            Some(EncoderAnomaly::IndexMisplaced | EncoderAnomaly::IndexMissing) if testing => None,
            other => other,
        });
        let current = inputs.current;
        let obs = Observation {
            state: self.state,
            duty: self.last_duty,
            speed_rpm: map2(m.speed_rad_s, rad_s_to_rpm),
            current,
            current_filtered: self.current_filtered,
            encoder_anomaly,
            phase_error_deg: self.phase_error_unwrapped.map(|(sum, _)| sum),
            supply_voltage: inputs.supply_voltage,
            estop: inputs.estop,
            link_age_s: self.link_age_s,
            deadline_missed: FaultMonitor::missed_deadline(inputs.timing, &self.params.limits),
        };
        let found = self.monitor.check(&obs, &self.params.limits, dt);
        if obs.deadline_missed {
            self.overruns = self.overruns.saturating_add(1);
        }
        if !found.is_empty() {
            self.latch(found);
        }

        // 4. Command.
        let rejected = self.command(inputs.command, &obs, &m, found);
        self.last_speed_rpm = obs.speed_rpm;

        // 4b. Self-test: its duties, or its end.
        let mut test_duty = [0.0; 2];
        if self.state == State::SelfTest {
            if let Some(run) = self.self_test.as_mut() {
                let step = run.step(
                    &SelfTestSample {
                        encoder: inputs.encoder,
                        index: inputs.index,
                        current,
                        speed_rpm: obs.speed_rpm,
                    },
                    dt,
                );
                test_duty = step.duty;
                if step.done {
                    self.end_self_test(SelfTestStatus::Done);
                    self.state = State::Idle;
                }
            } else {
                self.state = State::Idle;
            }
        }

        // 5. References.
        let (accel_rpm_s, offset_rate_deg_s) = self.references(&m, dt);

        // 6. Phase loop: dw = w1 - w2, rad/s.
        let p = &self.params;
        let ramp_rad_s = rpm_to_rad_s(self.ramp_rpm);
        let dw = match (self.phase_closed, phase_error_deg) {
            (true, Some(e)) => {
                // min(trim_max, fraction x max(ramp, 0)), written out: `f32::min`
                // and `max` are library calls on the Cortex-M4F. The ramp is
                // finite; a NaN would give 0 as `max` does.
                let ramp_pos = if ramp_rad_s > 0.0 { ramp_rad_s } else { 0.0 };
                let fraction = p.phase_trim_fraction * ramp_pos;
                let limit = if fraction < self.phase_trim_max_rad_s {
                    fraction
                } else {
                    self.phase_trim_max_rad_s
                };
                self.phase_loop.update(
                    e / DEG_PER_RAD,
                    offset_rate_deg_s / DEG_PER_RAD,
                    p.phase_kp,
                    p.phase_ki,
                    limit,
                    dt,
                )
            }
            _ => {
                self.phase_loop.reset();
                0.0
            }
        };
        let speed_ref = [ramp_rad_s + 0.5 * dw, ramp_rad_s - 0.5 * dw];

        // 7. Speed loops.
        let supply_v = if inputs.supply_voltage.is_finite()
            && inputs.supply_voltage >= 0.5 * p.supply_nominal_v
        {
            inputs.supply_voltage
        } else {
            p.supply_nominal_v
        };
        let mut duty = [0.0; 2];
        if self.state == State::SelfTest {
            duty = test_duty;
            self.speed_loops.iter_mut().for_each(SpeedLoop::reset);
        } else if self.state.drives() {
            let accel_ref_rad_s2 = rpm_to_rad_s(accel_rpm_s);
            let update = |k: usize, speed_loop: &mut SpeedLoop| {
                let input = SpeedLoopInput {
                    speed_ref_rad_s: speed_ref[k],
                    accel_ref_rad_s2,
                    speed_rad_s: m.speed_rad_s[k],
                    supply_v,
                };
                speed_loop.update(&input, &p.speed_gains[k], &p.rotors[k], p.min_duty, dt)
            };
            let [loop1, loop2] = &mut self.speed_loops;
            duty = if self.one_rotor {
                // Rotor 2 is not driven: exactly 0.
                [update(0, loop1), 0.0]
            } else {
                [update(0, loop1), update(1, loop2)]
            };
        } else {
            self.speed_loops.iter_mut().for_each(SpeedLoop::reset);
        }

        // 8. Output, with the safe-state override.
        let enable = self.state.drives() && self.faults.is_empty();
        let duty = if enable {
            map2(duty, |d| {
                // In range already (the loops' duties are): as it is; otherwise
                // clamped, and 0 if not finite.
                if libm::fabsf(d) <= 1.0 {
                    d
                } else if d.is_finite() {
                    d.clamp(-1.0, 1.0)
                } else {
                    0.0
                }
            })
        } else {
            [0.0; 2]
        };
        self.last_duty = duty;
        let driving = self.state.drives();
        let on = self.params.rotor_count.bridges_on(enable);
        Outputs {
            bridges: [
                Bridge::driven_if(on[0], duty[0]),
                Bridge::driven_if(on[1], duty[1]),
            ],
            state: self.state,
            faults: self.faults,
            telemetry: Telemetry {
                speed_rpm: obs.speed_rpm,
                speed_ref_rpm: if !driving {
                    [0.0; 2]
                } else if self.one_rotor {
                    [rad_s_to_rpm(speed_ref[0]), 0.0]
                } else {
                    map2(speed_ref, rad_s_to_rpm)
                },
                phase_valid: m.offset_deg.is_some(),
                phase_offset_deg: m.offset_deg.unwrap_or(0.0),
                phase_loop_closed: self.phase_closed,
                commanded_offset_deg: self.offset.reference_deg(),
                target_offset_deg: self.offset.target_deg(),
                phase_error_deg: if self.phase_closed {
                    phase_error_deg.unwrap_or(0.0)
                } else {
                    0.0
                },
                current,
                supply_voltage: inputs.supply_voltage,
                duty,
                command_rejected: rejected,
                tick_late_us: saturating_us(inputs.timing.late_s),
                tick_busy_us: saturating_us(inputs.timing.busy_s),
                overruns: self.overruns,
            },
        }
    }

    /// Stage 2: encoders, phase offset, current filter.
    fn measure(&mut self, inputs: &Inputs, dt: f32) -> Measurement {
        let p = &self.params;
        let max_counts = self.dt_constants.max_counts;
        let [e1, e2] = &mut self.encoders;
        let s1 = e1.update(inputs.encoder[0], inputs.index[0], dt, max_counts);
        let s2 = e2.update(inputs.encoder[1], inputs.index[1], dt, max_counts);
        let s = [s1, s2];
        let speed_rad_s = map2(s, |s| s.speed_rad_s);
        let anomaly = map2(s, |s| s.anomaly);
        let angle = map2(s, |s| s.angle_counts);

        // theta_1 - theta_2 from the angles since the index, exact in counts:
        //   offset = 360 ((a1 - a2) mod N) / N   degrees.
        // Both angles are in [0, N), so `a1 - a2` is in (-N, N) and the `mod N` is
        // one addition of N to a negative difference (in 32 bits: N <= 2^24).
        let offset_deg = match angle {
            [Some(a1), Some(a2)] => {
                let d = if a1 >= a2 {
                    a1 - a2
                } else {
                    a1 + p.encoder_counts - a2
                };
                Some(wrap_deg(d as f32 * self.deg_per_count))
            }
            _ => None,
        };

        // Currents: first-order low-pass, non-finite samples skipped;
        //   alpha = dt / (tau_i + dt)   (cached with dt).
        let alpha = self.dt_constants.current_alpha;
        let filter = |filtered: &mut f32, i: f32| {
            if i.is_finite() {
                *filtered += alpha * (i - *filtered);
            }
        };
        let [i1, i2] = &mut self.current_filtered;
        filter(i1, inputs.current[0]);
        filter(i2, inputs.current[1]);

        Measurement {
            speed_rad_s,
            anomaly,
            offset_deg,
        }
    }

    /// Latch `found`: motors off, references and loops back to rest.
    fn latch(&mut self, found: Faults) {
        self.end_self_test(SelfTestStatus::Aborted);
        self.faults |= found;
        self.state = State::Fault;
        self.stop_run();
    }

    /// Forget the run: no target, ramps and loops at rest, phase loop open.
    fn stop_run(&mut self) {
        self.target = None;
        self.ramp_rpm = 0.0;
        self.phase_closed = false;
        self.phase_loop.reset();
        self.speed_loops.iter_mut().for_each(SpeedLoop::reset);
        self.stop_elapsed_s = 0.0;
    }

    /// Stage 4: apply this tick's command; true if it was refused. `found`: the
    /// faults detected in this very tick, which a reset in the same tick leaves
    /// latched so that they are reported at least once.
    fn command(
        &mut self,
        command: Option<Command>,
        obs: &Observation,
        m: &Measurement,
        found: Faults,
    ) -> bool {
        match command {
            None | Some(Command::Heartbeat) => false,
            Some(Command::ResetFaults) => {
                if self.state == State::Fault {
                    let keep =
                        FaultMonitor::present(obs, &self.params.limits) | Faults::PARAMS | found;
                    self.faults = Faults::from_bits(self.faults.bits() & keep.bits());
                    if self.faults.is_empty() {
                        self.state = State::Idle;
                        self.monitor.clear();
                        self.stop_run();
                    }
                }
                false
            }
            Some(Command::Stop) => {
                if self.state == State::SelfTest {
                    self.end_self_test(SelfTestStatus::Aborted);
                    self.state = State::Idle;
                } else if matches!(self.state, State::Starting | State::Running) {
                    self.state = State::Stopping;
                    self.stop_elapsed_s = 0.0;
                }
                false
            }
            Some(Command::Travel {
                direction,
                speed_rpm,
            }) => self.run(speed_rpm, OffsetSource::Table(direction), m),
            Some(Command::HoldOffset {
                speed_rpm,
                offset_deg,
            }) => {
                if offset_deg.is_finite() {
                    self.run(speed_rpm, OffsetSource::Fixed(wrap_deg(offset_deg)), m)
                } else {
                    true
                }
            }
        }
    }

    /// A run command: refused in a fault or out of the speed range; otherwise it
    /// sets the target and starts from idle or a stop.
    fn run(&mut self, speed_rpm: f32, offset: OffsetSource, m: &Measurement) -> bool {
        let p = &self.params;
        if matches!(self.state, State::Fault | State::SelfTest)
            || !(speed_rpm >= p.min_speed_rpm && speed_rpm <= p.max_speed_rpm)
        {
            return true;
        }
        if self.state == State::Idle {
            // Start from the speed the rotors have (0 at rest, more if coasting).
            self.stop_run();
            let max = self.params.max_speed_rpm;
            let mean = if self.one_rotor {
                rad_s_to_rpm(m.speed_rad_s[0])
            } else {
                rad_s_to_rpm(0.5 * (m.speed_rad_s[0] + m.speed_rad_s[1]))
            };
            self.ramp_rpm = if mean.is_finite() {
                mean.clamp(0.0, max)
            } else {
                0.0
            };
        }
        self.target = Some(RunTarget { speed_rpm, offset });
        if self.state != State::Running {
            self.state = State::Starting;
        }
        if self.phase_closed {
            let to = self.target_offset();
            self.offset.command(to);
        }
        false
    }

    /// The offset the current target asks for at the ramped speed, degrees.
    fn target_offset(&mut self) -> f32 {
        match self.target.map(|t| t.offset) {
            Some(OffsetSource::Table(direction)) => {
                let speed_bits = self.ramp_rpm.to_bits();
                match self.table_offset {
                    Some(c) if c.direction == direction && c.speed_bits == speed_bits => {
                        c.offset_deg
                    }
                    _ => {
                        let offset_deg = self.params.tuning.offset(direction, self.ramp_rpm);
                        self.table_offset = Some(TableOffset {
                            direction,
                            speed_bits,
                            offset_deg,
                        });
                        offset_deg
                    }
                }
            }
            Some(OffsetSource::Fixed(o)) => o,
            None => self.offset.target_deg(),
        }
    }

    /// Stage 5: ramp the speed and the offset, open or close the phase loop, move
    /// between states. Returns the speed reference's acceleration (rpm/s) and the
    /// offset reference's rate (degrees/s).
    fn references(&mut self, m: &Measurement, dt: f32) -> (f32, f32) {
        let p = &self.params;
        let target_rpm = match (self.state, self.target) {
            (State::Starting | State::Running, Some(t)) => t.speed_rpm,
            (State::Stopping, _) => 0.0,
            _ => {
                self.ramp_rpm = 0.0;
                self.phase_closed = false;
                return (0.0, 0.0);
            }
        };

        // Speed ramp.
        let rates = SpeedRampRates {
            normal_rpm_s: p.speed_ramp_rpm_s,
            resonance_rpm_s: p.resonance_ramp_rpm_s,
            band_rpm: p.resonance_band_rpm,
        };
        let (ramp, accel) = ramp_speed(self.ramp_rpm, target_rpm, &rates, dt);
        self.ramp_rpm = ramp;
        let offset_step_deg = p.offset_ramp_deg_s * dt;
        let stop_speed_rpm = p.stop_speed_rpm;
        let stop_timeout_s = p.stop_timeout_s;

        // Phase loop open or closed: closed with both angles known above its speed.
        let can_close = m.offset_deg.is_some() && self.ramp_rpm >= p.phase_loop_min_rpm;
        if can_close && !self.phase_closed {
            self.phase_closed = true;
            self.phase_loop.reset();
            // From the measured offset along the shorter arc: at closing the
            // rotors are slow (the loop closes at `phase_loop_min_rpm`) and the
            // platform barely excited, so the through-180 rule of direction
            // changes would only delay a start to the left by half a turn.
            self.offset = OffsetRamp::new(m.offset_deg.unwrap_or(0.0));
            let to = self.target_offset();
            self.offset.follow(to);
        } else if !can_close && self.phase_closed {
            self.phase_closed = false;
            self.phase_loop.reset();
        }

        // Offset ramp; the table's offset follows the ramped speed.
        let mut offset_rate = 0.0;
        if self.phase_closed {
            if self.state != State::Stopping {
                let to = self.target_offset();
                self.offset.follow(to);
            }
            let moved = self.offset.step(offset_step_deg);
            offset_rate = moved / dt;
        }

        // State changes.
        match self.state {
            // One rotor: no phase loop to wait for.
            State::Starting
                if self.ramp_rpm == target_rpm && (self.phase_closed || self.one_rotor) =>
            {
                self.state = State::Running;
            }
            State::Stopping if self.ramp_rpm == 0.0 => {
                self.stop_elapsed_s += dt;
                let slow = m
                    .speed_rad_s
                    .iter()
                    .all(|w| libm::fabsf(rad_s_to_rpm(*w)) < stop_speed_rpm);
                if slow || self.stop_elapsed_s >= stop_timeout_s {
                    self.state = State::Idle;
                    self.stop_run();
                }
            }
            _ => {}
        }
        (accel, offset_rate)
    }
}

/// `s` seconds in whole microseconds, saturating at `u16::MAX` (NaN and negative
/// values give 0).
fn saturating_us(s: f32) -> u16 {
    // A float-to-integer `as` saturates, and takes NaN to 0.
    (s * 1e6) as u16
}
