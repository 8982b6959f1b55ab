//! The device's end of the link, as the firmware runs it: received bytes ->
//! [`Decoder`] -> one answer per frame ([`answer_event`]) -> encoded frames back;
//! the telemetry stream; the flash writes. It lives here, not in `firmware/`, so
//! that host tests (and `host-sim device`'s tests) run the very code the board runs.
//!
//! Data flow on the board: the UART RX interrupt pushes bytes into a ring;
//! [`Link::poll`] (the lowest-priority task) takes them one by one, decodes,
//! answers against [`LinkState`] (shared with the control task under a lock) and
//! hands the encoded answers to a send function. Commands reach the control task
//! through [`LinkState::command`], one per tick; a new tuning table through
//! [`LinkState::new_tuning`]; a self-test request through
//! [`LinkState::self_test_requested`], an identification's through
//! [`LinkState::identify_requested`].

use super::{
    answer_event, encode, Decoder, Device, NackReason, Response, StatusReport,
    FRAME_GAP_TIMEOUT_MS, MAX_FRAME,
};
use crate::capture::{Capture, CaptureInfo, Slot, Start, Trigger, RECORDS_PER_FRAME};
use crate::controller::identify::{IdentifyProgress, IdentifyReport, IdentifyStatus, Identity};
use crate::controller::self_test::{SelfTest, SelfTestReport, SelfTestStatus};
use crate::controller::{
    may_write_table, Command, Controller, Inputs, Outputs, Params, Telemetry, TuningTable,
};
use crate::storage::{self, Record, Stored};
use embedded_storage::nor_flash::NorFlash;

/// Bytes [`Link::poll`] takes from the receive side per call: bounded work per
/// pass, so the caller gets to sleep and to check its clock.
pub const POLL_CHUNK: usize = 64;

/// What the link and the control task share (under a lock on the board).
#[derive(Debug)]
pub struct LinkState {
    /// The latest control tick's report (written by the control task each tick).
    pub status: StatusReport,
    /// A command waiting for the next control tick (taken by the control task).
    pub command: Option<Command>,
    /// The tuning table in use (a copy of the controller's).
    pub tuning: TuningTable,
    /// A tuning table stored in flash and waiting for the control task to hand it
    /// to the controller (taken by the control task).
    pub new_tuning: Option<TuningTable>,
    /// The self-test's status and latest result (written by the control task).
    pub self_test: SelfTestReport,
    /// The status of the controller's self-test report when it was last copied:
    /// a finished report is copied once, so that a later request the controller
    /// refuses stays reported aborted.
    pub self_test_seen: SelfTestStatus,
    /// A self-test was requested and waits for the control task to start it.
    pub self_test_requested: bool,
    /// A finished self-test's result waits to be stored in flash with the table
    /// (set by the control task; the link stores it when writing is allowed).
    pub self_test_unsaved: bool,
    /// The newest finished self-test's result: the stored one at start, replaced
    /// when a test finishes. What a store writes with the table, so that a test
    /// aborted later never drops a good result from flash.
    pub finished_self_test: Option<SelfTest>,
    /// The motor identification's status and latest result (written by the
    /// control task).
    pub identify: IdentifyReport,
    /// An identification was requested and waits for the control task to start
    /// it.
    pub identify_requested: bool,
    /// The identification's progress when its report was last copied.
    pub identify_progress: IdentifyProgress,
    /// A finished identification waits to be stored in flash with the table.
    pub identify_unsaved: bool,
    /// The newest finished motor identification: the stored one at start,
    /// replaced when one finishes. What a store writes with the table, so that
    /// storing a table never drops it.
    pub finished_identity: Option<Identity>,
    /// Telemetry period, ms (0: none).
    pub telemetry_period_ms: u16,
    /// Received bytes lost since the start (the receive ring full, or the UART's
    /// overrun), as the receiving side counts them; reported in every status.
    pub rx_dropped: u32,
    /// A flash store is under way (outside the lock): the control task holds
    /// motion commands and a requested self-test back until it ends, so the
    /// motors stay stopped while the flash is written.
    pub storing: bool,
    /// The capture: armed by the link, recorded by the control task
    /// ([`crate::capture`]); none until [`LinkState::with_capture`].
    pub capture: Capture,
}

