//! The closed loop of a one-rotor machine (issue 12): host-sim's
//! `ControllerDriver` built from the one-rotor machine file drives rotor 1 and
//! holds its speed, commands rotor 2's H-bridge `Off` at every tick, records its
//! duty 0, and takes no fault from it.
//!
//! The simulated plant takes two rotors so far
//! (`host_sim::simulation::limits::PLANT_ROTORS`), so the plant here is a stand-in:
//! the same machine with a second, plain rotor (no eccentric) that nothing drives.
//! The driver does not know of it: it samples rotor 1's encoder and current only,
//! and the second rotor turns as the platform's motion and its own friction make
//! it. What is checked is the driver's side of the plant's interface, the calls a
//! one-rotor plant will get.

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
    // The stand-in plant: a second rotor, plain, beside the first.
    let stand_in = machine(&ONE_ROTOR.replace(
        "[motor]",
        "[[rotors]]\nname = \"idle\"\naxis = [0.03, 0.03]\neccentric_mass = 0.0\neccentricity = 0.0\ninertia = 6.0e-6\nsense = \"cw\"\n\n[motor]",
    ));
    assert_eq!((one.rotors.len(), stand_in.rotors.len()), (1, 2));
    let mut plant = Plant::new(
        PlantModel::new(&stand_in),
        initial_state(&stand_in),
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
    let rpm = plant.v()[3] * 30.0 / std::f64::consts::PI;
    assert!((rpm - 3000.0).abs() < 60.0, "rotor 1 at {rpm} rpm");
    // Rotor 2's winding was never connected: no current.
    assert_eq!(plant.currents()[1], 0.0);
    assert_eq!(driver.commanded_offset_deg(), None);
    assert_eq!(driver.state(), "running");
}
