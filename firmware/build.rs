//! Build script of the firmware:
//!
//! 1. puts the repository's root `memory.x` (the one memory layout of the
//!    STM32F405RG) on the linker's search path, where cortex-m-rt's `link.x`
//!    includes it;
//! 2. compiles in the machine: reads the machine file (`VIBRO_MACHINE`, default
//!    `../examples/vibro-driver.toml`) and writes `OUT_DIR/machine.rs` with
//!    `MACHINE: shared::controller::MachineConstants`, for
//!    `Params::from_machine(&MACHINE)` at init;
//! 3. compiles in the tuning table: `VIBRO_TUNING` if set, else the machine file's
//!    `[controller].tuning_table`, and writes `OUT_DIR/tuning.rs` with
//!    `TUNING_ROWS: [(f32, f32, f32); N]`, rows of `(speed_rpm, right_offset_deg,
//!    left_offset_deg)` in the file's order, for `TuningTable::from_rows` at init.
//!    A machine without a table gets the controller's default (one row, 90 degrees
//!    right and 270 left at every speed), as in host-sim, with a warning.
//!
//! Relative paths in `VIBRO_MACHINE` and `VIBRO_TUNING` are taken from `firmware/`
//! (cargo runs build scripts there); a machine file's `tuning_table` from the
//! machine file's folder, as host-sim does.
//!
//! # The machine file -> `MachineConstants` mapping
//!
//! The same as host-sim's `closed_loop::machine_constants`, key by key, so the
//! firmware runs the controller the simulator tuned (`tests/tests/firmware_machine.rs`
//! includes this file and checks the two agree on several machine files):
//!
//! | constant | from |
//! | --- | --- |
//! | `rate_hz` | `[controller].rate_hz` (default 1000) |
//! | `encoder_counts` | `[sensors].encoder_counts` (default 4096) |
//! | `supply_voltage_v` | `[drive].supply_voltage` |
//! | `current_limit_a` | the smaller `current_limit` of the two rotors' motors |
//! | `rotors[k]` | rotor k's motor `resistance`, `torque_constant`; `inertia + eccentric_mass x eccentricity^2`; load torque `eccentric_mass x eccentricity x g + coulomb_friction` |
//! | `resonance_band_rpm` | 0.7 to 1.18 x the lift-off speed `sqrt(M g / (2 m e))` (`M`: platform and both eccentric masses, `g = \|[fundament].gravity\|`, `m e` the rotors' mean), `[0, 0]` without eccentric masses |
//! | `bridge` | `[drive].decay` (`"slow"` or `"fast"`, default `"slow"`) and `[drive].pwm_hz` (an integer in [1000, 200000], default 20000) |
//!
//! A rotor's motor is `[motor]` with any key its own `[rotors.motor]` gives in its
//! place. Only the keys above are read and checked (types, finite, ranges); the rest
//! of the file is the simulator's: check a new machine file with `host-sim run`
//! first. Every problem fails the build with the file, the key and what is wrong.
//! The tuning file is parsed by hand: only `[[rows]]` tables with the three keys
//! set to numbers, `#` comments and blank lines; anything else fails the build with
//! the line number.

use std::env;
use std::fs;
use std::path::{Path, PathBuf};

use toml::{Table, Value};