/// Take the stored record's tuning table into `params` (a table written over the
/// link wins over the compiled-in one); `stored` is [`storage::load`]'s answer.
pub fn use_stored(params: &mut Params, stored: Option<&Stored>) {
    if let Some(s) = stored {
        params.tuning = s.record.tuning.clone();
    }
}

impl LinkState {
    /// The state at start, for `controller` before its first tick, with the
    /// self-test result of the `stored` record if it holds one.
    pub fn at_start(controller: &Controller, stored: Option<&Stored>) -> Self {
        let self_test = stored
            .and_then(|s| s.record.self_test)
            .map(|result| SelfTestReport {
                status: SelfTestStatus::Done,
                result,
            });
        let mut state = LinkState::new(
            StatusReport {
                uptime_ms: 0,
                state: controller.state(),
                faults: controller.faults(),
                telemetry: no_telemetry(),
                rx_dropped: 0,
            },
            controller.params().tuning.clone(),
            self_test,
        );
        if let Some(identity) = stored.and_then(|s| s.record.identity) {
            state.finished_identity = Some(identity);
            state.identify = IdentifyReport {
                status: IdentifyStatus::Done,
                identity,
            };
        }
        state
    }

    /// The state at start: `status` of the controller before its first tick, the
    /// table in use, the stored self-test result if any.
    pub fn new(
        status: StatusReport,
        tuning: TuningTable,
        self_test: Option<SelfTestReport>,
    ) -> Self {
        let finished_self_test = self_test
            .filter(|r| r.status == SelfTestStatus::Done)
            .map(|r| r.result);
        LinkState {
            status,
            command: None,
            tuning,
            new_tuning: None,
            finished_self_test,
            finished_identity: None,
            identify: IdentifyReport {
                status: IdentifyStatus::NotRun,
                identity: Identity::default(),
            },
            identify_requested: false,
            identify_progress: IdentifyProgress {
                run: 0,
                status: IdentifyStatus::NotRun,
                rotors_finished: 0,
            },
            identify_unsaved: false,
            self_test: self_test.unwrap_or(SelfTestReport {
                status: SelfTestStatus::NotRun,
                result: Default::default(),
            }),
            self_test_requested: false,
            self_test_seen: SelfTestStatus::NotRun,
            self_test_unsaved: false,
            telemetry_period_ms: 0,
            rx_dropped: 0,
            storing: false,
            capture: Capture::none(),
        }
    }

    /// The state with `capture` as its capture (a buffer of the board's).
    pub fn with_capture(mut self, capture: Capture) -> Self {
        self.capture = capture;
        self
    }

    /// The control task's side, before its step: hand a newly stored tuning
    /// table to `controller`, start a requested self-test or identification, and
    /// take the waiting command for this tick. A procedure the controller refuses
    /// (the link checked idle and at rest on the previous tick's status; the
    /// controller checks again) is reported aborted, nothing measured.
    pub fn take_for_tick(&mut self, controller: &mut Controller) -> ForTick {
        let state_before = controller.state();
        let (tuning_handed, tuning_refused) = match self.new_tuning.take() {
            Some(table) => {
                let taken = controller.set_tuning(table);
                (taken, !taken)
            }
            None => (false, false),
        };
        // A self-test drives the motors: like a motion command, it waits while the
        // flash is written.
        let self_test_asked = !self.storing && core::mem::take(&mut self.self_test_requested);
        let self_test_started = self_test_asked && controller.start_self_test();
        let self_test_refused = self_test_asked && !self_test_started;
        if self_test_refused {
            self.self_test = SelfTestReport {
                status: SelfTestStatus::Aborted,
                result: Default::default(),
            };
        }
        // The identification, likewise.
        let identify_asked = !self.storing && core::mem::take(&mut self.identify_requested);
        let identify_started = identify_asked && controller.start_identify();
        let identify_refused = identify_asked && !identify_started;
        if identify_refused {
            self.identify = IdentifyReport {
                status: IdentifyStatus::Aborted,
                identity: Identity::default(),
            };
        }
        // While the flash is written, a motion command waits (a stop or a
        // heartbeat passes: they never start the motors).
        let command = match self.command {
            Some(Command::Stop | Command::Heartbeat | Command::ResetFaults) | None => {
                self.command.take()
            }
            Some(_) if self.storing => None,
            Some(_) => self.command.take(),
        };
        if self.capture.waiting() {
            let before = Start {
                state: state_before,
                speed_rpm: self.status.telemetry.speed_rpm,
                index: controller.index_counts(),
                uptime_ms: self.status.uptime_ms,
            };
            let started = [self_test_started, identify_started, tuning_handed];
            self.capture.note_before(before, started);
        }
        ForTick {
            command,
            tuning_refused,
            self_test_refused,
            identify_refused,
        }
    }

