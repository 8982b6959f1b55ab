//! The paper's Fig. 8 machine (`examples/paper-fig8.toml`, docs/paper-fig8.md)
//! through the real binary: it travels right, its actuator strikes the collision
//! element at K3 and K4 together (nine instants in ten or more) and, with a foot
//! closed, in one impact with that foot, and no contact ever pulls.

use std::collections::BTreeMap;

use serde_json::Value;

mod common;
use common::{root, run, scratch};

/// Runs the example open loop at `volts` for `t_end` s; returns the summary, the
/// trace and the events files' text.
fn fig8(volts: &str, t_end: &str) -> (Value, String, String) {
    let (out, events) = (
        scratch("cli-fig8", &format!("{volts}-t.csv")),
        scratch("cli-fig8", &format!("{volts}-e.csv")),
    );
    let machine = root().join("examples/paper-fig8.toml");
    let r = run(&[
        "run",
        machine.to_str().unwrap(),
        "--open-loop",
        volts,
        "--t-end",
        t_end,
        "--format",
        "json",
        "--out",
        out.to_str().unwrap(),
        "--events",
        events.to_str().unwrap(),
    ]);
    assert_eq!(r.status, 0, "{}", r.stderr);
    let summary = serde_json::from_str(&r.stdout).expect("one JSON document");
    (
        summary,
        std::fs::read_to_string(out).unwrap(),
        std::fs::read_to_string(events).unwrap(),
    )
}

/// The contacts that struck at each impact instant, from the events file.
fn impact_sets(events: &str) -> BTreeMap<String, Vec<String>> {
    let mut lines = events.lines();
    let head: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| head.iter().position(|h| *h == name).unwrap();
    let (t, kind, contact) = (col("t"), col("kind"), col("contact"));
    let mut sets: BTreeMap<String, Vec<String>> = BTreeMap::new();
    for line in lines {
        let f: Vec<&str> = line.split(',').collect();
        if f[kind] == "impact" {
            sets.entry(f[t].to_string())
                .or_default()
                .push(f[contact].to_string());
        }
    }
    sets
}

#[test]
fn the_fig8_machine_travels_right_with_simultaneous_impacts() {
    let (summary, trace, events) = fig8("12", "3");
    assert_eq!(summary["faults"], serde_json::json!([]), "{summary}");
    // It travels right: millimetres per second, not a drift of the integrator.
    let v = summary["mean_velocity"].as_f64().unwrap();
    assert!(v > 5e-3, "mean velocity {v} m/s");

    // K3 and K4 strike together (the faces meet along their height at once), and
    // with a foot closed the impact takes it in too (K1 or K2 with K3 and K4).
    let sets = impact_sets(&events);
    let has = |s: &[String], names: &[&str]| names.iter().all(|n| s.iter().any(|c| c == n));
    let k3_or_k4 = sets
        .values()
        .filter(|s| has(s, &["K3"]) || has(s, &["K4"]))
        .count();
    let k34 = sets.values().filter(|s| has(s, &["K3", "K4"])).count();
    let with_a_foot = sets
        .values()
        .filter(|s| has(s, &["K3", "K4"]) && (has(s, &["K1"]) || has(s, &["K2"])))
        .count();
    assert!(
        k34 >= 100 && k34 * 10 >= k3_or_k4 * 9,
        "K3 and K4 together at {k34} of {k3_or_k4} instants"
    );
    assert!(
        with_a_foot >= 10,
        "K3 and K4 with a foot at {with_a_foot} instants"
    );

    // No contact pulls: every normal force in the trace is >= -eps_F, the force
    // tolerance, 1e-6 of the machine's weight (2 + 0.4 + 0.15 + 0.01 kg; the row
    // just before a lift-off has the force at that threshold, to the event
    // location's error: 1 % of eps_F allowed, as for the reference machine).
    let eps_f = 1.01e-6 * 2.56 * 9.81;
    let mut lines = trace.lines();
    let head: Vec<&str> = lines.next().unwrap().split(',').collect();
    let normal: Vec<usize> = (0..head.len())
        .filter(|&i| head[i].starts_with("fn_"))
        .collect();
    assert_eq!(normal.len(), 4, "{head:?}");
    let mut rows = 0;
    for line in lines {
        let f: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
        for &i in &normal {
            assert!(f[i] >= -eps_f, "{} = {} N in {line}", head[i], f[i]);
        }
        rows += 1;
    }
    assert!(rows > 3000, "{rows} rows");
}

/// The README's command: the controller holds the one rotor, which sits on the
/// actuator (its angle the 6th coordinate), at 3000 rpm; no fault, and it travels
/// right.
#[test]
fn the_controller_holds_the_fig8_rotor_at_speed() {
    let machine = root().join("examples/paper-fig8.toml");
    let r = run(&[
        "run",
        machine.to_str().unwrap(),
        "--command",
        "right",
        "--speed",
        "3000",
        "--t-end",
        "1.5",
        "--format",
        "json",
    ]);
    assert_eq!(r.status, 0, "{}", r.stderr);
    let v: Value = serde_json::from_str(&r.stdout).unwrap();
    assert_eq!(v["faults"], serde_json::json!([]), "{v}");
    assert_eq!(v["state"], "running", "{v}");
    let rpm = v["rotor_speed_rpm"][0].as_f64().unwrap();
    assert!((rpm - 3000.0).abs() < 30.0, "rotor at {rpm} rpm");
    assert!(v["mean_velocity"].as_f64().unwrap() > 0.0, "{v}");
    // The controller's constants are a single platform's: said.
    let warned = v["warnings"].as_array().unwrap().iter().any(|w| {
        w.as_str()
            .is_some_and(|w| w.starts_with("the controller's constants"))
    });
    assert!(warned, "{v}");
}
