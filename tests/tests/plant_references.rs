//! The simulated plant (`host_sim::plant`) against independent references: closed
//! forms derived here, a second solver (`shared::impact::solve_body` for one rigid
//! body), and conservation laws computed from the state with formulas written here
//! (never the plant's own mass matrix or energy).
//!
//! - drop test: a flat platform bouncing on two feet is a bouncing ball, whose impact
//!   velocities fall by `e` and whose impacts accumulate at `t1 (1 + e) / (1 - e)`;
//! - the Zeno threshold does not move the accumulation point;
//! - a rotor spun up by its motor on a held platform: the second-order step response
//!   of `(L, R, k, J)`, and the current limit's linear ramp;
//! - mechanical energy: conserved without friction at restitution 1, never growing
//!   with dissipation;
//! - the exciting force of a counter-rotating pair: along `offset / 2`, amplitude
//!   `2 m e w^2`;
//! - a flat landing against `solve_body` for the combined rigid body, and the angular
//!   momentum about a single landing contact conserved through the impact;
//! - the sliding threshold `F0 (cos b + mu sin b) = mu M g`;
//! - determinism: two runs give the same bits.
//!
//! Conventions: world `x` right, `y` up, the fundament `y = 0` with normal `n = (0, 1)`
//! and tangent `t = (-n_y, n_x) = (-1, 0)`; gravity `(0, -G)`; state layout
//! `(x, y, theta, phi1, phi2, x', y', theta', phi1', phi2', i1, i2)`.

use shared::Enumerated;
use std::f64::consts::PI;

use host_sim::event::{EventKind, EventRow};
use host_sim::plant::contact::ContactMode;
use host_sim::plant::model::NY;
use host_sim::plant::motor::Winding;
use host_sim::plant::simulator::{Holds, Output, Plant, Settings};
use shared::impact::{solve_body, BodyContact, ContactLaw, ImpactLaw, PlanarBody};
use shared::vec2::{add, cross, norm, spin, sub};
use tests::rig::*;

/// The impact rows grouped by instant, in order.
fn impact_instants(events: &[EventRow]) -> Vec<Vec<&EventRow>> {
    let mut out: Vec<Vec<&EventRow>> = Vec::new();
    for e in events.iter().filter(|e| e.kind == EventKind::Impact) {
        match out.last_mut() {
            Some(group) if group[0].t == e.t => group.push(e),
            _ => out.push(vec![e]),
        }
    }
    out
}

// ---------------------------------------------------------------------------------
// 1, 2: the drop test
// ---------------------------------------------------------------------------------

/// Drop height of the feet above the floor, m.
const DROP_HEIGHT: f64 = 0.05;
/// Restitution at both feet.
const DROP_RESTITUTION: f64 = 0.5;

/// The reference platform held flat with its feet `DROP_HEIGHT` above the floor,
/// eccentrics hanging straight down (`phi = -pi/2`, mirror images about the centre
/// line), windings open, frictionless motors.
fn drop_rig() -> Rig {
    let mut rig = Rig::reference();
    rig.position = [0.0, 0.03 + DROP_HEIGHT];
    for f in &mut rig.feet {
        f.restitution = DROP_RESTITUTION;
    }
    for r in &mut rig.rotors {
        r.angle = -PI / 2.0;
    }
    rig
}

/// What a drop run reports.
struct Drop {
    plant: Plant,
    zeno_time: f64,
}

/// Drops the platform and lets it settle: until 0.2 s past the closed-form
/// accumulation point.
fn run_drop(settings: Settings) -> Drop {
    let rig = drop_rig();
    let mut plant = rig.plant(settings, Holds::default(), |_| {});
    let e = DROP_RESTITUTION;
    let t1 = (2.0 * DROP_HEIGHT / G).sqrt();
    plant
        .advance_to(t1 * (1.0 + e) / (1.0 - e) + 0.2, &mut |_| {})
        .unwrap();
    let zeno: Vec<&EventRow> = plant
        .events
        .iter()
        .filter(|e| e.kind == EventKind::Zeno)
        .collect();
    assert_eq!(
        zeno.len(),
        2,
        "one Zeno row per foot expected, events: {:#?}",
        plant.events
    );
    assert_eq!(zeno[0].t, zeno[1].t);
    let parse = |e: &EventRow| -> f64 {
        e.detail
            .strip_prefix("accumulation_time=")
            .and_then(|s| s.parse().ok())
            .unwrap_or_else(|| panic!("Zeno detail {:?}", e.detail))
    };
    let zeno_time = parse(zeno[0]);
    assert_eq!(zeno_time, parse(zeno[1]));
    Drop { plant, zeno_time }
}

