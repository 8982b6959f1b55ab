//! The scales of a capture's residuals (docs/calibration.md, "Motor keys from
//! a capture"): each replayed signal's difference from the recorded one, tick
//! by tick, is divided by the resolution the board measures or sets that signal
//! with, so that a speed, a current and a duty each off by its own resolution
//! weigh alike in the sum of squares.
//!
//! | quantity | scale | the reference machine |
//! | --- | --- | --- |
//! | speed, rpm | one encoder count a tick, through the speed filter | 0.736 rpm |
//! | current, A | one step of the board's current ADC, with the machine's sensor noise | 2.33 mA |
//! | duty | the speed loop's answer to one speed scale | 3.21e-4 |
//!
//! **Speed.** The board counts `c = floor(N theta / 2 pi)`; the count's
//! rounding error `e` is uniform over one count and, at a speed not locked to
//! the tick, independent from tick to tick, of variance 1/12 count^2 (Widrow,
//! Kollar & Liu, *IEEE Trans. Instrum. Meas.* 45, 1996, the quantization noise
//! model). The raw speed of a tick, `q (c_k - c_(k-1))` with `q = 60 / (N dt)`
//! rpm a count, carries `q (e_k - e_(k-1))`, and the controller's first-order
//! filter `w += a (w_raw - w)`, `a = dt / (tau + dt)` (`shared::controller::
//! encoder`), passes it with the impulse response `a h_j`, `h_0 = 1`,
//! `h_j = -a (1 - a)^(j-1)`, whose squares sum to `1 + a^2 / (1 - (1 - a)^2) =
//! 2 / (2 - a)`:
//!
//! ```text
//! sigma_w = q a sqrt(2 / (2 - a)) / sqrt(12)                       rpm
//! ```
//!
//! (the reference machine: `N` = 4096, `dt` = 1 ms, `tau` = 5 ms: `q` = 14.65
//! rpm, `a` = 1/6, `sigma_w` = 0.736 rpm).
//!
//! **Current.** The board reads each winding's current with a 12-bit ADC over
//! 3.3 V behind a 0.1 V/A amplifier (`firmware/src/sense.rs`): a step of
//! `3.3 / 4095 / 0.1` = 8.06 mA, of rounding variance `step^2 / 12`; the
//! machine file's `sensors.current_noise` (the sensor's own noise, 0 for an
//! ideal one) adds in quadrature:
//!
//! ```text
//! sigma_i = sqrt(step^2 / 12 + current_noise^2)                    A
//! ```
//!
//! **Duty.** The duty is no measurement: the board writes it, and the capture
//! keeps it to 1/32767. The twin's duty differs from the board's by what its
//! controller reacts to, the speed first: the speed loop's proportional gain
//! `kp` (duty per rad/s, the firmware's controller, `shared::controller::
//! params`) turns one speed scale into
//!
//! ```text
//! sigma_d = kp sigma_w (2 pi / 60)                                   duty
//! ```
//!
//! (the reference machine: `kp` = 4.17e-3 per rad/s, `sigma_d` = 3.21e-4), so a
//! duty counts as much as the speed error that would make it.
//!
//! At the truth the replay of a capture from a simulated board is off by about
//! half of each scale (RMS 0.4 rpm, 0.8 to 1 mA, 2e-4 of duty against the
//! reference machine's scales above: its residuals are the replay's drift by an
//! encoder count here and there), and on a file 10 to 30 % off it by 14 to 16,
//! 13 to 16 and 190 to 210 scales: the duty, the effort the speed loop spends,
//! tells most.

use shared::controller::Params;

use crate::machine::Machine;

/// The reference board's current ADC: volts of its reference (VDDA).
pub const ADC_REFERENCE_V: f64 = 3.3;

/// Its full scale, counts (12 bits).
pub const ADC_FULL_SCALE: f64 = 4095.0;

/// The current amplifier's gain, V/A (a 5 mOhm shunt times 20).
pub const CURRENT_V_PER_A: f64 = 0.1;

/// The scales of one capture's residuals.
#[derive(Clone, Debug, PartialEq)]
pub struct Scales {
    /// Speed, rpm.
    pub speed_rpm: f64,
    /// Current, A.
    pub current_a: f64,
    /// Duty of each rotor (its own speed loop's gain).
    pub duty: Vec<f64>,
}

impl Scales {
    /// The scales of a capture replayed with the board's controller `params`
    /// on the twin `machine` (its sensors' noise).
    pub fn new(params: &Params, machine: &Machine) -> Scales {
        let n = f64::from(params.encoder_counts.max(1));
        let dt = f64::from(params.tick_s());
        let tau = f64::from(params.speed_filter_tau_s);
        // sigma_w = q a sqrt(2 / (2 - a)) / sqrt(12).
        let q = 60.0 / (n * dt);
        let a = dt / (tau + dt);
        let speed_rpm = q * a * (2.0 / (2.0 - a)).sqrt() / 12f64.sqrt();
        // sigma_i = sqrt(step^2 / 12 + current_noise^2).
        let step = ADC_REFERENCE_V / ADC_FULL_SCALE / CURRENT_V_PER_A;
        let current_a = (step * step / 12.0 + machine.sensors.current_noise.powi(2)).sqrt();
        // sigma_d = kp sigma_w, the speed in rad/s.
        let speed_rad_s = speed_rpm * std::f64::consts::TAU / 60.0;
        let duty = params.speed_gains[..params.rotor_count.count()]
            .iter()
            .map(|g| f64::from(g.kp) * speed_rad_s)
            .collect();
        Scales {
            speed_rpm,
            current_a,
            duty,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simulation::closed_loop::params;

    /// The reference machine's scales, as the module doc works them out.
    #[test]
    fn the_reference_machines_scales() {
        let text = include_str!("../../../../examples/vibro-driver.toml");
        let mut machine =
            Machine::from_text("m.toml", text, std::path::Path::new(""), &[]).unwrap();
        machine.controller.tuning_table = None;
        let p = params(&machine).unwrap();
        let s = Scales::new(&p, &machine);
        // 14.6484 x (1/6) x sqrt(12/11) / sqrt(12) = 0.73611 rpm.
        assert!((s.speed_rpm - 0.73611).abs() < 1e-5, "{}", s.speed_rpm);
        // 8.0586 mA / sqrt(12) = 2.3263 mA.
        assert!((s.current_a - 2.3263e-3).abs() < 1e-7, "{}", s.current_a);
        // kp = 50 x 2 x 1e-5 / (0.02 x 12) = 4.1667e-3 per rad/s, times
        // 0.077085 rad/s: 3.2119e-4 (the gain an f32).
        for d in &s.duty {
            assert!((d - 3.2119e-4).abs() < 1e-8, "{d}");
        }
    }
}
