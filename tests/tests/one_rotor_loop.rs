//! The closed loop of a one-rotor machine (issue 12): host-sim's
//! `ControllerDriver` built from the one-rotor machine file drives rotor 1 and
//! holds its speed, commands rotor 2's H-bridge `Off` at every tick, records its
//! duty 0, and takes no fault from it.
//!
//! The plant is the one-rotor machine itself: its coordinates are
//! `(x, y, theta, phi_1)`, and a second winding it does not have is held open.

use host_sim::machine::Machine;
use host_sim::plant::bridge::BridgeCommand;
use host_sim::plant::model::{initial_state, PlantModel};
use host_sim::plant::simulator::{Holds, Plant, Settings};
use host_sim::simulation::closed_loop::ControllerDriver;
use host_sim::simulation::Driver;
use shared::controller::{Command, Direction, RotorCount, State};

/// The one-rotor machine of the tests (rotor "centre", ccw).
const ONE_ROTOR: &str = include_str!("../fixtures/one-rotor-machine.toml");

fn machine(text: &str) -> Machine {
    Machine::from_text("m.toml", text, std::path::Path::new(""), &[])
        .unwrap_or_else(|p| panic!("{}", host_sim::machine::input::render(&p)))
}

#[test]
fn the_driver_holds_rotor_1_and_leaves_rotor_2_off() {
    let one = machine(ONE_ROTOR);
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
    assert!(!driver.phase_loop());

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
        plant.advance_to((tick + 1) as f64 / rate, &mut |_| {});
    }
    // The ramp reaches 3000 rpm in about 0.72 s (no phase loop to wait for);
    // rotor 1 then holds it. Rotor 1 is ccw: its driven speed is +phi_1'.
    let running_at = running_at.expect("running");
    assert!(
        (0.6..1.0).contains(&running_at),
        "running at {running_at} s"
    );
    let rpm = plant.rotor_angle(0).1 * 30.0 / std::f64::consts::PI;
    assert!((rpm - 3000.0).abs() < 60.0, "rotor 1 at {rpm} rpm");
    // There is no rotor 2, and no current in its winding.
    assert_eq!(plant.currents()[1], 0.0);
    assert_eq!(driver.commanded_offset_deg(), None);
    assert_eq!(driver.state(), "running");
}
