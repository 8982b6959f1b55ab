//! `host-sim replay MACHINE.toml CAPTURE.csv`: the twin driven as the board was
//! during a capture, and compared with what the board recorded, tick by tick
//! (docs/calibration.md, "The check: replay").
//!
//! Stages:
//! 1. read the capture ([`crate::capture::file`]: its checksum, its rows) and
//!    the machine files: `MACHINE.toml` for the twin's plant, the file the
//!    board's firmware was built for (`--firmware-machine`, default
//!    `MACHINE.toml`) for its controller, which must be the capture's (the
//!    fingerprint it carries);
//! 2. check the premises: the capture starts with the controller idle and the
//!    rotors at rest (the platform's motion before it is not measured), its
//!    tick is the firmware file's, no tuning table was handed over in it;
//! 3. re-run the board's controller on the recorded inputs ([`shadow`]): it
//!    must write the recorded outputs, which gives the board's own speed and
//!    phase estimates;
//! 4. run the twin from the capture's start ([`twin`]);
//! 5. the residuals ([`residual`]), printed; the plot (`plot`).

mod plot;
pub mod residual;
pub mod shadow;
pub mod twin;

use std::path::{Path, PathBuf};

use clap::Args;
use serde_json::{json, Value};

use shared::capture::MachineFingerprint;
use shared::controller::{Params, State};

use crate::args::{FormatArg, MachineArg, PlotArg};
use crate::capture::{CaptureFile, SETTLED_RPM};
use crate::failure::{Console, Failure};
use crate::help::epilogue;
use crate::machine::Machine;
use crate::numbers;
use crate::output::file::Staged;
use crate::simulation::closed_loop::params;
use crate::simulation::{simulate_observed, Interruptible, RunOptions};

use residual::{residuals, Residual, Sample};

/// Arguments of `host-sim replay`.
#[derive(Debug, Args)]
#[command(after_help = epilogue(
    &[
        "host-sim device --port /dev/ttyUSB0 capture --for 2 --travel right --speed 3000 --out travel.csv",
        "host-sim replay examples/vibro-driver.toml travel.csv --plot replay.svg",
        "host-sim replay identified.toml travel.csv --firmware-machine examples/vibro-driver.toml",
    ],
    &[],
    &["docs/calibration.md"],
))]
pub struct ReplayArgs {
    /// The machine file of the twin: its plant is simulated.
    #[command(flatten)]
    pub machine: MachineArg,
    /// The capture (`host-sim device capture --out`).
    #[arg(value_name = "CAPTURE.csv")]
    pub capture: PathBuf,
    /// The machine file the board's firmware was built for: the controller of
    /// the replay is built from it, as the board's was (default: MACHINE.toml).
    #[arg(long, value_name = "FILE.toml")]
    pub firmware_machine: Option<PathBuf>,
    /// Plot recorded and simulated side by side.
    #[command(flatten)]
    pub plot: PlotArg,
    /// Output format.
    #[command(flatten)]
    pub format: FormatArg,
}

/// What a replay gives.
#[derive(Clone, Debug)]
pub struct Replay {
    /// The residuals.
    pub residuals: Vec<Residual>,
    /// Ticks replayed.
    pub ticks: usize,
    /// The tick, s.
    pub tick_s: f64,
    /// Ticks at which the twin's state differs from the recorded one, and the
    /// first.
    pub state_differs: (usize, Option<usize>),
    /// What the numbers rest on that the user should know.
    pub warnings: Vec<String>,
    /// Recorded and simulated, every tick (for the plot).
    pub recorded: Vec<Sample>,
    /// Simulated.
    pub simulated: Vec<Sample>,
}

/// The fingerprint of a machine file's bytes.
fn fingerprint(path: &Path) -> Result<MachineFingerprint, Failure> {
    let bytes = std::fs::read(path)
        .map_err(|e| Failure::usage(format!("{}: cannot read: {e}", path.display())))?;
    Ok(MachineFingerprint {
        crc32: shared::codec::crc::crc32(&bytes),
        len: bytes.len() as u32,
    })
}

