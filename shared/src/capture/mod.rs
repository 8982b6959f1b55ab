//! The capture: every control tick of a window, recorded on the board at the
//! tick's own rate into a RAM buffer when a trigger fires, and read out over the
//! link afterwards (docs/protocol.md, "Capture"; `host-sim device capture`).
//!
//! A capture is armed with a trigger and a window of ticks ([`Capture::arm`]).
//! From the tick the trigger fires (that tick included) it keeps one [`Record`]
//! per tick, what the controller was given and what it wrote, until the window
//! is full; then it is done and stays so until it is armed again. The records
//! are stored as bytes ([`RECORD_LEN`] each), ready to send.
//!
//! What the records alone do not say is kept once, in [`CaptureInfo`]: the state
//! before the first tick, the rotors' speeds and the index latches the
//! controller knew then (so that a replay starts the twin where the board
//! was), the values of every run command (the records keep the kind), the tick
//! period and the fingerprint of the machine file the firmware was built for.
//!
//! Triggers ([`Trigger`]):
//! - `now`: the next tick;
//! - `command`: the next tick that takes a command other than a heartbeat, or
//!   starts a self-test or an identification;
//! - `state`: the next tick whose state differs from the state before it;
//! - `fault`: the next tick that ends in [`State::Fault`] from another state.
//!
//! A window holds at most [`MAX_COMMANDS`] run commands (travel, hold): a
//! capture that would take one more ends before that tick, done and marked
//! [`CaptureInfo::ended_early`].
//!
//! The recorder is the control task's (it records in the tick's stage 5,
//! [`crate::tick::Port::publish`]) and the link's (arm, info, read), under the
//! link state's lock: a tick adds one record, a read copies at most
//! [`RECORDS_PER_FRAME`].

mod record;

pub use record::{duty_raw, CommandKind, Record, DUTY_SCALE, RECORD_LEN};

use crate::codec::wire::{Reader, Writer};
use crate::controller::{Command, Direction, Inputs, Outputs, State};

/// Ticks the board's buffer holds: 2 048, that is 2.048 s at 1 kHz, in
/// `2048 x 36 = 73 728` bytes of RAM.
pub const BOARD_CAPACITY: usize = 2048;

/// Run commands (travel, hold) a capture keeps the values of.
pub const MAX_COMMANDS: usize = 16;

/// Records in one [`crate::protocol::Response::CaptureRecords`] frame: 11, so
/// that `3 + 11 x 36 = 399` bytes fit a payload.
pub const RECORDS_PER_FRAME: usize = 11;

/// The buffer a capture records into: one [`RECORD_LEN`]-byte slot per tick.
pub type Slot = [u8; RECORD_LEN];

/// What starts the recording.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Trigger {
    /// The next tick (code 0).
    Now,
    /// The next command other than a heartbeat, or a procedure started (1).
    Command,
    /// The next change of state (2).
    State,
    /// The next fault (3).
    Fault,
}

impl Trigger {
    /// Every trigger, in code order.
    pub const ALL: [Trigger; 4] = [
        Trigger::Now,
        Trigger::Command,
        Trigger::State,
        Trigger::Fault,
    ];

    /// Its wire code.
    pub fn code(self) -> u8 {
        match self {
            Trigger::Now => 0,
            Trigger::Command => 1,
            Trigger::State => 2,
            Trigger::Fault => 3,
        }
    }

    /// The trigger of wire code `b`.
    pub fn from_code(b: u8) -> Option<Trigger> {
        Trigger::ALL.into_iter().find(|t| t.code() == b)
    }

    /// `now`, `command`, `state` or `fault`.
    pub fn name(self) -> &'static str {
        match self {
            Trigger::Now => "now",
            Trigger::Command => "command",
            Trigger::State => "state",
            Trigger::Fault => "fault",
        }
    }

    /// Whether it fires on a tick that began in `before`, took `record` and
    /// ended in `out`.
    fn fires(self, before: State, record: &Record) -> bool {
        match self {
            Trigger::Now => true,
            Trigger::Command => {
                record.command.is_some_and(|k| k != CommandKind::Heartbeat)
                    || record.self_test_started
                    || record.identify_started
            }
            Trigger::State => record.state != before,
            Trigger::Fault => record.state == State::Fault && before != State::Fault,
        }
    }
}

/// Where a capture is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CaptureStatus {
    /// Never armed since the start, or disarmed (code 0).
    Empty,
    /// Armed, waiting for its trigger (1).
    Armed,
    /// Triggered, recording (2).
    Recording,
    /// The window recorded (or ended early): the records are readable (3).
    Done,
}

