//! The messages: ids, the [`Request`]s the host sends, the [`Response`]s the device
//! sends, and their payload layouts (little-endian, fixed, no padding; `f32` is IEEE
//! 754 binary32). Every layout is listed in `docs/protocol.md`.

use crate::codec::wire::{flag_byte, Field, Reader, Writer};
use crate::codec::{IDENTIFY_REPORT_LEN, SELF_TEST_REPORT_LEN, TUNING_ROW_LEN};
use crate::controller::identify::IdentifyReport;
use crate::controller::self_test::SelfTestReport;
use crate::controller::{
    Command, Direction, Faults, Outputs, State, Telemetry, TuningRow, TuningTable, MAX_TUNING_ROWS,
};

use super::frame::Frame;
use crate::capture::{
    CaptureInfo, Record, Slot, Trigger, CAPTURE_INFO_LEN, RECORDS_PER_FRAME, RECORD_LEN,
};

/// Message ids: requests (host to device) below `0x80`, responses (device to host)
/// from `0x80`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(u8)]
pub enum MessageId {
    /// [`Command::Heartbeat`] ([`Request::Command`]).
    Heartbeat = 0x01,
    /// [`Request::GetStatus`].
    GetStatus = 0x02,
    /// [`Command::Stop`] ([`Request::Command`]).
    Stop = 0x03,
    /// [`Command::Travel`] ([`Request::Command`]).
    Travel = 0x04,
    /// [`Command::HoldOffset`] ([`Request::Command`]).
    HoldOffset = 0x05,
    /// [`Command::ResetFaults`] ([`Request::Command`]).
    ResetFaults = 0x06,
    /// [`Request::ReadTuningTable`].
    ReadTuningTable = 0x07,
    /// [`Request::WriteTuningTable`].
    WriteTuningTable = 0x08,
    /// [`Request::RunSelfTest`].
    RunSelfTest = 0x09,
    /// [`Request::ReadSelfTest`].
    ReadSelfTest = 0x0A,
    /// [`Request::StreamTelemetry`].
    StreamTelemetry = 0x0B,
    /// [`Request::RunIdentify`].
    RunIdentify = 0x0C,
    /// [`Request::ReadIdentify`].
    ReadIdentify = 0x0D,
    /// [`Request::ArmCapture`].
    ArmCapture = 0x0E,
    /// [`Request::GetCapture`].
    GetCapture = 0x0F,
    /// [`Request::ReadCapture`].
    ReadCapture = 0x10,
    /// [`Response::Ack`].
    Ack = 0x80,
    /// [`Response::Nack`].
    Nack = 0x81,
    /// [`Response::Status`].
    Status = 0x82,
    /// [`Response::TuningTable`].
    TuningTable = 0x83,
    /// [`Response::SelfTest`].
    SelfTestResult = 0x84,
    /// [`Response::Telemetry`] (unsolicited).
    Telemetry = 0x85,
    /// [`Response::Identify`].
    IdentifyResult = 0x86,
    /// [`Response::Capture`].
    CaptureInfo = 0x87,
    /// [`Response::CaptureRecords`].
    CaptureRecords = 0x88,
}

impl MessageId {
    /// Every id, requests first.
    pub const ALL: [MessageId; 25] = [
        MessageId::Heartbeat,
        MessageId::GetStatus,
        MessageId::Stop,
        MessageId::Travel,
        MessageId::HoldOffset,
        MessageId::ResetFaults,
        MessageId::ReadTuningTable,
        MessageId::WriteTuningTable,
        MessageId::RunSelfTest,
        MessageId::ReadSelfTest,
        MessageId::StreamTelemetry,
        MessageId::RunIdentify,
        MessageId::ReadIdentify,
        MessageId::ArmCapture,
        MessageId::GetCapture,
        MessageId::ReadCapture,
        MessageId::Ack,
        MessageId::Nack,
        MessageId::Status,
        MessageId::TuningTable,
        MessageId::SelfTestResult,
        MessageId::Telemetry,
        MessageId::IdentifyResult,
        MessageId::CaptureInfo,
        MessageId::CaptureRecords,
    ];

    /// The id of byte `b`, if there is one.
    pub fn from_u8(b: u8) -> Option<MessageId> {
        MessageId::ALL.into_iter().find(|id| *id as u8 == b)
    }

    /// Whether the host sends it (ids below `0x80`).
    pub fn is_request(self) -> bool {
        (self as u8) < 0x80
    }
}

