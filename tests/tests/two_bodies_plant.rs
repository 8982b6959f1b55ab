//! Two free planar bodies meeting at a point-on-face contact, simulated by the
//! plant from a machine file (the event located, the impact solved on the plant's
//! own Delassus matrix, the velocities jumped, the flight integrated), against the
//! closed forms of Poisson's law that `multibody_impact.rs` checks the solver alone
//! against ([`tests::two_bodies`], the same impacts):
//!
//! - a central impact, the normal through both centres of mass (the textbook
//!   `v_A' = v_A - (1 + e) m_B / (m_A + m_B) (v_A - v_B)` and its mirror);
//! - an off-centre impact, the line of impact missing both centres: the effective
//!   mass `1 / W_nn`, the impulse `P = (1 + e) (-u_n) / W_nn`, each body's velocity
//!   and spin from it (Stronge, *Impact Mechanics*, 2000, ch. 4);
//! - an impact with friction whose slip never stops (the paper's case 1).
//!
//! The machine: no gravity, the platform is body A and one `[[bodies]]` entry
//! body B, free (no joints), and one contact, B's point on A's face; no contact
//! against the fundament. Each case gives the bodies at the instant they meet;
//! the machine starts them [`T_HIT`] earlier, moved back along their free flight
//! (velocities constant, angles `-omega T_HIT` at t = 0 and 0 at the impact), so the
//! plant must find the impact at `T_HIT`, in the configuration of the closed form.
//!
//! What the plant must give: one impact, at `T_HIT`; just after it both bodies'
//! `v_x`, `v_y`, `omega` of the closed form, kept to the end of the run; linear and
//! angular momentum kept through it; the kinetic energy lost the closed form's.
//!
//! The one rotor is on the platform and must not disturb: no eccentric mass, its
//! winding open (the plant starts with open windings and nothing drives the
//! bridges), its motor without friction, so nothing acts between the rotor and the
//! platform. Its inertia `I_k` turns at `theta_A' + phi'` (`dynamics.rs`), so the
//! mass matrix couples it to the platform's angle: on `(theta_A, phi)` the block is
//! `[[J_A + I_k, I_k], [I_k, I_k]]`, whose inverse has `I_k / (J_A I_k) = 1 / J_A` on
//! `theta_A`. An impulse on the platform therefore turns it as if the rotor were
//! not there (the rotor keeps its own speed `theta_A' + phi'`, which the test
//! checks); a rotor held to the platform would add `I_k` to `J_A`. `I_k` is taken
//! large here (5e-3 kg m^2, a sixth to a half of the platforms' `J_A`) so that any
//! leak of it into the impact would show (held, it moves the off-centre impulse by
//! 3 %).

use tests::initial_state;
use tests::machine::{TestMachine, DRIVE_12V, FRICTIONLESS_MOTOR};

use host_sim::machine::Machine;
use host_sim::plant::model::PlantModel;
use host_sim::plant::model::NY;
use host_sim::plant::simulator::{Holds, Output, Plant, Settings};
use shared::vec2::{add, norm, sub};
use tests::rig::{check, rot};
use tests::two_bodies::{
    central_after, central_loss, central_pair, off_centre_pair, poisson_closed_form, slipping_pair,
    Body, Contact, Pair, CENTRAL_CASES,
};

/// Time from the start to the impact, s: the bodies start 3 to 22 mm apart
/// (closing at 0.3 to 2.2 m/s) and turn by at most 0.02 rad on the way.
const T_HIT: f64 = 0.01;

/// The rotor's inertia, kg m^2 (see the module's doc).
const ROTOR_INERTIA: f64 = 5e-3;

/// Relative tolerance of the velocities, impulses, momenta and energies. The
/// plant's event lies within its time tolerance (1e-12 s) of the crossing: the
/// bodies then stand up to `|v| 1e-12 s` = 3e-12 m from the closed form's
/// configuration, which moves the lever arms (0.1 m and more) by 3e-11 of
/// themselves and the impulse by as much; the rest is rounding (1e-16 per
/// operation). 1e-9 leaves a margin of 30 over that.
const REL: f64 = 1e-9;

/// `[x, y]` in TOML.
fn vector(v: [f64; 2]) -> String {
    format!("[{:?}, {:?}]", v[0], v[1])
}

