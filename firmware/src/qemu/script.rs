//! The scripted host: a fixed sequence of requests and fault injections, run by
//! the `idle` task once per control tick, each answer decoded and checked.
//!
//! 1. status at start (idle, no fault); the compiled-in tuning table read back; no
//!    self-test run;
//! 2. a tuning table written (stored in the RAM flash), read back, and found in
//!    the flash record;
//! 3. frames that must be refused or ignored: a frame CRC error (`Nack BadCrc`),
//!    a header CRC error (no answer), garbage before a frame (skipped, the frame
//!    answered), an unknown id (`Nack UnknownMessage`), a NaN speed and a too short
//!    telemetry period (`Nack BadValue`);
//! 4. telemetry streamed every [`TELEMETRY_PERIOD_MS`];
//! 5. travel right at [`SPEED_RPM`], heartbeats every `HEARTBEAT_PERIOD_MS`:
//!    `running` within [`RUNNING_LIMIT_TICKS`], then after [`SETTLE_TICKS`] the
//!    speeds, the phase loop, the written table's offset and the model's true
//!    offset checked; stop: `idle` within [`STOP_LIMIT_TICKS`];
//! 6. self-test, once both rotors are at rest (within [`REST_LIMIT_TICKS`]):
//!    `RunSelfTest` Acked, `ReadSelfTest` polled every tick until it is no longer
//!    running (at most the documented worst case, `self_test_limit_ticks`), a
//!    `Travel` meanwhile `Nack Busy`; status `Done`; per rotor both polarities, the
//!    index, the model's counts a turn and the index offset the model predicts from
//!    its true rest angle ([`index_offset_model`]); the result stored in flash with
//!    the table; then the motor identification, the rotors at rest: `RunIdentify`
//!    Acked, `ReadIdentify` polled every tick until it is no longer running (at
//!    most [`IDENTIFY_LIMIT_TICKS`]), a `Travel` meanwhile `Nack Busy`; status
//!    `Done`; per rotor every value measured and within 5 % of the model's
//!    constants (friction within 20 %); the result stored in flash with the table
//!    and the self-test's;
//! 7. fault: a capture armed on the trigger `fault`, travel again, open the
//!    E-stop: `ESTOP` latched in the first tick that sees it, the driver disabled
//!    and both duties 0 in that tick; the capture read over the link holds that
//!    tick (state fault, `ESTOP`, the E-stop open, both bridges off) after a
//!    `running` start, stamped with the compiled-in machine file; a reset while it
//!    is open keeps the fault, a reset after it closed goes idle;
//! 8. fault: travel again, make the control task work [`overrun_us`] longer once
//!    (over its 500 us budget): `DEADLINE` latched in the next tick, the outputs
//!    safe, one overrun counted in the status; a reset goes idle;
//! 9. fault: travel again, disconnect encoder 2: `ENCODER` (or `STALL`) latched
//!    within the controller's bound, the outputs safe. It stays latched: the
//!    counter lost counts, so the index is off a whole turn for good (a board
//!    needs a restart);
//! 10. the telemetry stream stopped and its frames checked;
//! 11. the encoder back, the fault reset, a run started: once the bridges are
//!     driven the script is done, the measurements are reported, and idle pends
//!     an interrupt that nothing is bound to ([`pend_unexpected`]). The default
//!     handler (`exceptions`) cuts the bridges and ends the run through
//!     [`unexpected_interrupt`], which checks that it was that interrupt, that
//!     the bridges had been driven, and that every input is now low.

use core::sync::atomic::{AtomicBool, Ordering};

use cortex_m::peripheral::NVIC;
use stm32f4xx_hal::pac::Interrupt;

use shared::capture::{CaptureStatus, Record, Trigger};
use shared::controller::identify::{IdentifyReport, IdentifyStatus, RotorIdentity};
use shared::controller::self_test::{RotorSelfTest, SelfTestReport, SelfTestStatus};
use shared::controller::self_test::{DRIVE_TIMEOUT_S, REST_RPM, SETTLE_TIMEOUT_S};
use shared::controller::{
    Bridge, Command, Direction, Faults, Params, State, TuningTable, CONTROL_RATE_HZ,
};
use shared::protocol::link::{Link, LinkState};
use shared::protocol::{
    encode_frame, MessageId, NackReason, Request, Response, StatusReport, HEARTBEAT_PERIOD_MS,
    MAX_FRAME,
};
use shared::storage::{self, SimFlash};

use super::checks::check;
use super::host::{Device, Host};
use super::world::{DriveStart, FaultSeen, World};

/// The run speed, rpm.
pub const SPEED_RPM: f32 = 3000.0;
/// Longest from a travel command to `running`, ticks (host tests: about 710).
pub const RUNNING_LIMIT_TICKS: u32 = 2000;
/// Ticks in `running` before the run is checked.
pub const SETTLE_TICKS: u32 = 500;
/// Longest from a stop command to `idle`, ticks.
pub const STOP_LIMIT_TICKS: u32 = 4000;
/// The written table's right offsets are the compiled-in ones plus this, degrees.
pub const TABLE_SHIFT_DEG: f32 = 5.0;
/// Telemetry period asked for, ms.
pub const TELEMETRY_PERIOD_MS: u16 = 100;
/// Largest speed error after settling, rpm.
const SPEED_TOLERANCE_RPM: f32 = 30.0;
/// The injected overrun of the control task, us: 200 us over its budget
/// (`limits.tick_busy_max_s`: 500 us at 1 kHz), under a whole tick.
pub fn overrun_us() -> u32 {
    (Params::reference().limits.tick_busy_max_s * 1e6) as u32 + 200
}
/// Largest phase error after settling, degrees.
const PHASE_TOLERANCE_DEG: f32 = 5.0;
/// Ticks in `running` before a fault is injected.
const RUN_BEFORE_FAULT_TICKS: u32 = 100;
/// Longest from `idle` after the stop to both rotors at rest, ticks.
pub const REST_LIMIT_TICKS: u32 = 1000;
/// Longest from `RunSelfTest` to the test reported running, ticks (the control
/// task starts it at its next tick).
pub const START_LIMIT_TICKS: u32 = 10;
/// Longest from `RunIdentify` to its end, ticks: 40 s, twice what it takes on the
/// reference machine's rotors.
pub const IDENTIFY_LIMIT_TICKS: u32 = 40_000;

/// The script's steps ([`Script::step`] numbers them from 0).
const STEPS: u8 = 31;

/// What a script step did.
enum Next {
    /// Wait for a later tick.
    Wait,
    /// Go on with the next step at the next tick.
    Advance,
    /// A check failed that later steps depend on: stop the script.
    Abort,
}

/// Whether the script has finished.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Progress {
    /// Steps remain.
    Running,
    /// Done (every check logged).
    Done,
}

