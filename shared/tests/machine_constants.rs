//! The machine's physical values to the controller's constants
//! (`shared/src/controller/machine.rs`), against values worked out by hand from the
//! formulas: the reference machine (`examples/vibro-driver.toml`), and the edge
//! cases of the resonance band.

use shared::controller::{
    lift_off_speed_rad_s, resonance_band_rpm, MachineConstants, MachinePhysics, RotorCount,
    RotorModel, RotorPhysics,
};
use shared::drive::BridgeConfig;

/// The reference machine's rotor and motor: `R = 2 ohm`, `k = 0.02 N m/A`,
/// `J_r = 6e-6 kg m^2`, a 10 g eccentric at 20 mm, `T_c = 1e-3 N m`, 2 A.
const ROTOR: RotorPhysics = RotorPhysics {
    resistance_ohm: 2.0,
    torque_constant: 0.02,
    inertia_kg_m2: 6.0e-6,
    eccentric_mass_kg: 0.01,
    eccentricity_m: 0.02,
    coulomb_friction_nm: 1.0e-3,
    current_limit_a: 2.0,
};

/// The reference machine: a 2 kg platform, 1 kHz, 4096 counts, 12 V.
fn reference() -> MachinePhysics {
    MachinePhysics {
        rate_hz: 1000.0,
        encoder_counts: 4096,
        supply_voltage_v: 12.0,
        platform_mass_kg: 2.0,
        gravity_m_s2: [0.0, -9.81],
        rotor_count: RotorCount::Two,
        rotors: [ROTOR; 2],
        bridge: BridgeConfig::DEFAULT,
    }
}

fn close(got: f64, want: f64, rel: f64) -> bool {
    (got - want).abs() <= rel * want.abs()
}

#[test]
fn reference_machine_gives_the_reference_constants() {
    let c = MachineConstants::from_physics(&reference());
    // J = 6e-6 + 0.01 x 0.02^2 = 1e-5; load = 0.01 x 0.02 x 9.81 + 1e-3 = 2.962e-3.
    let want = MachineConstants::REFERENCE;
    assert_eq!(
        MachineConstants {
            resonance_band_rpm: want.resonance_band_rpm,
            ..c
        },
        want
    );
    // Lift-off: M = 2.02 kg, sqrt(2.02 x 9.81 / (2 x 2e-4)) = 222.577 rad/s, 2125.45
    // rpm; the band 0.7 and 1.18 times it (REFERENCE rounds to 1500 and 2500).
    let w0 = lift_off_speed_rad_s(2.02, 9.81, 2.0e-4);
    assert!(close(w0, 222.577, 1e-5), "{w0}");
    let [lo, hi] = c.resonance_band_rpm;
    assert!(close(f64::from(lo), 0.7 * 2125.45, 1e-5), "{lo}");
    assert!(close(f64::from(hi), 1.18 * 2125.45, 1e-5), "{hi}");
}

#[test]
fn each_rotor_its_own_model_and_the_smaller_current_limit() {
    let mut m = reference();
    // Rotor 2: no eccentric, its own winding, a lower limit; gravity tilted, |g| = 5.
    m.rotors[1] = RotorPhysics {
        resistance_ohm: 3.5,
        eccentric_mass_kg: 0.0,
        current_limit_a: 1.5,
        ..ROTOR
    };
    m.gravity_m_s2 = [3.0, -4.0];
    let c = MachineConstants::from_physics(&m);
    assert_eq!(c.current_limit_a, 1.5);
    assert_eq!(
        c.rotors[1],
        RotorModel {
            resistance_ohm: 3.5,
            torque_constant: 0.02,
            inertia_kg_m2: 6.0e-6,
            load_torque_nm: 1.0e-3,
        }
    );
    assert!(close(
        f64::from(c.rotors[0].load_torque_nm),
        0.01 * 0.02 * 5.0 + 1.0e-3,
        1e-6
    ));
    // The mean unbalance halves: m e = 1e-4 kg m, M = 2.01 kg.
    let rpm = (2.01 * 5.0 / 2.0e-4_f64).sqrt() * 60.0 / std::f64::consts::TAU;
    assert!(close(f64::from(c.resonance_band_rpm[0]), 0.7 * rpm, 1e-6));
}

#[test]
fn no_unbalance_no_band() {
    assert_eq!(resonance_band_rpm(2.0, 9.81, 0.0), [0.0, 0.0]);
    let mut m = reference();
    for r in &mut m.rotors {
        r.eccentric_mass_kg = 0.0;
    }
    let c = MachineConstants::from_physics(&m);
    assert_eq!(c.resonance_band_rpm, [0.0, 0.0]);
    assert_eq!(c.rotors[0].inertia_kg_m2, 6.0e-6);
}

#[test]
fn one_rotor_counts_rotor_1_alone() {
    // Rotor 2's values are there but not the machine's: a 0.1 A limit, a 0 ohm
    // winding, a 1 kg eccentric. None of them may show.
    let mut m = reference();
    m.rotor_count = RotorCount::One;
    m.rotors[1] = RotorPhysics {
        resistance_ohm: 0.0,
        eccentric_mass_kg: 1.0,
        current_limit_a: 0.1,
        ..ROTOR
    };
    assert_eq!(m.total_mass_kg(), 2.01);
    let c = MachineConstants::from_physics(&m);
    assert_eq!(c.rotor_count, RotorCount::One);
    assert_eq!(c.current_limit_a, 2.0);
    assert_eq!(c.rotors[1], c.rotors[0]);
    assert_eq!(
        c.rotors[0],
        MachineConstants::from_physics(&reference()).rotors[0]
    );
    // One eccentric: its force m e w^2 = 2e-4 w^2 lifts M g = 2.01 x 9.81 at
    // w0 = sqrt(2.01 x 9.81 / 2e-4) = 314.0 rad/s, 2998.5 rpm (the pair of the
    // reference machine lifts off at 2125 rpm).
    let rpm = (2.01 * 9.81 / 2.0e-4_f64).sqrt() * 60.0 / std::f64::consts::TAU;
    assert!(close(rpm, 2998.5, 1e-4), "{rpm}");
    let [lo, hi] = c.resonance_band_rpm;
    assert!(close(f64::from(lo), 0.7 * rpm, 1e-6), "{lo}");
    assert!(close(f64::from(hi), 1.18 * rpm, 1e-6), "{hi}");
    // The controller's parameters: rotor 1's, rotor 2 a copy; valid.
    let p = shared::controller::Params::from_machine(&c);
    assert_eq!(p.rotor_count, RotorCount::One);
    assert_eq!(p.speed_gains[1], p.speed_gains[0]);
    assert_eq!(p.validate(), Ok(()));
}
