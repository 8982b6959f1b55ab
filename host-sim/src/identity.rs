//! A motor identification's result (`shared::controller::identify`) for people
//! and for the machine file, whichever board measured it (`host-sim device
//! identify`, `host-sim run --firmware --identify`): the values printed with
//! their standard errors, beside the machine file's when one is given, and
//! written into a copy of it with `--write`.
//!
//! # What `--write` changes
//!
//! Each rotor's `inertia`, in the file's own convention (without the eccentric's
//! `m e^2`, which the model adds from `eccentric_mass` and `eccentricity`), and
//! the motor keys `resistance`, `torque_constant`, `coulomb_friction`,
//! `viscous_friction`:
//!
//! - in `[motor]`, at the two motors' mean weighted by their variances, when they
//!   agree within their uncertainty (every key's difference within
//!   [`AGREE_SIGMAS`] combined standard errors) and no rotor has a
//!   `[rotors.motor]` of its own (whose keys would win over `[motor]`);
//! - otherwise in each rotor's `[rotors.motor]`, made where the file has none.
//!
//! Each value is written to [`WRITTEN_DIGITS`] significant digits, every comment
//! and every other key kept; the file written reads back with these values, or
//! nothing is written. A rotor that fell short of a value (its `shortfall`)
//! writes nothing.

use std::path::{Path, PathBuf};

use serde_json::{json, Value};
use shared::controller::identify::{
    Estimate, IdentifyReport, IdentifyStatus, RotorIdentity, Shortfall,
};
use toml_edit::DocumentMut;

use crate::args::Format;
use crate::failure::{Console, Failure};
use crate::machine::{input, Machine};
use crate::numbers;
use crate::output::file::Staged;
use crate::output::machine_edit::with_values;
use crate::output::text::{Align, Table};

/// Two motors agree on a key when their values differ by at most this many
/// combined standard errors, `sqrt(se_1^2 + se_2^2)`.
pub const AGREE_SIGMAS: f64 = 3.0;

/// Significant digits of a value `--write` writes: finer than any standard
/// error the identification reaches (0.02 % at best, on the torque constant).
pub const WRITTEN_DIGITS: usize = 5;

/// The machine file given, read and checked before the device is asked.
pub struct Prepared {
    file: Option<MachineFile>,
    /// `--write`'s staged file and its path.
    write: Option<(Staged, usize, PathBuf)>,
}

/// `--machine`: its path, text and reading.
struct MachineFile {
    path: PathBuf,
    text: String,
    machine: Machine,
}

/// Reads the machine file `machine` (`--machine`, the file the board was built
/// for) and stages `write` (`--write`): a user's mistake is exit 2, before any
/// request.
pub fn prepare(machine: Option<&Path>, write: Option<&Path>) -> Result<Prepared, Failure> {
    let file = match machine {
        None => None,
        Some(path) => {
            let text = input::read_text(path)?;
            let dir = path.parent().unwrap_or(Path::new(""));
            let machine = Machine::from_text(&path.display().to_string(), &text, dir, &[])?;
            Some(MachineFile {
                path: path.to_path_buf(),
                text,
                machine,
            })
        }
    };
    let write = match write {
        None => None,
        Some(path) => {
            let mut staged = Staged::new();
            let index = staged.add("--write", path)?;
            Some((staged, index, path.to_path_buf()))
        }
    };
    Ok(Prepared { file, write })
}

