//! A small model of the two rotors and their encoders, standing in for the board's
//! sensors and H-bridges in the `qemu` binaries.
//!
//! Each rotor is a brushed DC motor with an inertia, at the reference machine's
//! constants ([`MachineConstants::REFERENCE`]: `R = 2 ohm`, `k = 0.02 N m/A`,
//! `J = 1e-5 kg m^2`, 12 V, current limit 2 A) and its friction
//! (`examples/vibro-driver.toml`: Coulomb `T_c = 1e-3 N m`, viscous
//! `b = 1e-6 N m s`). The winding's inductance (`L/R = 0.25 ms`) is left out, so the
//! current follows the voltage at once; the platform and the eccentrics' weight are
//! left out too. The windings are driven through the bridges as wired: the model
//! reads the inputs the shared driver wrote ([`super::pwm`], the firmware's
//! `Drive`, the board's code) and takes each part of the PWM period
//! (`shared::drive::period`) with its voltage: forward `+V`, reverse `-V`, short
//! 0 V; a coasting part carries no current (without inductance a current dies at
//! once through the diodes). In the rotor's driven sense, with `V` the supply and
//! `l_j`, `u_j` each part's length (a fraction of the period) and voltage:
//!
//! ```text
//!   i = clamp(sum_j l_j (u_j - k w) / R, -I_lim, I_lim)   over the conducting parts
//!   J dw/dt = k i - T_c sign(w) - b w                      (stuck while |k i| <= T_c at w = 0)
//! ```
//!
//! The limit acts on the mean current, as the winding's inductance smooths the
//! current over a 50 us period (`L / R = 0.25 ms`) and the driver's chopper sees
//! it; in slow decay this is `i = clamp((d V - k w) / R)`.
//!
//! integrated with explicit Euler in [`SUBSTEPS`] steps a control tick. The
//! encoders count `N = 4096` a turn (x4 decoded) from 0 at the index; the index
//! pulse latches the counter once per turn, as the board's EXTI handlers do. The
//! supply sags by [`SUPPLY_RESISTANCE_OHM`] times the current drawn.
//!
//! Faults the script can set: the E-stop circuit open (the board's E-stop handler
//! then cuts the bridges at once, so the driver writes both inputs low and the
//! windings coast), an encoder disconnected (its counter and its index stop;
//! the rotor turns on), and an overrun of the control task (it busy-waits at the
//! end of one tick).

use shared::controller::{MachineConstants, CONTROL_RATE_HZ};
use shared::drive::{lengths, period};

/// Euler steps per control tick: 0.1 ms each, against the mechanical time
/// constant `J R / k^2 = 50 ms`.
pub const SUBSTEPS: u32 = 10;
/// Coulomb friction of each rotor, N m (the reference machine file).
pub const COULOMB_NM: f32 = 1.0e-3;
/// Viscous friction of each rotor, N m s (the reference machine file).
pub const VISCOUS_NM_S: f32 = 1.0e-6;
/// Source resistance of the supply, ohm: the supply the controller reads is
/// `V - R_s (|i_1| + |i_2|)`.
pub const SUPPLY_RESISTANCE_OHM: f32 = 0.1;

/// What the script breaks in the model.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, defmt::Format)]
pub struct Injected {
    /// The E-stop circuit is open.
    pub estop_open: bool,
    /// The encoder of rotor 1, rotor 2 is disconnected.
    pub encoder_cut: [bool; 2],
    /// The control task works this much longer at the end of its next tick, us
    /// (once; the task clears it): an overrun, as a stuck driver or a runaway
    /// interrupt would cause on the board.
    pub overrun_us: u32,
}

/// The readings of one tick, in the controller's units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// Encoder counters.
    pub encoder: [u32; 2],
    /// Counter values latched at an index pulse since the last sample.
    pub index: [Option<u32>; 2],
    /// Winding currents, A.
    pub current: [f32; 2],
    /// Supply voltage, V.
    pub supply_voltage: f32,
}

/// One rotor and its encoder.
#[derive(Clone, Copy, Debug)]
struct Rotor {
    /// Whole turns from the start, wrapping.
    turns: u32,
    /// Position within the turn, turns in [0, 1).
    fraction: f32,
    /// Speed, rad/s, driven sense.
    speed: f32,
    /// Winding current, A: the mean over the last tick.
    current: f32,
    /// The encoder counter (stops while the encoder is disconnected).
    counter: u32,
    /// The counter latched at the last index pulse, not yet sampled.
    index: Option<u32>,
}

impl Rotor {
    const AT_REST: Rotor = Rotor {
        turns: 0,
        fraction: 0.0,
        speed: 0.0,
        current: 0.0,
        counter: 0,
        index: None,
    };

    /// The absolute count of the true position, wrapping.
    fn counts(&self, n: u32) -> u32 {
        self.turns
            .wrapping_mul(n)
            .wrapping_add((self.fraction * n as f32) as u32)
    }
}

/// The two rotors of the reference machine.
pub struct Plant {
    rotors: [Rotor; 2],
    m: MachineConstants,
}

impl Default for Plant {
    fn default() -> Self {
        Plant::new()
    }
}

