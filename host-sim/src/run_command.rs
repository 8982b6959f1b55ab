//! `host-sim run MACHINE [--open-loop V1,V2|coast] [--t-end T] [--out FILE.csv]
//! [--events FILE.csv] [--plot FILE.svg] [--format table|json] [--set KEY=VALUE]...`
//!
//! Stages:
//! 1. read and check the machine file with the `--set` overrides
//!    ([`crate::machine`]), and the options: every problem at once, exit 2;
//! 2. simulate ([`crate::simulation`]);
//! 3. write the files asked for, each whole or not at all, then the summary on
//!    stdout as a table or JSON.

use crate::cli::{Format, Output, RunArgs, EXIT_OK, EXIT_USAGE};
use crate::input;
use crate::machine::Machine;
use crate::plant::simulator::{Holds, Settings};
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
    let open_loop = match args.open_loop.as_deref().map(parse_open_loop) {
        Some(Ok(o)) => Some(o),
        Some(Err(e)) => {
            problems.push(e);
            None
        }
        None => {
            problems.push(
                "error: run: nothing drives the motors: give --open-loop V1,V2 (winding voltages, V) or --open-loop coast"
                    .to_string(),
            );
            None
        }
    };
    let t_end = args.t_end.unwrap_or(machine.simulation.t_end);
    if !(t_end.is_finite() && t_end > 0.0) {
        problems.push(format!(
            "error: --t-end {t_end}: must be a positive number of seconds"
        ));
    }
    let Some(open_loop) = open_loop.filter(|_| problems.is_empty()) else {
        return usage(problems.join("\n") + "\n");
    };

    // 2. Simulate.
    let supply = machine.drive.supply_voltage;
    let mut warnings = Vec::new();
    if let OpenLoop::Voltages(v) = open_loop {
        if v.iter().any(|u| u.abs() > supply) {
            warnings.push(format!(
                "--open-loop {},{}: clamped to the supply of {supply} V",
                v[0], v[1]
            ));
        }
    }
    let mut driver = OpenLoopDriver::new(open_loop, supply);
    let options = RunOptions {
        t_end,
        settings: Settings::default(),
        holds: Holds::default(),
    };
    let mut result = simulate(&machine, &mut driver, &options);
    result.summary.warnings.extend(warnings);

    // 3. Files, then the summary.
    let title = format!(
        "host-sim run {} (open loop{})",
        args.machine.display(),
        match open_loop {
            OpenLoop::Coast => ", coast".to_string(),
            OpenLoop::Voltages(v) => format!(", {} V, {} V", v[0], v[1]),
        }
    );
    let outputs = [
        (&args.out, OutputFile::Trace),
        (&args.events, OutputFile::Events),
        (&args.plot, OutputFile::Plot),
    ];
    for (path, what) in outputs {
        let Some(path) = path else { continue };
        let contents = match what {
            OutputFile::Trace => trace_csv(&result.rows),
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

/// A user mistake: the problems, exit 2.
fn usage(stderr: String) -> Output {
    Output {
        stderr,
        status: EXIT_USAGE,
        ..Output::default()
    }
}