impl CaptureStatus {
    /// Every status, in code order.
    pub const ALL: [CaptureStatus; 4] = [
        CaptureStatus::Empty,
        CaptureStatus::Armed,
        CaptureStatus::Recording,
        CaptureStatus::Done,
    ];

    /// Its wire code.
    pub fn code(self) -> u8 {
        match self {
            CaptureStatus::Empty => 0,
            CaptureStatus::Armed => 1,
            CaptureStatus::Recording => 2,
            CaptureStatus::Done => 3,
        }
    }

    /// `empty`, `armed`, `recording` or `done`.
    pub fn name(self) -> &'static str {
        match self {
            CaptureStatus::Empty => "empty",
            CaptureStatus::Armed => "armed",
            CaptureStatus::Recording => "recording",
            CaptureStatus::Done => "done",
        }
    }
}

/// A run command of the window, with its values.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CommandEntry {
    /// The record (tick of the window, from 0) that took it.
    pub record: u16,
    /// The command: [`Command::Travel`] or [`Command::HoldOffset`].
    pub command: Command,
}

/// The controller where a capture starts: before its first tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Start {
    /// The state.
    pub state: State,
    /// The rotors' filtered speeds, rpm.
    pub speed_rpm: [f32; 2],
    /// The count each encoder latched at its last index pulse, `None` before
    /// the first ([`crate::controller::Controller::index_counts`]).
    pub index: [Option<u32>; 2],
    /// Time since the device started, ms, at the tick before.
    pub uptime_ms: u32,
}

impl Start {
    const IDLE: Start = Start {
        state: State::Idle,
        speed_rpm: [0.0; 2],
        index: [None; 2],
        uptime_ms: 0,
    };
}

/// The machine file a firmware was built for: the CRC-32/ISO-HDLC of its bytes
/// and their count (as the processor-in-the-loop build states them).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MachineFingerprint {
    /// CRC-32 of the file's bytes.
    pub crc32: u32,
    /// The file's length, bytes.
    pub len: u32,
}

/// A capture's status and everything besides its records.
#[derive(Clone, Debug, PartialEq)]
pub struct CaptureInfo {
    /// Counts the arms since the start (wrapping): a reader checks that the
    /// capture it read is the one it asked about.
    pub id: u16,
    /// Where it is.
    pub status: CaptureStatus,
    /// Its trigger.
    pub trigger: Trigger,
    /// Ticks the device's buffer holds.
    pub capacity: u16,
    /// Ticks asked for.
    pub window: u16,
    /// Ticks recorded so far.
    pub recorded: u16,
    /// It ended before its window: more run commands than [`MAX_COMMANDS`].
    pub ended_early: bool,
    /// The control tick, us.
    pub tick_us: u32,
    /// The controller before the first record.
    pub start: Start,
    /// The firmware's machine file.
    pub machine: MachineFingerprint,
    /// The run commands of the window, in order.
    pub commands: heapless::Vec<CommandEntry, MAX_COMMANDS>,
}

/// Payload bytes of a [`CaptureInfo`]: `45 + 16 x 12`.
pub const CAPTURE_INFO_LEN: usize = 45 + MAX_COMMANDS * 12;

/// An index latch on the wire: a flag bit and the count.
fn index_flags(index: [Option<u32>; 2]) -> u8 {
    u8::from(index[0].is_some()) | u8::from(index[1].is_some()) << 1
}