/// The link's state behind the RTIC lock the script takes it through.
pub trait LinkLock: rtic::Mutex<T = LinkState> {}
impl<M: rtic::Mutex<T = LinkState>> LinkLock for M {}

/// The emulated world behind the RTIC lock the script takes it through.
pub trait WorldLock: rtic::Mutex<T = World> {}
impl<M: rtic::Mutex<T = World>> WorldLock for M {}

/// What one pass of the script works on.
pub struct Io<'a, L, W> {
    /// The control tick number.
    pub tick: u32,
    /// The link task's state.
    pub link: &'a mut Link,
    /// The parameter flash.
    pub flash: &'a mut SimFlash,
    /// The state shared by the link and the control task.
    pub state: &'a mut L,
    /// The state shared with the control task.
    pub world: &'a mut W,
}

/// The script's position and memory.
pub struct Script {
    /// Current step.
    step: u8,
    /// Tick at which the current step began.
    since: u32,
    /// The host's end of the link.
    host: Host,
    /// Send a heartbeat when nothing else was sent for `HEARTBEAT_PERIOD_MS`.
    keepalive: bool,
    /// Tick of the last request.
    last_request: u32,
    /// Heartbeats not answered with an Ack.
    heartbeat_failures: u32,
    /// The table written.
    table: Option<TuningTable>,
    /// Tick of the last fault injection.
    injected_at: u32,
    /// Detection bound of the injected fault, ticks.
    bound_ticks: u32,
    /// A Travel was sent (and checked) while the self-test ran.
    travel_nacked: bool,
    /// The self-test's final report.
    self_test: Option<SelfTestReport>,
    /// The identification's final report.
    identify: Option<IdentifyReport>,
    /// The motors are driven and the unexpected interrupt may be pended.
    armed: bool,
}

/// Circular distance of two angles, degrees in [0, 180].
fn angle_distance(a: f32, b: f32) -> f32 {
    let d = (a - b) % 360.0;
    let d = if d < 0.0 { d + 360.0 } else { d };
    if d > 180.0 {
        360.0 - d
    } else {
        d
    }
}

fn abs(x: f32) -> f32 {
    if x < 0.0 {
        -x
    } else {
        x
    }
}

impl Default for Script {
    fn default() -> Self {
        Script::new()
    }
}

impl Script {
    /// At its first step.
    pub const fn new() -> Self {
        Script {
            step: 0,
            since: 0,
            host: Host::new(),
            keepalive: false,
            last_request: 0,
            heartbeat_failures: 0,
            table: None,
            injected_at: 0,
            bound_ticks: 0,
            travel_nacked: false,
            self_test: None,
            identify: None,
            armed: false,
        }
    }

    /// One pass at control tick `io.tick`.
    pub fn run<L: LinkLock, W: WorldLock>(&mut self, io: &mut Io<'_, L, W>) -> Progress {
        // The link task's pass with nothing received: telemetry when due.
        self.exchange(io, &[]);
        if self.keepalive && io.tick.wrapping_sub(self.last_request) >= HEARTBEAT_PERIOD_MS {
            let answer = self.ask(io, &Request::Command(Command::Heartbeat));
            if !matches!(answer, Some(Response::Ack { .. })) {
                self.heartbeat_failures += 1;
            }
        }
        match self.step(io) {
            Next::Wait => Progress::Running,
            Next::Advance => {
                self.step += 1;
                self.since = io.tick;
                Progress::Running
            }
            Next::Abort => {
                defmt::error!("script aborted at step {=u8}", self.step);
                Progress::Done
            }
        }
    }

    /// Push raw bytes through the link; the answers.
    fn exchange<L: LinkLock, W>(&mut self, io: &mut Io<'_, L, W>, bytes: &[u8]) -> usize {
        let now_ms = io.state.lock(|l| l.status.uptime_ms);
        let mut device = Device {
            link: &mut *io.link,
            flash: &mut *io.flash,
            state: &mut *io.state,
            now_ms,
        };
        self.host.exchange(bytes, &mut device).len()
    }

    /// Send `request`; its answer.
    fn ask<L: LinkLock, W>(
        &mut self,
        io: &mut Io<'_, L, W>,
        request: &Request,
    ) -> Option<Response> {
        self.last_request = io.tick;
        let now_ms = io.state.lock(|l| l.status.uptime_ms);
        let mut device = Device {
            link: &mut *io.link,
            flash: &mut *io.flash,
            state: &mut *io.state,
            now_ms,
        };
        self.host.request(request, &mut device)
    }

    /// Send `request` and check that it is answered Ack.
    fn ack<L: LinkLock, W>(
        &mut self,
        io: &mut Io<'_, L, W>,
        request: &Request,
        what: &str,
    ) -> bool {
        let id = request_id(request);
        let answer = self.ask(io, request);
        check!(
            matches!(answer, Some(Response::Ack { request }) if request == id),
            "{=str}: Ack",
            what
        )
    }

    /// Send `request` and check that it is answered `Nack(reason)`.
    fn nack<L: LinkLock, W>(
        &mut self,
        io: &mut Io<'_, L, W>,
        request: &Request,
        reason: NackReason,
        what: &str,
    ) -> bool {
        let id = request_id(request);
        let answer = self.ask(io, request);
        check!(
            matches!(answer, Some(Response::Nack { request, reason: r }) if request == id && r == reason),
            "{=str}: Nack {}",
            what,
            reason
        )
    }

    /// GetStatus; the report, checked to be one.
    fn status<L: LinkLock, W>(&mut self, io: &mut Io<'_, L, W>) -> Option<StatusReport> {
        match self.ask(io, &Request::GetStatus) {
            Some(Response::Status(report)) => Some(report),
            _ => {
                check!(false, "GetStatus: Status");
                None
            }
        }
    }

    /// ReadTuningTable; the table, if the answer is one.
    fn read_table<L: LinkLock, W>(&mut self, io: &mut Io<'_, L, W>) -> Option<TuningTable> {
        match self.ask(io, &Request::ReadTuningTable) {
            Some(Response::TuningTable(t)) => Some(t),
            _ => None,
        }
    }

    /// ReadSelfTest; the report, if the answer is one.
    fn read_self_test<L: LinkLock, W>(&mut self, io: &mut Io<'_, L, W>) -> Option<SelfTestReport> {
        match self.ask(io, &Request::ReadSelfTest) {
            Some(Response::SelfTest(report)) => Some(report),
            _ => None,
        }
    }

    /// ReadIdentify; the report, if the answer is one.
    fn read_identify<L: LinkLock, W>(&mut self, io: &mut Io<'_, L, W>) -> Option<IdentifyReport> {
        match self.ask(io, &Request::ReadIdentify) {
            Some(Response::Identify(report)) => Some(report),
            _ => None,
        }
    }

    /// The state the control task published at its latest tick.
    fn state_now<L: LinkLock, W>(io: &mut Io<'_, L, W>) -> State {
        io.state.lock(|l| l.status.state)
    }

