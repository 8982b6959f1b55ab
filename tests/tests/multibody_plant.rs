//! The plant with several bodies (issue 12), against closed forms and
//! conservation laws that do not go through the plant's Jacobians:
//!
//! - a body hinged to the held platform on a torsional spring, no gravity, swings
//!   with the period `2 pi sqrt(J_h / k)` for small angles, `J_h = I_c + m d^2`
//!   its inertia about the hinge (Steiner), `d` the hinge-to-centre distance;
//! - the same body hinged to the fundament under gravity, without a spring: a
//!   compound pendulum, period `2 pi sqrt(J_h / (m g d))` for small angles;
//! - a pendulum hinged to a platform that rests on a frictionless floor, striking a
//!   stop on the platform: no horizontal external force, so the system's
//!   horizontal momentum `sum m v_x` (from the bodies' velocities the plant
//!   reports) stays zero through every impact, and, independently of those
//!   velocities, the system's horizontal centre of mass (from the bodies'
//!   positions alone) stays where it started; the mechanical energy (the rotors'
//!   spin included) never grows, from one reported state to the next, under
//!   Poisson's law with one restitution;
//! - every contact's Jacobian rows and velocity-product terms (a face turning with
//!   its body among them) against finite differences of its gap and slip along a
//!   path, and the mass matrix against the kinetic energy summed mass by mass with
//!   finite-difference velocities.

use std::f64::consts::PI;
use tests::initial_state;
use tests::machine::TestMachine;

use host_sim::machine::bodies::MAX_DOF;
use host_sim::machine::Machine;
use host_sim::plant::dynamics::{Frame, Pose, Vector};
use host_sim::plant::model::{Mount, PlantModel};
use host_sim::plant::simulator::{Holds, Output, Plant, Settings};
use host_sim::simulation::trace::TraceRow;
use tests::Rng;

/// The reference machine's text with `replace` applied and `extra` appended.
fn machine(replace: &[(&str, &str)], extra: &str) -> Machine {
    let mut m = TestMachine::example();
    for (from, to) in replace {
        m = m.replace(from, to);
    }
    m.with(extra).machine()
}

/// The arm of the swinging tests: 0.3 kg, `I_c` = 1e-3 kg m^2, its centre 0.1 m
/// from the hinge along +x, started `angle0` from its spring's rest.
fn arm(against: &str, hinge: [f64; 2], angle0: f64, stiffness: f64) -> String {
    let d = 0.1;
    let (s, c) = angle0.sin_cos();
    format!(
        r#"
[[bodies]]
name = "arm"
mass = 0.3
inertia = 1e-3
position = [{}, {}]
angle = {angle0}

[[joints]]
name = "hinge"
kind = "revolute"
bodies = ["{against}", "arm"]
point = [{}, {}]
stiffness = {stiffness}
rest_angle = 0.0
"#,
        hinge[0] + d * c,
        hinge[1] + d * s,
        hinge[0],
        hinge[1]
    )
}

/// The times the arm's angular velocity crosses zero from above (its turning
/// points at the positive end), over `t_end`.
fn turning_points(plant: &mut Plant, omega: usize, t_end: f64) -> Vec<f64> {
    let mut last: Option<(f64, f64)> = None;
    let mut found = Vec::new();
    let dt = 1e-4;
    let mut t = 0.0;
    while t < t_end {
        t += dt;
        plant.advance_to(t, &mut |_| {}).unwrap();
        let w = plant.y[omega];
        if let Some((t0, w0)) = last {
            if w0 > 0.0 && w <= 0.0 {
                found.push(t0 + dt * w0 / (w0 - w));
            }
        }
        last = Some((t, w));
    }
    found
}

/// The mean period from turning points.
fn period(points: &[f64]) -> f64 {
    assert!(points.len() >= 3, "too few swings: {points:?}");
    (points[points.len() - 1] - points[0]) / (points.len() - 1) as f64
}

