//! What a run with the firmware in the loop asks of it beyond its command
//! (docs/pil.md, "Identification and capture in the loop"):
//!
//! - `--identify [--write OUT.toml]`: the firmware's motor identification on
//!   the simulated plant, no command; the run ends with its final report,
//!   printed as `host-sim device identify` prints it ([`crate::device::identify`]);
//! - `--capture FILE.csv --capture-for S`: the firmware's capture armed before
//!   the run's command (trigger `command`), read out after its window while
//!   the run goes on, and written as the capture file `host-sim device
//!   capture` writes ([`crate::capture::file`]), which `host-sim replay`
//!   replays.
//!
//! The options are checked together here, every problem at once (exit 2);
//! the requests are [`identify`]'s and [`capture`]'s, on
//! [`mod@script`]'s shared parts.

pub mod capture;
pub mod identify;
pub mod script;

use std::path::{Path, PathBuf};

use shared::capture::BOARD_CAPACITY;
use shared::controller::identify::WORST_ROTOR_S;
use shared::controller::Command;

use super::RunArgs;
use crate::args::Format;
use crate::capture::CaptureFile;

use crate::failure::{Console, Failure};
use crate::identity::{self, Prepared};
use crate::link::rest::REST_TIMEOUT_S;
use crate::machine::Machine;
use crate::numbers::sig;
use crate::simulation::pil::script::Script;
use crate::simulation::pil::{FirmwareDriver, BUILD};
use capture::{capture_file, needed_s, CaptureScript};
use identify::{final_report, last_status, IdentifyScript};

/// What the run asks of the firmware besides its command.
pub enum Asks {
    /// `--identify`: the machine file read, `--write` staged.
    Identify(Box<Prepared>),
    /// `--capture`: the window, ticks, and the run's command, which the
    /// capture's requests send once it is armed.
    Capture(u16, Command),
}

/// The end time of a run with `--identify` when `--t-end` is not given, s:
/// the wait for rest ([`REST_TIMEOUT_S`], 10 s) and the worst case of each
/// rotor's identification with every wait at its timeout ([`WORST_ROTOR_S`],
/// 60 s): 130 s on two rotors. The run ends with the identification, 20 to 40
/// s on the reference machine.
pub fn identify_t_end(machine: &Machine) -> f64 {
    REST_TIMEOUT_S + machine.rotors.len() as f64 * f64::from(WORST_ROTOR_S)
}

/// The capture's window for `--capture-for S`, ticks, at the machine's rate:
/// 1 to the firmware's buffer ([`BOARD_CAPACITY`]), else the problem.
fn window(s: f64, machine: &Machine) -> Result<u16, String> {
    if !(s.is_finite() && s > 0.0) {
        return Err(format!(
            "--capture-for {s}: must be a number of seconds above 0"
        ));
    }
    let tick_s = 1.0 / machine.controller.rate_hz;
    let ticks = (s / tick_s).round();
    if ticks < 1.0 || ticks > BOARD_CAPACITY as f64 {
        return Err(format!(
            "--capture-for {s}: {ticks} ticks of {} ms; the firmware records 1 to {BOARD_CAPACITY} ticks ({} s)",
            sig(tick_s * 1e3),
            sig(BOARD_CAPACITY as f64 * tick_s)
        ));
    }
    Ok(ticks as u16)
}

