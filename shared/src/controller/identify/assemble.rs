//! One rotor's measurements put together: the voltage fit, the friction fit and
//! the spin-up's energy balance give a [`RotorIdentity`].
//!
//! 1. **Voltage** (the armature circuit averaged over a level, where
//!    `L di/dt` averages to nothing between equal currents):
//!    `V = R i + k w + c_0 + c_1 sign(i)`, one row per level: the standstill
//!    levels of both signs (`w` near 0) tell `R`, `c_0` and `c_1` apart, the speed
//!    levels give `k`. `V` is the duty times the measured supply, `i` and `w` the
//!    level's time means.
//! 2. **Friction** (the torque balance averaged over whole turns at a steady
//!    speed, where the kinetic and the eccentric's potential energy come back to
//!    where they were, so the mean is taken over the angle, not over time):
//!    `k <i>_theta = T_c + b <w>_theta`, one row per speed level, with `k` from 1,
//!    each row weighted by the standard error of its mean current (the spread
//!    of the level's samples over the square root of their number).
//! 3. **Inertia**: [`super::energy`], with `k`, `T_c` and `b` from 1 and 2, at the
//!    first whole turn of the spin-up where the speed has reached
//!    [`INERTIA_SPEED_FRACTION`] of the top level's.
//!
//! Standard errors: both fits weigh each row by its own errors (the mean
//! current's, by von Neumann's estimator of the sense's noise; the mean speed's,
//! a count of quantization at each end of the level) and give
//! `sqrt([(X^T W X)^-1]_jj)`, times the scatter's `s` where it is above 1 (the
//! model misses by more than the rows' errors; a dozen rows, or four, say little
//! of their own scatter otherwise). The friction values are widened by `k`'s
//! relative error (they are proportional to `k`); and the
//! inertia's propagated from `k`, `T_c`, `b` and the boundary speed's count
//! quantization, plus the eccentric's work over the boundary's miss of the whole
//! turn (at most `T_L |miss|`, taken as uniform: `/ sqrt 3`), each to first
//! order, their covariances left out.

use super::energy::{Snapshot, HALF_WINDOW};
use super::fit::LeastSquares;
use super::result::{Estimate, RotorIdentity, Shortfall};

/// The spin-up turn used for the inertia: the first whose speed has reached this
/// fraction of the top level's (most of the kinetic energy, little of the
/// friction's work).
pub const INERTIA_SPEED_FRACTION: f64 = 0.8;

/// The most rows of the voltage fit: the standstill levels both ways and the
/// speed levels.
pub const VOLTAGE_ROWS: usize = 2 * super::HOLD_LEVELS.len() + super::SPEED_LEVELS.len();

/// One level's row of the voltage fit: its time means and their errors.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct VoltageRow {
    /// Mean voltage (duty times supply), V.
    pub volts: f64,
    /// Mean current, A.
    pub amps: f64,
    /// Mean speed, rad/s.
    pub speed: f64,
    /// The current's direction, +1 or -1.
    pub sign: f64,
    /// The mean current's standard error, A.
    pub amps_std_error: f64,
    /// The mean speed's standard error, rad/s (the counts' quantization).
    pub speed_std_error: f64,
}

/// One speed level's means.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SpeedRow {
    /// `<w>_theta`, rad/s.
    pub speed_by_angle: f64,
    /// `<i>_theta`, A.
    pub amps_by_angle: f64,
    /// Its standard error, A ([`SpeedRow::amps_by_angle`]).
    pub amps_std_error: f64,
    /// The time-mean speed, rad/s.
    pub speed: f64,
}

/// What one rotor's run gathered.
pub struct Gathered<'a> {
    /// The voltage rows.
    pub voltage: &'a [VoltageRow],
    /// The machine file's resistance, ohm, and torque constant, N m/A: the rows'
    /// weights.
    pub file_motor: (f32, f32),
    /// The speed levels, in order (the top level first).
    pub speeds: &'a [SpeedRow],
    /// The spin-up's whole turns.
    pub snapshots: &'a [Snapshot],
    /// Standstill levels used and speed levels used.
    pub levels: (u8, u8),
    /// The largest load torque at low speed, N m (the eccentric's work bound).
    pub load_torque_nm: f32,
    /// Counts per turn and the tick, s (the boundary speed's quantization).
    pub counts_per_rev: u32,
    /// The control tick, s.
    pub dt: f32,
}

/// Voltage rows added to the fit in one tick of the assembly.
const ROWS_A_TICK: usize = 3;

/// The voltage fit's values.
#[derive(Clone, Copy, Debug, PartialEq)]
struct VoltageFit {
    /// `R, k, c_0, c_1`.
    values: [f64; 4],
    /// Their standard errors.
    std_errors: [f64; 4],
}

/// The friction fit's values.
#[derive(Clone, Copy, Debug, PartialEq)]
struct FrictionFit {
    /// `T_c, b`.
    values: [f64; 2],
    /// Their standard errors, `k`'s relative error included.
    std_errors: [f64; 2],
    /// The fit's residual, N m.
    residual: f64,
}