#[test]
fn a_body_on_a_torsional_spring_swings_with_the_closed_form_period() {
    // No gravity; the platform held; the arm on the platform's spring joint.
    let k = 5.0;
    let m = machine(
        &[("gravity = [0.0, -9.81]", "gravity = [0.0, 0.0]")],
        &arm("platform", [0.15, 0.03], 0.02, k),
    );
    let model = PlantModel::new(&m);
    // Layout: platform free (x, y, theta), the arm's angle, the two rotors.
    assert_eq!(model.dof, 6);
    assert!(matches!(
        model.bodies[1].mount,
        Mount::Child { parent: 0, .. }
    ));
    let omega = model.dof + model.bodies[1].angle;
    let holds = Holds {
        platform: true,
        ..Holds::default()
    };
    let mut plant = Plant::new(model, initial_state(&m), Settings::default(), holds);
    let points = turning_points(&mut plant, omega, 2.0);
    let j_hinge = 1e-3 + 0.3 * 0.1 * 0.1;
    let expected = 2.0 * PI * (j_hinge / k).sqrt();
    let got = period(&points);
    // Small-angle error of a linear spring: none (the spring is linear in the
    // angle and nothing else acts); the turning points are interpolated to
    // O(dt^2 / T^2), far below 1e-6 of the period.
    assert!(
        (got - expected).abs() < 1e-6 * expected,
        "period {got} s, closed form {expected} s"
    );
}

#[test]
fn a_compound_pendulum_on_the_fundament_swings_with_the_closed_form_period() {
    // Gravity -9.81; the arm hinged to the fundament high above the floor, hanging
    // down (angle -pi/2), started 0.01 rad off; no spring.
    let hinge = [0.5, 1.0];
    let angle0 = -PI / 2.0 + 0.01;
    let m = machine(&[], &arm("fundament", hinge, angle0, 0.0));
    let model = PlantModel::new(&m);
    assert!(matches!(model.bodies[1].mount, Mount::Pinned { .. }));
    let omega = model.dof + model.bodies[1].angle;
    let holds = Holds {
        platform: true,
        ..Holds::default()
    };
    let mut plant = Plant::new(model, initial_state(&m), Settings::default(), holds);
    let points = turning_points(&mut plant, omega, 3.0);
    let (mass, d, g): (f64, f64, f64) = (0.3, 0.1, 9.81);
    let j_hinge = 1e-3 + mass * d * d;
    let small = 2.0 * PI * (j_hinge / (mass * g * d)).sqrt();
    // Amplitude 0.01 rad: the period grows by theta0^2 / 16 (the pendulum's series,
    // Landau & Lifshitz, Mechanics, sec. 11), 6e-6 of it.
    let expected = small * (1.0 + 0.01f64.powi(2) / 16.0);
    let got = period(&points);
    assert!(
        (got - expected).abs() < 1e-6 * expected,
        "period {got} s, closed form {expected} s"
    );
}

/// A pendulum (the arm, 0.3 kg) hinged 0.25 m above the floor to the platform,
/// which stands on a frictionless floor; its tip strikes a stop, a vertical face of
/// the platform at x = 0.03 m, with `restitution` and `friction`. Rotors without
/// eccentric masses.
fn pendulum_on_a_sliding_platform(restitution: f64, friction: f64) -> Machine {
    let hinge = [0.0, 0.25];
    let a0 = -PI / 2.0 - 0.3;
    let (s, c) = a0.sin_cos();
    let tip = 0.15;
    let extra = format!(
        r#"{}
[[contacts]]
name = "stop"
body = "arm"
against = "platform"
point = [{}, {}]
face = [0.03, 0.1]
normal = [-1.0, 0.0]
restitution = {restitution:?}
friction = {friction:?}
"#,
        arm("platform", hinge, a0, 0.0),
        hinge[0] + tip * c,
        hinge[1] + tip * s,
    );
    machine(
        &[
            // Every occurrence: both feet, both rotors.
            ("friction = 0.4\nweight", "friction = 0.0\nweight"),
            ("eccentric_mass = 0.01 ", "eccentric_mass = 0.0 "),
        ],
        &extra,
    )
}

