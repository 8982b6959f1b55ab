//! A machine with one rotor through the real binary (issue 12): `--open-loop`
//! takes one voltage per rotor of the machine, `tune` is refused, a scenario may
//! not name rotor 2 nor expect a phase offset; every refusal is exit 2 with the
//! option or key named; a run goes end to end and reports one rotor.

use std::path::PathBuf;

use serde_json::Value;

mod common;
use common::{keys, root, run, scratch};
use host_sim::run::report::{ONE_ROTOR_LINE, SUMMARY_KEYS};

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
fn a_one_rotor_run_reports_one_rotor() {
    for args in [
        &["--open-loop", "12"][..],
        &["--open-loop", "coast"],
        &["--command", "right"],
    ] {
        let r = run_one_rotor(args);
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
    // The table says the controller holds speed only.
    let one = one_rotor();
    let r = run(&["run", path(&one), "--command", "right", "--t-end", "0.3"]);
    assert_eq!(r.status, 0, "{}", r.stderr);
    assert!(r.stdout.contains(ONE_ROTOR_LINE), "{}", r.stdout);
    // No phase offset to hold.
    let r = run_one_rotor(&["--command", "right", "--offset", "90"]);
    r.refused("error: --offset 90: the machine has one rotor (\"centre\"): there is no phase offset to hold");
}

/// The controller holds the one rotor at the commanded speed with its eccentric
/// shaking the platform, and rotor 2's trace columns stay 0.
#[test]
fn the_controller_holds_the_one_rotor_at_speed() {
    let out = scratch("cli-one-rotor", "trace.csv");
    let r = run(&[
        "run",
        path(&one_rotor()),
        "--command",
        "right",
        "--speed",
        "3000",
        "--t-end",
        "2",
        "--format",
        "json",
        "--out",
        path(&out),
    ]);
    assert_eq!(r.status, 0, "{}", r.stderr);
    let v: Value = serde_json::from_str(&r.stdout).expect("one JSON document");
    let rpm = v["rotor_speed_rpm"][0].as_f64().expect("rotor 1 speed");
    assert!((rpm - 3000.0).abs() < 30.0, "rotor 1 at {rpm} rpm");
    assert_eq!(v["state"], "running", "{v}");
    let text = std::fs::read_to_string(&out).expect("the trace");
    let mut lines = text.lines();
    let head: Vec<&str> = lines.next().expect("header").split(',').collect();
    let col = |name: &str| head.iter().position(|h| *h == name).expect(name);
    let (phi2, omega2, i2, duty2, vy) = (
        col("phi2"),
        col("omega2"),
        col("i2"),
        col("duty2"),
        col("vy"),
    );
    let mut max_vy: f64 = 0.0;
    for line in lines {
        let f: Vec<f64> = line
            .split(',')
            .map(|x| x.parse().expect("a number"))
            .collect();
        for c in [phi2, omega2, i2, duty2] {
            assert_eq!(f[c], 0.0, "rotor 2's column {} in {line}", head[c]);
        }
        max_vy = max_vy.max(f[vy].abs());
    }
    // The eccentric shakes the platform (a rotor that turned without its mass
    // would leave it at rest on its feet). At 3000 rpm the pull m e w^2 = 19.7 N
    // is just the weight (2.01 kg, 19.7 N), and the rotor slows at the top of its
    // turn, so the platform does not leave the floor at the held speed: this
    // vertical speed comes from the ramp's overshoot (measured: |vy| up to 1.7e-3
    // m/s at 0.76 s, 3056 rpm; below 1e-17 m/s after 0.8 s). The mechanism (the
    // holding force's m e w^2 along the eccentric, the platform on frictionless feet
    // swinging opposite to it below lift-off) is checked against closed forms
    // through the plant in tests/tests/one_rotor_loop.rs.
    assert!(
        max_vy > 1e-3,
        "the platform's vertical speed stays below {max_vy} m/s"
    );
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

[[commands]]
t = 0.2
command = "hold"
offset_deg = 90

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
    r.refused("commands[1].command: \"hold\" holds a phase offset: the machine has one rotor (\"centre\"), there is none to hold");
    // Rotor 1's fault and the speed of the rotor there is are fine.
    assert!(!r.stderr.contains("faults[1]"), "{}", r.stderr);
    assert!(!r.stderr.contains("expect[2]"), "{}", r.stderr);
}

/// A one-rotor machine has no direction: `--command left` runs its rotor and
/// the platform goes where rotor and feet take it (right, on this machine). The
/// run says so, naming the way it went (issue 23: no word of it).
#[test]
fn a_direction_given_to_one_rotor_is_said_to_be_ignored() {
    let r = run_one_rotor(&["--command", "left", "--speed", "3000"]);
    assert_eq!(r.status, 0, "{}", r.stderr);
    let v: Value = serde_json::from_str(&r.stdout).expect("one JSON document");
    // The tool's words for the way it went: right, left, or nowhere at 0.
    let mean_velocity = v["mean_velocity"].as_f64().unwrap();
    let went = if mean_velocity > 0.0 {
        "right"
    } else if mean_velocity < 0.0 {
        "left"
    } else {
        "nowhere"
    };
    let warnings = v["warnings"].to_string();
    assert!(
        warnings.contains("--command left: the machine has one rotor (\\\"centre\\\"): it has no direction to choose; the controller runs the rotor at the speed and ignores `left`"),
        "{warnings}"
    );
    assert!(
        warnings.contains(&format!("this run went {went} (")),
        "{warnings}"
    );
}

/// A one-rotor run that went through the fundament names no way it went: the
/// summary has no travel, and the warning says so instead of a speed (the
/// one-rotor machine without its foot K2 tips onto its side).
#[test]
fn a_one_rotor_run_through_the_fundament_names_no_way() {
    let text = std::fs::read_to_string(one_rotor()).unwrap();
    let k2 =
        "[[contacts]]\nname = \"K2\"\npoint = [0.08, 0.0]\nrestitution = 0.3\nfriction = 0.4\n";
    assert!(text.contains(k2), "the fixture's K2 moved");
    let one_foot = scratch("cli-one-rotor", "one-foot.toml");
    std::fs::write(&one_foot, text.replace(k2, "")).unwrap();
    let r = run(&[
        "run",
        path(&one_foot),
        "--command",
        "left",
        "--speed",
        "3000",
        "--t-end",
        "1",
        "--format",
        "json",
    ]);
    assert_eq!(r.status, 0, "{}", r.stderr);
    let v: Value = serde_json::from_str(&r.stdout).expect("one JSON document");
    assert!(v["mean_velocity"].is_null(), "{v}");
    let warnings = v["warnings"].to_string();
    assert!(warnings.contains("through the fundament"), "{warnings}");
    assert!(
        warnings.contains("ignores `left`, and the platform goes where its rotor and feet take it: this run was no travel (see the warning of its breach)"),
        "{warnings}"
    );
    assert!(!warnings.contains("this run went"), "{warnings}");
}

/// The same through the link: `device travel left --for` on a simulated
/// one-rotor board warns that the direction is ignored, from the status
/// (rotor 2's speed reference 0 while rotor 1 is driven).
#[cfg(unix)]
#[test]
fn a_one_rotor_device_says_the_direction_is_ignored() {
    let one = one_rotor();
    let dev = common::device_sim::DeviceSim::start(&["--machine", path(&one)]);
    let r = run(&[
        "device", "--port", &dev.port, "travel", "left", "--speed", "3000", "--for", "1",
    ]);
    assert_eq!(r.status, 0, "{}{}", r.stdout, r.stderr);
    assert!(
        r.stderr.contains("warning: the device drives one rotor (rotor 2's speed reference is 0 while rotor 1's is ")
            && r.stderr.contains("`left` is ignored"),
        "{}",
        r.stderr
    );
    // A two-rotor board says nothing of the kind.
    let two = common::machine();
    let dev = common::device_sim::DeviceSim::start(&["--machine", path(&two)]);
    let r = run(&[
        "device", "--port", &dev.port, "travel", "left", "--speed", "3000", "--for", "1",
    ]);
    assert_eq!(r.status, 0, "{}{}", r.stdout, r.stderr);
    assert!(!r.stderr.contains("one rotor"), "{}", r.stderr);
}
