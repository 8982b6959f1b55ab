//! `host-sim scenario` through the real binary: a shipped scenario passes (exit 0,
//! one PASS line per expectation), a failing expectation gives exit 1 with a FAIL
//! line, a bad file gives exit 2 with every problem's key path, never a panic.

use std::path::PathBuf;

use serde_json::Value;

mod common;
use common::{root, run};

fn scratch(name: &str, text: &str) -> PathBuf {
    let path = common::scratch("cli-scenario", name);
    std::fs::write(&path, text).unwrap();
    path
}

/// A scenario on the reference machine (absolute path) with `body` appended.
fn scenario_text(body: &str) -> String {
    let machine = root().join("examples/vibro-driver.toml");
    format!("machine = '{}'\n{body}", machine.display())
}

#[test]
fn a_shipped_scenario_passes() {
    let file = root().join("tests/scenarios/supply-sag.toml");
    let r = run(&["scenario", file.to_str().unwrap()]);
    assert_eq!(r.status, 0, "{}{}", r.stdout, r.stderr);
    let pass_lines = r.stdout.lines().filter(|l| l.starts_with("PASS ")).count();
    assert_eq!(pass_lines, 5, "{}", r.stdout);
    assert!(!r.stdout.contains("FAIL"), "{}", r.stdout);
    assert!(
        r.stdout.contains("supply at 2.009 s (+9 ms)"),
        "{}",
        r.stdout
    );
    assert!(
        r.stdout.ends_with("PASS: 5 of 5 expectations hold\n"),
        "{}",
        r.stdout
    );

    let r = run(&["scenario", file.to_str().unwrap(), "--format", "json"]);
    assert_eq!(r.status, 0);
    let doc: Value = serde_json::from_str(&r.stdout).expect("one JSON document");
    assert_eq!(doc["pass"], true);
    assert_eq!(doc["expectations"].as_array().unwrap().len(), 5);
    assert_eq!(doc["expectations"][1]["kind"], "fault");
    assert_eq!(doc["injections"][0]["latched"][0], "supply");
    let delay = doc["injections"][0]["delay"].as_f64().unwrap();
    assert!((delay - 0.009).abs() < 1e-9, "{delay}");
}

#[test]
fn a_failing_expectation_exits_1() {
    // The reference machine reaches running at about 0.71 s, not within 0.5 s; it
    // travels right, not left.
    let text = scenario_text(
        "t_end = 1.0\n\
         [[commands]]\nt = 0.0\ncommand = \"right\"\n\
         [[expect]]\nkind = \"state\"\nstate = \"running\"\nwithin = [0.0, 0.5]\n\
         [[expect]]\nkind = \"no_fault\"\n",
    );
    let file = scratch("fails.toml", &text);
    let r = run(&["scenario", file.to_str().unwrap()]);
    assert_eq!(r.status, 1, "{}{}", r.stdout, r.stderr);
    let fail = r
        .stdout
        .lines()
        .find(|l| l.starts_with("FAIL "))
        .expect("a FAIL line");
    assert!(fail.contains("expect[0] state"), "{fail}");
    assert!(fail.contains("not reached"), "{fail}");
    assert!(r
        .stdout
        .lines()
        .any(|l| l.starts_with("PASS ") && l.contains("expect[1] no_fault")));
    assert!(
        r.stdout.ends_with("FAIL: 1 of 2 expectations hold\n"),
        "{}",
        r.stdout
    );
}

#[test]
fn a_bad_file_exits_2_with_every_key_path() {
    let text = scenario_text(
        "t_end = 2.0\n\
         [[commands]]\nt = 0.0\ncommand = \"rigth\"\n\
         [[faults]]\nt = 1.0\nkind = \"encoder_dropout\"\nrotor = 1\n\
         [[faults]]\nt = 1.0\nkind = \"encodr\"\n\
         [[faults]]\nt = 1.0\nkind = \"jammed_rotor\"\nrotor = 3\n\
         [[expect]]\nkind = \"fault\"\nfault = \"encoder\"\nwithin = [1.0, 5.0]\n\
         [[expect]]\nkind = \"travel\"\ndirection = \"right\"\nbetwen = [0.0, 1.0]\n",
    );
    let file = scratch("bad.toml", &text);
    let r = run(&["scenario", file.to_str().unwrap()]);
    assert_eq!(r.status, 2, "{}{}", r.stdout, r.stderr);
    assert!(r.stdout.is_empty(), "{}", r.stdout);
    for expected in [
        "commands[0].command: unknown value \"rigth\"; did you mean \"right\"?",
        "faults[1].kind: unknown value \"encodr\"; did you mean \"encoder_dropout\"?",
        "faults[2].rotor: must be in [1, 2] (got 3)",
        "expect[1].betwen: unknown key; did you mean `between`?",
        "expect[1].between: missing",
    ] {
        assert!(
            r.stderr.contains(expected),
            "missing {expected:?} in\n{}",
            r.stderr
        );
    }
    assert!(
        r.stderr.lines().all(|l| l.starts_with("error: ")),
        "{}",
        r.stderr
    );

    // A missing file, and a machine that does not exist: exit 2, named.
    let r = run(&["scenario", "no-such-scenario.toml"]);
    r.refused("no-such-scenario.toml: cannot read the file");
    let file = scratch(
        "no-machine.toml",
        "machine = \"nowhere.toml\"\n[[expect]]\nkind = \"no_fault\"\n",
    );
    let r = run(&["scenario", file.to_str().unwrap()]);
    r.refused("machine: no such file");
}

/// Defect: a scenario whose `machine` names a directory was told "no such file".
#[test]
fn a_machine_that_is_a_directory_is_named_as_such() {
    let s = scratch(
        "dir-machine.toml",
        &format!(
            "machine = '{}'\n[[expect]]\nkind = \"no_fault\"\n",
            root().join("examples").display()
        ),
    );
    let r = run(&["scenario", s.to_str().unwrap()]);
    r.refused("machine: is a directory, not a machine file");
}