/// Reference (derivation): the platform falls flat and both feet strike together.
/// With the eccentrics hanging straight down, the eccentric arm is along the impulse
/// the axis transmits, so the rotors take no angular impulse; the feet are mirror
/// images about the centre line through the combined centre of mass, so both take the
/// same impulse and nothing rotates. In flight everything falls at `g` together, so
/// nothing moves relative to the platform. The machine is then a bouncing ball:
/// - first impact at `t1 = sqrt(2 H / g)` with `v0 = g t1`;
/// - Poisson (and Newton, Stronge) restitution at a frictionless-in-effect flat
///   landing: rebound `e v`; the next impact comes after a flight of `2 e v / g` at the
///   same speed `e v`: successive impact speeds fall by `e`;
/// - accumulation point `t_inf = t1 + sum_{k>=1} 2 e^k v0 / g = t1 (1 + e) / (1 - e)`.
///
/// Tolerances: the free flight is a parabola, which Dormand-Prince (order 5) and its
/// dense output (order 4) reproduce to rounding; events are located to
/// `event_time_tolerance` `dt = 1e-12 s`. A late location by `dt` changes an impact
/// speed by `g dt` and starts the next flight `v dt` below the floor, which adds
/// `g dt` more on arrival: `|v_{k+1} - e v_k| <= 1e-9 v_k + 2 g dt`. The first impact
/// time is exact to `dt` (10 dt allowed); the accumulation point to 1e-6 relative
/// (docs/plant-model.md, "What the tests check"; the flight times are exact to `dt`
/// each).
#[test]
fn drop_test_bounces_like_a_ball_and_comes_to_rest_on_both_feet() {
    let settings = Settings::default();
    let dt = settings.event_time_tolerance;
    let Drop {
        mut plant,
        zeno_time,
    } = run_drop(settings);
    let e = DROP_RESTITUTION;
    let t1 = (2.0 * DROP_HEIGHT / G).sqrt();
    let v0 = G * t1;
    assert!(plant.warnings.is_empty(), "warnings: {:?}", plant.warnings);

    // Every impact instant has both feet, once each.
    let instants = impact_instants(&plant.events);
    assert!(instants.len() >= 10, "only {} impacts", instants.len());
    assert_eq!(plant.impacts, instants.len());
    for group in &instants {
        let mut names: Vec<&str> = group.iter().map(|e| e.contact.as_str()).collect();
        names.sort_unstable();
        assert_eq!(names, ["K1", "K2"], "impact at t = {}", group[0].t);
        check(
            "both feet strike at the same speed",
            group[1].normal_velocity_before,
            group[0].normal_velocity_before,
            1e-12 * group[0].normal_velocity_before.abs(),
        );
    }

    // First impact at sqrt(2H/g), speed g t1.
    check("first impact time", instants[0][0].t, t1, 10.0 * dt);
    check(
        "first impact speed",
        -instants[0][0].normal_velocity_before,
        v0,
        1e-9 * v0,
    );

    // Successive impact speeds fall by e; each rebound is e times its impact speed
    // (all but the last, Zeno-closed one, which ends plastically).
    let speeds: Vec<f64> = instants
        .iter()
        .map(|g| -g[0].normal_velocity_before)
        .collect();
    for k in 0..speeds.len() - 1 {
        check(
            &format!("impact speed {} over impact speed {k}", k + 1),
            speeds[k + 1],
            e * speeds[k],
            1e-9 * speeds[k] + 2.0 * G * dt,
        );
        for row in &instants[k] {
            check(
                &format!("rebound of impact {k}"),
                row.normal_velocity_after,
                e * speeds[k],
                1e-9 * speeds[k],
            );
        }
    }

    // The accumulation point.
    let t_inf = t1 * (1.0 + e) / (1.0 - e);
    check("Zeno accumulation time", zeno_time, t_inf, 1e-6 * t_inf);

    // At rest on both feet, and still there a second later (no sinking).
    let rest_y = 0.03;
    let at_rest = |p: &Plant, when: &str| {
        assert!(
            p.modes.iter().all(|m| *m != ContactMode::Open),
            "{when}: modes {:?}",
            p.modes
        );
        check(&format!("{when}: height"), p.y[1], rest_y, 1e-9);
        check(&format!("{when}: angle"), p.y[2], 0.0, 1e-12);
        for i in 5..8 {
            check(&format!("{when}: velocity {i}"), p.y[i], 0.0, 1e-9);
        }
    };
    at_rest(&plant, "after the accumulation");
    let t = plant.t;
    plant.advance_to(t + 1.0, &mut |_| {}).unwrap();
    at_rest(&plant, "one second later");
}

/// Reference: the accumulation point is a property of the bouncing ball,
/// `t1 (1 + e) / (1 - e)`, not of the rebound speed below which the plant stops
/// following single bounces; the plant closes the tail analytically. Halving or
/// doubling the threshold must leave it within 1e-6 relative.
#[test]
fn zeno_accumulation_time_does_not_depend_on_the_threshold() {
    let e = DROP_RESTITUTION;
    let t_inf = (2.0 * DROP_HEIGHT / G).sqrt() * (1.0 + e) / (1.0 - e);
    let base = Settings::default();
    let times: Vec<f64> = [0.5, 1.0, 2.0]
        .iter()
        .map(|f| {
            run_drop(Settings {
                zeno_velocity: f * base.zeno_velocity,
                ..base
            })
            .zeno_time
        })
        .collect();
    for (f, t) in [0.5, 1.0, 2.0].iter().zip(&times) {
        check(
            &format!("accumulation time at {f} x zeno_velocity"),
            *t,
            t_inf,
            1e-6 * t_inf,
        );
        check(
            &format!("accumulation time at {f} x zeno_velocity vs 1 x"),
            *t,
            times[1],
            1e-6 * t_inf,
        );
    }
}

// ---------------------------------------------------------------------------------
// 3: a rotor spun up by its motor
// ---------------------------------------------------------------------------------

/// A held platform with plain rotors (no eccentric mass) and frictionless motors.
fn spin_rig(current_limit: f64) -> Rig {
    let mut rig = Rig::reference();
    for r in &mut rig.rotors {
        r.mass = 0.0;
    }
    rig.motor.current_limit = current_limit;
    rig
}

/// Reference: with the platform held and no eccentric mass, each rotor is an inertia
/// `J` (the rotor's own) on its motor:
///
/// ```text
///   L i' = u - R i - k w,   J w' = k i,   i(0) = w(0) = 0
/// ```
///
/// Eliminating `i`: `L J w'' + R J w' + k^2 w = k u`, poles `p1, p2` the roots of
/// `L J s^2 + R J s + k^2 = 0` (real and distinct here: `(RJ)^2 > 4 L J k^2`), steady
/// speed `w_ss = u / k`. With `w(0) = w'(0) = 0` (`w' = k i / J`):
///
/// ```text
///   w(t) = w_ss (1 + (p2 e^{p1 t} - p1 e^{p2 t}) / (p1 - p2))
///   i(t) = (J / k) w'(t) = (J / k) w_ss p1 p2 (e^{p1 t} - e^{p2 t}) / (p1 - p2)
/// ```
///
/// Rotor 1 (ccw) turns at `phi1' = +w`, rotor 2 (cw) at `phi2' = -w`, both drawing `i`.
/// The current peaks near `u / R = 6 A`, so the limit is set to 100 A.
///
/// Tolerance, from the integrator's `rtol` (`Settings::default()`): each accepted step
/// errs by at most `sqrt(12) (atol + rtol |y|)` per component (see
/// [`step_allowance`]; `atol = rtol` on rates and currents), in the coordinates scaled
/// by `u / R` and `w_ss` at most `sqrt(2) sqrt(12) rtol (1 + 1 / min scale)`. The
/// system is linear and stable: a local error `d_j` is carried to `t` as
/// `V e^{Lambda (t - t_j)} V^-1 d_j` (`V` the eigenvectors, both poles negative), so
/// the global error is at most `kappa(V) * sum_j |d_j|` = `kappa * steps * that`
/// (about 5e-3 relative at rtol = 1e-6, 5e-5 at 1e-8).
#[test]
fn free_rotor_spin_up_is_the_second_order_step_response() {
    let rig = spin_rig(100.0);
    let settings = Settings::default();
    let holds = Holds {
        platform: true,
        rotors: false,
        ..Holds::default()
    };
    let mut plant = rig.plant(settings, holds, |_| {});
    let u = 12.0;
    plant.set_winding([Winding::Voltage(u), Winding::Voltage(u)]);

    let m = &rig.motor;
    let (l, r, k, j) = (
        m.inductance,
        m.resistance,
        m.torque_constant,
        rig.rotors[0].inertia,
    );
    let (a, b, c) = (l * j, r * j, k * k);
    let disc = b * b - 4.0 * a * c;
    assert!(disc > 0.0, "real poles expected");
    let p1 = (-b + disc.sqrt()) / (2.0 * a);
    let p2 = (-b - disc.sqrt()) / (2.0 * a);
    let w_ss = u / k;
    // Scales: speed w_ss, current u / R (both bound |w|, |i| over the transient).
    let scale = [u / r, w_ss];
    // Eigenvectors of (i, w)' = [[-R/L, -k/L], [k/J, 0]] (i, w): (p J / k, 1), here
    // in the scaled coordinates (i / scale_i, w / scale_w), normalised (any scaling of
    // the columns gives a valid bound; unit columns a near-best one).
    let col = |p: f64| {
        let c = [p * j / k / scale[0], 1.0 / scale[1]];
        let n = c[0].hypot(c[1]);
        [c[0] / n, c[1] / n]
    };
    let (c1, c2) = (col(p1), col(p2));
    let kappa = cond2([[c1[0], c2[0]], [c1[1], c2[1]]]);

    // Five slow time constants, 300 samples.
    let t_end = 5.0 / -p1;
    let mut worst = [0.0f64; 2];
    for n in 1..=300 {
        let t = t_end * n as f64 / 300.0;
        plant.advance_to(t, &mut |_| {}).unwrap();
        let (e1, e2) = ((p1 * t).exp(), (p2 * t).exp());
        let w = w_ss * (1.0 + (p2 * e1 - p1 * e2) / (p1 - p2));
        let i = j / k * w_ss * p1 * p2 * (e1 - e2) / (p1 - p2);
        let y = plant.y;
        worst[0] = worst[0].max((y[10] - i).abs()).max((y[11] - i).abs());
        worst[1] = worst[1].max((y[8] - w).abs()).max((y[9] + w).abs());
        assert_eq!(y[5..8], [0.0; 3], "the platform is held");
    }
    // Per step, each scaled component errs by at most sqrt(12) (atol + rtol |y|) /
    // scale <= sqrt(12) rtol (1 + 1 / scale) (atol = rtol on rates and currents), the
    // pair by sqrt(2) times that; errors decay in modal coordinates, so the global
    // scaled error is at most kappa * steps * that.
    let rtol = settings.rtol;
    let per_step =
        2f64.sqrt() * (STATE_LEN as f64).sqrt() * rtol * (1.0 + 1.0 / scale[0].min(scale[1]));
    let bound = kappa * plant.steps as f64 * per_step;
    eprintln!(
        "spin-up: {} steps, kappa {kappa:.3}, relative bound {bound:.3e}; worst current \
         error {:.3e} A, speed error {:.3e} rad/s",
        plant.steps, worst[0], worst[1]
    );
    for (n, what) in ["current", "speed"].iter().enumerate() {
        assert!(
            worst[n] <= bound * scale[n],
            "{what} error {} > {}",
            worst[n],
            bound * scale[n]
        );
    }
    // A meaningful bound: a 1 % error in R, L, k or J would show.
    assert!(bound < 1e-2, "bound {bound}");
}