/// The identification's final `report` printed in `format`, beside the
/// machine file's values if one was given, and the file `--write` written:
/// a failure (exit 1) if it was aborted or a rotor fell short, and then
/// nothing is written. The device's and the firmware in the loop's alike.
pub fn conclude(
    report: &IdentifyReport,
    prepared: Prepared,
    format: Format,
    out: &mut Console<'_>,
) -> Result<(), Failure> {
    let file = prepared.file.as_ref();
    out.print(&match format {
        Format::Table => table(report, file),
        Format::Json => format!("{:#}\n", to_json(report, file)),
    });
    if report.status != IdentifyStatus::Done {
        return Err(Failure::device(
            "the identification was aborted (a fault, the E-stop or a stop)",
        ));
    }
    let rotors = &report.identity.rotors[..usize::from(report.identity.rotors_run)];
    if let Some(k) = rotors.iter().position(|r| r.shortfall.is_some()) {
        return Err(Failure::device(format!(
            "rotor {}: {}{}",
            k + 1,
            shortfall_text(rotors[k].shortfall),
            if prepared.write.is_some() {
                "; nothing written"
            } else {
                ""
            }
        )));
    }
    if let (Some((mut staged, index, out_path)), Some(file)) = (prepared.write, file) {
        let text = written(file, rotors, &out_path)?;
        staged.write(index, &text)?;
        staged.commit()?;
        out.note(&format!("wrote {}\n", out_path.display()));
    }
    Ok(())
}

/// An identification's status for people, as the procedure runner names its
/// stages: `not run`, `running`, `done`, `aborted`.
pub fn status_name(s: IdentifyStatus) -> &'static str {
    match s {
        IdentifyStatus::NotRun => "not run",
        IdentifyStatus::Running => "running",
        IdentifyStatus::Done => "done",
        IdentifyStatus::Aborted => "aborted",
    }
}

/// What a shortfall means, for people.
pub fn shortfall_text(s: Option<Shortfall>) -> &'static str {
    match s {
        None => "measured",
        Some(Shortfall::NoStandstill) => "not measured: the rotor turned over under the standstill duties (its eccentric and friction hold less than the machine file says)",
        Some(Shortfall::NoRest) => "not measured: the rotor did not come to rest",
        Some(Shortfall::NoSpeed) => "not measured: a speed level did not turn the rotor four times within 4 s",
        Some(Shortfall::TooFast) => "not measured: the rotor ran faster than the controller's top speed (a motor much unlike its machine file)",
        Some(Shortfall::NoTurn) => "not measured: the spin-up made no whole turn (the inertia)",
        Some(Shortfall::NoFit) => "not measured: a fit did not tell its unknowns apart",
        Some(Shortfall::Aborted) => "aborted (a fault, the E-stop or a stop)",
    }
}

/// The keys of one rotor, with their units: what is measured of it.
fn keys(r: &RotorIdentity) -> [(&'static str, Estimate, &'static str); 5] {
    [
        ("resistance", r.resistance_ohm, "ohm"),
        ("torque_constant", r.torque_constant, "N m/A"),
        ("coulomb_friction", r.coulomb_friction_nm, "N m"),
        ("viscous_friction", r.viscous_friction, "N m s/rad"),
        ("inertia", r.inertia_kg_m2, "kg m^2"),
    ]
}

/// The machine file's value of `key` for rotor `k`: the motor's keys, and the
/// inertia with the eccentric's `m e^2` (as measured).
fn file_value(m: &Machine, k: usize, key: &str) -> Option<f64> {
    let r = m.rotors.get(k)?;
    Some(match key {
        "resistance" => r.motor.resistance,
        "torque_constant" => r.motor.torque_constant,
        "coulomb_friction" => r.motor.coulomb_friction,
        "viscous_friction" => r.motor.viscous_friction,
        "inertia" => r.inertia + r.eccentric_mass * r.eccentricity * r.eccentricity,
        _ => return None,
    })
}

