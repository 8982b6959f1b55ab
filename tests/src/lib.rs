//! Integration tests live in `tests/tests/`; this library holds what several of
//! them share.

#![forbid(unsafe_code)]

pub mod held;
pub mod impact_oscillator;
pub mod machine;
pub mod moreau_jean;
pub mod rig;
pub mod two_bodies;

use std::path::{Path, PathBuf};

use host_sim::machine::Machine;
use host_sim::plant::model::PlantModel;
use host_sim::plant::motor::Winding;
use host_sim::plant::simulator::{Holds, Plant, Settings};
use rand::rngs::ChaCha8Rng;
use rand::{Rng as _, SeedableRng};

/// The state of `m` at `t = 0` (its model's [`PlantModel::initial_state`]).
pub fn initial_state(m: &Machine) -> [f64; host_sim::plant::model::NY] {
    PlantModel::new(m).initial_state(m)
}

/// The plant of `m` at its start state with the default settings, nothing held
/// and both windings open: a mechanism left to its own motion (no motor torque),
/// as the Painleve tests take it.
pub fn unpowered_plant(m: &Machine) -> Plant {
    let model = PlantModel::new(m);
    let y0 = model.initial_state(m);
    let mut plant = Plant::new(model, y0, Settings::default(), Holds::default());
    plant.set_winding([Winding::Open, Winding::Open]);
    plant
}

/// `text` written to the file `name` in the folder `dir` (created if missing), for
/// a test that hands a file to a reader: a test passes its
/// `env!("CARGO_TARGET_TMPDIR")` joined with a folder of its own.
pub fn scratch_file(dir: &Path, name: &str, text: &str) -> PathBuf {
    std::fs::create_dir_all(dir).expect("scratch folder");
    let path = dir.join(name);
    std::fs::write(&path, text).expect("scratch file");
    path
}

/// The random parameter sets' generator: ChaCha8 from a seed, the generator of
/// the simulator's sensor noise, so that the cases are the same on every run and
/// every machine.
pub struct Rng(ChaCha8Rng);

impl Rng {
    /// A generator from `seed`.
    pub fn new(seed: u64) -> Self {
        Rng(ChaCha8Rng::seed_from_u64(seed))
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0.next_u64()
    }

    /// Uniform in [lo, hi).
    pub fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        let unit = (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
        lo + (hi - lo) * unit
    }
}
