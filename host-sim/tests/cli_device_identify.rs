//! `host-sim device identify`, `device capture` and `replay` through the real
//! binaries, against a hidden truth, end to end as a bench would run them:
//! `host-sim device-sim --machine TRUE.toml --firmware-machine
//! examples/vibro-driver.toml` is a board built for the example file on a
//! machine whose motors are 10 to 30 % off it, the two unlike.
//! 1. `identify --machine examples/vibro-driver.toml --write OUT.toml` must find
//!    each motor's constants (within 5 %, friction within 20 %, each within three
//!    of its standard errors) and write them where the machine file takes them;
//! 2. a capture of a travel, replayed on the file written, must leave residuals
//!    at least 5 times smaller than on the example file, in every quantity;
//! 3. the file written must tune.
//!
//! Bad input: exit 2, nothing asked of the device, nothing written.

use std::path::{Path, PathBuf};
use std::process::Stdio;

use host_sim::machine::Machine;

mod common;
use common::device_sim::DeviceSim;
use common::truth::TRUTH;
use common::Run;

fn host_sim(args: &[&str]) -> Run {
    let mut cmd = common::host_sim();
    cmd.args(args).stdin(Stdio::null());
    common::finish(cmd)
}

fn scratch(name: &str) -> PathBuf {
    common::scratch("cli-device-identify", name)
}

fn example() -> PathBuf {
    common::machine()
}

/// The truth's machine file ([`common::truth`]).
fn truth_file() -> PathBuf {
    common::truth::truth_file("cli-device-identify")
}

/// `value` within `tolerance` (relative) of `truth`.
fn within(what: &str, value: f64, truth: f64, tolerance: f64) {
    let off = (value - truth) / truth;
    assert!(
        off.abs() <= tolerance,
        "{what}: {value} against {truth} ({:+.2} %, allowed {} %)",
        100.0 * off,
        100.0 * tolerance
    );
}

