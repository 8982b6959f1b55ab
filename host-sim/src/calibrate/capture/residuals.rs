//! The weighted residuals of one replay of a capture: rotor by rotor, the
//! replayed speed, current and duty minus the recorded ones, tick by tick, each
//! over its scale ([`super::scales`]), summed over windows of `w` ticks
//! ([`window`]):
//!
//! ```text
//! r = sum_(k in window) (x_sim,k - x_rec,k) / sigma_x / sqrt(w),    x in (speed, current, duty)
//! S = sum over windows, rotors and the three of r^2
//! ```
//!
//! the rows of window `m` for rotor `j` at `(m R + j) 3 + q` ([`row`]): a
//! window's rows together, for the scores of the standard errors
//! ([`super::super::serial`]).
//!
//! **Why windows.** The twin counts its own encoder, and its controller reacts
//! to its own counts: where the twin's rotor crosses a count a tick before or
//! after the board's, its speed estimate differs by a count's worth for that
//! tick (14.6 rpm raw on the reference machine, 2.4 rpm after the filter) and
//! its duty and current by the speed loop's answer to it. The share of ticks
//! where that happens grows with the angle by which the twin is off, so tick by
//! tick the sum of squares has a kink at the board's values, like `|d|`, not
//! `d^2`, which a Gauss–Newton step misjudges. The counts' rounding enters the speed as a difference
//! (`q (e_k - e_(k-1))`, [`super::scales`]), so its sum over a window
//! telescopes to the rounding at the window's two ends, and the loops' answers
//! to it die out with the speed loop's time constant; a model's error, a
//! resistance or a friction off, persists over many ticks and adds up.
//! Dividing the sum by `sqrt(w)` keeps the weight of a persistent error what it
//! is tick by tick (`w` ticks of `e / sigma` give `w e^2 / sigma^2` either way),
//! and a noise independent from tick to tick of the scale's size still counts 1
//! a window. Measured on a capture of a simulated board's 3000 rpm travel
//! (the test's truth, `host-sim/tests/cli_calibrate_capture.rs`), replayed
//! with rotor 1's resistance off the truth by 0.2 to 2 %: tick by tick the sum
//! of squares jumps from 2700 at the truth to 13000 at 0.2 % and grows about in
//! proportion to the error beyond (30000 at 1 %, 43000 at 2 %); over windows
//! of 50 ticks it is 6 at the truth and grows with the error's square (100,
//! 330, 770, 1250, 2000 at 0.2, 0.4, 0.6, 0.8 and 1 %, 7800 at 2 %), and the
//! fit of the ten motor keys converges where tick by tick it stalled with the
//! frictions off by 5 to 70 %.
//!
//! The phase offset is left out: the board measures it from the two rotors'
//! angles, whose difference is the time integral of their speeds' difference,
//! so its residual repeats the speeds' residuals summed over the ticks before,
//! and would count their errors again.

use shared::controller::Params;

use super::scales::Scales;
use crate::replay::Replay;

/// The quantities of a window and rotor, in their order in the residuals.
pub const QUANTITIES: [&str; 3] = ["speed_rpm", "current_a", "duty"];

/// The window, in the closed speed loop's time constants.
pub const WINDOW_TIME_CONSTANTS: f64 = 2.5;

/// The window's length, ticks: [`WINDOW_TIME_CONSTANTS`] of the closed speed
/// loop's time constant `1 / w_c = 4 tau_f` (its crossover for damping 1,
/// `shared::controller::params`), over which the loop answers a count's
/// rounding; on the reference controller (`tau_f` = 5 ms, 1 kHz) 50 ticks.
/// At least one tick.
pub fn window(params: &Params) -> usize {
    let loop_s = 4.0 * f64::from(params.speed_filter_tau_s);
    let w = (WINDOW_TIME_CONSTANTS * loop_s / f64::from(params.tick_s())).round();
    (w as usize).max(1)
}

/// The index of quantity `q` of rotor `j` in window `m` among `rotors` rotors.
pub fn row(m: usize, j: usize, q: usize, rotors: usize) -> usize {
    (m * rotors + j) * QUANTITIES.len() + q
}