    /// Wait until the published state is `state`, at most `limit` ticks.
    fn wait_state<L: LinkLock, W>(
        &mut self,
        io: &mut Io<'_, L, W>,
        state: State,
        limit: u32,
    ) -> Next {
        let waited = io.tick.wrapping_sub(self.since);
        if Self::state_now(io) == state {
            check!(
                true,
                "{=str} after {=u32} ticks (limit {=u32})",
                state.name(),
                waited,
                limit
            );
            Next::Advance
        } else if waited >= limit {
            check!(
                false,
                "{=str} within {=u32} ticks: still {=str}",
                state.name(),
                limit,
                Self::state_now(io).name()
            );
            Next::Abort
        } else {
            Next::Wait
        }
    }

    /// Inject `injected` faults into the model from the next tick on.
    fn inject<W: WorldLock, L>(
        &mut self,
        io: &mut Io<'_, L, W>,
        estop_open: bool,
        encoder_cut: [bool; 2],
    ) {
        io.world.lock(|w| {
            w.injected.estop_open = estop_open;
            w.injected.encoder_cut = encoder_cut;
            w.first_fault = None;
        });
        self.injected_at = io.tick;
    }

    /// After a reset: the status idle without a fault; then the next part of the
    /// script (`what`) starts with a travel command.
    fn reset_done_then_travel<L: LinkLock, W>(
        &mut self,
        io: &mut Io<'_, L, W>,
        what: &str,
    ) -> Next {
        let Some(s) = self.status(io) else {
            return Next::Abort;
        };
        check!(
            s.state == State::Idle && s.faults.is_empty(),
            "after the reset: {=str}, faults {}",
            s.state.name(),
            s.faults
        );
        defmt::info!("script: {=str}", what);
        self.ack(io, &travel_right(), "Travel right");
        Next::Advance
    }

    /// The script's steps in their order: step `self.step` at this tick.
    fn step<L: LinkLock, W: WorldLock>(&mut self, io: &mut Io<'_, L, W>) -> Next {
        let waited = io.tick.wrapping_sub(self.since);
        match self.step {
            0 => self.start_status(io),
            1 => self.write_table(io),
            2 => self.refused_frames(io),
            3 => self.travel_with_telemetry(io),
            4 => self.wait_state(io, State::Running, RUNNING_LIMIT_TICKS),
            5 => self.settled_run(io, waited),
            6 => self.wait_state(io, State::Idle, STOP_LIMIT_TICKS),
            7 => self.await_rest(io, waited),
            8 => self.start_self_test(io),
            9 => self.poll_self_test(io, waited),
            10 => self.self_test_result(io),
            11 => self.start_identify(io),
            12 => self.poll_identify(io, waited),
            13 => self.identify_result(io),
            14 => self.estop_travel(io),
            15 => self.wait_state(io, State::Running, RUNNING_LIMIT_TICKS),
            16 => self.open_estop(io, waited),
            17 => self.estop_latched(io),
            18 => self.estop_reset(io),
            19 => self.reset_done_then_travel(io, "control tick overrun while running"),
            20 => self.wait_state(io, State::Running, RUNNING_LIMIT_TICKS),
            21 => self.inject_overrun(io, waited),
            22 => self.deadline_latched(io, waited),
            23 => self.reset_done_then_travel(io, "encoder 2 disconnected while running"),
            24 => self.wait_state(io, State::Running, RUNNING_LIMIT_TICKS),
            25 => self.disconnect_encoder(io, waited),
            26 => self.encoder_fault_latched(io, waited),
            27 => self.telemetry_off(io),
            28 => self.stream_stopped(io, waited),
            29 => self.travel_to_drive(io),
            30 => self.await_driving(io, waited),
            _ => Next::Abort,
        }
    }

    /// Part 1, at start (from tick 5): the status idle without a fault, the
    /// compiled-in tuning table read back, no self-test run.
    fn start_status<L: LinkLock, W: WorldLock>(&mut self, io: &mut Io<'_, L, W>) -> Next {
        if io.tick < 5 {
            return Next::Wait;
        }
        defmt::info!("script: status and tuning table at start");
        let Some(s) = self.status(io) else {
            return Next::Abort;
        };
        check!(
            s.state == State::Idle && s.faults.is_empty(),
            "status at start: {=str}, faults {}",
            s.state.name(),
            s.faults
        );
        let compiled = TuningTable::from_rows(&crate::tuning::TUNING_ROWS).ok();
        let read = self.read_table(io);
        check!(
            read.is_some() && read == compiled,
            "ReadTuningTable: the compiled-in table ({=usize} rows)",
            compiled.as_ref().map_or(0, |t| t.rows().len())
        );
        let self_test = self.read_self_test(io);
        check!(
            self_test.is_some_and(
                |r| r.status == SelfTestStatus::NotRun && r.result == Default::default()
            ),
            "ReadSelfTest at start: not run, nothing measured"
        );
        Next::Advance
    }

    /// Part 2: a table written (the compiled-in one, its right offsets shifted by
    /// [`TABLE_SHIFT_DEG`]), read back, and found in the flash record.
    fn write_table<L: LinkLock, W: WorldLock>(&mut self, io: &mut Io<'_, L, W>) -> Next {
        defmt::info!("script: tuning table written and read back");
        let rows = crate::tuning::TUNING_ROWS.map(|(s, r, l)| (s, r + TABLE_SHIFT_DEG, l));
        let Ok(table) = TuningTable::from_rows(&rows) else {
            check!(false, "shifted tuning table valid");
            return Next::Abort;
        };
        self.ack(
            io,
            &Request::WriteTuningTable(table.clone()),
            "WriteTuningTable",
        );
        let read = self.read_table(io);
        check!(
            read.as_ref() == Some(&table),
            "ReadTuningTable: the table written"
        );
        let stored = storage::load(&*io.flash);
        check!(
            stored
                .as_ref()
                .is_some_and(|s| s.record.tuning == table && s.sequence == 1),
            "flash record 1 holds the table written"
        );
        self.table = Some(table);
        Next::Advance
    }

    /// Part 3: frames refused or ignored (a frame CRC error, a header CRC error,
    /// garbage before a frame, an unknown id, values out of their domain); still idle
    /// after them.
    fn refused_frames<L: LinkLock, W: WorldLock>(&mut self, io: &mut Io<'_, L, W>) -> Next {
        defmt::info!("script: damaged and invalid frames");
        self.frame_crc_error(io);
        self.header_crc_error(io);
        self.garbage_before_frame(io);
        self.unknown_message(io);
        // Values out of their domain.
        self.nack(
            io,
            &Request::Command(Command::Travel {
                direction: Direction::Right,
                speed_rpm: f32::NAN,
            }),
            NackReason::BadValue,
            "Travel at NaN rpm",
        );
        self.nack(
            io,
            &Request::StreamTelemetry { period_ms: 5 },
            NackReason::BadValue,
            "telemetry every 5 ms",
        );
        check!(
            Self::state_now(io) == State::Idle,
            "still idle after the refused frames"
        );
        Next::Advance
    }