/// The platform's and the arm's mass (kg) and inertia about their centres (kg m^2);
/// each rotor's inertia about its axis (kg m^2; no eccentric mass).
const PLATFORM: (f64, f64) = (2.0, 7.3e-3);
const ARM: (f64, f64) = (0.3, 1e-3);
const ROTOR_INERTIA: f64 = 6e-6;

/// Horizontal momentum and mechanical energy from a trace row: the platform
/// and the arm, each `m v_x`, and `m v^2 / 2 + I omega^2 / 2 + m g y`, and each
/// rotor's `I_k (theta' + phi_k')^2 / 2`. The rotors matter: an impact leaves their
/// own spin `theta' + phi'` unchanged while it jolts the platform's, so `phi'`
/// jumps and the motors' friction then trades energy between rotors and platform
/// (measured without them: the platform and the arm gain 1.5e-7 J in the 2 ms
/// after the first impact, 1.7e-8 J between two steps). The velocities are the
/// row's, the plant's own (`PlantModel::body_motion`: the arm's centre's velocity
/// through its Jacobian); [`centre_x`] is the independent side.
fn momentum_and_energy(r: &TraceRow) -> (f64, f64) {
    let g = 9.81;
    let platform = (
        PLATFORM.0,
        PLATFORM.1,
        [r.x, r.y, r.angle, r.vx, r.vy, r.omega],
    );
    let arm = (ARM.0, ARM.1, r.bodies[0]);
    let mut p = 0.0;
    let mut e = 0.0;
    for (m, i, b) in [platform, arm] {
        p += m * b[3];
        e += 0.5 * m * (b[3] * b[3] + b[4] * b[4]) + 0.5 * i * b[5] * b[5] + m * g * b[1];
    }
    // Each rotor's own spin, at theta' + phi'.
    for w in [r.omega + r.omega1, r.omega + r.omega2] {
        e += 0.5 * ROTOR_INERTIA * w * w;
    }
    (p, e)
}

/// The machine's horizontal centre of mass from a trace row's positions alone,
/// `(m_p x_p + m_a x_a) / (m_p + m_a)`, m (the rotors carry no eccentric mass).
fn centre_x(r: &TraceRow) -> f64 {
    (PLATFORM.0 * r.x + ARM.0 * r.bodies[0][0]) / (PLATFORM.0 + ARM.0)
}

/// One reported state of a swing: what kind, when, and what it says.
#[derive(Clone, Copy, Debug)]
struct Seen {
    /// A step's end (dense output), or the state just before or just after an
    /// event.
    kind: Kind,
    t: f64,
    /// The plant's momentum (N s) and the energy (J), [`momentum_and_energy`].
    momentum: f64,
    energy: f64,
    /// [`centre_x`], m.
    centre: f64,
    /// The platform's velocity along x, m/s.
    platform_vx: f64,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    Step,
    Before,
    After,
}

/// The pendulum on the sliding platform, its stop at `restitution` and
/// `friction`, run to `t_end` s: every step's end and every event's states, and
/// the plant.
fn swing(restitution: f64, friction: f64, t_end: f64) -> (Vec<Seen>, Plant) {
    let m = pendulum_on_a_sliding_platform(restitution, friction);
    let model = PlantModel::new(&m);
    let row_model = model.clone();
    let mut plant = Plant::new(
        model,
        initial_state(&m),
        Settings::default(),
        Holds::default(),
    );
    let forces = Default::default();
    let seen_at = |kind: Kind, t: f64, y: &[f64; host_sim::plant::model::NY]| {
        let r = TraceRow::of(&row_model, t, y, [0.0; 2], &forces);
        let (momentum, energy) = momentum_and_energy(&r);
        Seen {
            kind,
            t,
            momentum,
            energy,
            centre: centre_x(&r),
            platform_vx: r.vx,
        }
    };
    let mut seen = vec![seen_at(Kind::Step, 0.0, &plant.y)];
    plant
        .advance_to(t_end, &mut |out| match out {
            Output::Dense(step, upto) => seen.push(seen_at(Kind::Step, upto, &step.at(upto))),
            Output::Before(at) => seen.push(seen_at(Kind::Before, at.t, at.y)),
            Output::After(at) => seen.push(seen_at(Kind::After, at.t, at.y)),
        })
        .unwrap();
    (seen, plant)
}

