//! Motor identifications for the tests of their bytes: one per `k`, rotor 1
//! measured, rotor 2 short of a whole turn.

use shared::controller::identify::{Estimate, Identity, RotorIdentity, Shortfall};

/// An identification that differs with `k`: every value finite, every standard
/// error 1 % of its value.
pub fn identity(k: u32) -> Identity {
    let e = |v: f32| {
        let value = v * (1.0 + k as f32 / 100.0);
        Estimate {
            value,
            std_error: value.abs() / 100.0,
        }
    };
    Identity {
        rotors: [
            RotorIdentity {
                shortfall: None,
                resistance_ohm: e(2.0),
                torque_constant: e(0.02),
                coulomb_friction_nm: e(1e-3),
                viscous_friction: e(1e-6),
                inertia_kg_m2: e(1e-5),
                offset_v: e(-0.001),
                drop_v: e(0.002),
                voltage_residual_v: 1e-4,
                friction_residual_nm: 1e-7,
                standstill_levels: 4,
                speed_levels: 4,
            },
            RotorIdentity::short(Shortfall::NoTurn),
        ],
        rotors_run: 2,
    }
}