    /// Frame CRC broken: `Nack BadCrc` with the frame's own sequence number.
    fn frame_crc_error<L: LinkLock, W>(&mut self, io: &mut Io<'_, L, W>) {
        let mut out = [0u8; MAX_FRAME];
        let (seq, len) = self.host.frame(&Request::GetStatus, &mut out);
        if let Some(b) = out.get_mut(len.saturating_sub(1)) {
            *b ^= 0x01;
        }
        let frame = out;
        self.exchange(io, frame.get(..len).unwrap_or(&[]));
        let answers = self.host_answers();
        check!(
            matches!(answers, [(s, Response::Nack { request, reason: NackReason::BadCrc })]
                if *s == seq && *request == MessageId::GetStatus as u8),
            "frame CRC error: Nack BadCrc"
        );
    }

    /// Header CRC broken: no answer at all.
    fn header_crc_error<L: LinkLock, W>(&mut self, io: &mut Io<'_, L, W>) {
        let mut out = [0u8; MAX_FRAME];
        let (_, len) = self.host.frame(&Request::GetStatus, &mut out);
        if let Some(b) = out.get_mut(8) {
            *b ^= 0x80;
        }
        let frame = out;
        let n = self.exchange(io, frame.get(..len).unwrap_or(&[]));
        check!(n == 0, "header CRC error: no answer ({=usize})", n);
    }

    /// Garbage, then a frame: the frame is found and answered.
    fn garbage_before_frame<L: LinkLock, W>(&mut self, io: &mut Io<'_, L, W>) {
        let mut out = [0u8; MAX_FRAME];
        let mut frame = [0u8; 7 + MAX_FRAME];
        frame[..7].copy_from_slice(&[0x00, 0xA5, 0x13, 0x5A, 0xFF, 0xA5, 0xA5]);
        let (seq, len) = self
            .host
            .frame(&Request::Command(Command::Heartbeat), &mut out);
        frame[7..].copy_from_slice(&out);
        self.exchange(io, frame.get(..7 + len).unwrap_or(&[]));
        let answers = self.host_answers();
        check!(
            matches!(answers, [(s, Response::Ack { .. })] if *s == seq),
            "garbage before a frame: the frame answered"
        );
    }

    /// An unknown message id: `Nack UnknownMessage`.
    fn unknown_message<L: LinkLock, W>(&mut self, io: &mut Io<'_, L, W>) {
        let mut out = [0u8; MAX_FRAME];
        let len = encode_frame(0x7E, 900, &[], &mut out).unwrap_or(0);
        let frame = out;
        self.exchange(io, frame.get(..len).unwrap_or(&[]));
        let answers = self.host_answers();
        check!(
            matches!(
                answers,
                [(
                    900,
                    Response::Nack {
                        request: 0x7E,
                        reason: NackReason::UnknownMessage
                    }
                )]
            ),
            "unknown id: Nack UnknownMessage"
        );
    }

    /// Parts 4 and 5: telemetry on, every [`TELEMETRY_PERIOD_MS`], heartbeats from
    /// here on, and travel right.
    fn travel_with_telemetry<L: LinkLock, W: WorldLock>(&mut self, io: &mut Io<'_, L, W>) -> Next {
        defmt::info!("script: travel right at 3000 rpm");
        self.ack(
            io,
            &Request::StreamTelemetry {
                period_ms: TELEMETRY_PERIOD_MS,
            },
            "StreamTelemetry",
        );
        self.keepalive = true;
        self.ack(io, &travel_right(), "Travel right");
        Next::Advance
    }

    /// Part 5: the run, [`SETTLE_TICKS`] after `running`: the phase loop closed,
    /// the measured and true speeds, the written table's offset, the phase error and
    /// the model's true offset; then stop.
    fn settled_run<L: LinkLock, W: WorldLock>(
        &mut self,
        io: &mut Io<'_, L, W>,
        waited: u32,
    ) -> Next {
        if waited < SETTLE_TICKS {
            return Next::Wait;
        }
        let Some(s) = self.status(io) else {
            return Next::Abort;
        };
        let t = s.telemetry;
        let world = io.world.lock(|w| (w.true_speed_rpm, w.true_offset_deg));
        let table_offset = self
            .table
            .as_ref()
            .map_or(f32::NAN, |t| t.offset(Direction::Right, SPEED_RPM));
        check!(
            s.state == State::Running && t.phase_loop_closed && t.phase_valid,
            "{=u32} ticks later: {=str}, phase loop closed",
            SETTLE_TICKS,
            s.state.name()
        );
        check!(
            t.speed_rpm
                .iter()
                .chain(world.0.iter())
                .all(|v| abs(v - SPEED_RPM) < SPEED_TOLERANCE_RPM),
            "measured and true speeds within {=f32} rpm of {=f32}",
            SPEED_TOLERANCE_RPM,
            SPEED_RPM
        );
        check!(
            abs(t.target_offset_deg - table_offset) < 0.01,
            "target offset from the table written: {=f32} deg",
            table_offset
        );
        check!(
            abs(t.phase_error_deg) < PHASE_TOLERANCE_DEG
                && angle_distance(world.1, t.commanded_offset_deg) < PHASE_TOLERANCE_DEG,
            "phase error and true offset within {=f32} deg",
            PHASE_TOLERANCE_DEG
        );
        self.ack(io, &Request::Command(Command::Stop), "Stop");
        Next::Advance
    }

    /// Part 6: both rotors at rest (true speeds 0, measured ones within
    /// `REST_RPM`) within [`REST_LIMIT_TICKS`] after idle.
    fn await_rest<L: LinkLock, W: WorldLock>(
        &mut self,
        io: &mut Io<'_, L, W>,
        waited: u32,
    ) -> Next {
        let true_speed = io.world.lock(|w| w.true_speed_rpm);
        let measured = io.state.lock(|l| l.status.telemetry.speed_rpm);
        if true_speed == [0.0; 2] && measured.iter().all(|v| abs(*v) <= REST_RPM) {
            check!(
                true,
                "rotors at rest {=u32} ticks after idle (limit {=u32}): true speeds 0, measured within {=f32} rpm",
                waited,
                REST_LIMIT_TICKS,
                REST_RPM
            );
            Next::Advance
        } else if waited >= REST_LIMIT_TICKS {
            check!(
                false,
                "rotors at rest within {=u32} ticks: true {=f32} / {=f32} rpm, measured {=f32} / {=f32} rpm",
                REST_LIMIT_TICKS,
                true_speed[0],
                true_speed[1],
                measured[0],
                measured[1]
            );
            Next::Abort
        } else {
            Next::Wait
        }
    }

