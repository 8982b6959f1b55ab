//! `host-sim device capture`: the board records every control tick of a window
//! from a trigger (`shared::capture`), the host reads the records out and
//! writes them, whole, as a capture file ([`crate::capture::file`]).
//!
//! Stages:
//! 1. ask the capture's status: its buffer and tick; a window longer than the
//!    buffer is refused (exit 2) before anything is armed;
//! 2. with `--travel` or `--hold`, wait until the controller has been idle
//!    with both speed estimates within 0.01 rpm for 0.5 s (a rotor that swings
//!    as a pendulum after a stop, or creeps, passes 10 rpm long before; the
//!    start a replay needs), at most 30 s; arm the capture, then send that command (the trigger `command` by
//!    default fires on it);
//! 3. ask the capture's status every 50 ms (each request keeps the link alive)
//!    until it is done, or `--timeout`, or Ctrl-C; a run's capture whose start
//!    shows a rotor moved after all (its speed estimate off 0) is stopped and
//!    taken again, at most 3 tries;
//! 4. a run command sent in 2 is followed by a stop, and the rotors awaited at
//!    rest, before anything is read (so a lost link mid-read leaves the board
//!    stopped);
//! 5. read the records, 11 a frame, and the capture's status again (the same
//!    capture, nothing re-armed meanwhile), and the tuning table in use;
//! 6. write the file whole.

use std::time::Instant;

use shared::capture::{CaptureInfo, CaptureStatus, Record, Trigger, RECORDS_PER_FRAME};
use shared::controller::{Command, Direction, TuningTable};
use shared::protocol::{Request, Response};

use super::args::{CaptureArgs, DirectionArg, TriggerArg};
use crate::capture::{settled, CaptureFile, SETTLED_RPM};
use crate::failure::{Console, Failure};
use crate::interrupt;
use crate::link::client::Client;
use crate::link::requests::{ask, command, unexpected, HEARTBEAT_EVERY};
use crate::link::rest::{await_rest, await_steady, REST_HOLD_S, REST_TIMEOUT_S};
use crate::numbers;
use crate::output::file::Staged;

/// What `check` found: the output staged, the run command to send.
pub struct Prepared {
    out: (Staged, usize),
    run: Option<Command>,
    trigger: Trigger,
}

/// The options checked before the port is opened.
pub fn prepare(a: &CaptureArgs) -> Result<Prepared, Failure> {
    if !(a.for_s.is_finite() && a.for_s > 0.0) {
        return Err(Failure::usage(format!(
            "--for: must be a number of seconds above 0 (got {})",
            a.for_s
        )));
    }
    if !(a.timeout.is_finite() && a.timeout > 0.0) {
        return Err(Failure::usage(format!(
            "--timeout: must be a number of seconds above 0 (got {})",
            a.timeout
        )));
    }
    let run =
        match (a.travel, a.hold, a.speed) {
            (Some(_), Some(_), _) => {
                return Err(Failure::usage(
                    "--travel and --hold: give one run command, not both",
                ))
            }
            (Some(_), None, None) | (None, Some(_), None) => return Err(Failure::usage(
                "--speed: missing: --travel and --hold need the rotor speed (e.g. --speed 3000)",
            )),
            (None, None, Some(_)) => {
                return Err(Failure::usage(
                    "--speed: goes with --travel or --hold (the capture then starts that run)",
                ))
            }
            (None, None, None) => None,
            (_, _, Some(speed)) if !(speed.is_finite() && speed > 0.0) => {
                return Err(Failure::usage(format!(
                    "--speed: must be a number of rpm above 0 (got {speed})"
                )))
            }
            (Some(d), None, Some(speed_rpm)) => Some(Command::Travel {
                direction: match d {
                    DirectionArg::Right => Direction::Right,
                    DirectionArg::Left => Direction::Left,
                },
                speed_rpm,
            }),
            (None, Some(offset_deg), Some(speed_rpm)) => {
                if !offset_deg.is_finite() {
                    return Err(Failure::usage(format!(
                        "--hold: must be a finite offset in degrees (got {offset_deg})"
                    )));
                }
                Some(Command::HoldOffset {
                    speed_rpm,
                    offset_deg,
                })
            }
        };
    let trigger = match (a.trigger, run) {
        (Some(t), _) => trigger_of(t),
        (None, Some(_)) => Trigger::Command,
        (None, None) => Trigger::Now,
    };
    let mut set = Staged::new();
    let i = set.add("--out", &a.out)?;
    Ok(Prepared {
        out: (set, i),
        run,
        trigger,
    })
}

fn trigger_of(t: TriggerArg) -> Trigger {
    match t {
        TriggerArg::Now => Trigger::Now,
        TriggerArg::Command => Trigger::Command,
        TriggerArg::State => Trigger::State,
        TriggerArg::Fault => Trigger::Fault,
    }
}

