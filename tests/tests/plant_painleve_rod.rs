//! Painleve's rod (`examples/painleve-rod.toml`, Glocker's parameters): a uniform
//! rod of mass 1 kg and half-length 1 m sliding on one end at 30 m/s, leaning back
//! at 31 degrees, friction 5/3, no rebound, gravity 10 m/s^2. While the end slides
//! its normal force is `lambda_n = -B / A` with
//!
//! ```text
//!   A = 1/m + (l^2 / J)(cos^2 theta - mu sin theta cos theta)     (1/kg)
//!   B = -g + l sin theta theta'^2                                 (m/s^2)
//!   theta'' = (l / J)(mu sin theta - cos theta) lambda_n          (rad/s^2)
//!   x_G''   = -mu lambda_n / m                                    (m/s^2)
//! ```
//!
//! (the rod's angle `theta` from the floor, its centre `G` a length `l` behind and
//! above the end: `y_G = l sin theta` while the end touches, `x_end = x_G + l cos
//! theta`; Newton-Euler for the rod with the end's force `(-mu lambda_n,
//! lambda_n)`; Glocker, *Set-Valued Force Laws*, and Genot and Brogliato, *New
//! results on Painleve paradoxes*, write the same two coefficients). Friction
//! turns the rod up; `A` vanishes at 45 degrees (`tan theta = 1`), reached at about
//! 0.81 s while the end slides at some 9 m/s and `B` is nearly 0 as well: the
//! dynamic jam at Genot and Brogliato's singular point, where `lambda_n` grows
//! without bound.
//!
//! The reference is those equations integrated here (classical Runge-Kutta, its
//! step shrinking with `A` towards the jam), independent of the plant's
//! generalized coordinates, mass matrix and contact solver.

use std::f64::consts::PI;

use host_sim::event::EventKind;
use host_sim::machine::Machine;
use host_sim::plant::model::PlantModel;
use host_sim::plant::simulator::{Output, Plant};
use tests::machine::TestMachine;
use tests::unpowered_plant;

const M: f64 = 1.0;
const L: f64 = 1.0;
const J: f64 = M * L * L / 3.0;
const G: f64 = 10.0;
const MU: f64 = 5.0 / 3.0;
/// The rod's angle from the floor at t = 0, rad.
const THETA0: f64 = 31.0 * PI / 180.0;
/// The end's sliding speed at t = 0, m/s.
const SLIP0: f64 = 30.0;

fn machine() -> Machine {
    TestMachine::file("examples/painleve-rod.toml").machine()
}

/// The slip equations' state: `theta` (rad), `theta'` (rad/s), `x_G'` (m/s).
type Slide = [f64; 3];

/// `(A, B)` at a state (the module doc).
fn coefficients(s: &Slide) -> (f64, f64) {
    let (sin, cos) = s[0].sin_cos();
    let a = 1.0 / M + (L * L / J) * (cos * cos - MU * sin * cos);
    let b = -G + L * sin * s[1] * s[1];
    (a, b)
}

/// The normal force while the end slides, N.
fn normal_force(s: &Slide) -> f64 {
    let (a, b) = coefficients(s);
    -b / a
}

fn rates(s: &Slide) -> Slide {
    let lambda = normal_force(s);
    let (sin, cos) = s[0].sin_cos();
    [s[1], (L / J) * (MU * sin - cos) * lambda, -MU * lambda / M]
}

/// The end's sliding speed, m/s: `x_end' = x_G' - l sin theta theta'`.
fn slip(s: &Slide) -> f64 {
    s[2] - L * s[0].sin() * s[1]
}

