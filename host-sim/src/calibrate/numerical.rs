//! The simulator's own numerical noise at the fit (docs/calibration.md,
//! "Numerical noise"): how much each measured point's simulated speed changes
//! when only the integrator's tolerance changes.
//!
//! A run's mean velocity at a finite tolerance `rtol` differs from the exact
//! solution's. Where the gait is periodic the difference shrinks with `rtol` and
//! is small (about 1e-4 mm/s at 1e-3 on the reference machine); where it is
//! chaotic, any change of the trajectory's rounding gives another sample of the
//! gait's finite-time mean, and the speed jumps by up to 1 to 2 mm/s from one
//! tolerance to the next (3000 rpm at 150 degrees: +1.03 mm/s from 1e-8 to 1e-3).
//! That difference is a model error the fit cannot tell from a measurement's, and
//! it is shared by every row at the point (one run serves them all).
//!
//! The estimate: at the fit, every point run again at `rtol / 2` to `rtol / 16`
//! ([`DIVISORS`]), or at `rtol * 2` to `rtol * 16` where `rtol / 16` is below the
//! machine file's lowest tolerance (1e-12): five distinct tolerances either way
//! ([`tolerances`]), and the sample variance of the five speeds `g_0 .. g_4` (the fit's first):
//!
//! ```text
//! tau_k^2 = sum_i (g_i - gbar)^2 / 4
//! ```
//!
//! unbiased when the five are independent samples of a chaotic gait's mean;
//! where the error is a smooth bias `e rtol` it gives `tau = 0.38 e rtol`, an
//! underestimate, but such biases are below 0.02 mm/s at 1e-3 on the reference
//! machine (over the coarser tolerances, `rtol` to `16 rtol`, it gives
//! `6.1 e rtol`, an overestimate, of a bias at 1e-12 far below any measurement's). A point held at the fit but not at another tolerance has no settled
//! speed to speak of: its `tau` is the residual of a run not held,
//! [`NOT_HELD_RESIDUAL_MPS`]. [`super::precision`] adds `W_k tau_k^2` to the
//! point's variance in the standard errors.
//!
//! The same runs give the sum of squares at the fit at each tolerance, `S_0` (the
//! search's) and `S_1 .. S_4`. Where speeds jump with the tolerance they jump as
//! much from one trial value to the next, and the search ends where that noise
//! happened to lower `S` most: the fresh `S_i` lie higher on average by the
//! search's gain from the noise, and scatter by the noise of `S` itself,
//!
//! ```text
//! G = mean(S_1 .. S_4) - S_0,    sigma_S = sd(S_1 .. S_4)
//! ```
//!
//! ([`super::precision`] turns them into how far the noise may have moved the
//! fit).

use rayon::prelude::*;

use super::points::{Point, NOT_HELD_RESIDUAL_MPS};
use crate::machine::{Machine, RTOL_RANGE};
use crate::sweep::{run_point, RunOutcome};

/// The fit's tolerance is divided by these for the runs again.
pub const DIVISORS: [f64; 4] = [2.0, 4.0, 8.0, 16.0];

/// The runs at other tolerances, and the noise they show.
#[derive(Clone, Debug, PartialEq)]
pub struct Noise {
    /// The fit's tolerance, then those of the runs again.
    pub rtols: Vec<f64>,
    /// Per point, its speed at each tolerance, m/s (`None` where not held).
    pub speeds: Vec<Vec<Option<f64>>>,
    /// Per point, `tau`, m/s: the standard deviation of its speeds over the
    /// tolerances (0 where the fit's run did not hold its offset: its residual is
    /// the fixed [`NOT_HELD_RESIDUAL_MPS`] at any tolerance).
    pub sd: Vec<f64>,
    /// The points' sum of squares `S_i` at each tolerance, m^2/s^2 (without the
    /// scatter within the points, the same at every tolerance).
    pub ssr: Vec<f64>,
}

impl Noise {
    /// The search's gain from the noise, `G = mean(S_1 ..) - S_0`, m^2/s^2 (0
    /// where negative).
    pub fn gain(&self) -> f64 {
        let fresh = &self.ssr[1..];
        (fresh.iter().sum::<f64>() / fresh.len() as f64 - self.ssr[0]).max(0.0)
    }

    /// The noise of `S`: the standard deviation of `S_1 ..`, m^2/s^2.
    pub fn ssr_sd(&self) -> f64 {
        let fresh: Vec<Option<f64>> = self.ssr[1..].iter().map(|s| Some(*s)).collect();
        spread(&fresh)
    }
}