/// The 2-norm condition number of a 2x2 matrix (from its singular values).
fn cond2(m: [[f64; 2]; 2]) -> f64 {
    // Singular values: eigenvalues of M^T M are (tr +- sqrt(tr^2 - 4 det^2)) / 2.
    let fro = m[0][0].powi(2) + m[0][1].powi(2) + m[1][0].powi(2) + m[1][1].powi(2);
    let det = m[0][0] * m[1][1] - m[0][1] * m[1][0];
    let root = (fro * fro - 4.0 * det * det).max(0.0).sqrt();
    ((fro + root) / (fro - root)).sqrt()
}

/// A step-end sample of the current-limit run: `(t, i1, i2, w1, w2)`.
type LimitSample = (f64, f64, f64, f64, f64);

/// The current-limit run: 12 V on a 1 A limit, both rotors, until 1.5 x the release
/// time. Returns the rig, the step-end samples `(t, i1, i2, w1, w2)` on a grid of
/// 3000 targets, and the largest current the dense output shows (sampled at quarter
/// steps).
fn run_current_limit() -> (Rig, Vec<LimitSample>, f64) {
    let limit = 1.0;
    let rig = spin_rig(limit);
    let holds = Holds {
        platform: true,
        rotors: false,
        ..Holds::default()
    };
    let mut plant = rig.plant(Settings::default(), holds, |_| {});
    let u = CLAMP_VOLTAGE;
    plant.set_winding([Winding::Voltage(u), Winding::Voltage(u)]);
    let m = &rig.motor;
    let slope = m.torque_constant * limit / rig.rotors[0].inertia;
    let t_release = (u - m.resistance * limit) / m.torque_constant / slope;
    let mut samples = Vec::new();
    let mut worst_dense = 0.0f64;
    let mut record = |out: Output<'_>| {
        if let Output::Dense(step, upto) = out {
            for f in [0.25, 0.5, 0.75, 1.0] {
                let y = step.at(step.t0 + f * (upto - step.t0));
                worst_dense = worst_dense.max(y[10].abs()).max(y[11].abs());
            }
        }
    };
    let t_end = 1.5 * t_release;
    let n = 3000;
    for s in 1..=n {
        plant
            .advance_to(t_end * s as f64 / n as f64, &mut record)
            .unwrap();
        let y = plant.y;
        samples.push((plant.t, y[10], y[11], y[8], y[9]));
    }
    (rig, samples, worst_dense)
}

/// The winding voltage of the current-limit tests, V.
const CLAMP_VOLTAGE: f64 = 12.0;

/// Reference: 12 V on the winding would draw `u / R = 6 A`; the driver holds
/// `I_lim = 1 A`. While held, `J w' = k I_lim`: the speed rises linearly at
/// `k I_lim / J`, exactly (a constant acceleration is integrated to rounding). The
/// limit lets go where the bridge can no longer push the current up,
/// `u - R I_lim - k w = 0`: `w_release = (u - R I_lim) / k`. At every step end the
/// current is within `[-I_lim, I_lim]`.
#[test]
fn current_limit_clamps_and_the_speed_ramps_linearly() {
    let (rig, samples, _) = run_current_limit();
    let m = &rig.motor;
    let (u, limit) = (CLAMP_VOLTAGE, m.current_limit);
    let (r, k, j) = (m.resistance, m.torque_constant, rig.rotors[0].inertia);
    let slope = k * limit / j;
    let w_release = (u - r * limit) / k;
    let t_release = w_release / slope; // plus the ~L I / u = 42 us to reach the limit

    // At step ends the current is within the limit, to rounding.
    for &(t, i1, i2, _, _) in &samples {
        assert!(
            i1.abs() <= limit && i2.abs() <= limit,
            "t = {t}: currents {i1}, {i2} beyond the {limit} A limit"
        );
    }
    // While clamped (from 1 ms to just before the release) i = I_lim exactly, and the
    // speed rises at k I_lim / J.
    let clamped: Vec<_> = samples
        .iter()
        .filter(|s| s.0 >= 1e-3 && s.0 <= 0.95 * t_release)
        .collect();
    for s in &clamped {
        assert_eq!((s.1, s.2), (limit, limit), "t = {}: not at the limit", s.0);
    }
    let (first, last) = (clamped[0], clamped[clamped.len() - 1]);
    for (name, w0, w1, sign) in [
        ("rotor 1", first.3, last.3, 1.0),
        ("rotor 2", first.4, last.4, -1.0),
    ] {
        check(
            &format!("{name}: speed rise while clamped"),
            sign * (w1 - w0),
            slope * (last.0 - first.0),
            1e-9 * slope * (last.0 - first.0),
        );
    }
    // The release: the last sample at the limit is at or below w_release, the first
    // one off it at or above (to rounding).
    let off = samples
        .iter()
        .position(|s| s.0 > 1e-3 && s.1 < limit)
        .expect("the limit lets go");
    let (before, after) = (samples[off - 1], samples[off]);
    assert!(
        before.3 <= w_release * (1.0 + 1e-12) && after.3 >= w_release * (1.0 - 1e-12),
        "release speed {w_release} not within [{}, {}]",
        before.3,
        after.3
    );
}

