//! The capture on the firmware in the loop (`host-sim run --firmware ELF
//! --command ... --capture FILE.csv --capture-for S`), asked as `host-sim
//! device capture --travel ...` asks a board for it (`device::capture`):
//!
//! 1. the status every [`POLL_S`] until the machine has held at rest
//!    ([`RestWait`]: 0.5 s of the firmware's uptime). A replay starts its
//!    controller afresh, idle and at rest, at the capture's first tick; the
//!    board's must be so there too. At the run's start it is not: the
//!    eccentrics start where the machine file puts them and may move, and
//!    the board's controller has seen a count or two go by (a speed a fresh
//!    one has not), as a board at rest for a while has not;
//! 2. `ArmCapture` with the trigger `command` and the window, then the run's
//!    command once the firmware has accepted it: the recording starts at the
//!    tick that takes the command;
//! 3. the capture's status every [`POLL_S`] until it is done;
//! 4. its records, [`RECORDS_PER_FRAME`] a request, each asked once the last
//!    came; then its status again (the same capture: its id and count) and the
//!    tuning table in use.
//!
//! The plant runs on meanwhile under the run's command; the run's end time
//! must leave room for the wait, the window and the read ([`needed_s`]).
//! [`capture_file`] puts the file together from the answers.

use shared::capture::{CaptureInfo, CaptureStatus, Record, Trigger, RECORDS_PER_FRAME, RECORD_LEN};
use shared::controller::{Command, TuningTable};
use shared::pil::MAX_BYTES;
use shared::protocol::{Request, Response, CRC_LEN, HEADER_LEN};

use super::script::{exchange, refused, Asker, Poll, RestWait, POLL_S};
use crate::capture::CaptureFile;
use crate::link::rest::REST_HOLD_S;
use crate::simulation::pil::host::Answer;
use crate::simulation::pil::script::Script;

/// Where the capture stands.
#[derive(Clone, Debug, PartialEq)]
enum Stage {
    /// Waiting for rest.
    Rest(RestWait),
    /// `ArmCapture` sent, its answer awaited.
    Arming,
    /// Armed, the run's command sent, its answer awaited.
    Commanding,
    /// Armed: its status polled until it is done.
    Waiting,
    /// Done (`info`): the records from `next` on asked.
    Reading {
        /// The capture read.
        info: CaptureInfo,
        /// The first record not read yet.
        next: u16,
    },
    /// Every record read: its status asked again.
    Checking(CaptureInfo),
    /// The same capture: the tuning table asked.
    Table,
    /// Read out.
    Over,
}

/// The capture's requests ([module doc](self)).
#[derive(Clone, Debug)]
pub struct CaptureScript {
    window: u16,
    command: Command,
    stage: Stage,
    poll: Poll,
    awaited: Option<Request>,
    failure: Option<String>,
}

impl CaptureScript {
    /// A capture of `window` ticks from the run's `command`, which it sends.
    pub fn new(window: u16, command: Command) -> Self {
        CaptureScript {
            window,
            command,
            stage: Stage::Rest(RestWait::settled()),
            poll: Poll::new(POLL_S),
            awaited: None,
            failure: None,
        }
    }

