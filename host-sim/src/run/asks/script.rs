//! What the scripts of `host-sim run --firmware` share: one request at a time
//! ([`Poll`]), the wait for rest before a procedure ([`RestWait`]), and what a
//! refused or missing answer says.
//!
//! Time here is the simulation's, the firmware's own clock (one control tick a
//! `1 / rate_hz`): the polling periods and the answer timeout are those
//! `host-sim device` keeps on the host's clock against a board.

use shared::protocol::{Request, Response, StatusReport, ANSWER_TIMEOUT_MS};

use crate::link::client::{answer_text, nack_text, request_name};
use crate::link::rest::{at_rest, motion, REST_HOLD_S, REST_TIMEOUT_S};
use crate::simulation::pil::host::Answer;

/// How often a script asks for a report it waits on, s: every 50 ms, as
/// `host-sim device` polls a procedure's report (each poll keeps the link
/// alive, so no heartbeat is sent meanwhile).
pub const POLL_S: f64 = 0.05;

/// One request at a time: asked when due, the next not before its answer came
/// and [`Poll::period_s`] after the last was asked; an answer that has not
/// come [`ANSWER_TIMEOUT_MS`] after its request is overdue (the firmware
/// answers within a few ticks: a frame of at most 414 bytes at 128 bytes an
/// exchange).
#[derive(Clone, Debug)]
pub struct Poll {
    /// The least time between two requests, s.
    pub period_s: f64,
    /// When the request awaited was asked, s.
    asked_s: Option<f64>,
    /// When the next may be asked, s.
    next_s: f64,
}

impl Poll {
    /// A poll every `period_s`, the first at once.
    pub fn new(period_s: f64) -> Self {
        Poll {
            period_s,
            asked_s: None,
            next_s: 0.0,
        }
    }

    /// Whether to ask now, at `t`, s (then the request is taken as asked).
    pub fn due(&mut self, t: f64) -> bool {
        if self.asked_s.is_some() || t < self.next_s - 1e-12 {
            return false;
        }
        self.asked(t);
        true
    }

    /// A request asked at `t`, s, outside [`Poll::due`] (the first of a read).
    pub fn asked(&mut self, t: f64) {
        self.asked_s = Some(t);
        self.next_s = t + self.period_s;
    }

    /// Its answer came.
    pub fn answered(&mut self) {
        self.asked_s = None;
    }

    /// Whether the request awaited is overdue at `t`, s.
    pub fn overdue(&self, t: f64) -> bool {
        self.asked_s
            .is_some_and(|a| t - a > f64::from(ANSWER_TIMEOUT_MS) * 1e-3 + 1e-12)
    }
}

/// The machine at rest before a procedure, as `host-sim device` waits for it
/// on a board (`link::rest::await_steady_rest`): every status asked for
/// [`REST_HOLD_S`] of the firmware's uptime at rest ([`at_rest`]: idle or
/// fault, both rotors below 10 rpm), at most [`REST_TIMEOUT_S`] from the
/// run's start. The plant starts with the eccentrics where the machine file
/// puts them, which they may leave: a rotor swinging through 0 rpm is not at
/// rest.
///
/// A capture waits for more ([`RestWait::settled`]): the controller idle with
/// both speed estimates settled (`crate::capture::settled`), the start a
/// replay needs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RestWait {
    /// The uptime, ms, since which every status was at rest.
    since_ms: Option<u32>,
    /// What counts as at rest: `at_rest`, or settled for a capture.
    settled: bool,
    /// How long it may take from the run's start, s.
    timeout_s: f64,
}

impl Default for RestWait {
    fn default() -> Self {
        RestWait {
            since_ms: None,
            settled: false,
            timeout_s: REST_TIMEOUT_S,
        }
    }
}

impl RestWait {
    /// Takes the status `s` that came at `t`, s: whether the machine has now
    /// held at rest long enough, or why `what` cannot start (not at rest by
    /// [`REST_TIMEOUT_S`]).
    pub fn take(&mut self, t: f64, s: &StatusReport, what: &str) -> Result<bool, String> {
        let still = if self.settled {
            crate::capture::settled(s)
        } else {
            at_rest(s)
        };
        self.since_ms = still.then(|| self.since_ms.unwrap_or(s.uptime_ms));
        let held = self
            .since_ms
            .is_some_and(|u0| f64::from(s.uptime_ms.wrapping_sub(u0)) >= REST_HOLD_S * 1e3);
        if !held && t >= self.timeout_s {
            return Err(format!(
                "{what} needs the motors stopped and both rotors at rest for {REST_HOLD_S} s; not so within {} s: {}",
                self.timeout_s,
                motion(s)
            ));
        }
        Ok(held)
    }