    /// Part 6: the self-test asked for, the model's record of its drives cleared
    /// and the rotors' rest angles logged.
    fn start_self_test<L: LinkLock, W: WorldLock>(&mut self, io: &mut Io<'_, L, W>) -> Next {
        defmt::info!("script: self-test");
        let angles = io.world.lock(|w| {
            w.self_test_ticks = 0;
            w.drive_start = [None; 2];
            w.drive_ticks = [0; 2];
            w.drive_peak_rpm = [0.0; 2];
            w.angle_turns
        });
        defmt::info!(
            "rest angles (model, from the index): {=f32} / {=f32} deg",
            angles[0] * 360.0,
            angles[1] * 360.0
        );
        self.travel_nacked = false;
        if !self.ack(io, &Request::RunSelfTest, "RunSelfTest") {
            return Next::Abort;
        }
        Next::Advance
    }

    /// Part 6: the self-test polled every tick until it has ended, within
    /// [`self_test_limit_ticks`]; a `Travel` while it drives rotor 1 `Nack Busy`.
    fn poll_self_test<L: LinkLock, W: WorldLock>(
        &mut self,
        io: &mut Io<'_, L, W>,
        waited: u32,
    ) -> Next {
        let Some(report) = self.read_self_test(io) else {
            check!(false, "ReadSelfTest: SelfTest");
            return Next::Abort;
        };
        let limit = self_test_limit_ticks();
        match report.status {
            SelfTestStatus::Done | SelfTestStatus::Aborted => {
                check!(
                    report.status == SelfTestStatus::Done && waited <= limit,
                    "self-test {} after {=u32} ticks (limit {=u32}, the documented worst case)",
                    report.status,
                    waited,
                    limit
                );
                self.self_test = Some(report);
                Next::Advance
            }
            _ if waited >= limit => {
                check!(
                    false,
                    "self-test finished within {=u32} ticks: still {}",
                    limit,
                    report.status
                );
                Next::Abort
            }
            SelfTestStatus::Running => {
                // A run command while rotor 1 is driven: refused, the test
                // goes on.
                let driving = io.world.lock(|w| w.drive_start[0].is_some());
                if driving && !self.travel_nacked {
                    self.travel_nacked = true;
                    self.nack(
                        io,
                        &travel_right(),
                        NackReason::Busy,
                        "Travel while the self-test drives rotor 1",
                    );
                }
                Next::Wait
            }
            SelfTestStatus::NotRun if waited < START_LIMIT_TICKS => Next::Wait,
            SelfTestStatus::NotRun => {
                check!(
                    false,
                    "self-test started within {=u32} ticks",
                    START_LIMIT_TICKS
                );
                Next::Abort
            }
        }
    }

    /// Part 6: the self-test's result: per rotor both polarities, the index, the
    /// model's counts a turn and the index offset the model predicts
    /// ([`index_offset_model`]); the result stored in flash with the table; idle.
    fn self_test_result<L: LinkLock, W: WorldLock>(&mut self, io: &mut Io<'_, L, W>) -> Next {
        let Some(report) = self.self_test else {
            return Next::Abort;
        };
        if !self.travel_nacked {
            check!(false, "a Travel sent while the self-test drove rotor 1");
        }
        let (ticks, starts, driven, peak, n, cost) = io.world.lock(|w| {
            (
                w.self_test_ticks,
                w.drive_start,
                w.drive_ticks,
                w.drive_peak_rpm,
                w.encoder_counts,
                w.cost_self_test,
            )
        });
        // Left out of the comparison as the other measurements (`report`
        // logs those, with the calibration to convert into instructions).
        defmt::info!(
            "measure: control step, self-test: {=u32} steps, mean {=u32} / max {=u32} SysTick counts",
            cost.steps,
            cost.mean(),
            cost.max
        );
        defmt::info!(
            "self-test: {=u32} ticks in state self_test; driven {=u32} / {=u32} ticks, peak {=f32} / {=f32} rpm (model)",
            ticks,
            driven[0],
            driven[1],
            peak[0],
            peak[1]
        );
        for (k, r) in report.result.rotors.iter().enumerate() {
            check_rotor_self_test(k + 1, r, starts[k], n);
        }
        let stored = storage::load(&*io.flash);
        check!(
            stored.as_ref().is_some_and(|s| s.sequence == 2
                && s.record.self_test == Some(report.result)
                && Some(&s.record.tuning) == self.table.as_ref()),
            "flash record {=u32}: the self-test result with the table written",
            stored.as_ref().map_or(0, |s| s.sequence)
        );
        check!(
            Self::state_now(io) == State::Idle,
            "idle after the self-test"
        );
        Next::Advance
    }

    /// Part 6: the identification asked for, the rotors at rest after the
    /// self-test.
    fn start_identify<L: LinkLock, W: WorldLock>(&mut self, io: &mut Io<'_, L, W>) -> Next {
        defmt::info!("script: motor identification");
        self.travel_nacked = false;
        if !self.ack(io, &Request::RunIdentify, "RunIdentify") {
            return Next::Abort;
        }
        Next::Advance
    }

    /// Part 6: the identification polled every tick until it has ended, within
    /// [`IDENTIFY_LIMIT_TICKS`]; a `Travel` while it runs `Nack Busy`.
    fn poll_identify<L: LinkLock, W: WorldLock>(
        &mut self,
        io: &mut Io<'_, L, W>,
        waited: u32,
    ) -> Next {
        let Some(report) = self.read_identify(io) else {
            check!(false, "ReadIdentify: Identify");
            return Next::Abort;
        };
        match report.status {
            IdentifyStatus::Done | IdentifyStatus::Aborted => {
                check!(
                    report.status == IdentifyStatus::Done,
                    "identification {} after {=u32} ticks (limit {=u32})",
                    report.status,
                    waited,
                    IDENTIFY_LIMIT_TICKS
                );
                self.identify = Some(report);
                Next::Advance
            }
            _ if waited >= IDENTIFY_LIMIT_TICKS => {
                check!(
                    false,
                    "identification finished within {=u32} ticks: still {}",
                    IDENTIFY_LIMIT_TICKS,
                    report.status
                );
                Next::Abort
            }
            _ => {
                if report.status == IdentifyStatus::Running && !self.travel_nacked {
                    self.travel_nacked = true;
                    self.nack(
                        io,
                        &travel_right(),
                        NackReason::Busy,
                        "Travel while the identification runs",
                    );
                }
                Next::Wait
            }
        }
    }