/// The report for people: per rotor, each value with its standard error, the
/// file's value and the difference; then the fits' residuals.
fn table(report: &IdentifyReport, file: Option<&MachineFile>) -> String {
    let mut out = format!("identification  {}\n", status_name(report.status));
    let id = &report.identity;
    for (k, r) in id.rotors[..usize::from(id.rotors_run)].iter().enumerate() {
        let name = file
            .and_then(|f| f.machine.rotors.get(k))
            .map_or(String::new(), |r| format!(" ({})", r.name));
        out.push_str(&format!(
            "rotor {}{name}  {}\n",
            k + 1,
            shortfall_text(r.shortfall)
        ));
        if r.shortfall.is_some() {
            continue;
        }
        let mut t = Table::new(&[
            ("  key", Align::Left),
            ("measured", Align::Right),
            ("std error", Align::Right),
            ("unit", Align::Left),
            ("machine file", Align::Right),
            ("difference", Align::Right),
        ]);
        for (key, e, unit) in keys(r) {
            let (v, se) = (f64::from(e.value), f64::from(e.std_error));
            let (given, diff) = match file.and_then(|f| file_value(&f.machine, k, key)) {
                // A file's 0 (no friction, say) has no relative difference.
                Some(x) if x == 0.0 => (numbers::sig(x), "-".to_string()),
                Some(x) => (
                    numbers::sig(x),
                    format!("{} %", numbers::fixed_signed(100.0 * (v - x) / x, 1)),
                ),
                None => (String::new(), String::new()),
            };
            t.row(vec![
                format!("  {key}"),
                numbers::sig(v),
                numbers::sig(two_digits(se)),
                unit.to_string(),
                given,
                diff,
            ]);
        }
        out.push_str(&t.render());
        out.push_str(&format!(
            "  the inertia includes the eccentric's m e^2\n  voltage fit: offset {} V, drop {} V, residual {} V ({} standstill levels each way, {} speeds)\n  friction fit: residual {} N m\n",
            numbers::sig(two_digits(f64::from(r.offset_v.value))),
            numbers::sig(two_digits(f64::from(r.drop_v.value))),
            numbers::sig(two_digits(f64::from(r.voltage_residual_v))),
            r.standstill_levels,
            r.speed_levels,
            numbers::sig(two_digits(f64::from(r.friction_residual_nm))),
        ));
    }
    out
}

/// The report for programs.
fn to_json(report: &IdentifyReport, file: Option<&MachineFile>) -> Value {
    let id = &report.identity;
    let rotors: Vec<Value> = id.rotors[..usize::from(id.rotors_run)]
        .iter()
        .enumerate()
        .map(|(k, r)| {
            let mut values = serde_json::Map::new();
            if r.shortfall.is_none() {
                for (key, e, unit) in keys(r) {
                    values.insert(
                        key.to_string(),
                        json!({
                            "value": f64::from(e.value),
                            "std_error": f64::from(e.std_error),
                            "unit": unit,
                            "machine_file": file.and_then(|f| file_value(&f.machine, k, key)),
                        }),
                    );
                }
            }
            json!({
                "rotor": k + 1,
                "name": file.and_then(|f| f.machine.rotors.get(k)).map(|r| r.name.clone()),
                "shortfall": r.shortfall.map(|s| shortfall_text(Some(s))),
                "values": values,
                "offset_v": f64::from(r.offset_v.value),
                "drop_v": f64::from(r.drop_v.value),
                "voltage_residual_v": f64::from(r.voltage_residual_v),
                "friction_residual_nm": f64::from(r.friction_residual_nm),
                "standstill_levels": r.standstill_levels,
                "speed_levels": r.speed_levels,
            })
        })
        .collect();
    json!({
        "status": status_name(report.status),
        "machine": file.map(|f| f.path.display().to_string()),
        "rotors": rotors,
    })
}

/// `x` to two significant digits: a standard error or a residual, for people.
fn two_digits(x: f64) -> f64 {
    format!("{x:.1e}").parse().unwrap_or(x)
}

/// `x` to [`WRITTEN_DIGITS`] significant digits.
fn rounded(x: f64) -> f64 {
    format!("{x:.*e}", WRITTEN_DIGITS - 1).parse().unwrap_or(x)
}