/// The machine compiled in unless `VIBRO_MACHINE` is set, relative to `firmware/`.
pub const DEFAULT_MACHINE_FILE: &str = "../examples/vibro-driver.toml";
/// Environment variable naming the machine file.
pub const MACHINE_ENV: &str = "VIBRO_MACHINE";
/// Environment variable naming the tuning table file (overrides the machine's).
pub const TUNING_ENV: &str = "VIBRO_TUNING";
/// The controller's default offsets, degrees (`shared::controller::TuningTable::
/// default_offsets`): for a machine without a tuning table.
pub const DEFAULT_ROWS: [(f32, f32, f32); 1] = [(0.0, 90.0, 270.0)];
/// `[drive].pwm_hz` when absent, Hz (`shared::drive::BridgeConfig::DEFAULT`).
pub const DEFAULT_PWM_HZ: u32 = 20_000;
/// The range of `[drive].pwm_hz`, Hz (host-sim's `machine::PWM_HZ_RANGE`).
pub const PWM_HZ_RANGE: [i64; 2] = [1_000, 200_000];
/// Rows the controller's table holds (`shared::controller::MAX_TUNING_ROWS`).
pub const MAX_TUNING_ROWS: usize = 32;
/// Largest encoder resolution the controller accepts (`MAX_ENCODER_COUNTS`, 2^24).
pub const MAX_ENCODER_COUNTS: i64 = 1 << 24;
/// Highest control rate, Hz (host-sim's `MAX_RATE_HZ`, `Params::validate`).
pub const MAX_RATE_HZ: f64 = 100_000.0;
/// The firmware's control tick, Hz: `shared::controller::CONTROL_RATE_HZ`, the rate
/// board.rs starts TIM7 at. A machine file must state the same `rate_hz` (the
/// controller's `dt` comes from it).
pub const FIRMWARE_RATE_HZ: f64 = 1000.0;
/// Default `[fundament].gravity`, m/s^2 (host-sim's `DEFAULT_GRAVITY`).
pub const DEFAULT_GRAVITY: [f64; 2] = [0.0, -9.81];

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
    let from_env = |name: &str| {
        env::var_os(name)
            .filter(|v| !v.is_empty())
            .map(|v| manifest_dir.join(v))
    };
    let machine_path =
        from_env(MACHINE_ENV).unwrap_or_else(|| manifest_dir.join(DEFAULT_MACHINE_FILE));
    println!("cargo:rerun-if-changed={}", machine_path.display());
    let machine = read_machine(&machine_path).unwrap_or_else(|problems| fail(&problems));
    if machine.rate_hz != FIRMWARE_RATE_HZ {
        fail(&[format!(
            "{}: controller.rate_hz: the firmware ticks at {FIRMWARE_RATE_HZ} Hz \
             (CONTROL_RATE_HZ, TIM7 in board.rs); the machine file says {}",
            machine_path.display(),
            machine.rate_hz
        )]);
    }
    fs::write(
        out_dir.join("machine.rs"),
        machine_rs(&machine, &machine_path),
    )
    .expect("cannot write machine.rs");

    // The tuning table: the environment's, the machine's, or the default.
    let tuning = from_env(TUNING_ENV).or_else(|| machine.tuning_table.clone());
    let rows = match &tuning {
        Some(path) => {
            println!("cargo:rerun-if-changed={}", path.display());
            parse_tuning(path).unwrap_or_else(|problem| fail(&[problem]))
        }
        None => {
            println!(
                "cargo:warning={}: no [controller].tuning_table and no {TUNING_ENV}: \
                 the controller's default offsets (90 right, 270 left) are compiled in",
                machine_path.display()
            );
            DEFAULT_ROWS.to_vec()
        }
    };
    fs::write(
        out_dir.join("tuning.rs"),
        tuning_rs(&rows, tuning.as_deref()),
    )
    .expect("cannot write tuning.rs");

    // Rebuild when the layout or this script changes (the files above too).
    println!("cargo:rerun-if-changed={}", memory_x.display());
    println!("cargo:rerun-if-changed=build.rs");
}

/// Print every problem and fail the build.
fn fail(problems: &[String]) -> ! {
    for p in problems {
        eprintln!("error: {p}");
    }
    std::process::exit(1);
}

/// One rotor's constants, as read (f64, cast to f32 in the generated code).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RotorValues {
    /// Winding resistance, ohm.
    pub resistance_ohm: f64,
    /// Torque constant, N m/A.
    pub torque_constant: f64,
    /// Inertia about the axis, eccentric mass included, kg m^2.
    pub inertia_kg_m2: f64,
    /// The largest torque holding the rotor back at low speed, N m: the eccentric's
    /// weight torque `m e g` plus the motor's Coulomb friction.
    pub load_torque_nm: f64,
}

