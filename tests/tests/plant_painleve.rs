//! A Painleve configuration reached with high friction on one foot: the platform
//! slides on foot K1 (the other foot in the air) with friction 2. No contact
//! force is consistent with Coulomb's law there; the plant must report a
//! `painleve` event, resolve it by a tangential impact, and go on without
//! sinking into the fundament or gaining energy.

use host_sim::event::EventKind;
use host_sim::machine::Machine;
use tests::machine::TestMachine;
use tests::unpowered_plant;

const G: f64 = 9.81;
const MASS: f64 = 2.0;
const INERTIA: f64 = 7.3e-3;
const MU: f64 = 2.0;
/// Foot K1 relative to the platform's centre of mass, m.
const R1: [f64; 2] = [-0.1, -0.1];
/// Sliding velocity of the platform (to the left), m/s.
const VX: f64 = -0.5;

fn machine() -> Machine {
    // The minimal machine with the Painleve geometry: a tall platform sliding left,
    // foot K1 with high friction, rotors without eccentrics, motors without friction.
    let sets: Vec<String> = [
        format!("platform.mass={MASS}"),
        format!("platform.inertia={INERTIA}"),
        "platform.position=[0.0, 0.1]".to_string(),
        format!("platform.velocity=[{VX}, 0.0]"),
        format!("contacts.K1.point=[{}, {}]", R1[0], 0.1 + R1[1]),
        format!("contacts.K1.friction={MU}"),
        "contacts.K2.point=[0.1, 0.05]".to_string(),
        "rotors.left.axis=[-0.03, 0.13]".to_string(),
        "rotors.right.axis=[0.03, 0.13]".to_string(),
        "rotors.left.eccentric_mass=0.0".to_string(),
        "rotors.right.eccentric_mass=0.0".to_string(),
        "rotors.left.eccentricity=0.0".to_string(),
        "rotors.right.eccentricity=0.0".to_string(),
        "motor.coulomb_friction=0.0".to_string(),
        "motor.viscous_friction=0.0".to_string(),
    ]
    .to_vec();
    TestMachine::file("tests/fixtures/minimal-machine.toml")
        .sets(&sets)
        .machine()
}

/// The premise, by hand: foot K1 at `r = (-0.1, -0.1)` from C, fundament normal
/// `n = (0, 1)`, tangent `t = (-1, 0)`. Its velocity `(-0.5, 0)` is along `+t`:
/// slip `s = +1`, friction `-mu lambda_n` along `t`. A normal force `lambda_n`
/// changes the foot's normal acceleration by `(W_nn - mu W_nt) lambda_n` with
/// `W_nn = 1/m + (r x n)^2 / J`, `W_nt = (r x n)(r x t) / J` (rotors without
/// eccentric mass do not couple). Gravity alone accelerates the foot at `-g`
/// along `n`. With `W_nn - mu W_nt < 0` a positive force only pulls it down
/// further: no `lambda_n >= 0` gives a non-negative normal acceleration, and
/// `lambda_n = 0` leaves it accelerating into the fundament. (The rotors' own
/// inertia adds only to the rotor coordinates.)
#[test]
fn the_configuration_has_no_consistent_contact_force() {
    let r_x_n = R1[0]; // (r_x, r_y) x (0, 1) = r_x
    let r_x_t = R1[1]; // (r_x, r_y) x (-1, 0) = r_y
    let w_nn = 1.0 / MASS + r_x_n * r_x_n / INERTIA;
    let w_nt = r_x_n * r_x_t / INERTIA;
    assert!(
        w_nn - MU * w_nt < 0.0,
        "W_nn - mu W_nt = {}",
        w_nn - MU * w_nt
    );
    // Normal acceleration without contact force: -g (no spin yet).
    let free = -G;
    // Any lambda_n >= 0 gives free + (w_nn - mu w_nt) lambda_n < 0.
    for lambda in [0.0, 1.0, 10.0, 1e3] {
        assert!(free + (w_nn - MU * w_nt) * lambda < 0.0);
    }
}

#[test]
fn painleve_is_reported_and_resolved_by_a_tangential_impact() {
    let mut plant = unpowered_plant(&machine());
    let energy0 = plant.mechanical_energy();

    // Reported at t = 0 for K1.
    let painleve: Vec<_> = plant
        .events
        .iter()
        .filter(|e| e.kind == EventKind::Painleve)
        .collect();
    assert!(
        painleve.iter().any(|e| e.contact == "K1" && e.t == 0.0),
        "{:?}",
        plant.events
    );
    // Resolved by a tangential impact at K1: a positive normal impulse, friction
    // inside the cone, the slip stopped (the jam ends in stick), no energy gained.
    let impact = plant
        .events
        .iter()
        .find(|e| e.kind == EventKind::Impact && e.contact == "K1")
        .expect("a tangential impact at K1");
    assert!(impact.normal_impulse > 0.0, "{impact:?}");
    assert!(impact.tangential_impulse.abs() <= MU * impact.normal_impulse * (1.0 + 1e-12));
    // Second method: the impact is plastic and ends with the foot stuck (normal
    // and tangential velocity zero), so whatever its path the total impulse is
    // the one that brings the foot's velocity from (u_n, u_t) = (0, 0.5) to zero:
    // W P = -u0 with the foot's 2x2 Delassus block, by hand from the platform's
    // mass and inertia (the rotors carry no eccentric mass, so they do not
    // couple): W_nn = 1/m + (r x n)^2/J, W_nt = (r x n)(r x t)/J,
    // W_tt = 1/m + (r x t)^2/J, r x n = r_x, r x t = r_y, u_t0 = t . v = -VX.
    let (rn, rt) = (R1[0], R1[1]);
    let w_nn = 1.0 / MASS + rn * rn / INERTIA;
    let w_nt = rn * rt / INERTIA;
    let w_tt = 1.0 / MASS + rt * rt / INERTIA;
    let u_t0 = -VX;
    let det = w_nn * w_tt - w_nt * w_nt;
    let p_n = w_nt * u_t0 / det;
    let p_t = -w_nn * u_t0 / det;
    // The impact starts from a nudge of 1e-6 of the slip speed in approach.
    assert!(
        (impact.normal_impulse - p_n).abs() <= 1e-5 * p_n.abs(),
        "{} vs {p_n}",
        impact.normal_impulse
    );
    assert!(
        (impact.tangential_impulse - p_t).abs() <= 1e-5 * p_t.abs(),
        "{} vs {p_t}",
        impact.tangential_impulse
    );
    assert!(impact.normal_velocity_after.abs() <= 1e-6 * u_t0);
    let e_after = plant.mechanical_energy();
    assert!(
        e_after <= energy0 * (1.0 + 1e-12),
        "energy {energy0} -> {e_after}"
    );

    // And the run goes on: a second of simulated time, K1 never below the
    // fundament beyond the together gap, the energy never above the start.
    let mut lowest = f64::INFINITY;
    let mut highest_energy = f64::NEG_INFINITY;
    for k in 1..=200 {
        plant.advance_to(k as f64 * 0.005, &mut |_| {}).unwrap();
        let q = plant.q();
        let (s, c) = q[2].sin_cos();
        let foot_y = q[1] + s * R1[0] + c * R1[1];
        lowest = lowest.min(foot_y);
        highest_energy = highest_energy.max(plant.mechanical_energy());
    }
    assert!((plant.t - 1.0).abs() < 1e-12);
    assert!(lowest >= -1e-7, "K1 sank to {lowest} m");
    assert!(
        highest_energy <= energy0 * (1.0 + 1e-9),
        "energy rose to {highest_energy} from {energy0}"
    );
}