/// Why a payload does not make a message; [`NackReason::from`] gives the answer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ParseError {
    /// No message of this kind (request or response) has this id.
    UnknownId,
    /// The payload length is wrong for the id.
    BadLength,
    /// A field is outside its domain: an enum or flag value without a meaning, a
    /// reserved byte not 0, a non-finite command value, an invalid tuning table.
    BadValue,
}

/// Why a request was refused ([`Response::Nack`]), one byte on the wire.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(u8)]
pub enum NackReason {
    /// The id is no request ([`ParseError::UnknownId`]).
    UnknownMessage = 1,
    /// The payload length is wrong for the id ([`ParseError::BadLength`]).
    BadLength = 2,
    /// A field is outside its domain ([`ParseError::BadValue`]).
    BadValue = 3,
    /// The header was right but the frame CRC-32 was not ([`super::FrameError::BadCrc`]).
    BadCrc = 4,
    /// The header announced more than [`super::MAX_PAYLOAD`] bytes.
    TooLong = 5,
    /// The header carried another protocol version; the Nack's own header carries
    /// the device's [`super::PROTOCOL_VERSION`].
    BadVersion = 6,
    /// Needs the motors stopped: state idle or fault and both rotors below
    /// [`crate::controller::WRITE_MAX_SPEED_RPM`]
    /// ([`crate::controller::may_write_table`]).
    NotStopped = 7,
    /// A fault is latched: reset it first (for [`Request::RunSelfTest`] and
    /// [`Request::RunIdentify`]).
    Faulted = 8,
    /// The flash write failed; the previous table is still the one in use and in
    /// flash.
    StorageFailed = 9,
    /// The device is busy (a self-test or an identification runs) and refuses this
    /// request for now.
    Busy = 10,
}

impl NackReason {
    /// Every reason, in code order.
    pub const ALL: [NackReason; 10] = [
        NackReason::UnknownMessage,
        NackReason::BadLength,
        NackReason::BadValue,
        NackReason::BadCrc,
        NackReason::TooLong,
        NackReason::BadVersion,
        NackReason::NotStopped,
        NackReason::Faulted,
        NackReason::StorageFailed,
        NackReason::Busy,
    ];

    /// The reason of code `b`, if there is one.
    pub fn from_u8(b: u8) -> Option<NackReason> {
        NackReason::ALL.into_iter().find(|r| *r as u8 == b)
    }
}

impl From<ParseError> for NackReason {
    fn from(e: ParseError) -> Self {
        match e {
            ParseError::UnknownId => NackReason::UnknownMessage,
            ParseError::BadLength => NackReason::BadLength,
            ParseError::BadValue => NackReason::BadValue,
        }
    }
}

/// Shortest telemetry stream period, ms: a [`Response::Telemetry`] frame is
/// `14 + StatusReport::LEN = 82` bytes, 7.1 ms at 115200 baud; every 20 ms that is
/// a third of the link, which leaves room for the answers.
pub const MIN_TELEMETRY_PERIOD_MS: u16 = 20;

/// A message from the host.
// No heap to box the table in: a request lives on the stack while it is handled.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug, PartialEq)]
pub enum Request {
    /// A controller command, each its own message (docs/protocol.md): a
    /// [`Command::Heartbeat`] ("the link is alive", for a host with nothing else
    /// to say; every valid request counts as one) answered [`Response::Ack`];
    /// [`Command::Stop`] and [`Command::ResetFaults`] answered Ack;
    /// [`Command::Travel`] and [`Command::HoldOffset`] (speeds and offsets
    /// finite) answered Ack (handed to the controller; its range check shows in
    /// [`Telemetry::command_rejected`]) or Nack.
    Command(Command),
    /// Answered [`Response::Status`].
    GetStatus,
    /// Answered [`Response::TuningTable`]: the table in use.
    ReadTuningTable,
    /// Replace the tuning table, in use and in flash; only with the motors stopped.
    /// Answered Ack once it is stored, else Nack (`NotStopped`, `StorageFailed`).
    WriteTuningTable(TuningTable),
    /// Start the self-test (motors stopped, no fault); answered Ack once started.
    RunSelfTest,
    /// Answered [`Response::SelfTest`].
    ReadSelfTest,
    /// Start the motor identification (motors stopped, no fault); answered Ack
    /// once started.
    RunIdentify,
    /// Answered [`Response::Identify`].
    ReadIdentify,
    /// Arm the capture ([`crate::capture`]) for `window` ticks from `trigger`
    /// (a window of 0 disarms); answered Ack, or Nack `BadValue` for a window
    /// longer than the device's buffer.
    ArmCapture {
        /// What starts the recording.
        trigger: Trigger,
        /// Ticks to record, 0 to the buffer's capacity.
        window: u16,
    },
    /// Answered [`Response::Capture`].
    GetCapture,
    /// Answered [`Response::CaptureRecords`]: the records from `first` on.
    ReadCapture {
        /// The first record wanted (a tick of the window, from 0).
        first: u16,
    },
    /// Send [`Response::Telemetry`] every `period_ms` (0: stop the stream); answered
    /// Ack, or Nack `BadValue` below [`MIN_TELEMETRY_PERIOD_MS`].
    StreamTelemetry {
        /// Period, ms; 0 or at least [`MIN_TELEMETRY_PERIOD_MS`].
        period_ms: u16,
    },
}

