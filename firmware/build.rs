//! Build script of the firmware:
//!
//! 1. puts the repository's root `memory.x` (the one memory layout of the
//!    STM32F405RG) on the linker's search path, where cortex-m-rt's `link.x`
//!    includes it;
//! 2. compiles in the machine: reads the machine file (`VIBRO_MACHINE`, default
//!    `../examples/vibro-driver.toml`) with `machine_file::Machine::load`, the reader
//!    and checks of `host-sim run`, and writes `OUT_DIR/machine.rs` with
//!    `MACHINE: shared::controller::MachineConstants` from
//!    `machine_file::machine_constants` (shared's formulas), for
//!    `Params::from_machine(&MACHINE)` at init, and the file's fingerprint
//!    (`MACHINE_FILE_CRC32`, `MACHINE_FILE_LEN`) for the processor in the loop. The firmware ticks at
//!    `CONTROL_RATE_HZ`: a machine file with another `rate_hz` fails. A machine
//!    with one rotor builds: `MACHINE.rotor_count` is `RotorCount::One`, the
//!    controller holds that rotor's speed and the second bridge stays off;
//! 3. compiles in the tuning table: `VIBRO_TUNING` if set, else the machine file's
//!    `[controller].tuning_table`, read with `machine_file::tuning_file::read` (the
//!    controller's rule for rows), and writes `OUT_DIR/tuning.rs` with
//!    `TUNING_ROWS: [(f32, f32, f32); N]`, rows of `(speed_rpm, right_offset_deg,
//!    left_offset_deg)` in the file's order, for `TuningTable::from_rows` at init.
//!    A machine without a table gets the controller's default
//!    (`TuningTable::default_offsets`), as in host-sim, with a warning.
//!
//! Relative paths in `VIBRO_MACHINE` and `VIBRO_TUNING` are taken from `firmware/`
//! (cargo runs build scripts there); a machine file's `tuning_table` from the
//! machine file's folder, as host-sim does. Every problem fails the build, one line
//! each as host-sim prints them: `error: FILE: KEY: MESSAGE`.
//!
//! This file is only the glue (paths, environment, generated code);
//! `tests/tests/firmware_machine.rs` includes it to test that glue.

use std::env;
use std::ffi::OsString;
use std::fs;
use std::path::{Path, PathBuf};

use machine_file::input::{render, Location, Problem};
use machine_file::{machine_constants, tuning_file, Machine};
use shared::controller::{MachineConstants, Params, TuningTable, CONTROL_RATE_HZ};
use shared::drive::Decay;

/// The machine compiled in unless `VIBRO_MACHINE` is set, relative to `firmware/`.
pub const DEFAULT_MACHINE_FILE: &str = "../examples/vibro-driver.toml";
/// Environment variable naming the machine file.
pub const MACHINE_ENV: &str = "VIBRO_MACHINE";
/// Environment variable naming the tuning table file (overrides the machine's).
pub const TUNING_ENV: &str = "VIBRO_TUNING";

/// A row of the generated table: speed, rpm; right and left offsets, degrees.
pub type Row = (f32, f32, f32);

fn main() {
    let manifest_dir = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").expect("set by cargo"));
    let out_dir = PathBuf::from(env::var_os("OUT_DIR").expect("set by cargo"));

    // memory.x: copy into OUT_DIR rather than pointing at the root: the search path
    // then holds nothing but memory.x, so no other file there can shadow a linker
    // script.
    let memory_x = manifest_dir.join("..").join("memory.x");
    fs::copy(&memory_x, out_dir.join("memory.x"))
        .unwrap_or_else(|e| panic!("cannot copy {}: {e}", memory_x.display()));
    println!("cargo:rustc-link-search={}", out_dir.display());

    // The machine.
    println!("cargo:rerun-if-env-changed={MACHINE_ENV}");
    println!("cargo:rerun-if-env-changed={TUNING_ENV}");
    let machine_path = machine_path(&manifest_dir, env::var_os(MACHINE_ENV));
    println!("cargo:rerun-if-changed={}", machine_path.display());
    let machine = load_machine(&machine_path).unwrap_or_else(|problems| {
        fail(
            &problems,
            &format!(
                "the machine file is {MACHINE_ENV} (relative to firmware/ or absolute), \
                 {DEFAULT_MACHINE_FILE} unless set; `host-sim run FILE` checks it the same way"
            ),
        )
    });
    let constants = machine_constants(&machine);
    let machine_bytes = fs::read(&machine_path)
        .unwrap_or_else(|e| panic!("cannot read {}: {e}", machine_path.display()));
    fs::write(
        out_dir.join("machine.rs"),
        machine_rs(&constants, &machine_path) + &fingerprint_rs(&machine_bytes),
    )
    .expect("cannot write machine.rs");

    // The tuning table: the environment's, the machine's, or the default.
    let tuning = tuning_path(&manifest_dir, env::var_os(TUNING_ENV), &machine);
    if let Some(path) = &tuning {
        println!("cargo:rerun-if-changed={}", path.display());
    } else if machine.rotors.len() == 2 {
        // (One rotor has no offset to look up: the table is compiled in unused.)
        println!(
            "cargo:warning={}: no [controller].tuning_table and no {TUNING_ENV}: \
             the controller's default offsets (90 right, 270 left) are compiled in",
            machine_path.display()
        );
    }
    let rows = tuning_rows(tuning.as_deref()).unwrap_or_else(|problems| {
        fail(
            &problems,
            &format!(
                "the tuning table is {TUNING_ENV} (relative to firmware/ or absolute), else \
                 the machine file's [controller].tuning_table (relative to the machine file)"
            ),
        )
    });
    fs::write(
        out_dir.join("tuning.rs"),
        tuning_rs(&rows, tuning.as_deref()),
    )
    .expect("cannot write tuning.rs");

    // Rebuild when the layout or this script changes (the files above too; a change
    // in machine-file or shared rebuilds this script, and so runs it again).
    println!("cargo:rerun-if-changed={}", memory_x.display());
    println!("cargo:rerun-if-changed=build.rs");
}

