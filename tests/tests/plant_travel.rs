//! Travel of the reference machine with its rotors forced at constant speed
//! (3000 rpm, counter-rotating) and a fixed phase offset: the plant alone, no
//! controller.
//!
//! - The Zeno criterion does not change results: halving or doubling its
//!   threshold leaves the mean velocity within 1 % (it closes only the
//!   accumulation tails of landings, whose remaining flight it accounts for).
//! - Mirror symmetry: the reference platform is mirror-symmetric about its
//!   vertical centre line, and mirroring the machine maps the offset `d` to
//!   `360 - d` (the spec's convention: the exciting force's line at `d/2` from +x
//!   mirrors to `180 - d/2`) and `x` to `-x`. So `v(360 - d) = -v(d)`, and the
//!   vertical-force offset 180 degrees gives no travel.
//! - The spec's convention for the direction: near 90 degrees the force pushes
//!   up-and-right then down-and-left, and the platform travels right.

use std::f64::consts::{FRAC_PI_2, PI};
use std::path::Path;

use host_sim::machine::Machine;
use host_sim::plant::model::{initial_state, PlantModel};
use host_sim::plant::simulator::{Holds, Plant, Settings};

/// Mean velocity `(x(T) - x(T/2)) / (T/2)` of the reference machine with the
/// rotors forced at 3000 rpm and phase offset `offset_deg`, m/s.
fn mean_velocity(offset_deg: f64, t_end: f64, settings: Settings) -> f64 {
    // Offset = theta_1 - theta_2 = phi_1 + phi_2 (rotor 2 turns cw, index angles 0).
    let phi1 = -FRAC_PI_2;
    let phi2 = offset_deg.to_radians() - phi1;
    let sets = [
        format!("rotors.0.angle={phi1}"),
        format!("rotors.1.angle={phi2}"),
    ];
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/vibro-driver.toml");
    let m = Machine::load(&path, &sets).expect("reference machine");
    let w = 3000.0 * PI / 30.0;
    let mut y = initial_state(&m);
    y[8] = w;
    y[9] = -w;
    let holds = Holds {
        platform: false,
        rotors: true,
        ..Holds::default()
    };
    let mut plant = Plant::new(PlantModel::new(&m), y, settings, holds);
    plant.advance_to(t_end / 2.0, &mut |_| {});
    let x_half = plant.q()[0];
    plant.advance_to(t_end, &mut |_| {});
    (plant.q()[0] - x_half) / (t_end / 2.0)
}

#[test]
fn zeno_threshold_does_not_change_the_mean_velocity() {
    let base = Settings::default();
    let v1 = mean_velocity(90.0, 4.0, base);
    assert!(v1.abs() > 1e-3, "the machine travels: {v1} m/s");
    for factor in [0.5, 2.0] {
        let s = Settings {
            zeno_velocity: base.zeno_velocity * factor,
            ..base
        };
        let v = mean_velocity(90.0, 4.0, s);
        assert!(
            (v - v1).abs() <= 0.01 * v1.abs(),
            "zeno_velocity x{factor}: {v} m/s vs {v1} m/s"
        );
    }
}

#[test]
fn travel_is_mirror_antisymmetric_in_the_offset() {
    let s = Settings::default();
    for d in [60.0, 90.0, 120.0] {
        let v = mean_velocity(d, 4.0, s);
        let mirrored = mean_velocity(360.0 - d, 4.0, s);
        assert!(
            (v + mirrored).abs() <= 0.01 * v.abs().max(1e-3),
            "v({d}) = {v}, v({}) = {mirrored}",
            360.0 - d
        );
    }
    // Near 90 degrees the platform travels right (spec convention).
    assert!(mean_velocity(90.0, 4.0, s) > 0.0);
    // The vertical-force offset: no travel beyond rounding of a symmetric motion.
    let v180 = mean_velocity(180.0, 4.0, s);
    assert!(v180.abs() < 1e-9, "v(180) = {v180}");
}
