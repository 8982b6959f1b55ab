//! One control tick as a capture keeps it: [`Record`], [`RECORD_LEN`] bytes,
//! little-endian, no padding (docs/protocol.md, "Capture").
//!
//! | bytes | field |
//! | --- | --- |
//! | 0..8 | encoder counters of rotor 1 and 2, `u32` each |
//! | 8..12 | index latches, `i16` each: the latch minus the tick's counter, `i16::MIN` for none |
//! | 12..20 | mean winding currents, A, `f32` each |
//! | 20..24 | supply, V, `f32` |
//! | 24..28 | duties, `i16` each: `round(duty x 32767)`, `i16::MIN` for a bridge off |
//! | 28..30 | latched faults after the tick, `u16` (the status report's bits) |
//! | 30 | state after the tick (its wire code) |
//! | 31 | flags: bit 0 E-stop open, bit 1 self-test started, bit 2 identification started, bit 3 tuning table handed over, bits 4..6 the command ([`CommandKind`]) |
//! | 32..34 | how late the tick started, us, `u16` (saturating) |
//! | 34..36 | how long the previous tick worked, us, `u16` (saturating) |
//!
//! Everything the controller read and wrote is there exactly (counters,
//! currents, supply as `f32`), except the duties, kept to 1/32767 (the
//! bridge's timer resolves 1/4200 at 20 kHz), the index latch, kept within
//! 32 767 counts of the counter (a rotor would travel more than 32 767 counts in
//! a tick above 1.9 million rpm at 1 kHz with 1 024 counts a turn), and the
//! timing, kept to the microsecond.

use crate::codec::wire::{Reader, Writer};
use crate::controller::{Bridge, Command, Faults, Inputs, Outputs, State, TickTiming};

/// Bytes of a [`Record`].
pub const RECORD_LEN: usize = 36;

/// Full scale of a recorded duty: `duty = raw / DUTY_SCALE`.
pub const DUTY_SCALE: f32 = 32767.0;

/// The raw duty of a bridge that is off.
const OFF: i16 = i16::MIN;

/// The raw index latch of a tick without an index pulse.
const NO_INDEX: i16 = i16::MIN;

/// Flag bits of byte 31.
const ESTOP: u8 = 1 << 0;
const SELF_TEST_STARTED: u8 = 1 << 1;
const IDENTIFY_STARTED: u8 = 1 << 2;
const TUNING_CHANGED: u8 = 1 << 3;
const COMMAND_SHIFT: u8 = 4;
const COMMAND_MASK: u8 = 0b111 << COMMAND_SHIFT;

/// The kind of command a tick received (its values, for a run command, are in
/// the capture's command list, [`super::CaptureInfo::commands`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CommandKind {
    /// [`Command::Heartbeat`] (code 1).
    Heartbeat,
    /// [`Command::Stop`] (2).
    Stop,
    /// [`Command::ResetFaults`] (3).
    ResetFaults,
    /// [`Command::Travel`] (4).
    Travel,
    /// [`Command::HoldOffset`] (5).
    HoldOffset,
}

impl CommandKind {
    /// Every kind, in code order.
    pub const ALL: [CommandKind; 5] = [
        CommandKind::Heartbeat,
        CommandKind::Stop,
        CommandKind::ResetFaults,
        CommandKind::Travel,
        CommandKind::HoldOffset,
    ];

    /// The kind of `command`.
    pub fn of(command: &Command) -> CommandKind {
        match command {
            Command::Heartbeat => CommandKind::Heartbeat,
            Command::Stop => CommandKind::Stop,
            Command::ResetFaults => CommandKind::ResetFaults,
            Command::Travel { .. } => CommandKind::Travel,
            Command::HoldOffset { .. } => CommandKind::HoldOffset,
        }
    }

    /// Its code, 1 to 5 (0 is no command).
    pub fn code(self) -> u8 {
        match self {
            CommandKind::Heartbeat => 1,
            CommandKind::Stop => 2,
            CommandKind::ResetFaults => 3,
            CommandKind::Travel => 4,
            CommandKind::HoldOffset => 5,
        }
    }

    /// `heartbeat`, `stop`, `reset`, `travel` or `hold`.
    pub fn name(self) -> &'static str {
        match self {
            CommandKind::Heartbeat => "heartbeat",
            CommandKind::Stop => "stop",
            CommandKind::ResetFaults => "reset",
            CommandKind::Travel => "travel",
            CommandKind::HoldOffset => "hold",
        }
    }

    /// Whether the command carries values (kept in the command list).
    pub fn has_values(self) -> bool {
        matches!(self, CommandKind::Travel | CommandKind::HoldOffset)
    }
}

/// One control tick of a capture: what the controller was given and what it
/// wrote.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Record {
    /// Encoder counters ([`Inputs::encoder`]).
    pub encoder: [u32; 2],
    /// Index latches ([`Inputs::index`]).
    pub index: [Option<u32>; 2],
    /// Mean winding currents, A ([`Inputs::current`]).
    pub current: [f32; 2],
    /// Supply, V ([`Inputs::supply_voltage`]).
    pub supply_voltage: f32,
    /// E-stop open ([`Inputs::estop`]).
    pub estop: bool,
    /// The command of the tick, by kind.
    pub command: Option<CommandKind>,
    /// A requested self-test was started before the step.
    pub self_test_started: bool,
    /// A requested identification was started before the step.
    pub identify_started: bool,
    /// A new tuning table was handed to the controller before the step.
    pub tuning_changed: bool,
    /// The tick's timing, to the microsecond.
    pub timing_us: [u16; 2],
    /// The bridges: a duty in units of 1/[`DUTY_SCALE`], `None` for off.
    pub duty_raw: [Option<i16>; 2],
    /// The state after the tick.
    pub state: State,
    /// The faults latched after the tick.
    pub faults: Faults,
}

