//! The rotor rig of the controller tests: the reference machine's motor and rotor
//! (examples/vibro-driver.toml), its encoder and the control tick, and one rotor's
//! model ([`Rotor`]).

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

/// One rotor of the rig.
#[derive(Clone, Copy, Debug)]
pub struct Rotor {
    /// Encoder angle `theta`, rad (driven sense), not wrapped.
    pub theta: f64,
    /// Speed, rad/s.
    pub omega: f64,
    /// Winding current, A.
    pub current: f64,
    /// Constant load torque, N m.
    pub disturbance: f64,
    /// Phase of the eccentric's weight torque, rad.
    pub gravity_phase: f64,
    /// Held at rest (a jammed rotor).
    pub blocked: bool,
}

impl Rotor {
    pub fn new(theta: f64) -> Self {
        Rotor {
            theta,
            omega: 0.0,
            current: 0.0,
            disturbance: 0.0,
            gravity_phase: 0.0,
            blocked: false,
        }
    }

    /// Advance by `h` s with duty `d` (driver enabled or not).
    pub fn advance(&mut self, duty: f64, enable: bool, h: f64) {
        let drive = if enable {
            ((duty * V - K * self.omega) / R).clamp(-I_MAX, I_MAX)
        } else {
            0.0
        };
        self.current = drive;
        if self.blocked {
            self.omega = 0.0;
            return;
        }
        // Coulomb friction smoothed over 1 rad/s so that rest is reachable.
        let friction = TAU_C * (self.omega / 1.0).clamp(-1.0, 1.0);
        let gravity = GRAVITY_TORQUE * (self.theta + self.gravity_phase).cos();
        let torque = K * drive - B * self.omega - friction - gravity - self.disturbance;
        self.omega += torque / J * h;
        self.theta += self.omega * h;
    }
}
