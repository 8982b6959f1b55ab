//! The summary of `host-sim run` as a JSON document or as a table for people
//! (docs/cli-run.md, "Outputs"): the JSON's keys and their order are the contract
//! (`t_end`, `mean_velocity`, `distance`, `impacts`, `rotor_speed_rpm`,
//! `phase_offset_deg`, `phase_error_deg_rms`, `state`, `faults`, `final`,
//! `warnings`, `rotors`, `phase_loop`, `not_a_travel`); a number that is not finite
//! is written `null`, so the document always parses.
//!
//! A run in which a body went through the fundament or tipped over
//! ([`crate::simulation::breach`]) has no travel: `mean_velocity` and `distance`
//! are `null` and `not_a_travel` says why (it is `null` otherwise); the table says
//! `not a travel: ...` in their place. The warnings say what happened.
//!
//! A machine with one rotor: `rotor_speed_rpm` has one entry,
//! `phase_offset_deg` is `null`, `rotors` is 1 and `phase_loop` false; the table
//! says in a line of its own that the controller holds the rotor's speed only.

use serde_json::{Map, Value};

use crate::numbers;
use crate::output::text::{Align, Table};
use crate::simulation::trace::{EndState, Summary};

/// The keys of the summary document, in the documented order (docs/cli-run.md,
/// "Outputs"); the last three: `rotors` (1 or 2), `phase_loop` (whether a phase loop
/// held the offset: a controller run on two rotors) and `not_a_travel` (why
/// `mean_velocity` and `distance` are `null`, or `null`).
pub const SUMMARY_KEYS: [&str; 14] = [
    "t_end",
    "mean_velocity",
    "distance",
    "impacts",
    "rotor_speed_rpm",
    "phase_offset_deg",
    "phase_error_deg_rms",
    "state",
    "faults",
    "final",
    "warnings",
    "rotors",
    "phase_loop",
    "not_a_travel",
];

/// The table's line for a one-rotor machine run by the controller.
pub const ONE_ROTOR_LINE: &str =
    "one rotor: the controller holds its speed only (no phase loop, no phase offset)";

/// The table's line for a one-rotor machine in open loop.
pub const ONE_ROTOR_OPEN_LOOP_LINE: &str = "one rotor: no phase offset";

/// What the table shows for the mean velocity and the distance of a run in which
/// a body went through the fundament or tipped over, and how its line on why
/// begins.
pub const NOT_A_TRAVEL: &str = "not a travel";

/// The keys of the summary's `final` object, in the documented order.
pub const FINAL_KEYS: [&str; 4] = ["position", "angle", "velocity", "angular_velocity"];

/// A JSON number, or `null` when `x` is not finite (JSON has no NaN or infinity).
fn number(x: f64) -> Value {
    // serde_json gives Null for a non-finite f64.
    Value::from(x)
}

/// `[x, y]` as a JSON array.
fn pair(v: [f64; 2]) -> Value {
    Value::Array(vec![number(v[0]), number(v[1])])
}

/// A list of strings as a JSON array.
fn strings(list: &[String]) -> Value {
    Value::Array(list.iter().map(|s| Value::from(s.as_str())).collect())
}

