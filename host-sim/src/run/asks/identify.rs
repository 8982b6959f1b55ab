//! The motor identification on the firmware in the loop (`host-sim run
//! --firmware ELF --identify`), asked as `host-sim device identify` asks a
//! board for it (`device::procedure::run`):
//!
//! 1. the status every [`POLL_S`] until the machine has held at rest
//!    ([`RestWait`]: 0.5 s of the firmware's uptime, at most 10 s);
//! 2. `RunIdentify`, which the firmware must accept;
//! 3. its report every [`POLL_S`] until it is done or aborted; one still not
//!    started [`NOT_STARTED_S`] after the Ack is a failure.
//!
//! The run ends with the tick that brought the final report
//! ([`Script::ends_run`]); [`final_report`] finds it among the answers.

use shared::controller::identify::{IdentifyReport, IdentifyStatus};
use shared::protocol::{Request, Response};

use super::script::{exchange, refused, Asker, Poll, RestWait, POLL_S};
use crate::simulation::pil::host::Answer;
use crate::simulation::pil::script::Script;

/// A report still `not run` this long after the firmware accepted
/// `RunIdentify` is a failure, s: its control task takes the request at its
/// next tick (`device::procedure` allows a board 2 s).
pub const NOT_STARTED_S: f64 = 2.0;

/// Where the identification stands.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Stage {
    /// Waiting for rest.
    Rest(RestWait),
    /// `RunIdentify` sent, its answer awaited.
    Asked,
    /// Accepted at `since_s`: its report polled.
    Running { since_s: f64 },
    /// Done or aborted: the final report came.
    Over,
}

/// The identification's requests ([module doc](self)).
#[derive(Clone, Debug)]
pub struct IdentifyScript {
    stage: Stage,
    poll: Poll,
    /// The request awaited (for a timeout's message).
    awaited: Option<Request>,
    failure: Option<String>,
}

impl Default for IdentifyScript {
    fn default() -> Self {
        IdentifyScript::new()
    }
}

impl IdentifyScript {
    /// At the start of the run.
    pub fn new() -> Self {
        IdentifyScript {
            stage: Stage::Rest(RestWait::default()),
            poll: Poll::new(POLL_S),
            awaited: None,
            failure: None,
        }
    }

    /// Takes one answer at `t`, s; a request to send at once, if any.
    fn take(&mut self, t: f64, answer: &Answer) -> Option<Request> {
        self.poll.answered();
        self.awaited = None;
        match (self.stage, &answer.response) {
            (Stage::Rest(mut rest), Response::Status(s)) => {
                match rest.take(t, s, "the identification") {
                    Ok(true) => {
                        self.stage = Stage::Asked;
                        return Some(Request::RunIdentify);
                    }
                    Ok(false) => self.stage = Stage::Rest(rest),
                    Err(why) => self.failure = Some(why),
                }
            }
            (Stage::Asked, Response::Ack { .. }) => {
                self.stage = Stage::Running { since_s: t };
            }
            (Stage::Running { since_s }, Response::Identify(r)) => match r.status {
                IdentifyStatus::Done | IdentifyStatus::Aborted => self.stage = Stage::Over,
                IdentifyStatus::NotRun if t - since_s >= NOT_STARTED_S => {
                    self.failure = Some(format!(
                        "the firmware accepted the identification but has not started it after {NOT_STARTED_S} s"
                    ));
                }
                IdentifyStatus::NotRun | IdentifyStatus::Running => {}
            },
            _ => self.failure = Some(refused(answer)),
        }
        None
    }
}

impl Asker for IdentifyScript {
    fn take(&mut self, t: f64, a: &Answer) -> Option<Request> {
        IdentifyScript::take(self, t, a)
    }

    fn poll_request(&self) -> Option<Request> {
        match self.stage {
            Stage::Rest(_) => Some(Request::GetStatus),
            Stage::Running { .. } => Some(Request::ReadIdentify),
            Stage::Asked | Stage::Over => None,
        }
    }

    fn asking(&mut self) -> (&mut Poll, &mut Option<Request>, &mut Option<String>) {
        (&mut self.poll, &mut self.awaited, &mut self.failure)
    }
}

impl Script for IdentifyScript {
    fn step(&mut self, t: f64, answers: &[Answer]) -> Vec<Request> {
        // RunIdentify, once decided, is awaited as any request.
        exchange(self, t, answers)
    }

    fn ends_run(&self) -> bool {
        self.stage == Stage::Over
    }

    fn failure(&self) -> Option<String> {
        self.failure.clone()
    }
}

