//! The host link: UART bytes -> the shared protocol's [`Decoder`] -> one answer per
//! frame ([`answer_event`]) -> encoded frames back; and the telemetry stream.
//!
//! Data flow: the USART2 RX interrupt pushes each byte into a lock-free ring
//! ([`RxRing`], heapless SPSC); [`Link::poll`] (run from `idle`, the lowest
//! priority) drains it, decodes, answers against [`LinkState`] (shared with the
//! control task under a lock) and writes the answers with a blocking UART write.
//! Commands go to the control task through [`LinkState::command`], one per tick.

use heapless::spsc::{Consumer, Queue};
use shared::controller::{Command, Telemetry, TuningTable};
use shared::protocol::{
    answer_event, encode, Decoder, Device, NackReason, Response, SelfTestReport, SelfTestStatus,
    StatusReport, FRAME_GAP_TIMEOUT_MS, MAX_FRAME,
};

/// Bytes the RX ring holds: more than one largest frame (414 bytes), so a whole
/// tuning table can arrive while the link task waits for a long control tick.
pub const RX_RING_LEN: usize = 1024;

/// The ring of received bytes, from the RX interrupt to the link task.
pub type RxRing = Queue<u8, RX_RING_LEN>;

/// What the link and the control task share (under an RTIC lock).
pub struct LinkState {
    /// The latest control tick's report (written by the control task each tick).
    pub status: StatusReport,
    /// A command waiting for the next control tick (taken by the control task).
    pub command: Option<Command>,
    /// The tuning table in use (a copy of the controller's).
    pub tuning: TuningTable,
    /// Telemetry period, ms (0: none).
    pub telemetry_period_ms: u16,
}

impl Device for LinkState {
    fn status(&self) -> StatusReport {
        self.status
    }

    fn command(&mut self, command: Command) -> Result<(), NackReason> {
        // A heartbeat never replaces a motion command still waiting.
        let waiting = matches!(self.command, Some(c) if c != Command::Heartbeat);
        if !(command == Command::Heartbeat && waiting) {
            self.command = Some(command);
        }
        Ok(())
    }

    fn tuning_table(&self) -> TuningTable {
        self.tuning.clone()
    }

    fn store_tuning_table(&mut self, _table: &TuningTable) -> Result<(), NackReason> {
        // Not implemented yet: no `storage::Flash` for the STM32F405's sectors 10/11.
        Err(NackReason::StorageFailed)
    }

    fn self_test(&self) -> SelfTestReport {
        SelfTestReport {
            status: SelfTestStatus::NotRun,
            result: Default::default(),
        }
    }

    fn start_self_test(&mut self) -> Result<(), NackReason> {
        // Not implemented yet.
        Err(NackReason::Busy)
    }

    fn set_telemetry_period(&mut self, period_ms: u16) {
        self.telemetry_period_ms = period_ms;
    }
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

    /// One pass of the link task: decode what `rx` holds, answer every frame on
    /// `state` (through `with_state`, which takes the lock), send answers and due
    /// telemetry with `send`; `now_ms` is the uptime. Returns whether there was
    /// anything to do (the caller sleeps otherwise).
    pub fn poll(
        &mut self,
        rx: &mut Consumer<'_, u8>,
        now_ms: u32,
        mut with_state: impl FnMut(&mut dyn FnMut(&mut LinkState)),
        mut send: impl FnMut(&[u8]),
    ) -> bool {
        // Stage 1: move received bytes into a local chunk.
        let mut chunk = [0u8; 64];
        let mut n = 0;
        while n < chunk.len() {
            match rx.dequeue() {
                Some(b) => {
                    chunk[n] = b;
                    n += 1;
                }
                None => break,
            }
        }
        if n > 0 {
            self.last_byte_ms = now_ms;
        } else if self.decoder.held() > 0
            && now_ms.wrapping_sub(self.last_byte_ms) >= FRAME_GAP_TIMEOUT_MS
        {
            // Stage 2: silence inside a frame: give up on it.
            self.decoder.abandon();
            self.last_byte_ms = now_ms;
        }

        // Stage 3: decode and answer every frame of the chunk.
        let mut input = &chunk[..n];
        while let Some(event) = self.decoder.decode(&mut input) {
            let mut answer = None;
            with_state(&mut |state| answer = answer_event(state, event));
            if let Some((seq, response)) = answer {
                if let Ok(len) = encode(&response, seq, &mut self.out) {
                    send(&self.out[..len]);
                }
            }
        }

        // Stage 4: telemetry when due.
        let mut report = None;
        with_state(&mut |state| {
            let period = u32::from(state.telemetry_period_ms);
            if period > 0 && now_ms.wrapping_sub(self.last_telemetry_ms) >= period {
                report = Some(state.status);
            }
        });
        if let Some(status) = report {
            self.last_telemetry_ms = now_ms;
            self.telemetry_seq = self.telemetry_seq.wrapping_add(1);
            if let Ok(len) = encode(
                &Response::Telemetry(status),
                self.telemetry_seq,
                &mut self.out,
            ) {
                send(&self.out[..len]);
            }
        }
        n > 0
    }
}
