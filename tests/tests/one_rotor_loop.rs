//! The closed loop of a one-rotor machine (issue 12): host-sim's
//! `ControllerDriver` built from the one-rotor machine file drives rotor 1 and
//! holds its speed, commands rotor 2's H-bridge `Off` at every tick, records its
//! duty 0, and takes no fault from it.
//!
//! The plant is the one-rotor machine itself: its coordinates are
//! `(x, y, theta, phi_1)`, and a second winding it does not have is held open.
//!
//! Its mechanism against closed forms written here (the eccentric mass `m` on a
//! circle of radius `e` about its axis, Newton's laws for the whole machine; none of
//! the plant's matrices):
//!
//! - platform and rotor held at `w`: the holding force is the weight less the
//!   eccentric's `m e w^2 (cos psi, sin psi)`, and its moment about the platform's
//!   centre of mass the rate of the eccentric's angular momentum less gravity's
//!   moment on it;
//! - the rotor held at `w`, the feet frictionless, below lift-off: the machine's
//!   centre of mass moves along x at its initial velocity, so the platform's
//!   `x_C` oscillates opposite to the eccentric (the mechanism that makes the
//!   platform move at all, which `cli_one_rotor.rs`'s vertical speed check, met at
//!   3000 rpm only on the controller's overshoot, does not isolate).

use std::f64::consts::PI;
use tests::initial_state;
use tests::machine::TestMachine;

use host_sim::event::EventKind;
use host_sim::machine::Machine;
use host_sim::plant::bridge::BridgeCommand;
use host_sim::plant::contact::ContactMode;
use host_sim::plant::model::PlantModel;
use host_sim::plant::simulator::{Holds, Plant, Settings};
use host_sim::simulation::closed_loop::ControllerDriver;
use host_sim::simulation::Driver;
use shared::controller::{Command, Direction, RotorCount, State};
use shared::vec2::cross;
use tests::rig::{check, G};

/// The one-rotor machine of the tests (rotor "centre", ccw), from the repository's root.
const ONE_ROTOR: &str = "tests/fixtures/one-rotor-machine.toml";

#[test]
fn the_driver_holds_rotor_1_and_leaves_rotor_2_off() {
    let one = TestMachine::file(ONE_ROTOR).machine();
    assert_eq!(one.rotors.len(), 1);
    let model = PlantModel::new(&one);
    assert_eq!(model.dof, 4);
    let mut plant = Plant::new(
        model,
        initial_state(&one),
        Settings::default(),
        Holds::default(),
    );
    let travel = Command::Travel {
        direction: Direction::Right,
        speed_rpm: 3000.0,
    };
    let mut driver = ControllerDriver::new(&one, vec![(0.0, travel)]).expect("the controller");
    assert_eq!(driver.rotor_count(), RotorCount::One);
    assert!(!driver.last_tick().expect("a controller").phase_loop());

    // Two seconds at the control rate, as `simulate` steps it.
    let rate = one.controller.rate_hz;
    let mut running_at = None;
    for tick in 0..(2.0 * rate) as u64 {
        let t = tick as f64 / rate;
        driver.before_tick(t, &mut plant);
        let (commands, duty) = driver.bridges(t, &plant);
        assert_eq!(commands[1], BridgeCommand::Off, "t = {t}");
        assert_eq!(duty[1].to_bits(), 0.0f64.to_bits(), "t = {t}");
        let out = driver.last().expect("stepped");
        assert!(out.faults.is_empty(), "t = {t}: {}", out.faults);
        assert!(!out.telemetry.phase_loop_closed);
        if out.state == State::Running && running_at.is_none() {
            running_at = Some(t);
        }
        plant.set_bridges(commands);
        plant
            .advance_to((tick + 1) as f64 / rate, &mut |_| {})
            .unwrap();
    }
    // The ramp reaches 3000 rpm in about 0.72 s (no phase loop to wait for);
    // rotor 1 then holds it. Rotor 1 is ccw: its driven speed is +phi_1'.
    let running_at = running_at.expect("running");
    assert!(
        (0.6..1.0).contains(&running_at),
        "running at {running_at} s"
    );
    let rpm = plant.rotor_angle(0).1 * 30.0 / PI;
    assert!((rpm - 3000.0).abs() < 60.0, "rotor 1 at {rpm} rpm");
    // There is no rotor 2, and no current in its winding.
    assert_eq!(plant.currents()[1], 0.0);
    let last_tick = driver.last_tick().expect("a controller");
    assert_eq!(last_tick.held_offset_deg(), None);
    assert_eq!(last_tick.state(), State::Running);
}