    /// Part 6: the identification's result against the model's constants, its
    /// cost, and the flash record.
    fn identify_result<L: LinkLock, W: WorldLock>(&mut self, io: &mut Io<'_, L, W>) -> Next {
        let Some(report) = self.identify else {
            return Next::Abort;
        };
        if !self.travel_nacked {
            check!(false, "a Travel sent while the identification ran");
        }
        let cost = io.world.lock(|w| w.cost_identify);
        // Left out of the comparison as the other measurements.
        defmt::info!(
            "measure: control step, identify: {=u32} steps, mean {=u32} / max {=u32} SysTick counts",
            cost.steps,
            cost.mean(),
            cost.max
        );
        for (k, r) in report.identity.rotors.iter().enumerate() {
            check_rotor_identity(k + 1, r);
        }
        let stored = storage::load(&*io.flash);
        check!(
            stored.as_ref().is_some_and(|s| s.sequence == 3
                && s.record.identity == Some(report.identity)
                && s.record.self_test == self.self_test.map(|t| t.result)),
            "flash record {=u32}: the identification with the table and the self-test",
            stored.as_ref().map_or(0, |s| s.sequence)
        );
        check!(
            Self::state_now(io) == State::Idle,
            "idle after the identification"
        );
        Next::Advance
    }

    /// Part 7, the E-stop fault: travel right again.
    fn estop_travel<L: LinkLock, W: WorldLock>(&mut self, io: &mut Io<'_, L, W>) -> Next {
        defmt::info!("script: E-stop fault while running, captured");
        self.ack(
            io,
            &Request::ArmCapture {
                trigger: Trigger::Fault,
                window: 1,
            },
            "ArmCapture on a fault",
        );
        self.ack(io, &travel_right(), "Travel right");
        Next::Advance
    }

    /// Part 7: the capture of the fault's tick, read over the link.
    fn check_fault_capture<L: LinkLock, W>(&mut self, io: &mut Io<'_, L, W>) {
        let info = match self.ask(io, &Request::GetCapture) {
            Some(Response::Capture(info)) => info,
            _ => {
                check!(false, "GetCapture: CaptureInfo");
                return;
            }
        };
        check!(
            info.status == CaptureStatus::Done
                && info.recorded == 1
                && info.capacity as usize == shared::capture::BOARD_CAPACITY
                && info.start.state == State::Running
                && info.machine.crc32 == crate::machine::MACHINE_FILE_CRC32
                && info.machine.len == crate::machine::MACHINE_FILE_LEN,
            "capture on the fault: done, 1 of {=u16} ticks, from {=str}, machine file stamped",
            info.capacity,
            info.start.state.name()
        );
        let record = match self.ask(io, &Request::ReadCapture { first: 0 }) {
            Some(Response::CaptureRecords {
                first: 0,
                count: 1,
                records,
            }) => Record::from_bytes(&records[0]),
            _ => None,
        };
        check!(
            record.is_some_and(|r| r.state == State::Fault
                && r.faults.contains(Faults::ESTOP)
                && r.estop
                && r.duty_raw == [None, None]),
            "the captured tick: fault, ESTOP, the E-stop open, both bridges off"
        );
    }

    /// Part 7: the E-stop circuit opened, [`RUN_BEFORE_FAULT_TICKS`] into the
    /// run.
    fn open_estop<L: LinkLock, W: WorldLock>(
        &mut self,
        io: &mut Io<'_, L, W>,
        waited: u32,
    ) -> Next {
        if waited < RUN_BEFORE_FAULT_TICKS {
            return Next::Wait;
        }
        defmt::info!("E-stop opened");
        self.inject(io, true, [false; 2]);
        Next::Advance
    }

    /// Part 7: `ESTOP` latched in the first tick that sees the circuit open, the
    /// outputs safe in that tick; a reset asked for while it is still open.
    fn estop_latched<L: LinkLock, W: WorldLock>(&mut self, io: &mut Io<'_, L, W>) -> Next {
        let Some(seen) = io.world.lock(|w| w.first_fault) else {
            check!(false, "ESTOP latched in the first tick that sees it");
            return Next::Abort;
        };
        check!(
            seen.faults.contains(Faults::ESTOP) && seen.tick.wrapping_sub(self.injected_at) == 1,
            "ESTOP latched in the first tick that sees the circuit open (bound: that tick), faults {}",
            seen.faults
        );
        check_outputs_cut(&seen);
        self.check_fault_capture(io);
        self.ack(
            io,
            &Request::Command(Command::ResetFaults),
            "ResetFaults, E-stop open",
        );
        Next::Advance
    }

    /// Part 7: the fault kept while the E-stop is open; the circuit closed and a
    /// reset asked for.
    fn estop_reset<L: LinkLock, W: WorldLock>(&mut self, io: &mut Io<'_, L, W>) -> Next {
        let Some(s) = self.status(io) else {
            return Next::Abort;
        };
        check!(
            s.state == State::Fault && s.faults.contains(Faults::ESTOP),
            "still fault while the E-stop is open: {}",
            s.faults
        );
        defmt::info!("E-stop closed");
        self.inject(io, false, [false; 2]);
        self.ack(
            io,
            &Request::Command(Command::ResetFaults),
            "ResetFaults, E-stop closed",
        );
        Next::Advance
    }

    /// Part 8, the deadline: no overrun so far, then the control task made to
    /// work [`overrun_us`] longer once, [`RUN_BEFORE_FAULT_TICKS`] into the run.
    fn inject_overrun<L: LinkLock, W: WorldLock>(
        &mut self,
        io: &mut Io<'_, L, W>,
        waited: u32,
    ) -> Next {
        if waited < RUN_BEFORE_FAULT_TICKS {
            return Next::Wait;
        }
        let overruns = io.state.lock(|l| l.status.telemetry.overruns);
        check!(
            overruns == 0,
            "no overrun so far: {=u16} ticks missed their deadline",
            overruns
        );
        let overrun = overrun_us();
        defmt::info!("control task busy {=u32} us longer once", overrun);
        io.world.lock(|w| {
            w.injected.overrun_us = overrun;
            w.first_fault = None;
        });
        self.injected_at = io.tick;
        Next::Advance
    }

    /// Part 8: `DEADLINE` latched in the tick after the overrun, the outputs safe
    /// in that tick, the overrun counted and its tick's busy time in the status; a
    /// reset asked for.
    fn deadline_latched<L: LinkLock, W: WorldLock>(
        &mut self,
        io: &mut Io<'_, L, W>,
        waited: u32,
    ) -> Next {
        let Some(seen) = io.world.lock(|w| w.first_fault) else {
            if waited <= 3 {
                return Next::Wait;
            }
            check!(false, "DEADLINE latched after the overrun");
            return Next::Abort;
        };
        // The overrun ends tick n + 1 (the first after the injection);
        // tick n + 2 reads its duration.
        check!(
            seen.faults == Faults::DEADLINE && seen.tick.wrapping_sub(self.injected_at) == 2,
            "DEADLINE latched in the tick after the overrun (bound: that tick), faults {}, {=u32} ticks after the injection",
            seen.faults,
            seen.tick.wrapping_sub(self.injected_at)
        );
        check_outputs_cut(&seen);
        let Some(s) = self.status(io) else {
            return Next::Abort;
        };
        let t = s.telemetry;
        // The status of the tick that latched it: the overrun tick's
        // duration, and the count.
        check!(
            u32::from(t.tick_busy_us) >= overrun_us() && t.overruns == 1 && s.state == State::Fault,
            "status: {=str}, {=u16} overrun counted, the overrun tick busy {=u16} us",
            s.state.name(),
            t.overruns,
            t.tick_busy_us
        );
        self.ack(
            io,
            &Request::Command(Command::ResetFaults),
            "ResetFaults after the overrun",
        );
        Next::Advance
    }

