//! From the machine's physical values to the constants the controller needs: the one
//! mapping to [`MachineConstants`] that host-sim (`machine_file::machine_constants`)
//! and the firmware's build script both call, so the firmware runs the controller
//! with the constants the simulator tuned it with.
//!
//! The values are the machine file's (docs/machine-file.md), SI units, in `f64`: the
//! host computes them and each constant is rounded to `f32` once, at the end.
//!
//! | constant | formula |
//! | --- | --- |
//! | rotor inertia `J` | `J_r + m e^2`: the rotor and its eccentric mass about the axis |
//! | load torque | `m e g + T_c`: the eccentric's weight torque (greatest with the eccentric horizontal) plus the motor's Coulomb friction |
//! | current limit | the smaller of the two motors' |
//! | resonance band | [`RESONANCE_BAND_LOW`] to [`RESONANCE_BAND_HIGH`] times the lift-off speed `w_0 = sqrt(M g / (2 m e))` |
//!
//! with `m`, `e` a rotor's eccentric mass and eccentricity, `J_r` its inertia without
//! the eccentric mass, `g = |gravity|`, `M` the platform with both eccentric masses.
//!
//! A machine with one rotor ([`RotorCount::One`]): its rotor 2 is not there. `M`
//! has rotor 1's eccentric mass alone, the exciting force is `m e w^2` (half a
//! pair's: [`MachinePhysics::unbalance_kg_m`] is `m e / 2`), the current limit is
//! rotor 1's, and the constants' rotor 2 repeats rotor 1's model (unused by the
//! controller, [`super::Params::from_machine`]).

use core::f64::consts::PI;

use crate::drive::BridgeConfig;

use super::params::{MachineConstants, RotorCount, RotorModel};

/// The low end of the resonance band, times the lift-off speed: the exciting force
/// `~ w^2` is then `0.7^2 = 0.49` of the weight, about where the rigid platform
/// starts to chatter with partial lift-offs.
pub const RESONANCE_BAND_LOW: f64 = 0.7;

/// The high end of the resonance band, times the lift-off speed: the exciting force
/// is `1.18^2 = 1.39` times the weight, about where the chattering ends and the
/// platform leaves the floor every turn.
pub const RESONANCE_BAND_HIGH: f64 = 1.18;

/// One rotor and its motor, as the machine file gives them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RotorPhysics {
    /// Winding resistance `R`, ohm.
    pub resistance_ohm: f64,
    /// Torque constant `k`, N m/A (= back-EMF constant, V s/rad).
    pub torque_constant: f64,
    /// Inertia `J_r` about the axis, without the eccentric mass, kg m^2.
    pub inertia_kg_m2: f64,
    /// Eccentric mass `m`, kg (0 for a plain rotor).
    pub eccentric_mass_kg: f64,
    /// Eccentricity `e`: distance of the eccentric mass from the axis, m.
    pub eccentricity_m: f64,
    /// Coulomb friction torque `T_c` of the motor, N m.
    pub coulomb_friction_nm: f64,
    /// The driver's current limit, A.
    pub current_limit_a: f64,
}

/// The machine as the controller's constants depend on it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MachinePhysics {
    /// Control rate, Hz.
    pub rate_hz: f64,
    /// Encoder counts per turn after x4 decoding.
    pub encoder_counts: u32,
    /// Nominal supply voltage, V.
    pub supply_voltage_v: f64,
    /// Mass of the platform without the rotors' eccentric masses, kg.
    pub platform_mass_kg: f64,
    /// Gravity, m/s^2 (a vector in the plane; its magnitude `g` counts).
    pub gravity_m_s2: [f64; 2],
    /// One rotor or two.
    pub rotor_count: RotorCount,
    /// Rotor 1 and rotor 2; with [`RotorCount::One`] rotor 2's entry is ignored.
    pub rotors: [RotorPhysics; 2],
    /// The H-bridges as wired.
    pub bridge: BridgeConfig,
}

impl RotorModel {
    /// The controller's model of a rotor under gravity `g` (m/s^2, a magnitude):
    ///
    /// ```text
    ///   J      = J_r + m e^2        (the eccentric mass about the axis)
    ///   T_load = m e g + T_c        (its weight torque, eccentric horizontal,
    ///                                plus the motor's Coulomb friction)
    /// ```
    pub fn from_physics(r: &RotorPhysics, g: f64) -> RotorModel {
        let (m, e) = (r.eccentric_mass_kg, r.eccentricity_m);
        RotorModel {
            resistance_ohm: r.resistance_ohm as f32,
            torque_constant: r.torque_constant as f32,
            inertia_kg_m2: (r.inertia_kg_m2 + m * e * e) as f32,
            load_torque_nm: (m * e * g + r.coulomb_friction_nm) as f32,
        }
    }
}