    /// Takes one answer at `t`, s; the request to send at once, if any.
    fn take(&mut self, t: f64, answer: &Answer) -> Option<Request> {
        self.poll.answered();
        self.awaited = None;
        match (&self.stage, &answer.response) {
            (Stage::Rest(rest), Response::Status(s)) => {
                let mut rest = *rest;
                match rest.take(t, s, "the capture") {
                    Ok(true) => {
                        self.stage = Stage::Arming;
                        return Some(Request::ArmCapture {
                            trigger: Trigger::Command,
                            window: self.window,
                        });
                    }
                    Ok(false) => self.stage = Stage::Rest(rest),
                    Err(why) => self.failure = Some(why),
                }
            }
            (Stage::Arming, Response::Ack { .. }) => {
                self.stage = Stage::Commanding;
                return Some(Request::Command(self.command));
            }
            (Stage::Commanding, Response::Ack { .. }) => self.stage = Stage::Waiting,
            (Stage::Waiting, Response::Capture(i)) => match i.status {
                CaptureStatus::Done => return self.read_from(i.clone(), 0),
                CaptureStatus::Armed | CaptureStatus::Recording => {}
                CaptureStatus::Empty => {
                    self.failure = Some("the firmware's capture was disarmed".into());
                }
            },
            (Stage::Reading { info, next }, Response::CaptureRecords { first, count, .. })
                if first == next =>
            {
                let info = info.clone();
                if *count == 0 {
                    self.failure = Some(format!(
                        "the firmware sent no record from tick {next} of {}",
                        info.recorded
                    ));
                    return None;
                }
                return self.read_from(info, next + u16::from(*count));
            }
            (Stage::Checking(info), Response::Capture(after)) => {
                if (after.id, after.recorded) != (info.id, info.recorded) {
                    self.failure = Some("the firmware's capture changed while it was read".into());
                    return None;
                }
                self.stage = Stage::Table;
                return Some(Request::ReadTuningTable);
            }
            (Stage::Table, Response::TuningTable(_)) => self.stage = Stage::Over,
            _ => self.failure = Some(refused(answer)),
        }
        None
    }

    /// The records of `info` from `next` on: the next request.
    fn read_from(&mut self, info: CaptureInfo, next: u16) -> Option<Request> {
        if next >= info.recorded {
            self.stage = Stage::Checking(info);
            return Some(Request::GetCapture);
        }
        self.stage = Stage::Reading { info, next };
        Some(Request::ReadCapture { first: next })
    }
}

impl Asker for CaptureScript {
    fn take(&mut self, t: f64, a: &Answer) -> Option<Request> {
        CaptureScript::take(self, t, a)
    }

    fn poll_request(&self) -> Option<Request> {
        match self.stage {
            Stage::Rest(_) => Some(Request::GetStatus),
            Stage::Waiting => Some(Request::GetCapture),
            _ => None,
        }
    }

    fn asking(&mut self) -> (&mut Poll, &mut Option<Request>, &mut Option<String>) {
        (&mut self.poll, &mut self.awaited, &mut self.failure)
    }
}

impl Script for CaptureScript {
    fn step(&mut self, t: f64, answers: &[Answer]) -> Vec<Request> {
        exchange(self, t, answers)
    }

    fn failure(&self) -> Option<String> {
        self.failure.clone()
    }
}

/// Exchanges the read of one frame of records takes at most: its answer
/// (`HEADER_LEN + 3 + RECORDS_PER_FRAME x RECORD_LEN + CRC_LEN` = 413 bytes)
/// at [`MAX_BYTES`] (128) an exchange, and one for the next request.
pub fn exchanges_per_frame() -> usize {
    let frame = HEADER_LEN + 3 + RECORDS_PER_FRAME * RECORD_LEN + CRC_LEN;
    frame.div_ceil(MAX_BYTES) + 1
}

/// How long the read of a capture of `window` ticks takes at most after its
/// last tick, s, ticking every `tick_s`: a poll period until its status says
/// done, every frame of records ([`exchanges_per_frame`]), and the status and
/// the table at the end (a frame each) with a poll period's slack.
pub fn read_out_s(window: u16, tick_s: f64) -> f64 {
    let frames = usize::from(window).div_ceil(RECORDS_PER_FRAME) + 2;
    2.0 * POLL_S + (frames * exchanges_per_frame()) as f64 * tick_s
}

/// The least run, s, that reads out a capture of `window` ticks, ticking
/// every `tick_s`, when the machine is at rest from the start: the rest held
/// ([`REST_HOLD_S`]) seen within a poll period, the arm and the command (a
/// frame each way, two poll periods at most), the window and the read
/// ([`read_out_s`]). A machine that takes longer to rest needs more.
pub fn needed_s(window: u16, tick_s: f64) -> f64 {
    REST_HOLD_S + 3.0 * POLL_S + f64::from(window) * tick_s + read_out_s(window, tick_s)
}