/// One classical Runge-Kutta step.
fn rk4(s: &Slide, h: f64) -> Slide {
    let at = |k: &Slide, f: f64| [s[0] + f * k[0], s[1] + f * k[1], s[2] + f * k[2]];
    let k1 = rates(s);
    let k2 = rates(&at(&k1, h / 2.0));
    let k3 = rates(&at(&k2, h / 2.0));
    let k4 = rates(&at(&k3, h));
    let mut out = *s;
    for i in 0..3 {
        out[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
    }
    out
}

/// The reference slide at each of `times` (ascending, before the jam), and the
/// instant at which `A` falls to `a_end` with the state there. The step is
/// `min(1e-5, 1e-3 A)` s: `lambda_n` and `theta''` grow like `1 / A` towards the
/// jam, so the step shrinks with it and RK4's error per step stays of the order of
/// `(1e-5)^5` times the rates' fifth derivatives, far below the plant's tolerance.
fn reference(times: &[f64], a_end: f64) -> (Vec<Slide>, f64, Slide) {
    let (mut t, mut s): (f64, Slide) = (0.0, [THETA0, 0.0, SLIP0]);
    let mut at = Vec::new();
    let mut next = times.iter().peekable();
    loop {
        let (a, _) = coefficients(&s);
        if a <= a_end {
            return (at, t, s);
        }
        let mut h = (1e-5f64).min(1e-3 * a);
        if let Some(&&mark) = next.peek() {
            if t + h >= mark {
                h = mark - t;
            }
        }
        s = rk4(&s, h);
        t += h;
        if let Some(&&mark) = next.peek() {
            if (t - mark).abs() < 1e-12 {
                at.push(s);
                next.next();
            }
        }
    }
}

/// The plant's rod as a slide: `theta = THETA0 - phi` (the platform's angle `phi`
/// turns clockwise as the rod rises), and its normal force at the end.
fn plant_slide(plant: &Plant) -> (Slide, f64) {
    let (q, v) = (plant.q(), plant.v());
    let forces = plant.contact_forces();
    ([THETA0 - q[2], -v[2], v[0]], forces[0][0])
}

fn plant() -> Plant {
    unpowered_plant(&machine())
}

/// Before the jam the plant slides the rod as the slip equations do: its angle,
/// angular velocity, sliding speed and normal force at 0.3, 0.5, 0.7 and 0.8 s.
///
/// Tolerance: the plant keeps each step's local error within `1e-8 (1 + |y|)`;
/// the slide is smooth and stable up to 0.7 s (`lambda_n` 10 to 15 N), and the
/// global error a sum of such local errors over some 10^3 steps, 1e-6 relative
/// at most. At 0.8 s `A` has fallen to 0.14 and the force grows like `1 / A`:
/// the same error in `theta` moves `lambda_n` by `|d lambda / d theta|`, about
/// 30 times more, so 3e-5 there.
#[test]
fn before_the_jam_the_rod_slides_as_the_slip_equations_say() {
    let times = [0.3, 0.5, 0.7, 0.8];
    let (want, _, _) = reference(&times, 1e-3);
    assert_eq!(want.len(), times.len());
    let mut plant = plant();
    for (t, want) in times.iter().zip(&want) {
        plant.advance_to(*t, &mut |_| {}).unwrap();
        let (got, lambda) = plant_slide(&plant);
        let tol = if *t < 0.75 { 1e-6 } else { 3e-5 };
        let checks = [
            ("theta (rad)", got[0], want[0]),
            ("theta' (rad/s)", got[1], want[1]),
            ("sliding speed (m/s)", slip(&got), slip(want)),
            ("normal force (N)", lambda, normal_force(want)),
        ];
        for (what, got, want) in checks {
            let scale = want.abs().max(1.0);
            assert!(
                (got - want).abs() <= tol * scale,
                "t = {t} s: {what} {got} in the plant, {want} in the slip equations"
            );
        }
    }
}

/// The premise of the jam, by hand: `A` vanishes at 45 degrees, where the end still
/// slides fast and `B` is small and negative, so `lambda_n = -B / A` grows without
/// bound on the way there: `B` falls with `A` but more slowly (about as
/// `A^(2/3)` on this slide), so each hundredfold fall of `A` multiplies the force
/// by some 4.6 (`100^(1/3)`).
#[test]
fn the_slide_reaches_the_jam_at_45_degrees_still_sliding() {
    let (_, t_jam, s) = reference(&[], 1e-6);
    let (_, b) = coefficients(&s);
    assert!((t_jam - 0.8145).abs() < 5e-4, "A = 0 at t = {t_jam} s");
    assert!(
        (s[0] - PI / 4.0).abs() < 1e-4,
        "theta = {} deg",
        s[0] * 180.0 / PI
    );
    assert!(slip(&s) > 5.0, "sliding at {} m/s", slip(&s));
    assert!(b < 0.0 && b > -0.1, "B = {b} m/s^2");
    let mut force = normal_force(&s);
    for a_end in [1e-8, 1e-10] {
        let (_, _, closer) = reference(&[], a_end);
        let grown = normal_force(&closer);
        assert!(
            grown > 4.0 * force,
            "lambda_n {grown} N at A = {a_end}, {force} N at 100 A"
        );
        force = grown;
    }
}

/// At the jam the plant stops the slide by an impact without collision: a
/// `painleve` event (detail `dynamic jam; tangential impact`) where the slip
/// equations reach `A = 0`, at 45 degrees, then a tangential impact at the end
/// whose normal impulse is the one that stops the slip with friction on the cone,
/// then the rod leaves the floor (its end stopped, the rod turning), and the run
/// goes on to its end without another Painleve configuration and without gaining
/// energy.
///
/// The impulse, by hand: along the slip `s = (1, 0)` and the normal `n = (0, 1)`,
/// with the end at `r = (l cos theta, -l sin theta)` from the centre,
/// `W_nn = 1/m + (l^2/J) cos^2 theta`, `W_ns = (l^2/J) sin theta cos theta`,
/// `W_ss = 1/m + (l^2/J) sin^2 theta`; a normal impulse `P_n` with friction
/// `-mu P_n` along the slip changes the normal velocity by `(W_nn - mu W_ns) P_n`
/// (`A P_n`, nothing at the jam) and the slip by `(W_ns - mu W_ss) P_n`, so the slip
/// `u_s` stops at `P_n = u_s / (mu W_ss - W_ns)`, `P_t = mu P_n` against it. The
/// plant's impact starts from a nudged approach `1e-6 u_s` and the event is at
/// `A = 1e-6 W_nn`: 1e-5 relative covers both.
#[test]
fn at_the_jam_an_impact_without_collision_stops_the_slide() {
    let (_, t_jam, _) = reference(&[], 1e-10);
    let mut plant = plant();
    // The rod's state just before the jam's event: (x, y, phi, x', y', phi').
    let mut before: Option<[f64; 6]> = None;
    let n = PlantModel::new(&machine()).dof;
    plant
        .advance_to(1.5, &mut |out| match &out {
            Output::Before(at) if before.is_none() && (at.t - t_jam).abs() < 1e-3 => {
                let y = at.y;
                before = Some([y[0], y[1], y[2], y[n], y[n + 1], y[n + 2]]);
            }
            _ => {}
        })
        .unwrap();
    assert!(
        (plant.t - 1.5).abs() < 1e-12,
        "the run ended at {} s",
        plant.t
    );
    let painleve: Vec<_> = plant
        .events
        .iter()
        .filter(|e| e.kind == EventKind::Painleve)
        .collect();
    assert_eq!(painleve.len(), 1, "{painleve:?}");
    let jam = painleve[0];
    assert_eq!(jam.detail, "dynamic jam; tangential impact");
    assert!(
        (jam.t - t_jam).abs() < 1e-5,
        "the jam at {} s, the slip equations' A = 0 at {t_jam} s",
        jam.t
    );
    let b = before.expect("the state before the jam's event");
    let theta = THETA0 - b[2];
    assert!(
        (theta - PI / 4.0).abs() < 1e-3,
        "theta = {} deg at the event",
        theta * 180.0 / PI
    );
    // The impulse by hand (the doc above).
    let (sin, cos) = theta.sin_cos();
    let k = L * L / J;
    let (w_ns, w_ss) = (k * sin * cos, 1.0 / M + k * sin * sin);
    let u_s = b[3] - L * sin * (-b[5]);
    let p_n = u_s / (MU * w_ss - w_ns);
    let impact = plant
        .events
        .iter()
        .find(|e| e.kind == EventKind::Impact && e.t == jam.t)
        .expect("the tangential impact");
    assert_eq!(impact.detail, "tangential impact");
    assert!(
        (impact.normal_impulse / p_n - 1.0).abs() < 1e-5,
        "P_n = {} N s, by hand {p_n} N s (slip {u_s} m/s)",
        impact.normal_impulse
    );
    // Friction on the cone's edge while the end slid, inside it once the slip
    // stopped (the last normal impulse, of the nudge's size, stops the approach).
    let (p_t, cone) = (impact.tangential_impulse.abs(), MU * impact.normal_impulse);
    assert!(
        p_t <= cone * (1.0 + 1e-12) && p_t >= cone * (1.0 - 1e-5),
        "P_t = {p_t} N s against mu P_n = {cone} N s"
    );
    // Then the end leaves the floor at the same instant, and nothing more happens
    // to the contact until the run's end but flight and landing.
    assert!(plant
        .events
        .iter()
        .any(|e| e.kind == EventKind::Liftoff && e.t == jam.t));
    assert!(
        plant.warnings.iter().all(|w| !w.contains("no progress")),
        "{:?}",
        plant.warnings
    );
}

/// No energy is gained across the jam and after it: the mechanical energy (the
/// rod's kinetic and potential energy; the rotor has no eccentric and its winding
/// is open) never rises above its value at the start, sampled every millisecond and
/// at every event, and the impact without collision takes energy out (the slip's).
#[test]
fn no_energy_is_gained_across_the_jam() {
    let mut plant = plant();
    let start = plant.mechanical_energy();
    let (_, t_jam, _) = reference(&[], 1e-10);
    let mut highest: f64 = start;
    let mut at_jam = (f64::NAN, f64::NAN);
    for k in 1..=1500 {
        plant.advance_to(k as f64 * 1e-3, &mut |_| {}).unwrap();
        let e = plant.mechanical_energy();
        highest = highest.max(e);
        if (plant.t - t_jam).abs() < 1.5e-3 && at_jam.0.is_nan() && plant.t > t_jam {
            at_jam = (plant.t, e);
        }
    }
    assert!(
        highest <= start * (1.0 + 1e-9),
        "energy rose to {highest} J from {start} J"
    );
    let (t, e) = at_jam;
    assert!(
        e < 0.5 * start,
        "{e} J just after the jam (t = {t} s), {start} J at the start"
    );
}