/// The one-rotor machine's numbers: platform mass, eccentric mass, eccentricity (kg,
/// kg, m), from the fixture.
const PLATFORM_MASS: f64 = 2.0;
const ECCENTRIC_MASS: f64 = 0.01;
const ECCENTRICITY: f64 = 0.02;

/// The one-rotor machine with its rotor's axis at `axis` (world, t = 0; the
/// fixture's is the platform's centre of mass, `[0.0, 0.03]`) and `replace`
/// applied to its text.
fn one_rotor(axis: [f64; 2], replace: &[(&str, &str)]) -> Machine {
    let mut m = TestMachine::file(ONE_ROTOR).replace(
        "axis = [0.0, 0.03]",
        &format!("axis = [{:?}, {:?}]", axis[0], axis[1]),
    );
    for (a, b) in replace {
        m = m.replace(a, b);
    }
    m.machine()
}

/// The plant of `m` with its rotor at `phi0` (rad) turning at `w` (rad/s), the
/// platform at rest, and `holds`.
fn spinning(m: &Machine, phi0: f64, w: f64, holds: Holds) -> Plant {
    let model = PlantModel::new(m);
    let mut y = initial_state(m);
    let phi = model.rotors[0].phi;
    y[phi] = phi0;
    y[model.dof + phi] = w;
    Plant::new(model, y, Settings::default(), holds)
}

/// Platform and rotor held, the rotor at `w` (ccw), the platform level with its
/// centre of mass `C` at rest: the eccentric mass `m` moves on a circle about its
/// axis `A = C + rho` at `eps = e (cos psi, sin psi)`, `psi = phi_0 + w t`, so
/// (Newton for the whole machine, whose only moving mass is the eccentric)
///
/// ```text
///   h_xy + M g_vec = d/dt (m v) = -m w^2 eps   =>   h_xy = (0, M g) - m e w^2 (cos psi, sin psi)
/// ```
///
/// with `M` the total mass (the platform's and the eccentric's) and `g_vec = (0,
/// -g)`: the holding force (`Plant::holding_force`, the generalized force the hold
/// exerts on `x, y`) carries the weight and takes the eccentric's pull `m e w^2`
/// along `psi`. Its moment about `C` (fixed): the machine's angular momentum about
/// `C` is `m r x v + I psi'` with `r = rho + eps`, `v = w z x eps`; `I psi'` is
/// constant and `d/dt (r x v) = r x (-w^2 eps)` (`v x v = 0`), so
///
/// ```text
///   h_theta + r x m g_vec = -m w^2 rho x eps
/// ```
///
/// (the force at `C` has no moment about it; the hold on `phi` acts between the
/// rotor and the platform, internal). Tolerance 1e-10 of `F0 = m e w^2`: the held
/// rotor's angle is `phi_0 + w t` to rounding (the two-rotor version:
/// `plant_references.rs`, `exciting_force_lies_along_half_the_offset_...`); the
/// moment's scale is `F0` on the 0.1 m of the platform.
#[test]
fn the_held_platform_takes_the_weight_less_the_eccentric_pull() {
    let total = PLATFORM_MASS + ECCENTRIC_MASS;
    let holds = Holds {
        platform: true,
        rotors: true,
        ..Holds::default()
    };
    // The fixture's axis (rho = 0: no moment of the pull) and one off the centre.
    for (axis, w, phi0) in [([0.0, 0.03], 314.0, -PI / 2.0), ([0.05, 0.045], 200.0, 0.3)] {
        let m = one_rotor(axis, &[]);
        let rho = [axis[0], axis[1] - 0.03];
        let mut plant = spinning(&m, phi0, w, holds);
        let f0 = ECCENTRIC_MASS * ECCENTRICITY * w * w;
        let period = 2.0 * PI / w;
        let (mut worst_f, mut worst_m) = (0.0f64, 0.0f64);
        for k in 1..=360 {
            let t = period * k as f64 / 360.0;
            plant.advance_to(t, &mut |_| {}).unwrap();
            let h = plant.holding_force();
            let psi = phi0 + w * t;
            let (s, c) = psi.sin_cos();
            let ctx = format!("axis {axis:?}, w {w}, t = {t:.6}");
            let fx = -f0 * c;
            let fy = total * G - f0 * s;
            check(&format!("{ctx}: h_x"), h[0], fx, 1e-10 * f0);
            check(&format!("{ctx}: h_y"), h[1], fy, 1e-10 * f0);
            let eps = [ECCENTRICITY * c, ECCENTRICITY * s];
            let r = [rho[0] + eps[0], rho[1] + eps[1]];
            let moment =
                -ECCENTRIC_MASS * w * w * cross(rho, eps) - cross(r, [0.0, -ECCENTRIC_MASS * G]);
            check(&format!("{ctx}: h_theta"), h[2], moment, 1e-10 * f0 * 0.1);
            worst_f = worst_f.max((h[0] - fx).abs()).max((h[1] - fy).abs());
            worst_m = worst_m.max((h[2] - moment).abs());
        }
        eprintln!(
            "axis {axis:?}: worst force error {worst_f:.1e} N, moment {worst_m:.1e} N m \
             (F0 {f0:.3} N)"
        );
    }
}

