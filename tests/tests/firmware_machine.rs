//! The machine the firmware compiles in is the machine host-sim simulates.
//!
//! `firmware/build.rs` reads the machine file and its tuning table with the
//! `machine-file` crate (host-sim's reader) and maps it with
//! `machine_file::machine_constants` (shared's formulas); what is left in it is glue:
//! the paths, the environment, the firmware's own checks and the generated code.
//! This test includes that build script as a module and checks the glue:
//! - the generated `machine.rs` reads back (its literals parsed as rustc parses them)
//!   as exactly the constants the crate computes, on the reference machine and on
//!   variants that change every value it carries;
//! - the reference machine gives `MachineConstants::REFERENCE`;
//! - the generated `tuning.rs` holds the rows the crate reads, or the controller's
//!   default offsets;
//! - the paths: `VIBRO_MACHINE` and `VIBRO_TUNING` relative to `firmware/`, a
//!   machine's table relative to the machine file;
//! - a machine file with problems fails the build with every problem, each naming
//!   the file and the key, as host-sim prints them; and what only the firmware
//!   refuses (another control rate, constants its controller refuses) too.

use std::ffi::OsString;
use std::fs;
use std::path::{Path, PathBuf};

use machine_file::input::render;
use machine_file::{machine_constants, tuning_file, Machine};
use shared::controller::{MachineConstants, RotorCount, RotorModel, TuningTable, MAX_TUNING_ROWS};
use shared::drive::{BridgeConfig, Decay};

#[allow(dead_code)]
#[path = "../../firmware/build.rs"]
mod firmware_build;

use firmware_build::{
    load_machine, machine_path, machine_rs, tuning_path, tuning_rows, tuning_rs, Row,
};

/// The repository's root.
fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The firmware's folder, where cargo runs its build script.
fn firmware_dir() -> PathBuf {
    root().join("firmware")
}

/// The reference machine file.
fn reference_file() -> PathBuf {
    root().join("examples/vibro-driver.toml")
}

/// A scratch copy of the reference machine with `edits` (text replacements, each
/// must match) applied, written under the target directory (one file per name).
fn variant(name: &str, edits: &[(&str, &str)]) -> PathBuf {
    let mut text = fs::read_to_string(reference_file()).expect("reference machine");
    for (from, to) in edits {
        assert!(
            text.contains(from),
            "{name}: `{from}` not in the reference file"
        );
        text = text.replacen(from, to, 1);
    }
    scratch(&format!("{name}.toml"), &text)
}

/// `text` written to the scratch file `name`.
fn scratch(name: &str, text: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("firmware_machine");
    tests::scratch_file(&dir, name, text)
}

/// The `KEY: VALUE` pairs of generated code, in order, each value as written
/// (a trailing comma dropped).
fn fields(code: &str) -> Vec<(String, String)> {
    code.lines()
        .filter_map(|line| {
            let (key, value) = line.trim().split_once(": ")?;
            let value = value.strip_suffix(',')?;
            Some((key.to_string(), value.to_string()))
        })
        .collect()
}

/// A float literal of generated code, read as rustc reads it (correctly rounded).
fn float(literal: &str) -> f32 {
    literal
        .parse()
        .unwrap_or_else(|e| panic!("`{literal}`: {e}"))
}

