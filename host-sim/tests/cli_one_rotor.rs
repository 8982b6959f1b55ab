//! A machine with one rotor through the real binary (issue 12): `--open-loop`
//! takes one voltage per rotor of the machine, `tune` is refused, a scenario may
//! not name rotor 2 nor expect a phase offset; every refusal is exit 2 with the
//! option or key named. A run itself needs the simulated plant to take one rotor
//! (`host_sim::simulation::limits::PLANT_ROTORS`): until it does, it is refused
//! naming the plant, and from then on it is checked end to end here.

use std::path::PathBuf;

use serde_json::Value;

mod common;
use common::{keys, root, run, scratch};
use host_sim::run::report::{ONE_ROTOR_LINE, SUMMARY_KEYS};
use host_sim::simulation::limits::PLANT_ROTORS;

/// The one-rotor machine of the tests (rotor "centre").
fn one_rotor() -> PathBuf {
    root().join("tests/fixtures/one-rotor-machine.toml")
}

fn path(p: &std::path::Path) -> &str {
    p.to_str().expect("a UTF-8 path")
}

#[test]
fn open_loop_takes_one_voltage_per_rotor() {
    let one = one_rotor();
    let r = run(&["run", path(&one), "--open-loop", "12,12"]);
    r.refused("error: --open-loop 12,12: 2 voltages for a machine with 1 rotor: give one winding voltage `V` (V, signed), or `coast`");
    let two = common::machine();
    let r = run(&["run", path(&two), "--open-loop", "-6"]);
    r.refused("error: --open-loop -6: 1 voltage for a machine with 2 rotors: give two winding voltages `V1,V2`");
    // Not a number at all: the parser's refusal, which lists every form.
    let r = run(&["run", path(&one), "--open-loop", "twelve"]);
    r.refused("one `V` for a machine with one rotor");
}

/// The one-rotor machine run with `args` (and `--t-end 0.3 --format json`).
fn run_one_rotor(args: &[&str]) -> common::Run {
    let one = one_rotor();
    let mut all = vec!["run", path(&one)];
    all.extend_from_slice(args);
    all.extend_from_slice(&["--t-end", "0.3", "--format", "json"]);
    run(&all)
}

#[test]
fn a_one_rotor_run_is_refused_by_the_plant_or_reports_one_rotor() {
    for args in [
        &["--open-loop", "12"][..],
        &["--open-loop", "coast"],
        &["--command", "right", "--offset", "90"],
    ] {
        let r = run_one_rotor(args);
        if !PLANT_ROTORS.contains(&1) {
            // The options are right: the plant alone refuses.
            r.refused("the machine has 1 rotor (centre): the file, the controller and the firmware take it, but the simulated plant takes 2 rotors so far");
            assert!(!r.stderr.contains("--open-loop"), "{args:?}: {}", r.stderr);
            continue;
        }
        assert_eq!(r.status, 0, "{args:?}: {}", r.stderr);
        let v: Value = serde_json::from_str(&r.stdout).expect("one JSON document");
        assert_eq!(keys(&v), SUMMARY_KEYS);
        assert_eq!(v["rotors"], 1, "{v}");
        assert_eq!(v["phase_loop"], false, "{v}");
        assert!(v["phase_offset_deg"].is_null(), "{v}");
        assert_eq!(
            v["rotor_speed_rpm"].as_array().map(Vec::len),
            Some(1),
            "{v}"
        );
    }
    if PLANT_ROTORS.contains(&1) {
        // The table says the controller holds speed only.
        let one = one_rotor();
        let r = run(&["run", path(&one), "--command", "right", "--t-end", "0.3"]);
        assert_eq!(r.status, 0, "{}", r.stderr);
        assert!(r.stdout.contains(ONE_ROTOR_LINE), "{}", r.stdout);
    }
}

#[test]
fn tune_refuses_one_rotor_with_the_reason() {
    let one = one_rotor();
    let r = run(&["tune", path(&one), "--speeds", "3000"]);
    r.refused("rotors: the machine has one rotor (\"centre\"): tune sweeps the phase offset between two rotors");
    assert!(r.stderr.contains("holds speed only"), "{}", r.stderr);
    assert_eq!(r.stderr.lines().count(), 1, "{}", r.stderr);
}

#[test]
fn a_scenario_may_not_name_rotor_2_of_one_rotor() {
    let file = scratch("cli-one-rotor", "one-rotor-scenario.toml");
    let text = format!(
        r#"machine = {machine:?}
t_end = 1.0

[[commands]]
t = 0.0
command = "right"

[[faults]]
t = 0.5
kind = "encoder_dropout"
rotor = 2

[[faults]]
t = 0.5
kind = "current_offset"
rotor = 1
amps = 0.1

[[expect]]
kind = "speed"
rotor = 2
range_rpm = [0, 100]
between = [0.5, 1.0]

[[expect]]
kind = "phase"
range_deg = [80, 100]
within = [0.5, 1.0]

[[expect]]
kind = "speed"
range_rpm = [0, 4000]
between = [0.5, 1.0]
"#,
        machine = path(&one_rotor())
    );
    std::fs::write(&file, text).expect("scratch file");
    let r = run(&["scenario", path(&file)]);
    r.refused("faults[0].rotor: must be 1: the machine has one rotor (\"centre\"), rotor 2 does not exist (got 2)");
    r.refused("expect[0].rotor: must be 1");
    r.refused("expect[1].kind: \"phase\" does not apply: the machine has one rotor");
    // Rotor 1's fault and the speed of the rotor there is are fine.
    assert!(!r.stderr.contains("faults[1]"), "{}", r.stderr);
    assert!(!r.stderr.contains("expect[2]"), "{}", r.stderr);
}