impl CaptureInfo {
    /// Its [`CAPTURE_INFO_LEN`] bytes: id `u16`, status, trigger, capacity `u16`,
    /// window `u16`, recorded `u16`, flags (bit 0 ended early, bits 1 and 2 the
    /// index latches known), the state before, tick `u32` us, uptime `u32` ms,
    /// machine CRC `u32` and length `u32`, index latches `u32` x 2, speeds `f32`
    /// x 2, the number of commands, then 16 command slots of 12 bytes (record
    /// `u16`, kind, direction, speed `f32`, offset `f32`; unused slots zero).
    pub fn to_bytes(&self) -> [u8; CAPTURE_INFO_LEN] {
        let mut out = [0u8; CAPTURE_INFO_LEN];
        let mut w = Writer::new(&mut out);
        w.u16(self.id);
        w.u8(self.status.code());
        w.u8(self.trigger.code());
        w.u16(self.capacity);
        w.u16(self.window);
        w.u16(self.recorded);
        w.u8(u8::from(self.ended_early) | index_flags(self.start.index) << 1);
        w.u8(self.start.state.code());
        w.u32(self.tick_us);
        w.u32(self.start.uptime_ms);
        w.u32(self.machine.crc32);
        w.u32(self.machine.len);
        for i in self.start.index {
            w.u32(i.unwrap_or(0));
        }
        for s in self.start.speed_rpm {
            w.f32(s);
        }
        w.u8(self.commands.len() as u8);
        for e in &self.commands {
            w.u16(e.record);
            match e.command {
                Command::Travel {
                    direction,
                    speed_rpm,
                } => {
                    w.u8(CommandKind::Travel.code());
                    w.u8(u8::from(direction == Direction::Left));
                    w.f32(speed_rpm);
                    w.f32(0.0);
                }
                Command::HoldOffset {
                    speed_rpm,
                    offset_deg,
                } => {
                    w.u8(CommandKind::HoldOffset.code());
                    w.u8(0);
                    w.f32(speed_rpm);
                    w.f32(offset_deg);
                }
                // Only run commands are kept ([`Capture::record`]).
                _ => w.zeros(10),
            }
        }
        out
    }

    /// The info of [`CAPTURE_INFO_LEN`] bytes; `None` if a field is outside its
    /// domain.
    pub fn from_bytes(bytes: &[u8]) -> Option<CaptureInfo> {
        if bytes.len() != CAPTURE_INFO_LEN {
            return None;
        }
        let mut r = Reader::new(bytes);
        let id = r.u16()?;
        let status = *CaptureStatus::ALL.get(usize::from(r.u8()?))?;
        let trigger = Trigger::from_code(r.u8()?)?;
        let (capacity, window, recorded) = (r.u16()?, r.u16()?, r.u16()?);
        let flags = r.u8()?;
        let state = State::from_code(r.u8()?)?;
        let (tick_us, uptime_ms, crc32, len) = (r.u32()?, r.u32()?, r.u32()?, r.u32()?);
        let latch = [r.u32()?, r.u32()?];
        let speed_rpm = [r.f32()?, r.f32()?];
        let n = usize::from(r.u8()?);
        if flags & !0b111 != 0 || n > MAX_COMMANDS || recorded > window || window > capacity {
            return None;
        }
        let mut commands = heapless::Vec::new();
        for _ in 0..n {
            let record = r.u16()?;
            let kind = r.u8()?;
            let dir = r.u8()?;
            let (speed_rpm, offset_deg) = (r.f32()?, r.f32()?);
            let command = match (kind, dir) {
                (4, 0 | 1) => Command::Travel {
                    direction: if dir == 0 {
                        Direction::Right
                    } else {
                        Direction::Left
                    },
                    speed_rpm,
                },
                (5, 0) => Command::HoldOffset {
                    speed_rpm,
                    offset_deg,
                },
                _ => return None,
            };
            commands.push(CommandEntry { record, command }).ok()?;
        }
        let index = [
            (flags & 0b010 != 0).then_some(latch[0]),
            (flags & 0b100 != 0).then_some(latch[1]),
        ];
        Some(CaptureInfo {
            id,
            status,
            trigger,
            capacity,
            window,
            recorded,
            ended_early: flags & 1 != 0,
            tick_us,
            start: Start {
                state,
                speed_rpm,
                index,
                uptime_ms,
            },
            machine: MachineFingerprint { crc32, len },
            commands,
        })
    }
}

/// Why a capture cannot be armed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ArmError {
    /// The window is longer than the buffer (or 0 on a device without one).
    Window,
}

/// The recorder: its buffer and where the capture is.
pub struct Capture {
    buffer: &'static mut [Slot],
    machine: MachineFingerprint,
    id: u16,
    status: CaptureStatus,
    trigger: Trigger,
    window: u16,
    recorded: u16,
    ended_early: bool,
    tick_us: u32,
    /// The controller before the coming tick (noted by [`Capture::note_before`]).
    before: Start,
    /// What the link handed over before the coming tick: self-test,
    /// identification, tuning table.
    started: [bool; 3],
    start: Start,
    commands: heapless::Vec<CommandEntry, MAX_COMMANDS>,
}

impl core::fmt::Debug for Capture {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Capture")
            .field("capacity", &self.buffer.len())
            .field("status", &self.status)
            .field("recorded", &self.recorded)
            .finish()
    }
}