/// What the generated `MACHINE` holds: its literals read back, field by field.
fn read_back(code: &str) -> MachineConstants {
    let fields = fields(code);
    let one = |key: &str| -> &str {
        let mut found = fields.iter().filter(|(k, _)| k == key);
        let (_, value) = found
            .next()
            .unwrap_or_else(|| panic!("no {key} in\n{code}"));
        assert!(found.next().is_none(), "{key} twice in\n{code}");
        value
    };
    let per_rotor = |key: &str| -> [f32; 2] {
        let values: Vec<f32> = fields
            .iter()
            .filter(|(k, _)| k == key)
            .map(|(_, v)| float(v))
            .collect();
        values
            .try_into()
            .unwrap_or_else(|_| panic!("{key}: not two in\n{code}"))
    };
    let [resistance, torque_constant, inertia, load] = [
        "resistance_ohm",
        "torque_constant",
        "inertia_kg_m2",
        "load_torque_nm",
    ]
    .map(per_rotor);
    let rotor = |k: usize| RotorModel {
        resistance_ohm: resistance[k],
        torque_constant: torque_constant[k],
        inertia_kg_m2: inertia[k],
        load_torque_nm: load[k],
    };
    let band: Vec<f32> = one("resonance_band_rpm")
        .trim_matches(['[', ']'])
        .split(", ")
        .map(float)
        .collect();
    let decay = match one("decay") {
        "shared::drive::Decay::Slow" => Decay::Slow,
        "shared::drive::Decay::Fast" => Decay::Fast,
        other => panic!("decay `{other}`"),
    };
    let rotor_count = match one("rotor_count") {
        "shared::controller::RotorCount::One" => RotorCount::One,
        "shared::controller::RotorCount::Two" => RotorCount::Two,
        other => panic!("rotor_count `{other}`"),
    };
    MachineConstants {
        rate_hz: float(one("rate_hz")),
        encoder_counts: one("encoder_counts").parse().unwrap(),
        supply_voltage_v: float(one("supply_voltage_v")),
        current_limit_a: float(one("current_limit_a")),
        rotor_count,
        rotors: [rotor(0), rotor(1)],
        resonance_band_rpm: [band[0], band[1]],
        bridge: BridgeConfig {
            decay,
            pwm_hz: one("pwm_hz").parse().unwrap(),
        },
    }
}

/// The rows of generated `TUNING_ROWS`, read back.
fn read_back_rows(code: &str) -> Vec<Row> {
    code.lines()
        .filter_map(|line| line.trim().strip_prefix('(')?.strip_suffix("),"))
        .map(|row| {
            let v: Vec<f32> = row.split(", ").map(float).collect();
            (v[0], v[1], v[2])
        })
        .collect()
}

#[test]
fn generated_machine_reads_back_as_the_crates_constants() {
    let cases: [(&str, &[(&str, &str)]); 6] = [
        ("reference", &[]),
        (
            "fast_decay",
            // The bridge wired for fast decay at 10 kHz.
            &[
                ("decay = \"slow\"", "decay = \"fast\""),
                ("pwm_hz = 20000", "pwm_hz = 10000"),
            ],
        ),
        (
            "own_motor",
            // Rotor 2 with its own winding and a lower current limit.
            &[(
                "index_angle = 0.0               # rad\n",
                "index_angle = 0.0\n[rotors.motor]\nresistance = 3.5\ntorque_constant = 0.025\ncurrent_limit = 1.5\ncoulomb_friction = 2.0e-3\n",
            )],
        ),
        (
            "gravity_counts_supply",
            &[
                ("gravity = [0.0, -9.81]", "gravity = [-1.0, -9.7]"),
                ("encoder_counts = 4096", "encoder_counts = 2048"),
                ("supply_voltage = 12.0", "supply_voltage = 24"),
            ],
        ),
        (
            "no_eccentric",
            &[
                ("eccentric_mass = 0.01           # kg: a 10 g", "eccentric_mass = 0.0 # "),
                ("eccentric_mass = 0.01           # kg\n", "eccentric_mass = 0.0\n"),
            ],
        ),
        (
            "heavy",
            &[
                ("mass = 2.0                      # kg", "mass = 5.5"),
                ("eccentricity = 0.02             # m: its", "eccentricity = 0.03 # "),
            ],
        ),
    ];
    for (name, edits) in cases {
        let path = variant(name, edits);
        // The generated code for every machine the crate reads (the firmware's own
        // refusals, fast decay among them, are checked below).
        let machine =
            Machine::load(&path, &[]).unwrap_or_else(|p| panic!("{name}: {}", render(&p)));
        let constants = machine_constants(&machine);
        let code = machine_rs(&constants, &path);
        assert_eq!(read_back(&code), constants, "{name}:\n{code}");
        assert!(
            code.contains(&format!(
                "pub const MACHINE_FILE: &str = {:?};",
                path.display().to_string()
            )),
            "{name}"
        );
    }
}