/// The controller's state, faults and telemetry at one tick, with the device's
/// clock: the body of [`Response::Status`] and [`Response::Telemetry`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StatusReport {
    /// Time since the device started, ms, wrapping at `2^32` (49.7 days).
    pub uptime_ms: u32,
    /// Controller state.
    pub state: State,
    /// Latched faults.
    pub faults: Faults,
    /// The tick's measurements and references.
    pub telemetry: Telemetry,
    /// Received bytes the device lost since it started (its receive ring full, or
    /// the UART overrun), saturating.
    pub rx_dropped: u16,
}

impl StatusReport {
    /// Payload bytes: see `docs/protocol.md`.
    pub const LEN: usize = 68;

    /// The report of a controller tick's outputs at `uptime_ms` (no byte lost).
    pub fn from_outputs(uptime_ms: u32, outputs: &Outputs) -> Self {
        StatusReport {
            uptime_ms,
            state: outputs.state,
            faults: outputs.faults,
            telemetry: outputs.telemetry,
            rx_dropped: 0,
        }
    }

    /// Its [`StatusReport::LEN`] payload bytes (as in [`Response::Status`]).
    pub fn to_bytes(&self) -> [u8; StatusReport::LEN] {
        let mut out = [0u8; StatusReport::LEN];
        write_status(&mut Writer::new(&mut out), self);
        out
    }

    /// The report of [`StatusReport::LEN`] payload bytes ([`StatusReport::to_bytes`]).
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, ParseError> {
        read_status(bytes)
    }
}

/// A message from the device.
// No heap to box the table in: a response lives on the stack until it is encoded.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug, PartialEq)]
pub enum Response {
    /// The request with the frame's sequence number and id `request` was accepted.
    Ack {
        /// The id of the request answered (a raw byte: it may be unknown).
        request: u8,
    },
    /// The request with the frame's sequence number and id `request` was refused.
    Nack {
        /// The id of the request answered (a raw byte: it may be unknown).
        request: u8,
        /// Why.
        reason: NackReason,
    },
    /// The answer to [`Request::GetStatus`].
    Status(StatusReport),
    /// The answer to [`Request::ReadTuningTable`]: the table in use.
    TuningTable(TuningTable),
    /// The answer to [`Request::ReadSelfTest`].
    SelfTest(SelfTestReport),
    /// The answer to [`Request::ReadIdentify`].
    Identify(IdentifyReport),
    /// The answer to [`Request::GetCapture`].
    Capture(CaptureInfo),
    /// The answer to [`Request::ReadCapture`]: `count` records from `first`
    /// (none from the last recorded on).
    CaptureRecords {
        /// The first record sent.
        first: u16,
        /// How many, at most [`RECORDS_PER_FRAME`].
        count: u8,
        /// The records' bytes (the first `count` slots).
        records: [Slot; RECORDS_PER_FRAME],
    },
    /// Sent unsolicited every period of [`Request::StreamTelemetry`], with the
    /// device's own sequence counter in the header.
    Telemetry(StatusReport),
}

/// A message type that travels in frames: requests and responses.
pub trait Message: Sized {
    /// Its id.
    fn id(&self) -> MessageId;

    /// Write its payload into `out`; its length, or `None` if `out` is too small
    /// ([`super::MAX_PAYLOAD`] bytes always suffice).
    fn write_payload(&self, out: &mut [u8]) -> Option<usize>;