/// The JSON document of a run's summary, keys in the documented order.
pub fn summary_value(s: &Summary) -> Value {
    let mut doc = Map::new();
    let not_a_travel = s.not_a_travel();
    let travel = |x: f64| match not_a_travel {
        None => number(x),
        Some(_) => Value::Null,
    };
    doc.insert("t_end".into(), number(s.t_end));
    doc.insert("mean_velocity".into(), travel(s.mean_velocity));
    doc.insert("distance".into(), travel(s.distance));
    doc.insert("impacts".into(), Value::from(s.impacts));
    doc.insert(
        "rotor_speed_rpm".into(),
        Value::Array(s.rotor_speed_rpm.iter().map(|w| number(*w)).collect()),
    );
    doc.insert(
        "phase_offset_deg".into(),
        s.phase_offset_deg.map_or(Value::Null, number),
    );
    doc.insert("phase_error_deg_rms".into(), number(s.phase_error_deg_rms));
    doc.insert("state".into(), Value::from(s.state.name()));
    let faults: Vec<String> = s.faults.names().map(str::to_string).collect();
    doc.insert("faults".into(), strings(&faults));
    let f = &s.final_state;
    let mut fin = Map::new();
    fin.insert("position".into(), pair(f.position));
    fin.insert("angle".into(), number(f.angle));
    fin.insert("velocity".into(), pair(f.velocity));
    fin.insert("angular_velocity".into(), number(f.angular_velocity));
    doc.insert("final".into(), Value::Object(fin));
    doc.insert("warnings".into(), strings(&s.warnings));
    doc.insert("rotors".into(), Value::from(s.rotors()));
    doc.insert("phase_loop".into(), Value::from(s.phase_loop));
    doc.insert("not_a_travel".into(), Value::from(not_a_travel));
    Value::Object(doc)
}

/// [`summary_value`] as text: pretty-printed, ending with a newline.
pub fn summary_json(s: &Summary) -> String {
    let mut text = serde_json::to_string_pretty(&summary_value(s))
        .unwrap_or_else(|e| format!("{{\"error\": \"{e}\"}}"));
    text.push('\n');
    text
}

/// The decimals the table gives the platform's motion (the mean velocity, the
/// distance and the final state; m, m/s, rad, rad/s): 1e-9, as the animation's
/// pose. What the solver leaves below that is noise (a level platform at rest
/// ends at an angle of 2.5e-19 rad), so a motion that is zero shows as 0; the JSON
/// keeps every digit.
pub const MOTION_DECIMALS: i32 = 9;