/// The pendulum strikes the stop (restitution 0.3, friction 0.3) and the
/// platform slides on its frictionless feet, rocking as the blows lift a foot.
///
/// - Momentum: no horizontal external force, so `p_x = 0` throughout. At an event
///   the impulses and the projections onto the contacts are internal (equal and
///   opposite at each contact, mass-weighted), exact up to rounding, `1e-16` of
///   the impulses (0.1 N s) at each of some 30 events: 3e-15 N s. In flight the
///   equations keep `p_x` (`Q_x = 0`) and the integrator does up to its local
///   error, which falls with `rtol`: measured over the run 4.4e-15 N s at 1000
///   times the default `rtol` (1e-5; 2.1e-14 N s with an elastic frictionless
///   stop), 7.8e-16 N s at the default. One tolerance
///   for both, 1e-13 N s (1e-12 of the swing's momentum `m v` = 0.12 N s), checked
///   twice: on the plant's velocities ([`momentum_and_energy`]), and independently
///   of them on the positions alone: the machine's horizontal centre of mass
///   [`centre_x`], whose rate is `p_x / M`, stays where it started, to
///   `1e-13 N s x 1.5 s / 2.3 kg` = 7e-14 m, 1e-13 m.
/// - Energy: nothing adds any (no spring, no motor drive; impacts, the stop's
///   friction and the motors' friction take), so it never rises: not above the
///   start, never at an event, and never from one reported state to the next
///   (a gain in flight smaller than the impacts' losses would pass the first).
///   The allowance between two states: rounding, 2 ulp of the 1 J sum (4.4e-16
///   J, measured), and the integrator's local error on a smooth flight, O((w
///   h)^6) of the swing's energy (0.05 J) with `w h <= 8 rad/s x 1e-3 s` (the
///   largest step): 1.3e-14 J. 1e-12 J leaves a margin of 75 over both, and lies
///   1e4 below the 1.7e-8 J a step that an energy without the rotors gains.
#[test]
fn a_pendulum_striking_a_stop_on_a_frictionless_platform_keeps_the_momentum() {
    let (seen, plant) = swing(0.3, 0.3, 1.5);
    let (p0, e0, x0) = (seen[0].momentum, seen[0].energy, seen[0].centre);
    assert_eq!(p0, 0.0);
    let mut impacts = 0;
    let mut worst_p: f64 = 0.0;
    let mut highest_e = f64::NEG_INFINITY;
    let mut before_e = f64::NAN;
    let mut gained: f64 = 0.0;
    let (mut worst_rise, mut worst_centre) = (f64::NEG_INFINITY, 0.0f64);
    for (k, s) in seen.iter().enumerate() {
        match s.kind {
            Kind::Step => highest_e = highest_e.max(s.energy),
            Kind::Before => before_e = s.energy,
            Kind::After => {
                gained = gained.max(s.energy - before_e);
                impacts += 1;
            }
        }
        worst_p = worst_p.max(s.momentum.abs());
        worst_centre = worst_centre.max((s.centre - x0).abs());
        // From one state to the next, events apart (those are `gained`).
        if k > 0 && s.kind != Kind::After {
            let rise = s.energy - seen[k - 1].energy;
            assert!(
                rise <= 1e-12,
                "the energy rose by {rise} J from t = {} to {} s",
                seen[k - 1].t,
                s.t
            );
            worst_rise = worst_rise.max(rise);
        }
    }
    let platform_speed = seen.iter().fold(0.0f64, |m, s| m.max(s.platform_vx.abs()));
    let stop_impacts = plant
        .events
        .iter()
        .filter(|e| e.contact == "stop" && e.kind.name() == "impact")
        .count();
    assert!(
        stop_impacts >= 2,
        "the arm strikes the stop: {stop_impacts} impacts"
    );
    // The platform is pushed back and forth by the swing (the mechanism under
    // test): the arm's momentum m v ~ 0.1 N s over 2.3 kg.
    assert!(
        platform_speed > 1e-2,
        "the platform moved at most {platform_speed} m/s"
    );
    // Momentum: zero to the integrator's and the projections' accuracy, against
    // the swing's own momentum scale m v (0.3 kg x 0.4 m/s).
    assert!(
        worst_p < 1e-7,
        "horizontal momentum reached {worst_p} N s ({impacts} events)"
    );
    // The tolerance derived above, on the plant's velocities and on the positions.
    assert!(
        worst_p <= 1e-13,
        "horizontal momentum reached {worst_p} N s ({impacts} events)"
    );
    assert!(
        worst_centre <= 1e-13,
        "the centre of mass moved by {worst_centre} m along x"
    );
    // Energy: never above the start (no spring, no motor; impacts and friction
    // only take), to the integrator's tolerance.
    let scale = e0.abs().max(1.0);
    assert!(
        highest_e <= e0 + 1e-7 * scale,
        "energy rose from {e0} J to {highest_e} J"
    );
    assert!(gained <= 1e-9 * scale, "an event gained {gained} J");
    eprintln!(
        "{} states, {impacts} events: |p_x| <= {worst_p:.1e} N s, |X - X0| <= \
         {worst_centre:.1e} m, largest rise between states {worst_rise:.1e} J, at an \
         event {gained:.1e} J, E {e0} -> {} J",
        seen.len(),
        seen[seen.len() - 1].energy
    );
}