    /// Part 9, the encoder fault: encoder 2 disconnected,
    /// [`RUN_BEFORE_FAULT_TICKS`] into the run; the controller's detection bound for
    /// its speed ([`encoder_bound_ticks`]).
    fn disconnect_encoder<L: LinkLock, W: WorldLock>(
        &mut self,
        io: &mut Io<'_, L, W>,
        waited: u32,
    ) -> Next {
        if waited < RUN_BEFORE_FAULT_TICKS {
            return Next::Wait;
        }
        let speed = io.state.lock(|l| l.status.telemetry.speed_rpm[1]);
        self.bound_ticks = encoder_bound_ticks(&Params::reference(), speed);
        defmt::info!(
            "encoder 2 disconnected; bound {=u32} ticks",
            self.bound_ticks
        );
        self.inject(io, false, [false, true]);
        Next::Advance
    }

    /// Part 9: `ENCODER` (or `STALL`) latched within the bound, the outputs safe
    /// in that tick; heartbeats stop, the encoder stays disconnected.
    fn encoder_fault_latched<L: LinkLock, W: WorldLock>(
        &mut self,
        io: &mut Io<'_, L, W>,
        waited: u32,
    ) -> Next {
        match io.world.lock(|w| w.first_fault) {
            None if waited <= self.bound_ticks + 1 => Next::Wait,
            None => {
                check!(false, "encoder fault within {=u32} ticks", self.bound_ticks);
                Next::Abort
            }
            Some(seen) => {
                let latency = seen.tick.wrapping_sub(self.injected_at);
                check!(
                    seen.faults.intersects(Faults::ENCODER | Faults::STALL)
                        && latency <= self.bound_ticks,
                    "fault {} latched {=u32} ticks after the disconnection (bound {=u32})",
                    seen.faults,
                    latency,
                    self.bound_ticks
                );
                check_outputs_cut(&seen);
                // Left disconnected: the counter has lost counts, so the index
                // is no longer a whole number of turns from the last one, and
                // the controller would latch ENCODER again at the next pulse.
                self.keepalive = false;
                Next::Advance
            }
        }
    }

    /// Part 10: the status in `ENCODER` fault; the telemetry stream stopped, and
    /// what it delivered: frames in sequence, [`TELEMETRY_PERIOD_MS`] apart, every
    /// heartbeat answered, every frame parsed.
    fn telemetry_off<L: LinkLock, W: WorldLock>(&mut self, io: &mut Io<'_, L, W>) -> Next {
        let Some(s) = self.status(io) else {
            return Next::Abort;
        };
        check!(
            s.state == State::Fault && s.faults.contains(Faults::ENCODER),
            "status: {=str}, faults {}",
            s.state.name(),
            s.faults
        );
        self.ack(
            io,
            &Request::StreamTelemetry { period_ms: 0 },
            "StreamTelemetry off",
        );
        let t = self.host.telemetry;
        check!(
            t.frames > 10 && t.seq_gaps == 0 && t.min_step_ms >= u32::from(TELEMETRY_PERIOD_MS),
            "telemetry: {=u32} frames, {=u32} sequence gaps, at least {=u32} ms apart",
            t.frames,
            t.seq_gaps,
            t.min_step_ms
        );
        check!(
            self.heartbeat_failures == 0 && self.host.bad_frames == 0,
            "heartbeats all answered, every frame from the device parsed"
        );
        Next::Advance
    }

    /// Part 10: the stream is off: nothing more comes. Part 11, an unexpected
    /// interrupt while driving: the encoder back, the fault reset.
    fn stream_stopped<L: LinkLock, W: WorldLock>(
        &mut self,
        io: &mut Io<'_, L, W>,
        waited: u32,
    ) -> Next {
        let frames = self.host.telemetry.frames;
        if waited < 300 {
            return Next::Wait;
        }
        check!(
            self.host.telemetry.frames == frames,
            "no telemetry after the stream was stopped"
        );
        defmt::info!("script: an unexpected interrupt while the motors are driven");
        self.inject(io, false, [false; 2]);
        self.ack(io, &Request::Command(Command::ResetFaults), "ResetFaults");
        Next::Advance
    }

    /// Part 11: one command a tick: the run command at the tick after the reset;
    /// heartbeats again.
    fn travel_to_drive<L: LinkLock, W: WorldLock>(&mut self, io: &mut Io<'_, L, W>) -> Next {
        self.ack(io, &travel_right(), "Travel right");
        self.keepalive = true;
        Next::Advance
    }

    /// Part 11: the bridges driven within [`RUNNING_LIMIT_TICKS`]: the script is
    /// done, and [`Script::end`] pends the unexpected interrupt after the report.
    fn await_driving<L: LinkLock, W: WorldLock>(
        &mut self,
        io: &mut Io<'_, L, W>,
        waited: u32,
    ) -> Next {
        let bridges = io.world.lock(|w| w.bridges);
        if bridges.iter().any(|b| b.duty() != 0.0) {
            check!(
                true,
                "driving {=u32} ticks after the run command: the interrupt is pended after the checks' report",
                waited
            );
            self.armed = true;
            Next::Advance
        } else if waited >= RUNNING_LIMIT_TICKS {
            check!(false, "driving within {=u32} ticks", RUNNING_LIMIT_TICKS);
            Next::Abort
        } else {
            Next::Wait
        }
    }

    /// The answers of the last exchange.
    fn host_answers(&self) -> &[(u16, Response)] {
        self.host.answers()
    }

    /// Whether every step ran.
    pub fn completed(&self) -> bool {
        self.step >= STEPS
    }

    /// The run's end, after the measurements. When the last step left the motors
    /// driven, the interrupt nothing is bound to is pended ([`pend_unexpected`]):
    /// its default handler ends the run ([`unexpected_interrupt`]), and a run that
    /// goes on past it fails. Otherwise the verdict.
    pub fn end(&self) -> ! {
        if self.armed {
            pend_unexpected();
            for _ in 0..1000 {
                cortex_m::asm::nop();
            }
            check!(false, "the pended interrupt reached the default handler");
        }
        super::checks::finish()
    }
}