/// Prints every problem as host-sim does, then `hint`, and fails the build.
fn fail(problems: &[Problem], hint: &str) -> ! {
    eprint!("{}", render(problems));
    eprintln!("note: {hint}");
    std::process::exit(1);
}

/// A path from the environment (`value` of a variable; unset or empty: `None`),
/// relative to `firmware/` (`manifest_dir`) unless absolute.
fn from_env(manifest_dir: &Path, value: Option<OsString>) -> Option<PathBuf> {
    value
        .filter(|v| !v.is_empty())
        .map(|v| manifest_dir.join(v))
}

/// The machine file: `VIBRO_MACHINE`'s `value`, else [`DEFAULT_MACHINE_FILE`], both
/// relative to `firmware/` (`manifest_dir`).
pub fn machine_path(manifest_dir: &Path, value: Option<OsString>) -> PathBuf {
    from_env(manifest_dir, value).unwrap_or_else(|| manifest_dir.join(DEFAULT_MACHINE_FILE))
}

/// The tuning table file: `VIBRO_TUNING`'s `value` (relative to `firmware/`), else
/// the machine's `[controller].tuning_table` (resolved against the machine file's
/// folder by [`Machine::load`]), else none.
pub fn tuning_path(manifest_dir: &Path, value: Option<OsString>, m: &Machine) -> Option<PathBuf> {
    from_env(manifest_dir, value).or_else(|| m.controller.tuning_table.clone())
}

/// The machine file at `path`, checked as `host-sim run` checks it, and then for the
/// firmware: its `rate_hz` must be the firmware's tick, and the controller must
/// take the constants it gives.
pub fn load_machine(path: &Path) -> Result<Machine, Vec<Problem>> {
    let machine = Machine::load(path, &[])?;
    let file = path.display().to_string();
    // The tick is TIM7's (board.rs), fixed in the firmware; the controller's dt
    // comes from the file.
    let rate = machine.controller.rate_hz;
    if rate != f64::from(CONTROL_RATE_HZ) {
        return Err(vec![Problem {
            file,
            location: Location::Key("controller.rate_hz".into()),
            message: format!(
                "must be {CONTROL_RATE_HZ} Hz: the firmware ticks at CONTROL_RATE_HZ \
                 (TIM7 in board.rs) (got {rate})"
            ),
        }]);
    }
    // The constants' formulas (the lift-off band from the platform's weight) are
    // those of a single platform so far.
    let beyond = machine.beyond_the_platform();
    if !beyond.is_empty() {
        return Err(vec![Problem {
            file,
            location: Location::File,
            message: format!(
                "several bodies ({}): the controller's constants are defined for a single platform on the fundament so far",
                beyond.join(", ")
            ),
        }]);
    }
    // The current the controller reads is the mean over the tick in host-sim; the
    // board samples once per PWM update, at the period's extreme, which is the
    // period's mean only while the ripple is linear about it: slow decay. In fast
    // decay the current dies in each coasting part and a sample mid-coast reads 0.
    if machine.drive.bridge.decay == Decay::Fast {
        return Err(vec![Problem {
            file,
            location: Location::Key("drive.decay".into()),
            message: "must be \"slow\" for the firmware: its ADC samples the current once per PWM period, which is the period's mean only in slow decay (host-sim simulates \"fast\")".into(),
        }]);
    }
    // What host-sim accepts but the controller would refuse at init (a parameters
    // fault on the board), such as more than 2^24 encoder counts.
    if let Err(e) = Params::from_machine(&machine_constants(&machine)).validate() {
        return Err(vec![Problem {
            file,
            location: Location::File,
            message: format!("the firmware's controller refuses this machine: {e}"),
        }]);
    }
    Ok(machine)
}