/// Reference: the driver clamps the winding current to `+-I_lim` (docs/machine-file.md,
/// `motor.current_limit`), so every state the plant reports, including the dense output
/// that `run --out` samples between step ends, has `|i| <= I_lim` (to rounding,
/// 1e-12 relative).
#[test]
fn dense_output_current_stays_within_the_limit() {
    let (rig, _, worst_dense) = run_current_limit();
    let limit = rig.motor.current_limit;
    assert!(
        worst_dense <= limit * (1.0 + 1e-12),
        "dense output current {worst_dense} A beyond the {limit} A limit"
    );
}

// ---------------------------------------------------------------------------------
// 4: mechanical energy
// ---------------------------------------------------------------------------------

/// The reference platform dropped tilted, rocking and bouncing on its feet, windings
/// open and motors frictionless (the rotors swing freely), with this restitution and
/// friction at both feet.
fn rocking_rig(restitution: f64, friction: f64) -> Rig {
    let mut rig = Rig::reference();
    rig.angle = 0.15;
    rig.velocity = [0.2, 0.0];
    rig.angular_velocity = -1.0;
    for f in &mut rig.feet {
        f.restitution = restitution;
        f.friction = friction;
    }
    rig.rotors[0].angle = 0.3;
    rig.rotors[1].angle = 2.5;
    // The lower foot (K1, tilted ccw) 2 cm above the floor.
    let low = rot(rig.angle, rig.feet[0].local)[1];
    rig.position = [0.0, 0.02 - low];
    rig
}

/// Energy samples of a run: `(kind, t, E, allowance)` at every step end (`Dense`) and
/// around every event (`Before`, `After`), the allowance being the step's
/// [`step_allowance`] of the energy.
fn energy_samples(rig: &Rig, t_end: f64) -> (Plant, Vec<(char, f64, f64, f64)>) {
    let settings = Settings::default();
    let mut plant = rig.plant(settings, Holds::default(), |y| {
        y[8] = 3.0;
        y[9] = -2.0;
    });
    let mut samples = vec![('0', 0.0, energy(rig, &plant.y), 0.0)];
    let e = |y: &[f64; NY]| energy(rig, y);
    plant
        .advance_to(t_end, &mut |out| match out {
            Output::Dense(step, upto) => {
                let y = step.at(upto);
                samples.push(('D', upto, e(&y), step_allowance(&e, &y, settings.rtol)));
            }
            Output::Before(at) => samples.push(('B', at.t, e(at.y), 0.0)),
            Output::After(at) => {
                samples.push(('A', at.t, e(at.y), step_allowance(&e, at.y, settings.rtol)))
            }
        })
        .unwrap();
    (plant, samples)
}

/// Reference: without motors (open windings, no motor friction), without friction at
/// the feet and with restitution 1, nothing dissipates: between impacts the system is
/// conservative (gravity only; the rotors swing freely), and an impact at restitution
/// 1 without friction returns every contact's normal velocity reversed, which keeps
/// the kinetic energy (`dT = P . (u- + u+) / 2 = 0`). The energy, computed here from
/// the state ([`energy`]), stays at its initial value.
///
/// Tolerances:
/// - across an impact (`Before` to `After`, same configuration): rounding, 1e-12 of
///   the energy's terms, plus what a Zeno closure may take at most, the kinetic
///   energy `M v_z^2 / 2` of a rebound below `zeno_velocity` (a grazing impact);
/// - over one step: the step's [`step_allowance`] (the integrator's accepted local
///   error carried into the energy);
/// - from the start: the sum of all of those.
#[test]
fn energy_is_conserved_through_elastic_frictionless_impacts() {
    let rig = rocking_rig(1.0, 0.0);
    let (plant, samples) = energy_samples(&rig, 3.0);
    assert!(plant.warnings.is_empty(), "warnings: {:?}", plant.warnings);
    assert!(plant.impacts >= 50, "only {} impacts", plant.impacts);
    let e0 = samples[0].2;
    let zeno = 0.5 * rig.total_mass() * Settings::default().zeno_velocity.powi(2);
    let mut allowed = 0.0;
    let mut worst = [0.0f64; 3];
    for w in samples.windows(2) {
        let ((k0, t0, e_prev, _), (k1, t1, e_next, step)) = (w[0], w[1]);
        let local = if (k0, k1) == ('B', 'A') {
            1e-12 * e0.abs() + zeno
        } else {
            step
        };
        allowed += local;
        let what = format!("energy from t = {t0} ({k0}) to t = {t1} ({k1})");
        check(&what, e_next, e_prev, local);
        check(&format!("{what}, from the start"), e_next, e0, allowed);
        let n = if (k0, k1) == ('B', 'A') { 0 } else { 1 };
        worst[n] = worst[n].max((e_next - e_prev).abs());
        worst[2] = worst[2].max((e_next - e0).abs());
    }
    eprintln!(
        "elastic: {} impacts, {} samples; worst change across an impact {:.3e} J, over a \
         step {:.3e} J, from the start {:.3e} J of {e0:.4} J (allowance at the end {allowed:.3e} J)",
        plant.impacts,
        samples.len(),
        worst[0],
        worst[1],
        worst[2]
    );
}