/// The identification's final report among `answers` (done or aborted), if
/// it came.
pub fn final_report(answers: &[Answer]) -> Option<IdentifyReport> {
    answers.iter().rev().find_map(|a| match &a.response {
        Response::Identify(r)
            if matches!(r.status, IdentifyStatus::Done | IdentifyStatus::Aborted) =>
        {
            Some(*r)
        }
        _ => None,
    })
}

/// The status of the last report among `answers`, for a run that ended before
/// the final one: `not asked` before the first.
pub fn last_status(answers: &[Answer]) -> &'static str {
    answers
        .iter()
        .rev()
        .find_map(|a| match &a.response {
            Response::Identify(r) => Some(match r.status {
                IdentifyStatus::NotRun => "not started",
                IdentifyStatus::Running => "running",
                IdentifyStatus::Done => "done",
                IdentifyStatus::Aborted => "aborted",
            }),
            _ => None,
        })
        .unwrap_or("not started (the rotors never held at rest, or no report came)")
}

#[cfg(test)]
mod tests {
    use super::*;
    use shared::controller::{Faults, State};
    use shared::protocol::link::no_telemetry;
    use shared::protocol::Message;
    use shared::protocol::StatusReport;

    fn status(uptime_ms: u32, rpm: f32) -> Answer {
        Answer {
            request: Request::GetStatus,
            response: Response::Status(StatusReport {
                uptime_ms,
                state: State::Idle,
                faults: Faults::NONE,
                telemetry: shared::controller::Telemetry {
                    speed_rpm: [rpm, 0.0],
                    ..no_telemetry()
                },
                rx_dropped: 0,
            }),
        }
    }

    fn report(status: IdentifyStatus) -> Answer {
        Answer {
            request: Request::ReadIdentify,
            response: Response::Identify(IdentifyReport {
                status,
                identity: Default::default(),
            }),
        }
    }

    #[test]
    fn it_waits_for_rest_then_asks_and_polls_until_the_report_is_final() {
        let mut s = IdentifyScript::new();
        assert_eq!(s.step(0.0, &[]), vec![Request::GetStatus]);
        // Swinging, then at rest from 100 ms: held at 600 ms.
        assert_eq!(s.step(0.002, &[status(2, 40.0)]), Vec::<Request>::new());
        assert_eq!(s.step(0.05, &[]), vec![Request::GetStatus]);
        assert_eq!(s.step(0.1, &[status(100, 3.0)]), vec![Request::GetStatus]);
        assert_eq!(s.step(0.6, &[status(600, 0.0)]), vec![Request::RunIdentify]);
        let ack = Answer {
            request: Request::RunIdentify,
            response: Response::Ack {
                request: Request::RunIdentify.id() as u8,
            },
        };
        // The report polled from one period after the request.
        assert_eq!(s.step(0.601, &[ack]), Vec::<Request>::new());
        assert_eq!(s.step(0.65, &[]), vec![Request::ReadIdentify]);
        assert!(!s.ends_run());
        let polled = s.step(0.7, &[report(IdentifyStatus::Running)]);
        assert_eq!(polled, vec![Request::ReadIdentify]);
        s.step(0.75, &[report(IdentifyStatus::Done)]);
        assert!(s.ends_run());
        assert_eq!(s.failure(), None);
        let answers = [
            report(IdentifyStatus::Running),
            report(IdentifyStatus::Done),
        ];
        assert_eq!(
            final_report(&answers).map(|r| r.status),
            Some(IdentifyStatus::Done)
        );
        assert_eq!(final_report(&answers[..1]), None);
        assert_eq!(last_status(&answers[..1]), "running");
    }

    #[test]
    fn a_refusal_a_silence_or_a_machine_never_at_rest_fails() {
        let mut s = IdentifyScript::new();
        s.step(0.0, &[]);
        s.step(0.6, &[status(600, 0.0)]);
        s.step(1.2, &[status(1200, 0.0)]);
        let nack = Answer {
            request: Request::RunIdentify,
            response: Response::Nack {
                request: Request::RunIdentify.id() as u8,
                reason: shared::protocol::NackReason::Faulted,
            },
        };
        s.step(1.21, &[nack]);
        assert!(s.failure().unwrap().contains("refused RunIdentify"));

        let mut s = IdentifyScript::new();
        s.step(0.0, &[]);
        s.step(0.5, &[]);
        assert!(s.failure().unwrap().contains("no answer to GetStatus"));

        let mut s = IdentifyScript::new();
        s.step(10.0, &[status(10_000, 50.0)]);
        assert!(s.failure().unwrap().contains("not so within"));
    }
}