/// Stages 1 and 2 for a capture already read: the controller's parameters
/// (the firmware file's, with the capture's table), checked against the
/// capture. `warnings` gets what the user should know.
pub fn controller_params(
    capture: &CaptureFile,
    capture_path: &Path,
    firmware_path: &Path,
    warnings: &mut Vec<String>,
) -> Result<Params, Failure> {
    let print = |m: MachineFingerprint| format!("CRC-32 {:08x}, {} bytes", m.crc32, m.len);
    let ours = fingerprint(firmware_path)?;
    let theirs = capture.header.machine;
    if theirs == MachineFingerprint::default() {
        warnings.push(format!(
            "{}: the capture names no machine file (its device was built for none): its controller is taken to be {}'s",
            capture_path.display(),
            firmware_path.display()
        ));
    } else if theirs != ours {
        return Err(Failure::usage(format!(
            "{}: recorded by firmware built for another machine file ({}); {} is {}: give the file the board's firmware was built for with --firmware-machine",
            capture_path.display(),
            print(theirs),
            firmware_path.display(),
            print(ours)
        )));
    }
    let firmware = Machine::load(firmware_path, &[])?;
    let mut p = params(&firmware)?;
    p.tuning = capture
        .tuning_table()
        .map_err(|e| Failure::usage(format!("{}: tuning_table: {e}", capture_path.display())))?;
    let tick = f64::from(p.tick_s());
    if (tick - capture.header.tick_s).abs() > 1e-9 {
        return Err(Failure::usage(format!(
            "{}: a tick of {} s; {}'s controller ticks every {} s",
            capture_path.display(),
            capture.header.tick_s,
            firmware_path.display(),
            tick
        )));
    }
    let start = &capture.header.start;
    let moving = start.speed_rpm.iter().any(|s| s.abs() > SETTLED_RPM);
    if start.state != State::Idle || moving {
        return Err(Failure::usage(format!(
            "{}: it starts in state {} with the rotors' speed estimates at {} and {} rpm: a replay starts the twin idle and at rest (the platform's motion before a capture is not measured, nor the controller's filters), so the capture must start idle with both estimates settled below {SETTLED_RPM} rpm; capture from rest, e.g. `host-sim device --port PORT capture --for 2 --travel right --speed 3000 --out FILE.csv` (which waits for rest)",
            capture_path.display(),
            start.state.name(),
            numbers::sig(f64::from(start.speed_rpm[0])),
            numbers::sig(f64::from(start.speed_rpm[1])),
        )));
    }
    if let Some(k) = capture.records.iter().position(|r| r.tuning_changed) {
        return Err(Failure::usage(format!(
            "{}: a tuning table was handed to the controller at tick {k}, and the capture keeps only the one in use at its start: capture again after the table write",
            capture_path.display()
        )));
    }
    Ok(p)
}

/// The twin `machine` (read from `machine_path`) has the rotors of the
/// controller `params` (built from `firmware_path`).
pub fn check_rotor_count(
    machine: &Machine,
    params: &Params,
    machine_path: &Path,
    firmware_path: &Path,
) -> Result<(), Failure> {
    if params.rotor_count.count() != machine.rotors.len() {
        return Err(Failure::usage(format!(
            "{}: {} rotors; the firmware's file {} has {}",
            machine_path.display(),
            machine.rotors.len(),
            firmware_path.display(),
            params.rotor_count.count()
        )));
    }
    Ok(())
}

/// Stages 3 to 5 without the output: the replay of `capture` on the twin
/// `machine` with the controller `params`, each rotor started in the middle
/// of its count ([`twin::MIDDLE_OF_THE_COUNT`]).
pub fn replay(
    capture: &CaptureFile,
    machine: &Machine,
    params: &Params,
    warnings: Vec<String>,
) -> Result<Replay, Failure> {
    replay_within(
        capture,
        machine,
        params,
        warnings,
        twin::MIDDLE_OF_THE_COUNT,
    )
}