/// Reference: with restitution 0.5 and friction 0.4 every impact and every slip
/// dissipates (Poisson's law at one contact, or at several with equal restitution,
/// never gains energy: `docs/impact-model.md`, "Energy"), and sticking or resting
/// does no work. So from one sample to the next the energy never grows by more than
/// the step's integration allowance ([`step_allowance`]) plus 1e-12 relative.
#[test]
fn energy_never_grows_with_dissipation() {
    let rig = rocking_rig(0.5, 0.4);
    let (plant, samples) = energy_samples(&rig, 1.5);
    assert!(plant.warnings.is_empty(), "warnings: {:?}", plant.warnings);
    assert!(plant.impacts >= 10, "only {} impacts", plant.impacts);
    let e0 = samples[0].2;
    for w in samples.windows(2) {
        let ((k0, t0, e_prev, _), (k1, t1, e_next, allow)) = (w[0], w[1]);
        assert!(
            e_next <= e_prev + allow + 1e-12 * e0.abs(),
            "energy grew from {e_prev:.15e} J ({k0}, t = {t0}) to {e_next:.15e} J ({k1}, t = {t1}): \
             +{:.3e} J > allowance {allow:.3e} J",
            e_next - e_prev
        );
    }
    let last = samples[samples.len() - 1].2;
    assert!(last < e0, "no energy lost: {e0} -> {last}");
}

// ---------------------------------------------------------------------------------
// 5: the exciting force of the counter-rotating pair
// ---------------------------------------------------------------------------------

/// Reference: platform and rotors held, rotor 1 at `phi1' = +w`, rotor 2 at
/// `phi2' = -w`, both eccentricities `e`, masses `m`, platform level. Each eccentric
/// mass moves on a circle at constant speed, so the axis must pull it inward with
/// `-m w^2 eps_k`; it pushes the platform with `+m w^2 eps_k`,
/// `eps_k = e (cos phi_k, sin phi_k)`. The sum, with `phi1 = phi1_0 + w t`,
/// `phi2 = phi2_0 - w t`:
///
/// ```text
///   F = m e w^2 (cos phi1 + cos phi2, sin phi1 + sin phi2)
///     = 2 m e w^2 cos((phi1 - phi2) / 2) (cos((phi1 + phi2) / 2), sin((phi1 + phi2) / 2))
/// ```
///
/// `phi1 + phi2 = phi1_0 + phi2_0` is constant, and equals the phase offset
/// `d = theta1 - theta2` (docs/machine-file.md, "Conventions":
/// `theta_k = s_k (phi_k - index_angle_k)`, `s = +1, -1`, index angles 0): `F` lies on
/// the line at `d / 2` from +x with amplitude `F0 = 2 m e w^2`, reached where
/// `phi1 - phi2 = 0 (mod 2 pi)`.
///
/// The plant's holding force on `(x, y)` balances gravity on everything and the
/// exciting force: `F = -h_xy - M g`, `M` the total mass. Its moment about the
/// platform's centre of mass (from the whole system's angular momentum: the rotors'
/// own spin is constant) is `sum_k m w^2 rho_k x eps_k`, `rho_k` the axis offsets:
/// `-h_theta - sum_k r_k x m g`, `r_k = rho_k + eps_k`.
///
/// Tolerance 1e-10 of `F0`: the held rotors turn at exactly constant speed, so their
/// angles are `phi_0 +- w t` to rounding.
#[test]
fn exciting_force_lies_along_half_the_offset_with_amplitude_2_m_e_w2() {
    let rig = Rig::reference();
    let (m, e) = (rig.rotors[0].mass, rig.rotors[0].eccentricity);
    let total = rig.total_mass();
    let w = 300.0;
    let f0 = 2.0 * m * e * w * w;
    let period = 2.0 * PI / w;
    let holds = Holds {
        platform: true,
        rotors: true,
        ..Holds::default()
    };
    for offset_deg in [0.0f64, 60.0, 90.0, 180.0, 270.0] {
        let d = offset_deg.to_radians();
        // Start angles with phi1 + phi2 = d (and an arbitrary phi1 - phi2).
        let (phi1_0, phi2_0) = (d - 0.7, 0.7);
        let mut plant = rig.plant(Settings::default(), holds, |y| {
            y[3] = phi1_0;
            y[4] = phi2_0;
            y[8] = w;
            y[9] = -w;
        });
        let u = [(d / 2.0).cos(), (d / 2.0).sin()];
        // Sample times: 720 over one revolution and the amplitude's peak,
        // phi1 - phi2 = phi1_0 - phi2_0 + 2 w t = 2 pi k.
        let mut times: Vec<f64> = (1..=720).map(|n| period * n as f64 / 720.0).collect();
        let t_peak = (2.0 * PI - (phi1_0 - phi2_0)).rem_euclid(2.0 * PI) / (2.0 * w);
        times.push(t_peak);
        times.sort_by(f64::total_cmp);
        let mut peak = 0.0f64;
        for &t in &times {
            plant.advance_to(t, &mut |_| {}).unwrap();
            let h = plant.holding_force();
            let f = [-h[0], -h[1] + total * G];
            let (phi1, phi2) = (phi1_0 + w * t, phi2_0 - w * t);
            let amplitude = f0 * (0.5 * (phi1 - phi2)).cos();
            let ctx = format!("offset {offset_deg} deg, t = {t}");
            check(&format!("{ctx}: F x u"), cross(u, f), 0.0, 1e-10 * f0);
            check(
                &format!("{ctx}: F . u"),
                f[0] * u[0] + f[1] * u[1],
                amplitude,
                1e-10 * f0,
            );
            peak = peak.max(norm(f));
            // The moment about the platform's centre of mass.
            let mut gravity_moment = 0.0;
            let mut exciting_moment = 0.0;
            for (k, phi) in [phi1, phi2].into_iter().enumerate() {
                let r = &rig.rotors[k];
                let eps = [e * phi.cos(), e * phi.sin()];
                let arm = add(r.axis, eps);
                gravity_moment += cross(arm, [0.0, -r.mass * G]);
                exciting_moment += r.mass * w * w * cross(r.axis, eps);
            }
            check(
                &format!("{ctx}: exciting moment"),
                -h[2] - gravity_moment,
                exciting_moment,
                // F0 on a 0.1 m arm sets the moment's scale.
                1e-10 * f0 * 0.1,
            );
        }
        check(
            &format!("offset {offset_deg} deg: peak amplitude"),
            peak,
            f0,
            1e-10 * f0,
        );
    }
}

// ---------------------------------------------------------------------------------
// 6: landings against the single-body impact solver and angular momentum
// ---------------------------------------------------------------------------------

/// The states just before and just after the plant's first event.
fn first_event(plant: &mut Plant, t_end: f64) -> ([f64; NY], [f64; NY]) {
    let mut before: Option<[f64; NY]> = None;
    let mut after: Option<[f64; NY]> = None;
    plant
        .advance_to(t_end, &mut |out| match out {
            Output::Before(at) if before.is_none() => before = Some(*at.y),
            Output::After(at) if after.is_none() => after = Some(*at.y),
            _ => {}
        })
        .unwrap();
    (
        before.expect("an event before t_end"),
        after.expect("an event before t_end"),
    )
}