/// The reference machine with an arm hinged to the platform (striking a stop on
/// the platform) and a free block striking the arm: contacts on the fundament, of
/// a child body against its parent, and of a free body against a child body.
fn three_bodies() -> Machine {
    machine(&[], include_str!("../fixtures/three-bodies.toml"))
}

/// `q + v t + a t^2 / 2` and `v + a t`.
fn along(q: &Vector, v: &Vector, a: &Vector, t: f64) -> (Vector, Vector) {
    (
        core::array::from_fn(|i| q[i] + v[i] * t + 0.5 * a[i] * t * t),
        core::array::from_fn(|i| v[i] + a[i] * t),
    )
}

/// Every contact's kinematics against finite differences along a path
/// `q(t) = q + v t + a t^2 / 2`: the gap's rate is `u_n`, its second derivative
/// `j_n . a + bias_n`, the slip's rate `j_t . a + bias_t` (the velocity-product
/// terms of a face turning with its body are the ones that need this). Central
/// differences at `h = 1e-4` s err by `O(h^2)`, up to 2e-5 of these rates on the
/// sharpest paths (measured: the error quarters with h halved); combined with
/// those at `h / 2` (Richardson) they err by `O(h^4)`, and by rounding
/// `1e-16 / h^2` (4e-8 m/s^2) on the second difference.
#[test]
fn contact_kinematics_agree_with_finite_differences() {
    let m = three_bodies();
    let model = PlantModel::new(&m);
    let n = model.dof;
    let mut rng = Rng::new(12);
    let h = 1e-4;
    for case in 0..50 {
        let mut q = initial_state_q(&m, &model);
        let (mut v, mut a) = ([0.0; MAX_DOF], [0.0; MAX_DOF]);
        for i in 0..n {
            q[i] += rng.uniform(-0.3, 0.3);
            v[i] = rng.uniform(-3.0, 3.0);
            a[i] = rng.uniform(-50.0, 50.0);
        }
        let kin = |t: f64, j: usize| {
            let (qt, vt) = along(&q, &v, &a, t);
            Pose::new(&model, &qt).contact(&model, j, &vt)
        };
        for j in 0..model.contacts.len() {
            let k0 = kin(0.0, j);
            // Central differences at h and h / 2, combined (Richardson) to cancel
            // the h^2 term: (4 D(h / 2) - D(h)) / 3.
            let richardson = |d: &dyn Fn(f64) -> f64| (4.0 * d(h / 2.0) - d(h)) / 3.0;
            let gap_rate = richardson(&|h| (kin(h, j).gap - kin(-h, j).gap) / (2.0 * h));
            let gap_acc =
                richardson(&|h| (kin(h, j).gap - 2.0 * k0.gap + kin(-h, j).gap) / (h * h));
            let slip_rate = richardson(&|h| (kin(h, j).u_t - kin(-h, j).u_t) / (2.0 * h));
            let dot = |r: &Vector| (0..n).map(|i| r[i] * a[i]).sum::<f64>();
            let name = &model.contacts[j].name;
            let close = |what: &str, numeric: f64, analytic: f64, tol: f64| {
                assert!(
                    (numeric - analytic).abs() <= tol * (1.0 + analytic.abs()),
                    "case {case}, {name}: {what} {analytic} against {numeric} by differences"
                );
            };
            close("u_n", gap_rate, k0.u_n, 1e-6);
            close(
                "normal acceleration",
                gap_acc,
                dot(&k0.j_n) + k0.bias_n,
                1e-5,
            );
            close(
                "slip acceleration",
                slip_rate,
                dot(&k0.j_t) + k0.bias_t,
                1e-6,
            );
        }
    }
}