fn info(client: &mut Client) -> Result<CaptureInfo, Failure> {
    match ask(client, &Request::GetCapture)? {
        Response::Capture(i) => Ok(i),
        other => Err(unexpected(&Request::GetCapture, &other)),
    }
}

/// Runs the capture (the module's stages).
pub fn run(
    client: &mut Client,
    a: &CaptureArgs,
    prepared: Prepared,
    out: &mut Console<'_>,
) -> Result<(), Failure> {
    // 1. The buffer and the tick.
    let before = info(client)?;
    if before.capacity == 0 || before.tick_us == 0 {
        return Err(Failure::device(
            "the device has no capture buffer (its firmware predates the capture, or records none)",
        ));
    }
    let tick_s = f64::from(before.tick_us) * 1e-6;
    let window = (a.for_s / tick_s).round();
    if window < 1.0 || window > f64::from(before.capacity) {
        return Err(Failure::usage(format!(
            "--for: {} s is {} ticks of {} ms; the device records 1 to {} ticks ({} s)",
            a.for_s,
            window,
            numbers::sig(tick_s * 1e3),
            before.capacity,
            numbers::sig(f64::from(before.capacity) * tick_s)
        )));
    }
    let window = window as u16;

    // 2. and 3., again while a rotor moved just before the run's first tick.
    let mut attempt = 1;
    let last = loop {
        let last = record_once(client, a, &prepared, window, tick_s, out)?;
        let moved = last.start.speed_rpm.iter().any(|v| v.abs() > SETTLED_RPM);
        if prepared.run.is_none() || !moved {
            break last;
        }
        stop_run(client, true, out)?;
        if attempt == ATTEMPTS {
            return Err(Failure::device(format!(
                "capture: a rotor moved just before the run's first tick in each of {ATTEMPTS} tries (speed estimates {} and {} rpm at the start, more than {SETTLED_RPM}): a replay could not start where the board was; nothing written; the motors were stopped",
                numbers::sig(f64::from(last.start.speed_rpm[0])),
                numbers::sig(f64::from(last.start.speed_rpm[1]))
            )));
        }
        out.print(&format!(
            "capture: a rotor moved just before the run's first tick (speed estimates {} and {} rpm): captured again\n",
            numbers::sig(f64::from(last.start.speed_rpm[0])),
            numbers::sig(f64::from(last.start.speed_rpm[1]))
        ));
        attempt += 1;
    };

    // 4. The motors stopped before the read.
    stop_run(client, prepared.run.is_some(), out)?;

    // 5. The records, the same capture, the table.
    let records = read_records(client, &last)?;
    let after = info(client)?;
    if after.id != last.id || after.recorded != last.recorded {
        return Err(Failure::device(
            "capture: the device's capture changed while it was read (armed again by another host?); nothing written",
        ));
    }
    let table = match ask(client, &Request::ReadTuningTable)? {
        Response::TuningTable(t) => t,
        other => return Err(unexpected(&Request::ReadTuningTable, &other)),
    };

    // 6. The file, whole.
    write(a, prepared.out, &last, records, &table, out)
}

/// Tries of a run's capture: a rotor that moves a count between the last
/// settled status and the run's first tick (an eccentric creeping after a
/// long stand, the host slow to send) leaves the board's speed estimate off 0
/// at the start, which a replay cannot start from; the run is stopped and
/// captured again.
const ATTEMPTS: u32 = 3;

/// Stages 2 and 3: the rest awaited (with a run), the capture armed, the run
/// sent, and the capture's status polled until done; its last status.
fn record_once(
    client: &mut Client,
    a: &CaptureArgs,
    prepared: &Prepared,
    window: u16,
    tick_s: f64,
    out: &mut Console<'_>,
) -> Result<CaptureInfo, Failure> {
    // 2. Arm, then the run command: from rest held for a while, so that the
    // controller's speed estimates have settled at 0 and a replay starts where
    // the board was.
    if prepared.run.is_some() {
        interrupt::catch();
        let rest = await_steady(client, REST_HOLD_S, SETTLE_TIMEOUT_S, settled)?;
        if !rest.reached {
            return Err(Failure::device(format!(
                "capture: a run is captured from rest: state idle and both speed estimates within {SETTLED_RPM} rpm for {REST_HOLD_S} s, not so within {SETTLE_TIMEOUT_S} s: {}; nothing armed",
                crate::link::rest::motion(&rest.status)
            )));
        }
    }
    command(
        client,
        &Request::ArmCapture {
            trigger: prepared.trigger,
            window,
        },
    )?;
    out.print(&format!(
        "capture: armed for {window} ticks ({} s) from trigger {}\n",
        numbers::sig(f64::from(window) * tick_s),
        prepared.trigger.name()
    ));
    if let Some(run) = prepared.run {
        command(client, &Request::Command(run))?;
        out.print(&format!("{}: accepted\n", describe(&run)));
    }

    // 3. Until done.
    let started = Instant::now();
    let mut last = info(client)?;
    while last.status != CaptureStatus::Done {
        let waited = started.elapsed().as_secs_f64();
        if interrupt::interrupted() || waited >= a.timeout {
            let why = if interrupt::interrupted() {
                interrupt::interruption().to_string()
            } else {
                format!(
                    "not done {} s after it was armed (--timeout): {}",
                    numbers::sig(a.timeout),
                    waiting_text(&last)
                )
            };
            stop_run(client, prepared.run.is_some(), out)?;
            let _ = command(
                client,
                &Request::ArmCapture {
                    trigger: Trigger::Now,
                    window: 0,
                },
            );
            return Err(Failure::device(format!(
                "capture: {why}; nothing written{}",
                if prepared.run.is_some() {
                    "; the motors were stopped"
                } else {
                    ""
                }
            )));
        }
        client.pump(HEARTBEAT_EVERY)?;
        last = info(client)?;
    }
    Ok(last)
}

