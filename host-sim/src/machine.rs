//! The machine file (`../shared/spec/machine.md`): the vibro driver that host-sim
//! simulates, checked into plain values. All positions are world coordinates at
//! `t = 0`, SI units, radians.

use std::path::PathBuf;

use shared::impact::ImpactLaw;

/// The obstacle line the platform strikes, and gravity.
#[derive(Clone, Debug, PartialEq)]
pub struct Fundament {
    /// A point of the line, m.
    pub point: [f64; 2],
    /// Unit normal, from the fundament towards the platform.
    pub normal: [f64; 2],
    /// Gravity, m/s^2.
    pub gravity: [f64; 2],
}

/// The moving platform, without the rotors' eccentric masses.
#[derive(Clone, Debug, PartialEq)]
pub struct Platform {
    /// Mass, kg.
    pub mass: f64,
    /// Moment of inertia about its centre of mass, kg m^2.
    pub inertia: f64,
    /// Centre of mass at t = 0, m.
    pub position: [f64; 2],
    /// Angle at t = 0, rad.
    pub angle: f64,
    /// Velocity of the centre of mass at t = 0, m/s.
    pub velocity: [f64; 2],
    /// Angular velocity at t = 0, rad/s.
    pub angular_velocity: f64,
}

/// A point of the platform that strikes the fundament.
#[derive(Clone, Debug, PartialEq)]
pub struct MachineContact {
    /// Name (K1, K2, ...).
    pub name: String,
    /// World position at t = 0, m.
    pub point: [f64; 2],
    /// Restitution coefficient of the impact law, in [0, 1].
    pub restitution: f64,
    /// Coulomb friction coefficient, >= 0.
    pub friction: f64,
    /// Relative stiffness, > 0.
    pub weight: f64,
}

/// The sense a rotor turns when driven forward.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Sense {
    /// Counter-clockwise: `s = +1`.
    Ccw,
    /// Clockwise: `s = -1`.
    Cw,
}

impl Sense {
    /// `+1` for ccw, `-1` for cw.
    pub fn sign(self) -> f64 {
        match self {
            Sense::Ccw => 1.0,
            Sense::Cw => -1.0,
        }
    }
}

/// A brushed DC motor.
#[derive(Clone, Debug, PartialEq)]
pub struct MotorParams {
    /// Winding resistance, ohm.
    pub resistance: f64,
    /// Winding inductance, H.
    pub inductance: f64,
    /// Torque constant, N m / A (= back-EMF constant, V s / rad).
    pub torque_constant: f64,
    /// Coulomb friction torque, N m.
    pub coulomb_friction: f64,
    /// Viscous friction, N m s.
    pub viscous_friction: f64,
    /// The driver's current limit, A (the winding current stays within +-this).
    pub current_limit: f64,
}

/// An unbalance rotor on the platform.
#[derive(Clone, Debug, PartialEq)]
pub struct Rotor {
    /// Name.
    pub name: String,
    /// World position of the axis at t = 0, m (fixed on the platform).
    pub axis: [f64; 2],
    /// Eccentric mass, kg (0 allowed).
    pub eccentric_mass: f64,
    /// Distance of the eccentric mass from the axis, m.
    pub eccentricity: f64,
    /// Inertia about the axis without the eccentric mass, kg m^2.
    pub inertia: f64,
    /// The sense it turns when driven forward.
    pub sense: Sense,
    /// Eccentric angle phi in the platform frame at t = 0, rad.
    pub angle: f64,
    /// Eccentric angle at which the index pulse fires, rad.
    pub index_angle: f64,
    /// Its motor (the machine's `[motor]` unless the rotor has its own).
    pub motor: MotorParams,
}

/// The motor driver.
#[derive(Clone, Debug, PartialEq)]
pub struct Drive {
    /// Supply voltage, V; duty d in [-1, 1] puts d x supply on the winding.
    pub supply_voltage: f64,
}

/// The sensors.
#[derive(Clone, Debug, PartialEq)]
pub struct Sensors {
    /// Counter increments per revolution (after x4 decoding).
    pub encoder_counts: u32,
    /// Standard deviation of the current measurement noise, A.
    pub current_noise: f64,
    /// Standard deviation of the encoder edge timing jitter, s.
    pub encoder_jitter: f64,
}

/// The controller's settings.
#[derive(Clone, Debug, PartialEq)]
pub struct ControllerSettings {
    /// Control tick, Hz (the firmware uses the same value).
    pub rate_hz: f64,
    /// Default rotor speed for `--command`, rpm.
    pub speed_rpm: f64,
    /// The tuning table file, resolved relative to the machine file.
    pub tuning_table: Option<PathBuf>,
}

/// The simulation's settings.
#[derive(Clone, Debug, PartialEq)]
pub struct Simulation {
    /// End time, s.
    pub t_end: f64,
    /// Time between rows of `--out`, s.
    pub output_step: f64,
    /// Seed of every noise source.
    pub seed: u64,
}

/// A checked machine file.
#[derive(Clone, Debug, PartialEq)]
pub struct Machine {
    /// The fundament and gravity.
    pub fundament: Fundament,
    /// The platform.
    pub platform: Platform,
    /// The contact points, K1, K2, ...
    pub contacts: Vec<MachineContact>,
    /// Rotor 1, then rotor 2.
    pub rotors: [Rotor; 2],
    /// The motor driver.
    pub drive: Drive,
    /// The sensors.
    pub sensors: Sensors,
    /// The controller's settings.
    pub controller: ControllerSettings,
    /// The impact law.
    pub law: ImpactLaw,
    /// The simulation's settings.
    pub simulation: Simulation,
}