/// [`replay`] with each rotor started `within` of its count's angle span in,
/// in [0, 1): a replay as valid as the one from the middle, the count saying
/// no more (`calibrate --capture` measures what that leaves open).
pub fn replay_within(
    capture: &CaptureFile,
    machine: &Machine,
    params: &Params,
    mut warnings: Vec<String>,
    within: f64,
) -> Result<Replay, Failure> {
    if capture.header.ended_early {
        warnings.push(format!(
            "the capture ended early, at {} s of its window: it met more run commands than the board keeps ({}), so the residuals are over that much only",
            numbers::sig(capture.records.len() as f64 * capture.header.tick_s),
            shared::capture::MAX_COMMANDS
        ));
    }
    // 3. The board's controller again.
    let shadow = shadow::rerun(params, capture).map_err(|m| {
        Failure::usage(format!(
            "the capture's outputs are not those of the controller built from the firmware's machine file and the capture's table: at tick {} the board wrote {}, that controller {}: the firmware was built from another file or table, the capture was edited, or the board's controller carried something from before the capture that a fresh one lacks (a capture in the first seconds after the board started, when the rotors still swing: capture again after a while at rest)",
            m.tick, m.recorded, m.recomputed
        ))
    })?;
    let recorded: Vec<Sample> = shadow
        .iter()
        .enumerate()
        .map(|(k, out)| Sample::of(&shadow::inputs_at(capture, k), out))
        .collect();

    // 4. The twin.
    let n = machine.sensors.encoder_counts;
    let angles = twin::start_angles(capture, n);
    for (r, a) in angles.iter().enumerate().take(machine.rotors.len()) {
        if a.is_none() {
            warnings.push(format!(
                "rotor {}: no index pulse before or in the capture, so its angle at the start is unknown: the twin starts it at the machine file's angle",
                r + 1
            ));
        }
    }
    let mut twin_machine = twin::placed(machine, angles, within);
    // The twin predicts; its sensors add no noise of their own.
    twin_machine.sensors.current_noise = 0.0;
    twin_machine.sensors.encoder_jitter = 0.0;
    let ticks = capture.records.len();
    let tick_s = capture.header.tick_s;
    let mut driver = twin::ReplayDriver::new(capture, &twin_machine, params, angles);
    let mut options = RunOptions::new(ticks as f64 * tick_s);
    options.keep_rows = false;
    options.keep_events = false;
    let run = simulate_observed(
        &twin_machine,
        &mut driver,
        &options,
        &mut Interruptible::new(),
    );
    if let Some(stop) = &run.stopped {
        return Err(Failure::run(format!(
            "the twin stopped before the capture's end: {}",
            crate::simulation::stop_message(stop, Some(ticks as f64 * tick_s))
        )));
    }
    let simulated: Vec<Sample> = driver
        .ticks
        .iter()
        .map(|(inputs, out)| Sample::of(inputs, out))
        .collect();
    for w in &run.summary.warnings {
        warnings.push(format!("the twin: {w}"));
    }

    // 5. The residuals.
    let rotors = machine.rotors.len();
    let mut differs = 0;
    let mut first = None;
    for (k, (rec, (_, out))) in capture.records.iter().zip(&driver.ticks).enumerate() {
        if rec.state != out.state {
            differs += 1;
            first.get_or_insert(k);
        }
    }
    Ok(Replay {
        residuals: residuals(&recorded, &simulated, rotors),
        ticks,
        tick_s,
        state_differs: (differs, first),
        warnings,
        recorded,
        simulated,
    })
}