/// The machine file's text with the identified values (module documentation),
/// checked to read back with them; `out` is where it goes.
fn written(file: &MachineFile, rotors: &[RotorIdentity], out: &Path) -> Result<String, Failure> {
    let fail = |why: String| Failure::run(format!("--write {}: {why}", out.display()));
    let m = &file.machine;
    if rotors.len() != m.rotors.len() {
        return Err(fail(format!(
            "the device identified {} but {} has {}: the board was built for another machine file",
            numbers::count(rotors.len(), "rotor"),
            file.path.display(),
            numbers::count(m.rotors.len(), "rotor")
        )));
    }
    let doc: DocumentMut = file
        .text
        .parse()
        .map_err(|e| fail(format!("{} does not parse again: {e}", file.path.display())))?;
    let own_motor = (0..m.rotors.len()).any(|k| {
        doc.get("rotors")
            .and_then(|r| r.as_array_of_tables())
            .and_then(|a| a.get(k))
            .is_some_and(|t| t.contains_key("motor"))
    });
    let motor_keys = |r: &RotorIdentity| {
        [
            ("resistance", r.resistance_ohm),
            ("torque_constant", r.torque_constant),
            ("coulomb_friction", r.coulomb_friction_nm),
            ("viscous_friction", r.viscous_friction),
        ]
    };
    let agree = rotors.len() == 1
        || motor_keys(&rotors[0])
            .iter()
            .zip(motor_keys(&rotors[1]))
            .all(|((_, a), (_, b))| {
                let spread = (sq(a.std_error) + sq(b.std_error)).sqrt();
                f64::from((a.value - b.value).abs()) <= AGREE_SIGMAS * spread
            });
    // The machine file takes no negative friction: a value below 0 (the viscous
    // friction, a small term the sense's noise can take below 0) is said, not
    // written.
    for (k, r) in rotors.iter().enumerate() {
        for (key, e) in motor_keys(r) {
            if e.value < 0.0 {
                return Err(fail(format!(
                    "rotor {}: {key} came out {} +- {}, below 0, which the machine file does not take: not written; measure again, or set it by hand",
                    k + 1,
                    numbers::sig(f64::from(e.value)),
                    numbers::sig(two_digits(f64::from(e.std_error)))
                )));
            }
        }
    }
    // (key path, value) to write.
    let mut values: Vec<(String, f64)> = Vec::new();
    if agree && !own_motor {
        for (i, (key, _)) in motor_keys(&rotors[0]).iter().enumerate() {
            let pooled = pooled(
                &rotors
                    .iter()
                    .map(|r| motor_keys(r)[i].1)
                    .collect::<Vec<_>>(),
            );
            values.push((format!("motor.{key}"), rounded(pooled)));
        }
    } else {
        for (k, r) in rotors.iter().enumerate() {
            for (key, e) in motor_keys(r) {
                values.push((
                    format!("rotors[{k}].motor.{key}"),
                    rounded(f64::from(e.value)),
                ));
            }
        }
    }
    for (k, r) in rotors.iter().enumerate() {
        let rotor = &m.rotors[k];
        let eccentric = rotor.eccentric_mass * rotor.eccentricity * rotor.eccentricity;
        let own = f64::from(r.inertia_kg_m2.value) - eccentric;
        if own <= 0.0 {
            return Err(fail(format!(
                "rotor {}: the measured inertia {} kg m^2 is not above the eccentric's m e^2 alone ({} kg m^2 from eccentric_mass and eccentricity): check those keys",
                k + 1,
                numbers::sig(f64::from(r.inertia_kg_m2.value)),
                numbers::sig(eccentric)
            )));
        }
        values.push((format!("rotors[{k}].inertia"), rounded(own)));
    }
    with_values(&file.path, &file.text, &values, out)
        .map_err(|why| fail(format!("{why} (an internal error)")))
}

fn sq(x: f32) -> f64 {
    f64::from(x) * f64::from(x)
}

/// The inverse-variance weighted mean of `e` (the plain mean where a standard
/// error is 0).
fn pooled(e: &[Estimate]) -> f64 {
    if e.iter().any(|e| e.std_error <= 0.0) {
        return e.iter().map(|e| f64::from(e.value)).sum::<f64>() / e.len() as f64;
    }
    let w: Vec<f64> = e.iter().map(|e| 1.0 / sq(e.std_error)).collect();
    let total: f64 = w.iter().sum();
    e.iter()
        .zip(&w)
        .map(|(e, w)| f64::from(e.value) * w)
        .sum::<f64>()
        / total
}
