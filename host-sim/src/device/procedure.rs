//! A procedure the device runs on its own once asked (the self-test, the motor
//! identification), from the host's side: wait for the rotors at rest, ask for
//! it, make sure the device took it, poll its report (every poll a heartbeat
//! too) until it is done or aborted, and stop it on Ctrl-C.

use std::time::{Duration, Instant};

use shared::controller::{Command, State};
use shared::protocol::{Request, StatusReport};

use crate::failure::Failure;
use crate::interrupt;
use crate::link::client::Client;
use crate::link::requests::command;
use crate::link::rest::{self, await_steady_rest, Poll, REST_HOLD_S, REST_TIMEOUT_S};

/// How often a procedure's report is asked for.
const POLL: Duration = Duration::from_millis(50);

/// The longest wait for the device's next control tick, s: the board ticks
/// every millisecond; a device whose uptime stands this long is said to.
pub const TICK_WAIT_S: f64 = 1.0;

/// Where a procedure stands, whichever it is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    /// None has run since the device started (or the result was stored).
    NotRun,
    /// One runs.
    Running,
    /// The last one finished.
    Done,
    /// The last one was stopped (a fault, the E-stop or a stop).
    Aborted,
}

impl Stage {
    /// `not run`, `running`, `done` or `aborted`.
    pub fn name(self) -> &'static str {
        match self {
            Stage::NotRun => "not run",
            Stage::Running => "running",
            Stage::Done => "done",
            Stage::Aborted => "aborted",
        }
    }
}

/// One procedure: its name in messages, its request, and how to read its report.
pub struct Procedure<R> {
    /// `self-test`, `identification`.
    pub name: &'static str,
    /// The last one's report, for messages: `the last test's`.
    pub last: &'static str,
    /// The request that starts it.
    pub start: Request,
    /// Its report, asked of the device.
    pub read: fn(&mut Client) -> Result<R, Failure>,
    /// The report's stage.
    pub stage: fn(&R) -> Stage,
}

/// Runs `p` on the device through `client`, giving up after `timeout_s`: its
/// final report, done or aborted (the caller prints it and says which); a
/// failure if the rotors do not come to rest, the device refuses or never takes
/// it, it does not end in time, or Ctrl-C stopped it.
pub fn run<R>(client: &mut Client, p: &Procedure<R>, timeout_s: f64) -> Result<R, Failure> {
    interrupt::catch();
    // The device takes it only with both rotors at rest; after a stop an
    // eccentric may swing on for a while (module `rest`). With the motors
    // driven (or a procedure running) there is nothing to wait for: the device
    // answers the request with its reason.
    if matches!(Poll::status(client)?.state, State::Idle | State::Fault) {
        let rest = await_steady_rest(client, REST_HOLD_S, REST_TIMEOUT_S)?;
        if !rest.reached {
            return Err(Failure::device(format!(
                "the {} needs the motors stopped and both rotors at rest (below {} rpm) for {REST_HOLD_S} s; not so within {REST_TIMEOUT_S} s: {}",
                p.name,
                shared::controller::WRITE_MAX_SPEED_RPM,
                rest::motion(&rest.status)
            )));
        }
    }
    command(client, &p.start)?;
    // Until the controller takes the request at its next tick, the device
    // reports the previous one's outcome: not this one's.
    if !taken(client, p)? {
        return Err(Failure::device(format!(
            "the device accepted the {} but its uptime stood for {TICK_WAIT_S} s: its report cannot be told from {}; ask `host-sim device --port PORT status` until its uptime moves, then again",
            p.name, p.last
        )));
    }
    let start = Instant::now();
    let timeout = Duration::from_secs_f64(timeout_s);
    // A device that accepted it but never reports it running.
    let never_started = Duration::from_secs(2).min(timeout);
    loop {
        // Every poll is a heartbeat too.
        let r = (p.read)(client)?;
        match (p.stage)(&r) {
            Stage::Done | Stage::Aborted => return Ok(r),
            Stage::NotRun if start.elapsed() >= never_started => {
                return Err(Failure::device(format!(
                    "the device accepted the {} but has not started it after {:.1} s",
                    p.name,
                    never_started.as_secs_f64()
                )));
            }
            _ => {}
        }
        if start.elapsed() >= timeout {
            return Err(Failure::device(format!(
                "the {} did not finish within {timeout_s} s (--timeout); status: {}",
                p.name,
                (p.stage)(&r).name()
            )));
        }
        if interrupt::interrupted() {
            command(client, &Request::Command(Command::Stop))?;
            let ticked = after_a_tick(client)?.1;
            let after = (p.read)(client)?;
            return Err(Failure::device(format!(
                "{}: the {} was stopped (Stop accepted); its status now: {}{}",
                interrupt::interruption(),
                p.name,
                (p.stage)(&after).name(),
                stood(ticked, "stop")
            )));
        }
        client.pump(POLL)?;
    }
}

/// Whether the controller took the procedure just acknowledged, asked every few
/// milliseconds for at most [`TICK_WAIT_S`]: one reported running is this one
/// (a device refuses the request while one runs), and so is any report once the
/// device's uptime moved past that of the first status asked after the Ack. (A
/// device whose clock stands while it runs, as a debugger can hold a board's
/// control task, takes it at the tick before that first status can be asked:
/// its uptime never moves again, but it is running.)
fn taken<R>(client: &mut Client, p: &Procedure<R>) -> Result<bool, Failure> {
    let first = client.status()?;
    let start = Instant::now();
    loop {
        if (p.stage)(&(p.read)(client)?) == Stage::Running {
            return Ok(true);
        }
        client.pump(Duration::from_millis(2))?;
        if client.status()?.uptime_ms != first.uptime_ms {
            return Ok(true);
        }
        if start.elapsed().as_secs_f64() >= TICK_WAIT_S {
            return Ok(false);
        }
    }
}

/// The status once the controller has taken the command just acknowledged,
/// which it does at its next control tick: a status whose uptime differs from
/// that of the first status asked after the Ack (that one may still be from
/// the tick before the command came), asked every few milliseconds, at most
/// [`TICK_WAIT_S`]; with whether the device ticked (if not, the status may be
/// from before the command, and the caller must say so).
pub fn after_a_tick(client: &mut Client) -> Result<(StatusReport, bool), Failure> {
    let first = client.status()?;
    let start = Instant::now();
    loop {
        client.pump(Duration::from_millis(2))?;
        let s = client.status()?;
        if s.uptime_ms != first.uptime_ms {
            return Ok((s, true));
        }
        if start.elapsed().as_secs_f64() >= TICK_WAIT_S {
            return Ok((s, false));
        }
    }
}

/// What a status after a command says when the device did not tick.
pub fn stood(ticked: bool, command: &str) -> String {
    if ticked {
        String::new()
    } else {
        format!(
            " (the device's uptime stood for {TICK_WAIT_S} s: this status may be from before the {command})"
        )
    }
}