/// Check rotor `rotor`'s self-test result `r` against the model: both
/// polarities, the index seen, `n` counts a turn, and the index offset the model
/// predicts from the rest angle at `start`, the self-test's drive of it.
fn check_rotor_self_test(rotor: usize, r: &RotorSelfTest, start: Option<DriveStart>, n: u32) {
    check!(
        r.motor_polarity_ok && r.encoder_polarity_ok && r.index_seen,
        "rotor {=usize}: motor polarity ok {=bool}, encoder polarity ok {=bool}, index seen {=bool}",
        rotor,
        r.motor_polarity_ok,
        r.encoder_polarity_ok,
        r.index_seen
    );
    check!(
        r.counts_per_rev == n,
        "rotor {=usize}: {=u32} counts a turn (model {=u32})",
        rotor,
        r.counts_per_rev,
        n
    );
    let Some(start) = start else {
        check!(false, "rotor {=usize}: driven by the self-test", rotor);
        return;
    };
    let (exact, predicted) = index_offset_model(start.angle_turns, n);
    check!(
        r.index_offset_counts < n && r.index_offset_counts == predicted,
        "rotor {=usize}: index offset {=u32} counts, model {=u32} ({=f32} from its rest angle {=f32} deg at tick {=u32})",
        rotor,
        r.index_offset_counts,
        predicted,
        exact,
        start.angle_turns * 360.0,
        start.tick
    );
}

/// Check that the tick that latched a fault left the outputs safe: both
/// H-bridges off.
fn check_outputs_cut(seen: &FaultSeen) {
    check!(
        seen.bridges == [Bridge::Off; 2],
        "driver disabled and duties 0 in that tick"
    );
}

/// One rotor's identification against the rotor model's constants
/// ([`super::plant`]: the reference machine's motor, `J = 1e-5 kg m^2`): every
/// value measured, within 5 % (friction within 20 %).
fn check_rotor_identity(rotor: usize, r: &RotorIdentity) {
    let reference = Params::reference().rotors[0];
    let within = |value: f32, truth: f32, tolerance: f32| abs(value - truth) <= tolerance * truth;
    check!(
        r.shortfall.is_none()
            && within(r.resistance_ohm.value, reference.resistance_ohm, 0.05)
            && within(r.torque_constant.value, reference.torque_constant, 0.05)
            && within(r.inertia_kg_m2.value, reference.inertia_kg_m2, 0.05)
            && within(r.coulomb_friction_nm.value, super::plant::COULOMB_NM, 0.2)
            && within(r.viscous_friction.value, super::plant::VISCOUS_NM_S, 0.2),
        "rotor {=usize} identified: R {=f32} ohm, k {=f32} N m/A, J {=f32} kg m^2, T_c {=f32} N m, b {=f32} N m s (shortfall {})",
        rotor,
        r.resistance_ohm.value,
        r.torque_constant.value,
        r.inertia_kg_m2.value,
        r.coulomb_friction_nm.value,
        r.viscous_friction.value,
        r.shortfall
    );
}

/// Travel right at [`SPEED_RPM`].
fn travel_right() -> Request {
    Request::Command(Command::Travel {
        direction: Direction::Right,
        speed_rpm: SPEED_RPM,
    })
}

/// The longest a self-test can take, ticks: the documented worst case, three
/// settles of [`SETTLE_TIMEOUT_S`] and two drives of [`DRIVE_TIMEOUT_S`] (17 s), and
/// [`START_LIMIT_TICKS`] for the request to reach the control task.
fn self_test_limit_ticks() -> u32 {
    let worst_s = 3.0 * SETTLE_TIMEOUT_S + 2.0 * DRIVE_TIMEOUT_S;
    (worst_s * CONTROL_RATE_HZ + 0.5) as u32 + START_LIMIT_TICKS
}

/// The index offset the self-test should measure for a rotor at rest at
/// `angle_turns` (turns from its index, driven sense, in [0, 1)) with `n` counts a
/// turn, from the model's geometry alone: `(exact, counts)`. `exact` is the
/// distance forward to the model's index at angle 0, `n (1 - angle)`, in (0, n];
/// `counts` is what an ideal encoder gives for it, whose counter reads the whole
/// counts passed, `floor(n angle)` at the rest position and a multiple of `n` at
/// the index: `(n - floor(n angle)) mod n`, within a count above `exact`.
pub fn index_offset_model(angle_turns: f32, n: u32) -> (f32, u32) {
    let exact = (1.0 - angle_turns) * n as f32;
    let at_rest = (angle_turns * n as f32) as u32;
    (exact, (n - at_rest.min(n)) % n.max(1))
}

/// The message id byte of `request`.
fn request_id(request: &Request) -> u8 {
    use shared::protocol::Message;
    request.id() as u8
}

/// The controller's detection bound for a rotor whose encoder stops at
/// `speed_rpm`, in ticks: `t_fall + stall_time_s + encoder_time_s` (the
/// controller's fault table, "any current"), with `t_fall` the ticks the filtered
/// speed takes to fall below the stall speed, `ceil(ln(w0 / w_stall) / ln(1 + dt /
/// tau_f))`, counted here by repeated division.
pub fn encoder_bound_ticks(p: &Params, speed_rpm: f32) -> u32 {
    let dt = p.tick_s();
    let mut w = speed_rpm;
    let mut fall = 0;
    while w >= p.limits.stall_speed_rpm && fall < 100_000 {
        w /= 1.0 + dt / p.speed_filter_tau_s;
        fall += 1;
    }
    let timers = (p.limits.stall_time_s + p.limits.encoder_time_s) / dt;
    fall + (timers + 0.5) as u32
}

/// The interrupt the script pends at the end: CAN1 TX, bound to no task.
const UNEXPECTED_IRQ: Interrupt = Interrupt::CAN1_TX;
/// Set when the script pends it.
static PENDED: AtomicBool = AtomicBool::new(false);

/// Pend `UNEXPECTED_IRQ` (unmasked first: a masked interrupt stays pending and
/// never runs). The default handler takes it at once.
pub fn pend_unexpected() {
    defmt::info!("script: pending an interrupt nothing is bound to");
    PENDED.store(true, Ordering::SeqCst);
    // SAFETY: unmasking an interrupt without a task only reaches the default
    // handler, which is what this step checks.
    unsafe { NVIC::unmask(UNEXPECTED_IRQ) };
    NVIC::pend(UNEXPECTED_IRQ);
}

/// The default handler's end of the scripted run (binary `qemu`), after its cut:
/// `irqn` the interrupt it took, `driven` whether a bridge input was high before
/// the cut. Checks, then the verdict.
pub fn unexpected_interrupt(irqn: i16, driven: bool) -> ! {
    check!(
        PENDED.load(Ordering::SeqCst) && irqn == UNEXPECTED_IRQ as i16,
        "default handler: interrupt {=i16}, the one the script pended",
        irqn
    );
    check!(driven, "the bridges were driven when it came");
    check!(
        !super::pwm::driven(),
        "every bridge input low after the handler's cut"
    );
    super::checks::finish()
}