/// Runs `host-sim replay`.
pub fn run(args: &ReplayArgs, console: &mut Console<'_>) -> Result<(), Failure> {
    // 1. The inputs, the output staged.
    let mut staged = Staged::new();
    let plot_file = match &args.plot.file {
        Some(p) => Some(staged.add("--plot", p)?),
        None => None,
    };
    let capture = CaptureFile::read(&args.capture)?;
    let machine_path = &args.machine.path;
    let machine = Machine::load(machine_path, &[])?;
    let firmware_path = args.firmware_machine.as_deref().unwrap_or(machine_path);
    let mut warnings = Vec::new();
    // 2. The premises.
    let params = controller_params(&capture, &args.capture, firmware_path, &mut warnings)?;
    check_rotor_count(&machine, &params, machine_path, firmware_path)?;
    let result = replay(&capture, &machine, &params, warnings)?;
    let title = format!(
        "replay of {} on {}",
        args.capture.display(),
        machine_path.display()
    );
    if let Some(i) = plot_file {
        staged.write(i, &plot::svg(&result, &title))?;
    }
    staged.commit()?;
    let text = match args.format.format {
        crate::args::Format::Table => table(&result, args, firmware_path),
        crate::args::Format::Json => {
            let mut s = serde_json::to_string_pretty(&to_json(&result, args, firmware_path))
                .unwrap_or_default();
            s.push('\n');
            s
        }
    };
    console.print(&text);
    Ok(())
}

/// A residual's value for people, with its unit's precision.
fn value(r: &Residual, v: f64) -> String {
    let digits = match r.quantity {
        "speed_rpm" | "phase_offset_deg" => 2,
        "current_a" => 4,
        _ => 4,
    };
    numbers::fixed(v, digits)
}

fn table(r: &Replay, args: &ReplayArgs, firmware: &Path) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "replay: {} ({}, {} s) on {}'s plant with {}'s controller",
        args.capture.display(),
        numbers::count(r.ticks, "tick"),
        numbers::sig(r.ticks as f64 * r.tick_s),
        args.machine.path.display(),
        firmware.display()
    );
    let _ = writeln!(
        s,
        "the board's controller re-run on the capture's inputs writes its recorded outputs at every tick"
    );
    let _ = writeln!(
        s,
        "\nresidual (simulated - recorded)  rotor  ticks        rms        max   at (s)"
    );
    for x in &r.residuals {
        let _ = writeln!(
            s,
            "{:<32} {:>5} {:>6} {:>10} {:>10} {:>8}",
            x.quantity,
            x.rotor.map_or("-".into(), |k| k.to_string()),
            x.ticks,
            if x.ticks > 0 {
                value(x, x.rms)
            } else {
                "-".into()
            },
            if x.ticks > 0 {
                value(x, x.max)
            } else {
                "-".into()
            },
            if x.ticks > 0 {
                numbers::fixed(x.at_tick as f64 * r.tick_s, 3)
            } else {
                "-".into()
            }
        );
    }
    let (n, first) = r.state_differs;
    let _ = writeln!(
        s,
        "\nstates: {}",
        match first {
            None => "the twin's state is the board's at every tick".to_string(),
            Some(k) => format!(
                "the twin's state differs from the board's at {} (first at {} s)",
                numbers::count(n, "tick"),
                numbers::fixed(k as f64 * r.tick_s, 3)
            ),
        }
    );
    let _ = writeln!(
        s,
        "warnings: {}",
        if r.warnings.is_empty() {
            "none".into()
        } else {
            r.warnings.join("; ")
        }
    );
    s
}

fn to_json(r: &Replay, args: &ReplayArgs, firmware: &Path) -> Value {
    let residuals: Vec<Value> = r
        .residuals
        .iter()
        .map(|x| {
            json!({
                "quantity": x.quantity,
                "rotor": x.rotor,
                "ticks": x.ticks,
                "rms": (x.ticks > 0).then_some(x.rms),
                "max": (x.ticks > 0).then_some(x.max),
                "at_s": (x.ticks > 0).then_some(x.at_tick as f64 * r.tick_s),
            })
        })
        .collect();
    json!({
        "capture": args.capture.display().to_string(),
        "machine": args.machine.path.display().to_string(),
        "firmware_machine": firmware.display().to_string(),
        "ticks": r.ticks,
        "tick_s": r.tick_s,
        "residuals": residuals,
        "state_differs_ticks": r.state_differs.0,
        "state_differs_first_s": r.state_differs.1.map(|k| k as f64 * r.tick_s),
        "warnings": r.warnings,
    })
}