/// What the firmware compiles in from a machine file: the fields of
/// `shared::controller::MachineConstants`, and the tuning table it names.
#[derive(Clone, Debug, PartialEq)]
pub struct MachineValues {
    /// Control rate, Hz.
    pub rate_hz: f64,
    /// Encoder counts per turn (x4).
    pub encoder_counts: u32,
    /// Supply voltage, V.
    pub supply_voltage_v: f64,
    /// The smaller of the two motors' current limits, A.
    pub current_limit_a: f64,
    /// Rotor 1, rotor 2.
    pub rotors: [RotorValues; 2],
    /// Resonance band, rpm, as f32 (computed in f64 and rounded as host-sim does).
    pub resonance_band_rpm: [f32; 2],
    /// `[drive].decay`: fast decay (`true`) or slow decay.
    pub fast_decay: bool,
    /// `[drive].pwm_hz`, Hz.
    pub pwm_hz: u32,
    /// `[controller].tuning_table`, resolved against the machine file's folder.
    pub tuning_table: Option<PathBuf>,
}

/// The problems found in one file, each `FILE: KEY: MESSAGE`.
struct Problems<'a> {
    file: &'a Path,
    list: Vec<String>,
}

impl Problems<'_> {
    fn at(&mut self, key: &str, message: impl std::fmt::Display) {
        self.list
            .push(format!("{}: {key}: {message}", self.file.display()));
    }
}

/// A value for a message: scalars as written, anything else by its type.
fn shown(v: &Value) -> String {
    match v {
        Value::Integer(i) => i.to_string(),
        Value::Float(x) => x.to_string(),
        Value::Boolean(b) => b.to_string(),
        Value::String(s) => format!("{s:?}"),
        other => other.type_str().to_string(),
    }
}

/// A finite number (TOML float or integer) at `key` of `table`, `default` when
/// absent (`None`: required), checked with `ok` (`what` says the range).
fn number(
    p: &mut Problems,
    table: &Table,
    path: &str,
    key: &str,
    default: Option<f64>,
    ok: impl Fn(f64) -> bool,
    what: &str,
) -> Option<f64> {
    let full = format!("{path}{key}");
    let x = match table.get(key) {
        None => match default {
            Some(d) => return Some(d),
            None => {
                p.at(&full, format!("missing: a number {what}"));
                return None;
            }
        },
        Some(Value::Float(x)) => *x,
        Some(Value::Integer(i)) => *i as f64,
        Some(other) => {
            p.at(
                &full,
                format!("must be a number {what} (got {})", shown(other)),
            );
            return None;
        }
    };
    if x.is_finite() && ok(x) {
        Some(x)
    } else {
        p.at(&full, format!("must be {what} (got {x})"));
        None
    }
}

/// The table at `key` of `table`: `Some(empty)` when absent and `optional`.
fn section<'t>(
    p: &mut Problems,
    table: &'t Table,
    key: &str,
    optional: bool,
    empty: &'t Table,
) -> Option<&'t Table> {
    match table.get(key) {
        Some(Value::Table(t)) => Some(t),
        None if optional => Some(empty),
        None => {
            p.at(&format!("[{key}]"), "missing: a table");
            None
        }
        Some(other) => {
            p.at(
                &format!("[{key}]"),
                format!("must be a table (got {})", other.type_str()),
            );
            None
        }
    }
}

