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
//! Standard errors: the voltage fit's from its residuals (`s sqrt([(X^T
//! X)^-1]_jj)`, eight degrees of freedom); the friction fit's from its rows' own
//! errors (`sqrt([(X^T W X)^-1]_jj)`, the scatter's `s` taken where it is above
//! 1: four rows say little of their own scatter), widened by `k`'s relative
//! error (the values are proportional to `k`); and the
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
    pub voltage: &'a LeastSquares<4>,
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
    let Some(v) = g.voltage.solve() else {
        return RotorIdentity::short(Shortfall::NoFit);
    };
    let [r, k, c0, c1] = v.coefficients;
    if !(r > 0.0 && k > 0.0 && r.is_finite() && k.is_finite()) {
        return RotorIdentity::short(Shortfall::NoFit);
    }
    let k_rel = v.std_errors[1] / k;

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
        2.0 * s.s_i / w2 * v.std_errors[1],
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
        resistance_ohm: est(r, v.std_errors[0]),
        torque_constant: est(k, v.std_errors[1]),
        coulomb_friction_nm: est(t_c, se_tc),
        viscous_friction: est(b, se_b),
        inertia_kg_m2: est(j, se_j),
        offset_v: est(c0, v.std_errors[2]),
        drop_v: est(c1, v.std_errors[3]),
        voltage_residual_v: v.residual_rms as f32,
        friction_residual_nm: friction_residual as f32,
        standstill_levels: g.levels.0,
        speed_levels: g.levels.1,
    }
}