/// The rotor held at `w` (ccw), the feet frictionless, the pull below the
/// weight: no horizontal external force, so the machine's centre of mass moves
/// along x at its initial velocity `p_x / M`, `p_x = m v_ecc,x = -m w e sin psi_0`
/// (the platform at rest at t = 0). With the platform level and its feet down
/// (`M x_G = M x_C + m (rho_x + e cos psi)`, `rho` the axis from `C`, 0 here):
///
/// ```text
///   x_C(t) = x_C(0) - (m / M) e (cos psi - cos psi_0) - (m w e sin psi_0 / M) t,   psi = psi_0 + w t
/// ```
///
/// At 200 rad/s the pull `m e w^2` is 8 N against the 19.7 N weight, and its
/// moment about `C` is zero (the axis at `C`): both feet stay down. Tolerance 1e-9
/// m as the two-rotor closed form (`plant_unilateral.rs`,
/// `frictionless_platform_on_the_floor_follows_the_closed_form`): the integrator's
/// relative tolerance 1e-8 on an oscillation of `2 (m / M) e = 0.2 mm`, 2e-12 m a
/// step, over some 500 steps.
#[test]
fn the_platform_on_frictionless_feet_moves_opposite_to_the_eccentric() {
    let total = PLATFORM_MASS + ECCENTRIC_MASS;
    let w = 200.0;
    let holds = Holds {
        rotors: true,
        ..Holds::default()
    };
    for phi0 in [0.0, -PI / 2.0, 2.0] {
        let m = one_rotor([0.0, 0.03], &[("friction = 0.4", "friction = 0.0")]);
        let mut plant = spinning(&m, phi0, w, holds);
        assert!(plant.modes.iter().all(|m| *m != ContactMode::Open));
        let x0 = plant.platform_motion()[0];
        let drift = -ECCENTRIC_MASS * w * ECCENTRICITY * phi0.sin() / total;
        let mut worst = 0.0f64;
        let (mut lowest, mut highest) = (f64::INFINITY, f64::NEG_INFINITY);
        let t_end = 0.5;
        let n = 2000;
        for k in 1..=n {
            let t = t_end * k as f64 / n as f64;
            plant.advance_to(t, &mut |_| {}).unwrap();
            let [x, y, theta, ..] = plant.platform_motion();
            let psi = phi0 + w * t;
            let expected =
                x0 - ECCENTRIC_MASS / total * ECCENTRICITY * (psi.cos() - phi0.cos()) + drift * t;
            check(&format!("phi0 {phi0}, t = {t}: x_C"), x, expected, 1e-9);
            check(&format!("phi0 {phi0}, t = {t}: y_C"), y, 0.03, 1e-12);
            check(&format!("phi0 {phi0}, t = {t}: theta"), theta, 0.0, 1e-12);
            worst = worst.max((x - expected).abs());
            let oscillation = x - x0 - drift * t;
            lowest = lowest.min(oscillation);
            highest = highest.max(oscillation);
        }
        assert!(
            !plant
                .events
                .iter()
                .any(|e| e.kind == EventKind::Liftoff || e.kind == EventKind::Impact),
            "phi0 {phi0}: a foot left the floor: {:?}",
            plant.events
        );
        // The mechanism, not a constant: the platform swings by 2 (m / M) e. The
        // samples are w dt = 0.05 rad apart, so each extreme is missed by at most
        // (w dt / 2)^2 / 2 = 3e-4 of the amplitude: 1e-3 of the swing.
        let swing = 2.0 * ECCENTRIC_MASS / total * ECCENTRICITY;
        check(
            &format!("phi0 {phi0}: swing"),
            highest - lowest,
            swing,
            1e-3 * swing,
        );
        eprintln!("phi0 {phi0}: worst |x_C - closed form| {worst:.1e} m (swing {swing:.2e} m)");
    }
}