/// The capture file from `answers`: the capture's status when it was done,
/// its records in order and the table in use; `Err` says what is missing or
/// does not fit.
pub fn capture_file(answers: &[Answer]) -> Result<CaptureFile, String> {
    let mut info: Option<&CaptureInfo> = None;
    let mut records = Vec::new();
    let mut table: Option<&TuningTable> = None;
    for a in answers {
        match &a.response {
            Response::Capture(i) if i.status == CaptureStatus::Done => info = Some(i),
            Response::CaptureRecords {
                count,
                records: slots,
                ..
            } => {
                let count = usize::from(*count).min(RECORDS_PER_FRAME);
                // The frame's parse checked every record.
                records.extend(slots[..count].iter().filter_map(Record::from_bytes));
            }
            Response::TuningTable(t) => table = Some(t),
            _ => {}
        }
    }
    let (Some(info), Some(table)) = (info, table) else {
        return Err("the capture had not been read out".into());
    };
    if records.len() != usize::from(info.recorded) {
        return Err(format!(
            "{} records read of {}",
            records.len(),
            info.recorded
        ));
    }
    CaptureFile::from_device(info, records, table)
}

#[cfg(test)]
mod tests {
    use super::*;
    use shared::protocol::Message;

    #[test]
    fn a_frame_of_records_takes_five_exchanges() {
        // 413 bytes: 4 exchanges of 128, and one for the next request.
        assert_eq!(exchanges_per_frame(), 5);
        // 2000 ticks: 182 frames and two more, 0.92 s at 1 kHz, and 0.1 s.
        assert!((read_out_s(2000, 1e-3) - 1.02).abs() < 1e-12);
    }

    fn status(uptime_ms: u32) -> Answer {
        Answer {
            request: Request::GetStatus,
            response: Response::Status(shared::protocol::StatusReport {
                uptime_ms,
                state: shared::controller::State::Idle,
                faults: shared::controller::Faults::NONE,
                telemetry: shared::protocol::link::no_telemetry(),
                rx_dropped: 0,
            }),
        }
    }

    fn ack(r: &Request) -> Answer {
        Answer {
            request: r.clone(),
            response: Response::Ack {
                request: r.id() as u8,
            },
        }
    }

    #[test]
    fn it_arms_at_rest_then_sends_the_command_and_fails_on_a_refusal() {
        let travel = Command::Travel {
            direction: shared::controller::Direction::Right,
            speed_rpm: 3000.0,
        };
        let mut s = CaptureScript::new(100, travel);
        assert_eq!(s.step(0.0, &[]), vec![Request::GetStatus]);
        assert_eq!(s.step(0.05, &[status(1)]), vec![Request::GetStatus]);
        let arm = s.step(0.55, &[status(550)]);
        assert_eq!(
            arm,
            vec![Request::ArmCapture {
                trigger: Trigger::Command,
                window: 100
            }]
        );
        let command = s.step(0.551, &[ack(&arm[0])]);
        assert_eq!(command, vec![Request::Command(travel)]);
        assert!(s.step(0.552, &[ack(&command[0])]).is_empty());
        assert_eq!(s.step(0.601, &[]), vec![Request::GetCapture]);
        assert_eq!(s.failure(), None);

        let mut s = CaptureScript::new(100, travel);
        s.step(0.0, &[]);
        s.step(0.05, &[status(1)]);
        let arm = s.step(0.55, &[status(550)]);
        let nack = Answer {
            request: arm[0].clone(),
            response: Response::Nack {
                request: arm[0].id() as u8,
                reason: shared::protocol::NackReason::BadValue,
            },
        };
        assert!(s.step(0.551, &[nack]).is_empty());
        assert!(s.failure().unwrap().contains("refused ArmCapture"));
        assert!(capture_file(&[]).is_err());
    }
}