/// The state's coordinates at t = 0.
fn initial_state_q(m: &Machine, model: &PlantModel) -> Vector {
    let y = initial_state(m);
    core::array::from_fn(|i| if i < model.dof { y[i] } else { 0.0 })
}

/// The mass matrix against the kinetic energy summed mass by mass: each body's
/// `m |v_c|^2 / 2 + I omega^2 / 2` and each eccentric's `m |v|^2 / 2` plus its
/// rotor's `I (theta_b' + phi')^2 / 2`, with every point's velocity a central
/// difference of its position along `q + v t` (positions from the bodies' poses,
/// the eccentric at `e (cos(theta_b + phi), sin(theta_b + phi))` from its axis).
#[test]
fn the_mass_matrix_gives_the_kinetic_energy_of_every_mass() {
    let m = three_bodies();
    let model = PlantModel::new(&m);
    let n = model.dof;
    let mut rng = Rng::new(7);
    let h = 1e-6;
    for case in 0..50 {
        let mut q = initial_state_q(&m, &model);
        let mut v = [0.0; MAX_DOF];
        for i in 0..n {
            q[i] += rng.uniform(-1.0, 1.0);
            v[i] = rng.uniform(-5.0, 5.0);
        }
        // Where every mass is at q + v t.
        let positions = |t: f64| {
            let qt: Vector = core::array::from_fn(|i| q[i] + v[i] * t);
            let pose = Pose::new(&model, &qt);
            let mut p: Vec<[f64; 2]> = (0..model.bodies.len())
                .map(|b| pose.centre_of_mass(&model, b).p)
                .collect();
            for r in &model.rotors {
                let axis = pose.point(&model, r.body, r.axis).p;
                let angle = qt[model.bodies[r.body].angle] + qt[r.phi];
                p.push([
                    axis[0] + r.eccentricity * angle.cos(),
                    axis[1] + r.eccentricity * angle.sin(),
                ]);
            }
            p
        };
        let (up, down) = (positions(h), positions(-h));
        let speed2 = |i: usize| {
            let d = [
                (up[i][0] - down[i][0]) / (2.0 * h),
                (up[i][1] - down[i][1]) / (2.0 * h),
            ];
            d[0] * d[0] + d[1] * d[1]
        };
        let mut energy = 0.0;
        for (b, body) in model.bodies.iter().enumerate() {
            let w = v[body.angle];
            energy += 0.5 * body.mass * speed2(b) + 0.5 * body.inertia * w * w;
        }
        for (k, r) in model.rotors.iter().enumerate() {
            let w = v[model.bodies[r.body].angle] + v[r.phi];
            energy += 0.5 * r.mass * speed2(model.bodies.len() + k) + 0.5 * r.inertia * w * w;
        }
        let from_matrix = Frame::new(&model, &q).kinetic_energy(&v);
        assert!(
            (from_matrix - energy).abs() < 1e-7 * energy.max(1e-3),
            "case {case}: q'^T M q' / 2 = {from_matrix} J, mass by mass {energy} J"
        );
    }
}
