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
//! - `io`: inputs, commands, outputs, telemetry, states;
//! - `mode`: the state with the data only it uses (a run's command, ramp and
//!   loops; the self-test in progress; the latched faults);
//! - `params`: parameters and the design rules of their defaults;
//! - `machine`: the machine's physical values mapped to [`MachineConstants`];
//! - `encoder`: speed from counts, angle from the index pulse, encoder checks;
//! - [`ramp`]: speed ramp (soft start, fast through the resonance band) and offset
//!   ramp (direction changes through the vertical-force offset);
//! - [`speed_loop`]: feedforward + PI per rotor, anti-windup;
//! - [`phase_loop`]: PI on the phase error, giving the rotors a speed difference;
//! - `faults`: the fault flags and their checks;
//! - `tuning`: the offset table, interpolated circularly;
//! - [`self_test`]: the first-run self-test (polarities, index, counts per turn) and
//!   its result;
//! - [`identify`]: the motor identification (resistance, torque constant,
//!   friction, inertia) and its result;
//! - `stopped`: whether the motors are stopped for a flash write;
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
//!   Idle --start_identify()--> Identify --done--> Idle
//!   Identify --Stop--> Idle (aborted)
//!   any --fault--> Fault --ResetFaults, causes gone--> Idle   (a self-test or an
//!                                                              identification: aborted)
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
//! shows it, i.e. at most `T` after the first one (`faults`):
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
mod encoder;
mod faults;
pub mod identify;
mod io;
mod machine;
mod mode;
mod params;
pub mod phase_loop;
pub mod ramp;
pub mod self_test;
pub mod speed_loop;
mod stopped;
mod tuning;

pub use encoder::{EncoderAnomaly, EncoderSample, EncoderTracker, SpeedEstimator};
pub use faults::{FaultMonitor, Faults, Observation};
pub use io::{
    Bridge, Command, Direction, Inputs, Outputs, ResetCause, State, Telemetry, TickTiming,
};
pub use machine::{lift_off_speed_rad_s, resonance_band_rpm, MachinePhysics, RotorPhysics};
pub use params::{
    FaultLimits, MachineConstants, ParamError, Params, RotorCount, RotorModel, SpeedGains,
    CONTROL_RATE_HZ,
};
pub use stopped::{may_write_table, WRITE_MAX_SPEED_RPM};
pub use tuning::{
    RowField, TableError, TuningRow, TuningTable, DEFAULT_ROW_SPEED_RPM, MAX_TUNING_ROWS,
};

use angle::{rad_s_to_rpm, rpm_to_rad_s, wrap_deg, wrap_deg_signed, DEG_PER_RAD, TURN_DEG};
use identify::{
    IdentifyConfig, IdentifyProgress, IdentifyReport, IdentifyRun, IdentifySample, IdentifyStatus,
    Identity,
};
use mode::{Mode, OffsetSource, PhaseLock, Run, RunTarget, UnwrappedError};
use phase_loop::PhaseLoop;
use ramp::{ramp_speed, OffsetRamp, SpeedRampRates};
use self_test::{
    SelfTest, SelfTestConfig, SelfTestReport, SelfTestRun, SelfTestSample, SelfTestStatus,
};
use speed_loop::{SpeedLoop, SpeedLoopInput};

/// One tick's measurements.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Measurement {
    /// The state they were taken in (before this tick's command).
    state: State,
    /// Filtered speeds, rad/s.
    speed_rad_s: [f32; 2],
    /// The same in rpm.
    speed_rpm: [f32; 2],
    /// Encoder inconsistencies.
    anomaly: [Option<EncoderAnomaly>; 2],
    /// Measured offset `theta_1 - theta_2`, degrees in [0, 360), once both index
    /// pulses are known.
    offset_deg: Option<f32>,
    /// The phase error, while the phase loop is closed and the offset measured.
    phase_error: Option<PhaseError>,
}

