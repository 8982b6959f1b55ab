//! The phase-lock loop: holds the phase offset `theta_1 - theta_2` at its reference
//! by asking the speed loops for a speed difference.
//!
//! Increasing rotor 1's speed increases `theta_1` and so the offset; increasing
//! rotor 2's decreases it: `(theta_1 - theta_2)' = w1 - w2`. The loop asks for
//!
//! ```text
//!   dw = r' + kp e + I,   I += ki e dt,   e = wrap(r - offset) (rad, in (-pi, pi])
//!   w1_ref = w_ramp + dw / 2,   w2_ref = w_ramp - dw / 2
//! ```
//!
//! with `r'` the rate of the offset reference (feedforward: a ramping reference is
//! followed without lag), `|dw| <= limit`, and conditional integration as in the
//! speed loop. With ideal speed loops the error obeys `e'' + kp e' + ki e = 0`
//! (params module: damping 1 with `ki = kp^2 / 4`). Splitting `dw` half and half
//! keeps the mean speed, and with it the exciting force, where the ramp puts it.

/// The state of the phase loop.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PhaseLoop {
    /// The integral term, rad/s.
    integral: f32,
}

impl PhaseLoop {
    /// A loop with an empty integral.
    pub fn new() -> Self {
        PhaseLoop::default()
    }

    /// Empty the integral.
    pub fn reset(&mut self) {
        self.integral = 0.0;
    }

    /// The speed difference `w1 - w2` to ask for, rad/s, in `[-limit, limit]`, from
    /// the error `error_rad` (rad), the reference's rate `ff_rad_s` (rad/s), gains
    /// `kp` (1/s) and `ki` (1/s^2), over `dt` s. 0 (integral emptied) if an input
    /// is not finite.
    pub fn update(
        &mut self,
        error_rad: f32,
        ff_rad_s: f32,
        kp: f32,
        ki: f32,
        limit_rad_s: f32,
        dt: f32,
    ) -> f32 {
        let limit = if limit_rad_s > 0.0 { limit_rad_s } else { 0.0 };
        let unclamped = ff_rad_s + kp * error_rad + self.integral;
        let pushing_up = unclamped > limit && error_rad > 0.0;
        let pushing_down = unclamped < -limit && error_rad < 0.0;
        if !(pushing_up || pushing_down) {
            self.integral = (self.integral + ki * error_rad * dt).clamp(-limit, limit);
        }
        let dw = ff_rad_s + kp * error_rad + self.integral;
        if !dw.is_finite() || !self.integral.is_finite() {
            self.integral = 0.0;
            return 0.0;
        }
        dw.clamp(-limit, limit)
    }
}