    /// The message in a frame: its id, then the payload's exact length and values.
    fn parse(frame: &Frame<'_>) -> Result<Self, ParseError>;
}

/// Wire code of a direction: 0 right, 1 left.
fn direction_code(d: Direction) -> u8 {
    match d {
        Direction::Right => 0,
        Direction::Left => 1,
    }
}

/// Telemetry flag bits.
const PHASE_VALID: u8 = 1 << 0;
/// See [`Telemetry::phase_loop_closed`].
const PHASE_LOOP_CLOSED: u8 = 1 << 1;
/// See [`Telemetry::command_rejected`].
const COMMAND_REJECTED: u8 = 1 << 2;

/// Write a table: row count `u8`, then the rows.
pub(crate) fn write_table(w: &mut Writer<'_>, table: &TuningTable) {
    let rows = table.rows();
    w.u8(rows.len().min(usize::from(u8::MAX)) as u8);
    for row in rows {
        row.write(w);
    }
}

/// Read a table written by [`write_table`] that fills the payload exactly.
fn read_table(payload: &[u8]) -> Result<TuningTable, ParseError> {
    let mut r = Reader::new(payload);
    let count = usize::from(r.u8().ok_or(ParseError::BadLength)?);
    if payload.len() != 1 + count * TUNING_ROW_LEN {
        return Err(ParseError::BadLength);
    }
    if count > MAX_TUNING_ROWS {
        return Err(ParseError::BadValue);
    }
    let mut rows = [(0.0f32, 0.0f32, 0.0f32); MAX_TUNING_ROWS];
    for row in rows.iter_mut().take(count) {
        let r = TuningRow::read(&mut r).ok_or(ParseError::BadLength)?;
        *row = (r.speed_rpm, r.right_offset_deg, r.left_offset_deg);
    }
    TuningTable::from_rows(rows.get(..count).unwrap_or(&[])).map_err(|_| ParseError::BadValue)
}

/// Write a status report ([`StatusReport::LEN`] bytes).
fn write_status(w: &mut Writer<'_>, s: &StatusReport) {
    let t = &s.telemetry;
    let flags = flag_byte(&[
        (t.phase_valid, PHASE_VALID),
        (t.phase_loop_closed, PHASE_LOOP_CLOSED),
        (t.command_rejected, COMMAND_REJECTED),
    ]);
    w.u32(s.uptime_ms);
    w.u8(s.state.code());
    w.u8(flags);
    w.u16(s.faults.bits());
    for v in [
        t.speed_rpm[0],
        t.speed_rpm[1],
        t.speed_ref_rpm[0],
        t.speed_ref_rpm[1],
        t.phase_offset_deg,
        t.commanded_offset_deg,
        t.target_offset_deg,
        t.phase_error_deg,
        t.current[0],
        t.current[1],
        t.supply_voltage,
        t.duty[0],
        t.duty[1],
    ] {
        w.f32(v);
    }
    w.u16(t.tick_late_us);
    w.u16(t.tick_busy_us);
    w.u16(t.overruns);
    w.u16(s.rx_dropped);
}

/// Read a status report that fills the payload exactly.
fn read_status(payload: &[u8]) -> Result<StatusReport, ParseError> {
    if payload.len() != StatusReport::LEN {
        return Err(ParseError::BadLength);
    }
    let mut r = Reader::new(payload);
    let mut f = [0.0f32; 13];
    let (Some(uptime_ms), Some(state), Some(flags), Some(bits)) =
        (r.u32(), r.u8(), r.u8(), r.u16())
    else {
        return Err(ParseError::BadLength);
    };
    for v in f.iter_mut() {
        *v = r.f32().ok_or(ParseError::BadLength)?;
    }
    let (Some(tick_late_us), Some(tick_busy_us), Some(overruns), Some(rx_dropped)) =
        (r.u16(), r.u16(), r.u16(), r.u16())
    else {
        return Err(ParseError::BadLength);
    };
    let state = State::from_code(state).ok_or(ParseError::BadValue)?;
    let faults = Faults::from_bits(bits);
    if faults.bits() != bits || flags & !(PHASE_VALID | PHASE_LOOP_CLOSED | COMMAND_REJECTED) != 0 {
        return Err(ParseError::BadValue);
    }
    let [s1, s2, r1, r2, phase, commanded, target, error, i1, i2, supply, d1, d2] = f;
    Ok(StatusReport {
        uptime_ms,
        state,
        faults,
        telemetry: Telemetry {
            speed_rpm: [s1, s2],
            speed_ref_rpm: [r1, r2],
            phase_valid: flags & PHASE_VALID != 0,
            phase_offset_deg: phase,
            phase_loop_closed: flags & PHASE_LOOP_CLOSED != 0,
            commanded_offset_deg: commanded,
            target_offset_deg: target,
            phase_error_deg: error,
            current: [i1, i2],
            supply_voltage: supply,
            duty: [d1, d2],
            command_rejected: flags & COMMAND_REJECTED != 0,
            tick_late_us,
            tick_busy_us,
            overruns,
        },
        rx_dropped,
    })
}

/// Read a [`Response::CaptureRecords`] payload: first `u16`, count, then the
/// count's records exactly, each a valid [`crate::capture::Record`].
fn read_records(p: &[u8]) -> Result<Response, ParseError> {
    let mut r = Reader::new(p);
    let (Some(first), Some(count)) = (r.u16(), r.u8()) else {
        return Err(ParseError::BadLength);
    };
    let n = usize::from(count);
    if n > RECORDS_PER_FRAME {
        return Err(ParseError::BadValue);
    }
    if p.len() != 3 + n * RECORD_LEN {
        return Err(ParseError::BadLength);
    }
    let mut records = [[0u8; RECORD_LEN]; RECORDS_PER_FRAME];
    for slot in records.iter_mut().take(n) {
        *slot = r.array().ok_or(ParseError::BadLength)?;
        Record::from_bytes(slot).ok_or(ParseError::BadValue)?;
    }
    Ok(Response::CaptureRecords {
        first,
        count,
        records,
    })
}

/// Check that a payload has exactly `len` bytes.
fn expect_len(payload: &[u8], len: usize) -> Result<Reader<'_>, ParseError> {
    if payload.len() == len {
        Ok(Reader::new(payload))
    } else {
        Err(ParseError::BadLength)
    }
}

