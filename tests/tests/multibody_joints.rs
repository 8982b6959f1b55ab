//! The plant's revolute joints (issue 12) against references written here from the
//! test's own geometry: closed forms, normal modes and conservation laws. The plant
//! is only read (its state); positions, velocities, momenta and energies are
//! computed below from the machine's numbers.
//!
//! - a damped swing on a joint's spring-damper: the zero crossings of the angular
//!   velocity half a damped period apart, the turning points shrinking by the
//!   logarithmic decrement;
//! - a spring with a `rest_angle` against gravity: the static balance, and its sign
//!   when the joint's bodies are given the other way round; without gravity and
//!   without a `rest_angle` the arm stays at its file angle;
//! - a free platform with an arm on a spring-damper: linear momentum, angular
//!   momentum and the energy balance (kinetic + spring + dissipated) kept, the
//!   joint's torque acting on both bodies;
//! - a double compound pendulum (a chain of two joints with a pinned root): the
//!   period of each normal mode from `det(K - w^2 M) = 0`;
//! - a rotor driven on a pinned arm: the angular momentum about the pivot stays
//!   zero, `J_O theta' + I_k (theta' + phi') = 0`; with every body held, only the
//!   rotor turns.
//!
//! Every machine has the platform lifted 1 m clear of the floor (its one foot
//! 0.97 m above it) and one rotor; where the platform plays no part it is held.

use std::f64::consts::PI;
use tests::initial_state;
use tests::machine::{TestMachine, DRIVE_12V, FRICTIONLESS_MOTOR, REFERENCE_MOTOR};

use host_sim::machine::joint_limits::effective_inertia;
use host_sim::machine::Machine;
use host_sim::plant::model::NY;
use host_sim::plant::model::{Mount, PlantModel};
use host_sim::plant::motor::Winding;
use host_sim::plant::simulator::{Holds, Output, Plant, Settings};
use shared::vec2::{add, cross, spin, sub};
use tests::rig::rot;

/// The platform: mass, kg; inertia about its centre of mass, kg m^2; centre of
/// mass at t = 0, m.
const PLATFORM_MASS: f64 = 2.0;
const PLATFORM_INERTIA: f64 = 7.3e-3;
const PLATFORM_CENTRE: [f64; 2] = [0.0, 1.0];

/// A rotor that does nothing: no eccentric mass, on the platform, inertia 1e-5
/// kg m^2. With the winding open (the plant starts so) and a motor without
/// friction nothing acts on it: it keeps its own speed `theta_p' + phi'`.
const INERT_ROTOR: &str = r#"
[[rotors]]
name = "R1"
body = "platform"
axis = [0.0, 1.0]
eccentric_mass = 0.0
eccentricity = 0.0
inertia = 1e-5
sense = "ccw"
"#;

/// The inert rotor's inertia, kg m^2.
const INERT_ROTOR_INERTIA: f64 = 1e-5;

/// The machine: gravity `(0, -g)`, the platform (with `platform` keys added:
/// velocities, angle), `rotor` and `motor` as TOML tables, then `extra` (bodies and
/// joints).
fn machine(g: f64, platform: &str, rotor: &str, motor: &str, extra: &str) -> Machine {
    let text = format!(
        r#"[fundament]
gravity = [0.0, {:?}]

[platform]
mass = {PLATFORM_MASS:?}
inertia = {PLATFORM_INERTIA:?}
position = {}
{platform}
[[contacts]]
name = "K1"
point = [-0.08, 0.97]
restitution = 0.3
friction = 0.0
{rotor}
{motor}
{extra}"#,
        -g,
        vector(PLATFORM_CENTRE),
    );
    TestMachine::new("joints.toml")
        .with(&text)
        .with(DRIVE_12V)
        .machine()
}

/// `[x, y]` in TOML.
fn vector(v: [f64; 2]) -> String {
    format!("[{:?}, {:?}]", v[0], v[1])
}

/// `(cos a, sin a)`.
fn unit(a: f64) -> [f64; 2] {
    let (s, c) = a.sin_cos();
    [c, s]
}

/// `a v`.
fn scale(a: f64, v: [f64; 2]) -> [f64; 2] {
    [a * v[0], a * v[1]]
}

/// A `[[bodies]]` table: centre of mass `com`, angle, velocities at t = 0.
fn body(name: &str, mass: f64, inertia: f64, com: [f64; 2], angle: f64) -> String {
    moving_body(name, mass, inertia, com, angle, [0.0, 0.0], 0.0)
}

fn moving_body(
    name: &str,
    mass: f64,
    inertia: f64,
    com: [f64; 2],
    angle: f64,
    velocity: [f64; 2],
    angular_velocity: f64,
) -> String {
    format!(
        r#"
[[bodies]]
name = "{name}"
mass = {mass:?}
inertia = {inertia:?}
position = {}
angle = {angle:?}
velocity = {}
angular_velocity = {angular_velocity:?}
"#,
        vector(com),
        vector(velocity)
    )
}

/// A revolute `[[joints]]` table between `a` and `b` at `point`; `rest_angle`
/// omitted when `None` (the relative angle at t = 0).
fn joint(
    name: &str,
    a: &str,
    b: &str,
    point: [f64; 2],
    stiffness: f64,
    damping: f64,
    rest_angle: Option<f64>,
) -> String {
    let rest = rest_angle.map_or(String::new(), |r| format!("rest_angle = {r:?}\n"));
    format!(
        r#"
[[joints]]
name = "{name}"
kind = "revolute"
bodies = ["{a}", "{b}"]
point = {}
stiffness = {stiffness:?}
damping = {damping:?}
{rest}"#,
        vector(point)
    )
}

/// The arm of most tests: 0.3 kg, 1e-3 kg m^2 about its centre of mass, which lies
/// `ARM_D` from the hinge along the arm's own x axis. Its inertia about the hinge
/// (Steiner): `J_h = I_c + m d^2 = 4e-3` kg m^2.
const ARM_MASS: f64 = 0.3;
const ARM_INERTIA: f64 = 1e-3;
const ARM_D: f64 = 0.1;
const ARM_J_HINGE: f64 = ARM_INERTIA + ARM_MASS * ARM_D * ARM_D;

/// The arm hinged at `hinge` at angle `angle`, at rest.
fn arm_at(hinge: [f64; 2], angle: f64) -> String {
    body(
        "arm",
        ARM_MASS,
        ARM_INERTIA,
        add(hinge, scale(ARM_D, unit(angle))),
        angle,
    )
}

/// The platform held (its `x, y, theta`), where it plays no part.
fn platform_held() -> Holds {
    Holds {
        platform: true,
        ..Holds::default()
    }
}