/// Reads the keys of the machine file at `path` the firmware compiles in (module
/// documentation); every problem at once.
pub fn read_machine(path: &Path) -> Result<MachineValues, Vec<String>> {
    let text = fs::read_to_string(path).map_err(|e| {
        vec![format!(
            "{}: cannot read the machine file: {e} (set {MACHINE_ENV} to a machine file, \
             relative to firmware/ or absolute)",
            path.display()
        )]
    })?;
    let root: Table = text
        .parse()
        .map_err(|e| vec![format!("{}: TOML syntax: {e}", path.display())])?;
    let mut p = Problems {
        file: path,
        list: Vec::new(),
    };
    let empty = Table::new();
    let pos = |x: f64| x > 0.0;
    let non_neg = |x: f64| x >= 0.0;

    // [controller]
    let mut rate_hz = None;
    let mut tuning_table = None;
    if let Some(c) = section(&mut p, &root, "controller", true, &empty) {
        rate_hz = number(
            &mut p,
            c,
            "controller.",
            "rate_hz",
            Some(1000.0),
            |x| x > 0.0 && x <= MAX_RATE_HZ,
            "in (0, 100000] Hz",
        );
        match c.get("tuning_table") {
            None => {}
            Some(Value::String(s)) if !s.is_empty() => {
                let dir = path.parent().unwrap_or(Path::new(""));
                tuning_table = Some(dir.join(s));
            }
            Some(other) => p.at(
                "controller.tuning_table",
                format!(
                    "must be a non-empty file name relative to the machine file (got {})",
                    shown(other)
                ),
            ),
        }
    }

    // [sensors]
    let mut encoder_counts = None;
    if let Some(s) = section(&mut p, &root, "sensors", true, &empty) {
        encoder_counts = match s.get("encoder_counts") {
            None => Some(4096),
            Some(Value::Integer(c)) if (4..=MAX_ENCODER_COUNTS).contains(c) && c % 4 == 0 => {
                u32::try_from(*c).ok()
            }
            Some(other) => {
                p.at(
                    "sensors.encoder_counts",
                    format!(
                        "must be an integer multiple of 4 in [4, 2^24]: counts per turn after \
                         x4 decoding (got {})",
                        shown(other)
                    ),
                );
                None
            }
        };
    }

    // [drive]
    let mut supply = None;
    let mut fast_decay = Some(false);
    let mut pwm_hz = Some(DEFAULT_PWM_HZ);
    if let Some(d) = section(&mut p, &root, "drive", false, &empty) {
        supply = number(&mut p, d, "drive.", "supply_voltage", None, pos, "> 0 V");
        fast_decay = match d.get("decay") {
            None => Some(false),
            Some(Value::String(s)) if s == "slow" => Some(false),
            Some(Value::String(s)) if s == "fast" => Some(true),
            Some(other) => {
                p.at(
                    "drive.decay",
                    format!("must be one of slow, fast (got {})", shown(other)),
                );
                None
            }
        };
        pwm_hz = match d.get("pwm_hz") {
            None => Some(DEFAULT_PWM_HZ),
            Some(Value::Integer(f)) if (PWM_HZ_RANGE[0]..=PWM_HZ_RANGE[1]).contains(f) => {
                u32::try_from(*f).ok()
            }
            Some(other) => {
                p.at(
                    "drive.pwm_hz",
                    format!(
                        "must be an integer in [{}, {}] Hz (got {})",
                        PWM_HZ_RANGE[0],
                        PWM_HZ_RANGE[1],
                        shown(other)
                    ),
                );
                None
            }
        };
    }

    // [platform], [fundament]: the mass that moves and gravity (resonance band).
    let mass = section(&mut p, &root, "platform", false, &empty)
        .and_then(|s| number(&mut p, s, "platform.", "mass", None, pos, "> 0 kg"));
    let mut gravity = None;
    if let Some(f) = section(&mut p, &root, "fundament", true, &empty) {
        gravity = match f.get("gravity") {
            None => Some(DEFAULT_GRAVITY),
            Some(Value::Array(a)) if a.len() == 2 => {
                let g: Vec<f64> = a
                    .iter()
                    .filter_map(|v| match v {
                        Value::Float(x) if x.is_finite() => Some(*x),
                        Value::Integer(i) => Some(*i as f64),
                        _ => None,
                    })
                    .collect();
                if g.len() == 2 {
                    Some([g[0], g[1]])
                } else {
                    p.at("fundament.gravity", "must be two finite numbers [x, y]");
                    None
                }
            }
            Some(other) => {
                p.at(
                    "fundament.gravity",
                    format!(
                        "must be an array of two numbers [x, y] (got {})",
                        shown(other)
                    ),
                );
                None
            }
        };
    }

    // [motor] and the rotors' own [rotors.motor].
    const MOTOR_KEYS: [(&str, &str); 4] = [
        ("resistance", "> 0 ohm"),
        ("torque_constant", "> 0 N m / A"),
        ("current_limit", "> 0 A"),
        ("coulomb_friction", ">= 0 N m"),
    ];
    let motor = match root.get("motor") {
        None => Some(&empty),
        Some(Value::Table(t)) => Some(t),
        Some(other) => {
            p.at(
                "[motor]",
                format!("must be a table (got {})", other.type_str()),
            );
            None
        }
    };
    let rotor_tables: Vec<&Table> = match root.get("rotors") {
        Some(Value::Array(a)) => {
            let tables: Vec<&Table> = a.iter().filter_map(Value::as_table).collect();
            if tables.len() != 2 || a.len() != 2 {
                p.at(
                    "rotors",
                    format!(
                        "must be exactly two [[rotors]] tables (got {} entries)",
                        a.len()
                    ),
                );
            }
            tables
        }
        _ => {
            p.at("rotors", "missing: two [[rotors]] tables");
            Vec::new()
        }
    };
    let mut rotors = Vec::new();
    let mut limits = Vec::new();
    let mut eccentric = Vec::new();
    for (k, r) in rotor_tables.iter().take(2).enumerate() {
        let at = format!("rotors[{k}].");
        let m = number(&mut p, r, &at, "eccentric_mass", None, non_neg, ">= 0 kg");
        let e = number(&mut p, r, &at, "eccentricity", None, non_neg, ">= 0 m");
        let j = number(&mut p, r, &at, "inertia", None, pos, "> 0 kg m^2");
        if let (Some(m), Some(e)) = (m, e) {
            if m > 0.0 && e == 0.0 {
                p.at(
                    &format!("{at}eccentricity"),
                    "must be > 0 when eccentric_mass > 0",
                );
            }
        }
        let own = match r.get("motor") {
            None => Some(&empty),
            Some(Value::Table(t)) => Some(t),
            Some(other) => {
                p.at(
                    &format!("{at}motor"),
                    format!("must be a table (got {})", other.type_str()),
                );
                None
            }
        };
        // Each motor key: the rotor's own, else the machine's [motor].
        let mut values = [None; 4];
        if let (Some(own), Some(base)) = (own, motor) {
            for (slot, (key, what)) in values.iter_mut().zip(MOTOR_KEYS) {
                let ok = |x: f64| {
                    if key == "coulomb_friction" {
                        x >= 0.0
                    } else {
                        x > 0.0
                    }
                };
                *slot = if own.contains_key(key) {
                    number(&mut p, own, &format!("{at}motor."), key, None, ok, what)
                } else if base.contains_key(key) {
                    number(&mut p, base, "motor.", key, None, ok, what)
                } else {
                    p.at(
                        &format!("motor.{key}"),
                        format!(
                            "missing for rotor {k}: a number {what} in [motor] or [rotors.motor]"
                        ),
                    );
                    None
                };
            }
        }
        if let (Some(m), Some(e), Some(j), [Some(r), Some(kt), Some(limit), Some(friction)]) =
            (m, e, j, values)
        {
            rotors.push(RotorValues {
                resistance_ohm: r,
                torque_constant: kt,
                // The rotor with its eccentric mass, about its axis.
                inertia_kg_m2: j + m * e * e,
                // Set below, once gravity is known.
                load_torque_nm: friction,
            });
            limits.push(limit);
            eccentric.push((m, e));
        }
    }

    if !p.list.is_empty() {
        // A [motor] key is read for each rotor: say it once.
        let mut seen = Vec::new();
        p.list.retain(|m| {
            let new = !seen.contains(m);
            seen.push(m.clone());
            new
        });
        return Err(p.list);
    }
    let (
        Some(rate_hz),
        Some(encoder_counts),
        Some(supply_voltage_v),
        Some(fast_decay),
        Some(pwm_hz),
        Some(mass),
        Some(gravity),
        [r1, r2],
    ) = (
        rate_hz,
        encoder_counts,
        supply,
        fast_decay,
        pwm_hz,
        mass,
        gravity,
        rotors.as_slice(),
    )
    else {
        return Err(vec![format!("{}: incomplete machine file", path.display())]);
    };
    // The band the ramps hurry through, as host-sim computes it: around lift-off,
    // where the exciting force 2 m e w^2 equals the weight M g.
    let me = (eccentric[0].0 * eccentric[0].1 + eccentric[1].0 * eccentric[1].1) / 2.0;
    let g = (gravity[0].powi(2) + gravity[1].powi(2)).sqrt();
    // Load torque: the eccentric's weight torque (greatest with the eccentric
    // horizontal) plus the Coulomb friction read into the field above.
    let load = |k: usize, r: &RotorValues| RotorValues {
        load_torque_nm: eccentric[k].0 * eccentric[k].1 * g + r.load_torque_nm,
        ..*r
    };
    let total_mass = mass + (eccentric[0].0 + eccentric[1].0);
    let band = if me > 0.0 {
        let w = (total_mass * g / (2.0 * me)).sqrt();
        let rpm = w * 30.0 / std::f64::consts::PI;
        [(0.7 * rpm) as f32, (1.18 * rpm) as f32]
    } else {
        [0.0, 0.0]
    };
    Ok(MachineValues {
        rate_hz,
        encoder_counts,
        supply_voltage_v,
        current_limit_a: limits[0].min(limits[1]),
        rotors: [load(0, r1), load(1, r2)],
        resonance_band_rpm: band,
        fast_decay,
        pwm_hz,
        tuning_table,
    })
}