    /// The control task's side, after its step: the tick's status at
    /// `uptime_ms`, and `controller`'s reports. A report still `NotRun` (none
    /// since the start) keeps the result loaded from flash; one that just
    /// finished is marked for storing with the table. A finished report is
    /// copied once, not every tick (the identification's when its progress
    /// changes: a new run, a rotor finished, its status), so that a later request the
    /// controller refuses stays reported aborted. The tick, stepped on `inputs`,
    /// goes to the capture.
    pub fn publish(
        &mut self,
        uptime_ms: u32,
        inputs: &Inputs,
        out: &Outputs,
        controller: &Controller,
    ) {
        self.capture.record(inputs, out);
        self.status = StatusReport::from_outputs(uptime_ms, out);
        self.status.rx_dropped = u16::try_from(self.rx_dropped).unwrap_or(u16::MAX);
        // The self-test's report while it runs (its result grows) and once when
        // it ends.
        let self_test = controller.self_test_report();
        let changed = self_test.status != self.self_test_seen;
        if self_test.status == SelfTestStatus::Running || changed {
            if self.self_test.status == SelfTestStatus::Running
                && self_test.status == SelfTestStatus::Done
            {
                self.self_test_unsaved = true;
                self.finished_self_test = Some(self_test.result);
            }
            if self_test.status != SelfTestStatus::NotRun {
                self.self_test = self_test;
            }
            self.self_test_seen = self_test.status;
        }
        let progress = controller.identify_progress();
        if progress.status != IdentifyStatus::NotRun && progress != self.identify_progress {
            let identify = controller.identify_report();
            if self.identify.status == IdentifyStatus::Running
                && identify.status == IdentifyStatus::Done
            {
                self.identify_unsaved = true;
                self.finished_identity = Some(identify.identity);
            }
            self.identify = identify;
            self.identify_progress = progress;
        }
    }

    /// Ask the control task to start a procedure (its request flag `flag`):
    /// `Busy` while one asked for has not started yet, which the handler's
    /// check of the reports cannot see.
    fn request_procedure(
        &mut self,
        flag: fn(&mut LinkState) -> &mut bool,
    ) -> Result<(), NackReason> {
        if self.self_test_requested || self.identify_requested {
            return Err(NackReason::Busy);
        }
        *flag(self) = true;
        Ok(())
    }

    /// The record to store: `tuning`, the newest finished self-test's result and
    /// motor identification.
    fn record(&self, tuning: &TuningTable) -> Record {
        Record {
            tuning: tuning.clone(),
            self_test: self.finished_self_test,
            identity: self.finished_identity,
        }
    }
}

/// What [`LinkState::take_for_tick`] took for the control tick.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ForTick {
    /// The command for this tick, if one came.
    pub command: Option<Command>,
    /// A new tuning table came but the controller kept its own (motors running).
    pub tuning_refused: bool,
    /// A self-test was requested but the controller did not start it.
    pub self_test_refused: bool,
    /// An identification was requested but the controller did not start it.
    pub identify_refused: bool,
}

/// Telemetry before the first control tick: all zero, nothing measured.
pub fn no_telemetry() -> Telemetry {
    Telemetry {
        speed_rpm: [0.0; 2],
        speed_ref_rpm: [0.0; 2],
        phase_valid: false,
        phase_offset_deg: 0.0,
        phase_loop_closed: false,
        commanded_offset_deg: 0.0,
        target_offset_deg: 0.0,
        phase_error_deg: 0.0,
        current: [0.0; 2],
        supply_voltage: 0.0,
        duty: [0.0; 2],
        command_rejected: false,
        tick_late_us: 0,
        tick_busy_us: 0,
        overruns: 0,
    }
}

/// The lock on [`LinkState`] the link works through, taken for each access (on
/// the board, RTIC's lock that the control task shares; in a test or a simulated
/// device, the state itself).
pub trait StateLock {
    /// Run `f` on the state under the lock.
    fn lock<R>(&mut self, f: impl FnOnce(&mut LinkState) -> R) -> R;
}

