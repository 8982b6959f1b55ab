//! The brushed DC motor that turns each unbalance rotor, as the simulator's ODE
//! right-hand side sees it: pure, cheap functions of the winding current and the shaft
//! speed, no state and no allocation.
//!
//! # Model
//!
//! The armature circuit and the torque on the rotor (Franklin, Powell, Emami-Naeini,
//! *Feedback Control of Dynamic Systems*, Sec. 2.3, the DC motor; the same equations
//! in any electrical-drives text), with `omega` the shaft speed relative to the
//! platform in the motor's driven sense:
//!
//! ```text
//!   L di/dt = u - R i - k omega                      (armature circuit)
//!   T       = k i - T_f(omega)                       (torque on the rotor)
//!   T_f     = T_c tanh(omega / omega_s) + b omega    (friction, regularised Coulomb)
//! ```
//!
//! `k` is both the torque constant (N m / A) and the back-EMF constant (V s / rad),
//! equal in SI units by the power balance `u i = R i^2 + d(L i^2 / 2)/dt + k omega i`
//! (the winding's input power goes to copper loss, stored magnetic energy and
//! mechanical power; [`DcMotor::electrical_power`]).
//!
//! # Sense
//!
//! The motor knows only its driven sense. With `s = `[`Sense::sign`] of the rotor and
//! `phi'` the eccentric's angular velocity in the platform frame (ccw positive), the
//! caller passes `omega = s phi'` and applies `s T` to the rotor (ccw positive).
//!
//! # The winding
//!
//! [`Winding`] says what the H-bridge does: a PWM-averaged voltage (`0 V` shorts the
//! winding, which brakes through the back-EMF), or open (coast, no current). The
//! driver's current limit and the open bridge are the two places where the model
//! departs from the linear circuit above; both are documented at
//! [`DcMotor::current_rate`] and [`DcMotor::project_current`].
//!
//! [`Sense::sign`]: crate::machine::Sense::sign

use crate::machine::MotorParams;

/// The speed scale `omega_s` of the regularised Coulomb friction
/// `T_c tanh(omega / omega_s)`, rad/s.
///
/// Coulomb friction is set-valued at zero speed (anything in `[-T_c, T_c]`); the
/// `tanh` makes it a smooth function an explicit ODE solver can integrate. Why
/// `0.01 rad/s`:
/// - accuracy: at the driven speeds (hundreds of rad/s) `tanh` is exactly 1 in `f64`,
///   and below breakaway a rotor loaded by `|T| < T_c` creeps at
///   `omega = omega_s atanh(|T| / T_c)`, at most `0.026 rad/s` (0.25 rpm) for
///   `|T| <= 0.99 T_c`: about 1e-4 of a 3000 rpm operating speed;
/// - stiffness: the friction's slope at zero speed, `T_c / omega_s`, over the rotor
///   inertia `J` is a rate `T_c / (omega_s J)`: `1e4 1/s` for the reference machine
///   (`T_c = 1e-3 N m`, `J = 6e-6 + 0.01 x 0.02^2 = 1e-5 kg m^2`), the same order as
///   the electrical pole `R / L = 4e3 1/s` that already sets the step size. A smaller
///   `omega_s` would buy less creep for a proportionally smaller step.
///
/// The alternative is an explicit stick state (Karnopp, "Computer simulation of
/// stick-slip friction in mechanical dynamic systems", ASME J. Dyn. Syst. Meas.
/// Control 107 (1985) 100-103; Olsson, Åström, Canudas de Wit et al., "Friction
/// models and friction compensation", Eur. J. Control 4 (1998), Sec. 3): the rotor
/// is held at `omega = 0` while the applied torque stays within `T_c`
/// ([`DcMotor::breaks_away`] is that test) and released when it leaves. It is exact
/// at standstill but needs events in the integrator; the rotors here are driven, so
/// creep while stopped is not worth them.
pub const FRICTION_SMOOTHING_SPEED: f64 = 0.01;

