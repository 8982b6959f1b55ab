//! The device side of the answer rule: every frame gets exactly one answer, except
//! one whose header failed its CRC (nothing in it, not even the sequence number, can
//! be trusted). [`answer_event`] turns a decoder event into that answer;
//! [`answer_request`] carries out a valid request on a [`Device`].
//!
//! | frame | answer (header sequence number = the request's) |
//! | --- | --- |
//! | header CRC wrong | none: the host times out and sends again |
//! | other version | `Nack(id, BadVersion)` |
//! | length above `MAX_PAYLOAD` | `Nack(id, TooLong)` |
//! | frame CRC wrong | `Nack(id, BadCrc)` |
//! | unknown or response id | `Nack(id, UnknownMessage)` |
//! | payload length wrong for the id | `Nack(id, BadLength)` |
//! | a field out of its domain | `Nack(id, BadValue)` |
//! | `Heartbeat` | `Ack` |
//! | `GetStatus` | `Status` |
//! | `Stop`, `Travel`, `HoldOffset`, `ResetFaults` | `Ack`, or `Nack` with the device's reason |
//! | `ReadTuningTable` | `TuningTable` |
//! | `WriteTuningTable` | `Ack` once stored; `Nack(Busy)` while a self-test or an identification runs; `Nack(NotStopped)` unless [`may_write_table`]; `Nack(StorageFailed)` |
//! | `RunSelfTest`, `RunIdentify` | `Ack` once started; `Nack(Busy)` while a self-test or an identification runs or waits to start; `Nack(Faulted)` in fault; `Nack(NotStopped)` unless idle and at rest |
//! | `ReadSelfTest` | `SelfTest` |
//! | `ReadIdentify` | `Identify` |
//! | `StreamTelemetry` | `Ack` |
//! | `ArmCapture` | `Ack`; `Nack(BadValue)` for a window longer than the buffer |
//! | `GetCapture` | `Capture` |
//! | `ReadCapture` | `CaptureRecords` |

use crate::controller::{may_write_table, Command, State, TuningTable};

use crate::controller::identify::{IdentifyReport, IdentifyStatus};
use crate::controller::self_test::{SelfTestReport, SelfTestStatus};

use crate::capture::{Capture, CaptureInfo, Slot, Trigger, RECORDS_PER_FRAME, RECORD_LEN};

use super::frame::{Frame, FrameError};
use super::message::{Message, MessageId, NackReason, Request, Response, StatusReport};

/// What the protocol needs from the device (the firmware, or host-sim's simulated
/// device). Every method returns at once except
/// [`Device::store_tuning_table`], which erases and writes a flash sector.
pub trait Device {
    /// The state, faults and telemetry of the latest control tick.
    fn status(&self) -> StatusReport;

    /// Hand `command` to the controller for its next tick; `Err` to refuse it (a
    /// self-test running: [`NackReason::Busy`]). Called once for every valid
    /// request: with [`Command::Heartbeat`] for those that carry no motion command,
    /// so every valid frame keeps the link alive. A heartbeat must not replace a
    /// motion command still waiting for the next tick.
    fn command(&mut self, command: Command) -> Result<(), NackReason>;

    /// The tuning table in use.
    fn tuning_table(&self) -> TuningTable;

    /// Store `table` in flash ([`crate::storage::store`], motors stopped: the caller
    /// checked [`may_write_table`]) and use it from now on; `Err` leaves the previous table
    /// in use (and in flash).
    fn store_tuning_table(&mut self, table: &TuningTable) -> Result<(), NackReason>;

    /// The self-test's status and its latest result.
    fn self_test(&self) -> SelfTestReport;

    /// Start the self-test (the caller checked: idle, rotors at rest); `Busy`
    /// while a procedure asked for has not started yet.
    fn start_self_test(&mut self) -> Result<(), NackReason>;

    /// The motor identification's status and its latest result.
    fn identify(&self) -> IdentifyReport;

    /// Start the motor identification (the caller checked: idle, rotors at
    /// rest); `Busy` while a procedure asked for has not started yet.
    fn start_identify(&mut self) -> Result<(), NackReason>;

    /// Send [`Response::Telemetry`] every `period_ms` from now on (0: none).
    fn set_telemetry_period(&mut self, period_ms: u16);

    /// Arm the capture ([`Capture::arm`]): `BadValue` for a window longer than
    /// the buffer. A device without a capture buffer (the default) refuses
    /// every window but 0.
    fn arm_capture(&mut self, trigger: Trigger, window: u16) -> Result<(), NackReason> {
        Capture::none()
            .arm(trigger, window)
            .map_err(|_| NackReason::BadValue)
    }

    /// The capture's status and everything besides its records.
    fn capture_info(&self) -> CaptureInfo {
        Capture::none().info()
    }