impl StateLock for LinkState {
    fn lock<R>(&mut self, f: impl FnOnce(&mut LinkState) -> R) -> R {
        f(self)
    }
}

impl<L: StateLock + ?Sized> StateLock for &mut L {
    fn lock<R>(&mut self, f: impl FnOnce(&mut LinkState) -> R) -> R {
        (**self).lock(f)
    }
}

/// The [`Device`] the handler answers on: [`LinkState`] through its lock, taken
/// for each access and never across a flash operation, and the flash. (The
/// handler asks the device through `&self` for what it only reads; the lock needs
/// `&mut`, hence the cell, borrowed for one access at a time.)
struct Session<'a, L: StateLock, F: NorFlash> {
    state: core::cell::RefCell<&'a mut L>,
    flash: &'a mut F,
}

impl<L: StateLock, F: NorFlash> Session<'_, L, F> {
    /// Run `f` on the state under the lock.
    fn locked<R>(&self, f: impl FnOnce(&mut LinkState) -> R) -> R {
        self.state.borrow_mut().lock(f)
    }
}

impl<L: StateLock, F: NorFlash> Device for Session<'_, L, F> {
    fn status(&self) -> StatusReport {
        self.locked(|s| s.status)
    }

    fn command(&mut self, command: Command) -> Result<(), NackReason> {
        self.locked(|state| {
            // A self-test or an identification drives the motors itself: only
            // stop (which aborts it) and heartbeats while it runs.
            let testing = state.self_test.status == SelfTestStatus::Running
                || state.self_test_requested
                || state.identify.status == IdentifyStatus::Running
                || state.identify_requested;
            if testing && !matches!(command, Command::Stop | Command::Heartbeat) {
                return Err(NackReason::Busy);
            }
            // A heartbeat never replaces a motion command still waiting.
            let waiting = matches!(state.command, Some(c) if c != Command::Heartbeat);
            if !(command == Command::Heartbeat && waiting) {
                state.command = Some(command);
            }
            Ok(())
        })
    }

    fn tuning_table(&self) -> TuningTable {
        self.locked(|s| s.tuning.clone())
    }

    /// The record under the lock, the flash written outside it (an erase takes up
    /// to 2 s, during which the control task must not be masked), the result
    /// under the lock again.
    fn store_tuning_table(&mut self, table: &TuningTable) -> Result<(), NackReason> {
        // The motors checked stopped and the store marked under one lock: a
        // control tick between a check and the mark could take a waiting run
        // command and start the motors just before the erase stalls everything.
        let record = self.locked(|state| {
            // A procedure asked for but not yet started would start meanwhile.
            if state.self_test_requested || state.identify_requested {
                return Err(NackReason::Busy);
            }
            if !may_write_table(state.status.state, state.status.telemetry.speed_rpm) {
                return Err(NackReason::NotStopped);
            }
            state.storing = true;
            Ok(state.record(table))
        })?;
        let stored = storage::store(&mut *self.flash, &record);
        self.locked(|state| {
            state.storing = false;
            if stored.is_ok() {
                state.tuning = table.clone();
                state.new_tuning = Some(table.clone());
                // The finished results went into this record too.
                state.self_test_unsaved = false;
                state.identify_unsaved = false;
            }
        });
        stored.map(|_| ()).map_err(|_| NackReason::StorageFailed)
    }

    fn self_test(&self) -> SelfTestReport {
        self.locked(|s| s.self_test)
    }

    fn start_self_test(&mut self) -> Result<(), NackReason> {
        self.locked(|s| s.request_procedure(|s| &mut s.self_test_requested))
    }

    fn identify(&self) -> IdentifyReport {
        self.locked(|s| s.identify)
    }

    fn start_identify(&mut self) -> Result<(), NackReason> {
        self.locked(|s| s.request_procedure(|s| &mut s.identify_requested))
    }

    fn set_telemetry_period(&mut self, period_ms: u16) {
        self.locked(|s| s.telemetry_period_ms = period_ms);
    }

    fn arm_capture(&mut self, trigger: Trigger, window: u16) -> Result<(), NackReason> {
        self.locked(|s| s.capture.arm(trigger, window))
            .map_err(|_| NackReason::BadValue)
    }

    fn capture_info(&self) -> CaptureInfo {
        self.locked(|s| s.capture.info())
    }

    fn read_capture(&self, first: u16, out: &mut [Slot; RECORDS_PER_FRAME]) -> usize {
        self.locked(|s| s.capture.read(first, out))
    }
}