    /// The wait of a capture: idle with both speed estimates within
    /// `crate::capture::SETTLED_RPM` for [`REST_HOLD_S`], at most 30 s (as
    /// `device capture` waits).
    pub fn settled() -> Self {
        RestWait {
            since_ms: None,
            settled: true,
            timeout_s: 30.0,
        }
    }
}

/// What is wrong with `answer` for a script that waited for another: a Nack
/// is the firmware's refusal, with its reason; another answer (to the request
/// or not) is not what the script's stage waited for.
pub fn refused(answer: &Answer) -> String {
    match &answer.response {
        Response::Nack { reason, .. } => format!(
            "the firmware refused {}: {}",
            request_name(&answer.request),
            nack_text(*reason)
        ),
        other => format!(
            "the firmware answered {} with {}, not what was waited for",
            request_name(&answer.request),
            answer_text(other)
        ),
    }
}

/// The overdue answer's failure at `t`, s.
pub fn no_answer(request: &Request, t: f64) -> String {
    format!(
        "no answer to {} within {ANSWER_TIMEOUT_MS} ms (at t = {t} s)",
        request_name(request)
    )
}

/// A script's side of an exchange: the answers taken one by one, the answer
/// awaited given up when overdue, the next poll sent when due.
pub trait Asker {
    /// Takes answer `a` at `t`, s: the request it decides on, if any.
    fn take(&mut self, t: f64, a: &Answer) -> Option<Request>;
    /// The request polled in the stage it is in now, if any.
    fn poll_request(&self) -> Option<Request>;
    /// Its poll, its request awaited and its failure.
    fn asking(&mut self) -> (&mut Poll, &mut Option<Request>, &mut Option<String>);
}

/// One exchange of `s` at `t`, s, with `answers` received since the last:
/// each answer taken (a failure ends it with nothing sent), an awaited answer
/// overdue the script's failure, then the request decided on (awaited from
/// now), else the stage's poll when due.
pub fn exchange<A: Asker>(s: &mut A, t: f64, answers: &[Answer]) -> Vec<Request> {
    let mut out = Vec::new();
    for a in answers {
        out.extend(s.take(t, a));
        if s.asking().2.is_some() {
            return Vec::new();
        }
    }
    let poll_request = s.poll_request();
    let (poll, awaited, failure) = s.asking();
    if let Some(r) = awaited.as_ref() {
        if poll.overdue(t) {
            *failure = Some(no_answer(r, t));
            return Vec::new();
        }
    }
    if let Some(r) = out.first() {
        poll.asked(t);
        *awaited = Some(r.clone());
    } else if let Some(r) = poll_request.filter(|_| poll.due(t)) {
        *awaited = Some(r.clone());
        out.push(r);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use shared::protocol::{Message, NackReason};

    #[test]
    fn a_poll_asks_once_at_a_time_and_not_before_its_period() {
        let mut p = Poll::new(0.05);
        assert!(p.due(0.0));
        // Not answered: nothing more, however late.
        assert!(!p.due(0.2));
        assert!(p.overdue(0.2));
        p.answered();
        assert!(!p.overdue(0.2));
        assert!(p.due(0.2));
        p.answered();
        // Answered at once: the next after the period.
        assert!(!p.due(0.21));
        assert!(p.due(0.25));
    }

    #[test]
    fn a_refusal_says_the_request_and_the_reason() {
        let a = Answer {
            request: Request::RunIdentify,
            response: Response::Nack {
                request: Request::RunIdentify.id() as u8,
                reason: NackReason::NotStopped,
            },
        };
        assert_eq!(
            refused(&a),
            "the firmware refused RunIdentify: the motors must be stopped (state idle or fault, rotors at rest)"
        );
        let a = Answer {
            request: Request::GetCapture,
            response: Response::Ack {
                request: Request::GetCapture.id() as u8,
            },
        };
        assert!(
            refused(&a).contains("GetCapture with an Ack"),
            "{}",
            refused(&a)
        );
    }
}