/// What the H-bridge puts on a winding.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Winding {
    /// A voltage, V: the bridge conducting (forward, reverse, or both low-side
    /// switches on, `Voltage(0.0)`, which shorts the winding: the back-EMF drives a
    /// braking current), or the exact mean of a slow-decay PWM period
    /// ([`super::bridge`]).
    Voltage(f64),
    /// Every switch off with a supply of this many volts (coast): a current
    /// freewheels through the switches' body diodes against the supply, the
    /// winding seeing `-V_s sign(i)`, until it dies; then no current flows, unless
    /// the back-EMF exceeds the supply, which makes the diodes conduct again.
    /// (Diode forward drops are not modelled: about 1 V against 12 V.)
    Coast(f64),
    /// An ideal open circuit: no current, ever (the current is set to 0). For
    /// tests that want the motors out of the way; a bridge coasts instead.
    Open,
}

/// A brushed DC motor: its constant parameters and the model's functions.
#[derive(Clone, Debug, PartialEq)]
pub struct DcMotor {
    /// Resistance, inductance, torque constant, friction, current limit.
    pub params: MotorParams,
}

impl DcMotor {
    /// The motor with these parameters.
    pub fn new(params: MotorParams) -> Self {
        DcMotor { params }
    }

    /// The back-EMF `e = k omega`, V, at shaft speed `omega_m` (rad/s, driven sense).
    pub fn back_emf(&self, omega_m: f64) -> f64 {
        self.params.torque_constant * omega_m
    }

    /// The electromagnetic torque `k i`, N m, driven sense.
    pub fn electromagnetic_torque(&self, i: f64) -> f64 {
        self.params.torque_constant * i
    }

    /// The friction torque opposing the shaft's motion, N m (positive when
    /// `omega_m > 0`): `T_c tanh(omega / omega_s) + b omega`, with
    /// `omega_s = `[`FRICTION_SMOOTHING_SPEED`].
    pub fn friction_torque(&self, omega_m: f64) -> f64 {
        let p = &self.params;
        // Regularised Coulomb (odd, bounded by T_c) plus viscous.
        p.coulomb_friction * (omega_m / FRICTION_SMOOTHING_SPEED).tanh()
            + p.viscous_friction * omega_m
    }

    /// Whether a shaft at rest starts turning under `applied_torque` (N m, all torques
    /// on the rotor but friction): `|T| > T_c`. The exit test of a stick state
    /// (see [`FRICTION_SMOOTHING_SPEED`] for why the simulator does not use one).
    pub fn breaks_away(&self, applied_torque: f64) -> bool {
        applied_torque.abs() > self.params.coulomb_friction
    }

    /// The torque the motor puts on its rotor, N m, driven sense: electromagnetic
    /// minus friction, `T = k i - T_c tanh(omega / omega_s) - b omega`.
    pub fn shaft_torque(&self, i: f64, omega_m: f64) -> f64 {
        self.electromagnetic_torque(i) - self.friction_torque(omega_m)
    }

    /// Whether the driver's current limit is acting: `|i| >= I_lim` and the applied
    /// voltage would push the current further out (`u - R i - k omega` of the sign of
    /// `i`). Never for an open winding.
    pub fn is_limiting(&self, winding: Winding, i: f64, omega_m: f64) -> bool {
        match winding {
            Winding::Open | Winding::Coast(_) => false,
            Winding::Voltage(u) => {
                let p = &self.params;
                let drive = u - p.resistance * i - self.back_emf(omega_m);
                (i >= p.current_limit && drive > 0.0) || (i <= -p.current_limit && drive < 0.0)
            }
        }
    }

