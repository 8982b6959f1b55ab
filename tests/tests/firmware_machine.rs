//! The machine the firmware compiles in is the machine host-sim simulates.
//!
//! `firmware/build.rs` reads the machine file (`VIBRO_MACHINE`, default
//! `examples/vibro-driver.toml`) with its own small reader (the firmware does not
//! depend on host-sim) and writes `MachineConstants` into the firmware. This test
//! includes that build script as a module and checks, on the reference machine and
//! on variants that exercise every key it reads (a rotor's own `[rotors.motor]`,
//! other gravity, rate, counts, supply, no eccentric masses), that its values are
//! exactly host-sim's `closed_loop::machine_constants` of the same file: the
//! firmware runs the controller with the parameters `host-sim run` and
//! `host-sim tune` used. It also checks the reference against
//! `MachineConstants::REFERENCE`, the tuning-table reading against host-sim's, and
//! that mistakes name the file and the key.

use std::fs;
use std::path::{Path, PathBuf};

use host_sim::machine::machine_constants;
use host_sim::machine::Machine;
use shared::controller::{MachineConstants, RotorModel, TuningTable, MAX_TUNING_ROWS};
use shared::drive::{BridgeConfig, Decay};

#[allow(dead_code)]
#[path = "../../firmware/build.rs"]
mod firmware_build;

use firmware_build::{machine_rs, parse_tuning, read_machine, MachineValues};

/// The repository's root.
fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The reference machine file.
fn reference_file() -> PathBuf {
    root().join("examples/vibro-driver.toml")
}

/// What the firmware's generated `MACHINE` holds for `v` (the build script writes
/// each value as the shortest `f32` literal, which reads back as the same `f32`).
fn constants(v: &MachineValues) -> MachineConstants {
    let rotor = |k: usize| RotorModel {
        resistance_ohm: v.rotors[k].resistance_ohm as f32,
        torque_constant: v.rotors[k].torque_constant as f32,
        inertia_kg_m2: v.rotors[k].inertia_kg_m2 as f32,
        load_torque_nm: v.rotors[k].load_torque_nm as f32,
    };
    MachineConstants {
        rate_hz: v.rate_hz as f32,
        encoder_counts: v.encoder_counts,
        supply_voltage_v: v.supply_voltage_v as f32,
        current_limit_a: v.current_limit_a as f32,
        rotors: [rotor(0), rotor(1)],
        resonance_band_rpm: v.resonance_band_rpm,
        bridge: BridgeConfig {
            decay: if v.fast_decay {
                Decay::Fast
            } else {
                Decay::Slow
            },
            pwm_hz: v.pwm_hz,
        },
    }
}

/// Both readers on the machine file at `path`: (firmware, host-sim).
fn both(path: &Path) -> (MachineConstants, MachineConstants) {
    let firmware = read_machine(path).unwrap_or_else(|e| panic!("firmware reader: {e:?}"));
    let machine = Machine::load(path, &[]).unwrap_or_else(|e| panic!("host-sim reader: {e:?}"));
    (constants(&firmware), machine_constants(&machine))
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
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("firmware_machine");
    fs::create_dir_all(&dir).expect("scratch folder");
    let path = dir.join(format!("{name}.toml"));
    fs::write(&path, text).expect("scratch machine file");
    path
}

#[test]
fn build_script_constants_are_shareds_and_host_sims() {
    assert_eq!(
        firmware_build::FIRMWARE_RATE_HZ as f32,
        shared::controller::CONTROL_RATE_HZ
    );
    assert_eq!(
        firmware_build::MAX_ENCODER_COUNTS,
        i64::from(shared::controller::params::MAX_ENCODER_COUNTS)
    );
    assert_eq!(firmware_build::MAX_RATE_HZ, host_sim::machine::MAX_RATE_HZ);
    assert_eq!(
        firmware_build::DEFAULT_GRAVITY,
        host_sim::machine::DEFAULT_GRAVITY
    );
    assert_eq!(firmware_build::DEFAULT_PWM_HZ, BridgeConfig::DEFAULT.pwm_hz);
    assert_eq!(
        firmware_build::PWM_HZ_RANGE.map(|f| f as u32),
        host_sim::machine::PWM_HZ_RANGE
    );
}

#[test]
fn reference_machine_is_host_sims() {
    let (firmware, host) = both(&reference_file());
    assert_eq!(firmware, host);
}

