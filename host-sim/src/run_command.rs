//! `host-sim run MACHINE [--command right|left|stop] [--speed RPM] [--offset DEG]
//! [--open-loop V1,V2|coast] [--t-end T] [--out FILE.csv]
//! [--events FILE.csv] [--plot FILE.svg] [--format table|json] [--set KEY=VALUE]...`
//!
//! Stages:
//! 1. read and check the machine file with the `--set` overrides
//!    ([`crate::machine`]), and the options: every problem at once, exit 2;
//! 2. simulate ([`crate::simulation`]);
//! 3. write the files asked for, each whole or not at all, then the summary on
//!    stdout as a table or JSON.

use shared::controller::{Command, Direction};

use crate::cli::{CommandArg, Format, Output, RunArgs, EXIT_OK, EXIT_USAGE};
use crate::closed_loop::ControllerDriver;
use crate::input;
use crate::machine::Machine;
use crate::run_output::{events_csv, summary_json, summary_table, trace_csv, write_whole};
use crate::simulation::{simulate, OpenLoop, OpenLoopDriver, RunOptions};

/// Parses `--open-loop`: `coast`, or two voltages `V1,V2`.
pub fn parse_open_loop(text: &str) -> Result<OpenLoop, String> {
    if text.trim() == "coast" {
        return Ok(OpenLoop::Coast);
    }
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    let volts: Vec<Option<f64>> = parts
        .iter()
        .map(|p| p.parse::<f64>().ok().filter(|v| v.is_finite()))
        .collect();
    match volts.as_slice() {
        [Some(a), Some(b)] => Ok(OpenLoop::Voltages([*a, *b])),
        _ => Err(format!(
            "error: --open-loop {text}: expected two winding voltages in V, `V1,V2` (e.g. `12,12`; `0,0` shorts the windings), or `coast` (windings open)"
        )),
    }
}

/// Runs the command (stages of the module doc).
pub fn run(args: &RunArgs) -> Output {
    // 1. The machine and the options.
    let machine = match Machine::load(&args.machine, &args.set) {
        Ok(m) => m,
        Err(problems) => return usage(input::render(&problems)),
    };
    let mut problems = Vec::new();
    let drive = match (args.command, args.open_loop.as_deref()) {
        (Some(_), Some(_)) => {
            problems.push(
                "error: run: give either --command (the controller drives) or --open-loop, not both"
                    .to_string(),
            );
            None
        }
        (Some(c), None) => match controller_schedule(c, args, &machine) {
            Ok(schedule) => Some(Drive::Controller(schedule)),
            Err(e) => {
                problems.extend(e);
                None
            }
        },
        (None, Some(text)) => match parse_open_loop(text) {
            Ok(o) => Some(Drive::OpenLoop(o)),
            Err(e) => {
                problems.push(e);
                None
            }
        },
        (None, None) => {
            problems.push(
                "error: run: nothing drives the motors: give --command right|left|stop (the controller), --open-loop V1,V2 (winding voltages, V) or --open-loop coast"
                    .to_string(),
            );
            None
        }
    };
    if args.command.is_none() && (args.speed.is_some() || args.offset.is_some()) {
        problems.push("error: --speed and --offset go with --command".to_string());
    }
    let t_end = args.t_end.unwrap_or(machine.simulation.t_end);
    if !(t_end.is_finite() && t_end > 0.0) {
        problems.push(format!(
            "error: --t-end {t_end}: must be a positive number of seconds"
        ));
    }
    let Some(drive) = drive.filter(|_| problems.is_empty()) else {
        return usage(problems.join("\n") + "\n");
    };

    // 2. Simulate.
    let supply = machine.drive.supply_voltage;
    let mut warnings = Vec::new();
    let options = RunOptions::new(t_end);
    let (mut result, how) = match &drive {
        Drive::OpenLoop(open_loop) => {
            if let OpenLoop::Voltages(v) = open_loop {
                if v.iter().any(|u| u.abs() > supply) {
                    warnings.push(format!(
                        "--open-loop {},{}: clamped to the supply of {supply} V",
                        v[0], v[1]
                    ));
                }
            }
            let mut driver = OpenLoopDriver::new(*open_loop, supply);
            let how = match open_loop {
                OpenLoop::Coast => "open loop, coast".to_string(),
                OpenLoop::Voltages(v) => format!("open loop, {} V, {} V", v[0], v[1]),
            };
            (simulate(&machine, &mut driver, &options), how)
        }
        Drive::Controller(schedule) => {
            let mut driver = match ControllerDriver::new(&machine, schedule.clone()) {
                Ok(d) => d,
                Err(problems) => return usage(input::render(&problems)),
            };
            let how = describe_command(args, &machine);
            (simulate(&machine, &mut driver, &options), how)
        }
    };
    result.summary.warnings.extend(warnings);

    // 3. Files, then the summary.
    let title = format!("host-sim run {} ({how})", args.machine.display());
    let outputs = [
        (&args.out, OutputFile::Trace),
        (&args.events, OutputFile::Events),
        (&args.plot, OutputFile::Plot),
    ];
    for (path, what) in outputs {
        let Some(path) = path else { continue };
        let contents = match what {
            OutputFile::Trace => {
                let names: Vec<String> = machine.contacts.iter().map(|c| c.name.clone()).collect();
                trace_csv(&result.rows, &names)
            }
            OutputFile::Events => events_csv(&result.events),
            OutputFile::Plot => {
                crate::plot::plot_svg(&result.rows, &result.events, &machine, &title)
            }
        };
        if let Err(e) = write_whole(path, &contents) {
            // An output path that cannot be written is the user's to fix.
            return usage(format!("error: {e}\n"));
        }
    }
    Output {
        stdout: match args.format {
            Format::Json => summary_json(&result.summary),
            Format::Table => summary_table(&result.summary),
        },
        status: EXIT_OK,
        ..Output::default()
    }
}

