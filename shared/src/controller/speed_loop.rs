//! One rotor's speed loop: feedforward from the motor model plus a PI on the speed
//! error, with anti-windup.
//!
//! ```text
//!   d_ff = (k w_ref + R J a_ref / k) / V            (back-EMF + acceleration torque)
//!   e    = w_ref - w
//!   d    = clamp(d_ff + kp e + I, d_min, 1)
//!   I   += ki e dt   unless d is clamped and e pushes further into the clamp
//! ```
//!
//! From the rotor equation `J w' = k i - tau`, `i = (d V - k w) / R` (params module,
//! eq. (1)): the feedforward is the duty that holds `w_ref` and accelerates at
//! `a_ref` with no load; the PI takes the load and the model's errors. The
//! anti-windup is conditional integration (Astrom and Hagglund, *Advanced PID
//! Control*, 2006, sec. 3.5): the integral stops while the output is saturated in
//! the direction the error pushes, and is itself kept in [-1, 1].

use super::params::{RotorModel, SpeedGains};

/// The state of one speed loop.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SpeedLoop {
    /// The integral term, duty.
    integral: f32,
}

/// One tick's references and measurement for a speed loop.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpeedLoopInput {
    /// Speed reference, rad/s.
    pub speed_ref_rad_s: f32,
    /// Acceleration of the reference, rad/s^2 (feedforward).
    pub accel_ref_rad_s2: f32,
    /// Measured speed, rad/s.
    pub speed_rad_s: f32,
    /// Supply voltage used to turn volts into duty, V, > 0.
    pub supply_v: f32,
}

impl SpeedLoop {
    /// A loop with an empty integral.
    pub fn new() -> Self {
        SpeedLoop::default()
    }

    /// Empty the integral.
    pub fn reset(&mut self) {
        self.integral = 0.0;
    }

    /// The integral term, duty.
    pub fn integral(&self) -> f32 {
        self.integral
    }

    /// The duty for this tick, in `[min_duty, 1]`; 0 (and the integral emptied) if
    /// any input is not finite.
    ///
    /// Always inlined: the controller's tick calls it for each rotor, and out of
    /// line its input, gains and model go through memory at every call.
    #[inline(always)]
    pub fn update(
        &mut self,
        input: &SpeedLoopInput,
        gains: &SpeedGains,
        rotor: &RotorModel,
        min_duty: f32,
        dt: f32,
    ) -> f32 {
        let SpeedLoopInput {
            speed_ref_rad_s: w_ref,
            accel_ref_rad_s2: a_ref,
            speed_rad_s: w,
            supply_v: v,
        } = *input;

        // Feedforward: back-EMF and acceleration torque, in duty.
        let k = rotor.torque_constant;
        let ff = (k * w_ref + rotor.resistance_ohm * rotor.inertia_kg_m2 * a_ref / k) / v;

        // PI with conditional integration.
        let e = w_ref - w;
        let unclamped = ff + gains.kp * e + self.integral;
        let pushing_up = unclamped > 1.0 && e > 0.0;
        let pushing_down = unclamped < min_duty && e < 0.0;
        if !(pushing_up || pushing_down) {
            self.integral = (self.integral + gains.ki * e * dt).clamp(-1.0, 1.0);
        }
        let duty = ff + gains.kp * e + self.integral;
        if !duty.is_finite() || !self.integral.is_finite() {
            self.integral = 0.0;
            return 0.0;
        }
        duty.clamp(min_duty, 1.0)
    }
}
