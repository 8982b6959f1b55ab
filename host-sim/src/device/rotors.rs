//! The device simulator's two rotors: a DC motor each (resistance, torque
//! constant), the rotor's inertia with its eccentric mass, viscous and dry
//! friction, no platform (the rotors do not feel each other). Enough for the
//! controller to start, run, hold a phase offset and stop as on the bench with
//! the platform lifted; `host-sim run` has the whole machine.
//!
//! Sensors as the board sees them: quadrature encoders (x4 counts, wrapping 32-bit
//! counters, zero at power-on), an index pulse at every turn (the count latched
//! there), the winding currents, the supply voltage.

use std::f64::consts::TAU;

use shared::controller::{MachineConstants, Outputs};

use super::mechanics::Mechanics;
use crate::simulation::board::Readings;

/// Integration sub-steps per control tick.
const SUBSTEPS: u32 = 20;

/// One rotor.
#[derive(Clone, Copy, Debug)]
struct Rotor {
    /// Angle in the driven sense since power-on, rad, plus the start angle.
    angle: f64,
    /// Speed, rad/s.
    speed: f64,
    /// Winding current, A.
    current: f64,
}

/// Both rotors and their motors.
#[derive(Clone, Debug)]
pub struct Rotors {
    rotors: [Rotor; 2],
    /// Angle at power-on, rad (the encoder counter reads 0 there).
    start: [f64; 2],
    resistance: f64,
    torque_constant: f64,
    inertia: f64,
    /// Viscous friction, N m s/rad.
    viscous: f64,
    /// Dry friction, N m.
    dry: f64,
    supply: f64,
    counts: u32,
}

impl Rotors {
    /// At rest, rotor 1 at 30 degrees past its index, rotor 2 at 200 degrees, for
    /// the motors and encoders of `m` (rotor 1's motor for both).
    pub fn new(m: &MachineConstants) -> Rotors {
        let r = &m.rotors[0];
        let start = [30f64.to_radians(), 200f64.to_radians()];
        Rotors {
            rotors: start.map(|a| Rotor {
                angle: a,
                speed: 0.0,
                current: 0.0,
            }),
            start,
            resistance: f64::from(r.resistance_ohm),
            torque_constant: f64::from(r.torque_constant),
            inertia: f64::from(r.inertia_kg_m2),
            // 0.3 mN m at 3000 rpm, 0.2 mN m dry: a few percent of the motor's.
            viscous: 1.0e-6,
            dry: 2.0e-4,
            supply: f64::from(m.supply_voltage_v),
            counts: m.encoder_counts,
        }
    }

    /// The supply voltage, V.
    pub fn supply(&self) -> f32 {
        self.supply as f32
    }

    /// The encoder counters.
    pub fn counts(&self) -> [u32; 2] {
        [0, 1].map(|k| self.count_at(k, self.rotors[k].angle))
    }

    /// The counter of rotor `k` at `angle`.
    fn count_at(&self, k: usize, angle: f64) -> u32 {
        let c = ((angle - self.start[k]) / TAU * f64::from(self.counts)).floor();
        (c as i64) as u32
    }

    /// The winding currents, A.
    pub fn currents(&self) -> [f32; 2] {
        self.rotors.map(|r| r.current as f32)
    }

    /// Speeds, rpm.
    pub fn speeds_rpm(&self) -> [f64; 2] {
        self.rotors.map(|r| r.speed * 60.0 / TAU)
    }

    /// Advance `dt` s with the controller's `out` on the windings (open windings
    /// when it disables the driver); the counts latched at index pulses on the way.
    pub fn advance(&mut self, out: Option<&Outputs>, dt: f64) -> [Option<u32>; 2] {
        let h = dt / f64::from(SUBSTEPS);
        let mut index = [None; 2];
        for (k, latched) in index.iter_mut().enumerate() {
            let duty = match out {
                Some(o) if o.bridges[k] => f64::from(o.duty[k]).clamp(-1.0, 1.0),
                _ => f64::NAN,
            };
            for _ in 0..SUBSTEPS {
                let r = self.rotors[k];
                // The inductance's time constant (L/R ~ 0.1 ms) is below a
                // sub-step: the current follows the voltage at once.
                let current = if duty.is_nan() {
                    0.0
                } else {
                    (duty * self.supply - self.torque_constant * r.speed) / self.resistance
                };
                let drive = self.torque_constant * current - self.viscous * r.speed;
                let torque = if r.speed.abs() > 1e-3 {
                    drive - self.dry * r.speed.signum()
                } else if drive.abs() <= self.dry {
                    // Stuck: dry friction holds it.
                    -r.speed * self.inertia / h
                } else {
                    drive - self.dry * drive.signum()
                };
                let speed = r.speed + torque / self.inertia * h;
                let angle = r.angle + 0.5 * (r.speed + speed) * h;
                // An index pulse at every whole turn crossed (driven sense).
                let (before, after) = ((r.angle / TAU).floor(), (angle / TAU).floor());
                if before != after {
                    let turn = before.max(after);
                    *latched = Some(self.count_at(k, turn * TAU));
                }
                self.rotors[k] = Rotor {
                    angle,
                    speed,
                    current,
                };
            }
        }
        index
    }
}

impl Mechanics for Rotors {
    fn advance(&mut self, out: Option<&Outputs>, dt: f64) -> Readings {
        let index = Rotors::advance(self, out, dt);
        Readings {
            encoder: self.counts(),
            index,
            current: self.currents(),
        }
    }

    fn supply(&self) -> f32 {
        Rotors::supply(self)
    }

    fn speeds_rpm(&self) -> [f64; 2] {
        Rotors::speeds_rpm(self)
    }
}
