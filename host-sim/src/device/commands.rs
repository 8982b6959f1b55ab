//! `host-sim device --port PORT <COMMAND>`: the arguments checked, the port
//! opened, the requests made through a [`Client`], the answers printed.
//!
//! Exit status: 0 done; 1 the device refused (a Nack), did not answer, answered
//! something else than what was asked (an Ack for another request is no
//! acceptance), sent no telemetry it was asked for, or the port failed while in
//! use; 2 a user mistake (a bad or missing option, a port that cannot be opened,
//! an unreadable table file).

use std::path::Path;
use std::time::{Duration, Instant};

use shared::controller::{Command, Direction, TuningTable};

use shared::controller::self_test::{SelfTestReport, SelfTestStatus};
use shared::protocol::{Request, Response, StatusReport, MIN_TELEMETRY_PERIOD_MS};

use super::args::{
    DeviceArgs, DeviceCommand, DirectionArg, HoldArgs, SelfTestArgs, TableCommand, TravelArgs,
};
use super::procedure::{self, after_a_tick, stood, Procedure, Stage};
use super::report;
use super::{capture, identify, live, telemetry, tune};
use crate::failure::{Console, Failure};
use crate::interrupt;
use crate::link::client::{Client, LinkError};
use crate::link::port::PortSpec;
use crate::link::requests::{ask, command, unexpected, HEARTBEAT_EVERY};
use crate::link::rest::{await_rest, Poll, REST_TIMEOUT_S};
use crate::machine::tuning_file;
use crate::numbers;
use crate::output::file::Staged;

/// The header comment of a table read from the device.
pub const TABLE_HEADER: &str =
    "Tuning table read from the device by `host-sim device table read`.\n\
Rows: speed_rpm ascending; offsets in degrees for rightward and leftward travel.";

impl From<LinkError> for Failure {
    fn from(e: LinkError) -> Self {
        Failure::device(e.to_string())
    }
}

/// Runs `host-sim device`: its lines go out as they come (what was printed before
/// a failure stays printed).
pub fn run(args: &DeviceArgs, console: &mut Console<'_>) -> Result<(), Failure> {
    let Checked {
        port,
        table,
        file,
        tune,
        identify,
        capture,
    } = check(args)?;
    // A port that cannot be opened is a bad --port, as a missing file is.
    let port = port
        .open()
        .map_err(|e| Failure::usage(format!("--port: {e}")))?;
    let mut client = Client::new(port, args.retries);
    let prepared = Prepared {
        table,
        file,
        tune,
        identify,
        capture,
    };
    run_on(&mut client, args, prepared, console)
}

/// What [`check`] found: the port, the table to write, and the output file staged
/// (`--csv` or `--out`), so that an unwritable path is refused before the device
/// is asked anything.
struct Checked {
    port: PortSpec,
    table: Option<TuningTable>,
    file: Option<(Staged, usize)>,
    /// `tune`'s grid, measured file and table output.
    tune: Option<tune::Prepared>,
    /// `identify`'s machine file and output.
    identify: Option<crate::identity::Prepared>,
    /// `capture`'s output and run command.
    capture: Option<capture::Prepared>,
}

/// What a command prepared before the port was opened.
struct Prepared {
    table: Option<TuningTable>,
    file: Option<(Staged, usize)>,
    tune: Option<tune::Prepared>,
    identify: Option<crate::identity::Prepared>,
    capture: Option<capture::Prepared>,
}

/// `path`, given as `option`, staged as the command's one output file.
fn staged(option: &str, path: &Path) -> Result<Option<(Staged, usize)>, Failure> {
    let mut set = Staged::new();
    let i = set.add(option, path)?;
    Ok(Some((set, i)))
}