/// A finite `f32` (command values), else [`ParseError::BadValue`].
fn finite(v: Option<f32>) -> Result<f32, ParseError> {
    match v {
        Some(v) if v.is_finite() => Ok(v),
        Some(_) => Err(ParseError::BadValue),
        None => Err(ParseError::BadLength),
    }
}

impl Request {
    /// The controller command this request carries. Every valid request proves the
    /// link alive, so the requests that carry no motion command give
    /// [`Command::Heartbeat`]: the device hands exactly one command per valid
    /// request to the controller ([`super::Device::command`]).
    pub fn command(&self) -> Command {
        match *self {
            Request::Command(command) => command,
            Request::GetStatus
            | Request::ReadTuningTable
            | Request::WriteTuningTable(_)
            | Request::RunSelfTest
            | Request::ReadSelfTest
            | Request::RunIdentify
            | Request::ReadIdentify
            | Request::ArmCapture { .. }
            | Request::GetCapture
            | Request::ReadCapture { .. }
            | Request::StreamTelemetry { .. } => Command::Heartbeat,
        }
    }

    /// Whether the request is a motion command (stop, travel, hold, reset): its
    /// Ack or Nack is the controller's acceptance ([`super::Device::command`]).
    pub fn is_motion_command(&self) -> bool {
        !matches!(self.command(), Command::Heartbeat)
    }
}

impl From<Command> for Request {
    /// The request that carries `command` (the host side of [`Request::command`]).
    fn from(command: Command) -> Self {
        Request::Command(command)
    }
}

impl Message for Request {
    fn id(&self) -> MessageId {
        match self {
            Request::Command(Command::Heartbeat) => MessageId::Heartbeat,
            Request::GetStatus => MessageId::GetStatus,
            Request::Command(Command::Stop) => MessageId::Stop,
            Request::Command(Command::Travel { .. }) => MessageId::Travel,
            Request::Command(Command::HoldOffset { .. }) => MessageId::HoldOffset,
            Request::Command(Command::ResetFaults) => MessageId::ResetFaults,
            Request::ReadTuningTable => MessageId::ReadTuningTable,
            Request::WriteTuningTable(_) => MessageId::WriteTuningTable,
            Request::RunSelfTest => MessageId::RunSelfTest,
            Request::ReadSelfTest => MessageId::ReadSelfTest,
            Request::StreamTelemetry { .. } => MessageId::StreamTelemetry,
            Request::RunIdentify => MessageId::RunIdentify,
            Request::ReadIdentify => MessageId::ReadIdentify,
            Request::ArmCapture { .. } => MessageId::ArmCapture,
            Request::GetCapture => MessageId::GetCapture,
            Request::ReadCapture { .. } => MessageId::ReadCapture,
        }
    }