    /// The capture's records from `first` on, copied into `out`; how many.
    fn read_capture(&self, first: u16, out: &mut [Slot; RECORDS_PER_FRAME]) -> usize {
        Capture::none().read(first, out)
    }
}

/// The Ack or Nack of request id `request`.
fn verdict(request: u8, result: Result<(), NackReason>) -> Response {
    match result {
        Ok(()) => Response::Ack { request },
        Err(reason) => Response::Nack { request, reason },
    }
}

/// Whether a procedure that drives the motors on its own (the self-test, the
/// identification) runs: the other requests that need the motors stopped wait.
fn busy<D: Device + ?Sized>(device: &D) -> bool {
    device.self_test().status == SelfTestStatus::Running
        || device.identify().status == IdentifyStatus::Running
}

/// Whether a procedure may start now: `Busy`, `Faulted` or `NotStopped` if not.
fn may_start<D: Device + ?Sized>(device: &D) -> Result<(), NackReason> {
    let status = device.status();
    if busy(device) {
        Err(NackReason::Busy)
    } else if status.state == State::Fault {
        Err(NackReason::Faulted)
    } else if status.state != State::Idle
        || !may_write_table(status.state, status.telemetry.speed_rpm)
    {
        Err(NackReason::NotStopped)
    } else {
        Ok(())
    }
}

/// Carry out a valid request on `device` and give its answer (the module's table).
pub fn answer_request<D: Device + ?Sized>(device: &mut D, request: &Request) -> Response {
    let id = request.id() as u8;
    // One command per valid request: the motion command, or a heartbeat.
    let commanded = device.command(request.command());
    match request {
        Request::Command(Command::Stop)
        | Request::Command(Command::Travel { .. })
        | Request::Command(Command::HoldOffset { .. })
        | Request::Command(Command::ResetFaults)
        | Request::Command(Command::Heartbeat) => verdict(id, commanded),
        Request::GetStatus => Response::Status(device.status()),
        Request::ReadTuningTable => Response::TuningTable(device.tuning_table()),
        Request::ReadSelfTest => Response::SelfTest(device.self_test()),
        Request::ReadIdentify => Response::Identify(device.identify()),
        Request::StreamTelemetry { period_ms } => {
            device.set_telemetry_period(*period_ms);
            Response::Ack { request: id }
        }
        Request::WriteTuningTable(table) => {
            let status = device.status();
            if busy(device) {
                verdict(id, Err(NackReason::Busy))
            } else if may_write_table(status.state, status.telemetry.speed_rpm) {
                verdict(id, device.store_tuning_table(table))
            } else {
                verdict(id, Err(NackReason::NotStopped))
            }
        }
        Request::RunSelfTest => verdict(
            id,
            may_start(device).and_then(|()| device.start_self_test()),
        ),
        Request::RunIdentify => {
            verdict(id, may_start(device).and_then(|()| device.start_identify()))
        }
        Request::ArmCapture { trigger, window } => {
            verdict(id, device.arm_capture(*trigger, *window))
        }
        Request::GetCapture => Response::Capture(device.capture_info()),
        Request::ReadCapture { first } => {
            let mut records = [[0u8; RECORD_LEN]; RECORDS_PER_FRAME];
            let count = device.read_capture(*first, &mut records);
            Response::CaptureRecords {
                first: *first,
                count: count as u8,
                records,
            }
        }
    }
}

/// The answer to one decoder event, as `(sequence number, response)` to encode with
/// [`super::encode`]; `None` only for [`FrameError::HeaderCrc`].
pub fn answer_event<D: Device + ?Sized>(
    device: &mut D,
    event: Result<Frame<'_>, FrameError>,
) -> Option<(u16, Response)> {
    match event {
        Ok(frame) => {
            let response = match Request::parse(&frame) {
                Ok(request) => answer_request(device, &request),
                Err(e) => Response::Nack {
                    request: frame.id,
                    reason: NackReason::from(e),
                },
            };
            Some((frame.seq, response))
        }
        Err(error) => answer_error(&error),
    }
}

/// The answer to a rejected frame: a Nack to its sequence number when its header
/// was right, nothing otherwise.
pub fn answer_error(error: &FrameError) -> Option<(u16, Response)> {
    let reason = match error {
        FrameError::HeaderCrc => return None,
        FrameError::BadVersion { .. } => NackReason::BadVersion,
        FrameError::TooLong { .. } => NackReason::TooLong,
        FrameError::BadCrc { .. } => NackReason::BadCrc,
    };
    let (seq, request) = error.header()?;
    Some((seq, Response::Nack { request, reason }))
}

/// Whether a response id is a direct answer to a request (not the telemetry stream).
pub fn is_answer(id: MessageId) -> bool {
    !id.is_request() && id != MessageId::Telemetry
}