/// Reference: the platform lands flat (angle 0, no rotation) with a vertical velocity
/// on two feet at once, eccentrics hanging straight down. At the feet's normal
/// velocities, equal and approaching, the impact drives both to `e |v|` together with
/// no rotation: the only velocity change is a vertical translation of the whole
/// machine, which the eccentric masses follow through their vertical arms, so the
/// rotors take no angular impulse (`Delta v_axis` is parallel to `eps`) and the
/// machine acts as ONE rigid body of
///
/// ```text
///   M   = m_p + m_1 + m_2
///   G   = (m_p C + m_1 P_1 + m_2 P_2) / M                (P_k = A_k + eps_k)
///   I_G = J_p + m_p |C - G|^2 + sum_k (m_k |P_k - G|^2 + I_k)
/// ```
///
/// (the rotors' own inertias as if locked; `I_G` does not change the answer when
/// nothing rotates, mass and centre of mass do). `solve_body` for that body with the
/// same feet, normal, restitution, friction and law is the reference for the feet's
/// impulses and the velocities after. The feet are not symmetric about `G`, so the
/// impulses differ (lever rule about `G`).
///
/// Tolerance 1e-9 relative: both sides solve the same impact by the same
/// Darboux-Keller path (the `shared` solver), with Delassus matrices assembled
/// differently; rounding only.
#[test]
fn flat_landing_matches_the_single_body_solver_for_the_combined_body() {
    let mut rig = Rig::reference();
    rig.feet[1].local = [0.11, -0.03];
    rig.rotors[1].axis = [0.05, 0.01];
    rig.rotors[1].mass = 0.03;
    rig.rotors[1].eccentricity = 0.015;
    for f in &mut rig.feet {
        f.restitution = 0.6;
    }
    for r in &mut rig.rotors {
        r.angle = -PI / 2.0;
    }
    rig.position = [0.01, 0.03 + 1e-3];
    rig.velocity = [0.0, -1.0];
    for law in ["poisson", "newton", "stronge"] {
        rig.law = law;
        let mut plant = rig.plant(Settings::default(), Holds::default(), |_| {});
        let (before, after) = first_event(&mut plant, 0.1);
        let instants = impact_instants(&plant.events);
        let rows = &instants[0];
        assert_eq!(rows.len(), 2, "{law}: both feet strike: {rows:#?}");

        // The combined rigid body, from the state before the impact.
        let kin = kinematics(&rig, &before);
        let total = rig.total_mass();
        let masses = [rig.platform_mass, rig.rotors[0].mass, rig.rotors[1].mass];
        let points = [kin.c, kin.p[0], kin.p[1]];
        let mut g = [0.0; 2];
        for (m, p) in masses.iter().zip(&points) {
            g[0] += m * p[0] / total;
            g[1] += m * p[1] / total;
        }
        let sq = |a: [f64; 2]| a[0] * a[0] + a[1] * a[1];
        let mut inertia = rig.platform_inertia;
        for (m, p) in masses.iter().zip(&points) {
            inertia += m * sq(sub(*p, g));
        }
        inertia += rig.rotors[0].inertia + rig.rotors[1].inertia;
        let p = momentum(&rig, &before);
        let body = PlanarBody {
            mass: total,
            inertia,
            position: g,
            velocity: [p[0] / total, p[1] / total],
            angular_velocity: before[7],
        };
        let contacts: Vec<BodyContact<f64>> = (0..2)
            .map(|j| BodyContact {
                point: foot(&rig, &before, j),
                normal: [0.0, 1.0],
                law: ContactLaw {
                    restitution: rig.feet[j].restitution,
                    friction: rig.feet[j].friction,
                    weight: 1.0,
                },
            })
            .collect();
        let law_enum = ImpactLaw::from_name(law).unwrap();
        let reference = solve_body::<f64, 8>(&body, None, &contacts, law_enum)
            .unwrap_or_else(|e| panic!("solve_body: {e:?}"));

        let scale = total * before[6].abs();
        for (j, row) in rows.iter().enumerate() {
            assert_eq!(row.contact, format!("K{}", j + 1));
            let c = &reference.outcome.contacts[j];
            check(
                &format!("{law}: K{} normal impulse", j + 1),
                row.normal_impulse,
                c.normal_impulse,
                1e-9 * scale,
            );
            check(
                &format!("{law}: K{} tangential impulse", j + 1),
                row.tangential_impulse,
                c.tangential_impulse,
                1e-9 * scale,
            );
        }
        assert!(
            (rows[0].normal_impulse - rows[1].normal_impulse).abs() > 1e-3 * scale,
            "the lever rule should split the impulse unequally"
        );
        // Velocities after: the platform's centre C moves with the rigid body.
        let w1 = reference.angular_velocity_after;
        let v_c = add(reference.velocity_after, spin(w1, sub(kin.c, g)));
        let vs = 1e-9 * before[6].abs();
        check(&format!("{law}: x' after"), after[5], v_c[0], vs);
        check(&format!("{law}: y' after"), after[6], v_c[1], vs);
        check(&format!("{law}: theta' after"), after[7], w1, vs / 0.1);
        // The rotors took no impulse.
        check(
            &format!("{law}: phi1' after"),
            after[8],
            before[8],
            vs / 0.1,
        );
        check(
            &format!("{law}: phi2' after"),
            after[9],
            before[9],
            vs / 0.1,
        );
    }
}

/// Reference: a tilted landing on ONE foot K with the rotors free (open windings):
/// the only impulse acts at K (gravity and the motors are not impulsive; the motors'
/// reaction torques are internal anyway), so the whole system's angular momentum
/// about K is the same just before and just after the impact,
///
/// ```text
///   H_K = m_p (C - K) x v_C + J_p theta'
///       + sum_k [m_k (P_k - K) x v_P_k + I_k (theta' + phi_k')]
/// ```
///
/// computed here from the state ([`angular_momentum`]); and its linear momentum
/// changes by the impulse `P_n n + P_t t` the plant reports (`n = (0, 1)`,
/// `t = (-1, 0)`). For every law, with friction (the foot slides in).
///
/// Tolerance 1e-10 of the sum of the terms' magnitudes (rounding).
#[test]
fn tilted_landing_keeps_angular_momentum_about_the_contact() {
    let mut rig = Rig::reference();
    rig.angle = 0.3;
    rig.velocity = [0.3, -0.8];
    rig.angular_velocity = 1.5;
    rig.rotors[0].angle = 0.4;
    rig.rotors[1].angle = 2.0;
    for f in &mut rig.feet {
        f.restitution = 0.5;
        f.friction = 0.4;
    }
    let low = rot(rig.angle, rig.feet[0].local)[1];
    rig.position = [0.0, 2e-3 - low];
    for law in ["poisson", "newton", "stronge"] {
        rig.law = law;
        let mut plant = rig.plant(Settings::default(), Holds::default(), |y| {
            y[8] = 80.0;
            y[9] = -50.0;
        });
        let (before, after) = first_event(&mut plant, 0.1);
        let instants = impact_instants(&plant.events);
        let rows = &instants[0];
        assert_eq!(rows.len(), 1, "{law}: one foot strikes: {rows:#?}");
        assert_eq!(rows[0].contact, "K1");
        assert!(
            rows[0].tangential_impulse.abs() > 1e-3 * rows[0].normal_impulse,
            "{law}: friction should act"
        );
        assert_eq!(before[..5], after[..5], "{law}: an impact moves nothing");

        let k = foot(&rig, &before, 0);
        let (h0, s0) = angular_momentum(&rig, &before, k);
        let (h1, s1) = angular_momentum(&rig, &after, k);
        check(
            &format!("{law}: angular momentum about K1"),
            h1,
            h0,
            1e-10 * s0.max(s1),
        );
        // Linear momentum: p+ - p- = P_n n + P_t t.
        let (p0, p1) = (momentum(&rig, &before), momentum(&rig, &after));
        let impulse = [-rows[0].tangential_impulse, rows[0].normal_impulse];
        let scale = rig.total_mass() * norm(p0) / rig.total_mass() + norm(impulse);
        for i in 0..2 {
            check(
                &format!("{law}: momentum change {i}"),
                p1[i] - p0[i],
                impulse[i],
                1e-10 * scale,
            );
        }
        // The rotors did take impulse (the check is not trivial).
        assert!(
            (after[8] - before[8]).abs() > 1e-3,
            "{law}: rotor 1 unchanged"
        );
    }
}