/// One rotor's measurements put together a share at a time, one share a control
/// tick while the rotor coasts: the fits in `f64` are soft-float on the board,
/// and all at once they took about 104 000 instructions in one tick (QEMU), over
/// the tick's 0.5 ms budget at 168 MHz. In shares: [`ROWS_A_TICK`] voltage rows
/// a tick, then the voltage fit's solve, its residual, the friction fit, the
/// inertia.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Assembly {
    /// Voltage rows added so far.
    rows: usize,
    voltage: LeastSquares<4>,
    voltage_fit: Option<VoltageFit>,
    voltage_residual: Option<f64>,
    friction_fit: Option<FrictionFit>,
    /// Where it fell short, once it has.
    short: Option<Shortfall>,
}

impl Default for Assembly {
    fn default() -> Self {
        Assembly::new()
    }
}

impl Assembly {
    /// Nothing done yet.
    pub const fn new() -> Self {
        Assembly {
            rows: 0,
            voltage: LeastSquares::new(),
            voltage_fit: None,
            voltage_residual: None,
            friction_fit: None,
            short: None,
        }
    }

    /// One tick's share of the work on `g`; the identity once the last share is
    /// done (or where it fell short).
    pub fn step(&mut self, g: &Gathered<'_>) -> Option<RotorIdentity> {
        if let Some(why) = self.short {
            return Some(RotorIdentity::short(why));
        }
        if self.rows < g.voltage.len() {
            let end = (self.rows + ROWS_A_TICK).min(g.voltage.len());
            for row in &g.voltage[self.rows..end] {
                add_voltage_row(&mut self.voltage, row, g.file_motor);
            }
            self.rows = end;
            return None;
        }
        let Some(v) = self.voltage_fit else {
            self.voltage_fit = solve_voltage(&self.voltage);
            if self.voltage_fit.is_none() {
                self.short = Some(Shortfall::NoFit);
            }
            return None;
        };
        let Some(voltage_residual) = self.voltage_residual else {
            self.voltage_residual = Some(voltage_residual(g.voltage, &v.values));
            return None;
        };
        let Some(f) = self.friction_fit else {
            self.friction_fit = friction_fit(g.speeds, &v);
            if self.friction_fit.is_none() {
                self.short = Some(Shortfall::NoFit);
            }
            return None;
        };
        let identity = inertia(g, &v, &f).map_or_else(RotorIdentity::short, |(j, se_j)| {
            let est = |value: f64, se: f64| Estimate {
                value: value as f32,
                std_error: se as f32,
            };
            let [r, k, c0, c1] = v.values;
            RotorIdentity {
                shortfall: None,
                resistance_ohm: est(r, v.std_errors[0]),
                torque_constant: est(k, v.std_errors[1]),
                coulomb_friction_nm: est(f.values[0], f.std_errors[0]),
                viscous_friction: est(f.values[1], f.std_errors[1]),
                inertia_kg_m2: est(j, se_j),
                offset_v: est(c0, v.std_errors[2]),
                drop_v: est(c1, v.std_errors[3]),
                voltage_residual_v: voltage_residual as f32,
                friction_residual_nm: f.residual as f32,
                standstill_levels: g.levels.0,
                speed_levels: g.levels.1,
            }
        });
        // Only finite numbers are reported and stored (the record refuses others).
        Some(if identity.is_finite() {
            identity
        } else {
            RotorIdentity::short(Shortfall::NoFit)
        })
    }
}

/// The least error a mean of `x` can have: the resolution of the `f32` its
/// samples came in (a current sense that reads the same every tick gives no
/// noise to estimate; without a floor its weight would overflow the fit).
fn resolution(x: f64) -> f64 {
    (x.abs() * f64::from(f32::EPSILON)).max(f64::from(f32::MIN_POSITIVE))
}

/// Adds a voltage row, weighted by its own error: the current's and the speed's,
/// through the file's R and k (`sigma_V^2 = (R sigma_i)^2 + (k sigma_w)^2`).
fn add_voltage_row(fit: &mut LeastSquares<4>, row: &VoltageRow, file_motor: (f32, f32)) {
    let (r_file, k_file) = (f64::from(file_motor.0), f64::from(file_motor.1));
    let se = libm::sqrt(
        (r_file * row.amps_std_error) * (r_file * row.amps_std_error)
            + (k_file * row.speed_std_error) * (k_file * row.speed_std_error),
    )
    .max(resolution(row.volts));
    fit.add(
        [row.amps / se, row.speed / se, 1.0 / se, row.sign / se],
        row.volts / se,
    );
}