/// Everything checked before the port is opened, so that a mistake in an
/// option never reaches the device.
fn check(args: &DeviceArgs) -> Result<Checked, Failure> {
    let port = args.port.as_deref().ok_or_else(|| {
        Failure::usage(
            "--port: missing: name the device, a serial port (e.g. --port /dev/ttyUSB0) \
             or tcp:HOST:PORT (e.g. --port tcp:127.0.0.1:5555, as `host-sim device-sim --listen` serves)",
        )
    })?;
    let port = PortSpec::parse(port).map_err(|e| Failure::usage(format!("--port: {e}")))?;
    let positive = |flag: &str, v: f64, unit: &str| {
        if v.is_finite() && v > 0.0 {
            Ok(())
        } else {
            Err(Failure::usage(format!(
                "{flag}: must be a number of {unit} above 0 (got {v})"
            )))
        }
    };
    let mut table = None;
    let mut file = None;
    let mut tune = None;
    let mut identify = None;
    let mut capture = None;
    match &args.command {
        DeviceCommand::Travel(a) => {
            positive("--speed", f64::from(a.speed), "rpm")?;
            if let Some(s) = a.for_s {
                positive("--for", s, "seconds")?;
            }
        }
        DeviceCommand::Hold(a) => {
            positive("--speed", f64::from(a.speed), "rpm")?;
            if !a.offset.is_finite() {
                return Err(Failure::usage(format!(
                    "--offset: must be a finite number of degrees (got {})",
                    a.offset
                )));
            }
            if let Some(s) = a.for_s {
                positive("--for", s, "seconds")?;
            }
        }
        DeviceCommand::Telemetry(a) => {
            if a.period < MIN_TELEMETRY_PERIOD_MS {
                return Err(Failure::usage(format!(
                    "--period: must be {MIN_TELEMETRY_PERIOD_MS} to 65535 ms (got {})",
                    a.period
                )));
            }
            if let Some(d) = a.duration {
                positive("--duration", d, "seconds")?;
            }
            if let Some(path) = &a.csv {
                file = staged("--csv", path)?;
            }
            if let Some(addr) = &a.serve {
                live::listen_address(addr, a.allow_remote)?;
            }
            if a.count == Some(0) {
                return Err(Failure::usage("--count: must be at least 1 frame (got 0)"));
            }
        }
        DeviceCommand::SelfTest(a) => positive("--timeout", a.timeout, "seconds")?,
        DeviceCommand::Identify(a) => {
            positive("--timeout", a.timeout, "seconds")?;
            identify = Some(crate::identity::prepare(
                a.machine.as_deref(),
                a.write.as_deref(),
            )?);
        }
        DeviceCommand::Table(TableCommand::Write { file }) => {
            table = Some(tuning_file::read_table(file)?);
        }
        DeviceCommand::Table(TableCommand::Read { out: Some(path) }) => {
            file = staged("--out", path)?
        }
        DeviceCommand::Tune(a) => tune = Some(tune::prepare(a)?),
        DeviceCommand::Capture(a) => capture = Some(capture::prepare(a)?),
        DeviceCommand::Table(TableCommand::Read { out: None })
        | DeviceCommand::Status
        | DeviceCommand::Stop
        | DeviceCommand::Reset => {}
    }
    Ok(Checked {
        port,
        table,
        file,
        tune,
        identify,
        capture,
    })
}

