//! Stage 1 of `calibrate --capture` ([`super`]): the machine file, the fitted
//! keys, each one a capture measures ([`motor_key`]), the capture and its
//! premises, checked with every problem at once (exit 2); then one replay at
//! the file's values, timed, which refuses a capture whose recorded outputs
//! are not the controller's.

use std::path::{Path, PathBuf};
use std::time::Instant;

use shared::controller::Params;

use super::residuals;
use super::scales::Scales;
use crate::calibrate::keys::{self, FitKey};
use crate::calibrate::CalibrateArgs;
use crate::capture::CaptureFile;
use crate::failure::{Failure, Kind, Reason};
use crate::machine::set::MOTOR_KEYS;
use crate::machine::Machine;
use crate::parts::read_machine_file;
use crate::replay::{self, Replay};

/// What stage 1 read and checked.
pub struct Inputs {
    /// The machine file's text, as checked.
    pub text: String,
    /// The fitted keys.
    pub keys: Vec<FitKey>,
    /// The capture.
    pub capture: CaptureFile,
    /// The board's controller (the firmware's machine file, the capture's table).
    pub params: Params,
    /// The rotors.
    pub rotors: usize,
    /// The residuals' scales.
    pub scales: Scales,
    /// The residuals' window, ticks ([`residuals::window`]).
    pub window: usize,
    /// The firmware's machine file.
    pub firmware: PathBuf,
    /// What the premises' checks found that the user should know.
    pub warnings: Vec<String>,
    /// The replay at the file's values.
    pub nominal: Replay,
    /// Seconds it took.
    pub seconds_per_replay: f64,
}

/// Whether the reader's key path `key_path` is one a capture measures: a motor
/// key, the machine's (`motor.resistance`) or a rotor's own
/// (`rotors[0].motor.resistance`), or a rotor's inertia (`rotors[1].inertia`).
pub fn motor_key(key_path: &str) -> bool {
    let motor = |k: &str| MOTOR_KEYS.iter().any(|(name, _)| *name == k);
    if let Some(k) = key_path.strip_prefix("motor.") {
        return motor(k);
    }
    let Some(rest) = key_path.strip_prefix("rotors[") else {
        return false;
    };
    match rest.split_once("].") {
        Some((i, k)) if i.parse::<usize>().is_ok() => {
            k == "inertia" || k.strip_prefix("motor.").is_some_and(motor)
        }
        _ => false,
    }
}

/// Stage 1 for the capture `capture_path`, every problem at once (exit 2).
pub fn read_inputs(args: &CalibrateArgs, capture_path: &Path) -> Result<Inputs, Failure> {
    let path = &args.machine.path;
    let (text, _) = read_machine_file(path)?;
    let dir = path.parent().unwrap_or(Path::new(""));
    let machine = Machine::from_text(&path.display().to_string(), &text, dir, &args.set.keys)?;
    let mut problems: Vec<Reason> = Vec::new();
    let keys = match keys::resolve(path, &text, &args.set.keys, &args.fit) {
        Ok(keys) => {
            for k in &keys {
                if let Some(p) = k.key_paths.iter().find(|p| !motor_key(p)) {
                    problems.push(Reason::new(format!(
                        "--fit {}: {p} is not a key a capture measures: with --capture, calibrate fits each rotor's motor and inertia (motor.KEY or a rotor's own rotors.NAME.motor.KEY, KEY one of {}; rotors.NAME.inertia); fit the contacts to measured travel (--measured, docs/calibration.md)",
                        k.key,
                        MOTOR_KEYS.iter().map(|(n, _)| *n).collect::<Vec<_>>().join(", ")
                    )));
                }
            }
            Some(keys)
        }
        Err(f) => {
            problems.extend(f.into_reasons());
            None
        }
    };
    let firmware = args
        .firmware_machine
        .clone()
        .unwrap_or_else(|| path.clone());
    let mut warnings = Vec::new();
    let premises = CaptureFile::read(capture_path).and_then(|capture| {
        let params = replay::controller_params(&capture, capture_path, &firmware, &mut warnings)?;
        replay::check_rotor_count(&machine, &params, path, &firmware)?;
        Ok((capture, params))
    });
    let (capture, params) = match premises {
        Ok(found) => found,
        Err(f) => {
            problems.extend(f.into_reasons());
            return Err(Failure::new(Kind::Usage, problems));
        }
    };
    let Some(keys) = keys.filter(|_| problems.is_empty()) else {
        return Err(Failure::new(Kind::Usage, problems));
    };
    // The replay at the file's values: a capture that does not replay is
    // refused here, before the fit.
    let started = Instant::now();
    let nominal = replay::replay(&capture, &machine, &params, Vec::new())?;
    let seconds_per_replay = started.elapsed().as_secs_f64();
    let rotors = machine.rotors.len();
    let scales = Scales::new(&params, &machine);
    let window = residuals::window(&params);
    Ok(Inputs {
        text,
        keys,
        capture,
        params,
        rotors,
        scales,
        window,
        firmware,
        warnings,
        nominal,
        seconds_per_replay,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_keys_a_capture_measures() {
        for yes in [
            "motor.resistance",
            "motor.current_limit",
            "rotors[0].motor.torque_constant",
            "rotors[1].inertia",
        ] {
            assert!(motor_key(yes), "{yes}");
        }
        for no in [
            "contacts[0].friction",
            "motor.speed",
            "rotors[0].eccentric_mass",
            "rotors[x].inertia",
            "rotors[0].motor.resistance.x",
            "platform.inertia",
        ] {
            assert!(!motor_key(no), "{no}");
        }
    }
}