/// Residuals a window: three a rotor.
pub fn per_window(rotors: usize) -> usize {
    rotors * QUANTITIES.len()
}

/// The weighted residuals of `replay` for `rotors` rotors over windows of
/// `window` ticks (the last one the ticks left, its sum over the square root
/// of its own length; module doc).
pub fn weighted(replay: &Replay, scales: &Scales, rotors: usize, window: usize) -> Vec<f64> {
    let ticks: Vec<_> = replay.recorded.iter().zip(&replay.simulated).collect();
    let mut r = Vec::with_capacity(ticks.len().div_ceil(window.max(1)) * per_window(rotors));
    for chunk in ticks.chunks(window.max(1)) {
        let root = (chunk.len() as f64).sqrt();
        for j in 0..rotors {
            let mut sums = [0.0; 3];
            for (rec, sim) in chunk {
                sums[0] += (sim.speed_rpm[j] - rec.speed_rpm[j]) / scales.speed_rpm;
                sums[1] += (sim.current_a[j] - rec.current_a[j]) / scales.current_a;
                sums[2] += (sim.duty[j] - rec.duty[j]) / scales.duty[j];
            }
            r.extend(sums.iter().map(|s| s / root));
        }
    }
    r
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::replay::residual::Sample;

    fn replay_of(recorded: Vec<Sample>, simulated: Vec<Sample>) -> Replay {
        Replay {
            residuals: vec![],
            ticks: recorded.len(),
            tick_s: 1e-3,
            state_differs: (0, None),
            warnings: vec![],
            recorded,
            simulated,
        }
    }

    /// Each residual over its scale, in its row; a window of one tick is the
    /// tick.
    #[test]
    fn each_residual_over_its_scale_in_its_row() {
        let rec = Sample::default();
        let sim = Sample {
            speed_rpm: [1.0, 2.0],
            phase_deg: Some(5.0),
            current_a: [0.01, 0.02],
            duty: [0.001, 0.002],
        };
        let replay = replay_of(vec![rec, rec], vec![rec, sim]);
        let scales = Scales {
            speed_rpm: 0.5,
            current_a: 0.01,
            duty: vec![0.001, 0.002],
        };
        let r = weighted(&replay, &scales, 2, 1);
        assert_eq!(r.len(), 12);
        assert!(r[..6].iter().all(|x| *x == 0.0));
        assert_eq!(r[row(1, 0, 0, 2)], 2.0);
        assert_eq!(r[row(1, 1, 0, 2)], 4.0);
        assert_eq!(r[row(1, 0, 1, 2)], 1.0);
        assert_eq!(r[row(1, 1, 1, 2)], 2.0);
        assert_eq!(r[row(1, 0, 2, 2)], 1.0);
        assert_eq!(r[row(1, 1, 2, 2)], 1.0);
    }

    /// Over windows: a count's rounding, `+q` at one tick and `-q` at the
    /// next, sums to nothing; a persistent error `e` over `w` ticks gives
    /// `sqrt(w) e / sigma`, its square what the ticks' squares add to; the
    /// last window is the ticks left.
    #[test]
    fn windows_cancel_a_rounding_and_keep_a_persistent_error() {
        let scales = Scales {
            speed_rpm: 1.0,
            current_a: 1.0,
            duty: vec![1.0],
        };
        let speeds = [2.4, -2.4, 0.0, 0.0, 3.0, 3.0, 3.0, 3.0, 1.0];
        let rec = vec![Sample::default(); speeds.len()];
        let sim: Vec<Sample> = speeds
            .iter()
            .map(|v| Sample {
                speed_rpm: [*v, 0.0],
                ..Sample::default()
            })
            .collect();
        let r = weighted(&replay_of(rec, sim), &scales, 1, 4);
        assert_eq!(r.len(), 9);
        assert_eq!(r[row(0, 0, 0, 1)], 0.0);
        assert_eq!(r[row(1, 0, 0, 1)], 6.0);
        assert_eq!(r[row(1, 0, 0, 1)].powi(2), 4.0 * 9.0);
        assert_eq!(r[row(2, 0, 0, 1)], 1.0);
    }
}