// ---------------------------------------------------------------------------------
// 7: the sliding threshold
// ---------------------------------------------------------------------------------

/// What a run at rotor speed `w` shows: whether a foot slipped (a Slip event), and
/// the largest `|x - x0|`.
struct SlideRun {
    slip_event: bool,
    max_dx: f64,
}

/// The reference machine at rest on both feet (friction `mu`), rotors held at
/// `phi1' = w`, `phi2' = -w` with phase offset `2 b`; the amplitude's positive peak
/// (`phi1 - phi2 = 0 mod 2 pi`) first comes a quarter revolution in, and the run
/// lasts three revolutions (three peaks).
fn slide_run(mu: f64, b: f64, w: f64) -> SlideRun {
    let mut rig = Rig::reference();
    for f in &mut rig.feet {
        f.friction = mu;
    }
    // (phi1 - phi2) / 2 = -pi/2 + w t: the peak at t = T / 4.
    rig.rotors[0].angle = b - PI / 2.0;
    rig.rotors[1].angle = b + PI / 2.0;
    let holds = Holds {
        platform: false,
        rotors: true,
        ..Holds::default()
    };
    let mut plant = rig.plant(Settings::default(), holds, |y| {
        y[8] = w;
        y[9] = -w;
    });
    let x0 = plant.y[0];
    let mut max_dx = 0.0f64;
    let period = 2.0 * PI / w;
    let mut record = |out: Output<'_>| {
        let y = match out {
            Output::Dense(step, upto) => step.at(upto),
            Output::Before(at) | Output::After(at) => *at.y,
        };
        max_dx = max_dx.max((y[0] - x0).abs());
    };
    plant.advance_to(3.0 * period, &mut record).unwrap();
    SlideRun {
        slip_event: plant.events.iter().any(|e| e.kind == EventKind::Slip),
        max_dx,
    }
}