/// The problems of `--identify`, `--write`, `--capture` and `--capture-for`
/// in `args` for a run of `machine` to `t_end`, s (given as `t_end_origin`),
/// pushed to `problems`; the capture's window when it is sound.
pub fn check(
    args: &RunArgs,
    machine: &Machine,
    t_end: f64,
    t_end_origin: &str,
    problems: &mut Vec<String>,
) -> Option<u16> {
    if args.identify {
        if args.firmware.is_none() {
            problems.push(format!(
                "--identify runs the firmware's identification on the plant: give --firmware ELF (the binary `pil`: `{BUILD}`)"
            ));
        }
        if args.command.is_some() || args.open_loop.is_some() {
            problems.push(
                "--identify: the identification drives the motors itself: give no --command or --open-loop"
                    .to_string(),
            );
        }
        if args.capture.is_some() {
            problems.push(
                "--identify and --capture: give one (--capture records the ticks of a run's --command)"
                    .to_string(),
            );
        }
    } else if args.write.is_some() {
        problems.push(
            "--write goes with --identify: the machine file with the motor keys and rotor inertias the firmware measured"
                .to_string(),
        );
    }
    let window = match (&args.capture, args.capture_for) {
        (None, None) => return None,
        (None, Some(_)) => {
            problems.push("--capture-for goes with --capture FILE.csv".to_string());
            return None;
        }
        (Some(_), None) => {
            problems.push(
                "--capture needs --capture-for S: the window recorded from the command, s"
                    .to_string(),
            );
            return None;
        }
        (Some(_), Some(s)) => window(s, machine),
    };
    // With --identify, said above.
    if !args.identify && (args.firmware.is_none() || args.command.is_none()) {
        problems.push(
            "--capture records the firmware's control ticks from its command: give --firmware ELF and --command"
                .to_string(),
        );
    }
    let window = match window {
        Ok(w) => w,
        Err(p) => {
            problems.push(p);
            return None;
        }
    };
    // The machine at rest first, the window from the command, the read after
    // it, the run going on meanwhile.
    let needed = needed_s(window, 1.0 / machine.controller.rate_hz);
    if t_end.is_finite() && t_end < needed {
        problems.push(format!(
            "{t_end_origin} {}: the capture of {} ticks starts with the machine at rest and is read out after its window, while the run goes on: the run must last at least {} s",
            sig(t_end),
            window,
            sig((needed * 1e3).ceil() * 1e-3)
        ));
    }
    Some(window)
}

/// The requests of `asks`.
pub fn script(asks: &Asks) -> Box<dyn Script> {
    match asks {
        Asks::Identify(_) => Box::new(IdentifyScript::new()),
        Asks::Capture(window, command) => Box::new(CaptureScript::new(*window, *command)),
    }
}

/// `--identify`: the firmware's final report printed in `format` as `host-sim
/// device identify` prints it, `--write` written; a run that ended (at
/// `t_end`, s) before the report is a failure. `note` is said on stderr first.
pub fn conclude_identify(
    firmware: &FirmwareDriver,
    prepared: Box<Prepared>,
    format: Format,
    (t_end, origin): (f64, &str),
    note: &str,
    out: &mut Console<'_>,
) -> Result<(), Failure> {
    out.note(note);
    let Some(report) = final_report(firmware.answers()) else {
        return Err(Failure::run(format!(
            "--identify: the identification had not ended at t = {} s ({origin}); its status then: {}",
            sig(t_end),
            last_status(firmware.answers())
        )));
    };
    identity::conclude(&report, *prepared, format, out)
}

/// `--capture`: the capture read out of the firmware by the run's end at
/// `t_end`, s (given as `origin`), or why not (a run failure: nothing is
/// written).
pub fn captured(
    firmware: &FirmwareDriver,
    path: &Path,
    (t_end, origin): (f64, &str),
) -> Result<CaptureFile, Failure> {
    capture_file(firmware.answers()).map_err(|why| {
        Failure::run(format!(
            "--capture {}: {why} at t = {} s ({origin}): the machine took longer to rest, or a longer run is needed; nothing written",
            path.display(),
            sig(t_end)
        ))
    })
}

/// A capture written, for the summary.
#[derive(Clone, Debug)]
pub struct CaptureNote {
    /// Where.
    pub path: PathBuf,
    /// What it holds ([`CaptureFile::contents`]).
    pub contents: String,
    /// Its ticks.
    pub ticks: usize,
}

impl CaptureNote {
    /// The note of `file` written to `path`.
    pub fn of(file: &CaptureFile, path: &Path) -> Self {
        CaptureNote {
            path: path.to_path_buf(),
            contents: file.contents(),
            ticks: file.records.len(),
        }
    }
}