    fn write_payload(&self, out: &mut [u8]) -> Option<usize> {
        let mut w = Writer::new(out);
        match self {
            Request::Command(Command::Travel {
                direction,
                speed_rpm,
            }) => {
                w.u8(direction_code(*direction));
                w.f32(*speed_rpm);
            }
            Request::Command(Command::HoldOffset {
                speed_rpm,
                offset_deg,
            }) => {
                w.f32(*speed_rpm);
                w.f32(*offset_deg);
            }
            Request::WriteTuningTable(table) => write_table(&mut w, table),
            Request::StreamTelemetry { period_ms } => w.u16(*period_ms),
            Request::ArmCapture { trigger, window } => {
                w.u8(trigger.code());
                w.u16(*window);
            }
            Request::ReadCapture { first } => w.u16(*first),
            Request::Command(Command::Heartbeat | Command::Stop | Command::ResetFaults)
            | Request::GetStatus
            | Request::ReadTuningTable
            | Request::RunSelfTest
            | Request::ReadSelfTest
            | Request::RunIdentify
            | Request::ReadIdentify
            | Request::GetCapture => {}
        }
        w.finish()
    }

    fn parse(frame: &Frame<'_>) -> Result<Self, ParseError> {
        let id = MessageId::from_u8(frame.id)
            .filter(|id| id.is_request())
            .ok_or(ParseError::UnknownId)?;
        let p = frame.payload;
        let empty = |request: Request| expect_len(p, 0).map(|_| request);
        match id {
            MessageId::Heartbeat => empty(Request::Command(Command::Heartbeat)),
            MessageId::GetStatus => empty(Request::GetStatus),
            MessageId::Stop => empty(Request::Command(Command::Stop)),
            MessageId::ResetFaults => empty(Request::Command(Command::ResetFaults)),
            MessageId::ReadTuningTable => empty(Request::ReadTuningTable),
            MessageId::RunSelfTest => empty(Request::RunSelfTest),
            MessageId::ReadSelfTest => empty(Request::ReadSelfTest),
            MessageId::RunIdentify => empty(Request::RunIdentify),
            MessageId::ReadIdentify => empty(Request::ReadIdentify),
            MessageId::GetCapture => empty(Request::GetCapture),
            MessageId::ArmCapture => {
                let mut r = expect_len(p, 3)?;
                let (Some(trigger), Some(window)) = (r.u8(), r.u16()) else {
                    return Err(ParseError::BadLength);
                };
                let trigger = Trigger::from_code(trigger).ok_or(ParseError::BadValue)?;
                Ok(Request::ArmCapture { trigger, window })
            }
            MessageId::ReadCapture => {
                let mut r = expect_len(p, 2)?;
                let first = r.u16().ok_or(ParseError::BadLength)?;
                Ok(Request::ReadCapture { first })
            }
            MessageId::Travel => {
                let mut r = expect_len(p, 5)?;
                let direction = match r.u8() {
                    Some(0) => Direction::Right,
                    Some(1) => Direction::Left,
                    Some(_) => return Err(ParseError::BadValue),
                    None => return Err(ParseError::BadLength),
                };
                let speed_rpm = finite(r.f32())?;
                Ok(Request::Command(Command::Travel {
                    direction,
                    speed_rpm,
                }))
            }
            MessageId::HoldOffset => {
                let mut r = expect_len(p, 8)?;
                let speed_rpm = finite(r.f32())?;
                let offset_deg = finite(r.f32())?;
                Ok(Request::Command(Command::HoldOffset {
                    speed_rpm,
                    offset_deg,
                }))
            }
            MessageId::WriteTuningTable => read_table(p).map(Request::WriteTuningTable),
            MessageId::StreamTelemetry => {
                let mut r = expect_len(p, 2)?;
                let period_ms = r.u16().ok_or(ParseError::BadLength)?;
                if period_ms != 0 && period_ms < MIN_TELEMETRY_PERIOD_MS {
                    return Err(ParseError::BadValue);
                }
                Ok(Request::StreamTelemetry { period_ms })
            }
            // Responses were filtered out above.
            MessageId::Ack
            | MessageId::Nack
            | MessageId::Status
            | MessageId::TuningTable
            | MessageId::SelfTestResult
            | MessageId::Telemetry
            | MessageId::IdentifyResult
            | MessageId::CaptureInfo
            | MessageId::CaptureRecords => Err(ParseError::UnknownId),
        }
    }
}