/// Reference: the platform rests on both feet (same height, `n = (0, 1)`), the rotors
/// turn at constant `+-w` with phase offset `d = 2 b`. While it rests, the whole
/// machine's momentum balance (only the eccentric masses accelerate, `-w^2 eps_k`)
/// gives the feet's total forces from the exciting force
/// `F = F0 cos psi(t) (cos b, sin b)`, `F0 = 2 m e w^2`, `psi = (phi1 - phi2) / 2`
/// (see the exciting-force test):
///
/// ```text
///   T = -F0 cos psi cos b              (total tangential, along x)
///   N = M g - F0 cos psi sin b         (total normal)
/// ```
///
/// A rigid platform's feet share one tangential velocity, so it slides when the
/// total friction needed exceeds the total available, `|T| > mu N` (Coulomb at each
/// foot, `|T_j| <= mu N_j`, allows any split with `sum |T_j| <= mu sum N_j`). The
/// largest margin is at `cos psi = 1` (for `b >= 0`): sliding starts at
///
/// ```text
///   F0 (cos b + mu sin b) = mu M g,   w* = sqrt(mu M g / ((cos b + mu sin b) 2 m e))
/// ```
///
/// provided the platform neither lifts (`F0 sin b < M g`) nor tips (both feet keep
/// `N_j > 0`; from the angular momentum about the floor point O below the centre,
/// `x_1 N_1 + x_2 N_2 = g (m_p x_C + sum m_k x_Pk) - w^2 sum m_k A_k x eps_k`, with
/// `N_1 + N_2 = N`; checked over a revolution at the bracket's upper end).
///
/// The plant's threshold is found by bisection on `w`: a run of three revolutions
/// (three force peaks) slides if any Slip event occurs or `x` moves by more than
/// 1e-9 m. Resolution: the bracket is narrowed to 1e-4 of `w*`. Detection margin
/// above `w*`: at `w = w* (1 + delta)` the friction limit is exceeded for
/// `|psi| < 2 sqrt(delta)` around each peak, and the platform slides by about
/// `(32/3) mu g delta^2 / w^2` (the excess `mu g (2 delta - psi^2 / 2)` integrated
/// twice), 2e-9 m at `delta = 1e-3`: above the 1e-9 m criterion even if no Slip event
/// were reported. So the plant must slide at `w* (1 + 1e-3)` and must not below `w*`
/// (1e-6 for event location and rounding).
#[test]
fn sliding_starts_where_the_exciting_force_beats_friction() {
    let rig = Rig::reference();
    let (m, e) = (rig.rotors[0].mass, rig.rotors[0].eccentricity);
    let total = rig.total_mass();
    // Every case runs before any is judged, so a failure shows them all.
    let mut failures = Vec::new();
    for (mu, b_deg) in [(0.4, 0.0), (0.4, 10.0), (0.2, 20.0)] {
        let b = f64::to_radians(b_deg);
        let f_star = mu * total * G / (b.cos() + mu * b.sin());
        let w_star = (f_star / (2.0 * m * e)).sqrt();
        let ctx = format!("mu {mu}, b {b_deg} deg");

        // Bracket [0.9, 1.2] w*; the preconditions hold at its upper end.
        let (mut lo, mut hi) = (0.9 * w_star, 1.2 * w_star);
        let f_hi = 2.0 * m * e * hi * hi;
        assert!(f_hi * b.sin() < total * G, "{ctx}: it would lift");
        for n in 0..360 {
            let psi = 2.0 * PI * n as f64 / 360.0;
            let (phi1, phi2) = (b + psi, b - psi);
            let feet = normal_forces(&rig, hi, [phi1, phi2]);
            assert!(
                feet[0] > 0.0 && feet[1] > 0.0,
                "{ctx}: it would tip at psi = {psi}: {feet:?}"
            );
        }
        let slides = |w: f64| {
            let r = slide_run(mu, b, w);
            r.slip_event || r.max_dx > 1e-9
        };
        assert!(!slides(lo), "{ctx}: slides at 0.9 w*");
        assert!(slides(hi), "{ctx}: does not slide at 1.2 w*");
        while hi - lo > 1e-4 * w_star {
            let mid = 0.5 * (lo + hi);
            if slides(mid) {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        eprintln!(
            "{ctx}: w* = {w_star:.6} rad/s; the plant slides from w in [{lo:.6}, {hi:.6}] = \
             [{:.6}, {:.6}] w*",
            lo / w_star,
            hi / w_star
        );
        if hi < w_star * (1.0 - 1e-6) {
            failures.push(format!(
                "{ctx}: slides at {hi} rad/s, below w* = {w_star} rad/s"
            ));
        }
        if lo > w_star * (1.0 + 1e-3) {
            failures.push(format!(
                "{ctx}: still sticks at {lo} rad/s = {:.6} w* (w* = {w_star} rad/s): \
                 F0 (cos b + mu sin b) = {:.4} N > mu M g = {:.4} N",
                lo / w_star,
                2.0 * m * e * lo * lo * (b.cos() + mu * b.sin()),
                mu * total * G
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The feet's normal forces `(N_1, N_2)` of the resting platform (reference geometry,
/// centre of mass above the floor point O = (0, 0), feet at `x_j`, y = 0) with the
/// rotors at `+-w` and eccentric angles `phi`, from the momentum and the angular
/// momentum about O of the whole machine:
///
/// ```text
///   N_1 + N_2         = M g - w^2 sum_k m_k eps_k,y
///   x_1 N_1 + x_2 N_2 = g (m_p x_C + sum_k m_k x_Pk) - w^2 sum_k m_k A_k x eps_k
/// ```
///
/// (friction acts at the floor's height, no moment about O; the rotors' own spin is
/// constant).
fn normal_forces(rig: &Rig, w: f64, phi: [f64; 2]) -> [f64; 2] {
    let c = rig.position;
    let mut sum = rig.total_mass() * G;
    let mut moment = G * rig.platform_mass * c[0];
    for (r, phi) in rig.rotors.iter().zip(phi) {
        let axis = add(c, r.axis);
        let eps = [r.eccentricity * phi.cos(), r.eccentricity * phi.sin()];
        sum -= w * w * r.mass * eps[1];
        moment += G * r.mass * (axis[0] + eps[0]) - w * w * r.mass * cross(axis, eps);
    }
    let (x1, x2) = (c[0] + rig.feet[0].local[0], c[0] + rig.feet[1].local[0]);
    // Solve [1 1; x1 x2] N = (sum, moment).
    let n2 = (moment - x1 * sum) / (x2 - x1);
    [sum - n2, n2]
}

/// Reference: Coulomb's law at every closed foot, `|lambda_t| <= mu lambda_n`, whatever
/// the split of an indeterminate tangential force. The resting platform of the
/// sliding test at `b = 0`, `w = 0.98 w*` (below the threshold, so it must keep
/// sticking) and at `1.03 w*` (above it): at every sample of one revolution, every
/// closed contact's force is in its cone (1e-9 relative), and the plant reports
/// these forces while it keeps the feet sticking.
#[test]
fn sticking_contact_forces_stay_in_the_friction_cone() {
    let rig = Rig::reference();
    let (m, e) = (rig.rotors[0].mass, rig.rotors[0].eccentricity);
    let mu = 0.4;
    let w_star = (mu * rig.total_mass() * G / (2.0 * m * e)).sqrt();
    for f in [0.98, 1.03] {
        let w = f * w_star;
        let mut r = rig.clone();
        for foot in &mut r.feet {
            foot.friction = mu;
        }
        r.rotors[0].angle = -PI / 2.0;
        r.rotors[1].angle = PI / 2.0;
        let holds = Holds {
            platform: false,
            rotors: true,
            ..Holds::default()
        };
        let mut plant = r.plant(Settings::default(), holds, |y| {
            y[8] = w;
            y[9] = -w;
        });
        let period = 2.0 * PI / w;
        for n in 1..=400 {
            let t = period * n as f64 / 400.0;
            plant.advance_to(t, &mut |_| {}).unwrap();
            let forces = plant.contact_forces();
            for (j, mode) in plant.modes.iter().enumerate() {
                if *mode == ContactMode::Open {
                    continue;
                }
                let [ln, lt] = forces[j];
                assert!(
                    lt.abs() <= mu * ln * (1.0 + 1e-9),
                    "w = {f} w*, t = {t:.6}: K{} in mode {mode:?} has |lambda_t| = {:.6} N > \
                     mu lambda_n = {:.6} N (forces {forces:?}, modes {:?})",
                    j + 1,
                    lt.abs(),
                    mu * ln,
                    plant.modes
                );
            }
        }
    }
}

// ---------------------------------------------------------------------------------
// Determinism
// ---------------------------------------------------------------------------------

/// Two runs of the same machine from the same state give the same bits: final state,
/// time, step count and every event (docs/plant-model.md, "Determinism"). The run
/// exercises everything at once: a tilted drop with friction, both motors driven,
/// rocking, impacts, sticking and slipping.
#[test]
fn two_identical_runs_are_bit_identical() {
    let run = || {
        let rig = rocking_rig(0.3, 0.4);
        let mut plant = rig.plant(Settings::default(), Holds::default(), |_| {});
        plant.set_winding([Winding::Voltage(10.0), Winding::Voltage(9.0)]);
        let mut trace: Vec<u64> = Vec::new();
        plant
            .advance_to(0.5, &mut |out| {
                let (t, y) = match out {
                    Output::Dense(step, upto) => (upto, step.at(upto)),
                    Output::Before(at) | Output::After(at) => (at.t, *at.y),
                };
                trace.push(t.to_bits());
                trace.extend(y.iter().map(|v| v.to_bits()));
            })
            .unwrap();
        (plant, trace)
    };
    let (a, trace_a) = run();
    let (b, trace_b) = run();
    assert!(a.impacts > 5, "only {} impacts", a.impacts);
    assert_eq!(a.t.to_bits(), b.t.to_bits());
    assert_eq!(a.steps, b.steps);
    let bits = |p: &Plant| p.y.map(f64::to_bits);
    assert_eq!(bits(&a), bits(&b), "final states differ");
    assert_eq!(a.events, b.events);
    assert_eq!(a.modes, b.modes);
    assert_eq!(trace_a, trace_b, "recorded outputs differ");
}
