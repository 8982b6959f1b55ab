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

/// The identity of one rotor from what its run gathered, or where it fell short.
pub fn identity(g: &Gathered<'_>) -> RotorIdentity {
    // Each row weighted by its own error: the current's and the speed's, through
    // the file's R and k (`sigma_V^2 = (R sigma_i)^2 + (k sigma_w)^2`).
    let (r_file, k_file) = (f64::from(g.file_motor.0), f64::from(g.file_motor.1));
    let mut voltage = LeastSquares::<4>::new();
    for row in g.voltage {
        let se = libm::sqrt(
            (r_file * row.amps_std_error) * (r_file * row.amps_std_error)
                + (k_file * row.speed_std_error) * (k_file * row.speed_std_error),
        )
        .max(f64::MIN_POSITIVE);
        voltage.add(
            [row.amps / se, row.speed / se, 1.0 / se, row.sign / se],
            row.volts / se,
        );
    }
    let Some(v) = voltage.solve() else {
        return RotorIdentity::short(Shortfall::NoFit);
    };
    let [r, k, c0, c1] = v.coefficients;
    if !(r > 0.0 && k > 0.0 && r.is_finite() && k.is_finite()) {
        return RotorIdentity::short(Shortfall::NoFit);
    }
    let v_scale = v.residual_scale.max(1.0);
    let v_se = v.unit_errors.map(|u| v_scale * u);
    // The voltage fit's residual in V, unweighted.
    let voltage_residual = {
        let sum: f64 = g
            .voltage
            .iter()
            .map(|row| {
                let e = row.volts - r * row.amps - k * row.speed - c0 - c1 * row.sign;
                e * e
            })
            .sum();
        libm::sqrt(sum / g.voltage.len().max(1) as f64)
    };
    let k_rel = v_se[1] / k;

    // Each row weighted by its own standard error (the current's, times k), so
    // that the errors come from what was measured, not only from the scatter of
    // four rows about a line; widened by the scatter where it is the larger.
    let mut friction = LeastSquares::<2>::new();
    for row in g.speeds {
        let se = (k * row.amps_std_error).max(f64::MIN_POSITIVE);
        friction.add(
            [1.0 / se, row.speed_by_angle / se],
            k * row.amps_by_angle / se,
        );
    }
    let Some(f) = friction.solve() else {
        return RotorIdentity::short(Shortfall::NoFit);
    };
    let [t_c, b] = f.coefficients;
    let scale = f.residual_scale.max(1.0);
    let widen = |value: f64, se: f64| libm::sqrt(se * se + (value * k_rel) * (value * k_rel));
    let (se_tc, se_b) = (
        widen(t_c, scale * f.unit_errors[0]),
        widen(b, scale * f.unit_errors[1]),
    );
    // The friction fit's residual in N m, unweighted.
    let friction_residual = {
        let sum: f64 = g
            .speeds
            .iter()
            .map(|r| {
                let e = k * r.amps_by_angle - t_c - b * r.speed_by_angle;
                e * e
            })
            .sum();
        libm::sqrt(sum / g.speeds.len().max(1) as f64)
    };

    let Some(top) = g.speeds.first() else {
        return RotorIdentity::short(Shortfall::NoSpeed);
    };
    let mut resolved = g.snapshots.iter().filter(|s| s.resolved());
    let chosen = resolved
        .clone()
        .find(|s| s.speed >= INERTIA_SPEED_FRACTION * top.speed)
        .or_else(|| resolved.next_back());
    let Some(s) = chosen else {
        return RotorIdentity::short(Shortfall::NoTurn);
    };
    let w2 = s.speed * s.speed;
    let work = k * s.s_i - t_c * s.s_1 - b * s.s_w;
    let j = 2.0 * work / w2;
    if !(j > 0.0 && j.is_finite()) {
        return RotorIdentity::short(Shortfall::NoFit);
    }
    // One count of quantization at each end of the central difference.
    let count_speed = core::f64::consts::TAU
        / (f64::from(g.counts_per_rev) * 2.0 * HALF_WINDOW as f64 * f64::from(g.dt));
    let se_w = count_speed * libm::sqrt(2.0 / 12.0);
    let terms = [
        2.0 * s.s_i / w2 * v_se[1],
        2.0 * s.s_1 / w2 * se_tc,
        2.0 * s.s_w / w2 * se_b,
        2.0 * j * se_w / s.speed,
        2.0 * f64::from(g.load_torque_nm) * s.miss_rad.abs() / w2 / libm::sqrt(3.0),
    ];
    let se_j = libm::sqrt(terms.iter().map(|t| t * t).sum());

    let est = |value: f64, se: f64| Estimate {
        value: value as f32,
        std_error: se as f32,
    };
    RotorIdentity {
        shortfall: None,
        resistance_ohm: est(r, v_se[0]),
        torque_constant: est(k, v_se[1]),
        coulomb_friction_nm: est(t_c, se_tc),
        viscous_friction: est(b, se_b),
        inertia_kg_m2: est(j, se_j),
        offset_v: est(c0, v_se[2]),
        drop_v: est(c1, v_se[3]),
        voltage_residual_v: voltage_residual as f32,
        friction_residual_nm: friction_residual as f32,
        standstill_levels: g.levels.0,
        speed_levels: g.levels.1,
    }
}