/// A run command for people.
fn describe(c: &Command) -> String {
    match c {
        Command::Travel {
            direction,
            speed_rpm,
        } => format!(
            "travel {} at {speed_rpm} rpm",
            match direction {
                Direction::Right => "right",
                Direction::Left => "left",
            }
        ),
        Command::HoldOffset {
            speed_rpm,
            offset_deg,
        } => format!("hold offset {offset_deg} deg at {speed_rpm} rpm"),
        other => format!("{other:?}"),
    }
}

/// Where a capture not done is.
fn waiting_text(i: &CaptureInfo) -> String {
    match i.status {
        CaptureStatus::Armed => format!("its trigger ({}) never fired", i.trigger.name()),
        CaptureStatus::Recording => format!("{} of {} ticks recorded", i.recorded, i.window),
        CaptureStatus::Empty => "it was disarmed".into(),
        CaptureStatus::Done => "done".into(),
    }
}

/// After a run this command started: stop, and await rest.
fn stop_run(client: &mut Client, ran: bool, out: &mut Console<'_>) -> Result<(), Failure> {
    if !ran {
        return Ok(());
    }
    command(client, &Request::Command(Command::Stop))?;
    let rest = await_rest(client, REST_TIMEOUT_S)?;
    if !rest.reached {
        return Err(Failure::device(format!(
            "capture: stop accepted, but {}; stop it by hand (E-stop) or again with `host-sim device --port PORT stop`; nothing written",
            rest.describe()
        )));
    }
    out.print(&format!("stop: {}\n", rest.describe()));
    Ok(())
}

/// Every record of the capture `info`, in order.
fn read_records(client: &mut Client, info: &CaptureInfo) -> Result<Vec<Record>, Failure> {
    let mut records = Vec::with_capacity(usize::from(info.recorded));
    while records.len() < usize::from(info.recorded) {
        let first = records.len() as u16;
        let request = Request::ReadCapture { first };
        let (count, slots) = match ask(client, &request)? {
            Response::CaptureRecords {
                first: f,
                count,
                records: slots,
            } if f == first => (count, slots),
            other => return Err(unexpected(&request, &other)),
        };
        let count = usize::from(count).min(RECORDS_PER_FRAME);
        if count == 0 {
            return Err(Failure::device(format!(
                "capture: the device sent no record from tick {first} of {}; nothing written",
                info.recorded
            )));
        }
        for slot in slots.iter().take(count) {
            // The frame's parse checked every record.
            if let Some(r) = Record::from_bytes(slot) {
                records.push(r);
            }
        }
    }
    records.truncate(usize::from(info.recorded));
    Ok(records)
}

fn write(
    a: &CaptureArgs,
    (mut set, i): (Staged, usize),
    info: &CaptureInfo,
    records: Vec<Record>,
    table: &TuningTable,
    out: &mut Console<'_>,
) -> Result<(), Failure> {
    let file = CaptureFile::from_device(info, records, table)
        .map_err(|e| Failure::device(format!("capture: {e}; nothing written")))?;
    set.write(i, &file.to_text())?;
    set.commit()?;
    out.print(&format!(
        "capture: {}\ncapture: written to {}\n",
        file.contents(),
        a.out.display()
    ));
    Ok(())
}

/// The longest wait for the machine settled before a run is captured, s: a
/// rotor swinging on its eccentric after a stop comes to rest within a few
/// seconds on the reference machine.
const SETTLE_TIMEOUT_S: f64 = 30.0;

/// How long the capture's wait may take at most by default, s.
pub const DEFAULT_TIMEOUT_S: f64 = 30.0;