/// `OUT_DIR/machine.rs`: the `MACHINE` constant (and `MACHINE_FILE`, its source).
pub fn machine_rs(m: &MachineValues, path: &Path) -> String {
    let f = |x: f64| format!("{:?}", x as f32);
    let rotor = |r: &RotorValues| {
        format!(
            "        shared::controller::RotorModel {{\n            resistance_ohm: {},\n            \
             torque_constant: {},\n            inertia_kg_m2: {},\n            \
             load_torque_nm: {},\n        }},\n",
            f(r.resistance_ohm),
            f(r.torque_constant),
            f(r.inertia_kg_m2),
            f(r.load_torque_nm)
        )
    };
    let mut code = format!(
        "/// The machine file compiled in by build.rs (`{MACHINE_ENV}`).\n\
         #[allow(dead_code)]\n\
         pub const MACHINE_FILE: &str = {:?};\n\n\
         /// The controller's constants of the machine file compiled in by build.rs.\n\
         pub const MACHINE: shared::controller::MachineConstants = \
         shared::controller::MachineConstants {{\n",
        path.display().to_string()
    );
    code.push_str(&format!("    rate_hz: {},\n", f(m.rate_hz)));
    code.push_str(&format!("    encoder_counts: {},\n", m.encoder_counts));
    code.push_str(&format!(
        "    supply_voltage_v: {},\n",
        f(m.supply_voltage_v)
    ));
    code.push_str(&format!("    current_limit_a: {},\n", f(m.current_limit_a)));
    code.push_str("    rotors: [\n");
    code.push_str(&rotor(&m.rotors[0]));
    code.push_str(&rotor(&m.rotors[1]));
    code.push_str("    ],\n");
    code.push_str(&format!(
        "    resonance_band_rpm: [{:?}, {:?}],\n",
        m.resonance_band_rpm[0], m.resonance_band_rpm[1]
    ));
    code.push_str(&format!(
        "    bridge: shared::drive::BridgeConfig {{\n        decay: shared::drive::Decay::{},\n        \
         pwm_hz: {},\n    }},\n}};\n",
        if m.fast_decay { "Fast" } else { "Slow" },
        m.pwm_hz
    ));
    code
}

