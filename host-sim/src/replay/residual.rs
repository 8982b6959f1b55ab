//! Recorded against simulated, tick by tick: each quantity's residual
//! (simulated minus recorded) as its RMS, its largest magnitude and where.
//!
//! | quantity | recorded | simulated |
//! | --- | --- | --- |
//! | `speed_rpm` | the board's filtered speed (the re-run controller's, [`super::shadow`]) | the twin controller's |
//! | `phase_offset_deg` | the board's measured offset | the twin's, wrapped to (-180, 180], over the ticks where both know it |
//! | `current_a` | the recorded mean current | the twin's sensed mean current |
//! | `duty` | the recorded duty (0 for a bridge off) | the twin's |

use shared::controller::{Inputs, Outputs};

/// One quantity's residual for one rotor (or none, for the phase offset).
#[derive(Clone, Debug, PartialEq)]
pub struct Residual {
    /// `speed_rpm`, `phase_offset_deg`, `current_a` or `duty`.
    pub quantity: &'static str,
    /// Rotor 1 or 2; `None` for the phase offset.
    pub rotor: Option<usize>,
    /// Ticks compared.
    pub ticks: usize,
    /// Root mean square over them.
    pub rms: f64,
    /// Largest magnitude.
    pub max: f64,
    /// The tick of the largest.
    pub at_tick: usize,
}

/// What is compared at one tick.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Sample {
    /// Speeds, rpm.
    pub speed_rpm: [f64; 2],
    /// Phase offset, degrees, if known.
    pub phase_deg: Option<f64>,
    /// Currents, A.
    pub current_a: [f64; 2],
    /// Duties.
    pub duty: [f64; 2],
}

impl Sample {
    /// The sample of a tick that stepped on `inputs` and wrote `out`.
    pub fn of(inputs: &Inputs, out: &Outputs) -> Sample {
        let t = &out.telemetry;
        Sample {
            speed_rpm: t.speed_rpm.map(f64::from),
            phase_deg: t.phase_valid.then_some(f64::from(t.phase_offset_deg)),
            current_a: inputs.current.map(f64::from),
            duty: out.duties().map(f64::from),
        }
    }
}

/// `a - b` for angles in degrees, wrapped to (-180, 180].
pub fn angle_diff(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(360.0);
    if d > 180.0 {
        d - 360.0
    } else {
        d
    }
}

/// Accumulates one residual.
struct Acc {
    sum2: f64,
    n: usize,
    max: f64,
    at: usize,
}

impl Acc {
    fn new() -> Acc {
        Acc {
            sum2: 0.0,
            n: 0,
            max: 0.0,
            at: 0,
        }
    }

    fn add(&mut self, k: usize, d: f64) {
        if !d.is_finite() {
            return;
        }
        self.sum2 += d * d;
        self.n += 1;
        if d.abs() > self.max {
            self.max = d.abs();
            self.at = k;
        }
    }

    fn done(self, quantity: &'static str, rotor: Option<usize>) -> Residual {
        Residual {
            quantity,
            rotor,
            ticks: self.n,
            rms: if self.n > 0 {
                (self.sum2 / self.n as f64).sqrt()
            } else {
                f64::NAN
            },
            max: self.max,
            at_tick: self.at,
        }
    }
}

/// The residuals of `simulated` against `recorded`, tick by tick, for
/// `rotors` rotors.
pub fn residuals(recorded: &[Sample], simulated: &[Sample], rotors: usize) -> Vec<Residual> {
    let mut out = Vec::new();
    for r in 0..rotors {
        let mut acc = Acc::new();
        for (k, (a, b)) in recorded.iter().zip(simulated).enumerate() {
            acc.add(k, b.speed_rpm[r] - a.speed_rpm[r]);
        }
        out.push(acc.done("speed_rpm", Some(r + 1)));
    }
    if rotors == 2 {
        let mut acc = Acc::new();
        for (k, (a, b)) in recorded.iter().zip(simulated).enumerate() {
            if let (Some(pa), Some(pb)) = (a.phase_deg, b.phase_deg) {
                acc.add(k, angle_diff(pb, pa));
            }
        }
        out.push(acc.done("phase_offset_deg", None));
    }
    for r in 0..rotors {
        let mut acc = Acc::new();
        for (k, (a, b)) in recorded.iter().zip(simulated).enumerate() {
            acc.add(k, b.current_a[r] - a.current_a[r]);
        }
        out.push(acc.done("current_a", Some(r + 1)));
    }
    for r in 0..rotors {
        let mut acc = Acc::new();
        for (k, (a, b)) in recorded.iter().zip(simulated).enumerate() {
            acc.add(k, b.duty[r] - a.duty[r]);
        }
        out.push(acc.done("duty", Some(r + 1)));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn angles_wrap_to_the_short_way_round() {
        assert_eq!(angle_diff(10.0, 350.0), 20.0);
        assert_eq!(angle_diff(350.0, 10.0), -20.0);
        assert_eq!(angle_diff(180.0, 0.0), 180.0);
    }

    #[test]
    fn a_residual_is_its_rms_and_its_largest_with_where() {
        let rec = vec![Sample::default(); 4];
        let sim: Vec<Sample> = [1.0, -3.0, 1.0, 1.0]
            .iter()
            .map(|&v| Sample {
                speed_rpm: [v, 0.0],
                ..Sample::default()
            })
            .collect();
        let r = &residuals(&rec, &sim, 1)[0];
        assert_eq!((r.ticks, r.max, r.at_tick), (4, 3.0, 1));
        assert!((r.rms - (12.0f64 / 4.0).sqrt()).abs() < 1e-12);
    }
}