/// `x` s in microseconds, saturating at `u16::MAX`.
fn micros(x: f32) -> u16 {
    let us = x * 1e6;
    if us >= f32::from(u16::MAX) {
        u16::MAX
    } else if us > 0.0 {
        (us + 0.5) as u16
    } else {
        0
    }
}

/// The raw duty of a bridge.
pub fn duty_raw(bridge: Bridge) -> Option<i16> {
    match bridge {
        Bridge::Off => None,
        // In [-1, 1], so the product is in [-32767, 32767]; `as` saturates.
        Bridge::Driven(d) => Some(libm::roundf(d.clamp(-1.0, 1.0) * DUTY_SCALE) as i16),
    }
}

impl Record {
    /// The record of a tick that stepped on `inputs` and wrote `out`; `started`
    /// says what the link handed over before the step (self-test, identification,
    /// tuning table).
    pub fn of(inputs: &Inputs, started: [bool; 3], out: &Outputs) -> Record {
        Record {
            encoder: inputs.encoder,
            index: inputs.index,
            current: inputs.current,
            supply_voltage: inputs.supply_voltage,
            estop: inputs.estop,
            command: inputs.command.as_ref().map(CommandKind::of),
            self_test_started: started[0],
            identify_started: started[1],
            tuning_changed: started[2],
            timing_us: [micros(inputs.timing.late_s), micros(inputs.timing.busy_s)],
            duty_raw: out.bridges.map(duty_raw),
            state: out.state,
            faults: out.faults,
        }
    }

    /// The duties, in [-1, 1], `None` for a bridge off.
    pub fn duty(&self) -> [Option<f32>; 2] {
        self.duty_raw.map(|d| d.map(|d| f32::from(d) / DUTY_SCALE))
    }

    /// The controller's inputs of the tick, with `command` (the record keeps the
    /// command's kind only; its values are in the capture's command list).
    pub fn inputs(&self, command: Option<Command>) -> Inputs {
        Inputs {
            encoder: self.encoder,
            index: self.index,
            current: self.current,
            supply_voltage: self.supply_voltage,
            estop: self.estop,
            command,
            timing: TickTiming {
                late_s: f32::from(self.timing_us[0]) * 1e-6,
                busy_s: f32::from(self.timing_us[1]) * 1e-6,
            },
        }
    }

    /// Its [`RECORD_LEN`] bytes.
    pub fn to_bytes(&self) -> [u8; RECORD_LEN] {
        let mut out = [0u8; RECORD_LEN];
        let mut w = Writer::new(&mut out);
        for c in self.encoder {
            w.u32(c);
        }
        for (latch, count) in self.index.iter().zip(self.encoder) {
            let raw = match latch {
                None => NO_INDEX,
                Some(l) => {
                    (l.wrapping_sub(count) as i32).clamp(-i16::MAX as i32, i16::MAX as i32) as i16
                }
            };
            w.u16(raw as u16);
        }
        for i in self.current {
            w.f32(i);
        }
        w.f32(self.supply_voltage);
        for d in self.duty_raw {
            w.u16(d.unwrap_or(OFF) as u16);
        }
        w.u16(self.faults.bits());
        w.u8(self.state.code());
        let command = self.command.map_or(0, CommandKind::code);
        let mut flags = command << COMMAND_SHIFT;
        for (set, bit) in [
            (self.estop, ESTOP),
            (self.self_test_started, SELF_TEST_STARTED),
            (self.identify_started, IDENTIFY_STARTED),
            (self.tuning_changed, TUNING_CHANGED),
        ] {
            if set {
                flags |= bit;
            }
        }
        w.u8(flags);
        w.u16(self.timing_us[0]);
        w.u16(self.timing_us[1]);
        out
    }

    /// The record of [`RECORD_LEN`] bytes; `None` if a field is outside its
    /// domain (a state or command code without a meaning, an unknown fault bit,
    /// a flag bit reserved).
    pub fn from_bytes(bytes: &[u8; RECORD_LEN]) -> Option<Record> {
        let mut r = Reader::new(bytes);
        let encoder = [r.u32()?, r.u32()?];
        let latch = [r.u16()? as i16, r.u16()? as i16];
        let current = [r.f32()?, r.f32()?];
        let supply_voltage = r.f32()?;
        let duty = [r.u16()? as i16, r.u16()? as i16];
        let bits = r.u16()?;
        let state = State::from_code(r.u8()?)?;
        let flags = r.u8()?;
        let timing_us = [r.u16()?, r.u16()?];
        let faults = Faults::from_bits(bits);
        if faults.bits() != bits || flags & 0x80 != 0 {
            return None;
        }
        let command = match (flags & COMMAND_MASK) >> COMMAND_SHIFT {
            0 => None,
            code => Some(CommandKind::ALL.into_iter().find(|k| k.code() == code)?),
        };
        let mut index = [None; 2];
        for k in 0..2 {
            if latch[k] != NO_INDEX {
                index[k] = Some(encoder[k].wrapping_add(latch[k] as i32 as u32));
            }
        }
        Some(Record {
            encoder,
            index,
            current,
            supply_voltage,
            estop: flags & ESTOP != 0,
            command,
            self_test_started: flags & SELF_TEST_STARTED != 0,
            identify_started: flags & IDENTIFY_STARTED != 0,
            tuning_changed: flags & TUNING_CHANGED != 0,
            timing_us,
            duty_raw: duty.map(|d| (d != OFF).then_some(d)),
            state,
            faults,
        })
    }
}