    /// The winding's terminal voltage, V: what the bridge effectively applies.
    ///
    /// - `Voltage(u)`, not limiting: `u`;
    /// - `Voltage(u)`, limiting: `R i + k omega`, the voltage that holds `di/dt = 0`
    ///   (the chopper's average over its on/off cycle);
    /// - `Open`: `R i + k omega`, which is the back-EMF `k omega` since an open winding
    ///   carries no current;
    /// - `Coast(V_s)`: `-V_s sign(i)` while a current freewheels through the diodes;
    ///   without current the back-EMF, clamped to `+-V_s` by the diodes.
    pub fn terminal_voltage(&self, winding: Winding, i: f64, omega_m: f64) -> f64 {
        let p = &self.params;
        let holding = p.resistance * i + self.back_emf(omega_m);
        match winding {
            Winding::Voltage(_) if self.is_limiting(winding, i, omega_m) => holding,
            Winding::Voltage(u) => u,
            Winding::Open => holding,
            Winding::Coast(supply) => {
                if i > 0.0 {
                    -supply
                } else if i < 0.0 {
                    supply
                } else {
                    self.back_emf(omega_m).clamp(-supply, supply)
                }
            }
        }
    }

    /// The rate of the winding current, A/s:
    ///
    /// ```text
    ///   di/dt = (u - R i - k omega) / L
    /// ```
    ///
    /// with two departures from the circuit:
    /// - **Current limit.** When `|i| >= I_lim` and `u` would push the current further
    ///   out, `di/dt = 0`. This is the driver's cycle-by-cycle chopper (the current
    ///   regulation of integrated H-bridge drivers): on reaching the limit it switches
    ///   off until the current has decayed, which, averaged over the chopping period,
    ///   lowers the effective voltage to `R i + k omega`
    ///   ([`DcMotor::terminal_voltage`]). The limit acts in both signs, for driving
    ///   and for braking currents alike, as docs/machine-file.md says of
    ///   `motor.current_limit`: "the driver clamps the winding current to +- this".
    ///   Idealisation: the chopper can always find that voltage (true while
    ///   `|R I_lim + k omega|` stays within the supply). An integrator step that
    ///   crosses the limit overshoots it by `O(h di/dt)`; the integrator clamps the
    ///   state with [`DcMotor::clamp_current`] after each step.
    /// - **Open winding.** `di/dt = 0`: the current is forced to 0 when the bridge
    ///   opens ([`DcMotor::project_current`]) and stays there.
    /// - **Coasting bridge.** The body diodes put `-V_s sign(i)` on the winding
    ///   while a current flows: `L di/dt = -V_s sign(i) - R i - k omega`, which
    ///   drives it to zero (`L |i| / (V_s + k omega)` at most, some 80 us at 2 A);
    ///   the plant stops it there (an event) and then `di/dt = 0`, unless the
    ///   back-EMF exceeds the supply: then the diodes conduct,
    ///   `L di/dt = V_s sign(k omega) - k omega`.
    pub fn current_rate(&self, winding: Winding, i: f64, omega_m: f64) -> f64 {
        match winding {
            Winding::Open => 0.0,
            Winding::Coast(_) => {
                // The diodes' voltage (`terminal_voltage`): `-V_s sign(i)` while a
                // current flows; without one the back-EMF clamped to the supply,
                // which holds the current at zero until the back-EMF exceeds it.
                let p = &self.params;
                let u = self.terminal_voltage(winding, i, omega_m);
                (u - p.resistance * i - self.back_emf(omega_m)) / p.inductance
            }
            Winding::Voltage(u) => {
                if self.is_limiting(winding, i, omega_m) {
                    return 0.0;
                }
                let p = &self.params;
                (u - p.resistance * i - self.back_emf(omega_m)) / p.inductance
            }
        }
    }

    /// The current held within the driver's limit, `clamp(i, -I_lim, I_lim)`, A: what
    /// the integrator stores after each step (see [`DcMotor::current_rate`]). Never
    /// panics (a negative or NaN limit is the input checker's to refuse).
    pub fn clamp_current(&self, i: f64) -> f64 {
        let limit = self.params.current_limit;
        i.max(-limit).min(limit)
    }

    /// The admissible current for the winding state, A: `0` when open, otherwise
    /// [`DcMotor::clamp_current`]. The integrator applies it after each step and
    /// whenever the winding changes.
    ///
    /// A coasting winding's current is not clamped: it only decays (the driver's
    /// limit does not act with the switches off).
    pub fn project_current(&self, winding: Winding, i: f64) -> f64 {
        match winding {
            Winding::Open => 0.0,
            Winding::Coast(_) => i,
            Winding::Voltage(_) => self.clamp_current(i),
        }
    }