impl Plant {
    /// Both rotors at rest at their index.
    pub fn new() -> Self {
        Plant {
            rotors: [Rotor::AT_REST; 2],
            m: MachineConstants::REFERENCE,
        }
    }

    /// The readings now; takes the latched index counts.
    pub fn sample(&mut self) -> Sample {
        let draw: f32 = self.rotors.iter().map(|r| abs(r.current)).sum();
        Sample {
            encoder: self.rotors.map(|r| r.counter),
            index: [self.rotors[0].index.take(), self.rotors[1].index.take()],
            current: self.rotors.map(|r| r.current),
            supply_voltage: self.m.supply_voltage_v - SUPPLY_RESISTANCE_OHM * draw,
        }
    }

    /// True speeds, rpm.
    pub fn speed_rpm(&self) -> [f32; 2] {
        self.rotors
            .map(|r| r.speed * 60.0 / (2.0 * core::f32::consts::PI))
    }

    /// True angles within the turn, turns in [0, 1), driven sense. Each rotor's
    /// index sits at angle 0 (the wrap of the turn), where its encoder counts from.
    pub fn angle_turns(&self) -> [f32; 2] {
        self.rotors.map(|r| r.fraction)
    }

    /// Encoder counts a turn of the model (the machine's, 4096).
    pub fn encoder_counts(&self) -> u32 {
        self.m.encoder_counts
    }

    /// True phase offset `theta_1 - theta_2`, degrees in [0, 360).
    pub fn offset_deg(&self) -> f32 {
        let d = self.rotors[0].fraction - self.rotors[1].fraction;
        let d = if d < 0.0 { d + 1.0 } else { d };
        d * 360.0
    }

    /// One control tick with the bridges' inputs as the driver last wrote them
    /// ([`super::pwm::inputs`]), the faults `injected`.
    pub fn step(&mut self, injected: &Injected) {
        let h = 1.0 / (CONTROL_RATE_HZ * SUBSTEPS as f32);
        let n = self.m.encoder_counts;
        let draw: f32 = self.rotors.iter().map(|r| abs(r.current)).sum();
        let supply = self.m.supply_voltage_v - SUPPLY_RESISTANCE_OHM * draw;
        let limit = self.m.current_limit_a;
        for (k, rotor) in self.rotors.iter_mut().enumerate() {
            let c = &self.m.rotors[k];
            let cut = injected.encoder_cut[k];
            let parts = period(super::pwm::inputs(k));
            let mut current_sum = 0.0;
            for _ in 0..SUBSTEPS {
                // The mean current over the period's conducting parts.
                let back_emf = c.torque_constant * rotor.speed;
                let i: f32 = lengths(&parts)
                    .filter_map(|(len, conn)| {
                        conn.fraction()
                            .map(|u| len * (u * supply - back_emf) / c.resistance_ohm)
                    })
                    .sum();
                let i = i.clamp(-limit, limit);
                current_sum += i;
                let drive = c.torque_constant * i;
                let w = rotor.speed;
                let w_new = if w == 0.0 && abs(drive) <= COULOMB_NM {
                    0.0 // static friction holds it
                } else {
                    let friction = COULOMB_NM * sign(if w == 0.0 { drive } else { w });
                    let w_new = w + (drive - friction - VISCOUS_NM_S * w) / c.inertia_kg_m2 * h;
                    // Friction stops a rotor; it never turns it backwards.
                    if w != 0.0 && sign(w_new) != sign(w) && abs(drive) <= COULOMB_NM {
                        0.0
                    } else {
                        w_new
                    }
                };
                rotor.speed = w_new;

                // Position, encoder and index.
                let before = rotor.counts(n);
                rotor.fraction += w_new * h / (2.0 * core::f32::consts::PI);
                let mut crossed = false;
                if rotor.fraction >= 1.0 {
                    rotor.fraction -= 1.0;
                    rotor.turns = rotor.turns.wrapping_add(1);
                    crossed = true;
                } else if rotor.fraction < 0.0 {
                    rotor.fraction += 1.0;
                    // Crossing backwards: the index is at the start of the turn left.
                    crossed = true;
                }
                let index_at = rotor.turns.wrapping_mul(n);
                if rotor.fraction >= 1.0 || rotor.fraction < 0.0 {
                    rotor.fraction = 0.0; // rounding at the wrap
                }
                if w_new < 0.0 && crossed {
                    rotor.turns = rotor.turns.wrapping_sub(1);
                }
                let after = rotor.counts(n);
                if !cut {
                    let latched = rotor.counter.wrapping_add(index_at.wrapping_sub(before));
                    rotor.counter = rotor.counter.wrapping_add(after.wrapping_sub(before));
                    if crossed {
                        rotor.index = Some(latched);
                    }
                }
            }
            // What the board's current sensing gives the next tick: the mean over
            // this one (`shared::controller::Inputs::current`).
            rotor.current = current_sum / SUBSTEPS as f32;
        }
    }
}

fn abs(x: f32) -> f32 {
    if x < 0.0 {
        -x
    } else {
        x
    }
}

fn sign(x: f32) -> f32 {
    if x < 0.0 {
        -1.0
    } else {
        1.0
    }
}