/// The summary for people: one quantity a line with its unit, then the faults and
/// the warnings.
pub fn summary_table(s: &Summary) -> String {
    let mut out = format!(
        "run to t = {} s, controller state: {}\n",
        numbers::sig(s.t_end),
        s.state.name()
    );
    if s.rotors() == 1 {
        out.push_str(if s.state == EndState::OpenLoop {
            ONE_ROTOR_OPEN_LOOP_LINE
        } else {
            ONE_ROTOR_LINE
        });
        out.push('\n');
    }
    if let Some(why) = s.not_a_travel() {
        let more = if s.breaches.is_empty() {
            ""
        } else {
            " (the warnings say more)"
        };
        out.push_str(&format!("{NOT_A_TRAVEL}: {why}{more}\n"));
    }
    out.push('\n');
    let mut t = Table::new(&[
        ("quantity", Align::Left),
        ("value", Align::Right),
        ("unit", Align::Left),
    ]);
    let mut row = |name: &str, value: String, unit: &str| {
        t.row(vec![name.to_string(), value, unit.to_string()]);
    };
    let motion = |x: f64| numbers::rounded(x, MOTION_DECIMALS);
    let motion2 = |v: [f64; 2]| numbers::pair([motion(v[0]), motion(v[1])]);
    match s.not_a_travel() {
        None => {
            row(
                "mean velocity (second half)",
                numbers::signed(motion(s.mean_velocity)),
                "m/s",
            );
            row("distance", numbers::signed(motion(s.distance)), "m");
        }
        Some(_) => {
            row("mean velocity (second half)", NOT_A_TRAVEL.to_string(), "");
            row("distance", NOT_A_TRAVEL.to_string(), "");
        }
    }
    row("impacts", s.impacts.to_string(), "");
    for (k, w) in s.rotor_speed_rpm.iter().enumerate() {
        row(
            &format!("rotor {} speed (second half)", k + 1),
            numbers::sig(*w),
            "rpm",
        );
    }
    // One rotor: no offset, no phase error.
    if let Some(offset) = s.phase_offset_deg {
        row("phase offset (circular mean)", numbers::sig(offset), "deg");
        row(
            "phase error (RMS)",
            numbers::sig(s.phase_error_deg_rms),
            "deg",
        );
    }
    let f = &s.final_state;
    row("final position", motion2(f.position), "m");
    let angle = motion(f.angle);
    row(
        "final angle",
        format!(
            "{} ({} deg)",
            numbers::sig(angle),
            numbers::sig(angle.to_degrees())
        ),
        "rad",
    );
    row("final velocity", motion2(f.velocity), "m/s");
    row(
        "final angular velocity",
        numbers::sig(motion(f.angular_velocity)),
        "rad/s",
    );
    out.push_str(&t.render());
    out.push('\n');

    // Faults and warnings, one a line.
    let faults: Vec<String> = s.faults.names().map(str::to_string).collect();
    for (title, list) in [("faults", &faults), ("warnings", &s.warnings)] {
        if list.is_empty() {
            out.push_str(&format!("{title}: none\n"));
        } else {
            out.push_str(&format!("{title}:\n"));
            for item in list {
                out.push_str(&format!("  - {item}\n"));
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simulation::breach::{Breach, BreachKind};
    use crate::simulation::trace::FinalState;
    use shared::controller::{Faults, State};

    fn summary() -> Summary {
        Summary {
            t_end: 10.0,
            mean_velocity: 0.0125,
            distance: 0.1,
            impacts: 42,
            rotor_speed_rpm: vec![3000.5, 2999.5],
            phase_offset_deg: Some(90.25),
            phase_error_deg_rms: 1.5,
            state: EndState::Controller(State::Running),
            phase_loop: true,
            faults: Faults::NONE,
            final_state: FinalState {
                position: [0.25, 0.03],
                angle: 0.01,
                velocity: [0.05, -0.5],
                angular_velocity: 2.0,
            },
            warnings: vec!["w1".to_string()],
            breaches: vec![],
        }
    }

    /// The line of table `t` that starts with `start`.
    fn line_of(t: &str, start: &str) -> String {
        t.lines()
            .find(|l| l.starts_with(start))
            .unwrap_or_else(|| panic!("no {start} line in\n{t}"))
            .to_string()
    }

    fn keys(v: &Value) -> Vec<&str> {
        v.as_object().unwrap().keys().map(String::as_str).collect()
    }

    #[test]
    fn json_has_exactly_the_documented_keys_in_order() {
        let text = summary_json(&summary());
        let doc: Value = serde_json::from_str(&text).unwrap();
        assert_eq!(keys(&doc), SUMMARY_KEYS);
        assert_eq!(keys(&doc["final"]), FINAL_KEYS);
        assert_eq!(doc["impacts"], 42);
        assert_eq!(doc["rotor_speed_rpm"][1], 2999.5);
        assert_eq!(doc["final"]["velocity"][1], -0.5);
        assert_eq!(doc["state"], "running");
        assert_eq!(doc["faults"], Value::Array(vec![]));
        assert_eq!(doc["warnings"][0], "w1");
        assert!(text.ends_with("}\n"));
    }

    #[test]
    fn non_finite_numbers_are_null() {
        let mut s = summary();
        s.mean_velocity = f64::NAN;
        s.rotor_speed_rpm[0] = f64::INFINITY;
        s.final_state.angle = f64::NEG_INFINITY;
        let text = summary_json(&s);
        let doc: Value = serde_json::from_str(&text).expect("valid JSON");
        assert!(doc["mean_velocity"].is_null());
        assert!(doc["rotor_speed_rpm"][0].is_null());
        assert_eq!(doc["rotor_speed_rpm"][1], 2999.5);
        assert!(doc["final"]["angle"].is_null());
        // Nothing else is added.
        assert_eq!(doc.as_object().unwrap().len(), SUMMARY_KEYS.len());
        assert_eq!(doc["warnings"].as_array().unwrap().len(), 1);
    }

    #[test]
    fn table_states_units() {
        let mut s = summary();
        s.faults = Faults::OVER_CURRENT;
        let t = summary_table(&s);
        assert!(
            t.starts_with("run to t = 10 s, controller state: running"),
            "{t}"
        );
        let line = |start: &str| line_of(&t, start);
        assert!(line("mean velocity").ends_with("+0.0125  m/s"), "{t}");
        assert!(line("rotor 1 speed").ends_with("3000.5  rpm"), "{t}");
        assert!(line("phase offset").ends_with("90.25  deg"), "{t}");
        assert!(line("final velocity").ends_with("[0.05, -0.5]  m/s"), "{t}");
        assert!(line("impacts").contains("42"), "{t}");
        assert!(t.contains("faults:\n  - over_current\n"), "{t}");
        assert!(t.contains("warnings:\n  - w1\n"), "{t}");
    }

    /// Issue 23: a level platform at rest printed `final angle -7.51015e-18
    /// (-4.303e-16 deg)`, its position and velocities with such noise too.
    #[test]
    fn the_table_gives_the_motion_to_1e_9_and_the_json_every_digit() {
        let mut s = summary();
        s.mean_velocity = 1.70341e-21;
        s.distance = -1.32191e-21;
        s.final_state = FinalState {
            position: [-1.32191e-21, 0.030000000000000002],
            angle: -7.51015e-18,
            velocity: [1.26047e-21, -6.74353e-21],
            angular_velocity: 6.87237e-20,
        };
        let t = summary_table(&s);
        let line = |start: &str| line_of(&t, start);
        assert!(line("mean velocity").ends_with(" 0  m/s"), "{t}");
        assert!(line("distance").ends_with(" 0  m"), "{t}");
        assert!(line("final position").ends_with(" [0, 0.03]  m"), "{t}");
        assert!(line("final angle").ends_with(" 0 (0 deg)  rad"), "{t}");
        assert!(line("final velocity").ends_with(" [0, 0]  m/s"), "{t}");
        assert!(line("final angular velocity").ends_with(" 0  rad/s"), "{t}");
        // What is not noise keeps 6 significant digits down to 1e-9.
        s.final_state.angle = 2.913081234e-3;
        s.final_state.position = [1.234567891e-7, 0.0301146];
        let t = summary_table(&s);
        assert!(t.contains(" 0.00291308 (0.166907 deg)  rad"), "{t}");
        assert!(t.contains(" [1.23e-7, 0.0301146]  m"), "{t}");
        // The JSON: every digit.
        let doc: Value = serde_json::from_str(&summary_json(&s)).unwrap();
        assert_eq!(doc["final"]["angular_velocity"], 6.87237e-20);
        assert_eq!(doc["distance"], -1.32191e-21);
    }

    /// [`summary`] with the platform through the fundament at 0.25 s.
    fn through_the_floor() -> Summary {
        let breach = Breach {
            body: "platform".to_string(),
            t: 0.25,
            kind: BreachKind::Fundament {
                first: "its centre of mass".to_string(),
                deepest: 0.085,
                deepest_what: "its centre of mass".to_string(),
                deepest_t: 9.5,
            },
        };
        let mut s = summary();
        s.warnings.push(breach.warning());
        s.breaches.push(breach);
        s
    }

    #[test]
    fn no_travel_is_shown_where_a_body_went_through_the_floor() {
        // JSON: the documented keys in order; no number for the travel, the reason
        // beside it.
        let doc: Value = serde_json::from_str(&summary_json(&through_the_floor())).unwrap();
        assert_eq!(keys(&doc), SUMMARY_KEYS);
        assert!(doc["mean_velocity"].is_null(), "{doc}");
        assert!(doc["distance"].is_null(), "{doc}");
        assert_eq!(
            doc["not_a_travel"],
            "platform went through the fundament at t = 0.25 s"
        );
        assert_eq!(doc["final"]["position"][0], 0.25);
        assert_eq!(doc["warnings"].as_array().unwrap().len(), 2);
        // A run that kept off the floor: its numbers, `not_a_travel` null.
        let doc: Value = serde_json::from_str(&summary_json(&summary())).unwrap();
        assert_eq!(doc["mean_velocity"], 0.0125);
        assert!(doc["not_a_travel"].is_null());
        // The table: no bare number, the reason in its place.
        let t = summary_table(&through_the_floor());
        let line = |start: &str| t.lines().find(|l| l.starts_with(start)).unwrap_or_default();
        assert_eq!(
            t.lines().nth(1),
            Some("not a travel: platform went through the fundament at t = 0.25 s (the warnings say more)"),
            "{t}"
        );
        assert!(line("mean velocity").ends_with("not a travel"), "{t}");
        assert!(line("distance").ends_with("not a travel"), "{t}");
        assert!(!t.contains("+0.0125"), "{t}");
        assert!(t.contains("  - platform went through the fundament"), "{t}");
    }

    /// A mean velocity beyond 10 m/s is no travel in `run` as in `tune`: one rule
    /// (`Summary::not_a_travel`), no warning to point to where no body breached.
    #[test]
    fn a_speed_no_travel_by_impacts_reaches_is_no_travel() {
        let mut s = summary();
        s.mean_velocity = 411.0;
        let doc: Value = serde_json::from_str(&summary_json(&s)).unwrap();
        assert!(doc["mean_velocity"].is_null(), "{doc}");
        assert_eq!(
            doc["not_a_travel"],
            "mean velocity 411 m/s, beyond the 10 m/s of any travel by impacts"
        );
        let t = summary_table(&s);
        assert_eq!(
            t.lines().nth(1),
            Some("not a travel: mean velocity 411 m/s, beyond the 10 m/s of any travel by impacts"),
            "{t}"
        );
        // At the bound, a travel still.
        s.mean_velocity = -10.0;
        assert_eq!(s.not_a_travel(), None);
    }

    /// The summary of a one-rotor machine's controller run.
    fn one_rotor() -> Summary {
        Summary {
            rotor_speed_rpm: vec![3000.5],
            phase_offset_deg: None,
            phase_error_deg_rms: 0.0,
            phase_loop: false,
            ..summary()
        }
    }

    #[test]
    fn one_rotor_json_has_one_speed_no_offset_and_says_so() {
        let doc: Value = serde_json::from_str(&summary_json(&one_rotor())).unwrap();
        assert_eq!(keys(&doc), SUMMARY_KEYS);
        assert_eq!(doc["rotor_speed_rpm"], serde_json::json!([3000.5]));
        assert!(doc["phase_offset_deg"].is_null());
        assert_eq!(doc["phase_error_deg_rms"], 0.0);
        assert_eq!(doc["rotors"], 1);
        assert_eq!(doc["phase_loop"], false);
        // Two rotors: both speeds, the offset, the phase loop.
        let doc: Value = serde_json::from_str(&summary_json(&summary())).unwrap();
        assert_eq!(doc["rotors"], 2);
        assert_eq!(doc["phase_loop"], true);
        assert_eq!(doc["phase_offset_deg"], 90.25);
    }

    #[test]
    fn one_rotor_table_says_speed_only() {
        let t = summary_table(&one_rotor());
        let second = t.lines().nth(1).unwrap_or_default();
        assert_eq!(second, ONE_ROTOR_LINE, "{t}");
        assert!(t.contains("rotor 1 speed (second half)"), "{t}");
        assert!(!t.contains("rotor 2 speed"), "{t}");
        assert!(
            !t.lines()
                .any(|l| l.starts_with("phase offset") || l.starts_with("phase error")),
            "{t}"
        );
        // Open loop: no controller to hold anything.
        let open = summary_table(&Summary {
            state: EndState::OpenLoop,
            ..one_rotor()
        });
        assert_eq!(
            open.lines().nth(1),
            Some(ONE_ROTOR_OPEN_LOOP_LINE),
            "{open}"
        );
        // Two rotors: no such line, both speeds and the offset.
        let two = summary_table(&summary());
        assert!(!two.contains("one rotor"), "{two}");
        assert!(
            two.contains("rotor 2 speed") && two.contains("phase offset"),
            "{two}"
        );
        assert_eq!(two.lines().nth(1), Some(""), "{two}");
    }
}