/// The phase error of one tick, measured while the phase loop is closed: the offset
/// reference in force over the tick just ended minus the measured offset.
#[derive(Clone, Copy, Debug, PartialEq)]
struct PhaseError {
    /// Wrapped, degrees in (-180, 180]: what the phase loop corrects and the
    /// telemetry reports.
    wrapped_deg: f32,
    /// Unwrapped since the loop closed, degrees: what the lock check judges.
    unwrapped_deg: f32,
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

/// The phase offset `run` asks for at its ramped speed, degrees: the tuning table's
/// for its direction, or its fixed offset. `last` keeps the table's last answer:
/// while the speed reference stays put (running at the commanded speed) the table
/// is not interpolated again every tick.
fn target_offset(run: &Run, tuning: &TuningTable, last: &mut Option<TableOffset>) -> f32 {
    match run.target.offset {
        OffsetSource::Table(direction) => {
            let speed_bits = run.ramp_rpm.to_bits();
            match *last {
                Some(c) if c.direction == direction && c.speed_bits == speed_bits => c.offset_deg,
                _ => {
                    let offset_deg = tuning.offset(direction, run.ramp_rpm);
                    *last = Some(TableOffset {
                        direction,
                        speed_bits,
                        offset_deg,
                    });
                    offset_deg
                }
            }
        }
        OffsetSource::Fixed(o) => o,
    }
}

/// `[f(a[0]), f(a[1])]`: `<[T; 2]>::map` written out. The array method goes
/// through a generic loop that `opt-level = "s"` leaves in place (with its stack
/// copies); this is straight-line code for the rotor pairs of a tick.
#[inline(always)]
fn map2<T: Copy, U>(a: [T; 2], f: impl Fn(T) -> U) -> [U; 2] {
    [f(a[0]), f(a[1])]
}

/// The vibro driver's motor controller. See the module documentation.
///
/// `repr(C)`: its fields in the order written, the identification's working
/// memory last, so that what the tick uses stays within the short offsets of
/// the FPU's loads and stores (in Rust's own order the step while driving is
/// about 10 % dearer, benchmarks/firmware.md).
#[derive(Clone, Debug)]
#[repr(C)]
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
    /// The speed ramp's rates and band, from the parameters (gathered once).
    speed_rates: SpeedRampRates,
    /// The machine has one rotor ([`RotorCount::One`]): rotor 2 is neither read
    /// nor driven (computed once).
    one_rotor: bool,
    /// The constants of the last tick's `dt`, recomputed when `dt` changes.
    dt_constants: DtConstants,
    /// The last table offset looked up ([`target_offset`]), cleared when the table
    /// changes ([`Controller::set_tuning`]).
    table_offset: Option<TableOffset>,
    /// Why the given parameters were refused.
    params_error: Option<ParamError>,
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
    /// The offset reference the phase loop follows: set to the measured offset when
    /// the loop closes, ramped while it is closed. Outside a run it stays where the
    /// last one left it, as the telemetry reports it in every state.
    offset: OffsetRamp,
    /// Duties written in the previous tick.
    last_duty: [f32; 2],
    /// The report of the last self-test that ended, `Done` or `Aborted` (`NotRun`,
    /// all zero: none has run on this controller).
    last_self_test: SelfTestReport,
    /// The report of the last identification that ended, as the self-test's.
    last_identify: IdentifyReport,
    /// Identifications started (wrapping), for [`IdentifyProgress::run`].
    identify_runs: u16,
    /// The state, with the data only it uses: a run's command, speed ramp and
    /// loops; the self-test in progress; the latched faults.
    mode: Mode,
    /// The identification's working memory (its fits' sums, the spin-up's
    /// turns: 1.6 KB), meaningful in [`Mode::Identify`] only, where it is
    /// started afresh. Kept apart from the mode and last, so that the mode and
    /// the fields the tick uses stay within the short offsets of the FPU's loads
    /// and stores (a mode holding it made every tick 20 to 40 instructions
    /// dearer: benchmarks/firmware.md).
    identify_run: IdentifyRun,
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
            mode: if faults.is_empty() {
                Mode::Idle
            } else {
                Mode::Fault(faults)
            },
            params_error,
            encoders: [encoder; 2],
            current_filtered: [0.0; 2],
            monitor: FaultMonitor::new(),
            link_age_s: 0.0,
            overruns: 0,
            offset: OffsetRamp::new(ramp::VERTICAL_OFFSET_DEG),
            last_duty: [0.0; 2],
            last_self_test: SelfTestReport {
                status: SelfTestStatus::NotRun,
                result: SelfTest::default(),
            },
            last_identify: IdentifyReport {
                status: IdentifyStatus::NotRun,
                identity: Identity::default(),
            },
            identify_runs: 0,
            tick_s: params.tick_s(),
            deg_per_count: TURN_DEG / params.encoder_counts as f32,
            phase_trim_max_rad_s: rpm_to_rad_s(params.phase_trim_max_rpm),
            speed_rates: SpeedRampRates {
                normal_rpm_s: params.speed_ramp_rpm_s,
                resonance_rpm_s: params.resonance_ramp_rpm_s,
                band_rpm: params.resonance_band_rpm,
            },
            one_rotor: params.rotor_count == RotorCount::One,
            dt_constants: DtConstants {
                given_dt: f32::NAN,
                dt: 0.0,
                max_counts: 0.0,
                current_alpha: 0.0,
            },
            table_offset: None,
            identify_run: IdentifyRun::new(IdentifyConfig::from_params(&params)),
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
        if matches!(self.mode, Mode::Idle | Mode::Fault(_)) {
            self.params.tuning = table;
            self.table_offset = None;
            true
        } else {
            false
        }
    }

    /// Start the first-run self-test ([`self_test`]): only from [`State::Idle`]
    /// (no fault latched) with both rotors at rest (the last tick's speeds within
    /// [`self_test::REST_RPM`]); `false` says it did not start and changes nothing.
    /// The state is [`State::SelfTest`] until it finishes ([`State::Idle`], status
    /// `Done`) or is aborted by a fault ([`State::Fault`]) or [`Command::Stop`]
    /// ([`State::Idle`]), both with status `Aborted`.
    pub fn start_self_test(&mut self) -> bool {
        // The speeds the last tick measured.
        let at_rest = self
            .encoders
            .iter()
            .all(|e| libm::fabsf(rad_s_to_rpm(e.speed_rad_s())) <= self_test::REST_RPM);
        if !matches!(self.mode, Mode::Idle) || !at_rest {
            return false;
        }
        self.mode = Mode::SelfTest(SelfTestRun::new(SelfTestConfig::from_params(&self.params)));
        true
    }

    /// The self-test's status and result: `NotRun` (all zero) until one is started
    /// on this controller, then `Running` with what it has measured so far, then
    /// `Done` or `Aborted` with its measurements.
    pub fn self_test_report(&self) -> SelfTestReport {
        match &self.mode {
            Mode::SelfTest(run) => SelfTestReport {
                status: SelfTestStatus::Running,
                result: run.result(),
            },
            _ => self.last_self_test,
        }
    }

    /// Start the motor identification ([`identify`]): only from [`State::Idle`]
    /// (no fault latched) with both rotors at rest (the last tick's speeds within
    /// [`identify::REST_RPM`]); `false` says it did not start and changes nothing.
    /// The state is [`State::Identify`] until it finishes ([`State::Idle`], status
    /// `Done`) or is aborted by a fault ([`State::Fault`]) or [`Command::Stop`]
    /// ([`State::Idle`]), both with status `Aborted`.
    pub fn start_identify(&mut self) -> bool {
        let at_rest = self
            .encoders
            .iter()
            .all(|e| libm::fabsf(rad_s_to_rpm(e.speed_rad_s())) <= identify::REST_RPM);
        if !matches!(self.mode, Mode::Idle) || !at_rest {
            return false;
        }
        self.identify_run = IdentifyRun::new(IdentifyConfig::from_params(&self.params));
        self.identify_runs = self.identify_runs.wrapping_add(1);
        self.mode = Mode::Identify;
        true
    }

    /// The identification's status and result: `NotRun` until one is started on
    /// this controller, then `Running` with the rotors finished so far, then
    /// `Done` or `Aborted`.
    pub fn identify_report(&self) -> IdentifyReport {
        match self.mode {
            Mode::Identify => IdentifyReport {
                status: IdentifyStatus::Running,
                identity: self.identify_run.result(),
            },
            _ => self.last_identify,
        }
    }

    /// Keep the report of the self-test or identification in progress, if one
    /// is, ended: `done` (finished) or aborted; the caller moves the mode on.
    fn end_procedure(&mut self, done: bool) {
        match &mut self.mode {
            Mode::SelfTest(run) => {
                self.last_self_test = SelfTestReport {
                    status: if done {
                        SelfTestStatus::Done
                    } else {
                        SelfTestStatus::Aborted
                    },
                    result: run.result(),
                };
            }
            Mode::Identify => {
                let run = &mut self.identify_run;
                if !done {
                    run.abort();
                }
                self.last_identify = IdentifyReport {
                    status: if done {
                        IdentifyStatus::Done
                    } else {
                        IdentifyStatus::Aborted
                    },
                    identity: run.result(),
                };
            }
            _ => {}
        }
    }

    /// How far the identification has come: what changes whenever its report
    /// does ([`Controller::identify_report`]), cheap to ask every tick.
    pub fn identify_progress(&self) -> IdentifyProgress {
        match self.mode {
            Mode::Identify => IdentifyProgress {
                run: self.identify_runs,
                status: IdentifyStatus::Running,
                rotors_finished: self.identify_run.rotors_finished(),
            },
            _ => IdentifyProgress {
                run: self.identify_runs,
                status: self.last_identify.status,
                rotors_finished: self.last_identify.identity.rotors_run,
            },
        }
    }

    /// The count each encoder latched at its last index pulse, `None` until one
    /// has been seen: where `theta = 0` is for the controller (a capture's start,
    /// [`crate::capture`]).
    pub fn index_counts(&self) -> [Option<u32>; 2] {
        [
            self.encoders[0].index_count(),
            self.encoders[1].index_count(),
        ]
    }

    /// The current state.
    pub fn state(&self) -> State {
        self.mode.state()
    }

    /// The latched faults.
    pub fn faults(&self) -> Faults {
        self.mode.faults()
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
        let dt = self.usable_dt(dt);

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
        self.link_age_s = if inputs.command.is_some() {
            0.0
        } else {
            self.link_age_s + dt
        };

        // 3. Check faults.
        let obs = self.observe(inputs, &m);
        let found = self.check_faults(&obs, dt);

        // 4. Command.
        let rejected = self.command(inputs.command, &obs, &m, found);

        // 4 to 7: the self-test's tick, or a run's references, phase loop and
        // speed loops.
        let actuation = self.drive(inputs, &m, dt);

        // 8. Output.
        self.outputs(inputs, &m, &actuation, rejected)
    }

    /// Stage 1: the usable `dt`, s: NaN, infinite or <= 0 taken as one nominal tick,
    /// otherwise clamped to [0.1, 10] nominal ticks, so that a broken tick source
    /// leaves the controller defined. The constants of that `dt` are worked out
    /// again only when the `dt` given changes.
    fn usable_dt(&mut self, dt: f32) -> f32 {
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
        self.dt_constants.dt
    }

    /// Stage 2: encoders, phase offset and phase error, current filter.
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

        let (state, phase_error) = self.phase_error(offset_deg);
        Measurement {
            state,
            speed_rad_s,
            speed_rpm: map2(speed_rad_s, rad_s_to_rpm),
            anomaly,
            offset_deg,
            phase_error,
        }
    }

    /// Stage 2, the phase error: measured while the phase loop is closed and the
    /// offset known, against the offset reference in force over the tick just
    /// ended. Its unwrapped sum is carried from tick to tick for the lock check: a
    /// rotor slipping whole turns would otherwise bring the wrapped error back
    /// through 0 every turn and restart the check's timer. Returns the state
    /// too, found on the same look at it.
    fn phase_error(&mut self, offset_deg: Option<f32>) -> (State, Option<PhaseError>) {
        let reference_deg = self.offset.reference_deg();
        let (state, run) = match &mut self.mode {
            Mode::Starting(run) => (State::Starting, run),
            Mode::Running(run) => (State::Running, run),
            Mode::Stopping { run, .. } => (State::Stopping, run),
            Mode::Idle => return (State::Idle, None),
            Mode::SelfTest(_) => return (State::SelfTest, None),
            Mode::Identify => return (State::Identify, None),
            Mode::Fault(_) => return (State::Fault, None),
        };
        // No offset measured: the loop opens in this tick's stage 5 (or the run
        // ends before), which drops the error with it.
        let (PhaseLock::Closed { error, .. }, Some(o)) = (&mut run.phase, offset_deg) else {
            return (state, None);
        };
        let e = wrap_deg_signed(reference_deg - o);
        let unwrapped = match *error {
            Some(u) => UnwrappedError {
                sum_deg: u.sum_deg + wrap_deg_signed(e - u.last_deg),
                last_deg: e,
            },
            None => UnwrappedError {
                sum_deg: e,
                last_deg: e,
            },
        };
        *error = Some(unwrapped);
        let phase_error = PhaseError {
            wrapped_deg: e,
            unwrapped_deg: unwrapped.sum_deg,
        };
        (state, Some(phase_error))
    }

    /// Stage 3, what the fault checks look at: this tick's inputs and
    /// measurements, the previous tick's duties, the state before this tick's
    /// command. A reset in this tick's command looks at it too (the causes still
    /// present).
    fn observe(&self, inputs: &Inputs, m: &Measurement) -> Observation {
        let state = m.state;
        // The self-test measures the index itself: only count jumps are faults.
        let testing = state == State::SelfTest;
        let encoder_anomaly = map2(m.anomaly, |a| match a {
            Some(EncoderAnomaly::IndexMisplaced | EncoderAnomaly::IndexMissing) if testing => None,
            other => other,
        });
        Observation {
            state,
            duty: self.last_duty,
            speed_rpm: m.speed_rpm,
            current: inputs.current,
            current_filtered: self.current_filtered,
            encoder_anomaly,
            phase_error_deg: m.phase_error.map(|e| e.unwrapped_deg),
            supply_voltage: inputs.supply_voltage,
            estop: inputs.estop,
            link_age_s: self.link_age_s,
            deadline_missed: FaultMonitor::missed_deadline(inputs.timing, &self.params.limits),
        }
    }

    /// Stage 3, the fault checks on `obs`: what they find is latched at once (the
    /// state becomes [`State::Fault`], a run or self-test ends), in this very
    /// tick; a deadline missed is counted whatever the state. Returns the faults
    /// found in this tick.
    fn check_faults(&mut self, obs: &Observation, dt: f32) -> Faults {
        let found = self.monitor.check(obs, &self.params.limits, dt);
        if obs.deadline_missed {
            self.overruns = self.overruns.saturating_add(1);
        }
        if !found.is_empty() {
            self.latch(found);
        }
        found
    }

    /// Latch `found`: the state becomes [`State::Fault`] with them added to those
    /// already latched; a run ends (motors off, references and loops gone), a
    /// self-test is aborted.
    fn latch(&mut self, found: Faults) {
        self.end_procedure(false);
        self.mode = Mode::Fault(self.mode.faults() | found);
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
                self.reset_faults(obs, found);
                false
            }
            Some(Command::Stop) => {
                self.stop();
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

    /// A reset: in [`State::Fault`], clear the latched faults whose cause is gone
    /// (not [`Faults::PARAMS`], not those `found` in this tick); none left: idle.
    fn reset_faults(&mut self, obs: &Observation, found: Faults) {
        if let Mode::Fault(latched) = self.mode {
            let keep = FaultMonitor::present(obs, &self.params.limits) | Faults::PARAMS | found;
            let left = Faults::from_bits(latched.bits() & keep.bits());
            if left.is_empty() {
                self.mode = Mode::Idle;
                self.monitor.clear();
            } else {
                self.mode = Mode::Fault(left);
            }
        }
    }

    /// A stop: a self-test or an identification is aborted (idle); a run
    /// starting or running ramps down to rest (stopping).
    fn stop(&mut self) {
        match self.mode {
            Mode::SelfTest(_) | Mode::Identify => {
                self.end_procedure(false);
                self.mode = Mode::Idle;
            }
            Mode::Starting(run) | Mode::Running(run) => {
                self.mode = Mode::Stopping {
                    run,
                    ramp_at_zero_s: 0.0,
                };
            }
            Mode::Idle | Mode::Stopping { .. } | Mode::Fault(_) => {}
        }
    }

    /// A run command: refused in a fault or a self-test or out of the speed range;
    /// otherwise it starts a run from idle (its ramp from the speed the rotors
    /// have), or takes over the run in progress (a stop starts again). With the
    /// phase loop closed the offset reference heads for the new offset, through the
    /// vertical-force offset on a change of side.
    fn run(&mut self, speed_rpm: f32, offset: OffsetSource, m: &Measurement) -> bool {
        let p = &self.params;
        if !(speed_rpm >= p.min_speed_rpm && speed_rpm <= p.max_speed_rpm) {
            return true;
        }
        let target = RunTarget { speed_rpm, offset };
        match &mut self.mode {
            Mode::Fault(_) | Mode::SelfTest(_) | Mode::Identify => return true,
            Mode::Idle => {
                // Start from the speed the rotors have (0 at rest, more if
                // coasting).
                let ramp_rpm = self.start_speed_rpm(m);
                self.mode = Mode::Starting(Run::new(target, ramp_rpm));
            }
            Mode::Starting(run) | Mode::Running(run) | Mode::Stopping { run, .. } => {
                run.target = target;
                if run.phase_closed() {
                    let to = target_offset(run, &self.params.tuning, &mut self.table_offset);
                    self.offset.command(to);
                }
                if let Mode::Stopping { run, .. } = self.mode {
                    self.mode = Mode::Starting(run);
                }
            }
        }
        false
    }

    /// Where a run from idle starts its speed ramp, rpm: the rotors' mean measured
    /// speed (rotor 1's on one rotor) in [0, max_speed_rpm], 0 if not finite.
    fn start_speed_rpm(&self, m: &Measurement) -> f32 {
        let max = self.params.max_speed_rpm;
        let mean = if self.one_rotor {
            rad_s_to_rpm(m.speed_rad_s[0])
        } else {
            rad_s_to_rpm(0.5 * (m.speed_rad_s[0] + m.speed_rad_s[1]))
        };
        if mean.is_finite() {
            mean.clamp(0.0, max)
        } else {
            0.0
        }
    }

    /// Stages 4 (the self-test's tick) to 7, on one look at the state: in
    /// [`State::SelfTest`] the test steps on this tick's sample and gives its
    /// duties, or it has finished (idle, status `Done`); in a run the references,
    /// the phase loop and the speed loops ([`RunStages`]), after which a start may
    /// be running and a stop idle; nothing driven in any other state.
    fn drive(&mut self, inputs: &Inputs, m: &Measurement, dt: f32) -> Actuation {
        let (run, stage) = match &mut self.mode {
            Mode::Starting(run) => (run, Stage::Starting),
            Mode::Running(run) => (run, Stage::Running),
            Mode::Stopping {
                run,
                ramp_at_zero_s,
            } => (run, Stage::Stopping(ramp_at_zero_s)),
            Mode::SelfTest(test) => {
                let step = test.step(
                    &SelfTestSample {
                        encoder: inputs.encoder,
                        index: inputs.index,
                        current: inputs.current,
                        speed_rpm: m.speed_rpm,
                    },
                    dt,
                );
                if !step.done {
                    return Actuation {
                        duty: step.duty,
                        ..Actuation::off(State::SelfTest, Faults::NONE)
                    };
                }
                self.end_procedure(true);
                self.mode = Mode::Idle;
                return Actuation::off(State::Idle, Faults::NONE);
            }
            Mode::Identify => {
                let step = self.identify_run.step(
                    &IdentifySample {
                        encoder: inputs.encoder,
                        current: inputs.current,
                        supply_voltage: inputs.supply_voltage,
                        speed_rpm: m.speed_rpm,
                    },
                    dt,
                );
                if !step.done {
                    return Actuation {
                        duty: step.bridges.map(Bridge::duty),
                        open: step.bridges.map(|b| !b.is_driven()),
                        ..Actuation::off(State::Identify, Faults::NONE)
                    };
                }
                self.end_procedure(true);
                self.mode = Mode::Idle;
                return Actuation::off(State::Idle, Faults::NONE);
            }
            Mode::Idle => return Actuation::off(State::Idle, Faults::NONE),
            Mode::Fault(faults) => return Actuation::off(State::Fault, *faults),
        };
        let mut stages = RunStages {
            params: &self.params,
            speed_rates: &self.speed_rates,
            offset: &mut self.offset,
            table_offset: &mut self.table_offset,
            one_rotor: self.one_rotor,
            phase_trim_max_rad_s: self.phase_trim_max_rad_s,
        };

        // 5. References.
        let starting = matches!(stage, Stage::Starting);
        let refs = stages.references(run, stage, m, dt);
        if refs.state == State::Idle {
            // The stop has ended: the run is gone.
            self.mode = Mode::Idle;
            return Actuation::off(State::Idle, Faults::NONE);
        }

        // 6. Phase loop.
        let speed_ref = stages.speed_references(run, m, refs.offset_rate_deg_s, dt);

        // 7. Speed loops.
        let duty = stages.duties(
            run,
            inputs.supply_voltage,
            m,
            speed_ref,
            refs.accel_rpm_s,
            dt,
        );

        let phase_closed = run.phase_closed();
        if starting && refs.state == State::Running {
            // The same run, now running: the run stays where it is in the state,
            // only its tag is written.
            if let Mode::Starting(run) = self.mode {
                self.mode = Mode::Running(run);
            }
        }
        Actuation {
            state: refs.state,
            faults: Faults::NONE,
            phase_closed,
            speed_ref,
            duty,
            open: [false; 2],
        }
    }

    /// Stage 8: the outputs, built afresh. The state after this tick (`drive`'s)
    /// decides which bridges are driven; a latched fault is [`State::Fault`],
    /// which drives none: the safe state overrides whatever the loops computed. A
    /// duty out of [-1, 1] is clamped, a non-finite one written as 0.
    fn outputs(
        &mut self,
        inputs: &Inputs,
        m: &Measurement,
        actuation: &Actuation,
        rejected: bool,
    ) -> Outputs {
        let state = actuation.state;
        let driving = state.drives();
        let duty = if driving {
            map2(actuation.duty, |d| {
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
        // [`RotorCount::bridges_on`]: rotor 2's bridge only on two rotors; a
        // bridge the identification leaves open (a rotor coasting) is off.
        let on = [
            driving && !actuation.open[0],
            driving && !self.one_rotor && !actuation.open[1],
        ];
        let phase_closed = actuation.phase_closed;
        let speed_ref = actuation.speed_ref;
        Outputs {
            bridges: [
                Bridge::driven_if(on[0], duty[0]),
                Bridge::driven_if(on[1], duty[1]),
            ],
            state,
            faults: actuation.faults,
            telemetry: Telemetry {
                speed_rpm: m.speed_rpm,
                speed_ref_rpm: if !driving {
                    [0.0; 2]
                } else if self.one_rotor {
                    [rad_s_to_rpm(speed_ref[0]), 0.0]
                } else {
                    map2(speed_ref, rad_s_to_rpm)
                },
                phase_valid: m.offset_deg.is_some(),
                phase_offset_deg: m.offset_deg.unwrap_or(0.0),
                phase_loop_closed: phase_closed,
                commanded_offset_deg: self.offset.reference_deg(),
                target_offset_deg: self.offset.target_deg(),
                phase_error_deg: match m.phase_error {
                    Some(e) if phase_closed => e.wrapped_deg,
                    _ => 0.0,
                },
                current: inputs.current,
                supply_voltage: inputs.supply_voltage,
                duty,
                command_rejected: rejected,
                tick_late_us: saturating_us(inputs.timing.late_s),
                tick_busy_us: saturating_us(inputs.timing.busy_s),
                overruns: self.overruns,
            },
        }
    }
}

/// What stages 4 to 7 leave for the output: the state after them, with its
/// latched faults and, in a run, the phase loop's state, the speed references
/// (rad/s) and the duties (before the output's clamp).
#[derive(Clone, Copy, Debug)]
struct Actuation {
    /// The state after this tick.
    state: State,
    /// The latched faults (none outside [`State::Fault`]).
    faults: Faults,
    /// Whether a run's phase loop is closed.
    phase_closed: bool,
    /// The speed loops' references, rad/s (0 outside a run).
    speed_ref: [f32; 2],
    /// The duties.
    duty: [f32; 2],
    /// Bridges left off although the state drives (the identification's coast).
    open: [bool; 2],
}

impl Actuation {
    /// Nothing driven in `state`, `faults` latched.
    fn off(state: State, faults: Faults) -> Actuation {
        Actuation {
            state,
            faults,
            phase_closed: false,
            speed_ref: [0.0; 2],
            duty: [0.0; 2],
            open: [false; 2],
        }
    }
}

/// Where a run is: starting, running, or stopping with the time its speed ramp
/// has been at 0 (s).
enum Stage<'a> {
    /// [`Mode::Starting`].
    Starting,
    /// [`Mode::Running`].
    Running,
    /// [`Mode::Stopping`], with its time at zero speed.
    Stopping(&'a mut f32),
}

/// What stage 5 gives: the speed reference's acceleration, the offset
/// reference's rate, and the state the run is in after it.
struct References {
    /// The speed reference's acceleration, rpm/s.
    accel_rpm_s: f32,
    /// The offset reference's rate, degrees/s.
    offset_rate_deg_s: f32,
    /// Starting, running, stopping, or idle once a stop has ended.
    state: State,
}

/// Stages 5 to 7 of a run: what they use of the controller besides the run,
/// borrowed apart from the state that holds the run.
struct RunStages<'a> {
    /// The parameters in use.
    params: &'a Params,
    /// The speed ramp's rates and band, from the parameters.
    speed_rates: &'a SpeedRampRates,
    /// The offset reference ([`Controller`]'s).
    offset: &'a mut OffsetRamp,
    /// The last table offset looked up ([`target_offset`]).
    table_offset: &'a mut Option<TableOffset>,
    /// The machine has one rotor.
    one_rotor: bool,
    /// [`Params::phase_trim_max_rpm`] in rad/s.
    phase_trim_max_rad_s: f32,
}

impl RunStages<'_> {
    /// Stage 5: ramp the speed and the offset, open or close the phase loop, and
    /// say where the run is now: a start at the commanded speed with the phase
    /// loop closed is running, a stop at rest idle.
    fn references(
        &mut self,
        run: &mut Run,
        stage: Stage<'_>,
        m: &Measurement,
        dt: f32,
    ) -> References {
        let p = self.params;
        let target_rpm = match stage {
            Stage::Starting | Stage::Running => run.target.speed_rpm,
            Stage::Stopping(_) => 0.0,
        };

        // Speed ramp.
        let (ramp, accel) = ramp_speed(run.ramp_rpm, target_rpm, self.speed_rates, dt);
        run.ramp_rpm = ramp;

        // Phase loop open or closed: closed with both angles known above its speed.
        let can_close = m.offset_deg.is_some() && run.ramp_rpm >= p.phase_loop_min_rpm;
        if can_close && !run.phase_closed() {
            run.phase = PhaseLock::Closed {
                pi: PhaseLoop::new(),
                error: None,
            };
            // From the measured offset along the shorter arc: at closing the
            // rotors are slow (the loop closes at `phase_loop_min_rpm`) and the
            // platform barely excited, so the through-180 rule of direction
            // changes would only delay a start to the left by half a turn.
            *self.offset = OffsetRamp::new(m.offset_deg.unwrap_or(0.0));
            let to = target_offset(run, &p.tuning, self.table_offset);
            self.offset.follow(to);
        } else if !can_close && run.phase_closed() {
            run.phase = PhaseLock::Open;
        }

        // Offset ramp; the table's offset follows the ramped speed, except in a
        // stop, which keeps heading where the run left it.
        let phase_closed = run.phase_closed();
        let mut offset_rate_deg_s = 0.0;
        if phase_closed {
            if !matches!(stage, Stage::Stopping(_)) {
                let to = target_offset(run, &p.tuning, self.table_offset);
                self.offset.follow(to);
            }
            let moved = self.offset.step(p.offset_ramp_deg_s * dt);
            offset_rate_deg_s = moved / dt;
        }

        // State changes: a start at the commanded speed with the phase loop closed
        // (one rotor: no phase loop to wait for) is running; a stop ends once the
        // ramp is at 0 and the rotors are slow, or after its timeout.
        let state = match stage {
            Stage::Stopping(ramp_at_zero_s) if run.ramp_rpm == 0.0 => {
                *ramp_at_zero_s += dt;
                let slow = m
                    .speed_rad_s
                    .iter()
                    .all(|w| libm::fabsf(rad_s_to_rpm(*w)) < p.stop_speed_rpm);
                if slow || *ramp_at_zero_s >= p.stop_timeout_s {
                    State::Idle
                } else {
                    State::Stopping
                }
            }
            Stage::Stopping(_) => State::Stopping,
            Stage::Starting if run.ramp_rpm == target_rpm && (phase_closed || self.one_rotor) => {
                State::Running
            }
            Stage::Starting => State::Starting,
            Stage::Running => State::Running,
        };
        References {
            accel_rpm_s: accel,
            offset_rate_deg_s,
            state,
        }
    }

    /// Stage 6: the speed references of the speed loops, rad/s: the ramp's, plus
    /// and minus half the speed difference `dw = w1 - w2` the phase loop asks for
    /// to correct the phase error (none with the loop open).
    fn speed_references(
        &self,
        run: &mut Run,
        m: &Measurement,
        offset_rate_deg_s: f32,
        dt: f32,
    ) -> [f32; 2] {
        let p = self.params;
        let ramp_rad_s = rpm_to_rad_s(run.ramp_rpm);
        let dw = match (&mut run.phase, m.phase_error) {
            (PhaseLock::Closed { pi, .. }, Some(e)) => {
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
                pi.update(
                    e.wrapped_deg / DEG_PER_RAD,
                    offset_rate_deg_s / DEG_PER_RAD,
                    p.phase_kp,
                    p.phase_ki,
                    limit,
                    dt,
                )
            }
            // Open, or closed in this very tick: no error measured yet, the
            // integrator empty.
            _ => 0.0,
        };
        [ramp_rad_s + 0.5 * dw, ramp_rad_s - 0.5 * dw]
    }

    /// Stage 7: the speed loops' duties: feedforward + PI towards `speed_ref`
    /// (rad/s), with the reference's acceleration `accel_rpm_s`.
    fn duties(
        &self,
        run: &mut Run,
        supply_voltage: f32,
        m: &Measurement,
        speed_ref: [f32; 2],
        accel_rpm_s: f32,
        dt: f32,
    ) -> [f32; 2] {
        let p = self.params;
        // The measured supply, unless unusable: then the nominal one.
        let supply_v = if supply_voltage.is_finite() && supply_voltage >= 0.5 * p.supply_nominal_v {
            supply_voltage
        } else {
            p.supply_nominal_v
        };
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
        let [loop1, loop2] = &mut run.speed_loops;
        if self.one_rotor {
            // Rotor 2 is not driven: exactly 0.
            [update(0, loop1), 0.0]
        } else {
            [update(0, loop1), update(1, loop2)]
        }
    }
}

/// `s` seconds in whole microseconds, saturating at `u16::MAX` (NaN and negative
/// values give 0).
fn saturating_us(s: f32) -> u16 {
    // A float-to-integer `as` saturates, and takes NaN to 0: to `u32` it is one
    // conversion instruction on the Cortex-M4F (to `u16` it is followed by two
    // compares of the float), then the bound of `u16` on the integer.
    ((s * 1e6) as u32).min(u16::MAX as u32) as u16
}