impl Capture {
    /// A recorder into `buffer` (at most `u16::MAX` slots are used) for a
    /// firmware built for `machine`, ticking every `tick_s` seconds.
    pub fn new(buffer: &'static mut [Slot], machine: MachineFingerprint, tick_s: f32) -> Self {
        Capture {
            buffer,
            machine,
            id: 0,
            status: CaptureStatus::Empty,
            trigger: Trigger::Now,
            window: 0,
            recorded: 0,
            ended_early: false,
            tick_us: (tick_s * 1e6 + 0.5) as u32,
            before: Start::IDLE,
            started: [false; 3],
            start: Start::IDLE,
            commands: heapless::Vec::new(),
        }
    }

    /// A device without a capture buffer: every arm is refused.
    pub fn none() -> Self {
        Capture::new(&mut [], MachineFingerprint::default(), 0.0)
    }

    /// Stamp the captures with `machine`, the machine file the firmware was
    /// built for.
    pub fn set_machine(&mut self, machine: MachineFingerprint) {
        self.machine = machine;
    }

    /// Ticks the buffer holds.
    pub fn capacity(&self) -> u16 {
        u16::try_from(self.buffer.len()).unwrap_or(u16::MAX)
    }

    /// Arm for `window` ticks (1 to [`Capture::capacity`]) from `trigger`; a
    /// window of 0 disarms. The previous capture is dropped.
    pub fn arm(&mut self, trigger: Trigger, window: u16) -> Result<(), ArmError> {
        if window > self.capacity() {
            return Err(ArmError::Window);
        }
        self.id = self.id.wrapping_add(1);
        self.trigger = trigger;
        self.window = window;
        self.recorded = 0;
        self.ended_early = false;
        self.commands.clear();
        self.status = if window == 0 {
            CaptureStatus::Empty
        } else {
            CaptureStatus::Armed
        };
        Ok(())
    }

    /// Whether the coming tick is to be recorded or checked for the trigger.
    pub fn waiting(&self) -> bool {
        matches!(self.status, CaptureStatus::Armed | CaptureStatus::Recording)
    }

    /// The control task, before the step of the coming tick (stage 2): the
    /// controller as it is (`before`, the last published uptime included) and
    /// what the link handed it (`started`: self-test, identification, tuning
    /// table).
    pub fn note_before(&mut self, before: Start, started: [bool; 3]) {
        self.before = before;
        self.started = started;
    }

    /// The control task, after the step (stage 5): the tick that stepped on
    /// `inputs` and wrote `out`, at `uptime_ms`, recorded if the capture is
    /// recording or its trigger fires now.
    pub fn record(&mut self, inputs: &Inputs, out: &Outputs) {
        if !self.waiting() {
            return;
        }
        let record = Record::of(inputs, self.started, out);
        self.started = [false; 3];
        if self.status == CaptureStatus::Armed {
            if !self.trigger.fires(self.before.state, &record) {
                return;
            }
            self.status = CaptureStatus::Recording;
            self.start = self.before;
        }
        if let Some(command @ (Command::Travel { .. } | Command::HoldOffset { .. })) =
            inputs.command
        {
            let entry = CommandEntry {
                record: self.recorded,
                command,
            };
            if self.commands.push(entry).is_err() {
                self.ended_early = true;
                self.status = CaptureStatus::Done;
                return;
            }
        }
        if let Some(slot) = self.buffer.get_mut(usize::from(self.recorded)) {
            *slot = record.to_bytes();
            self.recorded += 1;
        }
        if self.recorded >= self.window {
            self.status = CaptureStatus::Done;
        }
    }

    /// The status and everything besides the records.
    pub fn info(&self) -> CaptureInfo {
        CaptureInfo {
            id: self.id,
            status: self.status,
            trigger: self.trigger,
            capacity: self.capacity(),
            window: self.window,
            recorded: self.recorded,
            ended_early: self.ended_early,
            tick_us: self.tick_us,
            start: self.start,
            machine: self.machine,
            commands: self.commands.clone(),
        }
    }

    /// The records from `first` on, at most [`RECORDS_PER_FRAME`], copied into
    /// `out`; how many (0 from the last recorded on).
    pub fn read(&self, first: u16, out: &mut [Slot; RECORDS_PER_FRAME]) -> usize {
        let from = usize::from(first);
        let to = usize::from(self.recorded).min(from + RECORDS_PER_FRAME);
        let records = self.buffer.get(from..to).unwrap_or(&[]);
        for (dst, src) in out.iter_mut().zip(records) {
            *dst = *src;
        }
        records.len()
    }
}