/// The machine of `pair` meeting at `contact` at `T_HIT`: each body's centre
/// `C - v T_HIT`, its angle `-omega T_HIT`; B's point, A's face and its normal where
/// those angles put them (`R(-omega T_HIT) (P - C)` from the centre).
fn machine(pair: &Pair, contact: &Contact) -> Machine {
    let start = |x: &Body| {
        let c = [
            x.centre[0] - x.velocity[0] * T_HIT,
            x.centre[1] - x.velocity[1] * T_HIT,
        ];
        (c, -x.omega * T_HIT)
    };
    let rigid = |x: &Body| {
        let (c, angle) = start(x);
        format!(
            "mass = {:?}\ninertia = {:?}\nposition = {}\nangle = {angle:?}\n\
             velocity = {}\nangular_velocity = {:?}\n",
            x.mass,
            x.inertia,
            vector(c),
            vector(x.velocity),
            x.omega
        )
    };
    let (a, b) = (&pair.a, &pair.b);
    let (ca, angle_a) = start(a);
    let (cb, angle_b) = start(b);
    let p = contact.point;
    let point = add(cb, rot(angle_b, sub(p, b.centre)));
    let face = add(ca, rot(angle_a, sub(p, a.centre)));
    let normal = rot(angle_a, contact.normal);
    let text = format!(
        r#"[fundament]
gravity = [0.0, 0.0]

[platform]
{}
[[bodies]]
name = "B"
{}
[[contacts]]
name = "hit"
body = "B"
against = "platform"
point = {}
face = {}
normal = {}
restitution = {:?}
friction = {:?}

[[rotors]]
axis = {}
eccentric_mass = 0.0
eccentricity = 0.0
inertia = {ROTOR_INERTIA:?}
sense = "ccw"

"#,
        rigid(a),
        rigid(b),
        vector(point),
        vector(face),
        vector(normal),
        contact.law.restitution,
        contact.law.friction,
        vector(ca),
    );
    TestMachine::new("two-bodies.toml")
        .with(&text)
        .with(FRICTIONLESS_MOTOR)
        .with(DRIVE_12V)
        .machine()
}

/// The bodies at a state of the plant, and the rotor's own speed
/// `theta_A' + phi'`, rad/s.
#[derive(Clone, Copy, Debug)]
struct Seen {
    t: f64,
    pair: Pair,
    rotor: f64,
}

/// What the plant did in `2 T_HIT` from the machine of `pair` and `contact`.
struct Run {
    /// Just before and just after each event.
    before: Vec<Seen>,
    after: Vec<Seen>,
    /// At the end.
    end: Seen,
    /// The impact instants the plant counted.
    impacts: usize,
    /// Its impact rows: time, contact, `u_n` before and after, `P_n`, `P_t`.
    rows: Vec<(f64, String, [f64; 4])>,
    warnings: Vec<String>,
}

fn run(pair: &Pair, contact: &Contact) -> Run {
    let m = machine(pair, contact);
    let model = PlantModel::new(&m);
    assert_eq!(model.bodies.len(), 2);
    let probe = model.clone();
    let n = probe.dof;
    let (theta, phi) = (probe.bodies[0].angle, probe.rotors[0].phi);
    let seen = |t: f64, y: &[f64; NY]| {
        let motion = |b: usize, x: &Body| {
            let [cx, cy, _, vx, vy, omega] = probe.body_motion(b, y);
            Body {
                centre: [cx, cy],
                velocity: [vx, vy],
                omega,
                ..*x
            }
        };
        Seen {
            t,
            pair: Pair {
                a: motion(0, &pair.a),
                b: motion(1, &pair.b),
            },
            rotor: y[n + theta] + y[n + phi],
        }
    };
    let mut plant = Plant::new(
        model,
        initial_state(&m),
        Settings::default(),
        Holds::default(),
    );
    let (mut before, mut after) = (Vec::new(), Vec::new());
    plant
        .advance_to(2.0 * T_HIT, &mut |out| match out {
            Output::Before(at) => before.push(seen(at.t, at.y)),
            Output::After(at) => after.push(seen(at.t, at.y)),
            Output::Dense(..) => {}
        })
        .unwrap();
    Run {
        before,
        after,
        end: seen(plant.t, &plant.y),
        impacts: plant.impacts,
        rows: plant
            .events
            .iter()
            .filter(|e| e.kind.name() == "impact")
            .map(|e| {
                (
                    e.t,
                    e.contact.clone(),
                    [
                        e.normal_velocity_before,
                        e.normal_velocity_after,
                        e.normal_impulse,
                        e.tangential_impulse,
                    ],
                )
            })
            .collect(),
        warnings: plant.warnings.clone(),
    }
}