#[test]
fn reference_machine_is_the_reference_constants() {
    let machine = load_machine(&reference_file()).unwrap();
    let constants = machine_constants(&machine);
    let reference = MachineConstants::REFERENCE;
    // Everything but the resonance band exactly.
    assert_eq!(
        MachineConstants {
            resonance_band_rpm: reference.resonance_band_rpm,
            ..constants
        },
        reference
    );
    // The band: REFERENCE rounds the file's 0.7 and 1.18 x the 2125 rpm lift-off
    // (1488 and 2508 rpm) to 1500 and 2500.
    for (got, want) in constants
        .resonance_band_rpm
        .iter()
        .zip(reference.resonance_band_rpm)
    {
        assert!((got - want).abs() <= 0.01 * want, "band {got} vs {want}");
    }
}

#[test]
fn one_rotor_machine_builds_with_one_rotor() {
    // The firmware takes a one-rotor machine: its constants say so, and the
    // generated code carries it (the controller then drives motor 1 alone and
    // `drive.rs` leaves motor 2's bridge off).
    let path = root().join("tests/fixtures/one-rotor-machine.toml");
    let machine = load_machine(&path).unwrap_or_else(|p| panic!("{}", render(&p)));
    let constants = machine_constants(&machine);
    assert_eq!(constants.rotor_count, RotorCount::One);
    let code = machine_rs(&constants, &path);
    assert!(
        code.contains("    rotor_count: shared::controller::RotorCount::One,\n"),
        "{code}"
    );
    assert_eq!(read_back(&code), constants, "{code}");
    // The reference machine: two.
    let two = machine_constants(&load_machine(&reference_file()).unwrap());
    assert_eq!(two.rotor_count, RotorCount::Two);
}

#[test]
fn generated_tuning_rows_are_the_crates() {
    let machine = load_machine(&reference_file()).unwrap();
    // The machine's table, relative to the machine file.
    let path = tuning_path(&firmware_dir(), None, &machine).expect("the machine names a table");
    assert_eq!(
        fs::canonicalize(&path).unwrap(),
        fs::canonicalize(root().join("examples/vibro-driver.tuning.toml")).unwrap()
    );
    let rows = tuning_rows(Some(&path)).unwrap();
    let read: Vec<Row> = tuning_file::read(&path)
        .unwrap()
        .iter()
        .map(|&(s, r, l)| (s as f32, r as f32, l as f32))
        .collect();
    assert_eq!(rows, read);
    let code = tuning_rs(&rows, Some(&path));
    assert_eq!(read_back_rows(&code), rows, "{code}");
    assert!(code.contains(&format!("[(f32, f32, f32); {}]", rows.len())));
    // The controller takes them as host-sim does.
    assert_eq!(
        TuningTable::<MAX_TUNING_ROWS>::from_rows(&rows),
        tuning_file::table(&tuning_file::read(&path).unwrap())
    );
    // Without a table: the controller's default offsets.
    let default = tuning_rows(None).unwrap();
    assert_eq!(
        TuningTable::<MAX_TUNING_ROWS>::from_rows(&default).unwrap(),
        TuningTable::default()
    );
    let code = tuning_rs(&default, None);
    assert_eq!(read_back_rows(&code), default, "{code}");
    assert!(code.contains("the controller's default offsets"), "{code}");
}

#[test]
fn paths_are_relative_to_the_firmware_and_the_machine_file() {
    let dir = firmware_dir();
    // The default machine, and an unset or empty variable.
    for value in [None, Some(OsString::new())] {
        assert_eq!(
            machine_path(&dir, value),
            dir.join("../examples/vibro-driver.toml")
        );
    }
    // Relative to firmware/, or absolute.
    assert_eq!(
        machine_path(&dir, Some("my.toml".into())),
        dir.join("my.toml")
    );
    assert_eq!(
        machine_path(&dir, Some("/abs/my.toml".into())),
        PathBuf::from("/abs/my.toml")
    );
    // VIBRO_TUNING wins over the machine's table; without either, none.
    let mut machine = load_machine(&reference_file()).unwrap();
    assert_eq!(
        tuning_path(&dir, Some("t.toml".into()), &machine),
        Some(dir.join("t.toml"))
    );
    machine.controller.tuning_table = None;
    assert_eq!(tuning_path(&dir, Some(OsString::new()), &machine), None);
}