/// The files `run` can write.
enum OutputFile {
    Trace,
    Events,
    Plot,
}

/// What drives the motors in a run.
enum Drive {
    /// Open loop.
    OpenLoop(OpenLoop),
    /// The controller, with its commands.
    Controller(Vec<(f64, Command)>),
}

/// The controller's command at t = 0 for `--command`, `--speed`, `--offset`.
fn controller_schedule(
    c: CommandArg,
    args: &RunArgs,
    machine: &Machine,
) -> Result<Vec<(f64, Command)>, Vec<String>> {
    let mut problems = Vec::new();
    let speed = args.speed.unwrap_or(machine.controller.speed_rpm);
    // The controller refuses speeds outside its range (and would stay idle):
    // say so here instead. Stop needs no speed.
    let limits = crate::closed_loop::params(machine)
        .map(|p| (f64::from(p.min_speed_rpm), f64::from(p.max_speed_rpm)))
        .unwrap_or((0.0, f64::INFINITY));
    let in_range = speed.is_finite() && speed >= limits.0 && speed <= limits.1;
    if c != CommandArg::Stop && !in_range {
        let origin = if args.speed.is_some() {
            "--speed"
        } else {
            "controller.speed_rpm"
        };
        problems.push(format!(
            "error: {origin} {speed}: the controller runs the rotors from {:.0} to {:.0} rpm (80 % of the motors' no-load speed)",
            limits.0, limits.1
        ));
    }
    if let Some(o) = args.offset {
        if !o.is_finite() {
            problems.push(format!(
                "error: --offset {o}: must be a finite angle in degrees"
            ));
        }
    }
    if !problems.is_empty() {
        return Err(problems);
    }
    let command = match (c, args.offset) {
        (CommandArg::Stop, _) => Command::Stop,
        (_, Some(offset)) => Command::HoldOffset {
            speed_rpm: speed as f32,
            offset_deg: offset.rem_euclid(360.0) as f32,
        },
        (CommandArg::Right, None) => Command::Travel {
            direction: Direction::Right,
            speed_rpm: speed as f32,
        },
        (CommandArg::Left, None) => Command::Travel {
            direction: Direction::Left,
            speed_rpm: speed as f32,
        },
    };
    Ok(vec![(0.0, command)])
}

/// The plot title's description of a controller run.
fn describe_command(args: &RunArgs, machine: &Machine) -> String {
    let speed = args.speed.unwrap_or(machine.controller.speed_rpm);
    match (args.command, args.offset) {
        (Some(CommandArg::Stop), _) => "controller, stop".to_string(),
        (_, Some(o)) => format!("controller, offset {o} deg at {speed} rpm"),
        (Some(CommandArg::Left), None) => format!("controller, travel left at {speed} rpm"),
        _ => format!("controller, travel right at {speed} rpm"),
    }
}

/// A user mistake: the problems, exit 2.
fn usage(stderr: String) -> Output {
    Output {
        stderr,
        status: EXIT_USAGE,
        ..Output::default()
    }
}