/// The voltage fit, `None` if its rows do not tell `R, k, c_0, c_1` apart or
/// `R` or `k` is not positive.
fn solve_voltage(fit: &LeastSquares<4>) -> Option<VoltageFit> {
    let v = fit.solve()?;
    let [r, k, _, _] = v.coefficients;
    if !(r > 0.0 && k > 0.0 && r.is_finite() && k.is_finite()) {
        return None;
    }
    let scale = v.residual_scale.max(1.0);
    Some(VoltageFit {
        values: v.coefficients,
        std_errors: v.unit_errors.map(|u| scale * u),
    })
}

/// The voltage fit's residual in V, unweighted.
fn voltage_residual(rows: &[VoltageRow], values: &[f64; 4]) -> f64 {
    let [r, k, c0, c1] = *values;
    let sum: f64 = rows
        .iter()
        .map(|row| {
            let e = row.volts - r * row.amps - k * row.speed - c0 - c1 * row.sign;
            e * e
        })
        .sum();
    libm::sqrt(sum / rows.len().max(1) as f64)
}

/// The friction fit on `speeds`, with `k` from the voltage fit: each row
/// weighted by its own standard error (the current's, times k), so that the
/// errors come from what was measured, not only from the scatter of four rows
/// about a line; widened by the scatter where it is the larger, and by `k`'s
/// relative error.
fn friction_fit(speeds: &[SpeedRow], v: &VoltageFit) -> Option<FrictionFit> {
    let k = v.values[1];
    let k_rel = v.std_errors[1] / k;
    let mut friction = LeastSquares::<2>::new();
    for row in speeds {
        let se = (k * row.amps_std_error).max(resolution(k * row.amps_by_angle));
        friction.add(
            [1.0 / se, row.speed_by_angle / se],
            k * row.amps_by_angle / se,
        );
    }
    let f = friction.solve()?;
    let [t_c, b] = f.coefficients;
    let scale = f.residual_scale.max(1.0);
    let widen = |value: f64, se: f64| libm::sqrt(se * se + (value * k_rel) * (value * k_rel));
    let sum: f64 = speeds
        .iter()
        .map(|r| {
            let e = k * r.amps_by_angle - t_c - b * r.speed_by_angle;
            e * e
        })
        .sum();
    Some(FrictionFit {
        values: [t_c, b],
        std_errors: [
            widen(t_c, scale * f.unit_errors[0]),
            widen(b, scale * f.unit_errors[1]),
        ],
        residual: libm::sqrt(sum / speeds.len().max(1) as f64),
    })
}

/// The inertia and its standard error from the spin-up (module documentation,
/// 3), or where it fell short.
fn inertia(g: &Gathered<'_>, v: &VoltageFit, f: &FrictionFit) -> Result<(f64, f64), Shortfall> {
    let top = g.speeds.first().ok_or(Shortfall::NoSpeed)?;
    let mut resolved = g.snapshots.iter().filter(|s| s.resolved());
    let s = resolved
        .clone()
        .find(|s| s.speed >= INERTIA_SPEED_FRACTION * top.speed)
        .or_else(|| resolved.next_back())
        .ok_or(Shortfall::NoTurn)?;
    let k = v.values[1];
    let [t_c, b] = f.values;
    let w2 = s.speed * s.speed;
    let j = 2.0 * (k * s.s_i - t_c * s.s_1 - b * s.s_w) / w2;
    if !(j > 0.0 && j.is_finite()) {
        return Err(Shortfall::NoFit);
    }
    // One count of quantization at each end of the central difference.
    let count_speed = core::f64::consts::TAU
        / (f64::from(g.counts_per_rev) * 2.0 * HALF_WINDOW as f64 * f64::from(g.dt));
    let se_w = count_speed * libm::sqrt(2.0 / 12.0);
    let terms = [
        2.0 * s.s_i / w2 * v.std_errors[1],
        2.0 * s.s_1 / w2 * f.std_errors[0],
        2.0 * s.s_w / w2 * f.std_errors[1],
        2.0 * j * se_w / s.speed,
        2.0 * f64::from(g.load_torque_nm) * s.miss_rad.abs() / w2 / libm::sqrt(3.0),
    ];
    Ok((j, libm::sqrt(terms.iter().map(|t| t * t).sum())))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A current that reads the same every tick (no noise to estimate, as a
    /// quantized reading of a steady current gives): the friction fit still
    /// solves, to the line through the rows.
    #[test]
    fn a_noise_free_current_still_fits() {
        let (t_c, b, k) = (1e-3, 1e-6, 0.02);
        let speeds: [SpeedRow; 4] = [80.0, 64.0, 48.0, 32.0].map(|w| SpeedRow {
            speed_by_angle: w,
            amps_by_angle: (t_c + b * w) / k,
            amps_std_error: 0.0,
            speed: w,
        });
        let v = VoltageFit {
            values: [2.0, k, 0.0, 0.0],
            std_errors: [0.0; 4],
        };
        let f = friction_fit(&speeds, &v).expect("a fit");
        assert!(
            (f.values[0] - t_c).abs() < 1e-9 && (f.values[1] - b).abs() < 1e-12,
            "{f:?}"
        );
    }
}
