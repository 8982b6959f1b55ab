//! One rotor or two (issue 12): a machine file with one `[[rotors]]` table reads,
//! with its controller's constants those of one rotor; none, or three, are
//! refused at the key `rotors`, saying what is allowed, with the file's other
//! problems.

use std::path::Path;

mod common;
use common::assert_problem;
use machine_file::input::{render, Problem};
use machine_file::rotors::Rotors;
use machine_file::{machine_constants, Machine};
use shared::controller::{Params, RotorCount};

/// Only the required sections, two rotors (`left`, `right`).
const MINIMAL: &str = include_str!("../../../tests/fixtures/minimal-machine.toml");
/// The same machine with one rotor (`centre`).
const ONE_ROTOR: &str = include_str!("../../../tests/fixtures/one-rotor-machine.toml");

fn read(text: &str, sets: &[&str]) -> Result<Machine, Vec<Problem>> {
    let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
    Machine::from_text("m.toml", text, Path::new(""), &sets)
}

/// The `[[rotors]]` tables of the minimal machine: (first, second).
fn minimal_rotors() -> (String, String) {
    let first = MINIMAL.find("[[rotors]]").unwrap();
    let second = first + 1 + MINIMAL[first + 1..].find("[[rotors]]").unwrap();
    let end = MINIMAL.find("[motor]").unwrap();
    (
        MINIMAL[first..second].to_string(),
        MINIMAL[second..end].to_string(),
    )
}

#[test]
fn one_rotor_is_accepted() {
    let m = read(ONE_ROTOR, &[]).unwrap_or_else(|e| panic!("{}", render(&e)));
    assert_eq!(m.rotors.len(), 1);
    assert_eq!(m.rotors.count(), RotorCount::One);
    assert_eq!(m.rotors.rotor1().name, "centre");
    assert!(m.rotors.rotor2().is_none());
    assert_eq!(m.rotors[0].axis, [0.0, 0.03]);
    // The mass that moves has one eccentric.
    assert!((m.total_mass() - 2.01).abs() < 1e-12);
    // The controller's constants: one rotor, rotor 1's model in both places, and
    // the lift-off of one eccentric, sqrt(M g / (m e)) = 314.0 rad/s (the pair
    // of the two-rotor machine: 222.6 rad/s).
    let c = machine_constants(&m);
    assert_eq!(c.rotor_count, RotorCount::One);
    assert_eq!(c.rotors[1], c.rotors[0]);
    let two = machine_constants(&read(MINIMAL, &[]).unwrap());
    assert_eq!(c.rotors[0], two.rotors[0]);
    let lift_off_rpm = (2.01f64 * 9.81 / 2.0e-4).sqrt() * 30.0 / std::f64::consts::PI;
    let low = f64::from(c.resonance_band_rpm[0]);
    assert!((low - 0.7 * lift_off_rpm).abs() < 1e-3 * low, "{low}");
    assert!(c.resonance_band_rpm[0] > two.resonance_band_rpm[0]);
    assert_eq!(Params::from_machine(&c).validate(), Ok(()));
}

#[test]
fn one_rotor_with_its_own_motor_needs_no_machine_motor() {
    // [motor] moved into the rotor's own [rotors.motor]: complete for the one
    // rotor there is.
    let motor = &ONE_ROTOR[ONE_ROTOR.find("[motor]").unwrap()..ONE_ROTOR.find("[drive]").unwrap()];
    let text = ONE_ROTOR.replace(motor, "").replace(
        "sense = \"ccw\"\n",
        &format!(
            "sense = \"ccw\"\n{}",
            motor.replace("[motor]", "[rotors.motor]")
        ),
    );
    let m = read(&text, &[]).unwrap_or_else(|e| panic!("{}", render(&e)));
    assert_eq!(m.rotors[0].motor.resistance, 2.0);
    // And --set reaches the one rotor, by name or index; rotor 2 is not there.
    let m = read(
        ONE_ROTOR,
        &["rotors.centre.sense=cw", "rotors[0].angle=1.5"],
    )
    .unwrap();
    assert_eq!((m.rotors[0].sense.name(), m.rotors[0].angle), ("cw", 1.5));
    let e = read(ONE_ROTOR, &["rotors.1.angle=1"]).unwrap_err();
    assert!(
        render(&e).contains("no rotors[1]: the file has 1 [[rotors]] tables"),
        "{}",
        render(&e)
    );
}

#[test]
fn no_rotor_is_refused_with_the_key_and_what_is_allowed() {
    let (first, second) = minimal_rotors();
    let none = MINIMAL.replace(&first, "").replace(&second, "");
    let e = read(&none, &[]).unwrap_err();
    assert_problem(
        &e,
        "rotors",
        "one or two [[rotors]] tables are required (got 0): rotor 1, then rotor 2 if the machine has two",
    );
    assert_eq!(e.len(), 1, "{}", render(&e));
}

#[test]
fn three_rotors_are_refused_with_the_other_problems() {
    let (first, _) = minimal_rotors();
    let third = first.replace("\"left\"", "\"third\"");
    let three = MINIMAL.replacen("[motor]", &format!("{third}[motor]"), 1);
    let e = read(&three, &[]).unwrap_err();
    assert_problem(
        &e,
        "rotors",
        "one or two [[rotors]] tables are required (got 3)",
    );
    // Each rotor is still read on its own, and the file's other problems come too.
    let e = read(&three, &["platform.mass=0", "rotors.third.inertia=-1"]).unwrap_err();
    assert_problem(&e, "rotors", "(got 3)");
    assert_problem(&e, "platform.mass", "must be > 0");
    assert!(render(&e).contains("rotors[2].inertia"), "{}", render(&e));
    assert!(e.iter().all(|p| !p.message.is_empty()));
}

#[test]
fn rotors_holds_one_or_two_only() {
    let m = read(MINIMAL, &[]).unwrap();
    let two = m.rotors.clone().into_vec();
    assert_eq!(m.rotors.count(), RotorCount::Two);
    assert_eq!(m.rotors.rotor2().map(|r| r.name.as_str()), Some("right"));
    assert!(Rotors::new(Vec::new()).is_err());
    let three = [two.clone(), two[..1].to_vec()].concat();
    assert_eq!(Rotors::new(three).unwrap_err().len(), 3);
    assert_eq!(Rotors::new(two[..1].to_vec()).unwrap().len(), 1);
    assert_eq!(Rotors::COUNTS, [1, 2]);
}