/// What the closed form says of one impact.
struct Expected {
    /// Both bodies just after.
    after: Pair,
    /// The normal relative velocity before, m/s (after: `-e` times it).
    u_n: f64,
    /// The impulses on B along `n` and `t`, N s.
    impulse: [f64; 2],
    /// The kinetic energy the impact takes, J.
    loss: f64,
}

/// The worst error of each quantity, relative to its tolerance's scale.
#[derive(Debug, Default)]
struct Errors {
    velocity: f64,
    omega: f64,
    momentum: f64,
    angular_momentum: f64,
    energy: f64,
}

/// Checks the plant's run of `pair` meeting at `contact` against `expected`;
/// returns the errors (m/s, rad/s, N s, N m s, J).
fn check_run(case: &str, pair: &Pair, contact: &Contact, expected: &Expected) -> Errors {
    let run = run(pair, contact);
    let e = contact.law.restitution;
    assert!(run.warnings.is_empty(), "{case}: {:?}", run.warnings);

    // Scales: the largest speed V (m/s) before or after, the shortest lever arm L
    // (m) from a centre to the contact; an angular velocity's error is a
    // velocity's over L.
    let (a, b) = (&pair.a, &pair.b);
    let speeds = [a, b, &expected.after.a, &expected.after.b]
        .iter()
        .flat_map(|x| [x.velocity[0].abs(), x.velocity[1].abs()])
        .fold(expected.u_n.abs(), f64::max);
    let lever = norm(sub(contact.point, a.centre)).min(norm(sub(contact.point, b.centre)));
    let (tol_v, tol_w) = (REL * speeds, REL * speeds / lever);
    let masses = a.mass + b.mass;
    let inertias = a.inertia + b.inertia;

    // One event, the impact, at T_HIT: located to 1e-12 s, far below 1e-10 s.
    assert_eq!(run.after.len(), 1, "{case}: events at {:?}", run.after);
    assert_eq!(run.impacts, 1, "{case}: impacts");
    assert_eq!(run.rows.len(), 1, "{case}: impact rows {:?}", run.rows);
    let (before, after) = (run.before[0], run.after[0]);
    let (t_row, name, [u_before, u_after, p_n, p_t]) = &run.rows[0];
    assert_eq!(name, "hit");
    assert_eq!(*t_row, after.t);
    check(&format!("{case}: impact time"), after.t, T_HIT, 1e-10);

    // Before: the bodies as the case gives them (free flight keeps the velocities
    // exactly; the positions to the event time's tolerance).
    for (got, want) in [(&before.pair.a, a), (&before.pair.b, b)] {
        for k in 0..2 {
            check(
                &format!("{case}: C before"),
                got.centre[k],
                want.centre[k],
                1e-10,
            );
            check(
                &format!("{case}: v before"),
                got.velocity[k],
                want.velocity[k],
                tol_v,
            );
        }
        check(
            &format!("{case}: omega before"),
            got.omega,
            want.omega,
            tol_w,
        );
    }

    // The impact row: u_n' = -e u_n (Poisson's law for a contact that separates),
    // the impulses.
    check(&format!("{case}: u_n"), *u_before, expected.u_n, tol_v);
    check(&format!("{case}: u_n'"), *u_after, -e * expected.u_n, tol_v);
    let tol_p = REL * speeds * masses;
    check(&format!("{case}: P_n"), *p_n, expected.impulse[0], tol_p);
    check(&format!("{case}: P_t"), *p_t, expected.impulse[1], tol_p);

    // After, and at the end of the run (free flight: the same).
    let mut errors = Errors::default();
    for (when, seen) in [("after", after), ("at the end", run.end)] {
        let pairs = [
            ("A", &seen.pair.a, &expected.after.a),
            ("B", &seen.pair.b, &expected.after.b),
        ];
        for (body, got, want) in pairs {
            for (k, axis) in ["v_x", "v_y"].iter().enumerate() {
                let what = format!("{case}: {axis} of {body} {when}");
                check(&what, got.velocity[k], want.velocity[k], tol_v);
                errors.velocity = errors
                    .velocity
                    .max((got.velocity[k] - want.velocity[k]).abs());
            }
            let what = format!("{case}: omega of {body} {when}");
            check(&what, got.omega, want.omega, tol_w);
            errors.omega = errors.omega.max((got.omega - want.omega).abs());
        }
    }
    check(
        &format!("{case}: rotor's speed"),
        after.rotor,
        before.rotor,
        tol_w,
    );

    // Momentum: no external impulse, so sum m v and sum (J omega + C x m v) (about
    // the origin; the rotor's I_k (theta' + phi') is unchanged, above) are kept.
    let (p0, p1) = (before.pair.momentum(), after.pair.momentum());
    for k in 0..2 {
        check(&format!("{case}: momentum"), p1[k], p0[k], tol_p);
        errors.momentum = errors.momentum.max((p1[k] - p0[k]).abs());
    }
    let arm = norm(a.centre).max(norm(b.centre));
    let tol_l = REL * speeds * (masses * arm + inertias / lever);
    let (l0, l1) = (
        before.pair.angular_momentum(),
        after.pair.angular_momentum(),
    );
    check(&format!("{case}: angular momentum"), l1, l0, tol_l);
    errors.angular_momentum = (l1 - l0).abs();

    // Energy: the loss of the closed form, to the scale m V^2 + J (V / L)^2.
    let lost = before.pair.energy() - after.pair.energy();
    let tol_e = REL * speeds * speeds * (masses + inertias / (lever * lever));
    check(&format!("{case}: energy lost"), lost, expected.loss, tol_e);
    errors.energy = (lost - expected.loss).abs();
    eprintln!("{case}: errors {errors:?}; tolerances v {tol_v:.1e} m/s, omega {tol_w:.1e} rad/s, p {tol_p:.1e} N s, L {tol_l:.1e} N m s, E {tol_e:.1e} J");
    errors
}

