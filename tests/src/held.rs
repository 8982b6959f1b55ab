//! The reference machine (`examples/vibro-driver.toml`) with its rotors held at a
//! constant speed and phase offset: the plant alone, without controller or motors,
//! the setting of the plant's travel references.
//!
//! The offset is `theta_1 - theta_2 = phi_1 + phi_2` (docs/machine-file.md,
//! "Conventions", with index angles 0 and rotor 2 clockwise); rotor 1 starts hanging
//! down (`phi_1 = -90` degrees) and rotor 2 at `offset - phi_1`, the platform at rest
//! on both feet.

use std::f64::consts::{FRAC_PI_2, PI};

use crate::machine::TestMachine;

use host_sim::machine::Machine;
use host_sim::plant::model::PlantModel;
use host_sim::plant::simulator::{Holds, Plant, Settings};

/// The reference machine with `sets` (`--set` overrides), its rotors started at
/// the phase offset `offset_deg`.
pub fn reference_machine(offset_deg: f64, sets: &[String]) -> Machine {
    let phi1 = -FRAC_PI_2;
    let phi2 = offset_deg.to_radians() - phi1;
    TestMachine::example()
        .set("rotors.0.angle", phi1)
        .set("rotors.1.angle", phi2)
        .sets(sets)
        .machine()
}

/// The plant of `m` with its rotors held at `rpm` (rotor 1 counter-clockwise,
/// rotor 2 clockwise) and the platform at rest, with `settings`.
pub fn held_rotors(m: &Machine, rpm: f64, settings: Settings) -> Plant {
    let holds = Holds {
        rotors: true,
        ..Holds::default()
    };
    held_plant(m, rpm, settings, holds)
}

/// The plant of `m` with its rotors turning at `rpm` (rotor 1 counter-clockwise,
/// rotor 2 clockwise) and the platform at rest, with `settings` and `holds`.
pub fn held_plant(m: &Machine, rpm: f64, settings: Settings, holds: Holds) -> Plant {
    let w = rpm * PI / 30.0;
    let model = PlantModel::new(m);
    let mut y = model.initial_state(m);
    // Each rotor's phi' (wherever the machine's coordinates put it).
    for (rotor, speed) in model.rotors.iter().zip([w, -w]) {
        y[model.dof + rotor.phi] = speed;
    }
    Plant::new(model, y, settings, holds)
}

/// The mean velocity of the platform's centre of mass from `t0` to `t1`,
/// `(x(t1) - x(t0)) / (t1 - t0)`, m/s, advancing `plant` to `t1`.
pub fn mean_velocity(plant: &mut Plant, t0: f64, t1: f64) -> f64 {
    plant.advance_to(t0, &mut |_| {}).unwrap();
    let x0 = plant.platform_motion()[0];
    plant.advance_to(t1, &mut |_| {}).unwrap();
    (plant.platform_motion()[0] - x0) / (t1 - t0)
}