#[test]
fn reference_machine_is_the_reference_constants() {
    let firmware = constants(&read_machine(&reference_file()).unwrap());
    let reference = MachineConstants::REFERENCE;
    // Everything but the resonance band exactly.
    assert_eq!(
        MachineConstants {
            resonance_band_rpm: reference.resonance_band_rpm,
            ..firmware
        },
        reference
    );
    // The band: REFERENCE rounds the file's 0.7 and 1.18 x the 2125 rpm lift-off
    // (1488 and 2508 rpm) to 1500 and 2500.
    for (got, want) in firmware
        .resonance_band_rpm
        .iter()
        .zip(reference.resonance_band_rpm)
    {
        assert!((got - want).abs() <= 0.01 * want, "band {got} vs {want}");
    }
}

#[test]
fn variants_are_host_sims() {
    let cases: [(&str, &[(&str, &str)]); 6] = [
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
            "gravity_rate_counts",
            &[
                ("gravity = [0.0, -9.81]", "gravity = [-1.0, -9.7]"),
                ("rate_hz = 1000", "rate_hz = 2000"),
                ("encoder_counts = 4096", "encoder_counts = 2048"),
                ("supply_voltage = 12.0", "supply_voltage = 24"),
            ],
        ),
        (
            "defaults",
            // No [fundament] gravity, no rate, no counts: the defaults.
            &[
                ("gravity = [0.0, -9.81]", ""),
                ("rate_hz = 1000", ""),
                ("encoder_counts = 4096", ""),
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
        let (firmware, host) = both(&path);
        assert_eq!(firmware, host, "{name}");
    }
}

#[test]
fn generated_code_holds_the_values() {
    let values = read_machine(&reference_file()).unwrap();
    let code = machine_rs(&values, &reference_file());
    let c = constants(&values);
    for line in [
        format!("rate_hz: {:?},", c.rate_hz),
        format!("encoder_counts: {},", c.encoder_counts),
        format!("supply_voltage_v: {:?},", c.supply_voltage_v),
        format!("current_limit_a: {:?},", c.current_limit_a),
        format!("inertia_kg_m2: {:?},", c.rotors[0].inertia_kg_m2),
        format!("load_torque_nm: {:?},", c.rotors[0].load_torque_nm),
        format!(
            "resonance_band_rpm: [{:?}, {:?}],",
            c.resonance_band_rpm[0], c.resonance_band_rpm[1]
        ),
    ] {
        assert!(code.contains(&line), "`{line}` not in\n{code}");
    }
}

#[test]
fn tuning_table_is_host_sims() {
    let path = root().join("examples/vibro-driver.tuning.toml");
    let firmware = parse_tuning(&path).unwrap();
    let host: Vec<(f32, f32, f32)> = host_sim::machine::tuning_file::read(&path)
        .unwrap()
        .iter()
        .map(|&(s, r, l)| (s as f32, r as f32, l as f32))
        .collect();
    assert_eq!(firmware, host);
    assert_eq!(firmware_build::MAX_TUNING_ROWS, MAX_TUNING_ROWS);
    assert!(TuningTable::<MAX_TUNING_ROWS>::from_rows(&firmware).is_ok());
    // The machine names this table.
    let machine = read_machine(&reference_file()).unwrap();
    assert_eq!(
        machine.tuning_table.map(|p| fs::canonicalize(p).unwrap()),
        Some(fs::canonicalize(&path).unwrap())
    );
    // Without a table the firmware gets the controller's default, as host-sim.
    assert_eq!(
        TuningTable::<MAX_TUNING_ROWS>::from_rows(&firmware_build::DEFAULT_ROWS).unwrap(),
        TuningTable::default()
    );
}

#[test]
fn mistakes_name_the_file_and_the_key() {
    let path = variant(
        "bad",
        &[
            ("encoder_counts = 4096", "encoder_counts = 4098"),
            ("torque_constant = 0.02", "torque_constant = \"0.02\""),
            ("supply_voltage = 12.0", "supply_voltage = -12.0"),
            ("decay = \"slow\"", "decay = \"medium\""),
            ("pwm_hz = 20000", "pwm_hz = 500"),
        ],
    );
    let problems = read_machine(&path).unwrap_err();
    let file = path.display().to_string();
    for key in [
        "drive.decay",
        "drive.pwm_hz",
        "drive.supply_voltage",
        "sensors.encoder_counts",
        "motor.torque_constant",
    ] {
        assert!(
            problems
                .iter()
                .any(|p| p.starts_with(&file) && p.contains(key)),
            "{key} not named in {problems:?}"
        );
    }
    let missing = read_machine(&root().join("examples/no-such-machine.toml")).unwrap_err();
    assert!(missing[0].contains("no-such-machine.toml") && missing[0].contains("VIBRO_MACHINE"));
}