#[test]
fn a_central_impact_through_the_plant_follows_the_textbook_formula() {
    for (ma, mb, e, va, vb) in CENTRAL_CASES {
        let (pair, contact) = central_pair(ma, mb, e, va, vb);
        let case = format!("m_A {ma}, m_B {mb}, e {e}, v_A {va}, v_B {vb}");
        // Along the line of centres (x), the textbook velocities; no spin, no v_y.
        // The impulse on B: m_B (v_B' - v_B), N s.
        let [va_after, vb_after] = central_after(ma, mb, e, va, vb);
        let mut after = pair;
        after.a.velocity[0] = va_after;
        after.b.velocity[0] = vb_after;
        let expected = Expected {
            after,
            u_n: vb - va,
            impulse: [mb * (vb_after - vb), 0.0],
            loss: central_loss(ma, mb, e, va, vb),
        };
        check_run(&case, &pair, &contact, &expected);
    }
}

#[test]
fn an_off_centre_impact_through_the_plant_spins_both_bodies_as_the_effective_mass_says() {
    let (pair, contact) = off_centre_pair();
    let closed = poisson_closed_form(&pair, &contact);
    assert!(closed.u_n < 0.0, "the bodies approach: {}", closed.u_n);
    let e = contact.law.restitution;
    // Frictionless: the energy taken is (1 - e^2) times the compression's, the
    // kinetic energy of the relative normal motion at the effective mass,
    // `m_eff u_n^2 / 2` with `m_eff = 1 / W_nn` (Stronge 2000, ch. 4), J.
    let loss = (1.0 - e * e) * closed.u_n * closed.u_n / (2.0 * closed.w_nn);
    let expected = Expected {
        after: closed.after,
        u_n: closed.u_n,
        impulse: [closed.normal_impulse, 0.0],
        loss,
    };
    check_run("off centre", &pair, &contact, &expected);
}

#[test]
fn friction_with_slip_throughout_through_the_plant_matches_the_closed_form() {
    let (pair, contact) = slipping_pair();
    let closed = poisson_closed_form(&pair, &contact);
    // The closed form holds while the slip keeps its sign to the end.
    assert!(
        closed.u_t_after * closed.u_t > 0.0,
        "slip continues: {} -> {}",
        closed.u_t,
        closed.u_t_after
    );
    // The energy taken: the closed form's bodies before and after (friction
    // takes some besides the normal impulse), J.
    let expected = Expected {
        after: closed.after,
        u_n: closed.u_n,
        impulse: [closed.normal_impulse, closed.tangential_impulse],
        loss: pair.energy() - closed.after.energy(),
    };
    check_run("slip throughout", &pair, &contact, &expected);
}
