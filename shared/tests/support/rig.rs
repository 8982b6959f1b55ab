//! The rotor rig of the controller tests: the reference machine's motor and rotor
//! (examples/vibro-driver.toml), its encoder and the control tick.

/// Winding resistance, ohm.
pub const R: f64 = 2.0;
/// Torque and back-EMF constant, N m/A.
pub const K: f64 = 0.02;
/// Supply, V.
pub const V: f64 = 12.0;
/// Rotor inertia, kg m^2.
pub const J: f64 = 1.0e-5;
/// Viscous friction, N m s/rad.
pub const B: f64 = 1.0e-6;
/// Coulomb friction torque, N m.
pub const TAU_C: f64 = 1.0e-3;
/// Current limit, A.
pub const I_MAX: f64 = 2.0;
/// Weight torque of the eccentric, `m g e`, N m.
pub const GRAVITY_TORQUE: f64 = 0.01 * 9.81 * 0.02;
/// Encoder counts per revolution.
pub const N: u32 = 4096;
/// Control tick, s.
pub const DT: f32 = 1.0e-3;
/// Integration substeps per tick.
pub const SUBSTEPS: usize = 20;
