//! The hidden truth of the bench tests: the example machine with motors 10 to
//! 30 % off its file's, the two unlike, as a machine file a `device-sim
//! --machine` runs while its firmware is built for the example
//! (`cli_device_identify.rs`, `cli_calibrate_capture.rs`).

use std::path::PathBuf;

use host_sim::output::machine_edit::with_values;

/// One rotor's motor as it really is.
pub struct TrueMotor {
    pub resistance: f64,
    pub torque_constant: f64,
    pub coulomb_friction: f64,
    pub viscous_friction: f64,
    /// The rotor's inertia without the eccentric, kg m^2 (the file's convention).
    pub inertia: f64,
}

impl TrueMotor {
    /// Its values in the order of [`KEYS`].
    pub fn values(&self) -> [f64; 5] {
        [
            self.resistance,
            self.torque_constant,
            self.coulomb_friction,
            self.viscous_friction,
            self.inertia,
        ]
    }
}

/// A rotor's keys, as the machine file (below `rotors[N]`) and `calibrate --fit`
/// name them, in the order of [`TrueMotor::values`].
pub const KEYS: [&str; 5] = [
    "motor.resistance",
    "motor.torque_constant",
    "motor.coulomb_friction",
    "motor.viscous_friction",
    "inertia",
];

/// The example's rotors with motors 10 to 30 % off its `[motor]` (2 ohm,
/// 0.02 N m/A, 1e-3 N m, 1e-6 N m s) and inertias off its 6e-6 kg m^2, the two
/// unlike.
pub const TRUTH: [TrueMotor; 2] = [
    TrueMotor {
        resistance: 1.6,
        torque_constant: 0.023,
        coulomb_friction: 1.3e-3,
        viscous_friction: 0.8e-6,
        inertia: 7.5e-6,
    },
    TrueMotor {
        resistance: 2.4,
        torque_constant: 0.017,
        coulomb_friction: 0.8e-3,
        viscous_friction: 1.2e-6,
        inertia: 5.0e-6,
    },
];

/// The truth's machine file, in the scratch directory of `tag`: the example
/// with each rotor's own motor and inertia, every comment kept.
pub fn truth_file(tag: &str) -> PathBuf {
    let example = super::machine();
    let text = std::fs::read_to_string(&example).unwrap();
    let mut values = Vec::new();
    for (k, t) in TRUTH.iter().enumerate() {
        for (key, x) in KEYS.iter().zip(t.values()) {
            values.push((format!("rotors[{k}].{key}"), x));
        }
    }
    let path = super::scratch(tag, "truth.toml");
    let written = with_values(&example, &text, &values, &path).unwrap();
    std::fs::write(&path, written).unwrap();
    path
}