/// The whole check: identify on the bench, the values and their errors against
/// the truth, the file written against the truth, and a tune of the file
/// written.
#[cfg(unix)]
#[test]
fn identify_write_capture_replay_and_tune_end_to_end() {
    let truth = truth_file();
    let example = example();
    let dev = DeviceSim::start(&[
        "--machine",
        truth.to_str().unwrap(),
        "--firmware-machine",
        example.to_str().unwrap(),
    ]);
    let out = scratch("identified.toml");
    let _ = std::fs::remove_file(&out);
    let json = dev.device(&[
        "identify",
        "--machine",
        example.to_str().unwrap(),
        "--write",
        out.to_str().unwrap(),
        "--format",
        "json",
    ]);
    let report: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!(report["status"], "done", "{json}");
    for (k, t) in TRUTH.iter().enumerate() {
        let values = &report["rotors"][k]["values"];
        let m = Machine::load(&example, &[]).unwrap();
        let r = &m.rotors[k];
        let eccentric = r.eccentric_mass * r.eccentricity * r.eccentricity;
        for (key, truth, tolerance) in [
            ("resistance", t.resistance, 0.05),
            ("torque_constant", t.torque_constant, 0.05),
            ("coulomb_friction", t.coulomb_friction, 0.2),
            ("viscous_friction", t.viscous_friction, 0.2),
            ("inertia", t.inertia + eccentric, 0.05),
        ] {
            let v = values[key]["value"].as_f64().unwrap();
            let se = values[key]["std_error"].as_f64().unwrap();
            within(&format!("rotor {} {key}", k + 1), v, truth, tolerance);
            assert!(
                (v - truth).abs() <= 3.0 * se,
                "rotor {} {key}: {v} +- {se} does not cover {truth}",
                k + 1
            );
        }
    }

    // The file written: each rotor's own motor (the two are unlike), and its
    // inertia without the eccentric; everything else as the example has it.
    let written = Machine::load(&out, &[]).unwrap();
    for (k, t) in TRUTH.iter().enumerate() {
        let r = &written.rotors[k];
        let name = format!("rotor {}", k + 1);
        within(
            &format!("{name} resistance"),
            r.motor.resistance,
            t.resistance,
            0.05,
        );
        within(
            &format!("{name} torque_constant"),
            r.motor.torque_constant,
            t.torque_constant,
            0.05,
        );
        within(
            &format!("{name} coulomb_friction"),
            r.motor.coulomb_friction,
            t.coulomb_friction,
            0.2,
        );
        within(
            &format!("{name} viscous_friction"),
            r.motor.viscous_friction,
            t.viscous_friction,
            0.2,
        );
        within(&format!("{name} inertia"), r.inertia, t.inertia, 0.05);
    }
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(text.contains("[rotors.motor]"), "{text}");
    let original = std::fs::read_to_string(&example).unwrap();
    for comment in original.lines().filter(|l| l.trim_start().starts_with('#')) {
        assert!(text.contains(comment), "comment dropped: {comment}");
    }

    // A travel captured on the bench, replayed on the file the firmware was
    // built for and on the file identify wrote: every residual at least 5 times
    // smaller on the latter.
    let capture = scratch("travel.csv");
    let said = dev.device(&[
        "capture",
        "--for",
        "2",
        "--travel",
        "right",
        "--speed",
        "3000",
        "--out",
        capture.to_str().unwrap(),
    ]);
    assert!(said.contains("capture: 2000 ticks"), "{said}");
    let replay = |machine: &Path| -> serde_json::Value {
        let r = host_sim(&[
            "replay",
            machine.to_str().unwrap(),
            capture.to_str().unwrap(),
            "--firmware-machine",
            example.to_str().unwrap(),
            "--format",
            "json",
        ]);
        assert_eq!(r.status, 0, "{}{}", r.stdout, r.stderr);
        serde_json::from_str(&r.stdout).unwrap()
    };
    let before = replay(&example);
    let after = replay(&out);
    let rows = |v: &serde_json::Value| v["residuals"].as_array().unwrap().clone();
    assert_eq!(rows(&before).len(), 7, "{before}");
    for (b, a) in rows(&before).iter().zip(rows(&after)) {
        let (rb, ra) = (b["rms"].as_f64().unwrap(), a["rms"].as_f64().unwrap());
        assert!(
            ra * 5.0 <= rb,
            "{} rotor {}: rms {ra} on the identified file, {rb} on the example: not 5 times smaller",
            a["quantity"],
            a["rotor"]
        );
    }
    assert_eq!(after["state_differs_ticks"], 0, "{after}");

    // The file written is a machine host-sim runs and tunes.
    let tuned = host_sim(&[
        "tune",
        out.to_str().unwrap(),
        "--speeds",
        "3000:3000:1",
        "--offsets",
        "0:360:90",
        "--t-end",
        "1",
    ]);
    assert_eq!(tuned.status, 0, "{}{}", tuned.stdout, tuned.stderr);
}

/// Mistakes in the options are refused with exit 2 before the device is asked
/// anything (the port here answers nothing), and nothing is written.
#[test]
fn bad_options_are_refused_before_the_device() {
    let out = scratch("never.toml");
    let _ = std::fs::remove_file(&out);
    let example = example();
    let port = "tcp:127.0.0.1:9";
    let cases: [(Vec<&str>, &str); 4] = [
        (
            vec!["identify", "--write", out.to_str().unwrap()],
            "--machine",
        ),
        (
            vec!["identify", "--machine", "no-such-machine.toml"],
            "no-such-machine.toml",
        ),
        (
            vec![
                "identify",
                "--timeout",
                "0",
                "--machine",
                example.to_str().unwrap(),
            ],
            "--timeout: must be a number of seconds above 0",
        ),
        (
            vec![
                "identify",
                "--machine",
                example.to_str().unwrap(),
                "--write",
                "/no/such/dir/out.toml",
            ],
            "--write",
        ),
    ];
    for (args, said) in cases {
        let mut all = vec!["device", "--port", port];
        all.extend_from_slice(&args);
        let r = host_sim(&all);
        assert_eq!(r.status, 2, "{args:?}: {}{}", r.stdout, r.stderr);
        assert!(r.stderr.contains(said), "{args:?}: {}", r.stderr);
        assert!(!r.stderr.contains("panicked"), "{}", r.stderr);
    }
    assert!(!Path::new(&out).exists());
}