/// The link task's own state: decoder, output buffer, clocks of the last byte and
/// the last telemetry frame.
pub struct Link {
    decoder: Decoder,
    /// One encoded frame.
    out: [u8; MAX_FRAME],
    /// Sequence counter of the telemetry stream.
    telemetry_seq: u16,
    /// Uptime of the last telemetry frame, ms.
    last_telemetry_ms: u32,
    /// Uptime at which the last byte came, ms.
    last_byte_ms: u32,
}

impl Default for Link {
    fn default() -> Self {
        Link::new()
    }
}

impl Link {
    /// A link with nothing received.
    pub const fn new() -> Self {
        Link {
            decoder: Decoder::new(),
            out: [0; MAX_FRAME],
            telemetry_seq: 0,
            last_telemetry_ms: 0,
            last_byte_ms: 0,
        }
    }

    /// One pass of the link task at uptime `now_ms`:
    ///
    /// 1. take up to [`POLL_CHUNK`] bytes from `rx` (`None`: nothing more now);
    /// 2. give up on a frame after [`FRAME_GAP_TIMEOUT_MS`] of silence inside it;
    /// 3. decode and answer every frame on the state (reached through `state`,
    ///    its lock taken for each access; a flash write runs outside it) and
    ///    `flash`, and `send` the answers;
    /// 4. store a finished self-test's or identification's result, when the
    ///    motors allow a write;
    /// 5. send telemetry when due.
    ///
    /// Returns whether a byte came (the caller sleeps otherwise).
    pub fn poll<F: NorFlash>(
        &mut self,
        mut rx: impl FnMut() -> Option<u8>,
        now_ms: u32,
        mut state: impl StateLock,
        flash: &mut F,
        mut send: impl FnMut(&[u8]),
    ) -> bool {
        // 1. Received bytes into a local chunk.
        let mut chunk = [0u8; POLL_CHUNK];
        let mut n = 0;
        while n < chunk.len() {
            match rx() {
                Some(b) => {
                    chunk[n] = b;
                    n += 1;
                }
                None => break,
            }
        }

        // 2. Silence inside a frame.
        if n > 0 {
            self.last_byte_ms = now_ms;
        } else if self.decoder.held() > 0
            && now_ms.wrapping_sub(self.last_byte_ms) >= FRAME_GAP_TIMEOUT_MS
        {
            self.decoder.abandon();
            self.last_byte_ms = now_ms;
        }

        // 3. Every frame of the chunk, answered (the lock taken per access, never
        // across a flash write).
        let mut input = chunk.get(..n).unwrap_or(&[]);
        while let Some(event) = self.decoder.decode(&mut input) {
            let answer = {
                let mut session = Session {
                    state: core::cell::RefCell::new(&mut state),
                    flash: &mut *flash,
                };
                answer_event(&mut session, event)
            };
            if let Some((seq, response)) = answer {
                if let Ok(len) = encode(&response, seq, &mut self.out) {
                    send(self.out.get(..len).unwrap_or(&[]));
                }
            }
        }

        // 4. A result to keep: the record under the lock, the flash written
        // outside it.
        let record = state.lock(|s| {
            let due = (s.self_test_unsaved || s.identify_unsaved)
                && may_write_table(s.status.state, s.status.telemetry.speed_rpm);
            s.storing |= due;
            due.then(|| s.record(&s.tuning))
        });
        if let Some(record) = record {
            // A failed write leaves the result reported but unsaved; the next
            // table write stores it.
            let _ = storage::store(&mut *flash, &record);
            state.lock(|s| {
                s.storing = false;
                s.self_test_unsaved = false;
                s.identify_unsaved = false;
            });
        }

        // 5. Telemetry when due.
        let last = self.last_telemetry_ms;
        let report = state.lock(|s| {
            let period = u32::from(s.telemetry_period_ms);
            (period > 0 && now_ms.wrapping_sub(last) >= period).then_some(s.status)
        });
        if let Some(status) = report {
            self.last_telemetry_ms = now_ms;
            self.telemetry_seq = self.telemetry_seq.wrapping_add(1);
            if let Ok(len) = encode(
                &Response::Telemetry(status),
                self.telemetry_seq,
                &mut self.out,
            ) {
                send(self.out.get(..len).unwrap_or(&[]));
            }
        }
        n > 0
    }
}