/// Every instant in `(0, t_end]` at which `y[w]` crosses zero, with the state
/// there: found on each accepted step's dense output (the integrator's 4th-order
/// interpolant), the crossing bracketed between the step's ends and bisected to
/// the last bit. The sign of `y[w]` before the crossing comes with it.
fn crossings(plant: &mut Plant, w: usize, t_end: f64) -> Vec<(f64, [f64; NY], f64)> {
    let mut found = Vec::new();
    plant
        .advance_to(t_end, &mut |out| {
            if let Output::Dense(step, upto) = out {
                let f = |t: f64| step.at(t)[w];
                let (mut lo, mut hi) = (step.t0, upto);
                let (f_lo, f_hi) = (f(lo), f(hi));
                if !((f_lo > 0.0 && f_hi <= 0.0) || (f_lo < 0.0 && f_hi >= 0.0)) {
                    return;
                }
                let before = f_lo.signum();
                for _ in 0..200 {
                    let mid = 0.5 * (lo + hi);
                    if mid <= lo || mid >= hi {
                        break;
                    }
                    if f(mid) * before > 0.0 {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                // The end nearer zero.
                let t = if f(lo).abs() < f(hi).abs() { lo } else { hi };
                found.push((t, step.at(t), before));
            }
        })
        .unwrap();
    found
}

/// A scalar function of the plant's state.
type StateFunction<'a> = dyn Fn(&[f64; NY]) -> f64 + 'a;

/// The integrator's per-step error allowance for a scalar function `f` of the
/// state (the approach of `tests/src/rig.rs`, `step_allowance`, for a machine of
/// several bodies). The plant's Dormand-Prince controller (`simulator.rs`,
/// `tolerance`) accepts a step when `sqrt(mean_i (e_i / sc_i)^2) <= 1` over the
/// machine's `ny` state components, `sc_i = atol_i + rtol |y_i|`, `atol` being
/// `1e-3 rtol` on the position of a free body, `rtol` times the current limit on a
/// winding current and `rtol` elsewhere. Then `sum_i (e_i / sc_i)^2 <= ny` and by
/// Cauchy-Schwarz the error the step puts into `f` is at most
/// `sqrt(ny) |grad f o sc|_2`, the gradient taken here by central differences.
fn step_allowance(
    model: &PlantModel,
    current_limit: f64,
    f: &StateFunction<'_>,
    y: &[f64; NY],
    rtol: f64,
) -> f64 {
    let ny = model.ny();
    let mut atol = [rtol; NY];
    for b in &model.bodies {
        if let Mount::Free { x } = b.mount {
            atol[x] = 1e-3 * rtol;
            atol[x + 1] = 1e-3 * rtol;
        }
    }
    for k in 0..model.rotors.len() {
        atol[model.current(k)] = rtol * current_limit;
    }
    let mut sum = 0.0;
    for i in 0..ny {
        let sc = atol[i] + rtol * y[i].abs();
        let h = 1e-6 * (1.0 + y[i].abs());
        let (mut up, mut down) = (*y, *y);
        up[i] += h;
        down[i] -= h;
        let g = (f(&up) - f(&down)) / (2.0 * h);
        sum += (g * sc) * (g * sc);
    }
    (ny as f64).sqrt() * sum.sqrt()
}

// ---------------------------------------------------------------------------------
// 1: the damped swing
// ---------------------------------------------------------------------------------

/// The arm on a torsional spring-damper hinged to the held platform, no gravity:
///
/// ```text
///   J_h theta'' + c theta' + k theta = 0            (N m; theta in rad)
///   omega_n = sqrt(k / J_h),  zeta = c / (2 sqrt(k J_h)),  omega_d = omega_n sqrt(1 - zeta^2)
///   theta(t) = A exp(-zeta omega_n t) cos(omega_d t + psi)
/// ```
///
/// (Meirovitch, *Elements of Vibration Analysis*, 2nd ed., 1986: the free
/// vibration of the damped single-degree-of-freedom system and its logarithmic
/// decrement). Its velocity is
/// `-A omega_n exp(-zeta omega_n t) sin(omega_d t + psi + beta)` with a constant
/// `beta`, so its zeros are exactly `pi / omega_d` s apart, and the angle there
/// (the turning points, alternately either side of the rest angle) shrinks by
/// `exp(-pi zeta / sqrt(1 - zeta^2))` from one to the next, by
/// `exp(-2 pi zeta / sqrt(1 - zeta^2))` over a whole period (the logarithmic
/// decrement `delta = 2 pi zeta / sqrt(1 - zeta^2)`).
///
/// The equation is exact for the plant's model here: with the platform held the
/// hinge is fixed and the arm's world angle is the joint's relative angle; the
/// spring-damper is linear, nothing else acts (no gravity, the rotor on the held
/// platform has no coupling to the arm), so there is no small-angle error and the
/// arm is started 0.2 rad from rest.
#[test]
fn a_damped_swing_has_the_damped_period_and_the_logarithmic_decrement() {
    let (k, zeta) = (5.0, 0.02);
    let c = 2.0 * zeta * (k * ARM_J_HINGE).sqrt();
    let hinge = [0.15, 1.03];
    let angle0 = 0.2;
    let extra = format!(
        "{}{}",
        arm_at(hinge, angle0),
        joint("hinge", "platform", "arm", hinge, k, c, Some(0.0))
    );
    let m = machine(0.0, "", INERT_ROTOR, FRICTIONLESS_MOTOR, &extra);
    let model = PlantModel::new(&m);
    assert_eq!(model.dof, 5, "platform x, y, theta; the arm; the rotor");
    assert!(matches!(
        model.bodies[1].mount,
        Mount::Child { parent: 0, .. }
    ));
    let angle = model.bodies[1].angle;
    let omega = model.dof + angle;
    let mut plant = Plant::new(
        model,
        initial_state(&m),
        Settings::default(),
        platform_held(),
    );
    let found = crossings(&mut plant, omega, 1.5);

    let omega_n = (k / ARM_J_HINGE).sqrt();
    let root = (1.0 - zeta * zeta).sqrt();
    let half = PI / (omega_n * root);
    let ratio_half = (-PI * zeta / root).exp();
    let ratio_full = (-2.0 * PI * zeta / root).exp();
    assert!(found.len() >= 15, "{} turning points", found.len());

    // Tolerances. The plant's integrator keeps each step's local error within
    // `atol + rtol |y|` = 1e-8 (1 + |y|) (rad, rad/s) and its steps are at most
    // 1e-3 s (about 180 per period, `omega_n h` = 0.035: the 5th-order method's
    // local error `(omega_n h)^6 ~ 2e-9` of the amplitude, below the controller's
    // bound). A crossing's time moves by the velocity's error over the slope
    // there, `|omega'| = omega_n^2 A >= 1250 x 0.065 = 81 rad/s^2` (A >= 0.065 rad
    // over the run): 8e-8 rad/s / 81 rad/s^2 = 1e-9 s per local error, 1.1e-8 of
    // the half period 0.089 s; the global error is a sum of such local errors
    // carried along (a phase drift over ~1500 steps, a few 1e-7 of the half
    // period at the worst). 1e-6 of the half period bounds the spacing. The
    // turning points' angles do not depend on the crossing time to first order
    // (theta' = 0 there): their error is the angle's, 1e-8 (1 + A) rad per step
    // carried along, at most a few 1e-6 of A >= 0.065 rad; 1e-5 bounds the ratios.
    let mut worst = [0.0f64; 3];
    for w in found.windows(2) {
        let ((t0, y0, _), (t1, y1, _)) = (w[0], w[1]);
        let spacing = (t1 - t0 - half) / half;
        worst[0] = worst[0].max(spacing.abs());
        assert!(
            spacing.abs() < 1e-6,
            "omega crosses zero at {t0} s and {t1} s: {} s apart, pi / omega_d = {half} s",
            t1 - t0
        );
        let r = -y1[angle] / y0[angle];
        worst[1] = worst[1].max((r / ratio_half - 1.0).abs());
        assert!(
            (r / ratio_half - 1.0).abs() < 1e-5,
            "turning points {} rad at {t0} s, {} rad at {t1} s: ratio {r}, closed form {ratio_half}",
            y0[angle],
            y1[angle]
        );
    }
    for w in found.windows(3) {
        let ((t0, y0, _), (t2, y2, _)) = (w[0], w[2]);
        let r = y2[angle] / y0[angle];
        worst[2] = worst[2].max((r / ratio_full - 1.0).abs());
        assert!(
            (r / ratio_full - 1.0).abs() < 1e-5,
            "turning points {} rad at {t0} s, {} rad at {t2} s: ratio {r}, exp(-delta) = {ratio_full}",
            y0[angle],
            y2[angle]
        );
    }
    eprintln!(
        "damped swing: {} turning points; worst relative error of the half-period spacing \
         {:.3e} (tol 1e-6), of the half-period ratio {:.3e}, of the period ratio {:.3e} (tol 1e-5)",
        found.len(),
        worst[0],
        worst[1],
        worst[2]
    );
}

// ---------------------------------------------------------------------------------
// 2: the preload (rest angle) and its sign
// ---------------------------------------------------------------------------------

/// The arm pinned to the fundament under gravity `g` on a spring-damper with
/// `bodies` in this order; `rest_angle` as given; started at rest at `angle0`.
fn preload_plant(
    g: f64,
    bodies: [&str; 2],
    k: f64,
    c: f64,
    rest: Option<f64>,
    angle0: f64,
) -> (Plant, usize) {
    let pivot = [0.5, 2.0];
    let extra = format!(
        "{}{}",
        arm_at(pivot, angle0),
        joint("pin", bodies[0], bodies[1], pivot, k, c, rest)
    );
    let m = machine(g, "", INERT_ROTOR, FRICTIONLESS_MOTOR, &extra);
    let model = PlantModel::new(&m);
    assert!(matches!(model.bodies[1].mount, Mount::Pinned { .. }));
    let angle = model.bodies[1].angle;
    let plant = Plant::new(
        model,
        initial_state(&m),
        Settings::default(),
        platform_held(),
    );
    (plant, angle)
}

/// Newton's method for `f(x) = 0` from `x`, `df` its derivative, to rounding.
fn newton(f: &dyn Fn(f64) -> f64, df: &dyn Fn(f64) -> f64, mut x: f64) -> f64 {
    for _ in 0..50 {
        let dx = f(x) / df(x);
        x -= dx;
        if dx.abs() < 1e-16 {
            break;
        }
    }
    x
}

/// Static balance of the pinned arm (its centre of mass `d` from the pivot along
/// its own axis, at `d (cos theta, sin theta)`): gravity `(0, -m g)` there has the
/// moment `-m g d cos theta` (N m) about the pivot, and the joint's spring
///
/// - with `bodies = ["fundament", "arm"]`: relative angle `alpha = theta - 0`, the
///   torque `-k (theta - alpha_0)` on the arm, so
///   `-k (theta - alpha_0) - m g d cos theta = 0`;
/// - with `bodies = ["arm", "fundament"]`: `alpha = 0 - theta`, the torque
///   `-k (-theta - alpha_0)` on the fundament and its reaction `k (-theta - alpha_0)`
///   on the arm, so `-k (theta + alpha_0) - m g d cos theta = 0`
///
/// (the balance of moments about a fixed pivot; the joint's law from
/// docs/machine-file.md, "Several bodies"). Each has one root: its derivative `-k + m g d sin theta`
/// keeps its sign as `k > m g d`. Solved here by Newton's method to rounding.
///
/// The damper settles the arm there: linearised, `J_h x'' + c x' + k_e x = 0` with
/// `k_e = k - m g d sin theta*` (1.95 and 2.12 N m/rad), damping ratio
/// `zeta = c / (2 sqrt(k_e J_h))` ~ 0.5, so the deflection decays as
/// `exp(-zeta omega_e t)`, `zeta omega_e = c / (2 J_h)` = 11.2 1/s. The arm starts
/// 0.15 rad (first case) and 0.13 rad (second) from balance; after 3 s the
/// deflection is below `0.15 x 1.5 x exp(-33) = 1e-15` rad. The integrator
/// keeps a state whose forces vanish (a Runge-Kutta step maps an equilibrium
/// onto itself), so the plant's final angle is its balance up to rounding of the
/// forces, `1e-16 k |alpha_0| / k_e` ~ 1e-16 rad. The tolerance 1e-9 rad leaves
/// orders of magnitude; a wrong sign of the joint's angle would miss by 0.3 rad
/// and more.
#[test]
fn a_preloaded_spring_balances_gravity_with_the_sign_of_the_joint_order() {
    let (k, g) = (2.0, 9.81);
    let mgd = ARM_MASS * g * ARM_D;
    let c = 0.09;
    let alpha0: f64 = 0.3;
    let cases: [([&str; 2], f64, f64); 2] = [
        // (bodies, sign of theta in alpha, start: where the spring is relaxed)
        (["fundament", "arm"], 1.0, alpha0),
        (["arm", "fundament"], -1.0, -alpha0),
    ];
    let mut balances = Vec::new();
    for (bodies, s, angle0) in cases {
        // alpha = s theta; the torque on the arm is s (-k (s theta - alpha_0)).
        let f = |x: f64| -k * (x - s * alpha0) - mgd * x.cos();
        let df = |x: f64| -k + mgd * x.sin();
        let expected = newton(&f, &df, angle0);
        assert!(
            f(expected).abs() < 1e-15,
            "Newton: residual {}",
            f(expected)
        );
        let (mut plant, angle) = preload_plant(g, bodies, k, c, Some(alpha0), angle0);
        plant.advance_to(3.0, &mut |_| {}).unwrap();
        let n = plant.model.dof;
        let got = plant.y[angle];
        eprintln!(
            "preload {bodies:?}: balance {expected:.15} rad, plant {got:.15} rad, \
             |diff| {:.3e} rad (tol 1e-9), speed {:.3e} rad/s",
            (got - expected).abs(),
            plant.y[n + angle]
        );
        assert!(
            (got - expected).abs() < 1e-9,
            "{bodies:?}: the arm settles at {got} rad; the static balance is at {expected} rad"
        );
        assert!(plant.y[n + angle].abs() < 1e-9, "still moving");
        balances.push(expected);
    }
    // The order of the bodies matters: the balances lie either side of zero.
    assert!(balances[0] > 0.1 && balances[1] < -0.4, "{balances:?}");

    // No gravity, no rest angle (the relative angle at t = 0 is the spring's
    // rest): nothing acts, the arm stays at its file angle, in either order. The
    // forces are exactly zero there (`(theta - 0) - (theta_0 - 0)` and
    // `(0 - theta) - (0 - theta_0)` vanish in floating point at theta = theta_0),
    // so the state does not move at all.
    for bodies in [["fundament", "arm"], ["arm", "fundament"]] {
        let angle0 = 0.7;
        let (mut plant, angle) = preload_plant(0.0, bodies, k, c, None, angle0);
        let n = plant.model.dof;
        let mut worst: f64 = 0.0;
        plant
            .advance_to(1.0, &mut |out| {
                if let Output::Dense(step, upto) = out {
                    let y = step.at(upto);
                    worst = worst.max((y[angle] - angle0).abs()).max(y[n + angle].abs());
                }
            })
            .unwrap();
        eprintln!("no preload {bodies:?}: the arm moved {worst:.3e} rad (tol 1e-15)");
        assert!(
            worst <= 1e-15,
            "{bodies:?}: the arm left its file angle by {worst} rad (or rad/s)"
        );
    }
}

// ---------------------------------------------------------------------------------
// 3: the reaction on body A
// ---------------------------------------------------------------------------------

/// The free platform's arm: hinged at `FREE_HINGE` (world, t = 0), its angle
/// `FREE_ARM_ANGLE` at t = 0, the spring relaxed at relative angle 0.
const FREE_HINGE: [f64; 2] = [0.1, 1.05];
const FREE_PLATFORM_ANGLE: f64 = 0.1;
const FREE_ARM_ANGLE: f64 = 0.4;

/// The free platform and its arm at a state: each body's centre of mass,
/// velocity, angle and angular velocity, from the state's coordinates and this
/// test's geometry alone. The platform's are coordinates (`x, y, theta` and their
/// rates); the hinge is `h = C + R(theta_p) s_p`, `s_p = R(-theta_p0) (h_0 - C_0)`
/// the hinge in the platform's frame, and the arm's centre
/// `c_a = h + R(theta_a) s_a`, `s_a = R(-theta_a0) (c_a0 - h_0)`, with the
/// velocities `v_h = v_C + theta_p' z x R(theta_p) s_p` and
/// `v_a = v_h + theta_a' z x R(theta_a) s_a` (the velocity of a point of a rigid
/// body, Goldstein, *Classical Mechanics*, 3rd ed., ch. 4).
struct TwoBodies {
    c: [[f64; 2]; 2],
    v: [[f64; 2]; 2],
    angle: [f64; 2],
    omega: [f64; 2],
}

fn two_bodies(y: &[f64; NY], n: usize, arm: usize) -> TwoBodies {
    let (c_p, v_p) = ([y[0], y[1]], [y[n], y[n + 1]]);
    let (theta_p, w_p) = (y[2], y[n + 2]);
    let (theta_a, w_a) = (y[arm], y[n + arm]);
    let s_p = rot(-FREE_PLATFORM_ANGLE, sub(FREE_HINGE, PLATFORM_CENTRE));
    let s_a = rot(-FREE_ARM_ANGLE, scale(ARM_D, unit(FREE_ARM_ANGLE)));
    let r_p = rot(theta_p, s_p);
    let r_a = rot(theta_a, s_a);
    let h = add(c_p, r_p);
    let v_h = add(v_p, spin(w_p, r_p));
    TwoBodies {
        c: [c_p, add(h, r_a)],
        v: [v_p, add(v_h, spin(w_a, r_a))],
        angle: [theta_p, theta_a],
        omega: [w_p, w_a],
    }
}

/// A free platform (lifted, no gravity, the rotor inert) with the arm hinged to
/// it on a spring-damper, started with relative motion: the platform moving and
/// turning, the arm turning faster, the spring stretched 0.3 rad. Nothing outside
/// acts (no gravity, no contact: the foot stays more than 0.5 m above the floor,
/// checked), so (Goldstein, *Classical Mechanics*, 3rd ed., sec. 1.2)
///
/// ```text
///   P = sum_b m_b v_b                                         (N s)
///   L_O = sum_b (I_b omega_b + m_b c_b x v_b) + I_k (theta_p' + phi')   (N m s)
/// ```
///
/// stay constant (the rotor has no eccentric mass: it adds its inertia `I_k`
/// turning at `theta_p' + phi'` to `L_O` and nothing to `P`), and the mechanical
/// energy less what the damper took,
///
/// ```text
///   E = sum_b (m_b |v_b|^2 / 2 + I_b omega_b^2 / 2) + I_k (theta_p' + phi')^2 / 2
///       + k (alpha - alpha_0)^2 / 2,     alpha = theta_a - theta_p       (J)
///   D(t) = integral_0^t c alpha'^2 dt                                    (J)
/// ```
///
/// `E + D` stays constant (the damper's power is `-c alpha'^2`). The joint's torque
/// acts on the arm and its reaction on the platform: dropping the reaction would
/// change `L_O` by the spring's torque (1.5 N m at the start) over the run, of
/// order 1 N m s; the hinge's constraint force, likewise, must be equal and
/// opposite on the two bodies for `P`.
///
/// Tolerances (the integrator's, the approach of `plant_references.rs`' energy
/// tests): each accepted step may err by its [`step_allowance`] in each of these
/// quantities; `D` is integrated here on each step's dense output by 5-point
/// Gauss-Legendre (exact for the interpolant's `alpha'^2`, a polynomial of degree
/// 8), its error from the interpolant's velocities within
/// `2 c |alpha'| sc_alpha' h` per step (`sc` the controller's scale of `alpha'`,
/// `rtol (1 + |theta_a'| + |theta_p'|)`). From the start each quantity must stay
/// within the sum of the allowances so far, plus rounding (1e-13 of its terms).
#[test]
fn a_joint_spring_damper_on_a_free_platform_keeps_momentum_and_the_energy_balance() {
    let (k, c) = (5.0, 0.01);
    let (v_p, w_p) = ([0.05, 0.02], 0.5);
    let w_a = 3.0;
    // The arm's centre moves with the hinge: v_h + w_a z x (c_a - h).
    let c_a = add(FREE_HINGE, scale(ARM_D, unit(FREE_ARM_ANGLE)));
    let v_h = add(v_p, spin(w_p, sub(FREE_HINGE, PLATFORM_CENTRE)));
    let v_a = add(v_h, spin(w_a, sub(c_a, FREE_HINGE)));
    let platform = format!(
        "angle = {FREE_PLATFORM_ANGLE:?}\nvelocity = {}\nangular_velocity = {w_p:?}\n",
        vector(v_p)
    );
    let rest = 0.0;
    let extra = format!(
        "{}{}",
        moving_body("arm", ARM_MASS, ARM_INERTIA, c_a, FREE_ARM_ANGLE, v_a, w_a),
        joint("hinge", "platform", "arm", FREE_HINGE, k, c, Some(rest))
    );
    let m = machine(0.0, &platform, INERT_ROTOR, FRICTIONLESS_MOTOR, &extra);
    let model = PlantModel::new(&m);
    assert_eq!(model.dof, 5, "platform x, y, theta; the arm; the rotor");
    assert_eq!(model.bodies[0].mount, Mount::Free { x: 0 });
    assert_eq!(model.bodies[0].angle, 2);
    let (n, arm, phi) = (model.dof, model.bodies[1].angle, model.rotors[0].phi);
    let allowance_model = model.clone();
    let masses = [PLATFORM_MASS, ARM_MASS];
    let inertias = [PLATFORM_INERTIA, ARM_INERTIA];

    let momentum = |y: &[f64; NY], axis: usize| {
        let s = two_bodies(y, n, arm);
        masses[0] * s.v[0][axis] + masses[1] * s.v[1][axis]
    };
    let angular_momentum = |y: &[f64; NY]| {
        let s = two_bodies(y, n, arm);
        let rotor = INERT_ROTOR_INERTIA * (y[n + 2] + y[n + phi]);
        (0..2).fold(rotor, |l, b| {
            l + inertias[b] * s.omega[b] + masses[b] * cross(s.c[b], s.v[b])
        })
    };
    let energy = |y: &[f64; NY]| {
        let s = two_bodies(y, n, arm);
        let rotor = 0.5 * INERT_ROTOR_INERTIA * (y[n + 2] + y[n + phi]).powi(2);
        let stretch = s.angle[1] - s.angle[0] - rest;
        (0..2).fold(rotor + 0.5 * k * stretch * stretch, |e, b| {
            e + 0.5 * masses[b] * (s.v[b][0].powi(2) + s.v[b][1].powi(2))
                + 0.5 * inertias[b] * s.omega[b].powi(2)
        })
    };
    // The terms' sizes, for rounding.
    let magnitude = |y: &[f64; NY]| {
        let s = two_bodies(y, n, arm);
        (0..2).fold(0.0, |a, b| {
            a + masses[b] * (s.v[b][0].abs() + s.v[b][1].abs())
                + inertias[b] * s.omega[b].abs()
                + masses[b] * cross(s.c[b], s.v[b]).abs()
        })
    };

    let y0 = initial_state(&m);
    let mut plant = Plant::new(model, y0, Settings::default(), Holds::default());
    let rtol = plant.settings.rtol;
    let quantities: [&StateFunction<'_>; 4] = [
        &|y| momentum(y, 0),
        &|y| momentum(y, 1),
        &angular_momentum,
        &energy,
    ];
    let start: Vec<f64> = quantities.iter().map(|f| f(&y0)).collect();
    let scale0 = magnitude(&y0) + energy(&y0);
    let mut allowed = [0.0; 4];
    let mut worst = [0.0f64; 4];
    let mut dissipated = 0.0;
    let mut travel: f64 = 0.0;
    let mut lowest_foot = f64::INFINITY;
    let mut steps = 0;
    // 5-point Gauss-Legendre on [-1, 1].
    let gauss = [
        (0.0, 128.0 / 225.0),
        (0.538_469_310_105_683_1, 0.478_628_670_499_366_5),
        (-0.538_469_310_105_683_1, 0.478_628_670_499_366_5),
        (0.906_179_845_938_664, 0.236_926_885_056_189_1),
        (-0.906_179_845_938_664, 0.236_926_885_056_189_1),
    ];
    plant
        .advance_to(2.0, &mut |out| {
            let Output::Dense(step, upto) = out else {
                panic!("no event expected");
            };
            let (t0, h) = (step.t0, upto - step.t0);
            let rate = |y: &[f64; NY]| y[n + arm] - y[n + 2];
            let mut d = 0.0;
            let mut fastest: f64 = 0.0;
            for (x, w) in gauss {
                let y = step.at(t0 + 0.5 * h * (1.0 + x));
                d += 0.5 * h * w * c * rate(&y).powi(2);
                fastest = fastest.max(rate(&y).abs());
            }
            dissipated += d;
            let y = step.at(upto);
            steps += 1;
            let s = two_bodies(&y, n, arm);
            travel =
                travel.max((s.angle[1] - s.angle[0] - FREE_ARM_ANGLE + FREE_PLATFORM_ANGLE).abs());
            let foot = add(
                s.c[0],
                rot(s.angle[0], rot(-FREE_PLATFORM_ANGLE, [-0.08, -0.03])),
            );
            lowest_foot = lowest_foot.min(foot[1]);
            let sc_rate = rtol * (1.0 + y[n + arm].abs() + y[n + 2].abs());
            for (i, f) in quantities.iter().enumerate() {
                allowed[i] += step_allowance(&allowance_model, 2.0, *f, &y, rtol);
                let mut got = f(&y);
                if i == 3 {
                    allowed[i] += 2.0 * c * fastest * sc_rate * h;
                    got += dissipated;
                }
                let drift = (got - start[i]).abs();
                worst[i] = worst[i].max(drift);
                let tol = allowed[i] + 1e-13 * scale0;
                assert!(
                    drift <= tol,
                    "quantity {i} (P_x, P_y, L_O, E + D) at t = {upto}: {got:.15e}, \
                 at the start {:.15e}: drift {drift:.3e} > allowed {tol:.3e}",
                    start[i]
                );
            }
        })
        .unwrap();
    assert!(plant.events.is_empty(), "events: {:?}", plant.events.len());
    assert!(lowest_foot > 0.5, "the foot came down to {lowest_foot} m");
    // The arm swung relative to the platform and the damper took energy.
    assert!(travel > 0.2, "relative swing {travel} rad");
    assert!(
        dissipated > 0.05 * start[3],
        "dissipated {dissipated} J of {} J",
        start[3]
    );
    eprintln!(
        "free platform and arm, {steps} steps: P_x {:.6} N s drift {:.3e} (allowed {:.3e}); \
         P_y {:.6} N s drift {:.3e} (allowed {:.3e}); L_O {:.6} N m s drift {:.3e} (allowed \
         {:.3e}); E {:.6} J, dissipated {dissipated:.6} J, E + D drift {:.3e} (allowed {:.3e})",
        start[0],
        worst[0],
        allowed[0],
        start[1],
        worst[1],
        allowed[1],
        start[2],
        worst[2],
        allowed[2],
        start[3],
        worst[3],
        allowed[3]
    );
}

/// A free platform and its arm, no gravity, nothing held, the spring relaxed at
/// t = 0, the platform at rest and the arm turning about the hinge at `W0` rad/s.
/// The pair swings about each other (and drifts and turns slowly as a whole, with
/// the momentum the arm was given) in the one mode whose inertia is the least the
/// joint's relative rotation can have: the `J` by which the machine file limits a
/// joint's rate (`host_sim::machine::joint_limits`: the two bodies pinned at the
/// hinge, otherwise free). So the relative swing's period is `2 pi sqrt(J / k)`.
/// The arm's angular velocity is the relative swing's share plus the whole pair's
/// slow turn: it crosses zero once a half period, the crossings alternately early
/// and late by the same amount, so every second crossing is one period on. The
/// file's `J` comes from its own 4x4 mass matrix at the file's configuration; the
/// plant integrates its own generalized coordinates: two methods.
///
/// Tolerances: `J` changes with the relative angle (the centres' distance
/// products): the swing, of amplitude `a = W0 / omega` = 1.7e-4 rad about the
/// file's configuration, moves the period by `O(a^2)`, some 1e-8 relative; the
/// whole pair's turn, at about `W0 J_h / (J_p + J_h)` = 4e-3 rad/s against the
/// swing's 58 rad/s, adds a centrifugal `O((4e-3 / 58)^2)` = 5e-9; the crossing
/// times carry the integrator's phase error, a few 1e-8 of the period (the damped
/// swing's budget above). 1e-6 covers these and is 3e5 times smaller than what the
/// held platform's inertia would give (`J_h = 4e-3` against this pair's 1.5e-3
/// kg m^2: 64 % in the period).
#[test]
fn a_free_pair_swings_with_the_least_relative_inertia_the_file_limits_by() {
    const W0: f64 = 0.01;
    let k = 5.0;
    let hinge = FREE_HINGE;
    let centre = add(hinge, scale(ARM_D, unit(FREE_ARM_ANGLE)));
    let extra = format!(
        "{}{}",
        moving_body(
            "arm",
            ARM_MASS,
            ARM_INERTIA,
            centre,
            FREE_ARM_ANGLE,
            spin(W0, sub(centre, hinge)),
            W0
        ),
        joint("hinge", "platform", "arm", hinge, k, 0.0, None)
    );
    let m = machine(0.0, "", INERT_ROTOR, FRICTIONLESS_MOTOR, &extra);
    let inertia = effective_inertia(Some(&m.platform), Some(&m.bodies[0].rigid), hinge);
    let held = ARM_J_HINGE;
    assert!(
        inertia < 0.9 * held,
        "J = {inertia} kg m^2 against {held} held: the test would not tell them apart"
    );
    let model = PlantModel::new(&m);
    let omega = model.dof + model.bodies[1].angle;
    let mut plant = Plant::new(
        model,
        initial_state(&m),
        Settings::default(),
        Holds::default(),
    );
    let period = 2.0 * PI * (inertia / k).sqrt();
    let found = crossings(&mut plant, omega, 6.2 * period);
    assert!(found.len() >= 12, "{} crossings", found.len());
    let mut worst = 0.0f64;
    for w in found.windows(3) {
        let error = (w[2].0 - w[0].0 - period) / period;
        worst = worst.max(error.abs());
        assert!(
            error.abs() < 1e-6,
            "the arm's rate crosses zero at {} s and again at {} s: {} s apart; 2 pi sqrt(J / k) = {period} s with J = {inertia} kg m^2",
            w[0].0,
            w[2].0,
            w[2].0 - w[0].0
        );
    }
    eprintln!(
        "free pair: J = {inertia:.6e} kg m^2 (held: {held:.1e}); {} crossings, worst relative error of the period {worst:.2e} (tol 1e-6)",
        found.len()
    );
}

// ---------------------------------------------------------------------------------
// 4: a chain of two joints: the double compound pendulum
// ---------------------------------------------------------------------------------

/// The upper link: pinned to the fundament at `PIVOT`, its centre of mass `D1`
/// from the pivot and the lower link's hinge `L1` from it, both along its axis.
const UPPER: (f64, f64) = (0.3, 1e-3);
const D1: f64 = 0.1;
const L1: f64 = 0.2;
/// The lower link: hinged to the upper one, its centre of mass `D2` from its hinge.
const LOWER: (f64, f64) = (0.2, 5e-4);
const D2: f64 = 0.08;
const PIVOT: [f64; 2] = [0.5, 2.0];

/// The double compound pendulum under gravity `g`, hanging (world angles
/// `-pi/2 + delta_i`), released at rest at `delta`.
fn double_pendulum(g: f64, delta: [f64; 2]) -> (Plant, [usize; 2]) {
    let (a1, a2) = (-PI / 2.0 + delta[0], -PI / 2.0 + delta[1]);
    let hinge = add(PIVOT, scale(L1, unit(a1)));
    let extra = format!(
        "{}{}{}{}",
        body(
            "upper",
            UPPER.0,
            UPPER.1,
            add(PIVOT, scale(D1, unit(a1))),
            a1
        ),
        body(
            "lower",
            LOWER.0,
            LOWER.1,
            add(hinge, scale(D2, unit(a2))),
            a2
        ),
        joint("pin", "fundament", "upper", PIVOT, 0.0, 0.0, None),
        joint("knee", "upper", "lower", hinge, 0.0, 0.0, None),
    );
    let m = machine(g, "", INERT_ROTOR, FRICTIONLESS_MOTOR, &extra);
    let model = PlantModel::new(&m);
    assert!(matches!(model.bodies[1].mount, Mount::Pinned { .. }));
    assert!(matches!(
        model.bodies[2].mount,
        Mount::Child { parent: 1, .. }
    ));
    assert!(model.springs.is_empty());
    let angles = [model.bodies[1].angle, model.bodies[2].angle];
    let plant = Plant::new(
        model,
        initial_state(&m),
        Settings::default(),
        platform_held(),
    );
    (plant, angles)
}

/// Reference (Meirovitch, *Elements of Vibration Analysis*, 2nd ed., 1986: the
/// free vibration of two-degree-of-freedom systems, the eigenvalue problem
/// `det(K - w^2 M) = 0`). With `delta_i` the links' angles from hanging, the
/// centres of mass are `c_1 = P + d_1 u(theta_1)`, `c_2 = P + l_1 u(theta_1) +
/// d_2 u(theta_2)`, and Lagrange's function is
///
/// ```text
///   T = (I_1 + m_1 d_1^2 + m_2 l_1^2) delta_1'^2 / 2
///       + m_2 l_1 d_2 cos(delta_1 - delta_2) delta_1' delta_2'
///       + (I_2 + m_2 d_2^2) delta_2'^2 / 2                                     (J)
///   V = -g ((m_1 d_1 + m_2 l_1) cos delta_1 + m_2 d_2 cos delta_2)              (J)
/// ```
///
/// so for small angles `M = [[I_1 + m_1 d_1^2 + m_2 l_1^2, m_2 l_1 d_2],
/// [m_2 l_1 d_2, I_2 + m_2 d_2^2]]` (kg m^2) and `K = diag(g (m_1 d_1 + m_2 l_1),
/// g m_2 d_2)` (N m/rad); `det(K - w^2 M) = 0` is a quadratic in `w^2`, each root
/// with the mode `v = (w^2 M_12, K_11 - w^2 M_11)`, scaled here to a largest
/// component of 1. Started at rest on `A v`, `A` = 1e-3 rad, the linear system
/// swings in that mode alone, with the period `2 pi / w`.
///
/// The amplitude correction. `L` is even in `(delta, delta')`, so the first
/// correction comes from its quartic part
/// `L_4 = (K_11 delta_1^4 + K_22 delta_2^4) / 24 - M_12 (delta_1 - delta_2)^2
/// delta_1' delta_2' / 2`. Averaged over the linear orbit `delta = A v cos(w t)`
/// (Whitham's averaged Lagrangian, *Linear and Nonlinear Waves*, 1974; Landau
/// and Lifshitz, *Mechanics*, sec. 28, for one degree of freedom),
/// `<L> = A^2 (w^2 v.Mv - v.Kv) / 4 + A^4 B` with
/// `B = (K_11 v_1^4 + K_22 v_2^4) / 64 - M_12 w^2 (v_1 - v_2)^2 v_1 v_2 / 16`, and
/// `d<L>/dA = 0` gives `w^2 = w_0^2 (1 - 8 A^2 B / v.Kv)`: the period
/// `T = T_0 (1 + 4 A^2 B / v.Kv)` to `O(A^4)` ~ 1e-12. For a single pendulum this is
/// the textbook `T_0 (1 + A^2 / 16)`. Here the correction is 3.3e-8 of the period
/// in the slow mode and 5.5e-7 in the fast one (the test prints them).
///
/// Tolerances. Starting on the linear mode rather than the nonlinear one leaves
/// the other link off the mode's ratio by `O(A^2)` of the amplitude (1e-6 x `A`
/// allowed at the turning points, checked below; 1.8e-7 measured). Such a part
/// `eps A` swinging at the other mode's frequency `w_o` moves a zero of the main
/// link's speed by at most `eps w_o / w^2`, `eps (w_o / w) / (2 pi)` of a period
/// (`w_o / w` = 2.4 and 0.41): 3.9e-7 of it, and the period is taken from the first
/// and the last of about 20 crossings, 19 periods apart or more: `2 x 3.9e-7 / 19` = 4e-8. The
/// amplitude correction's own error is `O(A^4)` ~ 1e-12 and the integration's
/// ~1e-10 (the damped swing's crossings: the steps are at most 1e-3 s,
/// `w h <= 0.015`). The period must agree to 1e-7 of itself, tight enough that the
/// fast mode's correction (5.5e-7) is itself checked.
#[test]
fn a_double_compound_pendulum_swings_in_each_normal_mode_with_its_period() {
    let g = 9.81;
    let (m1, i1) = UPPER;
    let (m2, i2) = LOWER;
    let mass = [
        [i1 + m1 * D1 * D1 + m2 * L1 * L1, m2 * L1 * D2],
        [m2 * L1 * D2, i2 + m2 * D2 * D2],
    ];
    let stiffness = [g * (m1 * D1 + m2 * L1), g * m2 * D2];
    // det(K - w^2 M) = a w^4 + b w^2 + c with K diagonal.
    let a = mass[0][0] * mass[1][1] - mass[0][1] * mass[1][0];
    let b = -(stiffness[0] * mass[1][1] + stiffness[1] * mass[0][0]);
    let c = stiffness[0] * stiffness[1];
    let disc = (b * b - 4.0 * a * c).sqrt();
    let amplitude = 1e-3;
    for w2 in [(-b - disc) / (2.0 * a), (-b + disc) / (2.0 * a)] {
        let w = w2.sqrt();
        let raw = [w2 * mass[0][1], stiffness[0] - w2 * mass[0][0]];
        // The other row of (K - w^2 M) v = 0 holds too.
        let residual = -w2 * mass[1][0] * raw[0] + (stiffness[1] - w2 * mass[1][1]) * raw[1];
        assert!(residual.abs() < 1e-12 * stiffness[0] * raw[0].abs().max(raw[1].abs()));
        let largest = if raw[0].abs() > raw[1].abs() {
            raw[0]
        } else {
            raw[1]
        };
        let v = [raw[0] / largest, raw[1] / largest];
        let vkv = stiffness[0] * v[0] * v[0] + stiffness[1] * v[1] * v[1];
        let quartic = (stiffness[0] * v[0].powi(4) + stiffness[1] * v[1].powi(4)) / 64.0
            - mass[0][1] * w2 * (v[0] - v[1]).powi(2) * v[0] * v[1] / 16.0;
        let correction = 4.0 * amplitude * amplitude * quartic / vkv;
        let linear = 2.0 * PI / w;
        let expected = linear * (1.0 + correction);

        let (mut plant, angles) = double_pendulum(g, [amplitude * v[0], amplitude * v[1]]);
        let n = plant.model.dof;
        // Downward crossings of the upper link's speed (or the lower's, whichever
        // moves more in this mode).
        let which = if v[0].abs() >= v[1].abs() { 0 } else { 1 };
        let found = crossings(&mut plant, n + angles[which], 20.5 * linear);
        let down: Vec<f64> = found
            .iter()
            .filter(|(_, _, before)| *before > 0.0)
            .map(|(t, _, _)| *t)
            .collect();
        assert!(down.len() >= 19, "{} periods", down.len());
        let got = (down[down.len() - 1] - down[0]) / (down.len() - 1) as f64;
        eprintln!(
            "double pendulum, mode v = [{:.6}, {:.6}], w = {w:.6} rad/s: period {got:.12} s, \
             linear {linear:.12} s, with the amplitude correction ({correction:.3e}) \
             {expected:.12} s; relative error {:.3e} (tol 1e-7), without the correction {:.3e}",
            v[0],
            v[1],
            (got - expected).abs() / expected,
            (got - linear).abs() / linear
        );
        assert!(
            (got - expected).abs() < 1e-7 * expected,
            "mode {v:?}: period {got} s, reference {expected} s"
        );
        // And the other link swings with it in the mode's ratio, to O(A^2) of the
        // amplitude (the nonlinear terms; A^2 = 1e-6).
        let other = 1 - which;
        let mut off_mode: f64 = 0.0;
        for (t, y, _) in &found {
            let ratio = y[angles[other]] + PI / 2.0;
            let main = y[angles[which]] + PI / 2.0;
            off_mode = off_mode.max((ratio - main * v[other] / v[which]).abs() / amplitude);
            assert!(
                (ratio - main * v[other] / v[which]).abs() < 1e-6 * amplitude,
                "at {t} s: delta = {main}, {ratio}; mode {v:?}"
            );
        }
        eprintln!(
            "  off the mode at the turning points: {off_mode:.3e} of the amplitude (tol 1e-6)"
        );
    }
}

// ---------------------------------------------------------------------------------
// 5: a rotor on a hinged body
// ---------------------------------------------------------------------------------

/// The driven rotor's inertia about its axis, kg m^2 (no eccentric mass).
const DRIVEN_ROTOR_INERTIA: f64 = 1e-4;

/// The machine of [`rotor_on_an_arm`]: no gravity, the arm hinged at `[0.5, 2.0]`
/// to `to` at angle 0.3 rad (returned), its rotor 0.15 m out along it.
fn rotor_arm_machine(to: &str) -> (Machine, f64) {
    let hinge = [0.5, 2.0];
    let angle0 = 0.3;
    let axis = add(hinge, scale(0.15, unit(angle0)));
    let rotor = format!(
        r#"
[[rotors]]
name = "R1"
body = "arm"
axis = {}
eccentric_mass = 0.0
eccentricity = 0.0
inertia = {DRIVEN_ROTOR_INERTIA:?}
sense = "ccw"
"#,
        vector(axis)
    );
    let extra = format!(
        "{}{}",
        arm_at(hinge, angle0),
        joint("hinge", to, "arm", hinge, 0.0, 0.0, None)
    );
    (machine(0.0, "", &rotor, REFERENCE_MOTOR, &extra), angle0)
}

/// The arm hinged at `hinge` to `to` (the fundament, or the held platform), no
/// gravity, no spring, carrying a rotor without eccentric mass 0.15 m from the
/// hinge, its winding at 6 V from t = 0.
///
/// Reference: nothing outside exerts a moment about the hinge, a fixed point (the
/// hinge's force has no arm about it; the motor's torque and its friction act
/// between the rotor and the arm and cancel in the sum), so the angular momentum
/// about the hinge is what it was at rest, zero (Goldstein, *Classical
/// Mechanics*, 3rd ed., sec. 1.2):
///
/// ```text
///   L_O = J_O theta' + I_k (theta' + phi') = 0                            (N m s)
///   theta' = -I_k phi' / (J_O + I_k)                                      (rad/s)
/// ```
///
/// `J_O = I_c + m d^2` the arm's inertia about the hinge (kg m^2), `I_k` the
/// rotor's about its axis, turning at `theta' + phi'` (its axis may sit anywhere
/// on the arm: without an eccentric mass the rotor adds no mass off the arm's,
/// only its spin).
///
/// Tolerance: rounding. `L_O` is a linear function of the state,
/// `c . y` with `c` = `J_O + I_k` on `theta'` and `I_k` on `phi'`, and the
/// equations of motion keep it exactly: the arm's row of `M q'' = Q` is
/// `(J_O + I_k) theta'' + I_k phi'' = 0` (the motor's torque on `phi` only). A
/// Runge-Kutta step, and its dense output, is a linear combination of such
/// derivatives, so it keeps every linear first integral exactly (Hairer, Lubich
/// and Wanner, *Geometric Numerical Integration*, 2nd ed., 2006, thm. IV.1.5),
/// whatever the step's error. What remains is rounding: a few units of 1e-16 of
/// the terms `|J_O theta'| + I_k |theta' + phi'|` per stage, carried from step to
/// step: at most `steps x 7 stages x 4 x 1.1e-16` of the largest terms (the run
/// takes ~1000 steps: 3e-12 of them). For `theta'` the same divided by `J_O + I_k`.
/// (The integrator's own per-step allowance, [`step_allowance`], would allow
/// 1e-6 N m s here: a plant whose accelerations broke the balance by the
/// integrator's tolerance would pass that, not this.)
fn rotor_on_an_arm(to: &str) {
    let (m, angle0) = rotor_arm_machine(to);
    let model = PlantModel::new(&m);
    assert_eq!(model.rotors[0].body, 1);
    let (n, angle, phi) = (model.dof, model.bodies[1].angle, model.rotors[0].phi);
    let (j_o, i_k) = (ARM_J_HINGE, DRIVEN_ROTOR_INERTIA);
    let l_o = |y: &[f64; NY]| j_o * y[n + angle] + i_k * (y[n + angle] + y[n + phi]);
    let mut plant = Plant::new(
        model,
        initial_state(&m),
        Settings::default(),
        platform_held(),
    );
    plant.set_winding([Winding::Voltage(6.0), Winding::Voltage(6.0)]);
    let mut steps = 0u32;
    let mut terms: f64 = 0.0;
    let (mut worst_l, mut worst_rate): (f64, f64) = (0.0, 0.0);
    let mut tol_l: f64 = 0.0;
    let (mut fastest, mut turned) = (0.0f64, 0.0f64);
    plant
        .advance_to(1.0, &mut |out| {
            let Output::Dense(step, upto) = out else {
                panic!("no event expected");
            };
            steps += 1;
            let y = step.at(upto);
            let (w, w_phi) = (y[n + angle], y[n + phi]);
            terms = terms.max(j_o * w.abs() + i_k * (w + w_phi).abs());
            tol_l = f64::from(steps) * 7.0 * 4.0 * 1.1e-16 * terms;
            let l = l_o(&y);
            assert!(
                l.abs() <= tol_l,
                "{to}: L_O = {l:.3e} N m s at t = {upto} (allowed {tol_l:.3e})"
            );
            let expected = -i_k * w_phi / (j_o + i_k);
            assert!(
                (w - expected).abs() <= tol_l / (j_o + i_k),
                "{to}: theta' = {w} rad/s at t = {upto}, -I_k phi' / (J_O + I_k) = {expected}"
            );
            worst_l = worst_l.max(l.abs());
            worst_rate = worst_rate.max((w - expected).abs());
            fastest = fastest.max(w_phi.abs());
            turned = turned.max((y[angle] - angle0).abs());
        })
        .unwrap();
    eprintln!(
        "rotor on the arm hinged to {to}, {steps} steps: phi' up to {fastest:.1} rad/s, the arm \
         turned {turned:.2} rad; |L_O| up to {worst_l:.3e} N m s (allowed {tol_l:.3e}), \
         |theta' + I_k phi' / (J_O + I_k)| up to {worst_rate:.3e} rad/s (allowed {:.3e})",
        tol_l / (j_o + i_k)
    );
    // The motor did drive the rotor, and the arm turned back.
    assert!(fastest > 100.0, "the rotor reached {fastest} rad/s");
    assert!(turned > 1.0, "the arm turned {turned} rad");
}

#[test]
fn a_rotor_driven_on_an_arm_pinned_to_the_fundament_keeps_zero_angular_momentum() {
    rotor_on_an_arm("fundament");
}

#[test]
fn a_rotor_driven_on_an_arm_hinged_to_the_held_platform_keeps_zero_angular_momentum() {
    rotor_on_an_arm("platform");
}

/// Every body held ([`Holds::bodies`]): the motor drives the rotor on the arm
/// hinged to the platform up to speed, and neither the arm nor the platform
/// moves (the platform's foot left out of the contacts), their coordinates exactly at their start and at rest at every step
/// (with the platform alone held the same drive turns the arm by more than a
/// radian, [`rotor_on_an_arm`]).
#[test]
fn with_every_body_held_only_the_rotor_on_an_arm_turns() {
    let (m, _) = rotor_arm_machine("platform");
    let model = PlantModel::new(&m);
    let (n, phi) = (model.dof, model.rotors[0].phi);
    let start = initial_state(&m);
    let holds = Holds {
        bodies: true,
        ..Holds::default()
    };
    assert_eq!(model.contacts.len(), 1);
    let mut plant = Plant::new(model, start, Settings::default(), holds);
    // The platform's foot, a held body's against the fundament, moves nothing:
    // left out.
    assert!(plant.model.contacts.is_empty());
    assert!(plant.modes.is_empty());
    plant.set_winding([Winding::Voltage(6.0), Winding::Voltage(6.0)]);
    let mut fastest: f64 = 0.0;
    plant
        .advance_to(1.0, &mut |out| {
            let Output::Dense(step, upto) = out else {
                panic!("no event expected");
            };
            let y = step.at(upto);
            for i in (0..n).filter(|&i| i != phi) {
                assert_eq!(y[i], start[i], "coordinate {i} at t = {upto}");
                assert_eq!(y[n + i], 0.0, "velocity {i} at t = {upto}");
            }
            fastest = fastest.max(y[n + phi].abs());
        })
        .unwrap();
    assert!(fastest > 100.0, "the rotor reached {fastest} rad/s");
}
