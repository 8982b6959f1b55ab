//! The machines the tests write, built one way: a machine file's text from
//! named parts (a shipped file, tables the test writes, the common motor and
//! drive below) with `--set` changes, read and checked by the machine reader as a
//! user's file is. A file the reader refuses fails the test with every problem
//! and the whole text.

use std::fmt::Display;
use std::path::{Path, PathBuf};

use host_sim::machine::input::render;
use host_sim::machine::Machine;

/// A 12 V motor without friction: resistance 2 ohm, inductance 0.5 mH, torque
/// constant 0.02 N m/A, current limit 2 A.
pub const FRICTIONLESS_MOTOR: &str = "
[motor]
resistance = 2.0
inductance = 0.5e-3
torque_constant = 0.02
coulomb_friction = 0.0
viscous_friction = 0.0
current_limit = 2.0
";

/// [`FRICTIONLESS_MOTOR`] with the reference machine's friction: Coulomb
/// 1e-3 N m and viscous 1e-6 N m s, between the rotor and the body carrying it.
pub const REFERENCE_MOTOR: &str = "
[motor]
resistance = 2.0
inductance = 0.5e-3
torque_constant = 0.02
coulomb_friction = 1.0e-3
viscous_friction = 1.0e-6
current_limit = 2.0
";

/// A 12 V supply.
pub const DRIVE_12V: &str = "
[drive]
supply_voltage = 12.0
";

/// A machine file a test builds: its name (for messages), its text, the folder
/// its relative paths are read from, and `--set` changes.
#[derive(Clone, Debug)]
pub struct TestMachine {
    name: String,
    text: String,
    dir: PathBuf,
    sets: Vec<String>,
}

impl TestMachine {
    /// An empty file named `name`.
    pub fn new(name: &str) -> Self {
        TestMachine {
            name: name.to_string(),
            text: String::new(),
            dir: PathBuf::from(env!("CARGO_MANIFEST_DIR")),
            sets: Vec::new(),
        }
    }

    /// The shipped reference machine (`examples/vibro-driver.toml`), its tuning
    /// table read beside it.
    pub fn example() -> Self {
        TestMachine::file("examples/vibro-driver.toml")
    }

    /// The shipped machine file `path` (relative to the repository's root),
    /// its relative paths read beside it.
    pub fn file(path: &str) -> Self {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(path);
        let text =
            std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        TestMachine {
            name: path.display().to_string(),
            text,
            dir: path.parent().expect("its folder").to_path_buf(),
            sets: Vec::new(),
        }
    }

    /// With the text `from` replaced by `to` (a change `--set` cannot make, such
    /// as a table renamed); `from` must be there.
    pub fn replace(mut self, from: &str, to: &str) -> Self {
        assert!(self.text.contains(from), "{from:?} not in {}", self.name);
        self.text = self.text.replace(from, to);
        self
    }

    /// With the TOML `part` (tables) appended.
    pub fn with(mut self, part: &str) -> Self {
        self.text.push_str(part);
        if !self.text.ends_with('\n') {
            self.text.push('\n');
        }
        self
    }

    /// With `--set key=value` (the value as `Display` writes it).
    pub fn set(mut self, key: &str, value: impl Display) -> Self {
        self.sets.push(format!("{key}={value}"));
        self
    }

    /// With the `--set KEY=VALUE` changes `sets`, in order.
    pub fn sets(mut self, sets: &[String]) -> Self {
        self.sets.extend_from_slice(sets);
        self
    }

    /// The machine file's text.
    pub fn text(&self) -> &str {
        &self.text
    }

    /// The machine, read and checked; a refused file fails the test with its
    /// problems and its text.
    pub fn machine(&self) -> Machine {
        Machine::from_text(&self.name, &self.text, &self.dir, &self.sets).unwrap_or_else(|p| {
            panic!(
                "the test machine {} is refused:\n{}--set {:?}\n{}",
                self.name,
                render(&p),
                self.sets,
                self.text
            )
        })
    }
}