/// `OUT_DIR/tuning.rs`: the `TUNING_ROWS` constant.
fn tuning_rs(rows: &[(f32, f32, f32)], path: Option<&Path>) -> String {
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

/// The rows of the tuning file at `path`, checked as `TuningTable::from_rows`
/// checks them (1 to 32 rows, finite, speeds >= 0 and strictly increasing, offsets
/// in [0, 360]); the problem names the file and the line or row.
pub fn parse_tuning(path: &Path) -> Result<Vec<(f32, f32, f32)>, String> {
    let text = fs::read_to_string(path).map_err(|e| {
        format!(
            "{}: cannot read the tuning table: {e} (set {TUNING_ENV}, relative to firmware/ \
             or absolute, or the machine file's [controller].tuning_table)",
            path.display()
        )
    })?;
    // One row as it is read: the three keys, each set at most once.
    let mut rows: Vec<[Option<f32>; 3]> = Vec::new();
    for (n, raw) in text.lines().enumerate() {
        let line = raw.split('#').next().unwrap_or("").trim();
        let at = format!("{}:{}", path.display(), n + 1);
        if line.is_empty() {
            continue;
        }
        if line == "[[rows]]" {
            rows.push([None; 3]);
            continue;
        }
        let (key, value) = line
            .split_once('=')
            .ok_or_else(|| format!("{at}: expected `key = number` or `[[rows]]`"))?;
        let slot = match key.trim() {
            "speed_rpm" => 0,
            "right_offset_deg" => 1,
            "left_offset_deg" => 2,
            other => return Err(format!("{at}: unknown key `{other}`")),
        };
        let value: f32 = value
            .trim()
            .parse()
            .map_err(|e| format!("{at}: not a number: {e}"))?;
        let row = rows
            .last_mut()
            .ok_or_else(|| format!("{at}: key outside a [[rows]] table"))?;
        if row[slot].replace(value).is_some() {
            return Err(format!("{at}: key set twice in one row"));
        }
    }
    let file = path.display();
    let rows = rows
        .iter()
        .enumerate()
        .map(|(i, r)| match r {
            [Some(s), Some(a), Some(b)] => Ok((*s, *a, *b)),
            _ => Err(format!(
                "{file}: rows[{i}]: needs speed_rpm, right_offset_deg and left_offset_deg"
            )),
        })
        .collect::<Result<Vec<_>, _>>()?;
    if rows.is_empty() || rows.len() > MAX_TUNING_ROWS {
        return Err(format!(
            "{file}: rows: 1 to {MAX_TUNING_ROWS} [[rows]] tables (got {})",
            rows.len()
        ));
    }
    for (i, &(speed, right, left)) in rows.iter().enumerate() {
        if !(speed.is_finite() && speed >= 0.0) {
            return Err(format!(
                "{file}: rows[{i}].speed_rpm: must be >= 0 (got {speed})"
            ));
        }
        if i > 0 && speed <= rows[i - 1].0 {
            return Err(format!(
                "{file}: rows[{i}].speed_rpm: speeds must increase strictly (got {speed} after {})",
                rows[i - 1].0
            ));
        }
        for (key, o) in [("right_offset_deg", right), ("left_offset_deg", left)] {
            if !(0.0..=360.0).contains(&o) {
                return Err(format!(
                    "{file}: rows[{i}].{key}: must be in [0, 360] degrees (got {o})"
                ));
            }
        }
    }
    Ok(rows)
}