/// The rows of the tuning table file at `path` (checked by the controller's rule),
/// or the controller's default offsets without one.
pub fn tuning_rows(path: Option<&Path>) -> Result<Vec<Row>, Vec<Problem>> {
    match path {
        Some(path) => Ok(tuning_file::read(path)?
            .iter()
            .map(|&(s, r, l)| (s as f32, r as f32, l as f32))
            .collect()),
        None => Ok(
            TuningTable::<{ shared::controller::MAX_TUNING_ROWS }>::default_offsets()
                .rows()
                .iter()
                .map(|r| (r.speed_rpm, r.right_offset_deg, r.left_offset_deg))
                .collect(),
        ),
    }
}

/// `OUT_DIR/machine.rs`: the `MACHINE` constant (and `MACHINE_FILE`, its source).
/// Each number is written as the shortest literal that reads back as the same `f32`.
pub fn machine_rs(m: &MachineConstants, path: &Path) -> String {
    let mut code = format!(
        "/// The machine file compiled in by build.rs (`{MACHINE_ENV}`).\n\
         #[allow(dead_code)]\n\
         pub const MACHINE_FILE: &str = {:?};\n\n\
         /// The controller's constants of the machine file compiled in by build.rs.\n\
         pub const MACHINE: shared::controller::MachineConstants = \
         shared::controller::MachineConstants {{\n",
        path.display().to_string()
    );
    code.push_str(&format!("    rate_hz: {:?},\n", m.rate_hz));
    code.push_str(&format!("    encoder_counts: {},\n", m.encoder_counts));
    code.push_str(&format!(
        "    supply_voltage_v: {:?},\n",
        m.supply_voltage_v
    ));
    code.push_str(&format!("    current_limit_a: {:?},\n", m.current_limit_a));
    code.push_str(&format!(
        "    rotor_count: shared::controller::RotorCount::{:?},\n",
        m.rotor_count
    ));
    code.push_str("    rotors: [\n");
    for r in &m.rotors {
        code.push_str(&format!(
            "        shared::controller::RotorModel {{\n            resistance_ohm: {:?},\n            \
             torque_constant: {:?},\n            inertia_kg_m2: {:?},\n            \
             load_torque_nm: {:?},\n        }},\n",
            r.resistance_ohm, r.torque_constant, r.inertia_kg_m2, r.load_torque_nm
        ));
    }
    code.push_str("    ],\n");
    code.push_str(&format!(
        "    resonance_band_rpm: [{:?}, {:?}],\n",
        m.resonance_band_rpm[0], m.resonance_band_rpm[1]
    ));
    code.push_str(&format!(
        "    bridge: shared::drive::BridgeConfig {{\n        decay: shared::drive::Decay::{:?},\n        \
         pwm_hz: {},\n    }},\n}};\n",
        m.bridge.decay, m.bridge.pwm_hz
    ));
    code
}

/// The machine file's fingerprint for `OUT_DIR/machine.rs` (`host-sim run
/// --firmware` compares it with the file it simulates, `shared::pil`):
/// `MACHINE_FILE_CRC32`, CRC-32/ISO-HDLC of its bytes, and `MACHINE_FILE_LEN`.
pub fn fingerprint_rs(bytes: &[u8]) -> String {
    format!(
        "\n/// CRC-32/ISO-HDLC of the machine file's bytes.\n\
         #[allow(dead_code)]\n\
         pub const MACHINE_FILE_CRC32: u32 = {:#010x};\n\
         /// The machine file's length, bytes.\n\
         #[allow(dead_code)]\n\
         pub const MACHINE_FILE_LEN: u32 = {};\n",
        shared::codec::crc::crc32(bytes),
        bytes.len()
    )
}

/// `OUT_DIR/tuning.rs`: the `TUNING_ROWS` constant, from the file at `path` (`None`:
/// the controller's default offsets).
pub fn tuning_rs(rows: &[Row], path: Option<&Path>) -> String {
    let source = match path {
        Some(p) => format!("`{}`", p.display()),
        None => "the controller's default offsets".to_string(),
    };
    let mut code = format!(
        "/// Rows `(speed_rpm, right_offset_deg, left_offset_deg)` of the tuning table\n\
         /// compiled in by build.rs from {source}.\n"
    );
    code.push_str(&format!(
        "pub const TUNING_ROWS: [(f32, f32, f32); {}] = [\n",
        rows.len()
    ));
    for (speed, right, left) in rows {
        code.push_str(&format!("    ({speed:?}, {right:?}, {left:?}),\n"));
    }
    code.push_str("];\n");
    code
}