#[test]
fn mistakes_fail_the_build_naming_the_file_and_the_key() {
    // Every problem at once, each as host-sim prints it.
    let path = variant(
        "bad",
        &[
            ("encoder_counts = 4096", "encoder_counts = 4098"),
            ("torque_constant = 0.02", "torque_constant = \"0.02\""),
            ("supply_voltage = 12.0", "supply_voltage = -12.0"),
            ("decay = \"slow\"", "decay = \"medium\""),
            (
                "mass = 2.0                      # kg",
                "mass = 2.0\nmas = 1",
            ),
        ],
    );
    let problems = load_machine(&path).unwrap_err();
    assert_eq!(
        render(&problems),
        render(&Machine::load(&path, &[]).unwrap_err())
    );
    let file = path.display().to_string();
    for key in [
        "platform.mas",
        "motor.torque_constant",
        "drive.supply_voltage",
        "drive.decay",
        "sensors.encoder_counts",
    ] {
        let start = format!("error: {file}: {key}: ");
        assert!(
            render(&problems).lines().any(|l| l.starts_with(&start)),
            "{key} not named in\n{}",
            render(&problems)
        );
    }

    // Only the firmware refuses: another control rate, and constants its
    // controller refuses (host-sim takes any multiple of 4 counts; the controller
    // at most 2^24).
    let rate = variant("rate", &[("rate_hz = 1000", "rate_hz = 2000")]);
    let p = render(&load_machine(&rate).unwrap_err());
    assert!(
        p.starts_with(&format!(
            "error: {}: controller.rate_hz: must be 1000 Hz",
            rate.display()
        )),
        "{p}"
    );
    let counts = variant(
        "counts",
        &[("encoder_counts = 4096", "encoder_counts = 33554432")],
    );
    assert!(Machine::load(&counts, &[]).is_ok());
    let p = render(&load_machine(&counts).unwrap_err());
    assert!(
        p.starts_with(&format!("error: {}: ", counts.display())) && p.contains("encoder_counts"),
        "{p}"
    );

    // Several bodies: read and checked, but the constants are a single platform's.
    let text = std::fs::read_to_string(reference_file()).unwrap()
        + "\n[[bodies]]\nname = \"element\"\nmass = 0.05\ninertia = 2e-5\nposition = [0.1, 0.2]\n";
    let bodies = scratch("bodies.toml", &text);
    assert!(Machine::load(&bodies, &[]).is_ok());
    let p = render(&load_machine(&bodies).unwrap_err());
    assert!(
        p.starts_with(&format!("error: {}: several bodies", bodies.display())),
        "{p}"
    );

    // Fast decay: host-sim simulates it, the board's current sampling does not
    // follow it.
    let fast = variant("fast", &[("decay = \"slow\"", "decay = \"fast\"")]);
    assert!(Machine::load(&fast, &[]).is_ok());
    let p = render(&load_machine(&fast).unwrap_err());
    assert!(
        p.starts_with(&format!(
            "error: {}: drive.decay: must be \"slow\"",
            fast.display()
        )),
        "{p}"
    );

    // A machine file that is not there, a bad tuning table.
    let missing = render(&load_machine(&root().join("examples/no-such-machine.toml")).unwrap_err());
    assert!(
        missing.contains("no-such-machine.toml: cannot read the file"),
        "{missing}"
    );
    let table = scratch(
        "bad.tuning.toml",
        "[[rows]]\nspeed_rpm = 3000\nright_offset_deg = 90\nleft_ofset_deg = 270\n",
    );
    let p = render(&tuning_rows(Some(&table)).unwrap_err());
    assert!(
        p.contains(&format!(
            "error: {}: rows[0].left_ofset_deg: unknown key",
            table.display()
        )),
        "{p}"
    );
}