    /// The power the bridge delivers into the winding, W (negative when the winding
    /// returns energy): `P = u_t i` with `u_t` the [`DcMotor::terminal_voltage`]. It
    /// balances `R i^2 + L i di/dt + k omega i` (copper loss, rate of magnetic energy,
    /// mechanical power before friction).
    pub fn electrical_power(&self, winding: Winding, i: f64, omega_m: f64) -> f64 {
        self.terminal_voltage(winding, i, omega_m) * i
    }

    /// The copper loss `R i^2`, W.
    pub fn copper_loss(&self, i: f64) -> f64 {
        self.params.resistance * i * i
    }

    /// The steady speed under a constant winding voltage `u` with no load but the
    /// motor's own friction (exact Coulomb law), rad/s, driven sense:
    ///
    /// ```text
    ///   k (u - k omega) / R = T_c sign(omega) + b omega
    ///   =>  omega = (k u - R T_c sign(u)) / (k^2 + R b)   if |k u| > R T_c, else 0
    /// ```
    ///
    /// (`omega = k u / (R b + k^2)` without Coulomb friction). Assumes the steady
    /// current `(T_c + b |omega|) / k` is within the limit.
    pub fn steady_speed(&self, u: f64) -> f64 {
        let p = &self.params;
        let k = p.torque_constant;
        let drive = k * u;
        let stiction = p.resistance * p.coulomb_friction;
        if drive.abs() <= stiction {
            return 0.0;
        }
        (drive - stiction * drive.signum()) / (k * k + p.resistance * p.viscous_friction)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The reference machine's motor (`examples/vibro-driver.toml`).
    fn reference() -> MotorParams {
        MotorParams {
            resistance: 2.0,
            inductance: 0.5e-3,
            torque_constant: 0.02,
            coulomb_friction: 1.0e-3,
            viscous_friction: 1.0e-6,
            current_limit: 2.0,
        }
    }

    /// The reference rotor's inertia about its axis with the eccentric mass,
    /// `6e-6 + 0.01 x 0.02^2`, kg m^2.
    const J: f64 = 1.0e-5;

    /// The reference motor without friction or current limit: the linear circuit.
    fn linear() -> DcMotor {
        DcMotor::new(MotorParams {
            coulomb_friction: 0.0,
            viscous_friction: 0.0,
            current_limit: f64::INFINITY,
            ..reference()
        })
    }

    /// Motor plus a rotor of inertia `J` on a fixed platform: `(i, omega)` after `steps`
    /// classical RK4 steps of size `h`, projecting the current after each step as the
    /// simulator's integrator does. `observe(t, i, omega)` sees every step.
    fn integrate(
        motor: &DcMotor,
        winding: Winding,
        (i0, w0): (f64, f64),
        h: f64,
        steps: usize,
        mut observe: impl FnMut(f64, f64, f64),
    ) -> (f64, f64) {
        let f = |i: f64, w: f64| {
            (
                motor.current_rate(winding, i, w),
                motor.shaft_torque(i, w) / J,
            )
        };
        let (mut i, mut w) = (motor.project_current(winding, i0), w0);
        for n in 0..steps {
            let k1 = f(i, w);
            let k2 = f(i + 0.5 * h * k1.0, w + 0.5 * h * k1.1);
            let k3 = f(i + 0.5 * h * k2.0, w + 0.5 * h * k2.1);
            let k4 = f(i + h * k3.0, w + h * k3.1);
            i += h / 6.0 * (k1.0 + 2.0 * k2.0 + 2.0 * k3.0 + k4.0);
            w += h / 6.0 * (k1.1 + 2.0 * k2.1 + 2.0 * k3.1 + k4.1);
            i = motor.project_current(winding, i);
            observe((n + 1) as f64 * h, i, w);
        }
        (i, w)
    }

    /// The rotor's speed after 1.5 s at the constant voltage `u` from rest, in steps
    /// of 10 us.
    fn speed_after_1_5_s(motor: &DcMotor, u: f64) -> f64 {
        let (_, w) = integrate(
            motor,
            Winding::Voltage(u),
            (0.0, 0.0),
            1e-5,
            150_000,
            |_, _, _| {},
        );
        w
    }

    /// The poles `p1` (slow), `p2` (fast) of `L J s^2 + R J s + k^2 = 0`.
    fn poles(m: &DcMotor) -> (f64, f64) {
        let p = &m.params;
        let (a, b, c) = (
            p.inductance * J,
            p.resistance * J,
            p.torque_constant.powi(2),
        );
        let d = (b * b - 4.0 * a * c).sqrt();
        ((-b + d) / (2.0 * a), (-b - d) / (2.0 * a))
    }

    #[test]
    fn step_response_matches_the_second_order_closed_form() {
        // From rest, u = 12 V: omega(t) = omega_ss (1 + (p2 e^{p1 t} - p1 e^{p2 t}) /
        // (p1 - p2)), omega_ss = u / k, and i = (J / k) omega' =
        // (J / k) omega_ss p1 p2 (e^{p1 t} - e^{p2 t}) / (p1 - p2).
        let m = linear();
        let (p1, p2) = poles(&m);
        assert!(p2 < p1 && p1 < 0.0, "two real poles: {p1}, {p2}");
        let u = 12.0;
        let k = m.params.torque_constant;
        let w_ss = u / k;
        let mut worst = (0.0f64, 0.0f64);
        integrate(
            &m,
            Winding::Voltage(u),
            (0.0, 0.0),
            1e-6,
            250_000,
            |t, i, w| {
                let (e1, e2) = ((p1 * t).exp(), (p2 * t).exp());
                let w_exact = w_ss * (1.0 + (p2 * e1 - p1 * e2) / (p1 - p2));
                let i_exact = J / k * w_ss * p1 * p2 * (e1 - e2) / (p1 - p2);
                worst.0 = worst.0.max((w - w_exact).abs());
                worst.1 = worst.1.max((i - i_exact).abs());
            },
        );
        // RK4 with h |p2| = 4e-3: global error ~ (h p2)^4 = 3e-10 relative at most
        // (observed 2e-14 in speed, 8e-13 in current).
        assert!(worst.0 < 1e-10 * w_ss, "speed error {}", worst.0);
        assert!(
            worst.1 < 1e-10 * u / m.params.resistance,
            "current error {}",
            worst.1
        );
    }

    #[test]
    fn short_circuit_brake_matches_the_free_response() {
        // Shorted winding (0 V) from omega0, i = 0: by linearity the free response
        // omega(t) = -omega0 (p2 e^{p1 t} - p1 e^{p2 t}) / (p1 - p2).
        let m = linear();
        let (p1, p2) = poles(&m);
        let w0 = 300.0;
        let mut worst = 0.0f64;
        let (i, w) = integrate(
            &m,
            Winding::Voltage(0.0),
            (0.0, w0),
            1e-6,
            100_000,
            |t, i, w| {
                let exact = -w0 * (p2 * (p1 * t).exp() - p1 * (p2 * t).exp()) / (p1 - p2);
                worst = worst.max((w - exact).abs());
                // The braking current opposes the motion.
                assert!(i <= 0.0);
            },
        );
        assert!(worst < 1e-10 * w0, "speed error {worst}");
        assert!(w < w0 && i < 0.0);
    }

    #[test]
    fn no_load_speed_with_viscous_friction_is_k_u_over_r_b_plus_k_squared() {
        // Steady state of k (u - k omega) / R = b omega: omega = k u / (R b + k^2).
        let m = DcMotor::new(MotorParams {
            coulomb_friction: 0.0,
            current_limit: f64::INFINITY,
            ..reference()
        });
        let p = &m.params;
        let u = 6.0;
        let exact =
            p.torque_constant * u / (p.resistance * p.viscous_friction + p.torque_constant.powi(2));
        assert!((m.steady_speed(u) - exact).abs() < 1e-12 * exact);
        // Mechanical time constant J R / (k^2 + R b) ~ 50 ms: 1.5 s is 30 of them.
        let w = speed_after_1_5_s(&m, u);
        assert!((w - exact).abs() < 1e-9 * exact, "{w} vs {exact}");
    }

    #[test]
    fn steady_speed_with_coulomb_friction_matches_simulation() {
        // (k u - R T_c) / (k^2 + R b); tanh(omega / omega_s) is 1 in f64 at this speed.
        let m = DcMotor::new(MotorParams {
            current_limit: f64::INFINITY,
            ..reference()
        });
        let u = 6.0;
        let exact = m.steady_speed(u);
        assert!((exact - (0.02 * 6.0 - 2.0e-3) / (4e-4 + 2e-6)).abs() < 1e-9);
        let w = speed_after_1_5_s(&m, u);
        assert!((w - exact).abs() < 1e-9 * exact, "{w} vs {exact}");
        // Odd in u, and zero below breakaway.
        assert_eq!(m.steady_speed(-u), -exact);
        assert_eq!(m.steady_speed(0.09), 0.0);
    }

    #[test]
    fn current_limit_holds_and_the_speed_rises_linearly() {
        // 12 V from rest would draw u / R = 6 A; the driver holds 2 A, so the rotor
        // accelerates at (k I_lim - T_c) / J (no viscous friction here) until the back-
        // EMF leaves too little voltage: u - R I_lim - k omega < 0 at omega = 400 rad/s.
        let m = DcMotor::new(MotorParams {
            viscous_friction: 0.0,
            ..reference()
        });
        let p = m.params.clone();
        let slope = (p.torque_constant * p.current_limit - p.coulomb_friction) / J;
        let release = (12.0 - p.resistance * p.current_limit) / p.torque_constant;
        let h = 1e-6;
        let (mut w1, mut w2, mut peak) = (f64::NAN, f64::NAN, 0.0f64);
        let mut released_at = f64::NAN;
        integrate(
            &m,
            Winding::Voltage(12.0),
            (0.0, 0.0),
            h,
            200_000,
            |t, i, w| {
                peak = peak.max(i.abs());
                // Engaged after L I / u ~ 83 us; check a window well inside the limited phase.
                if (t - 0.005).abs() < 0.5 * h {
                    w1 = w;
                    assert_eq!(i, p.current_limit);
                }
                if (t - 0.05).abs() < 0.5 * h {
                    w2 = w;
                    assert_eq!(i, p.current_limit);
                }
                if released_at.is_nan() && i < p.current_limit && t > 0.005 {
                    released_at = w;
                }
            },
        );
        assert!(peak <= p.current_limit, "peak current {peak}");
        let rise = w2 - w1;
        let expected = slope * (0.05 - 0.005);
        assert!(
            (rise - expected).abs() < 1e-9 * expected,
            "{rise} vs {expected}"
        );
        // The limit lets go where the bridge can no longer push more current.
        assert!(
            (released_at - release).abs() < 1e-3 * release,
            "{released_at}"
        );
    }

    #[test]
    fn open_winding_coasts_on_friction_alone() {
        // i = 0, J omega' = -T_c - b omega: omega(t) = (omega0 + T_c / b) e^{-b t / J}
        // - T_c / b while omega >> omega_s.
        let m = DcMotor::new(reference());
        let p = m.params.clone();
        let w0 = 300.0;
        let tc_b = p.coulomb_friction / p.viscous_friction;
        let mut worst = 0.0f64;
        // Starts with 1.5 A flowing: the open bridge forces it to 0 at once.
        integrate(&m, Winding::Open, (1.5, w0), 1e-5, 100_000, |t, i, w| {
            assert_eq!(i, 0.0);
            let exact = (w0 + tc_b) * (-p.viscous_friction * t / J).exp() - tc_b;
            worst = worst.max((w - exact).abs());
        });
        assert!(worst < 1e-9 * w0, "speed error {worst}");
        assert_eq!(m.current_rate(Winding::Open, 0.0, w0), 0.0);
        assert_eq!(m.electrical_power(Winding::Open, 0.0, w0), 0.0);
        assert_eq!(m.terminal_voltage(Winding::Open, 0.0, w0), m.back_emf(w0));
    }

    /// A coasting winding: the body diodes put `-V_s sign(i)` on it while a current
    /// flows (`L di/dt = -V_s sign(i) - R i - k omega`), nothing once it has died,
    /// unless the back-EMF exceeds the supply, and no current limit acts.
    #[test]
    fn a_coasting_current_freewheels_against_the_supply() {
        let m = DcMotor::new(reference());
        let coast = Winding::Coast(12.0);
        let (r, l, k) = (2.0, 0.5e-3, 0.02);
        for (i, w) in [(1.5, 0.0), (-1.5, 100.0), (0.3, -300.0)] {
            let u = -12.0 * f64::signum(i);
            let want = (u - r * i - k * w) / l;
            assert!((m.current_rate(coast, i, w) - want).abs() < 1e-9 * want.abs());
            assert_eq!(m.terminal_voltage(coast, i, w), u);
        }
        // No current and a back-EMF within the supply: nothing flows.
        assert_eq!(m.current_rate(coast, 0.0, 300.0), 0.0);
        assert_eq!(m.terminal_voltage(coast, 0.0, 300.0), 6.0);
        // A back-EMF above the supply (900 rad/s: 18 V): the diodes conduct.
        assert!((m.current_rate(coast, 0.0, 900.0) - (12.0 - 18.0) / l).abs() < 1e-6);
        assert!(!m.is_limiting(coast, 5.0, 0.0));
        assert_eq!(m.project_current(coast, 5.0), 5.0);
    }

    #[test]
    fn friction_is_coulomb_plus_viscous_away_from_zero() {
        let m = DcMotor::new(reference());
        assert_eq!(m.friction_torque(0.0), 0.0);
        assert!((m.friction_torque(100.0) - 1.1e-3).abs() < 1e-18);
        assert!((m.friction_torque(-100.0) + 1.1e-3).abs() < 1e-18);
        // One smoothing speed: tanh(1) of T_c.
        let at_s = m.friction_torque(FRICTION_SMOOTHING_SPEED);
        assert!((at_s - (1.0e-3 * 1f64.tanh() + 1e-8)).abs() < 1e-18);
        assert!(m.breaks_away(1.1e-3) && m.breaks_away(-1.1e-3));
        assert!(!m.breaks_away(0.9e-3));
    }

    proptest! {
        #[test]
        fn power_balances_copper_loss_magnetic_and_mechanical(
            u in -24.0f64..24.0, i in -3.0f64..3.0, w in -800.0f64..800.0,
        ) {
            // u_t i = R i^2 + L i di/dt + k omega i, limiting or not.
            let m = DcMotor::new(reference());
            let win = Winding::Voltage(u);
            let p = &m.params;
            let i = m.clamp_current(i);
            let rhs = m.copper_loss(i)
                + p.inductance * i * m.current_rate(win, i, w)
                + m.back_emf(w) * i;
            let lhs = m.electrical_power(win, i, w);
            prop_assert!((lhs - rhs).abs() <= 1e-12 * (1.0 + lhs.abs() + rhs.abs()));
        }

        #[test]
        fn current_rate_never_pushes_past_the_limit(
            u in -24.0f64..24.0, s in -1.0f64..1.0, w in -800.0f64..800.0,
        ) {
            // At the limit, di/dt points inward or is zero.
            let m = DcMotor::new(reference());
            let i = 2.0 * s.signum();
            prop_assert!(i * m.current_rate(Winding::Voltage(u), i, w) <= 0.0);
            prop_assert!(m.clamp_current(3.0 * s).abs() <= 2.0);
        }

        #[test]
        fn friction_is_odd_and_within_coulomb_of_viscous(w in -1000.0f64..1000.0) {
            let m = DcMotor::new(reference());
            prop_assert_eq!(m.friction_torque(-w), -m.friction_torque(w));
            let coulomb = m.friction_torque(w) - m.params.viscous_friction * w;
            prop_assert!(coulomb.abs() <= m.params.coulomb_friction * (1.0 + 1e-15));
            prop_assert!(coulomb * w >= 0.0);
        }
    }
}