/// Runs the measured `points` again on `machine` (the fitted values, the fit's
/// tolerance) at the other tolerances ([`tolerances`]), `at_fit` the runs at the fit,
/// in parallel; `done` is told of each run.
pub fn noise(
    machine: &Machine,
    points: &[Point],
    t_end: f64,
    at_fit: &[RunOutcome],
    done: &(dyn Fn() + Sync),
) -> Noise {
    let rtols = tolerances(machine.simulation.rtol);
    let others: Vec<Machine> = rtols[1..]
        .iter()
        .map(|r| {
            let mut m = machine.clone();
            m.simulation.rtol = *r;
            m
        })
        .collect();
    let jobs: Vec<(usize, usize)> = (0..others.len())
        .flat_map(|m| (0..points.len()).map(move |k| (m, k)))
        .collect();
    let runs: Vec<RunOutcome> = jobs
        .par_iter()
        .map(|&(m, k)| {
            let o = run_point(&others[m], points[k].speed_rpm, points[k].offset_deg, t_end);
            done();
            o
        })
        .collect();
    let speed = RunOutcome::velocity;
    let speeds: Vec<Vec<Option<f64>>> = (0..points.len())
        .map(|k| {
            let mut s = vec![speed(&at_fit[k])];
            s.extend((0..others.len()).map(|m| speed(&runs[m * points.len() + k])));
            s
        })
        .collect();
    let sd = speeds.iter().map(|s| spread(s)).collect();
    let ssr = (0..rtols.len())
        .map(|i| {
            points
                .iter()
                .zip(&speeds)
                .map(|(p, s)| {
                    // A run not held at the fit counts as such at every tolerance.
                    let g = if s[0].is_some() { s[i] } else { None };
                    p.residual(g).powi(2)
                })
                .sum()
        })
        .collect();
    Noise {
        rtols,
        speeds,
        sd,
        ssr,
    }
}

/// The fit's tolerance `rtol` and the four others its points run again at:
/// `rtol` divided by [`DIVISORS`], or, where the finest of those is below the
/// machine file's lowest tolerance, multiplied by them (clamping them to it
/// would run the same tolerance five times and measure a noise of 0).
pub fn tolerances(rtol: f64) -> Vec<f64> {
    let finest = DIVISORS[DIVISORS.len() - 1];
    let coarser = rtol / finest < RTOL_RANGE.0;
    let mut rtols = vec![rtol];
    for d in DIVISORS {
        rtols.push(if coarser { rtol * d } else { rtol / d });
    }
    rtols
}

/// The sample standard deviation of `speeds` (the fit's first), m/s: `tau` of
/// the module doc (0 and [`NOT_HELD_RESIDUAL_MPS`] where runs were not held).
pub fn spread(speeds: &[Option<f64>]) -> f64 {
    match speeds.first() {
        Some(None) | None => 0.0,
        Some(Some(_)) => {
            let held: Vec<f64> = speeds.iter().flatten().copied().collect();
            if held.len() < speeds.len() {
                return NOT_HELD_RESIDUAL_MPS;
            }
            let mean = held.iter().sum::<f64>() / held.len() as f64;
            let ss: f64 = held.iter().map(|g| (g - mean).powi(2)).sum();
            (ss / (held.len() - 1) as f64).sqrt()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// At the lowest tolerance, 1e-12, the runs again went to 1e-12 five times
    /// over, gave the same speeds and a numerical noise of 0 (issue 23). They
    /// go to five distinct tolerances, and a chaotic point (3250 rpm at 120
    /// degrees, docs/calibration.md, "Numerical noise") shows its noise.
    #[test]
    fn at_the_lowest_tolerance_the_noise_is_measured_over_distinct_ones() {
        let text = include_str!("../../../examples/vibro-driver.toml");
        let sets = ["simulation.rtol=1e-12".to_string()];
        let mut machine =
            Machine::from_text("m.toml", text, std::path::Path::new(""), &sets).unwrap();
        machine.controller.tuning_table = None;
        let point = Point {
            speed_rpm: 3250.0,
            offset_deg: 120.0,
            rows: 1,
            weight: 1.0,
            mean_mps: 0.017,
            scatter: 0.0,
        };
        // 2 s: the offset is held from about 0.85 s, before T/2.
        let t_end = 2.0;
        let at_fit = run_point(&machine, point.speed_rpm, point.offset_deg, t_end);
        let n = noise(&machine, &[point], t_end, &[at_fit], &|| {});
        assert_eq!(n.rtols, [1e-12, 2e-12, 4e-12, 8e-12, 1.6e-11]);
        let speeds: Vec<f64> = n.speeds[0]
            .iter()
            .map(|v| v.expect("held at every tolerance"))
            .collect();
        assert!(
            speeds.iter().any(|v| *v != speeds[0]),
            "a chaotic point's speeds at five tolerances: {speeds:?}"
        );
        assert!(n.sd[0] > 0.0);
    }

    #[test]
    fn the_spread_of_the_speeds() {
        // 1, 2, 3 mm/s: mean 2, squares 1 + 0 + 1 over 2: 1 mm/s.
        let s = spread(&[Some(1e-3), Some(2e-3), Some(3e-3)]);
        assert!((s - 1e-3).abs() < 1e-15);
        assert_eq!(spread(&[Some(0.02); 3]), 0.0);
        // Held at the fit, not at another tolerance: no settled speed.
        assert_eq!(
            spread(&[Some(0.02), None, Some(0.02)]),
            NOT_HELD_RESIDUAL_MPS
        );
        // Not held at the fit: its residual does not depend on the tolerance.
        assert_eq!(spread(&[None, Some(0.02), Some(0.03)]), 0.0);
    }
}