/// The command's requests through `client`.
fn run_on(
    client: &mut Client,
    args: &DeviceArgs,
    prepared: Prepared,
    out: &mut Console<'_>,
) -> Result<(), Failure> {
    let Prepared {
        table,
        file,
        tune,
        identify,
        capture,
    } = prepared;
    match &args.command {
        DeviceCommand::Status => {
            let s = client.status()?;
            out.print(&report::status_text(&s));
        }
        DeviceCommand::Travel(a) => travel(client, a, out)?,
        DeviceCommand::Hold(a) => hold(client, a, out)?,
        DeviceCommand::Stop => {
            command(client, &Request::Command(Command::Stop))?;
            out.print("stop: accepted\n");
        }
        DeviceCommand::Reset => {
            command(client, &Request::Command(Command::ResetFaults))?;
            let (s, ticked) = after_a_tick(client)?;
            out.print(&format!(
                "reset: accepted; state {}, faults {}{}\n",
                s.state.name(),
                report::faults_text(s.faults),
                stood(ticked, "reset")
            ));
        }
        DeviceCommand::Telemetry(a) => {
            telemetry::run(client, a, args.port.as_deref().unwrap_or(""), file, out)?
        }
        DeviceCommand::Tune(a) => {
            if let Some(prepared) = tune {
                tune::run(client, a, prepared, out)?;
            }
        }
        DeviceCommand::SelfTest(a) => self_test(client, a, out)?,
        DeviceCommand::Identify(a) => {
            if let Some(prepared) = identify {
                identify::run(client, a, prepared, out)?;
            }
        }
        DeviceCommand::Capture(a) => {
            if let Some(prepared) = capture {
                capture::run(client, a, prepared, out)?;
            }
        }
        DeviceCommand::Table(TableCommand::Read { out: path }) => {
            table_read(client, path.as_deref().zip(file), out)?
        }
        DeviceCommand::Table(TableCommand::Write { file }) => {
            let table = table.unwrap_or_default();
            command(client, &Request::WriteTuningTable(table.clone()))?;
            out.print(&format!(
                "table write: {} from {} stored in the device's flash and in use\n",
                numbers::count(table.rows().len(), "row"),
                file.display()
            ));
        }
    }
    Ok(())
}

fn travel(client: &mut Client, a: &TravelArgs, out: &mut Console<'_>) -> Result<(), Failure> {
    let (direction, name) = match a.direction {
        DirectionArg::Right => (Direction::Right, "right"),
        DirectionArg::Left => (Direction::Left, "left"),
    };
    catch_for(a.for_s);
    command(
        client,
        &Request::Command(Command::Travel {
            direction,
            speed_rpm: a.speed,
        }),
    )?;
    out.print(&format!("travel {name} at {} rpm: accepted\n", a.speed));
    keep_alive(client, a.for_s, Some(name), out)
}

/// The warning for a direction (`name`) sent to a one-rotor device, if `s`
/// shows one: rotor 1 driven (its speed reference not 0) and rotor 2's
/// reference 0, which only a one-rotor controller reports while driving (two
/// rotors share the ramp).
fn one_rotor_direction(s: &StatusReport, name: &str) -> Option<String> {
    let r = s.telemetry.speed_ref_rpm;
    (r[0] != 0.0 && r[1] == 0.0).then(|| {
        format!(
            "the device drives one rotor (rotor 2's speed reference is 0 while rotor 1's is {:.0} rpm): a one-rotor machine has no direction, `{name}` is ignored; it travels the way its rotor and feet take it",
            r[0]
        )
    })
}

fn hold(client: &mut Client, a: &HoldArgs, out: &mut Console<'_>) -> Result<(), Failure> {
    catch_for(a.for_s);
    command(
        client,
        &Request::Command(Command::HoldOffset {
            speed_rpm: a.speed,
            offset_deg: a.offset,
        }),
    )?;
    out.print(&format!(
        "hold offset {} deg at {} rpm: accepted\n",
        a.offset, a.speed
    ));
    keep_alive(client, a.for_s, None, out)
}

/// With `--for`, signals are caught before the motion command goes out: one
/// that comes as the device starts the motors then ends the hold as one during
/// it does, with the motors stopped ([`keep_alive`]), never the process alone.
fn catch_for(for_s: Option<f64>) {
    if for_s.is_some() {
        interrupt::catch();
    }
}