/// The lift-off speed, rad/s: where the exciting force of the two rotors,
/// `2 m e w^2`, equals the weight `M g` of all that moves,
///
/// ```text
///   w_0 = sqrt(M g / (2 m e))
/// ```
///
/// with `M` the total mass, kg, `g` gravity's magnitude, m/s^2, and `m e` the rotors'
/// mean unbalance, kg m (> 0).
pub fn lift_off_speed_rad_s(total_mass_kg: f64, g: f64, unbalance_kg_m: f64) -> f64 {
    libm::sqrt(total_mass_kg * g / (2.0 * unbalance_kg_m))
}

/// The resonance band, rpm: `RESONANCE_BAND_LOW` to `RESONANCE_BAND_HIGH` times
/// the lift-off speed ([`lift_off_speed_rad_s`]); `[0, 0]` (none) without an
/// unbalance (`m e = 0`: nothing shakes the platform).
pub fn resonance_band_rpm(total_mass_kg: f64, g: f64, unbalance_kg_m: f64) -> [f32; 2] {
    if unbalance_kg_m > 0.0 {
        // rad/s to rpm: 60 / (2 pi).
        let rpm = lift_off_speed_rad_s(total_mass_kg, g, unbalance_kg_m) * 30.0 / PI;
        [
            (RESONANCE_BAND_LOW * rpm) as f32,
            (RESONANCE_BAND_HIGH * rpm) as f32,
        ]
    } else {
        [0.0, 0.0]
    }
}

impl MachinePhysics {
    /// Gravity's magnitude `g = |gravity|`, m/s^2.
    pub fn gravity(&self) -> f64 {
        let [x, y] = self.gravity_m_s2;
        libm::sqrt(x * x + y * y)
    }

    /// All that moves, kg: the platform and the eccentric masses (both, or rotor
    /// 1's on a one-rotor machine).
    pub fn total_mass_kg(&self) -> f64 {
        match self.rotor_count {
            RotorCount::Two => {
                self.platform_mass_kg
                    + (self.rotors[0].eccentric_mass_kg + self.rotors[1].eccentric_mass_kg)
            }
            RotorCount::One => self.platform_mass_kg + self.rotors[0].eccentric_mass_kg,
        }
    }

    /// The unbalance `m e` per rotor of the pair whose exciting force `2 m e w^2`
    /// is the machine's, kg m: the rotors' mean `(m_1 e_1 + m_2 e_2) / 2`; on a
    /// one-rotor machine `m_1 e_1 / 2`, its force being `m_1 e_1 w^2`.
    pub fn unbalance_kg_m(&self) -> f64 {
        let me = |r: &RotorPhysics| r.eccentric_mass_kg * r.eccentricity_m;
        match self.rotor_count {
            RotorCount::Two => (me(&self.rotors[0]) + me(&self.rotors[1])) / 2.0,
            RotorCount::One => me(&self.rotors[0]) / 2.0,
        }
    }
}

impl MachineConstants {
    /// The controller's constants of a machine (the module documentation's table):
    /// rate, counts, supply and bridge as given; each rotor by
    /// [`RotorModel::from_physics`]; the smaller current limit; the resonance band
    /// by [`resonance_band_rpm`]. On a one-rotor machine rotor 1 stands in for
    /// rotor 2 (module documentation).
    pub fn from_physics(p: &MachinePhysics) -> MachineConstants {
        let g = p.gravity();
        let r1 = &p.rotors[0];
        let r2 = match p.rotor_count {
            RotorCount::Two => &p.rotors[1],
            RotorCount::One => r1,
        };
        MachineConstants {
            rate_hz: p.rate_hz as f32,
            encoder_counts: p.encoder_counts,
            supply_voltage_v: p.supply_voltage_v as f32,
            // The driver limits both windings; the controller plans with the weaker.
            current_limit_a: r1.current_limit_a.min(r2.current_limit_a) as f32,
            rotor_count: p.rotor_count,
            rotors: [
                RotorModel::from_physics(r1, g),
                RotorModel::from_physics(r2, g),
            ],
            resonance_band_rpm: resonance_band_rpm(p.total_mass_kg(), g, p.unbalance_kg_m()),
            bridge: p.bridge,
        }
    }
}