impl Message for Response {
    fn id(&self) -> MessageId {
        match self {
            Response::Ack { .. } => MessageId::Ack,
            Response::Nack { .. } => MessageId::Nack,
            Response::Status(_) => MessageId::Status,
            Response::TuningTable(_) => MessageId::TuningTable,
            Response::SelfTest(_) => MessageId::SelfTestResult,
            Response::Telemetry(_) => MessageId::Telemetry,
            Response::Identify(_) => MessageId::IdentifyResult,
            Response::Capture(_) => MessageId::CaptureInfo,
            Response::CaptureRecords { .. } => MessageId::CaptureRecords,
        }
    }

    fn write_payload(&self, out: &mut [u8]) -> Option<usize> {
        let mut w = Writer::new(out);
        match self {
            Response::Ack { request } => w.u8(*request),
            Response::Nack { request, reason } => {
                w.u8(*request);
                w.u8(*reason as u8);
            }
            Response::Status(s) | Response::Telemetry(s) => write_status(&mut w, s),
            Response::TuningTable(table) => write_table(&mut w, table),
            Response::SelfTest(report) => report.write(&mut w),
            Response::Identify(report) => report.write(&mut w),
            Response::Capture(info) => w.bytes(&info.to_bytes()),
            Response::CaptureRecords {
                first,
                count,
                records,
            } => {
                w.u16(*first);
                w.u8(*count);
                for slot in records.iter().take(usize::from(*count)) {
                    w.bytes(slot);
                }
            }
        }
        w.finish()
    }

    fn parse(frame: &Frame<'_>) -> Result<Self, ParseError> {
        let id = MessageId::from_u8(frame.id)
            .filter(|id| !id.is_request())
            .ok_or(ParseError::UnknownId)?;
        let p = frame.payload;
        match id {
            MessageId::Ack => {
                let mut r = expect_len(p, 1)?;
                let request = r.u8().ok_or(ParseError::BadLength)?;
                Ok(Response::Ack { request })
            }
            MessageId::Nack => {
                let mut r = expect_len(p, 2)?;
                let (Some(request), Some(reason)) = (r.u8(), r.u8()) else {
                    return Err(ParseError::BadLength);
                };
                let reason = NackReason::from_u8(reason).ok_or(ParseError::BadValue)?;
                Ok(Response::Nack { request, reason })
            }
            MessageId::Status => read_status(p).map(Response::Status),
            MessageId::Telemetry => read_status(p).map(Response::Telemetry),
            MessageId::TuningTable => read_table(p).map(Response::TuningTable),
            MessageId::SelfTestResult => {
                let mut r = expect_len(p, SELF_TEST_REPORT_LEN)?;
                let report = SelfTestReport::read(&mut r).ok_or(ParseError::BadValue)?;
                Ok(Response::SelfTest(report))
            }
            MessageId::IdentifyResult => {
                let mut r = expect_len(p, IDENTIFY_REPORT_LEN)?;
                let report = IdentifyReport::read(&mut r).ok_or(ParseError::BadValue)?;
                Ok(Response::Identify(report))
            }
            MessageId::CaptureInfo => {
                expect_len(p, CAPTURE_INFO_LEN)?;
                let info = CaptureInfo::from_bytes(p).ok_or(ParseError::BadValue)?;
                Ok(Response::Capture(info))
            }
            MessageId::CaptureRecords => read_records(p),
            // Requests were filtered out above.
            MessageId::Heartbeat
            | MessageId::GetStatus
            | MessageId::Stop
            | MessageId::Travel
            | MessageId::HoldOffset
            | MessageId::ResetFaults
            | MessageId::ReadTuningTable
            | MessageId::WriteTuningTable
            | MessageId::RunSelfTest
            | MessageId::ReadSelfTest
            | MessageId::StreamTelemetry
            | MessageId::RunIdentify
            | MessageId::ReadIdentify
            | MessageId::ArmCapture
            | MessageId::GetCapture
            | MessageId::ReadCapture => Err(ParseError::UnknownId),
        }
    }
}