/// After a motion command: return at once (`None`), or keep the link alive for
/// `for_s` seconds (a signal ends it early: the time held is said, the motors
/// stopped and awaited as after the whole time, then exit 1 naming it), say so if the status then shows a
/// one-rotor device given a direction (`direction`: `travel`'s), then stop and
/// ask the status until
/// the rotors are at rest ([`await_rest`], at most [`REST_TIMEOUT_S`]), so that
/// a `table write` may follow at once; not at rest by then is a failure.
fn keep_alive(
    client: &mut Client,
    for_s: Option<f64>,
    direction: Option<&str>,
    out: &mut Console<'_>,
) -> Result<(), Failure> {
    let Some(for_s) = for_s else {
        return Ok(());
    };
    let started = Instant::now();
    let end = started + Duration::from_secs_f64(for_s);
    while Instant::now() < end && !interrupt::interrupted() {
        client.request(&Request::Command(Command::Heartbeat))?;
        client.pump(HEARTBEAT_EVERY.min(end.saturating_duration_since(Instant::now())))?;
    }
    // The time held: all of --for, or up to the signal.
    let interrupted = interrupt::interrupted();
    let held = if interrupted {
        started.elapsed().as_secs_f64().min(for_s)
    } else {
        for_s
    };
    let s = client.status()?;
    command(client, &Request::Command(Command::Stop))?;
    out.print(&format!(
        "after {held:.1} s: {}\nstop: accepted\n",
        report::telemetry_line(&s).trim_start()
    ));
    if let Some(w) = direction.and_then(|d| one_rotor_direction(&s, d)) {
        out.note(&format!("warning: {w}\n"));
    }
    let rest = await_rest(client, REST_TIMEOUT_S)?;
    if !rest.reached {
        let why = if interrupted {
            format!(
                "{} after {held:.1} s of --for {for_s} s; ",
                interrupt::interruption()
            )
        } else {
            String::new()
        };
        return Err(Failure::device(format!(
            "{why}stop: accepted, but {}; stop it by hand (E-stop) or again with `host-sim device --port PORT stop`, and ask `host-sim device --port PORT status` until state idle with both rotors below 10 rpm (a table write and the self-test need that)",
            rest.describe()
        )));
    }
    out.print(&format!("stop: {}\n", rest.describe()));
    if interrupted {
        return Err(Failure::device(format!(
            "{} after {held:.1} s of --for {for_s} s; the motors were stopped and are at rest",
            interrupt::interruption()
        )));
    }
    Ok(())
}

fn read_self_test(client: &mut Client) -> Result<SelfTestReport, Failure> {
    match ask(client, &Request::ReadSelfTest)? {
        Response::SelfTest(r) => Ok(r),
        other => Err(unexpected(&Request::ReadSelfTest, &other)),
    }
}

/// The self-test, for [`procedure::run`].
const SELF_TEST: Procedure<SelfTestReport> = Procedure {
    name: "self-test",
    last: "the last test's",
    start: Request::RunSelfTest,
    read: read_self_test,
    stage: self_test_stage,
};

fn self_test_stage(r: &SelfTestReport) -> Stage {
    match r.status {
        SelfTestStatus::NotRun => Stage::NotRun,
        SelfTestStatus::Running => Stage::Running,
        SelfTestStatus::Done => Stage::Done,
        SelfTestStatus::Aborted => Stage::Aborted,
    }
}

fn self_test(client: &mut Client, a: &SelfTestArgs, out: &mut Console<'_>) -> Result<(), Failure> {
    let r = procedure::run(client, &SELF_TEST, a.timeout)?;
    out.print(&report::self_test_text(&r));
    if r.status == SelfTestStatus::Done {
        Ok(())
    } else {
        Err(Failure::device(
            "the self-test was aborted (a fault, the E-stop or a stop)",
        ))
    }
}

fn table_read(
    client: &mut Client,
    file: Option<(&Path, (Staged, usize))>,
    out: &mut Console<'_>,
) -> Result<(), Failure> {
    let table = match ask(client, &Request::ReadTuningTable)? {
        Response::TuningTable(t) => t,
        other => return Err(unexpected(&Request::ReadTuningTable, &other)),
    };
    let rows: Vec<tuning_file::Row> = table
        .rows()
        .iter()
        .map(|r| {
            (
                f64::from(r.speed_rpm),
                f64::from(r.right_offset_deg),
                f64::from(r.left_offset_deg),
            )
        })
        .collect();
    let text = tuning_file::write(&rows, TABLE_HEADER);
    match file {
        None => out.print(&text),
        Some((path, (mut set, i))) => {
            set.write(i, &text)?;
            set.commit()?;
            out.print(&format!(
                "table read: {} written to {}\n",
                numbers::count(rows.len(), "row"),
                path.display()
            ));
        }
    }
    Ok(())
}
